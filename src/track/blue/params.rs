//! Parameters of the `blue` tracker (paper 002): the paper's where it gives
//! them, the extensions' (module doc of [`super`]) otherwise, each with its
//! range, checked by [`BlueParams::validate`].

use serde::{Deserialize, Serialize};

use crate::Result;
use crate::bounds::{Interval, check_count};
use crate::early::compaction::MAX_CAP;
use crate::estimate::CornerCovariance;

/// Parameters of the blue tracker (paper 002), all with defaults, so a
/// `--config` TOML file may set any subset (unknown keys are refused).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BlueParams {
    /// Sobel 3×3 magnitude threshold of the binary edge image (§2.3; for the
    /// backend; weaker pixels handed over are ignored). Unnormalised Sobel on
    /// 0..255 grey levels gives 4·C on a step of contrast C; 80 keeps steps
    /// of 20 grey levels and more. The paper gives no value.
    /// Range: (0, [`MAX_EDGE_THRESHOLD`]].
    pub edge_threshold: f32,
    /// Cap on the edge pixels sampled in the window (§2.3: 1500).
    /// Range: 1 ..= [`MAX_COUNT`] (the backend lists at most
    /// [`MAX_CAP`] pixels).
    pub max_edge_points: usize,
    /// Seed of the backend's random subsample. Range: any.
    pub sample_seed: u64,
    /// Orientation agreement of §2.4, radians (paper: no value). 10°: Sobel
    /// orientations of a sharp edge are good to a few degrees and the
    /// target's orientation is fixed, so its edges never turn; a random
    /// clutter orientation passes with probability 1/9, and a bookshelf's
    /// vertical edges stay out of target edges tilted more than 10° (15°
    /// let an upright crossing a 7°-tilted edge capture it in the tests).
    /// Range: (0, π/2].
    pub angle_tolerance: f64,
    /// Spatial proximity of §2.4 while tracking, px.
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub distance_tolerance: f64,
    /// Spatial proximity while acquiring or lost, px: must exceed a frame's
    /// motion before velocity is known (1.2 rad/s at f = 500 px, 30 Hz: 20 px).
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub acquire_distance: f64,
    /// Proximity of the re-association around the BLUE (step 7), px: wide
    /// enough for a first estimate biased by clutter to still see the true
    /// edge, narrow enough to drop clutter further out.
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub refine_distance: f64,
    /// Re-association passes (step 7); 0: the paper's single pass. 3 lets an
    /// estimate pulled by clutter in the wide first strips walk back.
    /// Range: 0 ..= [`MAX_PASSES`].
    pub refine_passes: usize,
    /// Coarse alignment before association (step 1, extension): the image
    /// shift of the predicted model within ± the association distance that
    /// the most compatible edge pixels support jointly (a Hough vote over all
    /// visible lines), after which the first association uses the narrow
    /// [`BlueParams::refine_distance`]. Off: the paper's single association
    /// around the prediction with the wide distance. Range: either.
    pub align: bool,
    /// Pixels whose foot lies within this distance of a segment end are not
    /// associated, px. 2: the 3×3 Sobel blurs the two lines of a corner into
    /// each other over about a pixel, whatever the target's size; a margin
    /// of 4 px left a 13-px model edge of the target at 5 m (26 px wide) too
    /// few pixels to fit, and those corners were never measured.
    /// Range: [0, [`MAX_DISTANCE_PX`]].
    pub end_margin: f64,
    /// Fewest associated pixels to fit a line (eq. 1–3 need 2; eq. 4's
    /// variance 3). Range: 3 ..= [`MAX_COUNT`].
    pub min_points_per_line: usize,
    /// Floor on the standard deviation of eq. 4, px: pixel positions are
    /// quantised (1/√12 ≈ 0.29 px), so a perfectly straight run of pixels
    /// does not claim infinite precision. Range: (0, [`MAX_DISTANCE_PX`]].
    pub min_point_std: f64,
    /// How eq. 6's Σ is formed ([`crate::estimate`] module doc). Range: any.
    pub corner_covariance: CornerCovariance,
    /// Smallest angle between the two lines of a corner, radians: eq. 5's
    /// intersection of nearly parallel lines is ill-conditioned.
    /// Range: (0, π/2].
    pub min_corner_angle: f64,
    /// Nominal range Z₀ of the model (§2.8), m; `None`: the init range.
    /// Range: (0, [`MAX_RANGE_M`]].
    pub nominal_range: Option<f64>,
    /// The general (perspective) form of eq. 7 ([`super`] module doc); off:
    /// the paper's affine form. Range: either.
    pub perspective_correction: bool,
    /// Fixed-point iterations of eq. 9 for the perspective correction.
    /// Range: 0 ..= [`MAX_PASSES`].
    pub perspective_iterations: usize,
    /// Exponential decay λ of eq. 14, 0 < λ < 1. The paper gives no value.
    /// 0.6 (α-β-γ gains of eq. 18: α = 0.784, β = 0.384, γ = 0.128): the
    /// one-step prediction of a 2nd-order fit lags a changing acceleration
    /// (jerk j) by ≈ j/γ; on a target sweeping ±180 px at 20 px/frame peak
    /// (1.2 rad/s, reversing every 28 frames) the largest prediction error
    /// is 3.6 px at λ = 0.6, 7.9 px at 0.7 and 22 px at 0.8, and the
    /// association distance must cover it. Measurement noise of a BLUE from
    /// hundreds of edge pixels is ≈ 0.1 px, so the short memory costs little.
    /// Range: (0, 1).
    pub lambda: f64,
    /// Fewest corners of a tracked frame: two corners give the four
    /// equations eq. 9 needs for its three unknowns. Range: 2 ..= [`MAX_COUNT`].
    pub min_corners: usize,
    /// Largest RMS of the consistency vector e of eq. 11 of a tracked frame, px.
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub max_inconsistency: f64,
    /// Corners whose consistency |e_j| (eq. 11) exceeds this are dropped
    /// one at a time, worst first, and eq. 9 solved again, while more than
    /// `min_corners` remain (extension: the paper only down-weights), px.
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub max_corner_inconsistency: f64,
    /// Floor on each |e_j| in eq. 12, px (a perfect fit does not make the
    /// location exact). 0.2: the corners of Sobel edges on rendered frames
    /// are good to a few tenths of a pixel; a floor of 0.05 px let one
    /// frame whose few corners happened to agree outweigh the motion
    /// models' memory (eq. 14 weights by 1/C_l), and its error was
    /// extrapolated into the next predictions. Range: (0, [`MAX_DISTANCE_PX`]].
    pub min_feature_std: f64,
    /// Margin of the window of interest beyond the association distance, px.
    /// Range: [0, [`MAX_DISTANCE_PX`]].
    pub window_margin: f64,
    /// Prior standard deviation of the velocity at the start, px per frame:
    /// loose, it only makes the first predictions defined.
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub prior_speed: f64,
    /// Prior standard deviation of the acceleration at the start, px per
    /// frame²: a hand-held target reversing 20 px/frame within half a second
    /// accelerates ≈ 1.3 px/frame²; without this prior the second frame's
    /// prediction extrapolates a parabola through two samples.
    /// Range: (0, [`MAX_DISTANCE_PX`]].
    pub prior_acceleration: f64,
    /// Lost frames during which the motion models keep extrapolating; after
    /// them the models restart at the last tracked location at rest (a
    /// parabola extrapolated for long runs away from where the target was).
    /// Range: 0 ..= [`MAX_COAST_FRAMES`] (0 restarts them at the first lost frame).
    pub coast_frames: usize,
    /// Verify every estimate against the image before the frame is reported
    /// `tracking` (module doc, "Verification"); off: the paper's method,
    /// where only the corner count, eq. 9 and the consistency of eq. 11 lose
    /// the track. Range: either.
    pub verify: bool,
    /// Smallest excess of contour support of a tracked frame: the supported
    /// fraction of the visible outline at the estimate less the larger one
    /// of the outline shifted ±(2·`support_distance` + 1) px across itself
    /// (module doc, "Verification"). The edge list is a random subsample
    /// (`max_edge_points`), so an outline on the target is only partly
    /// supported; measured on target3dof (bookshelf, seed 0): 0.29–0.5 on
    /// frames within 5 px of the truth (0.29 with 30 % of the target
    /// hidden), at most 0.24 on frames locked on the bookshelf (1.6–3 rad/s).
    /// Range: [0, 1].
    pub min_support: f64,
    /// After a tracked frame, an estimate whose outline stands out less
    /// than the prediction's outline on the same frame's edges, by more
    /// than this excess of contour support (see
    /// [`BlueParams::min_support`]), is refused (extension, [`super`]
    /// module doc, "Verification"): the fit moved the model from where its
    /// outline stood out to where it stands out less, so it took in
    /// something other than the target. Over the 69 held-out runs of
    /// `benches/held_out.sh` (seeds 0–12 and 31–40) the prediction stood out
    /// more by at most 0.157 on the 20 692 frames tracked within 5 px, and
    /// by 0.264 on a frame fitted at 0.86 times the target's range. Range:
    /// [0, 2]; 2 never refuses.
    pub max_excess_below_prediction: f64,
    /// Largest distance across the contour of an edge pixel that supports a
    /// contour sample in the verification, px. Range: (0, [`MAX_DISTANCE_PX`]].
    pub support_distance: f64,
    /// With `verify`, lost frames in a row after which the tracker searches
    /// the whole image: the window of interest opens to the full frame (its
    /// edge cap grown in proportion) and the coarse alignment's vote over
    /// every image shift, at the last tracked range and ranges around it,
    /// places the model before the frame is measured (module doc,
    /// "Verification").
    /// Range: 1 ..= [`MAX_SEARCH_AFTER`].
    pub search_after: usize,
    /// [`BlueParams::min_support`] of a frame measured where the
    /// whole-image search put the model: the search picks the best of many
    /// places, so chance support is higher there than around a prediction.
    /// Range: [0, 1].
    pub search_min_support: f64,
    /// Least fraction of the visible model lines that a frame measured
    /// where the whole-image search put the model must fit (step 3): on
    /// clutter that stands out like the target, a wrong place fits only
    /// some of the target's lines. Range: [0, 1].
    pub search_min_fitted: f64,
    /// Reversal hypotheses (extension, [`super`] module doc, "Abrupt
    /// reversals"): after a tracked frame at which the target moved at least
    /// half [`BlueParams::distance_tolerance`] per frame, measure the frame
    /// also around the last tracked location turned back by one frame's
    /// velocity and around it at rest (within that velocity, at most
    /// [`BlueParams::acquire_distance`]),
    /// keep the estimate whose outline stands out most among those passing
    /// the checks, and restart the motion models from the last tracked frame
    /// when it (or the prediction's own estimate) lies off the prediction.
    /// A hypothesis whose outline reaches beyond the window of interest by
    /// enough to change that choice gets a second look at the frame in a
    /// window grown to hold it (through `Tracker::track_or_widen`).
    /// Off: only the prediction.
    /// Range: either.
    pub reversal_hypotheses: bool,
}

