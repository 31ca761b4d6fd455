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
    /// Pose at frame 0 (3-D trackers). The trackers refuse a pose that puts
    /// the model behind the camera, beside the image or at less than a pixel
    /// across ([`crate::geometry::Camera::start_image_problem`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<Pose>,
    /// Joint values at frame 0.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub params: Vec<f64>,
    /// Image positions of every model vertex at frame 0 (2-D trackers):
    /// each within one image size of the image (x in [−W, 2W], y in
    /// [−H, 2H]), their polygon overlapping it
    /// ([`crate::geometry::polygon::check_polygon_in_image`]).
    #[serde(default)]
    pub corners: Vec<[f64; 2]>,
    /// The known motion of the camera from frame 0 to frame 1: camera 1 in
    /// the frame of camera 0, `[tx, ty, tz, rx, ry, rz]` (metres, axis-angle
    /// radians), as 004's experiments know it (SPEC §4; optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_motion: Option<[f64; 6]>,
}

/// Largest magnitude of each number of a known camera motion (`init.json`'s
/// `camera_motion`, and the `condensation` parameter of that name).
pub const MAX_CAMERA_MOTION: f64 = 1e3;

/// Which parts of the object a line of `truth.jsonl` says are seen: one
/// boolean per model vertex (SPEC §4), or one boolean for the whole object.
/// Written as JSON the way it was read: `true` or `[true, false, ...]`.
#[derive(Clone, Debug, PartialEq)]
pub enum Visibility {
    /// One flag for the whole object.
    Object(bool),
    /// One flag per model vertex, in vertex order.
    Vertices(Vec<bool>),
}

impl Visibility {
    /// Whether any part of the object is seen.
    #[must_use]
    pub fn any(&self) -> bool {
        match self {
            Visibility::Object(seen) => *seen,
            Visibility::Vertices(seen) => seen.contains(&true),
        }
    }

    /// Whether vertex `i` is seen; a vertex beyond a per-vertex list is not.
    #[must_use]
    pub fn vertex(&self, i: usize) -> bool {
        match self {
            Visibility::Object(seen) => *seen,
            Visibility::Vertices(seen) => seen.get(i).copied().unwrap_or(false),
        }
    }
}

impl Default for Visibility {
    /// Seen, as a line without `"visible"` is.
    fn default() -> Self {
        Visibility::Object(true)
    }
}

impl From<bool> for Visibility {
    fn from(seen: bool) -> Self {
        Visibility::Object(seen)
    }
}

impl Serialize for Visibility {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            Visibility::Object(seen) => serializer.serialize_bool(*seen),
            Visibility::Vertices(seen) => seen.serialize(serializer),
        }
    }
}

impl<'de> Deserialize<'de> for Visibility {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> std::result::Result<Self, D::Error> {
        struct VisibilityVisitor;
        impl<'de> serde::de::Visitor<'de> for VisibilityVisitor {
            type Value = Visibility;

            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a boolean or a list of booleans, one per model vertex")
            }

            fn visit_bool<E: serde::de::Error>(self, seen: bool) -> std::result::Result<Visibility, E> {
                Ok(Visibility::Object(seen))
            }

            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<Visibility, A::Error> {
                let mut seen = Vec::with_capacity(seq.size_hint().unwrap_or(0));
                while let Some(flag) = seq.next_element::<bool>()? {
                    seen.push(flag);
                }
                Ok(Visibility::Vertices(seen))
            }
        }
        deserializer.deserialize_any(VisibilityVisitor)
    }
}

/// One line of `truth.jsonl`: the fields of [`InitState`] plus frame and visibility.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TruthFrame {
    /// Frame index.
    pub frame: usize,
    /// Which vertices are seen in this frame (all of them when the key is absent).
    #[serde(default)]
    pub visible: Visibility,
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
    /// Velocity screw estimate (T_x, T_y, T_z, ω_x, ω_y, ω_z), where the
    /// tracker has one (Condensation; a tracker's own key).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_screw: Option<[f64; 6]>,
    /// Effective sample size of the particle weights (Condensation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub effective_sample_size: Option<f64>,
    /// Search branches tried on this frame (Lowe's best-first search).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub search_branches: Option<usize>,
    /// Why the frame is lost, on lost frames: the test the tracker's answer
    /// failed (e.g. too little of its contour supported by image edges) or
    /// why there was no answer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lost_reason: Option<String>,
    /// Milliseconds spent on this frame.
    pub ms: f64,
}

