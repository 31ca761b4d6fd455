//! Window energy (004 §III-B.2, eq. 20–28): the score of N candidate
//! windows of a colour frame against a template window, for Condensation.
//!
//! Each window is a quadrilateral of the frame (corners in order: the images
//! of the template's top-left, top-right, bottom-right and bottom-left). It is
//! warped to a 2^L × 2^L window by the projective map of the unit square onto
//! the quadrilateral ([`WindowMap`]), sampling the frame by bilinear
//! interpolation with clamp to edge (004: "we must compute the inverse
//! transformation and warp the destination window to also be 2^l × 2^l"). The
//! four critical-point filters (eq. 1–4, with the pairing of
//! [`super::cpf`]: the inner op takes the two children of one column) reduce
//! it to 2^k × 2^k, and the energy against the template at the same level is
//!
//! ```text
//! C_I  = Σ_ij Σ_m (I_s − I_d)²                                   (eq. 23)
//! C_HS = Σ_ij Σ_m (S_s cos 2πH_s − S_d cos 2πH_d)²
//!                + (S_s sin 2πH_s − S_d sin 2πH_d)²              (eq. 24)
//! U    = C_I / Σ_n C_I + C_HS / Σ_n C_HS                  (eq. 22, 25–26)
//! ```
//!
//! # Reading of the paper's equations
//! * Eq. 24 as printed subtracts each term from itself (`S_s cos − S_s cos`);
//!   the only reading that compares windows is source minus destination, as
//!   above. Eq. 7 writes `½(R−G) + (R−B)` for the numerator of the HSI hue;
//!   the HSI formula it cites is `½[(R−G) + (R−B)]`, which we use, with
//!   `H = θ` when `B ≤ G` and `360° − θ` otherwise, and H in turns inside
//!   `cos 2πH` (eq. 7 returns degrees). Eq. 8 prints `1 − min/(R+G+B)`, which
//!   is never below ⅔; the HSI saturation is `1 − 3·min/(R+G+B)`, used here.
//! * The chroma vector `(S cos 2πH, S sin 2πH)` is computed without
//!   trigonometry: `cos 2πH = num/den`, `sin 2πH = (√3/2)(G−B)/den`, with
//!   `num = ½[(R−G)+(R−B)]` and `den² = (R−G)² + (R−B)(G−B) = num² + ¾(G−B)²`.
//!   Grey and black pixels have no hue and give (0, 0).
//! * The paper applies the CPFs to intensity and compares hue and saturation
//!   per hierarchy without saying how a colour pixel is filtered. Here each
//!   hierarchy filters intensity `I = (R+G+B)/3` and each of R, G, B on its
//!   own (min and max are continuous, so small shifts of a window change its
//!   filtered colours a little, never by a jump), and the hierarchy's hue and
//!   saturation are those of its filtered (R, G, B).
//! * A term whose sum over the windows is 0 (grey frames have no chroma)
//!   adds 0. The intensity scale (0..255) does not matter after eq. 25–26.
//!
//! # Layout and order of arithmetic
//! A window's filtered values ([`WindowTemplate::values`]) are
//! `values[((m · K²) + p) · 3 + c]`: hierarchy m, output pixel p = y·K + x
//! (K = 2^k), channel c ∈ {I, S cos 2πH, S sin 2πH}. One GPU workgroup of 64
//! invocations scores one window: invocation `t` sums the output pixels
//! `t, t+64, …` and a tree halves the 64 partial sums; the CPU twin runs the
//! same loops in the same order. The GPU's division may round differently
//! (lavapipe), so parity is to a tolerance, not bit equality.

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use crate::gpu::{
    Binding::{ReadOnly, Storage, Uniform},
    EntryPoint, GpuContext, Recorder, ShaderDef, run_once,
};
use crate::image::{GrayImage, RgbImage};
use crate::{Error, Result};

/// The shader of this stage.
pub const SHADER: ShaderDef = ShaderDef {
    name: "window_energy",
    source: include_str!("../../shaders/window_energy.wgsl"),
    includes: &[],
    entry_points: &[
        EntryPoint::linear("window_terms", GROUP as u32, &[Uniform, ReadOnly, ReadOnly, ReadOnly, Storage]),
        EntryPoint::linear("normalise", NORMALISE_GROUP as u32, &[Uniform, ReadOnly, Storage]),
    ],
    overrides: &[],
};

/// Invocations scoring one window (the shader's `GROUP`).
const GROUP: usize = 64;
/// Invocations of the normalising pass (the shader's `NORMALISE_GROUP`).
const NORMALISE_GROUP: usize = 256;
/// Floats per window in the map buffer (the shader's `MAP_STRIDE`).
const MAP_STRIDE: usize = 12;
/// Map kind: projective (the shader compares with `MAP_BILINEAR`).
const MAP_PROJECTIVE: f32 = 0.0;
/// Map kind: bilinear in the corners.
const MAP_BILINEAR: f32 = 1.0;
/// `mode` of the shader: per-window energy terms.
const MODE_TERMS: u32 = 0;
/// `mode` of the shader: per-window filtered values.
const MODE_FEATURES: u32 = 1;
/// Number of CPF hierarchies.
pub const HIERARCHIES: usize = 4;
/// Channels of a filtered pixel: I, S cos 2πH, S sin 2πH.
pub const CHANNELS: usize = 3;
/// Largest L: windows of up to 128 × 128 (the paper uses 64 × 64, L = 6).
pub const MAX_SIDE_LOG2: u32 = 7;
/// Most windows in one request (one GPU workgroup each, in one dimension).
pub const MAX_WINDOWS: usize = 65_535;
/// Most floats of filtered windows handed back by one request (64 MiB):
/// 5461 windows at the largest level compared (64 × 64), any number at 16 × 16.
pub const MAX_FEATURE_FLOATS: usize = 1 << 24;
/// √3 / 2.
const HALF_SQRT3: f32 = 0.866_025_4;

/// A quadrilateral of the frame, in pixel coordinates (SPEC §4): the images
/// of the window's top-left, top-right, bottom-right and bottom-left corners.
pub type Quad = [[f32; 2]; 4];

/// Sizes of the window energy: windows of 2^`side_log2` pixels a side,
/// compared at CPF level 2^`cpf_log2`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WindowEnergyParams {
    /// L: the warped window is 2^L × 2^L (004 Fig. 4: 64 × 64, L = 6); 1..=7.
    pub side_log2: u32,
    /// k: the CPF level compared, 2^k × 2^k; 1..=L (k = L: no reduction).
    pub cpf_log2: u32,
}

impl Default for WindowEnergyParams {
    fn default() -> Self {
        Self { side_log2: 6, cpf_log2: 4 }
    }
}

