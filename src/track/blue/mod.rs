//! The `blue` tracker of paper 002 (Schneiderman, Wavering, Nashman & Lumia,
//! "Real-Time Model-Based Visual Tracking"): a polyhedron with a fixed
//! orientation translating in x, y, z, located in every image by the best
//! linear unbiased estimate (BLUE) of (c_x, c_y, 1/c_z) from its corners, and
//! followed by exponentially weighted 2nd-order polynomial motion models.
//!
//! # Input
//! Per frame the backend's edge pixels (§2.3): Sobel 3×3 magnitude
//! thresholded at [`BlueParams::edge_threshold`], only inside
//! [`BlueTracker::window_of_interest`], a seeded random subsample of at most
//! [`BlueParams::max_edge_points`] (paper: 1500). Each pixel carries the
//! gradient direction θ = atan2(g_y, g_x); its edge runs along θ + π/2.
//!
//! # State and geometry (SPEC §4 conventions)
//! The object's rotation R is the one of `init.json` and never changes. The
//! tracked point is the centroid c of the model's vertices; with q_i =
//! R·(P_i − c) the vertex offsets in the camera frame and X = (X, Y, Z) the
//! centroid in the camera frame, the paper's target location is
//! - c_x = f_x·X/Z + u₀, c_y = f_y·Y/Z + v₀: the image of the centroid, px;
//! - c_z = Z: its range, m (the model estimates 1/c_z, eq. 7–9);
//!
//! and back: X = (c_x − u₀)·c_z/f_x, Y = (c_y − v₀)·c_z/f_y, Z = c_z; the
//! pose's translation is t = X − R·c, its rotation the init one.
//!
//! Vertex i projects exactly to u_i = u₀ + (c_x − u₀ + f_x·q_ix/c_z)/(1 + q_iz/c_z),
//! which rearranges to u_i = c_x + (1/c_z)·(f_x·q_ix − (u_i − u₀)·q_iz): the
//! linear form of eq. 7 with p_x·u_xi = f_x·q_ix − (u_i − u₀)·q_iz. The model is
//! "given at a nominal range" Z₀ ([`BlueParams::nominal_range`], default the
//! init range) as the paper does: u_xi = (q_ix − q_iz·(u_i − u₀)/f_x)/Z₀ are
//! normalised model coordinates at Z₀ and p_x = f_x·Z₀, p_y = f_y·Z₀ (from
//! camera.json and Z₀). The q_iz term is the perspective correction of the
//! general case; it needs u_i, taken from the current estimate and iterated
//! ([`BlueParams::perspective_iterations`]; a fixed point of eq. 9 whose rows
//! are exact at convergence). With [`BlueParams::perspective_correction`]
//! off, u_xi = q_ix/Z₀: the paper's affine (weak-perspective) model, exact
//! only for vertices in the plane Z = c_z (q_iz = 0) and off by
//! ≈ (u_i − u₀)·q_iz/c_z px otherwise — several px for a box 0.1 m deep seen
//! off-axis at 0.85 m, which is why the correction is on by default.
//!
//! # Steps per frame (paper §2, Fig. 1)
//! 1. Prediction (6a): the motion models give (c_x, c_y, c_z) at this frame;
//!    the model's visible edges (those bordering a face that faces the
//!    camera, SPEC §4; every edge when the model has no faces) are projected.
//!    Then coarse alignment (extension, [`BlueParams::align`]): the model is
//!    shifted in the image by the translation (within ± the association
//!    distance, 1-px grid) that the edge pixels support jointly: each pixel
//!    votes, for every visible line of compatible orientation, for the
//!    shifts that would put it on that line. Only the target's own lines,
//!    of many orientations, agree on one shift; a background edge supports
//!    a whole line of shifts. Steps 2–6 then run around the shifted model
//!    with the narrow [`BlueParams::refine_distance`]. Without it the first
//!    association needs strips as wide as the prediction error (up to
//!    10 px at 1.2 rad/s), and at long range, where the whole target is
//!    26–36 px wide, such strips take in the target's other edges (door
//!    divider, light boxes, bumper) and the bookshelf behind it: the fits
//!    turn beyond the angle tolerance, are refused, no corner is left and
//!    the frame is lost although the prediction was right (target3dof at
//!    0.3 rad/s, frame 230); the same wide strips around a target that had
//!    moved made re-acquisition fail.
//! 2. Data association (§2.4): an edge pixel joins the visible model line
//!    whose orientation is within [`BlueParams::angle_tolerance`] (modulo π)
//!    and whose segment lies within the association distance (perpendicular,
//!    foot inside the segment less [`BlueParams::end_margin`] at each end,
//!    where the two lines of a corner blur into each other); the nearest such
//!    line wins; pixels matching none are dropped.
//! 3. Feature measurement (§2.5–2.6): each line with at least
//!    [`BlueParams::min_points_per_line`] pixels is fitted in the horizontal
//!    (y = m·x + b) or vertical (x = m·y + b) form chosen from its *predicted*
//!    orientation (eq. 1–3), with the empirical variance of eq. 4 (floored at
//!    [`BlueParams::min_point_std`]²). A fit turned more than the angle
//!    tolerance from its prediction is refused (clutter, not the edge).
//! 4. Corners (§2.7): at each vertex with two or more fitted visible lines,
//!    the pair meeting at the largest angle (at least
//!    [`BlueParams::min_corner_angle`]) is intersected with eq. 5 and its
//!    covariance propagated with eq. 6 ([`crate::estimate::intersect_lines`];
//!    Σ per [`BlueParams::corner_covariance`]). A corner farther from the
//!    projected vertex than the association distance allows (d/sin(angle)
//!    + 2 px) is dropped.
//! 5. Aggregation (§2.8): eq. 9 with full 2×2 blocks C_vi
//!    ([`crate::estimate::BlueProblem`]).
//! 6. Confidence (§2.9): C_l of eq. 12 with e of eq. 11 (normalised per
//!    coordinate, see [`crate::estimate`]), e_j floored at
//!    [`BlueParams::min_feature_std`].
//!    Extension: the corner least consistent with the estimate (largest
//!    |e_j|) is dropped and eq. 9 solved again while |e_j| exceeds
//!    [`BlueParams::max_corner_inconsistency`] and more than
//!    [`BlueParams::min_corners`] corners remain (the paper only
//!    down-weights; a corner on a line captured by a parallel background
//!    edge can be wrong with a small variance).
//! 7. Re-association (extension, [`BlueParams::refine_passes`], 0 = the
//!    paper's single pass): steps 2–6 again around the model projected at the
//!    BLUE, with the narrower [`BlueParams::refine_distance`]. The first pass
//!    must accept the prediction error; these passes drop the background
//!    edges the wide first strips took in. A pass that fails only the
//!    consistency check is still refined; the last pass decides.
//! 8. Motion models (§2.10): c_x, c_y and c_z each get a 2nd-order polynomial
//!    fitted with decay λ and weights 1/C_l(k, k) (eq. 13–14; the variance of
//!    c_z from that of 1/c_z by the delta method, Var(c_z) = Var(1/c_z)·c_z⁴),
//!    solved recursively by [`crate::estimate::PolynomialSrif`]. Eq. 15
//!    predicts the next image; [`BlueTracker::predict_ahead`] any time ahead
//!    (6b, the servo cycle).
//!
//! # Start, loss and output
//! Frame 0 is measured around the init pose. While the polynomials have
//! fewer than 3 samples (their velocity and acceleration not yet measured)
//! or the track is lost, association uses the wider
//! [`BlueParams::acquire_distance`]. The filters start with the init location
//! as a weak prior (2 px), zero velocity with a loose prior
//! ([`BlueParams::prior_speed`]) and zero acceleration with
//! [`BlueParams::prior_acceleration`]; priors decay like data.
//!
//! A frame is **lost** when fewer than [`BlueParams::min_corners`] corners
//! are measured (2: four equations for three unknowns), when eq. 9 is
//! singular, when the estimate is not in front of the camera, or when the
//! global consistency fails badly: RMS of e (eq. 11) above
//! [`BlueParams::max_inconsistency`] px. A lost frame feeds nothing to the
//! motion models (their information decays, the polynomials extrapolate),
//! reports the predicted vertices and pose with status `lost`, and the next
//! frames re-acquire with the wide distance around the prediction. After
//! [`BlueParams::coast_frames`] lost frames in a row (or when the
//! extrapolation leaves the space in front of the camera) the models restart
//! at the last tracked location at rest: a parabola extrapolated for long
//! runs away from where the target was.
//!
//! Reported per frame: the projection of every model vertex (model-vertex
//! order, hidden ones too) at the frame's BLUE (the prediction when lost),
//! the pose, and as covariance C_l of (c_x, c_y, 1/c_z) row-major (eq. 12; when
//! lost, the motion models' prediction variances on the diagonal).

