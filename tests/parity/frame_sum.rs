//! GPU/CPU parity of `shaders/frame_sum.wgsl` against `early::frame_sum`.
//!
//! Tolerance: exact (one correctly rounded f32 addition per pixel).
use crate::common;

use pipetrack::early::frame_sum;
use pipetrack::early::gaussian::{self, GaussianParams};
use pipetrack::testimage::natural;

#[test]
fn parity_frame_sum_exact_all_sizes() {
    let Some((ctx, _g)) = common::gpu("parity_frame_sum_exact_all_sizes") else { return };
    let g = GaussianParams::default();
    for &(w, h) in common::PARITY_SIZES {
        let a = gaussian::gaussian(&natural(w, h, 31).to_f32(), &g).unwrap();
        let b = gaussian::gaussian(&natural(w, h, 32).to_f32(), &g).unwrap();
        let cpu = frame_sum::frame_sum(&a, &b).unwrap();
        let gpu = frame_sum::frame_sum_gpu(ctx, &a, &b).unwrap();
        common::assert_equal(&format!("frame_sum/{w}x{h}"), &cpu, &gpu);
    }
}
