//! Compaction (000's ISMAP; 002's window of interest and its cap of 1500
//! points): the list of [`Feature`]s `(x, y, θ, magnitude)` of the pixels of a
//! window whose `select` value exceeds a threshold, in row-major order.
//!
//! `select` is any f32 image: a 0/1 mask (threshold 0.5) or a magnitude
//! (threshold = the smallest interesting magnitude). A pixel `p` is listed when
//! `select[p] > threshold`, with `theta[p]` and `magnitude[p]` copied bit for
//! bit from two other images of the same size. The window is clipped to the
//! image first.
//!
//! **Cap: a stratified random subsample.** When a cap is given and the number
//! `n` of selected pixels exceeds it, exactly `cap` of them are kept, one per
//! stratum: ranks `0..n` are split into `cap` strata `[lo_j, lo_{j+1})` with
//! `lo_j = floor(j·n/cap)`, and stratum `j` keeps rank
//! `lo_j + lowbias32(seed ^ j·0x9E3779B9) % (lo_{j+1} − lo_j)` (u32 wrapping
//! arithmetic; `lowbias32` is C. Wellons' 32-bit integer hash). The kept
//! points stay in row-major order and are spread uniformly over the whole
//! list, hence over the window: this serves 002's purpose of bounding the
//! work per frame while keeping points all over the object. `lo_j` is computed
//! as `j·q + (j·r)/cap` with `q = n / cap`, `r = n % cap`, which fits in u32
//! because the cap is at most [`MAX_CAP`]; both twins use exactly this integer
//! arithmetic, so their lists are identical element for element.
//!
//! GPU: four passes over blocks of window pixels (a scan, since atomic
//! append gives an unspecified order), see `encode`; only the header and
//! the final list are read back. Each of a block's [`GROUP`] invocations
//! reads a run of consecutive pixels, so the workgroup's scan and its
//! barriers serve a run of pixels an invocation. The run's length is the
//! context's [`GpuContext::compaction_run`] (the shader's overridable
//! `COMPACTION_RUN`): 32 on a CPU adapter, 8 on a GPU, the same lists
//! either way.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::rows::{for_each_row, parallel};
use super::{Feature, Window};
use crate::gpu::{
    Binding::{ReadOnly, Storage, Uniform},
    EntryPoint, GpuContext, GpuImage, Recorder, ShaderDef, run_once,
};
use crate::image::FloatImage;
use crate::{Error, Result};

/// The shader of this stage.
pub const SHADER: ShaderDef = ShaderDef {
    name: "compaction",
    source: include_str!("../../shaders/compaction.wgsl"),
    includes: &[],
    entry_points: &[
        EntryPoint::linear("count_blocks", GROUP, &[Uniform, ReadOnly, ReadOnly, Storage]),
        EntryPoint::linear("scan_blocks", GROUP, &[Uniform, ReadOnly, ReadOnly, Storage, Storage]),
        EntryPoint::linear("scatter", GROUP, &[Uniform, ReadOnly, ReadOnly, ReadOnly, ReadOnly, ReadOnly, Storage]),
        EntryPoint::linear("gather", GROUP, &[Uniform, ReadOnly, ReadOnly, ReadOnly, Storage]),
    ],
    overrides: &["COMPACTION_RUN"],
};

/// Largest cap accepted: keeps `j·(n % cap)` below 2³² in the stratum bounds.
pub const MAX_CAP: u32 = 65_535;
/// Invocations per workgroup of every pass (the shader's `GROUP`).
pub const GROUP: u32 = 256;
/// Most workgroups per grid dimension (wgpu's downlevel limit); longer block
/// grids wrap onto a second dimension.
const MAX_GROUPS_PER_DIM: u32 = 65_535;
/// Bytes of the header in front of the list in the staging buffer.
const HEADER_BYTES: u64 = std::mem::size_of::<Header>() as u64;
/// Bytes of one listed feature.
const FEATURE_BYTES: u64 = std::mem::size_of::<Feature>() as u64;
/// Features [`compaction_gpu`] prefetches with the header when there is no cap.
const STANDALONE_PREFETCH: u32 = 4096;
/// Window rows per task of the parallel CPU twin.
const BAND_ROWS: usize = 16;

/// Parameters of compaction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompactionParams {
    /// Window of interest (clipped to the image).
    pub window: Window,
    /// A pixel is listed when `select > threshold` (must not be NaN).
    pub threshold: f32,
    /// Keep at most this many features (a stratified random subsample, see the
    /// module doc); at most [`MAX_CAP`]. 002 uses 1500.
    pub cap: Option<u32>,
    /// Seed of the subsample's hash.
    pub seed: u32,
}

