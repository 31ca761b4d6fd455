//! Running a tracker over a sequence: frames → backend → tracker → JSON
//! Lines, with optional overlays and a progress bar. The `track` and `demo`
//! commands and the end-to-end tests all go through [`track_sequence`], which
//! walks [`track_frames`]; an embedder drives the same loop with its own
//! frames, as bytes or as wgpu textures ([`Frame`]), or calls
//! [`track_step`] once per frame from its own render loop.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::backend::{BackendKind, EarlyVision, FrameFeatures, FrameRequest, make_backend};
use crate::geometry::{ModelGeometry, check_polygon_in_image, check_simple_polygon};
use crate::image::{GrayImage, RgbImage};
use crate::io::formats::{FrameResult, Status};
use crate::io::json::input_error;
use crate::io::sequence::CAMERA_FILE;
use crate::io::{OutputFile, Sequence, StagedDir};
use crate::track::{
    BlueParams, BlueTracker, CondensationParams, CondensationTracker, FrameOutcome, LoweParams, LoweTracker,
    MotionEdgeParams, MotionEdgeTracker, Observations, Tracked, Tracker,
};
use crate::{Error, Result};

/// The `--tracker` names pipetrack knows.
pub const TRACKERS: &[&str] = &["motion-edge", "blue", "condensation", "lowe"];

/// Largest config file read, bytes: a tracker has a few dozen parameters.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

/// Read tracker parameters of type `P` from a TOML file: the table named after
/// the tracker (`[motion-edge]`) when there is one, else the file's top-level
/// keys; other trackers' tables are left to them, and a key beside the
/// tracker's own table is an error.
/// Errors name the file, in one short line, with long numbers and long
/// quoted text shortened (`io::json::one_short_line`).
pub fn read_config<P: serde::de::DeserializeOwned + Default>(path: Option<&Path>, tracker: &str) -> Result<P> {
    use toml::de::{DeTable, DeValue, Deserializer};
    let Some(path) = path else { return Ok(P::default()) };
    let text = crate::io::json::read_text_at_most(path, MAX_CONFIG_BYTES)?;
    // Parsed with the span of every key and value, so that an unknown key
    // is named with its line.
    let document = DeTable::parse(&text).map_err(|e| toml_error(path, &text, &e))?;
    let span = document.span();
    let mut table = document.into_inner();
    let own = table.remove(tracker);
    // Other trackers' tables are theirs: one file may serve several trackers.
    let theirs: Vec<String> = table
        .iter()
        .filter(|(key, value)| TRACKERS.contains(&key.as_ref().as_ref()) && matches!(value.as_ref(), DeValue::Table(_)))
        .map(|(key, _)| key.as_ref().to_string())
        .collect();
    for key in &theirs {
        table.remove(key.as_str());
    }
    let section = match own.map(|value| (value.span(), value.into_inner())) {
        // Beside the tracker's table, a key would be silently ignored.
        Some((own_span, DeValue::Table(t))) => match table.keys().next() {
            Some(key) => {
                let key = key.as_ref();
                let message = format!(
                    "{key:?} lies outside [{tracker}], which holds this tracker's parameters: move it into the table"
                );
                return Err(input_error(path, message));
            }
            None => toml::Spanned::new(own_span, t),
        },
        Some(_) => return Err(Error::input(path, format!("[{tracker}] must be a table"))),
        None => toml::Spanned::new(span, table),
    };
    let tables = table_keys(section.as_ref());
    P::deserialize(Deserializer::from(section)).map_err(|e| {
        let at = e.span().and_then(|span| text_position(&text, span.start)).map(|(line, _)| line);
        unknown_key_error(path, tracker, e.message(), at, &tables).unwrap_or_else(|| {
            let message = crate::io::json::plain_type_names(&crate::bounds::one_line(&e.to_string()));
            input_error(
                path,
                match at {
                    Some(line) => format!("line {line}: {message}"),
                    None => message,
                },
            )
        })
    })
}

/// The keys of `table` and of the tables in it whose values are tables.
fn table_keys(table: &toml::de::DeTable<'_>) -> Vec<String> {
    let mut keys = Vec::new();
    for (key, value) in table {
        if let toml::de::DeValue::Table(inner) = value.as_ref() {
            keys.push(key.as_ref().to_string());
            keys.extend(table_keys(inner));
        }
    }
    keys
}

