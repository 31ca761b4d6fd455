//! Critical-point filter (CPF) hierarchies (004 eq. 1–4, after Shinagawa and
//! Kunii), and the level machinery (sizes, concatenated GPU layout, row
//! reduction) that the averaged edge hierarchies of [`super::edge_pyramid`]
//! share.
//!
//! # The four CPF hierarchies
//! Each level halves the previous one; a parent takes, over its 2×2
//! children `p00 = (2i, 2j)`, `p01 = (2i, 2j+1)`, `p10 = (2i+1, 2j)`,
//! `p11 = (2i+1, 2j+1)`:
//!
//! | m | paper type   | value                                       | eq. |
//! |---|--------------|---------------------------------------------|-----|
//! | 0 | minimum      | `min(min(p00, p01), min(p10, p11))`         | 1   |
//! | 1 | saddle point | `max(min(p00, p01), min(p10, p11))`         | 2   |
//! | 2 | saddle point | `min(max(p00, p01), max(p10, p11))`         | 3   |
//! | 3 | maximum      | `max(max(p00, p01), max(p10, p11))`         | 4   |
//!
//! Deeper levels read their own hierarchy's previous level; the first
//! reduced level of all four reads the input.
//!
//! **Which index is x.** 004 does not say whether `i` in `p_(i,j)` is the
//! column or the row. We read `(i, j)` as `(x, y)`, as the paper writes
//! every other image coordinate pair (window vertices `f = (u, v)`, "*i* and
//! *j* are the coordinates of a pixel"), and as Shinagawa and Kunii do: `i` is
//! the column, `j` the row. So the inner min/max of eq. 1–4 takes the two
//! vertically adjacent children of one column, `(2i, 2j)` and `(2i, 2j+1)`,
//! and the outer op combines the left and the right column. The reading
//! matters only for the saddle hierarchies m = 1, 2: with `i` as the row they
//! would be the max of row minima and the min of row maxima (the same filters
//! on the transposed image).
//!
//! **Parent index.** The OCR of 004 garbles the parent of `(i, j)` as
//! `(⌊i/2⌋, ⌊i/2⌋)`; we take it as `(⌊i/2⌋, ⌊j/2⌋)`, the only reading
//! consistent with eq. 1–4. Likewise the garbled child indices `(2i, 2)`,
//! `(2i, 2)+1)` of eq. 10 are read as `(2i, 2j)`, `(2i, 2j+1)`, as in eq. 11.
//!
//! # Levels and odd sizes
//! `levels[0]` is the finest level (the input, `w`×`h`); `levels[k]` is
//! `ceil(w/2^k)`×`ceil(h/2^k)`, down to 1×1 inclusive (see [`level_sizes`]).
//! The paper's level is `l = d − k` with `d = levels.len() − 1` (a 256×256
//! input has `d = 8` and 9 levels, `l = 8..=0`). When a level has an odd
//! width (height), the last column (row) of parents has only one child column
//! (row): the missing child is clamped to the edge child. For min/max that is
//! the filter over the children that exist (a parent with one child column
//! gets `m1 = min`, `m2 = max` of that column; with one child row it gets
//! `m1 = max`, `m2 = min` of that row). A 1×1 input has one level.
//!
//! # GPU layout
//! Each hierarchy lives in ONE storage buffer with its levels concatenated
//! (level 0 first, offsets from [`CpfGpu::level_offsets`]); the shaders read
//! the previous level's size and offset from their uniform.

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::rows::{for_each_row, parallel};
use crate::gpu::{
    Binding::{Storage, Uniform},
    EntryPoint, GpuContext, GpuImage, Include, Recorder, ShaderDef, run_once, workgroups_2d,
};
use crate::image::FloatImage;
use crate::{Error, Result};

/// The shader of the CPF hierarchies.
pub const SHADER: ShaderDef = ShaderDef {
    name: "cpf",
    source: include_str!("../../shaders/cpf.wgsl"),
    includes: &[PYRAMID_TILE],
    entry_points: &[EntryPoint::pyramid_levels("cpf_levels", &[Uniform, Storage, Storage, Storage, Storage])],
    overrides: &[],
};

/// The index arithmetic of a pyramid built several levels to a dispatch,
/// included by `cpf.wgsl` and `edge_pyramid.wgsl`.
pub(super) const PYRAMID_TILE: Include =
    Include { name: "pyramid_tile", source: include_str!("../../shaders/pyramid_tile.wgsl") };

