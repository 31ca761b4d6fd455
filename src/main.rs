//! The `pipetrack` command line (SPEC §5).
//!
//! Exit status: 0 on success; 2 for bad input (a file named on the command
//! line, its content or an output that cannot be written, one line on stderr
//! naming it); 1 for anything else. A reader that closes our standard output
//! early (`pipetrack score ... | head -1`) ends the command quietly with
//! status 0, as it means the reader has had enough. SIGINT and SIGTERM remove
//! every unfinished output (`FILE.partial-PID-N`, overlay staging folders) and exit
//! with 128 + the signal's number (130, 143).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use pipetrack::backend::BackendKind;
use pipetrack::bounds::counted;
use pipetrack::io::Sequence;
use pipetrack::synth;
use pipetrack::track::run::{self, TrackOptions};

/// Model-based visual tracking with GPU early vision.
#[derive(Parser)]
#[command(
    name = "pipetrack",
    version,
    about,
    after_help = "Exit status: 0 on success, and when the reader of stdout closes it early; 2 for bad input \
                  (one line on stderr naming the file); 130 or 143 after SIGINT or SIGTERM, with unfinished \
                  outputs removed; 1 otherwise."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The tracker and how it runs, as `track` and `roundtrip` take them.
#[derive(Args)]
struct TrackerArgs {
    /// Tracker: motion-edge (000), lowe (001), blue (002) or condensation (004).
    #[arg(long)]
    tracker: String,
    /// Early-vision backend.
    #[arg(long, value_enum, default_value_t = Backend::Gpu)]
    backend: Backend,
    /// Tracker parameters (TOML; the tracker's own table, e.g. `[lowe]`, or top-level keys).
    #[arg(long)]
    config: Option<PathBuf>,
}

