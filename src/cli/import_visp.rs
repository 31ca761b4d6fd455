//! `pipetrack import-visp SRC OUT_DIR`: a ViSP model-based-tracking data set
//! with ground truth, or a ViSP tracking sequence without it, converted to a
//! sequence folder (SPEC §4).
//!
//! The source folder has the layout of ViSP's test data for its generic
//! model-based tracker (`mbt-depth/Castle-simu` in the `visp-images` data
//! set; depth maps and other folders are ignored):
//!
//! ```text
//! SRC/Images/Image_0001.png ...   the frames (PNG, PGM, PPM or JPEG; grey or colour),
//!                                 numbered without gaps
//! SRC/CameraPose/Camera_001.txt   the true pose of frame 0001 (number printed with
//!                                 at least three digits), ViSP's cMo: either the 4×4
//!                                 homogeneous matrix, row-major (16 numbers), or the
//!                                 pose vector tx ty tz θux θuy θuz (6 numbers)
//! SRC/Config/NAME.xml             tracker settings whose <camera> element gives the
//!                                 intrinsics px, py, u0, v0 (no distortion)
//! SRC/Models/NAME.cao             the model, with the files it load()s
//! ```
//!
//! A ViSP tracking sequence without ground truth (in the same data set
//! `mbt/cube`, the video its model-based-tracking tutorials track, and
//! `mbt-depth/castel`, the castle filmed) is converted too: SRC is then the
//! folder of the frames, and the model, its settings and the first frame's
//! pose sit beside it, named as ViSP's examples name them:
//!
//! ```text
//! SRC/image0000.png ...           the frames (PNG, PGM, PPM or JPEG; also image_0000.png),
//!                                 numbered without gaps
//! SRC.cao                         the model (e.g. mbt/cube.cao for mbt/cube), else the only
//!                                 .cao beside SRC (mbt-depth/castel/chateau.cao)
//! MODEL.xml                       beside the model, named like it: the <camera> intrinsics
//! MODEL.0.pos                     beside the model, named like it: the first frame's pose, as above
//! ```
//!
//! Such a sequence has no `truth.jsonl`: its `init.json` holds the pose of
//! the first frame, and the alignment check below measures that frame only.
//!
//! A sequence filmed by a camera moving around objects at rest beside a grid
//! of AprilTags (`rbt/sequence` in the same data set, the video of ViSP's
//! render-based tracker, with several objects) is converted with its truth:
//!
//! ```text
//! SRC/color_image_0000.png ...    the frames, numbered without gaps
//! SRC/apriltag_data.json          "grid": per frame, the tag grid's pose cMg
//!                                 (4×4 matrices, row-major, as nested lists)
//! SRC/init/NAME.json              the first frame's pose cMo of the object NAME (4×4)
//! SRC/camera.xml                  the <camera> intrinsics (the first <camera>)
//! SRC/../models/NAME/NAME.obj     the object's model (Wavefront OBJ, metres)
//! ```
//!
//! The object is the one of `--init` (`init/NAME.json`), or the only one in
//! `init/`. Frame k's true pose is cMo(k) = cMg(k)·cMg(0)⁻¹·cMo(0): the object
//! and the grid do not move, so the object keeps its place in the grid's
//! frame. That truth is only as good as the grid's pose from its tags: on
//! ViSP's `rbt/sequence` a tracker's fit that lies on the cube's edges is
//! up to 20 px from it on frames where the camera moves fast (the tags
//! blurred; a shutter that rolls would also read the grid and the object
//! at different moments). The model is `model.obj`.
//!
//! ViSP's conventions are pipetrack's: cMo maps object points to the camera
//! frame (X_c = R·X_o + t), the camera frame has x right, y down, z forward,
//! u = u0 + px·X/Z with pixel (0, 0) the centre of the top-left pixel, θu is
//! the axis-angle vector, and lengths (model and translations) are metres.
//! So a pose converts as R ↦ its axis-angle vector, t as it is.
//!
//! The output holds `frames/NNNNNN.png` (grey, through the crate's colour
//! conversion; frame k is the k-th source image), `camera.json` (the image
//! size of the frames), `model.cao` (the source model, byte for byte) and
//! every file it `load()`s at the same path relative to it (with parts
//! added by `--include`, as in ViSP's own test that places a cube beside the
//! castle, `model.cao` is a file that loads the model and the parts, all
//! copied under their own names), `init.json`
//! (frame 0's true pose, no params, every vertex projected), `truth.jsonl`
//! (per frame the pose, the projected vertices and which vertices are in
//! front of the camera and inside the image; self-occlusion is not
//! computed) and `meta.json` (where each file came from). It is written
//! through a [`StagedDir`] and opened as a [`Sequence`] (truth included,
//! where there is truth) before it appears under its name.
//!
//! As a check of the conversion, [`import_visp`] also measures how far the
//! projected visible model edges lie from the image's edges
//! ([`EdgeAlignment`]) and can draw the projection over every frame.

use std::collections::HashSet;
use std::fs;
use std::path::{Component, Path, PathBuf};

use glam::{DMat3, DVec2, DVec3};
use rayon::prelude::*;
use serde::Serialize;

use crate::early::sobel::{SobelOutput, sobel};
use crate::geometry::{ModelGeometry, Pose};
use crate::image::{FloatImage, GrayImage};
use crate::io::formats::{Camera, InitState, Status, TruthFrame, Visibility};
use crate::io::json::{input_error, one_short_line};
use crate::io::sequence::{CAMERA_FILE, FRAMES_DIR, INIT_FILE, MODEL_CAO_FILE, MODEL_OBJ_FILE, TRUTH_FILE};
use crate::io::{Sequence, StagedDir, decode_gray};
use crate::{Error, Result};

/// Folder of the frames in a ViSP data set.
pub const IMAGES_DIR: &str = "Images";
/// Folder of the true poses.
pub const POSES_DIR: &str = "CameraPose";
/// Folder of the tracker settings (camera intrinsics).
pub const CONFIG_DIR: &str = "Config";
/// Folder of the models.
pub const MODELS_DIR: &str = "Models";
/// Name prefix of a frame file (`Image_0001.png`).
pub const IMAGE_PREFIX: &str = "Image_";
/// Name prefix of a frame file of a tracking sequence (`image0000.png`).
pub const SEQUENCE_IMAGE_PREFIX: &str = "image";
/// Extension, after the model's name, of a tracking sequence's first pose
/// (`cube.0.pos` beside `cube.cao`).
pub const SEQUENCE_POSE_EXTENSION: &str = "0.pos";
/// The tag grid's poses of a sequence filmed beside AprilTags.
pub const TAG_GRID_FILE: &str = "apriltag_data.json";
/// Name prefix of its frame files (`color_image_0000.png`).
pub const TAG_IMAGE_PREFIX: &str = "color_image";
/// Its folder of the objects' first poses (`init/NAME.json`).
pub const TAG_INIT_DIR: &str = "init";
/// Its camera settings (`camera.xml`).
pub const TAG_CAMERA_FILE: &str = "camera.xml";
/// Its models' folder, beside the sequence (`../models/NAME/NAME.obj`).
pub const TAG_MODELS_DIR: &str = "models";
/// Extensions of frame files.
pub const IMAGE_EXTENSIONS: [&str; 5] = ["png", "pgm", "ppm", "jpg", "jpeg"];
/// Largest departure of a pose matrix from a rotation (|RᵀR − I| per entry,
/// |det R − 1|) and of its last row from (0, 0, 0, 1): ViSP writes poses with
/// at least single precision, about 1e-7.
pub const ROTATION_TOLERANCE: f64 = 1e-4;
/// Spacing of the points sampled along a projected model edge, pixels.
pub const ALIGNMENT_STEP_PX: f64 = 2.0;
/// Points closer than this to an edge's projected ends are not sampled
/// (where two image edges meet, the nearest one may be the other edge).
pub const ALIGNMENT_END_MARGIN_PX: f64 = 4.0;
/// How far along the edge's normal an image edge is looked for, pixels.
pub const ALIGNMENT_SEARCH_PX: f64 = 6.0;
/// A strong image edge: Sobel gradient across the model edge at least this
/// (a step of 10 grey levels gives 40).
pub const STRONG_EDGE_GRADIENT: f64 = 40.0;

