//! `pipetrack demo`: a 120-frame pendulum at 3.9 px/frame, synthesised into a
//! temporary folder, tracked by motion-edge with overlays (on the GPU
//! backend unless told otherwise), and scored against its truth.

use std::io::Write;
use std::path::PathBuf;

use crate::backend::BackendKind;
use crate::io::Sequence;
use crate::track::{TrackOptions, track_to_file};
use crate::{Error, Result, synth};

/// Frames of the demo sequence.
const DEMO_FRAMES: usize = 120;
/// Peak speed of the demo pendulum, px/frame (one of paper 000's speeds).
const DEMO_SPEED: &str = "3.9";

/// Run the demo under `root` (created if absent) on `backend` and write its
/// report to `out`.
pub fn run_demo(root: &std::path::Path, backend: BackendKind, out: &mut dyn Write) -> Result<()> {
    let seq_dir = root.join("sequence");
    let overlay = root.join("overlay");
    std::fs::create_dir_all(root).map_err(|e| Error::input(root, format!("cannot create folder: {e}")))?;
    let extra = [("speed".to_string(), DEMO_SPEED.to_string())];
    synth::generate("pendulum", &seq_dir, Some(DEMO_FRAMES), 1, &extra)?;
    let seq = Sequence::open(&seq_dir, false)?;
    let opts = TrackOptions {
        tracker: "motion-edge".into(),
        backend,
        config: None,
        overlay: Some(overlay.clone()),
        progress: true,
    };
    let pred_path = root.join("track.jsonl");
    let summary = track_to_file(&seq, &opts, &pred_path)?;
    let score = super::score::score_file(&seq.read_truth()?, &pred_path)?;
    let report = format!(
        "pipetrack demo: pendulum, {DEMO_FRAMES} frames at {DEMO_SPEED} px/frame, tracker motion-edge on {}\n\
         sequence: {}\noutput:   {}\noverlays: {}\n{:.1} frames/s\n{score}\n",
        summary.backend,
        seq_dir.display(),
        pred_path.display(),
        overlay.display(),
        summary.fps
    );
    out.write_all(report.as_bytes()).map_err(|e| Error::io("output", e))
}

/// The demo's default folder: a fresh folder under the system's temporary directory.
#[must_use]
pub fn default_root() -> PathBuf {
    std::env::temp_dir().join(format!("pipetrack-demo-{}", std::process::id()))
}
