//! The two interchangeable early-vision backends.
//!
//! A tracker states what it needs for the next frame in one [`FrameRequest`]
//! (which lists, inside which window, with which caps); a backend computes
//! only those stages and hands back compact [`FrameFeatures`]. The
//! [`CpuBackend`] runs the CPU twins; the [`GpuBackend`] records every pass of
//! a frame into one command encoder, submits once and reads back only the
//! lists. Both walk the same [`FramePlan`], derived from the request once
//! per frame.

mod cpu;
mod gpu;
pub mod plan;

pub use cpu::CpuBackend;
pub use gpu::{
    FrameStats, GpuBackend, GpuStack, LaneFrame, MAX_LANES, StackTicket, Ticket, check_lane_count, lane_groups,
};
pub use plan::FramePlan;

use crate::early::compaction::{CompactionParams, MAX_CAP};
use crate::early::cpf::CpfPyramids;
use crate::early::edge_pyramid::EdgePyramids;
use crate::early::gaussian::GaussianParams;
use crate::early::log::LogParams;
use crate::early::temporal_diff::TemporalDiffParams;
use crate::early::window_energy::{self, Quad, WindowEnergies, WindowEnergyParams, WindowTemplate};
use crate::early::zero_crossing::ZeroCrossingParams;
use crate::early::{Feature, Window};
use crate::image::{GrayImage, RgbImage};
use crate::{Error, Result};

/// Where a list's pixels are kept: window, cap and subsample seed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ListSpec {
    /// Window of interest (clipped to the frame).
    pub window: Window,
    /// Keep at most this many pixels (a seeded stratified random subsample).
    pub cap: Option<u32>,
    /// Seed of the subsample.
    pub seed: u32,
}

impl ListSpec {
    /// The whole `width`×`height` frame, uncapped.
    #[must_use]
    pub fn full(width: usize, height: usize) -> Self {
        Self { window: Window::full(width, height), cap: None, seed: 0 }
    }

    pub(crate) fn compaction(&self, threshold: f32) -> CompactionParams {
        CompactionParams { window: self.window, threshold, cap: self.cap, seed: self.seed }
    }
}

/// Motion pixels of 000: the temporal difference of this frame's and the
/// previous frame's smoothed images, thresholded (eq. 1), listed with the edge
/// orientation θ (eq. 2) and gradient magnitude of the Sobel operator applied
/// to the sum of the two smoothed frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionRequest {
    /// Threshold of the temporal difference.
    pub diff: TemporalDiffParams,
    /// Window, cap, seed.
    pub list: ListSpec,
}

/// Edge pixels of 002 §2.3: Sobel magnitude above a threshold, listed with
/// the gradient direction and magnitude.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeRequest {
    /// Magnitude threshold (Sobel units: 4× grey-level step for an ideal edge).
    pub threshold: f32,
    /// Apply Sobel to the smoothed frame (true) or the raw frame (false, as 002).
    pub smoothed: bool,
    /// Window, cap, seed.
    pub list: ListSpec,
}

/// Zero crossings of the Laplacian of Gaussian (001), listed with the
/// direction and strength of the gradient across each crossing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZeroCrossingRequest {
    /// LoG parameters (σ = 1.2 by default).
    pub log: LogParams,
    /// Crossing parameters.
    pub crossings: ZeroCrossingParams,
    /// Window, cap, seed.
    pub list: ListSpec,
}

/// Everything a tracker asks of early vision for one frame.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct FrameRequest {
    /// Smoothing applied to each frame (needed by `motion`, and by `edges`
    /// when `smoothed`); defaults to σ = 1. Motion differences a frame only
    /// against a predecessor smoothed with the same σ (see [`FramePlan`]).
    pub smoothing: GaussianParams,
    /// Motion pixels (000).
    pub motion: Option<MotionRequest>,
    /// Edge pixels (002).
    pub edges: Option<EdgeRequest>,
    /// LoG zero crossings (001).
    pub zero_crossings: Option<ZeroCrossingRequest>,
    /// Critical-point and edge hierarchies of the frame (004).
    pub pyramids: Pyramids,
    /// Sample windows of the frame to filter or score (004 §III-B.2); they
    /// read the frame's colour (a grey frame has no hue).
    pub windows: Option<WindowRequest>,
}

