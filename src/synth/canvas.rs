//! The renderer core: a super-sampled canvas with an exact-coverage polygon
//! rasteriser.
//!
//! Scenes draw into a [`Canvas`]: a grey image held at `S`× the output
//! resolution (`S` = [`DEFAULT_SUPERSAMPLE`] = 4 unless asked otherwise).
//! [`Canvas::downsample_into`] averages each `S`×`S` block of cells (a box
//! filter) into one output pixel.
//!
//! Coordinates are output-pixel coordinates in the convention of SPEC §4: pixel
//! `(0, 0)` is the *centre* of the top-left pixel, so pixel `(x, y)` covers
//! `[x − ½, x + ½] × [y − ½, y + ½]`. Super-sample (cell) `(i, j)` — column `i`,
//! row `j` of the `S·W × S·H` grid — covers the square of side `1/S` centred at
//! `((i + 0.5)/S − 0.5, (j + 0.5)/S − 0.5)`; [`Canvas::sample_centre`] says so
//! in code, and cell coordinates are `u = (x + ½)·S`.
//!
//! Polygons are filled with *exact area coverage*: an accumulation-buffer
//! rasteriser (the signed-area method of font renderers) gives every cell the
//! fraction of its area inside the polygon, and the cell is blended with the
//! polygon's grey by that fraction. After the box filter an output pixel
//! therefore holds the exact area-weighted mix at any edge position, not only
//! at multiples of `1/S`, and ground-truth corners are exact. Super-sampling
//! still matters where several things meet inside one pixel (an edge over a
//! texture, two polygons, a corner): blending per cell confines the error of
//! compositing by coverage to cells `1/S` of a pixel wide. Faces that share
//! edges (a polyhedron's visible faces) should be drawn as one layer with
//! [`Canvas::fill_faces`], which adds their coverages before blending, so no
//! background shows through a shared edge; overlapping polygons are drawn back
//! to front (painter's algorithm). Both [`FillRule`]s are offered; scenes use
//! [`FillRule::EvenOdd`] unless they say otherwise.
//!
//! A sequence is made by rendering its static background once
//! ([`super::render_background`]) and box-filtering it down once; then for every frame
//! only the window the moving things touch ([`Canvas::window_around`]) is
//! restored from the background, drawn, and box-filtered into a copy of the
//! downsampled background, before Gaussian noise is added and values are
//! rounded to `u8` ([`super::add_noise_and_quantise`]). Frames are independent (the noise of frame `k`
//! comes from its own ChaCha stream), so they render in parallel and the same
//! seed always gives the same bytes.

use std::ops::Range;

use rayon::prelude::*;

use crate::early::Window;
use crate::image::FloatImage;
use crate::{Error, Result};

/// Super-sampling factor used by the scenes unless told otherwise.
pub const DEFAULT_SUPERSAMPLE: usize = 4;
/// Largest super-sampling factor a [`Canvas`] accepts.
pub const MAX_SUPERSAMPLE: usize = 16;

/// How [`Canvas::fill_polygon`] decides which samples a self-intersecting or
/// multiply-wound outline covers. Convex and simple polygons look the same
/// under both.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FillRule {
    /// Inside where a ray crosses the outline an odd number of times.
    #[default]
    EvenOdd,
    /// Inside where the winding number is not zero.
    NonZero,
}

/// A grey canvas at `S`× the output resolution (see the module docs for the
/// sample positions). Values are grey levels in the 0..255 scale, as `f32`.
#[derive(Clone, Debug)]
pub struct Canvas {
    width: usize,
    height: usize,
    supersample: usize,
    samples: Vec<f32>,
    /// Reused buffers of polygon filling.
    scratch: FillScratch,
}

/// Buffers [`Canvas::fill_faces`] reuses from call to call. All four are
/// zero between calls: each cell is cleared where it is read, so no call
/// clears a whole buffer.
#[derive(Clone, Debug, Default)]
struct FillScratch {
    /// Signed-area accumulator of one face.
    accumulator: Vec<f64>,
    /// One bit per accumulator cell an edge added to, row by row.
    touched: Vec<u64>,
    /// Summed coverage of the layer's faces per cell.
    alpha: Vec<f32>,
    /// Summed coverage × grey per cell.
    premultiplied: Vec<f32>,
}

