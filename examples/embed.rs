//! Embedding pipetrack in your own wgpu program: you create the device and
//! queue, you render the frames into your own textures, and pipetrack tracks
//! an object in them, handing back one `FrameResult` (corners, status) per
//! frame.
//!
//! The scene is a plate swinging on a pendulum over a shaded background,
//! drawn by a small render pipeline into `Rgba8Unorm` textures (4× MSAA,
//! resolved). The `motion-edge` tracker follows the plate's corners through
//! the texture path of pipetrack's per-frame loop. The example then reads the
//! frames back to bytes, runs the same loop on the CPU backend, and checks
//! that both paths give the same results apart from timing (exit status 1
//! when they do not).
//!
//! Run: `cargo run --example embed` (JSON Lines on stdout, summary on stderr).

use std::f64::consts::FRAC_PI_2;

use anyhow::{Context, Result, ensure};
use pipetrack::early::ingest::gray_from_texels;
use pipetrack::{
    CpuBackend, FrameResult, GpuBackend, GpuContext, GrayImage, MotionEdgeParams, MotionEdgeTracker, Status,
    track_frames,
};

/// Frame size, pixels.
pub const WIDTH: u32 = 256;
/// Frame height, pixels.
pub const HEIGHT: u32 = 192;
/// Frames rendered and tracked.
pub const FRAMES: usize = 40;
/// Format of the rendered frames (any of `pipetrack::TEXTURE_FORMATS` works).
pub const FRAME_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// MSAA samples of the render target (resolved into the frame texture).
const SAMPLES: u32 = 4;
/// Pivot of the pendulum in pipetrack's pixel coordinates ((0, 0) is the
/// centre of the top-left pixel, y down); above the image.
const PIVOT: [f64; 2] = [127.5, -60.0];
/// Distance from the pivot to the plate's centre, pixels.
const ARM: f64 = 170.0;
/// Half width and half height of the plate, pixels.
const HALF_PLATE: [f64; 2] = [25.0, 17.5];
/// Swing amplitude, radians (released from rest at frame 0).
const AMPLITUDE: f64 = 0.25;
/// Quarter period of the swing, frames (the plate passes the bottom
/// between frames 15 and 16, at about 4.5 px/frame at its outer corners).
const QUARTER_PERIOD: f64 = 15.5;
/// Corner pairs of the plate's outline (model-vertex order: top-left,
/// top-right, bottom-right, bottom-left at rest).
pub const EDGES: [[usize; 2]; 4] = [[0, 1], [1, 2], [2, 3], [3, 0]];

/// The plate's corners at frame `t` (pipetrack pixel coordinates): the plate
/// is fixed to the arm and turns with it, the arm at angle
/// `θ(t) = A·cos(ω t)` from the vertical.
#[must_use]
pub fn plate_corners(t: usize) -> [[f64; 2]; 4] {
    let theta = AMPLITUDE * (FRAC_PI_2 / QUARTER_PERIOD * t as f64).cos();
    let (s, c) = theta.sin_cos();
    let centre = [PIVOT[0] + ARM * s, PIVOT[1] + ARM * c];
    let [hu, hv] = HALF_PLATE;
    [[-hu, -hv], [hu, -hv], [hu, hv], [-hu, hv]].map(|[u, v]| [centre[0] + u * c + v * s, centre[1] - u * s + v * c])
}

/// Vertex of the scene: clip-space position, RGB colour.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Vertex {
    clip: [f32; 2],
    colour: [f32; 3],
}

impl Vertex {
    /// A vertex at pipetrack pixel coordinates `(x, y)`: pixel centres sit at
    /// integer coordinates there and at half-integers in wgpu's framebuffer.
    fn at(x: f64, y: f64, colour: [f32; 3]) -> Self {
        let ndc_x = (x + 0.5) / f64::from(WIDTH) * 2.0 - 1.0;
        let ndc_y = 1.0 - (y + 0.5) / f64::from(HEIGHT) * 2.0;
        Self { clip: [ndc_x as f32, ndc_y as f32], colour }
    }
}

/// Vertex and fragment shader of the scene: colour interpolated across each triangle.
const SCENE_WGSL: &str = r"
struct Out {
    @builtin(position) clip: vec4<f32>,
    @location(0) colour: vec3<f32>,
}

