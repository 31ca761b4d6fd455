//! The exponentially weighted least-squares polynomial motion model of 002
//! §2.10 (eq. 13–15), solved recursively by a square-root information filter.
//!
//! # Eq. 14 recursively
//!
//! The polynomial is kept in time relative to the latest sample,
//! c(n) = Σ_k a_k·(n − t)^k, which is the polynomial of eq. 13 re-parametrised
//! (no conditioning problem for large t). Moving t to t + d multiplies the
//! coefficient vector by the binomial shift Φ_d (`Φ_d[i][j] = C(j, i)·d^(j−i)`);
//! the square-root information equation R·a = z becomes R·Φ_{−d}·a' = z, and
//! the exponential decay of eq. 14 multiplies (R, z) by λ^{d/2}. A sample c
//! with variance C adds the row (1/√C)·[1, 0, …, 0] | c/√C, folded into R by
//! Givens rotations. Without a prior the result equals the batch weighted
//! least-squares solution of eq. 14 (test `srif_equals_batch_eq_14`).

#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use crate::{Error, Result};

/// Binomial coefficient C(n, k) as f64 (small n).
fn binomial(n: usize, k: usize) -> f64 {
    if k > n {
        return 0.0;
    }
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// Exponentially weighted least-squares fit of a polynomial of N
/// coefficients (degree N − 1) to a time series (eq. 13–14), solved by a
/// square-root information filter (module doc, "Eq. 14 recursively").
/// N = 3 is the paper's 2nd-order motion model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolynomialSrif<const N: usize> {
    lambda: f64,
    /// Upper triangular square-root information matrix.
    r: [[f64; N]; N],
    /// Information-weighted state, R·a = z.
    z: [f64; N],
    /// Time of the latest sample (the polynomial's origin).
    time: f64,
    /// Samples taken.
    samples: usize,
}

impl<const N: usize> PolynomialSrif<N> {
    /// An empty filter (no information) at time `time`, decay 0 < λ ≤ 1.
    pub fn new(lambda: f64, time: f64) -> Result<Self> {
        if !(lambda > 0.0 && lambda <= 1.0) || N == 0 || !time.is_finite() {
            return Err(Error::Parameter(format!("polynomial filter: decay lambda must be in (0, 1], got {lambda}")));
        }
        Ok(Self { lambda, r: [[0.0; N]; N], z: [0.0; N], time, samples: 0 })
    }