impl FrameResult {
    /// The line of frame `frame` with `status` and `corners`, none of the
    /// optional keys and `ms` 0.
    #[must_use]
    pub fn new(frame: usize, status: Status, corners: Vec<[f64; 2]>) -> Self {
        Self {
            frame,
            status,
            corners,
            pose: None,
            params: None,
            covariance: None,
            velocity_screw: None,
            effective_sample_size: None,
            search_branches: None,
            lost_reason: None,
            ms: 0.0,
        }
    }
}

// ---------------------------------------------------------------------------
// Validation. serde checks the shape of a file; these check what serde cannot
// (finite numbers, positive focal lengths, indices in range). Each takes the
// path of the file the value came from, so the error names it.

use std::path::Path;

use super::json::input_error;
use crate::Result;
use crate::bounds::short_number;

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
            Some(problem) => Err(input_error(path, problem)),
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

/// The `units` a model may have: metres (SPEC §4, ViSP) and the pixel units
/// of the synthetic planar scenes.
pub const MODEL_UNITS: [&str; 2] = ["m", "px"];

/// Largest magnitude of a model coordinate (vertices, joint origins), in
/// the model's units: far beyond any object a camera tracks, and small
/// enough that the model's size and every product of coordinates stay
/// finite.
pub const MAX_MODEL_COORDINATE: f64 = 1e9;

/// Most vertices, edges and faces a model may have (each): every frame
/// projects every vertex and tests every edge against the faces for hidden
/// lines, so per-frame work grows with their product (a 20 000-edge model
/// already takes seconds a frame), and a million-vertex model takes
/// gigabytes to hold.
pub const MAX_MODEL_ELEMENTS: usize = 100_000;

/// Whether every coordinate of `v` lies within ±[`MAX_MODEL_COORDINATE`].
fn within_model_bound(v: &[f64; 3]) -> bool {
    v.iter().all(|c| c.abs() <= MAX_MODEL_COORDINATE)
}

/// Two vertices closer than this fraction of the model's size (the diagonal
/// of its bounding box) are the same point listed twice.
pub const DUPLICATE_VERTEX_TOLERANCE: f64 = 1e-9;

/// A face vertex farther than this fraction of the model's size from the
/// plane of its face makes the face non-planar. Loose enough for coordinates
/// printed with a few decimals and for hand-made CAD models (ViSP's castle
/// tower has a face bent by 3·10⁻³ of the model's size), tight enough to
/// catch a face folded by a wrong vertex index.
pub const FACE_PLANARITY_TOLERANCE: f64 = 1e-2;

/// A part of a model that a problem lies in, so that the reader of a model
/// file can name the line the part was written on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelPart {
    /// Vertex `i`.
    Vertex(usize),
    /// Edge `e`.
    Edge(usize),
    /// Face `f`.
    Face(usize),
    /// Joint `j`.
    Joint(usize),
    /// Entry `k` of joint `j`'s `vertices`.
    JointVertex(usize, usize),
}

/// What is wrong with a model, and in which part (none for the model as a
/// whole, e.g. its units or too few vertices).
#[derive(Clone, Debug, PartialEq)]
pub struct ModelProblem {
    /// The part the problem lies in.
    pub part: Option<ModelPart>,
    /// One line saying what is wrong.
    pub message: String,
}

impl ModelProblem {
    fn of(part: ModelPart, message: String) -> Self {
        Self { part: Some(part), message }
    }

    fn whole(message: String) -> Self {
        Self { part: None, message }
    }
}

/// Where a part of a model was written: a file and a 1-based line.
pub type SourceLine = (std::path::PathBuf, usize);

impl Model {
    /// Check the model: `units` one of [`MODEL_UNITS`], at least two
    /// vertices and one edge, at most [`MAX_MODEL_ELEMENTS`] vertices,
    /// edges and faces, finite coordinates within
    /// ±[`MAX_MODEL_COORDINATE`], no vertex listed twice
    /// (within [`DUPLICATE_VERTEX_TOLERANCE`] of the model's size), the
    /// indices of [`Model::check_indices`], no edge listed twice (either
    /// direction), faces that enclose an area and lie in a plane (within
    /// [`FACE_PLANARITY_TOLERANCE`] of the model's size), joints with
    /// distinct names and `min <= max`. `path` names the model file in the
    /// error.
    pub fn validate(&self, path: &Path) -> Result<()> {
        self.validate_at(path, |_| None)
    }

