//! Zero crossings of the LoG image: Marr–Hildreth edgels (001 "Real-time
//! line detection": "zero-crossing locations where there is a change of sign
//! between adjacent pixels. The approximate gradient at the zero crossing is
//! computed by taking the difference of neighboring pixels across the zero
//! crossing").
//!
//! For each pair of horizontally (or vertically) adjacent LoG values
//! `a = L(x, y)`, `b = L(x+1, y)` (or `L(x, y+1)`):
//! - a crossing exists when their signs differ (0 counts as positive:
//!   `sign(v) = v >= 0`) and the slope `|b − a|` is at least `min_slope`;
//! - its zero lies at `t = a/(a − b) = |a|/(|a| + |b|) ∈ [0, 1]` along the pair;
//! - it is assigned to the pixel nearer to the zero: the first one when
//!   `t ≤ 1/2`, i.e. when `|a| ≤ |b|` (the twins compare magnitudes, not `t`,
//!   so the assignment has no rounding to disagree on).
//!
//! Per pixel, among the crossings assigned to it, the horizontal one with the
//! largest slope and the vertical one with the largest slope are kept (a tie
//! keeps the pair on the left / above). Then `gx = b − a` of the kept
//! horizontal crossing (0 if none), `gy` likewise, and:
//! - `strength = sqrt(gx² + gy²)`, 0 where the pixel has no edgel;
//! - `direction = atan2(gy, gx)` (y down; both twins evaluate the polynomial
//!   [`super::angle::fast_atan2`], operation for operation), 0 where
//!   strength is 0 — the
//!   direction in which the LoG *increases* across the edge, i.e. from the
//!   bright side towards the dark side (opposite the intensity gradient: an
//!   intensity step up to the right gives direction π);
//! - `offset_x`, `offset_y ∈ [−1/2, 1/2]`: the zero's position minus the
//!   pixel's, so the edgel lies at `(x + offset_x, y + offset_y)` (an offset
//!   is 0 along an axis without a kept crossing).
//!
//! Borders clamp to the edge: a border pixel pairs with itself outside the
//! image and so finds no crossing there. Each pixel gathers its 4 neighbours
//! and writes only its own outputs (one dispatch, no atomics).

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::Window;
use super::angle::fast_atan2;
use super::rows::for_each_row;
use crate::Result;
use crate::gpu::{
    Binding::{ReadOnly, Storage, Uniform},
    EntryPoint, GpuContext, GpuImage, Recorder, ShaderDef, run_once,
};
use crate::image::FloatImage;

/// The shader of this stage.
pub const SHADER: ShaderDef = ShaderDef {
    name: "zero_crossing",
    source: include_str!("../../shaders/zero_crossing.wgsl"),
    includes: &[super::angle::INCLUDE],
    entry_points: &[EntryPoint::tiled("edgels", &[Uniform, ReadOnly, Storage, Storage, Storage, Storage])],
    overrides: &[],
};

/// Smallest effective `min_slope`: smaller values (and NaN) act as this one,
/// so every kept slope is far above f32 underflow and `strength > 0` exactly
/// marks the edgels.
pub const MIN_SLOPE_FLOOR: f32 = 1e-6;

/// Parameters of zero-crossing detection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZeroCrossingParams {
    /// Least slope `|b − a|` (LoG units, grey levels per pixel²) across a
    /// crossing. 001 gives none (its Canny hysteresis thresholds on the
    /// gradient come later); pipetrack's default 1.0 is a floor that removes
    /// sign flips of float noise in flat regions (|LoG| there stays below
    /// ~1e-4 on 0..255 images, 4 orders of magnitude under it) while at σ = 1.2
    /// an ideal step of contrast C gives a slope of ≈ 0.21·C (the unit tests'
    /// step of 100 gives ≈ 21), so every step of 5 grey levels or more is kept.
    pub min_slope: f32,
}

impl Default for ZeroCrossingParams {
    fn default() -> Self {
        Self { min_slope: 1.0 }
    }
}

