//! Straight line segments from the LoG zero crossings (001, "Real-time line
//! detection"): the zero crossings of a window are linked into chains with
//! Canny hysteresis, the chains are cut into straight segments by Lowe's
//! (1987) scale-invariant recursive subdivision, and the segments are indexed
//! by midpoint and orientation for the matcher.
//!
//! # Input
//!
//! The zero-crossing list of one frame
//! ([`FrameFeatures::zero_crossings`](crate::backend::FrameFeatures::zero_crossings),
//! asked for with a [`ZeroCrossingRequest`](crate::backend::ZeroCrossingRequest))
//! and the window it was computed in. Each [`Feature`] is one edgel: its
//! pixel `(x, y)` in frame coordinates, `magnitude` = the strength
//! `sqrt(gx² + gy²)` of the LoG differences across the crossing, and `theta`
//! = `atan2(gy, gx)`, the direction in which the LoG increases across the
//! edge: from the bright side towards the dark side, opposite the intensity
//! gradient ([`crate::early::zero_crossing`]). The list should be uncapped (a
//! random subsample breaks the chains). Its order does not matter; features
//! outside the window, and a second feature at a pixel already listed, are
//! ignored.
//!
//! # Linking with hysteresis
//!
//! 001: "edge pixels are linked into lists on the basis of local 8-neighbor
//! connectivity. At the same time, Canny (1986) hysteresis thresholding is
//! performed using a high and low threshold on gradient."
//!
//! 1. *Hysteresis.* Edgels with `magnitude ≥ low_threshold` are candidates.
//!    A candidate is kept when it is 8-connected through candidates to an
//!    edgel with `magnitude ≥ high_threshold` (Canny's rule, by connected
//!    component: a faint edge joined to a strong one is kept wherever it
//!    joins it, a faint edge on its own is dropped).
//! 2. *Adjacency.* Kept edgels are linked to their 8-neighbours by mixed
//!    adjacency (m-adjacency): the four side neighbours always, a diagonal
//!    neighbour only when neither of the two side neighbours the pair shares
//!    is kept. The zero crossings of a slanted edge form a 4-connected
//!    staircase (horizontal and vertical crossings fall on different
//!    pixels); under plain 8-adjacency every step of it would have three
//!    neighbours, under m-adjacency it is a simple path with the same
//!    connectivity.
//! 3. *Junctions.* A kept edgel with three or more neighbours is a junction.
//!    Chains run through edgels with at most two neighbours and stop at ends
//!    (one neighbour) and at junctions; a chain that reaches a junction takes
//!    the junction edgel as its last pixel, so the chains meeting at a
//!    junction share that pixel and each reaches it. Two junctions next to
//!    each other are not a chain. A chain that comes back to its first pixel
//!    without meeting an end or a junction is *closed*.
//!
//! Chains are traced from their pixels in list order (raster order for a
//! backend list), so the result does not depend on the platform.
//!
//! # Recursive subdivision
//!
//! 001: "The resulting lists of connected edge points are segmented into
//! straight line segments using a scale-invariant recursive subdivision
//! algorithm described in an earlier paper (Lowe 1987)." For a piece of a
//! chain, pixels `p_i ..= p_j` in chain order:
//!
//! - its *deviation* is the largest distance of a pixel from the chord
//!   `p_i p_j` (from `p_i` when `p_i = p_j`), and the pixel of largest
//!   deviation (the first one on a tie) is its *split point* `p_k`;
//! - its *significance* is `|p_j − p_i| / max(deviation, deviation_floor)`:
//!   the ratio of length to deviation, which does not change with the scale
//!   of the image, with the deviation floored (default 2 px) because pixel
//!   quantisation and the LoG's rounding of corners make deviations below a
//!   couple of pixels meaningless;
//! - a piece of fewer than three pixels, or whose deviation is at most the
//!   floor, is represented by itself (one segment);
//! - otherwise both pieces `p_i ..= p_k` and `p_k ..= p_j` are represented
//!   recursively; the significance of a representation is the largest
//!   significance among the segments it consists of. When the larger of the
//!   two pieces' representations' significances exceeds the piece's own,
//!   the piece is represented by its two pieces' segments (which share
//!   `p_k`); otherwise by itself, as one segment.
//!
//! An open chain is subdivided from its first to its last pixel. A closed
//! chain has no ends: it is cut at the pixel `A` farthest from its first
//! pixel and at the pixel `B` farthest from `A` (both lie on its convex hull,
//! at corners of a polygon), and the two halves `A → B` and `B → A` are
//! subdivided as open chains.
//!
//! Each segment is a total least squares line through its piece's pixels
//! (the principal axis of their scatter, through their centroid), its end
//! points the projections of the piece's first and last pixels on that line,
//! so segments are sub-pixel. Segments shorter than `min_length` are dropped.
//!
//! # Index
//!
//! 001: "all of the line segments are indexed into a three-dimensional array
//! on the basis of 2-D position of the midpoint and orientation."
//! [`SegmentIndex`] is that array: square cells of `cell_size` pixels over the
//! window (larger cells over a window wider than [`MAX_CELLS_PER_AXIS`]
//! cells; a midpoint outside the window goes to the nearest border cell)
//! times `orientation_bins` bins of `[0, π)`, held as one list of segment
//! numbers grouped by cell with an offset per cell. A query visits only the
//! cells whose position range and orientation bins intersect its bounds (the
//! orientation range wraps around at 0 = π) and checks each segment found
//! there against the exact bounds.
//!
//! # Defaults of the thresholds
//!
//! Measured with the CPU backend (LoG σ = 1.2, default zero-crossing
//! `min_slope` 1) on rendered straight steps (exact-coverage canvas,
//! 128×128) at 18 orientations from 1.3° to 86.3° and sub-pixel offsets
//! 0..6.3 px, every edgel within 1 px of the step and 10 px of the border
//! (about 1940 per row), strength by contrast and pixel noise σ:
//!
//! | contrast | noise σ | least | 1st percentile | median | largest |
//! |---:|---:|---:|---:|---:|---:|
//! | 10 | 0 | 1.42 | 1.42 | 1.84 | 2.34 |
//! | 15 | 0 | 2.17 | 2.18 | 2.79 | 3.50 |
//! | 20 | 0 | 2.83 | 2.89 | 3.73 | 4.67 |
//! | 50 | 0 | 7.10 | 7.35 | 9.32 | 11.59 |
//! | 100 | 0 | 14.19 | 14.79 | 18.63 | 23.17 |
//! | 10 | 2 | 1.00 | 1.03 | 1.92 | 3.52 |
//! | 15 | 2 | 1.36 | 1.69 | 2.83 | 4.57 |
//! | 20 | 2 | 2.14 | 2.53 | 3.77 | 5.67 |
//!
//! so a step of contrast C gives 0.14·C to 0.23·C (weakest where the zero
//! falls on a pixel, strongest half-way between pixels and at corners).
//! Flat 640×480 frames of Gaussian pixel noise rounded to 8 bits give zero
//! crossings (the default `min_slope` drops most) of strength: σ = 1: 10
//! edgels, largest 1.09; σ = 2 (pipetrack's synthetic scenes): 12 010,
//! 99th percentile 1.68, largest 2.34; σ = 3: 52 254, 99th percentile 2.26,
//! largest 3.31; σ = 4: 85 337, 99th percentile 2.89, largest 4.50.
//!
//! The defaults `high_threshold` = 2.5 and `low_threshold` = 1.5 follow:
//! no noise edgel of σ ≤ 2 reaches `high`, so noise alone seeds nothing
//! (at σ = 3 it seeds 128 chains on a flat 640×480 frame, none giving a
//! segment of `min_length` 8 px); the median edgel of a step of contrast 15
//! passes `high` and 99 % of its edgels pass `low` even at noise σ = 2,
//! so it links along its length. On a quadrilateral over noise σ = 2 the
//! segments within 1.5 px and 5° of the sides cover 97–99 % of them at
//! contrast 15 (13 segments for 4 sides), 100 % at contrast 20 (one per
//! side) and 17–58 % at contrast 10. Edges of contrast 10 (weaker than
//! `high` without noise) are kept where they join a stronger edge.
//!
//! [`Feature`]: crate::early::Feature

use std::f64::consts::PI;
use std::ops::RangeInclusive;

use serde::{Deserialize, Serialize};

use crate::Result;
use crate::bounds::{Interval, check_count};
use crate::early::{Feature, Window};
use crate::estimate::line_fit::{orientation_difference, wrap_orientation};

/// Upper bound of [`SegmentParams::high_threshold`] and
/// [`SegmentParams::low_threshold`]: no zero crossing of an 8-bit frame is
/// this strong. The LoG kernels' second-derivative half has at most
/// `Σ|d_k| = 4` (the 5-point Laplacian's `[1, −2, 1]`, which the kernel
/// becomes at the smallest σ), so `|LoG| ≤ 2·4·255`, a difference across a
/// crossing at most twice that, and the strength at most `√2` times the
/// difference: 5770.
pub const MAX_THRESHOLD: f32 = 6000.0;

