//! Recording many stage dispatches into one command encoder, and the
//! device-resident image type they read and write.

use std::collections::HashMap;
use std::sync::Mutex;

use wgpu::util::DeviceExt;

use super::GpuContext;
use super::{Binding, ShaderDef};
use crate::image::Image;
use crate::{Error, Result};

/// Uniform parameter blocks are placed at this stride (wgpu's minimum
/// uniform offset alignment).
const UNIFORM_STRIDE: u64 = 256;
/// Most dispatches one [`Recorder`] holds (its uniform buffer is this × 256 bytes).
pub(crate) const MAX_DISPATCHES: u64 = 128;

/// A `width`×`height` image of 32-bit values (f32 or u32) living on the GPU
/// in a storage buffer, row-major like [`Image`]; or a stack of `layers`
/// such images, one after another in the buffer (layer `l` from element
/// `l·width·height`), which every stage processes in one dispatch with the
/// layer as the grid's third dimension.
#[derive(Debug)]
pub struct GpuImage {
    pub(crate) buffer: wgpu::Buffer,
    width: usize,
    height: usize,
    layers: usize,
}

impl GpuImage {
    /// Allocate an uninitialised image of `width`×`height` 32-bit values.
    #[must_use]
    pub fn new(ctx: &GpuContext, width: usize, height: usize, label: &str) -> Self {
        Self::layered(ctx, width, height, 1, label)
    }

    /// Allocate an uninitialised stack of `layers` (at least 1) images of
    /// `width`×`height` 32-bit values.
    #[must_use]
    pub fn layered(ctx: &GpuContext, width: usize, height: usize, layers: usize, label: &str) -> Self {
        let layers = layers.max(1);
        let bytes = (width * height * layers).max(1) as u64 * 4;
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self { buffer, width, height, layers }
    }

    /// Upload a CPU image of 32-bit values.
    #[must_use]
    pub fn from_image<T: bytemuck::Pod + Default>(ctx: &GpuContext, image: &Image<T>, label: &str) -> Self {
        let (width, height) = image.size();
        let mut contents: Vec<u8> = bytemuck::cast_slice(image.data()).to_vec();
        if contents.is_empty() {
            contents = vec![0; 4];
        }
        let buffer = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: &contents,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        });
        Self { buffer, width, height, layers: 1 }
    }

    /// Overwrite the contents from a CPU image of the same size.
    pub fn write<T: bytemuck::Pod + Default>(&self, ctx: &GpuContext, image: &Image<T>) -> Result<()> {
        if image.size() != (self.width, self.height) || self.layers != 1 {
            return Err(Error::Size(format!(
                "writing {}x{} into a {}x{} GPU image of {} layers",
                image.width(),
                image.height(),
                self.width,
                self.height,
                self.layers
            )));
        }
        if !image.data().is_empty() {
            ctx.queue.write_buffer(&self.buffer, 0, bytemuck::cast_slice(image.data()));
        }
        Ok(())
    }

    /// Copy the image back to the CPU (waits for the GPU); a stack comes
    /// back as one image of its layers one below another. For tests and
    /// benches; the frame path reads back only compact lists.
    pub fn download<T: bytemuck::Pod + Default>(&self, ctx: &GpuContext) -> Result<Image<T>> {
        let n = self.width * self.height * self.layers;
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pipetrack.download"),
            size: (n.max(1) * 4) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc =
            ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("pipetrack.download") });
        enc.copy_buffer_to_buffer(&self.buffer, 0, &staging, 0, (n.max(1) * 4) as u64);
        ctx.wait_for(ctx.queue.submit([enc.finish()]))?;
        let bytes = ctx.read_buffer(&staging, 0..(n * 4) as u64)?;
        let data: Vec<T> = bytemuck::pod_collect_to_vec(&bytes);
        Image::from_vec(self.width, self.height * self.layers, data)
    }

    /// `(width, height)` in pixels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// [`Error::Size`] unless `other` has this image's size and layers;
    /// `what` names the pair in the message, as [`Image::check_same_size`]
    /// does on the CPU.
    pub fn check_same_size(&self, other: &GpuImage, what: &str) -> Result<()> {
        if self.size() != other.size() {
            return Err(Error::Size(format!(
                "{what}: {}x{} vs {}x{} GPU images",
                self.width, self.height, other.width, other.height
            )));
        }
        if self.layers != other.layers {
            return Err(Error::Size(format!("{what}: stacks of {} vs {} layers", self.layers, other.layers)));
        }
        Ok(())
    }

    /// Images in the stack (1 for a single image).
    #[must_use]
    pub fn layers(&self) -> usize {
        self.layers
    }

    /// Workgroups covering every layer with 16×16 tiles, one layer per
    /// step of the grid's third dimension.
    #[must_use]
    pub(crate) fn grid(&self) -> [u32; 3] {
        self.region_grid(self.width as u32, self.height as u32)
    }

    /// Workgroups covering a `width`×`height` region of every layer with
    /// 16×16 tiles (a shader adds the region's corner to its invocation id).
    #[must_use]
    pub(crate) fn region_grid(&self, width: u32, height: u32) -> [u32; 3] {
        let [x, y, _] = workgroups_2d(width as usize, height as usize);
        [x, y, self.layers as u32]
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// The storage buffer holding the pixels.
    #[must_use]
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }
}

