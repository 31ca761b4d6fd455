//! `pipetrack import-visp`: a small data set in ViSP's layout, made here,
//! becomes a sequence folder whose poses, corners and frames are checked
//! against values worked out independently; missing poses exit 2 and leave
//! nothing behind.

use std::f64::consts::FRAC_PI_2;
use std::path::{Path, PathBuf};

use pipetrack::io::formats::{Camera, InitState, TruthFrame};

use crate::common::{pipetrack, pipetrack_in};

const WIDTH: u32 = 64;
const HEIGHT: u32 = 48;
const FX: f64 = 100.0;
const FY: f64 = 110.0;
const CX: f64 = 31.5;
const CY: f64 = 24.0;

/// A tetrahedron with its right angle at the origin, 0.1 m legs along x, y, z.
const TETRAHEDRON: &str = "V1
# points
4
0 0 0
0.1 0 0
0 0.1 0
0 0 0.1
# lines
0
# faces from lines
0
# faces from points
4
3 0 2 1  name=bottom
3 0 1 3
3 0 3 2
3 1 2 3
# cylinders
0
# circles
0
";

/// The true poses: R (row-major) and t of frames 1..=3. Frame 1 is a
/// quarter turn about x that puts vertex 3 above the image, frame 2 the
/// identity rotation, frame 3 a quarter turn about z.
fn true_poses() -> [([[f64; 3]; 3], [f64; 3]); 3] {
    [
        ([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]], [0.01, -0.02, 0.5]),
        ([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0, 0.0, 0.6]),
        ([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [0.12, 0.0, 0.5]),
    ]
}

/// Their axis-angle vectors, worked out by hand.
const TRUE_AXIS_ANGLES: [[f64; 3]; 3] = [[FRAC_PI_2, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, FRAC_PI_2]];

/// The colour of pixel (x, y) of source frame `k`.
fn colour(k: u32, x: u32, y: u32) -> [u8; 3] {
    [(x * 4) as u8, (y * 5) as u8, (k * 60 + (x + y) % 7) as u8]
}

/// Three frames of `colour(first + k, …)`, k = 0, 1, 2, as `dir/name(k)`.
fn write_frames(dir: &Path, first: u32, name: impl Fn(u32) -> String) {
    for k in 0..3u32 {
        let img = image::RgbImage::from_fn(WIDTH, HEIGHT, |x, y| image::Rgb(colour(first + k, x, y)));
        img.save(dir.join(name(k))).unwrap();
    }
}

