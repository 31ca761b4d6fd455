// Levels of a pyramid several to a dispatch, shared by the shaders that
// include it (cpf, edge_pyramid: see `includes` in their ShaderDef). Each
// workgroup owns a TILE×TILE tile of the first level it builds: each of its
// (TILE/2)×(TILE/2) invocations builds a 2×2 block of it from the level read
// in the buffers, then the workgroup halves the tile in workgroup memory
// (8×8, 4×4, 2×2, 1×1), writing every level. The children of a tile's
// pixels lie in the tile of the level before (a clamped child of an odd edge
// is the pixel's own edge child), so no workgroup needs another's values.
// Level k of the dispatch lives in half k % 2 of the workgroup's tile
// arrays (a level is read from one half while the next is written into the
// other), pixel (x, y) at y · TILE + x of its half.
// Layers (workgroup_id.z) stack level by level: a level's offset is where
// the level of layer 0 starts, and layer l's follows l whole levels later.
// Kept in sync with `LevelsUniform` and `LEVELS_PER_DISPATCH` in
// src/early/cpf.rs.

const TILE: u32 = 16u;
const LEVELS: u32 = 5u;

struct Params {
    // The level read: width, height, offset of its first value (layer 0).
    src_width: u32,
    src_height: u32,
    src_offset: u32,
    // Levels built by this dispatch (1 ..= LEVELS).
    levels: u32,
    // Each level built: (width, height, offset of layer 0, unused).
    dst: array<vec4<u32>, LEVELS>,
}

// Buffer index of pixel `p` of `layer` in `level` (width, height, offset).
fn level_index(level: vec4<u32>, layer: u32, p: vec2<u32>) -> u32 {
    return level.z + (layer * level.y + p.y) * level.x + p.x;
}

// Pixel `b` (0..4) of invocation `lid`'s 2×2 block of the first level:
// (x, y) in the tile.
fn block_pixel(lid: vec2<u32>, b: u32) -> vec2<u32> {
    return vec2<u32>(2u * lid.x + b % 2u, 2u * lid.y + b / 2u);
}

// Buffer indices of the children p00 = (2i, 2j), p01 = (2i, 2j+1),
// p10 = (2i+1, 2j), p11 = (2i+1, 2j+1) of pixel (i, j) = `p` of the first
// level built, in the level read (`width`×`height` from `offset`), clamped
// to its edge.
fn level_children(p: vec2<u32>, width: u32, height: u32, offset: u32) -> vec4<u32> {
    let x0 = 2u * p.x;
    let x1 = min(x0 + 1u, width - 1u);
    let y0 = 2u * p.y;
    let y1 = min(y0 + 1u, height - 1u);
    let r0 = offset + y0 * width;
    let r1 = offset + y1 * width;
    return vec4<u32>(r0 + x0, r1 + x0, r0 + x1, r1 + x1);
}

// Tile indices of the children (p00, p01, p10, p11) of the level-k pixel of
// invocation `lid` in workgroup `wg` (its tile is TILE >> k wide), in the
// half of the level before, whose size is `prev` (width, height, …).
fn tile_children(lid: vec2<u32>, wg: vec2<u32>, k: u32, prev: vec4<u32>) -> vec4<u32> {
    let n = TILE >> k;
    let read = ((k - 1u) % 2u) * TILE * TILE;
    // The level before's tile starts at wg · 2n.
    let x0 = 2u * lid.x;
    let x1 = min(2u * (wg.x * n + lid.x) + 1u, prev.x - 1u) - wg.x * 2u * n;
    let y0 = 2u * lid.y;
    let y1 = min(2u * (wg.y * n + lid.y) + 1u, prev.y - 1u) - wg.y * 2u * n;
    return read + vec4<u32>(y0 * TILE + x0, y1 * TILE + x0, y0 * TILE + x1, y1 * TILE + x1);
}

// Whether invocation `lid` of workgroup `wg` builds a pixel of level k of
// the dispatch (`levels` built in all, level k of size `cur`), and which:
// (inside, x, y).
fn tile_pixel(lid: vec2<u32>, wg: vec2<u32>, k: u32, levels: u32, cur: vec4<u32>) -> vec3<u32> {
    let n = TILE >> k;
    let p = wg * n + lid;
    let inside = k < levels && lid.x < n && lid.y < n && p.x < cur.x && p.y < cur.y;
    return vec3<u32>(select(0u, 1u, inside), p);
}

// Tile position of pixel `lid` of level k (in half k % 2).
fn tile_slot(lid: vec2<u32>, k: u32) -> u32 {
    return (k % 2u) * TILE * TILE + lid.y * TILE + lid.x;
}