impl Canvas {
    /// A canvas for a `width`×`height` output image at `supersample`× resolution,
    /// filled with `grey`. Errors when a size is zero or `supersample` is not in
    /// `1..=MAX_SUPERSAMPLE`.
    pub fn new(width: usize, height: usize, supersample: usize, grey: f32) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::Parameter(format!("canvas size {width}x{height} is empty")));
        }
        if !(1..=MAX_SUPERSAMPLE).contains(&supersample) {
            return Err(Error::Parameter(format!("supersample factor {supersample} is not in 1..={MAX_SUPERSAMPLE}")));
        }
        let n = width * supersample * height * supersample;
        Ok(Self { width, height, supersample, samples: vec![grey; n], scratch: FillScratch::default() })
    }

    /// Output width in pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Output height in pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// The super-sampling factor `S`.
    #[must_use]
    pub fn supersample(&self) -> usize {
        self.supersample
    }

    /// The super-samples, row-major, `S·W` per row.
    #[must_use]
    pub fn samples(&self) -> &[f32] {
        &self.samples
    }

    /// The super-samples, row-major, for writing.
    pub(crate) fn samples_mut(&mut self) -> &mut [f32] {
        &mut self.samples
    }

    /// Where super-sample `(i, j)` sits in output-pixel coordinates:
    /// `((i + 0.5)/S − 0.5, (j + 0.5)/S − 0.5)`.
    #[must_use]
    pub fn sample_centre(&self, i: usize, j: usize) -> [f64; 2] {
        let s = self.supersample as f64;
        [(i as f64 + 0.5) / s - 0.5, (j as f64 + 0.5) / s - 0.5]
    }

    /// Set every sample to `grey`.
    pub fn fill(&mut self, grey: f32) {
        self.samples.fill(grey);
    }

    /// Set every sample to `shade(x, y)`, evaluated at the sample's position in
    /// output-pixel coordinates (so a smooth texture is area-averaged by
    /// [`Canvas::downsample_into`]). Rows are shaded in parallel.
    pub fn shade_with(&mut self, shade: impl Fn(f64, f64) -> f32 + Sync) {
        let sw = self.width * self.supersample;
        let s = self.supersample as f64;
        self.samples.par_chunks_mut(sw).enumerate().for_each(|(j, row)| {
            let y = (j as f64 + 0.5) / s - 0.5;
            for (i, v) in row.iter_mut().enumerate() {
                *v = shade((i as f64 + 0.5) / s - 0.5, y);
            }
        });
    }

    /// Copy another canvas of the same size and factor into this one (the
    /// per-frame "start from the background" step; no allocation).
    pub fn copy_from(&mut self, other: &Canvas) -> Result<()> {
        self.check_same_shape(other)?;
        self.samples.copy_from_slice(&other.samples);
        Ok(())
    }

    fn check_same_shape(&self, other: &Canvas) -> Result<()> {
        if (self.width, self.height, self.supersample) != (other.width, other.height, other.supersample) {
            return Err(Error::Size(format!(
                "canvas {}x{}@{} vs {}x{}@{}",
                self.width, self.height, self.supersample, other.width, other.height, other.supersample
            )));
        }
        Ok(())
    }

    /// Fill the polygon with vertices `points` (output-pixel coordinates, in
    /// order, implicitly closed) with `grey`, deciding inside by `rule`: every
    /// cell is blended with `grey` by the exact fraction of its area the
    /// polygon covers. Convex, non-convex and self-intersecting outlines all
    /// work; parts outside the canvas are clipped. A polygon with fewer than
    /// three points or a non-finite coordinate draws nothing.
    pub fn fill_polygon(&mut self, points: &[[f64; 2]], rule: FillRule, grey: f32) {
        self.fill_faces(&[Face { points, grey }], rule);
    }

    /// Fill several polygons that do not overlap one another (e.g. the visible
    /// faces of a convex polyhedron) as one layer: their coverages add up
    /// before blending, so along an edge two faces share the background does
    /// not show through. Polygons that do overlap should be drawn back to front
    /// with separate calls instead. Faces with fewer than three points or a
    /// non-finite coordinate are skipped.
    pub fn fill_faces(&mut self, faces: &[Face<'_>], rule: FillRule) {
        let sw = self.width * self.supersample;
        let supersample = self.supersample;
        let to_cell = |p: &[f64; 2]| to_cell(p, supersample);
        let boxes = self.cell_boxes(faces);
        let Some(layer) = boxes.iter().flatten().copied().reduce(CellBox::union) else {
            return;
        };
        // One face is blended straight into the samples, run by run; several
        // add their coverages in the layer's buffers first.
        let alone = boxes.iter().flatten().count() == 1;
        let (lw, lh) = (layer.x1 - layer.x0, layer.y1 - layer.y0);
        let mut scratch = std::mem::take(&mut self.scratch);
        if !alone {
            grow_zeroed(&mut scratch.alpha, lw * lh);
            grow_zeroed(&mut scratch.premultiplied, lw * lh);
        }
        for (face, cells) in faces.iter().zip(&boxes) {
            let Some(cells) = cells else { continue };
            let (fw, fh) = (cells.x1 - cells.x0, cells.y1 - cells.y0);
            // Two spare columns: an edge on the right border writes one past it.
            let stride = fw + 2;
            let words = stride.div_ceil(64);
            grow_zeroed(&mut scratch.accumulator, stride * fh);
            grow_zeroed(&mut scratch.touched, words * fh);
            let mut acc = Accumulator {
                cells: &mut scratch.accumulator[..stride * fh],
                touched: &mut scratch.touched[..words * fh],
                stride,
                words,
            };
            let origin = [cells.x0 as f64, cells.y0 as f64];
            let n = face.points.len();
            for k in 0..n {
                let a = to_cell(&face.points[k]);
                let b = to_cell(&face.points[(k + 1) % n]);
                acc.add_edge(
                    [fw as f64, fh as f64],
                    [a[0] - origin[0], a[1] - origin[1]],
                    [b[0] - origin[0], b[1] - origin[1]],
                );
            }
            // Running sums along each row turn edge contributions into the
            // covered area of every cell (its mean winding number).
            for r in 0..fh {
                let (acc_row, touched_row) = acc.row(r);
                if alone {
                    let at = (cells.y0 + r) * sw + cells.x0;
                    let row = &mut self.samples[at..at + fw];
                    sweep_row(acc_row, touched_row, fw, rule, |run, coverage| {
                        blend_run(&mut row[run], coverage, face.grey);
                    });
                } else {
                    let at = (cells.y0 - layer.y0 + r) * lw + (cells.x0 - layer.x0);
                    let alpha = &mut scratch.alpha[at..at + fw];
                    let premultiplied = &mut scratch.premultiplied[at..at + fw];
                    sweep_row(acc_row, touched_row, fw, rule, |run, coverage| {
                        for (a, p) in alpha[run.clone()].iter_mut().zip(&mut premultiplied[run]) {
                            *a += coverage;
                            *p += coverage * face.grey;
                        }
                    });
                }
            }
        }
        if !alone {
            for r in 0..lh {
                let at = (layer.y0 + r) * sw + layer.x0;
                let cells = r * lw..(r + 1) * lw;
                blend_layer_row(
                    &mut self.samples[at..at + lw],
                    &mut scratch.alpha[cells.clone()],
                    &mut scratch.premultiplied[cells],
                );
            }
        }
        self.scratch = scratch;
    }

    /// The cells each of `faces` can touch, clipped to the canvas; `None`
    /// for a face with fewer than three points, a non-finite coordinate or
    /// nothing on the canvas.
    fn cell_boxes(&self, faces: &[Face<'_>]) -> Vec<Option<CellBox>> {
        let (sw, sh) = (self.width * self.supersample, self.height * self.supersample);
        let drawable = |f: &Face<'_>| f.points.len() >= 3 && f.points.iter().flatten().all(|c| c.is_finite());
        faces
            .iter()
            .map(|f| {
                drawable(f)
                    .then(|| CellBox::of(f.points.iter().map(|p| to_cell(p, self.supersample)), sw, sh))
                    .flatten()
            })
            .collect()
    }

    /// Fill an ellipse with centre `centre`, semi-axes `radii` and the first
    /// axis turned by `angle` radians (from +x towards +y), as a polygon of
    /// [`ELLIPSE_SEGMENTS`] sides.
    pub fn fill_ellipse(&mut self, centre: [f64; 2], radii: [f64; 2], angle: f64, grey: f32) {
        let points = ellipse_points(centre, radii, angle, ELLIPSE_SEGMENTS);
        self.fill_polygon(&points, FillRule::EvenOdd, grey);
    }

    /// Draw the segment `a`–`b` as a filled rectangle `width` pixels wide
    /// (square caps flush with the end points). A zero-length segment draws nothing.
    pub fn fill_segment(&mut self, a: [f64; 2], b: [f64; 2], width: f64, grey: f32) {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        if len == 0.0 || !len.is_finite() {
            return;
        }
        let (nx, ny) = (-dy / len * width / 2.0, dx / len * width / 2.0);
        let quad = [[a[0] + nx, a[1] + ny], [b[0] + nx, b[1] + ny], [b[0] - nx, b[1] - ny], [a[0] - nx, a[1] - ny]];
        self.fill_polygon(&quad, FillRule::EvenOdd, grey);
    }

    /// Box-filter down to the output resolution: every output pixel is the mean
    /// of its `S`×`S` block. `out` is resized to `width`×`height` if needed.
    pub fn downsample_into(&self, out: &mut FloatImage) {
        if out.size() != (self.width, self.height) {
            out.resize(self.width, self.height);
        }
        self.downsample_rows(out, Window::full(self.width, self.height));
    }

    /// Box-filter only the pixels of `window` (clipped to the canvas) into
    /// `out`, which must be `width`×`height`; other pixels are left as they
    /// are. With [`Canvas::copy_window_from`] this lets a scene redo only the
    /// part of a frame that moving things touch ([`Canvas::window_around`]).
    pub fn downsample_window_into(&self, out: &mut FloatImage, window: Window) -> Result<()> {
        if out.size() != (self.width, self.height) {
            return Err(Error::Size(format!(
                "downsample into {}x{} from a {}x{} canvas",
                out.width(),
                out.height(),
                self.width,
                self.height
            )));
        }
        self.downsample_rows(out, window.clipped(self.width, self.height));
        Ok(())
    }

    fn downsample_rows(&self, out: &mut FloatImage, window: Window) {
        if window.is_empty() {
            return;
        }
        let (w, s) = (self.width, self.supersample);
        let (x0, x1) = (window.x0 as usize, window.x1 as usize);
        let (y0, y1) = (window.y0 as usize, window.y1 as usize);
        let norm = 1.0 / (s * s) as f32;
        let block_rows = w * s * s;
        let samples = &self.samples[y0 * block_rows..y1 * block_rows];
        out.data_mut()[y0 * w..y1 * w].par_chunks_mut(w).zip(samples.par_chunks(block_rows)).for_each(
            |(out_row, block)| {
                let out_row = &mut out_row[x0..x1];
                out_row.fill(0.0);
                for sample_row in block.chunks_exact(w * s) {
                    add_cell_sums(out_row, &sample_row[x0 * s..x1 * s], s);
                }
                for o in out_row.iter_mut() {
                    *o *= norm;
                }
            },
        );
    }

    /// Copy the cells under output-pixel window `window` (clipped) from a
    /// canvas of the same size and factor.
    pub fn copy_window_from(&mut self, other: &Canvas, window: Window) -> Result<()> {
        self.check_same_shape(other)?;
        let window = window.clipped(self.width, self.height);
        if window.is_empty() {
            return Ok(());
        }
        let (s, sw) = (self.supersample, self.width * self.supersample);
        let (i0, i1) = (window.x0 as usize * s, window.x1 as usize * s);
        for j in window.y0 as usize * s..window.y1 as usize * s {
            let span = j * sw + i0..j * sw + i1;
            self.samples[span.clone()].copy_from_slice(&other.samples[span]);
        }
        Ok(())
    }

    /// The output pixels that polygons with vertices `points` can change: their
    /// bounding box grown to whole pixels plus a one-pixel margin, clipped to
    /// the canvas ([`Window::around`] with a half-pixel margin). Non-finite
    /// points are ignored.
    #[must_use]
    pub fn window_around<'a>(&self, points: impl IntoIterator<Item = &'a [f64; 2]>) -> Window {
        let finite = points.into_iter().filter(|p| p[0].is_finite() && p[1].is_finite());
        Window::around(finite, 0.5, self.width, self.height).unwrap_or_default()
    }

    /// Box-filter down to a new image (see [`Canvas::downsample_into`]).
    #[must_use]
    pub fn downsample(&self) -> FloatImage {
        let mut out = FloatImage::new(self.width, self.height);
        self.downsample_into(&mut out);
        out
    }
}

