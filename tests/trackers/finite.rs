//! Every number the trackers write is finite (SPEC §4), and `score` reads
//! every line back: a pose that puts part of the model behind the camera,
//! cameras with absurd intrinsics (refused, naming `camera.json`), the
//! smallest and largest accepted ones, and the last guard in
//! [`FrameOutcome::to_result`].

use std::path::Path;
use std::process::Command;

use glam::DVec3;
use pipetrack::Error;
use pipetrack::cli::score::{read_predictions, score};
use pipetrack::early::Feature;
use pipetrack::geometry::Pose as RigidPose;
use pipetrack::io::formats::{Camera, FrameResult, InitState, Model, Pose, Status, TruthFrame};
use pipetrack::track::{BlueParams, BlueTracker, Diagnostics, FrameOutcome, Phase};

use crate::common::box_model;

fn camera() -> Camera {
    Camera { width: 640, height: 480, fx: 500.0, fy: 500.0, cx: 319.5, cy: 239.5 }
}

const ROTATION: [f64; 3] = [0.4, -0.5, 0.1];

/// Walk a JSON value; panic at the first number that is not finite or any
/// `null` (serde writes NaN and ±∞ as `null`).
fn assert_all_finite(value: &serde_json::Value, at: &str) {
    match value {
        serde_json::Value::Null => panic!("{at}: null (a NaN or infinite number)"),
        serde_json::Value::Number(n) => {
            assert!(n.as_f64().is_some_and(f64::is_finite), "{at}: {n} is not finite");
        }
        serde_json::Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                assert_all_finite(item, &format!("{at}[{i}]"));
            }
        }
        serde_json::Value::Object(map) => {
            for (key, item) in map {
                assert_all_finite(item, &format!("{at}.{key}"));
            }
        }
        serde_json::Value::Bool(_) | serde_json::Value::String(_) => {}
    }
}

fn scratch(name: &str) -> crate::common::Scratch {
    crate::common::scratch("finite", name)
}

/// Write `results` as the tracker does (one `serde_json` line each), check
/// every number of every line, read the file back with `score`'s reader and
/// score it against `truth`. Returns what was read.
fn write_check_and_score(name: &str, results: &[FrameResult], truth: &[TruthFrame]) -> Vec<FrameResult> {
    let mut text = String::new();
    for result in results {
        let line = serde_json::to_string(result).expect("serialise");
        let value: serde_json::Value = serde_json::from_str(&line).expect("a JSON line");
        assert_all_finite(&value, &format!("frame {}", result.frame));
        text.push_str(&line);
        text.push('\n');
    }
    let folder = scratch(name);
    let path = folder.join("pred.jsonl");
    std::fs::write(&path, text).expect("write predictions");
    let read = read_predictions(&path).unwrap_or_else(|e| panic!("score cannot read the output: {e}"));
    assert_eq!(read.len(), results.len());
    score(truth, &read).unwrap_or_else(|e| panic!("score: {e}"));
    read
}

/// Truth lines for `frames` frames of an 8-vertex model (contents do not
/// matter for reading; lost frames are not scored).
fn truth(frames: usize, corners: &[[f64; 2]]) -> Vec<TruthFrame> {
    (0..frames)
        .map(|frame| TruthFrame {
            frame,
            visible: true.into(),
            pose: None,
            params: Vec::new(),
            corners: corners.to_vec(),
        })
        .collect()
}

/// Camera-frame vertices of the box at `translation`.
fn camera_vertices(model: &Model, translation: [f64; 3]) -> Vec<DVec3> {
    let pose = RigidPose::from(&Pose { rotation: ROTATION, translation });
    model.vertices.iter().map(|p| pose.apply(DVec3::from_array(*p))).collect()
}

/// Edge pixels along the segment p–q (every pixel within 1 px), θ its normal.
fn edge_pixels(p: [f64; 2], q: [f64; 2], out: &mut Vec<Feature>) {
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    let len = dx.hypot(dy);
    let theta = (dx / len).atan2(-dy / len) as f32;
    for k in 0..=len as usize {
        let s = k as f64 / len;
        let (x, y) = (p[0] + s * dx, p[1] + s * dy);
        if (0.0..640.0).contains(&x) && (0.0..480.0).contains(&y) {
            out.push(Feature { x: x as u32, y: y as u32, theta, magnitude: 200.0 });
        }
    }
}

