//! The GPU backend: pipelines built once (cached in the [`GpuContext`]),
//! per-slot buffers reused across frames, one submission per frame, only the
//! compact lists read back, and a ring of frame slots so that uploading,
//! computing and reading back successive frames overlap.
//!
//! Frames of several independent sequences can share one submission: each
//! sequence runs in its own *lane* (its own ring of slots and its own
//! previous frame), and [`GpuBackend::submit_lanes`] records one frame of
//! each lane into one `queue.submit`. The single-sequence API
//! ([`EarlyVision`], [`GpuBackend::submit`]) uses lane 0.
//!
//! Stages run over the whole frame, except the LoG and its zero crossings
//! when only windowed lists read them ([`FramePlan::log_windows`]): they
//! run over those windows (the union of every layer's), the LoG one pixel
//! around them, each value the whole frame's.
//!
//! A [`GpuStack`] goes further for sequences of one frame size whose
//! requests differ only in their lists' windows: their frames are stacked
//! in the same buffers, layer after layer, and each stage is dispatched once
//! for all of them, the layer being the grid's third dimension, so the
//! dispatches per step do not grow with the number of sequences.

use super::plan::{EdgelPart, FramePlan, List, Plane, PreviousFrame, SobelPart, SobelPlanes, Source, Step};
use super::{EarlyVision, FrameFeatures, FrameRequest, WindowRequest};
use crate::early::compaction::{self, CompactionGpu, CompactionParams};
use crate::early::cpf::{self, CpfGpu};
use crate::early::edge_pyramid::{self, EdgePyramidGpu};
use crate::early::sobel::{self, SobelGpu};
use crate::early::window_energy::{self, WindowEnergyGpu};
use crate::early::zero_crossing::{self, EdgelsGpu};
use crate::early::{Feature, Window, gaussian, ingest, log, temporal_diff};
use crate::gpu::{FrameArena, GpuContext, GpuImage, Recorder};
use crate::image::{GrayImage, RgbImage};
use crate::{Error, Result};

use rayon::prelude::*;

/// Frame slots in the ring: up to `SLOTS` frames may be submitted and not yet
/// finished; [`GpuBackend::process_stream`] keeps `SLOTS − 1` in flight while
/// it reads one back.
const SLOTS: usize = 3;
/// Frame slots of a [`GpuStack`]: one step on the device while the step
/// before is read back.
const STACK_SLOTS: usize = 2;
/// Features copied back in the frame's own submission at least (at most a
/// list's cap); a list longer than what was copied costs one more
/// submission and wait, which on a queue shared by several lanes waits for
/// all work submitted before it.
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

/// Most lanes (independent sequences) one backend keeps.
pub const MAX_LANES: usize = 64;

/// Error unless `lanes` sequences in flight is 1 to [`MAX_LANES`].
pub fn check_lane_count(lanes: usize) -> Result<()> {
    if (1..=MAX_LANES).contains(&lanes) {
        Ok(())
    } else {
        Err(Error::Parameter(format!("{lanes} sequences in flight: give 1 to {MAX_LANES}")))
    }
}

/// The lanes `0..lanes` in the groups that take turns on the device: even
/// and odd lanes, so one group's frames are on the device while the other's
/// are read back and tracked (one group when there is a single lane).
#[must_use]
pub fn lane_groups(lanes: usize) -> Vec<Vec<usize>> {
    if lanes == 1 { vec![vec![0]] } else { vec![(0..lanes).step_by(2).collect(), (1..lanes).step_by(2).collect()] }
}

/// A frame submitted to the GPU whose results are not yet collected; pass it
/// to [`GpuBackend::finish`].
#[derive(Debug)]
#[must_use = "a submitted frame must be finished to get its features and free its slot"]
pub struct Ticket {
    lane: usize,
    slot: usize,
}

/// One frame of one lane for [`GpuBackend::submit_lanes`]: the next frame of
/// the sequence running in `lane`.
#[derive(Clone, Copy, Debug)]
pub struct LaneFrame<'a> {
    /// The lane (below [`MAX_LANES`]); each lane differences its frames
    /// against its own previous frame only.
    pub lane: usize,
    /// The grey frame (for a colour frame, its luma: [`RgbImage::to_gray`]).
    pub frame: &'a GrayImage,
    /// The colour frame `frame` is the luma of, read by sample windows (as
    /// [`GpuBackend::submit_rgb`] does); `None`: they read the grey frame.
    pub colour: Option<&'a RgbImage>,
    /// What to compute on it.
    pub request: &'a FrameRequest,
}

/// Where a recorded frame's pixels come from: grey bytes (with the colour
/// frame they are the luma of, for sample windows), or a texture.
#[derive(Clone, Copy)]
enum Input<'a> {
    Bytes(&'a GrayImage, Option<&'a RgbImage>),
    Texture(&'a wgpu::Texture),
}

impl Input<'_> {
    fn size(&self) -> (usize, usize) {
        match self {
            Input::Bytes(g, _) => g.size(),
            Input::Texture(t) => (t.width() as usize, t.height() as usize),
        }
    }
}

