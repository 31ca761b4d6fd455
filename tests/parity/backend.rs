//! The two backends give the same frame results: the whole chain (motion,
//! edges, zero crossings, pyramids) over a short moving sequence, through
//! `GpuBackend` (one submission per frame, slot ring, pipelined stream,
//! texture input) and `CpuBackend`, with one request throughout and with
//! requests that change every frame.
use crate::common;

use pipetrack::GrayImage;
use pipetrack::backend::{
    CpuBackend, EarlyVision, EdgeRequest, FrameFeatures, FrameRequest, GpuBackend, ListSpec, MotionRequest, Pyramids,
    ZeroCrossingRequest,
};
use pipetrack::early::gaussian::GaussianParams;
use pipetrack::early::log::LogParams;
use pipetrack::early::temporal_diff::TemporalDiffParams;
use pipetrack::early::zero_crossing::ZeroCrossingParams;
use pipetrack::early::{Feature, Window};
use pipetrack::testimage::natural;

/// Angle and magnitude tolerance of listed features (Sobel/LoG rounding).
const FEATURE_ATOL: f32 = 1e-3;
/// Gradient error (grey levels) a device's f32 arithmetic may leave in a
/// feature's gradient: a device that fuses multiply-adds (an NVIDIA H200
/// left up to 3.7e-4) rounds differently from the CPU twins. A feature's
/// angle is the gradient's direction, so it may differ by about this over
/// the gradient's magnitude, which matters only where the gradient is
/// nearly flat.
const GRADIENT_ATOL: f32 = 1e-3;

fn sequence(w: usize, h: usize, n: usize) -> Vec<GrayImage> {
    let scene = natural(w + 3 * n, h, 99);
    (0..n).map(|k| GrayImage::from_fn(w, h, |x, y| scene.get(x + 3 * k, y))).collect()
}

fn same_lists(what: &str, cpu: &[Feature], gpu: &[Feature]) {
    assert_eq!(cpu.len(), gpu.len(), "{what}: list lengths differ");
    for (i, (c, g)) in cpu.iter().zip(gpu).enumerate() {
        assert_eq!((c.x, c.y), (g.x, g.y), "{what}: element {i} at a different pixel");
        let dt = (c.theta - g.theta).abs();
        let dt = dt.min((dt - std::f32::consts::TAU).abs());
        let angle_tolerance = FEATURE_ATOL + GRADIENT_ATOL / c.magnitude.abs();
        assert!(
            dt <= angle_tolerance,
            "{what}: element {i} theta {} vs {} (gradient magnitude {})",
            c.theta,
            g.theta,
            c.magnitude
        );
        assert!(
            (c.magnitude - g.magnitude).abs() <= FEATURE_ATOL * c.magnitude.abs().max(1.0),
            "{what}: element {i} magnitude"
        );
    }
}

pub(crate) fn same_features(what: &str, cpu: &FrameFeatures, gpu: &FrameFeatures) {
    for (name, c, g) in [
        ("motion", &cpu.motion, &gpu.motion),
        ("edges", &cpu.edges, &gpu.edges),
        ("zero_crossings", &cpu.zero_crossings, &gpu.zero_crossings),
    ] {
        assert_eq!(c.is_some(), g.is_some(), "{what}/{name}: presence differs");
        if let (Some(c), Some(g)) = (c, g) {
            same_lists(&format!("{what}/{name}"), c, g);
        }
    }
    assert_eq!(cpu.pyramids.is_some(), gpu.pyramids.is_some());
    if let (Some((cc, ce)), Some((gc, ge))) = (&cpu.pyramids, &gpu.pyramids) {
        assert_eq!(cc, gc, "{what}: CPF hierarchies differ");
        for (c, g) in ce.horizontal.iter().zip(&ge.horizontal).chain(ce.vertical.iter().zip(&ge.vertical)) {
            common::assert_close(&format!("{what}/edge_pyramid"), c, g, 1e-3, 1e-5);
        }
    }
}

