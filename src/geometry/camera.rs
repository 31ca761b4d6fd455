//! The pinhole camera of SPEC §4 (`camera.json`): x right, y down, z
//! forward; pixel (0, 0) is the centre of the top-left pixel;
//! u = f_x·X/Z + c_x, v = f_y·Y/Z + c_y for a camera-frame point (X, Y, Z).
//!
//! The intrinsics are the serde type [`crate::io::formats::Camera`] itself
//! (re-exported here as [`Camera`]); this module adds its geometry.

use glam::DVec3;

pub use crate::io::formats::Camera;

/// Least width and height, pixels, of a target's image for a tracker to
/// start from it ([`Camera::start_image_problem`]): smaller, the target has
/// no outline to follow.
pub const MIN_START_IMAGE_PX: f64 = 1.0;

impl Camera {
    /// The pixel (u, v) = (f_x·X/Z + c_x, f_y·Y/Z + c_y) of the camera-frame
    /// point `p`. Defined for any Z ≠ 0 (a point behind the camera, Z < 0,
    /// also gets a pixel, mirrored through the centre of projection: callers
    /// that must tell check `p.z > 0` or use [`Camera::project_in_front`]).
    #[must_use]
    pub fn project(&self, p: DVec3) -> [f64; 2] {
        [self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy]
    }

    /// [`Camera::project`] for a point in front of the camera (Z > 0) whose
    /// pixel is finite; `None` otherwise: a point at or behind the camera, a
    /// NaN coordinate, or a Z so small against X, Y that the pixel overflows.
    #[must_use]
    pub fn project_in_front(&self, p: DVec3) -> Option<[f64; 2]> {
        if p.z.is_nan() || p.z <= 0.0 {
            return None;
        }
        let pixel = self.project(p);
        (pixel[0].is_finite() && pixel[1].is_finite()).then_some(pixel)
    }

    /// The camera-frame point at depth Z = `depth` whose image is `pixel`:
    /// X = (u − c_x)·Z/f_x, Y = (v − c_y)·Z/f_y (the inverse of
    /// [`Camera::project`] at a known depth).
    #[must_use]
    pub fn back_project(&self, pixel: [f64; 2], depth: f64) -> DVec3 {
        DVec3::new((pixel[0] - self.cx) * depth / self.fx, (pixel[1] - self.cy) * depth / self.fy, depth)
    }

    /// The 2×3 Jacobian ∂(u, v)/∂(X, Y, Z) of [`Camera::project`] at the
    /// camera-frame point `p`, row-major:
    /// `[[f_x/Z, 0, −f_x·X/Z²], [0, f_y/Z, −f_y·Y/Z²]]`.
    #[must_use]
    pub fn projection_jacobian(&self, p: DVec3) -> [[f64; 3]; 2] {
        let inv_z = 1.0 / p.z;
        [[self.fx * inv_z, 0.0, -self.fx * p.x * inv_z * inv_z], [0.0, self.fy * inv_z, -self.fy * p.y * inv_z * inv_z]]
    }

    /// The image Jacobian of 004 eq. 21 (the interaction matrix of visual
    /// servoing) at `pixel`, for a point at depth `depth`: the 2×6 matrix
    /// with `(u̇, v̇) = J · (T_x, T_y, T_z, ω_x, ω_y, ω_z)` when the point moves
    /// relative to the camera by `Ṗ = T + ω × P` (camera frame). With
    /// `u' = u − c_x`, `v' = v − c_y` it is eq. 21 with λ = f_x in the first
    /// row and f_y in the second:
    /// `[f_x/Z, 0, −u'/Z, −u'v'/f_y, (f_x² + u'²)/f_x, −v' f_x/f_y]` and
    /// `[0, f_y/Z, −v'/Z, −(f_y² + v'²)/f_y, u'v'/f_x, u' f_y/f_x]`.
    #[must_use]
    pub fn image_jacobian(&self, pixel: [f64; 2], depth: f64) -> [[f64; 6]; 2] {
        let (u, v) = (pixel[0] - self.cx, pixel[1] - self.cy);
        let (fx, fy, z) = (self.fx, self.fy, depth);
        [
            [fx / z, 0.0, -u / z, -u * v / fy, (fx * fx + u * u) / fx, -v * fx / fy],
            [0.0, fy / z, -v / z, -(fy * fy + v * v) / fy, u * v / fx, u * fy / fx],
        ]
    }

