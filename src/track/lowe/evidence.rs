//! Zero crossings by position, for the verification's outline support.
//!
//! A model segment is sampled every pixel (less [`END_MARGIN_PX`] at each
//! end). A sample is supported when a zero crossing at or above the
//! hysteresis' low threshold lies within 1 px of it across the segment and
//! within 1 px along it, with its edge orientation (the gradient direction
//! turned by 90°) within `angle` of the segment's, and, where the segment
//! names the side of it that must be dark, with its gradient (from the
//! bright side to the dark side) pointing to that side. The map is a byte
//! per window pixel holding the quantised orientation of the crossing
//! there (0: none), and when asked a second byte with its gradient's
//! direction, rebuilt each frame into the same buffers.

use crate::early::{Feature, Window};
use std::f64::consts::{FRAC_PI_2, PI};

use crate::estimate::line_fit::rem_pi;

/// Samples closer than this to a segment's end points are not taken, px
/// (two edges blur into each other at a corner).
pub const END_MARGIN_PX: f64 = 2.0;
/// Orientation levels over [0, π), direction levels over [0, 2π) (1 ..=
/// 255; 0 marks an empty pixel).
const LEVELS: f64 = 255.0;

/// Zero-crossing orientations over a window of interest.
#[derive(Clone, Debug, Default)]
pub struct CrossingMap {
    window: Window,
    width: usize,
    height: usize,
    /// Row after row of the window, then a spare cell.
    cells: Vec<u8>,
    /// The crossings' gradient directions, laid out as `cells`; empty
    /// unless the map was rebuilt with directions.
    directions: Vec<u8>,
}

impl CrossingMap {
    /// Refill the map with the crossings of `crossings` inside `window`
    /// whose magnitude is at least `min_magnitude` (a later crossing at the
    /// same pixel replacing an earlier one); their gradients' directions
    /// too when `with_directions`.
    pub fn rebuild(&mut self, crossings: &[Feature], window: Window, min_magnitude: f32, with_directions: bool) {
        self.window = window;
        self.width = (window.x1.saturating_sub(window.x0)) as usize;
        self.height = (window.y1.saturating_sub(window.y0)) as usize;
        // One more cell, past the window's, takes the writes of the
        // crossings left out, so that no branch depends on the crossing.
        let spare = self.width * self.height;
        self.cells.clear();
        self.cells.resize(spare + 1, 0);
        self.directions.clear();
        if with_directions {
            self.directions.resize(spare + 1, 0);
        }
        for f in crossings {
            let inside = (f.x >= window.x0) & (f.y >= window.y0) & (f.x < window.x1) & (f.y < window.y1);
            let taken = inside & !(f.magnitude < min_magnitude) & f.theta.is_finite();
            let at = (f.y.wrapping_sub(window.y0)) as usize * self.width + (f.x.wrapping_sub(window.x0)) as usize;
            let edge = rem_pi(f64::from(f.theta) + FRAC_PI_2);
            self.cells[if taken { at } else { spare }] = 1 + ((edge / PI * LEVELS) as u8).min(254);
            if with_directions {
                let direction = f64::from(f.theta).rem_euclid(2.0 * PI);
                self.directions[if taken { at } else { spare }] =
                    1 + ((direction / (2.0 * PI) * LEVELS) as u8).min(254);
            }
        }
    }

    /// Orientation level at pixel (x, y); 0 outside the window or where
    /// there is no crossing.
    fn level(&self, x: i64, y: i64) -> u8 {
        self.cell(x, y).map_or(0, |k| self.cells[k])
    }

    /// Gradient direction at pixel (x, y), radians in [0, 2π) (the middle
    /// of its level); `None` outside the window, where there is no
    /// crossing, or when the map holds no directions.
    fn direction(&self, x: i64, y: i64) -> Option<f64> {
        let level = *self.directions.get(self.cell(x, y)?)?;
        (level > 0).then(|| (f64::from(level - 1) + 0.5) / LEVELS * 2.0 * PI)
    }