/// Upper bound of the pixel-sized parameters ([`SegmentParams::min_length`],
/// [`SegmentParams::deviation_floor`], [`SegmentParams::cell_size`]), px: a
/// frame is at most a few thousand pixels across.
pub const MAX_LENGTH_PX: f64 = 10_000.0;

/// Upper bound of [`SegmentParams::orientation_bins`]: bins of 1° are finer
/// than a segment's orientation is known.
pub const MAX_ORIENTATION_BINS: usize = 180;

/// Most cells of [`SegmentIndex`] along each axis: over a window wider than
/// this many cells the cells grow, so the array stays bounded whatever the
/// window (a 4K frame at the default 16 px needs 240).
pub const MAX_CELLS_PER_AXIS: usize = 256;

/// Default [`SegmentParams::cell_size`], px.
pub const DEFAULT_CELL_SIZE: f64 = 16.0;

/// Default [`SegmentParams::orientation_bins`] (15° each).
pub const DEFAULT_ORIENTATION_BINS: usize = 12;

/// Parameters of segment extraction and indexing, all with defaults, so a
/// `--config` TOML table may set any subset (unknown keys are refused).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SegmentParams {
    /// Canny's high threshold on the zero-crossing strength: a chain is
    /// kept only when joined to an edgel at least this strong. 2.5: above
    /// the strongest zero crossing of pixel noise σ = 2 (2.34), below the
    /// median edgel of a step of contrast 15 (2.79); module doc, "Defaults
    /// of the thresholds". The paper gives no value. Range: [`low_threshold`](Self::low_threshold)
    /// ..= [`MAX_THRESHOLD`].
    pub high_threshold: f32,
    /// Canny's low threshold: weaker edgels are dropped before linking.
    /// 1.5: above every zero crossing of pixel noise σ = 1 (at most 1.09)
    /// and 90 % of those of σ = 2, below 95 % of the edgels of a clean step
    /// of contrast 10. The paper gives no value. Range: (0, [`MAX_THRESHOLD`]].
    pub low_threshold: f32,
    /// Shortest segment kept, px. 8: a segment's orientation is known to
    /// about 1/length radians from its ±½ px pixel quantisation, so shorter
    /// ones say little about the model's edges and are mostly noise.
    /// Range: [0, [`MAX_LENGTH_PX`]].
    pub min_length: f64,
    /// Floor on a piece's deviation in its significance, px, so that pixel
    /// quantisation does not make short, nearly straight pieces arbitrarily
    /// significant. 2: the LoG at σ = 1.2 rounds a corner over about two
    /// pixels. Range: (0, [`MAX_LENGTH_PX`]].
    pub deviation_floor: f64,
    /// Side of the index's square cells, px. 16: a matcher's position
    /// bounds are a few pixels to a few tens of pixels wide, so a query
    /// visits a handful of cells, while a 640×480 window needs only 1200
    /// cells per orientation bin. Range: [1, [`MAX_LENGTH_PX`]].
    pub cell_size: f64,
    /// Orientation bins of the index over `[0, π)`. 12 (15° each): the
    /// matcher's orientation bounds are of that order.
    /// Range: 1 ..= [`MAX_ORIENTATION_BINS`].
    pub orientation_bins: usize,
}

impl Default for SegmentParams {
    fn default() -> Self {
        Self {
            high_threshold: 2.5,
            low_threshold: 1.5,
            min_length: 8.0,
            deviation_floor: 2.0,
            cell_size: DEFAULT_CELL_SIZE,
            orientation_bins: DEFAULT_ORIENTATION_BINS,
        }
    }
}

impl SegmentParams {
    /// Check every parameter against its documented range
    /// ([`crate::Error::Parameter`] naming the first bad one and its range).
    pub fn validate(&self) -> Result<()> {
        const WHO: &str = "lowe segments";
        let threshold = f64::from(MAX_THRESHOLD);
        Interval::open_closed(0.0, threshold).check(WHO, "low_threshold", f64::from(self.low_threshold), "")?;
        Interval::closed(f64::from(self.low_threshold), threshold).check(
            WHO,
            "high_threshold",
            f64::from(self.high_threshold),
            " (from low_threshold)",
        )?;
        Interval::closed(0.0, MAX_LENGTH_PX).check(WHO, "min_length", self.min_length, " px")?;
        Interval::open_closed(0.0, MAX_LENGTH_PX).check(WHO, "deviation_floor", self.deviation_floor, " px")?;
        Interval::closed(1.0, MAX_LENGTH_PX).check(WHO, "cell_size", self.cell_size, " px")?;
        check_count(WHO, "orientation_bins", self.orientation_bins, 1, MAX_ORIENTATION_BINS)
    }
}

/// One straight segment of the zero crossings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageSegment {
    /// End point at the chain's first pixel of the piece, pixel coordinates.
    pub start: [f64; 2],
    /// End point at the piece's last pixel.
    pub end: [f64; 2],
    /// `(start + end) / 2`.
    pub midpoint: [f64; 2],
    /// `|end − start|`, px.
    pub length: f64,
    /// Undirected orientation of `end − start`, radians in `[0, π)`
    /// (y down: π/2 is a vertical segment).
    pub orientation: f64,
    /// Mean zero-crossing strength of the piece's edgels.
    pub strength: f64,
    /// Circular mean of the piece's edgel directions `theta`, radians in
    /// `(−π, π]`: across the segment, from its bright side towards its dark
    /// side (the direction in which the LoG increases).
    pub direction: f64,
    /// Number of edgels of the piece.
    pub pixels: u32,
}

/// A chain of linked edgels, as a range of [`SegmentExtractor`]'s chain
/// pixel list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Chain {
    /// First entry in `chain_pixels`.
    first: usize,
    /// One past the last entry.
    end: usize,
    /// Whether the chain is a loop (its last pixel neighbours its first).
    closed: bool,
}

/// Edgel bit: kept by hysteresis.
const KEPT: u8 = 1;
/// Edgel bit: traced into a chain.
const VISITED: u8 = 2;

/// The eight neighbours of a pixel as `(dx, dy)`, in the order of their
/// bits in an edgel's neighbour mask: the side neighbours east, south,
/// west, north, then the diagonals south-east, south-west, north-west,
/// north-east (diagonal `4 + k` lies between sides `k` and `(k + 1) % 4`).
const NEIGHBOURS: [(isize, isize); 8] = [(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1)];

/// The m-adjacent neighbours of a kept edgel (module doc, "Linking"), as
/// directions into [`NEIGHBOURS`], in its order.
#[derive(Clone, Copy, Debug)]
struct MNeighbours {
    /// How many (at most four).
    count: u8,
    /// The first `count` are the directions.
    directions: [u8; 4],
}

/// [`MNeighbours`] by the mask of an edgel's kept 8-neighbours (bit `d` for
/// `NEIGHBOURS[d]`): every side neighbour, and a diagonal one when neither
/// side neighbour it shares with the edgel is kept. There are never more
/// than four (a kept side neighbour rules out the two diagonals beside it),
/// which the table's construction checks when it is compiled.
const M_ADJACENCY: [MNeighbours; 256] = {
    let mut table = [MNeighbours { count: 0, directions: [0; 4] }; 256];
    let mut mask = 0;
    while mask < 256 {
        let mut d = 0;
        while d < 8 {
            let kept = mask >> d & 1 != 0;
            let sides_free = d < 4 || (mask >> (d - 4) & 1 == 0 && mask >> ((d - 3) % 4) & 1 == 0);
            if kept && sides_free {
                table[mask].directions[table[mask].count as usize] = d as u8;
                table[mask].count += 1;
            }
            d += 1;
        }
        mask += 1;
    }
    table
};

/// Links zero crossings into chains and cuts them into [`ImageSegment`]s
/// (module doc), reusing its buffers from frame to frame: a frame
/// allocates nothing unless it has more zero crossings, edgels, chains or
/// segments, or a wider spread of edgels, than any before.
#[derive(Clone, Debug)]
pub struct SegmentExtractor {
    params: SegmentParams,
    /// One bit per cell (pixel) of the candidates' bounding box, padded by
    /// one empty pixel on each side, in rows of `stride` cells, and a spare
    /// word at the end: whether an edgel lies there.
    occupied: Vec<u64>,
    /// Cells per row of `occupied` and `grid`, a multiple of 64.
    stride: usize,
    /// Edgel number of each occupied cell (the others hold stale numbers
    /// and are not read).
    grid: Vec<u32>,
    /// Offset in `grid` of each of the [`NEIGHBOURS`] of a cell.
    offsets: [isize; 8],
    /// The features of the list that pass the candidates' test, at its
    /// start (only grows: its tail is scratch).
    passed: Vec<Feature>,
    /// The candidate edgels (magnitude ≥ low), in list order.
    edgels: Vec<Feature>,
    /// `grid` cell of each edgel.
    cells: Vec<usize>,
    /// [`KEPT`] and [`VISITED`] bits of each edgel.
    flags: Vec<u8>,
    /// Number of m-adjacent candidates of each edgel.
    degree: Vec<u8>,
    /// The m-adjacent candidates of each edgel, the first `degree` entries
    /// (only grows: entries past `degree` are scratch).
    adjacent: Vec<[u32; 4]>,
    /// Work stack of the hysteresis flood fill.
    stack: Vec<u32>,
    /// Edgel numbers of all chains, chain after chain.
    chain_pixels: Vec<u32>,
    /// The chains of the last call.
    chains: Vec<Chain>,
    /// A trace away from a chain's starting pixel.
    forward: Vec<u32>,
    /// The trace the other way.
    backward: Vec<u32>,
    /// One chain's pixel positions, in subdivision order.
    points: Vec<[f64; 2]>,
    /// One chain's edgel numbers, parallel to `points`.
    point_edgels: Vec<u32>,
    /// Work stack of the subdivision.
    tasks: Vec<Task>,
    /// Significances of finished pieces' representations.
    significances: Vec<f64>,
    /// Pieces `(i, j)` of `points` chosen by the subdivision.
    pieces: Vec<(usize, usize)>,
}

