//! Scene `target3dof`: the laboratory experiment of paper 002 §3 — a
//! polyhedral target shaped like the back of a truck, translating in x, y and
//! z with a *fixed* orientation (the paper's 3-DOF assumption) in front of a
//! bookshelf, seen by a 640×480 camera at 30 Hz.
//!
//! # Camera
//!
//! 640×480, fx = fy = [`FOCAL_PX`] = 500 px (a 65° horizontal field of view),
//! principal point at the image centre (319.5, 239.5), [`FRAME_RATE_HZ`] = 30.
//!
//! # Model (`model.json`, metres, object frame x right, y down, z forward)
//!
//! The origin is the centre of the rear face, which lies in the plane z = 0;
//! the body extends away from the camera to z = [`BODY_SIZE`]`[2]`. Parts, in
//! model-vertex order (every part is convex; its faces are listed
//! counter-clockwise seen from outside, i.e. their right-hand normal points
//! outwards):
//!
//! 1. **body** (vertices 0–9), [`BODY_SIZE`] = 0.26 × 0.20 × 0.22 m: the rear
//!    face is split into two doors by a vertical dividing edge (vertices 1 and
//!    4 are the top and bottom of that edge); roof, floor, two sides, front.
//! 2. **bumper** (vertices 10–17): a bar 0.28 m wide, 2.5 cm high and 3 cm
//!    deep hanging 1 cm below the body, standing out 3 cm towards the camera.
//! 3. **left and right light boxes** (vertices 18–25, 26–33): 5 × 3 × 1.5 cm
//!    boxes on the doors, 1.5 cm in from the sides and the bottom.
//!
//! Every face has its own flat grey ([`face_greys`]), different from every
//! face it shares an edge with, so every model edge between two visible faces
//! is an intensity edge. Edges are the undirected sides of the faces.
//!
//! # Orientation (fixed)
//!
//! R = Rx([`PITCH_RAD`])·Ry([`YAW_RAD`]) (yaw 0.55 rad, pitch 0.40 rad): the
//! camera sees the rear face, the roof and the right side face (the side at
//! +x) of the body and of every attachment in every frame of every path this
//! scene makes, at least 3° away from edge-on (the bearing and range limits
//! below were chosen for that: checked on a dense grid of bearings and ranges,
//! and per frame in the tests); the floor, the left sides and the fronts are
//! always hidden, so the set of visible faces and edges never changes.
//! `init.json` and every truth line carry this rotation as an axis-angle
//! vector ([`rotation`]).
//!
//! # Motion
//!
//! The *target centre* is the object origin (the centre of the rear face); its
//! camera coordinates are the pose's translation `(a·Z, b·Z, Z)`, where
//! `(a, b)` = (X/Z, Y/Z) is its bearing as normalised image coordinates and
//! `Z` its *range* (depth along the optical axis, the paper's c_z). In scene
//! time τ (seconds):
//!
//! ```text
//! a(τ) = A·sin(ω·τ),   b(τ) = B·sin(2ω·τ)              (a figure-eight)
//! Z(τ) = Zmin·(Zmax/Zmin)^((1 − cos(Ω·τ))/2)            (slow, geometric)
//! ```
//!
//! with A = [`BEARING_AMPLITUDE`]`[0]` = 0.26, B = 0.18 (the target centre
//! stays within ±130 × ±90 px of the image centre), Zmin = 0.85 m, Zmax = 5 m
//! and Ω = 2π / [`RANGE_PERIOD_S`] (20 s: a 300-frame sequence goes from
//! 0.85 m to about 4.9 m). Scene time τ runs with the clock t = frame / 30 s
//! after a smooth start of [`RAMP_S`] = 1 s: `τ'(t) = 3x² − 2x³` with
//! x = t / RAMP_S for t < RAMP_S, 1 afterwards, so the target starts from rest
//! at the image centre at 0.85 m, accelerates without a jerk, and from t = 1 s
//! on moves along the path at full speed (τ = t − ½ s).
//!
//! **Speed.** `speed` is the peak angular speed of the line of sight to the
//! target centre, in rad/s: the rate at which the unit vector
//! `l = t / |t|` turns, `|dl/dt|` (the paper's "equivalent angular velocity",
//! 1 m/s at 0.85 m ≈ 1.2 rad/s). Range changes do not turn `l`. For the
//! gnomonic bearing `(a, b)`,
//!
//! ```text
//! |dl/dt|² = ((1 + a² + b²)(ȧ² + ḃ²) − (a·ȧ + b·ḃ)²) / (1 + a² + b²)²  ≤  ȧ² + ḃ²
//!          ≤ (A·ω)² + (2B·ω)²,
//! ```
//!
//! with equality exactly when the path crosses the image centre (a = b = 0,
//! both cosines ±1) at full speed. So ω = speed / √(A² + 4B²), and the peak is
//! reached at every centre crossing after the ramp: τ = π/ω, 2π/ω, … (for the
//! default 0.3 rad/s first at t = 5.15 s, frame 155; for 1.2 rad/s at
//! t = 1.66 s, frame 50). [`Target3dofPath::angular_speed`] evaluates the
//! formula; tests measure it from the truth poses.
//!
//! The path's shape in (a, b) and its range limits do not depend on `speed`,
//! so every model vertex stays inside the image at any speed (at least 40 px
//! from every border); `visible` in `truth.jsonl` is still computed per frame
//! (true when every model vertex projects inside the image, in front of the
//! camera).
//!
//! # Shaken path (`shake`)
//!
//! With `shake` = true the bearing does not follow the figure-eight: the
//! target is shaken back and forth with **abrupt reversals**. The bearing
//! `(a, b)` moves along straight runs at the constant rate
//! `|(ȧ, ḃ)|` = `speed` (normalised image units per second, i.e. rad/s at the
//! image centre), starting at the image centre at frame 0. Each run lasts a
//! whole number of frames drawn uniformly from [`SHAKE_RUN_FRAMES`] (5–25)
//! from the seed's own stream (so the path depends on `seed`), shortened
//! where it would leave the box |a| ≤ A, |b| ≤ B of the figure-eight; the
//! next run turns back by 180° ± up to [`SHAKE_TURN_JITTER_DEG`] (50°), so its
//! direction changes by at least 130° from one frame to the next and the
//! axis of the shaking wanders. Of [`SHAKE_TURN_TRIES`] seeded turns the first
//! that leaves room for a run of 5 frames is taken, else the one leaving the
//! most room (at 1.2 rad/s a run crosses the box in 9–13 frames, so runs
//! there are often shorter than drawn). The range follows `Z(τ)` as above.
//!
//! The angular speed of the line of sight is then at most `speed`, and equal
//! to it when a run crosses the image centre (the formula above with
//! `(ȧ, ḃ)` of the run; at least 0.9·`speed` anywhere in the box, where
//! 1 + a² + b² ≤ 1.1). In pixels: the target centre's image is
//! `(u₀ + f·a, v₀ + f·b)`, so it moves exactly f·`speed`/30 px per frame,
//! 16.7 px per frame per rad/s: 20 px/frame at 1.2 rad/s (30 px/frame would
//! be 1.8 rad/s); the vertices move 15–23 px per frame there (seed 0), as
//! the range and the viewing direction change the target's image. A reversal changes the image velocity
//! by 1.5–2 times that within one frame (the turn is 130°–230°).
//!
//! # Occluder
//!
//! `occlude` = f in 0..=[`MAX_OCCLUDE`] adds a vertical opaque bar (grey
//! [`OCCLUDER_GREY`]) spanning the full image height in front of the target,
//! moving with it: in every frame it is centred on the image column that
//! halves the target's projected area, and just wide enough to hide the
//! fraction f of that area (the area is measured on the target's exact-coverage
//! silhouette at [`OCCLUDER_SUPERSAMPLE`]× resolution, spread evenly across
//! each quarter-pixel column, so the hidden fraction is f within a
//! thousandth). `meta.json` lists the bar's columns per frame
//! (`occluder_columns`, `[x_left, x_right]` in pixel coordinates).
//!
//! # Rendering
//!
//! The bookshelf background (a wall, a bookcase with uprights and shelf
//! boards, seeded book spines of varied widths, heights and greys with a few
//! labels) is drawn once per sequence at [`DEFAULT_SUPERSAMPLE`]× resolution.
//! Per frame, in painter's order: the background, the body's front-facing
//! faces (one layer, back-face culled), the bumper's, each light box's (every
//! attachment lies in z ≤ 0 of the object frame, between the rear-face plane
//! and the camera, and with the camera above the floor plane as here none of
//! them hides another), then the occluder bar. Gaussian noise of σ = `noise`
//! grey levels (default 2) is added per frame from the seed's own stream, and
//! values are rounded to 8 bits.

