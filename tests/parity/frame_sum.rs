//! GPU/CPU parity of `shaders/frame_sum.wgsl` against `early::frame_sum`.
//!
//! Tolerance: exact (one correctly rounded f32 addition per pixel).
use crate::common;
use crate::per_size;

use pipetrack::early::frame_sum;
use pipetrack::early::gaussian::{self, GaussianParams};
use pipetrack::testimage::natural;

fn parity_frame_sum_exact(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_frame_sum_exact/{w}x{h}")) else { return };
    let g = GaussianParams::default();
    let a = gaussian::gaussian(&natural(w, h, 31).to_f32(), &g).unwrap();
    let b = gaussian::gaussian(&natural(w, h, 32).to_f32(), &g).unwrap();
    let cpu = frame_sum::frame_sum(&a, &b).unwrap();
    let gpu = frame_sum::frame_sum_gpu(ctx, &a, &b).unwrap();
    common::assert_equal(&format!("frame_sum/{w}x{h}"), &cpu, &gpu);
}
per_size!(parity_frame_sum_exact);
