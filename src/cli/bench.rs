//! Benchmark runners shared by `cargo bench` and `pipetrack bench`: every
//! stage and the whole chain, prepared once on resident data, then timed on
//! the CPU and on the GPU side by side.

use std::time::{Duration, Instant};

use serde::Serialize;

use crate::backend::plan::PreviousFrame;
use rayon::prelude::*;

use crate::backend::{
    CpuBackend, EarlyVision, FramePlan, FrameRequest, FrameStats, GpuBackend, GpuStack, LaneFrame, Ticket,
    check_lane_count, lane_groups,
};
use crate::early::compaction::{self, CompactionGpu, CompactionParams};
use crate::early::cpf::{self, CpfGpu, CpfPyramids};
use crate::early::edge_pyramid::{self, EdgePyramidGpu, EdgePyramids};
use crate::early::gaussian::{self, GaussianParams};
use crate::early::log::{self, LogParams};
use crate::early::sobel::{self, SobelGpu, SobelOutput};
use crate::early::temporal_diff::{self, TemporalDiffParams};
use crate::early::zero_crossing::{self, Edgels, EdgelsGpu, ZeroCrossingParams};
use crate::early::{Window, frame_sum};
use crate::gpu::{FrameArena, GpuContext, GpuImage, Recorder};
use crate::image::{FloatImage, GrayImage};
use crate::testimage::natural;
use crate::{Error, Result};

/// The whole frame, every stage of the full chain: the last benchmark.
const CHAIN: &str = "chain";

/// The stages benchmarked, by the names used in shader files and bench ids:
/// those the plan of [`FrameRequest::full_chain`] runs on a frame that has a
/// previous one (so motion runs too), in plan order, then `chain`.
#[must_use]
pub fn stages() -> Vec<&'static str> {
    // Which stages a plan runs does not depend on the frame size.
    let (w, h) = (1, 1);
    let request = FrameRequest::full_chain(w, h);
    let previous = PreviousFrame { width: w, height: h, smoothing: request.smoothing };
    let mut names = FramePlan::new(&request, w, h, Some(&previous)).stage_names();
    names.push(CHAIN);
    names
}

/// Frames in the synthetic sequence the chain benchmark streams through.
const CHAIN_FRAMES: usize = 8;
/// Stage dispatches recorded per GPU submission when timing one stage.
const GPU_REPEATS: usize = 8;
/// Submissions queued before each wait when timing one stage, so a fast
/// device is timed on its work more than on the wait's round trip.
const GPU_SUBMISSIONS: usize = 8;

/// A prepared benchmark body: one call = one frame's worth of that stage.
pub type Body<'a> = Box<dyn FnMut() -> Result<()> + 'a>;

/// Inputs shared by the stage bodies: a natural-looking frame pair at one size.
pub struct Inputs {
    /// Frames of a short sequence (a textured scene shifting one pixel per frame).
    pub frames: Vec<GrayImage>,
    /// First frame as f32.
    pub luma: FloatImage,
    /// The first two frames smoothed with σ = 1.
    pub smoothed: [FloatImage; 2],
    /// Cap on every list of the whole chain with sequences in flight
    /// ([`Inputs::chain_request`]); `None`: every listed pixel comes back.
    pub list_cap: Option<u32>,
}

impl Inputs {
    /// Inputs of `width`×`height`.
    pub fn new(width: usize, height: usize) -> Result<Self> {
        let base = natural(width + CHAIN_FRAMES, height, 2024);
        let frames: Vec<GrayImage> =
            (0..CHAIN_FRAMES).map(|k| GrayImage::from_fn(width, height, |x, y| base.get(x + k, y))).collect();
        let luma = frames[0].to_f32();
        let p = GaussianParams::default();
        let smoothed = [gaussian::gaussian(&luma, &p)?, gaussian::gaussian(&frames[1].to_f32(), &p)?];
        Ok(Self { frames, luma, smoothed, list_cap: None })
    }

