//! Scene `pendulum`: the experiment of paper 000 §4 — a planar rectangle on a
//! pendulum swinging in the image plane, seen by a 256×242 camera at 60 Hz.
//!
//! # Geometry (output-pixel coordinates, y down)
//!
//! The pivot sits above the image at [`PIVOT`]; the arm of [`ARM_LENGTH_PX`]
//! holds the centre of a [`RECT_SIZE_PX`] rectangle. At arm angle θ (0 =
//! hanging straight down, θ > 0 = swung to the right) the rectangle's centre is
//! `PIVOT + L·(sin θ, cos θ)`. With [`PendulumMotion::Rotating`] (the default,
//! as a real pendulum) the rectangle is fixed to the arm and turns with it; with
//! [`PendulumMotion::Translating`] it hangs on a parallelogram linkage and
//! stays axis-aligned (paper 000 calls its experiment "simple translational
//! velocity"; this option gives that reading). Model vertex order is top-left,
//! top-right, bottom-right, bottom-left of the rectangle at θ = 0.
//!
//! # Motion
//!
//! The pendulum is released from rest at angle A at frame 0 ("released at
//! different heights", paper 000 §4), and swings harmonically (the small-angle
//! solution of θ'' = −(g/L)·sin θ, used as the definition of the motion, so the
//! truth is exact):
//!
//! ```text
//! θ(t) = A·cos(ω·t),   t in frames,   ω = sqrt(g/L) in rad/frame.
//! ```
//!
//! `speed` is the paper's velocity: "the distance that an object feature moves
//! between camera frames", taken at its peak, i.e. for the corner farthest from
//! the pivot (radius r) on the frame pair around the bottom of the swing. We
//! make that pair straddle the bottom symmetrically by choosing ω so that a
//! quarter period is a whole number of frames plus one half: then every bottom
//! pass has θ = ±A·sin(ω/2) on its two frames, the corner moves by the chord
//!
//! ```text
//! speed = 2r·sin(A·sin(ω/2))   ⇒   A = asin(speed / 2r) / sin(ω/2),
//! ```
//!
//! and the largest frame-to-frame corner displacement in the sequence is
//! `speed` exactly (once the sequence reaches the first bottom pass, frame
//! `q + ½` with `q` the quarter period). ω is the physical one of a
//! "seconds pendulum" ([`NATURAL_QUARTER_PERIOD_FRAMES`] = 30.5 frames, period
//! 2.03 s, L = g/ω² ≈ 1.03 m) as long as that needs A ≤ [`MAX_AMPLITUDE_RAD`];
//! faster requests keep A near that limit and shorten the period instead
//! (quarter period rounded down to a whole number plus one half, so A stays ≤
//! the limit). With r = 238.8 px (rotating; 220 px translating) the natural
//! period covers speeds up to about 5.2 px/frame (4.8 translating), so the
//! paper's 1.1, 3.9 and 4.5 swing with it; 16 px/frame swings with a period of
//! 38 frames (34 translating).
//! At every speed up to [`MAX_SPEED`] the rectangle stays at least 6 px inside
//! the frame, jump included.

use rayon::prelude::*;

use super::{
    Background, DEFAULT_SUPERSAMPLE, FillRule, SyntheticSequence, add_noise_and_quantise, check_frames, check_range,
    frame_rng, parse_option, render_background,
};
use crate::image::{FloatImage, GrayImage};
use crate::io::formats::{Camera, InitState, Model, TruthFrame};
use crate::{Error, Result};

