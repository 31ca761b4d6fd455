//! GPU/CPU parity of the ingest shaders: `shaders/ingest.wgsl` (packed bytes)
//! and `shaders/ingest_texture.wgsl` (textures of every format in
//! `ingest::TEXTURE_FORMATS`).
use crate::common;
use crate::per_size;

use pipetrack::early::ingest;
use pipetrack::testimage::natural;

use common::texture;

fn parity_ingest_bytes_exact(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_ingest_bytes_exact/{w}x{h}")) else { return };
    let frame = natural(w, h, 7);
    let cpu = ingest::ingest(&frame);
    let gpu = ingest::ingest_gpu(ctx, &frame).unwrap();
    common::assert_equal(&format!("ingest/{w}x{h}"), &cpu, &gpu);
}
per_size!(parity_ingest_bytes_exact);

/// Texels of `format` whose R, G, B bytes are `r`, `g`, `b` (alpha 255 in
/// colour formats; the red byte alone for R8Unorm).
fn texels(format: wgpu::TextureFormat, r: &[u8], g: &[u8], b: &[u8]) -> Vec<u8> {
    use wgpu::TextureFormat as F;
    (0..r.len())
        .flat_map(|i| match format {
            F::R8Unorm => vec![r[i]],
            F::Bgra8Unorm | F::Bgra8UnormSrgb => vec![b[i], g[i], r[i], 255],
            _ => vec![r[i], g[i], b[i], 255],
        })
        .collect()
}

/// A test image: width, height, and the R, G, B bytes of its pixels.
type Channels = (usize, usize, Vec<u8>, Vec<u8>, Vec<u8>);

/// One texture of each accepted format ingests to exactly the grey image its
/// bytes give on the CPU: natural images in every channel at every parity
/// size, and a ramp through all 256 levels of each channel (where sRGB
/// decoding and re-encoding must give every byte back).
#[test]
fn parity_ingest_texture_every_format_exact() {
    let Some((ctx, _g)) = common::gpu("parity_ingest_texture_every_format_exact") else { return };
    let ramp = |f: fn(usize) -> u8| -> Vec<u8> { (0..256 * 3).map(f).collect() };
    let (ramp_r, ramp_g, ramp_b) =
        (ramp(|i| (i % 256) as u8), ramp(|i| 255 - (i % 256) as u8), ramp(|i| ((i % 256) * 7 + i / 256 * 50) as u8));
    for format in ingest::TEXTURE_FORMATS {
        let mut cases: Vec<Channels> = common::PARITY_SIZES
            .iter()
            .map(|&(w, h)| {
                let (r, g, b) = (natural(w, h, 1), natural(w, h, 2), natural(w, h, 3));
                (w, h, r.data().to_vec(), g.data().to_vec(), b.data().to_vec())
            })
            .collect();
        cases.push((256, 3, ramp_r.clone(), ramp_g.clone(), ramp_b.clone()));
        for (w, h, r, g, b) in cases {
            let bytes = texels(format, &r, &g, &b);
            let t = texture(ctx, w, h, format, &bytes);
            let gpu = ingest::ingest_texture_gpu(ctx, &t).unwrap();
            let cpu = ingest::ingest_texture_cpu(&bytes, w, h, format).unwrap();
            common::assert_equal(&format!("ingest_texture/{format:?}/{w}x{h}"), &cpu, &gpu);
            // The texture path equals the byte path of the same pixels.
            let gray = ingest::gray_from_texels(&bytes, w, h, format).unwrap();
            common::assert_equal(
                &format!("ingest_texture/{format:?}/{w}x{h}/bytes"),
                &ingest::ingest_gpu(ctx, &gray).unwrap(),
                &gpu,
            );
        }
    }
}

#[test]
fn ingest_texture_rejects_other_formats() {
    let Some((ctx, _g)) = common::gpu("ingest_texture_rejects_other_formats") else { return };
    let t = texture(ctx, 2, 2, wgpu::TextureFormat::Rgba8Uint, &[0u8; 16]);
    let err = ingest::ingest_texture_gpu(ctx, &t).unwrap_err();
    assert!(matches!(err, pipetrack::Error::TextureFormat(wgpu::TextureFormat::Rgba8Uint)), "{err:?}");
    assert!(err.to_string().contains("Rgba8Uint is not supported"), "{err}");
}

#[test]
fn ingest_texture_needs_texture_binding_usage() {
    let Some((ctx, _g)) = common::gpu("ingest_texture_needs_texture_binding_usage") else { return };
    let t = ctx.device().create_texture(&wgpu::TextureDescriptor {
        label: Some("copy-only frame"),
        size: wgpu::Extent3d { width: 4, height: 4, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let err = ingest::ingest_texture_gpu(ctx, &t).unwrap_err();
    assert!(err.to_string().contains("TEXTURE_BINDING"), "{err}");
}