#[test]
fn gpu_and_cpu_backends_agree_on_the_full_chain() {
    let Some((ctx, _g)) = common::gpu("gpu_and_cpu_backends_agree_on_the_full_chain") else { return };
    for (w, h) in [(257, 243), (64, 48), (2, 3)] {
        let frames = sequence(w, h, 4);
        let mut request = FrameRequest::full_chain(w, h);
        request.pyramids = Pyramids::Return;
        // An off-centre window and a cap on one list, as trackers ask.
        request.edges.as_mut().unwrap().list =
            ListSpec { window: Window { x0: 3, y0: 5, x1: w as u32 / 2 + 1, y1: h as u32 }, cap: Some(300), seed: 4 };
        let mut cpu = CpuBackend::new();
        let mut gpu = GpuBackend::new(ctx.clone());
        for (i, f) in frames.iter().enumerate() {
            let c = cpu.process(f, &request).unwrap();
            let g = gpu.process(f, &request).unwrap();
            if i == 0 {
                assert_eq!(c.motion.as_deref(), Some(&[][..]), "no motion without a previous frame");
            } else if w > 8 {
                assert!(!c.motion.as_ref().unwrap().is_empty(), "a moving scene has motion pixels");
            }
            same_features(&format!("{w}x{h}/frame{i}"), &c, &g);
        }
        let stats = gpu.last_frame_stats();
        assert!(stats.dispatches > 0 && stats.bytes_uploaded == ((w * h).div_ceil(4) * 4) as u64, "{stats:?}");
    }
}

#[test]
fn pipelined_stream_equals_frame_by_frame() {
    let Some((ctx, _g)) = common::gpu("pipelined_stream_equals_frame_by_frame") else { return };
    let (w, h) = (160, 120);
    let frames = sequence(w, h, 7);
    let mut request = FrameRequest::full_chain(w, h);
    request.pyramids = Pyramids::Return;
    let mut one = GpuBackend::new(ctx.clone());
    let expected: Vec<FrameFeatures> = frames.iter().map(|f| one.process(f, &request).unwrap()).collect();
    let mut streamed = Vec::new();
    GpuBackend::new(ctx.clone()).process_stream(&frames, &request, |i, f| streamed.push((i, f))).unwrap();
    assert_eq!(streamed.len(), frames.len());
    for (i, f) in streamed {
        assert_eq!(f, expected[i], "frame {i} differs when pipelined");
    }
}

#[test]
fn texture_frames_equal_byte_frames() {
    let Some((ctx, _g)) = common::gpu("texture_frames_equal_byte_frames") else { return };
    let (w, h) = (97, 61);
    let frames = sequence(w, h, 3);
    let request = FrameRequest::full_chain(w, h);
    let texture = common::empty_texture(ctx, w, h, wgpu::TextureFormat::R8Unorm);
    let mut by_bytes = GpuBackend::new(ctx.clone());
    let mut by_texture = GpuBackend::new(ctx.clone());
    for f in &frames {
        common::write_texture(ctx, &texture, f.data());
        let a = by_bytes.process(f, &request).unwrap();
        let b = by_texture.process_texture(&texture, &request).unwrap();
        assert_eq!(a, b);
        assert_eq!(by_texture.last_frame_stats().bytes_uploaded, 0);
    }
}

#[test]
fn too_many_frames_in_flight_is_an_error_not_a_hang() {
    let Some((ctx, _g)) = common::gpu("too_many_frames_in_flight_is_an_error_not_a_hang") else { return };
    let frames = sequence(16, 16, 4);
    let request = FrameRequest::full_chain(16, 16);
    let mut gpu = GpuBackend::new(ctx.clone());
    let a = gpu.submit(&frames[0], &request).unwrap();
    let b = gpu.submit(&frames[1], &request).unwrap();
    let c = gpu.submit(&frames[2], &request).unwrap();
    assert!(gpu.submit(&frames[3], &request).is_err());
    for t in [a, b, c] {
        gpu.finish(t).unwrap();
    }
}

// ---------------------------------------------------------------------------
// Requests that change from frame to frame. A tracker asks for different
// stages, windows and caps on every frame; both backends must still give the
// same lists, and motion must always difference two consecutive frames
// smoothed the same way (the previous-frame rule of `FramePlan`).

/// Frames of the changing-request scenarios: an awkward size, ≥ 12 frames.
const CHANGING: (usize, usize) = (57, 43);

pub(crate) fn motion(spec: ListSpec) -> MotionRequest {
    MotionRequest { diff: TemporalDiffParams::default(), list: spec }
}

