//! Straight lines: least-squares fitting (weighted), intersection and
//! point–line distance. Written once for every tracker that fits lines to
//! labelled pixels: the motion-edge tracker (paper 000, eq. 4–8) and the BLUE
//! tracker (paper 002, §2.5–2.7, which also needs the empirical residual
//! variance of its eq. 4).
//!
//! Regressions follow the papers: y on x ("horizontal representation",
//! y = m·x + b, 000 eq. 5–6) for lines whose points spread more in x, and x
//! on y ("vertical representation", x = m·y + b) for the rest. 000's eq. 7–8
//! are garbled in the source; the x-on-y fit used here is eq. 5–6 with x and
//! y swapped, as 002 §2.5 says ("the x and y coordinates are interchanged"):
//! m = (nΣxy − ΣxΣy)/(nΣy² − (Σy)²), b = (Σx − mΣy)/n. 000 calls a line
//! "vertical" when the standard deviation of x falls below a threshold; the x
//! on y regression fits such a line exactly (m = 0), so no threshold is needed.
//!
//! Every sum may carry a weight w_i ≥ 0 (n becomes Σw_i); unit weights give
//! the papers' formulas. Sums are accumulated relative to an origin chosen by
//! the caller (e.g. the predicted line's midpoint) to keep the cancellation in
//! nΣx² − (Σx)² small for large pixel coordinates.

/// A line in normalised general form a·x + b·y + c = 0 with a² + b² = 1,
/// (a, b) the unit normal. The sign of (a, b, c) is arbitrary but fixed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// x coefficient (normal x).
    pub a: f64,
    /// y coefficient (normal y).
    pub b: f64,
    /// Constant term: minus the normal offset.
    pub c: f64,
}

impl Line {
    /// The line a·x + b·y + c = 0, normalised; `None` when a = b = 0 or a
    /// coefficient is not finite.
    #[must_use]
    pub fn from_general(a: f64, b: f64, c: f64) -> Option<Self> {
        let norm = a.hypot(b);
        if !(norm > 0.0 && norm.is_finite() && c.is_finite()) {
            return None;
        }
        Some(Self { a: a / norm, b: b / norm, c: c / norm })
    }

    /// The line through `p` and `q`; `None` when they coincide.
    #[must_use]
    pub fn through(p: [f64; 2], q: [f64; 2]) -> Option<Self> {
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        // Normal (−dy, dx); c makes p satisfy the equation.
        Self::from_general(-dy, dx, dy * p[0] - dx * p[1])
    }

    /// The line y = m·x + b (horizontal representation).
    #[must_use]
    pub fn y_on_x(m: f64, b: f64) -> Option<Self> {
        Self::from_general(m, -1.0, b)
    }

    /// The line x = m·y + b (vertical representation).
    #[must_use]
    pub fn x_on_y(m: f64, b: f64) -> Option<Self> {
        Self::from_general(1.0, -m, -b)
    }

    /// Signed perpendicular distance of `p` from the line (000 eq. 4).
    #[must_use]
    pub fn signed_distance(&self, p: [f64; 2]) -> f64 {
        self.a * p[0] + self.b * p[1] + self.c
    }

    /// Perpendicular distance of `p` from the line (|eq. 4|).
    #[must_use]
    pub fn distance(&self, p: [f64; 2]) -> f64 {
        self.signed_distance(p).abs()
    }

    /// Undirected orientation of the line in [0, π): the angle of its
    /// direction from +x towards +y (image y points down), the convention of
    /// the edge orientation θ of 000 eq. 2.
    #[must_use]
    pub fn orientation(&self) -> f64 {
        // Direction (b, −a) is the normal rotated by −90°.
        wrap_orientation(f64::atan2(-self.a, self.b))
    }

    /// The foot of the perpendicular from `p` onto the line.
    #[must_use]
    pub fn project(&self, p: [f64; 2]) -> [f64; 2] {
        let d = self.signed_distance(p);
        [p[0] - d * self.a, p[1] - d * self.b]
    }

    /// Intersection with `other` (Cramer's rule); `None` when the lines are
    /// parallel (|sin angle| < 1e-9).
    #[must_use]
    pub fn intersection(&self, other: &Line) -> Option<[f64; 2]> {
        let det = self.a * other.b - other.a * self.b;
        if det.abs() < PARALLEL_SINE {
            return None;
        }
        let x = (self.b * other.c - other.b * self.c) / det;
        let y = (other.a * self.c - self.a * other.c) / det;
        Some([x, y])
    }
}

/// |sin| of the angle between two lines below which they count as parallel.
const PARALLEL_SINE: f64 = 1e-9;

/// An angle wrapped into [0, π): the undirected orientation of a line.
#[must_use]
pub fn wrap_orientation(theta: f64) -> f64 {
    let t = rem_pi(theta);
    // rem_euclid can return π itself for tiny negative inputs.
    if t >= std::f64::consts::PI { 0.0 } else { t }
}

