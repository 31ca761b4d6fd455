//! The steps of paper 002 §2 (Fig. 1) in the paper's order, each a function
//! named for what it does; [`BlueTracker::update`] (in [`super`]) runs them
//! per frame and keeps the state between frames.
//!
//! 1. Prediction (6a, eq. 15) and coarse alignment (extension):
//!    [`BlueTracker::location_at`], [`BlueTracker::predicted_lines`],
//!    [`BlueTracker::align_shift`], [`BlueTracker::first_association`].
//! 2. Data association (§2.4): [`associate_edge_pixels`].
//! 3. Feature measurement (§2.5–2.6, eq. 1–4): [`fit_model_lines`].
//! 4. Corners (§2.7, eq. 5–6): [`intersect_corners`].
//! 5. BLUE (§2.8, eq. 7–9) and 6. its confidence (§2.9, eq. 10–12):
//!    [`BlueTracker::solve_blue`], [`BlueTracker::estimate_location`];
//!    steps 2–6 together: [`BlueTracker::measure`].
//! 7. Re-association (extension): [`BlueTracker::reassociate`].
//! 8. Motion models (§2.10, eq. 13–15): [`start_filters`],
//!    [`BlueTracker::feed_motion_models`], [`BlueTracker::advance_motion_models`].

// `!(x > 0.0)` rejects NaN on purpose.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::{BlueParams, BlueTracker, TargetLocation};
use crate::Result;
use crate::early::Feature;
use crate::estimate::line_fit::{Line, LineSums, fit_x_on_y, fit_y_on_x, orientation_difference, wrap_orientation};
use crate::estimate::{BlueProblem, BlueSolution, Corner, LineLocation, PolynomialSrif, intersect_lines};
use crate::track::round_to_i64;

/// Prior standard deviation of the init location at the start, px.
const INIT_PRIOR_PX: f64 = 2.0;
/// The mantissa bits of an f64: zero for a power of two.
const F64_MANTISSA: u64 = (1 << 52) - 1;
/// Slack, far above float error, of the foot positions a grid of shifts
/// can reach along a segment, px.
const SPREAD_SLACK_PX: f64 = 1e-6;
/// Slack of the corner gate beyond d/sin(angle), px.
const CORNER_GATE_SLACK_PX: f64 = 2.0;

/// A projected visible model line (step 1).
#[derive(Clone, Copy, Debug)]
pub(super) struct PredictedLine {
    line: Line,
    start: [f64; 2],
    direction: [f64; 2],
    length: f64,
    orientation: f64,
    /// Horizontal representation (y on x) when true (eq. 1 from the prediction).
    horizontal: bool,
}

impl PredictedLine {
    #[must_use]
    fn between(p: [f64; 2], q: [f64; 2]) -> Option<Self> {
        let line = Line::through(p, q)?;
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        let length = dx.hypot(dy);
        Some(Self {
            line,
            start: p,
            direction: [dx / length, dy / length],
            length,
            orientation: line.orientation(),
            horizontal: dx.abs() >= dy.abs(),
        })
    }

    #[must_use]
    fn along(&self, p: [f64; 2]) -> f64 {
        (p[0] - self.start[0]) * self.direction[0] + (p[1] - self.start[1]) * self.direction[1]
    }
}

/// One pass of steps 2–6 around a model location.
#[derive(Clone, Debug)]
pub(super) struct Pass {
    pub(super) location: TargetLocation,
    pub(super) covariance: [[f64; 3]; 3],
    pub(super) rms_consistency: f64,
    pub(super) points_per_line: Vec<usize>,
    pub(super) line_fitted: Vec<bool>,
    pub(super) corner_measured: Vec<bool>,
    pub(super) max_corner_deviation: Option<f64>,
    pub(super) unexplained: usize,
    pub(super) labelled: Vec<Vec<(u32, u32)>>,
    /// Whether eq. 9 gave a valid estimate (possibly failing consistency).
    pub(super) estimated: bool,
    pub(super) failure: Option<String>,
}

impl Pass {
    /// A pass that measured nothing, for `edges` model edges and `vertices`
    /// model vertices, failing for `reason`.
    #[must_use]
    pub(super) fn failed(location: &TargetLocation, edges: usize, vertices: usize, reason: String) -> Self {
        Pass {
            location: *location,
            covariance: [[0.0; 3]; 3],
            rms_consistency: f64::NAN,
            points_per_line: vec![0; edges],
            line_fitted: vec![false; edges],
            corner_measured: vec![false; vertices],
            max_corner_deviation: None,
            unexplained: 0,
            labelled: vec![Vec::new(); edges],
            estimated: false,
            failure: Some(reason),
        }
    }
}

/// The edge pixels of step 2, per model line.
#[derive(Clone, Debug)]
pub(super) struct Association {
    /// Sums of eq. 1–3 over each line's pixels.
    sums: Vec<LineSums>,
    /// Each line's pixels (x, y), for the overlay.
    labelled: Vec<Vec<(u32, u32)>>,
    /// Pixels of an orientation compatible with some visible line but near none.
    unexplained: usize,
}

