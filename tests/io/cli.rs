//! The command line, run as a user runs it: every bad input of SPEC §5 gets
//! one line on stderr naming the file and the problem, exit status 2, and no
//! output file; the happy path synthesises, tracks and scores.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use crate::common::pipetrack;

/// `pipetrack track SEQ --tracker motion-edge --backend cpu` with `extra` arguments.
fn track_motion_edge_cpu(seq: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["track", seq.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "cpu"];
    args.extend_from_slice(extra);
    pipetrack(&args)
}

fn scratch(name: &str) -> crate::common::Scratch {
    crate::common::scratch("cli", name)
}

/// A good 6-frame pendulum sequence in `root/seq`.
fn good_sequence(root: &Path) -> PathBuf {
    let seq = root.join("seq");
    let out = pipetrack(&["synth", "pendulum", seq.to_str().unwrap(), "--frames", "6", "--seed", "3"]);
    assert!(out.status.success(), "synth failed: {}", String::from_utf8_lossy(&out.stderr));
    seq
}

/// [`good_sequence`] tracked by motion-edge on the CPU into `root/pred.jsonl`
/// (the run must succeed): the sequence folder and the output.
fn tracked_good_sequence(root: &Path) -> (PathBuf, PathBuf) {
    let seq = good_sequence(root);
    let pred = root.join("pred.jsonl");
    let out = track_motion_edge_cpu(&seq, &["--out", pred.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    (seq, pred)
}

/// Run `track` on `seq` with `--out`, expect exit 2, a one-line message
/// containing every `needles`, and no output file left.
fn expect_bad_input(root: &Path, seq: &Path, needles: &[&str]) {
    let out_file = root.join("out.jsonl");
    let out = track_motion_edge_cpu(seq, &["--out", out_file.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "exit status for {needles:?}; stderr: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("pipetrack:")).collect();
    assert_eq!(lines.len(), 1, "one error line expected, got: {stderr}");
    for n in needles {
        assert!(lines[0].contains(n), "{n:?} missing from: {}", lines[0]);
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!out_file.exists(), "no output file may be left");
    assert!(crate::common::partials(root, "out.jsonl").is_empty(), "no partial output may be left");
}

#[test]
fn synth_track_score_round_trip() {
    let root = scratch("ok");
    let (seq, pred) = tracked_good_sequence(&root);
    let text = std::fs::read_to_string(&pred).unwrap();
    assert_eq!(text.lines().count(), 6);
    for (i, line) in text.lines().enumerate() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(v["frame"], i);
        assert!(v["status"] == "tracking" || v["status"] == "lost");
        assert_eq!(v["corners"].as_array().unwrap().len(), 4);
        assert!(v["ms"].as_f64().unwrap() >= 0.0);
    }
    let out = pipetrack(&["score", seq.to_str().unwrap(), pred.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = String::from_utf8_lossy(&out.stdout);
    for key in [
        "mean corner error",
        "median corner error",
        "p95 corner error",
        "max corner error",
        "frames tracked",
        "first lost frame",
    ] {
        assert!(s.contains(key), "score output lacks {key}: {s}");
    }
}

#[test]
fn stdout_output_and_overlays() {
    let root = scratch("stdout");
    let seq = good_sequence(&root);
    let overlay = root.join("overlay");
    let out = track_motion_edge_cpu(&seq, &["--overlay", overlay.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 6);
    let pngs = std::fs::read_dir(&overlay).unwrap().count();
    assert_eq!(pngs, 6);
    let img = image::open(overlay.join("000000.png")).unwrap().to_rgb8();
    assert!(img.pixels().any(|p| p.0 == [255, 255, 0]), "model drawn in yellow while tracking");
}

/// The first `frames` frames of the sequence at `seq` (256×242) as a mono Y4M stream.
fn y4m_stream(seq: &Path, frames: usize) -> Vec<u8> {
    let (w, h) = (256usize, 242usize);
    let mut stream = format!("YUV4MPEG2 W{w} H{h} F60:1 Ip A1:1 Cmono\n").into_bytes();
    for i in 0..frames {
        let img = image::open(seq.join(format!("frames/{i:06}.png"))).unwrap().to_luma8();
        stream.extend_from_slice(b"FRAME\n");
        stream.extend_from_slice(img.as_raw());
    }
    stream
}

/// `track SEQ --frames -` with motion-edge on the CPU, stdin and stdout piped.
fn track_y4m_on_stdin(seq: &Path, stderr: Stdio) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .args(["track", seq.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "cpu", "--frames", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(stderr)
        .spawn()
        .unwrap()
}

#[test]
fn y4m_frames_on_stdin() {
    use std::io::Write;
    let root = scratch("y4m");
    let seq = good_sequence(&root);
    let mut child = track_y4m_on_stdin(&seq, Stdio::piped());
    child.stdin.take().unwrap().write_all(&y4m_stream(&seq, 6)).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 6);
}

/// A stream that is not Y4M: one error line naming standard input, exit 2.
#[test]
fn a_bad_stream_on_stdin_is_named_standard_input() {
    use std::io::Write;
    let root = scratch("y4m-bad");
    let seq = good_sequence(&root);
    let mut child = track_y4m_on_stdin(&seq, Stdio::piped());
    child.stdin.take().unwrap().write_all(b"garbage\n").unwrap();
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("pipetrack: standard input: not a YUV4MPEG2 stream"), "{stderr}");
    assert!(out.stdout.is_empty());
}

/// With the stream still open after two frames, both frames' lines have
/// already been written: a reader of a live stream sees each result as its
/// frame is tracked.
#[test]
fn y4m_frames_on_stdin_give_each_line_as_its_frame_is_tracked() {
    use std::io::{BufRead, Write};
    let root = scratch("y4m-live");
    let seq = good_sequence(&root);
    let mut child = track_y4m_on_stdin(&seq, Stdio::null());
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(&y4m_stream(&seq, 2)).unwrap();
    stdin.flush().unwrap();
    let stdout = child.stdout.take().unwrap();
    let (lines, arrived) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stdout).lines().map_while(std::result::Result::ok) {
            if lines.send(line).is_err() {
                break;
            }
        }
    });
    for frame in 0..2 {
        let line = arrived.recv_timeout(std::time::Duration::from_secs(60));
        let line = line.unwrap_or_else(|_| panic!("frame {frame}'s line is not written while the stream is open"));
        assert!(line.contains(&format!("\"frame\":{frame}")), "{line}");
    }
    drop(stdin);
    assert!(child.wait().unwrap().success());
}

/// On a machine with no session runtime folder (headless, a batch job) the
/// GPU backend says nothing on stderr but its summary line: Mesa's Vulkan
/// device-selection layer would make libwayland print an error line there.
#[test]
fn the_gpu_backend_is_quiet_without_a_runtime_folder() {
    let root = scratch("headless");
    let seq = good_sequence(&root);
    for runtime in [None, Some(""), Some("not/absolute")] {
        let mut command = Command::new(env!("CARGO_BIN_EXE_pipetrack"));
        command.args(["track", seq.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "gpu"]);
        command.args(["--out", root.join("pred.jsonl").to_str().unwrap()]);
        match runtime {
            Some(value) => command.env("XDG_RUNTIME_DIR", value),
            None => command.env_remove("XDG_RUNTIME_DIR"),
        };
        let out = command.output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        let others: Vec<_> = stderr.lines().filter(|l| !l.starts_with("pipetrack: ")).collect();
        assert!(others.is_empty(), "XDG_RUNTIME_DIR {runtime:?}: {others:?}");
    }
}

#[test]
fn missing_folder() {
    let root = scratch("missing");
    expect_bad_input(&root, &root.join("nope"), &["nope"]);
}

#[test]
fn empty_folder() {
    let root = scratch("empty");
    let seq = root.join("seq");
    std::fs::create_dir_all(&seq).unwrap();
    expect_bad_input(&root, &seq, &["seq"]);
}

#[test]
fn missing_camera_file() {
    let root = scratch("nocam");
    let seq = good_sequence(&root);
    std::fs::remove_file(seq.join("camera.json")).unwrap();
    expect_bad_input(&root, &seq, &["camera.json"]);
}

#[test]
fn malformed_json() {
    let root = scratch("badjson");
    let seq = good_sequence(&root);
    std::fs::write(seq.join("init.json"), "{\"corners\": [[1, 2],").unwrap();
    expect_bad_input(&root, &seq, &["init.json"]);
}

/// Start corners far outside the image are said to be there, not taken for
/// a polygon whose edges lie on one line (every turn looks flat at 1e300).
#[test]
fn start_corners_far_outside_the_image() {
    let root = scratch("far_corners");
    let seq = good_sequence(&root);
    std::fs::write(seq.join("init.json"), r#"{"corners":[[1e300,1e300],[2e300,1e300],[2e300,2e300],[1e300,2e300]]}"#)
        .unwrap();
    expect_bad_input(&root, &seq, &["init.json", "image size outside"]);
}

#[test]
fn nan_intrinsics() {
    let root = scratch("nan");
    let seq = good_sequence(&root);
    std::fs::write(seq.join("camera.json"), r#"{"width":256,"height":242,"fx":NaN,"fy":300,"cx":127.5,"cy":120.5}"#)
        .unwrap();
    expect_bad_input(&root, &seq, &["camera.json", "NaN"]);
}

#[test]
fn corrupt_frame_mid_sequence_leaves_no_output() {
    let root = scratch("corrupt");
    let seq = good_sequence(&root);
    std::fs::write(seq.join("frames/000003.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    expect_bad_input(&root, &seq, &["000003.png"]);
}

#[test]
fn frames_of_changing_size() {
    let root = scratch("size");
    let seq = good_sequence(&root);
    image::GrayImage::new(100, 80).save(seq.join("frames/000004.png")).unwrap();
    expect_bad_input(&root, &seq, &["000004.png", "100"]);
}

#[test]
fn model_with_fewer_vertices_than_init_corners() {
    let root = scratch("fewer");
    let seq = good_sequence(&root);
    std::fs::write(
        seq.join("model.json"),
        r#"{"name":"tri","units":"px","vertices":[[0,0,0],[1,0,0],[0,1,0]],"edges":[[0,1],[1,2],[2,0]],"faces":[[0,1,2]]}"#,
    )
    .unwrap();
    expect_bad_input(&root, &seq, &["model.json"]);
}

#[test]
fn unknown_tracker_and_bad_config() {
    let root = scratch("tracker");
    let seq = good_sequence(&root);
    let out = pipetrack(&["track", seq.to_str().unwrap(), "--tracker", "nonesuch", "--backend", "cpu"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("nonesuch"));
    let cfg = root.join("bad.toml");
    std::fs::write(&cfg, "[motion-edge]\nzeta = -3.0\n").unwrap();
    let out = track_motion_edge_cpu(&seq, &["--config", cfg.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    let cfg2 = root.join("typo.toml");
    std::fs::write(&cfg2, "zetta = 3.0\n").unwrap();
    let out = track_motion_edge_cpu(&seq, &["--config", cfg2.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    // A misspelt key or table: its line and the name meant.
    for (text, needle) in [
        ("zetta = 3.0\n", "typo.toml: line 1: unknown key \"zetta\" for motion-edge: did you mean zeta?"),
        (
            "epsilon = 20.0\n\n[motion_edge]\nzeta = 3.0\n",
            "typo.toml: line 3: [motion_edge] is no tracker's table: did you mean [motion-edge]?",
        ),
        // No key near it: where the keys are listed.
        ("qqqqqq = 1\n", "unknown key \"qqqqqq\" for motion-edge (`pipetrack config motion-edge` lists every key)"),
        ("delta = 2.0\nlowe = 1\n", "typo.toml: line 2: unknown key \"lowe\" for motion-edge (`pipetrack config"),
        // A value of the wrong type: its line, the type in words, the key.
        ("zeta = \"big\"\n", "typo.toml: line 1: invalid type: string \"big\", expected a number; in `zeta`"),
        // The line in the tracker's own table, not in another tracker's.
        (
            "[lowe]\nwindow_margin_px = 8.0\n[motion-edge]\nwindow_margin_px = 8.0\n",
            "typo.toml: line 4: unknown key \"window_margin_px\" for motion-edge",
        ),
    ] {
        std::fs::write(&cfg2, text).unwrap();
        let out = track_motion_edge_cpu(&seq, &["--config", cfg2.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{text}: {stderr}");
        assert!(stderr.contains(needle), "{text}: {needle:?} missing from {stderr}");
    }
    // Beside the tracker's table, a key or table that belongs to no tracker
    // is refused (it would be ignored); another tracker's table is not.
    let cfg3 = root.join("outside.toml");
    for (text, refused) in [
        ("zeta = -3.0\n[motion-edge]\nepsilon = 20.0\n", Some("\"zeta\" lies outside [motion-edge]")),
        ("[motion-edge]\nepsilon = 20.0\n[segments]\nmin_length = 3.0\n", Some("\"segments\" lies outside")),
        ("[motion-edge]\nepsilon = 20.0\n[blue]\nlambda = 0.5\n", None),
        ("[blue]\nlambda = 0.5\n[lowe]\nmax_branches = 4\n", None),
        ("epsilon = 20.0\n[blue]\nlambda = 0.5\n", None),
    ] {
        std::fs::write(&cfg3, text).unwrap();
        let out = track_motion_edge_cpu(&seq, &["--config", cfg3.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        match refused {
            Some(needle) => {
                assert_eq!(out.status.code(), Some(2), "{text}: {stderr}");
                assert!(stderr.contains("outside.toml") && stderr.contains(needle), "{text}: {stderr}");
            }
            None => assert!(out.status.success(), "{text}: {stderr}"),
        }
    }
}

#[test]
fn synth_refuses_a_non_empty_folder_and_unknown_scenes() {
    let root = scratch("synth");
    let seq = good_sequence(&root);
    let out = pipetrack(&["synth", "pendulum", seq.to_str().unwrap(), "--frames", "2"]);
    assert_eq!(out.status.code(), Some(2));
    let out = pipetrack(&["synth", "teapot", root.join("t").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("pendulum"), "lists known scenes");
}

/// A negative value of a scene option reaches its range check; an option
/// given both as a flag and by `--set`, or by `--set` twice, is refused
/// rather than one silently winning. Each: exit 2, one line, no folder.
#[test]
fn synth_checks_negative_values_and_refuses_an_option_given_twice() {
    let root = scratch("synth-options");
    let dir = root.join("seq");
    let cases: [(&[&str], &str); 5] = [
        (&["box", "--speed", "-2"], "speed = -2"),
        (&["pendulum", "--noise", "-1"], "noise"),
        (&["pendulum", "--speed", "4", "--set", "speed=3"], "--speed both set speed"),
        (&["target3dof", "--shake", "--set", "shake=false"], "--shake both set shake"),
        (&["box", "--set", "noise=3", "--set", "noise=4"], "another --set both set noise"),
    ];
    for (args, needle) in cases {
        let mut all = vec!["synth", args[0], dir.to_str().unwrap(), "--frames", "2"];
        all.extend_from_slice(&args[1..]);
        let out = pipetrack(&all);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("pipetrack:")).collect();
        assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
        assert!(lines[0].contains(needle), "{args:?}: {needle:?} missing from {}", lines[0]);
        assert!(!dir.exists(), "{args:?}: nothing written");
    }
}

#[test]
fn score_rejects_short_predictions() {
    let root = scratch("score");
    let seq = good_sequence(&root);
    let pred = root.join("short.jsonl");
    std::fs::write(&pred, "{\"frame\":0,\"status\":\"tracking\",\"corners\":[[0,0],[1,0],[1,1],[0,1]],\"ms\":1}\n")
        .unwrap();
    let out = pipetrack(&["score", seq.to_str().unwrap(), pred.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("short.jsonl"));
}

/// `pipetrack ARGS` with stdout a pipe whose reader is gone before the
/// command writes (it is closed right after the spawn).
fn with_stdout_closed(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary runs");
    drop(child.stdout.take());
    child.wait_with_output().expect("binary ends")
}

/// `pipetrack ARGS` with stdout `/dev/full`, or `None` where there is no `/dev/full`.
fn with_stdout_full(args: &[&str]) -> Option<Output> {
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").ok()?;
    Some(Command::new(env!("CARGO_BIN_EXE_pipetrack")).args(args).stdout(full).output().expect("binary runs"))
}

/// The lines of `out`'s stderr starting with `pipetrack:`, checking there is no panic.
fn error_lines(out: &Output) -> Vec<String> {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr.lines().filter(|l| l.starts_with("pipetrack:")).map(str::to_string).collect()
}

#[test]
fn a_closed_stdout_ends_quietly_with_status_0() {
    let root = scratch("pipe");
    let seq = good_sequence(&root);
    let pred = root.join("pred.jsonl");
    assert!(track_motion_edge_cpu(&seq, &["--out", pred.to_str().unwrap()]).status.success());
    let out = with_stdout_closed(&["score", seq.to_str().unwrap(), pred.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.stderr.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));

    let overlay = root.join("overlay");
    let seq_arg = seq.to_str().unwrap();
    let args =
        ["track", seq_arg, "--tracker", "motion-edge", "--backend", "cpu", "--overlay", overlay.to_str().unwrap()];
    let out = with_stdout_closed(&args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(error_lines(&out).is_empty(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!overlay.exists(), "the stopped run's overlays are not left looking complete");
    assert_eq!(std::fs::read_dir(&root).unwrap().count(), 2, "only seq and pred.jsonl: no staging folder left");
}

#[test]
fn a_full_stdout_or_out_file_is_one_error_line() {
    let root = scratch("full");
    let seq = good_sequence(&root);
    let pred = root.join("pred.jsonl");
    assert!(track_motion_edge_cpu(&seq, &["--out", pred.to_str().unwrap()]).status.success());
    let Some(out) = with_stdout_full(&["score", seq.to_str().unwrap(), pred.to_str().unwrap()]) else {
        eprintln!("skipped: no /dev/full");
        return;
    };
    let lines = error_lines(&out);
    // A full disk is not bad input: exit status 1.
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains("stdout") && lines[0].contains("No space left"), "{}", lines[0]);
    assert_eq!(lines[0].matches("No space left").count(), 1, "{}", lines[0]);

    let seq_arg = seq.to_str().unwrap();
    let out = with_stdout_full(&["track", seq_arg, "--tracker", "motion-edge", "--backend", "cpu"]).unwrap();
    let lines = error_lines(&out);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains("stdout") && lines[0].contains("No space left"), "{}", lines[0]);

    // A device as --out is written in place, never replaced by a file.
    let out = track_motion_edge_cpu(&seq, &["--out", "/dev/full"]);
    let lines = error_lines(&out);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains("/dev/full") && lines[0].contains("No space left"), "{}", lines[0]);
    // The OS error is said once (it is the I/O error's message and its source).
    assert_eq!(lines[0].matches("No space left").count(), 1, "{}", lines[0]);
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata("/dev/full").unwrap().file_type().is_char_device());
    assert!(!Path::new("/dev/full.partial").exists());
}

#[test]
fn out_over_an_input_file_or_a_folder_is_refused_before_tracking() {
    let root = scratch("outcheck");
    let seq = good_sequence(&root);
    for input in ["init.json", "camera.json", "model.json", "truth.jsonl", "frames/000002.png"] {
        let target = seq.join(input);
        let before = std::fs::read(&target).unwrap();
        // Through a detour, so only the resolved paths are equal.
        let detour = seq.join("frames").join("..").join(input);
        let out = track_motion_edge_cpu(&seq, &["--out", detour.to_str().unwrap()]);
        let lines = error_lines(&out);
        assert_eq!(out.status.code(), Some(2), "{lines:?}");
        assert!(lines[0].contains("input file") && lines[0].contains(input), "{}", lines[0]);
        assert_eq!(std::fs::read(&target).unwrap(), before, "{input} untouched");
    }
    // A new file among the frames would be read as a frame next time.
    for name in ["000006.png", "out.jsonl"] {
        let target = seq.join("frames").join(name);
        let out = track_motion_edge_cpu(&seq, &["--out", target.to_str().unwrap()]);
        let lines = error_lines(&out);
        assert_eq!(out.status.code(), Some(2), "{lines:?}");
        assert!(lines[0].contains("frames folder"), "{}", lines[0]);
        assert!(!target.exists());
    }
    let dir = root.join("a-folder");
    std::fs::create_dir(&dir).unwrap();
    let out = track_motion_edge_cpu(&seq, &["--out", dir.to_str().unwrap()]);
    let lines = error_lines(&out);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(lines.len(), 1, "refused before tracking, so no summary line: {lines:?}");
    assert!(lines[0].contains("a-folder: is a folder"), "{}", lines[0]);
    assert!(crate::common::partials(&root, "a-folder").is_empty());

    let file = root.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let out = track_motion_edge_cpu(&seq, &["--overlay", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty(), "refused before the first frame");
}

#[test]
fn a_gap_in_the_frames_is_refused_naming_the_missing_file() {
    let root = scratch("gap");
    let seq = good_sequence(&root);
    std::fs::remove_file(seq.join("frames/000002.png")).unwrap();
    expect_bad_input(&root, &seq, &["frames/000002.png", "missing"]);
}

#[test]
fn camera_as_a_positional_array_is_refused() {
    let root = scratch("camarray");
    let seq = good_sequence(&root);
    std::fs::write(seq.join("camera.json"), "[256, 242, 300, 300, 127.5, 120.5]").unwrap();
    expect_bad_input(&root, &seq, &["camera.json", "array"]);
}

#[test]
fn bad_models_are_refused() {
    let model = |units: &str, vertices: &str| {
        format!(
            r#"{{"name":"r","units":"{units}","vertices":{vertices},"edges":[[0,1],[1,2],[2,3],[3,0]],"faces":[[0,3,2,1]]}}"#
        )
    };
    let cases = [
        (model("px", "[[0,0,0],[10,0,0],[10,5,0],[10,0,0]]"), "vertex 3 repeats vertex 1"),
        (model("px", "[[0,0,0],[10,0,0],[10,5,3],[0,5,0]]"), "face 0 is not planar"),
        (model("inch", "[[0,0,0],[10,0,0],[10,5,0],[0,5,0]]"), "m, px"),
    ];
    for (text, needle) in cases {
        let root = scratch("badmodel");
        let seq = good_sequence(&root);
        std::fs::write(seq.join("model.json"), text).unwrap();
        expect_bad_input(&root, &seq, &["model.json", needle]);
    }
}

#[test]
fn track_never_reads_truth_and_score_takes_per_vertex_visibility() {
    let root = scratch("truth");
    let seq = good_sequence(&root);
    let truth_text = std::fs::read_to_string(seq.join("truth.jsonl")).unwrap();
    std::fs::write(seq.join("truth.jsonl"), "{\"frame\": damaged").unwrap();
    let pred = root.join("pred.jsonl");
    let out = track_motion_edge_cpu(&seq, &["--out", pred.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "a damaged truth.jsonl does not stop track: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = pipetrack(&["score", seq.to_str().unwrap(), pred.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(error_lines(&out)[0].contains("truth.jsonl"));

    // Per-vertex visibility, corner 0 hidden everywhere, and an extra key.
    let per_vertex: String = truth_text
        .lines()
        .map(|l| {
            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
            v["visible"] = serde_json::json!([false, true, true, true]);
            v["occluded_fraction"] = serde_json::json!(0.25);
            format!("{v}\n")
        })
        .collect();
    std::fs::write(seq.join("truth.jsonl"), per_vertex).unwrap();
    let out = track_motion_edge_cpu(&seq, &["--out", pred.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = pipetrack(&["score", seq.to_str().unwrap(), pred.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("frames scored:       6"));
}

#[test]
fn degenerate_init_corners_are_blamed_on_init_json() {
    for (name, corners) in [
        ("equal", "[[100,100],[100,100],[100,100],[100,100]]"),
        ("bowtie", "[[100,100],[160,160],[160,100],[100,160]]"),
        ("collinear", "[[100,100],[130,100],[160,100],[100,160]]"),
    ] {
        let root = scratch(&format!("init-{name}"));
        let seq = good_sequence(&root);
        std::fs::write(seq.join("init.json"), format!("{{\"corners\":{corners}}}")).unwrap();
        expect_bad_input(&root, &seq, &["init.json"]);
    }
}

#[test]
fn sigint_during_track_leaves_no_partial_output() {
    let root = scratch("sigint");
    let seq = root.join("seq");
    let out = pipetrack(&["synth", "pendulum", seq.to_str().unwrap(), "--frames", "2000", "--seed", "1"]);
    assert!(out.status.success(), "synth failed: {}", String::from_utf8_lossy(&out.stderr));
    let pred = root.join("pred.jsonl");
    let overlay = root.join("overlay");
    // Stale leftovers of an earlier run killed outright (a process id that
    // does not run: above the kernel's pid limit).
    let stale = root.join(".overlay.partial-4294967295");
    std::fs::create_dir(&stale).unwrap();
    let args = ["--out", pred.to_str().unwrap(), "--overlay", overlay.to_str().unwrap()];
    let mut child = Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .args(["track", seq.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "cpu"])
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary runs");
    let staging = root.join(format!(".overlay.partial-{}", child.id()));
    let started = std::time::Instant::now();
    let writing = || !crate::common::partials(&root, "pred.jsonl").is_empty();
    while !(writing() && std::fs::read_dir(&staging).is_ok_and(|mut d| d.next().is_some())) {
        assert!(started.elapsed().as_secs() < 120, "the run never started writing");
        assert!(child.try_wait().unwrap().is_none(), "the run ended before the signal");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(!stale.exists(), "a stale staging folder of the same output is removed at start");
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill runs");
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{}", String::from_utf8_lossy(&out.stderr));
    let left: Vec<_> = std::fs::read_dir(&root).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left, ["seq"], "nothing but the sequence is left");
}

/// `track --tracker condensation` on a `textured-plane` folder (colour PNG
/// frames): every line has corners, a pose, a velocity screw and an
/// effective sample size; a sequence without a pose, a model that is not a
/// quadrilateral and an out-of-range parameter are one-line errors with
/// exit status 2 naming the file.
#[test]
fn condensation_round_trip_and_bad_input() {
    let root = scratch("condensation");
    let seq = root.join("plane");
    let out =
        pipetrack(&["synth", "textured-plane", seq.to_str().unwrap(), "--frames", "4", "--set", "motion=translation"]);
    assert!(out.status.success(), "synth failed: {}", String::from_utf8_lossy(&out.stderr));
    let config = root.join("c.toml");
    std::fs::write(&config, "samples = 30\ncomponent_weights = [1.0, 1.0, 0.0, 0.0, 0.0, 0.0]\n").unwrap();
    let pred = root.join("pred.jsonl");
    let track = |seq: &Path, config: &Path| {
        pipetrack(&[
            "track",
            seq.to_str().unwrap(),
            "--tracker",
            "condensation",
            "--backend",
            "cpu",
            "--config",
            config.to_str().unwrap(),
            "--out",
            pred.to_str().unwrap(),
        ])
    };
    let out = track(&seq, &config);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&pred).unwrap();
    let lines: Vec<serde_json::Value> = text.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 4);
    for v in &lines[1..] {
        assert_eq!(v["status"], "tracking", "{v}");
        assert_eq!(v["corners"].as_array().unwrap().len(), 4);
        assert!(v["pose"].is_object());
        assert_eq!(v["velocity_screw"].as_array().unwrap().len(), 6);
        assert!(v["effective_sample_size"].as_f64().unwrap() >= 1.0);
    }
    std::fs::remove_file(&pred).unwrap();

    let expect_error = |out: Output, needles: &[&str]| {
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("pipetrack:")).collect();
        assert_eq!(lines.len(), 1, "{stderr}");
        for n in needles {
            assert!(lines[0].contains(n), "{n:?} missing from {}", lines[0]);
        }
        assert!(!pred.exists());
    };
    let pendulum = good_sequence(&root);
    expect_error(track(&pendulum, &config), &["init.json", "pose"]);
    let truck = root.join("truck");
    let out = pipetrack(&["synth", "target3dof", truck.to_str().unwrap(), "--frames", "2"]);
    assert!(out.status.success());
    expect_error(track(&truck, &config), &["model.json", "4 vertices"]);
    std::fs::write(&config, "samples = 0\n").unwrap();
    expect_error(track(&seq, &config), &["c.toml", "samples"]);
}

/// `bench --windows` with `--cpu-only` times the CPU backend alone: no GPU
/// row values, no adapter; its JSON has the shape of the stages' report
/// (adapter, CPU threads, rows), the same as `bench --stages`.
#[test]
fn bench_windows_cpu_only_opens_no_adapter() {
    let out = pipetrack(&["bench", "--windows", "7,20", "--seconds", "0.01", "--json", "--cpu-only"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    let stages =
        pipetrack(&["bench", "--stages", "gaussian", "--sizes", "9x5", "--seconds", "0.01", "--json", "--cpu-only"]);
    let stages: serde_json::Value = serde_json::from_slice(&stages.stdout).expect("JSON report");
    assert_eq!(report["adapter"], "not used (CPU only)");
    assert_eq!((&report["adapter"], &report["cpu_threads"]), (&stages["adapter"], &stages["cpu_threads"]));
    let rows = report["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 2);
    for (row, n) in rows.iter().zip([7, 20]) {
        assert_eq!(row["windows"], n);
        assert!(row["cpu_ms"].as_f64().is_some_and(|ms| ms > 0.0), "{row}");
        assert!(row["gpu_ms"].is_null() && row["gpu_over_cpu"].is_null(), "{row}");
    }
}

/// `reproduce` refuses options that do not apply to the tracker named:
/// exit 2, one line saying which, nothing written.
#[test]
fn reproduce_refuses_options_of_the_other_paper() {
    let root = scratch("reproduce");
    let out_dir = root.join("fig4");
    let out_arg = out_dir.to_str().unwrap();
    for (args, needle) in [
        (vec!["reproduce", "condensation", "--out", out_arg, "--config", "paper"], "--config is for motion-edge"),
        (vec!["reproduce", "condensation", "--out", out_arg, "--seeds", "1,2"], "takes one seed"),
        (vec!["reproduce", "motion-edge", "--out", out_arg], "--out is for condensation"),
    ] {
        let out = pipetrack(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(needle) && stderr.trim().lines().count() == 1, "{args:?}: {stderr}");
        assert!(!out_dir.exists(), "{args:?} wrote {out_arg}");
    }
}

/// Keys no reader reads (a misspelt `"corner"` for `"corners"` is one) do
/// not stop a run, and are named after it, file by file; a sequence as
/// `synth` writes it has none.
#[test]
fn keys_no_reader_reads_are_noted_after_the_run() {
    let root = scratch("ignored-keys");
    let seq = good_sequence(&root);
    let out = track_motion_edge_cpu(&seq, &["--out", root.join("a.jsonl").to_str().unwrap()]);
    assert!(out.status.success());
    assert!(!String::from_utf8_lossy(&out.stderr).contains("note:"), "{}", String::from_utf8_lossy(&out.stderr));

    let edit = |file: &str, key: &str, to: f64| {
        let path = seq.join(file);
        let mut value: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        value[key] = serde_json::json!(to);
        std::fs::write(&path, value.to_string()).unwrap();
    };
    // A distortion coefficient other than 0 is refused: the camera is a
    // pinhole; at 0 it is only noted.
    edit("camera.json", "k1", 0.1);
    let out = track_motion_edge_cpu(&seq, &["--out", root.join("d.jsonl").to_str().unwrap()]);
    let lines = error_lines(&out);
    assert_eq!(out.status.code(), Some(2), "{lines:?}");
    assert!(lines[0].contains("camera.json: \"k1\" gives lens distortion"), "{lines:?}");
    edit("camera.json", "k1", 0.0);
    edit("init.json", "corner", 1.0);
    let out = track_motion_edge_cpu(&seq, &["--out", root.join("b.jsonl").to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 3, "{stderr}");
    assert!(lines[0].contains("frames/s"), "the run's summary first: {stderr}");
    assert!(lines[1].contains("camera.json: ignored, not read by pipetrack: \"k1\""), "{stderr}");
    assert!(lines[2].contains("init.json: ignored, not read by pipetrack: \"corner\""), "{stderr}");

    // A model file beside model.json is named as not read.
    std::fs::write(seq.join("model.cao"), "not a model").unwrap();
    let out = track_motion_edge_cpu(&seq, &["--out", root.join("c.jsonl").to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("model.cao: not read: the model is model.json"), "{stderr}");
}

/// An error in a file that has keys pipetrack does not read names them: the
/// hinged box's `"joints"` misspelt leaves its lid's vertices on the box's,
/// and the error about that says which key went unread.
#[test]
fn an_error_in_a_file_names_its_unread_keys() {
    let root = scratch("unread-keys");
    let seq = root.join("hinged");
    let out = pipetrack(&["synth", "hinged-box", seq.to_str().unwrap(), "--frames", "2"]);
    assert!(out.status.success(), "synth failed: {}", String::from_utf8_lossy(&out.stderr));
    // `key` of `file` spelt `typo`: `lowe` fails with exit status 2; its
    // one error line, and the file put back.
    let misspelt = |file: &str, key: &str, typo: &str| {
        let path = seq.join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(&format!("{key:?}")), "{file} has no {key:?}");
        std::fs::write(&path, text.replace(&format!("{key:?}"), &format!("{typo:?}"))).unwrap();
        let out = pipetrack(&["track", seq.to_str().unwrap(), "--tracker", "lowe", "--backend", "cpu"]);
        std::fs::write(&path, text).unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("pipetrack:")).collect();
        assert_eq!(lines.len(), 1, "{stderr}");
        lines[0].to_string()
    };
    let line = misspelt("model.json", "joints", "joint");
    assert!(line.contains("model.json") && line.contains("(keys not read: \"joint\"; misspelt?)"), "{line}");

    // A key a tracker needs misspelt: the file reads without it, and the
    // tracker's error about init.json names it.
    let line = misspelt("init.json", "pose", "poes");
    assert!(line.contains("init.json") && line.contains("(keys not read: \"poes\"; misspelt?)"), "{line}");

    // A required key misspelt: the key the file has instead of it.
    let line = misspelt("camera.json", "width", "widht");
    assert!(
        line.contains("camera.json")
            && line.contains("missing field `width` (the file's \"widht\" is not read: misspelt?)"),
        "{line}"
    );
}

/// `track --tracker blue` on a model with a joint (the hinged box): blue
/// holds the model rigid, so it is one line naming `model.json` and the
/// joint, exit status 2, no output; the rigid box is tracked.
#[test]
fn blue_refuses_a_model_with_joints() {
    let root = scratch("blue-joints");
    let pred = root.join("pred.jsonl");
    let track = |scene: &str| {
        let seq = root.join(scene);
        let out = pipetrack(&["synth", scene, seq.to_str().unwrap(), "--frames", "2"]);
        assert!(out.status.success(), "synth failed: {}", String::from_utf8_lossy(&out.stderr));
        pipetrack(&[
            "track",
            seq.to_str().unwrap(),
            "--tracker",
            "blue",
            "--backend",
            "cpu",
            "--out",
            pred.to_str().unwrap(),
        ])
    };
    let out = track("hinged-box");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("pipetrack:")).collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(lines[0].contains("model.json") && lines[0].contains("1 joint;"), "{}", lines[0]);
    assert!(!pred.exists(), "no output");
    let out = track("box");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// One frame is said as one: `synth` and `track` of a single frame.
#[test]
fn one_frame_is_counted_in_the_singular() {
    let root = scratch("singular");
    let seq = root.join("one");
    let out = pipetrack(&["synth", "pendulum", seq.to_str().unwrap(), "--frames", "1"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && stderr.contains("wrote 1 frame of 'pendulum'"), "{stderr}");
    let out = track_motion_edge_cpu(&seq, &["--out", root.join("p.jsonl").to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && stderr.contains("pipetrack: 1 frame, "), "{stderr}");
}

/// A mistake on the command line is one line on stderr with exit status 2,
/// as every other bad input; help still prints in full, with exit status 0.
#[test]
fn command_line_mistakes_are_one_line() {
    let root = scratch("usage");
    let seq = good_sequence(&root);
    let seq = seq.to_str().unwrap();
    let cases: [(&[&str], &str); 5] = [
        (&["batch", "manifest.txt", "--out", "o", "--jobs", "0"], "--jobs"),
        (&["track", seq], "--tracker"),
        (&["track", seq, "--tracker", "lowe", "--bogus"], "--bogus"),
        (&["nope"], "nope"),
        (&["score", seq, "p.jsonl", "--plot-size", "640x360"], "--plot <PLOT>"),
    ];
    for (args, needle) in cases {
        let out = pipetrack(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: one line: {stderr}");
        assert!(stderr.starts_with("pipetrack: ") && stderr.contains(needle), "{args:?}: {stderr}");
        assert!(out.stdout.is_empty(), "{args:?}");
    }
    let help = pipetrack(&["track", "--help"]);
    assert_eq!(help.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&help.stdout).contains("Usage:"));
}

/// `--out -` is stdout, as `--frames -` is stdin: no file named `-`.
#[test]
fn out_dash_writes_to_stdout() {
    let root = scratch("out-dash");
    let seq = good_sequence(&root);
    let args = ["track", seq.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "cpu", "--out", "-"];
    let out = crate::common::pipetrack_in(root.path(), &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 6);
    assert!(!root.join("-").exists());
}

/// `pipetrack config T` prints T's defaults as a config file that `track
/// --config` takes and that gives the run without it.
#[test]
fn config_prints_the_defaults_as_a_config_file() {
    let root = scratch("config");
    let seq = good_sequence(&root);
    let out = pipetrack(&["config", "motion-edge"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("[motion-edge]") && text.contains("\nzeta = "), "{text}");
    let cfg = root.join("defaults.toml");
    std::fs::write(&cfg, &text).unwrap();
    // Each frame's line without its time.
    let run = |args: &[&str]| -> Vec<serde_json::Value> {
        let out = track_motion_edge_cpu(&seq, args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let lines = String::from_utf8(out.stdout).unwrap();
        let parse = |l: &str| {
            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
            v.as_object_mut().unwrap().remove("ms");
            v
        };
        lines.lines().map(parse).collect()
    };
    assert_eq!(run(&["--config", cfg.to_str().unwrap()]), run(&[]), "the defaults give the default run");
    let bad = pipetrack(&["config", "nope"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown tracker \"nope\""));
}

/// `demo` (the README's first command) synthesises, tracks and scores its
/// pendulum on the backend asked for, in a fresh folder of the temp folder,
/// and names that folder's files.
#[test]
fn demo_tracks_its_pendulum_and_names_its_files() {
    let tmp = scratch("demo");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .args(["demo", "--backend", "cpu"])
        .env("TMPDIR", tmp.path())
        .output()
        .expect("binary runs");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        text.starts_with("pipetrack demo: pendulum, 120 frames at 3.9 px/frame, tracker motion-edge on CPU"),
        "{text}"
    );
    assert!(text.contains("frames tracked:      120 of 120") && text.contains("false tracking:      0 "), "{text}");
    let named = |key: &str| {
        let line = text.lines().find(|l| l.starts_with(key)).unwrap_or_else(|| panic!("no {key} line: {text}"));
        std::path::PathBuf::from(line[key.len()..].trim())
    };
    let overlays = named("overlays:");
    assert!(overlays.starts_with(tmp.path()), "{}", overlays.display());
    assert_eq!(std::fs::read_dir(&overlays).unwrap().count(), 120);
    let lines = std::fs::read_to_string(named("output:")).unwrap();
    assert_eq!(lines.lines().count(), 120);
    assert!(named("sequence:").join("truth.jsonl").is_file());
}

/// A named pipe made with `mkfifo` at `path`, and a `cat` draining it into
/// `drained` (it waits for a writer to open the pipe).
fn fifo_with_reader(path: &Path, drained: &Path) -> std::process::Child {
    let made = Command::new("mkfifo").arg(path).status().expect("mkfifo runs");
    assert!(made.success(), "mkfifo {}", path.display());
    Command::new("cat").arg(path).stdout(std::fs::File::create(drained).unwrap()).spawn().expect("cat runs")
}

/// What `reader` drained, once the command that should have written the
/// pipe has ended: a reader still waiting (the pipe was replaced and never
/// opened) is stopped, and what it has is returned all the same.
fn drained(mut reader: std::process::Child, drained: &Path) -> Vec<u8> {
    let start = std::time::Instant::now();
    while reader.try_wait().unwrap().is_none() && start.elapsed().as_secs() < 10 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    if reader.try_wait().unwrap().is_none() {
        reader.kill().unwrap();
        reader.wait().unwrap();
    }
    std::fs::read(drained).unwrap()
}

/// `roundtrip --out` and `score --plot` naming a named pipe write into it,
/// as `track --out` does, and leave it a pipe (a regular file is still
/// replaced only when complete).
#[test]
fn roundtrip_out_and_score_plot_write_into_a_named_pipe() {
    use std::os::unix::fs::FileTypeExt;
    let root = scratch("fifo");
    let seq = good_sequence(&root);
    let seq_arg = seq.to_str().unwrap();
    let is_fifo = |p: &Path| std::fs::symlink_metadata(p).unwrap().file_type().is_fifo();

    let pipe = root.join("agreement.jsonl");
    let reader = fifo_with_reader(&pipe, &root.join("agreement.read"));
    let args = ["roundtrip", seq_arg, "--tracker", "motion-edge", "--backend", "cpu", "--out", pipe.to_str().unwrap()];
    let out = pipetrack(&args);
    let read = drained(reader, &root.join("agreement.read"));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(is_fifo(&pipe), "--out replaced the named pipe with a file");
    assert!(crate::common::partials(&root, "agreement.jsonl").is_empty());
    let text = String::from_utf8(read).unwrap();
    assert_eq!(text.lines().count(), 6, "one line per frame through the pipe: {text}");

    let pred = root.join("pred.jsonl");
    assert!(track_motion_edge_cpu(&seq, &["--out", pred.to_str().unwrap()]).status.success());
    let plot = root.join("plot.png");
    let reader = fifo_with_reader(&plot, &root.join("plot.read"));
    let out = pipetrack(&["score", seq_arg, pred.to_str().unwrap(), "--plot", plot.to_str().unwrap()]);
    let read = drained(reader, &root.join("plot.read"));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(is_fifo(&plot), "--plot replaced the named pipe with a file");
    assert!(read.starts_with(b"\x89PNG"), "the PNG went through the pipe: {} bytes", read.len());
}

/// `roundtrip` prints its report as the other commands do: a reader that
/// closes stdout early ends it quietly, without a panic.
#[test]
fn roundtrip_with_stdout_closed_ends_quietly() {
    let root = scratch("roundtrip-pipe");
    let seq = good_sequence(&root);
    let out = with_stdout_closed(&["roundtrip", seq.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "cpu"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(error_lines(&out).is_empty(), "{stderr}");
}

/// motion-edge's start corners must lie near the image and their polygon
/// overlap it: a corner far out (which made the run take ever longer) or
/// a polygon beside the image names init.json.
#[test]
fn motion_edge_start_corners_far_from_the_image_are_refused() {
    let root = scratch("far-corners");
    let seq = good_sequence(&root);
    let init_path = seq.join("init.json");
    let init: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&init_path).unwrap()).unwrap();
    let with_corners = |f: &dyn Fn(&mut Vec<serde_json::Value>)| {
        let mut edited = init.clone();
        f(edited["corners"].as_array_mut().unwrap());
        std::fs::write(&init_path, edited.to_string()).unwrap();
    };
    with_corners(&|corners| corners[0] = serde_json::json!([-1e5, 0.0]));
    expect_bad_input(&root, &seq, &["init.json", "corner 0 at [-100000, 0]", "x in [-256, 512]"]);
    // The whole polygon moved to start 10 px right of the 256-pixel-wide image.
    with_corners(&|corners| {
        let left = corners.iter().map(|c| c[0].as_f64().unwrap()).fold(f64::INFINITY, f64::min);
        for c in corners.iter_mut() {
            c[0] = serde_json::json!(c[0].as_f64().unwrap() - left + 266.0);
        }
    });
    expect_bad_input(&root, &seq, &["init.json", "wholly outside the 256x242 image"]);
}

/// A gap in truth.jsonl is that file's error, with the frame missing, not
/// a disagreement blamed on the predictions.
#[test]
fn score_names_a_frame_missing_from_truth() {
    let root = scratch("truth-gap");
    let seq = good_sequence(&root);
    let pred = root.join("pred.jsonl");
    assert!(track_motion_edge_cpu(&seq, &["--out", pred.to_str().unwrap()]).status.success());
    let truth_path = seq.join("truth.jsonl");
    let truth = std::fs::read_to_string(&truth_path).unwrap();
    let without_frame_2: Vec<&str> = truth.lines().enumerate().filter(|(k, _)| *k != 2).map(|(_, l)| l).collect();
    std::fs::write(&truth_path, without_frame_2.join("\n") + "\n").unwrap();
    let out = pipetrack(&["score", seq.to_str().unwrap(), pred.to_str().unwrap()]);
    let lines = error_lines(&out);
    assert_eq!(out.status.code(), Some(2), "{lines:?}");
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains("truth.jsonl: line 3: frame 3 after frame 1: frame 2 is missing"), "{}", lines[0]);
    assert!(!lines[0].contains("pred.jsonl"), "{}", lines[0]);
}

/// Every scene takes the noise σ that `synth --help` gives, 0 to 64.
#[test]
fn every_scene_takes_noise_up_to_64() {
    let root = scratch("noise-range");
    for scene in ["pendulum", "target3dof", "textured-plane", "box", "hinged-box"] {
        let dir = root.join(scene);
        let out = pipetrack(&["synth", scene, dir.to_str().unwrap(), "--frames", "1", "--noise", "64"]);
        assert!(out.status.success(), "{scene}: {}", String::from_utf8_lossy(&out.stderr));
        let dir = root.join(format!("{scene}-over"));
        let out = pipetrack(&["synth", scene, dir.to_str().unwrap(), "--frames", "1", "--noise", "64.5"]);
        assert_eq!(out.status.code(), Some(2), "{scene}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("not in 0..=64"), "{scene}");
    }
    let help = pipetrack(&["synth", "--help"]);
    assert!(String::from_utf8_lossy(&help.stdout).contains("Gaussian noise σ in grey levels, 0 to 64"));
}

/// `WGPU_ADAPTER_NAME` naming no adapter is the GPU's absence, said in one
/// line with the adapters there are, and the run goes on on the CPU (wgpu's
/// own reading of the variable panics instead).
#[test]
fn an_adapter_name_that_matches_nothing_falls_back_to_the_cpu() {
    let root = scratch("adapter_name");
    let seq = good_sequence(&root);
    let pred = root.join("pred.jsonl");
    let out = Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .args(["track", seq.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "gpu"])
        .args(["--out", pred.to_str().unwrap()])
        .env("WGPU_ADAPTER_NAME", "no adapter is called this")
        .output()
        .expect("binary runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let notice: Vec<&str> = stderr.lines().filter(|l| l.contains("names no adapter")).collect();
    assert_eq!(notice.len(), 1, "{stderr}");
    assert!(notice[0].contains("\"no adapter is called this\"") && notice[0].contains("running the CPU backend"));
    assert_eq!(std::fs::read_to_string(&pred).unwrap().lines().count(), 6);
}

/// Two runs writing the same `--out` at once each write their own partial
/// file: the file is then the whole output of the run that finished last,
/// never a mix of the two.
#[test]
fn two_runs_writing_one_output_leave_the_last_ones_whole() {
    let root = scratch("same_out");
    let long = root.join("long");
    let out = pipetrack(&["synth", "pendulum", long.to_str().unwrap(), "--frames", "3000", "--seed", "2"]);
    assert!(out.status.success(), "synth failed: {}", String::from_utf8_lossy(&out.stderr));
    let short = good_sequence(&root);
    let pred = root.join("pred.jsonl");
    let first = Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .args(["track", long.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "cpu"])
        .args(["--out", pred.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary runs");
    let first_prefix = format!("pred.jsonl.partial-{}-", first.id());
    let started = std::time::Instant::now();
    while !crate::common::partials(&root, "pred.jsonl").iter().any(|p| {
        p.file_name().unwrap().to_string_lossy().starts_with(&first_prefix)
            && std::fs::metadata(p).is_ok_and(|m| m.len() > 0)
    }) {
        assert!(started.elapsed().as_secs() < 120, "the first run never started writing");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let second = track_motion_edge_cpu(&short, &["--out", pred.to_str().unwrap()]);
    assert!(second.status.success(), "{}", String::from_utf8_lossy(&second.stderr));
    let mut first = first;
    assert!(first.try_wait().unwrap().is_none(), "the first run ended before the second: no overlap to test");
    let first = first.wait_with_output().unwrap();
    assert!(first.status.success(), "{}", String::from_utf8_lossy(&first.stderr));
    let text = std::fs::read_to_string(&pred).unwrap();
    let frames: Vec<u64> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(frames, (0..3000).collect::<Vec<u64>>(), "the output is the last run's, whole");
    assert!(crate::common::partials(&root, "pred.jsonl").is_empty());
}

/// `score` reads no frames: a sequence folder without `frames/` scores the
/// same (its truth then unbounded by a frame count), and `-` for the
/// predictions is one line saying they come from a file.
#[test]
fn score_without_frames_and_not_from_stdin() {
    let root = scratch("score_no_frames");
    let (seq, pred) = tracked_good_sequence(&root);
    let with_frames = pipetrack(&["score", seq.to_str().unwrap(), pred.to_str().unwrap()]);
    assert!(with_frames.status.success(), "{}", String::from_utf8_lossy(&with_frames.stderr));
    std::fs::remove_dir_all(seq.join("frames")).unwrap();
    let without = pipetrack(&["score", seq.to_str().unwrap(), pred.to_str().unwrap()]);
    assert!(without.status.success(), "{}", String::from_utf8_lossy(&without.stderr));
    assert_eq!(without.stdout, with_frames.stdout);
    assert!(String::from_utf8_lossy(&without.stdout).contains("mean corner error"));

    let stdin = pipetrack(&["score", seq.to_str().unwrap(), "-"]);
    let stderr = String::from_utf8_lossy(&stdin.stderr);
    assert_eq!(stdin.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("pipetrack: -: ") && stderr.contains("not from stdin"), "{stderr}");
}

/// A negative number given to an option is refused for its value, in one
/// line naming the option, not taken for an unknown flag.
#[test]
fn a_negative_number_is_refused_as_the_options_value() {
    let root = scratch("negative");
    let seq = root.join("seq");
    for (args, option) in [
        (vec!["synth", "box", seq.to_str().unwrap(), "--seed", "-1"], "'-1' for '--seed"),
        (vec!["synth", "box", seq.to_str().unwrap(), "--frames", "-5"], "'-5' for '--frames"),
    ] {
        let out = pipetrack(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(option) && !stderr.contains("'-- "), "{stderr}");
        assert!(!seq.exists(), "nothing written for {args:?}");
    }
}