    /// Whether the crossing at pixel (x, y) is dark on side `side` (±1; 0:
    /// either) of a line of direction `u`: its gradient points from the
    /// bright side to the dark side.
    fn dark_on_side(&self, x: i64, y: i64, side: f64, u: [f64; 2]) -> bool {
        side == 0.0 || self.direction(x, y).is_some_and(|a| (a.sin() * u[0] - a.cos() * u[1]) * side > 0.0)
    }

    /// Index of pixel (x, y) in the window's cells.
    fn cell(&self, x: i64, y: i64) -> Option<usize> {
        let (cx, cy) = (x - i64::from(self.window.x0), y - i64::from(self.window.y0));
        (cx >= 0 && cy >= 0 && cx < self.width as i64 && cy < self.height as i64)
            .then(|| cy as usize * self.width + cx as usize)
    }

    /// `(supported, samples)` over the segments `lines` (module doc), with
    /// orientations within `angle` radians. Each line `(p, q, side)` with
    /// `side` ±1 is supported only by crossings dark on that side of it
    /// (+1: along its normal, `p → q` turned by +90°) and needs a map
    /// rebuilt with directions; 0 takes either.
    #[must_use]
    pub fn support(&self, lines: impl Iterator<Item = ([f64; 2], [f64; 2], f64)>, angle: f64) -> (usize, usize) {
        let tolerance = angle / std::f64::consts::PI * LEVELS;
        let (mut supported, mut samples) = (0, 0);
        let (x0w, y0w) = (i64::from(self.window.x0), i64::from(self.window.y0));
        let (w, h) = (self.width as i64, self.height as i64);
        for (p, q, side) in lines {
            let Some((length, [ux, uy], orientation)) = sampled_line(p, q) else { continue };
            // Whether each level lies within the tolerance of the line's
            // orientation, worked out the first time a sample meets it (0:
            // not yet, 1: no, 2: yes); level 0, no crossing, never does.
            let mut accepts = [0u8; 256];
            accepts[0] = 1;
            let mut matches_level = |level: u8| {
                let known = &mut accepts[usize::from(level)];
                if *known == 0 {
                    *known = if level_within(level, orientation, tolerance) { 2 } else { 1 };
                }
                *known == 2
            };
            let mut s = END_MARGIN_PX;
            while s <= length - END_MARGIN_PX {
                samples += 1;
                let c = [p[0] + s * ux, p[1] + s * uy];
                let (xc, yc) = (c[0].round() as i64, c[1].round() as i64);
                // The crossings of the 3×3 pixels around the sample: most
                // hold none, so look first and measure after.
                let (cx, cy) = (xc - x0w, yc - y0w);
                let mut levels = [0u8; 9];
                if cx >= 1 && cy >= 1 && cx + 1 < w && cy + 1 < h {
                    let at = (cy - 1) as usize * self.width + (cx - 1) as usize;
                    for (j, row) in levels.chunks_exact_mut(3).enumerate() {
                        row.copy_from_slice(&self.cells[at + j * self.width..at + j * self.width + 3]);
                    }
                } else {
                    for (k, level) in levels.iter_mut().enumerate() {
                        *level = self.level(xc + k as i64 % 3 - 1, yc + k as i64 / 3 - 1);
                    }
                }
                let hit = levels.iter().enumerate().any(|(k, &level)| {
                    matches_level(level) && {
                        let (x, y) = (xc + k as i64 % 3 - 1, yc + k as i64 / 3 - 1);
                        let (rx, ry) = (x as f64 - c[0], y as f64 - c[1]);
                        (rx * uy - ry * ux).abs() <= 1.0
                            && (rx * ux + ry * uy).abs() <= 1.0
                            && self.dark_on_side(x, y, side, [ux, uy])
                    }
                });
                if hit {
                    supported += 1;
                }
                s += 1.0;
            }
        }
        (supported, samples)
    }
}

/// The line `p → q` as [`CrossingMap::support`] samples it: its length,
/// unit direction and orientation in levels; `None` when it is not finite
/// or too short to leave a sample between the end margins.
fn sampled_line(p: [f64; 2], q: [f64; 2]) -> Option<(f64, [f64; 2], f64)> {
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    let length = dx.hypot(dy);
    if !(length.is_finite() && length > 2.0 * END_MARGIN_PX) {
        return None;
    }
    let orientation = dy.atan2(dx).rem_euclid(PI) / PI * LEVELS;
    Some((length, [dx / length, dy / length], orientation))
}