/// Options of `pipetrack import-visp`.
#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// The model file; relative paths are taken from the source folder (a
    /// tracking sequence: from the folder that holds it). Without it: the
    /// only `.cao` in `Models/`, or among several the one named like a
    /// settings file in `Config/` (a tracking sequence: `SRC.cao`, else the
    /// only `.cao` beside SRC).
    pub model: Option<PathBuf>,
    /// The settings file with the intrinsics; relative paths are taken as
    /// for `model`. Without it: `Config/` + the model's name + `.xml`, or
    /// the only `.xml` in `Config/` with a `<camera>` (a tracking sequence:
    /// the model's name + `.xml` beside the model).
    pub camera: Option<PathBuf>,
    /// The first frame's pose of a tracking sequence (ViSP's pose vector or
    /// cMo matrix), relative as `model`. Without it: the model's name +
    /// `.0.pos` beside the model, as ViSP's tracker examples keep it.
    pub init: Option<PathBuf>,
    /// Convert only the first this many frames.
    pub frames: Option<usize>,
    /// Also draw the true projection (visible edges, every vertex) over
    /// every frame with a known pose into this folder, one PNG per frame.
    pub overlay: Option<PathBuf>,
    /// More parts of the object, each the arguments of a ViSP `load()`: a
    /// `.cao` file relative to the source folder (as for `model`), optionally followed by its
    /// placement in the model's frame, e.g.
    /// `Models/cube.cao, t=[-0.2; 0.12; -0.15], R=[-1; 0; 0; 0; 0; 1; 0; 1; 0]`
    /// (as ViSP's own test places the cube of `Castle-simu`). With parts,
    /// `model.cao` is a file that loads the model and the parts.
    pub include: Vec<String>,
}

/// What [`import_visp`] wrote and measured.
#[derive(Clone, Debug, Serialize)]
pub struct ImportReport {
    /// Number of frames written.
    pub frames: usize,
    /// Intrinsics and image size written to `camera.json`.
    pub camera: Camera,
    /// Number of model vertices (corners per frame).
    pub vertices: usize,
    /// The model files copied, relative to the output folder (`model.cao`
    /// or `model.obj` first).
    pub model_files: Vec<PathBuf>,
    /// Whether the source had every frame's pose (a data set) and
    /// `truth.jsonl` was written, or only the first frame's (a tracking
    /// sequence).
    pub truth: bool,
    /// Mean motion of the visible vertices from one frame to the next,
    /// pixels (with truth).
    pub mean_motion_px: Option<f64>,
    /// Largest motion of a vertex visible in both frames, pixels (with truth).
    pub max_motion_px: Option<f64>,
    /// Distance of the projected visible edges to the image edges, over the
    /// frames with a known pose.
    pub alignment: EdgeAlignment,
}

/// How far the true projection of the model's visible edges lies from the
/// image's edges: at points [`ALIGNMENT_STEP_PX`] apart along every visible
/// edge (both ends visible, a bordering face towards the camera), the
/// distance along the edge's normal to the nearest local maximum of the
/// image gradient across the edge (Sobel, interpolated, refined to
/// sub-pixel by a parabola) of at least [`STRONG_EDGE_GRADIENT`], searched
/// up to [`ALIGNMENT_SEARCH_PX`]. Edges hidden by other parts of the model
/// are sampled too (self-occlusion is not computed): their points may find
/// no image edge or a far one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct EdgeAlignment {
    /// Points sampled.
    pub samples: usize,
    /// Points with a strong image edge within the search range.
    pub found: usize,
    /// Mean distance over the points that found one, pixels.
    pub mean_px: f64,
    /// Median distance over the points that found one, pixels.
    pub median_px: f64,
}