pub(crate) fn edges(smoothed: bool, spec: ListSpec) -> EdgeRequest {
    EdgeRequest { threshold: 60.0, smoothed, list: spec }
}

pub(crate) fn crossings(spec: ListSpec) -> ZeroCrossingRequest {
    ZeroCrossingRequest { log: LogParams::default(), crossings: ZeroCrossingParams::default(), list: spec }
}

/// Whether a frame processed with `r` leaves a smoothed image behind: the
/// stages that read the smoothed frame are motion and smoothed edges.
fn smooths(r: &FrameRequest) -> bool {
    r.motion.is_some() || r.edges.is_some_and(|e| e.smoothed)
}

/// Run `requests` (one per frame) on both backends over a moving sequence and
/// compare frame by frame; also check every motion list against the rule:
/// empty unless the previous frame was smoothed with the same σ, and then
/// equal to the motion of a fresh backend fed only those two frames.
fn run_changing_requests(test: &str, (w, h): (usize, usize), requests: &[FrameRequest]) {
    let Some((ctx, _g)) = common::gpu(test) else { return };
    let frames = sequence(w, h, requests.len());
    let mut cpu = CpuBackend::new();
    let mut gpu = GpuBackend::new(ctx.clone());
    let mut moving_frames = 0;
    for (i, (f, r)) in frames.iter().zip(requests).enumerate() {
        let what = format!("{test}/{w}x{h}/frame{i}");
        let c = cpu.process(f, r).unwrap();
        let g = gpu.process(f, r).unwrap();
        same_features(&what, &c, &g);
        assert_eq!(c.motion.is_some(), r.motion.is_some(), "{what}: motion presence");
        assert_eq!(c.edges.is_some(), r.edges.is_some(), "{what}: edges presence");
        assert_eq!(c.zero_crossings.is_some(), r.zero_crossings.is_some(), "{what}: crossings presence");
        assert_eq!(c.pyramids.is_some(), r.pyramids == Pyramids::Return, "{what}: pyramids presence");
        let (Some(m), Some(mr)) = (&c.motion, &r.motion) else { continue };
        let consecutive = i > 0 && smooths(&requests[i - 1]) && requests[i - 1].smoothing == r.smoothing;
        if !consecutive {
            assert!(m.is_empty(), "{what}: motion without a consecutive previous frame smoothed alike");
            continue;
        }
        let mut fresh = CpuBackend::new();
        let first = FrameRequest { smoothing: r.smoothing, motion: Some(*mr), ..FrameRequest::default() };
        fresh.process(&frames[i - 1], &first).unwrap();
        let expected = fresh.process(f, r).unwrap().motion.unwrap();
        same_lists(&format!("{what}/motion against frames {} and {i} alone", i - 1), &expected, m);
        moving_frames += usize::from(!m.is_empty());
    }
    assert!(moving_frames > 0, "{test}: no frame had motion pixels to compare");
}

#[test]
fn changing_requests_mix_motion_and_edges() {
    let (w, h) = CHANGING;
    let full = ListSpec::full(w, h);
    let r = |motion_on: bool, edge: Option<bool>| FrameRequest {
        motion: motion_on.then(|| motion(full)),
        edges: edge.map(|smoothed| edges(smoothed, full)),
        ..FrameRequest::default()
    };
    let requests = [
        r(true, None),
        r(true, None),
        r(false, Some(true)), // smooths without motion: the next frame's motion differences against it
        r(true, None),
        r(false, Some(false)), // does not smooth: the next frame's motion is empty
        r(true, None),
        r(true, Some(false)),
        r(false, None), // nothing at all
        r(true, Some(true)),
        r(true, Some(true)),
        r(false, Some(false)),
        r(false, Some(true)),
        r(true, None),
        r(true, Some(false)),
    ];
    run_changing_requests("changing_requests_mix_motion_and_edges", (w, h), &requests);
}

