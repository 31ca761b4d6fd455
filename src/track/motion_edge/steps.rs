//! The steps of paper 000 §2 in order, each a function of the predicted model
//! and this frame's motion pixels: model lines (step 1), labelling (eq. 3–4),
//! line fits (eq. 4–8), corners (intersections) and the deviation check (eq. 9).

use super::params::LineFitMethod;
use crate::early::{Feature, simd_dispatch};
use crate::estimate::line_fit::{
    Line, LineFit, LineSums, fit_band_across, fit_line, fit_line_orthogonal, orientation_difference,
    orientation_difference_near,
};

/// A band of labelled pixels whose perpendicular standard deviation about
/// the pooled fit exceeds this is fitted as two edges (the edge at t−1 and at
/// t, [`fit_band_across`]), px: a band about 8 px wide or more, where the two
/// edges' responses (each ±2 px) are resolved.
pub(super) const BAND_SPLIT_STD_PX: f64 = 2.5;

/// A model line at its predicted position: the line, its end points
/// (corners) and its orientation (the paper's per-line description).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelLine {
    /// The line through the two corners.
    pub line: Line,
    /// First end point.
    pub start: [f64; 2],
    /// Unit direction from `start` to the other end point.
    pub direction: [f64; 2],
    /// Length of the segment.
    pub length: f64,
    /// Undirected orientation in [0, π), the convention of θ in eq. 2.
    pub orientation: f64,
}

impl ModelLine {
    /// The model line from corner `p` to corner `q`; `None` when they coincide.
    #[must_use]
    pub fn between(p: [f64; 2], q: [f64; 2]) -> Option<Self> {
        let line = Line::through(p, q)?;
        let length = (q[0] - p[0]).hypot(q[1] - p[1]);
        let direction = [(q[0] - p[0]) / length, (q[1] - p[1]) / length];
        Some(Self { line, start: p, direction, length, orientation: line.orientation() })
    }

    /// Position of the foot of `p` along the segment (0 at `start`, `length` at the end).
    #[must_use]
    pub fn along(&self, p: [f64; 2]) -> f64 {
        (p[0] - self.start[0]) * self.direction[0] + (p[1] - self.start[1]) * self.direction[1]
    }
}

/// How far from a model line its pixels may lie, and which of them are fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineTolerance {
    /// Largest |d| of eq. 4, px.
    pub distance: f64,
    /// How far beyond the segment's end points a pixel's foot may lie, px.
    pub extent: f64,
    /// Only pixels whose foot lies in [trim, length − trim] are fitted (a
    /// negative trim fits beyond the end points); the others near the line
    /// are explained by it but not fitted (module doc, "Trimmed ends").
    pub trim: f64,
}

impl LineTolerance {
    /// Distance and extent `d`, every labelled pixel fitted.
    #[must_use]
    pub fn uniform(d: f64) -> Self {
        Self { distance: d, extent: d, trim: -d }
    }
}

/// Motion pixels labelled to model lines (step 2).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Labelling {
    /// Sums for the line fit, per model line.
    pub sums: Vec<LineSums>,
    /// Labelled pixels per model line.
    pub pixels: Vec<Vec<(u32, u32)>>,
    /// Per model line: pixels of its orientation (eq. 3) labelled to no line.
    pub unexplained: Vec<usize>,
    /// Pixels of a model line's orientation labelled to no line (each counted once).
    pub unexplained_total: usize,
}

/// Step 1: the model lines through the predicted corners, in model edge
/// order; `None` for a line whose corners coincide.
#[must_use]
pub fn model_lines(corners: &[[f64; 2]], edges: &[[usize; 2]]) -> Vec<Option<ModelLine>> {
    edges.iter().map(|&[i, j]| ModelLine::between(corners[i], corners[j])).collect()
}

