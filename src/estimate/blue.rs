//! The best linear unbiased estimate of 002 §2.8–2.9: a K-vector from 2-D
//! measurements with 2×2 covariances (eq. 7–9), its propagated covariance
//! (eq. 10) and the covariance from the global consistency of the
//! measurements (eq. 11–12).
//!
//! # Eq. 11 normalisation
//!
//! Eq. 11 prints e = C_f^{−1/2}(b − A x̂) / trace(C_f^{−1/2}). With equal
//! variances σ² for all 2n coordinates that is e = r/(2n): it shrinks with the
//! number of features and cannot be a feature variance in eq. 12. Here the
//! trace is taken per coordinate, e = C_f^{−1/2} r / (trace(C_f^{−1/2})/2n):
//! the whitened residuals rescaled to pixels by the mean precision, so that
//! for equal variances e = r and eq. 12, C_l = L·diag(e²)·Lᵀ, is the
//! heteroscedasticity-consistent ("sandwich") covariance of the weighted
//! least-squares estimate — each feature contributes the error it actually
//! shows against the global fit, which is what §2.9 asks for.

#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use super::linalg::*;

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
        let s: f64 = self.consistency.iter().map(|e| e[0] * e[0] + e[1] * e[1]).sum();
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
        self.blocks.push(BlueBlock { rows, value, covariance });
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
            .map(|b| std::array::from_fn(|r| b.value[r] - (0..K).map(|k| b.rows[r][k] * estimate[k]).sum::<f64>()))
            .collect();
        // Eq. 11: whitened residuals, normalised per coordinate (module doc).
        let mut whitened = Vec::with_capacity(self.blocks.len());
        let mut trace = 0.0;
        let mut chi_square = 0.0;
        for (r, w) in residuals.iter().zip(&weights) {
            // C_i^{−1/2} of the weights' covariance W_i⁻¹.
            let s = inverse_sqrt2(inverse2(*w)?)?;
            trace += s[0][0] + s[1][1];
            let wr = [s[0][0] * r[0] + s[0][1] * r[1], s[1][0] * r[0] + s[1][1] * r[1]];
            chi_square += wr[0] * wr[0] + wr[1] * wr[1];
            whitened.push(wr);
        }
        let mean_precision = trace / (2 * self.blocks.len()).max(1) as f64;
        let consistency: Vec<[f64; 2]> =
            whitened.iter().map(|wr| [wr[0] / mean_precision, wr[1] / mean_precision]).collect();
        // Eq. 12: C_l = Σ_i L_i diag(e_i²) L_iᵀ with L_i = M⁻¹ A_iᵀ W_i.
        let mut consistency_covariance = [[0.0; K]; K];
        for (aw, e) in awt.iter().zip(&consistency) {
            let l: [[f64; 2]; K] =
                std::array::from_fn(|k| std::array::from_fn(|c| (0..K).map(|j| m_inv[k][j] * aw[j][c]).sum()));
            let e2 = [(e[0] * e[0]).max(feature_variance_floor), (e[1] * e[1]).max(feature_variance_floor)];
            for k in 0..K {
                for j in 0..K {
                    consistency_covariance[k][j] += l[k][0] * e2[0] * l[j][0] + l[k][1] * e2[1] * l[j][1];
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
