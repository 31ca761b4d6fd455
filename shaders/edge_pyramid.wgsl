// Averaged edge hierarchies (004 eq. 10–11): each level is the mean of the
// 2×2 children of the previous one, for the horizontal and the vertical
// Sobel edge images at once. Both buffers hold all levels concatenated
// (level 0, the finest, first). Odd sizes clamp the missing child to the
// edge child, which equals the mean of the children that exist.
//
// One dispatch builds up to LEVELS consecutive levels, as `cpf.wgsl` does:
// each workgroup owns a 16×16 tile of the first level, each of its 8×8
// invocations builds a 2×2 block of it from the buffers, then the workgroup
// halves the tile in workgroup memory, writing every level it builds.
// Kept in sync with `LevelsUniform` in src/early/cpf.rs; the CPU twin is
// src/early/edge_pyramid.rs.

const TILE: u32 = 16u;
const LEVELS: u32 = 5u;

struct Params {
    // The level read: width, height, offset of its first value.
    src_width: u32,
    src_height: u32,
    src_offset: u32,
    // Levels built by this dispatch (1 ..= LEVELS).
    levels: u32,
    // Each level built: (width, height, offset, unused).
    dst: array<vec4<u32>, LEVELS>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> edge_h: array<f32>;
@group(0) @binding(2) var<storage, read_write> edge_v: array<f32>;

// The workgroup's tiles: level k of the dispatch in half k % 2 (read from
// one half while the next level is written into the other), pixel (x, y)
// at y · TILE + x of its half.
var<workgroup> th: array<f32, 512>;
var<workgroup> tv: array<f32, 512>;

// eq. 10 and 11 of children (p00, p01, p10, p11): ((p00 + p01) + (p10 + p11)) / 4.
fn mean(c: vec4<f32>) -> f32 {
    return ((c.x + c.y) + (c.z + c.w)) * 0.25;
}

// Store pixel (x, y) of level `level` (its tile-local position `l`).
fn store(level: vec4<u32>, x: u32, y: u32, l: u32, h: f32, v: f32) {
    let o = level.z + y * level.x + x;
    edge_h[o] = h;
    edge_v[o] = v;
    th[l] = h;
    tv[l] = v;
}

@compute @workgroup_size(8, 8)
fn edge_levels(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wg: vec3<u32>) {
    // First level: children read from the buffers, clamp-to-edge.
    let first = params.dst[0];
    for (var b = 0u; b < 4u; b++) {
        let tx = 2u * lid.x + b % 2u;
        let ty = 2u * lid.y + b / 2u;
        let x = wg.x * TILE + tx;
        let y = wg.y * TILE + ty;
        if (x < first.x && y < first.y) {
            let x0 = 2u * x;
            let x1 = min(x0 + 1u, params.src_width - 1u);
            let y0 = 2u * y;
            let y1 = min(y0 + 1u, params.src_height - 1u);
            let r0 = params.src_offset + y0 * params.src_width;
            let r1 = params.src_offset + y1 * params.src_width;
            let i00 = r0 + x0; // (2i,   2j)
            let i01 = r1 + x0; // (2i,   2j+1)
            let i10 = r0 + x1; // (2i+1, 2j)
            let i11 = r1 + x1; // (2i+1, 2j+1)
            let h = mean(vec4<f32>(edge_h[i00], edge_h[i01], edge_h[i10], edge_h[i11]));
            let v = mean(vec4<f32>(edge_v[i00], edge_v[i01], edge_v[i10], edge_v[i11]));
            store(first, x, y, ty * TILE + tx, h, v);
        }
    }
    // Deeper levels from the tile: level k's tile is TILE >> k wide.
    for (var k = 1u; k < LEVELS; k++) {
        // Level k − 1 is complete in its half of the tiles.
        workgroupBarrier();
        let read = ((k - 1u) % 2u) * TILE * TILE;
        let write = (k % 2u) * TILE * TILE;
        let n = TILE >> k;
        let prev = params.dst[k - 1u];
        let cur = params.dst[k];
        let px = wg.x * n + lid.x;
        let py = wg.y * n + lid.y;
        if (k < params.levels && lid.x < n && lid.y < n && px < cur.x && py < cur.y) {
            // Children in the previous level's tile, which starts at
            // (wg · 2n); the clamped child of an odd edge is the pixel's own.
            let x0 = 2u * lid.x;
            let x1 = min(2u * px + 1u, prev.x - 1u) - wg.x * 2u * n;
            let y0 = 2u * lid.y;
            let y1 = min(2u * py + 1u, prev.y - 1u) - wg.y * 2u * n;
            let i00 = read + y0 * TILE + x0;
            let i01 = read + y1 * TILE + x0;
            let i10 = read + y0 * TILE + x1;
            let i11 = read + y1 * TILE + x1;
            let h = mean(vec4<f32>(th[i00], th[i01], th[i10], th[i11]));
            let v = mean(vec4<f32>(tv[i00], tv[i01], tv[i10], tv[i11]));
            store(cur, px, py, write + lid.y * TILE + lid.x, h, v);
        }
    }
}
