//! Parameters of the `blue` tracker (paper 002): the paper's where it gives
//! them, the extensions' (module doc of [`super`]) otherwise, each with its
//! range, checked by [`BlueParams::validate`].

use serde::{Deserialize, Serialize};

use crate::estimate::CornerCovariance;
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
    /// Range: positive, finite.
    pub edge_threshold: f32,
    /// Cap on the edge pixels sampled in the window (§2.3: 1500).
    /// Range: at least 1 (the backend lists at most
    /// [`crate::early::compaction::MAX_CAP`]).
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
    /// variance 3). Range: at least 3.
    pub min_points_per_line: usize,
    /// Floor on the standard deviation of eq. 4, px: pixel positions are
    /// quantised (1/√12 ≈ 0.29 px), so a perfectly straight run of pixels
    /// does not claim infinite precision. Range: positive, finite.
    pub min_point_std: f64,
    /// How eq. 6's Σ is formed ([`crate::estimate`] module doc). Range: any.
    pub corner_covariance: CornerCovariance,
    /// Smallest angle between the two lines of a corner, radians: eq. 5's
    /// intersection of nearly parallel lines is ill-conditioned.
    /// Range: (0, π/2].
    pub min_corner_angle: f64,
    /// Nominal range Z₀ of the model (§2.8), m; `None`: the init range.
    /// Range: positive, finite.
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
    /// equations eq. 9 needs for its three unknowns. Range: at least 2.
    pub min_corners: usize,
    /// Largest RMS of the consistency vector e of eq. 11 of a tracked frame, px.
    /// Range: positive, finite.
    pub max_inconsistency: f64,
    /// Corners whose consistency |e_j| (eq. 11) exceeds this are dropped
    /// one at a time, worst first, and eq. 9 solved again, while more than
    /// `min_corners` remain (extension: the paper only down-weights), px.
    /// Range: positive, finite.
    pub max_corner_inconsistency: f64,
    /// Floor on each |e_j| in eq. 12, px (a perfect fit does not make the
    /// location exact). 0.2: the corners of Sobel edges on rendered frames
    /// are good to a few tenths of a pixel; a floor of 0.05 px let one
    /// frame whose few corners happened to agree outweigh the motion
    /// models' memory (eq. 14 weights by 1/C_l), and its error was
    /// extrapolated into the next predictions. Range: positive, finite.
    pub min_feature_std: f64,
    /// Margin of the window of interest beyond the association distance, px.
    /// Range: [0, [`MAX_DISTANCE_PX`]].
    pub window_margin: f64,
    /// Prior standard deviation of the velocity at the start, px per frame:
    /// loose, it only makes the first predictions defined.
    /// Range: positive, finite.
    pub prior_speed: f64,
    /// Prior standard deviation of the acceleration at the start, px per
    /// frame²: a hand-held target reversing 20 px/frame within half a second
    /// accelerates ≈ 1.3 px/frame²; without this prior the second frame's
    /// prediction extrapolates a parabola through two samples.
    /// Range: positive, finite.
    pub prior_acceleration: f64,
    /// Lost frames during which the motion models keep extrapolating; after
    /// them the models restart at the last tracked location at rest (a
    /// parabola extrapolated for long runs away from where the target was).
    /// Range: any (0 restarts them at the first lost frame).
    pub coast_frames: usize,
}

/// Upper bound of the distances and margins, px: the association strips,
/// the window of interest and the alignment's (2d + 1)² vote grid grow
/// with them, and a frame is at most a few thousand pixels across.
pub const MAX_DISTANCE_PX: f64 = 1000.0;

/// Upper bound of [`BlueParams::refine_passes`] and
/// [`BlueParams::perspective_iterations`]: each is one more solve per frame,
/// and both converge within a handful.
pub const MAX_PASSES: usize = 100;

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
        let distances = [
            ("distance_tolerance", self.distance_tolerance),
            ("acquire_distance", self.acquire_distance),
            ("refine_distance", self.refine_distance),
            ("end_margin", self.end_margin),
            ("window_margin", self.window_margin),
        ];
        for (name, v) in distances {
            if v > MAX_DISTANCE_PX {
                return bad(format!("{name} is at most {MAX_DISTANCE_PX} px, got {v}"));
            }
        }
        for (name, v) in
            [("refine_passes", self.refine_passes), ("perspective_iterations", self.perspective_iterations)]
        {
            if v > MAX_PASSES {
                return bad(format!("{name} is at most {MAX_PASSES}, got {v}"));
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