/// The blue tracker started at a pose whose box straddles Z = 0 (centroid
/// 4 cm in front of the camera, the box 10–20 cm deep along the view): the
/// vertices behind the camera cannot be projected. Every frame is lost
/// with that reason, every corner is finite (the vertices that project at
/// their projection, the others at the image of the centroid, their only
/// position), every output number is finite and `score` reads the lines.
/// Fed the edges of the projectable part, the tracker still never claims
/// `tracking` for a model it cannot project.
#[test]
fn blue_pose_straddling_the_camera_plane_writes_finite_lost_lines() {
    let model = box_model();
    let translation = [0.01, 0.0, 0.04];
    let cam = camera_vertices(&model, translation);
    assert!(cam.iter().any(|p| p.z <= 0.0) && cam.iter().any(|p| p.z > 0.0), "the box straddles Z = 0: {cam:?}");
    let c = camera();
    let init = InitState { pose: Some(Pose { rotation: ROTATION, translation }), ..InitState::default() };
    let mut tracker = BlueTracker::new(c, model.clone(), init, BlueParams::default()).expect("tracker");
    let centroid = [c.fx * translation[0] / translation[2] + c.cx, c.fy * translation[1] / translation[2] + c.cy];
    // Edges between two vertices in front of the camera, clipped to the image.
    let mut edges = Vec::new();
    for &[i, j] in &model.edges {
        if let (Some(p), Some(q)) = (c.project_in_front(cam[i]), c.project_in_front(cam[j])) {
            edge_pixels(p, q, &mut edges);
        }
    }
    edges.sort_by_key(|f| (f.y, f.x));
    let mut results = Vec::new();
    for frame in 0..12 {
        let features: &[Feature] = if frame % 2 == 0 { &edges } else { &[] };
        let outcome = tracker.update(frame, features);
        assert_eq!(outcome.corners.len(), 8);
        for (i, (corner, p)) in outcome.corners.iter().zip(&cam).enumerate() {
            assert!(corner.iter().all(|v| v.is_finite()), "frame {frame} corner {i}: {corner:?}");
            if p.z <= 0.0 && frame == 0 {
                assert_eq!(*corner, centroid, "vertex {i} behind the camera: the centroid's image");
            }
        }
        assert_eq!(outcome.status, Status::Lost, "frame {frame}");
        let reason = outcome.diagnostics.lost_reason.clone().unwrap_or_default();
        assert!(reason.contains("cannot be projected"), "frame {frame}: {reason}");
        results.push(outcome.to_result(1.0));
    }
    write_check_and_score("straddle", &results, &truth(results.len(), &[[0.0, 0.0]; 8]));
}

/// Absurd intrinsics are refused by `Camera::validate` with a message
/// naming `camera.json` and the field, and by `BlueTracker::new`; the
/// ends of the accepted ranges pass.
#[test]
fn absurd_intrinsics_are_refused() {
    let path = Path::new("seq/camera.json");
    let good = camera();
    assert!(good.validate(path).is_ok());
    let bad = [
        ("fx", Camera { fx: 1e-300, ..good }),
        ("fy", Camera { fy: 1e-300, ..good }),
        ("fx", Camera { fx: 1e12, ..good }),
        ("fx", Camera { fx: 6.3, ..good }),
        ("cx", Camera { cx: 1e308, ..good }),
        ("cy", Camera { cy: -1e308, ..good }),
        ("cx", Camera { cx: 11.0 * 640.0 + 1.0, ..good }),
        ("cy", Camera { cy: -10.0 * 480.0 - 1.0, ..good }),
    ];
    for (field, c) in bad {
        let message = c.validate(path).expect_err(&format!("{c:?} refused")).to_string();
        assert!(message.contains("camera.json") && message.contains(field), "{message}");
        assert!(!message.contains('\n'), "one line: {message}");
        let init =
            InitState { pose: Some(Pose { rotation: ROTATION, translation: [0.0, 0.0, 0.9] }), ..InitState::default() };
        let refused = BlueTracker::new(c, box_model(), init, BlueParams::default());
        assert!(matches!(refused, Err(Error::Parameter(_))), "blue takes {c:?}");
    }
    // max(W, H) = 640: focal lengths 6.4 to 6.4e6 px; c_x in [−6400, 7040], c_y in [−4800, 5280].
    for c in [
        Camera { fx: 6.4, fy: 6.4e6, ..good },
        Camera { cx: -6400.0, cy: 5280.0, ..good },
        Camera { cx: 7040.0, cy: -4800.0, ..good },
    ] {
        assert!(c.validate(path).is_ok(), "{c:?}: {:?}", c.validate(path));
    }
}