/// Number of CPF hierarchies (m = 0..3: minimum, two saddles, maximum).
pub const HIERARCHIES: usize = 4;

/// Sizes of all levels of a `width`×`height` input, finest first:
/// `levels[k]` is `ceil(width/2^k)`×`ceil(height/2^k)`, down to 1×1
/// inclusive. An empty input (`width` or `height` 0) has just its own level.
#[must_use]
pub fn level_sizes(width: usize, height: usize) -> Vec<(usize, usize)> {
    let mut sizes = vec![(width, height)];
    if width == 0 || height == 0 {
        return sizes;
    }
    let (mut w, mut h) = (width, height);
    while w > 1 || h > 1 {
        w = w.div_ceil(2);
        h = h.div_ceil(2);
        sizes.push((w, h));
    }
    sizes
}

/// The four CPF hierarchies of one image.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CpfPyramids {
    /// `hierarchies[m][k]`: hierarchy m (0 min, 1 max of column minima,
    /// 2 min of column maxima, 3 max) at level k (0 = finest, the input).
    pub hierarchies: [Vec<FloatImage>; HIERARCHIES],
}

// ---------------------------------------------------------------- CPU twin

/// One parent row from child rows `r0` (row 2j) and `r1` (row 2j+1, or 2j
/// when clamped): `dst[i] = outer(inner(r0[2i], r1[2i]), inner(r0[2i+1], r1[2i+1]))`,
/// the last column clamped when `r0` has odd length.
#[inline(always)]
pub(super) fn reduce_row(
    r0: &[f32],
    r1: &[f32],
    dst: &mut [f32],
    inner: impl Fn(f32, f32) -> f32,
    outer: impl Fn(f32, f32) -> f32,
) {
    let pairs = r0.len() / 2;
    for ((d, a), b) in dst[..pairs].iter_mut().zip(r0.chunks_exact(2)).zip(r1.chunks_exact(2)) {
        *d = outer(inner(a[0], b[0]), inner(a[1], b[1]));
    }
    if r0.len() % 2 == 1 {
        let last = r0.len() - 1;
        let column = inner(r0[last], r1[last]);
        dst[pairs] = outer(column, column);
    }
}

/// First reduced level of all four hierarchies from one input row pair.
fn cpf_rows_all(r0: &[f32], r1: &[f32], dst: [&mut [f32]; HIERARCHIES]) {
    let [d0, d1, d2, d3] = dst;
    let pairs = r0.len() / 2;
    let outs = d0[..pairs].iter_mut().zip(&mut d1[..pairs]).zip(&mut d2[..pairs]).zip(&mut d3[..pairs]);
    for ((((o0, o1), o2), o3), (a, b)) in outs.zip(r0.chunks_exact(2).zip(r1.chunks_exact(2))) {
        // Column 2i: (2i, 2j), (2i, 2j+1); column 2i+1 likewise.
        let (lo_l, hi_l) = (a[0].min(b[0]), a[0].max(b[0]));
        let (lo_r, hi_r) = (a[1].min(b[1]), a[1].max(b[1]));
        *o0 = lo_l.min(lo_r); // eq. 1
        *o1 = lo_l.max(lo_r); // eq. 2
        *o2 = hi_l.min(hi_r); // eq. 3
        *o3 = hi_l.max(hi_r); // eq. 4
    }
    if r0.len() % 2 == 1 {
        let last = r0.len() - 1;
        let (lo, hi) = (r0[last].min(r1[last]), r0[last].max(r1[last]));
        d0[pairs] = lo.min(lo);
        d1[pairs] = lo.max(lo);
        d2[pairs] = hi.min(hi);
        d3[pairs] = hi.max(hi);
    }
}

/// The two child rows of parent row `y` in a `height`-row level (the second clamped).
#[inline]
fn child_rows(y: usize, height: usize) -> (usize, usize) {
    (2 * y, (2 * y + 1).min(height - 1))
}

/// Build `dst` (already sized) from `src` one parent row at a time with `row`.
pub(super) fn reduce_level(src: &FloatImage, dst: &mut FloatImage, row: impl Fn(&[f32], &[f32], &mut [f32]) + Sync) {
    let (sw, sh) = src.size();
    let dw = dst.width();
    if dw == 0 || dst.height() == 0 {
        return;
    }
    let body = |(y, d): (usize, &mut [f32])| {
        let (y0, y1) = child_rows(y, sh);
        row(src.row(y0), src.row(y1), d);
    };
    for_each_row(sw * sh, dst.data_mut().par_chunks_mut(dw).enumerate(), body);
}

