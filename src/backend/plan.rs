//! The frame plan: what a [`FrameRequest`] implies for one frame, derived
//! once and walked by both backends and the benchmark.
//!
//! A plan is a list of [`Step`]s in the order they run, each reading and
//! writing named images ([`Plane`], [`SobelPlanes`], the edgels), with the
//! compaction parameters of every list, the Sobel set the pyramids take their
//! gradient from, and what the frame leaves behind for the next frame's
//! motion step ([`FramePlan::next_previous`]). The CPU backend runs the steps
//! on its images; the GPU backend allocates a slot's buffers for them, records
//! them into one submission, and reads back the lists they produce.
//!
//! Every frame starts from [`Plane::Luma`], the ingested frame as f32.

use super::{FrameRequest, Pyramids};
use crate::early::compaction::{self, CompactionParams};
use crate::early::gaussian::{self, GaussianParams};
use crate::early::log::{self, LogParams};
use crate::early::temporal_diff::{self, TemporalDiffParams};
use crate::early::zero_crossing::{self, ZeroCrossingParams};
use crate::early::{Window, cpf, edge_pyramid, frame_sum, sobel, window_energy};

/// The motion mask is 0 or 1: pixels above one half are moving.
const MASK_THRESHOLD: f32 = 0.5;
/// Edgel strength is 0 where there is no edgel and positive where there is one.
const EDGEL_THRESHOLD: f32 = 0.0;

/// A single f32 image of the frame's size that a step reads or writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Plane {
    /// The frame as f32 grey levels (0..255).
    Luma,
    /// The frame smoothed with the request's Gaussian.
    Smoothed,
    /// The previous frame's smoothed image (see [`FramePlan::next_previous`]).
    Previous,
    /// 000 eq. 1: 1 where `|Previous − Smoothed|` exceeds the threshold, else 0.
    MotionMask,
    /// `Previous + Smoothed`, whose Sobel gives the motion pixels' θ (000 eq. 2).
    Sum,
    /// Laplacian of Gaussian of the frame (001).
    Log,
}

/// One of the two sets of Sobel images (gx, gy, magnitude, direction, θ).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SobelPlanes {
    /// Sobel of [`Plane::Sum`], for the motion list.
    OfSum,
    /// Sobel of the frame ([`Plane::Luma`] or [`Plane::Smoothed`], whichever
    /// the last [`Step::Sobel`] into it read), for edges and pyramids.
    OfFrame,
}

/// One image of a Sobel set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SobelPart {
    /// Horizontal derivative.
    Gx,
    /// Vertical derivative.
    Gy,
    /// Gradient magnitude.
    Magnitude,
    /// Gradient direction in `(−π, π]`.
    Direction,
    /// Edge orientation of 000 eq. 2 in `[0, π)`.
    Theta,
}

/// One image of the LoG zero-crossing edgels that compaction reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EdgelPart {
    /// Gradient strength across the crossing; 0 where there is none.
    Strength,
    /// Gradient direction across the crossing.
    Direction,
}

/// An f32 image a step reads or writes: a plane, or one image of a Sobel set
/// or of the edgels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Source {
    /// A single plane.
    Plane(Plane),
    /// One image of a Sobel set.
    Sobel(SobelPlanes, SobelPart),
    /// One image of the edgels.
    Edgels(EdgelPart),
}

impl Source {
    /// Whether this is the LoG or one of its edgel images.
    #[must_use]
    pub fn reads_log(self) -> bool {
        matches!(self, Source::Plane(Plane::Log) | Source::Edgels(_))
    }
}

/// The feature lists a frame can hand back.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum List {
    /// [`FrameFeatures::motion`](super::FrameFeatures::motion).
    Motion,
    /// [`FrameFeatures::edges`](super::FrameFeatures::edges).
    Edges,
    /// [`FrameFeatures::zero_crossings`](super::FrameFeatures::zero_crossings).
    ZeroCrossings,
}

