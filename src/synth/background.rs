//! Static backdrops of the scenes (flat, textured, cluttered), the noise and
//! quantisation applied to every frame, and the seeded random streams that
//! make a seed always give the same bytes.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::canvas::*;
use crate::image::{FloatImage, GrayImage};
use crate::{Error, Result};

/// Add zero-mean Gaussian noise of standard deviation `noise_sigma` (grey
/// levels) to `image`, clamp to 0..255 and round to the nearest integer (halves
/// away from zero) into `out` (resized if needed). Gaussian deviates come from
/// the Box–Muller transform of `rng`'s uniforms; with `noise_sigma == 0` the
/// generator is not touched.
pub fn add_noise_and_quantise(image: &FloatImage, noise_sigma: f32, rng: &mut impl Rng, out: &mut GrayImage) {
    let (w, h) = image.size();
    if out.size() != (w, h) {
        out.resize(w, h);
    }
    if noise_sigma == 0.0 {
        quantise(image.data(), out.data_mut());
        return;
    }
    // The noisy values of a piece of the image, then the piece quantised.
    let mut noisy = [0.0f32; NOISE_PIECE];
    for (o, v) in out.data_mut().chunks_mut(NOISE_PIECE).zip(image.data().chunks(NOISE_PIECE)) {
        for (n, v) in noisy.chunks_mut(2).zip(v.chunks(2)) {
            let (z0, z1) = standard_normal_pair(rng);
            n[0] = v[0] + noise_sigma * z0;
            if v.len() > 1 {
                n[1] = v[1] + noise_sigma * z1;
            }
        }
        quantise(&noisy[..v.len()], o);
    }
}

/// Pixels per piece of [`add_noise_and_quantise`] (even, so every piece but
/// the last takes whole pairs of deviates, as one pass over the image would).
const NOISE_PIECE: usize = 256;

crate::early::simd_dispatch!(fn quantise(values: &[f32], out: &mut [u8]) => quantise_body);

/// Each value clamped to 0..255 and rounded to the nearest integer (halves
/// away from zero). With SSE4.1 or later (the dispatched builds) the
/// rounding is a few instructions instead of a call to the C library.
#[inline(always)]
fn quantise_body(values: &[f32], out: &mut [u8]) {
    for (o, &v) in out.iter_mut().zip(values) {
        *o = v.clamp(0.0, 255.0).round() as u8;
    }
}

/// Two independent standard normal deviates (Box–Muller).
fn standard_normal_pair(rng: &mut impl Rng) -> (f32, f32) {
    // 1 − U lies in (0, 1], so the logarithm is finite.
    let u1 = 1.0 - rng.random::<f32>();
    let u2 = rng.random::<f32>();
    let r = (-2.0 * u1.ln()).sqrt();
    let (s, c) = (std::f32::consts::TAU * u2).sin_cos();
    (r * c, r * s)
}

/// The static backdrop of a scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Background {
    /// One flat grey level ([`BACKGROUND_GREY`]).
    Flat,
    /// Seeded smooth value noise (three octaves) around [`BACKGROUND_GREY`].
    #[default]
    Textured,
    /// A milder texture with seeded random rectangles, lines and blobs on it.
    Cluttered,
}

impl Background {
    /// The names [`Background::from_str`](std::str::FromStr) accepts.
    pub const NAMES: [&'static str; 3] = ["flat", "textured", "cluttered"];

    /// The lowercase name of this background.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Background::Flat => "flat",
            Background::Textured => "textured",
            Background::Cluttered => "cluttered",
        }
    }
}

impl std::str::FromStr for Background {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s {
            "flat" => Ok(Background::Flat),
            "textured" => Ok(Background::Textured),
            "cluttered" => Ok(Background::Cluttered),
            _ => Err(Error::Parameter(format!("unknown background '{s}' (known: {})", Background::NAMES.join(", ")))),
        }
    }
}

