//! `tracking` is a claim the tracker checks: the trackers on synthetic
//! sequences whose object jumps, leaves the image and comes back, is hidden
//! for 20 frames, or is initialised far off. Per frame, the status is
//! asserted against what the image shows: lost within a few frames of the
//! evidence going, tracking again within a bound each test states of it
//! returning where the tracker can re-acquire, and never `tracking` more
//! than 5 px off (false tracking, [`pipetrack::cli::score`]). Every lost
//! frame's output line says why.
//!
//! The events are made from the rendered scenes: a hidden frame is a flat
//! grey image (the camera covered), a pan shifts the whole frame (and the
//! truth) sideways, a jump replaces the frames from then on by frames of a
//! later part of the sequence.

use crate::common;

use pipetrack::backend::{CpuBackend, EarlyVision, GpuBackend};
use pipetrack::cli::score::score;
use pipetrack::image::GrayImage;
use pipetrack::io::formats::{FrameResult, Status, Visibility};
use pipetrack::synth::SyntheticSequence;
use pipetrack::synth::boxes::{BoxOptions, render_box};
use pipetrack::synth::pendulum::{PendulumOptions, render_pendulum};
use pipetrack::synth::target3dof::{Target3dofOptions, render_target3dof};
use pipetrack::synth::textured_plane::{PlaneMotion, TexturedPlaneOptions};
use pipetrack::track::{
    BlueParams, BlueTracker, CondensationParams, CondensationTracker, FrameOutcome, LoweParams, LoweTracker,
    MotionEdgeParams, MotionEdgeTracker, Tracker,
};

/// Grey of a covered camera.
const COVER_GREY: u8 = 100;

fn pendulum() -> SyntheticSequence {
    render_pendulum(&PendulumOptions { frames: 200, speed: 3.9, ..PendulumOptions::default() }).expect("render")
}

fn target() -> SyntheticSequence {
    render_target3dof(&Target3dofOptions { frames: 150, speed: 0.3, ..Target3dofOptions::default() }).expect("render")
}

fn motion_edge(seq: &SyntheticSequence) -> Box<dyn Tracker> {
    Box::new(
        MotionEdgeTracker::new(seq.init.corners.clone(), seq.model.edges.clone(), MotionEdgeParams::default())
            .expect("tracker"),
    )
}

fn blue(seq: &SyntheticSequence) -> Box<dyn Tracker> {
    Box::new(BlueTracker::new(seq.camera, seq.model.clone(), seq.init.clone(), BlueParams::default()).expect("tracker"))
}

/// Frames `range` replaced by a flat grey image (grey and colour frames);
/// truth: nothing visible.
fn cover(seq: &mut SyntheticSequence, range: std::ops::Range<usize>) {
    for k in range {
        seq.frames[k].data_mut().fill(COVER_GREY);
        if let Some(rgb) = seq.rgb_frames.get_mut(k) {
            rgb.data_mut().fill([COVER_GREY; 3]);
        }
        seq.truth[k].visible = Visibility::Vertices(vec![false; seq.truth[k].corners.len()]);
    }
}

/// Frame k shifted right by `dx(k)` px (revealed columns flat grey), truth
/// corners with it, each vertex visible while inside the image.
fn pan(seq: &mut SyntheticSequence, dx: impl Fn(usize) -> i64) {
    let (w, h) = (seq.camera.width as usize, seq.camera.height as usize);
    for k in 0..seq.frames.len() {
        let d = dx(k);
        let old = seq.frames[k].clone();
        let mut new = GrayImage::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let src = x as i64 - d;
                new.data_mut()[y * w + x] =
                    if (0..w as i64).contains(&src) { old.data()[y * w + src as usize] } else { COVER_GREY };
            }
        }
        seq.frames[k] = new;
        let t = &mut seq.truth[k];
        for c in &mut t.corners {
            c[0] += d as f64;
        }
        let inside = t.corners.iter().map(|c| c[0] >= 0.0 && c[0] <= w as f64 - 1.0).collect();
        t.visible = Visibility::Vertices(inside);
    }
}

