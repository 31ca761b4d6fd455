//! The `motion-edge` tracker of paper 000 (Chaconas, Nashman & Lumia,
//! "Model-Based Vision for Space Applications"): the 2-D corners of a planar
//! polygon, tracked by labelling motion pixels to predicted model lines,
//! fitting lines, intersecting them and predicting each corner with double
//! exponential smoothing.
//!
//! # Input
//! Per frame, the motion pixels of the backend: pixels where the thresholded
//! temporal difference of this frame's and the previous frame's smoothed
//! images is set (eq. 1), each with the edge orientation θ ∈ [0, π) of eq. 2
//! (Sobel on the *sum* of the two smoothed frames, θ = atan(gy/gx) + π/2,
//! measured from +x towards +y, y down) and the Sobel magnitude of that sum.
//!
//! # Steps per frame (paper §2, in order)
//! 1. [`model_lines`]: the model lines through the predicted corners (the
//!    paper keeps slope/intercept, end points and direction per line).
//! 2. [`label_motion_pixels`]: a motion pixel is labelled to the line it best
//!    matches (smallest |d|) among the lines with |θ_model − θ_data| < δ
//!    (eq. 3, compared modulo π) and |d| < ζ (eq. 4); otherwise discarded.
//! 3. [`fit_model_lines`]: least squares per line ([`crate::estimate::line_fit`]). A line
//!    with fewer than `min_points_per_line` points (a pendulum's turning
//!    point, an edge moving along itself) is not updated (step 4).
//! 4. [`intersect_corners`]: each corner is the intersection of its two
//!    lines; a corner is *measured* when at least one of them was fitted.
//! 5. [`corner_deviation`]: eq. 9 on measured corners only; a measured corner
//!    ε or more from its prediction loses the track.
//! 6. [`MotionEdgeTracker::update`] feeds each corner to its smoother
//!    (eq. 10–11) and predicts the next frame with eq. 12 (or, by default,
//!    from the outline's measured displacement: "Prediction under
//!    acceleration" and "The outline moves as one" below)
//!    ([`crate::estimate::smoothing`]; form used: x̂_{t+1} = a_t + b_t =
//!    (2 + α/β)·S1_t − (1 + α/β)·S2_t, Brown's double exponential smoothing
//!    of Montgomery et al. \[17\], which matches the legible coefficients of
//!    the garbled eq. 12). Predictions are made every cycle, with or without
//!    data (paper Fig. 2).
//!
//! # The half-frame lag of motion pixels, and its correction
//! The temporal difference of frames t−1 and t is set on the band the edge
//! swept between its two positions (plus blur on both sides, symmetrically),
//! and the orientation from the summed frames is valid at both ends of the
//! band. A line fitted to these pixels therefore lies halfway between the
//! edge at t−1 and at t: it measures the edge at time t − ½, half a frame's
//! motion (v/2 px at v px/frame) behind the edge in the current frame. The
//! paper reports fitted corners as the current ones, so its corners lag by
//! v/2 (0.55 px at its 1.1 px/frame; 8 px at 16 px/frame).
//!
//! This tracker keeps the whole measure–predict loop in that "band time"
//! (measurements are the band centres at t − ½ and
//! the one-step forecast is the centre of the *next* frame's band, t + ½,
//! exactly where the next motion pixels will be, so labelling is unbiased),
//! and moves only the *reported* corners to the current frame:
//! with `lag_correction` (default) a measured corner is reported at
//! m_t + ½·v_t, where v_t is its last measured displacement m_t − m_{t−1}
//! when it was measured in both frames (the smoother's trend lags under
//! acceleration: a·(1−α)/α ≈ 4a px/frame at α = 0.2), twice its offset from
//! the position where it rested when it starts moving again, and the
//! smoother's trend otherwise. Without it, corners are reported at the band
//! centre, as in the paper. Test `lag_correction_removes_the_half_frame_lag`:
//! at 8 px/frame the uncorrected error is ≈ 4.0 px, the corrected ≈ 0.06 px.
//!
//! # Where the paper is silent or its literal form fails (each switchable)
//! - **Line fit** (`line_fit`): eq. 5–8 regress y on x or x on y. On a thick
//!   band (fast motion) a regression on an image axis is biased towards the
//!   axis (errors-in-variables: the band's thickness is error in both
//!   coordinates) — at 16 px/frame by ~2° on a 20° edge, several px at the
//!   corners. The paper's remedy is to regress on the axis the line runs
//!   along; the default fit ([`LineFitMethod::Across`]) does that exactly:
//!   eq. 5–6 in the frame of the predicted model line, the offset across it
//!   regressed on the position along it ([`crate::estimate::line_fit::fit_line_across`]),
//!   so the band's thickness is error in the dependent coordinate only, at
//!   any slope. With the trimmed ends (below) the band is cut perpendicular
//!   to the model line, which makes the slope unbiased however thick the
//!   band. A band more than about 8 px thick (perpendicular standard
//!   deviation above 2.5 px) is fitted as the two edges that bound it, the
//!   edge at t−1 and at t ([`crate::estimate::line_fit::fit_band_across`]: one slope within
//!   the two halves), so the band's width is not noise in the slope. On real
//!   frames at 16 px/frame the 35 px edges keep ~17 px after trimming inside
//!   a ~14 px wide band: the orthogonal fit (`Orthogonal`, the previous
//!   default) then has no principal axis and turned the line by 10° or more,
//!   and the pooled regression by ±5°, which lost the track; the two-edge fit
//!   holds it. `Regression` gives eq. 5–8 (by the standard deviations of x
//!   and y).
//! - **Stray pixels in a strip**: a second moving object's edges of
//!   similar orientation inside a line's strip pull a least-squares fit.
//!   With the default fit the line is fitted again, three times, without the
//!   pixels farther from the last fit than three robust standard deviations
//!   (1.4826 × the median distance, at least 2 px); a clean band keeps every
//!   pixel (its half-width is about 2 robust standard deviations). On the
//!   pendulum with the hexagon crossing behind the rectangle
//!   (`synth pendulum --set distractor=true --set distractor_y=120`) this
//!   raises the frames tracking from 115 / 173 / 176 to 170 / 187 / 173 of
//!   200 at 1.1 / 3.9 / 16 px/frame, none false. Then, a line is fitted
//!   only when the kept pixels span at least 40 % of its length: near the
//!   turning points the rectangle's bands vanish while the hexagon's
//!   13-px edges still move through the strips. With both, 170 / 200 / 177;
//!   without the distractor the output is unchanged (identical at 1.1 and
//!   3.9 px/frame; at 16 the mean 0.774 → 0.775 px, the worst frame
//!   1.82 → 1.78 px).
//! - **Band-aware ζ** (`band_tolerance`): at speeds where the band is wider
//!   than 2ζ a fixed ζ clips the band around the *prediction*, so the fit
//!   returns the prediction. Line k accepts |d| < ζ + w_k, w_k = half the
//!   predicted band width along its normal; ζ keeps its meaning as the
//!   tolerance for prediction error.
//! - **Trimmed ends**: a segment moving obliquely sweeps a *sheared*
//!   parallelogram, whose ends tilt any fit; and near a corner the two bands
//!   overlap. While tracking, only pixels whose foot lies a frame's motion
//!   (+2 px, at most a quarter of the line) inside the end points are fitted.
//! - **Re-centred labelling** (`refine_iterations`): after the fit, pixels are
//!   labelled again around the fitted lines (same tolerances) and refitted,
//!   until the labels stop changing. Each pass halves a prediction error that
//!   only partly overlaps the band, so prediction error from acceleration
//!   (α = 0.2 forecasts lag up to several px on a pendulum) does not bias the
//!   measurement. 0 gives the paper's single pass.
//! - **Second chance**: when a line is *contradicted* (below) the frame is
//!   measured again with the wide acquisition strips around the prediction,
//!   then re-centred with the narrow ones, before the track is declared lost.
//! - **Prediction under acceleration** (`prediction`): eq. 12 with α = 0.2
//!   lags an accelerating corner by several frames' worth of acceleration;
//!   the pendulum released from rest at 16 px/frame peak accelerates by
//!   ~2.7 px/frame², the eq. 12 forecast fell 15–20 px behind the band by
//!   frame 6 and the track was lost at frame 7 (labelling strips around the
//!   forecast miss the band, then eq. 9 fires).
//!   [`Prediction::MeasuredVelocity`]: a corner measured in this and the
//!   previous frame is predicted at its band centre plus its last measured
//!   displacement (the displacement the lag correction uses too), which lags
//!   by one frame's acceleration only. Eq. 10–12 still run for every corner
//!   and predict where that displacement is not measured (start of
//!   tracking, motion resuming after frames without motion pixels, lost).
//!   [`Prediction::Smoothed`] is eq. 12 throughout. At the paper's speeds
//!   on the pendulum both give the same errors (within ±0.03 px mean).
//! - **The outline moves as one** (`prediction`, default
//!   [`Prediction::MeasuredMotion`]): a corner's own displacement carries
//!   its measurement noise twice (c_t + (c_t − c_{t−1})), and on a short
//!   side of a fast turning rectangle a few degrees of fit error grow into
//!   a predicted side leaning past δ. When every corner was measured in this
//!   and the previous frame, the step is the least-squares similarity
//!   transform (turn, scale, shift) between the two measured outlines,
//!   applied once more ([`crate::geometry::similarity_step`]): the noise of
//!   one corner is shared by all, and the path bends with the turn, as an
//!   arc does. Otherwise as `MeasuredVelocity`. On the rotating pendulum at
//!   20 px/frame, seed 1, a short side's fit 5° off at frame 5 made the
//!   per-corner prediction lean 12° at frame 6; only the band's trailing
//!   edge was labelled, the side was put 12 px behind, and the track was
//!   lost on frames 6–11 and 36–41 (188 of 200 frames); with the outline's
//!   step all 200 are held, and the mean corner error of each of the 41
//!   pendulum runs in RESULTS.md falls by 10–24 % (17–24 % at 16 and
//!   20 px/frame).
//! - **No motion pixels** (`missing`): default
//!   [`MissingMeasurement::LastMeasurement`]: no motion pixels means no
//!   visible motion, so a line that got no points keeps its last fitted
//!   position (a corner with one fitted line slides along the held other
//!   one — the aperture problem), a corner with neither is reported where it
//!   was last measured, and its smoother is fed that last measurement again,
//!   which makes the predictions slow down as the paper describes for
//!   cycles without data (§2, Fig. 2). Feeding the prediction itself
//!   ([`MissingMeasurement::Prediction`], an option: lines and corners coast
//!   at the smoother's velocity) overshoots every turning point of a
//!   pendulum, by the lagging trend.
//! - **Lines without motion pixels turn with the object**: a held line is
//!   not frozen. An edge that moves along itself gets (almost) no motion
//!   pixels, but the object may still turn: on the pendulum the rectangle
//!   turns with the arm (36° per swing at 3.9 px/frame) while its top and
//!   bottom edges only slide along themselves, and a frozen top line made
//!   the left corners slide along the left line (18 px by frame 30 on the
//!   demo, then loss). Each frame, a line that is not fitted turns by the
//!   point-weighted mean turn of the fitted lines from their held positions
//!   (a rigid planar object's edges all turn alike), about the middle of the
//!   path of its segment's midpoint over the frame — the point of a line
//!   without normal motion when the object turns about a distant centre
//!   (exact for an edge tangent to a circle about the pivot, with no
//!   second-order drift). Without fitted lines nothing turns.
//! - **Held lines on the frame's edges** (`held_line_edges`): the turn is
//!   the fitted lines' estimate, and its errors add up over the frames a
//!   line goes without motion pixels (the pendulum's top and bottom edges
//!   get none for most of a swing); a second object's pixels in a fitted
//!   line's strip tilt that estimate further (on the pendulum with a hexagon
//!   crossing behind it at 1.1 px/frame the bottom line tilted until its
//!   corners were 6–8 px off, and the contour support lost 30 frames). So a
//!   line that has gone three tracking frames without motion pixels and
//!   moves less than 1 px/frame across itself (by its corners' trend) is,
//!   after turning, fitted to the frame's static edge pixels (Sobel on the
//!   smoothed frame, the pixels of the verification) labelled to it by the
//!   tests of eq. 3–4 in the same strip, with the same robust fit. An edge
//!   that moves along itself is at the same place at band time t − ½ and at
//!   t, so the static fit is the band-time line the motion fit would give.
//!   A fit that would move the held line's ends by more than 4 px, or whose
//!   pixels spread more than 1.5 px (standard deviation) across it, is not
//!   taken: a correction, not a jump to a parallel background edge. With
//!   the distractor at 1.1 / 3.9 / 16 px/frame: 196 / 200 / 172 of 200
//!   frames tracking (170 / 200 / 172 without it), none false; without the
//!   distractor the mean error goes from 0.32 / 0.40 / 0.78 to 0.26 / 0.22 /
//!   0.77 px, on the cluttered pendulum from 0.55 to 0.48 px. Applied from
//!   the first frame without motion pixels and at any speed across, the
//!   same fit lost 13 more frames at 16 px/frame on a translating pendulum,
//!   whose top and bottom lines miss a frame's band as the swing turns.
//!   Needs the edge pixels (requested whenever this or `verify` is on).
//!
//! # Initialisation and loss
//! The operator's corners (`init.json`) are the model at frame 0. The tracker
//! starts *acquiring* (paper §2: "tracking begins when all features selected
//! by the operator are within an acceptable distance from the extracted image
//! corners"): motion pixels are labelled to the operator's lines with the
//! wider distance `init_tolerance` (the first band extends a whole frame's
//! motion from the operator's position), lines fitted (refused when their
//! points scatter like clutter: perpendicular standard deviation above a
//! third of that distance) and intersected. When at least one line is
//! fitted, every measured corner lies within `init_tolerance` of the
//! operator's, and no line is contradicted, tracking begins: the fit is
//! refined with the tracking strips this first motion implies, and the
//! smoothers start (Montgomery's start from a level and a trend) at level =
//! measured band centre and trend = 2·(measured − operator corner), since the
//! band centre lies half a frame after the last position at rest. While
//! acquiring, frames without labelled motion report the operator's corners
//! with status `tracking`: the object has not moved, and the operator's
//! corners are its frame-0 position by contract (SPEC §4), so frame 0 —
//! which has no motion pixels — is `tracking`. A frame whose motion
//! contradicts the operator's model (measured corners too far, or a
//! contradicted line) is `lost`; acquisition goes on.
//!
//! Loss while tracking: eq. 9 (a measured corner ε or more from its
//! prediction), or a *contradicted line* (extension): a line that got fewer
//! than `min_points_per_line` points while at least `lost_evidence` motion
//! pixels of its orientation (eq. 3) in the window were labelled to no line,
//! even after the second chance. Eq. 9 alone cannot see an object that
//! jumped out of the ζ strips: no corner is measured, so none is too far.
//! Nor can either see an object that jumped out of the window of interest:
//! no motion pixels at all, which [`MissingMeasurement::LastMeasurement`]
//! reads as the object at rest. So a third loss (extension, *vanished
//! motion*): no line fitted right after a frame in which every corner was
//! measured (in it and the frame before) and the slowest had moved
//! `vanished_motion` px or more (or the frame before that: the jump frame's
//! own "band" is the vacated outline, half a frame's motion back). Continuous motion does not stop within a
//! frame: at a pendulum's turning point the last bands are seen moving well
//! under 1 px/frame (below ~0.3 px/frame an edge's temporal difference no
//! longer passes the threshold; measured: ≤ 0.75 px/frame). Only measured
//! displacements count: after a frame without data the smoother's trend
//! still carries the speed before the turning point. On the rendered
//! pendulum whose rectangle jumps 80 px mid-swing this is what reports the
//! loss; an object slower than `vanished_motion` that vanishes looks like
//! one coming to rest, and is not reported.
//!
//! # Verification (extension, `verify`; off: the paper's method)
//! Before a frame is reported `tracking` — also while acquiring at rest —
//! the reported outline is checked against the image: the backend also lists
//! the edge pixels of the σ-smoothed frame in the window
//! (`support_edge_threshold`), and at least `min_support` (60 %) of the
//! outline's 1-px samples, and at least `min_side_support` (50 %) of each
//! side's, must have an edge pixel within `support_distance` (3 px) across
//! it at the line's orientation (±δ) ([`crate::track::support`]). A side too
//! short to sample counts as unsupported (a collapsed outline), as does a
//! side outside the image. Otherwise the frame is `lost` with the support
//! in the reason, and a tracking phase turns to lost. Measured on the
//! pendulum: every side ≥ 96 % on every frame at 1.1–16 px/frame; after a
//! jump, with the operator's corners 40 px off, or with an outline slid 3 px
//! along one side, the weakest side falls to 0–20 %: the per-side test sees
//! the slide the overall fraction misses. The first frame reported tracking
//! after a loss must have `reacquire_min_support` (85 %) overall and on
//! every side: re-acquisitions on target have ≥ 88 % on every side, and the
//! thresholds while tracking, low enough for a side hidden in part by a
//! second object, let a re-acquired outline 6 px off through. Without an
//! edge list ([`MotionEdgeTracker::update`]) the check is skipped.
//!
//! # A second look at a wider angle (extension, `retry_delta`; needs `verify`)
//! A tracking frame that is about to be lost — eq. 9, a contradicted line,
//! vanished motion or the verification — is measured once more from the
//! same prediction, with the orientation tolerance of labelling and fitting
//! (eq. 3) widened from δ to `retry_delta` (30°); the second measurement
//! stands when it passes every test, the verification at δ included, and
//! otherwise the first attempt's outcome and state do. A side whose
//! prediction leans more than δ from the side in the image gets its own
//! pixels refused: on the pendulum at the bottom of the swing the top and
//! bottom sides move along themselves and get no motion pixels, the second
//! object's pixels pulled a corner of the right side 2–5 px back, and the
//! next prediction of that side leant 16° (second object at 16 px/frame,
//! seed 3, frame 104); a pendulum turning at 20 px/frame does the same. On
//! the pendulum, seeds 0–9 (`synth pendulum --frames 200 --speed V --seed
//! S`, with and without `--set distractor=true --set distractor_y=120`), with
//! corners predicted one by one (`MeasuredVelocity`), the second look raises
//! the frames tracking at 20 px/frame from 166–200 to
//! 188–200 and with the second object at 16 px/frame from 187–198 to
//! 198–200, leaves the frames tracking of the other runs (16 px/frame; the
//! second object at 1.1 and 3.9 px/frame; 3.9 px/frame) as they were, and
//! reports no frame tracking more than 5 px off. (Verified at the wider δ
//! too, the second look also held the second object at 1.1 px/frame on
//! every frame; the verification stays at δ, as on every frame: it is what
//! keeps a wrong outline from being reported.)
//!
//! # A look from the accelerating outline (extension, `acceleration_look`; needs `verify`)
//! The outline's step (`Prediction::MeasuredMotion`) lags an accelerating
//! object by one frame's change of speed: released from rest at 22 px/frame
//! peak, the pendulum gains 3.5–4 px/frame per frame, and by frame 4 the
//! predicted sides stood 2–6 px behind their bands and leant 12–15° off them,
//! so the frame was lost on most frames of the fast part of every swing.
//! A tracking frame that both looks above would lose is measured a third
//! time, from the outline moved on by its last step plus that step's change
//! from the step before (the constant-acceleration forecast, with that step
//! as the band's width), and that measurement stands when it passes every
//! test. Predicting at constant acceleration on every frame instead was
//! tried: it doubles the noise of the step, and the pendulum with a second
//! object crossing at 16 px/frame lost up to 11 frames (seed 3: 189 of 200)
//! that the outline's step holds. As a third look only, it changes no frame
//! that the first two looks track (the 41 pendulum runs of RESULTS.md give
//! the same lines), and at 22 / 24 / 28 px/frame, seed 0, the frames
//! tracking rise from 87 / 68 / 48 to 193 / 125 / 142 of 200, none false.
//!
//! # Loss and re-acquisition
//! When lost, the tracker keeps predicting (fed as for a missing
//! measurement) and writes an outcome every frame with status `lost`. It
//! re-acquires like the initial acquisition, around the predicted corners,
//! in two frames: a frame whose motion matches every corner makes a
//! candidate and stays `lost`; the next frame, measured around the
//! candidate, confirms it when every corner moved less than
//! `init_tolerance`, and tracking restarts with the displacement between the
//! two as velocity (one frame of motion can match by chance, two consistent
//! ones rarely do). After `search_after` lost frames (with `verify`) the
//! window of interest opens to the whole image and the candidate is searched
//! there: the last tracked shape is placed on the centroid of the motion
//! pixels and turned by multiples of δ up to ±45°, the smallest turn that
//! the motion confirms first. A candidate whose sides are not those of the
//! last tracked outline (a side more than 1.25 times longer or shorter) is
//! refused: the lines are undirected, so a shape turned by 45° can have its
//! lines fitted each to the next side of a rectangle, the outline then on
//! the object with every corner named one place round (on the pendulum at
//! 24 and 28 px/frame this reported 7 and 18 frames tracking 42–61 px off;
//! now none). The verification then decides, as on every frame.