impl WindowEnergyParams {
    /// Error unless `1 ≤ k ≤ L ≤ 7`.
    pub fn validate(&self) -> Result<()> {
        if !(1..=MAX_SIDE_LOG2).contains(&self.side_log2) || !(1..=self.side_log2).contains(&self.cpf_log2) {
            return Err(Error::Parameter(format!(
                "window energy: need 1 <= cpf level k ({}) <= window level L ({}) <= {MAX_SIDE_LOG2}",
                self.cpf_log2, self.side_log2
            )));
        }
        Ok(())
    }

    /// Side of the compared level, K = 2^k.
    #[must_use]
    pub fn level_side(&self) -> usize {
        1 << self.cpf_log2
    }

    /// Floats of one filtered window: 4 hierarchies × K² pixels × 3 channels.
    #[must_use]
    pub fn window_len(&self) -> usize {
        HIERARCHIES * self.level_side() * self.level_side() * CHANNELS
    }
}

/// A window filtered to its CPF level: the template that candidate windows
/// are compared with (layout in the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct WindowTemplate {
    /// The sizes it was made with.
    pub params: WindowEnergyParams,
    /// `values[((m · K²) + p) · 3 + c]`.
    pub values: Vec<f32>,
}

/// The energies of N windows.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct WindowEnergies {
    /// U of eq. 22 per window (normalised by eq. 25–26), in request order.
    pub energies: Vec<f32>,
    /// Σ_n C_I: the intensity terms before normalising.
    pub intensity_total: f32,
    /// Σ_n C_HS: the hue/saturation terms before normalising.
    pub colour_total: f32,
}

/// How a window point `(s, t)` of the unit square maps into the frame: 12
/// floats as the shader reads them. Projective: `x = (a s + b t + c)/w`,
/// `y = (d s + e t + f)/w`, `w = g s + h t + 1`, the map of the square onto
/// the quadrilateral (Heckbert's closed form). When the quadrilateral has no
/// such map that stays in front of the camera over the whole square (zero
/// area, three corners in a line, not convex) the corners are interpolated
/// bilinearly instead.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowMap(pub [f32; MAP_STRIDE]);

impl WindowMap {
    /// The map of `quad`, computed in f64 and stored as f32 (both backends
    /// use the same coefficients).
    #[must_use]
    pub fn from_quad(quad: &Quad) -> Self {
        let p: [[f64; 2]; 4] = quad.map(|c| [f64::from(c[0]), f64::from(c[1])]);
        let bilinear = || {
            let mut m = [0.0f32; MAP_STRIDE];
            for (i, c) in quad.iter().enumerate() {
                m[2 * i] = c[0];
                m[2 * i + 1] = c[1];
            }
            m[8] = MAP_BILINEAR;
            Self(m)
        };
        let (x, y) = (p.map(|c| c[0]), p.map(|c| c[1]));
        let (dx1, dx2, dx3) = (x[1] - x[2], x[3] - x[2], x[0] - x[1] + x[2] - x[3]);
        let (dy1, dy2, dy3) = (y[1] - y[2], y[3] - y[2], y[0] - y[1] + y[2] - y[3]);
        let det = dx1 * dy2 - dx2 * dy1;
        let scale = (dx1 * dy2).abs() + (dx2 * dy1).abs();
        if !(det.abs() > 1e-9 * scale && scale > 0.0) {
            return bilinear();
        }
        let g = (dx3 * dy2 - dx2 * dy3) / det;
        let h = (dx1 * dy3 - dx3 * dy1) / det;
        // w is affine in (s, t): positive at the four corners means positive on the square.
        if [1.0, 1.0 + g, 1.0 + g + h, 1.0 + h].iter().any(|&w| !(w > 1e-6)) {
            return bilinear();
        }
        let coefficients = [
            x[1] - x[0] + g * x[1],
            x[3] - x[0] + h * x[3],
            x[0],
            y[1] - y[0] + g * y[1],
            y[3] - y[0] + h * y[3],
            y[0],
            g,
            h,
        ];
        let mut m = [0.0f32; MAP_STRIDE];
        for (dst, v) in m.iter_mut().zip(coefficients) {
            *dst = v as f32;
        }
        m[8] = MAP_PROJECTIVE;
        Self(m)
    }

    /// Frame position of window point `(s, t)`; the shader's `frame_position`.
    #[must_use]
    #[inline(always)]
    pub fn position(&self, s: f32, t: f32) -> [f32; 2] {
        let [a, b, c, d, e, f, g, h, kind, ..] = self.0;
        if kind == MAP_BILINEAR {
            let (w0, w1, w2, w3) = ((1.0 - s) * (1.0 - t), s * (1.0 - t), s * t, (1.0 - s) * t);
            return [w0 * a + w1 * c + w2 * e + w3 * g, w0 * b + w1 * d + w2 * f + w3 * h];
        }
        let w = g * s + h * t + 1.0;
        [(a * s + b * t + c) / w, (d * s + e * t + f) / w]
    }
}

/// Error unless the frame is non-empty, the sizes valid, there are at most
/// [`MAX_WINDOWS`] quadrilaterals, all finite, and the template (if any)
/// was made with the same sizes.
fn check_inputs(
    frame: &RgbImage,
    params: &WindowEnergyParams,
    quads: &[Quad],
    template: Option<&WindowTemplate>,
) -> Result<()> {
    params.validate()?;
    if frame.width() == 0 || frame.height() == 0 {
        return Err(Error::Size("window energy of an empty frame".into()));
    }
    check_windows(params, quads, template)
}

/// The checks of the stage that need no frame, for `params` already
/// validated: at most [`MAX_WINDOWS`] windows (and [`MAX_FEATURE_FLOATS`]
/// filtered values without a template), finite corners, and a template made
/// for `params`.
pub(crate) fn check_windows(
    params: &WindowEnergyParams,
    quads: &[Quad],
    template: Option<&WindowTemplate>,
) -> Result<()> {
    if quads.len() > MAX_WINDOWS {
        return Err(Error::Parameter(format!("window energy: {} windows, at most {MAX_WINDOWS}", quads.len())));
    }
    if template.is_none() && quads.len() * params.window_len() > MAX_FEATURE_FLOATS {
        return Err(Error::Parameter(format!(
            "window energy: {} filtered windows of {} values exceed {MAX_FEATURE_FLOATS} values",
            quads.len(),
            params.window_len()
        )));
    }
    if let Some(i) = quads.iter().position(|q| q.iter().flatten().any(|v| !v.is_finite())) {
        return Err(Error::Parameter(format!("window energy: window {i} has a corner that is not finite")));
    }
    if let Some(t) = template
        && (t.params != *params || t.values.len() != params.window_len())
    {
        return Err(Error::Parameter(format!(
            "window energy: template made for {:?} with {} values, request is {params:?}",
            t.params,
            t.values.len()
        )));
    }
    Ok(())
}