/// The corners of step 4.
#[derive(Clone, Debug)]
pub(super) struct CornerMeasurements {
    /// (vertex, corner) for every measured vertex.
    corners: Vec<(usize, Corner)>,
    /// Per vertex: whether its corner was measured.
    measured: Vec<bool>,
    /// Largest distance of a measured corner from its predicted vertex, px.
    max_deviation: Option<f64>,
}

/// The line along which an edge pixel runs: perpendicular to its gradient
/// direction θ (§2.3), as an orientation modulo π.
#[must_use]
fn edge_orientation(feature: &Feature) -> f64 {
    wrap_orientation(f64::from(feature.theta) + std::f64::consts::FRAC_PI_2)
}

/// Orientation buckets over [0, π) of [`LinesByOrientation`].
const ORIENTATION_BUCKETS: usize = 90;
/// Slack of a bucket's reach beyond the angle tolerance, far above float error, rad.
const BUCKET_SLACK_RAD: f64 = 1e-9;

/// Lines indexed by orientation: for an edge orientation, the lines whose
/// orientation may be within the angle tolerance of it (a superset, in the
/// lines' order), so that a pixel tests only those instead of every line.
struct LinesByOrientation {
    /// Bucket j's lines are `lines[starts[j]..starts[j + 1]]`.
    starts: Vec<usize>,
    lines: Vec<usize>,
}

impl LinesByOrientation {
    /// Index `orientations` (line index, orientation mod π) for `tolerance`:
    /// bucket j, centred on (j + ½)·w with w = π / [`ORIENTATION_BUCKETS`],
    /// holds every line within `tolerance` + w/2 of its centre, so that an
    /// orientation in the bucket within `tolerance` of a line finds it there.
    /// A line with no finite orientation is in every bucket.
    fn new(orientations: &[(usize, f64)], tolerance: f64) -> Self {
        let width = std::f64::consts::PI / ORIENTATION_BUCKETS as f64;
        let reach = tolerance + 0.5 * width + BUCKET_SLACK_RAD;
        let mut starts = Vec::with_capacity(ORIENTATION_BUCKETS + 1);
        let mut lines = Vec::new();
        for j in 0..ORIENTATION_BUCKETS {
            starts.push(lines.len());
            let centre = (j as f64 + 0.5) * width;
            lines.extend(
                orientations
                    .iter()
                    .filter(|&&(_, o)| !o.is_finite() || orientation_difference(o, centre) < reach)
                    .map(|&(k, _)| k),
            );
        }
        starts.push(lines.len());
        Self { starts, lines }
    }

    /// The lines that may be within the tolerance of `orientation` (in [0, π)).
    fn near(&self, orientation: f64) -> &[usize] {
        let width = std::f64::consts::PI / ORIENTATION_BUCKETS as f64;
        let j = ((orientation / width) as usize).min(ORIENTATION_BUCKETS - 1);
        &self.lines[self.starts[j]..self.starts[j + 1]]
    }
}

/// Whether an edge pixel is one of the binary edge image's (§2.3): at least
/// the threshold, with a defined direction.
#[must_use]
fn is_edge(params: &BlueParams, feature: &Feature) -> bool {
    feature.magnitude >= params.edge_threshold && feature.theta.is_finite()
}

// ---------------------------------------------------------------------------
// Step 1: prediction (6a) and coarse alignment.

impl BlueTracker {
    /// Step 1, prediction (eq. 15 at any time; 6a for the next frame, 6b for
    /// the servo cycle): the motion models' (c_x, c_y, c_z) at (frame) time
    /// `time`.
    #[must_use]
    pub(super) fn location_at(&self, time: f64) -> TargetLocation {
        let value = |k: usize| {
            let f = &self.filters[k];
            f.predict(time - f.time()).unwrap_or(f64::NAN)
        };
        TargetLocation { cx: value(0), cy: value(1), cz: value(2) }
    }

    /// Step 1: the visible model lines (SPEC §4) projected at `location`,
    /// one per model edge (`None` for a hidden or degenerate one).
    #[must_use]
    pub(super) fn predicted_lines(&self, location: &TargetLocation) -> Vec<Option<PredictedLine>> {
        let vertices = self.vertices_at(location);
        let visible = self.visible_edges(location);
        self.geometry
            .edges()
            .iter()
            .zip(&visible)
            .map(|(&[i, j], &v)| if v { PredictedLine::between(vertices[i], vertices[j]) } else { None })
            .collect()
    }

    /// Step 1 and the first association's strips: with
    /// [`BlueParams::align`], the `predicted` model shifted by
    /// [`BlueTracker::align_shift`] and the narrow
    /// [`BlueParams::refine_distance`]; otherwise (or when no pixel votes)
    /// the prediction itself and the association distance `distance`.
    #[must_use]
    pub(super) fn first_association(
        &self,
        edges: &[Feature],
        predicted: &TargetLocation,
        distance: f64,
    ) -> (TargetLocation, f64) {
        let shift = if self.params.align { self.align_shift(edges, predicted, distance) } else { None };
        match shift {
            Some([sx, sy]) => (
                TargetLocation { cx: predicted.cx + sx, cy: predicted.cy + sy, cz: predicted.cz },
                self.params.refine_distance,
            ),
            None => (*predicted, distance),
        }
    }