    /// [`Model::validate`], naming in the error the file and line that
    /// `locate` gives for the part at fault, or `path` when it gives none.
    pub fn validate_at(&self, path: &Path, locate: impl Fn(ModelPart) -> Option<SourceLine>) -> Result<()> {
        self.check().map_err(|problem| match problem.part.and_then(locate) {
            Some((file, line)) => input_error(&file, format!("line {line}: {}", problem.message)),
            None => input_error(path, problem.message),
        })
    }

    /// The checks of [`Model::validate`], returning the first problem.
    pub fn check(&self) -> std::result::Result<(), ModelProblem> {
        if !MODEL_UNITS.contains(&self.units.as_str()) {
            return Err(ModelProblem::whole(format!(
                "units {:?} is not one pipetrack reads: use one of {}",
                self.units,
                MODEL_UNITS.join(", ")
            )));
        }
        let n = self.vertices.len();
        if n < 2 {
            return Err(ModelProblem::whole(format!("the model has {n} vertices: it needs at least 2")));
        }
        if n > MAX_MODEL_ELEMENTS || self.edges.len() > MAX_MODEL_ELEMENTS || self.faces.len() > MAX_MODEL_ELEMENTS {
            return Err(ModelProblem::whole(format!(
                "the model has {n} vertices, {} edges and {} faces: at most {MAX_MODEL_ELEMENTS} of each",
                self.edges.len(),
                self.faces.len()
            )));
        }
        if let Some(i) = self.vertices.iter().position(|v| !all_finite(v)) {
            return Err(ModelProblem::of(
                ModelPart::Vertex(i),
                format!("vertex {i} has a coordinate that is not a finite number"),
            ));
        }
        if let Some(i) = self.vertices.iter().position(|v| !within_model_bound(v)) {
            return Err(ModelProblem::of(
                ModelPart::Vertex(i),
                format!("vertex {i} has a coordinate beyond ±{}", short_number(MAX_MODEL_COORDINATE)),
            ));
        }
        let size = self.size();
        if let Some((i, j)) = self.duplicate_vertex(DUPLICATE_VERTEX_TOLERANCE * size) {
            return Err(ModelProblem::of(
                ModelPart::Vertex(j),
                format!("vertex {j} repeats vertex {i} ({:?}): list each point once", self.vertices[i]),
            ));
        }
        if self.edges.is_empty() {
            return Err(ModelProblem::whole("the model has no edges".to_string()));
        }
        self.check_indices()?;
        let mut seen = std::collections::HashMap::with_capacity(self.edges.len());
        for (e, &[a, b]) in self.edges.iter().enumerate() {
            if let Some(first) = seen.insert((a.min(b), a.max(b)), e) {
                return Err(ModelProblem::of(ModelPart::Edge(e), format!("edge {e} [{a}, {b}] repeats edge {first}")));
            }
        }
        for (f, face) in self.faces.iter().enumerate() {
            self.check_planar(f, face, size).map_err(|msg| ModelProblem::of(ModelPart::Face(f), msg))?;
        }
        let mut names = std::collections::HashSet::new();
        for (j, joint) in self.joints.iter().enumerate() {
            let name = &joint.name;
            let fail = |msg: String| Err(ModelProblem::of(ModelPart::Joint(j), msg));
            if !names.insert(name.as_str()) {
                return fail(format!("joint {j} \"{name}\": another joint has the same name"));
            }
            if !(joint.min.is_finite() && joint.max.is_finite() && joint.min <= joint.max) {
                return fail(format!(
                    "joint \"{name}\": limits min = {} and max = {} must be finite with min <= max",
                    joint.min, joint.max
                ));
            }
        }
        Ok(())
    }