/// From frame `at` on, frame k shows frame k + `ahead` (the object jumps to
/// where it is `ahead` frames later); the sequence is cut to keep frames.
fn jump(seq: &mut SyntheticSequence, at: usize, ahead: usize) {
    let n = seq.frames.len() - ahead;
    for k in at..n {
        seq.frames[k] = seq.frames[k + ahead].clone();
        if k + ahead < seq.rgb_frames.len() {
            seq.rgb_frames[k] = seq.rgb_frames[k + ahead].clone();
        }
        seq.truth[k].corners = seq.truth[k + ahead].corners.clone();
        seq.truth[k].visible = seq.truth[k + ahead].visible.clone();
    }
    seq.frames.truncate(n);
    seq.rgb_frames.truncate(n);
    seq.truth.truncate(n);
}

/// Track `seq` on `backend` (its colour frames for a tracker that reads
/// colour); each frame's outcome and output line.
fn run(
    seq: &SyntheticSequence,
    mut tracker: Box<dyn Tracker>,
    backend: &mut dyn EarlyVision,
) -> Vec<(FrameOutcome, FrameResult)> {
    let size = (seq.camera.width as usize, seq.camera.height as usize);
    let mut out = Vec::new();
    let keep = |_: pipetrack::track::run::Frame<'_>, o: &FrameOutcome, r: &FrameResult| {
        out.push((o.clone(), r.clone()));
        Ok(())
    };
    let tracker = tracker.as_mut();
    if tracker.wants_colour() && !seq.rgb_frames.is_empty() {
        pipetrack::track::run::track_frames(tracker, backend, seq.rgb_frames.iter().cloned().map(Ok), size, keep)
    } else {
        pipetrack::track::run::track_frames(tracker, backend, seq.frames.iter().cloned().map(Ok), size, keep)
    }
    .expect("track");
    out
}

/// The status string of a run ('T' tracking, 'L' lost), one char per frame.
fn statuses(out: &[(FrameOutcome, FrameResult)]) -> String {
    out.iter().map(|(_, r)| if r.status == Status::Tracking { 'T' } else { 'L' }).collect()
}

/// Asserts no false tracking (> 5 px or nothing visible) and a reason on
/// every lost frame's output line (none on tracking ones); prints the run.
fn check_no_false_tracking(label: &str, seq: &SyntheticSequence, out: &[(FrameOutcome, FrameResult)]) -> String {
    let results: Vec<FrameResult> = out.iter().map(|(_, r)| r.clone()).collect();
    let s = score(&seq.truth, &results).expect("score");
    let st = statuses(out);
    println!("{label}: {st}");
    println!("{label}: {} of {} tracking, false tracking {:?}", s.tracked, s.frames, s.false_tracking);
    let why: Vec<String> = s
        .false_tracking
        .iter()
        .take(5)
        .map(|&f| format!("{f}: {:?}", s.frame_errors.iter().find(|e| e.0 == f)))
        .collect();
    assert!(s.false_tracking.is_empty(), "{label}: false tracking at {}", why.join(", "));
    for (_, r) in out {
        match r.status {
            Status::Lost => assert!(
                r.lost_reason.as_ref().is_some_and(|why| !why.is_empty()),
                "{label}: frame {} is lost without a reason in its output line",
                r.frame
            ),
            Status::Tracking => assert_eq!(r.lost_reason, None, "{label}: frame {} tracking", r.frame),
        }
    }
    st
}

/// First frame at or after `from` with status `want`.
fn first(st: &str, from: usize, want: char) -> Option<usize> {
    st[from..].find(want).map(|i| i + from)
}

fn reason(out: &[(FrameOutcome, FrameResult)], k: usize) -> String {
    out[k].0.diagnostics.lost_reason.clone().unwrap_or_default()
}

// ---------------------------------------------------------------------------
// motion-edge on the pendulum (256×242, 3.9 px/frame, rotating).