// `!(x > 0.0)` rejects NaN on purpose.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use serde::{Deserialize, Serialize};

use super::{Diagnostics, FrameOutcome, Observations, Phase, Tracker};
use crate::backend::{EdgeRequest, FrameRequest, ListSpec};
use crate::early::compaction::MAX_CAP;
use crate::early::{Feature, Window};
use crate::estimate::line_fit::{Line, LineSums, fit_x_on_y, fit_y_on_x, orientation_difference, wrap_orientation};
use crate::estimate::{BlueProblem, CornerCovariance, LineLocation, PolynomialSrif, intersect_lines};
use crate::io::formats::{Camera, InitState, Model, Pose, Status};
use crate::{Error, Result};

/// Parameters of the blue tracker (paper 002), all with defaults, so a
/// `--config` TOML file may set any subset (unknown keys are refused).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BlueParams {
    /// Sobel 3×3 magnitude threshold of the binary edge image (§2.3; for the
    /// backend; weaker pixels handed over are ignored). Unnormalised Sobel on
    /// 0..255 grey levels gives 4·C on a step of contrast C; 80 keeps steps
    /// of 20 grey levels and more. The paper gives no value.
    pub edge_threshold: f32,
    /// Cap on the edge pixels sampled in the window (§2.3: 1500).
    pub max_edge_points: usize,
    /// Seed of the backend's random subsample.
    pub sample_seed: u64,
    /// Orientation agreement of §2.4, radians (paper: no value). 10°: Sobel
    /// orientations of a sharp edge are good to a few degrees and the
    /// target's orientation is fixed, so its edges never turn; a random
    /// clutter orientation passes with probability 1/9, and a bookshelf's
    /// vertical edges stay out of target edges tilted more than 10° (15°
    /// let an upright crossing a 7°-tilted edge capture it in the tests).
    pub angle_tolerance: f64,
    /// Spatial proximity of §2.4 while tracking, px.
    pub distance_tolerance: f64,
    /// Spatial proximity while acquiring or lost, px: must exceed a frame's
    /// motion before velocity is known (1.2 rad/s at f = 500 px, 30 Hz: 20 px).
    pub acquire_distance: f64,
    /// Proximity of the re-association around the BLUE (step 7), px: wide
    /// enough for a first estimate biased by clutter to still see the true
    /// edge, narrow enough to drop clutter further out.
    pub refine_distance: f64,
    /// Re-association passes (step 7); 0: the paper's single pass. 3 lets an
    /// estimate pulled by clutter in the wide first strips walk back.
    pub refine_passes: usize,
    /// Coarse alignment before association (step 1, extension): the image
    /// shift of the predicted model within ± the association distance that
    /// the most compatible edge pixels support jointly (a Hough vote over all
    /// visible lines), after which the first association uses the narrow
    /// [`BlueParams::refine_distance`]. Off: the paper's single association
    /// around the prediction with the wide distance.
    pub align: bool,
    /// Pixels whose foot lies within this distance of a segment end are not
    /// associated, px. 2: the 3×3 Sobel blurs the two lines of a corner into
    /// each other over about a pixel, whatever the target's size; a margin
    /// of 4 px left a 13-px model edge of the target at 5 m (26 px wide) too
    /// few pixels to fit, and those corners were never measured.
    pub end_margin: f64,
    /// Fewest associated pixels to fit a line (≥ 3).
    pub min_points_per_line: usize,
    /// Floor on the standard deviation of eq. 4, px: pixel positions are
    /// quantised (1/√12 ≈ 0.29 px), so a perfectly straight run of pixels
    /// does not claim infinite precision.
    pub min_point_std: f64,
    /// How eq. 6's Σ is formed ([`crate::estimate`] module doc).
    pub corner_covariance: CornerCovariance,
    /// Smallest angle between the two lines of a corner, radians.
    pub min_corner_angle: f64,
    /// Nominal range Z₀ of the model (§2.8), m; `None`: the init range.
    pub nominal_range: Option<f64>,
    /// The general (perspective) form of eq. 7 (module doc); off: affine.
    pub perspective_correction: bool,
    /// Fixed-point iterations of eq. 9 for the perspective correction.
    pub perspective_iterations: usize,
    /// Exponential decay λ of eq. 14, 0 < λ < 1. The paper gives no value.
    /// 0.6 (α-β-γ gains of eq. 18: α = 0.784, β = 0.384, γ = 0.128): the
    /// one-step prediction of a 2nd-order fit lags a changing acceleration
    /// (jerk j) by ≈ j/γ; on a target sweeping ±180 px at 20 px/frame peak
    /// (1.2 rad/s, reversing every 28 frames) the largest prediction error
    /// is 3.6 px at λ = 0.6, 7.9 px at 0.7 and 22 px at 0.8, and the
    /// association distance must cover it. Measurement noise of a BLUE from
    /// hundreds of edge pixels is ≈ 0.1 px, so the short memory costs little.
    pub lambda: f64,
    /// Fewest corners of a tracked frame (≥ 2).
    pub min_corners: usize,
    /// Largest RMS of the consistency vector e of eq. 11 of a tracked frame, px.
    pub max_inconsistency: f64,
    /// Corners whose consistency |e_j| (eq. 11) exceeds this are dropped
    /// one at a time, worst first, and eq. 9 solved again, while more than
    /// `min_corners` remain (extension: the paper only down-weights), px.
    pub max_corner_inconsistency: f64,
    /// Floor on each |e_j| in eq. 12, px (a perfect fit does not make the
    /// location exact). 0.2: the corners of Sobel edges on rendered frames
    /// are good to a few tenths of a pixel; a floor of 0.05 px let one
    /// frame whose few corners happened to agree outweigh the motion
    /// models' memory (eq. 14 weights by 1/C_l), and its error was
    /// extrapolated into the next predictions.
    pub min_feature_std: f64,
    /// Margin of the window of interest beyond the association distance, px.
    pub window_margin: f64,
    /// Prior standard deviation of the velocity at the start, px per frame:
    /// loose, it only makes the first predictions defined.
    pub prior_speed: f64,
    /// Prior standard deviation of the acceleration at the start, px per
    /// frame²: a hand-held target reversing 20 px/frame within half a second
    /// accelerates ≈ 1.3 px/frame²; without this prior the second frame's
    /// prediction extrapolates a parabola through two samples.
    pub prior_acceleration: f64,
    /// Lost frames during which the motion models keep extrapolating; after
    /// them the models restart at the last tracked location at rest (a
    /// parabola extrapolated for long runs away from where the target was).
    pub coast_frames: usize,
}