use glam::{DMat3, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::{
    Background, Canvas, DEFAULT_SUPERSAMPLE, Face, FillRule, SyntheticSequence, add_noise_and_quantise, check_frames,
    check_range, frame_rng, parse_option, render_background,
};
use crate::early::Window;
use crate::geometry::{self, ModelGeometry};
use crate::image::{FloatImage, GrayImage};
use crate::io::formats::{Camera, InitState, Model, Pose, TruthFrame};
use crate::{Error, Result};

/// Frame width in pixels.
pub const WIDTH: usize = 640;
/// Frame height in pixels.
pub const HEIGHT: usize = 480;
/// Frame rate, Hz (a frame every 1/30 s).
pub const FRAME_RATE_HZ: f64 = 30.0;
/// Focal length fx = fy, pixels.
pub const FOCAL_PX: f64 = 500.0;
/// Width (x), height (y) and depth (z) of the truck body, metres.
pub const BODY_SIZE: [f64; 3] = [0.26, 0.20, 0.22];
/// Yaw of the fixed orientation (rotation about the camera's y axis), radians.
pub const YAW_RAD: f64 = 0.55;
/// Pitch of the fixed orientation (rotation about the camera's x axis), radians.
pub const PITCH_RAD: f64 = 0.40;
/// Bearing amplitudes (A, B) of the figure-eight, normalised image coordinates.
pub const BEARING_AMPLITUDE: [f64; 2] = [0.26, 0.18];
/// Nearest range (depth of the target centre), metres (paper 002: 0.85 m).
pub const MIN_RANGE_M: f64 = 0.85;
/// Farthest range, metres.
pub const MAX_RANGE_M: f64 = 5.0;
/// Period of the range oscillation, seconds of scene time.
pub const RANGE_PERIOD_S: f64 = 20.0;
/// Duration of the smooth start from rest, seconds.
pub const RAMP_S: f64 = 1.0;
/// Default peak angular speed of the line of sight, rad/s.
pub const DEFAULT_SPEED: f64 = 0.3;
/// Largest `speed` accepted, rad/s (paper 002 tracks up to 1.2).
pub const MAX_SPEED: f64 = 5.0;
/// Largest `occlude` fraction accepted.
pub const MAX_OCCLUDE: f64 = 0.3;
/// Largest `noise` σ accepted, grey levels.
pub const MAX_NOISE_SIGMA: f64 = 64.0;
/// Longest sequence accepted, frames (all frames are held in memory).
pub const MAX_FRAMES: usize = 20_000;
/// Grey level of the occluder bar.
pub const OCCLUDER_GREY: f32 = 55.0;
/// Duration of a run of the shaken path between two reversals, frames
/// (drawn uniformly; shortened where the box would be left).
pub const SHAKE_RUN_FRAMES: std::ops::RangeInclusive<usize> = 5..=25;
/// Largest deviation of a reversal from an exact about-turn, degrees.
pub const SHAKE_TURN_JITTER_DEG: f64 = 50.0;
/// Seeded turns tried at each reversal of the shaken path.
pub const SHAKE_TURN_TRIES: usize = 8;
/// ChaCha stream of the shaken path (the bookshelf uses 1, frame noise streams from 2³²).
const SHAKE_STREAM: u64 = 2;

/// Backdrop of the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Backdrop {
    /// A bookcase full of horizontal and vertical edges (default, paper 002 Fig. 4).
    #[default]
    Bookshelf,
    /// One of the shared backgrounds of [`super::render_background`].
    Shared(Background),
}