    /// Why a tracker cannot start from a pose that puts a target's vertices
    /// at the camera-frame `points`, in words (to be blamed on the file the
    /// pose came from), or `None`. The images of the points in front of the
    /// camera ([`Camera::project_in_front`]) must have a bounding box that
    /// meets the image (a close-up whose vertices all lie outside still
    /// crosses it; see [`Camera::in_image`] for the image's extent) and is
    /// at least [`MIN_START_IMAGE_PX`] wide and high (a target so far away,
    /// or a flat one seen edge on, has no outline). No point in front is a
    /// problem; whether some points may lie behind is the caller's to say.
    #[must_use]
    pub fn start_image_problem(&self, points: &[DVec3]) -> Option<String> {
        let pixels: Vec<[f64; 2]> = points.iter().filter_map(|&p| self.project_in_front(p)).collect();
        if pixels.is_empty() {
            return Some("the pose puts the whole model behind the camera".into());
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &pixels {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let (w, h) = (f64::from(self.width) - 0.5, f64::from(self.height) - 0.5);
        if hi[0] < -0.5 || lo[0] > w || hi[1] < -0.5 || lo[1] > h {
            return Some(format!(
                "the pose puts the whole model beside the {}x{} image (with the intrinsics of camera.json)",
                self.width, self.height
            ));
        }
        let (across, down) = (hi[0] - lo[0], hi[1] - lo[1]);
        if across < MIN_START_IMAGE_PX || down < MIN_START_IMAGE_PX {
            return Some(format!(
                "the pose makes the model's image {}x{} px: it must be at least {MIN_START_IMAGE_PX} px wide and high \
                 (the model is too far away, or seen edge on)",
                crate::bounds::short_number(across),
                crate::bounds::short_number(down)
            ));
        }
        None
    }

    /// Whether `pixel` lies on the image: pixel centres span 0..W−1 and
    /// 0..H−1, and pixels reach half a pixel beyond their centres, so
    /// −½ ≤ u ≤ W − ½ and −½ ≤ v ≤ H − ½ (false for NaN).
    #[must_use]
    pub fn in_image(&self, pixel: [f64; 2]) -> bool {
        let (w, h) = (f64::from(self.width) - 0.5, f64::from(self.height) - 0.5);
        (-0.5..=w).contains(&pixel[0]) && (-0.5..=h).contains(&pixel[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera { width: 640, height: 480, fx: 500.0, fy: 480.0, cx: 319.5, cy: 239.5 }
    }

    #[test]
    fn point_on_the_optical_axis_projects_to_the_principal_point() {
        let c = camera();
        for z in [0.1, 1.0, 7.5] {
            assert_eq!(c.project(DVec3::new(0.0, 0.0, z)), [319.5, 239.5]);
        }
        // One metre right and half a metre down at 2 m: 250 px right, 120 px down.
        assert_eq!(c.project(DVec3::new(1.0, 0.5, 2.0)), [569.5, 359.5]);
        assert_eq!(c.project_in_front(DVec3::new(0.0, 0.0, -1.0)), None);
        assert_eq!(c.project_in_front(DVec3::new(0.0, 0.0, 1.0)), Some([319.5, 239.5]));
        assert_eq!(c.project_in_front(DVec3::new(0.0, 0.0, 0.0)), None);
        assert_eq!(c.project_in_front(DVec3::new(f64::NAN, 0.0, 1.0)), None);
        // In front, but so close that f_x·X/Z overflows.
        assert_eq!(c.project_in_front(DVec3::new(1.0, 0.0, 1e-310)), None);
    }

    #[test]
    fn back_project_inverts_project() {
        let c = camera();
        for p in [DVec3::new(0.3, -0.2, 1.7), DVec3::new(-2.0, 1.0, 0.4), DVec3::new(0.0, 0.0, 3.0)] {
            let q = c.back_project(c.project(p), p.z);
            assert!((q - p).length() < 1e-12, "{p} -> {q}");
        }
        let pixel = [12.25, 400.5];
        let back = c.project(c.back_project(pixel, 2.5));
        assert!((back[0] - pixel[0]).abs() < 1e-12 && (back[1] - pixel[1]).abs() < 1e-12, "{back:?}");
    }

    #[test]
    fn projection_jacobian_matches_finite_differences() {
        let c = camera();
        let p = DVec3::new(0.31, -0.17, 1.3);
        let j = c.projection_jacobian(p);
        let h = 1e-6;
        for a in 0..3 {
            let mut dp = DVec3::ZERO;
            dp[a] = h;
            let (plus, minus) = (c.project(p + dp), c.project(p - dp));
            for r in 0..2 {
                let numeric = (plus[r] - minus[r]) / (2.0 * h);
                assert!((numeric - j[r][a]).abs() < 1e-5, "d{r}/d{a}: {numeric} vs {}", j[r][a]);
            }
        }
        assert_eq!(j[0][1], 0.0);
        assert_eq!(j[1][0], 0.0);
    }

    #[test]
    fn a_start_image_must_meet_the_image_and_span_a_pixel() {
        let c = camera();
        let square = |x: f64, z: f64| {
            [[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]].map(|[dx, dy]| DVec3::new(x + dx, dy, z))
        };
        assert_eq!(c.start_image_problem(&square(0.0, 1.0)), None);
        // A close-up: every vertex outside, the outline across the image.
        assert_eq!(c.start_image_problem(&square(0.0, 0.01)), None);
        // Part of the target behind the camera: the rest is judged.
        let mut straddling = square(0.0, 1.0).to_vec();
        straddling.push(DVec3::new(0.0, 0.0, -1.0));
        assert_eq!(c.start_image_problem(&straddling), None);
        let beside = c.start_image_problem(&square(1e6, 1.0)).unwrap();
        assert!(beside.contains("beside the 640x480 image"), "{beside}");
        let far = c.start_image_problem(&square(0.0, 1e9)).unwrap();
        assert!(far.contains("at least 1 px wide and high"), "{far}");
        let edge_on = [DVec3::new(-0.1, 0.0, 1.0), DVec3::new(0.1, 0.0, 1.0)];
        assert!(c.start_image_problem(&edge_on).unwrap().contains("x0 px"));
        let behind = square(0.0, -1.0);
        assert!(c.start_image_problem(&behind).unwrap().contains("behind the camera"));
    }

    #[test]
    fn in_image_reaches_half_a_pixel_beyond_the_centres() {
        let c = camera();
        assert!(c.in_image([-0.5, -0.5]) && c.in_image([639.5, 479.5]));
        assert!(!c.in_image([-0.51, 0.0]) && !c.in_image([0.0, 479.51]) && !c.in_image([f64::NAN, 0.0]));
    }

    /// A small rigid motion of a point, P' = R(ω)·P + T, moves its pixel by
    /// J·(T, ω) to first order (eq. 20–21).
    #[test]
    fn the_image_jacobian_predicts_a_small_motion() {
        let cam = Camera { width: 320, height: 240, fx: 400.0, fy: 380.0, cx: 160.0, cy: 120.0 };
        let p = DVec3::new(0.05, -0.03, 0.6);
        let screw = [1e-4, -2e-4, 3e-4, 2e-4, -1e-4, 3e-4];
        let moved = crate::geometry::pose::rotation_from_axis_angle(DVec3::new(screw[3], screw[4], screw[5])) * p
            + DVec3::new(screw[0], screw[1], screw[2]);
        let (a, b) = (cam.project(p), cam.project(moved));
        let j = cam.image_jacobian(a, p.z);
        for row in 0..2 {
            let predicted: f64 = (0..6).map(|k| j[row][k] * screw[k]).sum();
            assert!((predicted - (b[row] - a[row])).abs() < 1e-3 * predicted.abs().max(1e-3), "{row}");
        }
    }
}
