//! Sequence folders (SPEC §4): reading and validating `camera.json`, the
//! model (`model.json`, else `model.cao`), `init.json`, the optional
//! `truth.jsonl` and the list of frames; streaming the frames one at a time
//! (from `frames/` or a Y4M stream on stdin); and [`AtomicFile`], which keeps
//! a half-written output from ever looking complete.
//!
//! Every problem with a user's file is an [`Error::Input`] whose one-line
//! message names the file (and the line, for JSON Lines) and says what is
//! wrong, ready for the command line to print.

use std::cmp::Ordering;
use std::fs::{self, File};
use std::io::{self, BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;

use crate::cao;
use crate::formats::{Camera, InitState, Model, TruthFrame};
use crate::image::{GrayImage, luma};
use crate::y4m::{STDIN_NAME, Y4mReader};
use crate::{Error, Result};

/// `camera.json`.
pub const CAMERA_FILE: &str = "camera.json";
/// `model.json` (wins over `model.cao`).
pub const MODEL_JSON_FILE: &str = "model.json";
/// `model.cao`, ViSP's format, read when there is no `model.json`.
pub const MODEL_CAO_FILE: &str = "model.cao";
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
/// lengths and a finite principal point; the model's indices are in range
/// (see [`Model::validate`]); `init` has a pose or one corner per model
/// vertex, and one param per joint or none; every truth line passes the same
/// checks and truth frame numbers strictly increase and (for a frames folder)
/// name existing frames; the frames folder is non-empty and its first frame
/// has the camera's size.
#[derive(Clone, Debug)]
pub struct Sequence {
    /// Intrinsics and image size.
    pub camera: Camera,
    /// The object.
    pub model: Model,
    /// The state at frame 0.
    pub init: InitState,
    /// Ground truth, one entry per line of `truth.jsonl`, when the file exists.
    pub truth: Option<Vec<TruthFrame>>,
    dir: PathBuf,
    model_path: PathBuf,
    frames: FrameList,
}

#[derive(Clone, Debug)]
enum FrameList {
    Files(Vec<PathBuf>),
    Stdin,
}

impl Sequence {
    /// Read and validate the sequence folder `dir`. With `frames_from_stdin`
    /// the frames come as a Y4M stream on stdin (`--frames -`) and any
    /// `frames/` folder is ignored; otherwise `frames/` must hold at least
    /// one PNG, PGM or JPEG file. Files in the folder other than those of
    /// SPEC §4 are ignored.
    pub fn open(dir: &Path, frames_from_stdin: bool) -> Result<Self> {
        check_folder(dir)?;
        let camera_path = dir.join(CAMERA_FILE);
        let camera: Camera = read_json(&camera_path)?;
        camera.validate(&camera_path)?;

        let (model, model_path) = read_model(dir)?;

        let init_path = dir.join(INIT_FILE);
        let init: InitState = read_json(&init_path)?;
        init.validate(&init_path, &model, &model_path)?;

        let frames = if frames_from_stdin {
            FrameList::Stdin
        } else {
            let paths = list_frames(&dir.join(FRAMES_DIR))?;
            check_frame_header(&paths[0], &camera, &camera_path)?;
            FrameList::Files(paths)
        };

        let truth_path = dir.join(TRUTH_FILE);
        let truth = if truth_path.exists() {
            let frame_count = match &frames {
                FrameList::Files(paths) => Some(paths.len()),
                FrameList::Stdin => None,
            };
            Some(read_truth(&truth_path, &model, &model_path, frame_count)?)
        } else {
            None
        };

        Ok(Self { camera, model, init, truth, dir: dir.to_path_buf(), model_path, frames })
    }

    /// The sequence folder.
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The model file that was read (`model.json` or `model.cao`).
    #[must_use]
    pub fn model_path(&self) -> &Path {
        &self.model_path
    }

    /// Where `truth.jsonl` is (whether or not it exists).
    #[must_use]
    pub fn truth_path(&self) -> PathBuf {
        self.dir.join(TRUTH_FILE)
    }

    /// The ground truth, or an input error naming `truth.jsonl` when the
    /// folder has none (for `score`).
    pub fn require_truth(&self) -> Result<&[TruthFrame]> {
        self.truth.as_deref().ok_or_else(|| Error::input(self.truth_path(), "missing: scoring needs ground truth"))
    }

    /// The frame files in order, or `None` when frames come from stdin.
    #[must_use]
    pub fn frame_paths(&self) -> Option<&[PathBuf]> {
        match &self.frames {
            FrameList::Files(paths) => Some(paths),
            FrameList::Stdin => None,
        }
    }

    /// Number of frames, when known (not for stdin).
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
            "empty folder: a sequence needs camera.json, model.json (or model.cao), init.json and frames/",
        ));
    }
    Ok(())
}

