//! Parameters of the motion-edge tracker: the paper's values as defaults,
//! every one documented and bounded ([`MotionEdgeParams::validate`]), and the
//! switchable extensions where the paper's literal method fails (module doc of
//! [`super`]).

use serde::{Deserialize, Serialize};

use crate::Result;
use crate::bounds::{Interval, check_count};
use crate::early::gaussian::MAX_SIGMA;
use crate::io::frames::MAX_FRAME_PIXELS;

/// What a corner without a measurement feeds its smoother.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MissingMeasurement {
    /// Its own prediction: the corner keeps its velocity.
    Prediction,
    /// Its last measurement again: the prediction slows to a stop (paper
    /// Fig. 2). Default: no motion pixels means no visible motion.
    #[default]
    LastMeasurement,
}

/// Where the next frame's model lines are predicted (step 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Prediction {
    /// Eq. 12 for every corner: Brown's forecast of the smoothed corners.
    /// Lags by several frames' worth of acceleration (module doc).
    Smoothed,
    /// A corner measured in this and the previous frame moves on by its last
    /// measured displacement; eq. 12 for the others (tracking start, motion
    /// resuming after frames without motion pixels, lost).
    MeasuredVelocity,
    /// When every corner was measured in this and the previous frame, the
    /// outline moves on as a whole: by the least-squares similarity transform
    /// (turn, scale, shift) that took the previous measured outline to this
    /// one ([`crate::geometry::similarity_step`]), which is also the
    /// displacement the lag correction halves. Otherwise as
    /// [`Prediction::MeasuredVelocity`]. Default.
    #[default]
    MeasuredMotion,
}

/// How step 3 fits a line to its labelled pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LineFitMethod {
    /// Eq. 5–8 as printed: y on x, or x on y when y spreads more.
    Regression,
    /// Perpendicular errors minimised (what the paper's "minimizes errors in
    /// both x and y" asks for); unbiased on thick bands at any slope, as
    /// long as the band is clearly longer than it is thick.
    Orthogonal,
    /// Eq. 5–6 in the predicted line's frame: the offset across the model
    /// line regressed on the position along it
    /// ([`crate::estimate::line_fit::fit_line_across`]). Unbiased on bands of any thickness
    /// and slope, also as thick as they are long. Default.
    #[default]
    Across,
}