    /// Coarse alignment of step 1 (extension, [`BlueParams::align`]): the image shift (s_x, s_y),
    /// |s_x|, |s_y| ≤ `radius`, of the model projected at `model` that the
    /// edge pixels support best. Every pixel votes, for each visible line of
    /// compatible orientation, for the shifts that put it on that line
    /// (foot inside the segment less the end margins): a line n·s = d in the
    /// 1-px shift grid. The peak of the 3×3-summed votes is where many lines
    /// of different orientations agree; a background edge supports only
    /// shifts along one direction. `None` when no pixel votes.
    #[must_use]
    pub(super) fn align_shift(&self, edges: &[Feature], model: &TargetLocation, radius: f64) -> Option<[f64; 2]> {
        self.shift_peaks(edges, model, radius, 1.0, 1, 0, None).first().copied()
    }

    /// The `count` best shifts of [`BlueTracker::align_shift`]'s vote on a
    /// grid of shifts `step` px apart, best first, each the peak of its
    /// 3×3-summed votes over the grid cells within `separation` cells (the
    /// whole-image search of a lost target uses a coarse grid and several
    /// peaks). With `image` (width, height), only shifts that keep the
    /// model's centroid (`model.cx`, `model.cy`) inside the image are voted
    /// for.
    #[must_use]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn shift_peaks(
        &self,
        edges: &[Feature],
        model: &TargetLocation,
        radius: f64,
        step: f64,
        count: usize,
        separation: i64,
        image: Option<(f64, f64)>,
    ) -> Vec<[f64; 2]> {
        let p = &self.params;
        let lines: Vec<PredictedLine> = self.predicted_lines(model).into_iter().flatten().collect();
        if lines.is_empty() || !(radius >= 0.0) || !(step > 0.0) {
            return Vec::new();
        }
        let r = (radius / step).ceil() as i64;
        let n = (2 * r + 1) as usize;
        // Cells voted for, per axis: the whole grid, or the shifts that keep
        // the centroid in the image.
        let cells = |centre: f64, size: Option<f64>| match size {
            Some(size) => {
                let lo = ((-centre / step).ceil() as i64).clamp(-r, r);
                let hi = (((size - centre) / step).floor() as i64).clamp(-r, r);
                (lo, hi)
            }
            None => (-r, r),
        };
        let (x_lo, x_hi) = cells(model.cx, image.map(|i| i.0));
        let (y_lo, y_hi) = cells(model.cy, image.map(|i| i.1));
        let mut votes = vec![0u32; n * n];
        // Shift in px to grid cells: x / step, as a product where that is
        // exact (a power-of-two step, such as 1).
        let inverse = 1.0 / step;
        let exact_inverse = inverse * step == 1.0 && inverse.to_bits() & F64_MANTISSA == 0;
        let to_cells = |shift: f64| round_to_i64(if exact_inverse { shift * inverse } else { shift / step });
        let reach = radius * std::f64::consts::SQRT_2 + step;
        let orientations: Vec<(usize, f64)> = lines.iter().map(|l| l.orientation).enumerate().collect();
        let by_orientation = LinesByOrientation::new(&orientations, p.angle_tolerance);
        // A coarse grid needs fewer voters: every `step`-th edge pixel.
        for feature in edges.iter().step_by(step.max(1.0) as usize) {
            if !is_edge(p, feature) {
                continue;
            }
            let point = [f64::from(feature.x), f64::from(feature.y)];
            let orientation = edge_orientation(feature);
            for line in by_orientation.near(orientation).iter().map(|&i| &lines[i]) {
                if orientation_difference(orientation, line.orientation) >= p.angle_tolerance {
                    continue;
                }
                let d = line.line.signed_distance(point);
                if d.abs() > reach {
                    continue;
                }
                let s = line.along(point);
                let (a, b) = (line.line.a, line.line.b);
                let [ux, uy] = line.direction;
                let (first, last) = (p.end_margin, line.length - p.end_margin);
                // No shift of the grid brings the foot inside the segment:
                // |u·(i_x, i_y)| ≤ r·(|u_x| + |u_y|).
                let spread = step * r as f64 * (ux.abs() + uy.abs()) + SPREAD_SLACK_PX;
                if s + spread < first || s - spread > last {
                    continue;
                }
                // The foot of the pixel on the segment shifted by cell (i_x, i_y).
                let foot_inside = |ix: i64, iy: i64| {
                    let along = s - step * (ux * ix as f64 + uy * iy as f64);
                    along >= first && along <= last
                };
                // Shifted line: a·(x − s_x) + b·(y − s_y) + c = 0 ⇔ a·s_x + b·s_y = d.
                // Along the dominant axis the other coordinate is
                // d/a − (b·step/a)·i (or with a and b swapped).
                if a.abs() >= b.abs() {
                    let (start, slope) = (d / a, b * step / a);
                    let rows = votes.chunks_exact_mut(n).skip((y_lo + r) as usize);
                    for (iy, row) in (y_lo..=y_hi).zip(rows) {
                        let ix = to_cells(start - slope * iy as f64);
                        if (x_lo..=x_hi).contains(&ix) && foot_inside(ix, iy) {
                            row[(ix + r) as usize] += 1;
                        }
                    }
                } else {
                    let (start, slope) = (d / b, a * step / b);
                    for ix in x_lo..=x_hi {
                        let iy = to_cells(start - slope * ix as f64);
                        if (y_lo..=y_hi).contains(&iy) && foot_inside(ix, iy) {
                            votes[(iy + r) as usize * n + (ix + r) as usize] += 1;
                        }
                    }
                }
            }
        }
        let mut summed = vec![0u32; n * n];
        for iy in y_lo..=y_hi {
            for ix in x_lo..=x_hi {
                let mut sum = 0;
                for jy in (iy - 1).max(-r)..=(iy + 1).min(r) {
                    for jx in (ix - 1).max(-r)..=(ix + 1).min(r) {
                        sum += votes[(jy + r) as usize * n + (jx + r) as usize];
                    }
                }
                summed[(iy + r) as usize * n + (ix + r) as usize] = sum;
            }
        }
        // Cells by summed votes, highest first; ties go to the smaller shift
        // (the prediction is a prior).
        let cell = |i: usize| (i as i64 % n as i64 - r, i as i64 / n as i64 - r);
        let rank = |&i: &usize| {
            let (ix, iy) = cell(i);
            (std::cmp::Reverse(summed[i]), ix * ix + iy * iy)
        };
        let voted = (0..n * n).filter(|&i| summed[i] > 0);
        let order: Vec<usize> = if count == 1 {
            // The first cell of the stable order below.
            voted.min_by_key(rank).into_iter().collect()
        } else {
            let mut order: Vec<usize> = voted.collect();
            order.sort_by_key(rank);
            order
        };
        let mut peaks: Vec<(u32, i64, i64)> = Vec::with_capacity(count);
        for i in order {
            if peaks.len() == count {
                break;
            }
            let (ix, iy) = cell(i);
            if !peaks.iter().any(|&(_, px, py)| (ix - px).abs() <= separation && (iy - py).abs() <= separation) {
                peaks.push((summed[i], ix, iy));
            }
        }
        peaks.into_iter().map(|(_, ix, iy)| [step * ix as f64, step * iy as f64]).collect()
    }
}