/// A step of the subdivision's explicit stack (no recursion, so a chain
/// of any length cannot overflow the call stack).
#[derive(Clone, Copy, Debug)]
enum Task {
    /// Represent piece `i ..= j`.
    Split { i: usize, j: usize },
    /// Both halves of piece `i ..= j` are represented: keep them, or the
    /// piece itself (`significance`), whose segment would go at `pieces[first]`.
    Choose { i: usize, j: usize, significance: f64, first: usize },
}

impl SegmentExtractor {
    /// An extractor with `params` (checked by [`SegmentParams::validate`]).
    pub fn new(params: SegmentParams) -> Result<Self> {
        params.validate()?;
        Ok(Self {
            params,
            occupied: Vec::new(),
            stride: 0,
            grid: Vec::new(),
            offsets: [0; 8],
            passed: Vec::new(),
            edgels: Vec::new(),
            cells: Vec::new(),
            flags: Vec::new(),
            degree: Vec::new(),
            adjacent: Vec::new(),
            stack: Vec::new(),
            chain_pixels: Vec::new(),
            chains: Vec::new(),
            forward: Vec::new(),
            backward: Vec::new(),
            points: Vec::new(),
            point_edgels: Vec::new(),
            tasks: Vec::new(),
            significances: Vec::new(),
            pieces: Vec::new(),
        })
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &SegmentParams {
        &self.params
    }

    /// The segments of the zero crossings `crossings` of `window` into
    /// `segments` (cleared first): [`link`](Self::link), then the
    /// subdivision of every chain (module doc), chain by chain.
    pub fn extract(&mut self, crossings: &[Feature], window: Window, segments: &mut Vec<ImageSegment>) {
        self.link(crossings, window);
        segments.clear();
        for c in 0..self.chains.len() {
            self.subdivide_chain(c, segments);
        }
    }

    /// Link the zero crossings `crossings` of `window` into chains with
    /// hysteresis (module doc); read them with [`chain_count`](Self::chain_count)
    /// and [`chain`](Self::chain).
    pub fn link(&mut self, crossings: &[Feature], window: Window) {
        self.collect_candidates(crossings, window);
        self.find_neighbours();
        self.hysteresis();
        self.trace_chains();
    }

    /// Number of chains of the last [`link`](Self::link) or
    /// [`extract`](Self::extract).
    #[must_use]
    pub fn chain_count(&self) -> usize {
        self.chains.len()
    }

    /// The edgels of chain `c` in chain order; a junction edgel ends every
    /// chain that reaches it. Panics unless `c < chain_count()`.
    pub fn chain(&self, c: usize) -> impl ExactSizeIterator<Item = Feature> + '_ {
        let chain = self.chains[c];
        self.chain_pixels[chain.first..chain.end].iter().map(|&e| self.edgels[e as usize])
    }

    /// Whether chain `c` is closed (a loop with no end and no junction).
    /// Panics unless `c < chain_count()`.
    #[must_use]
    pub fn chain_is_closed(&self, c: usize) -> bool {
        self.chains[c].closed
    }

    /// Fill `edgels` with the features of `window` at least `low_threshold`
    /// strong, the first at each pixel, and mark them in `occupied` and `grid`.
    fn collect_candidates(&mut self, crossings: &[Feature], window: Window) {
        self.edgels.clear();
        self.cells.clear();
        self.flags.clear();
        self.degree.clear();
        // About half of a frame's crossings pass, unpredictably: every
        // feature is written to `passed`, and counted when it passes.
        if self.passed.len() < crossings.len() {
            self.passed.resize(crossings.len(), Feature::default());
        }
        let low = self.params.low_threshold;
        let mut count = 0;
        for f in crossings {
            self.passed[count] = *f;
            let inside = (f.x >= window.x0) & (f.x < window.x1) & (f.y >= window.y0) & (f.y < window.y1);
            count += usize::from(inside & (f.magnitude >= low));
        }
        let passed = &self.passed[..count];
        // The grid spans the candidates' bounding box (at most the window).
        let [x0, y0, x1, y1] = bounding_box(passed);
        if x0 > x1 {
            return;
        }
        self.stride = ((x1 - x0) as usize + 2) / 64 * 64 + 64;
        let cells = self.stride * ((y1 - y0) as usize + 3);
        self.occupied.clear();
        self.occupied.resize(cells / 64 + 1, 0);
        if self.grid.len() < cells {
            self.grid.resize(cells, 0);
        }
        self.offsets = NEIGHBOURS.map(|(dx, dy)| dy * self.stride as isize + dx);
        // Keep the first candidate at each pixel, in list order.
        for f in passed {
            let cell = (f.y - y0 + 1) as usize * self.stride + (f.x - x0 + 1) as usize;
            let (word, bit) = (cell / 64, 1 << (cell % 64));
            if self.occupied[word] & bit != 0 {
                continue;
            }
            self.occupied[word] |= bit;
            self.grid[cell] = self.edgels.len() as u32;
            self.edgels.push(*f);
            self.cells.push(cell);
        }
        let n = self.edgels.len();
        self.flags.resize(n, 0);
        self.degree.resize(n, 0);
        if self.adjacent.len() < n {
            self.adjacent.resize(n, [0; 4]);
        }
    }

    /// Occupancy of the cells `cell - 1`, `cell`, `cell + 1` as bits 0, 1, 2.
    fn occupied_three(&self, cell: usize) -> u32 {
        let (word, bit) = ((cell - 1) / 64, (cell - 1) % 64);
        let pair = u128::from(self.occupied[word]) | u128::from(self.occupied[word + 1]) << 64;
        (pair >> bit) as u32 & 7
    }

    /// The m-adjacent candidates of every candidate edgel, from the
    /// occupancy of the 3×3 cells around it.
    fn find_neighbours(&mut self) {
        for e in 0..self.edgels.len() {
            // The one-pixel border is empty, so every neighbour of a candidate is a cell.
            let cell = self.cells[e];
            // Bits 0, 1, 2 of each: west, centre, east.
            let north = self.occupied_three(cell - self.stride);
            let middle = self.occupied_three(cell);
            let south = self.occupied_three(cell + self.stride);
            // Bit `d` for `NEIGHBOURS[d]`.
            let mask = (middle >> 2)
                | (south >> 1 & 1) << 1
                | (middle & 1) << 2
                | (north >> 1 & 1) << 3
                | (south >> 2) << 4
                | (south & 1) << 5
                | (north & 1) << 6
                | (north >> 2) << 7;
            let m = M_ADJACENCY[mask as usize];
            self.degree[e] = m.count;
            for (slot, &d) in self.adjacent[e].iter_mut().zip(&m.directions[..usize::from(m.count)]) {
                *slot = self.grid[cell.wrapping_add_signed(self.offsets[usize::from(d)])];
            }
        }
    }

    /// Canny's hysteresis: flood from every edgel at least `high_threshold`
    /// strong through connected candidates, marking them [`KEPT`].
    /// m-adjacency connects the same candidates as 8-adjacency (a diagonal
    /// pair that is not m-adjacent shares a side neighbour that is
    /// m-adjacent to both), so the flood follows `adjacent`; and as every
    /// candidate m-adjacent to a kept edgel is kept, `adjacent` of a kept
    /// edgel lists kept edgels only.
    fn hysteresis(&mut self) {
        let high = self.params.high_threshold;
        // Every edgel is pushed at most once; a push writes the top slot
        // and only counts when the edgel was not kept yet.
        self.stack.clear();
        self.stack.resize(self.edgels.len() + 1, 0);
        for seed in 0..self.edgels.len() {
            if self.flags[seed] & KEPT != 0 || !(self.edgels[seed].magnitude >= high) {
                continue;
            }
            self.flags[seed] |= KEPT;
            self.stack[0] = seed as u32;
            let mut top = 1;
            while top > 0 {
                top -= 1;
                let e = self.stack[top] as usize;
                let adjacent = self.adjacent[e];
                for &n in &adjacent[..usize::from(self.degree[e])] {
                    let fresh = self.flags[n as usize] & KEPT == 0;
                    self.flags[n as usize] |= KEPT;
                    self.stack[top] = n;
                    top += usize::from(fresh);
                }
            }
        }
    }