/// Level 1 of all four hierarchies from the input (each `dst` already
/// sized), copying the input into each of `copies` (level-0 images of the
/// input's size) on the way: on one thread row by row, while the rows are
/// in the fastest cache for the reduction anyway.
fn cpf_first_level(src: &FloatImage, dst: [&mut FloatImage; HIERARCHIES], copies: &mut [&mut FloatImage]) {
    let (sw, sh) = src.size();
    let [d0, d1, d2, d3] = dst;
    let dw = d0.width();
    if dw == 0 || d0.height() == 0 {
        for c in copies.iter_mut() {
            c.data_mut().copy_from_slice(src.data());
        }
        return;
    }
    if !parallel(sw * sh) {
        let outs = d0.data_mut().chunks_exact_mut(dw).zip(d1.data_mut().chunks_exact_mut(dw));
        let outs = outs.zip(d2.data_mut().chunks_exact_mut(dw)).zip(d3.data_mut().chunks_exact_mut(dw));
        for (y, (((a, b), c), d)) in outs.enumerate() {
            let (y0, y1) = child_rows(y, sh);
            cpf_rows_all(src.row(y0), src.row(y1), [a, b, c, d]);
            for copy in copies.iter_mut() {
                let rows = y0 * sw..(y1 + 1) * sw;
                copy.data_mut()[rows.clone()].copy_from_slice(&src.data()[rows]);
            }
        }
        return;
    }
    for c in copies.iter_mut() {
        c.data_mut().copy_from_slice(src.data());
    }
    let planes = (
        d0.data_mut().par_chunks_mut(dw),
        d1.data_mut().par_chunks_mut(dw),
        d2.data_mut().par_chunks_mut(dw),
        d3.data_mut().par_chunks_mut(dw),
    );
    for_each_row(sw * sh, planes.into_par_iter().enumerate(), |(y, (a, b, c, d))| {
        let (y0, y1) = child_rows(y, sh);
        cpf_rows_all(src.row(y0), src.row(y1), [a, b, c, d]);
    });
}

/// Level k ≥ 2 of hierarchy `m` from its level k − 1 (`dst` already sized).
fn cpf_next_level(m: usize, src: &FloatImage, dst: &mut FloatImage) {
    match m {
        0 => reduce_level(src, dst, |a, b, d| reduce_row(a, b, d, f32::min, f32::min)),
        1 => reduce_level(src, dst, |a, b, d| reduce_row(a, b, d, f32::min, f32::max)),
        2 => reduce_level(src, dst, |a, b, d| reduce_row(a, b, d, f32::max, f32::min)),
        _ => reduce_level(src, dst, |a, b, d| reduce_row(a, b, d, f32::max, f32::max)),
    }
}

/// Resize `levels` to the given sizes, reusing their allocations.
pub(super) fn shape_levels(levels: &mut Vec<FloatImage>, sizes: &[(usize, usize)]) {
    levels.resize_with(sizes.len(), || FloatImage::new(0, 0));
    for (img, &(w, h)) in levels.iter_mut().zip(sizes) {
        img.resize(w, h);
    }
}

/// CPU twin: all levels of the four CPF hierarchies of `src` into `out`,
/// reusing its allocations (no allocation once they have grown).
pub fn cpf_cpu(src: &FloatImage, out: &mut CpfPyramids) {
    let sizes = level_sizes(src.width(), src.height());
    for levels in &mut out.hierarchies {
        shape_levels(levels, &sizes);
    }
    reduce_hierarchies(src, out, &sizes, 0);
}

/// [`cpf_cpu`] for a caller done with its input: `src` becomes level 0 of
/// hierarchy 0 without a copy, and `src` is left holding an image of the
/// same size whose values are unspecified (the buffer that level held).
/// The hierarchies are those [`cpf_cpu`] gives.
pub fn cpf_cpu_taking(src: &mut FloatImage, out: &mut CpfPyramids) {
    let sizes = level_sizes(src.width(), src.height());
    for levels in &mut out.hierarchies {
        shape_levels(levels, &sizes);
    }
    std::mem::swap(src, &mut out.hierarchies[0][0]);
    let input = std::mem::replace(&mut out.hierarchies[0][0], FloatImage::new(0, 0));
    reduce_hierarchies(&input, out, &sizes, 1);
    out.hierarchies[0][0] = input;
}