#[test]
fn changing_requests_with_crossings_and_pyramids() {
    let (w, h) = CHANGING;
    let full = ListSpec::full(w, h);
    let requests: Vec<FrameRequest> = (0..15)
        .map(|i| FrameRequest {
            motion: (i % 5 != 2).then(|| motion(full)),
            edges: [None, Some(false), Some(true), None][i % 4].map(|s| edges(s, full)),
            zero_crossings: (i % 2 == 0).then(|| crossings(full)),
            pyramids: [Pyramids::Off, Pyramids::Keep, Pyramids::Return][i % 3],
            ..FrameRequest::default()
        })
        .collect();
    run_changing_requests("changing_requests_with_crossings_and_pyramids", (w, h), &requests);
}

#[test]
fn changing_requests_with_moving_shrinking_windows_and_caps() {
    let (w, h) = CHANGING;
    let requests: Vec<FrameRequest> = (0..14u32)
        .map(|i| {
            // Windows drift right and down and shrink until empty (frames
            // 10 and up), some reaching past the frame; caps come and go.
            let x0 = 2 * i;
            let y0 = i;
            let window = Window {
                x0,
                y0,
                x1: (x0 + (w as u32 + 6).saturating_sub(7 * i)),
                y1: y0 + (h as u32).saturating_sub(4 * i),
            };
            let cap = [None, Some(25), Some(400), Some(0), None, Some(3)][i as usize % 6];
            let spec = ListSpec { window, cap, seed: 17 * i };
            let mut r = FrameRequest::full_chain(w, h);
            r.motion = Some(motion(ListSpec { cap: cap.map(|c| c + 1), ..spec }));
            r.edges = Some(edges(i % 2 == 0, ListSpec { seed: 3 + i, ..spec }));
            r.zero_crossings = (i % 3 != 1).then(|| crossings(ListSpec { cap: None, ..spec }));
            r.pyramids = if i % 4 == 0 { Pyramids::Return } else { Pyramids::Off };
            r
        })
        .collect();
    assert!(requests.iter().any(|r| r.motion.unwrap().list.window.clipped(w, h).is_empty()));
    run_changing_requests("changing_requests_with_moving_shrinking_windows_and_caps", (w, h), &requests);
}

/// Zero crossings alone, in windows that move from frame to frame: a
/// one-pixel window at the corner, a column and a row on the far borders,
/// windows off-centre and partly outside, an empty one, the whole frame.
/// Each backend computes the LoG and its crossings only around the windows
/// (the GPU leaves the rest of its images as earlier frames left them), and
/// each list is the whole frame's crossings inside the window, the same on
/// both backends.
#[test]
fn crossings_in_awkward_windows_are_the_whole_frames() {
    let test = "crossings_in_awkward_windows_are_the_whole_frames";
    let Some((ctx, _g)) = common::gpu(test) else { return };
    let (w, h) = CHANGING;
    let (wu, hu) = (w as u32, h as u32);
    let windows = [
        Window { x0: 0, y0: 0, x1: 1, y1: 1 },
        Window::full(w, h),
        Window { x0: wu - 1, y0: 0, x1: wu, y1: hu },
        Window { x0: 5, y0: 7, x1: 12, y1: 30 },
        Window { x0: 0, y0: hu - 1, x1: wu, y1: hu },
        Window { x0: 40, y0: 30, x1: wu + 20, y1: hu + 9 },
        Window { x0: 20, y0: 20, x1: 20, y1: 25 },
        Window { x0: 1, y0: 1, x1: wu - 1, y1: hu - 1 },
        Window { x0: 30, y0: 2, x1: 33, y1: 41 },
    ];
    let frames = sequence(w, h, windows.len());
    let request = |window| FrameRequest {
        zero_crossings: Some(crossings(ListSpec { window, cap: None, seed: 0 })),
        ..FrameRequest::default()
    };
    let (mut cpu, mut gpu, mut whole) = (CpuBackend::new(), GpuBackend::new(ctx.clone()), CpuBackend::new());
    let mut listed = 0;
    for (i, (f, &window)) in frames.iter().zip(&windows).enumerate() {
        let what = format!("{test}/frame{i}/{window:?}");
        let c = cpu.process(f, &request(window)).unwrap().zero_crossings.unwrap();
        let g = gpu.process(f, &request(window)).unwrap().zero_crossings.unwrap();
        same_lists(&what, &c, &g);
        let all = whole.process(f, &request(Window::full(w, h))).unwrap().zero_crossings.unwrap();
        let inside: Vec<Feature> = all
            .into_iter()
            .filter(|p| (window.x0..window.x1).contains(&p.x) && (window.y0..window.y1).contains(&p.y))
            .collect();
        same_lists(&format!("{what} against the whole frame"), &inside, &g);
        listed += g.len();
    }
    assert!(listed > 100, "{test}: only {listed} crossings listed");
}

