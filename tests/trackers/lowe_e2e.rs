//! End to end: the `lowe` tracker (paper 001) on rendered `box` and
//! `hinged-box` sequences (640×480, cluttered background, 300 frames),
//! through the real per-frame loop and a backend: slow (4 px/frame), fast
//! (20 px/frame of the fastest vertex, up to about 8° of rotation per frame
//! for the hinged box and 14° for the box) and occluded (a band hiding half
//! the visible edge length for stretches of 30–60 frames).
//!
//! Each case asserts the frames reported tracking, that none is more than
//! 5 px off (false tracking), the mean vertex error, and for the hinged box
//! the lid angle's error: its largest value and how many frames are more
//! than 2° off. The figures asserted are what the tracker achieves today
//! with a margin; they are printed with `--nocapture`, with the lid's
//! reported standard deviation on each frame more than 2° off (those are
//! frames where the image pins the lid down poorly: seen edge-on, or half
//! hidden).

use std::cell::Cell;

use crate::common;

use pipetrack::backend::{CpuBackend, EarlyVision, FrameRequest, GpuBackend};
use pipetrack::cli::score::score;
use pipetrack::early::Window;
use pipetrack::io::formats::{FrameResult, Status};
use pipetrack::synth::SyntheticSequence;
use pipetrack::synth::boxes::{BoxKind, BoxOptions, render_box};
use pipetrack::track::{FrameExtras, FrameOutcome, LoweParams, LoweTracker, Observations, Tracked, Tracker};

struct Case {
    kind: BoxKind,
    speed: f64,
    occlude: f64,
    /// Standard deviation of the added pixel noise, grey levels (`synth`'s
    /// default is 2).
    noise: f64,
    /// Seed of the scene's textures, clutter and noise.
    seed: u64,
    /// Fewest frames of the 300 reported tracking.
    min_tracked: usize,
    /// Most frames reported tracking more than 5 px off.
    max_false: usize,
    /// Largest mean vertex error over the tracking frames, px.
    max_mean_px: f64,
    /// Most frames whose lid angle is more than 2° off (hinged box).
    max_lid_frames_over_2deg: usize,
    /// Largest lid angle error, degrees (hinged box).
    max_lid_deg: f64,
    /// `LoweParams::ambiguous_carry_ratio` (the other parameters'
    /// defaults).
    carry_ratio: f64,
    /// `LoweParams::confident_window_doublings`.
    window_doublings: usize,
}

const BOX_SLOW: Case = Case {
    kind: BoxKind::Rigid,
    speed: 4.0,
    occlude: 0.0,
    noise: 2.0,
    seed: 0,
    min_tracked: 300,
    max_false: 0,
    max_mean_px: 1.0,
    max_lid_frames_over_2deg: 0,
    max_lid_deg: 0.0,
    carry_ratio: 0.0,
    window_doublings: 0,
};
const BOX_FAST: Case = Case { speed: 20.0, ..BOX_SLOW };
const BOX_OCCLUDED: Case = Case { occlude: 0.5, ..BOX_SLOW };
/// With the contrast memory (`remember_contrast`), no frame of the slow
/// hinged box has the lid more than 2° off (2 without: frames 233 and 234,
/// where a stripe of the background beside the lid's side joined it), and
/// the mean vertex error is 0.141 px (0.200 without).
const HINGED_SLOW: Case =
    Case { kind: BoxKind::Hinged, max_mean_px: 0.17, max_lid_frames_over_2deg: 0, max_lid_deg: 2.0, ..BOX_SLOW };