    /// The decay factor λ.
    #[must_use]
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    /// Time of the polynomial's origin (the latest sample or advance).
    #[must_use]
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Samples taken so far.
    #[must_use]
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Add prior information: coefficient `index` (relative to the current
    /// time) is `value` with variance `variance`. Decays like a sample.
    pub fn add_prior(&mut self, index: usize, value: f64, variance: f64) {
        if index >= N || !(variance > 0.0 && variance.is_finite() && value.is_finite()) {
            return;
        }
        let mut row = [0.0; N];
        let sw = 1.0 / variance.sqrt();
        row[index] = sw;
        self.fold_row(row, value * sw);
    }

    /// Move the polynomial's origin to `time` (≥ the current one): shift
    /// the coefficients (Φ) and decay the information by λ^{Δt} (eq. 14).
    pub fn advance_to(&mut self, time: f64) {
        let d = time - self.time;
        if !(d > 0.0 && d.is_finite()) {
            return;
        }
        // R ← R·Φ_{−d}, Φ_{−d}[i][j] = C(j, i)·(−d)^{j−i}.
        let mut shifted = [[0.0; N]; N];
        for (i, row) in shifted.iter_mut().enumerate() {
            for (j, entry) in row.iter_mut().enumerate().skip(i) {
                *entry = (i..=j).map(|k| self.r[i][k] * binomial(j, k) * (-d).powi((j - k) as i32)).sum();
            }
        }
        let decay = self.lambda.powf(0.5 * d);
        for (i, row) in shifted.iter().enumerate() {
            for j in 0..N {
                self.r[i][j] = decay * row[j];
            }
            self.z[i] *= decay;
        }
        self.time = time;
    }

    /// Take the sample `value` with variance `variance` at `time`
    /// (advancing to it first); ignored unless finite with variance > 0.
    pub fn update(&mut self, time: f64, value: f64, variance: f64) {
        if !(variance > 0.0 && variance.is_finite() && value.is_finite()) {
            return;
        }
        self.advance_to(time);
        let sw = 1.0 / variance.sqrt();
        let mut row = [0.0; N];
        row[0] = sw; // h = [1, 0, …] at τ = 0
        self.fold_row(row, value * sw);
        self.samples += 1;
    }

    /// Fold the information row (row | rhs) into (R, z) by Givens rotations.
    fn fold_row(&mut self, mut row: [f64; N], mut rhs: f64) {
        for i in 0..N {
            if row[i] == 0.0 {
                continue;
            }
            let rho = self.r[i][i].hypot(row[i]);
            let (cs, sn) = (self.r[i][i] / rho, row[i] / rho);
            for j in i..N {
                let (a, b) = (self.r[i][j], row[j]);
                self.r[i][j] = cs * a + sn * b;
                row[j] = -sn * a + cs * b;
            }
            let (a, b) = (self.z[i], rhs);
            self.z[i] = cs * a + sn * b;
            rhs = -sn * a + cs * b;
        }
    }

    /// Whether R is invertible (enough information for every coefficient).
    fn determined(&self) -> bool {
        let scale = (0..N).map(|i| self.r[i][i].abs()).fold(0.0, f64::max);
        scale > 0.0 && (0..N).all(|i| self.r[i][i].abs() > 1e-12 * scale)
    }

    /// Coefficients a_k of c(n) = Σ a_k·(n − time)^k; `None` until determined.
    #[must_use]
    pub fn coefficients(&self) -> Option<[f64; N]> {
        if !self.determined() {
            return None;
        }
        let mut a = [0.0; N];
        for i in (0..N).rev() {
            let s: f64 = (i + 1..N).map(|j| self.r[i][j] * a[j]).sum();
            a[i] = (self.z[i] - s) / self.r[i][i];
        }
        Some(a)
    }

    /// Covariance of the coefficients, (RᵀR)⁻¹; `None` until determined.
    #[must_use]
    pub fn covariance(&self) -> Option<[[f64; N]; N]> {
        if !self.determined() {
            return None;
        }
        // R⁻¹ (upper triangular) by back substitution.
        let mut ri = [[0.0; N]; N];
        for c in 0..N {
            for i in (0..=c).rev() {
                let rhs = if i == c { 1.0 } else { 0.0 };
                let s: f64 = (i + 1..=c).map(|k| self.r[i][k] * ri[k][c]).sum();
                ri[i][c] = (rhs - s) / self.r[i][i];
            }
        }
        Some(std::array::from_fn(|i| std::array::from_fn(|j| (i.max(j)..N).map(|k| ri[i][k] * ri[j][k]).sum())))
    }

    /// Eq. 15 generalised: the polynomial's value `tau` after its origin
    /// (τ = 1: the next image; fractional τ: e.g. the next servo cycle).
    #[must_use]
    pub fn predict(&self, tau: f64) -> Option<f64> {
        let a = self.coefficients()?;
        Some(a.iter().rev().fold(0.0, |acc, &c| acc * tau + c))
    }

    /// Variance of [`PolynomialSrif::predict`] from the coefficients'
    /// covariance (the weights' scale, not the model's adequacy).
    #[must_use]
    pub fn prediction_variance(&self, tau: f64) -> Option<f64> {
        let p = self.covariance()?;
        let h: [f64; N] = std::array::from_fn(|k| tau.powi(k as i32));
        Some((0..N).map(|i| (0..N).map(|j| h[i] * p[i][j] * h[j]).sum::<f64>()).sum())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srif_fits_a_parabola_exactly_and_shifts_time() {
        let mut f = PolynomialSrif::<3>::new(0.8, 0.0).expect("lambda");
        let c = |t: f64| 2.0 - 0.5 * t + 0.25 * t * t;
        assert!(f.coefficients().is_none());
        for t in 0..6 {
            f.update(f64::from(t), c(f64::from(t)), 1.0);
        }
        // Relative to t = 5: c(5 + τ) = 5.75 + 2τ + 0.25τ² (c(5) = 2 − 2.5 + 6.25).
        let a = f.coefficients().expect("determined");
        assert!((a[0] - 5.75).abs() < 1e-9 && (a[1] - 2.0).abs() < 1e-9 && (a[2] - 0.25).abs() < 1e-9, "{a:?}");
        assert!((f.predict(1.0).expect("p") - c(6.0)).abs() < 1e-9);
        assert!((f.predict(2.5).expect("p") - c(7.5)).abs() < 1e-9);
        let before = f.prediction_variance(1.0).expect("var");
        f.advance_to(7.0);
        assert!((f.predict(0.0).expect("p") - c(7.0)).abs() < 1e-9);
        assert!(f.prediction_variance(-1.0).expect("var") > before, "decay loses information");
    }
}
