//! The GPU backend: pipelines built once (cached in the [`GpuContext`]),
//! per-slot buffers reused across frames, one submission per frame, only the
//! compact lists read back, and a ring of frame slots so that uploading,
//! computing and reading back successive frames overlap.

use super::{EarlyVision, FrameFeatures, FrameRequest, Pyramids};
use crate::early::compaction::{self, CompactionGpu};
use crate::early::cpf::{self, CpfGpu};
use crate::early::edge_pyramid::{self, EdgePyramidGpu};
use crate::early::sobel::{self, SobelGpu};
use crate::early::zero_crossing::{self, EdgelsGpu};
use crate::early::{frame_sum, gaussian, ingest, log, temporal_diff};
use crate::gpu::{FrameArena, GpuContext, GpuImage, Recorder};
use crate::image::GrayImage;
use crate::{Error, Result};

/// Frame slots in the ring: up to `SLOTS − 1` frames in flight while one is read back.
const SLOTS: usize = 3;
/// Features copied back in the frame's own submission when a list has no cap;
/// longer lists cost one more small copy.
const DEFAULT_PREFETCH: u32 = 4096;

/// Counts of the last frame's GPU work: dispatches and bytes across the bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FrameStats {
    /// Compute dispatches recorded for the frame.
    pub dispatches: u32,
    /// Bytes uploaded (the packed frame, or 0 for a texture already on the GPU).
    pub bytes_uploaded: u64,
    /// Bytes read back (list headers and features, plus pyramids when asked).
    pub bytes_read_back: u64,
}

/// A frame submitted to the GPU whose results are not yet collected; pass it
/// to [`GpuBackend::finish`].
#[derive(Debug)]
#[must_use = "a submitted frame must be finished to get its features and free its slot"]
pub struct Ticket {
    slot: usize,
}

/// Device buffers of one frame slot, allocated on first need.
struct Slot {
    width: usize,
    height: usize,
    arena: FrameArena,
    packed: wgpu::Buffer,
    luma: GpuImage,
    tmp: GpuImage,
    tmp2: GpuImage,
    smoothed: GpuImage,
    motion_mask: Option<GpuImage>,
    sum: Option<GpuImage>,
    sobel_sum: Option<SobelGpu>,
    sobel_frame: Option<SobelGpu>,
    log: Option<GpuImage>,
    edgels: Option<EdgelsGpu>,
    cpf: Option<(CpfGpu, EdgePyramidGpu)>,
    motion_list: Option<CompactionGpu>,
    edge_list: Option<CompactionGpu>,
    crossing_list: Option<CompactionGpu>,
    /// What the pending submission asked for (None when the slot is free).
    pending: Option<FrameRequest>,
    /// Whether the pending frame had a previous frame to difference against.
    had_previous: bool,
}

impl Slot {
    fn new(ctx: &GpuContext, width: usize, height: usize) -> Self {
        let img = |label| GpuImage::new(ctx, width, height, label);
        Self {
            width,
            height,
            arena: FrameArena::new(ctx),
            packed: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pipetrack.frame_bytes"),
                size: ((width * height).div_ceil(4).max(1) * 4) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            luma: img("luma"),
            tmp: img("tmp"),
            tmp2: img("tmp2"),
            smoothed: img("smoothed"),
            motion_mask: None,
            sum: None,
            sobel_sum: None,
            sobel_frame: None,
            log: None,
            edgels: None,
            cpf: None,
            motion_list: None,
            edge_list: None,
            crossing_list: None,
            pending: None,
            had_previous: false,
        }
    }
}

/// Early vision on the GPU. Build it from [`GpuContext::new`] or from your
/// own device with [`GpuContext::from_device`]; feed byte frames with
/// [`EarlyVision::process`] or [`GpuBackend::submit`], or your own textures
/// with [`GpuBackend::submit_texture`].
pub struct GpuBackend {
    ctx: GpuContext,
    slots: Vec<Option<Slot>>,
    next_slot: usize,
    /// Slot holding the previous frame's smoothed image, if any.
    previous: Option<usize>,
    stats: FrameStats,
}

impl std::fmt::Debug for GpuBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuBackend").field("adapter", &self.ctx.adapter_name()).finish()
    }
}