fn read_model(dir: &Path) -> Result<(Model, PathBuf)> {
    let json_path = dir.join(MODEL_JSON_FILE);
    let cao_path = dir.join(MODEL_CAO_FILE);
    if json_path.exists() || !cao_path.exists() {
        let model: Model = read_json(&json_path).map_err(|e| match e {
            Error::Input { path, message } if message == MISSING => {
                Error::input(path, "missing (and there is no model.cao either)")
            }
            other => other,
        })?;
        model.validate(&json_path)?;
        Ok((model, json_path))
    } else {
        Ok((cao::read_cao(&cao_path)?, cao_path))
    }
}

fn read_truth(path: &Path, model: &Model, model_path: &Path, frame_count: Option<usize>) -> Result<Vec<TruthFrame>> {
    let lines: Vec<(usize, TruthFrame)> = read_jsonl(path)?;
    let mut previous: Option<usize> = None;
    for (line, t) in &lines {
        t.validate(path, *line, model, model_path)?;
        if let Some(p) = previous.filter(|&p| t.frame <= p) {
            return Err(Error::input(
                path,
                format!("line {line}: frame {} after frame {p}: frames must be in increasing order", t.frame),
            ));
        }
        if let Some(n) = frame_count.filter(|&n| t.frame >= n) {
            return Err(Error::input(path, format!("line {line}: frame {} but the sequence has {n} frames", t.frame)));
        }
        previous = Some(t.frame);
    }
    Ok(lines.into_iter().map(|(_, t)| t).collect())
}

/// The frame images in `frames_dir`, in natural name order (digit runs
/// compare as numbers, so `2.png` < `10.png`; zero-padded names sort as
/// usual). Files without a frame extension, hidden files and folders are
/// ignored; an empty or missing folder is an error naming it.
pub fn list_frames(frames_dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = match fs::read_dir(frames_dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            return Err(Error::input(frames_dir, "missing: put the frames there or pass --frames - for a Y4M stream"));
        }
        Err(e) => return Err(Error::input(frames_dir, format!("cannot read folder: {e}"))),
    };
    let mut named = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::input(frames_dir, format!("cannot read folder: {e}")))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let path = entry.path();
        let is_frame = !name.starts_with('.')
            && path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| FRAME_EXTENSIONS.iter().any(|f| f.eq_ignore_ascii_case(e)))
            && fs::metadata(&path).is_ok_and(|m| m.is_file());
        if is_frame {
            named.push((name, path));
        }
    }
    if named.is_empty() {
        return Err(Error::input(frames_dir, "no frames: expected PNG, PGM or JPEG files"));
    }
    named.sort_by(|a, b| natural_cmp(&a.0, &b.0));
    Ok(named.into_iter().map(|(_, p)| p).collect())
}

