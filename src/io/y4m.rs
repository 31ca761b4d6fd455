//! A reader for YUV4MPEG2 (`.y4m`) streams, so that
//! `ffmpeg -i clip.mp4 -f yuv4mpegpipe - | pipetrack track SEQ --frames -`
//! works. Only the luma (Y) plane is kept, as the grey frame; chroma planes
//! are skipped.
//!
//! The format: one header line `YUV4MPEG2 W<width> H<height> [F<n>:<d>]
//! [I<interlacing>] [A<n>:<d>] [C<colour space>] [X<comment>]...`, then per
//! frame a line `FRAME [params]` followed by the planes, Y first (width ×
//! height bytes for 8-bit colour spaces). Accepted colour spaces: `420jpeg`,
//! `420paldv`, `420mpeg2`, `420` (the default when `C` is absent), `411`,
//! `422`, `444`, `444alpha` and `mono`; higher bit depths (`420p10`, ...)
//! are refused with a hint to convert to 8 bits. A header declaring a frame
//! larger than [`super::frames::check_frame_size`] allows is refused, and a
//! frame's buffer grows with the bytes that arrive, so a short stream that
//! promises a large frame costs only what it sent.

use std::io::{self, BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use super::frames::check_frame_size;
use crate::bounds::shorten_digit_runs;
use crate::image::GrayImage;
use crate::{Error, Result};

/// How stdin is named in error messages.
pub const STDIN_NAME: &str = "standard input";

const MAGIC: &[u8] = b"YUV4MPEG2";
const FRAME_TAG: &[u8] = b"FRAME";
/// Longest header or `FRAME` line we read before calling the stream corrupt.
const MAX_LINE: usize = 4096;
/// Largest first allocation of a frame's Y plane, bytes; a larger plane's
/// buffer grows as its bytes arrive.
const FIRST_READ: usize = 1 << 22;

/// Chroma layout of a stream: decides how many bytes follow the Y plane in
/// each frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chroma {
    /// 4:2:0 (`420jpeg`, `420paldv`, `420mpeg2`, `420`): two planes of ⌈w/2⌉×⌈h/2⌉.
    C420,
    /// 4:1:1: two planes of ⌈w/4⌉×h.
    C411,
    /// 4:2:2: two planes of ⌈w/2⌉×h.
    C422,
    /// 4:4:4: two planes of w×h.
    C444,
    /// 4:4:4 with alpha: three planes of w×h after Y.
    C444Alpha,
    /// Luma only.
    Mono,
}

impl Chroma {
    /// Parse the value of a `C` header parameter (without the `C`).
    fn parse(tag: &str) -> std::result::Result<Self, String> {
        Ok(match tag {
            "420jpeg" | "420paldv" | "420mpeg2" | "420" => Chroma::C420,
            "411" => Chroma::C411,
            "422" => Chroma::C422,
            "444" => Chroma::C444,
            "444alpha" => Chroma::C444Alpha,
            "mono" => Chroma::Mono,
            other if other.contains('p') || other.ends_with("16") => {
                return Err(format!(
                    "colour space {} has more than 8 bits per sample; convert to 8 bits \
                     (e.g. ffmpeg -pix_fmt gray or yuv420p)",
                    quoted(&format!("C{other}"))
                ));
            }
            other => return Err(format!("unknown colour space {}", quoted(&format!("C{other}")))),
        })
    }

    /// Bytes that follow the Y plane of a `width`×`height` frame.
    #[must_use]
    pub fn extra_bytes(self, width: usize, height: usize) -> usize {
        let half_w = width.div_ceil(2);
        match self {
            Chroma::C420 => 2 * half_w * height.div_ceil(2),
            Chroma::C411 => 2 * width.div_ceil(4) * height,
            Chroma::C422 => 2 * half_w * height,
            Chroma::C444 => 2 * width * height,
            Chroma::C444Alpha => 3 * width * height,
            Chroma::Mono => 0,
        }
    }
}

/// What the stream header says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Y4mHeader {
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height in pixels.
    pub height: usize,
    /// Frame rate as numerator, denominator (`F` parameter), if given.
    pub frame_rate: Option<(u32, u32)>,
    /// Chroma layout (`C` parameter; 4:2:0 when absent).
    pub chroma: Chroma,
}

/// Reads frames from a YUV4MPEG2 stream, one grey image (the Y plane) per
/// frame. Errors are [`Error::Input`] naming the stream (`-` for stdin).
pub struct Y4mReader<R: Read> {
    input: BufReader<R>,
    name: PathBuf,
    header: Y4mHeader,
    /// Frames read so far (the index of the next frame).
    frames_read: usize,
    done: bool,
    line: Vec<u8>,
}

