//! Laplacian of Gaussian (001 "Real-time line detection": an LoG operator
//! with σ = 1.2 for Marr–Hildreth edge detection), computed separably as
//! `LoG = g''(x)·g(y) + g(x)·g''(y)`.
//!
//! Kernels, radius `r = ceil(3σ)` (at least 1; σ = 1.2 gives 9 taps),
//! computed in f64 for `k = −r..=r` and then rounded to f32 so both twins use
//! identical weights:
//! - `g_k = exp(−k²/2σ²)`, normalised to sum 1 (the smoothing kernel of
//!   [`super::gaussian`]);
//! - `d_k = (k²/σ⁴ − 1/σ²)·g_k` (the sampled second derivative of the
//!   Gaussian), then corrected to sum exactly 0 by subtracting its mean, so a
//!   constant image has zero response, and scaled so that `Σ k²·d_k = 2`, so
//!   the LoG of `x²` (or `y²`) is exactly 2 and the discrete operator
//!   approximates ∇² of the smoothed image in grey levels per pixel². Both
//!   corrections are small for σ = 1.2 (mean removed −1.5e-4 against a
//!   centre tap of −0.231, scale factor 1.012, making up for the tails cut at
//!   3σ); for tiny σ the kernel degenerates to the 5-point Laplacian's
//!   `[1, −2, 1]`.
//!
//! Two passes, clamp-to-edge borders: `rows` turns `src` into `tmp_g` (rows
//! convolved with g) and `tmp_d` (rows convolved with g''); `cols` gives
//! `out = cols_g''(tmp_g) + cols_g(tmp_d)`. σ must lie in `(0, MAX_SIGMA]`.

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::Window;
use super::rows::{RowStore, for_each_row, parallel};
use crate::bounds::Interval;
use crate::gpu::{
    Binding::{ReadOnly, Storage, Uniform},
    EntryPoint, GpuContext, GpuImage, Recorder, ShaderDef, run_once,
};
use crate::image::FloatImage;
use crate::{Error, Result};

/// The shader of this stage.
pub const SHADER: ShaderDef = ShaderDef {
    name: "log",
    source: include_str!("../../shaders/log.wgsl"),
    includes: &[],
    entry_points: &[
        EntryPoint::tiled("rows", &[Uniform, ReadOnly, Storage, Storage]),
        EntryPoint::tiled("cols", &[Uniform, ReadOnly, ReadOnly, Storage]),
    ],
    overrides: &[],
};

/// Most half-kernel weights the shader's uniform block holds per kernel
/// (7 `vec4`s each: the whole block must fit the recorder's 256-byte stride).
const MAX_TAPS: usize = 28;
/// Largest σ accepted (radius `ceil(3σ)` must stay below `MAX_TAPS`).
pub const MAX_SIGMA: f32 = 9.0;
/// Lanes of the column pass's stack accumulator.
const COL_BLOCK: usize = 256;

/// Parameters of the Laplacian of Gaussian.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogParams {
    /// Standard deviation of the Gaussian in pixels; 001 uses 1.2.
    pub sigma: f32,
}

impl Default for LogParams {
    fn default() -> Self {
        Self { sigma: 1.2 }
    }
}

impl LogParams {
    /// Error unless σ lies in `(0, MAX_SIGMA]` (NaN never does).
    pub fn validate(&self) -> Result<()> {
        Interval::open_closed(0.0, f64::from(MAX_SIGMA)).check("LoG", "sigma", f64::from(self.sigma), " px")
    }
}

/// The two half kernels of the separable LoG, `k = 0..=r`.
#[derive(Clone, Debug, PartialEq)]
pub struct LogKernels {
    /// Gaussian `g_k`; the full kernel sums to 1.
    pub gauss: Vec<f32>,
    /// Second derivative `d_k`; the full kernel sums to 0 and `Σ k²·d_k = 2`.
    pub second: Vec<f32>,
}

impl LogKernels {
    /// Radius `r` of both kernels.
    #[must_use]
    pub fn radius(&self) -> usize {
        self.gauss.len() - 1
    }
}

