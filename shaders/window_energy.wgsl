// Window energy (004 §III-B.2, eq. 20–28): warp N quadrilaterals of a colour
// frame to 2^L × 2^L windows by bilinear interpolation, apply the four
// critical-point filters (eq. 1–4) down to 2^k × 2^k, and score each window
// against a template window at the same level: the intensity term (eq. 23)
// and the hue/saturation term (eq. 24, hue and saturation of eq. 7–8),
// summed over the four hierarchies; `normalise` then divides each term by
// its sum over the windows (eq. 25–26) and adds them (eq. 22).
// Kept in sync with `WindowEnergyUniform` and the CPU twin in
// src/early/window_energy.rs (same loops, same order of arithmetic).

struct Params {
    width: u32,
    height: u32,
    // L: the warped window is 2^L × 2^L.
    side_log2: u32,
    // k: the CPF level compared, 2^k × 2^k.
    cpf_log2: u32,
    // Number of windows.
    count: u32,
    // 0: write (intensity, colour) terms per window; 1: write the filtered window.
    mode: u32,
    _pad0: u32,
    _pad1: u32,
}

const GROUP: u32 = 64u;
const NORMALISE_GROUP: u32 = 256u;
// Floats per window in `maps`: a, b, c, d, e, f, g, h, kind, 3 unused.
const MAP_STRIDE: u32 = 12u;
const MAP_BILINEAR: f32 = 1.0;
const MODE_FEATURES: u32 = 1u;
const HIERARCHIES: u32 = 4u;
// Deepest reduction L − k (L ≤ 7).
const MAX_DEPTH: u32 = 7u;
const HALF_SQRT3: f32 = 0.8660254037844386;

@group(0) @binding(0) var<uniform> params: Params;

// window_terms
@group(0) @binding(1) var<storage, read> frame: array<u32>;
@group(0) @binding(2) var<storage, read> maps: array<f32>;
@group(0) @binding(3) var<storage, read> template_values: array<f32>;
@group(0) @binding(4) var<storage, read_write> window_out: array<f32>;

// normalise
@group(0) @binding(1) var<storage, read> norm_terms: array<f32>;
@group(0) @binding(2) var<storage, read_write> norm_energies: array<f32>;

var<workgroup> partial_i: array<f32, 256>;
var<workgroup> partial_hs: array<f32, 256>;

// Pixel (x, y) as (R, G, B), 0..255; the frame holds r | g << 8 | b << 16.
fn texel(x: u32, y: u32) -> vec3<f32> {
    let p = frame[y * params.width + x];
    return vec3<f32>(f32(p & 0xffu), f32((p >> 8u) & 0xffu), f32((p >> 16u) & 0xffu));
}

// Bilinear interpolation at (x, y), clamped to the frame (clamp to edge).
fn sample_rgb(x_in: f32, y_in: f32) -> vec3<f32> {
    let x = clamp(x_in, 0.0, f32(params.width - 1u));
    let y = clamp(y_in, 0.0, f32(params.height - 1u));
    let fx0 = floor(x);
    let fy0 = floor(y);
    let fx = x - fx0;
    let fy = y - fy0;
    let x0 = u32(fx0);
    let y0 = u32(fy0);
    let x1 = min(x0 + 1u, params.width - 1u);
    let y1 = min(y0 + 1u, params.height - 1u);
    let top = (1.0 - fx) * texel(x0, y0) + fx * texel(x1, y0);
    let bottom = (1.0 - fx) * texel(x0, y1) + fx * texel(x1, y1);
    return (1.0 - fy) * top + fy * bottom;
}

