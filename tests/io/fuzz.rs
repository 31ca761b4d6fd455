//! Bounded property tests of every parser of user files, runnable on stable
//! (the cargo-fuzz targets under `fuzz/` drive the same entry points with
//! libFuzzer on nightly).
//!
//! For each parser a seeded ChaCha RNG generates inputs: mutations of valid
//! seed files (byte flips, truncations, duplicated, deleted and swapped lines
//! and tokens, huge and non-finite numbers, deep nesting, wrong types, lists
//! of the wrong length, unicode, splices of two seeds), empty files and
//! purely random bytes. Each input goes through the library's public entry
//! point, written to a file where that takes a path (a tracker's config:
//! the tracker is built and, when it is, tracks a small sequence, which
//! must succeed). Every input must give
//! `Ok` or an [`Error::Input`] naming the file with a short one-line
//! message, without a panic, and quickly: a case slower than [`SLOW_CASE`]
//! fails, and a watchdog fails the test with the input when a case runs
//! longer than [`HANG`]. Seeds are fixed, so a failure reproduces; the
//! input of a failing case is written under `CARGO_TARGET_TMPDIR`.

use std::fs;
use std::io::Cursor;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use pipetrack::cli::import_visp::{loaded_files, read_camera, read_pose_file};
use pipetrack::cli::score::{read_predictions, score_file};
use pipetrack::io::cao::read_cao;
use pipetrack::io::formats::TruthFrame;
use pipetrack::io::y4m::Y4mReader;
use pipetrack::track::make_tracker;
use pipetrack::{CpuBackend, Error, GrayImage, Sequence, track_frames};
use rand::seq::IndexedRandom;
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Inputs per parser, at most.
const CASES: usize = 5000;
/// Time box per parser: generation stops after this even if [`CASES`]
/// have not all run (the count run is printed).
const TIME_BOX: Duration = Duration::from_millis(1500);
/// A single input taking longer than this fails the test.
const SLOW_CASE: Duration = Duration::from_secs(1);
/// A single input running longer than this is a hang: the watchdog fails.
const HANG: Duration = Duration::from_secs(20);
/// Largest generated input, bytes.
const MAX_INPUT: usize = 1 << 18;
/// Longest error message accepted, bytes: one line a user reads.
const MAX_MESSAGE: usize = 600;

// ---------------------------------------------------------------------------
// The harness.

/// What one parser's run needs: a name, seed files, words worth splicing in,
/// and the check of one input.
struct Target<C> {
    name: &'static str,
    rng_seed: u64,
    seeds: Vec<Vec<u8>>,
    dictionary: Vec<String>,
    /// Builds the fixture (good files in the target's scratch folder) once,
    /// in the worker.
    setup: fn(&Path) -> C,
    /// Runs one input; `Err` describes a violated property.
    check: fn(&C, &[u8]) -> Result<(), String>,
}

enum Report {
    Tick,
    Done { cases: usize, elapsed: Duration, checking: Duration, slowest: (Duration, usize) },
    Failed { case: usize, message: String },
}

/// Run `target` for up to [`CASES`] inputs or [`TIME_BOX`], panicking with
/// the input of the first case that breaks a property.
fn run<C: 'static>(target: Target<C>) {
    let name = target.name;
    let current: Arc<Mutex<(usize, Vec<u8>)>> = Arc::new(Mutex::new((0, Vec::new())));
    let (tx, rx) = mpsc::channel();
    let shared = Arc::clone(&current);
    // A plain thread, not a scoped one: a hung worker must not keep the
    // test from failing.
    std::thread::spawn(move || {
        let folder = scratch(target.name);
        let context = (target.setup)(&folder);
        let report = run_cases(&target, &context, &shared, &tx);
        // The folder goes before the last report, after which the test
        // binary may exit.
        drop(context);
        drop(folder);
        let _ = tx.send(report);
    });
    loop {
        match rx.recv_timeout(HANG) {
            Ok(Report::Tick) => {}
            Ok(Report::Done { cases, elapsed, checking, slowest }) => {
                println!(
                    "fuzz {name}: {cases} inputs in {:.2} s ({:.2} s parsing, slowest {:.1} ms for {} bytes), \
                     all Ok or one-line input errors",
                    elapsed.as_secs_f64(),
                    checking.as_secs_f64(),
                    slowest.0.as_secs_f64() * 1e3,
                    slowest.1
                );
                assert!(cases > 0, "fuzz {name}: no input ran");
                return;
            }
            Ok(Report::Failed { case, message }) => {
                let input = current.lock().map(|slot| slot.1.clone()).unwrap_or_default();
                fail(name, case, &input, &message);
            }
            Err(_) => {
                let (case, input) = current.lock().map(|slot| slot.clone()).unwrap_or_default();
                fail(name, case, &input, &format!("no answer within {HANG:?}: a hang"));
            }
        }
    }
}

/// The inputs of `target` on `context`, one after another: `current` holds
/// the case running (for the watchdog), a tick goes to `tx` after each, and
/// the result is the report of the first failing case or of them all.
fn run_cases<C>(
    target: &Target<C>,
    context: &C,
    current: &Mutex<(usize, Vec<u8>)>,
    tx: &mpsc::Sender<Report>,
) -> Report {
    let (seed, cases_wanted, time_box) = budget(target.rng_seed);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let start = Instant::now();
    let mut cases = 0;
    let mut checking = Duration::ZERO;
    let mut slowest = (Duration::ZERO, 0);
    while cases < cases_wanted && start.elapsed() < time_box {
        let input = generate(&mut rng, &target.seeds, &target.dictionary);
        if let Ok(mut slot) = current.lock() {
            *slot = (cases, input.clone());
        }
        let t0 = Instant::now();
        let outcome = catch_unwind(AssertUnwindSafe(|| (target.check)(context, &input)));
        let took = t0.elapsed();
        checking += took;
        slowest = slowest.max((took, input.len()));
        let failure = match outcome {
            Err(panic) => Some(format!("panicked: {}", panic_text(&panic))),
            Ok(Err(message)) => Some(message),
            Ok(Ok(())) if took > SLOW_CASE => Some(format!("took {took:?} (limit {SLOW_CASE:?})")),
            Ok(Ok(())) => None,
        };
        if let Some(message) = failure {
            return Report::Failed { case: cases, message: format!("(seed {seed:#x}) {message}") };
        }
        cases += 1;
        let _ = tx.send(Report::Tick);
    }
    Report::Done { cases, elapsed: start.elapsed(), checking, slowest }
}

