//! Reading sequence folders (SPEC §4) and the bad inputs of SPEC §5: every
//! one must be an `Error::Input` with a one-line message naming the right
//! file. Each test builds a small folder under the system temp dir.

use std::fs;
use std::path::{Path, PathBuf};

use pipetrack::Error;
use pipetrack::io::formats::{Camera, Visibility};
use pipetrack::io::{FrameSource, Sequence};

/// A sequence folder under the temp dir, removed when dropped.
struct Folder(PathBuf);

impl Folder {
    /// A good 4×3 sequence: a planar square model, init corners, two grey
    /// frames whose pixel `i` is `10 * k + i` in frame `k`.
    fn good(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("pipetrack-seqio-{}-{name}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(dir.join("frames")).unwrap();
        let f = Folder(dir);
        f.write("camera.json", r#"{"width":4,"height":3,"fx":100.0,"fy":100.0,"cx":1.5,"cy":1.0}"#);
        f.write(
            "model.json",
            r#"{"name":"square","units":"m",
               "vertices":[[0,0,0],[0.1,0,0],[0.1,0.1,0],[0,0.1,0]],
               "edges":[[0,1],[1,2],[2,3],[3,0]],
               "faces":[[0,1,2,3]]}"#,
        );
        f.write(
            "init.json",
            r#"{"pose":{"rotation":[0,0,0],"translation":[0,0,1]},"corners":[[1,1],[2,1],[2,2],[1,2]]}"#,
        );
        for k in 0..2u8 {
            f.gray_png(&format!("frames/00000{k}.png"), 4, 3, |i| 10 * k + i as u8);
        }
        f
    }

    fn path(&self, rel: &str) -> PathBuf {
        self.0.join(rel)
    }

    fn write(&self, rel: &str, text: &str) {
        fs::write(self.path(rel), text).unwrap();
    }

    fn remove(&self, rel: &str) {
        let p = self.path(rel);
        if p.is_dir() { fs::remove_dir_all(p).unwrap() } else { fs::remove_file(p).unwrap() }
    }

    fn gray_png(&self, rel: &str, w: u32, h: u32, pixel: impl Fn(usize) -> u8) {
        let data: Vec<u8> = (0..(w * h) as usize).map(pixel).collect();
        image::save_buffer(self.path(rel), &data, w, h, image::ExtendedColorType::L8).unwrap();
    }

    fn open(&self) -> pipetrack::Result<Sequence> {
        Sequence::open(&self.0, false)
    }
}

impl Drop for Folder {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// The path and message of an input error, checking the path ends with
/// `file` and the message is one line.
fn input_error<T: std::fmt::Debug>(result: pipetrack::Result<T>, file: &str) -> String {
    match result {
        Err(Error::Input { path, message }) => {
            assert!(path.ends_with(file), "error names {} instead of {file}: {message}", path.display());
            assert!(!message.contains('\n'), "message spans lines: {message}");
            message
        }
        other => panic!("expected an input error naming {file}, got {other:?}"),
    }
}

/// Collect all frames, returning the first error.
fn all_frames(seq: &Sequence) -> pipetrack::Result<Vec<pipetrack::GrayImage>> {
    seq.frames().collect()
}

#[test]
fn good_folder_loads_and_streams_frames() {
    let f = Folder::good("good");
    let seq = f.open().unwrap();
    assert_eq!(seq.camera, Camera { width: 4, height: 3, fx: 100.0, fy: 100.0, cx: 1.5, cy: 1.0 });
    assert_eq!(seq.model.vertices.len(), 4);
    assert_eq!(seq.init.corners.len(), 4);
    assert!(seq.model_path().ends_with("model.json"));
    assert_eq!(seq.frame_count(), Some(2));
    let frames = all_frames(&seq).unwrap();
    assert_eq!(frames.len(), 2);
    assert_eq!(frames[1].size(), (4, 3));
    assert_eq!(frames[1].data()[..3], [10, 11, 12]);
    assert!(input_error(seq.read_truth(), "truth.jsonl").starts_with("missing"));
}

#[test]
fn good_truth_loads() {
    let f = Folder::good("truth-good");
    f.write(
        "truth.jsonl",
        "{\"frame\":0,\"visible\":true,\"corners\":[[1,1],[2,1],[2,2],[1,2]]}\n\n{\"frame\":1,\"visible\":false}\n",
    );
    let seq = f.open().unwrap();
    let truth = seq.read_truth().unwrap();
    assert_eq!(truth.len(), 2);
    assert!(!truth[1].visible.any());
}

#[test]
fn model_json_wins_over_model_cao() {
    let f = Folder::good("json-wins");
    let cube = "V1\n8\n0 0 0\n0 0 1\n0 1 1\n0 1 0\n1 0 0\n1 0 1\n1 1 1\n1 1 0\n0\n0\n\
                6\n4 0 1 2 3\n4 4 7 6 5\n4 0 4 5 1\n4 3 2 6 7\n4 0 3 7 4\n4 1 5 6 2\n0\n0\n";
    f.write("model.cao", cube);
    let seq = f.open().unwrap();
    assert_eq!(seq.model.vertices.len(), 4);
    assert!(seq.model_path().ends_with("model.json"));

    // Without model.json, model.cao is read (8 vertices, so 4 init corners is
    // fewer than the vertices: give init a pose only).
    f.remove("model.json");
    f.write("init.json", r#"{"pose":{"rotation":[0,0,0],"translation":[0,0,3]}}"#);
    let seq = f.open().unwrap();
    assert_eq!(seq.model.vertices.len(), 8);
    assert_eq!(seq.model.edges.len(), 12);
    assert!(seq.model_path().ends_with("model.cao"));
}

#[test]
fn extra_files_are_ignored() {
    let f = Folder::good("extra");
    f.write("meta.json", "not even json");
    f.write("notes.txt", "hello");
    f.write("frames/readme.txt", "frames go here");
    f.write("frames/.000000.png", "macOS resource fork, not an image");
    fs::create_dir(f.path("frames/sub.png")).unwrap();
    let seq = f.open().unwrap();
    assert_eq!(seq.frame_count(), Some(2));
    assert_eq!(all_frames(&seq).unwrap().len(), 2);
}

#[test]
fn frames_sort_by_name_with_numbers_as_numbers() {
    let f = Folder::good("order");
    f.remove("frames");
    fs::create_dir(f.path("frames")).unwrap();
    // 1 to 10 in an order where plain string order would put 10 before 2.
    let mut names: Vec<(String, u8)> = vec![("10.png".into(), 10), ("2.png".into(), 2), ("1.PNG".into(), 1)];
    names.extend((3..10).map(|k| (format!("{k}.png"), k)));
    for (name, v) in names {
        f.gray_png(&format!("frames/{name}"), 4, 3, |_| v);
    }
    let seq = f.open().unwrap();
    let firsts: Vec<u8> = all_frames(&seq).unwrap().iter().map(|im| im.data()[0]).collect();
    assert_eq!(firsts, [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
}

#[test]
fn a_gap_in_the_frame_numbers_names_the_missing_frame() {
    let f = Folder::good("gap");
    f.gray_png("frames/000003.png", 4, 3, |_| 0);
    let msg = input_error(f.open(), "frames/000002.png");
    assert!(msg.starts_with("missing") && msg.contains("000001.png") && msg.contains("000003.png"), "{msg}");

    // Numbering from 1 is accepted; from 2 the first frame is missing.
    f.remove("frames/000003.png");
    f.remove("frames/000000.png");
    f.gray_png("frames/000002.png", 4, 3, |_| 0);
    assert_eq!(f.open().unwrap().frame_count(), Some(2));
    f.remove("frames/000001.png");
    f.gray_png("frames/000003.png", 4, 3, |_| 0);
    assert!(input_error(f.open(), "frames/000000.png").starts_with("missing"));

    // A folder named like the next frame is named as such, not as a gap.
    let f = Folder::good("folder-frame");
    std::fs::create_dir(f.path("frames/000002.png")).unwrap();
    f.gray_png("frames/000003.png", 4, 3, |_| 0);
    assert!(input_error(f.open(), "frames/000002.png").starts_with("is a folder"));

    let f = Folder::good("same-number");
    f.gray_png("frames/1.png", 4, 3, |_| 0);
    assert!(input_error(f.open(), "frames/1.png").contains("frame number of 000001.png"));

    let f = Folder::good("no-number");
    f.gray_png("frames/last.png", 4, 3, |_| 0);
    assert!(input_error(f.open(), "frames/last.png").contains("no number"));
}

#[test]
fn rgb_and_rgba_png_frames_become_bt601_luma() {
    let f = Folder::good("rgb");
    let rgb = [255, 0, 0, 0, 255, 0, 0, 0, 255, 10, 20, 30];
    let rgb: Vec<u8> = rgb.iter().copied().cycle().take(4 * 3 * 3).collect();
    image::save_buffer(f.path("frames/000000.png"), &rgb, 4, 3, image::ExtendedColorType::Rgb8).unwrap();
    let rgba: Vec<u8> = rgb.chunks(3).flat_map(|p| [p[0], p[1], p[2], 7]).collect();
    image::save_buffer(f.path("frames/000001.png"), &rgba, 4, 3, image::ExtendedColorType::Rgba8).unwrap();
    let seq = f.open().unwrap();
    let frames = all_frames(&seq).unwrap();
    // 0.299·255 = 76.2, 0.587·255 = 149.7, 0.114·255 = 29.1, 0.299·10 + 0.587·20 + 0.114·30 = 18.15.
    assert_eq!(frames[0].data()[..4], [76, 150, 29, 18]);
    assert_eq!(frames[1].data(), frames[0].data());
}

#[test]
fn pgm_frames_load() {
    let f = Folder::good("pgm");
    f.remove("frames/000001.png");
    let mut pgm = b"P5\n4 3\n255\n".to_vec();
    pgm.extend(0..12u8);
    fs::write(f.path("frames/000001.pgm"), pgm).unwrap();
    let frames = all_frames(&f.open().unwrap()).unwrap();
    assert_eq!(frames[1].data()[11], 11);
}

#[test]
fn missing_files_are_named() {
    for file in ["camera.json", "init.json", "model.json"] {
        let f = Folder::good(&format!("missing-{file}"));
        f.remove(file);
        let msg = input_error(f.open(), file);
        assert!(msg.starts_with("missing"), "{msg}");
    }
    let f = Folder::good("missing-frames");
    f.remove("frames");
    assert!(input_error(f.open(), "frames").starts_with("missing"));
    // With frames on stdin, no frames folder is needed.
    let seq = Sequence::open(&f.0, true).unwrap();
    assert!(seq.reads_stdin() && seq.frame_count().is_none());
    let no_folder = f.path("no-such-sequence");
    assert_eq!(input_error(Sequence::open(&no_folder, false), "no-such-sequence"), "no such folder");
}

#[test]
fn corrupt_png_is_named() {
    let f = Folder::good("corrupt");
    let mut bytes = fs::read(f.path("frames/000001.png")).unwrap();
    bytes.truncate(bytes.len() / 2);
    fs::write(f.path("frames/000001.png"), bytes).unwrap();
    let seq = f.open().unwrap();
    let mut frames = seq.frames();
    assert!(frames.next().unwrap().is_ok());
    let msg = input_error(frames.next().unwrap(), "frames/000001.png");
    assert!(msg.starts_with("corrupt image"), "{msg}");
    assert!(frames.next().is_none(), "the source ends after an error");

    // A first frame that is not an image at all fails at open.
    f.write("frames/000000.png", "this is not a PNG");
    input_error(f.open(), "frames/000000.png");
}

#[test]
fn malformed_json_is_named_with_position() {
    let f = Folder::good("malformed");
    f.write("camera.json", "{\"width\":4,\n\"height\":3 \"fx\":1}");
    let msg = input_error(f.open(), "camera.json");
    assert!(msg.starts_with("malformed JSON at line 2 column"), "{msg}");

    let f = Folder::good("wrong-field");
    f.write("init.json", r#"{"corners":"here"}"#);
    assert!(input_error(f.open(), "init.json").starts_with("wrong content"));

    let f = Folder::good("empty-json");
    f.write("model.json", "  \n");
    assert_eq!(input_error(f.open(), "model.json"), "empty file");
}

#[test]
fn frames_of_changing_size_are_named_with_both_sizes() {
    let f = Folder::good("size");
    f.gray_png("frames/000001.png", 5, 3, |_| 0);
    let seq = f.open().unwrap();
    let err = all_frames(&seq);
    let msg = input_error(err, "frames/000001.png");
    assert!(msg.contains("5x3") && msg.contains("4x3"), "{msg}");

    // A first frame that disagrees with camera.json fails at open.
    f.gray_png("frames/000000.png", 8, 6, |_| 0);
    let msg = input_error(f.open(), "frames/000000.png");
    assert!(msg.contains("8x6") && msg.contains("camera.json") && msg.contains("4x3"), "{msg}");
}

#[test]
fn empty_folders_are_errors() {
    let f = Folder::good("empty");
    for entry in fs::read_dir(&f.0).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() { fs::remove_dir_all(p).unwrap() } else { fs::remove_file(p).unwrap() }
    }
    let name = f.0.file_name().unwrap().to_str().unwrap().to_string();
    assert!(input_error(f.open(), &name).starts_with("empty folder"));

    let f = Folder::good("empty-frames");
    f.remove("frames");
    fs::create_dir(f.path("frames")).unwrap();
    f.write("frames/list.txt", "no images");
    assert!(input_error(f.open(), "frames").starts_with("no frames"));
}

#[test]
fn nan_and_bad_intrinsics_are_rejected() {
    let f = Folder::good("nan");
    f.write("camera.json", r#"{"width":4,"height":3,"fx":NaN,"fy":100.0,"cx":1.5,"cy":1.0}"#);
    let msg = input_error(f.open(), "camera.json");
    assert!(msg.starts_with("NaN at line 1 column") && msg.contains("finite"), "{msg}");

    f.write("camera.json", r#"{"width":4,"height":3,"fx":100,"fy":100.0,"cx":-Infinity,"cy":1.0}"#);
    assert!(input_error(f.open(), "camera.json").starts_with("Infinity"));

    f.write("camera.json", r#"{"width":4,"height":3,"fx":0,"fy":100.0,"cx":1.5,"cy":1.0}"#);
    assert!(input_error(f.open(), "camera.json").starts_with("fx = 0"));

    f.write("camera.json", r#"{"width":0,"height":3,"fx":1,"fy":100.0,"cx":1.5,"cy":1.0}"#);
    assert!(input_error(f.open(), "camera.json").contains("must be > 0"));

    f.write("camera.json", r#"{"width":4,"height":3,"fx":1,"fy":100.0,"cx":1.5,"cy":1e999}"#);
    input_error(f.open(), "camera.json");
}

#[test]
fn model_with_fewer_vertices_than_init_corners_names_the_model() {
    let f = Folder::good("fewer");
    f.write("init.json", r#"{"corners":[[1,1],[2,1],[2,2],[1,2],[0,0]]}"#);
    let msg = input_error(f.open(), "model.json");
    assert!(msg.contains("4 vertices") && msg.contains("5 corners in init.json"), "{msg}");
    // Fewer corners than vertices (but some) is an init.json problem.
    f.write("init.json", r#"{"corners":[[1,1],[2,1]]}"#);
    assert!(input_error(f.open(), "init.json").contains("one corner per model vertex"));
    // Neither pose nor corners.
    f.write("init.json", "{}");
    assert!(input_error(f.open(), "init.json").contains("neither a pose nor corners"));
    // A known camera motion beyond the bound of the parameter of that name.
    f.write("init.json", r#"{"corners":[[1,1],[2,1],[2,2],[1,2]],"camera_motion":[0,0,1e300,0,0,0]}"#);
    let msg = input_error(f.open(), "init.json");
    assert!(msg.contains("camera_motion has 1.0e300") && msg.contains("±1000"), "{msg}");
}

#[test]
fn bad_models_are_named() {
    let cases = [
        (r#"[[0,1],[1,2],[2,3],[3,4]]"#, "edge 3 [3, 4] refers to a vertex beyond"),
        (r#"[[0,1],[1,2],[2,3],[1,0]]"#, "edge 3 [1, 0] repeats edge 0"),
        (r#"[[0,1],[1,2],[2,2]]"#, "edge 2 [2, 2] joins a vertex to itself"),
        (r#"[]"#, "the model has no edges"),
    ];
    for (edges, expected) in cases {
        let f = Folder::good("bad-model");
        f.write(
            "model.json",
            &format!(r#"{{"name":"sq","vertices":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]],"edges":{edges}}}"#),
        );
        // Each edge's problem names its line (the one line of this file).
        let msg = input_error(f.open(), "model.json");
        assert!(msg.strip_prefix("line 1: ").unwrap_or(&msg).starts_with(expected), "{msg}");
    }
    let f = Folder::good("bad-face");
    f.write(
        "model.json",
        r#"{"name":"sq","vertices":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]],"edges":[[0,1]],"faces":[[0,1,1]]}"#,
    );
    assert!(input_error(f.open(), "model.json").contains("face 0 lists vertex 1 twice"));
    let f = Folder::good("bad-joint");
    f.write(
        "model.json",
        r#"{"name":"sq","vertices":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]],"edges":[[0,1]],
           "joints":[{"name":"lid","origin":[0,0,0],"axis":[0,0,0],"vertices":[2,3],"min":0,"max":1}]}"#,
    );
    assert!(input_error(f.open(), "model.json").contains("axis is the zero vector"));
    // Coordinates far beyond any object: the model's size would overflow.
    f.write("model.json", r#"{"name":"sq","vertices":[[0,0,0],[1e308,0,0],[1,1,0],[0,1,0]],"edges":[[0,1]]}"#);
    assert!(input_error(f.open(), "model.json").contains("vertex 1 has a coordinate beyond ±1.0e9"));
    f.write(
        "model.json",
        r#"{"name":"sq","vertices":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]],"edges":[[0,1]],
           "joints":[{"name":"lid","origin":[0,2e9,0],"axis":[1,0,0],"vertices":[2,3],"min":0,"max":1}]}"#,
    );
    assert!(input_error(f.open(), "model.json").contains("joint \"lid\": the origin has a coordinate beyond"));
    // More vertices than a model may have.
    let many: Vec<String> = (0..100_001).map(|i| format!("[{i},0,0]")).collect();
    f.write("model.json", &format!(r#"{{"name":"line","vertices":[{}],"edges":[[0,1]]}}"#, many.join(",")));
    assert!(input_error(f.open(), "model.json").contains("the model has 100001 vertices"));
    f.write("model.cao", "V1\n2\n0 0 0\n1 0 0\n1\n0 5\n0\n0\n");
    f.remove("model.json");
    assert!(input_error(f.open(), "model.cao").starts_with("line 6: 3-D line 0: point index 5"));
}

#[test]
fn a_json_array_in_place_of_an_object_is_refused() {
    let f = Folder::good("array-camera");
    f.write("camera.json", "[4, 3, 100.0, 100.0, 1.5, 1.0]");
    assert!(input_error(f.open(), "camera.json").contains("array where an object is expected"));
    let f = Folder::good("array-init");
    f.write("init.json", " [null, [], [[1,1],[2,1],[2,2],[1,2]]]");
    input_error(f.open(), "init.json");
    let f = Folder::good("array-truth");
    f.write("truth.jsonl", "{\"frame\":0}\n[1, true]\n");
    assert!(f.open().unwrap().read_truth().is_err_and(|e| e.to_string().contains("line 2: a JSON array")));
}

#[test]
fn model_units_duplicate_vertices_and_bent_faces_are_refused() {
    let model = |units: &str, vertices: &str| {
        format!(
            r#"{{"name":"sq","units":"{units}","vertices":{vertices},"edges":[[0,1],[1,2],[2,3],[3,0]],"faces":[[0,1,2,3]]}}"#
        )
    };
    let square = "[[0,0,0],[0.1,0,0],[0.1,0.1,0],[0,0.1,0]]";
    let f = Folder::good("units");
    f.write("model.json", &model("px", square));
    f.open().expect("px, the synthetic scenes' unit, is accepted");
    f.write("model.json", &model("furlong", square));
    let msg = input_error(f.open(), "model.json");
    assert!(msg.contains("\"furlong\"") && msg.contains("m, px"), "{msg}");

    f.write("model.json", &model("m", "[[0,0,0],[0.1,0,0],[0.1,0.1,0],[0.1,0,0]]"));
    assert!(input_error(f.open(), "model.json").starts_with("line 1: vertex 3 repeats vertex 1"));
    // Coincident vertices of parts moved by different joints (a closed lid
    // on its box) are two vertices, not one listed twice.
    let jointed = r#"{"name":"sq","units":"m","vertices":[[0,0,0],[0.1,0,0],[0.1,0.1,0],[0.1,0,0]],"edges":[[0,1],[1,2],[2,0],[2,3]],"joints":[{"name":"lid","origin":[0,0,0],"axis":[0,1,0],"vertices":[3],"min":0,"max":1}]}"#;
    f.write("model.json", jointed);
    f.write("init.json", r#"{"pose":{"rotation":[0,0,0],"translation":[0,0,1]},"params":[0]}"#);
    f.open().expect("vertex 3 moves with the joint, vertex 1 does not");
    f.write("model.json", &jointed.replace(r#""vertices":[3]"#, r#""vertices":[1,3]"#));
    assert!(input_error(f.open(), "model.json").contains("vertex 3 repeats vertex 1"));
    f.write("init.json", r#"{"pose":{"rotation":[0,0,0],"translation":[0,0,1]}}"#);

    // A corner lifted by 10 % of the size is far outside the tolerance; a
    // rounding-sized lift (1e-6 of the size) is not.
    f.write("model.json", &model("m", "[[0,0,0],[0.1,0,0],[0.1,0.1,0.01],[0,0.1,0]]"));
    assert!(input_error(f.open(), "model.json").starts_with("line 1: face 0 is not planar"));
    f.write("model.json", &model("m", "[[0,0,0],[0.1,0,0],[0.1,0.1,1e-7],[0,0.1,0]]"));
    f.open().expect("a face within the tolerance is planar");
    // The tolerance scales with the model: the same shape in kilometres.
    f.write("model.json", &model("m", "[[0,0,0],[100,0,0],[100,100,0.0001],[0,100,0]]"));
    f.write("init.json", r#"{"pose":{"rotation":[0,0,0],"translation":[0,0,1000]}}"#);
    f.open().expect("tolerance relative to the model's size");

    f.write("model.json", &model("m", "[[0,0,0],[0.1,0,0],[0.2,0,0],[0.3,0,0]]"));
    assert!(input_error(f.open(), "model.json").contains("encloses no area"));
}

#[test]
fn truth_is_read_only_on_request_and_takes_per_vertex_visibility() {
    let f = Folder::good("truth-lazy");
    f.write("truth.jsonl", "this is not JSON\n");
    let seq = f.open().expect("open does not read truth.jsonl");
    assert!(input_error(seq.read_truth(), "truth.jsonl").starts_with("line 1: malformed JSON"));

    f.write(
        "truth.jsonl",
        "{\"frame\":0,\"visible\":[true,true,false,true],\"corners\":[[1,1],[2,1],[2,2],[1,2]]}\n\
         {\"frame\":1,\"visible\":false,\"occluded_fraction\":1.0}\n",
    );
    let truth = f.open().unwrap().read_truth().unwrap();
    assert_eq!(truth[0].visible, Visibility::Vertices(vec![true, true, false, true]));
    assert!(truth[0].visible.any() && !truth[0].visible.vertex(2));
    assert_eq!(truth[1].visible, Visibility::Object(false));

    f.write("truth.jsonl", "{\"frame\":0,\"visible\":[true,false]}\n");
    let msg = input_error(f.open().unwrap().read_truth(), "truth.jsonl");
    assert!(msg.starts_with("line 1: \"visible\" has 2 flags but the model has 4 vertices"), "{msg}");
    f.write("truth.jsonl", "{\"frame\":0,\"visible\":[1,0,1,1]}\n");
    let msg = input_error(f.open().unwrap().read_truth(), "truth.jsonl");
    assert!(msg.contains("wrong content"), "{msg}");
}

#[test]
fn bad_truth_lines_are_named_with_their_line() {
    let f = Folder::good("truth-bad");
    f.write("truth.jsonl", "{\"frame\":0,\"corners\":[[1,1],[2,1],[2,2],[1,2]]}\n{\"frame\":1,\"corners\":[[1,1],\n");
    let msg = input_error(f.open().unwrap().read_truth(), "truth.jsonl");
    assert!(msg.starts_with("line 2: malformed JSON at column"), "{msg}");

    f.write("truth.jsonl", "{\"frame\":1}\n{\"frame\":0}\n");
    assert!(input_error(f.open().unwrap().read_truth(), "truth.jsonl").starts_with("line 2: frame 0 after frame 1"));

    f.write("truth.jsonl", "{\"frame\":0}\n{\"frame\":5}\n");
    assert!(
        input_error(f.open().unwrap().read_truth(), "truth.jsonl")
            .starts_with("line 2: frame 5 but the sequence has 2 frames")
    );

    f.write("truth.jsonl", "{\"frame\":0,\"corners\":[[1,NaN],[2,1],[2,2],[1,2]]}\n");
    assert!(input_error(f.open().unwrap().read_truth(), "truth.jsonl").starts_with("line 1: NaN at column"));

    f.write("truth.jsonl", "{\"frame\":0,\"corners\":[[1,1],[2,1]]}\n");
    assert!(
        input_error(f.open().unwrap().read_truth(), "truth.jsonl").starts_with("line 1: 2 corners but the model has 4")
    );

    f.write("truth.jsonl", "\n\n");
    assert!(input_error(f.open().unwrap().read_truth(), "truth.jsonl").starts_with("empty file"));
}

#[test]
fn a_gap_in_truth_names_the_missing_frames() {
    let f = Folder::good("truth-gap");
    f.write("truth.jsonl", "{\"frame\":1}\n");
    let msg = input_error(f.open().unwrap().read_truth(), "truth.jsonl");
    assert!(msg.starts_with("line 1: the first frame is 1: frame 0 is missing"), "{msg}");
    // Lines counted as in the file, a blank one too.
    f.write("truth.jsonl", "\n{\"frame\":1}\n");
    let msg = input_error(f.open().unwrap().read_truth(), "truth.jsonl");
    assert!(msg.starts_with("line 2: the first frame is 1"), "{msg}");
    // A truth that stops early has no gap.
    f.write("truth.jsonl", "{\"frame\":0}\n");
    f.open().unwrap().read_truth().expect("frame 0 alone");
}

/// A 4×3 mono Y4M stream with `frames` frames.
fn y4m(w: usize, h: usize, frames: usize) -> Vec<u8> {
    let mut s = format!("YUV4MPEG2 W{w} H{h} F25:1 Cmono\n").into_bytes();
    for k in 0..frames {
        s.extend_from_slice(b"FRAME\n");
        s.extend((0..w * h).map(|i| (k + i) as u8));
    }
    s
}

fn camera() -> Camera {
    Camera { width: 4, height: 3, fx: 1.0, fy: 1.0, cx: 0.0, cy: 0.0 }
}

#[test]
fn y4m_frames_are_checked_against_the_camera() {
    let frames: Vec<_> =
        FrameSource::y4m(std::io::Cursor::new(y4m(4, 3, 3)), Path::new("-"), camera(), "camera.json".into())
            .collect::<pipetrack::Result<_>>()
            .unwrap();
    assert_eq!(frames.len(), 3);
    assert_eq!(frames[2].data()[0], 2);

    let wrong = FrameSource::y4m(std::io::Cursor::new(y4m(5, 3, 1)), Path::new("-"), camera(), "camera.json".into())
        .collect::<pipetrack::Result<Vec<_>>>();
    let msg = input_error(wrong, "-");
    assert!(msg.contains("5x3") && msg.contains("4x3"), "{msg}");

    let none = FrameSource::y4m(std::io::Cursor::new(y4m(4, 3, 0)), Path::new("-"), camera(), "camera.json".into())
        .collect::<pipetrack::Result<Vec<_>>>();
    assert!(input_error(none, "-").contains("no frames"));

    let garbage = FrameSource::y4m(
        std::io::Cursor::new(b"P5 4 3 255\n".to_vec()),
        Path::new("-"),
        camera(),
        "camera.json".into(),
    )
    .collect::<pipetrack::Result<Vec<_>>>();
    assert!(input_error(garbage, "-").starts_with("not a YUV4MPEG2 stream"));
}

#[test]
fn bundled_cube_cao_reads_as_a_closed_box() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cube.cao");
    let model = pipetrack::io::cao::read_cao(&path).expect("assets/cube.cao parses");
    assert_eq!(model.vertices.len(), 8);
    assert_eq!(model.faces.len(), 6);
    // A closed box: 12 distinct edges, every edge shared by exactly two faces.
    assert_eq!(model.edges.len(), 12);
    for e in &model.edges {
        let shared = model
            .faces
            .iter()
            .filter(|f| {
                (0..f.len()).any(|i| {
                    let (a, b) = (f[i], f[(i + 1) % f.len()]);
                    (a, b) == (e[0], e[1]) || (b, a) == (e[0], e[1])
                })
            })
            .count();
        assert_eq!(shared, 2, "edge {e:?}");
    }
}

/// A colour PNG read as colour and reduced to luma is the grey reading of
/// the same file, byte for byte; a grey PNG read as colour is grey in R, G, B.
#[test]
fn colour_and_grey_readings_of_a_frame_agree() {
    use pipetrack::io::frames::{decode_gray, decode_rgb};
    let dir = crate::common::scratch("colour_reading", "frames");
    let (w, h) = (13u32, 7u32);
    let rgb: Vec<u8> = (0..w * h * 3).map(|i| (i * 37 % 251) as u8).collect();
    let colour_path = dir.join("colour.png");
    image::save_buffer(&colour_path, &rgb, w, h, image::ColorType::Rgb8).unwrap();
    let colour = decode_rgb(&colour_path).unwrap();
    assert_eq!(colour.get(1, 0), [rgb[3], rgb[4], rgb[5]]);
    assert_eq!(colour.to_gray(), decode_gray(&colour_path).unwrap());
    let grey_path = dir.join("grey.png");
    let grey: Vec<u8> = (0..w * h).map(|i| (i * 11 % 256) as u8).collect();
    image::save_buffer(&grey_path, &grey, w, h, image::ColorType::L8).unwrap();
    let as_colour = decode_rgb(&grey_path).unwrap();
    assert!(as_colour.data().iter().zip(&grey).all(|(p, &g)| *p == [g, g, g]));
    assert_eq!(as_colour.to_gray(), decode_gray(&grey_path).unwrap());
}
