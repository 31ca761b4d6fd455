//! A fitted line with the uncertainty of its location (002 §2.5–2.6, eq. 1–4)
//! and the intersection of two lines with the covariance of eq. 5–6 (§2.7).
//!
//! # Eq. 6 in general
//!
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
//! Carlo in `tests/trackers/blue_logic.rs`). Taking Σ_kk = σ² of eq. 4 itself, as the
//! paper prints it, is [`CornerCovariance::PointVariance`]: it weighs a line
//! by its scatter only, not by its number of points or its extent.

#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::linalg::*;
use super::line_fit::{LineFit, LineSums, Regression};

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
pub fn intersect_lines(l1: &LineLocation, l2: &LineLocation, mode: CornerCovariance) -> Option<Corner> {
    let (f1, w1) = l1.eq5_row();
    let (f2, w2) = l2.eq5_row();
    let det = f1[0] * f2[1] - f1[1] * f2[0];
    let sine = det.abs() / (f1[0].hypot(f1[1]) * f2[0].hypot(f2[1]));
    if !(sine > MIN_CORNER_SINE) {
        return None;
    }
    let f_inv = inverse2([f1, f2])?;
    let v = [f_inv[0][0] * w1 + f_inv[0][1] * w2, f_inv[1][0] * w1 + f_inv[1][1] * w2];
    let (s1, s2) = match mode {
        CornerCovariance::LineLocation => (l1.variance_at(l1.independent(v)), l2.variance_at(l2.independent(v))),
        CornerCovariance::PointVariance => (l1.point_variance, l2.point_variance),
    };
    // Eq. 6: C_v = F⁻¹ diag(s1, s2) F⁻ᵀ.
    let g = f_inv;
    let c01 = g[0][0] * s1 * g[1][0] + g[0][1] * s2 * g[1][1];
    let covariance = [
        [g[0][0] * s1 * g[0][0] + g[0][1] * s2 * g[0][1], c01],
        [c01, g[1][0] * s1 * g[1][0] + g[1][1] * s2 * g[1][1]],
    ];
    Some(Corner { position: v, covariance })
}
