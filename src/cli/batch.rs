//! The `batch` command: track every sequence a manifest lists, each into
//! `OUT/<name>.jsonl`, and keep one summary line per sequence in
//! `OUT/summary.jsonl`.
//!
//! **Manifest.** Either a folder, whose sub-folders (sorted by name, the
//! output folder and hidden ones left out) are the sequences (a sequence
//! folder itself, holding `camera.json`, `init.json` or a model file, is
//! refused: its parent is the folder of sequences), or a text
//! file with one sequence per line:
//! `SEQ_DIR [TRACKER [CONFIG]]`, fields separated by spaces or tabs (no
//! quoting: a folder whose name has a space is listed by its parent), blank
//! lines and lines starting with `#` ignored, relative paths taken from the
//! manifest's folder. A missing TRACKER (or `-`) is `--tracker`'s. A
//! sequence's `<name>` is its folder's name; two sequences of one name, or
//! one named `summary`, are an error of the manifest.
//!
//! **Shards.** `--shard I/N` takes the sequences at positions I, I + N,
//! I + 2N, … of the manifest (0 ≤ I < N), so N machines given the same
//! manifest and `I = 0 … N−1` split it exactly, with no coordinator.
//!
//! **Complete outputs are skipped.** Outputs are written through
//! [`crate::io::AtomicFile`], so `<name>.jsonl` exists only once its run
//! ended; it counts as complete when it reads as tracker output
//! ([`crate::cli::score::read_predictions`]) with exactly one line per frame
//! of the sequence, and `<name>.run.json` beside it records the tracker
//! and the config text (or none) that the manifest now gives the sequence.
//! A complete output is not tracked again; anything else (missing, a file
//! left by another sequence of that name, or an output of another tracker
//! or config) is tracked and replaced. The record is removed before a
//! sequence is tracked and written once its output is in place, so a
//! killed batch leaves no output with another run's record, and a killed
//! batch run again finishes the rest.
//!
//! **Summary.** Each line is one JSON object ([`SummaryLine`]): the
//! sequence's name, folder, tracker, `status` (`tracked`, `skipped` for a
//! complete output found, or `failed` with its `error`), frames, frames
//! tracking, frames per second (of the run that wrote the output), and,
//! when the folder has `truth.jsonl`, the corner-error figures of `score`.
//! At the end of a run, `summary.jsonl` is rewritten atomically: the lines
//! of this run's sequences replace any earlier lines of the same names, the
//! other lines are kept, in manifest order; a re-run never duplicates a
//! line. The summary is read again for this, under an exclusive lock on
//! `OUT/.summary.lock` held until it is rewritten, so shards that run at
//! once into one folder each add their lines to what the others wrote:
//! once every shard has ended, the summary has a line for every sequence.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::score::{read_predictions, score};
use crate::backend::BackendKind;
use crate::io::formats::FrameResult;
use crate::io::sequence::{CAMERA_FILE, INIT_FILE, MODEL_CAO_FILE, MODEL_JSON_FILE, MODEL_OBJ_FILE};
use crate::io::{AtomicFile, Sequence};
use crate::track::batch::{BatchJob, BatchProgress, run_batch};
use crate::track::run::{MAX_CONFIG_BYTES, RunSummary, TRACKERS, TrackOptions};
use crate::{Error, Result};

/// File name of the summary in the output folder.
pub const SUMMARY_FILE: &str = "summary.jsonl";

/// Largest manifest file read, bytes.
pub const MAX_MANIFEST_BYTES: u64 = 64 << 20;

/// One sequence of a manifest.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ManifestEntry {
    /// The sequence folder.
    pub dir: PathBuf,
    /// Its outputs' name: `<name>.jsonl`.
    pub name: String,
    /// Tracker to run.
    pub tracker: String,
    /// Tracker parameters (TOML), if any.
    pub config: Option<PathBuf>,
}

/// `--shard I/N`: the sequences at positions I, I + N, … (0 ≤ I < N).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// I.
    pub index: usize,
    /// N.
    pub count: usize,
}

impl Shard {
    /// The whole manifest.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// The items of `items` this shard takes, in order.
    #[must_use]
    pub fn select<T>(&self, items: Vec<T>) -> Vec<T> {
        items.into_iter().skip(self.index).step_by(self.count).collect()
    }
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let (i, n) = s.split_once('/').ok_or_else(|| format!("{s:?} is not I/N"))?;
        let index: usize = i.trim().parse().map_err(|_| format!("{s:?}: I must be a whole number"))?;
        let count: usize = n.trim().parse().map_err(|_| format!("{s:?}: N must be a whole number"))?;
        if count == 0 || index >= count {
            return Err(format!("{s:?}: need 0 ≤ I < N"));
        }
        Ok(Self { index, count })
    }
}

