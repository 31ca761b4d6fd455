//! Estimation shared by the trackers, written once:
//!
//! - [`line_fit`]: straight lines fitted to labelled pixels (000 eq. 4–8,
//!   002 §2.5), intersections and point–line distances.
//! - [`corners`]: a fitted line with the uncertainty of its location (002
//!   eq. 1–4) and the intersection of two lines with its covariance (eq. 5–6).
//! - [`blue`]: the best linear unbiased estimate of a K-vector from 2-D
//!   measurements (002 eq. 7–10) and its consistency covariance (eq. 11–12).
//! - [`srif`]: the exponentially weighted polynomial motion model of 002
//!   (eq. 13–15), solved by a square-root information filter.
//! - [`alpha_beta_gamma`]: the α-β-γ filter of 002 eq. 16–18.
//! - [`smoothing`]: Brown's double exponential smoothing and forecast of 000
//!   (eq. 10–12).
//! - [`linalg`]: the small dense linear algebra they need.

pub mod alpha_beta_gamma;
pub mod blue;
pub mod corners;
pub mod linalg;
pub mod line_fit;
pub mod smoothing;
pub mod srif;

pub use alpha_beta_gamma::AlphaBetaGamma;
pub use blue::{BlueBlock, BlueProblem, BlueSolution};
pub use corners::{Corner, CornerCovariance, LineLocation, intersect_lines};
pub use linalg::{Mat2, inverse_sqrt2, inverse2, invert_spd};
pub use srif::PolynomialSrif;
