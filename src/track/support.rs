//! Image support of a predicted model contour: the check a tracker makes
//! before it reports `tracking` (STYLE: "`tracking` is a claim the tracker
//! checks").
//!
//! The contour is sampled every [`SAMPLE_STEP_PX`] along each visible model
//! segment (less [`END_MARGIN_PX`] at each end, where two edges blur into each
//! other). A sample is *supported* when an edge pixel lies within `distance`
//! of it, perpendicular to the segment, no further than half a sample step plus half a pixel
//! along it, with its edge orientation within `angle` of the segment's
//! (modulo π). The support is the supported fraction of all samples; a
//! segment outside the image has no edge pixels and counts as unsupported,
//! so an object panned out of view loses its support with the part it
//! takes out.

use crate::early::Feature;
use crate::estimate::line_fit::orientation_difference;
use crate::track::round_to_i64;

/// Distance between contour samples, px.
pub const SAMPLE_STEP_PX: f64 = 1.0;
/// Samples closer than this to a segment's end points are not taken, px.
pub const END_MARGIN_PX: f64 = 2.0;
/// Slack of the box of cells searched around a sample, px.
const BOX_MARGIN_PX: f64 = 1e-6;

/// Edge pixels indexed by position: the strongest pixel's edge orientation
/// per cell (NaN where there is none).
#[derive(Clone, Debug, Default)]
pub struct EdgeMap {
    x0: i64,
    y0: i64,
    width: usize,
    height: usize,
    orientation: Vec<f32>,
    magnitude: Vec<f32>,
}

impl EdgeMap {
    /// The map of `features` whose magnitude is at least `min_magnitude`;
    /// `orientation_of` gives a feature's edge orientation (radians, mod π).
    #[must_use]
    pub fn new(features: &[Feature], min_magnitude: f32, orientation_of: impl Fn(&Feature) -> f64) -> Self {
        let strong = || features.iter().filter(|f| f.magnitude >= min_magnitude && f.theta.is_finite());
        let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0u32, 0u32);
        for f in strong() {
            x0 = x0.min(f.x);
            y0 = y0.min(f.y);
            x1 = x1.max(f.x);
            y1 = y1.max(f.y);
        }
        if x0 > x1 {
            return Self::default();
        }
        let (width, height) = ((x1 - x0) as usize + 1, (y1 - y0) as usize + 1);
        let mut map = Self {
            x0: i64::from(x0),
            y0: i64::from(y0),
            width,
            height,
            orientation: vec![f32::NAN; width * height],
            magnitude: vec![f32::NEG_INFINITY; width * height],
        };
        for f in strong() {
            let i = (f.y - y0) as usize * width + (f.x - x0) as usize;
            if f.magnitude > map.magnitude[i] {
                map.magnitude[i] = f.magnitude;
                map.orientation[i] = orientation_of(f) as f32;
            }
        }
        map
    }

    /// Edge orientation at pixel (x, y), if an edge pixel is there.
    fn at(&self, x: i64, y: i64) -> Option<f64> {
        let (cx, cy) = (x - self.x0, y - self.y0);
        if cx < 0 || cy < 0 || cx >= self.width as i64 || cy >= self.height as i64 {
            return None;
        }
        let o = self.orientation[cy as usize * self.width + cx as usize];
        o.is_finite().then_some(f64::from(o))
    }

    /// Index of pixel (x, y) in the map when every pixel within `box_x` of
    /// it in x and `box_y` in y is inside the map.
    fn index_of_box(&self, x: i64, y: i64, box_x: i64, box_y: i64) -> Option<i64> {
        let (cx, cy) = (x - self.x0, y - self.y0);
        let inside =
            cx - box_x >= 0 && cy - box_y >= 0 && cx + box_x < self.width as i64 && cy + box_y < self.height as i64;
        inside.then_some(cy * self.width as i64 + cx)
    }

    /// Support of the segments `segments` (module doc): `(supported, samples)`.
    #[must_use]
    pub fn support(&self, segments: &[([f64; 2], [f64; 2])], distance: f64, angle: f64) -> (usize, usize) {
        total(&self.support_by_segment(segments, distance, angle))
    }

    /// Support of each segment of `segments` (module doc): `(supported,
    /// samples)` per segment, in order; `(0, 0)` for a segment too short to
    /// sample.
    #[must_use]
    pub fn support_by_segment(
        &self,
        segments: &[([f64; 2], [f64; 2])],
        distance: f64,
        angle: f64,
    ) -> Vec<(usize, usize)> {
        let reach = distance.ceil() as i64 + 1;
        // Cells around a sample, nearest first: a supported sample usually
        // finds its edge pixel among the first few.
        let mut cells: Vec<(i64, i64)> = (-reach..=reach).flat_map(|j| (-reach..=reach).map(move |i| (i, j))).collect();
        cells.sort_by_key(|&(i, j)| i * i + j * j);
        let half_along = 0.5 * SAMPLE_STEP_PX + 0.5;
        let mut near = Vec::with_capacity(cells.len());
        let mut near_offsets = Vec::with_capacity(cells.len());
        segments
            .iter()
            .map(|&(p, q)| {
                let (mut supported, mut samples) = (0, 0);
                let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
                let length = dx.hypot(dy);
                if !(length.is_finite() && length > 2.0 * END_MARGIN_PX) {
                    return (0, 0);
                }
                let (ux, uy) = (dx / length, dy / length);
                let orientation = dy.atan2(dx).rem_euclid(std::f64::consts::PI);
                // A pixel within `distance` across and `half_along` along lies
                // at most this far from the rounded sample in x and in y (half
                // a pixel of rounding, and a margin far above float error).
                let box_x = (half_along * ux.abs() + distance * uy.abs() + 0.5 + BOX_MARGIN_PX).floor() as i64;
                let box_y = (half_along * uy.abs() + distance * ux.abs() + 0.5 + BOX_MARGIN_PX).floor() as i64;
                near.clear();
                near.extend(cells.iter().filter(|&&(i, j)| i.abs() <= box_x && j.abs() <= box_y));
                near_offsets.clear();
                near_offsets.extend(near.iter().map(|&(i, j)| j * self.width as i64 + i));
                for c in sample_positions(p, q) {
                    samples += 1;
                    let (cx, cy) = (round_to_i64(c[0]), round_to_i64(c[1]));
                    let supports = |(i, j): (i64, i64), o: f64| {
                        let (rx, ry) = ((cx + i) as f64 - c[0], (cy + j) as f64 - c[1]);
                        let along = rx * ux + ry * uy;
                        let across = rx * uy - ry * ux;
                        across.abs() <= distance
                            && along.abs() <= half_along
                            && orientation_difference(o, orientation) < angle
                    };
                    // Most cells hold no edge pixel: look first, measure after.
                    let hit = match self.index_of_box(cx, cy, box_x, box_y) {
                        Some(centre) => near.iter().zip(&near_offsets).any(|(&cell, &offset)| {
                            let o = self.orientation[(centre + offset) as usize];
                            o.is_finite() && supports(cell, f64::from(o))
                        }),
                        None => near.iter().any(|&(i, j)| self.at(cx + i, cy + j).is_some_and(|o| supports((i, j), o))),
                    };
                    if hit {
                        supported += 1;
                    }
                }
                (supported, samples)
            })
            .collect()
    }
}

