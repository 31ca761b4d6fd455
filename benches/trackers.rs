//! The trackers' own time per frame on one thread, apart from early vision
//! (see `pipetrack::cli::tracker_bench`): median, mean and slowest frame,
//! each frame timed at its fastest of several replays.
//!
//! `segments` (run with the others, or alone: `-- segments`) times the
//! `lowe` tracker's line-segment extraction (linking with hysteresis,
//! recursive subdivision, indexing) against the early-vision request that
//! feeds it (LoG σ = 1.2, zero crossings, compaction of the whole frame) on
//! the same frames and thread: target3dof at 640×480.
//!
//! `lowe-split` (also alone: `-- lowe-split`) splits the `lowe` tracker's time
//! per frame into early vision, segments, matching and estimation.

use std::time::Instant;

use pipetrack::backend::{CpuBackend, EarlyVision, FrameRequest, GpuBackend, ListSpec, ZeroCrossingRequest};
use pipetrack::cli::tracker_bench::time_trackers;
use pipetrack::early::Window;
use pipetrack::early::log::LogParams;
use pipetrack::early::zero_crossing::ZeroCrossingParams;
use pipetrack::track::lowe::segments::{ImageSegment, SegmentExtractor, SegmentIndex, SegmentParams};

/// Replays per tracker; a frame counts at its fastest.
const PASSES: usize = 15;

/// Frames of target3dof timed by `segments`.
const SEGMENT_FRAMES: usize = 40;

/// Calls per frame of the GPU request (slow where the adapter is a CPU
/// implementation of Vulkan).
const GPU_PASSES: usize = 3;

fn main() -> pipetrack::Result<()> {
    // `cargo bench --bench trackers -- blue` times only the trackers named;
    // cargo adds flags of its own (`--bench`).
    let names: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| pipetrack::Error::Parameter(format!("cannot build a one-thread pool: {e}")))?;
    let trackers: Vec<String> = names.iter().filter(|n| *n != "segments").cloned().collect();
    if names.is_empty() || !trackers.is_empty() {
        let timings = pool.install(|| time_trackers(&trackers, PASSES))?;
        println!(
            "{:<12} {:<11} {:>8} {:>7} {:>8} {:>10} {:>9} {:>8}",
            "tracker", "scene", "size", "frames", "tracked", "median ms", "mean ms", "max ms"
        );
        for t in &timings {
            println!(
                "{:<12} {:<11} {:>8} {:>7} {:>8} {:>10.4} {:>9.4} {:>8.3}",
                t.tracker, t.scene, t.size, t.frames, t.tracked, t.median_ms, t.mean_ms, t.max_ms
            );
        }
    }
    if names.is_empty() || names.iter().any(|n| n == "segments") {
        pool.install(time_segments)?;
    }
    if names.is_empty() || names.iter().any(|n| n == "lowe-split") {
        pool.install(time_lowe_split)?;
    }
    Ok(())
}

/// The `lowe` tracker's time per frame split into early vision (the CPU
/// backend's request), linking and segmentation, matching and search, and
/// estimation (the tracker's own timers), on the `box` scene at 640×480,
/// one thread: means over its 300 frames.
fn time_lowe_split() -> pipetrack::Result<()> {
    use pipetrack::synth::boxes::{BoxOptions, render_box};
    use pipetrack::track::run::{track_once, until_tracked};
    use pipetrack::track::{LoweParams, LoweTracker, Observations, Tracked};
    let seq = render_box(&BoxOptions::default())?;
    let mut tracker = LoweTracker::new(seq.camera, &seq.model, &seq.init, LoweParams::default())?;
    let mut backend = CpuBackend::new();
    let (mut early, mut segments, mut matching, mut estimation, mut branches) = (0.0, 0.0, 0.0, 0.0, 0usize);
    for (i, frame) in seq.frames.iter().enumerate() {
        // A frame whose window the tracker widens is processed twice; the
        // diagnostics hold both searches' times.
        until_tracked(&mut tracker, frame.size(), |tracker, request, may_widen| {
            let start = Instant::now();
            let features = backend.process(frame, &request)?;
            early += start.elapsed().as_secs_f64() * 1e3;
            let look = track_once(tracker, i, &Observations::from(&features), may_widen);
            Ok(matches!(look, Tracked::Outcome(_)).then_some(()))
        })?;
        let d = tracker.diagnostics();
        segments += d.segments_ms;
        matching += d.matching_ms;
        estimation += d.estimation_ms;
        branches += d.branches;
    }
    let n = seq.frames.len().max(1) as f64;
    println!("\nlowe on box 640x480, one thread, mean ms per frame over {} frames", seq.frames.len());
    println!(
        "{:>12} {:>12} {:>12} {:>12} {:>10} {:>10}",
        "early vision", "segments", "matching", "estimation", "total", "branches"
    );
    println!(
        "{:>12.3} {:>12.3} {:>12.3} {:>12.3} {:>10.3} {:>10.2}",
        early / n,
        segments / n,
        matching / n,
        estimation / n,
        (early + segments + matching + estimation) / n,
        branches as f64 / n
    );
    Ok(())
}

