//! Scene `textured-plane`: the set-up of paper 004 — a camera on a robot's
//! end-effector looking at a static, colourfully textured plane, moving with
//! a smooth velocity screw whose first step is known.
//!
//! # Camera and plane
//!
//! 320×240, fx = fy = [`FOCAL_PX`] px, principal point at the image centre.
//! The plane is the object frame's z = 0 (x right, y down), facing the
//! camera, [`DEPTH_M`] in front of it at frame 0 (pose R = I,
//! t = (0, 0, DEPTH_M)). The model is a square of side [`WINDOW_SIDE_M`] on
//! the plane centred on the optical axis (about 64 px wide, the paper's
//! 64×64 window): vertices top-left, top-right, bottom-right, bottom-left,
//! one face, four edges.
//!
//! # Texture
//!
//! On the plane: per channel a sum of [`WAVES`] plane waves of random
//! direction, phase and wavelength (6–30 mm, 4–20 px at frame 0's depth)
//! and [`BLOBS`] soft discs of random colour, so hue, saturation and
//! intensity all vary on the window and no two places look alike; rendered
//! once into texels of 0.5 mm (a third of a pixel) and interpolated
//! bilinearly. Each pixel is the texture at the points of the plane its rays
//! meet (a 2×2 supersample), plus Gaussian noise of `noise` grey levels per
//! channel, rounded to 8 bits.
//!
//! # Motion
//!
//! The camera's own velocity screw, in its own frame, per frame `t`:
//! `v = (A_x cos 2πt/P_x, A_y sin 2πt/P_y, A_z sin 2πt/P_z)`,
//! `ω = (B_x sin 2πt/Q_x, B_y cos 2πt/Q_y, B_z sin 2πt/Q_z)`; camera t+1 is
//! camera t moved by `exp(v, ω)` (rotation by ω, then translation by v in
//! camera t's frame). `motion` picks which components move: `translation`
//! (v_x, v_y), `roll` (those and ω_z, about the optical axis) or `screw`
//! (all six). Amplitudes are a few pixels per frame at the window ([`AMPLITUDES`]).
//! `init.json` carries the pose at frame 0 and `camera_motion`, camera 1 in
//! the frame of camera 0 (SPEC §4); `truth.jsonl` the pose and window corners
//! of every frame.

use glam::{DMat3, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

use super::{SyntheticSequence, check_frames, check_range, frame_rng, parse_option};
use crate::geometry::pose::{Pose, rotation_from_axis_angle};
use crate::image::RgbImage;
use crate::io::formats::{self, Camera, InitState, Model, TruthFrame, Visibility};
use crate::{Error, Result};

/// Image width, px.
pub const WIDTH: u32 = 320;
/// Image height, px.
pub const HEIGHT: u32 = 240;
/// Focal length, px.
pub const FOCAL_PX: f64 = 400.0;
/// Distance of the plane at frame 0, m.
pub const DEPTH_M: f64 = 0.6;
/// Side of the tracked square, m (64 px at frame 0).
pub const WINDOW_SIDE_M: f64 = 0.096;
/// Plane waves per channel.
pub const WAVES: usize = 6;
/// Soft colour discs.
pub const BLOBS: usize = 60;
/// Largest number of frames.
pub const MAX_FRAMES: usize = 100_000;
/// Amplitudes of the camera's screw: `[A_x, A_y, A_z]` m/frame and
/// `[B_x, B_y, B_z]` rad/frame (at 0.6 m, 1 px is 1.5 mm sideways).
pub const AMPLITUDES: ([f64; 3], [f64; 3]) = ([3.0e-3, 2.25e-3, 4.0e-3], [2.0e-3, 1.5e-3, 0.015]);
/// Periods of the screw's components in frames: `[P_x, P_y, P_z]`, `[Q_x, Q_y, Q_z]`.
pub const PERIODS: ([f64; 3], [f64; 3]) = ([150.0, 110.0, 130.0], [170.0, 140.0, 90.0]);

/// Which components of the camera's screw move.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlaneMotion {
    /// Translation in x and y (the paper's experiment).
    Translation,
    /// Translation in x and y and rotation about the optical axis.
    Roll,
    /// All six components.
    Screw,
}

impl std::str::FromStr for PlaneMotion {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s {
            "translation" => Ok(Self::Translation),
            "roll" => Ok(Self::Roll),
            "screw" => Ok(Self::Screw),
            other => Err(Error::Parameter(format!(
                "textured-plane option motion: '{other}' is not one of translation, roll, screw"
            ))),
        }
    }
}