/// serde's `unknown field `K`, expected one of `A`, `B`, …` as one line
/// naming its line (`at`) and the known key closest to K (a table named
/// like a tracker, `[motion_edge]`, as that tracker's: `tables` are the
/// keys that open tables), or else the command that lists the keys.
fn unknown_key_error(path: &Path, tracker: &str, message: &str, at: Option<usize>, tables: &[String]) -> Option<Error> {
    let rest = message.strip_prefix("unknown field `")?;
    let (key, expected) = rest.rsplit_once("`, expected").unwrap_or((rest.strip_suffix('`')?, ""));
    let known = quoted_names(expected);
    let at = at.map_or_else(String::new, |line| format!("line {line}: "));
    let closest = |names: &[&str]| {
        names
            .iter()
            .map(|name| (strsim::damerau_levenshtein(key, name), *name))
            .filter(|&(distance, name)| distance <= 2.max(name.len() / 4))
            .min()
            .map(|(_, name)| name.to_string())
    };
    let message = match closest(TRACKERS).filter(|_| tables.iter().any(|t| t == key)) {
        Some(name) => format!("{at}[{key}] is no tracker's table: did you mean [{name}]?"),
        None => match closest(&known) {
            Some(name) => format!("{at}unknown key {key:?} for {tracker}: did you mean {name}?"),
            // The keys are too many for one short line: the command lists them.
            None => format!("{at}unknown key {key:?} for {tracker} (`pipetrack config {tracker}` lists every key)"),
        },
    };
    Some(input_error(path, message))
}

/// The line and column (from 1) of byte `offset` of `text`.
fn text_position(text: &str, offset: usize) -> Option<(usize, usize)> {
    let before = text.get(..offset)?;
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    Some((line, column))
}

/// A TOML error as one line naming `path`: `line L, column C: message` when
/// the error points into `text`, with what it quotes of the file shortened
/// ([`crate::io::json::one_short_line`]).
fn toml_error(path: &Path, text: &str, e: &toml::de::Error) -> Error {
    let message = match e.span().and_then(|span| text_position(text, span.start)) {
        Some((line, column)) => format!("line {line}, column {column}: {}", crate::bounds::one_line(e.message())),
        None => crate::bounds::one_line(&e.to_string()),
    };
    input_error(path, message)
}

/// A parameter error blamed on the config file when there is one.
fn config_error(config: Option<&Path>, e: Error) -> Error {
    match config {
        Some(path) => Error::input(path, e.message()),
        None => e,
    }
}

/// Make the tracker `name` for `seq`, with parameters from `config`.
pub fn make_tracker(name: &str, seq: &Sequence, config: Option<&Path>) -> Result<Box<dyn Tracker + Send>> {
    match name {
        "motion-edge" => {
            let params: MotionEdgeParams = read_config(config, name)?;
            params.validate().map_err(|e| config_error(config, e))?;
            if seq.init.corners.is_empty() {
                return Err(seq.init_error("motion-edge needs \"corners\" (the operator's points)"));
            }
            // Where the corners are first: corners far outside the image
            // (1e300) make every turn of the polygon look flat.
            let (w, h) = (seq.camera.width, seq.camera.height);
            check_polygon_in_image(&seq.init.corners, &seq.model.edges, w, h).map_err(|msg| seq.init_error(msg))?;
            check_simple_polygon(&seq.init.corners, &seq.model.edges).map_err(|msg| seq.init_error(msg))?;
            let tracker = MotionEdgeTracker::new(seq.init.corners.clone(), seq.model.edges.clone(), params)
                .map_err(|e| Error::input(seq.model_path(), e.message()))?;
            Ok(Box::new(tracker))
        }
        "blue" => {
            let params: BlueParams = read_config(config, name)?;
            params.validate().map_err(|e| config_error(config, e))?;
            BlueTracker::check_model(&seq.model).map_err(|e| Error::input(seq.model_path(), e.message()))?;
            let tracker = BlueTracker::new(seq.camera, seq.model.clone(), seq.init.clone(), params)
                .map_err(|e| seq.init_error(e.message()))?;
            Ok(Box::new(tracker))
        }
        "condensation" => {
            let params: CondensationParams = read_config(config, name)?;
            params.validate().map_err(|e| config_error(config, e))?;
            if seq.model.vertices.len() != 4 {
                return Err(Error::input(
                    seq.model_path(),
                    format!(
                        "condensation tracks a window of 4 vertices (top-left, top-right, bottom-right, bottom-left); the model has {}",
                        seq.model.vertices.len()
                    ),
                ));
            }
            let tracker = CondensationTracker::new(seq.camera, &seq.model, &seq.init, params)
                .map_err(|e| seq.init_error(e.message()))?;
            Ok(Box::new(tracker))
        }
        "lowe" => {
            let params: LoweParams = read_config(config, name)?;
            params.validate().map_err(|e| config_error(config, e))?;
            // What the model alone decides is the model file's error.
            LoweTracker::check_model(&seq.model).map_err(|e| Error::input(seq.model_path(), e.message()))?;
            let tracker =
                LoweTracker::new(seq.camera, &seq.model, &seq.init, params).map_err(|e| seq.init_error(e.message()))?;
            Ok(Box::new(tracker))
        }
        other => Err(unknown_tracker(other)),
    }
}

/// The names serde quotes in `expected` (`` `a`, `b` or `c` ``).
fn quoted_names(expected: &str) -> Vec<&str> {
    expected.split('`').skip(1).step_by(2).collect()
}

/// Every key of parameters `P`, as serde names them when refusing another.
fn parameter_keys<P: serde::de::DeserializeOwned>() -> Vec<String> {
    let refusal = toml::from_str::<P>("not_a_parameter = 0").err().map(|e| e.message().to_string());
    let expected = refusal.as_deref().and_then(|m| m.split_once("expected")).map_or("", |(_, rest)| rest);
    quoted_names(expected).into_iter().map(str::to_string).collect()
}