impl Default for BlueParams {
    fn default() -> Self {
        Self {
            edge_threshold: 80.0,
            max_edge_points: 1500,
            sample_seed: 0,
            angle_tolerance: 10f64.to_radians(),
            distance_tolerance: 12.0,
            acquire_distance: 30.0,
            refine_distance: 5.0,
            refine_passes: 3,
            align: true,
            end_margin: 2.0,
            min_points_per_line: 10,
            min_point_std: 1.0 / 12f64.sqrt(),
            corner_covariance: CornerCovariance::LineLocation,
            min_corner_angle: 20f64.to_radians(),
            nominal_range: None,
            perspective_correction: true,
            perspective_iterations: 3,
            lambda: 0.6,
            min_corners: 2,
            max_inconsistency: 3.0,
            max_corner_inconsistency: 2.0,
            min_feature_std: 0.2,
            window_margin: 10.0,
            prior_speed: 30.0,
            prior_acceleration: 2.0,
            coast_frames: 3,
        }
    }
}

impl BlueParams {
    /// Check every parameter's range (`Error::Parameter` naming the first bad one).
    pub fn validate(&self) -> Result<()> {
        let bad = |msg: String| Err(Error::Parameter(format!("blue: {msg}")));
        let positive = [
            ("edge_threshold", f64::from(self.edge_threshold)),
            ("angle_tolerance", self.angle_tolerance),
            ("distance_tolerance", self.distance_tolerance),
            ("acquire_distance", self.acquire_distance),
            ("refine_distance", self.refine_distance),
            ("min_point_std", self.min_point_std),
            ("min_corner_angle", self.min_corner_angle),
            ("max_inconsistency", self.max_inconsistency),
            ("max_corner_inconsistency", self.max_corner_inconsistency),
            ("min_feature_std", self.min_feature_std),
            ("prior_speed", self.prior_speed),
            ("prior_acceleration", self.prior_acceleration),
        ];
        for (name, v) in positive {
            if !(v > 0.0 && v.is_finite()) {
                return bad(format!("{name} must be positive and finite, got {v}"));
            }
        }
        for (name, v) in [("end_margin", self.end_margin), ("window_margin", self.window_margin)] {
            if !(v >= 0.0 && v.is_finite()) {
                return bad(format!("{name} must be ≥ 0 and finite, got {v}"));
            }
        }
        if self.angle_tolerance > std::f64::consts::FRAC_PI_2 {
            return bad(format!("angle_tolerance is at most π/2 radians, got {}", self.angle_tolerance));
        }
        if self.min_corner_angle > std::f64::consts::FRAC_PI_2 {
            return bad(format!("min_corner_angle is at most π/2 radians, got {}", self.min_corner_angle));
        }
        if !(self.lambda > 0.0 && self.lambda < 1.0) {
            return bad(format!("lambda must be in (0, 1), got {}", self.lambda));
        }
        if self.max_edge_points == 0 {
            return bad("max_edge_points must be at least 1".into());
        }
        if self.min_points_per_line < 3 {
            return bad(format!("min_points_per_line must be at least 3, got {}", self.min_points_per_line));
        }
        if self.min_corners < 2 {
            return bad(format!("min_corners must be at least 2, got {}", self.min_corners));
        }
        if let Some(z) = self.nominal_range {
            if !(z > 0.0 && z.is_finite()) {
                return bad(format!("nominal_range must be positive and finite, got {z}"));
            }
        }
        Ok(())
    }
}

