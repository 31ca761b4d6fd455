// Critical-point filter hierarchies (004 eq. 1–4; Shinagawa & Kunii).
// Each level is built from the previous level of its own hierarchy:
// m = 0 min of mins, m = 1 max of mins, m = 2 min of maxes, m = 3 max of
// maxes over the 2×2 children.
// Each hierarchy is one storage buffer with its levels concatenated (level 0,
// the input, first). Index convention: p_(i,j) has i = column (x), j = row
// (y), so the inner min/max pairs (2i,2j),(2i,2j+1) are the two children of
// one column and the outer op combines the two columns.
// A missing last column/row (odd size) is clamped to the edge child.
// One dispatch builds up to LEVELS consecutive levels, a tile per workgroup
// (`pyramid_tile.wgsl`, included).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> h0: array<f32>;
@group(0) @binding(2) var<storage, read_write> h1: array<f32>;
@group(0) @binding(3) var<storage, read_write> h2: array<f32>;
@group(0) @binding(4) var<storage, read_write> h3: array<f32>;

// The workgroup's tiles, one array per hierarchy (`pyramid_tile.wgsl`).
var<workgroup> t0: array<f32, 512>;
var<workgroup> t1: array<f32, 512>;
var<workgroup> t2: array<f32, 512>;
var<workgroup> t3: array<f32, 512>;

// eq. 1–4 of four hierarchies' children p00 = (2i, 2j), p01 = (2i, 2j+1),
// p10 = (2i+1, 2j), p11 = (2i+1, 2j+1), each given as (p00, p01, p10, p11).
fn reduce(c0: vec4<f32>, c1: vec4<f32>, c2: vec4<f32>, c3: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(
        // eq. 1: minimum.
        min(min(c0.x, c0.y), min(c0.z, c0.w)),
        // eq. 2: saddle, max of column mins.
        max(min(c1.x, c1.y), min(c1.z, c1.w)),
        // eq. 3: saddle, min of column maxes.
        min(max(c2.x, c2.y), max(c2.z, c2.w)),
        // eq. 4: maximum.
        max(max(c3.x, c3.y), max(c3.z, c3.w)),
    );
}

// Store pixel `p` of level `level` in the buffers and at `slot` of the tiles.
fn store(level: vec4<u32>, layer: u32, p: vec2<u32>, slot: u32, v: vec4<f32>) {
    let o = level_index(level, layer, p);
    h0[o] = v.x;
    h1[o] = v.y;
    h2[o] = v.z;
    h3[o] = v.w;
    t0[slot] = v.x;
    t1[slot] = v.y;
    t2[slot] = v.z;
    t3[slot] = v.w;
}

@compute @workgroup_size(8, 8)
fn cpf_levels(@builtin(local_invocation_id) lid3: vec3<u32>, @builtin(workgroup_id) wg3: vec3<u32>) {
    let lid = lid3.xy;
    let wg = wg3.xy;
    let layer = wg3.z;
    // First level: children read from the buffers.
    let first = params.dst[0];
    for (var b = 0u; b < 4u; b++) {
        let t = block_pixel(lid, b);
        let p = wg * TILE + t;
        if (p.x < first.x && p.y < first.y) {
            let src_offset = params.src_offset + layer * params.src_width * params.src_height;
            let i = level_children(p, params.src_width, params.src_height, src_offset);
            let v = reduce(
                vec4<f32>(h0[i.x], h0[i.y], h0[i.z], h0[i.w]),
                vec4<f32>(h1[i.x], h1[i.y], h1[i.z], h1[i.w]),
                vec4<f32>(h2[i.x], h2[i.y], h2[i.z], h2[i.w]),
                vec4<f32>(h3[i.x], h3[i.y], h3[i.z], h3[i.w]),
            );
            store(first, layer, p, t.y * TILE + t.x, v);
        }
    }
    // Deeper levels from the tile.
    for (var k = 1u; k < LEVELS; k++) {
        // Level k − 1 is complete in its half of the tiles.
        workgroupBarrier();
        let cur = params.dst[k];
        let at = tile_pixel(lid, wg, k, params.levels, cur);
        if (at.x == 1u) {
            let i = tile_children(lid, wg, k, params.dst[k - 1u]);
            let v = reduce(
                vec4<f32>(t0[i.x], t0[i.y], t0[i.z], t0[i.w]),
                vec4<f32>(t1[i.x], t1[i.y], t1[i.z], t1[i.w]),
                vec4<f32>(t2[i.x], t2[i.y], t2[i.z], t2[i.w]),
                vec4<f32>(t3[i.x], t3[i.y], t3[i.z], t3[i.w]),
            );
            store(cur, layer, at.yz, tile_slot(lid, k), v);
        }
    }
}