/// The error for a tracker name pipetrack does not know.
fn unknown_tracker(name: &str) -> Error {
    Error::Parameter(format!("unknown tracker {name:?}; known: {}", TRACKERS.join(", ")))
}

/// The default parameters of tracker `name` as a `--config` file: its
/// table (`[lowe]`, with `[lowe.segments]`) holding every key with its
/// default value. Read back, it gives the defaults.
pub fn default_config(name: &str) -> Result<String> {
    /// An f32 parameter (`log_sigma = 1.2`) is written as its f32 reads,
    /// not as the f64 it widens to (`1.2000000476837158`).
    fn shortest_floats(value: &mut toml::Value) {
        match value {
            toml::Value::Float(v) => {
                let narrow = *v as f32;
                if f64::from(narrow) == *v {
                    *v = format!("{narrow}").parse().unwrap_or(*v);
                }
            }
            toml::Value::Table(t) => t.iter_mut().for_each(|(_, v)| shortest_floats(v)),
            toml::Value::Array(a) => a.iter_mut().for_each(shortest_floats),
            _ => {}
        }
    }
    fn table<P: serde::Serialize + serde::de::DeserializeOwned + Default>(name: &str) -> Result<String> {
        let mut document = toml::Table::new();
        let mut params = toml::Value::try_from(P::default())
            .map_err(|e| Error::Parameter(format!("{name}'s defaults as TOML: {e}")))?;
        shortest_floats(&mut params);
        // Keys unset by default (an option) have no value to write: named.
        let unset: Vec<String> =
            parameter_keys::<P>().into_iter().filter(|k| params.get(k.as_str()).is_none()).collect();
        document.insert(name.to_string(), params);
        let text =
            toml::to_string(&document).map_err(|e| Error::Parameter(format!("{name}'s defaults as TOML: {e}")))?;
        Ok(match unset.as_slice() {
            [] => text,
            keys => text.replacen(
                &format!("[{name}]\n"),
                &format!("[{name}]\n# Unset by default: {}\n", keys.join(", ")),
                1,
            ),
        })
    }
    let body = match name {
        "motion-edge" => table::<MotionEdgeParams>(name)?,
        "blue" => table::<BlueParams>(name)?,
        "condensation" => table::<CondensationParams>(name)?,
        "lowe" => table::<LoweParams>(name)?,
        other => return Err(unknown_tracker(other)),
    };
    Ok(format!("# The default parameters of {name}: edit and give with `track --config FILE`.\n{body}"))
}

/// Options of one tracking run.
#[derive(Clone, Debug)]
pub struct TrackOptions {
    /// `--tracker`.
    pub tracker: String,
    /// `--backend`.
    pub backend: BackendKind,
    /// `--config`.
    pub config: Option<PathBuf>,
    /// `--overlay DIR`.
    pub overlay: Option<PathBuf>,
    /// Show a progress bar on stderr (hidden anyway when stderr is not a terminal).
    pub progress: bool,
}

/// What a run did, for the summary line.
#[derive(Clone, Debug)]
pub struct RunSummary {
    /// The backend that ran (after any fallback).
    pub backend: String,
    /// Frames processed.
    pub frames: usize,
    /// Frames with status tracking.
    pub tracked: usize,
    /// Frames per second over the whole run.
    pub fps: f64,
    /// Why the GPU was not used, when it was asked for and missing.
    pub fallback: Option<String>,
}

/// Track `seq` and write one JSON line per frame to `out`; with
/// `opts.overlay`, write one PNG per frame into that folder (a
/// [`StagedDir`]: an interrupted run never leaves a folder that looks
/// complete). The overlay folder is checked before the tracker starts, and
/// published only after `out` is flushed without error. Errors writing
/// `out` are [`Error::Io`] naming `output`.
pub fn track_sequence(
    seq: &Sequence,
    opts: &TrackOptions,
    out: &mut dyn Write,
    on_result: impl FnMut(&FrameResult),
) -> Result<RunSummary> {
    track_named(seq, opts, out, Path::new("output"), on_result)
}

