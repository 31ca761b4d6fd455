//! Frames of a sequence: the frame files of a folder in natural order,
//! decoding to grey, and [`FrameSource`], which streams them (from `frames/`
//! or a Y4M stream on stdin) one at a time, each checked against the camera.

use std::cmp::Ordering;
use std::fs::{self};
use std::io::{self, Read};
use std::path::{Path, PathBuf};

use super::formats::Camera;
use super::json::*;
use super::sequence::FRAME_EXTENSIONS;
use super::y4m::Y4mReader;
use crate::image::{GrayImage, RgbImage, luma};
use crate::{Error, Result};

/// Largest width or height of a frame, px: four times HD, and the side of
/// the largest 2-D texture most GPUs take.
pub const MAX_FRAME_SIDE: usize = 16_384;

/// Largest frame, pixels (2²⁵: 8192×4096; 8K UHD, 7680×4320, fits). The
/// backends keep about a dozen 4-byte planes of a frame, so this bounds
/// their memory to a few GiB; a header that promises more is refused before
/// anything of that size is allocated.
pub const MAX_FRAME_PIXELS: usize = 1 << 25;

/// The limits of a frame, for messages.
fn limits_text() -> String {
    format!("pipetrack takes frames of at most {MAX_FRAME_SIDE} px a side and {MAX_FRAME_PIXELS} pixels")
}

/// `Ok` unless a `width`×`height` frame exceeds [`MAX_FRAME_SIDE`] or
/// [`MAX_FRAME_PIXELS`]; the error names `path` (the file that declares the
/// size: a frame, a stream, `camera.json`) and states the limits.
pub fn check_frame_size(path: &Path, width: usize, height: usize) -> Result<()> {
    let pixels = width.checked_mul(height);
    if width <= MAX_FRAME_SIDE && height <= MAX_FRAME_SIDE && pixels.is_some_and(|p| p <= MAX_FRAME_PIXELS) {
        return Ok(());
    }
    Err(Error::input(path, format!("frame size {width}x{height} is too large: {}", limits_text())))
}

/// The decoder limits of a frame file: [`MAX_FRAME_SIDE`] a side, and the
/// image crate's default cap on what a decoder allocates.
fn decoder_limits() -> ::image::Limits {
    let side = u32::try_from(MAX_FRAME_SIDE).unwrap_or(u32::MAX);
    let mut limits = ::image::Limits::default();
    limits.max_image_width = Some(side);
    limits.max_image_height = Some(side);
    limits
}

/// An image that failed to decode: too large (a decoder limit) or corrupt.
fn decode_error(path: &Path, e: &::image::ImageError) -> Error {
    match e {
        ::image::ImageError::Limits(limit) => {
            Error::input(path, format!("image too large ({limit}): {}", limits_text()))
        }
        other => Error::input(path, format!("corrupt image: {}", without_chunk_dumps(&other.to_string()))),
    }
}

/// A decoder's message with each PNG chunk type it prints as a Rust
/// structure (`ChunkType { type: IDAT, critical: true, … }`) put as its
/// name (`IDAT`).
fn without_chunk_dumps(message: &str) -> String {
    const OPEN: &str = "ChunkType { type: ";
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(start) = rest.find(OPEN) {
        let after = &rest[start + OPEN.len()..];
        let Some(end) = after.find('}') else { break };
        out.push_str(&rest[..start]);
        out.push_str(after[..end].split(',').next().unwrap_or("").trim());
        rest = &after[end + 1..];
    }
    out.push_str(rest);
    out
}

