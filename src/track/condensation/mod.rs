//! The `condensation` tracker (paper 004, Chambers and Hutchinson): a
//! particle filter over the velocity screw of a camera looking at a static
//! planar window, each sample scored by the critical-point-filter energy of
//! the window it predicts.
//!
//! # The method, as Fig. 2 runs it
//! * **State** (eq. 14): each sample is a velocity screw s = (T, ω), the
//!   motion of the scene relative to the camera since the *reference* (see
//!   [`steps`] for the sign convention of eq. 21).
//! * **Window and template.** The tracked window is the model's quadrilateral
//!   (`model.json`, four vertices: the template's top-left, top-right,
//!   bottom-right and bottom-left), at the pose of `init.json`, which gives
//!   the depths eq. 21 needs. Frame 0 is the source image: the backend warps
//!   the window to 2^L × 2^L and filters it to CPF level k; that is the
//!   template (§III-B.3).
//! * **Initial set** (§III-B.3): N draws from N(r_i, Σ), r_i the screw of the
//!   known first camera motion (`init.json`'s `camera_motion`, or the
//!   `camera_motion` parameter; zero without either).
//! * **Each frame** (Fig. 2, steps 1–5): project the reference window's
//!   vertices with every sample through eq. 20–21 at the reference depths;
//!   score all N windows in the frame's one request (the `window_energy`
//!   stage: warp, CPF to level k, eq. 22–26); weight π = 1/U normalised
//!   (eq. 27–28); resample by cumulative weights (eq. 16–18); drift by the
//!   best sample with gain K (eq. 19); diffuse by a Brownian random walk.
//!
//! # From one image pair to a sequence
//! 004 tracks one source–destination pair; a sequence extends it so:
//! * **Accumulating the motion.** The reference is a pose of the window;
//!   the drift of eq. 19, `s ← s − K·s^max`, is read as the servo step it is
//!   in the paper: the reference moves by `K·s^max` (applied exactly, as a
//!   rigid motion) and every sample is re-expressed relative to it. The
//!   camera keeps moving, so each sample then gets the motion of the last
//!   frame interval added (a constant-velocity prediction; the paper's
//!   robot knows its own motion instead). With K = I (the default) the
//!   reference is the last estimate and the samples are the screw of the
//!   next frame interval, so their spread stays that of the diffusion.
//!   Depths come from the reference pose each frame (the paper keeps the
//!   source depth for its single step).
//! * **Keeping the template.** The template is frame 0's window, kept for
//!   the whole sequence. Each sample window is warped projectively onto the
//!   template's square, so for a plane every frame is compared with the same
//!   template without accumulated error; refreshing the template from the
//!   estimate would make each frame's sub-pixel error part of the next
//!   frame's reference, a random walk that grows with the sequence.
//!
//! # Output
//! Corners: the window scored for the estimate (the best sample by
//! default, [`Estimate`]; on the frame after a search, the best sample; on
//! a lost frame with the search on, the search's centre), in model-vertex
//! order; pose: the window's pose
//! relative to the camera (the estimate's screw applied to the reference);
//! the velocity screw estimate (`velocity_screw`, per frame interval) and the
//! effective sample size 1/Σπ² (`effective_sample_size`) as extra keys; the
//! weighted covariance of the samples' screws as `covariance`.
//!
//! A frame is `tracking` when the best window matches the template: the RMS
//! intensity difference per compared value, bounded from above by its
//! energy (`U · Σ_n C_I / 4K²`, since U ≥ C_I / Σ_n C_I), is at most
//! [`CondensationParams::max_residual`]. Otherwise it is `lost`, with the
//! residual in the reason; the template stays, so the window can be found
//! again.
//!
//! # Searching while lost
//! 004 tracks one image pair and has no loss. On a sequence, a window that
//! is hidden or jumps leaves the sample set, whose spread is the diffusion
//! of one frame (0.3 px), where the paper's update cannot bring it back: on
//! a lost frame the best sample is any mismatch, the drift of eq. 19 moves
//! the reference to it and the motion of the next interval is taken from
//! that jump. With [`CondensationParams::search_spread_px`] above 0 (the
//! default), a lost frame instead runs a search:
//! * the reference stays where the window was last tracked, and the motion
//!   of the last tracked interval is kept as the prediction;
//! * the next frame's samples are drawn afresh, as §III-B.3 draws the
//!   initial set: sample 0 is the search's centre, half of the others are
//!   drawn around it with the search's spread, the other half around where
//!   the last tracked motion carries the window (its *coast*) with
//!   [`CondensationParams::max_search_spread_px`];
//! * the centre starts at the filter's own prediction with
//!   `search_spread_px`. A best sample is evidence of the window when its
//!   residual is below [`CondensationParams::search_evidence_ratio`] of the
//!   median residual of the frame's samples (so the luck of the draw among
//!   mismatches is not). On evidence the spread halves (down to
//!   `diffusion_px`) and the centre moves to the best sample if its
//!   residual is below 0.9 of the centre's (it stays when it is the best
//!   sample itself); without, the spread doubles (up to the largest);
//! * the centre and the coast move on by the last tracked motion each
//!   frame, the centre only until the search first finds evidence: from
//!   then on the window's motion since the loss is unknown, and the centre
//!   stays at the evidence while its spread covers where the window moves;
//! * a frame whose best window matches the template is `tracking` again,
//!   and the paper's update resumes from it, with the motion kept from
//!   before the loss as the next interval's prediction.
//!
//! A frame that is never lost takes exactly the paper's update. With fewer
//! than 3 samples the search has no sample both around its centre and
//! around the coast and does little.