impl<R: Read> Y4mReader<R> {
    /// Read the stream header from `input`, naming the stream `-` in errors.
    pub fn new(input: R) -> Result<Self> {
        Self::with_name(input, Path::new(STDIN_NAME))
    }

    /// Read the stream header from `input`, naming it `name` in errors.
    pub fn with_name(input: R, name: &Path) -> Result<Self> {
        let mut input = BufReader::with_capacity(1 << 16, input);
        let name = name.to_path_buf();
        let mut line = Vec::new();
        let complete =
            read_line(&mut input, &mut line).map_err(|e| Error::input(&name, format!("cannot read: {e}")))?;
        if line.is_empty() && !complete {
            return Err(Error::input(&name, "empty stream: expected a YUV4MPEG2 header"));
        }
        if !line.starts_with(MAGIC) || !(line.len() == MAGIC.len() || line[MAGIC.len()] == b' ') {
            let head = &line[..line.len().min(16)];
            // Text is quoted; bytes that are not printable ASCII are shown
            // as hexadecimal rather than as replacement characters.
            let start = if head.iter().all(|b| b.is_ascii_graphic() || *b == b' ') {
                format!("{:?}", String::from_utf8_lossy(head))
            } else {
                let bytes: Vec<String> = head.iter().map(|b| format!("{b:02x}")).collect();
                format!("the bytes {}", bytes.join(" "))
            };
            return Err(Error::input(
                &name,
                format!("not a YUV4MPEG2 stream: it starts with {start} instead of \"YUV4MPEG2 \""),
            ));
        }
        if !complete {
            return Err(Error::input(&name, "YUV4MPEG2 header line is truncated or too long"));
        }
        let header = parse_header(&line[MAGIC.len()..]).map_err(|msg| Error::input(&name, msg))?;
        check_frame_size(&name, header.width, header.height)?;
        Ok(Self { input, name, header, frames_read: 0, done: false, line })
    }

    /// The stream header.
    #[must_use]
    pub fn header(&self) -> &Y4mHeader {
        &self.header
    }

    /// The name used in errors (`-` for stdin).
    #[must_use]
    pub fn name(&self) -> &Path {
        &self.name
    }

    /// Frames read so far.
    #[must_use]
    pub fn frames_read(&self) -> usize {
        self.frames_read
    }

    /// Read the next frame's Y plane into `out` (resized to the stream's
    /// size, reusing its allocation). `Ok(false)` at the end of the stream.
    pub fn read_frame_into(&mut self, out: &mut GrayImage) -> Result<bool> {
        if self.done {
            return Ok(false);
        }
        let index = self.frames_read;
        let fail = |name: &Path, msg: String| Error::input(name, format!("frame {index}: {msg}"));
        let complete =
            read_line(&mut self.input, &mut self.line).map_err(|e| fail(&self.name, format!("cannot read: {e}")))?;
        if self.line.is_empty() && !complete {
            self.done = true;
            return Ok(false);
        }
        let tag_ok = self.line.starts_with(FRAME_TAG)
            && (self.line.len() == FRAME_TAG.len() || self.line[FRAME_TAG.len()] == b' ');
        if !tag_ok {
            self.done = true;
            let start = String::from_utf8_lossy(&self.line[..self.line.len().min(16)]).into_owned();
            return Err(fail(&self.name, format!("expected a FRAME line, found {start:?}")));
        }
        if !complete {
            self.done = true;
            return Err(fail(&self.name, "truncated stream: FRAME line without its data".to_string()));
        }
        let Y4mHeader { width, height, chroma, .. } = self.header;
        let luma_bytes = width * height;
        let got = if out.size() == (width, height) {
            read_full(&mut self.input, out.data_mut())
        } else {
            // A new buffer grows with what arrives rather than with what the
            // header promises.
            let mut data = Vec::with_capacity(luma_bytes.min(FIRST_READ));
            let got = (&mut self.input).take(luma_bytes as u64).read_to_end(&mut data);
            if data.len() == luma_bytes {
                *out = GrayImage::from_vec(width, height, data).map_err(|e| fail(&self.name, e.to_string()))?;
            }
            got
        }
        .map_err(|e| fail(&self.name, format!("cannot read: {e}")))?;
        let extra = chroma.extra_bytes(width, height) as u64;
        let skipped = if got == luma_bytes {
            io::copy(&mut (&mut self.input).take(extra), &mut io::sink())
                .map_err(|e| fail(&self.name, format!("cannot read: {e}")))?
        } else {
            0
        };
        if got < luma_bytes || skipped < extra {
            self.done = true;
            let expected = luma_bytes as u64 + extra;
            return Err(fail(
                &self.name,
                format!("truncated stream: the frame needs {expected} bytes, only {} arrived", got as u64 + skipped),
            ));
        }
        self.frames_read += 1;
        Ok(true)
    }