/// One sequence's frame stream (or, in a [`GpuStack`], the streams of its
/// layers, which move together): its ring of slots, and the slot holding its
/// previous frame's smoothed image with what that image is.
pub(super) struct Lane {
    slots: Vec<Option<Slot>>,
    next_slot: usize,
    previous: Option<(usize, PreviousFrame)>,
    /// Images stacked in each of the lane's buffers.
    layers: usize,
    /// Length of each list in each layer's last finished frame, by [`list_index`].
    listed: Vec<[u32; 3]>,
}

impl Lane {
    fn new() -> Self {
        Self::layered(1, SLOTS)
    }

    /// A lane of `layers` stacked sequences with a ring of `slots` slots.
    pub(super) fn layered(layers: usize, slots: usize) -> Self {
        Self {
            slots: (0..slots).map(|_| None).collect(),
            next_slot: 0,
            previous: None,
            layers,
            listed: vec![[0; 3]; layers],
        }
    }

    fn slot(&self, slot: usize) -> Result<&Slot> {
        self.slots[slot].as_ref().ok_or_else(|| Error::Gpu("slot vanished".into()))
    }

    fn slot_mut(&mut self, slot: usize) -> Result<&mut Slot> {
        self.slots[slot].as_mut().ok_or_else(|| Error::Gpu("slot vanished".into()))
    }
}

/// Device buffers of one frame slot, allocated on first need; each holds a
/// stack of `layers` images.
struct Slot {
    width: usize,
    height: usize,
    layers: usize,
    arena: FrameArena,
    packed: wgpu::Buffer,
    luma: GpuImage,
    tmp: GpuImage,
    tmp2: GpuImage,
    smoothed: GpuImage,
    motion_mask: Option<GpuImage>,
    sum: Option<GpuImage>,
    sobel_of_sum: Option<SobelGpu>,
    sobel_of_frame: Option<SobelGpu>,
    log: Option<GpuImage>,
    edgels: Option<EdgelsGpu>,
    cpf: Option<(CpfGpu, EdgePyramidGpu)>,
    motion_list: Option<CompactionGpu>,
    edge_list: Option<CompactionGpu>,
    crossing_list: Option<CompactionGpu>,
    windows: Option<WindowEnergyGpu>,
    /// The submitted frame's plan and submission (None when the slot is free).
    pending: Option<(FramePlan, wgpu::SubmissionIndex)>,
}

impl Slot {
    fn new(ctx: &GpuContext, width: usize, height: usize, layers: usize) -> Self {
        let img = |label| GpuImage::layered(ctx, width, height, layers, label);
        Self {
            width,
            height,
            layers,
            arena: FrameArena::new(ctx),
            packed: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pipetrack.frame_bytes"),
                size: (ingest::packed_words(width, height).max(1) * 4 * layers) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            luma: img("luma"),
            tmp: img("tmp"),
            tmp2: img("tmp2"),
            smoothed: img("smoothed"),
            motion_mask: None,
            sum: None,
            sobel_of_sum: None,
            sobel_of_frame: None,
            log: None,
            edgels: None,
            cpf: None,
            motion_list: None,
            edge_list: None,
            crossing_list: None,
            windows: None,
            pending: None,
        }
    }

    /// Allocate every buffer `plan` uses that the slot does not have yet.
    fn allocate(&mut self, ctx: &GpuContext, plan: &FramePlan) -> Result<()> {
        let (w, h, layers) = (self.width, self.height, self.layers);
        let img = |label| GpuImage::layered(ctx, w, h, layers, label);
        for step in plan.steps() {
            match *step {
                Step::Smooth(_) | Step::EmptyList(_) => {}
                Step::DiffAndSum(_) => {
                    self.motion_mask.get_or_insert_with(|| img("motion_mask"));
                    self.sum.get_or_insert_with(|| img("frame_sum"));
                }
                Step::Sobel { output, .. } => {
                    self.sobel_set_mut(output).get_or_insert_with(|| SobelGpu::layered(ctx, w, h, layers));
                }
                Step::Log(_) => {
                    self.log.get_or_insert_with(|| img("log"));
                }
                Step::ZeroCrossings(_) => {
                    self.edgels.get_or_insert_with(|| EdgelsGpu::layered(ctx, w, h, layers));
                }
                Step::Compact { list, params, .. } => {
                    let scratch = self.list_mut(list);
                    if !scratch.as_ref().is_some_and(|l| l.fits(w * h, params.cap)) {
                        *scratch = Some(CompactionGpu::layered(ctx, w * h, params.cap, layers)?);
                    }
                }
                Step::Pyramids { .. } => {
                    self.cpf.get_or_insert_with(|| {
                        (CpfGpu::layered(ctx, w, h, layers), EdgePyramidGpu::layered(ctx, w, h, layers))
                    });
                }
                Step::Windows { count, params, energies } => {
                    if layers > 1 {
                        return Err(Error::Parameter("sample windows are not computed on stacked frames".into()));
                    }
                    let (len, features) = (params.window_len(), !energies);
                    if !self.windows.as_ref().is_some_and(|b| b.fits(w * h, count, len, features)) {
                        self.windows = Some(WindowEnergyGpu::new(ctx, w * h, count, len, features));
                    }
                }
            }
        }
        Ok(())
    }