mod params;
mod steps;

pub use params::{
    LineFitMethod, MAX_COUNT, MAX_DISTANCE_PX, MAX_MIN_MAGNITUDE, MAX_MOTION_THRESHOLD, MAX_PASSES, MAX_SEARCH_AFTER,
    MissingMeasurement, MotionEdgeParams, Prediction,
};
pub use steps::{
    Labelling, LineTolerance, ModelLine, corner_deviation, fit_model_lines, intersect_corners, label_motion_pixels,
    model_lines,
};

use super::support::{self, EdgeMap};
use super::{Diagnostics, FrameOutcome, Observations, Phase, Tracker};
use crate::backend::EdgeRequest;
use crate::backend::{FrameRequest, ListSpec, MotionRequest};
use crate::early::gaussian::GaussianParams;
use crate::early::temporal_diff::TemporalDiffParams;
use crate::early::{Feature, Window};
use crate::estimate::line_fit::{Line, LineFit, LineSums, wrap_orientation};
use crate::estimate::smoothing::DoubleExponentialSmoother;
use crate::geometry::similarity_step;
use crate::io::formats::Status;
use crate::{Error, Result};

/// Blur allowance added to a frame's motion when trimming line ends, px.
const TRIM_BLUR_PX: f64 = 2.0;
/// At most this fraction of a line is trimmed at each end.
const MAX_TRIM_FRACTION: f64 = 0.25;
/// While acquiring, a fitted line's perpendicular residual standard deviation
/// must stay below this fraction of the labelling distance: clutter spread
/// evenly over the ±d strip has d/√3 ≈ 0.58·d, an edge band far less.
const ACQUISITION_SPREAD_FRACTION: f64 = 1.0 / 3.0;