    /// Read the next frame as a new image; `Ok(None)` at the end.
    pub fn next_frame(&mut self) -> Result<Option<GrayImage>> {
        let mut img = GrayImage::new(0, 0);
        Ok(self.read_frame_into(&mut img)?.then_some(img))
    }
}

impl<R: Read> Iterator for Y4mReader<R> {
    type Item = Result<GrayImage>;

    /// The next frame; after an error, `None`.
    fn next(&mut self) -> Option<Self::Item> {
        self.next_frame().transpose()
    }
}

/// Read up to and excluding the next `\n` into `line` (cleared first), at
/// most [`MAX_LINE`] bytes. Returns whether the newline was found.
fn read_line<R: BufRead>(input: &mut R, line: &mut Vec<u8>) -> io::Result<bool> {
    line.clear();
    let n = input.take(MAX_LINE as u64 + 1).read_until(b'\n', line)?;
    if n > 0 && line.last() == Some(&b'\n') {
        line.pop();
        return Ok(true);
    }
    Ok(false)
}

/// Fill `buf` from `input`, stopping early only at end of stream; returns
/// the number of bytes read.
fn read_full<R: Read>(input: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match input.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// Parse the parameters after the magic word.
fn parse_header(params: &[u8]) -> std::result::Result<Y4mHeader, String> {
    let text = std::str::from_utf8(params).map_err(|_| "YUV4MPEG2 header is not ASCII".to_string())?;
    let (mut width, mut height, mut frame_rate, mut chroma) = (None, None, None, Chroma::C420);
    for token in text.split(' ').filter(|t| !t.is_empty()) {
        let mut chars = token.chars();
        let key = chars.next().unwrap_or(' ');
        let value = chars.as_str();
        match key {
            'W' | 'H' => {
                let side: usize = value
                    .parse()
                    .ok()
                    .filter(|&v| v > 0)
                    .ok_or_else(|| format!("bad frame size parameter {} in the YUV4MPEG2 header", quoted(token)))?;
                if key == 'W' {
                    width = Some(side);
                } else {
                    height = Some(side);
                }
            }
            'F' => frame_rate = Some(parse_ratio(value).ok_or_else(|| format!("bad frame rate {}", quoted(token)))?),
            'C' => chroma = Chroma::parse(value)?,
            // Interlacing, pixel aspect and comments do not change the layout.
            'I' | 'A' | 'X' => {}
            _ => return Err(format!("unknown parameter {} in the YUV4MPEG2 header", quoted(token))),
        }
    }
    match (width, height) {
        (Some(width), Some(height)) => Ok(Y4mHeader { width, height, frame_rate, chroma }),
        _ => Err("YUV4MPEG2 header lacks the W (width) or H (height) parameter".to_string()),
    }
}

/// Longest header token quoted whole in a message.
const MAX_QUOTED: usize = 32;

/// A header token for a message: long digit runs shortened
/// ([`shorten_digit_runs`]), then at most [`MAX_QUOTED`] characters, quoted.
fn quoted(token: &str) -> String {
    let short = shorten_digit_runs(token);
    match short.char_indices().nth(MAX_QUOTED) {
        Some((end, _)) => format!("{:?}", format!("{}…", &short[..end])),
        None => format!("{short:?}"),
    }
}

fn parse_ratio(value: &str) -> Option<(u32, u32)> {
    let (n, d) = value.split_once(':')?;
    Some((n.parse().ok()?, d.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stream of `frames` frames of `w`×`h` where frame `k`'s Y pixel at
    /// index `i` is `k * 10 + i` and chroma bytes are 200.
    fn stream(header: &str, w: usize, h: usize, chroma: usize, frames: usize) -> Vec<u8> {
        let mut s = format!("{header}\n").into_bytes();
        for k in 0..frames {
            s.extend_from_slice(b"FRAME\n");
            s.extend((0..w * h).map(|i| (k * 10 + i) as u8));
            s.extend(std::iter::repeat_n(200u8, chroma));
        }
        s
    }

    #[test]
    fn reads_420_frames_skipping_chroma() {
        // 3×2 frame: Y 6 bytes, chroma 2 × (2×1) = 4 bytes.
        let data = stream("YUV4MPEG2 W3 H2 F30000:1001 Ip A1:1 C420jpeg XYSCSS=420JPEG", 3, 2, 4, 2);
        let mut r = Y4mReader::new(data.as_slice()).unwrap();
        assert_eq!(r.header().frame_rate, Some((30000, 1001)));
        assert_eq!(r.header().chroma, Chroma::C420);
        let f0 = r.next_frame().unwrap().unwrap();
        assert_eq!(f0.size(), (3, 2));
        assert_eq!(f0.data(), &[0, 1, 2, 3, 4, 5]);
        let f1 = r.next_frame().unwrap().unwrap();
        assert_eq!(f1.data(), &[10, 11, 12, 13, 14, 15]);
        assert!(r.next_frame().unwrap().is_none());
        assert_eq!(r.frames_read(), 2);
    }

    #[test]
    fn default_colour_space_is_420() {
        let data = stream("YUV4MPEG2 W2 H2", 2, 2, 2, 1);
        let frames: Vec<_> = Y4mReader::new(data.as_slice()).unwrap().collect::<Result<_>>().unwrap();
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].data(), &[0, 1, 2, 3]);
    }

    #[test]
    fn reads_mono_stream() {
        let data = stream("YUV4MPEG2 W2 H1 Cmono", 2, 1, 0, 3);
        let frames: Vec<_> = Y4mReader::new(data.as_slice()).unwrap().collect::<Result<_>>().unwrap();
        assert_eq!(frames.len(), 3);
        assert_eq!(frames[2].data(), &[20, 21]);
    }

    #[test]
    fn frame_lines_may_carry_parameters() {
        let mut data = b"YUV4MPEG2 W1 H1 C444\nFRAME Ixyz\n".to_vec();
        data.extend_from_slice(&[7, 1, 1]);
        let frames: Vec<_> = Y4mReader::new(data.as_slice()).unwrap().collect::<Result<_>>().unwrap();
        assert_eq!(frames[0].data(), &[7]);
    }

    #[test]
    fn chroma_sizes_round_up() {
        assert_eq!(Chroma::C420.extra_bytes(3, 3), 2 * 2 * 2);
        assert_eq!(Chroma::C422.extra_bytes(3, 3), 2 * 2 * 3);
        assert_eq!(Chroma::C411.extra_bytes(5, 1), 2 * 2);
        assert_eq!(Chroma::C444Alpha.extra_bytes(2, 2), 12);
        assert_eq!(Chroma::Mono.extra_bytes(9, 9), 0);
    }

    fn message(err: Error) -> String {
        match err {
            Error::Input { path, message } => {
                assert_eq!(path, Path::new(STDIN_NAME));
                message
            }
            other => panic!("expected an input error, got {other:?}"),
        }
    }

    #[test]
    fn truncated_frame_is_an_error_naming_stdin() {
        let mut data = stream("YUV4MPEG2 W3 H2 C420", 3, 2, 4, 2);
        data.truncate(data.len() - 3);
        let mut r = Y4mReader::new(data.as_slice()).unwrap();
        assert!(r.next_frame().unwrap().is_some());
        let msg = message(r.next_frame().unwrap_err());
        assert!(
            msg.contains("frame 1") && msg.contains("truncated") && msg.contains("needs 10 bytes, only 7"),
            "{msg}"
        );
        assert!(r.next().is_none(), "the iterator stops after an error");
    }

    #[test]
    fn truncated_in_luma_and_in_frame_line() {
        let data = b"YUV4MPEG2 W4 H4 Cmono\nFRAME\n\x01\x02".to_vec();
        let msg = message(Y4mReader::new(data.as_slice()).unwrap().next_frame().unwrap_err());
        assert!(msg.contains("only 2 arrived"), "{msg}");
        let data = b"YUV4MPEG2 W4 H4 Cmono\nFRA".to_vec();
        let msg = message(Y4mReader::new(data.as_slice()).unwrap().next_frame().unwrap_err());
        assert!(msg.contains("expected a FRAME line"), "{msg}");
    }

    #[test]
    fn bad_headers_are_errors() {
        let msg = |s: &[u8]| message(Y4mReader::new(s).err().expect("should fail"));
        assert!(
            msg(b"\x89PNG\r\n").contains("not a YUV4MPEG2 stream: it starts with the bytes 89 50 4e 47 0d instead")
        );
        assert!(msg(b"P5 4 4\n").contains("it starts with \"P5 4 4\" instead"));
        assert!(msg(b"").contains("empty stream"));
        assert!(msg(b"YUV4MPEG2 W4 H4").contains("truncated"));
        assert!(msg(b"YUV4MPEG2 W4\n").contains("lacks the W"));
        assert!(msg(b"YUV4MPEG2 W0 H4\n").contains("bad frame size"));
        assert!(msg(b"YUV4MPEG2 W4 H4 C420p10\n").contains("more than 8 bits"));
        assert!(msg(b"YUV4MPEG2 W4 H4 Cfoo\n").contains("unknown colour space"));
        assert!(msg(b"YUV4MPEG2 W4 H4 Q1\n").contains("unknown parameter"));
    }

    #[test]
    fn empty_stream_after_header_has_no_frames() {
        let mut r = Y4mReader::new(&b"YUV4MPEG2 W2 H2\n"[..]).unwrap();
        assert!(r.next_frame().unwrap().is_none());
    }
}