/// `seq` covered for `covered`, tracked by `tracker`: tracking before the
/// cover, lost throughout it, tracking again within 5 frames after it, and
/// holding the `what` from frame `held_from` on.
fn check_cover(
    label: &str,
    mut seq: SyntheticSequence,
    tracker: fn(&SyntheticSequence) -> Box<dyn Tracker>,
    backend: &mut dyn EarlyVision,
    covered: std::ops::Range<usize>,
    held_from: usize,
    what: &str,
) {
    let (start, end) = (covered.start, covered.end);
    cover(&mut seq, covered);
    let out = run(&seq, tracker(&seq), backend);
    let st = check_no_false_tracking(label, &seq, &out);
    assert!(st[..start].chars().all(|c| c == 'T'), "{label}: tracking before the cover");
    assert!(st[start..end].chars().all(|c| c == 'L'), "{label}: lost while covered: {}", &st[start..end]);
    println!("{label}: frame {start}: {}", reason(&out, start));
    let back = first(&st, end, 'T').expect("re-acquired");
    println!("{label}: re-acquired at frame {back}");
    assert!(back <= end + 5, "{label}: re-acquired at {back}, 5 frames after the cover at most");
    assert!(st[held_from..].chars().all(|c| c == 'T'), "{label}: holds the {what} from frame {held_from}");
}

fn me_cover(backend: &mut dyn EarlyVision, label: &str) {
    // Covered for 20 frames around the turning point at frame 122 (period
    // 122 frames): it reappears ~10 px from where it was hidden, within the
    // re-acquisition strips.
    check_cover(label, pendulum(), motion_edge, backend, 112..132, 150, "object");
}

#[test]
fn motion_edge_covered_for_20_frames_is_lost_then_reacquired_cpu() {
    me_cover(&mut CpuBackend::new(), "motion-edge cover cpu");
}

#[test]
fn motion_edge_covered_for_20_frames_is_lost_then_reacquired_gpu() {
    let Some((ctx, _guard)) = common::gpu("motion_edge_covered_for_20_frames_is_lost_then_reacquired_gpu") else {
        return;
    };
    me_cover(&mut GpuBackend::new(ctx.clone()), "motion-edge cover gpu");
}

#[test]
fn motion_edge_jump_is_lost_at_once_and_never_falsely_tracked() {
    // The pendulum at frame 40 shows frame 70: the object is ~90 px away.
    // After `search_after` (2) lost frames the whole image is searched for
    // the last tracked shape, turned in steps of δ; the side a step leaves
    // a few degrees off is reported lost for a frame or two before the track
    // settles.
    let mut seq = pendulum();
    jump(&mut seq, 40, 30);
    let out = run(&seq, motion_edge(&seq), &mut CpuBackend::new());
    let st = check_no_false_tracking("motion-edge jump", &seq, &out);
    assert!(st[..40].chars().all(|c| c == 'T'));
    let lost = first(&st, 40, 'L').expect("lost");
    println!("motion-edge jump: lost at {lost}: {}", reason(&out, lost));
    assert!(lost <= 41, "lost at {lost}");
    let back = first(&st, lost, 'T').expect("re-acquired");
    println!("motion-edge jump: re-acquired at {back}");
    assert!(back <= 44, "re-acquired at {back}");
    let relost = st[back..].chars().filter(|&c| c == 'L').count();
    assert!(relost <= 2, "{relost} frames lost after re-acquisition");
    assert!(st[60..].chars().all(|c| c == 'T'), "holds the object from frame 60");
}

#[test]
fn motion_edge_pan_out_and_back_is_lost_and_reacquired() {
    // The camera pans the object out of the right border (6 px/frame from
    // frame 30, out by frame ~60), holds 20 frames, and pans back.
    let mut seq = pendulum();
    let dx = |k: usize| -> i64 {
        let k = k as i64;
        6 * (k - 30).clamp(0, 35) - 6 * (k - 85).clamp(0, 35)
    };
    pan(&mut seq, dx);
    let out = run(&seq, motion_edge(&seq), &mut CpuBackend::new());
    let st = check_no_false_tracking("motion-edge pan", &seq, &out);
    let lost = first(&st, 30, 'L').expect("lost");
    println!("motion-edge pan: lost at {lost}: {}", reason(&out, lost));
    // Motion-edge sees the object by its motion against a still
    // background: the evidence returns when the camera stops, at frame 120.
    check_lost_while_out_and_back("motion-edge pan", &seq, &st, 120, 5);
}

