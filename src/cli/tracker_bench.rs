//! The trackers' own time per frame, apart from early vision: each tracker
//! runs once over its paper's synthetic sequence on the CPU backend while
//! every frame's feature lists are kept; then fresh trackers replay those
//! lists and only the tracker's own calls are timed ([`Tracker::track_or_widen`],
//! and [`Tracker::track`] again on a frame whose window it widened). A
//! tracker is deterministic, so
//! the replay asks for the same features frame by frame (checked: a request
//! that differs from the recorded one is an error).
//!
//! `cargo bench --bench trackers` prints the table (`-- blue` for one tracker).

use std::time::Instant;

use serde::Serialize;

use crate::backend::{CpuBackend, EarlyVision, FrameFeatures, FrameRequest};
use crate::io::formats::Status;
use crate::synth::{SyntheticSequence, render_scene};
use crate::track::run::{track_once, until_tracked};
use crate::track::{
    BlueParams, BlueTracker, LoweParams, LoweTracker, MotionEdgeParams, MotionEdgeTracker, Observations, Tracked,
    Tracker,
};
use crate::{Error, Result};

/// Each tracker with the synthetic scene of its paper, at the scene's defaults
/// (motion-edge: `pendulum`, 256×242; blue: `target3dof`, 640×480; lowe:
/// `box`, 640×480).
pub const CASES: &[(&str, &str)] = &[("motion-edge", "pendulum"), ("blue", "target3dof"), ("lowe", "box")];

/// A tracker's per-frame host time over one sequence.
#[derive(Clone, Debug, Serialize)]
pub struct TrackerTiming {
    /// `--tracker` name.
    pub tracker: String,
    /// Synthetic scene tracked.
    pub scene: String,
    /// `WxH`.
    pub size: String,
    /// Frames in the sequence.
    pub frames: usize,
    /// Frames reported `tracking`.
    pub tracked: usize,
    /// Replays timed; a frame's time is its fastest replay.
    pub passes: usize,
    /// Median over frames of the per-frame time, ms.
    pub median_ms: f64,
    /// Mean over frames, ms.
    pub mean_ms: f64,
    /// Slowest frame, ms.
    pub max_ms: f64,
}

/// A fresh tracker `name` for `seq`, with default parameters.
pub fn new_tracker(name: &str, seq: &SyntheticSequence) -> Result<Box<dyn Tracker>> {
    Ok(match name {
        "motion-edge" => Box::new(MotionEdgeTracker::new(
            seq.init.corners.clone(),
            seq.model.edges.clone(),
            MotionEdgeParams::default(),
        )?),
        "blue" => Box::new(BlueTracker::new(seq.camera, seq.model.clone(), seq.init.clone(), BlueParams::default())?),
        "lowe" => Box::new(LoweTracker::new(seq.camera, &seq.model, &seq.init, LoweParams::default())?),
        other => return Err(Error::Parameter(format!("unknown tracker {other:?}"))),
    })
}

/// A frame's requests and the features the backend computed for each: one,
/// or two when the tracker widened its window ([`Tracker::track_or_widen`]).
pub type FrameRecording = Vec<(FrameRequest, FrameFeatures)>;

/// Run tracker `name` over `seq` on the CPU backend, keeping each frame's
/// requests and the features the backend computed for them.
pub fn record_features(name: &str, seq: &SyntheticSequence) -> Result<Vec<FrameRecording>> {
    let mut tracker = new_tracker(name, seq)?;
    let mut backend = CpuBackend::new();
    backend.reset();
    let mut recorded = Vec::with_capacity(seq.frames.len());
    for (i, frame) in seq.frames.iter().enumerate() {
        let mut attempts = Vec::new();
        until_tracked(tracker.as_mut(), frame.size(), |tracker, request, may_widen| {
            let features = backend.process(frame, &request)?;
            let look = track_once(tracker, i, &Observations::from(&features), may_widen);
            attempts.push((request, features));
            Ok(matches!(look, Tracked::Outcome(_)).then_some(()))
        })?;
        recorded.push(attempts);
    }
    Ok(recorded)
}

