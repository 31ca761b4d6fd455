//! Scoring a tracker's output against `truth.jsonl` (the `score` command).
//!
//! **Corner error** of a frame: the mean over the visible model vertices of
//! the Euclidean distance in pixels between predicted and true corners.
//! `truth.jsonl`'s `"visible"` says which vertices are visible, one boolean
//! per vertex (or one for the whole object). It is computed on the frames
//! where at least one vertex is visible and the prediction is tracking; a
//! lost frame counts against "frames tracked", not against the error
//! figures. Over those frames we report mean, median (mean of the two
//! middle values for an even count), p95 (nearest rank: the ⌈0.95·n⌉-th
//! smallest) and max.
//!
//! **False tracking**: a frame reported `tracking` whose corner error
//! exceeds a threshold ([`DEFAULT_FALSE_TRACKING_PX`] = 5 px unless
//! `--false-tracking-px` says otherwise), or that is reported `tracking`
//! while truth shows no vertex of the object at all: the tracker claims the
//! object where it is not. Counted over the whole run and reported with its
//! fraction of the tracking frames and of all frames, and the frames listed
//! as runs of consecutive frames (the first 20 runs, the rest counted).
//!
//! **Frame agreement.** The tracker writes one line per frame, so the
//! predictions must list exactly the truth's frames, in the same order:
//! a different count (a run that stopped early, a truth file for another
//! sequence) or a different frame number is an error naming the
//! predictions file, never a silently partial score; a gap in the truth's
//! own frames is an error of `truth.jsonl`, found as it is read
//! ([`crate::io::Sequence::read_truth`]). A tracking frame whose
//! truth is visible must have as many corners as the truth.

use std::fmt;
use std::path::Path;

use crate::io::formats::{FrameResult, Status, TruthFrame, Visibility};
use crate::io::json::read_frame_lines;
use crate::{Error, Result};

/// Corner error above which a tracking frame is false tracking, px
/// (module doc).
pub const DEFAULT_FALSE_TRACKING_PX: f64 = 5.0;

/// Figures over per-frame values: the corner errors of the scored frames,
/// in pixels, or any other per-frame measure (the units are the values').
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorStats {
    /// Mean of the per-frame corner errors.
    pub mean: f64,
    /// Median of the per-frame corner errors.
    pub median: f64,
    /// 95th percentile (nearest rank) of the per-frame corner errors.
    pub p95: f64,
    /// Largest per-frame corner error.
    pub max: f64,
}

impl ErrorStats {
    /// Figures of `errors`; `None` when it is empty.
    #[must_use]
    pub fn of(errors: &[f64]) -> Option<Self> {
        if errors.is_empty() {
            return None;
        }
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let median = if n % 2 == 1 { sorted[n / 2] } else { 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]) };
        // Nearest rank: the smallest value with at least 95 % of the values at or below it.
        let rank = (n * 95).div_ceil(100).max(1);
        Some(Self { mean: sorted.iter().sum::<f64>() / n as f64, median, p95: sorted[rank - 1], max: sorted[n - 1] })
    }
}

/// The result of scoring one run.
#[derive(Clone, Debug, PartialEq)]
pub struct Score {
    /// Frames in the run (prediction lines).
    pub frames: usize,
    /// Frames whose status is tracking.
    pub tracked: usize,
    /// The first frame whose status is lost, if any.
    pub first_lost: Option<usize>,
    /// `(frame, corner error)` for every scored frame (some vertex visible
    /// and tracking), in frame order.
    pub frame_errors: Vec<(usize, f64)>,
    /// Mean error of each model vertex over the scored frames where that
    /// vertex is visible, in vertex order; `None` for a vertex never visible
    /// in a scored frame (empty when no frame was scored).
    pub corner_errors: Vec<Option<f64>>,
    /// Figures over `frame_errors`; `None` when no frame was scored.
    pub stats: Option<ErrorStats>,
    /// The threshold of false tracking, px (module doc).
    pub false_tracking_px: f64,
    /// Frames reported `tracking` whose corner error exceeds
    /// `false_tracking_px`, or whose truth shows no vertex (module doc), in
    /// frame order.
    pub false_tracking: Vec<usize>,
    /// Frames with a visible corner farther than [`MAX_CORNER_ERROR_PX`]
    /// from the truth, counted as that far off, in frame order.
    pub capped_frames: Vec<usize>,
    /// Pose errors over the scored frames where both the prediction and the
    /// truth have a pose; `None` without any.
    pub pose_errors: Option<PoseErrors>,
}

