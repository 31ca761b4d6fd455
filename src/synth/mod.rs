//! Synthetic sequences with exact ground truth (`pipetrack synth`, SPEC §5).
//!
//! Scenes draw into a [`Canvas`] (the exact-coverage rasteriser of [`canvas`])
//! over a static [`Background`] (from [`background`]).
//!
//! # Scenes
//!
//! [`scene_names`] lists them, [`render_scene`] renders one in memory and
//! [`generate`] renders and writes a sequence folder (SPEC §4). Today:
//! `pendulum` ([`pendulum`], paper 000), `target3dof` ([`target3dof`],
//! paper 002: the back of a truck translating in front of a bookshelf) and
//! `textured-plane` ([`textured_plane`], paper 004: a camera moving with a
//! velocity screw in front of a colourful plane), and `box` / `hinged-box`
//! ([`boxes`], paper 001: a file box, rigid or with a hinged lid, moving in
//! six degrees of freedom, optionally behind an occluder).

pub mod background;
pub mod boxes;
pub mod canvas;
pub mod pendulum;
pub mod target3dof;
pub mod textured_plane;

use std::path::Path;

use rayon::prelude::*;

use crate::image::{GrayImage, RgbImage};
use crate::io::StagedDir;
use crate::io::formats::{Camera, InitState, Model, TruthFrame};
use crate::{Error, Result};

pub use background::{
    BACKGROUND_GREY, Background, FRAME_STREAM_BASE, add_noise_and_quantise, frame_rng, render_background,
};
pub use boxes::{BoxKind, BoxOptions, BoxScene, render_box};
pub use canvas::{Canvas, DEFAULT_SUPERSAMPLE, ELLIPSE_SEGMENTS, Face, FillRule, MAX_SUPERSAMPLE, ellipse_points};
pub use pendulum::{PendulumMotion, PendulumOptions, PendulumSwing, render_pendulum};
pub use target3dof::{Target3dofOptions, Target3dofScene, render_target3dof};
pub use textured_plane::{PlaneMotion, TexturedPlaneOptions, render_textured_plane};

/// A rendered sequence held in memory: what a sequence folder (SPEC §4) holds.
#[derive(Clone, Debug)]
pub struct SyntheticSequence {
    /// Name of the scene that made it.
    pub scene: String,
    /// Intrinsics and image size (`camera.json`).
    pub camera: Camera,
    /// The object (`model.json`).
    pub model: Model,
    /// The state at frame 0 (`init.json`).
    pub init: InitState,
    /// Ground truth, one entry per frame (`truth.jsonl`).
    pub truth: Vec<TruthFrame>,
    /// Further keys of each `truth.jsonl` line (e.g. `occluded_fraction`),
    /// one map per frame, written after the [`TruthFrame`] fields; empty
    /// when the scene adds none.
    pub truth_extra: Vec<serde_json::Map<String, serde_json::Value>>,
    /// The frames, 8-bit grey (`frames/000000.png`, ...); the luma of
    /// `rgb_frames` for a colour scene.
    pub frames: Vec<GrayImage>,
    /// The frames in colour, for a colour scene (then written instead of
    /// `frames`); empty for a grey one.
    pub rgb_frames: Vec<RgbImage>,
    /// Scene parameters for people reading the folder (`meta.json`, ignored by readers).
    pub meta: serde_json::Value,
}

impl SyntheticSequence {
    /// Write the sequence folder `dir`: `camera.json`, `model.json`,
    /// `init.json`, `truth.jsonl`, `meta.json` and `frames/NNNNNN.png`.
    ///
    /// `dir` must not exist or be an empty folder, otherwise this is an
    /// [`Error::Input`] (sequences are never mixed). Everything is written into a
    /// hidden sibling folder first and renamed to `dir` at the end, so an
    /// interrupted write never leaves a folder that looks complete.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let staged = StagedDir::create(dir)?;
        self.write_files(staged.path())?;
        staged.finish()
    }

    fn write_files(&self, dir: &Path) -> Result<()> {
        let frames_dir = dir.join("frames");
        std::fs::create_dir_all(&frames_dir).map_err(|e| Error::io(&frames_dir, e))?;
        write_json(&dir.join("camera.json"), &self.camera)?;
        write_json(&dir.join("model.json"), &self.model)?;
        write_json(&dir.join("init.json"), &self.init)?;
        write_json(&dir.join("meta.json"), &self.meta)?;
        let mut truth = String::new();
        let no_extra = serde_json::Map::new();
        for (k, line) in self.truth.iter().enumerate() {
            let extra = self.truth_extra.get(k).unwrap_or(&no_extra);
            let line = TruthLine { truth: line, extra };
            truth.push_str(&serde_json::to_string(&line).map_err(|e| json_error(dir, e))?);
            truth.push('\n');
        }
        let truth_path = dir.join("truth.jsonl");
        std::fs::write(&truth_path, truth).map_err(|e| Error::io(&truth_path, e))?;
        self.rgb_frames.par_iter().enumerate().try_for_each(|(k, frame)| {
            let path = frames_dir.join(format!("{k:06}.png"));
            let bytes: Vec<u8> = frame.data().iter().flatten().copied().collect();
            image::save_buffer_with_format(
                &path,
                &bytes,
                frame.width() as u32,
                frame.height() as u32,
                image::ColorType::Rgb8,
                image::ImageFormat::Png,
            )
            .map_err(|e| Error::io(&path, std::io::Error::other(e)))
        })?;
        if !self.rgb_frames.is_empty() {
            return Ok(());
        }
        self.frames.par_iter().enumerate().try_for_each(|(k, frame)| {
            let path = frames_dir.join(format!("{k:06}.png"));
            image::save_buffer_with_format(
                &path,
                frame.data(),
                frame.width() as u32,
                frame.height() as u32,
                image::ColorType::L8,
                image::ImageFormat::Png,
            )
            .map_err(|e| Error::io(&path, std::io::Error::other(e)))
        })
    }
}

