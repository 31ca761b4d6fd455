//! Bounds on everything a user can size: every tracker parameter has a
//! documented range that `validate` enforces (so work per frame is bounded),
//! frame sizes from image headers, Y4M headers and `camera.json` are capped
//! before anything that size is allocated, and every such error is one
//! short line naming the file, with exit status 2 from the binary.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use pipetrack::track::make_tracker;
use pipetrack::track::{CondensationParams, LoweParams};
use pipetrack::{BlueParams, EarlyVision, MotionEdgeParams, Sequence};

fn pipetrack(args: &[&str], stdin: &[u8]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_pipetrack"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary runs");
    let mut input = child.stdin.take().expect("stdin");
    // The binary may exit before reading all of stdin; a broken pipe is fine.
    let _ = input.write_all(stdin);
    drop(input);
    child.wait_with_output().expect("binary runs")
}

fn scratch(name: &str) -> crate::common::Scratch {
    crate::common::scratch("bounds", name)
}

/// A rendered sequence `root/seq` of `scene` with two frames.
fn synth(root: &Path, scene: &str) -> PathBuf {
    let seq = root.join("seq");
    let out = pipetrack(&["synth", scene, seq.to_str().expect("utf-8"), "--frames", "2", "--seed", "1"], b"");
    assert!(out.status.success(), "synth failed: {}", String::from_utf8_lossy(&out.stderr));
    seq
}

/// The `pipetrack:` lines of stderr, asserting there is exactly one, no
/// panic, and exit status 2; that line.
fn one_error_line(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "exit status; stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("pipetrack:")).collect();
    assert_eq!(lines.len(), 1, "one error line expected, got: {stderr}");
    lines[0].to_string()
}

/// A message of one short line: no run of more than a dozen digits.
fn assert_short(msg: &str) {
    assert!(msg.len() < 400, "message too long ({} bytes): {msg}", msg.len());
    let longest_run = msg.split(|c: char| !c.is_ascii_digit()).map(str::len).max().unwrap_or(0);
    assert!(longest_run <= 12, "a long number is echoed whole: {msg}");
}

/// Every parameter of a tracker, as its default TOML table has them (a
/// nested table's as dotted keys, `segments.min_length`), plus the
/// optional ones that are absent by default.
fn parameter_names<P: serde::Serialize>(params: &P, optional: &[&str]) -> Vec<(String, toml::Value)> {
    fn flatten(prefix: &str, table: toml::Table, names: &mut Vec<(String, toml::Value)>) {
        for (name, value) in table {
            match value {
                toml::Value::Table(inner) => flatten(&format!("{prefix}{name}."), inner, names),
                value => names.push((format!("{prefix}{name}"), value)),
            }
        }
    }
    let mut names = Vec::new();
    flatten("", toml::Table::try_from(params).expect("params serialise"), &mut names);
    names.extend(optional.iter().map(|n| (n.to_string(), toml::Value::Float(1.0))));
    names
}

/// The last part of a dotted parameter name, as its range error names it.
fn leaf(name: &str) -> &str {
    name.rsplit('.').next().unwrap_or(name)
}

const HUGE_INTEGER: &str = "1000000000";
/// Absurd values as TOML: huge, negative, not a number, and a number of
/// 300 digits.
fn absurd_values() -> Vec<String> {
    vec![
        HUGE_INTEGER.to_string(),
        "1e9".into(),
        "1e30".into(),
        "-1".into(),
        "-1.0".into(),
        "nan".into(),
        format!("1{}.0", "0".repeat(300)),
        format!("1{}", "0".repeat(300)),
    ]
}

/// Values a parameter documents as allowed although they look absurd:
/// a random seed (blue's subsample, condensation's particles) takes any
/// 64-bit integer.
fn allowed(tracker: &str, name: &str, value: &str) -> bool {
    matches!((tracker, name), ("blue", "sample_seed") | ("condensation", "seed")) && value == HUGE_INTEGER
}