/// Levels 1.. of the four hierarchies of `src` into `out`, leaving each
/// level 0 (shaped to the input's size) with unspecified values instead of
/// four copies of `src`: for a caller that keeps the hierarchies where no
/// one reads their level 0, which is the input it holds anyway.
pub(crate) fn cpf_cpu_coarser_levels(src: &FloatImage, out: &mut CpfPyramids) {
    let sizes = level_sizes(src.width(), src.height());
    for levels in &mut out.hierarchies {
        shape_levels(levels, &sizes);
    }
    reduce_hierarchies(src, out, &sizes, HIERARCHIES);
}

/// Levels 1.. of the four hierarchies of `src`, whose level sizes are
/// `sizes` (levels already shaped), and `src` copied into level 0 of the
/// hierarchies `copy_from..`.
fn reduce_hierarchies(src: &FloatImage, out: &mut CpfPyramids, sizes: &[(usize, usize)], copy_from: usize) {
    let [h0, h1, h2, h3] = &mut out.hierarchies;
    let ([l0, r0 @ ..], [l1, r1 @ ..], [l2, r2 @ ..], [l3, r3 @ ..]) =
        (&mut h0[..], &mut h1[..], &mut h2[..], &mut h3[..])
    else {
        return;
    };
    let mut level0 = [l0, l1, l2, l3];
    let copies = &mut level0[copy_from..];
    let ([n0, ..], [n1, ..], [n2, ..], [n3, ..]) = (r0, r1, r2, r3) else {
        for c in copies.iter_mut() {
            c.data_mut().copy_from_slice(src.data());
        }
        return;
    };
    cpf_first_level(src, [n0, n1, n2, n3], copies);
    for (m, levels) in out.hierarchies.iter_mut().enumerate() {
        for k in 2..sizes.len() {
            let (coarser, finer) = levels.split_at_mut(k);
            cpf_next_level(m, &coarser[k - 1], &mut finer[0]);
        }
    }
}

/// CPU twin, allocating: the four CPF hierarchies of `src`.
#[must_use]
pub fn cpf(src: &FloatImage) -> CpfPyramids {
    let mut out = CpfPyramids::default();
    cpf_cpu(src, &mut out);
    out
}

/// The four CPF images of `src` at level `levels_down` only (`0` = `src`
/// itself), without keeping the finer levels: what the window-energy stage
/// needs (004 §III: "the full hierarchy does not need to be computed").
/// Errors when `src` has fewer than `levels_down + 1` levels.
pub fn cpf_to_level(src: &FloatImage, levels_down: usize) -> Result<[FloatImage; HIERARCHIES]> {
    let sizes = level_sizes(src.width(), src.height());
    let Some(&(w1, h1)) = sizes.get(levels_down) else {
        return Err(Error::Parameter(format!(
            "CPF level {levels_down} of a {}x{} image: it has levels 0..={}",
            src.width(),
            src.height(),
            sizes.len() - 1
        )));
    };
    if levels_down == 0 {
        return Ok(std::array::from_fn(|_| src.clone()));
    }
    let (w, h) = sizes[1];
    let mut cur: [FloatImage; HIERARCHIES] = std::array::from_fn(|_| FloatImage::new(w, h));
    let [c0, c1, c2, c3] = &mut cur;
    cpf_first_level(src, [c0, c1, c2, c3], &mut []);
    let mut next: [FloatImage; HIERARCHIES] = std::array::from_fn(|_| FloatImage::new(0, 0));
    for &(w, h) in &sizes[2..=levels_down] {
        for (m, (c, n)) in cur.iter().zip(next.iter_mut()).enumerate() {
            n.resize(w, h);
            cpf_next_level(m, c, n);
        }
        std::mem::swap(&mut cur, &mut next);
    }
    debug_assert_eq!(cur[0].size(), (w1, h1));
    Ok(cur)
}

// ---------------------------------------------------------------- GPU

/// Most levels one dispatch of `cpf.wgsl` or `edge_pyramid.wgsl` builds:
/// a 16×16 tile of the first, halved in workgroup memory down to 1×1
/// (`LEVELS` in `pyramid_tile.wgsl`).
pub(super) const LEVELS_PER_DISPATCH: usize = 5;

