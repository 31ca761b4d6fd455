//! Double exponential smoothing (Brown's linear exponential smoothing) and
//! its forecast, paper 000 eq. 10–12 after Montgomery, Johnson & Gardiner
//! \[17\]. One smoother per tracked quantity; `N` coordinates are smoothed
//! independently (000 filters "each corner independently of the others").
//!
//! With smoothing constant 0 < α < 1 and β = 1 − α:
//! - eq. 10, first smoothing: S1_t = α·x_t + β·S1_{t−1}
//! - eq. 11, second smoothing: S2_t = α·S1_t + β·S2_{t−1}
//! - level a_t = 2·S1_t − S2_t, trend (per step) b_t = α/β·(S1_t − S2_t)
//! - eq. 12, forecast: x̂_{t+τ} = a_t + τ·b_t.
//!
//! Eq. 12 is garbled in the paper's text; for τ = 1 the form above expands to
//! x̂_{t+1} = (2 + α/β)·S1_t − (1 + α/β)·S2_t, which is exactly the legible
//! coefficients of the paper's eq. 12 (its second term is printed as
//! "(x, y)_t"; it must be the doubly smoothed (x, y)''_t, otherwise a constant
//! input would not forecast itself). That is the form implemented here.
//!
//! Initial values: the paper sets S1 and S2 to the initial position
//! ([`DoubleExponentialSmoother::new`], trend 0). Montgomery's textbook
//! start from a known level a_0 and trend b_0 is S1 = a_0 − (β/α)·b_0,
//! S2 = a_0 − 2(β/α)·b_0 ([`DoubleExponentialSmoother::with_level_and_trend`]).

use crate::{Error, Result};

/// Brown's double exponential smoother of an `N`-vector (000 eq. 10–12).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubleExponentialSmoother<const N: usize> {
    alpha: f64,
    first: [f64; N],
    second: [f64; N],
}

impl<const N: usize> DoubleExponentialSmoother<N> {
    /// A smoother whose two smoothed values both start at `initial` (000:
    /// "set to the position of the corner when tracking is initially begun"),
    /// i.e. level `initial` and trend 0. Needs 0 < α < 1.
    pub fn new(alpha: f64, initial: [f64; N]) -> Result<Self> {
        validate_alpha(alpha)?;
        Ok(Self { alpha, first: initial, second: initial })
    }

    /// A smoother starting from a known level and trend per step
    /// (Montgomery et al.: S1 = a − (β/α)·b, S2 = a − 2(β/α)·b).
    pub fn with_level_and_trend(alpha: f64, level: [f64; N], trend: [f64; N]) -> Result<Self> {
        validate_alpha(alpha)?;
        let lag = (1.0 - alpha) / alpha;
        let first = std::array::from_fn(|i| level[i] - lag * trend[i]);
        let second = std::array::from_fn(|i| level[i] - 2.0 * lag * trend[i]);
        Ok(Self { alpha, first, second })
    }

    /// Take the observation `x` of this step (eq. 10 then eq. 11).
    pub fn update(&mut self, x: [f64; N]) {
        let (alpha, beta) = (self.alpha, 1.0 - self.alpha);
        for i in 0..N {
            self.first[i] = alpha * x[i] + beta * self.first[i]; // eq. 10
            self.second[i] = alpha * self.first[i] + beta * self.second[i]; // eq. 11
        }
    }

    /// Current level a_t = 2·S1_t − S2_t (the smoothed value at this step).
    #[must_use]
    pub fn level(&self) -> [f64; N] {
        std::array::from_fn(|i| 2.0 * self.first[i] - self.second[i])
    }

    /// Current trend b_t = α/(1 − α)·(S1_t − S2_t), change per step.
    #[must_use]
    pub fn trend(&self) -> [f64; N] {
        let gain = self.alpha / (1.0 - self.alpha);
        std::array::from_fn(|i| gain * (self.first[i] - self.second[i]))
    }

    /// Forecast τ steps ahead, x̂_{t+τ} = a_t + τ·b_t (eq. 12 for τ = 1;
    /// fractional τ interpolates the fitted line).
    #[must_use]
    pub fn forecast(&self, tau: f64) -> [f64; N] {
        let (level, trend) = (self.level(), self.trend());
        std::array::from_fn(|i| level[i] + tau * trend[i])
    }