fn readback_prefetch(cap: Option<u32>, capacity: usize) -> u32 {
    cap.unwrap_or(DEFAULT_PREFETCH).min(capacity as u32)
}

impl GpuBackend {
    /// A backend on `ctx`; pipelines are compiled now, buffers on the first frame.
    #[must_use]
    pub fn new(ctx: GpuContext) -> Self {
        ctx.warm_up(&[
            (ingest::SHADER, "from_bytes"),
            (gaussian::SHADER, "blur_rows"),
            (gaussian::SHADER, "blur_cols"),
        ]);
        Self {
            ctx,
            slots: (0..SLOTS).map(|_| None).collect(),
            next_slot: 0,
            previous: None,
            stats: FrameStats::default(),
        }
    }

    /// The context (device, queue, adapter name).
    #[must_use]
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Dispatch and transfer counts of the last finished frame.
    #[must_use]
    pub fn last_frame_stats(&self) -> FrameStats {
        self.stats
    }

    /// Submit a grey frame; the GPU starts on it at once. Collect the result
    /// with [`GpuBackend::finish`]; up to two frames may be in flight.
    pub fn submit(&mut self, frame: &GrayImage, request: &FrameRequest) -> Result<Ticket> {
        let (w, h) = frame.size();
        let slot = self.prepare_slot(w, h, request)?;
        let s = self.slots[slot].as_ref().ok_or_else(|| Error::Gpu("slot vanished".into()))?;
        let packed = ingest::pack_bytes(frame.data());
        if !packed.is_empty() {
            self.ctx.queue.write_buffer(&s.packed, 0, bytemuck::cast_slice(&packed));
        }
        self.stats.bytes_uploaded = (packed.len() * 4) as u64;
        self.record_and_submit(slot, request, |rec, s| ingest::encode(rec, &s.packed, &s.luma))
    }

    /// Submit a frame that is already a texture on this backend's device
    /// (`R8Unorm` or `Rgba8Unorm`, with `TEXTURE_BINDING` usage).
    pub fn submit_texture(&mut self, texture: &wgpu::Texture, request: &FrameRequest) -> Result<Ticket> {
        let (w, h) = (texture.width() as usize, texture.height() as usize);
        let slot = self.prepare_slot(w, h, request)?;
        self.stats.bytes_uploaded = 0;
        self.record_and_submit(slot, request, |rec, s| ingest::encode_texture(rec, texture, &s.luma))
    }

    /// Process a texture frame and wait for its features.
    pub fn process_texture(&mut self, texture: &wgpu::Texture, request: &FrameRequest) -> Result<FrameFeatures> {
        let t = self.submit_texture(texture, request)?;
        self.finish(t)
    }

