//! `GpuStack`: sequences whose frames share every dispatch give, layer by
//! layer, what the CPU backend gives each sequence alone — on an odd frame
//! size, with a different window, cap and seed per layer (one window empty,
//! one a single column at the border), pyramids handed back, two steps in
//! flight, one layer starting a new sequence while the others go on, and a
//! reset of all; and requests that cannot stack are refused.
use crate::backend::{crossings, edges, motion, same_features};
use crate::common;

use pipetrack::GrayImage;
use pipetrack::backend::{CpuBackend, EarlyVision, FrameFeatures, FrameRequest, GpuStack, ListSpec, Pyramids};
use pipetrack::early::Window;
use pipetrack::testimage::natural;

const SIZE: (usize, usize) = (131, 67);
const LAYERS: usize = 3;

/// Frame `i` of sequence `layer`: its own part of a scene, moving by
/// `layer + 1` px per frame.
fn frame(scene: &GrayImage, layer: usize, i: usize) -> GrayImage {
    let (w, h) = SIZE;
    GrayImage::from_fn(w, h, |x, y| scene.get(x + (layer + 1) * i % 30, y + 9 * layer))
}

/// The request of `layer` at step `step`: the whole chain with pyramids
/// handed back; every list has its own window (layer 1's motion reaching
/// past the right border, layer 2's motion empty and its edges a single
/// column at that border), and edges and crossings their own caps and seeds.
fn request(layer: usize, step: usize) -> FrameRequest {
    let (w, h) = SIZE;
    let (wu, hu) = (w as u32, h as u32);
    let window = match layer {
        0 => Window::full(w, h),
        1 => Window { x0: wu - 40, y0: 0, x1: wu + 5, y1: hu },
        _ => Window { x0: 10 + step as u32, y0: 5, x1: 10 + step as u32, y1: 40 },
    };
    let mut r = FrameRequest::full_chain(w, h);
    let list_window = match layer {
        2 => Window { x0: wu - 1, y0: 0, x1: wu + 5, y1: hu },
        _ => Window { x0: 3 * layer as u32, y0: layer as u32, x1: wu - 2, y1: hu },
    };
    let spec = ListSpec { window: list_window, ..ListSpec::full(w, h) };
    r.motion = Some(motion(ListSpec { window, ..spec }));
    r.edges = Some(edges(layer == 0, ListSpec { cap: Some(40 + 300 * layer as u32), seed: step as u32, ..spec }));
    r.zero_crossings = Some(crossings(ListSpec { cap: Some(5 + 7 * layer as u32), seed: layer as u32, ..spec }));
    r.pyramids = Pyramids::Return;
    r
}

/// With the device's compaction run and with the other one (8 on a CPU
/// adapter, 32 on a GPU), so both shader variants are checked here.
#[test]
fn stacked_sequences_equal_the_cpu_per_sequence() {
    let Some((ctx, _g)) = common::gpu("stacked_sequences_equal_the_cpu_per_sequence") else { return };
    let other = ctx.with_compaction_run(if ctx.compaction_run() == 8 { 32 } else { 8 }).unwrap();
    for ctx in [ctx.clone(), other] {
        stacked_sequences_equal_the_cpu_on(&ctx);
    }
}

