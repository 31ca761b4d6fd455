//! Scenes `box` and `hinged-box`: the experiment of paper 001 — a file box,
//! rigid or with a hinged lid, turning and moving in all six degrees of
//! freedom in front of a cluttered background, sometimes partly hidden by an
//! occluder, seen by a 640×480 grey camera at 30 Hz.
//!
//! # Camera
//!
//! 640×480, fx = fy = [`FOCAL_PX`] = 550 px, principal point at the image
//! centre (319.5, 239.5), [`FRAME_RATE_HZ`] = 30.
//!
//! # Model (`model.json`, metres; object frame x right, y down, z away from the camera)
//!
//! The origin is the centre of the closed box, [`BOX_SIZE`] = 0.30 × 0.15 ×
//! 0.20 m (w × h × d along x, y, z); its front face (z = −d/2) faces the
//! camera at the nominal pose and its top face is at y = −h/2. Every part is
//! a cuboid listed as 8 vertices — the front face (z = z_lo) top-left,
//! top-right, bottom-right, bottom-left (left = −x, top = −y), then the back
//! face (z = z_hi) in the same order — and 6 faces, counter-clockwise seen
//! from outside, in the order front (−z), back (+z), top (−y), bottom (+y),
//! left (−x), right (+x). Edges are the undirected face sides, each once.
//!
//! - `box`: one cuboid, vertices 0–7, x ∈ ±0.15, y ∈ ±0.075, z ∈ ±0.10. No joints.
//! - `hinged-box`: the body, vertices 0–7, y from −0.065 to 0.075 (0.14 m
//!   high), and the lid, vertices 8–15, a slab [`LID_THICKNESS`] = 1 cm
//!   thick lying on it (y from −0.075 to −0.065) when closed. One joint,
//!   `lid`, moves vertices 8–15 about the hinge: the axis −x through
//!   (0, −0.065, 0.10), the lid's bottom back edge, which is also the body's
//!   top back edge; q = 0 is closed and q > 0 lifts the front edge
//!   (towards −y); limits [`LID_MIN_RAD`] = 0 and [`LID_MAX_RAD`] = 1.9.
//!   Vertices 8–15 are listed at q = 0.
//!
//! # Motion
//!
//! A fixed closed path in *path time* τ, periodic in 2π; the seed picks the
//! phases φ of its seven terms (and nothing about their ranges):
//!
//! ```text
//! yaw   = 0.50 + 0.40·sin(3τ + φ₁)     pitch = 0.50 + 0.25·sin(2τ + φ₂)
//! roll  =        0.30·sin(4τ + φ₃)     R = Rz(roll)·Rx(pitch)·Ry(yaw)   (camera axes)
//! Z     = 1.20 + 0.20·sin(τ + φ₆)  m   t = (a·Z, b·Z, Z)
//! a     =        0.14·sin(2τ + φ₄)     b = 0.06 + 0.06·sin(3τ + φ₅)
//! q     = 0.95 + 0.75·sin(2τ + φ₇)     (lid, hinged-box only: 0.2 … 1.7 rad)
//! ```
//!
//! At the nominal pose the camera sees the front, the top and the right side
//! (pitch and yaw tip the top and the right side towards it). Every model
//! vertex stays inside the image for every phase (the unit tests check the
//! extremes of all seven terms on a grid).
//!
//! **Speed.** `speed` V is the image motion of the fastest model vertex
//! (hidden ones included) between consecutive frames, in px/frame. The path
//! is walked so that this displacement is *exactly* V·g(k) from frame k to
//! k + 1, with g rising smoothly from 0 to 1 over the first [`RAMP_FRAMES`]
//! frames (g(k) = smoothstep((k + ½)/15), a start from rest) and 1 after:
//! each step Δτ is solved by bisection. So the peak is V and every frame
//! after the start moves that fast. The path's shape does not depend on V;
//! a faster sequence covers more of it (at the default 4 px/frame, 300 frames
//! cover about three quarters of a period; at 30 px/frame, several). How much
//! of V is rotation: a pure turn by θ about the box centre moves the farthest
//! vertex by about 90·θ px at 1.2 m, so the box turns by at most about
//! 0.7·V degrees per frame; measured peaks over 300 frames (seed 3) are 3.0°
//! and 20.6° per frame for `box` at V = 4 and 30, 1.8° and 12.5° for
//! `hinged-box`, whose lid takes part of the motion (`meta.json` gives the
////! `peak_rotation_deg_per_frame` of each sequence).
//!
//! # Occluders
//!
//! `occlude` = f in 0..=[`MAX_OCCLUDE`] (default 0: none) hides the fraction
//! f of the visible model edge length during *occluded stretches*: after
//! 30–60 unoccluded frames, stretches of 30–60 frames with an occluder
//! alternate with 30–60 frames without (lengths seeded). The occluder is an
//! opaque straight band ([`OCCLUDER_GREY`], flat, crossing the whole image)
//! at a seeded angle per stretch. Its centre line sweeps across the object
//! during the stretch (from −0.4 to +0.4 of the visible edges' half extent
//! across the band, about their length-weighted centroid), and its width is
//! solved per frame (bisection on the exact hidden length) so that it hides
//! the fraction f of the visible edge length. `truth.jsonl` carries that
//! fraction as `occluded_fraction` (0 outside the stretches) and `meta.json`
//! the band of every frame.
//!
//! *Visible edge length*: the image length of the parts of model edges that
//! border a face facing the camera and are not hidden by the other part of
//! the model (the open lid over the body, or the body over the lid). A vertex
//! is `visible` in the truth when it is in front of the camera, inside the
//! image, on a face facing the camera, not strictly inside the image of the
//! other part when that part is nearer, and not strictly inside the band.
//!
//! # Rendering
//!
//! **Visibility by a painter's order that is exact for these shapes.** The
//! body and the lid are convex, so each part's faces that face the camera
//! never overlap in the image: each part is drawn as one layer (back faces
//! culled). The two parts are disjoint convex sets (they touch along the
//! hinge, and along the lid's bottom face when it is closed), separated by a
//! plane through the hinge: the plane of the lid's bottom face for q ≤ π/2,
//! the body's back face plane for q ≥ π/2 (the body lies in y ≥ y_h, z ≤ z_h
//! relative to the hinge, the lid in the wedge its bottom face sweeps). A ray
//! from a camera on the lid's side of that plane meets every point of the lid
//! before crossing the plane and every point of the body after, so the body
//! can never hide the lid: draw the body, then the lid; the other way round
//! for a camera on the body's side ([`BoxScene::lid_is_nearer`]). The
//! occluder band is drawn last.
//!
//! **Shading.** Each face has an albedo ([`face_albedos`]) from the levels
//! 45, 90, 150, 228, and is shaded Lambertian from a light fixed in the camera
//! frame ([`LIGHT_DIRECTION`]): grey = albedo·(A + (1 − A)·max(0, n·l)) with
//! ambient A = [`AMBIENT`] = 0.75. Faces that share an edge (and the closed
//! lid's sides and the body sides under them, and the lid's underside and the
//! body's top) have different levels, chosen so that
//! `0.75·brighter − darker ≥ 20`: their greys differ by at least 20 levels in
//! any pose. **Texture**: five seeded low-contrast elliptic blobs per face
//! larger than 5 cm (albedo ± 3–6), each at least 8 % of the face's size away
//! from its sides, so no straight edge lies inside a face and every model edge
//! keeps its full contrast.
//!
//! The background ([`Background::Cluttered`] by default: rectangles, lines
//! and blobs with strong straight edges) is drawn once at
//! [`DEFAULT_SUPERSAMPLE`]× resolution; per frame only the window the box and
//! the band touch is redrawn with the exact-coverage rasteriser and box
//! filtered (anti-aliased, sub-pixel accurate edges). Gaussian noise of
//! σ = `noise` grey levels (default 2) is added from the frame's own seeded
//! stream and values are rounded to 8 bits.