    /// The singly and doubly smoothed values (S1_t, S2_t).
    #[must_use]
    pub fn smoothed(&self) -> ([f64; N], [f64; N]) {
        (self.first, self.second)
    }

    /// The smoothing constant α.
    #[must_use]
    pub fn alpha(&self) -> f64 {
        self.alpha
    }
}

/// 0 < α < 1 (α = 1 would divide by zero in the trend).
fn validate_alpha(alpha: f64) -> Result<()> {
    if alpha > 0.0 && alpha < 1.0 {
        Ok(())
    } else {
        Err(Error::Parameter(format!("smoothing constant alpha must be in (0, 1), got {alpha}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_input_forecasts_itself() {
        let mut s = DoubleExponentialSmoother::new(0.2, [7.0, -3.0]).expect("alpha");
        for _ in 0..50 {
            s.update([7.0, -3.0]);
            let f = s.forecast(1.0);
            assert!((f[0] - 7.0).abs() < 1e-12 && (f[1] + 3.0).abs() < 1e-12, "{f:?}");
        }
        assert!(s.trend()[0].abs() < 1e-12);
    }

    #[test]
    fn ramp_is_forecast_exactly_after_warm_up() {
        // x_t = 10 + 3t, started the paper's way (S1 = S2 = x_0, trend 0).
        let mut s = DoubleExponentialSmoother::new(0.2, [10.0]).expect("alpha");
        let mut errors = Vec::new();
        for t in 1..=80 {
            s.update([10.0 + 3.0 * t as f64]);
            errors.push((s.forecast(1.0)[0] - (10.0 + 3.0 * (t + 1) as f64)).abs());
        }
        // The zero initial trend costs a transient, then the ramp is recovered.
        assert!(errors[0] > 1.0, "the paper's start has no trend: {}", errors[0]);
        assert!(errors[79] < 1e-4, "forecast error after warm-up {}", errors[79]);
        assert!((s.trend()[0] - 3.0).abs() < 1e-4, "trend {}", s.trend()[0]);
        // τ steps ahead too.
        assert!((s.forecast(2.5)[0] - (10.0 + 3.0 * 82.5)).abs() < 1e-3);
    }

    #[test]
    fn known_level_and_trend_start_is_exact_on_a_ramp() {
        let mut s = DoubleExponentialSmoother::with_level_and_trend(0.2, [4.0], [-1.5]).expect("alpha");
        assert!((s.level()[0] - 4.0).abs() < 1e-12 && (s.trend()[0] + 1.5).abs() < 1e-12);
        for t in 1..=5 {
            s.update([4.0 - 1.5 * t as f64]);
            assert!((s.forecast(1.0)[0] - (4.0 - 1.5 * (t + 1) as f64)).abs() < 1e-9);
        }
    }

    #[test]
    fn eq_12_coefficients_match_the_paper() {
        // x̂_{t+1} = (2 + α/β)·S1 − (1 + α/β)·S2, the legible part of eq. 12.
        let alpha = 0.2;
        let mut s = DoubleExponentialSmoother::new(alpha, [0.0]).expect("alpha");
        for x in [1.0, 4.0, 2.0, 8.0] {
            s.update([x]);
        }
        let (s1, s2) = s.smoothed();
        let g = alpha / (1.0 - alpha);
        let paper = (2.0 + g) * s1[0] - (1.0 + g) * s2[0];
        assert!((s.forecast(1.0)[0] - paper).abs() < 1e-12);
        // Eq. 10–11 by hand for the first step: S1 = 0.2, S2 = 0.04.
        let mut one = DoubleExponentialSmoother::new(alpha, [0.0]).expect("alpha");
        one.update([1.0]);
        let (a, b) = one.smoothed();
        assert!((a[0] - 0.2).abs() < 1e-12 && (b[0] - 0.04).abs() < 1e-12);
    }

    #[test]
    fn alpha_out_of_range_is_an_error() {
        for alpha in [0.0, 1.0, -0.1, f64::NAN] {
            assert!(DoubleExponentialSmoother::new(alpha, [0.0]).is_err(), "alpha {alpha}");
        }
    }
}