/// Convert the ViSP data set `src` into the sequence folder `out_dir` (which
/// must be absent or empty), as the module doc describes. Bad input is an
/// [`Error::Input`] naming the file; nothing appears under `out_dir` (or
/// the overlay folder) unless everything was written.
pub fn import_visp(src: &Path, out_dir: &Path, opts: &ImportOptions) -> Result<ImportReport> {
    if !src.is_dir() {
        return Err(Error::input(
            src,
            "not a folder: expected a ViSP data set (Images/, CameraPose/, Config/, Models/) or a folder of frames imageNNNN.png",
        ));
    }
    if opts.frames == Some(0) {
        return Err(Error::Parameter("--frames must be at least 1".into()));
    }
    if let Some(overlay) = opts.overlay.as_deref().filter(|overlay| nested(overlay, out_dir)) {
        return Err(Error::input(
            overlay,
            format!(
                "is the output folder {}, or one holds the other: give --overlay a folder of its own",
                out_dir.display()
            ),
        ));
    }
    let Sources { images, poses, truth: has_truth, model: model_path, camera: camera_path, base, source } =
        Sources::of(src, opts)?;
    let first = decode_gray(&images[0].1)?;
    let camera = read_camera(&camera_path, first.width(), first.height())?;
    let parts = opts.include.iter().map(|arg| Part::parse(&base, arg)).collect::<Result<Vec<_>>>()?;
    let obj = model_path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if obj && !parts.is_empty() {
        return Err(Error::Parameter("--include adds parts to a .cao model; this model is a .obj file".into()));
    }
    let model_copies = if obj {
        vec![(model_path.clone(), PathBuf::from(MODEL_OBJ_FILE))]
    } else {
        model_copies(&model_path, &parts)?
    };
    let model_files: Vec<PathBuf> = model_copies.iter().map(|(_, to)| to.clone()).collect();

    let staged = StagedDir::create(out_dir)?;
    let overlay = opts.overlay.as_deref().map(StagedDir::create).transpose()?;
    let dir = staged.path();
    for (from, to) in &model_copies {
        let to = dir.join(to);
        if let Some(parent) = to.parent() {
            fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
        }
        fs::copy(from, &to).map_err(|e| Error::input(from, format!("cannot copy: {e}")))?;
    }
    if !parts.is_empty() {
        let path = dir.join(MODEL_CAO_FILE);
        fs::write(&path, loading_model(&model_path, &parts)).map_err(|e| Error::io(&path, e))?;
    }
    let model = if obj {
        crate::io::obj::read_obj(&dir.join(MODEL_OBJ_FILE)).map_err(|e| source_error(e, dir, &model_copies))?
    } else {
        crate::io::cao::read_cao(&dir.join(MODEL_CAO_FILE)).map_err(|e| {
            match e {
                // An error in the written model.cao is one in the --include
                // arguments: its line 4 + k loads part k (`loading_model`).
                Error::Input { path, message } if !parts.is_empty() && path == dir.join(MODEL_CAO_FILE) => {
                    let part = message
                        .strip_prefix("line ")
                        .and_then(|rest| rest.split_once(": "))
                        .and_then(|(line, rest)| Some((line.parse::<usize>().ok()?.checked_sub(4)?, rest)))
                        .and_then(|(k, rest)| Some((parts.get(k)?, rest)));
                    match part {
                        Some((part, rest)) => {
                            let placement =
                                if part.placement.is_empty() { String::new() } else { format!(", {}", part.placement) };
                            Error::Parameter(format!("--include \"{}{placement}\": {rest}", part.file.display()))
                        }
                        None => Error::Parameter(format!("--include: {message}")),
                    }
                }
                e => source_error(e, dir, &model_copies),
            }
        })?
    };
    let geometry = ModelGeometry::new(&model).map_err(|e| Error::input(&model_path, e.message()))?;

    let truth = poses
        .iter()
        .enumerate()
        .map(|(frame, (pose, pose_path))| true_state(frame, pose, &geometry, &camera, pose_path))
        .collect::<Result<Vec<_>>>()?;

    let frames_dir = dir.join(FRAMES_DIR);
    fs::create_dir_all(&frames_dir).map_err(|e| Error::io(&frames_dir, e))?;
    let per_frame = images
        .par_iter()
        .enumerate()
        .map(|(index, (_, image))| {
            let frame = if index == 0 { first.clone() } else { decode_gray(image)? };
            first.check_same_size(&frame, "frame").map_err(|_| {
                Error::input(
                    image,
                    format!(
                        "{}×{} differs from the first frame's {}×{}",
                        frame.width(),
                        frame.height(),
                        camera.width,
                        camera.height
                    ),
                )
            })?;
            let name = format!("{index:06}.png");
            save_gray_png(&frames_dir.join(&name), &frame)?;
            let Some(state) = truth.get(index) else { return Ok(Vec::new()) };
            if let Some(overlay) = &overlay {
                let edges: Vec<[usize; 2]> =
                    geometry.edges().iter().zip(&state.visible_edges).filter(|(_, v)| **v).map(|(e, _)| *e).collect();
                let img = crate::io::overlay::draw_overlay(&frame, &state.truth.corners, &edges, Status::Tracking, &[]);
                let path = overlay.path().join(&name);
                img.save(&path).map_err(|e| Error::io(&path, std::io::Error::other(e)))?;
            }
            Ok(edge_distances(&frame, state, geometry.edges()))
        })
        .collect::<Result<Vec<_>>>()?;
    let alignment = summarise_alignment(per_frame);

    write_json(&dir.join(CAMERA_FILE), &camera)?;
    let init = InitState {
        pose: truth[0].truth.pose,
        params: Vec::new(),
        corners: truth[0].truth.corners.clone(),
        camera_motion: None,
    };
    write_json(&dir.join(INIT_FILE), &init)?;
    if has_truth {
        let mut lines = String::new();
        for state in &truth {
            lines.push_str(&serde_json::to_string(&state.truth).map_err(|e| Error::io(dir, std::io::Error::other(e)))?);
            lines.push('\n');
        }
        let truth_path = dir.join(TRUTH_FILE);
        fs::write(&truth_path, lines).map_err(|e| Error::io(&truth_path, e))?;
    }
    let meta = serde_json::json!({
        "source": source,
        "images": images.iter().map(|(_, p)| file_name(p)).collect::<Vec<_>>(),
        "poses": poses.iter().map(|(_, p)| file_name(p)).collect::<Vec<_>>(),
        "camera": file_name(&camera_path),
        "model": file_name(&model_path),
        "model_files": model_files,
        "include": opts.include,
        "visible": "per vertex: in front of the camera and inside the image; self-occlusion not computed",
    });
    write_json(&dir.join("meta.json"), &meta)?;

    let sequence = Sequence::open(dir, false).map_err(|e| relocate_error(e, dir, out_dir))?;
    if has_truth {
        sequence.read_truth().map_err(|e| relocate_error(e, dir, out_dir))?;
    }
    staged.finish()?;
    if let Some(overlay) = overlay {
        overlay.finish()?;
    }
    let (mean_motion_px, max_motion_px) = if has_truth { motion(&truth) } else { (f64::NAN, f64::NAN) };
    Ok(ImportReport {
        frames: images.len(),
        truth: has_truth,
        mean_motion_px: has_truth.then_some(mean_motion_px),
        max_motion_px: has_truth.then_some(max_motion_px),
        camera,
        vertices: model.vertices.len(),
        model_files,
        alignment,
    })
}

/// The files a source provides, whichever its layout.
struct Sources {
    /// The frames, `(number, path)`, by number (the first `--frames`).
    images: Vec<(u64, PathBuf)>,
    /// Known poses and their files: every frame's (a data set) or the
    /// first frame's (a tracking sequence).
    poses: Vec<(Pose, PathBuf)>,
    /// Whether `poses` is every frame's: the truth.
    truth: bool,
    /// The model file.
    model: PathBuf,
    /// The settings file with the intrinsics.
    camera: PathBuf,
    /// The folder that `--model`, `--camera`, `--init` and `--include`
    /// paths are relative to: the data set (or a sequence filmed beside a
    /// tag grid), or the folder holding a tracking sequence.
    base: PathBuf,
    /// What the source is, for `meta.json`.
    source: &'static str,
}

impl Sources {
    /// The files of `src`: a data set when it has `Images/`, else a
    /// tracking sequence when it holds `imageNNNN` frames.
    fn of(src: &Path, opts: &ImportOptions) -> Result<Self> {
        if src.join(IMAGES_DIR).exists() {
            Self::data_set(src, opts)
        } else if src.join(TAG_GRID_FILE).exists() {
            Self::tag_grid_sequence(src, opts)
        } else {
            Self::tracking_sequence(src, opts)
        }
    }