use std::f64::consts::FRAC_PI_2;
use std::ops::Range;

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
use crate::io::formats::{Camera, InitState, Joint, Model, Pose, TruthFrame, Visibility};
use crate::{Error, Result};

/// Frame width in pixels.
pub const WIDTH: usize = 640;
/// Frame height in pixels.
pub const HEIGHT: usize = 480;
/// Frame rate, Hz.
pub const FRAME_RATE_HZ: f64 = 30.0;
/// Focal length fx = fy, pixels.
pub const FOCAL_PX: f64 = 550.0;
/// Width (x), height (y) and depth (z) of the closed box, metres.
pub const BOX_SIZE: [f64; 3] = [0.30, 0.15, 0.20];
/// Thickness of the lid of `hinged-box`, metres.
pub const LID_THICKNESS: f64 = 0.01;
/// Lower limit of the lid joint (closed), radians.
pub const LID_MIN_RAD: f64 = 0.0;
/// Upper limit of the lid joint, radians.
pub const LID_MAX_RAD: f64 = 1.9;
/// Range of the lid angle along the path, radians.
pub const LID_PATH_RANGE: [f64; 2] = [0.2, 1.7];
/// Default peak image speed of the vertices, px/frame.
pub const DEFAULT_SPEED: f64 = 4.0;
/// Largest `speed` accepted, px/frame.
pub const MAX_SPEED: f64 = 50.0;
/// Largest `occlude` fraction accepted (half of the visible edge length).
pub const MAX_OCCLUDE: f64 = 0.5;
/// Largest `noise` σ accepted, grey levels.
pub const MAX_NOISE_SIGMA: f64 = 64.0;
/// Longest sequence accepted, frames (all frames are held in memory).
pub const MAX_FRAMES: usize = 20_000;
/// Frames of the smooth start from rest.
pub const RAMP_FRAMES: usize = 15;
/// Grey level of the occluder band.
pub const OCCLUDER_GREY: f32 = 165.0;
/// Lengths (frames) of the occluded and unoccluded stretches.
pub const STRETCH_FRAMES: Range<usize> = 30..61;
/// Ambient share of the shading.
pub const AMBIENT: f64 = 0.75;
/// Direction towards the light in the camera frame (up, left, towards the camera; normalised on use).
pub const LIGHT_DIRECTION: [f64; 3] = [-0.35, -0.6, -0.72];

/// Mean yaw, pitch; amplitudes of yaw, pitch, roll (radians).
const ROTATION_PATH: [f64; 5] = [0.50, 0.50, 0.40, 0.25, 0.30];
/// Mean range and its amplitude (m); bearing amplitude in x; mean and amplitude of the bearing in y.
const TRANSLATION_PATH: [f64; 5] = [1.20, 0.20, 0.14, 0.06, 0.06];
/// Frequencies (multiples of τ) of yaw, pitch, roll, a, b, Z, lid.
const PATH_FREQUENCIES: [f64; 7] = [3.0, 2.0, 4.0, 2.0, 3.0, 1.0, 2.0];
/// Albedo levels: any brighter level times [`AMBIENT`] exceeds a darker one by ≥ 20.
const LEVELS: [f32; 4] = [45.0, 90.0, 150.0, 228.0];
/// ChaCha streams of the path phases, the texture and the occluders
/// (the background uses stream 0, frame noise streams from 2³²).
const PATH_STREAM: u64 = 11;
const TEXTURE_STREAM: u64 = 12;
const OCCLUDER_STREAM: u64 = 13;
/// Blobs per textured face; faces smaller than [`TEXTURED_FACE_M`] get none.
const BLOBS_PER_FACE: usize = 5;
const TEXTURED_FACE_M: f64 = 0.05;
/// Sides of a blob polygon.
const BLOB_SEGMENTS: usize = 32;
/// Margin of [`Window::around`] for the pixels polygons touch.
const TOUCHED_MARGIN_PX: f64 = 0.5;
/// Half length of the occluder band's polygon, px (beyond every image corner).
const BAND_HALF_LENGTH_PX: f64 = 2000.0;

/// Which of the two scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BoxKind {
    /// `box`: one rigid cuboid.
    #[default]
    Rigid,
    /// `hinged-box`: body and lid on a hinge (one joint).
    Hinged,
}

impl BoxKind {
    /// The scene name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            BoxKind::Rigid => "box",
            BoxKind::Hinged => "hinged-box",
        }
    }
}

