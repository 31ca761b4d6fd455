//! Thresholded temporal difference (000 eq. 1): the binary motion image.
//!
//! 000 subtracts two temporally consecutive smoothed frames,
//! `∂I/∂t = G*_t − G*_{t+1}`, and thresholds the result. Here a pixel is
//! moving when `|prev − cur| > threshold` (strictly greater): the mask holds
//! `1.0` there and `0.0` elsewhere. The mask is stored as f32 so that every
//! mask in pipetrack has the same pixel type as the images it is combined with.

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::Window;
use super::rows::for_each_row;
use crate::gpu::{
    Binding::{ReadOnly, Storage, Uniform},
    EntryPoint, GpuContext, GpuImage, Recorder, ShaderDef, run_once,
};
use crate::image::FloatImage;
use crate::{Error, Result};

/// The shader of this stage.
pub const SHADER: ShaderDef = ShaderDef {
    name: "temporal_diff",
    source: include_str!("../../shaders/temporal_diff.wgsl"),
    includes: &[],
    entry_points: &[
        EntryPoint::tiled("temporal_diff", &[Uniform, ReadOnly, ReadOnly, Storage]),
        EntryPoint::tiled("temporal_diff_and_sum", &[Uniform, ReadOnly, ReadOnly, Storage, Storage]),
    ],
    overrides: &[],
};

/// Mask value of a moving pixel.
pub const MOVING: f32 = 1.0;
/// Mask value of a still pixel.
pub const STILL: f32 = 0.0;

/// Parameters of the temporal difference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TemporalDiffParams {
    /// A pixel is moving when `|prev − cur|` exceeds this, in grey levels of
    /// the 0..255 scale; must be finite and `>= 0`. 000 gives no value.
    /// pipetrack's default, 8, sits far above the noise of a difference of
    /// two smoothed frames (8-bit camera noise of σ ≈ 2 levels drops below
    /// 1 level after a σ = 1 Gaussian, so the difference has σ ≈ 1) while an
    /// edge of contrast ≥ 16 levels moving ≥ 1 px/frame (000 tracks at
    /// 1.1–4.5 px/frame) still changes the smoothed image by more than 8.
    pub threshold: f32,
}

impl Default for TemporalDiffParams {
    fn default() -> Self {
        Self { threshold: 8.0 }
    }
}

impl TemporalDiffParams {
    /// Error unless the threshold is finite and non-negative.
    pub fn validate(&self) -> Result<()> {
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return Err(Error::Parameter(format!(
                "temporal difference threshold {} must be finite and >= 0",
                self.threshold
            )));
        }
        Ok(())
    }
}

/// Uniform block of `temporal_diff.wgsl`; kept in sync with its `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct TemporalDiffUniform {
    width: u32,
    height: u32,
    threshold: f32,
    _pad: u32,
}

// The two row loops below are compiled for the baseline instruction set,
// not dispatched to AVX-512 like the filters: they move 12 bytes per pixel
// for one comparison, so memory traffic bounds them, and on the AVX-512 CPU
// measured (frames of 640×480 and above, one thread) the 512-bit build ran
// 15–25 % slower than the baseline one.

/// One row (or any run of pixels); same arithmetic as the shader.
fn diff_row(prev: &[f32], cur: &[f32], out: &mut [f32], threshold: f32) {
    for ((o, &p), &c) in out.iter_mut().zip(prev).zip(cur) {
        // 000 eq. 1: G*_t − G*_{t+1}, thresholded on its magnitude.
        *o = if (p - c).abs() > threshold { MOVING } else { STILL };
    }
}

/// The mask and the frame sum of one run of pixels, in one loop.
fn diff_and_sum_row(prev: &[f32], cur: &[f32], mask: &mut [f32], sum: &mut [f32], threshold: f32) {
    for (((m, s), &p), &c) in mask.iter_mut().zip(sum.iter_mut()).zip(prev).zip(cur) {
        *m = if (p - c).abs() > threshold { MOVING } else { STILL };
        *s = p + c;
    }
}

/// Rows handed to one call of a per-pixel row function: each pixel depends
/// on its own inputs alone, so a band of rows is one run of pixels, and a
/// band of about 16 K pixels keeps the per-call cost out of the loop.
fn band_rows(width: usize) -> usize {
    (BAND_PIXELS / width).max(1)
}

/// Pixels of one band (see [`band_rows`]).
const BAND_PIXELS: usize = 1 << 14;

