//! GPU/CPU parity of the ingest shaders: `shaders/ingest.wgsl` (packed bytes)
//! and `shaders/ingest_texture.wgsl` (R8Unorm / Rgba8Unorm textures).
mod common;

use pipetrack::GpuContext;
use pipetrack::early::ingest;
use pipetrack::testimage::natural;

/// Luma of RGBA: three products in f32; the GPU may fuse them (FMA).
const LUMA_ATOL: f32 = 1e-3;

fn texture(ctx: &GpuContext, w: usize, h: usize, format: wgpu::TextureFormat, bytes: &[u8]) -> wgpu::Texture {
    let size = wgpu::Extent3d { width: w as u32, height: h as u32, depth_or_array_layers: 1 };
    let t = ctx.device().create_texture(&wgpu::TextureDescriptor {
        label: Some("test frame"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let bpp = bytes.len() / (w * h);
    ctx.queue().write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: &t,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        bytes,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some((w * bpp) as u32),
            rows_per_image: Some(h as u32),
        },
        size,
    );
    t
}

#[test]
fn parity_ingest_bytes_exact() {
    let Some((ctx, _g)) = common::gpu("parity_ingest_bytes_exact") else { return };
    for &(w, h) in common::PARITY_SIZES {
        let frame = natural(w, h, 7);
        let cpu = ingest::ingest(&frame);
        let gpu = ingest::ingest_gpu(ctx, &frame).unwrap();
        common::assert_equal(&format!("ingest/{w}x{h}"), &cpu, &gpu);
    }
}

#[test]
fn parity_ingest_texture_r8_exact() {
    let Some((ctx, _g)) = common::gpu("parity_ingest_texture_r8_exact") else { return };
    for &(w, h) in common::PARITY_SIZES {
        let frame = natural(w, h, 8);
        let t = texture(ctx, w, h, wgpu::TextureFormat::R8Unorm, frame.data());
        let gpu = ingest::ingest_texture_gpu(ctx, &t).unwrap();
        common::assert_equal(&format!("ingest_texture/r8/{w}x{h}"), &ingest::ingest(&frame), &gpu);
    }
}

#[test]
fn parity_ingest_texture_rgba8_luma() {
    let Some((ctx, _g)) = common::gpu("parity_ingest_texture_rgba8_luma") else { return };
    for &(w, h) in common::PARITY_SIZES {
        let (r, g, b) = (natural(w, h, 1), natural(w, h, 2), natural(w, h, 3));
        let rgba: Vec<u8> = (0..w * h).flat_map(|i| [r.data()[i], g.data()[i], b.data()[i], 255]).collect();
        let t = texture(ctx, w, h, wgpu::TextureFormat::Rgba8Unorm, &rgba);
        let gpu = ingest::ingest_texture_gpu(ctx, &t).unwrap();
        let cpu = ingest::ingest_texture_cpu(&rgba, w, h).unwrap();
        common::assert_close(&format!("ingest_texture/rgba8/{w}x{h}"), &cpu, &gpu, LUMA_ATOL, 0.0);
    }
}

#[test]
fn ingest_texture_rejects_other_formats() {
    let Some((ctx, _g)) = common::gpu("ingest_texture_rejects_other_formats") else { return };
    let t = texture(ctx, 2, 2, wgpu::TextureFormat::Rgba8Uint, &[0u8; 16]);
    let err = ingest::ingest_texture_gpu(ctx, &t).unwrap_err();
    assert!(err.to_string().contains("R8Unorm or Rgba8Unorm"), "{err}");
}