/// Workgroup counts covering a `width`×`height` image with 16×16 tiles.
#[must_use]
pub(crate) fn workgroups_2d(width: usize, height: usize) -> [u32; 3] {
    let t = super::TILE as usize;
    [width.div_ceil(t) as u32, height.div_ceil(t) as u32, 1]
}

/// Records stage dispatches into one encoder; [`Recorder::submit`] writes all
/// their uniform blocks at once and submits a single command buffer.
/// Consecutive dispatches share one compute pass (a copy ends it); WebGPU
/// makes each dispatch its own usage scope, so a dispatch sees the writes of
/// the dispatches before it in the pass as it would across passes.
///
/// Binding convention shared by every shader: `@binding(0)` is the stage's
/// uniform `Params`, `@binding(1..)` are the resources in the order the
/// stage's `encode` passes them, as its [`ShaderDef`] declares them.
pub(crate) struct Recorder<'a> {
    ctx: &'a GpuContext,
    encoder: wgpu::CommandEncoder,
    /// The open compute pass of the dispatches since the last copy.
    pass: Option<wgpu::ComputePass<'static>>,
    arena: &'a FrameArena,
    uniforms: Vec<u8>,
    dispatches: u32,
}

/// What identifies a bind group of buffers: the pipeline, the uniform slot
/// and the storage buffers bound.
type BindKey = (&'static str, &'static str, u64, Vec<wgpu::Buffer>);

/// Per-frame-slot GPU state a [`Recorder`] records against: a uniform buffer
/// with room for every dispatch's parameter block, and the bind groups made
/// for it. A frame slot records the same dispatches onto the same buffers
/// frame after frame, so after the first frame no bind group is created on
/// the per-frame path. Keep one per frame slot and reuse it.
pub(crate) struct FrameArena {
    uniforms: wgpu::Buffer,
    bind_groups: Mutex<HashMap<BindKey, wgpu::BindGroup>>,
}

impl FrameArena {
    /// A new arena on `ctx`'s device.
    pub(crate) fn new(ctx: &GpuContext) -> Self {
        let uniforms = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pipetrack.uniforms"),
            size: UNIFORM_STRIDE * MAX_DISPATCHES,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self { uniforms, bind_groups: Mutex::default() }
    }
}