/// Sides of the polygon [`Canvas::fill_ellipse`] draws.
pub const ELLIPSE_SEGMENTS: usize = 48;

/// The `n` vertices of an ellipse (centre, semi-axes, rotation in radians).
#[must_use]
pub fn ellipse_points(centre: [f64; 2], radii: [f64; 2], angle: f64, n: usize) -> Vec<[f64; 2]> {
    let (sa, ca) = angle.sin_cos();
    (0..n)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / n as f64;
            let (u, v) = (radii[0] * t.cos(), radii[1] * t.sin());
            [centre[0] + ca * u - sa * v, centre[1] + sa * u + ca * v]
        })
        .collect()
}

/// A polygon and its grey level, for [`Canvas::fill_faces`].
#[derive(Clone, Copy, Debug)]
pub struct Face<'a> {
    /// Vertices in output-pixel coordinates, in order, implicitly closed.
    pub points: &'a [[f64; 2]],
    /// Grey level to fill with.
    pub grey: f32,
}

impl FillRule {
    /// Coverage of a cell from its mean winding number `w` (exact wherever
    /// the winding number inside the cell takes only the values 0 and ±1, as
    /// everywhere for a simple polygon; for overlapping outlines the rule is
    /// applied to the mean, as font rasterisers do).
    fn coverage(self, w: f64) -> f64 {
        let w = w.abs();
        match self {
            FillRule::NonZero => w.min(1.0),
            FillRule::EvenOdd => {
                let m = w % 2.0;
                if m <= 1.0 { m } else { 2.0 - m }
            }
        }
    }
}