// ---------------------------------------------------------------- CPU twin

/// Bilinear sample of `frame` at `(x, y)`, clamped to the frame: the
/// shader's `sample_rgb`, one pixel at a time (the unit tests' reference
/// for [`SampleRun`]).
#[cfg(test)]
fn sample_rgb(frame: &RgbImage, x: f32, y: f32) -> [f32; 3] {
    let (w, h) = frame.size();
    let x = x.clamp(0.0, (w - 1) as f32);
    let y = y.clamp(0.0, (h - 1) as f32);
    let (fx0, fy0) = (x.floor(), y.floor());
    let (fx, fy) = (x - fx0, y - fy0);
    let (x0, y0) = (fx0 as usize, fy0 as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let texel = |x: usize, y: usize| frame.get(x, y).map(f32::from);
    let (p00, p10, p01, p11) = (texel(x0, y0), texel(x1, y0), texel(x0, y1), texel(x1, y1));
    let mut out = [0.0; 3];
    for c in 0..3 {
        let top = (1.0 - fx) * p00[c] + fx * p10[c];
        let bottom = (1.0 - fx) * p01[c] + fx * p11[c];
        out[c] = (1.0 - fy) * top + fy * bottom;
    }
    out
}

/// Window pixel `(px, py)` as (I, R, G, B): the shader's `window_pixel`.
#[cfg(test)]
fn window_pixel(frame: &RgbImage, map: &WindowMap, side_log2: u32, px: usize, py: usize) -> [f32; 4] {
    let side = (1u32 << side_log2) as f32;
    let s = (px as f32 + 0.5) / side;
    let t = (py as f32 + 0.5) / side;
    let [x, y] = map.position(s, t);
    let [r, g, b] = sample_rgb(frame, x, y);
    [(r + g + b) / 3.0, r, g, b]
}

/// Window pixels sampled together by [`SampleRun::sample`].
const SAMPLE_RUN: usize = 16;

/// A run of [`SAMPLE_RUN`] window pixels of one row, sampled in steps over
/// the whole run (positions, then the texels, then the interpolation), each
/// step a loop over the run's pixels with one array per quantity, so that
/// the arithmetic steps run on vectors; each pixel's value is the shader's
/// `window_pixel`, by the same operations in the same order.
#[derive(Default)]
struct SampleRun {
    /// Frame positions of the pixels, x and y.
    x: [f32; SAMPLE_RUN],
    y: [f32; SAMPLE_RUN],
    /// Fractional position between the corner texels, x and y.
    fx: [f32; SAMPLE_RUN],
    fy: [f32; SAMPLE_RUN],
    /// Texel indices of the corners (x0, y0), (x1, y0), (x0, y1), (x1, y1).
    corners: [[usize; SAMPLE_RUN]; 4],
    /// The corners' R, G and B as f32: `texels[channel][corner][pixel]`.
    texels: [[[f32; SAMPLE_RUN]; 4]; 3],
    /// (I, R, G, B) of each pixel.
    pixels: [[f32; 4]; SAMPLE_RUN],
}

impl SampleRun {
    /// Window pixels `(px0 .. px0 + len, py)` into `pixels[..len]` (`len` ≤ [`SAMPLE_RUN`]).
    #[inline(always)]
    fn sample(&mut self, frame: &RgbImage, map: &WindowMap, side_log2: u32, px0: usize, py: usize, len: usize) {
        let (fw, fh) = frame.size();
        let side = (1u32 << side_log2) as f32;
        let t = (py as f32 + 0.5) / side;
        // `WindowMap::position`, its kind decided once for the run (plain
        // loops, no closure: see `window_levels`).
        let [a, b, c, d, e, f, g, h, kind, ..] = map.0;
        if kind == MAP_BILINEAR {
            for i in 0..len {
                let s = ((px0 + i) as f32 + 0.5) / side;
                let (w0, w1, w2, w3) = ((1.0 - s) * (1.0 - t), s * (1.0 - t), s * t, (1.0 - s) * t);
                self.x[i] = w0 * a + w1 * c + w2 * e + w3 * g;
                self.y[i] = w0 * b + w1 * d + w2 * f + w3 * h;
            }
        } else {
            for i in 0..len {
                let s = ((px0 + i) as f32 + 0.5) / side;
                let w = g * s + h * t + 1.0;
                self.x[i] = (a * s + b * t + c) / w;
                self.y[i] = (d * s + e * t + f) / w;
            }
        }
        // `sample_rgb`'s clamp, floor and corners.
        let (x_max, y_max) = ((fw - 1) as f32, (fh - 1) as f32);
        for i in 0..len {
            let x = self.x[i].clamp(0.0, x_max);
            let y = self.y[i].clamp(0.0, y_max);
            let (fx0, fy0) = (x.floor(), y.floor());
            (self.fx[i], self.fy[i]) = (x - fx0, y - fy0);
            let (x0, y0) = (fx0 as usize, fy0 as usize);
            let (x1, y1) = ((x0 + 1).min(fw - 1), (y0 + 1).min(fh - 1));
            self.corners[0][i] = y0 * fw + x0;
            self.corners[1][i] = y0 * fw + x1;
            self.corners[2][i] = y1 * fw + x0;
            self.corners[3][i] = y1 * fw + x1;
        }
        let data = frame.data();
        for (corner, indices) in self.corners.iter().enumerate() {
            for (i, &k) in indices[..len].iter().enumerate() {
                let [r, g, b] = data[k];
                self.texels[0][corner][i] = f32::from(r);
                self.texels[1][corner][i] = f32::from(g);
                self.texels[2][corner][i] = f32::from(b);
            }
        }
        let mut rgb = [[0.0f32; SAMPLE_RUN]; 3];
        for (out, [p00, p10, p01, p11]) in rgb.iter_mut().zip(&self.texels) {
            for i in 0..len {
                let (fx, fy) = (self.fx[i], self.fy[i]);
                let top = (1.0 - fx) * p00[i] + fx * p10[i];
                let bottom = (1.0 - fx) * p01[i] + fx * p11[i];
                out[i] = (1.0 - fy) * top + fy * bottom;
            }
        }
        for i in 0..len {
            let (r, g, b) = (rgb[0][i], rgb[1][i], rgb[2][i]);
            self.pixels[i] = [(r + g + b) / 3.0, r, g, b];
        }
    }
}

/// The chroma vector `(S cos 2πH, S sin 2πH)` of (R, G, B) by eq. 7–8 as
/// the module documentation reads them; (0, 0) for grey and black.
#[must_use]
#[inline(always)]
pub fn chroma(rgb: [f32; 3]) -> [f32; 2] {
    let [r, g, b] = rgb;
    let sum = r + g + b;
    let lo = r.min(g.min(b));
    let (rg, rb, gb) = (r - g, r - b, g - b);
    let den2 = rg * rg + rb * gb;
    if sum <= 0.0 || den2 <= 0.0 {
        return [0.0, 0.0];
    }
    let saturation = 1.0 - 3.0 * lo / sum;
    let den = den2.sqrt();
    let num = 0.5 * (rg + rb);
    [saturation * num / den, saturation * HALF_SQRT3 * gb / den]
}

#[inline(always)]
fn min4(a: [f32; 4], b: [f32; 4]) -> [f32; 4] {
    std::array::from_fn(|i| a[i].min(b[i]))
}

#[inline(always)]
fn max4(a: [f32; 4], b: [f32; 4]) -> [f32; 4] {
    std::array::from_fn(|i| a[i].max(b[i]))
}

/// The four hierarchies' (I, R, G, B) at output pixel `(ox, oy)` (eq. 1–4
/// over its block, in Z order): the shader's `cpf_block`, one block at a
/// time (the unit tests' reference for [`window_levels`]).
#[cfg(test)]
fn cpf_block(frame: &RgbImage, map: &WindowMap, params: &WindowEnergyParams, ox: usize, oy: usize) -> [[f32; 4]; 4] {
    let depth = (params.side_log2 - params.cpf_log2) as usize;
    let block = 1usize << depth;
    let (mut lo, mut hi) = ([f32::MAX; 4], [f32::MIN; 4]);
    let mut stack = [[[0.0f32; 4]; 4]; MAX_SIDE_LOG2 as usize];
    let (mut s1, mut s2) = ([0.0f32; 4], [0.0f32; 4]);
    for n in 0..block * block {
        let (mut bx, mut by) = (0, 0);
        for b in 0..depth {
            let c = (n >> (2 * b)) & 3;
            bx |= (c >> 1) << b;
            by |= (c & 1) << b;
        }
        let v = window_pixel(frame, map, params.side_log2, ox * block + bx, oy * block + by);
        // eq. 1 and eq. 4.
        lo = min4(lo, v);
        hi = max4(hi, v);
        // eq. 2 (m = 1) and eq. 3 (m = 2); stack[b] = [a1, b1, a2, b2].
        let (mut v1, mut v2) = (v, v);
        let mut done = false;
        for (b, level) in stack.iter_mut().enumerate().take(depth) {
            match (n >> (2 * b)) & 3 {
                0 => {
                    (level[0], level[2]) = (v1, v2);
                    done = true;
                }
                1 => {
                    (level[0], level[2]) = (min4(level[0], v1), max4(level[2], v2));
                    done = true;
                }
                2 => {
                    (level[1], level[3]) = (v1, v2);
                    done = true;
                }
                _ => {
                    v1 = max4(level[0], min4(level[1], v1));
                    v2 = min4(level[2], max4(level[3], v2));
                }
            }
            if done {
                break;
            }
        }
        if !done {
            (s1, s2) = (v1, v2);
        }
    }
    [lo, s1, s2, hi]
}

/// The four hierarchies of a whole window at the output level, into
/// `levels` (one entry per output pixel, row by row: `[lo, s1, s2, hi]`,
/// each (I, R, G, B)): every window pixel sampled once, then each level of
/// the pyramid made from the one below, 2×2 cells at a time. A cell's
/// children in the shader's Z order are top-left, bottom-left, top-right,
/// bottom-right (c0–c3), and eq. 2 (m = 1) is max(min(c0, c1), min(c2, c3)),
/// eq. 3 (m = 2) min(max(c0, c1), max(c2, c3)), eq. 1 and 4 the min and max
/// of all four: the values of `cpf_block`, bit for bit (eq. 2 and 3 group
/// as it does; min and max of the same values, NaN ignored as `f32::min`
/// ignores it, do not depend on the grouping).
#[inline(always)]
fn window_levels(frame: &RgbImage, map: &WindowMap, params: &WindowEnergyParams, levels: &mut Vec<[[f32; 4]; 4]>) {
    let mut n = 1usize << params.side_log2;
    levels.clear();
    // Plain loops, not closures: a closure is not compiled with the
    // caller's target features.
    let mut run = SampleRun::default();
    let len = n.min(SAMPLE_RUN);
    for py in 0..n {
        for px0 in (0..n).step_by(len) {
            run.sample(frame, map, params.side_log2, px0, py, len);
            for &v in &run.pixels[..len] {
                // As `cpf_block` folds them from f32::MAX and f32::MIN.
                levels.push([min4([f32::MAX; 4], v), v, v, max4([f32::MIN; 4], v)]);
            }
        }
    }
    for _ in params.cpf_log2..params.side_log2 {
        let half = n / 2;
        // Cell (cx, cy) is written at cy·half + cx, never past the first of
        // the children it reads (at 2cy·n + 2cx): the level shrinks in place.
        for cy in 0..half {
            for cx in 0..half {
                let top = 2 * cy * n + 2 * cx;
                let [c0, c2] = [levels[top], levels[top + 1]];
                let [c1, c3] = [levels[top + n], levels[top + n + 1]];
                levels[cy * half + cx] = [
                    min4(min4(c0[0], c1[0]), min4(c2[0], c3[0])),
                    max4(min4(c0[1], c1[1]), min4(c2[1], c3[1])),
                    min4(max4(c0[2], c1[2]), max4(c2[2], c3[2])),
                    max4(max4(c0[3], c1[3]), max4(c2[3], c3[3])),
                ];
            }
        }
        n = half;
    }
    levels.truncate(n * n);
}

// The per-window loops are compiled for AVX-512 or AVX2 where the CPU has
// them (the same operations in the same order: the results do not change;
// the rounding to integers of the bilinear sampling then runs inline).
simd_dispatch!(fn window_values(frame: &RgbImage, map: &WindowMap, params: &WindowEnergyParams, levels: &mut Vec<[[f32; 4]; 4]>, out: &mut [f32]) => window_values_body);

/// One window's filtered values (layout of [`WindowTemplate::values`]).
#[inline(always)]
fn window_values_body(
    frame: &RgbImage,
    map: &WindowMap,
    params: &WindowEnergyParams,
    levels: &mut Vec<[[f32; 4]; 4]>,
    out: &mut [f32],
) {
    window_levels(frame, map, params, levels);
    let pixels = levels.len();
    for (p, hierarchies) in levels.iter().enumerate() {
        for (m, v) in hierarchies.iter().enumerate() {
            let c = chroma([v[1], v[2], v[3]]);
            let o = (m * pixels + p) * CHANNELS;
            out[o..o + CHANNELS].copy_from_slice(&[v[0], c[0], c[1]]);
        }
    }
}

simd_dispatch!(fn window_terms(frame: &RgbImage, map: &WindowMap, template: &WindowTemplate, levels: &mut Vec<[[f32; 4]; 4]>) -> [f32; 2] => window_terms_body);

/// (C_I, C_HS) of one window against `template` (eq. 23–24), in the
/// shader's order: 64 strided partial sums halved by a tree; `levels` is
/// scratch.
#[inline(always)]
fn window_terms_body(
    frame: &RgbImage,
    map: &WindowMap,
    template: &WindowTemplate,
    levels: &mut Vec<[[f32; 4]; 4]>,
) -> [f32; 2] {
    window_levels(frame, map, &template.params, levels);
    let pixels = levels.len();
    let t = &template.values;
    let mut partial = [[0.0f32; 2]; GROUP];
    for (lane, sums) in partial.iter_mut().enumerate() {
        for p in (lane..pixels).step_by(GROUP) {
            for (m, v) in levels[p].iter().enumerate() {
                let cd = chroma([v[1], v[2], v[3]]);
                let o = (m * pixels + p) * CHANNELS;
                let di = t[o] - v[0];
                sums[0] += di * di;
                let (dx, dy) = (t[o + 1] - cd[0], t[o + 2] - cd[1]);
                sums[1] += dx * dx + dy * dy;
            }
        }
    }
    tree_sum(&mut partial)
}

/// Sum `values` by halving: `v[i] += v[i + stride]` for stride = len/2, …, 1
/// (the shaders' workgroup reduction; `len` a power of two).
fn tree_sum(values: &mut [[f32; 2]]) -> [f32; 2] {
    let mut stride = values.len() / 2;
    while stride > 0 {
        for i in 0..stride {
            values[i][0] += values[i + stride][0];
            values[i][1] += values[i + stride][1];
        }
        stride /= 2;
    }
    values[0]
}

/// Eq. 25–26 and 22 over per-window `(C_I, C_HS)` terms, in the order of the
/// shader's `normalise`.
#[must_use]
pub fn normalise_cpu(terms: &[[f32; 2]]) -> WindowEnergies {
    let mut partial = [[0.0f32; 2]; NORMALISE_GROUP];
    for (lane, sums) in partial.iter_mut().enumerate() {
        for term in terms.iter().skip(lane).step_by(NORMALISE_GROUP) {
            sums[0] += term[0];
            sums[1] += term[1];
        }
    }
    let [total_i, total_hs] = tree_sum(&mut partial);
    let energies = terms
        .iter()
        .map(|&[ci, chs]| {
            let mut u = 0.0;
            if total_i > 0.0 {
                u += ci / total_i;
            }
            if total_hs > 0.0 {
                u += chs / total_hs;
            }
            u
        })
        .collect();
    WindowEnergies { energies, intensity_total: total_i, colour_total: total_hs }
}

/// CPU twin: the filtered values of each window of `quads` (a template per
/// window; the tracker takes its template window this way).
pub fn window_features_cpu(
    frame: &RgbImage,
    params: &WindowEnergyParams,
    quads: &[Quad],
) -> Result<Vec<WindowTemplate>> {
    check_inputs(frame, params, quads, None)?;
    Ok(quads
        .par_iter()
        .map_init(Vec::new, |levels, q| {
            let mut values = vec![0.0; params.window_len()];
            window_values(frame, &WindowMap::from_quad(q), params, levels, &mut values);
            WindowTemplate { params: *params, values }
        })
        .collect())
}

/// CPU twin: the per-window `(C_I, C_HS)` of eq. 23–24 against `template`.
pub fn window_terms_cpu(frame: &RgbImage, quads: &[Quad], template: &WindowTemplate) -> Result<Vec<[f32; 2]>> {
    check_inputs(frame, &template.params, quads, Some(template))?;
    Ok(quads
        .par_iter()
        .map_init(Vec::new, |levels, q| window_terms(frame, &WindowMap::from_quad(q), template, levels))
        .collect())
}

/// CPU twin: the energies of eq. 22 (normalised by eq. 25–26) of the windows
/// `quads` of `frame` against `template`.
pub fn window_energy_cpu(frame: &RgbImage, quads: &[Quad], template: &WindowTemplate) -> Result<WindowEnergies> {
    Ok(normalise_cpu(&window_terms_cpu(frame, quads, template)?))
}

// ------------------------------------------------ pixel-match energy (CPU)

/// The coefficients of the pixel-match energy (004 Table II).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelMatchCoefficients {
    /// ψ of eq. 9: weight of the hue/saturation term (0.0125).
    pub psi: f32,
    /// λ of eq. 13: weight of the intensity-and-colour term C (1).
    pub lambda: f32,
    /// θ of eq. 13: weight of the edge term E (2).
    pub theta: f32,
}