/// Largest ratio between a side's length in a re-acquired outline and in
/// the last tracked one, either way
/// ([`MotionEdgeTracker::changed_side`]).
const MAX_SIDE_CHANGE: f64 = 1.25;

/// The motion-edge tracker (module doc).
#[derive(Clone, Debug)]
pub struct MotionEdgeTracker {
    params: MotionEdgeParams,
    /// The size of the first frame given, which every later one must have.
    frame_size: Option<(usize, usize)>,
    edges: Vec<[usize; 2]>,
    /// The two model lines (edge indices) meeting at each corner.
    corner_lines: Vec<[usize; 2]>,
    phase: Phase,
    /// While acquiring: where the object is believed at rest (frame time).
    anchor: Vec<[f64; 2]>,
    smoothers: Vec<DoubleExponentialSmoother<2>>,
    /// Predicted centre of the next frame's motion band per corner (band time).
    predicted: Vec<[f64; 2]>,
    /// Smoothers' trend per corner, px per frame.
    trend: Vec<[f64; 2]>,
    /// Last measured band-time position per corner.
    last_measured: Vec<[f64; 2]>,
    /// Band-time position measured in the previous frame, per corner.
    previous_measured: Vec<Option<[f64; 2]>>,
    /// The slowest corner's measured displacement in the last frame, px,
    /// when every corner was measured in it and in the frame before.
    measured_speed: Option<f64>,
    /// `measured_speed` of the frame before.
    earlier_measured_speed: Option<f64>,
    /// The outline's step into the last frame (`Prediction::MeasuredMotion`),
    /// per corner, when every corner was measured in it and the frame before.
    last_outline_step: Option<Vec<[f64; 2]>>,
    /// The next band at constant acceleration, when the outline's last two
    /// steps are known (`acceleration_look`).
    accelerated: Option<Forecast>,
    /// Per model line: its last fitted position (initially the operator's).
    held_lines: Vec<Option<Line>>,
    /// Per model line: tracking frames in a row up to the last one in which
    /// it was not fitted.
    unfitted_run: Vec<usize>,
    /// Per corner, its last reported position (finite; initially the
    /// operator's): what a corner that is not finite is reported as.
    last_reported: Vec<[f64; 2]>,
    /// This frame's edge pixels for the verification, when given.
    support_map: Option<EdgeMap>,
    /// This frame's edge pixels with their edge orientation (the θ
    /// convention of eq. 2) as `theta`, for the held lines' fit.
    edge_pixels: Vec<Feature>,
    /// While lost: the band-time corners of the previous frame's
    /// re-acquisition measurement, awaiting confirmation by this frame's.
    reacquisition_candidate: Option<Vec<[f64; 2]>>,
    /// The corners of the last tracking frame (initially the operator's):
    /// the shape searched for once lost for `search_after` frames.
    last_tracked: Vec<[f64; 2]>,
    /// Lost frames in a row.
    lost_run: usize,
    /// Whether the frame is being measured a second time, at `retry_delta`.
    retrying: bool,
}

/// Largest move of a held line's end points by its fit to the frame's
/// edges, px (module doc, "Held lines on the frame's edges").
const HELD_LINE_CORRECTION_PX: f64 = 4.0;
/// Largest standard deviation across a held line's edge fit of the pixels
/// it keeps, px (a Sobel band of one edge is about ±1 px; a fit mixing two
/// parallel edges spreads wider).
const HELD_LINE_SPREAD_PX: f64 = 1.5;
/// Fastest motion across itself of a held line fitted to the frame's edges,
/// px/frame.
const HELD_LINE_MAX_ACROSS: f64 = 1.0;
/// Frames a line must have gone without motion pixels before its held
/// position is fitted to the frame's edges (a line missed for a frame or
/// two has not drifted; its band may only have left the strip).
const HELD_LINE_MIN_FRAMES: usize = 3;

/// One frame's measurement (steps 1–5).
struct Measurement {
    labelling: Labelling,
    fitted: Vec<Option<LineFit>>,
    /// The lines the unfitted lines were taken as (held and turned, or the model's).
    fallback_lines: Vec<Option<Line>>,
    corners: Vec<[f64; 2]>,
    measured: Vec<bool>,
    deviation: Option<f64>,
    /// A line starved while its orientation's motion lay elsewhere.
    contradicted: Option<usize>,
}