    /// A sequence filmed beside a tag grid (module doc): the truth from the
    /// grid's poses and the object's first pose.
    fn tag_grid_sequence(src: &Path, opts: &ImportOptions) -> Result<Self> {
        let mut images = list_images(src, TAG_IMAGE_PREFIX)?;
        images.truncate(opts.frames.unwrap_or(usize::MAX));
        let init = match opts.init.as_deref() {
            Some(given) => given_file(src, given, "the object's first pose given with --init")?,
            None => {
                let dir = src.join(TAG_INIT_DIR);
                match files_with_extension(&dir, "json")?.as_slice() {
                    [one] => one.clone(),
                    [] => return Err(Error::input(&dir, "no NAME.json: the first pose of the object to convert")),
                    several => {
                        let names: Vec<String> = several.iter().map(|p| file_name(p)).collect();
                        return Err(Error::input(
                            &dir,
                            format!("holds {}: choose the object with --init init/NAME.json", names.join(", ")),
                        ));
                    }
                }
            }
        };
        let name = init.file_stem().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let model = match opts.model.as_deref() {
            Some(given) => given_file(src, given, "the model given with --model")?,
            None => existing(
                src.join("..").join(TAG_MODELS_DIR).join(&name).join(format!("{name}.obj")),
                "the object's model (or give it with --model)",
            )?,
        };
        let camera = match opts.camera.as_deref() {
            Some(given) => given_file(src, given, "the settings given with --camera")?,
            None => existing(src.join(TAG_CAMERA_FILE), "the <camera> intrinsics (or give them with --camera)")?,
        };
        let first = read_matrix_file(&init)?;
        let grid_path = src.join(TAG_GRID_FILE);
        let grid = read_tag_grid(&grid_path)?;
        if grid.len() < images.len() {
            return Err(Error::input(
                &grid_path,
                format!("\"grid\" has {} poses for {} frames: one per frame is needed", grid.len(), images.len()),
            ));
        }
        // The object at rest in the grid's frame: gMo = cMg(0)⁻¹·cMo(0).
        let in_grid = grid[0].inverse().compose(&first);
        let poses = grid[..images.len()].iter().map(|cmg| (cmg.compose(&in_grid), grid_path.clone())).collect();
        let source =
            "ViSP sequence filmed beside a tag grid (truth: the grid's pose from its tags, the object at rest)";
        Ok(Self { images, poses, truth: true, model, camera, base: src.to_path_buf(), source })
    }

    fn data_set(src: &Path, opts: &ImportOptions) -> Result<Self> {
        if opts.init.is_some() {
            return Err(Error::Parameter(
                "--init is for a folder of frames; a data set's poses are CameraPose/Camera_NNN.txt".into(),
            ));
        }
        let mut images = list_images(&src.join(IMAGES_DIR), IMAGE_PREFIX)?;
        images.truncate(opts.frames.unwrap_or(usize::MAX));
        let poses = images.iter().map(|(number, image)| read_pose(src, *number, image)).collect::<Result<Vec<_>>>()?;
        let model = choose_model(src, opts.model.as_deref())?;
        let camera = choose_camera(src, opts.camera.as_deref(), &model)?;
        let source = "ViSP model-based-tracking data set";
        Ok(Self { images, poses, truth: true, model, camera, base: src.to_path_buf(), source })
    }

    fn tracking_sequence(src: &Path, opts: &ImportOptions) -> Result<Self> {
        // Errors name the folder as given; a path ending in `.` or `..` has
        // no name of its own, so its full path stands for it.
        // A link is followed: ViSP's files lie beside the folder it points to.
        let link = fs::symlink_metadata(src).is_ok_and(|m| m.file_type().is_symlink());
        let src = if src.file_name().is_some() && !link {
            src.to_path_buf()
        } else {
            fs::canonicalize(src).map_err(|e| Error::input(src, format!("cannot resolve the folder: {e}")))?
        };
        let base = match src.parent() {
            Some(parent) if parent.as_os_str().is_empty() => PathBuf::from("."),
            Some(parent) => parent.to_path_buf(),
            None => PathBuf::from("/"),
        };
        let name = src.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let found = frame_files(&src, SEQUENCE_IMAGE_PREFIX)?;
        if found.is_empty() {
            return Err(Error::input(
                &src,
                "neither a ViSP data set (no Images/ folder) nor a tracking sequence (no frames image0000.png, …)",
            ));
        }
        let mut images = check_numbering(&src, found, SEQUENCE_IMAGE_PREFIX)?;
        images.truncate(opts.frames.unwrap_or(usize::MAX));
        let model = sequence_model(&base, &name, opts.model.as_deref())?;
        // ViSP names a model's settings and first pose after it, beside it.
        let beside_model = |ext: &str| {
            let stem = model.file_stem().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            model.parent().unwrap_or(&base).join(format!("{stem}.{ext}"))
        };
        let camera = match opts.camera.as_deref() {
            Some(given) => given_file(&base, given, "the settings given with --camera")?,
            None => {
                existing(beside_model("xml"), "the settings with the <camera> intrinsics (or give them with --camera)")?
            }
        };
        let pose_path = match opts.init.as_deref() {
            Some(given) => given_file(&base, given, "the pose given with --init")?,
            None => existing(
                beside_model(SEQUENCE_POSE_EXTENSION),
                "the pose of the first frame, ViSP's pose vector or cMo matrix (or give it with --init)",
            )?,
        };
        let pose = read_pose_file(&pose_path)?;
        let source = "ViSP model-based-tracking sequence (no ground truth; init.json from the first frame's pose)";
        Ok(Self { images, poses: vec![(pose, pose_path)], truth: false, model, camera, base, source })
    }
}

/// `given` taken relative to `base`, when it is a file; else the input
/// error "missing: `what`" naming it.
fn given_file(base: &Path, given: &Path, what: &str) -> Result<PathBuf> {
    existing(base.join(given), what)
}

/// Whether folders `a` and `b` are one, or one lies inside the other (as
/// written, from the current folder, `..` taken back lexically: `out/../ov`
/// is beside `out`; links are not followed).
fn nested(a: &Path, b: &Path) -> bool {
    // From the root down, so that `normalise` takes the path.
    let normal = |p: &Path| {
        let absolute = std::path::absolute(p).ok()?;
        normalise(
            &absolute
                .components()
                .filter(|c| matches!(c, Component::Normal(_) | Component::ParentDir))
                .collect::<PathBuf>(),
        )
    };
    match (normal(a), normal(b)) {
        (Some(a), Some(b)) => a.starts_with(&b) || b.starts_with(&a),
        _ => false,
    }
}

/// `path` when it is a file; else the input error "missing: `what`" naming it.
fn existing(path: PathBuf, what: &str) -> Result<PathBuf> {
    if path.is_file() { Ok(path) } else { Err(Error::input(path, format!("missing: {what}"))) }
}

/// The model of a tracking sequence whose frames are in `base/name`:
/// `given` (relative to `base`), else `base/<name>.cao`, else the only
/// `.cao` in `base`.
fn sequence_model(base: &Path, name: &str, given: Option<&Path>) -> Result<PathBuf> {
    if let Some(path) = given {
        return given_file(base, path, "the model given with --model");
    }
    let named = base.join(format!("{name}.cao"));
    if named.is_file() {
        return Ok(named);
    }
    match files_with_extension(base, "cao")?.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(Error::input(
            named,
            format!(
                "missing: the model of the frames in {name}/ (or the only .cao beside them; or give one with --model)"
            ),
        )),
        _ => Err(Error::input(base, format!("several .cao models and none named {name}.cao: pick one with --model"))),
    }
}

/// The frames in `images`: `(number, path)` of every `<prefix><digits>.<ext>`
/// file (also `<prefix>_<digits>`), by number; the numbers must follow each
/// other without a gap.
fn list_images(images: &Path, prefix: &str) -> Result<Vec<(u64, PathBuf)>> {
    let found = frame_files(images, prefix)?;
    check_numbering(images, found, prefix)
}

/// The frame files in `images` as [`list_images`] names them, by number
/// (none is no error here).
fn frame_files(images: &Path, prefix: &str) -> Result<Vec<(u64, PathBuf)>> {
    let entries = fs::read_dir(images).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            Error::input(images, format!("missing: the frames {prefix}NNNN.png"))
        } else {
            Error::io(images, e)
        }
    })?;
    let mut found = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| Error::io(images, e))?.path();
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else { continue };
        let Some((stem, ext)) = name.rsplit_once('.') else { continue };
        let Some(digits) = stem.strip_prefix(prefix) else { continue };
        let digits = digits.strip_prefix('_').unwrap_or(digits);
        if !IMAGE_EXTENSIONS.contains(&ext.to_ascii_lowercase().as_str()) || digits.is_empty() {
            continue;
        }
        let Ok(number) = digits.parse::<u64>() else { continue };
        found.push((number, path));
    }
    found.sort();
    Ok(found)
}

