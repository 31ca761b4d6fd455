//! Separable Gaussian smoothing (000 eq. 1, the G* of each frame).
//!
//! Kernel: radius `r = ceil(3σ)` (at least 1), weights
//! `w_k = exp(−k²/2σ²)` for `k = −r..=r`, computed in f64 and normalised to
//! sum 1, then rounded to f32 so both twins use identical weights. Borders
//! clamp to the edge. σ must lie in `(0, MAX_SIGMA]`.

use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::Window;
use super::rows::{RowStore, for_each_row, parallel};

use crate::Result;
use crate::bounds::Interval;
use crate::gpu::{
    Binding::{ReadOnly, Storage, Uniform},
    EntryPoint, GpuContext, GpuImage, Recorder, ShaderDef, run_once,
};
use crate::image::FloatImage;

/// The shader of this stage.
pub const SHADER: ShaderDef = ShaderDef {
    name: "gaussian",
    source: include_str!("../../shaders/gaussian.wgsl"),
    includes: &[],
    entry_points: &[
        EntryPoint::tiled("blur_rows", &[Uniform, ReadOnly, Storage]),
        EntryPoint::tiled("blur_cols", &[Uniform, ReadOnly, Storage]),
    ],
    overrides: &[],
};

/// Most half-kernel weights the shader's uniform block holds.
const MAX_TAPS: usize = 60;
/// Largest σ accepted (radius `ceil(3σ)` must stay below `MAX_TAPS`, so
/// the uniform block fits the recorder's 256-byte slot).
pub const MAX_SIGMA: f32 = 19.5;

/// Parameters of Gaussian smoothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaussianParams {
    /// Standard deviation in pixels; 000 does not give one, pipetrack's default is 1.0
    /// (a 7-tap kernel, close to the 5×5 filters of the PIPE era).
    pub sigma: f32,
}

impl Default for GaussianParams {
    fn default() -> Self {
        Self { sigma: 1.0 }
    }
}

impl GaussianParams {
    /// Error unless σ lies in `(0, MAX_SIGMA]` (NaN never does).
    pub fn validate(&self) -> Result<()> {
        Interval::open_closed(0.0, f64::from(MAX_SIGMA)).check(
            "Gaussian smoothing",
            "sigma",
            f64::from(self.sigma),
            " px",
        )
    }
}

/// The half kernel `w_0..=w_r` of a Gaussian with standard deviation `sigma`.
pub fn half_kernel(sigma: f32) -> Result<Vec<f32>> {
    GaussianParams { sigma }.validate()?;
    let radius = ((3.0 * sigma as f64).ceil() as usize).max(1);
    let s2 = 2.0 * (sigma as f64) * (sigma as f64);
    let w: Vec<f64> = (0..=radius).map(|k| (-((k * k) as f64) / s2).exp()).collect();
    let total = w[0] + 2.0 * w[1..].iter().sum::<f64>();
    Ok(w.iter().map(|v| (v / total) as f32).collect())
}

/// Uniform block of `gaussian.wgsl`; kept in sync with its `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GaussianUniform {
    width: u32,
    height: u32,
    radius: u32,
    _pad: u32,
    weights: [f32; MAX_TAPS],
}

impl GaussianUniform {
    fn new(width: usize, height: usize, half: &[f32]) -> Self {
        let mut weights = [0.0; MAX_TAPS];
        weights[..half.len()].copy_from_slice(half);
        Self { width: width as u32, height: height as u32, radius: (half.len() - 1) as u32, _pad: 0, weights }
    }
}

simd_dispatch!(fn blur_row(src: &[f32], dst: &mut [f32], half: &[f32]) => blur_row_body);

