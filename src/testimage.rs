//! Seeded "natural-looking" test images: smooth multi-scale texture with
//! hard-edged shapes and mild noise, used by parity tests and benchmarks.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::image::GrayImage;

/// A `width`×`height` 8-bit image: three octaves of smooth value noise, a few
/// filled rectangles and discs with sharp borders, and ±3 grey levels of noise.
#[must_use]
pub fn natural(width: usize, height: usize, seed: u64) -> GrayImage {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Value noise on coarse lattices, bilinearly interpolated.
    let octaves: Vec<(f32, usize, Vec<f32>)> = [(48.0f32, 32usize), (24.0, 12), (10.0, 5)]
        .iter()
        .map(|&(amp, cell)| {
            let gw = width / cell + 2;
            let gh = height / cell + 2;
            (amp, cell, (0..gw * gh).map(|_| rng.random_range(-1.0..1.0)).collect())
        })
        .collect();
    let shapes: Vec<(u8, [f32; 4], f32)> = (0..6)
        .map(|_| {
            let kind = rng.random_range(0..2u8);
            let x = rng.random_range(0.0..width as f32);
            let y = rng.random_range(0.0..height as f32);
            let a = rng.random_range(3.0..(width.max(4) as f32 / 4.0).max(3.5));
            let b = rng.random_range(3.0..(height.max(4) as f32 / 4.0).max(3.5));
            (kind, [x, y, a, b], rng.random_range(-70.0..70.0))
        })
        .collect();
    let mut img = GrayImage::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let mut v = 128.0f32;
            for (amp, cell, grid) in &octaves {
                let gw = width / cell + 2;
                let fx = x as f32 / *cell as f32;
                let fy = y as f32 / *cell as f32;
                let (ix, iy) = (fx as usize, fy as usize);
                let (tx, ty) = (fx - ix as f32, fy - iy as f32);
                let g = |i: usize, j: usize| grid[j * gw + i];
                let top = g(ix, iy) * (1.0 - tx) + g(ix + 1, iy) * tx;
                let bot = g(ix, iy + 1) * (1.0 - tx) + g(ix + 1, iy + 1) * tx;
                v += amp * (top * (1.0 - ty) + bot * ty);
            }
            for (kind, [sx, sy, a, b], delta) in &shapes {
                let (dx, dy) = (x as f32 - sx, y as f32 - sy);
                let inside = if *kind == 0 {
                    dx.abs() <= *a && dy.abs() <= *b
                } else {
                    (dx / a).powi(2) + (dy / b).powi(2) <= 1.0
                };
                if inside {
                    v += delta;
                }
            }
            v += rng.random_range(-3.0..3.0);
            img.set(x, y, v.round().clamp(0.0, 255.0) as u8);
        }
    }
    img
}