/// At 20 px/frame the lid stays within 2° on every frame: on frame 104
/// its 1 cm front, 2–3 px wide, showed one line, taken by the wrong one of
/// its two edges (2.1° off) until a swap with a clearly closer fit is kept
/// (`swap_residual_ratio`).
const HINGED_FAST: Case = Case { speed: 20.0, max_mean_px: 1.0, ..HINGED_SLOW };
/// Beyond the goal's 20 px/frame: the box turns up to ≈ 17° per frame, the
/// hinged box ≈ 10°; at least 95 % of the frames tracking, at most 1 % of
/// them more than 5 px off.
const BOX_25: Case = Case { speed: 25.0, min_tracked: 285, max_false: 3, max_mean_px: 1.0, ..BOX_SLOW };
const HINGED_25: Case = Case {
    speed: 25.0,
    min_tracked: 285,
    max_false: 3,
    max_mean_px: 1.0,
    max_lid_frames_over_2deg: 300,
    max_lid_deg: 180.0,
    ..HINGED_SLOW
};
/// The fastest motion `synth` makes (the box turns up to ≈ 20° per frame,
/// with abrupt reversals): at most 1 % of the frames more than 5 px off;
/// frames that lose the box as it slips out of reach are `lost`, not wrong,
/// and the whole-image search finds it again (box seeds 0–2 hold every
/// frame; before the search from slower predictions seed 1 was lost four
/// times and held 291).
const BOX_30: Case = Case { speed: 30.0, min_tracked: 285, max_false: 3, max_mean_px: 1.0, ..BOX_SLOW };
const HINGED_30: Case = Case { seed: 2, min_tracked: 270, ..Case { speed: 30.0, ..HINGED_25 } };
/// Half the edges hidden at 20 px/frame: at most 1 % of the frames more
/// than 5 px off (seed 0 loses the box at frame 77 and finds it again at a
/// remembered view).
const HINGED_OCCLUDED_FAST: Case = Case { speed: 20.0, occlude: 0.5, seed: 1, min_tracked: 275, ..HINGED_25 };
/// The box half hidden at 10 px/frame: frames 286–292 of seed 0 were
/// fitted to the wrong edges on 5–7 matches at 1.5–2.2 px residual and
/// reported tracking; a loose fit on few matches is no longer verified.
const BOX_OCCLUDED_10: Case = Case { speed: 10.0, occlude: 0.5, min_tracked: 295, max_false: 3, ..BOX_SLOW };
/// Seed 9: lost behind the occluder, the box was taken at frames 65, 73,
/// 80 and 82 on a dark rectangle of the background 106–141 px away, fitted
/// as the box seen face on with the rotation's σ 3.1–4.8° (9 frames
/// tracking off target). A re-acquisition must now fix the rotation.
const BOX_OCCLUDED_10_SEED_9: Case = Case { seed: 9, min_tracked: 250, ..BOX_OCCLUDED_10 };
/// Half the edges hidden: 4 frames with the lid more than 2° off and a
/// mean vertex error of 0.237 px (7 and 0.291 px without the contrast
/// memory; 13 frames with a step from an unmeasured lid extrapolated,
/// frames 245–255 behind the band).
const HINGED_OCCLUDED: Case =
    Case { occlude: 0.5, max_mean_px: 0.27, max_lid_frames_over_2deg: 4, max_lid_deg: 5.0, ..HINGED_SLOW };

/// The scene of `case`.
fn render(case: &Case) -> SyntheticSequence {
    let opts = BoxOptions {
        kind: case.kind,
        speed: case.speed,
        occlude: case.occlude,
        noise_sigma: case.noise,
        seed: case.seed,
        ..BoxOptions::default()
    };
    render_box(&opts).expect("render the box scene")
}

/// `seq` tracked by lowe with `params` on `backend`: each frame's result,
/// and the lost frames with their reasons.
fn track(
    seq: &SyntheticSequence,
    params: LoweParams,
    backend: &mut dyn EarlyVision,
) -> (Vec<FrameResult>, Vec<String>) {
    let mut tracker = LoweTracker::new(seq.camera, &seq.model, &seq.init, params).expect("lowe tracker");
    let size = (seq.camera.width as usize, seq.camera.height as usize);
    common::track_lost(&mut tracker, backend, seq.frames.iter().cloned(), size)
}

/// [`check`] each of `cases` on the CPU backend.
fn check_each_cpu(cases: &[Case]) {
    for case in cases {
        check(case, &mut CpuBackend::new(), "cpu");
    }
}