impl<'a> Recorder<'a> {
    /// Start recording; `arena` must not be in use by another recorder whose
    /// work has not yet been submitted.
    pub(crate) fn new(ctx: &'a GpuContext, arena: &'a FrameArena) -> Self {
        let encoder =
            ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("pipetrack.frame") });
        Self { ctx, encoder, pass: None, arena, uniforms: Vec::new(), dispatches: 0 }
    }

    /// The context recorded for.
    pub(crate) fn context(&self) -> &'a GpuContext {
        self.ctx
    }

    /// Number of compute dispatches recorded so far.
    pub(crate) fn dispatch_count(&self) -> u32 {
        self.dispatches
    }

    /// Record one dispatch of `entry` in `shader` with uniform `params` and
    /// storage `buffers` bound at 1, 2, …; empty grids are skipped. The bind
    /// group is made once per arena and reused on later frames. Errors when
    /// the buffers do not match the entry point's declared bindings.
    pub(crate) fn dispatch<P: bytemuck::Pod>(
        &mut self,
        shader: &ShaderDef,
        entry: &'static str,
        params: &P,
        buffers: &[&wgpu::Buffer],
        groups: [u32; 3],
    ) -> Result<()> {
        check_resources(shader, entry, buffers.len(), true)?;
        if groups.contains(&0) {
            return Ok(());
        }
        let pipeline = self.ctx.pipeline(shader, entry)?;
        let (offset, size) = self.push_uniform(shader, params)?;
        let key: BindKey = (shader.name, entry, offset, buffers.iter().map(|b| (*b).clone()).collect());
        let bind_group = {
            let mut cache = self.arena.bind_groups.lock().unwrap_or_else(|p| p.into_inner());
            cache
                .entry(key)
                .or_insert_with(|| {
                    let resources: Vec<wgpu::BindingResource<'_>> =
                        buffers.iter().map(|b| b.as_entire_binding()).collect();
                    self.make_bind_group(shader, &pipeline, offset, size, &resources)
                })
                .clone()
        };
        self.record(shader, &pipeline, &bind_group, groups);
        Ok(())
    }

    /// Like [`Recorder::dispatch`], with any binding resources (textures too)
    /// at 1, 2, …; the bind group is made for this dispatch only. Errors when
    /// the number of resources does not match the declared bindings.
    pub(crate) fn dispatch_with<P: bytemuck::Pod>(
        &mut self,
        shader: &ShaderDef,
        entry: &'static str,
        params: &P,
        resources: &[wgpu::BindingResource<'_>],
        groups: [u32; 3],
    ) -> Result<()> {
        check_resources(shader, entry, resources.len(), false)?;
        if groups.contains(&0) {
            return Ok(());
        }
        let pipeline = self.ctx.pipeline(shader, entry)?;
        let (offset, size) = self.push_uniform(shader, params)?;
        let bind_group = self.make_bind_group(shader, &pipeline, offset, size, resources);
        self.record(shader, &pipeline, &bind_group, groups);
        Ok(())
    }

    /// Append `params` to this submission's uniform blocks: (offset, bound size).
    fn push_uniform<P: bytemuck::Pod>(&mut self, shader: &ShaderDef, params: &P) -> Result<(u64, u64)> {
        let offset = self.uniforms.len() as u64;
        if offset / UNIFORM_STRIDE >= MAX_DISPATCHES {
            return Err(Error::Gpu(format!("more than {MAX_DISPATCHES} dispatches in one submission")));
        }
        let bytes = bytemuck::bytes_of(params);
        if bytes.len() as u64 > UNIFORM_STRIDE {
            return Err(Error::Gpu(format!(
                "{}: uniform block of {} bytes exceeds {UNIFORM_STRIDE}",
                shader.name,
                bytes.len()
            )));
        }
        self.uniforms.extend_from_slice(bytes);
        self.uniforms.resize((offset + UNIFORM_STRIDE) as usize, 0);
        Ok((offset, (bytes.len() as u64).next_multiple_of(16)))
    }

    fn make_bind_group(
        &self,
        shader: &ShaderDef,
        pipeline: &wgpu::ComputePipeline,
        offset: u64,
        size: u64,
        resources: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.arena.uniforms,
                offset,
                size: wgpu::BufferSize::new(size),
            }),
        }];
        for (i, r) in resources.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry { binding: i as u32 + 1, resource: r.clone() });
        }
        self.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(shader.name),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    }

    fn record(
        &mut self,
        shader: &ShaderDef,
        pipeline: &wgpu::ComputePipeline,
        bind_group: &wgpu::BindGroup,
        groups: [u32; 3],
    ) {
        let encoder = &mut self.encoder;
        let pass = self.pass.get_or_insert_with(|| {
            encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("pipetrack.stages"),
                    timestamp_writes: None,
                })
                .forget_lifetime()
        });
        pass.push_debug_group(shader.name);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
        pass.pop_debug_group();
        self.dispatches += 1;
    }

    /// Record a buffer-to-buffer copy.
    pub(crate) fn copy(&mut self, src: &wgpu::Buffer, src_offset: u64, dst: &wgpu::Buffer, dst_offset: u64, size: u64) {
        if size > 0 {
            // The open pass ends before the copy, so the copy follows its dispatches.
            self.pass = None;
            self.encoder.copy_buffer_to_buffer(src, src_offset, dst, dst_offset, size);
        }
    }

    /// Write the uniform blocks and submit everything recorded as one command
    /// buffer; wait for the returned index with [`GpuContext::wait_for`].
    pub(crate) fn submit(self) -> wgpu::SubmissionIndex {
        let ctx = self.ctx;
        ctx.queue.submit([self.finish()])
    }

    /// Queue the write of the uniform blocks and end recording: the command
    /// buffer, for a `queue.submit` that may carry other recorders' buffers
    /// too (each recorder has its own arena, so their uniforms do not mix).
    pub(crate) fn finish(mut self) -> wgpu::CommandBuffer {
        self.pass = None;
        if !self.uniforms.is_empty() {
            self.ctx.queue.write_buffer(&self.arena.uniforms, 0, &self.uniforms);
        }
        self.encoder.finish()
    }
}

