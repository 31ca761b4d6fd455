//! `score --plot`: a PNG of the size asked, with the error curve and the
//! status strip drawn (not blank), written only when it can be.

use std::path::Path;

use crate::common::pipetrack;

fn tracked_sequence(root: &Path) -> (String, String) {
    let seq = root.join("seq").to_str().unwrap().to_string();
    let pred = root.join("pred.jsonl").to_str().unwrap().to_string();
    assert!(pipetrack(&["synth", "pendulum", &seq, "--frames", "8", "--seed", "2"]).status.success());
    let track = pipetrack(&["track", &seq, "--tracker", "motion-edge", "--backend", "cpu", "--out", &pred]);
    assert!(track.status.success(), "{}", String::from_utf8_lossy(&track.stderr));
    (seq, pred)
}

#[test]
fn score_plot_draws_the_error_and_status() {
    let root = crate::common::scratch("plot", "ok");
    let (seq, pred) = tracked_sequence(&root);
    let png = root.join("score.png");
    let out = pipetrack(&["score", &seq, &pred, "--plot", png.to_str().unwrap(), "--plot-size", "640x360"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("mean corner error"), "the score is still printed");
    let img = image::open(&png).expect("the plot decodes").to_rgb8();
    assert_eq!(img.dimensions(), (640, 360));
    let colours: std::collections::HashSet<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    assert!(colours.len() > 20, "a blank plot: {} colours", colours.len());
    // Every frame tracked: the status strip is green, and no frame is drawn lost (red).
    assert!(colours.contains(&[46, 160, 67]), "no tracking green in the status strip");
    assert!(!colours.contains(&[210, 40, 40]), "a lost frame drawn");
}

#[test]
fn score_plot_errors_are_bad_input() {
    let root = crate::common::scratch("plot", "bad");
    let (seq, pred) = tracked_sequence(&root);
    let png = root.join("missing-folder/score.png");
    let out = pipetrack(&["score", &seq, &pred, "--plot", png.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("score.png"), "{stderr}");
    assert!(!png.exists());
    let small = root.join("small.png");
    for size in ["20x20", "300x200", "479x300", "480x299"] {
        let out = pipetrack(&["score", &seq, &pred, "--plot", small.to_str().unwrap(), "--plot-size", size]);
        assert_eq!(out.status.code(), Some(2), "{size}");
        assert!(String::from_utf8_lossy(&out.stderr).contains(&format!("plot size {size}")), "{size}");
        assert!(!small.exists());
    }
    let out = pipetrack(&["score", &seq, &pred, "--plot", small.to_str().unwrap(), "--plot-size", "480x300"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(small.exists(), "the smallest size allowed");
}

/// The plot never overwrites what it plots: the sequence's truth, a frame,
/// or the predictions named as `--plot` are refused, and left as they were.
#[test]
fn score_plot_refuses_to_overwrite_its_inputs() {
    let root = crate::common::scratch("plot", "inputs");
    let (seq, pred) = tracked_sequence(&root);
    let truth = Path::new(&seq).join("truth.jsonl");
    let frame = Path::new(&seq).join("frames/000000.png");
    let through_dots = Path::new(&seq).join("../seq/truth.jsonl");
    for target in [truth.clone(), frame.clone(), Path::new(&pred).to_path_buf(), through_dots] {
        let before = std::fs::read(&target).unwrap();
        let out = pipetrack(&["score", &seq, &pred, "--plot", target.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{}: {stderr}", target.display());
        assert!(stderr.contains("is the input file"), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert_eq!(std::fs::read(&target).unwrap(), before, "{} was changed", target.display());
    }
    let out = pipetrack(&["score", &seq, &pred, "--plot", &seq]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("is a folder"));
    // A plot named as another image format is refused, not written as PNG.
    let jpg = root.join("score.jpg");
    let out = pipetrack(&["score", &seq, &pred, "--plot", jpg.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("name it .png"));
    assert!(!jpg.exists());
    // --plot-size without --plot would be ignored.
    let out = pipetrack(&["score", &seq, &pred, "--plot-size", "640x360"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "one line: {stderr}");
    assert!(stderr.contains("--plot <PLOT>"), "{stderr}");
}