/// Options of the `box` and `hinged-box` scenes.
#[derive(Clone, Debug, PartialEq)]
pub struct BoxOptions {
    /// Rigid box or hinged lid.
    pub kind: BoxKind,
    /// Number of frames (default 300).
    pub frames: usize,
    /// Seed of the path phases, textures, background, occluders and noise.
    pub seed: u64,
    /// Image motion of the fastest vertex per frame after the start, px/frame
    /// (default 4). `0 ..= MAX_SPEED`.
    pub speed: f64,
    /// Fraction of the visible edge length hidden during occluded stretches
    /// (default 0: no occluder). `0 ..= MAX_OCCLUDE`.
    pub occlude: f64,
    /// Standard deviation of the Gaussian pixel noise, grey levels (default 2).
    pub noise_sigma: f64,
    /// Backdrop (default cluttered).
    pub background: Background,
}

impl Default for BoxOptions {
    fn default() -> Self {
        Self {
            kind: BoxKind::Rigid,
            frames: 300,
            seed: 0,
            speed: DEFAULT_SPEED,
            occlude: 0.0,
            noise_sigma: 2.0,
            background: Background::Cluttered,
        }
    }
}

impl BoxOptions {
    /// Keys [`BoxOptions::set`] accepts.
    pub const KEYS: [&'static str; 4] = ["speed", "occlude", "noise", "background"];

    /// Set one option from strings (for the command line): `speed`
    /// (px/frame), `occlude` (fraction 0–0.5), `noise` (σ, grey levels),
    /// `background` (flat|textured|cluttered). Range checks happen in
    /// [`BoxOptions::validate`].
    pub fn set(&mut self, key: &str, value: &str) -> Result<()> {
        let scene = self.kind.name();
        let number = "a number";
        match key {
            "speed" => self.speed = parse_option(scene, key, value, number)?,
            "occlude" => self.occlude = parse_option(scene, key, value, number)?,
            "noise" | "noise_sigma" => self.noise_sigma = parse_option(scene, key, value, number)?,
            "background" => self.background = value.parse()?,
            _ => return Err(super::no_such_option(scene, key, &Self::KEYS)),
        }
        Ok(())
    }

    /// Error unless every option is in its documented range.
    pub fn validate(&self) -> Result<()> {
        check_frames(self.frames, MAX_FRAMES)?;
        check_range("speed", self.speed, MAX_SPEED, " px/frame")?;
        check_range("occlude", self.occlude, MAX_OCCLUDE, "")?;
        check_range("noise sigma", self.noise_sigma, MAX_NOISE_SIGMA, "")
    }
}

/// `camera.json` of the scenes: 640×480, fx = fy = 550, principal point at the centre.
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

/// Append the cuboid `lo`..`hi` (vertex and face order of the module docs).
fn add_cuboid(vertices: &mut Vec<[f64; 3]>, faces: &mut Vec<Vec<usize>>, lo: [f64; 3], hi: [f64; 3]) {
    let b = vertices.len();
    for z in [lo[2], hi[2]] {
        for [x, y] in [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]] {
            vertices.push([x, y, z]);
        }
    }
    let (tl, tr, br, bl) = (b, b + 1, b + 2, b + 3);
    let (btl, btr, bbr, bbl) = (b + 4, b + 5, b + 6, b + 7);
    faces.extend([
        vec![tl, bl, br, tr],
        vec![btl, btr, bbr, bbl],
        vec![tl, tr, btr, btl],
        vec![bl, bbl, bbr, br],
        vec![tl, btl, bbl, bl],
        vec![tr, br, bbr, btr],
    ]);
}

/// Height (y) of the hinge and of the body's top face, object frame.
fn hinge_y(kind: BoxKind) -> f64 {
    match kind {
        BoxKind::Rigid => -BOX_SIZE[1] / 2.0,
        BoxKind::Hinged => -BOX_SIZE[1] / 2.0 + LID_THICKNESS,
    }
}

/// The hinge: a point on the axis (the body's top back edge) and the axis direction.
#[must_use]
pub fn hinge(kind: BoxKind) -> (DVec3, DVec3) {
    (DVec3::new(0.0, hinge_y(kind), BOX_SIZE[2] / 2.0), DVec3::NEG_X)
}

/// `model.json` of a scene (see the module docs for the vertex order).
#[must_use]
pub fn model(kind: BoxKind) -> Model {
    let [w, h, d] = BOX_SIZE;
    let (mut vertices, mut faces) = (Vec::new(), Vec::new());
    let top = hinge_y(kind);
    add_cuboid(&mut vertices, &mut faces, [-w / 2.0, top, -d / 2.0], [w / 2.0, h / 2.0, d / 2.0]);
    let mut joints = Vec::new();
    if kind == BoxKind::Hinged {
        add_cuboid(&mut vertices, &mut faces, [-w / 2.0, -h / 2.0, -d / 2.0], [w / 2.0, top, d / 2.0]);
        let (origin, axis) = hinge(kind);
        joints.push(Joint {
            name: "lid".to_string(),
            origin: origin.to_array(),
            axis: axis.to_array(),
            vertices: (8..16).collect(),
            min: LID_MIN_RAD,
            max: LID_MAX_RAD,
        });
    }
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
    Model { name: kind.name().to_string(), units: "m".to_string(), vertices, edges, faces, joints }
}

/// Albedo of every face of [`model`], in the order of its faces (module docs).
#[must_use]
pub fn face_albedos(kind: BoxKind) -> Vec<f32> {
    let [l1, l2, l3, l4] = LEVELS;
    // front, back, top, bottom, left, right
    let mut albedos = vec![l3, l3, l4, l4, l1, l1];
    if kind == BoxKind::Hinged {
        albedos.extend([l2, l2, l3, l1, l4, l4]);
    }
    albedos
}

/// Faces of the body.
const BODY_FACES: Range<usize> = 0..6;
/// Faces of the lid (hinged-box).
const LID_FACES: Range<usize> = 6..12;

/// The face index ranges of the parts: the body, then the lid.
fn part_faces(kind: BoxKind) -> Vec<Range<usize>> {
    match kind {
        BoxKind::Rigid => vec![BODY_FACES],
        BoxKind::Hinged => vec![BODY_FACES, LID_FACES],
    }
}

/// Pairs of faces that must differ in grey (they share an edge, or touch in
/// the image when the lid is closed or open): the module docs' contrast rule.
#[must_use]
pub fn neighbouring_faces(kind: BoxKind) -> Vec<[usize; 2]> {
    let m = model(kind);
    let mut pairs = Vec::new();
    for a in 0..m.faces.len() {
        for b in a + 1..m.faces.len() {
            let shared = m.faces[a].iter().filter(|v| m.faces[b].contains(v)).count();
            if shared >= 2 {
                pairs.push([a, b]);
            }
        }
    }
    if kind == BoxKind::Hinged {
        // Closed lid's sides over the body's sides; the lid's underside and the body's top.
        pairs.extend([[0, 6], [1, 7], [4, 10], [5, 11], [2, 9]]);
    }
    pairs
}