/// Errors of the reported pose and joint values against the truth's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseErrors {
    /// Frames compared.
    pub frames: usize,
    /// Mean and largest distance between the translations, m.
    pub translation_m: [f64; 2],
    /// Mean and largest angle of the relative rotation R_pred·R_truthᵀ, degrees.
    pub rotation_deg: [f64; 2],
    /// Mean and largest absolute joint value difference over joints and
    /// frames, degrees; `None` for a model without joints.
    pub joint_deg: Option<[f64; 2]>,
}

impl PoseErrors {
    /// The errors over `(predicted, truth)` pairs of pose and joint values.
    fn of(pairs: &[(&FrameResult, &TruthFrame)]) -> Option<Self> {
        use crate::geometry::{Pose as RigidPose, axis_angle_from_rotation};
        let mut translation = Vec::new();
        let mut rotation = Vec::new();
        let mut joints = Vec::new();
        for (p, t) in pairs {
            let (Some(pp), Some(tp)) = (&p.pose, &t.pose) else { continue };
            let (a, b) = (RigidPose::from(pp), RigidPose::from(tp));
            translation.push((a.translation - b.translation).length());
            rotation.push(axis_angle_from_rotation(&(a.rotation * b.rotation.transpose())).length().to_degrees());
            if let Some(params) = &p.params {
                joints.extend(params.iter().zip(&t.params).map(|(x, y)| (x - y).abs().to_degrees()));
            }
        }
        let mean_max = |v: &[f64]| [v.iter().sum::<f64>() / v.len() as f64, v.iter().copied().fold(0.0, f64::max)];
        (!translation.is_empty()).then(|| Self {
            frames: translation.len(),
            translation_m: mean_max(&translation),
            rotation_deg: mean_max(&rotation),
            joint_deg: (!joints.is_empty()).then(|| mean_max(&joints)),
        })
    }
}

impl Score {
    /// Fraction of the tracking frames that are false tracking; 0 when no
    /// frame is tracking.
    #[must_use]
    pub fn false_tracking_fraction_of_tracked(&self) -> f64 {
        if self.tracked == 0 { 0.0 } else { self.false_tracking.len() as f64 / self.tracked as f64 }
    }

    /// Fraction of all frames that are false tracking; 0 for an empty run.
    #[must_use]
    pub fn false_tracking_fraction(&self) -> f64 {
        if self.frames == 0 { 0.0 } else { self.false_tracking.len() as f64 / self.frames as f64 }
    }
}

/// Score `predictions` against `truth` (see the module docs for the rules).
/// A disagreement between the two is an [`Error::Parameter`]; use
/// [`score_file`] to get an error naming the predictions file.
/// False tracking is judged at [`DEFAULT_FALSE_TRACKING_PX`].
pub fn score(truth: &[TruthFrame], predictions: &[FrameResult]) -> Result<Score> {
    score_with(truth, predictions, DEFAULT_FALSE_TRACKING_PX)
}

/// [`score`] with false tracking judged at `false_tracking_px` (finite and
/// not negative, else an [`Error::Parameter`]).
pub fn score_with(truth: &[TruthFrame], predictions: &[FrameResult], false_tracking_px: f64) -> Result<Score> {
    check_threshold(false_tracking_px)?;
    score_impl(truth, predictions, false_tracking_px).map_err(Error::Parameter)
}

fn check_threshold(px: f64) -> Result<()> {
    if px.is_finite() && px >= 0.0 {
        Ok(())
    } else {
        Err(Error::Parameter(format!("false-tracking threshold {px} px is not a finite number ≥ 0")))
    }
}

/// Read the tracker output at `pred_path` and score it against `truth`;
/// errors name `pred_path`.
/// False tracking is judged at [`DEFAULT_FALSE_TRACKING_PX`].
pub fn score_file(truth: &[TruthFrame], pred_path: &Path) -> Result<Score> {
    score_file_with(truth, pred_path, DEFAULT_FALSE_TRACKING_PX)
}

/// [`score_file`] with false tracking judged at `false_tracking_px`.
pub fn score_file_with(truth: &[TruthFrame], pred_path: &Path, false_tracking_px: f64) -> Result<Score> {
    score_file_read(truth, pred_path, false_tracking_px).map(|(score, _)| score)
}