/// Mean grey level of every background.
pub const BACKGROUND_GREY: f32 = 100.0;
/// Texture octaves: (amplitude in grey levels, lattice cell in pixels).
const TEXTURE_OCTAVES: [(f32, f64); 3] = [(28.0, 48.0), (14.0, 20.0), (6.0, 8.0)];
/// Clutter shapes keep to this grey range, so a bright target (> 200) stays distinct.
const CLUTTER_GREYS: std::ops::Range<f32> = 20.0..170.0;

/// Render a static background into a new `width`×`height` canvas at factor
/// `supersample`. `seed` picks the texture and clutter (same seed, same image).
pub fn render_background(
    kind: Background,
    width: usize,
    height: usize,
    supersample: usize,
    seed: u64,
) -> Result<Canvas> {
    let mut canvas = Canvas::new(width, height, supersample, BACKGROUND_GREY)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(BACKGROUND_STREAM);
    match kind {
        Background::Flat => {}
        Background::Textured => {
            let noise = ValueNoise::new(width, height, 1.0, &mut rng);
            noise.paint(&mut canvas, BACKGROUND_GREY);
        }
        Background::Cluttered => {
            let noise = ValueNoise::new(width, height, 0.5, &mut rng);
            noise.paint(&mut canvas, BACKGROUND_GREY);
            draw_clutter(&mut canvas, &mut rng);
        }
    }
    Ok(canvas)
}

/// ChaCha stream of the background; frame `k`'s noise uses `FRAME_STREAM_BASE + k`.
const BACKGROUND_STREAM: u64 = 0;
/// First ChaCha stream used for per-frame noise.
pub const FRAME_STREAM_BASE: u64 = 1 << 32;

/// The generator of frame `frame`'s pixel noise for sequence seed `seed`:
/// its own ChaCha8 stream, so frames can be rendered in any order.
#[must_use]
pub fn frame_rng(seed: u64, frame: usize) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(FRAME_STREAM_BASE + frame as u64);
    rng
}

/// Seeded value noise: random values on square lattices, interpolated with the
/// quintic fade `6t⁵ − 15t⁴ + 10t³` (smooth to second order), summed over octaves.
struct ValueNoise {
    octaves: Vec<(f32, f64, usize, Vec<f32>)>,
}

impl ValueNoise {
    fn new(width: usize, height: usize, scale: f32, rng: &mut ChaCha8Rng) -> Self {
        let octaves = TEXTURE_OCTAVES
            .iter()
            .map(|&(amp, cell)| {
                let gw = (width as f64 / cell).ceil() as usize + 3;
                let gh = (height as f64 / cell).ceil() as usize + 3;
                let grid = (0..gw * gh).map(|_| rng.random_range(-1.0f32..1.0)).collect();
                (amp * scale, cell, gw, grid)
            })
            .collect();
        Self { octaves }
    }

    /// Set every cell of `canvas` to `base` plus the noise at the cell's
    /// centre. Separable: per row, the lattice is interpolated in y once, then
    /// every cell interpolates in x between precomputed columns.
    fn paint(&self, canvas: &mut Canvas, base: f32) {
        let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
        // +1 keeps positions down to −0.5 inside the lattice; the lattice has
        // two spare nodes past the far border, so `i + 1` stays in range.
        let lattice = |coord: f64, cell: f64| {
            let f = (coord + 1.0) / cell;
            let i = f.floor().max(0.0);
            (i as usize, fade(f - i) as f32)
        };
        let sw = canvas.width() * canvas.supersample();
        let columns: Vec<Vec<(usize, f32)>> = self
            .octaves
            .iter()
            .map(|(_, cell, _, _)| (0..sw).map(|i| lattice(canvas.sample_centre(i, 0)[0], *cell)).collect())
            .collect();
        let s = canvas.supersample() as f64;
        let widest = self.octaves.iter().map(|o| o.2).max().unwrap_or(0);
        canvas.samples_mut().par_chunks_mut(sw).enumerate().for_each_init(
            || vec![0.0f32; widest],
            |between_rows, (j, row)| {
                row.fill(base);
                let y = (j as f64 + 0.5) / s - 0.5;
                for ((amp, cell, gw, grid), columns) in self.octaves.iter().zip(&columns) {
                    let (iy, ty) = lattice(y, *cell);
                    let (upper, lower) = (&grid[iy * gw..][..*gw], &grid[(iy + 1) * gw..][..*gw]);
                    for ((m, &u), &l) in between_rows.iter_mut().zip(upper).zip(lower) {
                        *m = u * (1.0 - ty) + l * ty;
                    }
                    for (v, &(ix, tx)) in row.iter_mut().zip(columns) {
                        *v += amp * (between_rows[ix] * (1.0 - tx) + between_rows[ix + 1] * tx);
                    }
                }
            },
        );
    }
}

