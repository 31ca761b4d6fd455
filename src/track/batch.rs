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
use crate::backend::{BackendKind, EarlyVision, FrameRequest, GpuBackend, LaneFrame, MAX_LANES};
use crate::image::GrayImage;
use crate::io::formats::Status;
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

/// Track every job with up to `lanes` sequences in flight (1 ..= [`MAX_LANES`])
/// on `backend`; results in job order. Asking for the GPU without an adapter
/// says so once on stderr and runs the CPU path. An error is returned only
/// when the device fails; a job's own failure is its result.
pub fn run_batch(
    jobs: &[BatchJob],
    backend: BackendKind,
    lanes: usize,
    progress: &(dyn Fn(BatchProgress) + Sync),
) -> Result<Vec<Result<RunSummary>>> {
    if !(1..=MAX_LANES).contains(&lanes) {
        return Err(Error::Parameter(format!("{lanes} sequences in flight: give 1 to {MAX_LANES}")));
    }
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
    frames: FrameSource,
    out: AtomicFile,
    /// Index of the next frame.
    index: usize,
    tracked: usize,
    started: Instant,
    /// The frame submitted this step, with the tracker's request for it and when it was taken.
    current: Option<(GrayImage, FrameRequest, Instant)>,
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
        let frames = seq.frames();
        Ok(Self { job, seq, tracker, frames, out, index: 0, tracked: 0, started: Instant::now(), current: None })
    }

    /// Read the next frame and take the tracker's request for it: `Ok(true)`
    /// when there is one, `Ok(false)` after the last frame.
    fn next_frame(&mut self) -> Result<bool> {
        let Some(frame) = self.frames.next_frame() else { return Ok(false) };
        let frame = frame?;
        let size = (self.seq.camera.width as usize, self.seq.camera.height as usize);
        if frame.size() != size {
            let (w, h) = frame.size();
            return Err(Error::Size(format!("frame {} is {w}x{h}, the sequence is {}x{}", self.index, size.0, size.1)));
        }
        let requested = Instant::now();
        let request = self.tracker.request(size.0, size.1);
        // Checked here so that a bad request fails this sequence, not the shared submission.
        request.validate()?;
        self.current = Some((frame, request, requested));
        Ok(true)
    }

    /// Let the tracker update with this step's features and write its line.
    fn track(&mut self, features: &crate::backend::FrameFeatures) -> Result<()> {
        let (_, _, requested) = self.current.take().ok_or_else(|| Error::Gpu("no frame submitted".into()))?;
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
/// its own device), with up to `lanes` sequences in flight (1 ..= [`MAX_LANES`]).
pub fn run_batch_on_gpu(
    jobs: &[BatchJob],
    backend: &mut GpuBackend,
    lanes: usize,
    progress: &(dyn Fn(BatchProgress) + Sync),
) -> Result<Vec<Result<RunSummary>>> {
    if !(1..=MAX_LANES).contains(&lanes) {
        return Err(Error::Parameter(format!("{lanes} sequences in flight: give 1 to {MAX_LANES}")));
    }
    let name = backend.name();
    let lanes = lanes.min(jobs.len()).max(1);
    let mut results: Vec<Option<Result<RunSummary>>> = jobs.iter().map(|_| None).collect();
    let mut running: Vec<Option<Running<'_>>> = (0..lanes).map(|_| None).collect();
    let mut next_job = 0;
    // Two groups taking turns (one group when there is a single lane).
    let groups: Vec<Vec<usize>> =
        if lanes == 1 { vec![vec![0]] } else { vec![(0..lanes).step_by(2).collect(), (1..lanes).step_by(2).collect()] };
    let mut pending: Vec<Vec<(usize, crate::backend::Ticket)>> = groups.iter().map(|_| Vec::new()).collect();

    loop {
        let mut busy = false;
        for (g, group) in groups.iter().enumerate() {
            // Collect this group's last submission and run its trackers in parallel.
            let tickets = std::mem::take(&mut pending[g]);
            let mut features = Vec::with_capacity(tickets.len());
            for (lane, ticket) in tickets {
                features.push((lane, backend.finish(ticket)?));
            }
            let tracked: Vec<(usize, Result<()>)> = {
                let mut by_lane: Vec<(usize, &mut Running<'_>, crate::backend::FrameFeatures)> = Vec::new();
                let mut slots: Vec<Option<&mut Running<'_>>> = running.iter_mut().map(Option::as_mut).collect();
                for (lane, f) in features {
                    if let Some(r) = slots[lane].take() {
                        by_lane.push((lane, r, f));
                    }
                }
                by_lane
                    .into_par_iter()
                    .map(|(lane, r, f)| {
                        let result = r.track(&f);
                        progress(BatchProgress::Frame);
                        (lane, result)
                    })
                    .collect()
            };
            for (lane, result) in tracked {
                if let Err(e) = result {
                    fail(&mut running[lane], &mut results, e, progress);
                }
            }

            // Read every lane's next frame, starting new sequences in lanes that are free.
            loop {
                for &lane in group {
                    while running[lane].is_none() && next_job < jobs.len() {
                        match Running::start(next_job, &jobs[next_job], backend) {
                            Ok(r) => {
                                backend.reset_lane(lane);
                                running[lane] = Some(r);
                            }
                            Err(e) => {
                                results[next_job] = Some(Err(e));
                                progress(BatchProgress::Sequence);
                            }
                        }
                        next_job += 1;
                    }
                }
                let read: Vec<(usize, Result<bool>)> = running
                    .par_iter_mut()
                    .enumerate()
                    .filter(|(lane, r)| group.contains(lane) && r.as_ref().is_some_and(|r| r.current.is_none()))
                    .filter_map(|(lane, r)| r.as_mut().map(|r| (lane, r.next_frame())))
                    .collect();
                let mut freed = false;
                for (lane, result) in read {
                    match result {
                        Ok(true) => {}
                        Ok(false) => {
                            if let Some(r) = running[lane].take() {
                                let job = r.job;
                                results[job] = Some(r.finish(&name));
                                progress(BatchProgress::Sequence);
                            }
                            freed = true;
                        }
                        Err(e) => {
                            fail(&mut running[lane], &mut results, e, progress);
                            freed = true;
                        }
                    }
                }
                if !freed || next_job >= jobs.len() {
                    break;
                }
            }

            // One submission for the group's frames.
            let frames: Vec<LaneFrame<'_>> = group
                .iter()
                .filter_map(|&lane| {
                    let (frame, request, _) = running[lane].as_ref()?.current.as_ref()?;
                    Some(LaneFrame { lane, frame, request })
                })
                .collect();
            if !frames.is_empty() {
                let lanes_submitted: Vec<usize> = frames.iter().map(|f| f.lane).collect();
                let tickets = backend.submit_lanes(&frames)?;
                pending[g] = lanes_submitted.into_iter().zip(tickets).collect();
                busy = true;
            }
        }
        if !busy {
            break;
        }
    }
    Ok(results.into_iter().map(|r| r.unwrap_or_else(|| Err(Error::Gpu("job never ran".into())))).collect())
}

/// End the sequence in `lane` with `error` (its partial output is removed).
fn fail(
    lane: &mut Option<Running<'_>>,
    results: &mut [Option<Result<RunSummary>>],
    error: Error,
    progress: &(dyn Fn(BatchProgress) + Sync),
) {
    if let Some(r) = lane.take() {
        results[r.job] = Some(Err(error));
        progress(BatchProgress::Sequence);
    }
}