/// Cell coordinates of output-pixel point `p` at factor `supersample`:
/// cell (i, j) spans [i, i+1] × [j, j+1], i.e. u = (x + 1/2)·S.
fn to_cell(p: &[f64; 2], supersample: usize) -> [f64; 2] {
    let s = supersample as f64;
    [(p[0] + 0.5) * s, (p[1] + 0.5) * s]
}

/// A half-open range of canvas cells `x0..x1`, `y0..y1`, non-empty.
#[derive(Clone, Copy, Debug)]
struct CellBox {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

impl CellBox {
    /// The cells touched by `points` (cell coordinates), clipped to `sw`×`sh`;
    /// `None` when that is empty. Points left of the canvas clip to column 0,
    /// where [`accumulate_edge`] folds them.
    fn of(points: impl Iterator<Item = [f64; 2]>, sw: usize, sh: usize) -> Option<Self> {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let x0 = lo[0].floor().clamp(0.0, sw as f64) as usize;
        let x1 = hi[0].ceil().clamp(0.0, sw as f64) as usize;
        let y0 = lo[1].floor().clamp(0.0, sh as f64) as usize;
        let y1 = hi[1].ceil().clamp(0.0, sh as f64) as usize;
        // Entirely left of the canvas still covers nothing (winding cancels),
        // but a polygon straddling x = 0 needs column 0.
        (x0 < x1 && y0 < y1).then_some(Self { x0, y0, x1, y1 })
    }

