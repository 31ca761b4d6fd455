//! `pipetrack roundtrip SEQ --tracker NAME`: how well a tracker agrees with
//! itself on a sequence that has no ground truth.
//!
//! The tracker runs forward from `init.json` to the last frame, then
//! backward over the same frames from the forward run's last tracking
//! frame, started from that frame's reported state (pose, joint values and
//! corners). Where both runs report `tracking`, the two answers for a frame
//! came from different histories (the backward run has seen the frames
//! after it, not those before), and their difference is error of one run or
//! the other: at least half of it lies in one of them. A tracker that slid
//! off the object on the way out does not come back onto the forward run's
//! answers by chance. The converse does not hold: two runs that make the
//! same mistake agree, so a small disagreement is not an error against
//! truth.
//!
//! The frame the backward run starts from is not compared (its answer there
//! is the forward run's), so a run with nothing before its last tracking
//! frame has nothing to compare. A condensation `camera_motion` (the known
//! first motion, in `init.json` or `--config`) is the forward run's: the
//! backward run starts without one, and `roundtrip` refuses it in `--config`
//! (it would be applied to the backward run's first interval as well).
//!
//! Per frame where both track: the **corner disagreement**, the mean over
//! the model vertices of the distance between the two runs' corners, in
//! pixels; and, for trackers with a pose, the distance between the two
//! translations (metres) and the angle of the rotation between the two
//! orientations (radians). [`RoundtripReport`] summarises them with
//! [`ErrorStats`].

use std::io::{self, Write};
use std::path::Path;

use serde::Serialize;

use crate::cli::score::ErrorStats;
use crate::geometry::{Pose, mean_point_distance};
use crate::io::formats::{FrameResult, InitState, Status};
use crate::io::{OutputFile, Sequence};
use crate::track::run::{TrackOptions, check_output, read_config, track_sequence};
use crate::{Error, Result};

/// How the forward and the backward run agree on one frame (a line of
/// `--out`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameAgreement {
    /// Frame index.
    pub frame: usize,
    /// Status of the forward run.
    pub forward: Status,
    /// Status of the backward run; none for the frames after the forward
    /// run's last tracking frame, which the backward run does not see.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub backward: Option<Status>,
    /// Mean distance between the two runs' corners, px (both tracking, not
    /// the backward run's start).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corner_px: Option<f64>,
    /// Distance between the two translations, metres (both tracking, with a pose).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub translation_m: Option<f64>,
    /// Angle of the rotation from one orientation to the other, radians
    /// (both tracking, with a pose).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rotation_rad: Option<f64>,
}

/// One of the per-frame figures of a [`FrameAgreement`].
pub type Measure = fn(&FrameAgreement) -> Option<f64>;

/// What [`roundtrip`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct RoundtripReport {
    /// Frames in the sequence.
    pub frames: usize,
    /// Frames the forward run reports tracking.
    pub forward_tracked: usize,
    /// The frame the backward run starts from (the forward run's last
    /// tracking frame); `None` when the forward run tracked no frame.
    pub start: Option<usize>,
    /// Frames the backward run reports tracking.
    pub backward_tracked: usize,
    /// Per frame, in frame order.
    pub per_frame: Vec<FrameAgreement>,
}

impl RoundtripReport {
    /// Frames compared: both runs report tracking, the backward run's
    /// start excepted.
    #[must_use]
    pub fn compared(&self) -> usize {
        self.per_frame
            .iter()
            .filter(|f| {
                Some(f.frame) != self.start && f.forward == Status::Tracking && f.backward == Some(Status::Tracking)
            })
            .count()
    }

    /// Figures of one measure over the compared frames, e.g.
    /// `report.stats(|f| f.corner_px)`; `None` when no frame has it.
    #[must_use]
    pub fn stats(&self, measure: Measure) -> Option<ErrorStats> {
        ErrorStats::of(&self.per_frame.iter().filter_map(measure).collect::<Vec<_>>())
    }
}

