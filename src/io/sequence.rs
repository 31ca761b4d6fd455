//! Sequence folders (SPEC §4): reading and validating `camera.json`, the
//! model (`model.json`, else `model.cao`, else `model.obj`) and `init.json`,
//! handing out the frames as a stream, and reading the optional `truth.jsonl` on request
//! (only scoring reads it, so tracking never depends on it).
//!
//! Every problem with a user's file is an [`Error::Input`] whose one-line
//! message names the file (and the line, for JSON Lines) and says what is
//! wrong, ready for the command line to print.

use std::fs::{self};
use std::io::{self};
use std::path::{Path, PathBuf};

use super::formats::{Camera, InitState, Model, TruthFrame, model_json_line};
use super::frames::*;
use super::json::*;
use super::y4m::STDIN_NAME;
use super::{cao, obj};
use crate::{Error, Result};

/// `camera.json`.
pub const CAMERA_FILE: &str = "camera.json";
/// `model.json` (wins over `model.cao` and `model.obj`).
pub const MODEL_JSON_FILE: &str = "model.json";
/// `model.cao`, ViSP's format, read when there is no `model.json`.
pub const MODEL_CAO_FILE: &str = "model.cao";
/// `model.obj`, Wavefront's format, read when there is neither `model.json`
/// nor `model.cao`.
pub const MODEL_OBJ_FILE: &str = "model.obj";
/// `init.json`.
pub const INIT_FILE: &str = "init.json";
/// `truth.jsonl` (optional).
pub const TRUTH_FILE: &str = "truth.jsonl";
/// The folder of frame images.
pub const FRAMES_DIR: &str = "frames";
/// Frame file extensions (compared case-insensitively).
pub const FRAME_EXTENSIONS: [&str; 4] = ["png", "pgm", "jpg", "jpeg"];

/// A validated sequence folder. Frames are not loaded: [`Sequence::frames`]
/// streams them.
///
/// `open` guarantees: the camera has a positive size, finite positive focal
/// lengths and a finite principal point; the model passes
/// [`Model::validate`]; `init` has a pose or one corner per model vertex,
/// and one param per joint or none; the frames folder is non-empty, numbered
/// without gaps (see [`list_frames`]) and its first frame has the camera's
/// size. `open` does not read `truth.jsonl`: [`Sequence::read_truth`] does.
#[derive(Clone, Debug)]
pub struct Sequence {
    /// Intrinsics and image size.
    pub camera: Camera,
    /// The object.
    pub model: Model,
    /// The state at frame 0.
    pub init: InitState,
    dir: PathBuf,
    model_path: PathBuf,
    frames: FrameList,
    /// Keys of camera.json, model.json and init.json that no reader reads.
    ignored_keys: Vec<String>,
    /// The keys of init.json that no reader reads.
    init_keys: Vec<String>,
}

/// Where [`Sequence::read`] takes the frames from.
#[derive(Clone, Copy, Debug)]
enum FramesFrom {
    /// `frames/`.
    Folder,
    /// A Y4M stream on stdin.
    Stdin,
    /// Nowhere: the caller has its own.
    Caller,
    /// `frames/` when there is one, counted; else none, their number unknown.
    Counted,
}

#[derive(Clone, Debug)]
enum FrameList {
    Files(Vec<PathBuf>),
    Stdin,
    /// No frames here, and how many the sequence has is not known.
    Uncounted,
}

impl Sequence {
    /// Read and validate the sequence folder `dir`. With `frames_from_stdin`
    /// the frames come as a Y4M stream on stdin (`--frames -`) and any
    /// `frames/` folder is ignored; otherwise `frames/` must hold at least
    /// one PNG, PGM or JPEG file. Files in the folder other than those of
    /// SPEC §4 are ignored.
    pub fn open(dir: &Path, frames_from_stdin: bool) -> Result<Self> {
        Self::read(dir, if frames_from_stdin { FramesFrom::Stdin } else { FramesFrom::Folder })
    }

    /// Read and validate the camera, model and start of the sequence folder
    /// `dir` as [`Sequence::open`] does, without frames: for a program that
    /// brings its own (a live camera) and makes its tracker from the
    /// folder's files ([`crate::track::run::make_tracker`]), then runs it
    /// with [`crate::track_step`]. A `frames/` folder is ignored; the
    /// sequence has no frames ([`Sequence::frames`] yields none).
    pub fn open_without_frames(dir: &Path) -> Result<Self> {
        Self::read(dir, FramesFrom::Caller)
    }

