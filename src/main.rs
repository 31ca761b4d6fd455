//! The `pipetrack` command line (SPEC §5).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use clap::{Parser, Subcommand};
use pipetrack::backend::BackendKind;
use pipetrack::io::Sequence;
use pipetrack::synth;
use pipetrack::track::run::{self, TrackOptions};

/// Model-based visual tracking with GPU early vision.
#[derive(Parser)]
#[command(name = "pipetrack", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Track a sequence folder; JSON Lines to stdout (or --out), summary to stderr.
    Track {
        /// Sequence folder (camera.json, model.json or model.cao, init.json, frames/).
        seq_dir: PathBuf,
        /// Tracker: motion-edge (000) or blue (002).
        #[arg(long)]
        tracker: String,
        /// Early-vision backend.
        #[arg(long, value_enum, default_value_t = Backend::Gpu)]
        backend: Backend,
        /// Write the JSON Lines here instead of stdout (appears only when complete).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write one overlay PNG per frame into this folder.
        #[arg(long)]
        overlay: Option<PathBuf>,
        /// Tracker parameters (TOML; a `[motion-edge]` table or top-level keys).
        #[arg(long)]
        config: Option<PathBuf>,
        /// `-` reads the frames as a Y4M stream from stdin instead of SEQ_DIR/frames.
        #[arg(long)]
        frames: Option<String>,
    },
    /// Render a synthetic sequence with exact ground truth.
    Synth {
        /// Scene name: pendulum (000) or target3dof (002).
        scene: String,
        /// Output folder (must be absent or empty).
        out_dir: PathBuf,
        /// Number of frames (scene default when omitted).
        #[arg(long)]
        frames: Option<usize>,
        /// Seed of textures and noise.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Peak speed: px/frame for pendulum, rad/s of angular speed for target3dof.
        #[arg(long)]
        speed: Option<String>,
        /// Gaussian noise σ in grey levels.
        #[arg(long)]
        noise: Option<String>,
        /// Fraction of the target hidden by an occluding bar, 0–0.3 (target3dof).
        #[arg(long)]
        occlude: Option<String>,
        /// Scene option KEY=VALUE (repeatable), e.g. --set background=cluttered.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// Score a tracker's output against the sequence's truth.jsonl.
    Score {
        /// Sequence folder holding truth.jsonl.
        seq_dir: PathBuf,
        /// The tracker's JSON Lines.
        pred: PathBuf,
    },
    /// Synthesise a short sequence, track it, write overlays to a temp folder, print the score.
    Demo,
    /// Regenerate a paper's result tables on synthetic sequences (markdown on stdout).
    Reproduce {
        /// Tracker whose paper to reproduce: motion-edge (Tables 1–3 of 000).
        tracker: String,
        /// `default` (pipetrack's parameters), `paper` (the method as printed), or `both`.
        #[arg(long, default_value = "both")]
        config: String,
    },
    /// Compare every early-vision stage and the whole chain on the CPU and the GPU.
    Bench {
        /// Frame sizes, comma-separated WxH.
        #[arg(long, default_value = "256x242,640x480,1280x720", value_parser = parse_sizes)]
        sizes: Sizes,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
        /// Only these stages (comma-separated); default all.
        #[arg(long, value_delimiter = ',')]
        stages: Vec<String>,
        /// Seconds of timing per stage, size and backend.
        #[arg(long, default_value_t = 0.5)]
        seconds: f64,
    },
}

#[derive(Clone, Debug)]
struct Sizes(Vec<(usize, usize)>);

fn parse_sizes(s: &str) -> Result<Sizes, String> {
    s.split(',')
        .map(|part| {
            let (w, h) = part.trim().split_once(['x', 'X']).ok_or_else(|| format!("size {part:?} is not WxH"))?;
            let w: usize = w.parse().map_err(|_| format!("bad width in {part:?}"))?;
            let h: usize = h.parse().map_err(|_| format!("bad height in {part:?}"))?;
            if w == 0 || h == 0 || w > 16384 || h > 16384 {
                return Err(format!("size {part:?} out of range 1..=16384"));
            }
            Ok((w, h))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Sizes)
}

/// Exit status for problems with the user's input (SPEC §5).
const EXIT_BAD_INPUT: u8 = 2;

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("pipetrack: {e:#}");
            let bad_input = e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<pipetrack::Error>(),
                    Some(
                        pipetrack::Error::Input { .. }
                            | pipetrack::Error::Io { .. }
                            | pipetrack::Error::Parameter(_)
                            | pipetrack::Error::Size(_)
                    )
                )
            });
            ExitCode::from(if bad_input { EXIT_BAD_INPUT } else { 1 })
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Backend {
    Gpu,
    Cpu,
}

