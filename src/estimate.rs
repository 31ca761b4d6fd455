//! Shared estimation code of paper 002 (Schneiderman et al., "Real-Time
//! Model-Based Visual Tracking"), written once for any tracker:
//!
//! - [`LineLocation`] and [`intersect_lines`]: a fitted line with the
//!   uncertainty of its location (§2.5–2.6, eq. 1–4) and the intersection of
//!   two lines with the covariance of eq. 5–6 (§2.7).
//! - [`BlueProblem`]: the best linear unbiased estimate of a K-vector from
//!   2-D measurements with 2×2 covariances (eq. 7–9, §2.8), its propagated
//!   covariance (eq. 10) and the covariance from the global consistency of
//!   the measurements (eq. 11–12, §2.9).
//! - [`PolynomialSrif`]: the exponentially weighted least-squares fit of a
//!   polynomial in time (eq. 13–14, §2.10), solved recursively by a square-root
//!   information filter, with its prediction any time ahead (eq. 15).
//! - [`AlphaBetaGamma`]: the α-β-γ filter that eq. 16–18 show equivalent to
//!   the one-step predictor of the degree-2 [`PolynomialSrif`] in steady state.
//!
//! # Eq. 6 in general
//! Eq. 5 writes each line as a row of F v = w (horizontal representation
//! y = m·x + b: [m, −1]·v = −b; vertical x = m·y + b: [−1, m]·v = −b) and
//! eq. 6 propagates a diagonal Σ of the lines' "location" variances through
//! F⁻¹. Perturbing (m, b) moves the row's residual by s·dm + db, with s the
//! corner's independent coordinate (v_x for horizontal, v_y for vertical), so
//! to first order the exact Σ_kk is the variance of line k's fitted value at
//! the corner: Var(b + s·m) = σ²·(1/n + (s − s̄)²/S), σ² the empirical point
//! variance of eq. 4, n the number of points, s̄ and S the mean and the
//! centred sum of squares of the independent coordinate
//! ([`CornerCovariance::LineLocation`], the default, checked against Monte
//! Carlo in `tests/blue_logic.rs`). Taking Σ_kk = σ² of eq. 4 itself, as the
//! paper prints it, is [`CornerCovariance::PointVariance`]: it weighs a line
//! by its scatter only, not by its number of points or its extent.
//!
//! # Eq. 11 normalisation
//! Eq. 11 prints e = C_f^{−1/2}(b − A x̂) / trace(C_f^{−1/2}). With equal
//! variances σ² for all 2n coordinates that is e = r/(2n): it shrinks with the
//! number of features and cannot be a feature variance in eq. 12. Here the
//! trace is taken per coordinate, e = C_f^{−1/2} r / (trace(C_f^{−1/2})/2n):
//! the whitened residuals rescaled to pixels by the mean precision, so that
//! for equal variances e = r and eq. 12, C_l = L·diag(e²)·Lᵀ, is the
//! heteroscedasticity-consistent ("sandwich") covariance of the weighted
//! least-squares estimate — each feature contributes the error it actually
//! shows against the global fit, which is what §2.9 asks for.
//!
//! # Eq. 14 recursively
//! The polynomial is kept in time relative to the latest sample,
//! c(n) = Σ_k a_k·(n − t)^k, which is the polynomial of eq. 13 re-parametrised
//! (no conditioning problem for large t). Moving t to t + d multiplies the
//! coefficient vector by the binomial shift Φ_d (Φ_d[i][j] = C(j, i)·d^{j−i});
//! the square-root information equation R·a = z becomes R·Φ_{−d}·a' = z, and
//! the exponential decay of eq. 14 multiplies (R, z) by λ^{d/2}. A sample c
//! with variance C adds the row (1/√C)·[1, 0, …, 0] | c/√C, folded into R by
//! Givens rotations. Without a prior the result equals the batch weighted
//! least-squares solution of eq. 14 (test `srif_equals_batch_eq_14`).

// `!(x > 0.0)` rejects NaN on purpose; index loops mirror the matrix formulas.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use crate::fit::{LineFit, LineSums, Regression};
use crate::{Error, Result};