/// One 1-D pass along a row, clamp-to-edge; same arithmetic order as the shader.
#[inline(always)]
fn blur_row_body(src: &[f32], dst: &mut [f32], half: &[f32]) {
    let n = src.len();
    let r = half.len() - 1;
    let last = n as isize - 1;
    let edge = |x: usize, dst: &mut [f32]| {
        let mut sum = half[0] * src[x];
        for (k, &w) in half.iter().enumerate().skip(1) {
            let l = (x as isize - k as isize).clamp(0, last) as usize;
            let rr = (x as isize + k as isize).clamp(0, last) as usize;
            sum += w * (src[l] + src[rr]);
        }
        dst[x] = sum;
    };
    if n <= 2 * r {
        (0..n).for_each(|x| edge(x, dst));
        return;
    }
    match half.len() {
        2 => blur_row_fixed::<2>(src, dst, half),
        3 => blur_row_fixed::<3>(src, dst, half),
        4 => blur_row_fixed::<4>(src, dst, half),
        5 => blur_row_fixed::<5>(src, dst, half),
        _ => {
            (0..r).for_each(|x| edge(x, dst));
            blur_interior_any(src, &mut dst[r..n - r], half);
            (n - r..n).for_each(|x| edge(x, dst));
        }
    }
}

/// Most values of a border piece of [`blur_row_fixed`]: `3r` for `r ≤ 4`.
const BORDER_PIECE: usize = 12;

/// A row of more than `2r` pixels blurred with a half kernel of `N ≤ 5`
/// taps: the interior in place, and each border's `r` pixels as the interior
/// of a short piece of `3r` values clamped to the edge, so that borders too
/// sum their taps in registers, in the same order (the same bits as
/// clamping every index).
#[inline(always)]
fn blur_row_fixed<const N: usize>(src: &[f32], dst: &mut [f32], half: &[f32]) {
    let (n, r) = (src.len(), N - 1);
    // Output pixel x reads piece index x − first, i.e. r + (x − first − r).
    blur_border::<N>(src, -(r as isize), &mut dst[..r], half);
    blur_interior::<N>(src, &mut dst[r..n - r], half);
    blur_border::<N>(src, (n - 2 * r) as isize, &mut dst[n - r..], half);
}

/// The `r` border pixels `out` of [`blur_row_fixed`]: the interior of the
/// piece of `3r` values of `src` from index `first`, clamped to the edge.
#[inline(always)]
fn blur_border<const N: usize>(src: &[f32], first: isize, out: &mut [f32], half: &[f32]) {
    let r = N - 1;
    let mut piece = [0.0f32; BORDER_PIECE];
    fill_clamped(src, first, &mut piece[..3 * r]);
    blur_interior::<N>(&piece[..3 * r], out, half);
}

/// `out` filled with the values of `src` from index `first` on, each index
/// clamped to `src` (borders clamp to the edge).
#[inline(always)]
fn fill_clamped(src: &[f32], first: isize, out: &mut [f32]) {
    let last = src.len() as isize - 1;
    for (j, v) in out.iter_mut().enumerate() {
        *v = src[(first + j as isize).clamp(0, last) as usize];
    }
}

/// The interior `dst = src[r..n − r]` blurred, for a half kernel of `N`
/// taps known at compile time: every pixel sums its taps in registers, in
/// the order k = 0, 1, …, r like the shader, over shifted views of the row
/// (no bounds checks in the loop, so it vectorises).
#[inline(always)]
fn blur_interior<const N: usize>(src: &[f32], inner: &mut [f32], half: &[f32]) {
    let (r, n) = (N - 1, inner.len());
    let w: [f32; N] = std::array::from_fn(|k| half[k]);
    let left: [&[f32]; N] = std::array::from_fn(|k| &src[r - k..r - k + n]);
    let right: [&[f32]; N] = std::array::from_fn(|k| &src[r + k..r + k + n]);
    for (i, d) in inner.iter_mut().enumerate() {
        let mut sum = w[0] * left[0][i];
        for k in 1..N {
            sum += w[k] * (left[k][i] + right[k][i]);
        }
        *d = sum;
    }
}

/// [`blur_interior`] for any kernel length: tap-major, so the inner loop
/// runs along the row over equal-length slices and vectorises; each pixel
/// still sums its taps in the order k = 0, 1, …, r.
#[inline(always)]
fn blur_interior_any(src: &[f32], inner: &mut [f32], half: &[f32]) {
    let (r, n) = (half.len() - 1, inner.len());
    for (d, &c) in inner.iter_mut().zip(&src[r..r + n]) {
        *d = half[0] * c;
    }
    for (k, &w) in half.iter().enumerate().skip(1) {
        let (left, right) = (&src[r - k..r - k + n], &src[r + k..r + k + n]);
        for ((d, &l), &rr) in inner.iter_mut().zip(left).zip(right) {
            *d += w * (l + rr);
        }
    }
}