/// Difference of two undirected orientations, in [0, π/2]: compares line
/// orientations modulo π, as 000 eq. 3 must (θ and θ + π are the same line).
#[must_use]
pub fn orientation_difference(a: f64, b: f64) -> f64 {
    let d = rem_pi(a - b);
    d.min(std::f64::consts::PI - d)
}

/// Difference of two undirected orientations as
/// [`orientation_difference`] gives it, for `a − b` in (−2π, 2π) (two
/// orientations in [0, π], or an edge direction in [−π, π] and an
/// orientation), without a branch, so that a loop over many pixels
/// vectorises. The same value (at `a − b` = −π it is +0 where that is −0).
#[inline(always)]
pub(crate) fn orientation_difference_near(a: f64, b: f64) -> f64 {
    let x = a - b;
    let d = x - pi_multiple(x);
    d.min(std::f64::consts::PI - d)
}

/// The multiple of π (−2π, −π, 0 or π) that `x.rem_euclid(π)` takes from x
/// for −2π < x < 2π, from comparisons alone, which vectorise (the term of
/// [`rem_pi`]'s table where their ranges meet). For −π < x < 2π, x minus it
/// is `rem_euclid` bit for bit; below −π, `rem_euclid` adds π to the exact
/// x + π, one rounding of x + 2π as here; at −π it gives −0 and this +0.
#[inline(always)]
fn pi_multiple(x: f64) -> f64 {
    use std::f64::consts::PI;
    PI * f64::from(i32::from(x >= PI) - i32::from(x < 0.0) - i32::from(x < -PI))
}

/// `x.rem_euclid(π)`, bit for bit, without the division for −π < x < 2π
/// (the difference of two orientations, an edge direction turned by π/2):
/// for |x| < π the remainder is `x` itself, and `rem_euclid` adds π to a
/// negative one; for π ≤ x < 2π it is x − π, which is exact there
/// (Sterbenz). The term is taken from a table: one scalar at a time it
/// costs less than the comparisons of [`pi_multiple`] (blue 2 % per frame).
/// Subtracting 0 keeps −0 as `rem_euclid` does.
#[inline]
pub(crate) fn rem_pi(x: f64) -> f64 {
    use std::f64::consts::PI;
    const TERM: [f64; 3] = [-PI, 0.0, PI];
    if !(-PI < x && x < 2.0 * PI) {
        return x.rem_euclid(PI);
    }
    x - TERM[usize::from(x >= 0.0) + usize::from(x >= PI)]
}

/// Weighted sums of points for a least-squares line fit, relative to an
/// origin: Σw, Σw·x, Σw·y, Σw·x², Σw·y², Σw·x·y (x, y taken from the origin).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LineSums {
    origin: [f64; 2],
    count: usize,
    w: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    syy: f64,
    sxy: f64,
}

impl LineSums {
    /// Empty sums with origin (0, 0): the papers' plain sums.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Empty sums taken relative to `origin` (better conditioned for large coordinates).
    #[must_use]
    pub fn with_origin(origin: [f64; 2]) -> Self {
        Self { origin, ..Self::default() }
    }

    /// Add the point (x, y) with weight 1.
    pub fn add(&mut self, x: f64, y: f64) {
        self.add_weighted(x, y, 1.0);
    }

    /// Add the point (x, y) with weight `w` (ignored unless w > 0 and finite).
    pub fn add_weighted(&mut self, x: f64, y: f64, w: f64) {
        if !(w > 0.0 && w.is_finite() && x.is_finite() && y.is_finite()) {
            return;
        }
        let (x, y) = (x - self.origin[0], y - self.origin[1]);
        self.count += 1;
        self.w += w;
        self.sx += w * x;
        self.sy += w * y;
        self.sxx += w * x * x;
        self.syy += w * y * y;
        self.sxy += w * x * y;
    }

    /// Number of points added.
    #[must_use]
    pub fn count(&self) -> usize {
        self.count
    }

    /// Total weight Σw (= n for unit weights).
    #[must_use]
    pub fn weight(&self) -> f64 {
        self.w
    }

    /// Weighted mean point.
    #[must_use]
    pub fn mean(&self) -> Option<[f64; 2]> {
        (self.w > 0.0).then(|| [self.sx / self.w + self.origin[0], self.sy / self.w + self.origin[1]])
    }

    /// Weighted standard deviation of x (population form).
    #[must_use]
    pub fn std_dev_x(&self) -> f64 {
        (self.centered_xx() / self.w).max(0.0).sqrt()
    }

    /// Weighted standard deviation of y (population form).
    #[must_use]
    pub fn std_dev_y(&self) -> f64 {
        (self.centered_yy() / self.w).max(0.0).sqrt()
    }

    /// Σw(x − x̄)² = (nΣx² − (Σx)²)/n.
    fn centered_xx(&self) -> f64 {
        self.sxx - self.sx * self.sx / self.w
    }

    /// Σw(y − ȳ)².
    fn centered_yy(&self) -> f64 {
        self.syy - self.sy * self.sy / self.w
    }