/// A `truth.jsonl` line: the truth fields, then the scene's further keys.
#[derive(serde::Serialize)]
struct TruthLine<'a> {
    #[serde(flatten)]
    truth: &'a TruthFrame,
    #[serde(flatten)]
    extra: &'a serde_json::Map<String, serde_json::Value>,
}

fn json_error(path: &Path, e: serde_json::Error) -> Error {
    Error::io(path, std::io::Error::other(e))
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let mut text = serde_json::to_string_pretty(value).map_err(|e| json_error(path, e))?;
    text.push('\n');
    std::fs::write(path, text).map_err(|e| Error::io(path, e))
}

/// Parse the string `value` of scene option `key`; the error names the
/// scene, the key and what was expected (`what`).
pub(crate) fn parse_option<T: std::str::FromStr>(scene: &str, key: &str, value: &str, what: &str) -> Result<T> {
    value.parse().map_err(|_| Error::Parameter(format!("{scene} option {key}: '{value}' is not {what}")))
}

/// The error for a `--set` key that `scene` does not have; `keys` are its
/// options.
pub(crate) fn no_such_option(scene: &str, key: &str, keys: &[&str]) -> Error {
    Error::Parameter(format!("{scene} has no option {key:?} (its options: {})", keys.join(", ")))
}

/// Error unless `value` (named `name`, in `unit`) is finite and in `0..=max`.
pub(crate) fn check_range(name: &str, value: f64, max: f64, unit: &str) -> Result<()> {
    if value.is_finite() && (0.0..=max).contains(&value) {
        Ok(())
    } else {
        Err(Error::Parameter(format!("{name} = {}{unit} is not in 0..={max}", crate::bounds::short_number(value))))
    }
}

/// Error unless a scene's frame count is in `1..=max`.
pub(crate) fn check_frames(frames: usize, max: usize) -> Result<()> {
    if (1..=max).contains(&frames) {
        Ok(())
    } else {
        Err(Error::Parameter(format!("frames = {frames} is not in 1..={max}")))
    }
}

/// The scenes [`render_scene`] and [`generate`] know.
#[must_use]
pub fn scene_names() -> &'static [&'static str] {
    &["pendulum", "target3dof", "textured-plane", "box", "hinged-box"]
}

/// Render scene `scene` in memory. `frames` overrides the scene's default
/// length; `extra` holds scene options as `(key, value)` strings (for
/// `pendulum`: see [`PendulumOptions::set`]; for `target3dof`: see
/// [`Target3dofOptions::set`]; for `box` and `hinged-box`: see [`BoxOptions::set`]). Unknown scenes, keys or values are
/// [`Error::Parameter`]s naming what is known.
pub fn render_scene(
    scene: &str,
    frames: Option<usize>,
    seed: u64,
    extra: &[(String, String)],
) -> Result<SyntheticSequence> {
    match scene {
        "pendulum" => {
            let mut opts = PendulumOptions { seed, ..PendulumOptions::default() };
            if let Some(n) = frames {
                opts.frames = n;
            }
            for (key, value) in extra {
                opts.set(key, value)?;
            }
            render_pendulum(&opts)
        }
        "target3dof" => {
            let mut opts = Target3dofOptions { seed, ..Target3dofOptions::default() };
            if let Some(n) = frames {
                opts.frames = n;
            }
            for (key, value) in extra {
                opts.set(key, value)?;
            }
            render_target3dof(&opts)
        }
        "textured-plane" => {
            let mut opts = TexturedPlaneOptions { seed, ..TexturedPlaneOptions::default() };
            if let Some(n) = frames {
                opts.frames = n;
            }
            for (key, value) in extra {
                opts.set(key, value)?;
            }
            render_textured_plane(&opts)
        }
        "box" | "hinged-box" => {
            let kind = if scene == "box" { BoxKind::Rigid } else { BoxKind::Hinged };
            let mut opts = BoxOptions { kind, seed, ..BoxOptions::default() };
            if let Some(n) = frames {
                opts.frames = n;
            }
            for (key, value) in extra {
                opts.set(key, value)?;
            }
            render_box(&opts)
        }
        _ => Err(Error::Parameter(format!("unknown scene {scene:?} (known scenes: {})", scene_names().join(", ")))),
    }
}

/// `pipetrack synth SCENE OUT_DIR [--frames N] [--seed S]`: check that
/// `out_dir` is absent or empty, render the scene (validating every option)
/// and only then write the folder (see [`SyntheticSequence::write`]). Returns
/// the sequence that was written.
pub fn generate(
    scene: &str,
    out_dir: &Path,
    frames: Option<usize>,
    seed: u64,
    extra: &[(String, String)],
) -> Result<SyntheticSequence> {
    // Checked before the (long) render; nothing appears under `out_dir`
    // unless everything was written.
    let staged = StagedDir::create(out_dir)?;
    let sequence = render_scene(scene, frames, seed, extra)?;
    sequence.write_files(staged.path())?;
    staged.finish()?;
    Ok(sequence)
}
