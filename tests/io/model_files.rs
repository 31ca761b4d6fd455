//! The three model files of a sequence folder (SPEC §4) through the
//! command line: a ViSP `.cao` model made of several files and a Wavefront
//! `.obj` model track like the `model.json` they describe, and each bad
//! model gets one line naming the file and the line at fault, exit status
//! 2 and no output file.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Output;

use pipetrack::Sequence;
use pipetrack::io::formats::Model;

use crate::common::pipetrack;

fn scratch(name: &str) -> crate::common::Scratch {
    crate::common::scratch("model-files", name)
}

fn synth(scene: &str, dir: &Path, frames: &str) {
    let out = pipetrack(&["synth", scene, dir.to_str().unwrap(), "--frames", frames, "--seed", "3"]);
    assert!(out.status.success(), "synth {scene}: {}", String::from_utf8_lossy(&out.stderr));
}

/// `track DIR --tracker blue --backend cpu`: the JSON lines it printed.
fn track_blue(seq: &Path) -> Vec<serde_json::Value> {
    let out = pipetrack(&["track", seq.to_str().unwrap(), "--tracker", "blue", "--backend", "cpu"]);
    assert!(out.status.success(), "track {}: {}", seq.display(), String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).expect("JSON line")).collect()
}

/// The `target3dof` truck (`model.json` of `seq`) as the sequence folder
/// `dir` with no `model.json`: its frames, camera and init, and the model
/// written by `write_model`.
fn truck_without_json(seq: &Path, dir: &Path, write_model: impl Fn(&Model, &Path)) -> Model {
    let model = Sequence::open(seq, false).expect("synthesised sequence").model;
    std::fs::create_dir_all(dir.join("frames")).unwrap();
    for file in ["camera.json", "init.json"] {
        std::fs::copy(seq.join(file), dir.join(file)).unwrap();
    }
    for entry in std::fs::read_dir(seq.join("frames")).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), dir.join("frames").join(entry.file_name())).unwrap();
    }
    write_model(&model, dir);
    model
}

/// `.cao` text of the vertices `range` of `model` and the faces `faces`
/// (which use only those vertices), indices counted from the range's start.
fn cao_part(model: &Model, range: std::ops::Range<usize>, faces: std::ops::Range<usize>) -> String {
    let mut text = format!("V1\n# {} points\n{}\n", range.len(), range.len());
    for v in &model.vertices[range.clone()] {
        writeln!(text, "{:?} {:?} {:?}", v[0], v[1], v[2]).unwrap();
    }
    writeln!(text, "0\n0\n{}", faces.len()).unwrap();
    for face in &model.faces[faces] {
        let local: Vec<String> = face.iter().map(|&i| (i - range.start).to_string()).collect();
        writeln!(text, "{} {}  // a comment ViSP allows", face.len(), local.join(" ")).unwrap();
    }
    text.push_str("0\n0\n");
    text
}

/// The edges of `model` as a set of unordered pairs.
fn edge_set(model: &Model) -> std::collections::BTreeSet<(usize, usize)> {
    model.edges.iter().map(|&[a, b]| (a.min(b), a.max(b))).collect()
}