/// Whether orientation level `level` (1 ..= 255) lies within `tolerance`
/// levels of `orientation`, round the half turn.
fn level_within(level: u8, orientation: f64, tolerance: f64) -> bool {
    let d = (f64::from(level - 1) + 0.5 - orientation).abs();
    d.min(LEVELS - d) <= tolerance
}

#[cfg(test)]
mod tests {
    use super::*;

    impl CrossingMap {
        /// [`CrossingMap::support`] pixel by pixel through [`CrossingMap::level`].
        fn support_pixel_by_pixel(
            &self,
            lines: impl Iterator<Item = ([f64; 2], [f64; 2], f64)>,
            angle: f64,
        ) -> (usize, usize) {
            let tolerance = angle / std::f64::consts::PI * LEVELS;
            let (mut supported, mut samples) = (0, 0);
            for (p, q, side) in lines {
                let Some((length, [ux, uy], orientation)) = sampled_line(p, q) else { continue };
                let matches_level = |level: u8| level != 0 && level_within(level, orientation, tolerance);
                let dark_on_side = |x: i64, y: i64| self.dark_on_side(x, y, side, [ux, uy]);
                let mut s = END_MARGIN_PX;
                while s <= length - END_MARGIN_PX {
                    samples += 1;
                    let c = [p[0] + s * ux, p[1] + s * uy];
                    let (x0, y0) = (c[0].round() as i64, c[1].round() as i64);
                    // Most pixels hold no crossing: look first, measure after.
                    let hit = (-1..=1).any(|j| {
                        (-1..=1).any(|i| {
                            matches_level(self.level(x0 + i, y0 + j)) && {
                                let (rx, ry) = ((x0 + i) as f64 - c[0], (y0 + j) as f64 - c[1]);
                                (rx * uy - ry * ux).abs() <= 1.0
                                    && (rx * ux + ry * uy).abs() <= 1.0
                                    && dark_on_side(x0 + i, y0 + j)
                            }
                        })
                    });
                    if hit {
                        supported += 1;
                    }
                    s += 1.0;
                }
            }
            (supported, samples)
        }
    }

    fn horizontal(y: u32, xs: std::ops::Range<u32>, magnitude: f32) -> Vec<Feature> {
        // A horizontal edge: the gradient points along y.
        xs.map(|x| Feature { x, y, theta: std::f32::consts::FRAC_PI_2, magnitude }).collect()
    }

    #[test]
    fn a_segment_on_its_edge_is_supported_and_one_beside_it_is_not() {
        let window = Window { x0: 5, y0: 5, x1: 120, y1: 60 };
        let mut map = CrossingMap::default();
        map.rebuild(&horizontal(30, 10..110, 5.0), window, 1.5, false);
        let angle = 20f64.to_radians();
        let on = map.support([([10.0, 30.4], [109.0, 30.4], 0.0)].into_iter(), angle);
        assert_eq!(on.0, on.1);
        assert_eq!(on.1, 96);
        let beside = map.support([([10.0, 32.5], [109.0, 32.5], 0.0)].into_iter(), angle);
        assert_eq!(beside.0, 0);
        // Turned by 30°: only the samples near the crossing line count, and
        // not at this orientation.
        let turned =
            map.support([([20.0, 30.0], [80.0, 30.0 + 60.0 * 30f64.to_radians().tan()], 0.0)].into_iter(), angle);
        assert_eq!(turned.0, 0);
        // A weak edge below the threshold supports nothing.
        map.rebuild(&horizontal(30, 10..110, 1.0), window, 1.5, false);
        assert_eq!(map.support([([10.0, 30.0], [109.0, 30.0], 0.0)].into_iter(), angle).0, 0);
    }

