// Compaction (000's ISMAP; 002's window of interest and ≤1500 subsample):
// list (x, y, θ, magnitude) of the pixels of a window whose `select` value
// exceeds a threshold, in row-major order. Order comes from a scan, not from
// atomics (atomic append order is unspecified, e.g. on lavapipe).
//
// The window's pixels are numbered i = 0..area row-major inside the window
// and cut into blocks of BLOCK consecutive numbers, one workgroup each.
// Four entry points, one per pass:
//   count_blocks  how many pixels of each block are selected
//   scan_blocks   one workgroup: exclusive offsets of the blocks, and the header
//   scatter       each block rescans its flags, writes its features at offset + rank
//   gather        only with a cap: the stratified random subsample
//
// The entry points bind different buffers: each declares its own below, at
// bindings 1, 2, … in the order src/early/compaction.rs passes them.
// Kept in sync with `CompactionUniform` and `Header` in
// src/early/compaction.rs and `Feature` in src/early/mod.rs.

const BLOCK: u32 = 256u;

struct Params {
    image_width: u32,
    x0: u32,
    y0: u32,
    win_width: u32,
    area: u32,
    num_blocks: u32,
    // Workgroups per row of the (2-D) block grid: block = wg.y · grid_x + wg.x.
    grid_x: u32,
    // 0xffffffff when there is no cap.
    cap: u32,
    seed: u32,
    threshold: f32,
    _pad0: u32,
    _pad1: u32,
}

struct Feature {
    x: u32,
    y: u32,
    theta: f32,
    magnitude: f32,
}

struct Header {
    // Selected pixels in the window (n).
    total: u32,
    // Features in the final list: min(n, cap).
    listed: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;

// count_blocks
@group(0) @binding(1) var<storage, read> count_select: array<f32>;
@group(0) @binding(2) var<storage, read_write> count_out: array<u32>;

// scan_blocks
@group(0) @binding(1) var<storage, read> scan_counts: array<u32>;
@group(0) @binding(2) var<storage, read_write> scan_offsets: array<u32>;
@group(0) @binding(3) var<storage, read_write> scan_header: Header;

// scatter
@group(0) @binding(1) var<storage, read> scatter_select: array<f32>;
@group(0) @binding(2) var<storage, read> scatter_theta: array<f32>;
@group(0) @binding(3) var<storage, read> scatter_magnitude: array<f32>;
@group(0) @binding(4) var<storage, read> scatter_offsets: array<u32>;
@group(0) @binding(5) var<storage, read_write> scatter_list: array<Feature>;

// gather
@group(0) @binding(1) var<storage, read> gather_header: Header;
@group(0) @binding(2) var<storage, read> gather_list: array<Feature>;
@group(0) @binding(3) var<storage, read_write> gather_out: array<Feature>;

var<workgroup> partial: array<u32, BLOCK>;

// Inclusive prefix sum of `value` over the workgroup (Hillis–Steele, log2 BLOCK
// steps). Every invocation of the workgroup must call it.
fn inclusive_scan(lid: u32, value: u32) -> u32 {
    partial[lid] = value;
    workgroupBarrier();
    for (var d = 1u; d < BLOCK; d = d << 1u) {
        var left = 0u;
        if (lid >= d) {
            left = partial[lid - d];
        }
        workgroupBarrier();
        partial[lid] += left;
        workgroupBarrier();
    }
    return partial[lid];
}

// Image coordinates of window pixel number i.
fn window_xy(i: u32) -> vec2<u32> {
    let wy = i / params.win_width;
    let wx = i - wy * params.win_width;
    return vec2<u32>(params.x0 + wx, params.y0 + wy);
}

// lowbias32 (C. Wellons, "hash-prospector"): a 32-bit integer mix.
fn lowbias32(v: u32) -> u32 {
    var x = v;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

// lo_j = floor(j·n / cap) without overflow (j ≤ cap ≤ 65535).
fn stratum_start(j: u32, n: u32, cap: u32) -> u32 {
    let q = n / cap;
    let r = n % cap;
    return j * q + (j * r) / cap;
}

// The rank kept from stratum j when n > cap: lo_j + hash % (lo_{j+1} − lo_j).
fn subsample_rank(j: u32, n: u32, cap: u32, seed: u32) -> u32 {
    let lo = stratum_start(j, n, cap);
    let hi = stratum_start(j + 1u, n, cap);
    return lo + lowbias32(seed ^ (j * 0x9e3779b9u)) % (hi - lo);
}

// Pass 1: count_out[block] = number of selected pixels in the block.
@compute @workgroup_size(256)
fn count_blocks(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let block = wg.y * params.grid_x + wg.x;
    let i = block * BLOCK + lid;
    var flag = 0u;
    if (block < params.num_blocks && i < params.area) {
        let xy = window_xy(i);
        if (count_select[xy.y * params.image_width + xy.x] > params.threshold) {
            flag = 1u;
        }
    }
    let sum = inclusive_scan(lid, flag);
    if (lid == BLOCK - 1u && block < params.num_blocks) {
        count_out[block] = sum;
    }
}

// Pass 2, one workgroup: each invocation sums a contiguous chunk of blocks,
// the workgroup scans the chunk sums, and each invocation writes its chunk's
// exclusive offsets. The last invocation writes the header.
@compute @workgroup_size(256)
fn scan_blocks(@builtin(local_invocation_index) lid: u32) {
    let chunk = (params.num_blocks + BLOCK - 1u) / BLOCK;
    let begin = min(lid * chunk, params.num_blocks);
    let end = min(begin + chunk, params.num_blocks);
    var sum = 0u;
    for (var b = begin; b < end; b++) {
        sum += scan_counts[b];
    }
    let inclusive = inclusive_scan(lid, sum);
    var offset = inclusive - sum;
    for (var b = begin; b < end; b++) {
        let c = scan_counts[b];
        scan_offsets[b] = offset;
        offset += c;
    }
    if (lid == BLOCK - 1u) {
        scan_header.total = inclusive;
        scan_header.listed = min(inclusive, params.cap);
        scan_header._pad0 = 0u;
        scan_header._pad1 = 0u;
    }
}

// Pass 3: rescan the block's flags and write each selected pixel at
// offset(block) + (its rank in the block).
@compute @workgroup_size(256)
fn scatter(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let block = wg.y * params.grid_x + wg.x;
    let i = block * BLOCK + lid;
    var flag = 0u;
    var xy = vec2<u32>(0u, 0u);
    var p = 0u;
    if (block < params.num_blocks && i < params.area) {
        xy = window_xy(i);
        p = xy.y * params.image_width + xy.x;
        if (scatter_select[p] > params.threshold) {
            flag = 1u;
        }
    }
    let inclusive = inclusive_scan(lid, flag);
    if (flag == 1u) {
        let slot = scatter_offsets[block] + inclusive - 1u;
        scatter_list[slot] = Feature(xy.x, xy.y, scatter_theta[p], scatter_magnitude[p]);
    }
}

// Pass 4 (only with a cap): feature j of the final list, j < min(n, cap).
// When n ≤ cap it copies through; otherwise it takes one rank per stratum.
@compute @workgroup_size(256)
fn gather(@builtin(global_invocation_id) id: vec3<u32>) {
    let j = id.x;
    let n = gather_header.total;
    if (j >= min(n, params.cap)) {
        return;
    }
    var rank = j;
    if (n > params.cap) {
        rank = subsample_rank(j, n, params.cap, params.seed);
    }
    gather_out[j] = gather_list[rank];
}
