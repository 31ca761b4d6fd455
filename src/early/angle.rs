//! A fast arctangent shared by the CPU twins, and its GPU twin
//! `shaders/angle.wgsl` ([`INCLUDE`]), which the Sobel and zero-crossing
//! shaders include: the same polynomial (`fast_atan`,
//! `fast_atan_quotient`, `fast_atan2`),
//! operation for operation, so GPU and CPU orientations agree to a few ULPs
//! while the CPU avoids libm's `atan`, which would otherwise dominate the
//! Sobel and zero-crossing stages' cost. Both functions are branch-free in
//! effect (every `if` is a select), so loops calling them vectorise.

use std::f32::consts::{FRAC_PI_2, PI};

use crate::gpu::Include;

/// `shaders/angle.wgsl`: `PI`, `HALF_PI`, `fast_atan` and `fast_atan2` for
/// the shaders that list it in their `includes`.
pub const INCLUDE: Include = Include { name: "angle", source: include_str!("../../shaders/angle.wgsl") };

/// Coefficients of atan(a) ≈ a·Σ C[k]·a^(2k) on [0, 1] (Hastings' degree-15
/// odd polynomial, error below 1e-7 rad in exact arithmetic; in f32 the
/// result is within a few ULPs, checked against f64 below). Written digit
/// for digit as in `shaders/angle.wgsl`, so the two can be compared by eye;
/// both round each literal to the same f32.
#[allow(clippy::excessive_precision)]
const C: [f32; 8] = [
    0.999_999_33,
    -0.333_298_56,
    0.199_465_36,
    -0.139_085_34,
    0.096_420_044,
    -0.055_909_886,
    0.021_861_229,
    -0.004_054_058,
];

/// atan(a) for `a` in [0, 1]: the polynomial in `s = a²` by Estrin's
/// scheme — pairs of coefficients first, then the pairs in `s²`, then the
/// halves in `s⁴` (the shader uses the same order) — whose chain of
/// dependent operations is half as long as Horner's, so a vectorised loop
/// keeps more of them in flight.
#[inline]
fn atan_unit(a: f32) -> f32 {
    let s = a * a;
    let s2 = s * s;
    let s4 = s2 * s2;
    let (q0, q1, q2, q3) = (C[1] * s + C[0], C[3] * s + C[2], C[5] * s + C[4], C[7] * s + C[6]);
    let p = (q1 * s2 + q0) + (q3 * s2 + q2) * s4;
    p * a
}

/// `atan(t)` for any finite `t`, in (−π/2, π/2): the polynomial on
/// `[0, 1]`, with `atan(t) = π/2 − atan(1/t)` beyond.
#[inline]
#[must_use]
pub fn fast_atan(t: f32) -> f32 {
    let at = t.abs();
    let invert = at > 1.0;
    let a = if invert { 1.0 / at } else { at };
    let r = atan_unit(a);
    let r = if invert { FRAC_PI_2 - r } else { r };
    if t < 0.0 { -r } else { r }
}

/// `atan(y / x)` in [−π/2, π/2] for `x ≠ 0`, with one division: the
/// polynomial of `min(|x|, |y|) / max(|x|, |y|)`, reflected as
/// `π/2 − atan(|x|/|y|)` where `|y| > |x|`, negative where `x` and `y`
/// differ in sign (a `−0` counts as positive). Within a few ULPs of
/// [`fast_atan`]`(y / x)`, which divides twice.
#[inline]
#[must_use]
pub fn fast_atan_quotient(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let invert = ay > ax;
    // Select first, divide once (a vectorised loop would divide both ways).
    let (num, den) = if invert { (ax, ay) } else { (ay, ax) };
    let r = atan_unit(num / den);
    let r = if invert { FRAC_PI_2 - r } else { r };
    if (x < 0.0) != (y < 0.0) { -r } else { r }
}

/// `atan2(y, x)` in (−π, π], with `atan2(0, 0) = 0` (defined, unlike WGSL's).
#[inline]
#[must_use]
pub fn fast_atan2(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    // Selects rather than `f32::max`/`min`, whose NaN rules cost extra
    // instructions in a vectorised loop; `ax`, `ay` are never NaN or −0 here
    // (finite inputs, absolute values), where the two agree.
    let hi = if ax > ay { ax } else { ay };
    let lo = if ax > ay { ay } else { ax };
    let a = if hi > 0.0 { lo / hi } else { 0.0 };
    let mut r = atan_unit(a);
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 { -r } else { r }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_f64_atan2_within_1e6_everywhere() {
        let mut worst = 0.0f64;
        for i in -200..=200 {
            for j in -200..=200 {
                let (y, x) = (i as f32 * 0.37, j as f32 * 0.53);
                if x == 0.0 && y == 0.0 {
                    continue;
                }
                let exact = (y as f64).atan2(x as f64);
                let mut d = (fast_atan2(y, x) as f64 - exact).abs();
                if d > std::f64::consts::PI {
                    d = 2.0 * std::f64::consts::PI - d; // ±π are the same direction
                }
                worst = worst.max(d);
            }
        }
        assert!(worst < 1e-6, "worst error {worst}");
    }

    #[test]
    fn fast_atan_matches_f64_atan() {
        let mut worst = 0.0f64;
        for i in -4000..=4000 {
            let t = i as f32 * 0.01;
            worst = worst.max((fast_atan(t) as f64 - (t as f64).atan()).abs());
        }
        assert!(worst < 1e-6, "worst error {worst}");
        assert!((fast_atan(1e30) - FRAC_PI_2).abs() < 1e-6);
    }

    #[test]
    fn quotient_matches_f64_atan_of_the_quotient() {
        let mut worst = 0.0f64;
        for i in -300..=300 {
            for j in -300..=300 {
                let (y, x) = (i as f32 * 0.37, j as f32 * 0.53);
                if x == 0.0 {
                    continue;
                }
                let exact = (y as f64 / x as f64).atan();
                worst = worst.max((fast_atan_quotient(y, x) as f64 - exact).abs());
            }
        }
        assert!(worst < 1e-6, "worst error {worst}");
        assert_eq!(fast_atan_quotient(0.0, 1.0), 0.0);
        assert_eq!(fast_atan_quotient(-0.0, -1.0), 0.0);
        assert!((fast_atan_quotient(1e30, 1.0) - FRAC_PI_2).abs() < 1e-6);
        assert!((fast_atan_quotient(1.0, -1e-30) + FRAC_PI_2).abs() < 1e-6);
    }

    #[test]
    fn axes_and_origin() {
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
        assert_eq!(fast_atan2(0.0, 1.0), 0.0);
        assert!((fast_atan2(1.0, 0.0) - FRAC_PI_2).abs() < 1e-6);
        assert!((fast_atan2(0.0, -1.0) - PI).abs() < 1e-6);
        assert!((fast_atan2(-1.0, 0.0) + FRAC_PI_2).abs() < 1e-6);
    }
}