/// The RNG seed, the number of inputs and the time box of a run: the
/// target's seed, [`CASES`] and [`TIME_BOX`], unless `PIPETRACK_FUZZ_SEED`
/// (mixed into every target's seed) or `PIPETRACK_FUZZ_CASES` (the time box
/// then grows in proportion) ask for a longer or another run.
fn budget(target_seed: u64) -> (u64, usize, Duration) {
    let var = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<u64>().ok());
    let seed = var("PIPETRACK_FUZZ_SEED").map_or(target_seed, |s| target_seed ^ s.rotate_left(17));
    match var("PIPETRACK_FUZZ_CASES").and_then(|c| usize::try_from(c).ok()) {
        Some(cases) => (seed, cases, TIME_BOX.mul_f64(cases as f64 / CASES as f64).max(TIME_BOX)),
        None => (seed, CASES, TIME_BOX),
    }
}

fn panic_text(panic: &Box<dyn std::any::Any + Send>) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(non-string payload)".to_string())
}

/// Save the failing input and panic with it (shortened) and the case number.
fn fail(name: &str, case: usize, input: &[u8], message: &str) -> ! {
    let saved = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("fuzz-{name}-case{case}.bin"));
    let _ = fs::write(&saved, input);
    let text = String::from_utf8_lossy(input);
    let shown: String = text.chars().take(1500).collect();
    panic!(
        "fuzz {name}, case {case}: {message}\ninput ({} bytes, saved to {}):\n{shown:?}",
        input.len(),
        saved.display()
    );
}

/// `result` is `Ok`, or an input error naming one of `files` with a
/// non-empty, short, one-line message.
fn check_result<T>(result: pipetrack::Result<T>, files: &[&Path]) -> Result<(), String> {
    match result {
        Ok(_) => Ok(()),
        Err(Error::Input { path, message }) => {
            if !files.iter().any(|f| *f == path) {
                return Err(format!("the error names {} (expected one of {files:?}): {message}", path.display()));
            }
            if message.trim().is_empty() {
                return Err(format!("{}: empty message", path.display()));
            }
            if message.contains(['\n', '\r']) {
                return Err(format!("message spans lines: {message:?}"));
            }
            if message.len() > MAX_MESSAGE {
                let start: String = message.chars().take(200).collect();
                return Err(format!("message of {} bytes (at most {MAX_MESSAGE}): {start:?}…", message.len()));
            }
            Ok(())
        }
        Err(other) => Err(format!("not an input error: {other:?}")),
    }
}

// ---------------------------------------------------------------------------
// Generating inputs.

/// Numbers and values that break parsers: huge, tiny, non-finite, negative,
/// overflowing integers, wrong types, lists of other lengths.
const INTERESTING: &[&str] = &[
    "0",
    "-0",
    "-1",
    "1.5",
    "1e308",
    "-1e308",
    "1e309",
    "1e999",
    "4.9e-324",
    "1e-400",
    "NaN",
    "nan",
    "Infinity",
    "-Infinity",
    "inf",
    "-inf",
    "255",
    "65536",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999999999999999",
    "1.0e+99999999999",
    "0x10",
    "\"\"",
    "\"x\"",
    "true",
    "false",
    "null",
    "[]",
    "{}",
    "[[]]",
    "[0]",
    "[0,0]",
    "[0,0,0,0]",
    "[1,2,3,4,5,6,7,8,9]",
];

/// The numbers of [`INTERESTING`].
const NUMBERS: &[&str] = &[
    "0",
    "-0",
    "-1",
    "1.5",
    "1e308",
    "-1e308",
    "1e999",
    "4.9e-324",
    "NaN",
    "inf",
    "65536",
    "4294967296",
    "9223372036854775807",
    "18446744073709551615",
    "18446744073709551616",
    "1000000000000",
];

/// Text that is not plain ASCII, including escapes JSON turns into control
/// characters and bytes that are not UTF-8.
const UNICODE: &[&[u8]] = &[
    "é".as_bytes(),
    "\u{1F600}".as_bytes(),
    "\u{202E}".as_bytes(),
    "\u{FEFF}".as_bytes(),
    "\u{2028}".as_bytes(),
    "\u{0}".as_bytes(),
    b"\\u0000",
    b"\\n",
    b"\\r\\n",
    b"\\ud800",
    b"\r",
    b"\t",
    b"\xC3",
    b"\xFF\xFE",
    b"\xED\xA0\x80",
];

/// One input: mostly a mutated seed, sometimes empty or random bytes.
fn generate(rng: &mut ChaCha8Rng, seeds: &[Vec<u8>], dictionary: &[String]) -> Vec<u8> {
    match rng.random_range(0..100) {
        0..3 => Vec::new(),
        3..5 => b" \n\t\n".to_vec(),
        5..10 => {
            let mut bytes = vec![0; rng.random_range(0..512)];
            rng.fill_bytes(&mut bytes);
            bytes
        }
        10..15 => {
            // Random bytes from the seeds' own alphabet: plausible-looking noise.
            let seed = pick(rng, seeds);
            (0..rng.random_range(0..512)).map(|_| seed[rng.random_range(0..seed.len().max(1))]).collect()
        }
        _ => {
            let mut data = pick(rng, seeds).clone();
            for _ in 0..rng.random_range(1..=4) {
                mutate(rng, &mut data, seeds, dictionary);
                data.truncate(MAX_INPUT);
            }
            data
        }
    }
}

fn pick<'a>(rng: &mut ChaCha8Rng, seeds: &'a [Vec<u8>]) -> &'a Vec<u8> {
    seeds.choose(rng).expect("a target has seeds")
}

/// Byte ranges of the lines of `data` (without their `\n`).
fn lines(data: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, &b) in data.iter().enumerate() {
        if b == b'\n' {
            out.push((start, i));
            start = i + 1;
        }
    }
    if start < data.len() {
        out.push((start, data.len()));
    }
    out
}

