//! JSON and JSON Lines with one-line, file-naming errors.

use std::fs::{self, File};
use std::io::{self, BufRead, BufReader};
use std::path::Path;

use serde::de::DeserializeOwned;

use super::frames::*;
use crate::bounds::shorten_digit_runs;
use crate::{Error, Result};

pub(crate) const MISSING: &str = "missing";

/// Largest text input read whole (a model, a camera, an `init.json`):
/// 256 MiB, far above a model at the bounds of [`crate::bounds`].
pub const MAX_TEXT_BYTES: u64 = 256 << 20;
/// Longest line of a JSON Lines file: 64 MiB, far above one frame's record.
pub const MAX_LINE_BYTES: u64 = 64 << 20;

/// Open an input file for reading: a folder or a device (`/dev/zero`,
/// which would never end) is an input error naming `path`, as is a missing
/// or unreadable file. A pipe is read as it comes.
pub(crate) fn open_input(path: &Path) -> Result<File> {
    use std::os::unix::fs::FileTypeExt;
    if let Ok(meta) = fs::metadata(path) {
        let kind = meta.file_type();
        if kind.is_dir() {
            return Err(Error::input(path, "is a folder, not a file"));
        }
        if kind.is_char_device() || kind.is_block_device() || kind.is_socket() {
            return Err(Error::input(path, "is a device, not a file"));
        }
    }
    File::open(path).map_err(|e| open_error(path, &e))
}

/// A whole text file of at most [`MAX_TEXT_BYTES`]; missing, non-UTF-8,
/// unreadable and larger files are input errors naming it.
pub(crate) fn read_text(path: &Path) -> Result<String> {
    read_text_at_most(path, MAX_TEXT_BYTES)
}

/// [`read_text`] with a limit of `max` bytes.
pub(crate) fn read_text_at_most(path: &Path, max: u64) -> Result<String> {
    use std::io::Read;
    let mut text = String::new();
    open_input(path)?.take(max + 1).read_to_string(&mut text).map_err(|e| match e.kind() {
        io::ErrorKind::InvalidData => Error::input(path, "not a text file (invalid UTF-8)"),
        _ => Error::input(path, format!("cannot read: {e}")),
    })?;
    if text.len() as u64 > max {
        return Err(Error::input(path, format!("too large: more than {}", byte_size(max))));
    }
    // A byte-order mark (some editors write one) is not part of the text.
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// `bytes` as MiB when a whole number of them, else as bytes.
fn byte_size(bytes: u64) -> String {
    if bytes >= 1 << 20 && bytes.is_multiple_of(1 << 20) {
        format!("{} MiB", bytes >> 20)
    } else {
        format!("{bytes} bytes")
    }
}

/// A JSON Lines file of per-frame records (`truth.jsonl`, a tracker's
/// output): every line parsed into `T` and passed to `check` with its line
/// number, and the frame numbers (`frame_of`) strictly increasing. Errors
/// name the file and the line.
pub fn read_frame_lines<T: DeserializeOwned>(
    path: &Path,
    frame_of: impl Fn(&T) -> usize,
    mut check: impl FnMut(&T, usize) -> Result<()>,
) -> Result<Vec<T>> {
    let lines: Vec<(usize, T)> = read_jsonl(path)?;
    let mut previous: Option<usize> = None;
    for (line, record) in &lines {
        check(record, *line)?;
        let frame = frame_of(record);
        if let Some(p) = previous.filter(|&p| frame <= p) {
            return Err(Error::input(
                path,
                format!("line {line}: frame {frame} after frame {p}: frames must be in increasing order"),
            ));
        }
        previous = Some(frame);
    }
    Ok(lines.into_iter().map(|(_, record)| record).collect())
}

/// Read a whole JSON file holding one object into `T`. A missing file, an
/// empty one, malformed JSON (with line and column), a `NaN`/`Infinity`
/// token (which JSON does not have), an array where the object belongs
/// (serde would take it as the fields in order) or a wrong field are input
/// errors naming `path`.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T> {
    parse_json(path, &read_text(path)?)
}

