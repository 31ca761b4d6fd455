//! Regenerating the experiment of paper 000 §4 (Tables 1–3):
//! `pipetrack reproduce motion-edge` tracks synthetic pendulum sequences at
//! each peak image velocity, correlation threshold ζ and corner threshold ε,
//! for several seeds, and prints markdown tables beside the paper's figures.
//!
//! # Scene
//! The paper's set-up as far as it is described: a planar rectangle on a
//! pendulum, 256×242 frames at 60 Hz, 200 frames per data set, moving in
//! "simple translational velocity" ([`PendulumMotion::Translating`]: the
//! rectangle stays axis-aligned while its centre follows the arm), released
//! from rest. Noise σ = 2 grey levels on a textured static background. A
//! dark turning hexagon (the scene's distractor) crosses the frame once, its
//! centre row [`DISTRACTOR_GAP_PX`] px of clearance above the rectangle's top
//! edge at the bottom of the swing, so its motion pixels fall within reach of
//! the wider ζ strips: the paper attributes the growth of its error with ζ to
//! mislabelled motion pixels and claims that other moving features in view
//! are rejected, neither of which a scene without other motion can show.
//! Each seed renders its own background, noise and sequence; the sequence of
//! a (velocity, seed) pair is shared by every configuration, ζ and ε.
//!
//! # Configurations
//! `paper`: [`MotionEdgeParams::paper`], the method as printed with every
//! switchable extension off. `default`: pipetrack's defaults. Both with the
//! cell's ζ and ε.
//!
//! # Metrics, per run (one sequence, one configuration, one ζ and ε)
//! - *predicted − extracted* (the paper's "distance between the model corners
//!   and the actual corners", §4): over the frames reported tracking that
//!   followed a tracking frame, the mean distance between each corner's
//!   prediction for the frame (eq. 12, or the default's measured-motion
//!   prediction) and the corner extracted from the fitted lines, over the
//!   corners measured in that frame (at least one of their lines fitted).
//!   Extracted corners are the lines' intersections before any lag correction:
//!   with `lag_correction` on, a second tracker with it off runs on the same
//!   motion pixels (the correction moves only the reported corners, which
//!   the run checks by comparing both trackers' predictions every frame).
//! - *reported − truth*: over the frames reported tracking, the mean over the
//!   four corners of the distance between reported and true corner (what
//!   `pipetrack score` reports as mean corner error).
//!
//! Tracking runs on the CPU backend, deterministically: the same setup prints
//! the same tables.

use std::fmt::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use crate::backend::{CpuBackend, EarlyVision};
use crate::io::formats::Status;
use crate::synth::SyntheticSequence;
use crate::synth::pendulum::{
    ARM_LENGTH_PX, DISTRACTOR_RADIUS_PX, PIVOT, PendulumMotion, PendulumOptions, RECT_SIZE_PX, render_pendulum,
};
use crate::track::{MotionEdgeParams, MotionEdgeTracker, Observations, Phase, Tracker};
use crate::{Error, Result};

/// Peak image velocities, px/frame: the paper's three and two faster ones.
pub const SPEEDS: [f64; 5] = [1.1, 3.9, 4.5, 8.0, 16.0];
/// Correlation distance thresholds ζ of the tables' columns.
pub const ZETAS: [f64; 4] = [3.0, 5.0, 10.0, 15.0];
/// Corner thresholds ε of Tables 1, 2 and 3.
pub const EPSILONS: [f64; 3] = [20.0, 26.0, 32.0];
/// Frames per data set, as in the paper.
pub const FRAMES: usize = 200;
/// Seeds of the default run.
pub const SEEDS: [u64; 5] = [1, 2, 3, 4, 5];
/// Clearance between the distractor hexagon's circumcircle and the
/// rectangle's top edge at the bottom of the swing, px.
pub const DISTRACTOR_GAP_PX: f64 = 8.0;

/// The paper's velocities, in the row order of [`PAPER`].
pub const PAPER_SPEEDS: [f64; 3] = [1.1, 3.9, 4.5];
/// The paper's Tables 1–3 (mean data error, px), indexed `[table][velocity][ζ]`.
pub const PAPER: [[[f64; 4]; 3]; 3] = [
    [[0.302, 0.338, 0.335, 0.407], [0.045, 0.096, 0.096, 1.151], [0.009, 0.024, 1.174, 1.368]],
    [[0.301, 0.313, 0.357, 0.407], [0.110, 0.108, 0.052, 0.052], [0.009, 0.005, 1.177, 1.368]],
    [[0.302, 0.313, 0.348, 0.407], [0.031, 0.109, 0.097, 1.160], [0.001, 0.003, 1.174, 1.273]],
];

