//! The steps of 004's velocity-screw tracker (Fig. 2), in the paper's order,
//! each a function named for what it does.
//!
//! A *screw* `s = (T_x, T_y, T_z, ω_x, ω_y, ω_z)` (eq. 14) is the motion of
//! the scene relative to the camera over one step, in the sense of the image
//! Jacobian of eq. 21: a point moves by `Ṗ = T + ω × P` (camera frame), its
//! pixel by `J(u, v, Z)·s` (eq. 20). The camera itself moves by the opposite.
//! Applied exactly, a screw is the rigid motion `P ↦ R(ω)·P + T`.

use glam::DVec3;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::early::window_energy::Quad;
use crate::geometry::Camera;
use crate::geometry::pose::{Pose, rotation_from_axis_angle};

/// A velocity screw (T_x, T_y, T_z, ω_x, ω_y, ω_z), eq. 14.
pub type Screw = [f64; 6];

/// The screw of a known camera motion: camera 1 in the frame of camera 0 as
/// `[tx, ty, tz, rx, ry, rz]` (SPEC §4). Scene points seen from camera 1 are
/// `C⁻¹·P`, so the screw is the translation and axis-angle of `C⁻¹`.
#[must_use]
pub fn screw_of_camera_motion(motion: &[f64; 6]) -> Screw {
    let camera =
        Pose::from_axis_angle(DVec3::new(motion[3], motion[4], motion[5]), DVec3::new(motion[0], motion[1], motion[2]));
    screw_of_motion(&camera.inverse())
}

/// The rigid motion of `screw`, `P ↦ R(ω)·P + T`.
#[must_use]
pub fn screw_motion(screw: &Screw) -> Pose {
    Pose::new(
        rotation_from_axis_angle(DVec3::new(screw[3], screw[4], screw[5])),
        DVec3::new(screw[0], screw[1], screw[2]),
    )
}

/// The screw whose rigid motion is `motion` (its translation and axis-angle).
#[must_use]
pub fn screw_of_motion(motion: &Pose) -> Screw {
    let (t, r) = (motion.translation, motion.axis_angle());
    [t.x, t.y, t.z, r.x, r.y, r.z]
}

/// §III-B.3: the initial sample set, N draws from N(r_i, diag σ²).
pub fn draw_initial_samples(mean: &Screw, sigma: &Screw, n: usize, rng: &mut impl Rng) -> Vec<Screw> {
    (0..n).map(|_| std::array::from_fn(|k| mean[k] + sigma[k] * gaussian(rng))).collect()
}