/// What to do with a frame's sample windows (004 eq. 20–28, the
/// [`window_energy`] stage).
#[derive(Clone, Debug, PartialEq)]
pub enum WindowRequest {
    /// Warp and filter each window and hand back its values
    /// ([`FrameFeatures::window_features`]): how a template is taken.
    Features {
        /// Window and CPF level sizes.
        params: WindowEnergyParams,
        /// The quadrilaterals.
        windows: Vec<Quad>,
    },
    /// Score each window against `template` and hand back the N energies
    /// ([`FrameFeatures::window_energies`]).
    Energies {
        /// The quadrilaterals (at most [`window_energy::MAX_WINDOWS`]).
        windows: Vec<Quad>,
        /// The template, filtered with the sizes the windows are filtered with.
        template: std::sync::Arc<WindowTemplate>,
    },
}

impl WindowRequest {
    /// The quadrilaterals.
    #[must_use]
    pub fn windows(&self) -> &[Quad] {
        match self {
            Self::Features { windows, .. } | Self::Energies { windows, .. } => windows,
        }
    }

    /// The window and CPF level sizes.
    #[must_use]
    pub fn params(&self) -> WindowEnergyParams {
        match self {
            Self::Features { params, .. } => *params,
            Self::Energies { template, .. } => template.params,
        }
    }

    fn validate(&self) -> Result<()> {
        let params = self.params();
        params.validate()?;
        let template = match self {
            Self::Features { .. } => None,
            Self::Energies { template, .. } => Some(&**template),
        };
        window_energy::check_windows(&params, self.windows(), template)
    }
}

/// Whether to build the CPF and edge hierarchies, and where they end up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Pyramids {
    /// Not built.
    #[default]
    Off,
    /// Built, and left where they were computed (on the GPU: for later GPU
    /// stages; nothing crosses the bus).
    Keep,
    /// Built and returned in [`FrameFeatures::pyramids`] (on the GPU: read back).
    Return,
}

impl FrameRequest {
    /// Check every parameter of the request before any stage runs: the
    /// smoothing and LoG σ ([`GaussianParams::validate`],
    /// [`LogParams::validate`]), the thresholds (finite, not NaN) and the
    /// caps (at most [`MAX_CAP`]). Both backends call it first, so a bad
    /// request is refused before anything is recorded or allocated.
    pub fn validate(&self) -> Result<()> {
        self.smoothing.validate()?;
        let cap_ok = |list: &ListSpec, what: &str| match list.cap {
            Some(cap) if cap > MAX_CAP => Err(Error::Parameter(format!("{what} list cap {cap} exceeds {MAX_CAP}"))),
            _ => Ok(()),
        };
        if let Some(m) = &self.motion {
            m.diff.validate()?;
            cap_ok(&m.list, "motion")?;
        }
        if let Some(e) = &self.edges {
            if !e.threshold.is_finite() {
                return Err(Error::Parameter(format!("edge threshold {} must be finite", e.threshold)));
            }
            cap_ok(&e.list, "edge")?;
        }
        if let Some(z) = &self.zero_crossings {
            z.log.validate()?;
            if !z.crossings.min_slope.is_finite() {
                return Err(Error::Parameter(format!(
                    "zero-crossing min_slope {} must be finite",
                    z.crossings.min_slope
                )));
            }
            cap_ok(&z.list, "zero-crossing")?;
        }
        if let Some(w) = &self.windows {
            w.validate()?;
        }
        Ok(())
    }

    /// The full chain, every list over the whole frame, pyramids built but
    /// kept where they were computed: what the benchmarks run.
    #[must_use]
    pub fn full_chain(width: usize, height: usize) -> Self {
        let list = ListSpec::full(width, height);
        Self {
            smoothing: GaussianParams::default(),
            motion: Some(MotionRequest { diff: TemporalDiffParams::default(), list }),
            edges: Some(EdgeRequest { threshold: 60.0, smoothed: false, list }),
            zero_crossings: Some(ZeroCrossingRequest {
                log: LogParams::default(),
                crossings: ZeroCrossingParams::default(),
                list,
            }),
            pyramids: Pyramids::Keep,
            windows: None,
        }
    }
}

