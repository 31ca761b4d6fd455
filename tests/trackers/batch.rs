//! Many sequences at once: `track::batch` writes, for every sequence, the
//! same lines as tracking it alone (`track_to_file`), on the CPU with
//! several threads and on the GPU with one lane and with several lanes
//! sharing each submission (only the `ms` timing may differ).
use crate::common;

use std::path::{Path, PathBuf};

use pipetrack::backend::BackendKind;
use pipetrack::io::Sequence;
use pipetrack::track::batch::{BatchJob, BatchProgress, run_batch, run_batch_on_gpu};
use pipetrack::track::run::{TrackOptions, track_to_file};
use pipetrack::{GpuBackend, synth};

/// Sequences of three trackers and of different lengths, so lanes end at
/// different steps and take the next sequence while others run. The box
/// turns round ([`turn_round`]): `lowe` widens its window there and tracks
/// the frame again.
const SEQUENCES: &[(&str, &str, usize, u64)] = &[
    ("pendulum", "motion-edge", 7, 1),
    ("target3dof", "blue", 6, 2),
    ("box", "lowe", 14, 6),
    ("pendulum", "motion-edge", 4, 3),
    ("pendulum", "motion-edge", 9, 4),
    ("target3dof", "blue", 5, 5),
];

/// The frame of the box sequence where its motion turns round.
const TURN: usize = 10;

/// The box sequence in `dir` played forward to frame `TURN - 1`, then
/// backward from three frames before it: the prediction at the turn lies
/// four steps from the box, beyond a narrowed window.
fn turn_round(dir: &Path, frames: usize) {
    let frame = |i: usize| dir.join("frames").join(format!("{i:06}.png"));
    let images: Vec<Vec<u8>> = (0..frames).map(|i| std::fs::read(frame(i)).unwrap()).collect();
    for i in TURN..frames {
        std::fs::write(frame(i), &images[2 * TURN - 4 - i]).unwrap();
    }
}

fn options(tracker: &str, backend: BackendKind) -> TrackOptions {
    TrackOptions { tracker: tracker.into(), backend, config: None, overlay: None, progress: false }
}

/// The sequences rendered under `root`, as jobs writing into `root/<out>`.
fn jobs(root: &Path, out: &str) -> Vec<BatchJob> {
    std::fs::create_dir_all(root.join(out)).unwrap();
    SEQUENCES
        .iter()
        .enumerate()
        .map(|(i, &(scene, tracker, frames, seed))| {
            let dir = root.join(format!("seq{i}"));
            if !dir.exists() {
                let speed = [("speed".to_string(), "20".to_string())];
                let extra: &[(String, String)] = if scene == "box" { &speed } else { &[] };
                synth::generate(scene, &dir, Some(frames), seed, extra).unwrap();
                if scene == "box" {
                    turn_round(&dir, frames);
                }
            }
            let seq = Sequence::open(&dir, false).unwrap();
            BatchJob {
                seq,
                opts: options(tracker, BackendKind::Cpu),
                out_path: root.join(out).join(format!("seq{i}.jsonl")),
            }
        })
        .collect()
}

/// The output's lines without the `ms` field.
fn lines_without_time(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(|l| {
            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
            v.as_object_mut().unwrap().remove("ms");
            v
        })
        .collect()
}

/// Each sequence tracked alone on the CPU backend: the reference outputs.
fn reference(root: &Path) -> Vec<PathBuf> {
    jobs(root, "alone")
        .iter()
        .map(|j| {
            track_to_file(&j.seq, &j.opts, &j.out_path).unwrap();
            j.out_path.clone()
        })
        .collect()
}

fn check_equal(what: &str, jobs: &[BatchJob], reference: &[PathBuf]) {
    for ((job, want), (_, _, frames, _)) in jobs.iter().zip(reference).zip(SEQUENCES) {
        let (got, want) = (lines_without_time(&job.out_path), lines_without_time(want));
        assert_eq!(got.len(), *frames, "{what}: {}", job.out_path.display());
        assert_eq!(got, want, "{what}: {} differs from tracking it alone", job.out_path.display());
    }
}

fn no_progress(_: BatchProgress) {}