impl std::str::FromStr for Backdrop {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        if s == "bookshelf" {
            return Ok(Backdrop::Bookshelf);
        }
        s.parse::<Background>().map(Backdrop::Shared).map_err(|_| {
            Error::Parameter(format!(
                "unknown target3dof background '{s}' (known: bookshelf, {})",
                Background::NAMES.join(", ")
            ))
        })
    }
}

impl Backdrop {
    /// The lowercase name of this backdrop.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Backdrop::Bookshelf => "bookshelf",
            Backdrop::Shared(b) => b.name(),
        }
    }
}

/// Options of the `target3dof` scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Target3dofOptions {
    /// Number of frames (default 300: 10 s).
    pub frames: usize,
    /// Seed of the bookshelf and the pixel noise.
    pub seed: u64,
    /// Peak angular speed of the line of sight to the target centre, rad/s
    /// (default 0.3; the paper tracks up to 1.2). `0 ..= MAX_SPEED`.
    pub speed: f64,
    /// Fraction of the target's projected area the occluder bar hides
    /// (default 0: no bar). `0 ..= MAX_OCCLUDE`.
    pub occlude: f64,
    /// Standard deviation of the Gaussian pixel noise, grey levels (default 2).
    pub noise_sigma: f64,
    /// Backdrop (default bookshelf).
    pub background: Backdrop,
    /// Shake the target with abrupt reversals instead of the figure-eight
    /// (module doc, "Shaken path"; default false). `speed` is then the rate
    /// of every run.
    pub shake: bool,
}

impl Default for Target3dofOptions {
    fn default() -> Self {
        Self {
            frames: 300,
            seed: 0,
            speed: DEFAULT_SPEED,
            occlude: 0.0,
            noise_sigma: 2.0,
            background: Backdrop::Bookshelf,
            shake: false,
        }
    }
}

impl Target3dofOptions {
    /// Keys [`Target3dofOptions::set`] accepts.
    pub const KEYS: [&'static str; 5] = ["speed", "occlude", "noise", "background", "shake"];

    /// Set one option from strings (for the command line): `speed` (rad/s),
    /// `occlude` (fraction 0–0.3), `noise` (σ, grey levels), `background`
    /// (bookshelf|flat|textured|cluttered), `shake` (true|false). Range checks happen in
    /// [`Target3dofOptions::validate`].
    pub fn set(&mut self, key: &str, value: &str) -> Result<()> {
        let number = "a number";
        match key {
            "speed" => self.speed = parse_option("target3dof", key, value, number)?,
            "occlude" => self.occlude = parse_option("target3dof", key, value, number)?,
            "noise" | "noise_sigma" => self.noise_sigma = parse_option("target3dof", key, value, number)?,
            "background" => self.background = value.parse()?,
            "shake" => self.shake = parse_option("target3dof", key, value, "true or false")?,
            _ => return Err(super::no_such_option("target3dof", key, &Self::KEYS)),
        }
        Ok(())
    }

    /// Error unless every option is in its documented range.
    pub fn validate(&self) -> Result<()> {
        check_frames(self.frames, MAX_FRAMES)?;
        check_range("speed", self.speed, MAX_SPEED, " rad/s")?;
        check_range("occlude", self.occlude, MAX_OCCLUDE, "")?;
        check_range("noise sigma", self.noise_sigma, MAX_NOISE_SIGMA, "")
    }
}

/// The target's path for a requested peak angular speed (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Target3dofPath {
    /// Peak angular speed of the line of sight, rad/s.
    pub speed: f64,
    /// ω of the figure-eight, rad per second of scene time (b turns at 2ω).
    pub omega: f64,
}

impl Target3dofPath {
    /// The path whose line of sight turns at most, and at its centre crossings
    /// exactly, `speed` rad/s. Errors when `speed` is not in `0..=MAX_SPEED`.
    pub fn new(speed: f64) -> Result<Self> {
        super::check_range("speed", speed, MAX_SPEED, " rad/s")?;
        let [a, b] = BEARING_AMPLITUDE;
        // Peak of |dl/dt| = ω·√(A² + 4B²) at a centre crossing.
        Ok(Self { speed, omega: speed / (a * a + 4.0 * b * b).sqrt() })
    }

    /// Clock time of frame `frame`, seconds.
    #[must_use]
    pub fn time(frame: usize) -> f64 {
        frame as f64 / FRAME_RATE_HZ
    }

    /// Scene time τ(t) and its rate τ'(t) at clock time `t` (smooth start over
    /// [`RAMP_S`], then τ = t − RAMP_S/2).
    #[must_use]
    pub fn scene_time(t: f64) -> (f64, f64) {
        if t >= RAMP_S {
            return (t - RAMP_S / 2.0, 1.0);
        }
        let x = (t / RAMP_S).max(0.0);
        // τ' = smoothstep(x) = 3x² − 2x³, integrated: τ = RAMP_S·(x³ − x⁴/2).
        (RAMP_S * x * x * x * (1.0 - 0.5 * x), x * x * (3.0 - 2.0 * x))
    }

