//! The `lowe` tracker (paper 001, Lowe 1992): the 6-DOF pose and joint
//! parameters of an articulated polyhedron, from straight line segments of
//! the LoG zero crossings, matched by probability and a best-first search,
//! fitted by stabilised Gauss–Newton.
//!
//! # Each frame
//! 1. **Prediction** by velocity extrapolation from the two previous
//!    solutions (the rotation and the centre's displacement of the last
//!    frame interval applied once more; joints likewise, within their
//!    limits), with a prior standard deviation per parameter
//!    (`prior_rotation_sigma`, `prior_translation_px`, `prior_joint_sigma`).
//!    A joint's step is its last one between two frames whose matches both
//!    measured it (σ in P below 0.9 of `prior_joint_sigma`; our
//!    addition): where no match constrains a joint
//!    its value is the prior's, and a step from or to such a value is not
//!    the part's motion. Extrapolated, such a step (a lid under an occluder,
//!    unmeasured on one frame, loosely fitted 4° back on the next) puts the
//!    lid 13–32° off over the four frames that do not see it (hinged box
//!    half hidden at 10 px/frame, seed 0). Nor is a jump to another joint
//!    value (step 9): it corrects the fit, and the joint's step starts
//!    again from zero. Extrapolated, a lid found again 62° open after
//!    eight frames held shut on the box's rim was carried to its upper
//!    limit, 45° beyond it, and left there unmeasured (half hidden at
//!    20 px/frame, seed 14).
//! 2. **Features** ([`segments`]): LoG σ = 1.2 zero crossings in a window
//!    around the predicted model, linked with hysteresis, cut into
//!    straight segments, indexed by midpoint and orientation. The window
//!    is wide enough for the largest search range, or, after a frame
//!    verified with `confident_support` (or the steady bar of step 6) at
//!    its first range, for
//!    `confident_window_doublings` (our addition; the first range by
//!    default), each vertex's reach along x and y bounded on its own. A
//!    frame whose narrowed window gives no solution with
//!    `confident_support` (or that bar) widens it and is searched again in the wider
//!    window ([`Tracker::track_or_widen`]; through [`Tracker::track`] the
//!    wider ranges are searched in the narrowed window's features).
//!    The wider ranges are seldom needed after a confident frame, and the
//!    early vision and segments of the narrow window take half the time
//!    or less.
//! 3. **Visible model** at the prediction: back-face test and hidden-line
//!    removal ([`crate::geometry::hidden_lines`]), and each visible part of
//!    an edge clipped to the image ([`projection::clip_to_image`]: a part
//!    beyond the border can be neither matched nor supported); each is a
//!    model segment ([`projection`]).
//! 4. **Candidates** ([`matching`]): for each model segment the index is
//!    queried within `search_sigmas` of its predicted position and
//!    orientation (S = A P Aᵀ, eq. 2) and every hit gets its probability of
//!    correctness (eq. 3).
//! 5. **Too few candidates** (fewer model segments with one than a search
//!    node needs): the prior ranges double and step 4 repeats, up to
//!    `range_doublings` times (001: twice). A search that finds no
//!    acceptable set also doubles the ranges ("increase the search range
//!    when the system is unable to find the object").
//! 6. **Best-first search and locking on** ([`search`]), each solution a
//!    stabilised Gauss–Newton fit ([`estimation`], eq. 1); with
//!    `remember_contrast`, each verified frame's matches (of a frame with
//!    at least `remember_contrast_min_support` of its outline supported)
//!    add to the contrast memory of their edges that locking on consults
//!    ([`search`], step 4). A verified solution (step 7) whose outline support is below
//!    `confident_support` does not end the search (our addition): the
//!    wider ranges are searched as well, and the first verified solution
//!    there with that support replaces it. At an abrupt reversal the first range's best set can fit
//!    a model 10–16 px off whose outline is 30–45 % supported, where the
//!    doubled range finds the true pose at 90 % and more. A solution of a
//!    wider range that is not that confident replaces the first one when
//!    it clears the bar of a re-acquisition (`search_min_support`,
//!    `search_min_coverage`) with more of its outline supported and more
//!    matches: at 20 px/frame with noise σ 8 the first range fitted a
//!    closing lid 11–17° off (47–56 % support, 19–22 matches) on four
//!    frames where the doubled range had it within 3° (72–83 %, 26).
//!    While tracking, when no range gives a solution with
//!    `confident_support`, the search runs again from two slower
//!    predictions (our addition, `search_slower_predictions`): the last
//!    solution itself and the last solution moved by half its velocity. At
//!    an abrupt reversal the extrapolated prediction lies twice the last
//!    step from the object, and the search there either fails or fits
//!    clutter; a confident solution from a slower prediction, with more of
//!    its outline supported and no fewer matches, replaces it. After a
//!    frame that was not confident itself, the second look is made only
//!    when the answer is unverified or lost a tenth of that frame's
//!    support: an object whose outline is steadily part supported is not
//!    searched twice on every frame. With `steady_support_ratio` (our
//!    addition, off by default), nor in the widest window: after a
//!    claimed frame whose search of every range kept its first range's
//!    answer short of `confident_support`, that share of its support
//!    stands in for `confident_support` (when lower) in narrowing the
//!    window (step 2) and in widening it, for an answer whose model
//!    vertices lie on average within `ambiguous_distance_px` of the
//!    prediction's (the answer the motion predicts). Every range is
//!    still searched, in the narrowed window's features; a frame short of
//!    that bar widens the window and is searched again, its support the
//!    new reference. This holds only after a frame claimed with
//!    `confident_support` since the start and since the last frame not
//!    claimed (lost, ambiguous, or waiting for a claim, step 11). Without
//!    that condition (and with the search ended at the first range and no
//!    distance from the prediction asked), 24 frames of ViSP's real
//!    `rbt/sequence` (never confident after frame 20) were reported
//!    tracking more than 25 px off the cube, against none (RESULTS.md).
//! 7. **Verification**: the frame is `tracking` only when a set was
//!    accepted (its residual passes), locking on added at least one match
//!    to the node's (a node of ⌊n/2⌋ + 1 matches leaves one or two redundant
//!    measurements for n parameters, and a wrong node fits them: on `box`
//!    at 25–30 px/frame, 8 frames 12–32 px off had only the node's 4
//!    matches, no frame on target did), it is not a loose fit on few matches
//!    (at most `loose_fit_extra_matches` more than the node's, with a
//!    residual σ above `loose_fit_residual_ratio` measurement σ: a box half
//!    hidden, fitted to the wrong edges, kept 5–7 matches at 1.5–2.2 px),
//!    its matched image segments cover at least `min_coverage` of the
//!    visible model edges' length, and at least `min_support` of that
//!    length has a zero crossing along it (within 1 px across, at an edge
//!    orientation within 20°: [`crate::track::support`]; two model edges on
//!    one image line, as a shut lid's front on the box's rim, count once;
//!    with `remember_contrast`, along an edge whose contrast is remembered
//!    only crossings of that contrast count: [`evidence`]).
//!    The second test is independent of the matching: a few long clutter
//!    segments can cover a quarter of a model put in the wrong place, but
//!    the rest of its outline then runs over nothing. Otherwise it is
//!    `lost`: the output carries the prediction, which coasts on the last
//!    velocity while the model's centre stays in the image at a depth
//!    within a factor 1.5 of the last verified one (else it stands at the
//!    last verified state), and the next frame starts its search at the
//!    widest range.
//!    While tracking, a solution found only after the prior ranges were
//!    doubled must also have at least `widened_support_ratio` of the last
//!    frame's support (our addition): the prediction missed, and an outline
//!    does not lose most of its support in the same frame as it moves
//!    unexpectedly. An occluder that appears takes half the support at
//!    once, but then the prediction holds and the first range finds the
//!    model. On the box at 25–30 px/frame the first frame of most losses
//!    after an abrupt reversal was a doubled range's solution 8–17 px off
//!    with 27–56 % of its outline supported, against 76–94 % a frame
//!    before.
//!    After a loss the coverage must reach `search_min_coverage` and the
//!    support `search_min_support` instead, whichever search found the
//!    solution: re-acquisition is a claim about a new place, with dozens of
//!    places tried. Its matches must also fix the orientation: no rotation
//!    parameter's standard deviation in P (eq. 2) above
//!    `search_max_rotation_sigma` (our addition). A box seen face on is a
//!    rectangle, and a rectangle of the background fits it with the tilt
//!    barely fixed: with the box hidden behind an occluder, such fits were
//!    taken 98–143 px from the box with 73–88 % of the outline supported,
//!    their rotation σ 3–8° where re-acquisitions on target had at most
//!    0.9°.
//!    While tracking, the bound is looser: no rotation σ above twice
//!    `prior_rotation_sigma` (our addition). The prior alone keeps a
//!    solution of the first range or of a range doubled once below that;
//!    one of the twice-doubled range (prior σ four times as wide) above
//!    it has matches that barely fix the orientation. A box half hidden
//!    behind a band, its sides hidden, slid 19–47 px along the band's
//!    edges from such a solution (rotation σ 7.0°; 10 px/frame, seed 8)
//!    and was reported tracking for four frames. Over the 180 stress runs
//!    of RESULTS.md the largest rotation σ of a frame on target was 4.3°.
//! 8. **Whole-image search** (our addition; the paper only widens the
//!    ranges): after `search_after` lost frames the window of interest is
//!    the whole frame and, when the search at the prediction fails, the
//!    last verified state is moved across the image on a grid as wide as
//!    the widest search reaches (3 σ of the doubled translation prior) and
//!    searched at each position; of the verified solutions the one whose
//!    outline has the most zero crossings along it is taken when it passes
//!    those thresholds. The same grid is searched with the model at each of
//!    up to four remembered views: verified states of earlier frames whose
//!    orientations lie at least 20° from each other's (and from the last
//!    verified one's), the oldest replaced first. A model lost while it
//!    turns quickly is found again when it shows a side seen before, not
//!    only the last one: at 30 px/frame a box lost for 41 frames while it
//!    turned away from the last verified orientation is now lost for 3.
//!    At each position of the grid, a model with joints is searched with
//!    the joint values of step 9's grid whose outline has the most zero
//!    crossings along it, when that beats the state's own values by step
//!    9's margin: the lid of a hinged box lost at 30 px/frame swings by
//!    up to 86° in ten frames, and from the last verified lid angle the
//!    search found the box again only where the lid came back near it
//!    (seed 10: lost for 33 and 34 frames; with the grid's lid angles, for
//!    10 and 6).
//!    After a loss the velocity starts again from zero.
//! 9. **Other joint values** (our addition): a joint's part can fold onto
//!    another part (a shut lid's edges lie on the box's rim), and the fit
//!    then stays there while the part opens again. After every verified
//!    solution of a model with joints, each joint is set to values across
//!    its range (the pose and the other joints held), the two whose outline
//!    has the most zero crossings along it are searched from, and a
//!    verified solution at least 0.2 rad away replaces the frame's when its
//!    outline has 5 % + 10 % per radian moved more supported samples (the
//!    radians counted from the frame's fit or from the prediction,
//!    whichever is nearer: a part that folded onto another, away from
//!    where its motion was taking it, earns no margin from the fold), at a
//!    supported fraction no lower, and every joint it moved is measured
//!    there (its σ below 0.9 of `prior_joint_sigma`): a lid hidden by an
//!    occluder, searched from its limit, stays at the limit with no match
//!    to move it, and the box's outline alone must not place it. It must
//!    also match more image segments than the frame's solution: a part
//!    moved onto clutter gains supported samples but loses the matches of
//!    its own edges (hinged box, noise σ 8, an opening lid seen nearly edge
//!    on: its own fit 2° off with 28 matches and 53 % support lost to the
//!    lid 35° away with 18 matches and 60 %, and the velocity that jump
//!    left carried the lid to its limit for eight frames).
//!    The fold can also go the other way: the part's outline, well fitted,
//!    is taken for the part at another value on a body turned about the
//!    joint. On the hinged box at 30 px/frame, seed 6, frames 77–81, the
//!    lid open 14–43° was fitted as the lid shut on a box turned about the
//!    hinge (the model 9–26 px off), with a third or less of the box's own
//!    outline supported. So each value of the grid is also tried with the
//!    part the joint moves held where it is and the rest of the model
//!    swung about the joint (the joint's *swing*, for a joint whose axis no
//!    other joint moves). When the frame's solution has less than
//!    `confident_support`, the best supported swing whose outline beats
//!    the frame's by the margin above is searched from as well, and its
//!    solution replaces the frame's on the same terms.
//! 10. **An ambiguous answer** (our addition): the frame's searches (the
//!     wider ranges and slower predictions of step 6, the whole-image
//!     search of step 8, the other joint values of step 9) can give
//!     verified solutions other than the answer that are nearly as well
//!     supported. When one of them has at least `ambiguous_match_ratio`
//!     of the answer's matches (1: as many), at least
//!     `ambiguous_support_ratio` of the answer's supported outline samples
//!     and the model's vertices on average more than `ambiguous_distance_px`
//!     from the answer's, the image supports two different answers about
//!     equally: the frame is reported `lost`, its reason naming the rival,
//!     and the answer is still carried to the next frame as a verified one
//!     (its velocity, window and bars are those of tracking). A rival with
//!     at least `ambiguous_carry_ratio` of the answer's supported samples
//!     is carried on in the answer's place (its pose, joint values,
//!     covariance and visible model; the joints it moved by a jump of
//!     step 9 start from no velocity). The hinged box
//!     half hidden at 20 px/frame, seed 14, held its lid shut on the box's
//!     rim for eight frames while the lid opened 15–53° behind the band,
//!     7–32 px off; on seven of them a search from the lid open gave a
//!     verified solution with as many matches and as much support or more.
//!     The box half hidden at 20 px/frame, seed 25, was fitted 8–11 px off
//!     on frames 191, 193 and 194 as it turned behind the band, while other
//!     searches of the same frames gave verified solutions within 4 px of
//!     it with more support and matches.
//! 11. **Claims after an ambiguous answer** (our addition): an ambiguous
//!     frame's answer may be the wrong one of the two, and carried on it
//!     leads the next frames away from the object while each of them, on
//!     its own, passes the verification. So after an ambiguous frame the
//!     answers are carried on as before but reported `lost` until one has
//!     at least `reclaim_support_ratio` of the outline support of the last
//!     frame reported `tracking` (before the first ambiguous frame of the
//!     run; when no frame was reported `tracking` before it, as when the
//!     first frames are ambiguous, there is no such support to reach), or
//!     `reclaim_after_frames` unambiguous answers follow in a row;
//!     a frame lost for want of a solution ends the wait (a re-acquisition
//!     has its own bars, step 7). Only statuses change: poses, windows and
//!     velocities are those of the answers. On ViSP's real `rbt/sequence`
//!     video a hand-held camera turns a textured cube whose pictures'
//!     borders run parallel to its edges; from frame 20, a run of
//!     ambiguous frames carried the answer off the cube, and 12 answers
//!     between them, 25–125 px off with 26–48 % of their outline supported,
//!     were reported `tracking` where frame 19 had 59 % (RESULTS.md).
//!
//! Output per frame: status, `corners` (every model vertex projected),
//! `pose`, `params` (joint values) and the covariance P of the correction
//! parameters (ω about the camera axes through the model's centre, rad; the
//! centre's displacement, m; the joints, rad; see [`projection`]).