fn gaussian(rng: &mut impl Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// The screw components' standard deviations for which each component alone
/// moves the window's corners by `px` RMS (through eq. 21 at the corners and
/// their depths), times its weight; 0 for a component that does not move
/// the corners.
#[must_use]
pub fn component_sigmas(camera: &Camera, corners: &[[f64; 2]], depths: &[f64], px: f64, weights: &Screw) -> Screw {
    let mut sums = [0.0; 6];
    for (corner, &z) in corners.iter().zip(depths) {
        let j = camera.image_jacobian(*corner, z);
        for k in 0..6 {
            sums[k] += j[0][k] * j[0][k] + j[1][k] * j[1][k];
        }
    }
    let n = corners.len().max(1) as f64;
    std::array::from_fn(|k| {
        let rms = (sums[k] / n).sqrt();
        if rms > 0.0 { weights[k] * px / rms } else { 0.0 }
    })
}

/// Fig. 2 step 1, eq. 20–21: the sample window of each screw, `f' = f + J(f, Z)·s`
/// at each vertex `f` of the reference window and its depth `Z`.
#[must_use]
pub fn project_sample_windows(
    camera: &Camera,
    corners: &[[f64; 2]; 4],
    depths: &[f64; 4],
    samples: &[Screw],
) -> Vec<Quad> {
    let jacobians: [[[f64; 6]; 2]; 4] = std::array::from_fn(|i| camera.image_jacobian(corners[i], depths[i]));
    samples
        .iter()
        .map(|s| {
            std::array::from_fn(|i| {
                let j = &jacobians[i];
                let du: f64 = (0..6).map(|k| j[0][k] * s[k]).sum();
                let dv: f64 = (0..6).map(|k| j[1][k] * s[k]).sum();
                [(corners[i][0] + du) as f32, (corners[i][1] + dv) as f32]
            })
        })
        .collect()
}

/// Smallest energy a weight is taken from: an exact match (U = 0) weighs as
/// much as this, not infinitely.
pub const MIN_ENERGY: f64 = 1e-12;

/// Eq. 27–28: π_n = 1/U_n, normalised to sum to 1; a window whose energy
/// is not a finite number weighs nothing.
#[must_use]
pub fn weights_from_energies(energies: &[f32]) -> Vec<f64> {
    let raw: Vec<f64> =
        energies.iter().map(|&u| if u.is_finite() { 1.0 / f64::from(u).max(MIN_ENERGY) } else { 0.0 }).collect();
    let total: f64 = raw.iter().sum();
    if !(total.is_finite() && total > 0.0) {
        return vec![1.0 / energies.len().max(1) as f64; energies.len()];
    }
    raw.iter().map(|w| w / total).collect()
}

/// Eq. 17–18: c_0 = 0, c_n = c_{n−1} + π_n (returned without c_0).
#[must_use]
pub fn cumulative_weights(weights: &[f64]) -> Vec<f64> {
    weights
        .iter()
        .scan(0.0, |c, &w| {
            *c += w;
            Some(*c)
        })
        .collect()
}

/// §III-A: each new sample is the first s_n whose cumulative weight exceeds
/// a uniform r ∈ [0, c_N) (eq. 16: chosen with probability π_n).
pub fn resample(samples: &[Screw], cumulative: &[f64], rng: &mut impl Rng) -> Vec<Screw> {
    let total = cumulative.last().copied().unwrap_or(0.0);
    (0..samples.len())
        .map(|_| {
            let r = rng.random_range(0.0..1.0) * total;
            let n = cumulative.partition_point(|&c| c <= r).min(samples.len() - 1);
            samples[n]
        })
        .collect()
}

/// Eq. 19: s_n ← s_n − K·s^max (K diagonal).
pub fn drift(samples: &mut [Screw], best: &Screw, gain: &Screw) {
    for s in samples {
        for k in 0..6 {
            s[k] -= gain[k] * best[k];
        }
    }
}

/// Adds `motion` to every sample: the motion expected over the next frame.
pub fn predict(samples: &mut [Screw], motion: &Screw) {
    for s in samples {
        for k in 0..6 {
            s[k] += motion[k];
        }
    }
}

/// §III-B.1: the Brownian random walk, s_n ← s_n + N(0, diag σ²).
pub fn diffuse(samples: &mut [Screw], sigma: &Screw, rng: &mut impl Rng) {
    for s in samples {
        for k in 0..6 {
            s[k] += sigma[k] * gaussian(rng);
        }
    }
}

/// The effective sample size 1 / Σ π_n² of normalised weights.
#[must_use]
pub fn effective_sample_size(weights: &[f64]) -> f64 {
    let sum_sq: f64 = weights.iter().map(|w| w * w).sum();
    if sum_sq > 0.0 { 1.0 / sum_sq } else { 0.0 }
}

/// Index of the largest weight (the first of equals).
#[must_use]
pub fn best_sample(weights: &[f64]) -> usize {
    weights.iter().enumerate().fold(0, |best, (n, &w)| if w > weights[best] { n } else { best })
}

/// The mean of the samples.
#[must_use]
pub fn mean(samples: &[Screw]) -> Screw {
    let n = samples.len().max(1) as f64;
    std::array::from_fn(|k| samples.iter().map(|s| s[k]).sum::<f64>() / n)
}

/// The weighted mean of the samples.
#[must_use]
pub fn weighted_mean(samples: &[Screw], weights: &[f64]) -> Screw {
    let mut mean = [0.0; 6];
    for (s, w) in samples.iter().zip(weights) {
        for k in 0..6 {
            mean[k] += w * s[k];
        }
    }
    mean
}

/// An upper bound on the RMS intensity difference per compared value of a
/// window with energy `energy` (eq. 22): its intensity term is at most
/// `energy · Σ_n C_I` (eq. 25), spread over `values` = 4·K² compared values.
/// Infinite when the energy or the total is not a finite number (no such
/// window matches).
#[must_use]
pub fn residual_bound(energy: f32, intensity_total: f32, values: usize) -> f64 {
    let squared = f64::from(energy) * f64::from(intensity_total) / values.max(1) as f64;
    if squared.is_finite() { squared.max(0.0).sqrt() } else { f64::INFINITY }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// A window whose energy is NaN or infinite is no match: no weight,
    /// an infinite residual (a NaN used to become the best weight and a
    /// residual of 0).
    #[test]
    fn energies_that_are_not_finite_weigh_nothing_and_never_match() {
        let w = weights_from_energies(&[1.0, f32::NAN, f32::INFINITY, 0.5]);
        assert_eq!(w[1], 0.0);
        assert_eq!(w[2], 0.0);
        assert!((w[0] - 1.0 / 3.0).abs() < 1e-12 && (w[3] - 2.0 / 3.0).abs() < 1e-12, "{w:?}");
        assert_eq!(best_sample(&w), 3);
        assert_eq!(residual_bound(f32::NAN, 10.0, 64), f64::INFINITY);
        assert_eq!(residual_bound(1.0, f32::INFINITY, 64), f64::INFINITY);
        assert!((residual_bound(4.0, 16.0, 64) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn weights_are_inverse_energies_normalised() {
        let w = weights_from_energies(&[1.0, 0.5, 0.25]);
        // 1/U = 1, 2, 4, sum 7.
        for (got, want) in w.iter().zip([1.0 / 7.0, 2.0 / 7.0, 4.0 / 7.0]) {
            assert!((got - want).abs() < 1e-12);
        }
        assert_eq!(best_sample(&w), 2);
        let c = cumulative_weights(&w);
        assert!((c[2] - 1.0).abs() < 1e-12 && (c[0] - 1.0 / 7.0).abs() < 1e-12);
        // Equal weights: N effective samples; one weight: 1.
        assert!((effective_sample_size(&[0.25; 4]) - 4.0).abs() < 1e-12);
        assert!((effective_sample_size(&[1.0, 0.0]) - 1.0).abs() < 1e-12);
        // An exact match does not make the weights infinite.
        let w = weights_from_energies(&[0.0, 1.0]);
        assert!(w.iter().all(|v| v.is_finite()) && w[0] > 0.999);
    }

    #[test]
    fn resampling_picks_samples_in_proportion_to_their_weights() {
        let samples: Vec<Screw> = (0..3).map(|i| [i as f64; 6]).collect();
        let c = cumulative_weights(&[0.1, 0.0, 0.9]);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut counts = [0usize; 3];
        for _ in 0..1000 {
            for s in resample(&samples, &c, &mut rng) {
                counts[s[0] as usize] += 1;
            }
        }
        assert_eq!(counts[1], 0);
        let fraction = counts[2] as f64 / 3000.0;
        assert!((fraction - 0.9).abs() < 0.02, "{counts:?}");
    }

    #[test]
    fn drift_subtracts_the_gain_times_the_best() {
        let mut samples = vec![[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]];
        drift(&mut samples, &[1.0; 6], &[0.5, 1.0, 0.0, 0.5, 1.0, 0.0]);
        assert_eq!(samples[0], [0.5, 1.0, 3.0, 3.5, 4.0, 6.0]);
    }

    #[test]
    fn a_camera_motion_and_its_screw_agree() {
        let m = [0.01, -0.01, 0.002, 0.01, -0.02, 0.03];
        let s = screw_of_camera_motion(&m);
        // Scene motion is the inverse of the camera's: to first order its negative.
        for k in 0..6 {
            assert!((s[k] + m[k]).abs() < 1e-3, "{k}: {s:?}");
        }
        let camera = Pose::from_axis_angle(DVec3::new(m[3], m[4], m[5]), DVec3::new(m[0], m[1], m[2]));
        let p = DVec3::new(0.1, 0.2, 0.7);
        let moved = screw_motion(&s).apply(p);
        assert!((moved - camera.inverse().apply(p)).length() < 1e-12);
    }

    #[test]
    fn sigmas_move_the_corners_by_the_asked_pixels() {
        let cam = Camera { width: 320, height: 240, fx: 400.0, fy: 400.0, cx: 159.5, cy: 119.5 };
        let corners = [[127.5, 87.5], [191.5, 87.5], [191.5, 151.5], [127.5, 151.5]];
        let depths = [0.6; 4];
        let sigma = component_sigmas(&cam, &corners, &depths, 2.0, &[1.0, 1.0, 1.0, 1.0, 1.0, 0.0]);
        // T_x: 2 px at 0.6 m and 400 px is 3 mm.
        assert!((sigma[0] - 0.003).abs() < 1e-9, "{sigma:?}");
        assert_eq!(sigma[5], 0.0);
        let mut unit = [0.0; 6];
        unit[2] = sigma[2];
        let moved = project_sample_windows(&cam, &corners, &depths, &[unit]);
        let rms = (0..4)
            .map(|i| {
                (f64::from(moved[0][i][0]) - corners[i][0]).powi(2)
                    + (f64::from(moved[0][i][1]) - corners[i][1]).powi(2)
            })
            .sum::<f64>()
            / 4.0;
        assert!((rms.sqrt() - 2.0).abs() < 1e-3, "{}", rms.sqrt());
    }
}