    /// Bearing (a, b) = (X/Z, Y/Z) of the target centre and its derivative
    /// with respect to scene time, at scene time `tau`.
    #[must_use]
    pub fn bearing(&self, tau: f64) -> ([f64; 2], [f64; 2]) {
        let [a, b] = BEARING_AMPLITUDE;
        let (s1, c1) = (self.omega * tau).sin_cos();
        let (s2, c2) = (2.0 * self.omega * tau).sin_cos();
        ([a * s1, b * s2], [a * self.omega * c1, 2.0 * b * self.omega * c2])
    }

    /// Range Z (depth of the target centre) at scene time `tau`, metres.
    #[must_use]
    pub fn range(tau: f64) -> f64 {
        let phase = (1.0 - (std::f64::consts::TAU / RANGE_PERIOD_S * tau).cos()) / 2.0;
        MIN_RANGE_M * (MAX_RANGE_M / MIN_RANGE_M).powf(phase)
    }

    /// Translation of the target centre (camera frame, metres) at clock time `t`.
    #[must_use]
    pub fn translation_at(&self, t: f64) -> [f64; 3] {
        let (tau, _) = Self::scene_time(t);
        let ([a, b], _) = self.bearing(tau);
        let z = Self::range(tau);
        [a * z, b * z, z]
    }

    /// The true pose of frame `frame`: the fixed [`rotation`] and the path's translation.
    #[must_use]
    pub fn pose(&self, frame: usize) -> Pose {
        Pose { rotation: rotation(), translation: self.translation_at(Self::time(frame)) }
    }

    /// Angular speed `|dl/dt|` of the line of sight at clock time `t`, rad/s
    /// (the formula of the module docs; at most `speed`).
    #[must_use]
    pub fn angular_speed(&self, t: f64) -> f64 {
        let (tau, rate) = Self::scene_time(t);
        let ([a, b], [da, db]) = self.bearing(tau);
        let (da, db) = (da * rate, db * rate);
        let n2 = 1.0 + a * a + b * b;
        let radial = a * da + b * db;
        ((n2 * (da * da + db * db) - radial * radial).max(0.0)).sqrt() / n2
    }

    /// Clock time of the first centre crossing at full speed (where the
    /// angular speed peaks), seconds; `None` when `speed` is 0.
    #[must_use]
    pub fn first_peak_time(&self) -> Option<f64> {
        (self.omega > 0.0).then(|| std::f64::consts::PI / self.omega + RAMP_S / 2.0)
    }
}

/// The shaken path (module doc, "Shaken path"): the bearing at every frame,
/// piecewise linear with a reversal at each run's end.
#[derive(Clone, Debug, PartialEq)]
pub struct ShakePath {
    /// Rate of every run, rad/s (normalised image units per second).
    pub speed: f64,
    /// Bearing (a, b) of the target centre at frames 0 ..= `frames`.
    bearings: Vec<[f64; 2]>,
    /// Frames at which a run ends and the next, turned back, begins (those
    /// before the last frame).
    pub reversals: Vec<usize>,
}

impl ShakePath {
    /// The shaken path of `frames` frames at `speed` rad/s drawn from `seed`.
    /// Errors when `speed` is not in `0..=MAX_SPEED`.
    pub fn new(speed: f64, frames: usize, seed: u64) -> Result<Self> {
        super::check_range("speed", speed, MAX_SPEED, " rad/s")?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(SHAKE_STREAM);
        let step = speed / FRAME_RATE_HZ;
        let [ha, hb] = BEARING_AMPLITUDE;
        // Whole frames a run from `p` in direction `d` stays inside the box.
        let room = |p: [f64; 2], d: [f64; 2]| -> usize {
            if step <= 0.0 {
                return usize::MAX;
            }
            let along = |x: f64, dx: f64, h: f64| {
                if dx > 0.0 {
                    (h - x) / dx
                } else if dx < 0.0 {
                    (-h - x) / dx
                } else {
                    f64::INFINITY
                }
            };
            let reach = along(p[0], d[0], ha).min(along(p[1], d[1], hb)).max(0.0);
            (reach / step).floor().min(usize::MAX as f64) as usize
        };
        let jitter = SHAKE_TURN_JITTER_DEG.to_radians();
        let min_run = *SHAKE_RUN_FRAMES.start();
        let mut heading: f64 = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let mut bearings = vec![[0.0, 0.0]];
        let mut reversals = Vec::new();
        let mut first = true;
        while bearings.len() <= frames {
            let p = bearings[bearings.len() - 1];
            // The turn: an about-turn ± jitter (none before the first run).
            let mut best: Option<(usize, f64)> = None;
            for _ in 0..SHAKE_TURN_TRIES {
                let turn = if first { 0.0 } else { std::f64::consts::PI + rng.random_range(-jitter..=jitter) };
                let h = heading + turn;
                let r = room(p, [h.cos(), h.sin()]);
                if best.is_none_or(|(b, _)| r > b) {
                    best = Some((r, h));
                }
                if r >= min_run {
                    best = Some((r, h));
                    break;
                }
            }
            let (room_frames, h) = best.unwrap_or((1, heading));
            heading = h;
            first = false;
            let drawn = rng.random_range(SHAKE_RUN_FRAMES);
            let run = drawn.min(room_frames).max(1);
            let d = [step * heading.cos(), step * heading.sin()];
            for k in 1..=run {
                let q = [p[0] + d[0] * k as f64, p[1] + d[1] * k as f64];
                bearings.push([q[0].clamp(-ha, ha), q[1].clamp(-hb, hb)]);
            }
            reversals.push(bearings.len() - 1);
        }
        bearings.truncate(frames + 1);
        reversals.retain(|&k| k + 1 < frames);
        Ok(Self { speed, bearings, reversals })
    }

