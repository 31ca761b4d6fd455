//! Stabilised Gauss–Newton (001 eq. 1) over a set of matches: the
//! correction x solves (JᵀJ + WᵀW) x = Jᵀe with W_ii = 1/σ_i, σ_i the prior
//! standard deviation of parameter i; the residual variance is
//! σ² = ‖Jx − e‖² / (m − n) and the covariance P = (JᵀJ + WᵀW)⁻¹.
//!
//! Rows are in units of the measurement σ (each error and row divided by
//! `measurement_sigma_px`), so P is the parameters' covariance. The prior
//! rows keep every iterate near the frame's *prediction*: from an iterate
//! θ_k that has moved by d from the prediction, the system solved is
//! (JᵀJ + WᵀW) x = Jᵀe − WᵀW d (eq. 1 at k = 0, where d = 0).

use std::cell::Cell;
use std::time::{Duration, Instant};

use glam::DVec3;

use super::params::MAX_PARAMS;
use super::projection::{Linearised, ModelSegment, Row, State};
use crate::estimate::linalg::invert_spd;
use crate::geometry::{Camera, ModelGeometry};

/// A symmetric n×n matrix in the top-left of a fixed array.
pub type Matrix = [[f64; MAX_PARAMS]; MAX_PARAMS];

/// One match: an image segment (its two endpoints) paired with a visible
/// part of a model edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Match {
    /// The model edge.
    pub edge: usize,
    /// The visible part's 3-D parameter interval along the edge.
    pub interval: [f64; 2],
    /// The image segment's endpoints.
    pub endpoints: [[f64; 2]; 2],
    /// Which image segment (index into the frame's list).
    pub image: usize,
}

/// What the estimation needs besides the matches.
#[derive(Clone, Copy, Debug)]
pub struct Problem<'a> {
    /// The model.
    pub geometry: &'a ModelGeometry,
    /// The camera.
    pub camera: &'a Camera,
    /// Object-frame centre of rotation of the corrections.
    pub centre: DVec3,
    /// Joint limits.
    pub limits: &'a [[f64; 2]],
    /// The frame's prediction (the prior's mean).
    pub prediction: &'a State,
    /// Prior standard deviations σ_i, one per parameter.
    pub prior_sigmas: &'a Row,
    /// Measurement standard deviation, px, of the ends of a segment
    /// `reference_length` long.
    pub measurement_sigma: f64,
    /// Length at which a segment's ends have `measurement_sigma`; a segment
    /// of length L has σ·sqrt(reference_length / L) (its line is fitted to L
    /// edgels). 0: every segment has `measurement_sigma`.
    pub reference_length: f64,
}

/// A solution of the matches.
#[derive(Clone, Debug)]
pub struct Solution {
    /// The fitted state.
    pub state: State,
    /// P = (JᵀJ + WᵀW)⁻¹ at the fitted state (n×n in the top-left).
    pub covariance: Matrix,
    /// Residual σ = sqrt(‖e‖² / (m − n)) at the fitted state, px; `None`
    /// when m ≤ n (no redundancy to test).
    pub residual_sigma: Option<f64>,
    /// Number of measurement rows m (two per match).
    pub rows: usize,
}

/// The inverse of the n×n top-left of the symmetric `h`
/// ([`invert_spd`] with the unused diagonal set to 1, which leaves the used
/// block's inverse as it is); `None` unless positive definite.
#[must_use]
pub fn invert_top_left(h: &Matrix, n: usize) -> Option<Matrix> {
    let mut padded = *h;
    for (i, row) in padded.iter_mut().enumerate().skip(n) {
        row.fill(0.0);
        row[i] = 1.0;
    }
    for row in &mut padded[..n] {
        row[n..].fill(0.0);
    }
    invert_spd(&padded)
}

/// `M · v` over the n×n top-left.
fn times(m: &Matrix, v: &Row, n: usize) -> Row {
    let mut out = [0.0; MAX_PARAMS];
    for (o, row) in out.iter_mut().zip(m).take(n) {
        *o = (0..n).map(|j| row[j] * v[j]).sum();
    }
    out
}