/// [`score_file_with`], also giving the predictions it read.
pub fn score_file_read(
    truth: &[TruthFrame],
    pred_path: &Path,
    false_tracking_px: f64,
) -> Result<(Score, Vec<FrameResult>)> {
    check_threshold(false_tracking_px)?;
    let predictions = read_predictions(pred_path)?;
    let score = score_impl(truth, &predictions, false_tracking_px).map_err(|msg| Error::input(pred_path, msg))?;
    Ok((score, predictions))
}

/// Largest corner error `score` counts, px: a corner farther from the
/// truth counts as this far off (a finite corner can lie so far that its
/// distance overflows to infinity, and the means and the plot's axis with
/// it). Such a frame, reported tracking, is false tracking like any other.
pub const MAX_CORNER_ERROR_PX: f64 = 1e9;

fn score_impl(
    truth: &[TruthFrame],
    predictions: &[FrameResult],
    false_tracking_px: f64,
) -> std::result::Result<Score, String> {
    if predictions.len() != truth.len() {
        let range = |first: Option<usize>, last: Option<usize>| match (first, last) {
            (Some(a), Some(b)) => format!(" (frames {a} to {b})"),
            _ => String::new(),
        };
        return Err(format!(
            "{} frames{} but truth.jsonl has {}{}: score needs one prediction per truth frame",
            predictions.len(),
            range(predictions.first().map(|p| p.frame), predictions.last().map(|p| p.frame)),
            truth.len(),
            range(truth.first().map(|t| t.frame), truth.last().map(|t| t.frame)),
        ));
    }
    let mut frame_errors = Vec::new();
    let mut posed = Vec::new();
    let mut false_tracking = Vec::new();
    let mut capped_frames = Vec::new();
    let mut corner_sums: Vec<(f64, usize)> = Vec::new();
    for (p, t) in predictions.iter().zip(truth) {
        if p.frame != t.frame {
            return Err(format!("frame {} where truth.jsonl has frame {}", p.frame, t.frame));
        }
        if let Visibility::Vertices(seen) = &t.visible
            && !t.corners.is_empty()
            && seen.len() != t.corners.len()
        {
            return Err(format!(
                "frame {}: truth.jsonl has {} visibility flags for {} corners",
                t.frame,
                seen.len(),
                t.corners.len()
            ));
        }
        if p.status != Status::Tracking {
            continue;
        }
        if !t.visible.any() {
            false_tracking.push(p.frame);
            continue;
        }
        if t.corners.is_empty() {
            return Err(format!("frame {}: truth.jsonl has no corners for this visible frame", t.frame));
        }
        if p.corners.len() != t.corners.len() {
            return Err(format!(
                "frame {}: {} corners but truth.jsonl has {}",
                p.frame,
                p.corners.len(),
                t.corners.len()
            ));
        }
        if let Some(params) = p.params.as_ref().filter(|p| !p.is_empty() && !t.params.is_empty())
            && params.len() != t.params.len()
        {
            return Err(format!(
                "frame {}: {} joint values (\"params\") but truth.jsonl has {}",
                p.frame,
                params.len(),
                t.params.len()
            ));
        }
        if corner_sums.is_empty() {
            corner_sums = vec![(0.0, 0); t.corners.len()];
        } else if corner_sums.len() != t.corners.len() {
            return Err(format!(
                "frame {}: the number of corners changes from {} to {}",
                p.frame,
                corner_sums.len(),
                t.corners.len()
            ));
        }
        let (mut sum, mut visible, mut capped) = (0.0, 0, false);
        for (i, ((pc, tc), acc)) in p.corners.iter().zip(&t.corners).zip(&mut corner_sums).enumerate() {
            if t.visible.vertex(i) {
                let distance = (pc[0] - tc[0]).hypot(pc[1] - tc[1]);
                capped |= distance > MAX_CORNER_ERROR_PX;
                let d = distance.min(MAX_CORNER_ERROR_PX);
                acc.0 += d;
                acc.1 += 1;
                sum += d;
                visible += 1;
            }
        }
        if capped {
            capped_frames.push(p.frame);
        }
        let error = sum / visible as f64;
        if !(error <= false_tracking_px) {
            false_tracking.push(p.frame);
        }
        frame_errors.push((p.frame, error));
        posed.push((p, t));
    }
    let errors: Vec<f64> = frame_errors.iter().map(|&(_, e)| e).collect();
    Ok(Score {
        frames: predictions.len(),
        tracked: predictions.iter().filter(|p| p.status == Status::Tracking).count(),
        first_lost: predictions.iter().find(|p| p.status == Status::Lost).map(|p| p.frame),
        stats: ErrorStats::of(&errors),
        corner_errors: corner_sums.into_iter().map(|(sum, n)| (n > 0).then(|| sum / n as f64)).collect(),
        frame_errors,
        false_tracking_px,
        false_tracking,
        capped_frames,
        pose_errors: PoseErrors::of(&posed),
    })
}

