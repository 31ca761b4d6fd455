//! What each fuzz target does with its bytes: write them where the parser
//! reads them (a file in a good sequence folder, a `.cao` next to the files
//! it may `load`, a config file) or hand them over as a stream, and call the
//! library's public entry point. A target asserts only that the call
//! returns, `Ok` or `Err`: a panic, an abort or a hang is what libFuzzer
//! reports. The stable twin of these targets, with checks of the error
//! messages too, is `tests/io/fuzz.rs`.

use std::fs;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use pipetrack::cli::import_visp::{loaded_files, parse_pose, read_camera};
use pipetrack::cli::score::{read_predictions, score_file};
use pipetrack::io::cao::read_cao;
use pipetrack::io::formats::TruthFrame;
use pipetrack::io::obj::read_obj;
use pipetrack::io::y4m::Y4mReader;
use pipetrack::track::make_tracker;
use pipetrack::{CpuBackend, GrayImage, Sequence, track_frames};

const CAMERA: &str = r#"{"width":4,"height":3,"fx":100.0,"fy":100.0,"cx":1.5,"cy":1.0}"#;
const SQUARE: &str = r#"{"name":"square","units":"m",
 "vertices":[[0,0,0],[0.1,0,0],[0.1,0.1,0],[0,0.1,0]],
 "edges":[[0,1],[1,2],[2,3],[3,0]],
 "faces":[[0,1,2,3]]}"#;
const INIT: &str = r#"{"pose":{"rotation":[0,0,0],"translation":[0,0,1]},"corners":[[1,1],[2,1],[2,2],[1,2]]}"#;
const TRUTH: &str = "{\"frame\":0,\"corners\":[[1,1],[2,1],[2,2],[1,2]]}\n{\"frame\":1,\"visible\":false}\n";
/// The camera and first state of the config targets' sequence: the 0.1 m
/// square at 1 m seen 20 px wide, corners (14, 8) to (34, 28).
const TRACKING_CAMERA: &str = r#"{"width":48,"height":36,"fx":200.0,"fy":200.0,"cx":24.0,"cy":18.0}"#;
const TRACKING_INIT: &str =
    r#"{"pose":{"rotation":[0,0,0],"translation":[-0.05,-0.05,1]},"corners":[[14,8],[34,8],[34,28],[14,28]]}"#;
const SQUARE_CAO: &str = "V1\n4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0\n0\n1\n4 0 1 2 3\n0\n0\n";

/// Write `data` to `path` as a new file (removing the old one first spares
/// ext4 a flush per run).
fn put(path: &Path, data: &[u8]) {
    let _ = fs::remove_file(path);
    fs::write(path, data).expect("the fuzz folder is writable");
}

/// A folder of this process under the temp dir, named `name`, emptied.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipetrack-fuzz-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(dir.join("frames")).expect("the temp dir is writable");
    dir
}

