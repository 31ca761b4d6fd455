//! Sobel 3×3 gradient (000 eq. 2, 002 §2.3) with clamp-to-edge borders.
//!
//! Kernels, with x to the right and y down:
//!
//! ```text
//! gx = [-1 0 1]      gy = [-1 -2 -1]
//!      [-2 0 2]           [ 0  0  0]
//!      [-1 0 1]           [ 1  2  1]
//! ```
//!
//! so `gx > 0` where intensity grows to the right and `gy > 0` where it grows
//! downward. Five f32 planes come out of one pass:
//!
//! - `gx`, `gy`, and `magnitude = sqrt(gx² + gy²)`;
//! - `direction`: the gradient direction `atan2(gy, gx)` in `(−π, π]`
//!   (measured from +x towards +y, i.e. clockwise on screen);
//! - `theta`: the edge orientation of 000 eq. 2,
//!   `θ = atan(gy / gx) + π/2`, perpendicular to the gradient, as an
//!   undirected line orientation in `[0, π)`, measured from +x towards +y.
//!   A vertical edge line (gradient along x, `gy = 0`) has `θ = π/2`; a
//!   horizontal one (`gx = 0`, `gy ≠ 0`, where `atan(±∞) + π/2` is `π` or
//!   `0`) has `θ = 0`; a line from bottom-left to top-right on screen
//!   (gradient along (1, 1)) has `θ = 3π/4`.
//!
//! Where `gx = gy = 0` (magnitude 0) the angles are undefined; both twins
//! write `direction = 0` and `theta = π/2` (`atan(0) + π/2`) there, never
//! evaluating `atan2(0, 0)`, which is not portable across GPUs.
//!
//! Both twins compute the angles the same way, from one `a = atan(gy / gx)`
//! ([`super::angle::fast_atan_quotient`], one division):
//! `θ = a + π/2` (a result that rounds to below 0 or to π or above becomes
//! 0); `direction = a` for `gx > 0`, `a + π` for `gx < 0 ≤ gy`, `a − π` for
//! `gx < 0, gy < 0` (a result that rounds to `−π` becomes `π`); `±π/2` for
//! `gx = 0`. `gx` and `gy` are formed in the same order as in
//! `shaders/sobel.wgsl`: `gx` as the difference of the right and left
//! columns' `[1 2 1]` sums, `gy` as the `[1 2 1]` sum of the three columns'
//! `down − up` differences.

use std::f32::consts::{FRAC_PI_2, PI};
use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::Window;
use super::angle::fast_atan_quotient;
use super::rows::for_each_row;
use crate::Result;
use crate::gpu::{
    Binding::{ReadOnly, Storage, Uniform},
    EntryPoint, GpuContext, GpuImage, Recorder, ShaderDef, run_once,
};
use crate::image::FloatImage;

/// The shader of this stage.
pub const SHADER: ShaderDef = ShaderDef {
    name: "sobel",
    source: include_str!("../../shaders/sobel.wgsl"),
    includes: &[super::angle::INCLUDE],
    entry_points: &[EntryPoint::tiled("sobel", &[Uniform, ReadOnly, Storage, Storage, Storage, Storage, Storage])],
    overrides: &[],
};

/// The five planes of the Sobel stage on the CPU, all the same size.
#[derive(Clone, Debug, PartialEq)]
pub struct SobelOutput {
    /// Horizontal derivative (positive where intensity grows to the right).
    pub gx: FloatImage,
    /// Vertical derivative (positive where intensity grows downward).
    pub gy: FloatImage,
    /// Gradient magnitude `sqrt(gx² + gy²)`.
    pub magnitude: FloatImage,
    /// Gradient direction `atan2(gy, gx)` in `(−π, π]`; 0 where the magnitude is 0.
    pub direction: FloatImage,
    /// Edge orientation of 000 eq. 2 in `[0, π)`; `π/2` where the magnitude is 0.
    pub theta: FloatImage,
}

impl SobelOutput {
    /// Five zeroed `width`×`height` planes.
    #[must_use]
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            gx: FloatImage::new(width, height),
            gy: FloatImage::new(width, height),
            magnitude: FloatImage::new(width, height),
            direction: FloatImage::new(width, height),
            theta: FloatImage::new(width, height),
        }
    }

    /// Resize every plane to `width`×`height` (contents unspecified).
    pub fn resize(&mut self, width: usize, height: usize) {
        for plane in [&mut self.gx, &mut self.gy, &mut self.magnitude, &mut self.direction, &mut self.theta] {
            plane.resize(width, height);
        }
    }

    /// `(width, height)` of the planes.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        self.gx.size()
    }
}