/// Largest `noise` σ accepted, grey levels (as the other scenes').
pub const MAX_NOISE_SIGMA: f64 = 64.0;

/// Options of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct TexturedPlaneOptions {
    /// Number of frames.
    pub frames: usize,
    /// Seed of the texture and the noise.
    pub seed: u64,
    /// Which screw components move.
    pub motion: PlaneMotion,
    /// Scale of the screw's amplitudes (1 = [`AMPLITUDES`]), 0..=10.
    pub speed: f64,
    /// Noise per channel, grey levels (σ), 0..=[`MAX_NOISE_SIGMA`].
    pub noise_sigma: f64,
}

impl Default for TexturedPlaneOptions {
    fn default() -> Self {
        Self { frames: 200, seed: 0, motion: PlaneMotion::Screw, speed: 1.0, noise_sigma: 1.5 }
    }
}

impl TexturedPlaneOptions {
    /// The `--set` keys.
    pub const KEYS: &'static [&'static str] = &["motion", "speed", "noise"];

    /// Set option `key` from its string `value`.
    pub fn set(&mut self, key: &str, value: &str) -> Result<()> {
        match key {
            "motion" => self.motion = value.parse()?,
            "speed" => self.speed = parse_option("textured-plane", key, value, "a number")?,
            "noise" => self.noise_sigma = parse_option("textured-plane", key, value, "a number")?,
            _ => return Err(super::no_such_option("textured-plane", key, Self::KEYS)),
        }
        Ok(())
    }

    fn validate(&self) -> Result<()> {
        check_frames(self.frames, MAX_FRAMES)?;
        check_range("speed", self.speed, 10.0, "")?;
        check_range("noise", self.noise_sigma, MAX_NOISE_SIGMA, " grey levels")
    }
}

/// The camera of the scene.
#[must_use]
pub fn camera() -> Camera {
    Camera {
        width: WIDTH,
        height: HEIGHT,
        fx: FOCAL_PX,
        fy: FOCAL_PX,
        cx: (f64::from(WIDTH) - 1.0) / 2.0,
        cy: (f64::from(HEIGHT) - 1.0) / 2.0,
    }
}

/// The tracked square: vertices top-left, top-right, bottom-right, bottom-left.
#[must_use]
pub fn model() -> Model {
    let h = WINDOW_SIDE_M / 2.0;
    Model {
        name: "window".into(),
        units: "m".into(),
        vertices: vec![[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]],
        edges: vec![[0, 1], [1, 2], [2, 3], [3, 0]],
        // Counter-clockwise seen from the camera (image y down).
        faces: vec![vec![0, 3, 2, 1]],
        joints: Vec::new(),
    }
}

/// The camera's screw `(v, ω)` over frame interval `t → t+1`, in camera t's frame.
#[must_use]
pub fn camera_screw(motion: PlaneMotion, speed: f64, t: usize) -> (DVec3, DVec3) {
    let (a, b) = AMPLITUDES;
    let (p, q) = PERIODS;
    let phase = |period: f64| std::f64::consts::TAU * t as f64 / period;
    let mut v = DVec3::new(a[0] * phase(p[0]).cos(), a[1] * phase(p[1]).sin(), a[2] * phase(p[2]).sin());
    let mut w = DVec3::new(b[0] * phase(q[0]).sin(), b[1] * phase(q[1]).cos(), b[2] * phase(q[2]).sin());
    match motion {
        PlaneMotion::Translation => {
            v.z = 0.0;
            w = DVec3::ZERO;
        }
        PlaneMotion::Roll => {
            v.z = 0.0;
            w.x = 0.0;
            w.y = 0.0;
        }
        PlaneMotion::Screw => {}
    }
    (v * speed, w * speed)
}

/// Camera t in the frame of camera 0 (camera-0-from-camera-t), for t = 0..frames.
#[must_use]
pub fn camera_path(motion: PlaneMotion, speed: f64, frames: usize) -> Vec<Pose> {
    let mut path = Vec::with_capacity(frames);
    let mut camera = Pose::new(DMat3::IDENTITY, DVec3::ZERO);
    for t in 0..frames {
        path.push(camera);
        let (v, w) = camera_screw(motion, speed, t);
        camera = camera.compose(&Pose::new(rotation_from_axis_angle(w), v));
    }
    path
}

/// Texel size of the rendered texture, m (a third of a pixel at frame 0's depth).
const TEXEL_M: f64 = 0.0005;
/// Half extent of the rendered texture, m (x, y): what the camera sees over
/// the scene's motion at full speed, with room to spare; beyond it the
/// texture's edge texels repeat.
const TEXTURE_HALF_EXTENT_M: [f64; 2] = [0.5, 0.42];