/// The points of the segment `p → q` where [`EdgeMap::support`] samples
/// it (module doc): every [`SAMPLE_STEP_PX`] from [`END_MARGIN_PX`] after
/// `p` to [`END_MARGIN_PX`] before `q`; none for a segment too short or not
/// finite.
pub fn sample_positions(p: [f64; 2], q: [f64; 2]) -> impl Iterator<Item = [f64; 2]> {
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    let length = dx.hypot(dy);
    let (ux, uy) = (dx / length, dy / length);
    let last =
        if length.is_finite() && length > 2.0 * END_MARGIN_PX { length - END_MARGIN_PX } else { f64::NEG_INFINITY };
    std::iter::successors(Some(END_MARGIN_PX), |s| Some(s + SAMPLE_STEP_PX))
        .take_while(move |&s| s <= last)
        .map(move |s| [p[0] + s * ux, p[1] + s * uy])
}

/// The segments moved by `offset` px along their left normal.
#[must_use]
pub fn offset_segments(segments: &[([f64; 2], [f64; 2])], offset: f64) -> Vec<([f64; 2], [f64; 2])> {
    segments
        .iter()
        .map(|&(p, q)| {
            let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
            let l = dx.hypot(dy).max(f64::MIN_POSITIVE);
            let (nx, ny) = (-dy / l * offset, dx / l * offset);
            ([p[0] + nx, p[1] + ny], [q[0] + nx, q[1] + ny])
        })
        .collect()
}

/// The sum of per-segment `(supported, samples)` counts.
#[must_use]
pub fn total(counts: &[(usize, usize)]) -> (usize, usize) {
    counts.iter().fold((0, 0), |(s, n), &(si, ni)| (s + si, n + ni))
}

/// Supported fraction of `(supported, samples)`; 0 without samples.
#[must_use]
pub fn fraction((supported, samples): (usize, usize)) -> f64 {
    if samples == 0 { 0.0 } else { supported as f64 / samples as f64 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn horizontal_edge(y: u32, xs: std::ops::Range<u32>) -> Vec<Feature> {
        xs.map(|x| Feature { x, y, theta: 0.0, magnitude: 100.0 }).collect()
    }

    #[test]
    fn support_counts_samples_with_a_matching_edge_nearby() {
        // Edge pixels along y = 10 for x in 0..20 (orientation 0).
        let map = EdgeMap::new(&horizontal_edge(10, 0..20), 50.0, |f| f64::from(f.theta));
        // A segment from x = 0 to 40 at y = 11: samples at 2, 3, ..., 38 (37);
        // a pixel supports samples up to 1 px along (half a step plus half a
        // pixel), so those at x ≤ 20 are supported (19).
        assert_eq!(map.support(&[([0.0, 11.0], [40.0, 11.0])], 2.0, 0.2), (19, 37));
        // 4 px away: nothing within 2 px.
        assert_eq!(map.support(&[([0.0, 14.0], [40.0, 14.0])], 2.0, 0.2).0, 0);
        // A vertical segment through the edge pixels: wrong orientation.
        assert_eq!(map.support(&[([5.0, 0.0], [5.0, 20.0])], 2.0, 0.2).0, 0);
        assert_eq!(fraction((18, 36)), 0.5);
        assert_eq!(fraction((0, 0)), 0.0);
        // Weak pixels are not edges.
        let weak = EdgeMap::new(&horizontal_edge(10, 0..20), 200.0, |f| f64::from(f.theta));
        assert_eq!(weak.support(&[([0.0, 10.0], [20.0, 10.0])], 2.0, 0.2).0, 0);
    }
}