pub mod estimation;
pub mod evidence;
#[cfg(test)]
mod fixtures;
pub mod matching;
pub mod params;
pub mod projection;
pub mod search;
pub mod segments;

use std::cell::RefCell;

use glam::DVec3;

pub use params::LoweParams;

use self::estimation::{Matrix, Problem};
use self::evidence::CrossingMap;
use self::matching::{Candidate, Endpoints, MatchContext, ModelLine, SegmentSpread, search_bounds};
use self::params::MAX_PARAMS;
use self::projection::{Linearised, ModelSegment, Row, State};
use self::search::{SearchFrame, SearchSettings, Support, segments_needed};
use self::segments::{ImageSegment, SegmentExtractor, SegmentIndex};
use super::{Diagnostics, FrameExtras, FrameOutcome, Observations, Phase, Tracked, Tracker, support};
use crate::backend::{FrameRequest, ListSpec, ZeroCrossingRequest};
use crate::early::Window;
use crate::early::log::LogParams;
use crate::early::zero_crossing::ZeroCrossingParams;
use crate::geometry::{Camera, ModelGeometry, Pose, mean_point_distance};
use crate::io::formats::{self, InitState, Model, Status};
use crate::io::overlay::EdgeBand;
use crate::{Error, Result};

/// Model segments shorter than this in the image are not matched, px.
const MIN_MODEL_SEGMENT_PX: f64 = 4.0;

/// While tracking, a solution's rotation standard deviations in P are at
/// most this many times `prior_rotation_sigma` (module doc, step 7).
const TRACKING_ROTATION_SIGMA_PRIORS: f64 = 2.0;

/// What the tracker reports beyond the common diagnostics.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoweDiagnostics {
    /// Image segments found in the window.
    pub image_segments: usize,
    /// Search nodes tried this frame, over all ranges (and both searches
    /// of a frame whose window was widened).
    pub branches: usize,
    /// Times the prior ranges were doubled this frame.
    pub doublings: usize,
    /// Matches of the accepted solution.
    pub matches: usize,
    /// Residual σ of the accepted solution, px.
    pub residual_sigma: Option<f64>,
    /// Fraction of the visible model edges' length covered by matches.
    pub coverage: f64,
    /// Fraction of the visible model edges' length with a zero crossing
    /// along it.
    pub support: f64,
    /// Host time of linking, segmentation and indexing, ms.
    pub segments_ms: f64,
    /// Host time of visibility, candidates and the search, estimation
    /// excluded, ms.
    pub matching_ms: f64,
    /// Host time of the Gauss–Newton solutions, ms.
    pub estimation_ms: f64,
}

impl LoweDiagnostics {
    /// The host times of a search that started at `started` and had its
    /// segments at `segmented`: linking and segmentation, Gauss–Newton
    /// (taken from its timer), and the rest of the time since as matching.
    fn time_since(&mut self, started: std::time::Instant, segmented: std::time::Instant) {
        self.segments_ms = (segmented - started).as_secs_f64() * 1e3;
        self.estimation_ms = estimation::take_solve_time().as_secs_f64() * 1e3;
        self.matching_ms = (segmented.elapsed().as_secs_f64() * 1e3 - self.estimation_ms).max(0.0);
    }

    /// The host times of `earlier`, a search of the same frame before its
    /// window was widened, added to these.
    fn add_earlier_times(&mut self, earlier: &LoweDiagnostics) {
        self.segments_ms += earlier.segments_ms;
        self.matching_ms += earlier.matching_ms;
        self.estimation_ms += earlier.estimation_ms;
    }
}

/// The Lowe tracker.
#[derive(Debug)]
pub struct LoweTracker {
    camera: Camera,
    geometry: ModelGeometry,
    centre: DVec3,
    limits: Vec<[f64; 2]>,
    params: LoweParams,
    extractor: SegmentExtractor,
    index: SegmentIndex,
    image_segments: Vec<ImageSegment>,
    crossing_map: CrossingMap,
    /// The last accepted solution and the one before it.
    last: State,
    before_last: Option<State>,
    /// The last verified solution (where the whole-image search starts).
    last_tracked: State,
    /// Per joint, the step the prediction extrapolates: its last step
    /// between two verified frames that both measured it (module doc, step 1).
    joint_velocity: Vec<f64>,
    /// Per joint, whether the last verified frame measured it.
    joint_measured: Vec<bool>,
    /// This frame's prediction.
    prediction: State,
    /// Doubling the next frame's search starts at.
    first_doubling: usize,
    /// Consecutive frames lost up to the last one.
    lost_frames: usize,
    phase: Phase,
    /// Window of interest around this frame's prediction.
    window: Window,
    /// Doublings of the prior ranges the window is sized for.
    window_doublings: usize,
    /// Whether the window was narrowed after an answer that reached a
    /// steady bar: every range is searched in it (module doc, step 6).
    window_all_ranges: bool,
    /// The diagnostics of this frame's search before its window was
    /// widened, added to the frame's.
    before_widening: Option<LoweDiagnostics>,
    last_diagnostics: LoweDiagnostics,
    /// Verified states at orientations at least [`VIEW_GAP_RAD`] apart, the
    /// oldest first (where the whole-image search also starts).
    views: Vec<State>,
    /// Per model edge, the contrast its matches have shown (module doc of
    /// [`search`], step 4).
    contrast_memory: Vec<EdgeContrast>,
    /// Whether answers are claimed again after an ambiguous one (module
    /// doc, step 11).
    reclaim: Reclaim,
    /// The steady support that may lower the bar of confidence (module
    /// doc, step 6).
    steady: Steady,
}

/// Step 6 of the module doc: the bar of confidence of an object steadily
/// part supported (`steady_support_ratio`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Steady {
    /// The outline support of the last claimed frame whose search of
    /// every range kept its first range's answer, short of
    /// `confident_support`.
    support: Option<f64>,
    /// Whether a frame has been claimed with `confident_support` since the
    /// start, the last frame not claimed (lost, ambiguous, or waiting for
    /// a claim after an ambiguous one): only then is a steady support kept.
    confident_since_doubt: bool,
}

impl Steady {
    /// The support that keeps the window narrow: `confident`, or `ratio`
    /// of the steady support when lower.
    fn bar(&self, confident: f64, ratio: f64) -> f64 {
        self.support.map_or(confident, |steady| confident.min(ratio * steady))
    }

    /// The frame's outcome: the outline support of a `claimed` answer
    /// (`None`: not claimed), whether it was found at the first range
    /// (`first_range`), and whether it reached a steady bar
    /// (`reached_steady`; an answer that did not had every range searched).
    fn update(&mut self, claimed: Option<f64>, first_range: bool, reached_steady: bool, confident: f64, ratio: f64) {
        self.confident_since_doubt = claimed.is_some_and(|support| self.confident_since_doubt || support >= confident);
        self.support = match claimed {
            Some(support) if self.confident_since_doubt && first_range && support < confident && ratio > 0.0 => {
                match self.support {
                    Some(steady) if reached_steady => Some(steady),
                    _ => Some(support),
                }
            }
            _ => None,
        };
    }
}

/// What keeps a frame's window narrow (module doc, steps 2 and 6): at
/// least `support` of the answer's outline supported and, under a steady
/// bar, its model vertices on average within the given distance (px) of
/// the given projected vertices of the prediction.
#[derive(Clone, Copy, Debug)]
struct Bar<'a> {
    support: f64,
    near: Option<(&'a [[f64; 2]], f64)>,
}

impl Bar<'_> {
    /// Whether an answer with outline support `support` reaches it;
    /// `corners` projects the answer's model vertices, called only under
    /// a steady bar.
    fn reached(&self, support: f64, corners: impl FnOnce() -> Vec<[f64; 2]>) -> bool {
        support >= self.support
            && self.near.is_none_or(|(predicted, px)| mean_point_distance(predicted, &corners()) <= px)
    }
}

/// Step 11 of the module doc: after an ambiguous answer, the answers that
/// follow are claimed (reported `tracking`) again only once one has at
/// least `reclaim_support_ratio` of the outline support of the last
/// claimed frame, or `reclaim_after_frames` unambiguous answers in a row.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Reclaim {
    /// Outline support of the last frame reported `tracking` (`None`
    /// before one).
    claimed_support: Option<f64>,
    /// Since an ambiguous answer and until an answer is claimed again: the
    /// support that claims, and the unambiguous answers since the last
    /// ambiguous one.
    pending: Option<(f64, usize)>,
}

impl Reclaim {
    /// A frame's answer was ambiguous: the support to claim again is
    /// `ratio` of the last claimed frame's (kept from the first ambiguous
    /// frame of a run of them; out of reach when no frame was claimed
    /// yet, 0 when `ratio` is), and the count of unambiguous answers
    /// starts again.
    fn ambiguous(&mut self, ratio: f64) {
        let bar = match self.claimed_support {
            _ if ratio == 0.0 => 0.0,
            Some(support) => ratio * support,
            None => f64::INFINITY,
        };
        let (_, run) = self.pending.get_or_insert((bar, 0));
        *run = 0;
    }

    /// An unambiguous verified answer with outline support `support`:
    /// `Ok` when it is claimed, else the support it needed. `after_frames`
    /// 0 never claims by the count alone.
    fn claim(&mut self, support: f64, after_frames: usize) -> std::result::Result<(), f64> {
        if let Some((bar, run)) = &mut self.pending {
            *run += 1;
            if support < *bar && (after_frames == 0 || *run < after_frames) {
                return Err(*bar);
            }
        }
        self.pending = None;
        self.claimed_support = Some(support);
        Ok(())
    }

    /// The frame was lost: a re-acquisition has its own bars (step 7).
    fn lost(&mut self) {
        self.pending = None;
    }
}

/// Why an answer after an ambiguous one is not claimed (step 11): its
/// outline `support`, the `bar` it needed ([`Reclaim::claim`]; infinite
/// when no frame was claimed before the ambiguous one) and the run of
/// `after_frames` unambiguous answers that would claim instead (0: none).
fn refusal_reason(support: f64, bar: f64, after_frames: usize) -> String {
    let before = if bar.is_finite() { "" } else { ", with no frame claimed before it" };
    let needed = match (bar.is_finite(), after_frames) {
        (true, 0) => format!(", {:.0} % needed", 100.0 * bar),
        (true, k) => format!(", {:.0} % needed (or {k} unambiguous answers in a row)", 100.0 * bar),
        (false, 0) => String::new(),
        (false, k) => format!(" ({k} unambiguous answers in a row needed)"),
    };
    format!("after an ambiguous answer{before}: {:.0} % of the outline supported{needed}", 100.0 * support)
}

/// The contrast a model edge's matches have shown on the verified frames
/// the memory learns from (`remember_contrast_min_support`) with the same
/// faces facing the camera.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct EdgeContrast {
    /// [`ModelSegment::facing`] of the edge on those frames.
    facing: u8,
    /// The matched image segments' lengths, px, signed by the side of the
    /// model segment they are dark on (+ along its normal), summed over
    /// the frames whose matches of the edge all had one contrast, each
    /// learning frame's weight [`CONTRAST_MEMORY_DECAY`] times the next
    /// one's (frames it does not learn from do not fade it).
    dark_side_px: f64,
}

/// Weight of a learning frame's contrast evidence against the next one's.
const CONTRAST_MEMORY_DECAY: f64 = 0.9;
/// Least remembered length, px, for an edge's contrast to count as known.
const CONTRAST_MEMORY_MIN_PX: f64 = 20.0;

impl LoweTracker {
    /// Errors on a model the tracker cannot use: not in metres, more than
    /// [`params::MAX_JOINTS`] joints, or no edges. [`LoweTracker::new`]
    /// checks it first; a caller that read the model from a file calls it
    /// to name that file.
    pub fn check_model(model: &Model) -> Result<()> {
        if model.units != "m" {
            return Err(Error::Parameter(format!(
                "lowe tracks a 3-D model in metres (\"units\": \"m\"); this one is in {:?}",
                model.units
            )));
        }
        let joints = model.joints.len();
        if joints > params::MAX_JOINTS {
            return Err(Error::Parameter(format!(
                "lowe tracks at most {} joints; the model has {joints}",
                params::MAX_JOINTS
            )));
        }
        if model.edges.is_empty() {
            return Err(Error::Parameter("lowe needs a model with edges".into()));
        }
        Ok(())
    }