@vertex
fn vs(@location(0) clip: vec2<f32>, @location(1) colour: vec3<f32>) -> Out {
    return Out(vec4<f32>(clip, 0.0, 1.0), colour);
}

@fragment
fn fs(v: Out) -> @location(0) vec4<f32> {
    return vec4<f32>(v.colour, 1.0);
}
";

/// A wgpu device of your own, with the limits pipetrack asks for.
pub fn create_device() -> Result<(wgpu::Device, wgpu::Queue, String)> {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::VULKAN;
    let instance = wgpu::Instance::new(desc);
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
        .context("no Vulkan adapter (install mesa-vulkan-drivers for lavapipe)")?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("my app"),
        required_features: pipetrack::required_features(),
        required_limits: pipetrack::required_limits(),
        ..Default::default()
    }))?;
    Ok((device, queue, adapter.get_info().name))
}

/// The triangles of frame `t`: a background shaded from top to bottom, then the plate.
fn scene(t: usize) -> Vec<Vertex> {
    let (x0, y0, x1, y1) = (-0.5, -0.5, f64::from(WIDTH) - 0.5, f64::from(HEIGHT) - 0.5);
    let (top, bottom) = ([0.10, 0.16, 0.30], [0.22, 0.20, 0.16]);
    let mut vertices = vec![
        Vertex::at(x0, y0, top),
        Vertex::at(x1, y0, top),
        Vertex::at(x1, y1, bottom),
        Vertex::at(x0, y0, top),
        Vertex::at(x1, y1, bottom),
        Vertex::at(x0, y1, bottom),
    ];
    let p = plate_corners(t);
    let (warm, pale) = ([0.95, 0.62, 0.20], [0.98, 0.80, 0.45]);
    let colours = [pale, warm, warm, pale];
    for i in [0, 1, 2, 0, 2, 3] {
        vertices.push(Vertex::at(p[i][0], p[i][1], colours[i]));
    }
    vertices
}

/// Render `FRAMES` frames of the scene into textures of `FRAME_FORMAT`
/// (one submission per frame).
pub fn render_frames(device: &wgpu::Device, queue: &wgpu::Queue) -> Vec<wgpu::Texture> {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("scene"),
        source: wgpu::ShaderSource::Wgsl(SCENE_WGSL.into()),
    });
    let attributes = [
        wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x2, offset: 0, shader_location: 0 },
        wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x3, offset: 8, shader_location: 1 },
    ];
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("scene"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<Vertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &attributes,
            })],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: wgpu::MultisampleState { count: SAMPLES, ..Default::default() },
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[Some(FRAME_FORMAT.into())],
        }),
        multiview_mask: None,
        cache: None,
    });
    let size = wgpu::Extent3d { width: WIDTH, height: HEIGHT, depth_or_array_layers: 1 };
    let msaa = device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some("scene msaa"),
            size,
            mip_level_count: 1,
            sample_count: SAMPLES,
            dimension: wgpu::TextureDimension::D2,
            format: FRAME_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        })
        .create_view(&Default::default());
    let vertex_count = scene(0).len();
    let vertices = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("scene vertices"),
        size: (vertex_count * std::mem::size_of::<Vertex>()) as u64,
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    (0..FRAMES)
        .map(|t| {
            let frame = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("frame"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: FRAME_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            let view = frame.create_view(&Default::default());
            queue.write_buffer(&vertices, 0, bytemuck::cast_slice(&scene(t)));
            let mut encoder = device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("scene"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &msaa,
                        depth_slice: None,
                        resolve_target: Some(&view),
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Discard,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                pass.set_pipeline(&pipeline);
                pass.set_vertex_buffer(0, vertices.slice(..));
                pass.draw(0..vertex_count as u32, 0..1);
            }
            queue.submit([encoder.finish()]);
            frame
        })
        .collect()
}