pub mod params;
pub mod steps;

use std::sync::Arc;

use glam::DVec3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub use params::{CondensationParams, Estimate};
use steps::Screw;

use super::{Diagnostics, FrameExtras, FrameOutcome, Observations, Phase, Tracker};
use crate::backend::{FrameRequest, WindowRequest};
use crate::early::Window;
use crate::early::window_energy::{HIERARCHIES, Quad, WindowTemplate};
use crate::geometry::Camera;
use crate::geometry::pose::Pose;
use crate::io::formats::{self, InitState, Model, Status};
use crate::{Error, Result};

/// Margin of the window of interest around the sample windows, px.
const INTEREST_MARGIN_PX: f64 = 2.0;

/// The Condensation tracker of 004.
#[derive(Debug)]
pub struct CondensationTracker {
    params: CondensationParams,
    camera: Camera,
    /// The window's vertices in the object frame.
    vertices: [DVec3; 4],
    /// The pose (camera-from-object) the samples' screws are relative to.
    reference: Pose,
    /// The last frame's estimate.
    estimate: Pose,
    samples: Vec<Screw>,
    /// The sample windows of the next frame.
    windows: Vec<Quad>,
    template: Option<Arc<WindowTemplate>>,
    rng: ChaCha8Rng,
    extras: FrameExtras,
    phase: Phase,
    /// The motion of the last tracked frame interval: the prediction while lost.
    velocity: Screw,
    /// The search for the window while lost (None while tracking).
    search: Option<Search>,
}

/// A best sample moves a lost window's search only when its residual is
/// below this fraction of the residual of the search's centre.
const SEARCH_MIN_IMPROVEMENT: f64 = 0.9;

/// What a lost frame does to the search (module documentation, "Searching
/// while lost").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SearchStep {
    /// The first lost frame: centre on the filter's own prediction.
    Start,
    /// The centre is the best sample and evidence: stay, halve the spread.
    Narrow,
    /// This sample is evidence and clearly better than the centre: move
    /// there, halve the spread.
    MoveTo(usize),
    /// No evidence: stay, double the spread.
    Widen,
}

/// The search for a lost window: the next frame's sample 0 is its centre,
/// half of the rest (the larger half) are drawn around the centre with
/// `spread_px`, the others around `coast` with the largest spread.
#[derive(Clone, Copy, Debug)]
struct Search {
    spread_px: f64,
    /// Where the motion of the last tracked frame interval carries the
    /// window, relative to the reference.
    coast: Screw,
    /// Whether the search has moved to evidence of the window.
    found: bool,
}