/// Any JSON value of `path` (an array at the top too), with the errors of
/// [`read_json`] otherwise.
pub(crate) fn read_json_value(path: &Path) -> Result<serde_json::Value> {
    parse_any(path, &read_text(path)?)
}

/// [`read_json`] of `text`, the contents of `path`.
fn parse_json<T: DeserializeOwned>(path: &Path, text: &str) -> Result<T> {
    if let Some(msg) = not_an_object(text) {
        return Err(Error::input(path, msg));
    }
    parse_any(path, text)
}

/// `text`, the contents of `path`, as `T`, whatever JSON it holds: an
/// empty file or malformed JSON is an input error naming `path`.
fn parse_any<T: DeserializeOwned>(path: &Path, text: &str) -> Result<T> {
    if text.trim().is_empty() {
        return Err(Error::input(path, "empty file"));
    }
    serde_json::from_str(text).map_err(|e| input_error(path, describe_json_error(text, &e, None)))
}

/// [`read_json`], and the keys of the file that `T` does not read
/// ([`ignored_keys`]): a misspelt optional key (`"joint"` for `"joints"`)
/// is otherwise silently left out.
pub fn read_json_noting_ignored<T: DeserializeOwned + serde::Serialize>(path: &Path) -> Result<(T, Vec<String>)> {
    read_json_with_original(path).map(|(value, ignored, _)| (value, ignored))
}

/// [`read_json_noting_ignored`], and the file's JSON as written (`Null` if
/// only `T` reads it), for a reader that looks at the keys `T` leaves out.
pub(crate) fn read_json_with_original<T: DeserializeOwned + serde::Serialize>(
    path: &Path,
) -> Result<(T, Vec<String>, serde_json::Value)> {
    let text = read_text(path)?;
    let value: T = parse_json(path, &text)?;
    let original: serde_json::Value = serde_json::from_str(&text).unwrap_or_default();
    let ignored = match serde_json::to_value(&value) {
        Ok(parsed) if !original.is_null() => ignored_keys(&original, &parsed),
        _ => Vec::new(),
    };
    Ok((value, ignored, original))
}

/// The keys of `original` (a JSON object, and the objects and arrays in
/// it) that `parsed` (what was read from it, written back) does not have,
/// as paths (`joints[0].type`). A key whose value is null or empty is not
/// listed: an optional field left out on writing looks the same.
#[must_use]
pub fn ignored_keys(original: &serde_json::Value, parsed: &serde_json::Value) -> Vec<String> {
    use serde_json::Value;
    fn walk(original: &Value, parsed: &Value, at: &str, out: &mut Vec<String>) {
        match (original, parsed) {
            (Value::Object(o), Value::Object(p)) => {
                for (key, value) in o {
                    let path = if at.is_empty() { key.clone() } else { format!("{at}.{key}") };
                    match p.get(key) {
                        Some(read) => walk(value, read, &path, out),
                        None if !empty(value) => out.push(path),
                        None => {}
                    }
                }
            }
            (Value::Array(o), Value::Array(p)) => {
                for (k, (value, read)) in o.iter().zip(p).enumerate() {
                    walk(value, read, &format!("{at}[{k}]"), out);
                }
            }
            _ => {}
        }
    }
    fn empty(value: &Value) -> bool {
        match value {
            Value::Null => true,
            Value::Array(a) => a.is_empty(),
            Value::Object(o) => o.is_empty(),
            _ => false,
        }
    }
    let mut out = Vec::new();
    walk(original, parsed, "", &mut out);
    out
}

/// The complaint about a JSON text whose top level is an array: every file
/// and line pipetrack reads is one object with named fields.
fn not_an_object(text: &str) -> Option<String> {
    text.trim_start()
        .starts_with('[')
        .then(|| "a JSON array where an object is expected: give the fields by name, {\"key\": value, ...}".to_string())
}

/// Read a JSON Lines file: one `T` per non-blank line, each with its
/// 1-based line number; each line holds one object (an array is refused as
/// [`read_json`] refuses it). Errors name `path` and the line. An empty file
/// is an error.
pub fn read_jsonl<T: DeserializeOwned>(path: &Path) -> Result<Vec<(usize, T)>> {
    read_jsonl_lines_at_most(path, MAX_LINE_BYTES)
}