    /// A tracker of `model` seen by `camera`, starting at `init`'s pose and
    /// joint values. Errors on a model the tracker cannot use
    /// ([`LoweTracker::check_model`]) and on an `init` without a pose, with
    /// the wrong number of joint values or one outside its joint's limits,
    /// or whose pose puts the model's centre or any vertex at or behind the
    /// camera.
    pub fn new(camera: Camera, model: &Model, init: &InitState, params: LoweParams) -> Result<Self> {
        params.validate()?;
        if let Some(problem) = camera.intrinsics_problem() {
            return Err(Error::Parameter(format!("camera: {problem}")));
        }
        Self::check_model(model)?;
        let geometry = ModelGeometry::new(model)?;
        let pose = init.pose.as_ref().ok_or_else(|| Error::Parameter("lowe needs \"pose\" in init.json".into()))?;
        if !pose.is_finite() || !init.params.iter().all(|v| v.is_finite()) {
            return Err(Error::Parameter("the initial \"pose\" and \"params\" must be finite numbers".into()));
        }
        let joint_values = if init.params.is_empty() { vec![0.0; geometry.joint_count()] } else { init.params.clone() };
        if joint_values.len() != geometry.joint_count() {
            return Err(Error::Parameter(format!(
                "\"params\" has {}; the model has {}",
                crate::bounds::counted(joint_values.len(), "value", "values"),
                crate::bounds::counted(geometry.joint_count(), "joint", "joints")
            )));
        }
        for (k, (&value, [min, max])) in joint_values.iter().zip(geometry.joint_limits()).enumerate() {
            if !(min..=max).contains(&value) {
                return Err(Error::Parameter(format!(
                    "\"params\" value {k} is {}, outside its joint's limits [{}, {}]",
                    crate::bounds::short_number(value),
                    crate::bounds::short_number(min),
                    crate::bounds::short_number(max)
                )));
            }
        }
        let state = State { pose: Pose::from(pose), params: joint_values };
        let depth = state.pose.apply(geometry.centroid()).z;
        if !(depth > 0.0) {
            // Rounding leaves a centre in the camera's plane a few 1e-18 m off it.
            let shown = if depth.abs() < 1e-12 { 0.0 } else { depth };
            return Err(Error::Parameter(format!(
                "the pose puts the model's centre at depth {}: it must lie in front of the camera (depth > 0)",
                crate::bounds::short_number(shown)
            )));
        }
        // Every vertex must project: a vertex at or behind the camera has no
        // image, and the model no outline to match.
        let points = geometry.camera_vertices(&state.pose, &state.params)?;
        if let Some((k, p)) = points.iter().enumerate().find(|(_, p)| camera.project_in_front(**p).is_none()) {
            return Err(Error::Parameter(format!(
                "the pose puts model vertex {k} at depth {}: the whole model must lie in front of the camera",
                crate::bounds::short_number(p.z)
            )));
        }
        // A model whose image lies wholly beside the frame, or spans less
        // than a pixel, leaves nothing to start from: the pose, or the
        // camera's intrinsics, are wrong.
        if let Some(problem) = camera.start_image_problem(&points) {
            return Err(Error::Parameter(problem));
        }
        let segment_params = params.segments.clone();
        let mut tracker = Self {
            camera,
            centre: geometry.centroid(),
            limits: geometry.joint_limits(),
            extractor: SegmentExtractor::new(segment_params.clone())?,
            index: SegmentIndex::with_params(&segment_params),
            image_segments: Vec::new(),
            crossing_map: CrossingMap::default(),
            prediction: state.clone(),
            last_tracked: state.clone(),
            joint_velocity: vec![0.0; geometry.joint_count()],
            joint_measured: vec![false; geometry.joint_count()],
            last: state,
            before_last: None,
            first_doubling: 0,
            lost_frames: 0,
            phase: Phase::Tracking,
            window: Window::full(camera.width as usize, camera.height as usize),
            window_doublings: params.range_doublings,
            window_all_ranges: false,
            before_widening: None,
            last_diagnostics: LoweDiagnostics::default(),
            steady: Steady::default(),
            views: Vec::new(),
            contrast_memory: vec![EdgeContrast::default(); geometry.edges().len()],
            reclaim: Reclaim::default(),
            geometry,
            params,
        };
        tracker.window = tracker.window_at(
            &tracker.prediction,
            tracker.params.range_doublings,
            camera.width as usize,
            camera.height as usize,
        );
        Ok(tracker)
    }

    /// The diagnostics of the last frame.
    #[must_use]
    pub fn diagnostics(&self) -> &LoweDiagnostics {
        &self.last_diagnostics
    }

    fn n(&self) -> usize {
        6 + self.geometry.joint_count()
    }

    /// Prior standard deviations around `prediction` after `doublings`
    /// doublings.
    fn prior_sigmas(&self, prediction: &State, doublings: usize) -> Row {
        let scale = f64::from(1u32 << doublings);
        let depth = prediction.pose.apply(self.centre).z.abs().max(1e-6);
        let translation = self.params.prior_translation_px * depth / self.camera.fx;
        let mut sigmas = [0.0; MAX_PARAMS];
        for (i, s) in sigmas.iter_mut().enumerate().take(self.n()) {
            *s = scale
                * match i {
                    0..=2 => self.params.prior_rotation_sigma,
                    3..=5 => translation,
                    _ => self.params.prior_joint_sigma,
                };
        }
        sigmas
    }

    /// The image positions of every vertex at `state` (NaN for a vertex at
    /// or behind the camera).
    fn corners_at(&self, state: &State) -> Vec<[f64; 2]> {
        self.geometry.camera_vertices(&state.pose, &state.params).map_or_else(
            |_| vec![[f64::NAN; 2]; self.geometry.vertices().len()],
            |points| points.iter().map(|p| self.camera.project_in_front(*p).unwrap_or([f64::NAN; 2])).collect(),
        )
    }

    /// The next frame's prediction (module doc, step 1): the pose's step
    /// between the last two accepted solutions applied once more, each
    /// joint's `joint_velocity`; the last solution when there is no step.
    fn predict(&self) -> State {
        let Some(before) = &self.before_last else { return self.last.clone() };
        let mut step = self.last.deviation_from(before, self.centre);
        step[6..self.n()].copy_from_slice(&self.joint_velocity);
        self.last.corrected(&step[..self.n()], self.centre, &self.limits)
    }

    /// Window of interest around the model at `state` for the search
    /// range after `doublings` doublings of the prior, grown by
    /// `window_margin_px`. A narrowed window (fewer doublings than
    /// `range_doublings`) bounds each vertex's own reach: the box of
    /// `search_sigmas` standard deviations of its projection along x and
    /// along y, which holds the model at every pose of the range, each edge
    /// lying between its vertices. The widest window grows the vertices' box
    /// by the largest reach of any vertex (both coordinates' deviations in
    /// quadrature) on every side: bounded vertex by vertex as well, its
    /// whole-image search took a board of tags for ViSP's cube
    /// (BENCHMARKS.md, "A narrowed window bounded vertex by vertex").
    fn window_at(&self, state: &State, doublings: usize, width: usize, height: usize) -> Window {
        let n = self.n();
        let prior = estimation::diagonal(&self.prior_sigmas(state, doublings), n);
        let Ok(lin) = Linearised::at(&self.geometry, state, self.centre) else {
            return Window::full(width, height);
        };
        let narrowed = doublings < self.params.range_doublings;
        let sigmas = self.params.search_sigmas;
        let mut reach: f64 = 0.0;
        let mut points = Vec::with_capacity(2 * lin.points.len());
        for (p, rows) in lin.points.iter().zip(&lin.derivatives) {
            if let Some((pixel, pixel_rows)) = projection::project_with_rows(&self.camera, *p, rows, n) {
                let var = pixel_rows.map(|row| estimation::quadratic_form(&prior, &row, n));
                if narrowed {
                    let [rx, ry] = var.map(|v| (sigmas * v.sqrt()).min(1e6));
                    points.push([pixel[0] - rx, pixel[1] - ry]);
                    points.push([pixel[0] + rx, pixel[1] + ry]);
                } else {
                    points.push(pixel);
                    reach = reach.max((var[0] + var[1]).sqrt());
                }
            }
        }
        let margin = sigmas * reach + self.params.window_margin_px;
        Window::around(&points, margin.min(1e6), width, height).unwrap_or_else(|| Window::full(width, height))
    }

    /// Steps 4–6 of the module doc at `prediction`, whose visible model
    /// segments are `segs`, from doubling `first` to the widest: the first
    /// verified solution with outline support at least `confident_support`,
    /// else the first verified one or the later one that replaced it
    /// (module doc, step 6), else the last accepted one.
    fn search_at(
        &self,
        view: &FrameView<'_>,
        prediction: &State,
        segs: &[ModelSegment],
        first: usize,
        confident_support: f64,
        diag: &mut LoweDiagnostics,
    ) -> Option<Found> {
        let n = self.n();
        let needed = segments_needed(n);
        let settings = self.settings();
        let mut cands = Vec::new();
        let mut accepted = None;
        let mut verified: Option<Found> = None;
        for doubling in first..=view.widest_doubling.max(first) {
            diag.doublings = doubling;
            let sigmas = self.prior_sigmas(prediction, doubling);
            let p0 = estimation::diagonal(&sigmas, n);
            view.candidates(segs, &p0, &mut cands);
            let mut with_candidates: Vec<usize> = cands.iter().map(|c| c.model).collect();
            with_candidates.dedup();
            if with_candidates.len() < needed {
                continue;
            }
            let problem = Problem {
                geometry: &self.geometry,
                camera: &self.camera,
                centre: self.centre,
                limits: &self.limits,
                prediction,
                prior_sigmas: &sigmas,
                measurement_sigma: self.params.measurement_sigma_px,
                reference_length: self.params.reference_length_px,
            };
            let outcome = search::search(view, &problem, segs.to_vec(), &cands, &settings);
            diag.branches += outcome.branches;
            let Some(solution) = outcome.solution else { continue };
            let segs = outcome.model_segments;
            let support = outcome
                .support
                .filter(|&counts| view.range_tests(doubling, &solution.covariance, support::fraction(counts)).is_ok());
            let Some(support) = support else {
                accepted = Some(Found { solution, matches: outcome.matches, segs, support: None, doubling });
                continue;
            };
            let found = Found { solution, matches: outcome.matches, segs, support: Some(support), doubling };
            view.verified.borrow_mut().push(Verified {
                supported: support.0,
                matches: found.matches.len(),
                solution: found.solution.clone(),
            });
            // A weakly supported solution does not end the search: a wider
            // range may hold a confident one (module doc, step 6).
            let confident = support::fraction(support) >= confident_support;
            // A later range's solution replaces a weakly supported one when
            // it clears the bar of a re-acquisition and is better: more of
            // its outline supported, more matches (module doc, step 6).
            let better = verified.as_ref().is_none_or(|first| {
                let first_support = first.support.map_or(0.0, support::fraction);
                let fraction = support::fraction(support);
                fraction >= self.params.search_min_support
                    && fraction > first_support
                    && found.matches.len() > first.matches.len()
                    && coverage(&found.segs, &found.matches) >= self.params.search_min_coverage
            });
            if confident || better {
                verified = Some(found);
            }
            if confident {
                break;
            }
        }
        verified.or(accepted)
    }

    /// The second look of step 6 (module doc): when `found`, the search's
    /// result at the velocity-extrapolated prediction, is not a verified
    /// solution with `confident_support`, and either the last frame had
    /// that support or `found` has less than [`SLOWER_SEARCH_SUPPORT_DROP`]
    /// of the last frame's (or is not verified), the search runs again
    /// from the last solution itself, then from it moved by half its
    /// velocity (the motion may have turned round or slowed), each at the
    /// frame's first range. A solution found there replaces `found` when
    /// it is verified with `confident_support`, more of its outline
    /// supported than `found` and no fewer matches than a verified `found`.
    fn search_slower(&self, view: &FrameView<'_>, found: Option<Found>, diag: &mut LoweDiagnostics) -> Option<Found> {
        let confident = self.params.confident_support;
        let fraction = |found: &Found| found.support.map_or(0.0, support::fraction);
        if found.as_ref().is_some_and(|f| fraction(f) >= confident) {
            return found;
        }
        // A verified answer about as well supported as the last frame's,
        // after a frame short of `confident_support` itself, is no reversal.
        let last_support = self.last_diagnostics.support;
        if last_support < confident
            && found.as_ref().is_some_and(|f| f.verified() && fraction(f) >= SLOWER_SEARCH_SUPPORT_DROP * last_support)
        {
            return found;
        }
        let mut best = found;
        let mut half_step = self.prediction.deviation_from(&self.last, self.centre);
        for value in &mut half_step[..self.n()] {
            *value *= 0.5;
        }
        let slower = [self.last.clone(), self.last.corrected(&half_step[..self.n()], self.centre, &self.limits)];
        let mut segs = Vec::new();
        for start in &slower {
            view.visible_segments(start, &mut segs);
            let Some(other) = self.search_at(view, start, &segs, self.first_doubling, confident, diag) else {
                continue;
            };
            let better = best.as_ref().is_none_or(|b| {
                fraction(&other) > fraction(b) && (!b.verified() || other.matches.len() >= b.matches.len())
            });
            if other.verified() && fraction(&other) >= confident && better {
                best = Some(other);
            }
        }
        best
    }

    /// Whether `state` puts the model's centre inside the image at a depth
    /// within a factor 1.5 of the last verified state's.
    fn plausible(&self, state: &State) -> bool {
        let (centre, known) = (state.pose.apply(self.centre), self.last_tracked.pose.apply(self.centre));
        let ratio = centre.z / known.z;
        let inside = self.camera.project_in_front(centre).is_some_and(|[u, v]| {
            (0.0..f64::from(self.camera.width)).contains(&u) && (0.0..f64::from(self.camera.height)).contains(&v)
        });
        inside && (1.0 / 1.5..=1.5).contains(&ratio)
    }

