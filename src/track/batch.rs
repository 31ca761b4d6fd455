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
//! A tracker that reads colour gets colour frames here too: its lane's
//! frames carry their colour for the sample windows.
//!
//! On the CPU, K threads each track one sequence at a time with
//! [`run::track_to_file_with`].
//!
//! A sequence that fails (a bad file, a frame that cannot be read) gets its
//! error in its result and leaves no output; the others go on. Only a failing
//! device stops the batch.

use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::Tracker;
use super::run::{self, RunSummary, TrackOptions, make_tracker, track_features, write_result_line};
use crate::backend::{
    BackendKind, EarlyVision, FrameFeatures, FrameRequest, GpuBackend, LaneFrame, Ticket, check_lane_count, lane_groups,
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
    /// One more sequence finished, or failed.
    Sequence,
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
                eprintln!("pipetrack: no GPU ({e}; running the CPU backend)");
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
                    results.lock().unwrap_or_else(|p| p.into_inner())[index] = Some(result);
                    progress(BatchProgress::Sequence);
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
    /// beside it), with the tracker's request for it and when it was taken.
    current: Option<(GrayImage, Option<RgbImage>, FrameRequest, Instant)>,
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
        Ok(Self { job, seq, tracker, frames, out, index: 0, tracked: 0, started: Instant::now(), current: None })
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

    /// Let the tracker update with this step's features and write its line.
    fn track(&mut self, features: &FrameFeatures) -> Result<()> {
        let (_, _, _, requested) = self.current.take().ok_or_else(|| Error::Gpu("no frame submitted".into()))?;
        let (_, result) = track_features(self.tracker.as_mut(), self.index, features, requested);
        let name = self.out.path().to_path_buf();
        write_result_line(&mut self.out, &name, &result)?;
        self.tracked += usize::from(result.status == Status::Tracking);
        self.index += 1;
        Ok(())
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
    let mut batch = Lanes {
        jobs,
        running: (0..lanes).map(|_| None).collect(),
        results: jobs.iter().map(|_| None).collect(),
        next_job: 0,
        backend_name: backend.name(),
        progress,
    };
    let groups = lane_groups(lanes);
    let mut pending: Vec<Vec<(usize, Ticket)>> = groups.iter().map(|_| Vec::new()).collect();
    loop {
        let mut busy = false;
        for (group, submitted) in groups.iter().zip(&mut pending) {
            batch.track_submitted(backend, std::mem::take(submitted))?;
            batch.read_next_frames(group, backend);
            *submitted = batch.submit(group, backend)?;
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
}

impl<'j> Lanes<'j, '_> {
    /// Collect a group's submission and run its trackers in parallel, one
    /// sequence per thread; a sequence whose output cannot be written fails.
    fn track_submitted(&mut self, backend: &mut GpuBackend, submitted: Vec<(usize, Ticket)>) -> Result<()> {
        let (lanes_of, tickets): (Vec<usize>, Vec<Ticket>) = submitted.into_iter().unzip();
        let features: Vec<(usize, FrameFeatures)> = lanes_of.into_iter().zip(backend.finish_lanes(tickets)?).collect();
        let mut lanes: Vec<Option<&mut Running<'j>>> = self.running.iter_mut().map(Option::as_mut).collect();
        let work: Vec<(usize, &mut Running<'j>, FrameFeatures)> =
            features.into_iter().filter_map(|(lane, f)| Some((lane, lanes[lane].take()?, f))).collect();
        let progress = self.progress;
        let tracked: Vec<(usize, Result<()>)> = work
            .into_par_iter()
            .map(|(lane, running, features)| {
                let result = running.track(&features);
                progress(BatchProgress::Frame);
                (lane, result)
            })
            .collect();
        for (lane, result) in tracked {
            if let Err(e) = result {
                self.end(lane, Err(e));
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
                            self.results[job] = Some(summary);
                            (self.progress)(BatchProgress::Sequence);
                        }
                        freed = true;
                    }
                    Err(e) => {
                        self.end(lane, Err(e));
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
                    (self.progress)(BatchProgress::Sequence);
                }
            }
        }
    }

    /// Record the frames read in `group`'s lanes into one submission.
    fn submit(&self, group: &[usize], backend: &mut GpuBackend) -> Result<Vec<(usize, Ticket)>> {
        let frames: Vec<LaneFrame<'_>> = group
            .iter()
            .filter_map(|&lane| {
                let (frame, colour, request, _) = self.running[lane].as_ref()?.current.as_ref()?;
                Some(LaneFrame { lane, frame, colour: colour.as_ref(), request })
            })
            .collect();
        if frames.is_empty() {
            return Ok(Vec::new());
        }
        let tickets = backend.submit_lanes(&frames)?;
        Ok(frames.iter().map(|f| f.lane).zip(tickets).collect())
    }

    /// End the sequence in `lane` with `result` (after an error its partial
    /// output is removed as the sequence is dropped).
    fn end(&mut self, lane: usize, result: Result<RunSummary>) {
        if let Some(r) = self.running[lane].take() {
            self.results[r.job] = Some(result);
            (self.progress)(BatchProgress::Sequence);
        }
    }
}