/// A 2×2 matrix, row-major.
pub type Mat2 = [[f64; 2]; 2];

/// Inverse of a 2×2 matrix; `None` when (nearly) singular or not finite.
#[must_use]
pub fn inverse2(m: Mat2) -> Option<Mat2> {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    let scale = m[0][0]
        .abs()
        .max(m[1][1].abs())
        .max(m[0][1].abs())
        .max(m[1][0].abs());
    if !(det.abs() > 1e-14 * scale * scale && det.is_finite()) {
        return None;
    }
    Some([
        [m[1][1] / det, -m[0][1] / det],
        [-m[1][0] / det, m[0][0] / det],
    ])
}

/// The symmetric inverse square root C^{−1/2} of a symmetric positive
/// definite 2×2 matrix (eigen-decomposition); `None` unless positive definite.
#[must_use]
pub fn inverse_sqrt2(c: Mat2) -> Option<Mat2> {
    let (a, b, d) = (c[0][0], 0.5 * (c[0][1] + c[1][0]), c[1][1]);
    let half_trace = 0.5 * (a + d);
    let root = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (l1, l2) = (half_trace + root, half_trace - root);
    if !(l2 > 0.0 && l1.is_finite()) {
        return None;
    }
    // Unit eigenvector of l1.
    let angle = 0.5 * f64::atan2(2.0 * b, a - d);
    let (cs, sn) = (angle.cos(), angle.sin());
    let (s1, s2) = (1.0 / l1.sqrt(), 1.0 / l2.sqrt());
    Some([
        [s1 * cs * cs + s2 * sn * sn, (s1 - s2) * cs * sn],
        [(s1 - s2) * cs * sn, s1 * sn * sn + s2 * cs * cs],
    ])
}

/// How eq. 6's Σ is formed from a line fit (module doc, "Eq. 6 in general").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CornerCovariance {
    /// Σ_kk = variance of line k's fitted value at the corner (first-order exact).
    #[default]
    LineLocation,
    /// Σ_kk = σ² of eq. 4 (the paper's printed form).
    PointVariance,
}

/// A fitted line (eq. 1–3) with what its location uncertainty needs (eq. 4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineLocation {
    /// The fit, in the horizontal ([`Regression::YOnX`]) or vertical
    /// ([`Regression::XOnY`]) representation.
    pub fit: LineFit,
    /// Weighted mean of the independent coordinate (x for horizontal, y for vertical).
    pub independent_mean: f64,
    /// Σw·(s − s̄)² of the independent coordinate s.
    pub independent_spread: f64,
    /// Σw (the number of points for unit weights).
    pub weight: f64,
    /// Point variance σ² used (eq. 4, possibly floored by the caller).
    pub point_variance: f64,
}

impl LineLocation {
    /// The location of a horizontal or vertical fit of `sums` with point
    /// variance max(eq. 4, `min_point_variance`); `None` for an orthogonal
    /// fit or points without spread.
    #[must_use]
    pub fn new(sums: &LineSums, fit: LineFit, min_point_variance: f64) -> Option<Self> {
        let mean = sums.mean()?;
        let (sxx, syy, _) = sums.centered_moments();
        let (independent_mean, independent_spread) = match fit.regression {
            Regression::YOnX => (mean[0], sxx),
            Regression::XOnY => (mean[1], syy),
            Regression::Orthogonal | Regression::Across => return None,
        };
        if !(independent_spread > 0.0) {
            return None;
        }
        Some(Self {
            fit,
            independent_mean,
            independent_spread,
            weight: sums.weight(),
            point_variance: fit.residual_variance.max(min_point_variance),
        })
    }

    /// Variance of the line's fitted (dependent) coordinate at independent
    /// coordinate `s`: σ²·(1/n + (s − s̄)²/S).
    #[must_use]
    pub fn variance_at(&self, s: f64) -> f64 {
        let ds = s - self.independent_mean;
        self.point_variance * (1.0 / self.weight + ds * ds / self.independent_spread)
    }

    /// The row f and right-hand side w of eq. 5 for this line: f·v = w.
    #[must_use]
    pub fn eq5_row(&self) -> ([f64; 2], f64) {
        let (m, b) = (self.fit.slope, self.fit.intercept);
        match self.fit.regression {
            Regression::XOnY => ([-1.0, m], -b),
            _ => ([m, -1.0], -b),
        }
    }