    /// Centred second moments (Σw(x − x̄)², Σw(y − ȳ)², Σw(x − x̄)(y − ȳ)):
    /// Σw times the points' covariance matrix.
    #[must_use]
    pub fn centered_moments(&self) -> (f64, f64, f64) {
        (self.centered_xx(), self.centered_yy(), self.sxy - self.sx * self.sy / self.w)
    }
}

/// Which errors a fit minimised.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Regression {
    /// y = m·x + b, vertical errors minimised (000 eq. 5–6).
    YOnX,
    /// x = m·y + b, horizontal errors minimised (000 eq. 7–8, corrected).
    XOnY,
    /// Perpendicular errors minimised (orthogonal regression, the principal
    /// axis of the points); slope and intercept are given in the y-on-x form
    /// when the line is within 45° of horizontal, in the x-on-y form otherwise.
    Orthogonal,
    /// The perpendicular offset from a given (predicted) line regressed on
    /// the position along it ([`fit_line_across`]); slope and intercept as
    /// for [`Regression::Orthogonal`].
    Across,
}

/// A fitted line with its regression form and the spread of its points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineFit {
    /// Which regression produced it.
    pub regression: Regression,
    /// Slope m of the regression form.
    pub slope: f64,
    /// Intercept b of the regression form.
    pub intercept: f64,
    /// The same line in normalised general form.
    pub line: Line,
    /// Empirical residual variance along the regressed coordinate,
    /// Σw·r²/Σw (002 eq. 4 with weights; r = y − m·x − b or x − m·y − b).
    pub residual_variance: f64,
    /// Number of points fitted.
    pub count: usize,
}

impl LineFit {
    /// Residual variance perpendicular to the line: the regressed
    /// coordinate's residual variance times cos² of the line's angle to the
    /// regression axis, i.e. divided by 1 + m².
    #[must_use]
    pub fn perpendicular_residual_variance(&self) -> f64 {
        self.residual_variance / (1.0 + self.slope * self.slope)
    }
}

/// Least-squares fit of y = m·x + b (000 eq. 5–6, n → Σw).
/// `None` with fewer than two points or no spread in x.
#[must_use]
pub fn fit_y_on_x(sums: &LineSums) -> Option<LineFit> {
    regress(sums, Regression::YOnX)
}

/// Least-squares fit of x = m·y + b (000 eq. 7–8 as corrected in the module
/// doc: eq. 5–6 with x and y swapped). `None` with fewer than two points or
/// no spread in y.
#[must_use]
pub fn fit_x_on_y(sums: &LineSums) -> Option<LineFit> {
    regress(sums, Regression::XOnY)
}

/// Least-squares line through the points: y on x when the standard deviation
/// of x is at least that of y (a more horizontal line), x on y otherwise
/// (000 §2: "When the standard deviation of the y coordinates is larger, a
/// linear regression of x on y is used").
#[must_use]
pub fn fit_line(sums: &LineSums) -> Option<LineFit> {
    if sums.count < 2 || !(sums.w > 0.0) {
        return None;
    }
    if sums.centered_xx() >= sums.centered_yy() { fit_y_on_x(sums) } else { fit_x_on_y(sums) }
}

/// The regression of `u` on `v`, where (u, v) = (y, x) for y on x.
fn regress(sums: &LineSums, regression: Regression) -> Option<LineFit> {
    if sums.count < 2 || !(sums.w > 0.0) {
        return None;
    }
    // (independent v, dependent u) sums, in origin-relative coordinates.
    let (sv, su, svv, suv, suu) = match regression {
        Regression::YOnX | Regression::Orthogonal | Regression::Across => {
            (sums.sx, sums.sy, sums.sxx, sums.sxy, sums.syy)
        }
        Regression::XOnY => (sums.sy, sums.sx, sums.syy, sums.sxy, sums.sxx),
    };
    let n = sums.w;
    // Eq. 5: m = (nΣvu − ΣvΣu) / (nΣv² − (Σv)²).
    let denominator = n * svv - sv * sv;
    let spread_scale = n * svv;
    if !(denominator > SPREAD_EPSILON * spread_scale.max(f64::MIN_POSITIVE)) {
        return None;
    }
    let slope = (n * suv - sv * su) / denominator;
    // Eq. 6: b = (ΣuΣv² − ΣvΣvu) / (nΣv² − (Σv)²), i.e. (Σu − mΣv)/n.
    let local_intercept = (su * svv - sv * suv) / denominator;
    // Residuals: Σw(u − ū)² − m·Σw(u − ū)(v − v̄).
    let centered_uu = suu - su * su / n;
    let centered_uv = suv - su * sv / n;
    let residual_variance = ((centered_uu - slope * centered_uv) / n).max(0.0);
    // Back from origin-relative coordinates: u − o_u = m(v − o_v) + b'.
    let (ov, ou) = match regression {
        Regression::YOnX | Regression::Orthogonal | Regression::Across => (sums.origin[0], sums.origin[1]),
        Regression::XOnY => (sums.origin[1], sums.origin[0]),
    };
    let intercept = local_intercept + ou - slope * ov;
    let line = match regression {
        Regression::YOnX | Regression::Orthogonal | Regression::Across => Line::y_on_x(slope, intercept),
        Regression::XOnY => Line::x_on_y(slope, intercept),
    }?;
    Some(LineFit { regression, slope, intercept, line, residual_variance, count: sums.count })
}

