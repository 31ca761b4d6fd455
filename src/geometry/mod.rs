//! Camera and pose geometry shared by the 3-D trackers, the synthetic scenes
//! and the overlays, in the conventions of SPEC §4:
//!
//! - [`camera`]: the pinhole camera of `camera.json` (x right, y down, z
//!   forward; pixel (0, 0) is the centre of the top-left pixel):
//!   u = f_x·X/Z + c_x, v = f_y·Y/Z + c_y, its inverse at a known depth and
//!   its Jacobian.
//! - [`pose`]: rigid camera-from-object poses X_cam = R·X_obj + t on glam
//!   (f64), with R to and from axis-angle (Rodrigues) vectors.
//! - [`polygon`]: whether image corners trace a model's edges as a simple
//!   polygon, the similarity step that moves an outline on as a whole, and
//!   the mean distance between two sets of corners.
//! - [`model`]: the model's vertices under joint values (SPEC §4's joint
//!   rule), Newell face normals, back-face visibility and visible edges.
//! - [`hidden_lines`]: the parts of each edge the camera sees, once the
//!   parts behind the near plane and behind other faces are removed.
//!
//! Everything here is f64 and pure; nothing allocates per call except the
//! functions returning one value per vertex, face or edge (and hidden-line
//! removal's scratch buffers, once per call).

pub mod camera;
pub mod hidden_lines;
pub mod model;
pub mod polygon;
pub mod pose;

pub use camera::Camera;
pub use hidden_lines::{VisibleEdgeParts, VisibleSegment, visible_edge_parts, visible_edge_segments};
pub use model::{ModelGeometry, faces_camera, newell_normal};
pub use polygon::{check_polygon_in_image, check_simple_polygon, mean_point_distance, similarity_step};
pub use pose::{Pose, axis_angle_from_rotation, rotation_from_axis_angle};