impl MotionEdgeTracker {
    /// A tracker for the planar polygon with image `corners` at frame 0
    /// (model-vertex order) and `edges` (pairs of corner indices, model.json
    /// order). Every corner must be on exactly two edges whose lines are not
    /// parallel.
    pub fn new(corners: Vec<[f64; 2]>, edges: Vec<[usize; 2]>, params: MotionEdgeParams) -> Result<Self> {
        params.validate()?;
        let corner_lines = corner_lines_of(&corners, &edges)?;
        let smoothers =
            corners.iter().map(|&c| DoubleExponentialSmoother::new(params.alpha, c)).collect::<Result<Vec<_>>>()?;
        let n = corners.len();
        let held_lines: Vec<Option<Line>> = model_lines(&corners, &edges).iter().map(|l| l.map(|l| l.line)).collect();
        if corners.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::Parameter("motion-edge: the initial corners must be finite".into()));
        }
        crate::geometry::check_simple_polygon(&corners, &edges)
            .map_err(|msg| Error::Parameter(format!("motion-edge: {msg}")))?;
        Ok(Self {
            params,
            frame_size: None,
            edges,
            corner_lines,
            phase: Phase::Acquiring,
            anchor: corners.clone(),
            smoothers,
            predicted: corners.clone(),
            trend: vec![[0.0; 2]; n],
            last_reported: corners.clone(),
            last_measured: corners.clone(),
            previous_measured: vec![None; n],
            measured_speed: None,
            last_outline_step: None,
            accelerated: None,
            earlier_measured_speed: None,
            unfitted_run: vec![0; held_lines.len()],
            held_lines,
            support_map: None,
            edge_pixels: Vec::new(),
            reacquisition_candidate: None,
            last_tracked: corners,
            lost_run: 0,
            retrying: false,
        })
    }

    /// This tracker in its present state with `lag_correction` off: it
    /// reports the corners where the fitted lines put them (the paper's
    /// extracted corners).
    #[must_use]
    pub fn without_lag_correction(&self) -> Self {
        let mut twin = self.clone();
        twin.params.lag_correction = false;
        twin
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &MotionEdgeParams {
        &self.params
    }

    /// The model edges (corner index pairs).
    #[must_use]
    pub fn edges(&self) -> &[[usize; 2]] {
        &self.edges
    }

    /// The current phase.
    #[must_use]
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Where the next frame's model lines are expected: the predicted centre
    /// of its motion band per corner (band time; module doc). While acquiring,
    /// the corners at rest.
    #[must_use]
    pub fn predicted_corners(&self) -> &[[f64; 2]] {
        if self.phase == Phase::Acquiring { &self.anchor } else { &self.predicted }
    }

    /// Predicted motion per corner, px per frame.
    #[must_use]
    pub fn trend(&self) -> &[[f64; 2]] {
        &self.trend
    }

    /// The window holding the next frame's motion pixels: the bounding box of
    /// the predicted corners grown by `window_margin` plus ζ and a frame's
    /// predicted motion while tracking (the next band extends half a frame's
    /// motion beyond its predicted centre, the other half is slack for
    /// prediction error), plus `init_tolerance` while acquiring or lost;
    /// clipped to the image.
    #[must_use]
    pub fn window_of_interest(&self, width: usize, height: usize) -> Window {
        let max_motion = self.trend.iter().map(|b| b[0].hypot(b[1])).fold(0.0, f64::max);
        let margin = self.params.window_margin
            + match self.phase {
                Phase::Tracking => self.params.zeta + max_motion,
                Phase::Acquiring => self.params.init_tolerance,
                Phase::Lost => self.params.init_tolerance + max_motion,
            };
        // A corner that is not finite (a diverged prediction), or a search
        // after a long loss, opens the whole image.
        let corners = self.predicted_corners();
        let full = Window::full(width, height);
        if !(margin.is_finite() && corners.iter().flatten().all(|v| v.is_finite())) || self.searching() {
            return full;
        }
        Window::around(corners, margin, width, height).unwrap_or(full)
    }

    /// Whether the tracker has been lost long enough to search the whole
    /// image (module doc, "Verification").
    fn searching(&self) -> bool {
        self.phase == Phase::Lost && self.params.verify && self.lost_run >= self.params.search_after
    }

    /// Process frame `frame` given its motion pixels, without verification
    /// (no edge pixels to check against); every call returns an outcome
    /// (also when lost).
    pub fn update(&mut self, frame: usize, motion: &[Feature]) -> FrameOutcome {
        self.update_with_edges(frame, motion, None)
    }

    /// Process frame `frame` given its motion pixels and, for the
    /// verification (module doc), its edge pixels (Sobel on the smoothed
    /// frame, as [`Tracker::request`] asks for them); `None` skips the
    /// verification. Every call returns an outcome (also when lost).
    pub fn update_with_edges(&mut self, frame: usize, motion: &[Feature], edges: Option<&[Feature]>) -> FrameOutcome {
        let edge_orientation = |f: &Feature| wrap_orientation(f64::from(f.theta) + std::f64::consts::FRAC_PI_2);
        self.support_map = match edges {
            Some(edges) if self.params.verify => {
                Some(EdgeMap::new(edges, self.params.support_edge_threshold, edge_orientation))
            }
            _ => None,
        };
        // The held lines' fit needs them only while tracking with a line
        // held long enough (`edge_fitted_held_lines`).
        self.edge_pixels.clear();
        if self.params.held_line_edges
            && self.phase == Phase::Tracking
            && self.unfitted_run.iter().any(|&run| run >= HELD_LINE_MIN_FRAMES)
            && let Some(edges) = edges
        {
            self.edge_pixels.extend(
                edges
                    .iter()
                    .filter(|f| f.magnitude >= self.params.support_edge_threshold && f.theta.is_finite())
                    .map(|f| Feature { theta: edge_orientation(f) as f32, ..*f }),
            );
        }
        match self.phase {
            Phase::Acquiring => self.acquire(frame, motion),
            Phase::Tracking => self.track_frame(frame, motion),
            Phase::Lost => self.reacquire(frame, motion),
        }
    }

    /// Whether a line without points keeps its last fitted position (tracking
    /// with [`MissingMeasurement::LastMeasurement`]) rather than the model's.
    fn holds_lines(&self) -> bool {
        self.phase == Phase::Tracking && self.params.missing == MissingMeasurement::LastMeasurement
    }

    /// Steps 1–5 around `model` corners with per-line tolerances; with
    /// `max_spread`, fits whose points scatter more than that perpendicular
    /// standard deviation (px) are refused.
    fn measure(
        &self,
        motion: &[Feature],
        model: &[[f64; 2]],
        tolerances: &[LineTolerance],
        max_spread: Option<f64>,
    ) -> Measurement {
        let lines = model_lines(model, &self.edges);
        let labelling =
            label_motion_pixels(motion, &lines, tolerances, self.labelling_delta(), self.params.min_magnitude);
        let mut fitted = fit_model_lines(
            &labelling,
            &lines,
            self.params.min_points_per_line,
            self.labelling_delta(),
            self.params.line_fit,
        );
        if let Some(spread) = max_spread {
            for fit in &mut fitted {
                *fit = fit.filter(|f| f.perpendicular_residual_variance() <= spread * spread);
            }
        }
        let (corners, measured, fallback_lines) = if self.holds_lines() {
            let held = self.edge_fitted_held_lines(self.turned_held_lines(&fitted), &fitted, &lines, tolerances);
            let (corners, measured) = intersect_corners(&fitted, &held, &self.last_measured, &self.corner_lines);
            (corners, measured, held)
        } else {
            let model_lines: Vec<Option<Line>> = lines.iter().map(|l| l.map(|l| l.line)).collect();
            let (corners, measured) = intersect_corners(&fitted, &model_lines, model, &self.corner_lines);
            (corners, measured, model_lines)
        };
        let deviation = corner_deviation(&corners, &measured, model);
        let contradicted = (0..self.edges.len()).find(|&k| {
            labelling.sums[k].count() < self.params.min_points_per_line
                && labelling.unexplained[k] >= self.params.lost_evidence
        });
        Measurement { labelling, fitted, fallback_lines, corners, measured, deviation, contradicted }
    }

    /// The held lines of the lines not fitted this frame, each fitted to the
    /// frame's edge pixels in its strip of `lines` where that succeeds
    /// (module doc, "Held lines on the frame's edges").
    fn edge_fitted_held_lines(
        &self,
        mut held: Vec<Option<Line>>,
        fitted: &[Option<LineFit>],
        lines: &[Option<ModelLine>],
        tolerances: &[LineTolerance],
    ) -> Vec<Option<Line>> {
        if self.edge_pixels.is_empty() {
            return held;
        }
        // Only lines that move (nearly) along themselves: the frame's edge
        // is then where the band-time line is.
        let across = |line: &ModelLine, [i, j]: [usize; 2]| {
            let normal = [-line.direction[1], line.direction[0]];
            let speed = |b: [f64; 2]| (b[0] * normal[0] + b[1] * normal[1]).abs();
            speed(self.trend[i]).max(speed(self.trend[j]))
        };
        let strips: Vec<Option<ModelLine>> = lines
            .iter()
            .zip(fitted)
            .zip(&held)
            .zip(&self.edges)
            .zip(&self.unfitted_run)
            .map(|((((line, fit), held), &edge), &run)| {
                line.filter(|l| {
                    fit.is_none()
                        && held.is_some()
                        && run >= HELD_LINE_MIN_FRAMES
                        && across(l, edge) <= HELD_LINE_MAX_ACROSS
                })
            })
            .collect();
        if strips.iter().all(Option::is_none) {
            return held;
        }
        let labelling = label_motion_pixels(&self.edge_pixels, &strips, tolerances, self.labelling_delta(), 0.0);
        let fits = fit_model_lines(
            &labelling,
            &strips,
            self.params.min_points_per_line,
            self.labelling_delta(),
            LineFitMethod::Across,
        );
        for ((line, fit), strip) in held.iter_mut().zip(fits).zip(&strips) {
            let (Some(fit), Some(strip), Some(old)) = (fit, strip, *line) else { continue };
            // A correction of the held line, not a jump to another edge.
            let end = [
                strip.start[0] + strip.length * strip.direction[0],
                strip.start[1] + strip.length * strip.direction[1],
            ];
            let moved = |p: [f64; 2]| fit.line.distance(old.project(p)).abs();
            if moved(strip.start).max(moved(end)) <= HELD_LINE_CORRECTION_PX
                && fit.perpendicular_residual_variance() <= HELD_LINE_SPREAD_PX * HELD_LINE_SPREAD_PX
            {
                *line = Some(fit.line);
            }
        }
        held
    }

    /// The held lines of the lines not fitted this frame, turned with the
    /// object (module doc, "Lines without motion pixels turn with the
    /// object"): each by the point-weighted mean turn of the fitted lines
    /// from their held positions, about the middle of the path of its
    /// segment's midpoint (the point of the line without normal motion over
    /// the frame when the object turns about a distant centre). Fitted lines
    /// keep their held position here (the fit replaces it).
    fn turned_held_lines(&self, fitted: &[Option<LineFit>]) -> Vec<Option<Line>> {
        let (mut weight, mut turn) = (0.0, 0.0);
        for (fit, held) in fitted.iter().zip(&self.held_lines) {
            if let (Some(fit), Some(held)) = (fit, held) {
                let w = fit.count as f64;
                weight += w;
                turn += w * signed_turn(held.orientation(), fit.line.orientation());
            }
        }
        if !(weight > 0.0) || turn == 0.0 {
            return self.held_lines.clone();
        }
        let turn = turn / weight;
        let midpoint = |corners: &[[f64; 2]], [i, j]: [usize; 2]| {
            [0.5 * (corners[i][0] + corners[j][0]), 0.5 * (corners[i][1] + corners[j][1])]
        };
        let turned = |centres: &dyn Fn(usize) -> [f64; 2]| -> Vec<Option<Line>> {
            self.held_lines
                .iter()
                .enumerate()
                .map(|(k, held)| {
                    let held = (*held)?;
                    if fitted[k].is_some() {
                        return Some(held);
                    }
                    let q = held.project(centres(k));
                    let phi = held.orientation() + turn;
                    Line::through(q, [q[0] + phi.cos(), q[1] + phi.sin()]).or(Some(held))
                })
                .collect()
        };
        // First about the segment's last midpoint, then about the middle of
        // that midpoint's path to the midpoint between the new corners.
        let old_mid = |k: usize| midpoint(&self.last_measured, self.edges[k]);
        let first = turned(&old_mid);
        let (corners, _) = intersect_corners(fitted, &first, &self.last_measured, &self.corner_lines);
        let path_mid = |k: usize| {
            let (a, b) = (old_mid(k), midpoint(&corners, self.edges[k]));
            [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])]
        };
        turned(&path_mid)
    }

    /// [`Self::measure`] starting from `start`, then re-labelled around the
    /// corners just measured up to `refine_iterations` times (stopping when
    /// the labels no longer change); eq. 9's deviation is taken from `reference`.
    fn measure_refined(
        &self,
        motion: &[Feature],
        start: &[[f64; 2]],
        tolerances: &[LineTolerance],
        reference: &[[f64; 2]],
    ) -> Measurement {
        let mut m = self.measure(motion, start, tolerances, None);
        for _ in 0..self.params.refine_iterations {
            if m.fitted.iter().all(Option::is_none) {
                break;
            }
            let next = self.measure(motion, &m.corners, tolerances, None);
            let converged = next.labelling.pixels == m.labelling.pixels;
            m = next;
            if converged {
                break;
            }
        }
        m.deviation = corner_deviation(&m.corners, &m.measured, reference);
        m
    }

    /// Tolerances while tracking, for model `corners` moving by `trend` px
    /// per frame: ζ, widened by half the band width when `band_tolerance`, and
    /// ends trimmed by a frame's motion (module doc).
    fn tracking_tolerances(&self, corners: &[[f64; 2]], trend: &[[f64; 2]]) -> Vec<LineTolerance> {
        self.edges
            .iter()
            .map(|&[i, j]| {
                let (pi, pj) = (corners[i], corners[j]);
                let length = (pj[0] - pi[0]).hypot(pj[1] - pi[1]).max(f64::MIN_POSITIVE);
                let normal = [-(pj[1] - pi[1]) / length, (pj[0] - pi[0]) / length];
                let (bi, bj) = (trend[i], trend[j]);
                let across = |b: [f64; 2]| (b[0] * normal[0] + b[1] * normal[1]).abs();
                let along = |b: [f64; 2]| (b[0] * normal[1] - b[1] * normal[0]).abs();
                let half_band = if self.params.band_tolerance { 0.5 * across(bi).max(across(bj)) } else { 0.0 };
                let distance = self.params.zeta + half_band;
                let motion = bi[0].hypot(bi[1]).max(bj[0].hypot(bj[1]));
                let trim = (motion + TRIM_BLUR_PX).min(length * MAX_TRIM_FRACTION);
                LineTolerance { distance, extent: distance + 0.5 * along(bi).max(along(bj)), trim }
            })
            .collect()
    }

    /// Acquisition (module doc): label around the corners at rest with
    /// `init_tolerance`; start tracking when the image confirms them.
    fn acquire(&mut self, frame: usize, motion: &[Feature]) -> FrameOutcome {
        let tolerance = self.params.init_tolerance;
        let tolerances = vec![LineTolerance::uniform(tolerance); self.edges.len()];
        let anchor = self.anchor.clone();
        let m = self.measure(motion, &anchor, &tolerances, Some(tolerance * ACQUISITION_SPREAD_FRACTION));
        let any_fitted = m.fitted.iter().any(Option::is_some);
        let lost_reason = self.acquisition_failure(&m, tolerance);
        if any_fitted && lost_reason.is_none() {
            // The band centre lies half a frame after the position at rest.
            let trend_from = |m: &Measurement| -> Vec<[f64; 2]> {
                m.corners.iter().zip(&anchor).map(|(c, a)| [2.0 * (c[0] - a[0]), 2.0 * (c[1] - a[1])]).collect()
            };
            // Refine with the tracking strips and trimmed ends that this first
            // motion implies (the wide, untrimmed fit is biased by the band's
            // sheared ends), keeping the coarse result if that fails.
            let coarse_trend = trend_from(&m);
            let tolerances = self.tracking_tolerances(&m.corners, &coarse_trend);
            let fine = self.measure_refined(motion, &m.corners, &tolerances, &anchor);
            let fine_ok = fine.contradicted.is_none()
                && fine.measured == m.measured
                && fine.deviation.is_some_and(|d| d < tolerance);
            let m = if fine_ok { fine } else { m };
            let trend = trend_from(&m);
            return self.start_tracking(frame, m, &trend);
        }
        // No usable measurement: the object is where the operator put it
        // (status tracking), unless the motion contradicts that (lost).
        let status = if lost_reason.is_some() { Status::Lost } else { Status::Tracking };
        let corners = self.anchor.clone();
        self.outcome(frame, status, corners, m, lost_reason)
    }

    /// Re-acquisition while lost: like acquisition, around the predicted
    /// corners (or the previous frame's candidate), in two frames. A frame
    /// whose motion matches the model makes a candidate and stays lost; the
    /// next frame's measurement around the candidate confirms it when every
    /// corner moved less than `init_tolerance`, and tracking restarts with
    /// the displacement between the two as the corners' velocity, refined
    /// with the tracking strips that motion implies. One frame of motion can
    /// match the model by chance (the object's band elsewhere, a passing
    /// distractor); two consistent ones rarely do. Otherwise coast.
    fn reacquire(&mut self, frame: usize, motion: &[Feature]) -> FrameOutcome {
        let tolerance = self.params.init_tolerance;
        let tolerances = vec![LineTolerance::uniform(tolerance); self.edges.len()];
        let candidate = self.reacquisition_candidate.take();
        let models = match &candidate {
            Some(candidate) => vec![candidate.clone()],
            None if self.searching() => self.search_models(motion),
            None => vec![self.predicted.clone()],
        };
        let mut best: Option<Measurement> = None;
        let mut failure = Some("lost: searching the image for motion".to_string());
        for model in &models {
            let m = self.measure(motion, model, &tolerances, Some(tolerance * ACQUISITION_SPREAD_FRACTION));
            let all_measured = m.measured.iter().all(|&b| b);
            let why = self
                .acquisition_failure(&m, tolerance)
                .or_else(|| {
                    (!all_measured).then(|| "lost: no motion matches every corner of the predicted model".to_string())
                })
                .or_else(|| self.changed_side(&m.corners));
            if why.is_none() {
                best = Some(m);
                failure = None;
                break;
            }
            failure = why;
            if models.len() == 1 {
                best = Some(m);
            }
        }
        let m = match (best, failure) {
            (Some(m), None) => m,
            (best, failure) => {
                let m = best.unwrap_or_else(|| self.measure(&[], &self.predicted, &tolerances, None));
                return self.coast(frame, m, failure.unwrap_or_default());
            }
        };
        let Some(previous) = candidate else {
            self.reacquisition_candidate = Some(m.corners.clone());
            return self.coast(
                frame,
                m,
                "re-acquiring: motion matches the model, to be confirmed by the next frame".into(),
            );
        };
        let trend: Vec<[f64; 2]> = m.corners.iter().zip(&previous).map(|(c, p)| [c[0] - p[0], c[1] - p[1]]).collect();
        if trend.iter().any(|v| !(v[0].hypot(v[1]) < tolerance)) {
            self.reacquisition_candidate = Some(m.corners.clone());
            return self.coast(frame, m, "re-acquiring: the candidate moved too far to be confirmed".into());
        }
        let fine_tolerances = self.tracking_tolerances(&m.corners, &trend);
        let fine = self.measure_refined(motion, &m.corners, &fine_tolerances, &m.corners);
        let fine_ok =
            fine.contradicted.is_none() && fine.measured == m.measured && fine.deviation.is_some_and(|d| d < tolerance);
        let m = if fine_ok { fine } else { m };
        self.start_tracking(frame, m, &trend)
    }

    /// The shapes a search tries (module doc, "Verification"): the last
    /// tracked shape moved so that its centroid lies on the centroid of
    /// `motion` (the moving object's band, when it is the only thing moving),
    /// turned about it by every multiple of δ within ±45°, the smaller turns
    /// first (a symmetric shape turned further could match with its corners
    /// exchanged). None with fewer motion pixels than `min_points_per_line`
    /// per model line.
    fn search_models(&self, motion: &[Feature]) -> Vec<Vec<[f64; 2]>> {
        if motion.len() < self.params.min_points_per_line * self.edges.len() {
            return Vec::new();
        }
        let mean = |points: &mut dyn Iterator<Item = [f64; 2]>| {
            let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
            for [x, y] in points {
                (sx, sy, n) = (sx + x, sy + y, n + 1.0);
            }
            [sx / n, sy / n]
        };
        let target = mean(&mut motion.iter().map(|f| [f64::from(f.x), f64::from(f.y)]));
        let centre = mean(&mut self.last_tracked.iter().copied());
        let turns = (std::f64::consts::FRAC_PI_4 / self.params.delta).floor() as i64;
        let mut steps: Vec<i64> = (-turns..=turns).collect();
        steps.sort_by_key(|k| k.abs());
        steps
            .into_iter()
            .map(|k| {
                let (sin, cos) = (k as f64 * self.params.delta).sin_cos();
                self.last_tracked
                    .iter()
                    .map(|c| {
                        let (dx, dy) = (c[0] - centre[0], c[1] - centre[1]);
                        [target[0] + cos * dx - sin * dy, target[1] + sin * dx + cos * dy]
                    })
                    .collect()
            })
            .collect()
    }

    /// Why an acquisition measurement is refused, if it is.
    fn acquisition_failure(&self, m: &Measurement, tolerance: f64) -> Option<String> {
        if let Some(k) = m.contradicted {
            return Some(format!(
                "line {k} has {} motion pixels of its orientation elsewhere and too few on it",
                m.labelling.unexplained[k]
            ));
        }
        match m.deviation {
            Some(d) if d >= tolerance => {
                Some(format!("a measured corner is {d:.1} px from the model (acceptance {tolerance} px)"))
            }
            _ => None,
        }
    }

    /// Why re-acquired `corners` cannot be the object last tracked: a side
    /// whose length differs from its length then by more than
    /// [`MAX_SIDE_CHANGE`] either way. A rigid planar object keeps its
    /// sides' lengths in the image while it moves in its plane; a fit that
    /// moved each line onto another side of the object (a rectangle's corners
    /// named one place round) swaps long and short sides.
    fn changed_side(&self, corners: &[[f64; 2]]) -> Option<String> {
        let model = &self.last_tracked;
        let length = |p: &[[f64; 2]], [i, j]: [usize; 2]| (p[i][0] - p[j][0]).hypot(p[i][1] - p[j][1]);
        self.edges.iter().enumerate().find_map(|(k, &edge)| {
            let ratio = length(corners, edge) / length(model, edge);
            (!(1.0 / MAX_SIDE_CHANGE..=MAX_SIDE_CHANGE).contains(&ratio)).then(|| {
                format!(
                    "lost: side {k} of the re-acquired outline is {ratio:.2} times its last tracked length (at most {MAX_SIDE_CHANGE} either way)"
                )
            })
        })
    }

    /// Start (or restart) tracking from a measurement and per-corner trends.
    fn start_tracking(&mut self, frame: usize, m: Measurement, trend: &[[f64; 2]]) -> FrameOutcome {
        let alpha = self.params.alpha;
        for (i, (&c, &b)) in m.corners.iter().zip(trend).enumerate() {
            // Alpha was validated in `new`; the fallback cannot be taken.
            self.smoothers[i] =
                DoubleExponentialSmoother::with_level_and_trend(alpha, c, b).unwrap_or(self.smoothers[i]);
        }
        self.phase = Phase::Tracking;
        self.hold_fitted_lines(&m);
        self.previous_measured.iter_mut().for_each(|p| *p = None);
        let corners = self.advance_predictions(&m.corners, &m.measured, Some(trend));
        self.outcome(frame, Status::Tracking, corners, m, None)
    }

    /// A tracking frame: measured from the prediction and, when that would
    /// lose the track, measured again with the orientation tolerance
    /// widened to `retry_delta` (module doc, "A second look at a wider
    /// angle"), then from the accelerating outline (module doc, "A look from
    /// the accelerating outline"); the first attempt's outcome and state
    /// stand unless a later one is tracking. The state is copied only where
    /// a later look is on.
    fn track_frame(&mut self, frame: usize, motion: &[Feature]) -> FrameOutcome {
        let wider = self.params.verify && self.params.retry_delta > self.params.delta;
        let accelerated = self.params.verify && self.params.acceleration_look && self.accelerated.is_some();
        if !wider && !accelerated {
            return self.track_frame_once(frame, motion);
        }
        let before = self.without_frame_data(|t| t.clone());
        let first = self.track_frame_once(frame, motion);
        if first.status == Status::Tracking {
            return first;
        }
        let failed = self.without_frame_data(|t| std::mem::replace(t, before.clone()));
        if wider {
            self.retrying = true;
            let retry = self.track_frame_once(frame, motion);
            self.retrying = false;
            if retry.status == Status::Tracking {
                return retry;
            }
            self.without_frame_data(|t| t.clone_from(&before));
        }
        if accelerated && let Some(forecast) = before.accelerated {
            (self.predicted, self.trend) = (forecast.corners, forecast.steps);
            let look = self.track_frame_once(frame, motion);
            if look.status == Status::Tracking {
                return look;
            }
        }
        self.without_frame_data(|t| *t = failed);
        first
    }

    /// The angle tolerance of labelling and fitting (eq. 3): δ, or
    /// `retry_delta` while a frame is measured a second time.
    fn labelling_delta(&self) -> f64 {
        if self.retrying { self.params.retry_delta } else { self.params.delta }
    }

    /// `f` applied to the tracker with this frame's edge data (the support
    /// map, the edge pixels) set aside, which stay with the tracker.
    fn without_frame_data<R>(&mut self, f: impl FnOnce(&mut Self) -> R) -> R {
        let map = self.support_map.take();
        let pixels = std::mem::take(&mut self.edge_pixels);
        let result = f(self);
        self.support_map = map;
        self.edge_pixels = pixels;
        result
    }

    /// One tracking cycle: measure around the prediction, check eq. 9 and
    /// contradiction, update the smoothers, predict, and verify.
    fn track_frame_once(&mut self, frame: usize, motion: &[Feature]) -> FrameOutcome {
        let predicted = self.predicted.clone();
        let tolerances = self.tracking_tolerances(&predicted, &self.trend);
        let mut m = self.measure_refined(motion, &predicted, &tolerances, &predicted);
        if m.contradicted.is_some() {
            // Second chance (module doc): search the wide acquisition strips
            // around the prediction, then re-centre with the narrow ones.
            let wide = vec![LineTolerance::uniform(self.params.init_tolerance); self.edges.len()];
            let spread = self.params.init_tolerance * ACQUISITION_SPREAD_FRACTION;
            let coarse = self.measure(motion, &predicted, &wide, Some(spread));
            if coarse.fitted.iter().any(Option::is_some) {
                let retry = self.measure_refined(motion, &coarse.corners, &tolerances, &predicted);
                if retry.contradicted.is_none() {
                    m = retry;
                }
            }
        }
        let reason = match (m.deviation, m.contradicted) {
            (Some(d), _) if d >= self.params.epsilon => Some(format!(
                "eq. 9: a measured corner is {d:.1} px from its prediction (epsilon {} px)",
                self.params.epsilon
            )),
            (_, Some(k)) => Some(format!(
                "line {k} has {} motion pixels of its orientation elsewhere and too few on it",
                m.labelling.unexplained[k]
            )),
            _ => {
                // The frame before may be the jump itself, whose band is
                // the vacated outline half a frame back: also the one before.
                let expected = self.measured_speed.unwrap_or(0.0).max(self.earlier_measured_speed.unwrap_or(0.0));
                (m.fitted.iter().all(Option::is_none) && expected >= self.params.vanished_motion)
                    .then(|| {
                        format!(
                            "motion vanished: no line has motion pixels after moving {expected:.1} px/frame (vanished_motion {} px/frame)",
                            self.params.vanished_motion
                        )
                    })
            }
        };
        if let Some(reason) = reason {
            self.phase = Phase::Lost;
            return self.coast(frame, m, reason);
        }
        self.hold_fitted_lines(&m);
        let (corners, measured) = (m.corners.clone(), m.measured.clone());
        let reported = self.feed_smoothers(&corners, &measured);
        self.outcome(frame, Status::Tracking, reported, m, None)
    }

    /// Keep this frame's lines (fitted, else the fallback used) for the
    /// frames in which they get no points.
    fn hold_fitted_lines(&mut self, m: &Measurement) {
        for ((held, fit), fallback) in self.held_lines.iter_mut().zip(&m.fitted).zip(&m.fallback_lines) {
            if let Some(line) = fit.map(|f| f.line).or(*fallback) {
                *held = Some(line);
            }
        }
        for (run, fit) in self.unfitted_run.iter_mut().zip(&m.fitted) {
            *run = if fit.is_some() { 0 } else { *run + 1 };
        }
    }

    /// A lost frame: no measurement is used; the smoothers predict on.
    fn coast(&mut self, frame: usize, m: Measurement, reason: String) -> FrameOutcome {
        let predicted = self.predicted.clone();
        let none = vec![false; predicted.len()];
        let reported = self.feed_smoothers(&predicted, &none);
        self.outcome(frame, Status::Lost, reported, m, Some(reason))
    }

    /// Eq. 10–11 for every corner (measured corners, or what
    /// [`MissingMeasurement`] says), then [`Self::advance_predictions`].
    fn feed_smoothers(&mut self, corners: &[[f64; 2]], measured: &[bool]) -> Vec<[f64; 2]> {
        for (i, smoother) in self.smoothers.iter_mut().enumerate() {
            let observation = if measured[i] {
                corners[i]
            } else {
                match self.params.missing {
                    MissingMeasurement::Prediction => self.predicted[i],
                    MissingMeasurement::LastMeasurement => self.last_measured[i],
                }
            };
            smoother.update(observation);
        }
        self.advance_predictions(corners, measured, None)
    }

    /// Eq. 12: predict the next band centre (one step ahead) per corner, and
    /// return the corners reported for this frame: measured band centres (or
    /// the smoothed level where unmeasured) plus, with `lag_correction`, half
    /// a frame's motion — the last measured displacement where the corner was
    /// measured in this and the previous frame, the smoother's trend otherwise.
    fn advance_predictions(
        &mut self,
        corners: &[[f64; 2]],
        measured: &[bool],
        start_velocity: Option<&[[f64; 2]]>,
    ) -> Vec<[f64; 2]> {
        let shift = if self.params.lag_correction { 0.5 } else { 0.0 };
        let holding = self.params.missing == MissingMeasurement::LastMeasurement;
        self.earlier_measured_speed = self.measured_speed;
        self.measured_speed = corners
            .iter()
            .zip(measured)
            .zip(&self.previous_measured)
            .map(|((c, &m), p)| match (m, p) {
                (true, Some(p)) => Some((c[0] - p[0]).hypot(c[1] - p[1])),
                _ => None,
            })
            .try_fold(f64::INFINITY, |slowest, speed| speed.map(|v| slowest.min(v)))
            .filter(|v| v.is_finite());
        // With `MeasuredMotion` and every corner measured twice in a row: the
        // outline's displacement, one per corner.
        let outline_step = (self.params.prediction == Prediction::MeasuredMotion)
            .then(|| measured.iter().zip(&self.previous_measured).map(|(&m, p)| p.filter(|_| m)).collect())
            .and_then(|previous: Option<Vec<[f64; 2]>>| similarity_step(&previous?, corners));
        // Constant acceleration: this step plus its change from the last one.
        self.accelerated = match (&outline_step, &self.last_outline_step) {
            (Some(step), Some(last)) => {
                let steps: Vec<[f64; 2]> =
                    step.iter().zip(last).map(|(v, u)| [2.0 * v[0] - u[0], 2.0 * v[1] - u[1]]).collect();
                let corners = corners.iter().zip(&steps).map(|(c, v)| [c[0] + v[0], c[1] + v[1]]).collect();
                Some(Forecast { corners, steps })
            }
            _ => None,
        };
        self.last_outline_step.clone_from(&outline_step);
        let mut reported = Vec::with_capacity(corners.len());
        for (i, smoother) in self.smoothers.iter().enumerate() {
            let trend = smoother.trend();
            let c = corners[i];
            // Measured twice in a row: the displacement between the two band
            // centres (the corner's, or the outline's) is the velocity half a
            // frame before `c`.
            let displacement = match (measured[i], self.previous_measured[i], &outline_step) {
                (true, Some(_), Some(step)) => Some(step[i]),
                (true, Some(p), None) => Some([c[0] - p[0], c[1] - p[1]]),
                _ => None,
            };
            let (base, velocity) = match (displacement, measured[i], start_velocity) {
                (Some(v), _, _) => (c, v),
                (None, true, Some(start)) => (c, start[i]),
                // Moving again after frames without motion pixels: the band
                // started at the held position, so it is half a frame's motion.
                (None, true, None) if holding => {
                    let held = self.last_measured[i];
                    (c, [2.0 * (c[0] - held[0]), 2.0 * (c[1] - held[1])])
                }
                (None, true, None) => (c, trend),
                // No motion pixels: at rest where last seen.
                (None, false, _) if holding => (self.last_measured[i], [0.0; 2]),
                (None, false, _) => (smoother.level(), trend),
            };
            reported.push([base[0] + shift * velocity[0], base[1] + shift * velocity[1]]);
            // With `MeasuredVelocity` or `MeasuredMotion`, a corner measured in
            // this and the previous frame moves on by that displacement.
            let displacement = displacement.filter(|_| self.params.prediction != Prediction::Smoothed);
            self.previous_measured[i] = measured[i].then_some(c);
            if measured[i] {
                self.last_measured[i] = c;
            }
            match displacement {
                Some(v) => {
                    self.trend[i] = v;
                    self.predicted[i] = [c[0] + v[0], c[1] + v[1]];
                }
                None => {
                    self.trend[i] = trend;
                    self.predicted[i] = smoother.forecast(1.0);
                }
            }
        }
        reported
    }

    /// The frame's outcome. Reported corners are finite (SPEC §4): a corner
    /// that is not (a diverged measurement or prediction) is reported at its
    /// last reported position and makes the frame lost, with the reason.
    fn outcome(
        &mut self,
        frame: usize,
        mut status: Status,
        mut corners: Vec<[f64; 2]>,
        m: Measurement,
        mut lost_reason: Option<String>,
    ) -> FrameOutcome {
        if let Some(i) = super::hold_finite_corners(&mut corners, &mut self.last_reported) {
            status = Status::Lost;
            let reason = format!("corner {i} is not a finite number; reported at its last position");
            lost_reason = Some(super::add_lost_reason(lost_reason, reason));
        }
        // Verification: the contour about to be reported must have edge support,
        // on the whole and on every side.
        let support = self.support_map.as_ref().map(|map| {
            let segments: Vec<([f64; 2], [f64; 2])> =
                self.edges.iter().map(|&[i, j]| (corners[i], corners[j])).collect();
            let sides = map.support_by_segment(&segments, self.params.support_distance, self.params.delta);
            let total = support::total(&sides);
            // A side too short to sample has no support: the outline collapsed.
            let weakest = sides.iter().map(|&side| support::fraction(side)).fold(1.0, f64::min);
            (support::fraction(total), weakest)
        });
        let contour_support = support.map(|(total, _)| total);
        let side_support = support.map(|(_, weakest)| weakest);
        // After a loss the outline must fit the image's edges as a frame on
        // target does, nearly everywhere.
        let (min_support, min_side_support) = if self.lost_run > 0 {
            (self.params.reacquire_min_support, self.params.reacquire_min_support)
        } else {
            (self.params.min_support, self.params.min_side_support)
        };
        if status == Status::Tracking
            && let Some((total, weakest)) = support
            && !(total >= min_support && weakest >= min_side_support)
        {
            status = Status::Lost;
            if self.phase == Phase::Tracking {
                self.phase = Phase::Lost;
            }
            lost_reason = Some(format!(
                "contour support {:.0} % (at least {:.0} %), weakest side {:.0} % (at least {:.0} %): the reported outline is not on image edges",
                100.0 * total,
                100.0 * min_support,
                100.0 * weakest,
                100.0 * min_side_support
            ));
        }
        if status == Status::Tracking {
            self.last_tracked.clone_from(&corners);
            self.lost_run = 0;
        } else {
            self.lost_run += 1;
        }
        let diagnostics = Diagnostics {
            points_per_line: m.labelling.sums.iter().map(LineSums::count).collect(),
            line_fitted: m.fitted.iter().map(Option::is_some).collect(),
            corner_measured: m.measured,
            max_corner_deviation: m.deviation,
            unexplained_points: m.labelling.unexplained_total,
            contour_support,
            side_support,
            lost_reason,
            bands: Vec::new(),
        };
        FrameOutcome {
            frame,
            status,
            phase: self.phase,
            corners,
            pose: None,
            params: None,
            covariance: None,
            labelled: m.labelling.pixels,
            diagnostics,
        }
    }
}