/// Median, mean and largest of per-frame times, ms.
fn summary(times: &[f64]) -> (f64, f64, f64) {
    let mut sorted = times.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let median = if n % 2 == 1 { sorted[n / 2] } else { 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]) };
    (median, sorted.iter().sum::<f64>() / n as f64, sorted[n - 1])
}

/// Milliseconds `f` takes at its fastest of `passes` calls.
fn fastest_ms(passes: usize, mut f: impl FnMut()) -> f64 {
    (0..passes)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

/// Margin of the tracking-sized window around the target's true corners, px.
const TARGET_MARGIN: f64 = 20.0;

/// Time segment extraction on target3dof frames against the zero-crossing
/// request of the CPU backend (and of the GPU backend when there is an
/// adapter, at its fastest of [`GPU_PASSES`]), each frame at its fastest of
/// [`PASSES`]: over the whole frame, then over a tracker-sized window (the
/// target's true corners widened by [`TARGET_MARGIN`]).
fn time_segments() -> pipetrack::Result<()> {
    let seq = pipetrack::synth::render_scene("target3dof", Some(SEGMENT_FRAMES), 0, &[])?;
    let (w, h) = seq.frames[0].size();
    let full: Vec<Window> = vec![Window::full(w, h); seq.frames.len()];
    let around: Vec<Window> = seq
        .truth
        .iter()
        .map(|t| Window::around(&t.corners, TARGET_MARGIN, w, h).unwrap_or(Window::full(w, h)))
        .collect();
    let mut gpu = pipetrack::GpuContext::new().ok().map(|ctx| (ctx.adapter_name().to_string(), GpuBackend::new(ctx)));
    if let Some((name, _)) = &gpu {
        println!("\nGPU: {name}");
    }
    time_segments_in(&seq, &full, "whole frame", &mut gpu)?;
    time_segments_in(&seq, &around, "window around the target", &mut gpu)
}

/// [`time_segments`] with one window per frame.
fn time_segments_in(
    seq: &pipetrack::synth::SyntheticSequence,
    windows: &[Window],
    what: &str,
    gpu: &mut Option<(String, GpuBackend)>,
) -> pipetrack::Result<()> {
    let (w, h) = seq.frames[0].size();
    let params = SegmentParams::default();
    let mut extractor = SegmentExtractor::new(params.clone())?;
    let mut index = SegmentIndex::with_params(&params);
    let mut segments: Vec<ImageSegment> = Vec::new();
    let mut cpu = CpuBackend::new();
    let mut rows: Vec<(&str, Vec<f64>)> =
        ["zero crossings, CPU", "link", "link + subdivide", "index", "segments total"].map(|r| (r, Vec::new())).into();
    let mut gpu_times = Vec::new();
    let (mut area, mut edgels, mut chains, mut count) = (0, 0, 0, 0);
    for (frame, &window) in seq.frames.iter().zip(windows) {
        let request = FrameRequest {
            zero_crossings: Some(ZeroCrossingRequest {
                log: LogParams::default(),
                crossings: ZeroCrossingParams::default(),
                list: ListSpec { window, cap: None, seed: 0 },
            }),
            ..FrameRequest::default()
        };
        let mut crossings = Vec::new();
        rows[0].1.push(fastest_ms(PASSES, || {
            crossings = cpu.process(frame, &request).expect("CPU zero crossings").zero_crossings.unwrap_or_default();
        }));
        if let Some((_, backend)) = gpu {
            gpu_times.push(fastest_ms(GPU_PASSES, || {
                backend.process(frame, &request).expect("GPU zero crossings");
            }));
        }
        rows[1].1.push(fastest_ms(PASSES, || extractor.link(&crossings, window)));
        rows[2].1.push(fastest_ms(PASSES, || extractor.extract(&crossings, window, &mut segments)));
        rows[3].1.push(fastest_ms(PASSES, || index.build(&segments, window)));
        rows[4].1.push(fastest_ms(PASSES, || {
            extractor.extract(&crossings, window, &mut segments);
            index.build(&segments, window);
        }));
        area += window.area();
        edgels += crossings.len();
        chains += extractor.chain_count();
        count += segments.len();
    }
    let n = seq.frames.len();
    println!(
        "\nlowe segments, target3dof {w}x{h}, {what}, {n} frames, one thread; per frame: {} pixels, {} edgels, \
         {} chains, {} segments",
        area / n,
        edgels / n,
        chains / n,
        count / n
    );
    if gpu.is_some() {
        rows.insert(1, ("zero crossings, GPU", gpu_times));
    }
    println!("{:<22} {:>10} {:>9} {:>8}", "step", "median ms", "mean ms", "max ms");
    for (step, times) in &rows {
        let (median, mean, max) = summary(times);
        println!("{step:<22} {median:>10.4} {mean:>9.4} {max:>8.3}");
    }
    Ok(())
}