/// The half kernels of an LoG with standard deviation `sigma` (see the
/// module documentation for how they are built).
pub fn log_kernels(sigma: f32) -> Result<LogKernels> {
    LogParams { sigma }.validate()?;
    let s = sigma as f64;
    let radius = ((3.0 * s).ceil() as usize).max(1);
    // Full-kernel sum of a symmetric half kernel: h_0 + 2 Σ_{k≥1} h_k.
    let full_sum = |h: &[f64]| h[0] + 2.0 * h[1..].iter().sum::<f64>();
    let g: Vec<f64> = (0..=radius).map(|k| (-((k * k) as f64) / (2.0 * s * s)).exp()).collect();
    let g_total = full_sum(&g);
    let g: Vec<f64> = g.iter().map(|v| v / g_total).collect();
    // g''(k) = (k²/σ⁴ − 1/σ²)·g(k), then zero sum, then Σ k²·d_k = 2.
    let d: Vec<f64> = g.iter().enumerate().map(|(k, gk)| (((k * k) as f64) / s.powi(4) - 1.0 / (s * s)) * gk).collect();
    let mean = full_sum(&d) / (2 * radius + 1) as f64;
    let d: Vec<f64> = d.iter().map(|v| v - mean).collect();
    let second_moment = 2.0 * d.iter().enumerate().map(|(k, v)| (k * k) as f64 * v).sum::<f64>();
    if second_moment.is_nan() || second_moment <= 0.0 {
        return Err(Error::Parameter(format!("LoG sigma {sigma}: degenerate second-derivative kernel")));
    }
    let scale = 2.0 / second_moment;
    Ok(LogKernels {
        gauss: g.iter().map(|&v| v as f32).collect(),
        second: d.iter().map(|&v| (v * scale) as f32).collect(),
    })
}

/// Uniform block of `log.wgsl`; kept in sync with its `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct LogUniform {
    width: u32,
    height: u32,
    radius: u32,
    _pad: u32,
    /// The pixels a pass computes: x0, y0, x1, y1.
    region: [u32; 4],
    gauss: [f32; MAX_TAPS],
    second: [f32; MAX_TAPS],
}

// The recorder places uniform blocks 256 bytes apart.
const _: () = assert!(std::mem::size_of::<LogUniform>() <= 256);

impl LogUniform {
    fn new(width: usize, height: usize, k: &LogKernels, region: Window) -> Self {
        let mut gauss = [0.0; MAX_TAPS];
        let mut second = [0.0; MAX_TAPS];
        gauss[..k.gauss.len()].copy_from_slice(&k.gauss);
        second[..k.second.len()].copy_from_slice(&k.second);
        Self {
            width: width as u32,
            height: height as u32,
            radius: k.radius() as u32,
            _pad: 0,
            region: [region.x0, region.y0, region.x1, region.y1],
            gauss,
            second,
        }
    }
}

simd_dispatch!(fn log_row(src: &[f32], tg: &mut [f32], td: &mut [f32], k: &LogKernels) => log_row_body);