/// [`check`] each of `cases` on the CPU backend, then, where there is a GPU
/// adapter, on the GPU backend (the scene rendered once for both), and
/// assert that both give the same statuses and corners. `test` names the
/// test in the message of a missing adapter.
fn check_on_both_backends(test: &str, cases: &[Case]) {
    for case in cases {
        let seq = render(case);
        let cpu = check_scene(case, &seq, &mut CpuBackend::new(), "cpu");
        // The GPU tests take turns: the adapter is held for the GPU run only.
        let Some((ctx, _guard)) = common::gpu(test) else { continue };
        let gpu = check_scene(case, &seq, &mut GpuBackend::new(ctx.clone()), "gpu");
        assert_eq!(gpu.len(), cpu.len(), "frames tracked on the GPU and on the CPU");
        for (g, c) in gpu.iter().zip(&cpu) {
            assert_eq!(g.status, c.status, "frame {}", g.frame);
            for (a, b) in g.corners.iter().zip(&c.corners) {
                assert!((a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6, "frame {}: {a:?} vs {b:?}", g.frame);
            }
        }
    }
}

/// Track `case` on `backend` and assert its figures.
fn check(case: &Case, backend: &mut dyn EarlyVision, backend_name: &str) {
    check_scene(case, &render(case), backend, backend_name);
}

/// [`check`] on `seq`, the scene of `case` already rendered; the results.
fn check_scene(
    case: &Case,
    seq: &SyntheticSequence,
    backend: &mut dyn EarlyVision,
    backend_name: &str,
) -> Vec<FrameResult> {
    let params = LoweParams {
        ambiguous_carry_ratio: case.carry_ratio,
        confident_window_doublings: case.window_doublings,
        ..LoweParams::default()
    };
    let (results, lost) = track(seq, params, backend);
    let s = score(&seq.truth, &results).expect("score");
    let stats = s.stats.expect("scored frames");
    let lid_errors: Vec<(usize, f64)> = results
        .iter()
        .zip(&seq.truth)
        .filter_map(|(r, t)| Some((r.frame, (r.params.as_ref()?.first()? - t.params.first()?).abs().to_degrees())))
        .collect();
    let lid_over = lid_errors.iter().filter(|(_, e)| *e > 2.0).count();
    let lid_max = lid_errors.iter().map(|(_, e)| *e).fold(0.0, f64::max);
    // The lid is the seventh parameter: its variance is the covariance's
    // diagonal entry 6 of 7.
    let lid_sigma = |frame: usize| {
        results[frame].covariance.as_ref().and_then(|c| c.get(6 * 7 + 6)).map_or(f64::NAN, |v| v.sqrt().to_degrees())
    };
    let over: Vec<String> = lid_errors
        .iter()
        .filter(|(_, e)| *e > 2.0)
        .map(|&(f, e)| format!("{f}: {e:.1}° (σ {:.1}°)", lid_sigma(f)))
        .collect();
    let label = format!(
        "{backend_name}, {}, {} px/frame, occlude {}, noise {}, seed {}{}",
        case.kind.name(),
        case.speed,
        case.occlude,
        case.noise,
        case.seed,
        if case.carry_ratio > 0.0 { format!(", rivals carried from {}", case.carry_ratio) } else { String::new() }
    );
    eprintln!(
        "{label}: {} of {} frames tracked, mean {:.3} px, max {:.3} px, false tracking {}; lid: {lid_over} frames > 2°, max {lid_max:.2}° [{}]",
        s.tracked,
        s.frames,
        stats.mean,
        stats.max,
        s.false_tracking.len(),
        over.join(", ")
    );
    assert!(
        s.tracked >= case.min_tracked,
        "{label}: {} of 300 frames tracked (at least {}); lost: {}",
        s.tracked,
        case.min_tracked,
        lost.iter().take(10).cloned().collect::<Vec<_>>().join(", ")
    );
    assert!(
        s.false_tracking.len() <= case.max_false,
        "{label}: frames tracking more than 5 px off: {:?}",
        s.false_tracking
    );
    assert!(stats.mean <= case.max_mean_px, "{label}: mean vertex error {:.3} px", stats.mean);
    if case.kind == BoxKind::Hinged {
        assert!(
            lid_over <= case.max_lid_frames_over_2deg && lid_max <= case.max_lid_deg,
            "{label}: lid angle more than 2° off on {lid_over} frames, at most {lid_max:.2}°"
        );
    }
    results
}

/// The acceptance scenes hold on both backends; the GPU's statuses and
/// corners are the CPU's (the early-vision stages agree, so do the
/// features).
#[test]
fn lowe_holds_box_slow_fast_and_occluded_on_both_backends() {
    check_on_both_backends(
        "lowe_holds_box_slow_fast_and_occluded_on_both_backends",
        &[BOX_SLOW, BOX_FAST, BOX_OCCLUDED],
    );
}

/// With the window sized for the widest range on every frame
/// (`confident_window_doublings = 2`, twice the time per frame), the six
/// acceptance scenes meet the same bounds.
#[test]
fn lowe_holds_the_acceptance_scenes_with_the_widest_window_cpu() {
    let widest = |case: Case| Case { window_doublings: LoweParams::default().range_doublings, ..case };
    check_each_cpu(&[BOX_SLOW, BOX_FAST, BOX_OCCLUDED, HINGED_SLOW, HINGED_FAST, HINGED_OCCLUDED].map(widest));
}

#[test]
fn lowe_holds_box_half_hidden_at_10_px_per_frame_cpu() {
    check_each_cpu(&[BOX_OCCLUDED_10, BOX_OCCLUDED_10_SEED_9]);
}

#[test]
fn lowe_holds_hinged_box_slow_on_both_backends() {
    check_on_both_backends("lowe_holds_hinged_box_slow_on_both_backends", &[HINGED_SLOW]);
}

#[test]
fn lowe_holds_hinged_box_fast_on_both_backends() {
    check_on_both_backends("lowe_holds_hinged_box_fast_on_both_backends", &[HINGED_FAST]);
}

#[test]
fn lowe_holds_hinged_box_occluded_on_both_backends() {
    check_on_both_backends("lowe_holds_hinged_box_occluded_on_both_backends", &[HINGED_OCCLUDED]);
}

#[test]
fn lowe_holds_25_px_per_frame_without_false_tracking_cpu() {
    check_each_cpu(&[BOX_25, Case { seed: 2, ..BOX_25 }, HINGED_25, Case { seed: 1, ..HINGED_25 }]);
}

/// Seed 5: frames 14, 60, 106, 243, 268 and 289 began losses after abrupt
/// reversals, each a doubled range's solution 8–17 px off with 27–52 % of
/// its outline supported against 76–94 % a frame before, reported tracking.
/// A widened range's solution now needs 0.7 of the last frame's support.
const BOX_30_SEED_5: Case = Case { seed: 5, min_tracked: 270, ..BOX_30 };

#[test]
fn lowe_at_30_px_per_frame_has_no_more_than_1_percent_false_tracking_cpu() {
    check_each_cpu(&[BOX_30, Case { seed: 1, ..BOX_30 }, BOX_30_SEED_5, HINGED_30]);
}

/// The box half hidden at 10 px/frame, seed 8: with its sides behind the
/// band, a solution of the twice-doubled range whose matches fixed the
/// rotation to σ 7.0° only slid the box 19–47 px along the band's edges,
/// and frames 74–77 were reported tracking (5 false frames in all). While
/// tracking, a solution's rotation σ is at most twice the prior's, which
/// leaves one frame 6 px off and 229 frames tracking.
const BOX_OCCLUDED_10_SEED_8: Case = Case { seed: 8, min_tracked: 220, ..BOX_OCCLUDED_10 };

#[test]
fn lowe_does_not_verify_a_pose_its_matches_leave_loose_cpu() {
    check(&BOX_OCCLUDED_10_SEED_8, &mut CpuBackend::new(), "cpu");
}

/// The hinged box at 30 px/frame, seed 6: on frames 77–81 the lid, open
/// 14–43°, was taken for the lid shut on a box turned about the hinge
/// (the model 9–26 px off, a third or less of the box's own outline
/// supported) and reported tracking (6 false frames in all). Step 9 also
/// tries the lid's grid values with the lid held and the box swung about
/// the hinge, which leaves 2 false frames and 290 tracking.
const HINGED_30_SEED_6: Case = Case { seed: 6, min_tracked: 285, ..HINGED_30 };

#[test]
fn lowe_swings_the_box_about_the_hinge_under_a_well_fitted_lid_cpu() {
    check(&HINGED_30_SEED_6, &mut CpuBackend::new(), "cpu");
}

/// The hinged box at 30 px/frame seed 10: the lid swings by up to 86° in
/// ten frames, and searched with the lid at its last verified angle, the
/// whole image gave the box back only where the lid came near that angle
/// again (233 of 300 frames, lost for 33 and 34 frames). Searched with the
/// best supported lid angle at each position of the grid, it holds 283
/// without the contrast memory and 254 with it (lost on frames 72–83 and
/// 143–176, found again each time).
const HINGED_30_SEED_10: Case = Case { seed: 10, min_tracked: 250, ..HINGED_30 };

#[test]
fn lowe_reacquires_the_hinged_box_with_its_lid_moved_cpu() {
    check(&HINGED_30_SEED_10, &mut CpuBackend::new(), "cpu");
}

/// Abrupt reversals, where the extrapolated prediction lies twice the last
/// step from the object: searched at the extrapolation alone, the hinged
/// box at 25 px/frame seed 8 held 235 of its frames and the box at
/// 30 px/frame seed 12 held 260 (one of them 14 px off); searched again
/// from slower predictions (`search_slower_predictions`), each holds every
/// frame but frame 40 of the hinged box, reported ambiguous (step 10: a
/// rival 13.6 px away with 0.95 of the answer's support; with the contrast
/// memory), none more than 5 px off.
const HINGED_25_SEED_8: Case = Case { seed: 8, min_tracked: 299, max_false: 0, ..HINGED_25 };
const BOX_30_SEED_12: Case = Case { seed: 12, min_tracked: 300, max_false: 0, ..BOX_30 };

#[test]
fn lowe_holds_abrupt_reversals_by_searching_from_slower_predictions_cpu() {
    check_each_cpu(&[HINGED_25_SEED_8, BOX_30_SEED_12]);
}

/// The second look from slower predictions is made at a drop of support,
/// not on every frame of an object whose outline is steadily part
/// supported: on the box half hidden at 4 px/frame (less than 80 % of the
/// outline supported on 161 of the 300 frames, down to 34 %) it costs at
/// most a fifth more search branches per frame than no second look, and
/// the frames tracked are the same. Made whenever no solution was
/// confident, it cost 2.6 times as many (6.44 against 2.47 per frame).
#[test]
fn lowe_searches_from_slower_predictions_only_at_a_drop_of_support_cpu() {
    let seq = render(&BOX_OCCLUDED);
    let run = |search_slower_predictions: bool| {
        let params = LoweParams { search_slower_predictions, ..LoweParams::default() };
        let (results, _) = track(&seq, params, &mut CpuBackend::new());
        let tracked = results.iter().filter(|r| r.status == Status::Tracking).count();
        let branches: usize = results.iter().map(|r| r.search_branches.expect("lowe reports its branches")).sum();
        (tracked, branches as f64 / results.len() as f64)
    };
    let (tracked_on, branches_on) = run(true);
    let (tracked_off, branches_off) = run(false);
    eprintln!(
        "box half hidden, 4 px/frame: {branches_on:.2} branches per frame with the second look, {branches_off:.2} without; {tracked_on} and {tracked_off} frames tracked"
    );
    assert_eq!(tracked_on, tracked_off, "frames tracked with and without the second look");
    assert!(
        branches_on <= 1.2 * branches_off,
        "{branches_on:.2} search branches per frame with the second look against {branches_off:.2} without"
    );
}

/// A tracker that adds up the pixels of every window of interest its
/// frames ask early vision for (a widened frame asks twice).
struct WindowPixels<T> {
    inner: T,
    pixels: Cell<usize>,
}

impl<T: Tracker> Tracker for WindowPixels<T> {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn window_of_interest(&self, width: usize, height: usize) -> Window {
        self.inner.window_of_interest(width, height)
    }
    fn request(&self, width: usize, height: usize) -> FrameRequest {
        self.pixels.set(self.pixels.get() + self.inner.window_of_interest(width, height).area());
        self.inner.request(width, height)
    }
    fn track(&mut self, frame: usize, observations: &Observations<'_>) -> FrameOutcome {
        self.inner.track(frame, observations)
    }
    fn track_or_widen(&mut self, frame: usize, observations: &Observations<'_>) -> Tracked {
        self.inner.track_or_widen(frame, observations)
    }
    fn accept_frame_size(&mut self, width: usize, height: usize) -> std::result::Result<(), String> {
        self.inner.accept_frame_size(width, height)
    }
    fn extras(&self) -> FrameExtras {
        self.inner.extras()
    }
}

/// The box half hidden at 4 px/frame: behind the band its outline is 36–47 %
/// supported, short of `confident_support`, so those frames search the
/// widest window. With the steady bar (`steady_support_ratio` 0.9, off by
/// default; the tracker's module doc, step 6) they search a window
/// narrowed as after a confident frame, with the same frames tracked and
/// none false.
#[test]
fn lowe_narrows_the_window_of_a_steadily_part_hidden_box_cpu() {
    let seq = render(&BOX_OCCLUDED);
    let size = (seq.camera.width as usize, seq.camera.height as usize);
    let run = |steady_support_ratio: f64| {
        let params = LoweParams { steady_support_ratio, ..LoweParams::default() };
        let inner = LoweTracker::new(seq.camera, &seq.model, &seq.init, params).expect("lowe tracker");
        let mut tracker = WindowPixels { inner, pixels: Cell::new(0) };
        let (results, _) = common::track_lost(&mut tracker, &mut CpuBackend::new(), seq.frames.iter().cloned(), size);
        let s = score(&seq.truth, &results).expect("score");
        (s.tracked, s.false_tracking.len(), tracker.pixels.get() as f64 / results.len() as f64)
    };
    let (tracked_on, false_on, pixels_on) = run(0.9);
    let (tracked_off, false_off, pixels_off) = run(0.0);
    eprintln!(
        "box half hidden, 4 px/frame: windows of {pixels_on:.0} pixels per frame with the steady bar, \
         {pixels_off:.0} without; {tracked_on} and {tracked_off} frames tracked, {false_on} and {false_off} false"
    );
    assert!(tracked_on >= tracked_off, "{tracked_on} frames tracked with the steady bar, {tracked_off} without");
    assert_eq!(false_on, 0, "false frames with the steady bar");
    assert!(
        pixels_on <= 0.7 * pixels_off,
        "{pixels_on:.0} window pixels per frame with the steady bar against {pixels_off:.0} without"
    );
}

/// Half the edges hidden at 30 px/frame, seed 1: frames 121–123 lost the
/// lid as it opened behind the occluder; a search from the lid standing
/// open found the box's outline better supported with the lid at its
/// limit, where no match constrained it (σ = its prior), and replaced the
/// fit: 20–35 px off. An unmeasured joint no longer wins that way.
const HINGED_OCCLUDED_30: Case = Case { speed: 30.0, occlude: 0.5, seed: 1, min_tracked: 265, ..HINGED_25 };
/// Seed 0: at frame 247 the lid, opening again behind the occluder, folded
/// onto the box's rim, 14° from its prediction; the search from the lid
/// open, 6° from the prediction, was held to the margin of a 20° jump
/// from the fold, and the fold stayed for five frames, 7–22 px off. The
/// margin now counts from the prediction when that is nearer. Frames 47
/// and 50, their lid 9.5° and 13.8° off, are ambiguous (step 10) and lost
/// (and frame 45 with the contrast memory).
/// Lost behind the band from frame 85, the box is found again at frame 98
/// (at 107 without the contrast memory), and lost again from 279 to the
/// end (without it only frame 280): 260 frames tracking, one false (frame
/// 245; 271 and none without).
const HINGED_OCCLUDED_30_SEED_0: Case = Case { seed: 0, min_tracked: 255, ..HINGED_OCCLUDED_30 };

/// Half the edges hidden at 20 px/frame, seed 14: on frames 73–80 the
/// lid, opening from 15° to 53° behind the band, was held shut on the box's
/// rim, 7–32 px off, and reported tracking (8 false frames). On 74–80 the
/// search from the lid standing open gave a verified solution with as many
/// matches and about as much support: the answer is ambiguous, and such a
/// frame is now reported lost (the tracker's module doc, step 10).
const HINGED_OCCLUDED_FAST_SEED_14: Case = Case { seed: 14, min_tracked: 270, ..HINGED_OCCLUDED_FAST };
/// The box half hidden at 20 px/frame, seed 25: frames 191, 193 and 194,
/// fitted 8–11 px off as the box turned behind the band, each had another
/// verified solution within 4 px of the box, with more support and matches
/// (5 false frames before, 2 now).
const BOX_OCCLUDED_FAST_SEED_25: Case =
    Case { speed: 20.0, occlude: 0.5, seed: 25, min_tracked: 265, max_false: 3, ..BOX_SLOW };

#[test]
fn lowe_does_not_claim_an_ambiguous_answer_cpu() {
    check_each_cpu(&[HINGED_OCCLUDED_FAST_SEED_14, BOX_OCCLUDED_FAST_SEED_25]);
}

/// After an ambiguous answer the answers that follow are claimed again
/// only once as well supported as before it, or after a run of unambiguous
/// ones (the tracker's module doc, step 11), and only their statuses
/// change. Half the edges hidden at 10 px/frame, seed 0: behind the band,
/// ambiguous answers recur from frame 47 to 64, and the answers on 57–60
/// and 62–63, with 37–45 % of their outline supported where 48 % (0.9 of
/// frame 46's) claims, are reported lost; frame 65 reaches it. Ambiguous
/// again on 240–243, the answers of 244–250 have 44–49 % where 79 % claims,
/// and frame 251, the eighth unambiguous answer, is claimed.
#[test]
fn lowe_claims_the_answers_after_an_ambiguous_one_only_when_supported_again_cpu() {
    let seq = render(&Case { speed: 10.0, occlude: 0.5, seed: 0, ..HINGED_25 });
    let (claimed, _) = track(&seq, LoweParams::default(), &mut CpuBackend::new());
    let every = LoweParams { reclaim_support_ratio: 0.0, ..LoweParams::default() };
    let (all, _) = track(&seq, every, &mut CpuBackend::new());
    let is = |r: &FrameResult, what: &str| r.lost_reason.as_deref().is_some_and(|why| why.starts_with(what));
    let mut waiting = false;
    let mut refused = Vec::new();
    for (c, a) in claimed.iter().zip(&all) {
        assert_eq!((&c.corners, &c.pose, &c.params, &c.covariance), (&a.corners, &a.pose, &a.params, &a.covariance));
        if is(c, "after an ambiguous answer") {
            assert!(waiting, "frame {}: refused with no ambiguous answer before it", c.frame);
            assert_eq!(a.status, Status::Tracking, "frame {}: claimed without the rule", c.frame);
            refused.push(c.frame);
        } else {
            assert_eq!(c.status, a.status, "frame {}", c.frame);
        }
        if is(c, "ambiguous") {
            waiting = true;
        } else if c.status == Status::Tracking || a.lost_reason.is_some() {
            waiting = false;
        }
    }
    let expected: Vec<usize> = [57, 58, 59, 60, 62, 63].into_iter().chain(244..=250).collect();
    assert_eq!(refused, expected, "frames refused");
    for (frame, how) in [(65, "as well supported"), (251, "after 8 unambiguous answers")] {
        assert_eq!(claimed[frame].status, Status::Tracking, "frame {frame}: claimed again {how}");
    }
}

/// The contrast memory learns only from frames with at least 0.6 of the
/// outline supported (`remember_contrast_min_support`). Half the edges
/// hidden at 10 px/frame, seed 1: learning from every verified frame, the
/// answer slid onto the band's long edges, verified on frames 128–134
/// (7 false frames). At 20 px/frame, seed 7: at frame 239, under the band,
/// a lid edge took a line 10 px from its own and the memory learnt that
/// line's contrast (4 false frames). Both now have none. Seed 1 tracks
/// 289 frames: frames 124–130, after the ambiguous frames 122–123, are not
/// claimed (the tracker's module doc, step 11; 0.3–3.8 px off with 25–42 %
/// of their outline supported where 53 % claims; 296 frames before).
const HINGED_OCCLUDED_10_SEED_1: Case =
    Case { speed: 10.0, occlude: 0.5, seed: 1, min_tracked: 285, max_false: 0, ..HINGED_25 };
const HINGED_OCCLUDED_FAST_SEED_7: Case = Case { seed: 7, min_tracked: 275, max_false: 0, ..HINGED_OCCLUDED_FAST };
/// A rival carried in the answer's place (`ambiguous_carry_ratio` 1.2, off
/// by default): the box half hidden at 20 px/frame, seed 1, had at frame
/// 129 a rival 13.6 px away with 1.27 times the answer's supported outline;
/// the answer carried on, frame 130 was tracking 5 px off or more (279
/// frames tracking); the rival carried, 284 and none false.
const BOX_OCCLUDED_FAST_SEED_1_CARRIED: Case =
    Case { speed: 20.0, occlude: 0.5, seed: 1, min_tracked: 280, max_false: 0, carry_ratio: 1.2, ..BOX_SLOW };

#[test]
fn lowe_contrast_memory_learns_only_from_well_supported_frames_cpu() {
    check_each_cpu(&[HINGED_OCCLUDED_10_SEED_1, HINGED_OCCLUDED_FAST_SEED_7]);
}

#[test]
fn lowe_carries_a_clearly_better_supported_rival_cpu() {
    check(&BOX_OCCLUDED_FAST_SEED_1_CARRIED, &mut CpuBackend::new(), "cpu");
}

#[test]
fn lowe_hinged_box_occluded_at_20_and_30_px_per_frame_has_no_more_than_1_percent_false_tracking_cpu() {
    let seed_0 = Case { seed: 0, ..HINGED_OCCLUDED_FAST };
    check_each_cpu(&[HINGED_OCCLUDED_FAST, seed_0, HINGED_OCCLUDED_30, HINGED_OCCLUDED_30_SEED_0]);
}

/// Noise σ 8 at 20 px/frame, seed 0: at frames 26 and 276 the lid,
/// closing and seen nearly edge on, was fitted 2° off with 28 matches; a
/// search from the lid standing open matched 18 segments, some on clutter,
/// with more of its outline supported, and replaced the fit; the velocity
/// of that jump carried the lid to its limit, 14–37 px off for 15 frames
/// while tracking. Another joint value now needs more matches as well.
const HINGED_NOISY: Case = Case { speed: 20.0, noise: 8.0, min_tracked: 295, ..HINGED_25 };

/// Noise σ 8 at 20 px/frame, seed 6: at frames 280–283 the first range
/// fitted the closing lid 11–17° off (8–11 px, 47–56 % of the outline
/// supported) while the doubled range had it within 3° (72–83 %, more
/// matches); a wider range's solution that clears the re-acquisition bar
/// with more support and matches now replaces the first (4 false frames
/// before).
const HINGED_NOISY_SEED_6: Case = Case { seed: 6, ..HINGED_NOISY };

#[test]
fn lowe_hinged_box_with_noise_has_no_more_than_1_percent_false_tracking_cpu() {
    check_each_cpu(&[HINGED_NOISY, HINGED_NOISY_SEED_6]);
}

/// The box cut by the image border: frames of `box` at 4 px/frame cropped
/// to the columns left of 30 % of the box's width on frame 0 (the camera
/// keeps its intrinsics, the image is narrower), so that most of the box is
/// outside the image on every frame. The model edges beyond the border are
/// not part of the visible model, and the matches of the edges the border
/// cuts count: the tracker holds the box on every frame. Counting the
/// edges beyond the border, it held 2 of the 80 frames; clipped, but with
/// matches naming the clipped piece (which moves with the pose), 5.
#[test]
fn lowe_holds_a_box_cut_by_the_image_border_cpu() {
    use pipetrack::image::GrayImage;
    use pipetrack::io::formats::Visibility;
    let opts = BoxOptions { kind: BoxKind::Rigid, speed: 4.0, frames: 80, ..BoxOptions::default() };
    let seq = render_box(&opts).expect("render the box scene");
    let first = &seq.truth[0].corners;
    let (left, right) = first.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, r), c| (l.min(c[0]), r.max(c[0])));
    let width = (left + 0.3 * (right - left)).round() as usize;
    let height = seq.camera.height as usize;
    let crop = |frame: &GrayImage| {
        let mut data = Vec::with_capacity(width * height);
        for y in 0..height {
            data.extend_from_slice(&frame.row(y)[..width]);
        }
        GrayImage::from_vec(width, height, data).expect("cropped frame")
    };
    let frames: Vec<GrayImage> = seq.frames.iter().map(crop).collect();
    let mut camera = seq.camera;
    camera.width = width as u32;
    let mut cut_frames = 0;
    let truth: Vec<_> = seq
        .truth
        .iter()
        .map(|t| {
            let mut t = t.clone();
            let seen: Vec<bool> = t
                .corners
                .iter()
                .enumerate()
                .map(|(i, c)| t.visible.vertex(i) && c[0] >= 0.0 && c[0] <= width as f64 - 1.0)
                .collect();
            cut_frames += usize::from(t.corners.iter().any(|c| c[0] > width as f64 - 1.0));
            t.visible = Visibility::Vertices(seen);
            t
        })
        .collect();
    assert_eq!(cut_frames, 80, "the border cuts the box on {cut_frames} of 80 frames");
    let mut tracker = LoweTracker::new(camera, &seq.model, &seq.init, LoweParams::default()).expect("lowe tracker");
    let (results, _) = common::track_lost(&mut tracker, &mut CpuBackend::new(), frames, (width, height));
    let s = score(&truth, &results).expect("score");
    let stats = s.stats.expect("scored frames");
    println!(
        "box cut at x = {width} on {cut_frames} frames: {} of {} frames tracked, mean {:.3} px, max {:.3} px, false tracking {}",
        s.tracked,
        s.frames,
        stats.mean,
        stats.max,
        s.false_tracking.len()
    );
    assert!(s.tracked >= 78, "{} of 80 frames tracked", s.tracked);
    assert_eq!(s.false_tracking, Vec::<usize>::new(), "frames reported tracking more than 5 px off");
    assert!(stats.mean <= 1.0, "mean vertex error {:.3} px", stats.mean);
}

