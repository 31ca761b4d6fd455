//! Tracking many sequences at once, each written to its own JSON Lines file
//! as [`run::track_to_file`] writes it, line for line (only the `ms` timing
//! differs).
//!
//! On the GPU, up to K sequences run in *lanes* of one [`GpuBackend`]: at
//! each step every running lane's next frame is recorded into one
//! submission ([`GpuBackend::submit_lanes`]). The lanes form two groups that
//! take turns, so the device computes one group's frames while the host runs
//! the other group's trackers (in parallel, one sequence per thread); a lane
//! whose sequence ends takes the next one. Each tracker still sees its own
//! frames in order, one at a time: only the scheduling differs from `track`.
//! A frame whose tracker widens its window of interest
//! ([`Tracker::track_or_widen`]) stays in its lane and is submitted again,
//! with the new request, at the lane's next step.
//! A tracker that reads colour gets colour frames here too: its lane's
//! frames carry their colour for the sample windows.
//!
//! Within a group, sequences whose frames stack (one frame size, requests
//! that differ only in their lists' windows, thresholds, seeds and caps:
//! [`FramePlan::stacks_with`]) run as the layers of one [`GpuStack`], every
//! stage one dispatch for all of them. A sequence joins the stack on its
//! first frame when it matches the sequences already there (or the stack is
//! empty) and stays for its whole run, so its previous frame is always where
//! its next one is computed; the others run in their own lanes. A layer
//! without a sequence is given a copy of another layer's frame, and its
//! features are dropped.
//!
//! On the CPU, K threads each track one sequence at a time with
//! [`run::track_to_file_with`].
//!
//! A sequence that fails (a bad file, a frame that cannot be read) gets its
//! error in its result and leaves no output; the others go on. Only a failing
//! device stops the batch.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::Tracker;
use super::run::{self, RunSummary, TrackOptions, make_tracker, track_features, write_result_line};
use crate::backend::plan::PreviousFrame;
use crate::backend::{
    BackendKind, EarlyVision, FrameFeatures, FramePlan, FrameRequest, GpuBackend, GpuStack, LaneFrame, StackTicket,
    Ticket, check_lane_count, lane_groups,
};
use crate::image::{GrayImage, RgbImage};
use crate::io::formats::Status;
use crate::io::frames::ColourFrames;
use crate::io::sequence::CAMERA_FILE;
use crate::io::{AtomicFile, FrameSource, Sequence};
use crate::{Error, GpuContext, Result};

/// One sequence of a batch: where it is, how to track it, where its output goes.
#[derive(Clone, Debug)]
pub struct BatchJob {
    /// The opened sequence.
    pub seq: Sequence,
    /// Tracker and config (`backend`, `overlay` and `progress` are not used:
    /// the batch picks the backend and draws no overlays).
    pub opts: TrackOptions,
    /// The JSON Lines output, written atomically.
    pub out_path: PathBuf,
}

/// What [`run_batch`] reports as it goes (from any of its threads).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BatchProgress {
    /// One more frame tracked.
    Frame,
    /// One more sequence finished, or failed: job `job` of the list, whose
    /// output is `written` (complete, in place) or not.
    Sequence {
        /// Its place in the job list.
        job: usize,
        /// Whether its output was written.
        written: bool,
    },
}

/// Track every job with up to `lanes` sequences in flight (1 ..= [`MAX_LANES`](crate::backend::MAX_LANES))
/// on `backend`; results in job order. Asking for the GPU without an adapter
/// says so once on stderr and runs the CPU path. An error is returned only
/// when the device fails; a job's own failure is its result.
pub fn run_batch(
    jobs: &[BatchJob],
    backend: BackendKind,
    lanes: usize,
    progress: &(dyn Fn(BatchProgress) + Sync),
) -> Result<Vec<Result<RunSummary>>> {
    check_lane_count(lanes)?;
    match backend {
        BackendKind::Cpu => Ok(run_on_cpu(jobs, lanes, progress)),
        BackendKind::Gpu => match GpuContext::new() {
            Ok(ctx) => run_batch_on_gpu(jobs, &mut GpuBackend::new(ctx), lanes, progress),
            Err(e) => {
                // A closed or full stderr is no reason to stop.
                let _ = writeln!(std::io::stderr(), "pipetrack: no GPU ({e}; running the CPU backend)");
                Ok(run_on_cpu(jobs, lanes, progress))
            }
        },
    }
}