impl TrackerArgs {
    /// The run's options, drawing overlays into `overlay`.
    fn options(self, overlay: Option<PathBuf>) -> TrackOptions {
        TrackOptions {
            tracker: self.tracker,
            backend: self.backend.into(),
            config: self.config,
            overlay,
            progress: true,
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Track a sequence folder; JSON Lines to stdout (or --out), summary to stderr.
    Track {
        /// Sequence folder (camera.json, model.json, model.cao or model.obj, init.json, frames/).
        seq_dir: PathBuf,
        #[command(flatten)]
        tracker_args: TrackerArgs,
        /// Write the JSON Lines here instead of stdout (appears only when complete; `-`: stdout).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write one overlay PNG per frame into this folder (must be absent or empty).
        #[arg(long)]
        overlay: Option<PathBuf>,
        /// `-` reads the frames as a Y4M stream from stdin instead of SEQ_DIR/frames.
        #[arg(long)]
        frames: Option<String>,
    },
    /// Render a synthetic sequence with exact ground truth.
    Synth {
        /// Scene name: pendulum (000), target3dof (002), textured-plane (004), box or hinged-box (001).
        scene: String,
        /// Output folder (must be absent or empty).
        out_dir: PathBuf,
        /// Number of frames, 1 to 20000 [default: 200 for pendulum and textured-plane, 300 for the others].
        #[arg(long, allow_negative_numbers = true)]
        frames: Option<usize>,
        /// Seed of textures and noise.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Peak speed: px/frame for pendulum, 0 to 32 [default: 3.9], box and hinged-box, 0 to 50 [default: 4];
        /// rad/s of angular speed for target3dof, 0 to 5 [default: 0.3]; the scale of the motion's amplitudes
        /// for textured-plane, 0 to 10 [default: 1].
        #[arg(long, allow_negative_numbers = true)]
        speed: Option<String>,
        /// Gaussian noise σ in grey levels, 0 to 64 [default: 2; 1.5 for textured-plane].
        #[arg(long, allow_negative_numbers = true)]
        noise: Option<String>,
        /// Fraction of the target hidden by an occluding bar: of its area, 0–0.3 (target3dof); of its visible edge
        /// length, 0–0.5 (box, hinged-box) [default: 0].
        #[arg(long, allow_negative_numbers = true)]
        occlude: Option<String>,
        /// Shake the target with abrupt reversals (target3dof; same as --set shake=true).
        #[arg(long)]
        shake: bool,
        /// Scene option KEY=VALUE (repeatable), e.g. --set background=cluttered; an option the scene lacks is
        /// refused with the scene's list.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// Convert a ViSP model-based-tracking data set (Images/, CameraPose/, Config/, Models/), a folder of
    /// frames imageNNNN.png with NAME.cao, NAME.xml and NAME.0.pos beside it, or a folder of frames
    /// color_image_NNNN.png filmed beside a tag grid (apriltag_data.json, init/NAME.json, camera.xml,
    /// ../models/NAME/NAME.obj) to a sequence folder.
    ImportVisp {
        /// The ViSP data set folder, e.g. mbt-depth/Castle-simu of ViSP's test images, or a folder of frames
        /// such as mbt/cube.
        src: PathBuf,
        /// Output sequence folder (must be absent or empty).
        out_dir: PathBuf,
        /// The .cao model, relative to SRC (default: the one in Models/ named like a Config/ file; for a folder
        /// of frames, relative to the folder holding it, default SRC.cao or the only .cao there).
        #[arg(long)]
        model: Option<PathBuf>,
        /// The ViSP settings .xml with the <camera> intrinsics, relative as --model (default: Config/<model>.xml;
        /// <model>.xml beside the model for a folder of frames).
        #[arg(long)]
        camera: Option<PathBuf>,
        /// For a folder of frames: the first frame's pose, relative as --model (default: <model>.0.pos beside
        /// the model); beside a tag grid: the object's init/NAME.json (default: the only one).
        #[arg(long)]
        init: Option<PathBuf>,
        /// Convert only the first N frames.
        #[arg(long)]
        frames: Option<usize>,
        /// Also draw the true projection of the model over every frame with a known pose into this folder
        /// (must be absent or empty, and not in OUT_DIR).
        #[arg(long)]
        overlay: Option<PathBuf>,
        /// A further part of the object, as ViSP's load() arguments: FILE.cao (relative as --model)
        /// [, t=[x; y; z], tu=[a; b; c] or R=[r11; ...; r33]] (repeatable).
        #[arg(long, value_name = "FILE[, PLACEMENT]")]
        include: Vec<String>,
    },
    /// Track forward, then backward from the last tracking frame, and report how the two runs agree
    /// (a check for sequences without truth).
    Roundtrip {
        /// Sequence folder (as for track; truth.jsonl is not read).
        seq_dir: PathBuf,
        #[command(flatten)]
        tracker_args: TrackerArgs,
        /// Also write each frame's agreement as JSON Lines here (appears only when complete).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Score a tracker's output against the sequence's truth.jsonl.
    Score {
        /// Sequence folder holding truth.jsonl.
        seq_dir: PathBuf,
        /// The tracker's JSON Lines.
        pred: PathBuf,
        /// Corner error (px) above which a frame reported `tracking` counts as false tracking.
        #[arg(long = "false-tracking-px", allow_negative_numbers = true, default_value_t = pipetrack::cli::score::DEFAULT_FALSE_TRACKING_PX)]
        false_tracking_px: f64,
        /// Also draw the per-frame corner error and status over time into this PNG.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// With --plot: the plot's size in pixels, WxH: width 480 to 8192, height 300 to 8192.
        #[arg(long, default_value = "1000x500", value_parser = parse_plot_size, requires = "plot")]
        plot_size: (usize, usize),
    },
    /// Track every sequence of a manifest into OUT/<name>.jsonl, skipping complete outputs.
    Batch {
        /// A file listing `SEQ_DIR [TRACKER [CONFIG]]` per line (paths relative to the file's folder), or a
        /// folder of sequence folders.
        manifest: PathBuf,
        /// Output folder: <name>.jsonl per sequence and summary.jsonl. Needed with --list too: a folder
        /// manifest does not list the output folder when it lies inside it.
        #[arg(long)]
        out: PathBuf,
        /// Tracker for sequences whose manifest line names none.
        #[arg(long)]
        tracker: Option<String>,
        /// Early-vision backend.
        #[arg(long, value_enum, default_value_t = Backend::Gpu)]
        backend: Backend,
        /// Sequences in flight, 1 to 64: GPU lanes sharing one submission per step, or CPU threads.
        #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u16).range(1..=pipetrack::backend::MAX_LANES as i64))]
        jobs: u16,
        /// Take only the sequences at positions I, I+N, I+2N, … of the manifest (0 ≤ I < N).
        #[arg(long, value_name = "I/N")]
        shard: Option<pipetrack::cli::batch::Shard>,
        /// Print the sequences this shard takes (name and folder) and track nothing.
        #[arg(long)]
        list: bool,
    },
    /// Print a tracker's default parameters as a `--config` file (TOML, every key with its default).
    Config {
        /// Tracker: motion-edge, lowe, blue or condensation.
        tracker: String,
    },
    /// Synthesise a short sequence, track it, write overlays to a temp folder, print the score.
    Demo {
        /// Early-vision backend.
        #[arg(long, value_enum, default_value_t = Backend::Gpu)]
        backend: Backend,
    },
    /// Regenerate a paper's result tables on synthetic sequences (markdown on stdout).
    Reproduce {
        /// Tracker whose paper to reproduce: motion-edge (Tables 1–3 of 000)
        /// or condensation (Fig. 4 of 004, written to --out).
        tracker: String,
        /// motion-edge: `default` (pipetrack's parameters), `paper` (the
        /// method as printed), or `both` (the default).
        #[arg(long)]
        config: Option<String>,
        /// Seeds, comma-separated. motion-edge: each renders its own
        /// sequence per velocity (default 1,2,3,4,5); condensation: one seed
        /// (default 1).
        #[arg(long, value_delimiter = ',')]
        seeds: Option<Vec<u64>>,
        /// condensation: the folder for fig4.csv and fig4_l<l>.png.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Compare every early-vision stage and the whole chain on the CPU and the GPU.
    Bench {
        /// Frame sizes, comma-separated WxH.
        #[arg(long, default_value = "256x242,640x480,1280x720", value_parser = parse_sizes)]
        sizes: Sizes,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
        /// Only these stages (comma-separated) of gaussian, temporal_diff, frame_sum, sobel, compaction, log,
        /// zero_crossing, cpf, edge_pyramid and chain; default all.
        #[arg(long, value_delimiter = ',')]
        stages: Vec<String>,
        /// Seconds of timing per stage, size and backend, more than 0 and less than 60.
        #[arg(long, default_value_t = 0.5)]
        seconds: f64,
        /// Time the CPU twins only, without opening a GPU adapter.
        #[arg(long)]
        cpu_only: bool,
        /// Instead of the stages: the window energy with these numbers of
        /// sample windows (comma-separated, 1 to 65535), e.g. 200,1000,5000.
        #[arg(long, value_delimiter = ',', conflicts_with_all = ["stages", "sizes"])]
        windows: Vec<usize>,
        /// Instead of the stages: the whole chain with these numbers of
        /// sequences in flight (comma-separated, 1 to 64), as `batch` runs
        /// them: one submission per step carries a frame of each.
        #[arg(long, value_delimiter = ',', conflicts_with_all = ["windows", "stages"],
              value_parser = clap::value_parser!(u16).range(1..=pipetrack::backend::MAX_LANES as i64))]
        lanes: Vec<u16>,
        /// With --lanes: cap every list of the chain at this many features, 1 to
        /// 65535 (a stratified subsample, as the blue tracker caps its list at
        /// 1500); default: every listed pixel comes back.
        #[arg(long, requires = "lanes",
              value_parser = clap::value_parser!(u32).range(1..=i64::from(pipetrack::early::compaction::MAX_CAP)))]
        cap: Option<u32>,
    },
}

#[derive(Clone, Debug)]
struct Sizes(Vec<(usize, usize)>);

fn parse_plot_size(s: &str) -> Result<(usize, usize), String> {
    let (w, h) = parse_wxh(s)?;
    pipetrack::cli::plot::check_plot_size(w, h)?;
    Ok((w, h))
}

/// One `WxH` (or `WXH`), any sizes.
fn parse_wxh(part: &str) -> Result<(usize, usize), String> {
    let (w, h) = part.trim().split_once(['x', 'X']).ok_or_else(|| format!("size {part:?} is not WxH"))?;
    let w: usize = w.parse().map_err(|_| format!("bad width in {part:?}"))?;
    let h: usize = h.parse().map_err(|_| format!("bad height in {part:?}"))?;
    Ok((w, h))
}

fn parse_sizes(s: &str) -> Result<Sizes, String> {
    s.split(',')
        .map(|part| {
            let (w, h) = parse_wxh(part)?;
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
    quiet_headless_vulkan();
    let cli = match parse_command_line() {
        Ok(cli) => cli,
        Err(e) => return usage_error(&e),
    };
    remove_unfinished_outputs_on_signals();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            note(format_args!("pipetrack: {}", one_message(&e)));
            // A file the user named that cannot be read or written is bad
            // input; a full disk is not.
            let bad_input = e.chain().any(|c| match c.downcast_ref::<pipetrack::Error>() {
                Some(pipetrack::Error::Io { source, .. }) => {
                    !matches!(source.kind(), std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded)
                }
                Some(pipetrack::Error::Input { .. } | pipetrack::Error::Parameter(_) | pipetrack::Error::Size(_)) => {
                    true
                }
                _ => false,
            });
            ExitCode::from(if bad_input { EXIT_BAD_INPUT } else { 1 })
        }
    }
}

/// Help and version on stdout as clap prints them; a mistake on the command
/// line as one line on stderr, as every other bad input, with exit status 2.
/// The command line, a negative number given to an option read as its value
/// (so `--seed -1` is refused for its value, not taken for an unknown flag).
fn parse_command_line() -> Result<Cli, clap::Error> {
    use clap::{CommandFactory, FromArgMatches};
    let command = Cli::command().allow_negative_numbers(true).mut_subcommands(|s| s.allow_negative_numbers(true));
    Cli::from_arg_matches(&command.try_get_matches()?)
}

fn usage_error(e: &clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp | ErrorKind::DisplayVersion | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        e.exit();
    }
    // The message and its tips, without the usage clap adds after them.
    let text = e.render().to_string();
    let mut message = String::new();
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if line.starts_with("Usage:") || line.starts_with("For more information") {
            break;
        }
        match (line.strip_prefix("error: "), line.strip_prefix("tip: ")) {
            (Some(first), _) => message.push_str(first),
            (_, Some(tip)) => message.extend(["; ", tip]),
            _ => message.extend([" ", line]),
        }
    }
    note(format_args!("pipetrack: {message} (see --help)"));
    ExitCode::from(EXIT_BAD_INPUT)
}