/// Parameters of the motion-edge tracker (paper 000), all with defaults, so a
/// `--config` TOML file may set any subset (unknown keys are refused).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotionEdgeParams {
    /// Angle tolerance δ of eq. 3, radians. The paper gives no value; 15°:
    /// Sobel orientations of blurred edges are good to a few degrees, a model
    /// line turns little in a frame, and 15° still rejects 5/6 of clutter of
    /// random orientation (2δ/π = 1/6) and separates lines meeting at > 30°.
    /// Range: (0, π/2].
    pub delta: f64,
    /// Distance threshold ζ of eq. 4, px. Tables 1–3 test 3, 5, 10, 15: 3 and
    /// 5 give the smallest errors, 10–15 mislabel at 3.9–4.5 px/frame; 5 is as
    /// accurate as 3 in the tables and leaves room for blur tails and for
    /// prediction error when the object accelerates.
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub zeta: f64,
    /// Corner check ε of eq. 9, px. Tables test 20, 26, 32 with no significant
    /// difference; the tightest, 20, detects loss soonest.
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub epsilon: f64,
    /// Smoothing constant α of eq. 10–12 (paper: 0.2). Range: (0, 1).
    pub alpha: f64,
    /// Gaussian σ the backend smooths frames with before eq. 1 (not given in
    /// the paper), px. Range: (0, [`MAX_SIGMA`]] (the smoothing stage's own
    /// bound, [`crate::early::gaussian::GaussianParams::validate`]).
    pub sigma: f32,
    /// Threshold on |temporal difference| (eq. 1) in grey levels (0..255): well
    /// above sensor noise of a smoothed frame, well below edge contrasts.
    /// Range: [0, [`MAX_MOTION_THRESHOLD`]].
    pub motion_threshold: f32,
    /// Fewest labelled pixels that update a line; fewer keep its prediction.
    /// Range: 2 ..= [`MAX_COUNT`].
    pub min_points_per_line: usize,
    /// Extra margin of the window of interest beyond ζ plus a frame's
    /// predicted motion (covers blur and acceleration), px.
    /// Range: [0, [`MAX_DISTANCE_PX`]].
    pub window_margin: f64,
    /// Labelling distance and corner acceptance distance while acquiring (and
    /// re-acquiring), px: must exceed one frame's motion when tracking starts.
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub init_tolerance: f64,
    /// Report corners at the current frame rather than at the band centre
    /// half a frame earlier (module doc). Range: either.
    pub lag_correction: bool,
    /// Widen ζ by half the predicted band width (module doc); off: eq. 4 as
    /// printed. Range: either.
    pub band_tolerance: bool,
    /// Motion pixels with a weaker Sobel magnitude carry no edge orientation
    /// (eq. 2 is undefined where the gradient vanishes, and noise where it is
    /// small) and are ignored. Sobel units on the sum of two frames of 0..255
    /// grey levels: an edge steep enough to pass `motion_threshold` (≥ 10 grey
    /// levels, σ ≈ 1) gives ≳ 25 at the band's ends; noise of a smoothed frame
    /// gives a few units. Default 10. Range: [0, [`MAX_MIN_MAGNITUDE`]].
    pub min_magnitude: f32,
    /// What a line or corner without motion pixels does (module doc).
    /// Range: any.
    pub missing: MissingMeasurement,
    /// Unlabelled pixels of a starved line's orientation that declare it
    /// contradicted, i.e. the object lost (module doc).
    /// Range: 1 ..= [`MAX_COUNT`].
    pub lost_evidence: usize,
    /// A tracking frame in which no line is fitted right after a frame in
    /// which every corner was measured moving at least this, px/frame, loses
    /// the track (module doc, "vanished motion"); infinity disables the
    /// check. Default 1. Range: [0, [`MAX_DISTANCE_PX`]], or infinity.
    pub vanished_motion: f64,
    /// Line fit of step 3. Range: any.
    pub line_fit: LineFitMethod,
    /// Re-labelling passes around the fitted lines after the first one
    /// (module doc, "Re-centred labelling"); 0: the paper's single pass.
    /// Range: 0 ..= [`MAX_PASSES`].
    pub refine_iterations: usize,
    /// Prediction of the next frame's corners (module doc, "Prediction under
    /// acceleration"). Range: any.
    pub prediction: Prediction,
    /// Fit each line without motion pixels, once turned, to the frame's
    /// static edge pixels (module doc, "Held lines on the frame's edges");
    /// off: held lines only turn. Range: either.
    pub held_line_edges: bool,
    /// Check every frame about to be reported `tracking` against the image
    /// (module doc, "Verification"): the reported contour must have static
    /// edge support. Off: the paper's method, where only eq. 9 (and the
    /// extensions' contradiction and vanished-motion checks) lose the track.
    /// Range: either.
    pub verify: bool,
    /// Smallest fraction of the reported contour's samples with edge support
    /// (module doc, "Verification"). A contour on the object has 0.9–1.0; one
    /// a few px off the object has almost none, as the object's edge pixels
    /// lie outside `support_distance` and the background's mostly have
    /// other orientations. Range: [0, 1].
    pub min_support: f64,
    /// Smallest fraction of each side of the reported contour with edge
    /// support (module doc, "Verification"): a contour shifted along one of
    /// its sides keeps that side's support but loses that of the sides
    /// across it. Range: [0, 1].
    pub min_side_support: f64,
    /// With `verify`, smallest fraction of the contour's samples, and of
    /// each side's, with edge support in the first frame reported tracking
    /// after a loss (module doc, "Verification"). Re-acquisitions on target
    /// on the pendulum scenes (with a distractor, cluttered, up to 16
    /// px/frame, panned out and back) have ≥ 0.96 overall and ≥ 0.88 on
    /// each side; one 6 px off had 0.72 and 0.65. Range: [0, 1].
    pub reacquire_min_support: f64,
    /// Angle tolerance δ of the second look at a tracking frame that is
    /// about to be lost (module doc, "A second look at a wider angle"),
    /// radians: the frame is measured again from the same prediction with
    /// this δ, and the second measurement is kept when it passes every test,
    /// the verification included. Only with `verify`; a value at or below
    /// `delta` turns it off. Default 30°. Range: [0, π/2].
    pub retry_delta: f64,
    /// With `verify` and [`Prediction::MeasuredMotion`], a tracking frame
    /// about to be lost after both looks above is measured once more from
    /// the outline moved on at constant acceleration (its last step plus the
    /// change from the step before; module doc, "A look from the
    /// accelerating outline"), and kept when that measurement passes every
    /// test. Frames tracked without it are unchanged. Range: either.
    pub acceleration_look: bool,
    /// With `verify`, lost frames in a row after which re-acquisition
    /// searches the whole image: the window of interest opens to the full
    /// frame and the last tracked shape is placed on the centroid of the
    /// motion pixels (module doc, "Verification"). 2: on the pendulum at
    /// 16 px/frame the search finds the rectangle again sooner than the
    /// strips around the coasting prediction do (with a crossing hexagon
    /// 172 → 193 of 200 frames tracking against 10 lost frames; translating,
    /// seeds 2 and 3: 87 → 160 and 176 → 192; cluttered: 116 → 152), none
    /// false, and the slower scenes unchanged. Range: 1 ..= [`MAX_SEARCH_AFTER`].
    pub search_after: usize,
    /// Largest distance across the contour of an edge pixel that supports a
    /// contour sample, px. 3: the Sobel response of a blurred step is ~2 px
    /// wide, so a contour within ~1–2 px of its edge is fully supported and
    /// one 5 px off is not. Range: (0, [`MAX_DISTANCE_PX`]].
    pub support_distance: f64,
    /// Sobel magnitude threshold of the edge pixels of the support check,
    /// on the σ-smoothed frame (Sobel units: ≈ 4·σ-blurred contrast; a
    /// 115-grey-level step gives ≳ 300, smooth texture and noise of σ = 2
    /// stay well under 80). Range: (0, [`MAX_MIN_MAGNITUDE`]].
    pub support_edge_threshold: f32,
}