    /// The independent coordinate of point `v` (x for horizontal, y for vertical).
    #[must_use]
    pub fn independent(&self, v: [f64; 2]) -> f64 {
        match self.fit.regression {
            Regression::XOnY => v[1],
            _ => v[0],
        }
    }
}

/// A corner: position and covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corner {
    /// Image position (v_x, v_y), px.
    pub position: [f64; 2],
    /// Covariance C_v of eq. 6, px².
    pub covariance: Mat2,
}

/// |sin| of the angle between two lines below which they do not make a corner.
const MIN_CORNER_SINE: f64 = 1e-6;

/// Eq. 5–6: the intersection of two fitted lines and its covariance
/// C_v = F⁻¹·Σ·F⁻ᵀ; `None` for (nearly) parallel lines.
#[must_use]
pub fn intersect_lines(
    l1: &LineLocation,
    l2: &LineLocation,
    mode: CornerCovariance,
) -> Option<Corner> {
    let (f1, w1) = l1.eq5_row();
    let (f2, w2) = l2.eq5_row();
    let det = f1[0] * f2[1] - f1[1] * f2[0];
    let sine = det.abs() / (f1[0].hypot(f1[1]) * f2[0].hypot(f2[1]));
    if !(sine > MIN_CORNER_SINE) {
        return None;
    }
    let f_inv = inverse2([f1, f2])?;
    let v = [
        f_inv[0][0] * w1 + f_inv[0][1] * w2,
        f_inv[1][0] * w1 + f_inv[1][1] * w2,
    ];
    let (s1, s2) = match mode {
        CornerCovariance::LineLocation => (
            l1.variance_at(l1.independent(v)),
            l2.variance_at(l2.independent(v)),
        ),
        CornerCovariance::PointVariance => (l1.point_variance, l2.point_variance),
    };
    // Eq. 6: C_v = F⁻¹ diag(s1, s2) F⁻ᵀ.
    let g = f_inv;
    let c01 = g[0][0] * s1 * g[1][0] + g[0][1] * s2 * g[1][1];
    let covariance = [
        [g[0][0] * s1 * g[0][0] + g[0][1] * s2 * g[0][1], c01],
        [c01, g[1][0] * s1 * g[1][0] + g[1][1] * s2 * g[1][1]],
    ];
    Some(Corner {
        position: v,
        covariance,
    })
}

/// One 2-D measurement of eq. 8: two rows of A_f, two entries of b_f, and
/// its 2×2 block of C_f.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlueBlock<const K: usize> {
    /// Two rows of A_f.
    pub rows: [[f64; K]; 2],
    /// The measured values (v_x, v_y).
    pub value: [f64; 2],
    /// The block C_vi of C_f.
    pub covariance: Mat2,
}

/// The weighted least-squares problem of eq. 7–8 with block-diagonal C_f.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct BlueProblem<const K: usize> {
    /// The measurements.
    pub blocks: Vec<BlueBlock<K>>,
}

/// Eq. 9–12 solved.
#[derive(Clone, Debug, PartialEq)]
pub struct BlueSolution<const K: usize> {
    /// x̂_f of eq. 9.
    pub estimate: [f64; K],
    /// (A_fᵀ C_f⁻¹ A_f)⁻¹ = L C_f Lᵀ (eq. 10).
    pub propagated_covariance: [[f64; K]; K],
    /// C_l = L C_fe Lᵀ of eq. 12 (global consistency, module doc).
    pub consistency_covariance: [[f64; K]; K],
    /// b_f − A_f x̂ per block.
    pub residuals: Vec<[f64; 2]>,
    /// e of eq. 11 per block, px (module doc, "Eq. 11 normalisation").
    pub consistency: Vec<[f64; 2]>,
    /// Weighted residual sum of squares J of eq. 7 at x̂.
    pub chi_square: f64,
}

