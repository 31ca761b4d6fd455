//! Ingest: a frame (8-bit grey bytes, or a caller's texture in one of
//! [`TEXTURE_FORMATS`]) becomes the f32 grey image, 0..255 scale, that every
//! stage reads.
//!
//! # What a texture's grey level is
//!
//! A texture frame gives exactly the grey image its bytes give through the
//! byte path: [`gray_from_texels`] turns the texture's stored bytes into the
//! [`GrayImage`] whose ingest equals the texture's ingest, pixel for pixel.
//!
//! - `R8Unorm`: the byte itself.
//! - `Rgba8Unorm`, `Bgra8Unorm`: BT.601 luma of the R, G, B bytes
//!   ([`luma`]), alpha ignored.
//! - `Rgba8UnormSrgb`, `Bgra8UnormSrgb`: the same luma of the *stored*
//!   (sRGB-encoded) bytes. The GPU samples these formats linearised, so the
//!   shader re-encodes each channel to sRGB before the luma weights. The grey
//!   level is then the luma Y′ of gamma-encoded values, as for a PNG file read
//!   with [`crate::io::decode_gray`], not linear luminance; the same pixels
//!   give the same grey level whether they sit in an sRGB or a unorm texture.

use bytemuck::{Pod, Zeroable};

use super::Window;
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
    overrides: &[],
};
/// Shader for texture frames.
pub const TEXTURE_SHADER: ShaderDef = ShaderDef {
    name: "ingest_texture",
    source: include_str!("../../shaders/ingest_texture.wgsl"),
    includes: &[],
    entry_points: &[EntryPoint::tiled("from_texture", &[Uniform, Storage, Texture])],
    overrides: &[],
};

/// The texture formats [`ingest_texture_gpu`] and
/// [`crate::backend::GpuBackend::submit_texture`] read.
pub const TEXTURE_FORMATS: [wgpu::TextureFormat; 5] = [
    wgpu::TextureFormat::R8Unorm,
    wgpu::TextureFormat::Rgba8Unorm,
    wgpu::TextureFormat::Bgra8Unorm,
    wgpu::TextureFormat::Rgba8UnormSrgb,
    wgpu::TextureFormat::Bgra8UnormSrgb,
];

/// Uniform block of both ingest shaders; kept in sync with their `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct IngestUniform {
    width: u32,
    height: u32,
    /// A [`TexelKind`] for `from_texture`; unused by `from_bytes`.
    kind: u32,
    _pad: u32,
}

/// How `from_texture` turns a texel into bytes; kept in sync with the
/// shader's `KIND_*` constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum TexelKind {
    /// One grey channel (`R8Unorm`).
    Gray = 0,
    /// Colour, channels stored as unorm bytes.
    Colour = 1,
    /// Colour, channels stored sRGB-encoded (sampled linearised).
    SrgbColour = 2,
}

/// The [`TexelKind`] of a supported format, and where R, G and B sit in a
/// texel's bytes; an unsupported format is [`Error::TextureFormat`].
fn texel_layout(format: wgpu::TextureFormat) -> Result<(TexelKind, [usize; 3])> {
    use wgpu::TextureFormat as F;
    Ok(match format {
        F::R8Unorm => (TexelKind::Gray, [0, 0, 0]),
        F::Rgba8Unorm => (TexelKind::Colour, [0, 1, 2]),
        F::Bgra8Unorm => (TexelKind::Colour, [2, 1, 0]),
        F::Rgba8UnormSrgb => (TexelKind::SrgbColour, [0, 1, 2]),
        F::Bgra8UnormSrgb => (TexelKind::SrgbColour, [2, 1, 0]),
        other => return Err(Error::TextureFormat(other)),
    })
}

/// Bytes per texel of `format`, one of [`TEXTURE_FORMATS`] (1 or 4); any
/// other format is [`Error::TextureFormat`].
pub fn texel_bytes(format: wgpu::TextureFormat) -> Result<usize> {
    Ok(match texel_layout(format)?.0 {
        TexelKind::Gray => 1,
        TexelKind::Colour | TexelKind::SrgbColour => 4,
    })
}

/// CPU twin of `from_bytes`: grey bytes to f32.
#[must_use]
pub fn ingest(frame: &GrayImage) -> FloatImage {
    frame.to_f32()
}

/// CPU twin of `from_bytes` into a caller-allocated image.
pub fn ingest_cpu(frame: &GrayImage, dst: &mut FloatImage) {
    dst.resize(frame.width(), frame.height());
    grey_to_f32(frame.data(), dst.data_mut());
}