/// One step of a frame: a stage with its parameters, inputs and outputs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Gaussian smoothing: `Luma → Smoothed`.
    Smooth(GaussianParams),
    /// 000 eq. 1 and the sum of eq. 2 (one fused pass on the CPU, the
    /// `temporal_diff` and `frame_sum` shaders on the GPU):
    /// `Previous, Smoothed → MotionMask, Sum`.
    DiffAndSum(TemporalDiffParams),
    /// Sobel 3×3: `input → output` (all five images of the set).
    Sobel {
        /// The image differentiated.
        input: Plane,
        /// The set written.
        output: SobelPlanes,
    },
    /// Laplacian of Gaussian: `Luma → Log`.
    Log(LogParams),
    /// Zero crossings of the LoG: `Log → edgels`.
    ZeroCrossings(ZeroCrossingParams),
    /// Compaction of the pixels of `params.window` whose `select` exceeds
    /// `params.threshold` into `list`, with `theta` and `magnitude`.
    Compact {
        /// The list filled.
        list: List,
        /// Image compared with the threshold.
        select: Source,
        /// Image listed as each feature's θ.
        theta: Source,
        /// Image listed as each feature's magnitude.
        magnitude: Source,
        /// Window, threshold, cap and seed.
        params: CompactionParams,
    },
    /// The sample windows of 004 (the `window_energy` stage), filtered
    /// (`energies` false) or scored against a template (`energies` true),
    /// from the frame's colour.
    Windows {
        /// Number of windows.
        count: usize,
        /// Window and CPF level sizes.
        params: window_energy::WindowEnergyParams,
        /// Score them (true) or hand back their filtered values (false).
        energies: bool,
    },
    /// A list asked for with nothing to compact it from (motion with no
    /// usable previous frame): handed back empty.
    EmptyList(List),
    /// CPF hierarchies of `Luma` and averaged edge hierarchies of the
    /// `gradient` set's gx and gy (004).
    Pyramids {
        /// The Sobel set holding the frame's gradient (of `Luma`).
        gradient: SobelPlanes,
        /// Whether the pyramids are handed back ([`Pyramids::Return`]) or
        /// left where they were computed ([`Pyramids::Keep`]).
        returned: bool,
    },
}

const SMOOTH_STAGES: &[&str] = &[gaussian::SHADER.name];
const DIFF_AND_SUM_STAGES: &[&str] = &[temporal_diff::SHADER.name, frame_sum::SHADER.name];
const SOBEL_STAGES: &[&str] = &[sobel::SHADER.name];
const LOG_STAGES: &[&str] = &[log::SHADER.name];
const ZERO_CROSSING_STAGES: &[&str] = &[zero_crossing::SHADER.name];
const COMPACTION_STAGES: &[&str] = &[compaction::SHADER.name];
const PYRAMID_STAGES: &[&str] = &[cpf::SHADER.name, edge_pyramid::SHADER.name];
const WINDOW_STAGES: &[&str] = &[window_energy::SHADER.name];

const SOBEL_PARTS: [SobelPart; 5] =
    [SobelPart::Gx, SobelPart::Gy, SobelPart::Magnitude, SobelPart::Direction, SobelPart::Theta];