/// Row pass of one row, clamp-to-edge: `tg = g ∗ src`, `td = g'' ∗ src`,
/// accumulated `k = 0, 1, …, r` on the pair sums like the shader.
#[inline(always)]
fn log_row_body(src: &[f32], tg: &mut [f32], td: &mut [f32], k: &LogKernels) {
    let (g, d) = (&k.gauss, &k.second);
    let n = src.len();
    let r = k.radius();
    let last = n as isize - 1;
    let edge = |x: usize, tg: &mut [f32], td: &mut [f32]| {
        let mut sum_g = g[0] * src[x];
        let mut sum_d = d[0] * src[x];
        for j in 1..=r {
            let l = (x as isize - j as isize).clamp(0, last) as usize;
            let rr = (x as isize + j as isize).clamp(0, last) as usize;
            let pair = src[l] + src[rr];
            sum_g += g[j] * pair;
            sum_d += d[j] * pair;
        }
        tg[x] = sum_g;
        td[x] = sum_d;
    };
    if n <= 2 * r {
        (0..n).for_each(|x| edge(x, tg, td));
        return;
    }
    (0..r).for_each(|x| edge(x, tg, td));
    (n - r..n).for_each(|x| edge(x, tg, td));
    let inner = r..n - r;
    let (tg_in, td_in) = (&mut tg[inner.clone()], &mut td[inner.clone()]);
    match r {
        1 => return log_row_interior::<2>(src, tg_in, td_in, k),
        2 => return log_row_interior::<3>(src, tg_in, td_in, k),
        3 => return log_row_interior::<4>(src, tg_in, td_in, k),
        4 => return log_row_interior::<5>(src, tg_in, td_in, k),
        _ => {}
    }
    // Interior, tap-major so the inner loop runs along the row and vectorises;
    // each pixel still sums its taps in the order k = 0, 1, …, r.
    let centre = &src[inner];
    for ((a, b), &c) in tg_in.iter_mut().zip(td_in.iter_mut()).zip(centre) {
        *a = g[0] * c;
        *b = d[0] * c;
    }
    for j in 1..=r {
        let left = &src[r - j..n - r - j];
        let right = &src[r + j..n - r + j];
        let (gj, dj) = (g[j], d[j]);
        for (((a, b), &l), &rr) in tg_in.iter_mut().zip(td_in.iter_mut()).zip(left).zip(right) {
            let pair = l + rr;
            *a += gj * pair;
            *b += dj * pair;
        }
    }
}

/// The row pass's interior for kernels of `N` taps (radius `N − 1`) known at
/// compile time: each pixel sums its taps in registers, in the order
/// k = 0, 1, …, r, over shifted views of the row (no bounds checks in the
/// loop, so it vectorises).
#[inline(always)]
fn log_row_interior<const N: usize>(src: &[f32], tg: &mut [f32], td: &mut [f32], k: &LogKernels) {
    let (r, n) = (N - 1, tg.len());
    let g: [f32; N] = std::array::from_fn(|j| k.gauss[j]);
    let d: [f32; N] = std::array::from_fn(|j| k.second[j]);
    let left: [&[f32]; N] = std::array::from_fn(|j| &src[r - j..r - j + n]);
    let right: [&[f32]; N] = std::array::from_fn(|j| &src[r + j..r + j + n]);
    for (i, (a, b)) in tg.iter_mut().zip(td.iter_mut()).enumerate() {
        let c = left[0][i];
        let (mut sum_g, mut sum_d) = (g[0] * c, d[0] * c);
        for j in 1..N {
            let pair = left[j][i] + right[j][i];
            sum_g += g[j] * pair;
            sum_d += d[j] * pair;
        }
        *a = sum_g;
        *b = sum_d;
    }
}

simd_dispatch!(fn log_col_row(tg: &[f32], td: &[f32], rows: RowStore, y: usize, dst: &mut [f32], k: &LogKernels) => log_col_row_body);