    fn union(self, o: Self) -> Self {
        Self { x0: self.x0.min(o.x0), y0: self.y0.min(o.y0), x1: self.x1.max(o.x1), y1: self.y1.max(o.y1) }
    }
}

crate::early::simd_dispatch!(fn add_cell_sums(out: &mut [f32], samples: &[f32], s: usize) => add_cell_sums_body);

/// `out[i] += samples[s·i] + … + samples[s·i + s − 1]`, each cell summed
/// left to right (as `Iterator::sum`); the factor of the scenes, 4, in a
/// loop of known length that vectorises across cells.
#[inline(always)]
fn add_cell_sums_body(out: &mut [f32], samples: &[f32], s: usize) {
    if s == 4 {
        for (o, cell) in out.iter_mut().zip(samples.chunks_exact(4)) {
            *o += ((cell[0] + cell[1]) + cell[2]) + cell[3];
        }
        return;
    }
    for (o, cell) in out.iter_mut().zip(samples.chunks_exact(s)) {
        *o += cell.iter().sum::<f32>();
    }
}

/// `v` at least `n` long, every new element zero.
fn grow_zeroed<T: Copy + Default>(v: &mut Vec<T>, n: usize) {
    if v.len() < n {
        v.resize(n, T::default());
    }
}

/// The signed-area accumulator of one face's box of cells, with a bit per
/// cell that an edge added to (so the running sums visit those alone).
struct Accumulator<'a> {
    cells: &'a mut [f64],
    touched: &'a mut [u64],
    /// Cells per row (the box's width + 2).
    stride: usize,
    /// Words of `touched` per row.
    words: usize,
}

