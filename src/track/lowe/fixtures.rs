//! Test fixtures of the `lowe` tracker: a hinged box, a camera, errors.

use super::projection::State;
use crate::geometry::{Camera, ModelGeometry, mean_point_distance};
use crate::io::formats::{Joint, Model};

/// A box 0.30 × 0.15 × 0.20 m with a lid plate hinged about x at the
/// back of its top.
pub fn hinged_box() -> ModelGeometry {
    ModelGeometry::new(&hinged_box_model()).unwrap()
}

/// The model of [`hinged_box`].
pub fn hinged_box_model() -> Model {
    let (w, h, d) = (0.3, 0.15, 0.2);
    let vertices = vec![
        [0.0, 0.0, 0.0],
        [w, 0.0, 0.0],
        [w, h, 0.0],
        [0.0, h, 0.0],
        [0.0, 0.0, d],
        [w, 0.0, d],
        [w, h, d],
        [0.0, h, d],
        [0.0, -0.01, 0.0],
        [w, -0.01, 0.0],
        [w, -0.01, d],
        [0.0, -0.01, d],
    ];
    let mut edges =
        vec![[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [1, 5], [2, 6], [3, 7]];
    edges.extend([[8, 9], [9, 10], [10, 11], [11, 8]]);
    Model {
        name: "hinged".into(),
        units: "m".into(),
        vertices,
        edges,
        faces: vec![],
        joints: vec![Joint {
            name: "lid".into(),
            origin: [0.0, -0.01, d],
            axis: [1.0, 0.0, 0.0],
            vertices: vec![8, 9, 10, 11],
            min: 0.0,
            max: 1.9,
        }],
    }
}

/// A 640×480 camera with a 600 px focal length.
pub fn camera() -> Camera {
    Camera { width: 640, height: 480, fx: 600.0, fy: 600.0, cx: 320.0, cy: 240.0 }
}

/// Mean image distance of the vertices of two states, px.
pub fn vertex_error(geometry: &ModelGeometry, cam: &Camera, a: &State, b: &State) -> f64 {
    let image = |s: &State| -> Vec<[f64; 2]> {
        geometry.camera_vertices(&s.pose, &s.params).unwrap().into_iter().map(|p| cam.project(p)).collect()
    };
    mean_point_distance(&image(a), &image(b))
}