impl<const K: usize> BlueSolution<K> {
    /// Root mean square of the consistency vector e (eq. 11), px.
    #[must_use]
    pub fn rms_consistency(&self) -> f64 {
        let n = 2 * self.consistency.len();
        if n == 0 {
            return 0.0;
        }
        let s: f64 = self
            .consistency
            .iter()
            .map(|e| e[0] * e[0] + e[1] * e[1])
            .sum();
        (s / n as f64).sqrt()
    }
}

impl<const K: usize> BlueProblem<K> {
    /// An empty problem.
    #[must_use]
    pub fn new() -> Self {
        Self { blocks: Vec::new() }
    }

    /// Add a measurement; refused (false) unless its covariance is
    /// positive definite and everything is finite.
    pub fn add(&mut self, rows: [[f64; K]; 2], value: [f64; 2], covariance: Mat2) -> bool {
        let finite = rows.iter().flatten().chain(&value).all(|v| v.is_finite());
        if !finite || inverse_sqrt2(covariance).is_none() {
            return false;
        }
        self.blocks.push(BlueBlock {
            rows,
            value,
            covariance,
        });
        true
    }

    /// Eq. 9: x̂_f = (A_fᵀ C_f⁻¹ A_f)⁻¹ A_fᵀ C_f⁻¹ b_f, with eq. 10–12;
    /// `None` when A_fᵀ C_f⁻¹ A_f is singular (too few measurements).
    /// `feature_variance_floor` (px²) bounds each e_j² of eq. 12 from below.
    #[must_use]
    pub fn solve(&self, feature_variance_floor: f64) -> Option<BlueSolution<K>> {
        self.solve_with(|b| inverse2(b.covariance), feature_variance_floor)
    }

    /// The unweighted least-squares fit (C_f = I) of the same problem, for
    /// comparison with the BLUE (its covariances are those of C_f = I).
    #[must_use]
    pub fn solve_unweighted(&self) -> Option<BlueSolution<K>> {
        self.solve_with(|_| Some([[1.0, 0.0], [0.0, 1.0]]), 0.0)
    }

    fn solve_with(
        &self,
        weight_of: impl Fn(&BlueBlock<K>) -> Option<Mat2>,
        feature_variance_floor: f64,
    ) -> Option<BlueSolution<K>> {
        let weights: Vec<Mat2> = self.blocks.iter().map(&weight_of).collect::<Option<_>>()?;
        // Normal equations M x = g with M = Σ A_iᵀ W_i A_i, g = Σ A_iᵀ W_i b_i.
        let mut m = [[0.0; K]; K];
        let mut g = [0.0; K];
        let mut awt = Vec::with_capacity(self.blocks.len()); // A_iᵀ W_i (K×2)
        for (block, w) in self.blocks.iter().zip(&weights) {
            let mut aw = [[0.0; 2]; K];
            for (k, row) in aw.iter_mut().enumerate() {
                for (c, entry) in row.iter_mut().enumerate() {
                    *entry = block.rows[0][k] * w[0][c] + block.rows[1][k] * w[1][c];
                }
            }
            for k in 0..K {
                for j in 0..K {
                    m[k][j] += aw[k][0] * block.rows[0][j] + aw[k][1] * block.rows[1][j];
                }
                g[k] += aw[k][0] * block.value[0] + aw[k][1] * block.value[1];
            }
            awt.push(aw);
        }
        let m_inv = invert_spd(&m)?;
        let estimate: [f64; K] = std::array::from_fn(|k| (0..K).map(|j| m_inv[k][j] * g[j]).sum());
        let residuals: Vec<[f64; 2]> = self
            .blocks
            .iter()
            .map(|b| {
                std::array::from_fn(|r| {
                    b.value[r] - (0..K).map(|k| b.rows[r][k] * estimate[k]).sum::<f64>()
                })
            })
            .collect();
        // Eq. 11: whitened residuals, normalised per coordinate (module doc).
        let mut whitened = Vec::with_capacity(self.blocks.len());
        let mut trace = 0.0;
        let mut chi_square = 0.0;
        for (r, w) in residuals.iter().zip(&weights) {
            // C_i^{−1/2} of the weights' covariance W_i⁻¹.
            let s = inverse_sqrt2(inverse2(*w)?)?;
            trace += s[0][0] + s[1][1];
            let wr = [
                s[0][0] * r[0] + s[0][1] * r[1],
                s[1][0] * r[0] + s[1][1] * r[1],
            ];
            chi_square += wr[0] * wr[0] + wr[1] * wr[1];
            whitened.push(wr);
        }
        let mean_precision = trace / (2 * self.blocks.len()).max(1) as f64;
        let consistency: Vec<[f64; 2]> = whitened
            .iter()
            .map(|wr| [wr[0] / mean_precision, wr[1] / mean_precision])
            .collect();
        // Eq. 12: C_l = Σ_i L_i diag(e_i²) L_iᵀ with L_i = M⁻¹ A_iᵀ W_i.
        let mut consistency_covariance = [[0.0; K]; K];
        for (aw, e) in awt.iter().zip(&consistency) {
            let l: [[f64; 2]; K] = std::array::from_fn(|k| {
                std::array::from_fn(|c| (0..K).map(|j| m_inv[k][j] * aw[j][c]).sum())
            });
            let e2 = [
                (e[0] * e[0]).max(feature_variance_floor),
                (e[1] * e[1]).max(feature_variance_floor),
            ];
            for k in 0..K {
                for j in 0..K {
                    consistency_covariance[k][j] +=
                        l[k][0] * e2[0] * l[j][0] + l[k][1] * e2[1] * l[j][1];
                }
            }
        }
        Some(BlueSolution {
            estimate,
            propagated_covariance: m_inv,
            consistency_covariance,
            residuals,
            consistency,
            chi_square,
        })
    }
}