/// Column pass for output row `y`: `dst = Σ d_k (tg(y−k) + tg(y+k)) + Σ g_k (td(y−k) + td(y+k))`,
/// each sum accumulated separately (k = 0, 1, …, r) and added last, like the shader.
#[inline(always)]
fn log_col_row_body(tg: &[f32], td: &[f32], rows: RowStore, y: usize, dst: &mut [f32], k: &LogKernels) {
    let (g, d) = (&k.gauss, &k.second);
    // Columns x0..x0+n of row yy (clamped to the image).
    let row_of = |img, yy, x0: usize, n: usize| &rows.row(img, yy)[x0..x0 + n];
    let n = dst.len();
    let rows_at = |j: usize| {
        let (up, down) = (y as isize - j as isize, y as isize + j as isize);
        [row_of(tg, up, 0, n), row_of(tg, down, 0, n), row_of(td, up, 0, n), row_of(td, down, 0, n)]
    };
    match k.radius() {
        1 => return log_col_fixed::<2>(dst, k, rows_at),
        2 => return log_col_fixed::<3>(dst, k, rows_at),
        3 => return log_col_fixed::<4>(dst, k, rows_at),
        4 => return log_col_fixed::<5>(dst, k, rows_at),
        _ => {}
    }
    let mut acc_gd = [0.0f32; COL_BLOCK];
    for (block, out) in dst.chunks_mut(COL_BLOCK).enumerate() {
        let (x0, n) = (block * COL_BLOCK, out.len());
        let acc = &mut acc_gd[..n];
        let (tg_c, td_c) = (row_of(tg, y as isize, x0, n), row_of(td, y as isize, x0, n));
        for (((o, a), &p), &q) in out.iter_mut().zip(acc.iter_mut()).zip(tg_c).zip(td_c) {
            *o = d[0] * p;
            *a = g[0] * q;
        }
        for j in 1..=k.radius() {
            let (up, down) = (y as isize - j as isize, y as isize + j as isize);
            let (tg_u, tg_v) = (row_of(tg, up, x0, n), row_of(tg, down, x0, n));
            let (td_u, td_v) = (row_of(td, up, x0, n), row_of(td, down, x0, n));
            let (gj, dj) = (g[j], d[j]);
            for (((((o, a), &pu), &pv), &qu), &qv) in
                out.iter_mut().zip(acc.iter_mut()).zip(tg_u).zip(tg_v).zip(td_u).zip(td_v)
            {
                *o += dj * (pu + pv);
                *a += gj * (qu + qv);
            }
        }
        for (o, &a) in out.iter_mut().zip(acc.iter()) {
            *o += a;
        }
    }
}

/// The column pass of one output row for kernels of `N` taps known at
/// compile time: both sums in registers, each in the order k = 0, 1, …, r,
/// added last, like the shader. `rows_at(j)` gives the rows j above and j
/// below (clamped) of `tg` and then of `td`.
#[inline(always)]
fn log_col_fixed<'a, const N: usize>(dst: &mut [f32], k: &LogKernels, rows_at: impl Fn(usize) -> [&'a [f32]; 4]) {
    let n = dst.len();
    let g: [f32; N] = std::array::from_fn(|j| k.gauss[j]);
    let d: [f32; N] = std::array::from_fn(|j| k.second[j]);
    let rows: [[&[f32]; 4]; N] = std::array::from_fn(|j| rows_at(j).map(|r| &r[..n]));
    for (i, o) in dst.iter_mut().enumerate() {
        let (mut sum_dg, mut sum_gd) = (d[0] * rows[0][0][i], g[0] * rows[0][2][i]);
        for j in 1..N {
            let [tg_u, tg_v, td_u, td_v] = rows[j];
            sum_dg += d[j] * (tg_u[i] + tg_v[i]);
            sum_gd += g[j] * (td_u[i] + td_v[i]);
        }
        *o = sum_dg + sum_gd;
    }
}

/// CPU twin: the LoG of `src` into `out` (resized to match `src`), using
/// `tmp_g` and `tmp_d` as the intermediates of the row pass (the whole image
/// when rows run on several threads, rings of a few rows otherwise). No allocation
/// once the buffers have grown, apart from the two small kernels.
pub fn log_cpu(
    src: &FloatImage,
    params: &LogParams,
    tmp_g: &mut FloatImage,
    tmp_d: &mut FloatImage,
    out: &mut FloatImage,
) -> Result<()> {
    let k = log_kernels(params.sigma)?;
    let (w, h) = src.size();
    out.resize(w, h);
    if w == 0 || h == 0 {
        tmp_g.resize(w, h);
        tmp_d.resize(w, h);
        return Ok(());
    }
    if !parallel(w * h) {
        log_through_ring(src, &k, tmp_g, tmp_d, out);
        return Ok(());
    }
    tmp_g.resize(w, h);
    tmp_d.resize(w, h);
    let row_pass =
        src.data().par_chunks(w).zip(tmp_g.data_mut().par_chunks_mut(w)).zip(tmp_d.data_mut().par_chunks_mut(w));
    for_each_row(w * h, row_pass, |((s, a), b)| log_row(s, a, b, &k));
    let (tg, td, rows) = (tmp_g.data(), tmp_d.data(), RowStore { width: w, height: h, slots: h });
    for_each_row(w * h, out.data_mut().par_chunks_mut(w).enumerate(), |(y, o)| log_col_row(tg, td, rows, y, o, &k));
    Ok(())
}