/// Vertices of frame `k` the truth shows.
fn shown(seq: &SyntheticSequence, k: usize) -> usize {
    match &seq.truth[k].visible {
        Visibility::Vertices(v) => v.iter().filter(|&&b| b).count(),
        Visibility::Object(all) => {
            if *all {
                seq.truth[k].corners.len()
            } else {
                0
            }
        }
    }
}

/// With `st` from a pan out: the pan takes the object out of the image, and
/// every frame whose truth shows no vertex is lost.
fn check_lost_while_out(label: &str, seq: &SyntheticSequence, st: &str) {
    let out: Vec<usize> = (0..st.len()).filter(|&k| shown(seq, k) == 0).collect();
    assert!(!out.is_empty(), "{label}: the pan takes the object out of the image");
    assert!(out.iter().all(|&k| &st[k..=k] == "L"), "{label}: lost while out of the image");
}

/// With `st` from a pan out and back: every frame whose truth shows no
/// vertex is lost (also counted as false tracking), and the object is
/// tracked again within `within` frames of the evidence returning: the first
/// frame from `settled` on that shows every vertex.
fn check_lost_while_out_and_back(label: &str, seq: &SyntheticSequence, st: &str, settled: usize, within: usize) {
    check_lost_while_out(label, seq, st);
    let whole = (settled..st.len()).find(|&k| shown(seq, k) == seq.truth[k].corners.len()).expect("back in the image");
    let back = first(st, whole, 'T').expect("re-acquired");
    println!("{label}: whole again at frame {whole}, re-acquired at frame {back}");
    assert!(back <= whole + within, "{label}: re-acquired at {back}, more than {within} frames after {whole}");
}

#[test]
fn motion_edge_wrong_initialisation_is_never_tracking() {
    // Operator corners 40 px right of the object.
    let mut seq = pendulum();
    for c in &mut seq.init.corners {
        c[0] += 40.0;
    }
    let out = run(&seq, motion_edge(&seq), &mut CpuBackend::new());
    let st = check_no_false_tracking("motion-edge wrong init", &seq, &out);
    assert_eq!(&st[..1], "L", "frame 0: {}", reason(&out, 0));
    println!("motion-edge wrong init: frame 0: {}", reason(&out, 0));
    // The search after `search_after` (10) lost frames finds the object.
    let found = first(&st, 0, 'T').expect("found");
    assert!(found <= 15, "found at frame {found}");
    assert!(st[found..].chars().all(|c| c == 'T'), "holds the object once found");
}

// ---------------------------------------------------------------------------
// blue on target3dof (640×480, 0.3 rad/s, 150 frames).

fn blue_cover(backend: &mut dyn EarlyVision, label: &str) {
    check_cover(label, target(), blue, backend, 60..80, 100, "target");
}

#[test]
fn blue_covered_for_20_frames_is_lost_then_reacquired_cpu() {
    blue_cover(&mut CpuBackend::new(), "blue cover cpu");
}

#[test]
fn blue_covered_for_20_frames_is_lost_then_reacquired_gpu() {
    let Some((ctx, _guard)) = common::gpu("blue_covered_for_20_frames_is_lost_then_reacquired_gpu") else {
        return;
    };
    blue_cover(&mut GpuBackend::new(ctx.clone()), "blue cover gpu");
}

#[test]
fn blue_jump_is_lost_at_once_then_reacquired() {
    check_jump("blue jump", target(), blue, 40, 5);
}