/// Inverse of a symmetric positive definite K×K matrix by Cholesky; `None`
/// unless positive definite (relative to its diagonal).
#[must_use]
pub fn invert_spd<const K: usize>(m: &[[f64; K]; K]) -> Option<[[f64; K]; K]> {
    let mut l = [[0.0; K]; K];
    for i in 0..K {
        for j in 0..=i {
            let s = m[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if !(s > 1e-12 * m[i][i].abs() && s.is_finite()) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    // Inverse of L (lower triangular), then M⁻¹ = L⁻ᵀ L⁻¹.
    let mut li = [[0.0; K]; K];
    for c in 0..K {
        for i in c..K {
            let rhs = if i == c { 1.0 } else { 0.0 };
            let s = rhs - (c..i).map(|k| l[i][k] * li[k][c]).sum::<f64>();
            li[i][c] = s / l[i][i];
        }
    }
    Some(std::array::from_fn(|i| {
        std::array::from_fn(|j| (i.max(j)..K).map(|k| li[k][i] * li[k][j]).sum())
    }))
}

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
            return Err(Error::Parameter(format!(
                "polynomial filter: decay lambda must be in (0, 1], got {lambda}"
            )));
        }
        Ok(Self {
            lambda,
            r: [[0.0; N]; N],
            z: [0.0; N],
            time,
            samples: 0,
        })
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
                *entry = (i..=j)
                    .map(|k| self.r[i][k] * binomial(j, k) * (-d).powi((j - k) as i32))
                    .sum();
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
        Some(std::array::from_fn(|i| {
            std::array::from_fn(|j| (i.max(j)..N).map(|k| ri[i][k] * ri[j][k]).sum())
        }))
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
        Some(
            (0..N)
                .map(|i| (0..N).map(|j| h[i] * p[i][j] * h[j]).sum::<f64>())
                .sum(),
        )
    }
}

/// The α-β-γ filter (unit sample period): predict x⁻ = x + v + a/2,
/// v⁻ = v + a; update with residual r = m − x⁻: x = x⁻ + α·r,
/// v = v⁻ + β·r, a = a⁻ + (γ/2)·r. With α, β, γ from λ by eq. 18
/// ([`AlphaBetaGamma::from_lambda`]) its one-step prediction has the transfer
/// function of eq. 16–17, that of the λ-weighted degree-2 least-squares fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaBetaGamma {
    /// Position gain α.
    pub alpha: f64,
    /// Velocity gain β.
    pub beta: f64,
    /// Acceleration gain γ.
    pub gamma: f64,
    /// Filtered position.
    pub position: f64,
    /// Filtered velocity, per sample.
    pub velocity: f64,
    /// Filtered acceleration, per sample².
    pub acceleration: f64,
}