impl Accumulator<'_> {
    /// Row `r`'s cells and bits.
    fn row(&mut self, r: usize) -> (&mut [f64], &mut [u64]) {
        (
            &mut self.cells[r * self.stride..(r + 1) * self.stride],
            &mut self.touched[r * self.words..(r + 1) * self.words],
        )
    }

    /// Add the signed-area contribution of the edge `a`→`b` (cell units,
    /// origin at the box's top-left, `size` = box width and height). After a
    /// running sum along each row, every cell holds the area-weighted mean
    /// winding number of the polygon over that cell (the accumulation-buffer
    /// method of font rasterisers). Rows outside the box are dropped; x
    /// outside `0..=width` is folded onto the border, which leaves the
    /// winding of every cell inside the box unchanged.
    fn add_edge(&mut self, size: [f64; 2], a: [f64; 2], b: [f64; 2]) {
        if a[1] == b[1] {
            return;
        }
        // Split where the edge crosses x = 0 or x = width, then fold x into range.
        let mut cuts = [0.0, 1.0, 1.0, 1.0];
        let mut n = 1;
        for border in [0.0, size[0]] {
            let t = (border - a[0]) / (b[0] - a[0]);
            if t > 0.0 && t < 1.0 {
                cuts[n] = t;
                n += 1;
            }
        }
        cuts[n] = 1.0;
        cuts[..=n].sort_by(f64::total_cmp);
        let at = |t: f64| {
            if t == 1.0 { b } else { [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])] }
        };
        for k in 0..n {
            let (p, q) = (at(cuts[k]), at(cuts[k + 1]));
            let fold = |v: [f64; 2]| [v[0].clamp(0.0, size[0]), v[1]];
            self.add_piece(size, fold(p), fold(q));
        }
    }

    /// [`Accumulator::add_edge`] for an edge with `0 <= x <= width` at both ends.
    fn add_piece(&mut self, size: [f64; 2], a: [f64; 2], b: [f64; 2]) {
        if a[1] == b[1] {
            return;
        }
        let (dir, top, bottom) = if a[1] < b[1] { (1.0, a, b) } else { (-1.0, b, a) };
        let dxdy = (bottom[0] - top[0]) / (bottom[1] - top[1]);
        let (mut x, mut y0) = (top[0], top[1]);
        if y0 < 0.0 {
            x -= y0 * dxdy;
            y0 = 0.0;
        }
        let y1 = bottom[1].min(size[1]);
        if y0 >= y1 {
            return;
        }
        let width = size[0];
        for row in (y0.floor() as usize)..(y1.ceil() as usize) {
            let dy = ((row + 1) as f64).min(y1) - (row as f64).max(y0);
            let x_next = (x + dxdy * dy).clamp(0.0, width);
            let x_here = x.clamp(0.0, width);
            let d = dy * dir;
            let (xa, xb) = if x_here < x_next { (x_here, x_next) } else { (x_next, x_here) };
            let xa_floor = xa.floor();
            let ia = xa_floor as usize;
            let ib = xb.ceil() as usize;
            let (line, touched) = self.row(row);
            if ib <= ia + 1 {
                // Within one cell column: the part right of the edge's mean x.
                let mid = 0.5 * (x_here + x_next) - xa_floor;
                line[ia] += d - d * mid;
                line[ia + 1] += d * mid;
                set_bits(touched, ia..ia + 2);
            } else {
                // Across several columns: trapezoids and a triangle at each end.
                let inv = 1.0 / (xb - xa);
                let fa = xa - xa_floor;
                let first = 0.5 * inv * (1.0 - fa) * (1.0 - fa);
                let fb = xb - ib as f64 + 1.0;
                let last = 0.5 * inv * fb * fb;
                line[ia] += d * first;
                if ib == ia + 2 {
                    line[ia + 1] += d * (1.0 - first - last);
                } else {
                    let second = inv * (1.5 - fa);
                    line[ia + 1] += d * (second - first);
                    for v in &mut line[ia + 2..ib - 1] {
                        *v += d * inv;
                    }
                    let before_last = second + (ib - ia - 3) as f64 * inv;
                    line[ib - 1] += d * (1.0 - before_last - last);
                }
                line[ib] += d * last;
                set_bits(touched, ia..ib + 1);
            }
            x = x_next;
        }
    }
}

/// Set the bits `cells` of a bit row.
fn set_bits(bits: &mut [u64], cells: Range<usize>) {
    let (first, last) = (cells.start / 64, (cells.end - 1) / 64);
    for (k, word) in bits[first..=last].iter_mut().enumerate() {
        let lo = if k == 0 { cells.start % 64 } else { 0 };
        let hi = if first + k == last { (cells.end - 1) % 64 } else { 63 };
        *word |= (u64::MAX >> (63 - hi)) & (u64::MAX << lo);
    }
}

