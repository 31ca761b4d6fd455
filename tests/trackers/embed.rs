//! The embedding path: a caller's own device checked by
//! `GpuContext::from_device`, and `examples/embed.rs` run as a test — frames
//! rendered with wgpu, tracked through textures on the GPU and as bytes on
//! the CPU, with equal results.
use crate::common;

#[path = "../../examples/embed.rs"]
#[allow(dead_code)]
mod example;

use pipetrack::{CpuBackend, Error, Frame, GpuContext, MotionEdgeParams, MotionEdgeTracker, Status, track_step};

#[test]
fn texture_path_and_byte_path_give_equal_results() {
    let Some((_, _guard)) = common::gpu("texture_path_and_byte_path_give_equal_results") else { return };
    let (device, queue, _) = example::create_device().expect("the example's device");
    let outcome = example::run(&device, &queue).expect("the example runs");
    assert_eq!(outcome.gpu.len(), example::FRAMES);
    assert_eq!(outcome.cpu.len(), example::FRAMES);
    assert_eq!(outcome.differing_frames(), Vec::<usize>::new(), "texture and byte paths differ");
    let tracked = outcome.gpu.iter().filter(|r| r.status == Status::Tracking).count();
    assert_eq!(tracked, example::FRAMES, "every frame of the swinging plate is tracked");
    let error = outcome.mean_corner_error();
    assert!(error < 1.0, "mean corner error {error:.3} px");
}

#[test]
fn from_device_names_the_limit_a_device_lacks() {
    let Some((_, _guard)) = common::gpu("from_device_names_the_limit_a_device_lacks") else { return };
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::VULKAN;
    let instance = wgpu::Instance::new(desc);
    let adapter =
        pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default())).expect("adapter");
    // wgpu's downlevel defaults allow 4 storage buffers per stage; pipetrack needs 8.
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("too small"),
        required_limits: wgpu::Limits::downlevel_defaults(),
        ..Default::default()
    }))
    .expect("device");
    let err = GpuContext::from_device(device, queue).unwrap_err();
    assert!(
        matches!(err, Error::Limit { limit: "max_storage_buffers_per_shader_stage", needed: 8, available: 4 }),
        "{err:?}"
    );
    assert!(err.to_string().contains("max_storage_buffers_per_shader_stage"), "{err}");
}

#[test]
fn a_texture_on_the_cpu_backend_is_an_error() {
    let Some((ctx, _guard)) = common::gpu("a_texture_on_the_cpu_backend_is_an_error") else { return };
    let texture = common::empty_texture(ctx, 8, 8, wgpu::TextureFormat::Rgba8Unorm);
    let corners = vec![[1.0, 1.0], [6.0, 1.0], [6.0, 6.0], [1.0, 6.0]];
    let mut tracker = MotionEdgeTracker::new(corners, example::EDGES.to_vec(), MotionEdgeParams::default()).unwrap();
    let err = track_step(&mut tracker, &mut CpuBackend::new(), 0, Frame::Texture(&texture)).unwrap_err();
    assert!(matches!(err, Error::TextureOnCpu { .. }), "{err:?}");
}