/// `lanes` threads, each taking the next job and tracking it to its file.
fn run_on_cpu(jobs: &[BatchJob], lanes: usize, progress: &(dyn Fn(BatchProgress) + Sync)) -> Vec<Result<RunSummary>> {
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Result<RunSummary>>>> = Mutex::new(jobs.iter().map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..lanes.min(jobs.len()) {
            scope.spawn(|| {
                loop {
                    let index = next.fetch_add(1, Ordering::Relaxed);
                    let Some(job) = jobs.get(index) else { break };
                    let opts =
                        TrackOptions { backend: BackendKind::Cpu, overlay: None, progress: false, ..job.opts.clone() };
                    let result =
                        run::track_to_file_with(&job.seq, &opts, &job.out_path, |_| progress(BatchProgress::Frame));
                    let written = result.is_ok();
                    results.lock().unwrap_or_else(|p| p.into_inner())[index] = Some(result);
                    progress(BatchProgress::Sequence { job: index, written });
                }
            });
        }
    });
    let results = results.into_inner().unwrap_or_else(|p| p.into_inner());
    results.into_iter().map(|r| r.unwrap_or_else(|| Err(Error::Gpu("job never ran".into())))).collect()
}

/// A sequence running in a lane of the GPU backend.
struct Running<'j> {
    job: usize,
    seq: &'j Sequence,
    tracker: Box<dyn Tracker + Send>,
    frames: LaneFrames,
    out: AtomicFile,
    /// Index of the next frame.
    index: usize,
    tracked: usize,
    started: Instant,
    /// The frame submitted this step (grey, or the luma of the colour frame
    /// beside it), with the tracker's request for it and when its first
    /// request was taken (the output line's time runs from there).
    current: Option<(GrayImage, Option<RgbImage>, FrameRequest, Instant)>,
    /// Whether the tracker widened its window for the current frame, which
    /// is then submitted again ([`Tracker::track_or_widen`]).
    widened: bool,
    /// Whether the sequence runs in its group's stack (decided on its first
    /// frame), or in its own lane.
    stacked: Option<bool>,
}

/// A sequence's frames as its tracker reads them ([`Tracker::wants_colour`]).
enum LaneFrames {
    Gray(FrameSource),
    Colour(ColourFrames),
}

impl<'j> Running<'j> {
    /// Check the job as `track` does before its first frame (output, tracker,
    /// frame size) and open its output.
    fn start(job: usize, j: &'j BatchJob, backend: &GpuBackend) -> Result<Self> {
        let seq = &j.seq;
        run::check_output(seq, &j.opts, &j.out_path)?;
        let tracker = make_tracker(&j.opts.tracker, seq, j.opts.config.as_deref())?;
        let (w, h) = (seq.camera.width as usize, seq.camera.height as usize);
        backend.check_frame_size(w, h).map_err(|e| {
            let message = format!("frames of {w}x{h} are too large for the backend ({}): {e}", backend.name());
            Error::input(seq.dir().join(CAMERA_FILE), format!("{message}; try --backend cpu"))
        })?;
        let out = AtomicFile::create(&j.out_path)?;
        let frames = if tracker.wants_colour() {
            LaneFrames::Colour(seq.frames().colour())
        } else {
            LaneFrames::Gray(seq.frames())
        };
        Ok(Self {
            job,
            seq,
            tracker,
            frames,
            out,
            index: 0,
            tracked: 0,
            started: Instant::now(),
            current: None,
            widened: false,
            stacked: None,
        })
    }

    /// Read the next frame and take the tracker's request for it: `Ok(true)`
    /// when there is one, `Ok(false)` after the last frame.
    fn next_frame(&mut self) -> Result<bool> {
        let (frame, colour) = match &mut self.frames {
            LaneFrames::Gray(frames) => {
                let Some(frame) = frames.next_frame() else { return Ok(false) };
                (frame?, None)
            }
            LaneFrames::Colour(frames) => {
                let Some(colour) = frames.next() else { return Ok(false) };
                let colour = colour?;
                (colour.to_gray(), Some(colour))
            }
        };
        let size = (self.seq.camera.width as usize, self.seq.camera.height as usize);
        if frame.size() != size {
            let (w, h) = frame.size();
            return Err(Error::Size(format!("frame {} is {w}x{h}, the sequence is {}x{}", self.index, size.0, size.1)));
        }
        let requested = Instant::now();
        let request = self.tracker.request(size.0, size.1);
        // Checked here so that a bad request fails this sequence, not the shared submission.
        request.validate()?;
        self.current = Some((frame, colour, request, requested));
        Ok(true)
    }