/// Compare names with digit runs taken as numbers (`frame2` < `frame10`);
/// ties (e.g. `01` vs `1`) fall back to plain string order.
fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut x, mut y) = (a.as_bytes(), b.as_bytes());
    loop {
        match (x.first(), y.first()) {
            (None, None) => return a.cmp(b),
            (None, Some(_)) => return Ordering::Less,
            (Some(_), None) => return Ordering::Greater,
            (Some(c), Some(d)) if c.is_ascii_digit() && d.is_ascii_digit() => {
                let run = |s: &[u8]| s.iter().take_while(|c| c.is_ascii_digit()).count();
                let (nx, ny) = (run(x), run(y));
                let strip = |s: &[u8]| {
                    let zeros = s.iter().take_while(|&&c| c == b'0').count();
                    s[zeros..].to_vec()
                };
                let (vx, vy) = (strip(&x[..nx]), strip(&y[..ny]));
                let ord = vx.len().cmp(&vy.len()).then_with(|| vx.cmp(&vy));
                if ord != Ordering::Equal {
                    return ord;
                }
                x = &x[nx..];
                y = &y[ny..];
            }
            (Some(c), Some(d)) => {
                if c != d {
                    return c.cmp(d);
                }
                x = &x[1..];
                y = &y[1..];
            }
        }
    }
}

fn size_mismatch(frame: &Path, w: usize, h: usize, camera: &Camera, camera_path: &Path) -> Error {
    let camera_name =
        camera_path.file_name().map_or_else(|| camera_path.display().to_string(), |n| n.to_string_lossy().into_owned());
    Error::input(
        frame,
        format!(
            "frame is {w}x{h} but {camera_name} (and so every frame) is {}x{}: frames of changing size",
            camera.width, camera.height
        ),
    )
}

/// Read only the header of the first frame to fail early on a wrong size.
fn check_frame_header(path: &Path, camera: &Camera, camera_path: &Path) -> Result<()> {
    let (w, h) = ::image::ImageReader::open(path)
        .map_err(|e| open_error(path, &e))?
        .with_guessed_format()
        .map_err(|e| open_error(path, &e))?
        .into_dimensions()
        .map_err(|e| Error::input(path, format!("corrupt image: {e}")))?;
    if (w, h) != (camera.width, camera.height) {
        return Err(size_mismatch(path, w as usize, h as usize, camera, camera_path));
    }
    Ok(())
}

fn open_error(path: &Path, e: &io::Error) -> Error {
    if e.kind() == io::ErrorKind::NotFound {
        Error::input(path, MISSING)
    } else {
        Error::input(path, format!("cannot read: {e}"))
    }
}

/// Decode an image file to an 8-bit grey frame: grey as is (16-bit scaled
/// to 8), colour through BT.601 luma ([`luma`], the weights the GPU ingest
/// uses) rounded to the nearest integer, alpha ignored.
pub fn decode_gray(path: &Path) -> Result<GrayImage> {
    let img = ::image::ImageReader::open(path)
        .map_err(|e| open_error(path, &e))?
        .with_guessed_format()
        .map_err(|e| open_error(path, &e))?
        .decode()
        .map_err(|e| Error::input(path, format!("corrupt image: {e}")))?;
    dynamic_to_gray(img)
}

/// Convert any decoded image to grey as [`decode_gray`] describes.
pub fn dynamic_to_gray(img: ::image::DynamicImage) -> Result<GrayImage> {
    use ::image::DynamicImage as D;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let rgb_luma = |p: &[u8]| luma(p[0], p[1], p[2]).round() as u8;
    let data = match img {
        D::ImageLuma8(buf) => buf.into_raw(),
        D::ImageLumaA8(buf) => buf.as_raw().chunks_exact(2).map(|p| p[0]).collect(),
        D::ImageRgb8(buf) => buf.as_raw().chunks_exact(3).map(rgb_luma).collect(),
        D::ImageRgba8(buf) => buf.as_raw().chunks_exact(4).map(rgb_luma).collect(),
        img @ (D::ImageLuma16(_) | D::ImageLumaA16(_)) => img.to_luma8().into_raw(),
        other => other.to_rgb8().as_raw().chunks_exact(3).map(rgb_luma).collect(),
    };
    GrayImage::from_vec(w, h, data)
}

