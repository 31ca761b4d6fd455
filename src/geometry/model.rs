//! The model's geometry (SPEC §4 `model.json`): vertices under joint values,
//! face normals, which faces face the camera and which edges are visible.
//!
//! - **Joint rule.** A joint with value q moves its listed vertices to
//!   `origin + R(axis, q)·(X − origin)`, the right-hand rotation by q about
//!   the unit axis through `origin` (object frame), X the position listed in
//!   `vertices` (the vertices are given at q = 0). A vertex listed by several
//!   joints is moved by each, the last-listed joint first:
//!   X' = T₁(q₁)·T₂(q₂)·…·X, each Tⱼ about its q = 0 origin and axis — the
//!   kinematic chain when every joint lists the vertices of the joints
//!   carried by it and is listed before them.
//! - **Face normals.** Newell's method: for a loop p₀…p_{n−1},
//!   n = Σ (p_k − p_{k+1}) × … written out per component as
//!   n_x = Σ (y_k − y_{k+1})(z_k + z_{k+1}) and cyclically; exact for planar
//!   loops and the best-fit plane's normal for slightly non-planar ones; for
//!   a loop counter-clockwise seen from outside it points outwards.
//! - **Visibility.** A face faces the camera when its outward normal points
//!   towards the centre of projection: n·P < 0 for a point P of the face in
//!   the camera frame (the back-face test). An edge is visible when at least
//!   one face it borders faces the camera; an edge bordering no face (every
//!   edge of a model without faces) always is. Hiding of edges behind other
//!   faces of the model is not decided here.

use glam::{DMat3, DVec3};

use super::pose::Pose;
use crate::io::formats::Model;
use crate::{Error, Result};

/// Newell's normal of the face `face` (a loop of indices into `vertices`),
/// not normalised (its length is twice the loop's area). Outward for a loop
/// counter-clockwise seen from outside (module doc). Any frame: the normal
/// is in the frame of `vertices`.
#[must_use]
pub fn newell_normal(vertices: &[DVec3], face: &[usize]) -> DVec3 {
    let mut normal = DVec3::ZERO;
    for (k, &i) in face.iter().enumerate() {
        let (p, q) = (vertices[i], vertices[face[(k + 1) % face.len()]]);
        normal += DVec3::new((p.y - q.y) * (p.z + q.z), (p.z - q.z) * (p.x + q.x), (p.x - q.x) * (p.y + q.y));
    }
    normal
}

/// The back-face test: whether a face with outward normal `normal` through
/// the point `point` (both in the camera frame) faces the camera, n·P < 0.
/// False for a face seen exactly edge-on and for NaN.
#[must_use]
pub fn faces_camera(normal: DVec3, point: DVec3) -> bool {
    normal.dot(point) < 0.0
}

/// A joint with its axis normalised (see the module doc's joint rule).
#[derive(Clone, Debug, PartialEq)]
struct JointAxis {
    origin: DVec3,
    axis: DVec3,
    vertices: Vec<usize>,
    limits: [f64; 2],
}

/// The geometry of a model: its vertices at joint values 0 and its topology
/// (edges, faces, which faces each edge borders, which edges meet at each
/// vertex), indices checked.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelGeometry {
    vertices: Vec<DVec3>,
    edges: Vec<[usize; 2]>,
    faces: Vec<Vec<usize>>,
    joints: Vec<JointAxis>,
    edge_faces: Vec<Vec<usize>>,
    vertex_edges: Vec<Vec<usize>>,
}

/// The error for `values` joint values given a model of `joints` joints.
fn joint_count_error(values: usize, joints: usize) -> Error {
    Error::Parameter(format!(
        "{} for a model with {}",
        crate::bounds::counted(values, "joint value", "joint values"),
        crate::bounds::counted(joints, "joint", "joints")
    ))
}