/// The paper's target location: image position of the tracked point
/// (the model's vertex centroid) and its range (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TargetLocation {
    /// c_x: image column of the centroid, px.
    pub cx: f64,
    /// c_y: image row of the centroid, px.
    pub cy: f64,
    /// c_z: range (camera Z) of the centroid, m.
    pub cz: f64,
}

impl TargetLocation {
    /// 1/c_z, the third unknown of eq. 7–9.
    #[must_use]
    pub fn inverse_range(&self) -> f64 {
        1.0 / self.cz
    }

    fn is_valid(&self) -> bool {
        self.cx.is_finite() && self.cy.is_finite() && self.cz > 0.0 && self.cz.is_finite()
    }
}

/// A prediction of the motion models (6a/6b).
#[derive(Clone, Debug, PartialEq)]
pub struct TargetPrediction {
    /// Predicted (c_x, c_y, c_z).
    pub location: TargetLocation,
    /// Prediction variances of c_x, c_y (px²) and c_z (m²) from the filters'
    /// information (the weights' scale, not the model's adequacy).
    pub variance: [f64; 3],
    /// Predicted image positions of every model vertex.
    pub corners: Vec<[f64; 2]>,
    /// Predicted pose.
    pub pose: Pose,
}

/// Rotation matrix of an axis-angle (Rodrigues) vector, radians.
#[must_use]
pub fn rotation_from_axis_angle(r: [f64; 3]) -> [[f64; 3]; 3] {
    let angle = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    if angle < 1e-300 {
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    }
    let k = [r[0] / angle, r[1] / angle, r[2] / angle];
    let (s, c) = angle.sin_cos();
    let v = 1.0 - c;
    [
        [c + k[0] * k[0] * v, k[0] * k[1] * v - k[2] * s, k[0] * k[2] * v + k[1] * s],
        [k[1] * k[0] * v + k[2] * s, c + k[1] * k[1] * v, k[1] * k[2] * v - k[0] * s],
        [k[2] * k[0] * v - k[1] * s, k[2] * k[1] * v + k[0] * s, c + k[2] * k[2] * v],
    ]
}

fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// A projected visible model line (step 1).
#[derive(Clone, Copy, Debug)]
struct PredictedLine {
    line: Line,
    start: [f64; 2],
    direction: [f64; 2],
    length: f64,
    orientation: f64,
    /// Horizontal representation (y on x) when true (eq. 1 from the prediction).
    horizontal: bool,
}

impl PredictedLine {
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

    fn along(&self, p: [f64; 2]) -> f64 {
        (p[0] - self.start[0]) * self.direction[0] + (p[1] - self.start[1]) * self.direction[1]
    }
}

/// One pass of steps 2–6 around a model location.
#[derive(Clone, Debug)]
struct Pass {
    location: TargetLocation,
    covariance: [[f64; 3]; 3],
    rms_consistency: f64,
    points_per_line: Vec<usize>,
    line_fitted: Vec<bool>,
    corner_measured: Vec<bool>,
    max_corner_deviation: Option<f64>,
    unexplained: usize,
    labelled: Vec<Vec<(u32, u32)>>,
    /// Whether eq. 9 gave a valid estimate (possibly failing consistency).
    estimated: bool,
    failure: Option<String>,
}

/// The blue tracker (module doc).
#[derive(Clone, Debug)]
pub struct BlueTracker {
    params: BlueParams,
    camera: Camera,
    rotation_vector: [f64; 3],
    rotation: [[f64; 3]; 3],
    /// Vertex centroid in the object frame.
    centroid: [f64; 3],
    /// q_i = R·(P_i − c), camera-frame offsets of the vertices.
    offsets: Vec<[f64; 3]>,
    edges: Vec<[usize; 2]>,
    /// Per face: camera-frame normal (R·n) and offset of one vertex (q).
    faces: Vec<([f64; 3], [f64; 3])>,
    /// Per edge: the faces it borders.
    edge_faces: Vec<Vec<usize>>,
    /// Per vertex: its edges.
    vertex_edges: Vec<Vec<usize>>,
    nominal_range: f64,
    /// Image displacement per metre of range (scales the c_z priors).
    range_px_per_m: f64,
    filters: [PolynomialSrif<3>; 3],
    phase: Phase,
    next_frame: usize,
    /// Last frame processed (the time predictions are relative to).
    last_frame: Option<usize>,
    /// Location of the last tracked frame (the init one before).
    last_tracked: TargetLocation,
    /// Consecutive lost frames.
    lost_run: usize,
}

