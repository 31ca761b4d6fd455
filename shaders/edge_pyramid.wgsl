// Averaged edge hierarchies (004 eq. 10–11): each level is the mean of the
// 2×2 children of the previous one, for the horizontal and the vertical
// Sobel edge images at once. Both buffers hold all levels concatenated
// (level 0, the finest, first); `src_offset` / `dst_offset` say where the
// previous and the current level start. Odd sizes clamp the missing child to
// the edge child, which equals the mean of the children that exist.
// Kept in sync with `LevelUniform` in src/early/cpf.rs; the CPU twin is
// src/early/edge_pyramid.rs.

struct Params {
    src_width: u32,
    src_height: u32,
    dst_width: u32,
    dst_height: u32,
    src_offset: u32,
    dst_offset: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> edge_h: array<f32>;
@group(0) @binding(2) var<storage, read_write> edge_v: array<f32>;

@compute @workgroup_size(16, 16)
fn edge_level(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.dst_width || id.y >= params.dst_height) {
        return;
    }
    let x0 = 2u * id.x;
    let x1 = min(x0 + 1u, params.src_width - 1u);
    let y0 = 2u * id.y;
    let y1 = min(y0 + 1u, params.src_height - 1u);
    let r0 = params.src_offset + y0 * params.src_width;
    let r1 = params.src_offset + y1 * params.src_width;
    let i00 = r0 + x0; // (2i,   2j)
    let i01 = r1 + x0; // (2i,   2j+1)
    let i10 = r0 + x1; // (2i+1, 2j)
    let i11 = r1 + x1; // (2i+1, 2j+1)
    let o = params.dst_offset + id.y * params.dst_width + id.x;
    // eq. 10 and 11: ((p00 + p01) + (p10 + p11)) / 4.
    edge_h[o] = ((edge_h[i00] + edge_h[i01]) + (edge_h[i10] + edge_h[i11])) * 0.25;
    edge_v[o] = ((edge_v[i00] + edge_v[i01]) + (edge_v[i10] + edge_v[i11])) * 0.25;
}