/// Mesa's device-selection Vulkan layer (installed with its drivers) asks
/// Wayland for the display's GPU when Vulkan lists the devices, and
/// libwayland prints `error: XDG_RUNTIME_DIR is invalid or not set in the
/// environment.` where the session has no runtime folder (the variable
/// unset, or not an absolute path to a folder): a headless
/// machine, a batch job, a container. pipetrack picks its adapter itself
/// (`WGPU_ADAPTER_NAME`, `WGPU_POWER_PREF`), so there the layer is turned
/// off (`NODEVICE_SELECT=1`), unless the user asked it for a device
/// (`MESA_VK_DEVICE_SELECT`, `DRI_PRIME`) or set `NODEVICE_SELECT`.
fn quiet_headless_vulkan() {
    let unset = |name: &str| std::env::var_os(name).is_none();
    let no_runtime_folder = std::env::var_os("XDG_RUNTIME_DIR").is_none_or(|d| {
        let d = std::path::Path::new(&d);
        !(d.is_absolute() && d.is_dir())
    });
    if no_runtime_folder && ["NODEVICE_SELECT", "MESA_VK_DEVICE_SELECT", "DRI_PRIME"].into_iter().all(unset) {
        // SAFETY: called first thing in `main`, before any thread exists
        // that could read or write the environment.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}

/// On SIGINT or SIGTERM, remove the unfinished outputs and exit with
/// 128 + the signal's number. Without a signal thread the default action
/// (ending the process) stays.
fn remove_unfinished_outputs_on_signals() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else { return };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            pipetrack::io::atomic::remove_unfinished();
            note(format_args!("pipetrack: interrupted; unfinished outputs removed"));
            std::process::exit(128 + signal);
        }
    });
}