simd_dispatch!(fn blur_col_row(src: &[f32], rows: RowStore, y: usize, dst: &mut [f32], half: &[f32]) => blur_col_row_body);

/// One output row of the vertical pass: `dst = w0·row(y) + Σ w_k (row(y−k) + row(y+k))`.
#[inline(always)]
fn blur_col_row_body(src: &[f32], rows: RowStore, y: usize, dst: &mut [f32], half: &[f32]) {
    let row = |yy: isize| rows.row(src, yy);
    blur_col_taps(dst, half, |k| (row(y as isize - k as isize), row(y as isize + k as isize)));
}

/// One output row of the vertical pass, `rows_at(k)` giving the rows k
/// above and k below (clamped): the taps summed in registers for a half
/// kernel of up to 5 taps, tap by tap along the row otherwise, in the
/// order k = 0, 1, …, r either way.
#[inline(always)]
fn blur_col_taps<'a>(dst: &mut [f32], half: &[f32], rows_at: impl Fn(usize) -> (&'a [f32], &'a [f32])) {
    match half.len() {
        2 => blur_col_fixed::<2>(dst, half, rows_at),
        3 => blur_col_fixed::<3>(dst, half, rows_at),
        4 => blur_col_fixed::<4>(dst, half, rows_at),
        5 => blur_col_fixed::<5>(dst, half, rows_at),
        _ => {
            for (d, &c) in dst.iter_mut().zip(rows_at(0).0) {
                *d = half[0] * c;
            }
            for (k, &w) in half.iter().enumerate().skip(1) {
                let (up, down) = rows_at(k);
                for ((d, &u), &v) in dst.iter_mut().zip(up).zip(down) {
                    *d += w * (u + v);
                }
            }
        }
    }
}

/// One output row of the vertical pass for a half kernel of `N` taps known
/// at compile time, the taps summed in registers in the order k = 0, 1, …, r;
/// `rows_at(k)` gives the rows k above and k below (clamped).
#[inline(always)]
fn blur_col_fixed<'a, const N: usize>(
    dst: &mut [f32],
    half: &[f32],
    rows_at: impl Fn(usize) -> (&'a [f32], &'a [f32]),
) {
    let n = dst.len();
    let w: [f32; N] = std::array::from_fn(|k| half[k]);
    let up: [&[f32]; N] = std::array::from_fn(|k| &rows_at(k).0[..n]);
    let down: [&[f32]; N] = std::array::from_fn(|k| &rows_at(k).1[..n]);
    for (i, d) in dst.iter_mut().enumerate() {
        let mut sum = w[0] * up[0][i];
        for k in 1..N {
            sum += w[k] * (up[k][i] + down[k][i]);
        }
        *d = sum;
    }
}

/// CPU twin: smooth `src` into `dst` (resized to match), using `tmp` as the
/// intermediate of the row pass (the whole image when rows run on several
/// threads, a ring of a few rows otherwise). No allocation once the buffers
/// have grown.
pub fn gaussian_cpu(
    src: &FloatImage,
    params: &GaussianParams,
    tmp: &mut FloatImage,
    dst: &mut FloatImage,
) -> Result<()> {
    let half = half_kernel(params.sigma)?;
    let (w, h) = src.size();
    dst.resize(w, h);
    if w == 0 || h == 0 {
        tmp.resize(w, h);
        return Ok(());
    }
    if !parallel(w * h) {
        blur_through_ring(src, &half, tmp, dst);
        return Ok(());
    }
    tmp.resize(w, h);
    for_each_row(w * h, src.data().par_chunks(w).zip(tmp.data_mut().par_chunks_mut(w)), |(s, d)| blur_row(s, d, &half));
    let (t, rows) = (tmp.data(), RowStore { width: w, height: h, slots: h });
    for_each_row(w * h, dst.data_mut().par_chunks_mut(w).enumerate(), |(y, d)| blur_col_row(t, rows, y, d, &half));
    Ok(())
}