    /// The request of the whole chain with sequences in flight: every list
    /// of the frame ([`FrameRequest::full_chain`]), each capped at
    /// [`Inputs::list_cap`] (a stratified subsample, as 002 caps its list).
    #[must_use]
    pub fn chain_request(&self) -> FrameRequest {
        let (w, h) = self.luma.size();
        let mut request = FrameRequest::full_chain(w, h);
        for list in [
            request.motion.as_mut().map(|m| &mut m.list),
            request.edges.as_mut().map(|e| &mut e.list),
            request.zero_crossings.as_mut().map(|z| &mut z.list),
        ]
        .into_iter()
        .flatten()
        {
            list.cap = self.list_cap;
        }
        request
    }
}

/// Threshold on Sobel magnitude used by the compaction benchmark.
const EDGE_THRESHOLD: f32 = 60.0;

/// The CPU body of `stage` (caller-allocated outputs, allocated here once).
pub fn cpu_body<'a>(stage: &str, inp: &'a Inputs) -> Result<Body<'a>> {
    let (w, h) = inp.luma.size();
    let mut a = FloatImage::new(w, h);
    let mut b = FloatImage::new(w, h);
    let mut c = FloatImage::new(w, h);
    Ok(match stage {
        "gaussian" => Box::new(move || gaussian::gaussian_cpu(&inp.luma, &GaussianParams::default(), &mut a, &mut b)),
        "temporal_diff" => Box::new(move || {
            temporal_diff::temporal_diff_cpu(&inp.smoothed[0], &inp.smoothed[1], &TemporalDiffParams::default(), &mut a)
        }),
        "frame_sum" => Box::new(move || frame_sum::frame_sum_cpu(&inp.smoothed[0], &inp.smoothed[1], &mut a)),
        "sobel" => {
            let mut out = SobelOutput::new(w, h);
            Box::new(move || {
                sobel::sobel_cpu(&inp.luma, &mut out);
                Ok(())
            })
        }
        "log" => Box::new(move || log::log_cpu(&inp.luma, &LogParams::default(), &mut a, &mut b, &mut c)),
        "zero_crossing" => {
            let l = log::log(&inp.luma, &LogParams::default())?;
            let mut out = Edgels::new(w, h);
            Box::new(move || {
                zero_crossing::zero_crossing_cpu(&l, &ZeroCrossingParams::default(), &mut out);
                Ok(())
            })
        }
        "cpf" => {
            let mut out = CpfPyramids::default();
            Box::new(move || {
                cpf::cpf_cpu(&inp.luma, &mut out);
                Ok(())
            })
        }
        "edge_pyramid" => {
            let s = sobel::sobel(&inp.luma);
            let mut out = EdgePyramids::default();
            Box::new(move || edge_pyramid::edge_pyramid_cpu(&s.gx, &s.gy, &mut out))
        }
        "compaction" => {
            let s = sobel::sobel(&inp.luma);
            let p = compaction_params(w, h);
            let mut list = Vec::new();
            Box::new(move || compaction::compaction_cpu(&s.magnitude, &s.direction, &s.magnitude, &p, &mut list))
        }
        CHAIN => {
            let mut backend = CpuBackend::new();
            let request = FrameRequest::full_chain(w, h);
            let mut i = 0;
            Box::new(move || {
                let features = backend.process(&inp.frames[i % inp.frames.len()], &request)?;
                backend.recycle(features);
                i += 1;
                Ok(())
            })
        }
        other => return Err(Error::Parameter(format!("unknown stage {other:?}; known: {}", stages().join(", ")))),
    })
}

fn compaction_params(w: usize, h: usize) -> CompactionParams {
    CompactionParams { window: Window::full(w, h), threshold: EDGE_THRESHOLD, cap: Some(1500), seed: 1 }
}

