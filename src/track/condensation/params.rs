//! Parameters of the `condensation` tracker (paper 004): the paper's where
//! it gives them, documented choices otherwise, each with its range, checked
//! by [`CondensationParams::validate`].

use serde::{Deserialize, Serialize};

use crate::bounds::{Interval, check_count};
use crate::early::window_energy::{MAX_SIDE_LOG2, MAX_WINDOWS, WindowEnergyParams};
use crate::io::formats::MAX_CAMERA_MOTION;
use crate::{Error, Result};

/// Largest spread or diffusion, px.
pub const MAX_SPREAD_PX: f64 = 100.0;
/// Largest RMS residual threshold, grey levels.
pub const MAX_RESIDUAL: f64 = 255.0;

/// Which sample a frame's estimate is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Estimate {
    /// The highest-weighted sample, s^max of eq. 19 (004 Fig. 3 outlines the
    /// best match window).
    Best,
    /// The weighted mean of the samples (eq. 28's weights).
    WeightedMean,
}

/// Parameters of the Condensation tracker (paper 004), all with defaults, so
/// a `--config` TOML file may set any subset (unknown keys are refused).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CondensationParams {
    /// N, the number of samples (004 §IV: n = 200).
    /// Range: 1 ..= [`MAX_WINDOWS`].
    pub samples: usize,
    /// L: sample windows are warped to 2^L × 2^L (004 §IV: 64 × 64, L = 6).
    /// Range: 1 ..= [`MAX_SIDE_LOG2`].
    pub window_level: u32,
    /// k: the CPF level the energy compares, 2^k × 2^k (Fig. 2 step 2;
    /// Fig. 4 finds every level from 1 to 6 discriminates). 4 (16 × 16)
    /// keeps sub-pixel detail of a 64 px window at a sixteenth of the cost
    /// of the energy's comparison at full resolution. Range: 1 ..= L.
    pub cpf_level: u32,
    /// Spread of the initial sample set around the known first motion
    /// (§III-B.3: N(r_i, Σ)), as the RMS corner displacement one standard
    /// deviation of each screw component causes alone, px (the paper: "a
    /// large variance in x and y"; no number). Range: [0, [`MAX_SPREAD_PX`]].
    pub initial_spread_px: f64,
    /// Brownian diffusion per frame (§III-B.1's random walk), in the same
    /// units as `initial_spread_px`: the RMS corner displacement of one
    /// standard deviation of each component, px. Range: [0, [`MAX_SPREAD_PX`]].
    pub diffusion_px: f64,
    /// Weights of the six components (T_x, T_y, T_z, ω_x, ω_y, ω_z) in the
    /// spread and the diffusion; 0 freezes a component (004 §IV sets the
    /// variances of T_z and the rotations to zero for its pure translation).
    /// Range: each in [0, 10].
    pub component_weights: [f64; 6],
    /// The diagonal of the gain K of eq. 19, `s ← s − K s^max`: how far the
    /// reference window moves to the best sample each frame. 1: all the way.
    /// Range: each in [0, 1].
    pub gain: [f64; 6],
    /// The known first camera motion `[tx, ty, tz, rx, ry, rz]` (camera 1 in
    /// the frame of camera 0, m and rad); overrides `init.json`'s
    /// `camera_motion`. Default: none (then `init.json`'s, or zero).
    /// Range: each in [−1000, 1000] ([`MAX_CAMERA_MOTION`], as in
    /// `init.json`).
    pub camera_motion: Option<[f64; 6]>,
    /// Which sample is the frame's estimate.
    pub estimate: Estimate,
    /// A frame is `tracking` only when the best window's RMS intensity
    /// residual against the template (bounded from its energy, see the
    /// module documentation) is at most this, grey levels. On
    /// `textured-plane` (noise σ = 1.5 per channel) matched windows give
    /// about 2 levels and windows of another texture about 17.
    /// Range: (0, [`MAX_RESIDUAL`]].
    pub max_residual: f64,
    /// Spread of the search for a lost window on the first lost frame, in
    /// the units of `initial_spread_px` (module documentation, "Searching
    /// while lost"); 0 turns the search off, and lost frames then update the
    /// samples as tracking ones do (the paper's Fig. 2 has no loss).
    /// Range: [0, [`MAX_SPREAD_PX`]].
    pub search_spread_px: f64,
    /// Largest spread the search widens to, and the spread of its samples
    /// around where the last tracked motion carries the window, px.
    /// Range: [`search_spread_px`](Self::search_spread_px) ..=
    /// [`MAX_SPREAD_PX`], above 0 while the search is on.
    pub max_search_spread_px: f64,
    /// The search moves to its best sample (and narrows) only when that
    /// sample's residual is below this fraction of the median residual of
    /// the frame's samples: evidence of the window, not the luck of the
    /// draw among mismatches. Range: (0, 1].
    pub search_evidence_ratio: f64,
    /// Seed of the sampling. Range: any.
    pub seed: u64,
}