/// [`track_sequence`] with errors writing `out` naming `out_name`.
fn track_named(
    seq: &Sequence,
    opts: &TrackOptions,
    out: &mut dyn Write,
    out_name: &Path,
    mut on_result: impl FnMut(&FrameResult),
) -> Result<RunSummary> {
    let overlay = opts.overlay.as_deref().map(StagedDir::create).transpose()?;
    let mut tracker = make_tracker(&opts.tracker, seq, opts.config.as_deref())?;
    let (mut backend, fallback) = make_backend(opts.backend);
    if let Some(reason) = &fallback {
        let _ = writeln!(std::io::stderr(), "pipetrack: no GPU ({reason})");
    }
    let (w, h) = (seq.camera.width as usize, seq.camera.height as usize);
    // The frame size comes from camera.json: a size the backend cannot take
    // is that file's problem, refused before any output.
    backend.check_frame_size(w, h).map_err(|e| {
        let why = match e {
            Error::Parameter(msg) => msg,
            other => other.to_string(),
        };
        let message = format!("frames of {w}x{h} are too large for the backend ({}): {why}", backend.name());
        Error::input(seq.dir().join(CAMERA_FILE), format!("{message}; try --backend cpu"))
    })?;
    // Overlays of a tracker with a pose draw only the edges visible at that pose.
    let model_geometry = overlay.as_ref().and_then(|_| ModelGeometry::new(&seq.model).ok());
    // Declared after the folder, so dropped (its thread joined) before it.
    let mut overlay_writer = overlay.as_ref().map(|_| OverlayWriter::start());
    let frames = seq.frames();
    let bar = progress_bar(opts.progress, frames.len_hint());
    let start = Instant::now();
    let (mut count, mut tracked) = (0, 0);
    let mut sink = |frame: Frame<'_>, outcome: &FrameOutcome, result: &FrameResult| -> Result<()> {
        write_result_line(out, out_name, result)?;
        if let Some(dir) = &overlay {
            let luma_of_colour;
            let gray = match frame {
                Frame::Rgb(c) => {
                    luma_of_colour = c.to_gray();
                    Some(&luma_of_colour)
                }
                Frame::Gray(g) => Some(g),
                Frame::Texture(_) => None,
            };
            if let Some(frame) = gray {
                let labelled: Vec<(u32, u32)> = outcome.labelled.iter().flatten().copied().collect();
                let visible = match (&model_geometry, &outcome.pose) {
                    (Some(g), Some(pose)) => {
                        g.visible_edges_at(&(*pose).into(), outcome.params.as_deref().unwrap_or(&[])).ok()
                    }
                    _ => None,
                };
                let edges: std::borrow::Cow<'_, [[usize; 2]]> = match visible {
                    Some(v) => seq.model.edges.iter().zip(v).filter(|(_, on)| *on).map(|(e, _)| *e).collect(),
                    None => (&seq.model.edges[..]).into(),
                };
                let bands = &outcome.diagnostics.bands;
                let edges = if bands.is_empty() { edges } else { (&[][..]).into() };
                let mut img =
                    crate::io::overlay::draw_overlay(frame, &outcome.corners, &edges, outcome.status, &labelled);
                crate::io::overlay::draw_bands(&mut img, bands, crate::io::overlay::status_colour(outcome.status));
                let path = dir.path().join(format!("{:06}.png", outcome.frame));
                if let Some(writer) = &mut overlay_writer {
                    writer.write(img, path)?;
                }
            }
        }
        tracked += usize::from(result.status == Status::Tracking);
        count += 1;
        on_result(result);
        bar.inc(1);
        Ok(())
    };
    if tracker.wants_colour() {
        read_ahead(frames.colour(), |frames| {
            track_frames(tracker.as_mut(), backend.as_mut(), frames, (w, h), &mut sink)
        })?;
    } else {
        read_ahead(frames, |frames| track_frames(tracker.as_mut(), backend.as_mut(), frames, (w, h), &mut sink))?;
    }
    bar.finish_and_clear();
    // The output first: a run whose lines could not all be written publishes no overlays.
    out.flush().map_err(|e| Error::io(out_name, e))?;
    if let Some(writer) = overlay_writer {
        writer.finish()?;
    }
    if let Some(dir) = overlay {
        dir.finish()?;
    }
    Ok(RunSummary {
        backend: backend.name(),
        frames: count,
        tracked,
        fps: count as f64 / start.elapsed().as_secs_f64().max(1e-9),
        fallback,
    })
}

/// One frame handed to the per-frame loop: grey bytes, or a wgpu texture on
/// the GPU backend's device (read as [`crate::early::ingest`] describes).
#[derive(Clone, Copy, Debug)]
pub enum Frame<'a> {
    /// An 8-bit grey frame in memory (any backend).
    Gray(&'a GrayImage),
    /// An 8-bit colour frame in memory (any backend): the grey stages see
    /// its luma, sample windows its colour.
    Rgb(&'a RgbImage),
    /// A texture on the device of a [`crate::backend::GpuBackend`]; a CPU
    /// backend answers [`Error::TextureOnCpu`].
    Texture(&'a wgpu::Texture),
}

impl Frame<'_> {
    /// Width and height in pixels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        match self {
            Frame::Gray(g) => g.size(),
            Frame::Rgb(c) => c.size(),
            Frame::Texture(t) => (t.width() as usize, t.height() as usize),
        }
    }

    /// The grey image, for a grey byte frame.
    #[must_use]
    pub fn gray(&self) -> Option<&GrayImage> {
        match self {
            Frame::Gray(g) => Some(g),
            Frame::Rgb(_) | Frame::Texture(_) => None,
        }
    }
}

/// Anything [`track_frames`] takes as a frame: a [`GrayImage`] or an
/// [`RgbImage`] (owned or borrowed), a `&wgpu::Texture`, or a [`Frame`].
pub trait AsFrame {
    /// This frame as a [`Frame`].
    fn as_frame(&self) -> Frame<'_>;
}