    /// Let the tracker update with this step's features and write its line:
    /// `Ok(true)`. `Ok(false)` when the tracker widened its window of
    /// interest instead: the frame stays, with the new request, for the
    /// next step.
    fn track(&mut self, features: &FrameFeatures) -> Result<bool> {
        let (frame, colour, _, requested) =
            self.current.take().ok_or_else(|| Error::Gpu("no frame submitted".into()))?;
        let tracker = self.tracker.as_mut();
        let Some((_, result)) = track_features(tracker, self.index, features, requested, !self.widened) else {
            let (w, h) = frame.size();
            let request = self.tracker.request(w, h);
            request.validate()?;
            self.current = Some((frame, colour, request, requested));
            self.widened = true;
            return Ok(false);
        };
        self.widened = false;
        let name = self.out.path().to_path_buf();
        write_result_line(&mut self.out, &name, &result)?;
        self.tracked += usize::from(result.status == Status::Tracking);
        self.index += 1;
        Ok(true)
    }

    /// Publish the output: the sequence is complete.
    fn finish(self, backend: &str) -> Result<RunSummary> {
        let fps = self.index as f64 / self.started.elapsed().as_secs_f64().max(1e-9);
        self.out.finish()?;
        Ok(RunSummary { backend: backend.to_string(), frames: self.index, tracked: self.tracked, fps, fallback: None })
    }
}

/// The lockstep loop of the module doc on `backend` (for a caller that has
/// its own device), with up to `lanes` sequences in flight (1 ..= [`MAX_LANES`](crate::backend::MAX_LANES)).
pub fn run_batch_on_gpu(
    jobs: &[BatchJob],
    backend: &mut GpuBackend,
    lanes: usize,
    progress: &(dyn Fn(BatchProgress) + Sync),
) -> Result<Vec<Result<RunSummary>>> {
    check_lane_count(lanes)?;
    let lanes = lanes.min(jobs.len()).max(1);
    let groups = lane_groups(lanes);
    let stacks = groups
        .iter()
        .map(|group| {
            let stack =
                if group.len() > 1 { Some(GpuStack::new(backend.context().clone(), group.len())?) } else { None };
            Ok(stack.map(|stack| GroupStack { stack, shape: None }))
        })
        .collect::<Result<_>>()?;
    let mut batch = Lanes {
        jobs,
        running: (0..lanes).map(|_| None).collect(),
        results: jobs.iter().map(|_| None).collect(),
        next_job: 0,
        backend_name: backend.name(),
        progress,
        stacks,
    };
    let mut pending: Vec<Submitted> = groups.iter().map(|_| Submitted::default()).collect();
    loop {
        let mut busy = false;
        for (g, (group, submitted)) in groups.iter().zip(&mut pending).enumerate() {
            batch.track_submitted(g, backend, std::mem::take(submitted))?;
            batch.read_next_frames(group, backend);
            *submitted = batch.submit(g, group, backend)?;
            busy |= !submitted.is_empty();
        }
        if !busy {
            break;
        }
    }
    Ok(batch.results.into_iter().map(|r| r.unwrap_or_else(|| Err(Error::Gpu("job never ran".into())))).collect())
}

/// The state of [`run_batch_on_gpu`]: which sequence runs in which lane, and
/// the results so far.
struct Lanes<'j, 'p> {
    jobs: &'j [BatchJob],
    running: Vec<Option<Running<'j>>>,
    results: Vec<Option<Result<RunSummary>>>,
    next_job: usize,
    backend_name: String,
    progress: &'p (dyn Fn(BatchProgress) + Sync),
    /// Each group's stack (none for a group of one lane).
    stacks: Vec<Option<GroupStack>>,
}

/// A group's stack, layer `l` for the group's `l`-th lane, and what the
/// frames of the sequences in it share while it has any.
struct GroupStack {
    stack: GpuStack,
    shape: Option<((usize, usize), FramePlan)>,
}

/// What one group's step submitted: frames in their own lanes, and the
/// stack's step with the lane of each layer (`None`: a copied frame).
#[derive(Default)]
struct Submitted {
    lanes: Vec<(usize, Ticket)>,
    stack: Option<(Vec<Option<usize>>, StackTicket)>,
}