/// The paper's figure for corner threshold `epsilon`, velocity `speed` and
/// correlation threshold `zeta`, where it has one.
#[must_use]
pub fn paper_figure(epsilon: f64, speed: f64, zeta: f64) -> Option<f64> {
    let t = EPSILONS.iter().position(|&e| e == epsilon)?;
    let s = PAPER_SPEEDS.iter().position(|&v| v == speed)?;
    let z = ZETAS.iter().position(|&v| v == zeta)?;
    Some(PAPER[t][s][z])
}

/// A tracker configuration of the tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Config {
    /// pipetrack's defaults ([`MotionEdgeParams::default`]).
    Default,
    /// The method as printed ([`MotionEdgeParams::paper`]).
    Paper,
}

impl Config {
    /// The name on the command line and in the tables.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Config::Default => "default",
            Config::Paper => "paper",
        }
    }

    /// The parameters, before ζ and ε are set.
    #[must_use]
    pub fn params(self) -> MotionEdgeParams {
        match self {
            Config::Default => MotionEdgeParams::default(),
            Config::Paper => MotionEdgeParams::paper(),
        }
    }

    /// `default`, `paper` or `both` (paper first).
    pub fn parse_list(name: &str) -> Result<Vec<Config>> {
        match name {
            "default" => Ok(vec![Config::Default]),
            "paper" => Ok(vec![Config::Paper]),
            "both" => Ok(vec![Config::Paper, Config::Default]),
            other => Err(Error::Parameter(format!("unknown configuration {other:?} (default, paper, both)"))),
        }
    }
}

/// What to run: every combination of the lists.
#[derive(Clone, Debug, PartialEq)]
pub struct Setup {
    /// Peak image velocities, px/frame (rows).
    pub speeds: Vec<f64>,
    /// Correlation thresholds ζ, px (columns).
    pub zetas: Vec<f64>,
    /// Corner thresholds ε, px (one table each).
    pub epsilons: Vec<f64>,
    /// Seeds; each renders its own sequence per velocity.
    pub seeds: Vec<u64>,
    /// Frames per sequence.
    pub frames: usize,
    /// Tracker configurations (rows within a velocity).
    pub configs: Vec<Config>,
}

impl Setup {
    /// The paper's grid (plus 8 and 16 px/frame) with `configs` and `seeds`.
    #[must_use]
    pub fn tables(configs: Vec<Config>, seeds: Vec<u64>) -> Self {
        Self {
            speeds: SPEEDS.to_vec(),
            zetas: ZETAS.to_vec(),
            epsilons: EPSILONS.to_vec(),
            seeds,
            frames: FRAMES,
            configs,
        }
    }
}

/// Row of the distractor's centre: [`DISTRACTOR_GAP_PX`] plus its radius above
/// the rectangle's top edge at the bottom of the swing.
#[must_use]
pub fn distractor_row() -> f64 {
    PIVOT[1] + ARM_LENGTH_PX - RECT_SIZE_PX[1] / 2.0 - DISTRACTOR_RADIUS_PX - DISTRACTOR_GAP_PX
}

/// The scene of one sequence (module doc).
#[must_use]
pub fn scene(speed: f64, seed: u64, frames: usize) -> PendulumOptions {
    PendulumOptions {
        frames,
        seed,
        speed,
        motion: PendulumMotion::Translating,
        distractor: true,
        distractor_y: distractor_row(),
        ..PendulumOptions::default()
    }
}