impl Tracker for MotionEdgeTracker {
    fn name(&self) -> &'static str {
        "motion-edge"
    }

    fn accept_frame_size(&mut self, width: usize, height: usize) -> std::result::Result<(), String> {
        match *self.frame_size.get_or_insert((width, height)) {
            (w, h) if (w, h) == (width, height) => Ok(()),
            (w, h) => Err(format!("{width}x{height}, but the sequence's first frame was {w}x{h}")),
        }
    }

    fn window_of_interest(&self, width: usize, height: usize) -> Window {
        MotionEdgeTracker::window_of_interest(self, width, height)
    }

    /// Smoothing σ and the motion threshold of eq. 1 from the parameters;
    /// motion pixels inside the window of interest, uncapped (000 labels
    /// every motion pixel it gets); with `verify`, the edge pixels of the
    /// smoothed frame in the same window for the verification.
    fn request(&self, width: usize, height: usize) -> FrameRequest {
        FrameRequest {
            smoothing: GaussianParams { sigma: self.params.sigma },
            motion: Some(MotionRequest {
                diff: TemporalDiffParams { threshold: self.params.motion_threshold },
                list: ListSpec {
                    window: MotionEdgeTracker::window_of_interest(self, width, height),
                    cap: None,
                    seed: 0,
                },
            }),
            edges: (self.params.verify || self.params.held_line_edges).then(|| EdgeRequest {
                threshold: self.params.support_edge_threshold,
                smoothed: true,
                list: ListSpec {
                    window: MotionEdgeTracker::window_of_interest(self, width, height),
                    cap: None,
                    seed: 0,
                },
            }),
            ..FrameRequest::default()
        }
    }

    fn track(&mut self, frame: usize, observations: &Observations<'_>) -> FrameOutcome {
        self.update_with_edges(frame, observations.motion.unwrap_or(&[]), observations.edges)
    }
}

