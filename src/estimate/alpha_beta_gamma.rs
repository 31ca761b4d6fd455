//! The α-β-γ filter that 002 eq. 16–18 show equivalent, in steady state, to
//! the one-step predictor of the degree-2 polynomial motion model.

/// The α-β-γ filter (unit sample period): predict x⁻ = x + v + a/2,
/// v⁻ = v + a; update with residual r = m − x⁻: x = x⁻ + α·r,
/// v = v⁻ + β·r, a = a⁻ + (γ/2)·r. With α, β, γ from λ by eq. 18
/// ([`AlphaBetaGamma::from_lambda`]) its one-step prediction has the transfer
/// function of eq. 16–17, that of the λ-weighted degree-2 least-squares fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaBetaGamma {
    /// Position gain α.
    pub alpha: f64,
    /// Velocity gain β.
    pub beta: f64,
    /// Acceleration gain γ.
    pub gamma: f64,
    /// Filtered position.
    pub position: f64,
    /// Filtered velocity, per sample.
    pub velocity: f64,
    /// Filtered acceleration, per sample².
    pub acceleration: f64,
}

impl AlphaBetaGamma {
    /// Gains of eq. 18 for decay λ: α = 1 − λ³, β = 1.5(1 − λ − λ² + λ³),
    /// γ = 2 − 6λ + 6λ² − 2λ³; state zero.
    #[must_use]
    pub fn from_lambda(lambda: f64) -> Self {
        let l2 = lambda * lambda;
        let l3 = l2 * lambda;
        Self {
            alpha: 1.0 - l3,
            beta: 1.5 - 1.5 * lambda - 1.5 * l2 + 1.5 * l3,
            gamma: 2.0 - 6.0 * lambda + 6.0 * l2 - 2.0 * l3,
            position: 0.0,
            velocity: 0.0,
            acceleration: 0.0,
        }
    }

    /// The filter's one-step prediction of the next sample.
    #[must_use]
    pub fn prediction(&self) -> f64 {
        self.position + self.velocity + 0.5 * self.acceleration
    }

    /// Take measurement `m` and return the prediction of the next sample.
    pub fn update(&mut self, m: f64) -> f64 {
        let (x, v, a) = (self.prediction(), self.velocity + self.acceleration, self.acceleration);
        let r = m - x;
        self.position = x + self.alpha * r;
        self.velocity = v + self.beta * r;
        self.acceleration = a + 0.5 * self.gamma * r;
        self.prediction()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_beta_gamma_gains_of_eq_18() {
        let f = AlphaBetaGamma::from_lambda(0.5);
        assert!((f.alpha - 0.875).abs() < 1e-12);
        assert!((f.beta - 1.5 * 0.375).abs() < 1e-12); // 1 − .5 − .25 + .125
        assert!((f.gamma - 0.25).abs() < 1e-12); // 2(1 − λ)³
    }
}