/// The GPU body of `stage`: inputs resident on the device, the stage recorded
/// `GPU_REPEATS` times into each of `GPU_SUBMISSIONS` submissions, then one
/// wait. One call = `GPU_REPEATS × GPU_SUBMISSIONS` frames' worth; see
/// [`gpu_frames_per_call`]. The chain streams whole frames
/// (upload, compute, readback) through [`GpuBackend::process_stream`].
pub fn gpu_body<'a>(stage: &str, ctx: &'a GpuContext, inp: &'a Inputs) -> Result<Body<'a>> {
    let (w, h) = inp.luma.size();
    if stage == CHAIN {
        let mut backend = GpuBackend::new(ctx.clone());
        let request = FrameRequest::full_chain(w, h);
        return Ok(Box::new(move || backend.process_stream(&inp.frames, &request, |_, _| {})));
    }
    let img = |f: &FloatImage, label| GpuImage::from_image(ctx, f, label);
    let luma = img(&inp.luma, "bench.luma");
    let s0 = img(&inp.smoothed[0], "bench.s0");
    let s1 = img(&inp.smoothed[1], "bench.s1");
    let t1 = GpuImage::new(ctx, w, h, "bench.t1");
    let t2 = GpuImage::new(ctx, w, h, "bench.t2");
    let t3 = GpuImage::new(ctx, w, h, "bench.t3");
    let sob = SobelGpu::new(ctx, w, h);
    let edg = EdgelsGpu::new(ctx, w, h);
    let pyr = CpfGpu::new(ctx, w, h);
    let edge_pyr = EdgePyramidGpu::new(ctx, w, h);
    let list = CompactionGpu::new(ctx, w * h, Some(1500))?;
    let arena = FrameArena::new(ctx);
    let stage: &'static str = stages()
        .into_iter()
        .find(|s| *s == stage)
        .ok_or_else(|| Error::Parameter(format!("unknown stage {stage:?}")))?;
    // Inputs that are outputs of earlier stages are computed once up front.
    crate::gpu::run_once(ctx, |rec| {
        sobel::encode(rec, &luma, &sob)?;
        log::encode(rec, &luma, &t1, &t2, &t3, &LogParams::default(), Window::full(w, h))
    })?;
    Ok(Box::new(move || {
        let mut last = None;
        for _ in 0..GPU_SUBMISSIONS {
            let mut rec = Recorder::new(ctx, &arena);
            for _ in 0..GPU_REPEATS {
                record_stage(
                    &mut rec,
                    stage,
                    &luma,
                    &s0,
                    &s1,
                    [&t1, &t2, &t3],
                    &sob,
                    &edg,
                    (&pyr, &edge_pyr),
                    &list,
                    w,
                    h,
                )?;
            }
            last = Some(rec.submit());
        }
        last.map_or(Ok(()), |index| ctx.wait_for(index))
    }))
}

#[allow(clippy::too_many_arguments)]
fn record_stage(
    rec: &mut Recorder<'_>,
    stage: &str,
    luma: &GpuImage,
    s0: &GpuImage,
    s1: &GpuImage,
    t: [&GpuImage; 3],
    sob: &SobelGpu,
    edg: &EdgelsGpu,
    (pyr, edge_pyr): (&CpfGpu, &EdgePyramidGpu),
    list: &CompactionGpu,
    w: usize,
    h: usize,
) -> Result<()> {
    let full = Window::full(w, h);
    match stage {
        "gaussian" => gaussian::encode(rec, luma, t[0], t[1], &GaussianParams::default()),
        "temporal_diff" => temporal_diff::encode(rec, s0, s1, t[0], &TemporalDiffParams::default()),
        "frame_sum" => frame_sum::encode(rec, s0, s1, t[0]),
        "sobel" => sobel::encode(rec, luma, sob),
        // t[2] holds the LoG computed up front; LoG writes into other buffers.
        "log" => log::encode(rec, luma, t[0], t[1], s1, &LogParams::default(), full),
        "zero_crossing" => zero_crossing::encode(rec, t[2], edg, &ZeroCrossingParams::default(), full),
        "cpf" => cpf::encode(rec, luma, pyr),
        "edge_pyramid" => edge_pyramid::encode(rec, &sob.gx, &sob.gy, edge_pyr),
        "compaction" => {
            compaction::encode(rec, &sob.magnitude, &sob.direction, &sob.magnitude, &compaction_params(w, h), list)
        }
        other => Err(Error::Parameter(format!("unknown stage {other:?}"))),
    }
}