// ---------------------------------------------------------------------------
// Step 2: data association (§2.4).

/// Step 2 (§2.4): each edge pixel joins the visible model line of
/// compatible orientation (within [`BlueParams::angle_tolerance`] modulo π)
/// whose segment lies within `distance` (perpendicular distance, foot
/// inside the segment less [`BlueParams::end_margin`] at each end); the
/// nearest such line wins; pixels matching none are dropped.
#[must_use]
pub(super) fn associate_edge_pixels(
    params: &BlueParams,
    edges: &[Feature],
    lines: &[Option<PredictedLine>],
    distance: f64,
) -> Association {
    let p = params;
    let mut sums: Vec<LineSums> =
        lines.iter().map(|l| l.map_or_else(LineSums::new, |l| LineSums::with_origin(l.start))).collect();
    let mut labelled = vec![Vec::new(); lines.len()];
    let mut unexplained = 0;
    // The visible lines in model edge order, with the last foot position
    // inside each segment.
    let visible: Vec<(usize, &PredictedLine, f64)> =
        lines.iter().enumerate().filter_map(|(k, l)| l.as_ref().map(|l| (k, l, l.length - p.end_margin))).collect();
    let orientations: Vec<(usize, f64)> = visible.iter().enumerate().map(|(i, (_, l, _))| (i, l.orientation)).collect();
    let by_orientation = LinesByOrientation::new(&orientations, p.angle_tolerance);
    for feature in edges {
        if !is_edge(p, feature) {
            continue;
        }
        let point = [f64::from(feature.x), f64::from(feature.y)];
        let orientation = edge_orientation(feature);
        let mut best: Option<(usize, f64)> = None;
        let mut compatible = false;
        for &i in by_orientation.near(orientation) {
            let (k, line, last) = visible[i];
            if orientation_difference(orientation, line.orientation) >= p.angle_tolerance {
                continue;
            }
            compatible = true;
            let d = line.line.distance(point);
            if d < distance && best.is_none_or(|(_, bd)| d < bd) {
                let s = line.along(point);
                if s >= p.end_margin && s <= last {
                    best = Some((k, d));
                }
            }
        }
        match best {
            Some((k, _)) => {
                sums[k].add(point[0], point[1]);
                labelled[k].push((feature.x, feature.y));
            }
            None if compatible => unexplained += 1,
            None => {}
        }
    }
    Association { sums, labelled, unexplained }
}

// ---------------------------------------------------------------------------
// Step 3: feature measurement (§2.5–2.6).