    /// Bearing (a, b) at clock time `t` (linear between frames; held beyond
    /// the last one) and its rate d(a, b)/dt, per second.
    #[must_use]
    pub fn bearing(&self, t: f64) -> ([f64; 2], [f64; 2]) {
        let last = self.bearings.len() - 1;
        let x = (t * FRAME_RATE_HZ).clamp(0.0, last as f64);
        let k = (x.floor() as usize).min(last.saturating_sub(1));
        let (p, q) = (self.bearings[k], self.bearings[(k + 1).min(last)]);
        let s = x - k as f64;
        let rate = [(q[0] - p[0]) * FRAME_RATE_HZ, (q[1] - p[1]) * FRAME_RATE_HZ];
        ([p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])], rate)
    }

    /// Translation of the target centre (camera frame, metres) at clock time `t`.
    #[must_use]
    pub fn translation_at(&self, t: f64) -> [f64; 3] {
        let ([a, b], _) = self.bearing(t);
        let z = Target3dofPath::range(Target3dofPath::scene_time(t).0);
        [a * z, b * z, z]
    }

    /// Angular speed `|dl/dt|` of the line of sight at clock time `t`, rad/s
    /// (the formula of the module docs with the run's rate; at most `speed`).
    #[must_use]
    pub fn angular_speed(&self, t: f64) -> f64 {
        let ([a, b], [da, db]) = self.bearing(t);
        let n2 = 1.0 + a * a + b * b;
        let radial = a * da + b * db;
        ((n2 * (da * da + db * db) - radial * radial).max(0.0)).sqrt() / n2
    }
}

/// The fixed orientation R = Rx(pitch)·Ry(yaw) as a rotation matrix.
#[must_use]
pub fn rotation_matrix() -> DMat3 {
    DMat3::from_rotation_x(PITCH_RAD) * DMat3::from_rotation_y(YAW_RAD)
}

/// The fixed orientation as an axis-angle (Rodrigues) vector, radians.
#[must_use]
pub fn rotation() -> [f64; 3] {
    geometry::axis_angle_from_rotation(&rotation_matrix()).to_array()
}

/// `camera.json` of the scene: 640×480, fx = fy = 500, principal point at the centre.
#[must_use]
pub fn camera() -> Camera {
    Camera {
        width: WIDTH as u32,
        height: HEIGHT as u32,
        fx: FOCAL_PX,
        fy: FOCAL_PX,
        cx: (WIDTH as f64 - 1.0) / 2.0,
        cy: (HEIGHT as f64 - 1.0) / 2.0,
    }
}

/// A convex part of the model: its faces (vertex loops, model indices) and greys.
struct Part {
    faces: Vec<Vec<usize>>,
    greys: Vec<f32>,
}

/// The model's parts in painter's order: body, bumper, left and right light box.
struct TruckModel {
    vertices: Vec<[f64; 3]>,
    parts: Vec<Part>,
}

/// Grey levels of a box's faces, in [`add_box`]'s face order:
/// rear (−z), front (+z), top (−y), bottom (+y), left (−x), right (+x).
type BoxGreys = [f32; 6];

/// Append an axis-aligned box `lo`..`hi` (object frame) as a part; its faces
/// are listed with outward right-hand normals.
fn add_box(model: &mut TruckModel, lo: [f64; 3], hi: [f64; 3], greys: BoxGreys) {
    let base = model.vertices.len();
    // Rear face (z = lo) TL, TR, BR, BL, then the same at z = hi.
    for z in [lo[2], hi[2]] {
        for [x, y] in [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]] {
            model.vertices.push([x, y, z]);
        }
    }
    let (tl, tr, br, bl) = (base, base + 1, base + 2, base + 3);
    let (ftl, ftr, fbr, fbl) = (base + 4, base + 5, base + 6, base + 7);
    let faces = vec![
        vec![tl, bl, br, tr],
        vec![ftl, ftr, fbr, fbl],
        vec![tl, tr, ftr, ftl],
        vec![bl, fbl, fbr, br],
        vec![tl, ftl, fbl, bl],
        vec![tr, br, fbr, ftr],
    ];
    model.parts.push(Part { faces, greys: greys.to_vec() });
}

/// The truck-back model of the module docs.
fn truck_model() -> TruckModel {
    let [w, h, d] = BODY_SIZE;
    let (hw, hh) = (w / 2.0, h / 2.0);
    let mut model = TruckModel { vertices: Vec::new(), parts: Vec::new() };
    // Body: rear face TL, TM, TR, BR, BM, BL (z = 0), front TL, TR, BR, BL (z = d).
    model.vertices.extend_from_slice(&[
        [-hw, -hh, 0.0],
        [0.0, -hh, 0.0],
        [hw, -hh, 0.0],
        [hw, hh, 0.0],
        [0.0, hh, 0.0],
        [-hw, hh, 0.0],
        [-hw, -hh, d],
        [hw, -hh, d],
        [hw, hh, d],
        [-hw, hh, d],
    ]);
    let body_faces = vec![
        vec![0, 5, 4, 1],    // left door
        vec![1, 4, 3, 2],    // right door
        vec![0, 1, 2, 7, 6], // roof (through the divider's top)
        vec![5, 9, 8, 3, 4], // floor
        vec![0, 6, 9, 5],    // left side
        vec![2, 3, 8, 7],    // right side
        vec![6, 7, 8, 9],    // front
    ];
    model.parts.push(Part { faces: body_faces, greys: vec![185.0, 148.0, 222.0, 90.0, 100.0, 112.0, 80.0] });
    // Bumper: 1 cm below the body, 1 cm wider on each side, 3 cm towards the camera.
    add_box(
        &mut model,
        [-hw - 0.01, hh + 0.01, -0.03],
        [hw + 0.01, hh + 0.035, 0.0],
        [40.0, 50.0, 78.0, 50.0, 60.0, 62.0],
    );
    // Light boxes on the doors.
    for x0 in [-hw + 0.015, hw - 0.065] {
        add_box(
            &mut model,
            [x0, hh - 0.045, -0.015],
            [x0 + 0.05, hh - 0.015, 0.0],
            [245.0, 120.0, 205.0, 120.0, 95.0, 100.0],
        );
    }
    model
}