/// Uniform block of `compaction.wgsl`; kept in sync with its `Params`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct CompactionUniform {
    image_width: u32,
    image_height: u32,
    grid_x: u32,
    max_blocks: u32,
    list_stride: u32,
    capped_stride: u32,
    _pad0: u32,
    _pad1: u32,
}

/// One layer's window and list parameters; kept in sync with `LayerWindow`
/// in `compaction.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct LayerWindow {
    x0: u32,
    y0: u32,
    win_width: u32,
    area: u32,
    num_blocks: u32,
    cap: u32,
    seed: u32,
    threshold: f32,
}

/// The GPU list header; kept in sync with `Header` in `compaction.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Header {
    /// Selected pixels in the window (n).
    total: u32,
    /// Features in the final list: `min(n, cap)`.
    listed: u32,
    _pad0: u32,
    _pad1: u32,
}

/// lowbias32 (C. Wellons, "hash-prospector"): a 32-bit integer mix; same as the shader's.
fn lowbias32(v: u32) -> u32 {
    let mut x = v;
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// `lo_j = floor(j·n / cap)` without overflow (`j ≤ cap ≤ MAX_CAP`).
fn stratum_start(j: u32, n: u32, cap: u32) -> u32 {
    let q = n / cap;
    let r = n % cap;
    j * q + (j * r) / cap
}

/// The rank kept from stratum `j` when `n > cap`: `lo_j + hash % (lo_{j+1} − lo_j)`.
fn subsample_rank(j: u32, n: u32, cap: u32, seed: u32) -> u32 {
    let lo = stratum_start(j, n, cap);
    let hi = stratum_start(j + 1, n, cap);
    lo + lowbias32(seed ^ j.wrapping_mul(0x9e37_79b9)) % (hi - lo)
}

/// Check the parameters against images of `size`; the clipped window.
fn checked_window(size: (usize, usize), params: &CompactionParams) -> Result<Window> {
    if params.threshold.is_nan() {
        return Err(Error::Parameter("compaction threshold is NaN".into()));
    }
    if let Some(cap) = params.cap.filter(|&c| c > MAX_CAP) {
        return Err(Error::Parameter(format!("compaction cap {cap} exceeds {MAX_CAP}")));
    }
    let window = params.window.clipped(size.0, size.1);
    if window.area() > u32::MAX as usize {
        return Err(Error::Parameter(format!("window of {} pixels is too large to list", window.area())));
    }
    Ok(window)
}

fn check_sizes(select: (usize, usize), theta: (usize, usize), magnitude: (usize, usize)) -> Result<()> {
    if select != theta || select != magnitude {
        return Err(Error::Size(format!(
            "compaction: select {}x{}, theta {}x{}, magnitude {}x{}",
            select.0, select.1, theta.0, theta.1, magnitude.0, magnitude.1
        )));
    }
    Ok(())
}

/// Pixels of a row tested per bit mask in [`list_row`].
const SCAN_LANES: usize = 32;

/// Append the selected pixels of window row `y` (columns `x0..x0 + sel.len()`)
/// to `emit`, left to right. The row is tested `SCAN_LANES` pixels at a time
/// into a bit mask (no branch per pixel, so the comparisons vectorise), and
/// only the set bits are visited.
#[inline]
fn list_row(
    sel: &[f32],
    theta: &[f32],
    mag: &[f32],
    x0: usize,
    y: usize,
    threshold: f32,
    mut emit: impl FnMut(Feature),
) {
    let mut emit_at = |dx: usize| {
        emit(Feature { x: (x0 + dx) as u32, y: y as u32, theta: theta[dx], magnitude: mag[dx] });
    };
    let mut chunks = sel.chunks_exact(SCAN_LANES);
    for (c, chunk) in (&mut chunks).enumerate() {
        let mut bits = 0u32;
        for (i, &s) in chunk.iter().enumerate() {
            bits |= u32::from(s > threshold) << i;
        }
        while bits != 0 {
            emit_at(c * SCAN_LANES + bits.trailing_zeros() as usize);
            bits &= bits - 1;
        }
    }
    let tail = sel.len() - chunks.remainder().len();
    for (i, &s) in chunks.remainder().iter().enumerate() {
        if s > threshold {
            emit_at(tail + i);
        }
    }
}

/// CPU twin: the features of `params.window` into `out` (cleared first; the
/// list allocates only when it grows). A small window is listed row by row;
/// a large one by the GPU's own scheme — count per band of `BAND_ROWS` rows,
/// prefix-sum, fill each band's slice of the list — with its bands on
/// several threads. Both give the same list.
pub fn compaction_cpu(
    select: &FloatImage,
    theta: &FloatImage,
    magnitude: &FloatImage,
    params: &CompactionParams,
    out: &mut Vec<Feature>,
) -> Result<()> {
    check_sizes(select.size(), theta.size(), magnitude.size())?;
    let win = checked_window(select.size(), params)?;
    out.clear();
    if win.is_empty() {
        return Ok(());
    }
    let (x0, x1) = (win.x0 as usize, win.x1 as usize);
    let (y0, y1) = (win.y0 as usize, win.y1 as usize);
    let th = params.threshold;
    fn span(img: &FloatImage, y: usize, x0: usize, x1: usize) -> &[f32] {
        let w = img.width();
        &img.data()[y * w + x0..y * w + x1]
    }

    let area = win.area();
    if !parallel(area) {
        // One thread: rows straight into the list, in the same order.
        for y in y0..y1 {
            list_row(span(select, y, x0, x1), span(theta, y, x0, x1), span(magnitude, y, x0, x1), x0, y, th, |f| {
                out.push(f)
            });
        }
    } else {
        let bands = (y1 - y0).div_ceil(BAND_ROWS);
        let rows_of = |band: usize| y0 + band * BAND_ROWS..(y0 + (band + 1) * BAND_ROWS).min(y1);
        let mut counts = vec![0usize; bands];
        for_each_row(area, counts.par_iter_mut().enumerate(), |(band, count)| {
            *count = rows_of(band).map(|y| span(select, y, x0, x1).iter().filter(|&&s| s > th).count()).sum();
        });
        out.resize(counts.iter().sum(), Feature::default());
        let mut slices = Vec::with_capacity(bands);
        let mut rest = out.as_mut_slice();
        for &c in &counts {
            let (head, tail) = rest.split_at_mut(c);
            slices.push(head);
            rest = tail;
        }
        for_each_row(area, slices.into_par_iter().enumerate(), |(band, dst)| {
            let mut k = 0;
            for y in rows_of(band) {
                list_row(span(select, y, x0, x1), span(theta, y, x0, x1), span(magnitude, y, x0, x1), x0, y, th, |f| {
                    dst[k] = f;
                    k += 1;
                });
            }
        });
    }

    if let Some(cap) = params.cap {
        let n = out.len() as u32; // ≤ window area ≤ u32::MAX, checked above
        if n > cap {
            // In place: rank_j ≥ lo_j ≥ j, so slot j is read before it is overwritten.
            for j in 0..cap {
                out[j as usize] = out[subsample_rank(j, n, cap, params.seed) as usize];
            }
            out.truncate(cap as usize);
        }
    }
    Ok(())
}

/// CPU twin, allocating its output: the feature list.
pub fn compaction(
    select: &FloatImage,
    theta: &FloatImage,
    magnitude: &FloatImage,
    params: &CompactionParams,
) -> Result<Vec<Feature>> {
    let mut out = Vec::new();
    compaction_cpu(select, theta, magnitude, params, &mut out)?;
    Ok(out)
}

/// GPU scratch of compaction, allocated once and reused every frame: per-block
/// counts and offsets, the full list, the capped list, the header, and a
/// `MAP_READ` staging buffer for the header and the list; one part of each
/// per layer for stacked images ([`CompactionGpu::layered`]).
#[derive(Debug)]
pub struct CompactionGpu {
    block_counts: wgpu::Buffer,
    block_offsets: wgpu::Buffer,
    full_list: wgpu::Buffer,
    capped_list: wgpu::Buffer,
    header: wgpu::Buffer,
    windows: wgpu::Buffer,
    staging: wgpu::Buffer,
    max_pixels: usize,
    max_cap: Option<u32>,
    layers: usize,
    /// The run length the scratch was sized for (its context's
    /// [`GpuContext::compaction_run`]).
    run: u32,
    /// Whether the last [`encode`] gathered into `capped_list`.
    last_capped: AtomicBool,
    /// Features of each layer copied to `staging` by the last
    /// [`CompactionGpu::encode_readback`].
    prefetched: Mutex<Vec<u32>>,
}

/// `Ok` when a list of up to `max_pixels` features fits a device with
/// `limits` (one storage binding, one buffer with its header); otherwise an
/// [`Error::Parameter`] stating the list's size and the device's limit.
pub fn check_list_fits(limits: &wgpu::Limits, max_pixels: usize) -> Result<()> {
    let list_bytes = (max_pixels.max(1) as u64).saturating_mul(FEATURE_BYTES);
    let limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size.saturating_sub(HEADER_BYTES));
    if list_bytes > limit {
        return Err(Error::Parameter(format!(
            "a list of {max_pixels} features takes {list_bytes} bytes, more than the device's buffer limit of \
             {limit} bytes"
        )));
    }
    Ok(())
}

