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
//! singular, when the estimate is not in front of the camera or puts a
//! model vertex where it cannot be projected (at or behind the camera, or
//! so close to Z = 0 that its pixel overflows), when the
//! global consistency fails badly: RMS of e (eq. 11) above
//! [`BlueParams::max_inconsistency`] px, or when the frame before was
//! tracked and the estimated range differs from its range by more than a
//! factor 1.3 either way (no target changes its range by 30 % in a frame;
//! a fit that does has matched something else, e.g. clutter next to a
//! target that turned round). A lost frame feeds nothing to the
//! motion models (their information decays, the polynomials extrapolate),
//! reports the predicted vertices and pose with status `lost`, and the next
//! frames re-acquire with the wide distance around the prediction. After
//! [`BlueParams::coast_frames`] lost frames in a row (or when the
//! extrapolation leaves the space in front of the camera) the models restart
//! at the last tracked location at rest: a parabola extrapolated for long
//! runs away from where the target was.
//!
//! **Verification** (extension, [`BlueParams::verify`]; off: the paper's
//! method). An estimate that passed the checks above is reported `tracking`
//! only if its visible outline stands out on the frame's edge pixels: the
//! fraction of its 1-px samples with an edge pixel within
//! [`BlueParams::support_distance`] across it at the line's orientation
//! (± the angle tolerance) ([`crate::track::support`]), less the same
//! fraction for the outline shifted ±(2·d + 1) px across itself (the
//! support any outline gets from the edge density there, which the random
//! subsample of the edge list scales alike), must reach
//! [`BlueParams::min_support`]. Otherwise the frame is lost as above.
//! After a tracked frame the estimate is also set against the prediction
//! it was measured from, on the same frame's edges: when the prediction's
//! outline stands out more than the estimate's by more than
//! [`BlueParams::max_excess_below_prediction`], the fit moved the model off
//! where the target showed and the frame is lost (target3dof shaken at
//! 1.2 rad/s, seed 38, frame 257: the prediction within 1 px of the target
//! stood out by 0.63, the estimate, fitted at 0.86 times the range with 5
//! corners, by 0.36 and 5.3 px off). Both outlines meet the same occluder
//! and the same subsample, so the comparison holds when part of the target
//! is hidden.
//! After [`BlueParams::search_after`] lost frames in a row the target is
//! searched over the whole image: the window of interest opens to the full
//! frame (its edge cap grown with its area, so the edge density stays that
//! of a tracking window), and the coarse alignment's vote runs over every
//! image shift that keeps the centroid in the image, on a 4-px grid, at
//! three ranges: the last tracked one and, in turn from one searching frame
//! to the next, one step of 1.1× nearer and farther, the steps reaching
//! 1.25× the last range at first and 1 % more per frame lost (a target may
//! have moved farther in depth the longer it was unseen), at most 2×. The
//! best vote peaks are aligned again on the 1-px grid; the places whose
//! contour stands out most (the verification's excess) are measured in
//! full (steps 1–7), and the measured estimate that passes and stands out
//! most is where the frame is measured. Such a frame must pass the
//! verification with the higher [`BlueParams::search_min_support`] (the
//! search picks the best of many places), keep its estimated range within
//! 1.3 times the searched one, and fit at least
//! [`BlueParams::search_min_fitted`] of the visible model lines: on the
//! bookshelf a wrong place that stands out like the target fits 5–10 of
//! the 39 visible lines, the target 13–21. A searching frame costs about a
//! hundred tracking frames on the CPU (0.2–0.4 s at 640×480).
//!
//! **Abrupt reversals** (extension, [`BlueParams::reversal_hypotheses`]).
//! A target shaken back and forth turns round within a frame: the
//! 2nd-order polynomial of eq. 13 cannot predict that whatever λ (eq. 14 is
//! a fit to the past; a smaller λ only forgets the old motion sooner), so
//! the frame after a reversal lies about twice a frame's displacement from
//! the prediction (40 px at 20 px/frame), beyond the association distance,
//! and the prediction variance of eq. 15 does not grow there (it reflects
//! the measurements' weights, not the model's adequacy). After a tracked
//! frame at which the motion models' image velocity is at least half
//! [`BlueParams::distance_tolerance`] per frame (so a reversal, 2 frames'
//! displacement, leaves the association window; a slower target's stays
//! inside it), the frame is also measured (steps 1–7) around two more
//! hypotheses: the last tracked location moved back by the motion models'
//! velocity v (turned back) and the last tracked location (stopped), the
//! first association within |v| (clamped to `distance_tolerance` ..=
//! [`BlueParams::acquire_distance`]): a target that turned round by
//! 180° ± 50° lies within 0.85·|v| of the first, one that stopped or turned
//! within the frame within |v| of the second.
//! Of the estimates that pass every check, the one whose outline stands out
//! most (the verification's excess) is kept; a hypothesis's estimate
//! replaces one around the prediction that passed only when it lies farther
//! than [`BlueParams::refine_distance`] from it (elsewhere: the same target
//! found twice is kept as the prediction found it) and its excess is larger
//! by `REVERSAL_MARGIN` (0.05). When the kept estimate, the prediction's
//! own or a hypothesis's, lies farther than `distance_tolerance` from the
//! prediction after a tracked frame, the motion models restart from the
//! last tracked frame at rest before taking it, so the next prediction does
//! not carry the motion before the reversal: the association distance
//! bounds the prediction error of eq. 15 on the motion eq. 13 models (see
//! [`BlueParams::lambda`]), so an estimate beyond it means that motion
//! changed, and eq. 14 would still weigh the samples before the change by
//! λ, λ², …. This holds also for a target found by the coarse alignment
//! around the prediction itself (within its reach): target3dof shaken at
//! 0.6 rad/s, seed 32, turns at frame 259 from 10 px/frame to 10 px/frame
//! back; frame 260 found it 20 px from the prediction, the models, fed it,
//! still moved 5.7 px/frame forward, the next prediction lay 24 px off,
//! beyond the alignment's reach, and three frames fitted the model one face
//! to the right of the target.
//!
//! The window of interest surrounds the prediction, so a turned-back
//! target, two frames' displacement away, may lie partly outside it, where
//! no edge pixel was listed: its outline's samples there count as
//! unsupported. When a hypothesis's estimate, elsewhere than the estimate
//! kept so far, passed every check but did not win, or failed the
//! verification alone, by less than the fraction of its outline whose
//! verification reads pixels outside the window (the most that part could
//! add), the frame is looked at a second time
//! ([`Tracker::track_or_widen`]) in the window grown to hold that
//! hypothesis's outline and the outline shifted beside it, its edge cap
//! grown with its area so the density of the subsample stays the same.
//! The first look's estimate around the prediction is kept and judged
//! again on the second look's edges, the hypotheses are measured and
//! judged again from them, and the choice between them is made as above
//! (target3dof shaken at 1.2 rad/s, seed 31, frame 247: the prediction's
//! fit on the bookshelf stood out by 0.270, the turned-back hypothesis on
//! the target by 0.315 with half its outline outside the window, and
//! frames 247–248 were reported tracking off the target; with the second
//! look both are on it). A second look does not widen again.
//! Through [`BlueTracker::update`] there is no second look.
//!
//! Reported per frame: the projection of every model vertex (model-vertex
//! order, hidden ones too) at the frame's BLUE (the prediction when lost),
//! the pose, and as covariance C_l of (c_x, c_y, 1/c_z) row-major (eq. 12; when
//! lost, the motion models' prediction variances on the diagonal).
//! Every reported number is finite (SPEC §4). A tracked frame projects
//! every vertex (see above); on a lost frame a vertex that cannot be
//! projected at the prediction is reported at its last reported position
//! (at the init image of the centroid, c_x, c_y, if it never had one), and
//! the lost reason says so. A covariance that is not finite (a motion model
//! without a prediction variance) is left out.
//!
//! # Layout
//! [`params`]: the parameters and their ranges; `steps.rs`: steps 1–8 above,
//! one function each, in order; this file: the tracker's state between
//! frames (motion models, phase, lost run) and the per-frame state machine
//! [`BlueTracker::update`]. Camera, pose and visibility come from
//! [`crate::geometry`].