#[test]
fn a_multi_file_cao_model_tracks_as_its_model_json() {
    let root = scratch("cao");
    let seq = root.join("json");
    synth("target3dof", &seq, "5");
    // The truck's parts (see synth::target3dof): body, bumper, two light
    // boxes; the right light box is the left one moved along x.
    let cao = root.join("cao");
    let json_model = truck_without_json(&seq, &cao, |m, dir| {
        std::fs::create_dir_all(dir.join("parts")).unwrap();
        std::fs::write(dir.join("parts/body.cao"), cao_part(m, 0..10, 0..7)).unwrap();
        std::fs::write(dir.join("parts/bumper.cao"), cao_part(m, 10..18, 7..13)).unwrap();
        std::fs::write(dir.join("parts/light.cao"), cao_part(m, 18..26, 13..19)).unwrap();
        let dx = m.vertices[26][0] - m.vertices[18][0];
        let top = format!(
            "V1\n# truck back\nload(\"parts/body.cao\")\nload(\"parts/bumper.cao\")\n\
             load(\"parts/light.cao\")\nload(\"parts/light.cao\", t=[{dx:?}; 0; 0], tu=[0; 0; 0 deg]) # right\n"
        );
        std::fs::write(dir.join("model.cao"), top).unwrap();
    });

    let opened = Sequence::open(&cao, false).expect("the .cao sequence opens");
    assert!(opened.model_path().ends_with("model.cao"));
    let model = &opened.model;
    assert_eq!(model.vertices.len(), json_model.vertices.len());
    for (k, (a, b)) in model.vertices.iter().zip(&json_model.vertices).enumerate() {
        assert!((0..3).all(|c| (a[c] - b[c]).abs() < 1e-12), "vertex {k}: {a:?} vs {b:?}");
    }
    assert_eq!(model.faces, json_model.faces);
    assert_eq!(edge_set(model), edge_set(&json_model));

    let from_json = track_blue(&seq);
    let from_cao = track_blue(&cao);
    assert_eq!(from_json.len(), 5);
    assert_eq!(from_cao.len(), 5);
    for (a, b) in from_json.iter().zip(&from_cao) {
        assert_eq!(a["status"], b["status"], "frame {}", a["frame"]);
        let (ca, cb) = (a["corners"].as_array().unwrap(), b["corners"].as_array().unwrap());
        assert_eq!(ca.len(), 34);
        assert_eq!(ca.len(), cb.len());
        for (p, q) in ca.iter().zip(cb) {
            for c in 0..2 {
                assert!((p[c].as_f64().unwrap() - q[c].as_f64().unwrap()).abs() < 1e-6, "frame {}", a["frame"]);
            }
        }
    }
    assert!(from_cao.iter().any(|r| r["status"] == "tracking"));
}

#[test]
fn an_obj_model_tracks_with_the_edges_where_the_surface_bends() {
    let root = scratch("obj");
    let seq = root.join("json");
    synth("target3dof", &seq, "3");
    let obj = root.join("obj");
    let json_model = truck_without_json(&seq, &obj, |m, dir| {
        let mut text = String::from("# truck back\no truck\nmtllib truck.mtl\n");
        for v in &m.vertices {
            writeln!(text, "v {:?} {:?} {:?}", v[0], v[1], v[2]).unwrap();
        }
        text.push_str("vn 0 0 -1\ng body\nusemtl grey\ns off\n");
        for (f, face) in m.faces.iter().enumerate() {
            // Mixed reference forms, and negative ones for the last face.
            let refs: Vec<String> = face
                .iter()
                .map(|&i| match f % 3 {
                    _ if f + 1 == m.faces.len() => format!("{}", i as i64 - m.vertices.len() as i64),
                    0 => format!("{}", i + 1),
                    1 => format!("{}//1", i + 1),
                    _ => format!("{}/1/1", i + 1),
                })
                .collect();
            writeln!(text, "f {}", refs.join(" ")).unwrap();
        }
        std::fs::write(dir.join("model.obj"), text).unwrap();
    });

    let opened = Sequence::open(&obj, false).expect("the .obj sequence opens");
    assert!(opened.model_path().ends_with("model.obj"));
    assert_eq!(opened.model.vertices, json_model.vertices);
    assert_eq!(opened.model.faces, json_model.faces);
    // The two rear doors are one plane: the line between them (vertices 1
    // and 4, a painted divider in model.json) is no bend of the surface.
    let mut expected = edge_set(&json_model);
    assert!(expected.remove(&(1, 4)));
    assert_eq!(edge_set(&opened.model), expected);

    let lines = track_blue(&obj);
    assert_eq!(lines.len(), 3);
    assert!(lines.iter().all(|r| r["corners"].as_array().is_none_or(|c| c.len() == 34)));
    assert_eq!(lines[0]["status"], "tracking");
}

/// `track SEQ --tracker TRACKER --backend cpu --out OUT`.
fn track_cpu(seq: &Path, tracker: &str, out: &Path) -> Output {
    pipetrack(&[
        "track",
        seq.to_str().unwrap(),
        "--tracker",
        tracker,
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ])
}

