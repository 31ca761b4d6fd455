//! The model's state, its parameter corrections and the projected edge
//! measurements with their analytic Jacobians (001 "Modeling of measurement
//! errors"; the parameterisation of Lowe 1991).
//!
//! # Parameters
//! A state is a camera-from-object pose (R, t) and one value per joint. A
//! correction x = (ω, δc, δq) has n = 6 + joints entries:
//! - ω (rad): a small rotation about the camera axes through the model's
//!   centre c (the centroid of its vertices at joint values 0), composed
//!   onto the current rotation: R' = R(ω)·R;
//! - δc (m): a translation of that centre in the camera frame;
//! - δq (rad): added to the joint values (then held within their limits).
//!
//! Rotating about the centre rather than the camera or object origin keeps
//! rotation and translation nearly independent (Lowe 1991). A camera-frame
//! vertex X = R·Y + t moves by ∂X/∂ω_k = e_k × R(Y − c), ∂X/∂δc_k = e_k and
//! ∂X/∂q_j = R·∂Y/∂q_j (see
//! [`ModelGeometry::posed_vertices_with_joint_derivatives`]).
//!
//! # Measurements
//! A match pairs an image segment with a model edge. Its two errors are the
//! signed perpendicular distances of the image segment's endpoints from the
//! projected model line (Lowe 1991); the Jacobian rows are their derivatives
//! through the projection. The predictions of eq. 2 take their rows `A` from
//! the same derivatives: the perpendicular and parallel displacement of each
//! projected endpoint and the change of the projected edge's orientation.

use glam::DVec3;

use super::params::MAX_PARAMS;
use crate::geometry::{Camera, ModelGeometry, Pose, rotation_from_axis_angle};
use crate::{Error, Result};

/// A row of derivatives with respect to the correction x (first `n` used).
pub type Row = [f64; MAX_PARAMS];

/// The tracked state: pose and joint values.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Camera-from-object pose.
    pub pose: Pose,
    /// Joint values, radians, one per joint.
    pub params: Vec<f64>,
}

impl State {
    /// The state moved by the correction `x` (module doc), rotating about
    /// the object-frame point `centre`; joint values are held within
    /// `limits`.
    #[must_use]
    pub fn corrected(&self, x: &[f64], centre: DVec3, limits: &[[f64; 2]]) -> State {
        let rotation = rotation_from_axis_angle(DVec3::new(x[0], x[1], x[2])) * self.pose.rotation;
        let centre_cam = self.pose.apply(centre) + DVec3::new(x[3], x[4], x[5]);
        let translation = centre_cam - rotation * centre;
        let params =
            self.params.iter().zip(&x[6..]).zip(limits).map(|((q, dq), [lo, hi])| (q + dq).clamp(*lo, *hi)).collect();
        State { pose: Pose::new(rotation, translation), params }
    }

    /// The correction that takes `from` to `self` (the inverse of
    /// [`State::corrected`] without limits): the rotation R·R_fromᵀ as a
    /// vector, the centre's displacement, the joint differences.
    #[must_use]
    pub fn deviation_from(&self, from: &State, centre: DVec3) -> Row {
        let mut d = [0.0; MAX_PARAMS];
        let w = crate::geometry::axis_angle_from_rotation(&(self.pose.rotation * from.pose.rotation.transpose()));
        let dc = self.pose.apply(centre) - from.pose.apply(centre);
        d[..3].copy_from_slice(&w.to_array());
        d[3..6].copy_from_slice(&dc.to_array());
        for (k, (q, q0)) in self.params.iter().zip(&from.params).enumerate() {
            d[6 + k] = q - q0;
        }
        d
    }
}

/// The model linearised at a state: camera-frame vertices and their
/// derivatives with respect to the correction.
#[derive(Clone, Debug, Default)]
pub struct Linearised {
    /// Number of parameters, 6 + joints.
    pub n: usize,
    /// Camera-frame vertices.
    pub points: Vec<DVec3>,
    /// `derivatives[v]`: ∂X_v/∂x as three rows (x, y, z components).
    pub derivatives: Vec<[Row; 3]>,
}