/// Both passes on this thread, row by row: the row pass fills a ring of the
/// `2r + 1` rows (fewer on a short image) that the next output row of the
/// vertical pass reads, so the intermediate stays in the fastest cache
/// instead of making a round trip through memory. Same arithmetic as the
/// two whole-image passes, so the same bits.
fn blur_through_ring(src: &FloatImage, half: &[f32], ring: &mut FloatImage, dst: &mut FloatImage) {
    let (w, h) = src.size();
    let r = half.len() - 1;
    // Two output rows at a time read the 2r + 2 rows around them.
    let rows = RowStore { width: w, height: h, slots: (2 * r + 2).min(h) };
    ring.resize(w, rows.slots);
    let mut done = 0;
    for (pair, d) in dst.data_mut().chunks_mut(2 * w).enumerate() {
        let y = 2 * pair;
        // Rows up to y + 1 + r (clamped) must have been through the row pass.
        while done <= (y + 1 + r).min(h - 1) {
            let slot = done % rows.slots;
            blur_row(src.row(done), &mut ring.data_mut()[slot * w..(slot + 1) * w], half);
            done += 1;
        }
        match d.split_at_mut_checked(w) {
            Some((d0, d1)) if !d1.is_empty() => blur_col_row_pair(ring.data(), rows, y, d0, d1, half),
            _ => blur_col_row(ring.data(), rows, y, d, half),
        }
    }
}

simd_dispatch!(fn blur_col_row_pair(src: &[f32], rows: RowStore, y: usize, dst0: &mut [f32], dst1: &mut [f32], half: &[f32]) => blur_col_row_pair_body);

/// Output rows `y` and `y + 1` of the vertical pass together, each exactly
/// as [`blur_col_row`] computes it: the two rows share all but two of their
/// input rows, so each input value is loaded once for both.
#[inline(always)]
fn blur_col_row_pair_body(src: &[f32], rows: RowStore, y: usize, dst0: &mut [f32], dst1: &mut [f32], half: &[f32]) {
    // Row y − r + m (clamped).
    let rows_from = |m: usize| rows.row(src, y as isize - (half.len() as isize - 1) + m as isize);
    match half.len() {
        2 => blur_col_pair_fixed::<2, 4>(dst0, dst1, half, rows_from),
        3 => blur_col_pair_fixed::<3, 6>(dst0, dst1, half, rows_from),
        4 => blur_col_pair_fixed::<4, 8>(dst0, dst1, half, rows_from),
        5 => blur_col_pair_fixed::<5, 10>(dst0, dst1, half, rows_from),
        _ => {
            blur_col_row_body(src, rows, y, dst0, half);
            blur_col_row_body(src, rows, y + 1, dst1, half);
        }
    }
}

/// Two output rows of the vertical pass for a half kernel of `N` taps
/// (`M = 2N` input rows, `rows_from(m)` = row `y − r + m`), each row's taps
/// summed in the order of [`blur_col_fixed`].
#[inline(always)]
fn blur_col_pair_fixed<'a, const N: usize, const M: usize>(
    dst0: &mut [f32],
    dst1: &mut [f32],
    half: &[f32],
    rows_from: impl Fn(usize) -> &'a [f32],
) {
    let n = dst0.len();
    let r = N - 1;
    let w: [f32; N] = std::array::from_fn(|k| half[k]);
    let rows: [&[f32]; M] = std::array::from_fn(|m| &rows_from(m)[..n]);
    let dst1 = &mut dst1[..n];
    for (i, (d0, d1)) in dst0.iter_mut().zip(dst1.iter_mut()).enumerate() {
        let v: [f32; M] = std::array::from_fn(|m| rows[m][i]);
        // Row y is at index r, row y + 1 at r + 1.
        let (mut s0, mut s1) = (w[0] * v[r], w[0] * v[r + 1]);
        for k in 1..N {
            s0 += w[k] * (v[r - k] + v[r + k]);
            s1 += w[k] * (v[r + 1 - k] + v[r + 1 + k]);
        }
        *d0 = s0;
        *d1 = s1;
    }
}