/// The procedural colour texture of the plane, rendered once into texels.
struct Texture {
    width: usize,
    height: usize,
    texels: Vec<[f32; 3]>,
}

impl Texture {
    fn new(seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7e47_u64);
        // Per channel: (direction x, direction y, wavenumber rad/m, phase, amplitude).
        let waves: Vec<Vec<[f64; 5]>> = (0..3)
            .map(|_| {
                (0..WAVES)
                    .map(|_| {
                        let angle: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                        let wavelength: f64 = rng.random_range(0.006..0.030);
                        [
                            angle.cos(),
                            angle.sin(),
                            std::f64::consts::TAU / wavelength,
                            rng.random_range(0.0..std::f64::consts::TAU),
                            rng.random_range(6.0..16.0),
                        ]
                    })
                    .collect()
            })
            .collect();
        // (x, y, radius, colour offset r, g, b).
        let blobs: Vec<[f64; 6]> = (0..BLOBS)
            .map(|_| {
                [
                    rng.random_range(-0.35..0.35),
                    rng.random_range(-0.28..0.28),
                    rng.random_range(0.008..0.03),
                    rng.random_range(-70.0..70.0),
                    rng.random_range(-70.0..70.0),
                    rng.random_range(-70.0..70.0),
                ]
            })
            .collect();
        let [hx, hy] = TEXTURE_HALF_EXTENT_M;
        let (width, height) = ((2.0 * hx / TEXEL_M) as usize + 1, (2.0 * hy / TEXEL_M) as usize + 1);
        let texels = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (x, y) = ((i % width) as f64 * TEXEL_M - hx, (i / width) as f64 * TEXEL_M - hy);
                let mut c = [128.0, 118.0, 108.0];
                for (value, waves) in c.iter_mut().zip(&waves) {
                    for &[dx, dy, k, phase, amp] in waves {
                        *value += amp * (k * (dx * x + dy * y) + phase).sin();
                    }
                }
                for &[bx, by, r, cr, cg, cb] in &blobs {
                    let d2 = ((x - bx).powi(2) + (y - by).powi(2)) / (r * r);
                    if d2 < 9.0 {
                        let weight = (-d2).exp();
                        c[0] += cr * weight;
                        c[1] += cg * weight;
                        c[2] += cb * weight;
                    }
                }
                c.map(|v| v as f32)
            })
            .collect();
        Self { width, height, texels }
    }

    /// Colour (0..255 scale, unclamped) at plane point (x, y) metres:
    /// bilinear between texels.
    fn colour(&self, x: f64, y: f64) -> [f64; 3] {
        let [hx, hy] = TEXTURE_HALF_EXTENT_M;
        let tx = ((x + hx) / TEXEL_M).clamp(0.0, (self.width - 1) as f64);
        let ty = ((y + hy) / TEXEL_M).clamp(0.0, (self.height - 1) as f64);
        let (x0, y0) = (tx.floor() as usize, ty.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (tx - x0 as f64, ty - y0 as f64);
        let t = |x: usize, y: usize| self.texels[y * self.width + x];
        std::array::from_fn(|c| {
            let top = (1.0 - fx) * f64::from(t(x0, y0)[c]) + fx * f64::from(t(x1, y0)[c]);
            let bottom = (1.0 - fx) * f64::from(t(x0, y1)[c]) + fx * f64::from(t(x1, y1)[c]);
            (1.0 - fy) * top + fy * bottom
        })
    }
}

/// Render frame `k` at camera-from-plane `pose`: the texture where each
/// pixel's rays (a 2×2 supersample) meet the plane, plus noise, rounded.
fn render(texture: &Texture, cam: &Camera, pose: &Pose, noise: f64, seed: u64, k: usize) -> Result<RgbImage> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let inverse = pose.inverse();
    let centre = inverse.translation;
    let clean: Vec<[f64; 3]> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).map(move |x| {
                let mut sum = [0.0; 3];
                for (sx, sy) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                    let ray = DVec3::new((x as f64 + sx - cam.cx) / cam.fx, (y as f64 + sy - cam.cy) / cam.fy, 1.0);
                    let d = inverse.rotate(ray);
                    let p = centre + (-centre.z / d.z) * d;
                    let c = texture.colour(p.x, p.y);
                    for i in 0..3 {
                        sum[i] += c[i] / 4.0;
                    }
                }
                sum
            })
        })
        .collect();
    let mut rng = frame_rng(seed, k);
    let mut gauss = move || -> f64 { StandardNormal.sample(&mut rng) };
    let data = clean.into_iter().map(|c| c.map(|v| (v + noise * gauss()).clamp(0.0, 255.0).round() as u8)).collect();
    RgbImage::from_vec(w, h, data)
}

