//! The command line, run as a user runs it: every bad input of SPEC §5 gets
//! one line on stderr naming the file and the problem, exit status 2, and no
//! output file; the happy path synthesises, tracks and scores.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn pipetrack(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pipetrack")).args(args).output().expect("binary runs")
}

/// `pipetrack track SEQ --tracker motion-edge --backend cpu` with `extra` arguments.
fn track_motion_edge_cpu(seq: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["track", seq.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "cpu"];
    args.extend_from_slice(extra);
    pipetrack(&args)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipetrack-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A good 6-frame pendulum sequence in `root/seq`.
fn good_sequence(root: &Path) -> PathBuf {
    let seq = root.join("seq");
    let out = pipetrack(&["synth", "pendulum", seq.to_str().unwrap(), "--frames", "6", "--seed", "3"]);
    assert!(out.status.success(), "synth failed: {}", String::from_utf8_lossy(&out.stderr));
    seq
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
    let partial = root.join("out.jsonl.partial");
    assert!(!partial.exists(), "no partial output may be left");
}

#[test]
fn synth_track_score_round_trip() {
    let root = scratch("ok");
    let seq = good_sequence(&root);
    let pred = root.join("pred.jsonl");
    let out = track_motion_edge_cpu(&seq, &["--out", pred.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
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

#[test]
fn y4m_frames_on_stdin() {
    use std::io::Write;
    let root = scratch("y4m");
    let seq = good_sequence(&root);
    let (w, h) = (256usize, 242usize);
    let mut stream = format!("YUV4MPEG2 W{w} H{h} F60:1 Ip A1:1 Cmono\n").into_bytes();
    for i in 0..6 {
        let img = image::open(seq.join(format!("frames/{i:06}.png"))).unwrap().to_luma8();
        stream.extend_from_slice(b"FRAME\n");
        stream.extend_from_slice(img.as_raw());
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .args(["track", seq.to_str().unwrap(), "--tracker", "motion-edge", "--backend", "cpu", "--frames", "-"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(&stream).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 6);
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
    assert!(String::from_utf8_lossy(&out.stderr).contains("typo.toml"));
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