/// The motion mask of `prev → cur` into `mask` and the frame sum `prev + cur`
/// (000 eq. 2's input, see [`super::frame_sum`]) into `sum`, in one pass over
/// the two frames: the CPU backend's fusion of the two stages, each output
/// equal to its stage's own twin. Only `region` (clipped) is computed: the
/// outputs are resized to the frames' size, their values inside the region
/// are those of the whole frames, and outside it they are whatever the
/// images held before; `prev` and `cur` need only be valid inside it.
pub fn temporal_diff_and_sum_cpu(
    prev: &FloatImage,
    cur: &FloatImage,
    params: &TemporalDiffParams,
    region: Window,
    mask: &mut FloatImage,
    sum: &mut FloatImage,
) -> Result<()> {
    params.validate()?;
    prev.check_same_size(cur, "temporal difference prev/cur")?;
    let (w, h) = prev.size();
    mask.resize(w, h);
    sum.resize(w, h);
    let region = region.clipped(w, h);
    if region.is_empty() {
        return Ok(());
    }
    let t = params.threshold;
    let (x0, x1, y0, y1) = (region.x0 as usize, region.x1 as usize, region.y0 as usize, region.y1 as usize);
    if x1 - x0 < w {
        for y in y0..y1 {
            let run = y * w + x0..y * w + x1;
            let (p, c) = (&prev.data()[run.clone()], &cur.data()[run.clone()]);
            diff_and_sum_row(p, c, &mut mask.data_mut()[run.clone()], &mut sum.data_mut()[run], t);
        }
        return Ok(());
    }
    // Whole rows are one run of pixels, cut into bands.
    let (rows, band) = (y0 * w..y1 * w, band_rows(w) * w);
    let planes = (prev.data()[rows.clone()].par_chunks(band).zip(cur.data()[rows.clone()].par_chunks(band)))
        .zip(mask.data_mut()[rows.clone()].par_chunks_mut(band).zip(sum.data_mut()[rows].par_chunks_mut(band)));
    for_each_row(w * (y1 - y0), planes, |((p, c), (m, s))| diff_and_sum_row(p, c, m, s, t));
    Ok(())
}

/// CPU twin: write the motion mask of `prev → cur` into `out` (resized to
/// match). `prev` and `cur` must have the same size ([`Error::Size`]).
pub fn temporal_diff_cpu(
    prev: &FloatImage,
    cur: &FloatImage,
    params: &TemporalDiffParams,
    out: &mut FloatImage,
) -> Result<()> {
    params.validate()?;
    prev.check_same_size(cur, "temporal difference prev/cur")?;
    let (w, h) = prev.size();
    out.resize(w, h);
    if w == 0 || h == 0 {
        return Ok(());
    }
    let t = params.threshold;
    let band = band_rows(w) * w;
    let rows = prev.data().par_chunks(band).zip(cur.data().par_chunks(band)).zip(out.data_mut().par_chunks_mut(band));
    for_each_row(w * h, rows, |((p, c), o)| diff_row(p, c, o, t));
    Ok(())
}

/// CPU twin, allocating its output: the motion mask of `prev → cur`.
pub fn temporal_diff(prev: &FloatImage, cur: &FloatImage, params: &TemporalDiffParams) -> Result<FloatImage> {
    let mut out = FloatImage::new(0, 0);
    temporal_diff_cpu(prev, cur, params, &mut out)?;
    Ok(out)
}

/// Record the mask `out = |prev − cur| > threshold` (all three the same size).
pub(crate) fn encode(
    rec: &mut Recorder<'_>,
    prev: &GpuImage,
    cur: &GpuImage,
    out: &GpuImage,
    params: &TemporalDiffParams,
) -> Result<()> {
    let u = checked_uniform(prev, cur, out, params)?;
    rec.dispatch(&SHADER, "temporal_diff", &u, &[&prev.buffer, &cur.buffer, &out.buffer], prev.grid())
}

/// The uniform block for `prev → cur` into the mask `out`, after checking
/// the parameters and that the three images have one size.
fn checked_uniform(
    prev: &GpuImage,
    cur: &GpuImage,
    out: &GpuImage,
    params: &TemporalDiffParams,
) -> Result<TemporalDiffUniform> {
    params.validate()?;
    prev.check_same_size(cur, "temporal difference prev/cur")?;
    prev.check_same_size(out, "temporal difference prev/out")?;
    let (w, h) = prev.size();
    Ok(TemporalDiffUniform { width: w as u32, height: h as u32, threshold: params.threshold, _pad: 0 })
}