/// The row name of the whole chain timed with `lanes` sequences in flight.
#[must_use]
pub fn lanes_stage(lanes: usize) -> String {
    format!("chain x{lanes}")
}

/// The whole chain on `lanes` independent sequences at once, as `batch`
/// runs them on the GPU: each step records the next frame of every lane of
/// one group into one submission, and two groups take turns so one is on
/// the device while the other's features are read back. One call is a
/// fixed number of steps, [`lanes_frames_per_call`] frames in all.
pub fn gpu_lanes_body<'a>(ctx: &'a GpuContext, inp: &'a Inputs, lanes: usize) -> Result<Body<'a>> {
    check_lane_count(lanes)?;
    let mut backend = GpuBackend::new(ctx.clone());
    let request = inp.chain_request();
    let groups = lane_groups(lanes);
    Ok(Box::new(move || {
        let n = inp.frames.len();
        let mut pending: Vec<Vec<Ticket>> = groups.iter().map(|_| Vec::new()).collect();
        for step in 0..CHAIN_FRAMES {
            for (group, tickets) in groups.iter().zip(&mut pending) {
                for features in backend.finish_lanes(std::mem::take(tickets))? {
                    backend.recycle(features);
                }
                let frames: Vec<LaneFrame<'_>> = group
                    .iter()
                    .map(|&lane| LaneFrame {
                        lane,
                        frame: &inp.frames[(step + lane) % n],
                        colour: None,
                        request: &request,
                    })
                    .collect();
                *tickets = backend.submit_lanes(&frames)?;
            }
        }
        for tickets in pending {
            for features in backend.finish_lanes(tickets)? {
                backend.recycle(features);
            }
        }
        Ok(())
    }))
}

/// The CPU counterpart of [`gpu_lanes_body`]: `lanes` CPU backends, each
/// step processing one frame of every lane in parallel on the thread pool.
pub fn cpu_lanes_body<'a>(inp: &'a Inputs, lanes: usize) -> Result<Body<'a>> {
    check_lane_count(lanes)?;
    let mut backends: Vec<CpuBackend> = (0..lanes).map(|_| CpuBackend::new()).collect();
    let request = inp.chain_request();
    Ok(Box::new(move || {
        let n = inp.frames.len();
        for step in 0..CHAIN_FRAMES {
            backends.par_iter_mut().enumerate().try_for_each(|(lane, backend)| {
                let features = backend.process(&inp.frames[(step + lane) % n], &request)?;
                backend.recycle(features);
                Ok::<(), Error>(())
            })?;
        }
        Ok(())
    }))
}

