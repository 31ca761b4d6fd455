//! Trackers: host code that matches early-vision features to a model, fits,
//! verifies and predicts. One module per paper; all share the [`Tracker`]
//! trait and the per-frame [`FrameOutcome`].
//!
//! A tracker does no image processing itself: per frame it says where it
//! wants features ([`Tracker::window_of_interest`]), takes the feature lists
//! the backend computed there ([`Observations`]) and returns a
//! [`FrameOutcome`] (status, corners in model-vertex order, overlay and
//! diagnostic data), which [`FrameOutcome::to_result`] turns into the output
//! line of SPEC §4.

pub mod batch;
pub mod blue;
pub mod condensation;
pub mod lowe;
pub mod motion_edge;
pub mod run;
pub mod support;

pub use blue::{BlueParams, BlueTracker, TargetLocation, TargetPrediction};
pub use condensation::{CondensationParams, CondensationTracker};
pub use lowe::{LoweParams, LoweTracker};
pub use motion_edge::{LineFitMethod, MissingMeasurement, MotionEdgeParams, MotionEdgeTracker, Prediction};
pub use run::{
    RunSummary, TRACKERS, TrackOptions, make_tracker, read_config, track_frames, track_sequence, track_to_file,
    track_to_stdout,
};

use crate::backend::{FrameFeatures, FrameRequest};
use crate::early::window_energy::{WindowEnergies, WindowTemplate};
use crate::early::{Feature, Window};
use crate::io::formats::{FrameResult, Pose, Status};

/// The feature lists of one frame, as far as the backend computed them.
/// A tracker reads the lists it asked for and treats a missing one as empty.
#[derive(Clone, Copy, Debug, Default)]
pub struct Observations<'a> {
    /// Motion pixels with the edge orientation of the summed frames (000).
    pub motion: Option<&'a [Feature]>,
    /// Edge pixels (002).
    pub edges: Option<&'a [Feature]>,
    /// Zero crossings of the LoG (001).
    pub zero_crossings: Option<&'a [Feature]>,
    /// Filtered sample windows (004), when the request asked for them.
    pub window_features: Option<&'a [WindowTemplate]>,
    /// Energies of the sample windows (004), when the request asked for them.
    pub window_energies: Option<&'a WindowEnergies>,
}

impl<'a> From<&'a FrameFeatures> for Observations<'a> {
    /// The lists a backend handed back for one frame.
    fn from(features: &'a FrameFeatures) -> Self {
        Self {
            motion: features.motion.as_deref(),
            edges: features.edges.as_deref(),
            zero_crossings: features.zero_crossings.as_deref(),
            window_features: features.window_features.as_deref(),
            window_energies: features.window_energies.as_ref(),
        }
    }
}

/// [`Tracker::accept_frame_size`] of a tracker whose camera is `camera`.
pub(crate) fn camera_takes(
    camera: &crate::geometry::Camera,
    width: usize,
    height: usize,
) -> std::result::Result<(), String> {
    let (cw, ch) = (camera.width as usize, camera.height as usize);
    if (width, height) == (cw, ch) {
        Ok(())
    } else {
        Err(format!("{width}x{height}, but the camera's image is {cw}x{ch}"))
    }
}

/// Hold reported corners finite (SPEC §4): each corner of `corners` that is
/// not finite is replaced by its `last` reported position, and each finite
/// one becomes the new `last`. Returns the index of the first corner that
/// was not finite.
pub(crate) fn hold_finite_corners(corners: &mut [[f64; 2]], last: &mut [[f64; 2]]) -> Option<usize> {
    let mut first = None;
    for (i, (corner, last)) in corners.iter_mut().zip(last.iter_mut()).enumerate() {
        if corner[0].is_finite() && corner[1].is_finite() {
            *last = *corner;
        } else {
            first.get_or_insert(i);
            *corner = *last;
        }
    }
    first
}

/// `x.round() as i64` (halves away from zero), without a call into libm
/// where the fraction is exact (|x| < 2⁵²): truncate, then step by the
/// fraction, with comparisons rather than branches (the fraction of a vote's
/// cell coordinate is as likely above one half as below).
#[inline]
pub(crate) fn round_to_i64(x: f64) -> i64 {
    const EXACT_FRACTION: f64 = 4_503_599_627_370_496.0;
    if x.abs() < EXACT_FRACTION {
        let truncated = x as i64;
        let fraction = x - truncated as f64;
        truncated + i64::from(fraction >= 0.5) - i64::from(fraction <= -0.5)
    } else {
        x.round() as i64
    }
}