impl ModelGeometry {
    /// The geometry of `model`. Errors (`Error::Parameter`) when its
    /// indices are unsafe to follow ([`Model::check_indices`]: an edge not a
    /// pair of distinct vertices, a face of fewer than three distinct
    /// vertices or one out of range, a joint moving a vertex out of range or
    /// with a zero or non-finite axis). The other checks of a model file
    /// (finite coordinates, repeated edges, planar faces) are
    /// [`Model::validate`]'s.
    pub fn new(model: &Model) -> Result<Self> {
        model.check_indices().map_err(|problem| Error::Parameter(problem.message))?;
        let nv = model.vertices.len();
        let mut vertex_edges = vec![Vec::new(); nv];
        for (k, &[i, j]) in model.edges.iter().enumerate() {
            vertex_edges[i].push(k);
            vertex_edges[j].push(k);
        }
        let mut edge_faces = vec![Vec::new(); model.edges.len()];
        for (f, face) in model.faces.iter().enumerate() {
            for (a, &i) in face.iter().enumerate() {
                let j = face[(a + 1) % face.len()];
                for &k in &vertex_edges[i] {
                    let [ei, ej] = model.edges[k];
                    if (ei, ej) == (i, j) || (ei, ej) == (j, i) {
                        edge_faces[k].push(f);
                    }
                }
            }
        }
        let joints = model
            .joints
            .iter()
            .map(|joint| {
                let axis = DVec3::from_array(joint.axis);
                JointAxis {
                    origin: DVec3::from_array(joint.origin),
                    axis: axis / axis.length(),
                    vertices: joint.vertices.clone(),
                    limits: [joint.min, joint.max],
                }
            })
            .collect();
        Ok(Self {
            vertices: model.vertices.iter().map(|v| DVec3::from_array(*v)).collect(),
            edges: model.edges.clone(),
            faces: model.faces.clone(),
            joints,
            edge_faces,
            vertex_edges,
        })
    }

    /// The vertices at joint values 0 (object frame, model-vertex order).
    #[must_use]
    pub fn vertices(&self) -> &[DVec3] {
        &self.vertices
    }

    /// The edges, pairs of vertex indices.
    #[must_use]
    pub fn edges(&self) -> &[[usize; 2]] {
        &self.edges
    }

    /// The faces, vertex loops counter-clockwise seen from outside.
    #[must_use]
    pub fn faces(&self) -> &[Vec<usize>] {
        &self.faces
    }

    /// Per edge, the faces it borders (an edge of a face is a pair of
    /// consecutive vertices of its loop, either direction).
    #[must_use]
    pub fn edge_faces(&self) -> &[Vec<usize>] {
        &self.edge_faces
    }

    /// Per vertex, the edges that meet at it.
    #[must_use]
    pub fn vertex_edges(&self) -> &[Vec<usize>] {
        &self.vertex_edges
    }

    /// Number of joints.
    #[must_use]
    pub fn joint_count(&self) -> usize {
        self.joints.len()
    }

    /// The centroid (mean) of the vertices at joint values 0; the origin for
    /// a model without vertices.
    #[must_use]
    pub fn centroid(&self) -> DVec3 {
        let n = self.vertices.len();
        if n == 0 {
            return DVec3::ZERO;
        }
        let inv_n = 1.0 / n as f64;
        DVec3::new(
            self.vertices.iter().map(|v| v.x).sum::<f64>() * inv_n,
            self.vertices.iter().map(|v| v.y).sum::<f64>() * inv_n,
            self.vertices.iter().map(|v| v.z).sum::<f64>() * inv_n,
        )
    }

    /// The vertices (object frame) with the joints at `params`, one value
    /// per joint in radians, by the joint rule of the module doc; an empty
    /// `params` is every joint at 0. Errors when `params` has another length.
    pub fn posed_vertices(&self, params: &[f64]) -> Result<Vec<DVec3>> {
        let mut vertices = self.vertices.clone();
        if params.is_empty() {
            return Ok(vertices);
        }
        if params.len() != self.joints.len() {
            return Err(joint_count_error(params.len(), self.joints.len()));
        }
        for (joint, &q) in self.joints.iter().zip(params).rev() {
            let rotation = DMat3::from_axis_angle(joint.axis, q);
            for &v in &joint.vertices {
                vertices[v] = joint.origin + rotation * (vertices[v] - joint.origin);
            }
        }
        Ok(vertices)
    }

