//! GPU/CPU parity of `shaders/sobel.wgsl` against `early::sobel`.
//!
//! Tolerances:
//! - gx, gy, magnitude: `|gpu − cpu| ≤ 1e-3 + 1e-5·|cpu|` (gx and gy are
//!   formed in the same order on both sides and come out equal in practice;
//!   the magnitude may differ by a few ULPs of sqrt/fma);
//! - direction modulo 2π and theta modulo π: within 1e-4 rad wherever the
//!   CPU magnitude is ≥ 1e-2 (below that the angle is ill-defined);
//! - where the CPU gradient is exactly zero, the GPU must write the guarded
//!   values exactly: direction 0, theta π/2.
use crate::common;
use crate::per_size;

use std::f32::consts::{FRAC_PI_2, PI};

use pipetrack::FloatImage;
use pipetrack::early::frame_sum;
use pipetrack::early::gaussian::{self, GaussianParams};
use pipetrack::early::sobel::{self, SobelOutput};
use pipetrack::testimage::natural;

const ATOL: f32 = 1e-3;
const RTOL: f32 = 1e-5;
const ANGLE_MIN_MAGNITUDE: f32 = 1e-2;
const ANGLE_ATOL: f32 = 1e-4;

fn max_abs_diff(a: &FloatImage, b: &FloatImage) -> f32 {
    a.data().iter().zip(b.data()).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

/// Largest angle difference modulo `period` where the magnitude allows comparing.
fn max_angle_diff(a: &FloatImage, b: &FloatImage, magnitude: &FloatImage, period: f32) -> f32 {
    let pairs = a.data().iter().zip(b.data()).zip(magnitude.data());
    pairs
        .filter(|&(_, &m)| m >= ANGLE_MIN_MAGNITUDE)
        .map(|((x, y), _)| {
            let d = (y - x).rem_euclid(period);
            d.min(period - d)
        })
        .fold(0.0, f32::max)
}

fn assert_sobel_parity(name: &str, cpu: &SobelOutput, gpu: &SobelOutput) {
    eprintln!(
        "{name}: max |gpu − cpu| gx {} gy {} magnitude {} direction {} theta {}",
        max_abs_diff(&cpu.gx, &gpu.gx),
        max_abs_diff(&cpu.gy, &gpu.gy),
        max_abs_diff(&cpu.magnitude, &gpu.magnitude),
        max_angle_diff(&cpu.direction, &gpu.direction, &cpu.magnitude, 2.0 * PI),
        max_angle_diff(&cpu.theta, &gpu.theta, &cpu.magnitude, PI)
    );
    common::assert_close(&format!("{name}/gx"), &cpu.gx, &gpu.gx, ATOL, RTOL);
    common::assert_close(&format!("{name}/gy"), &cpu.gy, &gpu.gy, ATOL, RTOL);
    common::assert_close(&format!("{name}/magnitude"), &cpu.magnitude, &gpu.magnitude, ATOL, RTOL);
    let m = &cpu.magnitude;
    common::assert_angles_close(
        &format!("{name}/direction"),
        &cpu.direction,
        &gpu.direction,
        m,
        ANGLE_MIN_MAGNITUDE,
        2.0 * PI,
        ANGLE_ATOL,
    );
    common::assert_angles_close(
        &format!("{name}/theta"),
        &cpu.theta,
        &gpu.theta,
        m,
        ANGLE_MIN_MAGNITUDE,
        PI,
        ANGLE_ATOL,
    );
    for i in 0..cpu.gx.data().len() {
        let (d, t) = (gpu.direction.data()[i], gpu.theta.data()[i]);
        assert!(d > -PI && d <= PI, "{name}: gpu direction {d} out of (−π, π] at index {i}");
        assert!((0.0..PI).contains(&t), "{name}: gpu theta {t} out of [0, π) at index {i}");
        if cpu.gx.data()[i] == 0.0 && cpu.gy.data()[i] == 0.0 {
            assert_eq!((d, t), (0.0, FRAC_PI_2), "{name}: zero-gradient guard at index {i}");
        }
    }
}

fn parity_sobel_smoothed_natural(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_sobel_smoothed_natural/{w}x{h}")) else { return };
    let g = GaussianParams::default();
    let src = gaussian::gaussian(&natural(w, h, 41).to_f32(), &g).unwrap();
    let cpu = sobel::sobel(&src);
    let gpu = sobel::sobel_gpu(ctx, &src).unwrap();
    assert_sobel_parity(&format!("sobel/{w}x{h}"), &cpu, &gpu);
}
per_size!(parity_sobel_smoothed_natural);

fn parity_sobel_on_frame_sum(w: usize, h: usize) {
    // The input 000 actually differentiates: the sum of two smoothed frames.
    let Some((ctx, _g)) = common::gpu(&format!("parity_sobel_on_frame_sum/{w}x{h}")) else { return };
    let g = GaussianParams::default();
    let a = gaussian::gaussian(&natural(w, h, 42).to_f32(), &g).unwrap();
    let b = gaussian::gaussian(&natural(w, h, 43).to_f32(), &g).unwrap();
    let src = frame_sum::frame_sum(&a, &b).unwrap();
    let cpu = sobel::sobel(&src);
    let gpu = sobel::sobel_gpu(ctx, &src).unwrap();
    assert_sobel_parity(&format!("sobel_sum/{w}x{h}"), &cpu, &gpu);
}
per_size!(parity_sobel_on_frame_sum);

fn parity_sobel_flat_regions_and_axis_edges(w: usize, h: usize) {
    // Natural image quantised to 4 levels: large flat areas (zero-gradient
    // guard), and many pixels with gx = 0 or gy = 0 exactly (axis cases).
    let Some((ctx, _g)) = common::gpu(&format!("parity_sobel_flat_regions_and_axis_edges/{w}x{h}")) else { return };
    let raw = natural(w, h, 44).to_f32();
    let src = FloatImage::from_fn(w, h, |x, y| (raw.get(x, y) / 64.0).floor() * 64.0);
    let cpu = sobel::sobel(&src);
    let gpu = sobel::sobel_gpu(ctx, &src).unwrap();
    let name = format!("sobel_flat/{w}x{h}");
    assert_sobel_parity(&name, &cpu, &gpu);
    if w * h > 1000 {
        let zero = cpu.magnitude.data().iter().filter(|&&m| m == 0.0).count();
        let axis = cpu.gx.data().iter().zip(cpu.gy.data()).filter(|&(&x, &y)| (x == 0.0) != (y == 0.0)).count();
        assert!(zero > 0 && axis > 0, "{name}: test image lacks guard cases ({zero} flat, {axis} axis)");
    }
}
per_size!(parity_sobel_flat_regions_and_axis_edges);
