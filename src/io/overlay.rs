//! Overlay images for `pipetrack track --overlay DIR` (SPEC §5): the frame in
//! grey, the motion pixels the tracker labelled tinted cyan, the model edges as
//! anti-aliased 1-px lines — yellow while tracking, red when lost — and a small
//! cross on every corner.
//!
//! Lines use Xiaolin Wu's algorithm: along the major axis one pixel pair per
//! step, the two pixels straddling the exact line weighted by their distance to
//! it. Segments are clipped to the image (Liang–Barsky) first, so corners far
//! outside cost nothing; corners that are NaN or infinite, and edges naming a
//! corner that does not exist, are skipped.

use image::RgbImage;

use crate::geometry::polygon::clip_segment;
use crate::image::GrayImage;
use crate::io::formats::Status;

/// Model colour while tracking.
pub const TRACKING_COLOUR: [u8; 3] = [255, 255, 0];
/// Model colour when lost.
pub const LOST_COLOUR: [u8; 3] = [255, 0, 0];
/// Tint of labelled motion pixels.
pub const LABELLED_COLOUR: [u8; 3] = [0, 255, 255];
/// How much of [`LABELLED_COLOUR`] is blended into a labelled pixel.
pub const LABELLED_OPACITY: f32 = 0.35;
/// Half the arm length of a corner cross, pixels.
pub const CORNER_MARKER_RADIUS: i64 = 2;

/// The colour the model is drawn in for `status`.
#[must_use]
pub fn status_colour(status: Status) -> [u8; 3] {
    match status {
        Status::Tracking => TRACKING_COLOUR,
        Status::Lost => LOST_COLOUR,
    }
}

/// Draw the overlay for one frame: `frame` as grey RGB, `labelled` motion
/// pixels `(x, y)` tinted, `edges` (pairs of indices into `corners`) as
/// anti-aliased lines and every corner as a small cross, in the colour of
/// `status`. Never panics: out-of-image pixels, non-finite corners and
/// out-of-range indices are skipped.
#[must_use]
pub fn draw_overlay(
    frame: &GrayImage,
    corners: &[[f64; 2]],
    edges: &[[usize; 2]],
    status: Status,
    labelled: &[(u32, u32)],
) -> RgbImage {
    let (w, h) = (frame.width() as u32, frame.height() as u32);
    let mut out = RgbImage::new(w, h);
    for (rgb, &v) in out.chunks_exact_mut(3).zip(frame.data()) {
        rgb.copy_from_slice(&[v, v, v]);
    }
    for &(x, y) in labelled {
        blend(&mut out, i64::from(x), i64::from(y), LABELLED_COLOUR, LABELLED_OPACITY);
    }
    let colour = status_colour(status);
    let finite = |p: &[f64; 2]| p[0].is_finite() && p[1].is_finite();
    for &[i, j] in edges {
        if let (Some(a), Some(b)) = (corners.get(i), corners.get(j))
            && finite(a)
            && finite(b)
        {
            draw_line_aa(&mut out, *a, *b, colour);
        }
    }
    for p in corners.iter().filter(|p| finite(p)) {
        draw_cross(&mut out, *p, colour);
    }
    out
}

/// Colour of the uncertainty bands (001's figures shade them light grey).
pub const BAND_COLOUR: [u8; 3] = [200, 200, 255];
/// How much of [`BAND_COLOUR`] is blended into a pixel inside a band.
pub const BAND_OPACITY: f32 = 0.35;

/// A predicted model segment with the standard deviation of its
/// perpendicular position at each end, px: the overlay shades the region
/// within two standard deviations of it, as 001's Figs. 3–6 do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeBand {
    /// First end.
    pub a: [f64; 2],
    /// Second end.
    pub b: [f64; 2],
    /// Standard deviation across the segment at `a` and at `b`, px.
    pub sigma: [f64; 2],
}

/// Shade the union of the regions within two standard deviations of each
/// band (each a quadrilateral `a ± 2σ_a·n`, `b ± 2σ_b·n`; a pixel inside
/// several is shaded once), then draw each band's segment as a line in
/// `colour`. Non-finite bands are skipped.
pub fn draw_bands(img: &mut RgbImage, bands: &[EdgeBand], colour: [u8; 3]) {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let mut inside = vec![false; w * h];
    for band in bands {
        let finite = band.a.iter().chain(&band.b).chain(&band.sigma).all(|v| v.is_finite());
        let (dx, dy) = (band.b[0] - band.a[0], band.b[1] - band.a[1]);
        let len = dx.hypot(dy);
        if !finite || len <= 0.0 {
            continue;
        }
        let (nx, ny) = (-dy / len, dx / len);
        let (ra, rb) = (2.0 * band.sigma[0], 2.0 * band.sigma[1]);
        let quad = [
            [band.a[0] + nx * ra, band.a[1] + ny * ra],
            [band.b[0] + nx * rb, band.b[1] + ny * rb],
            [band.b[0] - nx * rb, band.b[1] - ny * rb],
            [band.a[0] - nx * ra, band.a[1] - ny * ra],
        ];
        mark_convex_polygon(&mut inside, w, h, &quad);
    }
    for (k, _) in inside.iter().enumerate().filter(|(_, on)| **on) {
        blend(img, (k % w) as i64, (k / w) as i64, BAND_COLOUR, BAND_OPACITY);
    }
    for band in bands {
        if band.a.iter().chain(&band.b).all(|v| v.is_finite()) {
            draw_line_aa(img, band.a, band.b, colour);
        }
    }
}