impl ZeroCrossingParams {
    /// The threshold both twins use: `min_slope`, floored at [`MIN_SLOPE_FLOOR`].
    fn effective_min_slope(&self) -> f32 {
        self.min_slope.max(MIN_SLOPE_FLOOR)
    }
}

/// The edgel planes of an image, all the same size (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Edgels {
    /// `sqrt(gx² + gy²)` of the kept crossings; 0 = no edgel.
    pub strength: FloatImage,
    /// `atan2(gy, gx)` in radians, y down; 0 where strength is 0.
    pub direction: FloatImage,
    /// Sub-pixel x of the edgel minus the pixel's x, in `[−1/2, 1/2]`.
    pub offset_x: FloatImage,
    /// Sub-pixel y of the edgel minus the pixel's y, in `[−1/2, 1/2]`.
    pub offset_y: FloatImage,
}

impl Edgels {
    /// Zeroed planes of `width`×`height`.
    #[must_use]
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            strength: FloatImage::new(width, height),
            direction: FloatImage::new(width, height),
            offset_x: FloatImage::new(width, height),
            offset_y: FloatImage::new(width, height),
        }
    }

    /// Width and height.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        self.strength.size()
    }

    /// Resize all planes, reusing their allocations (contents unspecified).
    pub fn resize(&mut self, width: usize, height: usize) {
        self.strength.resize(width, height);
        self.direction.resize(width, height);
        self.offset_x.resize(width, height);
        self.offset_y.resize(width, height);
    }

    /// True when pixel `(x, y)` holds an edgel.
    #[must_use]
    pub fn is_edgel(&self, x: usize, y: usize) -> bool {
        self.strength.get(x, y) > 0.0
    }

    /// Number of edgels.
    #[must_use]
    pub fn count(&self) -> usize {
        self.strength.data().iter().filter(|&&s| s > 0.0).count()
    }
}

/// Uniform block of `zero_crossing.wgsl`; kept in sync with its `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ZeroCrossingUniform {
    width: u32,
    height: u32,
    min_slope: f32,
    _pad: u32,
    /// The pixels the dispatch computes: x0, y0, x1, y1.
    region: [u32; 4],
}

/// The crossing kept by the centre pixel `c` along one axis, from the pairs
/// `(prev, c)` and `(c, next)`: `(b − a, offset)`, or `(0, 0)`. The shader's
/// `axis`, the same values from the same operations, but branch-free: the
/// kept pair is selected first and divided once (where neither is kept the
/// quotient may be NaN and is discarded), so a row of pixels vectorises.
#[inline(always)]
fn axis(prev: f32, c: f32, next: f32, min_slope: f32) -> (f32, f32) {
    let ac = c.abs();
    let c_pos = c >= 0.0;
    // Pair (prev, c): this pixel is the second one, nearer when |prev| > |c|.
    let back_g = c - prev;
    let back_slope = back_g.abs();
    let back = ((prev >= 0.0) != c_pos) & (back_slope >= min_slope) & (prev.abs() > ac);
    // Pair (c, next): this pixel is the first one, nearer when |c| ≤ |next|.
    let fwd_g = next - c;
    let fwd_slope = fwd_g.abs();
    let fwd = (c_pos != (next >= 0.0)) & (fwd_slope >= min_slope) & (ac <= next.abs());
    let take_fwd = fwd & (!back | (fwd_slope > back_slope));
    let (g, slope) = if take_fwd { (fwd_g, fwd_slope) } else { (back_g, back_slope) };
    // |c| / slope: the zero's distance from this pixel, forwards or backwards.
    let t = ac / slope;
    let o = if take_fwd { t } else { -t };
    if take_fwd | back { (g, o) } else { (0.0, 0.0) }
}

/// One pixel's outputs `(strength, direction, offset_x, offset_y)` from its
/// value and its 4 (clamped) neighbours. Branch-free; `fast_atan2(0, 0)` is
/// 0, so the direction needs no guard where there is no edgel.
#[inline(always)]
fn edgel(c: f32, left: f32, right: f32, up: f32, down: f32, min_slope: f32) -> (f32, f32, f32, f32) {
    let (gx, ox) = axis(left, c, right, min_slope);
    let (gy, oy) = axis(up, c, down, min_slope);
    let strength = (gx * gx + gy * gy).sqrt();
    (strength, fast_atan2(gy, gx), ox, oy)
}