/// The seeded path of the module docs: rotation, translation and lid angle at path time τ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxPath {
    /// Phases φ₁ … φ₇ of yaw, pitch, roll, a, b, Z, lid.
    pub phases: [f64; 7],
}

impl BoxPath {
    /// The path of sequence seed `seed`.
    #[must_use]
    pub fn new(seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(PATH_STREAM);
        Self { phases: std::array::from_fn(|_| rng.random_range(0.0..std::f64::consts::TAU)) }
    }

    /// The seven terms sin(kᵢτ + φᵢ), each in −1..1.
    fn terms(&self, tau: f64) -> [f64; 7] {
        std::array::from_fn(|i| (PATH_FREQUENCIES[i] * tau + self.phases[i]).sin())
    }

    /// Rotation, translation and lid angle for the seven terms `s` (each in −1..1).
    #[must_use]
    pub fn state_from_terms(s: [f64; 7]) -> (DMat3, DVec3, f64) {
        let [yaw0, pitch0, a_yaw, a_pitch, a_roll] = ROTATION_PATH;
        let [z0, a_z, a_x, b0, a_y] = TRANSLATION_PATH;
        let rotation = DMat3::from_rotation_z(a_roll * s[2])
            * DMat3::from_rotation_x(pitch0 + a_pitch * s[1])
            * DMat3::from_rotation_y(yaw0 + a_yaw * s[0]);
        let z = z0 + a_z * s[5];
        let translation = DVec3::new(a_x * s[3] * z, (b0 + a_y * s[4]) * z, z);
        let [q_lo, q_hi] = LID_PATH_RANGE;
        let lid = (q_lo + q_hi) / 2.0 + (q_hi - q_lo) / 2.0 * s[6];
        (rotation, translation, lid)
    }

    /// Rotation, translation (camera-from-object) and lid angle at path time `tau`.
    #[must_use]
    pub fn state(&self, tau: f64) -> (DMat3, DVec3, f64) {
        Self::state_from_terms(self.terms(tau))
    }
}

/// Smooth start: the share g(k) of the speed between frames k and k + 1.
fn ramp(k: usize) -> f64 {
    let x = ((k as f64 + 0.5) / RAMP_FRAMES as f64).min(1.0);
    x * x * (3.0 - 2.0 * x)
}

/// An occluder band: the points x with |n·(x − centre)| ≤ width/2, where
/// n = (−sin angle, cos angle) is normal to the band's direction (cos angle, sin angle).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Band {
    /// A point on the centre line, pixel coordinates.
    pub centre: [f64; 2],
    /// Direction of the band from +x towards +y, radians.
    pub angle: f64,
    /// Width across the band, px.
    pub width: f64,
}

impl Band {
    /// Unit normal n across the band.
    fn normal(&self) -> [f64; 2] {
        let (s, c) = self.angle.sin_cos();
        [-s, c]
    }

    /// Signed distance of `p` from the centre line, px.
    #[must_use]
    pub fn offset(&self, p: [f64; 2]) -> f64 {
        let n = self.normal();
        n[0] * (p[0] - self.centre[0]) + n[1] * (p[1] - self.centre[1])
    }

    /// Whether `p` lies strictly inside the band.
    #[must_use]
    pub fn hides(&self, p: [f64; 2]) -> bool {
        self.offset(p).abs() < self.width / 2.0
    }

    /// The band as a quadrilateral reaching beyond the image.
    #[must_use]
    pub fn polygon(&self) -> [[f64; 2]; 4] {
        let (s, c) = self.angle.sin_cos();
        let (l, h) = (BAND_HALF_LENGTH_PX, self.width / 2.0);
        let n = [-s, c];
        let at = |a: f64, b: f64| [self.centre[0] + a * c + b * n[0], self.centre[1] + a * s + b * n[1]];
        [at(-l, -h), at(l, -h), at(l, h), at(-l, h)]
    }

    /// Image length of the segment `a`–`b` inside a band of this centre and angle with width `width`.
    fn hidden_length(&self, a: [f64; 2], b: [f64; 2], width: f64) -> f64 {
        let (oa, ob) = (self.offset(a), self.offset(b));
        let length = (b[0] - a[0]).hypot(b[1] - a[1]);
        let h = width / 2.0;
        if oa == ob {
            return if oa.abs() <= h { length } else { 0.0 };
        }
        // Offset along the segment is linear in t: the t-interval with |offset| ≤ h.
        let (t0, t1) = ((-h - oa) / (ob - oa), (h - oa) / (ob - oa));
        let (lo, hi) = (t0.min(t1).max(0.0), t0.max(t1).min(1.0));
        (hi - lo).max(0.0) * length
    }
}

/// What frame k shows, computed from its pose and lid angle.
struct FrameView {
    /// Model vertices in the camera frame.
    camera_vertices: Vec<DVec3>,
    /// Their image positions.
    corners: Vec<[f64; 2]>,
    /// Whether each face faces the camera.
    facing: Vec<bool>,
    /// Whether the lid is nearer than the body (hinged-box only).
    lid_nearer: bool,
}

/// A texture blob: an axis-aligned ellipse in a face's (u, v) coordinates
/// (point = f₀ + u·(f₁ − f₀) + v·(f₃ − f₀) for face loop f₀ f₁ f₂ f₃) and its albedo offset.
#[derive(Clone, Copy, Debug)]
struct Blob {
    centre: [f64; 2],
    radii: [f64; 2],
    offset: f32,
}

/// The scene: options, model, the walked path and the occluders.
#[derive(Clone, Debug)]
pub struct BoxScene {
    /// The options it was made from.
    pub options: BoxOptions,
    /// The seeded path.
    pub path: BoxPath,
    /// `camera.json`.
    pub camera: Camera,
    /// `model.json`.
    pub model: Model,
    geometry: ModelGeometry,
    albedos: Vec<f32>,
    /// Path time of every frame.
    taus: Vec<f64>,
    /// Blobs of every face.
    texture: Vec<Vec<Blob>>,
    /// The occluder band of every frame (None outside occluded stretches).
    bands: Vec<Option<Band>>,
}