/// Track `seq` forward and backward with `opts` (its overlay is not
/// drawn) and compare the two runs frame by frame (module doc). A sequence
/// read from stdin cannot be read twice: [`Error::Parameter`].
pub fn roundtrip(seq: &Sequence, opts: &TrackOptions) -> Result<RoundtripReport> {
    if seq.reads_stdin() {
        return Err(Error::Parameter("roundtrip reads the frames twice: give a folder of frames, not stdin".into()));
    }
    if opts.tracker == "condensation" {
        let params: crate::track::CondensationParams = read_config(opts.config.as_deref(), &opts.tracker)?;
        if params.camera_motion.is_some() {
            let config = opts.config.clone().unwrap_or_default();
            return Err(Error::input(
                config,
                "camera_motion is the forward run's first motion: roundtrip would give it to the backward run too; leave it out (init.json's is used forward only)",
            ));
        }
    }
    let mut opts = TrackOptions { overlay: None, ..opts.clone() };
    let mut forward = Vec::new();
    let summary = track_sequence(seq, &opts, &mut io::sink(), |r| forward.push(r.clone()))?;
    if summary.fallback.is_some() {
        // The forward run said why there is no GPU; the backward run does not repeat it.
        opts.backend = crate::backend::BackendKind::Cpu;
    }
    let start = forward.iter().rposition(|r| r.status == Status::Tracking);
    let mut backward = Vec::new();
    if let Some(start) = start {
        let last = &forward[start];
        let init = InitState {
            pose: last.pose,
            params: last.params.clone().unwrap_or_default(),
            corners: last.corners.clone(),
            camera_motion: None,
        };
        let reversed = seq.reversed(start + 1, init).ok_or_else(|| Error::Parameter("no frames to reverse".into()))?;
        // The forward run read every file; what fails now is the start.
        track_sequence(&reversed, &opts, &mut io::sink(), |r| backward.push(r.clone())).map_err(|e| {
            let why = match e {
                Error::Input { message, .. } => message,
                other => other.to_string(),
            };
            Error::Parameter(format!(
                "the backward run cannot start from frame {start} at the forward run's answer there: {why}"
            ))
        })?;
        backward.reverse();
    }
    Ok(compare(&forward, &backward, start))
}

/// The report of a forward run and a backward run (in frame order, the
/// frames up to `start`).
#[must_use]
pub fn compare(forward: &[FrameResult], backward: &[FrameResult], start: Option<usize>) -> RoundtripReport {
    let per_frame = forward
        .iter()
        .enumerate()
        .map(|(frame, f)| {
            let b = backward.get(frame);
            let both =
                Some(frame) != start && f.status == Status::Tracking && b.is_some_and(|b| b.status == Status::Tracking);
            let (corner_px, translation_m, rotation_rad) = match b {
                Some(b) if both => {
                    let corners = (f.corners.len() == b.corners.len() && !f.corners.is_empty())
                        .then(|| mean_point_distance(&f.corners, &b.corners));
                    let poses = f.pose.zip(b.pose).map(|(p, q)| (Pose::from(p), Pose::from(q)));
                    (
                        corners,
                        poses.map(|(p, q)| p.translation.distance(q.translation)),
                        poses.map(|(p, q)| rotation_angle(&p, &q)),
                    )
                }
                _ => (None, None, None),
            };
            FrameAgreement {
                frame,
                forward: f.status,
                backward: b.map(|b| b.status),
                corner_px,
                translation_m,
                rotation_rad,
            }
        })
        .collect();
    RoundtripReport {
        frames: forward.len(),
        forward_tracked: forward.iter().filter(|r| r.status == Status::Tracking).count(),
        start,
        backward_tracked: backward.iter().filter(|r| r.status == Status::Tracking).count(),
        per_frame,
    }
}

/// Angle of the rotation taking `a`'s orientation to `b`'s, radians.
fn rotation_angle(a: &Pose, b: &Pose) -> f64 {
    let relative = a.rotation.transpose() * b.rotation;
    let cos = 0.5 * (relative.x_axis.x + relative.y_axis.y + relative.z_axis.z - 1.0);
    cos.clamp(-1.0, 1.0).acos()
}

/// [`roundtrip`], writing each frame's [`FrameAgreement`] as a JSON line
/// to `out`, checked and opened before the runs (an [`OutputFile`]: a
/// regular file appears under its name only when complete; a device or a
/// named pipe is written in place).
pub fn roundtrip_to_file(seq: &Sequence, opts: &TrackOptions, out: &Path) -> Result<RoundtripReport> {
    check_output(seq, opts, out)?;
    // Opened before the runs, so a place that cannot be written is known
    // at once; dropped unfinished, a regular file leaves nothing.
    let mut file = OutputFile::create(out)?;
    let report = roundtrip(seq, opts)?;
    for line in &report.per_frame {
        serde_json::to_writer(&mut file, line).map_err(|e| Error::io(out, e.into()))?;
        writeln!(file).map_err(|e| Error::io(out, e))?;
    }
    file.finish()?;
    Ok(report)
}