/// The two edges at every corner, checked: indices in range, no repeated
/// edge, exactly two edges per corner, and non-parallel lines at each corner.
fn corner_lines_of(corners: &[[f64; 2]], edges: &[[usize; 2]]) -> Result<Vec<[usize; 2]>> {
    fn bad<T>(msg: String) -> Result<T> {
        Err(Error::Parameter(format!("motion-edge model: {msg}")))
    }
    if corners.len() < 3 {
        return bad(format!("a planar polygon needs at least 3 corners, got {}", corners.len()));
    }
    if let Some(i) = corners.iter().position(|c| !(c[0].is_finite() && c[1].is_finite())) {
        return bad(format!("corner {i} is not finite"));
    }
    let mut incident: Vec<Vec<usize>> = vec![Vec::new(); corners.len()];
    for (k, &[i, j]) in edges.iter().enumerate() {
        if i >= corners.len() || j >= corners.len() {
            return bad(format!("edge {k} [{i}, {j}] names a corner beyond the {} given", corners.len()));
        }
        if i == j {
            return bad(format!("edge {k} joins corner {i} to itself"));
        }
        if edges[..k].iter().any(|&[a, b]| (a, b) == (i, j) || (a, b) == (j, i)) {
            return bad(format!("edge {k} [{i}, {j}] is listed twice"));
        }
        incident[i].push(k);
        incident[j].push(k);
    }
    let lines = model_lines(corners, edges);
    incident
        .iter()
        .enumerate()
        .map(|(c, ks)| {
            let &[k1, k2] = ks.as_slice() else {
                return bad(format!("corner {c} is on {} edges; a planar polygon has exactly 2 per corner", ks.len()));
            };
            match (lines[k1], lines[k2]) {
                (Some(l1), Some(l2)) if l1.line.intersection(&l2.line).is_some() => Ok([k1, k2]),
                _ => bad(format!("the edges at corner {c} are degenerate or parallel")),
            }
        })
        .collect()
}

