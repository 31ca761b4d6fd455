//! The file formats of SPEC §4 (contract) as serde types: `camera.json`,
//! `model.json`, `init.json`, lines of `truth.jsonl` and of the tracker's
//! JSON Lines output. Loading and validating a whole sequence folder is
//! [`crate::io`]'s job; these types only describe the fields.

use serde::{Deserialize, Serialize};

/// Pinhole intrinsics and image size (`camera.json`):
/// u = fx·X/Z + cx, v = fy·Y/Z + cy; pixel (0,0) is the centre of the top-left pixel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length in pixels, x.
    pub fx: f64,
    /// Focal length in pixels, y.
    pub fy: f64,
    /// Principal point, x.
    pub cx: f64,
    /// Principal point, y.
    pub cy: f64,
}

/// A rotational joint of an articulated model: moves its listed vertices to
/// `origin + R(axis, q)·(X − origin)`; vertices are given at q = 0.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Joint {
    /// Name of the joint.
    pub name: String,
    /// A point on the axis, object frame.
    pub origin: [f64; 3],
    /// Axis direction (normalised on use).
    pub axis: [f64; 3],
    /// Indices of the vertices this joint moves.
    pub vertices: Vec<usize>,
    /// Lower limit, radians.
    pub min: f64,
    /// Upper limit, radians.
    pub max: f64,
}

/// The object (`model.json`, or converted from ViSP's `.cao`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Model {
    /// Name of the object.
    pub name: String,
    /// Length unit of the vertices (`"m"`).
    #[serde(default = "default_units")]
    pub units: String,
    /// Vertex positions in the object frame.
    pub vertices: Vec<[f64; 3]>,
    /// Edges as pairs of vertex indices.
    pub edges: Vec<[usize; 2]>,
    /// Faces as vertex index loops, counter-clockwise seen from outside.
    #[serde(default)]
    pub faces: Vec<Vec<usize>>,
    /// Optional joints.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub joints: Vec<Joint>,
}

fn default_units() -> String {
    "m".to_string()
}

/// Camera-from-object pose: X_cam = R·X_obj + t, R as an axis-angle
/// (Rodrigues) vector in radians, t in metres.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose {
    /// Axis-angle rotation vector, radians.
    pub rotation: [f64; 3],
    /// Translation, metres.
    pub translation: [f64; 3],
}

/// The state at frame 0 (`init.json`).
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct InitState {
    /// Pose at frame 0 (3-D trackers).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<Pose>,
    /// Joint values at frame 0.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub params: Vec<f64>,
    /// Image positions of every model vertex at frame 0 (2-D trackers).
    #[serde(default)]
    pub corners: Vec<[f64; 2]>,
}

/// One line of `truth.jsonl`: the fields of [`InitState`] plus frame and visibility.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TruthFrame {
    /// Frame index.
    pub frame: usize,
    /// Whether the object is visible in this frame.
    #[serde(default = "default_true")]
    pub visible: bool,
    /// True pose.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<Pose>,
    /// True joint values.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub params: Vec<f64>,
    /// True image positions of every model vertex.
    #[serde(default)]
    pub corners: Vec<[f64; 2]>,
}

fn default_true() -> bool {
    true
}

/// Tracking status of one frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// The model is locked on the object.
    Tracking,
    /// The tracker lost the object (the line is still written).
    Lost,
}

/// One line of the tracker's output (JSON Lines, one per frame, in order).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameResult {
    /// Frame index.
    pub frame: usize,
    /// Tracking or lost.
    pub status: Status,
    /// Image positions of the model vertices, model-vertex order.
    pub corners: Vec<[f64; 2]>,
    /// Pose, where the tracker has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<Pose>,
    /// Joint parameters, where the tracker has them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub params: Option<Vec<f64>>,
    /// Covariance of the tracker's state, row-major, where it has one (not part of the contract's required fields).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<Vec<f64>>,
    /// Milliseconds spent on this frame.
    pub ms: f64,
}

// ---------------------------------------------------------------------------
// Validation. serde checks the shape of a file; these check what serde cannot
// (finite numbers, positive focal lengths, indices in range). Each takes the
// path of the file the value came from, so the error names it.

use std::path::Path;

use crate::{Error, Result};