/// [`ingest_cpu`] of `part` of `frame` alone, into `dst` resized to the
/// part: the values the whole frame's ingest holds there.
pub fn ingest_part_cpu(frame: &GrayImage, part: Window, dst: &mut FloatImage) {
    let part = part.clipped(frame.width(), frame.height());
    let (x0, x1) = (part.x0 as usize, part.x1 as usize);
    dst.resize(x1 - x0, part.height() as usize);
    if x1 == x0 {
        return;
    }
    for (y, row) in (part.y0 as usize..part.y1 as usize).zip(dst.data_mut().chunks_mut(x1 - x0)) {
        grey_to_f32(&frame.row(y)[x0..x1], row);
    }
}

fn grey_to_f32(src: &[u8], dst: &mut [f32]) {
    for (d, &s) in dst.iter_mut().zip(src) {
        *d = f32::from(s);
    }
}

/// The grey frame that a `width`×`height` texture of `format` holding
/// `texels` (its stored bytes, rows tightly packed, [`texel_bytes`] per
/// texel) gives: the byte-path twin of `from_texture` (see the module doc).
/// Feeding the result to the byte path gives what the texture path gives.
pub fn gray_from_texels(texels: &[u8], width: usize, height: usize, format: wgpu::TextureFormat) -> Result<GrayImage> {
    let (kind, [r, g, b]) = texel_layout(format)?;
    let size = texel_bytes(format)?;
    if texels.len() != width * height * size {
        return Err(Error::Size(format!("{} bytes of {format:?} texels for {width}x{height}", texels.len())));
    }
    let data = match kind {
        TexelKind::Gray => texels.to_vec(),
        TexelKind::Colour | TexelKind::SrgbColour => {
            texels.chunks_exact(size).map(|p| luma(p[r], p[g], p[b])).collect()
        }
    };
    GrayImage::from_vec(width, height, data)
}

/// CPU twin of [`ingest_texture_gpu`]: the f32 grey image of a texture's
/// stored bytes (arguments as [`gray_from_texels`]).
pub fn ingest_texture_cpu(
    texels: &[u8],
    width: usize,
    height: usize,
    format: wgpu::TextureFormat,
) -> Result<FloatImage> {
    Ok(ingest(&gray_from_texels(texels, width, height, format)?))
}

/// Queue the write of `bytes` into `buffer` as `from_bytes` reads them:
/// four to a u32 word, the first in the low byte (so the bytes go as they
/// are), the last word zero-padded. Returns the bytes written.
pub(crate) fn write_bytes(ctx: &GpuContext, buffer: &wgpu::Buffer, bytes: &[u8]) -> usize {
    write_bytes_at(ctx, buffer, 0, bytes)
}

/// [`write_bytes`] from byte `offset` (a multiple of 4) of `buffer`.
pub(crate) fn write_bytes_at(ctx: &GpuContext, buffer: &wgpu::Buffer, offset: u64, bytes: &[u8]) -> usize {
    let whole = bytes.len() / 4 * 4;
    if whole > 0 {
        ctx.queue.write_buffer(buffer, offset, &bytes[..whole]);
    }
    let tail = &bytes[whole..];
    if !tail.is_empty() {
        let mut word = [0u8; 4];
        word[..tail.len()].copy_from_slice(tail);
        ctx.queue.write_buffer(buffer, offset + whole as u64, &word);
    }
    bytes.len().div_ceil(4) * 4
}

/// Words of packed bytes one layer of a `width`×`height` frame takes.
#[must_use]
pub(crate) fn packed_words(width: usize, height: usize) -> usize {
    (width * height).div_ceil(4)
}

/// Record `from_bytes`: `packed` (a storage buffer of packed bytes, each
/// layer's frame from word `layer · packed_words`) into every layer of `dst`.
pub(crate) fn encode(rec: &mut Recorder<'_>, packed: &wgpu::Buffer, dst: &GpuImage) -> Result<()> {
    let (w, h) = (dst.width(), dst.height());
    let u = IngestUniform { width: w as u32, height: h as u32, kind: 0, _pad: 0 };
    rec.dispatch(&SHADER, "from_bytes", &u, &[&dst.buffer, packed], dst.grid())
}