/// One view of the scene's plane (the texture of `seed`) from the
/// camera-from-plane `pose`, with noise seeded by `seed` and `frame`: what
/// 004's experiments take as source and destination images.
pub fn render_view(seed: u64, noise_sigma: f64, pose: &Pose, frame: usize) -> Result<RgbImage> {
    render(&Texture::new(seed), &camera(), pose, noise_sigma, seed, frame)
}

/// Render the scene.
pub fn render_textured_plane(opts: &TexturedPlaneOptions) -> Result<SyntheticSequence> {
    opts.validate()?;
    let cam = camera();
    let model = model();
    let texture = Texture::new(opts.seed);
    let start = Pose::new(DMat3::IDENTITY, DVec3::new(0.0, 0.0, DEPTH_M));
    let path = camera_path(opts.motion, opts.speed, opts.frames.max(2));
    // Camera-from-plane at frame t: camera t's frame from camera 0's, then the start pose.
    let poses: Vec<Pose> = path.iter().take(opts.frames).map(|c| c.inverse().compose(&start)).collect();
    let corners = |pose: &Pose| -> Vec<[f64; 2]> {
        model.vertices.iter().map(|v| cam.project(pose.apply(DVec3::from_array(*v)))).collect()
    };
    let rgb_frames = poses
        .iter()
        .enumerate()
        .map(|(k, pose)| render(&texture, &cam, pose, opts.noise_sigma, opts.seed, k))
        .collect::<Result<Vec<_>>>()?;
    let frames = rgb_frames.iter().map(RgbImage::to_gray).collect();
    let truth = poses
        .iter()
        .enumerate()
        .map(|(k, pose)| TruthFrame {
            frame: k,
            visible: Visibility::Object(true),
            pose: Some(formats::Pose::from(pose)),
            params: Vec::new(),
            corners: corners(pose),
        })
        .collect();
    let first_motion = path[1];
    let r = first_motion.axis_angle();
    let t = first_motion.translation;
    let init = InitState {
        pose: Some(formats::Pose::from(&start)),
        params: Vec::new(),
        corners: corners(&start),
        camera_motion: Some([t.x, t.y, t.z, r.x, r.y, r.z]),
    };
    let meta = serde_json::json!({
        "scene": "textured-plane",
        "frames": opts.frames,
        "seed": opts.seed,
        "motion": format!("{:?}", opts.motion).to_lowercase(),
        "speed": opts.speed,
        "noise_sigma": opts.noise_sigma,
        "note": "camera screw per frame in its own frame: v = (Ax cos 2pi t/Px, Ay sin 2pi t/Py, Az sin 2pi t/Pz), w = (Bx sin 2pi t/Qx, By cos 2pi t/Qy, Bz sin 2pi t/Qz)",
    });
    Ok(SyntheticSequence {
        scene: "textured-plane".to_string(),
        camera: cam,
        model,
        init,
        truth,
        truth_extra: Vec::new(),
        frames,
        rgb_frames,
        meta,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_motion_and_the_truth_agree() {
        let seq =
            render_textured_plane(&TexturedPlaneOptions { frames: 3, ..TexturedPlaneOptions::default() }).unwrap();
        let m = seq.init.camera_motion.unwrap();
        let camera1 = Pose::from_axis_angle(DVec3::new(m[3], m[4], m[5]), DVec3::new(m[0], m[1], m[2]));
        let start: Pose = seq.init.pose.unwrap().into();
        let pose1: Pose = seq.truth[1].pose.unwrap().into();
        let expected = camera1.inverse().compose(&start);
        assert!((pose1.translation - expected.translation).length() < 1e-12);
        // A few pixels per frame, the window about 64 px wide, in colour.
        let moved = (0..4).map(|i| {
            let (a, b) = (seq.truth[0].corners[i], seq.truth[1].corners[i]);
            (a[0] - b[0]).hypot(a[1] - b[1])
        });
        assert!(moved.clone().all(|d| d > 0.5 && d < 6.0), "{:?}", moved.collect::<Vec<_>>());
        let c = &seq.truth[0].corners;
        assert!((c[1][0] - c[0][0] - 64.0).abs() < 0.5);
        let colourful = seq.rgb_frames[0].data().iter().filter(|p| p[0].abs_diff(p[1]) > 20).count();
        assert!(colourful > seq.rgb_frames[0].data().len() / 4, "{colourful}");
    }
}