/// Orthogonal (total) least squares: the line through the weighted mean
/// along the principal axis of the points' scatter, minimising the sum of
/// squared *perpendicular* distances. Unlike eq. 5–8 it is unbiased for
/// points scattered symmetrically across a line in any direction (e.g. a
/// thick band of motion pixels), at any slope. `None` with fewer than two
/// points or no spread.
#[must_use]
pub fn fit_line_orthogonal(sums: &LineSums) -> Option<LineFit> {
    if sums.count < 2 || !(sums.w > 0.0) {
        return None;
    }
    let (sxx, syy, sxy) = sums.centered_moments();
    let half_trace = 0.5 * (sxx + syy);
    let root = (0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy).sqrt();
    let (largest, smallest) = (half_trace + root, (half_trace - root).max(0.0));
    if !(largest > SPREAD_EPSILON * (sums.sxx + sums.syy).max(f64::MIN_POSITIVE)) {
        return None;
    }
    // Direction of the principal axis.
    let angle = 0.5 * f64::atan2(2.0 * sxy, sxx - syy);
    let (dir_x, dir_y) = (angle.cos(), angle.sin());
    let mean = sums.mean()?;
    let perpendicular_variance = smallest / sums.w;
    let (regression_form, slope) =
        if dir_x.abs() >= dir_y.abs() { (Regression::YOnX, dir_y / dir_x) } else { (Regression::XOnY, dir_x / dir_y) };
    let (intercept, line) = match regression_form {
        Regression::YOnX | Regression::Orthogonal | Regression::Across => {
            let b = mean[1] - slope * mean[0];
            (b, Line::y_on_x(slope, b)?)
        }
        _ => {
            let b = mean[0] - slope * mean[1];
            (b, Line::x_on_y(slope, b)?)
        }
    };
    Some(LineFit {
        regression: Regression::Orthogonal,
        slope,
        intercept,
        line,
        // Along the representation's dependent coordinate, so that
        // `perpendicular_residual_variance` gives the perpendicular one.
        residual_variance: perpendicular_variance * (1.0 + slope * slope),
        count: sums.count,
    })
}

/// Least squares across a given direction: with s the position of a point
/// along the unit vector `direction` and d its offset across it, the
/// regression d = m·s + b (eq. 5–6 in the frame of `direction` rather than
/// of the image axes). The paper regresses on the image axis along which the
/// points spread more, so that the band's thickness is error in the
/// dependent coordinate only; regressing on the predicted line's own
/// direction does that exactly, whatever the line's slope. Unlike the
/// orthogonal fit it needs no elongated point set: a band of motion pixels
/// as wide as it is long (fast motion on a short, end-trimmed edge) has no
/// principal axis, but a band cut perpendicular to `direction` has
/// offsets independent of s, so m is unbiased however thick the band.
/// `None` with fewer than two points or no spread along `direction`.
#[must_use]
pub fn fit_line_across(sums: &LineSums, direction: [f64; 2]) -> Option<LineFit> {
    if sums.count < 2 || !(sums.w > 0.0) {
        return None;
    }
    let norm = direction[0].hypot(direction[1]);
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    let u = [direction[0] / norm, direction[1] / norm];
    let (ss, _, sd) = moments_across(sums, u);
    if !(ss > SPREAD_EPSILON * (sums.sxx + sums.syy).max(f64::MIN_POSITIVE)) {
        return None;
    }
    line_across(sums, u, sd / ss)
}

/// Centred moments (Σw·s², Σw·d², Σw·s·d) of the points in the frame of the
/// unit vector `u` (s along it, d along the normal (−u_y, u_x)).
fn moments_across(sums: &LineSums, u: [f64; 2]) -> (f64, f64, f64) {
    let [ux, uy] = u;
    let (sxx, syy, sxy) = sums.centered_moments();
    (
        ux * ux * sxx + 2.0 * ux * uy * sxy + uy * uy * syy,
        uy * uy * sxx - 2.0 * ux * uy * sxy + ux * ux * syy,
        ux * uy * (syy - sxx) + (ux * ux - uy * uy) * sxy,
    )
}

/// The line through the points' mean with slope `m` in the frame of the
/// unit vector `u` (d = m·s + b), with the residual variance of the points
/// about it.
fn line_across(sums: &LineSums, u: [f64; 2], m: f64) -> Option<LineFit> {
    if !m.is_finite() {
        return None;
    }
    let [ux, uy] = u;
    let (ss, dd, sd) = moments_across(sums, u);
    let residual_across = ((dd - 2.0 * m * sd + m * m * ss) / sums.w).max(0.0);
    let perpendicular_variance = residual_across / (1.0 + m * m);
    let (dir_x, dir_y) = (ux - m * uy, uy + m * ux);
    let mean = sums.mean()?;
    let (slope, intercept, line) = if dir_x.abs() >= dir_y.abs() {
        let slope = dir_y / dir_x;
        let b = mean[1] - slope * mean[0];
        (slope, b, Line::y_on_x(slope, b)?)
    } else {
        let slope = dir_x / dir_y;
        let b = mean[0] - slope * mean[1];
        (slope, b, Line::x_on_y(slope, b)?)
    };
    Some(LineFit {
        regression: Regression::Across,
        slope,
        intercept,
        line,
        residual_variance: perpendicular_variance * (1.0 + slope * slope),
        count: sums.count,
    })
}