/// Both passes on this thread, row by row: the row pass fills rings of the
/// `2r + 1` rows (fewer on a short image) that the next output row of the
/// column pass reads, so the intermediates stay in the fastest cache instead
/// of making a round trip through memory. Same arithmetic as the two
/// whole-image passes, so the same bits.
fn log_through_ring(
    src: &FloatImage,
    k: &LogKernels,
    ring_g: &mut FloatImage,
    ring_d: &mut FloatImage,
    out: &mut FloatImage,
) {
    let (w, h) = src.size();
    let r = k.radius();
    // Two output rows at a time read the 2r + 2 rows around them.
    let rows = RowStore { width: w, height: h, slots: (2 * r + 2).min(h) };
    ring_g.resize(w, rows.slots);
    ring_d.resize(w, rows.slots);
    let mut done = 0;
    for (pair, o) in out.data_mut().chunks_mut(2 * w).enumerate() {
        let y = 2 * pair;
        // Rows up to y + 1 + r (clamped) must have been through the row pass.
        while done <= (y + 1 + r).min(h - 1) {
            let slot = (done % rows.slots) * w..(done % rows.slots + 1) * w;
            log_row(src.row(done), &mut ring_g.data_mut()[slot.clone()], &mut ring_d.data_mut()[slot], k);
            done += 1;
        }
        match o.split_at_mut_checked(w) {
            Some((o0, o1)) if !o1.is_empty() => log_col_row_pair(ring_g.data(), ring_d.data(), rows, y, o0, o1, k),
            _ => log_col_row(ring_g.data(), ring_d.data(), rows, y, o, k),
        }
    }
}

simd_dispatch!(fn log_col_row_pair(tg: &[f32], td: &[f32], rows: RowStore, y: usize, dst0: &mut [f32], dst1: &mut [f32], k: &LogKernels) => log_col_row_pair_body);

/// The column pass of output rows `y` and `y + 1` together, each exactly as
/// [`log_col_row`] computes it: the two rows share all but two of their
/// input rows, so each input value is loaded once for both.
#[inline(always)]
fn log_col_row_pair_body(
    tg: &[f32],
    td: &[f32],
    rows: RowStore,
    y: usize,
    dst0: &mut [f32],
    dst1: &mut [f32],
    k: &LogKernels,
) {
    // Rows y − r ..= y + 1 + r (clamped) of both intermediates.
    let rows_from = |m: usize| {
        let v = y as isize - k.radius() as isize + m as isize;
        [rows.row(tg, v), rows.row(td, v)]
    };
    match k.radius() {
        1 => log_col_pair_fixed::<2, 4>(dst0, dst1, k, rows_from),
        2 => log_col_pair_fixed::<3, 6>(dst0, dst1, k, rows_from),
        3 => log_col_pair_fixed::<4, 8>(dst0, dst1, k, rows_from),
        4 => log_col_pair_fixed::<5, 10>(dst0, dst1, k, rows_from),
        _ => {
            log_col_row_body(tg, td, rows, y, dst0, k);
            log_col_row_body(tg, td, rows, y + 1, dst1, k);
        }
    }
}