// `!(x > 0.0)` rejects NaN on purpose.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod params;
mod steps;

use glam::{DMat3, DVec3};

pub use params::BlueParams;
use steps::{Pass, start_filters};

use super::{Diagnostics, FrameOutcome, Observations, Phase, Tracked, Tracker};
use crate::backend::{EdgeRequest, FrameRequest, ListSpec};
use crate::early::compaction::MAX_CAP;
use crate::early::{Feature, Window};
use crate::estimate::PolynomialSrif;
use crate::estimate::line_fit::wrap_orientation;
use crate::geometry::{self, Camera, ModelGeometry};
use crate::io::formats::{InitState, Model, Pose, Status};
use crate::track::support::{self, EdgeMap};
use crate::{Error, Result};
use std::f64::consts::FRAC_PI_2;

/// Shift grid of the whole-image search of a lost target, px: the vote's
/// 3×3 sum gathers lines within ±1.5 steps; each peak is then aligned on
/// the 1-px grid within ±1 step.
const SEARCH_STEP_PX: f64 = 4.0;
/// Vote peaks the whole-image search compares by their contour support.
const SEARCH_PEAKS: usize = 8;
/// Ranges the whole-image search tries: the last tracked range times
/// `SEARCH_RANGE_RATIO^k` for every k whose ratio lies within the reach
/// (module doc): `SEARCH_RANGE_REACH` times `SEARCH_RANGE_GROWTH` per frame
/// lost, at most `SEARCH_RANGE_MAX_REACH`, either way.
const SEARCH_RANGE_RATIO: f64 = 1.1;
const SEARCH_RANGE_REACH: f64 = 1.25;
const SEARCH_RANGE_GROWTH: f64 = 1.01;
const SEARCH_RANGE_MAX_REACH: f64 = 2.0;
/// Largest ratio between a searched frame's estimated range and the range
/// searched, either way; also between a frame's estimated range and that of
/// the tracked frame just before it.
const SEARCH_RANGE_TOLERANCE: f64 = 1.3;
/// Excess of contour support by which a reversal hypothesis must beat an
/// estimate around the prediction that passed its checks (module doc,
/// "Abrupt reversals"): the two often find the same target, and the
/// prediction's keeps the motion models' continuity.
const REVERSAL_MARGIN: f64 = 0.05;
/// Least distance between two of those peaks, grid steps.
const SEARCH_SEPARATION: i64 = 3;
/// Places of the whole-image search (of every range) measured in full.
const SEARCH_MEASURED: usize = 6;

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