/// Record the mask `mask = |prev − cur| > threshold` and the frame sum
/// `sum = prev + cur` in one dispatch (all four the same size): the GPU
/// twin of [`temporal_diff_and_sum_cpu`] over the whole frame.
pub(crate) fn encode_with_sum(
    rec: &mut Recorder<'_>,
    prev: &GpuImage,
    cur: &GpuImage,
    mask: &GpuImage,
    sum: &GpuImage,
    params: &TemporalDiffParams,
) -> Result<()> {
    let u = checked_uniform(prev, cur, mask, params)?;
    prev.check_same_size(sum, "temporal difference prev/sum")?;
    let buffers = [&prev.buffer, &cur.buffer, &mask.buffer, &sum.buffer];
    rec.dispatch(&SHADER, "temporal_diff_and_sum", &u, &buffers, prev.grid())
}

/// GPU: the motion mask and the frame sum of two CPU images in one
/// dispatch, read back as `(mask, sum)` (tests and benches).
pub fn temporal_diff_and_sum_gpu(
    ctx: &GpuContext,
    prev: &FloatImage,
    cur: &FloatImage,
    params: &TemporalDiffParams,
) -> Result<(FloatImage, FloatImage)> {
    prev.check_same_size(cur, "temporal difference prev/cur")?;
    let (w, h) = prev.size();
    let p = GpuImage::from_image(ctx, prev, "temporal_diff.prev");
    let c = GpuImage::from_image(ctx, cur, "temporal_diff.cur");
    let mask = GpuImage::new(ctx, w, h, "temporal_diff.mask");
    let sum = GpuImage::new(ctx, w, h, "temporal_diff.sum");
    run_once(ctx, |rec| encode_with_sum(rec, &p, &c, &mask, &sum, params))?;
    Ok((mask.download(ctx)?, sum.download(ctx)?))
}