impl Linearised {
    /// Linearise `geometry` at `state`, rotating about the object-frame
    /// point `centre`.
    pub fn at(geometry: &ModelGeometry, state: &State, centre: DVec3) -> Result<Self> {
        let joints = geometry.joint_count();
        let n = 6 + joints;
        if n > MAX_PARAMS {
            return Err(Error::Parameter(format!("lowe tracks at most {} joints; the model has {joints}", n - 6)));
        }
        let (posed, joint_derivatives) = geometry.posed_vertices_with_joint_derivatives(&state.params)?;
        let rotation = state.pose.rotation;
        let mut points = Vec::with_capacity(posed.len());
        let mut derivatives = Vec::with_capacity(posed.len());
        for (v, y) in posed.iter().enumerate() {
            points.push(state.pose.apply(*y));
            let arm = rotation * (*y - centre);
            let mut rows = [[0.0; MAX_PARAMS]; 3];
            // ∂X/∂ω_k = e_k × arm; ∂X/∂δc = I.
            let columns = [DVec3::X.cross(arm), DVec3::Y.cross(arm), DVec3::Z.cross(arm)];
            for (k, col) in columns.iter().enumerate() {
                rows[0][k] = col.x;
                rows[1][k] = col.y;
                rows[2][k] = col.z;
            }
            for (a, row) in rows.iter_mut().enumerate() {
                row[3 + a] = 1.0;
            }
            for j in 0..joints {
                let col = rotation * joint_derivatives[v * joints + j];
                rows[0][6 + j] = col.x;
                rows[1][6 + j] = col.y;
                rows[2][6 + j] = col.z;
            }
            derivatives.push(rows);
        }
        Ok(Self { n, points, derivatives })
    }

    /// The camera-frame point at 3-D parameter `t` along edge `[i, j]` and
    /// its derivative rows.
    #[must_use]
    pub fn edge_point(&self, [i, j]: [usize; 2], t: f64) -> (DVec3, [Row; 3]) {
        let p = self.points[i] + (self.points[j] - self.points[i]) * t;
        let mut rows = [[0.0; MAX_PARAMS]; 3];
        for (a, row) in rows.iter_mut().enumerate() {
            for k in 0..self.n {
                row[k] = (1.0 - t) * self.derivatives[i][a][k] + t * self.derivatives[j][a][k];
            }
        }
        (p, rows)
    }
}

/// A camera-frame point's pixel and the pixel's derivative rows, `None`
/// when it does not project (at or behind the camera).
#[must_use]
pub fn project_with_rows(camera: &Camera, p: DVec3, rows: &[Row; 3], n: usize) -> Option<([f64; 2], [Row; 2])> {
    let pixel = camera.project_in_front(p)?;
    let jac = camera.projection_jacobian(p);
    let mut out = [[0.0; MAX_PARAMS]; 2];
    for (r, jr) in out.iter_mut().zip(&jac) {
        for k in 0..n {
            r[k] = jr[0] * rows[0][k] + jr[1] * rows[1][k] + jr[2] * rows[2][k];
        }
    }
    Some((pixel, out))
}

/// A visible part of a model edge, projected: the model side of a match.
#[derive(Clone, Debug)]
pub struct ModelSegment {
    /// Index of the model edge.
    pub edge: usize,
    /// The part's 3-D parameter interval along the edge, which a match
    /// names. The tracker's visible model keeps here the part hidden-line
    /// removal gives, while `a` and `b` are the ends of its piece inside
    /// the image ([`clip_to_image`]); both lie on one image line, so a fit
    /// to the match measures the same distances either way.
    pub interval: [f64; 2],
    /// Projected endpoints.
    pub a: [f64; 2],
    /// Projected endpoints.
    pub b: [f64; 2],
    /// Derivative rows of `a` (u, v).
    pub da: [Row; 2],
    /// Derivative rows of `b` (u, v).
    pub db: [Row; 2],
    /// Which of the edge's faces face the camera, bit k for its k-th face
    /// in [`crate::geometry::ModelGeometry::edge_faces`] (the first eight):
    /// what lies on either side of it in the image. 0 unless the tracker's
    /// visible model set it.
    pub facing: u8,
}

