//! Regenerating the paper's tables: `pipetrack reproduce motion-edge` runs
//! the experiment of 000 §4 (Tables 1–3) on synthetic pendulum sequences.
//!
//! Per peak image velocity (the paper's 1.1, 3.9 and 4.5 px/frame, plus 8 and
//! 16) one 200-frame pendulum sequence is rendered (noise σ = 2 grey levels);
//! each (ζ, ε) cell tracks it with the motion-edge tracker on the CPU backend
//! (deterministic, and the GPU gives the same lists) and reports the mean
//! corner error over the frames tracked, as the paper's "mean data error".
//! Two configurations run: pipetrack's defaults, and the paper's method as
//! printed (regression fits of eq. 5–8, one labelling pass, fixed ζ, eq. 12
//! predictions, coasting on predictions), keeping only the half-frame lag
//! correction.

use std::fmt::Write as _;

use crate::backend::CpuBackend;
use crate::cli::score::score;
use crate::io::formats::{FrameResult, Status};
use crate::synth::pendulum::{PendulumOptions, render_pendulum};
use crate::track::motion_edge::{LineFitMethod, MissingMeasurement, Prediction};
use crate::track::run::track_frames;
use crate::track::{MotionEdgeParams, MotionEdgeTracker};
use crate::{Error, Result};

/// Peak image velocities, px/frame: the paper's three and two faster ones.
pub const SPEEDS: [f64; 5] = [1.1, 3.9, 4.5, 8.0, 16.0];
/// Correlation distance thresholds ζ of the tables' columns.
pub const ZETAS: [f64; 4] = [3.0, 5.0, 10.0, 15.0];
/// Corner thresholds ε of Tables 1, 2 and 3.
pub const EPSILONS: [f64; 3] = [20.0, 26.0, 32.0];
/// Frames per data set, as in the paper.
pub const FRAMES: usize = 200;

/// The paper's Tables 1–3 (mean data error, px), [table][velocity][ζ].
pub const PAPER: [[[f64; 4]; 3]; 3] = [
    [[0.302, 0.338, 0.335, 0.407], [0.045, 0.096, 0.096, 1.151], [0.009, 0.024, 1.174, 1.368]],
    [[0.301, 0.313, 0.357, 0.407], [0.110, 0.108, 0.052, 0.052], [0.009, 0.005, 1.177, 1.368]],
    [[0.302, 0.313, 0.348, 0.407], [0.031, 0.109, 0.097, 1.160], [0.001, 0.003, 1.174, 1.273]],
];

/// One cell: mean corner error and how many frames were tracked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// Mean corner error over tracked frames, px (NaN if none).
    pub mean_error: f64,
    /// Largest per-frame corner error, px.
    pub max_error: f64,
    /// Frames whose status was tracking.
    pub tracked: usize,
}

/// The paper's method as printed, with only the lag correction kept.
#[must_use]
pub fn paper_literal() -> MotionEdgeParams {
    MotionEdgeParams {
        line_fit: LineFitMethod::Regression,
        refine_iterations: 0,
        band_tolerance: false,
        missing: MissingMeasurement::Prediction,
        prediction: Prediction::Smoothed,
        ..MotionEdgeParams::default()
    }
}

/// Track one rendered pendulum with `params`; score against its truth.
pub fn run_cell(speed: f64, params: MotionEdgeParams, seed: u64) -> Result<Cell> {
    let seq = render_pendulum(&PendulumOptions { frames: FRAMES, seed, speed, ..PendulumOptions::default() })?;
    let (w, h) = (seq.camera.width as usize, seq.camera.height as usize);
    let mut tracker = MotionEdgeTracker::new(seq.init.corners.clone(), seq.model.edges.clone(), params)?;
    let mut backend = CpuBackend::new();
    let mut results: Vec<FrameResult> = Vec::with_capacity(FRAMES);
    track_frames(&mut tracker, &mut backend, seq.frames.iter().cloned().map(Ok), (w, h), |_, _, r| {
        results.push(r.clone());
        Ok(())
    })?;
    let s = score(&seq.truth, &results)?;
    let tracked = results.iter().filter(|r| r.status == Status::Tracking).count();
    let (mean_error, max_error) = s.stats.map_or((f64::NAN, f64::NAN), |st| (st.mean, st.max));
    Ok(Cell { mean_error, max_error, tracked })
}

/// Run every table for `config` ("default" or "paper"); returns
/// `[ε][speed][ζ]` cells. `progress` is called after each cell.
pub fn run_tables(config: &str, mut progress: impl FnMut(usize, usize)) -> Result<Vec<Vec<Vec<Cell>>>> {
    let base = match config {
        "default" => MotionEdgeParams::default(),
        "paper" => paper_literal(),
        other => return Err(Error::Parameter(format!("unknown configuration {other:?} (default, paper)"))),
    };
    let total = EPSILONS.len() * SPEEDS.len() * ZETAS.len();
    let mut done = 0;
    let mut tables = Vec::new();
    for &epsilon in &EPSILONS {
        let mut rows = Vec::new();
        for (si, &speed) in SPEEDS.iter().enumerate() {
            let mut row = Vec::new();
            for &zeta in &ZETAS {
                let params = MotionEdgeParams { zeta, epsilon, ..base.clone() };
                row.push(run_cell(speed, params, 1 + si as u64)?);
                done += 1;
                progress(done, total);
            }
            rows.push(row);
        }
        tables.push(rows);
    }
    Ok(tables)
}

/// Markdown of the tables beside the paper's figures.
#[must_use]
pub fn markdown(config: &str, tables: &[Vec<Vec<Cell>>]) -> String {
    let mut md = String::new();
    for (t, (&epsilon, rows)) in EPSILONS.iter().zip(tables).enumerate() {
        let _ =
            writeln!(md, "\n#### Table {} — mean corner error (px), ε = {epsilon}, configuration `{config}`\n", t + 1);
        let _ = writeln!(md, "| velocity (px/frame) | ζ = 3 | ζ = 5 | ζ = 10 | ζ = 15 |");
        let _ = writeln!(md, "|---|---|---|---|---|");
        for (si, (&speed, row)) in SPEEDS.iter().zip(rows).enumerate() {
            let cells: Vec<String> = row
                .iter()
                .enumerate()
                .map(|(zi, c)| {
                    let ours = if c.tracked == FRAMES {
                        format!("{:.3}", c.mean_error)
                    } else {
                        format!("{:.3} ({} of {FRAMES} tracked)", c.mean_error, c.tracked)
                    };
                    match PAPER.get(t).and_then(|tab| tab.get(si)).map(|r| r[zi]) {
                        Some(p) => format!("{ours} (paper {p:.3})"),
                        None => ours,
                    }
                })
                .collect();
            let _ = writeln!(md, "| {speed} | {} |", cells.join(" | "));
        }
    }
    md
}