    /// The whole-image search of a lost model (module doc, step 8): the
    /// last verified state and the remembered views, each moved across the
    /// image on a grid as wide as the widest search reaches, each position
    /// searched at the widest range; of the solutions verified (at
    /// `search_min_coverage` and `search_min_support`), the one whose
    /// outline has the most zero crossings along it.
    fn search_image(&self, view: &FrameView<'_>, diag: &mut LoweDiagnostics) -> Option<Found> {
        let mut best: Option<(f64, Found)> = None;
        let others = self.views.iter().filter(|v| rotation_between(v, &self.last_tracked) > VIEW_GAP_RAD);
        for base in std::iter::once(&self.last_tracked).chain(others) {
            self.search_image_from(view, base, &mut best, diag);
        }
        best.map(|(_, found)| found)
    }

    /// The whole-image search's grid with the model at `base`'s orientation,
    /// depth and joint values, keeping in `best` the verified solution
    /// whose outline has the most zero crossings along it.
    fn search_image_from(
        &self,
        view: &FrameView<'_>,
        base: &State,
        best: &mut Option<(f64, Found)>,
        diag: &mut LoweDiagnostics,
    ) {
        let (width, height) = (f64::from(self.camera.width), f64::from(self.camera.height));
        let centre = base.pose.apply(self.centre);
        if !(centre.z > 0.0) {
            return;
        }
        let step = (self.params.search_sigmas
            * self.params.prior_translation_px
            * f64::from(1u32 << self.params.range_doublings))
        .max(8.0);
        let (columns, rows) = ((width / step).ceil() as usize, (height / step).ceil() as usize);
        let mut segs = Vec::new();
        for row in 0..rows {
            for column in 0..columns {
                let u = (column as f64 + 0.5) * width / columns as f64;
                let v = (row as f64 + 0.5) * height / rows as f64;
                let mut hypothesis = base.clone();
                let x = (u - self.camera.cx) * centre.z / self.camera.fx;
                let y = (v - self.camera.cy) * centre.z / self.camera.fy;
                hypothesis.pose.translation += DVec3::new(x - centre.x, y - centre.y, 0.0);
                view.visible_segments(&hypothesis, &mut segs);
                self.best_supported_joints(view, &mut hypothesis, &mut segs);
                let Some(found) = self.search_at(view, &hypothesis, &segs, self.params.range_doublings, 0.0, diag)
                else {
                    continue;
                };
                let Some(counts) = found.support else { continue };
                let support = support::fraction(counts);
                if best.as_ref().is_none_or(|(s, _)| support > *s) {
                    *best = Some((support, found));
                }
            }
        }
    }

    /// Each joint's range on a grid of [`JOINT_ALTERNATIVES`] values, as
    /// `(joint, value)`, without the values nearer than
    /// [`JOINT_ALTERNATIVE_GAP`] to `state`'s.
    fn joint_grid<'a>(&'a self, state: &'a State) -> impl Iterator<Item = (usize, f64)> + 'a {
        self.limits.iter().enumerate().flat_map(move |(joint, &[lo, hi])| {
            (0..JOINT_ALTERNATIVES)
                .map(move |k| lo + (hi - lo) * k as f64 / (JOINT_ALTERNATIVES - 1) as f64)
                .filter(move |value| (value - state.params[joint]).abs() >= JOINT_ALTERNATIVE_GAP)
                .map(move |value| (joint, value))
        })
    }

    /// Moves `hypothesis` (whose visible model segments are `segs`, which
    /// follow it) to the value of one joint on the grid of
    /// [`LoweTracker::joint_alternatives`] whose outline has the most
    /// supported samples, when that is more than the hypothesis' own by
    /// the margin of [`better_supported`] (module doc, step 8).
    fn best_supported_joints(&self, view: &FrameView<'_>, hypothesis: &mut State, segs: &mut Vec<ModelSegment>) {
        if self.limits.is_empty() {
            return;
        }
        let own = view.support_counts(segs);
        if let Some((_, other, other_segs)) = self.best_supported_grid_value(view, hypothesis, own, with_joint) {
            *hypothesis = other;
            *segs = other_segs;
        }
    }

    /// `visit` called, in the grid's order, with each state `alternative`
    /// makes from `state` for a value of [`LoweTracker::joint_grid`]
    /// (`None`: no such state), its outline's supported samples, the
    /// joint's change (radians) and its visible model segments. The
    /// segments are one buffer, refilled for each state: a visitor that
    /// keeps them takes them (`std::mem::take`) and may hand back another.
    fn for_each_grid_hypothesis(
        &self,
        view: &FrameView<'_>,
        state: &State,
        alternative: impl Fn(&State, usize, f64) -> Option<State>,
        mut visit: impl FnMut(Support, f64, State, &mut Vec<ModelSegment>),
    ) {
        let mut segs = Vec::new();
        for (joint, value) in self.joint_grid(state) {
            let Some(other) = alternative(state, joint, value) else { continue };
            view.visible_segments(&other, &mut segs);
            visit(view.support_counts(&segs), (value - state.params[joint]).abs(), other, &mut segs);
        }
    }

    /// Of [`LoweTracker::for_each_grid_hypothesis`]'s states, the first
    /// whose outline has the most supported samples, when that beats `own`
    /// by the margin of [`better_supported`] for the joint's change; with
    /// its support and visible model segments.
    fn best_supported_grid_value(
        &self,
        view: &FrameView<'_>,
        state: &State,
        own: Support,
        alternative: impl Fn(&State, usize, f64) -> Option<State>,
    ) -> Option<(Support, State, Vec<ModelSegment>)> {
        let mut best: Option<(Support, State, Vec<ModelSegment>)> = None;
        self.for_each_grid_hypothesis(view, state, alternative, |counts, moved, other, segs| {
            if better_supported(counts, own, moved) && best.as_ref().is_none_or(|(c, ..)| counts.0 > c.0) {
                // The winner keeps the buffer; the one it beat lends its own.
                let beaten = best.replace((counts, other, std::mem::take(segs)));
                *segs = beaten.map(|(.., buffer)| buffer).unwrap_or_default();
            }
        });
        best
    }

    /// Other values of each joint (module doc, step 9): the joint's range
    /// on a grid of [`JOINT_ALTERNATIVES`] values, each farther than
    /// [`JOINT_ALTERNATIVE_GAP`] from the solution's, with the pose and the
    /// other joints held. The [`JOINT_REFITS`] values whose outlines have
    /// the most zero crossings along them are searched from, and, when
    /// `found` has less than `confident_support`, the best supported swing
    /// ([`LoweTracker::best_joint_swing`]) if any; the best
    /// supported verified solution at least [`JOINT_ALTERNATIVE_GAP`] from
    /// `found`'s joint values replaces `found` when its outline has more
    /// supported samples by the margin of [`better_supported`] (for its
    /// distance from `found` or from the prediction, the nearer), every joint
    /// it moved is measured, and it has more matches than `found`. With
    /// the solution, which joints it moved by at least the gap (none when
    /// `found` stays).
    fn joint_alternatives(&self, view: &FrameView<'_>, found: Found, diag: &mut LoweDiagnostics) -> (Found, Vec<bool>) {
        // Only a verified solution has its outline's support counted.
        let Some(own) = found.support else { return (found, Vec::new()) };
        // Each hypothesis with its visible model segments and how many of
        // their samples are supported.
        let mut hypotheses: Vec<(usize, State, Vec<ModelSegment>)> = Vec::new();
        self.for_each_grid_hypothesis(view, &found.solution.state, with_joint, |counts, _, hypothesis, segs| {
            hypotheses.push((counts.0, hypothesis, std::mem::take(segs)));
        });
        hypotheses.sort_by_key(|h| std::cmp::Reverse(h.0));
        hypotheses.truncate(JOINT_REFITS);
        // A confident fit of the body is not turned under its part.
        if support::fraction(own) < self.params.confident_support {
            hypotheses.extend(self.best_joint_swing(view, &found.solution.state, own));
        }
        let mut best: Option<(usize, Found)> = None;
        for (_, hypothesis, segs) in &hypotheses {
            let Some(other) = self.search_at(view, hypothesis, segs, 0, 0.0, diag) else { continue };
            let Some(counts) = other.support else { continue };
            let params = &other.solution.state.params;
            let moved = largest_difference(params, &found.solution.state.params);
            // The jump that needs evidence: from the frame's fit or from the
            // prediction, whichever is nearer.
            let jump = moved.min(largest_difference(params, &self.prediction.params));
            // Each joint that moved is measured in the other solution: the
            // image, not the prior alone, sets its value.
            let measured = jumped_joints(&other.solution.state, &found.solution.state)
                .enumerate()
                .all(|(j, jumped)| !jumped || self.measures_joint(&other.solution.covariance, j));
            if moved >= JOINT_ALTERNATIVE_GAP
                && measured
                && other.matches.len() > found.matches.len()
                && better_supported(counts, own, jump)
                && best.as_ref().is_none_or(|(c, _)| counts.0 > *c)
            {
                best = Some((counts.0, other));
            }
        }
        match best {
            None => (found, Vec::new()),
            Some((_, other)) => {
                let jumped = jumped_joints(&other.solution.state, &found.solution.state).collect();
                (other, jumped)
            }
        }
    }

    /// Of the frame's `verified` solutions, the best supported one that
    /// makes `answer` ambiguous (module doc, step 10): at least
    /// `ambiguous_match_ratio` of its matches, at least
    /// `ambiguous_support_ratio` of its supported samples, its model
    /// vertices on average more than `ambiguous_distance_px` away.
    fn ambiguity(&self, answer: &Found, verified: &[Verified]) -> Option<Ambiguity> {
        let least_ratio = self.params.ambiguous_support_ratio;
        let own = answer.support?.0;
        if least_ratio == 0.0 || own == 0 {
            return None;
        }
        let corners = self.corners_at(&answer.solution.state);
        verified
            .iter()
            .filter(|rival| rival.matches as f64 >= self.params.ambiguous_match_ratio * answer.matches.len() as f64)
            .filter_map(|rival| {
                let support_ratio = rival.supported as f64 / own as f64;
                if support_ratio < least_ratio {
                    return None;
                }
                let distance_px = mean_point_distance(&corners, &self.corners_at(&rival.solution.state));
                (distance_px > self.params.ambiguous_distance_px).then_some((support_ratio, distance_px, rival))
            })
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(support_ratio, distance_px, rival)| Ambiguity {
                support_ratio,
                distance_px,
                matches: [rival.matches, answer.matches.len()],
                rival: rival.solution.clone(),
            })
    }

    /// The joint swing of step 9 (module doc): each joint of `state` set to
    /// the values of [`LoweTracker::joint_grid`] with the part it moves
    /// held where it is and the rest of the model swung about the joint
    /// ([`ModelGeometry::joint_swing`]); the best supported of them
    /// ([`LoweTracker::best_supported_grid_value`]), with its supported
    /// samples and visible model segments.
    fn best_joint_swing(
        &self,
        view: &FrameView<'_>,
        state: &State,
        own: Support,
    ) -> Option<(usize, State, Vec<ModelSegment>)> {
        let swung = |state: &State, joint: usize, value: f64| {
            let swing = self.geometry.joint_swing(joint, state.params[joint] - value)?;
            let mut other = state.clone();
            other.pose = other.pose * swing;
            other.params[joint] = value;
            Some(other)
        };
        self.best_supported_grid_value(view, state, own, swung).map(|(counts, other, segs)| (counts.0, other, segs))
    }

    /// Whether joint `joint` is measured in a solution of covariance `p`:
    /// its σ below [`UNMEASURED_SIGMA_RATIO`] of its prior.
    fn measures_joint(&self, p: &Matrix, joint: usize) -> bool {
        p[6 + joint][6 + joint] < (UNMEASURED_SIGMA_RATIO * self.params.prior_joint_sigma).powi(2)
    }

    /// The joint steps the next prediction extrapolates, after `solution`
    /// was verified with `previous` the last state (module doc, step 1): a
    /// joint measured in this frame and the last takes its step between
    /// them; any other keeps its last such step; after a loss none moves,
    /// nor does a joint that `jumped` to another value (step 9): that step
    /// corrected the fit and is no motion.
    fn update_joint_velocity(&mut self, previous: &State, solution: &estimation::Solution, jumped: &[bool]) {
        for joint in 0..self.joint_velocity.len() {
            let measured = self.measures_joint(&solution.covariance, joint);
            if self.lost_frames > 0 || jumped.get(joint).copied().unwrap_or(false) {
                self.joint_velocity[joint] = 0.0;
            } else if measured && self.joint_measured[joint] {
                self.joint_velocity[joint] = solution.state.params[joint] - previous.params[joint];
            }
            self.joint_measured[joint] = measured;
        }
    }

    /// Whether a solution of `matches` matches with residual σ `residual`
    /// is a loose fit on few matches (module doc, step 7): at most
    /// `loose_fit_extra_matches` more than a search node's and a residual σ
    /// above `loose_fit_residual_ratio` measurement σ.
    fn loose_fit(&self, matches: usize, residual: Option<f64>) -> bool {
        matches <= segments_needed(self.n()) + self.params.loose_fit_extra_matches
            && residual.is_some_and(|r| r > self.params.loose_fit_residual_ratio * self.params.measurement_sigma_px)
    }

    /// Each learning frame weighs [`CONTRAST_MEMORY_DECAY`] times the next
    /// one in the edges' contrast memory.
    fn fade_contrast_memory(&mut self) {
        for memory in &mut self.contrast_memory {
            memory.dark_side_px *= CONTRAST_MEMORY_DECAY;
        }
    }

    /// Adds a verified frame's matches to each edge's contrast memory: an
    /// edge whose matches all have one contrast adds their length on that
    /// side; its memory starts again when other faces of it face the
    /// camera.
    fn remember_contrast(&mut self, segs: &[ModelSegment], matches: &[estimation::Match]) {
        let mut seen: Vec<(usize, u8, f64, f64)> = Vec::new();
        for m in matches {
            let Some(seg) = segs.iter().find(|s| s.edge == m.edge && s.interval == m.interval) else { continue };
            let s = &self.image_segments[m.image];
            let (dark, bright) = match search::dark_side(s.direction, seg) {
                0.0 => continue,
                side if side > 0.0 => (s.length, 0.0),
                _ => (0.0, s.length),
            };
            match seen.iter_mut().find(|e| e.0 == m.edge) {
                Some(e) => {
                    e.2 += dark;
                    e.3 += bright;
                }
                None => seen.push((m.edge, seg.facing, dark, bright)),
            }
        }
        for (edge, facing, dark, bright) in seen {
            let memory = &mut self.contrast_memory[edge];
            if memory.facing != facing {
                *memory = EdgeContrast { facing, dark_side_px: 0.0 };
            }
            if dark == 0.0 || bright == 0.0 {
                memory.dark_side_px += dark - bright;
            }
        }
    }

    fn settings(&self) -> SearchSettings {
        SearchSettings {
            set_probability: self.params.set_probability,
            residual_limit: self.params.residual_ratio * self.params.measurement_sigma_px,
            max_branches: self.params.max_branches,
            iterations: self.params.iterations,
            lock_iterations: self.params.lock_iterations,
            lock_probability: self.params.lock_probability,
            swap_gap: self.params.swap_gap_px,
            swap_residual_ratio: self.params.swap_residual_ratio,
        }
    }
}

