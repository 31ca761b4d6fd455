// Thresholded temporal difference (000 eq. 1): the binary motion image
// |G*_t − G*_{t+1}| > threshold, stored as f32 (1.0 moving, 0.0 still).
// Two entry points: the mask alone, and the mask with the frame sum; each
// declares its own buffers at bindings 1, 2, … in the order
// src/early/temporal_diff.rs passes them.
// Kept in sync with `TemporalDiffUniform` in src/early/temporal_diff.rs.
// Stacked images (a stack of layers, each width×height after the one
// before) are one dispatch: the grid's z is the layer (`id.z`).

struct Params {
    width: u32,
    height: u32,
    threshold: f32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> prev: array<f32>;
@group(0) @binding(2) var<storage, read> cur: array<f32>;
@group(0) @binding(3) var<storage, read_write> mask: array<f32>;

@compute @workgroup_size(16, 16)
fn temporal_diff(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let i = (id.z * params.height + id.y) * params.width + id.x;
    // 000 eq. 1: ∂I/∂t = G*_t − G*_{t+1}, then thresholded on its magnitude.
    let moving = abs(prev[i] - cur[i]) > params.threshold;
    mask[i] = select(0.0, 1.0, moving);
}

// The mask and the frame sum G*_t + G*_{t+1} (000 eq. 2's input, the
// `frame_sum` stage) in one pass over the two frames, as the CPU backend
// fuses them; each output equals its own stage's.
@group(0) @binding(1) var<storage, read> fused_prev: array<f32>;
@group(0) @binding(2) var<storage, read> fused_cur: array<f32>;
@group(0) @binding(3) var<storage, read_write> fused_mask: array<f32>;
@group(0) @binding(4) var<storage, read_write> fused_sum: array<f32>;

@compute @workgroup_size(16, 16)
fn temporal_diff_and_sum(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let i = (id.z * params.height + id.y) * params.width + id.x;
    let p = fused_prev[i];
    let c = fused_cur[i];
    fused_mask[i] = select(0.0, 1.0, abs(p - c) > params.threshold);
    fused_sum[i] = p + c;
}