impl BlueTracker {
    /// A tracker for `model` seen by `camera`, starting at `init.pose`
    /// (required; its rotation stays fixed).
    pub fn new(camera: Camera, model: Model, init: InitState, params: BlueParams) -> Result<Self> {
        params.validate()?;
        let bad = |msg: String| Err(Error::Parameter(format!("blue: {msg}")));
        let intrinsics = [camera.fx, camera.fy, camera.cx, camera.cy];
        if !(intrinsics.iter().all(|v| v.is_finite()) && camera.fx > 0.0 && camera.fy > 0.0) {
            return bad(format!("camera intrinsics must be finite with fx, fy > 0, got {intrinsics:?}"));
        }
        let Some(pose) = init.pose else {
            return bad("init.json has no pose; the blue tracker needs the initial pose".into());
        };
        if model.vertices.is_empty() || model.edges.is_empty() {
            return bad("the model needs vertices and edges".into());
        }
        if !model.vertices.iter().flatten().chain(&pose.rotation).chain(&pose.translation).all(|v| v.is_finite()) {
            return bad("model vertices and init pose must be finite".into());
        }
        let nv = model.vertices.len();
        let mut vertex_edges = vec![Vec::new(); nv];
        for (k, &[i, j]) in model.edges.iter().enumerate() {
            if i >= nv || j >= nv || i == j {
                return bad(format!("edge {k} [{i}, {j}] is not a pair of distinct vertices of the {nv}"));
            }
            vertex_edges[i].push(k);
            vertex_edges[j].push(k);
        }
        let rotation = rotation_from_axis_angle(pose.rotation);
        let inv_n = 1.0 / nv as f64;
        let centroid: [f64; 3] = std::array::from_fn(|a| model.vertices.iter().map(|v| v[a]).sum::<f64>() * inv_n);
        let offsets: Vec<[f64; 3]> = model
            .vertices
            .iter()
            .map(|p| mat_vec(&rotation, [p[0] - centroid[0], p[1] - centroid[1], p[2] - centroid[2]]))
            .collect();
        let mut faces = Vec::with_capacity(model.faces.len());
        let mut edge_faces = vec![Vec::new(); model.edges.len()];
        for (f, face) in model.faces.iter().enumerate() {
            if face.len() < 3 || face.iter().any(|&i| i >= nv) {
                return bad(format!("face {f} needs at least 3 vertices of the {nv}"));
            }
            // Newell's normal, counter-clockwise seen from outside → outward.
            let mut n = [0.0; 3];
            for (a, &i) in face.iter().enumerate() {
                let (p, q) = (model.vertices[i], model.vertices[face[(a + 1) % face.len()]]);
                n[0] += (p[1] - q[1]) * (p[2] + q[2]);
                n[1] += (p[2] - q[2]) * (p[0] + q[0]);
                n[2] += (p[0] - q[0]) * (p[1] + q[1]);
            }
            faces.push((mat_vec(&rotation, n), offsets[face[0]]));
            for (a, &i) in face.iter().enumerate() {
                let j = face[(a + 1) % face.len()];
                for (k, &[ei, ej]) in model.edges.iter().enumerate() {
                    if (ei, ej) == (i, j) || (ei, ej) == (j, i) {
                        edge_faces[k].push(f);
                    }
                }
            }
        }
        let origin = mat_vec(&rotation, centroid);
        let reference: [f64; 3] = std::array::from_fn(|a| origin[a] + pose.translation[a]);
        if !(reference[2] > 0.0) {
            return bad(format!("the init pose puts the model's centroid behind the camera (Z = {})", reference[2]));
        }
        let init_location = TargetLocation {
            cx: camera.fx * reference[0] / reference[2] + camera.cx,
            cy: camera.fy * reference[1] / reference[2] + camera.cy,
            cz: reference[2],
        };
        let nominal_range = params.nominal_range.unwrap_or(reference[2]);
        // Image displacement per metre of range change for the model's extent.
        let extent = offsets.iter().map(|q| q[0].hypot(q[1])).fold(0.0, f64::max).max(1e-9);
        let range_px_per_m = camera.fx.max(camera.fy) * extent / (reference[2] * reference[2]);
        let filters = start_filters(&params, &init_location, 0.0, range_px_per_m)?;
        Ok(Self {
            params,
            camera,
            rotation_vector: pose.rotation,
            rotation,
            centroid,
            offsets,
            edges: model.edges,
            faces,
            edge_faces,
            vertex_edges,
            nominal_range,
            range_px_per_m,
            filters,
            phase: Phase::Acquiring,
            next_frame: 0,
            last_frame: None,
            last_tracked: init_location,
            lost_run: 0,
        })
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &BlueParams {
        &self.params
    }

    /// The current phase.
    #[must_use]
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Nominal range Z₀ of eq. 7, m.
    #[must_use]
    pub fn nominal_range(&self) -> f64 {
        self.nominal_range
    }

    /// p_x, p_y of eq. 7–8: f_x·Z₀ and f_y·Z₀ (module doc).
    #[must_use]
    pub fn eq7_scales(&self) -> [f64; 2] {
        [self.camera.fx * self.nominal_range, self.camera.fy * self.nominal_range]
    }

    /// The motion models' prediction `dt_frames` frames after the last
    /// processed frame (eq. 15 for dt = 1; fractional dt for the servo cycle,
    /// 6b). Before any frame, relative to frame 0 − 1, i.e. dt = 1 is frame 0.
    #[must_use]
    pub fn predict_ahead(&self, dt_frames: f64) -> TargetPrediction {
        let time = self.last_frame.map_or(dt_frames - 1.0, |f| f as f64 + dt_frames);
        let location = self.location_at(time);
        let variance: [f64; 3] = std::array::from_fn(|k| {
            let f = &self.filters[k];
            f.prediction_variance(time - f.time()).unwrap_or(f64::INFINITY)
        });
        TargetPrediction { location, variance, corners: self.vertices_at(&location), pose: self.pose_at(&location) }
    }

    /// The motion models' location at (frame) time `time`.
    fn location_at(&self, time: f64) -> TargetLocation {
        let value = |k: usize| {
            let f = &self.filters[k];
            f.predict(time - f.time()).unwrap_or(f64::NAN)
        };
        TargetLocation { cx: value(0), cy: value(1), cz: value(2) }
    }

    /// Centroid in the camera frame for `location`.
    fn reference_point(&self, location: &TargetLocation) -> [f64; 3] {
        let c = &self.camera;
        [(location.cx - c.cx) * location.cz / c.fx, (location.cy - c.cy) * location.cz / c.fy, location.cz]
    }

    /// Image positions of every model vertex at `location` (model-vertex
    /// order; NaN for a vertex not in front of the camera).
    #[must_use]
    pub fn vertices_at(&self, location: &TargetLocation) -> Vec<[f64; 2]> {
        let x = self.reference_point(location);
        let c = &self.camera;
        self.offsets
            .iter()
            .map(|q| {
                let z = x[2] + q[2];
                if z > 0.0 {
                    [c.fx * (x[0] + q[0]) / z + c.cx, c.fy * (x[1] + q[1]) / z + c.cy]
                } else {
                    [f64::NAN, f64::NAN]
                }
            })
            .collect()
    }

    /// The pose at `location`: init rotation, translation t = X − R·c.
    #[must_use]
    pub fn pose_at(&self, location: &TargetLocation) -> Pose {
        let x = self.reference_point(location);
        let rc = mat_vec(&self.rotation, self.centroid);
        Pose { rotation: self.rotation_vector, translation: std::array::from_fn(|a| x[a] - rc[a]) }
    }

    /// Whether each model edge is visible at `location` (borders a face
    /// facing the camera; edges bordering no face always are).
    #[must_use]
    pub fn visible_edges(&self, location: &TargetLocation) -> Vec<bool> {
        let x = self.reference_point(location);
        let facing: Vec<bool> = self
            .faces
            .iter()
            .map(|(n, q)| {
                let p = [x[0] + q[0], x[1] + q[1], x[2] + q[2]];
                n[0] * p[0] + n[1] * p[1] + n[2] * p[2] < 0.0
            })
            .collect();
        self.edge_faces.iter().map(|fs| fs.is_empty() || fs.iter().any(|&f| facing[f])).collect()
    }

    /// Association distance of the next frame.
    fn association_distance(&self) -> f64 {
        if self.phase == Phase::Tracking && self.filters[0].samples() >= 3 {
            self.params.distance_tolerance
        } else {
            self.params.acquire_distance
        }
    }

    /// The window holding the next frame's edges: the bounding box of the
    /// predicted vertices grown by the association distance plus
    /// `window_margin`, clipped to the image.
    #[must_use]
    pub fn window_of_interest(&self, width: usize, height: usize) -> Window {
        let location = self.location_at(self.next_frame as f64);
        let margin = self.association_distance() + self.params.window_margin;
        let (mut x0, mut y0, mut x1, mut y1) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
        for p in self.vertices_at(&location) {
            x0 = x0.min(p[0]);
            y0 = y0.min(p[1]);
            x1 = x1.max(p[0]);
            y1 = y1.max(p[1]);
        }
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            return Window::full(width, height);
        }
        let lo = |v: f64| (v - margin).floor().max(0.0) as u32;
        let hi = |v: f64| ((v + margin).ceil() + 1.0).clamp(0.0, f64::from(u32::MAX)) as u32;
        Window { x0: lo(x0), y0: lo(y0), x1: hi(x1), y1: hi(y1) }.clipped(width, height)
    }

