//! Sum of two consecutive smoothed frames, `G*_t + G*_{t+1}`.
//!
//! 000 extracts edge orientation (eq. 2) from this sum rather than from one
//! frame, so that a moving edge is present in the edge image at both of the
//! positions the temporal difference (eq. 1) marks. One f32 addition per
//! pixel: the two twins agree exactly.

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::rows::for_each_row;
use crate::Result;
use crate::gpu::{
    Binding::{ReadOnly, Storage, Uniform},
    EntryPoint, GpuContext, GpuImage, Recorder, ShaderDef, run_once,
};
use crate::image::FloatImage;

/// The shader of this stage.
pub const SHADER: ShaderDef = ShaderDef {
    name: "frame_sum",
    source: include_str!("../../shaders/frame_sum.wgsl"),
    includes: &[],
    entry_points: &[EntryPoint::tiled("frame_sum", &[Uniform, ReadOnly, ReadOnly, Storage])],
    overrides: &[],
};

/// Uniform block of `frame_sum.wgsl`; kept in sync with its `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FrameSumUniform {
    width: u32,
    height: u32,
    _pad: [u32; 2],
}

fn sum_row(a: &[f32], b: &[f32], out: &mut [f32]) {
    for ((o, &x), &y) in out.iter_mut().zip(a).zip(b) {
        *o = x + y;
    }
}

/// CPU twin: write `a + b` into `out` (resized to match). `a` and `b` must
/// have the same size ([`crate::Error::Size`]).
pub fn frame_sum_cpu(a: &FloatImage, b: &FloatImage, out: &mut FloatImage) -> Result<()> {
    a.check_same_size(b, "frame sum")?;
    let (w, h) = a.size();
    out.resize(w, h);
    if w == 0 || h == 0 {
        return Ok(());
    }
    let rows = a.data().par_chunks(w).zip(b.data().par_chunks(w)).zip(out.data_mut().par_chunks_mut(w));
    for_each_row(w * h, rows, |((x, y), o)| sum_row(x, y, o));
    Ok(())
}

/// CPU twin, allocating its output: `a + b`.
pub fn frame_sum(a: &FloatImage, b: &FloatImage) -> Result<FloatImage> {
    let mut out = FloatImage::new(0, 0);
    frame_sum_cpu(a, b, &mut out)?;
    Ok(out)
}

/// Record `out = a + b` (all three the same size).
pub(crate) fn encode(rec: &mut Recorder<'_>, a: &GpuImage, b: &GpuImage, out: &GpuImage) -> Result<()> {
    let (w, h) = (a.width(), a.height());
    a.check_same_size(b, "frame sum a/b")?;
    a.check_same_size(out, "frame sum a/out")?;
    let u = FrameSumUniform { width: w as u32, height: h as u32, _pad: [0; 2] };
    rec.dispatch(&SHADER, "frame_sum", &u, &[&a.buffer, &b.buffer, &out.buffer], a.grid())
}

/// GPU: `a + b` of two CPU images, read back (tests and benches).
pub fn frame_sum_gpu(ctx: &GpuContext, a: &FloatImage, b: &FloatImage) -> Result<FloatImage> {
    a.check_same_size(b, "frame sum")?;
    let (w, h) = a.size();
    let ga = GpuImage::from_image(ctx, a, "frame_sum.a");
    let gb = GpuImage::from_image(ctx, b, "frame_sum.b");
    let out = GpuImage::new(ctx, w, h, "frame_sum.out");
    run_once(ctx, |rec| encode(rec, &ga, &gb, &out))?;
    out.download(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Error;

    #[test]
    fn adds_pixelwise() {
        let a = FloatImage::from_vec(3, 1, vec![1.0, 2.5, 255.0]).unwrap();
        let b = FloatImage::from_vec(3, 1, vec![0.0, -0.5, 255.0]).unwrap();
        assert_eq!(frame_sum(&a, &b).unwrap().data(), &[1.0, 2.0, 510.0]);
    }

    #[test]
    fn size_mismatch_is_an_error_and_empty_images_work() {
        let mut out = FloatImage::new(0, 0);
        assert!(matches!(frame_sum_cpu(&FloatImage::new(2, 1), &FloatImage::new(1, 2), &mut out), Err(Error::Size(_))));
        let e = FloatImage::new(0, 5);
        assert_eq!(frame_sum(&e, &e).unwrap().size(), (0, 5));
    }

    #[test]
    fn large_images_take_the_parallel_path() {
        let (w, h) = (300, 250); // 75 000 pixels ≥ PARALLEL_PIXELS
        let a = FloatImage::from_fn(w, h, |x, y| (x + y) as f32);
        let b = FloatImage::from_fn(w, h, |x, _| x as f32);
        let s = frame_sum(&a, &b).unwrap();
        assert_eq!(s.get(299, 249), 299.0 + 249.0 + 299.0);
        assert_eq!(s.get(0, 7), 7.0);
    }
}