/// Step 2 (eq. 3–4): label each motion pixel to the model line it best
/// matches — orientation within `delta` (modulo π), perpendicular distance
/// within the line's tolerance, foot within the segment extended by the
/// tolerance's extent — choosing the smallest distance; discard the rest.
/// Of a line's pixels only those within its trimmed extent are kept for the
/// fit. Pixels weaker than `min_magnitude` have no orientation and are skipped.
#[must_use]
pub fn label_motion_pixels(
    motion: &[Feature],
    lines: &[Option<ModelLine>],
    tolerances: &[LineTolerance],
    delta: f64,
    min_magnitude: f32,
) -> Labelling {
    let mut labelling = Labelling {
        sums: lines.iter().map(|l| l.map_or_else(LineSums::new, |l| LineSums::with_origin(l.start))).collect(),
        pixels: vec![Vec::new(); lines.len()],
        unexplained: vec![0; lines.len()],
        unexplained_total: 0,
    };
    let kept: Vec<&Feature> = motion.iter().filter(|f| f.magnitude >= min_magnitude && f.theta.is_finite()).collect();
    let in_range = kept.iter().all(|f| (-std::f32::consts::PI..=std::f32::consts::PI).contains(&f.theta));
    if in_range && lines.len() <= MAX_LINE_MASK {
        label_by_lines(&kept, lines, tolerances, delta, &mut labelling);
    } else {
        label_pixel_by_pixel(&kept, lines, tolerances, delta, &mut labelling);
    }
    labelling
}

/// [`label_motion_pixels`] of `pixels`, pixel by pixel (any angles, any
/// number of lines).
fn label_pixel_by_pixel(
    pixels: &[&Feature],
    lines: &[Option<ModelLine>],
    tolerances: &[LineTolerance],
    delta: f64,
    labelling: &mut Labelling,
) {
    let mut compatible = Vec::with_capacity(lines.len());
    for feature in pixels {
        let p = [f64::from(feature.x), f64::from(feature.y)];
        let theta = f64::from(feature.theta);
        compatible.clear();
        let mut best: Option<(usize, f64)> = None;
        for (k, (line, tolerance)) in lines.iter().zip(tolerances).enumerate() {
            let Some(line) = line else { continue };
            // Eq. 3: orientation agreement, undirected.
            if orientation_difference(theta, line.orientation) >= delta {
                continue;
            }
            compatible.push(k);
            // Eq. 4: perpendicular distance, and the segment's extent.
            let d = line.line.distance(p);
            let s = line.along(p);
            if d < tolerance.distance
                && s >= -tolerance.extent
                && s <= line.length + tolerance.extent
                && best.is_none_or(|(_, bd)| d < bd)
            {
                best = Some((k, d));
            }
        }
        match best {
            Some((k, _)) => {
                let (Some(line), tolerance) = (&lines[k], &tolerances[k]) else {
                    continue;
                };
                let s = line.along(p);
                if s >= tolerance.trim && s <= line.length - tolerance.trim {
                    labelling.sums[k].add(p[0], p[1]);
                    labelling.pixels[k].push((feature.x, feature.y));
                }
            }
            None if !compatible.is_empty() => {
                labelling.unexplained_total += 1;
                for &k in &compatible {
                    labelling.unexplained[k] += 1;
                }
            }
            None => {}
        }
    }
}

/// Most lines [`label_by_lines`] takes: one bit per line of a pixel's mask.
const MAX_LINE_MASK: usize = 64;

