//! End-to-end tests of the `motion-edge` tracker (paper 000) on rendered
//! pendulum sequences: frames → backend (CPU twins, and the WGSL shaders
//! where a GPU adapter exists) → tracker → scored against the truth.
//!
//! The scene is the paper's experiment: a 50×35 px rectangle on a pendulum
//! arm, turning with it, released from rest at frame 0, 256×242 frames,
//! textured background, Gaussian pixel noise σ = 2, 200 frames (three and a
//! half swings at the paper's speeds, turning points included).
//!
//! Acceptance: at the paper's 1.1, 3.9 and 4.5 px/frame peak
//! speeds every frame is `tracking` on both backends, with mean corner error
//! ≤ 0.5 px and per-frame error ≤ 2 px; at 16 px/frame every frame is still
//! `tracking`, and at 20 px/frame; an object that jumps away is reported `lost`, and a line is
//! still written for every frame.

use crate::common;

use pipetrack::backend::{BackendKind, CpuBackend, EarlyVision, GpuBackend};
use pipetrack::cli::score::{Score, score};
use pipetrack::io::Sequence;
use pipetrack::io::formats::{FrameResult, Status};
use pipetrack::synth::pendulum::{PendulumOptions, render_pendulum};
use pipetrack::track::motion_edge::Prediction;
use pipetrack::track::run::{TrackOptions, track_frames, track_sequence};
use pipetrack::track::{MotionEdgeParams, MotionEdgeTracker};

/// The paper's peak image speeds, px/frame.
const PAPER_SPEEDS: [f64; 3] = [1.1, 3.9, 4.5];
/// Mean corner error allowed at the paper's speeds, px.
const MEAN_LIMIT: f64 = 0.5;
/// Largest per-frame mean corner error allowed at the paper's speeds, px.
const MAX_LIMIT: f64 = 2.0;

fn pendulum(speed: f64) -> PendulumOptions {
    PendulumOptions { frames: 200, speed, noise_sigma: 2.0, ..PendulumOptions::default() }
}

/// Render `opts`, track it with the default parameters on `backend`, score it.
fn track(opts: &PendulumOptions, backend: &mut dyn EarlyVision) -> (Vec<FrameResult>, Score) {
    track_with(opts, MotionEdgeParams::default(), backend)
}

/// Render `opts`, track it with `params` on `backend`, score it.
fn track_with(
    opts: &PendulumOptions,
    params: MotionEdgeParams,
    backend: &mut dyn EarlyVision,
) -> (Vec<FrameResult>, Score) {
    let seq = render_pendulum(opts).expect("render");
    let (w, h) = (seq.camera.width as usize, seq.camera.height as usize);
    let mut tracker =
        MotionEdgeTracker::new(seq.init.corners.clone(), seq.model.edges.clone(), params).expect("tracker");
    let mut results = Vec::with_capacity(seq.frames.len());
    track_frames(&mut tracker, backend, seq.frames.iter().cloned().map(Ok), (w, h), |_, _, r| {
        results.push(r.clone());
        Ok(())
    })
    .expect("track");
    let s = score(&seq.truth, &results).expect("score");
    (results, s)
}

/// Every frame tracking, and the error limits; prints the figures.
fn check(label: &str, speed: f64, results: &[FrameResult], s: &Score, mean_limit: f64, max_limit: f64) {
    let stats = s.stats.expect("frames scored");
    println!(
        "{label}: {speed:>4} px/frame: tracked {}/{}, mean corner error {:.3} px, median {:.3}, p95 {:.3}, max {:.3}",
        s.tracked, s.frames, stats.mean, stats.median, stats.p95, stats.max
    );
    assert_eq!(results.len(), 200, "{label} {speed}: a result per frame");
    if let Some(r) = results.iter().find(|r| r.status != Status::Tracking) {
        panic!("{label} {speed} px/frame: frame {} is {:?} (first lost {:?})", r.frame, r.status, s.first_lost);
    }
    assert!(
        stats.mean <= mean_limit,
        "{label} {speed} px/frame: mean corner error {:.3} px > {mean_limit}",
        stats.mean
    );
    assert!(stats.max <= max_limit, "{label} {speed} px/frame: worst frame {:.3} px > {max_limit}", stats.max);
    assert!(
        s.false_tracking_fraction() <= 0.01,
        "{label} {speed} px/frame: {} frames reported tracking more than {} px off: {:?}",
        s.false_tracking.len(),
        s.false_tracking_px,
        s.false_tracking
    );
}

#[test]
fn cpu_tracks_the_paper_speeds_within_half_a_pixel() {
    for speed in PAPER_SPEEDS {
        let (results, s) = track(&pendulum(speed), &mut CpuBackend::new());
        check("CPU", speed, &results, &s, MEAN_LIMIT, MAX_LIMIT);
    }
}