impl AlphaBetaGamma {
    /// Gains of eq. 18 for decay λ: α = 1 − λ³, β = 1.5(1 − λ − λ² + λ³),
    /// γ = 2 − 6λ + 6λ² − 2λ³; state zero.
    #[must_use]
    pub fn from_lambda(lambda: f64) -> Self {
        let l2 = lambda * lambda;
        let l3 = l2 * lambda;
        Self {
            alpha: 1.0 - l3,
            beta: 1.5 - 1.5 * lambda - 1.5 * l2 + 1.5 * l3,
            gamma: 2.0 - 6.0 * lambda + 6.0 * l2 - 2.0 * l3,
            position: 0.0,
            velocity: 0.0,
            acceleration: 0.0,
        }
    }

    /// The filter's one-step prediction of the next sample.
    #[must_use]
    pub fn prediction(&self) -> f64 {
        self.position + self.velocity + 0.5 * self.acceleration
    }

    /// Take measurement `m` and return the prediction of the next sample.
    pub fn update(&mut self, m: f64) -> f64 {
        let (x, v, a) = (
            self.prediction(),
            self.velocity + self.acceleration,
            self.acceleration,
        );
        let r = m - x;
        self.position = x + self.alpha * r;
        self.velocity = v + self.beta * r;
        self.acceleration = a + 0.5 * self.gamma * r;
        self.prediction()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_sqrt_squares_to_the_inverse() {
        let c = [[4.0, 1.0], [1.0, 2.0]];
        let s = inverse_sqrt2(c).expect("spd");
        let s2 = [
            [
                s[0][0] * s[0][0] + s[0][1] * s[1][0],
                s[0][0] * s[0][1] + s[0][1] * s[1][1],
            ],
            [
                s[1][0] * s[0][0] + s[1][1] * s[1][0],
                s[1][0] * s[0][1] + s[1][1] * s[1][1],
            ],
        ];
        let inv = inverse2(c).expect("regular");
        for i in 0..2 {
            for j in 0..2 {
                assert!((s2[i][j] - inv[i][j]).abs() < 1e-12, "{s2:?} vs {inv:?}");
            }
        }
        assert!(
            inverse_sqrt2([[1.0, 2.0], [2.0, 1.0]]).is_none(),
            "indefinite"
        );
    }

    #[test]
    fn spd_inverse_by_hand() {
        // [[4, 2], [2, 3]]⁻¹ = [[3, −2], [−2, 4]]/8.
        let m = invert_spd(&[[4.0, 2.0], [2.0, 3.0]]).expect("spd");
        assert!((m[0][0] - 3.0 / 8.0).abs() < 1e-12 && (m[0][1] + 0.25).abs() < 1e-12);
        assert!((m[1][1] - 0.5).abs() < 1e-12 && (m[1][0] + 0.25).abs() < 1e-12);
        assert!(invert_spd(&[[1.0, 1.0], [1.0, 1.0]]).is_none());
    }

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
        assert!(
            (a[0] - 5.75).abs() < 1e-9 && (a[1] - 2.0).abs() < 1e-9 && (a[2] - 0.25).abs() < 1e-9,
            "{a:?}"
        );
        assert!((f.predict(1.0).expect("p") - c(6.0)).abs() < 1e-9);
        assert!((f.predict(2.5).expect("p") - c(7.5)).abs() < 1e-9);
        let before = f.prediction_variance(1.0).expect("var");
        f.advance_to(7.0);
        assert!((f.predict(0.0).expect("p") - c(7.0)).abs() < 1e-9);
        assert!(
            f.prediction_variance(-1.0).expect("var") > before,
            "decay loses information"
        );
    }

    #[test]
    fn alpha_beta_gamma_gains_of_eq_18() {
        let f = AlphaBetaGamma::from_lambda(0.5);
        assert!((f.alpha - 0.875).abs() < 1e-12);
        assert!((f.beta - 1.5 * 0.375).abs() < 1e-12); // 1 − .5 − .25 + .125
        assert!((f.gamma - 0.25).abs() < 1e-12); // 2(1 − λ)³
    }
}