/// Walk every parameter of `tracker` with every absurd value through
/// [`make_tracker`], as `--config` does: each must be refused with an
/// error that names the config file and the parameter, in one short line.
fn walk_parameters(tracker: &str, seq_dir: &Path, names: Vec<(String, toml::Value)>) {
    let seq = Sequence::open(seq_dir, false).expect("sequence");
    let root = seq_dir.parent().expect("parent");
    // Fewest parameters each tracker has today: a walk that finds fewer
    // has lost some.
    let fewest = match tracker {
        "blue" => 30,
        "motion-edge" => 20,
        "lowe" => 40,
        _ => 12,
    };
    assert!(names.len() >= fewest, "{tracker}: only {} parameters found", names.len());
    for (name, _) in &names {
        for value in absurd_values() {
            let config = root.join(format!("{tracker}-{name}.toml"));
            std::fs::write(&config, format!("[{tracker}]\n{name} = {value}\n")).expect("config");
            let result = make_tracker(tracker, &seq, Some(&config));
            let shown = &value[..value.len().min(12)];
            if allowed(tracker, name, &value) {
                assert!(result.is_ok(), "{tracker}.{name} = {shown}: refused: {:?}", result.err());
                continue;
            }
            let err = match result {
                Ok(_) => panic!("{tracker}.{name} = {shown} was accepted"),
                Err(e) => e,
            };
            let msg = err.to_string();
            assert!(
                matches!(&err, pipetrack::Error::Input { path, .. } if path == &config),
                "{tracker}.{name} = {shown}: error does not name the config file: {msg}"
            );
            assert!(msg.contains(leaf(name)), "{tracker}.{name} = {shown}: parameter not named: {msg}");
            assert_short(&msg);
        }
    }
}

/// [`walk_parameters`] of `tracker` on a rendered `scene`.
fn walk_on_scene(tracker: &str, scene: &str, names: Vec<(String, toml::Value)>) {
    let root = scratch(&format!("{tracker}-walk"));
    walk_parameters(tracker, &synth(&root, scene), names);
}

#[test]
fn every_blue_parameter_is_bounded() {
    walk_on_scene("blue", "target3dof", parameter_names(&BlueParams::default(), &["nominal_range"]));
}

#[test]
fn every_motion_edge_parameter_is_bounded() {
    walk_on_scene("motion-edge", "pendulum", parameter_names(&MotionEdgeParams::default(), &[]));
}

#[test]
fn every_lowe_parameter_is_bounded() {
    walk_on_scene("lowe", "box", parameter_names(&LoweParams::default(), &[]));
}

#[test]
fn every_condensation_parameter_is_bounded() {
    walk_on_scene(
        "condensation",
        "textured-plane",
        parameter_names(&CondensationParams::default(), &["camera_motion"]),
    );
}

#[test]
fn range_errors_state_the_range() {
    let bad = BlueParams { acquire_distance: 1e10, ..BlueParams::default() };
    let msg = bad.validate().expect_err("1e10 px").to_string();
    assert!(msg.contains("acquire_distance must be in (0, 1000] px, got 1.0e10"), "{msg}");
    let bad = MotionEdgeParams { refine_iterations: 1_000_000_000, ..MotionEdgeParams::default() };
    let msg = bad.validate().expect_err("1e9 passes").to_string();
    assert!(msg.contains("refine_iterations must be in 0 ..= 100, got 1000000000"), "{msg}");
    let bad = MotionEdgeParams { sigma: 1e5, ..MotionEdgeParams::default() };
    let msg = bad.validate().expect_err("sigma 1e5").to_string();
    assert!(msg.contains("sigma must be in (0, 19.5] px"), "{msg}");
    // Infinity switches the vanished-motion check off; a huge finite value is refused.
    assert!(MotionEdgeParams { vanished_motion: f64::INFINITY, ..MotionEdgeParams::default() }.validate().is_ok());
    assert!(MotionEdgeParams { vanished_motion: 1e30, ..MotionEdgeParams::default() }.validate().is_err());
}

/// Through the binary, one absurd value per parameter: exit 2, one line
/// naming the config file and the parameter, before any frame is read.
fn binary_refuses_each_parameter(tracker: &str, scene: &str, names: Vec<(String, toml::Value)>) {
    let root = scratch(&format!("{tracker}-cli"));
    let seq = synth(&root, scene);
    let out_file = root.join("out.jsonl");
    for (name, default) in names {
        let value = match default {
            toml::Value::Integer(_) if name == "sample_seed" => "-1",
            toml::Value::Integer(_) => HUGE_INTEGER,
            _ => "1e30",
        };
        let config = root.join(format!("{name}.toml"));
        std::fs::write(&config, format!("[{tracker}]\n{name} = {value}\n")).expect("config");
        let out = pipetrack(
            &[
                "track",
                seq.to_str().expect("utf-8"),
                "--tracker",
                tracker,
                "--backend",
                "cpu",
                "--config",
                config.to_str().expect("utf-8"),
                "--out",
                out_file.to_str().expect("utf-8"),
            ],
            b"",
        );
        let line = one_error_line(&out);
        assert!(line.contains(&format!("{name}.toml")) && line.contains(leaf(&name)), "{name}: {line}");
        assert_short(&line);
        assert!(!out_file.exists(), "no output file may be left");
    }
}