/// A good 4×3 sequence folder (square model, two frames), made once per
/// `name`; each target overwrites only its own file in it.
fn sequence_dir(cell: &'static OnceLock<PathBuf>, name: &str) -> &'static Path {
    cell.get_or_init(|| {
        let dir = scratch(name);
        put(&dir.join("camera.json"), CAMERA.as_bytes());
        put(&dir.join("model.json"), SQUARE.as_bytes());
        put(&dir.join("init.json"), INIT.as_bytes());
        put(&dir.join("truth.jsonl"), TRUTH.as_bytes());
        for k in 0..2u8 {
            let pixels: Vec<u8> = (0..12).map(|i| 10 * k + i).collect();
            let frame = dir.join(format!("frames/00000{k}.png"));
            image::save_buffer(frame, &pixels, 4, 3, image::ExtendedColorType::L8).expect("frame written");
        }
        dir
    })
}

/// `camera.json` of a sequence folder: [`Sequence::open`].
pub fn camera_json(data: &[u8]) {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = sequence_dir(&DIR, "camera");
    put(&dir.join("camera.json"), data);
    let _ = Sequence::open(dir, false);
}

/// `model.json` of a sequence folder: [`Sequence::open`].
pub fn model_json(data: &[u8]) {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = sequence_dir(&DIR, "model");
    put(&dir.join("model.json"), data);
    let _ = Sequence::open(dir, false);
}

/// `init.json` of a sequence folder: [`Sequence::open`].
pub fn init_json(data: &[u8]) {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = sequence_dir(&DIR, "init");
    put(&dir.join("init.json"), data);
    let _ = Sequence::open(dir, false);
}

/// `truth.jsonl` of a good sequence: [`Sequence::read_truth`].
pub fn truth_jsonl(data: &[u8]) {
    static SEQ: OnceLock<Sequence> = OnceLock::new();
    let seq = SEQ.get_or_init(|| {
        static DIR: OnceLock<PathBuf> = OnceLock::new();
        Sequence::open(sequence_dir(&DIR, "truth"), false).expect("the fixture is a good sequence")
    });
    put(&seq.truth_path(), data);
    let _ = seq.read_truth();
}

/// A tracker output file: [`read_predictions`], and [`score_file`] against
/// a good `truth.jsonl`.
pub fn predictions_jsonl(data: &[u8]) {
    static FIXTURE: OnceLock<(Vec<TruthFrame>, PathBuf)> = OnceLock::new();
    let (truth, path) = FIXTURE.get_or_init(|| {
        static DIR: OnceLock<PathBuf> = OnceLock::new();
        let dir = sequence_dir(&DIR, "predictions");
        let truth = Sequence::open(dir, false).and_then(|s| s.read_truth()).expect("good truth");
        (truth, dir.join("pred.jsonl"))
    });
    put(path, data);
    let _ = read_predictions(path);
    let _ = score_file(truth, path);
}

/// A `.cao` model next to files it may include (`part.cao`,
/// `sub/part.cao`, which includes `../part.cao`): [`read_cao`], and
/// [`loaded_files`] (what `import-visp` copies beside the model).
pub fn cao(data: &[u8]) {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = DIR.get_or_init(|| {
        let dir = scratch("cao");
        fs::create_dir_all(dir.join("sub")).expect("the temp dir is writable");
        put(&dir.join("part.cao"), SQUARE_CAO.as_bytes());
        put(&dir.join("sub/part.cao"), b"V1\nload(\"../part.cao\")\n0\n0\n0\n0\n");
        dir
    });
    let path = dir.join("model.cao");
    put(&path, data);
    let _ = read_cao(&path);
    let _ = loaded_files(&path);
}

/// A Wavefront `.obj` model.
pub fn obj(data: &[u8]) {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = DIR.get_or_init(|| scratch("obj"));
    let path = dir.join("model.obj");
    put(&path, data);
    let _ = read_obj(&path);
}

/// A Y4M stream's header: [`Y4mReader::with_name`].
pub fn y4m_header(data: &[u8]) {
    let _ = Y4mReader::with_name(data, Path::new("fuzz.y4m"));
}

/// A whole Y4M stream, every frame read, alternately into a reused image
/// and as a new one.
pub fn y4m_frames(data: &[u8]) {
    let Ok(mut reader) = Y4mReader::with_name(Cursor::new(data), Path::new("fuzz.y4m")) else { return };
    let mut image = GrayImage::new(0, 0);
    for k in 0.. {
        let next =
            if k % 2 == 0 { reader.read_frame_into(&mut image) } else { reader.next_frame().map(|f| f.is_some()) };
        if !matches!(next, Ok(true)) {
            return;
        }
        // Every frame consumes at least its FRAME line.
        assert!(k <= data.len(), "{k} frames from {} bytes", data.len());
    }
}

/// A 48×36 sequence of the square model, bright on a dark ground and moving
/// a pixel a frame, and its three frames: what the config targets track.
fn tracking_sequence(name: &str) -> (Sequence, Vec<GrayImage>) {
    let dir = scratch(name);
    put(&dir.join("camera.json"), TRACKING_CAMERA.as_bytes());
    put(&dir.join("model.json"), SQUARE.as_bytes());
    put(&dir.join("init.json"), TRACKING_INIT.as_bytes());
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
        image::save_buffer(path, frame.data(), 48, 36, image::ExtendedColorType::L8).expect("frame written");
    }
    (Sequence::open(&dir, false).expect("the fixture is a good sequence"), frames)
}

/// A config file for `tracker`: [`make_tracker`] on a good sequence, which
/// reads the file (`read_config`), checks the parameters and builds the
/// tracker, then the tracker on the sequence's frames (CPU backend).
fn config(cell: &'static OnceLock<(Sequence, Vec<GrayImage>)>, tracker: &str, data: &[u8]) {
    let (seq, frames) = cell.get_or_init(|| tracking_sequence(&format!("config-{tracker}")));
    let path = seq.dir().join("config.toml");
    put(&path, data);
    let Ok(mut tracker) = make_tracker(tracker, seq, Some(&path)) else { return };
    let size = (seq.camera.width as usize, seq.camera.height as usize);
    let frames = frames.iter().map(Ok::<_, pipetrack::Error>);
    let _ = track_frames(tracker.as_mut(), &mut CpuBackend::new(), frames, size, |_, _, _| Ok(()));
}

/// A motion-edge config file.
pub fn config_motion_edge(data: &[u8]) {
    static FIXTURE: OnceLock<(Sequence, Vec<GrayImage>)> = OnceLock::new();
    config(&FIXTURE, "motion-edge", data);
}

/// A blue config file.
pub fn config_blue(data: &[u8]) {
    static FIXTURE: OnceLock<(Sequence, Vec<GrayImage>)> = OnceLock::new();
    config(&FIXTURE, "blue", data);
}

/// A condensation config file.
pub fn config_condensation(data: &[u8]) {
    static FIXTURE: OnceLock<(Sequence, Vec<GrayImage>)> = OnceLock::new();
    config(&FIXTURE, "condensation", data);
}

/// A lowe config file.
pub fn config_lowe(data: &[u8]) {
    static FIXTURE: OnceLock<(Sequence, Vec<GrayImage>)> = OnceLock::new();
    config(&FIXTURE, "lowe", data);
}

/// A ViSP pose file (`import-visp`'s first pose): [`parse_pose`].
pub fn visp_pose(data: &[u8]) {
    let _ = parse_pose(&String::from_utf8_lossy(data));
}

/// ViSP camera settings (`import-visp`'s intrinsics, XML): [`read_camera`]
/// for 4×3 frames.
pub fn visp_camera(data: &[u8]) {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = DIR.get_or_init(|| scratch("visp-camera"));
    let path = dir.join("camera.xml");
    put(&path, data);
    let _ = read_camera(&path, 4, 3);
}