fn all_finite(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

/// Smallest focal length, in units of the larger image side max(W, H): a
/// pinhole camera with f = max(W, H)/100 sees 2·atan(50) ≈ 177.7° across that
/// side, and no pinhole camera sees 180°.
pub const MIN_FOCAL_PER_IMAGE_SIZE: f64 = 0.01;
/// Largest focal length, in units of max(W, H): 10⁴ is a field of view of
/// 2·atan(1/(2·10⁴)) ≈ 0.006° (20″), narrower than long telescope optics.
pub const MAX_FOCAL_PER_IMAGE_SIZE: f64 = 1e4;
/// How far the principal point may lie outside the image, in image widths
/// (c_x) or heights (c_y): a crop keeps the principal point of the full
/// frame, which lies outside the crop for an off-centre one; 10 allows a
/// crop of a tenth of the frame at its border.
pub const MAX_PRINCIPAL_POINT_OFFSET: f64 = 10.0;

impl Camera {
    /// The first thing wrong with the intrinsics, in words, or `None`:
    /// width and height > 0; f_x and f_y finite, within
    /// [[`MIN_FOCAL_PER_IMAGE_SIZE`], [`MAX_FOCAL_PER_IMAGE_SIZE`]]·max(W, H);
    /// c_x within [−k·W, (1 + k)·W] and c_y within [−k·H, (1 + k)·H] for
    /// k = [`MAX_PRINCIPAL_POINT_OFFSET`]. The ranges cover every real
    /// pinhole camera (wide angle to telescope, crops) and keep projection,
    /// back-projection and the trackers' covariances far from overflow and
    /// underflow (an f_x of 1e-300 or a c_x of 1e308 yields infinite or
    /// undefined numbers downstream).
    #[must_use]
    pub fn intrinsics_problem(&self) -> Option<String> {
        if self.width == 0 || self.height == 0 {
            return Some(format!("image size {}x{} is empty: width and height must be > 0", self.width, self.height));
        }
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let size = w.max(h);
        let (f_min, f_max) = (MIN_FOCAL_PER_IMAGE_SIZE * size, MAX_FOCAL_PER_IMAGE_SIZE * size);
        for (name, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Some(format!("{name} = {v}: focal lengths must be finite and > 0"));
            }
            if !(f_min..=f_max).contains(&v) {
                return Some(format!(
                    "{name} = {v:?} px: focal lengths must lie in [{f_min}, {f_max}] px \
                     ({MIN_FOCAL_PER_IMAGE_SIZE} to {MAX_FOCAL_PER_IMAGE_SIZE} times the larger image side, {size} px)"
                ));
            }
        }
        let k = MAX_PRINCIPAL_POINT_OFFSET;
        for (name, v, side) in [("cx", self.cx, w), ("cy", self.cy, h)] {
            if !v.is_finite() {
                return Some(format!("{name} = {v}: the principal point must be finite"));
            }
            let (lo, hi) = (-k * side, (1.0 + k) * side);
            if !(lo..=hi).contains(&v) {
                return Some(format!(
                    "{name} = {v:?} px: the principal point must lie in [{lo}, {hi}] px \
                     (at most {k} image sizes outside the {}x{} image)",
                    self.width, self.height
                ));
            }
        }
        None
    }

    /// Check the intrinsics ([`Camera::intrinsics_problem`]). `path` names
    /// `camera.json` in the error.
    pub fn validate(&self, path: &Path) -> Result<()> {
        match self.intrinsics_problem() {
            Some(problem) => Err(Error::input(path, problem)),
            None => Ok(()),
        }
    }
}

impl Pose {
    /// Whether all six numbers are finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        all_finite(&self.rotation) && all_finite(&self.translation)
    }
}

impl Model {
    /// Check the model: at least two vertices and one edge, finite
    /// coordinates, edge/face/joint indices in range, no edge from a vertex
    /// to itself, no edge listed twice (either direction), faces of at least
    /// three distinct vertices, joints with a finite non-zero axis,
    /// `min <= max`, distinct names and no vertex listed twice.
    /// `path` names the model file in the error.
    pub fn validate(&self, path: &Path) -> Result<()> {
        let fail = |msg: String| Err(Error::input(path, msg));
        let n = self.vertices.len();
        if n < 2 {
            return fail(format!("the model has {n} vertices: it needs at least 2"));
        }
        if let Some(i) = self.vertices.iter().position(|v| !all_finite(v)) {
            return fail(format!("vertex {i} has a coordinate that is not a finite number"));
        }
        if self.edges.is_empty() {
            return fail("the model has no edges".to_string());
        }
        let mut seen = std::collections::HashMap::with_capacity(self.edges.len());
        for (e, &[a, b]) in self.edges.iter().enumerate() {
            if a >= n || b >= n {
                return fail(format!("edge {e} [{a}, {b}] refers to a vertex beyond the last one ({})", n - 1));
            }
            if a == b {
                return fail(format!("edge {e} [{a}, {b}] joins a vertex to itself"));
            }
            if let Some(first) = seen.insert((a.min(b), a.max(b)), e) {
                return fail(format!("edge {e} [{a}, {b}] repeats edge {first}"));
            }
        }
        for (f, face) in self.faces.iter().enumerate() {
            if face.len() < 3 {
                return fail(format!("face {f} has {} vertices: a face needs at least 3", face.len()));
            }
            for (k, &v) in face.iter().enumerate() {
                if v >= n {
                    return fail(format!("face {f} refers to vertex {v}, beyond the last one ({})", n - 1));
                }
                if face[..k].contains(&v) {
                    return fail(format!("face {f} lists vertex {v} twice"));
                }
            }
        }
        for (j, joint) in self.joints.iter().enumerate() {
            let name = &joint.name;
            if self.joints[..j].iter().any(|other| &other.name == name) {
                return fail(format!("joint {j} \"{name}\": another joint has the same name"));
            }
            if !all_finite(&joint.origin) || !all_finite(&joint.axis) {
                return fail(format!("joint \"{name}\": origin and axis must be finite numbers"));
            }
            if joint.axis.iter().map(|a| a * a).sum::<f64>() == 0.0 {
                return fail(format!("joint \"{name}\": the axis is the zero vector"));
            }
            if !(joint.min.is_finite() && joint.max.is_finite() && joint.min <= joint.max) {
                return fail(format!(
                    "joint \"{name}\": limits min = {} and max = {} must be finite with min <= max",
                    joint.min, joint.max
                ));
            }
            for (k, &v) in joint.vertices.iter().enumerate() {
                if v >= n {
                    return fail(format!("joint \"{name}\" moves vertex {v}, beyond the last one ({})", n - 1));
                }
                if joint.vertices[..k].contains(&v) {
                    return fail(format!("joint \"{name}\" lists vertex {v} twice"));
                }
            }
        }
        Ok(())
    }
}