/// Host time per frame with `lanes` sequences in flight, in milliseconds:
/// recording and submitting a step's frames, then reading their lists back
/// once the device is done, without the wait for the device; the median and
/// the fastest of [`HOST_FRAMES`] steps, and the GPU work of the last frame.
pub fn host_time(ctx: &GpuContext, inp: &Inputs, lanes: usize) -> Result<(FrameStats, f64, f64)> {
    check_lane_count(lanes)?;
    let mut backend = GpuBackend::new(ctx.clone());
    let request = inp.chain_request();
    let n = inp.frames.len();
    let mut per_frame = Vec::with_capacity(HOST_FRAMES);
    // Frames go back and forth through the sequence, so each differs from
    // its previous one by one shift. Two untimed steps first: buffers are
    // allocated, lists sized, and the timed frames all have a previous one
    // (so the motion stages run).
    let back_and_forth = |i: usize| {
        if n < 2 {
            return 0;
        }
        let period = 2 * (n - 1);
        let k = i % period;
        if k < n { k } else { period - k }
    };
    for step in 0..HOST_FRAMES + 2 {
        let frames: Vec<LaneFrame<'_>> = (0..lanes)
            .map(|lane| LaneFrame {
                lane,
                frame: &inp.frames[back_and_forth(step + lane)],
                colour: None,
                request: &request,
            })
            .collect();
        let record = Instant::now();
        let tickets = backend.submit_lanes(&frames)?;
        let recorded = record.elapsed();
        // Not timed: the device's own work.
        ctx.wait()?;
        let readback = Instant::now();
        for features in backend.finish_lanes(tickets)? {
            backend.recycle(features);
        }
        if step >= 2 {
            per_frame.push((recorded + readback.elapsed()).as_secs_f64() * 1e3 / lanes as f64);
        }
    }
    per_frame.sort_by(f64::total_cmp);
    Ok((backend.last_frame_stats(), per_frame[per_frame.len() / 2], per_frame[0]))
}

/// The row name of the whole chain with `lanes` sequences stacked
/// ([`GpuStack`]: each stage one dispatch for all of them).
#[must_use]
pub fn stacked_stage(lanes: usize) -> String {
    format!("chain stacked x{lanes}")
}

/// The whole chain on `lanes` sequences stacked in one [`GpuStack`]: each
/// step is one submission of one dispatch per stage for all of them, with
/// the step before read back while the device works on it. One call is
/// [`lanes_frames_per_call`] frames, as for [`gpu_lanes_body`].
pub fn gpu_stacked_body<'a>(ctx: &'a GpuContext, inp: &'a Inputs, lanes: usize) -> Result<Body<'a>> {
    let mut stack = GpuStack::new(ctx.clone(), lanes)?;
    let request = inp.chain_request();
    Ok(Box::new(move || {
        let n = inp.frames.len();
        let mut pending = None;
        for step in 0..CHAIN_FRAMES {
            let frames: Vec<(&GrayImage, &FrameRequest)> =
                (0..lanes).map(|lane| (&inp.frames[(step + lane) % n], &request)).collect();
            let ticket = stack.submit(&frames)?;
            if let Some(previous) = pending.replace(ticket) {
                stack.finish(previous)?;
            }
        }
        if let Some(last) = pending {
            stack.finish(last)?;
        }
        Ok(())
    }))
}

/// [`host_time`] for `lanes` sequences stacked in one [`GpuStack`]: the
/// median and fastest host time per frame (recording and submitting a
/// step, reading its lists back; the device's work not counted), and the
/// dispatches of a step.
pub fn stacked_host_time(ctx: &GpuContext, inp: &Inputs, lanes: usize) -> Result<(u32, f64, f64)> {
    let mut stack = GpuStack::new(ctx.clone(), lanes)?;
    let request = inp.chain_request();
    let n = inp.frames.len();
    let mut per_frame = Vec::with_capacity(HOST_FRAMES);
    for step in 0..HOST_FRAMES + 2 {
        let frames: Vec<(&GrayImage, &FrameRequest)> =
            (0..lanes).map(|lane| (&inp.frames[(step + lane) % n], &request)).collect();
        let record = Instant::now();
        let ticket = stack.submit(&frames)?;
        let recorded = record.elapsed();
        // Not timed: the device's own work.
        ctx.wait()?;
        let readback = Instant::now();
        stack.finish(ticket)?;
        if step >= 2 {
            per_frame.push((recorded + readback.elapsed()).as_secs_f64() * 1e3 / lanes as f64);
        }
    }
    per_frame.sort_by(f64::total_cmp);
    Ok((stack.last_step_stats().dispatches, per_frame[per_frame.len() / 2], per_frame[0]))
}