/// The diagonal covariance of independent parameters with standard
/// deviations `sigmas` (n×n in the top-left).
#[must_use]
pub fn diagonal(sigmas: &Row, n: usize) -> Matrix {
    let mut p = [[0.0; MAX_PARAMS]; MAX_PARAMS];
    for i in 0..n {
        p[i][i] = sigmas[i] * sigmas[i];
    }
    p
}

/// `row · M · rowᵀ` over the n×n top-left.
#[must_use]
pub fn quadratic_form(m: &Matrix, row: &Row, n: usize) -> f64 {
    (0..n).map(|i| row[i] * (0..n).map(|j| m[i][j] * row[j]).sum::<f64>()).sum()
}

/// The normal equations of eq. 1 at `state`: H = JᵀJ + WᵀW and
/// g = Jᵀe − WᵀW d, with the sum of squared errors (px²) and the number
/// of rows; `None` when a matched edge does not project.
fn normal_equations(problem: &Problem<'_>, state: &State, matches: &[Match]) -> Option<(Matrix, Row, f64, usize)> {
    let lin = Linearised::at(problem.geometry, state, problem.centre).ok()?;
    let n = lin.n;
    let mut h = [[0.0; MAX_PARAMS]; MAX_PARAMS];
    let mut g = [0.0; MAX_PARAMS];
    let deviation = state.deviation_from(problem.prediction, problem.centre);
    for i in 0..n {
        let w2 = 1.0 / (problem.prior_sigmas[i] * problem.prior_sigmas[i]);
        h[i][i] = w2;
        g[i] = -w2 * deviation[i];
    }
    let inv_var = 1.0 / (problem.measurement_sigma * problem.measurement_sigma);
    let mut sum_sq = 0.0;
    for m in matches {
        let seg = ModelSegment::new(&lin, problem.camera, problem.geometry.edges(), m.edge, m.interval)?;
        let length = (m.endpoints[1][0] - m.endpoints[0][0]).hypot(m.endpoints[1][1] - m.endpoints[0][1]);
        let weight = if problem.reference_length > 0.0 { length.max(1.0) / problem.reference_length } else { 1.0 };
        for p in m.endpoints {
            let (d, row) = seg.distance_with_row(p, n);
            sum_sq += weight * d * d;
            for i in 0..n {
                g[i] -= weight * row[i] * d * inv_var;
                for j in 0..=i {
                    h[i][j] += weight * row[i] * row[j] * inv_var;
                }
            }
        }
    }
    for i in 0..n {
        for j in 0..i {
            h[j][i] = h[i][j];
        }
    }
    Some((h, g, sum_sq, 2 * matches.len()))
}

thread_local! {
    /// Time spent in [`solve`] on this thread since the last [`take_solve_time`].
    static SOLVE_TIME: Cell<Duration> = const { Cell::new(Duration::ZERO) };
}

/// The time spent in [`solve`] on this thread since the last call (for the
/// tracker's time split).
#[must_use]
pub fn take_solve_time() -> Duration {
    SOLVE_TIME.with(|t| t.replace(Duration::ZERO))
}

/// Fit `matches` by `iterations` stabilised Gauss–Newton steps from
/// `start`; `None` when the system is singular or a matched edge leaves
/// the front of the camera.
#[must_use]
pub fn solve(problem: &Problem<'_>, start: &State, matches: &[Match], iterations: usize) -> Option<Solution> {
    let started = Instant::now();
    let solution = solve_untimed(problem, start, matches, iterations);
    SOLVE_TIME.with(|t| t.set(t.get() + started.elapsed()));
    solution
}