/// Upper bound of the distances, tolerances and margins, px: the window of
/// interest grows with them (it is clipped to the frame, but a frame is at
/// most a few thousand pixels across), and a corner further than this from
/// its prediction is no longer the same corner.
pub const MAX_DISTANCE_PX: f64 = 1000.0;

/// Upper bound of [`MotionEdgeParams::refine_iterations`]: each pass
/// re-labels every motion pixel of the window, and the labelling settles
/// within a few passes (it stops early when no corner moves).
pub const MAX_PASSES: usize = 100;

/// Upper bound of [`MotionEdgeParams::motion_threshold`], grey levels: the
/// temporal difference of two frames of 0..255 is at most 255 in magnitude,
/// and a pixel moves only when it exceeds the threshold, so from 255 on no
/// pixel moves.
pub const MAX_MOTION_THRESHOLD: f32 = 255.0;

/// Upper bound of [`MotionEdgeParams::min_magnitude`]: the 3×3 Sobel magnitude
/// of the sum of two frames of 0..255 is at most 4·510·√2 ≈ 2885, so a higher
/// floor ignores every pixel.
pub const MAX_MIN_MAGNITUDE: f32 = 2885.0;

/// Upper bound of the pixel counts [`MotionEdgeParams::min_points_per_line`]
/// and [`MotionEdgeParams::lost_evidence`]: no frame has more pixels.
pub const MAX_COUNT: usize = MAX_FRAME_PIXELS;

/// Upper bound of [`MotionEdgeParams::search_after`], frames (an hour at 30 Hz).
pub const MAX_SEARCH_AFTER: usize = 108_000;

/// Range of the positive distances, px.
const POSITIVE_PX: Interval = Interval::open_closed(0.0, MAX_DISTANCE_PX);
/// Range of the margins, px.
const MARGIN_PX: Interval = Interval::closed(0.0, MAX_DISTANCE_PX);

impl Default for MotionEdgeParams {
    fn default() -> Self {
        Self {
            delta: 15f64.to_radians(),
            zeta: 5.0,
            epsilon: 20.0,
            alpha: 0.2,
            sigma: 1.0,
            motion_threshold: 10.0,
            min_points_per_line: 10,
            window_margin: 8.0,
            init_tolerance: 24.0,
            lag_correction: true,
            band_tolerance: true,
            min_magnitude: 10.0,
            missing: MissingMeasurement::LastMeasurement,
            lost_evidence: 50,
            vanished_motion: 1.0,
            refine_iterations: 3,
            line_fit: LineFitMethod::Across,
            prediction: Prediction::MeasuredMotion,
            held_line_edges: true,
            verify: true,
            min_support: 0.6,
            min_side_support: 0.5,
            reacquire_min_support: 0.85,
            retry_delta: 30f64.to_radians(),
            acceleration_look: true,
            search_after: 2,
            support_distance: 3.0,
            support_edge_threshold: 80.0,
        }
    }
}

