//! Averaged edge hierarchies (004 eq. 10–11): from the horizontal and
//! vertical Sobel edge images at the finest level, each coarser level is the
//! mean of the 2×2 children of the previous one, summed in the order
//! `((p00 + p01) + (p10 + p11)) · ¼` by both twins (children indexed as in
//! [`super::cpf`]: `p_ab = (2i + a, 2j + b)`, `i` the column).
//!
//! Levels are those of the CPF hierarchies ([`level_sizes`]): `levels[0]` is
//! the input, `levels[k]` is `ceil(w/2^k)`×`ceil(h/2^k)`, down to 1×1. When a
//! level has an odd width (height), the missing child column (row) is clamped
//! to the edge child, which makes the mean exactly the mean of the children
//! that exist (each one is counted twice, and scaling by a power of two is
//! exact in f32).
//!
//! GPU layout: each hierarchy lives in one storage buffer with its levels
//! concatenated (level 0 first, offsets from [`EdgePyramidGpu::level_offsets`]),
//! like the CPF hierarchies; one dispatch builds up to five levels of both.

use super::cpf::{LevelLayout, PYRAMID_TILE, level_sizes, reduce_level, reduce_row, shape_levels};
use crate::gpu::{
    Binding::{Storage, Uniform},
    EntryPoint, GpuContext, GpuImage, Recorder, ShaderDef, run_once,
};
use crate::image::FloatImage;
use crate::{Error, Result};

/// The shader of this stage.
pub const SHADER: ShaderDef = ShaderDef {
    name: "edge_pyramid",
    source: include_str!("../../shaders/edge_pyramid.wgsl"),
    includes: &[PYRAMID_TILE],
    entry_points: &[EntryPoint::pyramid_levels("edge_levels", &[Uniform, Storage, Storage])],
    overrides: &[],
};

/// The averaged horizontal and vertical edge hierarchies of one image.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EdgePyramids {
    /// `horizontal[k]`: eq. 10 at level k (0 = the horizontal Sobel image).
    pub horizontal: Vec<FloatImage>,
    /// `vertical[k]`: eq. 11 at level k (0 = the vertical Sobel image).
    pub vertical: Vec<FloatImage>,
}

/// Mean of the children (eq. 10–11), same order as the shader.
#[inline(always)]
fn mean_row(r0: &[f32], r1: &[f32], dst: &mut [f32]) {
    reduce_row(r0, r1, dst, |a, b| a + b, |l, r| (l + r) * 0.25);
}

/// CPU twin: the averaged edge hierarchies (eq. 10–11) of the horizontal and
/// vertical Sobel images into `out`, reusing its allocations. Errors when
/// the two images differ in size.
pub fn edge_pyramid_cpu(horizontal: &FloatImage, vertical: &FloatImage, out: &mut EdgePyramids) -> Result<()> {
    horizontal.check_same_size(vertical, "edge pyramid inputs")?;
    let sizes = level_sizes(horizontal.width(), horizontal.height());
    for (levels, base) in [(&mut out.horizontal, horizontal), (&mut out.vertical, vertical)] {
        shape_levels(levels, &sizes);
        levels[0].data_mut().copy_from_slice(base.data());
        reduce_means(levels);
    }
    Ok(())
}

/// [`edge_pyramid_cpu`] for a caller done with its inputs: they become the
/// two level-0 images without a copy, and each of `horizontal` and
/// `vertical` is left holding an image of the same size whose values are
/// unspecified (the buffer that level held). The hierarchies are those
/// [`edge_pyramid_cpu`] gives.
pub fn edge_pyramid_cpu_taking(
    horizontal: &mut FloatImage,
    vertical: &mut FloatImage,
    out: &mut EdgePyramids,
) -> Result<()> {
    horizontal.check_same_size(vertical, "edge pyramid inputs")?;
    let sizes = level_sizes(horizontal.width(), horizontal.height());
    for (levels, base) in [(&mut out.horizontal, horizontal), (&mut out.vertical, vertical)] {
        shape_levels(levels, &sizes);
        std::mem::swap(base, &mut levels[0]);
        reduce_means(levels);
    }
    Ok(())
}