    /// Process frame `frame` given its edge pixels; every call returns an
    /// outcome (also when lost). Frames must come in increasing order.
    pub fn update(&mut self, frame: usize, edges: &[Feature]) -> FrameOutcome {
        let time = frame as f64;
        let mut predicted = self.location_at(time);
        if !predicted.is_valid() {
            // Extrapolated behind the camera (or not finite): search where
            // the target was last seen.
            predicted = self.last_tracked;
            if let Ok(filters) = start_filters(&self.params, &predicted, time, self.range_px_per_m) {
                self.filters = filters;
            }
        }
        let distance = self.association_distance();
        let mut pass = if predicted.is_valid() {
            // Step 1: coarse alignment, then the narrow first association.
            let aligned = if self.params.align {
                self.align_shift(edges, &predicted, distance).map(|[sx, sy]| TargetLocation {
                    cx: predicted.cx + sx,
                    cy: predicted.cy + sy,
                    cz: predicted.cz,
                })
            } else {
                None
            };
            match aligned {
                Some(model) => self.measure(edges, &model, &predicted, self.params.refine_distance),
                None => self.measure(edges, &predicted, &predicted, distance),
            }
        } else {
            self.failed_pass(&predicted, "the prediction is not in front of the camera".into())
        };
        // Re-association (step 7) after any pass with an estimate, also one
        // that failed the consistency check (the wide strips' clutter is
        // what the narrow ones drop).
        for _ in 0..self.params.refine_passes {
            if !pass.estimated {
                break;
            }
            let refined = self.measure(edges, &pass.location, &predicted, self.params.refine_distance);
            if !refined.estimated {
                break;
            }
            pass = refined;
        }
        self.next_frame = frame + 1;
        self.last_frame = Some(frame);
        let tracked = pass.failure.is_none();
        let (location, covariance) = if tracked {
            let c = pass.covariance;
            let rho = pass.location.inverse_range();
            // Var(c_z) = Var(1/c_z)·c_z⁴ (delta method).
            let variances = [c[0][0], c[1][1], c[2][2] / rho.powi(4)];
            let values = [pass.location.cx, pass.location.cy, pass.location.cz];
            for ((filter, &v), &var) in self.filters.iter_mut().zip(&values).zip(&variances) {
                filter.update(time, v, var);
            }
            self.phase = Phase::Tracking;
            self.last_tracked = pass.location;
            self.lost_run = 0;
            (pass.location, c.iter().flatten().copied().collect::<Vec<f64>>())
        } else {
            for filter in &mut self.filters {
                filter.advance_to(time);
            }
            self.phase = Phase::Lost;
            self.lost_run += 1;
            if self.lost_run >= self.params.coast_frames {
                // Stop extrapolating: search where the target was last seen.
                if let Ok(filters) = start_filters(&self.params, &self.last_tracked, time, self.range_px_per_m) {
                    self.filters = filters;
                }
            }
            let var: [f64; 3] =
                std::array::from_fn(|k| self.filters[k].prediction_variance(0.0).unwrap_or(f64::INFINITY));
            let rho = predicted.inverse_range();
            let cov = vec![var[0], 0.0, 0.0, 0.0, var[1], 0.0, 0.0, 0.0, var[2] * rho.powi(4)];
            (predicted, cov)
        };
        FrameOutcome {
            frame,
            status: if tracked { Status::Tracking } else { Status::Lost },
            phase: self.phase,
            corners: self.vertices_at(&location),
            pose: Some(self.pose_at(&location)),
            params: None,
            covariance: Some(covariance),
            labelled: pass.labelled,
            diagnostics: Diagnostics {
                points_per_line: pass.points_per_line,
                line_fitted: pass.line_fitted,
                corner_measured: pass.corner_measured,
                max_corner_deviation: pass.max_corner_deviation,
                unexplained_points: pass.unexplained,
                lost_reason: pass.failure,
            },
        }
    }

    fn failed_pass(&self, location: &TargetLocation, reason: String) -> Pass {
        let (ne, nv) = (self.edges.len(), self.offsets.len());
        Pass {
            location: *location,
            covariance: [[0.0; 3]; 3],
            rms_consistency: f64::NAN,
            points_per_line: vec![0; ne],
            line_fitted: vec![false; ne],
            corner_measured: vec![false; nv],
            max_corner_deviation: None,
            unexplained: 0,
            labelled: vec![Vec::new(); ne],
            estimated: false,
            failure: Some(reason),
        }
    }