/// The part of `interval` (3-D parameters along the edge `[i, j]`, both
/// ends in front of the camera) whose image lies inside the image, pixel
/// centres 0 … width − 1 and 0 … height − 1: the image segment is clipped
/// to that rectangle (Liang–Barsky) and the image fractions λ are taken back
/// to 3-D fractions μ = λ·Z_a / ((1 − λ)·Z_b + λ·Z_a), Z_a and Z_b the
/// depths of the interval's ends. `None` when no part of it is inside.
#[must_use]
pub fn clip_to_image(lin: &Linearised, camera: &Camera, [i, j]: [usize; 2], interval: [f64; 2]) -> Option<[f64; 2]> {
    let at = |t: f64| lin.points[i] + (lin.points[j] - lin.points[i]) * t;
    let (p, q) = (at(interval[0]), at(interval[1]));
    let (a, b) = (camera.project_in_front(p)?, camera.project_in_front(q)?);
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let (max_x, max_y) = (f64::from(camera.width) - 1.0, f64::from(camera.height) - 1.0);
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    // Each side of the rectangle as `d·λ ≤ room`.
    for (d, room) in [(-dx, a[0]), (dx, max_x - a[0]), (-dy, a[1]), (dy, max_y - a[1])] {
        if d == 0.0 {
            if room < 0.0 {
                return None;
            }
        } else if d > 0.0 {
            hi = hi.min(room / d);
        } else {
            lo = lo.max(room / d);
        }
    }
    if !(lo < hi) {
        return None;
    }
    let (za, zb) = (p.z, q.z);
    let to_3d = |lambda: f64| lambda * za / ((1.0 - lambda) * zb + lambda * za);
    let span = interval[1] - interval[0];
    Some([interval[0] + to_3d(lo) * span, interval[0] + to_3d(hi) * span])
}

impl ModelSegment {
    /// The projected part of `edge` over `interval`, `None` when an end does
    /// not project or the part is shorter than a pixel's thousandth.
    #[must_use]
    pub fn new(
        lin: &Linearised,
        camera: &Camera,
        edges: &[[usize; 2]],
        edge: usize,
        interval: [f64; 2],
    ) -> Option<Self> {
        let (p, rp) = lin.edge_point(edges[edge], interval[0]);
        let (q, rq) = lin.edge_point(edges[edge], interval[1]);
        let (a, da) = project_with_rows(camera, p, &rp, lin.n)?;
        let (b, db) = project_with_rows(camera, q, &rq, lin.n)?;
        let length = (b[0] - a[0]).hypot(b[1] - a[1]);
        (length > 1e-3).then_some(Self { edge, interval, a, b, da, db, facing: 0 })
    }

    /// Length in the image, px.
    #[must_use]
    pub fn length(&self) -> f64 {
        (self.b[0] - self.a[0]).hypot(self.b[1] - self.a[1])
    }

    /// Unit direction from `a` to `b`.
    #[must_use]
    pub fn direction(&self) -> [f64; 2] {
        let l = self.length();
        [(self.b[0] - self.a[0]) / l, (self.b[1] - self.a[1]) / l]
    }

    /// Unit normal (the direction turned by +90°).
    #[must_use]
    pub fn normal(&self) -> [f64; 2] {
        let [ux, uy] = self.direction();
        [-uy, ux]
    }

    /// Undirected orientation in [0, π).
    #[must_use]
    pub fn orientation(&self) -> f64 {
        let angle = (self.b[1] - self.a[1]).atan2(self.b[0] - self.a[0]);
        angle.rem_euclid(std::f64::consts::PI)
    }

    /// Signed perpendicular distance of `p` from the projected line and its
    /// derivative row: d = (L × (p − a)) / |L| with L = b − a.
    #[must_use]
    pub fn distance_with_row(&self, p: [f64; 2], n: usize) -> (f64, Row) {
        let (lx, ly) = (self.b[0] - self.a[0], self.b[1] - self.a[1]);
        let (px, py) = (p[0] - self.a[0], p[1] - self.a[1]);
        let len = lx.hypot(ly);
        let c = lx * py - ly * px;
        let d = c / len;
        let mut row = [0.0; MAX_PARAMS];
        for k in 0..n {
            let (dax, day) = (self.da[0][k], self.da[1][k]);
            let (dlx, dly) = (self.db[0][k] - dax, self.db[1][k] - day);
            let dc = dlx * py - lx * day - dly * px + ly * dax;
            let dlen = (lx * dlx + ly * dly) / len;
            row[k] = dc / len - c * dlen / (len * len);
        }
        (d, row)
    }