/// [`read_jsonl`] with lines of at most `max_line` bytes.
fn read_jsonl_lines_at_most<T: DeserializeOwned>(path: &Path, max_line: u64) -> Result<Vec<(usize, T)>> {
    use std::io::Read;
    let mut reader = BufReader::new(open_input(path)?);
    let mut out = Vec::new();
    let mut line = String::new();
    for n in 1.. {
        line.clear();
        let read = (&mut reader).take(max_line + 1).read_line(&mut line).map_err(|e| match e.kind() {
            io::ErrorKind::InvalidData => Error::input(path, format!("line {n}: not text (invalid UTF-8)")),
            _ => Error::input(path, format!("line {n}: cannot read: {e}")),
        })?;
        if read == 0 {
            break;
        }
        if read as u64 > max_line {
            return Err(Error::input(path, format!("line {n}: too long: more than {}", byte_size(max_line))));
        }
        let line = line.trim_end_matches(['\n', '\r']);
        let line = if n == 1 { line.trim_start_matches('\u{feff}') } else { line };
        if line.trim().is_empty() {
            continue;
        }
        if let Some(msg) = not_an_object(line) {
            return Err(Error::input(path, format!("line {n}: {msg}")));
        }
        let value = serde_json::from_str(line)
            .map_err(|e| input_error(path, format!("line {n}: {}", describe_json_error(line, &e, Some(n)))))?;
        out.push((n, value));
    }
    if out.is_empty() {
        return Err(Error::input(path, "empty file: expected one JSON object per line"));
    }
    Ok(out)
}

/// Longest run of non-blank characters a message keeps whole: a longer run
/// is user text echoed back (a string value, a token) and is cut.
const MAX_ECHO_CHARS: usize = 40;
/// Characters of a cut run that are kept before the `…`.
const ECHO_KEPT_CHARS: usize = 32;
/// Longest message, in characters; the rest is cut.
const MAX_MESSAGE_CHARS: usize = 300;

/// Characters that would break a message's one line or its display:
/// controls, line and paragraph separators, and bidirectional overrides.
fn breaks_line(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{2028}' | '\u{2029}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}' | '\u{FEFF}')
}

/// `message` as one short line for an [`Error::Input`], whatever user text
/// it quotes: characters that break a line escaped (`\n`, `\u{2028}`),
/// long digit runs shortened ([`shorten_digit_runs`]), a run of non-blank
/// characters longer than [`MAX_ECHO_CHARS`] cut to its start, `…` and its
/// closing quote or punctuation, and the whole at most
/// [`MAX_MESSAGE_CHARS`] characters.
pub(crate) fn one_short_line(message: &str) -> String {
    let escaped: String =
        message.chars().map(|c| if breaks_line(c) { c.escape_default().collect() } else { c.to_string() }).collect();
    let short = shorten_digit_runs(&escaped);
    let words: Vec<String> = short
        .split(' ')
        .map(|word| {
            if word.chars().count() <= MAX_ECHO_CHARS {
                return word.to_string();
            }
            let mut closing: Vec<char> = word
                .chars()
                .rev()
                .take_while(|c| matches!(c, '"' | '`' | '\'' | ',' | ')' | ']' | ':'))
                .take(3)
                .collect();
            closing.reverse();
            let closing: String = closing.into_iter().collect();
            format!("{}…{closing}", word.chars().take(ECHO_KEPT_CHARS).collect::<String>())
        })
        .collect();
    let line = words.join(" ");
    match line.char_indices().nth(MAX_MESSAGE_CHARS) {
        Some((end, _)) => format!("{}…", &line[..end]),
        None => line,
    }
}