#[test]
fn cpu_batch_equals_tracking_each_sequence_alone() {
    let root = common::scratch("batch", "cpu");
    let reference = reference(&root);
    let jobs = jobs(&root, "batch");
    let frames = std::sync::atomic::AtomicUsize::new(0);
    let count = |p: BatchProgress| {
        if p == BatchProgress::Frame {
            frames.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    };
    let results = run_batch(&jobs, BackendKind::Cpu, 3, &count).unwrap();
    assert!(results.iter().all(Result::is_ok), "{results:?}");
    assert_eq!(frames.into_inner(), SEQUENCES.iter().map(|s| s.2).sum::<usize>());
    check_equal("cpu, 3 threads", &jobs, &reference);
}

#[test]
fn gpu_batch_equals_tracking_each_sequence_alone_on_the_cpu() {
    let Some((ctx, _guard)) = common::gpu("gpu_batch_equals_tracking_each_sequence_alone_on_the_cpu") else {
        return;
    };
    let root = common::scratch("batch", "gpu");
    let reference = reference(&root);
    let mut backend = GpuBackend::new(ctx.clone());
    for lanes in [1, 2, 3, 8] {
        let jobs = jobs(&root, &format!("lanes{lanes}"));
        // A frame submitted again after the tracker widened its window is
        // counted once.
        let frames = std::sync::atomic::AtomicUsize::new(0);
        let count = |p: BatchProgress| {
            if p == BatchProgress::Frame {
                frames.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
        };
        let results = run_batch_on_gpu(&jobs, &mut backend, lanes, &count).unwrap();
        assert_eq!(frames.into_inner(), SEQUENCES.iter().map(|s| s.2).sum::<usize>(), "{lanes} lanes");
        for (job, r) in jobs.iter().zip(&results) {
            let summary = r.as_ref().unwrap_or_else(|e| panic!("{}: {e}", job.out_path.display()));
            assert!(summary.backend.starts_with("GPU"), "{}", summary.backend);
        }
        check_equal(&format!("gpu, {lanes} lanes"), &jobs, &reference);
    }
}

/// The premise of the batches above: `lowe` widens its window on the box
/// sequence where it turns round.
#[test]
fn lowe_widens_its_window_where_the_box_sequence_turns() {
    use pipetrack::backend::EarlyVision;
    use pipetrack::track::{LoweParams, LoweTracker, Observations, Tracked, Tracker};
    let root = common::scratch("batch", "turn");
    let job = jobs(&root, "out").into_iter().find(|j| j.opts.tracker == "lowe").expect("a lowe sequence");
    let seq = &job.seq;
    let (w, h) = (seq.camera.width as usize, seq.camera.height as usize);
    let mut tracker = LoweTracker::new(seq.camera, &seq.model, &seq.init, LoweParams::default()).unwrap();
    let mut backend = pipetrack::CpuBackend::new();
    backend.reset();
    let mut widened = Vec::new();
    for (i, frame) in seq.frames().enumerate() {
        let frame = frame.unwrap();
        let features = backend.process(&frame, &tracker.request(w, h)).unwrap();
        if let Tracked::Widened = tracker.track_or_widen(i, &Observations::from(&features)) {
            widened.push(i);
            let features = backend.process(&frame, &tracker.request(w, h)).unwrap();
            tracker.track(i, &Observations::from(&features));
        }
    }
    assert!(widened.contains(&TURN), "widened on frames {widened:?}");
}

/// A sequence whose frame cannot be read fails alone: no output, its error
/// names the frame, and the sequences beside it in other lanes finish.
#[test]
fn a_failing_lane_leaves_the_others_running() {
    let Some((ctx, _guard)) = common::gpu("a_failing_lane_leaves_the_others_running") else { return };
    let root = common::scratch("batch", "gpu-bad");
    let reference = reference(&root);
    let jobs = jobs(&root, "batch");
    let bad_frame = root.join("seq0/frames/000003.png");
    std::fs::write(&bad_frame, b"not a png").unwrap();
    let mut backend = GpuBackend::new(ctx.clone());
    let results = run_batch_on_gpu(&jobs, &mut backend, 3, &no_progress).unwrap();
    let err = results[0].as_ref().unwrap_err().to_string();
    assert!(err.contains("000003.png"), "{err}");
    assert!(!jobs[0].out_path.exists());
    let out_name = jobs[0].out_path.file_name().unwrap().to_string_lossy().into_owned();
    assert!(common::partials(jobs[0].out_path.parent().unwrap(), &out_name).is_empty());
    for (i, r) in results.iter().enumerate().skip(1) {
        assert!(r.is_ok(), "sequence {i}: {r:?}");
    }
    let (good_jobs, good_reference) = (&jobs[1..], &reference[1..]);
    for ((job, want), (_, _, frames, _)) in good_jobs.iter().zip(good_reference).zip(&SEQUENCES[1..]) {
        let got = lines_without_time(&job.out_path);
        assert_eq!(got.len(), *frames);
        assert_eq!(got, lines_without_time(want), "{}", job.out_path.display());
    }
}

/// Condensation reads colour frames: in a GPU batch its lanes carry each
/// frame's colour, and every sequence's lines equal tracking it alone with
/// `track` on the GPU (which reads the colour files).
#[test]
fn gpu_batch_of_colour_sequences_equals_tracking_each_alone() {
    let Some((ctx, _guard)) = common::gpu("gpu_batch_of_colour_sequences_equals_tracking_each_alone") else {
        return;
    };
    let root = common::scratch("batch", "gpu-colour");
    let frames = [5, 3, 4];
    let jobs = |out: &str, backend: BackendKind| -> Vec<BatchJob> {
        std::fs::create_dir_all(root.join(out)).unwrap();
        frames
            .iter()
            .enumerate()
            .map(|(i, &n)| {
                let dir = root.join(format!("plane{i}"));
                if !dir.exists() {
                    synth::generate("textured-plane", &dir, Some(n), 10 + i as u64, &[]).unwrap();
                }
                BatchJob {
                    seq: Sequence::open(&dir, false).unwrap(),
                    opts: options("condensation", backend),
                    out_path: root.join(out).join(format!("plane{i}.jsonl")),
                }
            })
            .collect()
    };
    let alone = jobs("alone", BackendKind::Gpu);
    for j in &alone {
        let summary = track_to_file(&j.seq, &j.opts, &j.out_path).unwrap();
        assert!(summary.backend.starts_with("GPU"), "{}", summary.backend);
    }
    let batch = jobs("lanes2", BackendKind::Cpu);
    let results = run_batch_on_gpu(&batch, &mut GpuBackend::new(ctx.clone()), 2, &no_progress).unwrap();
    for ((job, want), (r, &n)) in batch.iter().zip(&alone).zip(results.iter().zip(&frames)) {
        r.as_ref().unwrap_or_else(|e| panic!("{}: {e}", job.out_path.display()));
        let (got, want) = (lines_without_time(&job.out_path), lines_without_time(&want.out_path));
        assert_eq!(got.len(), n, "{}", job.out_path.display());
        assert_eq!(got, want, "{} differs from tracking it alone", job.out_path.display());
    }
}