// Frame position of window point (s, t) in the unit square: the projective
// map of the square onto the quadrilateral, or its bilinear map when the
// quadrilateral has no projective map (see `WindowMap` on the host).
fn frame_position(base: u32, s: f32, t: f32) -> vec2<f32> {
    let a = maps[base];
    let b = maps[base + 1u];
    let c = maps[base + 2u];
    let d = maps[base + 3u];
    let e = maps[base + 4u];
    let f = maps[base + 5u];
    let g = maps[base + 6u];
    let h = maps[base + 7u];
    if (maps[base + 8u] == MAP_BILINEAR) {
        // a..h are the corners x0, y0, x1, y1, x2, y2, x3, y3.
        let w0 = (1.0 - s) * (1.0 - t);
        let w1 = s * (1.0 - t);
        let w2 = s * t;
        let w3 = (1.0 - s) * t;
        return vec2<f32>(w0 * a + w1 * c + w2 * e + w3 * g, w0 * b + w1 * d + w2 * f + w3 * h);
    }
    let w = g * s + h * t + 1.0;
    return vec2<f32>((a * s + b * t + c) / w, (d * s + e * t + f) / w);
}

// The window pixel (px, py) of a 2^L window as (I, R, G, B): the bilinear
// sample of the frame, with intensity I = (R + G + B) / 3 (HSI).
fn window_pixel(base: u32, px: u32, py: u32) -> vec4<f32> {
    let side = f32(1u << params.side_log2);
    let s = (f32(px) + 0.5) / side;
    let t = (f32(py) + 0.5) / side;
    let pos = frame_position(base, s, t);
    let rgb = sample_rgb(pos.x, pos.y);
    return vec4<f32>((rgb.x + rgb.y + rgb.z) / 3.0, rgb.x, rgb.y, rgb.z);
}

// Chroma (S cos 2πH, S sin 2πH) of eq. 24 with H of eq. 7 (in turns) and S
// of eq. 8, without trigonometry: cos 2πH = num / den and
// sin 2πH = (√3/2)(G − B) / den, den² = (R−G)² + (R−B)(G−B). Grey and
// black have no hue: (0, 0).
fn chroma(c: vec3<f32>) -> vec2<f32> {
    let sum = c.x + c.y + c.z;
    let lo = min(c.x, min(c.y, c.z));
    let rg = c.x - c.y;
    let rb = c.x - c.z;
    let gb = c.y - c.z;
    let den2 = rg * rg + rb * gb;
    if (sum <= 0.0 || den2 <= 0.0) {
        return vec2<f32>(0.0, 0.0);
    }
    let saturation = 1.0 - 3.0 * lo / sum;
    let den = sqrt(den2);
    let num = 0.5 * (rg + rb);
    return vec2<f32>(saturation * num / den, saturation * HALF_SQRT3 * gb / den);
}

// One output pixel (ox, oy) of level k, for hierarchy m: (I, S cos, S sin).
// The block of 2^(L−k) × 2^(L−k) window pixels under it is reduced by
// eq. 1–4, children visited in Z order (bit pairs of n, finest first: bit 0
// the row, bit 1 the column), each level's pending children on a stack.
// Returns the four hierarchies' (I, R, G, B).
fn cpf_block(base: u32, ox: u32, oy: u32) -> array<vec4<f32>, 4> {
    let depth = params.side_log2 - params.cpf_log2;
    let block = 1u << depth;
    let leaves = block * block;
    var lo = vec4<f32>(3.4e38);
    var hi = vec4<f32>(-3.4e38);
    var a1: array<vec4<f32>, MAX_DEPTH>;
    var b1: array<vec4<f32>, MAX_DEPTH>;
    var a2: array<vec4<f32>, MAX_DEPTH>;
    var b2: array<vec4<f32>, MAX_DEPTH>;
    var s1 = vec4<f32>(0.0);
    var s2 = vec4<f32>(0.0);
    for (var n = 0u; n < leaves; n++) {
        var bx = 0u;
        var by = 0u;
        for (var b = 0u; b < depth; b++) {
            let c = (n >> (2u * b)) & 3u;
            bx |= (c >> 1u) << b;
            by |= (c & 1u) << b;
        }
        let v = window_pixel(base, ox * block + bx, oy * block + by);
        // eq. 1 and eq. 4: min and max over the block.
        lo = min(lo, v);
        hi = max(hi, v);
        // eq. 2 (m = 1): max over columns of the min of each column's pair;
        // eq. 3 (m = 2): min over columns of the max of each column's pair.
        var v1 = v;
        var v2 = v;
        var done = false;
        for (var b = 0u; b < depth; b++) {
            let c = (n >> (2u * b)) & 3u;
            if (c == 0u) {
                a1[b] = v1;
                a2[b] = v2;
                done = true;
                break;
            }
            if (c == 1u) {
                a1[b] = min(a1[b], v1);
                a2[b] = max(a2[b], v2);
                done = true;
                break;
            }
            if (c == 2u) {
                b1[b] = v1;
                b2[b] = v2;
                done = true;
                break;
            }
            v1 = max(a1[b], min(b1[b], v1));
            v2 = min(a2[b], max(b2[b], v2));
        }
        if (!done) {
            s1 = v1;
            s2 = v2;
        }
    }
    return array<vec4<f32>, 4>(lo, s1, s2, hi);
}