impl BoxScene {
    /// The scene for `options` (validated).
    pub fn new(options: &BoxOptions) -> Result<Self> {
        options.validate()?;
        let model = model(options.kind);
        let geometry = ModelGeometry::new(&model)?;
        let mut scene = Self {
            options: options.clone(),
            path: BoxPath::new(options.seed),
            camera: camera(),
            albedos: face_albedos(options.kind),
            texture: texture(&model, options.seed),
            geometry,
            model,
            taus: Vec::new(),
            bands: Vec::new(),
        };
        scene.taus = scene.walk_path()?;
        scene.bands = scene.place_occluders()?;
        Ok(scene)
    }

    /// Projected model vertices at path time `tau`.
    fn corners_at(&self, tau: f64) -> Result<Vec<[f64; 2]>> {
        let (rotation, translation, lid) = self.path.state(tau);
        let pose = geometry::Pose::new(rotation, translation);
        let cam = self.geometry.camera_vertices(&pose, &self.params_for(lid))?;
        Ok(cam.into_iter().map(|p| self.camera.project(p)).collect())
    }

    fn params_for(&self, lid: f64) -> Vec<f64> {
        match self.options.kind {
            BoxKind::Rigid => Vec::new(),
            BoxKind::Hinged => vec![lid],
        }
    }

    /// Path time of every frame: each step moves the fastest vertex by speed·g(k) px.
    fn walk_path(&self) -> Result<Vec<f64>> {
        let mut taus = Vec::with_capacity(self.options.frames);
        let mut tau = 0.0;
        taus.push(tau);
        for k in 0..self.options.frames.saturating_sub(1) {
            let target = self.options.speed * ramp(k);
            if target > 0.0 {
                let here = self.corners_at(tau)?;
                let moved = |dt: f64| -> Result<f64> {
                    let there = self.corners_at(tau + dt)?;
                    Ok(here.iter().zip(&there).map(|(a, b)| (b[0] - a[0]).hypot(b[1] - a[1])).fold(0.0, f64::max))
                };
                // Bracket the first crossing by doubling, then bisect.
                let (mut lo, mut hi) = (0.0, 1e-4);
                while moved(hi)? < target {
                    lo = hi;
                    hi *= 2.0;
                    if hi > 10.0 {
                        return Err(Error::Parameter(format!(
                            "speed {} px/frame cannot be reached",
                            self.options.speed
                        )));
                    }
                }
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if moved(mid)? < target { lo = mid } else { hi = mid }
                }
                tau += 0.5 * (lo + hi);
            }
            taus.push(tau);
        }
        Ok(taus)
    }

    /// Rotation, translation and lid angle of frame `frame`.
    fn state(&self, frame: usize) -> (DMat3, DVec3, f64) {
        self.path.state(self.taus[frame])
    }

    /// Path time of frame `frame`.
    #[must_use]
    pub fn path_time(&self, frame: usize) -> f64 {
        self.taus[frame]
    }

    /// The true pose of frame `frame` (camera-from-object).
    #[must_use]
    pub fn pose(&self, frame: usize) -> Pose {
        let (rotation, translation, _) = self.state(frame);
        geometry::Pose::new(rotation, translation).into()
    }

    /// The true joint values of frame `frame`: `[lid]` for hinged-box, none for box.
    #[must_use]
    pub fn params(&self, frame: usize) -> Vec<f64> {
        self.params_for(self.state(frame).2)
    }

    fn view(&self, frame: usize) -> Result<FrameView> {
        let (rotation, translation, lid) = self.state(frame);
        let pose = geometry::Pose::new(rotation, translation);
        let camera_vertices = self.geometry.camera_vertices(&pose, &self.params_for(lid))?;
        let corners = camera_vertices.iter().map(|&p| self.camera.project(p)).collect();
        let facing = self.geometry.facing_faces(&camera_vertices);
        let lid_nearer = self.options.kind == BoxKind::Hinged && self.lid_is_nearer(&pose, lid);
        Ok(FrameView { camera_vertices, corners, facing, lid_nearer })
    }

    /// Whether the camera lies on the lid's side of the plane separating lid
    /// and body (module docs), for the camera-from-object `pose` and lid angle `lid`.
    #[must_use]
    pub fn lid_is_nearer(&self, pose: &geometry::Pose, lid: f64) -> bool {
        let (origin, axis) = hinge(self.options.kind);
        let towards_lid = if lid <= FRAC_PI_2 {
            // Inward normal of the lid's bottom face: up (−y) turned with the lid.
            DMat3::from_axis_angle(axis, lid) * DVec3::NEG_Y
        } else {
            DVec3::Z
        };
        let eye = pose.inverse().translation;
        towards_lid.dot(eye - origin) > 0.0
    }

    /// Image positions of every model vertex at frame `frame`.
    pub fn corners(&self, frame: usize) -> Result<Vec<[f64; 2]>> {
        Ok(self.view(frame)?.corners)
    }

    /// Convex hull of the nearer part's image when it can hide the other
    /// part (hinged-box), with the vertex range of the farther part.
    fn near_hull(&self, view: &FrameView) -> Option<(Vec<[f64; 2]>, Range<usize>)> {
        if self.options.kind != BoxKind::Hinged {
            return None;
        }
        let (near, far) = if view.lid_nearer { (8..16, 0..8) } else { (0..8, 8..16) };
        Some((convex_hull(&view.corners[near]), far))
    }

    /// The visible parts of the model edges in frame `frame`'s image (module
    /// docs): pieces of edges bordering a facing face, minus what the nearer part hides.
    fn visible_pieces(&self, view: &FrameView) -> Vec<[[f64; 2]; 2]> {
        let hull = self.near_hull(view);
        let mut pieces = Vec::new();
        for (k, &[i, j]) in self.geometry.edges().iter().enumerate() {
            let faces = &self.geometry.edge_faces()[k];
            if !faces.iter().any(|&f| view.facing[f]) {
                continue;
            }
            let (a, b) = (view.corners[i], view.corners[j]);
            match &hull {
                Some((hull, far)) if far.contains(&i) && far.contains(&j) => {
                    pieces.extend(segment_outside_convex(a, b, hull));
                }
                _ => pieces.push([a, b]),
            }
        }
        pieces
    }

    /// Per-vertex visibility of frame `frame` (module docs).
    pub fn visible(&self, frame: usize) -> Result<Vec<bool>> {
        let view = self.view(frame)?;
        let hull = self.near_hull(&view);
        let band = self.bands[frame];
        Ok((0..self.model.vertices.len())
            .map(|v| {
                let p = view.corners[v];
                let on_facing =
                    self.model.faces.iter().enumerate().any(|(f, face)| view.facing[f] && face.contains(&v));
                let hidden_by_part =
                    hull.as_ref().is_some_and(|(hull, far)| far.contains(&v) && strictly_inside_convex(p, hull));
                view.camera_vertices[v].z > 0.0
                    && self.camera.in_image(p)
                    && on_facing
                    && !hidden_by_part
                    && !band.is_some_and(|b| b.hides(p))
            })
            .collect())
    }

    /// The occluder band of frame `frame`, if any.
    #[must_use]
    pub fn occluder(&self, frame: usize) -> Option<Band> {
        self.bands[frame]
    }

    /// Fraction of the visible edge length of frame `frame` the occluder hides (0 without one).
    pub fn occluded_fraction(&self, frame: usize) -> Result<f64> {
        let Some(band) = self.bands[frame] else {
            return Ok(0.0);
        };
        let pieces = self.visible_pieces(&self.view(frame)?);
        Ok(hidden_share(&pieces, &band, band.width))
    }

    /// The bands of every frame: seeded stretches, centre line sweeping
    /// across the visible edges, width solved for the requested fraction.
    fn place_occluders(&self) -> Result<Vec<Option<Band>>> {
        let n = self.options.frames;
        let mut bands = vec![None; n];
        let fraction = self.options.occlude;
        if fraction <= 0.0 {
            return Ok(bands);
        }
        let mut rng = ChaCha8Rng::seed_from_u64(self.options.seed);
        rng.set_stream(OCCLUDER_STREAM);
        let mut start = rng.random_range(STRETCH_FRAMES);
        while start < n {
            let length = rng.random_range(STRETCH_FRAMES);
            let angle = rng.random_range(0.0..std::f64::consts::PI);
            let sweep = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            for (k, band) in bands.iter_mut().enumerate().take((start + length).min(n)).skip(start) {
                let pieces = self.visible_pieces(&self.view(k)?);
                let along = (k - start) as f64 / (length - 1) as f64;
                *band = band_hiding(&pieces, angle, sweep * (2.0 * along - 1.0), fraction);
            }
            start += length + rng.random_range(STRETCH_FRAMES);
        }
        Ok(bands)
    }

    /// Shaded grey of every face at frame `frame` (before texture and noise):
    /// albedo·(A + (1 − A)·max(0, n·l)).
    pub fn face_greys(&self, frame: usize) -> Result<Vec<f32>> {
        Ok(self.shades(&self.view(frame)?))
    }

    fn shades(&self, view: &FrameView) -> Vec<f32> {
        let light = DVec3::from_array(LIGHT_DIRECTION).normalize();
        self.geometry
            .face_normals(&view.camera_vertices)
            .iter()
            .zip(&self.albedos)
            .map(|(n, &albedo)| {
                let lambert = n.normalize_or_zero().dot(light).max(0.0);
                albedo * (AMBIENT + (1.0 - AMBIENT) * lambert) as f32
            })
            .collect()
    }

    /// Draw frame `frame`'s box (parts in painter's order, textured) and band.
    fn draw(&self, canvas: &mut Canvas, view: &FrameView) {
        let shades = self.shades(view);
        let mut parts = part_faces(self.options.kind);
        if self.options.kind == BoxKind::Hinged && !view.lid_nearer {
            parts.reverse();
        }
        for part in parts {
            let outlines: Vec<(usize, Vec<[f64; 2]>)> = part
                .filter(|&f| view.facing[f])
                .map(|f| (f, self.model.faces[f].iter().map(|&i| view.corners[i]).collect()))
                .collect();
            let faces: Vec<Face<'_>> = outlines.iter().map(|(f, points)| Face { points, grey: shades[*f] }).collect();
            canvas.fill_faces(&faces, FillRule::NonZero);
            for (f, _) in &outlines {
                let loop_ = &self.model.faces[*f];
                let [f0, f1, f3] = [loop_[0], loop_[1], loop_[3]].map(|i| view.camera_vertices[i]);
                let factor = shades[*f] / self.albedos[*f];
                for blob in &self.texture[*f] {
                    let points: Vec<[f64; 2]> = (0..BLOB_SEGMENTS)
                        .map(|s| {
                            let t = std::f64::consts::TAU * s as f64 / BLOB_SEGMENTS as f64;
                            let u = blob.centre[0] + blob.radii[0] * t.cos();
                            let v = blob.centre[1] + blob.radii[1] * t.sin();
                            self.camera.project(f0 + u * (f1 - f0) + v * (f3 - f0))
                        })
                        .collect();
                    canvas.fill_polygon(&points, FillRule::EvenOdd, (self.albedos[*f] + blob.offset) * factor);
                }
            }
        }
    }
}