    /// Read and validate the sequence folder `dir` as [`Sequence::open`]
    /// does, for a program that reads no frames (`score`): `frames/` when
    /// there is one, which then bounds the frames `truth.jsonl` may name;
    /// without it the sequence has no frames and their number is not known.
    pub fn open_for_scoring(dir: &Path) -> Result<Self> {
        Self::read(dir, FramesFrom::Counted)
    }

    fn read(dir: &Path, frames_from: FramesFrom) -> Result<Self> {
        check_folder(dir)?;
        let camera_path = dir.join(CAMERA_FILE);
        let (camera, camera_keys, written) = read_json_with_original::<Camera>(&camera_path)?;
        refuse_distortion(&camera_path, &camera_keys, &written)?;
        let mut ignored_keys: Vec<String> = ignored_line(&camera_path, &camera_keys).into_iter().collect();
        // A size no frame may have is named as such before the intrinsics
        // are judged against it.
        check_frame_size(&camera_path, camera.width as usize, camera.height as usize)?;
        noting_ignored(camera.validate(&camera_path), &camera_path, &camera_keys)?;

        let (model, model_path, ignored) = read_model(dir)?;
        ignored_keys.extend(ignored);

        let init_path = dir.join(INIT_FILE);
        let (init, init_keys) = read_json_noting_ignored::<InitState>(&init_path)?;
        ignored_keys.extend(ignored_line(&init_path, &init_keys));
        noting_ignored(init.validate(&init_path, &model, &model_path), &init_path, &init_keys)?;

        let frames = match frames_from {
            FramesFrom::Stdin => FrameList::Stdin,
            FramesFrom::Caller => FrameList::Files(Vec::new()),
            FramesFrom::Counted if !dir.join(FRAMES_DIR).exists() => FrameList::Uncounted,
            FramesFrom::Folder | FramesFrom::Counted => {
                let paths = list_frames(&dir.join(FRAMES_DIR))?;
                check_frame_header(&paths[0], &camera, &camera_path)?;
                FrameList::Files(paths)
            }
        };

        Ok(Self { camera, model, init, dir: dir.to_path_buf(), model_path, frames, ignored_keys, init_keys })
    }

    /// An error about init.json (`message`), naming the file's keys that no
    /// reader reads: a tracker that finds no `"pose"` there may have been
    /// given `"poes"`.
    pub(crate) fn init_error(&self, message: impl Into<String>) -> Error {
        let path = self.dir.join(INIT_FILE);
        noting_unread(Error::input(&path, message), &path, &self.init_keys)
    }

    /// One line per input file with keys that no reader reads (misspelt,
    /// or meant for another tool), naming the file and the keys; empty when
    /// every key is read.
    #[must_use]
    pub fn ignored_keys(&self) -> &[String] {
        &self.ignored_keys
    }

    /// This sequence's first `count` frames (all when fewer) in reverse
    /// order, starting from `init`; `None` when the frames come from stdin.
    #[must_use]
    pub(crate) fn reversed(&self, count: usize, init: InitState) -> Option<Sequence> {
        let FrameList::Files(paths) = &self.frames else { return None };
        let frames = FrameList::Files(paths.iter().take(count).rev().cloned().collect());
        Some(Self { init, frames, init_keys: Vec::new(), ..self.clone() })
    }

    /// The sequence folder.
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The model file that was read (`model.json`, `model.cao` or `model.obj`).
    #[must_use]
    pub fn model_path(&self) -> &Path {
        &self.model_path
    }

    /// Where `truth.jsonl` is (whether or not it exists).
    #[must_use]
    pub fn truth_path(&self) -> PathBuf {
        self.dir.join(TRUTH_FILE)
    }

    /// Read and validate `truth.jsonl` (for `score`): every line passes
    /// [`TruthFrame::validate`] against the model, frame numbers count up
    /// from 0 without a gap and (for a frames folder) name existing frames.
    /// A missing file is an input error naming it.
    pub fn read_truth(&self) -> Result<Vec<TruthFrame>> {
        let path = self.truth_path();
        if !path.exists() {
            return Err(Error::input(path, "missing: scoring needs ground truth"));
        }
        read_truth(&path, &self.model, &self.model_path, self.frame_count())
    }