/// Mark the pixels whose centres lie inside the convex polygon `points`
/// (either winding), row by row between the polygon's crossings.
fn mark_convex_polygon(mask: &mut [bool], w: usize, h: usize, points: &[[f64; 2]]) {
    let lo = points.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min).max(0.0).ceil();
    let hi = points.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max).min(h as f64 - 1.0).floor();
    if !(lo <= hi) {
        return;
    }
    for y in lo as usize..=hi as usize {
        let yf = y as f64;
        let (mut x0, mut x1) = (f64::INFINITY, f64::NEG_INFINITY);
        for (k, p) in points.iter().enumerate() {
            let q = points[(k + 1) % points.len()];
            if (p[1] <= yf && q[1] >= yf) || (q[1] <= yf && p[1] >= yf) {
                let x = if q[1] == p[1] { p[0].min(q[0]) } else { p[0] + (yf - p[1]) * (q[0] - p[0]) / (q[1] - p[1]) };
                let x_other = if q[1] == p[1] { p[0].max(q[0]) } else { x };
                x0 = x0.min(x);
                x1 = x1.max(x_other);
            }
        }
        let (a, b) = (x0.max(0.0).ceil(), x1.min(w as f64 - 1.0).floor());
        if a <= b {
            for x in a as usize..=b as usize {
                mask[y * w + x] = true;
            }
        }
    }
}

/// Blend `colour` into pixel `(x, y)` with weight `alpha` in 0..=1; pixels
/// outside the image are ignored.
fn blend(img: &mut RgbImage, x: i64, y: i64, colour: [u8; 3], alpha: f32) {
    if x < 0 || y < 0 || x >= i64::from(img.width()) || y >= i64::from(img.height()) {
        return;
    }
    let alpha = alpha.clamp(0.0, 1.0);
    let px = img.get_pixel_mut(x as u32, y as u32);
    for (c, &target) in px.0.iter_mut().zip(&colour) {
        *c = (f32::from(*c) * (1.0 - alpha) + f32::from(target) * alpha).round() as u8;
    }
}

/// A cross of arm [`CORNER_MARKER_RADIUS`] centred on the pixel nearest `p`.
fn draw_cross(img: &mut RgbImage, p: [f64; 2], colour: [u8; 3]) {
    let limit = f64::from(img.width().max(img.height())) + 8.0;
    if p[0].abs() > limit || p[1].abs() > limit {
        return;
    }
    let (x, y) = (p[0].round() as i64, p[1].round() as i64);
    for d in -CORNER_MARKER_RADIUS..=CORNER_MARKER_RADIUS {
        blend(img, x + d, y, colour, 1.0);
        blend(img, x, y + d, colour, 1.0);
    }
}

/// Xiaolin Wu's anti-aliased line from `a` to `b`, clipped to the image
/// (plus a one-pixel fringe so lines along the border keep their antialiasing).
fn draw_line_aa(img: &mut RgbImage, a: [f64; 2], b: [f64; 2], colour: [u8; 3]) {
    let hi = [f64::from(img.width()), f64::from(img.height())];
    let Some((a, b)) = clip_segment(a, b, [-1.0, -1.0], hi) else {
        return;
    };
    // Guard against overflow in the clip of huge (finite) coordinates: the
    // loop below is bounded only when both ends lie in the clip box.
    let inside = |p: [f64; 2]| (0..2).all(|k| p[k] >= -2.0 && p[k] <= hi[k] + 1.0);
    if !(inside(a) && inside(b)) {
        return;
    }
    let steep = (b[1] - a[1]).abs() > (b[0] - a[0]).abs();
    // Work with x as the major axis.
    let (mut a, mut b) = if steep { ([a[1], a[0]], [b[1], b[0]]) } else { (a, b) };
    if a[0] > b[0] {
        std::mem::swap(&mut a, &mut b);
    }
    let dx = b[0] - a[0];
    let gradient = if dx == 0.0 { 0.0 } else { (b[1] - a[1]) / dx };
    let mut plot = |major: i64, minor: i64, alpha: f64| {
        if steep {
            blend(img, minor, major, colour, alpha as f32);
        } else {
            blend(img, major, minor, colour, alpha as f32);
        }
    };
    let (x_start, x_end) = (a[0].round() as i64, b[0].round() as i64);
    for x in x_start..=x_end {
        let y = a[1] + gradient * (x as f64 - a[0]);
        let y_floor = y.floor();
        let frac = y - y_floor;
        plot(x, y_floor as i64, 1.0 - frac);
        plot(x, y_floor as i64 + 1, frac);
    }
}

#[cfg(test)]
mod tests {
    use image::Rgb;

    use super::*;

    /// A horizontal band with σ = 2 px shades the pixels within 4 px of
    /// its line and nothing beyond, and draws the line itself.
    #[test]
    fn band_shades_two_sigmas_around_its_segment() {
        let mut img = RgbImage::from_pixel(40, 30, Rgb([0, 0, 0]));
        let band = EdgeBand { a: [5.0, 15.0], b: [35.0, 15.0], sigma: [2.0, 2.0] };
        draw_bands(&mut img, &[band, EdgeBand { a: [f64::NAN, 0.0], ..band }], TRACKING_COLOUR);
        let shaded = |x: u32, y: u32| img.get_pixel(x, y).0 != [0, 0, 0];
        for y in 11..=19 {
            assert!(shaded(20, y), "row {y} inside the band");
        }
        assert!(!shaded(20, 10) && !shaded(20, 20), "rows beyond 2σ");
        assert!(!shaded(3, 15) && !shaded(37, 15), "beyond the ends");
        assert_eq!(img.get_pixel(20, 15).0, TRACKING_COLOUR, "the line on top");
    }
}