/// An input error naming `path`, its message made one short line
/// ([`one_short_line`]): messages quote names and values from the file.
pub(crate) fn input_error(path: &Path, message: impl AsRef<str>) -> Error {
    Error::input(path, one_short_line(message.as_ref()))
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
    // serde reports a fixed-length list with too many entries (a vertex of
    // four coordinates) as "trailing characters" at the first extra entry,
    // right after a comma; say what it is.
    let before: String = text
        .lines()
        .take(e.line())
        .enumerate()
        .map(
            |(i, l)| {
                if i + 1 == e.line() { l.chars().take(e.column().saturating_sub(1)).collect() } else { l.to_string() }
            },
        )
        .collect();
    let after_comma = before.trim_end().ends_with(',');
    if message == "trailing characters" && after_comma {
        return format!(
            "wrong content at {}: this list has more entries than expected here",
            position(e.line(), e.column())
        );
    }
    let kind = match e.classify() {
        serde_json::error::Category::Data => "wrong content",
        _ => "malformed JSON",
    };
    let misspelt = message
        .strip_prefix("missing field `")
        .and_then(|rest| rest.split('`').next())
        .and_then(|field| key_like(text, field))
        .map_or_else(String::new, |key| format!(" (the file's {key:?} is not read: misspelt?)"));
    format!("{kind} at {}: {}{misspelt}", position(e.line(), e.column()), plain_type_names(message))
}

/// serde's type names in `message` in words: `expected f32` → `expected a
/// number`, `expected struct SegmentParams` → `expected a table`.
pub(crate) fn plain_type_names(message: &str) -> String {
    [
        ("expected f32", "expected a number"),
        ("expected f64", "expected a number"),
        ("expected usize", "expected a whole number from 0 to 18446744073709551615"),
        ("expected u64", "expected a whole number from 0 to 18446744073709551615"),
        ("expected u32", "expected a whole number from 0 to 4294967295"),
        ("expected u16", "expected a whole number from 0 to 65535"),
        ("expected u8", "expected a whole number from 0 to 255"),
        ("expected i64", "expected an integer"),
        ("expected i32", "expected an integer"),
    ]
    .iter()
    .fold(message.to_string(), |m, (rust, plain)| m.replace(rust, plain))
    .split("expected struct ")
    .enumerate()
    .map(|(i, part)| match i {
        0 => part.to_string(),
        // The struct's name, up to the end of its word, is a table.
        _ => format!("expected a table{}", part.trim_start_matches(|c: char| c.is_alphanumeric() || c == '_')),
    })
    .collect()
}