#[test]
fn gpu_tracks_the_paper_speeds_within_half_a_pixel() {
    let Some((ctx, _guard)) = common::gpu("gpu_tracks_the_paper_speeds_within_half_a_pixel") else { return };
    for speed in PAPER_SPEEDS {
        let (results, s) = track(&pendulum(speed), &mut GpuBackend::new(ctx.clone()));
        check("GPU", speed, &results, &s, MEAN_LIMIT, MAX_LIMIT);
    }
}

#[test]
fn cpu_keeps_tracking_at_16_px_per_frame() {
    // Four times the paper's fastest: bands ~14 px wide on 35 px edges, and
    // ~2.7 px/frame² of acceleration out of the turning points. Measured
    // (seed 0): mean 0.77 px, worst frame 1.8 px; the limits leave room.
    let (results, s) = track(&pendulum(16.0), &mut CpuBackend::new());
    check("CPU", 16.0, &results, &s, 1.0, 3.0);
}

#[test]
fn gpu_keeps_tracking_at_16_px_per_frame() {
    let Some((ctx, _guard)) = common::gpu("gpu_keeps_tracking_at_16_px_per_frame") else { return };
    let (results, s) = track(&pendulum(16.0), &mut GpuBackend::new(ctx.clone()));
    check("GPU", 16.0, &results, &s, 1.0, 3.0);
}

#[test]
fn cpu_keeps_tracking_at_20_px_per_frame() {
    // Beyond 16: ~18 px bands on 35 px edges, fast turns out of the bottom
    // of the swing. Measured (seed 0): every frame tracking, mean 1.1 px,
    // worst frame 2.3 px.
    let (results, s) = track(&pendulum(20.0), &mut CpuBackend::new());
    check("CPU", 20.0, &results, &s, 1.5, 3.5);
}

