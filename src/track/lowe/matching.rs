//! Probability of correctness of each potential match (001 "Matching with
//! minimal search", eq. 2–3).
//!
//! For a visible model segment predicted with covariance P, the variance of
//! each predicted measurement is the diagonal of S = A P Aᵀ (eq. 2), A's rows
//! being the derivatives of the segment's perpendicular position, endpoint
//! positions along it and orientation ([`ModelSegment`]). An image segment
//! with midpoint at perpendicular distance x from the predicted line and
//! orientation y away from it has
//!
//! - p(x, y) = exp(−½[(x/σ_x)² + (y/σ_y)²]) / (2π σ_x σ_y), the density of
//!   a correct match;
//! - q = N (m − s) / (π w h), the density of the N background segments of
//!   the w × h window over the positions where a segment of length s
//!   overlaps the predicted segment extended to length m;
//! - P = p / (p + q) (eq. 3).
//!
//! σ_x² is S's perpendicular variance at the point of the model segment
//! nearest the image segment's midpoint plus the measurement variance σ_m²
//! of a correct segment; σ_y² is S's orientation variance plus
//! (2σ_m / s)², the orientation noise of a segment of length s whose ends
//! are each σ_m off. Without the measurement terms a prediction locked on
//! (S → 0) would give every correct match a vanishing p. The model segment
//! is extended at each end (the paper's "extended in length to include the
//! uncertainty in its endpoint positions"), by two standard deviations of
//! the endpoint's position along it, S's parallel variance plus σ_m². A
//! candidate must lie within the extended segment (both its ends projected
//! onto the line fall inside it; so s ≤ m), and m − s is floored at σ_m so
//! a segment as long as the extended one still gets a finite background
//! density.

use std::f64::consts::PI;

use super::estimation::{Matrix, quadratic_form};
use super::projection::ModelSegment;

/// An image segment as the matcher sees it: its endpoints.
pub type Endpoints = [[f64; 2]; 2];

/// One potential match.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Index of the model segment.
    pub model: usize,
    /// Index of the image segment.
    pub image: usize,
    /// Probability of correctness, eq. 3.
    pub probability: f64,
}

/// The predicted spread of one model segment (eq. 2) and its search bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentSpread {
    /// Standard deviation of the perpendicular position at `a` and at `b`, px.
    pub perpendicular: [f64; 2],
    /// Standard deviation of `a` and of `b` along the segment, px.
    pub parallel: [f64; 2],
    /// Standard deviation of the orientation, rad.
    pub orientation: f64,
}

impl SegmentSpread {
    /// How far the model segment is extended beyond `a` and beyond `b`:
    /// two standard deviations of each end's position along it, with the
    /// measurement σ of a correct segment's ends.
    #[must_use]
    pub fn extension(&self, measurement_sigma: f64) -> [f64; 2] {
        [2.0 * self.parallel[0].hypot(measurement_sigma), 2.0 * self.parallel[1].hypot(measurement_sigma)]
    }

    /// The spread of `seg` under covariance `p` (n parameters).
    #[must_use]
    pub fn of(seg: &ModelSegment, p: &Matrix, n: usize) -> Self {
        let sd = |row| quadratic_form(p, &row, n).max(0.0).sqrt();
        let [pa, pb] = seg.parallel_rows(n);
        Self {
            perpendicular: [sd(seg.perpendicular_row(0.0, n)), sd(seg.perpendicular_row(1.0, n))],
            parallel: [sd(pa), sd(pb)],
            orientation: sd(seg.orientation_row(n)),
        }
    }
}

/// The matching context of a frame.
#[derive(Clone, Copy, Debug)]
pub struct MatchContext {
    /// Number of image segments N.
    pub segments: usize,
    /// Area of the window they were found in, px² (w·h).
    pub area: f64,
    /// Measurement standard deviation σ_m, px.
    pub measurement_sigma: f64,
    /// Candidates lie within this many σ of the prediction.
    pub search_sigmas: f64,
    /// Candidates below this probability are dropped.
    pub min_probability: f64,
}

/// The image bounds a model segment's candidates can lie in:
/// `[x0, y0, x1, y1]`, the extended segment grown by the search range.
#[must_use]
pub fn search_bounds(seg: &ModelSegment, spread: &SegmentSpread, ctx: &MatchContext) -> [f64; 4] {
    let [ux, uy] = seg.direction();
    let ext = spread.extension(ctx.measurement_sigma);
    let a = [seg.a[0] - ux * ext[0], seg.a[1] - uy * ext[0]];
    let b = [seg.b[0] + ux * ext[1], seg.b[1] + uy * ext[1]];
    let reach = ctx.search_sigmas * (spread.perpendicular[0].max(spread.perpendicular[1]).hypot(ctx.measurement_sigma));
    [a[0].min(b[0]) - reach, a[1].min(b[1]) - reach, a[0].max(b[0]) + reach, a[1].max(b[1]) + reach]
}