/// Seeded blobs of every face of `model` (module docs).
fn texture(model: &Model, seed: u64) -> Vec<Vec<Blob>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(TEXTURE_STREAM);
    let v = |i: usize| DVec3::from_array(model.vertices[i]);
    model
        .faces
        .iter()
        .map(|face| {
            let (eu, ev) = ((v(face[1]) - v(face[0])).length(), (v(face[3]) - v(face[0])).length());
            if eu.min(ev) < TEXTURED_FACE_M {
                return Vec::new();
            }
            (0..BLOBS_PER_FACE)
                .map(|_| {
                    let centre = [rng.random_range(0.3..0.7), rng.random_range(0.3..0.7)];
                    // At least 0.08 of the face from every side.
                    let room = |c: f64| c.min(1.0 - c) - 0.08;
                    let radii =
                        [rng.random_range(0.4..1.0) * room(centre[0]), rng.random_range(0.4..1.0) * room(centre[1])];
                    let size = rng.random_range(3.0f32..6.0);
                    let offset = if rng.random_bool(0.5) { size } else { -size };
                    Blob { centre, radii, offset }
                })
                .collect()
        })
        .collect()
}

/// Convex hull of `points`, counter-clockwise in a y-down image (Andrew's monotone chain).
fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut p = points.to_vec();
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        for &q in &p {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
        if pass == 0 {
            p.reverse();
        }
    }
    hull
}