/// GPU: the motion mask of two CPU images, read back (tests and benches).
pub fn temporal_diff_gpu(
    ctx: &GpuContext,
    prev: &FloatImage,
    cur: &FloatImage,
    params: &TemporalDiffParams,
) -> Result<FloatImage> {
    prev.check_same_size(cur, "temporal difference prev/cur")?;
    let (w, h) = prev.size();
    let p = GpuImage::from_image(ctx, prev, "temporal_diff.prev");
    let c = GpuImage::from_image(ctx, cur, "temporal_diff.cur");
    let out = GpuImage::new(ctx, w, h, "temporal_diff.mask");
    run_once(ctx, |rec| encode(rec, &p, &c, &out, params))?;
    out.download(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: usize, h: usize, v: &[f32]) -> FloatImage {
        FloatImage::from_vec(w, h, v.to_vec()).unwrap()
    }

    /// The fused pass equals the two stages' own twins, small and threaded
    /// sizes, on the whole frame and on regions.
    #[test]
    fn fused_diff_and_sum_equal_the_separate_twins() {
        for (w, h) in [(1, 1), (7, 5), (1, 9), (16_385, 2), (320, 240)] {
            let a = crate::testimage::natural(w, h, 1).to_f32();
            let b = crate::testimage::natural(w, h, 2).to_f32();
            let p = TemporalDiffParams::default();
            let (mut mask, mut sum) = (FloatImage::new(0, 0), FloatImage::new(0, 0));
            temporal_diff_and_sum_cpu(&a, &b, &p, Window::full(w, h), &mut mask, &mut sum).unwrap();
            let mut expected = FloatImage::new(0, 0);
            temporal_diff_cpu(&a, &b, &p, &mut expected).unwrap();
            assert_eq!(mask, expected);
            let expected_sum = crate::early::frame_sum::frame_sum(&a, &b).unwrap();
            assert_eq!(sum, expected_sum);
            // A region, part of the rows or all of them: its pixels as the
            // whole frame's, nothing else written.
            let (wu, hu) = (w as u32, h as u32);
            for region in
                [Window { x0: wu / 3, y0: hu / 4, x1: wu - wu / 3, y1: hu }, Window { x0: 0, y0: 1, x1: wu, y1: hu }]
            {
                let (mut part_mask, mut part_sum) = (FloatImage::from_fn(w, h, |_, _| -1.0), FloatImage::new(w, h));
                temporal_diff_and_sum_cpu(&a, &b, &p, region, &mut part_mask, &mut part_sum).unwrap();
                for y in 0..h {
                    for x in 0..w {
                        let inside = (region.x0 as usize..region.x1 as usize).contains(&x)
                            && (region.y0 as usize..region.y1 as usize).contains(&y);
                        let want = if inside { (expected.get(x, y), expected_sum.get(x, y)) } else { (-1.0, 0.0) };
                        assert_eq!((part_mask.get(x, y), part_sum.get(x, y)), want, "{w}x{h} {region:?} ({x}, {y})");
                    }
                }
            }
        }
    }

    /// Bands of rows and the vector loop equal a plain per-pixel loop, bit
    /// for bit, on odd widths, single rows and columns, and one-pixel images,
    /// with differences at and around the threshold.
    #[test]
    fn banded_vector_twin_equals_a_plain_loop_on_awkward_sizes() {
        for (w, h) in [(1, 1), (1, 37), (37, 1), (17, 13), (255, 3), (1000, 21), (16_385, 2)] {
            let prev = FloatImage::from_fn(w, h, |x, y| ((x * 7 + y * 13) % 23) as f32);
            let cur = FloatImage::from_fn(w, h, |x, y| ((x * 5 + y * 3) % 19) as f32 + 0.5 * (x % 2) as f32);
            let p = TemporalDiffParams::default();
            let mut out = FloatImage::new(3, 3);
            temporal_diff_cpu(&prev, &cur, &p, &mut out).unwrap();
            let expected: Vec<u32> = (prev.data().iter().zip(cur.data()))
                .map(|(&a, &b)| if (a - b).abs() > p.threshold { MOVING } else { STILL }.to_bits())
                .collect();
            assert_eq!(out.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>(), expected, "{w}x{h}");
        }
    }

    #[test]
    fn moving_where_difference_exceeds_threshold_in_either_direction() {
        // |prev − cur| = 0, 9, 9, 8, 7.5, 100 with threshold 8:
        // only strictly greater differences count, whatever their sign.
        let prev = img(3, 2, &[10.0, 10.0, 20.0, 50.0, 0.0, 200.0]);
        let cur = img(3, 2, &[10.0, 19.0, 11.0, 58.0, 7.5, 100.0]);
        let m = temporal_diff(&prev, &cur, &TemporalDiffParams::default()).unwrap();
        assert_eq!(m.data(), &[0.0, 1.0, 1.0, 0.0, 0.0, 1.0]);
    }

    #[test]
    fn zero_threshold_marks_every_change_and_identical_frames_give_no_motion() {
        let prev = img(2, 2, &[1.0, 2.0, 3.0, 4.0]);
        let cur = img(2, 2, &[1.0, 2.001, 3.0, 3.5]);
        let m = temporal_diff(&prev, &cur, &TemporalDiffParams { threshold: 0.0 }).unwrap();
        assert_eq!(m.data(), &[0.0, 1.0, 0.0, 1.0]);
        let m = temporal_diff(&prev, &prev, &TemporalDiffParams { threshold: 0.0 }).unwrap();
        assert!(m.data().iter().all(|&v| v == STILL));
    }

    #[test]
    fn size_mismatch_and_bad_threshold_are_errors() {
        let a = FloatImage::new(3, 2);
        let b = FloatImage::new(2, 3);
        let mut out = FloatImage::new(0, 0);
        let p = TemporalDiffParams::default();
        assert!(matches!(temporal_diff_cpu(&a, &b, &p, &mut out), Err(Error::Size(_))));
        for t in [-1.0, f32::NAN, f32::INFINITY] {
            assert!(matches!(temporal_diff(&a, &a, &TemporalDiffParams { threshold: t }), Err(Error::Parameter(_))));
        }
    }

    #[test]
    fn output_is_resized_and_large_images_take_the_parallel_path() {
        let (w, h) = (300, 250); // 75 000 pixels ≥ PARALLEL_PIXELS
        let prev = FloatImage::from_fn(w, h, |x, _| x as f32);
        let cur = FloatImage::from_fn(w, h, |x, y| if y % 2 == 0 { x as f32 + 10.0 } else { x as f32 });
        let mut out = FloatImage::new(1, 1);
        temporal_diff_cpu(&prev, &cur, &TemporalDiffParams::default(), &mut out).unwrap();
        assert_eq!(out.size(), (w, h));
        for y in 0..h {
            let expected = if y % 2 == 0 { MOVING } else { STILL };
            assert!(out.row(y).iter().all(|&v| v == expected), "row {y}");
        }
    }
}
