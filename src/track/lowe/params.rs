//! Parameters of the `lowe` tracker (paper 001): the paper's where it gives
//! them, documented choices otherwise, each with its range, checked by
//! [`LoweParams::validate`].

use serde::{Deserialize, Serialize};

use super::segments::SegmentParams;
use crate::Result;
use crate::bounds::{Interval, check_count};

/// Most joints a model may have (the parameter vector is 6 + joints long).
pub const MAX_JOINTS: usize = 10;
/// Length of the longest parameter vector: rotation, translation, joints.
pub const MAX_PARAMS: usize = 6 + MAX_JOINTS;
/// Most search branches per frame a configuration may ask for.
pub const MAX_BRANCHES: usize = 100;
/// Most Gauss–Newton iterations per solution.
pub const MAX_ITERATIONS: usize = 20;

/// Parameters of the Lowe tracker (paper 001), all with defaults, so a
/// `--config` TOML file may set any subset (unknown keys are refused).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LoweParams {
    /// σ of the Laplacian of Gaussian (001: 1.2). Range: [0.5, 4].
    pub log_sigma: f32,
    /// Least slope across a zero crossing, LoG units (see
    /// `ZeroCrossingParams::min_slope`). Range: [0, 1000].
    pub min_slope: f32,
    /// Prior standard deviation of the rotation about each camera axis
    /// through the model's centre from the velocity-extrapolated prediction,
    /// radians (001: "a prior standard deviation per parameter"; no number).
    /// 0.05 rad ≈ 3° of unpredicted turn per frame. Range: (0, 1].
    pub prior_rotation_sigma: f64,
    /// Prior standard deviation of the model centre's position along each
    /// camera axis, as the image motion it causes across the line of sight:
    /// px, converted to metres at the predicted depth (σ = px · Z / f_x) so
    /// that one value suits large and small objects. 7 px: on the synthetic
    /// hinged box at 20 px/frame 5 px lost 3 frames and 7 px none; on ViSP's
    /// castle (a model a quarter of the box's size) a fixed 0.015 m
    /// (≈ 17 px there) lost the object at frame 7, 7 px holds all 40 frames.
    /// Range: (0, 1000].
    pub prior_translation_px: f64,
    /// Prior standard deviation of each joint value, radians.
    /// Range: (0, 3.2].
    pub prior_joint_sigma: f64,
    /// Standard deviation of a correct segment's endpoint from its model
    /// line, px: the unit of the measurement rows of eq. 1 and the spread a
    /// true match adds to the prediction's own (eq. 2) in eq. 3.
    /// Range: (0, 20].
    pub measurement_sigma_px: f64,
    /// Length of an image segment whose ends have `measurement_sigma_px`,
    /// px: a segment of length L is fitted to L edgels, so its ends get
    /// σ·sqrt(reference / L) and long segments weigh more in eq. 1 than
    /// short ones. 40 px: on the hinged box (300 frames, 20 px/frame) it
    /// lowered the mean vertex error from 0.70 to 0.39 px against equal
    /// weights (0), 20 px gave 0.49. Range: [0, 4096].
    pub reference_length_px: f64,
    /// A solution is rejected when its residual σ (001: σ² = ‖Jx − e‖² /
    /// (m − n)) exceeds this many `measurement_sigma_px` ("much greater
    /// than the standard deviation of the measurement errors").
    /// Range: [1, 100].
    pub residual_ratio: f64,
    /// The search's initial set grows while the product of its matches'
    /// probabilities stays above this (001: 0.9). Range: (0, 1).
    pub set_probability: f64,
    /// Candidates below this probability of correctness are not listed.
    /// Range: [0, 1).
    pub min_probability: f64,
    /// After acceptance, further matches join when their probability is at
    /// least this. Range: (0, 1].
    pub lock_probability: f64,
    /// Bound on the search branches per frame (001: 5). Range: 1 ..= [`MAX_BRANCHES`].
    pub max_branches: usize,
    /// How often the prior ranges double when too few candidates are found
    /// (001: up to 2). Range: 0 ..= 4.
    pub range_doublings: usize,
    /// Candidate matches are looked for within this many standard
    /// deviations of a predicted edge's position and orientation.
    /// Range: [1, 10].
    pub search_sigmas: f64,
    /// Gauss–Newton iterations per solution (001: "one or two").
    /// Range: 1 ..= [`MAX_ITERATIONS`].
    pub iterations: usize,
    /// Re-predictions after acceptance ("locking on", Figs. 3–6).
    /// Range: 0 ..= 20.
    pub lock_iterations: usize,
    /// A frame is `tracking` only when its matches cover at least this
    /// fraction of the visible model edges' length. Unoccluded frames of the
    /// box scenes cover 0.6–0.9; with half the edges hidden 0.3–0.4, and 0.3
    /// lost 5 of 300 hinged-box frames that 0.25 holds (no false tracking at
    /// up to 20 px/frame either way). Range: [0, 1].
    pub min_coverage: f64,
    /// A frame is `tracking` only when at least this fraction of the
    /// visible model edges' length has a zero crossing along it (within
    /// 1 px, at the edge's orientation). Frames on target of the box scenes
    /// have 0.69–0.97 unoccluded and 0.32–0.34 at their lowest with half
    /// the edges hidden; frames 70–230 px off that passed the coverage test
    /// after a jump had 0.09–0.14. Range: [0, 1].
    pub min_support: f64,
    /// A solution with at most this many matches more than a search node's
    /// (⌊n/2⌋ + 1) is not verified when its residual σ is above
    /// `loose_fit_residual_ratio` measurement σ. Over 15 554 tracking
    /// frames of 54 synthetic sequences (box and hinged box, 4–30 px/frame,
    /// half the edges hidden, noise σ 8), 3 and 7 (with a ratio of 1.4)
    /// singled out 11 of the 62 frames more than 5 px off and 3 of the
    /// others; the residual alone (1.4) would have taken 14 and 90.
    /// Range: 0 ..= 100.
    pub loose_fit_extra_matches: usize,
    /// See `loose_fit_extra_matches`. Range: [0.1, 100].
    pub loose_fit_residual_ratio: f64,
    /// A verified solution whose outline support (as `min_support`) is
    /// below this does not end the search: the wider prior ranges are
    /// searched too and a verified solution reaching it there is taken
    /// instead, as is one that clears `search_min_support` and
    /// `search_min_coverage` with more supported outline and more matches
    /// (the tracker's module doc, step 6). Frames on target of the
    /// unoccluded box scenes have 0.8–0.97; at 30 px/frame, solutions
    /// 8–16 px off after abrupt reversals had 0.27–0.64. 0.8 took the
    /// false-tracking frames of six 300-frame sequences at 30 px/frame from
    /// 5 / 0 / 3 (box) and 3 / 3 / 2 (hinged box) to 0 / 0 / 2 and
    /// 2 / 1 / 1; taking the best supported solution of all ranges instead
    /// lost 22 frames of the occluded hinged box. 1 searches every range
    /// on every frame; 0 ends the search at the first verified solution, as
    /// the paper does. Range: [0, 1].
    pub confident_support: f64,
    /// While tracking, after a frame whose search of every range found
    /// its answer at the first range (verified, unambiguous, claimed) with
    /// less than `confident_support`, this share of that frame's outline
    /// support stands in for `confident_support` (when lower) in
    /// narrowing the next window and in widening it, for an answer whose
    /// model vertices lie on average within `ambiguous_distance_px` of the
    /// prediction's; every range is still searched, in the narrowed
    /// window's features. An answer short of that widens the window and is
    /// searched again, its support the new reference (the tracker's module
    /// doc, steps 2 and 6). Only after a frame claimed with
    /// `confident_support` since the last frame not claimed. An object
    /// steadily part hidden then searches the window of a confident frame,
    /// not the widest one: at 0.9 the box half hidden at 4 and 20 px/frame
    /// took 0.88 and 0.95 ms per frame (median, one thread) instead of
    /// 1.91 (300 and 296 frames tracking against 300 and 295, none false,
    /// `benches/vs_visp.sh`; ViSP's edge tracker 0.70 and 0.77 ms). Over
    /// the 360 stress runs of `benches/lowe_sweep.sh` (seeds 0–29) it
    /// tracked 30 frames more, with one more false frame (26 against 25)
    /// and as many with the lid more than 2° off (984), but it changes
    /// which frames of a scene are found ambiguous, and two scenes of the
    /// tests lose frames: the hinged box half hidden at 4 px/frame (frame
    /// 268 of 300 ambiguous) and at 30 px/frame, seed 1 (262 frames
    /// tracking, against 277); and on ViSP's real `mbt/cube` video the
    /// forward and backward runs of `roundtrip` disagree by 0.717 px mean
    /// against 0.302, for no time saved. So the default, 0, keeps
    /// `confident_support` on every frame (RESULTS.md). Range: [0, 1].
    pub steady_support_ratio: f64,
    /// While tracking, when the search at the velocity-extrapolated
    /// prediction finds no solution with `confident_support`, search again
    /// from the last solution itself and from it moved by half its
    /// velocity, and take a solution found there that has
    /// `confident_support`, more of its outline supported and no fewer
    /// matches (the tracker's module doc, step 6). An abrupt reversal puts
    /// the extrapolation twice the last step from the object, these
    /// predictions one step or less. Over the 180 sequences of the stress
    /// sweep (`benches/lowe_sweep.sh`, seeds 0–14) it took the frames
    /// tracking from 49 496 to 50 819 and the false-tracking frames from
    /// 94 to 75. After a frame short of `confident_support` itself, the
    /// second look is made only when the first answer is unverified or has
    /// less than 0.9 of that frame's support, so a steadily part-supported
    /// object is not searched twice on every frame (on ViSP's `mbt/cube`
    /// it was: 9.47 search branches per frame, 4.09 with that rule, 3.25
    /// without the second look). `false` searches at the extrapolation
    /// alone, as the paper does.
    pub search_slower_predictions: bool,
    /// While tracking, a solution found only after the prior ranges were
    /// doubled (the prediction missed) is verified only when its outline
    /// support (as `min_support`) is at least this part of the last
    /// frame's (the tracker's module doc, step 7). Over 84 sequences of
    /// 300 frames (`benches/lowe_sweep.sh --seeds "0 1 2 3 4 5 6"`), 0 / 0.6 /
    /// 0.7 / 0.8 gave 69 / 42 / 38 / 35 frames tracking more than 5 px off and
    /// 23 719 / 23 733 / 23 711 / 23 649 frames tracking. 0 turns the test
    /// off. Range: [0, 1].
    pub widened_support_ratio: f64,
    /// Lost frames after which the whole image is searched (the window of
    /// interest opens to the full frame and the last solution is tried at
    /// positions across it; see the tracker's module doc). Range: 1 ..= 1000.
    pub search_after: usize,
    /// Least coverage (as `min_coverage`) of a solution after a loss, at
    /// the widened prediction or by the whole-image search, and of a wider
    /// range's solution that replaces a weakly supported one (see
    /// `confident_support`). Re-acquisitions
    /// on target on the box scenes cover 0.88–0.97; at 25–30 px/frame,
    /// solutions 120–200 px off covered 0.27–0.56 with support 0.50–0.56.
    /// Range: [0, 1].
    pub search_min_coverage: f64,
    /// Least support (as `min_support`) of a solution after a loss, and of
    /// a wider range's solution that replaces a weakly supported one: higher
    /// than `min_support`, because the search tries dozens of positions over
    /// the clutter. Re-acquisitions on target on the box scenes have
    /// 0.90–0.98. Range: [0, 1].
    pub search_min_support: f64,
    /// Largest standard deviation of a re-acquisition's rotation (each of
    /// the three rotation parameters' in its covariance P, eq. 2), radians:
    /// after a loss a solution whose matches leave the orientation loose
    /// is not verified. A box seen face on is a rectangle, and the
    /// background's rectangles fit it with the tilt barely fixed. Over 120
    /// sequences of 300 frames (`benches/lowe_sweep.sh --seeds "0 1 2 3 4
    /// 5 6 7 8 9"`), the 188 re-acquisitions on target had at most 0.87°,
    /// the 7 that were 98–143 px off 3.1–7.9°. π turns the test off.
    /// Range: (0, π].
    pub search_max_rotation_sigma: f64,
    /// Extra margin of the window of interest around the predicted model,
    /// px, on top of the search range. Range: [0, 4096].
    pub window_margin_px: f64,
    /// Doublings of the prior ranges that the next frame's window of
    /// interest is sized for after a frame verified with
    /// `confident_support` at its first range; after any other frame the
    /// window is sized for `range_doublings`. A frame whose narrowed
    /// window gives no solution with `confident_support` in its ranges
    /// widens it to the widest and is searched again
    /// ([`crate::track::Tracker::track_or_widen`]), so the wider ranges are
    /// searched with their own features, as with the widest window. The
    /// default, 0, sizes it for the first range, each vertex's reach
    /// bounded on its own: on the rendered box at 4 px/frame those windows
    /// hold about 47 000 pixels on average against about 227 000 for the
    /// widest, and a frame takes less than half the time (BENCHMARKS.md, "A
    /// narrower window after a confident frame" and "A narrowed window
    /// bounded vertex by vertex"). `range_doublings` keeps the widest
    /// window on every frame. Range: 0 ..= `range_doublings`.
    pub confident_window_doublings: usize,
    /// Widest gap between a matched model edge and an unmatched, nearly
    /// parallel neighbour that the search tries the other way round after
    /// a verified solution, px (the two sides of a thin face; see
    /// [`super::search`], step 6); 0 tries none. 8 px: on the hinged box
    /// (300 frames each) the frames with the lid more than 2° off went from
    /// 24 to 2 at 4 px/frame, 31 to 1 at 20 px/frame and 28 to 13 with half
    /// the edges hidden; 6 px left 3 at 20 px/frame (the lid's 1 cm front
    /// is 2–6 px wide there). Range: [0, 50].
    pub swap_gap_px: f64,
    /// A swap of `swap_gap_px` (see [`super::search`], step 6) that covers
    /// no less of the model with as many matches is kept as well when its
    /// residual σ is at most this share of the solution's. 0 keeps none
    /// that way. 0.8: on frame 104 of the hinged box at 20 px/frame the
    /// lid's 1 cm front showed one line, taken by the wrong one of its two
    /// edges (lid 2.1° off); the swap to the other covered 5 px more, short
    /// of a quarter of its length, at residual σ 0.58 px against 0.84 px.
    /// With 0.8 no frame of that scene is more than 2° off (max 1.85°).
    /// Over the 180 stress runs (`benches/lowe_sweep.sh`, seeds 0–14) the
    /// hinged-box frames tracking with the lid more than 2° off went from
    /// 914 to 788 and the mean vertex error on target fell 2–5 % on the
    /// hinged box (the box's runs unchanged), for 50 964 → 50 882 frames
    /// tracking and 26 → 28 false, no run above 1 %; on seeds 15–29 the
    /// lid frames 822 → 597, the error 3–6 % lower, 50 741 → 50 750
    /// frames tracking, 20 → 20 false, none above 1 %.
    /// Range: [0, 1].
    pub swap_residual_ratio: f64,
    /// A verified answer is reported `lost` (its state still carried to
    /// the next frame) when another verified solution of the frame's
    /// searches (wider ranges, slower predictions, the whole-image search,
    /// other joint values: the tracker's module doc, step 10) has at least
    /// `ambiguous_match_ratio` of its matches, at least this share of the
    /// answer's supported outline samples, and the model's vertices on
    /// average more than `ambiguous_distance_px` away: the image supports
    /// two different answers about equally, and the tracker cannot say
    /// which it is on.
    /// Over the 180 runs of the stress sweep (`benches/lowe_sweep.sh`,
    /// seeds 0–14), 0.95 took the frames tracking more than 5 px off from
    /// 63 to 26, the runs with more than 1 % of them from 5 to none, and
    /// the frames tracking from 51 109 to 50 964; on seeds 15–29, 46 → 20,
    /// 2 → none and 50 885 → 50 741. 0 turns the test off. Range: [0, 10].
    pub ambiguous_support_ratio: f64,
    /// See `ambiguous_support_ratio`: the least share of the answer's
    /// matches a rival needs (1: as many). A wrong answer can take more
    /// image segments than the true one where clutter lines up with the
    /// model, and the true one is then a rival with fewer matches. 0.75
    /// takes the frames tracking more than 5 px off from 14 to 6 over the
    /// 180 stress runs of seeds 0–14 (`benches/lowe_sweep.sh`) and from 11
    /// to 9 on seeds 15–29, for 0.6 % and 0.5 % fewer frames tracking; but
    /// the hinged box half hidden at 4 px/frame (the acceptance scene) then
    /// reports 6 frames on target `lost` as ambiguous or after an ambiguous
    /// one, where every frame should be held, so the default stays 1
    /// (RESULTS.md). Range: [0, 10].
    pub ambiguous_match_ratio: f64,
    /// See `ambiguous_support_ratio`: the mean distance between the two
    /// answers' projected model vertices above which they are different
    /// answers, px (`pipetrack score` counts a frame more than 5 px off as
    /// false tracking). Range: (0, 4096].
    pub ambiguous_distance_px: f64,
    /// An ambiguous frame's rival (see `ambiguous_support_ratio`) with at
    /// least this share of the answer's supported outline samples is
    /// carried on to the next frame in the answer's place (its pose, joint
    /// values and covariance; the frame is still reported `lost`). 0 never
    /// carries a rival. The rival is often the worse answer: over the 180
    /// stress runs of seeds 0–14 (`benches/lowe_sweep.sh`, the other
    /// settings by default) 1.2 leaves the false frames at 24 and takes
    /// the frames tracking from 50 787 to 50 561; the box half hidden at 10
    /// px/frame, seed 0, carried a rival 23.5 px off the box at frame 66
    /// and was lost for 29 frames (RESULTS.md). Range: [0, 10].
    pub ambiguous_carry_ratio: f64,
    /// After an ambiguous answer (see `ambiguous_support_ratio`) the
    /// answers that follow are carried on as before but reported `lost`
    /// until one has at least this share of the outline support of the
    /// last frame reported `tracking` (the tracker's module doc, step 11).
    /// On ViSP's real `rbt/sequence` video the cube was carried off it
    /// through a run of ambiguous frames, and 12 of the answers between
    /// them, 25–125 px off with 26–48 % of their outline supported, were
    /// reported `tracking`, where the last frame reported before the first
    /// ambiguity had 59 % (RESULTS.md). Over the 180 stress runs of seeds
    /// 0–14 (`benches/lowe_sweep.sh`), 0.9 with `reclaim_after_frames` 8
    /// takes the frames tracking more than 5 px off from 22 to 14 and the
    /// frames tracking from 50 760 to 50 622; on seeds 15–29, 14 → 11 and
    /// 50 417 → 50 320. When no frame was reported `tracking` before the
    /// ambiguous one (the first frames ambiguous), no support claims and
    /// only `reclaim_after_frames` does. 0 claims every unambiguous
    /// answer. Range: [0, 2].
    pub reclaim_support_ratio: f64,
    /// See `reclaim_support_ratio`: the answer that makes this many
    /// unambiguous answers in a row since the last ambiguous one is claimed
    /// whatever its support (an occluder that arrives with the ambiguity
    /// keeps the support of answers on target low). 0: only the support
    /// claims. Range: [0, 1000].
    pub reclaim_after_frames: usize,
    /// Whether a model edge's contrast, as its matches showed it on the
    /// last verified frames, chooses between two lines of opposite
    /// contrast side by side on it while locking on ([`super::search`],
    /// step 4), and whether the verification then counts along it only the
    /// zero crossings of that contrast (the tracker's module doc, step 7).
    /// On by default, with `remember_contrast_min_support` 0.6. Over the
    /// 360 runs of the stress sweep (`benches/lowe_sweep.sh`, seeds 0–14
    /// and 15–29), against the memory off: the mean vertex error of the
    /// frames on target 12–21 % lower in every scene, the hinged-box frames
    /// with the lid more than 2° off 788 → 580 and 597 → 487, the frames
    /// tracking more than 5 px off 28 → 24 and 20 → 14, no run above
    /// 1 % either way, for 50 882 → 50 787 and 50 750 → 50 402 frames
    /// tracking. The slow hinged box of the acceptance runs has no frame
    /// with the lid more than 2° off (2 without).
    pub remember_contrast: bool,
    /// With `remember_contrast`, the contrast memory learns only from
    /// verified frames with at least this share of their visible outline
    /// supported (zero crossings along it, the tracker's module doc, step
    /// 7), and fades only on those: behind an occluder, where a fit to a
    /// line beside an edge is the likelier, it keeps what it learnt before.
    /// 0 learns from every verified frame. With 0, the hinged box half
    /// hidden at 20 px/frame, seed 7, has 4 false frames (at 239, under the
    /// band, a lid edge took a line 10 px from its own and the memory
    /// learnt that line's contrast), and at 10 px/frame, seed 1, 7; with
    /// 0.6 none. Range: [0, 1].
    pub remember_contrast_min_support: f64,
    /// Linking, segmentation and indexing of the zero crossings (a
    /// `[segments]` table in a file of top-level keys, `[lowe.segments]`
    /// in one with a `[lowe]` table; see [`SegmentParams`]).
    pub segments: SegmentParams,
}

