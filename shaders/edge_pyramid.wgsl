// Averaged edge hierarchies (004 eq. 10–11): each level is the mean of the
// 2×2 children of the previous one, for the horizontal and the vertical
// Sobel edge images at once. Both buffers hold all levels concatenated
// (level 0, the finest, first). Odd sizes clamp the missing child to the
// edge child, which equals the mean of the children that exist.
// One dispatch builds up to LEVELS consecutive levels, a tile per workgroup
// (`pyramid_tile.wgsl`, included). The CPU twin is
// src/early/edge_pyramid.rs.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> edge_h: array<f32>;
@group(0) @binding(2) var<storage, read_write> edge_v: array<f32>;

// The workgroup's tiles (`pyramid_tile.wgsl`).
var<workgroup> th: array<f32, 512>;
var<workgroup> tv: array<f32, 512>;

// eq. 10 and 11 of children (p00, p01, p10, p11): ((p00 + p01) + (p10 + p11)) / 4.
fn mean(c: vec4<f32>) -> f32 {
    return ((c.x + c.y) + (c.z + c.w)) * 0.25;
}

// Store pixel `p` of level `level` in the buffers and at `slot` of the tiles.
fn store(level: vec4<u32>, layer: u32, p: vec2<u32>, slot: u32, h: f32, v: f32) {
    let o = level_index(level, layer, p);
    edge_h[o] = h;
    edge_v[o] = v;
    th[slot] = h;
    tv[slot] = v;
}

@compute @workgroup_size(8, 8)
fn edge_levels(@builtin(local_invocation_id) lid3: vec3<u32>, @builtin(workgroup_id) wg3: vec3<u32>) {
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
            let h = mean(vec4<f32>(edge_h[i.x], edge_h[i.y], edge_h[i.z], edge_h[i.w]));
            let v = mean(vec4<f32>(edge_v[i.x], edge_v[i.y], edge_v[i.z], edge_v[i.w]));
            store(first, layer, p, t.y * TILE + t.x, h, v);
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
            let h = mean(vec4<f32>(th[i.x], th[i.y], th[i.z], th[i.w]));
            let v = mean(vec4<f32>(tv[i.x], tv[i.y], tv[i.z], tv[i.w]));
            store(cur, layer, at.yz, tile_slot(lid, k), h, v);
        }
    }
}