/// Step 2 of the tracker, with `confident_window_doublings = 0` (the
/// default): a frame verified with confident support at its first range
/// sizes the next window for the first range alone, with the same answers
/// as windows sized for the widest range; a lost frame (here a blank one)
/// sizes it for the widest again, and so does the frame that finds the
/// box at the doubled range after it.
#[test]
fn lowe_narrows_the_window_after_a_confident_frame_and_widens_it_after_a_loss_cpu() {
    use pipetrack::image::GrayImage;
    use pipetrack::io::formats::Status;
    use pipetrack::track::Tracker;
    use pipetrack::track::run::{AsFrame, track_step};
    const BLANK: usize = 20;
    let opts = BoxOptions { kind: BoxKind::Rigid, speed: 4.0, frames: 30, ..BoxOptions::default() };
    let mut seq = render_box(&opts).expect("render the box scene");
    let (width, height) = (seq.camera.width as usize, seq.camera.height as usize);
    seq.frames[BLANK] = GrayImage::from_vec(width, height, vec![128; width * height]).expect("blank frame");
    // Each frame's status, corners and the area of the next frame's window.
    let run = |params: LoweParams| {
        let mut tracker = LoweTracker::new(seq.camera, &seq.model, &seq.init, params).expect("lowe tracker");
        let mut backend = CpuBackend::new();
        backend.reset();
        let mut frames = Vec::new();
        for (i, frame) in seq.frames.iter().enumerate() {
            let (_, result) = track_step(&mut tracker, &mut backend, i, frame.as_frame()).expect("track");
            frames.push((result, tracker.window_of_interest(width, height).area()));
        }
        frames
    };
    let narrow = run(LoweParams::default());
    let wide =
        run(LoweParams { confident_window_doublings: LoweParams::default().range_doublings, ..LoweParams::default() });
    for ((n, n_area), (w, w_area)) in narrow.iter().zip(&wide) {
        let f = n.frame;
        assert_eq!(n.status, w.status, "frame {f}");
        assert_eq!(n.corners.len(), w.corners.len(), "frame {f}");
        for (a, b) in n.corners.iter().zip(&w.corners) {
            assert!((a[0] - b[0]).abs() < 0.05 && (a[1] - b[1]).abs() < 0.05, "frame {f}: {a:?} vs {b:?}");
        }
        let ratio = *n_area as f64 / *w_area as f64;
        if f == BLANK || f == BLANK + 1 {
            assert!(ratio > 0.95, "frame {f}: the window after it has {ratio:.2} of the widest's pixels");
        } else {
            assert_eq!(n.status, Status::Tracking, "frame {f}");
            assert!(ratio < 0.6, "frame {f}: the window after it has {ratio:.2} of the widest's pixels");
        }
    }
    assert_eq!(narrow[BLANK].0.status, Status::Lost, "the blank frame");
}