    /// The checks that make the model's indices safe to follow: edges join
    /// two distinct vertices; faces have at least three distinct vertices;
    /// joints move existing vertices, each once, about a finite non-zero
    /// axis through a finite origin. [`Model::check`] makes them too;
    /// geometry built from a model needs only these.
    pub fn check_indices(&self) -> std::result::Result<(), ModelProblem> {
        let n = self.vertices.len();
        let last = n.saturating_sub(1);
        for (e, &[a, b]) in self.edges.iter().enumerate() {
            let fail = |msg: String| Err(ModelProblem::of(ModelPart::Edge(e), msg));
            if a >= n || b >= n {
                return fail(format!("edge {e} [{a}, {b}] refers to a vertex beyond the last one ({last})"));
            }
            if a == b {
                return fail(format!("edge {e} [{a}, {b}] joins a vertex to itself"));
            }
        }
        // Sets, not list scans, so a face or joint of many vertices costs
        // time linear in their number.
        let mut listed = std::collections::HashSet::new();
        for (f, face) in self.faces.iter().enumerate() {
            let fail = |msg: String| Err(ModelProblem::of(ModelPart::Face(f), msg));
            if face.len() < 3 {
                return fail(format!("face {f} has {} vertices: a face needs at least 3", face.len()));
            }
            listed.clear();
            for &v in face {
                if v >= n {
                    return fail(format!("face {f} refers to vertex {v}, beyond the last one ({last})"));
                }
                if !listed.insert(v) {
                    return fail(format!("face {f} lists vertex {v} twice"));
                }
            }
        }
        for (j, joint) in self.joints.iter().enumerate() {
            let name = &joint.name;
            if !all_finite(&joint.origin) || !all_finite(&joint.axis) {
                return Err(ModelProblem::of(
                    ModelPart::Joint(j),
                    format!("joint \"{name}\": origin and axis must be finite numbers"),
                ));
            }
            if !within_model_bound(&joint.origin) {
                return Err(ModelProblem::of(
                    ModelPart::Joint(j),
                    format!(
                        "joint \"{name}\": the origin has a coordinate beyond ±{}",
                        short_number(MAX_MODEL_COORDINATE)
                    ),
                ));
            }
            let length2 = joint.axis.iter().map(|a| a * a).sum::<f64>();
            if length2 == 0.0 {
                return Err(ModelProblem::of(
                    ModelPart::Joint(j),
                    format!("joint \"{name}\": the axis is the zero vector"),
                ));
            }
            if !length2.is_finite() {
                return Err(ModelProblem::of(
                    ModelPart::Joint(j),
                    format!("joint \"{name}\": the axis is too long to normalise"),
                ));
            }
            listed.clear();
            for (k, &v) in joint.vertices.iter().enumerate() {
                let fail = |msg: String| Err(ModelProblem::of(ModelPart::JointVertex(j, k), msg));
                if v >= n {
                    return fail(format!("joint \"{name}\" moves vertex {v}, beyond the last one ({last})"));
                }
                if !listed.insert(v) {
                    return fail(format!("joint \"{name}\" lists vertex {v} twice"));
                }
            }
        }
        Ok(())
    }

    /// The diagonal of the vertices' bounding box ([`bounding_diagonal`]):
    /// the scale of the model's tolerances.
    fn size(&self) -> f64 {
        bounding_diagonal(&self.vertices)
    }

    /// The first vertex `j` within `tolerance` of an earlier vertex moved by
    /// the same joints, as `(i, j)` with `i` the earliest such vertex
    /// ([`PointGrid`]). Two parts of an articulated model may meet at q = 0,
    /// like a closed lid on its box: their vertices part when a joint moves.
    fn duplicate_vertex(&self, tolerance: f64) -> Option<(usize, usize)> {
        // Which joints move each vertex (indices out of range are another check's).
        let mut movers: Vec<Vec<usize>> = vec![Vec::new(); self.vertices.len()];
        for (k, joint) in self.joints.iter().enumerate() {
            for &i in &joint.vertices {
                if let Some(m) = movers.get_mut(i)
                    && m.last() != Some(&k)
                {
                    m.push(k);
                }
            }
        }
        let mut grid = PointGrid::new(&self.vertices, tolerance);
        for j in 0..self.vertices.len() {
            if let Some(i) = grid.earliest_near_where(j, |i| movers[i] == movers[j]) {
                return Some((i, j));
            }
            grid.insert(j);
        }
        None
    }