impl Step {
    /// The stages this step runs, by the names of their shader files (and
    /// benchmark ids); empty for [`Step::EmptyList`].
    #[must_use]
    pub fn stages(&self) -> &'static [&'static str] {
        match self {
            Step::Smooth(_) => SMOOTH_STAGES,
            Step::DiffAndSum(_) => DIFF_AND_SUM_STAGES,
            Step::Sobel { .. } => SOBEL_STAGES,
            Step::Log(_) => LOG_STAGES,
            Step::ZeroCrossings(_) => ZERO_CROSSING_STAGES,
            Step::Compact { .. } => COMPACTION_STAGES,
            Step::EmptyList(_) => &[],
            Step::Pyramids { .. } => PYRAMID_STAGES,
            Step::Windows { .. } => WINDOW_STAGES,
        }
    }

    /// The images this step reads.
    #[must_use]
    pub fn reads(&self) -> Vec<Source> {
        use Source::Plane as P;
        match *self {
            Step::Smooth(_) | Step::Log(_) => vec![P(Plane::Luma)],
            Step::DiffAndSum(_) => vec![P(Plane::Previous), P(Plane::Smoothed)],
            Step::Sobel { input, .. } => vec![P(input)],
            Step::ZeroCrossings(_) => vec![P(Plane::Log)],
            Step::Compact { select, theta, magnitude, .. } => vec![select, theta, magnitude],
            Step::EmptyList(_) | Step::Windows { .. } => Vec::new(),
            Step::Pyramids { gradient, .. } => {
                vec![P(Plane::Luma), Source::Sobel(gradient, SobelPart::Gx), Source::Sobel(gradient, SobelPart::Gy)]
            }
        }
    }

    /// The images this step writes (lists and pyramids are outputs, not images).
    #[must_use]
    pub fn writes(&self) -> Vec<Source> {
        use Source::Plane as P;
        match *self {
            Step::Smooth(_) => vec![P(Plane::Smoothed)],
            Step::DiffAndSum(_) => vec![P(Plane::MotionMask), P(Plane::Sum)],
            Step::Sobel { output, .. } => SOBEL_PARTS.iter().map(|&p| Source::Sobel(output, p)).collect(),
            Step::Log(_) => vec![P(Plane::Log)],
            Step::ZeroCrossings(_) => vec![Source::Edgels(EdgelPart::Strength), Source::Edgels(EdgelPart::Direction)],
            Step::Compact { .. } | Step::EmptyList(_) | Step::Pyramids { .. } | Step::Windows { .. } => Vec::new(),
        }
    }
}

/// The smoothed image a frame leaves for the next frame's motion step, as
/// far as the plan needs to know it: its size and the smoothing that made it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreviousFrame {
    /// Width of the frame.
    pub width: usize,
    /// Height of the frame.
    pub height: usize,
    /// The Gaussian it was smoothed with.
    pub smoothing: GaussianParams,
}

/// What one frame runs: the steps in order, derived from a [`FrameRequest`]
/// and what the previous frame left behind.
///
/// Steps run in this order: smoothing; motion (difference and sum, Sobel of
/// the sum, compaction); edges (Sobel of the raw or smoothed frame,
/// compaction); zero crossings (LoG, crossings, compaction); pyramids (Sobel
/// of the raw frame unless the edges step just computed it, then the
/// hierarchies); sample windows.
///
/// **The previous-frame rule.** Motion always differences two *consecutive*
/// frames smoothed the same way. A frame whose plan smooths (it asks for
/// motion, or for edges of the smoothed frame) keeps its smoothed image as
/// the next frame's [`Plane::Previous`] ([`FramePlan::next_previous`] is
/// `Some`). A frame that does not smooth leaves nothing (`None`), so motion on
/// the following frame is empty, as on a sequence's first frame. A previous
/// image of another size, or smoothed with another σ, is not used either:
/// that frame's motion list is empty too, and it leaves its own smoothed
/// image for the next one.
#[derive(Clone, Debug, PartialEq)]
pub struct FramePlan {
    steps: Vec<Step>,
    next_previous: Option<PreviousFrame>,
}