impl CompactionGpu {
    /// Scratch for windows of up to `max_pixels` pixels and caps up to
    /// `max_cap` (`None`: uncapped lists only). Errors when `max_cap` exceeds
    /// [`MAX_CAP`] or the lists exceed the device's buffer limits.
    pub fn new(ctx: &GpuContext, max_pixels: usize, max_cap: Option<u32>) -> Result<Self> {
        Self::layered(ctx, max_pixels, max_cap, 1)
    }

    /// [`CompactionGpu::new`] for `layers` (at least 1) stacked images, a
    /// list of each; the device must hold all of them in one buffer.
    pub fn layered(ctx: &GpuContext, max_pixels: usize, max_cap: Option<u32>, layers: usize) -> Result<Self> {
        if let Some(cap) = max_cap.filter(|&c| c > MAX_CAP) {
            return Err(Error::Parameter(format!("compaction cap {cap} exceeds {MAX_CAP}")));
        }
        let layers = layers.max(1);
        check_list_fits(&ctx.device.limits(), max_pixels.max(1).saturating_mul(layers))?;
        let n = layers as u64;
        let list_bytes = max_pixels.max(1) as u64 * FEATURE_BYTES * n;
        let run = ctx.compaction_run();
        let max_blocks = blocks(max_pixels, run).max(1) as u64;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let capped = u64::from(max_cap.unwrap_or(0)).min(max_pixels as u64).max(1);
        Ok(Self {
            block_counts: buffer("compaction.block_counts", max_blocks * 4 * n, storage),
            block_offsets: buffer("compaction.block_offsets", max_blocks * 4 * n, storage),
            full_list: buffer("compaction.full_list", list_bytes, storage),
            capped_list: buffer("compaction.capped_list", capped * FEATURE_BYTES * n, storage),
            header: buffer("compaction.header", HEADER_BYTES * n, storage),
            windows: buffer(
                "compaction.windows",
                std::mem::size_of::<LayerWindow>() as u64 * n,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ),
            staging: buffer(
                "compaction.staging",
                HEADER_BYTES * n + list_bytes,
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            max_pixels,
            max_cap,
            layers,
            run,
            last_capped: AtomicBool::new(false),
            prefetched: Mutex::new(vec![0; layers]),
        })
    }

    /// Whether this scratch serves windows of `max_pixels` pixels with cap `cap`.
    #[must_use]
    pub fn fits(&self, max_pixels: usize, cap: Option<u32>) -> bool {
        max_pixels <= self.max_pixels
            && match cap {
                None => true,
                Some(c) => self.max_cap.is_some_and(|m| c <= m),
            }
    }

    /// Features the capped list holds: never more than a window has pixels.
    fn capped_capacity(&self) -> u64 {
        u64::from(self.max_cap.unwrap_or(0)).min(self.max_pixels as u64)
    }

    /// The list the last [`encode`] left, how many features each layer's
    /// part can hold, and where the next layer's part starts (features).
    fn list(&self) -> (&wgpu::Buffer, u64, u64) {
        if self.last_capped.load(Ordering::Relaxed) {
            let capacity = self.capped_capacity();
            (&self.capped_list, capacity, capacity.max(1))
        } else {
            (&self.full_list, self.max_pixels as u64, self.max_pixels.max(1) as u64)
        }
    }

    fn prefetched(&self) -> std::sync::MutexGuard<'_, Vec<u32>> {
        self.prefetched.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Record, in the same submission as [`encode`], copies of the header and
    /// of the first `min(prefetch, capacity)` features into the staging buffer.
    pub(crate) fn encode_readback(&self, rec: &mut Recorder<'_>, prefetch: u32) {
        self.encode_readback_layers(rec, &[prefetch]);
    }

    /// [`CompactionGpu::encode_readback`] for every layer, `prefetch[l]`
    /// features of layer `l` (0 for a layer not given): the headers in one
    /// copy, then each layer's features packed one after another.
    pub(crate) fn encode_readback_layers(&self, rec: &mut Recorder<'_>, prefetch: &[u32]) {
        let (list, capacity, stride) = self.list();
        let headers = HEADER_BYTES * self.layers as u64;
        rec.copy(&self.header, 0, &self.staging, 0, headers);
        let mut prefetched = self.prefetched();
        let mut at = headers;
        for (layer, kept) in prefetched.iter_mut().enumerate() {
            let count = u64::from(prefetch.get(layer).copied().unwrap_or(0)).min(capacity);
            rec.copy(list, layer as u64 * stride * FEATURE_BYTES, &self.staging, at, count * FEATURE_BYTES);
            at += count * FEATURE_BYTES;
            *kept = count as u32;
        }
    }

    /// Bytes that crossed the bus for a list of `listed` features read by
    /// [`CompactionGpu::read`]: the header, the prefetched features, and
    /// the remainder's copy when the list was longer.
    #[must_use]
    pub fn bytes_read_back(&self, listed: usize) -> u64 {
        self.bytes_read_back_layer(0, listed)
    }

    /// [`CompactionGpu::bytes_read_back`] of layer `layer`.
    #[must_use]
    pub fn bytes_read_back_layer(&self, layer: usize, listed: usize) -> u64 {
        let prefetched = u64::from(self.prefetched().get(layer).copied().unwrap_or(0));
        HEADER_BYTES + FEATURE_BYTES * prefetched.max(listed as u64)
    }

    /// After the submission holding `CompactionGpu::encode_readback` is
    /// done: map the staging buffer and return the list. When it is longer
    /// than what was prefetched, one more copy of the remainder is submitted
    /// and mapped, so only `16 + 16·count` bytes ever cross the bus.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<Feature>> {
        self.read_layers(ctx)?.into_iter().next().ok_or_else(|| Error::Gpu("no compaction layer".into()))
    }