/// Files of a sequence folder: a folder holding one is a sequence, not a
/// folder of sequences.
const SEQUENCE_FILES: [&str; 5] = [CAMERA_FILE, INIT_FILE, MODEL_JSON_FILE, MODEL_CAO_FILE, MODEL_OBJ_FILE];

/// Read the manifest at `path` (module doc); `default_tracker` is
/// `--tracker`. Errors name the manifest and, for a file, the line.
pub fn read_manifest(path: &Path, default_tracker: Option<&str>, out_dir: &Path) -> Result<Vec<ManifestEntry>> {
    let check_tracker = |name: &str, place: &str| -> Result<String> {
        if TRACKERS.contains(&name) {
            Ok(name.to_string())
        } else {
            Err(Error::input(path, format!("{place}unknown tracker {name:?}; known: {}", TRACKERS.join(", "))))
        }
    };
    let default = |place: &str| -> Result<String> {
        match default_tracker {
            Some(t) => check_tracker(t, place),
            // A folder of sequences has no line to name one in.
            None if place.is_empty() => Err(Error::input(path, "no tracker: give --tracker")),
            None => Err(Error::input(path, format!("{place}no tracker: name one there or give --tracker"))),
        }
    };
    let mut entries = Vec::new();
    let mut lines = Vec::new();
    if path.is_dir() {
        if let Some(file) = SEQUENCE_FILES.iter().find(|f| path.join(f).is_file()) {
            return Err(Error::input(
                path,
                format!(
                    "is a sequence folder (it holds {file}), not a folder of sequences: \
                     give its parent folder, or a manifest listing it"
                ),
            ));
        }
        let out = fs::canonicalize(out_dir).ok();
        let mut dirs: Vec<PathBuf> = fs::read_dir(path)
            .map_err(|e| Error::input(path, format!("cannot read folder: {e}")))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_dir() && !p.file_name().is_some_and(|n| n.to_string_lossy().starts_with('.')))
            .filter(|p| out.is_none() || fs::canonicalize(p).ok() != out)
            .collect();
        dirs.sort();
        let tracker = if dirs.is_empty() { String::new() } else { default("")? };
        for dir in dirs {
            entries.push(ManifestEntry { name: name_of(&dir), dir, tracker: tracker.clone(), config: None });
            lines.push(0);
        }
    } else {
        let text = crate::io::json::read_text_at_most(path, MAX_MANIFEST_BYTES)?;
        let base = path.parent().unwrap_or(Path::new(""));
        for (i, line) in text.lines().enumerate() {
            let place = format!("line {}: ", i + 1);
            let fields: Vec<&str> = line.split_whitespace().collect();
            if fields.is_empty() || fields[0].starts_with('#') {
                continue;
            }
            // A folder name with a space reads as more than one field.
            let spaced = |e: Error| match e {
                Error::Input { path, message }
                    if line.contains(['"', '\''])
                        || fields
                            .get(1)
                            .is_some_and(|second| base.join(format!("{} {second}", fields[0])).is_dir()) =>
                {
                    Error::Input {
                        path,
                        message: format!(
                            "{message} (fields are separated by spaces or tabs, without quoting: \
                             rename a folder with a space, or list its parent folder as the manifest)"
                        ),
                    }
                }
                other => other,
            };
            if fields.len() > 3 {
                let message = format!("{place}expected SEQ_DIR [TRACKER [CONFIG]], got {} fields", fields.len());
                return Err(spaced(Error::input(path, message)));
            }
            let dir = base.join(fields[0]);
            let tracker = match fields.get(1) {
                None | Some(&"-") => default(&place)?,
                Some(t) => check_tracker(t, &place).map_err(spaced)?,
            };
            let config = fields.get(2).map(|c| base.join(c));
            entries.push(ManifestEntry { name: name_of(&dir), dir, tracker, config });
            lines.push(i + 1);
        }
    }
    if entries.is_empty() {
        return Err(Error::input(path, "lists no sequences"));
    }
    let at = |k: usize| if lines[k] > 0 { format!("line {}: ", lines[k]) } else { String::new() };
    let mut seen: HashMap<&str, usize> = HashMap::new();
    for (k, e) in entries.iter().enumerate() {
        if e.name.is_empty() || e.name == "summary" {
            return Err(Error::input(path, format!("{}{:?} cannot name a sequence's output", at(k), e.name)));
        }
        if let Some(&first) = seen.get(e.name.as_str()) {
            return Err(Error::input(
                path,
                format!(
                    "{}sequence name {:?} is also that of {}: their outputs would collide",
                    at(k),
                    e.name,
                    if lines[first] > 0 { format!("line {}", lines[first]) } else { e.dir.display().to_string() }
                ),
            ));
        }
        seen.insert(&e.name, k);
    }
    Ok(entries)
}

