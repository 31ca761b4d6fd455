// Sum of two consecutive smoothed frames G*_t + G*_{t+1}: 000 extracts edge
// orientation from it so that edges of a moving object are dense in both frames.
// Kept in sync with `FrameSumUniform` in src/early/frame_sum.rs.
// Stacked images (a stack of layers, each width×height after the one
// before) are one dispatch: the grid's z is the layer (`id.z`).

struct Params {
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> a: array<f32>;
@group(0) @binding(2) var<storage, read> b: array<f32>;
@group(0) @binding(3) var<storage, read_write> sum: array<f32>;

@compute @workgroup_size(16, 16)
fn frame_sum(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let i = (id.z * params.height + id.y) * params.width + id.x;
    sum[i] = a[i] + b[i];
}
