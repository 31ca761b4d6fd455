//! `pipetrack roundtrip`: a sequence tracked forward and back agrees with
//! itself where the tracker is on target, and the command reads no truth.

use crate::common::{self, pipetrack};

/// The number after `key` on the line that starts with `line`.
fn figure(stdout: &str, line: &str, key: &str) -> f64 {
    let text = stdout.lines().find(|l| l.starts_with(line)).unwrap_or_else(|| panic!("no {line:?} in {stdout}"));
    let rest = &text[text.find(key).unwrap_or_else(|| panic!("no {key:?} in {text}")) + key.len()..];
    rest.split_whitespace().next().and_then(|w| w.trim_end_matches(['°', ',']).parse().ok()).expect(text)
}

#[test]
fn lowe_tracked_forward_and_back_agrees_on_a_rendered_box() {
    let root = common::scratch("roundtrip", "box");
    let seq = root.join("box");
    let made = pipetrack(&["synth", "box", seq.to_str().unwrap(), "--frames", "40", "--speed", "10"]);
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    // The check must not lean on the truth.
    std::fs::remove_file(seq.join("truth.jsonl")).unwrap();
    let lines = root.join("agreement.jsonl");
    let out = pipetrack(&[
        "roundtrip",
        seq.to_str().unwrap(),
        "--tracker",
        "lowe",
        "--backend",
        "cpu",
        "--out",
        lines.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // One line per frame; the start (frame 39) has no figures.
    let rows: Vec<serde_json::Value> =
        std::fs::read_to_string(&lines).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(rows.len(), 40);
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row["frame"], k);
        assert_eq!((row["forward"].as_str(), row["backward"].as_str()), (Some("tracking"), Some("tracking")));
        assert_eq!(row.get("corner_px").is_some(), k != 39, "frame {k}: {row}");
    }
    println!("{stdout}");
    assert!(stdout.contains("frames: 40"), "{stdout}");
    assert!(stdout.contains("backward run tracking: 40 (from frame 39"), "{stdout}");
    assert!(stdout.contains("start excepted): 39"), "{stdout}");
    assert!(figure(&stdout, "corner disagreement", "mean") < 0.3, "{stdout}");
    assert!(figure(&stdout, "corner disagreement", "max") < 1.0, "{stdout}");
    assert!(figure(&stdout, "translation disagreement", "max") < 5.0, "{stdout}");
    assert!(figure(&stdout, "rotation disagreement", "max") < 1.0, "{stdout}");
}

#[test]
fn refusals_are_one_line_and_exit_2_with_nothing_written() {
    let root = common::scratch("roundtrip", "refused");
    let seq = root.join("plane");
    assert!(pipetrack(&["synth", "textured-plane", seq.to_str().unwrap(), "--frames", "3"]).status.success());
    let config = root.join("motion.toml");
    std::fs::write(&config, "camera_motion = [0.001, 0.0, 0.0, 0.0, 0.0, 0.0]\n").unwrap();
    let out_file = root.join("agreement.jsonl");
    let refused = |args: &[&str], needle: &str| {
        let out = pipetrack(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(needle), "{needle:?} missing from {stderr}");
        assert!(out.stdout.is_empty() && !out_file.exists());
    };
    let (seq, config, out) = (seq.to_str().unwrap(), config.to_str().unwrap(), out_file.to_str().unwrap());
    let base = ["roundtrip", seq, "--tracker", "condensation", "--backend", "cpu"];
    refused(&[&base[..], &["--config", config, "--out", out]].concat(), "camera_motion is the forward run's");
    let init = format!("{seq}/init.json");
    refused(&[&base[..], &["--out", &init]].concat(), "input file");
    let folder = root.to_str().unwrap();
    refused(&[&base[..], &["--out", folder]].concat(), "is a folder");
}

#[test]
fn a_bad_tracker_name_is_one_line_and_exit_2() {
    let root = common::scratch("roundtrip", "bad");
    let seq = root.join("box");
    assert!(pipetrack(&["synth", "box", seq.to_str().unwrap(), "--frames", "2"]).status.success());
    let out = pipetrack(&["roundtrip", seq.to_str().unwrap(), "--tracker", "nope", "--backend", "cpu"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("unknown tracker"), "{stderr}");
    assert!(out.stdout.is_empty());
}