/// `found` (sorted) when it holds frames numbered without a gap or a
/// repeat; else the input error naming the folder `images` or the file
/// after the gap.
fn check_numbering(images: &Path, found: Vec<(u64, PathBuf)>, prefix: &str) -> Result<Vec<(u64, PathBuf)>> {
    if found.is_empty() {
        return Err(Error::input(
            images,
            format!("no frames: expected files named {prefix}NNNN.png (or .pgm, .ppm, .jpg)"),
        ));
    }
    for pair in found.windows(2) {
        let ((a, pa), (b, pb)) = (&pair[0], &pair[1]);
        if a == b {
            return Err(Error::input(pb, format!("frame {b} also in {}: keep one file per frame", file_name(pa))));
        }
        let missing = match b - a {
            1 => continue,
            2 => format!("frame {} is missing", a + 1),
            _ => format!("frames {} to {} are missing", a + 1, b - 1),
        };
        return Err(Error::input(pb, format!("{missing} before it: the frames must follow each other")));
    }
    Ok(found)
}

/// The true pose of frame `number` (image file `image`) and its file,
/// `CameraPose/Camera_NNN.txt`.
fn read_pose(src: &Path, number: u64, image: &Path) -> Result<(Pose, PathBuf)> {
    let dir = src.join(POSES_DIR);
    if !dir.is_dir() {
        return Err(Error::input(&dir, "missing: a ViSP data set keeps the true poses in CameraPose/Camera_NNN.txt"));
    }
    let path = dir.join(format!("Camera_{number:03}.txt"));
    let text = match fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(Error::input(&path, format!("missing: frame {} has no true pose", file_name(image))));
        }
        Err(e) => return Err(Error::input(&path, format!("cannot read: {e}"))),
    };
    let pose = parse_pose(&text).map_err(|msg| Error::input(&path, msg))?;
    Ok((pose, path))
}

/// The ViSP pose file at `path` ([`parse_pose`]), errors naming it.
pub fn read_pose_file(path: &Path) -> Result<Pose> {
    let text = crate::io::json::read_text(path)?;
    parse_pose(&text).map_err(|msg| Error::input(path, msg))
}

/// A ViSP pose file: the 4×4 homogeneous matrix cMo, row-major, or the pose
/// vector `tx ty tz θux θuy θuz` (metres, axis-angle radians), numbers
/// separated by any white space.
pub fn parse_pose(text: &str) -> std::result::Result<Pose, String> {
    let numbers = text
        .split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| one_short_line(&format!("{t:?} is not a finite number")))
        })
        .collect::<std::result::Result<Vec<_>, _>>()?;
    match numbers.len() {
        16 => pose_from_matrix(&numbers),
        6 => Ok(Pose::from_axis_angle(
            DVec3::new(numbers[3], numbers[4], numbers[5]),
            DVec3::new(numbers[0], numbers[1], numbers[2]),
        )),
        n => Err(format!("{n} numbers: expected 16 (the 4×4 matrix cMo) or 6 (tx ty tz θux θuy θuz)")),
    }
}

/// The pose of a row-major 4×4 homogeneous matrix `[R t; 0 0 0 1]`,
/// checked to be a rigid transform within [`ROTATION_TOLERANCE`].
fn pose_from_matrix(m: &[f64]) -> std::result::Result<Pose, String> {
    let at = |r: usize, c: usize| m[4 * r + c];
    let last_row = [at(3, 0), at(3, 1), at(3, 2), at(3, 3)];
    if last_row.iter().zip([0.0, 0.0, 0.0, 1.0]).any(|(v, e)| (v - e).abs() > ROTATION_TOLERANCE) {
        return Err(format!("the last row is {last_row:?}, not [0, 0, 0, 1]: not a homogeneous transform"));
    }
    let rotation = DMat3::from_cols(
        DVec3::new(at(0, 0), at(1, 0), at(2, 0)),
        DVec3::new(at(0, 1), at(1, 1), at(2, 1)),
        DVec3::new(at(0, 2), at(1, 2), at(2, 2)),
    );
    let gram = rotation.transpose() * rotation - DMat3::IDENTITY;
    let off = gram.to_cols_array().iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    let det = rotation.determinant();
    if off > ROTATION_TOLERANCE || (det - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(format!("the upper-left 3×3 block is not a rotation (|RᵀR − I| up to {off:.2e}, det {det:.6})"));
    }
    Ok(Pose::new(rotation, DVec3::new(at(0, 3), at(1, 3), at(2, 3))))
}

/// A 4×4 pose matrix written as JSON, a list of four rows.
fn matrix_of(value: &serde_json::Value) -> std::result::Result<Pose, String> {
    let numbers: Option<Vec<f64>> = value
        .as_array()
        .filter(|rows| rows.len() == 4)
        .and_then(|rows| rows.iter().map(|r| r.as_array().filter(|r| r.len() == 4)).collect::<Option<Vec<_>>>())
        .and_then(|rows| rows.into_iter().flatten().map(serde_json::Value::as_f64).collect());
    // JSON numbers are finite (the reader refuses NaN and overflow).
    pose_from_matrix(&numbers.ok_or("not a 4×4 matrix (a list of four rows of four numbers)")?)
}

/// The pose in `path`: a JSON 4×4 matrix cMo.
fn read_matrix_file(path: &Path) -> Result<Pose> {
    let value = crate::io::json::read_json_value(path)?;
    matrix_of(&value).map_err(|msg| Error::input(path, msg))
}

/// The grid's poses cMg of `path` (`{"grid": [matrix, …]}`), one per frame.
fn read_tag_grid(path: &Path) -> Result<Vec<Pose>> {
    let value = crate::io::json::read_json_value(path)?;
    let grid = value
        .get("grid")
        .and_then(serde_json::Value::as_array)
        .ok_or_else(|| Error::input(path, "no \"grid\": a list of the tag grid's poses, one 4×4 matrix per frame"))?;
    grid.iter()
        .enumerate()
        .map(|(k, m)| matrix_of(m).map_err(|msg| Error::input(path, format!("\"grid\" pose {k}: {msg}"))))
        .collect()
}

/// The `.cao` model to convert: `given` (relative to `src`), or the only one
/// in `Models/`, or among several the one named like an `.xml` in `Config/`.
fn choose_model(src: &Path, given: Option<&Path>) -> Result<PathBuf> {
    if let Some(path) = given {
        return given_file(src, path, "the model given with --model");
    }
    let models = src.join(MODELS_DIR);
    let caos = files_with_extension(&models, "cao")?;
    match caos.as_slice() {
        [] => Err(Error::input(&models, "no .cao model: give one with --model")),
        [one] => Ok(one.clone()),
        several => {
            let configs = files_with_extension(&src.join(CONFIG_DIR), "xml").unwrap_or_default();
            let named: Vec<_> =
                several.iter().filter(|m| configs.iter().any(|c| c.file_stem() == m.file_stem())).collect();
            match named.as_slice() {
                [one] => Ok((*one).clone()),
                _ => Err(Error::input(
                    &models,
                    format!(
                        "several models ({}): pick one with --model",
                        several.iter().map(|p| file_name(p)).collect::<Vec<_>>().join(", ")
                    ),
                )),
            }
        }
    }
}