impl Default for LoweParams {
    fn default() -> Self {
        Self {
            log_sigma: 1.2,
            min_slope: 1.0,
            prior_rotation_sigma: 0.05,
            prior_translation_px: 7.0,
            prior_joint_sigma: 0.1,
            measurement_sigma_px: 1.0,
            reference_length_px: 40.0,
            residual_ratio: 2.5,
            set_probability: 0.9,
            min_probability: 0.05,
            lock_probability: 0.5,
            max_branches: 5,
            range_doublings: 2,
            search_sigmas: 3.0,
            iterations: 3,
            lock_iterations: 4,
            min_coverage: 0.25,
            min_support: 0.25,
            loose_fit_extra_matches: 3,
            loose_fit_residual_ratio: 1.4,
            confident_support: 0.8,
            steady_support_ratio: 0.0,
            search_slower_predictions: true,
            widened_support_ratio: 0.7,
            search_after: 3,
            search_min_coverage: 0.6,
            search_min_support: 0.7,
            search_max_rotation_sigma: 0.03,
            window_margin_px: 8.0,
            confident_window_doublings: 0,
            swap_gap_px: 8.0,
            swap_residual_ratio: 0.8,
            ambiguous_support_ratio: 0.95,
            ambiguous_match_ratio: 1.0,
            ambiguous_distance_px: 5.0,
            ambiguous_carry_ratio: 0.0,
            reclaim_support_ratio: 0.9,
            reclaim_after_frames: 8,
            remember_contrast: true,
            remember_contrast_min_support: 0.6,
            segments: SegmentParams::default(),
        }
    }
}