    /// The m-adjacent candidates of edgel `e` (kept edgels when it is kept).
    fn m_neighbours(&self, e: usize) -> &[u32] {
        &self.adjacent[e][..usize::from(self.degree[e])]
    }

    /// Trace every chain (module doc, "Linking"), starting from each kept,
    /// untraced edgel that is no junction, in list order.
    fn trace_chains(&mut self) {
        self.chain_pixels.clear();
        self.chains.clear();
        for start in 0..self.edgels.len() {
            let degree = self.degree[start];
            if self.flags[start] != KEPT || degree >= 3 || degree == 0 {
                continue;
            }
            self.flags[start] |= VISITED;
            let [one, other, ..] = self.adjacent[start];
            let mut forward = std::mem::take(&mut self.forward);
            let mut backward = std::mem::take(&mut self.backward);
            forward.clear();
            backward.clear();
            let closed = self.walk(start, one, &mut forward);
            if !closed && degree == 2 {
                self.walk(start, other, &mut backward);
            }
            let first = self.chain_pixels.len();
            self.chain_pixels.extend(backward.iter().rev());
            self.chain_pixels.push(start as u32);
            self.chain_pixels.extend(&forward);
            self.chains.push(Chain { first, end: self.chain_pixels.len(), closed });
            self.forward = forward;
            self.backward = backward;
        }
    }

    /// Follow the chain from `start` through its neighbour `next`, appending
    /// the edgels met to `out` until an end, a junction (appended, not
    /// marked traced) or `start` again; true in the last case (a loop).
    fn walk(&mut self, start: usize, mut next: u32, out: &mut Vec<u32>) -> bool {
        let mut prev = start as u32;
        loop {
            let e = next as usize;
            if e == start {
                return true;
            }
            if self.degree[e] >= 3 {
                out.push(next);
                return false;
            }
            if self.flags[e] & VISITED != 0 {
                return false;
            }
            self.flags[e] |= VISITED;
            out.push(next);
            match self.m_neighbours(e).iter().find(|&&q| q != prev) {
                Some(&q) => {
                    prev = next;
                    next = q;
                }
                None => return false,
            }
        }
    }

    /// Cut chain `c` into segments (module doc, "Recursive subdivision")
    /// and append those at least `min_length` long to `segments`.
    fn subdivide_chain(&mut self, c: usize, segments: &mut Vec<ImageSegment>) {
        let chain = self.chains[c];
        let pixels = &self.chain_pixels[chain.first..chain.end];
        if pixels.len() < 2 || !could_reach(self.extent(pixels), self.params.min_length) {
            return;
        }
        self.points.clear();
        self.point_edgels.clear();
        let position = |e: u32| {
            let f = &self.edgels[e as usize];
            [f64::from(f.x), f64::from(f.y)]
        };
        self.pieces.clear();
        if chain.closed {
            // Cut at A, farthest from the first pixel, and at B, farthest from A.
            let a = farthest(pixels.iter().map(|&e| position(e)), position(pixels[0]));
            let a_at = position(pixels[a]);
            let rotated = pixels[a..].iter().chain(&pixels[..=a]);
            self.point_edgels.extend(rotated);
            self.points.extend(self.point_edgels.iter().map(|&e| position(e)));
            let last = self.points.len() - 1;
            let b = farthest(self.points[..last].iter().copied(), a_at);
            self.subdivide(0, b);
            self.subdivide(b, last);
        } else {
            self.point_edgels.extend(pixels);
            self.points.extend(pixels.iter().map(|&e| position(e)));
            self.subdivide(0, self.points.len() - 1);
        }
        for &(i, j) in &self.pieces {
            let edgels = self.point_edgels[i..=j].iter().map(|&e| &self.edgels[e as usize]);
            segments.extend(fit_segment(&self.points[i..=j], edgels, self.params.min_length));
        }
    }

    /// The sides of the bounding box of `pixels` (edgel numbers, at least
    /// one), px: no two of them lie farther apart than its diagonal.
    fn extent(&self, pixels: &[u32]) -> [f64; 2] {
        let [x0, y0, x1, y1] = bounding_box(pixels.iter().map(|&e| &self.edgels[e as usize]));
        [f64::from(x1 - x0), f64::from(y1 - y0)]
    }

    /// Append to `pieces` the representation of `points[i ..= j]` (module
    /// doc, "Recursive subdivision"), depth first, with an explicit stack.
    fn subdivide(&mut self, i: usize, j: usize) {
        let floor = self.params.deviation_floor;
        self.tasks.clear();
        self.significances.clear();
        self.tasks.push(Task::Split { i, j });
        while let Some(task) = self.tasks.pop() {
            match task {
                Task::Split { i, j } => {
                    let (deviation, k, chord) = largest_deviation(&self.points[i..=j]);
                    let significance = chord / deviation.max(floor);
                    if j - i < 2 || deviation <= floor {
                        self.pieces.push((i, j));
                        self.significances.push(significance);
                    } else {
                        let k = i + k;
                        self.tasks.push(Task::Choose { i, j, significance, first: self.pieces.len() });
                        self.tasks.push(Task::Split { i: k, j });
                        self.tasks.push(Task::Split { i, j: k });
                    }
                }
                Task::Choose { i, j, significance, first } => {
                    let right = self.significances.pop().unwrap_or(0.0);
                    let left = self.significances.pop().unwrap_or(0.0);
                    let pieces_best = left.max(right);
                    if pieces_best > significance {
                        self.significances.push(pieces_best);
                    } else {
                        self.pieces.truncate(first);
                        self.pieces.push((i, j));
                        self.significances.push(significance);
                    }
                }
            }
        }
    }
}

/// Index of the first of `points` farthest from `from`.
fn farthest(points: impl Iterator<Item = [f64; 2]>, from: [f64; 2]) -> usize {
    let mut best = (0, -1.0);
    for (i, p) in points.enumerate() {
        let d = (p[0] - from[0]).powi(2) + (p[1] - from[1]).powi(2);
        if d > best.1 {
            best = (i, d);
        }
    }
    best.0
}

/// The largest distance of `points` from the chord through the first and
/// the last (from the first when they coincide), the index of the first
/// point at that distance, and the chord's length.
fn largest_deviation(points: &[[f64; 2]]) -> (f64, usize, f64) {
    let (a, b) = (points[0], points[points.len() - 1]);
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let chord = dx.hypot(dy);
    let mut best = (0.0, 0);
    for (k, p) in points.iter().enumerate() {
        let (px, py) = (p[0] - a[0], p[1] - a[1]);
        let d = if chord > 0.0 { (px * dy - py * dx).abs() / chord } else { px.hypot(py) };
        if d > best.0 {
            best = (d, k);
        }
    }
    (best.0, best.1, chord)
}

/// `[x0, y0, x1, y1]`, the smallest and largest pixel coordinates of
/// `features` (x0 > x1 when there are none).
fn bounding_box<'a>(features: impl IntoIterator<Item = &'a Feature>) -> [u32; 4] {
    let mut b = [u32::MAX, u32::MAX, 0, 0];
    for f in features {
        b = [b[0].min(f.x), b[1].min(f.y), b[2].max(f.x), b[3].max(f.y)];
    }
    b
}

/// Whether points at most `|apart|` apart (a vector, px) can give a segment
/// `min_length` long. A segment's length is the distance of its piece's
/// first and last points measured along its axis, so at most their distance
/// (times the axis vector's length, 1 within rounding, which the margin
/// covers): when this is false the segment would be dropped, and neither
/// the subdivision nor the fit needs to run.
fn could_reach(apart: [f64; 2], min_length: f64) -> bool {
    let reach = min_length * (1.0 - 1e-9);
    apart[0] * apart[0] + apart[1] * apart[1] >= reach * reach
}

/// The segment of a piece: the total least squares line through `points`
/// (principal axis of their scatter), its ends the projections of the first
/// and last points; strength and direction the means over `edgels`. None
/// when it is shorter than `min_length` (its edgels are then not read).
fn fit_segment<'a>(
    points: &[[f64; 2]],
    edgels: impl Iterator<Item = &'a Feature>,
    min_length: f64,
) -> Option<ImageSegment> {
    let (first, last) = (points[0], points[points.len() - 1]);
    if !could_reach([last[0] - first[0], last[1] - first[1]], min_length) {
        return None;
    }
    let n = points.len() as f64;
    let (sx, sy) = points.iter().fold((0.0, 0.0), |(sx, sy), p| (sx + p[0], sy + p[1]));
    let c = [sx / n, sy / n];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    // The principal axis of the 2×2 scatter matrix is at angle ½·atan2(2 Sxy, Sxx − Syy).
    let axis = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let d = [axis.cos(), axis.sin()];
    let along = |p: [f64; 2]| (p[0] - c[0]) * d[0] + (p[1] - c[1]) * d[1];
    let (t0, t1) = (along(points[0]), along(points[points.len() - 1]));
    let start = [c[0] + t0 * d[0], c[1] + t0 * d[1]];
    let end = [c[0] + t1 * d[0], c[1] + t1 * d[1]];
    let length = (t1 - t0).abs();
    if !(length >= min_length) {
        return None;
    }
    let (mut strength, mut cos, mut sin) = (0.0, 0.0, 0.0);
    for f in edgels {
        strength += f64::from(f.magnitude);
        cos += f64::from(f.theta).cos();
        sin += f64::from(f.theta).sin();
    }
    Some(ImageSegment {
        start,
        end,
        midpoint: [0.5 * (start[0] + end[0]), 0.5 * (start[1] + end[1])],
        length,
        orientation: undirected(end[1] - start[1], end[0] - start[0]),
        strength: strength / n,
        direction: sin.atan2(cos),
        pixels: points.len() as u32,
    })
}

