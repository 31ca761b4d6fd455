//! Planar polygons in the image: whether corners trace a model's edges as a
//! simple polygon, how an outline moves on as a whole, and how far apart
//! two sets of corners lie.

/// Two corners closer than this (pixels) are the same point.
const MIN_CORNER_SEPARATION_PX: f64 = 1e-6;
/// Two edges at a corner whose directions' sine is below this are on one line.
const MIN_CORNER_SINE: f64 = 1e-9;

/// Mean image distance between corresponding points of `a` and `b`, px
/// (0 for none).
#[must_use]
pub fn mean_point_distance(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    let sum: f64 = a.iter().zip(b).map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1])).sum();
    sum / a.len().max(1) as f64
}

/// Check that image `corners` (one per model vertex) trace the model's
/// polygon as a simple polygon: the two corners of an edge apart,
/// the two edges at a corner not on one line, and edges that share no
/// corner not touching (a bow-tie). `Err` is the message, to be blamed on the
/// file the corners came from (`init.json`). A model that is not a polygon (a corner on other than two
/// edges, an index out of range) passes: the tracker blames the model.
pub fn check_simple_polygon(corners: &[[f64; 2]], edges: &[[usize; 2]]) -> std::result::Result<(), String> {
    let n = corners.len();
    if n < 3 || edges.iter().flatten().any(|&i| i >= n) {
        return Ok(());
    }
    let mut degree = vec![0usize; n];
    for &i in edges.iter().flatten() {
        degree[i] += 1;
    }
    if degree.iter().any(|&d| d != 2) {
        return Ok(());
    }
    let sub = |a: [f64; 2], b: [f64; 2]| [a[0] - b[0], a[1] - b[1]];
    let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
    let norm = |a: [f64; 2]| a[0].hypot(a[1]);
    for (k, &[i, j]) in edges.iter().enumerate() {
        if norm(sub(corners[i], corners[j])) < MIN_CORNER_SEPARATION_PX {
            return Err(format!(
                "corners {i} and {j} (edge {k}) are both at {:?}: the corners must trace the model's polygon",
                corners[i]
            ));
        }
    }
    // Orientation of c relative to the line a→b: +1, −1, or 0 on the line.
    let orient = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        let v = cross(sub(b, a), sub(c, a));
        let scale = norm(sub(b, a)) * norm(sub(c, a));
        if v.abs() <= MIN_CORNER_SINE * scale { 0 } else { v.signum() as i32 }
    };
    let within = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        c[0] >= a[0].min(b[0]) && c[0] <= a[0].max(b[0]) && c[1] >= a[1].min(b[1]) && c[1] <= a[1].max(b[1])
    };
    for (k, &[a, b]) in edges.iter().enumerate() {
        for (m, &[c, d]) in edges.iter().enumerate().skip(k + 1) {
            let (pa, pb, pc, pd) = (corners[a], corners[b], corners[c], corners[d]);
            let shared = [a, b].into_iter().find(|v| *v == c || *v == d);
            if let Some(v) = shared {
                let (u, w) = (if v == a { pb } else { pa }, if v == c { pd } else { pc });
                let (du, dw) = (sub(u, corners[v]), sub(w, corners[v]));
                if cross(du, dw).abs() <= MIN_CORNER_SINE * norm(du) * norm(dw) {
                    return Err(format!(
                        "edges {k} and {m} are on one line at corner {v}: the corners must trace the model's polygon"
                    ));
                }
                continue;
            }
            let (o1, o2, o3, o4) = (orient(pa, pb, pc), orient(pa, pb, pd), orient(pc, pd, pa), orient(pc, pd, pb));
            let crossing = (o1 * o2 < 0 && o3 * o4 < 0)
                || (o1 == 0 && within(pa, pb, pc))
                || (o2 == 0 && within(pa, pb, pd))
                || (o3 == 0 && within(pc, pd, pa))
                || (o4 == 0 && within(pc, pd, pb));
            if crossing {
                return Err(format!(
                    "edges {k} [{a}, {b}] and {m} [{c}, {d}] cross: the corners must trace the model's polygon \
                     without crossing itself (check the corner order)"
                ));
            }
        }
    }
    Ok(())
}

/// How far outside the image a start corner may lie, in image sizes: x
/// within [−k·W, (1 + k)·W], y within [−k·H, (1 + k)·H]. Tracking samples
/// along the outline, so its length must stay of the image's order.
pub const MAX_START_CORNER_OFFSET: f64 = 1.0;