/// Check that `texture` can be read as a frame: a supported format, a plain
/// 2-D single-sampled texture with `TEXTURE_BINDING` usage. Returns its kind.
fn check_texture(texture: &wgpu::Texture) -> Result<TexelKind> {
    let (kind, _) = texel_layout(texture.format())?;
    if !texture.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING) {
        return Err(Error::Texture("it needs TextureUsages::TEXTURE_BINDING".into()));
    }
    if texture.dimension() != wgpu::TextureDimension::D2 {
        return Err(Error::Texture(format!("it is {:?}; frames are D2 textures", texture.dimension())));
    }
    if texture.sample_count() != 1 {
        return Err(Error::Texture(format!("it has {} samples per pixel; resolve it first", texture.sample_count())));
    }
    Ok(kind)
}

/// Record `from_texture`: a texture of the same size as `dst` into `dst`
/// (mip level 0 and array layer 0 of it).
pub(crate) fn encode_texture(rec: &mut Recorder<'_>, texture: &wgpu::Texture, dst: &GpuImage) -> Result<()> {
    let kind = check_texture(texture)?;
    let (w, h) = (dst.width(), dst.height());
    if (texture.width() as usize, texture.height() as usize) != (w, h) {
        return Err(Error::Size(format!("texture {}x{} for a {w}x{h} frame", texture.width(), texture.height())));
    }
    // A texture wgpu refuses to view (one destroyed already) is an error
    // here, caught in a scope of its own, not a panic of wgpu's default
    // handler or an invalid submission later.
    let scope = rec.context().device.push_error_scope(wgpu::ErrorFilter::Validation);
    let view = texture.create_view(&wgpu::TextureViewDescriptor {
        label: Some("pipetrack.ingest_texture.frame"),
        dimension: Some(wgpu::TextureViewDimension::D2),
        base_mip_level: 0,
        mip_level_count: Some(1),
        base_array_layer: 0,
        array_layer_count: Some(1),
        ..Default::default()
    });
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(Error::Texture(format!("wgpu cannot view it: {}", crate::bounds::one_line(&e.to_string()))));
    }
    let u = IngestUniform { width: w as u32, height: h as u32, kind: kind as u32, _pad: 0 };
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
    let buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("ingest.packed"),
        size: frame.data().len().div_ceil(4).max(1) as u64 * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    write_bytes(ctx, &buf, frame.data());
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
    fn rgba_luma_uses_bt601_weights_rounded() {
        // 0.299·255 = 76.245, 0.587·255 = 149.685, 0.114·255 = 29.07.
        let img = ingest_texture_cpu(
            &[255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255],
            3,
            1,
            wgpu::TextureFormat::Rgba8Unorm,
        )
        .unwrap();
        assert_eq!(img.data(), &[76.0, 150.0, 29.0]);
    }

    #[test]
    fn luma_rounds_halves_up_and_keeps_grey() {
        // 299·4 + 587·40 + 114·16 = 26500: exactly 26.5.
        assert_eq!(luma(4, 40, 16), 27);
        for v in [0, 1, 127, 254, 255] {
            assert_eq!(luma(v, v, v), v);
        }
    }

    #[test]
    fn bgra_and_srgb_texels_give_the_grey_of_their_bytes() {
        use wgpu::TextureFormat as F;
        let rgba = [10, 200, 30, 255, 255, 0, 0, 7];
        let bgra = [30, 200, 10, 255, 0, 0, 255, 7];
        let expected = [luma(10, 200, 30), luma(255, 0, 0)];
        for (format, texels) in
            [(F::Rgba8Unorm, rgba), (F::Bgra8Unorm, bgra), (F::Rgba8UnormSrgb, rgba), (F::Bgra8UnormSrgb, bgra)]
        {
            assert_eq!(gray_from_texels(&texels, 2, 1, format).unwrap().data(), &expected, "{format:?}");
        }
        assert_eq!(gray_from_texels(&[9, 8], 1, 2, F::R8Unorm).unwrap().data(), &[9, 8]);
    }

    #[test]
    fn other_formats_and_wrong_lengths_are_errors() {
        let err = gray_from_texels(&[0; 4], 1, 1, wgpu::TextureFormat::Rgba8Uint).unwrap_err();
        assert!(matches!(err, Error::TextureFormat(wgpu::TextureFormat::Rgba8Uint)), "{err:?}");
        assert!(err.to_string().contains("Rgba8UnormSrgb"), "{err}");
        assert!(matches!(gray_from_texels(&[0; 3], 1, 1, wgpu::TextureFormat::Rgba8Unorm), Err(Error::Size(_))));
        for f in TEXTURE_FORMATS {
            assert!(texel_bytes(f).is_ok(), "{f:?}");
        }
    }
}