/// Whether `p` lies strictly inside the convex polygon `hull` (positive
/// turn order of [`convex_hull`]), by more than a nanopixel.
fn strictly_inside_convex(p: [f64; 2], hull: &[[f64; 2]]) -> bool {
    let n = hull.len();
    n >= 3
        && (0..n).all(|k| {
            let (a, b) = (hull[k], hull[(k + 1) % n]);
            let len = (b[0] - a[0]).hypot(b[1] - a[1]);
            ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])) / len > 1e-9
        })
}

/// The parts of segment `a`–`b` outside the interior of the convex polygon
/// `hull` (Cyrus–Beck clipping): none, one or two pieces.
fn segment_outside_convex(a: [f64; 2], b: [f64; 2], hull: &[[f64; 2]]) -> Vec<[[f64; 2]; 2]> {
    let n = hull.len();
    let (mut enter, mut exit) = (0.0f64, 1.0f64);
    let d = [b[0] - a[0], b[1] - a[1]];
    let mut outside = n < 3;
    for k in 0..n {
        let (p, q) = (hull[k], hull[(k + 1) % n]);
        // Inside is where cross(q − p, x − p) > 0: c0 + t·dc along the segment.
        let c0 = (q[0] - p[0]) * (a[1] - p[1]) - (q[1] - p[1]) * (a[0] - p[0]);
        let dc = (q[0] - p[0]) * d[1] - (q[1] - p[1]) * d[0];
        if dc == 0.0 {
            if c0 <= 0.0 {
                outside = true;
            }
        } else if dc > 0.0 {
            enter = enter.max(-c0 / dc);
        } else {
            exit = exit.min(-c0 / dc);
        }
    }
    let at = |t: f64| [a[0] + t * d[0], a[1] + t * d[1]];
    if outside || enter >= exit {
        return vec![[a, b]];
    }
    let mut pieces = Vec::new();
    if enter > 0.0 {
        pieces.push([a, at(enter)]);
    }
    if exit < 1.0 {
        pieces.push([at(exit), b]);
    }
    pieces
}

/// Share of the total length of `pieces` inside the band of `band`'s centre and angle with width `width`.
fn hidden_share(pieces: &[[[f64; 2]; 2]], band: &Band, width: f64) -> f64 {
    let total: f64 = pieces.iter().map(|[a, b]| (b[0] - a[0]).hypot(b[1] - a[1])).sum();
    if total <= 0.0 {
        return 0.0;
    }
    pieces.iter().map(|&[a, b]| band.hidden_length(a, b, width)).sum::<f64>() / total
}

/// The band at `angle` whose centre line lies `sweep` (−1..1) × 0.4 of the
/// pieces' half extent across it from their length-weighted centroid, just
/// wide enough to hide the share `fraction` of their length; None without pieces.
fn band_hiding(pieces: &[[[f64; 2]; 2]], angle: f64, sweep: f64, fraction: f64) -> Option<Band> {
    let mut weight = 0.0;
    let mut centroid = [0.0, 0.0];
    for [a, b] in pieces {
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        weight += len;
        centroid[0] += len * (a[0] + b[0]) / 2.0;
        centroid[1] += len * (a[1] + b[1]) / 2.0;
    }
    if weight <= 0.0 {
        return None;
    }
    centroid = [centroid[0] / weight, centroid[1] / weight];
    let mut band = Band { centre: centroid, angle, width: 0.0 };
    let extent = pieces.iter().flatten().map(|&p| band.offset(p).abs()).fold(0.0, f64::max);
    let n = band.normal();
    let shift = 0.4 * sweep * extent;
    band.centre = [centroid[0] + shift * n[0], centroid[1] + shift * n[1]];
    let (mut lo, mut hi) = (0.0, 2.0 * (extent + shift.abs()) + 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if hidden_share(pieces, &band, mid) < fraction { lo = mid } else { hi = mid }
    }
    band.width = hi;
    Some(band)
}

/// Largest rotation between consecutive truth poses, degrees.
fn peak_rotation_deg(truth: &[TruthFrame]) -> f64 {
    truth
        .windows(2)
        .filter_map(|w| Some((w[0].pose.as_ref()?, w[1].pose.as_ref()?)))
        .map(|(a, b)| {
            let (ra, rb) = (geometry::Pose::from(a).rotation, geometry::Pose::from(b).rotation);
            geometry::axis_angle_from_rotation(&(rb * ra.transpose())).length().to_degrees()
        })
        .fold(0.0, f64::max)
}