/// CPU twin inside `region` only (clipped to the image): `dst` is resized to
/// `src`'s size, its values inside the region are bit for bit those of
/// [`gaussian_cpu`], and outside it they are whatever `dst` held before.
/// The row pass covers the region's columns on the rows the column pass
/// reads (the region's rows and `r` more on each side, within the image),
/// into `tmp`; `piece` holds a row's span clamped to the image where the
/// span reaches within `r` of a border. For callers that read the smoothed
/// image in a window of interest.
pub fn gaussian_region_cpu(
    src: &FloatImage,
    params: &GaussianParams,
    region: Window,
    tmp: &mut FloatImage,
    piece: &mut Vec<f32>,
    dst: &mut FloatImage,
) -> Result<()> {
    let half = half_kernel(params.sigma)?;
    let (w, h) = src.size();
    dst.resize(w, h);
    let region = region.clipped(w, h);
    if region.is_empty() {
        return Ok(());
    }
    let r = half.len() - 1;
    let (x0, x1, y0, y1) = (region.x0 as usize, region.x1 as usize, region.y0 as usize, region.y1 as usize);
    let rows = y0.saturating_sub(r)..(y1 + r).min(h);
    tmp.resize(x1 - x0, rows.len());
    let span = Span { width: w, height: h, columns: x0..x1, output_rows: y0..y1, rows };
    blur_region(src.data(), &span, &half, tmp.data_mut(), piece, dst.data_mut());
    Ok(())
}

/// Where [`gaussian_region_cpu`] works: the image's size, the region's
/// columns and rows, and the rows of the row pass.
struct Span {
    width: usize,
    height: usize,
    columns: Range<usize>,
    output_rows: Range<usize>,
    rows: Range<usize>,
}

simd_dispatch!(fn blur_region(src: &[f32], span: &Span, half: &[f32], tmp: &mut [f32], piece: &mut Vec<f32>, dst: &mut [f32]) => blur_region_body);

/// Both passes of [`gaussian_region_cpu`]; each value sums its taps in the
/// order of [`blur_row_body`] and [`blur_col_row_body`] (a span near a
/// border reads its values clamped to the image, as those do).
#[inline(always)]
fn blur_region_body(src: &[f32], span: &Span, half: &[f32], tmp: &mut [f32], piece: &mut Vec<f32>, dst: &mut [f32]) {
    let (w, r) = (span.width, half.len() - 1);
    let (x0, x1) = (span.columns.start, span.columns.end);
    let n = x1 - x0;
    for (v, out) in span.rows.clone().zip(tmp.chunks_exact_mut(n)) {
        let row = &src[v * w..(v + 1) * w];
        // Values x0 − r .. x1 + r of the row, clamped to it.
        let values = if x0 >= r && x1 + r <= w {
            &row[x0 - r..x1 + r]
        } else {
            piece.resize(n + 2 * r, 0.0);
            fill_clamped(row, x0 as isize - r as isize, piece);
            &piece[..]
        };
        match half.len() {
            2 => blur_interior::<2>(values, out, half),
            3 => blur_interior::<3>(values, out, half),
            4 => blur_interior::<4>(values, out, half),
            5 => blur_interior::<5>(values, out, half),
            _ => blur_interior_any(values, out, half),
        }
    }
    // Row v of the image (clamped) is row v − rows.start of `tmp`.
    let first = span.rows.start as isize;
    let last = span.height as isize - 1;
    let row = |v: isize| {
        let t = (v.clamp(0, last) - first) as usize;
        &tmp[t * n..(t + 1) * n]
    };
    for y in span.output_rows.clone() {
        let out = &mut dst[y * w + x0..y * w + x1];
        blur_col_taps(out, half, |k| (row(y as isize - k as isize), row(y as isize + k as isize)));
    }
}

/// CPU twin, allocating its outputs: the smoothed image.
pub fn gaussian(src: &FloatImage, params: &GaussianParams) -> Result<FloatImage> {
    let mut tmp = FloatImage::new(0, 0);
    let mut dst = FloatImage::new(0, 0);
    gaussian_cpu(src, params, &mut tmp, &mut dst)?;
    Ok(dst)
}