/// A folder's name, resolving `.` and `..` through the file system.
fn name_of(dir: &Path) -> String {
    let named = |p: &Path| p.file_name().map(|n| n.to_string_lossy().into_owned());
    match named(dir) {
        Some(n) if n != "." && n != ".." => n,
        _ => fs::canonicalize(dir).ok().and_then(|p| named(&p)).unwrap_or_default(),
    }
}

/// What happened to a sequence in a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SequenceStatus {
    /// Tracked in this run.
    Tracked,
    /// Its output was complete already.
    Skipped,
    /// It could not be tracked; `error` says why.
    Failed,
}

/// One line of `summary.jsonl`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SummaryLine {
    /// The output's name (`<name>.jsonl`).
    pub name: String,
    /// The sequence folder, as the manifest gives it.
    pub sequence: PathBuf,
    /// The tracker.
    pub tracker: String,
    /// What happened.
    pub status: SequenceStatus,
    /// Frames in the output.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<usize>,
    /// Frames reported tracking.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracked: Option<usize>,
    /// Frames per second of the run that wrote the output, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// The backend of that run, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backend: Option<String>,
    /// Mean corner error, px (with truth).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_px: Option<f64>,
    /// Median corner error, px (with truth).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub median_px: Option<f64>,
    /// 95th-percentile corner error, px (with truth).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p95_px: Option<f64>,
    /// Largest corner error, px (with truth).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_px: Option<f64>,
    /// Frames of false tracking (with truth; see [`crate::cli::score`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub false_tracking: Option<usize>,
    /// The first frame reported lost (with truth).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_lost: Option<usize>,
    /// Why the output could not be scored against its `truth.jsonl`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub score_error: Option<String>,
    /// Why the sequence failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl SummaryLine {
    fn new(entry: &ManifestEntry, status: SequenceStatus) -> Self {
        Self {
            name: entry.name.clone(),
            sequence: entry.dir.clone(),
            tracker: entry.tracker.clone(),
            status,
            frames: None,
            tracked: None,
            fps: None,
            backend: None,
            mean_px: None,
            median_px: None,
            p95_px: None,
            max_px: None,
            false_tracking: None,
            first_lost: None,
            score_error: None,
            error: None,
        }
    }

    fn failed(entry: &ManifestEntry, error: &Error) -> Self {
        Self { error: Some(crate::bounds::one_line(&error.to_string())), ..Self::new(entry, SequenceStatus::Failed) }
    }

    /// Fill frames, tracked and the score from the complete output of `seq`.
    fn describe_output(&mut self, seq: &Sequence, out_path: &Path) {
        match read_predictions(out_path) {
            Ok(predictions) => self.describe_predictions(seq, &predictions),
            Err(e) => self.score_error = Some(crate::bounds::one_line(&e.to_string())),
        }
    }

    /// Fill frames, tracked and the score from `predictions`, the output of `seq`.
    fn describe_predictions(&mut self, seq: &Sequence, predictions: &[FrameResult]) {
        self.frames = Some(predictions.len());
        self.tracked = Some(predictions.iter().filter(|p| p.status == crate::Status::Tracking).count());
        if !seq.truth_path().exists() {
            return;
        }
        match seq.read_truth().and_then(|truth| score(&truth, predictions)) {
            Ok(s) => {
                self.mean_px = s.stats.map(|s| s.mean);
                self.median_px = s.stats.map(|s| s.median);
                self.p95_px = s.stats.map(|s| s.p95);
                self.max_px = s.stats.map(|s| s.max);
                self.false_tracking = Some(s.false_tracking.len());
                self.first_lost = s.first_lost;
            }
            Err(e) => self.score_error = Some(crate::bounds::one_line(&e.to_string())),
        }
    }
}