/// Frames' worth of work one call of a lanes body does.
#[must_use]
pub fn lanes_frames_per_call(lanes: usize) -> usize {
    CHAIN_FRAMES * lanes
}

/// Frames' worth of work one call of a GPU body does.
#[must_use]
pub fn gpu_frames_per_call(stage: &str) -> usize {
    if stage == CHAIN { CHAIN_FRAMES } else { GPU_REPEATS * GPU_SUBMISSIONS }
}

/// Frames' worth of work one call of a CPU body does.
#[must_use]
pub fn cpu_frames_per_call(_stage: &str) -> usize {
    1
}

/// Frames per second of a timed body, from its median call and from its
/// fastest call.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Rate {
    /// Frames per second of the median call.
    pub median_fps: f64,
    /// Frames per second of the fastest call: on a machine shared with
    /// other processes, the figure least disturbed by them (a long call is
    /// more often interrupted than a short one, which skews a median).
    pub best_fps: f64,
}

/// Time `body` for about `budget` (at least three calls), after one warm-up call.
pub fn frames_per_second(body: &mut Body<'_>, frames_per_call: usize, budget: Duration) -> Result<Rate> {
    body()?;
    let start = Instant::now();
    let mut seconds = Vec::new();
    while seconds.len() < 3 || start.elapsed() < budget {
        let call = Instant::now();
        body()?;
        seconds.push(call.elapsed().as_secs_f64());
    }
    seconds.sort_by(f64::total_cmp);
    let fps = |s: f64| frames_per_call as f64 / s;
    Ok(Rate { median_fps: fps(seconds[seconds.len() / 2]), best_fps: fps(seconds[0]) })
}

/// One row of a comparison: a stage at a size on both backends.
#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    /// Stage name (or `chain`).
    pub stage: String,
    /// `WxH`.
    pub size: String,
    /// CPU frames per second (median call).
    pub cpu_fps: f64,
    /// CPU frames per second of the fastest call.
    pub cpu_best_fps: f64,
    /// GPU frames per second (median call), if a GPU was available.
    pub gpu_fps: Option<f64>,
    /// GPU fps / CPU fps.
    pub gpu_over_cpu: Option<f64>,
}

/// GPU work per frame of the whole chain at one size.
#[derive(Clone, Debug, Serialize)]
pub struct ChainCost {
    /// `WxH`.
    pub size: String,
    /// Dispatches and bytes across the bus for one frame.
    pub per_frame: FrameStats,
    /// Host time per frame in milliseconds (median over [`HOST_FRAMES`]
    /// frames): recording and submitting the frame, then reading its lists
    /// back once the device is done, without the wait for the device.
    pub host_ms: f64,
    /// Host time of the fastest of those frames, in milliseconds.
    pub host_best_ms: f64,
}

/// Frames timed for [`ChainCost::host_ms`].
pub const HOST_FRAMES: usize = 24;

/// A whole comparison run.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// The GPU adapter, or why there is none.
    pub adapter: String,
    /// CPU threads used by the CPU backend.
    pub cpu_threads: usize,
    /// Rows in size-major order.
    pub rows: Vec<BenchRow>,
    /// Per-frame GPU cost of the chain at each size (empty without a GPU).
    pub gpu_chain: Vec<ChainCost>,
    /// Host time per frame of the chain with several sequences in flight
    /// (`bench --lanes`; empty otherwise or without a GPU).
    pub gpu_lanes: Vec<LanesCost>,
}

/// Host time per frame of the whole chain with `lanes` sequences in flight
/// ([`host_time`]), or stacked ([`stacked_host_time`]).
#[derive(Clone, Debug, Serialize)]
pub struct LanesCost {
    /// `WxH`.
    pub size: String,
    /// Sequences in flight.
    pub lanes: usize,
    /// Whether they were stacked in one [`GpuStack`].
    pub stacked: bool,
    /// Dispatches of one step (every sequence's frame).
    pub dispatches_per_step: u32,
    /// Host milliseconds per frame, median step.
    pub host_ms: f64,
}

