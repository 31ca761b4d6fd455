//! Zero crossings by position, for the verification's outline support.
//!
//! A model segment is sampled every pixel (less [`END_MARGIN_PX`] at each
//! end). A sample is supported when a zero crossing at or above the
//! hysteresis' low threshold lies within 1 px of it across the segment and
//! within 1 px along it, with its edge orientation (the gradient direction
//! turned by 90°) within `angle` of the segment's. The map is a byte per
//! window pixel holding the quantised orientation of the crossing there (0:
//! none), rebuilt each frame into the same buffer.

use crate::early::{Feature, Window};
use std::f64::consts::{FRAC_PI_2, PI};

use crate::estimate::line_fit::rem_pi;

/// Samples closer than this to a segment's end points are not taken, px
/// (two edges blur into each other at a corner).
pub const END_MARGIN_PX: f64 = 2.0;
/// Orientation levels over [0, π) (1 ..= 255; 0 marks an empty pixel).
const LEVELS: f64 = 255.0;

/// Zero-crossing orientations over a window of interest.
#[derive(Clone, Debug, Default)]
pub struct CrossingMap {
    window: Window,
    width: usize,
    height: usize,
    /// Row after row of the window, then a spare cell.
    cells: Vec<u8>,
}

impl CrossingMap {
    /// Refill the map with the crossings of `crossings` inside `window`
    /// whose magnitude is at least `min_magnitude` (a later crossing at the
    /// same pixel replacing an earlier one).
    pub fn rebuild(&mut self, crossings: &[Feature], window: Window, min_magnitude: f32) {
        self.window = window;
        self.width = (window.x1.saturating_sub(window.x0)) as usize;
        self.height = (window.y1.saturating_sub(window.y0)) as usize;
        // One more cell, past the window's, takes the writes of the
        // crossings left out, so that no branch depends on the crossing.
        let spare = self.width * self.height;
        self.cells.clear();
        self.cells.resize(spare + 1, 0);
        for f in crossings {
            let inside = (f.x >= window.x0) & (f.y >= window.y0) & (f.x < window.x1) & (f.y < window.y1);
            let taken = inside & !(f.magnitude < min_magnitude) & f.theta.is_finite();
            let at = (f.y.wrapping_sub(window.y0)) as usize * self.width + (f.x.wrapping_sub(window.x0)) as usize;
            let edge = rem_pi(f64::from(f.theta) + FRAC_PI_2);
            self.cells[if taken { at } else { spare }] = 1 + ((edge / PI * LEVELS) as u8).min(254);
        }
    }

    /// Orientation level at pixel (x, y); 0 outside the window or where
    /// there is no crossing.
    fn level(&self, x: i64, y: i64) -> u8 {
        let (cx, cy) = (x - i64::from(self.window.x0), y - i64::from(self.window.y0));
        if cx < 0 || cy < 0 || cx >= self.width as i64 || cy >= self.height as i64 {
            return 0;
        }
        self.cells[cy as usize * self.width + cx as usize]
    }

    /// `(supported, samples)` over the segments `lines` (module doc), with
    /// orientations within `angle` radians.
    #[must_use]
    pub fn support(&self, lines: impl Iterator<Item = ([f64; 2], [f64; 2])>, angle: f64) -> (usize, usize) {
        let tolerance = angle / std::f64::consts::PI * LEVELS;
        let (mut supported, mut samples) = (0, 0);
        for (p, q) in lines {
            let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
            let length = dx.hypot(dy);
            if !(length.is_finite() && length > 2.0 * END_MARGIN_PX) {
                continue;
            }
            let (ux, uy) = (dx / length, dy / length);
            let orientation = dy.atan2(dx).rem_euclid(std::f64::consts::PI) / std::f64::consts::PI * LEVELS;
            let matches_level = |level: u8| {
                if level == 0 {
                    return false;
                }
                let d = (f64::from(level - 1) + 0.5 - orientation).abs();
                d.min(LEVELS - d) <= tolerance
            };
            let mut s = END_MARGIN_PX;
            while s <= length - END_MARGIN_PX {
                samples += 1;
                let c = [p[0] + s * ux, p[1] + s * uy];
                let (x0, y0) = (c[0].round() as i64, c[1].round() as i64);
                let hit = (-1..=1).any(|j| {
                    (-1..=1).any(|i| {
                        let (rx, ry) = ((x0 + i) as f64 - c[0], (y0 + j) as f64 - c[1]);
                        (rx * uy - ry * ux).abs() <= 1.0
                            && (rx * ux + ry * uy).abs() <= 1.0
                            && matches_level(self.level(x0 + i, y0 + j))
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

#[cfg(test)]
mod tests {
    use super::*;

    fn horizontal(y: u32, xs: std::ops::Range<u32>, magnitude: f32) -> Vec<Feature> {
        // A horizontal edge: the gradient points along y.
        xs.map(|x| Feature { x, y, theta: std::f32::consts::FRAC_PI_2, magnitude }).collect()
    }

    #[test]
    fn a_segment_on_its_edge_is_supported_and_one_beside_it_is_not() {
        let window = Window { x0: 5, y0: 5, x1: 120, y1: 60 };
        let mut map = CrossingMap::default();
        map.rebuild(&horizontal(30, 10..110, 5.0), window, 1.5);
        let angle = 20f64.to_radians();
        let on = map.support([([10.0, 30.4], [109.0, 30.4])].into_iter(), angle);
        assert_eq!(on.0, on.1);
        assert_eq!(on.1, 96);
        let beside = map.support([([10.0, 32.5], [109.0, 32.5])].into_iter(), angle);
        assert_eq!(beside.0, 0);
        // Turned by 30°: only the samples near the crossing line count, and
        // not at this orientation.
        let turned = map.support([([20.0, 30.0], [80.0, 30.0 + 60.0 * 30f64.to_radians().tan()])].into_iter(), angle);
        assert_eq!(turned.0, 0);
        // A weak edge below the threshold supports nothing.
        map.rebuild(&horizontal(30, 10..110, 1.0), window, 1.5);
        assert_eq!(map.support([([10.0, 30.0], [109.0, 30.0])].into_iter(), angle).0, 0);
    }

    #[test]
    fn rebuilding_forgets_the_last_frame() {
        let window = Window { x0: 0, y0: 0, x1: 64, y1: 48 };
        let mut map = CrossingMap::default();
        map.rebuild(&horizontal(20, 0..64, 5.0), window, 1.5);
        map.rebuild(&horizontal(40, 0..64, 5.0), window, 1.5);
        let angle = 20f64.to_radians();
        assert_eq!(map.support([([0.0, 20.0], [63.0, 20.0])].into_iter(), angle).0, 0);
        assert!(map.support([([0.0, 40.0], [63.0, 40.0])].into_iter(), angle).0 > 50);
    }
}