/// What a backend hands back for one frame: only the lists asked for.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct FrameFeatures {
    /// Motion pixels; empty on the first frame of a sequence, and on a frame
    /// whose predecessor was not smoothed with the same σ (the
    /// previous-frame rule of [`FramePlan`]).
    pub motion: Option<Vec<Feature>>,
    /// Edge pixels.
    pub edges: Option<Vec<Feature>>,
    /// LoG zero crossings.
    pub zero_crossings: Option<Vec<Feature>>,
    /// CPF hierarchies and averaged edge hierarchies.
    pub pyramids: Option<(CpfPyramids, EdgePyramids)>,
    /// The filtered sample windows ([`WindowRequest::Features`]).
    pub window_features: Option<Vec<WindowTemplate>>,
    /// The sample windows' energies ([`WindowRequest::Energies`]).
    pub window_energies: Option<WindowEnergies>,
}

impl FrameFeatures {
    /// The field holding `list`.
    pub(crate) fn list_mut(&mut self, list: plan::List) -> &mut Option<Vec<Feature>> {
        match list {
            plan::List::Motion => &mut self.motion,
            plan::List::Edges => &mut self.edges,
            plan::List::ZeroCrossings => &mut self.zero_crossings,
        }
    }
}

/// An early-vision backend: CPU twins or GPU shaders, same answers.
pub trait EarlyVision {
    /// A human-readable name: the adapter for the GPU, thread count for the CPU.
    fn name(&self) -> String;

    /// Compute what `request` asks for on `frame`, the next frame of the
    /// current sequence (the motion stage differences it against the previous
    /// one, under the previous-frame rule of [`FramePlan`]).
    fn process(&mut self, frame: &GrayImage, request: &FrameRequest) -> Result<FrameFeatures>;

    /// Like [`process`](Self::process) for a colour frame: every grey stage
    /// sees its luma ([`RgbImage::to_gray`], the bytes a colour file decodes
    /// to as grey), the sample windows see its colour. The default processes
    /// the luma alone (sample windows then see no hue); both backends
    /// override it.
    fn process_rgb(&mut self, frame: &RgbImage, request: &FrameRequest) -> Result<FrameFeatures> {
        self.process(&frame.to_gray(), request)
    }

    /// Like [`process`](Self::process) for a frame held in a wgpu texture
    /// (formats: [`crate::early::ingest::TEXTURE_FORMATS`]). Only a backend on
    /// the texture's device can read it; the default is
    /// [`crate::Error::TextureOnCpu`].
    fn process_texture(&mut self, texture: &wgpu::Texture, request: &FrameRequest) -> Result<FrameFeatures> {
        let _ = (texture, request);
        Err(crate::Error::TextureOnCpu { backend: self.name() })
    }

    /// Forget the previous frame: the next frame starts a new sequence.
    fn reset(&mut self);

    /// `Ok` when frames of `width`×`height` fit this backend: the GPU
    /// backend's lists and images must fit its device's buffer limits, the
    /// CPU backend takes any size. A caller that knows the frame size
    /// checks it before the first frame, so a size the device cannot take
    /// is refused before anything is written.
    fn check_frame_size(&self, width: usize, height: usize) -> Result<()> {
        let _ = (width, height);
        Ok(())
    }

    /// Hand a frame's features back once read, so that the next
    /// [`process`](Self::process) refills their lists and pyramid levels
    /// instead of allocating new ones (optional: a backend may ignore it).
    fn recycle(&mut self, features: FrameFeatures) {
        drop(features);
    }
}

/// Which backend to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendKind {
    /// WGSL shaders through wgpu.
    Gpu,
    /// CPU twins.
    Cpu,
}

/// Make a backend; asking for the GPU without an adapter falls back to the
/// CPU and returns the reason as the second value (callers print it once).
pub fn make_backend(kind: BackendKind) -> (Box<dyn EarlyVision>, Option<String>) {
    match kind {
        BackendKind::Cpu => (Box::new(CpuBackend::new()), None),
        BackendKind::Gpu => match crate::GpuContext::new() {
            Ok(ctx) => (Box::new(GpuBackend::new(ctx)), None),
            Err(e) => (Box::new(CpuBackend::new()), Some(format!("{e}; running the CPU backend"))),
        },
    }
}