/// Step 2 where the motion turns round: the box at 20 px/frame played
/// forward, then backward from three frames before the last, so the
/// prediction at the turn lies four steps from the box, beyond the
/// narrowed window's first range.
/// There the tracker widens the window and searches the frame again: the
/// same statuses and corners as the widest window at every frame, and the
/// window widened on few frames besides the turn.
#[test]
fn lowe_widens_a_narrowed_window_where_the_motion_turns_cpu() {
    use pipetrack::io::formats::Status;
    use pipetrack::track::run::{AsFrame, track_step};
    use pipetrack::track::{Observations, Tracked, Tracker};
    const TURN: usize = 16;
    let opts = BoxOptions { kind: BoxKind::Rigid, speed: 20.0, frames: TURN, ..BoxOptions::default() };
    let mut seq = render_box(&opts).expect("render the box scene");
    let back: Vec<_> = seq.frames[TURN - 10..TURN - 3].iter().rev().cloned().collect();
    seq.frames.extend(back);
    let (width, height) = (seq.camera.width as usize, seq.camera.height as usize);
    let tracker = |params| LoweTracker::new(seq.camera, &seq.model, &seq.init, params).expect("lowe tracker");

    let mut wide = tracker(LoweParams {
        confident_window_doublings: LoweParams::default().range_doublings,
        ..LoweParams::default()
    });
    let mut backend = CpuBackend::new();
    backend.reset();
    let wide: Vec<_> = (seq.frames.iter().enumerate())
        .map(|(i, frame)| track_step(&mut wide, &mut backend, i, frame.as_frame()).expect("track").1)
        .collect();
    assert!(wide.iter().all(|r| r.status == Status::Tracking), "the widest window tracks every frame");

    // The per-frame loop by hand, to see which frames widen.
    let mut narrow = tracker(LoweParams::default());
    let mut backend = CpuBackend::new();
    backend.reset();
    let mut widened = Vec::new();
    for (i, frame) in seq.frames.iter().enumerate() {
        let features = backend.process(frame, &narrow.request(width, height)).expect("early vision");
        let outcome = match narrow.track_or_widen(i, &Observations::from(&features)) {
            Tracked::Outcome(outcome) => outcome,
            Tracked::Widened => {
                widened.push(i);
                let features = backend.process(frame, &narrow.request(width, height)).expect("early vision");
                narrow.track(i, &Observations::from(&features))
            }
        };
        let w = &wide[i];
        assert_eq!(outcome.status, w.status, "frame {i}");
        for (a, b) in outcome.corners.iter().zip(&w.corners) {
            assert!((a[0] - b[0]).abs() < 0.05 && (a[1] - b[1]).abs() < 0.05, "frame {i}: {a:?} vs {b:?}");
        }
    }
    assert!(widened.contains(&TURN), "the window widened at the turn: frames {widened:?}");
    assert!(widened.len() <= 2, "the window widened on frames {widened:?}");
}