/// Read a frame texture back to its bytes (rows tightly packed).
pub fn read_back(device: &wgpu::Device, queue: &wgpu::Queue, texture: &wgpu::Texture) -> Result<Vec<u8>> {
    let texel = pipetrack::early::ingest::texel_bytes(texture.format())? as u32;
    let (w, h) = (texture.width(), texture.height());
    let row = w * texel;
    let padded = row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: u64::from(padded * h),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(padded), rows_per_image: Some(h) },
        },
        texture.size(),
    );
    let index = queue.submit([encoder.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::Wait {
        submission_index: Some(index),
        timeout: Some(std::time::Duration::from_secs(30)),
    })?;
    rx.recv()??;
    let bytes = {
        let view = buffer.get_mapped_range(..)?;
        view.chunks(padded as usize).flat_map(|r| &r[..row as usize]).copied().collect()
    };
    buffer.unmap();
    Ok(bytes)
}

/// Track `frames` with a fresh motion-edge tracker started on the plate's
/// frame-0 corners; `F` is a texture or a grey image.
fn track<F: pipetrack::AsFrame>(
    backend: &mut dyn pipetrack::EarlyVision,
    frames: impl IntoIterator<Item = F>,
) -> Result<Vec<FrameResult>> {
    let mut tracker = MotionEdgeTracker::new(plate_corners(0).to_vec(), EDGES.to_vec(), MotionEdgeParams::default())?;
    let mut results = Vec::with_capacity(FRAMES);
    track_frames(&mut tracker, backend, frames.into_iter().map(Ok), (WIDTH as usize, HEIGHT as usize), |_, _, r| {
        results.push(r.clone());
        Ok(())
    })?;
    Ok(results)
}

/// What one run of the example found.
pub struct Outcome {
    /// Results of the texture path (GPU backend on the caller's device).
    pub gpu: Vec<FrameResult>,
    /// Results of the byte path (CPU backend on the frames read back).
    pub cpu: Vec<FrameResult>,
}

impl Outcome {
    /// Frames whose results differ between the two paths (timing aside).
    #[must_use]
    pub fn differing_frames(&self) -> Vec<usize> {
        let untimed = |r: &FrameResult| FrameResult { ms: 0.0, ..r.clone() };
        let mut differ: Vec<usize> =
            self.gpu.iter().zip(&self.cpu).filter(|(g, c)| untimed(g) != untimed(c)).map(|(g, _)| g.frame).collect();
        if self.gpu.len() != self.cpu.len() {
            differ.push(self.gpu.len().min(self.cpu.len()));
        }
        differ
    }

    /// Mean distance of the texture path's corners from the rendered ones, px.
    #[must_use]
    pub fn mean_corner_error(&self) -> f64 {
        let mut sum = 0.0;
        let mut n = 0usize;
        for r in &self.gpu {
            for (c, t) in r.corners.iter().zip(plate_corners(r.frame)) {
                sum += (c[0] - t[0]).hypot(c[1] - t[1]);
                n += 1;
            }
        }
        sum / n.max(1) as f64
    }
}

/// The whole example on a device you made: render, track through textures
/// on the GPU, read back, track the bytes on the CPU.
pub fn run(device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Outcome> {
    let ctx = GpuContext::from_device(device.clone(), queue.clone())?;
    let textures = render_frames(device, queue);
    let gpu = track(&mut GpuBackend::new(ctx), &textures)?;
    let frames: Vec<GrayImage> = textures
        .iter()
        .map(|t| Ok(gray_from_texels(&read_back(device, queue, t)?, WIDTH as usize, HEIGHT as usize, t.format())?))
        .collect::<Result<_>>()?;
    let cpu = track(&mut CpuBackend::new(), frames)?;
    Ok(Outcome { gpu, cpu })
}

fn main() -> Result<()> {
    let (device, queue, adapter) = create_device()?;
    eprintln!("adapter: {adapter}");
    let outcome = run(&device, &queue)?;
    for r in &outcome.gpu {
        println!("{}", serde_json::to_string(r)?);
    }
    let tracked = outcome.gpu.iter().filter(|r| r.status == Status::Tracking).count();
    let differ = outcome.differing_frames();
    eprintln!(
        "texture path (GPU): {tracked}/{} frames tracking, mean corner error {:.3} px; \
         byte path (CPU) on the frames read back: {}",
        outcome.gpu.len(),
        outcome.mean_corner_error(),
        if differ.is_empty() { "equal results".to_string() } else { format!("results differ at frames {differ:?}") }
    );
    ensure!(differ.is_empty(), "the texture path and the byte path disagree");
    Ok(())
}