/// Most remembered views (see [`LoweTracker::search_image`]).
const MAX_VIEWS: usize = 4;
/// Least rotation between two remembered views, radians (20°).
const VIEW_GAP_RAD: f64 = 0.35;
/// After a frame below `confident_support`, a verified first answer with
/// at least this part of that frame's outline support is not searched
/// again from slower predictions ([`LoweTracker::search_slower`]): an
/// abrupt reversal fails the search or costs most of the support, while a
/// steadily part-supported object (half hidden, or a real image's
/// outline, 66–71 % on ViSP's cube) would pay for the second look on every
/// frame.
const SLOWER_SEARCH_SUPPORT_DROP: f64 = 0.9;

/// The angle of the rotation between two states' orientations, radians.
fn rotation_between(a: &State, b: &State) -> f64 {
    crate::geometry::axis_angle_from_rotation(&(a.pose.rotation.transpose() * b.pose.rotation)).length()
}

/// Values on each joint's range that [`LoweTracker::joint_alternatives`]
/// tries.
const JOINT_ALTERNATIVES: usize = 9;
/// Best supported joint values that are searched from.
const JOINT_REFITS: usize = 2;
/// Least distance of a tried joint value from the solution's, radians.
const JOINT_ALTERNATIVE_GAP: f64 = 0.2;
/// A joint whose standard deviation in a solution is at least this part of
/// its prior's (`prior_joint_sigma`) is not measured there: no match
/// constrains it, and its value is where the search started.
const UNMEASURED_SIGMA_RATIO: f64 = 0.9;

/// `state` with joint `joint` set to `value` (step 9's grid with the pose
/// held).
fn with_joint(state: &State, joint: usize, value: f64) -> Option<State> {
    let mut other = state.clone();
    other.params[joint] = value;
    Some(other)
}

/// Per joint, whether `a` and `b` differ by at least
/// [`JOINT_ALTERNATIVE_GAP`]: a jump to another joint value (step 9).
fn jumped_joints<'a>(a: &'a State, b: &'a State) -> impl Iterator<Item = bool> + 'a {
    a.params.iter().zip(&b.params).map(|(x, y)| (x - y).abs() >= JOINT_ALTERNATIVE_GAP)
}

/// The largest absolute difference of two joint-value lists, radians.
fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// Whether an outline with `(supported, samples)` = `other`, at joint
/// values up to `moved` radians from those of an outline with `own`, is
/// better supported than that one: more supported samples by 5 % plus 10 %
/// per radian moved (a farther jump needs more evidence: a lid hidden by an
/// occluder loses to the lid shut) and at least 20 (px), at a supported
/// fraction no lower (a part turned onto a clutter line gains samples
/// there but leaves more of its outline bare).
fn better_supported(other: Support, own: Support, moved: f64) -> bool {
    let margin = (own.0 as f64 * (0.05 + 0.1 * moved)).max(20.0);
    other.0 as f64 >= own.0 as f64 + margin && other.0 * own.1 >= own.0 * other.1
}

/// An accepted solution of a search.
struct Found {
    solution: estimation::Solution,
    matches: Vec<estimation::Match>,
    /// The visible model segments at the solution.
    segs: Vec<ModelSegment>,
    /// The outline support when the solution passed the verification,
    /// `None` when it did not.
    support: Option<Support>,
    /// Times the prior ranges were doubled for the search that found it.
    doubling: usize,
}

/// A verified solution of one of the frame's searches: a rival of its
/// answer (module doc, step 10).
#[derive(Clone, Debug)]
struct Verified {
    /// Supported samples of its outline.
    supported: usize,
    /// Its matches.
    matches: usize,
    /// Its fit.
    solution: estimation::Solution,
}

/// Another verified solution of the frame about as well supported as its
/// answer and far from it (module doc, step 10).
#[derive(Clone, Debug)]
struct Ambiguity {
    /// Its supported outline samples over the answer's.
    support_ratio: f64,
    /// Mean distance between the two solutions' projected model vertices, px.
    distance_px: f64,
    /// Its matches and the answer's.
    matches: [usize; 2],
    /// Its fit.
    rival: estimation::Solution,
}

impl Found {
    /// Whether the solution passed the verification.
    fn verified(&self) -> bool {
        self.support.is_some()
    }
}

/// The frame as the search sees it.
struct FrameView<'a> {
    tracker: &'a LoweTracker,
    ctx: MatchContext,
    /// The frame's zero crossings at or above the hysteresis' low
    /// threshold, by position.
    crossing_map: &'a CrossingMap,
    /// Least coverage and outline support a solution needs this frame:
    /// `min_coverage` and `min_support` while tracking,
    /// `search_min_coverage` and `search_min_support` after a loss.
    min_coverage: f64,
    min_support: f64,
    /// Least outline support of a solution found only in a widened range
    /// while tracking: `widened_support_ratio` of the last frame's (0 after
    /// a loss, where the re-acquisition bar holds instead).
    min_widened_support: f64,
    /// Largest standard deviation of the rotation a solution may have,
    /// radians: `search_max_rotation_sigma` after a loss,
    /// [`TRACKING_ROTATION_SIGMA_PRIORS`] times `prior_rotation_sigma`
    /// while tracking.
    max_rotation_sigma: f64,
    /// The widest doubling of the prior ranges searched: that of a narrowed
    /// window when the frame widens it rather than search beyond it (step
    /// 2), `range_doublings` otherwise.
    widest_doubling: usize,
    /// Every verified solution the frame's searches found so far: the
    /// rivals of its answer (module doc, step 10).
    verified: RefCell<Vec<Verified>>,
}

impl FrameView<'_> {
    fn visible_segments(&self, state: &State, out: &mut Vec<ModelSegment>) {
        out.clear();
        let t = self.tracker;
        let Ok(lin) = Linearised::at(&t.geometry, state, t.centre) else { return };
        let parts = crate::geometry::hidden_lines::visible_edge_parts(&t.geometry, &lin.points, &t.camera);
        for (edge, intervals) in parts.iter().enumerate() {
            // Only the contrast memory reads which faces of an edge face the camera.
            let facing = if t.params.remember_contrast {
                t.geometry.edge_faces()[edge]
                    .iter()
                    .take(8)
                    .enumerate()
                    .fold(0u8, |bits, (k, &f)| if parts.facing_faces()[f] { bits | 1 << k } else { bits })
            } else {
                0
            };
            for &part in intervals {
                let Some(inside) = projection::clip_to_image(&lin, &t.camera, t.geometry.edges()[edge], part) else {
                    continue;
                };
                if let Some(mut seg) = ModelSegment::new(&lin, &t.camera, t.geometry.edges(), edge, inside)
                    && seg.length() >= MIN_MODEL_SEGMENT_PX
                {
                    // Matches name the visible part, which stays the same
                    // while the image border cuts it at another place.
                    seg.interval = part;
                    seg.facing = facing;
                    out.push(seg);
                }
            }
        }
    }
}

impl FrameView<'_> {
    /// The verification of a solution with `matches`, residual σ
    /// `residual` and the model segments `segs` at its state (module doc,
    /// step 7): its outline support when it passes, else the test it
    /// failed; `support` counts the outline's support, asked for only when
    /// the other tests pass. `found_by` (the doublings of the range searched
    /// and the solution's covariance) adds [`FrameView::range_tests`]; the
    /// search itself knows neither.
    fn verdict(
        &self,
        segs: &[ModelSegment],
        matches: &[estimation::Match],
        residual: Option<f64>,
        found_by: Option<(usize, &Matrix)>,
        support: impl FnOnce() -> Support,
    ) -> Result<Support, Rejection> {
        let node = segments_needed(self.tracker.n());
        if matches.len() <= node {
            return Err(Rejection::NodeOnly { matches: matches.len(), node });
        }
        if self.tracker.loose_fit(matches.len(), residual) {
            return Err(Rejection::LooseFit { matches: matches.len(), residual: residual.unwrap_or(f64::NAN) });
        }
        let coverage = coverage(segs, matches);
        if coverage < self.min_coverage {
            return Err(Rejection::Coverage { coverage, least: self.min_coverage });
        }
        let counts = support();
        let support = support::fraction(counts);
        if support < self.min_support {
            return Err(Rejection::Support { support, least: self.min_support });
        }
        if let Some((doubling, covariance)) = found_by {
            self.range_tests(doubling, covariance, support)?;
        }
        Ok(counts)
    }

    /// The tests of a solution found after `doubling` doublings of the
    /// prior ranges, with covariance `covariance` and outline support
    /// `support` (module doc, step 7): the rotation fixed to
    /// `max_rotation_sigma`; while tracking, a widened range's solution
    /// keeps `widened_support_ratio` of the last frame's support.
    fn range_tests(&self, doubling: usize, covariance: &Matrix, support: f64) -> Result<(), Rejection> {
        let sigma = rotation_sigma(covariance);
        if sigma > self.max_rotation_sigma {
            return Err(Rejection::LoosePose { sigma, most: self.max_rotation_sigma });
        }
        if doubling > 0 && support < self.min_widened_support {
            let ratio = self.tracker.params.widened_support_ratio;
            return Err(Rejection::WidenedSupport { support, least: self.min_widened_support, ratio });
        }
        Ok(())
    }

    /// `(supported, samples)` of `segs`: samples of their length with a
    /// zero crossing within 1 px across at an edge orientation within 20°
    /// of its own (a crossing's `theta` is the gradient's direction, across
    /// the edge), each part of the outline counted once
    /// ([`distinct_outline`]); along an edge with a remembered contrast
    /// (`remember_contrast`), only crossings of that contrast.
    fn support_counts(&self, segs: &[ModelSegment]) -> Support {
        let pieces = distinct_outline(segs).into_iter().map(|(p, q, k)| (p, q, self.remembered_contrast(&segs[k])));
        self.crossing_map.support(pieces, SUPPORT_ANGLE_DEG.to_radians())
    }
}

/// Farthest two model segments may lie from each other's line to be the
/// same line of the outline, px.
const SAME_LINE_PX: f64 = 1.0;

/// The pieces of `segs` that no earlier segment already covers: a part of a
/// model segment running along an earlier one (within [`SAME_LINE_PX`],
/// nearly parallel) is left out. Two edges can project onto one line — a
/// shut lid's front on the box's rim, a hinge — and there the image has one
/// edge: counted twice it would let an outline that folds a part onto
/// another gain support from the fold alone. Each piece comes with the
/// index of its segment in `segs`.
fn distinct_outline(segs: &[ModelSegment]) -> Vec<([f64; 2], [f64; 2], usize)> {
    let max_sine = 3f64.to_radians().sin();
    let mut pieces: Vec<([f64; 2], [f64; 2], usize)> = Vec::with_capacity(segs.len());
    // Intervals of a segment (by distance from its `a`) covered by earlier segments.
    let mut covered: Vec<[f64; 2]> = Vec::new();
    for (i, seg) in segs.iter().enumerate() {
        let length = seg.length();
        if !(length > 0.0) {
            continue;
        }
        let [ux, uy] = seg.direction();
        covered.clear();
        for other in &segs[..i] {
            let [vx, vy] = other.direction();
            if (ux * vy - uy * vx).abs() > max_sine {
                continue;
            }
            let across = |p: [f64; 2]| ((p[1] - seg.a[1]) * ux - (p[0] - seg.a[0]) * uy).abs();
            if across(other.a).max(across(other.b)) > SAME_LINE_PX {
                continue;
            }
            let along = |p: [f64; 2]| (p[0] - seg.a[0]) * ux + (p[1] - seg.a[1]) * uy;
            let (s0, s1) = (along(other.a), along(other.b));
            let (lo, hi) = (s0.min(s1).max(0.0), s0.max(s1).min(length));
            if hi > lo {
                covered.push([lo, hi]);
            }
        }
        covered.sort_by(|x, y| x[0].total_cmp(&y[0]));
        let at = |t: f64| [seg.a[0] + t * ux, seg.a[1] + t * uy];
        let mut start = 0.0;
        for &[lo, hi] in &covered {
            if lo > start {
                pieces.push((at(start), at(lo), i));
            }
            start = f64::max(start, hi);
        }
        if start < length {
            pieces.push((at(start), at(length), i));
        }
    }
    pieces
}