/// The frame images in `frames_dir`, in natural name order (digit runs
/// compare as numbers, so `2.png` < `10.png`; zero-padded names sort as
/// usual). Files without a frame extension, hidden files and folders are
/// ignored; an empty or missing folder is an error naming it.
///
/// The frames are numbered (the last digit run of a name, `000007` in
/// `000007.png` or `img_000007.png`) from 0 or 1 without gaps: the output's
/// frame `i` is the `i`-th file, so a missing file would shift every later
/// frame. A gap is an error naming the missing file; a name without a
/// number, or two files with one number, are errors naming the file.
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
        let frame_named = !name.starts_with('.')
            && path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| FRAME_EXTENSIONS.iter().any(|f| f.eq_ignore_ascii_case(e)));
        if !frame_named {
            continue;
        }
        // A folder or device with a frame's extension is skipped unless it
        // is numbered like a frame: the frames would seem to jump over it.
        match fs::metadata(&path) {
            Ok(meta) if meta.is_file() => named.push((name, path)),
            _ if split_number(&name).is_none() => {}
            Ok(meta) if meta.is_dir() => return Err(Error::input(&path, "is a folder, not a frame file")),
            Ok(_) => return Err(Error::input(&path, "is a device or other special file, not a frame file")),
            Err(e) => return Err(open_error(&path, &e)),
        }
    }
    if named.is_empty() {
        return Err(Error::input(frames_dir, "no frames: expected PNG, PGM or JPEG files"));
    }
    named.sort_by(|a, b| natural_cmp(&a.0, &b.0));
    check_numbering(frames_dir, &named)?;
    Ok(named.into_iter().map(|(_, p)| p).collect())
}

/// A frame file name split around its number: `(before, digits, after)`,
/// the digits being the last run of digits before the extension.
fn split_number(name: &str) -> Option<(&str, &str, &str)> {
    let stem_end = name.rfind('.').unwrap_or(name.len());
    let stem = &name[..stem_end];
    let end = stem.rfind(|c: char| c.is_ascii_digit())? + 1;
    let start = stem[..end].rfind(|c: char| !c.is_ascii_digit()).map_or(0, |i| i + 1);
    Some((&name[..start], &name[start..end], &name[end..]))
}

