// Laplacian of Gaussian, separable (001 "Real-time line detection": LoG with
// σ = 1.2 for Marr–Hildreth edges):
//   LoG = g''(x)·g(y) + g(x)·g''(y).
// Two entry points, one per 1-D pass; clamp-to-edge borders. Each entry point
// declares its own storage bindings (1, 2, 3 in the order `encode` passes
// them); each pipeline's layout is built from its entry point's declared
// bindings in src/early/log.rs, so the two sets do not collide.
// Kept in sync with `LogUniform` in src/early/log.rs.
// Stacked images (a stack of layers, each width×height after the one
// before) are one dispatch: the grid's z is the layer (`id.z`).
// Each pass computes the pixels of `region` (x0, y0, x1, y1: columns x0..x1,
// rows y0..y1 of every layer), the grid covering the region; a pixel's value
// is the whole frame's (borders clamp to the frame, not to the region).

struct Params {
    width: u32,
    height: u32,
    radius: u32,
    _pad: u32,
    region: vec4<u32>,
    // Half kernels for offsets ±k, k = 0..=radius, 4 per vec4: g (Gaussian,
    // sums to 1) and d (its second derivative, sums to 0, Σ k²·d_k = 2).
    gauss: array<vec4<f32>, 7>,
    second: array<vec4<f32>, 7>,
}

@group(0) @binding(0) var<uniform> params: Params;

// `rows` bindings.
@group(0) @binding(1) var<storage, read> src: array<f32>;
@group(0) @binding(2) var<storage, read_write> tmp_g_out: array<f32>;
@group(0) @binding(3) var<storage, read_write> tmp_d_out: array<f32>;

// `cols` bindings.
@group(0) @binding(1) var<storage, read> tmp_g_in: array<f32>;
@group(0) @binding(2) var<storage, read> tmp_d_in: array<f32>;
@group(0) @binding(3) var<storage, read_write> dst: array<f32>;

fn g(k: u32) -> f32 {
    return params.gauss[k / 4u][k % 4u];
}

fn d(k: u32) -> f32 {
    return params.second[k / 4u][k % 4u];
}

// Horizontal pass, both kernels at once on the same pair sums:
//   tmp_g(x) = g0·src(x) + Σ_k g_k·(src(x−k) + src(x+k))
//   tmp_d(x) = d0·src(x) + Σ_k d_k·(src(x−k) + src(x+k)).
@compute @workgroup_size(16, 16)
fn rows(@builtin(global_invocation_id) id: vec3<u32>) {
    let px = params.region.x + id.x;
    let py = params.region.y + id.y;
    if (px >= params.region.z || py >= params.region.w) {
        return;
    }
    let row = (id.z * params.height + py) * params.width;
    let last = i32(params.width) - 1;
    let x = i32(px);
    let centre = src[row + px];
    var sum_g = g(0u) * centre;
    var sum_d = d(0u) * centre;
    for (var k = 1u; k <= params.radius; k++) {
        let l = u32(clamp(x - i32(k), 0, last));
        let r = u32(clamp(x + i32(k), 0, last));
        let pair = src[row + l] + src[row + r];
        sum_g += g(k) * pair;
        sum_d += d(k) * pair;
    }
    tmp_g_out[row + px] = sum_g;
    tmp_d_out[row + px] = sum_d;
}

// Vertical pass: dst = cols_d(tmp_g) + cols_g(tmp_d), each column sum
// accumulated separately and added last.
@compute @workgroup_size(16, 16)
fn cols(@builtin(global_invocation_id) id: vec3<u32>) {
    let px = params.region.x + id.x;
    let py = params.region.y + id.y;
    if (px >= params.region.z || py >= params.region.w) {
        return;
    }
    let w = params.width;
    let last = i32(params.height) - 1;
    let y = i32(py);
    let base = id.z * params.height * w + px;
    let i = base + py * w;
    var sum_dg = d(0u) * tmp_g_in[i];
    var sum_gd = g(0u) * tmp_d_in[i];
    for (var k = 1u; k <= params.radius; k++) {
        let u = base + u32(clamp(y - i32(k), 0, last)) * w;
        let v = base + u32(clamp(y + i32(k), 0, last)) * w;
        sum_dg += d(k) * (tmp_g_in[u] + tmp_g_in[v]);
        sum_gd += g(k) * (tmp_d_in[u] + tmp_d_in[v]);
    }
    dst[i] = sum_dg + sum_gd;
}