    fn sobel_set_mut(&mut self, set: SobelPlanes) -> &mut Option<SobelGpu> {
        match set {
            SobelPlanes::OfSum => &mut self.sobel_of_sum,
            SobelPlanes::OfFrame => &mut self.sobel_of_frame,
        }
    }

    fn list_mut(&mut self, list: List) -> &mut Option<CompactionGpu> {
        match list {
            List::Motion => &mut self.motion_list,
            List::Edges => &mut self.edge_list,
            List::ZeroCrossings => &mut self.crossing_list,
        }
    }

    fn sobel_set(&self, set: SobelPlanes) -> Result<&SobelGpu> {
        opt(match set {
            SobelPlanes::OfSum => &self.sobel_of_sum,
            SobelPlanes::OfFrame => &self.sobel_of_frame,
        })
    }

    fn list(&self, list: List) -> Result<&CompactionGpu> {
        opt(match list {
            List::Motion => &self.motion_list,
            List::Edges => &self.edge_list,
            List::ZeroCrossings => &self.crossing_list,
        })
    }
}

/// A slot's buffers as a plan names them, with the previous frame's
/// smoothed image (which lives in another slot).
struct FrameImages<'a> {
    slot: &'a Slot,
    previous: Option<&'a GpuImage>,
}

impl FrameImages<'_> {
    fn plane(&self, p: Plane) -> Result<&GpuImage> {
        let s = self.slot;
        match p {
            Plane::Luma => Ok(&s.luma),
            Plane::Smoothed => Ok(&s.smoothed),
            Plane::Previous => self.previous.ok_or_else(|| Error::Gpu("plan reads a previous frame it has not".into())),
            Plane::MotionMask => opt(&s.motion_mask),
            Plane::Sum => opt(&s.sum),
            Plane::Log => opt(&s.log),
        }
    }

    fn source(&self, source: Source) -> Result<&GpuImage> {
        match source {
            Source::Plane(p) => self.plane(p),
            Source::Sobel(set, part) => {
                let sob = self.slot.sobel_set(set)?;
                Ok(match part {
                    SobelPart::Gx => &sob.gx,
                    SobelPart::Gy => &sob.gy,
                    SobelPart::Magnitude => &sob.magnitude,
                    SobelPart::Direction => &sob.direction,
                    SobelPart::Theta => &sob.theta,
                })
            }
            Source::Edgels(part) => {
                let ed = opt(&self.slot.edgels)?;
                Ok(match part {
                    EdgelPart::Strength => &ed.strength,
                    EdgelPart::Direction => &ed.direction,
                })
            }
        }
    }
}

/// Early vision on the GPU. Build it from [`GpuContext::new`] or from your
/// own device with [`GpuContext::from_device`]; feed byte frames with
/// [`EarlyVision::process`] or [`GpuBackend::submit`], or your own textures
/// with [`GpuBackend::submit_texture`].
pub struct GpuBackend {
    ctx: GpuContext,
    /// Lane 0 serves the single-sequence API; more are made on demand.
    lanes: Vec<Lane>,
    stats: FrameStats,
}

impl std::fmt::Debug for GpuBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuBackend").field("adapter", &self.ctx.adapter_name()).finish()
    }
}

/// Features to copy back with the frame: what the list held on the lane's
/// last frame and a quarter more (consecutive frames list similar numbers),
/// at least [`DEFAULT_PREFETCH`], never more than the cap or the capacity.
fn readback_prefetch(cap: Option<u32>, capacity: usize, last_listed: u32) -> u32 {
    let expected = last_listed.saturating_add(last_listed / 4).max(DEFAULT_PREFETCH);
    cap.map_or(expected, |c| c.min(expected)).min(u32::try_from(capacity).unwrap_or(u32::MAX))
}

