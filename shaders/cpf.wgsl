// Critical-point filter hierarchies (004 eq. 1–4; Shinagawa & Kunii).
// One dispatch per level builds that level of all four hierarchies from the
// previous level of each: m = 0 min of mins, m = 1 max of mins,
// m = 2 min of maxes, m = 3 max of maxes over the 2×2 children.
// Each hierarchy is one storage buffer with its levels concatenated (level 0,
// the input, first); `src_offset` / `dst_offset` say where the previous and
// the current level start. Index convention: p_(i,j) has i = column (x),
// j = row (y), so the inner min/max pairs (2i,2j),(2i,2j+1) are the two
// children of one column and the outer op combines the two columns.
// A missing last column/row (odd size) is clamped to the edge child.
// Kept in sync with `LevelUniform` in src/early/cpf.rs.

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
@group(0) @binding(1) var<storage, read_write> h0: array<f32>;
@group(0) @binding(2) var<storage, read_write> h1: array<f32>;
@group(0) @binding(3) var<storage, read_write> h2: array<f32>;
@group(0) @binding(4) var<storage, read_write> h3: array<f32>;

@compute @workgroup_size(16, 16)
fn cpf_level(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.dst_width || id.y >= params.dst_height) {
        return;
    }
    // Children (2i, 2j) .. (2i+1, 2j+1) of the previous level, clamp-to-edge.
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
    // eq. 1: minimum.
    h0[o] = min(min(h0[i00], h0[i01]), min(h0[i10], h0[i11]));
    // eq. 2: saddle, max of column mins.
    h1[o] = max(min(h1[i00], h1[i01]), min(h1[i10], h1[i11]));
    // eq. 3: saddle, min of column maxes.
    h2[o] = min(max(h2[i00], h2[i01]), max(h2[i10], h2[i11]));
    // eq. 4: maximum.
    h3[o] = max(max(h3[i00], h3[i01]), max(h3[i10], h3[i11]));
}