#[test]
fn changing_smoothing_restarts_motion() {
    let (w, h) = CHANGING;
    let full = ListSpec::full(w, h);
    let sigmas = [1.0, 1.0, 1.0, 1.6, 1.6, 1.0, 1.6, 1.6, 1.6, 1.0, 1.0, 2.0, 2.0];
    let requests: Vec<FrameRequest> = sigmas
        .iter()
        .enumerate()
        .map(|(i, &sigma)| FrameRequest {
            smoothing: GaussianParams { sigma },
            motion: (i % 4 != 2).then(|| motion(full)),
            edges: (i % 4 == 2).then(|| edges(true, full)),
            ..FrameRequest::default()
        })
        .collect();
    run_changing_requests("changing_smoothing_restarts_motion", (w, h), &requests);
}

#[test]
fn changing_requests_on_a_tiny_frame() {
    let (w, h) = (5, 4);
    let full = ListSpec::full(w, h);
    let requests: Vec<FrameRequest> = (0..13)
        .map(|i| FrameRequest {
            motion: (i % 3 != 1).then(|| motion(full)),
            edges: [None, Some(true), Some(false)][i % 3].map(|s| edges(s, full)),
            zero_crossings: (i % 2 == 1).then(|| crossings(full)),
            pyramids: [Pyramids::Return, Pyramids::Off, Pyramids::Keep, Pyramids::Return][i % 4],
            ..FrameRequest::default()
        })
        .collect();
    run_changing_requests("changing_requests_on_a_tiny_frame", (w, h), &requests);
}

/// Frames in flight in the slot ring with a different request each: the
/// previous frame of a submission is the one submitted just before it.
#[test]
fn changing_requests_in_flight_equal_cpu() {
    let Some((ctx, _g)) = common::gpu("changing_requests_in_flight_equal_cpu") else { return };
    let (w, h) = CHANGING;
    let full = ListSpec::full(w, h);
    let frames = sequence(w, h, 12);
    let requests: Vec<FrameRequest> = (0..frames.len())
        .map(|i| FrameRequest {
            motion: (i % 3 != 1).then(|| motion(full)),
            edges: [Some(true), Some(false), None, Some(false)][i % 4].map(|s| edges(s, full)),
            pyramids: if i % 5 == 0 { Pyramids::Return } else { Pyramids::Keep },
            ..FrameRequest::default()
        })
        .collect();
    let mut cpu = CpuBackend::new();
    let mut gpu = GpuBackend::new(ctx.clone());
    let mut in_flight = std::collections::VecDeque::new();
    let mut compare = |i: usize, g: FrameFeatures| {
        let c = cpu.process(&frames[i], &requests[i]).unwrap();
        same_features(&format!("in_flight/frame{i}"), &c, &g);
    };
    for (i, (f, r)) in frames.iter().zip(&requests).enumerate() {
        if in_flight.len() == 2 {
            let (j, t) = in_flight.pop_front().unwrap();
            compare(j, gpu.finish(t).unwrap());
        }
        in_flight.push_back((i, gpu.submit(f, r).unwrap()));
    }
    while let Some((j, t)) = in_flight.pop_front() {
        compare(j, gpu.finish(t).unwrap());
    }
}