/// The probability of correctness (eq. 3) of image segment `image` for the
/// model segment `seg` under covariance `p`; `None` when the image segment
/// is outside the extended segment or further than the search range in
/// position or orientation.
#[must_use]
pub fn match_probability(
    seg: &ModelSegment,
    spread: &SegmentSpread,
    p: &Matrix,
    n: usize,
    image: &Endpoints,
    ctx: &MatchContext,
) -> Option<f64> {
    ModelLine::of(seg, spread, ctx).match_probability(p, n, image)
}

/// A model segment with its spread under a frame's matching context, and
/// what [`match_probability`] needs of them whatever the image segment,
/// worked out once for all its candidates.
#[derive(Clone, Copy, Debug)]
pub struct ModelLine<'a> {
    seg: &'a ModelSegment,
    spread: &'a SegmentSpread,
    ctx: &'a MatchContext,
    length: f64,
    direction: [f64; 2],
    normal: [f64; 2],
    orientation: f64,
    /// [`SegmentSpread::extension`].
    extension: [f64; 2],
}

impl<'a> ModelLine<'a> {
    /// The line of `seg` with the extension of `spread` under `ctx`.
    #[must_use]
    pub fn of(seg: &'a ModelSegment, spread: &'a SegmentSpread, ctx: &'a MatchContext) -> Self {
        Self {
            seg,
            spread,
            ctx,
            length: seg.length(),
            direction: seg.direction(),
            normal: seg.normal(),
            orientation: seg.orientation(),
            extension: spread.extension(ctx.measurement_sigma),
        }
    }

    /// The segment's undirected orientation in [0, π).
    #[must_use]
    pub fn orientation(&self) -> f64 {
        self.orientation
    }

    /// [`match_probability`] of `image` for this line's segment under
    /// covariance `p` (n parameters).
    #[must_use]
    pub fn match_probability(&self, p: &Matrix, n: usize, image: &Endpoints) -> Option<f64> {
        let (seg, spread, ctx) = (self.seg, self.spread, self.ctx);
        let length = self.length;
        let [ux, uy] = self.direction;
        let [nx, ny] = self.normal;
        let along_of = |p: [f64; 2]| ux * (p[0] - seg.a[0]) + uy * (p[1] - seg.a[1]);
        let (along0, along1) = (along_of(image[0]), along_of(image[1]));
        let ext = self.extension;
        let inside = |t: f64| t >= -ext[0] && t <= length + ext[1];
        if !(inside(along0) && inside(along1)) {
            return None;
        }
        let mid = [(image[0][0] + image[1][0]) * 0.5, (image[0][1] + image[1][1]) * 0.5];
        let (rx, ry) = (mid[0] - seg.a[0], mid[1] - seg.a[1]);
        let along = 0.5 * (along0 + along1);
        let x = nx * rx + ny * ry;
        let s_len = (image[1][0] - image[0][0]).hypot(image[1][1] - image[0][1]);
        if s_len <= 0.0 {
            return None;
        }
        let angle = (image[1][1] - image[0][1]).atan2(image[1][0] - image[0][0]);
        let mut y = (angle - self.orientation).rem_euclid(PI);
        if y > PI / 2.0 {
            y -= PI;
        }
        let sm2 = ctx.measurement_sigma * ctx.measurement_sigma;
        let s = (along / length).clamp(0.0, 1.0);
        let sigma_x = (quadratic_form(p, &seg.perpendicular_row(s, n), n).max(0.0) + sm2).sqrt();
        let angle_noise = 2.0 * ctx.measurement_sigma / s_len;
        let sigma_y = spread.orientation.hypot(angle_noise);
        if x.abs() > ctx.search_sigmas * sigma_x || y.abs() > ctx.search_sigmas * sigma_y {
            return None;
        }
        let density = (-0.5 * ((x / sigma_x).powi(2) + (y / sigma_y).powi(2))).exp() / (2.0 * PI * sigma_x * sigma_y);
        let extended = length + ext[0] + ext[1];
        let background = ctx.segments as f64 * (extended - s_len).max(ctx.measurement_sigma) / (PI * ctx.area);
        let probability = density / (density + background);
        (probability >= ctx.min_probability).then_some(probability)
    }
}

