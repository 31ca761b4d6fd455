//! End to end: the `blue` tracker (paper 002) on rendered `target3dof`
//! sequences (bookshelf background, 300 frames, 0.85 m → 4.9 m), through the
//! real per-frame loop ([`pipetrack::track::run::track_frames`]) and a backend.
//!
//! Acceptance: at 0.3 and 1.2 rad/s every frame has status `tracking`; at
//! 1.2 rad/s with 30 % of the target occluded at least 99 % of the frames
//! do, and no loss lasts more than 3 frames (the bar hides the edges that
//! would correct the estimate on frame 251, 7.2 px off: the verification
//! reports that frame and the next `lost`); no frame is reported tracking
//! more than 5 px off, and the mean vertex error is at most 1 px; on the CPU backend always, on the GPU backend when
//! an adapter exists (`PIPETRACK_REQUIRE_GPU=1` makes a missing one a
//! failure). On failure the message lists the lost frames with the
//! tracker's reason and the frames with the largest errors.
//! All three run on the GPU too (about 25 s on lavapipe, 2 cores).
//!
//! Shaken target (`shake`: straight runs with abrupt reversals every 5–25
//! frames, at 0.6 and 1.2 rad/s, seeds 0 and 1, and seed 7 at 1.2 rad/s):
//! at least 95 % of the 300
//! frames are reported tracking within 5 px of the truth (mean visible-vertex
//! error), and at most 1 % are reported tracking more than 5 px off; on the
//! CPU backend, and at 1.2 rad/s, seed 0 on the GPU backend too. Without
//! the reversal hypotheses (the paper's motion model alone) the 1.2 rad/s
//! case holds fewer than 95 % of the frames. On two held-out shaken
//! sequences (seed 32 at 0.6 rad/s, seed 31 at 1.2 rad/s) no frame at all
//! is reported tracking more than 5 px off; on a third (seed 38 at
//! 1.2 rad/s) none either, a frame whose fit stands out less than its
//! prediction being reported `lost` for that reason.

use crate::common;

use pipetrack::backend::{CpuBackend, EarlyVision, GpuBackend};
use pipetrack::cli::score::score;
use pipetrack::io::formats::{FrameResult, Status};
use pipetrack::synth::target3dof::{Target3dofOptions, render_target3dof};
use pipetrack::track::{BlueParams, BlueTracker};

struct Case {
    speed: f64,
    occlude: f64,
    /// Fewest frames of the 300 reported tracking.
    min_tracked: usize,
}

const CASES: [Case; 3] = [
    Case { speed: 0.3, occlude: 0.0, min_tracked: 300 },
    Case { speed: 1.2, occlude: 0.0, min_tracked: 300 },
    Case { speed: 1.2, occlude: 0.3, min_tracked: 297 },
];

/// Longest run of lost frames allowed.
const MAX_LOST_RUN: usize = 3;

/// Track the case on `backend`; assert the acceptance criteria.
fn check(case: &Case, backend: &mut dyn EarlyVision, backend_name: &str) {
    let opts =
        Target3dofOptions { frames: 300, speed: case.speed, occlude: case.occlude, ..Target3dofOptions::default() };
    let seq = render_target3dof(&opts).expect("render target3dof");
    let mut tracker =
        BlueTracker::new(seq.camera, seq.model.clone(), seq.init.clone(), BlueParams::default()).expect("blue tracker");
    let size = (seq.camera.width as usize, seq.camera.height as usize);
    let (results, lost) = common::track_lost(&mut tracker, backend, seq.frames.iter().cloned(), size);
    let s = score(&seq.truth, &results).expect("score");
    let stats = s.stats.expect("scored frames");
    let mut worst = s.frame_errors.clone();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1));
    let worst: Vec<String> = worst.iter().take(5).map(|(f, e)| format!("{f}: {e:.2} px")).collect();
    let label = format!("{backend_name}, {} rad/s, occlude {}", case.speed, case.occlude);
    eprintln!(
        "{label}: {} of {} frames tracked, mean {:.3} px, max {:.3} px",
        s.tracked, s.frames, stats.mean, stats.max
    );
    let longest_loss = results.split(|r| r.status == Status::Tracking).map(<[FrameResult]>::len).max().unwrap_or(0);
    assert!(
        s.tracked >= case.min_tracked && longest_loss <= MAX_LOST_RUN,
        "{label}: {} of 300 frames tracked (at least {}), longest loss {longest_loss} frames; lost: {}",
        s.tracked,
        case.min_tracked,
        lost.iter().take(10).cloned().collect::<Vec<_>>().join(", ")
    );
    assert_eq!(s.frame_errors.len(), s.tracked, "{label}: every tracking frame is scored");
    assert!(
        s.false_tracking_fraction() <= 0.01,
        "{label}: {} frames reported tracking more than {} px off: {:?}",
        s.false_tracking.len(),
        s.false_tracking_px,
        s.false_tracking
    );
    assert!(
        stats.mean <= 1.0,
        "{label}: mean vertex error {:.3} px > 1 px; worst frames {}",
        stats.mean,
        worst.join(", ")
    );
}