impl Default for PixelMatchCoefficients {
    fn default() -> Self {
        Self { psi: 0.0125, lambda: 1.0, theta: 2.0 }
    }
}

/// One pixel of a CPF hierarchy as the pixel-match energy sees it: its
/// intensity, its colour, and the averaged horizontal and vertical edge
/// values at its level (eq. 10–11).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatchPixel {
    /// Intensity I.
    pub intensity: f32,
    /// (R, G, B), for hue and saturation (eq. 7–8).
    pub rgb: [f32; 3],
    /// (edge^h, edge^v) of eq. 10–11.
    pub edge: [f32; 2],
}

/// The energy of matching source pixel `p` with destination pixel `q` at one
/// level of one hierarchy (004 §II-B, eq. 5–13):
/// `U = λ(C_I + ψ C_HS) + θ E` with `C_I = (I(p) − I(q))²` (eq. 5), `C_HS`
/// the squared distance of the chroma vectors (eq. 6, read as eq. 24 is;
/// see the module documentation) and
/// `E = ¼[(edge^h_p − edge^h_q)² + (edge^v_p − edge^v_q)²]` (eq. 12). The
/// window energy drops the edge term (§III-B.2); point matching keeps it.
#[must_use]
pub fn pixel_match_energy(p: &MatchPixel, q: &MatchPixel, k: &PixelMatchCoefficients) -> f32 {
    let di = p.intensity - q.intensity;
    let c_i = di * di;
    let (cp, cq) = (chroma(p.rgb), chroma(q.rgb));
    let c_hs = (cp[0] - cq[0]).powi(2) + (cp[1] - cq[1]).powi(2);
    let c = c_i + k.psi * c_hs;
    let e = 0.25 * ((p.edge[0] - q.edge[0]).powi(2) + (p.edge[1] - q.edge[1]).powi(2));
    k.lambda * c + k.theta * e
}