/// Frames of a sequence, one decoded at a time, each checked against the
/// camera size. An iterator of `Result<GrayImage>`; after the first error it
/// ends. Errors name the frame file (or `-` for stdin).
pub struct FrameSource {
    kind: SourceKind,
    camera: Camera,
    camera_path: PathBuf,
    delivered: usize,
    failed: bool,
}

enum SourceKind {
    Files(Vec<PathBuf>),
    Y4m { pending: Option<(Box<dyn Read + Send>, PathBuf)>, reader: Option<Y4mReader<Box<dyn Read + Send>>> },
}

impl FrameSource {
    /// Frames from image files, in the given order.
    #[must_use]
    pub fn files(paths: Vec<PathBuf>, camera: Camera, camera_path: PathBuf) -> Self {
        Self { kind: SourceKind::Files(paths), camera, camera_path, delivered: 0, failed: false }
    }

    /// Frames from a YUV4MPEG2 stream named `name` in errors (`-` for
    /// stdin). The header is read with the first frame.
    #[must_use]
    pub fn y4m(input: impl Read + Send + 'static, name: &Path, camera: Camera, camera_path: PathBuf) -> Self {
        let kind = SourceKind::Y4m { pending: Some((Box::new(input), name.to_path_buf())), reader: None };
        Self { kind, camera, camera_path, delivered: 0, failed: false }
    }

    /// Frames delivered so far (the index of the next frame).
    #[must_use]
    pub fn delivered(&self) -> usize {
        self.delivered
    }

    /// Number of frames, when known (image files, not streams).
    #[must_use]
    pub fn len_hint(&self) -> Option<usize> {
        match &self.kind {
            SourceKind::Files(paths) => Some(paths.len()),
            SourceKind::Y4m { .. } => None,
        }
    }

    /// The next frame: `None` after the last one (or after an error).
    pub fn next_frame(&mut self) -> Option<Result<GrayImage>> {
        if self.failed {
            return None;
        }
        let result = self.read_next();
        match &result {
            Some(Ok(_)) => self.delivered += 1,
            Some(Err(_)) => self.failed = true,
            None => {}
        }
        result
    }

    fn read_next(&mut self) -> Option<Result<GrayImage>> {
        let (cw, ch) = (self.camera.width as usize, self.camera.height as usize);
        match &mut self.kind {
            SourceKind::Files(paths) => {
                let path = paths.get(self.delivered)?;
                Some(decode_gray(path).and_then(|img| {
                    if img.size() == (cw, ch) {
                        Ok(img)
                    } else {
                        Err(size_mismatch(path, img.width(), img.height(), &self.camera, &self.camera_path))
                    }
                }))
            }
            SourceKind::Y4m { pending, reader } => {
                if let Some((input, name)) = pending.take() {
                    let r = match Y4mReader::with_name(input, &name) {
                        Ok(r) => r,
                        Err(e) => return Some(Err(e)),
                    };
                    let h = r.header();
                    if (h.width, h.height) != (cw, ch) {
                        return Some(Err(size_mismatch(&name, h.width, h.height, &self.camera, &self.camera_path)));
                    }
                    *reader = Some(r);
                }
                let r = reader.as_mut()?;
                match r.next_frame() {
                    Ok(Some(img)) => Some(Ok(img)),
                    Ok(None) if r.frames_read() == 0 => {
                        Some(Err(Error::input(r.name(), "the stream has a header but no frames")))
                    }
                    Ok(None) => None,
                    Err(e) => Some(Err(e)),
                }
            }
        }
    }
}

impl Iterator for FrameSource {
    type Item = Result<GrayImage>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_frame()
    }
}

// ---------------------------------------------------------------------------
// JSON and JSON Lines with one-line, file-naming errors.