/// The five planes of the Sobel stage on the GPU, all the same size.
#[derive(Debug)]
pub struct SobelGpu {
    /// Horizontal derivative.
    pub gx: GpuImage,
    /// Vertical derivative.
    pub gy: GpuImage,
    /// Gradient magnitude.
    pub magnitude: GpuImage,
    /// Gradient direction in `(−π, π]`.
    pub direction: GpuImage,
    /// Edge orientation of 000 eq. 2 in `[0, π)`.
    pub theta: GpuImage,
}

impl SobelGpu {
    /// Allocate five uninitialised `width`×`height` planes on the device.
    #[must_use]
    pub fn new(ctx: &GpuContext, width: usize, height: usize) -> Self {
        Self::layered(ctx, width, height, 1)
    }

    /// Five planes of `layers` stacked images each ([`GpuImage::layered`]).
    #[must_use]
    pub fn layered(ctx: &GpuContext, width: usize, height: usize, layers: usize) -> Self {
        let plane = |label| GpuImage::layered(ctx, width, height, layers, label);
        Self {
            gx: plane("sobel.gx"),
            gy: plane("sobel.gy"),
            magnitude: plane("sobel.magnitude"),
            direction: plane("sobel.direction"),
            theta: plane("sobel.theta"),
        }
    }

    /// `(width, height)` of the planes.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.gx.width(), self.gx.height())
    }

    /// Copy all five planes back to the CPU (waits for the GPU; tests and benches).
    pub fn download(&self, ctx: &GpuContext) -> Result<SobelOutput> {
        Ok(SobelOutput {
            gx: self.gx.download(ctx)?,
            gy: self.gy.download(ctx)?,
            magnitude: self.magnitude.download(ctx)?,
            direction: self.direction.download(ctx)?,
            theta: self.theta.download(ctx)?,
        })
    }
}

/// Uniform block of `sobel.wgsl`; kept in sync with its `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct SobelUniform {
    width: u32,
    height: u32,
    _pad: [u32; 2],
}

/// Gradient direction in `(−π, π]` and edge orientation θ in `[0, π)` of
/// the gradient `(gx, gy)`, with the conventions and guards of the module
/// documentation (the shader's arithmetic, step by step).
///
/// Branch-free, so a row of pixels vectorises: every candidate is computed
/// and the shader's branches become selects. Where `gx = 0` the quotient
/// `gy / gx` is ±∞ or NaN and everything derived from it is discarded.
#[inline]
#[must_use]
pub fn gradient_angles(gx: f32, gy: f32) -> (f32, f32) {
    let a = fast_atan_quotient(gy, gx);
    // 000 eq. 2: θ = atan(∇y/∇x) + π/2, folded into [0, π).
    let theta = a + FRAC_PI_2;
    #[allow(clippy::manual_range_contains)] // the shader's comparison, NaN kept as it keeps it
    let theta = if theta < 0.0 || theta >= PI { 0.0 } else { theta };
    let down = a - PI;
    let down = if down <= -PI { PI } else { down };
    let direction = if gx > 0.0 {
        a
    } else if gy >= 0.0 {
        a + PI
    } else {
        down
    };
    if gx != 0.0 {
        (direction, theta)
    } else if gy != 0.0 {
        (if gy > 0.0 { FRAC_PI_2 } else { -FRAC_PI_2 }, 0.0)
    } else {
        // Zero gradient: guarded, atan2(0, 0) is not portable.
        (0.0, FRAC_PI_2)
    }
}

/// `(gx, gy)` at column `xc` from the rows above, at and below, with
/// neighbour columns `xl`, `xr` (already clamped); the shader's order.
#[inline(always)]
fn gradient_at(up: &[f32], mid: &[f32], down: &[f32], xl: usize, xc: usize, xr: usize) -> (f32, f32) {
    let sum_l = (up[xl] + 2.0 * mid[xl]) + down[xl];
    let sum_r = (up[xr] + 2.0 * mid[xr]) + down[xr];
    let d_l = down[xl] - up[xl];
    let d_c = down[xc] - up[xc];
    let d_r = down[xr] - up[xr];
    (sum_r - sum_l, (d_l + 2.0 * d_c) + d_r)
}