/// Frame width in pixels (paper 000: 242×256 PIPE frames).
pub const WIDTH: usize = 256;
/// Frame height in pixels.
pub const HEIGHT: usize = 242;
/// Frame rate of the sequence (paper 000: 60 Hz).
pub const FRAME_RATE_HZ: f64 = 60.0;
/// Focal length written to `camera.json`, pixels.
pub const FOCAL_PX: f64 = 300.0;
/// Pivot of the pendulum, output-pixel coordinates (above the image).
pub const PIVOT: [f64; 2] = [127.5, -100.0];
/// Distance from the pivot to the centre of the rectangle, pixels.
pub const ARM_LENGTH_PX: f64 = 220.0;
/// Width and height of the rectangle, pixels.
pub const RECT_SIZE_PX: [f64; 2] = [50.0, 35.0];
/// Largest swing amplitude, radians (keeps the rectangle inside the frame).
pub const MAX_AMPLITUDE_RAD: f64 = 0.42;
/// Quarter period of the natural swing, frames (a whole number plus one half).
pub const NATURAL_QUARTER_PERIOD_FRAMES: f64 = 30.5;
/// Largest `speed` accepted, pixels per frame.
pub const MAX_SPEED: f64 = 32.0;
/// Largest `noise_sigma` accepted, grey levels.
pub const MAX_NOISE_SIGMA: f64 = 64.0;
/// Longest sequence accepted, frames (all frames are held in memory).
pub const MAX_FRAMES: usize = 20_000;
/// How far the object teleports at `jump_at`, pixels (x, y): 80 px down.
pub const JUMP_OFFSET_PX: [f64; 2] = [0.0, 80.0];
/// Grey level of the rectangle.
pub const TARGET_GREY: f32 = 215.0;
/// Grey level of the distractor.
pub const DISTRACTOR_GREY: f32 = 35.0;
/// Circumradius of the distractor (a turning hexagon), pixels.
pub const DISTRACTOR_RADIUS_PX: f64 = 13.0;
/// Default row of the distractor's centre: above every position of the
/// rectangle.
pub const DISTRACTOR_Y: f64 = 30.0;
/// Turning rate of the distractor, radians per frame.
pub const DISTRACTOR_SPIN: f64 = 0.04;

/// How the rectangle hangs on the arm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PendulumMotion {
    /// Fixed to the arm: it turns by θ as the pendulum swings (default).
    #[default]
    Rotating,
    /// On a parallelogram linkage: it follows the arm's end but stays axis-aligned.
    Translating,
}

impl std::str::FromStr for PendulumMotion {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s {
            "rotating" => Ok(PendulumMotion::Rotating),
            "translating" => Ok(PendulumMotion::Translating),
            _ => Err(Error::Parameter(format!("unknown pendulum motion '{s}' (known: rotating, translating)"))),
        }
    }
}

impl PendulumMotion {
    /// The lowercase name of this motion.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            PendulumMotion::Rotating => "rotating",
            PendulumMotion::Translating => "translating",
        }
    }
}

/// Options of the `pendulum` scene.
#[derive(Clone, Debug, PartialEq)]
pub struct PendulumOptions {
    /// Number of frames (default 200, as each data set of paper 000).
    pub frames: usize,
    /// Seed of the background and the pixel noise.
    pub seed: u64,
    /// Peak image speed of the corners, pixels per frame (default 3.9; the
    /// paper tests 1.1, 3.9 and 4.5). `0 ..= MAX_SPEED`.
    pub speed: f64,
    /// Standard deviation of the Gaussian pixel noise, grey levels (default 2).
    pub noise_sigma: f64,
    /// Static backdrop (default textured).
    pub background: Background,
    /// Add a dark turning hexagon that crosses the frame once, left to right,
    /// behind the rectangle (default false).
    pub distractor: bool,
    /// Row of the distractor's centre, px (default [`DISTRACTOR_Y`], above
    /// every position of the rectangle; a row nearer the rectangle brings the
    /// hexagon's edges near the model lines). `0 ..= HEIGHT`.
    pub distractor_y: f64,
    /// From this frame on, the object is [`JUMP_OFFSET_PX`] away and swings
    /// there (the tracker should report `lost`). `1 ..frames`.
    pub jump_at: Option<usize>,
    /// Rotating with the arm (default) or axis-aligned.
    pub motion: PendulumMotion,
}