/// The test of the verification a solution failed (module doc, step 7).
enum Rejection {
    /// No more matches than a search node's.
    NodeOnly { matches: usize, node: usize },
    /// A loose fit on few matches ([`LoweTracker::loose_fit`]).
    LooseFit { matches: usize, residual: f64 },
    /// Matches cover too little of the visible outline.
    Coverage { coverage: f64, least: f64 },
    /// Too little of the visible outline has zero crossings along it.
    Support { support: f64, least: f64 },
    /// Found only in a widened range, with far less of the outline
    /// supported than the last frame's.
    WidenedSupport { support: f64, least: f64, ratio: f64 },
    /// A re-acquisition whose matches leave the rotation loose.
    LoosePose { sigma: f64, most: f64 },
}

impl std::fmt::Display for Rejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Self::NodeOnly { matches, node } => {
                write!(f, "{matches} matches, no more than a search node's {node}: none joined on locking on")
            }
            Self::LooseFit { matches, residual } => {
                write!(f, "{matches} matches fitted with a residual σ of {residual:.2} px")
            }
            Self::Coverage { coverage, least } => {
                write!(f, "matches cover {:.0} % of the visible edges (< {:.0} %)", 100.0 * coverage, 100.0 * least)
            }
            Self::Support { support, least } => write!(
                f,
                "zero crossings lie along {:.0} % of the visible edges (< {:.0} %)",
                100.0 * support,
                100.0 * least
            ),
            Self::LoosePose { sigma, most } => write!(
                f,
                "the matches fix the rotation to σ {:.1}° only (at most {:.1}° accepted)",
                sigma.to_degrees(),
                most.to_degrees()
            ),
            Self::WidenedSupport { support, least, ratio } => write!(
                f,
                "found only in a widened range, with zero crossings along {:.0} % of the visible edges \
                 (< {:.0} %, {ratio} of the last frame's)",
                100.0 * support,
                100.0 * least
            ),
        }
    }
}

/// Largest angle between a model segment and a zero crossing's edge
/// orientation for the crossing to support it, degrees.
const SUPPORT_ANGLE_DEG: f64 = 20.0;

impl SearchFrame for FrameView<'_> {
    fn model_segments(&self, state: &State, out: &mut Vec<ModelSegment>) {
        self.visible_segments(state, out);
    }

    fn candidates(&self, segs: &[ModelSegment], p: &Matrix, out: &mut Vec<Candidate>) {
        out.clear();
        let t = self.tracker;
        let n = t.n();
        let min_length = t.params.segments.min_length.max(1.0);
        let mut hits = Vec::new();
        for (m, seg) in segs.iter().enumerate() {
            let spread = SegmentSpread::of(seg, p, n);
            let [x0, y0, x1, y1] = search_bounds(seg, &spread, &self.ctx);
            let tolerance =
                self.ctx.search_sigmas * spread.orientation.hypot(2.0 * self.ctx.measurement_sigma / min_length);
            let line = ModelLine::of(seg, &spread, &self.ctx);
            t.index.query(x0..=x1, y0..=y1, line.orientation(), tolerance.min(std::f64::consts::FRAC_PI_2), &mut hits);
            for &i in &hits {
                if let Some(probability) = line.match_probability(p, n, &self.endpoints(i)) {
                    out.push(Candidate { model: m, image: i, probability });
                }
            }
        }
    }

    fn endpoints(&self, image: usize) -> Endpoints {
        let s = &self.tracker.image_segments[image];
        [s.start, s.end]
    }

    fn contrast_direction(&self, image: usize) -> Option<f64> {
        Some(self.tracker.image_segments[image].direction)
    }

    fn remembered_contrast(&self, seg: &ModelSegment) -> f64 {
        let memory = self.tracker.contrast_memory[seg.edge];
        if memory.facing == seg.facing && memory.dark_side_px.abs() >= CONTRAST_MEMORY_MIN_PX {
            memory.dark_side_px.signum()
        } else {
            0.0
        }
    }

    fn verify(
        &self,
        segs: &[ModelSegment],
        matches: &[estimation::Match],
        residual_sigma: Option<f64>,
    ) -> Option<Support> {
        // `search_at` makes the range tests on what the search returns.
        self.verdict(segs, matches, residual_sigma, None, || self.support_counts(segs)).ok()
    }

    fn covered_length(&self, segs: &[ModelSegment], matches: &[estimation::Match]) -> f64 {
        covered_length(segs, matches)
    }
}

/// The largest standard deviation of the three rotation parameters in the
/// covariance `p` of a solution, radians.
fn rotation_sigma(p: &Matrix) -> f64 {
    (0..3).map(|i| p[i][i].max(0.0).sqrt()).fold(0.0, f64::max)
}

/// Fraction of the model segments' total length covered by the matched
/// image segments (each projected onto its model segment and clipped to
/// it; a model segment counts at most its own length).
fn coverage(segs: &[ModelSegment], matches: &[estimation::Match]) -> f64 {
    let total: f64 = segs.iter().map(ModelSegment::length).sum();
    if total <= 0.0 {
        return 0.0;
    }
    covered_length(segs, matches) / total
}

/// Length of the model segments covered by the matched image segments
/// (each projected onto its model segment and clipped to it), px.
fn covered_length(segs: &[ModelSegment], matches: &[estimation::Match]) -> f64 {
    let mut covered = 0.0;
    for seg in segs {
        let length = seg.length();
        let [ux, uy] = seg.direction();
        let mut spans: Vec<[f64; 2]> = matches
            .iter()
            .filter(|m| m.edge == seg.edge && m.interval == seg.interval)
            .map(|m| {
                let along = |p: [f64; 2]| ((p[0] - seg.a[0]) * ux + (p[1] - seg.a[1]) * uy).clamp(0.0, length);
                let (s0, s1) = (along(m.endpoints[0]), along(m.endpoints[1]));
                [s0.min(s1), s0.max(s1)]
            })
            .collect();
        spans.sort_by(|a, b| a[0].total_cmp(&b[0]));
        let mut end: f64 = 0.0;
        for [s0, s1] in spans {
            covered += (s1 - s0.max(end)).max(0.0);
            end = end.max(s1);
        }
    }
    covered
}

impl Tracker for LoweTracker {
    fn name(&self) -> &'static str {
        "lowe"
    }

    fn accept_frame_size(&mut self, width: usize, height: usize) -> std::result::Result<(), String> {
        super::camera_takes(&self.camera, width, height)
    }

    fn window_of_interest(&self, width: usize, height: usize) -> Window {
        self.window.clipped(width, height)
    }

    fn request(&self, width: usize, height: usize) -> FrameRequest {
        let window = self.window_of_interest(width, height);
        FrameRequest {
            zero_crossings: Some(ZeroCrossingRequest {
                log: LogParams { sigma: self.params.log_sigma },
                crossings: ZeroCrossingParams { min_slope: self.params.min_slope },
                list: ListSpec { window, cap: None, seed: 0 },
            }),
            ..FrameRequest::default()
        }
    }

    fn extras(&self) -> FrameExtras {
        FrameExtras { search_branches: Some(self.last_diagnostics.branches), ..FrameExtras::default() }
    }

    fn track(&mut self, frame: usize, observations: &Observations<'_>) -> FrameOutcome {
        match self.track_frame(frame, observations, false) {
            Tracked::Outcome(outcome) => outcome,
            Tracked::Widened => unreachable!("the window is widened only when asked"),
        }
    }

    fn track_or_widen(&mut self, frame: usize, observations: &Observations<'_>) -> Tracked {
        self.track_frame(frame, observations, true)
    }
}