/// [`label_motion_pixels`] of `pixels` (orientations or directions, in
/// [−π, π]), line by line over all pixels instead of pixel by pixel: each
/// line's tests run over arrays of the pixels' coordinates without
/// branches, so they vectorise, keeping per pixel the nearest line within
/// tolerance (the first of equals, as in pixel order) and a mask of the
/// lines of its orientation; the pixels are then labelled in their order.
/// The same values as [`orientation_difference`] (through
/// [`orientation_difference_near`]), [`Line::distance`] and
/// [`ModelLine::along`], so the same labelling bit for bit.
fn label_by_lines(
    pixels: &[&Feature],
    lines: &[Option<ModelLine>],
    tolerances: &[LineTolerance],
    delta: f64,
    labelling: &mut Labelling,
) {
    let n = pixels.len();
    let x: Vec<f64> = pixels.iter().map(|f| f64::from(f.x)).collect();
    let y: Vec<f64> = pixels.iter().map(|f| f64::from(f.y)).collect();
    let theta: Vec<f64> = pixels.iter().map(|f| f64::from(f.theta)).collect();
    let mut nearest = Nearest { line: vec![u32::MAX; n], distance: vec![f64::INFINITY; n], along: vec![0.0; n] };
    let mut masks = vec![0u64; n];
    let points = Points { x: &x, y: &y, theta: &theta };
    for (k, (line, tolerance)) in lines.iter().zip(tolerances).enumerate() {
        let Some(line) = line else { continue };
        test_line(points, line, tolerance, k, delta, &mut nearest, &mut masks);
    }
    for (i, feature) in pixels.iter().enumerate() {
        let k = nearest.line[i];
        if k != u32::MAX {
            let (k, s) = (k as usize, nearest.along[i]);
            let (Some(line), tolerance) = (&lines[k], &tolerances[k]) else { continue };
            if s >= tolerance.trim && s <= line.length - tolerance.trim {
                labelling.sums[k].add(x[i], y[i]);
                labelling.pixels[k].push((feature.x, feature.y));
            }
        } else if masks[i] != 0 {
            labelling.unexplained_total += 1;
            let mut mask = masks[i];
            while mask != 0 {
                labelling.unexplained[mask.trailing_zeros() as usize] += 1;
                mask &= mask - 1;
            }
        }
    }
}

/// Pixel coordinates and edge orientations, as f64 arrays.
#[derive(Clone, Copy)]
struct Points<'a> {
    x: &'a [f64],
    y: &'a [f64],
    theta: &'a [f64],
}

/// Per pixel: the nearest line within tolerance so far (`u32::MAX`: none),
/// its distance and the pixel's foot along it.
struct Nearest {
    line: Vec<u32>,
    distance: Vec<f64>,
    along: Vec<f64>,
}