/// The settings file with the intrinsics: `given` (relative to `src`), or
/// `Config/<model name>.xml`, or the only `.xml` in `Config/` with a `<camera>`.
fn choose_camera(src: &Path, given: Option<&Path>, model: &Path) -> Result<PathBuf> {
    if let Some(path) = given {
        return given_file(src, path, "the settings given with --camera");
    }
    let config = src.join(CONFIG_DIR);
    if let Some(stem) = model.file_stem() {
        let named = config.join(stem).with_extension("xml");
        if named.is_file() {
            return Ok(named);
        }
    }
    let with_camera: Vec<PathBuf> = files_with_extension(&config, "xml")?
        .into_iter()
        .filter(|p| fs::read_to_string(p).is_ok_and(|t| t.contains("<camera")))
        .collect();
    match with_camera.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(Error::input(&config, "no .xml settings with a <camera>: give the intrinsics with --camera")),
        _ => Err(Error::input(&config, "several .xml settings with a <camera>: pick one with --camera")),
    }
}

/// The files directly in `dir` whose extension is `ext`, sorted.
fn files_with_extension(dir: &Path, ext: &str) -> Result<Vec<PathBuf>> {
    let entries = fs::read_dir(dir).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound { Error::input(dir, "missing") } else { Error::io(dir, e) }
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x.eq_ignore_ascii_case(ext)))
        .collect();
    files.sort();
    Ok(files)
}

/// The intrinsics in the `<camera>` element of ViSP settings `path` (`px`,
/// `py`, `u0`, `v0`, anywhere below it), for frames of `width`×`height`.
/// Distortion (`kud`, `kdu` other than 0) and an image size other than the
/// frames' (`image_width`, `image_height`) are errors.
pub fn read_camera(path: &Path, width: usize, height: usize) -> Result<Camera> {
    let text = crate::io::json::read_text(path)?;
    let doc = roxmltree::Document::parse(&text).map_err(|e| input_error(path, format!("not XML: {e}")))?;
    let camera = doc
        .descendants()
        .find(|n| n.has_tag_name("camera"))
        .ok_or_else(|| Error::input(path, "no <camera> element: it holds the intrinsics px, py, u0, v0"))?;
    let value = |name: &str| -> Result<Option<f64>> {
        let Some(node) = camera.descendants().find(|n| n.has_tag_name(name)) else { return Ok(None) };
        let text = node.text().unwrap_or("").trim();
        text.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .map(Some)
            .ok_or_else(|| input_error(path, format!("<camera> <{name}> {text:?} is not a finite number")))
    };
    let required = |name: &str| -> Result<f64> {
        value(name)?.ok_or_else(|| Error::input(path, format!("<camera> has no <{name}>: px, py, u0, v0 are needed")))
    };
    for distortion in ["kud", "kdu"] {
        if value(distortion)?.is_some_and(|k| k != 0.0) {
            return Err(Error::input(
                path,
                format!("<camera> has distortion <{distortion}>: only undistorted frames are read"),
            ));
        }
    }
    for (name, size) in [("image_width", width), ("image_height", height)] {
        if let Some(v) = value(name)?
            && v != size as f64
        {
            return Err(Error::input(path, format!("<camera> <{name}> is {v} but the frames are {width}×{height}")));
        }
    }
    let too_big = || Error::input(path, format!("frames of {width}×{height} are too large"));
    let camera = Camera {
        width: u32::try_from(width).map_err(|_| too_big())?,
        height: u32::try_from(height).map_err(|_| too_big())?,
        fx: required("px")?,
        fy: required("py")?,
        cx: required("u0")?,
        cy: required("v0")?,
    };
    camera.validate(path)?;
    Ok(camera)
}

/// A part added to the model with `--include`.
#[derive(Clone, Debug, PartialEq)]
struct Part {
    /// The part's `.cao` file.
    file: PathBuf,
    /// Its placement, the `load()` arguments after the file (may be empty).
    placement: String,
}

impl Part {
    /// `FILE[, placement]`, `FILE` relative to `src`.
    fn parse(src: &Path, arg: &str) -> Result<Self> {
        // The argument becomes one line of the written model.cao.
        if arg.chars().any(char::is_control) {
            return Err(Error::Parameter(format!(
                "--include {arg:?}: a control character (a line break, a tab…) cannot be part of a load() line"
            )));
        }
        let (file, placement) = arg.split_once(',').unwrap_or((arg, ""));
        let file = given_file(src, Path::new(file.trim().trim_matches('"')), "the part given with --include")?;
        Ok(Self { file, placement: placement.trim().to_string() })
    }
}

