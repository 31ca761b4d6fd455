//! GPU/CPU parity of `shaders/log.wgsl` against its twin in src/early/log.rs.
use crate::common;
use crate::per_size;

use pipetrack::early::log;
use pipetrack::testimage::natural;

/// LoG of 0..255 images: values up to a few hundred, sums of 2 × (2r+1)
/// products per pass, and the GPU may fuse multiply-adds the CPU rounds twice:
/// absolute tolerance 2e-3 grey levels per pixel², no relative part.
const LOG_ATOL: f32 = 2e-3;

fn parity_log_sigmas(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_log_sigmas/{w}x{h}")) else { return };
    let src = natural(w, h, 13).to_f32();
    for sigma in [1.2f32, 0.7, 2.5] {
        let p = log::LogParams { sigma };
        let cpu = log::log(&src, &p).unwrap();
        let gpu = log::log_gpu(ctx, &src, &p).unwrap();
        let worst = cpu.data().iter().zip(gpu.data()).map(|(c, g)| (c - g).abs()).fold(0.0f32, f32::max);
        eprintln!("log/{w}x{h}/sigma{sigma}: max |gpu − cpu| = {worst:e}");
        common::assert_close(&format!("log/{w}x{h}/sigma{sigma}"), &cpu, &gpu, LOG_ATOL, 0.0);
    }
}
per_size!(parity_log_sigmas);

/// A sharp synthetic step (0 | 255) drives the LoG to its largest values.
#[test]
fn parity_log_strong_step() {
    let Some((ctx, _g)) = common::gpu("parity_log_strong_step") else { return };
    let src = pipetrack::FloatImage::from_fn(97, 61, |x, y| if x * 2 + y > 100 { 255.0 } else { 0.0 });
    let p = log::LogParams::default();
    let cpu = log::log(&src, &p).unwrap();
    let gpu = log::log_gpu(ctx, &src, &p).unwrap();
    common::assert_close("log/step", &cpu, &gpu, LOG_ATOL, 0.0);
}