/// Upper bound of the distances, margins and pixel-sized tolerances and
/// priors, px: the association strips, the window of interest and the
/// alignment's (2d + 1)² vote grid grow with them (at 1000 px a frame takes
/// a fraction of a second on the CPU), and a frame is at most a few
/// thousand pixels across.
pub const MAX_DISTANCE_PX: f64 = 1000.0;

/// Upper bound of [`BlueParams::refine_passes`] and
/// [`BlueParams::perspective_iterations`]: each is one more solve per frame,
/// and both converge within a handful.
pub const MAX_PASSES: usize = 100;

/// Upper bound of [`BlueParams::edge_threshold`]: the unnormalised 3×3 Sobel
/// magnitude on 0..255 grey levels is at most 4·255·√2 ≈ 1442.5, so a higher
/// threshold keeps no pixel.
pub const MAX_EDGE_THRESHOLD: f32 = 1443.0;

/// Upper bound of the pixel counts [`BlueParams::max_edge_points`] and
/// [`BlueParams::min_points_per_line`], and of [`BlueParams::min_corners`]:
/// the backend lists at most [`MAX_CAP`] pixels a frame, so no line (and no
/// model) can have more.
pub const MAX_COUNT: usize = MAX_CAP as usize;

/// Upper bound of [`BlueParams::nominal_range`], m: Z₀ only scales the
/// model's image size (§2.8), and a target a thousand kilometres away is not
/// one a camera tracks by its edges; the bound keeps products of Z₀ with
/// focal lengths and image coordinates far from overflow.
pub const MAX_RANGE_M: f64 = 1e6;