/// Uniform block of `cpf.wgsl` and `edge_pyramid.wgsl`; kept in sync with
/// `Params` in `pyramid_tile.wgsl`. Size and offset (in f32 elements) of the level read, and
/// of each level the dispatch builds, in the concatenated buffers.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(super) struct LevelsUniform {
    src_width: u32,
    src_height: u32,
    src_offset: u32,
    levels: u32,
    /// (width, height, offset, unused) of each level built.
    dst: [[u32; 4]; LEVELS_PER_DISPATCH],
}

/// Level sizes and offsets of a pyramid stored as one concatenated buffer.
#[derive(Clone, Debug)]
pub(super) struct LevelLayout {
    /// Size of each level, finest first.
    pub(super) sizes: Vec<(usize, usize)>,
    /// `offsets[k]`: first element of level k; `offsets[levels]` = total.
    /// A level holds the images of all layers, layer after layer.
    pub(super) offsets: Vec<usize>,
    /// Pyramids stacked level by level.
    pub(super) layers: usize,
}

impl LevelLayout {
    /// The layout of the levels of `layers` (at least 1) `width`×`height` inputs.
    pub(super) fn new(width: usize, height: usize, layers: usize) -> Self {
        let layers = layers.max(1);
        let sizes = level_sizes(width, height);
        let mut offsets = Vec::with_capacity(sizes.len() + 1);
        let mut total = 0;
        offsets.push(0);
        for &(w, h) in &sizes {
            total += w * h * layers;
            offsets.push(total);
        }
        Self { sizes, offsets, layers }
    }

    /// Values in all levels together.
    pub(super) fn total(&self) -> usize {
        self.offsets[self.sizes.len()]
    }

    /// The dispatches that build levels 1.. of the pyramid: for each, the
    /// uniform and its grid (the first level it builds, every layer).
    /// Each builds up to [`LEVELS_PER_DISPATCH`] levels from the last level
    /// the one before it built.
    pub(super) fn dispatches(&self) -> Result<Vec<(LevelsUniform, [u32; 3])>> {
        let too_big = || Error::Size(format!("pyramid of {} values exceeds u32 indexing", self.total()));
        let to_u32 = |v: usize| u32::try_from(v).map_err(|_| too_big());
        u32::try_from(self.total()).map_err(|_| too_big())?;
        let mut out = Vec::new();
        let mut src = 0;
        while src + 1 < self.sizes.len() {
            let built = (self.sizes.len() - 1 - src).min(LEVELS_PER_DISPATCH);
            let (sw, sh) = self.sizes[src];
            let mut u = LevelsUniform {
                src_width: to_u32(sw)?,
                src_height: to_u32(sh)?,
                src_offset: to_u32(self.offsets[src])?,
                levels: to_u32(built)?,
                dst: [[0; 4]; LEVELS_PER_DISPATCH],
            };
            for (slot, k) in u.dst.iter_mut().zip(src + 1..=src + built) {
                let (w, h) = self.sizes[k];
                *slot = [to_u32(w)?, to_u32(h)?, to_u32(self.offsets[k])?, 0];
            }
            let (w, h) = self.sizes[src + 1];
            let [x, y, _] = workgroups_2d(w, h);
            out.push((u, [x, y, to_u32(self.layers)?]));
            src += built;
        }
        Ok(out)
    }

    /// Split a downloaded concatenated buffer (a 1-row image) into the
    /// levels of `layer`.
    pub(super) fn split(&self, flat: &FloatImage, layer: usize) -> Result<Vec<FloatImage>> {
        let data = flat.data();
        self.sizes
            .iter()
            .enumerate()
            .map(|(k, &(w, h))| {
                let at = self.offsets[k] + layer * w * h;
                let level = data.get(at..at + w * h).ok_or_else(|| Error::Gpu("pyramid buffer too short".into()))?;
                FloatImage::from_vec(w, h, level.to_vec())
            })
            .collect()
    }

    /// Error unless `image` has the size and layers of level 0.
    pub(super) fn check_input(&self, image: &GpuImage, what: &str) -> Result<()> {
        let (w, h) = self.sizes[0];
        if (image.width(), image.height(), image.layers()) != (w, h, self.layers) {
            return Err(Error::Size(format!(
                "{what}: {}x{} image of {} layers for a {w}x{h} pyramid of {}",
                image.width(),
                image.height(),
                image.layers(),
                self.layers
            )));
        }
        Ok(())
    }

    /// Bytes of level 0.
    pub(super) fn base_bytes(&self) -> u64 {
        self.offsets[1] as u64 * 4
    }
}