impl Submitted {
    fn is_empty(&self) -> bool {
        self.lanes.is_empty() && self.stack.is_none()
    }
}

/// The plan a frame of `size` with `request` runs once its sequence has a
/// previous frame: what frames must share to stack.
fn stacking_shape((w, h): (usize, usize), request: &FrameRequest) -> FramePlan {
    FramePlan::new(request, w, h, Some(&PreviousFrame { width: w, height: h, smoothing: request.smoothing }))
}

impl<'j> Lanes<'j, '_> {
    /// Collect a group's submission and run its trackers in parallel, one
    /// sequence per thread; a sequence whose output cannot be written fails.
    fn track_submitted(&mut self, g: usize, backend: &mut GpuBackend, submitted: Submitted) -> Result<()> {
        let (lanes_of, tickets): (Vec<usize>, Vec<Ticket>) = submitted.lanes.into_iter().unzip();
        let mut features: Vec<(usize, FrameFeatures)> =
            lanes_of.into_iter().zip(backend.finish_lanes(tickets)?).collect();
        if let Some((layers, ticket)) = submitted.stack {
            let stack = self.stacks[g].as_mut().ok_or_else(|| Error::Gpu("group has no stack".into()))?;
            let read = stack.stack.finish(ticket)?;
            features.extend(layers.into_iter().zip(read).filter_map(|(lane, f)| Some((lane?, f))));
        }
        let mut lanes: Vec<Option<&mut Running<'j>>> = self.running.iter_mut().map(Option::as_mut).collect();
        let work: Vec<(usize, &mut Running<'j>, FrameFeatures)> =
            features.into_iter().filter_map(|(lane, f)| Some((lane, lanes[lane].take()?, f))).collect();
        let progress = self.progress;
        let tracked: Vec<(usize, Result<()>)> = work
            .into_par_iter()
            .map(|(lane, running, features)| {
                let result = running.track(&features);
                if matches!(result, Ok(true)) {
                    progress(BatchProgress::Frame);
                }
                (lane, result.map(|_| ()))
            })
            .collect();
        for (lane, result) in tracked {
            if let Err(e) = result {
                self.end(lane, e);
            }
        }
        Ok(())
    }

    /// Give every lane of `group` its next frame (read in parallel),
    /// publishing sequences that ended and starting the next jobs in lanes
    /// that are free, until each lane has a frame or no job is left.
    fn read_next_frames(&mut self, group: &[usize], backend: &mut GpuBackend) {
        loop {
            for &lane in group {
                self.start_next_job(lane, backend);
            }
            let read: Vec<(usize, Result<bool>)> = self
                .running
                .par_iter_mut()
                .enumerate()
                .filter(|(lane, _)| group.contains(lane))
                .filter_map(|(lane, r)| r.as_mut().filter(|r| r.current.is_none()).map(|r| (lane, r.next_frame())))
                .collect();
            let mut freed = false;
            for (lane, result) in read {
                match result {
                    Ok(true) => {}
                    Ok(false) => {
                        if let Some(r) = self.running[lane].take() {
                            let job = r.job;
                            let summary = r.finish(&self.backend_name);
                            let written = summary.is_ok();
                            self.results[job] = Some(summary);
                            (self.progress)(BatchProgress::Sequence { job, written });
                        }
                        freed = true;
                    }
                    Err(e) => {
                        self.end(lane, e);
                        freed = true;
                    }
                }
            }
            if !freed || self.next_job >= self.jobs.len() {
                return;
            }
        }
    }

    /// While `lane` is free and jobs are left, start the next one there (a
    /// job that cannot start fails at once).
    fn start_next_job(&mut self, lane: usize, backend: &mut GpuBackend) {
        while self.running[lane].is_none() && self.next_job < self.jobs.len() {
            let job = self.next_job;
            self.next_job += 1;
            match Running::start(job, &self.jobs[job], backend) {
                Ok(r) => {
                    backend.reset_lane(lane);
                    self.running[lane] = Some(r);
                }
                Err(e) => {
                    self.results[job] = Some(Err(e));
                    (self.progress)(BatchProgress::Sequence { job, written: false });
                }
            }
        }
    }

    /// Record the frames read in `group`'s lanes: the stacked sequences'
    /// as one step of the group's stack, the others into one submission of
    /// their lanes.
    fn submit(&mut self, g: usize, group: &[usize], backend: &mut GpuBackend) -> Result<Submitted> {
        self.join_stack(g, group)?;
        let in_stack = |r: &Running<'_>| r.stacked == Some(true);
        let frames: Vec<LaneFrame<'_>> = group
            .iter()
            .filter_map(|&lane| {
                let r = self.running[lane].as_ref().filter(|r| !in_stack(r))?;
                let (frame, colour, request, _) = r.current.as_ref()?;
                Some(LaneFrame { lane, frame, colour: colour.as_ref(), request })
            })
            .collect();
        let mut submitted = Submitted::default();
        if !frames.is_empty() {
            let tickets = backend.submit_lanes(&frames)?;
            submitted.lanes = frames.iter().map(|f| f.lane).zip(tickets).collect();
        }
        let layers: Vec<Option<(usize, &GrayImage, &FrameRequest)>> = group
            .iter()
            .map(|&lane| {
                let r = self.running[lane].as_ref().filter(|r| in_stack(r))?;
                let (frame, _, request, _) = r.current.as_ref()?;
                Some((lane, frame, request))
            })
            .collect();
        if let (Some(stack), Some(&(_, filler, filler_request))) =
            (self.stacks[g].as_mut(), layers.iter().flatten().next())
        {
            let batch: Vec<(&GrayImage, &FrameRequest)> =
                layers.iter().map(|l| l.map_or((filler, filler_request), |(_, f, r)| (f, r))).collect();
            let ticket = stack.stack.submit(&batch)?;
            submitted.stack = Some((layers.iter().map(|l| l.map(|(lane, ..)| lane)).collect(), ticket));
        }
        Ok(submitted)
    }

    /// Decide, for each sequence of `group` on its first frame, whether it
    /// runs in the group's stack: when its frame stacks with the frames of
    /// the sequences already there, or there are none, and the device holds
    /// a stack of such frames. A sequence that joins starts a new sequence
    /// in its layer. A sequence in the stack whose frame no longer stacks
    /// fails alone.
    fn join_stack(&mut self, g: usize, group: &[usize]) -> Result<()> {
        let Some(stack) = self.stacks[g].as_ref() else { return Ok(()) };
        let strayed: Vec<(usize, usize)> = group
            .iter()
            .filter_map(|&lane| {
                let r = self.running[lane].as_ref().filter(|r| r.stacked == Some(true))?;
                let (frame, _, request, _) = r.current.as_ref()?;
                let (size, plan) = stack.shape.as_ref()?;
                let fits = *size == frame.size() && stacking_shape(frame.size(), request).stacks_with(plan);
                (!fits).then_some((lane, r.index))
            })
            .collect();
        for (lane, index) in strayed {
            let message = format!(
                "frame {index} asks for other early-vision stages than the sequences stacked beside it; track it \
                 alone or with --jobs 1"
            );
            self.end(lane, Error::Parameter(message));
        }
        let Some(stack) = self.stacks[g].as_mut() else { return Ok(()) };
        if !group.iter().any(|&lane| self.running[lane].as_ref().is_some_and(|r| r.stacked == Some(true))) {
            stack.shape = None;
        }
        for (layer, &lane) in group.iter().enumerate() {
            let Some(r) = self.running[lane].as_mut() else { continue };
            let Some((frame, colour, request, _)) = r.current.as_ref() else { continue };
            if r.stacked.is_some() {
                continue;
            }
            let fits = stack.stack.check_frame_size(frame.width(), frame.height()).is_ok();
            let joins = fits && colour.is_none() && request.windows.is_none() && {
                let shape = stacking_shape(frame.size(), request);
                match &stack.shape {
                    None => {
                        stack.shape = Some((frame.size(), shape));
                        true
                    }
                    Some((size, plan)) => *size == frame.size() && shape.stacks_with(plan),
                }
            };
            if joins {
                stack.stack.reset_layer(layer)?;
            }
            r.stacked = Some(joins);
        }
        Ok(())
    }

    /// End the sequence in `lane` with `error` (its partial output is
    /// removed as the sequence is dropped).
    fn end(&mut self, lane: usize, error: Error) {
        if let Some(r) = self.running[lane].take() {
            self.results[r.job] = Some(Err(error));
            (self.progress)(BatchProgress::Sequence { job: r.job, written: false });
        }
    }
}