/// Options of the `batch` command.
#[derive(Clone, Debug)]
pub struct BatchOptions {
    /// The output folder (made when missing).
    pub out_dir: PathBuf,
    /// `--tracker`: for manifest entries that name none.
    pub tracker: Option<String>,
    /// `--backend`.
    pub backend: BackendKind,
    /// `--jobs`: sequences in flight.
    pub jobs: usize,
    /// `--shard`.
    pub shard: Shard,
    /// Draw a progress bar on stderr (hidden anyway when stderr is not a terminal).
    pub progress: bool,
}

/// What a batch run did: one summary line per sequence of the shard, in manifest order.
#[derive(Debug)]
pub struct BatchReport {
    /// This run's lines.
    pub lines: Vec<SummaryLine>,
    /// The error of the first sequence in the manifest that failed, when some did.
    pub first_error: Option<Error>,
}

impl BatchReport {
    /// Sequences that failed.
    #[must_use]
    pub fn failed(&self) -> usize {
        self.lines.iter().filter(|l| l.status == SequenceStatus::Failed).count()
    }
}

/// The sequences of `manifest` that `shard` takes (for `--list`).
pub fn shard_entries(manifest: &Path, opts: &BatchOptions) -> Result<Vec<ManifestEntry>> {
    Ok(opts.shard.select(read_manifest(manifest, opts.tracker.as_deref(), &opts.out_dir)?))
}

/// Run the `batch` command (module doc). An error is returned for a bad
/// manifest or output folder, before anything is tracked, and for a failing
/// device; a sequence's own failure is its summary line.
pub fn run(manifest: &Path, opts: &BatchOptions) -> Result<BatchReport> {
    let all = read_manifest(manifest, opts.tracker.as_deref(), &opts.out_dir)?;
    if opts.out_dir.exists() && !opts.out_dir.is_dir() {
        return Err(Error::input(&opts.out_dir, "is not a folder: --out takes the output folder"));
    }
    fs::create_dir_all(&opts.out_dir).map_err(|e| Error::input(&opts.out_dir, format!("cannot create: {e}")))?;
    let summary_path = opts.out_dir.join(SUMMARY_FILE);
    let earlier = read_summary(&summary_path);
    let selected = opts.shard.select(all.clone());

    let mut lines: Vec<Option<SummaryLine>> = selected.iter().map(|_| None).collect();
    let mut failures: Vec<(usize, Error)> = Vec::new();
    let mut jobs = Vec::new();
    let mut job_entry = Vec::new();
    let mut job_record = Vec::new();
    for (k, entry) in selected.iter().enumerate() {
        let seq = match Sequence::open(&entry.dir, false) {
            Ok(seq) => seq,
            Err(e) => {
                let line = SummaryLine::failed(entry, &e);
                report_failure(entry, &line);
                lines[k] = Some(line);
                failures.push((k, e));
                continue;
            }
        };
        let out_path = opts.out_dir.join(format!("{}.jsonl", entry.name));
        let record = RunRecord::of(entry);
        if let Some(predictions) = record.as_ref().and_then(|record| complete_output(&seq, &out_path, record)) {
            let mut line = SummaryLine::new(entry, SequenceStatus::Skipped);
            if let Some(before) = earlier.iter().find(|l| l.name == entry.name && l.status != SequenceStatus::Failed) {
                line.fps = before.fps;
                line.backend.clone_from(&before.backend);
            }
            line.describe_predictions(&seq, &predictions);
            lines[k] = Some(line);
            continue;
        }
        let track = TrackOptions {
            tracker: entry.tracker.clone(),
            backend: opts.backend,
            config: entry.config.clone(),
            overlay: None,
            progress: false,
        };
        RunRecord::remove(&out_path)?;
        jobs.push(BatchJob { seq, opts: track, out_path });
        job_entry.push(k);
        job_record.push(record);
    }

    let bar = progress_bar(opts.progress, &jobs);
    let sequences_done = std::sync::atomic::AtomicUsize::new(0);
    let progress = |p: BatchProgress| match p {
        BatchProgress::Frame => bar.inc(1),
        BatchProgress::Sequence { job, written } => {
            // Without its record an output is tracked again next time: so
            // too when its config changed while the batch ran (the tracker
            // read it after the record was made).
            let entry = &selected[job_entry[job]];
            let unchanged = |record: &&RunRecord| RunRecord::of(entry).as_ref() == Some(*record);
            if let (true, Some(record)) = (written, job_record[job].as_ref().filter(unchanged))
                && let Err(e) = record.write(&jobs[job].out_path)
            {
                bar.suspend(|| note(format_args!("pipetrack: {e}")));
            }
            let done = sequences_done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            bar.set_message(format!("{done}/{} sequences", jobs.len()));
        }
    };
    let results = run_batch(&jobs, opts.backend, opts.jobs, &progress)?;
    bar.finish_and_clear();

    for ((job, &k), result) in jobs.iter().zip(&job_entry).zip(results) {
        let entry = &selected[k];
        lines[k] = Some(match result {
            Ok(RunSummary { backend, fps, .. }) => {
                let mut line = SummaryLine::new(entry, SequenceStatus::Tracked);
                line.fps = Some(fps);
                line.backend = Some(backend);
                line.describe_output(&job.seq, &job.out_path);
                line
            }
            Err(e) => {
                let line = SummaryLine::failed(entry, &e);
                report_failure(entry, &line);
                failures.push((k, e));
                line
            }
        });
    }
    let lines: Vec<SummaryLine> = lines.into_iter().flatten().collect();
    write_summary(&summary_path, &all, &lines)?;
    let first_error = failures.into_iter().min_by_key(|(k, _)| *k).map(|(_, e)| e);
    Ok(BatchReport { lines, first_error })
}