/// The Sobel stage's five values at one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SobelPixel {
    /// Horizontal derivative.
    pub gx: f32,
    /// Vertical derivative.
    pub gy: f32,
    /// Gradient magnitude.
    pub magnitude: f32,
    /// Gradient direction in `(−π, π]`.
    pub direction: f32,
    /// Edge orientation of 000 eq. 2 in `[0, π)`.
    pub theta: f32,
}

/// The five Sobel values of `src` at pixel `(x, y)` alone, equal bit for bit
/// to that pixel of [`sobel_cpu`]'s planes (the same operations in the same
/// order): for callers that need the gradient at a few listed pixels only.
/// Panics when `(x, y)` lies outside `src`.
#[must_use]
pub fn sobel_at(src: &FloatImage, x: usize, y: usize) -> SobelPixel {
    let (gx, gy) = gradient_at_pixel(src, x, y);
    sobel_of_gradient(gx, gy)
}

/// `(gx, gy)` of `src` at pixel `(x, y)`, as [`sobel_at`] has them.
/// Panics when `(x, y)` lies outside `src`.
#[inline]
#[must_use]
pub fn gradient_at_pixel(src: &FloatImage, x: usize, y: usize) -> (f32, f32) {
    let (w, h) = src.size();
    assert!(x < w && y < h, "pixel ({x}, {y}) outside a {w}x{h} image");
    let (up, mid, down) = (src.row(y.saturating_sub(1)), src.row(y), src.row((y + 1).min(h - 1)));
    gradient_at(up, mid, down, x.saturating_sub(1), x, (x + 1).min(w - 1))
}

/// The five Sobel values of a pixel from its gradient `(gx, gy)`: the
/// magnitude and angles as [`sobel_cpu`] computes them.
#[inline]
#[must_use]
pub fn sobel_of_gradient(gx: f32, gy: f32) -> SobelPixel {
    let (direction, theta) = gradient_angles(gx, gy);
    SobelPixel { gx, gy, magnitude: (gx * gx + gy * gy).sqrt(), direction, theta }
}

/// The five output rows of one image row.
struct Rows<'a> {
    gx: &'a mut [f32],
    gy: &'a mut [f32],
    magnitude: &'a mut [f32],
    direction: &'a mut [f32],
    theta: &'a mut [f32],
}