/// The running sum along one accumulator row of a box `width` cells wide:
/// `paint(run, coverage)` for every run of cells of one nonzero coverage
/// (the winding number changes only at the cells an edge added to). Leaves
/// the row's cells and bits zero.
fn sweep_row(
    cells: &mut [f64],
    touched: &mut [u64],
    width: usize,
    rule: FillRule,
    mut paint: impl FnMut(Range<usize>, f32),
) {
    let mut winding = 0.0f64;
    let mut run: Option<(usize, f32)> = None;
    for (k, word) in touched.iter_mut().enumerate() {
        let mut bits = std::mem::take(word);
        while bits != 0 {
            let x = k * 64 + bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let contribution = std::mem::take(&mut cells[x]);
            // The spare columns past the box are cleared, not summed.
            if x >= width {
                continue;
            }
            if let Some((start, coverage)) = run.filter(|r| r.1 != 0.0) {
                paint(start..x, coverage);
            }
            winding += contribution;
            run = Some((x, rule.coverage(winding) as f32));
        }
    }
    if let Some((start, coverage)) = run.filter(|r| r.1 != 0.0) {
        paint(start..width, coverage);
    }
}

/// Blend a run of samples covered by one face to `coverage` with its
/// `grey`: each sample as [`blend`] takes a cell whose summed coverage and
/// premultiplied grey are those of this face alone.
fn blend_run(row: &mut [f32], coverage: f32, grey: f32) {
    let (a, p) = (0.0 + coverage, 0.0 + coverage * grey);
    if a > 0.0 {
        for v in row {
            *v = blend(*v, a, p);
        }
    }
}

/// A sample `v` blended with summed coverage `a` and premultiplied grey
/// `p`: their mean grey where fully covered (or where faces overlap after
/// all), `v` where not covered. Both candidates are computed and one
/// selected, so a loop of these has no branch to take per sample.
#[inline(always)]
fn blend(v: f32, a: f32, p: f32) -> f32 {
    let mean = p / a;
    let blended = v * (1.0 - a) + p;
    if a >= 1.0 {
        mean
    } else if a > 0.0 {
        blended
    } else {
        v
    }
}

crate::early::simd_dispatch!(fn blend_layer_row(row: &mut [f32], alpha: &mut [f32], premultiplied: &mut [f32]) => blend_layer_row_body);