    /// [`CompactionGpu::read`] for every layer: each layer's list, in layer
    /// order, decoded on parallel threads. The remainders of all lists
    /// longer than their prefetch go in one more submission.
    pub fn read_layers(&self, ctx: &GpuContext) -> Result<Vec<Vec<Feature>>> {
        let prefetched = self.prefetched().clone();
        let headers_bytes = HEADER_BYTES * self.layers as u64;
        let prefetched_bytes: u64 = prefetched.iter().map(|&p| u64::from(p) * FEATURE_BYTES).sum();
        // The headers and the prefetched features, decoded straight from the mapping.
        let (headers, mut lists) = ctx.read_mapped(&self.staging, 0..headers_bytes + prefetched_bytes, |bytes| {
            let headers: Vec<Header> = bytemuck::pod_collect_to_vec(&bytes[..headers_bytes as usize]);
            // Where each layer's prefetched features start, and how many of them it listed.
            let mut at = headers_bytes as usize;
            let parts: Vec<(usize, usize)> = headers
                .iter()
                .zip(&prefetched)
                .map(|(header, &kept)| {
                    let part = (at, header.listed.min(kept) as usize * FEATURE_BYTES as usize);
                    at += kept as usize * FEATURE_BYTES as usize;
                    part
                })
                .collect();
            let decode = |&(at, len): &(usize, usize)| bytemuck::pod_collect_to_vec(&bytes[at..at + len]);
            let lists: Vec<Vec<Feature>> = if parts.len() > 1 {
                parts.par_iter().map(decode).collect()
            } else {
                parts.iter().map(decode).collect()
            };
            (headers, lists)
        })?;
        let (list, capacity, stride) = self.list();
        let mut remainders = Vec::new();
        let mut at = 0;
        for (layer, (header, &kept)) in headers.iter().zip(&prefetched).enumerate() {
            let listed = u64::from(header.listed);
            if listed > capacity || header.listed > header.total {
                return Err(Error::Gpu(format!(
                    "compaction header lists {} of {} features, capacity {capacity}",
                    header.listed, header.total
                )));
            }
            if listed > u64::from(kept) {
                let size = (listed - u64::from(kept)) * FEATURE_BYTES;
                remainders.push((layer, (layer as u64 * stride + u64::from(kept)) * FEATURE_BYTES, at, size));
                at += size;
            }
        }
        if !remainders.is_empty() {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("compaction.readback") });
            for &(_, from, to, size) in &remainders {
                enc.copy_buffer_to_buffer(list, from, &self.staging, to, size);
            }
            ctx.wait_for(ctx.queue.submit([enc.finish()]))?;
            ctx.read_mapped(&self.staging, 0..at, |rest| {
                for &(layer, _, to, size) in &remainders {
                    let part = &rest[to as usize..(to + size) as usize];
                    lists[layer]
                        .extend(part.chunks_exact(FEATURE_BYTES as usize).map(bytemuck::pod_read_unaligned::<Feature>));
                }
            })?;
        }
        Ok(lists)
    }
}