/// Record the two passes `src → tmp → dst`; [`Error::Size`] unless all
/// three have the same size.
pub(crate) fn encode(
    rec: &mut Recorder<'_>,
    src: &GpuImage,
    tmp: &GpuImage,
    dst: &GpuImage,
    params: &GaussianParams,
) -> Result<()> {
    let half = half_kernel(params.sigma)?;
    src.check_same_size(tmp, "gaussian src/tmp")?;
    src.check_same_size(dst, "gaussian src/dst")?;
    let (w, h) = src.size();
    let u = GaussianUniform::new(w, h, &half);
    let groups = src.grid();
    rec.dispatch(&SHADER, "blur_rows", &u, &[&src.buffer, &tmp.buffer], groups)?;
    rec.dispatch(&SHADER, "blur_cols", &u, &[&tmp.buffer, &dst.buffer], groups)
}

/// GPU: smooth a CPU image and read the result back (tests and benches).
pub fn gaussian_gpu(ctx: &GpuContext, src: &FloatImage, params: &GaussianParams) -> Result<FloatImage> {
    let (w, h) = src.size();
    let input = GpuImage::from_image(ctx, src, "gaussian.src");
    let tmp = GpuImage::new(ctx, w, h, "gaussian.tmp");
    let out = GpuImage::new(ctx, w, h, "gaussian.dst");
    run_once(ctx, |rec| encode(rec, &input, &tmp, &out, params))?;
    out.download(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_sums_to_one_and_radius_is_ceil_three_sigma() {
        let h = half_kernel(1.2).unwrap();
        assert_eq!(h.len(), 5); // ceil(3.6) = 4
        let total: f32 = h[0] + 2.0 * h[1..].iter().sum::<f32>();
        assert!((total - 1.0).abs() < 1e-6);
        assert!(half_kernel(0.0).is_err());
        assert!(half_kernel(f32::NAN).is_err());
    }

    #[test]
    fn constant_image_stays_constant_and_impulse_spreads_as_kernel() {
        let flat = FloatImage::from_fn(9, 7, |_, _| 100.0);
        let s = gaussian(&flat, &GaussianParams { sigma: 1.0 }).unwrap();
        assert!(s.data().iter().all(|&v| (v - 100.0).abs() < 1e-3));

        let imp = FloatImage::from_fn(15, 15, |x, y| if (x, y) == (7, 7) { 1.0 } else { 0.0 });
        let s = gaussian(&imp, &GaussianParams { sigma: 1.0 }).unwrap();
        let h = half_kernel(1.0).unwrap();
        // Separable: value at (7+i, 7+j) = w_i · w_j.
        assert!((s.get(7, 7) - h[0] * h[0]).abs() < 1e-7);
        assert!((s.get(9, 6) - h[2] * h[1]).abs() < 1e-7);
        assert_eq!(s.get(11, 7), 0.0); // beyond radius 3
    }

    /// A region's values are the whole image's, bit for bit, and nothing
    /// outside the region is written: regions inside, at each border, one
    /// pixel, empty, larger than the image; kernels with and without a
    /// specialised loop; images narrower and shorter than the kernel.
    #[test]
    fn region_equals_the_whole_image_inside_it_bitwise() {
        for (w, h) in [(37, 29), (23, 3), (5, 40), (1, 1)] {
            let src = crate::testimage::natural(w, h, 5).to_f32();
            for sigma in [0.3, 1.0, 2.5, 4.0] {
                let params = GaussianParams { sigma };
                let whole = gaussian(&src, &params).unwrap();
                let (wu, hu) = (w as u32, h as u32);
                let regions = [
                    Window { x0: 10, y0: 8, x1: 25, y1: 20 },
                    Window { x0: 0, y0: 0, x1: 4, y1: 3 },
                    Window { x0: wu.saturating_sub(3), y0: hu.saturating_sub(2), x1: wu, y1: hu },
                    Window { x0: 0, y0: 1, x1: wu, y1: 2 },
                    Window { x0: wu / 2, y0: 0, x1: wu / 2 + 1, y1: hu },
                    Window { x0: 2, y0: 2, x1: 3, y1: 3 },
                    Window { x0: 6, y0: 6, x1: 6, y1: 9 },
                    Window { x0: 1, y0: 1, x1: 500, y1: 500 },
                ];
                for region in regions {
                    let (mut tmp, mut piece) = (FloatImage::new(0, 0), Vec::new());
                    let mut got = FloatImage::from_fn(w, h, |_, _| -7.0);
                    gaussian_region_cpu(&src, &params, region, &mut tmp, &mut piece, &mut got).unwrap();
                    let r = region.clipped(w, h);
                    for y in 0..h {
                        for x in 0..w {
                            let inside = (r.x0 as usize..r.x1 as usize).contains(&x)
                                && (r.y0 as usize..r.y1 as usize).contains(&y);
                            let expected = if inside { whole.get(x, y) } else { -7.0 };
                            assert_eq!(
                                got.get(x, y).to_bits(),
                                expected.to_bits(),
                                "{w}x{h} σ {sigma} {region:?} at ({x}, {y})"
                            );
                        }
                    }
                }
            }
        }
    }

    /// The ring of rows gives the bits of the two whole-image passes, for
    /// radii with and without a specialised loop and images shorter than
    /// the kernel.
    #[test]
    fn ring_equals_two_whole_image_passes_bitwise() {
        for (w, h) in [(37, 29), (23, 3), (40, 1)] {
            let src = crate::testimage::natural(w, h, 11).to_f32();
            for sigma in [0.3, 1.0, 1.2, 2.5, 4.0] {
                let half = half_kernel(sigma).unwrap();
                let mut ring = FloatImage::new(0, 0);
                let mut fused = FloatImage::new(w, h);
                blur_through_ring(&src, &half, &mut ring, &mut fused);
                let mut tmp = FloatImage::new(w, h);
                for y in 0..h {
                    blur_row(src.row(y), &mut tmp.data_mut()[y * w..(y + 1) * w], &half);
                }
                let rows = RowStore { width: w, height: h, slots: h };
                let mut two_pass = FloatImage::new(w, h);
                for y in 0..h {
                    blur_col_row(tmp.data(), rows, y, &mut two_pass.data_mut()[y * w..(y + 1) * w], &half);
                }
                let bits = |i: &FloatImage| i.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&fused), bits(&two_pass), "{w}x{h}, sigma {sigma}");
            }
        }
    }

    /// The row pass equals a plain loop that clamps every tap's index,
    /// bit for bit, for every radius with taps in registers and beyond, on
    /// widths around `2r` (all border, border meeting interior) and odd ones.
    #[test]
    fn row_pass_equals_clamping_every_tap_bitwise() {
        for sigma in [0.3, 0.5, 1.0, 1.2, 1.5, 2.0] {
            let half = half_kernel(sigma).unwrap();
            let r = half.len() - 1;
            for n in [1, 2, 3, 2 * r, 2 * r + 1, 2 * r + 2, 3 * r + 1, 37, 101] {
                let src: Vec<f32> = (0..n).map(|x| ((x * 37) % 29) as f32 * 1.3 - 7.0).collect();
                let mut got = vec![f32::NAN; n];
                blur_row(&src, &mut got, &half);
                let expected: Vec<u32> = (0..n)
                    .map(|x| {
                        let at = |i: isize| src[i.clamp(0, n as isize - 1) as usize];
                        let mut sum = half[0] * src[x];
                        for (k, &w) in half.iter().enumerate().skip(1) {
                            sum += w * (at(x as isize - k as isize) + at(x as isize + k as isize));
                        }
                        sum.to_bits()
                    })
                    .collect();
                let bits: Vec<u32> = got.iter().map(|v| v.to_bits()).collect();
                assert_eq!(bits, expected, "sigma {sigma}, width {n}");
            }
        }
    }

    #[test]
    fn clamp_border_on_a_one_pixel_image() {
        let one = FloatImage::from_fn(1, 1, |_, _| 42.0);
        let s = gaussian(&one, &GaussianParams { sigma: 2.0 }).unwrap();
        assert!((s.get(0, 0) - 42.0).abs() < 1e-4);
    }
}