#[test]
fn binary_refuses_absurd_blue_parameters() {
    binary_refuses_each_parameter("blue", "target3dof", parameter_names(&BlueParams::default(), &["nominal_range"]));
}

#[test]
fn binary_refuses_absurd_motion_edge_parameters() {
    binary_refuses_each_parameter("motion-edge", "pendulum", parameter_names(&MotionEdgeParams::default(), &[]));
}

#[test]
fn smoothing_sigma_is_refused_with_the_config_before_the_backend_starts() {
    let root = scratch("sigma");
    let seq = synth(&root, "pendulum");
    let config = root.join("sigma.toml");
    std::fs::write(&config, "[motion-edge]\nsigma = 1e5\n").expect("config");
    // The default (GPU) backend: the error must come before it starts.
    let out = pipetrack(
        &[
            "track",
            seq.to_str().expect("utf-8"),
            "--tracker",
            "motion-edge",
            "--config",
            config.to_str().expect("utf-8"),
        ],
        b"",
    );
    let line = one_error_line(&out);
    assert!(line.contains("sigma.toml") && line.contains("sigma must be in (0, 19.5]"), "{line}");
    assert!(!String::from_utf8_lossy(&out.stderr).contains("no GPU"), "the backend was started");
    assert!(out.stdout.is_empty(), "no frame may be tracked");
}

#[test]
fn a_number_of_300_digits_is_not_echoed_whole() {
    let root = scratch("digits");
    let seq = synth(&root, "pendulum");
    for value in [format!("1{}", "0".repeat(300)), format!("1{}.0", "0".repeat(300))] {
        for key in ["zeta", "refine_iterations"] {
            let config = root.join("digits.toml");
            std::fs::write(&config, format!("[motion-edge]\n{key} = {value}\n")).expect("config");
            let args = ["track", seq.to_str().expect("utf-8"), "--tracker", "motion-edge", "--backend", "cpu"];
            let out = pipetrack(&[&args[..], &["--config", config.to_str().expect("utf-8")]].concat(), b"");
            let line = one_error_line(&out);
            assert!(line.contains("digits.toml"), "{line}");
            assert_short(&line);
        }
    }
}

/// A sequence whose camera is `w`×`h`, with frames to come from stdin.
fn stdin_sequence(root: &Path, w: usize, h: usize) -> PathBuf {
    let seq = synth(root, "pendulum");
    std::fs::remove_dir_all(seq.join("frames")).expect("remove frames");
    std::fs::write(
        seq.join("camera.json"),
        format!(r#"{{"width":{w},"height":{h},"fx":300,"fy":300,"cx":127.5,"cy":120.5}}"#),
    )
    .expect("camera");
    seq
}

#[test]
fn a_huge_y4m_header_on_stdin_is_refused_before_allocating() {
    let root = scratch("y4m-huge");
    let seq = stdin_sequence(&root, 65536, 65536);
    let header = b"YUV4MPEG2 W65536 H65536 Cmono\nFRAME\nabc";
    for backend in ["cpu", "gpu"] {
        let args = ["track", seq.to_str().expect("utf-8"), "--tracker", "motion-edge", "--frames", "-"];
        let out = pipetrack(&[&args[..], &["--backend", backend]].concat(), header);
        let line = one_error_line(&out);
        assert!(line.contains("camera.json") && line.contains("too large"), "{backend}: {line}");
        assert!(line.contains("65536x65536"), "{backend}: {line}");
    }
}

#[test]
fn y4m_headers_are_checked_against_the_frame_limits() {
    use pipetrack::io::y4m::Y4mReader;
    let msg = |s: &[u8]| Y4mReader::new(s).err().expect("should fail").to_string();
    let m = msg(b"YUV4MPEG2 W65536 H65536 Cmono\n");
    assert!(m.starts_with("standard input: ") && m.contains("too large") && m.contains("16384"), "{m}");
    let m = msg(b"YUV4MPEG2 W16384 H16384 Cmono\n");
    assert!(m.contains("too large") && m.contains("33554432 pixels"), "{m}");
    let m = msg(format!("YUV4MPEG2 W1{} H4\n", "0".repeat(300)).as_bytes());
    assert!(m.contains("bad frame size"), "{m}");
    assert_short(&m);
}

#[test]
fn a_short_y4m_stream_costs_only_what_it_sent() {
    use pipetrack::io::y4m::Y4mReader;
    let data = b"YUV4MPEG2 W8192 H4096 Cmono\nFRAME\nabc";
    let mut reader = Y4mReader::new(&data[..]).expect("header");
    let mut frame = pipetrack::GrayImage::new(0, 0);
    let err = reader.read_frame_into(&mut frame).expect_err("truncated").to_string();
    assert!(err.contains("only 3 arrived"), "{err}");
    assert_eq!(frame.size(), (0, 0), "the frame was not sized to the header's promise");
}

/// A PNG declaring `w`×`h` grey pixels in its header, with no pixel data.
fn png_header_only(path: &Path, w: u32, h: u32) {
    fn chunk(kind: &[u8], data: &[u8]) -> Vec<u8> {
        let mut crc = crc32(kind);
        crc = crc32_update(crc, data);
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        out.extend_from_slice(&(!crc).to_be_bytes());
        out
    }
    fn crc32(data: &[u8]) -> u32 {
        crc32_update(0xffff_ffff, data)
    }
    fn crc32_update(mut crc: u32, data: &[u8]) -> u32 {
        for &b in data {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 != 0 { (crc >> 1) ^ 0xedb8_8320 } else { crc >> 1 };
            }
        }
        crc
    }
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    // An empty zlib stream: the pixel data is missing.
    png.extend(chunk(b"IDAT", b"\x78\x9c\x03\x00\x00\x00\x00\x01"));
    png.extend(chunk(b"IEND", b""));
    std::fs::write(path, png).expect("png");
}