/// `model.json` of the scene (see the module docs for the parts and vertex order).
#[must_use]
pub fn model() -> Model {
    let truck = truck_model();
    let faces: Vec<Vec<usize>> = truck.parts.iter().flat_map(|p| p.faces.clone()).collect();
    let mut edges: Vec<[usize; 2]> = Vec::new();
    for face in &faces {
        for k in 0..face.len() {
            let (i, j) = (face[k], face[(k + 1) % face.len()]);
            let edge = [i.min(j), i.max(j)];
            if !edges.contains(&edge) {
                edges.push(edge);
            }
        }
    }
    Model {
        name: "truck-back".to_string(),
        units: "m".to_string(),
        vertices: truck.vertices,
        edges,
        faces,
        joints: Vec::new(),
    }
}

/// Flat grey level of every face of [`model`], in the order of its `faces`.
#[must_use]
pub fn face_greys() -> Vec<f32> {
    truck_model().parts.iter().flat_map(|p| p.greys.clone()).collect()
}

/// Camera coordinates of the model's vertices under `pose` (X = R·X_obj + t).
fn to_camera(vertices: &[[f64; 3]], pose: &Pose) -> Vec<DVec3> {
    let pose = geometry::Pose::from(pose);
    vertices.iter().map(|v| pose.apply(DVec3::from_array(*v))).collect()
}

/// Image positions of every vertex of `model` under `pose` seen by `cam`
/// (also hidden ones), in model-vertex order.
#[must_use]
pub fn project_model(model: &Model, pose: &Pose, cam: &Camera) -> Vec<[f64; 2]> {
    to_camera(&model.vertices, pose).into_iter().map(|p| cam.project(p)).collect()
}

/// The projected front-facing faces of one part: (outline, grey) per face.
type PartOutlines = Vec<(Vec<[f64; 2]>, f32)>;

/// The scene: path, model and options, with what each frame shows.
#[derive(Clone, Debug)]
pub struct Target3dofScene {
    /// The options it was made from.
    pub options: Target3dofOptions,
    /// The target's figure-eight path (its bearing unused when shaken).
    pub path: Target3dofPath,
    /// The shaken path, with `shake`.
    pub shake: Option<ShakePath>,
    /// `camera.json`.
    pub camera: Camera,
    /// `model.json`.
    pub model: Model,
    /// The model's faces and their visibility.
    geometry: ModelGeometry,
    /// Grey of every model face.
    greys: Vec<f32>,
    /// Face index ranges of the parts, painter's order.
    parts: Vec<std::ops::Range<usize>>,
}

impl Target3dofScene {
    /// The scene for `options` (validated).
    pub fn new(options: &Target3dofOptions) -> Result<Self> {
        options.validate()?;
        let truck = truck_model();
        let mut parts = Vec::new();
        let mut start = 0;
        for p in &truck.parts {
            parts.push(start..start + p.faces.len());
            start += p.faces.len();
        }
        let model = model();
        Ok(Self {
            options: options.clone(),
            path: Target3dofPath::new(options.speed)?,
            shake: if options.shake {
                Some(ShakePath::new(options.speed, options.frames, options.seed)?)
            } else {
                None
            },
            camera: camera(),
            geometry: ModelGeometry::new(&model)?,
            model,
            greys: face_greys(),
            parts,
        })
    }

    /// The true pose of frame `frame`.
    #[must_use]
    pub fn pose(&self, frame: usize) -> Pose {
        match &self.shake {
            Some(shake) => {
                Pose { rotation: rotation(), translation: shake.translation_at(Target3dofPath::time(frame)) }
            }
            None => self.path.pose(frame),
        }
    }

    /// Angular speed of the line of sight at clock time `t`, rad/s, of the
    /// path in use.
    #[must_use]
    pub fn angular_speed(&self, t: f64) -> f64 {
        match &self.shake {
            Some(shake) => shake.angular_speed(t),
            None => self.path.angular_speed(t),
        }
    }

    /// Image positions of every model vertex at frame `frame`.
    #[must_use]
    pub fn corners(&self, frame: usize) -> Vec<[f64; 2]> {
        project_model(&self.model, &self.pose(frame), &self.camera)
    }

    /// Whether every model vertex at frame `frame` is in front of the camera
    /// and projects inside the image (pixel centres span 0..W−1, pixels
    /// reach half a pixel further).
    #[must_use]
    pub fn visible(&self, frame: usize) -> bool {
        let cam = to_camera(&self.model.vertices, &self.pose(frame));
        cam.iter().all(|p| p.z > 0.0 && self.camera.in_image(self.camera.project(*p)))
    }

    /// The front-facing faces of every part at frame `frame`, painter's order:
    /// one list of (projected outline, grey) per part.
    fn visible_faces(&self, frame: usize) -> Vec<PartOutlines> {
        let cam = to_camera(&self.model.vertices, &self.pose(frame));
        let facing = self.geometry.facing_faces(&cam);
        self.parts
            .iter()
            .map(|range| {
                range
                    .clone()
                    .filter(|&f| facing[f])
                    .map(|f| {
                        let outline = self.model.faces[f].iter().map(|&i| self.camera.project(cam[i])).collect();
                        (outline, self.greys[f])
                    })
                    .collect()
            })
            .collect()
    }