/// Time tracker `name` replaying `recorded` (from [`record_features`]) on
/// `seq`, `passes` times; per frame the fastest pass counts, a widened
/// frame's two calls together.
pub fn time_replay(
    name: &str,
    seq: &SyntheticSequence,
    recorded: &[FrameRecording],
    passes: usize,
) -> Result<TrackerTiming> {
    let (w, h) = (seq.camera.width as usize, seq.camera.height as usize);
    let mut fastest = vec![f64::INFINITY; recorded.len()];
    let mut tracked = 0;
    for _ in 0..passes.max(1) {
        let mut tracker = new_tracker(name, seq)?;
        tracked = 0;
        for (i, attempts) in recorded.iter().enumerate() {
            let mut ms = 0.0;
            let mut outcome = None;
            for (k, (request, features)) in attempts.iter().enumerate() {
                if outcome.is_some() {
                    return Err(Error::Parameter(format!("{name}: frame {i} widened its window less than recorded")));
                }
                if tracker.request(w, h) != *request {
                    return Err(Error::Parameter(format!("{name}: frame {i} asks for other features than recorded")));
                }
                let observations = Observations::from(features);
                let start = Instant::now();
                let tracked_here = track_once(tracker.as_mut(), i, &observations, k == 0);
                ms += start.elapsed().as_secs_f64() * 1e3;
                if let Tracked::Outcome(o) = tracked_here {
                    outcome = Some(o);
                }
            }
            let Some(outcome) = outcome else {
                return Err(Error::Parameter(format!("{name}: frame {i} widened its window more than recorded")));
            };
            fastest[i] = fastest[i].min(ms);
            tracked += usize::from(outcome.status == Status::Tracking);
        }
    }
    let mut sorted = fastest.clone();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let median_ms = match n {
        0 => 0.0,
        _ if n % 2 == 1 => sorted[n / 2],
        _ => 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]),
    };
    Ok(TrackerTiming {
        tracker: name.to_string(),
        scene: seq.scene.clone(),
        size: format!("{w}x{h}"),
        frames: n,
        tracked,
        passes: passes.max(1),
        median_ms,
        mean_ms: if n == 0 { 0.0 } else { sorted.iter().sum::<f64>() / n as f64 },
        max_ms: sorted.last().copied().unwrap_or(0.0),
    })
}

/// Time the trackers of [`CASES`] named in `names` (all when it is empty)
/// on their scenes at the scenes' defaults.
pub fn time_trackers(names: &[String], passes: usize) -> Result<Vec<TrackerTiming>> {
    CASES
        .iter()
        .filter(|(tracker, _)| names.is_empty() || names.iter().any(|n| n == tracker))
        .map(|&(tracker, scene)| {
            let seq = render_scene(scene, None, 0, &[])?;
            let recorded = record_features(tracker, &seq)?;
            time_replay(tracker, &seq, &recorded, passes)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A replay reports every frame and the same statuses as the recording run.
    #[test]
    fn replay_times_every_frame_and_tracks_as_recorded() {
        let seq = render_scene("pendulum", Some(6), 0, &[]).unwrap();
        let recorded = record_features("motion-edge", &seq).unwrap();
        assert_eq!(recorded.len(), 6);
        let timing = time_replay("motion-edge", &seq, &recorded, 2).unwrap();
        assert_eq!(timing.frames, 6);
        assert!(timing.median_ms > 0.0 && timing.median_ms <= timing.max_ms);
        // motion-edge never widens its window: one request per frame.
        let mut tracker = new_tracker("motion-edge", &seq).unwrap();
        let expected = recorded
            .iter()
            .enumerate()
            .filter(|(i, attempts)| tracker.track(*i, &Observations::from(&attempts[0].1)).status == Status::Tracking)
            .count();
        assert_eq!(timing.tracked, expected);
    }

    /// `lowe` on the box at 30 px/frame widens its narrowed window on some
    /// frames: those are recorded with both requests, and the replay asks
    /// for the same features frame by frame (else an error) and tracks.
    #[test]
    fn replay_of_a_tracker_that_widens_its_window_follows_the_recording() {
        let seq = render_scene("box", Some(60), 0, &[("speed".to_string(), "30".to_string())]).unwrap();
        let recorded = record_features("lowe", &seq).unwrap();
        assert_eq!(recorded.len(), 60);
        let widened = recorded.iter().filter(|attempts| attempts.len() == 2).count();
        assert!(widened > 0 && recorded.iter().all(|a| (1..=2).contains(&a.len())), "{widened} frames widened");
        let timing = time_replay("lowe", &seq, &recorded, 1).unwrap();
        assert_eq!(timing.frames, 60);
        assert!(timing.tracked >= 58, "{} of 60 frames tracking", timing.tracked);
    }
}