/// [`fit_line_across`] for a band of motion pixels bounded by two edges
/// (the edge at t−1 and at t): the points are split by the side of the
/// pooled fit they lie on, and the slope is the regression slope within the
/// two halves (one slope common to both, each half about its own mean), so
/// that the band's width — the distance between its two edges — is not
/// noise in the slope; the line passes through the points' mean. On a thin
/// band it is the pooled fit's slope half-way to the within-half one, on a
/// band as wide as its trimmed length several times less noisy than the
/// pooled regression. `None` as for [`fit_line_across`].
#[must_use]
pub fn fit_band_across(points: &[[f64; 2]], direction: [f64; 2], split_std: f64) -> Option<LineFit> {
    let origin = *points.first()?;
    let mut all = LineSums::with_origin(origin);
    for p in points {
        all.add(p[0], p[1]);
    }
    let pooled = fit_line_across(&all, direction)?;
    if pooled.perpendicular_residual_variance() <= split_std * split_std {
        return Some(pooled);
    }
    let norm = direction[0].hypot(direction[1]);
    let u = [direction[0] / norm, direction[1] / norm];
    let mut sides = [LineSums::with_origin(origin), LineSums::with_origin(origin)];
    for p in points {
        let side = usize::from(pooled.line.signed_distance(*p) >= 0.0);
        sides[side].add(p[0], p[1]);
    }
    let (mut ss, mut sd) = (0.0, 0.0);
    for side in &sides {
        if side.count() >= 2 {
            let (s2, _, c) = moments_across(side, u);
            ss += s2;
            sd += c;
        }
    }
    if !(ss > SPREAD_EPSILON * (all.sxx + all.syy).max(f64::MIN_POSITIVE)) {
        return Some(pooled);
    }
    line_across(&all, u, sd / ss).or(Some(pooled))
}

/// Relative size of nΣv² − (Σv)² below which the points have no spread.
const SPREAD_EPSILON: f64 = 1e-12;

#[cfg(test)]
mod tests {
    use super::*;

    /// The remainder's short cut gives `rem_euclid`'s bits, at and around
    /// its bounds and the values where `rem_euclid` rounds (tiny negatives).
    #[test]
    fn rem_pi_is_rem_euclid_bit_for_bit() {
        use std::f64::consts::PI;
        let below = |x: f64| f64::from_bits(x.to_bits() - 1);
        let mut values = vec![0.0, -0.0, 1e-300, -1e-300, -1e-17, 1e-17, PI, -PI, below(PI), -below(PI), 7.5, -7.5];
        values.extend([2.0 * PI, -2.0 * PI, below(2.0 * PI), -below(2.0 * PI), 1.5 * PI, PI + 1e-15]);
        values.extend([1e20, -1e20, f64::NAN, f64::INFINITY, f64::NEG_INFINITY]);
        values.extend((0..=1000).map(|k| PI + f64::from(k) * PI / 1000.0));
        values.extend((-400..=400).map(|k| f64::from(k) * 0.01 + 1e-9));
        // Edge directions turned by π/2: `f32` directions in (−π, π], a
        // little past π, around the cases' bounds and across the range.
        use std::f32::consts::{FRAC_PI_2 as HALF, PI as PI32};
        let next = |t: f32, k: i32| f32::from_bits(t.to_bits().wrapping_add_signed(k));
        let mut thetas = vec![0.0, -0.0, PI32, -PI32, HALF, -HALF, 3.0 * HALF, 7.0, -7.0, 1e30, -1e30];
        for t in [0.0f32, PI32, -PI32, HALF, -HALF] {
            thetas.extend((-40..=40).map(|k| next(t, k)));
        }
        thetas.extend((0..=20_000).map(|k| -PI32 + k as f32 * (2.0 * PI32 / 20_000.0)));
        values.extend(thetas.into_iter().map(|t| f64::from(t) + std::f64::consts::FRAC_PI_2));
        for x in values {
            assert_eq!(rem_pi(x).to_bits(), x.rem_euclid(PI).to_bits(), "x = {x:e}");
            // The branch-free remainder below −π as well, in value.
            if x.abs() < 2.0 * PI {
                assert_eq!(x - pi_multiple(x), x.rem_euclid(PI), "x = {x:e}");
                assert_eq!(orientation_difference_near(x, 0.0), orientation_difference(x, 0.0), "x = {x:e}");
            }
        }
    }

    fn sums_of(points: &[[f64; 2]]) -> LineSums {
        let mut s = LineSums::new();
        for p in points {
            s.add(p[0], p[1]);
        }
        s
    }