#[test]
fn an_image_too_large_is_called_too_large() {
    let root = scratch("png-huge");
    for (w, h) in [(20_000, 20_000), (16_384, 16_384), (100_000, 1)] {
        let path = root.join(format!("{w}x{h}.png"));
        png_header_only(&path, w, h);
        let msg = pipetrack::io::decode_gray(&path).expect_err("too large").to_string();
        assert!(msg.contains(&format!("{w}x{h}.png")), "{msg}");
        assert!(msg.contains("too large") && !msg.contains("corrupt"), "{msg}");
        assert!(msg.contains("16384 px a side"), "{msg}");
    }
    // Through the binary: the size is refused when the sequence opens.
    let seq = synth(&root, "pendulum");
    std::fs::write(
        seq.join("camera.json"),
        r#"{"width":20000,"height":20000,"fx":300,"fy":300,"cx":127.5,"cy":120.5}"#,
    )
    .expect("camera");
    for f in ["000000.png", "000001.png"] {
        png_header_only(&seq.join("frames").join(f), 20_000, 20_000);
    }
    let out = pipetrack(&["track", seq.to_str().expect("utf-8"), "--tracker", "motion-edge", "--backend", "cpu"], b"");
    let line = one_error_line(&out);
    // camera.json declares the size first, so it is the file named.
    assert!(line.contains("camera.json") && line.contains("too large"), "{line}");
}

#[test]
fn a_frame_size_the_gpu_cannot_list_names_the_camera_file() {
    let Some((ctx, _g)) = crate::common::gpu("a_frame_size_the_gpu_cannot_list_names_the_camera_file") else {
        return;
    };
    let limits = ctx.device().limits();
    let backend = pipetrack::GpuBackend::new(ctx.clone());
    assert!(backend.check_frame_size(640, 480).is_ok());
    let (w, h) = (16_384usize, 2048usize);
    let list_bytes = (w * h * std::mem::size_of::<pipetrack::early::Feature>()) as u64;
    if list_bytes <= limits.max_storage_buffer_binding_size.min(limits.max_buffer_size) {
        eprintln!("this device lists a {w}x{h} frame; only the in-range size is checked");
        return;
    }
    let msg = backend.check_frame_size(w, h).expect_err("too large for the device").to_string();
    assert!(msg.contains("a list of 33554432 features") && msg.contains("buffer limit"), "{msg}");
    // Through the binary: the error names camera.json, before any frame.
    let root = scratch("gpu-list");
    let seq = stdin_sequence(&root, w, h);
    let out = pipetrack(
        &["track", seq.to_str().expect("utf-8"), "--tracker", "motion-edge", "--backend", "gpu", "--frames", "-"],
        b"YUV4MPEG2 W16384 H2048 Cmono\n",
    );
    let line = one_error_line(&out);
    assert!(line.contains("camera.json") && line.contains("too large for the backend"), "{line}");
    assert!(line.contains("--backend cpu"), "{line}");
}