    /// The first of `inputs` that the existing file `path` is, compared
    /// resolved (so `./seq/../seq/init.json` and links are caught); `None`
    /// when none is, or `path` does not exist. Only an input of the same
    /// file name, or a link, is resolved.
    #[must_use]
    pub fn same_file_among<'a>(path: &Path, inputs: &'a [PathBuf]) -> Option<&'a PathBuf> {
        let target = fs::canonicalize(path).ok()?;
        inputs.iter().find(|p| {
            (p.file_name() == target.file_name() || p.is_symlink()) && fs::canonicalize(p).is_ok_and(|p| p == target)
        })
    }

    /// The files of SPEC §4 this folder holds: `camera.json`, the model
    /// files, `init.json`, `truth.jsonl` and the frames. An output must not
    /// be written over any of them.
    #[must_use]
    pub fn input_files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> =
            [CAMERA_FILE, MODEL_JSON_FILE, MODEL_CAO_FILE, MODEL_OBJ_FILE, INIT_FILE, TRUTH_FILE]
                .iter()
                .map(|name| self.dir.join(name))
                .filter(|p| p.exists())
                .collect();
        files.extend(self.frame_paths().unwrap_or(&[]).iter().cloned());
        files
    }

    /// The frame files in order, or `None` when frames come from stdin (or,
    /// opened for scoring, there are none and their number is not known).
    #[must_use]
    pub fn frame_paths(&self) -> Option<&[PathBuf]> {
        match &self.frames {
            FrameList::Files(paths) => Some(paths),
            FrameList::Stdin | FrameList::Uncounted => None,
        }
    }

    /// Number of frames, when known (not for stdin, nor for a sequence
    /// opened for scoring without `frames/`).
    #[must_use]
    pub fn frame_count(&self) -> Option<usize> {
        self.frame_paths().map(<[PathBuf]>::len)
    }

    /// Whether frames come from a Y4M stream on stdin.
    #[must_use]
    pub fn reads_stdin(&self) -> bool {
        matches!(self.frames, FrameList::Stdin)
    }

    /// Stream the frames, decoding one per call; each must have the
    /// camera's size. Call once per run: for stdin the stream is consumed.
    #[must_use]
    pub fn frames(&self) -> FrameSource {
        let camera_path = self.dir.join(CAMERA_FILE);
        match &self.frames {
            FrameList::Files(paths) => FrameSource::files(paths.clone(), self.camera, camera_path),
            FrameList::Stdin => FrameSource::y4m(io::stdin(), Path::new(STDIN_NAME), self.camera, camera_path),
            FrameList::Uncounted => FrameSource::files(Vec::new(), self.camera, camera_path),
        }
    }
}

fn check_folder(dir: &Path) -> Result<()> {
    let mut entries = match fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Err(Error::input(dir, "no such folder")),
        Err(_) if dir.is_file() => return Err(Error::input(dir, "not a folder: give a sequence folder")),
        Err(e) => return Err(Error::input(dir, format!("cannot read folder: {e}"))),
    };
    if entries.next().is_none() {
        return Err(Error::input(
            dir,
            "empty folder: a sequence needs camera.json, model.json (or model.cao or model.obj), init.json and frames/",
        ));
    }
    Ok(())
}

/// The keys of `path` that were not read ([`read_json_noting_ignored`]) as
/// one line naming it; none when every key was read.
fn ignored_line(path: &Path, keys: &[String]) -> Option<String> {
    (!keys.is_empty()).then(|| format!("{}: ignored, not read by pipetrack: {}", path.display(), shown_keys(keys)))
}

/// Up to five of `keys`, quoted and shortened as messages quote user text
/// ([`one_short_line`]), and how many more.
fn shown_keys(keys: &[String]) -> String {
    let shown: Vec<String> = keys.iter().take(5).map(|k| one_short_line(&format!("{k:?}"))).collect();
    let more = if keys.len() > 5 { format!(" and {} more", keys.len() - 5) } else { String::new() };
    format!("{}{more}", shown.join(", "))
}

/// `result`, its error about `file` naming the keys of `file` that were
/// not read: a misspelt key (`"joint"` for `"joints"`) is often what the
/// error is about.
fn noting_ignored<T>(result: Result<T>, file: &Path, keys: &[String]) -> Result<T> {
    result.map_err(|e| noting_unread(e, file, keys))
}

/// `error`, when it is about `file`, naming the keys of `file` that were
/// not read ([`noting_ignored`]).
fn noting_unread(error: Error, file: &Path, keys: &[String]) -> Error {
    match error {
        Error::Input { path, message } if path == file && !keys.is_empty() => {
            Error::Input { path, message: format!("{message} (keys not read: {}; misspelt?)", shown_keys(keys)) }
        }
        other => other,
    }
}