impl LoweTracker {
    /// Steps 1–10 of the module doc on one frame's features; with
    /// `may_widen`, a frame whose narrowed window (step 2) gives no
    /// confident solution widens it instead.
    fn track_frame(&mut self, frame: usize, observations: &Observations<'_>, may_widen: bool) -> Tracked {
        let (width, height) = (self.camera.width as usize, self.camera.height as usize);
        let started = std::time::Instant::now();
        let crossings = observations.zero_crossings.unwrap_or(&[]);
        // The support that keeps the window narrow (step 6): under a
        // steady bar, for an answer that is also the one the motion
        // predicts.
        let support_bar = self.steady.bar(self.params.confident_support, self.params.steady_support_ratio);
        let predicted = (support_bar < self.params.confident_support).then(|| self.corners_at(&self.prediction));
        let bar = Bar {
            support: support_bar,
            near: predicted.as_deref().map(|predicted| (predicted, self.params.ambiguous_distance_px)),
        };
        let mut image_segments = std::mem::take(&mut self.image_segments);
        self.extractor.extract(crossings, self.window, &mut image_segments);
        self.image_segments = image_segments;
        self.index.build(&self.image_segments, self.window);
        self.crossing_map.rebuild(
            crossings,
            self.window,
            self.params.segments.low_threshold,
            self.params.remember_contrast,
        );
        let segmented = std::time::Instant::now();
        let _ = estimation::take_solve_time();

        let n = self.n();
        let ctx = MatchContext {
            segments: self.image_segments.len(),
            area: (self.window.area() as f64).max(1.0),
            measurement_sigma: self.params.measurement_sigma_px,
            search_sigmas: self.params.search_sigmas,
            min_probability: self.params.min_probability,
        };
        // The search of this frame before its window was widened, if this
        // is the frame's second look (else a frame left unfinished).
        let earlier = self.before_widening.take().filter(|_| !may_widen);
        let mut diag = LoweDiagnostics {
            image_segments: self.image_segments.len(),
            branches: earlier.as_ref().map_or(0, |e| e.branches),
            ..LoweDiagnostics::default()
        };
        // After a loss the bar of a re-acquisition; while tracking, the
        // last frame (verified) sets the bar of a widened range's solution.
        let p = &self.params;
        let (min_coverage, min_support, min_widened_support, max_rotation_sigma) = if self.lost_frames > 0 {
            (p.search_min_coverage, p.search_min_support, 0.0, p.search_max_rotation_sigma)
        } else {
            (
                p.min_coverage,
                p.min_support,
                p.widened_support_ratio * self.last_diagnostics.support,
                TRACKING_ROTATION_SIGMA_PRIORS * p.prior_rotation_sigma,
            )
        };
        let view = FrameView {
            tracker: self,
            ctx,
            crossing_map: &self.crossing_map,
            min_coverage,
            min_support,
            min_widened_support,
            max_rotation_sigma,
            widest_doubling: if may_widen && !self.window_all_ranges {
                self.window_doublings
            } else {
                p.range_doublings
            },
            verified: RefCell::new(Vec::new()),
        };
        let mut segs = Vec::new();
        view.visible_segments(&self.prediction, &mut segs);
        let mut accepted = self.search_at(
            &view,
            &self.prediction,
            &segs,
            self.first_doubling,
            self.params.confident_support,
            &mut diag,
        );
        if self.params.search_slower_predictions && self.lost_frames == 0 && self.before_last.is_some() {
            accepted = self.search_slower(&view, accepted, &mut diag);
        }
        // Step 2: a narrowed window without a confident solution in it is
        // widened, and the frame searched again in the wider window.
        let confident = |found: &Found| {
            found.support.is_some_and(|s| bar.reached(support::fraction(s), || self.corners_at(&found.solution.state)))
        };
        if may_widen && self.window_doublings < p.range_doublings && !accepted.as_ref().is_some_and(confident) {
            drop(view);
            diag.time_since(started, segmented);
            self.before_widening = Some(diag);
            self.window_doublings = self.params.range_doublings;
            self.window = self.window_at(&self.prediction, self.window_doublings, width, height);
            return Tracked::Widened;
        }
        let verified_here = accepted.as_ref().is_some_and(Found::verified);
        if !verified_here
            && self.lost_frames >= self.params.search_after
            && let Some(found) = self.search_image(&view, &mut diag)
        {
            accepted = Some(found);
        }
        let mut joints_jumped = Vec::new();
        if let Some(found) = accepted.take() {
            accepted = Some(if found.verified() && !self.limits.is_empty() {
                let (found, jumped) = self.joint_alternatives(&view, found, &mut diag);
                joints_jumped = jumped;
                found
            } else {
                found
            });
        }
        let ambiguity = accepted.as_ref().and_then(|found| self.ambiguity(found, &view.verified.borrow()));
        // A rival clearly better supported than the answer is carried on in
        // its place (module doc, step 10).
        let carry_ratio = self.params.ambiguous_carry_ratio;
        let rival_carried = ambiguity.as_ref().is_some_and(|a| carry_ratio > 0.0 && a.support_ratio >= carry_ratio);
        diag.time_since(started, segmented);
        let at_first_range = accepted.as_ref().is_some_and(|found| found.doubling == 0);
        let mut lost_reason = None;
        let verified = match &accepted {
            None => {
                lost_reason = Some(format!(
                    "no consistent set of matches ({} image segments, {} branches)",
                    diag.image_segments, diag.branches
                ));
                None
            }
            Some(Found { solution, matches, segs, support, doubling }) => {
                diag.matches = matches.len();
                diag.residual_sigma = solution.residual_sigma;
                diag.coverage = coverage(segs, matches);
                let counts = support.unwrap_or_else(|| view.support_counts(segs));
                diag.support = support::fraction(counts);
                match view.verdict(
                    segs,
                    matches,
                    solution.residual_sigma,
                    Some((*doubling, &solution.covariance)),
                    || counts,
                ) {
                    Err(rejection) => {
                        lost_reason = Some(rejection.to_string());
                        None
                    }
                    Ok(_) => Some(solution.clone()),
                }
            }
        };
        // The carried rival's visible model replaces the answer's.
        let mut carried_segs = None;
        let verified = match (verified, &ambiguity) {
            (Some(answer), Some(Ambiguity { rival, .. })) if rival_carried => {
                joints_jumped = jumped_joints(&rival.state, &answer.state)
                    .enumerate()
                    .map(|(j, moved)| moved || joints_jumped.get(j).copied().unwrap_or(false))
                    .collect();
                let mut rival_segs = Vec::new();
                view.visible_segments(&rival.state, &mut rival_segs);
                carried_segs = Some(rival_segs);
                Some(rival.clone())
            }
            (verified, _) => verified,
        };
        // The overlay's bands: the visible model at the reported state (the
        // search's segments at the solution, or those at the prediction) with
        // the spread of its perpendicular position.
        // A verified answer that no rival matches, claimed or not (step 11
        // changes the status alone).
        let unambiguous = verified.is_some() && ambiguity.is_none();
        let (status, reported, covariance, band_segs) = match verified {
            Some(solution) => {
                // Across a loss there is no velocity to extrapolate.
                let previous = std::mem::replace(&mut self.last, solution.state.clone());
                self.update_joint_velocity(&previous, &solution, &joints_jumped);
                self.before_last = (self.lost_frames == 0).then_some(previous);
                self.last_tracked = solution.state.clone();
                if self.views.iter().all(|v| rotation_between(v, &solution.state) > VIEW_GAP_RAD) {
                    if self.views.len() == MAX_VIEWS {
                        self.views.remove(0);
                    }
                    self.views.push(solution.state.clone());
                }
                self.first_doubling = 0;
                self.lost_frames = 0;
                self.phase = Phase::Tracking;
                // The contrast memory learns nothing from a frame whose
                // rival is carried: its matches are not kept, and the
                // answer's are not its.
                let final_segs = match carried_segs {
                    Some(rival_segs) => rival_segs,
                    None => accepted
                        .map(|found| {
                            if self.params.remember_contrast
                                && diag.support >= self.params.remember_contrast_min_support
                            {
                                self.fade_contrast_memory();
                                self.remember_contrast(&found.segs, &found.matches);
                            }
                            found.segs
                        })
                        .unwrap_or_default(),
                };
                // An ambiguous answer, or the rival carried in its place, is
                // carried on, but not claimed; nor are the answers after it
                // until one is as well supported as before (step 11).
                let status = match ambiguity {
                    None => match self.reclaim.claim(diag.support, self.params.reclaim_after_frames) {
                        Ok(()) => Status::Tracking,
                        Err(bar) => {
                            lost_reason = Some(refusal_reason(diag.support, bar, self.params.reclaim_after_frames));
                            Status::Lost
                        }
                    },
                    Some(Ambiguity { support_ratio, distance_px, matches: [theirs, ours], .. }) => {
                        self.reclaim.ambiguous(self.params.reclaim_support_ratio);
                        let carried = if rival_carried { "; that one is carried on" } else { "" };
                        lost_reason = Some(format!(
                            "ambiguous: another verified solution {distance_px:.1} px away has {support_ratio:.2} \
                             of this one's supported outline and {theirs} matches to its {ours}{carried}"
                        ));
                        Status::Lost
                    }
                };
                (status, solution.state, Some(solution.covariance), final_segs)
            }
            None => {
                // Coast: the prediction becomes the last state, so the next
                // frame's prediction keeps the last velocity, while the
                // coasted model stays in the image at a depth near the last
                // verified one; past that, stand at the last verified state.
                self.lost_frames += 1;
                self.reclaim.lost();
                let coasted = self.prediction.clone();
                if self.plausible(&coasted) {
                    self.before_last = Some(std::mem::replace(&mut self.last, coasted));
                } else {
                    self.last = self.last_tracked.clone();
                    self.before_last = None;
                }
                self.first_doubling = self.params.range_doublings;
                self.phase = Phase::Lost;
                (Status::Lost, self.prediction.clone(), None, segs)
            }
        };
        let p = covariance.unwrap_or_else(|| {
            estimation::diagonal(&self.prior_sigmas(&self.prediction, self.params.range_doublings), n)
        });
        let bands = band_segs
            .iter()
            .map(|s| EdgeBand { a: s.a, b: s.b, sigma: SegmentSpread::of(s, &p, n).perpendicular })
            .collect();
        let corners = self.corners_at(&reported);
        self.prediction = self.predict();
        // Step 2: a frame verified with confident support (or the steady
        // bar of step 6) at its first range sizes the next window for
        // `confident_window_doublings`.
        let confident = unambiguous && at_first_range && bar.reached(diag.support, || corners.clone());
        // A claimed first-range answer short of `confident_support` sets
        // the bar of the frames that follow (step 6).
        let claimed = (status == Status::Tracking).then_some(diag.support);
        let (confident_support, ratio) = (self.params.confident_support, self.params.steady_support_ratio);
        let reached_steady = confident && bar.support < confident_support;
        self.steady.update(claimed, at_first_range, reached_steady, confident_support, ratio);
        let full = Window::full(width, height);
        self.window_doublings = self.params.range_doublings;
        self.window_all_ranges = false;
        self.window = if self.lost_frames >= self.params.search_after {
            full
        } else {
            let narrow = self.params.confident_window_doublings;
            // A narrowed window the image clips to the whole frame is the
            // widest one as well.
            match confident.then(|| self.window_at(&self.prediction, narrow, width, height)) {
                Some(window) if window.clipped(width, height) != full => {
                    self.window_doublings = narrow;
                    self.window_all_ranges = reached_steady;
                    window
                }
                _ => self.window_at(&self.prediction, self.window_doublings, width, height),
            }
        };
        let covariance = covariance.map(|p| (0..n).flat_map(|i| (0..n).map(move |j| p[i][j])).collect());
        if let Some(earlier) = &earlier {
            diag.add_earlier_times(earlier);
        }
        self.last_diagnostics = diag;
        Tracked::Outcome(FrameOutcome {
            frame,
            status,
            phase: self.phase,
            corners,
            pose: Some(formats::Pose::from(&reported.pose)),
            params: Some(reported.params),
            covariance,
            labelled: Vec::new(),
            diagnostics: Diagnostics { lost_reason, bands, ..Diagnostics::default() },
        })
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::estimation::{Match, Solution};
    use super::{
        Found, LoweParams, LoweTracker, Reclaim, State, Steady, Verified, better_supported, distinct_outline, fixtures,
        rotation_between,
    };
    use crate::geometry::{Pose, mean_point_distance};
    use crate::io::formats::InitState;
    use crate::track::lowe::params::MAX_PARAMS;
    use crate::track::lowe::projection::ModelSegment;

    /// A solution with the lid at `lid` and its variance `lid_variance`
    /// (every other parameter measured tightly).
    fn solution(lid: f64, lid_variance: f64) -> Solution {
        let mut covariance = [[0.0; MAX_PARAMS]; MAX_PARAMS];
        for (i, row) in covariance.iter_mut().enumerate().take(7) {
            row[i] = if i == 6 { lid_variance } else { 1e-8 };
        }
        let state = State { pose: Pose::from(&start_pose()), params: vec![lid] };
        Solution { state, covariance, residual_sigma: Some(1.0), rows: 40 }
    }

    fn start_pose() -> crate::io::formats::Pose {
        crate::io::formats::Pose { rotation: [0.3, 0.2, 0.1], translation: [0.0, 0.0, 1.0] }
    }

    /// The joint velocity of step 1: a step between two frames that both
    /// measured the joint; kept through a frame that did not; none after a
    /// jump to another joint value or a loss.
    #[test]
    fn a_joint_steps_only_between_frames_that_measured_it() {
        let init = InitState { pose: Some(start_pose()), params: vec![0.5], ..InitState::default() };
        let params = LoweParams::default();
        let mut tracker = LoweTracker::new(fixtures::camera(), &fixtures::hinged_box_model(), &init, params).unwrap();
        let measured = (0.3 * tracker.params.prior_joint_sigma).powi(2);
        let unmeasured = tracker.params.prior_joint_sigma.powi(2);
        let mut last = tracker.last.clone();
        let mut verify = |tracker: &mut LoweTracker, lid: f64, variance: f64, jumped: bool| {
            let s = solution(lid, variance);
            tracker.update_joint_velocity(&last, &s, &[jumped]);
            last = s.state;
            tracker.joint_velocity[0]
        };
        // The first measured frame has no measured frame before it.
        assert_eq!(verify(&mut tracker, 0.52, measured, false), 0.0);
        assert!((verify(&mut tracker, 0.55, measured, false) - 0.03).abs() < 1e-12);
        // Unmeasured: its value is the prior's; the last measured step stays.
        assert!((verify(&mut tracker, 0.40, unmeasured, false) - 0.03).abs() < 1e-12);
        // Measured again, but the step comes from an unmeasured value.
        assert!((verify(&mut tracker, 0.61, measured, false) - 0.03).abs() < 1e-12);
        assert!((verify(&mut tracker, 0.65, measured, false) - 0.04).abs() < 1e-12);
        // A jump to another joint value (step 9) is no motion; the next
        // measured step is.
        assert_eq!(verify(&mut tracker, 1.3, measured, true), 0.0);
        assert!((verify(&mut tracker, 1.34, measured, false) - 0.04).abs() < 1e-12);
        // The first frame after a loss starts from no velocity.
        tracker.lost_frames = 3;
        assert_eq!(verify(&mut tracker, 0.9, measured, false), 0.0);
    }

    /// Step 2's window holds the model at the extremes of the search
    /// range: for each vertex and image axis, the step within
    /// `search_sigmas` of the prior (after 0, 1 and 2 doublings) that moves
    /// the vertex farthest along it, one way and the other; every vertex
    /// of every such pose lies inside the window. A narrowed window holds
    /// no more than that and its margin: each side lies within the margin of
    /// the farthest vertex, give or take 3 px (2 of rounding to whole
    /// pixels, and the projection's curvature).
    #[test]
    fn the_window_holds_the_model_at_the_search_ranges_extremes() {
        let init = InitState { pose: Some(start_pose()), params: vec![0.5], ..InitState::default() };
        let tracker =
            LoweTracker::new(fixtures::camera(), &fixtures::hinged_box_model(), &init, LoweParams::default()).unwrap();
        let (width, height) = (tracker.camera.width as usize, tracker.camera.height as usize);
        let (n, k) = (tracker.n(), tracker.params.search_sigmas);
        let state = tracker.last.clone();
        let lin = super::Linearised::at(&tracker.geometry, &state, tracker.centre).unwrap();
        for doublings in 0..=tracker.params.range_doublings {
            let window = tracker.window_at(&state, doublings, width, height);
            assert!(window.area() < width * height, "doublings {doublings}: the whole frame");
            let sigmas = tracker.prior_sigmas(&state, doublings);
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for (p, rows) in lin.points.iter().zip(&lin.derivatives) {
                let (_, pixel_rows) = super::projection::project_with_rows(&tracker.camera, *p, rows, n).unwrap();
                for row in pixel_rows {
                    let spread = (0..n).map(|j| (sigmas[j] * row[j]).powi(2)).sum::<f64>().sqrt();
                    for sign in [-1.0, 1.0] {
                        let step: Vec<f64> =
                            (0..n).map(|j| sign * k * sigmas[j] * sigmas[j] * row[j] / spread).collect();
                        for c in tracker.corners_at(&state.corrected(&step, tracker.centre, &tracker.limits)) {
                            let inside = c[0] >= f64::from(window.x0)
                                && c[0] < f64::from(window.x1)
                                && c[1] >= f64::from(window.y0)
                                && c[1] < f64::from(window.y1);
                            assert!(inside, "doublings {doublings}: vertex at {c:?} outside {window:?}");
                            for a in 0..2 {
                                lo[a] = lo[a].min(c[a]);
                                hi[a] = hi[a].max(c[a]);
                            }
                        }
                    }
                }
            }
            if doublings < tracker.params.range_doublings {
                let beyond = [
                    lo[0] - f64::from(window.x0),
                    lo[1] - f64::from(window.y0),
                    f64::from(window.x1) - hi[0],
                    f64::from(window.y1) - hi[1],
                ];
                let most = tracker.params.window_margin_px + 3.0;
                assert!(beyond.iter().all(|b| *b <= most), "doublings {doublings}: {beyond:?} px beyond the range");
            }
        }
    }

    #[test]
    fn a_steadily_part_supported_object_lowers_the_bar_after_a_confident_frame() {
        let (confident, ratio) = (0.8, 0.9);
        let bar = |steady: &Steady| steady.bar(confident, ratio);
        let mut steady = Steady::default();
        assert_eq!(bar(&steady), confident);
        // No confident frame yet: a part-supported one sets nothing.
        steady.update(Some(0.5), true, false, confident, ratio);
        assert_eq!(bar(&steady), confident);
        steady.update(Some(0.9), true, false, confident, ratio);
        assert_eq!(bar(&steady), confident, "a confident frame needs no lower bar");
        // Half hidden: every range searched, the first range's answer kept.
        steady.update(Some(0.5), true, false, confident, ratio);
        let steady_bar = bar(&steady);
        assert!((steady_bar - 0.45).abs() < 1e-12, "{steady_bar}");
        // Answers that reach the steady bar keep the reference, also when
        // better supported.
        steady.update(Some(0.46), true, true, confident, ratio);
        steady.update(Some(0.7), true, true, confident, ratio);
        assert_eq!(bar(&steady), steady_bar);
        // One that did not reach it (too little support, or too far from
        // the prediction) was searched in full: its support is the new one.
        steady.update(Some(0.4), true, false, confident, ratio);
        let lower = bar(&steady);
        assert!((lower - 0.36).abs() < 1e-12, "{lower}");
        steady.update(Some(0.6), true, false, confident, ratio);
        assert!((bar(&steady) - 0.54).abs() < 1e-12);
        // An answer of a wider range keeps no steady support.
        steady.update(Some(0.6), false, false, confident, ratio);
        assert_eq!(bar(&steady), confident);
        // Nor does a frame not claimed (lost, ambiguous or waiting), and it
        // takes a confident frame again before one does.
        steady.update(Some(0.5), true, false, confident, ratio);
        assert!(bar(&steady) < confident);
        steady.update(None, false, false, confident, ratio);
        assert_eq!(bar(&steady), confident);
        steady.update(Some(0.5), true, false, confident, ratio);
        assert_eq!(bar(&steady), confident, "no confident frame since the doubt");
        steady.update(Some(0.85), true, false, confident, ratio);
        steady.update(Some(0.5), true, false, confident, ratio);
        assert!(bar(&steady) < confident);
        // A ratio of 0 keeps none.
        let mut off = Steady::default();
        off.update(Some(0.9), true, false, confident, 0.0);
        off.update(Some(0.5), true, false, confident, 0.0);
        assert_eq!(off.bar(confident, 0.0), confident);
    }

    /// Step 11: after an ambiguous answer, an answer is claimed once it has
    /// the given share of the last claimed frame's support or completes a
    /// run of unambiguous answers; a loss ends the wait.
    #[test]
    fn answers_after_an_ambiguous_one_are_claimed_once_supported_as_before_or_after_a_run() {
        let mut reclaim = Reclaim::default();
        assert_eq!(reclaim.claim(0.6, 8), Ok(()), "nothing ambiguous yet");
        reclaim.ambiguous(0.9);
        let bar = reclaim.claim(0.4, 8).expect_err("0.4 < 0.9 of 0.6");
        assert!((bar - 0.54).abs() < 1e-12, "{bar}");
        // A second ambiguous frame keeps the bar and counts the run again.
        for _ in 0..5 {
            assert!(reclaim.claim(0.4, 8).is_err());
        }
        reclaim.ambiguous(0.9);
        for run in 1..8 {
            assert_eq!(reclaim.claim(0.4, 8), Err(bar), "answer {run} of the run");
        }
        assert_eq!(reclaim.claim(0.4, 8), Ok(()), "the eighth in a row is claimed");
        // The reference is now that answer's support.
        reclaim.ambiguous(0.9);
        assert_eq!(reclaim.claim(0.35, 8), Err(0.9 * 0.4));
        assert_eq!(reclaim.claim(0.37, 8), Ok(()), "as well supported as 0.9 of the last claim");
        // Without a count, only the support claims.
        reclaim.ambiguous(0.9);
        for _ in 0..50 {
            assert!(reclaim.claim(0.2, 0).is_err());
        }
        // A loss ends the wait; a ratio of 0 never waits.
        reclaim.lost();
        assert_eq!(reclaim.claim(0.05, 8), Ok(()));
        reclaim.ambiguous(0.0);
        assert_eq!(reclaim.claim(0.01, 0), Ok(()));
        // Ambiguous before any frame was claimed: only the run claims.
        let mut first = Reclaim::default();
        first.ambiguous(0.9);
        for run in 1..8 {
            assert_eq!(first.claim(0.9, 8), Err(f64::INFINITY), "answer {run} of the run");
        }
        assert_eq!(first.claim(0.9, 8), Ok(()), "the eighth in a row is claimed");
        let mut never = Reclaim::default();
        never.ambiguous(0.9);
        assert!((0..50).all(|_| never.claim(1.0, 0).is_err()), "no run counted, no reference");
        let mut off = Reclaim::default();
        off.ambiguous(0.0);
        assert_eq!(off.claim(0.01, 0), Ok(()), "a ratio of 0 never waits");
    }

    /// The refusals' reasons name the support, what would claim, and
    /// whether a frame was claimed before the ambiguous one.
    #[test]
    fn refusal_reasons_say_what_would_claim() {
        use super::refusal_reason;
        assert_eq!(
            refusal_reason(0.43, 0.47, 8),
            "after an ambiguous answer: 43 % of the outline supported, 47 % needed (or 8 unambiguous answers in a row)"
        );
        assert_eq!(
            refusal_reason(0.43, 0.47, 0),
            "after an ambiguous answer: 43 % of the outline supported, 47 % needed"
        );
        assert_eq!(
            refusal_reason(0.53, f64::INFINITY, 8),
            "after an ambiguous answer, with no frame claimed before it: 53 % of the outline supported \
             (8 unambiguous answers in a row needed)"
        );
        assert_eq!(
            refusal_reason(0.53, f64::INFINITY, 0),
            "after an ambiguous answer, with no frame claimed before it: 53 % of the outline supported"
        );
    }

    /// Step 10: a verified solution far from the answer, with as many
    /// matches and nearly its support, makes it ambiguous; a less supported
    /// one, one with fewer matches, one near the answer, or the test turned
    /// off does not.
    #[test]
    fn an_answer_is_ambiguous_when_a_far_solution_is_about_as_well_supported() {
        let init = InitState { pose: Some(start_pose()), params: vec![0.5], ..InitState::default() };
        let mut tracker =
            LoweTracker::new(fixtures::camera(), &fixtures::hinged_box_model(), &init, LoweParams::default()).unwrap();
        let answer = Found {
            solution: solution(0.5, 1e-4),
            matches: vec![fixture_match(); 12],
            segs: Vec::new(),
            support: Some((200, 400)),
            doubling: 0,
        };
        // The lid is a third of the model's vertices, 1 m away.
        tracker.params.ambiguous_distance_px = 1.0;
        let far = solution(1.2, 1e-4);
        let near = solution(0.51, 1e-4);
        let far_px = mean_point_distance(&tracker.corners_at(&answer.solution.state), &tracker.corners_at(&far.state));
        assert!(far_px > 1.0, "the lid 0.7 rad away moves the vertices {far_px} px on average");
        let verified =
            |supported, matches, solution: &Solution| Verified { supported, matches, solution: solution.clone() };
        let rival = tracker
            .ambiguity(&answer, &[verified(200, 12, &answer.solution), verified(192, 12, &far)])
            .expect("ambiguous");
        assert!((rival.support_ratio - 0.96).abs() < 1e-12);
        assert!((rival.distance_px - far_px).abs() < 1e-9);
        assert_eq!(rival.rival.state.params, far.state.params, "the rival's own fit");
        assert!(tracker.ambiguity(&answer, &[verified(188, 14, &far)]).is_none(), "less supported");
        assert!(tracker.ambiguity(&answer, &[verified(230, 11, &far)]).is_none(), "fewer matches");
        // With 0.75 of the answer's 12 matches needed, 9 are enough, 8 not.
        tracker.params.ambiguous_match_ratio = 0.75;
        assert!(tracker.ambiguity(&answer, &[verified(230, 8, &far)]).is_none(), "too few matches");
        let fewer = tracker.ambiguity(&answer, &[verified(230, 9, &far)]).expect("enough matches");
        assert_eq!(fewer.matches, [9, 12]);
        tracker.params.ambiguous_match_ratio = 1.0;
        assert!(tracker.ambiguity(&answer, &[verified(230, 12, &near)]).is_none(), "the same answer");
        tracker.params.ambiguous_support_ratio = 0.0;
        assert!(tracker.ambiguity(&answer, &[verified(230, 12, &far)]).is_none(), "the test off");
    }

    fn fixture_match() -> Match {
        Match { edge: 0, interval: [0.0, 1.0], endpoints: [[0.0, 0.0], [1.0, 0.0]], image: 0 }
    }

    /// An edge's matches of one contrast add their length on its dark
    /// side; matches of both contrasts add nothing; a match running along
    /// the edge is not counted; the memory fades by
    /// [`super::CONTRAST_MEMORY_DECAY`] a learning frame and starts again when other
    /// faces of the edge face the camera.
    #[test]
    fn an_edge_remembers_the_contrast_of_its_matches_while_its_faces_stay() {
        use super::{CONTRAST_MEMORY_DECAY, EdgeContrast};
        use crate::track::lowe::segments::ImageSegment;
        use std::f64::consts::FRAC_PI_2;
        let init = InitState { pose: Some(start_pose()), params: vec![0.5], ..InitState::default() };
        let mut tracker =
            LoweTracker::new(fixtures::camera(), &fixtures::hinged_box_model(), &init, LoweParams::default()).unwrap();
        let piece = |y: f64, length: f64, direction: f64| ImageSegment {
            start: [0.0, y],
            end: [length, y],
            midpoint: [0.5 * length, y],
            length,
            orientation: 0.0,
            strength: 1.0,
            direction,
            pixels: length as u32,
        };
        let (down, up, along) = (FRAC_PI_2, -FRAC_PI_2, 0.0);
        tracker.image_segments =
            vec![piece(0.0, 30.0, down), piece(0.5, 20.0, down), piece(40.0, 30.0, down), piece(40.2, 25.0, up)];
        tracker.image_segments.push(piece(0.2, 50.0, along));
        let edge = |edge: usize, y: f64, facing: u8| ModelSegment { edge, facing, ..segment([0.0, y], [100.0, y]) };
        let segs = vec![edge(0, 0.0, 0b01), edge(1, 40.0, 0b01)];
        assert_eq!(segs[0].normal(), [0.0, 1.0]);
        let images = tracker.image_segments.clone();
        let matched = |seg: &ModelSegment, image: usize| Match {
            edge: seg.edge,
            interval: seg.interval,
            endpoints: [images[image].start, images[image].end],
            image,
        };
        let matches: Vec<Match> =
            [(0, 0), (0, 1), (1, 2), (1, 3), (0, 4)].iter().map(|&(m, i)| matched(&segs[m], i)).collect();
        tracker.remember_contrast(&segs, &matches);
        assert_eq!(tracker.contrast_memory[0], EdgeContrast { facing: 0b01, dark_side_px: 50.0 });
        assert_eq!(tracker.contrast_memory[1], EdgeContrast { facing: 0b01, dark_side_px: 0.0 });
        assert_eq!(tracker.contrast_memory[2], EdgeContrast::default());

        tracker.fade_contrast_memory();
        assert!((tracker.contrast_memory[0].dark_side_px - 50.0 * CONTRAST_MEMORY_DECAY).abs() < 1e-12);
        // Edge 0 with its other face turned to the camera: what it showed
        // before lies between other surfaces.
        let turned = vec![edge(0, 0.0, 0b11), edge(1, 40.0, 0b01)];
        let matches = vec![matched(&turned[0], 3), matched(&turned[1], 3)];
        tracker.remember_contrast(&turned, &matches);
        assert_eq!(tracker.contrast_memory[0], EdgeContrast { facing: 0b11, dark_side_px: -25.0 });
        assert_eq!(tracker.contrast_memory[1], EdgeContrast { facing: 0b01, dark_side_px: -25.0 });
    }

    fn segment(a: [f64; 2], b: [f64; 2]) -> ModelSegment {
        let rows = [[0.0; MAX_PARAMS]; 2];
        ModelSegment { edge: 0, interval: [0.0, 1.0], a, b, da: rows, db: rows, facing: 0 }
    }

    fn length((p, q): ([f64; 2], [f64; 2])) -> f64 {
        (q[0] - p[0]).hypot(q[1] - p[1])
    }

    #[test]
    fn rotation_between_two_views_is_the_angle_of_their_relative_turn() {
        let state = |axis_angle: DVec3| State {
            pose: Pose::from_axis_angle(axis_angle, DVec3::new(0.0, 0.0, 1.0)),
            params: Vec::new(),
        };
        let a = state(DVec3::new(0.3, -0.2, 0.1));
        // a turned a further 25° about some axis, in the camera frame.
        let turn = Pose::from_axis_angle(DVec3::new(1.0, 2.0, -2.0).normalize() * 25f64.to_radians(), DVec3::ZERO);
        let b = State { pose: Pose { rotation: turn.rotation * a.pose.rotation, ..a.pose }, params: Vec::new() };
        assert!((rotation_between(&a, &b) - 25f64.to_radians()).abs() < 1e-12);
        assert!((rotation_between(&b, &a) - 25f64.to_radians()).abs() < 1e-12);
        assert!(rotation_between(&a, &a) < 1e-15);
    }

    #[test]
    fn an_outline_counts_two_edges_on_one_line_once() {
        let segs = [
            segment([0.0, 0.0], [100.0, 0.0]),
            // The same line, drawn the other way, 0.4 px off: left out.
            segment([100.0, 0.4], [0.0, 0.4]),
            // Half along the first, half beyond it: the half beyond stays.
            segment([50.0, -0.3], [150.0, -0.3]),
            // Parallel but 3 px away, and one crossing: both stay whole.
            segment([0.0, 3.0], [100.0, 3.0]),
            segment([50.0, -50.0], [50.0, 50.0]),
        ];
        let pieces = distinct_outline(&segs);
        let lengths: Vec<f64> = pieces.iter().map(|&(p, q, _)| length((p, q))).collect();
        assert_eq!(pieces.len(), 4, "{pieces:?}");
        assert_eq!(pieces.iter().map(|&(_, _, k)| k).collect::<Vec<_>>(), vec![0, 2, 3, 4]);
        for (got, want) in lengths.iter().zip([100.0, 50.0, 100.0, 100.0]) {
            assert!((got - want).abs() < 1e-9, "{lengths:?}");
        }
        assert!((pieces[1].0[0] - 100.0).abs() < 1e-9, "the piece beyond starts at x = 100: {pieces:?}");
    }

    #[test]
    fn another_joint_value_needs_more_supported_samples_the_farther_it_moves() {
        // The lid shut against the lid 1.4 rad open (hinged box at
        // 25 px/frame, frame 40): far more samples, a higher fraction.
        assert!(better_supported((967, 1000), (641, 955), 1.4));
        // 12 % more, 1.7 rad away: a lid hidden by an occluder against the
        // lid shut; the margin there is 22 %.
        assert!(!better_supported((493, 700), (437, 900), 1.7));
        // The same gain 0.3 rad away passes (margin 8 %).
        assert!(better_supported((493, 700), (437, 900), 0.3));
        // More samples at a lower fraction: a part turned onto a clutter
        // line (772 of 1008 against 623 of 674).
        assert!(!better_supported((772, 1008), (623, 674), 1.2));
        // A small outline: at least 20 samples more.
        assert!(!better_supported((115, 120), (100, 120), 0.2));
        assert!(better_supported((120, 120), (100, 120), 0.2));
    }
}