impl Default for PendulumOptions {
    fn default() -> Self {
        Self {
            frames: 200,
            seed: 0,
            speed: 3.9,
            noise_sigma: 2.0,
            background: Background::Textured,
            distractor: false,
            distractor_y: DISTRACTOR_Y,
            jump_at: None,
            motion: PendulumMotion::Rotating,
        }
    }
}

impl PendulumOptions {
    /// Keys [`PendulumOptions::set`] accepts.
    pub const KEYS: [&'static str; 7] =
        ["speed", "noise", "background", "distractor", "distractor_y", "jump_at", "motion"];

    /// Set one option from strings (for the command line): `speed` (px/frame),
    /// `noise` (σ, grey levels), `background` (flat|textured|cluttered),
    /// `distractor` (true|false), `distractor_y` (row, px), `jump_at` (frame), `motion`
    /// (rotating|translating). Range checks happen in [`render_pendulum`].
    pub fn set(&mut self, key: &str, value: &str) -> Result<()> {
        let number = "a number";
        match key {
            "speed" => self.speed = parse_option("pendulum", key, value, number)?,
            "noise" | "noise_sigma" => self.noise_sigma = parse_option("pendulum", key, value, number)?,
            "background" => self.background = value.parse()?,
            "distractor" => self.distractor = parse_option("pendulum", key, value, "true or false")?,
            "distractor_y" => self.distractor_y = parse_option("pendulum", key, value, number)?,
            "jump_at" => self.jump_at = Some(parse_option("pendulum", key, value, "a frame index")?),
            "motion" => self.motion = value.parse()?,
            _ => return Err(super::no_such_option("pendulum", key, &Self::KEYS)),
        }
        Ok(())
    }

    /// Error unless every option is in its documented range.
    pub fn validate(&self) -> Result<()> {
        check_frames(self.frames, MAX_FRAMES)?;
        check_range("speed", self.speed, MAX_SPEED, " px/frame")?;
        check_range("noise sigma", self.noise_sigma, MAX_NOISE_SIGMA, "")?;
        check_range("distractor_y", self.distractor_y, HEIGHT as f64, " px")?;
        if let Some(j) = self.jump_at
            && !(1..self.frames).contains(&j)
        {
            return Err(Error::Parameter(format!("jump_at = {j} is not in 1..{} (frames)", self.frames)));
        }
        Ok(())
    }
}

/// The swing that realises a requested peak corner speed (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PendulumSwing {
    /// Amplitude A, radians (the release angle at frame 0).
    pub amplitude_rad: f64,
    /// Angular frequency ω, radians per frame.
    pub omega_rad_per_frame: f64,
    /// How the rectangle hangs.
    pub motion: PendulumMotion,
    /// Frame from which the object is moved by [`JUMP_OFFSET_PX`].
    pub jump_at: Option<usize>,
}

impl PendulumSwing {
    /// The swing whose peak frame-to-frame corner displacement is `speed`
    /// pixels. Errors when `speed` is not in `0..=MAX_SPEED`.
    pub fn new(speed: f64, motion: PendulumMotion, jump_at: Option<usize>) -> Result<Self> {
        super::check_range("speed", speed, MAX_SPEED, " px/frame")?;
        // A·sin(ω/2) = asin(speed / 2r): half the arm angle swept across the bottom.
        let half_sweep = (speed / (2.0 * Self::corner_radius(motion))).asin();
        let amplitude = |quarter: f64| half_sweep / (omega_of(quarter) / 2.0).sin();
        let mut quarter = NATURAL_QUARTER_PERIOD_FRAMES;
        if amplitude(quarter) > MAX_AMPLITUDE_RAD {
            // Shortest period with A = MAX_AMPLITUDE_RAD, rounded to k + ½ frames (down, so A shrinks).
            let omega_needed = 2.0 * (half_sweep / MAX_AMPLITUDE_RAD).min(1.0).asin();
            quarter = ((std::f64::consts::FRAC_PI_2 / omega_needed - 0.5).floor() + 0.5).max(1.5);
        }
        let amplitude_rad = amplitude(quarter);
        if amplitude_rad > MAX_AMPLITUDE_RAD + 1e-12 {
            return Err(Error::Parameter(format!(
                "speed = {} px/frame cannot be reached",
                crate::bounds::short_number(speed)
            )));
        }
        Ok(Self { amplitude_rad, omega_rad_per_frame: omega_of(quarter), motion, jump_at })
    }

