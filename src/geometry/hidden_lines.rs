//! Hidden-line removal for polyhedral models: which parts of each model edge
//! the camera sees, as parameter intervals along the 3-D edge.
//!
//! An edge k runs P(t) = A + t·(B − A), t ∈ [0, 1], from A = `edges[k][0]`
//! to B = `edges[k][1]` (camera frame). A point P(t) is **seen** when
//!
//! 1. the edge passes the back-face test ([`ModelGeometry::visible_edges`]:
//!    it borders a face that faces the camera, or no face at all);
//! 2. it lies beyond the near plane, Z > [`NEAR_PLANE_Z`];
//! 3. no **occluder** hides it: an occluder is a face that faces the camera
//!    ([`faces_camera`]) and that the edge does not border, taken beyond the
//!    near plane; it hides P when the ray from the centre of projection to P
//!    crosses the interior of the face's polygon strictly in front of P.
//!
//! Back faces never hide: on a closed surface whatever they would hide is
//! hidden by a facing face too.
//!
//! # Method
//!
//! Every occluder is clipped to Z ≥ [`NEAR_PLANE_Z`] in 3-D (Sutherland–
//! Hodgman) and projected, giving its image outline (any simple polygon,
//! non-convex allowed), and its plane n̂·X = d̂ is taken from its unit Newell
//! normal ([`newell_normal`]) through its vertices' centroid. For a facing
//! face d̂ < 0, so the ray to P crosses the plane at s·P with
//! s = d̂ / (n̂·P) ∈ (0, 1) exactly when n̂·P < d̂: "in front of P" is "P on the
//! inner side of the plane", a condition linear in t (one half-interval of
//! t, solved in 3-D). The ray crosses the clipped polygon exactly when P's
//! pixel is inside its image outline, since central projection maps the
//! plane's points beyond the camera one-to-one onto the image. So for each
//! edge (clipped to the near plane and projected, image parameter
//! λ ∈ [0, 1]) and each occluder whose image bounding box meets the edge's:
//!
//! - the half-interval of t behind the occluder's plane; none: next occluder;
//! - the λ where the image segment crosses the outline's sides, sorted; each
//!   piece between consecutive crossings is inside or outside as its middle
//!   point is (an even–odd test), which holds for non-convex outlines;
//! - the inside pieces go from λ to 3-D parameters exactly: for the clipped
//!   segment A′B′ (depths Z_A′, Z_B′) the image point at λ is the 3-D point
//!   at τ = λ·Z_A′ / ((1 − λ)·Z_B′ + λ·Z_A′) along A′B′ (perspective division
//!   is not linear in t), and are cut to the half-interval behind the plane.
//!
//! The union of the hidden pieces over all occluders is taken from the
//! edge's range in front of the near plane. The work is O(edges × faces):
//! the occluders are sorted by the left sides of their image bounding boxes,
//! so an edge reads only those starting left of its right end, and the
//! bounding-box and plane tests reject most pairs before the outline is
//! read; there is no allocation per pair (scratch buffers are reused).
//!
//! # Tolerances
//!
//! - [`ON_PLANE_TOLERANCE`]: a point nearer an occluder's plane than this
//!   times its depth Z is on the plane, not behind it: edges lying in an
//!   occluder's plane (coplanar neighbours, a closed lid resting on its box,
//!   seams drawn on a face) are not hidden by it when rounding puts them a
//!   hair behind it. An edge bordering the occluder is never tested
//!   against it.
//! - [`ON_OUTLINE_TOLERANCE`]: an image point nearer an occluder's outline
//!   than this (in normalised image units, pixels / focal length) is on the
//!   outline, not inside it: an edge whose image runs along an occluder's
//!   outline (the ray grazes the face's border) is not hidden by that face,
//!   and a face seen edge-on, whose outline has no inside, hides nothing.
//!   A part seen exactly along the border shared by two occluders is seen.
//! - [`MIN_PART_LENGTH`]: hidden and seen pieces shorter than this (in t)
//!   are dropped, so that the seen intervals are disjoint, sorted, at least
//!   this long and at least this far apart (touching ones merged). A
//!   millionth of the edge is far below a pixel for any edge in view, and
//!   far above the slivers the two tolerances above leave where an edge
//!   leaves an occluder's plane or outline at a vertex they share.

use glam::DVec3;

use super::camera::Camera;
use super::model::{ModelGeometry, faces_camera, newell_normal};

/// The near plane (camera-frame depth, metres): the parts of edges and faces
/// at Z ≤ this are neither seen nor hide anything.
pub const NEAR_PLANE_Z: f64 = 1e-3;

/// A point whose distance to an occluder's plane is below this times its
/// depth Z lies on the plane (module doc, tolerances): relative, far above
/// the rounding of camera-frame coordinates (about 1e-16 of their size).
pub const ON_PLANE_TOLERANCE: f64 = 1e-12;

/// An image point whose distance to an occluder's outline is below this, in
/// normalised image units (pixels divided by the larger focal length), lies
/// on the outline (module doc, tolerances).
pub const ON_OUTLINE_TOLERANCE: f64 = 1e-9;

/// Seen and hidden pieces of an edge shorter than this, in the edge
/// parameter t ∈ [0, 1], are dropped (module doc, tolerances).
pub const MIN_PART_LENGTH: f64 = 1e-6;

/// A crossing of the edge's image with an outline side counts when it falls
/// on the side's extent widened by this fraction at each end; a spurious
/// crossing only splits a piece in two, a missed one would merge an inside
/// piece with an outside one.
const SIDE_EXTENT_SLACK: f64 = 1e-9;

/// The seen parts of every edge of a model: per edge, the sorted, disjoint
/// parameter intervals `[t0, t1]` ⊆ [0, 1] along the 3-D edge (t = 0 at
/// `edges[k][0]`, 1 at `edges[k][1]`), by [`visible_edge_parts`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VisibleEdgeParts {
    /// The intervals of every edge, edge after edge.
    intervals: Vec<[f64; 2]>,
    /// Edge k's intervals are `intervals[starts[k]..starts[k + 1]]`.
    starts: Vec<usize>,
    /// Whether each face faces the camera (the back-face test's answer).
    facing: Vec<bool>,
}

impl VisibleEdgeParts {
    /// Whether each face of the model faces the camera.
    #[must_use]
    pub fn facing_faces(&self) -> &[bool] {
        &self.facing
    }