/// `atan2(dy, dx)` folded into `[0, π)`.
fn undirected(dy: f64, dx: f64) -> f64 {
    wrap_orientation(dy.atan2(dx))
}

/// The segments of a frame indexed by midpoint and orientation (module doc,
/// "Index"). Built once per frame with [`build`](Self::build); its buffers
/// are reused from frame to frame.
#[derive(Clone, Debug)]
pub struct SegmentIndex {
    /// Requested cell side, px.
    cell_size: f64,
    /// Orientation bins over `[0, π)`.
    bins: usize,
    /// Position of cell `(0, 0)`'s top-left corner.
    origin: [f64; 2],
    /// Cell width and height actually used (grown past `cell_size` only
    /// when the window needs more than [`MAX_CELLS_PER_AXIS`] cells).
    cell: [f64; 2],
    /// Cells along x and y.
    cells: [usize; 2],
    /// Per array entry `((cy·nx + cx)·bins + bin)`, where its segments start
    /// in `entries`; one more at the end.
    offsets: Vec<u32>,
    /// Segment numbers, grouped by array entry.
    entries: Vec<u32>,
    /// Next free place of each array entry while building.
    cursor: Vec<u32>,
    /// Midpoint x, y and orientation of every segment, for the exact test.
    keys: Vec<[f64; 3]>,
}

impl Default for SegmentIndex {
    /// An empty index with [`DEFAULT_CELL_SIZE`] and [`DEFAULT_ORIENTATION_BINS`].
    fn default() -> Self {
        Self::with_params(&SegmentParams::default())
    }
}

impl SegmentIndex {
    /// An empty index with `params`' cell size and orientation bins
    /// (values out of their ranges are clamped into them; check
    /// [`SegmentParams::validate`] first to refuse them instead).
    #[must_use]
    pub fn with_params(params: &SegmentParams) -> Self {
        let cell_size = if params.cell_size.is_nan() { DEFAULT_CELL_SIZE } else { params.cell_size };
        Self {
            cell_size: cell_size.clamp(1.0, MAX_LENGTH_PX),
            bins: params.orientation_bins.clamp(1, MAX_ORIENTATION_BINS),
            origin: [0.0, 0.0],
            cell: [1.0, 1.0],
            cells: [1, 1],
            offsets: vec![0; 2],
            entries: Vec::new(),
            cursor: Vec::new(),
            keys: Vec::new(),
        }
    }

