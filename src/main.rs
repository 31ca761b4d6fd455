//! The `pipetrack` command line (SPEC §5).

use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use clap::{Parser, Subcommand};

/// Model-based visual tracking with GPU early vision.
#[derive(Parser)]
#[command(name = "pipetrack", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
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
                    Some(pipetrack::Error::Input { .. } | pipetrack::Error::Io { .. } | pipetrack::Error::Parameter(_) | pipetrack::Error::Size(_))
                )
            });
            ExitCode::from(if bad_input { EXIT_BAD_INPUT } else { 1 })
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Bench { sizes, json, stages, seconds } => bench(&sizes.0, json, &stages, seconds),
    }
}

fn bench(sizes: &[(usize, usize)], json: bool, stages: &[String], seconds: f64) -> anyhow::Result<()> {
    let all = pipetrack::bench::STAGES;
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
    let report = pipetrack::bench::compare(sizes, &chosen, budget, |row| {
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
        println!("adapter: {}\ncpu threads: {}", report.adapter, report.cpu_threads);
    }
    Ok(())
}