/// Output rows of one image row `cur`, with the rows above and below
/// (clamped: `up`/`down` is `cur` itself at the image border).
struct RowOut<'a> {
    strength: &'a mut [f32],
    direction: &'a mut [f32],
    offset_x: &'a mut [f32],
    offset_y: &'a mut [f32],
}

simd_dispatch!(fn edgel_row(up: &[f32], cur: &[f32], down: &[f32], min_slope: f32, out: RowOut<'_>) => edgel_row_body);
simd_dispatch!(fn edgel_row_without_offsets(up: &[f32], cur: &[f32], down: &[f32], min_slope: f32, out: RowOut<'_>) => edgel_row_without_offsets_body);

/// One output row, all four planes.
#[inline(always)]
fn edgel_row_body(up: &[f32], cur: &[f32], down: &[f32], min_slope: f32, out: RowOut<'_>) {
    edgel_row_planes::<true>(up, cur, down, min_slope, out);
}

/// One output row, strength and direction only (`out`'s offset rows are
/// left alone): the same values without the two divisions of the offsets.
#[inline(always)]
fn edgel_row_without_offsets_body(up: &[f32], cur: &[f32], down: &[f32], min_slope: f32, out: RowOut<'_>) {
    edgel_row_planes::<false>(up, cur, down, min_slope, out);
}

/// One output row: the interior columns in one straight, vectorisable loop
/// over equal-length slices (no clamping, no bounds checks), then the two
/// border columns with their clamped neighbours. The offset planes are
/// written only with `OFFSETS`.
#[inline(always)]
fn edgel_row_planes<const OFFSETS: bool>(up: &[f32], cur: &[f32], down: &[f32], min_slope: f32, out: RowOut<'_>) {
    let w = cur.len();
    let RowOut { strength, direction, offset_x, offset_y } = out;
    let mut put = |x: usize, left: f32, right: f32| {
        let (s, d, ox, oy) = edgel(cur[x], left, right, up[x], down[x], min_slope);
        (strength[x], direction[x]) = (s, d);
        if OFFSETS {
            (offset_x[x], offset_y[x]) = (ox, oy);
        }
    };
    if w == 1 {
        put(0, cur[0], cur[0]);
        return;
    }
    put(0, cur[0], cur[1]);
    put(w - 1, cur[w - 2], cur[w - 1]);
    if w < 3 {
        return;
    }
    let n = w - 2;
    let (l, c, r) = (&cur[..n], &cur[1..=n], &cur[2..n + 2]);
    let (u, d) = (&up[1..=n], &down[1..=n]);
    let (s, dir) = (&mut strength[1..=n], &mut direction[1..=n]);
    if OFFSETS {
        let (ox, oy) = (&mut offset_x[1..=n], &mut offset_y[1..=n]);
        for i in 0..n {
            (s[i], dir[i], ox[i], oy[i]) = edgel(c[i], l[i], r[i], u[i], d[i], min_slope);
        }
    } else {
        for i in 0..n {
            let (strength, direction, _, _) = edgel(c[i], l[i], r[i], u[i], d[i], min_slope);
            (s[i], dir[i]) = (strength, direction);
        }
    }
}

/// CPU twin: the edgels of the LoG image `log` into `out` (resized to match).
/// No allocation once `out` has grown.
pub fn zero_crossing_cpu(log: &FloatImage, params: &ZeroCrossingParams, out: &mut Edgels) {
    let (w, h) = log.size();
    out.resize(w, h);
    if w == 0 || h == 0 {
        return;
    }
    let min_slope = params.effective_min_slope();
    let l = log.data();
    let row = |y: usize| &l[y * w..(y + 1) * w];
    let one_row = |y: usize, out: RowOut<'_>| {
        edgel_row(row(y.saturating_sub(1)), row(y), row((y + 1).min(h - 1)), min_slope, out)
    };
    let Edgels { strength, direction, offset_x, offset_y } = out;
    let planes = (
        strength.data_mut().par_chunks_mut(w),
        direction.data_mut().par_chunks_mut(w),
        offset_x.data_mut().par_chunks_mut(w),
        offset_y.data_mut().par_chunks_mut(w),
    );
    for_each_row(w * h, planes.into_par_iter().enumerate(), |(y, (s, d, ox, oy))| {
        one_row(y, RowOut { strength: s, direction: d, offset_x: ox, offset_y: oy })
    });
}

/// The `strength` and `direction` planes of [`zero_crossing_cpu`] alone,
/// bit for bit, into images resized to match `log`: for callers that list
/// edgels and never read their sub-pixel offsets (it skips their divisions).
pub fn zero_crossing_strength_direction_cpu(
    log: &FloatImage,
    params: &ZeroCrossingParams,
    strength: &mut FloatImage,
    direction: &mut FloatImage,
) {
    let (w, h) = log.size();
    strength.resize(w, h);
    direction.resize(w, h);
    if w == 0 || h == 0 {
        return;
    }
    let min_slope = params.effective_min_slope();
    let l = log.data();
    let row = |y: usize| &l[y * w..(y + 1) * w];
    let planes = (strength.data_mut().par_chunks_mut(w), direction.data_mut().par_chunks_mut(w));
    for_each_row(w * h, planes.into_par_iter().enumerate(), |(y, (s, d))| {
        let out = RowOut { strength: s, direction: d, offset_x: &mut [], offset_y: &mut [] };
        edgel_row_without_offsets(row(y.saturating_sub(1)), row(y), row((y + 1).min(h - 1)), min_slope, out);
    });
}

/// CPU twin, allocating its outputs: the edgels of the LoG image `log`.
#[must_use]
pub fn zero_crossing(log: &FloatImage, params: &ZeroCrossingParams) -> Edgels {
    let mut out = Edgels::new(0, 0);
    zero_crossing_cpu(log, params, &mut out);
    out
}

/// The edgel planes on the GPU, all the same size.
#[derive(Debug)]
pub struct EdgelsGpu {
    /// See [`Edgels::strength`].
    pub strength: GpuImage,
    /// See [`Edgels::direction`].
    pub direction: GpuImage,
    /// See [`Edgels::offset_x`].
    pub offset_x: GpuImage,
    /// See [`Edgels::offset_y`].
    pub offset_y: GpuImage,
}

impl EdgelsGpu {
    /// Allocate (uninitialised) planes of `width`×`height`.
    #[must_use]
    pub fn new(ctx: &GpuContext, width: usize, height: usize) -> Self {
        Self::layered(ctx, width, height, 1)
    }

    /// Four planes of `layers` stacked images each ([`GpuImage::layered`]).
    #[must_use]
    pub fn layered(ctx: &GpuContext, width: usize, height: usize, layers: usize) -> Self {
        let plane = |label| GpuImage::layered(ctx, width, height, layers, label);
        Self {
            strength: plane("zero_crossing.strength"),
            direction: plane("zero_crossing.direction"),
            offset_x: plane("zero_crossing.offset_x"),
            offset_y: plane("zero_crossing.offset_y"),
        }
    }

    /// Copy all four planes back to the CPU (waits for the GPU).
    pub fn download(&self, ctx: &GpuContext) -> Result<Edgels> {
        Ok(Edgels {
            strength: self.strength.download(ctx)?,
            direction: self.direction.download(ctx)?,
            offset_x: self.offset_x.download(ctx)?,
            offset_y: self.offset_y.download(ctx)?,
        })
    }
}

/// Record the one dispatch `log → out` (same size) over `part` of the
/// frame (clipped to it): the outputs there are the whole frame's, given
/// the LoG of `part` grown by one pixel. Elsewhere they keep what they held.
pub(crate) fn encode(
    rec: &mut Recorder<'_>,
    log: &GpuImage,
    out: &EdgelsGpu,
    params: &ZeroCrossingParams,
    part: Window,
) -> Result<()> {
    let (w, h) = (log.width(), log.height());
    for (plane, what) in [
        (&out.strength, "zero crossing LoG/strength"),
        (&out.direction, "zero crossing LoG/direction"),
        (&out.offset_x, "zero crossing LoG/offset_x"),
        (&out.offset_y, "zero crossing LoG/offset_y"),
    ] {
        log.check_same_size(plane, what)?;
    }
    let part = part.clipped(w, h);
    let u = ZeroCrossingUniform {
        width: w as u32,
        height: h as u32,
        min_slope: params.effective_min_slope(),
        _pad: 0,
        region: [part.x0, part.y0, part.x1, part.y1],
    };
    rec.dispatch(
        &SHADER,
        "edgels",
        &u,
        &[&log.buffer, &out.strength.buffer, &out.direction.buffer, &out.offset_x.buffer, &out.offset_y.buffer],
        log.region_grid(part.width(), part.height()),
    )
}

/// GPU: the edgels of a CPU LoG image, read back (tests and benches).
pub fn zero_crossing_gpu(ctx: &GpuContext, log: &FloatImage, params: &ZeroCrossingParams) -> Result<Edgels> {
    let (w, h) = log.size();
    let input = GpuImage::from_image(ctx, log, "zero_crossing.log");
    let out = EdgelsGpu::new(ctx, w, h);
    run_once(ctx, |rec| encode(rec, &input, &out, params, Window::full(w, h)))?;
    out.download(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::early::log::{LogParams, log};
    use std::f32::consts::PI;

    /// The dispatched row (AVX2 where the CPU has it) equals the baseline
    /// build of the same body bit for bit, on every plane.
    #[test]
    fn dispatched_rows_equal_baseline_rows_bitwise() {
        let (w, h) = (41, 11);
        let l = log(&crate::testimage::natural(w, h, 5).to_f32(), &LogParams::default()).unwrap();
        let p = ZeroCrossingParams::default();
        let fast = zero_crossing(&l, &p);
        assert!(fast.count() > 0);
        let mut base = Edgels::new(w, h);
        let row = |y: usize| &l.data()[y * w..(y + 1) * w];
        for y in 0..h {
            let r = y * w..(y + 1) * w;
            let Edgels { strength, direction, offset_x, offset_y } = &mut base;
            let out = RowOut {
                strength: &mut strength.data_mut()[r.clone()],
                direction: &mut direction.data_mut()[r.clone()],
                offset_x: &mut offset_x.data_mut()[r.clone()],
                offset_y: &mut offset_y.data_mut()[r],
            };
            edgel_row_body(row(y.saturating_sub(1)), row(y), row((y + 1).min(h - 1)), p.effective_min_slope(), out);
        }
        let bits = |e: &Edgels| -> Vec<u32> {
            [&e.strength, &e.direction, &e.offset_x, &e.offset_y]
                .iter()
                .flat_map(|p| p.data().iter().map(|v| v.to_bits()))
                .collect()
        };
        assert_eq!(bits(&fast), bits(&base));
    }

    /// Columns 0..=4 are 0, 5..=9 are 100. The LoG is antisymmetric about
    /// x = 4.5 (L(9 − x) = −L(x), since LoG(100 − f) = −LoG(f)): positive on
    /// the dark side (the smoothed profile curves upwards there), negative on
    /// the bright side, so a = L(4) > 0 > b = L(5) = −a and t = a/(a − b) = 1/2:
    /// the zero is at x = 4.5 exactly. gx = b − a < 0 and every row is the
    /// same (no vertical crossing, gy = 0), so direction = atan2(0, gx) = π.
    #[test]
    fn vertical_step_edge_crosses_between_columns_four_and_five() {
        let step = FloatImage::from_fn(10, 6, |x, _| if x <= 4 { 0.0 } else { 100.0 });
        let l = log(&step, &LogParams::default()).unwrap();
        assert!(l.get(4, 2) > 0.0 && l.get(5, 2) < 0.0);
        assert!((l.get(4, 2) + l.get(5, 2)).abs() < 1e-3);
        let e = zero_crossing(&l, &ZeroCrossingParams::default());
        for y in 0..6 {
            let cols: Vec<usize> = (0..10).filter(|&x| e.is_edgel(x, y)).collect();
            assert_eq!(cols.len(), 1, "row {y}: edgels at {cols:?}");
            let x = cols[0];
            assert!(x == 4 || x == 5, "row {y}: edgel at column {x}");
            let sub_x = x as f32 + e.offset_x.get(x, y);
            assert!((sub_x - 4.5).abs() < 0.05, "row {y}: sub-pixel x {sub_x}");
            assert_eq!(e.offset_y.get(x, y), 0.0);
            assert!((e.direction.get(x, y).abs() - PI).abs() < 1e-6, "direction {}", e.direction.get(x, y));
            // Strength = |gx| = |L(5) − L(4)| ≈ 0.21 × contrast 100 (the default's justification).
            let s = e.strength.get(x, y);
            assert!((s - (l.get(5, y) - l.get(4, y)).abs()).abs() < 1e-5);
            assert!(s > 15.0 && s < 30.0, "slope {s}");
        }
    }

    /// L = [−1, 3, 3]: pair (−1, 3) changes sign, slope 4 ≥ 1, t = 1/4, so the
    /// edgel goes to pixel 0 with offset_x 0.25, gx = 4, direction 0, strength
    /// 4; pair (3, 3) does not change sign.
    #[test]
    fn literal_three_by_one() {
        let l = FloatImage::from_vec(3, 1, vec![-1.0, 3.0, 3.0]).unwrap();
        let e = zero_crossing(&l, &ZeroCrossingParams { min_slope: 1.0 });
        assert_eq!(e.strength.data(), &[4.0, 0.0, 0.0]);
        assert_eq!(e.offset_x.data(), &[0.25, 0.0, 0.0]);
        assert_eq!(e.direction.data(), &[0.0, 0.0, 0.0]);
        assert_eq!(e.offset_y.data(), &[0.0, 0.0, 0.0]);
        // Mirrored, [3, 3, −1]: t = 3/4 → pixel 2, offset −0.25, gx = −4, direction π.
        let l = FloatImage::from_vec(3, 1, vec![3.0, 3.0, -1.0]).unwrap();
        let e = zero_crossing(&l, &ZeroCrossingParams { min_slope: 1.0 });
        assert_eq!(e.strength.data(), &[0.0, 0.0, 4.0]);
        assert_eq!(e.offset_x.data(), &[0.0, 0.0, -0.25]);
        assert!((e.direction.get(2, 0) - PI).abs() < 1e-6);
        // A slope below min_slope is no crossing: [−1, 3] with min_slope 5.
        let e = zero_crossing(
            &FloatImage::from_vec(2, 1, vec![-1.0, 3.0]).unwrap(),
            &ZeroCrossingParams { min_slope: 5.0 },
        );
        assert_eq!(e.count(), 0);
    }

    /// Zero counts as positive: [0, −2] is a crossing (slope 2) at t = 0,
    /// pixel 0, offset 0; [0, 2] is not.
    #[test]
    fn zero_is_positive() {
        let e = zero_crossing(&FloatImage::from_vec(2, 1, vec![0.0, -2.0]).unwrap(), &ZeroCrossingParams::default());
        assert_eq!(e.strength.data(), &[2.0, 0.0]);
        assert_eq!(e.offset_x.data(), &[0.0, 0.0]);
        let e = zero_crossing(&FloatImage::from_vec(2, 1, vec![0.0, 2.0]).unwrap(), &ZeroCrossingParams::default());
        assert_eq!(e.count(), 0);
    }

    /// A 3×3 literal with a horizontal and a vertical crossing at the centre:
    /// centre 1, right −3 (t = 1/4 → centre, gx = −4, offset_x 0.25); below −1
    /// (t = 1/2 exactly: |1| ≤ |−1|, so the first pixel, the centre, gets it:
    /// gy = −2, offset_y 0.5). Left 2 and above 5 are positive like the centre.
    /// strength = sqrt(16 + 4), direction = atan2(−2, −4).
    #[test]
    fn both_axes_and_the_half_way_tie() {
        #[rustfmt::skip]
        let l = FloatImage::from_vec(3, 3, vec![
            5.0, 5.0, 5.0,
            2.0, 1.0, -3.0,
            -1.0, -1.0, -3.0,
        ]).unwrap();
        let e = zero_crossing(&l, &ZeroCrossingParams::default());
        assert!((e.strength.get(1, 1) - 20f32.sqrt()).abs() < 1e-6);
        assert!((e.direction.get(1, 1) - (-2f32).atan2(-4.0)).abs() < 1e-6);
        assert_eq!(e.offset_x.get(1, 1), 0.25);
        assert_eq!(e.offset_y.get(1, 1), 0.5);
    }

    /// Two crossings assigned to one pixel along an axis: the steeper is kept.
    /// [4, −1, 9]: (4, −1) slope 5, |4| > |−1| → pixel 1, offset −0.2;
    /// (−1, 9) slope 10, |−1| ≤ |9| → pixel 1, offset 0.1: gx = 10 wins.
    #[test]
    fn steeper_crossing_wins() {
        let e =
            zero_crossing(&FloatImage::from_vec(3, 1, vec![4.0, -1.0, 9.0]).unwrap(), &ZeroCrossingParams::default());
        assert_eq!(e.strength.data(), &[0.0, 10.0, 0.0]);
        assert!((e.offset_x.get(1, 0) - 0.1).abs() < 1e-7);
    }

    #[test]
    fn strength_and_direction_alone_equal_the_full_planes_bitwise() {
        for (w, h) in [(41, 11), (1, 1), (2, 5), (300, 250)] {
            let l = log(&crate::testimage::natural(w, h, 8).to_f32(), &LogParams::default()).unwrap();
            let p = ZeroCrossingParams::default();
            let full = zero_crossing(&l, &p);
            let (mut s, mut d) = (FloatImage::new(0, 0), FloatImage::new(0, 0));
            zero_crossing_strength_direction_cpu(&l, &p, &mut s, &mut d);
            let bits = |i: &FloatImage| i.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&s), bits(&full.strength), "{w}x{h}");
            assert_eq!(bits(&d), bits(&full.direction), "{w}x{h}");
        }
    }

    #[test]
    fn one_pixel_and_empty_images_have_no_edgels() {
        let e = zero_crossing(&FloatImage::from_vec(1, 1, vec![-5.0]).unwrap(), &ZeroCrossingParams::default());
        assert_eq!(e.size(), (1, 1));
        assert_eq!(e.count(), 0);
        assert_eq!(e.direction.get(0, 0), 0.0);
        let e = zero_crossing(&FloatImage::new(0, 0), &ZeroCrossingParams::default());
        assert_eq!(e.size(), (0, 0));
    }

    /// Float noise of a flat region (sign flips of ±1e-5) is no edgel at the
    /// default min_slope; a NaN or zero min_slope acts as MIN_SLOPE_FLOOR, so
    /// flips of ±1e-7 (slope 2e-7) are still none.
    #[test]
    fn flat_noise_is_no_edgel() {
        let l = FloatImage::from_fn(8, 8, |x, y| if (x + y) % 2 == 0 { 1e-5 } else { -1e-5 });
        assert_eq!(zero_crossing(&l, &ZeroCrossingParams::default()).count(), 0);
        let l = FloatImage::from_fn(8, 8, |x, y| if (x + y) % 2 == 0 { 1e-7 } else { -1e-7 });
        assert_eq!(zero_crossing(&l, &ZeroCrossingParams { min_slope: f32::NAN }).count(), 0);
        assert_eq!(zero_crossing(&l, &ZeroCrossingParams { min_slope: 0.0 }).count(), 0);
    }
}