/// Levels 1.. of one averaged hierarchy from its level 0 (levels already shaped).
fn reduce_means(levels: &mut [FloatImage]) {
    for k in 1..levels.len() {
        let (coarser, finer) = levels.split_at_mut(k);
        reduce_level(&coarser[k - 1], &mut finer[0], mean_row);
    }
}

/// CPU twin, allocating: the averaged edge hierarchies of `horizontal` and `vertical`.
pub fn edge_pyramid(horizontal: &FloatImage, vertical: &FloatImage) -> Result<EdgePyramids> {
    let mut out = EdgePyramids::default();
    edge_pyramid_cpu(horizontal, vertical, &mut out)?;
    Ok(out)
}

/// GPU buffers of the averaged edge hierarchies of a `width`×`height`
/// image: one buffer each for horizontal and vertical, levels concatenated.
#[derive(Debug)]
pub struct EdgePyramidGpu {
    layout: LevelLayout,
    horizontal: GpuImage,
    vertical: GpuImage,
}

impl EdgePyramidGpu {
    /// Allocate the buffers for `width`×`height` edge images; reuse them across frames.
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
        let horizontal = GpuImage::new(ctx, total, 1, "edge_pyramid.h");
        let vertical = GpuImage::new(ctx, total, 1, "edge_pyramid.v");
        Self { layout, horizontal, vertical }
    }

    /// Sizes of the levels, finest first (see [`level_sizes`]).
    #[must_use]
    pub fn level_sizes(&self) -> &[(usize, usize)] {
        &self.layout.sizes
    }

    /// Offset (in f32 elements) of each level in either buffer, plus the
    /// total length as the last entry.
    #[must_use]
    pub fn level_offsets(&self) -> &[usize] {
        &self.layout.offsets
    }

    /// The horizontal hierarchy's buffer, as a 1-row image of all levels.
    #[must_use]
    pub fn horizontal(&self) -> &GpuImage {
        &self.horizontal
    }

    /// The vertical hierarchy's buffer, as a 1-row image of all levels.
    #[must_use]
    pub fn vertical(&self) -> &GpuImage {
        &self.vertical
    }

    /// Read all levels of both hierarchies back (tests and benches).
    pub fn download(&self, ctx: &GpuContext) -> Result<EdgePyramids> {
        self.download_layers(ctx)?.into_iter().next().ok_or_else(|| Error::Gpu("no pyramid layer".into()))
    }

    /// Read all levels of both hierarchies of every layer back.
    pub fn download_layers(&self, ctx: &GpuContext) -> Result<Vec<EdgePyramids>> {
        let (h, v) = (self.horizontal.download(ctx)?, self.vertical.download(ctx)?);
        (0..self.layout.layers)
            .map(|layer| {
                Ok(EdgePyramids { horizontal: self.layout.split(&h, layer)?, vertical: self.layout.split(&v, layer)? })
            })
            .collect()
    }
}

/// Record the edge hierarchies of the Sobel images `gx` (horizontal) and
/// `gy` (vertical) into `out`: two buffer copies for level 0, then
/// dispatches of up to [`super::cpf::LEVELS_PER_DISPATCH`] coarser levels of both
/// hierarchies, as [`super::cpf`] records them.
pub(crate) fn encode(rec: &mut Recorder<'_>, gx: &GpuImage, gy: &GpuImage, out: &EdgePyramidGpu) -> Result<()> {
    let layout = &out.layout;
    layout.check_input(gx, "edge pyramid horizontal input")?;
    layout.check_input(gy, "edge pyramid vertical input")?;
    rec.copy(&gx.buffer, 0, &out.horizontal.buffer, 0, layout.base_bytes());
    rec.copy(&gy.buffer, 0, &out.vertical.buffer, 0, layout.base_bytes());
    for (u, grid) in layout.dispatches()? {
        rec.dispatch(&SHADER, "edge_levels", &u, &[&out.horizontal.buffer, &out.vertical.buffer], grid)?;
    }
    Ok(())
}