/// Check one set of state fields (shared by `init.json` and `truth.jsonl`
/// lines): finite pose, params and corners; params one per joint when given;
/// corners one per model vertex when given. `line` (1-based) is the line of
/// a JSON Lines file the fields came from.
fn validate_state(
    path: &Path,
    line: Option<usize>,
    pose: Option<&Pose>,
    params: &[f64],
    corners: &[[f64; 2]],
    model: &Model,
    model_path: &Path,
) -> Result<()> {
    let what = line.map_or_else(String::new, |l| format!("line {l}: "));
    let fail = |msg: String| Err(Error::input(path, format!("{what}{msg}")));
    if pose.is_some_and(|p| !p.is_finite()) {
        return fail("the pose has a value that is not a finite number".to_string());
    }
    if !all_finite(params) {
        return fail("params has a value that is not a finite number".to_string());
    }
    if !params.is_empty() && params.len() != model.joints.len() {
        return fail(format!(
            "{} params but the model has {} joints (give one value per joint, or none)",
            params.len(),
            model.joints.len()
        ));
    }
    if corners.iter().any(|c| !all_finite(c)) {
        return fail("corners has a value that is not a finite number".to_string());
    }
    let n = model.vertices.len();
    if corners.len() > n {
        // The model is the likelier culprit: name it, and the file with the corners.
        let file = path.file_name().map_or_else(|| path.display().to_string(), |f| f.to_string_lossy().into_owned());
        let at = line.map_or_else(String::new, |l| format!(" line {l}"));
        return Err(Error::input(
            model_path,
            format!("the model has {n} vertices, fewer than the {} corners in {file}{at}", corners.len()),
        ));
    }
    if !corners.is_empty() && corners.len() < n {
        return fail(format!(
            "{} corners but the model has {n} vertices (give one corner per model vertex, or none)",
            corners.len()
        ));
    }
    Ok(())
}

impl InitState {
    /// Check `init.json` against the model: finite numbers, one param per
    /// joint (or none), one corner per model vertex (or none), and at least a
    /// pose or corners. More corners than vertices names the model file.
    pub fn validate(&self, path: &Path, model: &Model, model_path: &Path) -> Result<()> {
        if self.pose.is_none() && self.corners.is_empty() {
            return Err(Error::input(path, "neither a pose nor corners: a tracker needs one of them"));
        }
        validate_state(path, None, self.pose.as_ref(), &self.params, &self.corners, model, model_path)
    }
}

impl TruthFrame {
    /// Check one line (1-based `line`) of `truth.jsonl` against the model,
    /// as [`InitState::validate`] does.
    pub fn validate(&self, path: &Path, line: usize, model: &Model, model_path: &Path) -> Result<()> {
        validate_state(path, Some(line), self.pose.as_ref(), &self.params, &self.corners, model, model_path)
    }
}

impl FrameResult {
    /// Check one line (1-based `line`) of a tracker output file: every
    /// number finite (corners, pose, params, covariance, ms), and corners
    /// present while tracking.
    pub fn validate(&self, path: &Path, line: usize) -> Result<()> {
        let fail = |msg: &str| Err(Error::input(path, format!("line {line}: {msg}")));
        if self.status == Status::Tracking && self.corners.is_empty() {
            return fail("status is tracking but there are no corners");
        }
        if self.corners.iter().any(|c| !all_finite(c)) {
            return fail("corners has a value that is not a finite number");
        }
        if self.pose.is_some_and(|p| !p.is_finite()) {
            return fail("the pose has a value that is not a finite number");
        }
        if self.params.as_deref().is_some_and(|p| !all_finite(p)) {
            return fail("params has a value that is not a finite number");
        }
        if self.covariance.as_deref().is_some_and(|c| !all_finite(c)) {
            return fail("covariance has a value that is not a finite number");
        }
        if !self.ms.is_finite() {
            return fail("ms is not a finite number");
        }
        Ok(())
    }
}
