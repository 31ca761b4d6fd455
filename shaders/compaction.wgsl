// Compaction (000's ISMAP; 002's window of interest and ≤1500 subsample):
// list (x, y, θ, magnitude) of the pixels of a window whose `select` value
// exceeds a threshold, in row-major order. Order comes from a scan, not from
// atomics (atomic append order is unspecified, e.g. on lavapipe).
//
// The window's pixels are numbered i = 0..area row-major inside the window
// and cut into blocks of BLOCK consecutive numbers, one workgroup each; each
// of the workgroup's GROUP invocations takes a run of COMPACTION_RUN consecutive pixels
// of its block, so a workgroup's scan (its barriers) serves BLOCK pixels.
// Four entry points, one per pass:
//   count_blocks  how many pixels of each block are selected
//   scan_blocks   one workgroup: exclusive offsets of the blocks, and the header
//   scatter       each block rescans its flags, writes its features at offset + rank
//   gather        only with a cap: the stratified random subsample
//
// The entry points bind different buffers: each declares its own below, at
// bindings 1, 2, … in the order src/early/compaction.rs passes them (count_blocks
// and scatter share binding 2, the image that selects the pixels).
//
// Layers: one dispatch compacts a window of each layer of stacked images
// (workgroup_id.z is the layer), each into its own part of every buffer:
// its image from element layer · width · height, its block counts and
// offsets from layer · max_blocks, its full list from layer · list_stride,
// its capped list from layer · capped_stride, its header at [layer]. Each
// layer has its own window, threshold, cap and seed (`LayerWindow`).
// Kept in sync with `CompactionUniform`, `LayerWindow` and `Header` in
// src/early/compaction.rs and `Feature` in src/early/mod.rs.

const GROUP: u32 = 256u;
// Pixels per invocation (1 to 32), set by the host for its device: long runs
// suit a CPU adapter, short ones a GPU (coalesced reads, more workgroups).
override COMPACTION_RUN: u32 = 32u;
override BLOCK: u32 = GROUP * COMPACTION_RUN;

struct Params {
    image_width: u32,
    image_height: u32,
    // Workgroups per row of the (2-D) block grid: block = wg.y · grid_x + wg.x.
    grid_x: u32,
    max_blocks: u32,
    list_stride: u32,
    capped_stride: u32,
    _pad0: u32,
    _pad1: u32,
}