/// `seq` from frame 60 on showing where its object is `ahead` frames
/// later: tracking before, lost at 60 or 61, tracking again within
/// `within` frames of the loss and from then on.
fn check_jump(
    label: &str,
    mut seq: SyntheticSequence,
    tracker: fn(&SyntheticSequence) -> Box<dyn Tracker>,
    ahead: usize,
    within: usize,
) {
    jump(&mut seq, 60, ahead);
    let out = run(&seq, tracker(&seq), &mut CpuBackend::new());
    let st = check_no_false_tracking(label, &seq, &out);
    assert!(st[..60].chars().all(|c| c == 'T'), "{label}: {st}");
    let lost = first(&st, 60, 'L').expect("lost");
    println!("{label}: lost at {lost}: {}", reason(&out, lost));
    assert!(lost <= 61, "{label}: lost at {lost}");
    let back = first(&st, lost, 'T').expect("re-acquired");
    println!("{label}: re-acquired at {back}");
    assert!(back <= lost + within, "{label}: re-acquired at {back}");
    assert!(st[back..].chars().all(|c| c == 'T'), "{label}: holds the object once re-acquired: {st}");
}

#[test]
fn blue_pan_out_and_back_is_lost_and_reacquired() {
    // The camera pans the target out of the right border (12 px/frame from
    // frame 30), holds 20 frames, and pans back. Meanwhile the target moves
    // from 0.87 m to 1.5 m away: the whole-image search must widen its
    // ranges to find it.
    let mut seq = target();
    pan(&mut seq, |k| {
        let k = k as i64;
        12 * (k - 30).clamp(0, 40) - 12 * (k - 90).clamp(0, 40)
    });
    let out = run(&seq, blue(&seq), &mut CpuBackend::new());
    let st = check_no_false_tracking("blue pan", &seq, &out);
    let lost = first(&st, 30, 'L').expect("lost");
    println!("blue pan: lost at {lost}: {}", reason(&out, lost));
    check_lost_while_out_and_back("blue pan", &seq, &st, 130, 5);
}

#[test]
fn blue_wrong_initialisation_is_never_tracking() {
    let mut seq = target();
    if let Some(pose) = &mut seq.init.pose {
        pose.translation[0] += 0.08;
    }
    let out = run(&seq, blue(&seq), &mut CpuBackend::new());
    let st = check_no_false_tracking("blue wrong init", &seq, &out);
    assert_eq!(&st[..1], "L", "frame 0: {}", reason(&out, 0));
    // The search after `search_after` (3) lost frames finds the target.
    let found = first(&st, 0, 'T').expect("found");
    assert!(found <= 8, "found at frame {found}");
    assert!(st[found..].chars().all(|c| c == 'T'), "holds the target once found");
}

// ---------------------------------------------------------------------------
// lowe on the box (640×480, 4 px/frame of the fastest vertex).

fn box_scene() -> SyntheticSequence {
    render_box(&BoxOptions { frames: 150, ..BoxOptions::default() }).expect("render")
}

fn lowe(seq: &SyntheticSequence) -> Box<dyn Tracker> {
    Box::new(LoweTracker::new(seq.camera, &seq.model, &seq.init, LoweParams::default()).expect("tracker"))
}

#[test]
fn lowe_covered_for_20_frames_is_lost_then_reacquired_cpu() {
    check_cover("lowe cover cpu", box_scene(), lowe, &mut CpuBackend::new(), 60..80, 85, "box");
}

#[test]
fn lowe_wrong_initialisation_is_never_tracking() {
    // Initialised 8 cm (≈ 37 px) to the side: lost at frame 0, found by the
    // doubled search ranges, and never tracking off the box.
    let mut seq = box_scene();
    if let Some(pose) = &mut seq.init.pose {
        pose.translation[0] += 0.08;
    }
    let out = run(&seq, lowe(&seq), &mut CpuBackend::new());
    let st = check_no_false_tracking("lowe wrong init", &seq, &out);
    assert_eq!(&st[..1], "L", "frame 0: {}", reason(&out, 0));
    let found = first(&st, 0, 'T').expect("found");
    println!("lowe wrong init: found at {found}");
    assert!(found <= 5 && st[found..].chars().all(|c| c == 'T'), "found at {found}, then held: {st}");
}