/// Lanes of one backend (independent sequences) recorded into shared
/// submissions: each lane's frames are differenced against that lane's own
/// previous frame, and equal the CPU backend run on that sequence alone, on
/// an odd size, with lanes joining late, one starting a new sequence
/// part-way, and requests that differ between lanes.
#[test]
fn lanes_in_one_submission_equal_cpu_per_sequence() {
    use pipetrack::backend::LaneFrame;
    let Some((ctx, _g)) = common::gpu("lanes_in_one_submission_equal_cpu_per_sequence") else { return };
    let (w, h) = (257, 243);
    let full = ListSpec::full(w, h);
    let scene = natural(w + 40, h + 40, 7);
    // Lane k shows the scene moving by k + 1 px per frame from its own offset.
    let frame =
        |lane: usize, i: usize| GrayImage::from_fn(w, h, |x, y| scene.get(x + (lane + 1) * i % 40, y + 5 * lane));
    let requests = [
        FrameRequest { motion: Some(motion(full)), ..FrameRequest::default() },
        FrameRequest { motion: Some(motion(full)), edges: Some(edges(true, full)), ..FrameRequest::default() },
        FrameRequest { edges: Some(edges(false, full)), motion: Some(motion(full)), ..FrameRequest::default() },
    ];
    let mut gpu = GpuBackend::new(ctx.clone());
    let mut cpu: Vec<CpuBackend> = (0..3).map(|_| CpuBackend::new()).collect();
    let mut frame_index = [0usize; 3];
    for step in 0..6 {
        // Lane 2 joins at step 2; lane 0 starts a new sequence at step 4.
        let lanes: Vec<usize> = (0..3).filter(|&l| l != 2 || step >= 2).collect();
        if step == 4 {
            gpu.reset_lane(0);
            cpu[0].reset();
            frame_index[0] = 10;
        }
        let frames: Vec<GrayImage> = lanes.iter().map(|&l| frame(l, frame_index[l])).collect();
        let batch: Vec<LaneFrame<'_>> = lanes
            .iter()
            .zip(&frames)
            .map(|(&lane, frame)| LaneFrame { lane, frame, colour: None, request: &requests[lane] })
            .collect();
        let tickets = gpu.submit_lanes(&batch).unwrap();
        // Odd steps read the lanes back together, even steps one by one.
        let read: Vec<FrameFeatures> = if step % 2 == 1 {
            gpu.finish_lanes(tickets).unwrap()
        } else {
            tickets.into_iter().map(|t| gpu.finish(t).unwrap()).collect()
        };
        for ((&lane, f), g) in lanes.iter().zip(&frames).zip(read) {
            let c = cpu[lane].process(f, &requests[lane]).unwrap();
            same_features(&format!("lane{lane}/step{step}"), &c, &g);
            let motion = g.motion.as_ref().unwrap();
            let first_of_sequence = frame_index[lane] == 0 || (lane == 0 && step == 4);
            assert_eq!(motion.is_empty(), first_of_sequence, "lane{lane}/step{step}: motion only after a first frame");
            frame_index[lane] += 1;
        }
    }
    let again = frame(1, 0);
    let one = [LaneFrame { lane: 1, frame: &again, colour: None, request: &requests[1] }; 2];
    assert!(gpu.submit_lanes(&one).is_err(), "a lane twice in one submission");
}

/// A list far longer than the lane's last frame listed (a flat frame, then
/// a textured one, then flat again) is read back whole, and a short one
/// after a long one is not padded: the GPU lists equal the CPU's on every
/// frame, through `finish` and through `finish_lanes`.
#[test]
fn lists_longer_or_shorter_than_the_last_frame_are_read_back_whole() {
    use pipetrack::backend::LaneFrame;
    let Some((ctx, _g)) = common::gpu("lists_longer_or_shorter_than_the_last_frame_are_read_back_whole") else {
        return;
    };
    let (w, h) = (257, 243);
    let textured = sequence(w, h, 4);
    let flat = GrayImage::from_fn(w, h, |_, _| 90);
    let frames = [&flat, &textured[0], &textured[1], &flat, &textured[2], &textured[3]];
    let request = FrameRequest::full_chain(w, h);
    let mut cpu = CpuBackend::new();
    let mut gpu = GpuBackend::new(ctx.clone());
    let mut longest = 0;
    for (i, f) in frames.into_iter().enumerate() {
        let c = cpu.process(f, &request).unwrap();
        let g = if i % 2 == 0 {
            gpu.process(f, &request).unwrap()
        } else {
            let ticket = gpu.submit_lanes(&[LaneFrame { lane: 0, frame: f, colour: None, request: &request }]).unwrap();
            gpu.finish_lanes(ticket).unwrap().remove(0)
        };
        same_features(&format!("frame{i}"), &c, &g);
        longest = longest.max(c.zero_crossings.as_ref().map_or(0, Vec::len));
    }
    assert!(longest > 4096, "the textured frames list more than one readback's default ({longest})");
}