    /// [`ModelGeometry::posed_vertices`] at `params` (one value per joint),
    /// with the derivative of every vertex with respect to every joint value:
    /// `derivatives[v * joints + j]` = ∂Y_v/∂q_j (object frame). Joint j
    /// rotates by R(a_j, q_j) about the axis a_j through o_j, so a vertex it
    /// moves to Z gets a_j × (Z − o_j), carried on by the rotations of the
    /// joints applied after it (the joint rule's order); zero for a vertex
    /// the joint does not move. Errors when `params` has another length.
    pub fn posed_vertices_with_joint_derivatives(&self, params: &[f64]) -> Result<(Vec<DVec3>, Vec<DVec3>)> {
        let joints = self.joints.len();
        if params.len() != joints {
            return Err(joint_count_error(params.len(), joints));
        }
        let mut vertices = self.vertices.clone();
        let mut derivatives = vec![DVec3::ZERO; vertices.len() * joints];
        for (j, (joint, &q)) in self.joints.iter().zip(params).enumerate().rev() {
            let rotation = DMat3::from_axis_angle(joint.axis, q);
            for &v in &joint.vertices {
                vertices[v] = joint.origin + rotation * (vertices[v] - joint.origin);
                for d in &mut derivatives[v * joints + j + 1..(v + 1) * joints] {
                    *d = rotation * *d;
                }
                derivatives[v * joints + j] = joint.axis.cross(vertices[v] - joint.origin);
            }
        }
        Ok((vertices, derivatives))
    }

    /// The rigid motion of the object frame that turns it by `angle`
    /// radians about joint `joint`'s axis (the right-hand rotation about
    /// the axis through its origin). Composed onto a camera-from-object
    /// pose (`pose * swing`) while that joint's value changes by −`angle`,
    /// it leaves the part the joint moves where it was and swings the rest
    /// of the model about the joint. `None` when `joint` is out of range or
    /// a joint applied after it (a lower index) moves a vertex it moves:
    /// its axis then moves with that joint.
    #[must_use]
    pub fn joint_swing(&self, joint: usize, angle: f64) -> Option<Pose> {
        let moved = &self.joints.get(joint)?.vertices;
        if self.joints[..joint].iter().any(|outer| outer.vertices.iter().any(|v| moved.contains(v))) {
            return None;
        }
        let JointAxis { origin, axis, .. } = self.joints[joint];
        let rotation = DMat3::from_axis_angle(axis, angle);
        Some(Pose::new(rotation, origin - rotation * origin))
    }

    /// Each joint's limits `[min, max]`, radians, in joint order.
    #[must_use]
    pub fn joint_limits(&self) -> Vec<[f64; 2]> {
        self.joints.iter().map(|j| j.limits).collect()
    }

    /// The vertices in the camera frame: [`ModelGeometry::posed_vertices`]
    /// at `params`, carried by the camera-from-object `pose`.
    pub fn camera_vertices(&self, pose: &Pose, params: &[f64]) -> Result<Vec<DVec3>> {
        Ok(self.posed_vertices(params)?.into_iter().map(|v| pose.apply(v)).collect())
    }

    /// Newell's normal ([`newell_normal`]) of every face of `vertices`
    /// (this model's vertices in any frame, model-vertex order).
    #[must_use]
    pub fn face_normals(&self, vertices: &[DVec3]) -> Vec<DVec3> {
        self.faces.iter().map(|face| newell_normal(vertices, face)).collect()
    }

    /// Whether each face faces the camera ([`faces_camera`]), given the
    /// vertices in the camera frame.
    #[must_use]
    pub fn facing_faces(&self, camera_vertices: &[DVec3]) -> Vec<bool> {
        self.faces
            .iter()
            .map(|face| faces_camera(newell_normal(camera_vertices, face), camera_vertices[face[0]]))
            .collect()
    }

    /// Whether each edge is visible with the joints at `params` and the model
    /// at the camera-from-object `pose`: [`ModelGeometry::camera_vertices`],
    /// [`ModelGeometry::facing_faces`], [`ModelGeometry::visible_edges`].
    pub fn visible_edges_at(&self, pose: &Pose, params: &[f64]) -> Result<Vec<bool>> {
        let camera_vertices = self.camera_vertices(pose, params)?;
        Ok(self.visible_edges(&self.facing_faces(&camera_vertices)))
    }