impl MotionEdgeParams {
    /// The method as paper 000 prints it, every switchable extension off:
    /// eq. 5–8 regression fits, one labelling pass with the fixed ζ of eq. 4,
    /// eq. 12 predictions throughout, corners reported where the lines fitted
    /// to the motion band put them (no half-frame lag correction), lines
    /// without motion pixels not fitted to the frame's edges, loss by
    /// eq. 9 only (no contradicted-line or vanished-motion loss, no
    /// verification against the image's edges, no second look at a wider
    /// angle, no look from the accelerating outline). A corner
    /// without motion pixels feeds its last measurement to eq. 10–11, so its
    /// predictions slow down (paper §2, Fig. 2).
    ///
    /// Kept, because no parameter switches them off: a line without motion
    /// pixels is held at its last fit and turned by the fitted lines' mean
    /// turn, and the fitted pixels are trimmed a frame's motion inside the
    /// segment's ends (module doc of [`super`]). δ, σ, the motion threshold,
    /// `min_points_per_line`, `min_magnitude` and the acquisition tolerance,
    /// which the paper does not give, keep their defaults.
    #[must_use]
    pub fn paper() -> Self {
        Self {
            lag_correction: false,
            band_tolerance: false,
            missing: MissingMeasurement::LastMeasurement,
            lost_evidence: MAX_COUNT,
            vanished_motion: f64::INFINITY,
            line_fit: LineFitMethod::Regression,
            refine_iterations: 0,
            prediction: Prediction::Smoothed,
            held_line_edges: false,
            verify: false,
            retry_delta: 0.0,
            acceleration_look: false,
            ..Self::default()
        }
    }

    /// Check every parameter against its documented range
    /// ([`crate::Error::Parameter`] naming the first bad one and its range).
    pub fn validate(&self) -> Result<()> {
        const WHO: &str = "motion-edge";
        let reals = [
            ("delta", self.delta, Interval::open_closed(0.0, std::f64::consts::FRAC_PI_2), " radians"),
            ("zeta", self.zeta, POSITIVE_PX, " px"),
            ("epsilon", self.epsilon, POSITIVE_PX, " px"),
            ("alpha", self.alpha, Interval::open(0.0, 1.0), ""),
            ("sigma", f64::from(self.sigma), Interval::open_closed(0.0, f64::from(MAX_SIGMA)), " px"),
            (
                "motion_threshold",
                f64::from(self.motion_threshold),
                Interval::closed(0.0, f64::from(MAX_MOTION_THRESHOLD)),
                " grey levels",
            ),
            ("window_margin", self.window_margin, MARGIN_PX, " px"),
            ("init_tolerance", self.init_tolerance, POSITIVE_PX, " px"),
            ("min_magnitude", f64::from(self.min_magnitude), Interval::closed(0.0, f64::from(MAX_MIN_MAGNITUDE)), ""),
            ("min_support", self.min_support, Interval::closed(0.0, 1.0), ""),
            ("min_side_support", self.min_side_support, Interval::closed(0.0, 1.0), ""),
            ("reacquire_min_support", self.reacquire_min_support, Interval::closed(0.0, 1.0), ""),
            ("retry_delta", self.retry_delta, Interval::closed(0.0, std::f64::consts::FRAC_PI_2), " radians"),
            ("support_distance", self.support_distance, POSITIVE_PX, " px"),
            (
                "support_edge_threshold",
                f64::from(self.support_edge_threshold),
                Interval::open_closed(0.0, f64::from(MAX_MIN_MAGNITUDE)),
                "",
            ),
        ];
        for (name, v, range, unit) in reals {
            range.check(WHO, name, v, unit)?;
        }
        if self.vanished_motion != f64::INFINITY {
            MARGIN_PX.check(WHO, "vanished_motion", self.vanished_motion, " px/frame (or inf)")?;
        }
        let counts = [
            ("min_points_per_line", self.min_points_per_line, 2, MAX_COUNT),
            ("lost_evidence", self.lost_evidence, 1, MAX_COUNT),
            ("refine_iterations", self.refine_iterations, 0, MAX_PASSES),
            ("search_after", self.search_after, 1, MAX_SEARCH_AFTER),
        ];
        for (name, v, lo, hi) in counts {
            check_count(WHO, name, v, lo, hi)?;
        }
        Ok(())
    }
}