    /// Row of the perpendicular displacement of the projected line at
    /// fraction `s` along it (0 at `a`, 1 at `b`): n·((1 − s)∂a + s∂b).
    #[must_use]
    pub fn perpendicular_row(&self, s: f64, n: usize) -> Row {
        let [nx, ny] = self.normal();
        let mut row = [0.0; MAX_PARAMS];
        for k in 0..n {
            let du = (1.0 - s) * self.da[0][k] + s * self.db[0][k];
            let dv = (1.0 - s) * self.da[1][k] + s * self.db[1][k];
            row[k] = nx * du + ny * dv;
        }
        row
    }

    /// Rows of the displacement of `a` and of `b` along the line.
    #[must_use]
    pub fn parallel_rows(&self, n: usize) -> [Row; 2] {
        let [ux, uy] = self.direction();
        let mut rows = [[0.0; MAX_PARAMS]; 2];
        for k in 0..n {
            rows[0][k] = ux * self.da[0][k] + uy * self.da[1][k];
            rows[1][k] = ux * self.db[0][k] + uy * self.db[1][k];
        }
        rows
    }

    /// Row of the change of orientation: (L × ∂L) / |L|².
    #[must_use]
    pub fn orientation_row(&self, n: usize) -> Row {
        let (lx, ly) = (self.b[0] - self.a[0], self.b[1] - self.a[1]);
        let len2 = lx * lx + ly * ly;
        let mut row = [0.0; MAX_PARAMS];
        for k in 0..n {
            let (dlx, dly) = (self.db[0][k] - self.da[0][k], self.db[1][k] - self.da[1][k]);
            row[k] = (lx * dly - ly * dlx) / len2;
        }
        row
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::lowe::fixtures::{camera, hinged_box as hinged};

    fn state() -> State {
        State {
            pose: Pose::from_axis_angle(DVec3::new(0.4, -0.3, 0.2), DVec3::new(-0.1, 0.05, 0.9)),
            params: vec![0.7],
        }
    }

    /// An edge running out of the image keeps the part inside: its clipped
    /// ends project onto the border, under perspective (the ends at
    /// different depths), and an edge wholly outside has no part.
    #[test]
    fn clip_to_image_keeps_the_part_inside() {
        let cam = camera();
        let (w, h) = (f64::from(cam.width) - 1.0, f64::from(cam.height) - 1.0);
        let lin = Linearised {
            n: 6,
            points: vec![DVec3::new(-0.1, 0.02, 0.5), DVec3::new(1.5, 0.3, 2.5), DVec3::new(-3.0, 0.0, 1.0)],
            derivatives: vec![[[0.0; MAX_PARAMS]; 3]; 3],
        };
        let start = cam.project(lin.points[0]);
        assert!(start[0] > 0.0 && start[0] < w && start[1] > 0.0 && start[1] < h, "starts inside: {start:?}");
        assert!(cam.project(lin.points[1])[0] > w, "ends beyond the right border");
        let [t0, t1] = clip_to_image(&lin, &cam, [0, 1], [0.0, 1.0]).expect("a part inside");
        assert_eq!(t0, 0.0);
        assert!(t1 > 0.0 && t1 < 1.0);
        let end = cam.project(lin.points[0] + (lin.points[1] - lin.points[0]) * t1);
        assert!((end[0] - w).abs() < 1e-9, "clipped end on the border: {end:?}");
        // The same edge the other way round, and from within an interval.
        let [u0, u1] = clip_to_image(&lin, &cam, [1, 0], [0.0, 1.0]).unwrap();
        assert!((u0 - (1.0 - t1)).abs() < 1e-12 && u1 == 1.0);
        let [v0, v1] = clip_to_image(&lin, &cam, [0, 1], [0.2, 0.9]).unwrap();
        assert!(v0 == 0.2 && (v1 - t1).abs() < 1e-12);
        // An edge crossing the whole image, both ends outside: both ends
        // clipped onto the borders it crosses.
        let across = Linearised {
            n: 6,
            points: vec![DVec3::new(-2.0, 0.1, 1.5), DVec3::new(3.0, -0.2, 3.0), DVec3::new(-3.0, 0.0, 1.0)],
            derivatives: vec![[[0.0; MAX_PARAMS]; 3]; 3],
        };
        assert!(cam.project(across.points[0])[0] < 0.0 && cam.project(across.points[1])[0] > w);
        let [c0, c1] = clip_to_image(&across, &cam, [0, 1], [0.0, 1.0]).expect("crosses the image");
        assert!(c0 > 0.0 && c1 < 1.0 && c0 < c1);
        let on = |t: f64| cam.project(across.points[0] + (across.points[1] - across.points[0]) * t);
        assert!(on(c0)[0].abs() < 1e-9 && (on(c1)[0] - w).abs() < 1e-9, "{:?} {:?}", on(c0), on(c1));
        // Edges wholly outside: one left of the image, and a single point.
        assert_eq!(clip_to_image(&across, &cam, [2, 0], [0.0, 1.0]), None);
        assert_eq!(clip_to_image(&across, &cam, [2, 2], [0.0, 1.0]), None);
        assert_eq!(clip_to_image(&lin, &cam, [0, 1], [0.0, 0.5 * t1]), Some([0.0, 0.5 * t1]));
    }

    /// Every measurement's analytic row agrees with central finite
    /// differences of the measurement through [`State::corrected`], for
    /// every pose and joint parameter.
    #[test]
    fn jacobians_match_finite_differences() {
        let geometry = hinged();
        let cam = camera();
        let centre = geometry.centroid();
        let limits = geometry.joint_limits();
        let s0 = state();
        let lin = Linearised::at(&geometry, &s0, centre).unwrap();
        let n = lin.n;
        assert_eq!(n, 7);
        let p = [350.0, 260.0];
        for edge in [0, 5, 10, 12, 14] {
            let interval = [0.1, 0.8];
            let seg = ModelSegment::new(&lin, &cam, geometry.edges(), edge, interval).unwrap();
            let (_, row) = seg.distance_with_row(p, n);
            let perp = seg.perpendicular_row(0.3, n);
            let [par_a, _] = seg.parallel_rows(n);
            let orient = seg.orientation_row(n);
            for k in 0..n {
                let h = 1e-6;
                let eval = |sign: f64| {
                    let mut x = vec![0.0; n];
                    x[k] = sign * h;
                    let s = s0.corrected(&x, centre, &limits);
                    let l = Linearised::at(&geometry, &s, centre).unwrap();
                    ModelSegment::new(&l, &cam, geometry.edges(), edge, interval).unwrap()
                };
                let (plus, minus) = (eval(1.0), eval(-1.0));
                let fd = |f: &dyn Fn(&ModelSegment) -> f64| (f(&plus) - f(&minus)) / (2.0 * h);
                let d_fd = fd(&|s: &ModelSegment| s.distance_with_row(p, n).0);
                assert!(
                    (d_fd - row[k]).abs() < 1e-4 * (1.0 + row[k].abs()),
                    "edge {edge} param {k}: {d_fd} vs {}",
                    row[k]
                );
                // Perpendicular displacement of the point at s = 0.3 of the original line.
                let pt = |s: &ModelSegment| {
                    let nrm = seg.normal();
                    let x = [0.7 * s.a[0] + 0.3 * s.b[0], 0.7 * s.a[1] + 0.3 * s.b[1]];
                    nrm[0] * x[0] + nrm[1] * x[1]
                };
                let perp_fd = fd(&pt);
                assert!((perp_fd - perp[k]).abs() < 1e-4 * (1.0 + perp[k].abs()), "perp {edge}/{k}");
                let dir = seg.direction();
                let par_fd = fd(&|s: &ModelSegment| dir[0] * s.a[0] + dir[1] * s.a[1]);
                assert!((par_fd - par_a[k]).abs() < 1e-4 * (1.0 + par_a[k].abs()), "parallel {edge}/{k}");
                let ang = |s: &ModelSegment| (s.b[1] - s.a[1]).atan2(s.b[0] - s.a[0]);
                let o_fd = fd(&ang);
                assert!((o_fd - orient[k]).abs() < 1e-4 * (1.0 + orient[k].abs()), "orientation {edge}/{k}");
            }
        }
    }

    /// [`State::deviation_from`] inverts [`State::corrected`].
    #[test]
    fn deviation_inverts_correction() {
        let geometry = hinged();
        let centre = geometry.centroid();
        let s0 = state();
        let x = [0.02, -0.03, 0.01, 0.004, -0.002, 0.01, 0.05];
        let s1 = s0.corrected(&x, centre, &geometry.joint_limits());
        let d = s1.deviation_from(&s0, centre);
        for k in 0..7 {
            assert!((d[k] - x[k]).abs() < 1e-12, "{k}: {} vs {}", d[k], x[k]);
        }
    }
}