impl LoweParams {
    /// Check every parameter against its documented range.
    pub fn validate(&self) -> Result<()> {
        const WHO: &str = "lowe";
        Interval::closed(0.5, 4.0).check(WHO, "log_sigma", f64::from(self.log_sigma), "")?;
        Interval::closed(0.0, 1000.0).check(WHO, "min_slope", f64::from(self.min_slope), "")?;
        Interval::open_closed(0.0, 1.0).check(WHO, "prior_rotation_sigma", self.prior_rotation_sigma, " rad")?;
        Interval::open_closed(0.0, 1000.0).check(WHO, "prior_translation_px", self.prior_translation_px, " px")?;
        Interval::open_closed(0.0, 3.2).check(WHO, "prior_joint_sigma", self.prior_joint_sigma, " rad")?;
        Interval::open_closed(0.0, 20.0).check(WHO, "measurement_sigma_px", self.measurement_sigma_px, " px")?;
        Interval::closed(0.0, 4096.0).check(WHO, "reference_length_px", self.reference_length_px, " px")?;
        Interval::closed(1.0, 100.0).check(WHO, "residual_ratio", self.residual_ratio, "")?;
        Interval::open(0.0, 1.0).check(WHO, "set_probability", self.set_probability, "")?;
        Interval { lo: 0.0, lo_closed: true, hi: 1.0, hi_closed: false }.check(
            WHO,
            "min_probability",
            self.min_probability,
            "",
        )?;
        Interval::open_closed(0.0, 1.0).check(WHO, "lock_probability", self.lock_probability, "")?;
        check_count(WHO, "max_branches", self.max_branches, 1, MAX_BRANCHES)?;
        check_count(WHO, "range_doublings", self.range_doublings, 0, 4)?;
        Interval::closed(1.0, 10.0).check(WHO, "search_sigmas", self.search_sigmas, "")?;
        check_count(WHO, "iterations", self.iterations, 1, MAX_ITERATIONS)?;
        check_count(WHO, "lock_iterations", self.lock_iterations, 0, 20)?;
        Interval::closed(0.0, 1.0).check(WHO, "min_coverage", self.min_coverage, "")?;
        Interval::closed(0.0, 1.0).check(WHO, "min_support", self.min_support, "")?;
        check_count(WHO, "loose_fit_extra_matches", self.loose_fit_extra_matches, 0, 100)?;
        Interval::closed(0.1, 100.0).check(WHO, "loose_fit_residual_ratio", self.loose_fit_residual_ratio, "")?;
        Interval::closed(0.0, 1.0).check(WHO, "confident_support", self.confident_support, "")?;
        Interval::closed(0.0, 1.0).check(WHO, "steady_support_ratio", self.steady_support_ratio, "")?;
        Interval::closed(0.0, 1.0).check(WHO, "widened_support_ratio", self.widened_support_ratio, "")?;
        check_count(WHO, "search_after", self.search_after, 1, 1000)?;
        Interval::closed(0.0, 1.0).check(WHO, "search_min_coverage", self.search_min_coverage, "")?;
        Interval::closed(0.0, 1.0).check(WHO, "search_min_support", self.search_min_support, "")?;
        Interval::open_closed(0.0, std::f64::consts::PI).check(
            WHO,
            "search_max_rotation_sigma",
            self.search_max_rotation_sigma,
            " rad",
        )?;
        Interval::closed(0.0, 4096.0).check(WHO, "window_margin_px", self.window_margin_px, " px")?;
        check_count(WHO, "confident_window_doublings", self.confident_window_doublings, 0, self.range_doublings)?;
        Interval::closed(0.0, 50.0).check(WHO, "swap_gap_px", self.swap_gap_px, " px")?;
        Interval::closed(0.0, 1.0).check(WHO, "swap_residual_ratio", self.swap_residual_ratio, "")?;
        Interval::closed(0.0, 10.0).check(WHO, "ambiguous_support_ratio", self.ambiguous_support_ratio, "")?;
        Interval::closed(0.0, 10.0).check(WHO, "ambiguous_match_ratio", self.ambiguous_match_ratio, "")?;
        Interval::open_closed(0.0, 4096.0).check(WHO, "ambiguous_distance_px", self.ambiguous_distance_px, " px")?;
        Interval::closed(0.0, 10.0).check(WHO, "ambiguous_carry_ratio", self.ambiguous_carry_ratio, "")?;
        Interval::closed(0.0, 2.0).check(WHO, "reclaim_support_ratio", self.reclaim_support_ratio, "")?;
        check_count(WHO, "reclaim_after_frames", self.reclaim_after_frames, 0, 1000)?;
        Interval::closed(0.0, 1.0).check(
            WHO,
            "remember_contrast_min_support",
            self.remember_contrast_min_support,
            "",
        )?;
        self.segments.validate()
    }
}
