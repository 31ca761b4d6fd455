// Zero crossings of the LoG image (001 "Real-time line detection": a change
// of sign between adjacent pixels; the approximate gradient at the crossing is
// the difference of the neighbouring pixels across it).
// One entry point; each pixel gathers its 4 neighbours (clamp to edge, so a
// border pixel pairs with itself and finds no crossing there) and writes only
// its own outputs. Kept in sync with `ZeroCrossingUniform` in
// src/early/zero_crossing.rs, and with its CPU twin `axis` / `edgel`.
// fast_atan2 comes from shaders/angle.wgsl, appended to this file when the
// module is built.
// Stacked images (a stack of layers, each width×height after the one
// before) are one dispatch: the grid's z is the layer (`id.z`).
// The dispatch computes the pixels of `region` (x0, y0, x1, y1: columns
// x0..x1, rows y0..y1 of every layer), the grid covering the region; a
// pixel's outputs are the whole frame's (its neighbours clamp to the frame).

struct Params {
    width: u32,
    height: u32,
    // Least |b − a| across a crossing (already floored on the Rust side).
    min_slope: f32,
    _pad: u32,
    region: vec4<u32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> lap: array<f32>;
@group(0) @binding(2) var<storage, read_write> strength: array<f32>;
@group(0) @binding(3) var<storage, read_write> direction: array<f32>;
@group(0) @binding(4) var<storage, read_write> offset_x: array<f32>;
@group(0) @binding(5) var<storage, read_write> offset_y: array<f32>;

// The crossing kept by the centre pixel `c` along one axis, from the pairs
// (prev, c) and (c, next): (b − a, zero position − pixel position), or (0, 0).
// Sign: v >= 0 counts as positive. The zero of a pair (a, b) lies at
// t = a/(a − b) = |a|/(|a| + |b|); it belongs to the nearer pixel, i.e. to the
// first one when |a| <= |b| (t <= 1/2). The steeper crossing wins; on a tie
// the backward pair (prev, c).
fn axis(prev: f32, c: f32, next: f32) -> vec2<f32> {
    let back_slope = abs(c - prev);
    let back = ((prev >= 0.0) != (c >= 0.0)) && back_slope >= params.min_slope && abs(prev) > abs(c);
    let fwd_slope = abs(next - c);
    let fwd = ((c >= 0.0) != (next >= 0.0)) && fwd_slope >= params.min_slope && abs(c) <= abs(next);
    if (fwd && (!back || fwd_slope > back_slope)) {
        return vec2<f32>(next - c, abs(c) / fwd_slope);
    }
    if (back) {
        return vec2<f32>(c - prev, -(abs(c) / back_slope));
    }
    return vec2<f32>(0.0, 0.0);
}

@compute @workgroup_size(16, 16)
fn edgels(@builtin(global_invocation_id) id: vec3<u32>) {
    let x = params.region.x + id.x;
    let y = params.region.y + id.y;
    if (x >= params.region.z || y >= params.region.w) {
        return;
    }
    let w = params.width;
    let base = id.z * params.height * w;
    let i = base + y * w + x;
    let xl = max(x, 1u) - 1u;
    let xr = min(x + 1u, w - 1u);
    let yu = max(y, 1u) - 1u;
    let yd = min(y + 1u, params.height - 1u);
    let c = lap[i];
    let h = axis(lap[base + y * w + xl], c, lap[base + y * w + xr]);
    let v = axis(lap[base + yu * w + x], c, lap[base + yd * w + x]);
    let s = sqrt(h.x * h.x + v.x * v.x);
    strength[i] = s;
    // No edgel: gx = gy = 0 and fast_atan2(0, 0) = 0, as on the CPU.
    direction[i] = fast_atan2(v.x, h.x);
    offset_x[i] = h.y;
    offset_y[i] = v.y;
}
