//! GPU/CPU parity of `shaders/cpf.wgsl` (the `cpf` stage, four critical-point
//! filter hierarchies) and `shaders/edge_pyramid.wgsl` (the `edge_pyramid`
//! stage, averaged edge hierarchies) against their twins in
//! src/early/cpf.rs and src/early/edge_pyramid.rs. Both shaders build their
//! levels with `shaders/pyramid_tile.wgsl` (tiles of 16×16, five levels to a
//! dispatch), whose index arithmetic every test here goes through;
//! `parity_pyramid_tile_*` aims at its edges.
//!
//! Tolerances: CPF levels must be **equal** (min/max are exact in f32, both
//! twins pick the same children). Edge pyramid levels: `atol 1e-4, rtol 1e-5`
//! (sums of four values times ¼ in the same order on both sides; the
//! tolerance only absorbs a possible reassociation by the GPU compiler).
use crate::common;
use crate::per_size;

use pipetrack::FloatImage;
use pipetrack::early::{cpf, edge_pyramid};
use pipetrack::testimage::natural;

const EDGE_PYRAMID_ATOL: f32 = 1e-4;
const EDGE_PYRAMID_RTOL: f32 = 1e-5;

/// A signed image standing in for a Sobel edge image (values −255..255).
fn signed(w: usize, h: usize, seed: u64) -> FloatImage {
    let a = natural(w, h, seed).to_f32();
    let b = natural(w, h, seed + 100).to_f32();
    FloatImage::from_vec(w, h, a.data().iter().zip(b.data()).map(|(x, y)| x - y).collect()).expect("same size")
}

fn parity_cpf_all_levels_exact(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_cpf_all_levels_exact/{w}x{h}")) else { return };
    let src = natural(w, h, 21).to_f32();
    let cpu = cpf::cpf(&src);
    let gpu = cpf::cpf_gpu(ctx, &src).unwrap();
    let levels = cpf::level_sizes(w, h).len();
    for m in 0..cpf::HIERARCHIES {
        assert_eq!(cpu.hierarchies[m].len(), levels, "cpf/{w}x{h}: CPU level count");
        assert_eq!(gpu.hierarchies[m].len(), levels, "cpf/{w}x{h}: GPU level count");
        for (k, (c, g)) in cpu.hierarchies[m].iter().zip(&gpu.hierarchies[m]).enumerate() {
            common::assert_equal(&format!("cpf/{w}x{h}/m{m}/level{k}"), c, g);
        }
    }
}
// One dispatch builds up to five levels from 16×16 tiles: 33×65 and 1500×7
// need two and three dispatches with odd sizes inside and across tiles,
// 2049×1 and 1×2049 three from a one-row and a one-column image.
per_size!(parity_cpf_all_levels_exact; w256_h256 = (256, 256); w1_h7 = (1, 7); w7_h1 = (7, 1);
    w33_h65 = (33, 65); w1500_h7 = (1500, 7); w2049_h1 = (2049, 1); w1_h2049 = (1, 2049));

/// Saddle hierarchies depend on which child pairs the inner min/max takes;
/// an image with a strong row/column asymmetry makes a swapped pairing fail.
#[test]
fn parity_cpf_saddles_on_stripes() {
    let Some((ctx, _g)) = common::gpu("parity_cpf_saddles_on_stripes") else { return };
    let src = FloatImage::from_fn(33, 18, |x, y| ((x * 7 + y * 13) % 17) as f32 + if y % 2 == 0 { 100.0 } else { 0.0 });
    let cpu = cpf::cpf(&src);
    let gpu = cpf::cpf_gpu(ctx, &src).unwrap();
    assert_eq!(cpu, gpu);
}

fn parity_edge_pyramid_all_levels(w: usize, h: usize) {
    let Some((ctx, _g)) = common::gpu(&format!("parity_edge_pyramid_all_levels/{w}x{h}")) else { return };
    let gx = signed(w, h, 3);
    let gy = signed(w, h, 4);
    let cpu = edge_pyramid::edge_pyramid(&gx, &gy).unwrap();
    let gpu = edge_pyramid::edge_pyramid_gpu(ctx, &gx, &gy).unwrap();
    let levels = cpf::level_sizes(w, h).len();
    assert_eq!((cpu.horizontal.len(), cpu.vertical.len()), (levels, levels), "edge_pyramid/{w}x{h}: CPU level count");
    assert_eq!((gpu.horizontal.len(), gpu.vertical.len()), (levels, levels), "edge_pyramid/{w}x{h}: GPU level count");
    for k in 0..levels {
        for (dir, c, g) in [("h", &cpu.horizontal[k], &gpu.horizontal[k]), ("v", &cpu.vertical[k], &gpu.vertical[k])] {
            common::assert_close(
                &format!("edge_pyramid/{w}x{h}/{dir}/level{k}"),
                c,
                g,
                EDGE_PYRAMID_ATOL,
                EDGE_PYRAMID_RTOL,
            );
        }
    }
}
per_size!(parity_edge_pyramid_all_levels; w256_h256 = (256, 256); w1_h7 = (1, 7); w7_h1 = (7, 1);
    w33_h65 = (33, 65); w1500_h7 = (1500, 7); w2049_h1 = (2049, 1); w1_h2049 = (1, 2049));

/// Both stages through `pyramid_tile.wgsl` at sizes on its edges: a first
/// built level of exactly one 16×16 tile and one pixel more (32×32, 34×34),
/// exactly five levels in one dispatch and five plus one (32×32 builds 5,
/// 64×64 builds 6), and a last tile one pixel wide (1023×17 → 512×9, …).
fn parity_pyramid_tile_both_stages(w: usize, h: usize) {
    parity_cpf_all_levels_exact(w, h);
    parity_edge_pyramid_all_levels(w, h);
}
per_size!(parity_pyramid_tile_both_stages; w32_h32 = (32, 32); w34_h34 = (34, 34); w64_h64 = (64, 64);
    w1023_h17 = (1023, 17));

#[test]
fn parity_edge_pyramid_rejects_mismatched_inputs() {
    let Some((ctx, _g)) = common::gpu("parity_edge_pyramid_rejects_mismatched_inputs") else { return };
    let a = FloatImage::new(4, 4);
    let b = FloatImage::new(4, 3);
    assert!(edge_pyramid::edge_pyramid_gpu(ctx, &a, &b).is_err());
    assert!(edge_pyramid::edge_pyramid(&a, &b).is_err());
}