/// Check that start `corners` (`init.json`'s, one per model vertex) suit a
/// `width`×`height` image: every corner within [`MAX_START_CORNER_OFFSET`]
/// image sizes of it, and the polygon the model's `edges` trace over the
/// corners overlapping it (an edge on or across it, clipped by
/// [`clip_segment`], or the image inside the polygon). The image spans −½
/// to W − ½ and −½ to H − ½, the pixels' extent. `Err` is the message, to be blamed on the
/// file the corners came from. Edges whose indices are out of range are
/// left out (the model is to blame for them).
pub fn check_polygon_in_image(
    corners: &[[f64; 2]],
    edges: &[[usize; 2]],
    width: u32,
    height: u32,
) -> std::result::Result<(), String> {
    let (w, h) = (f64::from(width), f64::from(height));
    let k = MAX_START_CORNER_OFFSET;
    let (x_range, y_range) = (-k * w..=(1.0 + k) * w, -k * h..=(1.0 + k) * h);
    if let Some((i, c)) =
        corners.iter().enumerate().find(|(_, c)| !(x_range.contains(&c[0]) && y_range.contains(&c[1])))
    {
        return Err(format!(
            "corner {i} at [{}, {}] lies more than {k} image size outside the {width}x{height} image: \
             every corner must have x in [{}, {}] and y in [{}, {}]",
            crate::bounds::short_number(c[0]),
            crate::bounds::short_number(c[1]),
            x_range.start(),
            x_range.end(),
            y_range.start(),
            y_range.end()
        ));
    }
    let (lo, hi) = ([-0.5, -0.5], [w - 0.5, h - 0.5]);
    let segments: Vec<([f64; 2], [f64; 2])> =
        edges.iter().filter_map(|&[i, j]| Some((*corners.get(i)?, *corners.get(j)?))).collect();
    let crosses = |&(a, b): &([f64; 2], [f64; 2])| clip_segment(a, b, lo, hi).is_some();
    // Even–odd rule: whether the image's centre lies inside the polygon.
    let centre = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
    let encloses_centre = segments
        .iter()
        .filter(|(a, b)| {
            (a[1] > centre[1]) != (b[1] > centre[1])
                && centre[0] < a[0] + (centre[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
        })
        .count()
        % 2
        == 1;
    if segments.iter().any(crosses) || encloses_centre {
        Ok(())
    } else {
        Err(format!("the corners' polygon lies wholly outside the {width}x{height} image: it must overlap it"))
    }
}

/// Clip the segment `a`–`b` to `[lo, hi]` in both coordinates (Liang–Barsky);
/// `None` when nothing of it is inside.
#[must_use]
pub fn clip_segment(a: [f64; 2], b: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> Option<([f64; 2], [f64; 2])> {
    let d = [b[0] - a[0], b[1] - a[1]];
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for axis in 0..2 {
        for (p, q) in [(-d[axis], a[axis] - lo[axis]), (d[axis], hi[axis] - a[axis])] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let at = |t: f64| [a[0] + t * d[0], a[1] + t * d[1]];
    Some((at(t0), at(t1)))
}

/// The displacement of each of `to`'s points when the least-squares
/// similarity transform (turn, uniform scale, shift) that takes `from` to
/// `to` is applied once more: `T(to_i) − to_i`, `T` minimising
/// Σ‖T(from_i) − to_i‖². `None` when the two lists differ in length, hold
/// fewer than two points, `from`'s points coincide, or a result is not finite.
#[must_use]
pub fn similarity_step(from: &[[f64; 2]], to: &[[f64; 2]]) -> Option<Vec<[f64; 2]>> {
    if from.len() != to.len() || from.len() < 2 {
        return None;
    }
    let n = from.len() as f64;
    let centroid = |p: &[[f64; 2]]| {
        let (sx, sy) = p.iter().fold((0.0, 0.0), |(sx, sy), q| (sx + q[0], sy + q[1]));
        [sx / n, sy / n]
    };
    let (a, b) = (centroid(from), centroid(to));
    // T(p) = b + [[c, −s], [s, c]](p − a), c = Σ u·v / Σ|u|², s = Σ u×v / Σ|u|²
    // with u = from_i − a, v = to_i − b.
    let (mut dot, mut cross, mut norm) = (0.0, 0.0, 0.0);
    for (p, q) in from.iter().zip(to) {
        let (u, v) = ([p[0] - a[0], p[1] - a[1]], [q[0] - b[0], q[1] - b[1]]);
        dot += u[0] * v[0] + u[1] * v[1];
        cross += u[0] * v[1] - u[1] * v[0];
        norm += u[0] * u[0] + u[1] * u[1];
    }
    if !(norm > MIN_CORNER_SEPARATION_PX * MIN_CORNER_SEPARATION_PX) {
        return None;
    }
    let (c, s) = (dot / norm, cross / norm);
    let step: Vec<[f64; 2]> = to
        .iter()
        .map(|q| {
            let u = [q[0] - a[0], q[1] - a[1]];
            [b[0] + c * u[0] - s * u[1] - q[0], b[1] + s * u[0] + c * u[1] - q[1]]
        })
        .collect();
    step.iter().all(|d| d[0].is_finite() && d[1].is_finite()).then_some(step)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn moved(points: &[[f64; 2]], turn: f64, scale: f64, shift: [f64; 2]) -> Vec<[f64; 2]> {
        let (s, c) = (scale * turn.sin(), scale * turn.cos());
        points.iter().map(|p| [c * p[0] - s * p[1] + shift[0], s * p[0] + c * p[1] + shift[1]]).collect()
    }

    #[test]
    fn similarity_step_repeats_an_exact_similarity() {
        let from = [[100.0, 50.0], [150.0, 40.0], [160.0, 75.0], [108.0, 83.0]];
        let to = moved(&from, 0.07, 1.03, [-12.0, 4.5]);
        let next = moved(&to, 0.07, 1.03, [-12.0, 4.5]);
        let step = similarity_step(&from, &to).unwrap();
        for ((q, d), r) in to.iter().zip(&step).zip(&next) {
            assert!((q[0] + d[0] - r[0]).abs() < 1e-9 && (q[1] + d[1] - r[1]).abs() < 1e-9, "{q:?} + {d:?} ≠ {r:?}");
        }
    }

    #[test]
    fn similarity_step_spreads_one_corners_error_over_the_outline() {
        // A shift of 10 px to the right with one corner measured 4 px off:
        // that corner's own displacement is 4 px wrong, the outline's step
        // for it much less, and no corner's step is as wrong.
        let from = [[0.0, 0.0], [40.0, 0.0], [40.0, 30.0], [0.0, 30.0]];
        let mut to = moved(&from, 0.0, 1.0, [10.0, 0.0]);
        to[2][1] += 4.0;
        let step = similarity_step(&from, &to).unwrap();
        for d in &step {
            let error = (d[0] - 10.0).hypot(d[1]);
            assert!(error < 2.5, "step {d:?}");
        }
    }

    #[test]
    fn start_polygons_must_overlap_the_image_and_stay_near_it() {
        let square = [[0usize, 1], [1, 2], [2, 3], [3, 0]];
        let ok = |c: &[[f64; 2]]| check_polygon_in_image(c, &square, 100, 80);
        // On the image, partly off it, and around the whole image.
        assert!(ok(&[[10.0, 10.0], [50.0, 10.0], [50.0, 40.0], [10.0, 40.0]]).is_ok());
        assert!(ok(&[[-50.0, 10.0], [20.0, 10.0], [20.0, 40.0], [-50.0, 40.0]]).is_ok());
        assert!(ok(&[[-90.0, -70.0], [190.0, -70.0], [190.0, 150.0], [-90.0, 150.0]]).is_ok());
        // Every corner off the image, an edge across it.
        assert!(ok(&[[-50.0, 30.0], [150.0, 30.0], [150.0, 150.0], [-50.0, 150.0]]).is_ok());
        // Wholly beside the image.
        let msg = ok(&[[110.0, 10.0], [150.0, 10.0], [150.0, 40.0], [110.0, 40.0]]).unwrap_err();
        assert!(msg.contains("wholly outside the 100x80 image"), "{msg}");
        // A corner far out, even with the rest on the image.
        let msg = ok(&[[-1e9, 0.0], [50.0, 10.0], [50.0, 40.0], [10.0, 40.0]]).unwrap_err();
        assert!(msg.starts_with("corner 0 at [-1.0e9, 0] lies more than 1 image size outside"), "{msg}");
        assert!(msg.contains("x in [-100, 200] and y in [-80, 160]"), "{msg}");
        assert!(ok(&[[10.0, 10.0], [50.0, 10.0], [50.0, 160.5], [10.0, 40.0]]).is_err());
        assert!(ok(&[[10.0, 10.0], [50.0, 10.0], [50.0, 160.0], [10.0, 40.0]]).is_ok());
    }

    #[test]
    fn similarity_step_refuses_what_has_no_transform() {
        assert!(similarity_step(&[[1.0, 1.0]], &[[2.0, 2.0]]).is_none());
        assert!(similarity_step(&[[1.0, 1.0], [1.0, 1.0]], &[[2.0, 2.0], [3.0, 3.0]]).is_none());
        assert!(similarity_step(&[[0.0, 0.0], [1.0, 0.0]], &[[2.0, 2.0]]).is_none());
        assert!(similarity_step(&[[0.0, 0.0], [1.0, 0.0]], &[[f64::NAN, 2.0], [3.0, 3.0]]).is_none());
    }
}