/// The blocks covering `pixels` window pixels with runs of `run` pixels: a
/// block (the shader's `BLOCK`) is the `GROUP` runs of one workgroup of the
/// count and scatter passes.
fn blocks(pixels: usize, run: u32) -> usize {
    pixels.div_ceil((GROUP * run) as usize)
}

/// Workgroups covering `blocks` blocks, wrapping onto a second dimension past
/// the per-dimension limit; `[0, 1, 1]` (skipped) when there are none.
fn block_grid(blocks: u32) -> [u32; 3] {
    let x = blocks.min(MAX_GROUPS_PER_DIM);
    [x, if x == 0 { 1 } else { blocks.div_ceil(x) }, 1]
}

/// Record compaction of `params.window` of `select`, `theta`, `magnitude`
/// (all the same size) into `scratch`'s list. Dispatches: 3 without a cap
/// (count_blocks, scan_blocks, scatter; the first and last over
/// `ceil(area / block)` workgroups, skipped for an empty window, scan_blocks
/// always one workgroup so the header is always written), 4 with a cap
/// (gather over `ceil(min(cap, area) / GROUP)` workgroups). Follow with
/// [`CompactionGpu::encode_readback`] in the same submission.
pub(crate) fn encode(
    rec: &mut Recorder<'_>,
    select: &GpuImage,
    theta: &GpuImage,
    magnitude: &GpuImage,
    params: &CompactionParams,
    scratch: &CompactionGpu,
) -> Result<()> {
    encode_layers(rec, select, theta, magnitude, &[*params], scratch)
}