    /// The visible model lines projected at `location` (step 1).
    fn predicted_lines(&self, location: &TargetLocation) -> Vec<Option<PredictedLine>> {
        let vertices = self.vertices_at(location);
        let visible = self.visible_edges(location);
        self.edges
            .iter()
            .zip(&visible)
            .map(|(&[i, j], &v)| if v { PredictedLine::between(vertices[i], vertices[j]) } else { None })
            .collect()
    }

    /// Coarse alignment of step 1 (extension, [`BlueParams::align`]): the image shift (s_x, s_y),
    /// |s_x|, |s_y| ≤ `radius`, of the model projected at `model` that the
    /// edge pixels support best. Every pixel votes, for each visible line of
    /// compatible orientation, for the shifts that put it on that line
    /// (foot inside the segment less the end margins): a line n·s = d in the
    /// 1-px shift grid. The peak of the 3×3-summed votes is where many lines
    /// of different orientations agree; a background edge supports only
    /// shifts along one direction. `None` when no pixel votes.
    fn align_shift(&self, edges: &[Feature], model: &TargetLocation, radius: f64) -> Option<[f64; 2]> {
        let p = &self.params;
        let lines: Vec<PredictedLine> = self.predicted_lines(model).into_iter().flatten().collect();
        if lines.is_empty() || !(radius >= 0.0) {
            return None;
        }
        let r = radius.ceil() as i64;
        let n = (2 * r + 1) as usize;
        let mut votes = vec![0u32; n * n];
        for feature in edges {
            if !(feature.magnitude >= p.edge_threshold) || !feature.theta.is_finite() {
                continue;
            }
            let point = [f64::from(feature.x), f64::from(feature.y)];
            let orientation = wrap_orientation(f64::from(feature.theta) + std::f64::consts::FRAC_PI_2);
            for line in &lines {
                if orientation_difference(orientation, line.orientation) >= p.angle_tolerance {
                    continue;
                }
                let d = line.line.signed_distance(point);
                if d.abs() > radius * std::f64::consts::SQRT_2 + 1.0 {
                    continue;
                }
                let s = line.along(point);
                let (a, b) = (line.line.a, line.line.b);
                let [ux, uy] = line.direction;
                let mut vote = |ix: i64, iy: i64| {
                    if ix.abs() > r || iy.abs() > r {
                        return;
                    }
                    // The foot of the pixel on the shifted segment.
                    let along = s - (ux * ix as f64 + uy * iy as f64);
                    if along >= p.end_margin && along <= line.length - p.end_margin {
                        votes[(iy + r) as usize * n + (ix + r) as usize] += 1;
                    }
                };
                // Shifted line: a·(x − s_x) + b·(y − s_y) + c = 0 ⇔ a·s_x + b·s_y = d.
                if a.abs() >= b.abs() {
                    for iy in -r..=r {
                        let sx = (d - b * iy as f64) / a;
                        vote(sx.round() as i64, iy);
                    }
                } else {
                    for ix in -r..=r {
                        let sy = (d - a * ix as f64) / b;
                        vote(ix, sy.round() as i64);
                    }
                }
            }
        }
        let mut best: Option<(u32, i64, i64)> = None;
        for iy in -r..=r {
            for ix in -r..=r {
                let mut sum = 0;
                for jy in (iy - 1).max(-r)..=(iy + 1).min(r) {
                    for jx in (ix - 1).max(-r)..=(ix + 1).min(r) {
                        sum += votes[(jy + r) as usize * n + (jx + r) as usize];
                    }
                }
                // Ties go to the smaller shift (the prediction is a prior).
                let closer = |bx: i64, by: i64| ix * ix + iy * iy < bx * bx + by * by;
                if sum > 0 && best.is_none_or(|(bs, bx, by)| sum > bs || (sum == bs && closer(bx, by))) {
                    best = Some((sum, ix, iy));
                }
            }
        }
        best.map(|(_, ix, iy)| [ix as f64, iy as f64])
    }