    /// Distance from the pivot of the fastest corner: the bottom corners when
    /// rotating, the arm length when translating (all corners move alike).
    #[must_use]
    pub fn corner_radius(motion: PendulumMotion) -> f64 {
        match motion {
            PendulumMotion::Rotating => (ARM_LENGTH_PX + RECT_SIZE_PX[1] / 2.0).hypot(RECT_SIZE_PX[0] / 2.0),
            PendulumMotion::Translating => ARM_LENGTH_PX,
        }
    }

    /// Swing period, frames.
    #[must_use]
    pub fn period_frames(&self) -> f64 {
        std::f64::consts::TAU / self.omega_rad_per_frame
    }

    /// Arm angle θ(t) = A·cos(ω·t) at frame `frame`, radians.
    #[must_use]
    pub fn angle(&self, frame: usize) -> f64 {
        self.amplitude_rad * (self.omega_rad_per_frame * frame as f64).cos()
    }

    /// Image positions of the four rectangle corners at frame `frame`, in model
    /// vertex order (top-left, top-right, bottom-right, bottom-left at θ = 0).
    #[must_use]
    pub fn corners(&self, frame: usize) -> [[f64; 2]; 4] {
        let theta = self.angle(frame);
        let (s, c) = theta.sin_cos();
        let jump = if self.jump_at.is_some_and(|j| frame >= j) { JUMP_OFFSET_PX } else { [0.0; 2] };
        let centre = [PIVOT[0] + ARM_LENGTH_PX * s + jump[0], PIVOT[1] + ARM_LENGTH_PX * c + jump[1]];
        // Rectangle axes in the image: along the arm's perpendicular and along the arm.
        let (x_axis, y_axis) = match self.motion {
            PendulumMotion::Rotating => ([c, -s], [s, c]),
            PendulumMotion::Translating => ([1.0, 0.0], [0.0, 1.0]),
        };
        let [hw, hh] = [RECT_SIZE_PX[0] / 2.0, RECT_SIZE_PX[1] / 2.0];
        [[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]]
            .map(|[u, v]| [centre[0] + u * x_axis[0] + v * y_axis[0], centre[1] + u * x_axis[1] + v * y_axis[1]])
    }
}

/// ω of a swing whose quarter period is `quarter` frames.
fn omega_of(quarter: f64) -> f64 {
    std::f64::consts::FRAC_PI_2 / quarter
}

/// `camera.json` of the scene: fx = fy = 300, principal point at the image centre.
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

/// `model.json` of the scene: the rectangle in its own pixel units (z = 0),
/// vertices top-left, top-right, bottom-right, bottom-left, one face listed
/// counter-clockwise as seen by the camera.
#[must_use]
pub fn model() -> Model {
    let [hw, hh] = [RECT_SIZE_PX[0] / 2.0, RECT_SIZE_PX[1] / 2.0];
    Model {
        name: "pendulum-rectangle".to_string(),
        units: "px".to_string(),
        vertices: vec![[-hw, -hh, 0.0], [hw, -hh, 0.0], [hw, hh, 0.0], [-hw, hh, 0.0]],
        edges: vec![[0, 1], [1, 2], [2, 3], [3, 0]],
        faces: vec![vec![0, 3, 2, 1]],
        joints: Vec::new(),
    }
}