impl AsFrame for GrayImage {
    fn as_frame(&self) -> Frame<'_> {
        Frame::Gray(self)
    }
}

impl AsFrame for &GrayImage {
    fn as_frame(&self) -> Frame<'_> {
        Frame::Gray(self)
    }
}

impl AsFrame for RgbImage {
    fn as_frame(&self) -> Frame<'_> {
        Frame::Rgb(self)
    }
}

impl AsFrame for &RgbImage {
    fn as_frame(&self) -> Frame<'_> {
        Frame::Rgb(self)
    }
}

impl AsFrame for &wgpu::Texture {
    fn as_frame(&self) -> Frame<'_> {
        Frame::Texture(self)
    }
}

impl AsFrame for Frame<'_> {
    fn as_frame(&self) -> Frame<'_> {
        *self
    }
}

/// One turn of the per-frame loop: ask the tracker what it needs for a frame
/// of this size, run the backend on `frame`, let the tracker update with the
/// features as frame `index` ([`Tracker::track_or_widen`]: a tracker that
/// widens its window of interest gets the frame's features once more, from
/// its new request). Returns the tracker's outcome and its output line,
/// timed from the first request to the outcome.
///
/// The backend differences each frame against the one before (motion), so
/// successive calls must be successive frames of one sequence; call
/// [`EarlyVision::reset`] before the first. A frame with no pixel, or of a
/// size the tracker does not take ([`Tracker::accept_frame_size`]: its
/// camera's, or its first frame's), is [`Error::Size`] and changes nothing.
pub fn track_step(
    tracker: &mut dyn Tracker,
    backend: &mut dyn EarlyVision,
    index: usize,
    frame: Frame<'_>,
) -> Result<(FrameOutcome, FrameResult)> {
    let t0 = Instant::now();
    let (w, h) = frame.size();
    if w == 0 || h == 0 {
        return Err(Error::Size(format!("frame {index} is {w}x{h}: a frame needs at least one pixel")));
    }
    tracker.accept_frame_size(w, h).map_err(|why| Error::Size(format!("frame {index} is {why}")))?;
    until_tracked(tracker, frame.size(), |tracker, request, may_widen| {
        let features = match frame {
            Frame::Gray(g) => backend.process(g, &request)?,
            Frame::Rgb(c) => backend.process_rgb(c, &request)?,
            Frame::Texture(t) => backend.process_texture(t, &request)?,
        };
        let step = track_features(tracker, index, &features, t0, may_widen);
        backend.recycle(features);
        Ok(step)
    })
}

/// The looks at one frame of size `(w, h)` until `tracker` answers: `look`
/// gets the tracker, its request for the frame and whether it may still
/// widen its window (the first look only, [`Tracker::track_or_widen`]),
/// and returns `None` when the tracker widened it. A second look cannot
/// widen, so there are at most two.
pub fn until_tracked<T>(
    tracker: &mut dyn Tracker,
    (w, h): (usize, usize),
    mut look: impl FnMut(&mut dyn Tracker, FrameRequest, bool) -> Result<Option<T>>,
) -> Result<T> {
    let mut may_widen = true;
    loop {
        let request = tracker.request(w, h);
        if let Some(answer) = look(tracker, request, may_widen)? {
            return Ok(answer);
        }
        may_widen = false;
    }
}

/// The second half of [`track_step`], for a caller that ran early vision
/// itself (several sequences' frames in one GPU submission): let the tracker
/// update with `features` as frame `index`; the output line's time runs from
/// `requested` (when the tracker's first request for the frame was taken)
/// to the outcome. With `may_widen` the tracker may widen its window of
/// interest instead ([`Tracker::track_or_widen`]): then `None`, and the
/// caller runs early vision on the same frame with the tracker's new
/// request and calls this again without `may_widen`.
pub fn track_features(
    tracker: &mut dyn Tracker,
    index: usize,
    features: &FrameFeatures,
    requested: Instant,
    may_widen: bool,
) -> Option<(FrameOutcome, FrameResult)> {
    let Tracked::Outcome(outcome) = track_once(tracker, index, &Observations::from(features), may_widen) else {
        return None;
    };
    let mut result = outcome.to_result(requested.elapsed().as_secs_f64() * 1e3);
    let extras = tracker.extras();
    result.velocity_screw = extras.velocity_screw.filter(|s| s.iter().all(|v| v.is_finite()));
    result.effective_sample_size = extras.effective_sample_size.filter(|v| v.is_finite());
    result.search_branches = extras.search_branches;
    Some((outcome, result))
}

/// One look of `tracker` at frame `index`: [`Tracker::track_or_widen`]
/// with `may_widen`, else [`Tracker::track`] (the frame's second look,
/// after its window was widened).
pub fn track_once(
    tracker: &mut dyn Tracker,
    index: usize,
    observations: &Observations<'_>,
    may_widen: bool,
) -> Tracked {
    if may_widen {
        tracker.track_or_widen(index, observations)
    } else {
        Tracked::Outcome(tracker.track(index, observations))
    }
}