/// Upper bound of [`BlueParams::search_after`], frames (an hour at 30 Hz).
pub const MAX_SEARCH_AFTER: usize = 108_000;

/// Upper bound of [`BlueParams::coast_frames`]: extrapolating the motion
/// models for longer than about half a minute at 30 Hz only carries the
/// prediction away from where the target was.
pub const MAX_COAST_FRAMES: usize = 1000;

/// Range of the angles [`BlueParams::angle_tolerance`] and
/// [`BlueParams::min_corner_angle`], radians.
const ANGLE: Interval = Interval::open_closed(0.0, std::f64::consts::FRAC_PI_2);
/// Range of the positive pixel-sized parameters, px.
const POSITIVE_PX: Interval = Interval::open_closed(0.0, MAX_DISTANCE_PX);
/// Range of the margins, px.
const MARGIN_PX: Interval = Interval::closed(0.0, MAX_DISTANCE_PX);

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
            verify: true,
            min_support: 0.26,
            max_excess_below_prediction: 0.2,
            support_distance: 3.0,
            search_after: 3,
            search_min_support: 0.35,
            search_min_fitted: 0.3,
            reversal_hypotheses: true,
        }
    }
}

impl BlueParams {
    /// Check every parameter against its documented range
    /// ([`crate::Error::Parameter`] naming the first bad one and its range).
    pub fn validate(&self) -> Result<()> {
        const WHO: &str = "blue";
        let reals = [
            (
                "edge_threshold",
                f64::from(self.edge_threshold),
                Interval::open_closed(0.0, f64::from(MAX_EDGE_THRESHOLD)),
                "",
            ),
            ("angle_tolerance", self.angle_tolerance, ANGLE, " radians"),
            ("distance_tolerance", self.distance_tolerance, POSITIVE_PX, " px"),
            ("acquire_distance", self.acquire_distance, POSITIVE_PX, " px"),
            ("refine_distance", self.refine_distance, POSITIVE_PX, " px"),
            ("end_margin", self.end_margin, MARGIN_PX, " px"),
            ("min_point_std", self.min_point_std, POSITIVE_PX, " px"),
            ("min_corner_angle", self.min_corner_angle, ANGLE, " radians"),
            ("lambda", self.lambda, Interval::open(0.0, 1.0), ""),
            ("max_inconsistency", self.max_inconsistency, POSITIVE_PX, " px"),
            ("max_corner_inconsistency", self.max_corner_inconsistency, POSITIVE_PX, " px"),
            ("min_feature_std", self.min_feature_std, POSITIVE_PX, " px"),
            ("window_margin", self.window_margin, MARGIN_PX, " px"),
            ("prior_speed", self.prior_speed, POSITIVE_PX, " px/frame"),
            ("prior_acceleration", self.prior_acceleration, POSITIVE_PX, " px/frame²"),
            ("support_distance", self.support_distance, POSITIVE_PX, " px"),
            ("min_support", self.min_support, Interval::closed(0.0, 1.0), ""),
            ("max_excess_below_prediction", self.max_excess_below_prediction, Interval::closed(0.0, 2.0), ""),
            ("search_min_support", self.search_min_support, Interval::closed(0.0, 1.0), ""),
            ("search_min_fitted", self.search_min_fitted, Interval::closed(0.0, 1.0), ""),
        ];
        for (name, v, range, unit) in reals {
            range.check(WHO, name, v, unit)?;
        }
        if let Some(z) = self.nominal_range {
            Interval::open_closed(0.0, MAX_RANGE_M).check(WHO, "nominal_range", z, " m")?;
        }
        let counts = [
            ("max_edge_points", self.max_edge_points, 1, MAX_COUNT),
            ("refine_passes", self.refine_passes, 0, MAX_PASSES),
            ("min_points_per_line", self.min_points_per_line, 3, MAX_COUNT),
            ("perspective_iterations", self.perspective_iterations, 0, MAX_PASSES),
            ("min_corners", self.min_corners, 2, MAX_COUNT),
            ("coast_frames", self.coast_frames, 0, MAX_COAST_FRAMES),
            ("search_after", self.search_after, 1, MAX_SEARCH_AFTER),
        ];
        for (name, v, lo, hi) in counts {
            check_count(WHO, name, v, lo, hi)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_validate() {
        assert!(BlueParams::default().validate().is_ok());
        let bad = BlueParams { lambda: 1.0, ..BlueParams::default() };
        assert!(bad.validate().is_err());
        let bad = BlueParams { min_corners: 1, ..BlueParams::default() };
        assert!(bad.validate().is_err());
        let bad = BlueParams { acquire_distance: 2.0 * MAX_DISTANCE_PX, ..BlueParams::default() };
        assert!(bad.validate().is_err());
        let bad = BlueParams { refine_passes: MAX_PASSES + 1, ..BlueParams::default() };
        assert!(bad.validate().is_err());
        let bad = BlueParams { nominal_range: Some(0.0), ..BlueParams::default() };
        assert!(bad.validate().is_err());
        let parsed: BlueParams = toml::from_str("lambda = 0.7\nrefine_passes = 0").expect("toml");
        assert_eq!(parsed.lambda, 0.7);
        assert_eq!(parsed.max_edge_points, 1500);
        assert!(toml::from_str::<BlueParams>("lamda = 0.7").is_err(), "unknown keys refused");
    }
}