/// GPU buffers of the four CPF hierarchies of a `width`×`height` image:
/// one storage buffer per hierarchy, all its levels concatenated.
#[derive(Debug)]
pub struct CpfGpu {
    layout: LevelLayout,
    hierarchies: [GpuImage; HIERARCHIES],
}

impl CpfGpu {
    /// Allocate the buffers for a `width`×`height` input; reuse them across frames.
    #[must_use]
    pub fn new(ctx: &GpuContext, width: usize, height: usize) -> Self {
        Self::layered(ctx, width, height, 1)
    }

    /// The buffers for a stack of `layers` inputs ([`GpuImage::layered`]),
    /// stacked level by level.
    #[must_use]
    pub fn layered(ctx: &GpuContext, width: usize, height: usize, layers: usize) -> Self {
        let layout = LevelLayout::new(width, height, layers);
        let total = layout.total();
        let hierarchies = std::array::from_fn(|m| GpuImage::new(ctx, total, 1, &format!("cpf.m{m}")));
        Self { layout, hierarchies }
    }

    /// Sizes of the levels, finest first (see [`level_sizes`]).
    #[must_use]
    pub fn level_sizes(&self) -> &[(usize, usize)] {
        &self.layout.sizes
    }

    /// Offset (in f32 elements) of each level in a hierarchy's buffer, plus
    /// the total length as the last entry.
    #[must_use]
    pub fn level_offsets(&self) -> &[usize] {
        &self.layout.offsets
    }

    /// The buffer of hierarchy `m` (0..=3), as a 1-row image of all levels.
    #[must_use]
    pub fn hierarchy(&self, m: usize) -> Option<&GpuImage> {
        self.hierarchies.get(m)
    }

    /// Read all levels of the four hierarchies back (tests and benches).
    pub fn download(&self, ctx: &GpuContext) -> Result<CpfPyramids> {
        self.download_layers(ctx)?.into_iter().next().ok_or_else(|| Error::Gpu("no pyramid layer".into()))
    }

    /// Read all levels of the four hierarchies of every layer back.
    pub fn download_layers(&self, ctx: &GpuContext) -> Result<Vec<CpfPyramids>> {
        let mut out = vec![CpfPyramids::default(); self.layout.layers];
        for (m, buffer) in self.hierarchies.iter().enumerate() {
            let flat = buffer.download(ctx)?;
            for (layer, pyramids) in out.iter_mut().enumerate() {
                pyramids.hierarchies[m] = self.layout.split(&flat, layer)?;
            }
        }
        Ok(out)
    }
}

/// Record the CPF hierarchies of `src` into `out`: four buffer copies put
/// the input at level 0 of each hierarchy, then each dispatch builds up to
/// [`LEVELS_PER_DISPATCH`] coarser levels of all four hierarchies (level 1
/// reads the copies of the input, deeper levels their own hierarchy's
/// previous level): `⌈(levels − 1) / 5⌉` dispatches (2 for the 10 coarser
/// levels of 640×480).
pub(crate) fn encode(rec: &mut Recorder<'_>, src: &GpuImage, out: &CpfGpu) -> Result<()> {
    let layout = &out.layout;
    layout.check_input(src, "CPF input")?;
    for h in &out.hierarchies {
        rec.copy(&src.buffer, 0, &h.buffer, 0, layout.base_bytes());
    }
    let [h0, h1, h2, h3] = &out.hierarchies;
    for (u, grid) in layout.dispatches()? {
        rec.dispatch(&SHADER, "cpf_levels", &u, &[&h0.buffer, &h1.buffer, &h2.buffer, &h3.buffer], grid)?;
    }
    Ok(())
}