    #[test]
    fn rebuilding_forgets_the_last_frame() {
        let window = Window { x0: 0, y0: 0, x1: 64, y1: 48 };
        let mut map = CrossingMap::default();
        map.rebuild(&horizontal(20, 0..64, 5.0), window, 1.5, false);
        map.rebuild(&horizontal(40, 0..64, 5.0), window, 1.5, false);
        let angle = 20f64.to_radians();
        assert_eq!(map.support([([0.0, 20.0], [63.0, 20.0], 0.0)].into_iter(), angle).0, 0);
        assert!(map.support([([0.0, 40.0], [63.0, 40.0], 0.0)].into_iter(), angle).0 > 50);
    }

    /// A line that names its dark side is supported only by crossings dark
    /// on that side: the same edge supports it one way round and not the
    /// other, and a map without directions supports neither.
    #[test]
    fn a_line_with_a_dark_side_takes_only_crossings_of_that_contrast() {
        let window = Window { x0: 0, y0: 0, x1: 120, y1: 60 };
        let mut map = CrossingMap::default();
        // Gradient along +y: bright above, dark below.
        map.rebuild(&horizontal(30, 10..110, 5.0), window, 1.5, true);
        let angle = 20f64.to_radians();
        let (rightwards, leftwards) = (([10.0, 30.0], [109.0, 30.0]), ([109.0, 30.0], [10.0, 30.0]));
        let count =
            |map: &CrossingMap, (p, q): ([f64; 2], [f64; 2]), side: f64| map.support([(p, q, side)].into_iter(), angle);
        let all = count(&map, rightwards, 0.0);
        assert_eq!(all.0, all.1);
        // Rightwards, the normal points down (+y), the dark side.
        assert_eq!(count(&map, rightwards, 1.0), all);
        assert_eq!(count(&map, rightwards, -1.0).0, 0);
        assert_eq!(count(&map, leftwards, -1.0), all);
        assert_eq!(count(&map, leftwards, 1.0).0, 0);
        map.rebuild(&horizontal(30, 10..110, 5.0), window, 1.5, false);
        assert_eq!(count(&map, rightwards, 0.0), all);
        assert_eq!(count(&map, rightwards, 1.0).0, 0);
    }

    /// The support of random lines (inside, across the border and outside
    /// the window, with and without a dark side) over random crossings
    /// (dense and sparse, on the window's border rows and columns) is what
    /// the pixel-by-pixel count gives.
    #[test]
    fn support_equals_the_pixel_by_pixel_count() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut supported = 0;
        for case in 0..200 {
            let (x0, y0) = (rng.random_range(0..20), rng.random_range(0..20));
            let window = Window { x0, y0, x1: x0 + rng.random_range(1..60), y1: y0 + rng.random_range(1..50) };
            let density = [0.02, 0.2, 0.8][case % 3];
            let mut crossings = Vec::new();
            for y in y0.saturating_sub(2)..window.y1 + 2 {
                for x in x0.saturating_sub(2)..window.x1 + 2 {
                    if rng.random_bool(density) {
                        let theta = rng.random_range(-4.0f32..4.0);
                        crossings.push(Feature { x, y, theta, magnitude: rng.random_range(0.0..4.0) });
                    }
                }
            }
            let with_directions = case % 2 == 0;
            let mut map = CrossingMap::default();
            map.rebuild(&crossings, window, 1.5, with_directions);
            let point = |rng: &mut rand_chacha::ChaCha8Rng| {
                [
                    rng.random_range(f64::from(x0) - 5.0..f64::from(window.x1) + 5.0),
                    rng.random_range(f64::from(y0) - 5.0..f64::from(window.y1) + 5.0),
                ]
            };
            let lines: Vec<([f64; 2], [f64; 2], f64)> =
                (0..12).map(|_| (point(&mut rng), point(&mut rng), [0.0, 1.0, -1.0][rng.random_range(0..3)])).collect();
            let angle = rng.random_range(0.05..0.6);
            let fast = map.support(lines.iter().copied(), angle);
            assert_eq!(fast, map.support_pixel_by_pixel(lines.iter().copied(), angle), "case {case}");
            assert!(fast.1 > 0, "case {case}: no samples");
            supported += fast.0;
        }
        assert!(supported > 1000, "{supported} samples supported in all");
    }
}