/// Write `result` as one JSON line to `out`; errors are [`Error::Io`] naming `out_name`.
pub fn write_result_line(out: &mut dyn Write, out_name: &Path, result: &FrameResult) -> Result<()> {
    serde_json::to_writer(&mut *out, result).map_err(|e| Error::io(out_name, e.into()))?;
    writeln!(out).map_err(|e| Error::io(out_name, e))
}

/// The per-frame loop shared by every caller: reset the backend, then for
/// each frame [`track_step`] and hand the frame, its outcome and its output
/// line to `sink`. Frames are grey images or textures (see [`AsFrame`]) and
/// must all be `size` (a different size is [`Error::Size`]); errors stop the run.
pub fn track_frames<I, F>(
    tracker: &mut dyn Tracker,
    backend: &mut dyn EarlyVision,
    frames: I,
    size: (usize, usize),
    mut sink: impl FnMut(Frame<'_>, &FrameOutcome, &FrameResult) -> Result<()>,
) -> Result<()>
where
    I: IntoIterator<Item = Result<F>>,
    F: AsFrame,
{
    backend.reset();
    for (i, frame) in frames.into_iter().enumerate() {
        let frame = frame?;
        let frame = frame.as_frame();
        if frame.size() != size {
            let (w, h) = frame.size();
            return Err(Error::Size(format!("frame {i} is {w}x{h}, the sequence is {}x{}", size.0, size.1)));
        }
        let (outcome, result) = track_step(tracker, backend, i, frame)?;
        sink(frame, &outcome, &result)?;
    }
    Ok(())
}

/// Frames decoded ahead of the one being tracked, at most.
const READ_AHEAD_FRAMES: usize = 2;

/// Run `body` on `frames` read on a thread of their own, up to
/// [`READ_AHEAD_FRAMES`] ahead: decoding the next frame (a PNG takes about
/// as long as tracking it) overlaps tracking this one. Frames arrive in
/// order, an error in its place. When `body` has read to the end, a panic
/// of the reader is raised here; when it stops before, it does not wait
/// for the reader (which may be blocked on a stream's next frame): the
/// reader ends at the next frame it reads.
fn read_ahead<T: Send + 'static, R>(
    frames: impl Iterator<Item = Result<T>> + Send + 'static,
    body: impl FnOnce(&mut ReadAhead<T>) -> R,
) -> R {
    let (sender, receiver) = std::sync::mpsc::sync_channel(READ_AHEAD_FRAMES);
    let reader = std::thread::spawn(move || {
        for frame in frames {
            if sender.send(frame).is_err() {
                break;
            }
        }
    });
    let mut ahead = ReadAhead { receiver, ended: false };
    let result = body(&mut ahead);
    if ahead.ended {
        // The reader has left its loop (or unwound out of it).
        if let Err(panic) = reader.join() {
            std::panic::resume_unwind(panic);
        }
    }
    result
}

/// The frames [`read_ahead`] hands its body.
struct ReadAhead<T> {
    receiver: std::sync::mpsc::Receiver<Result<T>>,
    /// Whether the reader has closed the channel.
    ended: bool,
}

impl<T> Iterator for ReadAhead<T> {
    type Item = Result<T>;

    fn next(&mut self) -> Option<Result<T>> {
        let frame = self.receiver.recv().ok();
        self.ended |= frame.is_none();
        frame
    }
}

/// Overlay images waiting to be written, at most.
const OVERLAYS_QUEUED: usize = 2;

/// Overlay PNGs encoded and written on a thread of their own (encoding a
/// 640×480 overlay takes longer than tracking its frame), in the order
/// given. The first error stops the thread; the next [`write`](Self::write)
/// or [`finish`](Self::finish) returns it. Dropped, it waits for the thread.
struct OverlayWriter {
    sender: Option<std::sync::mpsc::SyncSender<(image::RgbImage, PathBuf)>>,
    thread: Option<std::thread::JoinHandle<Result<()>>>,
}

impl OverlayWriter {
    fn start() -> Self {
        let (sender, receiver) = std::sync::mpsc::sync_channel::<(image::RgbImage, PathBuf)>(OVERLAYS_QUEUED);
        let thread = std::thread::spawn(move || {
            for (img, path) in receiver {
                img.save(&path).map_err(|e| Error::input(&path, format!("cannot write overlay: {e}")))?;
            }
            Ok(())
        });
        Self { sender: Some(sender), thread: Some(thread) }
    }

    /// Queue `img` to be written as `path`; waits while the queue is full.
    fn write(&mut self, img: image::RgbImage, path: PathBuf) -> Result<()> {
        let sent = self.sender.as_ref().is_some_and(|s| s.send((img, path)).is_ok());
        if sent { Ok(()) } else { self.wait() }
    }

    /// Write what is queued; the first error of the thread, if any.
    fn finish(mut self) -> Result<()> {
        self.wait()
    }

    /// Close the queue and wait for the thread: its result, its panic raised here.
    fn wait(&mut self) -> Result<()> {
        match self.close() {
            Some(Ok(result)) => result,
            Some(Err(panic)) => std::panic::resume_unwind(panic),
            None => Ok(()),
        }
    }