/// Step 3 (§2.5–2.6): each line with at least
/// [`BlueParams::min_points_per_line`] pixels fitted in the form its
/// *predicted* orientation picks — y = m·x + b (eq. 1–2) when nearer
/// horizontal, x = m·y + b (eq. 3) otherwise — with eq. 4's empirical
/// variance floored at [`BlueParams::min_point_std`]². A fit turned by the
/// angle tolerance or more from its prediction is refused (clutter, not the
/// edge).
#[must_use]
pub(super) fn fit_model_lines(
    params: &BlueParams,
    sums: &[LineSums],
    lines: &[Option<PredictedLine>],
) -> Vec<Option<LineLocation>> {
    let p = params;
    let min_var = p.min_point_std * p.min_point_std;
    sums.iter()
        .zip(lines)
        .map(|(s, line)| {
            let line = line.as_ref()?;
            if s.count() < p.min_points_per_line {
                return None;
            }
            let fit = if line.horizontal { fit_y_on_x(s) } else { fit_x_on_y(s) }?;
            if orientation_difference(fit.line.orientation(), line.orientation) >= p.angle_tolerance {
                return None;
            }
            LineLocation::new(s, fit, min_var)
        })
        .collect()
}

// ---------------------------------------------------------------------------
// Step 4: corners (§2.7).

/// Step 4 (§2.7): at each vertex with two or more fitted lines among its
/// edges (`vertex_edges`), the pair meeting at the largest angle (at least
/// [`BlueParams::min_corner_angle`]) intersected by eq. 5 with eq. 6's
/// covariance ([`intersect_lines`]). A corner farther from the vertex
/// projected at the model location (`vertices`) than `distance`/sin(angle)
/// + 2 px is dropped; the deviation is measured from `predicted_vertices`.
#[must_use]
pub(super) fn intersect_corners(
    params: &BlueParams,
    vertex_edges: &[Vec<usize>],
    fitted: &[Option<LineLocation>],
    vertices: &[[f64; 2]],
    predicted_vertices: &[[f64; 2]],
    distance: f64,
) -> CornerMeasurements {
    let p = params;
    let min_sine = p.min_corner_angle.sin();
    let mut corners: Vec<(usize, Corner)> = Vec::new();
    let mut measured = vec![false; vertices.len()];
    let mut max_deviation: Option<f64> = None;
    for (v, incident) in vertex_edges.iter().enumerate() {
        let mut best: Option<(f64, usize, usize)> = None;
        for (a, &k1) in incident.iter().enumerate() {
            for &k2 in &incident[a + 1..] {
                let (Some(l1), Some(l2)) = (&fitted[k1], &fitted[k2]) else {
                    continue;
                };
                let sine = (l1.fit.line.a * l2.fit.line.b - l1.fit.line.b * l2.fit.line.a).abs();
                if sine >= min_sine && best.is_none_or(|(bs, _, _)| sine > bs) {
                    best = Some((sine, k1, k2));
                }
            }
        }
        let Some((sine, k1, k2)) = best else { continue };
        let (Some(l1), Some(l2)) = (&fitted[k1], &fitted[k2]) else {
            continue;
        };
        let Some(corner) = intersect_lines(l1, l2, p.corner_covariance) else {
            continue;
        };
        let gate = distance / sine + CORNER_GATE_SLACK_PX;
        let (dx, dy) = (corner.position[0] - vertices[v][0], corner.position[1] - vertices[v][1]);
        if !(dx.hypot(dy) <= gate) {
            continue;
        }
        measured[v] = true;
        let pv = predicted_vertices[v];
        let dev = (corner.position[0] - pv[0]).hypot(corner.position[1] - pv[1]);
        max_deviation = Some(max_deviation.map_or(dev, |m: f64| m.max(dev)));
        corners.push((v, corner));
    }
    CornerMeasurements { corners, measured, max_deviation }
}

// ---------------------------------------------------------------------------
// Steps 5–6: the BLUE (§2.8) and its confidence (§2.9).

/// Eq. 9–12 solved for a list of corners.
#[derive(Clone, Debug)]
pub(super) struct BlueEstimate {
    /// (c_x, c_y, c_z) from x̂_f = (c_x, c_y, 1/c_z).
    pub(super) location: TargetLocation,
    /// Eq. 9–12's solution; its per-block vectors (residuals, e of eq. 11)
    /// are in block order.
    pub(super) solution: BlueSolution<3>,
    /// Block j of the solution is the corner at index `used[j]` of the list
    /// solved: [`BlueProblem::add`] refuses a corner whose rows or value
    /// are not finite or whose covariance is not positive definite, and a
    /// refused corner has no block.
    pub(super) used: Vec<usize>,
}