/// Byte ranges of the words of `data`: runs of letters, digits and `_.+-`.
fn words(data: &[u8]) -> Vec<(usize, usize)> {
    let is_word = |b: u8| b.is_ascii_alphanumeric() || b"_.+-".contains(&b);
    let mut out = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if is_word(data[i]) {
            let start = i;
            while i < data.len() && is_word(data[i]) {
                i += 1;
            }
            out.push((start, i));
        } else {
            i += 1;
        }
    }
    out
}

/// A replacement value: interesting in general, or one of the target's words.
fn value(rng: &mut ChaCha8Rng, dictionary: &[String]) -> Vec<u8> {
    if !dictionary.is_empty() && rng.random_bool(0.4) {
        return dictionary.choose(rng).map(|s| s.as_bytes().to_vec()).unwrap_or_default();
    }
    match rng.random_range(0..20) {
        0 => "9".repeat(rng.random_range(20..400)).into_bytes(),
        1 => format!("1{}", "0".repeat(rng.random_range(300..400))).into_bytes(),
        _ => INTERESTING.choose(rng).map(|s| s.as_bytes().to_vec()).unwrap_or_default(),
    }
}

fn mutate(rng: &mut ChaCha8Rng, data: &mut Vec<u8>, seeds: &[Vec<u8>], dictionary: &[String]) {
    let len = data.len();
    let at = |rng: &mut ChaCha8Rng| rng.random_range(0..=len);
    match rng.random_range(0..18) {
        // Flip a bit.
        0 if len > 0 => {
            let i = rng.random_range(0..len);
            data[i] ^= 1 << rng.random_range(0..8);
        }
        // Set a byte to a syntax character.
        1 if len > 0 => {
            let i = rng.random_range(0..len);
            data[i] = *b"\"[]{},:.-+e#=\n 0\0\xff".choose(rng).unwrap_or(&b' ');
        }
        // Insert random bytes.
        2 => {
            let mut bytes = vec![0; rng.random_range(1..8)];
            rng.fill_bytes(&mut bytes);
            let i = at(rng);
            data.splice(i..i, bytes);
        }
        // Delete a range.
        3 if len > 0 => {
            let i = rng.random_range(0..len);
            let j = (i + rng.random_range(1..32)).min(len);
            data.drain(i..j);
        }
        // Truncate.
        4 => data.truncate(at(rng)),
        // Duplicate a line, now and then many times.
        5 => {
            let ls = lines(data);
            if let Some(&(s, e)) = ls.choose(rng) {
                let times = if rng.random_bool(0.1) { rng.random_range(100..3000) } else { rng.random_range(1..4) };
                let mut line = data[s..e].to_vec();
                line.push(b'\n');
                let copies: Vec<u8> = line.repeat(times);
                let end = (e + 1).min(len);
                data.splice(end..end, copies);
            }
        }
        // Delete a line.
        6 => {
            let ls = lines(data);
            if let Some(&(s, e)) = ls.choose(rng) {
                data.drain(s..(e + 1).min(len));
            }
        }
        // Swap two lines.
        7 => {
            let ls = lines(data);
            if ls.len() >= 2 {
                let (a, b) = (rng.random_range(0..ls.len()), rng.random_range(0..ls.len()));
                let (a, b) = (a.min(b), a.max(b));
                if a != b {
                    let (la, lb) = (data[ls[a].0..ls[a].1].to_vec(), data[ls[b].0..ls[b].1].to_vec());
                    data.splice(ls[b].0..ls[b].1, la);
                    data.splice(ls[a].0..ls[a].1, lb);
                }
            }
        }
        // Replace a word (a number, a key, a keyword) with a value.
        8 => {
            if let Some(&(s, e)) = words(data).choose(rng) {
                let v = value(rng, dictionary);
                data.splice(s..e, v);
            }
        }
        // Replace a number (a count, an index, a coordinate, a size) with
        // an interesting number.
        9 => {
            let numbers: Vec<(usize, usize)> = words(data)
                .into_iter()
                .filter(|&(s, e)| data[s..e].iter().find(|&&b| b != b'-').is_some_and(u8::is_ascii_digit))
                .collect();
            if let Some(&(s, e)) = numbers.choose(rng) {
                let v = NUMBERS.choose(rng).map_or(b"0".to_vec(), |n| n.as_bytes().to_vec());
                data.splice(s..e, v);
            }
        }
        // Delete a word.
        10 => {
            if let Some(&(s, e)) = words(data).choose(rng) {
                data.drain(s..e);
            }
        }
        // Duplicate a word with the separator after it (a list one longer).
        11 => {
            if let Some(&(s, e)) = words(data).choose(rng) {
                let e2 = (e + 1).min(len);
                let copy = data[s..e2].to_vec();
                data.splice(e2..e2, copy);
            }
        }
        // Deep nesting around a point, closed or not.
        12 => {
            let depth = *[10usize, 100, 129, 1000, 20_000].choose(rng).unwrap_or(&10);
            let (open, close): (&[u8], &[u8]) =
                *[(&b"["[..], &b"]"[..]), (b"{\"a\":", b"}"), (b"{a=", b"}"), (b"a.", b"")]
                    .choose(rng)
                    .unwrap_or(&(&b"["[..], &b"]"[..]));
            let i = at(rng);
            let mut inner = open.repeat(depth);
            inner.extend_from_slice(b"0");
            if rng.random_bool(0.7) {
                inner.extend(close.repeat(depth));
            }
            data.splice(i..i, inner);
        }
        // Insert unicode or an escape.
        13 => {
            let u = UNICODE.choose(rng).copied().unwrap_or(b"");
            let i = at(rng);
            data.splice(i..i, u.iter().copied());
        }
        // Splice the start of this input with the end of a seed.
        14 => {
            let other = pick(rng, seeds);
            let j = rng.random_range(0..=other.len());
            data.truncate(at(rng));
            data.extend_from_slice(&other[j..]);
        }
        // A list one longer or shorter: add or remove `,<number>`.
        15 => {
            if rng.random_bool(0.5) {
                let ws = words(data);
                if let Some(&(_, e)) = ws.choose(rng) {
                    data.splice(e..e, b",0".iter().copied());
                }
            } else if let Some(i) = (0..len).filter(|&i| data[i] == b',').collect::<Vec<_>>().choose(rng) {
                let j = data[i + 1..].iter().position(|&b| b == b',' || b == b']').map_or(len, |p| i + 1 + p);
                data.drain(*i..j);
            }
        }
        // Insert a dictionary word or interesting value anywhere.
        16 => {
            let v = value(rng, dictionary);
            let i = at(rng);
            data.splice(i..i, v);
        }
        // Replace the whole input by another seed (then mutated further).
        _ => *data = pick(rng, seeds).clone(),
    }
}