impl Default for CondensationParams {
    fn default() -> Self {
        let window = WindowEnergyParams::default();
        Self {
            samples: 200,
            window_level: window.side_log2,
            cpf_level: window.cpf_log2,
            initial_spread_px: 1.0,
            diffusion_px: 0.3,
            component_weights: [1.0; 6],
            gain: [1.0; 6],
            camera_motion: None,
            estimate: Estimate::Best,
            max_residual: 8.0,
            search_spread_px: 4.0,
            max_search_spread_px: 32.0,
            search_evidence_ratio: 0.75,
            seed: 0x0c0d_e45e,
        }
    }
}

impl CondensationParams {
    /// The window energy's sizes.
    #[must_use]
    pub fn window(&self) -> WindowEnergyParams {
        WindowEnergyParams { side_log2: self.window_level, cpf_log2: self.cpf_level }
    }

    /// Error naming the first parameter out of its range.
    pub fn validate(&self) -> Result<()> {
        const WHO: &str = "condensation";
        check_count(WHO, "samples", self.samples, 1, MAX_WINDOWS)?;
        check_count(WHO, "window_level", self.window_level as usize, 1, MAX_SIDE_LOG2 as usize)?;
        check_count(WHO, "cpf_level", self.cpf_level as usize, 1, self.window_level as usize)?;
        let spread = Interval::closed(0.0, MAX_SPREAD_PX);
        spread.check(WHO, "initial_spread_px", self.initial_spread_px, " px")?;
        spread.check(WHO, "diffusion_px", self.diffusion_px, " px")?;
        spread.check(WHO, "search_spread_px", self.search_spread_px, " px")?;
        spread.check(WHO, "max_search_spread_px", self.max_search_spread_px, " px")?;
        if self.search_spread_px > self.max_search_spread_px {
            return Err(Error::Parameter(format!(
                "condensation: search_spread_px {} exceeds max_search_spread_px {}",
                self.search_spread_px, self.max_search_spread_px
            )));
        }
        Interval::open_closed(0.0, 1.0).check(WHO, "search_evidence_ratio", self.search_evidence_ratio, "")?;
        for w in self.component_weights {
            Interval::closed(0.0, 10.0).check(WHO, "component_weights", w, "")?;
        }
        for k in self.gain {
            Interval::closed(0.0, 1.0).check(WHO, "gain", k, "")?;
        }
        if let Some(m) = self.camera_motion {
            for v in m {
                Interval::closed(-MAX_CAMERA_MOTION, MAX_CAMERA_MOTION).check(WHO, "camera_motion", v, "")?;
            }
        }
        Interval::open_closed(0.0, MAX_RESIDUAL).check(WHO, "max_residual", self.max_residual, " grey levels")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The search's spreads are checked: within [0, MAX_SPREAD_PX], the
    /// first no larger than the largest; the evidence ratio in (0, 1].
    #[test]
    fn search_parameters_are_checked() {
        let ok = CondensationParams::default();
        assert!(ok.validate().is_ok());
        let off = CondensationParams { search_spread_px: 0.0, max_search_spread_px: 0.0, ..ok.clone() };
        assert!(off.validate().is_ok());
        for (bad, needle) in [
            (CondensationParams { search_spread_px: -1.0, ..ok.clone() }, "search_spread_px"),
            (CondensationParams { max_search_spread_px: 1e9, ..ok.clone() }, "max_search_spread_px"),
            (CondensationParams { search_spread_px: 8.0, max_search_spread_px: 4.0, ..ok.clone() }, "exceeds"),
            (CondensationParams { search_evidence_ratio: 0.0, ..ok.clone() }, "search_evidence_ratio"),
            (CondensationParams { search_evidence_ratio: 1.5, ..ok.clone() }, "search_evidence_ratio"),
            (CondensationParams { search_evidence_ratio: f64::NAN, ..ok.clone() }, "search_evidence_ratio"),
        ] {
            let e = bad.validate().expect_err(needle).to_string();
            assert!(e.contains(needle), "{e}");
        }
    }
}