    /// Steps 2–6 with the model at `model` and association distance
    /// `distance`; `predicted` is only used for the corner deviation.
    fn measure(&self, edges: &[Feature], model: &TargetLocation, predicted: &TargetLocation, distance: f64) -> Pass {
        let p = &self.params;
        let vertices = self.vertices_at(model);
        let lines = self.predicted_lines(model);
        // Step 2: data association (§2.4).
        let mut sums: Vec<LineSums> =
            lines.iter().map(|l| l.map_or_else(LineSums::new, |l| LineSums::with_origin(l.start))).collect();
        let mut labelled = vec![Vec::new(); lines.len()];
        let mut unexplained = 0;
        for feature in edges {
            if !(feature.magnitude >= p.edge_threshold) || !feature.theta.is_finite() {
                continue;
            }
            let point = [f64::from(feature.x), f64::from(feature.y)];
            // The edge runs perpendicular to the gradient.
            let orientation = wrap_orientation(f64::from(feature.theta) + std::f64::consts::FRAC_PI_2);
            let mut best: Option<(usize, f64)> = None;
            let mut compatible = false;
            for (k, line) in lines.iter().enumerate() {
                let Some(line) = line else { continue };
                if orientation_difference(orientation, line.orientation) >= p.angle_tolerance {
                    continue;
                }
                compatible = true;
                let d = line.line.distance(point);
                let s = line.along(point);
                if d < distance
                    && s >= p.end_margin
                    && s <= line.length - p.end_margin
                    && best.is_none_or(|(_, bd)| d < bd)
                {
                    best = Some((k, d));
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
        // Step 3: feature measurement (eq. 1–4), form from the prediction.
        let min_var = p.min_point_std * p.min_point_std;
        let fitted: Vec<Option<LineLocation>> = sums
            .iter()
            .zip(&lines)
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
            .collect();
        // Step 4: corners (eq. 5–6), one per vertex, best-conditioned pair.
        let min_sine = p.min_corner_angle.sin();
        let mut corners: Vec<(usize, crate::estimate::Corner)> = Vec::new(); // (vertex, corner)
        let mut corner_measured = vec![false; vertices.len()];
        let predicted_vertices = self.vertices_at(predicted);
        let mut max_deviation: Option<f64> = None;
        for (v, incident) in self.vertex_edges.iter().enumerate() {
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
            corner_measured[v] = true;
            let pv = predicted_vertices[v];
            let dev = (corner.position[0] - pv[0]).hypot(corner.position[1] - pv[1]);
            max_deviation = Some(max_deviation.map_or(dev, |m: f64| m.max(dev)));
            corners.push((v, corner));
        }
        let mut pass = Pass {
            location: *model,
            covariance: [[0.0; 3]; 3],
            rms_consistency: f64::NAN,
            points_per_line: sums.iter().map(LineSums::count).collect(),
            line_fitted: fitted.iter().map(Option::is_some).collect(),
            corner_measured,
            max_corner_deviation: max_deviation,
            unexplained,
            labelled,
            estimated: false,
            failure: None,
        };
        if corners.len() < p.min_corners {
            pass.failure =
                Some(format!("{} corners measured, fewer than min_corners = {}", corners.len(), p.min_corners));
            return pass;
        }
        // Steps 5–6: BLUE (eq. 7–9) and its confidence (eq. 10–12), then
        // the corner least consistent with it (largest |e_j|, eq. 11) dropped
        // while it exceeds `max_corner_inconsistency` and redundancy remains.
        let (mut estimate, mut solution) = match self.solve_blue(&corners, model) {
            Ok(found) => found,
            Err(reason) => {
                pass.failure = Some(reason);
                return pass;
            }
        };
        while corners.len() > p.min_corners.max(2) {
            let Some((worst, e)) = solution
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
            pass.corner_measured[v] = false;
            match self.solve_blue(&corners, &estimate) {
                Ok(found) => (estimate, solution) = found,
                Err(reason) => {
                    pass.failure = Some(reason);
                    return pass;
                }
            }
        }
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

    /// Eq. 9 for `corners` (vertex, corner), iterated for the perspective
    /// term from `start` (module doc); the estimate and eq. 9–12's solution.
    fn solve_blue(
        &self,
        corners: &[(usize, crate::estimate::Corner)],
        start: &TargetLocation,
    ) -> std::result::Result<(TargetLocation, crate::estimate::BlueSolution<3>), String> {
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
            for (v, corner) in corners {
                let q = self.offsets[*v];
                let (ux, uy) = if p.perspective_correction {
                    let u = projected[*v];
                    ((q[0] - q[2] * (u[0] - u0) / fx) / z0, (q[1] - q[2] * (u[1] - v0) / fy) / z0)
                } else {
                    (q[0] / z0, q[1] / z0)
                };
                // Eq. 8: rows [1, 0, p_x·u_x], [0, 1, p_y·u_y] for x_f = (c_x, c_y, 1/c_z).
                problem.add([[1.0, 0.0, px * ux], [0.0, 1.0, py * uy]], corner.position, corner.covariance);
            }
            let floor = p.min_feature_std * p.min_feature_std;
            let s = problem.solve(floor).ok_or_else(|| "eq. 9 is singular for the measured corners".to_string())?;
            estimate = TargetLocation { cx: s.estimate[0], cy: s.estimate[1], cz: 1.0 / s.estimate[2] };
            if !estimate.is_valid() {
                return Err(format!("the estimate puts the target behind the camera (1/c_z = {})", s.estimate[2]));
            }
            solution = Some(s);
        }
        solution.map(|s| (estimate, s)).ok_or_else(|| "no estimate".to_string())
    }
}

/// Fresh motion models at `location` at time `time`: the location with
/// standard deviation [`INIT_PRIOR_PX`], velocity and acceleration zero with
/// the params' prior deviations (px converted to m for c_z).
fn start_filters(
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

/// Prior standard deviation of the init location at the start, px.
const INIT_PRIOR_PX: f64 = 2.0;
/// Slack of the corner gate beyond d/sin(angle), px.
const CORNER_GATE_SLACK_PX: f64 = 2.0;

impl Tracker for BlueTracker {
    fn name(&self) -> &'static str {
        "blue"
    }

    fn window_of_interest(&self, width: usize, height: usize) -> Window {
        BlueTracker::window_of_interest(self, width, height)
    }

    /// §2.3: Sobel on the raw frame, magnitude above `edge_threshold`, inside
    /// the window of interest, at most `max_edge_points` by the seeded subsample.
    fn request(&self, width: usize, height: usize) -> FrameRequest {
        let cap = u32::try_from(self.params.max_edge_points).unwrap_or(u32::MAX).min(MAX_CAP);
        FrameRequest {
            edges: Some(EdgeRequest {
                threshold: self.params.edge_threshold,
                smoothed: false,
                list: ListSpec {
                    window: BlueTracker::window_of_interest(self, width, height),
                    cap: Some(cap),
                    // Fold the 64-bit seed into the compaction's 32 bits.
                    seed: (self.params.sample_seed ^ (self.params.sample_seed >> 32)) as u32,
                },
            }),
            ..FrameRequest::default()
        }
    }

    fn track(&mut self, frame: usize, observations: &Observations<'_>) -> FrameOutcome {
        self.update(frame, observations.edges.unwrap_or(&[]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rodrigues_quarter_turn_about_z() {
        let r = rotation_from_axis_angle([0.0, 0.0, std::f64::consts::FRAC_PI_2]);
        let x = mat_vec(&r, [1.0, 0.0, 0.0]);
        assert!(x[0].abs() < 1e-12 && (x[1] - 1.0).abs() < 1e-12 && x[2].abs() < 1e-12, "{x:?}");
    }

    #[test]
    fn params_validate() {
        assert!(BlueParams::default().validate().is_ok());
        let bad = BlueParams { lambda: 1.0, ..BlueParams::default() };
        assert!(bad.validate().is_err());
        let bad = BlueParams { min_corners: 1, ..BlueParams::default() };
        assert!(bad.validate().is_err());
        let parsed: BlueParams = toml::from_str("lambda = 0.7\nrefine_passes = 0").expect("toml");
        assert_eq!(parsed.lambda, 0.7);
        assert_eq!(parsed.max_edge_points, 1500);
        assert!(toml::from_str::<BlueParams>("lamda = 0.7").is_err(), "unknown keys refused");
    }
}