fn dict(words: &[&str]) -> Vec<String> {
    words.iter().map(|s| s.to_string()).collect()
}

fn seeds(texts: &[&str]) -> Vec<Vec<u8>> {
    texts.iter().map(|s| s.as_bytes().to_vec()).collect()
}

// ---------------------------------------------------------------------------
// Fixtures.

/// Write `input` to `path` as a new file. Removing the old one first spares
/// ext4 the flush it does when a file is truncated and rewritten (which
/// costs milliseconds per case).
fn put(path: &Path, input: &[u8]) -> Result<(), String> {
    let _ = fs::remove_file(path);
    fs::write(path, input).map_err(|e| format!("writing the input to {}: {e}", path.display()))
}

/// A new scratch folder for the target or test `name`.
fn scratch(name: &str) -> crate::common::Scratch {
    crate::common::scratch("fuzz", name)
}

const CAMERA: &str = r#"{"width":4,"height":3,"fx":100.0,"fy":100.0,"cx":1.5,"cy":1.0}"#;
const SQUARE: &str = r#"{"name":"square","units":"m",
 "vertices":[[0,0,0],[0.1,0,0],[0.1,0.1,0],[0,0.1,0]],
 "edges":[[0,1],[1,2],[2,3],[3,0]],
 "faces":[[0,1,2,3]]}"#;
const LID_BOX: &str = r#"{"name":"box","units":"m",
 "vertices":[[0,0,0],[0.1,0,0],[0.1,0.1,0],[0,0.1,0],[0,0,0.1],[0.1,0,0.1]],
 "edges":[[0,1],[1,2],[2,3],[3,0],[0,4],[1,5],[4,5]],
 "faces":[[0,3,2,1],[0,1,5,4]],
 "joints":[{"name":"lid","origin":[0,0,0],"axis":[1,0,0],"vertices":[4,5],"min":-1.5,"max":1.5}]}"#;
const INIT: &str = r#"{"pose":{"rotation":[0,0,0],"translation":[0,0,1]},"corners":[[1,1],[2,1],[2,2],[1,2]]}"#;

/// A good 4×3 sequence folder with the square model and two frames.
struct SeqFixture {
    dir: PathBuf,
    camera: PathBuf,
    model: PathBuf,
    init: PathBuf,
    frame: PathBuf,
}

fn sequence_fixture(folder: &Path) -> SeqFixture {
    let dir = folder.to_path_buf();
    fs::create_dir_all(dir.join("frames")).expect("frames folder");
    let f = SeqFixture {
        camera: dir.join("camera.json"),
        model: dir.join("model.json"),
        init: dir.join("init.json"),
        frame: dir.join("frames/000000.png"),
        dir,
    };
    fs::write(&f.camera, CAMERA).expect("camera");
    fs::write(&f.model, SQUARE).expect("model");
    fs::write(&f.init, INIT).expect("init");
    for k in 0..2u8 {
        let data: Vec<u8> = (0..12).map(|i| 10 * k + i).collect();
        image::save_buffer(f.dir.join(format!("frames/00000{k}.png")), &data, 4, 3, image::ExtendedColorType::L8)
            .expect("frame");
    }
    Sequence::open(&f.dir, false).expect("the fixture is a good sequence");
    f
}

impl SeqFixture {
    /// Write `input` over `file`, open the folder, and restore nothing: each
    /// target fuzzes one file and leaves the others good.
    fn open_with(&self, file: &Path, input: &[u8]) -> Result<(), String> {
        put(file, input)?;
        let files = [self.camera.as_path(), self.model.as_path(), self.init.as_path(), self.frame.as_path()];
        check_result(Sequence::open(&self.dir, false), &files)
    }
}

const JSON_WORDS: &[&str] = &[
    "\"width\"",
    "\"height\"",
    "\"fx\"",
    "\"vertices\"",
    "\"edges\"",
    "\"faces\"",
    "\"joints\"",
    "\"units\"",
    "\"px\"",
    "\"pose\"",
    "\"corners\"",
    "\"params\"",
    "\"rotation\"",
    "\"translation\"",
    "\"visible\"",
    "\"frame\"",
    "\"status\"",
    "\"tracking\"",
    "\"lost\"",
    "\"covariance\"",
    "\"ms\"",
    "\"a\\nb\"",
    "\"\\u0000\"",
];

// ---------------------------------------------------------------------------
// The targets.

