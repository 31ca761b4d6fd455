// Separable Gaussian smoothing (000 eq. 1: G* applied to each frame; 001).
// Two entry points, one per 1-D pass; clamp-to-edge borders.
// Kept in sync with `GaussianUniform` in src/early/gaussian.rs.
// Stacked images (a stack of layers, each width×height after the one
// before) are one dispatch: the grid's z is the layer (`id.z`).

struct Params {
    width: u32,
    height: u32,
    radius: u32,
    _pad: u32,
    // Half kernel: weights[k] for offsets ±k, k = 0..=radius, 4 per vec4.
    weights: array<vec4<f32>, 15>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> src: array<f32>;
@group(0) @binding(2) var<storage, read_write> dst: array<f32>;

fn weight(k: u32) -> f32 {
    return params.weights[k / 4u][k % 4u];
}

// Horizontal pass: dst(x, y) = w0·src(x) + Σ_k w_k·(src(x−k) + src(x+k)).
@compute @workgroup_size(16, 16)
fn blur_rows(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let row = (id.z * params.height + id.y) * params.width;
    let last = i32(params.width) - 1;
    let x = i32(id.x);
    var sum = weight(0u) * src[row + id.x];
    for (var k = 1u; k <= params.radius; k++) {
        let l = u32(clamp(x - i32(k), 0, last));
        let r = u32(clamp(x + i32(k), 0, last));
        sum += weight(k) * (src[row + l] + src[row + r]);
    }
    dst[row + id.x] = sum;
}

// Vertical pass, same arithmetic along columns.
@compute @workgroup_size(16, 16)
fn blur_cols(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let w = params.width;
    let base = id.z * params.height * w + id.x;
    let last = i32(params.height) - 1;
    let y = i32(id.y);
    var sum = weight(0u) * src[base + id.y * w];
    for (var k = 1u; k <= params.radius; k++) {
        let u = u32(clamp(y - i32(k), 0, last));
        let d = u32(clamp(y + i32(k), 0, last));
        sum += weight(k) * (src[base + u * w] + src[base + d * w]);
    }
    dst[base + id.y * w] = sum;
}