/// The GPU context for a comparison (`gpu` asks for one) and the adapter's
/// name, or why there is none.
pub(crate) fn open_gpu(gpu: bool) -> (String, Option<GpuContext>) {
    match gpu.then(GpuContext::new) {
        None => ("not used (CPU only)".to_string(), None),
        Some(Ok(ctx)) => (ctx.adapter_name().to_string(), Some(ctx)),
        Some(Err(e)) => (format!("none ({e})"), None),
    }
}

/// Time a CPU body (with its frames per call), then, on `gpu` (with its
/// frames per call), the body `make_gpu` builds once the CPU body is gone,
/// into a row named `stage` at `w`×`h`.
fn timed_row<'a>(
    stage: String,
    (w, h): (usize, usize),
    budget: Duration,
    (mut cpu, cpu_frames): (Body<'a>, usize),
    gpu: Option<(&'a GpuContext, usize)>,
    make_gpu: impl FnOnce(&'a GpuContext) -> Result<Body<'a>>,
) -> Result<BenchRow> {
    let cpu_rate = frames_per_second(&mut cpu, cpu_frames, budget)?;
    drop(cpu);
    let gpu_fps = match gpu {
        Some((ctx, frames)) => Some(frames_per_second(&mut make_gpu(ctx)?, frames, budget)?.median_fps),
        None => None,
    };
    Ok(BenchRow {
        stage,
        size: format!("{w}x{h}"),
        cpu_fps: cpu_rate.median_fps,
        cpu_best_fps: cpu_rate.best_fps,
        gpu_fps,
        gpu_over_cpu: gpu_fps.map(|g| g / cpu_rate.median_fps),
    })
}

/// Run every stage at every size on the CPU and, with `gpu`, on the GPU too.
pub fn compare(
    sizes: &[(usize, usize)],
    stages: &[&str],
    budget: Duration,
    gpu: bool,
    mut progress: impl FnMut(&BenchRow),
) -> Result<BenchReport> {
    let (adapter, gpu) = open_gpu(gpu);
    let mut rows = Vec::new();
    let mut gpu_chain = Vec::new();
    for &(w, h) in sizes {
        let inp = Inputs::new(w, h)?;
        if let Some(ctx) = &gpu {
            let (per_frame, host_ms, host_best_ms) = host_time(ctx, &inp, 1)?;
            gpu_chain.push(ChainCost { size: format!("{w}x{h}"), per_frame, host_ms, host_best_ms });
        }
        for &stage in stages {
            let row = timed_row(
                stage.to_string(),
                (w, h),
                budget,
                (cpu_body(stage, &inp)?, cpu_frames_per_call(stage)),
                gpu.as_ref().map(|ctx| (ctx, gpu_frames_per_call(stage))),
                |ctx| gpu_body(stage, ctx, &inp),
            )?;
            progress(&row);
            rows.push(row);
        }
    }
    Ok(BenchReport { adapter, cpu_threads: rayon::current_num_threads(), rows, gpu_chain, gpu_lanes: Vec::new() })
}

/// The whole chain at every size with each number of sequences in flight
/// ([`gpu_lanes_body`], [`cpu_lanes_body`]), CPU and, with `gpu`, GPU; with
/// a GPU also stacked ([`gpu_stacked_body`], a row beside the CPU figures
/// of the row before). With `list_cap` every list is capped
/// ([`Inputs::chain_request`]) and the rows' names say so.
pub fn compare_lanes(
    sizes: &[(usize, usize)],
    lanes: &[usize],
    list_cap: Option<u32>,
    budget: Duration,
    gpu: bool,
    mut progress: impl FnMut(&BenchRow),
) -> Result<BenchReport> {
    for &k in lanes {
        check_lane_count(k)?;
    }
    let (adapter, gpu) = open_gpu(gpu);
    let mut rows = Vec::new();
    let mut gpu_lanes = Vec::new();
    for &(w, h) in sizes {
        let inp = Inputs { list_cap, ..Inputs::new(w, h)? };
        let capped = |name: String| list_cap.map_or(name.clone(), |c| format!("{name} cap {c}"));
        for &k in lanes {
            let size = format!("{w}x{h}");
            if let Some(ctx) = &gpu {
                let (stats, host_ms, _) = host_time(ctx, &inp, k)?;
                let dispatches_per_step = stats.dispatches * k as u32;
                gpu_lanes.push(LanesCost {
                    size: size.clone(),
                    lanes: k,
                    stacked: false,
                    dispatches_per_step,
                    host_ms,
                });
            }
            let row = timed_row(
                capped(lanes_stage(k)),
                (w, h),
                budget,
                (cpu_lanes_body(&inp, k)?, lanes_frames_per_call(k)),
                gpu.as_ref().map(|ctx| (ctx, lanes_frames_per_call(k))),
                |ctx| gpu_lanes_body(ctx, &inp, k),
            )?;
            progress(&row);
            if let Some(ctx) = &gpu {
                let (dispatches_per_step, host_ms, _) = stacked_host_time(ctx, &inp, k)?;
                gpu_lanes.push(LanesCost { size: size.clone(), lanes: k, stacked: true, dispatches_per_step, host_ms });
                let mut body = gpu_stacked_body(ctx, &inp, k)?;
                let fps = frames_per_second(&mut body, lanes_frames_per_call(k), budget)?.median_fps;
                drop(body);
                let stacked = BenchRow {
                    stage: capped(stacked_stage(k)),
                    gpu_fps: Some(fps),
                    gpu_over_cpu: Some(fps / row.cpu_fps),
                    ..row.clone()
                };
                rows.push(row);
                progress(&stacked);
                rows.push(stacked);
            } else {
                rows.push(row);
            }
        }
    }
    Ok(BenchReport { adapter, cpu_threads: rayon::current_num_threads(), rows, gpu_chain: Vec::new(), gpu_lanes })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::MAX_LANES;

    /// Every stage the full chain's plan runs has a benchmark body, and the
    /// list ends with the whole chain.
    #[test]
    fn every_planned_stage_has_a_cpu_body() {
        let names = stages();
        assert_eq!(names.last(), Some(&CHAIN));
        assert!(names.len() > 1);
        let inputs = Inputs::new(12, 9).unwrap();
        for stage in names {
            let mut body = cpu_body(stage, &inputs).unwrap();
            body().unwrap();
        }
    }

    /// The lanes bodies run, and a number of lanes outside 1..=MAX_LANES is
    /// refused with the range.
    #[test]
    fn lanes_bodies_run_and_refuse_out_of_range_counts() {
        let inputs = Inputs::new(13, 9).unwrap();
        for k in [1, 3] {
            let mut body = cpu_lanes_body(&inputs, k).unwrap();
            body().unwrap();
        }
        for k in [0, MAX_LANES + 1] {
            let message = cpu_lanes_body(&inputs, k).err().unwrap().to_string();
            assert!(message.contains(&format!("1 to {MAX_LANES}")), "{message}");
            assert!(compare_lanes(&[(13, 9)], &[k], None, Duration::from_millis(1), false, |_| {}).is_err());
        }
        let report = compare_lanes(&[(13, 9)], &[2], None, Duration::from_millis(1), false, |_| {}).unwrap();
        assert_eq!(report.rows.len(), 1);
        assert_eq!(report.rows[0].stage, "chain x2");
        let capped = compare_lanes(&[(13, 9)], &[2], Some(7), Duration::from_millis(1), false, |_| {}).unwrap();
        assert_eq!(capped.rows[0].stage, "chain x2 cap 7");
        assert!(report.rows[0].cpu_fps > 0.0 && report.rows[0].gpu_fps.is_none());
    }
}