impl FramePlan {
    /// The plan of `request` on a `width`×`height` frame whose predecessor
    /// left `previous` (`None` on a sequence's first frame).
    #[must_use]
    pub fn new(request: &FrameRequest, width: usize, height: usize, previous: Option<&PreviousFrame>) -> Self {
        let mut steps = Vec::new();
        let smooths = request.motion.is_some() || request.edges.is_some_and(|e| e.smoothed);
        let this = PreviousFrame { width, height, smoothing: request.smoothing };
        if smooths {
            steps.push(Step::Smooth(request.smoothing));
        }

        if let Some(m) = &request.motion {
            if previous == Some(&this) {
                steps.push(Step::DiffAndSum(m.diff));
                steps.push(Step::Sobel { input: Plane::Sum, output: SobelPlanes::OfSum });
                steps.push(Step::Compact {
                    list: List::Motion,
                    select: Source::Plane(Plane::MotionMask),
                    theta: Source::Sobel(SobelPlanes::OfSum, SobelPart::Theta),
                    magnitude: Source::Sobel(SobelPlanes::OfSum, SobelPart::Magnitude),
                    params: m.list.compaction(MASK_THRESHOLD),
                });
            } else {
                steps.push(Step::EmptyList(List::Motion));
            }
        }

        // Which plane `SobelPlanes::OfFrame` holds the Sobel of, once written.
        let mut sobel_of_frame = None;
        if let Some(e) = &request.edges {
            let input = if e.smoothed { Plane::Smoothed } else { Plane::Luma };
            steps.push(Step::Sobel { input, output: SobelPlanes::OfFrame });
            sobel_of_frame = Some(input);
            let of_frame = |part| Source::Sobel(SobelPlanes::OfFrame, part);
            steps.push(Step::Compact {
                list: List::Edges,
                select: of_frame(SobelPart::Magnitude),
                theta: of_frame(SobelPart::Direction),
                magnitude: of_frame(SobelPart::Magnitude),
                params: e.list.compaction(e.threshold),
            });
        }

        if let Some(z) = &request.zero_crossings {
            steps.push(Step::Log(z.log));
            steps.push(Step::ZeroCrossings(z.crossings));
            steps.push(Step::Compact {
                list: List::ZeroCrossings,
                select: Source::Edgels(EdgelPart::Strength),
                theta: Source::Edgels(EdgelPart::Direction),
                magnitude: Source::Edgels(EdgelPart::Strength),
                params: z.list.compaction(EDGEL_THRESHOLD),
            });
        }

        if request.pyramids != Pyramids::Off {
            // The edge hierarchies take the raw frame's gradient: reuse the
            // edges' Sobel when it was of the raw frame, else compute it.
            if sobel_of_frame != Some(Plane::Luma) {
                steps.push(Step::Sobel { input: Plane::Luma, output: SobelPlanes::OfFrame });
            }
            steps.push(Step::Pyramids {
                gradient: SobelPlanes::OfFrame,
                returned: request.pyramids == Pyramids::Return,
            });
        }

        if let Some(w) = &request.windows {
            let energies = matches!(w, super::WindowRequest::Energies { .. });
            steps.push(Step::Windows { count: w.windows().len(), params: w.params(), energies });
        }

        Self { steps, next_previous: smooths.then_some(this) }
    }

    /// The steps, in the order they run.
    #[must_use]
    pub fn steps(&self) -> &[Step] {
        &self.steps
    }

    /// What this frame leaves for the next frame's motion step: its smoothed
    /// image when the plan smooths, else nothing (see the rule on [`FramePlan`]).
    #[must_use]
    pub fn next_previous(&self) -> Option<PreviousFrame> {
        self.next_previous
    }

    /// Whether `other` runs the same steps with the same parameters, its
    /// lists aside: they may differ in window, threshold, seed and cap
    /// value, but not in whether they are capped. Frames whose plans stack
    /// this way can share every dispatch ([`super::gpu::GpuStack`]).
    #[must_use]
    pub fn stacks_with(&self, other: &FramePlan) -> bool {
        self.steps.len() == other.steps.len()
            && self.steps.iter().zip(&other.steps).all(|(a, b)| match (a, b) {
                (
                    Step::Compact { list, select, theta, magnitude, params },
                    Step::Compact { list: l, select: s, theta: t, magnitude: m, params: p },
                ) => (list, select, theta, magnitude) == (l, s, t, m) && params.cap.is_some() == p.cap.is_some(),
                _ => a == b,
            })
    }

    /// Compact `list` from an empty window: the list comes back empty, as
    /// on a sequence's first frame, while every step still runs.
    pub(crate) fn empty_list(&mut self, list: List) {
        for step in &mut self.steps {
            if let Step::Compact { list: l, params, .. } = step
                && *l == list
            {
                params.window = crate::early::Window { x0: 0, y0: 0, x1: 0, y1: 0 };
            }
        }
    }