#[test]
fn lowe_jump_is_lost_at_once_then_found_by_the_whole_image_search() {
    // At frame 40 the box jumps to where it is 40 frames later: ≈ 120 px
    // away, turned by 43° and 10 cm further. The local search loses it at
    // once; after `search_after` lost frames the whole image is searched
    // from the last verified pose, which finds the box once its pose comes
    // within the search's reach, and holds it from there.
    let mut seq = box_scene();
    jump(&mut seq, 40, 40);
    let out = run(&seq, lowe(&seq), &mut CpuBackend::new());
    let st = check_no_false_tracking("lowe jump", &seq, &out);
    assert!(st[..40].chars().all(|c| c == 'T'), "{st}");
    let lost = first(&st, 40, 'L').expect("lost");
    println!("lowe jump: lost at {lost}: {}", reason(&out, lost));
    assert_eq!(lost, 40);
    let back = first(&st, lost, 'T').expect("re-acquired");
    println!("lowe jump: re-acquired at {back}");
    assert!(back < 80, "re-acquired at {back}");
    assert!(st[back..].chars().all(|c| c == 'T'), "holds the box once re-acquired: {st}");
}

// ---------------------------------------------------------------------------
// condensation on the textured plane (a camera translating in x and y, 150
// frames). Its template is the window at the initial pose, so an
// initialisation elsewhere is another window to track, not a wrong one: the
// wrong-initialisation case has no condensation counterpart.

fn plane() -> SyntheticSequence {
    crate::condensation_e2e::textured_plane(&TexturedPlaneOptions {
        frames: 150,
        motion: PlaneMotion::Translation,
        ..TexturedPlaneOptions::default()
    })
}

fn condensation(seq: &SyntheticSequence) -> Box<dyn Tracker> {
    condensation_with(seq, crate::condensation_e2e::params(PlaneMotion::Translation))
}

fn condensation_with(seq: &SyntheticSequence, params: CondensationParams) -> Box<dyn Tracker> {
    Box::new(CondensationTracker::new(seq.camera, &seq.model, &seq.init, params).expect("tracker"))
}

fn condensation_cover(backend: &mut dyn EarlyVision, label: &str) {
    // While covered the window moves on by 43 px; the search widens from
    // where the motion before the cover carries it.
    check_cover(label, plane(), condensation, backend, 60..80, 90, "window");
}

#[test]
fn condensation_covered_for_20_frames_is_lost_then_reacquired_cpu() {
    condensation_cover(&mut CpuBackend::new(), "condensation cover cpu");
}

#[test]
fn condensation_covered_for_20_frames_is_lost_then_reacquired_gpu() {
    let Some((ctx, _guard)) = common::gpu("condensation_covered_for_20_frames_is_lost_then_reacquired_gpu") else {
        return;
    };
    condensation_cover(&mut GpuBackend::new(ctx.clone()), "condensation cover gpu");
}

#[test]
fn condensation_jump_is_lost_at_once_then_reacquired() {
    check_jump("condensation jump", plane(), condensation, 15, 8);
}

/// Seeds of the condensation sweep below: `PIPETRACK_STATUS_SEEDS=A-B`
/// (inclusive) runs others, e.g. seeds not used to choose the search's
/// parameters; 1–3 by default. `PIPETRACK_STATUS_SEARCH_SPREAD=0` runs it
/// with the search off (it then fails: the paper's update does not bring
/// the window back).
fn sweep_seeds() -> std::ops::RangeInclusive<u64> {
    let default = 1..=3;
    let Ok(spec) = std::env::var("PIPETRACK_STATUS_SEEDS") else {
        return default;
    };
    let (a, b) = spec.split_once('-').expect("PIPETRACK_STATUS_SEEDS is A-B");
    a.parse().expect("seed")..=b.parse().expect("seed")
}