/// Every candidate of every model segment, by brute force over the image
/// segments (the tracker uses the segment index instead; this is the
/// reference).
#[must_use]
pub fn all_candidates(
    segs: &[ModelSegment],
    p: &Matrix,
    n: usize,
    images: &[Endpoints],
    ctx: &MatchContext,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    for (m, seg) in segs.iter().enumerate() {
        let spread = SegmentSpread::of(seg, p, n);
        let line = ModelLine::of(seg, &spread, ctx);
        for (i, image) in images.iter().enumerate() {
            if let Some(probability) = line.match_probability(p, n, image) {
                out.push(Candidate { model: m, image: i, probability });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::geometry::Pose;
    use crate::track::lowe::fixtures::{camera, hinged_box};
    use crate::track::lowe::params::MAX_PARAMS;
    use crate::track::lowe::projection::{Linearised, State};

    /// In a constructed case — a model edge predicted with a few pixels of
    /// uncertainty, its true image segment 1 px off, clutter segments nearby
    /// at larger offsets and angles, one long clutter line — the true
    /// segment has the highest probability, and the probabilities fall with
    /// distance and angle.
    #[test]
    fn true_segment_ranks_above_clutter() {
        let geometry = hinged_box();
        let cam = camera();
        let centre = geometry.centroid();
        let state = State {
            pose: Pose::from_axis_angle(DVec3::new(0.3, 0.2, 0.0), DVec3::new(-0.1, 0.0, 0.9)),
            params: vec![0.5],
        };
        let lin = Linearised::at(&geometry, &state, centre).unwrap();
        let seg = ModelSegment::new(&lin, &cam, geometry.edges(), 0, [0.0, 1.0]).unwrap();
        let n = lin.n;
        let mut sigmas = [0.0; MAX_PARAMS];
        sigmas[..7].copy_from_slice(&[0.02, 0.02, 0.02, 0.005, 0.005, 0.005, 0.05]);
        let p = crate::track::lowe::estimation::diagonal(&sigmas, n);
        let spread = SegmentSpread::of(&seg, &p, n);
        assert!(spread.perpendicular[0] > 1.0 && spread.perpendicular[0] < 20.0, "{spread:?}");
        let [nx, ny] = seg.normal();
        let [ux, uy] = seg.direction();
        let at = |s: f64, off: f64| {
            [seg.a[0] + s * (seg.b[0] - seg.a[0]) + off * nx, seg.a[1] + s * (seg.b[1] - seg.a[1]) + off * ny]
        };
        let turned = |s0: f64, s1: f64, off: f64, angle: f64| {
            let m = at((s0 + s1) / 2.0, off);
            let half = (s1 - s0) * seg.length() / 2.0;
            let (c, s) = (angle.cos(), angle.sin());
            let d = [ux * c - uy * s, ux * s + uy * c];
            [[m[0] - d[0] * half, m[1] - d[1] * half], [m[0] + d[0] * half, m[1] + d[1] * half]]
        };
        let images = [
            turned(0.1, 0.9, 1.0, 0.0),  // the true segment
            turned(0.2, 0.7, 6.0, 0.0),  // parallel clutter 6 px off
            turned(0.1, 0.6, 2.0, 0.25), // close but turned 14°
            turned(0.3, 0.5, 12.0, 0.0), // far parallel
        ];
        let ctx = MatchContext {
            segments: 400,
            area: 640.0 * 480.0,
            measurement_sigma: 1.0,
            search_sigmas: 3.0,
            min_probability: 0.0,
        };
        let probs: Vec<Option<f64>> =
            images.iter().map(|im| match_probability(&seg, &spread, &p, n, im, &ctx)).collect();
        let truth = probs[0].expect("true segment is a candidate");
        assert!(truth > 0.9, "{probs:?}");
        for other in probs.iter().skip(1).flatten() {
            assert!(*other < truth, "{probs:?}");
        }
        assert!(probs[1].unwrap() > probs[3].unwrap_or(0.0), "{probs:?}");
        // A segment beyond the extended model segment is no candidate.
        let beyond = [at(1.6, 0.0), at(1.9, 0.0)];
        assert_eq!(match_probability(&seg, &spread, &p, n, &beyond, &ctx), None);
        // More background segments lower the probability of the same match.
        let dense = MatchContext { segments: 40_000, ..ctx };
        assert!(match_probability(&seg, &spread, &p, n, &images[1], &dense).unwrap() < probs[1].unwrap());
    }
}