/// `e` and its causes on one line, a cause left out where the message
/// before it already says it (an I/O error names its OS error, which is
/// also its source).
fn one_message(e: &anyhow::Error) -> String {
    let mut message = e.to_string();
    for cause in e.chain().skip(1) {
        let text = cause.to_string();
        if !message.contains(&text) {
            message = format!("{message}: {text}");
        }
    }
    message
}

/// Whether `e` comes from writing to a pipe whose reader has gone.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe))
}

/// A line on stderr; a closed or full stderr is ignored (there is nowhere
/// left to report it).
fn note(line: std::fmt::Arguments<'_>) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// After a run, the keys of the sequence's files that no reader read
/// (a misspelt key is otherwise silently without effect).
fn note_ignored_keys(seq: &Sequence) {
    for line in seq.ignored_keys() {
        note(format_args!("pipetrack: note: {line}"));
    }
}

/// A line on stdout, flushed; a failed write is an error naming `stdout`.
fn say(line: std::fmt::Arguments<'_>) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{line}").and_then(|()| out.flush()).map_err(|e| pipetrack::Error::io("stdout", e))?;
    Ok(())
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
        Command::Track { seq_dir, tracker_args, out, overlay, frames } => {
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
            let opts = tracker_args.options(overlay);
            let summary = match out.as_deref().filter(|path| *path != Path::new("-")) {
                Some(path) => run::track_to_file(&seq, &opts, path)?,
                None => run::track_to_stdout(&seq, &opts)?,
            };
            note(format_args!(
                "pipetrack: {}, {} tracking, {:.1} frames/s on {}",
                counted(summary.frames, "frame", "frames"),
                summary.tracked,
                summary.fps,
                summary.backend
            ));
            note_ignored_keys(&seq);
            Ok(())
        }
        Command::Synth { scene, out_dir, frames, seed, speed, noise, occlude, shake, set } => {
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
            if shake {
                extra.push(("shake".to_string(), "true".to_string()));
            }
            let flags = extra.len();
            for kv in set {
                let (k, v) = kv
                    .split_once('=')
                    .ok_or_else(|| pipetrack::Error::Parameter(format!("--set {kv:?} is not KEY=VALUE")))?;
                if let Some(at) = extra.iter().position(|(key, _)| key == k) {
                    let other = if at < flags { format!("--{k}") } else { "another --set".to_string() };
                    let msg = format!("--set {kv:?} and {other} both set {k}; give it once");
                    return Err(pipetrack::Error::Parameter(msg).into());
                }
                extra.push((k.to_string(), v.to_string()));
            }
            let seq = synth::generate(&scene, &out_dir, frames, seed, &extra)?;
            let frames = counted(seq.frames.len(), "frame", "frames");
            note(format_args!("pipetrack: wrote {frames} of '{}' to {}", scene, out_dir.display()));
            Ok(())
        }
        Command::ImportVisp { src, out_dir, model, camera, init, frames, overlay, include } => {
            use pipetrack::cli::import_visp::{ImportOptions, import_visp};
            let r = import_visp(&src, &out_dir, &ImportOptions { model, camera, init, frames, overlay, include })?;
            let a = &r.alignment;
            let motion = match (r.mean_motion_px, r.max_motion_px) {
                (Some(mean), Some(max)) => format!("true vertex motion {mean:.2} px/frame mean, {max:.2} max"),
                _ => "no truth, init.json from the first frame's pose".to_string(),
            };
            let over = if r.truth { "" } else { " of the first frame" };
            let alignment = if a.found == 0 {
                // Nothing measured is no alignment, good or bad.
                format!(
                    "no image edge found near the visible edges{over} ({} points sampled): \
                     check the intrinsics and the poses (--overlay draws them)",
                    a.samples
                )
            } else {
                format!(
                    "visible edges{over} to image edges: {:.3} px mean, {:.3} px median over {} of {} points",
                    a.mean_px, a.median_px, a.found, a.samples
                )
            };
            note(format_args!(
                "pipetrack: wrote {} of {}x{} and a model of {} ({}) to {}; {motion}; {alignment}",
                counted(r.frames, "frame", "frames"),
                r.camera.width,
                r.camera.height,
                counted(r.vertices, "vertex", "vertices"),
                counted(r.model_files.len(), "file", "files"),
                out_dir.display(),
            ));
            Ok(())
        }
        Command::Roundtrip { seq_dir, tracker_args, out } => {
            use pipetrack::cli::roundtrip::{roundtrip, roundtrip_to_file, summary};
            let seq = Sequence::open(&seq_dir, false)?;
            let opts = tracker_args.options(None);
            let report = match &out {
                Some(path) => roundtrip_to_file(&seq, &opts, path)?,
                None => roundtrip(&seq, &opts)?,
            };
            say(format_args!("{}", summary(&report)))?;
            note_ignored_keys(&seq);
            Ok(())
        }
        Command::Score { seq_dir, pred, false_tracking_px, plot, plot_size } => {
            if pred.as_os_str() == "-" {
                let msg = "score reads the predictions from a file (`track --out FILE`), not from stdin";
                return Err(pipetrack::Error::input(&pred, msg).into());
            }
            let seq = Sequence::open_for_scoring(&seq_dir)?;
            if let Some(png) = &plot {
                let mut inputs = seq.input_files();
                inputs.push(pred.clone());
                pipetrack::cli::plot::check_plot_path(png, &inputs)?;
            }
            let truth = seq.read_truth()?;
            let (score, predictions) = pipetrack::cli::score::score_file_read(&truth, &pred, false_tracking_px)?;
            if let Some(png) = plot {
                pipetrack::cli::plot::plot_score(&score, &predictions, &png, plot_size)?;
            }
            say(format_args!("{score}"))
        }
        Command::Batch { manifest, out, tracker, backend, jobs, shard, list } => {
            use pipetrack::cli::batch::{self, BatchOptions, Shard};
            let opts = BatchOptions {
                out_dir: out,
                tracker,
                backend: backend.into(),
                jobs: usize::from(jobs),
                shard: shard.unwrap_or(Shard::ALL),
                progress: true,
            };
            if list {
                for entry in batch::shard_entries(&manifest, &opts)? {
                    say(format_args!("{}\t{}", entry.name, entry.dir.display()))?;
                }
                return Ok(());
            }
            let start = std::time::Instant::now();
            let report = batch::run(&manifest, &opts)?;
            let seconds = start.elapsed().as_secs_f64().max(1e-9);
            say(format_args!("{}", batch::markdown(&report.lines)))?;
            let tracked: Vec<_> = report.lines.iter().filter(|l| l.status == batch::SequenceStatus::Tracked).collect();
            let frames: usize = tracked.iter().filter_map(|l| l.frames).sum();
            note(format_args!(
                "pipetrack: {} tracked, {} skipped, {} failed in {seconds:.2} s: {:.2} sequences/s, {:.1} frames/s",
                counted(tracked.len(), "sequence", "sequences"),
                report.lines.iter().filter(|l| l.status == batch::SequenceStatus::Skipped).count(),
                report.failed(),
                tracked.len() as f64 / seconds,
                frames as f64 / seconds
            ));
            let (failed, total) = (report.failed(), report.lines.len());
            match report.first_error {
                None => Ok(()),
                Some(first) => Err(anyhow::Error::new(first).context(format!(
                    "{failed} of {total} sequences failed (each named in {}); first failure",
                    opts.out_dir.join(batch::SUMMARY_FILE).display()
                ))),
            }
        }
        Command::Config { tracker } => {
            let text = run::default_config(&tracker)?;
            say(format_args!("{}", text.trim_end()))
        }
        Command::Demo { backend } => {
            let root = pipetrack::cli::demo::default_root();
            pipetrack::cli::demo::run_demo(&root, backend.into(), &mut std::io::stdout().lock())?;
            Ok(())
        }
        Command::Reproduce { tracker, config, seeds, out } => {
            use pipetrack::cli::reproduce::{Config, Setup, markdown, run_tables};
            if tracker == "condensation" {
                if config.is_some() {
                    return Err(pipetrack::Error::Parameter(
                        "reproduce condensation has one configuration: --config is for motion-edge".into(),
                    )
                    .into());
                }
                let seed = match seeds.as_deref() {
                    None => 1,
                    Some(&[seed]) => seed,
                    Some(_) => {
                        return Err(pipetrack::Error::Parameter("reproduce condensation takes one seed".into()).into());
                    }
                };
                let out = out.ok_or_else(|| {
                    pipetrack::Error::Parameter("reproduce condensation writes figures: give --out DIR".into())
                })?;
                let summary = pipetrack::cli::reproduce_condensation::reproduce_fig4(&out, seed)?;
                note(format_args!("reproduce: wrote fig4.csv and fig4_l1..6.png to {}", out.display()));
                return say(format_args!("{summary}"));
            }
            if tracker != "motion-edge" {
                return Err(pipetrack::Error::Parameter(format!(
                    "no tables to reproduce for tracker {tracker:?} (motion-edge, condensation)"
                ))
                .into());
            }
            if out.is_some() {
                return Err(pipetrack::Error::Parameter(
                    "reproduce motion-edge prints its tables on stdout: --out is for condensation's figures".into(),
                )
                .into());
            }
            let seeds = seeds.unwrap_or_else(|| pipetrack::cli::reproduce::SEEDS.to_vec());
            let setup = Setup::tables(Config::parse_list(config.as_deref().unwrap_or("both"))?, seeds);
            let tables = run_tables(&setup, &|done, total| {
                let _ = write!(std::io::stderr(), "\rreproduce: {done}/{total} runs");
            })?;
            note(format_args!(""));
            say(format_args!("{}", markdown(&tables)))
        }
        Command::Bench { windows, json, seconds, cpu_only, .. } if !windows.is_empty() => {
            bench_windows(&windows, json, seconds, !cpu_only)
        }
        Command::Bench { sizes, json, stages, seconds, cpu_only, lanes, cap, .. } => {
            let lanes: Vec<usize> = lanes.into_iter().map(usize::from).collect();
            bench(&sizes.0, json, &stages, (&lanes, cap), seconds, !cpu_only)
        }
    }
}

