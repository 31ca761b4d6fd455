//! GPU/CPU parity of `shaders/temporal_diff.wgsl` against
//! `early::temporal_diff`.
//!
//! Tolerance: masks are exact, except pixels whose `|prev − cur|` lies
//! within [`NEAR_THRESHOLD`] of the threshold, which are counted and
//! allowed. (The difference is one correctly rounded f32 subtraction on both
//! sides, so in practice there are none.)
use crate::common;
use crate::per_size;

use pipetrack::FloatImage;
use pipetrack::early::gaussian::{self, GaussianParams};
use pipetrack::early::temporal_diff::{self, MOVING, STILL, TemporalDiffParams};
use pipetrack::testimage::natural;

/// Pixels this close to the threshold may differ between the twins.
const NEAR_THRESHOLD: f32 = 1e-3;

/// Two smoothed frames of one natural scene translated by `(dx, dy)` pixels
/// between them, as the real chain feeds the stage.
fn moving_pair(w: usize, h: usize, seed: u64, dx: usize, dy: usize) -> (FloatImage, FloatImage) {
    let scene = natural(w + dx, h + dy, seed).to_f32();
    let prev = FloatImage::from_fn(w, h, |x, y| scene.get(x, y));
    let cur = FloatImage::from_fn(w, h, |x, y| scene.get(x + dx, y + dy));
    let g = GaussianParams::default();
    (gaussian::gaussian(&prev, &g).unwrap(), gaussian::gaussian(&cur, &g).unwrap())
}

/// Assert the masks are equal except near the threshold; returns how many
/// pixels sit near it and how many of those differ.
fn assert_masks_match(
    name: &str,
    prev: &FloatImage,
    cur: &FloatImage,
    threshold: f32,
    cpu: &FloatImage,
    gpu: &FloatImage,
) -> (usize, usize) {
    assert_eq!(cpu.size(), gpu.size(), "{name}: sizes differ");
    let w = cpu.width().max(1);
    let (mut near, mut near_differing) = (0, 0);
    let mut bad = Vec::new();
    for (i, (((&c, &g), &p), &q)) in cpu.data().iter().zip(gpu.data()).zip(prev.data()).zip(cur.data()).enumerate() {
        assert!(c == MOVING || c == STILL, "{name}: cpu mask value {c}");
        let is_near = ((p - q).abs() - threshold).abs() <= NEAR_THRESHOLD;
        near += usize::from(is_near);
        near_differing += usize::from(is_near && c != g);
        if c != g && !is_near {
            bad.push(format!("  ({}, {}): cpu {c} gpu {g} |prev−cur| {}", i % w, i / w, (p - q).abs()));
        }
    }
    assert!(
        bad.is_empty(),
        "{name}: {} mask pixels differ; first ones:\n{}",
        bad.len(),
        bad[..bad.len().min(10)].join("\n")
    );
    (near, near_differing)
}

fn parity_temporal_diff_thresholds(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_temporal_diff_thresholds/{w}x{h}")) else {
        return;
    };
    let (prev, cur) = moving_pair(w, h, 21, 3, 2);
    for threshold in [TemporalDiffParams::default().threshold, 2.0, 0.5, 0.0] {
        let p = TemporalDiffParams { threshold };
        let cpu = temporal_diff::temporal_diff(&prev, &cur, &p).unwrap();
        let gpu = temporal_diff::temporal_diff_gpu(ctx, &prev, &cur, &p).unwrap();
        let name = format!("temporal_diff/{w}x{h}/t{threshold}");
        let (near, near_differing) = assert_masks_match(&name, &prev, &cur, threshold, &cpu, &gpu);
        let moving = cpu.data().iter().filter(|&&v| v == MOVING).count();
        eprintln!("{name}: {moving} moving, {near} near the threshold, {near_differing} of them differ");
        if w * h > 1000 {
            // The test must be able to fail: both classes present.
            assert!(moving > 0 && moving < w * h, "{name}: degenerate mask ({moving} moving)");
        }
    }
}
per_size!(parity_temporal_diff_thresholds);

fn parity_temporal_diff_integer_differences_on_the_threshold(w: usize, h: usize) {
    // Unsmoothed 8-bit frames: many differences are exactly the threshold
    // (not moving, strict >) or one grey level above it (moving).
    let Some((ctx, _g)) = common::gpu(&format!("parity_temporal_diff_integer_differences_on_the_threshold/{w}x{h}"))
    else {
        return;
    };
    let prev = natural(w, h, 5).to_f32();
    let cur = FloatImage::from_fn(w, h, |x, y| prev.get(x, y) + ((x + 3 * y) % 5) as f32 + 6.0);
    let p = TemporalDiffParams { threshold: 8.0 };
    let cpu = temporal_diff::temporal_diff(&prev, &cur, &p).unwrap();
    let gpu = temporal_diff::temporal_diff_gpu(ctx, &prev, &cur, &p).unwrap();
    common::assert_equal(&format!("temporal_diff_integer/{w}x{h}"), &cpu, &gpu);
}
per_size!(parity_temporal_diff_integer_differences_on_the_threshold);

/// The fused entry point (mask and frame sum in one dispatch, as the GPU
/// backend runs them) against the CPU backend's fused twin: the mask equal
/// (integer differences on and one level above the threshold, and smoothed
/// frames), the sum equal, bit for bit.
fn parity_temporal_diff_and_sum_exact(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_temporal_diff_and_sum_exact/{w}x{h}")) else {
        return;
    };
    let integer = natural(w, h, 5).to_f32();
    let shifted = FloatImage::from_fn(w, h, |x, y| integer.get(x, y) + ((x + 3 * y) % 5) as f32 + 6.0);
    for (what, prev, cur) in [
        ("integer", integer.clone(), shifted),
        ("smoothed", moving_pair(w, h, 21, 3, 2).0, moving_pair(w, h, 21, 3, 2).1),
    ] {
        let p = TemporalDiffParams::default();
        let (mut mask, mut sum) = (FloatImage::new(0, 0), FloatImage::new(0, 0));
        let full = pipetrack::early::Window::full(w, h);
        temporal_diff::temporal_diff_and_sum_cpu(&prev, &cur, &p, full, &mut mask, &mut sum).unwrap();
        let (gpu_mask, gpu_sum) = temporal_diff::temporal_diff_and_sum_gpu(ctx, &prev, &cur, &p).unwrap();
        common::assert_equal(&format!("temporal_diff_and_sum/{what}/{w}x{h}/mask"), &mask, &gpu_mask);
        common::assert_equal(&format!("temporal_diff_and_sum/{what}/{w}x{h}/sum"), &sum, &gpu_sum);
        if w * h > 1000 {
            let moving = mask.data().iter().filter(|&&v| v == MOVING).count();
            assert!(moving > 0 && moving < w * h, "{what}/{w}x{h}: degenerate mask ({moving} moving)");
        }
    }
}
per_size!(parity_temporal_diff_and_sum_exact);
