//! The embedding path: a caller's own device checked by
//! `GpuContext::from_device`, and `examples/embed.rs` run as a test — frames
//! rendered with wgpu, tracked through textures on the GPU and as bytes on
//! the CPU, with equal results.
use crate::common;

#[path = "../../examples/embed.rs"]
#[allow(dead_code)]
mod example;

use pipetrack::{
    CpuBackend, EarlyVision, Error, Frame, GpuContext, MotionEdgeParams, MotionEdgeTracker, Status, track_step,
};

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

/// A destroyed texture is an error naming what wgpu refused, not a panic,
/// and the backend takes the next good frame as before.
#[test]
fn a_destroyed_texture_is_an_error_and_the_run_goes_on() {
    let Some((ctx, _guard)) = common::gpu("a_destroyed_texture_is_an_error_and_the_run_goes_on") else { return };
    let good = common::empty_texture(ctx, 8, 8, wgpu::TextureFormat::Rgba8Unorm);
    let gone = common::empty_texture(ctx, 8, 8, wgpu::TextureFormat::Rgba8Unorm);
    gone.destroy();
    let corners = vec![[1.0, 1.0], [6.0, 1.0], [6.0, 6.0], [1.0, 6.0]];
    let mut tracker = MotionEdgeTracker::new(corners, example::EDGES.to_vec(), MotionEdgeParams::default()).unwrap();
    let mut backend = pipetrack::GpuBackend::new(ctx.clone());
    track_step(&mut tracker, &mut backend, 0, Frame::Texture(&good)).expect("a good texture");
    let err = track_step(&mut tracker, &mut backend, 1, Frame::Texture(&gone)).unwrap_err();
    assert!(matches!(err, Error::Texture(_)) && err.to_string().contains("destroyed"), "{err}");
    assert_eq!(err.to_string().lines().count(), 1, "{err}");
    track_step(&mut tracker, &mut backend, 2, Frame::Texture(&good)).expect("the next good texture");
}

/// `track_step` refuses a frame with no pixel, a frame of another size than
/// a camera tracker's camera, and a frame of another size than a
/// motion-edge run's first frame, each with [`Error::Size`] naming both
/// sizes; a tracker made with a camera that is wrong or a start that is
/// not finite is refused when made.
#[test]
fn trackers_refuse_frames_of_the_wrong_size_and_bad_starts() {
    use pipetrack::synth::boxes::{BoxOptions, render_box};
    use pipetrack::{GrayImage, LoweParams, LoweTracker};
    let seq = render_box(&BoxOptions { frames: 2, ..BoxOptions::default() }).expect("render");
    let (w, h) = seq.frames[0].size();
    let mut backend = CpuBackend::new();
    let mut lowe = LoweTracker::new(seq.camera, &seq.model, &seq.init, LoweParams::default()).unwrap();
    let small = GrayImage::new(w / 2, h / 2);
    let err = track_step(&mut lowe, &mut backend, 0, Frame::Gray(&small)).unwrap_err();
    let expected = format!("frame 0 is {}x{}, but the camera's image is {w}x{h}", w / 2, h / 2);
    assert!(matches!(err, Error::Size(_)) && err.to_string().contains(&expected), "{err}");
    let empty = GrayImage::new(0, 0);
    let err = track_step(&mut lowe, &mut backend, 0, Frame::Gray(&empty)).unwrap_err();
    assert!(err.to_string().contains("frame 0 is 0x0: a frame needs at least one pixel"), "{err}");
    track_step(&mut lowe, &mut backend, 0, Frame::Gray(&seq.frames[0])).expect("the camera's size");

    let corners = vec![[1.0, 1.0], [6.0, 1.0], [6.0, 6.0], [1.0, 6.0]];
    let mut edge =
        MotionEdgeTracker::new(corners.clone(), example::EDGES.to_vec(), MotionEdgeParams::default()).unwrap();
    backend.reset();
    track_step(&mut edge, &mut backend, 0, Frame::Gray(&GrayImage::new(32, 24))).expect("the first frame");
    let err = track_step(&mut edge, &mut backend, 1, Frame::Gray(&GrayImage::new(24, 32))).unwrap_err();
    assert!(err.to_string().contains("frame 1 is 24x32, but the sequence's first frame was 32x24"), "{err}");
    track_step(&mut edge, &mut backend, 1, Frame::Gray(&GrayImage::new(32, 24))).expect("the first frame's size");

    // A bow tie: the polygon's sides cross.
    let bow_tie = vec![corners[0], corners[2], corners[1], corners[3]];
    let err = MotionEdgeTracker::new(bow_tie, example::EDGES.to_vec(), MotionEdgeParams::default()).err().unwrap();
    assert!(err.to_string().contains("motion-edge: "), "{err}");
    let mut camera = seq.camera;
    camera.fx = f64::NAN;
    let err = LoweTracker::new(camera, &seq.model, &seq.init, LoweParams::default()).err().unwrap();
    assert!(err.to_string().contains("camera: fx = NaN"), "{err}");
    let mut init = seq.init.clone();
    init.pose.as_mut().unwrap().rotation[0] = f64::NAN;
    let err = LoweTracker::new(seq.camera, &seq.model, &init, LoweParams::default()).err().unwrap();
    assert!(err.to_string().contains("must be finite"), "{err}");

    use pipetrack::synth::textured_plane::{TexturedPlaneOptions, render_textured_plane};
    use pipetrack::{CondensationParams, CondensationTracker};
    let plane = render_textured_plane(&TexturedPlaneOptions { frames: 1, ..TexturedPlaneOptions::default() }).unwrap();
    let mut init = plane.init.clone();
    init.pose.as_mut().unwrap().rotation[0] = f64::NAN;
    let err = CondensationTracker::new(plane.camera, &plane.model, &init, CondensationParams::default()).err().unwrap();
    assert!(err.to_string().contains("must be finite"), "{err}");
    let mut camera = plane.camera;
    camera.width = 0;
    let err = CondensationTracker::new(camera, &plane.model, &plane.init, CondensationParams::default()).err().unwrap();
    assert!(err.to_string().contains("camera: image size 0x"), "{err}");
}

/// A program with its own frames (a live camera) reads the camera, model
/// and start from a sequence folder without frames, makes the tracker the
/// command line would, and tracks its frames one at a time; `open` still
/// asks for the frames.
#[test]
fn a_sequence_folder_without_frames_makes_a_tracker_for_a_live_camera() {
    use pipetrack::io::Sequence;
    use pipetrack::synth::boxes::{BoxOptions, render_box};
    let root = common::scratch("embed", "live");
    let seq = render_box(&BoxOptions { frames: 3, ..BoxOptions::default() }).expect("render");
    seq.write(root.path()).expect("written");
    std::fs::remove_dir_all(root.join("frames")).unwrap();
    let err = Sequence::open(root.path(), false).expect_err("open needs frames/");
    assert!(err.to_string().contains("frames"), "{err}");
    let files = Sequence::open_without_frames(root.path()).expect("camera, model and init");
    assert_eq!((files.frame_count(), files.frames().count()), (Some(0), 0));
    let mut tracker = pipetrack::track::run::make_tracker("lowe", &files, None).expect("lowe from the folder's files");
    let mut backend = CpuBackend::new();
    for (k, frame) in seq.frames.iter().enumerate() {
        let (_, line) = track_step(tracker.as_mut(), &mut backend, k, Frame::Gray(frame)).expect("a frame");
        assert_eq!(line.status, Status::Tracking, "frame {k}");
    }
}
