//! Embedding pipetrack in your own wgpu program: you create the device and
//! queue, you own the frame textures, pipetrack records its early vision on
//! your device and hands back compact feature lists.
//!
//! Run: `cargo run --example embed`

use anyhow::{Context, Result};
use pipetrack::backend::{CpuBackend, EarlyVision, FrameRequest, GpuBackend};
use pipetrack::testimage::natural;

fn main() -> Result<()> {
    // 1. Your program's own wgpu setup.
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::VULKAN;
    let instance = wgpu::Instance::new(desc);
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
        .context("no Vulkan adapter (install mesa-vulkan-drivers for lavapipe)")?;
    let mut limits = wgpu::Limits::downlevel_defaults();
    limits.max_storage_buffers_per_shader_stage = 8;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("my app"),
        required_limits: limits,
        ..Default::default()
    }))?;
    println!("adapter: {}", adapter.get_info().name);

    // 2. Hand pipetrack your device and queue.
    let ctx = pipetrack::GpuContext::from_device(device.clone(), queue.clone())?;
    let mut gpu = GpuBackend::new(ctx);
    let mut cpu = CpuBackend::new();

    // 3. Frames that live in your textures (R8Unorm here; Rgba8Unorm works too).
    let (w, h) = (320usize, 240usize);
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("my frame"),
        size: wgpu::Extent3d { width: w as u32, height: h as u32, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let request = FrameRequest::full_chain(w, h);
    let scene = natural(w + 4, h, 5);
    for k in 0..3 {
        // The frame moves one pixel to the left each time.
        let frame = pipetrack::GrayImage::from_fn(w, h, |x, y| scene.get(x + k, y));
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            frame.data(),
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w as u32), rows_per_image: Some(h as u32) },
            wgpu::Extent3d { width: w as u32, height: h as u32, depth_or_array_layers: 1 },
        );
        let from_gpu = gpu.process_texture(&texture, &request)?;
        let from_cpu = cpu.process(&frame, &request)?;
        let count = |l: &Option<Vec<pipetrack::early::Feature>>| l.as_ref().map_or(0, Vec::len);
        println!(
            "frame {k}: motion {} px, edges {} px, zero crossings {} px (CPU: {}, {}, {}); stats {:?}",
            count(&from_gpu.motion),
            count(&from_gpu.edges),
            count(&from_gpu.zero_crossings),
            count(&from_cpu.motion),
            count(&from_cpu.edges),
            count(&from_cpu.zero_crossings),
            gpu.last_frame_stats()
        );
        anyhow::ensure!(from_gpu.edges == from_cpu.edges, "GPU and CPU edge lists differ");
    }
    Ok(())
}