/// A key of an object in JSON `text`, other than `field`, spelt within two
/// edits of it (`"widht"` for a missing `"width"`).
fn key_like(text: &str, field: &str) -> Option<String> {
    fn walk(value: &serde_json::Value, field: &str) -> Option<String> {
        match value {
            serde_json::Value::Object(map) => map
                .keys()
                .find(|key| *key != field && strsim::damerau_levenshtein(key, field) <= 2)
                .cloned()
                .or_else(|| map.values().find_map(|v| walk(v, field))),
            serde_json::Value::Array(items) => items.iter().find_map(|v| walk(v, field)),
            _ => None,
        }
    }
    walk(&serde_json::from_str(text).ok()?, field)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Keys the reader does not know are found at any depth; empty ones
    /// and known ones are not listed.
    #[test]
    fn ignored_keys_are_listed_with_their_paths() {
        let original = serde_json::json!({
            "name": "box", "joint": [{"name": "lid"}], "pose": null, "extra": [],
            "joints": [{"name": "lid", "type": "prismatic"}, {"name": "arm"}]
        });
        let parsed = serde_json::json!({"name": "box", "joints": [{"name": "lid"}, {"name": "arm"}]});
        assert_eq!(ignored_keys(&original, &parsed), ["joint", "joints[0].type"]);
        assert!(ignored_keys(&parsed, &parsed).is_empty());
    }

    /// Devices and folders are refused before a byte is read, and a file
    /// or a line longer than the limit is refused once the limit is passed:
    /// no input is read without end.
    #[test]
    fn inputs_are_files_of_bounded_size() {
        let dev_zero = Path::new("/dev/zero");
        let e = read_text(dev_zero).unwrap_err().to_string();
        assert!(e.contains("/dev/zero") && e.contains("is a device"), "{e}");
        let e = read_jsonl::<serde_json::Value>(dev_zero).unwrap_err().to_string();
        assert!(e.contains("is a device"), "{e}");
        let dir = std::env::temp_dir();
        let e = read_text(&dir).unwrap_err().to_string();
        assert!(e.contains("is a folder"), "{e}");
        let e = read_jsonl::<serde_json::Value>(&dir).unwrap_err().to_string();
        assert!(e.contains("is a folder"), "{e}");

        let path = dir.join(format!("pipetrack-bounded-{}.jsonl", std::process::id()));
        fs::write(&path, "{\"frame\": 0}\n{\"frame\": 1, \"pad\": \"xxxxxxxxxxxxxxxxxxxx\"}\n").unwrap();
        assert_eq!(read_text_at_most(&path, 64).unwrap().len(), 57);
        let e = read_text_at_most(&path, 56).unwrap_err().to_string();
        assert!(e.contains("too large: more than 56 bytes"), "{e}");
        assert_eq!(read_jsonl_lines_at_most::<serde_json::Value>(&path, 44).unwrap().len(), 2);
        let e = read_jsonl_lines_at_most::<serde_json::Value>(&path, 43).unwrap_err().to_string();
        assert!(e.contains("line 2: too long: more than 43 bytes"), "{e}");
        // A byte-order mark is skipped.
        fs::write(&path, "\u{feff}{\"frame\": 0}\n").unwrap();
        assert_eq!(read_text(&path).unwrap(), "{\"frame\": 0}\n");
        assert_eq!(read_jsonl::<serde_json::Value>(&path).unwrap()[0].1["frame"], 0);
        fs::remove_file(&path).unwrap();
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

    #[test]
    fn messages_are_one_short_line_whatever_they_quote() {
        assert_eq!(one_short_line("unknown variant `los\nt`"), r"unknown variant `los\nt`");
        assert_eq!(one_short_line("name \"a\u{2028}b\""), r#"name "a\u{2028}b""#);
        let long = format!("invalid type: string \"{}\", expected f64", "x".repeat(5000));
        assert_eq!(one_short_line(&long), format!("invalid type: string \"{}…\", expected f64", "x".repeat(31)));
        let many = "ab ".repeat(1000);
        assert_eq!(one_short_line(&many).chars().count(), MAX_MESSAGE_CHARS + 1);
        assert_eq!(one_short_line("fx = -1e308 is not > 0"), "fx = -1e308 is not > 0");
    }

    #[test]
    fn a_list_too_long_is_named_not_trailing_characters() {
        #[derive(Debug, serde::Deserialize)]
        #[allow(dead_code)]
        struct Model {
            vertices: Vec<[f64; 3]>,
        }
        let text = r#"{"vertices": [[0, 0, 0], [1, 0, 0, 7]]}"#;
        let e = serde_json::from_str::<Model>(text).unwrap_err();
        let msg = describe_json_error(text, &e, None);
        assert_eq!(msg, "wrong content at line 1 column 36: this list has more entries than expected here");
        let text = "{\"vertices\": []} x";
        let e = serde_json::from_str::<Model>(text).unwrap_err();
        assert!(describe_json_error(text, &e, None).contains("trailing characters"));
    }

    #[test]
    fn a_value_of_the_wrong_type_is_described_in_words() {
        #[derive(Debug, serde::Deserialize)]
        #[allow(dead_code)]
        struct Camera {
            width: u32,
            fx: f64,
        }
        for (text, expected) in [
            (r#"{"width": "x", "fx": 1}"#, "a whole number from 0 to 4294967295"),
            (r#"{"width": 1099511627776, "fx": 1}"#, "a whole number from 0 to 4294967295"),
            (r#"{"width": 1, "fx": "y"}"#, "a number"),
        ] {
            let e = serde_json::from_str::<Camera>(text).unwrap_err();
            let msg = describe_json_error(text, &e, None);
            assert!(msg.ends_with(&format!("expected {expected}")), "{msg}");
        }
        assert_eq!(
            plain_type_names("invalid type: integer `3`, expected struct SegmentParams; in `segments`"),
            "invalid type: integer `3`, expected a table; in `segments`"
        );
    }
}