    /// `Err(message)` when face `f` (indices in range) encloses no area or
    /// has a vertex off its plane by more than [`FACE_PLANARITY_TOLERANCE`]
    /// times `size`. The plane is Newell's: the normal of the polygon's
    /// vector area, through the centroid of its vertices.
    fn check_planar(&self, f: usize, face: &[usize], size: f64) -> std::result::Result<(), String> {
        let p: Vec<[f64; 3]> = face.iter().map(|&i| self.vertices[i]).collect();
        let normal = newell_normal(&self.vertices, face);
        let mut centroid = [0.0; 3];
        for a in &p {
            for c in 0..3 {
                centroid[c] += a[c] / p.len() as f64;
            }
        }
        // |normal| is twice the area.
        let twice_area = normal.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(twice_area > DUPLICATE_VERTEX_TOLERANCE * size * size) {
            return Err(format!("face {f} encloses no area: its vertices are on one line"));
        }
        let tolerance = FACE_PLANARITY_TOLERANCE * size;
        for (k, a) in p.iter().enumerate() {
            let distance = (0..3).map(|c| (a[c] - centroid[c]) * normal[c]).sum::<f64>().abs() / twice_area;
            if distance > tolerance {
                return Err(format!(
                    "face {f} is not planar: vertex {} is {distance:.3e} {} off the face's plane \
                     (tolerance {tolerance:.3e}, {FACE_PLANARITY_TOLERANCE} of the model's size)",
                    face[k], self.units
                ));
            }
        }
        Ok(())
    }
}