    /// Run a whole sequence with one fixed request, keeping two frames in
    /// flight so upload, compute and readback overlap; `sink` gets each
    /// frame's features in order.
    pub fn process_stream<'f>(
        &mut self,
        frames: impl IntoIterator<Item = &'f GrayImage>,
        request: &FrameRequest,
        mut sink: impl FnMut(usize, FrameFeatures),
    ) -> Result<()> {
        let mut in_flight = std::collections::VecDeque::new();
        for (i, frame) in frames.into_iter().enumerate() {
            if in_flight.len() == SLOTS - 1 {
                let (j, t) = in_flight.pop_front().ok_or_else(|| Error::Gpu("empty queue".into()))?;
                sink(j, self.finish(t)?);
            }
            in_flight.push_back((i, self.submit(frame, request)?));
        }
        while let Some((j, t)) = in_flight.pop_front() {
            sink(j, self.finish(t)?);
        }
        Ok(())
    }

    /// Pick the next slot, (re)allocating its buffers for this size and request.
    fn prepare_slot(&mut self, w: usize, h: usize, request: &FrameRequest) -> Result<usize> {
        let slot = self.next_slot;
        if self.slots[slot].as_ref().is_some_and(|s| s.pending.is_some()) {
            return Err(Error::Gpu(format!("more than {} frames in flight: finish a ticket first", SLOTS - 1)));
        }
        if self.slots[slot].as_ref().is_none_or(|s| (s.width, s.height) != (w, h)) {
            self.slots[slot] = Some(Slot::new(&self.ctx, w, h));
        }
        if self.previous.is_some_and(|p| self.slots[p].as_ref().is_none_or(|s| (s.width, s.height) != (w, h))) {
            self.previous = None;
        }
        let ctx = &self.ctx;
        let s = self.slots[slot].as_mut().ok_or_else(|| Error::Gpu("slot vanished".into()))?;
        let area = w * h;
        if let Some(m) = &request.motion {
            s.motion_mask.get_or_insert_with(|| GpuImage::new(ctx, w, h, "motion_mask"));
            s.sum.get_or_insert_with(|| GpuImage::new(ctx, w, h, "frame_sum"));
            s.sobel_sum.get_or_insert_with(|| SobelGpu::new(ctx, w, h));
            ensure_list(ctx, &mut s.motion_list, area, m.list.cap)?;
        }
        if let Some(e) = &request.edges {
            s.sobel_frame.get_or_insert_with(|| SobelGpu::new(ctx, w, h));
            ensure_list(ctx, &mut s.edge_list, area, e.list.cap)?;
        }
        if let Some(z) = &request.zero_crossings {
            s.log.get_or_insert_with(|| GpuImage::new(ctx, w, h, "log"));
            s.edgels.get_or_insert_with(|| EdgelsGpu::new(ctx, w, h));
            ensure_list(ctx, &mut s.crossing_list, area, z.list.cap)?;
        }
        if request.builds_pyramids() {
            s.sobel_frame.get_or_insert_with(|| SobelGpu::new(ctx, w, h));
            s.cpf.get_or_insert_with(|| (CpfGpu::new(ctx, w, h), EdgePyramidGpu::new(ctx, w, h)));
        }
        Ok(slot)
    }

    /// Record ingest (by `ingest`) and every requested stage into one encoder, then submit.
    fn record_and_submit(
        &mut self,
        slot: usize,
        request: &FrameRequest,
        ingest: impl FnOnce(&mut Recorder<'_>, &Slot) -> Result<()>,
    ) -> Result<Ticket> {
        let previous = self.previous.filter(|&p| p != slot);
        let (before, rest) = self.slots.split_at(slot);
        let (this, after) = rest.split_first().ok_or_else(|| Error::Gpu("bad slot".into()))?;
        let s = this.as_ref().ok_or_else(|| Error::Gpu("slot vanished".into()))?;
        let prev_smoothed = previous.and_then(|p| {
            let other = if p < slot { before[p].as_ref() } else { after[p - slot - 1].as_ref() };
            other.map(|o| &o.smoothed)
        });

        let mut rec = Recorder::new(&self.ctx, &s.arena);
        ingest(&mut rec, s)?;
        if request.needs_smoothing() {
            gaussian::encode(&mut rec, &s.luma, &s.tmp, &s.smoothed, &request.smoothing)?;
        }
        let had_previous = prev_smoothed.is_some();
        if let (Some(m), Some(prev)) = (&request.motion, prev_smoothed) {
            let (mask, sum, sob, list) = (opt(&s.motion_mask)?, opt(&s.sum)?, opt(&s.sobel_sum)?, opt(&s.motion_list)?);
            // 000 eq. 1 and eq. 2, as in the CPU backend.
            temporal_diff::encode(&mut rec, prev, &s.smoothed, mask, &m.diff)?;
            frame_sum::encode(&mut rec, prev, &s.smoothed, sum)?;
            sobel::encode(&mut rec, sum, sob)?;
            let p = m.list.compaction(0.5);
            compaction::encode(&mut rec, mask, &sob.theta, &sob.magnitude, &p, list)?;
            list.encode_readback(&mut rec, readback_prefetch(m.list.cap, s.width * s.height));
        }
        let sobel_of_frame_done = if let Some(e) = &request.edges {
            let sob = opt(&s.sobel_frame)?;
            sobel::encode(&mut rec, if e.smoothed { &s.smoothed } else { &s.luma }, sob)?;
            let list = opt(&s.edge_list)?;
            let p = e.list.compaction(e.threshold);
            compaction::encode(&mut rec, &sob.magnitude, &sob.direction, &sob.magnitude, &p, list)?;
            list.encode_readback(&mut rec, readback_prefetch(e.list.cap, s.width * s.height));
            !e.smoothed
        } else {
            false
        };
        if let Some(z) = &request.zero_crossings {
            let (l, ed, list) = (opt(&s.log)?, opt(&s.edgels)?, opt(&s.crossing_list)?);
            log::encode(&mut rec, &s.luma, &s.tmp, &s.tmp2, l, &z.log)?;
            zero_crossing::encode(&mut rec, l, ed, &z.crossings)?;
            let p = z.list.compaction(0.0);
            compaction::encode(&mut rec, &ed.strength, &ed.direction, &ed.strength, &p, list)?;
            list.encode_readback(&mut rec, readback_prefetch(z.list.cap, s.width * s.height));
        }
        if request.builds_pyramids() {
            let sob = opt(&s.sobel_frame)?;
            if !sobel_of_frame_done {
                sobel::encode(&mut rec, &s.luma, sob)?;
            }
            let (c, e) = opt(&s.cpf)?;
            cpf::encode(&mut rec, &s.luma, c)?;
            edge_pyramid::encode(&mut rec, &sob.gx, &sob.gy, e)?;
        }
        self.stats.dispatches = rec.dispatch_count();
        rec.submit();

        let s = self.slots[slot].as_mut().ok_or_else(|| Error::Gpu("slot vanished".into()))?;
        s.pending = Some(request.clone());
        s.had_previous = had_previous;
        self.previous = if request.needs_smoothing() { Some(slot) } else { None };
        self.next_slot = (slot + 1) % SLOTS;
        Ok(Ticket { slot })
    }

    /// Wait for a submitted frame and read back its lists.
    pub fn finish(&mut self, ticket: Ticket) -> Result<FrameFeatures> {
        let s = self.slots[ticket.slot].as_mut().ok_or_else(|| Error::Gpu("slot vanished".into()))?;
        let request = s.pending.take().ok_or_else(|| Error::Gpu("ticket already finished".into()))?;
        let mut out = FrameFeatures::default();
        let mut bytes = 0u64;
        let mut read = |list: &Option<CompactionGpu>| -> Result<Vec<crate::early::Feature>> {
            let v = opt(list)?.read(&self.ctx)?;
            bytes += 4 + 16 * v.len() as u64;
            Ok(v)
        };
        if request.motion.is_some() {
            out.motion = Some(if s.had_previous { read(&s.motion_list)? } else { Vec::new() });
        }
        if request.edges.is_some() {
            out.edges = Some(read(&s.edge_list)?);
        }
        if request.zero_crossings.is_some() {
            out.zero_crossings = Some(read(&s.crossing_list)?);
        }
        if request.pyramids == Pyramids::Return {
            let (c, e) = opt(&s.cpf)?;
            let pyr = c.download(&self.ctx)?;
            let edges = e.download(&self.ctx)?;
            bytes += 4
                * (pyr.hierarchies.iter().flatten().map(|l| l.data().len()).sum::<usize>()
                    + edges.horizontal.iter().chain(&edges.vertical).map(|l| l.data().len()).sum::<usize>())
                    as u64;
            out.pyramids = Some((pyr, edges));
        }
        self.stats.bytes_read_back = bytes;
        Ok(out)
    }
}

fn opt<T>(v: &Option<T>) -> Result<&T> {
    v.as_ref().ok_or_else(|| Error::Gpu("stage buffers not allocated".into()))
}

/// Allocate (or grow) a slot's compaction scratch for `area` pixels and `cap`.
fn ensure_list(ctx: &GpuContext, list: &mut Option<CompactionGpu>, area: usize, cap: Option<u32>) -> Result<()> {
    let fits = list.as_ref().is_some_and(|l| l.fits(area, cap));
    if !fits {
        *list = Some(CompactionGpu::new(ctx, area, cap)?);
    }
    Ok(())
}

impl EarlyVision for GpuBackend {
    fn name(&self) -> String {
        format!("GPU: {}", self.ctx.adapter_name())
    }

    fn reset(&mut self) {
        self.previous = None;
    }

    fn process(&mut self, frame: &GrayImage, request: &FrameRequest) -> Result<FrameFeatures> {
        let t = self.submit(frame, request)?;
        self.finish(t)
    }
}