    /// Number of edges.
    #[must_use]
    pub fn edge_count(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// The seen intervals of edge `edge`, sorted and disjoint; empty for an
    /// edge not seen at all. Panics when `edge` is not an edge's index.
    #[must_use]
    pub fn edge(&self, edge: usize) -> &[[f64; 2]] {
        &self.intervals[self.starts[edge]..self.starts[edge + 1]]
    }

    /// The seen intervals of every edge, in edge order.
    pub fn iter(&self) -> impl Iterator<Item = &[[f64; 2]]> {
        self.starts.windows(2).map(|w| &self.intervals[w[0]..w[1]])
    }

    /// The seen fraction of edge `edge`'s length, Σ (t1 − t0).
    #[must_use]
    pub fn seen_fraction(&self, edge: usize) -> f64 {
        self.edge(edge).iter().map(|[t0, t1]| t1 - t0).sum()
    }

    /// One [`VisibleSegment`] per seen interval, edge after edge: its ends
    /// in 3-D (camera frame) projected by `camera`. `geometry`,
    /// `camera_vertices` and `camera` are those the parts were found for.
    #[must_use]
    pub fn segments(
        &self,
        geometry: &ModelGeometry,
        camera_vertices: &[DVec3],
        camera: &Camera,
    ) -> Vec<VisibleSegment> {
        let mut segments = Vec::with_capacity(self.intervals.len());
        for (edge, (parts, &[i, j])) in self.iter().zip(geometry.edges()).enumerate() {
            let (a, b) = (camera_vertices[i], camera_vertices[j]);
            for &t in parts {
                let image = t.map(|t| camera.project(a + t * (b - a)));
                segments.push(VisibleSegment { edge, t, image });
            }
        }
        segments
    }
}

/// A seen piece of a model edge: what a tracker matches to image segments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisibleSegment {
    /// The model edge (index into [`ModelGeometry::edges`]).
    pub edge: usize,
    /// The piece's parameter interval `[t0, t1]` along the 3-D edge.
    pub t: [f64; 2],
    /// The piece's ends in the image, `[[u0, v0], [u1, v1]]` (pixels), at
    /// t0 and t1.
    pub image: [[f64; 2]; 2],
}

/// A face that may hide parts of edges: it faces the camera.
#[derive(Clone, Debug)]
struct Occluder {
    /// Index of the face.
    face: usize,
    /// Unit outward normal n̂ (camera frame).
    normal: DVec3,
    /// Plane offset d̂ = n̂·X for X on the face (negative: it faces the camera).
    offset: f64,
    /// The image outline (clipped to the near plane) in [`Occluders::outlines`].
    outline: std::ops::Range<usize>,
}

/// Every occluder of a view, sorted by the left side of its image bounding
/// box, so that an edge reads only those starting left of its right end.
#[derive(Clone, Debug)]
struct Occluders {
    /// Image bounding boxes `[u_min, v_min, u_max, v_max]`, by `u_min`.
    boxes: Vec<[f64; 4]>,
    /// The occluder of each box.
    planes: Vec<Occluder>,
    /// The outlines, one after the other.
    outlines: Vec<[f64; 2]>,
}

/// The seen parts of every edge of `geometry` (module doc) with the model's
/// vertices at `camera_vertices` (camera frame, one per model vertex, e.g.
/// from [`ModelGeometry::camera_vertices`]), projected by `camera`.
/// Panics when `camera_vertices` is shorter than the model's vertices.
#[must_use]
pub fn visible_edge_parts(geometry: &ModelGeometry, camera_vertices: &[DVec3], camera: &Camera) -> VisibleEdgeParts {
    let facing = geometry.facing_faces(camera_vertices);
    let visible = geometry.visible_edges(&facing);
    let occluders = Occluders::new(geometry, camera_vertices, camera, &facing);
    let outline_tolerance = ON_OUTLINE_TOLERANCE * camera.fx.abs().max(camera.fy.abs());

    let edges = geometry.edges();
    let mut parts = VisibleEdgeParts {
        intervals: Vec::with_capacity(edges.len()),
        starts: Vec::with_capacity(edges.len() + 1),
        facing: Vec::new(),
    };
    parts.starts.push(0);
    let mut hidden = Vec::new();
    let mut crossings = Vec::new();
    for (k, &[i, j]) in edges.iter().enumerate() {
        let (a, b) = (camera_vertices[i], camera_vertices[j]);
        if let (true, Some(range)) = (visible[k], in_front_of_near_plane(a.z, b.z)) {
            let edge = ClippedEdge::new(a, b, range, camera);
            hidden.clear();
            let left_of_edge_end = occluders.boxes.partition_point(|b| b[0] <= edge.max[0]);
            for (image_box, occluder) in occluders.boxes.iter().zip(&occluders.planes).take(left_of_edge_end) {
                if !edge.image_box_meets(image_box) || geometry.edge_faces()[k].contains(&occluder.face) {
                    continue;
                }
                let Some(behind) = behind_plane(a, b, occluder, range) else { continue };
                let outline = &occluders.outlines[occluder.outline.clone()];
                edge.hidden_by_outline(outline, behind, outline_tolerance, &mut crossings, &mut hidden);
            }
            subtract_hidden(range, &mut hidden, &mut parts.intervals);
        }
        parts.starts.push(parts.intervals.len());
    }
    parts.facing = facing;
    parts
}

/// [`visible_edge_parts`] as image segments, one per seen interval
/// ([`VisibleEdgeParts::segments`]).
#[must_use]
pub fn visible_edge_segments(
    geometry: &ModelGeometry,
    camera_vertices: &[DVec3],
    camera: &Camera,
) -> Vec<VisibleSegment> {
    visible_edge_parts(geometry, camera_vertices, camera).segments(geometry, camera_vertices, camera)
}