/// Render the `box` or `hinged-box` scene in memory (nothing touches the disk).
pub fn render_box(opts: &BoxOptions) -> Result<SyntheticSequence> {
    let scene = BoxScene::new(opts)?;
    let background = render_background(opts.background, WIDTH, HEIGHT, DEFAULT_SUPERSAMPLE, opts.seed)?;
    let background_small = background.downsample();
    let noise_sigma = opts.noise_sigma as f32;
    let frames = (0..opts.frames)
        .into_par_iter()
        .map_init(
            || (background.clone(), FloatImage::new(WIDTH, HEIGHT)),
            |(canvas, smooth), k| -> Result<GrayImage> {
                let view = scene.view(k)?;
                let band = scene.bands[k].map(|b| b.polygon());
                let clipped_band =
                    band.map(|quad| quad.map(|[x, y]| [x.clamp(-1.0, WIDTH as f64), y.clamp(-1.0, HEIGHT as f64)]));
                // Only the pixels the box and the band touch differ from the background.
                let moving = view.corners.iter().chain(clipped_band.iter().flatten());
                let window = Window::around(moving, TOUCHED_MARGIN_PX, WIDTH, HEIGHT).unwrap_or_default();
                smooth.data_mut().copy_from_slice(background_small.data());
                canvas.copy_window_from(&background, window)?;
                scene.draw(canvas, &view);
                if let Some(quad) = &band {
                    canvas.fill_polygon(quad, FillRule::NonZero, OCCLUDER_GREY);
                }
                canvas.downsample_window_into(smooth, window)?;
                let mut frame = GrayImage::new(WIDTH, HEIGHT);
                add_noise_and_quantise(smooth, noise_sigma, &mut frame_rng(opts.seed, k), &mut frame);
                Ok(frame)
            },
        )
        .collect::<Result<Vec<_>>>()?;
    let truth = (0..opts.frames)
        .map(|k| {
            Ok(TruthFrame {
                frame: k,
                visible: Visibility::Vertices(scene.visible(k)?),
                pose: Some(scene.pose(k)),
                params: scene.params(k),
                corners: scene.corners(k)?,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let truth_extra = (0..opts.frames)
        .map(|k| {
            let mut extra = serde_json::Map::new();
            extra.insert("occluded_fraction".to_string(), scene.occluded_fraction(k)?.into());
            Ok(extra)
        })
        .collect::<Result<Vec<_>>>()?;
    let init = InitState {
        pose: truth[0].pose,
        params: truth[0].params.clone(),
        corners: truth[0].corners.clone(),
        camera_motion: None,
    };
    let meta = serde_json::json!({
        "scene": opts.kind.name(),
        "seed": opts.seed,
        "frames": opts.frames,
        "frame_rate_hz": FRAME_RATE_HZ,
        "speed_px_per_frame": opts.speed,
        "speed_definition": "image displacement of the fastest model vertex between consecutive frames, exactly speed after a 15-frame smooth start",
        "peak_rotation_deg_per_frame": peak_rotation_deg(&truth),
        "path_phases": scene.path.phases,
        "path_time": scene.taus,
        "lid_path_range_rad": LID_PATH_RANGE,
        "occlude": opts.occlude,
        "occluder": "opaque straight band at a seeded angle per stretch of 30-60 frames, hiding the occlude fraction of the visible edge length",
        "occluder_bands": scene.bands,
        "occluder_grey": OCCLUDER_GREY,
        "noise_sigma": opts.noise_sigma,
        "background": opts.background.name(),
        "supersample": DEFAULT_SUPERSAMPLE,
        "face_albedos": scene.albedos,
        "ambient": AMBIENT,
        "light_direction_camera": LIGHT_DIRECTION,
    });
    Ok(SyntheticSequence {
        scene: opts.kind.name().to_string(),
        camera: scene.camera,
        model: scene.model,
        init,
        truth,
        truth_extra,
        frames,
        rgb_frames: Vec::new(),
        meta,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hinge_plane_separates_lid_and_body_at_every_lid_angle() {
        let model = model(BoxKind::Hinged);
        let geometry = ModelGeometry::new(&model).expect("model");
        let (origin, axis) = hinge(BoxKind::Hinged);
        for step in 0..=190 {
            let q = step as f64 / 100.0;
            let towards_lid = if q <= FRAC_PI_2 { DMat3::from_axis_angle(axis, q) * DVec3::NEG_Y } else { DVec3::Z };
            let v = geometry.posed_vertices(&[q]).expect("one joint");
            for (i, p) in v.iter().enumerate() {
                let side = towards_lid.dot(*p - origin);
                if i < 8 {
                    assert!(side <= 1e-12, "q {q}: body vertex {i} on the lid's side ({side})");
                } else {
                    assert!(side >= -1e-12, "q {q}: lid vertex {i} on the body's side ({side})");
                }
            }
        }
    }

    #[test]
    fn every_phase_of_the_path_keeps_the_box_in_view() {
        // The seven terms independently at -1, -0.5, 0, 0.5, 1: every corner of the path's box of states.
        let cam = camera();
        let levels = [-1.0, -0.5, 0.0, 0.5, 1.0];
        let mut margin = f64::INFINITY;
        for kind in [BoxKind::Rigid, BoxKind::Hinged] {
            let geometry = ModelGeometry::new(&model(kind)).expect("model");
            for index in 0..levels.len().pow(7) {
                let terms: [f64; 7] =
                    std::array::from_fn(|i| levels[index / levels.len().pow(i as u32) % levels.len()]);
                let (rotation, translation, lid) = BoxPath::state_from_terms(terms);
                let pose = geometry::Pose::new(rotation, translation);
                let params = if kind == BoxKind::Hinged { vec![lid] } else { Vec::new() };
                for p in geometry.camera_vertices(&pose, &params).expect("pose") {
                    let [u, v] = cam.project(p);
                    margin = margin.min(u).min(v).min(WIDTH as f64 - 1.0 - u).min(HEIGHT as f64 - 1.0 - v);
                }
            }
        }
        assert!(margin > 10.0, "{margin}");
    }

    #[test]
    fn segment_clipping_by_a_convex_polygon_matches_sampling() {
        let square = convex_hull(&[[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [5.0, 5.0]]);
        assert_eq!(square.len(), 4);
        assert!(strictly_inside_convex([5.0, 5.0], &square));
        assert!(!strictly_inside_convex([10.0, 5.0], &square), "the border is not inside");
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for _ in 0..200 {
            let mut r = || [rng.random_range(-5.0..15.0), rng.random_range(-5.0..15.0)];
            let (a, b) = (r(), r());
            let pieces = segment_outside_convex(a, b, &square);
            let outside_length: f64 = pieces.iter().map(|[p, q]| (q[0] - p[0]).hypot(q[1] - p[1])).sum();
            let n = 4000;
            let sampled = (0..n)
                .filter(|&s| {
                    let t = (s as f64 + 0.5) / n as f64;
                    !strictly_inside_convex([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])], &square)
                })
                .count() as f64
                / n as f64
                * (b[0] - a[0]).hypot(b[1] - a[1]);
            assert!((outside_length - sampled).abs() < 0.02, "{a:?} {b:?}: {outside_length} vs {sampled}");
        }
    }

    #[test]
    fn the_band_is_as_wide_as_needed_for_the_fraction() {
        // Two vertical segments 10 px long at x = 0 and x = 10; a vertical band hides by x.
        let pieces = [[[0.0, 0.0], [0.0, 10.0]], [[10.0, 0.0], [10.0, 10.0]]];
        let band = band_hiding(&pieces, FRAC_PI_2, 0.0, 0.5).expect("pieces");
        // Centred at x = 5: half the length needs one whole segment, i.e. a band reaching x = 0 (or 10).
        assert!((band.centre[0] - 5.0).abs() < 1e-12);
        assert!((band.width - 10.0).abs() < 1e-9, "{}", band.width);
        // A horizontal band hides a share of each vertical segment: 40 % needs a width of 4 px.
        let band = band_hiding(&pieces, 0.0, 0.0, 0.4).expect("pieces");
        assert!((band.width - 4.0).abs() < 1e-9, "{}", band.width);
        assert!((hidden_share(&pieces, &band, band.width) - 0.4).abs() < 1e-9);
        assert!(band.hides([0.0, 5.0]) && !band.hides([0.0, 7.5]));
    }
}