/// Say on stderr why the sequence of `entry` failed: the error of its
/// summary `line`, led by the sequence's folder unless it names that already.
fn report_failure(entry: &ManifestEntry, line: &SummaryLine) {
    let error = line.error.as_deref().unwrap_or_default();
    let shown = entry.dir.display().to_string();
    let dir = shown.trim_end_matches(std::path::MAIN_SEPARATOR);
    let names_dir = error.strip_prefix(dir).is_some_and(|rest| rest.starts_with([':', std::path::MAIN_SEPARATOR]));
    if names_dir {
        note(format_args!("pipetrack: {error}"));
    } else {
        note(format_args!("pipetrack: {dir}: {error}"));
    }
}

/// A line on stderr; a closed or full stderr is ignored (there is nowhere
/// left to report it).
fn note(line: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// What made an output (module doc): `<name>.run.json` beside it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RunRecord {
    /// The tracker.
    tracker: String,
    /// The text of the config file, if one was given.
    config: Option<String>,
}

impl RunRecord {
    /// The record `entry` would leave, or `None` when its config cannot be
    /// read (then its run fails and says why).
    fn of(entry: &ManifestEntry) -> Option<Self> {
        let config = match &entry.config {
            Some(path) => Some(crate::io::json::read_text_at_most(path, MAX_CONFIG_BYTES).ok()?),
            None => None,
        };
        Some(Self { tracker: entry.tracker.clone(), config })
    }

    /// Where the record of output `out_path` lies.
    fn path(out_path: &Path) -> PathBuf {
        out_path.with_extension("run.json")
    }

    /// The record beside `out_path`, if one reads.
    fn read(out_path: &Path) -> Option<Self> {
        serde_json::from_str(&fs::read_to_string(Self::path(out_path)).ok()?).ok()
    }

    /// Write the record beside `out_path`, atomically.
    fn write(&self, out_path: &Path) -> Result<()> {
        let path = Self::path(out_path);
        let mut file = AtomicFile::create(&path)?;
        serde_json::to_writer(&mut file, self).map_err(|e| Error::io(&path, e.into()))?;
        file.finish()
    }

    /// Remove the record beside `out_path`; none there is no error.
    fn remove(out_path: &Path) -> Result<()> {
        let path = Self::path(out_path);
        match fs::remove_file(&path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::io(&path, e)),
            _ => Ok(()),
        }
    }
}

/// The output at `out_path` when it is a complete output of `seq` made as
/// `record` says (module doc).
fn complete_output(seq: &Sequence, out_path: &Path, record: &RunRecord) -> Option<Vec<FrameResult>> {
    let frames = seq.frame_count()?;
    if !out_path.is_file() || RunRecord::read(out_path).as_ref() != Some(record) {
        return None;
    }
    read_predictions(out_path)
        .ok()
        .filter(|p| p.len() == frames && p.last().is_some_and(|last| last.frame + 1 == frames))
}

/// The lines of an existing summary; lines that do not read are dropped
/// (the file is rewritten whole at the end of the run).
fn read_summary(path: &Path) -> Vec<SummaryLine> {
    fs::read_to_string(path)
        .map(|text| text.lines().filter_map(|l| serde_json::from_str(l).ok()).collect())
        .unwrap_or_default()
}

/// File locked while a run reads and rewrites the summary.
const SUMMARY_LOCK_FILE: &str = ".summary.lock";