/// Blend one row of samples with a layer's summed coverage `alpha` and
/// premultiplied grey, and clear both.
#[inline(always)]
fn blend_layer_row_body(row: &mut [f32], alpha: &mut [f32], premultiplied: &mut [f32]) {
    for ((v, a), p) in row.iter_mut().zip(alpha.iter_mut()).zip(premultiplied.iter_mut()) {
        *v = blend(*v, std::mem::take(a), std::mem::take(p));
    }
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    /// [`Canvas::fill_faces`] the plain way: every face's accumulator summed
    /// cell by cell over its whole box, every coverage added to the layer's
    /// buffers, every cell of the layer blended.
    fn fill_faces_densely(canvas: &mut Canvas, faces: &[Face<'_>], rule: FillRule) {
        let sw = canvas.width * canvas.supersample;
        let to_cell = |p: &[f64; 2]| to_cell(p, canvas.supersample);
        let boxes = canvas.cell_boxes(faces);
        let Some(layer) = boxes.iter().flatten().copied().reduce(CellBox::union) else { return };
        let (lw, lh) = (layer.x1 - layer.x0, layer.y1 - layer.y0);
        let (mut alpha, mut premultiplied) = (vec![0.0f32; lw * lh], vec![0.0f32; lw * lh]);
        for (face, cells) in faces.iter().zip(&boxes) {
            let Some(cells) = cells else { continue };
            let (fw, fh) = (cells.x1 - cells.x0, cells.y1 - cells.y0);
            let (stride, words) = (fw + 2, (fw + 2).div_ceil(64));
            let (mut sums, mut touched) = (vec![0.0f64; stride * fh], vec![0u64; words * fh]);
            let mut acc = Accumulator { cells: &mut sums, touched: &mut touched, stride, words };
            let n = face.points.len();
            for k in 0..n {
                let (a, b) = (to_cell(&face.points[k]), to_cell(&face.points[(k + 1) % n]));
                let origin = [cells.x0 as f64, cells.y0 as f64];
                acc.add_edge(
                    [fw as f64, fh as f64],
                    [a[0] - origin[0], a[1] - origin[1]],
                    [b[0] - origin[0], b[1] - origin[1]],
                );
            }
            for r in 0..fh {
                let mut winding = 0.0f64;
                for x in 0..fw {
                    winding += sums[r * stride + x];
                    let coverage = rule.coverage(winding) as f32;
                    let at = (cells.y0 - layer.y0 + r) * lw + (cells.x0 - layer.x0) + x;
                    alpha[at] += coverage;
                    premultiplied[at] += coverage * face.grey;
                }
            }
        }
        for r in 0..lh {
            for x in 0..lw {
                let v = &mut canvas.samples[(layer.y0 + r) * sw + layer.x0 + x];
                let (a, p) = (alpha[r * lw + x], premultiplied[r * lw + x]);
                if a >= 1.0 {
                    *v = p / a;
                } else if a > 0.0 {
                    *v = *v * (1.0 - a) + p;
                }
            }
        }
    }

    #[test]
    fn fill_faces_equals_the_dense_fill_bitwise() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for case in 0..300 {
            let (w, h) = (rng.random_range(1..40), rng.random_range(1..30));
            let s = [1, 2, 3, 4, 5][case % 5];
            let mut canvas = Canvas::new(w, h, s, 0.0).unwrap();
            canvas.shade_with(|x, y| (x * 7.0 + y * 3.0).rem_euclid(255.0) as f32);
            let mut reference = canvas.clone();
            let rule = if case % 2 == 0 { FillRule::EvenOdd } else { FillRule::NonZero };
            // Outlines reaching past every border, some self-crossing, some
            // nearly horizontal, in layers of one to four faces.
            for _ in 0..3 {
                let outlines: Vec<Vec<[f64; 2]>> = (0..rng.random_range(1..5))
                    .map(|_| {
                        let n = rng.random_range(2..12);
                        let flat = rng.random_bool(0.2);
                        (0..n)
                            .map(|_| {
                                let x = rng.random_range(-8.0..w as f64 + 8.0);
                                let y = if flat { 0.3 * x + 2.0 } else { rng.random_range(-8.0..h as f64 + 8.0) };
                                [x, y]
                            })
                            .collect()
                    })
                    .collect();
                let greys: Vec<f32> = outlines.iter().map(|_| rng.random_range(0.0..255.0)).collect();
                let faces: Vec<Face<'_>> =
                    outlines.iter().zip(&greys).map(|(points, &grey)| Face { points, grey }).collect();
                canvas.fill_faces(&faces, rule);
                fill_faces_densely(&mut reference, &faces, rule);
                for (k, (a, b)) in canvas.samples().iter().zip(reference.samples()).enumerate() {
                    assert_eq!(a.to_bits(), b.to_bits(), "case {case}, {w}x{h}@{s}, sample {k}: {a} vs {b}");
                }
            }
            assert!(canvas.scratch.accumulator.iter().all(|&v| v == 0.0), "case {case}: accumulator left set");
            assert!(canvas.scratch.touched.iter().all(|&v| v == 0), "case {case}: bits left set");
            assert!(canvas.scratch.alpha.iter().chain(&canvas.scratch.premultiplied).all(|&v| v == 0.0));
        }
    }

    #[test]
    fn cell_sums_equal_iterator_sums_bitwise() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for s in 1..=6 {
            for n in [0, 1, 5, 16, 17, 63] {
                let samples: Vec<f32> = (0..n * s).map(|_| rng.random_range(0.0..255.0)).collect();
                let start: Vec<f32> = (0..n).map(|_| rng.random_range(0.0..1000.0)).collect();
                let mut out = start.clone();
                add_cell_sums(&mut out, &samples, s);
                for (i, (o, cell)) in out.iter().zip(samples.chunks_exact(s)).enumerate() {
                    let expected = start[i] + cell.iter().sum::<f32>();
                    assert_eq!(o.to_bits(), expected.to_bits(), "s {s}, n {n}, cell {i}");
                }
            }
        }
    }

    #[test]
    fn set_bits_sets_exactly_the_range() {
        for start in 0..140 {
            for end in start + 1..=192 {
                let mut bits = [0u64; 3];
                set_bits(&mut bits, start..end);
                for i in 0..192 {
                    assert_eq!(bits[i / 64] >> (i % 64) & 1 == 1, (start..end).contains(&i), "{start}..{end} bit {i}");
                }
            }
        }
    }
}