#[test]
fn blue_holds_target3dof_slow_cpu() {
    check(&CASES[0], &mut CpuBackend::new(), "cpu");
}

#[test]
fn blue_holds_target3dof_fast_cpu() {
    check(&CASES[1], &mut CpuBackend::new(), "cpu");
}

#[test]
fn blue_holds_target3dof_fast_occluded_cpu() {
    check(&CASES[2], &mut CpuBackend::new(), "cpu");
}

#[test]
fn blue_holds_target3dof_gpu() {
    let Some((ctx, _guard)) = common::gpu("blue_holds_target3dof_gpu") else {
        return;
    };
    for case in &CASES {
        check(case, &mut GpuBackend::new(ctx.clone()), "gpu");
    }
}

/// A shaken `target3dof` sequence (300 frames).
struct ShakeCase {
    speed: f64,
    seed: u64,
}

/// Seed 7 at 1.2 rad/s: after the reversal at frame 238 the fit around the
/// prediction passes the verification on clutter at 1.7 times the range;
/// the range check between consecutive tracked frames refuses it.
const SHAKE_CASES: [ShakeCase; 5] = [
    ShakeCase { speed: 0.6, seed: 0 },
    ShakeCase { speed: 0.6, seed: 1 },
    ShakeCase { speed: 1.2, seed: 0 },
    ShakeCase { speed: 1.2, seed: 1 },
    ShakeCase { speed: 1.2, seed: 7 },
];

/// Least fraction of the frames reported tracking within the false-tracking distance.
const MIN_SHAKEN_HELD: f64 = 0.95;

/// Track the shaken case on `backend`; assert its acceptance criteria and
/// return the frames reported tracking more than the false-tracking
/// distance off.
fn check_shaken(case: &ShakeCase, backend: &mut dyn EarlyVision, backend_name: &str) -> Vec<usize> {
    let opts = Target3dofOptions {
        frames: 300,
        seed: case.seed,
        speed: case.speed,
        shake: true,
        ..Target3dofOptions::default()
    };
    let seq = render_target3dof(&opts).expect("render target3dof");
    let mut tracker =
        BlueTracker::new(seq.camera, seq.model.clone(), seq.init.clone(), BlueParams::default()).expect("blue tracker");
    let size = (seq.camera.width as usize, seq.camera.height as usize);
    let (results, lost) = common::track_lost(&mut tracker, backend, seq.frames.iter().cloned(), size);
    let s = score(&seq.truth, &results).expect("score");
    let held = s.frame_errors.iter().filter(|(_, e)| *e <= s.false_tracking_px).count();
    let label = format!("{backend_name}, shaken at {} rad/s, seed {}", case.speed, case.seed);
    let mean = s.stats.map_or(f64::NAN, |st| st.mean);
    eprintln!(
        "{label}: {} of {} frames tracked, {held} within {} px, {} false, mean {mean:.3} px",
        s.tracked,
        s.frames,
        s.false_tracking_px,
        s.false_tracking.len()
    );
    assert!(
        held as f64 >= MIN_SHAKEN_HELD * s.frames as f64,
        "{label}: {held} of {} frames tracked within {} px (at least {MIN_SHAKEN_HELD} of them); lost: {}",
        s.frames,
        s.false_tracking_px,
        lost.iter().take(10).cloned().collect::<Vec<_>>().join(", ")
    );
    assert!(
        s.false_tracking_fraction() <= 0.01,
        "{label}: {} frames reported tracking more than {} px off: {:?}",
        s.false_tracking.len(),
        s.false_tracking_px,
        s.false_tracking
    );
    s.false_tracking
}

#[test]
fn blue_holds_shaken_target3dof_cpu() {
    for case in &SHAKE_CASES {
        check_shaken(case, &mut CpuBackend::new(), "cpu");
    }
}