impl BlueTracker {
    /// Step 5 (§2.8, eq. 7–9) with step 6's confidence (§2.9, eq. 10–12):
    /// eq. 9 for `corners` (vertex, corner), the rows of eq. 8 per corner
    /// with u_xi, u_yi of eq. 7 in the perspective form iterated from `start`
    /// ([`super`] module doc); the estimate, eq. 9–12's solution and which
    /// corners its blocks are. Fails when eq. 9 is singular, or when an
    /// estimate is not in front of the camera or puts a model vertex where
    /// it cannot be projected (the perspective rows need every vertex's
    /// pixel, and so does the output).
    pub(super) fn solve_blue(
        &self,
        corners: &[(usize, Corner)],
        start: &TargetLocation,
    ) -> std::result::Result<BlueEstimate, String> {
        let p = &self.params;
        let [px, py] = self.eq7_scales();
        let (fx, fy, u0, v0) = (self.camera.fx, self.camera.fy, self.camera.cx, self.camera.cy);
        let z0 = self.nominal_range;
        let iterations = if p.perspective_correction { 1 + p.perspective_iterations } else { 1 };
        let mut estimate = *start;
        let mut solution = None;
        for _ in 0..iterations {
            let projected = self.vertices_at(&estimate);
            let mut problem = BlueProblem::<3>::new();
            let mut used = Vec::with_capacity(corners.len());
            for (i, (v, corner)) in corners.iter().enumerate() {
                let q = self.offsets[*v];
                let (ux, uy) = if p.perspective_correction {
                    let u = projected[*v];
                    ((q.x - q.z * (u[0] - u0) / fx) / z0, (q.y - q.z * (u[1] - v0) / fy) / z0)
                } else {
                    (q.x / z0, q.y / z0)
                };
                // Eq. 8: rows [1, 0, p_x·u_x], [0, 1, p_y·u_y] for x_f = (c_x, c_y, 1/c_z).
                if problem.add([[1.0, 0.0, px * ux], [0.0, 1.0, py * uy]], corner.position, corner.covariance) {
                    used.push(i);
                }
            }
            let floor = p.min_feature_std * p.min_feature_std;
            let s = problem.solve(floor).ok_or_else(|| "eq. 9 is singular for the measured corners".to_string())?;
            estimate = TargetLocation { cx: s.estimate[0], cy: s.estimate[1], cz: 1.0 / s.estimate[2] };
            if !estimate.is_valid() {
                return Err(format!("the estimate puts the target behind the camera (1/c_z = {})", s.estimate[2]));
            }
            if let Some(reason) = self.unprojectable_vertex(&estimate) {
                return Err(format!("the estimate cannot be projected: {reason}"));
            }
            solution = Some((s, used));
        }
        solution
            .map(|(solution, used)| BlueEstimate { location: estimate, solution, used })
            .ok_or_else(|| "no estimate".to_string())
    }

    /// Steps 5–6 with the consistency extension: eq. 9 for `corners` from
    /// `start`, then, while the least consistent corner (largest |e_j|,
    /// eq. 11) exceeds [`BlueParams::max_corner_inconsistency`] and more
    /// than [`BlueParams::min_corners`] remain, that corner dropped (and
    /// unmarked in `measured`) and eq. 9 solved again from the last estimate.
    /// Corners eq. 9 refuses (no block, [`BlueEstimate::used`]) are dropped
    /// and unmarked too, so that on return `corners[j]` is the solution's
    /// block j; fewer than [`BlueParams::min_corners`] left is a failure.
    pub(super) fn estimate_location(
        &self,
        corners: &mut Vec<(usize, Corner)>,
        measured: &mut [bool],
        start: &TargetLocation,
    ) -> std::result::Result<(TargetLocation, BlueSolution<3>), String> {
        let p = &self.params;
        let mut found = self.solve_blue(corners, start)?;
        loop {
            keep_used_corners(corners, measured, &found.used);
            if corners.len() < p.min_corners {
                return Err(format!(
                    "{} corners usable in eq. 9, fewer than min_corners = {}",
                    corners.len(),
                    p.min_corners
                ));
            }
            if corners.len() <= p.min_corners.max(2) {
                break;
            }
            let Some((worst, e)) = found
                .solution
                .consistency
                .iter()
                .enumerate()
                .map(|(i, e)| (i, e[0].hypot(e[1])))
                .max_by(|a, b| a.1.total_cmp(&b.1))
            else {
                break;
            };
            if !(e > p.max_corner_inconsistency) {
                break;
            }
            let (v, _) = corners.remove(worst);
            measured[v] = false;
            found = self.solve_blue(corners, &found.location)?;
        }
        Ok((found.location, found.solution))
    }

    /// Steps 2–6 with the model at `model` and association distance
    /// `distance`; `predicted` only serves the corner deviation. The pass
    /// fails with fewer than [`BlueParams::min_corners`] corners, without a
    /// valid estimate, or when the RMS of eq. 11's e exceeds
    /// [`BlueParams::max_inconsistency`] (then still `estimated`).
    #[must_use]
    pub(super) fn measure(
        &self,
        edges: &[Feature],
        model: &TargetLocation,
        predicted: &TargetLocation,
        distance: f64,
    ) -> Pass {
        let p = &self.params;
        let vertices = self.vertices_at(model);
        let lines = self.predicted_lines(model);
        let association = associate_edge_pixels(p, edges, &lines, distance);
        let fitted = fit_model_lines(p, &association.sums, &lines);
        let predicted_vertices = self.vertices_at(predicted);
        let CornerMeasurements { mut corners, measured, max_deviation } =
            intersect_corners(p, self.geometry.vertex_edges(), &fitted, &vertices, &predicted_vertices, distance);
        let mut pass = Pass {
            location: *model,
            covariance: [[0.0; 3]; 3],
            rms_consistency: f64::NAN,
            points_per_line: association.sums.iter().map(LineSums::count).collect(),
            line_fitted: fitted.iter().map(Option::is_some).collect(),
            corner_measured: measured,
            max_corner_deviation: max_deviation,
            unexplained: association.unexplained,
            labelled: association.labelled,
            estimated: false,
            failure: None,
        };
        if corners.len() < p.min_corners {
            pass.failure =
                Some(format!("{} corners measured, fewer than min_corners = {}", corners.len(), p.min_corners));
            return pass;
        }
        let (estimate, solution) = match self.estimate_location(&mut corners, &mut pass.corner_measured, model) {
            Ok(found) => found,
            Err(reason) => {
                pass.failure = Some(reason);
                return pass;
            }
        };
        pass.location = estimate;
        pass.estimated = true;
        pass.covariance = solution.consistency_covariance;
        pass.rms_consistency = solution.rms_consistency();
        if !(pass.rms_consistency <= p.max_inconsistency) {
            pass.failure = Some(format!(
                "global consistency fails: RMS of e (eq. 11) {:.2} px > max_inconsistency {} px",
                pass.rms_consistency, p.max_inconsistency
            ));
        }
        pass
    }
}