/// [`encode`] over stacked images: layer `l` of `select`, `theta`,
/// `magnitude` compacted with `params[l]` into list `l` of `scratch`, the
/// same dispatches covering every layer (their grids sized for the
/// largest window). The layers' caps may differ, but either all are capped
/// or none is.
pub(crate) fn encode_layers(
    rec: &mut Recorder<'_>,
    select: &GpuImage,
    theta: &GpuImage,
    magnitude: &GpuImage,
    params: &[CompactionParams],
    scratch: &CompactionGpu,
) -> Result<()> {
    let size = select.size();
    check_sizes(size, theta.size(), magnitude.size())?;
    let layers = select.layers();
    if [theta.layers(), magnitude.layers(), params.len(), scratch.layers].iter().any(|&n| n != layers) {
        return Err(Error::Size(format!(
            "compaction of {layers} layers (theta {}, magnitude {}) with {} windows into scratch for {} lists",
            theta.layers(),
            magnitude.layers(),
            params.len(),
            scratch.layers
        )));
    }
    if rec.context().compaction_run() != scratch.run {
        return Err(Error::Gpu(format!(
            "compaction scratch sized for runs of {} pixels recorded on a context with runs of {}",
            scratch.run,
            rec.context().compaction_run()
        )));
    }
    let capped = params.first().is_some_and(|p| p.cap.is_some());
    if params.iter().any(|p| p.cap.is_some() != capped) {
        return Err(Error::Parameter("stacked compaction: either every layer has a cap or none has".into()));
    }
    let mut windows = Vec::with_capacity(params.len());
    for p in params {
        let win = checked_window(size, p)?;
        if win.area() > scratch.max_pixels {
            return Err(Error::Size(format!(
                "window of {} pixels, compaction scratch holds {}",
                win.area(),
                scratch.max_pixels
            )));
        }
        if let Some(cap) = p.cap.filter(|&c| c > scratch.max_cap.unwrap_or(0)) {
            return Err(Error::Parameter(format!(
                "cap {cap}, compaction scratch built for caps up to {:?}",
                scratch.max_cap
            )));
        }
        let area = win.area() as u32;
        windows.push(LayerWindow {
            x0: win.x0,
            y0: win.y0,
            win_width: win.width(),
            area,
            num_blocks: blocks(area as usize, scratch.run) as u32,
            cap: p.cap.unwrap_or(u32::MAX),
            seed: p.seed,
            threshold: p.threshold,
        });
    }
    let layers = layers as u32;
    let most_blocks = windows.iter().map(|w| w.num_blocks).max().unwrap_or(0);
    let [gx, gy, _] = block_grid(most_blocks);
    let grid = [gx, gy, layers];
    let s = scratch;
    let u = CompactionUniform {
        image_width: size.0 as u32,
        image_height: size.1 as u32,
        grid_x: gx,
        max_blocks: blocks(s.max_pixels, s.run).max(1) as u32,
        list_stride: s.max_pixels.max(1) as u32,
        capped_stride: s.capped_capacity().max(1) as u32,
        _pad0: 0,
        _pad1: 0,
    };
    rec.context().queue.write_buffer(&s.windows, 0, bytemuck::cast_slice(&windows));
    rec.dispatch(&SHADER, "count_blocks", &u, &[&s.windows, &select.buffer, &s.block_counts], grid)?;
    rec.dispatch(
        &SHADER,
        "scan_blocks",
        &u,
        &[&s.windows, &s.block_counts, &s.block_offsets, &s.header],
        [1, 1, layers],
    )?;
    rec.dispatch(
        &SHADER,
        "scatter",
        &u,
        &[&s.windows, &select.buffer, &theta.buffer, &magnitude.buffer, &s.block_offsets, &s.full_list],
        grid,
    )?;
    if capped {
        let groups = windows.iter().map(|w| w.cap.min(w.area).div_ceil(GROUP)).max().unwrap_or(0);
        rec.dispatch(
            &SHADER,
            "gather",
            &u,
            &[&s.windows, &s.header, &s.full_list, &s.capped_list],
            [groups, 1, layers],
        )?;
    }
    s.last_capped.store(capped, Ordering::Relaxed);
    Ok(())
}