/// The metrics of one run (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    /// Mean predicted − extracted corner distance, px (NaN without measured corners).
    pub paper_error: f64,
    /// Frames that contributed to `paper_error`.
    pub measured_frames: usize,
    /// Mean reported − true corner distance over tracking frames, px (NaN if none).
    pub truth_error: f64,
    /// Frames reported tracking.
    pub tracked: usize,
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Track `seq` with `params` on the CPU backend and measure both metrics.
pub fn run_one(seq: &SyntheticSequence, params: &MotionEdgeParams) -> Result<Run> {
    let (w, h) = (seq.camera.width as usize, seq.camera.height as usize);
    let corners = seq.init.corners.clone();
    let edges = seq.model.edges.clone();
    let mut tracker = MotionEdgeTracker::new(corners.clone(), edges.clone(), params.clone())?;
    // Extracted corners: a tracker without the lag correction on the same motion pixels.
    let mut twin = if params.lag_correction {
        let p = MotionEdgeParams { lag_correction: false, ..params.clone() };
        Some(MotionEdgeTracker::new(corners, edges, p)?)
    } else {
        None
    };
    let mut backend = CpuBackend::new();
    backend.reset();
    let (mut paper_sum, mut paper_count, mut measured_frames) = (0.0, 0usize, 0usize);
    let (mut truth_sum, mut tracked) = (0.0, 0usize);
    for (i, (frame, truth)) in seq.frames.iter().zip(&seq.truth).enumerate() {
        let predicted = tracker.predicted_corners().to_vec();
        let was_tracking = tracker.phase() == Phase::Tracking;
        let request = Tracker::request(&tracker, w, h);
        let features = backend.process(frame, &request)?;
        let obs = Observations::from(&features);
        let outcome = tracker.track(i, &obs);
        // `None` where the twin's loop parted from the tracker's (the
        // verification judges the reported corners, which the lag correction
        // moves): that frame has no extracted corners, and the twin restarts
        // from the tracker's state.
        let extracted = match twin.as_mut() {
            Some(t) => {
                let o = t.track(i, &obs);
                if t.phase() != tracker.phase() || t.predicted_corners() != tracker.predicted_corners() {
                    *t = tracker.without_lag_correction();
                    None
                } else {
                    Some(o.corners)
                }
            }
            None => Some(outcome.corners.clone()),
        };
        backend.recycle(features);
        if outcome.status != Status::Tracking {
            continue;
        }
        tracked += 1;
        let n = outcome.corners.len().min(truth.corners.len()).max(1);
        truth_sum += outcome.corners.iter().zip(&truth.corners).map(|(&c, &t)| distance(c, t)).sum::<f64>() / n as f64;
        if was_tracking && let Some(extracted) = extracted {
            let deviations: Vec<f64> = outcome
                .diagnostics
                .corner_measured
                .iter()
                .enumerate()
                .filter(|&(_, &m)| m)
                .map(|(k, _)| distance(extracted[k], predicted[k]))
                .collect();
            if !deviations.is_empty() {
                measured_frames += 1;
                paper_count += deviations.len();
                paper_sum += deviations.iter().sum::<f64>();
            }
        }
    }
    let mean = |sum: f64, n: usize| if n == 0 { f64::NAN } else { sum / n as f64 };
    Ok(Run {
        paper_error: mean(paper_sum, paper_count),
        measured_frames,
        truth_error: mean(truth_sum, tracked),
        tracked,
    })
}

/// Every run of a [`Setup`].
#[derive(Clone, Debug, PartialEq)]
pub struct Tables {
    /// What was run.
    pub setup: Setup,
    /// Runs indexed `[config][epsilon][speed][zeta][seed]`, flattened.
    runs: Vec<Run>,
}

impl Tables {
    /// The runs over the seeds of one cell (indices into the setup's lists).
    #[must_use]
    pub fn cell(&self, config: usize, epsilon: usize, speed: usize, zeta: usize) -> &[Run] {
        let s = &self.setup;
        let n = s.seeds.len();
        let index = (((config * s.epsilons.len() + epsilon) * s.speeds.len() + speed) * s.zetas.len() + zeta) * n;
        &self.runs[index..index + n]
    }
}

/// Run every cell of `setup` (in parallel; the result does not depend on the
/// order). `progress(done, total)` is called after each run.
pub fn run_tables(setup: &Setup, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<Tables> {
    let s = setup;
    let lists = [s.speeds.len(), s.zetas.len(), s.epsilons.len(), s.seeds.len(), s.configs.len(), s.frames];
    if lists.contains(&0) {
        return Err(Error::Parameter(
            "reproduce: speeds, zetas, epsilons, seeds, configurations and frames each need at least one".into(),
        ));
    }
    let total = s.configs.len() * s.epsilons.len() * s.speeds.len() * s.zetas.len() * s.seeds.len();
    let done = AtomicUsize::new(0);
    let mut runs = vec![None; total];
    for (si, &speed) in s.speeds.iter().enumerate() {
        for (ki, &seed) in s.seeds.iter().enumerate() {
            let seq = render_pendulum(&scene(speed, seed, s.frames))?;
            let jobs: Vec<(usize, usize, usize)> = (0..s.configs.len())
                .flat_map(|c| (0..s.epsilons.len()).flat_map(move |e| (0..s.zetas.len()).map(move |z| (c, e, z))))
                .collect();
            let results = jobs
                .par_iter()
                .map(|&(c, e, z)| {
                    let params = MotionEdgeParams { zeta: s.zetas[z], epsilon: s.epsilons[e], ..s.configs[c].params() };
                    let run = run_one(&seq, &params)?;
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                    Ok(((c, e, z), run))
                })
                .collect::<Result<Vec<_>>>()?;
            for ((c, e, z), run) in results {
                let index =
                    (((c * s.epsilons.len() + e) * s.speeds.len() + si) * s.zetas.len() + z) * s.seeds.len() + ki;
                runs[index] = Some(run);
            }
        }
    }
    let runs = runs.into_iter().map(|r| r.ok_or_else(|| Error::Parameter("a run is missing".into())));
    Ok(Tables { setup: setup.clone(), runs: runs.collect::<Result<Vec<_>>>()? })
}

/// `mean [min–max]` of `values` over the seeds (3 decimals), `—` when none is a number.
fn spread(values: &[f64]) -> String {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return "—".into();
    }
    let mean = finite.iter().sum::<f64>() / finite.len() as f64;
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let missing = values.len() - finite.len();
    let mut out = if finite.len() == 1 { format!("{mean:.3}") } else { format!("{mean:.3} [{lo:.3}–{hi:.3}]") };
    if missing > 0 {
        let _ = write!(out, " ({missing} seed(s) without data)");
    }
    out
}