/// `reason` appended to a frame's lost reason, if it has one.
pub(crate) fn add_lost_reason(lost_reason: Option<String>, reason: String) -> String {
    match lost_reason {
        Some(first) => format!("{first}; {reason}"),
        None => reason,
    }
}

/// Where a tracker is in its cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Waiting for the image to confirm the initial model (000 §2: tracking
    /// begins when the operator's features match extracted ones).
    Acquiring,
    /// Locked on; measurements update the motion model.
    Tracking,
    /// Lost; predictions continue and re-acquisition is attempted.
    Lost,
}

/// Per-frame numbers for diagnosis and tests.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Diagnostics {
    /// Labelled feature points per model line (model edge order).
    pub points_per_line: Vec<usize>,
    /// Whether each model line was fitted this frame (enough points).
    pub line_fitted: Vec<bool>,
    /// Whether each corner was measured (at least one of its lines fitted).
    pub corner_measured: Vec<bool>,
    /// Largest distance of a measured corner from its prediction (000 eq. 9), px.
    pub max_corner_deviation: Option<f64>,
    /// Features that matched a model line's orientation but lay near no
    /// model line (evidence of the object elsewhere).
    pub unexplained_points: usize,
    /// Fraction of the reported contour's samples with edge support in the
    /// image ([`support`]), where the tracker checked it.
    pub contour_support: Option<f64>,
    /// The smallest supported fraction of one side of the reported contour,
    /// where the tracker checked it.
    pub side_support: Option<f64>,
    /// Why the frame is lost, when it is.
    pub lost_reason: Option<String>,
    /// The visible model segments with the spread of their predicted
    /// position, for overlays that draw them as 001's figures do (empty for
    /// trackers without them).
    pub bands: Vec<crate::io::overlay::EdgeBand>,
}

/// What a tracker reports for one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameOutcome {
    /// Frame index.
    pub frame: usize,
    /// Tracking or lost (the output contract's status).
    pub status: Status,
    /// The tracker's phase after this frame.
    pub phase: Phase,
    /// Image positions of the model vertices at this frame, model-vertex order.
    pub corners: Vec<[f64; 2]>,
    /// Pose, where the tracker has one.
    pub pose: Option<Pose>,
    /// Joint parameters, where the tracker has them.
    pub params: Option<Vec<f64>>,
    /// Covariance of the state, row-major, where the tracker has one.
    pub covariance: Option<Vec<f64>>,
    /// Labelled feature pixels per model line, for overlays (model edge order).
    pub labelled: Vec<Vec<(u32, u32)>>,
    /// Diagnostics.
    pub diagnostics: Diagnostics,
}

impl FrameOutcome {
    /// The output line of SPEC §4 for this frame, with its timing.
    ///
    /// Every number in it is finite (SPEC §4; serde would write NaN and ±∞
    /// as `null`, which no reader takes back). The trackers report finite
    /// numbers themselves; this is the last guard: a frame whose corners,
    /// pose or params are not all finite is reported `lost`, without its
    /// corners (an empty list) and without the offending pose or params; a
    /// covariance that is not all finite is left out; a non-finite `ms` is
    /// written as 0.
    #[must_use]
    pub fn to_result(&self, ms: f64) -> FrameResult {
        let finite = |values: &[f64]| values.iter().all(|v| v.is_finite());
        let corners_finite = self.corners.iter().all(|c| finite(c));
        let pose = self.pose.filter(Pose::is_finite);
        let params = self.params.clone().filter(|p| finite(p));
        let state_finite =
            corners_finite && pose.is_some() == self.pose.is_some() && params.is_some() == self.params.is_some();
        let status = if state_finite { self.status } else { Status::Lost };
        let lost_reason = match status {
            Status::Tracking => None,
            Status::Lost if state_finite => self.diagnostics.lost_reason.clone(),
            Status::Lost => Some("the tracker's state is not all finite numbers".to_string()),
        };
        let corners = if corners_finite { self.corners.clone() } else { Vec::new() };
        FrameResult {
            pose,
            params,
            covariance: self.covariance.clone().filter(|c| finite(c)),
            lost_reason,
            ms: if ms.is_finite() { ms } else { 0.0 },
            ..FrameResult::new(self.frame, status, corners)
        }
    }
}