const MISSING: &str = "missing";

fn read_text(path: &Path) -> Result<String> {
    fs::read_to_string(path).map_err(|e| match e.kind() {
        io::ErrorKind::NotFound => Error::input(path, MISSING),
        io::ErrorKind::InvalidData => Error::input(path, "not a text file (invalid UTF-8)"),
        _ => Error::input(path, format!("cannot read: {e}")),
    })
}

/// Read a whole JSON file into `T`. A missing file, an empty one, malformed
/// JSON (with line and column), a `NaN`/`Infinity` token (which JSON does
/// not have) or a wrong field are input errors naming `path`.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = read_text(path)?;
    if text.trim().is_empty() {
        return Err(Error::input(path, "empty file"));
    }
    serde_json::from_str(&text).map_err(|e| Error::input(path, describe_json_error(&text, &e, None)))
}

/// Read a JSON Lines file: one `T` per non-blank line, each with its
/// 1-based line number. Errors name `path` and the line. An empty file is
/// an error.
pub fn read_jsonl<T: DeserializeOwned>(path: &Path) -> Result<Vec<(usize, T)>> {
    let file = File::open(path).map_err(|e| open_error(path, &e))?;
    let mut out = Vec::new();
    for (i, line) in BufReader::new(file).lines().enumerate() {
        let n = i + 1;
        let line = line.map_err(|e| match e.kind() {
            io::ErrorKind::InvalidData => Error::input(path, format!("line {n}: not text (invalid UTF-8)")),
            _ => Error::input(path, format!("line {n}: cannot read: {e}")),
        })?;
        if line.trim().is_empty() {
            continue;
        }
        let value = serde_json::from_str(&line)
            .map_err(|e| Error::input(path, format!("line {n}: {}", describe_json_error(&line, &e, Some(n)))))?;
        out.push((n, value));
    }
    if out.is_empty() {
        return Err(Error::input(path, "empty file: expected one JSON object per line"));
    }
    Ok(out)
}

/// One-line description of a serde_json error in `text`. With `line`
/// (JSON Lines), the position is given as a column only.
fn describe_json_error(text: &str, e: &serde_json::Error, line: Option<usize>) -> String {
    let position =
        |l: usize, c: usize| if line.is_some() { format!("column {c}") } else { format!("line {l} column {c}") };
    if let Some((token, l, c)) = find_non_json_number(text) {
        return format!("{token} at {}: JSON has no NaN or Infinity, every number must be finite", position(l, c));
    }
    let full = e.to_string();
    let message = full.rfind(" at line ").map_or(full.as_str(), |i| &full[..i]);
    let kind = match e.classify() {
        serde_json::error::Category::Data => "wrong content",
        _ => "malformed JSON",
    };
    format!("{kind} at {}: {message}", position(e.line(), e.column()))
}

/// The first bare `NaN`, `Infinity` or `inf` token outside strings (any
/// case), with its 1-based line and column.
fn find_non_json_number(text: &str) -> Option<(String, usize, usize)> {
    let (mut in_string, mut escaped) = (false, false);
    let (mut line, mut col) = (1, 0);
    let mut word = String::new();
    let mut word_at = (1, 1);
    for c in text.chars().chain(std::iter::once(' ')) {
        col += 1;
        if in_string {
            match (escaped, c) {
                (true, _) => escaped = false,
                (false, '\\') => escaped = true,
                (false, '"') => in_string = false,
                _ => {}
            }
        } else if c.is_ascii_alphabetic() {
            if word.is_empty() {
                word_at = (line, col);
            }
            word.push(c);
        } else {
            if ["nan", "infinity", "inf"].contains(&word.to_ascii_lowercase().as_str()) {
                return Some((word, word_at.0, word_at.1));
            }
            word.clear();
            in_string = c == '"';
        }
        if c == '\n' {
            line += 1;
            col = 0;
        }
    }
    None
}