#[test]
fn fuzz_camera_json() {
    run(Target {
        name: "camera_json",
        rng_seed: 0xC0FF_EE01,
        seeds: seeds(&[CAMERA, r#"{"width":640,"height":480,"fx":500,"fy":500,"cx":319.5,"cy":239.5}"#]),
        dictionary: dict(JSON_WORDS),
        setup: sequence_fixture,
        check: |f, input| f.open_with(&f.camera, input),
    });
}

#[test]
fn fuzz_model_json() {
    run(Target {
        name: "model_json",
        rng_seed: 0xC0FF_EE02,
        seeds: seeds(&[SQUARE, LID_BOX]),
        dictionary: dict(JSON_WORDS),
        setup: sequence_fixture,
        check: |f, input| f.open_with(&f.model, input),
    });
}

#[test]
fn fuzz_init_json() {
    run(Target {
        name: "init_json",
        rng_seed: 0xC0FF_EE03,
        seeds: seeds(&[
            INIT,
            r#"{"corners":[[1,1],[2,1],[2,2],[1,2]]}"#,
            r#"{"pose":{"rotation":[0.1,-0.2,0.3],"translation":[0.01,0,0.5]},"params":[],"camera_motion":[0,0,0,0,0,0]}"#,
        ]),
        dictionary: dict(JSON_WORDS),
        setup: sequence_fixture,
        check: |f, input| f.open_with(&f.init, input),
    });
}

const TRUTH: &str = "{\"frame\":0,\"visible\":[true,true,false,true],\"corners\":[[1,1],[2,1],[2,2],[1,2]],\
\"pose\":{\"rotation\":[0,0,0],\"translation\":[0,0,1]}}
{\"frame\":1,\"visible\":true,\"corners\":[[1.5,1],[2.5,1],[2.5,2],[1.5,2]],\"occluded_fraction\":0.25}
";

struct TruthFixture {
    seq: Sequence,
    truth: PathBuf,
    model: PathBuf,
}

#[test]
fn fuzz_truth_jsonl() {
    run(Target {
        name: "truth_jsonl",
        rng_seed: 0xC0FF_EE04,
        seeds: seeds(&[TRUTH, "{\"frame\":0,\"visible\":false}\n\n{\"frame\":1}\n"]),
        dictionary: dict(JSON_WORDS),
        setup: |folder| {
            let f = sequence_fixture(folder);
            let seq = Sequence::open(&f.dir, false).expect("good sequence");
            TruthFixture { truth: seq.truth_path(), model: f.model, seq }
        },
        check: |f, input| {
            put(&f.truth, input)?;
            check_result(f.seq.read_truth(), &[&f.truth, &f.model])
        },
    });
}

const PREDICTIONS: &str = "{\"frame\":0,\"status\":\"tracking\",\"corners\":[[1,1],[2,1],[2,2],[1,2]],\
\"pose\":{\"rotation\":[0,0,0],\"translation\":[0,0,1]},\"params\":[],\"covariance\":[1,0,0,1],\"ms\":1.5}
{\"frame\":1,\"status\":\"lost\",\"corners\":[[1.5,1],[2.5,1],[2.5,2],[1.5,2]],\"ms\":0.5,\"ess\":3}
";

struct PredictionFixture {
    truth: Vec<TruthFrame>,
    path: PathBuf,
}

#[test]
fn fuzz_predictions_jsonl() {
    run(Target {
        name: "predictions_jsonl",
        rng_seed: 0xC0FF_EE05,
        seeds: seeds(&[PREDICTIONS, "{\"frame\":0,\"status\":\"lost\",\"corners\":[],\"ms\":0}\n"]),
        dictionary: dict(JSON_WORDS),
        setup: |folder| {
            let f = sequence_fixture(folder);
            fs::write(f.dir.join("truth.jsonl"), TRUTH).expect("truth");
            let truth = Sequence::open(&f.dir, false).and_then(|s| s.read_truth()).expect("good truth");
            PredictionFixture { truth, path: f.dir.join("pred.jsonl") }
        },
        check: |f, input| {
            put(&f.path, input)?;
            check_result(read_predictions(&f.path), &[&f.path])?;
            check_result(score_file(&f.truth, &f.path), &[&f.path])
        },
    });
}

const CUBE_CAO: &str = include_str!("../../assets/cube.cao");
const SQUARE_FROM_LINES_CAO: &str = "V1
4
0 0 0
1 0 0
1 1 0
0 1 0
4
1 0
1 2
3 2
0 3   name=\"edge # 3\"
1
4 0 1 2 3
0
0
0
";
const CAO_WITH_LOAD: &str = "V1
load(\"part.cao\")
4
0 0 0
1 0 0
1 1 0
0 1 0
0
0
1
4 0 1 2 3
";

struct CaoFixture {
    dir: PathBuf,
    path: PathBuf,
}

#[test]
fn fuzz_cao() {
    run(Target {
        name: "cao",
        rng_seed: 0xC0FF_EE06,
        seeds: seeds(&[CUBE_CAO, SQUARE_FROM_LINES_CAO, CAO_WITH_LOAD]),
        dictionary: dict(&[
            "V1",
            "V2",
            "load(\"part.cao\")",
            "load(\"sub/part.cao\")",
            "load(\"missing.cao\")",
            "load(\"model.cao\")",
            "load(\"../part.cao\")",
            "load(",
            "name=\"a b\"",
            "\"",
            "#",
            "=",
        ]),
        setup: |folder| {
            let dir = folder.to_path_buf();
            fs::create_dir_all(dir.join("sub")).expect("sub folder");
            fs::write(dir.join("part.cao"), SQUARE_FROM_LINES_CAO).expect("include");
            fs::write(dir.join("sub/part.cao"), "V1\nload(\"../part.cao\")\n0\n0\n0\n0\n").expect("include");
            CaoFixture { path: dir.join("model.cao"), dir }
        },
        check: |f, input| {
            put(&f.path, input)?;
            let included = [f.dir.join("part.cao"), f.dir.join("sub/part.cao"), f.dir.join("missing.cao")];
            let mut files = vec![f.path.as_path()];
            files.extend(included.iter().map(PathBuf::as_path));
            check_result(read_cao(&f.path), &files)?;
            // What import-visp copies beside the model: every loaded file.
            check_result(loaded_files(&f.path), &files)
        },
    });
}

const CUBE_OBJ: &str = "# a unit cube of triangles
o cube
mtllib cube.mtl
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
v 0 0 1
v 1 0 1
v 0 1 1
v 1 1 1 0.5 0.5 0.5
vn 0 0 -1
vt 0 0
g sides
s off
usemtl grey
f 1//1 3//1 4//1
f 1//1 4//1 2//1
f 5 6 8
f 5 8 7
f 1/1 2/1 6/1
f 1/1 6/1 5/1
f 3/1/1 7/1/1 8/1/1
f -6/1/1 -1/1/1 -5/1/1
f 1 5 7 3
f 2 4 8 6
l 1 8
";

#[test]
fn fuzz_obj() {
    run(Target {
        name: "obj",
        rng_seed: 0x0B1E_C7F0,
        seeds: seeds(&[CUBE_OBJ]),
        dictionary: dict(&[
            "v", "f", "l", "vn", "vt", "o", "g", "s", "-1", "0", "/", "//", "#", "curv", "nan", "1e308",
        ]),
        setup: |folder| folder.join("model.obj"),
        check: |path, input| {
            put(path, input)?;
            check_result(pipetrack::io::obj::read_obj(path), &[path])
        },
    });
}

/// A Y4M stream: `header`, then `frames` frames of `w`×`h` luma plus `extra`
/// chroma bytes each.
fn y4m(header: &str, w: usize, h: usize, extra: usize, frames: usize) -> Vec<u8> {
    let mut s = format!("{header}\n").into_bytes();
    for k in 0..frames {
        s.extend_from_slice(if k == 1 { b"FRAME Ixyz\n" } else { b"FRAME\n" });
        s.extend((0..w * h + extra).map(|i| (i * 7 + k) as u8));
    }
    s
}

fn y4m_seeds() -> Vec<Vec<u8>> {
    vec![
        y4m("YUV4MPEG2 W4 H3 F30:1 Ip A1:1 C420jpeg XYSCSS=420JPEG", 4, 3, 8, 3),
        y4m("YUV4MPEG2 W3 H2 Cmono", 3, 2, 0, 4),
        y4m("YUV4MPEG2 W5 H1 C444alpha", 5, 1, 15, 2),
        y4m("YUV4MPEG2 W5 H2 C411", 5, 2, 8, 2),
        y4m("YUV4MPEG2 H2 W2 C422 F25:1", 2, 2, 4, 2),
    ]
}

const Y4M_WORDS: &[&str] = &[
    "YUV4MPEG2",
    "FRAME",
    "W16384",
    "H16384",
    "W99999999999999999999",
    "H0",
    "W-1",
    "C420p10",
    "C444alpha",
    "Cmono",
    "C411",
    "Cfoo",
    "F1:0",
    "F:",
    "A0:0",
    "Ip",
    "X",
    "Q",
];

#[test]
fn fuzz_y4m_header() {
    run(Target {
        name: "y4m_header",
        rng_seed: 0xC0FF_EE07,
        seeds: y4m_seeds(),
        dictionary: dict(Y4M_WORDS),
        setup: |_| PathBuf::from("fuzz.y4m"),
        check: |name, input| check_result(Y4mReader::with_name(input, name), &[name]),
    });
}

#[test]
fn fuzz_y4m_frames() {
    run(Target {
        name: "y4m_frames",
        rng_seed: 0xC0FF_EE08,
        seeds: y4m_seeds(),
        dictionary: dict(Y4M_WORDS),
        setup: |_| PathBuf::from("fuzz.y4m"),
        check: |name, input| {
            let mut reader = match Y4mReader::with_name(Cursor::new(input.to_vec()), name) {
                Ok(r) => r,
                Err(e) => return check_result::<()>(Err(e), &[name]),
            };
            // Both ways of reading a frame: into a reused image, and as a new one.
            let mut image = GrayImage::new(0, 0);
            for k in 0.. {
                let next = if k % 2 == 0 {
                    reader.read_frame_into(&mut image)
                } else {
                    reader.next_frame().map(|f| f.is_some())
                };
                match next {
                    Ok(true) => {}
                    Ok(false) => return Ok(()),
                    Err(e) => return check_result::<()>(Err(e), &[name]),
                }
                if k > input.len() {
                    return Err(format!("{k} frames from {} bytes: the reader does not advance", input.len()));
                }
            }
            Ok(())
        },
    });
}

/// A 48×36 sequence of the square model, bright on a dark ground and moving
/// a pixel a frame, with its three frames and a config file path: what the
/// config targets build a tracker for and track.
struct ConfigFixture {
    seq: Sequence,
    frames: Vec<GrayImage>,
    path: PathBuf,
}

const TRACKING_CAMERA: &str = r#"{"width":48,"height":36,"fx":200.0,"fy":200.0,"cx":24.0,"cy":18.0}"#;
/// The 0.1 m square at 1 m, seen 20 px wide: corners (14, 8) to (34, 28).
const TRACKING_INIT: &str =
    r#"{"pose":{"rotation":[0,0,0],"translation":[-0.05,-0.05,1]},"corners":[[14,8],[34,8],[34,28],[14,28]]}"#;

fn config_fixture(folder: &Path) -> ConfigFixture {
    let dir = folder.to_path_buf();
    fs::create_dir_all(dir.join("frames")).expect("frames folder");
    fs::write(dir.join("camera.json"), TRACKING_CAMERA).expect("camera");
    fs::write(dir.join("model.json"), SQUARE).expect("model");
    fs::write(dir.join("init.json"), TRACKING_INIT).expect("init");
    let frames: Vec<GrayImage> = (0..3)
        .map(|k| {
            GrayImage::from_fn(
                48,
                36,
                |x, y| if (14 + k..34 + k).contains(&x) && (8..28).contains(&y) { 200 } else { 40 },
            )
        })
        .collect();
    for (k, frame) in frames.iter().enumerate() {
        let path = dir.join(format!("frames/00000{k}.png"));
        image::save_buffer(path, frame.data(), 48, 36, image::ExtendedColorType::L8).expect("frame");
    }
    let seq = Sequence::open(&dir, false).expect("the fixture is a good sequence");
    ConfigFixture { seq, frames, path: dir.join("config.toml") }
}

/// `input` as `tracker`'s config: building the tracker gives `Ok` or an
/// input error naming the file; a tracker built tracks the fixture's frames
/// without an error.
fn check_config(f: &ConfigFixture, tracker: &str, input: &[u8]) -> Result<(), String> {
    put(&f.path, input)?;
    let built = make_tracker(tracker, &f.seq, Some(&f.path));
    let Ok(mut built) = built else { return check_result(built, &[&f.path]) };
    let size = (f.seq.camera.width as usize, f.seq.camera.height as usize);
    let frames = f.frames.iter().map(Ok::<_, Error>);
    track_frames(built.as_mut(), &mut CpuBackend::new(), frames, size, |_, _, _| Ok(()))
        .map_err(|e| format!("tracking with an accepted config failed: {e}"))
}

fn config_seeds<P: serde::Serialize + Default>(tracker: &str, tweaks: &str) -> Vec<Vec<u8>> {
    let whole = toml::to_string(&P::default()).expect("defaults serialise");
    vec![
        whole.clone().into_bytes(),
        format!("[{tracker}]\n{whole}").into_bytes(),
        format!("# tweaks\n[{tracker}]\n{tweaks}\n").into_bytes(),
        tweaks.as_bytes().to_vec(),
    ]
}

const TOML_WORDS: &[&str] = &[
    "[motion-edge]",
    "[blue]",
    "[[blue]]",
    "motion-edge = 1",
    "blue = \"x\"",
    "nan",
    "+inf",
    "-inf",
    "1e400",
    "1_000",
    "0o777",
    "0b11",
    "1979-05-27T07:32:00Z",
    "'''",
    "\"\"\"",
    "{a=1}",
    "[1, \"a\"]",
];

#[test]
fn fuzz_config_motion_edge() {
    run(Target {
        name: "config_motion_edge",
        rng_seed: 0xC0FF_EE09,
        seeds: config_seeds::<pipetrack::MotionEdgeParams>(
            "motion-edge",
            "delta = 0.3\nsigma = 1.5\nmissing = \"last-measurement\"\nline_fit = \"across\"\nrefine_iterations = 0",
        ),
        dictionary: dict(TOML_WORDS),
        setup: config_fixture,
        check: |f, input| check_config(f, "motion-edge", input),
    });
}

#[test]
fn fuzz_config_blue() {
    run(Target {
        name: "config_blue",
        rng_seed: 0xC0FF_EE0A,
        seeds: config_seeds::<pipetrack::BlueParams>(
            "blue",
            "lambda = 0.7\nnominal_range = 2.5\nmax_edge_points = 10\ncorner_covariance = \"line-location\"",
        ),
        dictionary: dict(TOML_WORDS),
        setup: config_fixture,
        check: |f, input| check_config(f, "blue", input),
    });
}

#[test]
fn fuzz_config_condensation() {
    run(Target {
        name: "config_condensation",
        rng_seed: 0xC0FF_EE0B,
        seeds: config_seeds::<pipetrack::track::CondensationParams>(
            "condensation",
            "samples = 50\nsearch_spread_px = 2.0\nestimate = \"weighted-mean\"\ncamera_motion = [0.001, 0, 0, 0, 0, 0.002]",
        ),
        dictionary: dict(TOML_WORDS),
        setup: config_fixture,
        check: |f, input| check_config(f, "condensation", input),
    });
}

#[test]
fn fuzz_config_lowe() {
    run(Target {
        name: "config_lowe",
        rng_seed: 0xC0FF_EE0C,
        seeds: config_seeds::<pipetrack::track::LoweParams>(
            "lowe",
            "max_branches = 10\nmeasurement_sigma_px = 1.5\nrange_doublings = 1\nsearch_after = 2",
        ),
        dictionary: dict(TOML_WORDS),
        setup: config_fixture,
        check: |f, input| check_config(f, "lowe", input),
    });
}

const VISP_WORDS: &[&str] = &[
    "<camera>",
    "</camera>",
    "<px>",
    "</px>",
    "<u0>",
    "<kud>0.1</kud>",
    "<image_width>4</image_width>",
    "<image_height>640</image_height>",
    "<!-- -->",
    "<![CDATA[1]]>",
    "&amp;",
    "&#1114112;",
    "nan",
    "inf",
    "1e400",
    "-0",
    "\u{3000}",
];

#[test]
fn fuzz_visp_pose() {
    run(Target {
        name: "visp_pose",
        rng_seed: 0xC0FF_EE0D,
        seeds: seeds(&["0.1 0.02 0.6 0.1 -0.2 0.05\n", "1 0 0 0.1\n0 1 0 0.02\n0 0 1 0.6\n0 0 0 1\n"]),
        dictionary: dict(VISP_WORDS),
        setup: |folder| folder.join("cube.0.pos"),
        check: |path, input| {
            put(path, input)?;
            check_result(read_pose_file(path), &[path])
        },
    });
}

#[test]
fn fuzz_visp_camera() {
    run(Target {
        name: "visp_camera",
        rng_seed: 0xC0FF_EE0E,
        seeds: seeds(&[
            "<?xml version=\"1.0\"?>\n<conf>\n  <camera>\n    <px>100</px>\n    <py>100</py>\n    <u0>1.5</u0>\n    <v0>1</v0>\n  </camera>\n</conf>\n",
            "<conf><camera><image_width>4</image_width><image_height>3</image_height><model><px>120.5</px><py>119</py><u0>2</u0><v0>1.5</v0><kud>0</kud></model></camera></conf>\n",
        ]),
        dictionary: dict(VISP_WORDS),
        setup: |folder| folder.join("cube.xml"),
        check: |path, input| {
            put(path, input)?;
            check_result(read_camera(path, 4, 3), &[path])
        },
    });
}

// ---------------------------------------------------------------------------
// Regression tests: inputs the property tests above found, and large inputs
// of the shapes they hinted at.

/// Time `Sequence::open` on the fixture with `model` as `model.json`.
fn time_model(f: &SeqFixture, model: &str) -> (Duration, Result<(), String>) {
    let t0 = Instant::now();
    let result = f.open_with(&f.model, model.as_bytes());
    (t0.elapsed(), result)
}

#[test]
fn large_models_of_30000_vertices_are_checked_quickly() {
    let folder = scratch("large-models");
    let f = sequence_fixture(&folder);
    let n = 30_000;
    let list = |item: &dyn Fn(usize) -> String| (0..n).map(item).collect::<Vec<_>>().join(",");
    let cases = [
        (
            "one point repeated",
            format!(r#"{{"name":"a","vertices":[{}],"edges":[[0,1]]}}"#, list(&|_| "[0,0,0]".into())),
        ),
        (
            "points on one x",
            format!(r#"{{"name":"a","vertices":[{}],"edges":[[0,1]]}}"#, list(&|i| format!("[0,{i},0]"))),
        ),
        (
            "a face of every vertex",
            format!(
                r#"{{"name":"a","vertices":[{}],"edges":[[0,1]],"faces":[[{}]]}}"#,
                list(&|i| format!("[{},{i},0]", i % 2)),
                list(&|i| i.to_string())
            ),
        ),
        (
            "a joint moving every vertex",
            format!(
                r#"{{"name":"a","vertices":[{}],"edges":[[0,1]],"joints":[{{"name":"j","origin":[0,0,0],"axis":[1,0,0],"min":0,"max":1,"vertices":[{}]}}]}}"#,
                list(&|i| format!("[{i},{i},0]")),
                list(&|i| i.to_string())
            ),
        ),
    ];
    for (what, model) in cases {
        let (took, result) = time_model(&f, &model);
        println!("{what}: {took:?}, {result:?}");
        assert!(took < SLOW_CASE, "{what}: {took:?}");
    }
}

/// The message of the input error `result` must be, naming `path`; panics
/// (with `what`) on a panic, `Ok`, or an error breaking [`check_result`].
fn input_message<T>(what: &str, path: &Path, run: impl FnOnce() -> pipetrack::Result<T>) -> String {
    match catch_unwind(AssertUnwindSafe(run)) {
        Err(panic) => panic!("{what:?} panicked: {}", panic_text(&panic)),
        Ok(Ok(_)) => panic!("{what:?} was accepted"),
        Ok(Err(e)) => {
            let message = match &e {
                Error::Input { message, .. } => message.clone(),
                _ => String::new(),
            };
            if let Err(problem) = check_result::<()>(Err(e), &[path]) {
                panic!("{what:?}: {problem}");
            }
            message
        }
    }
}

#[test]
fn cao_counts_beyond_memory_are_errors() {
    let dir = scratch("cao-counts");
    let path = dir.join("model.cao");
    for count in ["18446744073709551615", "4611686018427387904", "1000000000000"] {
        for text in [
            format!("V1\n{count}\n0 0 0\n"),
            format!("V1\n3\n0 0 0\n1 0 0\n0 1 0\n{count}\n0 1\n"),
            format!("V1\n3\n0 0 0\n1 0 0\n0 1 0\n0\n{count}\n"),
            format!("V1\n3\n0 0 0\n1 0 0\n0 1 0\n0\n0\n{count}\n3 0 1 2\n"),
            format!("V1\n3\n0 0 0\n1 0 0\n0 1 0\n0\n0\n1\n{count} 0 1 2\n"),
        ] {
            put(&path, text.as_bytes()).expect("write");
            let message = input_message(&text, &path, || read_cao(&path));
            assert!(message.contains("file ends where") || message.contains("expected"), "{text:?}: {message}");
        }
    }
}

#[test]
fn messages_quoting_the_file_stay_one_short_line() {
    let long = "a.".repeat(1000);
    // Found by fuzz_predictions_jsonl: serde quotes an unknown variant raw,
    // so the escaped newline in it became a real one.
    let dir = scratch("messages");
    let pred = dir.join("pred.jsonl");
    put(&pred, b"{\"frame\":0,\"status\":\"los\\nt\",\"corners\":[],\"ms\":0}\n").expect("write");
    let message = input_message("status with a newline", &pred, || read_predictions(&pred));
    assert!(message.contains(r"unknown variant `los\nt`"), "{message}");

    // Found by fuzz_model_json: a long string where the object belongs was
    // quoted whole.
    let folder = scratch("messages-model");
    let f = sequence_fixture(&folder);
    put(&f.model, format!(" \"edges{long}\"").as_bytes()).expect("write");
    let message = input_message("a long string for a model", &f.model, || Sequence::open(&f.dir, false));
    assert!(message.starts_with("wrong content at line 1 column 2008: invalid type: string \"edgesa.a."), "{message}");
    assert!(message.contains("…\""), "{message}");

    // The same for a name the model checks quote (a joint's).
    let joint = LID_BOX.replace("\"lid\"", &format!("\"lid\\n{long}\""));
    put(&f.model, joint.replace("\"min\":-1.5", "\"min\":2").as_bytes()).expect("write");
    let message = input_message("a joint name with a newline", &f.model, || Sequence::open(&f.dir, false));
    assert!(message.starts_with(r#"line 5: joint "lid\na.a."#) && message.contains("min <= max"), "{message}");

    // Found by fuzz_cao: a 3-D point's coordinate of 40 kB was quoted whole.
    let cao = dir.join("model.cao");
    put(&cao, CUBE_CAO.replacen("0.1 0.1 0.1", &format!("0.1 0.1 0.{long}"), 1).as_bytes()).expect("write");
    let message = input_message("a long coordinate", &cao, || read_cao(&cao));
    assert!(message.starts_with("line 11: 3-D point 6: \"0.a.a."), "{message}");

    // Found by fuzz_config_motion_edge: a long unknown variant of an enum
    // parameter was quoted whole.
    let folder = scratch("messages-config");
    let f = config_fixture(&folder);
    put(&f.path, format!("missing = \"last-measureme{}\"", "[".repeat(2000)).as_bytes()).expect("write");
    let message = input_message("a long variant", &f.path, || make_tracker("motion-edge", &f.seq, Some(&f.path)));
    assert!(
        message.starts_with("line 1: unknown variant `last-measureme[[[") && message.ends_with("in `missing`"),
        "{message}"
    );

    // Found by fuzz_visp_pose and fuzz_visp_camera: a long token of a ViSP
    // pose file, a long value in <camera> and the XML parser's message on a
    // long name were quoted whole.
    let pose = dir.join("cube.0.pos");
    put(&pose, format!("0.1 0.2 0.{long} 0 0 0").as_bytes()).expect("write");
    let message = input_message("a long pose token", &pose, || read_pose_file(&pose));
    assert!(message.starts_with("\"0.a.a.") && message.ends_with("is not a finite number"), "{message}");
    let xml = dir.join("cube.xml");
    put(&xml, format!("<conf><camera><px>1{long}</px></camera></conf>").as_bytes()).expect("write");
    let message = input_message("a long camera value", &xml, || read_camera(&xml, 4, 3));
    assert!(message.starts_with("<camera> <px> \"1a.a.") && message.ends_with("is not a finite number"), "{message}");
    put(&xml, format!("<conf><c{long}").as_bytes()).expect("write");
    let message = input_message("a long XML name", &xml, || read_camera(&xml, 4, 3));
    assert!(message.starts_with("not XML: ") && message.chars().count() < 300, "{message}");
    // A load() of a long name, in a model import-visp copies.
    put(&cao, format!("V1\nload(\"{long}.cao\")\n").as_bytes()).expect("write");
    let message = input_message("a long loaded name", &cao, || loaded_files(&cao));
    assert!(message.starts_with("line 2: load(\"a.a.") && message.ends_with("is missing"), "{message}");
}