/// GPU: the averaged edge hierarchies of two CPU images, read back (tests and benches).
pub fn edge_pyramid_gpu(ctx: &GpuContext, horizontal: &FloatImage, vertical: &FloatImage) -> Result<EdgePyramids> {
    horizontal.check_same_size(vertical, "edge pyramid inputs")?;
    let gx = GpuImage::from_image(ctx, horizontal, "edge_pyramid.gx");
    let gy = GpuImage::from_image(ctx, vertical, "edge_pyramid.gy");
    let out = EdgePyramidGpu::new(ctx, horizontal.width(), horizontal.height());
    run_once(ctx, |rec| encode(rec, &gx, &gy, &out))?;
    out.download(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, values: &[f32]) -> FloatImage {
        FloatImage::from_vec(w, h, values.to_vec()).unwrap()
    }

    #[test]
    fn edge_pyramid_of_two_by_two_is_the_mean() {
        let h = image(2, 2, &[1.0, 2.0, 3.0, 6.0]);
        let v = image(2, 2, &[-4.0, 0.0, 0.0, 0.0]);
        let e = edge_pyramid(&h, &v).unwrap();
        assert_eq!(e.horizontal.len(), 2);
        assert_eq!(e.horizontal[0], h);
        assert_eq!(e.horizontal[1].data(), &[3.0]);
        assert_eq!(e.vertical[1].data(), &[-1.0]);
        assert!(edge_pyramid(&h, &image(1, 2, &[0.0, 0.0])).is_err());
    }

    /// Odd sizes: the mean uses the children that exist.
    #[test]
    fn three_by_three_averages_the_children_that_exist() {
        #[rustfmt::skip]
        let src = image(3, 3, &[
            1.0, 2.0, 3.0,
            4.0, 5.0, 6.0,
            7.0, 8.0, 9.0,
        ]);
        let e = edge_pyramid(&src, &src).unwrap();
        // (1+2+4+5)/4 = 3, (3+6)/2 = 4.5, (7+8)/2 = 7.5, 9; then (3+4.5+7.5+9)/4 = 6.
        assert_eq!(e.horizontal[1].data(), &[3.0, 4.5, 7.5, 9.0]);
        assert_eq!(e.horizontal[2].data(), &[6.0]);
        assert_eq!(e.vertical, e.horizontal);
    }

    #[test]
    fn one_pixel_has_one_level() {
        let src = image(1, 1, &[42.0]);
        let e = edge_pyramid(&src, &src).unwrap();
        assert_eq!((e.horizontal.len(), e.vertical.len()), (1, 1));
        assert_eq!(e.horizontal[0], src);
    }

    /// Every level against the mean of the children that exist (1, 2 or 4 of
    /// them), on an odd size large enough to run on several threads.
    #[test]
    fn every_level_is_the_mean_of_its_children() {
        let src = crate::testimage::natural(301, 257, 5).to_f32();
        const { assert!(301 * 257 >= crate::early::rows::PARALLEL_PIXELS) };
        let e = edge_pyramid(&src, &src).unwrap();
        for k in 1..e.horizontal.len() {
            let (prev, cur) = (&e.horizontal[k - 1], &e.horizontal[k]);
            for j in 0..cur.height() {
                for i in 0..cur.width() {
                    let (xs, ys) = (2 * i..(2 * i + 2).min(prev.width()), 2 * j..(2 * j + 2).min(prev.height()));
                    let n = (xs.len() * ys.len()) as f32;
                    let sum: f32 = ys.flat_map(|y| xs.clone().map(move |x| (x, y))).map(|(x, y)| prev.get(x, y)).sum();
                    assert!((cur.get(i, j) - sum / n).abs() <= 1e-4, "edge level {k} at ({i}, {j})");
                }
            }
        }
    }
}