/// Two output rows of the column pass for kernels of `N` taps (`M = 2N`
/// input rows, `rows_from(m)` = row `y − r + m` of `tg` and of `td`), each
/// row's sums in the order of [`log_col_fixed`].
#[inline(always)]
fn log_col_pair_fixed<'a, const N: usize, const M: usize>(
    dst0: &mut [f32],
    dst1: &mut [f32],
    k: &LogKernels,
    rows_from: impl Fn(usize) -> [&'a [f32]; 2],
) {
    let n = dst0.len();
    let r = N - 1;
    let g: [f32; N] = std::array::from_fn(|j| k.gauss[j]);
    let d: [f32; N] = std::array::from_fn(|j| k.second[j]);
    let tg: [&[f32]; M] = std::array::from_fn(|m| &rows_from(m)[0][..n]);
    let td: [&[f32]; M] = std::array::from_fn(|m| &rows_from(m)[1][..n]);
    let dst1 = &mut dst1[..n];
    for (i, (o0, o1)) in dst0.iter_mut().zip(dst1.iter_mut()).enumerate() {
        let a: [f32; M] = std::array::from_fn(|m| tg[m][i]);
        let b: [f32; M] = std::array::from_fn(|m| td[m][i]);
        // Row y is at index r, row y + 1 at r + 1.
        let (mut dg0, mut gd0) = (d[0] * a[r], g[0] * b[r]);
        let (mut dg1, mut gd1) = (d[0] * a[r + 1], g[0] * b[r + 1]);
        for j in 1..N {
            dg0 += d[j] * (a[r - j] + a[r + j]);
            gd0 += g[j] * (b[r - j] + b[r + j]);
            dg1 += d[j] * (a[r + 1 - j] + a[r + 1 + j]);
            gd1 += g[j] * (b[r + 1 - j] + b[r + 1 + j]);
        }
        *o0 = dg0 + gd0;
        *o1 = dg1 + gd1;
    }
}

/// CPU twin, allocating its outputs: the LoG image.
pub fn log(src: &FloatImage, params: &LogParams) -> Result<FloatImage> {
    let mut tmp_g = FloatImage::new(0, 0);
    let mut tmp_d = FloatImage::new(0, 0);
    let mut out = FloatImage::new(0, 0);
    log_cpu(src, params, &mut tmp_g, &mut tmp_d, &mut out)?;
    Ok(out)
}

/// Record the two passes `src → (tmp_g, tmp_d) → out` (all the same size)
/// over `part` of the frame (clipped to it): `out` there holds the whole
/// frame's LoG, the row pass covering the rows the column pass reads above
/// and below it. Elsewhere `out` keeps what it held.
pub(crate) fn encode(
    rec: &mut Recorder<'_>,
    src: &GpuImage,
    tmp_g: &GpuImage,
    tmp_d: &GpuImage,
    out: &GpuImage,
    params: &LogParams,
    part: Window,
) -> Result<()> {
    let k = log_kernels(params.sigma)?;
    let (w, h) = (src.width(), src.height());
    for (img, what) in [(tmp_g, "LoG src/tmp_g"), (tmp_d, "LoG src/tmp_d"), (out, "LoG src/out")] {
        src.check_same_size(img, what)?;
    }
    let part = part.clipped(w, h);
    if part.is_empty() {
        return Ok(());
    }
    let r = k.radius() as u32;
    let rows = Window { y0: part.y0.saturating_sub(r), y1: part.y1.saturating_add(r), ..part }.clipped(w, h);
    for (entry, region, buffers) in [
        ("rows", rows, [&src.buffer, &tmp_g.buffer, &tmp_d.buffer]),
        ("cols", part, [&tmp_g.buffer, &tmp_d.buffer, &out.buffer]),
    ] {
        let u = LogUniform::new(w, h, &k, region);
        rec.dispatch(&SHADER, entry, &u, &buffers, src.region_grid(region.width(), region.height()))?;
    }
    Ok(())
}