simd_dispatch!(fn test_line(points: Points<'_>, line: &ModelLine, tolerance: &LineTolerance, k: usize, delta: f64, nearest: &mut Nearest, masks: &mut [u64]) => test_line_body);

/// Eq. 3–4 of every pixel against line `k`: its bit in the pixel's mask
/// when the orientations agree, and the line as the pixel's nearest when
/// it is within tolerance and nearer than the nearest so far.
#[inline(always)]
fn test_line_body(
    points: Points<'_>,
    line: &ModelLine,
    tolerance: &LineTolerance,
    k: usize,
    delta: f64,
    nearest: &mut Nearest,
    masks: &mut [u64],
) {
    let (low, high) = (-tolerance.extent, line.length + tolerance.extent);
    let (phi, bit, index) = (line.orientation, 1u64 << k, k as u32);
    let n = masks.len();
    let (xs, ys, thetas) = (&points.x[..n], &points.y[..n], &points.theta[..n]);
    let (best_line, best_distance, best_along) =
        (&mut nearest.line[..n], &mut nearest.distance[..n], &mut nearest.along[..n]);
    for i in 0..n {
        // Eq. 3, θ − φ in (−2π, 2π) by the orientations' range.
        let compatible = !(orientation_difference_near(thetas[i], phi) >= delta);
        let d = line.line.distance([xs[i], ys[i]]);
        let s = line.along([xs[i], ys[i]]);
        let nearer = compatible & (d < tolerance.distance) & (s >= low) & (s <= high) & (d < best_distance[i]);
        masks[i] |= if compatible { bit } else { 0 };
        best_line[i] = if nearer { index } else { best_line[i] };
        best_distance[i] = if nearer { d } else { best_distance[i] };
        best_along[i] = if nearer { s } else { best_along[i] };
    }
}

/// Step 3 (eq. 5–8): least-squares line per model line with at least
/// `min_points` labelled pixels; `None` keeps the predicted line. A fit
/// turned `delta` or more from its model line (eq. 3 applied to the whole
/// line: scattered clutter rather than an edge) is refused too.
#[must_use]
pub fn fit_model_lines(
    labelling: &Labelling,
    lines: &[Option<ModelLine>],
    min_points: usize,
    delta: f64,
    method: LineFitMethod,
) -> Vec<Option<LineFit>> {
    labelling
        .sums
        .iter()
        .zip(lines)
        .zip(&labelling.pixels)
        .map(|((sums, model), pixels)| {
            let model = model.as_ref()?;
            if sums.count() < min_points {
                return None;
            }
            let fit = match method {
                LineFitMethod::Regression => fit_line(sums),
                LineFitMethod::Orthogonal => fit_line_orthogonal(sums),
                LineFitMethod::Across => {
                    let points: Vec<[f64; 2]> = pixels.iter().map(|&(x, y)| [f64::from(x), f64::from(y)]).collect();
                    let (fit, extent) = robust_band_fit(&points, model.direction, min_points)?;
                    (extent >= MIN_COVERAGE * model.length).then_some(fit)
                }
            };
            fit.filter(|f| orientation_difference(f.line.orientation(), model.orientation) < delta)
        })
        .collect()
}

/// The band fit ([`fit_band_across`]) of `points`, made again up to
/// [`OUTLIER_ROUNDS`] times without the points far from the last fit
/// (extension): a point more than [`OUTLIER_SPREAD`] robust standard
/// deviations (1.4826 × the median distance of all points, at least
/// [`OUTLIER_FLOOR_PX`]) from it belongs to something else in the strip,
/// such as a second moving object's edge of similar orientation. A round
/// that would keep every point, or fewer than `min_points`, ends the
/// rounds. Returns the fit and the extent along `direction` of the points it
/// keeps, px.
fn robust_band_fit(points: &[[f64; 2]], direction: [f64; 2], min_points: usize) -> Option<(LineFit, f64)> {
    let mut fit = fit_band_across(points, direction, BAND_SPLIT_STD_PX)?;
    let mut scratch = Vec::with_capacity(points.len());
    let mut limit = outlier_limit(points, &fit, &mut scratch);
    for _ in 0..OUTLIER_ROUNDS {
        let within = |p: &[f64; 2]| fit.line.signed_distance(*p).abs() <= limit;
        let kept_count = points.iter().filter(|p| within(p)).count();
        if kept_count == points.len() || kept_count < min_points.max(2) {
            break;
        }
        let kept: Vec<[f64; 2]> = points.iter().filter(|p| within(p)).copied().collect();
        let Some(refit) = fit_band_across(&kept, direction, BAND_SPLIT_STD_PX) else { break };
        fit = refit;
        limit = outlier_limit(points, &fit, &mut scratch);
    }
    let (lo, hi) = points
        .iter()
        .filter(|p| fit.line.signed_distance(**p).abs() <= limit)
        .map(|p| p[0] * direction[0] + p[1] * direction[1])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), a| (lo.min(a), hi.max(a)));
    Some((fit, (hi - lo).max(0.0)))
}

/// The distance beyond which [`robust_band_fit`] refuses a point of
/// `points` around `fit`; `scratch` is working space.
fn outlier_limit(points: &[[f64; 2]], fit: &LineFit, scratch: &mut Vec<f64>) -> f64 {
    scratch.clear();
    scratch.extend(points.iter().map(|&p| fit.line.signed_distance(p).abs()));
    let middle = scratch.len() / 2;
    let (_, median, _) = scratch.select_nth_unstable_by(middle, f64::total_cmp);
    (OUTLIER_SPREAD * 1.4826 * *median).max(OUTLIER_FLOOR_PX)
}

/// Robust standard deviations beyond which [`robust_band_fit`] refuses a
/// point.
const OUTLIER_SPREAD: f64 = 3.0;

/// Least extent along a model line of the pixels its fit keeps, as a
/// fraction of the line's length: a shorter run is another object's edge.
const MIN_COVERAGE: f64 = 0.4;