fn bench_windows(counts: &[usize], json: bool, seconds: f64, gpu: bool) -> anyhow::Result<()> {
    if !(seconds > 0.0 && seconds < 60.0) {
        return Err(pipetrack::Error::Parameter(format!("--seconds {seconds} must be in (0, 60)")).into());
    }
    if let Some(&n) = counts.iter().find(|&&n| n == 0 || n > pipetrack::early::window_energy::MAX_WINDOWS) {
        return Err(pipetrack::Error::Parameter(format!(
            "--windows {n} must be in 1..={}",
            pipetrack::early::window_energy::MAX_WINDOWS
        ))
        .into());
    }
    if !json {
        say(format_args!("{:<22} {:>8} {:>12} {:>12} {:>9}", "stage", "windows", "cpu ms", "gpu ms", "gpu/cpu"))?;
    }
    let mut write_error = None;
    let report = pipetrack::cli::bench_windows::bench_windows(counts, Duration::from_secs_f64(seconds), gpu, |r| {
        if !json && write_error.is_none() {
            let gpu = r.gpu_ms.map_or("-".to_string(), |g| format!("{g:.2}"));
            let ratio = r.gpu_over_cpu.map_or("-".to_string(), |x| format!("{x:.2}"));
            write_error = say(format_args!(
                "{:<22} {:>8} {:>12.2} {:>12} {:>9}",
                "window_energy 64/16", r.windows, r.cpu_ms, gpu, ratio
            ))
            .err();
        }
    })
    .context("benchmark failed")?;
    if let Some(e) = write_error {
        return Err(e);
    }
    if json {
        say(format_args!("{}", serde_json::to_string_pretty(&report)?))?;
    } else {
        say(format_args!("{GPU_OVER_CPU}\nadapter: {}\ncpu threads: {}", report.adapter, report.cpu_threads))?;
    }
    Ok(())
}