/// A good pendulum sequence in `root/seq` whose model files are replaced
/// by `files` (name, text): `track` must exit 2 with one line on stderr
/// naming `file` and holding every `needles`, and leave no output.
fn expect_bad_model(name: &str, files: &[(&str, &str)], file: &str, needles: &[&str]) {
    let root = scratch(name);
    let seq = root.join("seq");
    synth("pendulum", &seq, "2");
    std::fs::remove_file(seq.join("model.json")).unwrap();
    for (path, text) in files {
        let path = seq.join(path);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }
    let out_file = root.join("out.jsonl");
    let out = track_cpu(&seq, "motion-edge", &out_file);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{name}: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("pipetrack:")).collect();
    assert_eq!(lines.len(), 1, "{name}: one error line expected, got: {stderr}");
    let expected_file = seq.join(file);
    assert!(lines[0].contains(&format!("{}: ", expected_file.display())), "{name}: {file} not named: {}", lines[0]);
    for n in needles {
        assert!(lines[0].contains(n), "{name}: {n:?} missing from: {}", lines[0]);
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!out_file.exists() && crate::common::partials(&root, "out.jsonl").is_empty(), "{name}: output left behind");
}

/// A rectangle `model.json` (the pendulum's four corners), one element a line.
const RECTANGLE_JSON: &str = r#"{"name": "rect", "units": "px",
 "vertices": [
  [-40, -20, 0],
  [40, -20, 0],
  [40, 20, 0],
  [-40, 20, 0]],
 "edges": [
  [0, 1],
  [1, 2],
  [2, 3],
  [3, 0]],
 "faces": [
  [0, 3, 2, 1]],
 "joints": [
  {"name": "flap", "origin": [0, 0, 0], "axis": [1, 0, 0], "min": -1, "max": 1,
   "vertices": [2,
                3]}]}
"#;

#[test]
fn bad_model_json_names_the_line_of_the_element() {
    let edge = RECTANGLE_JSON.replace("  [2, 3],\n", "  [2, 7],\n");
    expect_bad_model("json-edge", &[("model.json", &edge)], "model.json", &["line 10: edge 2 [2, 7]"]);
    let face = RECTANGLE_JSON.replace("[0, 3, 2, 1]]", "[0, 3]]");
    expect_bad_model("json-face", &[("model.json", &face)], "model.json", &["line 13: face 0 has 2 vertices"]);
    let joint = RECTANGLE_JSON.replace("                3]", "                5]");
    expect_bad_model(
        "json-joint",
        &[("model.json", &joint)],
        "model.json",
        &["line 17: joint \"flap\" moves vertex 5"],
    );
}

/// A rectangle `.cao` part: four points, its face.
const RECTANGLE_CAO: &str = "V1\n4\n-40 -20 0\n40 -20 0\n40 20 0\n-40 20 0\n0\n0\n1\n4 0 3 2 1\n0\n0\n";

#[test]
fn bad_model_cao_names_the_file_and_line() {
    let edge = RECTANGLE_CAO.replace("\n0\n0\n1\n", "\n1\n0 4\n0\n1\n");
    expect_bad_model("cao-edge", &[("model.cao", &edge)], "model.cao", &["line 8: 3-D line 0: point index 4"]);
    let face = RECTANGLE_CAO.replace("4 0 3 2 1", "2 0 3");
    expect_bad_model("cao-face", &[("model.cao", &face)], "model.cao", &["line 10: face from points 0 has 2 points"]);
    let missing = "V1\n# the rectangle\nload(\"parts/rect.cao\")\n";
    expect_bad_model(
        "cao-missing",
        &[("model.cao", missing)],
        "model.cao",
        &["line 3: load(\"parts/rect.cao\"): no such file"],
    );
    // model.cao ⊃ parts/a.cao ⊃ b.cao ⊃ a.cao: the file closing the cycle is named.
    expect_bad_model(
        "cao-cycle",
        &[
            ("model.cao", "V1\nload(\"parts/a.cao\")\n"),
            ("parts/a.cao", "V1\nload(\"b.cao\")\n"),
            ("parts/b.cao", "V1\nload(\"rect.cao\")\nload(\"a.cao\")\n"),
            ("parts/rect.cao", RECTANGLE_CAO),
        ],
        "parts/b.cao",
        &["line 3: load(\"a.cao\") makes a cycle of includes (a.cao → b.cao → a.cao)"],
    );
    expect_bad_model(
        "cao-folder",
        &[("model.cao", missing), ("parts/rect.cao/keep", "")],
        "model.cao",
        &["line 3: load(\"parts/rect.cao\"): is a folder"],
    );
    // A chain of 100 files, each loading the next: the file that would be
    // the 65th deep is refused (a chain of thousands would exhaust the stack).
    let chain: Vec<(String, String)> = (0..100)
        .map(|i| (format!("parts/p{i}.cao"), format!("V1\nload(\"p{}.cao\")\n", i + 1)))
        .chain(std::iter::once(("parts/p100.cao".to_string(), RECTANGLE_CAO.to_string())))
        .chain(std::iter::once(("model.cao".to_string(), "V1\nload(\"parts/p0.cao\")\n".to_string())))
        .collect();
    let chain: Vec<(&str, &str)> = chain.iter().map(|(p, t)| (p.as_str(), t.as_str())).collect();
    expect_bad_model(
        "cao-deep",
        &chain,
        "parts/p62.cao",
        &["line 2: load(\"p63.cao\"): includes nested more than 64 files deep"],
    );
    // An error inside an included file names that file.
    let bad_part = RECTANGLE_CAO.replace("40 20 0\n-40", "40 20\n-40");
    expect_bad_model(
        "cao-part",
        &[("model.cao", "V1\nload(\"rect.cao\")\n"), ("rect.cao", &bad_part)],
        "rect.cao",
        &["line 5: 3-D point 2: expected 3 numbers, found 2"],
    );
}

