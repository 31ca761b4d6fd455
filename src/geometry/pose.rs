//! Rigid poses (SPEC §4): camera-from-object, X_cam = R·X_obj + t, with R
//! written in files as an axis-angle (Rodrigues) vector r = θ·k (unit axis k,
//! right-hand angle θ in radians) and t in metres.

use glam::{DMat3, DQuat, DVec3};

use crate::io::formats;

/// The rotation matrix of the axis-angle vector `r` (Rodrigues' formula
/// R = cos θ·I + sin θ·\[k\]× + (1 − cos θ)·k·kᵀ with θ = |r|, k = r/θ);
/// the identity for r = 0 (and for a non-finite r). Valid at every angle,
/// π and beyond included. Accurate near θ = 0: k is a unit vector for any
/// θ > 0 and 1 − cos θ only weighs the second-order term, so R = I + \[r\]×
/// to within O(θ²) with no cancellation in the first-order part.
#[must_use]
pub fn rotation_from_axis_angle(r: DVec3) -> DMat3 {
    let angle = r.length();
    if angle > 0.0 && angle.is_finite() { DMat3::from_axis_angle(r / angle, angle) } else { DMat3::IDENTITY }
}

/// The axis-angle vector r = θ·k of the rotation matrix `m`, with
/// 0 ≤ θ ≤ π (at θ = π, k and −k are the same rotation; either may come
/// back). Through the unit quaternion (w, v) = (cos θ/2, sin θ/2·k) of `m`
/// taken from its largest diagonal term (Shepperd's method, well
/// conditioned at every angle), with w ≥ 0: θ = 2·atan2(|v|, w) and
/// k = v/|v|, accurate near θ = 0 (no arccos of a trace near 1) and near π
/// (no division by sin θ).
#[must_use]
pub fn axis_angle_from_rotation(m: &DMat3) -> DVec3 {
    let q = DQuat::from_mat3(m);
    let q = if q.w < 0.0 { -q } else { q };
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s > 0.0 { (v / s) * (2.0 * s.atan2(q.w)) } else { DVec3::ZERO }
}

/// A rigid transform X ↦ R·X + t; as a pose, camera-from-object (SPEC §4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Rotation R (orthonormal, det +1).
    pub rotation: DMat3,
    /// Translation t, metres.
    pub translation: DVec3,
}

impl Default for Pose {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Pose {
    /// The identity transform.
    pub const IDENTITY: Self = Self { rotation: DMat3::IDENTITY, translation: DVec3::ZERO };

    /// The pose with rotation `rotation` and translation `translation`.
    #[must_use]
    pub fn new(rotation: DMat3, translation: DVec3) -> Self {
        Self { rotation, translation }
    }

    /// The pose with the rotation of the axis-angle vector `r`
    /// ([`rotation_from_axis_angle`]) and translation `t`.
    #[must_use]
    pub fn from_axis_angle(r: DVec3, t: DVec3) -> Self {
        Self { rotation: rotation_from_axis_angle(r), translation: t }
    }

    /// The axis-angle vector of the rotation ([`axis_angle_from_rotation`]).
    #[must_use]
    pub fn axis_angle(&self) -> DVec3 {
        axis_angle_from_rotation(&self.rotation)
    }

    /// R·`p` + t: the point `p` carried by the transform (object frame to
    /// camera frame for a camera-from-object pose).
    #[must_use]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.rotation * p + self.translation
    }

    /// R·`v`: the direction `v` carried by the transform (no translation).
    #[must_use]
    pub fn rotate(&self, v: DVec3) -> DVec3 {
        self.rotation * v
    }

    /// `self ∘ other`: apply `other` first, then `self`
    /// (R = R_s·R_o, t = R_s·t_o + t_s). With `self` camera-from-object and
    /// `other` object-from-part, the result is camera-from-part.
    #[must_use]
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose { rotation: self.rotation * other.rotation, translation: self.apply(other.translation) }
    }

    /// The inverse transform X ↦ Rᵀ·(X − t) (object-from-camera for a
    /// camera-from-object pose).
    #[must_use]
    pub fn inverse(&self) -> Pose {
        let rt = self.rotation.transpose();
        Pose { rotation: rt, translation: -(rt * self.translation) }
    }
}

impl std::ops::Mul for Pose {
    type Output = Pose;

    /// [`Pose::compose`]: `a * b` applies `b` first.
    fn mul(self, rhs: Pose) -> Pose {
        self.compose(&rhs)
    }
}

impl From<&formats::Pose> for Pose {
    /// The pose of a file (`init.json`, `truth.jsonl`, output lines).
    fn from(p: &formats::Pose) -> Self {
        Pose::from_axis_angle(DVec3::from_array(p.rotation), DVec3::from_array(p.translation))
    }
}