/// The blue tracker (module doc).
#[derive(Clone, Debug)]
pub struct BlueTracker {
    params: BlueParams,
    camera: Camera,
    /// The init pose's rotation vector, reported unchanged in every pose.
    rotation_vector: [f64; 3],
    /// Its rotation R (fixed).
    rotation: DMat3,
    /// Vertex centroid c in the object frame.
    centroid: DVec3,
    /// q_i = R·(P_i − c), camera-frame offsets of the vertices.
    offsets: Vec<DVec3>,
    /// Edges, faces and their incidences.
    geometry: ModelGeometry,
    /// Per face: camera-frame outward normal R·n and the offset q of one of
    /// its vertices (the face's plane relative to the centroid).
    faces: Vec<(DVec3, DVec3)>,
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
    /// Per vertex, its last reported image position (finite; module doc,
    /// "Start, loss and output").
    last_corners: Vec<[f64; 2]>,
    /// The window of the current frame's second look, when its first look
    /// widened it (module doc, "Abrupt reversals"); `None` otherwise.
    second_look: Option<Window>,
    /// The frame of the first look and its estimate around the prediction,
    /// kept for the second look.
    first_look: Option<(usize, Pass)>,
}

impl BlueTracker {
    /// Errors on a model the tracker cannot use: no vertices or edges, or
    /// joints (002 tracks a rigid target at a fixed orientation; a joint's
    /// part would be drawn at its rest position). [`BlueTracker::new`]
    /// checks it first; a caller that read the model from a file calls it
    /// to name that file.
    pub fn check_model(model: &Model) -> Result<()> {
        let bad = |msg: String| Err(Error::Parameter(format!("blue: {msg}")));
        if model.vertices.is_empty() || model.edges.is_empty() {
            return bad("the model needs vertices and edges".into());
        }
        let joints = model.joints.len();
        if joints > 0 {
            return bad(format!(
                "the model has {joints} joint{}; blue tracks a rigid target at a fixed orientation \
                 (track an articulated model with lowe)",
                if joints == 1 { "" } else { "s" }
            ));
        }
        Ok(())
    }