/// The model files to copy, `(source, path in the sequence folder)`:
/// without `parts`, `model` as `model.cao` and every file it `load()`s
/// ([`loaded_files`]); with parts, `model` and each part under its own name
/// with the files they load (`model.cao` is then [`loading_model`]). Two
/// different sources for one path are an error.
fn model_copies(model: &Path, parts: &[Part]) -> Result<Vec<(PathBuf, PathBuf)>> {
    let tops: Vec<&Path> = std::iter::once(model).chain(parts.iter().map(|p| p.file.as_path())).collect();
    let mut copies: Vec<(PathBuf, PathBuf)> = Vec::new();
    for top in tops {
        let name = if parts.is_empty() { PathBuf::from(MODEL_CAO_FILE) } else { PathBuf::from(file_name(top)) };
        if !parts.is_empty() && is_sequence_file(&name) {
            return Err(Error::input(top, "has the name of a sequence file: copy it under another name"));
        }
        for (from, to) in std::iter::once((top.to_path_buf(), name)).chain(loaded_files(top)?) {
            match copies.iter().find(|(_, t)| *t == to) {
                Some((other, _)) if !same_file(other, &from) => {
                    return Err(Error::input(
                        &from,
                        format!("would be copied to {} as {} is: rename one", to.display(), other.display()),
                    ));
                }
                Some(_) => {}
                None => copies.push((from, to)),
            }
        }
    }
    Ok(copies)
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (fs::canonicalize(a), fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// The `model.cao` that loads `model` and the `parts` (copied beside it
/// under their own names), each part with its placement.
fn loading_model(model: &Path, parts: &[Part]) -> String {
    let mut text = String::from("V1\n# The model and the parts added to it, each placed in the model's frame.\n");
    text.push_str(&format!("load(\"{}\")\n", file_name(model)));
    for part in parts {
        let placement = if part.placement.is_empty() { String::new() } else { format!(", {}", part.placement) };
        text.push_str(&format!("load(\"{}\"{placement})\n", file_name(&part.file)));
    }
    // No points, lines, faces from lines, faces from points, cylinders, circles of its own.
    text.push_str("0\n0\n0\n0\n0\n0\n");
    text
}

/// Every file `top` `load()`s, directly or through another loaded file, as
/// `(source, path relative to top's folder)`. A loaded path is relative to
/// the folder of the file that loads it and must stay inside `top`'s folder
/// (the sequence folder holds the copies at the same relative paths).
pub fn loaded_files(top: &Path) -> Result<Vec<(PathBuf, PathBuf)>> {
    let top_dir = top.parent().unwrap_or(Path::new(".")).to_path_buf();
    let mut files = Vec::new();
    let mut seen = HashSet::new();
    let mut pending = vec![(top.to_path_buf(), PathBuf::new())];
    while let Some((path, rel_dir)) = pending.pop() {
        let text = crate::io::json::read_text(&path)?;
        for (i, line) in text.lines().enumerate() {
            let Some(target) = loaded_file(line) else { continue };
            let at = |msg: String| input_error(&path, format!("line {}: {msg}", i + 1));
            let rel = normalise(&rel_dir.join(&target)).ok_or_else(|| {
                at(format!("load({target:?}) leaves the model's folder; the sequence cannot hold it"))
            })?;
            if is_sequence_file(&rel) {
                return Err(at(format!("load({target:?}) has the name of a sequence file")));
            }
            let full = top_dir.join(&rel);
            if full.is_dir() {
                return Err(at(format!("load({target:?}): {} is a folder, not a .cao file", full.display())));
            }
            if !full.is_file() {
                return Err(at(format!("load({target:?}): {} is missing", full.display())));
            }
            if seen.insert(rel.clone()) {
                files.push((full.clone(), rel.clone()));
                pending.push((full, rel.parent().map(Path::to_path_buf).unwrap_or_default()));
            }
        }
    }
    Ok(files)
}

/// The file named by a `load("file.cao")` line of a `.cao` file (placement
/// arguments after the file allowed), if `line` is one.
fn loaded_file(line: &str) -> Option<String> {
    let code = line.split('#').next()?.trim();
    let args = code.strip_prefix("load(")?.trim_start();
    let file = match args.strip_prefix('"') {
        Some(quoted) => quoted.split('"').next()?,
        None => args.split([',', ')']).next()?.trim(),
    };
    (!file.is_empty()).then(|| file.to_string())
}

/// `path` with `.` and `name/..` removed; `None` if it is absolute or climbs
/// above its start.
fn normalise(path: &Path) -> Option<PathBuf> {
    let mut parts: Vec<&std::ffi::OsStr> = Vec::new();
    for c in path.components() {
        match c {
            Component::Normal(name) => parts.push(name),
            Component::CurDir => {}
            Component::ParentDir => {
                parts.pop()?;
            }
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    (!parts.is_empty()).then(|| parts.iter().collect())
}

/// Whether a copied model file would take the place of a file of SPEC §4.
fn is_sequence_file(rel: &Path) -> bool {
    let first = rel.components().next().map(|c| c.as_os_str().to_string_lossy().into_owned()).unwrap_or_default();
    [CAMERA_FILE, INIT_FILE, TRUTH_FILE, MODEL_CAO_FILE, "model.json", "model.obj", "meta.json", FRAMES_DIR]
        .contains(&first.as_str())
}

/// An error about `from` (a file in the staging folder) told about `to`.
fn relocate_error(e: Error, from: &Path, to: &Path) -> Error {
    match e {
        Error::Input { path, message } => match path.strip_prefix(from) {
            Ok(rest) => Error::Input { path: to.join(rest), message },
            Err(_) => Error::Input { path, message },
        },
        other => other,
    }
}

/// An error about a model file copied into the staging folder `dir` told
/// about the file it was copied from.
fn source_error(e: Error, dir: &Path, copies: &[(PathBuf, PathBuf)]) -> Error {
    match e {
        Error::Input { path, message } => match copies.iter().find(|(_, to)| dir.join(to) == path) {
            Some((from, _)) => Error::Input { path: from.clone(), message },
            None => Error::Input { path, message },
        },
        other => other,
    }
}

/// One frame's truth and what the alignment check needs of it.
struct FrameState {
    truth: TruthFrame,
    /// Whether each model edge borders a face towards the camera.
    visible_edges: Vec<bool>,
}

/// The truth of frame `frame` at `pose`: every vertex projected, and per
/// vertex whether it is in front of the camera and inside the image.
fn true_state(
    frame: usize,
    pose: &Pose,
    geometry: &ModelGeometry,
    camera: &Camera,
    pose_path: &Path,
) -> Result<FrameState> {
    let camera_vertices = geometry.camera_vertices(pose, &[])?;
    let mut corners = Vec::with_capacity(camera_vertices.len());
    let mut visible = Vec::with_capacity(camera_vertices.len());
    for (i, p) in camera_vertices.iter().enumerate() {
        // The first frame's pose becomes init.json, where a tracker starts:
        // the whole model must be in front of the camera there.
        if frame == 0 && !(p.z > 0.0) {
            return Err(Error::input(
                pose_path,
                format!(
                    "the first frame's pose puts model vertex {i} at depth {}: a tracker starts from it, with the whole model in front of the camera",
                    crate::bounds::short_number(p.z)
                ),
            ));
        }
        let pixel = camera.project(*p);
        if !(pixel[0].is_finite() && pixel[1].is_finite()) {
            let why = if p.z == 0.0 {
                "lies in the plane of the camera centre (Z = 0)"
            } else {
                "projects to no finite pixel: the pose puts the model beyond any image"
            };
            return Err(Error::input(pose_path, format!("model vertex {i} {why}")));
        }
        corners.push(pixel);
        visible.push(p.z > 0.0 && camera.in_image(pixel));
    }
    let visible_edges = geometry.visible_edges_at(pose, &[])?;
    Ok(FrameState {
        truth: TruthFrame {
            frame,
            visible: Visibility::Vertices(visible),
            pose: Some(pose.into()),
            params: Vec::new(),
            corners,
        },
        visible_edges,
    })
}

/// Mean and largest motion of the vertices visible in two consecutive frames, pixels.
fn motion(truth: &[FrameState]) -> (f64, f64) {
    let (mut sum, mut count, mut max) = (0.0, 0usize, 0.0_f64);
    for pair in truth.windows(2) {
        let (a, b) = (&pair[0].truth, &pair[1].truth);
        for (i, (p, q)) in a.corners.iter().zip(&b.corners).enumerate() {
            if a.visible.vertex(i) && b.visible.vertex(i) {
                let d = DVec2::from_array(*p).distance(DVec2::from_array(*q));
                sum += d;
                count += 1;
                max = max.max(d);
            }
        }
    }
    (if count > 0 { sum / count as f64 } else { 0.0 }, max)
}

/// The distances of [`EdgeAlignment`] found in one frame: `None` for a
/// sampled point without a strong image edge in range.
fn edge_distances(frame: &GrayImage, state: &FrameState, edges: &[[usize; 2]]) -> Vec<Option<f64>> {
    let gradient = sobel(&frame.to_f32());
    let visible = |i: usize| state.truth.visible.vertex(i);
    let mut out = Vec::new();
    for (&[i, j], &facing) in edges.iter().zip(&state.visible_edges) {
        if !(facing && visible(i) && visible(j)) {
            continue;
        }
        let (a, b) = (DVec2::from_array(state.truth.corners[i]), DVec2::from_array(state.truth.corners[j]));
        let length = a.distance(b);
        if length <= 2.0 * ALIGNMENT_END_MARGIN_PX {
            continue;
        }
        let along = (b - a) / length;
        let normal = along.perp();
        let mut s = ALIGNMENT_END_MARGIN_PX;
        while s <= length - ALIGNMENT_END_MARGIN_PX {
            out.push(nearest_edge(&gradient, a + along * s, normal));
            s += ALIGNMENT_STEP_PX;
        }
    }
    out
}

/// Distance from `point` along `normal` to the nearest local maximum of the
/// gradient across the edge, |∇I·n|, of at least [`STRONG_EDGE_GRADIENT`],
/// within ±[`ALIGNMENT_SEARCH_PX`]; refined by the parabola through the
/// maximum and its two neighbours (profile sampled every pixel).
fn nearest_edge(gradient: &SobelOutput, point: DVec2, normal: DVec2) -> Option<f64> {
    let reach = ALIGNMENT_SEARCH_PX as i32 + 1;
    let profile: Vec<Option<f64>> = (-reach..=reach)
        .map(|k| {
            let p = point + normal * f64::from(k);
            let gx = bilinear(&gradient.gx, p)?;
            let gy = bilinear(&gradient.gy, p)?;
            Some((gx * normal.x + gy * normal.y).abs())
        })
        .collect();
    let mut best: Option<f64> = None;
    for k in 1..profile.len() - 1 {
        let (Some(l), Some(c), Some(r)) = (profile[k - 1], profile[k], profile[k + 1]) else { continue };
        if c < STRONG_EDGE_GRADIENT || c < l || c <= r {
            continue;
        }
        let curvature = l - 2.0 * c + r;
        let shift = if curvature < 0.0 { 0.5 * (l - r) / curvature } else { 0.0 };
        let offset = (k as f64 - f64::from(reach) + shift).abs();
        if offset <= ALIGNMENT_SEARCH_PX && best.is_none_or(|b| offset < b) {
            best = Some(offset);
        }
    }
    best
}

/// `image` at the real position `p` by bilinear interpolation; `None` outside.
fn bilinear(image: &FloatImage, p: DVec2) -> Option<f64> {
    let (w, h) = (image.width() as f64, image.height() as f64);
    if !(p.x >= 0.0 && p.y >= 0.0 && p.x <= w - 1.0 && p.y <= h - 1.0) {
        return None;
    }
    let (x0, y0) = (p.x.floor() as usize, p.y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(image.width() - 1), (y0 + 1).min(image.height() - 1));
    let (fx, fy) = (p.x - x0 as f64, p.y - y0 as f64);
    let v = |x: usize, y: usize| f64::from(image.get(x, y));
    Some((v(x0, y0) * (1.0 - fx) + v(x1, y0) * fx) * (1.0 - fy) + (v(x0, y1) * (1.0 - fx) + v(x1, y1) * fx) * fy)
}

fn summarise_alignment(per_frame: Vec<Vec<Option<f64>>>) -> EdgeAlignment {
    let samples = per_frame.iter().map(Vec::len).sum();
    let mut found: Vec<f64> = per_frame.into_iter().flatten().flatten().collect();
    if found.is_empty() {
        return EdgeAlignment { samples, ..EdgeAlignment::default() };
    }
    found.sort_by(f64::total_cmp);
    let n = found.len();
    let median = if n % 2 == 1 { found[n / 2] } else { 0.5 * (found[n / 2 - 1] + found[n / 2]) };
    EdgeAlignment { samples, found: n, mean_px: found.iter().sum::<f64>() / n as f64, median_px: median }
}

fn save_gray_png(path: &Path, frame: &GrayImage) -> Result<()> {
    image::save_buffer_with_format(
        path,
        frame.data(),
        frame.width() as u32,
        frame.height() as u32,
        image::ColorType::L8,
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::io(path, std::io::Error::other(e)))
}

fn write_json(path: &Path, value: &impl Serialize) -> Result<()> {
    let mut text = serde_json::to_string_pretty(value).map_err(|e| Error::io(path, std::io::Error::other(e)))?;
    text.push('\n');
    fs::write(path, text).map_err(|e| Error::io(path, e))
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_vector_and_matrix_agree() {
        // A rotation of 0.3 rad about (0, 0.6, 0.8) and t = (0.1, -0.2, 0.5).
        let r = DVec3::new(0.0, 0.6, 0.8) * 0.3;
        let vector = parse_pose("0.1 -0.2 0.5\n0 0.18 0.24\n").unwrap();
        assert!((vector.axis_angle() - r).length() < 1e-12);
        let m = vector.rotation;
        let text = format!(
            "{} {} {} 0.1\n{} {} {} -0.2\n{} {} {} 0.5\n0 0 0 1\n",
            m.x_axis.x, m.y_axis.x, m.z_axis.x, m.x_axis.y, m.y_axis.y, m.z_axis.y, m.x_axis.z, m.y_axis.z, m.z_axis.z
        );
        let matrix = parse_pose(&text).unwrap();
        assert!((matrix.axis_angle() - r).length() < 1e-12);
        assert_eq!(matrix.translation, DVec3::new(0.1, -0.2, 0.5));
    }

    #[test]
    fn bad_poses_say_why() {
        assert!(parse_pose("1 2 3").unwrap_err().starts_with("3 numbers"));
        assert!(parse_pose("1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 2").unwrap_err().contains("last row"));
        assert!(parse_pose("2 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1").unwrap_err().contains("not a rotation"));
        // A reflection is orthonormal but not a rotation.
        assert!(parse_pose("-1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1").unwrap_err().contains("not a rotation"));
        assert!(parse_pose("0 0 0 nan 0 0").unwrap_err().contains("\"nan\""));
    }

    #[test]
    fn load_lines_and_relative_paths() {
        assert_eq!(loaded_file("load(\"parts/a.cao\")  # floor").as_deref(), Some("parts/a.cao"));
        assert_eq!(loaded_file("  load( b.cao ) "), Some("b.cao".to_string()));
        assert_eq!(loaded_file("# load(\"c.cao\")"), None);
        assert_eq!(loaded_file("4 0 1 2 3"), None);
        assert_eq!(loaded_file("load(\"cube.cao\", t=[0; 0; 1], tu=[0; 0; 90deg])").as_deref(), Some("cube.cao"));
        assert_eq!(normalise(Path::new("parts/./x/../a.cao")), Some(PathBuf::from("parts/a.cao")));
        assert_eq!(normalise(Path::new("../a.cao")), None);
        assert_eq!(normalise(Path::new("/abs/a.cao")), None);
        assert!(is_sequence_file(Path::new("frames/a.cao")) && !is_sequence_file(Path::new("parts/a.cao")));
    }

    #[test]
    fn nearest_edge_finds_a_step_at_sub_pixel_distance() {
        // A vertical step edge between x = 9 and x = 10 (grey 50 → 150).
        let img = GrayImage::from_fn(24, 16, |x, _| if x < 10 { 50 } else { 150 });
        let gradient = sobel(&img.to_f32());
        let d = nearest_edge(&gradient, DVec2::new(7.5, 8.0), DVec2::new(1.0, 0.0)).unwrap();
        assert!((d - 2.0).abs() < 0.05, "{d}");
        // Flat image: nothing.
        let flat = sobel(&GrayImage::from_fn(24, 16, |_, _| 80).to_f32());
        assert_eq!(nearest_edge(&flat, DVec2::new(7.5, 8.0), DVec2::new(1.0, 0.0)), None);
    }
}