    /// Where the LoG and its edgels are read, when only windowed lists read
    /// them: the union of the windows (clipped to the `width`×`height`
    /// frame, possibly empty) of the compactions reading them, when every
    /// step reading them is a compaction that reads nothing else and lists
    /// no subsample (`cap`). `None` when the plan runs no LoG or another
    /// step reads it (a Sobel of the LoG, a subsample), so the whole frame
    /// is needed. A backend computing the LoG and its crossings on a part of
    /// the frame around these windows gives the lists of the whole frame.
    #[must_use]
    pub fn log_windows(&self, width: usize, height: usize) -> Option<Window> {
        let mut runs_log = false;
        let mut union = Window::default();
        for step in &self.steps {
            match *step {
                Step::Log(_) => runs_log = true,
                Step::Sobel { input: Plane::Log, .. } => return None,
                Step::Compact { select, theta, magnitude, params, .. } => {
                    let reading = [select, theta, magnitude].map(Source::reads_log);
                    if reading.iter().all(|&r| !r) {
                        continue;
                    }
                    if reading.iter().any(|&r| !r) || params.cap.is_some() {
                        return None;
                    }
                    union = union.union(&params.window.clipped(width, height));
                }
                _ => {}
            }
        }
        runs_log.then_some(union)
    }

    /// Whether the plan reads the previous frame's smoothed image.
    #[must_use]
    pub fn reads_previous(&self) -> bool {
        self.steps.iter().any(|s| matches!(s, Step::DiffAndSum(_)))
    }

    /// The stages the plan runs, by shader name, each once, in order of first use.
    #[must_use]
    pub fn stage_names(&self) -> Vec<&'static str> {
        let mut names: Vec<&'static str> = Vec::new();
        for name in self.steps.iter().flat_map(Step::stages) {
            if !names.contains(name) {
                names.push(name);
            }
        }
        names
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::{EdgeRequest, ListSpec, MotionRequest, ZeroCrossingRequest};
    use crate::early::Window;

    const W: usize = 9;
    const H: usize = 7;

    fn motion() -> Option<MotionRequest> {
        Some(MotionRequest { diff: TemporalDiffParams::default(), list: ListSpec::full(W, H) })
    }

    fn edges(smoothed: bool) -> Option<EdgeRequest> {
        Some(EdgeRequest { threshold: 60.0, smoothed, list: ListSpec::full(W, H) })
    }

    fn previous(sigma: f32) -> PreviousFrame {
        PreviousFrame { width: W, height: H, smoothing: GaussianParams { sigma } }
    }

    /// The steps with their parameters dropped, for comparing shapes.
    fn shape(plan: &FramePlan) -> Vec<String> {
        plan.steps()
            .iter()
            .map(|s| match s {
                Step::Smooth(_) => "smooth".into(),
                Step::DiffAndSum(_) => "diff_and_sum".into(),
                Step::Sobel { input, output } => format!("sobel {input:?}->{output:?}"),
                Step::Log(_) => "log".into(),
                Step::ZeroCrossings(_) => "zero_crossings".into(),
                Step::Compact { list, .. } => format!("compact {list:?}"),
                Step::EmptyList(list) => format!("empty {list:?}"),
                Step::Pyramids { gradient, returned } => format!("pyramids {gradient:?} returned={returned}"),
                Step::Windows { count, energies, .. } => format!("windows {count} energies={energies}"),
            })
            .collect()
    }

    #[test]
    fn nothing_asked_runs_nothing_and_keeps_nothing() {
        let plan = FramePlan::new(&FrameRequest::default(), W, H, Some(&previous(1.0)));
        assert!(plan.steps().is_empty());
        assert_eq!(plan.next_previous(), None);
    }

    #[test]
    fn motion_with_a_matching_previous_frame_differences_it() {
        let request = FrameRequest { motion: motion(), ..FrameRequest::default() };
        let plan = FramePlan::new(&request, W, H, Some(&previous(1.0)));
        assert_eq!(shape(&plan), ["smooth", "diff_and_sum", "sobel Sum->OfSum", "compact Motion"]);
        assert!(plan.reads_previous());
        assert_eq!(plan.next_previous(), Some(previous(1.0)));
        let Some(Step::Compact { params, select, theta, .. }) = plan.steps().last() else { panic!("no compaction") };
        assert_eq!((params.threshold, params.window), (0.5, Window::full(W, H)));
        assert_eq!(*select, Source::Plane(Plane::MotionMask));
        assert_eq!(*theta, Source::Sobel(SobelPlanes::OfSum, SobelPart::Theta));
    }

