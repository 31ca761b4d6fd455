//! Ingest: a frame (8-bit grey bytes, or a caller's R8Unorm / Rgba8Unorm
//! texture) becomes the f32 grey image, 0..255 scale, that every stage reads.

use bytemuck::{Pod, Zeroable};

use crate::gpu::{
    Binding::{ReadOnly, Storage, Texture, Uniform},
    EntryPoint, GpuContext, GpuImage, Recorder, ShaderDef, run_once, workgroups_2d,
};
use crate::image::{FloatImage, GrayImage, luma};
use crate::{Error, Result};

/// Shader for byte frames.
pub const SHADER: ShaderDef = ShaderDef {
    name: "ingest",
    source: include_str!("../../shaders/ingest.wgsl"),
    includes: &[],
    entry_points: &[EntryPoint::tiled("from_bytes", &[Uniform, Storage, ReadOnly])],
};
/// Shader for texture frames.
pub const TEXTURE_SHADER: ShaderDef = ShaderDef {
    name: "ingest_texture",
    source: include_str!("../../shaders/ingest_texture.wgsl"),
    includes: &[],
    entry_points: &[EntryPoint::tiled("from_texture", &[Uniform, Storage, Texture])],
};

/// Uniform block of both ingest shaders; kept in sync with their `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct IngestUniform {
    width: u32,
    height: u32,
    rgba: u32,
    _pad: u32,
}

/// CPU twin of `from_bytes`: grey bytes to f32.
#[must_use]
pub fn ingest(frame: &GrayImage) -> FloatImage {
    frame.to_f32()
}

/// CPU twin of `from_bytes` into a caller-allocated image.
pub fn ingest_cpu(frame: &GrayImage, dst: &mut FloatImage) {
    dst.resize(frame.width(), frame.height());
    for (d, &s) in dst.data_mut().iter_mut().zip(frame.data()) {
        *d = f32::from(s);
    }
}

/// CPU twin of `from_texture` for Rgba8Unorm: `rgba` holds 4 bytes per pixel, row-major.
pub fn ingest_texture_cpu(rgba: &[u8], width: usize, height: usize) -> Result<FloatImage> {
    if rgba.len() != width * height * 4 {
        return Err(Error::Size(format!("{} RGBA bytes for {width}x{height}", rgba.len())));
    }
    FloatImage::from_vec(width, height, rgba.chunks_exact(4).map(|p| luma(p[0], p[1], p[2])).collect())
}

/// Bytes of `frame` packed four to a u32 word (zero-padded), as `from_bytes` reads them.
#[must_use]
pub(crate) fn pack_bytes(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks(4)
        .map(|c| {
            let mut w = [0u8; 4];
            w[..c.len()].copy_from_slice(c);
            u32::from_le_bytes(w)
        })
        .collect()
}

/// Record `from_bytes`: `packed` (a storage buffer of packed bytes) into `dst`.
pub(crate) fn encode(rec: &mut Recorder<'_>, packed: &wgpu::Buffer, dst: &GpuImage) -> Result<()> {
    let (w, h) = (dst.width(), dst.height());
    let u = IngestUniform { width: w as u32, height: h as u32, rgba: 0, _pad: 0 };
    rec.dispatch(&SHADER, "from_bytes", &u, &[&dst.buffer, packed], workgroups_2d(w, h))
}

/// Record `from_texture`: a texture of the same size as `dst` into `dst`.
pub(crate) fn encode_texture(rec: &mut Recorder<'_>, texture: &wgpu::Texture, dst: &GpuImage) -> Result<()> {
    let rgba = match texture.format() {
        wgpu::TextureFormat::R8Unorm => 0,
        wgpu::TextureFormat::Rgba8Unorm => 1,
        f => return Err(Error::Parameter(format!("texture format {f:?}: pipetrack takes R8Unorm or Rgba8Unorm"))),
    };
    let (w, h) = (dst.width(), dst.height());
    if (texture.width() as usize, texture.height() as usize) != (w, h) {
        return Err(Error::Size(format!("texture {}x{} for a {w}x{h} frame", texture.width(), texture.height())));
    }
    if !texture.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING) {
        return Err(Error::Parameter("the frame texture needs TextureUsages::TEXTURE_BINDING".into()));
    }
    let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
    let u = IngestUniform { width: w as u32, height: h as u32, rgba, _pad: 0 };
    rec.dispatch_with(
        &TEXTURE_SHADER,
        "from_texture",
        &u,
        &[dst.buffer.as_entire_binding(), wgpu::BindingResource::TextureView(&view)],
        workgroups_2d(w, h),
    )
}

/// GPU: ingest grey bytes and read the f32 image back (tests and benches).
pub fn ingest_gpu(ctx: &GpuContext, frame: &GrayImage) -> Result<FloatImage> {
    use wgpu::util::DeviceExt;
    let packed = pack_bytes(frame.data());
    let words = if packed.is_empty() { vec![0u32] } else { packed };
    let buf = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("ingest.packed"),
        contents: bytemuck::cast_slice(&words),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let dst = GpuImage::new(ctx, frame.width(), frame.height(), "ingest.dst");
    run_once(ctx, |rec| encode(rec, &buf, &dst))?;
    dst.download(ctx)
}

/// GPU: ingest a texture and read the f32 image back (tests and embedding checks).
pub fn ingest_texture_gpu(ctx: &GpuContext, texture: &wgpu::Texture) -> Result<FloatImage> {
    let dst = GpuImage::new(ctx, texture.width() as usize, texture.height() as usize, "ingest.dst");
    run_once(ctx, |rec| encode_texture(rec, texture, &dst))?;
    dst.download(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_pack_little_endian_with_zero_padding() {
        assert_eq!(pack_bytes(&[1, 2, 3, 4, 5]), vec![0x0403_0201, 5]);
    }

    #[test]
    fn rgba_luma_uses_bt601_weights() {
        let img = ingest_texture_cpu(&[255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255], 3, 1).unwrap();
        assert!((img.get(0, 0) - 76.245).abs() < 1e-3);
        assert!((img.get(1, 0) - 149.685).abs() < 1e-3);
        assert!((img.get(2, 0) - 29.07).abs() < 1e-3);
    }
}