/// Keep only the corners at the indices `used` (increasing, as
/// [`BlueEstimate::used`]), unmarking the others' vertices in `measured`:
/// afterwards corner j is block j of the solution that `used` describes.
fn keep_used_corners(corners: &mut Vec<(usize, Corner)>, measured: &mut [bool], used: &[usize]) {
    if used.len() == corners.len() {
        return;
    }
    let mut index = 0;
    corners.retain(|(v, _)| {
        let keep = used.binary_search(&index).is_ok();
        index += 1;
        if !keep {
            measured[*v] = false;
        }
        keep
    });
}

// ---------------------------------------------------------------------------
// Step 7: re-association (extension).

impl BlueTracker {
    /// Step 7 (extension, [`BlueParams::refine_passes`]): steps 2–6 again
    /// around the location of the last pass with an estimate, with the
    /// narrow [`BlueParams::refine_distance`]; also after a pass that failed
    /// only the consistency check (the wide strips' clutter is what the
    /// narrow ones drop). Stops at the first pass without an estimate; the
    /// last pass with one decides.
    #[must_use]
    pub(super) fn reassociate(&self, edges: &[Feature], mut pass: Pass, predicted: &TargetLocation) -> Pass {
        for _ in 0..self.params.refine_passes {
            if !pass.estimated {
                break;
            }
            let refined = self.measure(edges, &pass.location, predicted, self.params.refine_distance);
            if !refined.estimated {
                break;
            }
            pass = refined;
        }
        pass
    }
}

// ---------------------------------------------------------------------------
// Step 8: motion models (§2.10).

/// Fresh motion models at `location` at time `time`: the location with
/// standard deviation [`INIT_PRIOR_PX`], velocity and acceleration zero with
/// the params' prior deviations (px converted to m for c_z).
pub(super) fn start_filters(
    params: &BlueParams,
    location: &TargetLocation,
    time: f64,
    range_px_per_m: f64,
) -> Result<[PolynomialSrif<3>; 3]> {
    let mut filters = [PolynomialSrif::<3>::new(params.lambda, time)?; 3];
    let values = [location.cx, location.cy, location.cz];
    let px_to_unit = [1.0, 1.0, 1.0 / range_px_per_m];
    for ((filter, &value), &scale) in filters.iter_mut().zip(&values).zip(&px_to_unit) {
        let (p, v, a) = (INIT_PRIOR_PX * scale, params.prior_speed * scale, params.prior_acceleration * scale);
        filter.add_prior(0, value, p * p);
        filter.add_prior(1, 0.0, v * v);
        filter.add_prior(2, 0.0, a * a);
    }
    Ok(filters)
}

impl BlueTracker {
    /// Step 8 on a tracked frame (§2.10, eq. 13–14): c_x, c_y and c_z of
    /// `pass` fed to their polynomial filters at `time` with the variances of
    /// eq. 12's C_l; c_z's from that of 1/c_z by the delta method,
    /// Var(c_z) = Var(1/c_z)·c_z⁴.
    pub(super) fn feed_motion_models(&mut self, time: f64, pass: &Pass) {
        let c = pass.covariance;
        let rho = pass.location.inverse_range();
        let variances = [c[0][0], c[1][1], c[2][2] / rho.powi(4)];
        let values = [pass.location.cx, pass.location.cy, pass.location.cz];
        for ((filter, &v), &var) in self.filters.iter_mut().zip(&values).zip(&variances) {
            filter.update(time, v, var);
        }
    }

    /// Step 8 on a lost frame: the filters advance to `time` without data
    /// (their information decays, the polynomials extrapolate).
    pub(super) fn advance_motion_models(&mut self, time: f64) {
        for filter in &mut self.filters {
            filter.advance_to(time);
        }
    }