fn list_index(list: List) -> usize {
    match list {
        List::Motion => 0,
        List::Edges => 1,
        List::ZeroCrossings => 2,
    }
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
        Self { ctx, lanes: vec![Lane::new()], stats: FrameStats::default() }
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
    /// with [`GpuBackend::finish`]; up to three frames may be in flight.
    pub fn submit(&mut self, frame: &GrayImage, request: &FrameRequest) -> Result<Ticket> {
        self.submit_inputs(&[(0, Input::Bytes(frame, None), request)]).and_then(first_ticket)
    }

    /// Submit a colour frame: the grey stages read its luma
    /// ([`RgbImage::to_gray`]), the sample windows its colour.
    pub fn submit_rgb(&mut self, frame: &RgbImage, request: &FrameRequest) -> Result<Ticket> {
        let gray = frame.to_gray();
        self.submit_inputs(&[(0, Input::Bytes(&gray, Some(frame)), request)]).and_then(first_ticket)
    }

    /// Submit a frame that is already a texture on this backend's device (a
    /// format of [`crate::early::ingest::TEXTURE_FORMATS`], with
    /// `TEXTURE_BINDING` usage; colour is reduced to luma as that module says).
    pub fn submit_texture(&mut self, texture: &wgpu::Texture, request: &FrameRequest) -> Result<Ticket> {
        self.submit_inputs(&[(0, Input::Texture(texture), request)]).and_then(first_ticket)
    }

    /// Submit the next frame of several lanes (independent sequences, each
    /// at most once here) in one submission: every pass of every frame goes
    /// into one `queue.submit`, so the device gets all of them at once.
    /// Returns one ticket per frame, in order; [`GpuBackend::finish`] each.
    /// Every request is checked before anything is recorded.
    pub fn submit_lanes(&mut self, frames: &[LaneFrame<'_>]) -> Result<Vec<Ticket>> {
        for f in frames {
            if let Some(c) = f.colour
                && c.size() != f.frame.size()
            {
                let ((cw, ch), (w, h)) = (c.size(), f.frame.size());
                return Err(Error::Parameter(format!(
                    "lane {}: colour frame {cw}x{ch} and grey frame {w}x{h} differ in size",
                    f.lane
                )));
            }
        }
        let inputs: Vec<(usize, Input<'_>, &FrameRequest)> =
            frames.iter().map(|f| (f.lane, Input::Bytes(f.frame, f.colour), f.request)).collect();
        self.submit_inputs(&inputs)
    }

    /// Forget `lane`'s previous frame: its next frame starts a new sequence.
    pub fn reset_lane(&mut self, lane: usize) {
        if let Some(l) = self.lanes.get_mut(lane) {
            l.previous = None;
        }
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

    /// Check every frame (lane in range and not repeated, request valid),
    /// then record each into its lane's next slot and submit them all at once.
    fn submit_inputs(&mut self, frames: &[(usize, Input<'_>, &FrameRequest)]) -> Result<Vec<Ticket>> {
        for (i, &(lane, input, request)) in frames.iter().enumerate() {
            request.validate()?;
            if matches!(input, Input::Texture(_)) && request.windows.is_some() {
                return Err(Error::Parameter(
                    "sample windows read a frame's colour bytes: submit the frame as bytes, not as a texture".into(),
                ));
            }
            if lane >= MAX_LANES {
                return Err(Error::Parameter(format!("lane {lane} out of range (at most {MAX_LANES} lanes)")));
            }
            if frames[..i].iter().any(|&(other, _, _)| other == lane) {
                return Err(Error::Parameter(format!("lane {lane} given twice in one submission")));
            }
            if let Some(l) = self.lanes.get(lane) {
                l.check_next_slot_free()?;
            }
        }
        let mut recorded = Vec::with_capacity(frames.len());
        for &(lane, input, request) in frames {
            while self.lanes.len() <= lane {
                self.lanes.push(Lane::new());
            }
            let (w, h) = input.size();
            let (slot, plan) = prepare(&self.ctx, &mut self.lanes[lane], w, h, &[request])?;
            recorded.push((lane, slot, plan, input, request.windows.as_ref()));
        }
        // Each frame records into its own command buffer; several frames in
        // parallel (a single frame stays on the calling thread).
        let (ctx, lanes) = (&self.ctx, &self.lanes);
        let record_one = |(lane, slot, plans, input, windows): &(
            usize,
            usize,
            Vec<FramePlan>,
            Input<'_>,
            Option<&WindowRequest>,
        )| { record(ctx, &lanes[*lane], *slot, plans, &[*input], *windows) };
        let commands: Vec<(wgpu::CommandBuffer, FrameStats)> = if recorded.len() == 1 {
            recorded.iter().map(record_one).collect::<Result<_>>()?
        } else {
            recorded.par_iter().map(record_one).collect::<Result<_>>()?
        };
        for (lane, slot, plans, ..) in &recorded {
            self.lanes[*lane].advance(*slot, &plans[0]);
        }
        if let Some((_, stats)) = commands.last() {
            self.stats.dispatches = stats.dispatches;
            self.stats.bytes_uploaded = stats.bytes_uploaded;
        }
        let submitted = self.ctx.queue.submit(commands.into_iter().map(|(c, _)| c));
        let mut tickets = Vec::with_capacity(recorded.len());
        for (lane, slot, mut plans, ..) in recorded {
            self.lanes[lane].slot_mut(slot)?.pending = Some((plans.swap_remove(0), submitted.clone()));
            tickets.push(Ticket { lane, slot });
        }
        Ok(tickets)
    }

    /// Wait for a submitted frame (its own submission only, not other work
    /// on the device) and read back its lists.
    pub fn finish(&mut self, ticket: Ticket) -> Result<FrameFeatures> {
        let lane = self.lanes.get_mut(ticket.lane).ok_or_else(|| Error::Gpu("lane vanished".into()))?;
        let (features, bytes) = finish_in_lane(&self.ctx, lane, ticket.slot)?;
        self.stats.bytes_read_back = bytes;
        first_layer(features)
    }

    /// [`GpuBackend::finish`] for several tickets at once, as `submit_lanes`
    /// returns them: tickets of different lanes are read back in parallel.
    /// Features come in ticket order.
    pub fn finish_lanes(&mut self, tickets: Vec<Ticket>) -> Result<Vec<FrameFeatures>> {
        let distinct = tickets.iter().enumerate().all(|(i, t)| tickets[..i].iter().all(|o| o.lane != t.lane));
        if !distinct || tickets.len() == 1 {
            return tickets.into_iter().map(|t| self.finish(t)).collect();
        }
        let mut lanes: Vec<Option<&mut Lane>> = self.lanes.iter_mut().map(Some).collect();
        let work: Vec<(&mut Lane, usize)> = tickets
            .iter()
            .map(|t| {
                let lane = lanes.get_mut(t.lane).and_then(Option::take);
                lane.map(|l| (l, t.slot)).ok_or_else(|| Error::Gpu("lane vanished".into()))
            })
            .collect::<Result<_>>()?;
        let ctx = &self.ctx;
        let read: Vec<(Vec<FrameFeatures>, u64)> =
            work.into_par_iter().map(|(lane, slot)| finish_in_lane(ctx, lane, slot)).collect::<Result<_>>()?;
        if let Some(&(_, bytes)) = read.last() {
            self.stats.bytes_read_back = bytes;
        }
        read.into_iter().map(|(features, _)| first_layer(features)).collect()
    }
}

impl Lane {
    /// Make `slot`, just recorded with `plan`, the lane's latest frame.
    fn advance(&mut self, slot: usize, plan: &FramePlan) {
        self.previous = plan.next_previous().map(|kept| (slot, kept));
        self.next_slot = (slot + 1) % self.slots.len();
    }

    /// Error when the lane's next slot still holds a frame not finished.
    fn check_next_slot_free(&self) -> Result<()> {
        if self.slots[self.next_slot].as_ref().is_some_and(|s| s.pending.is_some()) {
            return Err(Error::Gpu(format!("more than {} frames in flight: finish a ticket first", self.slots.len())));
        }
        Ok(())
    }
}

/// Pick `lane`'s next slot, plan the frame of each layer (`requests`, one
/// per layer), check that the plans stack, and (re)allocate the slot's
/// buffers for this size and these plans.
fn prepare(
    ctx: &GpuContext,
    lane: &mut Lane,
    w: usize,
    h: usize,
    requests: &[&FrameRequest],
) -> Result<(usize, Vec<FramePlan>)> {
    if requests.len() != lane.layers {
        return Err(Error::Parameter(format!("{} frames for a stack of {}", requests.len(), lane.layers)));
    }
    let slot = lane.next_slot;
    if lane.slots[slot].as_ref().is_none_or(|s| (s.width, s.height) != (w, h)) {
        lane.slots[slot] = Some(Slot::new(ctx, w, h, lane.layers));
    }
    // The ring never puts two consecutive frames in one slot; a previous
    // frame in this very slot would be overwritten, so it does not count.
    let previous = lane.previous.filter(|&(p, _)| p != slot).map(|(_, kept)| kept);
    let plans: Vec<FramePlan> = requests.iter().map(|r| FramePlan::new(r, w, h, previous.as_ref())).collect();
    if let Some(layer) = (1..plans.len()).find(|&l| !plans[l].stacks_with(&plans[0])) {
        return Err(Error::Parameter(format!(
            "stacked frame {layer} asks for other stages or parameters than frame 0; stacked frames may differ \
             only in their lists' windows, thresholds, seeds and caps"
        )));
    }
    let s = lane.slot_mut(slot)?;
    for plan in &plans {
        s.allocate(ctx, plan)?;
    }
    Ok((slot, plans))
}

/// A step of a [`GpuStack`] submitted to the GPU whose results are not yet
/// collected; pass it to [`GpuStack::finish`].
#[derive(Debug)]
#[must_use = "a submitted step must be finished to get its features and free its slot"]
pub struct StackTicket {
    slot: usize,
}

/// Early vision on the GPU for several sequences at once, their frames
/// stacked: every stage is one dispatch for all of them. Each step takes
/// one frame of every sequence (the *layers* of the stack), all of one
/// size, with requests that stack ([`FramePlan::stacks_with`]: the same
/// stages and parameters, each list with its own window, threshold, seed
/// and cap). The features are those [`GpuBackend`] gives each sequence on
/// its own. Up to two steps may be in flight; sample windows and textures
/// are not taken. One sequence may end and another take its layer
/// ([`GpuStack::reset_layer`]) while the others go on.
pub struct GpuStack {
    ctx: GpuContext,
    lane: Lane,
    stats: FrameStats,
    /// Layers whose next frame starts a new sequence.
    fresh: Vec<bool>,
}

impl std::fmt::Debug for GpuStack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuStack")
            .field("adapter", &self.ctx.adapter_name())
            .field("layers", &self.lane.layers)
            .finish()
    }
}

impl GpuStack {
    /// A stack of `layers` sequences (1 to [`MAX_LANES`]) on `ctx`; buffers
    /// are allocated on the first step.
    pub fn new(ctx: GpuContext, layers: usize) -> Result<Self> {
        check_lane_count(layers)?;
        Ok(Self {
            ctx,
            lane: Lane::layered(layers, STACK_SLOTS),
            stats: FrameStats::default(),
            fresh: vec![false; layers],
        })
    }

    /// Sequences in the stack.
    #[must_use]
    pub fn layers(&self) -> usize {
        self.lane.layers
    }

    /// `Ok` when the device holds a step of `width`×`height` frames: every
    /// layer's list of every pixel in one buffer (the largest the stack
    /// makes); otherwise the error of [`compaction::check_list_fits`].
    pub fn check_frame_size(&self, width: usize, height: usize) -> Result<()> {
        let pixels = width.saturating_mul(height).saturating_mul(self.lane.layers);
        compaction::check_list_fits(&self.ctx.device.limits(), pixels)
    }

    /// Dispatch and transfer counts of the last step (bytes read back: its
    /// last layer's).
    #[must_use]
    pub fn last_step_stats(&self) -> FrameStats {
        self.stats
    }

    /// Submit the next frame of every sequence, `frames[l]` with its request
    /// for layer `l`; the GPU starts on them at once. Errors, recording
    /// nothing, unless there is one frame per layer, all of one size, with
    /// requests that stack and no sample windows.
    pub fn submit(&mut self, frames: &[(&GrayImage, &FrameRequest)]) -> Result<StackTicket> {
        let (w, h) = frames.first().map(|(f, _)| f.size()).unwrap_or_default();
        for (layer, (frame, request)) in frames.iter().enumerate() {
            request.validate()?;
            if request.windows.is_some() {
                return Err(Error::Parameter(format!("stacked frame {layer}: sample windows are not stacked")));
            }
            if frame.size() != (w, h) {
                let (fw, fh) = frame.size();
                return Err(Error::Size(format!("stacked frame {layer} is {fw}x{fh}, frame 0 is {w}x{h}")));
            }
        }
        self.lane.check_next_slot_free()?;
        let requests: Vec<&FrameRequest> = frames.iter().map(|(_, r)| *r).collect();
        let (slot, mut plans) = prepare(&self.ctx, &mut self.lane, w, h, &requests)?;
        // A layer starting a new sequence differences against another
        // sequence's frame: its motion list is compacted from no window.
        for (plan, fresh) in plans.iter_mut().zip(&self.fresh) {
            if *fresh {
                plan.empty_list(List::Motion);
            }
        }
        let inputs: Vec<Input<'_>> = frames.iter().map(|(f, _)| Input::Bytes(f, None)).collect();
        let (commands, stats) = record(&self.ctx, &self.lane, slot, &plans, &inputs, None)?;
        self.lane.advance(slot, &plans[0]);
        self.stats.dispatches = stats.dispatches;
        self.stats.bytes_uploaded = stats.bytes_uploaded;
        let submitted = self.ctx.queue.submit([commands]);
        self.lane.slot_mut(slot)?.pending = Some((plans.swap_remove(0), submitted));
        self.fresh.fill(false);
        Ok(StackTicket { slot })
    }

    /// Wait for a submitted step (its own submission only) and read back
    /// every layer's lists, in layer order.
    pub fn finish(&mut self, ticket: StackTicket) -> Result<Vec<FrameFeatures>> {
        let (features, bytes) = finish_in_lane(&self.ctx, &mut self.lane, ticket.slot)?;
        self.stats.bytes_read_back = bytes;
        Ok(features)
    }

    /// Forget the previous frames: the next step starts new sequences.
    pub fn reset(&mut self) {
        self.lane.previous = None;
        self.fresh.fill(false);
    }

    /// Forget the previous frame of `layer` only: its next frame starts a
    /// new sequence (no motion on it), the other layers go on.
    pub fn reset_layer(&mut self, layer: usize) -> Result<()> {
        let fresh = self
            .fresh
            .get_mut(layer)
            .ok_or_else(|| Error::Parameter(format!("layer {layer} out of range (a stack of {})", self.lane.layers)))?;
        *fresh = true;
        Ok(())
    }
}

/// Wait for the frame submitted in `lane`'s `slot` (its own submission
/// only) and read back its lists: the features of each layer and the bytes
/// that crossed the bus for the last layer.
fn finish_in_lane(ctx: &GpuContext, lane: &mut Lane, slot: usize) -> Result<(Vec<FrameFeatures>, u64)> {
    let Lane { slots, listed, layers, .. } = lane;
    let s = slots[slot].as_mut().ok_or_else(|| Error::Gpu("slot vanished".into()))?;
    let (plan, submitted) = s.pending.take().ok_or_else(|| Error::Gpu("ticket already finished".into()))?;
    ctx.wait_for(submitted)?;
    let mut out = vec![FrameFeatures::default(); *layers];
    let mut bytes = 0u64;
    // The lists of a stack are read back on parallel threads, each list's
    // layers decoded in parallel too; a single frame's lists one by one.
    let compacted: Vec<List> = plan
        .steps()
        .iter()
        .filter_map(|step| if let Step::Compact { list, .. } = step { Some(*list) } else { None })
        .collect();
    let read = |list: &List| s.list(*list).and_then(|scratch| scratch.read_layers(ctx));
    let read_lists: Vec<Vec<Vec<Feature>>> = if *layers > 1 {
        compacted.par_iter().map(read).collect::<Result<_>>()?
    } else {
        compacted.iter().map(read).collect::<Result<_>>()?
    };
    for (&list, lists) in compacted.iter().zip(read_lists) {
        let scratch = s.list(list)?;
        for (layer, v) in lists.into_iter().enumerate() {
            if layer + 1 == *layers {
                bytes += scratch.bytes_read_back_layer(layer, v.len());
            }
            listed[layer][list_index(list)] = u32::try_from(v.len()).unwrap_or(u32::MAX);
            *out[layer].list_mut(list) = Some(v);
        }
    }
    for step in plan.steps() {
        match *step {
            Step::EmptyList(list) => {
                for o in &mut out {
                    *o.list_mut(list) = Some(Vec::new());
                }
            }
            Step::Pyramids { returned: true, .. } => {
                let (c, e) = opt(&s.cpf)?;
                let layers = c.download_layers(ctx)?.into_iter().zip(e.download_layers(ctx)?);
                for (o, (pyr, edges)) in out.iter_mut().zip(layers) {
                    o.pyramids = Some((pyr, edges));
                }
                if let Some((pyr, edges)) = out.last().and_then(|o| o.pyramids.as_ref()) {
                    bytes += 4
                        * (pyr.hierarchies.iter().flatten().map(|l| l.data().len()).sum::<usize>()
                            + edges.horizontal.iter().chain(&edges.vertical).map(|l| l.data().len()).sum::<usize>())
                            as u64;
                }
            }
            Step::Windows { count, params, energies } => {
                let buffers = opt(&s.windows)?;
                let o = &mut out[0];
                if energies {
                    let e = if count == 0 {
                        window_energy::normalise_cpu(&[])
                    } else {
                        buffers.read_energies(ctx, count)?
                    };
                    bytes += 4 * (count as u64 + 2);
                    o.window_energies = Some(e);
                } else {
                    let f = if count == 0 { Vec::new() } else { buffers.read_features(ctx, &params, count)? };
                    bytes += 4 * (count * params.window_len()) as u64;
                    o.window_features = Some(f);
                }
            }
            _ => {}
        }
    }
    Ok((out, bytes))
}

/// Upload each layer's `inputs` (bytes, and for sample windows its colour
/// or the grey frame as colour; a texture only for a single layer) and
/// record its ingest and every step of `plans` (one per layer, stacking:
/// see [`FramePlan::stacks_with`]) into one command buffer, with its
/// dispatches and bytes uploaded (the caller makes it the lane's previous
/// frame).
fn record(
    ctx: &GpuContext,
    l: &Lane,
    slot: usize,
    plans: &[FramePlan],
    inputs: &[Input<'_>],
    windows: Option<&WindowRequest>,
) -> Result<(wgpu::CommandBuffer, FrameStats)> {
    let mut stats = FrameStats::default();
    let plan = plans.first().ok_or_else(|| Error::Gpu("no frame to record".into()))?;
    let previous_slot = l.previous.map(|(p, _)| p).filter(|&p| p != slot && plan.reads_previous());
    let s = l.slot(slot)?;
    if plans.len() != s.layers || inputs.len() != s.layers {
        return Err(Error::Gpu(format!("{} plans and {} frames for {} layers", plans.len(), inputs.len(), s.layers)));
    }
    let previous = previous_slot.and_then(|p| l.slots[p].as_ref()).map(|o| &o.smoothed);
    let images = FrameImages { slot: s, previous };
    let area = s.width * s.height;

    let mut rec = Recorder::new(ctx, &s.arena);
    let layer_bytes = (ingest::packed_words(s.width, s.height) * 4) as u64;
    let mut uploaded = 0;
    for (layer, input) in inputs.iter().enumerate() {
        match *input {
            Input::Bytes(frame, colour) => {
                uploaded += ingest::write_bytes_at(ctx, &s.packed, layer as u64 * layer_bytes, frame.data());
                if let Some(buffers) = &s.windows
                    && windows.is_some()
                {
                    let rgb = match colour {
                        Some(c) => window_energy::pack_rgb(c),
                        None => window_energy::pack_gray(frame),
                    };
                    buffers.write_frame(ctx, &rgb);
                    uploaded += rgb.len() * 4;
                }
            }
            Input::Texture(texture) if s.layers == 1 => ingest::encode_texture(&mut rec, texture, &s.luma)?,
            Input::Texture(_) => return Err(Error::Parameter("stacked frames are uploaded as bytes".into())),
        }
    }
    stats.bytes_uploaded = uploaded as u64;
    if inputs.iter().all(|i| matches!(i, Input::Bytes(..))) {
        ingest::encode(&mut rec, &s.packed, &s.luma)?;
    }
    let crossings_part = crossings_part(plans, s.width, s.height);
    for (i, step) in plan.steps().iter().enumerate() {
        match *step {
            Step::Smooth(p) => gaussian::encode(&mut rec, &s.luma, &s.tmp, &s.smoothed, &p)?,
            Step::DiffAndSum(p) => {
                // 000 eq. 1 and the sum of eq. 2, as in the CPU backend.
                let (prev, cur) = (images.plane(Plane::Previous)?, &s.smoothed);
                let (mask, sum) = (images.plane(Plane::MotionMask)?, images.plane(Plane::Sum)?);
                temporal_diff::encode_with_sum(&mut rec, prev, cur, mask, sum, &p)?;
            }
            Step::Sobel { input, output } => sobel::encode(&mut rec, images.plane(input)?, s.sobel_set(output)?)?,
            Step::Log(p) => {
                let part = crossings_part.grown(1);
                log::encode(&mut rec, &s.luma, &s.tmp, &s.tmp2, images.plane(Plane::Log)?, &p, part)?;
            }
            Step::ZeroCrossings(p) => {
                zero_crossing::encode(&mut rec, images.plane(Plane::Log)?, opt(&s.edgels)?, &p, crossings_part)?;
            }
            Step::Compact { list, select, theta, magnitude, .. } => {
                let scratch = s.list(list)?;
                let (sel, th, mag) = (images.source(select)?, images.source(theta)?, images.source(magnitude)?);
                let params: Vec<CompactionParams> = plans
                    .iter()
                    .map(|p| match p.steps().get(i) {
                        Some(Step::Compact { params, .. }) => Ok(*params),
                        _ => Err(Error::Gpu("stacked plans differ".into())),
                    })
                    .collect::<Result<_>>()?;
                compaction::encode_layers(&mut rec, sel, th, mag, &params, scratch)?;
                let prefetch: Vec<u32> = params
                    .iter()
                    .zip(&l.listed)
                    .map(|(p, last)| readback_prefetch(p.cap, area, last[list_index(list)]))
                    .collect();
                scratch.encode_readback_layers(&mut rec, &prefetch);
            }
            Step::EmptyList(_) => {}
            Step::Pyramids { gradient, .. } => {
                let (c, e) = opt(&s.cpf)?;
                let g = s.sobel_set(gradient)?;
                cpf::encode(&mut rec, &s.luma, c)?;
                edge_pyramid::encode(&mut rec, &g.gx, &g.gy, e)?;
            }
            Step::Windows { count, .. } => {
                let buffers = opt(&s.windows)?;
                let size = (s.width, s.height);
                match windows {
                    _ if count == 0 => {}
                    Some(WindowRequest::Features { params, windows }) => {
                        buffers.encode_features(&mut rec, ctx, size, params, windows)?;
                    }
                    Some(WindowRequest::Energies { windows, template }) => {
                        buffers.encode_energies(&mut rec, ctx, size, windows, template)?;
                    }
                    None => return Err(Error::Gpu("plan has sample windows the request has not".into())),
                }
            }
        }
    }
    stats.dispatches = rec.dispatch_count();
    Ok((rec.finish(), stats))
}

/// Where the zero crossings are computed (and the LoG, one pixel around):
/// the union of every layer's windows of the lists reading them
/// ([`FramePlan::log_windows`]), or the whole frame when a layer reads them
/// elsewhere. The lists are those of the whole frame's crossings.
fn crossings_part(plans: &[FramePlan], width: usize, height: usize) -> Window {
    let mut union = Window::default();
    for plan in plans {
        match plan.log_windows(width, height) {
            Some(windows) => union = union.union(&windows),
            None => return Window::full(width, height),
        }
    }
    union
}

fn first_layer(mut features: Vec<FrameFeatures>) -> Result<FrameFeatures> {
    features.truncate(1);
    features.pop().ok_or_else(|| Error::Gpu("no layer was read back".into()))
}

fn first_ticket(mut tickets: Vec<Ticket>) -> Result<Ticket> {
    tickets.pop().ok_or_else(|| Error::Gpu("no frame was submitted".into()))
}

fn opt<T>(v: &Option<T>) -> Result<&T> {
    v.as_ref().ok_or_else(|| Error::Gpu("stage buffers not allocated".into()))
}

impl EarlyVision for GpuBackend {
    fn name(&self) -> String {
        format!("GPU: {}", self.ctx.adapter_name())
    }

    fn reset(&mut self) {
        self.reset_lane(0);
    }

    /// A list may hold every pixel of the frame (a window of the whole
    /// frame, uncapped) and must fit one storage binding of the device; every
    /// f32 image of the frame is smaller than such a list.
    fn check_frame_size(&self, width: usize, height: usize) -> Result<()> {
        crate::early::compaction::check_list_fits(&self.ctx.device.limits(), width.saturating_mul(height))
    }

    fn process(&mut self, frame: &GrayImage, request: &FrameRequest) -> Result<FrameFeatures> {
        let t = self.submit(frame, request)?;
        self.finish(t)
    }

    fn process_rgb(&mut self, frame: &RgbImage, request: &FrameRequest) -> Result<FrameFeatures> {
        let t = self.submit_rgb(frame, request)?;
        self.finish(t)
    }

    fn process_texture(&mut self, texture: &wgpu::Texture, request: &FrameRequest) -> Result<FrameFeatures> {
        GpuBackend::process_texture(self, texture, request)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The readback follows the lane's last list with a quarter to spare,
    /// never below the default, never above the cap or the list's capacity.
    #[test]
    fn readback_prefetch_follows_the_last_frame_within_cap_and_capacity() {
        assert_eq!(readback_prefetch(None, 1_000_000, 0), DEFAULT_PREFETCH);
        assert_eq!(readback_prefetch(None, 1_000_000, 100), DEFAULT_PREFETCH);
        assert_eq!(readback_prefetch(None, 1_000_000, 40_000), 50_000);
        assert_eq!(readback_prefetch(None, 45_000, 40_000), 45_000);
        assert_eq!(readback_prefetch(Some(1500), 1_000_000, 40_000), 1500);
        assert_eq!(readback_prefetch(Some(100_000), 1_000_000, 40_000), 50_000);
        assert_eq!(readback_prefetch(None, 10, 0), 10);
        assert_eq!(readback_prefetch(None, usize::MAX, u32::MAX), u32::MAX);
    }
}