/// Where the distractor hexagon centred on row `y` is at frame `frame` of
/// `frames`: it enters at the left edge at frame 0 and leaves at the right
/// edge on the last frame.
fn distractor_polygon(y: f64, frame: usize, frames: usize) -> Vec<[f64; 2]> {
    let r = DISTRACTOR_RADIUS_PX;
    let travel = WIDTH as f64 + 2.0 * r + 4.0;
    let x = -r - 2.0 + travel * frame as f64 / (frames.max(2) - 1) as f64;
    let spin = DISTRACTOR_SPIN * frame as f64;
    super::ellipse_points([x, y], [r, r], spin, 6)
}

/// Render the `pendulum` scene in memory (nothing touches the disk).
pub fn render_pendulum(opts: &PendulumOptions) -> Result<SyntheticSequence> {
    opts.validate()?;
    let swing = PendulumSwing::new(opts.speed, opts.motion, opts.jump_at)?;
    let background = render_background(opts.background, WIDTH, HEIGHT, DEFAULT_SUPERSAMPLE, opts.seed)?;
    let background_small = background.downsample();
    let noise_sigma = opts.noise_sigma as f32;
    let frames = (0..opts.frames)
        .into_par_iter()
        .map_init(
            || (background.clone(), FloatImage::new(WIDTH, HEIGHT)),
            |(canvas, smooth), k| -> Result<GrayImage> {
                let target = swing.corners(k);
                let distractor = opts.distractor.then(|| distractor_polygon(opts.distractor_y, k, opts.frames));
                // Only the pixels the moving shapes touch differ from the background.
                let moving = target.iter().chain(distractor.iter().flatten());
                let window = canvas.window_around(moving);
                smooth.data_mut().copy_from_slice(background_small.data());
                canvas.copy_window_from(&background, window)?;
                if let Some(hexagon) = &distractor {
                    canvas.fill_polygon(hexagon, FillRule::EvenOdd, DISTRACTOR_GREY);
                }
                canvas.fill_polygon(&target, FillRule::EvenOdd, TARGET_GREY);
                canvas.downsample_window_into(smooth, window)?;
                let mut frame = GrayImage::new(WIDTH, HEIGHT);
                add_noise_and_quantise(smooth, noise_sigma, &mut frame_rng(opts.seed, k), &mut frame);
                Ok(frame)
            },
        )
        .collect::<Result<Vec<_>>>()?;
    let truth = (0..opts.frames)
        .map(|k| TruthFrame {
            frame: k,
            visible: true.into(),
            pose: None,
            params: Vec::new(),
            corners: swing.corners(k).to_vec(),
        })
        .collect();
    let init = InitState { pose: None, params: Vec::new(), corners: swing.corners(0).to_vec(), camera_motion: None };
    let meta = serde_json::json!({
        "scene": "pendulum",
        "seed": opts.seed,
        "frames": opts.frames,
        "frame_rate_hz": FRAME_RATE_HZ,
        "speed_px_per_frame": opts.speed,
        "noise_sigma": opts.noise_sigma,
        "background": opts.background.name(),
        "distractor": opts.distractor,
        "distractor_y": opts.distractor_y,
        "jump_at": opts.jump_at,
        "jump_offset_px": JUMP_OFFSET_PX,
        "motion": opts.motion.name(),
        "pivot_px": PIVOT,
        "arm_length_px": ARM_LENGTH_PX,
        "rectangle_px": RECT_SIZE_PX,
        "amplitude_rad": swing.amplitude_rad,
        "omega_rad_per_frame": swing.omega_rad_per_frame,
        "period_frames": swing.period_frames(),
        "supersample": DEFAULT_SUPERSAMPLE,
        "target_grey": TARGET_GREY,
        "note": "theta(t) = A cos(omega t), released from rest at frame 0; corners exact, pixel (0,0) = centre of the top-left pixel",
    });
    Ok(SyntheticSequence {
        scene: "pendulum".to_string(),
        camera: camera(),
        model: model(),
        init,
        truth,
        truth_extra: Vec::new(),
        frames,
        rgb_frames: Vec::new(),
        meta,
    })
}