/// Error unless `entry` of `shader` is declared with a uniform at binding 0
/// followed by `count` resources (all of them buffers when `buffers_only`).
fn check_resources(shader: &ShaderDef, entry: &str, count: usize, buffers_only: bool) -> Result<()> {
    let declared = shader
        .entry_point(entry)
        .ok_or_else(|| Error::Gpu(format!("{}: entry point `{entry}` is not declared", shader.path())))?;
    let (first, rest) = declared.bindings.split_first().unwrap_or((&Binding::Storage, &[]));
    if *first != Binding::Uniform || rest.len() != count || (buffers_only && !rest.iter().all(|b| b.is_buffer())) {
        return Err(Error::Gpu(format!(
            "{} `{entry}` declares bindings {:?}; the dispatch binds a uniform and {count} {}",
            shader.path(),
            declared.bindings,
            if buffers_only { "buffers" } else { "resources" }
        )));
    }
    Ok(())
}

/// Run `record` on a fresh recorder and wait for its submission: the standalone path
/// used by per-stage functions in tests and benches.
pub(crate) fn run_once(ctx: &GpuContext, record: impl FnOnce(&mut Recorder<'_>) -> Result<()>) -> Result<()> {
    let arena = FrameArena::new(ctx);
    let mut rec = Recorder::new(ctx, &arena);
    record(&mut rec)?;
    ctx.wait_for(rec.submit())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::early::{Window, frame_sum, gaussian, log, sobel, temporal_diff, zero_crossing};

    /// A context for the GPU unit tests, or `None` (printing that the test
    /// skipped) without an adapter, unless `PIPETRACK_REQUIRE_GPU=1`.
    fn test_context(test: &str) -> Option<GpuContext> {
        match GpuContext::new() {
            Ok(ctx) => Some(ctx),
            Err(e) if std::env::var("PIPETRACK_REQUIRE_GPU").is_ok_and(|v| v == "1") => {
                panic!("PIPETRACK_REQUIRE_GPU=1 but no GPU adapter: {e}")
            }
            Err(_) => {
                eprintln!("SKIPPED {test}: no GPU adapter (set PIPETRACK_REQUIRE_GPU=1 to make this a failure)");
                None
            }
        }
    }

    /// Compaction scratch sized on a context of one run length is refused
    /// by a recording on a context of another, not read with the wrong
    /// block size.
    #[test]
    fn compaction_scratch_of_another_run_length_is_refused() {
        use crate::early::compaction::{self, CompactionGpu, CompactionParams};
        let Some(ctx) = test_context("compaction_scratch_of_another_run_length_is_refused") else { return };
        let other = ctx.with_compaction_run(if ctx.compaction_run() == 8 { 32 } else { 8 }).unwrap();
        let scratch = CompactionGpu::new(&other, 15, None).unwrap();
        let img = || GpuImage::new(&ctx, 5, 3, "test");
        let (sel, th, mag) = (img(), img(), img());
        let p = CompactionParams { window: Window::full(5, 3), threshold: 0.5, cap: None, seed: 1 };
        let err = run_once(&ctx, |rec| compaction::encode(rec, &sel, &th, &mag, &p, &scratch))
            .expect_err("scratch of another run length");
        assert!(matches!(err, Error::Gpu(ref m) if m.contains("runs of")), "{err}");
        let own = CompactionGpu::new(&ctx, 15, None).unwrap();
        run_once(&ctx, |rec| compaction::encode(rec, &sel, &th, &mag, &p, &own)).unwrap();
    }

    /// Every stage's `encode` refuses a `GpuImage` whose size differs from
    /// its input's with [`Error::Size`] naming the pair, and records nothing;
    /// with matching sizes the same calls record their dispatches.
    #[test]
    fn encode_refuses_mismatched_gpu_images() {
        let Some(ctx) = test_context("encode_refuses_mismatched_gpu_images") else { return };
        let img = |w, h| GpuImage::new(&ctx, w, h, "test");
        let (a, b, c, d) = (img(5, 3), img(5, 3), img(5, 3), img(5, 3));
        let wrong = img(3, 5);
        let planes = |w, h| sobel::SobelGpu::new(&ctx, w, h);
        let mut sob = planes(5, 3);
        let edgels = |w, h| zero_crossing::EdgelsGpu::new(&ctx, w, h);
        let mut edg = edgels(5, 3);
        let arena = FrameArena::new(&ctx);

        type Encode<'t> = Box<dyn Fn(&mut Recorder<'_>, &GpuImage) -> Result<()> + 't>;
        let cases: Vec<(&str, Encode<'_>)> = vec![
            ("gaussian src/dst", Box::new(|r, x| gaussian::encode(r, &a, &b, x, &gaussian::GaussianParams::default()))),
            ("frame sum a/b", Box::new(|r, x| frame_sum::encode(r, &a, x, &c))),
            (
                "temporal difference prev/out",
                Box::new(|r, x| temporal_diff::encode(r, &a, &b, x, &temporal_diff::TemporalDiffParams::default())),
            ),
            (
                "LoG src/tmp_d",
                Box::new(|r, x| log::encode(r, &a, &b, x, &d, &log::LogParams::default(), Window::full(5, 3))),
            ),
        ];
        for (what, encode) in &cases {
            let mut rec = Recorder::new(&ctx, &arena);
            match encode(&mut rec, &wrong) {
                Err(Error::Size(m)) => assert!(m.starts_with(what) && m.contains("5x3 vs 3x5"), "{what}: {m}"),
                other => panic!("{what}: expected a size error, got {other:?}"),
            }
            assert_eq!(rec.dispatch_count(), 0, "{what}");
            let mut rec = Recorder::new(&ctx, &arena);
            encode(&mut rec, &d).unwrap();
            assert!(rec.dispatch_count() > 0, "{what}");
        }

        let mut rec = Recorder::new(&ctx, &arena);
        sob.theta = img(5, 4);
        assert!(matches!(sobel::encode(&mut rec, &a, &sob), Err(Error::Size(m)) if m.starts_with("sobel src/theta")));
        edg.offset_y = img(4, 3);
        let p = zero_crossing::ZeroCrossingParams::default();
        assert!(
            matches!(zero_crossing::encode(&mut rec, &a, &edg, &p, Window::full(5, 3)), Err(Error::Size(m)) if m.contains("offset_y"))
        );
        assert_eq!(rec.dispatch_count(), 0);
        sobel::encode(&mut rec, &a, &planes(5, 3)).unwrap();
        zero_crossing::encode(&mut rec, &a, &edgels(5, 3), &p, Window::full(5, 3)).unwrap();
        assert_eq!(rec.dispatch_count(), 2);
    }
}