    /// Whether each edge is visible given which faces face the camera
    /// (`facing`, one per face): it borders a facing face, or no face at all.
    #[must_use]
    pub fn visible_edges(&self, facing: &[bool]) -> Vec<bool> {
        self.edge_faces.iter().map(|fs| fs.is_empty() || fs.iter().any(|&f| facing[f])).collect()
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::FRAC_PI_2;

    use super::*;
    use crate::io::formats::Joint;

    /// The unit cube [0, 1]³: vertex i has coordinates from its bits
    /// (x: bit 0, y: bit 1, z: bit 2); faces −x, +x, −y, +y, −z, +z,
    /// counter-clockwise seen from outside; the twelve edges.
    fn cube() -> Model {
        let vertices = (0..8).map(|i| std::array::from_fn(|a| f64::from((i >> a) & 1))).collect();
        let faces = vec![
            vec![0, 4, 6, 2],
            vec![1, 3, 7, 5],
            vec![0, 1, 5, 4],
            vec![2, 6, 7, 3],
            vec![0, 2, 3, 1],
            vec![4, 5, 7, 6],
        ];
        let mut edges = Vec::new();
        for i in 0..8usize {
            for a in 0..3 {
                if i & (1 << a) == 0 {
                    edges.push([i, i | (1 << a)]);
                }
            }
        }
        Model { name: "cube".into(), units: "m".into(), vertices, edges, faces, joints: Vec::new() }
    }

    #[test]
    fn cube_newell_normals_are_the_outward_axes() {
        let geometry = ModelGeometry::new(&cube()).expect("cube");
        let normals = geometry.face_normals(geometry.vertices());
        let expected = [-DVec3::X, DVec3::X, -DVec3::Y, DVec3::Y, -DVec3::Z, DVec3::Z];
        for (n, e) in normals.iter().zip(expected) {
            // A unit square: |n| = 2·area = 2.
            assert_eq!(*n, 2.0 * e);
        }
        assert_eq!(geometry.centroid(), DVec3::splat(0.5));
        assert!(geometry.edge_faces().iter().all(|fs| fs.len() == 2));
        assert!(geometry.vertex_edges().iter().all(|es| es.len() == 3));
    }

    #[test]
    fn exactly_three_cube_faces_are_visible_from_a_corner_view() {
        let geometry = ModelGeometry::new(&cube()).expect("cube");
        // Camera on the diagonal beyond the corner (1, 1, 1) looking at the
        // centre: camera-from-object rotation taking (1, 1, 1)/√3 to −z.
        let back = DVec3::ONE.normalize();
        let right = DVec3::new(1.0, -1.0, 0.0).normalize();
        let down = (-back).cross(right);
        let rotation = DMat3::from_cols(right, down, -back).transpose();
        let eye = DVec3::splat(0.5) + back * 4.0;
        let pose = Pose::new(rotation, -(rotation * eye));
        assert!((pose.apply(DVec3::splat(0.5)) - DVec3::new(0.0, 0.0, 4.0)).length() < 1e-12);
        let cam = geometry.camera_vertices(&pose, &[]).expect("pose");
        let facing = geometry.facing_faces(&cam);
        assert_eq!(facing, [false, true, false, true, false, true], "+x, +y, +z face the eye");
        // The nine edges of those faces; the three meeting at the far corner 0 are hidden.
        let visible = geometry.visible_edges(&facing);
        assert_eq!(visible.iter().filter(|&&v| v).count(), 9);
        for (k, &[i, j]) in geometry.edges().iter().enumerate() {
            assert_eq!(visible[k], i != 0 && j != 0, "edge {i}-{j}");
        }
        assert_eq!(geometry.visible_edges_at(&pose, &[]).expect("pose"), visible);
    }

    #[test]
    fn every_edge_is_visible_without_faces() {
        let model = Model { faces: Vec::new(), ..cube() };
        let geometry = ModelGeometry::new(&model).expect("cube");
        assert_eq!(geometry.facing_faces(geometry.vertices()), Vec::<bool>::new());
        assert!(geometry.visible_edges(&[]).iter().all(|&v| v));
    }

    #[test]
    fn revolute_joint_moves_a_vertex_as_calculated_by_hand() {
        // A lid hinged on the cube's top-back edge: axis +x through (0, 0, 1),
        // moving the +z face's vertices 4..8.
        let mut model = cube();
        model.joints.push(Joint {
            name: "lid".into(),
            origin: [0.0, 0.0, 1.0],
            axis: [2.0, 0.0, 0.0],
            vertices: vec![6, 7],
            min: -FRAC_PI_2,
            max: FRAC_PI_2,
        });
        let geometry = ModelGeometry::new(&model).expect("cube with a lid");
        // Vertex 6 = (0, 1, 1): X − origin = (0, 1, 0); a right-hand quarter
        // turn about +x takes y to z: (0, 0, 1), so it lands at (0, 0, 2).
        let v = geometry.posed_vertices(&[FRAC_PI_2]).expect("one value");
        assert!((v[6] - DVec3::new(0.0, 0.0, 2.0)).length() < 1e-15, "{}", v[6]);
        assert!((v[7] - DVec3::new(1.0, 0.0, 2.0)).length() < 1e-15, "{}", v[7]);
        // At 30°: (0, cos 30°, 1 + sin 30°).
        let v = geometry.posed_vertices(&[30f64.to_radians()]).expect("one value");
        assert!((v[6] - DVec3::new(0.0, 0.75f64.sqrt(), 1.5)).length() < 1e-15, "{}", v[6]);
        // Unlisted vertices stay; q = 0 and no values are the listed positions.
        assert_eq!(v[5], DVec3::new(1.0, 0.0, 1.0));
        assert_eq!(geometry.posed_vertices(&[0.0]).expect("zero"), geometry.vertices());
        assert_eq!(geometry.posed_vertices(&[]).expect("none"), geometry.vertices());
        assert!(geometry.posed_vertices(&[0.1, 0.2]).is_err());
    }

    #[test]
    fn chained_joints_apply_the_child_first() {
        // Parent: about +z through the origin, moves 1 and 3; child: about +z
        // through vertex 1's rest position (1, 0, 0), moves 3 only.
        let mut model = cube();
        let joint = |name: &str, origin: [f64; 3], vertices: Vec<usize>| Joint {
            name: name.into(),
            origin,
            axis: [0.0, 0.0, 1.0],
            vertices,
            min: -3.0,
            max: 3.0,
        };
        model.joints = vec![joint("parent", [0.0; 3], vec![1, 3]), joint("child", [1.0, 0.0, 0.0], vec![3])];
        let geometry = ModelGeometry::new(&model).expect("chain");
        let v = geometry.posed_vertices(&[FRAC_PI_2, FRAC_PI_2]).expect("two values");
        // Child: (1, 1, 0) about (1, 0, 0) → (0, 0, 0); parent then leaves it at the origin.
        // Parent: (1, 0, 0) → (0, 1, 0).
        assert!((v[1] - DVec3::new(0.0, 1.0, 0.0)).length() < 1e-15, "{}", v[1]);
        assert!(v[3].length() < 1e-15, "{}", v[3]);
    }

    #[test]
    fn a_joint_swing_keeps_the_moved_part_and_turns_the_rest_about_the_joint() {
        let mut model = cube();
        let joint = |origin: [f64; 3], axis: [f64; 3], vertices: Vec<usize>| Joint {
            name: "joint".into(),
            origin,
            axis,
            vertices,
            min: -3.0,
            max: 3.0,
        };
        model.joints = vec![
            joint([0.0, 0.0, 1.0], [2.0, 0.0, 0.0], vec![6, 7]),
            joint([0.0, 1.0, 0.0], [0.0, 0.0, 1.0], vec![2, 6]),
        ];
        let geometry = ModelGeometry::new(&model).expect("cube with two joints");
        let pose = Pose::from_axis_angle(DVec3::new(0.3, -0.2, 0.1), DVec3::new(0.1, 0.2, 3.0));
        let params = [0.4, -0.7];
        let before = geometry.camera_vertices(&pose, &params).expect("posed");
        let delta = 0.25;
        let swung = pose * geometry.joint_swing(0, delta).expect("the outermost joint swings");
        let after = geometry.camera_vertices(&swung, &[params[0] - delta, params[1]]).expect("posed");
        // The lid (6, 7) stays; the rest turns by `delta` about the hinge,
        // the x axis through (0, 0, 1) in the object frame.
        for v in [6, 7] {
            assert!((after[v] - before[v]).length() < 1e-12, "vertex {v}");
        }
        let hinge = pose.apply(DVec3::new(0.0, 0.0, 1.0));
        let axis = pose.rotate(DVec3::X);
        let turned = DMat3::from_axis_angle(axis, delta);
        for v in [0, 1, 2, 3, 4, 5] {
            let expected = hinge + turned * (before[v] - hinge);
            assert!((after[v] - expected).length() < 1e-12, "vertex {v}");
        }
        // Vertex 6 is moved by both joints: the second one's axis moves
        // with the first, so it has no swing of its own.
        assert!(geometry.joint_swing(1, delta).is_none());
        assert!(geometry.joint_swing(2, delta).is_none());
    }

    #[test]
    fn bad_indices_are_refused() {
        let mut model = cube();
        model.edges.push([0, 0]);
        assert!(ModelGeometry::new(&model).is_err());
        let mut model = cube();
        model.faces.push(vec![0, 1]);
        assert!(ModelGeometry::new(&model).is_err());
        let mut model = cube();
        model.faces.push(vec![0, 1, 9]);
        assert!(ModelGeometry::new(&model).is_err());
    }
}