impl Occluders {
    /// Every facing face (`facing`, one per face) with a non-degenerate
    /// normal, clipped to the near plane and projected.
    fn new(geometry: &ModelGeometry, camera_vertices: &[DVec3], camera: &Camera, facing: &[bool]) -> Self {
        let mut found = Vec::new();
        let mut outlines = Vec::new();
        let mut clipped = Vec::new();
        for (f, face) in geometry.faces().iter().enumerate() {
            if !facing[f] {
                continue;
            }
            let normal = newell_normal(camera_vertices, face);
            let length = normal.length();
            if !(length > 0.0 && length.is_finite()) {
                continue;
            }
            let normal = normal / length;
            let centroid = face.iter().map(|&v| camera_vertices[v]).sum::<DVec3>() / face.len() as f64;
            let offset = normal.dot(centroid);
            // The back-face test at the centroid (a non-planar loop can pass it
            // at its first vertex only): d̂ < 0 is n̂·centroid < 0.
            if !faces_camera(normal, centroid) {
                continue;
            }
            clip_to_near_plane(face.iter().map(|&v| camera_vertices[v]), &mut clipped);
            if clipped.len() < 3 {
                continue;
            }
            let start = outlines.len();
            let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for &p in &clipped {
                let pixel = camera.project(p);
                for c in 0..2 {
                    min[c] = min[c].min(pixel[c]);
                    max[c] = max[c].max(pixel[c]);
                }
                outlines.push(pixel);
            }
            if !(min.iter().chain(&max).all(|x| x.is_finite())) {
                outlines.truncate(start);
                continue;
            }
            let outline = start..outlines.len();
            found.push(([min[0], min[1], max[0], max[1]], Occluder { face: f, normal, offset, outline }));
        }
        found.sort_unstable_by(|x, y| x.0[0].total_cmp(&y.0[0]));
        let (boxes, planes) = found.into_iter().unzip();
        Self { boxes, planes, outlines }
    }
}

/// The part of the polygon `loop_points` at Z ≥ [`NEAR_PLANE_Z`], into
/// `clipped` (Sutherland–Hodgman against one plane).
fn clip_to_near_plane(loop_points: impl Iterator<Item = DVec3> + Clone, clipped: &mut Vec<DVec3>) {
    clipped.clear();
    let next = loop_points.clone().cycle().skip(1);
    for (p, q) in loop_points.zip(next) {
        let (p_in, q_in) = (p.z >= NEAR_PLANE_Z, q.z >= NEAR_PLANE_Z);
        if p_in {
            clipped.push(p);
        }
        if p_in != q_in {
            let s = (NEAR_PLANE_Z - p.z) / (q.z - p.z);
            let mut crossing = p + s * (q - p);
            crossing.z = NEAR_PLANE_Z;
            clipped.push(crossing);
        }
    }
}

/// The range of t ∈ [0, 1] where Z(t) = z_a + t·(z_b − z_a) ≥
/// [`NEAR_PLANE_Z`], if at least [`MIN_PART_LENGTH`] long.
fn in_front_of_near_plane(z_a: f64, z_b: f64) -> Option<[f64; 2]> {
    let range = match (z_a >= NEAR_PLANE_Z, z_b >= NEAR_PLANE_Z) {
        (true, true) => [0.0, 1.0],
        (false, false) => return None,
        (a_in, _) => {
            let t = ((NEAR_PLANE_Z - z_a) / (z_b - z_a)).clamp(0.0, 1.0);
            if a_in { [0.0, t] } else { [t, 1.0] }
        }
    };
    (range[1] - range[0] >= MIN_PART_LENGTH).then_some(range)
}

/// The part of `range` (in t) where the edge P(t) = a + t·(b − a) lies
/// strictly behind the occluder's plane, n̂·P − d̂ < −[`ON_PLANE_TOLERANCE`]·Z:
/// h(t) = n̂·P − d̂ + tolerance·Z is linear in t, so this is where a linear
/// function is negative.
fn behind_plane(a: DVec3, b: DVec3, occluder: &Occluder, range: [f64; 2]) -> Option<[f64; 2]> {
    let h = |p: DVec3| occluder.normal.dot(p) - occluder.offset + ON_PLANE_TOLERANCE * p.z;
    let (h_a, h_b) = (h(a), h(b));
    let [lo, hi] = range;
    let behind = match (h_a < 0.0, h_b < 0.0) {
        (true, true) => [lo, hi],
        (false, false) => return None,
        (a_behind, _) => {
            let root = h_a / (h_a - h_b);
            if a_behind { [lo, hi.min(root)] } else { [lo.max(root), hi] }
        }
    };
    (behind[1] > behind[0]).then_some(behind)
}

/// An edge clipped to the near plane, with its image segment.
struct ClippedEdge {
    /// The edge's parameter range in front of the near plane.
    range: [f64; 2],
    /// Depths of the clipped ends, Z_A′ and Z_B′ (≥ the near plane).
    depths: [f64; 2],
    /// Image of the clipped ends: λ = 0 at `image[0]`, 1 at `image[1]`.
    image: [[f64; 2]; 2],
    /// Image bounding box, min corner.
    min: [f64; 2],
    /// Image bounding box, max corner.
    max: [f64; 2],
}

impl ClippedEdge {
    fn new(a: DVec3, b: DVec3, range: [f64; 2], camera: &Camera) -> Self {
        let ends = range.map(|t| a + t * (b - a));
        let image = ends.map(|p| camera.project(p));
        let min = [image[0][0].min(image[1][0]), image[0][1].min(image[1][1])];
        let max = [image[0][0].max(image[1][0]), image[0][1].max(image[1][1])];
        Self { range, depths: ends.map(|p| p.z), image, min, max }
    }

    /// Whether the edge's image bounding box meets `image_box`,
    /// `[u_min, v_min, u_max, v_max]`.
    fn image_box_meets(&self, image_box: &[f64; 4]) -> bool {
        (0..2).all(|c| self.max[c] >= image_box[c] && self.min[c] <= image_box[c + 2])
    }

    /// The edge parameter t of the image point at `lambda` along the image
    /// segment: τ = λ·Z_A′ / ((1 − λ)·Z_B′ + λ·Z_A′) along the clipped 3-D
    /// segment (module doc), then t = t_lo + τ·(t_hi − t_lo).
    fn edge_parameter(&self, lambda: f64) -> f64 {
        let [z_a, z_b] = self.depths;
        let tau = lambda * z_a / ((1.0 - lambda) * z_b + lambda * z_a);
        let [lo, hi] = self.range;
        (lo + tau * (hi - lo)).clamp(lo, hi)
    }

    /// The image point at `lambda`.
    fn image_point(&self, lambda: f64) -> [f64; 2] {
        let [p, q] = self.image;
        [p[0] + lambda * (q[0] - p[0]), p[1] + lambda * (q[1] - p[1])]
    }