#[test]
fn bad_model_obj_names_the_line() {
    let good = "v -40 -20 0\nv 40 -20 0\nv 40 20 0\nv -40 20 0\n";
    let face = format!("{good}# the face\nf 1 4\n");
    expect_bad_model("obj-face", &[("model.obj", &face)], "model.obj", &["line 6: face has 2 vertices"]);
    let edge = format!("{good}f 1 4 3 2\nl 2 5\n");
    expect_bad_model(
        "obj-edge",
        &[("model.obj", &edge)],
        "model.obj",
        &["line 6: vertex reference 5 but the file has 4"],
    );
}

/// `track SEQ --tracker lowe` must exit 2 with an error naming `file`
/// (`init.json`, `model.json`) and containing `needle`, and write nothing;
/// `what` labels a failure.
fn expect_lowe_refused(seq: &Path, file: &str, needle: &str, what: &str) {
    let out_file = seq.with_extension("jsonl");
    let out = track_cpu(seq, "lowe", &out_file);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{what}: {stderr}");
    assert!(stderr.contains(&format!("{file}: ")) && stderr.contains(needle), "{what}: {stderr}");
    assert!(!out_file.exists(), "{what}: nothing written");
}

/// `f` applied to the JSON file at `path`, written back.
fn edit_json(path: &Path, f: impl FnOnce(&mut serde_json::Value)) {
    let mut value: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    f(&mut value);
    std::fs::write(path, value.to_string()).unwrap();
}

