//! GPU/CPU parity of `shaders/gaussian.wgsl` and `shaders/ingest.wgsl`
//! against their twins in src/early/.
mod common;

use pipetrack::early::{gaussian, ingest};
use pipetrack::testimage::natural;

/// Smoothed values are 0..255 sums of at most ~130 products: a few ULPs of 255.
const GAUSSIAN_ATOL: f32 = 2e-4;

#[test]
fn parity_ingest_bytes_exact() {
    let Some((ctx, _g)) = common::gpu("parity_ingest_bytes_exact") else { return };
    for &(w, h) in common::PARITY_SIZES {
        let frame = natural(w, h, 7);
        let cpu = ingest::ingest_gray(&frame);
        let gpu = ingest::ingest_gray_gpu(ctx, &frame).unwrap();
        common::assert_equal(&format!("ingest/{w}x{h}"), &cpu, &gpu);
    }
}

#[test]
fn parity_gaussian_all_sizes_and_sigmas() {
    let Some((ctx, _g)) = common::gpu("parity_gaussian_all_sizes_and_sigmas") else { return };
    for &(w, h) in common::PARITY_SIZES {
        let src = natural(w, h, 11).to_f32();
        for sigma in [0.8f32, 1.0, 1.2, 2.5] {
            let p = gaussian::GaussianParams { sigma };
            let cpu = gaussian::smooth(&src, &p).unwrap();
            let gpu = gaussian::smooth_gpu(ctx, &src, &p).unwrap();
            common::assert_close(&format!("gaussian/{w}x{h}/sigma{sigma}"), &cpu, &gpu, GAUSSIAN_ATOL, 1e-6);
        }
    }
}