// ---------------------------------------------------------------------------
// Output files that never look complete before they are.

/// A file written under `<path>.partial` and renamed to `path` by
/// [`AtomicFile::finish`]. Dropped without `finish` (an error, a panic that
/// unwinds), it deletes the partial file, so a half-written output never
/// sits under the final name. A process killed outright leaves at most a
/// `.partial` file. Note that `std::process::exit` runs no destructors:
/// drop or finish the file before exiting.
///
/// Writes are buffered. Meant for regular files (`--out FILE.jsonl`,
/// overlay PNGs), not for devices or pipes.
pub struct AtomicFile {
    path: PathBuf,
    partial: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Create (or truncate) `<path>.partial` for writing.
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let mut name = path.file_name().ok_or_else(|| Error::input(&path, "not a file name"))?.to_os_string();
        name.push(".partial");
        let partial = path.with_file_name(name);
        let file = File::create(&partial)
            .map_err(|e| Error::input(&path, format!("cannot create (as {}): {e}", partial.display())))?;
        Ok(Self { path, partial, writer: Some(BufWriter::new(file)) })
    }

    /// Write `bytes` to `path` atomically (through `<path>.partial`).
    pub fn write_all_to(path: impl AsRef<Path>, bytes: &[u8]) -> Result<()> {
        let mut f = Self::create(path)?;
        f.write_all(bytes).map_err(|e| Error::io(&f.partial, e))?;
        f.finish()
    }

    /// The final path.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The path written until [`finish`](Self::finish).
    #[must_use]
    pub fn partial_path(&self) -> &Path {
        &self.partial
    }

    /// Flush, sync to disk, and rename the partial file to the final path.
    /// On failure the partial file is deleted.
    pub fn finish(mut self) -> Result<()> {
        let result = self.commit();
        if result.is_err() {
            let _ = fs::remove_file(&self.partial);
        }
        result
    }

    fn commit(&mut self) -> Result<()> {
        let Some(writer) = self.writer.take() else {
            return Ok(());
        };
        let file = writer.into_inner().map_err(|e| Error::io(&self.partial, e.into_error()))?;
        file.sync_all().map_err(|e| Error::io(&self.partial, e))?;
        drop(file);
        fs::rename(&self.partial, &self.path).map_err(|e| Error::io(&self.path, e))
    }

    fn writer(&mut self) -> io::Result<&mut BufWriter<File>> {
        self.writer.as_mut().ok_or_else(|| io::Error::other("AtomicFile already finished"))
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer()?.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer()?.flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let Some(writer) = self.writer.take() {
            drop(writer);
            let _ = fs::remove_file(&self.partial);
        }
    }
}

/// An output folder written in full or not at all: files go into a hidden
/// sibling staging folder, which [`StagedDir::finish`] renames to the final
/// name; dropped unfinished, the staging folder is removed. The final folder
/// must be absent or empty, so sequences and overlays are never mixed.
#[derive(Debug)]
pub struct StagedDir {
    dir: PathBuf,
    staging: PathBuf,
    finished: bool,
}