/// Lens distortion coefficients a calibration may write beside the
/// intrinsics.
const DISTORTION_KEYS: &[&str] = &["k1", "k2", "k3", "k4", "k5", "k6", "p1", "p2", "kud", "kdu", "distortion"];

/// Error when `camera.json` at `path`, written as `camera`, whose unread
/// keys are `unread`, gives lens distortion: pipetrack's camera is a
/// pinhole, so the frames must be undistorted. A coefficient of 0 (or a
/// list of zeros) is no distortion, only noted as unread.
fn refuse_distortion(path: &Path, unread: &[String], camera: &serde_json::Value) -> Result<()> {
    let nonzero = |v: &serde_json::Value| match v {
        serde_json::Value::Array(values) => values.iter().any(|x| x.as_f64() != Some(0.0)),
        other => other.as_f64() != Some(0.0),
    };
    match unread.iter().find(|k| DISTORTION_KEYS.contains(&k.as_str()) && nonzero(&camera[k.as_str()])) {
        Some(key) => Err(input_error(
            path,
            format!(
                "{key:?} gives lens distortion, which pipetrack does not model: undistort the frames first \
                 (and give the undistorted camera's intrinsics)"
            ),
        )),
        None => Ok(()),
    }
}

/// The model of the folder: `model.json`, else `model.cao`, else
/// `model.obj` (SPEC §4), validated; a problem with one of its parts names
/// the file and line the part was written on. With the model, its file and
/// (for `model.json`) the line of [`ignored_line`].
fn read_model(dir: &Path) -> Result<(Model, PathBuf, Vec<String>)> {
    let json_path = dir.join(MODEL_JSON_FILE);
    let cao_path = dir.join(MODEL_CAO_FILE);
    let obj_path = dir.join(MODEL_OBJ_FILE);
    // A model file beside the one read is named, lest an edit to it be
    // thought to count.
    let unread = |read: &Path, others: &[&PathBuf]| -> Vec<String> {
        let name = read.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        others
            .iter()
            .filter(|p| p.exists())
            .map(|p| {
                format!("{}: not read: the model is {name} (model.json before model.cao before model.obj)", p.display())
            })
            .collect()
    };
    if !json_path.exists() && cao_path.exists() {
        return Ok((cao::read_cao(&cao_path)?, cao_path.clone(), unread(&cao_path, &[&obj_path])));
    }
    if !json_path.exists() && obj_path.exists() {
        return Ok((obj::read_obj(&obj_path)?, obj_path, Vec::new()));
    }
    let (model, keys) = read_json_noting_ignored::<Model>(&json_path).map_err(|e| match e {
        Error::Input { path, message } if message == MISSING => {
            Error::input(path, "missing (and there is no model.cao or model.obj either)")
        }
        other => other,
    })?;
    let checked = model.validate_at(&json_path, |part| {
        let text = read_text(&json_path).ok()?;
        model_json_line(&text, part).map(|line| (json_path.clone(), line))
    });
    noting_ignored(checked, &json_path, &keys)?;
    let mut ignored: Vec<String> = ignored_line(&json_path, &keys).into_iter().collect();
    ignored.extend(unread(&json_path, &[&cao_path, &obj_path]));
    Ok((model, json_path, ignored))
}

fn read_truth(path: &Path, model: &Model, model_path: &Path, frame_count: Option<usize>) -> Result<Vec<TruthFrame>> {
    // The frame each line must hold, the lines before it having held 0, 1, …;
    // the first line after a gap, reported once the file passes the other
    // checks (a frame out of order, one beyond the sequence, a bad line).
    let mut next = 0;
    let mut gap = None;
    let truth = read_frame_lines(
        path,
        |t: &TruthFrame| t.frame,
        |t, line| {
            t.validate(path, line, model, model_path)?;
            if gap.is_none() && t.frame > next {
                let found = match next {
                    0 => format!("the first frame is {}", t.frame),
                    _ => format!("frame {} after frame {}", t.frame, next - 1),
                };
                let missing = match t.frame - next {
                    1 => format!("frame {next} is missing"),
                    _ => format!("frames {next} to {} are missing", t.frame - 1),
                };
                gap = Some(format!("line {line}: {found}: {missing} (one line per frame, from frame 0)"));
            }
            next = t.frame.saturating_add(1);
            match frame_count.filter(|&n| t.frame >= n) {
                Some(n) => {
                    Err(Error::input(path, format!("line {line}: frame {} but the sequence has {n} frames", t.frame)))
                }
                None => Ok(()),
            }
        },
    )?;
    match gap {
        Some(message) => Err(Error::input(path, message)),
        None => Ok(truth),
    }
}