/// A start pose that puts the model at or behind the camera: refused with
/// init.json named, not tracked as lost on every frame.
#[test]
fn lowe_refuses_a_start_pose_behind_the_camera() {
    let root = scratch("behind");
    let seq = root.join("seq");
    synth("box", &seq, "2");
    // The centre behind the camera, at it, and in front of it with the
    // camera inside the box (its nearest vertices behind).
    for z in [-1.0, -0.3, 0.0, 0.05] {
        edit_json(&seq.join("init.json"), |init| init["pose"]["translation"] = serde_json::json!([0.0, 0.0, z]));
        // At the camera's plane, the depth is 0, not rounding's 1e-18.
        let needle =
            if z == 0.0 { "centre at depth 0: it must lie in front of the camera" } else { "in front of the camera" };
        expect_lowe_refused(&seq, "init.json", needle, &format!("z = {z}"));
    }
    // In front, but the whole model beside the image: a wrong pose, or a
    // principal point far off (cx within its range, five widths out).
    edit_json(&seq.join("init.json"), |init| init["pose"]["translation"] = serde_json::json!([3.0, 0.0, 1.0]));
    expect_lowe_refused(&seq, "init.json", "the whole model beside the 640x480 image", "x = 3 m");
    std::fs::remove_dir_all(&seq).unwrap();
    synth("box", &seq, "2");
    edit_json(&seq.join("camera.json"), |camera| camera["cx"] = serde_json::json!(3190.5));
    expect_lowe_refused(&seq, "init.json", "the whole model beside", "cx = 3190.5");
    // A message about init.json does not lead with "invalid parameter".
    let out = track_cpu(&seq, "lowe", &seq.with_extension("jsonl"));
    assert!(!String::from_utf8_lossy(&out.stderr).contains("invalid parameter"));
    // A close-up with every vertex outside the image, its edges across it,
    // is a start pose like any other.
    std::fs::remove_dir_all(&seq).unwrap();
    synth("box", &seq, "2");
    edit_json(&seq.join("init.json"), |init| {
        init["pose"]["rotation"] = serde_json::json!([0.0, 0.0, 0.0]);
        init["pose"]["translation"] = serde_json::json!([0.0, 0.0, 0.15]);
    });
    let out = track_cpu(&seq, "lowe", &seq.with_extension("jsonl"));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// What the model alone decides (pixel units, too many joints) names the
/// model file; a start joint value outside its joint's limits names
/// init.json. None is tracked.
#[test]
fn lowe_names_the_file_at_fault_for_joints() {
    let root = scratch("joints");
    let seq = root.join("seq");
    synth("hinged-box", &seq, "2");
    let init_path = seq.join("init.json");
    edit_json(&init_path, |init| init["params"] = serde_json::json!([5.0]));
    expect_lowe_refused(&seq, "init.json", "outside its joint's limits", "lid at 5 rad");
    // No start joint values: each joint starts at 0.
    edit_json(&init_path, |init| {
        init.as_object_mut().unwrap().remove("params");
    });

    let model_path = seq.join("model.json");
    let good_model = std::fs::read_to_string(&model_path).unwrap();
    edit_json(&model_path, |model| model["units"] = serde_json::json!("px"));
    expect_lowe_refused(&seq, "model.json", "in metres", "pixel units");
    std::fs::write(&model_path, good_model).unwrap();
    edit_json(&model_path, |model| {
        let joint = model["joints"][0].clone();
        let joints = (0..11)
            .map(|k| {
                let mut j = joint.clone();
                j["name"] = serde_json::json!(format!("lid {k}"));
                j
            })
            .collect();
        model["joints"] = serde_json::Value::Array(joints);
    });
    expect_lowe_refused(&seq, "model.json", "at most 10 joints", "11 joints");
}

/// blue and condensation, like lowe, refuse a start pose whose model lies
/// beside the image or projects to less than a pixel, naming init.json,
/// instead of reporting frames tracked (or lost) from it.
#[test]
fn blue_and_condensation_refuse_a_start_pose_off_the_image_or_too_small() {
    let root = scratch("start-image");
    for (scene, tracker) in [("target3dof", "blue"), ("textured-plane", "condensation")] {
        let seq = root.join(scene);
        synth(scene, &seq, "2");
        let init_path = seq.join("init.json");
        let init = std::fs::read_to_string(&init_path).unwrap();
        for (axis, value, needle) in [(0, 1e6, "the whole model beside the"), (2, 1e9, "at least 1 px wide and high")] {
            std::fs::write(&init_path, &init).unwrap();
            edit_json(&init_path, |init| init["pose"]["translation"][axis] = serde_json::json!(value));
            let out_file = seq.with_extension("jsonl");
            let out = track_cpu(&seq, tracker, &out_file);
            let stderr = String::from_utf8_lossy(&out.stderr);
            let what = format!("{tracker}, translation[{axis}] = {value}");
            assert_eq!(out.status.code(), Some(2), "{what}: {stderr}");
            assert_eq!(stderr.lines().count(), 1, "{what}: {stderr}");
            assert!(stderr.contains("init.json: ") && stderr.contains(needle), "{what}: {stderr}");
            assert!(!out_file.exists(), "{what}: nothing written");
        }
        std::fs::write(&init_path, &init).unwrap();
        let out = track_cpu(&seq, tracker, &seq.with_extension("jsonl"));
        assert!(out.status.success(), "{tracker} from the scene's own pose: {}", String::from_utf8_lossy(&out.stderr));
    }
}
