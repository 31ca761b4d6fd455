//! The two backends give the same frame results: the whole chain (motion,
//! edges, zero crossings, pyramids) over a short moving sequence, through
//! `GpuBackend` (one submission per frame, slot ring, pipelined stream,
//! texture input) and `CpuBackend`.
use crate::common;

use pipetrack::GrayImage;
use pipetrack::backend::{CpuBackend, EarlyVision, FrameFeatures, FrameRequest, GpuBackend, ListSpec, Pyramids};
use pipetrack::early::{Feature, Window};
use pipetrack::testimage::natural;

/// Angle and magnitude tolerance of listed features (Sobel/LoG rounding).
const FEATURE_ATOL: f32 = 1e-3;

fn sequence(w: usize, h: usize, n: usize) -> Vec<GrayImage> {
    let scene = natural(w + 3 * n, h, 99);
    (0..n).map(|k| GrayImage::from_fn(w, h, |x, y| scene.get(x + 3 * k, y))).collect()
}

fn same_lists(what: &str, cpu: &[Feature], gpu: &[Feature]) {
    assert_eq!(cpu.len(), gpu.len(), "{what}: list lengths differ");
    for (i, (c, g)) in cpu.iter().zip(gpu).enumerate() {
        assert_eq!((c.x, c.y), (g.x, g.y), "{what}: element {i} at a different pixel");
        let dt = (c.theta - g.theta).abs();
        let dt = dt.min((dt - std::f32::consts::TAU).abs());
        assert!(dt <= FEATURE_ATOL, "{what}: element {i} theta {} vs {}", c.theta, g.theta);
        assert!(
            (c.magnitude - g.magnitude).abs() <= FEATURE_ATOL * c.magnitude.abs().max(1.0),
            "{what}: element {i} magnitude"
        );
    }
}

fn same_features(what: &str, cpu: &FrameFeatures, gpu: &FrameFeatures) {
    for (name, c, g) in [
        ("motion", &cpu.motion, &gpu.motion),
        ("edges", &cpu.edges, &gpu.edges),
        ("zero_crossings", &cpu.zero_crossings, &gpu.zero_crossings),
    ] {
        assert_eq!(c.is_some(), g.is_some(), "{what}/{name}: presence differs");
        if let (Some(c), Some(g)) = (c, g) {
            same_lists(&format!("{what}/{name}"), c, g);
        }
    }
    assert_eq!(cpu.pyramids.is_some(), gpu.pyramids.is_some());
    if let (Some((cc, ce)), Some((gc, ge))) = (&cpu.pyramids, &gpu.pyramids) {
        assert_eq!(cc, gc, "{what}: CPF hierarchies differ");
        for (c, g) in ce.horizontal.iter().zip(&ge.horizontal).chain(ce.vertical.iter().zip(&ge.vertical)) {
            common::assert_close(&format!("{what}/edge_pyramid"), c, g, 1e-3, 1e-5);
        }
    }
}

#[test]
fn gpu_and_cpu_backends_agree_on_the_full_chain() {
    let Some((ctx, _g)) = common::gpu("gpu_and_cpu_backends_agree_on_the_full_chain") else { return };
    for (w, h) in [(257, 243), (64, 48), (2, 3)] {
        let frames = sequence(w, h, 4);
        let mut request = FrameRequest::full_chain(w, h);
        request.pyramids = Pyramids::Return;
        // An off-centre window and a cap on one list, as trackers ask.
        request.edges.as_mut().unwrap().list =
            ListSpec { window: Window { x0: 3, y0: 5, x1: w as u32 / 2 + 1, y1: h as u32 }, cap: Some(300), seed: 4 };
        let mut cpu = CpuBackend::new();
        let mut gpu = GpuBackend::new(ctx.clone());
        for (i, f) in frames.iter().enumerate() {
            let c = cpu.process(f, &request).unwrap();
            let g = gpu.process(f, &request).unwrap();
            if i == 0 {
                assert_eq!(c.motion.as_deref(), Some(&[][..]), "no motion without a previous frame");
            } else if w > 8 {
                assert!(!c.motion.as_ref().unwrap().is_empty(), "a moving scene has motion pixels");
            }
            same_features(&format!("{w}x{h}/frame{i}"), &c, &g);
        }
        let stats = gpu.last_frame_stats();
        assert!(stats.dispatches > 0 && stats.bytes_uploaded == ((w * h).div_ceil(4) * 4) as u64, "{stats:?}");
    }
}

#[test]
fn pipelined_stream_equals_frame_by_frame() {
    let Some((ctx, _g)) = common::gpu("pipelined_stream_equals_frame_by_frame") else { return };
    let (w, h) = (160, 120);
    let frames = sequence(w, h, 7);
    let mut request = FrameRequest::full_chain(w, h);
    request.pyramids = Pyramids::Return;
    let mut one = GpuBackend::new(ctx.clone());
    let expected: Vec<FrameFeatures> = frames.iter().map(|f| one.process(f, &request).unwrap()).collect();
    let mut streamed = Vec::new();
    GpuBackend::new(ctx.clone()).process_stream(&frames, &request, |i, f| streamed.push((i, f))).unwrap();
    assert_eq!(streamed.len(), frames.len());
    for (i, f) in streamed {
        assert_eq!(f, expected[i], "frame {i} differs when pipelined");
    }
}

#[test]
fn texture_frames_equal_byte_frames() {
    let Some((ctx, _g)) = common::gpu("texture_frames_equal_byte_frames") else { return };
    let (w, h) = (97, 61);
    let frames = sequence(w, h, 3);
    let request = FrameRequest::full_chain(w, h);
    let size = wgpu::Extent3d { width: w as u32, height: h as u32, depth_or_array_layers: 1 };
    let texture = ctx.device().create_texture(&wgpu::TextureDescriptor {
        label: Some("frame"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let mut by_bytes = GpuBackend::new(ctx.clone());
    let mut by_texture = GpuBackend::new(ctx.clone());
    for f in &frames {
        ctx.queue().write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            f.data(),
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w as u32), rows_per_image: Some(h as u32) },
            size,
        );
        let a = by_bytes.process(f, &request).unwrap();
        let b = by_texture.process_texture(&texture, &request).unwrap();
        assert_eq!(a, b);
        assert_eq!(by_texture.last_frame_stats().bytes_uploaded, 0);
    }
}

#[test]
fn too_many_frames_in_flight_is_an_error_not_a_hang() {
    let Some((ctx, _g)) = common::gpu("too_many_frames_in_flight_is_an_error_not_a_hang") else { return };
    let frames = sequence(16, 16, 4);
    let request = FrameRequest::full_chain(16, 16);
    let mut gpu = GpuBackend::new(ctx.clone());
    let a = gpu.submit(&frames[0], &request).unwrap();
    let b = gpu.submit(&frames[1], &request).unwrap();
    let c = gpu.submit(&frames[2], &request).unwrap();
    assert!(gpu.submit(&frames[3], &request).is_err());
    for t in [a, b, c] {
        gpu.finish(t).unwrap();
    }
}