impl CondensationTracker {
    /// A tracker of the four-vertex window `model` seen by `camera`, starting
    /// at `init.pose`; the first motion from `params.camera_motion`, else
    /// `init.camera_motion`, else zero. Errors on a start pose that puts a
    /// window vertex at or behind the camera, or whose window's image
    /// misses the image or is less than a pixel wide or high
    /// ([`Camera::start_image_problem`]).
    pub fn new(camera: Camera, model: &Model, init: &InitState, params: CondensationParams) -> Result<Self> {
        params.validate()?;
        let [a, b, c, d] = model.vertices[..] else {
            return Err(Error::Parameter(format!(
                "condensation tracks a window of 4 vertices (top-left, top-right, bottom-right, bottom-left); the model has {}",
                model.vertices.len()
            )));
        };
        if let Some(problem) = camera.intrinsics_problem() {
            return Err(Error::Parameter(format!("camera: {problem}")));
        }
        if !model.vertices.iter().flatten().all(|v| v.is_finite()) {
            return Err(Error::Parameter("the window's vertices must be finite numbers".into()));
        }
        let vertices = [a, b, c, d].map(DVec3::from_array);
        let init_pose = init
            .pose
            .ok_or_else(|| Error::Parameter("condensation needs \"pose\" (the window's depth comes from it)".into()))?;
        if !init_pose.is_finite() {
            return Err(Error::Parameter("the initial \"pose\" must be finite numbers".into()));
        }
        let pose: Pose = init_pose.into();
        if vertices.iter().any(|v| !(pose.apply(*v).z > 0.0)) {
            return Err(Error::Parameter("a window vertex is not in front of the camera at the initial pose".into()));
        }
        if let Some(problem) = camera.start_image_problem(&vertices.map(|v| pose.apply(v))) {
            return Err(Error::Parameter(problem));
        }
        let motion = params.camera_motion.or(init.camera_motion).unwrap_or([0.0; 6]);
        let mut tracker = Self {
            camera,
            vertices,
            reference: pose,
            estimate: pose,
            samples: Vec::new(),
            windows: Vec::new(),
            template: None,
            rng: ChaCha8Rng::seed_from_u64(params.seed),
            extras: FrameExtras::default(),
            phase: Phase::Acquiring,
            velocity: steps::screw_of_camera_motion(&motion),
            search: None,
            params,
        };
        let (corners, depths) = tracker.reference_window();
        let sigma = steps::component_sigmas(
            &camera,
            &corners,
            &depths,
            tracker.params.initial_spread_px,
            &tracker.params.component_weights,
        );
        tracker.samples = steps::draw_initial_samples(
            &steps::screw_of_camera_motion(&motion),
            &sigma,
            tracker.params.samples,
            &mut tracker.rng,
        );
        tracker.windows = steps::project_sample_windows(&camera, &corners, &depths, &tracker.samples);
        Ok(tracker)
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &CondensationParams {
        &self.params
    }

    /// The samples' screws (relative to the reference) the next frame scores.
    #[must_use]
    pub fn samples(&self) -> &[Screw] {
        &self.samples
    }

    /// The sample windows the next frame scores.
    #[must_use]
    pub fn sample_windows(&self) -> &[Quad] {
        &self.windows
    }

    /// Corners and depths of the window at `pose`.
    fn window_at(&self, pose: &Pose) -> ([[f64; 2]; 4], [f64; 4]) {
        let cam: [DVec3; 4] = self.vertices.map(|v| pose.apply(v));
        (cam.map(|p| self.camera.project(p)), cam.map(|p| p.z))
    }

    fn reference_window(&self) -> ([[f64; 2]; 4], [f64; 4]) {
        self.window_at(&self.reference)
    }

    /// The corners of the window of sample `screw`, from the reference
    /// window's `corners` and `depths` (as the samples' windows are made).
    fn sample_corners(&self, corners: &[[f64; 2]; 4], depths: &[f64; 4], screw: &Screw) -> Vec<[f64; 2]> {
        let window = steps::project_sample_windows(&self.camera, corners, depths, std::slice::from_ref(screw));
        window[0].iter().map(|c| [f64::from(c[0]), f64::from(c[1])]).collect()
    }

    fn outcome(&self, frame: usize, status: Status, corners: Vec<[f64; 2]>, reason: Option<String>) -> FrameOutcome {
        FrameOutcome {
            frame,
            status,
            phase: self.phase,
            corners,
            pose: Some(formats::Pose::from(&self.estimate)),
            params: None,
            covariance: None,
            labelled: Vec::new(),
            diagnostics: Diagnostics { lost_reason: reason, ..Diagnostics::default() },
        }
    }

    /// Frame 0: keep the filtered window as the template.
    fn take_template(&mut self, frame: usize, observations: &Observations<'_>) -> FrameOutcome {
        let (corners, _) = self.reference_window();
        match observations.window_features.and_then(|f| f.first()) {
            Some(t) if t.params == self.params.window() => {
                self.template = Some(Arc::new(t.clone()));
                self.phase = Phase::Tracking;
                self.outcome(frame, Status::Tracking, corners.to_vec(), None)
            }
            _ => {
                self.outcome(frame, Status::Lost, corners.to_vec(), Some("no template window from the backend".into()))
            }
        }
    }

    /// Fig. 2 for one destination frame.
    fn track_frame(&mut self, frame: usize, observations: &Observations<'_>) -> FrameOutcome {
        let (ref_corners, ref_depths) = self.reference_window();
        let energies = match observations.window_energies {
            Some(e) if e.energies.len() == self.samples.len() => e,
            _ => {
                self.phase = Phase::Lost;
                let reason = "no window energies from the backend".to_string();
                return self.outcome(frame, Status::Lost, ref_corners.to_vec(), Some(reason));
            }
        };
        // Eq. 27–28.
        let weights = steps::weights_from_energies(&energies.energies);
        let best = steps::best_sample(&weights);
        let best_screw = self.samples[best];
        // After a search the samples are spread widely: the weighted mean of
        // that frame is no estimate, the best sample is.
        let estimate_screw = match self.params.estimate {
            Estimate::WeightedMean if self.search.is_none() => steps::weighted_mean(&self.samples, &weights),
            Estimate::Best | Estimate::WeightedMean => best_screw,
        };
        let corners = self.sample_corners(&ref_corners, &ref_depths, &estimate_screw);
        let estimate = steps::screw_motion(&estimate_screw).compose(&self.reference);
        let interval_motion = steps::screw_of_motion(&estimate.compose(&self.estimate.inverse()));
        self.estimate = estimate;

        // The claim of tracking, checked against the image.
        let side = self.params.window().level_side();
        let residual_of =
            |n: usize| steps::residual_bound(energies.energies[n], energies.intensity_total, HIERARCHIES * side * side);
        let residual = residual_of(best);
        let lost_reason = (residual > self.params.max_residual)
            .then(|| format!("best window's residual {residual:.1} grey levels exceeds {}", self.params.max_residual));
        if let Some(reason) = lost_reason.clone().filter(|_| self.params.search_spread_px > 0.0) {
            // Evidence of the window: the best sample stands out from the
            // frame's typical mismatch, the samples' median residual; it
            // moves the search when it also beats the search's centre
            // (sample 0) clearly.
            let mut all: Vec<f64> = (0..energies.energies.len()).map(residual_of).collect();
            let middle = all.len() / 2;
            let median = *all.select_nth_unstable_by(middle, f64::total_cmp).1;
            let evidence = residual < self.params.search_evidence_ratio * median;
            let step = match self.search {
                None => SearchStep::Start,
                Some(_) if evidence && best == 0 => SearchStep::Narrow,
                Some(_) if evidence && residual < SEARCH_MIN_IMPROVEMENT * residual_of(0) => SearchStep::MoveTo(best),
                Some(_) => SearchStep::Widen,
            };
            return self.search_while_lost(frame, (&ref_corners, &ref_depths), &weights, step, reason);
        }
        // After a search, the motion before the loss is the prediction, not
        // the jump from the search's centre to the window found.
        let interval_motion = if self.search.take().is_some() { self.velocity } else { interval_motion };
        self.velocity = interval_motion;
        let status = if lost_reason.is_none() { Status::Tracking } else { Status::Lost };
        self.phase = if lost_reason.is_none() { Phase::Tracking } else { Phase::Lost };
        let mut outcome = self.outcome(frame, status, corners, lost_reason);
        outcome.covariance = Some(screw_covariance(&self.samples, &weights));
        self.extras = FrameExtras {
            velocity_screw: Some(interval_motion),
            effective_sample_size: Some(steps::effective_sample_size(&weights)),
            search_branches: None,
        };

        // Eq. 16–18: resample.
        let cumulative = steps::cumulative_weights(&weights);
        let mut next = steps::resample(&self.samples, &cumulative, &mut self.rng);
        // Eq. 19: drift by K·s^max; the reference follows the same step.
        let gain = self.params.gain;
        let step: Screw = std::array::from_fn(|k| gain[k] * best_screw[k]);
        self.reference = steps::screw_motion(&step).compose(&self.reference);
        steps::drift(&mut next, &best_screw, &gain);
        // Each sample now says where this frame's camera is relative to the
        // new reference; the next frame's camera is one more interval on,
        // the motion of the last interval (to first order, screws add).
        steps::predict(&mut next, &interval_motion);
        // §III-B.1: Brownian diffusion, scaled at the new reference.
        let (corners, depths) = self.reference_window();
        let sigma = steps::component_sigmas(
            &self.camera,
            &corners,
            &depths,
            self.params.diffusion_px,
            &self.params.component_weights,
        );
        steps::diffuse(&mut next, &sigma, &mut self.rng);
        self.windows = steps::project_sample_windows(&self.camera, &corners, &depths, &next);
        self.samples = next;
        outcome
    }
}

impl CondensationTracker {
    /// A lost frame with the search on (module documentation, "Searching
    /// while lost").
    /// `reference` is the reference window's corners and depths, which the
    /// search keeps.
    fn search_while_lost(
        &mut self,
        frame: usize,
        (corners, depths): (&[[f64; 2]; 4], &[f64; 4]),
        weights: &[f64],
        step: SearchStep,
        reason: String,
    ) -> FrameOutcome {
        self.phase = Phase::Lost;
        let (largest, least) = (self.params.max_search_spread_px, self.params.diffusion_px);
        let (centre, spread_px, coast, found) = match (self.search, step) {
            (Some(s), SearchStep::Narrow) => (self.samples[0], (s.spread_px / 2.0).max(least), s.coast, true),
            (Some(s), SearchStep::MoveTo(n)) => (self.samples[n], (s.spread_px / 2.0).max(least), s.coast, true),
            (Some(s), SearchStep::Widen) => (self.samples[0], (s.spread_px * 2.0).min(largest), s.coast, s.found),
            (None, _) | (Some(_), SearchStep::Start) => {
                let predicted = steps::mean(&self.samples);
                (predicted, self.params.search_spread_px, predicted, false)
            }
        };
        let reported = self.sample_corners(corners, depths, &centre);
        self.estimate = steps::screw_motion(&centre).compose(&self.reference);
        let mut outcome = self.outcome(frame, Status::Lost, reported, Some(reason));
        outcome.covariance = Some(screw_covariance(&self.samples, weights));
        self.extras = FrameExtras {
            velocity_screw: Some(self.velocity),
            effective_sample_size: Some(steps::effective_sample_size(weights)),
            search_branches: None,
        };
        let coasted = |s: &Screw| -> Screw { std::array::from_fn(|k| s[k] + self.velocity[k]) };
        // Once the search has found evidence of the window, its centre stays
        // where the evidence is; before, it coasts.
        let (next_centre, next_coast) = (if found { centre } else { coasted(&centre) }, coasted(&coast));
        let component_weights = &self.params.component_weights;
        let near = steps::component_sigmas(&self.camera, corners, depths, spread_px, component_weights);
        let wide = steps::component_sigmas(&self.camera, corners, depths, largest, component_weights);
        let others = self.params.samples - 1;
        let around_centre = others.div_ceil(2);
        let mut next = vec![next_centre];
        next.extend(steps::draw_initial_samples(&next_centre, &near, around_centre, &mut self.rng));
        next.extend(steps::draw_initial_samples(&next_coast, &wide, others - around_centre, &mut self.rng));
        self.windows = steps::project_sample_windows(&self.camera, corners, depths, &next);
        self.samples = next;
        self.search = Some(Search { spread_px, coast: next_coast, found });
        outcome
    }
}

/// The weighted covariance of the samples' screws, 6×6 row-major.
fn screw_covariance(samples: &[Screw], weights: &[f64]) -> Vec<f64> {
    let mean = steps::weighted_mean(samples, weights);
    let mut cov = vec![0.0; 36];
    for (s, w) in samples.iter().zip(weights) {
        for i in 0..6 {
            for j in 0..6 {
                cov[i * 6 + j] += w * (s[i] - mean[i]) * (s[j] - mean[j]);
            }
        }
    }
    cov
}

impl Tracker for CondensationTracker {
    fn name(&self) -> &'static str {
        "condensation"
    }