fn stacked_sequences_equal_the_cpu_on(ctx: &pipetrack::GpuContext) {
    let scene = natural(SIZE.0 + 30, SIZE.1 + 9 * LAYERS, 5);
    // Edge lists smoothed on layer 0 only: requests that differ in a stage's
    // input do not stack, so every layer takes the raw frame's edges here.
    let requests = |step| -> Vec<FrameRequest> {
        (0..LAYERS)
            .map(|l| {
                let mut r = request(l, step);
                r.edges = r.edges.map(|e| pipetrack::backend::EdgeRequest { smoothed: false, ..e });
                r
            })
            .collect()
    };
    let mut stack = GpuStack::new(ctx.clone(), LAYERS).unwrap();
    let mut cpu: Vec<CpuBackend> = (0..LAYERS).map(|_| CpuBackend::new()).collect();
    let mut pending = None;
    let mut expected: Vec<Vec<FrameFeatures>> = Vec::new();
    let check = |step: usize, read: Vec<FrameFeatures>, expected: &[FrameFeatures]| {
        assert_eq!(read.len(), LAYERS);
        for (layer, (c, g)) in expected.iter().zip(&read).enumerate() {
            same_features(&format!("layer{layer}/step{step}"), c, g);
        }
        // The empty window lists nothing; the others only their own pixels.
        assert!(read[2].motion.as_ref().unwrap().is_empty());
        assert!(read[2].edges.as_ref().unwrap().iter().all(|f| f.x == SIZE.0 as u32 - 1));
        assert!(read[1].motion.as_ref().unwrap().iter().all(|f| f.x >= SIZE.0 as u32 - 40));
    };
    let mut sequence_start = 0;
    let mut offset = [0usize; LAYERS];
    for step in 0..7 {
        if step == 2 {
            // Layer 1 alone starts a new sequence, elsewhere in the scene.
            stack.reset_layer(1).unwrap();
            cpu[1].reset();
            offset[1] = 11;
        }
        if step == 4 {
            // A new sequence in every layer: no motion on its first frame.
            if let Some((s, t)) = pending.take() {
                check(s, stack.finish(t).unwrap(), &expected[s]);
            }
            stack.reset();
            cpu.iter_mut().for_each(EarlyVision::reset);
            sequence_start = step;
        }
        let frames: Vec<GrayImage> = (0..LAYERS).map(|l| frame(&scene, l, step + offset[l] + 7 * (step / 4))).collect();
        let reqs = requests(step);
        let batch: Vec<(&GrayImage, &FrameRequest)> = frames.iter().zip(&reqs).collect();
        let ticket = stack.submit(&batch).unwrap();
        let c: Vec<FrameFeatures> = cpu.iter_mut().zip(&batch).map(|(b, (f, r))| b.process(f, r).unwrap()).collect();
        let moving = c[0].motion.as_ref().unwrap();
        assert_eq!(moving.is_empty(), step == sequence_start, "step {step}: motion only after a first frame");
        let restarted = c[1].motion.as_ref().unwrap();
        assert_eq!(restarted.is_empty(), step == sequence_start || step == 2, "layer 1, step {step}");
        expected.push(c);
        if let Some((s, t)) = pending.replace((step, ticket)) {
            check(s, stack.finish(t).unwrap(), &expected[s]);
        }
    }
    let (s, t) = pending.take().unwrap();
    check(s, stack.finish(t).unwrap(), &expected[s]);
    assert!(stack.last_step_stats().dispatches > 0);
}

#[test]
fn requests_that_do_not_stack_are_refused() {
    let Some((ctx, _g)) = common::gpu("requests_that_do_not_stack_are_refused") else { return };
    let scene = natural(SIZE.0 + 30, SIZE.1 + 9 * LAYERS, 6);
    let frames: Vec<GrayImage> = (0..LAYERS).map(|l| frame(&scene, l, 0)).collect();
    let plain: Vec<FrameRequest> = (0..LAYERS).map(|_| FrameRequest::full_chain(SIZE.0, SIZE.1)).collect();
    let mut stack = GpuStack::new(ctx.clone(), LAYERS).unwrap();
    let refused = |stack: &mut GpuStack, frames: &[&GrayImage], reqs: &[FrameRequest], why: &str| {
        let batch: Vec<(&GrayImage, &FrameRequest)> = frames.iter().copied().zip(reqs).collect();
        match stack.submit(&batch) {
            Err(e) => assert!(e.to_string().contains(why), "{why}: {e}"),
            Ok(_) => panic!("{why}: accepted"),
        }
    };
    let all: Vec<&GrayImage> = frames.iter().collect();
    refused(&mut stack, &all[..2], &plain[..2], "2 frames for a stack of 3");
    let mut other = plain.clone();
    other[1].edges = None;
    refused(&mut stack, &all, &other, "stacked frame 1 asks for other stages");
    let mut capped = plain.clone();
    capped[2].edges.as_mut().unwrap().list.cap = Some(10);
    refused(&mut stack, &all, &capped, "stacked frame 2 asks for other stages");
    let small = GrayImage::from_fn(SIZE.0 - 1, SIZE.1, |x, _| x as u8);
    refused(&mut stack, &[all[0], &small, all[2]], &plain, "stacked frame 1 is 130x67");
    assert!(GpuStack::new(ctx.clone(), 0).is_err());
    assert!(stack.reset_layer(LAYERS).is_err());
    stack.check_frame_size(SIZE.0, SIZE.1).unwrap();
    let too_large = stack.check_frame_size(100_000, 100_000).unwrap_err().to_string();
    assert!(too_large.contains("buffer limit"), "{too_large}");
    // Two steps in flight, not three.
    let batch: Vec<(&GrayImage, &FrameRequest)> = all.iter().copied().zip(&plain).collect();
    let first = stack.submit(&batch).unwrap();
    let second = stack.submit(&batch).unwrap();
    refused(&mut stack, &all, &plain, "frames in flight");
    for t in [first, second] {
        assert_eq!(stack.finish(t).unwrap().len(), LAYERS);
    }
    stack.submit(&batch).map(|t| stack.finish(t)).unwrap().unwrap();
}