/// GPU: the CPF hierarchies of a CPU image, read back (tests and benches).
pub fn cpf_gpu(ctx: &GpuContext, src: &FloatImage) -> Result<CpfPyramids> {
    let input = GpuImage::from_image(ctx, src, "cpf.src");
    let out = CpfGpu::new(ctx, src.width(), src.height());
    run_once(ctx, |rec| encode(rec, &input, &out))?;
    out.download(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, values: &[f32]) -> FloatImage {
        FloatImage::from_vec(w, h, values.to_vec()).unwrap()
    }

    /// Level `k` of the four hierarchies, as `[m][pixel]` vectors.
    fn level(p: &CpfPyramids, k: usize) -> Vec<Vec<f32>> {
        p.hierarchies.iter().map(|levels| levels[k].data().to_vec()).collect()
    }

    /// The dispatches build every coarser level exactly once, in order, at
    /// most five each, each reading the last level the one before built,
    /// with its grid over its first level and every layer; a level holds
    /// every layer's image.
    #[test]
    fn dispatches_build_each_level_once_five_at_most() {
        let sizes = [(1, 1, 0), (2, 1, 1), (640, 480, 2), (33, 65, 2), (1500, 7, 3), (2049, 1, 3)];
        for ((w, h, count), layers) in sizes.into_iter().flat_map(|s| [(s, 1), (s, 3)]) {
            let layout = LevelLayout::new(w, h, layers);
            for (k, &(lw, lh)) in layout.sizes.iter().enumerate() {
                assert_eq!(layout.offsets[k + 1] - layout.offsets[k], lw * lh * layers, "{w}x{h}x{layers}");
            }
            let dispatches = layout.dispatches().unwrap();
            assert_eq!(dispatches.len(), count, "{w}x{h}");
            let mut next = 1;
            for (u, grid) in &dispatches {
                let src = next - 1;
                let built = u.levels as usize;
                assert!((1..=LEVELS_PER_DISPATCH).contains(&built), "{w}x{h}: {built} levels");
                let (sw, sh) = layout.sizes[src];
                assert_eq!(
                    (u.src_width, u.src_height, u.src_offset),
                    (sw as u32, sh as u32, layout.offsets[src] as u32)
                );
                let (gw, gh) = layout.sizes[next];
                assert_eq!(*grid, [gw.div_ceil(16) as u32, gh.div_ceil(16) as u32, layers as u32], "{w}x{h}");
                for (j, dst) in u.dst.iter().enumerate() {
                    if j < built {
                        let (dw, dh) = layout.sizes[next + j];
                        assert_eq!(*dst, [dw as u32, dh as u32, layout.offsets[next + j] as u32, 0], "{w}x{h}");
                    } else {
                        assert_eq!(*dst, [0; 4], "{w}x{h}");
                    }
                }
                next += built;
            }
            assert_eq!(next, layout.sizes.len(), "{w}x{h}: every level built");
        }
    }

    #[test]
    fn level_sizes_halve_with_ceil_down_to_one_pixel() {
        assert_eq!(level_sizes(1, 1), vec![(1, 1)]);
        assert_eq!(level_sizes(4, 4), vec![(4, 4), (2, 2), (1, 1)]);
        assert_eq!(level_sizes(7, 1), vec![(7, 1), (4, 1), (2, 1), (1, 1)]);
        assert_eq!(level_sizes(3, 5), vec![(3, 5), (2, 3), (1, 2), (1, 1)]);
        assert_eq!(level_sizes(256, 256).len(), 9); // paper: d = 8, l = 8..=0
        assert_eq!(level_sizes(640, 480).len(), 11);
        assert_eq!(level_sizes(0, 5), vec![(0, 5)]);
    }

    /// 2×2 blocks chosen so that reading `i` as the row instead of the column
    /// would change the saddle hierarchies (m = 1, 2) of three of them.
    #[test]
    fn four_by_four_by_hand() {
        #[rustfmt::skip]
        let src = image(4, 4, &[
            1.0,  2.0,  8.0,  6.0,
            3.0,  4.0,  7.0,  5.0,
            9.0, 12.0, 13.0, 14.0,
           10.0, 11.0, 15.0, 16.0,
        ]);
        let p = cpf(&src);
        assert!(p.hierarchies.iter().all(|l| l.len() == 3 && l[0] == src));
        // Block (0,0) = [1 2; 3 4]: columns {1,3}, {2,4}: min 1, max(1,2) = 2, min(3,4) = 3, max 4.
        // Block (1,0) = [8 6; 7 5]: columns {8,7}, {6,5}: min 5, max(7,5) = 7, min(8,6) = 6, max 8.
        // Block (0,1) = [9 12; 10 11]: columns {9,10}, {12,11}: 9, max(9,11) = 11, min(10,12) = 10, 12.
        // Block (1,1) = [13 14; 15 16]: columns {13,15}, {14,16}: 13, max(13,14) = 14, min(15,16) = 15, 16.
        assert_eq!(
            level(&p, 1),
            vec![
                vec![1.0, 5.0, 9.0, 13.0],
                vec![2.0, 7.0, 11.0, 14.0],
                vec![3.0, 6.0, 10.0, 15.0],
                vec![4.0, 8.0, 12.0, 16.0],
            ]
        );
        // Level 2 from each hierarchy's own level 1:
        // m0: min(1, 5, 9, 13) = 1;  m1 on [2 7; 11 14]: max(min(2,11), min(7,14)) = 7;
        // m2 on [3 6; 10 15]: min(max(3,10), max(6,15)) = 10;  m3: max(4, 8, 12, 16) = 16.
        assert_eq!(level(&p, 2), vec![vec![1.0], vec![7.0], vec![10.0], vec![16.0]]);
    }

    /// Odd sizes: the missing child column/row is clamped to the edge one.
    #[test]
    fn three_by_three_clamps_the_missing_children() {
        #[rustfmt::skip]
        let src = image(3, 3, &[
            1.0, 2.0, 3.0,
            4.0, 5.0, 6.0,
            7.0, 8.0, 9.0,
        ]);
        let p = cpf(&src);
        // (0,0) from [1 2; 4 5]: 1, max(1,2) = 2, min(4,5) = 4, 5.
        // (1,0) from the single column {3, 6}: 3, m1 = min = 3, m2 = max = 6, 6.
        // (0,1) from the single row [7 8]: 7, m1 = max = 8, m2 = min = 7, 8.
        // (1,1) from the single pixel 9.
        assert_eq!(
            level(&p, 1),
            vec![
                vec![1.0, 3.0, 7.0, 9.0],
                vec![2.0, 3.0, 8.0, 9.0],
                vec![4.0, 6.0, 7.0, 9.0],
                vec![5.0, 6.0, 8.0, 9.0],
            ]
        );
        // m1 on [2 3; 8 9]: max(min(2,8), min(3,9)) = 3;  m2 on [4 6; 7 9]: min(max(4,7), max(6,9)) = 7.
        assert_eq!(level(&p, 2), vec![vec![1.0], vec![3.0], vec![7.0], vec![9.0]]);
    }

    #[test]
    fn one_pixel_has_one_level() {
        let src = image(1, 1, &[42.0]);
        let p = cpf(&src);
        assert!(p.hierarchies.iter().all(|l| l.len() == 1 && l[0] == src));
        assert_eq!(cpf_to_level(&src, 0).unwrap()[3], src);
        assert!(cpf_to_level(&src, 1).is_err());
    }

    /// Direct evaluation of eq. 1–4 with `get_clamped`, one pixel at a time.
    fn reference_level(src: &FloatImage, m: usize) -> FloatImage {
        let (w, h) = (src.width().div_ceil(2), src.height().div_ceil(2));
        FloatImage::from_fn(w, h, |i, j| {
            let p = |a: usize, b: usize| src.get_clamped((2 * i + a) as isize, (2 * j + b) as isize);
            type Op = fn(f32, f32) -> f32;
            let (inner, outer): (Op, Op) = match m {
                0 => (f32::min, f32::min),
                1 => (f32::min, f32::max),
                2 => (f32::max, f32::min),
                _ => (f32::max, f32::max),
            };
            outer(inner(p(0, 0), p(0, 1)), inner(p(1, 0), p(1, 1)))
        })
    }

    /// The fast (row-wise, parallel above PARALLEL_PIXELS) twin against the
    /// per-pixel definition, on an odd size large enough to run in parallel.
    #[test]
    fn fast_twin_matches_per_pixel_definition() {
        let src = crate::testimage::natural(301, 257, 5).to_f32();
        const { assert!(301 * 257 >= crate::early::rows::PARALLEL_PIXELS) };
        let p = cpf(&src);
        for (m, levels) in p.hierarchies.iter().enumerate() {
            for k in 1..levels.len() {
                assert_eq!(levels[k], reference_level(&levels[k - 1], m), "m {m} level {k}");
            }
        }
        for k in 0..p.hierarchies[0].len() {
            let direct = cpf_to_level(&src, k).unwrap();
            for (m, image) in direct.iter().enumerate() {
                assert_eq!(image, &p.hierarchies[m][k], "cpf_to_level m {m} level {k}");
            }
        }
    }

    #[test]
    fn cpu_twin_reuses_outputs_across_sizes() {
        let mut out = CpfPyramids::default();
        cpf_cpu(&crate::testimage::natural(9, 5, 1).to_f32(), &mut out);
        let small = image(2, 2, &[4.0, 3.0, 2.0, 1.0]);
        cpf_cpu(&small, &mut out);
        assert_eq!(out, cpf(&small));
        assert_eq!(level(&out, 1), vec![vec![1.0], vec![2.0], vec![3.0], vec![4.0]]);
    }
}