/// Seeded static clutter: turned rectangles, lines 1–3 px wide and elliptic blobs.
fn draw_clutter(canvas: &mut Canvas, rng: &mut ChaCha8Rng) {
    let (w, h) = (canvas.width() as f64, canvas.height() as f64);
    let extent = w.min(h);
    for _ in 0..12 {
        let c = [rng.random_range(0.0..w), rng.random_range(0.0..h)];
        let half = [rng.random_range(3.0..extent / 8.0), rng.random_range(3.0..extent / 8.0)];
        let (sa, ca) = rng.random_range(0.0..std::f64::consts::PI).sin_cos();
        let corners: Vec<[f64; 2]> = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
            .iter()
            .map(|[u, v]| {
                let (u, v) = (u * half[0], v * half[1]);
                [c[0] + ca * u - sa * v, c[1] + sa * u + ca * v]
            })
            .collect();
        let grey = rng.random_range(CLUTTER_GREYS);
        canvas.fill_polygon(&corners, FillRule::EvenOdd, grey);
    }
    for _ in 0..10 {
        let a = [rng.random_range(0.0..w), rng.random_range(0.0..h)];
        let b = [rng.random_range(0.0..w), rng.random_range(0.0..h)];
        let width = rng.random_range(1.0..3.0);
        let grey = rng.random_range(CLUTTER_GREYS);
        canvas.fill_segment(a, b, width, grey);
    }
    for _ in 0..8 {
        let c = [rng.random_range(0.0..w), rng.random_range(0.0..h)];
        let radii = [rng.random_range(3.0..extent / 10.0), rng.random_range(3.0..extent / 10.0)];
        let angle = rng.random_range(0.0..std::f64::consts::PI);
        let grey = rng.random_range(CLUTTER_GREYS);
        canvas.fill_ellipse(c, radii, angle, grey);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dispatched quantisation rounds as the plain expression does,
    /// halves away from zero, at the clamps, and on values one ulp from a
    /// half; and the pieces of the noisy path take the deviates in the
    /// order of one pass over the image.
    #[test]
    fn quantise_equals_the_plain_rounding_and_pieces_keep_the_noise() {
        let mut values = vec![-3.0, -0.5, -0.0, 0.5, 1.5, 2.5, 127.5, 254.5, 255.0, 255.49998, 300.0, f32::NAN];
        for k in 0..=255u8 {
            let half = f32::from(k) + 0.5;
            // One ulp below and above (positive values: the next bit patterns).
            let (below, above) = (f32::from_bits(half.to_bits() - 1), f32::from_bits(half.to_bits() + 1));
            values.extend([half, below, above, f32::from(k)]);
        }
        let mut out = vec![0u8; values.len()];
        quantise(&values, &mut out);
        for (&v, &o) in values.iter().zip(&out) {
            assert_eq!(o, v.clamp(0.0, 255.0).round() as u8, "{v:?}");
        }

        // 641 pixels: two whole pieces and an odd tail.
        let image = FloatImage::from_vec(641, 1, (0..641).map(|x| (x % 256) as f32 + 0.25).collect()).unwrap();
        let mut noisy = GrayImage::new(0, 0);
        add_noise_and_quantise(&image, 3.0, &mut ChaCha8Rng::seed_from_u64(5), &mut noisy);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut expected = Vec::new();
        for pair in image.data().chunks(2) {
            let (z0, z1) = standard_normal_pair(&mut rng);
            for (v, z) in pair.iter().zip([z0, z1]) {
                expected.push((v + 3.0 * z).clamp(0.0, 255.0).round() as u8);
            }
        }
        assert_eq!(noisy.data(), &expected[..]);
    }
}