    fn accept_frame_size(&mut self, width: usize, height: usize) -> std::result::Result<(), String> {
        super::camera_takes(&self.camera, width, height)
    }

    fn window_of_interest(&self, width: usize, height: usize) -> Window {
        let corners: Vec<[f64; 2]> =
            self.windows.iter().flatten().map(|c| [f64::from(c[0]), f64::from(c[1])]).collect();
        Window::around(&corners, INTEREST_MARGIN_PX, width, height).unwrap_or_else(|| Window::full(width, height))
    }

    fn request(&self, _width: usize, _height: usize) -> FrameRequest {
        let windows = match &self.template {
            None => {
                let (corners, _) = self.reference_window();
                WindowRequest::Features {
                    params: self.params.window(),
                    windows: vec![corners.map(|c| [c[0] as f32, c[1] as f32])],
                }
            }
            Some(template) => WindowRequest::Energies { windows: self.windows.clone(), template: Arc::clone(template) },
        };
        FrameRequest { windows: Some(windows), ..FrameRequest::default() }
    }

    fn track(&mut self, frame: usize, observations: &Observations<'_>) -> FrameOutcome {
        self.extras = FrameExtras::default();
        if self.template.is_none() {
            self.take_template(frame, observations)
        } else {
            self.track_frame(frame, observations)
        }
    }

    fn wants_colour(&self) -> bool {
        true
    }

    fn extras(&self) -> FrameExtras {
        self.extras.clone()
    }
}
