//! Small dense linear algebra for the estimators: 2×2 inverses and inverse
//! square roots, and the inverse of a small symmetric positive definite matrix.

// `!(x > 0.0)` rejects NaN on purpose; index loops mirror the matrix formulas.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

/// A 2×2 matrix, row-major.
pub type Mat2 = [[f64; 2]; 2];

/// Inverse of a 2×2 matrix; `None` when (nearly) singular or not finite.
#[must_use]
pub fn inverse2(m: Mat2) -> Option<Mat2> {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    let scale = m[0][0].abs().max(m[1][1].abs()).max(m[0][1].abs()).max(m[1][0].abs());
    if !(det.abs() > 1e-14 * scale * scale && det.is_finite()) {
        return None;
    }
    Some([[m[1][1] / det, -m[0][1] / det], [-m[1][0] / det, m[0][0] / det]])
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
    Some([[s1 * cs * cs + s2 * sn * sn, (s1 - s2) * cs * sn], [(s1 - s2) * cs * sn, s1 * sn * sn + s2 * cs * cs]])
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
    Some(std::array::from_fn(|i| std::array::from_fn(|j| (i.max(j)..K).map(|k| li[k][i] * li[k][j]).sum())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_sqrt_squares_to_the_inverse() {
        let c = [[4.0, 1.0], [1.0, 2.0]];
        let s = inverse_sqrt2(c).expect("spd");
        let s2 = [
            [s[0][0] * s[0][0] + s[0][1] * s[1][0], s[0][0] * s[0][1] + s[0][1] * s[1][1]],
            [s[1][0] * s[0][0] + s[1][1] * s[1][0], s[1][0] * s[0][1] + s[1][1] * s[1][1]],
        ];
        let inv = inverse2(c).expect("regular");
        for i in 0..2 {
            for j in 0..2 {
                assert!((s2[i][j] - inv[i][j]).abs() < 1e-12, "{s2:?} vs {inv:?}");
            }
        }
        assert!(inverse_sqrt2([[1.0, 2.0], [2.0, 1.0]]).is_none(), "indefinite");
    }

    #[test]
    fn spd_inverse_by_hand() {
        // [[4, 2], [2, 3]]⁻¹ = [[3, −2], [−2, 4]]/8.
        let m = invert_spd(&[[4.0, 2.0], [2.0, 3.0]]).expect("spd");
        assert!((m[0][0] - 3.0 / 8.0).abs() < 1e-12 && (m[0][1] + 0.25).abs() < 1e-12);
        assert!((m[1][1] - 0.5).abs() < 1e-12 && (m[1][0] + 0.25).abs() < 1e-12);
        assert!(invert_spd(&[[1.0, 1.0], [1.0, 1.0]]).is_none());
    }
}
