// Critical-point filter hierarchies (004 eq. 1–4; Shinagawa & Kunii).
// Each level is built from the previous level of its own hierarchy:
// m = 0 min of mins, m = 1 max of mins, m = 2 min of maxes, m = 3 max of
// maxes over the 2×2 children.
// Each hierarchy is one storage buffer with its levels concatenated (level 0,
// the input, first). Index convention: p_(i,j) has i = column (x), j = row
// (y), so the inner min/max pairs (2i,2j),(2i,2j+1) are the two children of
// one column and the outer op combines the two columns.
// A missing last column/row (odd size) is clamped to the edge child.
//
// One dispatch builds up to LEVELS consecutive levels. Each workgroup owns a
// 16×16 tile of the first level: each of its 8×8 invocations builds a 2×2
// block of that tile from the buffers, then the workgroup halves the tile in
// workgroup memory (8×8, 4×4, 2×2, 1×1), writing every level it builds. The
// children of a tile's pixels lie in the tile of the level before (a clamped
// child is the pixel's own edge child), so no workgroup needs another's values.
// Kept in sync with `LevelsUniform` in src/early/cpf.rs.

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
@group(0) @binding(1) var<storage, read_write> h0: array<f32>;
@group(0) @binding(2) var<storage, read_write> h1: array<f32>;
@group(0) @binding(3) var<storage, read_write> h2: array<f32>;
@group(0) @binding(4) var<storage, read_write> h3: array<f32>;

// The workgroup's tiles, one array per hierarchy: level k of the dispatch in
// half k % 2 (a level is read from one half while the next is written into
// the other), pixel (x, y) of the tile at y · TILE + x of its half.
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

// Store pixel (x, y) of level `level` (its tile-local position `l`).
fn store(level: vec4<u32>, x: u32, y: u32, l: u32, v: vec4<f32>) {
    let o = level.z + y * level.x + x;
    h0[o] = v.x;
    h1[o] = v.y;
    h2[o] = v.z;
    h3[o] = v.w;
    t0[l] = v.x;
    t1[l] = v.y;
    t2[l] = v.z;
    t3[l] = v.w;
}

@compute @workgroup_size(8, 8)
fn cpf_levels(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wg: vec3<u32>) {
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
            let v = reduce(
                vec4<f32>(h0[i00], h0[i01], h0[i10], h0[i11]),
                vec4<f32>(h1[i00], h1[i01], h1[i10], h1[i11]),
                vec4<f32>(h2[i00], h2[i01], h2[i10], h2[i11]),
                vec4<f32>(h3[i00], h3[i01], h3[i10], h3[i11]),
            );
            store(first, x, y, ty * TILE + tx, v);
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
            let v = reduce(
                vec4<f32>(t0[i00], t0[i01], t0[i10], t0[i11]),
                vec4<f32>(t1[i00], t1[i01], t1[i10], t1[i11]),
                vec4<f32>(t2[i00], t2[i01], t2[i10], t2[i11]),
                vec4<f32>(t3[i00], t3[i01], t3[i10], t3[i11]),
            );
            store(cur, px, py, write + lid.y * TILE + lid.x, v);
        }
    }
}