/// Read a tracker output file (JSON Lines, SPEC §4): each line must parse,
/// pass [`FrameResult::validate`], and frame numbers must strictly increase.
/// Errors name the file and the line.
pub fn read_predictions(path: &Path) -> Result<Vec<FrameResult>> {
    read_frame_lines(path, |p: &FrameResult| p.frame, |p, line| p.validate(path, line))
}

/// Most runs of frames the summary lists before it counts the rest.
const MAX_LISTED_RANGES: usize = 20;

/// Ascending frame numbers as comma-separated runs (`3, 7–9, 12`), the
/// first `max_ranges` runs only, the rest counted (`… and 5 more frames`).
fn frame_ranges(frames: &[usize], max_ranges: usize) -> String {
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for &frame in frames {
        match runs.last_mut() {
            Some((_, last)) if *last + 1 == frame => *last = frame,
            _ => runs.push((frame, frame)),
        }
    }
    let mut text: Vec<String> =
        runs.iter().take(max_ranges).map(|&(a, b)| if a == b { a.to_string() } else { format!("{a}–{b}") }).collect();
    let rest: usize = runs.iter().skip(max_ranges).map(|(a, b)| b - a + 1).sum();
    if rest > 0 {
        text.push(format!("… and {rest} more frames"));
    }
    text.join(", ")
}

impl fmt::Display for Score {
    /// The summary the `score` command prints, one figure per line.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.stats {
            Some(s) => {
                writeln!(f, "mean corner error:   {:.3} px", s.mean)?;
                writeln!(f, "median corner error: {:.3} px", s.median)?;
                writeln!(f, "p95 corner error:    {:.3} px", s.p95)?;
                writeln!(f, "max corner error:    {:.3} px", s.max)?;
            }
            None => writeln!(f, "corner error:        n/a (no frame with the object visible and tracked)")?,
        }
        writeln!(f, "frames scored:       {} (truth visible and tracking)", self.frame_errors.len())?;
        writeln!(f, "frames tracked:      {} of {}", self.tracked, self.frames)?;
        writeln!(
            f,
            "false tracking:      {} ({:.1} % of tracked, {:.1} % of all frames; tracking with error > {} px or nothing visible)",
            self.false_tracking.len(),
            100.0 * self.false_tracking_fraction_of_tracked(),
            100.0 * self.false_tracking_fraction(),
            crate::bounds::short_number(self.false_tracking_px)
        )?;
        if !self.false_tracking.is_empty() {
            writeln!(f, "false tracking at:   {}", frame_ranges(&self.false_tracking, MAX_LISTED_RANGES))?;
        }
        if !self.capped_frames.is_empty() {
            writeln!(
                f,
                "corners too far:     a corner over {MAX_CORNER_ERROR_PX:e} px off counted as {MAX_CORNER_ERROR_PX:e} px at {}",
                frame_ranges(&self.capped_frames, MAX_LISTED_RANGES)
            )?;
        }
        if let Some(e) = &self.pose_errors {
            writeln!(
                f,
                "pose error:          translation {:.2} mm mean, {:.2} mm max; rotation {:.3}° mean, {:.3}° max ({} frames)",
                1e3 * e.translation_m[0],
                1e3 * e.translation_m[1],
                e.rotation_deg[0],
                e.rotation_deg[1],
                e.frames
            )?;
            if let Some([mean, max]) = e.joint_deg {
                writeln!(f, "joint error:         {mean:.2}° mean, {max:.2}° max")?;
            }
        }
        match self.first_lost {
            Some(frame) => write!(f, "first lost frame:    {frame}"),
            None => write!(f, "first lost frame:    none"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::frame_ranges;

    #[test]
    fn frame_ranges_joins_consecutive_frames_and_counts_what_it_leaves_out() {
        assert_eq!(frame_ranges(&[], 3), "");
        assert_eq!(frame_ranges(&[7], 3), "7");
        assert_eq!(frame_ranges(&[0, 4, 5, 6, 9, 11, 12], 10), "0, 4–6, 9, 11–12");
        // Three runs listed; the fourth, frames 11–12, counted.
        assert_eq!(frame_ranges(&[0, 4, 5, 6, 9, 11, 12], 3), "0, 4–6, 9, … and 2 more frames");
    }
}