    /// Step 8 restarted: fresh filters at `location` at rest at `time`
    /// ([`start_filters`]); the filters stay as they are if that fails.
    pub(super) fn restart_motion_models(&mut self, location: &TargetLocation, time: f64) {
        if let Ok(filters) = start_filters(&self.params, location, time, self.range_px_per_m) {
            self.filters = filters;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::formats::{Camera, InitState, Model, Pose};

    /// A 0.2 × 0.15 × 0.1 m box (vertex i: signs from bits 0–2 of i), its
    /// centroid 0.9 m in front of a 640×480 camera with f = 500 px.
    fn tracker() -> BlueTracker {
        let half = [0.1, 0.075, 0.05];
        let vertices: Vec<[f64; 3]> =
            (0..8).map(|i| std::array::from_fn(|a| if (i >> a) & 1 == 1 { half[a] } else { -half[a] })).collect();
        let edges = (0..8usize).flat_map(|i| (0..3).map(move |a| [i, i | (1 << a)])).filter(|&[i, j]| i != j).collect();
        let model =
            Model { name: "box".into(), units: "m".into(), vertices, edges, faces: Vec::new(), joints: Vec::new() };
        let camera = Camera { width: 640, height: 480, fx: 500.0, fy: 500.0, cx: 319.5, cy: 239.5 };
        let pose = Pose { rotation: [0.4, -0.5, 0.1], translation: [0.02, -0.01, 0.9] };
        let init = InitState { pose: Some(pose), ..InitState::default() };
        BlueTracker::new(camera, model, init, BlueParams::default()).expect("tracker")
    }

    /// Five exact corners (vertices 0–4, Σ = 0.25 px²·I) where eq. 9
    /// refuses vertex 0's block (its covariance is not positive definite)
    /// and vertex 3 is 8 px off. The consistency extension must drop vertex
    /// 3 (the outlier), not the corner that sits at its block index in the
    /// list with the refused one; vertex 0 is unmarked too, and the estimate
    /// is eq. 9 on vertices 1, 2 and 4: the true location.
    #[test]
    fn a_refused_block_keeps_corners_and_blocks_aligned() {
        let tracker = tracker();
        let truth = tracker.last_tracked;
        let vertices = tracker.vertices_at(&truth);
        let covariance = [[0.25, 0.0], [0.0, 0.25]];
        let mut corners: Vec<(usize, Corner)> =
            (0..5).map(|v| (v, Corner { position: vertices[v], covariance })).collect();
        corners[0].1.covariance = [[0.0; 2]; 2];
        corners[3].1.position[0] += 8.0;
        let mut measured = [true, true, true, true, true, false, false, false];

        let (location, solution) = tracker.estimate_location(&mut corners, &mut measured, &truth).expect("an estimate");

        let kept: Vec<usize> = corners.iter().map(|&(v, _)| v).collect();
        assert_eq!(kept, [1, 2, 4], "corners left");
        assert_eq!(measured, [false, true, true, false, true, false, false, false]);
        assert_eq!(solution.consistency.len(), corners.len(), "one block per corner left");
        // The perspective rows are iterated a fixed number of times, so the
        // estimate is the true location to within the iteration's residue.
        let alone = tracker.solve_blue(&corners, &truth).expect("eq. 9 on vertices 1, 2, 4");
        assert_eq!(alone.used, [0, 1, 2]);
        for other in [truth, alone.location] {
            let close = (location.cx - other.cx).abs() < 1e-4
                && (location.cy - other.cy).abs() < 1e-4
                && (location.cz - other.cz).abs() < 1e-6;
            assert!(close, "estimate {location:?}, expected {other:?}");
        }
    }

    /// Every line within the tolerance of an orientation is among the
    /// bucket's lines, in line order, also across the wrap at 0 and π.
    #[test]
    fn orientation_buckets_hold_every_compatible_line_in_order() {
        use std::f64::consts::PI;
        let mut orientations: Vec<(usize, f64)> =
            (0..40).map(|k| (k, (f64::from(k as u32) * 0.611).rem_euclid(PI))).collect();
        orientations.extend([(40, 0.0), (41, PI - 1e-12), (42, 1e-12), (43, f64::NAN), (44, 0.5 * PI)]);
        for tolerance in [1e-3, 0.05, 10f64.to_radians(), 1.0, 2.0] {
            let index = LinesByOrientation::new(&orientations, tolerance);
            for step in 0..=4000 {
                let o = wrap_orientation(f64::from(step) * PI / 4000.0 - 1e-13);
                let near = index.near(o);
                assert!(near.windows(2).all(|w| w[0] < w[1]), "lines in order");
                for &(k, line) in &orientations {
                    if !(orientation_difference(o, line) >= tolerance) {
                        assert!(near.contains(&k), "line {k} at {line} missing for {o} (tolerance {tolerance})");
                    }
                }
            }
        }
    }

    /// Eq. 9 reports which corners its blocks are: a corner with a NaN
    /// position gets no block.
    #[test]
    fn solve_blue_lists_the_corners_it_used() {
        let tracker = tracker();
        let truth = tracker.last_tracked;
        let vertices = tracker.vertices_at(&truth);
        let covariance = [[0.25, 0.0], [0.0, 0.25]];
        let mut corners: Vec<(usize, Corner)> =
            (0..4).map(|v| (v, Corner { position: vertices[v], covariance })).collect();
        corners[1].1.position = [f64::NAN, 0.0];
        let found = tracker.solve_blue(&corners, &truth).expect("eq. 9");
        assert_eq!(found.used, [0, 2, 3]);
        assert_eq!(found.solution.consistency.len(), 3);
    }
}