/// The report as the command prints it: one line per figure.
#[must_use]
pub fn summary(report: &RoundtripReport) -> String {
    let mut lines = vec![format!("frames: {}", report.frames)];
    lines.push(format!("forward run tracking: {}", report.forward_tracked));
    match report.start {
        Some(start) => lines.push(format!(
            "backward run tracking: {} (from frame {start}, the forward run's last tracking frame)",
            report.backward_tracked
        )),
        None => lines.push("backward run: none (the forward run tracked no frame)".into()),
    }
    lines.push(format!("frames compared (both tracking, the backward run's start excepted): {}", report.compared()));
    // (name, measure, scale to the printed unit, unit, decimals)
    let measures: [(&str, Measure, f64, &str, usize); 3] = [
        ("corner", |f| f.corner_px, 1.0, " px", 3),
        ("translation", |f| f.translation_m, 1e3, " mm", 2),
        ("rotation", |f| f.rotation_rad, 180.0 / std::f64::consts::PI, "°", 3),
    ];
    for (name, measure, scale, unit, d) in measures {
        let Some(s) = report.stats(measure) else { continue };
        let worst = report.per_frame.iter().filter_map(|f| measure(f).map(|v| (f.frame, v)));
        let (frame, _) = worst.max_by(|a, b| a.1.total_cmp(&b.1)).unwrap_or_default();
        let [mean, median, p95, max] = [s.mean, s.median, s.p95, s.max].map(|v| v * scale);
        lines.push(format!(
            "{name} disagreement: mean {mean:.d$}{unit}, median {median:.d$}{unit}, p95 {p95:.d$}{unit}, max {max:.d$}{unit} (frame {frame})"
        ));
    }
    lines.join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::formats;
    use glam::{DMat3, DVec3};

    fn result(frame: usize, status: Status, corners: Vec<[f64; 2]>, pose: Option<Pose>) -> FrameResult {
        FrameResult { pose: pose.map(formats::Pose::from), ..FrameResult::new(frame, status, corners) }
    }

    #[test]
    fn agreement_is_measured_where_both_runs_track() {
        let pose =
            |angle: f64, x: f64| Pose { rotation: DMat3::from_rotation_z(angle), translation: DVec3::new(x, 0.0, 1.0) };
        let forward = vec![
            result(0, Status::Tracking, vec![[0.0, 0.0], [10.0, 0.0]], Some(pose(0.0, 0.0))),
            result(1, Status::Tracking, vec![[1.0, 1.0], [11.0, 1.0]], Some(pose(0.1, 0.01))),
            result(2, Status::Lost, vec![[2.0, 2.0], [12.0, 2.0]], Some(pose(0.2, 0.02))),
            result(3, Status::Tracking, vec![[3.0, 3.0], [13.0, 3.0]], Some(pose(0.3, 0.03))),
            result(4, Status::Lost, vec![[4.0, 4.0], [14.0, 4.0]], None),
        ];
        // The backward run: frame 0 off by (3, 4) and (0, 0), frame 1 lost,
        // frames 2 and 3 exact, starting at frame 3.
        let backward = vec![
            result(0, Status::Tracking, vec![[3.0, 4.0], [10.0, 0.0]], Some(pose(0.05, 0.003))),
            result(1, Status::Lost, vec![[1.0, 1.0], [11.0, 1.0]], Some(pose(0.1, 0.01))),
            result(2, Status::Tracking, vec![[2.0, 2.0], [12.0, 2.0]], Some(pose(0.2, 0.02))),
            result(3, Status::Tracking, vec![[3.0, 3.0], [13.0, 3.0]], Some(pose(0.3, 0.03))),
        ];
        let report = compare(&forward, &backward, Some(3));
        assert_eq!((report.frames, report.forward_tracked, report.backward_tracked), (5, 3, 3));
        assert_eq!(report.compared(), 1, "frame 0 (frame 3 is the backward run's start)");
        let f0 = &report.per_frame[0];
        assert!((f0.corner_px.unwrap() - 2.5).abs() < 1e-12, "mean of 5 and 0 px");
        assert!((f0.translation_m.unwrap() - 0.003).abs() < 1e-12);
        assert!((f0.rotation_rad.unwrap() - 0.05).abs() < 1e-9);
        assert_eq!(report.per_frame[3].corner_px, None, "the start is not compared");
        assert_eq!((report.per_frame[1].corner_px, report.per_frame[2].corner_px), (None, None));
        assert_eq!(report.per_frame[4].backward, None, "after the start the backward run has no frame");
        let corners = report.stats(|f| f.corner_px).unwrap();
        assert!((corners.mean - 2.5).abs() < 1e-12 && (corners.max - 2.5).abs() < 1e-12);
        let text = summary(&report);
        assert!(text.contains("start excepted): 1"), "{text}");
        assert!(text.contains("max 2.500 px (frame 0)"), "{text}");
    }

    #[test]
    fn a_forward_run_that_never_tracks_has_nothing_to_compare() {
        let forward = vec![result(0, Status::Lost, vec![[0.0, 0.0]], None)];
        let report = compare(&forward, &[], None);
        assert_eq!((report.compared(), report.start), (0, None));
        assert!(report.stats(|f| f.corner_px).is_none());
        assert!(summary(&report).contains("the forward run tracked no frame"));
    }
}