/// `a–b` (or `a`) of frame counts over the seeds.
fn count_range(counts: impl Iterator<Item = usize> + Clone) -> String {
    let lo = counts.clone().min().unwrap_or(0);
    let hi = counts.max().unwrap_or(0);
    if lo == hi { format!("{lo}") } else { format!("{lo}–{hi}") }
}

/// Markdown of `tables`: one table per ε, rows per velocity: the paper's
/// figure, then per configuration both metrics.
#[must_use]
pub fn markdown(tables: &Tables) -> String {
    let s = &tables.setup;
    let mut md = String::new();
    let seeds: Vec<String> = s.seeds.iter().map(u64::to_string).collect();
    let _ = writeln!(
        md,
        "Scene: translating pendulum with a distractor (row {:.1}), {} frames, noise σ = 2, seeds {}; \
         CPU backend. Cells: mean over the seeds [min–max].",
        distractor_row(),
        s.frames,
        seeds.join(", ")
    );
    let columns: Vec<String> = s.zetas.iter().map(|z| format!("ζ = {z}")).collect();
    for (e, &epsilon) in s.epsilons.iter().enumerate() {
        let number = EPSILONS.iter().position(|&x| x == epsilon).map_or(String::new(), |t| format!(" {}", t + 1));
        let _ = writeln!(md, "\n#### Table{number} — corner error (px), ε = {epsilon}\n");
        let _ = writeln!(md, "| velocity (px/frame) | row | {} |", columns.join(" | "));
        let _ = writeln!(md, "|---|---|{}", "---|".repeat(s.zetas.len()));
        for (si, &speed) in s.speeds.iter().enumerate() {
            let figures: Vec<Option<f64>> = s.zetas.iter().map(|&z| paper_figure(epsilon, speed, z)).collect();
            if figures.iter().any(Option::is_some) {
                let cells: Vec<String> =
                    figures.iter().map(|f| f.map_or_else(|| "—".into(), |v| format!("{v:.3}"))).collect();
                let _ = writeln!(md, "| {speed} | paper's table | {} |", cells.join(" | "));
            }
            for (c, config) in s.configs.iter().enumerate() {
                let runs = |z: usize| tables.cell(c, e, si, z);
                let paper: Vec<String> = (0..s.zetas.len())
                    .map(|z| {
                        let r = runs(z);
                        let values: Vec<f64> = r.iter().map(|r| r.paper_error).collect();
                        format!("{}; {} fr.", spread(&values), count_range(r.iter().map(|r| r.measured_frames)))
                    })
                    .collect();
                let truth: Vec<String> = (0..s.zetas.len())
                    .map(|z| {
                        let r = runs(z);
                        let values: Vec<f64> = r.iter().map(|r| r.truth_error).collect();
                        let tracked = r.iter().map(|r| r.tracked);
                        let mut cell = spread(&values);
                        if tracked.clone().min().unwrap_or(0) < s.frames {
                            let _ = write!(cell, "; {} of {} tracked", count_range(tracked), s.frames);
                        }
                        cell
                    })
                    .collect();
                let name = config.name();
                let _ = writeln!(md, "| {speed} | `{name}` predicted − extracted | {} |", paper.join(" | "));
                let _ = writeln!(md, "| {speed} | `{name}` reported − truth | {} |", truth.join(" | "));
            }
        }
    }
    md
}