impl From<formats::Pose> for Pose {
    fn from(p: formats::Pose) -> Self {
        Pose::from(&p)
    }
}

impl From<&Pose> for formats::Pose {
    /// The pose as a file writes it: axis-angle with 0 ≤ θ ≤ π.
    fn from(p: &Pose) -> Self {
        formats::Pose { rotation: p.axis_angle().to_array(), translation: p.translation.to_array() }
    }
}

impl From<Pose> for formats::Pose {
    fn from(p: Pose) -> Self {
        formats::Pose::from(&p)
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::{FRAC_PI_2, PI};

    use super::*;

    fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
        (a - b).length() <= tol
    }

    fn mat_close(a: &DMat3, b: &DMat3, tol: f64) -> bool {
        (0..3).all(|c| close(a.col(c), b.col(c), tol))
    }

    #[test]
    fn quarter_turn_about_z_maps_x_to_y() {
        let r = rotation_from_axis_angle(DVec3::new(0.0, 0.0, FRAC_PI_2));
        assert!(close(r * DVec3::X, DVec3::Y, 1e-15), "{}", r * DVec3::X);
        assert!(close(r * DVec3::Y, -DVec3::X, 1e-15));
        assert!(close(r * DVec3::Z, DVec3::Z, 1e-15));
        assert_eq!(rotation_from_axis_angle(DVec3::ZERO), DMat3::IDENTITY);
    }

    #[test]
    fn axis_angle_round_trip_near_zero_near_pi_and_between() {
        let axes = [DVec3::X, DVec3::new(0.3, -0.5, 0.81).normalize(), DVec3::new(-1.0, 2.0, 0.5).normalize()];
        for k in axes {
            for angle in [0.0, 1e-14, 1e-9, 1e-5, 0.3, 1.7, PI - 1e-3, PI - 1e-7, PI - 1e-10] {
                let r = k * angle;
                let back = axis_angle_from_rotation(&rotation_from_axis_angle(r));
                // The absolute error is a few ulp of the matrix entries at every angle.
                assert!(close(back, r, 1e-12 + 1e-12 * angle), "k {k} θ {angle}: {back} vs {r}");
            }
            // Exactly π: the axis comes back up to its sign.
            let back = axis_angle_from_rotation(&rotation_from_axis_angle(k * PI));
            assert!(close(back, k * PI, 1e-9) || close(back, -k * PI, 1e-9), "k {k}: {back}");
        }
        // Beyond π the same rotation comes back with θ' = 2π − θ about −k.
        let k = axes[1];
        let back = axis_angle_from_rotation(&rotation_from_axis_angle(k * (PI + 0.2)));
        assert!(close(back, -k * (PI - 0.2), 1e-12), "{back}");
    }

    #[test]
    fn small_rotation_is_identity_plus_cross_product() {
        let r = DVec3::new(2e-9, -1e-9, 3e-9);
        let m = rotation_from_axis_angle(r);
        let p = DVec3::new(0.4, -1.0, 2.0);
        assert!(close(m * p, p + r.cross(p), 1e-16 * 10.0), "{}", m * p - p - r.cross(p));
    }

    #[test]
    fn compose_with_inverse_is_identity() {
        let a = Pose::from_axis_angle(DVec3::new(0.4, -0.5, 0.1), DVec3::new(0.1, -0.2, 1.5));
        let b = Pose::from_axis_angle(DVec3::new(-1.2, 0.3, 2.0), DVec3::new(-0.3, 0.05, 0.2));
        for c in [a * a.inverse(), a.inverse() * a] {
            assert!(mat_close(&c.rotation, &DMat3::IDENTITY, 1e-15) && close(c.translation, DVec3::ZERO, 1e-15));
        }
        // Composition applies the right operand first.
        let p = DVec3::new(0.7, 0.2, -0.4);
        assert!(close((a * b).apply(p), a.apply(b.apply(p)), 1e-15));
        assert!(close((a * b).inverse().apply((a * b).apply(p)), p, 1e-15));
    }

    #[test]
    fn converts_to_and_from_the_file_pose() {
        let file = formats::Pose { rotation: [0.4, -0.5, 0.1], translation: [0.1, -0.2, 1.5] };
        let pose = Pose::from(&file);
        let back = formats::Pose::from(pose);
        assert_eq!(back.translation, file.translation);
        for a in 0..3 {
            assert!((back.rotation[a] - file.rotation[a]).abs() < 1e-15, "{back:?}");
        }
        // X_cam = R·X_obj + t.
        assert_eq!(pose.apply(DVec3::ZERO), DVec3::new(0.1, -0.2, 1.5));
        assert_eq!(Pose::from(formats::Pose::default()), Pose::IDENTITY);
    }
}