/// GPU: the LoG of a CPU image, read back (tests and benches).
pub fn log_gpu(ctx: &GpuContext, src: &FloatImage, params: &LogParams) -> Result<FloatImage> {
    let (w, h) = src.size();
    let input = GpuImage::from_image(ctx, src, "log.src");
    let tmp_g = GpuImage::new(ctx, w, h, "log.tmp_g");
    let tmp_d = GpuImage::new(ctx, w, h, "log.tmp_d");
    let out = GpuImage::new(ctx, w, h, "log.out");
    run_once(ctx, |rec| encode(rec, &input, &tmp_g, &tmp_d, &out, params, Window::full(w, h)))?;
    out.download(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testimage::natural;

    fn full_sum(h: &[f32]) -> f64 {
        h[0] as f64 + 2.0 * h[1..].iter().map(|&v| v as f64).sum::<f64>()
    }

    #[test]
    fn kernels_have_nine_taps_unit_mass_zero_sum_and_second_moment_two() {
        let k = log_kernels(1.2).unwrap();
        assert_eq!(k.gauss.len(), 5); // r = ceil(3.6) = 4: 9 taps
        assert_eq!(k.second.len(), 5);
        assert!((full_sum(&k.gauss) - 1.0).abs() < 1e-6);
        assert!(full_sum(&k.second).abs() < 1e-6);
        let m2: f64 = 2.0 * k.second.iter().enumerate().map(|(j, &v)| (j * j) as f64 * v as f64).sum::<f64>();
        assert!((m2 - 2.0).abs() < 1e-5, "second moment {m2}");
        // Centre negative, tails positive, like −1/σ² at 0 and the Mexican hat's brim.
        assert!(k.second[0] < 0.0 && k.second[4] > 0.0);
        // The corrections are small: the f32 centre tap stays within 10 % of
        // the uncorrected continuous value −g(0)/σ² = −0.3324/1.44 · (1/Σg ≈ 1).
        let uncorrected = -k.gauss[0] / (1.2 * 1.2);
        assert!((k.second[0] / uncorrected - 1.0).abs() < 0.1, "{} vs {uncorrected}", k.second[0]);
        assert!(log_kernels(0.0).is_err());
        assert!(log_kernels(f32::NAN).is_err());
        assert!(log_kernels(MAX_SIGMA).is_ok());
        assert!(log_kernels(MAX_SIGMA + 0.01).is_err());
    }

    #[test]
    fn tiny_sigma_gives_the_five_point_laplacian() {
        let k = log_kernels(0.1).unwrap();
        assert_eq!(k.second.len(), 2);
        assert!((k.second[0] + 2.0).abs() < 1e-5 && (k.second[1] - 1.0).abs() < 1e-5, "{:?}", k.second);
    }

    /// LoG of x² + 3y² is 2 + 6 = 8 wherever the clamped border is out of reach
    /// (r = 4 pixels); of a constant or a plane it is 0.
    #[test]
    fn log_of_quadratics_is_their_laplacian() {
        let p = LogParams::default();
        let quad = FloatImage::from_fn(20, 14, |x, y| (x * x) as f32 + 3.0 * (y * y) as f32);
        let l = log(&quad, &p).unwrap();
        for y in 4..10 {
            for x in 4..16 {
                assert!((l.get(x, y) - 8.0).abs() < 2e-3, "({x},{y}): {}", l.get(x, y));
            }
        }
        let plane = FloatImage::from_fn(20, 14, |x, y| 100.0 + 3.0 * x as f32 - 2.0 * y as f32);
        let l = log(&plane, &p).unwrap();
        for y in 4..10 {
            for x in 4..16 {
                assert!(l.get(x, y).abs() < 1e-3, "({x},{y}): {}", l.get(x, y));
            }
        }
        let flat = FloatImage::from_fn(9, 7, |_, _| 255.0);
        let l = log(&flat, &p).unwrap();
        assert!(l.data().iter().all(|v| v.abs() < 1e-3));
    }

    /// An impulse spreads as the 2-D kernel `d_i g_j + g_i d_j`.
    #[test]
    fn impulse_response_is_the_two_d_kernel() {
        let k = log_kernels(1.2).unwrap();
        let imp = FloatImage::from_fn(15, 15, |x, y| if (x, y) == (7, 7) { 1.0 } else { 0.0 });
        let l = log(&imp, &LogParams::default()).unwrap();
        let kernel = |i: usize, j: usize| k.second[i] * k.gauss[j] + k.gauss[i] * k.second[j];
        assert!((l.get(7, 7) - kernel(0, 0)).abs() < 1e-7);
        assert!((l.get(9, 6) - kernel(2, 1)).abs() < 1e-7);
        assert!((l.get(3, 11) - kernel(4, 4)).abs() < 1e-7);
        assert_eq!(l.get(12, 7), 0.0); // beyond radius 4
    }

    /// The CPU twin against a float64 direct 2-D convolution with the same
    /// (f32-rounded) kernels and the same clamp-to-edge border; tolerance 1e-3
    /// on a 0..255 image, several sizes including ones smaller than the kernel.
    #[test]
    fn cpu_twin_matches_direct_f64_convolution() {
        let p = LogParams::default();
        let k = log_kernels(p.sigma).unwrap();
        let r = k.radius() as isize;
        let tap = |h: &[f32], i: isize| h[i.unsigned_abs()] as f64;
        for (w, h) in [(37usize, 29usize), (300, 5), (3, 2), (1, 1)] {
            let src = natural(w, h, 5).to_f32();
            let l = log(&src, &p).unwrap();
            let mut worst = 0.0f64;
            for y in 0..h as isize {
                for x in 0..w as isize {
                    let mut sum = 0.0f64;
                    for j in -r..=r {
                        for i in -r..=r {
                            let v = src.get_clamped(x + i, y + j) as f64;
                            sum += (tap(&k.second, i) * tap(&k.gauss, j) + tap(&k.gauss, i) * tap(&k.second, j)) * v;
                        }
                    }
                    worst = worst.max((l.get(x as usize, y as usize) as f64 - sum).abs());
                }
            }
            assert!(worst < 1e-3, "{w}x{h}: worst |cpu − f64| = {worst}");
        }
    }

    /// The rings of rows give the bits of the two whole-image passes, for
    /// radii with and without a specialised loop and images shorter than
    /// the kernel.
    #[test]
    fn ring_equals_two_whole_image_passes_bitwise() {
        for (w, h) in [(37, 29), (23, 3), (40, 1)] {
            let src = natural(w, h, 13).to_f32();
            for sigma in [0.3, 1.2, 2.0, 3.0] {
                let k = log_kernels(sigma).unwrap();
                let (mut ring_g, mut ring_d) = (FloatImage::new(0, 0), FloatImage::new(0, 0));
                let mut fused = FloatImage::new(w, h);
                log_through_ring(&src, &k, &mut ring_g, &mut ring_d, &mut fused);
                let (mut tg, mut td) = (FloatImage::new(w, h), FloatImage::new(w, h));
                for y in 0..h {
                    let r = y * w..(y + 1) * w;
                    log_row(src.row(y), &mut tg.data_mut()[r.clone()], &mut td.data_mut()[r], &k);
                }
                let rows = RowStore { width: w, height: h, slots: h };
                let mut two_pass = FloatImage::new(w, h);
                for y in 0..h {
                    log_col_row(tg.data(), td.data(), rows, y, &mut two_pass.data_mut()[y * w..(y + 1) * w], &k);
                }
                let bits = |i: &FloatImage| i.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&fused), bits(&two_pass), "{w}x{h}, sigma {sigma}");
            }
        }
    }

    /// The parallel path (≥ PARALLEL_PIXELS) gives the same bits as the serial
    /// one: a 300×240 image against its 300×200 crop (serial), compared where
    /// the crop's clamped top and bottom borders are out of reach (r = 4).
    #[test]
    fn parallel_and_serial_paths_agree() {
        let big = natural(300, 240, 9).to_f32();
        use crate::early::rows::PARALLEL_PIXELS;
        const { assert!(300 * 240 >= PARALLEL_PIXELS && 300 * 200 < PARALLEL_PIXELS) };
        let l = log(&big, &LogParams::default()).unwrap();
        let crop = FloatImage::from_fn(300, 200, |x, y| big.get(x, y + 20));
        let lc = log(&crop, &LogParams::default()).unwrap();
        for y in 30..210 {
            for x in 0..300 {
                assert_eq!(l.get(x, y), lc.get(x, y - 20), "({x},{y})");
            }
        }
    }
}