    #[test]
    fn y_on_x_three_points_by_hand() {
        // (0,1), (1,2), (2,4): n=3, Σx=3, Σy=7, Σx²=5, Σxy=10.
        // Eq. 5: m = (3·10 − 3·7)/(3·5 − 9) = 9/6 = 1.5.
        // Eq. 6: b = (7·5 − 3·10)/6 = 5/6.
        // Residuals 1−5/6, 2−(1.5+5/6), 4−(3+5/6) = 1/6, −1/3, 1/6 → Σr²/n = (1/36+1/9+1/36)/3 = 1/18.
        let fit = fit_y_on_x(&sums_of(&[[0.0, 1.0], [1.0, 2.0], [2.0, 4.0]])).expect("fit");
        assert!((fit.slope - 1.5).abs() < 1e-12, "m = {}", fit.slope);
        assert!((fit.intercept - 5.0 / 6.0).abs() < 1e-12, "b = {}", fit.intercept);
        assert!((fit.residual_variance - 1.0 / 18.0).abs() < 1e-12, "var = {}", fit.residual_variance);
        // Perpendicular: vertical residuals × cos(atan 1.5) = × 1/√3.25.
        assert!((fit.perpendicular_residual_variance() - 1.0 / 18.0 / 3.25).abs() < 1e-12);
        assert_eq!(fit.count, 3);
        // fit_line compares spreads: std of x (0,1,2) = 0.816 < std of y (1,2,4) = 1.247, so x on y.
        assert_eq!(
            fit_line(&sums_of(&[[0.0, 1.0], [1.0, 2.0], [2.0, 4.0]])).map(|f| f.regression),
            Some(Regression::XOnY)
        );
    }

    #[test]
    fn origin_shift_gives_the_same_line() {
        let pts = [[100.0, 201.0], [101.0, 202.0], [102.0, 204.0]];
        let plain = fit_y_on_x(&sums_of(&pts)).expect("fit");
        let mut shifted = LineSums::with_origin([101.0, 202.0]);
        for p in pts {
            shifted.add(p[0], p[1]);
        }
        let shifted = fit_y_on_x(&shifted).expect("fit");
        assert!((plain.slope - shifted.slope).abs() < 1e-9);
        assert!((plain.intercept - shifted.intercept).abs() < 1e-9);
        assert!((plain.residual_variance - shifted.residual_variance).abs() < 1e-9);
        assert!((plain.slope - 1.5).abs() < 1e-12);
        // y = 1.5x + b through the mean (101, 202.333): b = 202.333 − 151.5.
        assert!((plain.intercept - (607.0 / 3.0 - 151.5)).abs() < 1e-9);
    }