/// Where the next band is forecast: per corner, its centre and the step
/// that takes it there, px.
#[derive(Clone, Debug)]
struct Forecast {
    corners: Vec<[f64; 2]>,
    steps: Vec<[f64; 2]>,
}

/// The signed turn from orientation `from` to `to` (both undirected, in
/// [0, π)), in [−π/2, π/2).
fn signed_turn(from: f64, to: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    (to - from + FRAC_PI_2).rem_euclid(PI) - FRAC_PI_2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::line_fit::fit_line;
    use std::f64::consts::FRAC_PI_2;

    fn feature(x: u32, y: u32, theta: f64) -> Feature {
        Feature { x, y, theta: theta as f32, magnitude: 100.0 }
    }

    fn square_lines() -> Vec<Option<ModelLine>> {
        // Square 10..50: top, right, bottom, left.
        let c = [[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
        model_lines(&c, &[[0, 1], [1, 2], [2, 3], [3, 0]])
    }

    #[test]
    fn labelling_applies_eq_3_and_eq_4() {
        let lines = square_lines();
        let tol = vec![LineTolerance { distance: 3.0, extent: 3.0, trim: -3.0 }; 4];
        let delta = 15f64.to_radians();
        let motion = [
            feature(30, 11, 0.0),                        // top line, right angle: labelled to 0
            feature(30, 12, std::f64::consts::PI - 0.1), // θ ≈ π is the same line as 0: labelled to 0
            feature(30, 11, FRAC_PI_2),                  // wrong angle: discarded
            feature(30, 16, 0.0),                        // right angle, 6 px away: discarded
            feature(49, 30, FRAC_PI_2),                  // right line: labelled to 1
            feature(90, 10, 0.0),                        // on the top line's extension, beyond its extent
        ];
        let mut weak = feature(30, 10, 0.0);
        weak.magnitude = 0.0;
        let mut all = motion.to_vec();
        all.push(weak);
        let l = label_motion_pixels(&all, &lines, &tol, delta, 1.0);
        assert_eq!(l.pixels[0], vec![(30, 11), (30, 12)]);
        assert_eq!(l.pixels[1], vec![(49, 30)]);
        assert!(l.pixels[2].is_empty() && l.pixels[3].is_empty());
        // Unexplained evidence: the two far horizontal pixels count for both
        // horizontal lines (0, 2), the vertical one at (30, 11) for both
        // vertical lines (1, 3); the weak pixel counts for nothing.
        assert_eq!(l.unexplained, vec![2, 1, 2, 1]);
        assert_eq!(l.unexplained_total, 3);
    }

    #[test]
    fn labelling_picks_the_nearest_matching_line() {
        // Two parallel horizontal lines 4 px apart, tolerance 3: a pixel 1 px
        // from the second goes to the second.
        let lines = vec![ModelLine::between([0.0, 10.0], [40.0, 10.0]), ModelLine::between([0.0, 14.0], [40.0, 14.0])];
        let tol = vec![LineTolerance { distance: 3.0, extent: 0.0, trim: 0.0 }; 2];
        let l = label_motion_pixels(&[feature(20, 13, 0.0)], &lines, &tol, 0.2, 0.0);
        assert!(l.pixels[0].is_empty());
        assert_eq!(l.pixels[1], vec![(20, 13)]);
    }

    #[test]
    fn corners_are_intersections_of_fitted_or_predicted_lines() {
        let lines: Vec<Option<Line>> = square_lines().iter().map(|l| l.map(|l| l.line)).collect();
        let predicted = [[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
        let corner_lines = [[3, 0], [0, 1], [1, 2], [2, 3]];
        // Only the left line is fitted, at x = 12.
        let mut sums = LineSums::new();
        for y in 10..=50 {
            sums.add(12.0, f64::from(y));
        }
        let fitted = vec![None, None, None, fit_line(&sums)];
        let (corners, measured) = intersect_corners(&fitted, &lines, &predicted, &corner_lines);
        assert_eq!(measured, vec![true, false, false, true]);
        assert!((corners[0][0] - 12.0).abs() < 1e-9 && (corners[0][1] - 10.0).abs() < 1e-9);
        assert!((corners[3][0] - 12.0).abs() < 1e-9 && (corners[3][1] - 50.0).abs() < 1e-9);
        assert_eq!(corners[1], predicted[1]);
        let d = corner_deviation(&corners, &measured, &predicted).expect("measured");
        assert!((d - 2.0).abs() < 1e-9);
        assert_eq!(corner_deviation(&corners, &[false; 4], &predicted), None);
    }

    #[test]
    fn params_are_validated_and_read_from_toml() {
        assert!(MotionEdgeParams::default().validate().is_ok());
        for bad in [
            MotionEdgeParams { zeta: 0.0, ..Default::default() },
            MotionEdgeParams { alpha: 1.0, ..Default::default() },
            MotionEdgeParams { delta: 2.0, ..Default::default() },
            MotionEdgeParams { epsilon: f64::NAN, ..Default::default() },
            MotionEdgeParams { min_points_per_line: 1, ..Default::default() },
            MotionEdgeParams { vanished_motion: f64::NAN, ..Default::default() },
        ] {
            assert!(matches!(bad.validate(), Err(Error::Parameter(_))), "{bad:?}");
        }
        let p: MotionEdgeParams =
            toml::from_str("zeta = 3.0\nlag_correction = false\nmissing = \"last-measurement\"").expect("toml");
        assert_eq!(p.zeta, 3.0);
        assert!(!p.lag_correction);
        assert_eq!(p.missing, MissingMeasurement::LastMeasurement);
        assert_eq!(p.epsilon, 20.0);
        assert!(toml::from_str::<MotionEdgeParams>("zetta = 3.0").is_err(), "typos are refused");
    }

    #[test]
    fn bad_models_are_refused() {
        let square = vec![[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
        let p = MotionEdgeParams::default;
        assert!(MotionEdgeTracker::new(square.clone(), vec![[0, 1], [1, 2], [2, 3], [3, 0]], p()).is_ok());
        assert!(MotionEdgeTracker::new(square.clone(), vec![[0, 1], [1, 2], [2, 3]], p()).is_err());
        assert!(MotionEdgeTracker::new(square.clone(), vec![[0, 1], [1, 2], [2, 3], [3, 9]], p()).is_err());
        assert!(MotionEdgeTracker::new(square.clone(), vec![[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]], p()).is_err());
        let collinear = vec![[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]];
        assert!(MotionEdgeTracker::new(collinear, vec![[0, 1], [1, 2], [2, 0]], p()).is_err());
    }

    #[test]
    fn window_is_the_clipped_bounding_box_plus_margin() {
        let square = vec![[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
        let params = MotionEdgeParams { window_margin: 2.0, init_tolerance: 4.0, ..Default::default() };
        let t = MotionEdgeTracker::new(square, vec![[0, 1], [1, 2], [2, 3], [3, 0]], params).expect("tracker");
        // Acquiring: margin 2 + 4 = 6 → columns 4..=56, rows 4..=56.
        assert_eq!(t.window_of_interest(640, 480), Window { x0: 4, y0: 4, x1: 57, y1: 57 });
        assert_eq!(t.window_of_interest(30, 20), Window { x0: 4, y0: 4, x1: 30, y1: 20 });
    }

    #[test]
    fn frame_zero_without_motion_reports_the_operator_corners() {
        let square = vec![[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
        let mut t = MotionEdgeTracker::new(square.clone(), vec![[0, 1], [1, 2], [2, 3], [3, 0]], Default::default())
            .expect("tracker");
        let out = t.update(0, &[]);
        assert_eq!(out.status, Status::Tracking);
        assert_eq!(out.phase, Phase::Acquiring);
        assert_eq!(out.corners, square);
        assert_eq!(out.labelled.len(), 4);
    }

    /// A prediction that is not finite (a diverged state) gives a lost
    /// frame whose corners are the last reported ones, never NaN.
    #[test]
    fn corners_that_are_not_finite_are_reported_at_their_last_position() {
        let square = vec![[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
        let mut t = MotionEdgeTracker::new(square.clone(), vec![[0, 1], [1, 2], [2, 3], [3, 0]], Default::default())
            .expect("tracker");
        assert_eq!(t.update(0, &[]).corners, square);
        t.phase = Phase::Tracking;
        t.predicted[2] = [f64::NAN, 50.0];
        t.last_measured[2] = [f64::NAN, 50.0];
        let out = t.update(1, &[]);
        assert!(out.corners.iter().flatten().all(|v| v.is_finite()), "{:?}", out.corners);
        assert_eq!(out.corners[2], square[2]);
        assert_eq!(out.status, Status::Lost);
        assert!(out.diagnostics.lost_reason.is_some_and(|r| r.contains("corner 2")));
        let mut bad = square.clone();
        bad[1][0] = f64::INFINITY;
        assert!(MotionEdgeTracker::new(bad, vec![[0, 1], [1, 2], [2, 3], [3, 0]], Default::default()).is_err());
    }
}