@compute @workgroup_size(64)
fn window_terms(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let window = wg.x;
    if (window >= params.count) {
        return;
    }
    let base = window * MAP_STRIDE;
    let out_side = 1u << params.cpf_log2;
    let pixels = out_side * out_side;
    var sum_i = 0.0;
    var sum_hs = 0.0;
    for (var p = lid; p < pixels; p += GROUP) {
        let levels = cpf_block(base, p % out_side, p / out_side);
        for (var m = 0u; m < HIERARCHIES; m++) {
            let v = levels[m];
            let cd = chroma(v.yzw);
            if (params.mode == MODE_FEATURES) {
                let o = ((window * HIERARCHIES + m) * pixels + p) * 3u;
                window_out[o] = v.x;
                window_out[o + 1u] = cd.x;
                window_out[o + 2u] = cd.y;
            } else {
                let o = (m * pixels + p) * 3u;
                // eq. 23: squared intensity difference.
                let di = template_values[o] - v.x;
                sum_i += di * di;
                // eq. 24: squared distance of the chroma vectors.
                let dx = template_values[o + 1u] - cd.x;
                let dy = template_values[o + 2u] - cd.y;
                sum_hs += dx * dx + dy * dy;
            }
        }
    }
    if (params.mode == MODE_FEATURES) {
        return;
    }
    partial_i[lid] = sum_i;
    partial_hs[lid] = sum_hs;
    workgroupBarrier();
    for (var stride = GROUP / 2u; stride > 0u; stride /= 2u) {
        if (lid < stride) {
            partial_i[lid] += partial_i[lid + stride];
            partial_hs[lid] += partial_hs[lid + stride];
        }
        workgroupBarrier();
    }
    if (lid == 0u) {
        window_out[2u * window] = partial_i[0];
        window_out[2u * window + 1u] = partial_hs[0];
    }
}

// eq. 25–26 and 22: U_n = C_I,n / Σ C_I + C_HS,n / Σ C_HS (a term whose sum
// is 0 adds 0); the two sums follow the N energies.
@compute @workgroup_size(256)
fn normalise(@builtin(local_invocation_index) lid: u32) {
    let n = params.count;
    var sum_i = 0.0;
    var sum_hs = 0.0;
    for (var w = lid; w < n; w += NORMALISE_GROUP) {
        sum_i += norm_terms[2u * w];
        sum_hs += norm_terms[2u * w + 1u];
    }
    partial_i[lid] = sum_i;
    partial_hs[lid] = sum_hs;
    workgroupBarrier();
    for (var stride = NORMALISE_GROUP / 2u; stride > 0u; stride /= 2u) {
        if (lid < stride) {
            partial_i[lid] += partial_i[lid + stride];
            partial_hs[lid] += partial_hs[lid + stride];
        }
        workgroupBarrier();
    }
    let total_i = partial_i[0];
    let total_hs = partial_hs[0];
    for (var w = lid; w < n; w += NORMALISE_GROUP) {
        var u = 0.0;
        if (total_i > 0.0) {
            u += norm_terms[2u * w] / total_i;
        }
        if (total_hs > 0.0) {
            u += norm_terms[2u * w + 1u] / total_hs;
        }
        norm_energies[w] = u;
    }
    if (lid == 0u) {
        norm_energies[n] = total_i;
        norm_energies[n + 1u] = total_hs;
    }
}