// ---------------------------------------------------------------- GPU

/// Uniform block of `window_energy.wgsl`; kept in sync with its `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct WindowEnergyUniform {
    width: u32,
    height: u32,
    side_log2: u32,
    cpf_log2: u32,
    count: u32,
    mode: u32,
    _pad: [u32; 2],
}

/// `r | g << 8 | b << 16` per pixel: the frame as the shader reads it.
#[must_use]
pub fn pack_rgb(frame: &RgbImage) -> Vec<u32> {
    frame.data().iter().map(|&[r, g, b]| u32::from(r) | u32::from(g) << 8 | u32::from(b) << 16).collect()
}

/// [`pack_rgb`] of the grey frame as colour ([`RgbImage::from_gray`]: each
/// byte in all three channels), without building that colour frame.
#[must_use]
pub fn pack_gray(frame: &GrayImage) -> Vec<u32> {
    frame.data().iter().map(|&g| u32::from(g) * 0x0001_0101).collect()
}

/// Device buffers of the stage, grown to the largest request seen: the
/// packed frame, the window maps, the template, the per-window terms (or
/// filtered values), and the energies with their staging copy.
pub(crate) struct WindowEnergyGpu {
    frame: wgpu::Buffer,
    frame_pixels: usize,
    maps: wgpu::Buffer,
    template: wgpu::Buffer,
    out: wgpu::Buffer,
    energies: wgpu::Buffer,
    staging: wgpu::Buffer,
    /// Windows, floats of a filtered window (the template's size), and
    /// whether `out` holds every window's filtered values.
    windows: usize,
    window_len: usize,
    features: bool,
}