/// Cameras at the ends of the accepted ranges: the blue tracker, started
/// with the box on the image centre and tracking nothing (every frame lost,
/// the motion models coasting and restarting), writes only finite numbers.
/// (A start that puts the box beside the image, or at less than a pixel
/// across, is refused.)
#[test]
fn blue_at_the_ends_of_the_camera_ranges_writes_finite_numbers() {
    let good = camera();
    let start = |c: Camera, translation| {
        let init = InitState { pose: Some(Pose { rotation: ROTATION, translation }), ..InitState::default() };
        BlueTracker::new(c, box_model(), init, BlueParams::default())
    };
    for (c, depth) in [
        (Camera { fx: 6.4, fy: 6.4, ..good }, 0.45),
        (Camera { fx: 6.4e6, fy: 6.4e6, ..good }, 0.9),
        (Camera { cx: -6400.0, cy: 5280.0, ..good }, 0.9),
    ] {
        let centre = c.back_project([319.5, 239.5], depth).to_array();
        let mut tracker = start(c, centre).expect("tracker");
        let results: Vec<FrameResult> = (0..40).map(|frame| tracker.update(frame, &[]).to_result(1.0)).collect();
        write_check_and_score(&format!("ends-{}", c.fx), &results, &truth(results.len(), &[[0.0, 0.0]; 8]));
    }
    let refusal = |c, translation| start(c, translation).err().map(|e| e.to_string()).unwrap_or_default();
    let beside = refusal(Camera { cx: -6400.0, cy: 5280.0, ..good }, [0.01, -0.02, 0.9]);
    assert!(beside.contains("beside the 640x480 image"), "{beside}");
    let tiny = refusal(Camera { fx: 6.4, fy: 6.4, ..good }, [0.0, 0.0, 9.0]);
    assert!(tiny.contains("at least 1 px wide and high"), "{tiny}");
}

fn outcome(corners: Vec<[f64; 2]>, pose: Option<Pose>, covariance: Option<Vec<f64>>) -> FrameOutcome {
    FrameOutcome {
        frame: 0,
        status: Status::Tracking,
        phase: Phase::Tracking,
        corners,
        pose,
        params: None,
        covariance,
        labelled: Vec::new(),
        diagnostics: Diagnostics::default(),
    }
}

/// The last guard: an outcome with a NaN corner, an infinite pose entry or
/// an infinite covariance never reaches the JSON as `null`. Non-finite
/// corners or pose make the line `lost` without them; a non-finite
/// covariance alone is left out and the status kept.
#[test]
fn to_result_writes_only_finite_numbers() {
    let square = vec![[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
    let pose = Pose { rotation: [0.1, 0.2, 0.3], translation: [0.0, 0.0, 1.0] };
    let mut bad_corner = square.clone();
    bad_corner[2][1] = f64::NAN;
    let bad_pose = Pose { translation: [0.0, f64::INFINITY, 1.0], ..pose };
    let bad_cov = Some(vec![1.0, 0.0, 0.0, f64::NEG_INFINITY]);
    let cases = [
        outcome(bad_corner, Some(pose), Some(vec![1.0; 4])),
        outcome(square.clone(), Some(bad_pose), None),
        outcome(square.clone(), Some(pose), bad_cov),
    ];
    let results: Vec<FrameResult> =
        cases.iter().enumerate().map(|(i, o)| FrameOutcome { frame: i, ..o.clone() }.to_result(f64::NAN)).collect();
    assert_eq!(results[0].status, Status::Lost);
    assert!(results[0].corners.is_empty() && results[0].pose == Some(pose));
    assert_eq!(results[1].status, Status::Lost);
    assert!(results[1].pose.is_none() && results[1].corners == square);
    assert_eq!(results[2].status, Status::Tracking);
    assert!(results[2].covariance.is_none() && results[2].corners == square);
    for r in &results[..2] {
        assert!(r.lost_reason.as_deref().is_some_and(|why| why.contains("not all finite")), "{:?}", r.lost_reason);
    }
    assert_eq!(results[2].lost_reason, None);
    let read = write_check_and_score("guard", &results, &truth(results.len(), &square));
    assert_eq!(read, results);
}

/// `pipetrack track` on a sequence whose `camera.json` has f_x = 1e-300:
/// exit status 2, one line on stderr naming `camera.json`, no output file.
#[test]
fn cli_refuses_an_absurd_focal_length() {
    let root = scratch("cli-fx");
    let seq = root.join("seq");
    let bin = env!("CARGO_BIN_EXE_pipetrack");
    let synth = Command::new(bin)
        .args(["synth", "target3dof", seq.to_str().expect("utf-8"), "--frames", "2"])
        .output()
        .expect("synth runs");
    assert!(synth.status.success(), "synth: {}", String::from_utf8_lossy(&synth.stderr));
    let camera_path = seq.join("camera.json");
    let mut c: Camera =
        serde_json::from_str(&std::fs::read_to_string(&camera_path).expect("camera.json")).expect("camera.json parses");
    c.fx = 1e-300;
    std::fs::write(&camera_path, serde_json::to_string(&c).expect("json")).expect("write camera.json");
    let out_file = root.join("out.jsonl");
    let out = Command::new(bin)
        .args(["track", seq.to_str().expect("utf-8"), "--tracker", "blue", "--backend", "cpu"])
        .args(["--out", out_file.to_str().expect("utf-8")])
        .output()
        .expect("track runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line: {stderr}");
    assert!(lines[0].contains("camera.json") && lines[0].contains("fx"), "{stderr}");
    assert!(!out_file.exists(), "no output file");
}