    /// The occluder bar of frame `frame` as image columns `[x_left, x_right]`
    /// (pixel coordinates), or `None` without occlusion or when no part of
    /// the target is in the image (see the module docs).
    pub fn occluder(&self, frame: usize) -> Result<Option<[f64; 2]>> {
        let fraction = self.options.occlude;
        if fraction <= 0.0 {
            return Ok(None);
        }
        let mut parts = self.visible_faces(frame);
        // The target's exact-coverage silhouette, in a canvas over the pixels it touches only.
        let outlines = parts.iter().flatten().flat_map(|(points, _)| points.iter());
        let Some(window) = Window::around(outlines, TOUCHED_MARGIN_PX, WIDTH, HEIGHT).filter(|w| !w.is_empty()) else {
            return Ok(None);
        };
        let origin = [f64::from(window.x0), f64::from(window.y0)];
        for (points, _) in parts.iter_mut().flatten() {
            for p in points.iter_mut() {
                *p = [p[0] - origin[0], p[1] - origin[1]];
            }
        }
        let (ww, wh) = ((window.x1 - window.x0) as usize, (window.y1 - window.y0) as usize);
        let mut mask = Canvas::new(ww, wh, OCCLUDER_SUPERSAMPLE, 0.0)?;
        draw_target(&mut mask, &parts, Some(1.0));
        let columns = column_areas(&mask);
        // Sample column j spans [x0 − ½ + j/S, x0 − ½ + (j + 1)/S] in the image.
        let cell = 1.0 / OCCLUDER_SUPERSAMPLE as f64;
        Ok(strip_hiding(&columns, origin[0] - 0.5, cell, fraction))
    }
}

/// Margin of [`Window::around`] for the pixels polygons touch: ½ px reaches
/// every pixel a polygon's bounding box overlaps, and one more pixel comes
/// with the window's outward rounding.
const TOUCHED_MARGIN_PX: f64 = 0.5;

/// Super-sampling of the silhouette [`Target3dofScene::occluder`] measures:
/// its area is resolved to quarter-pixel columns.
pub const OCCLUDER_SUPERSAMPLE: usize = 4;

/// Draw the parts' faces in painter's order, each part as one layer; with
/// `flat` every face gets that grey (a silhouette mask).
fn draw_target(canvas: &mut Canvas, parts: &[PartOutlines], flat: Option<f32>) {
    for part in parts {
        let faces: Vec<Face<'_>> =
            part.iter().map(|(points, grey)| Face { points, grey: flat.unwrap_or(*grey) }).collect();
        canvas.fill_faces(&faces, FillRule::NonZero);
    }
}

/// Sum of a canvas's samples per sample column.
fn column_areas(mask: &Canvas) -> Vec<f64> {
    let sw = mask.width() * mask.supersample();
    let mut columns = vec![0.0f64; sw];
    for row in mask.samples().chunks_exact(sw) {
        for (c, &v) in columns.iter_mut().zip(row) {
            *c += f64::from(v);
        }
    }
    columns
}

/// The strip `[m − h, m + h]` around the area median m holding `fraction` of
/// the total of `columns` (column i's area spread evenly over
/// `[left + i·cell, left + (i + 1)·cell]`).
fn strip_hiding(columns: &[f64], left: f64, cell: f64, fraction: f64) -> Option<[f64; 2]> {
    let total: f64 = columns.iter().sum();
    if total <= 0.0 {
        return None;
    }
    // Cumulative area left of position x (piecewise linear).
    let mut prefix = Vec::with_capacity(columns.len() + 1);
    prefix.push(0.0);
    for c in columns {
        prefix.push(prefix.last().copied().unwrap_or(0.0) + c);
    }
    let n = columns.len() as f64;
    let area_left_of = |x: f64| {
        let s = ((x - left) / cell).clamp(0.0, n);
        let i = (s.floor() as usize).min(columns.len() - 1);
        prefix[i] + columns[i] * (s - i as f64)
    };
    let solve = |target: f64, f: &dyn Fn(f64) -> f64, lo: f64, hi: f64| {
        let (mut lo, mut hi) = (lo, hi);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if f(mid) < target { lo = mid } else { hi = mid }
        }
        0.5 * (lo + hi)
    };
    let width = n * cell;
    let median = solve(total / 2.0, &area_left_of, left, left + width);
    let hidden = |half: f64| area_left_of(median + half) - area_left_of(median - half);
    let half = solve(fraction * total, &hidden, 0.0, width);
    Some([median - half, median + half])
}

/// ChaCha stream of the bookshelf (frame noise uses streams from 2³²).
const BOOKSHELF_STREAM: u64 = 1;
/// Grey of the wall around the bookcase.
const WALL_GREY: f32 = 150.0;
/// Grey of the bookcase's uprights and shelf boards.
const SHELF_GREY: f32 = 62.0;
/// Range of book-spine greys (the target's faces lie mostly outside it).
const BOOK_GREYS: std::ops::Range<f32> = 25.0..175.0;