fn storage(ctx: &GpuContext, label: &str, bytes: usize, extra: wgpu::BufferUsages) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(4).next_multiple_of(4) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra,
        mapped_at_creation: false,
    })
}

impl WindowEnergyGpu {
    /// Buffers for frames of `pixels` pixels, up to `windows` windows, a
    /// template of `window_len` floats, and (with `features`) every window's
    /// `window_len` filtered values.
    pub(crate) fn new(ctx: &GpuContext, pixels: usize, windows: usize, window_len: usize, features: bool) -> Self {
        let windows = windows.max(1);
        let per_window = if features { window_len.max(2) } else { 2 };
        let staging_bytes = ((windows + 2) * 4).max(windows * per_window * 4);
        Self {
            frame: storage(ctx, "window_energy.frame", pixels * 4, wgpu::BufferUsages::empty()),
            frame_pixels: pixels,
            maps: storage(ctx, "window_energy.maps", windows * MAP_STRIDE * 4, wgpu::BufferUsages::empty()),
            template: storage(ctx, "window_energy.template", window_len * 4, wgpu::BufferUsages::empty()),
            out: storage(ctx, "window_energy.out", windows * per_window * 4, wgpu::BufferUsages::COPY_SRC),
            energies: storage(ctx, "window_energy.energies", (windows + 2) * 4, wgpu::BufferUsages::COPY_SRC),
            staging: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("window_energy.staging"),
                size: staging_bytes.next_multiple_of(4) as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            windows,
            window_len,
            features,
        }
    }

    /// Whether these buffers take what [`WindowEnergyGpu::new`] with these arguments would.
    pub(crate) fn fits(&self, pixels: usize, windows: usize, window_len: usize, features: bool) -> bool {
        self.frame_pixels == pixels
            && windows <= self.windows
            && window_len <= self.window_len
            && (self.features || !features)
    }

    /// Upload the packed frame (before the submission that reads it).
    pub(crate) fn write_frame(&self, ctx: &GpuContext, packed: &[u32]) {
        if !packed.is_empty() {
            ctx.queue.write_buffer(&self.frame, 0, bytemuck::cast_slice(packed));
        }
    }

    /// Upload the maps of `quads` and the template values.
    fn write_windows(&self, ctx: &GpuContext, quads: &[Quad], template: Option<&WindowTemplate>) {
        let maps: Vec<f32> = quads.iter().flat_map(|q| WindowMap::from_quad(q).0).collect();
        if !maps.is_empty() {
            ctx.queue.write_buffer(&self.maps, 0, bytemuck::cast_slice(&maps));
        }
        if let Some(t) = template {
            ctx.queue.write_buffer(&self.template, 0, bytemuck::cast_slice(&t.values));
        }
    }

    /// Record `window_terms` over `n` windows in `mode`; the uniform block it used.
    fn dispatch_terms(
        &self,
        rec: &mut Recorder<'_>,
        size: (usize, usize),
        params: &WindowEnergyParams,
        n: usize,
        mode: u32,
    ) -> Result<WindowEnergyUniform> {
        let u = uniform(size, params, n, mode);
        rec.dispatch(
            &SHADER,
            "window_terms",
            &u,
            &[&self.frame, &self.maps, &self.template, &self.out],
            [n as u32, 1, 1],
        )?;
        Ok(u)
    }

    /// Record the energies of `quads` against `template` (uploading both
    /// now) and the copy of the N energies and two totals for
    /// [`WindowEnergyGpu::read_energies`].
    pub(crate) fn encode_energies(
        &self,
        rec: &mut Recorder<'_>,
        ctx: &GpuContext,
        size: (usize, usize),
        quads: &[Quad],
        template: &WindowTemplate,
    ) -> Result<()> {
        let params = &template.params;
        self.write_windows(ctx, quads, Some(template));
        let n = quads.len();
        let u = self.dispatch_terms(rec, size, params, n, MODE_TERMS)?;
        rec.dispatch(&SHADER, "normalise", &u, &[&self.out, &self.energies], [1, 1, 1])?;
        rec.copy(&self.energies, 0, &self.staging, 0, ((n + 2) * 4) as u64);
        Ok(())
    }

    /// After the submission of [`WindowEnergyGpu::encode_energies`] for `n`
    /// windows is done: the energies and totals.
    pub(crate) fn read_energies(&self, ctx: &GpuContext, n: usize) -> Result<WindowEnergies> {
        let values: Vec<f32> = ctx.read_mapped(&self.staging, 0..((n + 2) * 4) as u64, bytemuck::pod_collect_to_vec)?;
        Ok(WindowEnergies { energies: values[..n].to_vec(), intensity_total: values[n], colour_total: values[n + 1] })
    }

    /// Record the filtered values of `quads` (uploading their maps now) and
    /// their copy for [`WindowEnergyGpu::read_features`].
    pub(crate) fn encode_features(
        &self,
        rec: &mut Recorder<'_>,
        ctx: &GpuContext,
        size: (usize, usize),
        params: &WindowEnergyParams,
        quads: &[Quad],
    ) -> Result<()> {
        self.write_windows(ctx, quads, None);
        let n = quads.len();
        self.dispatch_terms(rec, size, params, n, MODE_FEATURES)?;
        rec.copy(&self.out, 0, &self.staging, 0, (n * params.window_len() * 4) as u64);
        Ok(())
    }