/// GPU: upload the three images, compact, and read the list back (tests and benches).
pub fn compaction_gpu(
    ctx: &GpuContext,
    select: &FloatImage,
    theta: &FloatImage,
    magnitude: &FloatImage,
    params: &CompactionParams,
) -> Result<Vec<Feature>> {
    check_sizes(select.size(), theta.size(), magnitude.size())?;
    let win = checked_window(select.size(), params)?;
    let scratch = CompactionGpu::new(ctx, win.area(), params.cap)?;
    let sel = GpuImage::from_image(ctx, select, "compaction.select");
    let th = GpuImage::from_image(ctx, theta, "compaction.theta");
    let mag = GpuImage::from_image(ctx, magnitude, "compaction.magnitude");
    run_once(ctx, |rec| {
        encode(rec, &sel, &th, &mag, params, &scratch)?;
        scratch.encode_readback(rec, params.cap.unwrap_or(STANDALONE_PREFETCH));
        Ok(())
    })?;
    scratch.read(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 4×3 mask (1 = selected), θ = x + y/10 and magnitude = 10·y + x, so each
    /// feature's values name its pixel.
    fn tiny() -> (FloatImage, FloatImage, FloatImage) {
        #[rustfmt::skip]
        let mask = vec![
            0.0, 1.0, 0.0, 1.0,
            1.0, 0.0, 0.0, 0.0,
            0.0, 0.0, 1.0, 1.0,
        ];
        let select = FloatImage::from_vec(4, 3, mask).unwrap();
        let theta = FloatImage::from_fn(4, 3, |x, y| x as f32 + y as f32 / 10.0);
        let magnitude = FloatImage::from_fn(4, 3, |x, y| (10 * y + x) as f32);
        (select, theta, magnitude)
    }

    fn f(x: u32, y: u32, theta: f32, magnitude: f32) -> Feature {
        Feature { x, y, theta, magnitude }
    }

    fn params(window: Window, cap: Option<u32>) -> CompactionParams {
        CompactionParams { window, threshold: 0.5, cap, seed: 7 }
    }

    #[test]
    fn tiny_mask_lists_set_pixels_row_major() {
        let (s, t, m) = tiny();
        let all = compaction(&s, &t, &m, &params(Window::full(4, 3), None)).unwrap();
        let expected =
            vec![f(1, 0, 1.0, 1.0), f(3, 0, 3.0, 3.0), f(0, 1, 0.1, 10.0), f(2, 2, 2.2, 22.0), f(3, 2, 3.2, 23.0)];
        assert_eq!(all, expected);

        // Columns 1..3, rows 0..3: only (1, 0) and (2, 2).
        let win = Window { x0: 1, y0: 0, x1: 3, y1: 3 };
        assert_eq!(compaction(&s, &t, &m, &params(win, None)).unwrap(), vec![f(1, 0, 1.0, 1.0), f(2, 2, 2.2, 22.0)]);

        // A window reaching past the image is clipped: rows 2.., columns 3..
        let outside = Window { x0: 3, y0: 2, x1: 100, y1: 100 };
        assert_eq!(compaction(&s, &t, &m, &params(outside, None)).unwrap(), vec![f(3, 2, 3.2, 23.0)]);

        // Empty window.
        let empty = Window { x0: 2, y0: 0, x1: 2, y1: 3 };
        assert!(compaction(&s, &t, &m, &params(empty, None)).unwrap().is_empty());
    }

    /// The bit-mask scan lists exactly the pixels a plain left-to-right
    /// filter lists, on rows shorter than, equal to and longer than the
    /// mask width, with NaN and ±∞ among the values.
    #[test]
    fn row_scan_lists_what_a_plain_filter_lists() {
        for len in [0, 1, 5, SCAN_LANES - 1, SCAN_LANES, SCAN_LANES + 1, 3 * SCAN_LANES + 7, 17 * SCAN_LANES + 3] {
            let sel: Vec<f32> = (0..len)
                .map(|i| match i % 11 {
                    3 => f32::NAN,
                    5 => f32::INFINITY,
                    7 => f32::NEG_INFINITY,
                    k => (k as f32 * 0.37 + i as f32 * 0.11).sin(),
                })
                .collect();
            let theta: Vec<f32> = (0..len).map(|i| i as f32).collect();
            let mag: Vec<f32> = (0..len).map(|i| -(i as f32)).collect();
            let mut listed = Vec::new();
            list_row(&sel, &theta, &mag, 4, 9, 0.25, |f| listed.push(f));
            let expected: Vec<Feature> =
                (0..len).filter(|&i| sel[i] > 0.25).map(|i| f(4 + i as u32, 9, theta[i], mag[i])).collect();
            assert_eq!(listed, expected, "row of {len}");
        }
    }

    #[test]
    fn threshold_is_strict() {
        let (_, t, m) = tiny();
        // Magnitude as select: 23 > 22 only; 22 itself is not listed.
        let p = CompactionParams { window: Window::full(4, 3), threshold: 22.0, cap: None, seed: 0 };
        assert_eq!(compaction(&m, &t, &m, &p).unwrap(), vec![f(3, 2, 3.2, 23.0)]);
    }

    #[test]
    fn strata_of_ten_into_three() {
        // n = 10, cap = 3: q = 3, r = 1, lo = 0, 3 + 1/3 = 3, 6 + 2/3 = 6, 9 + 3/3 = 10.
        let starts: Vec<u32> = (0..=3).map(|j| stratum_start(j, 10, 3)).collect();
        assert_eq!(starts, vec![0, 3, 6, 10]);
        // A 10×1 all-selected image, θ = x: the listed x are the kept ranks.
        let ones = FloatImage::from_fn(10, 1, |_, _| 1.0);
        let xs = FloatImage::from_fn(10, 1, |x, _| x as f32);
        for seed in [0u32, 1, 7, 12345] {
            let p = CompactionParams { window: Window::full(10, 1), threshold: 0.5, cap: Some(3), seed };
            let got = compaction(&ones, &xs, &xs, &p).unwrap();
            let ranks: Vec<u32> = got.iter().map(|f| f.x).collect();
            let expected: Vec<u32> = (0..3u32)
                .map(|j| {
                    let (lo, hi) = (starts[j as usize], starts[j as usize + 1]);
                    lo + lowbias32(seed ^ j.wrapping_mul(0x9e37_79b9)) % (hi - lo)
                })
                .collect();
            assert_eq!(ranks, expected, "seed {seed}");
            assert!(ranks[0] < 3 && (3..6).contains(&ranks[1]) && (6..10).contains(&ranks[2]), "{ranks:?}");
        }
    }

    #[test]
    fn lowbias32_mixes() {
        assert_eq!(lowbias32(0), 0);
        assert_ne!(lowbias32(1), lowbias32(2));
        // One input bit flips about half the output bits.
        let flips = (lowbias32(0x1234_5678) ^ lowbias32(0x1234_5679)).count_ones();
        assert!((8..=24).contains(&flips), "{flips}");
    }

    #[test]
    fn cap_at_least_n_returns_all() {
        let (s, t, m) = tiny();
        let all = compaction(&s, &t, &m, &params(Window::full(4, 3), None)).unwrap();
        for cap in [5, 6, 100] {
            assert_eq!(compaction(&s, &t, &m, &params(Window::full(4, 3), Some(cap))).unwrap(), all);
        }
        assert_eq!(compaction(&s, &t, &m, &params(Window::full(4, 3), Some(0))).unwrap(), vec![]);
        assert_eq!(compaction(&s, &t, &m, &params(Window::full(4, 3), Some(1))).unwrap().len(), 1);
    }

    #[test]
    fn bad_parameters_are_errors() {
        let (s, t, m) = tiny();
        assert!(matches!(
            compaction(&s, &t, &m, &params(Window::full(4, 3), Some(MAX_CAP + 1))),
            Err(Error::Parameter(_))
        ));
        let nan = CompactionParams { threshold: f32::NAN, ..params(Window::full(4, 3), None) };
        assert!(matches!(compaction(&s, &t, &m, &nan), Err(Error::Parameter(_))));
        let small = FloatImage::new(3, 3);
        assert!(matches!(compaction(&s, &small, &m, &params(Window::full(4, 3), None)), Err(Error::Size(_))));
    }

    #[test]
    fn parallel_path_matches_serial_rows() {
        // A window big enough to list its bands on several threads (≥ PARALLEL_PIXELS).
        let (w, h) = (300, 250);
        let sel = FloatImage::from_fn(w, h, |x, y| ((x * 7 + y * 13) % 5 == 0) as u32 as f32);
        let th = FloatImage::from_fn(w, h, |x, y| (x + y) as f32);
        let got = compaction(&sel, &th, &th, &params(Window::full(w, h), None)).unwrap();
        let mut expected = Vec::new();
        for y in 0..h {
            for x in 0..w {
                if sel.get(x, y) > 0.5 {
                    expected.push(f(x as u32, y as u32, (x + y) as f32, (x + y) as f32));
                }
            }
        }
        assert_eq!(got, expected);
    }
}