    #[test]
    fn motion_without_a_usable_previous_frame_is_an_empty_list() {
        let request = FrameRequest { motion: motion(), ..FrameRequest::default() };
        let other_size = PreviousFrame { width: W + 1, ..previous(1.0) };
        for prev in [None, Some(previous(1.5)), Some(other_size)] {
            let plan = FramePlan::new(&request, W, H, prev.as_ref());
            assert_eq!(shape(&plan), ["smooth", "empty Motion"], "previous {prev:?}");
            assert!(!plan.reads_previous());
            // It still smooths, so the next frame has a previous one.
            assert_eq!(plan.next_previous(), Some(previous(1.0)));
        }
    }

    #[test]
    fn the_previous_frame_is_kept_exactly_when_the_frame_smooths() {
        let sigma = GaussianParams { sigma: 2.0 };
        let cases = [
            (FrameRequest { motion: motion(), ..FrameRequest::default() }, true),
            (FrameRequest { edges: edges(true), ..FrameRequest::default() }, true),
            (FrameRequest { edges: edges(false), ..FrameRequest::default() }, false),
            (FrameRequest { pyramids: Pyramids::Return, ..FrameRequest::default() }, false),
            (FrameRequest::default(), false),
        ];
        for (request, keeps) in cases {
            let request = FrameRequest { smoothing: sigma, ..request };
            let plan = FramePlan::new(&request, W, H, None);
            let expected = keeps.then_some(PreviousFrame { width: W, height: H, smoothing: sigma });
            assert_eq!(plan.next_previous(), expected, "{request:?}");
            assert_eq!(plan.steps().contains(&Step::Smooth(sigma)), keeps, "{request:?}");
        }
    }

    #[test]
    fn edges_take_sobel_of_the_raw_or_smoothed_frame() {
        let raw = FramePlan::new(&FrameRequest { edges: edges(false), ..FrameRequest::default() }, W, H, None);
        assert_eq!(shape(&raw), ["sobel Luma->OfFrame", "compact Edges"]);
        let smoothed = FramePlan::new(&FrameRequest { edges: edges(true), ..FrameRequest::default() }, W, H, None);
        assert_eq!(shape(&smoothed), ["smooth", "sobel Smoothed->OfFrame", "compact Edges"]);
    }

    #[test]
    fn pyramids_reuse_the_raw_frames_sobel_and_recompute_it_otherwise() {
        let with = |e, pyramids| FrameRequest { edges: e, pyramids, ..FrameRequest::default() };
        let reuse = FramePlan::new(&with(edges(false), Pyramids::Keep), W, H, None);
        assert_eq!(shape(&reuse), ["sobel Luma->OfFrame", "compact Edges", "pyramids OfFrame returned=false"]);
        let recompute = FramePlan::new(&with(edges(true), Pyramids::Return), W, H, None);
        assert_eq!(
            shape(&recompute),
            [
                "smooth",
                "sobel Smoothed->OfFrame",
                "compact Edges",
                "sobel Luma->OfFrame",
                "pyramids OfFrame returned=true"
            ]
        );
        let alone = FramePlan::new(&with(None, Pyramids::Return), W, H, None);
        assert_eq!(shape(&alone), ["sobel Luma->OfFrame", "pyramids OfFrame returned=true"]);
        assert!(FramePlan::new(&with(None, Pyramids::Off), W, H, None).steps().is_empty());
    }

    #[test]
    fn zero_crossings_list_edgels_above_zero_strength() {
        let z = ZeroCrossingRequest {
            log: LogParams::default(),
            crossings: ZeroCrossingParams::default(),
            list: ListSpec { window: Window { x0: 1, y0: 2, x1: 5, y1: 6 }, cap: Some(10), seed: 3 },
        };
        let plan = FramePlan::new(&FrameRequest { zero_crossings: Some(z), ..FrameRequest::default() }, W, H, None);
        assert_eq!(shape(&plan), ["log", "zero_crossings", "compact ZeroCrossings"]);
        assert_eq!(
            plan.steps()[2],
            Step::Compact {
                list: List::ZeroCrossings,
                select: Source::Edgels(EdgelPart::Strength),
                theta: Source::Edgels(EdgelPart::Direction),
                magnitude: Source::Edgels(EdgelPart::Strength),
                params: z.list.compaction(0.0),
            }
        );
    }