struct LayerWindow {
    x0: u32,
    y0: u32,
    win_width: u32,
    area: u32,
    num_blocks: u32,
    // 0xffffffff when there is no cap.
    cap: u32,
    seed: u32,
    threshold: f32,
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

// count_blocks and scatter: the image whose values select the pixels.
@group(0) @binding(2) var<storage, read> select_values: array<f32>;

// count_blocks
@group(0) @binding(1) var<storage, read> count_windows: array<LayerWindow>;
@group(0) @binding(3) var<storage, read_write> count_out: array<u32>;

// scan_blocks
@group(0) @binding(1) var<storage, read> scan_windows: array<LayerWindow>;
@group(0) @binding(2) var<storage, read> scan_counts: array<u32>;
@group(0) @binding(3) var<storage, read_write> scan_offsets: array<u32>;
@group(0) @binding(4) var<storage, read_write> scan_header: array<Header>;

// scatter
@group(0) @binding(1) var<storage, read> scatter_windows: array<LayerWindow>;
@group(0) @binding(3) var<storage, read> scatter_theta: array<f32>;
@group(0) @binding(4) var<storage, read> scatter_magnitude: array<f32>;
@group(0) @binding(5) var<storage, read> scatter_offsets: array<u32>;
@group(0) @binding(6) var<storage, read_write> scatter_list: array<Feature>;

// gather
@group(0) @binding(1) var<storage, read> gather_windows: array<LayerWindow>;
@group(0) @binding(2) var<storage, read> gather_header: array<Header>;
@group(0) @binding(3) var<storage, read> gather_list: array<Feature>;
@group(0) @binding(4) var<storage, read_write> gather_out: array<Feature>;

var<workgroup> partial: array<u32, GROUP>;

// Inclusive prefix sum of `value` over the workgroup (Hillis–Steele, log2 GROUP
// steps). Every invocation of the workgroup must call it.
fn inclusive_scan(lid: u32, value: u32) -> u32 {
    partial[lid] = value;
    workgroupBarrier();
    for (var d = 1u; d < GROUP; d = d << 1u) {
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

// Image coordinates of pixel number i of window `win`.
fn window_xy(win: LayerWindow, i: u32) -> vec2<u32> {
    let wy = i / win.win_width;
    let wx = i - wy * win.win_width;
    return vec2<u32>(win.x0 + wx, win.y0 + wy);
}

// Index in a stacked image of pixel `xy` of `layer`.
fn pixel_index(layer: u32, xy: vec2<u32>) -> u32 {
    return (layer * params.image_height + xy.y) * params.image_width + xy.x;
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

// Bit r of the result: whether pixel (run start) + r of window `win` of
// `layer` is selected (pixels past the window's area are not).
fn run_flags(win: LayerWindow, layer: u32, start: u32) -> u32 {
    var flags = 0u;
    let end = min(start + COMPACTION_RUN, win.area);
    if (start >= end) {
        return 0u;
    }
    // Walk the run along the window's rows: one division for its first pixel.
    let first = window_xy(win, start);
    let row_end = win.x0 + win.win_width;
    var x = first.x;
    var p = pixel_index(layer, first);
    for (var i = start; i < end; i++) {
        if (select_values[p] > win.threshold) {
            flags |= 1u << (i - start);
        }
        x += 1u;
        p += 1u;
        if (x == row_end) {
            x = win.x0;
            p += params.image_width - win.win_width;
        }
    }
    return flags;
}

// Pass 1: count_out[block] = number of selected pixels in the block.
@compute @workgroup_size(256)
fn count_blocks(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let win = count_windows[wg.z];
    let block = wg.y * params.grid_x + wg.x;
    var count = 0u;
    if (block < win.num_blocks) {
        count = countOneBits(run_flags(win, wg.z, block * BLOCK + lid * COMPACTION_RUN));
    }
    let sum = inclusive_scan(lid, count);
    if (lid == GROUP - 1u && block < win.num_blocks) {
        count_out[wg.z * params.max_blocks + block] = sum;
    }
}

// Pass 2, one workgroup: each invocation sums a contiguous chunk of blocks,
// the workgroup scans the chunk sums, and each invocation writes its chunk's
// exclusive offsets. The last invocation writes the header.
@compute @workgroup_size(256)
fn scan_blocks(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let win = scan_windows[wg.z];
    let base = wg.z * params.max_blocks;
    let chunk = (win.num_blocks + GROUP - 1u) / GROUP;
    let begin = min(lid * chunk, win.num_blocks);
    let end = min(begin + chunk, win.num_blocks);
    var sum = 0u;
    for (var b = begin; b < end; b++) {
        sum += scan_counts[base + b];
    }
    let inclusive = inclusive_scan(lid, sum);
    var offset = inclusive - sum;
    for (var b = begin; b < end; b++) {
        let c = scan_counts[base + b];
        scan_offsets[base + b] = offset;
        offset += c;
    }
    if (lid == GROUP - 1u) {
        scan_header[wg.z] = Header(inclusive, min(inclusive, win.cap), 0u, 0u);
    }
}

// Pass 3: rescan the block's runs and write each selected pixel at
// offset(block) + (the selected pixels of the block's earlier runs) + (its
// rank in its run).
@compute @workgroup_size(256)
fn scatter(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let win = scatter_windows[wg.z];
    let block = wg.y * params.grid_x + wg.x;
    let start = block * BLOCK + lid * COMPACTION_RUN;
    var flags = 0u;
    if (block < win.num_blocks) {
        flags = run_flags(win, wg.z, start);
    }
    let count = countOneBits(flags);
    let inclusive = inclusive_scan(lid, count);
    if (count == 0u) {
        return;
    }
    var slot = wg.z * params.list_stride + scatter_offsets[wg.z * params.max_blocks + block] + inclusive - count;
    var left = flags;
    while (left != 0u) {
        let r = firstTrailingBit(left);
        left &= left - 1u;
        let xy = window_xy(win, start + r);
        let p = pixel_index(wg.z, xy);
        scatter_list[slot] = Feature(xy.x, xy.y, scatter_theta[p], scatter_magnitude[p]);
        slot++;
    }
}

// Pass 4 (only with a cap): feature j of the final list, j < min(n, cap).
// When n ≤ cap it copies through; otherwise it takes one rank per stratum.
@compute @workgroup_size(256)
fn gather(@builtin(global_invocation_id) id: vec3<u32>) {
    let win = gather_windows[id.z];
    let j = id.x;
    let n = gather_header[id.z].total;
    if (j >= min(n, win.cap)) {
        return;
    }
    var rank = j;
    if (n > win.cap) {
        rank = subsample_rank(j, n, win.cap, win.seed);
    }
    gather_out[id.z * params.capped_stride + j] = gather_list[id.z * params.list_stride + rank];
}