/// Merge `ours` into the summary at `path` as it is now (ours replace lines
/// of the same name) and write it atomically, in the order of the manifest
/// `all`, lines of names it does not list last; all under an exclusive lock
/// on [`SUMMARY_LOCK_FILE`] beside it, so that runs into the same folder
/// (shards) do not drop each other's lines.
fn write_summary(path: &Path, all: &[ManifestEntry], ours: &[SummaryLine]) -> Result<()> {
    let lock_path = path.with_file_name(SUMMARY_LOCK_FILE);
    let lock = fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .map_err(|e| Error::input(&lock_path, format!("cannot create: {e}")))?;
    match lock.lock() {
        Ok(()) => {}
        // A file system without locks (some parallel and FUSE ones): merged
        // unlocked, as good as runs that do not end at the same moment.
        Err(e) if e.kind() == std::io::ErrorKind::Unsupported => {
            note(format_args!(
                "pipetrack: {}: cannot lock ({e}); the summary is merged without it",
                lock_path.display()
            ));
        }
        Err(e) => return Err(Error::io(&lock_path, e)),
    }
    let earlier = read_summary(path);
    let mut merged: Vec<SummaryLine> = earlier.into_iter().filter(|l| !ours.iter().any(|o| o.name == l.name)).collect();
    merged.extend(ours.iter().cloned());
    let position: HashMap<&str, usize> = all.iter().enumerate().map(|(i, e)| (e.name.as_str(), i)).collect();
    merged.sort_by_key(|l| position.get(l.name.as_str()).copied().unwrap_or(usize::MAX));
    merged.dedup_by(|a, b| a.name == b.name);
    let mut text = String::new();
    for line in &merged {
        text.push_str(&serde_json::to_string(line).map_err(|e| Error::io(path, e.into()))?);
        text.push('\n');
    }
    AtomicFile::write_all_to(path, text.as_bytes())
}

fn progress_bar(enabled: bool, jobs: &[BatchJob]) -> indicatif::ProgressBar {
    if !enabled {
        return indicatif::ProgressBar::hidden();
    }
    let frames: usize = jobs.iter().filter_map(|j| j.seq.frame_count()).sum();
    let bar = indicatif::ProgressBar::with_draw_target(Some(frames as u64), indicatif::ProgressDrawTarget::stderr());
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{spinner} {msg} {pos}/{len} frames {per_sec} [{elapsed_precise}] {wide_bar}",
    ) {
        bar.set_style(style);
    }
    bar.set_message(format!("0/{} sequences", jobs.len()));
    bar
}

/// This run's lines as a markdown table.
#[must_use]
pub fn markdown(lines: &[SummaryLine]) -> String {
    let num = |v: Option<usize>| v.map_or("-".to_string(), |v| v.to_string());
    let px = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    let mut out = String::from(
        "| sequence | tracker | status | frames | tracking | fps | mean px | p95 px | note |\n\
         |---|---|---|---:|---:|---:|---:|---:|---|\n",
    );
    for l in lines {
        let status = match l.status {
            SequenceStatus::Tracked => "tracked",
            SequenceStatus::Skipped => "skipped",
            SequenceStatus::Failed => "failed",
        };
        let note = l.error.as_deref().or(l.score_error.as_deref()).unwrap_or("").replace('|', "\\|");
        out.push_str(&format!(
            "| {} | {} | {status} | {} | {} | {} | {} | {} | {note} |\n",
            l.name.replace('|', "\\|"),
            l.tracker,
            num(l.frames),
            num(l.tracked),
            l.fps.map_or("-".to_string(), |f| format!("{f:.1}")),
            px(l.mean_px),
            px(l.p95_px),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_a_manifest() {
        for len in [0usize, 1, 5, 17] {
            for count in 1..=6 {
                let mut seen = vec![0; len];
                for index in 0..count {
                    let shard = Shard { index, count };
                    let taken = shard.select((0..len).collect());
                    assert!(taken.iter().all(|&i| i % count == index), "{shard:?} took {taken:?}");
                    for i in taken {
                        seen[i] += 1;
                    }
                }
                assert!(seen.iter().all(|&n| n == 1), "len {len}, {count} shards: {seen:?}");
            }
        }
    }

    #[test]
    fn shard_parses_i_over_n() {
        assert_eq!("2/5".parse::<Shard>(), Ok(Shard { index: 2, count: 5 }));
        assert_eq!("0/1".parse::<Shard>(), Ok(Shard::ALL));
        for bad in ["5/5", "1/0", "a/2", "1", "-1/3", "1/2/3"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