/// Check that the frames (name, path), in natural order, are numbered from
/// 0 or 1 without gaps or repeats (see [`list_frames`]).
fn check_numbering(frames_dir: &Path, named: &[(String, PathBuf)]) -> Result<()> {
    let number = |name: &str, path: &Path| -> Result<(u64, String, String, usize)> {
        let unnumbered = || {
            Error::input(path, "frame file name has no number: name the frames 000000.png, 000001.png, ... in order")
        };
        let (before, digits, after) = split_number(name).ok_or_else(unnumbered)?;
        let n = digits.parse().map_err(|_| Error::input(path, format!("frame number {digits} is too large")))?;
        Ok((n, before.to_string(), after.to_string(), digits.len()))
    };
    let Some((first_name, first_path)) = named.first() else { return Ok(()) };
    let (mut previous, mut before, mut after, mut width) = number(first_name, first_path)?;
    if previous > 1 {
        let missing = format!("{before}{:0width$}{after}", 0);
        return Err(Error::input(
            frames_dir.join(missing),
            format!("missing: the first frame is {first_name}; frames are numbered from 0 (or 1) without gaps"),
        ));
    }
    let mut previous_name = first_name;
    for (name, path) in &named[1..] {
        let (n, b, a, w) = number(name, path)?;
        if n == previous {
            return Err(Error::input(path, format!("has the frame number of {previous_name}: number each frame once")));
        }
        if n < previous {
            return Err(Error::input(
                path,
                format!(
                    "numbered {n} but comes after {previous_name} in name order: give every frame one name pattern"
                ),
            ));
        }
        if n > previous + 1 {
            let missing = format!("{before}{:0width$}{after}", previous + 1);
            return Err(Error::input(
                frames_dir.join(missing),
                format!("missing: the frames jump from {previous_name} to {name}; number them without gaps"),
            ));
        }
        (previous, before, after, width) = (n, b, a, w);
        previous_name = name;
    }
    Ok(())
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
pub(crate) fn check_frame_header(path: &Path, camera: &Camera, camera_path: &Path) -> Result<()> {
    let (w, h) = ::image::ImageReader::open(path)
        .map_err(|e| open_error(path, &e))?
        .with_guessed_format()
        .map_err(|e| open_error(path, &e))?
        .into_dimensions()
        .map_err(|e| decode_error(path, &e))?;
    check_frame_size(path, w as usize, h as usize)?;
    if (w, h) != (camera.width, camera.height) {
        return Err(size_mismatch(path, w as usize, h as usize, camera, camera_path));
    }
    Ok(())
}

pub(crate) fn open_error(path: &Path, e: &io::Error) -> Error {
    if e.kind() == io::ErrorKind::NotFound {
        Error::input(path, MISSING)
    } else {
        Error::input(path, format!("cannot read: {e}"))
    }
}

/// Decode an image file to an 8-bit grey frame: grey as is (16-bit scaled
/// to 8), colour through BT.601 luma ([`luma`], the weights the GPU ingest
/// uses) rounded to the nearest integer, alpha ignored. A frame larger
/// than [`check_frame_size`] allows is refused from its header, before it
/// is decoded.
pub fn decode_gray(path: &Path) -> Result<GrayImage> {
    let mut reader = ::image::ImageReader::open(path)
        .map_err(|e| open_error(path, &e))?
        .with_guessed_format()
        .map_err(|e| open_error(path, &e))?;
    reader.limits(decoder_limits());
    let decoder = reader.into_decoder().map_err(|e| decode_error(path, &e))?;
    let (w, h) = ::image::ImageDecoder::dimensions(&decoder);
    check_frame_size(path, w as usize, h as usize)?;
    let img = ::image::DynamicImage::from_decoder(decoder).map_err(|e| decode_error(path, &e))?;
    dynamic_to_gray(img).map_err(|e| Error::input(path, e.to_string()))
}

/// Decode an image file to an 8-bit colour frame: colour as is (16-bit
/// scaled to 8, alpha ignored), grey repeated in R, G and B. Its
/// [`RgbImage::to_gray`] is what [`decode_gray`] gives for the same file.
pub fn decode_rgb(path: &Path) -> Result<RgbImage> {
    let mut reader = ::image::ImageReader::open(path)
        .map_err(|e| open_error(path, &e))?
        .with_guessed_format()
        .map_err(|e| open_error(path, &e))?;
    reader.limits(decoder_limits());
    let decoder = reader.into_decoder().map_err(|e| decode_error(path, &e))?;
    let (w, h) = ::image::ImageDecoder::dimensions(&decoder);
    check_frame_size(path, w as usize, h as usize)?;
    let img = ::image::DynamicImage::from_decoder(decoder).map_err(|e| decode_error(path, &e))?;
    dynamic_to_rgb(img).map_err(|e| Error::input(path, e.to_string()))
}

/// Convert any decoded image to colour as [`decode_rgb`] describes.
pub fn dynamic_to_rgb(img: ::image::DynamicImage) -> Result<RgbImage> {
    use ::image::DynamicImage as D;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data = match img {
        img @ (D::ImageLuma8(_) | D::ImageLumaA8(_) | D::ImageLuma16(_) | D::ImageLumaA16(_)) => {
            return Ok(RgbImage::from_gray(&dynamic_to_gray(img)?));
        }
        D::ImageRgb8(buf) => buf.as_raw().chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(),
        other => other.to_rgb8().as_raw().chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(),
    };
    RgbImage::from_vec(w, h, data)
}

/// Convert any decoded image to grey as [`decode_gray`] describes.
pub fn dynamic_to_gray(img: ::image::DynamicImage) -> Result<GrayImage> {
    use ::image::DynamicImage as D;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let rgb_luma = |p: &[u8]| luma(p[0], p[1], p[2]);
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

    /// The next frame: `None` after the last one (or after an error). Before
    /// the first, the camera's size is checked against [`check_frame_size`]
    /// (the error names the camera file).
    pub fn next_frame(&mut self) -> Option<Result<GrayImage>> {
        self.next_with(decode_gray, |g| g)
    }

    /// Colour frames instead of grey ones: image files decode with
    /// [`decode_rgb`]; a Y4M stream (luma only) arrives as grey in R, G and B.
    #[must_use]
    pub fn colour(self) -> ColourFrames {
        ColourFrames(self)
    }

    /// The next frame as [`next_frame`](Self::next_frame) gives it, decoding
    /// files with `decode` and taking stream frames through `from_gray`.
    fn next_with<T: FrameSize>(
        &mut self,
        decode: fn(&Path) -> Result<T>,
        from_gray: fn(GrayImage) -> T,
    ) -> Option<Result<T>> {
        if self.failed {
            return None;
        }
        let (cw, ch) = (self.camera.width as usize, self.camera.height as usize);
        let result = match check_frame_size(&self.camera_path, cw, ch) {
            Ok(()) => self.read_next_with(decode, from_gray),
            Err(e) => Some(Err(e)),
        };
        match &result {
            Some(Ok(_)) => self.delivered += 1,
            Some(Err(_)) => self.failed = true,
            None => {}
        }
        result
    }

    /// The next frame, decoding files with `decode` and taking stream frames through `from_gray`.
    fn read_next_with<T: FrameSize>(
        &mut self,
        decode: fn(&Path) -> Result<T>,
        from_gray: fn(GrayImage) -> T,
    ) -> Option<Result<T>> {
        let (cw, ch) = (self.camera.width as usize, self.camera.height as usize);
        match &mut self.kind {
            SourceKind::Files(paths) => {
                let path = paths.get(self.delivered)?;
                Some(decode(path).and_then(|img| {
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
                    Ok(Some(img)) => Some(Ok(from_gray(img))),
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

/// Anything a frame file decodes to, by its size.
trait FrameSize {
    fn size(&self) -> (usize, usize);
    fn width(&self) -> usize {
        self.size().0
    }
    fn height(&self) -> usize {
        self.size().1
    }
}

impl<T: Copy + Default> FrameSize for crate::image::Image<T> {
    fn size(&self) -> (usize, usize) {
        crate::image::Image::size(self)
    }
}

/// [`FrameSource`] decoding colour: an iterator of `Result<RgbImage>` (see
/// [`FrameSource::colour`]).
pub struct ColourFrames(FrameSource);

impl ColourFrames {
    /// Number of frames, when known (image files, not streams).
    #[must_use]
    pub fn len_hint(&self) -> Option<usize> {
        self.0.len_hint()
    }
}

impl Iterator for ColourFrames {
    type Item = Result<RgbImage>;

    fn next(&mut self) -> Option<Self::Item> {
        self.0.next_with(decode_rgb, |g| RgbImage::from_gray(&g))
    }
}

impl Iterator for FrameSource {
    type Item = Result<GrayImage>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_frame()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunk_types_in_decoder_messages_are_named() {
        let message =
            "CRC error: expected 0x4e while decoding ChunkType { type: IDAT, critical: true, private: false } chunk.";
        assert_eq!(without_chunk_dumps(message), "CRC error: expected 0x4e while decoding IDAT chunk.");
        assert_eq!(without_chunk_dumps("no chunk here"), "no chunk here");
    }

    #[test]
    fn natural_order_compares_digit_runs_as_numbers() {
        let mut names = vec!["10.png", "2.png", "000001.png", "1.png", "b.png", "a10.png", "a9.png"];
        names.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(names, ["000001.png", "1.png", "2.png", "10.png", "a9.png", "a10.png", "b.png"]);
        assert_eq!(natural_cmp("000010.png", "000009.png"), Ordering::Greater);
    }

    #[test]
    fn frame_numbers_are_the_last_digit_run_before_the_extension() {
        assert_eq!(split_number("000007.png"), Some(("", "000007", ".png")));
        assert_eq!(split_number("cam2_img_0031.jpg"), Some(("cam2_img_", "0031", ".jpg")));
        assert_eq!(split_number("frame.png"), None);
    }
}