    #[test]
    fn sample_windows_run_last_and_keep_no_previous_frame() {
        use crate::backend::WindowRequest;
        use crate::early::window_energy::WindowEnergyParams;
        let params = WindowEnergyParams::default();
        let windows = Some(WindowRequest::Features { params, windows: vec![[[0.0; 2]; 4]; 3] });
        let request = FrameRequest { edges: edges(false), windows, ..FrameRequest::default() };
        let plan = FramePlan::new(&request, W, H, None);
        assert_eq!(shape(&plan), ["sobel Luma->OfFrame", "compact Edges", "windows 3 energies=false"]);
        assert_eq!(plan.steps()[2], Step::Windows { count: 3, params, energies: false });
        assert_eq!(plan.next_previous(), None);
        assert_eq!(plan.stage_names(), ["sobel", "compaction", "window_energy"]);
    }

    #[test]
    fn full_chain_runs_every_stage() {
        let request = FrameRequest::full_chain(W, H);
        let plan =
            FramePlan::new(&request, W, H, Some(&PreviousFrame { width: W, height: H, smoothing: request.smoothing }));
        assert_eq!(
            plan.stage_names(),
            [
                "gaussian",
                "temporal_diff",
                "frame_sum",
                "sobel",
                "compaction",
                "log",
                "zero_crossing",
                "cpf",
                "edge_pyramid"
            ]
        );
    }

    /// Every step reads only images written earlier in the same plan, or
    /// the previous frame's; every list asked for is produced exactly once.
    #[test]
    fn every_plan_reads_only_what_it_wrote_and_lists_what_was_asked() {
        let mut checked = 0;
        for motion_on in [false, true] {
            for edge in [None, edges(false), edges(true)] {
                for zc in [false, true] {
                    for pyramids in [Pyramids::Off, Pyramids::Keep, Pyramids::Return] {
                        for prev in [None, Some(previous(1.0))] {
                            let request = FrameRequest {
                                motion: if motion_on { motion() } else { None },
                                edges: edge,
                                zero_crossings: zc.then(|| ZeroCrossingRequest {
                                    log: LogParams::default(),
                                    crossings: ZeroCrossingParams::default(),
                                    list: ListSpec::full(W, H),
                                }),
                                pyramids,
                                ..FrameRequest::default()
                            };
                            let plan = FramePlan::new(&request, W, H, prev.as_ref());
                            let mut written = vec![Source::Plane(Plane::Luma), Source::Plane(Plane::Previous)];
                            let mut frame_sobel_of = None;
                            for step in plan.steps() {
                                for r in step.reads() {
                                    assert!(written.contains(&r), "{step:?} reads {r:?} before it is written");
                                }
                                written.extend(step.writes());
                                match *step {
                                    Step::Sobel { input, output: SobelPlanes::OfFrame } => frame_sobel_of = Some(input),
                                    Step::Pyramids { .. } => {
                                        assert_eq!(frame_sobel_of, Some(Plane::Luma), "pyramids of {request:?}")
                                    }
                                    _ => {}
                                }
                            }
                            let lists = |l: List| {
                                plan.steps()
                                    .iter()
                                    .filter(|s| matches!(s, Step::Compact { list, .. } | Step::EmptyList(list) if *list == l))
                                    .count()
                            };
                            assert_eq!(lists(List::Motion), usize::from(motion_on));
                            assert_eq!(lists(List::Edges), usize::from(edge.is_some()));
                            assert_eq!(lists(List::ZeroCrossings), usize::from(zc));
                            let pyr = plan.steps().iter().filter(|s| matches!(s, Step::Pyramids { .. })).count();
                            assert_eq!(pyr, usize::from(pyramids != Pyramids::Off));
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert_eq!(checked, 72);
    }
}