impl StagedDir {
    /// Check that `dir` is absent or an empty folder and create its staging folder.
    pub fn create(dir: &Path) -> Result<Self> {
        if dir.exists() {
            if !dir.is_dir() {
                return Err(Error::input(dir, "exists and is not a folder"));
            }
            if fs::read_dir(dir).map_err(|e| Error::io(dir, e))?.next().is_some() {
                return Err(Error::input(dir, "output folder exists and is not empty; remove it or pick another"));
            }
        }
        let name = dir.file_name().ok_or_else(|| Error::input(dir, "output folder has no name"))?.to_string_lossy();
        let parent = match dir.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        let staging = parent.join(format!(".{name}.partial-{}", std::process::id()));
        if staging.exists() {
            fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        fs::create_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        Ok(Self { dir: dir.to_path_buf(), staging, finished: false })
    }

    /// The folder to write into until [`StagedDir::finish`].
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Move the staged folder to its final name.
    pub fn finish(mut self) -> Result<()> {
        if self.dir.exists() {
            // Empty (checked in `create`): replace it.
            fs::remove_dir(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        }
        fs::rename(&self.staging, &self.dir).map_err(|e| Error::io(&self.dir, e))?;
        self.finished = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.finished {
            let _ = fs::remove_dir_all(&self.staging);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order_compares_digit_runs_as_numbers() {
        let mut names = vec!["10.png", "2.png", "000001.png", "1.png", "b.png", "a10.png", "a9.png"];
        names.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(names, ["000001.png", "1.png", "2.png", "10.png", "a9.png", "a10.png", "b.png"]);
        assert_eq!(natural_cmp("000010.png", "000009.png"), Ordering::Greater);
    }

    #[test]
    fn finds_nan_and_infinity_outside_strings() {
        assert_eq!(find_non_json_number(r#"{"fx": NaN}"#), Some(("NaN".into(), 1, 8)));
        assert_eq!(find_non_json_number("{\"a\": 1,\n \"b\": -Infinity}"), Some(("Infinity".into(), 2, 8)));
        assert_eq!(find_non_json_number(r#"{"name": "NaN \" inf", "x": 1e5, "t": true}"#), None);
    }

    #[test]
    fn json_errors_are_one_line_with_position() {
        let text = "{\"a\": 1,\n \"b\" 2}";
        let e = serde_json::from_str::<serde_json::Value>(text).unwrap_err();
        let msg = describe_json_error(text, &e, None);
        assert!(msg.starts_with("malformed JSON at line 2 column 6: expected `:`"), "{msg}");
        assert!(!msg.contains('\n'));
        let msg = describe_json_error(r#"{"fx": nan}"#, &e, Some(3));
        assert_eq!(msg, "nan at column 8: JSON has no NaN or Infinity, every number must be finite");
    }

    fn temp_path(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pipetrack-atomic-{}-{name}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        dir.join("out.jsonl")
    }

    #[test]
    fn atomic_file_appears_only_on_finish() {
        let path = temp_path("finish");
        let _ = fs::remove_file(&path);
        let mut f = AtomicFile::create(&path).unwrap();
        assert_eq!(f.partial_path(), path.with_file_name("out.jsonl.partial"));
        writeln!(f, "{{\"frame\":0}}").unwrap();
        f.flush().unwrap();
        assert!(!path.exists(), "nothing under the final name before finish");
        assert!(path.with_file_name("out.jsonl.partial").exists());
        f.finish().unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "{\"frame\":0}\n");
        assert!(!path.with_file_name("out.jsonl.partial").exists());
        fs::remove_dir_all(path.parent().unwrap()).unwrap();
    }

    #[test]
    fn atomic_file_dropped_unfinished_leaves_nothing_and_keeps_old_output() {
        let path = temp_path("drop");
        fs::write(&path, "old complete output\n").unwrap();
        {
            let mut f = AtomicFile::create(&path).unwrap();
            f.write_all(b"half of a new").unwrap();
        }
        assert!(!path.with_file_name("out.jsonl.partial").exists());
        assert_eq!(fs::read_to_string(&path).unwrap(), "old complete output\n");
        AtomicFile::write_all_to(&path, b"new\n").unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "new\n");
        fs::remove_dir_all(path.parent().unwrap()).unwrap();
    }

    #[test]
    fn atomic_file_in_missing_folder_is_an_input_error() {
        let path = std::env::temp_dir().join("pipetrack-no-such-dir-xyz").join("out.jsonl");
        match AtomicFile::create(&path) {
            Err(Error::Input { path: p, message }) => {
                assert_eq!(p, path);
                assert!(message.starts_with("cannot create"), "{message}");
            }
            other => panic!("expected an input error, got {:?}", other.err()),
        }
    }
}