    /// Close the queue and join the thread, if not done before.
    fn close(&mut self) -> Option<std::thread::Result<Result<()>>> {
        self.sender = None;
        self.thread.take().map(std::thread::JoinHandle::join)
    }
}

impl Drop for OverlayWriter {
    fn drop(&mut self) {
        let _ = self.close();
    }
}

fn progress_bar(enabled: bool, len: Option<usize>) -> indicatif::ProgressBar {
    if !enabled {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::with_draw_target(len.map(|n| n as u64), indicatif::ProgressDrawTarget::stderr());
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{spinner} {pos}/{len} frames {per_sec} [{elapsed_precise}] {wide_bar}")
    {
        bar.set_style(style);
    }
    bar
}

/// Track `seq` writing JSON Lines to `out_path` (an [`OutputFile`]): a
/// regular file appears only when the run completed; an existing
/// `out_path` that is not a regular file or a folder (a device such as
/// `/dev/null`, a named pipe) is written in place, as it cannot be replaced.
///
/// Before tracking, `out_path` is checked (see [`check_output`]) and so is
/// the overlay folder. Errors writing name `out_path`.
pub fn track_to_file(seq: &Sequence, opts: &TrackOptions, out_path: &Path) -> Result<RunSummary> {
    track_to_file_with(seq, opts, out_path, |_| {})
}

/// [`track_to_file`], handing each frame's output line to `on_result` once written.
pub fn track_to_file_with(
    seq: &Sequence,
    opts: &TrackOptions,
    out_path: &Path,
    mut on_result: impl FnMut(&FrameResult),
) -> Result<RunSummary> {
    check_output(seq, opts, out_path)?;
    let mut file = OutputFile::create(out_path)?;
    let summary = track_named(seq, opts, &mut file, out_path, &mut on_result)?;
    file.finish()?;
    Ok(summary)
}

/// Track `seq` writing JSON Lines to standard output; errors writing name
/// `stdout`. A closed pipe is an [`Error::Io`] of kind
/// [`std::io::ErrorKind::BrokenPipe`], which the command line takes as the
/// reader having had enough. Each frame's line is written when the frame
/// is tracked (standard output is line-buffered), so a reader of a live
/// stream (`--frames -`) sees every frame's result as it comes.
pub fn track_to_stdout(seq: &Sequence, opts: &TrackOptions) -> Result<RunSummary> {
    let name = Path::new("stdout");
    track_named(seq, opts, &mut std::io::stdout().lock(), name, |_| {})
}

/// Check `--out` before a run: it must not be a folder, one of the
/// sequence's input files ([`Sequence::input_files`]), the config file, or
/// the overlay folder. Input errors name `out_path`.
pub fn check_output(seq: &Sequence, opts: &TrackOptions, out_path: &Path) -> Result<()> {
    if out_path.is_dir() {
        return Err(Error::input(out_path, "is a folder: --out takes a file name"));
    }
    if opts.overlay.as_deref().is_some_and(|o| o == out_path) {
        return Err(Error::input(out_path, "is also the overlay folder: give --out and --overlay different names"));
    }
    if let Some(input) = Sequence::same_file_among(out_path, &seq.input_files()) {
        let message = if input == out_path {
            "is one of the sequence's input files: write the output elsewhere".to_string()
        } else {
            format!("is the sequence's input file {}: write the output elsewhere", input.display())
        };
        return Err(Error::input(out_path, message));
    }
    // A file among the frames would be read as one the next time.
    let frames = std::fs::canonicalize(seq.dir().join(crate::io::sequence::FRAMES_DIR));
    let parent = out_path.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
    if frames.is_ok_and(|frames| parent.and_then(|p| std::fs::canonicalize(p).ok()) == Some(frames)) {
        return Err(Error::input(out_path, "lies in the sequence's frames folder: write the output elsewhere"));
    }
    if let Some(config) = &opts.config
        && Sequence::same_file_among(out_path, std::slice::from_ref(config)).is_some()
    {
        return Err(Error::input(out_path, "is the --config file: write the output elsewhere"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

    use super::*;

    /// `pipetrack config T`'s file reads back as T's defaults, every key
    /// known (a key it wrote that no reader took would be an error).
    #[test]
    fn each_default_config_reads_back_as_the_defaults() {
        fn reads_back<P: serde::de::DeserializeOwned + Default + PartialEq + std::fmt::Debug>(name: &str) {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("defaults.toml");
            let text = default_config(name).unwrap();
            assert!(text.contains(&format!("[{name}]")), "{text}");
            // Every key is written, or named as unset.
            let keys = parameter_keys::<P>();
            assert!(keys.len() > 5, "{keys:?}");
            for key in keys {
                let written =
                    text.lines().any(|l| l.starts_with(&format!("{key} = ")) || l == format!("[{name}.{key}]"));
                let unset = text.lines().any(|l| l.starts_with("# Unset by default:") && l.contains(&key));
                assert!(written || unset, "{key} missing from {text}");
            }
            std::fs::write(&path, &text).unwrap();
            assert_eq!(read_config::<P>(Some(&path), name).unwrap(), P::default(), "{text}");
        }
        reads_back::<MotionEdgeParams>("motion-edge");
        reads_back::<BlueParams>("blue");
        reads_back::<CondensationParams>("condensation");
        reads_back::<LoweParams>("lowe");
        assert!(default_config("lowee").is_err());
        // An f32 parameter as it reads, not widened.
        assert!(default_config("lowe").unwrap().contains("log_sigma = 1.2\n"));
        // An option unset by default is named.
        assert!(
            default_config("blue").unwrap().contains("# Unset by default: nominal_range\n"),
            "{}",
            default_config("blue").unwrap()
        );
    }

    /// Counts the frames pulled from it and flags when it is dropped (the
    /// reader thread has ended).
    struct Counted {
        next: i32,
        pulled: Arc<AtomicUsize>,
        dropped: Arc<AtomicBool>,
    }

    impl Iterator for Counted {
        type Item = Result<i32>;
        fn next(&mut self) -> Option<Result<i32>> {
            self.pulled.fetch_add(1, Ordering::SeqCst);
            self.next += 1;
            (self.next <= 100).then(|| numbered(self.next - 1))
        }
    }

    impl Drop for Counted {
        fn drop(&mut self) {
            self.dropped.store(true, Ordering::SeqCst);
        }
    }

    fn numbered(i: i32) -> Result<i32> {
        if i == 7 { Err(Error::Parameter(format!("frame {i}"))) } else { Ok(i) }
    }

    fn wait_for(flag: &AtomicBool) -> bool {
        let started = std::time::Instant::now();
        while !flag.load(Ordering::SeqCst) && started.elapsed().as_secs() < 10 {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        flag.load(Ordering::SeqCst)
    }

    #[test]
    fn read_ahead_keeps_order_and_errors_and_stops_when_dropped() {
        let (pulled, dropped) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicBool::new(false)));
        let frames = Counted { next: 0, pulled: pulled.clone(), dropped: dropped.clone() };
        let seen: Vec<std::result::Result<i32, String>> =
            read_ahead(frames, |frames| frames.take(10).map(|f| f.map_err(|e| e.to_string())).collect());
        let expected: Vec<_> = (0..10).map(|i| numbered(i).map_err(|e| e.to_string())).collect();
        assert_eq!(seen, expected);
        assert!(wait_for(&dropped), "the reader ends once the frames are dropped");
        // It stops at most one frame past what the channel holds.
        let pulled = pulled.load(Ordering::SeqCst);
        assert!(pulled <= 10 + READ_AHEAD_FRAMES + 1, "{pulled} frames read for 10 taken");

        let frames = Counted { next: 0, pulled: Arc::default(), dropped: Arc::default() };
        assert_eq!(read_ahead(frames, |frames| frames.count()), 100);
    }

    #[test]
    fn read_ahead_raises_the_readers_panic_and_does_not_wait_for_a_blocked_reader() {
        let panicking = (0..10).map(|i| if i == 3 { panic!("decoder bug") } else { Ok(i) });
        let caught = std::panic::catch_unwind(|| read_ahead(panicking, |frames| frames.count()));
        assert!(caught.is_err(), "a panic of the reader is not a shorter sequence");

        // A stream whose fourth frame never comes: the body stops after two.
        let (hold, stalled) = std::sync::mpsc::channel::<()>();
        let blocking = (0..10).map(move |i| {
            if i == 3 {
                let _ = stalled.recv();
            }
            Ok(i)
        });
        assert_eq!(read_ahead(blocking, |frames| frames.take(2).count()), 2);
        drop(hold);
    }

    #[test]
    fn overlay_writer_writes_in_order_and_reports_the_first_failure() {
        let dir = tempfile::tempdir().unwrap();
        let mut writer = OverlayWriter::start();
        for i in 0..4u8 {
            writer
                .write(image::RgbImage::from_pixel(3, 2, image::Rgb([i, 0, 0])), dir.path().join(format!("{i}.png")))
                .unwrap();
        }
        writer.finish().unwrap();
        for i in 0..4u8 {
            let img = image::open(dir.path().join(format!("{i}.png"))).unwrap().to_rgb8();
            assert_eq!((img.dimensions(), img.get_pixel(2, 1).0), ((3, 2), [i, 0, 0]));
        }

        let missing = dir.path().join("absent").join("0.png");
        let mut writer = OverlayWriter::start();
        let mut first_error = None;
        for i in 0..2 * OVERLAYS_QUEUED + 2 {
            let path = if i == 0 { missing.clone() } else { dir.path().join(format!("later{i}.png")) };
            if let Err(e) = writer.write(image::RgbImage::new(3, 2), path) {
                first_error = Some(e);
                break;
            }
        }
        let error = match first_error {
            Some(e) => e,
            None => writer.finish().expect_err("writing into a missing folder fails"),
        };
        assert!(error.to_string().contains(&missing.display().to_string()), "{error}");
        assert!(error.to_string().contains("cannot write overlay"), "{error}");
        let names = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap());
        assert!(!names.into_iter().any(|n| n.starts_with("later")), "nothing is written after the failure");
    }
}