fn solve_untimed(problem: &Problem<'_>, start: &State, matches: &[Match], iterations: usize) -> Option<Solution> {
    let n = 6 + problem.geometry.joint_count();
    let mut state = start.clone();
    for _ in 0..iterations {
        let (h, g, _, _) = normal_equations(problem, &state, matches)?;
        let x = times(&invert_top_left(&h, n)?, &g, n);
        state = state.corrected(&x[..n], problem.centre, problem.limits);
    }
    let (h, _, sum_sq, rows) = normal_equations(problem, &state, matches)?;
    let covariance = invert_top_left(&h, n)?;
    let residual_sigma = (rows > n).then(|| (sum_sq / (rows - n) as f64).sqrt());
    Some(Solution { state, covariance, residual_sigma, rows })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use crate::track::lowe::fixtures::{camera, hinged_box, vertex_error};

    /// Exact matches (every edge's projected endpoints at the true state,
    /// no noise): from a start several pixels and degrees off, Gauss–Newton
    /// reaches the true state in at most three iterations.
    #[test]
    fn exact_matches_converge_within_three_iterations() {
        let geometry = hinged_box();
        let cam = camera();
        let centre = geometry.centroid();
        let limits = geometry.joint_limits();
        let truth = State {
            pose: Pose::from_axis_angle(DVec3::new(0.5, -0.4, 0.1), DVec3::new(-0.12, 0.0, 0.8)),
            params: vec![0.9],
        };
        let lin = Linearised::at(&geometry, &truth, centre).unwrap();
        let matches: Vec<Match> = (0..geometry.edges().len())
            .map(|edge| {
                let seg = ModelSegment::new(&lin, &cam, geometry.edges(), edge, [0.0, 1.0]).unwrap();
                // An image segment on the true line, shorter than the edge.
                let at = |s: f64| [seg.a[0] + s * (seg.b[0] - seg.a[0]), seg.a[1] + s * (seg.b[1] - seg.a[1])];
                Match { edge, interval: [0.0, 1.0], endpoints: [at(0.15), at(0.8)], image: edge }
            })
            .collect();
        let start = truth.corrected(&[0.04, -0.03, 0.05, 0.01, -0.012, 0.02, -0.15], centre, &limits);
        // A wide prior: the stabilisation must not hold the solution back.
        let sigmas = [1.0; MAX_PARAMS];
        let problem = Problem {
            geometry: &geometry,
            camera: &cam,
            centre,
            limits: &limits,
            prediction: &start,
            prior_sigmas: &sigmas,
            measurement_sigma: 1.0,
            reference_length: 0.0,
        };
        let before = vertex_error(&geometry, &cam, &start, &truth);
        assert!(before > 5.0, "start {before} px off");
        let mut errors = Vec::new();
        for iterations in 1..=3 {
            let solution = solve(&problem, &start, &matches, iterations).unwrap();
            errors.push(vertex_error(&geometry, &cam, &solution.state, &truth));
        }
        assert!(errors[2] < 1e-3, "vertex error after 1, 2, 3 iterations: {errors:?} px");
        let solution = solve(&problem, &start, &matches, 3).unwrap();
        assert!(solution.residual_sigma.unwrap() < 1e-3);
        assert!((solution.state.params[0] - 0.9).abs() < 1e-4);
    }

    /// The prior holds an unconstrained parameter at the prediction: with
    /// no matches the solution is the prediction and P is the prior's.
    #[test]
    fn without_matches_the_prior_is_the_answer() {
        let geometry = hinged_box();
        let cam = camera();
        let centre = geometry.centroid();
        let limits = geometry.joint_limits();
        let prediction = State {
            pose: Pose::from_axis_angle(DVec3::new(0.2, 0.1, 0.0), DVec3::new(0.0, 0.0, 1.0)),
            params: vec![0.4],
        };
        let mut sigmas = [0.0; MAX_PARAMS];
        sigmas[..7].copy_from_slice(&[0.05, 0.05, 0.05, 0.01, 0.01, 0.01, 0.1]);
        let problem = Problem {
            geometry: &geometry,
            camera: &cam,
            centre,
            limits: &limits,
            prediction: &prediction,
            prior_sigmas: &sigmas,
            measurement_sigma: 1.0,
            reference_length: 0.0,
        };
        let solution = solve(&problem, &prediction, &[], 2).unwrap();
        assert_eq!(solution.state, prediction);
        for i in 0..7 {
            assert!((solution.covariance[i][i] - sigmas[i] * sigmas[i]).abs() < 1e-15);
        }
        assert_eq!(solution.residual_sigma, None);
    }
}
