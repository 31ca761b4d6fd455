//! GPU/CPU parity of `shaders/zero_crossing.wgsl` against its twin in
//! src/early/zero_crossing.rs.
//!
//! Tolerances:
//! - same LoG input to both twins: the edgel sets are equal exactly (the
//!   decisions compare f32 values computed identically: signs, `|b − a|`
//!   against `min_slope`, `|a|` against `|b|`, slope against slope);
//!   strength and offsets within 1e-4 absolute (a division and a square root
//!   the GPU may round differently); direction within 1e-4 modulo 2π where
//!   there is an edgel.
//! - the chain GPU LoG → GPU edgels against CPU LoG → CPU edgels: the LoGs
//!   differ by up to 2e-3 (tests/parity_log.rs), so decisions near a
//!   threshold may flip. A pixel whose edgel differs is allowed only when one
//!   of its 4 pairs is within [`AMBIGUOUS`] of a decision boundary (a value
//!   near 0, a slope near `min_slope`, `|a|` near `|b|`, or two competing
//!   slopes near each other), and such pixels must stay under 0.5 % of the
//!   edgels. Elsewhere gx, gy within 5e-3 (two LoG errors) and offsets within
//!   1e-2 (slopes are ≥ 1, so t moves by at most ~4e-3).
use crate::common;
use crate::per_size;

use std::f32::consts::TAU;

use pipetrack::FloatImage;
use pipetrack::early::log::{LogParams, log, log_gpu};
use pipetrack::early::zero_crossing::{Edgels, ZeroCrossingParams, zero_crossing, zero_crossing_gpu};
use pipetrack::image::Image;
use pipetrack::testimage::natural;

const VALUE_ATOL: f32 = 1e-4;
const ANGLE_ATOL: f32 = 1e-4;
/// Distance to a decision boundary within which a chain mismatch is allowed.
const AMBIGUOUS: f32 = 1e-2;
const CHAIN_G_ATOL: f32 = 5e-3;
const CHAIN_OFFSET_ATOL: f32 = 1e-2;

fn edgel_mask(e: &Edgels) -> Image<u8> {
    Image::from_vec(
        e.strength.width(),
        e.strength.height(),
        e.strength.data().iter().map(|&s| u8::from(s > 0.0)).collect(),
    )
    .unwrap()
}

fn assert_same_edgels(name: &str, cpu: &Edgels, gpu: &Edgels) {
    common::assert_equal(&format!("{name}/edgels"), &edgel_mask(cpu), &edgel_mask(gpu));
    common::assert_close(&format!("{name}/strength"), &cpu.strength, &gpu.strength, VALUE_ATOL, 0.0);
    common::assert_close(&format!("{name}/offset_x"), &cpu.offset_x, &gpu.offset_x, VALUE_ATOL, 0.0);
    common::assert_close(&format!("{name}/offset_y"), &cpu.offset_y, &gpu.offset_y, VALUE_ATOL, 0.0);
    common::assert_angles_close(
        &format!("{name}/direction"),
        &cpu.direction,
        &gpu.direction,
        &cpu.strength,
        f32::MIN_POSITIVE,
        TAU,
        ANGLE_ATOL,
    );
    // Where there is no edgel, everything is exactly 0 on both sides.
    for e in [cpu, gpu] {
        for (i, &s) in e.strength.data().iter().enumerate() {
            if s == 0.0 {
                assert_eq!(
                    (e.direction.data()[i], e.offset_x.data()[i], e.offset_y.data()[i]),
                    (0.0, 0.0, 0.0),
                    "{name}: pixel {i}"
                );
            }
        }
    }
}

fn parity_zero_crossing_same_log(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_zero_crossing_same_log/{w}x{h}")) else { return };
    let log = log(&natural(w, h, 17).to_f32(), &LogParams::default()).unwrap();
    for min_slope in [1.0f32, 0.25, 8.0] {
        let p = ZeroCrossingParams { min_slope };
        let cpu = zero_crossing(&log, &p);
        let gpu = zero_crossing_gpu(ctx, &log, &p).unwrap();
        if (w, h) == (640, 480) {
            eprintln!("zero_crossing/{w}x{h}/min_slope{min_slope}: {} edgels", cpu.count());
            assert!(cpu.count() > 100, "too few edgels to test anything");
        }
        assert_same_edgels(&format!("zero_crossing/{w}x{h}/min_slope{min_slope}"), &cpu, &gpu);
    }
}
per_size!(parity_zero_crossing_same_log);

/// Small integers −3..=3 as a LoG: exact zeros (positive), exact half-way
/// ties |a| = |b|, slopes exactly at min_slope and equal competing slopes
/// everywhere — every tie-break rule must agree between the twins.
#[test]
fn parity_zero_crossing_ties_and_zeros() {
    let Some((ctx, _g)) = common::gpu("parity_zero_crossing_ties_and_zeros") else { return };
    let (w, h) = (67, 45);
    let log = FloatImage::from_fn(w, h, |x, y| (((x * 5 + y * 3 + x * y * 7 + x * x) % 7) as f32) - 3.0);
    for min_slope in [1.0f32, 2.0, 3.0] {
        let p = ZeroCrossingParams { min_slope };
        let cpu = zero_crossing(&log, &p);
        let gpu = zero_crossing_gpu(ctx, &log, &p).unwrap();
        assert!(cpu.count() > 100);
        assert_same_edgels(&format!("zero_crossing/ties/min_slope{min_slope}"), &cpu, &gpu);
    }
}