simd_dispatch!(fn sobel_row(src: &[f32], width: usize, height: usize, y: usize, out: Rows<'_>) => sobel_row_body);

simd_dispatch!(
    fn gradient_magnitude_row(src: &[f32], size: (usize, usize), y: usize, columns: Range<usize>, gx: &mut [f32], gy: &mut [f32], magnitude: &mut [f32]) => gradient_magnitude_row_body
);

/// The derivatives of output row `y` in `columns`: interior without
/// clamping (vectorisable), then the border columns among them clamped.
/// Each value is the same whatever the span.
#[inline(always)]
fn derivative_row(
    src: &[f32],
    width: usize,
    height: usize,
    y: usize,
    columns: Range<usize>,
    gx: &mut [f32],
    gy: &mut [f32],
) {
    let row = |yy: usize| &src[yy * width..(yy + 1) * width];
    let (up, mid, down) = (row(y.saturating_sub(1)), row(y), row((y + 1).min(height - 1)));
    // Interior columns 1..width − 1 within the span.
    let (lo, hi) = (columns.start.max(1), columns.end.min(width.saturating_sub(1)));
    if lo < hi {
        let n = hi - lo;
        let (ul, uc, ur) = (&up[lo - 1..hi - 1], &up[lo..hi], &up[lo + 1..hi + 1]);
        let (ml, mr) = (&mid[lo - 1..hi - 1], &mid[lo + 1..hi + 1]);
        let (dl, dc, dr) = (&down[lo - 1..hi - 1], &down[lo..hi], &down[lo + 1..hi + 1]);
        let (gx_in, gy_in) = (&mut gx[lo..hi], &mut gy[lo..hi]);
        for i in 0..n {
            let sum_l = (ul[i] + 2.0 * ml[i]) + dl[i];
            let sum_r = (ur[i] + 2.0 * mr[i]) + dr[i];
            gx_in[i] = sum_r - sum_l;
            gy_in[i] = ((dl[i] - ul[i]) + 2.0 * (dc[i] - uc[i])) + (dr[i] - ur[i]);
        }
    }
    let last = width - 1;
    for xc in [0, last].into_iter().filter(|x| columns.contains(x)) {
        let (x, y) = gradient_at(up, mid, down, xc.saturating_sub(1), xc, (xc + 1).min(last));
        gx[xc] = x;
        gy[xc] = y;
    }
}

/// One output row `y`: derivatives, then magnitude and angles.
#[inline(always)]
fn sobel_row_body(src: &[f32], width: usize, height: usize, y: usize, out: Rows<'_>) {
    let Rows { gx, gy, magnitude, direction, theta } = out;
    derivative_row(src, width, height, y, 0..width, gx, gy);
    let pieces = width / ANGLE_LANES * ANGLE_LANES;
    for start in (0..pieces).step_by(ANGLE_LANES) {
        let (x, y) = (lanes(gx, start), lanes(gy, start));
        let (m, d, t) = (lanes_mut(magnitude, start), lanes_mut(direction, start), lanes_mut(theta, start));
        for i in 0..ANGLE_LANES {
            m[i] = (x[i] * x[i] + y[i] * y[i]).sqrt();
            (d[i], t[i]) = gradient_angles(x[i], y[i]);
        }
    }
    for i in pieces..width {
        let (x, y) = (gx[i], gy[i]);
        magnitude[i] = (x * x + y * y).sqrt();
        (direction[i], theta[i]) = gradient_angles(x, y);
    }
}

/// Pixels per piece of a row whose magnitude and angles one loop of known
/// length computes (one AVX-512 vector), which the compiler turns into
/// straight vector code with no scalar remainder; the rest of the row is
/// computed pixel by pixel.
const ANGLE_LANES: usize = 16;

/// The `ANGLE_LANES` values of `v` from `start`.
#[inline(always)]
fn lanes(v: &[f32], start: usize) -> &[f32; ANGLE_LANES] {
    v[start..start + ANGLE_LANES].try_into().expect("a piece lies inside the row")
}

/// The `ANGLE_LANES` values of `v` from `start`, to write.
#[inline(always)]
fn lanes_mut(v: &mut [f32], start: usize) -> &mut [f32; ANGLE_LANES] {
    (&mut v[start..start + ANGLE_LANES]).try_into().expect("a piece lies inside the row")
}

/// One output row `y` of a `size` (width, height) image: derivatives and
/// magnitude in `columns`, no angles.
#[inline(always)]
fn gradient_magnitude_row_body(
    src: &[f32],
    (width, height): (usize, usize),
    y: usize,
    columns: Range<usize>,
    gx: &mut [f32],
    gy: &mut [f32],
    magnitude: &mut [f32],
) {
    derivative_row(src, width, height, y, columns.clone(), gx, gy);
    for ((m, &x), &y) in magnitude[columns.clone()].iter_mut().zip(&gx[columns.clone()]).zip(&gy[columns]) {
        *m = (x * x + y * y).sqrt();
    }
}

/// CPU twin without the angles: `gx`, `gy` and `magnitude` of `src` into
/// `out`, each bit for bit as [`sobel_cpu`] writes it; `direction` and
/// `theta` are left empty (0×0), for callers that read the angles at a few
/// pixels only ([`sobel_at`]) and so skip the arctangent of every pixel.
pub fn sobel_gradient_magnitude_cpu(src: &FloatImage, out: &mut SobelOutput) {
    let (w, h) = src.size();
    sobel_gradient_magnitude_region_cpu(src, Window::full(w, h), out);
}

/// [`sobel_gradient_magnitude_cpu`] inside `region` only (clipped to the
/// image): the planes are the image's size, their values inside the region
/// are bit for bit those of the whole image's, and outside it they are
/// whatever the planes held before. For callers that read the planes in a
/// window of interest.
pub fn sobel_gradient_magnitude_region_cpu(src: &FloatImage, region: Window, out: &mut SobelOutput) {
    let (w, h) = src.size();
    out.gx.resize(w, h);
    out.gy.resize(w, h);
    out.magnitude.resize(w, h);
    out.direction.resize(0, 0);
    out.theta.resize(0, 0);
    let region = region.clipped(w, h);
    if region.is_empty() {
        return;
    }
    let (rows, columns) = (region.y0 as usize * w..region.y1 as usize * w, region.x0 as usize..region.x1 as usize);
    let s = src.data();
    let planes = (
        out.gx.data_mut()[rows.clone()].par_chunks_mut(w),
        out.gy.data_mut()[rows.clone()].par_chunks_mut(w),
        out.magnitude.data_mut()[rows].par_chunks_mut(w),
    );
    let (y0, pixels) = (region.y0 as usize, region.width() as usize * region.height() as usize);
    for_each_row(pixels, planes.into_par_iter().enumerate(), |(y, (gx, gy, magnitude))| {
        gradient_magnitude_row(s, (w, h), y0 + y, columns.clone(), gx, gy, magnitude);
    });
}

/// CPU twin: the five Sobel planes of `src` into `out` (resized to match).
/// No allocation once `out` has grown.
pub fn sobel_cpu(src: &FloatImage, out: &mut SobelOutput) {
    let (w, h) = src.size();
    out.resize(w, h);
    if w == 0 || h == 0 {
        return;
    }
    let s = src.data();
    let SobelOutput { gx, gy, magnitude, direction, theta } = out;
    let planes = (
        gx.data_mut().par_chunks_mut(w),
        gy.data_mut().par_chunks_mut(w),
        magnitude.data_mut().par_chunks_mut(w),
        direction.data_mut().par_chunks_mut(w),
        theta.data_mut().par_chunks_mut(w),
    );
    for_each_row(w * h, planes.into_par_iter().enumerate(), |(y, (gx, gy, magnitude, direction, theta))| {
        sobel_row(s, w, h, y, Rows { gx, gy, magnitude, direction, theta });
    });
}

/// CPU twin, allocating its outputs: the five Sobel planes of `src`.
#[must_use]
pub fn sobel(src: &FloatImage) -> SobelOutput {
    let mut out = SobelOutput::new(0, 0);
    sobel_cpu(src, &mut out);
    out
}

/// Record one dispatch writing all five planes of `out` from `src` (same size).
pub(crate) fn encode(rec: &mut Recorder<'_>, src: &GpuImage, out: &SobelGpu) -> Result<()> {
    let (w, h) = (src.width(), src.height());
    for (plane, what) in [
        (&out.gx, "sobel src/gx"),
        (&out.gy, "sobel src/gy"),
        (&out.magnitude, "sobel src/magnitude"),
        (&out.direction, "sobel src/direction"),
        (&out.theta, "sobel src/theta"),
    ] {
        src.check_same_size(plane, what)?;
    }
    let u = SobelUniform { width: w as u32, height: h as u32, _pad: [0; 2] };
    let buffers =
        [&src.buffer, &out.gx.buffer, &out.gy.buffer, &out.magnitude.buffer, &out.direction.buffer, &out.theta.buffer];
    rec.dispatch(&SHADER, "sobel", &u, &buffers, src.grid())
}

/// GPU: the five Sobel planes of a CPU image, read back (tests and benches).
pub fn sobel_gpu(ctx: &GpuContext, src: &FloatImage) -> Result<SobelOutput> {
    let (w, h) = src.size();
    let input = GpuImage::from_image(ctx, src, "sobel.src");
    let out = SobelGpu::new(ctx, w, h);
    run_once(ctx, |rec| encode(rec, &input, &out))?;
    out.download(ctx)
}

#[cfg(test)]
mod tests {
    use std::f32::consts::FRAC_PI_4;

    use super::*;

    /// The dispatched row (AVX2 where the CPU has it) equals the baseline
    /// build of the same body bit for bit, on every plane.
    #[test]
    fn dispatched_rows_equal_baseline_rows_bitwise() {
        let (w, h) = (37, 9);
        let src = crate::testimage::natural(w, h, 3).to_f32();
        let fast = sobel(&src);
        let mut base = SobelOutput::new(w, h);
        for y in 0..h {
            let r = y * w..(y + 1) * w;
            let SobelOutput { gx, gy, magnitude, direction, theta } = &mut base;
            let rows = Rows {
                gx: &mut gx.data_mut()[r.clone()],
                gy: &mut gy.data_mut()[r.clone()],
                magnitude: &mut magnitude.data_mut()[r.clone()],
                direction: &mut direction.data_mut()[r.clone()],
                theta: &mut theta.data_mut()[r],
            };
            sobel_row_body(src.data(), w, h, y, rows);
        }
        let bits = |o: &SobelOutput| -> Vec<u32> {
            [&o.gx, &o.gy, &o.magnitude, &o.direction, &o.theta]
                .iter()
                .flat_map(|p| p.data().iter().map(|v| v.to_bits()))
                .collect()
        };
        assert_eq!(bits(&fast), bits(&base));
    }

    /// `sobel_at` gives every pixel's five values bit for bit as the planes
    /// do, borders and interior, on an image with values of both signs.
    #[test]
    fn one_pixel_equals_the_planes_bitwise() {
        // Widths below, at and around the rows' pieces of ANGLE_LANES pixels.
        for w in [1, 2, 15, 16, 17, 23, 32, 33, 47] {
            let h = 7;
            let src = FloatImage::from_fn(w, h, |x, y| ((x * 37 + y * 91) % 53) as f32 * 1.7 - 40.0);
            let s = sobel(&src);
            for y in 0..h {
                for x in 0..w {
                    let p = sobel_at(&src, x, y);
                    let planes = [&s.gx, &s.gy, &s.magnitude, &s.direction, &s.theta].map(|i| i.get(x, y).to_bits());
                    let pixel = [p.gx, p.gy, p.magnitude, p.direction, p.theta].map(f32::to_bits);
                    assert_eq!(pixel, planes, "width {w}, ({x}, {y})");
                }
            }
        }
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-6
    }

    /// Without the angles, gx, gy and the magnitude equal the full twin's
    /// bit for bit on awkward sizes (1 px, one row, one column, odd widths,
    /// the threaded size), and the angle planes are empty.
    #[test]
    fn gradient_and_magnitude_alone_equal_the_full_twin_bitwise() {
        for (w, h) in [(1, 1), (1, 9), (9, 1), (2, 2), (37, 11), (300, 250)] {
            let src = FloatImage::from_fn(w, h, |x, y| ((x * 37 + y * 91) % 53) as f32 * 1.7 - 40.0);
            let full = sobel(&src);
            let mut out = SobelOutput::new(3, 3);
            sobel_gradient_magnitude_cpu(&src, &mut out);
            let bits = |i: &FloatImage| i.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&out.gx), bits(&full.gx), "gx {w}x{h}");
            assert_eq!(bits(&out.gy), bits(&full.gy), "gy {w}x{h}");
            assert_eq!(bits(&out.magnitude), bits(&full.magnitude), "magnitude {w}x{h}");
            assert_eq!((out.gx.size(), out.direction.size(), out.theta.size()), ((w, h), (0, 0), (0, 0)));
        }
    }

    #[test]
    fn vertical_step_edge() {
        // 6×3 image, columns 0..=2 are 0 and columns 3..=5 are 100:
        //   0 0 0 100 100 100   (every row)
        // At x = 2 the right column (x = 3) has [1 2 1] sum 400 and the left
        // (x = 1) sum 0, so gx = 400; the same at x = 3 (right 400, left 0).
        // Elsewhere left and right columns are equal (clamp at x = 0, 5): 0.
        // All rows are equal, so every down − up difference and gy are 0.
        // Direction 0 (gradient along +x); theta = atan(0) + π/2 = π/2, a
        // vertical edge line. Where gx = gy = 0: direction 0, theta π/2 by guard.
        let src = FloatImage::from_fn(6, 3, |x, _| if x >= 3 { 100.0 } else { 0.0 });
        let s = sobel(&src);
        for y in 0..3 {
            for x in 0..6 {
                let expected_gx = if x == 2 || x == 3 { 400.0 } else { 0.0 };
                assert_eq!(s.gx.get(x, y), expected_gx, "gx at ({x}, {y})");
                assert_eq!(s.gy.get(x, y), 0.0);
                assert_eq!(s.magnitude.get(x, y), expected_gx);
                assert_eq!(s.direction.get(x, y), 0.0);
                assert_eq!(s.theta.get(x, y), FRAC_PI_2);
            }
        }
        // Mirrored step (bright on the left): gx = −400, direction π, theta still π/2.
        let src = FloatImage::from_fn(6, 3, |x, _| if x < 3 { 100.0 } else { 0.0 });
        let s = sobel(&src);
        assert_eq!(s.gx.get(2, 1), -400.0);
        assert_eq!(s.direction.get(2, 1), PI);
        assert_eq!(s.theta.get(3, 1), FRAC_PI_2);
    }

    #[test]
    fn horizontal_step_edge_has_theta_zero() {
        // 3×6 image, rows 0..=2 are 0 and rows 3..=5 are 100. At y = 2 and
        // y = 3 each column's down − up difference is 100, so
        // gy = 100 + 2·100 + 100 = 400; gx = 0 (all columns equal).
        // Direction π/2 (gradient points down, +y); the edge line is
        // horizontal: atan(400/0) + π/2 = π ≡ 0, reported as 0 in [0, π).
        let src = FloatImage::from_fn(3, 6, |_, y| if y >= 3 { 100.0 } else { 0.0 });
        let s = sobel(&src);
        for x in 0..3 {
            for y in [2, 3] {
                assert_eq!(s.gx.get(x, y), 0.0);
                assert_eq!(s.gy.get(x, y), 400.0);
                assert_eq!(s.magnitude.get(x, y), 400.0);
                assert_eq!(s.direction.get(x, y), FRAC_PI_2);
                assert_eq!(s.theta.get(x, y), 0.0);
            }
            assert_eq!(s.gy.get(x, 0), 0.0); // clamp: rows 0, 0, 1 all 0
            assert_eq!(s.gy.get(x, 5), 0.0);
        }
        // Bright on top: gy = −400, direction −π/2, theta still 0.
        let src = FloatImage::from_fn(3, 6, |_, y| if y < 3 { 100.0 } else { 0.0 });
        let s = sobel(&src);
        assert_eq!(s.gy.get(1, 2), -400.0);
        assert_eq!(s.direction.get(1, 2), -FRAC_PI_2);
        assert_eq!(s.theta.get(1, 2), 0.0);
    }

    #[test]
    fn diagonal_ramp_gives_theta_three_quarter_pi() {
        // I(x, y) = 10·(x + y) on 5×5. At an interior pixel the right column
        // exceeds the left by 20 in each row: gx = 20·(1 + 2 + 1) = 80; by
        // symmetry gy = 80. Direction atan2(80, 80) = π/4 (down-right); the
        // edge line is perpendicular: θ = atan(1) + π/2 = 3π/4, a line
        // running from bottom-left to top-right on screen (iso-intensity
        // x + y = const). Magnitude 80·√2.
        let src = FloatImage::from_fn(5, 5, |x, y| 10.0 * (x + y) as f32);
        let s = sobel(&src);
        for (x, y) in [(1, 1), (2, 2), (3, 1), (2, 3)] {
            assert_eq!(s.gx.get(x, y), 80.0);
            assert_eq!(s.gy.get(x, y), 80.0);
            assert!(close(s.magnitude.get(x, y), 80.0 * 2f32.sqrt()));
            assert!(close(s.direction.get(x, y), FRAC_PI_4));
            assert!(close(s.theta.get(x, y), 3.0 * FRAC_PI_4));
        }
        // Anti-diagonal ramp I = 10·(x − y): gx = 80, gy = −80, direction
        // −π/4, θ = atan(−1) + π/2 = π/4.
        let src = FloatImage::from_fn(5, 5, |x, y| 10.0 * (x as f32 - y as f32));
        let s = sobel(&src);
        assert!(close(s.direction.get(2, 2), -FRAC_PI_4));
        assert!(close(s.theta.get(2, 2), FRAC_PI_4));
    }

    /// Gradients and magnitude of a region are the whole image's, bit for
    /// bit, and nothing outside the region is written: regions inside, at
    /// each border, one row, one column, one pixel, empty, beyond the image;
    /// images one and two pixels wide.
    #[test]
    fn region_gradients_equal_the_whole_images_inside_it_bitwise() {
        for (w, h) in [(37, 29), (2, 9), (1, 5), (9, 1)] {
            let src = crate::testimage::natural(w, h, 3).to_f32();
            let whole = sobel(&src);
            let (wu, hu) = (w as u32, h as u32);
            let regions = [
                Window { x0: 5, y0: 4, x1: 20, y1: 17 },
                Window { x0: 0, y0: 0, x1: 3, y1: 2 },
                Window { x0: wu.saturating_sub(2), y0: hu.saturating_sub(3), x1: wu, y1: hu },
                Window { x0: 0, y0: hu / 2, x1: wu, y1: hu / 2 + 1 },
                Window { x0: wu / 2, y0: 0, x1: wu / 2 + 1, y1: hu },
                Window { x0: 1, y0: 1, x1: 2, y1: 2 },
                Window { x0: 4, y0: 4, x1: 4, y1: 8 },
                Window { x0: 1, y0: 0, x1: 400, y1: 400 },
            ];
            for region in regions {
                let mut out = SobelOutput::new(w, h);
                for plane in [&mut out.gx, &mut out.gy, &mut out.magnitude] {
                    plane.data_mut().fill(-5.0);
                }
                sobel_gradient_magnitude_region_cpu(&src, region, &mut out);
                let r = region.clipped(w, h);
                for y in 0..h {
                    for x in 0..w {
                        let inside =
                            (r.x0 as usize..r.x1 as usize).contains(&x) && (r.y0 as usize..r.y1 as usize).contains(&y);
                        for (got, all) in
                            [(&out.gx, &whole.gx), (&out.gy, &whole.gy), (&out.magnitude, &whole.magnitude)]
                        {
                            let want = if inside { all.get(x, y) } else { -5.0 };
                            assert_eq!(got.get(x, y).to_bits(), want.to_bits(), "{w}x{h} {region:?} at ({x}, {y})");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn one_pixel_image_is_all_zero_gradient_with_clamp() {
        // Every neighbour clamps to the one pixel: gx = gy = 0, so the
        // zero-gradient guard gives direction 0 and theta π/2.
        let s = sobel(&FloatImage::from_fn(1, 1, |_, _| 42.0));
        assert_eq!((s.gx.get(0, 0), s.gy.get(0, 0), s.magnitude.get(0, 0)), (0.0, 0.0, 0.0));
        assert_eq!((s.direction.get(0, 0), s.theta.get(0, 0)), (0.0, FRAC_PI_2));
    }

    #[test]
    fn angle_ranges_and_quadrants() {
        let q = |gx: f32, gy: f32| gradient_angles(gx, gy);
        assert_eq!(q(1.0, 0.0), (0.0, FRAC_PI_2));
        assert_eq!(q(-1.0, 0.0), (PI, FRAC_PI_2));
        assert_eq!(q(-1.0, -0.0), (PI, FRAC_PI_2)); // −0 counts as gy ≥ 0: never −π
        assert_eq!(q(0.0, 1.0), (FRAC_PI_2, 0.0));
        assert_eq!(q(0.0, -1.0), (-FRAC_PI_2, 0.0));
        assert_eq!(q(0.0, 0.0), (0.0, FRAC_PI_2));
        // Opposite gradients share one edge line: (−1, −1) ∥ (1, 1) → 3π/4,
        // (−1, 1) ∥ (1, −1) → π/4.
        let (d, t) = q(-1.0, -1.0);
        assert!(close(d, -3.0 * FRAC_PI_4) && close(t, 3.0 * FRAC_PI_4));
        let (d, t) = q(-1.0, 1.0);
        assert!(close(d, 3.0 * FRAC_PI_4) && close(t, FRAC_PI_4));
        // Nearly vertical gradients: θ folds to 0 instead of reaching π.
        assert_eq!(q(1e-30, 1.0).1, 0.0);
        // Gradient just below −x: direction stays in (−π, π].
        let (d, _) = q(-1.0, -1e-9);
        assert!(d > -PI && d <= PI);
        for i in 0..360 {
            let a = (i as f32).to_radians();
            let (d, t) = q(a.cos(), a.sin());
            assert!(d > -PI && d <= PI, "direction {d} at {i}°");
            assert!((0.0..PI).contains(&t), "theta {t} at {i}°");
        }
    }

    #[test]
    fn parallel_path_matches_row_by_row_and_output_is_resized() {
        // 300×250 = 75 000 pixels takes the rayon path; each of its rows
        // must equal the middle row of the 3-row strip around it, which a
        // small (single-threaded) run computes.
        let src = FloatImage::from_fn(300, 250, |x, y| ((x * 7 + y * 13) % 31) as f32);
        let mut out = SobelOutput::new(1, 1);
        sobel_cpu(&src, &mut out);
        assert_eq!(out.size(), (300, 250));
        for y in [0usize, 1, 100, 248, 249] {
            // Rows y−1, y, y+1 clamped to the image, as the border rows see them.
            let strip = FloatImage::from_fn(300, 3, |x, dy| src.get(x, (y + dy).saturating_sub(1).min(249)));
            let s = sobel(&strip);
            assert_eq!(out.gx.row(y), s.gx.row(1));
            assert_eq!(out.gy.row(y), s.gy.row(1));
            assert_eq!(out.magnitude.row(y), s.magnitude.row(1));
            assert_eq!(out.direction.row(y), s.direction.row(1));
            assert_eq!(out.theta.row(y), s.theta.row(1));
        }
    }
}