    #[test]
    fn vertical_line_x_equals_5_by_x_on_y() {
        let pts = [[5.0, 0.0], [5.0, 1.0], [5.0, 2.0], [5.0, 7.0]];
        assert!(fit_y_on_x(&sums_of(&pts)).is_none(), "y on x must refuse a vertical line");
        let fit = fit_line(&sums_of(&pts)).expect("fit");
        assert_eq!(fit.regression, Regression::XOnY);
        assert!(fit.slope.abs() < 1e-12 && (fit.intercept - 5.0).abs() < 1e-12, "{fit:?}");
        assert!(fit.residual_variance < 1e-12);
        assert!(fit.line.distance([5.0, 100.0]) < 1e-12);
        assert!((fit.line.distance([8.0, -3.0]) - 3.0).abs() < 1e-12);
        assert!((fit.line.orientation() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn line_at_45_degrees() {
        // y = x + 2 through (0,2), (1,3), (2,4), (3,5).
        let pts = [[0.0, 2.0], [1.0, 3.0], [2.0, 4.0], [3.0, 5.0]];
        let yx = fit_y_on_x(&sums_of(&pts)).expect("fit");
        assert!((yx.slope - 1.0).abs() < 1e-12 && (yx.intercept - 2.0).abs() < 1e-12);
        // x = y − 2 by x on y.
        let xy = fit_x_on_y(&sums_of(&pts)).expect("fit");
        assert!((xy.slope - 1.0).abs() < 1e-12 && (xy.intercept + 2.0).abs() < 1e-12);
        // Same line either way; orientation 45° (down-right in the image).
        assert!(yx.line.distance([10.0, 12.0]) < 1e-12 && xy.line.distance([10.0, 12.0]) < 1e-12);
        assert!((yx.line.orientation() - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        // Distance of (0,0) from x − y + 2 = 0 is 2/√2.
        assert!((yx.line.distance([0.0, 0.0]) - std::f64::consts::SQRT_2).abs() < 1e-12);
    }

    #[test]
    fn weights_act_like_repeated_points() {
        let mut weighted = LineSums::new();
        weighted.add_weighted(0.0, 0.0, 2.0);
        weighted.add(1.0, 1.0);
        weighted.add(2.0, 4.0);
        let repeated = sums_of(&[[0.0, 0.0], [0.0, 0.0], [1.0, 1.0], [2.0, 4.0]]);
        let (a, b) = (fit_y_on_x(&weighted).expect("fit"), fit_y_on_x(&repeated).expect("fit"));
        assert!((a.slope - b.slope).abs() < 1e-12 && (a.intercept - b.intercept).abs() < 1e-12);
        assert!((a.residual_variance - b.residual_variance).abs() < 1e-12);
        assert_eq!(a.count, 3, "count is points, not weight");
        assert!((weighted.weight() - 4.0).abs() < 1e-12);
    }

    #[test]
    fn orthogonal_fit_by_hand_and_unbiased_for_a_thick_band() {
        // Square corners (0,0), (2,0), (0,2), (2,2) plus (3,3), (−1,−1): the
        // scatter's principal axis is the diagonal y = x.
        let pts = [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [2.0, 2.0], [3.0, 3.0], [-1.0, -1.0]];
        let fit = fit_line_orthogonal(&sums_of(&pts)).expect("fit");
        assert_eq!(fit.regression, Regression::Orthogonal);
        assert!((fit.line.orientation() - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        assert!(fit.line.distance([1.0, 1.0]) < 1e-12);
        // Perpendicular residuals: ±√2 for (2,0), (0,2); 0 for the rest → 4/6.
        assert!((fit.perpendicular_residual_variance() - 4.0 / 6.0).abs() < 1e-12);
        // A band 10 px thick around y = tan(20°)·x: y on x is attenuated
        // (errors-in-variables), orthogonal is not.
        let (c, sn) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
        let mut band = LineSums::new();
        for i in 0..=60 {
            for j in -5..=5 {
                let (s, n) = (f64::from(i), f64::from(j));
                band.add(s * c - n * sn, s * sn + n * c);
            }
        }
        let ortho = fit_line_orthogonal(&band).expect("fit");
        assert!((ortho.line.orientation() - 20f64.to_radians()).abs() < 1e-9);
        let ols = fit_y_on_x(&band).expect("fit");
        assert!((ols.line.orientation() - 20f64.to_radians()).abs() > 0.5f64.to_radians(), "OLS is biased here");
        assert!(fit_line_orthogonal(&sums_of(&[[1.0, 1.0], [1.0, 1.0]])).is_none());
        // Vertical points: x = 5.
        let v = fit_line_orthogonal(&sums_of(&[[5.0, 0.0], [5.0, 1.0], [5.0, 4.0]])).expect("fit");
        assert!(v.slope.abs() < 1e-12 && (v.intercept - 5.0).abs() < 1e-12);
    }

    #[test]
    fn degenerate_inputs_give_none() {
        assert!(fit_line(&LineSums::new()).is_none());
        assert!(fit_line(&sums_of(&[[1.0, 1.0]])).is_none());
        assert!(fit_line(&sums_of(&[[1.0, 1.0], [1.0, 1.0]])).is_none());
        assert!(Line::through([1.0, 2.0], [1.0, 2.0]).is_none());
    }

    #[test]
    fn intersection_of_two_known_lines() {
        // y = 2x + 1 and x = −y + 7 (i.e. y = −x + 7) meet at (2, 5).
        let l1 = Line::y_on_x(2.0, 1.0).expect("line");
        let l2 = Line::x_on_y(-1.0, 7.0).expect("line");
        let p = l1.intersection(&l2).expect("not parallel");
        assert!((p[0] - 2.0).abs() < 1e-12 && (p[1] - 5.0).abs() < 1e-12, "{p:?}");
        // x = 3 and y = 4 meet at (3, 4).
        let v = Line::x_on_y(0.0, 3.0).expect("line");
        let h = Line::y_on_x(0.0, 4.0).expect("line");
        let q = v.intersection(&h).expect("not parallel");
        assert!((q[0] - 3.0).abs() < 1e-12 && (q[1] - 4.0).abs() < 1e-12, "{q:?}");
        // Parallel lines do not meet.
        assert!(l1.intersection(&Line::y_on_x(2.0, -3.0).expect("line")).is_none());
    }

    #[test]
    fn line_through_two_points_distance_and_projection() {
        let l = Line::through([0.0, 0.0], [4.0, 3.0]).expect("line");
        // (3, −4) is perpendicular to (4, 3), 5 away.
        assert!((l.distance([3.0, -4.0]) - 5.0).abs() < 1e-12);
        assert!((l.signed_distance([3.0, -4.0]) + l.signed_distance([-3.0, 4.0])).abs() < 1e-12);
        let foot = l.project([3.0, -4.0]);
        assert!(foot[0].abs() < 1e-12 && foot[1].abs() < 1e-12, "{foot:?}");
        assert!((l.orientation() - (3.0f64).atan2(4.0)).abs() < 1e-12);
    }

    #[test]
    fn orientations_compare_modulo_pi() {
        use std::f64::consts::PI;
        assert!(orientation_difference(0.01, PI - 0.01) < 0.0200001);
        assert!((orientation_difference(0.0, PI / 2.0) - PI / 2.0).abs() < 1e-12);
        assert!((orientation_difference(0.3, 0.1) - 0.2).abs() < 1e-12);
        assert!(orientation_difference(1.0, 1.0 + PI) < 1e-12);
        assert!((wrap_orientation(-0.25) - (PI - 0.25)).abs() < 1e-12);
        assert!(wrap_orientation(PI) < 1e-12);
    }

    /// Two parallel edges `width` px apart of a band along `angle`, cut
    /// perpendicular to `cut` (the direction a tracker's trimmed ends cut a
    /// band: its model line's): pixels every 0.5 px of the position along
    /// `cut`, 3 rows (0.5 px apart) per edge.
    fn two_edge_band(angle: f64, cut: f64, length: f64, width: f64) -> Vec<[f64; 2]> {
        let (u, n, m) = ([angle.cos(), angle.sin()], [-angle.sin(), angle.cos()], [cut.cos(), cut.sin()]);
        let dot = |a: [f64; 2], b: [f64; 2]| a[0] * b[0] + a[1] * b[1];
        let mut pts = Vec::new();
        for i in 0..=(2.0 * length) as usize {
            let s = 0.5 * i as f64;
            for d in [
                -0.5 * width - 0.5,
                -0.5 * width,
                -0.5 * width + 0.5,
                0.5 * width - 0.5,
                0.5 * width,
                0.5 * width + 0.5,
            ] {
                // Position t along the line whose point at offset d lies at s along `cut`.
                let t = (s - d * dot(n, m)) / dot(u, m);
                pts.push([100.0 + t * u[0] + d * n[0], 50.0 + t * u[1] + d * n[1]]);
            }
        }
        pts
    }

    #[test]
    fn fit_across_a_direction_recovers_lines_at_any_slope() {
        for angle in [0.0f64, 0.3, 1.2, std::f64::consts::FRAC_PI_2, 2.5] {
            // A thick band cut perpendicular to a direction 5° off the line,
            // regressed across that direction: exact.
            let cut = angle + 0.09;
            let pts = two_edge_band(angle, cut, 40.0, 6.0);
            let fit = fit_line_across(&sums_of(&pts), [cut.cos(), cut.sin()]).expect("fit");
            assert_eq!(fit.regression, Regression::Across);
            assert!(orientation_difference(fit.line.orientation(), wrap_orientation(angle)) < 1e-9, "{angle}: {fit:?}");
            assert!(fit.line.distance([100.0, 50.0]) < 1e-9);
            // Perpendicular spread of the points about the line.
            let expected: f64 =
                pts.iter().map(|p| fit.line.signed_distance(*p).powi(2)).sum::<f64>() / pts.len() as f64;
            assert!((fit.perpendicular_residual_variance() - expected).abs() < 1e-9);
        }
        assert!(fit_line_across(&sums_of(&[[0.0, 0.0], [0.0, 5.0]]), [1.0, 0.0]).is_none(), "no spread along");
    }

    #[test]
    fn a_band_as_wide_as_long_is_fitted_as_two_edges() {
        // 16 px wide, 17 px long (fast motion, trimmed ends), model direction
        // 8° off: the orthogonal fit's principal axis is *across* the band;
        // regressing across the model direction finds the centre line, and
        // the two-edge fit does so with the within-edge residuals only.
        let (angle, cut): (f64, f64) = (1.3, 1.3 - 0.14);
        let dir = [cut.cos(), cut.sin()];
        let exact = two_edge_band(angle, cut, 17.0, 16.0);
        let orthogonal = fit_line_orthogonal(&sums_of(&exact)).expect("fit");
        assert!(orientation_difference(orthogonal.line.orientation(), angle) > 1.0, "{orthogonal:?}");
        // Keep a pseudo-random half of the pixels (as eq. 3 keeps the
        // well-oriented ones), 50 trials: RMS orientation errors.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let (mut sq_pooled, mut sq_band) = (0.0, 0.0);
        let trials = 50;
        for _ in 0..trials {
            let pts: Vec<[f64; 2]> = exact
                .iter()
                .copied()
                .filter(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    state.is_multiple_of(2)
                })
                .collect();
            let pooled = fit_line_across(&sums_of(&pts), dir).expect("fit");
            let band = fit_band_across(&pts, dir, 2.5).expect("fit");
            sq_pooled += orientation_difference(pooled.line.orientation(), angle).powi(2);
            sq_band += orientation_difference(band.line.orientation(), angle).powi(2);
        }
        let (e_pooled, e_band) = ((sq_pooled / trials as f64).sqrt(), (sq_band / trials as f64).sqrt());
        assert!(e_band < 0.25 * e_pooled, "RMS error: band {e_band} rad, pooled {e_pooled} rad");
        let pts = exact;
        let pooled = fit_line_across(&sums_of(&pts), dir).expect("fit");
        let band = fit_band_across(&pts, dir, 2.5).expect("fit");
        assert!(orientation_difference(band.line.orientation(), angle) < 1e-9);
        // Below the split threshold it is the pooled fit.
        let unsplit = fit_band_across(&pts, dir, 100.0).expect("fit");
        assert!(orientation_difference(unsplit.line.orientation(), pooled.line.orientation()) < 1e-9);
        assert_eq!(fit_band_across(&[], dir, 2.5), None);
    }
}