impl From<Backend> for BackendKind {
    fn from(b: Backend) -> Self {
        match b {
            Backend::Gpu => BackendKind::Gpu,
            Backend::Cpu => BackendKind::Cpu,
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Track { seq_dir, tracker, backend, out, overlay, config, frames } => {
            let from_stdin = match frames.as_deref() {
                None => false,
                Some("-") => true,
                Some(other) => {
                    return Err(pipetrack::Error::Parameter(format!(
                        "--frames takes only '-' (Y4M on stdin), not {other:?}"
                    ))
                    .into());
                }
            };
            let seq = Sequence::open(&seq_dir, from_stdin)?;
            let opts = TrackOptions { tracker, backend: backend.into(), config, overlay, progress: true };
            let summary = match &out {
                Some(path) => run::track_to_file(&seq, &opts, path)?,
                None => {
                    let stdout = std::io::stdout();
                    let mut lock = std::io::BufWriter::new(stdout.lock());
                    let s = run::track_sequence(&seq, &opts, &mut lock, |_| {})?;
                    lock.flush()?;
                    s
                }
            };
            eprintln!(
                "pipetrack: {} frames, {} tracking, {:.1} frames/s on {}",
                summary.frames, summary.tracked, summary.fps, summary.backend
            );
            Ok(())
        }
        Command::Synth { scene, out_dir, frames, seed, speed, noise, occlude, set } => {
            let mut extra = Vec::new();
            if let Some(v) = speed {
                extra.push(("speed".to_string(), v));
            }
            if let Some(v) = noise {
                extra.push(("noise".to_string(), v));
            }
            if let Some(v) = occlude {
                extra.push(("occlude".to_string(), v));
            }
            for kv in set {
                let (k, v) = kv
                    .split_once('=')
                    .ok_or_else(|| pipetrack::Error::Parameter(format!("--set {kv:?} is not KEY=VALUE")))?;
                extra.push((k.to_string(), v.to_string()));
            }
            let seq = synth::generate(&scene, &out_dir, frames, seed, &extra)?;
            eprintln!("pipetrack: wrote {} frames of '{}' to {}", seq.frames.len(), scene, out_dir.display());
            Ok(())
        }
        Command::Score { seq_dir, pred } => {
            let seq = Sequence::open(&seq_dir, false)?;
            let truth = seq.require_truth()?;
            let score = pipetrack::cli::score::score_file(truth, &pred)?;
            println!("{score}");
            Ok(())
        }
        Command::Demo => {
            pipetrack::cli::demo::run_demo(&pipetrack::cli::demo::default_root(), &mut std::io::stdout().lock())?;
            Ok(())
        }
        Command::Reproduce { tracker, config } => {
            if tracker != "motion-edge" {
                return Err(pipetrack::Error::Parameter(format!(
                    "no tables to reproduce for tracker {tracker:?} (motion-edge)"
                ))
                .into());
            }
            let configs: Vec<&str> = match config.as_str() {
                "both" => vec!["default", "paper"],
                c => vec![c],
            };
            for c in configs {
                let tables =
                    pipetrack::cli::reproduce::run_tables(c, |done, total| eprint!("\r{c}: {done}/{total} runs"))?;
                eprintln!();
                println!("{}", pipetrack::cli::reproduce::markdown(c, &tables));
            }
            Ok(())
        }
        Command::Bench { sizes, json, stages, seconds } => bench(&sizes.0, json, &stages, seconds),
    }
}

fn bench(sizes: &[(usize, usize)], json: bool, stages: &[String], seconds: f64) -> anyhow::Result<()> {
    let all = pipetrack::cli::bench::stages();
    let chosen: Vec<&str> = if stages.is_empty() {
        all.to_vec()
    } else {
        stages
            .iter()
            .map(|s| {
                all.iter().copied().find(|a| a == s).ok_or_else(|| {
                    pipetrack::Error::Parameter(format!("unknown stage {s:?}; known: {}", all.join(", ")))
                })
            })
            .collect::<Result<_, _>>()?
    };
    if !(seconds > 0.0 && seconds < 60.0) {
        return Err(pipetrack::Error::Parameter(format!("--seconds {seconds} must be in (0, 60)")).into());
    }
    let budget = Duration::from_secs_f64(seconds);
    if !json {
        println!("{:<14} {:>10} {:>12} {:>12} {:>9}", "stage", "size", "cpu fps", "gpu fps", "gpu/cpu");
    }
    let report = pipetrack::cli::bench::compare(sizes, &chosen, budget, |row| {
        if !json {
            let gpu = row.gpu_fps.map_or("-".to_string(), |g| format!("{g:.1}"));
            let ratio = row.gpu_over_cpu.map_or("-".to_string(), |r| format!("{r:.2}"));
            println!("{:<14} {:>10} {:>12.1} {:>12} {:>9}", row.stage, row.size, row.cpu_fps, gpu, ratio);
        }
    })
    .context("benchmark failed")?;
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        for c in &report.gpu_chain {
            let f = &c.per_frame;
            println!(
                "gpu chain {:>10}: {} dispatches, {} bytes up, {} bytes back per frame",
                c.size, f.dispatches, f.bytes_uploaded, f.bytes_read_back
            );
        }
        println!("adapter: {}\ncpu threads: {}", report.adapter, report.cpu_threads);
    }
    Ok(())
}