    /// A tracker for `model` seen by `camera`, starting at `init.pose`
    /// (required; its rotation stays fixed). Errors on a model the tracker
    /// cannot use ([`BlueTracker::check_model`]), and on a start pose that
    /// puts the model's centroid at or behind the camera, or whose image of
    /// the model (of its vertices in front of the camera) misses the image
    /// or is less than a pixel wide or high
    /// ([`Camera::start_image_problem`]).
    pub fn new(camera: Camera, model: Model, init: InitState, params: BlueParams) -> Result<Self> {
        params.validate()?;
        Self::check_model(&model)?;
        let bad = |msg: String| Err(Error::Parameter(format!("blue: {msg}")));
        if let Some(problem) = camera.intrinsics_problem() {
            return bad(format!("camera: {problem}"));
        }
        let Some(init_pose) = init.pose else {
            return bad("init.json has no pose; the blue tracker needs the initial pose".into());
        };
        if !model
            .vertices
            .iter()
            .flatten()
            .chain(&init_pose.rotation)
            .chain(&init_pose.translation)
            .all(|v| v.is_finite())
        {
            return bad("model vertices and init pose must be finite".into());
        }
        let geometry = match ModelGeometry::new(&model) {
            Ok(geometry) => geometry,
            Err(Error::Parameter(msg)) => return bad(msg),
            Err(e) => return Err(e),
        };
        let pose = geometry::Pose::from(&init_pose);
        let rotation = pose.rotation;
        let centroid = geometry.centroid();
        let offsets: Vec<DVec3> = geometry.vertices().iter().map(|&p| rotation * (p - centroid)).collect();
        let faces = geometry
            .face_normals(geometry.vertices())
            .into_iter()
            .zip(geometry.faces())
            .map(|(n, face)| (rotation * n, offsets[face[0]]))
            .collect();
        let reference = pose.apply(centroid);
        if !(reference.z > 0.0) {
            return bad(format!("the init pose puts the model's centroid behind the camera (Z = {})", reference.z));
        }
        let points: Vec<DVec3> = offsets.iter().map(|&q| reference + q).collect();
        if let Some(problem) = camera.start_image_problem(&points) {
            return bad(problem);
        }
        let [cx, cy] = camera.project(reference);
        let init_location = TargetLocation { cx, cy, cz: reference.z };
        let nominal_range = params.nominal_range.unwrap_or(reference.z);
        // Image displacement per metre of range change for the model's extent.
        let extent = offsets.iter().map(|q| q.x.hypot(q.y)).fold(0.0, f64::max).max(1e-9);
        let range_px_per_m = camera.fx.max(camera.fy) * extent / (reference.z * reference.z);
        let filters = start_filters(&params, &init_location, 0.0, range_px_per_m)?;
        let init_corners = offsets
            .iter()
            .map(|&q| camera.project_in_front(reference + q).unwrap_or([init_location.cx, init_location.cy]))
            .collect();
        Ok(Self {
            params,
            camera,
            rotation_vector: init_pose.rotation,
            rotation,
            centroid,
            offsets,
            geometry,
            faces,
            nominal_range,
            range_px_per_m,
            filters,
            phase: Phase::Acquiring,
            next_frame: 0,
            last_frame: None,
            last_tracked: init_location,
            lost_run: 0,
            last_corners: init_corners,
            second_look: None,
            first_look: None,
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

    /// Centroid in the camera frame for `location`: the back-projection of
    /// (c_x, c_y) at depth c_z.
    fn reference_point(&self, location: &TargetLocation) -> DVec3 {
        self.camera.back_project([location.cx, location.cy], location.cz)
    }

    /// Image positions of every model vertex at `location` (model-vertex
    /// order; NaN for a vertex not in front of the camera).
    #[must_use]
    pub fn vertices_at(&self, location: &TargetLocation) -> Vec<[f64; 2]> {
        let x = self.reference_point(location);
        self.offsets.iter().map(|&q| self.camera.project_in_front(x + q).unwrap_or([f64::NAN; 2])).collect()
    }

    /// Why the model at `location` cannot be projected: the first vertex at
    /// or behind the camera, or whose pixel is not finite; `None` when every
    /// vertex projects.
    #[must_use]
    fn unprojectable_vertex(&self, location: &TargetLocation) -> Option<String> {
        let x = self.reference_point(location);
        self.offsets.iter().enumerate().find_map(|(i, &q)| {
            let p = x + q;
            self.camera.project_in_front(p).is_none().then(|| {
                format!(
                    "model vertex {i} cannot be projected: it is at camera Z = {:?} m (c_z = {:?} m)",
                    p.z, location.cz
                )
            })
        })
    }

    /// The corners reported at `location`: [`BlueTracker::vertices_at`],
    /// with a vertex that cannot be projected at its last reported position;
    /// remembers the reported positions.
    fn report_corners(&mut self, location: &TargetLocation) -> Vec<[f64; 2]> {
        let mut corners = self.vertices_at(location);
        super::hold_finite_corners(&mut corners, &mut self.last_corners);
        corners
    }

    /// The pose at `location`: init rotation, translation t = X − R·c.
    #[must_use]
    pub fn pose_at(&self, location: &TargetLocation) -> Pose {
        let t = self.reference_point(location) - self.rotation * self.centroid;
        Pose { rotation: self.rotation_vector, translation: t.to_array() }
    }

    /// Whether each model edge is visible at `location` (borders a face
    /// facing the camera; edges bordering no face always are; SPEC §4).
    #[must_use]
    pub fn visible_edges(&self, location: &TargetLocation) -> Vec<bool> {
        let x = self.reference_point(location);
        let facing: Vec<bool> = self.faces.iter().map(|&(n, q)| geometry::faces_camera(n, x + q)).collect();
        self.geometry.visible_edges(&facing)
    }

    /// The verification's figures at `location` (module doc,
    /// "Verification"): the supported fraction of the visible contour and
    /// the larger supported fraction of that contour shifted by ±(2·d + 1)
    /// px across itself (d = [`BlueParams::support_distance`]), i.e. the
    /// support the edge density around the target gives any outline there;
    /// `None` when no contour is visible.
    fn contour_support(&self, map: &EdgeMap, location: &TargetLocation) -> Option<(f64, f64)> {
        let p = &self.params;
        let segments = self.visible_outline(location);
        let counts = map.support(&segments, p.support_distance, p.angle_tolerance);
        if counts.1 == 0 {
            return None;
        }
        let shift = 2.0 * p.support_distance + 1.0;
        let shifted = |offset: f64| {
            support::fraction(map.support(
                &support::offset_segments(&segments, offset),
                p.support_distance,
                p.angle_tolerance,
            ))
        };
        Some((support::fraction(counts), shifted(shift).max(shifted(-shift))))
    }

    /// How far across the outline the verification reads edge pixels:
    /// the outline shifted ±(2·d + 1) px, with d =
    /// [`BlueParams::support_distance`] on either side of it, and a pixel
    /// of rounding.
    fn verification_reach(&self) -> f64 {
        3.0 * self.params.support_distance + 2.0
    }

    /// The visible model edges at `location`, as image segments.
    fn visible_outline(&self, location: &TargetLocation) -> Vec<([f64; 2], [f64; 2])> {
        let vertices = self.vertices_at(location);
        self.geometry
            .edges()
            .iter()
            .zip(self.visible_edges(location))
            .filter(|&(_, v)| v)
            .map(|(&[i, j], _)| (vertices[i], vertices[j]))
            .collect()
    }

    /// The fraction of the visible outline's samples at `location` (those
    /// of the verification, [`support::sample_positions`]) whose
    /// verification reads edge pixels outside `window`: the most its
    /// support could gain were that part of the image listed.
    fn outline_unseen(&self, location: &TargetLocation, window: &Window) -> f64 {
        let reach = self.verification_reach();
        let inside = |[x, y]: [f64; 2]| {
            x - reach >= f64::from(window.x0)
                && y - reach >= f64::from(window.y0)
                && x + reach < f64::from(window.x1)
                && y + reach < f64::from(window.y1)
        };
        let counts = self
            .visible_outline(location)
            .into_iter()
            .flat_map(|(a, b)| support::sample_positions(a, b))
            .fold((0, 0), |(unseen, samples), c| (unseen + usize::from(!inside(c)), samples + 1));
        support::fraction(counts)
    }

    /// The frame's edge pixels indexed by position for the verification.
    fn edge_map(&self, edges: &[Feature]) -> EdgeMap {
        EdgeMap::new(edges, self.params.edge_threshold, |f| wrap_orientation(f64::from(f.theta) + FRAC_PI_2))
    }

    /// Whether the tracker has been lost long enough to search the whole
    /// image (module doc, "Verification").
    fn searching(&self) -> bool {
        self.phase == Phase::Lost && self.params.verify && self.lost_run >= self.params.search_after
    }

    /// Association distance of the next frame.
    fn association_distance(&self) -> f64 {
        if self.phase == Phase::Tracking && self.filters[0].samples() >= 3 {
            self.params.distance_tolerance
        } else {
            self.params.acquire_distance
        }
    }

    /// The window holding the next frame's edges: the predicted vertices'
    /// [`Window::around`] with the association distance plus
    /// `window_margin` as margin; the whole image when no vertex is in
    /// front of the camera.
    /// While a frame is looked at a second time, the wider window of that
    /// look (module doc, "Abrupt reversals").
    #[must_use]
    pub fn window_of_interest(&self, width: usize, height: usize) -> Window {
        match self.second_look {
            Some(window) => window.clipped(width, height),
            None => self.first_look_window(width, height),
        }
    }

    /// The window of a frame's first look (see [`Self::window_of_interest`]).
    fn first_look_window(&self, width: usize, height: usize) -> Window {
        if self.searching() {
            return Window::full(width, height);
        }
        let location = self.location_at(self.next_frame as f64);
        let margin = self.association_distance() + self.params.window_margin;
        Window::around(&self.vertices_at(&location), margin, width, height)
            .unwrap_or_else(|| Window::full(width, height))
    }

    /// The checks after steps 1–7 (module doc, "Start, loss and output" and
    /// "Verification"): the reason `pass` loses the frame, if any, and the
    /// verification's supported fractions (on, beside) of its outline.
    /// `searched`: the frame was measured where the whole-image search put
    /// the model; `follows_tracked`: the frame before was tracked.
    fn judge(
        &self,
        pass: &Pass,
        map: &EdgeMap,
        searched: Option<f64>,
        follows_tracked: bool,
    ) -> (Option<String>, Option<(f64, f64)>) {
        // Steps 5–6 refuse an estimate that puts a vertex where it cannot be
        // projected; checked again here because every reported corner must
        // be finite.
        let mut failure = pass.failure.clone();
        if failure.is_none() {
            failure = self.unprojectable_vertex(&pass.location);
        }
        // A search fixes the range: an estimate far from it fitted something
        // else than the target (clutter of another scale).
        // Nor does a target tracked a frame ago change its range by 30 %.
        if failure.is_none() && (searched.is_some() || follows_tracked) && pass.estimated {
            let ratio = pass.location.cz / searched.unwrap_or(self.last_tracked.cz);
            if !((1.0 / SEARCH_RANGE_TOLERANCE..=SEARCH_RANGE_TOLERANCE).contains(&ratio)) {
                let (prefix, reference) = if searched.is_some() {
                    ("search: ", "the searched one")
                } else {
                    ("", "the last tracked frame's")
                };
                failure = Some(format!(
                    "{prefix}the estimate's range is {ratio:.2} times {reference} (at most {SEARCH_RANGE_TOLERANCE} either way)"
                ));
            }
        }
        // A search picks the best of many places: the estimate must fit most
        // of the visible model lines.
        if failure.is_none() && searched.is_some() && pass.estimated {
            let visible = self.visible_edges(&pass.location);
            let shown = visible.iter().filter(|&&v| v).count();
            let fitted = pass.line_fitted.iter().zip(&visible).filter(|&(&f, &v)| f && v).count();
            if (fitted as f64) < self.params.search_min_fitted * shown as f64 {
                failure = Some(format!(
                    "search: {fitted} of the {shown} visible model lines fitted, fewer than search_min_fitted = {:.0} %",
                    100.0 * self.params.search_min_fitted
                ));
            }
        }
        // Verification: the estimate's outline must stand out on the image's edges.
        let support =
            if pass.estimated && failure.is_none() { self.contour_support(map, &pass.location) } else { None };
        if failure.is_none() && self.params.verify {
            let excess = support.map_or(0.0, |(on, off)| on - off);
            // A search picks the best of many places: the bar is higher.
            let min_support = if searched.is_some() { self.params.search_min_support } else { self.params.min_support };
            if !(excess >= min_support) {
                failure = Some(match support {
                    Some((on, off)) => format!(
                        "contour support {:.0} % on the outline against {:.0} % beside it: excess {:.0} % < min_support {:.0} %",
                        100.0 * on,
                        100.0 * off,
                        100.0 * excess,
                        100.0 * min_support
                    ),
                    None => "no visible contour to verify".to_string(),
                });
            }
        }
        (failure, support)
    }

    /// Steps 1 (alignment) to 6 around `predicted`, associating within
    /// `distance`; a failed pass when `predicted` is not in front of the
    /// camera.
    fn measure_around(&self, edges: &[Feature], predicted: &TargetLocation, distance: f64) -> Pass {
        let pass = if predicted.is_valid() {
            let (model, first_distance) = self.first_association(edges, predicted, distance);
            self.measure(edges, &model, predicted, first_distance)
        } else {
            let (ne, nv) = (self.geometry.edges().len(), self.offsets.len());
            Pass::failed(predicted, ne, nv, "the prediction is not in front of the camera".into())
        };
        self.reassociate(edges, pass, predicted)
    }

    /// The motion models' image velocity (dc_x/dt, dc_y/dt) at their
    /// latest sample, px per frame.
    fn image_velocity(&self) -> Option<[f64; 2]> {
        let velocity = |k: usize| self.filters[k].coefficients().map(|a| a[1]).filter(|v| v.is_finite());
        Some([velocity(0)?, velocity(1)?])
    }

    /// Process frame `frame` given its edge pixels; every call returns an
    /// outcome (also when lost). Frames must come in increasing order.
    /// Through [`Tracker::track_or_widen`] a frame may instead be looked at
    /// a second time in a wider window (module doc, "Abrupt reversals").
    pub fn update(&mut self, frame: usize, edges: &[Feature]) -> FrameOutcome {
        match self.look(frame, edges, false) {
            Some(outcome) => outcome,
            None => unreachable!("a look that may not widen answers"),
        }
    }

    /// [`Self::update`], or `None` after widening the window for a second
    /// look at the frame when `may_widen` (the tracker's state otherwise
    /// unchanged).
    fn look(&mut self, frame: usize, edges: &[Feature], may_widen: bool) -> Option<FrameOutcome> {
        let (width, height) = (self.camera.width as usize, self.camera.height as usize);
        let window = self.window_of_interest(width, height);
        self.second_look = None;
        let time = frame as f64;
        // Whether the previous frame was tracked, and the image velocity
        // there (for the reversal hypotheses).
        let follows_tracked = self.phase == Phase::Tracking && self.last_frame.is_some_and(|f| f + 1 == frame);
        let previous_velocity = follows_tracked.then(|| self.image_velocity()).flatten();
        // Step 1: prediction.
        let mut predicted = self.location_at(time);
        let may_widen = may_widen && predicted.is_valid();
        if !predicted.is_valid() {
            // Extrapolated behind the camera (or not finite): search where
            // the target was last seen.
            predicted = self.last_tracked;
            self.restart_motion_models(&predicted, time);
        }
        let map = self.edge_map(edges);
        let searched = self.searching();
        let mut searched_pass = None;
        if searched {
            // Lost for `search_after` frames: look for the target over the
            // whole image, around the last tracked range (module doc,
            // "Verification").
            let radius = f64::from(self.camera.width.max(self.camera.height));
            let image = (f64::from(self.camera.width), f64::from(self.camera.height));
            let last = self.last_tracked;
            let excess = |location: &TargetLocation| {
                self.contour_support(&map, location).map_or(f64::NEG_INFINITY, |(on, off)| on - off)
            };
            let reach =
                (SEARCH_RANGE_REACH * SEARCH_RANGE_GROWTH.powf(self.lost_run as f64)).min(SEARCH_RANGE_MAX_REACH);
            // The last tracked range and, in turn from one searching frame to
            // the next, one ratio step nearer and farther.
            let steps = (reach.ln() / SEARCH_RANGE_RATIO.ln()).floor() as usize;
            let ranges: Vec<i32> = match steps {
                0 => vec![0],
                _ => {
                    let j = (1 + (self.lost_run - self.params.search_after) % steps) as i32;
                    vec![0, -j, j]
                }
            };
            let best = ranges
                .into_iter()
                .flat_map(|k| {
                    let at_range = TargetLocation { cz: last.cz * SEARCH_RANGE_RATIO.powi(k), ..last };
                    let peaks = self.shift_peaks(
                        edges,
                        &at_range,
                        radius,
                        SEARCH_STEP_PX,
                        SEARCH_PEAKS,
                        SEARCH_SEPARATION,
                        Some(image),
                    );
                    peaks.into_iter().map(move |[sx, sy]| TargetLocation {
                        cx: at_range.cx + sx,
                        cy: at_range.cy + sy,
                        ..at_range
                    })
                })
                .map(|coarse| {
                    let [fx, fy] = self.align_shift(edges, &coarse, SEARCH_STEP_PX).unwrap_or([0.0; 2]);
                    let fine = TargetLocation { cx: coarse.cx + fx, cy: coarse.cy + fy, ..coarse };
                    let e = excess(&fine);
                    (e, fine)
                });
            let mut candidates: Vec<(f64, TargetLocation)> = best.collect();
            candidates.sort_by(|a, b| b.0.total_cmp(&a.0));
            // The places whose outlines stand out most are measured; the
            // one whose measured outline passes and stands out most wins
            // (or, when none passes, the place that stood out most), and its
            // measurement is the frame's.
            let mut chosen: Option<(f64, TargetLocation, Pass)> = None;
            for (k, (_, place)) in candidates.iter().take(SEARCH_MEASURED).enumerate() {
                let pass = self.measure_around(edges, place, self.params.acquire_distance);
                let excess = match self.judge(&pass, &map, Some(place.cz), false) {
                    (None, Some((on, off))) => on - off,
                    _ if k == 0 => f64::NEG_INFINITY,
                    _ => continue,
                };
                if chosen.as_ref().is_none_or(|(best, _, _)| excess >= *best) {
                    chosen = Some((excess, *place, pass));
                }
            }
            if let Some((_, location, pass)) = chosen {
                predicted = location;
                searched_pass = Some(pass);
                self.restart_motion_models(&predicted, time);
            }
        }
        // Steps 1 (alignment) to 6, then step 7 (already done where the
        // search measured its places).
        // A second look keeps the first look's estimate around the
        // prediction, judged again on this look's edges; only the
        // hypotheses are measured again.
        let first_look = self.first_look.take().filter(|(f, _)| *f == frame);
        let mut pass = match (first_look, searched_pass) {
            (Some((_, pass)), _) | (None, Some(pass)) => pass,
            (None, None) => self.measure_around(edges, &predicted, self.association_distance()),
        };
        let (mut failure, mut support) = self.judge(&pass, &map, searched.then_some(predicted.cz), follows_tracked);
        // A reversal (extension, module doc "Abrupt reversals"): after a
        // tracked frame, when the target moves so fast that a reversal
        // leaves the association window, the frame is measured again around
        // the target turned back and at rest; the estimate whose outline
        // stands out most is kept.
        let apart = |a: &TargetLocation, b: &TargetLocation| (a.cx - b.cx).hypot(a.cy - b.cy);
        let fast = |v: &[f64; 2]| v[0].hypot(v[1]) >= 0.5 * self.params.distance_tolerance;
        if self.params.reversal_hypotheses
            && !searched
            && let Some([vx, vy]) = previous_velocity.filter(fast)
        {
            let last = self.last_tracked;
            let hypotheses = [
                TargetLocation { cx: last.cx - vx, cy: last.cy - vy, ..last },
                TargetLocation { cx: last.cx, cy: last.cy, ..last },
            ];
            // A hypothesis replaces an estimate that passed only when it
            // found another place (farther than `refine_distance`) whose
            // outline stands out clearly more.
            let main = (failure.is_none() && support.is_some()).then_some(pass.location);
            let mut best = match (&failure, support) {
                (None, Some((on, off))) => on - off + REVERSAL_MARGIN,
                _ => f64::NEG_INFINITY,
            };
            // The target is within a frame's displacement of either: turned
            // back by 180° ± 50° or stopped anywhere along the way.
            let reach = vx.hypot(vy).min(self.params.acquire_distance).max(self.params.distance_tolerance);
            // Where a hypothesis's outline, and the outline shifted beside it
            // that the verification also reads, reach beyond this frame's
            // window: edge pixels there were not listed.
            let bar = if self.params.verify { self.params.min_support } else { f64::NEG_INFINITY };
            let mut unseen = Window::default();
            let mut winner: Option<(Pass, (f64, f64))> = None;
            for hypothesis in &hypotheses {
                let candidate = self.measure_around(edges, hypothesis, reach);
                if main.is_some_and(|m| apart(&m, &candidate.location) <= self.params.refine_distance) {
                    continue;
                }
                let kept = winner.as_ref().map_or(main, |(w, _)| Some(w.location));
                match self.judge(&candidate, &map, None, true) {
                    (None, Some((on, off))) if on - off > best => {
                        best = on - off;
                        winner = Some((candidate, (on, off)));
                    }
                    // Elsewhere than the estimate kept so far, passed but
                    // did not win, or failed the verification alone, on an
                    // outline partly unseen, by less than the unseen part
                    // could give: the frame is looked at again with the
                    // hypothesis's edges listed.
                    (_, Some((on, off)))
                        if may_widen
                            && !kept.is_some_and(|k| apart(&k, &candidate.location) <= self.params.refine_distance)
                            && on - off + self.outline_unseen(&candidate.location, &window) > best.max(bar) =>
                    {
                        let outline = self.vertices_at(&candidate.location);
                        if let Some(around) = Window::around(&outline, self.verification_reach(), width, height) {
                            unseen = unseen.union(&around);
                        }
                    }
                    _ => {}
                }
            }
            if !unseen.is_empty() {
                self.second_look = Some(window.union(&unseen));
                self.first_look = Some((frame, pass));
                return None;
            }
            if let Some((candidate, s)) = winner {
                pass = candidate;
                failure = None;
                support = Some(s);
            }
        }
        self.next_frame = frame + 1;
        self.last_frame = Some(frame);
        // The estimate must not stand out clearly less than the prediction
        // it was measured from (module doc, "Verification").
        if failure.is_none() && self.params.verify && follows_tracked && !searched {
            let excess = |s: Option<(f64, f64)>| s.map(|(on, off)| on - off);
            if let (Some(kept), Some(expected)) = (excess(support), excess(self.contour_support(&map, &predicted)))
                && expected - kept > self.params.max_excess_below_prediction
            {
                failure = Some(format!(
                    "the estimate's outline stands out by {:.0} %, the prediction's by {:.0} %: more than max_excess_below_prediction = {:.0} % less",
                    100.0 * kept,
                    100.0 * expected,
                    100.0 * self.params.max_excess_below_prediction
                ));
            }
        }
        let tracked = failure.is_none();
        // Restart the motion models when the kept estimate, the prediction's
        // or a hypothesis's, is not where they predicted.
        let reversed = self.params.reversal_hypotheses
            && follows_tracked
            && !searched
            && apart(&pass.location, &predicted) > self.params.distance_tolerance;
        let (location, covariance) = if tracked {
            if reversed {
                // The polynomials extrapolate the motion before the reversal:
                // start them again from the last tracked frame, at rest.
                let last = self.last_tracked;
                self.restart_motion_models(&last, time - 1.0);
            }
            self.feed_motion_models(time, &pass);
            self.phase = Phase::Tracking;
            self.last_tracked = pass.location;
            self.lost_run = 0;
            (pass.location, pass.covariance.iter().flatten().copied().collect::<Vec<f64>>())
        } else {
            self.advance_motion_models(time);
            self.phase = Phase::Lost;
            self.lost_run += 1;
            if self.lost_run >= self.params.coast_frames {
                // Stop extrapolating: search where the target was last seen.
                let last = self.last_tracked;
                self.restart_motion_models(&last, time);
            }
            let var: [f64; 3] =
                std::array::from_fn(|k| self.filters[k].prediction_variance(0.0).unwrap_or(f64::INFINITY));
            let rho = predicted.inverse_range();
            let cov = vec![var[0], 0.0, 0.0, 0.0, var[1], 0.0, 0.0, 0.0, var[2] * rho.powi(4)];
            (predicted, cov)
        };
        if !tracked && let Some(reason) = self.unprojectable_vertex(&location) {
            failure = Some(super::add_lost_reason(failure, format!("{reason}; reported at its last position")));
        }
        let contour_support = support.map(|(on, _)| on);
        let corners = self.report_corners(&location);
        Some(FrameOutcome {
            frame,
            status: if tracked { Status::Tracking } else { Status::Lost },
            phase: self.phase,
            corners,
            pose: Some(self.pose_at(&location)),
            params: None,
            covariance: covariance.iter().all(|v| v.is_finite()).then_some(covariance),
            labelled: pass.labelled,
            diagnostics: Diagnostics {
                points_per_line: pass.points_per_line,
                line_fitted: pass.line_fitted,
                corner_measured: pass.corner_measured,
                max_corner_deviation: pass.max_corner_deviation,
                unexplained_points: pass.unexplained,
                contour_support,
                side_support: None,
                lost_reason: failure,
                bands: Vec::new(),
            },
        })
    }
}

impl Tracker for BlueTracker {
    fn name(&self) -> &'static str {
        "blue"
    }

    fn accept_frame_size(&mut self, width: usize, height: usize) -> std::result::Result<(), String> {
        super::camera_takes(&self.camera, width, height)
    }

    fn window_of_interest(&self, width: usize, height: usize) -> Window {
        BlueTracker::window_of_interest(self, width, height)
    }

    /// §2.3: Sobel on the raw frame, magnitude above `edge_threshold`, inside
    /// the window of interest, at most `max_edge_points` by the seeded subsample.
    fn request(&self, width: usize, height: usize) -> FrameRequest {
        let window = BlueTracker::window_of_interest(self, width, height);
        // While searching, the cap grows with the window so that the edge
        // pixels keep the density of a tracking window.
        let area = |w: &Window| w.area() as f64;
        let scale = if self.second_look.is_some() {
            // A second look keeps the edge density of its first.
            area(&window) / area(&self.first_look_window(width, height)).max(1.0)
        } else if self.searching() {
            let tracking_margin = self.params.distance_tolerance + self.params.window_margin;
            Window::around(&self.vertices_at(&self.last_tracked), tracking_margin, width, height)
                .map_or(1.0, |w| (area(&window) / area(&w).max(1.0)).max(1.0))
        } else {
            1.0
        };
        let cap = (self.params.max_edge_points as f64 * scale).min(f64::from(MAX_CAP)) as u32;
        FrameRequest {
            edges: Some(EdgeRequest {
                threshold: self.params.edge_threshold,
                smoothed: false,
                list: ListSpec {
                    window,
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

    fn track_or_widen(&mut self, frame: usize, observations: &Observations<'_>) -> Tracked {
        match self.look(frame, observations.edges.unwrap_or(&[]), true) {
            Some(outcome) => Tracked::Outcome(outcome),
            None => Tracked::Widened,
        }
    }
}