#[test]
fn a_jump_away_is_lost_and_every_frame_still_gets_a_line() {
    // The object jumps 80 px down at frame 40, mid-swing (3.9 px/frame).
    let jump = 40;
    let opts = PendulumOptions { jump_at: Some(jump), ..pendulum(3.9) };
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("motion_edge_e2e_jump_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    render_pendulum(&opts).expect("render").write(&dir).expect("write sequence");
    let seq = Sequence::open(&dir, false).expect("open sequence");
    let opts = TrackOptions {
        tracker: "motion-edge".into(),
        backend: BackendKind::Cpu,
        config: None,
        overlay: None,
        progress: false,
    };
    let mut out = Vec::new();
    let summary = track_sequence(&seq, &opts, &mut out, |_| {}).expect("track runs to the end");
    let _ = std::fs::remove_dir_all(&dir);
    let lines: Vec<FrameResult> = String::from_utf8(out)
        .expect("utf-8")
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON result per line"))
        .collect();
    assert_eq!(lines.len(), 200, "one line per frame");
    assert_eq!(summary.frames, 200);
    for (k, r) in lines.iter().enumerate() {
        assert_eq!(r.frame, k);
        assert_eq!(r.corners.len(), 4, "frame {k}");
        assert!(r.corners.iter().all(|c| c[0].is_finite() && c[1].is_finite()), "frame {k}: {:?}", r.corners);
    }
    assert!(lines[..jump].iter().all(|r| r.status == Status::Tracking), "tracking before the jump");
    let first_lost = lines.iter().position(|r| r.status == Status::Lost).expect("the jump must be lost");
    println!("jump at frame {jump}: first lost frame {first_lost}, {} frames tracking in all", summary.tracked);
    assert!((jump..=jump + 2).contains(&first_lost), "lost at frame {first_lost}");
}

#[test]
fn a_second_object_crossing_behind_the_target_is_never_tracked_instead() {
    // The hexagon crosses the frame on row 120, behind the rectangle, at
    // every speed. Its edges in the lines' strips pull the fits; frames
    // whose outline is then off the image's edges are reported lost, and no
    // frame is reported tracking more than 5 px off.
    for speed in [1.1, 3.9, 16.0] {
        let opts = PendulumOptions { distractor: true, distractor_y: 120.0, ..pendulum(speed) };
        let (results, s) = track(&opts, &mut CpuBackend::new());
        let st: String = results.iter().map(|r| if r.status == Status::Tracking { 'T' } else { 'L' }).collect();
        println!("distractor {speed:>4} px/frame: {st}");
        println!("distractor {speed:>4} px/frame: tracked {}/{}, false {:?}", s.tracked, s.frames, s.false_tracking);
        assert!(s.false_tracking.is_empty(), "{speed} px/frame: false tracking at {:?}", s.false_tracking);
        // Measured: 195, 200 and 200 of 200.
        let least = 190;
        assert!(s.tracked >= least, "{speed} px/frame: {} of 200 frames tracking", s.tracked);
    }
}

/// A side whose prediction leans past δ (the hexagon's pixels pulled a
/// corner the frame before, or the pendulum turns fast) gets its own pixels
/// refused; the second look at `retry_delta` measures it, and the
/// verification at δ still decides. Without it (`retry_delta = 0`) these
/// runs hold 200, 200 and 190 of 200 frames; with corners predicted one by
/// one (`Prediction::MeasuredVelocity`) as well, 187, 176 and 176.
#[test]
fn a_second_look_at_a_wider_angle_holds_a_leaning_side() {
    let cases = [
        (
            "second object, 16 px/frame, seed 3",
            PendulumOptions { distractor: true, distractor_y: 120.0, seed: 3, ..pendulum(16.0) },
        ),
        ("20 px/frame, seed 4", PendulumOptions { seed: 4, ..pendulum(20.0) }),
        ("20 px/frame, seed 8", PendulumOptions { seed: 8, ..pendulum(20.0) }),
    ];
    for (name, opts) in cases {
        let (_, s) = track(&opts, &mut CpuBackend::new());
        println!("{name}: tracked {}/{}, false {:?}", s.tracked, s.frames, s.false_tracking);
        assert!(s.false_tracking.is_empty(), "{name}: false tracking at {:?}", s.false_tracking);
        assert!(s.tracked >= 190, "{name}: {} of 200 frames tracking", s.tracked);
    }
}

/// The outline moves on as one (module doc, "The outline moves as one"):
/// rotating at 20 px/frame, seed 1, corners predicted one by one let a short
/// side lean past δ and lost frames 6–11 and 36–41; moved by the outline's
/// similarity step, every frame holds. Both are run, so the test fails when
/// the scene no longer tells the two apart.
#[test]
fn the_outline_moving_as_one_holds_a_fast_turning_rectangle() {
    let opts = PendulumOptions { seed: 1, ..pendulum(20.0) };
    let by_corner = MotionEdgeParams { prediction: Prediction::MeasuredVelocity, ..MotionEdgeParams::default() };
    let (_, corners) = track_with(&opts, by_corner, &mut CpuBackend::new());
    let (_, outline) = track(&opts, &mut CpuBackend::new());
    for (name, s) in [("corner by corner", &corners), ("as one outline", &outline)] {
        let mean = s.stats.map_or(f64::NAN, |st| st.mean);
        println!("{name}: tracked {}/{}, mean {mean:.3} px, false {:?}", s.tracked, s.frames, s.false_tracking);
        assert!(s.false_tracking.is_empty(), "{name}: false tracking at {:?}", s.false_tracking);
    }
    assert!(corners.tracked < 195, "corner by corner: {} of 200 frames tracking", corners.tracked);
    assert_eq!(outline.tracked, 200, "as one outline: first lost {:?}", outline.first_lost);
}

/// The third look, from the outline moved on at constant acceleration
/// (module doc, "A look from the accelerating outline"): at 22 px/frame it
/// holds most of the frames lost without it, and on a run the first two
/// looks hold it changes nothing.
#[test]
fn a_look_from_the_accelerating_outline_holds_22_px_per_frame() {
    let without_look = || MotionEdgeParams { acceleration_look: false, ..MotionEdgeParams::default() };
    let fast = pendulum(22.0);
    let (_, before) = track_with(&fast, without_look(), &mut CpuBackend::new());
    let (_, after) = track(&fast, &mut CpuBackend::new());
    for (name, s) in [("without the look", &before), ("with it", &after)] {
        println!("22 px/frame {name}: tracked {}/{}, false {:?}", s.tracked, s.frames, s.false_tracking);
        assert!(s.false_tracking.is_empty(), "{name}: false tracking at {:?}", s.false_tracking);
    }
    assert!(before.tracked < 120, "without the look: {} of 200 frames tracking", before.tracked);
    assert!(after.tracked >= 185, "with the look: {} of 200 frames tracking", after.tracked);

    let held = PendulumOptions { seed: 1, ..pendulum(20.0) };
    let (lines_without, _) = track_with(&held, without_look(), &mut CpuBackend::new());
    let (lines_with, s) = track(&held, &mut CpuBackend::new());
    assert_eq!(s.tracked, 200);
    for (a, b) in lines_without.iter().zip(&lines_with) {
        assert_eq!((a.status, &a.corners), (b.status, &b.corners), "frame {}", a.frame);
    }
}

#[test]
fn beyond_20_px_per_frame_frames_are_lost_but_never_falsely_tracked() {
    // Between the turning points the rectangle outruns the strips; each
    // re-acquisition must name its corners as before (a fit that moved every
    // line onto the next side of the rectangle is refused by side length).
    for speed in [24.0, 28.0] {
        let (results, s) = track(&pendulum(speed), &mut CpuBackend::new());
        let st: String = results.iter().map(|r| if r.status == Status::Tracking { 'T' } else { 'L' }).collect();
        println!("{speed:>4} px/frame: {st}");
        println!("{speed:>4} px/frame: tracked {}/{}, false {:?}", s.tracked, s.frames, s.false_tracking);
        assert!(s.tracked > 0, "{speed} px/frame: never tracking");
        assert!(s.false_tracking.is_empty(), "{speed} px/frame: false tracking at {:?}", s.false_tracking);
    }
}