#[test]
fn condensation_reacquires_after_covers_and_jumps_across_seeds() {
    // Per seed: covered for frames 60–79 with the camera translating, and
    // translating and rolling; the frames jumping 15 and 30 frames ahead at
    // frame 60 (the window 31 and 66 px away). Never tracking off the window,
    // and tracking again within 30 frames of the evidence returning (70
    // with the roll, a third dimension to search: seeds 1–16 take 3–58).
    // (scene, motion, frames jumped ahead at 60, or covered for 60–79)
    let scenes = [
        ("cover", PlaneMotion::Translation, None),
        ("roll cover", PlaneMotion::Roll, None),
        ("jump 15", PlaneMotion::Translation, Some(15)),
        ("jump 30", PlaneMotion::Translation, Some(30)),
    ];
    let runs: Vec<_> = sweep_seeds().flat_map(|seed| scenes.map(|scene| (seed, scene))).collect();
    // The runs are independent: each on its own thread, checked in order.
    let statuses: Vec<String> = std::thread::scope(|threads| {
        let handles: Vec<_> = runs
            .iter()
            .map(|&(seed, (scene, motion, ahead))| {
                threads.spawn(move || {
                    let opts = TexturedPlaneOptions { frames: 150, seed, motion, ..TexturedPlaneOptions::default() };
                    // A cover and the jumps share one rendering per seed.
                    let mut seq = crate::condensation_e2e::textured_plane(&opts);
                    match ahead {
                        Some(ahead) => jump(&mut seq, 60, ahead),
                        None => cover(&mut seq, 60..80),
                    }
                    let mut params = crate::condensation_e2e::params(motion);
                    if let Ok(spread) = std::env::var("PIPETRACK_STATUS_SEARCH_SPREAD") {
                        params.search_spread_px = spread.parse().expect("a spread in px");
                    }
                    let out = run(&seq, condensation_with(&seq, params), &mut CpuBackend::new());
                    check_no_false_tracking(&format!("condensation seed {seed} {scene}"), &seq, &out)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().expect("a sweep run panicked")).collect()
    });
    let (mut tracked, mut frames, mut late) = (0, 0, Vec::new());
    for (&(seed, (scene, motion, ahead)), st) in runs.iter().zip(&statuses) {
        let label = format!("condensation seed {seed} {scene}");
        // The frame from which the window can be seen again.
        let returns = if ahead.is_some() { 60 } else { 80 };
        assert!(st[..60].chars().all(|c| c == 'T'), "{label}: tracking before frame 60");
        assert_eq!(&st[60..61], "L", "{label}: lost at frame 60");
        let back = first(st, returns, 'T');
        println!("{label}: re-acquired at {back:?}");
        let within = if motion == PlaneMotion::Roll { 70 } else { 30 };
        if back.is_none_or(|b| b > returns + within) {
            late.push(format!("{label}: {back:?}"));
        }
        tracked += st.chars().filter(|&c| c == 'T').count();
        frames += st.len();
    }
    println!("condensation sweep, seeds {:?}: {tracked} of {frames} frames tracking", sweep_seeds());
    assert!(late.is_empty(), "not re-acquired in time: {}", late.join("; "));
}

/// The search changes only lost frames: a run that is never lost writes the
/// same lines (but `ms`) with the search on and off.
#[test]
fn condensation_search_leaves_a_run_that_is_never_lost_unchanged() {
    let seq = plane();
    let lines = |search_spread_px: f64| -> Vec<FrameResult> {
        let params =
            CondensationParams { search_spread_px, ..crate::condensation_e2e::params(PlaneMotion::Translation) };
        let out = run(&seq, condensation_with(&seq, params), &mut CpuBackend::new());
        out.into_iter().map(|(_, r)| FrameResult { ms: 0.0, ..r }).collect()
    };
    let on = lines(CondensationParams::default().search_spread_px);
    assert!(on.iter().all(|r| r.status == Status::Tracking), "never lost");
    assert_eq!(on, lines(0.0));
}