/// Draw the bookshelf of the module docs into a new canvas (same seed, same image).
fn render_bookshelf(seed: u64) -> Result<Canvas> {
    let mut canvas = Canvas::new(WIDTH, HEIGHT, DEFAULT_SUPERSAMPLE, WALL_GREY)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(BOOKSHELF_STREAM);
    let (w, h) = (WIDTH as f64, HEIGHT as f64);
    let rect = |x0: f64, y0: f64, x1: f64, y1: f64| [[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
    // The bookcase: uprights at 4 % and 96 % of the width, shelf boards every ~95 px.
    let (left, right) = (0.04 * w, 0.96 * w);
    let upright = 14.0;
    let board = 9.0;
    let pitch = 95.3;
    canvas.fill_polygon(&rect(left, -1.0, right, h + 1.0), FillRule::NonZero, 70.0);
    let mut top = 6.4;
    while top < h {
        let bottom = (top + pitch - board).min(h + 1.0);
        // Books standing on the board below, left to right.
        let mut x = left + upright + rng.random_range(0.0..4.0);
        while x < right - upright - 4.0 {
            let width = rng.random_range(5.0f64..22.0).min(right - upright - x);
            if rng.random_bool(0.08) {
                x += width; // a gap
                continue;
            }
            let height = (bottom - top) * rng.random_range(0.55..0.92);
            let grey = rng.random_range(BOOK_GREYS);
            canvas.fill_polygon(&rect(x, bottom - height, x + width, bottom), FillRule::NonZero, grey);
            if rng.random_bool(0.3) {
                // A label band across the spine.
                let y = bottom - height * rng.random_range(0.3..0.8);
                let band = rng.random_range(3.0..8.0);
                let label = (grey + rng.random_range(40.0..80.0)).min(235.0);
                canvas.fill_polygon(&rect(x + 1.0, y, x + width - 1.0, y + band), FillRule::NonZero, label);
            }
            x += width + rng.random_range(0.0..1.5);
        }
        canvas.fill_polygon(&rect(left, bottom, right, bottom + board), FillRule::NonZero, SHELF_GREY);
        top = bottom + board;
    }
    canvas.fill_polygon(&rect(left, -1.0, left + upright, h + 1.0), FillRule::NonZero, SHELF_GREY);
    canvas.fill_polygon(&rect(right - upright, -1.0, right, h + 1.0), FillRule::NonZero, SHELF_GREY);
    Ok(canvas)
}

/// Render the `target3dof` scene in memory (nothing touches the disk).
pub fn render_target3dof(opts: &Target3dofOptions) -> Result<SyntheticSequence> {
    let scene = Target3dofScene::new(opts)?;
    let background = match opts.background {
        Backdrop::Bookshelf => render_bookshelf(opts.seed)?,
        Backdrop::Shared(kind) => render_background(kind, WIDTH, HEIGHT, DEFAULT_SUPERSAMPLE, opts.seed)?,
    };
    let background_small = background.downsample();
    let noise_sigma = opts.noise_sigma as f32;
    let rendered = (0..opts.frames)
        .into_par_iter()
        .map_init(
            || (background.clone(), FloatImage::new(WIDTH, HEIGHT)),
            |(canvas, smooth), k| -> Result<(GrayImage, Option<[f64; 2]>)> {
                let parts = scene.visible_faces(k);
                let bar = scene.occluder(k)?;
                let bar_outline = bar.map(|[x0, x1]| {
                    let (top, bottom) = (-1.0, HEIGHT as f64);
                    [[x0, top], [x1, top], [x1, bottom], [x0, bottom]]
                });
                // Only the pixels the target and the bar touch differ from the background.
                let moving = parts.iter().flatten().flat_map(|(p, _)| p.iter()).chain(bar_outline.iter().flatten());
                let window = Window::around(moving, TOUCHED_MARGIN_PX, WIDTH, HEIGHT).unwrap_or_default();
                smooth.data_mut().copy_from_slice(background_small.data());
                canvas.copy_window_from(&background, window)?;
                draw_target(canvas, &parts, None);
                if let Some(outline) = &bar_outline {
                    canvas.fill_polygon(outline, FillRule::NonZero, OCCLUDER_GREY);
                }
                canvas.downsample_window_into(smooth, window)?;
                let mut frame = GrayImage::new(WIDTH, HEIGHT);
                add_noise_and_quantise(smooth, noise_sigma, &mut frame_rng(opts.seed, k), &mut frame);
                Ok((frame, bar))
            },
        )
        .collect::<Result<Vec<_>>>()?;
    let (frames, bars): (Vec<GrayImage>, Vec<Option<[f64; 2]>>) = rendered.into_iter().unzip();
    let truth = (0..opts.frames)
        .map(|k| TruthFrame {
            frame: k,
            visible: scene.visible(k).into(),
            pose: Some(scene.pose(k)),
            params: Vec::new(),
            corners: scene.corners(k),
        })
        .collect();
    let init =
        InitState { pose: Some(scene.pose(0)), params: Vec::new(), corners: scene.corners(0), camera_motion: None };
    let occluder_columns: Vec<[f64; 2]> = bars.into_iter().flatten().collect();
    let meta = serde_json::json!({
        "scene": "target3dof",
        "seed": opts.seed,
        "frames": opts.frames,
        "frame_rate_hz": FRAME_RATE_HZ,
        "speed_rad_per_s": opts.speed,
        "speed_definition": "peak |d/dt (t/|t|)| of the line of sight to the object origin (rear-face centre), reached at each crossing of the image centre after the 1 s start",
        "first_peak_s": if opts.shake { None } else { scene.path.first_peak_time() },
        "omega_rad_per_s": scene.path.omega,
        "bearing_amplitude": BEARING_AMPLITUDE,
        "range_m": [MIN_RANGE_M, MAX_RANGE_M],
        "range_period_s": RANGE_PERIOD_S,
        "ramp_s": RAMP_S,
        "yaw_rad": YAW_RAD,
        "pitch_rad": PITCH_RAD,
        "shake": opts.shake,
        "shake_reversal_frames": scene.shake.as_ref().map(|p| p.reversals.clone()),
        "occlude": opts.occlude,
        "occluder": "vertical bar, full image height, centred on the column halving the target's projected area, hiding the occlude fraction of it",
        "occluder_columns": occluder_columns,
        "occluder_grey": OCCLUDER_GREY,
        "noise_sigma": opts.noise_sigma,
        "background": opts.background.name(),
        "supersample": DEFAULT_SUPERSAMPLE,
        "face_greys": scene.greys,
        "note": "a(tau) = A sin(w tau), b(tau) = B sin(2 w tau), Z(tau) = 0.85 (5/0.85)^((1 - cos(2 pi tau / 20))/2); translation (aZ, bZ, Z); rotation fixed; with shake, (a, b) moves in straight runs at |(da, db)/dt| = speed, turned back 180 +- 50 deg at each shake_reversal_frames entry",
    });
    Ok(SyntheticSequence {
        scene: "target3dof".to_string(),
        camera: scene.camera,
        model: scene.model,
        init,
        truth,
        truth_extra: Vec::new(),
        frames,
        rgb_frames: Vec::new(),
        meta,
    })
}