/// Rounds of [`robust_band_fit`], each about the last fit.
const OUTLIER_ROUNDS: usize = 3;
/// Least distance at which [`robust_band_fit`] refuses a point, px.
const OUTLIER_FLOOR_PX: f64 = 2.0;

/// Step 4: each corner is the intersection of its two model lines, fitted
/// where fitted, `fallback_lines` (the predicted lines, or the lines held
/// from earlier fits) otherwise. Returns the corners and whether each was
/// measured (at least one of its lines fitted and the lines not parallel);
/// an unmeasured corner is its `fallback_corners` entry.
#[must_use]
pub fn intersect_corners(
    fitted: &[Option<LineFit>],
    fallback_lines: &[Option<Line>],
    fallback_corners: &[[f64; 2]],
    corner_lines: &[[usize; 2]],
) -> (Vec<[f64; 2]>, Vec<bool>) {
    let current = |k: usize| fitted[k].map(|f| f.line).or(fallback_lines[k]);
    corner_lines
        .iter()
        .zip(fallback_corners)
        .map(|(&[k1, k2], &prediction)| {
            if fitted[k1].is_none() && fitted[k2].is_none() {
                return (prediction, false);
            }
            match (current(k1), current(k2)) {
                (Some(l1), Some(l2)) => l1.intersection(&l2).map_or((prediction, false), |c| (c, true)),
                _ => (prediction, false),
            }
        })
        .unzip()
}