/// Newell's normal of the polygon `face` (indices into `vertices`): the
/// normal of its vector area, twice the area long, pointing outwards for a
/// loop counter-clockwise seen from outside; for a loop p₀…p_{n−1},
/// n_x = Σ (y_k − y_{k+1})(z_k + z_{k+1}), and cyclically for n_y, n_z.
pub(crate) fn newell_normal(vertices: &[[f64; 3]], face: &[usize]) -> [f64; 3] {
    let mut normal = [0.0; 3];
    for (k, &i) in face.iter().enumerate() {
        let (a, b) = (vertices[i], vertices[face[(k + 1) % face.len()]]);
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    normal
}

/// The diagonal of the bounding box of `points` (0 for fewer than two
/// distinct points, or when it overflows).
pub(crate) fn bounding_diagonal(points: &[[f64; 3]]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for v in points {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    let d2: f64 = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum();
    if d2.is_finite() { d2.sqrt() } else { 0.0 }
}

/// Finds, among the points inserted so far, the earliest one within a
/// tolerance of a given point. Points go into a grid of cells `tolerance`
/// wide (for a zero tolerance, one cell per distinct point), and each query
/// looks only in its own and the 26 neighbouring cells; while few inserted
/// points share a cell, each query takes constant time.
pub(crate) struct PointGrid<'a> {
    points: &'a [[f64; 3]],
    lo: [f64; 3],
    tolerance: f64,
    cells: std::collections::HashMap<[i64; 3], Vec<usize>>,
}

impl<'a> PointGrid<'a> {
    /// An empty grid over `points` (finite coordinates).
    pub(crate) fn new(points: &'a [[f64; 3]], tolerance: f64) -> Self {
        let mut lo = [f64::INFINITY; 3];
        for p in points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
            }
        }
        Self { points, lo, tolerance, cells: std::collections::HashMap::new() }
    }

    fn cell(&self, p: &[f64; 3]) -> [i64; 3] {
        // Within the bounding box, (p - lo) / tolerance is at most
        // 1 / DUPLICATE_VERTEX_TOLERANCE, far inside i64.
        std::array::from_fn(|k| {
            if self.tolerance > 0.0 {
                ((p[k] - self.lo[k]) / self.tolerance).floor() as i64
            } else {
                // Adding 0.0 makes -0.0 the same point as 0.0.
                (p[k] + 0.0).to_bits() as i64
            }
        })
    }

    /// Add point `j` to the grid.
    pub(crate) fn insert(&mut self, j: usize) {
        let c = self.cell(&self.points[j]);
        self.cells.entry(c).or_default().push(j);
    }

    /// The earliest inserted point within the tolerance of point `j`.
    pub(crate) fn earliest_near(&self, j: usize) -> Option<usize> {
        self.earliest_near_where(j, |_| true)
    }

    /// [`PointGrid::earliest_near`] among the points `accept` takes.
    pub(crate) fn earliest_near_where(&self, j: usize, accept: impl Fn(usize) -> bool) -> Option<usize> {
        let p = &self.points[j];
        let c = self.cell(p);
        let reach: i64 = if self.tolerance > 0.0 { 1 } else { 0 };
        let mut earliest: Option<usize> = None;
        for dx in -reach..=reach {
            for dy in -reach..=reach {
                for dz in -reach..=reach {
                    let Some(near) = self.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else { continue };
                    for &i in near {
                        let d2: f64 = (0..3).map(|k| (self.points[i][k] - p[k]).powi(2)).sum();
                        if d2.sqrt() <= self.tolerance && earliest.is_none_or(|e| i < e) && accept(i) {
                            earliest = Some(i);
                        }
                    }
                }
            }
        }
        earliest
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
    let fail = |msg: String| Err(input_error(path, format!("{what}{msg}")));
    if pose.is_some_and(|p| !p.is_finite()) {
        return fail("the pose has a value that is not a finite number".to_string());
    }
    if !all_finite(params) {
        return fail("params has a value that is not a finite number".to_string());
    }
    if !params.is_empty() && params.len() != model.joints.len() {
        return fail(format!(
            "{} params but the model has {} (give one value per joint, or none)",
            params.len(),
            crate::bounds::counted(model.joints.len(), "joint", "joints")
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
        return Err(input_error(
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
            return Err(input_error(path, "neither a pose nor corners: a tracker needs one of them"));
        }
        if let Some(v) = self.camera_motion.into_iter().flatten().find(|v| !(v.abs() <= MAX_CAMERA_MOTION)) {
            return Err(input_error(
                path,
                format!(
                    "camera_motion has {}: each number must lie within ±{MAX_CAMERA_MOTION} (metres, radians)",
                    short_number(v)
                ),
            ));
        }
        validate_state(path, None, self.pose.as_ref(), &self.params, &self.corners, model, model_path)
    }
}

impl TruthFrame {
    /// Check one line (1-based `line`) of `truth.jsonl` against the model,
    /// as [`InitState::validate`] does.
    /// A per-vertex `"visible"` list must have one flag per model vertex.
    pub fn validate(&self, path: &Path, line: usize, model: &Model, model_path: &Path) -> Result<()> {
        validate_state(path, Some(line), self.pose.as_ref(), &self.params, &self.corners, model, model_path)?;
        if let Visibility::Vertices(seen) = &self.visible {
            let n = model.vertices.len();
            if seen.len() != n {
                return Err(input_error(
                    path,
                    format!(
                        "line {line}: \"visible\" has {} flags but the model has {n} vertices \
                         (give one boolean per vertex, or a single boolean)",
                        seen.len()
                    ),
                ));
            }
        }
        Ok(())
    }
}

impl FrameResult {
    /// Check one line (1-based `line`) of a tracker output file: every
    /// number finite (corners, pose, params, covariance, ms), and corners
    /// present while tracking.
    pub fn validate(&self, path: &Path, line: usize) -> Result<()> {
        let fail = |msg: &str| Err(input_error(path, format!("line {line}: {msg}")));
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

/// The 1-based line of `text`, the JSON text of a model, on which `part`
/// starts: a vertex, edge, face or joint, or one entry of a joint's
/// `vertices`; `None` when `text` is not a model or lacks the part. The
/// positions come from serde_json's raw values, which borrow their text
/// from `text`.
#[must_use]
pub fn model_json_line(text: &str, part: ModelPart) -> Option<usize> {
    use serde_json::value::RawValue;

    #[derive(Deserialize)]
    struct Lists<'a> {
        #[serde(borrow, default)]
        vertices: Vec<&'a RawValue>,
        #[serde(borrow, default)]
        edges: Vec<&'a RawValue>,
        #[serde(borrow, default)]
        faces: Vec<&'a RawValue>,
        #[serde(borrow, default)]
        joints: Vec<&'a RawValue>,
    }
    #[derive(Deserialize)]
    struct JointLists<'a> {
        #[serde(borrow, default)]
        vertices: Vec<&'a RawValue>,
    }

    let lists: Lists = serde_json::from_str(text).ok()?;
    let raw: &str = match part {
        ModelPart::Vertex(i) => lists.vertices.get(i)?.get(),
        ModelPart::Edge(e) => lists.edges.get(e)?.get(),
        ModelPart::Face(f) => lists.faces.get(f)?.get(),
        ModelPart::Joint(j) => lists.joints.get(j)?.get(),
        ModelPart::JointVertex(j, k) => {
            let joint: JointLists = serde_json::from_str(lists.joints.get(j)?.get()).ok()?;
            joint.vertices.get(k)?.get()
        }
    };
    let offset = (raw.as_ptr() as usize).checked_sub(text.as_ptr() as usize)?;
    Some(text.get(..offset)?.matches('\n').count() + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Error;

    const SQUARE: &str = r#"{"name": "sq",
 "vertices": [[0, 0, 0], [1, 0, 0],
              [1, 1, 0], [0, 1, 0]],
 "edges": [[0, 1], [1, 2],
           [2, 3], [3, 9]],
 "faces": [
   [0, 1, 2, 3]],
 "joints": [{"name": "lid", "origin": [0, 0, 0], "axis": [1, 0, 0], "min": 0, "max": 1,
             "vertices": [2,
                          7]}]}"#;

    #[test]
    fn json_lines_of_model_parts() {
        assert_eq!(model_json_line(SQUARE, ModelPart::Vertex(0)), Some(2));
        assert_eq!(model_json_line(SQUARE, ModelPart::Vertex(3)), Some(3));
        assert_eq!(model_json_line(SQUARE, ModelPart::Edge(3)), Some(5));
        assert_eq!(model_json_line(SQUARE, ModelPart::Face(0)), Some(7));
        assert_eq!(model_json_line(SQUARE, ModelPart::Joint(0)), Some(8));
        assert_eq!(model_json_line(SQUARE, ModelPart::JointVertex(0, 1)), Some(10));
        assert_eq!(model_json_line(SQUARE, ModelPart::Edge(4)), None);
        assert_eq!(model_json_line("not json", ModelPart::Edge(0)), None);
    }

    #[test]
    fn validate_at_names_the_line_of_the_part_at_fault() {
        let model: Model = serde_json::from_str(SQUARE).unwrap();
        let path = Path::new("seq/model.json");
        let locate = |part| model_json_line(SQUARE, part).map(|line| (path.to_path_buf(), line));
        let message = |result: Result<()>| match result {
            Err(Error::Input { path, message }) => {
                assert_eq!(path, Path::new("seq/model.json"));
                message
            }
            other => panic!("expected an input error, got {other:?}"),
        };
        let msg = message(model.validate_at(path, locate));
        assert_eq!(msg, "line 5: edge 3 [3, 9] refers to a vertex beyond the last one (3)");
        let mut fixed = model.clone();
        fixed.edges[3] = [3, 0];
        let msg = message(fixed.validate_at(path, locate));
        assert_eq!(msg, "line 10: joint \"lid\" moves vertex 7, beyond the last one (3)");
        // Without a line for the part, or for the model as a whole, no line.
        assert!(!message(model.validate(path)).starts_with("line"));
        fixed.units = "mm".into();
        assert!(message(fixed.validate_at(path, locate)).starts_with("units \"mm\""));
    }

    #[test]
    fn index_checks_are_part_of_the_model_checks() {
        let mut model: Model = serde_json::from_str(SQUARE).unwrap();
        model.edges[3] = [3, 0];
        model.joints[0].vertices = vec![2, 3];
        assert_eq!(model.check(), Ok(()));
        for (change, part) in [
            (Box::new(|m: &mut Model| m.edges[1] = [2, 2]) as Box<dyn Fn(&mut Model)>, ModelPart::Edge(1)),
            (Box::new(|m: &mut Model| m.faces[0].truncate(2)), ModelPart::Face(0)),
            (Box::new(|m: &mut Model| m.faces[0][3] = 4), ModelPart::Face(0)),
            (Box::new(|m: &mut Model| m.joints[0].axis = [1e300, 1e300, 0.0]), ModelPart::Joint(0)),
            (Box::new(|m: &mut Model| m.joints[0].vertices.push(2)), ModelPart::JointVertex(0, 2)),
        ] {
            let mut bad = model.clone();
            change(&mut bad);
            let problem = bad.check_indices().unwrap_err();
            assert_eq!(problem.part, Some(part), "{}", problem.message);
            assert_eq!(bad.check().unwrap_err(), problem);
        }
    }
}