/// `pipetrack import-visp SRC SEQ`, which must succeed; its stderr.
fn import_ok(src: &Path, seq: &Path) -> String {
    let out = pipetrack(&["import-visp", src.to_str().unwrap(), seq.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    stderr
}

/// A data set in ViSP's layout in `root/src`: three colour frames, the poses
/// of frames 1 and 3 as 4×4 matrices and of frame 2 as a pose vector, a
/// camera in a settings file and the tetrahedron model.
fn visp_data_set(root: &Path) -> PathBuf {
    let src = root.join("src");
    for dir in ["Images", "CameraPose", "Config", "Models", "Depth"] {
        std::fs::create_dir_all(src.join(dir)).unwrap();
    }
    write_frames(&src, 1, |k| format!("Images/Image_{:04}.png", k + 1));
    for (k, (r, t)) in true_poses().iter().enumerate() {
        let text = if k == 1 {
            // θu = 0 for the identity rotation.
            format!("{}\n{}\n{}\n0\n0\n0\n", t[0], t[1], t[2])
        } else {
            let row = |i: usize| format!("{} {} {} {}\n", r[i][0], r[i][1], r[i][2], t[i]);
            format!("{}{}{}0 0 0 1\n", row(0), row(1), row(2))
        };
        std::fs::write(src.join(format!("CameraPose/Camera_{:03}.txt", k + 1)), text).unwrap();
    }
    std::fs::write(src.join("Config/tetra.xml"), settings()).unwrap();
    std::fs::write(src.join("Models/tetra.cao"), TETRAHEDRON).unwrap();
    src
}

/// ViSP tracker settings with the test camera's intrinsics.
fn settings() -> String {
    format!(
        "<?xml version=\"1.0\"?>\n<conf>\n  <ecm><range><tracking>8</tracking></range></ecm>\n  \
         <camera>\n    <px>{FX}</px>\n    <py>{FY}</py>\n    <u0>{CX}</u0>\n    <v0>{CY}</v0>\n  </camera>\n</conf>\n"
    )
}

fn vertices() -> Vec<[f64; 3]> {
    vec![[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.1]]
}

/// u = fx·X/Z + cx, v = fy·Y/Z + cy of R·p + t, and whether it is in front
/// of the camera and on the image (−½ ≤ u ≤ W − ½, −½ ≤ v ≤ H − ½).
fn project(r: &[[f64; 3]; 3], t: &[f64; 3], p: &[f64; 3]) -> ([f64; 2], bool) {
    let c: Vec<f64> = (0..3).map(|i| r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2] + t[i]).collect();
    let (u, v) = (FX * c[0] / c[2] + CX, FY * c[1] / c[2] + CY);
    let inside = (-0.5..=f64::from(WIDTH) - 0.5).contains(&u) && (-0.5..=f64::from(HEIGHT) - 0.5).contains(&v);
    ([u, v], c[2] > 0.0 && inside)
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

/// The `truth.jsonl` of `seq`, checked against [`true_poses`]: per frame its
/// number, pose, no params, and every vertex projected with its visibility.
/// Returns the lines and how many vertices they have hidden.
fn checked_truth(seq: &Path) -> (Vec<TruthFrame>, usize) {
    let truth: Vec<TruthFrame> = std::fs::read_to_string(seq.join("truth.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(truth.len(), 3);
    let mut hidden = 0;
    for (k, ((r, t), line)) in true_poses().iter().zip(&truth).enumerate() {
        assert_eq!(line.frame, k);
        let pose = line.pose.expect("a pose per frame");
        for a in 0..3 {
            assert!(close(pose.rotation[a], TRUE_AXIS_ANGLES[k][a]), "frame {k}: rotation {:?}", pose.rotation);
            assert!(close(pose.translation[a], t[a]), "frame {k}: translation {:?}", pose.translation);
        }
        assert!(line.params.is_empty());
        assert_eq!(line.corners.len(), 4);
        for (i, p) in vertices().iter().enumerate() {
            let (pixel, seen) = project(r, t, p);
            let got = line.corners[i];
            assert!(close(got[0], pixel[0]) && close(got[1], pixel[1]), "frame {k} vertex {i}: {got:?} vs {pixel:?}");
            assert_eq!(line.visible.vertex(i), seen, "frame {k} vertex {i}");
            hidden += usize::from(!seen);
        }
    }
    (truth, hidden)
}

#[test]
fn a_visp_data_set_becomes_a_sequence_with_its_truth() {
    let root = crate::common::scratch("import-visp", "ok");
    let src = visp_data_set(&root);
    let seq = root.join("seq");
    let stderr = import_ok(&src, &seq);
    assert!(stderr.contains("wrote 3 frames of 64x48"), "{stderr}");

    let camera: Camera = serde_json::from_str(&std::fs::read_to_string(seq.join("camera.json")).unwrap()).unwrap();
    assert_eq!(camera, Camera { width: WIDTH, height: HEIGHT, fx: FX, fy: FY, cx: CX, cy: CY });
    assert_eq!(std::fs::read_to_string(seq.join("model.cao")).unwrap(), TETRAHEDRON);

    let (truth, hidden) = checked_truth(&seq);
    assert!(hidden > 0, "frame 0 has a vertex above the image");

    let init: InitState = serde_json::from_str(&std::fs::read_to_string(seq.join("init.json")).unwrap()).unwrap();
    assert_eq!(init.pose, truth[0].pose);
    assert_eq!(init.corners, truth[0].corners);
    assert!(init.params.is_empty());

    for k in 0..3u32 {
        let frame = image::open(seq.join(format!("frames/{k:06}.png"))).unwrap();
        let grey = frame.as_luma8().expect("frames are written grey");
        for (x, y, p) in grey.enumerate_pixels() {
            let [r, g, b] = colour(k + 1, x, y);
            assert_eq!(p.0[0], pipetrack::image::luma(r, g, b), "frame {k} pixel ({x}, {y})");
        }
    }

    // The folder is a sequence `track` and `score` accept.
    let opened = pipetrack::io::Sequence::open(&seq, false).unwrap();
    assert_eq!(opened.frame_count(), Some(3));
    assert_eq!(opened.read_truth().unwrap().len(), 3);
}

#[test]
fn the_first_frames_only_and_an_overlay() {
    let root = crate::common::scratch("import-visp", "frames");
    let src = visp_data_set(&root);
    let (seq, overlay) = (root.join("seq"), root.join("overlay"));
    let out = pipetrack(&[
        "import-visp",
        src.to_str().unwrap(),
        seq.to_str().unwrap(),
        "--frames",
        "2",
        "--overlay",
        overlay.to_str().unwrap(),
        "--model",
        "Models/tetra.cao",
        "--camera",
        "Config/tetra.xml",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read_to_string(seq.join("truth.jsonl")).unwrap().lines().count(), 2);
    assert_eq!(std::fs::read_dir(seq.join("frames")).unwrap().count(), 2);
    let drawn = image::open(overlay.join("000000.png")).unwrap().to_rgb8();
    assert_eq!(drawn.dimensions(), (WIDTH, HEIGHT));
    assert!(drawn.pixels().any(|p| p.0 == pipetrack::io::overlay::TRACKING_COLOUR), "the model is drawn");
}

/// Run the import on `src`, expect exit 2 with one line containing every
/// `needles`, and neither the sequence folder nor a staging folder left.
fn expect_refused(root: &Path, src: &Path, needles: &[&str]) {
    expect_refused_with(root, src, &[], needles);
}

/// [`expect_refused`] with `extra` arguments after the two folders.
fn expect_refused_with(root: &Path, src: &Path, extra: &[&str], needles: &[&str]) {
    let seq = root.join("seq");
    let out = pipetrack(&[&["import-visp", src.to_str().unwrap(), seq.to_str().unwrap()], extra].concat());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line: {stderr}");
    for n in needles {
        assert!(lines[0].contains(n), "{n:?} missing from {}", lines[0]);
    }
    assert!(!seq.exists(), "no sequence folder");
    let left: Vec<_> = std::fs::read_dir(root).unwrap().filter_map(|e| e.ok()).map(|e| e.file_name()).collect();
    assert!(left.iter().all(|n| n.to_string_lossy() == "src"), "nothing half-written: {left:?}");
}

#[test]
fn missing_poses_are_refused_by_name() {
    let root = crate::common::scratch("import-visp", "no-poses");
    let src = visp_data_set(&root);
    std::fs::remove_dir_all(src.join("CameraPose")).unwrap();
    expect_refused(&root, &src, &["CameraPose", "missing"]);
}

#[test]
fn a_frame_without_a_pose_is_refused_by_name() {
    let root = crate::common::scratch("import-visp", "no-pose");
    let src = visp_data_set(&root);
    std::fs::remove_file(src.join("CameraPose/Camera_002.txt")).unwrap();
    expect_refused(&root, &src, &["Camera_002.txt", "Image_0002.png has no true pose"]);
}

#[test]
fn a_bad_pose_or_a_gap_in_the_frames_is_refused_by_name() {
    let root = crate::common::scratch("import-visp", "bad-pose");
    let src = visp_data_set(&root);
    std::fs::write(src.join("CameraPose/Camera_003.txt"), "1 0 0\n0 1\n").unwrap();
    expect_refused(&root, &src, &["Camera_003.txt", "5 numbers: expected 16"]);

    // Finite numbers, but far too large to project.
    let root = crate::common::scratch("import-visp", "far-pose");
    let src = visp_data_set(&root);
    std::fs::write(src.join("CameraPose/Camera_002.txt"), "1e308\n1e308\n1e308\n0\n0\n0\n").unwrap();
    expect_refused(&root, &src, &["Camera_002.txt", "model vertex 0 projects to no finite pixel"]);

    // The first frame's pose is where a tracker starts: the model behind
    // the camera there is refused (a later frame may leave the view).
    let root = crate::common::scratch("import-visp", "behind");
    let src = visp_data_set(&root);
    std::fs::write(src.join("CameraPose/Camera_001.txt"), "0 0 -1 0 0 0\n").unwrap();
    expect_refused(
        &root,
        &src,
        &["Camera_001.txt", "the first frame's pose puts model vertex", "in front of the camera"],
    );

    let root = crate::common::scratch("import-visp", "gap");
    let src = visp_data_set(&root);
    std::fs::remove_file(src.join("Images/Image_0002.png")).unwrap();
    expect_refused(&root, &src, &["Image_0003.png", "frame 2 is missing before it"]);
}

/// The tetrahedron as a file of only includes, its points and faces in
/// `parts/tetra_body.cao`.
const TETRAHEDRON_BY_LOAD: &str = "V1\nload(\"parts/tetra_body.cao\")  # the body\n0\n0\n0\n0\n0\n0\n";

#[test]
fn loaded_files_are_copied_and_included_parts_placed() {
    let root = crate::common::scratch("import-visp", "load");
    let src = visp_data_set(&root);
    std::fs::create_dir_all(src.join("Models/parts")).unwrap();
    std::fs::write(src.join("Models/parts/tetra_body.cao"), TETRAHEDRON).unwrap();
    std::fs::write(src.join("Models/tetra.cao"), TETRAHEDRON_BY_LOAD).unwrap();
    std::fs::create_dir_all(src.join("Extra")).unwrap();
    std::fs::write(src.join("Extra/wedge.cao"), TETRAHEDRON).unwrap();

    // The model alone: model.cao and the file it loads, as they are.
    let seq = root.join("seq");
    import_ok(&src, &seq);
    assert_eq!(std::fs::read_to_string(seq.join("model.cao")).unwrap(), TETRAHEDRON_BY_LOAD);
    assert_eq!(std::fs::read_to_string(seq.join("parts/tetra_body.cao")).unwrap(), TETRAHEDRON);
    let truth: TruthFrame =
        serde_json::from_str(std::fs::read_to_string(seq.join("truth.jsonl")).unwrap().lines().next().unwrap())
            .unwrap();
    assert_eq!(truth.corners.len(), 4);

    // With a second tetrahedron placed 0.3 m along x (and turned a quarter
    // turn about z): four more vertices, projected where the placement puts them.
    let seq = root.join("seq-with-part");
    let out = pipetrack(&[
        "import-visp",
        src.to_str().unwrap(),
        seq.to_str().unwrap(),
        "--include",
        "Extra/wedge.cao, t=[0.3; 0; 0], tu=[0; 0; 90deg]",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for file in ["model.cao", "tetra.cao", "parts/tetra_body.cao", "wedge.cao"] {
        assert!(seq.join(file).is_file(), "{file} copied");
    }
    let truth: Vec<TruthFrame> = std::fs::read_to_string(seq.join("truth.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let (r, t) = &true_poses()[1];
    let frame = &truth[1];
    assert_eq!(frame.corners.len(), 8);
    // R_z(90°)·(x, y, z) + (0.3, 0, 0) = (0.3 − y, x, z): no point of the first.
    let placed: Vec<[f64; 3]> = vertices().iter().map(|p| [0.3 - p[1], p[0], p[2]]).collect();
    for p in vertices().iter().chain(&placed) {
        let (pixel, _) = project(r, t, p);
        assert!(
            frame.corners.iter().any(|c| (c[0] - pixel[0]).abs() < 1e-9 && (c[1] - pixel[1]).abs() < 1e-9),
            "vertex {p:?} at {pixel:?} among {:?}",
            frame.corners
        );
    }

    // A bad placement is named as the --include argument's; a line break
    // would add a line of its own to the written model.cao.
    for (include, needle) in [
        ("Extra/wedge.cao, t=[0.2; 0]", "Extra/wedge.cao, t=[0.2; 0]\": load(\"wedge.cao\")"),
        // A translation that would carry the part beyond the model coordinates' bound.
        ("Extra/wedge.cao, t=[1e300; 0; 0]", "t=[1e300; 0; 0]\": load(\"wedge.cao\"): t=: 1.0e300 is beyond"),
        ("Extra/wedge.cao, t=[0.2; 0; 0])\nload(\"/elsewhere/other.cao\")\n#", "control character"),
    ] {
        let bad = root.join("seq-bad");
        let out = pipetrack(&["import-visp", src.to_str().unwrap(), bad.to_str().unwrap(), "--include", include]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains("--include") && stderr.contains(needle), "{stderr}");
        assert!(!stderr.contains("line 4"), "a line of the written model.cao: {stderr}");
        assert!(!bad.exists());
    }
}

/// A tracking sequence in the layout of ViSP's `mbt/cube` under `root/src`:
/// the frames `tetra/image0000.png` … `image0002.png` (numbered from 0, as
/// ViSP's tutorials save them), and beside the folder `tetra.cao`,
/// `tetra.xml` and `tetra.0.pos` (the first frame's pose as a 4×4 matrix).
/// Returns the frames' folder.
fn visp_tracking_sequence(root: &Path) -> PathBuf {
    let frames = root.join("src").join("tetra");
    std::fs::create_dir_all(&frames).unwrap();
    write_frames(&frames, 0, |k| format!("image{k:04}.png"));
    let (r, t) = true_poses()[0];
    let row = |i: usize| format!("{} {} {} {}\n", r[i][0], r[i][1], r[i][2], t[i]);
    std::fs::write(root.join("src/tetra.0.pos"), format!("{}{}{}0 0 0 1\n", row(0), row(1), row(2))).unwrap();
    std::fs::write(root.join("src/tetra.xml"), settings()).unwrap();
    std::fs::write(root.join("src/tetra.cao"), TETRAHEDRON).unwrap();
    frames
}

#[test]
fn a_tracking_sequence_without_truth_starts_from_its_first_pose() {
    let root = crate::common::scratch("import-visp", "tracking-sequence");
    let src = visp_tracking_sequence(&root);
    let seq = root.join("seq");
    let stderr = import_ok(&src, &seq);
    assert!(stderr.contains("wrote 3 frames of 64x48") && stderr.contains("no truth"), "{stderr}");
    assert!(!seq.join("truth.jsonl").exists(), "no truth to write");
    assert_eq!(std::fs::read_to_string(seq.join("model.cao")).unwrap(), TETRAHEDRON);

    let init: InitState = serde_json::from_str(&std::fs::read_to_string(seq.join("init.json")).unwrap()).unwrap();
    let pose = init.pose.expect("the first frame's pose");
    let (r, t) = true_poses()[0];
    for a in 0..3 {
        assert!(close(pose.rotation[a], TRUE_AXIS_ANGLES[0][a]), "rotation {:?}", pose.rotation);
        assert!(close(pose.translation[a], t[a]), "translation {:?}", pose.translation);
    }
    for (i, p) in vertices().iter().enumerate() {
        let (pixel, _) = project(&r, &t, p);
        let got = init.corners[i];
        assert!(close(got[0], pixel[0]) && close(got[1], pixel[1]), "vertex {i}: {got:?} vs {pixel:?}");
    }
    for k in 0..3u32 {
        let frame = image::open(seq.join(format!("frames/{k:06}.png"))).unwrap();
        let grey = frame.as_luma8().expect("frames are written grey");
        let (x, y) = (5, 7);
        let [cr, cg, cb] = colour(k, x, y);
        assert_eq!(grey.get_pixel(x, y).0[0], pipetrack::image::luma(cr, cg, cb), "frame {k}");
    }
    let opened = pipetrack::io::Sequence::open(&seq, false).unwrap();
    assert_eq!(opened.frame_count(), Some(3));
}

#[test]
fn a_tracking_sequence_without_its_first_pose_or_frames_is_refused_by_name() {
    let root = crate::common::scratch("import-visp", "tracking-sequence-no-pose");
    let src = visp_tracking_sequence(&root);
    std::fs::remove_file(root.join("src/tetra.0.pos")).unwrap();
    expect_refused(&root, &src, &["tetra.0.pos", "missing", "pose of the first frame"]);

    let root = crate::common::scratch("import-visp", "tracking-sequence-no-frames");
    let src = visp_tracking_sequence(&root);
    std::fs::remove_file(src.join("image0001.png")).unwrap();
    expect_refused(&root, &src, &["image0002.png", "frame 1 is missing"]);
    for k in [0, 2] {
        std::fs::remove_file(src.join(format!("image{k:04}.png"))).unwrap();
    }
    expect_refused(&root, &src, &["neither a ViSP data set", "image0000.png"]);
}

/// An overlay folder that is the output folder, or lies in it, is refused
/// before anything is written.
#[test]
fn an_overlay_in_the_output_folder_is_refused() {
    let root = crate::common::scratch("import-visp", "overlay-in-out");
    let src = visp_data_set(&root);
    let seq = root.join("seq");
    // The output folder itself, a folder in it (also through `..`), and a
    // folder holding it.
    let through = root.join("src").join("..").join("seq").join("overlay");
    for overlay in [seq.clone(), seq.join("overlay"), through, root.to_path_buf()] {
        let overlay = overlay.to_str().unwrap();
        expect_refused_with(&root, &src, &["--overlay", overlay], &["give --overlay a folder of its own"]);
    }
    // Beside it through `..`: written.
    let beside = seq.join("..").join("overlay");
    let out = pipetrack(&[
        "import-visp",
        src.to_str().unwrap(),
        seq.to_str().unwrap(),
        "--overlay",
        beside.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(root.join("overlay").is_dir() && seq.join("init.json").is_file());
}

/// Intrinsics that put the model beside the frames: the import says that no
/// image edge was found, not a mean distance over no points.
#[test]
fn an_import_that_finds_no_image_edge_says_so() {
    let root = crate::common::scratch("import-visp", "no-edges");
    let src = visp_data_set(&root);
    let far = settings().replace(&format!("<u0>{CX}</u0>"), &format!("<u0>{}</u0>", 5.0 * f64::from(WIDTH)));
    assert_ne!(far, settings());
    std::fs::write(src.join("Config/tetra.xml"), far).unwrap();
    let seq = root.join("seq");
    let stderr = import_ok(&src, &seq);
    assert!(stderr.contains("no image edge found near the visible edges"), "{stderr}");
    assert!(!stderr.contains("px mean"), "{stderr}");
}

/// An error names a folder as the command line gave it, not its full path.
#[test]
fn a_tracking_sequence_given_by_a_relative_path_is_named_so() {
    let root = crate::common::scratch("import-visp", "tracking-sequence-relative");
    let src = visp_tracking_sequence(&root);
    std::fs::remove_file(root.join("src/tetra.0.pos")).unwrap();
    let out = pipetrack_in(root.path(), &["import-visp", "src/tetra", "seq"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.starts_with("pipetrack: src/tetra.0.pos: missing"), "{stderr}");
    for k in 0..3 {
        std::fs::remove_file(src.join(format!("image{k:04}.png"))).unwrap();
    }
    let out = pipetrack_in(src.parent().unwrap(), &["import-visp", "tetra", "seq"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.starts_with("pipetrack: tetra: neither a ViSP data set"), "{stderr}");
    assert!(!root.join("seq").exists() && !root.join("src/seq").exists(), "nothing written");
}

/// As ViSP's `mbt-depth/castel`: frames `image_0000.png …` in a folder
/// named unlike the model, the only `.cao` beside it taken, its settings
/// and first pose named like the model; `--init` names another pose file.
#[test]
fn a_tracking_sequence_named_unlike_its_model_and_an_init_option() {
    let root = crate::common::scratch("import-visp", "tracking-sequence-castel");
    let tetra = visp_tracking_sequence(&root);
    let film = root.join("src/film");
    std::fs::rename(&tetra, &film).unwrap();
    for k in 0..3 {
        std::fs::rename(film.join(format!("image{k:04}.png")), film.join(format!("image_{k:04}.png"))).unwrap();
    }
    let seq = root.join("seq");
    import_ok(&film, &seq);
    let init: InitState = serde_json::from_str(&std::fs::read_to_string(seq.join("init.json")).unwrap()).unwrap();
    let pose = init.pose.expect("the first frame's pose");
    assert!(close(pose.rotation[0], TRUE_AXIS_ANGLES[0][0]), "rotation {:?}", pose.rotation);
    assert_eq!(pipetrack::io::Sequence::open(&seq, false).unwrap().frame_count(), Some(3));

    // The pose under another name: refused by its default name, taken with --init.
    std::fs::remove_dir_all(&seq).unwrap();
    std::fs::rename(root.join("src/tetra.0.pos"), root.join("src/start.pos")).unwrap();
    expect_refused(&root, &film, &["tetra.0.pos", "missing", "--init"]);
    let out = pipetrack(&["import-visp", film.to_str().unwrap(), seq.to_str().unwrap(), "--init", "start.pos"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let again: InitState = serde_json::from_str(&std::fs::read_to_string(seq.join("init.json")).unwrap()).unwrap();
    assert_eq!(again.pose, init.pose);
}

/// A tracking sequence given as `.` from inside its folder is named by the
/// folder; `--init` with a data set is refused in one line.
#[test]
fn a_tracking_sequence_given_as_dot_and_init_with_a_data_set() {
    let root = crate::common::scratch("import-visp", "dot");
    let src = visp_tracking_sequence(&root);
    let seq = root.join("seq");
    let out = pipetrack_in(&src, &["import-visp", ".", seq.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(pipetrack::io::Sequence::open(&seq, false).unwrap().frame_count(), Some(3));

    let root = crate::common::scratch("import-visp", "init-with-data-set");
    let src = visp_data_set(&root);
    expect_refused_with(&root, &src, &["--init", "x.pos"], &["--init is for a folder of frames"]);
}

/// The tetrahedron as a Wavefront OBJ (the faces of `TETRAHEDRON`, 1-based).
const TETRAHEDRON_OBJ: &str = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/// 4×4 row-major matrix of `(R, t)`.
fn matrix((r, t): &([[f64; 3]; 3], [f64; 3])) -> [[f64; 4]; 4] {
    [
        [r[0][0], r[0][1], r[0][2], t[0]],
        [r[1][0], r[1][1], r[1][2], t[1]],
        [r[2][0], r[2][1], r[2][2], t[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

fn product(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..4).map(|k| a[i][k] * b[k][j]).sum()))
}

/// A sequence filmed beside a tag grid, in the layout of ViSP's
/// `rbt/sequence`, under `root/data`: the three frames, the object
/// `tetra`'s first pose, and per frame the grid's pose cMg = cMo·oMg for a
/// grid placed at oMg (a quarter turn about y, 0.3 m away) in the object's
/// frame, so that cMg(k)·cMg(0)⁻¹·cMo(0) is the true pose of frame k.
fn tag_grid_sequence(root: &Path) -> PathBuf {
    let src = root.join("data/sequence");
    std::fs::create_dir_all(src.join("init")).unwrap();
    std::fs::create_dir_all(root.join("data/models/tetra")).unwrap();
    write_frames(&src, 1, |k| format!("color_image_{k:04}.png"));
    let o_m_g = matrix(&([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]], [0.3, -0.1, 0.05]));
    let grid: Vec<[[f64; 4]; 4]> = true_poses().iter().map(|pose| product(&matrix(pose), &o_m_g)).collect();
    let json = serde_json::json!({ "tag_size": 0.1, "grid": grid, "detections": [] });
    std::fs::write(src.join("apriltag_data.json"), json.to_string()).unwrap();
    std::fs::write(src.join("init/tetra.json"), serde_json::json!(matrix(&true_poses()[0])).to_string()).unwrap();
    std::fs::write(src.join("camera.xml"), settings()).unwrap();
    std::fs::write(root.join("data/models/tetra/tetra.obj"), TETRAHEDRON_OBJ).unwrap();
    src
}

#[test]
fn a_sequence_filmed_beside_a_tag_grid_gets_its_truth_from_the_grid() {
    let root = crate::common::scratch("import-visp", "tag-grid");
    let src = tag_grid_sequence(&root);
    let seq = root.join("seq");
    let stderr = import_ok(&src, &seq);
    assert!(stderr.contains("wrote 3 frames of 64x48"), "{stderr}");
    assert_eq!(std::fs::read_to_string(seq.join("model.obj")).unwrap(), TETRAHEDRON_OBJ);
    let camera: Camera = serde_json::from_str(&std::fs::read_to_string(seq.join("camera.json")).unwrap()).unwrap();
    assert_eq!(camera, Camera { width: WIDTH, height: HEIGHT, fx: FX, fy: FY, cx: CX, cy: CY });
    checked_truth(&seq);
    let meta = std::fs::read_to_string(seq.join("meta.json")).unwrap();
    assert!(meta.contains("tag grid"), "{meta}");
}

#[test]
fn a_tag_grid_sequence_with_two_objects_or_too_few_grid_poses_is_refused() {
    let root = crate::common::scratch("import-visp", "tag-grid-bad");
    let src = tag_grid_sequence(&root);
    let dragon = src.join("init/dragon.json");
    std::fs::copy(src.join("init/tetra.json"), &dragon).unwrap();
    let refused = |extra: &[&str], needles: &[&str]| {
        let seq = root.join("seq");
        let out = pipetrack(&[&["import-visp", src.to_str().unwrap(), seq.to_str().unwrap()], extra].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        for n in needles {
            assert!(stderr.contains(n), "{n:?} missing from {stderr}");
        }
        assert!(!seq.exists());
    };
    refused(&[], &["init", "dragon.json, tetra.json", "--init init/NAME.json"]);
    // --init chooses the object; the dragon has no model.
    refused(&["--init", "init/dragon.json"], &["models/dragon/dragon.obj", "missing"]);
    std::fs::remove_file(&dragon).unwrap();
    let grid = src.join("apriltag_data.json");
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&grid).unwrap()).unwrap();
    json["grid"].as_array_mut().unwrap().truncate(2);
    std::fs::write(&grid, json.to_string()).unwrap();
    refused(&[], &["apriltag_data.json", "\"grid\" has 2 poses for 3 frames"]);
    json["grid"] = serde_json::json!([[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1]]]);
    std::fs::write(&grid, json.to_string()).unwrap();
    refused(&[], &["apriltag_data.json", "\"grid\" pose 0: not a 4×4 matrix"]);
}