    /// Appends to `hidden` the pieces of the edge, within `behind` (in t),
    /// whose image lies strictly inside `outline`. `crossings` is scratch.
    fn hidden_by_outline(
        &self,
        outline: &[[f64; 2]],
        behind: [f64; 2],
        tolerance: f64,
        crossings: &mut Vec<f64>,
        hidden: &mut Vec<[f64; 2]>,
    ) {
        crossings.clear();
        crossings.extend([0.0, 1.0]);
        let [a, b] = self.image;
        let d = sub(b, a);
        let d_len2 = dot(d, d);
        for (s, &p) in outline.iter().enumerate() {
            let q = outline[(s + 1) % outline.len()];
            let e = sub(q, p);
            let ap = sub(p, a);
            let den = cross(d, e);
            if den != 0.0 {
                let lambda = cross(ap, e) / den;
                let mu = cross(ap, d) / den;
                if lambda > 0.0 && lambda < 1.0 && (-SIDE_EXTENT_SLACK..=1.0 + SIDE_EXTENT_SLACK).contains(&mu) {
                    crossings.push(lambda);
                }
            }
            // An outline corner on (or within the tolerance of) the segment's
            // line bounds a piece that runs along an outline side.
            if d_len2 > 0.0 && cross(d, ap).abs() <= tolerance * d_len2.sqrt() {
                let lambda = dot(ap, d) / d_len2;
                if lambda > 0.0 && lambda < 1.0 {
                    crossings.push(lambda);
                }
            }
        }
        crossings.sort_unstable_by(f64::total_cmp);
        for w in crossings.windows(2) {
            if !(w[1] > w[0]) || !strictly_inside(self.image_point(0.5 * (w[0] + w[1])), outline, tolerance) {
                continue;
            }
            let (t0, t1) = (self.edge_parameter(w[0]).max(behind[0]), self.edge_parameter(w[1]).min(behind[1]));
            if t1 > t0 {
                hidden.push([t0, t1]);
            }
        }
    }
}

