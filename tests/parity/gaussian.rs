//! GPU/CPU parity of `shaders/gaussian.wgsl` against its twin in src/early/gaussian.rs.
use crate::common;
use crate::per_size;

use pipetrack::early::gaussian;
use pipetrack::testimage::natural;

/// Smoothed values are 0..255 sums of at most ~130 products: a few ULPs of 255.
const GAUSSIAN_ATOL: f32 = 2e-4;

fn parity_gaussian_sigmas(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_gaussian_sigmas/{w}x{h}")) else { return };
    let src = natural(w, h, 11).to_f32();
    for sigma in [0.8f32, 1.0, 1.2, 2.5, gaussian::MAX_SIGMA] {
        let p = gaussian::GaussianParams { sigma };
        let cpu = gaussian::gaussian(&src, &p).unwrap();
        let gpu = gaussian::gaussian_gpu(ctx, &src, &p).unwrap();
        common::assert_close(&format!("gaussian/{w}x{h}/sigma{sigma}"), &cpu, &gpu, GAUSSIAN_ATOL, 1e-6);
    }
}
per_size!(parity_gaussian_sigmas);