    /// Number of segments indexed.
    #[must_use]
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// True when no segment is indexed.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Index `segments` (numbered by their position in the slice) over
    /// `window`, replacing what was indexed. A midpoint outside the window
    /// goes to the nearest border cell, so every segment can be found.
    pub fn build(&mut self, segments: &[ImageSegment], window: Window) {
        self.origin = [f64::from(window.x0), f64::from(window.y0)];
        let extent = [f64::from(window.width()).max(1.0), f64::from(window.height()).max(1.0)];
        for axis in 0..2 {
            let cell = self.cell_size.max(extent[axis] / MAX_CELLS_PER_AXIS as f64);
            self.cell[axis] = cell;
            self.cells[axis] = ((extent[axis] / cell).ceil() as usize).clamp(1, MAX_CELLS_PER_AXIS);
        }
        let entries = self.cells[0] * self.cells[1] * self.bins;
        self.offsets.clear();
        self.offsets.resize(entries + 1, 0);
        self.keys.clear();
        self.keys.extend(segments.iter().map(|s| [s.midpoint[0], s.midpoint[1], s.orientation]));
        // Counting sort: sizes, then starts, then entries in segment order.
        for key in &self.keys {
            let e = self.entry_of(key);
            self.offsets[e + 1] += 1;
        }
        for e in 0..entries {
            self.offsets[e + 1] += self.offsets[e];
        }
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.offsets[..entries]);
        self.entries.clear();
        self.entries.resize(self.keys.len(), 0);
        for (s, key) in self.keys.iter().enumerate() {
            let e = self.entry_of(key);
            self.entries[self.cursor[e] as usize] = s as u32;
            self.cursor[e] += 1;
        }
    }

    /// The cell of `v` along `axis`, clamped to the grid (NaN → 0).
    fn cell_of(&self, v: f64, axis: usize) -> usize {
        ((v - self.origin[axis]) / self.cell[axis]).floor().clamp(0.0, (self.cells[axis] - 1) as f64) as usize
    }

    /// The orientation bin of `o` ∈ `[0, π)`, clamped (NaN → 0).
    fn bin_of(&self, o: f64) -> usize {
        (o / (PI / self.bins as f64)).floor().clamp(0.0, (self.bins - 1) as f64) as usize
    }

    /// The array entry of a segment's key.
    fn entry_of(&self, key: &[f64; 3]) -> usize {
        (self.cell_of(key[1], 1) * self.cells[0] + self.cell_of(key[0], 0)) * self.bins + self.bin_of(key[2])
    }

    /// The segments whose midpoint lies in `x_range` × `y_range` and whose
    /// orientation differs from `angle` (radians, any real: taken modulo π)
    /// by at most `angle_tolerance` ([`orientation_difference`]), into `out`
    /// (cleared first) in increasing order. Visits only the array entries
    /// that intersect the bounds.
    pub fn query(
        &self,
        x_range: RangeInclusive<f64>,
        y_range: RangeInclusive<f64>,
        angle: f64,
        angle_tolerance: f64,
        out: &mut Vec<usize>,
    ) {
        out.clear();
        let (&x0, &x1, &y0, &y1) = (x_range.start(), x_range.end(), y_range.start(), y_range.end());
        let angle = angle.rem_euclid(PI);
        if self.keys.is_empty() || !(x0 <= x1 && y0 <= y1 && angle_tolerance >= 0.0) || angle.is_nan() {
            return;
        }
        let bins = self.bin_ranges(angle, angle_tolerance);
        let (cx0, cx1) = (self.cell_of(x0, 0), self.cell_of(x1, 0));
        let (cy0, cy1) = (self.cell_of(y0, 1), self.cell_of(y1, 1));
        for cy in cy0..=cy1 {
            for cx in cx0..=cx1 {
                let base = (cy * self.cells[0] + cx) * self.bins;
                for &(b0, b1) in bins.iter().flatten() {
                    let range = self.offsets[base + b0] as usize..self.offsets[base + b1 + 1] as usize;
                    for &s in &self.entries[range] {
                        let [x, y, o] = self.keys[s as usize];
                        let inside = (x0..=x1).contains(&x) && (y0..=y1).contains(&y);
                        if inside && orientation_difference(o, angle) <= angle_tolerance {
                            out.push(s as usize);
                        }
                    }
                }
            }
        }
        out.sort_unstable();
    }

    /// The bins (one or two inclusive ranges) that orientations within
    /// `tolerance` of `angle` ∈ `[0, π)` fall into, widened by a rounding
    /// margin (the exact test decides).
    fn bin_ranges(&self, angle: f64, tolerance: f64) -> [Option<(usize, usize)>; 2] {
        const ROUNDING: f64 = 1e-9;
        let n = self.bins as i64;
        if tolerance + ROUNDING >= PI / 2.0 {
            return [Some((0, self.bins - 1)), None];
        }
        let width = PI / self.bins as f64;
        let lo = ((angle - tolerance - ROUNDING) / width).floor() as i64;
        let hi = ((angle + tolerance + ROUNDING) / width).floor() as i64;
        if hi - lo + 1 >= n {
            return [Some((0, self.bins - 1)), None];
        }
        let first = lo.rem_euclid(n);
        let last = first + (hi - lo);
        if last < n {
            [Some((first as usize, last as usize)), None]
        } else {
            [Some((first as usize, self.bins - 1)), Some((0, (last - n) as usize))]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::{CpuBackend, EarlyVision, FrameRequest, ListSpec, ZeroCrossingRequest};
    use crate::early::log::LogParams;
    use crate::early::zero_crossing::ZeroCrossingParams;
    use crate::image::GrayImage;
    use crate::synth::{Canvas, DEFAULT_SUPERSAMPLE, FillRule, add_noise_and_quantise};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The zero crossings of `frame` inside `window`, from the CPU backend.
    fn crossings(frame: &GrayImage, window: Window) -> Vec<Feature> {
        let (w, h) = frame.size();
        let request = FrameRequest {
            zero_crossings: Some(ZeroCrossingRequest {
                log: LogParams::default(),
                crossings: ZeroCrossingParams::default(),
                list: ListSpec { window, ..ListSpec::full(w, h) },
            }),
            ..FrameRequest::default()
        };
        let mut backend = CpuBackend::new();
        backend.process(frame, &request).unwrap().zero_crossings.unwrap()
    }

    /// A `w`×`h` frame of grey `background` with `draw` applied, Gaussian
    /// noise of σ = `noise` added and rounded to 8 bits.
    fn render(w: usize, h: usize, background: f32, noise: f32, draw: impl FnOnce(&mut Canvas)) -> GrayImage {
        let mut canvas = Canvas::new(w, h, DEFAULT_SUPERSAMPLE, background).unwrap();
        draw(&mut canvas);
        let mut frame = GrayImage::new(w, h);
        add_noise_and_quantise(&canvas.downsample(), noise, &mut ChaCha8Rng::seed_from_u64(3), &mut frame);
        frame
    }

    fn segments_of(frame: &GrayImage, window: Window, params: SegmentParams) -> Vec<ImageSegment> {
        let mut extractor = SegmentExtractor::new(params).unwrap();
        let mut segments = Vec::new();
        extractor.extract(&crossings(frame, window), window, &mut segments);
        segments
    }

    /// Signed distance of `p` from the line through `a` and `b`, and the
    /// position of its foot along `a → b` as a fraction of `|b − a|`.
    fn from_line(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> (f64, f64) {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let (px, py) = (p[0] - a[0], p[1] - a[1]);
        ((px * dy - py * dx) / len2.sqrt(), (px * dx + py * dy) / len2)
    }

    /// Literal edgels at `pixels`, all of strength `magnitude`, direction 0.
    fn edgels(pixels: &[(u32, u32)], magnitude: f32) -> Vec<Feature> {
        let mut list: Vec<Feature> = pixels.iter().map(|&(x, y)| Feature { x, y, theta: 0.0, magnitude }).collect();
        list.sort_by_key(|f| (f.y, f.x));
        list
    }

    /// Euclidean distance.
    fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
        (b[0] - a[0]).hypot(b[1] - a[1])
    }

    fn window(x0: u32, y0: u32, x1: u32, y1: u32) -> Window {
        Window { x0, y0, x1, y1 }
    }

    fn chains(extractor: &SegmentExtractor) -> Vec<Vec<(u32, u32)>> {
        (0..extractor.chain_count()).map(|c| extractor.chain(c).map(|f| (f.x, f.y)).collect()).collect()
    }

    /// A bright rotated rectangle and a dark triangle over noise σ = 2,
    /// through the CPU backend's zero crossings in a window: each side is
    /// one segment, its midpoint within 0.5 px of the true side and its ends
    /// within 1 px of its line, its direction pointing from the bright
    /// side to the dark side; nothing else is found.
    #[test]
    fn polygon_sides_are_single_segments() {
        let rotate = |c: [f64; 2], half: [f64; 2], angle: f64| {
            let (s, co) = angle.sin_cos();
            [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]].map(|[u, v]: [f64; 2]| {
                [c[0] + co * u * half[0] - s * v * half[1], c[1] + s * u * half[0] + co * v * half[1]]
            })
        };
        let rectangle = rotate([70.3, 88.6], [42.0, 27.0], 8f64.to_radians());
        let triangle = [[152.4, 38.7], [226.1, 71.3], [163.8, 151.2]];
        let frame = render(240, 180, 70.0, 2.0, |c| {
            c.fill_polygon(&rectangle, FillRule::EvenOdd, 170.0);
            c.fill_polygon(&triangle, FillRule::EvenOdd, 20.0);
        });
        let win = window(3, 5, 237, 176);
        let segments = segments_of(&frame, win, SegmentParams::default());
        let centre = |p: &[[f64; 2]]| {
            let n = p.len() as f64;
            [p.iter().map(|v| v[0]).sum::<f64>() / n, p.iter().map(|v| v[1]).sum::<f64>() / n]
        };
        /// A side's two corners, its polygon's centre, and whether the inside is the bright side.
        type Side = ([f64; 2], [f64; 2], [f64; 2], bool);
        let sides: Vec<Side> = (0..4)
            .map(|i| (rectangle[i], rectangle[(i + 1) % 4], centre(&rectangle), true))
            .chain((0..3).map(|i| (triangle[i], triangle[(i + 1) % 3], centre(&triangle), false)))
            .collect();
        for (a, b, inside, bright_inside) in &sides {
            let side_length = distance(*a, *b);
            let on_side: Vec<&ImageSegment> = segments
                .iter()
                .filter(|s| {
                    let (d, t) = from_line(s.midpoint, *a, *b);
                    d.abs() < 3.0 && (0.0..=1.0).contains(&t)
                })
                .collect();
            assert_eq!(on_side.len(), 1, "side {a:?} → {b:?}: {on_side:?}");
            let s = on_side[0];
            let (mid, _) = from_line(s.midpoint, *a, *b);
            let (d0, t0) = from_line(s.start, *a, *b);
            let (d1, t1) = from_line(s.end, *a, *b);
            let (near, far) = (t0.min(t1) * side_length, (1.0 - t0.max(t1)) * side_length);
            assert!(mid.abs() <= 0.5, "side {a:?} → {b:?}: midpoint {mid} px off");
            assert!(d0.abs() <= 1.0 && d1.abs() <= 1.0, "side {a:?} → {b:?}: ends {d0}, {d1} px off");
            // The LoG rounds corners: the ends stop short of (or pass) the corners by up to 1.3 px here.
            assert!(
                near.abs() <= 2.0 && far.abs() <= 2.0,
                "side {a:?} → {b:?}: ends {near}, {far} px from the corners"
            );
            let outwards =
                (s.midpoint[0] - inside[0]) * s.direction.cos() + (s.midpoint[1] - inside[1]) * s.direction.sin();
            assert_eq!(outwards > 0.0, *bright_inside, "side {a:?} → {b:?}: direction {}", s.direction);
        }
        assert_eq!(segments.len(), sides.len(), "{segments:?}");
    }

    /// A disc has no straight sides: its zero-crossing loop is cut into
    /// several short chords, each close to the circle.
    #[test]
    fn circle_is_cut_into_several_short_segments() {
        let (centre, radius) = ([60.3, 55.7], 30.0);
        let frame = render(120, 110, 70.0, 0.0, |c| c.fill_ellipse(centre, [radius, radius], 0.0, 170.0));
        let win = Window::full(120, 110);
        let segments = segments_of(&frame, win, SegmentParams::default());
        assert!(segments.len() >= 6, "{} segments", segments.len());
        let total: f64 = segments.iter().map(|s| s.length).sum();
        assert!(total > 0.9 * 2.0 * PI * radius, "segments cover {total} px of the circle");
        for s in &segments {
            assert!(s.length < radius, "{s:?}");
            for p in [s.start, s.end, s.midpoint] {
                assert!((distance(p, centre) - radius).abs() < 2.0, "{s:?}");
            }
        }
    }

    /// A T: the junction pixel (10, 10) has three neighbours; the three
    /// chains each end on it.
    #[test]
    fn junction_splits_chains_and_each_branch_ends_on_it() {
        let mut pixels: Vec<(u32, u32)> = (0..=20).map(|x| (x, 10)).collect();
        pixels.extend((11..=20).map(|y| (10, y)));
        let mut extractor =
            SegmentExtractor::new(SegmentParams { min_length: 5.0, ..SegmentParams::default() }).unwrap();
        let list = edgels(&pixels, 10.0);
        extractor.link(&list, window(0, 0, 30, 30));
        let found = chains(&extractor);
        let left: Vec<(u32, u32)> = (0..=10).map(|x| (x, 10)).collect();
        let right: Vec<(u32, u32)> = (10..=20).map(|x| (x, 10)).collect();
        let down: Vec<(u32, u32)> = (10..=20).map(|y| (10, y)).collect();
        assert_eq!(found, vec![left, right, down]);
        assert!((0..3).all(|c| !extractor.chain_is_closed(c)));
        let mut segments = Vec::new();
        extractor.extract(&list, window(0, 0, 30, 30), &mut segments);
        assert_eq!(segments.len(), 3);
        for s in &segments {
            assert!((s.length - 10.0).abs() < 1e-9, "{s:?}");
            let touches = [s.start, s.end].iter().any(|p| distance(*p, [10.0, 10.0]) < 1e-9);
            assert!(touches, "{s:?}");
        }
        let orientations: Vec<f64> = segments.iter().map(|s| s.orientation).collect();
        assert_eq!(orientations, vec![0.0, 0.0, PI / 2.0]);
    }

    /// Horizontal and vertical crossings of a diagonal edge fall on
    /// different pixels: a 4-connected staircase, one chain under
    /// m-adjacency (under 8-adjacency each step would be a junction).
    #[test]
    fn staircase_is_one_chain() {
        let mut pixels = Vec::new();
        for k in 0..15 {
            pixels.extend([(k, k), (k + 1, k)]);
        }
        pixels.push((15, 15));
        let mut extractor = SegmentExtractor::new(SegmentParams::default()).unwrap();
        extractor.link(&edgels(&pixels, 10.0), window(0, 0, 20, 20));
        assert_eq!(chains(&extractor), vec![pixels.clone()]);
        let mut segments = Vec::new();
        extractor.extract(&edgels(&pixels, 10.0), window(0, 0, 20, 20), &mut segments);
        assert_eq!(segments.len(), 1);
        assert!((segments[0].orientation - PI / 4.0).abs() < 1e-9, "{:?}", segments[0]);
    }

    /// The outline of a square is one closed chain, cut at its far corners
    /// and split at the other two: four sides of length 10.
    #[test]
    fn closed_square_gives_its_four_sides() {
        let mut pixels = Vec::new();
        for k in 0..10 {
            pixels.extend([(5 + k, 5), (15, 5 + k), (15 - k, 15), (5, 15 - k)]);
        }
        let list = edgels(&pixels, 10.0);
        let mut extractor = SegmentExtractor::new(SegmentParams::default()).unwrap();
        let mut segments = Vec::new();
        extractor.extract(&list, window(0, 0, 20, 20), &mut segments);
        assert_eq!(extractor.chain_count(), 1);
        assert!(extractor.chain_is_closed(0));
        assert_eq!(extractor.chain(0).len(), 40);
        assert_eq!(segments.len(), 4, "{segments:?}");
        let mut sides: Vec<[i64; 4]> = segments
            .iter()
            .map(|s| {
                let (a, b) = if s.start < s.end { (s.start, s.end) } else { (s.end, s.start) };
                [a[0], a[1], b[0], b[1]].map(|v| v.round() as i64)
            })
            .collect();
        sides.sort_unstable();
        assert_eq!(sides, vec![[5, 5, 5, 15], [5, 5, 15, 5], [5, 15, 15, 15], [15, 5, 15, 15]]);
        assert!(segments.iter().all(|s| (s.length - 10.0).abs() < 1e-9));
    }

    /// Hysteresis on literal edgels (high 2.5, low 1.5): a faint run joined
    /// to a strong one is kept whole, a faint run alone is dropped, and an
    /// edgel below `low` breaks a run.
    #[test]
    fn hysteresis_keeps_faint_edgels_joined_to_strong_ones() {
        let mut list = Vec::new();
        // Row 2: 5 strong then 15 faint edgels.
        list.extend((0..20).map(|x| Feature { x, y: 2, theta: 0.0, magnitude: if x < 5 { 10.0 } else { 2.0 } }));
        // Row 6: 20 faint edgels alone.
        list.extend((0..20).map(|x| Feature { x, y: 6, theta: 0.0, magnitude: 2.0 }));
        // Row 10: strong, with one edgel below `low` at x = 8.
        list.extend((0..20).map(|x| Feature { x, y: 10, theta: 0.0, magnitude: if x == 8 { 1.0 } else { 10.0 } }));
        let mut extractor = SegmentExtractor::new(SegmentParams::default()).unwrap();
        extractor.link(&list, window(0, 0, 20, 12));
        let row = |y: u32, xs: std::ops::Range<u32>| xs.map(|x| (x, y)).collect::<Vec<_>>();
        assert_eq!(chains(&extractor), vec![row(2, 0..20), row(10, 0..8), row(10, 9..20)]);
        // Without hysteresis (low = high) the faint part goes too.
        let strict = SegmentParams { low_threshold: 2.5, ..SegmentParams::default() };
        let mut extractor = SegmentExtractor::new(strict).unwrap();
        extractor.link(&list, window(0, 0, 20, 12));
        assert_eq!(chains(&extractor), vec![row(2, 0..5), row(10, 0..8), row(10, 9..20)]);
    }

    /// Rendered: a horizontal edge whose contrast falls from 80 to 10 grey
    /// levels along its length (its faint end is weaker than `high` but
    /// stronger than `low`) is kept over its whole length; an edge of
    /// contrast 10 on its own, across the whole frame (no corner, where the
    /// two axes' differences add up to more), gives no segment.
    #[test]
    fn hysteresis_on_a_rendered_edge_fading_out() {
        let frame = render(200, 100, 60.0, 0.0, |c| {
            c.shade_with(|x, y| {
                if y < 29.5 && (20.0..180.0).contains(&x) {
                    let fade = ((x - 70.0) / 60.0).clamp(0.0, 1.0) as f32;
                    60.0 + 80.0 - fade * 70.0
                } else if y >= 69.5 {
                    70.0
                } else {
                    60.0
                }
            });
        });
        let win = Window::full(200, 100);
        let params = SegmentParams::default();
        let faint_end: Vec<f32> = crossings(&frame, win)
            .iter()
            .filter(|f| f.x >= 140 && f.x < 170 && (29..=30).contains(&f.y))
            .map(|f| f.magnitude)
            .collect();
        assert_eq!(faint_end.len(), 30);
        assert!(faint_end.iter().all(|&m| m >= params.low_threshold && m < params.high_threshold), "{faint_end:?}");
        let reach = |segments: &[ImageSegment], y: f64| {
            segments
                .iter()
                .filter(|s| (s.midpoint[1] - y).abs() < 1.0 && orientation_difference(s.orientation, 0.0) < 0.05)
                .map(|s| s.start[0].max(s.end[0]))
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let segments = segments_of(&frame, win, params.clone());
        assert!(reach(&segments, 29.0) > 175.0, "the faint end is kept: {segments:?}");
        assert_eq!(reach(&segments, 69.0), f64::NEG_INFINITY, "the faint edge alone is dropped: {segments:?}");
        let strict = segments_of(&frame, win, SegmentParams { low_threshold: params.high_threshold, ..params });
        assert!(reach(&strict, 29.0) < 140.0, "without hysteresis the faint end goes: {strict:?}");
    }

    /// An L of two 20-pixel legs is two segments; a chain bending by one
    /// pixel stays one; a leg shorter than `min_length` is dropped.
    #[test]
    fn subdivision_splits_corners_not_wiggles() {
        let mut extractor = SegmentExtractor::new(SegmentParams::default()).unwrap();
        let mut segments = Vec::new();
        let mut l_shape: Vec<(u32, u32)> = (0..=20).map(|x| (x, 0)).collect();
        l_shape.extend((1..=20).map(|y| (20, y)));
        extractor.extract(&edgels(&l_shape, 10.0), window(0, 0, 25, 25), &mut segments);
        let ends: Vec<[[f64; 2]; 2]> = segments.iter().map(|s| [s.start, s.end]).collect();
        assert_eq!(ends, vec![[[0.0, 0.0], [20.0, 0.0]], [[20.0, 0.0], [20.0, 20.0]]]);
        // Significance: legs 20/2 = 10 each, the whole 28.3/14.1 = 2.
        let bend: Vec<(u32, u32)> = (0..=40).map(|x| (x, if (10..30).contains(&x) { 1 } else { 0 })).collect();
        extractor.extract(&edgels(&bend, 10.0), window(0, 0, 45, 5), &mut segments);
        assert_eq!(segments.len(), 1, "{segments:?}");
        assert_eq!(segments[0].pixels, 41);
        let mut short_leg: Vec<(u32, u32)> = (0..=20).map(|x| (x, 0)).collect();
        short_leg.extend((1..=6).map(|y| (20, y)));
        extractor.extract(&edgels(&short_leg, 10.0), window(0, 0, 25, 25), &mut segments);
        assert_eq!(segments.len(), 1, "{segments:?}");
        assert_eq!(segments[0].length, 20.0);
    }

    /// Buffers reused across frames and windows give what a fresh extractor gives.
    #[test]
    fn reused_extractor_equals_a_fresh_one() {
        let frame_a = render(160, 120, 70.0, 2.0, |c| {
            c.fill_polygon(&[[20.0, 20.0], [140.0, 30.0], [60.0, 100.0]], FillRule::EvenOdd, 170.0)
        });
        let frame_b = render(160, 120, 70.0, 2.0, |c| c.fill_ellipse([80.0, 60.0], [40.0, 25.0], 0.3, 20.0));
        let (wa, wb) = (Window::full(160, 120), window(30, 20, 131, 101));
        let mut extractor = SegmentExtractor::new(SegmentParams::default()).unwrap();
        let mut segments = Vec::new();
        extractor.extract(&crossings(&frame_a, wa), wa, &mut segments);
        assert!(!segments.is_empty());
        extractor.extract(&crossings(&frame_b, wb), wb, &mut segments);
        let fresh = segments_of(&frame_b, wb, SegmentParams::default());
        assert!(!fresh.is_empty());
        assert_eq!(segments, fresh);
        extractor.extract(&crossings(&frame_a, wa), wa, &mut segments);
        assert_eq!(segments, segments_of(&frame_a, wa, SegmentParams::default()));
    }

    /// Chains and pieces too short to give a segment of `min_length` are
    /// skipped before the subdivision and the fit; the segments are exactly
    /// those of `min_length` 0 (where nothing is skipped) that are at least
    /// `min_length` long, on noisy frames full of short chains and at the
    /// lengths of segments found (the bound's edge case).
    #[test]
    fn short_chains_skipped_lose_no_segment() {
        let shapes = |c: &mut Canvas| {
            c.fill_polygon(&[[20.0, 20.0], [140.0, 30.0], [60.0, 100.0]], FillRule::EvenOdd, 170.0);
            c.fill_ellipse([110.0, 80.0], [30.0, 18.0], 0.3, 20.0);
        };
        let mut lengths_checked = 0;
        for noise in [2.0, 8.0, 16.0] {
            let frame = render(160, 120, 90.0, noise, shapes);
            let win = Window::full(160, 120);
            let loose = SegmentParams { low_threshold: 0.5, high_threshold: 1.0, ..SegmentParams::default() };
            let all = segments_of(&frame, win, SegmentParams { min_length: 0.0, ..loose });
            assert!(all.len() > 200, "noise {noise}: {} segments", all.len());
            let mut min_lengths = vec![2.0, 3.5, 8.0, 12.0];
            min_lengths.extend(all.iter().step_by(17).map(|s| s.length));
            for min_length in min_lengths {
                let kept: Vec<_> = all.iter().filter(|s| s.length >= min_length).cloned().collect();
                assert_eq!(
                    segments_of(&frame, win, SegmentParams { min_length, ..loose }),
                    kept,
                    "noise {noise}, min_length {min_length}"
                );
                lengths_checked += 1;
            }
        }
        assert!(lengths_checked > 30);
    }

    /// Defaults: flat frames with the synthetic scenes' noise (σ = 2) give
    /// no segment; a quadrilateral of contrast 15 on that noise is found
    /// along nearly all of its outline.
    #[test]
    fn default_thresholds_reject_noise_and_keep_contrast_fifteen() {
        let noise_only = render(320, 240, 120.0, 2.0, |_| {});
        let win = Window::full(320, 240);
        assert_eq!(segments_of(&noise_only, win, SegmentParams::default()), vec![]);
        let quad = [[40.3, 30.7], [270.2, 45.1], [250.9, 200.4], [35.6, 180.2]];
        let frame = render(320, 240, 100.0, 2.0, |c| c.fill_polygon(&quad, FillRule::EvenOdd, 115.0));
        let segments = segments_of(&frame, win, SegmentParams::default());
        for i in 0..4 {
            let (a, b) = (quad[i], quad[(i + 1) % 4]);
            let covered: f64 = segments
                .iter()
                .filter(|s| from_line(s.midpoint, a, b).0.abs() < 1.5)
                .filter(|s| orientation_difference(s.orientation, undirected(b[1] - a[1], b[0] - a[0])) < 0.1)
                .map(|s| s.length)
                .sum();
            assert!(covered > 0.9 * distance(a, b), "side {i}: {covered} of {} px", distance(a, b));
        }
    }

    /// Random segments, random queries (wrapping orientations, ranges
    /// reaching outside the window, wide and zero tolerances): the index
    /// finds exactly what a filter over every segment finds.
    #[test]
    fn index_query_equals_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let win = window(13, 7, 653, 487);
        let mut segments: Vec<ImageSegment> = (0..600)
            .map(|_| {
                let m = [rng.random_range(5.0..660.0), rng.random_range(0.0..495.0)];
                let o = match rng.random_range(0..10) {
                    0 => 0.0,
                    1 => PI - 1e-12,
                    _ => rng.random_range(0.0..PI),
                };
                ImageSegment {
                    start: m,
                    end: m,
                    midpoint: m,
                    length: 10.0,
                    orientation: o,
                    strength: 5.0,
                    direction: 0.0,
                    pixels: 10,
                }
            })
            .collect();
        // Some midpoints on cell boundaries.
        segments[0].midpoint = [13.0 + 16.0 * 3.0, 7.0 + 16.0 * 5.0];
        segments[1].midpoint = [653.0, 487.0];
        for (bins, cell) in [(12, 16.0), (1, 16.0), (7, 5.5), (180, 100.0)] {
            let params = SegmentParams { orientation_bins: bins, cell_size: cell, ..SegmentParams::default() };
            let mut index = SegmentIndex::with_params(&params);
            index.build(&segments, win);
            assert_eq!(index.len(), segments.len());
            let mut found = Vec::new();
            for q in 0..1500 {
                let (cx, cy) = (rng.random_range(-20.0..700.0), rng.random_range(-20.0..520.0));
                let (rx, ry) = (rng.random_range(0.0..80.0), rng.random_range(0.0..80.0));
                let angle = rng.random_range(-4.0..7.0);
                let tolerance = match q % 5 {
                    0 => 0.0,
                    1 => rng.random_range(1.4..2.0),
                    _ => rng.random_range(0.0..0.5),
                };
                let (xr, yr) = (cx - rx..=cx + rx, cy - ry..=cy + ry);
                index.query(xr.clone(), yr.clone(), angle, tolerance, &mut found);
                let expected: Vec<usize> = (0..segments.len())
                    .filter(|&s| {
                        let [x, y] = segments[s].midpoint;
                        xr.contains(&x)
                            && yr.contains(&y)
                            && orientation_difference(segments[s].orientation, angle) <= tolerance
                    })
                    .collect();
                assert_eq!(found, expected, "bins {bins}, cell {cell}, query {q}");
            }
            // Exact hits: a segment's own midpoint and orientation, zero tolerance.
            for (s, seg) in segments.iter().enumerate() {
                let [x, y] = seg.midpoint;
                index.query(x..=x, y..=y, seg.orientation, 0.0, &mut found);
                assert!(found.contains(&s), "segment {s} not found at its own key");
            }
            // The whole plane and every orientation: everything.
            index.query(f64::NEG_INFINITY..=f64::INFINITY, f64::NEG_INFINITY..=f64::INFINITY, 0.0, PI, &mut found);
            assert_eq!(found, (0..segments.len()).collect::<Vec<_>>());
            index.query(0.0..=700.0, 0.0..=500.0, f64::NAN, 1.0, &mut found);
            assert!(found.is_empty());
        }
    }

    #[test]
    fn params_validate_and_parse() {
        assert!(SegmentParams::default().validate().is_ok());
        let bad = [
            SegmentParams { low_threshold: 0.0, ..SegmentParams::default() },
            SegmentParams { high_threshold: 1.0, ..SegmentParams::default() },
            SegmentParams { high_threshold: MAX_THRESHOLD * 2.0, ..SegmentParams::default() },
            SegmentParams { min_length: f64::NAN, ..SegmentParams::default() },
            SegmentParams { deviation_floor: 0.0, ..SegmentParams::default() },
            SegmentParams { cell_size: 0.5, ..SegmentParams::default() },
            SegmentParams { orientation_bins: 0, ..SegmentParams::default() },
            SegmentParams { orientation_bins: MAX_ORIENTATION_BINS + 1, ..SegmentParams::default() },
        ];
        for p in bad {
            assert!(p.validate().is_err(), "{p:?}");
            assert!(SegmentExtractor::new(p).is_err());
        }
        let parsed: SegmentParams = toml::from_str("high_threshold = 4.0\norientation_bins = 8").unwrap();
        assert_eq!((parsed.high_threshold, parsed.orientation_bins, parsed.low_threshold), (4.0, 8, 1.5));
        assert!(toml::from_str::<SegmentParams>("high = 4.0").is_err(), "unknown keys refused");
    }

    /// Features outside the window, duplicates and NaN strengths are
    /// ignored; an empty window gives nothing.
    #[test]
    fn odd_input_is_ignored() {
        let mut list = edgels(&(0..20).map(|x| (x, 3)).collect::<Vec<_>>(), 10.0);
        list.push(Feature { x: 50, y: 3, theta: 0.0, magnitude: 10.0 });
        list.push(Feature { x: 5, y: 3, theta: 0.0, magnitude: 10.0 });
        list.push(Feature { x: 5, y: 4, theta: 0.0, magnitude: f32::NAN });
        let mut extractor = SegmentExtractor::new(SegmentParams::default()).unwrap();
        let mut segments = Vec::new();
        extractor.extract(&list, window(0, 0, 20, 10), &mut segments);
        assert_eq!(chains(&extractor), vec![(0..20).map(|x| (x, 3)).collect::<Vec<_>>()]);
        assert_eq!(segments.len(), 1);
        extractor.extract(&list, window(4, 4, 4, 9), &mut segments);
        assert_eq!((extractor.chain_count(), segments.len()), (0, 0));
        // A window far larger than the frame costs no more than the edgels' spread.
        let huge = window(0, 0, u32::MAX, u32::MAX);
        extractor.extract(&list, huge, &mut segments);
        assert_eq!(segments.len(), 1);
        let mut index = SegmentIndex::default();
        index.build(&segments, huge);
        let mut found = Vec::new();
        index.query(0.0..=30.0, 0.0..=10.0, 0.0, 0.1, &mut found);
        assert_eq!(found, vec![0]);
    }
}