/// Whether `point` is inside the polygon `outline` (even–odd rule, any
/// simple polygon) by more than `tolerance` from its sides.
fn strictly_inside(point: [f64; 2], outline: &[[f64; 2]], tolerance: f64) -> bool {
    let mut inside = false;
    for (s, &p) in outline.iter().enumerate() {
        let q = outline[(s + 1) % outline.len()];
        if squared_distance_to_side(point, p, q) <= tolerance * tolerance {
            return false;
        }
        if (p[1] > point[1]) != (q[1] > point[1]) {
            let x = p[0] + (point[1] - p[1]) * (q[0] - p[0]) / (q[1] - p[1]);
            if point[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// Squared distance from `point` to the segment `p`–`q`.
fn squared_distance_to_side(point: [f64; 2], p: [f64; 2], q: [f64; 2]) -> f64 {
    let (e, w) = (sub(q, p), sub(point, p));
    let len2 = dot(e, e);
    let s = if len2 > 0.0 { (dot(w, e) / len2).clamp(0.0, 1.0) } else { 0.0 };
    let r = [w[0] - s * e[0], w[1] - s * e[1]];
    dot(r, r)
}

/// Appends to `seen` what is left of `range` once the pieces in `hidden`
/// are taken out: hidden pieces are merged where they overlap or are less
/// than [`MIN_PART_LENGTH`] apart, merged pieces shorter than that are
/// dropped, and so are seen pieces shorter than that. Sorts `hidden`.
fn subtract_hidden(range: [f64; 2], hidden: &mut [[f64; 2]], seen: &mut Vec<[f64; 2]>) {
    hidden.sort_unstable_by(|x, y| x[0].total_cmp(&y[0]));
    let mut cursor = range[0];
    let mut k = 0;
    while k < hidden.len() {
        let [start, mut end] = hidden[k];
        k += 1;
        while k < hidden.len() && hidden[k][0] - end < MIN_PART_LENGTH {
            end = end.max(hidden[k][1]);
            k += 1;
        }
        if end - start < MIN_PART_LENGTH {
            continue;
        }
        if start - cursor >= MIN_PART_LENGTH {
            seen.push([cursor, start]);
        }
        cursor = cursor.max(end);
    }
    if range[1] - cursor >= MIN_PART_LENGTH {
        seen.push([cursor, range[1]]);
    }
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use glam::DMat3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::geometry::pose::Pose;
    use crate::io::formats::{Joint, Model};

    fn camera() -> Camera {
        Camera { width: 640, height: 480, fx: 500.0, fy: 480.0, cx: 319.5, cy: 239.5 }
    }

    fn model(vertices: Vec<[f64; 3]>, edges: Vec<[usize; 2]>, faces: Vec<Vec<usize>>) -> Model {
        Model { name: "test".into(), units: "m".into(), vertices, edges, faces, joints: Vec::new() }
    }

    /// The polygon `outline` (counter-clockwise seen from +z) extruded from
    /// z0 to z1. Vertices: the bottom ring, then the top ring; edges: the
    /// bottom ring's, the top ring's, then the vertical ones (edge k of a
    /// ring runs from its vertex k to k + 1); faces: bottom, top, then the
    /// sides, counter-clockwise seen from outside.
    fn prism(outline: &[[f64; 2]], z0: f64, z1: f64) -> Model {
        let n = outline.len();
        let vertices = [z0, z1].iter().flat_map(|&z| outline.iter().map(move |&[x, y]| [x, y, z])).collect();
        let mut edges: Vec<[usize; 2]> = (0..n).map(|i| [i, (i + 1) % n]).collect();
        edges.extend((0..n).map(|i| [n + i, n + (i + 1) % n]));
        edges.extend((0..n).map(|i| [i, n + i]));
        let mut faces = vec![(0..n).rev().collect(), (n..2 * n).collect()];
        faces.extend((0..n).map(|i| vec![i, (i + 1) % n, n + (i + 1) % n, n + i]));
        model(vertices, edges, faces)
    }

    /// `a` and `b` as one model (b's indices after a's).
    fn union(mut a: Model, b: Model) -> Model {
        let offset = a.vertices.len();
        a.vertices.extend(b.vertices);
        a.edges.extend(b.edges.iter().map(|e| e.map(|i| i + offset)));
        a.faces.extend(b.faces.iter().map(|f| f.iter().map(|i| i + offset).collect()));
        a
    }

    /// A 2 × 2 × 1 box with a 0.6 × 0.6 × 1.5 tower standing on its top,
    /// near its front (−y) side. Box edge 6 is its top back edge, from
    /// (2, 2, 1) to (0, 2, 1).
    fn box_with_tower() -> Model {
        let box_ = prism(&[[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]], 0.0, 1.0);
        let tower = prism(&[[0.7, 0.1], [1.3, 0.1], [1.3, 0.7], [0.7, 0.7]], 1.0, 2.5);
        union(box_, tower)
    }

    /// The unit cube (a prism: top ring 4 (0, 0, 1), 5 (1, 0, 1),
    /// 6 (1, 1, 1), 7 (0, 1, 1)) with a lid of zero thickness (a face on
    /// each side) hinged on its top back edge 6–7: free corners 8 (0, 0, 1)
    /// and 9 (1, 0, 1) at q = 0, where the lid lies on the top; q < 0 opens
    /// it. Box edges 5 (5→6) and 7 (7→4) are the top's sides.
    fn box_with_lid() -> Model {
        let mut m = prism(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], 0.0, 1.0);
        m.vertices.extend([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]]);
        m.edges.extend([[8, 9], [9, 6], [7, 8]]);
        m.faces.extend([vec![8, 9, 6, 7], vec![7, 6, 9, 8]]);
        m.joints.push(Joint {
            name: "lid".into(),
            origin: [0.0, 1.0, 1.0],
            axis: [1.0, 0.0, 0.0],
            vertices: vec![8, 9],
            min: -PI,
            max: 0.0,
        });
        m
    }

    /// An L-shaped prism: non-convex top and bottom faces.
    fn l_prism() -> Model {
        prism(&[[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]], 0.0, 0.7)
    }

    /// The camera-from-object pose of a camera at `eye` looking at
    /// `target`, turned by `roll` about its optical axis.
    fn look_at(eye: DVec3, target: DVec3, roll: f64) -> Pose {
        let forward = (target - eye).normalize();
        let up = if forward.z.abs() < 0.99 { DVec3::Z } else { DVec3::X };
        let right = forward.cross(up).normalize();
        let down = forward.cross(right);
        let right = roll.cos() * right + roll.sin() * down;
        let down = forward.cross(right);
        let rotation = DMat3::from_cols(right, down, forward).transpose();
        Pose::new(rotation, -(rotation * eye))
    }

    /// A camera at a random distance (from inside the model to six times
    /// its size) and direction, looking near the model's centre.
    fn random_view(rng: &mut ChaCha8Rng, geometry: &ModelGeometry) -> Pose {
        let centre = geometry.centroid();
        let size = geometry.vertices().iter().map(|v| (*v - centre).length()).fold(0.0, f64::max);
        let direction = loop {
            let d = DVec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            if (0.1..1.0).contains(&d.length()) {
                break d.normalize();
            }
        };
        let jitter = DVec3::new(rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3));
        let target = centre + size * jitter;
        look_at(target + direction * size * rng.random_range(0.3..6.0), target, rng.random_range(-PI..PI))
    }

    /// Whether `x`, a point of the plane of face `face` (normal `normal`),
    /// lies inside the face's polygon and off its border (by 1e-9·|x|): the
    /// even–odd rule in the coordinate plane across which the normal is
    /// largest.
    fn point_in_face(x: DVec3, vertices: &[DVec3], face: &[usize], normal: DVec3) -> bool {
        let a = normal.abs();
        let drop = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let (i, j) = ((drop + 1) % 3, (drop + 2) % 3);
        let mut inside = false;
        for (k, &v) in face.iter().enumerate() {
            let (p, q) = (vertices[v], vertices[face[(k + 1) % face.len()]]);
            let s = ((x - p).dot(q - p) / (q - p).length_squared()).clamp(0.0, 1.0);
            if (x - (p + s * (q - p))).length() <= 1e-9 * x.length() {
                return false;
            }
            if (p[j] > x[j]) != (q[j] > x[j]) && x[i] < p[i] + (x[j] - p[j]) * (q[i] - p[i]) / (q[j] - p[j]) {
                inside = !inside;
            }
        }
        inside
    }

    /// The brute-force reference: whether the point at `t` on edge `k` is
    /// seen, by casting the ray from the centre of projection to it against
    /// every facing face in 3-D.
    fn seen_by_ray_casting(geometry: &ModelGeometry, cam: &[DVec3], facing: &[bool], k: usize, t: f64) -> bool {
        let [i, j] = geometry.edges()[k];
        let p = cam[i] + t * (cam[j] - cam[i]);
        if !geometry.visible_edges(facing)[k] || p.z <= NEAR_PLANE_Z {
            return false;
        }
        for (f, face) in geometry.faces().iter().enumerate() {
            if !facing[f] || geometry.edge_faces()[k].contains(&f) {
                continue;
            }
            let normal = newell_normal(cam, face);
            let on_plane = face.iter().map(|&v| cam[v]).sum::<DVec3>() / face.len() as f64;
            // The ray s·P meets the plane n·X = n·C at s = n·C / n·P.
            let s = normal.dot(on_plane) / normal.dot(p);
            let crossing = s * p;
            if s > 0.0 && s < 1.0 - 1e-9 && crossing.z >= NEAR_PLANE_Z && point_in_face(crossing, cam, face, normal) {
                return false;
            }
        }
        true
    }

    /// Checks that every edge's intervals are sorted, disjoint, within
    /// [0, 1] and at least the minimum length long and apart.
    fn assert_well_formed(parts: &VisibleEdgeParts) {
        for (k, intervals) in parts.iter().enumerate() {
            for [t0, t1] in intervals {
                assert!(0.0 <= *t0 && *t1 <= 1.0 && t1 - t0 >= MIN_PART_LENGTH, "edge {k}: {intervals:?}");
            }
            for w in intervals.windows(2) {
                assert!(w[1][0] - w[0][1] >= MIN_PART_LENGTH, "edge {k}: {intervals:?}");
            }
        }
    }

    /// Checks `parts` against [`seen_by_ray_casting`] at `samples` points
    /// per edge: a sample may disagree only within one sampling step of an
    /// interval's end. Returns the number of edges partly seen.
    fn assert_matches_ray_casting(
        label: &str,
        geometry: &ModelGeometry,
        cam: &[DVec3],
        parts: &VisibleEdgeParts,
        samples: usize,
    ) -> usize {
        assert_well_formed(parts);
        assert_eq!(parts.edge_count(), geometry.edges().len());
        let facing = geometry.facing_faces(cam);
        let step = 1.0 / samples as f64;
        let mut partly_seen = 0;
        for (k, intervals) in parts.iter().enumerate() {
            for s in 0..samples {
                let t = (s as f64 + 0.5) * step;
                let seen = intervals.iter().any(|&[t0, t1]| t0 <= t && t <= t1);
                if seen != seen_by_ray_casting(geometry, cam, &facing, k, t) {
                    let near_an_end = intervals.iter().flatten().any(|&end| (end - t).abs() <= step);
                    assert!(
                        near_an_end,
                        "{label}: edge {k} at t = {t}: computed {seen}, ray casting {}; {intervals:?}",
                        !seen
                    );
                }
            }
            let fraction = parts.seen_fraction(k);
            if fraction > 1e-3 && fraction < 1.0 - 1e-3 {
                partly_seen += 1;
            }
        }
        partly_seen
    }

    /// The parts the back-face test alone leaves: every visible edge whole.
    fn back_face_parts(geometry: &ModelGeometry, cam: &[DVec3]) -> Vec<Vec<[f64; 2]>> {
        let visible = geometry.visible_edges(&geometry.facing_faces(cam));
        visible.iter().map(|&v| if v { vec![[0.0, 1.0]] } else { Vec::new() }).collect()
    }

    fn as_vecs(parts: &VisibleEdgeParts) -> Vec<Vec<[f64; 2]>> {
        parts.iter().map(<[_]>::to_vec).collect()
    }

    fn assert_intervals_near(got: &[[f64; 2]], expected: &[[f64; 2]], tolerance: f64) {
        assert_eq!(got.len(), expected.len(), "{got:?} vs {expected:?}");
        for (g, e) in got.iter().zip(expected) {
            assert!((g[0] - e[0]).abs() <= tolerance && (g[1] - e[1]).abs() <= tolerance, "{got:?} vs {expected:?}");
        }
    }

    /// From (1, −4, 2) the ray to a point (x, 2, 1) of the box's top back
    /// edge meets the tower's front face y = 0.1 at s = 4.1/6 of the way,
    /// at x' = 1 + s·(x − 1) and z = 2 − s ∈ [1, 2.5]: hidden for
    /// |x − 1| ≤ 0.3/s = 18/41, so with x = 2 − 2t seen for t ≤ 23/82 and
    /// t ≥ 59/82.
    #[test]
    fn a_tower_in_front_hides_the_middle_of_the_back_top_edge() {
        let geometry = ModelGeometry::new(&box_with_tower()).expect("box with tower");
        let pose = look_at(DVec3::new(1.0, -4.0, 2.0), DVec3::new(1.0, 1.0, 0.8), 0.3);
        let cam = geometry.camera_vertices(&pose, &[]).expect("pose");
        let parts = visible_edge_parts(&geometry, &cam, &camera());
        assert_intervals_near(parts.edge(6), &[[0.0, 23.0 / 82.0], [59.0 / 82.0, 1.0]], 1e-12);
        // The box's front top edge and the tower's front vertical edges are whole.
        assert_eq!(parts.edge(4), [[0.0, 1.0]]);
        assert_eq!(parts.edge(8 + 8), [[0.0, 1.0]]);
        assert!(assert_matches_ray_casting("tower", &geometry, &cam, &parts, 2000) >= 1);

        let segments = parts.segments(&geometry, &cam, &camera());
        assert_eq!(segments.len(), parts.iter().map(<[_]>::len).sum::<usize>());
        let back: Vec<_> = segments.iter().filter(|s| s.edge == 6).collect();
        assert_eq!(back.len(), 2);
        for segment in back {
            let [i, j] = geometry.edges()[6];
            for (end, t) in segment.image.iter().zip(segment.t) {
                let expected = camera().project(cam[i] + t * (cam[j] - cam[i]));
                assert!((end[0] - expected[0]).abs() < 1e-9 && (end[1] - expected[1]).abs() < 1e-9);
            }
        }
        assert_eq!(visible_edge_segments(&geometry, &cam, &camera()), segments);
    }

    /// The lid opened by 0.6 rad (free edge at y = 1 − cos 0.6,
    /// z = 1 + sin 0.6) seen from the front and above its plane hides the
    /// back of the box top's side edges: a point (x, y, 1) is hidden when
    /// the ray from the eye passes beyond the lid's free edge, which in the
    /// y–z plane (the eye at x = 0.5, the lid spanning x ∈ [0, 1]) is
    /// y > y_e + (y_f − y_e)·(z_e − 1)/(z_e − z_f).
    #[test]
    fn an_open_lid_hides_the_back_of_the_box_top() {
        let geometry = ModelGeometry::new(&box_with_lid()).expect("box with lid");
        let q: f64 = -0.6;
        let eye = DVec3::new(0.5, -1.5, 4.5);
        let pose = look_at(eye, DVec3::new(0.5, 0.5, 0.8), 0.0);
        let cam = geometry.camera_vertices(&pose, &[q]).expect("pose");
        let parts = visible_edge_parts(&geometry, &cam, &camera());
        let (y_f, z_f) = (1.0 - q.cos(), 1.0 - q.sin());
        let y_hidden = eye.y + (y_f - eye.y) * (eye.z - 1.0) / (eye.z - z_f);
        assert!(y_hidden > 0.3 && y_hidden < 0.7, "{y_hidden}");
        // Edge 5 runs from (1, 0, 1) to (1, 1, 1), edge 7 from (0, 1, 1) to (0, 0, 1).
        assert_intervals_near(parts.edge(5), &[[0.0, y_hidden]], 1e-12);
        assert_intervals_near(parts.edge(7), &[[1.0 - y_hidden, 1.0]], 1e-12);
        assert!(assert_matches_ray_casting("open lid", &geometry, &cam, &parts, 2000) >= 2);
    }

    /// A closed lid lies in the plane of the box's top, coincident with it:
    /// neither hides the other's edges.
    #[test]
    fn a_closed_lid_on_its_box_hides_nothing() {
        let geometry = ModelGeometry::new(&box_with_lid()).expect("box with lid");
        for eye in [DVec3::new(0.5, -1.5, 4.5), DVec3::new(-2.0, -1.0, 3.0), DVec3::new(3.0, 2.5, 1.5)] {
            let pose = look_at(eye, DVec3::new(0.5, 0.5, 0.5), 0.2);
            let cam = geometry.camera_vertices(&pose, &[0.0]).expect("pose");
            let parts = visible_edge_parts(&geometry, &cam, &camera());
            assert_eq!(as_vecs(&parts), back_face_parts(&geometry, &cam), "eye {eye}");
            assert_matches_ray_casting("closed lid", &geometry, &cam, &parts, 500);
        }
    }

    /// On a convex solid seen from outside, the back-face test is the whole
    /// answer: hidden-line removal keeps every visible edge whole.
    #[test]
    fn a_convex_box_loses_nothing_beyond_the_back_face_test() {
        let geometry =
            ModelGeometry::new(&prism(&[[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [0.0, 2.0]], 0.0, 0.5)).expect("box");
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for trial in 0..200 {
            let direction =
                DVec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            if direction.length() < 0.1 {
                continue;
            }
            let target = geometry.centroid();
            let eye = target + direction.normalize() * rng.random_range(3.0..20.0);
            let cam = geometry.camera_vertices(&look_at(eye, target, rng.random_range(-PI..PI)), &[]).expect("pose");
            let parts = visible_edge_parts(&geometry, &cam, &camera());
            assert_eq!(as_vecs(&parts), back_face_parts(&geometry, &cam), "trial {trial}");
        }
    }

    /// An edge crossing the near plane keeps its part in front: from
    /// Z = −1 to 3, Z(t) = −1 + 4t ≥ NEAR from t = (1 + NEAR)/4. An edge
    /// wholly behind the camera is not seen.
    #[test]
    fn an_edge_crossing_the_near_plane_keeps_its_front_part() {
        let m = model(
            vec![[0.0, 0.0, -1.0], [0.5, 0.2, 3.0], [0.0, 0.0, -2.0], [1.0, 0.0, -0.5]],
            vec![[0, 1], [2, 3]],
            vec![],
        );
        let geometry = ModelGeometry::new(&m).expect("wires");
        let parts = visible_edge_parts(&geometry, geometry.vertices(), &camera());
        assert_intervals_near(parts.edge(0), &[[(1.0 + NEAR_PLANE_Z) / 4.0, 1.0]], 1e-15);
        assert_eq!(parts.edge(1), &[] as &[[f64; 2]]);
        let segments = parts.segments(&geometry, geometry.vertices(), &camera());
        assert_eq!(segments.len(), 1);
        assert!(segments[0].image.iter().flatten().all(|x| x.is_finite()));
    }

    /// A plate crossing the near plane hides only with its part in front of
    /// it: the ray casting agrees with the clipped outline.
    #[test]
    fn a_face_crossing_the_near_plane_hides_what_its_front_part_covers() {
        let mut vertices = vec![[-2.0, 1.0, -1.0], [2.0, 1.0, -1.0], [2.0, -1.0, 3.0], [-2.0, -1.0, 3.0]];
        vertices.extend([[-3.0, -3.0, 5.0], [3.0, 3.0, 5.0], [0.0, -4.0, 5.0], [0.0, 4.0, 5.0]]);
        vertices.extend([[-1.0, 2.0, 0.5], [1.0, -2.0, 6.0], [0.2, 0.05, 0.01], [0.3, 0.4, 2.0]]);
        let edges = vec![[4, 5], [6, 7], [8, 9], [10, 11]];
        // The plate y = 0.5 − 0.5·z, counter-clockwise seen from the camera.
        for face in [vec![0, 1, 2, 3], vec![3, 2, 1, 0]] {
            let geometry = ModelGeometry::new(&model(vertices.clone(), edges.clone(), vec![face])).expect("plate");
            let cam = geometry.vertices();
            let facing = geometry.facing_faces(cam)[0];
            let parts = visible_edge_parts(&geometry, cam, &camera());
            let partly_seen = assert_matches_ray_casting("near plate", &geometry, cam, &parts, 4000);
            if facing {
                assert!(partly_seen >= 3, "{:?}", as_vecs(&parts));
            } else {
                assert!(parts.iter().all(|p| p == [[0.0, 1.0]]), "a back face hides nothing");
            }
        }
    }

    /// An L-shaped face at Z = 2 (x ∈ [0, 2], y ∈ [0, 1] and x ∈ [0, 1],
    /// y ∈ [1, 2]) facing the camera, and edges behind, in front and through
    /// it, their hidden parts worked out by hand in normalised image
    /// coordinates (x/Z, y/Z): the L covers x/Z ∈ [0, 1] for y/Z < 0.5 and
    /// x/Z ∈ [0, 0.5] for y/Z ∈ (0.5, 1].
    #[test]
    fn an_l_shaped_face_hides_through_its_notch() {
        let mut vertices =
            vec![[0.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 1.0, 2.0], [1.0, 1.0, 2.0], [1.0, 2.0, 2.0], [0.0, 2.0, 2.0]];
        let mut edges: Vec<[usize; 2]> = (0..6).map(|i| [i, (i + 1) % 6]).collect();
        let wires = [
            // Across the notch's row y/Z = 0.75 from x/Z = −0.5 (Z = 3) to 1.5
            // (Z = 6): x/Z = (−1.5 + 10.5t)/(3 + 3t) is 0 at t = 1/7 and 0.5 at
            // t = 1/3.
            ([-1.5, 2.25, 3.0], [9.0, 4.5, 6.0], vec![[0.0, 1.0 / 7.0], [1.0 / 3.0, 1.0]]),
            // Down the column x/Z = 0.75 at Z = 4, y/Z from −0.5 to 1.5: the L
            // covers y/Z ∈ [0, 0.5] there (the notch above).
            ([3.0, -2.0, 4.0], [3.0, 6.0, 4.0], vec![[0.0, 0.25], [0.5, 1.0]]),
            // The first one in front of the L (Z from 0.75 to 1.5).
            ([-0.375, 0.5625, 0.75], [2.25, 1.125, 1.5], vec![[0.0, 1.0]]),
            // Through the L: image inside it all along, Z = 1 + 3t passes
            // Z = 2 at t = 1/3.
            ([0.5, 0.25, 1.0], [3.6, 1.0, 4.0], vec![[0.0, 1.0 / 3.0]]),
        ];
        for (a, b, _) in &wires {
            edges.push([vertices.len(), vertices.len() + 1]);
            vertices.extend([*a, *b]);
        }
        let face = vec![5, 4, 3, 2, 1, 0];
        let geometry = ModelGeometry::new(&model(vertices, edges, vec![face])).expect("L");
        let cam = geometry.vertices();
        assert_eq!(geometry.facing_faces(cam), [true]);
        let parts = visible_edge_parts(&geometry, cam, &camera());
        for k in 0..6 {
            assert_eq!(parts.edge(k), [[0.0, 1.0]], "the L's own edge {k}");
        }
        for (w, (_, _, expected)) in wires.iter().enumerate() {
            assert_intervals_near(parts.edge(6 + w), expected, 1e-11);
        }
        assert_matches_ray_casting("L", &geometry, cam, &parts, 2000);
    }

    /// A cube whose top (y = 0, the camera's height) is seen exactly
    /// edge-on: the top does not face the camera, the front face's edges
    /// are whole, an edge behind from y = −1 to 1 is hidden by the front
    /// face below y = 0 only, and an edge behind in the plane y = 0, whose
    /// image runs along the front face's top side, is not hidden. A plate seen edge-on or within 1e-13
    /// rad of it hides nothing, whichever side faces the camera.
    #[test]
    fn a_face_seen_edge_on_hides_nothing() {
        let mut vertices: Vec<[f64; 3]> =
            (0..8).map(|i| [f64::from(i & 1) - 0.5, f64::from((i >> 1) & 1), 3.0 + f64::from((i >> 2) & 1)]).collect();
        // A wire across the front face's image below y = 0, and one whose
        // image runs along the front face's top side (its ray grazes it).
        vertices.extend([[0.0, -1.0, 8.0], [0.0, 1.0, 8.0], [-1.0, 0.0, 8.0], [1.0, 0.0, 8.0]]);
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
        edges.extend([[8, 9], [10, 11]]);
        let geometry = ModelGeometry::new(&model(vertices, edges, faces)).expect("cube");
        let cam = geometry.vertices();
        assert_eq!(geometry.facing_faces(cam), [false, false, false, false, true, false]);
        let parts = visible_edge_parts(&geometry, cam, &camera());
        for (k, &[i, j]) in geometry.edges().iter().enumerate().take(12) {
            let front = i < 4 && j < 4;
            assert_eq!(parts.edge(k), if front { &[[0.0, 1.0]][..] } else { &[][..] }, "edge {i}-{j}");
        }
        assert_intervals_near(parts.edge(12), &[[0.0, 0.5]], 1e-12);
        assert_eq!(parts.edge(13), [[0.0, 1.0]]);
        assert_matches_ray_casting("edge-on cube", &geometry, cam, &parts, 2000);

        let mut facing_tilts = 0;
        for tilt in [-1e-13, 0.0, 1e-13] {
            let plate: Vec<[f64; 3]> = [[-1.0, 2.0], [1.0, 2.0], [1.0, 4.0], [-1.0, 4.0]]
                .iter()
                .map(|&[x, z]| [x, tilt * (z - 3.0), z])
                .collect();
            for face in [vec![0, 1, 2, 3], vec![3, 2, 1, 0]] {
                let mut vertices = plate.clone();
                vertices.extend([[0.0, -1.0, 8.0], [0.0, 1.0, 8.0]]);
                let m = model(vertices, vec![[4, 5]], vec![face]);
                let geometry = ModelGeometry::new(&m).expect("plate");
                facing_tilts += usize::from(geometry.facing_faces(geometry.vertices())[0]);
                let parts = visible_edge_parts(&geometry, geometry.vertices(), &camera());
                assert_eq!(parts.edge(0), [[0.0, 1.0]], "tilt {tilt}");
            }
        }
        assert_eq!(facing_tilts, 2, "one side of each tilted plate faces the camera");
    }

    /// A base slab with a 3 × 3 grid of towers of different heights: many
    /// occluders per edge, seen from seeded random views.
    #[test]
    fn a_city_of_towers_agrees_with_ray_casting() {
        let mut city = prism(&[[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]], -0.2, 0.0);
        for i in 0..3 {
            for j in 0..3 {
                let (x, y) = (f64::from(i) + 0.2, f64::from(j) + 0.2);
                let height = 0.5 + f64::from((i * 7 + j * 13) % 10) * 0.3;
                city = union(city, prism(&[[x, y], [x + 0.6, y], [x + 0.6, y + 0.6], [x, y + 0.6]], 0.0, height));
            }
        }
        let geometry = ModelGeometry::new(&city).expect("city");
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut partly_seen = 0;
        for trial in 0..12 {
            let cam = geometry.camera_vertices(&random_view(&mut rng, &geometry), &[]).expect("pose");
            let parts = visible_edge_parts(&geometry, &cam, &camera());
            partly_seen += assert_matches_ray_casting(&format!("city trial {trial}"), &geometry, &cam, &parts, 300);
        }
        assert!(partly_seen >= 30, "only {partly_seen} edges partly hidden over the views");
    }

    /// Seeded random views of the non-convex models (the lid at random
    /// openings), near and far, some with parts behind the camera, against
    /// the ray casting.
    #[test]
    fn random_views_agree_with_ray_casting() {
        let mut rng = ChaCha8Rng::seed_from_u64(2024);
        for (name, m) in [("tower", box_with_tower()), ("lid", box_with_lid()), ("L prism", l_prism())] {
            let geometry = ModelGeometry::new(&m).expect(name);
            let mut partly_seen = 0;
            for trial in 0..60 {
                let pose = random_view(&mut rng, &geometry);
                let params: Vec<f64> = (0..geometry.joint_count()).map(|_| rng.random_range(-2.5..0.0)).collect();
                let cam = geometry.camera_vertices(&pose, &params).expect("pose");
                let parts = visible_edge_parts(&geometry, &cam, &camera());
                partly_seen +=
                    assert_matches_ray_casting(&format!("{name} trial {trial}"), &geometry, &cam, &parts, 400);
            }
            assert!(partly_seen >= 20, "{name}: only {partly_seen} edges partly hidden over the views");
        }
    }
}