    /// After the submission of [`WindowEnergyGpu::encode_features`]: one
    /// template per window.
    pub(crate) fn read_features(
        &self,
        ctx: &GpuContext,
        params: &WindowEnergyParams,
        n: usize,
    ) -> Result<Vec<WindowTemplate>> {
        let len = params.window_len();
        let values: Vec<f32> = ctx.read_mapped(&self.staging, 0..(n * len * 4) as u64, bytemuck::pod_collect_to_vec)?;
        Ok(values.chunks_exact(len).map(|v| WindowTemplate { params: *params, values: v.to_vec() }).collect())
    }
}

fn uniform(size: (usize, usize), params: &WindowEnergyParams, count: usize, mode: u32) -> WindowEnergyUniform {
    WindowEnergyUniform {
        width: size.0 as u32,
        height: size.1 as u32,
        side_log2: params.side_log2,
        cpf_log2: params.cpf_log2,
        count: count as u32,
        mode,
        _pad: [0; 2],
    }
}

/// GPU: the energies of `quads` of `frame` against `template` (upload, one
/// submission, read back N energies and the two totals); tests and benches.
pub fn window_energy_gpu(
    ctx: &GpuContext,
    frame: &RgbImage,
    quads: &[Quad],
    template: &WindowTemplate,
) -> Result<WindowEnergies> {
    check_inputs(frame, &template.params, quads, Some(template))?;
    if quads.is_empty() {
        return Ok(normalise_cpu(&[]));
    }
    let gpu = WindowEnergyGpu::new(ctx, frame.data().len(), quads.len(), template.params.window_len(), false);
    gpu.write_frame(ctx, &pack_rgb(frame));
    run_once(ctx, |rec| gpu.encode_energies(rec, ctx, frame.size(), quads, template))?;
    gpu.read_energies(ctx, quads.len())
}