#[test]
fn blue_holds_shaken_target3dof_gpu() {
    let Some((ctx, _guard)) = common::gpu("blue_holds_shaken_target3dof_gpu") else {
        return;
    };
    check_shaken(&SHAKE_CASES[2], &mut GpuBackend::new(ctx.clone()), "gpu");
}

/// Reversals after which the tracker once went wrong, on seeds the cases
/// above do not use. Seed 32 at 0.6 rad/s turns at frame 259; frame 260
/// found the turned target around the prediction, 20 px off it, but the
/// motion models went on with the motion before the turn, and frames
/// 261–263 fitted the model one face to the right of the target. Seed 31
/// at 1.2 rad/s turns at frame 247: the estimate around the prediction
/// fitted the bookshelf, and the turned-back hypothesis, which found the
/// target, lost to it because half its outline lay outside the window of
/// interest, where no edge pixel was listed (frames 247–248 false).
const REVERSAL_CASES: [ShakeCase; 2] = [ShakeCase { speed: 0.6, seed: 32 }, ShakeCase { speed: 1.2, seed: 31 }];

#[test]
fn blue_reports_no_false_frame_after_a_reversal_cpu() {
    for case in &REVERSAL_CASES {
        let false_frames = check_shaken(case, &mut CpuBackend::new(), "cpu");
        assert!(
            false_frames.is_empty(),
            "shaken at {} rad/s, seed {}: frames reported tracking off the target: {false_frames:?}",
            case.speed,
            case.seed
        );
    }
}

/// Seed 38 at 1.2 rad/s, frame 257: the fit around a prediction within
/// 1 px of the target put the model at 0.86 times its range, 5.3 px off,
/// where its outline stood out by 0.36 against the prediction's 0.63. The
/// frame is lost for that, and no frame is reported tracking off the target.
#[test]
fn blue_refuses_an_estimate_that_stands_out_less_than_its_prediction_cpu() {
    let opts = Target3dofOptions { frames: 300, speed: 1.2, shake: true, seed: 38, ..Target3dofOptions::default() };
    let seq = render_target3dof(&opts).expect("render target3dof");
    let mut tracker =
        BlueTracker::new(seq.camera, seq.model.clone(), seq.init.clone(), BlueParams::default()).expect("blue tracker");
    let size = (seq.camera.width as usize, seq.camera.height as usize);
    let (results, lost) = common::track_lost(&mut tracker, &mut CpuBackend::new(), seq.frames.iter().cloned(), size);
    let s = score(&seq.truth, &results).expect("score");
    eprintln!(
        "cpu, shaken at 1.2 rad/s, seed 38: {} of {} tracked, false {:?}, lost {lost:?}",
        s.tracked, s.frames, s.false_tracking
    );
    assert!(s.false_tracking.is_empty(), "frames reported tracking off the target: {:?}", s.false_tracking);
    assert!(
        lost.iter().any(|why| why.contains("max_excess_below_prediction")),
        "no frame lost for standing out less than its prediction; lost: {lost:?}"
    );
    assert!(s.tracked >= 297, "{} of 300 frames tracked; lost: {lost:?}", s.tracked);
}

/// The paper's motion model alone (no reversal hypotheses) does not hold
/// the shaken target: each reversal puts the target twice a frame's
/// displacement from the prediction, and the criteria above fail.
#[test]
fn blue_without_reversal_hypotheses_loses_the_shaken_target_cpu() {
    let opts = Target3dofOptions { frames: 300, speed: 1.2, shake: true, ..Target3dofOptions::default() };
    let seq = render_target3dof(&opts).expect("render target3dof");
    let params = BlueParams { reversal_hypotheses: false, ..BlueParams::default() };
    let mut tracker = BlueTracker::new(seq.camera, seq.model.clone(), seq.init.clone(), params).expect("blue tracker");
    let size = (seq.camera.width as usize, seq.camera.height as usize);
    let (results, _) = common::track_lost(&mut tracker, &mut CpuBackend::new(), seq.frames.iter().cloned(), size);
    let s = score(&seq.truth, &results).expect("score");
    let held = s.frame_errors.iter().filter(|(_, e)| *e <= s.false_tracking_px).count();
    eprintln!("cpu, shaken at 1.2 rad/s, without reversal hypotheses: {held} of {} frames held", s.frames);
    assert!((held as f64) < MIN_SHAKEN_HELD * s.frames as f64, "{held} of {} frames held", s.frames);
}