/// True when the pair (a, b) sits within AMBIGUOUS of a decision boundary.
fn pair_ambiguous(a: f32, b: f32, min_slope: f32) -> bool {
    a.abs() < AMBIGUOUS
        || b.abs() < AMBIGUOUS
        || ((b - a).abs() - min_slope).abs() < AMBIGUOUS
        || (a.abs() - b.abs()).abs() < AMBIGUOUS
}

/// True when a decision at pixel (x, y) may flip under a LoG error of 2e-3:
/// one of its 4 pairs is ambiguous, or its two pairs along an axis both
/// change sign with slopes within AMBIGUOUS of each other.
fn pixel_ambiguous(l: &FloatImage, x: usize, y: usize, min_slope: f32) -> bool {
    let c = l.get(x, y);
    let at = |dx: isize, dy: isize| l.get_clamped(x as isize + dx, y as isize + dy);
    let crosses = |a: f32, b: f32| (a >= 0.0) != (b >= 0.0);
    [(-1, 0, 1, 0), (0, -1, 0, 1)].iter().any(|&(px, py, nx, ny)| {
        let (prev, next) = (at(px, py), at(nx, ny));
        pair_ambiguous(prev, c, min_slope)
            || pair_ambiguous(c, next, min_slope)
            || (crosses(prev, c) && crosses(c, next) && ((c - prev).abs() - (next - c).abs()).abs() < AMBIGUOUS)
    })
}

fn parity_zero_crossing_chain_gpu_log_vs_cpu_log(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_zero_crossing_chain_gpu_log_vs_cpu_log/{w}x{h}")) else {
        return;
    };
    let lp = LogParams::default();
    let zp = ZeroCrossingParams::default();
    let src = natural(w, h, 19).to_f32();
    let cpu_log = log(&src, &lp).unwrap();
    let gpu_log = log_gpu(ctx, &src, &lp).unwrap();
    let cpu = zero_crossing(&cpu_log, &zp);
    let gpu = zero_crossing_gpu(ctx, &gpu_log, &zp).unwrap();
    let g = |e: &Edgels, i: usize| {
        let (s, d) = (e.strength.data()[i], e.direction.data()[i]);
        (s * d.cos(), s * d.sin())
    };
    let (mut mismatches, mut unexplained) = (0usize, Vec::new());
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let ((cgx, cgy), (ggx, ggy)) = (g(&cpu, i), g(&gpu, i));
            let same = (cpu.strength.data()[i] > 0.0) == (gpu.strength.data()[i] > 0.0)
                && (cgx - ggx).abs() <= CHAIN_G_ATOL
                && (cgy - ggy).abs() <= CHAIN_G_ATOL
                && (cpu.offset_x.data()[i] - gpu.offset_x.data()[i]).abs() <= CHAIN_OFFSET_ATOL
                && (cpu.offset_y.data()[i] - gpu.offset_y.data()[i]).abs() <= CHAIN_OFFSET_ATOL;
            if same {
                continue;
            }
            mismatches += 1;
            if !(pixel_ambiguous(&cpu_log, x, y, zp.min_slope) || pixel_ambiguous(&gpu_log, x, y, zp.min_slope)) {
                unexplained.push(format!(
                    "  ({x}, {y}): cpu s {} dir {} off ({}, {}) | gpu s {} dir {} off ({}, {}) | L cpu {} gpu {}",
                    cpu.strength.data()[i],
                    cpu.direction.data()[i],
                    cpu.offset_x.data()[i],
                    cpu.offset_y.data()[i],
                    gpu.strength.data()[i],
                    gpu.direction.data()[i],
                    gpu.offset_x.data()[i],
                    gpu.offset_y.data()[i],
                    cpu_log.data()[i],
                    gpu_log.data()[i]
                ));
            }
        }
    }
    let edgels = cpu.count();
    eprintln!(
        "zero_crossing chain {w}x{h}: {edgels} edgels, {mismatches} mismatching pixels, all near a decision boundary: {}",
        unexplained.is_empty()
    );
    assert!(
        unexplained.is_empty(),
        "{w}x{h}: {} mismatches not near a decision boundary:\n{}",
        unexplained.len(),
        unexplained.iter().take(10).cloned().collect::<Vec<_>>().join("\n")
    );
    assert!(
        mismatches as f64 <= 0.005 * edgels as f64,
        "{w}x{h}: {mismatches} mismatching pixels of {edgels} edgels (≥ 0.5 %)"
    );
}
per_size!(parity_zero_crossing_chain_gpu_log_vs_cpu_log);