/// Step 5 (eq. 9): the largest distance of a measured corner from its
/// prediction; `None` when no corner was measured.
#[must_use]
pub fn corner_deviation(corners: &[[f64; 2]], measured: &[bool], predicted: &[[f64; 2]]) -> Option<f64> {
    corners
        .iter()
        .zip(measured)
        .zip(predicted)
        .filter(|((_, m), _)| **m)
        .map(|((c, _), p)| (c[0] - p[0]).hypot(c[1] - p[1]))
        .fold(None, |acc: Option<f64>, d| Some(acc.map_or(d, |a| a.max(d))))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The line-by-line labelling equals the pixel-by-pixel one bit for
    /// bit: random quadrilaterals (one line missing in some), pixels near
    /// and on their lines at random orientations and directions in [−π, π]
    /// (±π, 0 and the lines' own included), distances and foot positions at
    /// the tolerances' edges.
    #[test]
    fn labelling_line_by_line_equals_pixel_by_pixel() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for trial in 0..200 {
            let corners: Vec<[f64; 2]> =
                (0..4).map(|_| [rng.random_range(10.0..90.0), rng.random_range(10.0..70.0)]).collect();
            let mut lines = model_lines(&corners, &[[0, 1], [1, 2], [2, 3], [3, 0]]);
            if trial % 5 == 0 {
                lines[trial % 4] = None;
            }
            let tolerances: Vec<LineTolerance> = (0..4)
                .map(|_| LineTolerance {
                    distance: rng.random_range(1.0..8.0),
                    extent: rng.random_range(0.0..4.0),
                    trim: rng.random_range(-3.0..3.0),
                })
                .collect();
            let pixels: Vec<Feature> = (0..300)
                .map(|i| {
                    let line = lines[i % 4].or(lines[(i + 1) % 4]).expect("a line");
                    let t = rng.random_range(-10.0..line.length + 10.0);
                    let off = rng.random_range(-10.0..10.0);
                    let (x, y) = (
                        line.start[0] + t * line.direction[0] - off * line.direction[1],
                        line.start[1] + t * line.direction[1] + off * line.direction[0],
                    );
                    let pi = std::f32::consts::PI;
                    let theta = match i % 9 {
                        0 => pi,
                        1 => 0.0,
                        2 => line.orientation as f32,
                        3 => -pi,
                        4 => line.orientation as f32 - pi,
                        5 => rng.random_range(-pi..0.0),
                        _ => rng.random_range(0.0..pi),
                    };
                    Feature { x: x.clamp(0.0, 200.0) as u32, y: y.clamp(0.0, 200.0) as u32, theta, magnitude: 50.0 }
                })
                .collect();
            let kept: Vec<&Feature> = pixels.iter().collect();
            let delta = rng.random_range(0.05..0.6);
            let empty = || Labelling {
                sums: lines.iter().map(|l| l.map_or_else(LineSums::new, |l| LineSums::with_origin(l.start))).collect(),
                pixels: vec![Vec::new(); 4],
                unexplained: vec![0; 4],
                unexplained_total: 0,
            };
            let (mut by_lines, mut by_pixels) = (empty(), empty());
            label_by_lines(&kept, &lines, &tolerances, delta, &mut by_lines);
            label_pixel_by_pixel(&kept, &lines, &tolerances, delta, &mut by_pixels);
            assert_eq!(by_lines, by_pixels, "trial {trial}");
            assert!(trial > 0 || by_lines.pixels.iter().map(Vec::len).sum::<usize>() > 20);
        }
    }

    /// A 3-px band along the line y = 0.2·x + 10 for x in 0..60, and a short
    /// parallel edge 9 px below it (another object's pixels in the strip).
    fn band_with_a_parallel_stray() -> Vec<[f64; 2]> {
        let mut points = Vec::new();
        for x in 0..60 {
            for dy in [-1.0, 0.0, 1.0] {
                points.push([f64::from(x), 0.2 * f64::from(x) + 10.0 + dy]);
            }
        }
        for x in 40..55 {
            points.push([f64::from(x), 0.2 * f64::from(x) + 19.0]);
        }
        points
    }

    #[test]
    fn robust_band_fit_drops_a_parallel_stray_edge() {
        let points = band_with_a_parallel_stray();
        let direction = [1.0 / 1.04_f64.sqrt(), 0.2 / 1.04_f64.sqrt()];
        let fit = fit_band_across(&points, direction, BAND_SPLIT_STD_PX).expect("fit");
        let off = |f: &LineFit| [0.0, 60.0].map(|x: f64| f.line.signed_distance([x, 0.2 * x + 10.0]).abs());
        // The stray edge pulls the plain fit by more than a pixel at the far end.
        assert!(off(&fit)[1] > 1.0, "plain fit {:?}", off(&fit));
        let (refit, _) = robust_band_fit(&points, direction, 5).expect("refit");
        assert!(off(&refit).iter().all(|&d| d < 0.05), "refit {:?}", off(&refit));
        assert_eq!(refit.count, 180);
    }

    #[test]
    fn a_short_run_of_pixels_does_not_cover_the_model_line() {
        let model = ModelLine::between([0.0, 10.0], [60.0, 22.0]).expect("line");
        let band: Vec<[f64; 2]> = band_with_a_parallel_stray().into_iter().take(180).collect();
        let stray: Vec<[f64; 2]> = band_with_a_parallel_stray().into_iter().skip(180).collect();
        let extent = |points: &[[f64; 2]]| robust_band_fit(points, model.direction, 5).expect("fit").1;
        // The band spans the 61-px line (60 px along it, ±0.4 px of its
        // width); the 15-px stray edge alone does not reach MIN_COVERAGE.
        assert!((extent(&band) - 59.0 * 1.04_f64.sqrt()).abs() < 0.5, "{}", extent(&band));
        assert!(extent(&stray) < MIN_COVERAGE * model.length, "{}", extent(&stray));
        assert!(extent(&band) >= MIN_COVERAGE * model.length);
    }

    #[test]
    fn robust_band_fit_keeps_a_clean_band_as_it_is() {
        let points: Vec<[f64; 2]> = band_with_a_parallel_stray().into_iter().take(180).collect();
        let direction = [1.0 / 1.04_f64.sqrt(), 0.2 / 1.04_f64.sqrt()];
        let fit = fit_band_across(&points, direction, BAND_SPLIT_STD_PX).expect("fit");
        let (refit, _) = robust_band_fit(&points, direction, 5).expect("refit");
        assert_eq!(refit.line, fit.line);
        assert_eq!(refit.count, fit.count);
    }
}
