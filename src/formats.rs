//! The file formats of SPEC §4 (contract) as serde types: `camera.json`,
//! `model.json`, `init.json`, lines of `truth.jsonl` and of the tracker's
//! JSON Lines output. Loading and validating a whole sequence folder is
//! [`crate::sequence`]'s job; these types only describe the fields.

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