/// The footnote of `bench`'s tables.
const GPU_OVER_CPU: &str = "gpu/cpu: the GPU's frames per second over the CPU's (above 1: the GPU is faster)";

fn bench(
    sizes: &[(usize, usize)],
    json: bool,
    stages: &[String],
    (lanes, cap): (&[usize], Option<u32>),
    seconds: f64,
    gpu: bool,
) -> anyhow::Result<()> {
    let all = pipetrack::cli::bench::stages();
    let chosen: Vec<&str> = if stages.is_empty() {
        all.to_vec()
    } else {
        stages
            .iter()
            .map(|s| {
                all.iter().copied().find(|a| *a == s.trim()).ok_or_else(|| {
                    pipetrack::Error::Parameter(format!("unknown stage {s:?}; known: {}", all.join(", ")))
                })
            })
            .collect::<Result<_, _>>()?
    };
    if let Some(twice) = chosen.iter().enumerate().find_map(|(i, s)| chosen[..i].contains(s).then_some(s)) {
        return Err(pipetrack::Error::Parameter(format!("--stages names {twice} twice")).into());
    }
    if !(seconds > 0.0 && seconds < 60.0) {
        return Err(pipetrack::Error::Parameter(format!("--seconds {seconds} must be in (0, 60)")).into());
    }
    let budget = Duration::from_secs_f64(seconds);
    if !json {
        say(format_args!(
            "{:<26} {:>10} {:>12} {:>12} {:>9} {:>12}",
            "stage", "size", "cpu fps", "gpu fps", "gpu/cpu", "cpu best ms"
        ))?;
    }
    let mut write_error = None;
    let print_row = |row: &pipetrack::cli::bench::BenchRow| {
        if !json && write_error.is_none() {
            let gpu = row.gpu_fps.map_or("-".to_string(), |g| format!("{g:.1}"));
            let ratio = row.gpu_over_cpu.map_or("-".to_string(), |r| format!("{r:.2}"));
            write_error = say(format_args!(
                "{:<26} {:>10} {:>12.1} {:>12} {:>9} {:>12.4}",
                row.stage,
                row.size,
                row.cpu_fps,
                gpu,
                ratio,
                1e3 / row.cpu_best_fps
            ))
            .err();
        }
    };
    let report = if lanes.is_empty() {
        pipetrack::cli::bench::compare(sizes, &chosen, budget, gpu, print_row)
    } else {
        pipetrack::cli::bench::compare_lanes(sizes, lanes, cap, budget, gpu, print_row)
    }
    .context("benchmark failed")?;
    if let Some(e) = write_error {
        return Err(e);
    }
    if json {
        say(format_args!("{}", serde_json::to_string_pretty(&report)?))?;
    } else {
        for c in &report.gpu_chain {
            let f = &c.per_frame;
            say(format_args!(
                "gpu chain {:>10}: {} dispatches, {} bytes up, {} bytes back, host {:.3} ms per frame (best {:.3})",
                c.size, f.dispatches, f.bytes_uploaded, f.bytes_read_back, c.host_ms, c.host_best_ms
            ))?;
        }
        for c in &report.gpu_lanes {
            say(format_args!(
                "gpu chain {:>10}, {} {}: {} dispatches a step, host {:.3} ms per frame",
                c.size,
                c.lanes,
                if c.stacked { "stacked" } else { "in flight" },
                c.dispatches_per_step,
                c.host_ms
            ))?;
        }
        say(format_args!("{GPU_OVER_CPU}\nadapter: {}\ncpu threads: {}", report.adapter, report.cpu_threads))?;
    }
    Ok(())
}