/// What [`Tracker::track_or_widen`] did with a frame's features.
// Returned once per frame and taken apart at once: boxing the outcome
// would only add an allocation per frame.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Tracked {
    /// The frame's outcome.
    Outcome(FrameOutcome),
    /// The window of interest was widened: the frame's features are needed
    /// again, from the tracker's new request.
    Widened,
}

/// A model-based tracker driven frame by frame.
pub trait Tracker {
    /// The `--tracker` name (SPEC §3).
    fn name(&self) -> &'static str;

    /// Where the next frame's features are needed, clipped to the image.
    fn window_of_interest(&self, width: usize, height: usize) -> Window;

    /// What early vision must compute for the next frame of a
    /// `width`×`height` sequence: the feature lists [`Tracker::track`] reads,
    /// inside [`Tracker::window_of_interest`], with the tracker's own parameters.
    fn request(&self, width: usize, height: usize) -> FrameRequest;

    /// Take the features of frame `frame` and report the frame's outcome.
    fn track(&mut self, frame: usize, observations: &Observations<'_>) -> FrameOutcome;

    /// Like [`Tracker::track`], but a tracker whose window of interest was
    /// narrower than this frame turns out to need may instead widen it and
    /// answer [`Tracked::Widened`]: the caller then runs early vision on
    /// the same frame again, with the tracker's new
    /// [`request`](Tracker::request), and hands those features to
    /// [`Tracker::track`]. The per-frame loop ([`run::track_step`]) does
    /// this. The backend sees the frame twice, so a tracker that widens
    /// must not ask for the motion stage (the second pass would difference
    /// the frame against itself). The default never widens.
    fn track_or_widen(&mut self, frame: usize, observations: &Observations<'_>) -> Tracked {
        Tracked::Outcome(self.track(frame, observations))
    }

    /// `Err` with the reason in words when this tracker cannot take frames
    /// of `width`×`height`: a tracker with a camera takes the camera's image
    /// size (the intrinsics hold for that size only), one without takes the
    /// size of the first frame it was given (its corners and motion are in
    /// that frame's pixels). [`run::track_step`] asks before each frame and
    /// refuses the frame with [`crate::Error::Size`]. The default takes any.
    fn accept_frame_size(&mut self, width: usize, height: usize) -> std::result::Result<(), String> {
        let _ = (width, height);
        Ok(())
    }

    /// Whether the tracker reads colour (its requests have sample windows
    /// that compare hue): colour frames then reach the backend as colour.
    /// Grey otherwise (the default).
    fn wants_colour(&self) -> bool {
        false
    }

    /// The extra keys of the last frame's output line (none by default).
    fn extras(&self) -> FrameExtras {
        FrameExtras::default()
    }
}

/// Numbers a tracker reports beyond the common ones (SPEC §4 lets trackers
/// add keys; readers ignore them).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameExtras {
    /// The velocity screw estimate (T_x, T_y, T_z, ω_x, ω_y, ω_z) over the
    /// last frame interval (Condensation).
    pub velocity_screw: Option<[f64; 6]>,
    /// The effective sample size of a particle filter's weights.
    pub effective_sample_size: Option<f64>,
    /// Search branches tried on the frame (Lowe's best-first search).
    pub search_branches: Option<usize>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rounding short cut agrees with `f64::round` at halves, just
    /// below them, at the exact-fraction bound and beyond.
    #[test]
    fn round_to_i64_is_round_as_i64() {
        let below = |x: f64| f64::from_bits(x.to_bits() - 1);
        let mut values = vec![0.0, -0.0, 0.5, -0.5, below(0.5), -below(0.5), 2.5, -2.5, 1e15 + 0.5, -1e15 - 0.5];
        values.extend([4_503_599_627_370_496.0, below(4_503_599_627_370_496.0), 1e19, -1e19, f64::NAN]);
        values.extend((-3000..=3000).map(|k| f64::from(k) * 0.25 + f64::from(k % 7) * 1e-13));
        for x in values {
            assert_eq!(round_to_i64(x), x.round() as i64, "x = {x:e}");
        }
    }
}