/// GPU: the filtered values of each window of `quads`; tests and benches.
pub fn window_features_gpu(
    ctx: &GpuContext,
    frame: &RgbImage,
    params: &WindowEnergyParams,
    quads: &[Quad],
) -> Result<Vec<WindowTemplate>> {
    check_inputs(frame, params, quads, None)?;
    if quads.is_empty() {
        return Ok(Vec::new());
    }
    let gpu = WindowEnergyGpu::new(ctx, frame.data().len(), quads.len(), params.window_len(), true);
    gpu.write_frame(ctx, &pack_rgb(frame));
    run_once(ctx, |rec| gpu.encode_features(rec, ctx, frame.size(), params, quads))?;
    gpu.read_features(ctx, params, quads.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chroma_of_primaries_and_grey() {
        // Red: H = 0, S = 1.
        let [a, b] = chroma([255.0, 0.0, 0.0]);
        assert!((a - 1.0).abs() < 1e-6 && b.abs() < 1e-6, "{a} {b}");
        // Green: H = 120°, S = 1.
        let [a, b] = chroma([0.0, 200.0, 0.0]);
        assert!((a + 0.5).abs() < 1e-6 && (b - HALF_SQRT3).abs() < 1e-6, "{a} {b}");
        // Blue: H = 240°.
        let [a, b] = chroma([0.0, 0.0, 10.0]);
        assert!((a + 0.5).abs() < 1e-6 && (b + HALF_SQRT3).abs() < 1e-6, "{a} {b}");
        // Half-saturated red: (255, 85, 85): min/sum = 85/425, S = 1 − 0.6 = 0.4.
        let [a, b] = chroma([255.0, 85.0, 85.0]);
        assert!((a - 0.4).abs() < 1e-6 && b.abs() < 1e-6, "{a} {b}");
        assert_eq!(chroma([7.0, 7.0, 7.0]), [0.0, 0.0]);
        assert_eq!(chroma([0.0, 0.0, 0.0]), [0.0, 0.0]);
    }

    #[test]
    fn the_map_of_a_square_is_the_identity_scaled() {
        let quad = [[10.0, 20.0], [74.0, 20.0], [74.0, 84.0], [10.0, 84.0]];
        let map = WindowMap::from_quad(&quad);
        assert_eq!(map.0[8], MAP_PROJECTIVE);
        let [x, y] = map.position(0.25, 0.5);
        assert!((x - 26.0).abs() < 1e-4 && (y - 52.0).abs() < 1e-4, "{x} {y}");
        // A projective quad hits its four corners.
        let quad = [[3.0, 4.0], [40.0, 1.0], [52.0, 47.0], [0.5, 30.0]];
        let map = WindowMap::from_quad(&quad);
        assert_eq!(map.0[8], MAP_PROJECTIVE);
        for (corner, (s, t)) in quad.iter().zip([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]) {
            let p = map.position(s, t);
            assert!((p[0] - corner[0]).abs() < 1e-4 && (p[1] - corner[1]).abs() < 1e-4, "{p:?} {corner:?}");
        }
        // Zero area: every point maps to the one corner.
        let map = WindowMap::from_quad(&[[5.0, 6.0]; 4]);
        assert_eq!(map.0[8], MAP_BILINEAR);
        assert_eq!(map.position(0.3, 0.7), [5.0, 6.0]);
    }

    /// CPF of a window reduced by one level (k = L − 1) over a frame that is
    /// the window itself: each output pixel's 2×2 block, as eq. 1–4 say.
    #[test]
    fn one_level_of_cpf_by_hand() {
        // A 2×2 grey frame sampled by a 2×2 window exactly at its pixels:
        // the quad's corners sit half a pixel outside the centres.
        let px = [[10u8, 40], [20, 30]]; // px[y][x]
        let frame = RgbImage::from_fn(2, 2, |x, y| [px[y][x]; 3]);
        let quad = [[-0.5, -0.5], [1.5, -0.5], [1.5, 1.5], [-0.5, 1.5]];
        let params = WindowEnergyParams { side_log2: 1, cpf_log2: 1 };
        let t = &window_features_cpu(&frame, &params, &[quad]).unwrap()[0];
        // k = L: no reduction; every hierarchy is the window (I at channel 0).
        let i_of = |m: usize, p: usize| t.values[(m * 4 + p) * CHANNELS];
        for m in 0..4 {
            assert_eq!([i_of(m, 0), i_of(m, 1), i_of(m, 2), i_of(m, 3)], [10.0, 40.0, 20.0, 30.0]);
        }
        // L = 2, k = 1: a 4×4 frame sampled by a 4×4 window, reduced to 2×2.
        let f4 = [[1u8, 5, 9, 2], [7, 3, 4, 8], [6, 6, 1, 1], [2, 9, 3, 7]]; // f4[y][x]
        let frame = RgbImage::from_fn(4, 4, |x, y| [f4[y][x]; 3]);
        let quad = [[-0.5, -0.5], [3.5, -0.5], [3.5, 3.5], [-0.5, 3.5]];
        let params = WindowEnergyParams { side_log2: 2, cpf_log2: 1 };
        let t = &window_features_cpu(&frame, &params, &[quad]).unwrap()[0];
        let i_of = |m: usize, p: usize| t.values[(m * 4 + p) * CHANNELS];
        // Top-left block: columns (1, 7) and (5, 3).
        // m0 = 1; m1 = max(min(1,7), min(5,3)) = 3; m2 = min(max(1,7), max(5,3)) = 5; m3 = 7.
        assert_eq!([i_of(0, 0), i_of(1, 0), i_of(2, 0), i_of(3, 0)], [1.0, 3.0, 5.0, 7.0]);
        // Bottom-right block: columns (1, 3) and (1, 7): m1 = max(1, 1) = 1, m2 = min(3, 7) = 3.
        assert_eq!([i_of(0, 3), i_of(1, 3), i_of(2, 3), i_of(3, 3)], [1.0, 1.0, 3.0, 7.0]);
    }

    /// The whole window's levels at once equal `cpf_block`'s, block by
    /// block, bit for bit: every depth from none to six levels, windows
    /// inside, turned, partly outside the frame, perspective and folded
    /// (a self-crossing quadrilateral, whose map divides by values through
    /// zero).
    #[test]
    fn window_levels_equal_the_blocks_one_at_a_time() {
        let frame = RgbImage::from_fn(37, 29, |x, y| [(x * 7 + y) as u8, (y * 9) as u8, ((x * y * 13) % 251) as u8]);
        let quads: [Quad; 5] = [
            [[3.0, 2.0], [30.0, 2.0], [30.0, 25.0], [3.0, 25.0]],
            [[18.0, -4.0], [40.0, 12.0], [20.0, 33.0], [-3.0, 15.0]],
            [[-10.0, -6.0], [12.0, -6.0], [12.0, 9.0], [-10.0, 9.0]],
            [[3.0, 4.0], [34.0, 1.0], [30.0, 27.0], [0.5, 20.0]],
            [[2.0, 2.0], [30.0, 26.0], [30.0, 2.0], [2.0, 26.0]],
        ];
        let mut levels = Vec::new();
        let mut compared = 0;
        for (side_log2, cpf_log2) in [(1, 1), (2, 1), (3, 2), (4, 1), (5, 4), (6, 4), (7, 1)] {
            let params = WindowEnergyParams { side_log2, cpf_log2 };
            let side = params.level_side();
            for quad in &quads {
                let map = WindowMap::from_quad(quad);
                window_levels(&frame, &map, &params, &mut levels);
                assert_eq!(levels.len(), side * side);
                for (p, got) in levels.iter().enumerate() {
                    let want = cpf_block(&frame, &map, &params, p % side, p / side);
                    let bits = |v: &[[f32; 4]; 4]| v.map(|c| c.map(f32::to_bits));
                    assert_eq!(bits(got), bits(&want), "L {side_log2}, k {cpf_log2}, {quad:?}, pixel {p}");
                    compared += 1;
                }
            }
        }
        assert!(compared > 1000);
    }

    /// Eq. 22–26 on two windows: one the template itself (energy 0), one shifted.
    #[test]
    fn the_template_window_has_zero_energy_and_energies_sum_to_two() {
        let frame = RgbImage::from_fn(40, 30, |x, y| [(x * 6) as u8, (y * 8) as u8, ((x * y) % 251) as u8]);
        let params = WindowEnergyParams { side_log2: 3, cpf_log2: 2 };
        let quad = [[5.0, 5.0], [21.0, 5.0], [21.0, 21.0], [5.0, 21.0]];
        let template = window_features_cpu(&frame, &params, &[quad]).unwrap().remove(0);
        let shifted = quad.map(|[x, y]| [x + 3.0, y + 1.0]);
        let e = window_energy_cpu(&frame, &[quad, shifted, shifted], &template).unwrap();
        assert_eq!(e.energies[0], 0.0);
        assert!(e.energies[1] > 0.0 && e.intensity_total > 0.0 && e.colour_total > 0.0);
        let total: f32 = e.energies.iter().sum();
        assert!((total - 2.0).abs() < 1e-5, "{total}");
    }

    /// Eq. 5–13 by hand: intensities 10 and 13 (C_I = 9), pure red against
    /// pure green (chroma (1, 0) and (−½, √3/2): C_HS = 2.25 + 0.75 = 3),
    /// edges (4, −2) against (2, 0) (E = ¼(4 + 4) = 2):
    /// U = 1·(9 + 0.0125·3) + 2·2 = 13.0375.
    #[test]
    fn pixel_match_energy_by_hand() {
        let p = MatchPixel { intensity: 10.0, rgb: [200.0, 0.0, 0.0], edge: [4.0, -2.0] };
        let q = MatchPixel { intensity: 13.0, rgb: [0.0, 90.0, 0.0], edge: [2.0, 0.0] };
        let u = pixel_match_energy(&p, &q, &PixelMatchCoefficients::default());
        assert!((u - 13.0375).abs() < 1e-4, "{u}");
        assert_eq!(pixel_match_energy(&p, &p, &PixelMatchCoefficients::default()), 0.0);
        // θ weighs the edge term alone.
        let no_edges = PixelMatchCoefficients { theta: 0.0, ..PixelMatchCoefficients::default() };
        assert!((pixel_match_energy(&p, &q, &no_edges) - 9.0375).abs() < 1e-4);
    }

    #[test]
    fn a_grey_frame_packs_as_its_colour_frame() {
        let grey = GrayImage::from_fn(5, 3, |x, y| (x * 50 + y * 7) as u8);
        assert_eq!(pack_gray(&grey), pack_rgb(&RgbImage::from_gray(&grey)));
    }

    #[test]
    fn bad_sizes_and_windows_are_refused() {
        let frame = RgbImage::from_fn(4, 4, |_, _| [1, 2, 3]);
        let p = WindowEnergyParams { side_log2: 2, cpf_log2: 3 };
        assert!(window_features_cpu(&frame, &p, &[]).is_err());
        let p = WindowEnergyParams { side_log2: 2, cpf_log2: 1 };
        let nan = [[f32::NAN, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert!(window_features_cpu(&frame, &p, &[nan]).is_err());
        let template = WindowTemplate { params: p, values: vec![0.0; 3] };
        assert!(window_energy_cpu(&frame, &[], &template).is_err());
    }
}
