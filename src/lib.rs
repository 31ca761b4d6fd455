//! pipetrack: model-based visual tracking with early vision on the GPU
//! (WGSL compute shaders through wgpu) and a CPU twin of every stage.
//!
//! # Data flow
//!
//! ```text
//! frames ──► early vision (GpuBackend | CpuBackend) ──► feature lists ──► tracker ──► FrameResult
//!               ▲  FrameRequest: which lists, where, with which caps       │
//!               └──────────────── the tracker's prediction ◄───────────────┘
//! ```
//!
//! Per frame ([`track::run`], the one loop the CLI, the tests and embedders
//! share): the [`Tracker`] predicts and states a [`FrameRequest`]; the
//! backend derives a [`backend::FramePlan`] from it and runs only those
//! stages ([`early`]: one WGSL shader and one CPU twin each), inside the
//! window, handing back compact lists; the tracker matches, fits (with
//! [`estimate`] and [`geometry`]), verifies and predicts, and reports a
//! [`FrameResult`] (one line of the JSON Lines output). The layers, bottom up: [`io`] (files
//! and formats) → [`early`], [`gpu`], [`backend`] → [`track`], [`estimate`],
//! [`geometry`] → [`cli`]; [`synth`] renders test sequences with exact truth.
//!
//! # Embedding
//!
//! A wgpu program hands pipetrack its own device and queue, and its frames
//! as textures; a tracker turns each frame into a [`FrameResult`] (corners,
//! pose, status):
//!
//! ```no_run
//! # fn demo(device: wgpu::Device, queue: wgpu::Queue, textures: &[wgpu::Texture]) -> pipetrack::Result<()> {
//! use pipetrack::{GpuBackend, GpuContext, MotionEdgeParams, MotionEdgeTracker, track_frames};
//! // The device was created with `required_limits: pipetrack::required_limits()`.
//! let ctx = GpuContext::from_device(device, queue)?;
//! let mut backend = GpuBackend::new(ctx);
//! let corners = vec![[100.0, 80.0], [150.0, 80.0], [150.0, 115.0], [100.0, 115.0]];
//! let edges = vec![[0, 1], [1, 2], [2, 3], [3, 0]];
//! let mut tracker = MotionEdgeTracker::new(corners, edges, MotionEdgeParams::default())?;
//! let size = (textures[0].width() as usize, textures[0].height() as usize);
//! track_frames(&mut tracker, &mut backend, textures.iter().map(Ok), size, |_frame, _outcome, result| {
//!     println!("{:?} {:?}", result.status, result.corners);
//!     Ok(())
//! })?;
//! # Ok(()) }
//! ```
//!
//! Frames may also be grey or colour bytes ([`GrayImage`], [`RgbImage`]) on
//! either backend ([`GpuBackend`], [`CpuBackend`]); [`track_step`] runs one
//! frame at a time. Texture formats and what their grey level is:
//! [`early::ingest`]. `examples/embed.rs` renders a scene with wgpu and
//! tracks it this way.
//!
//! A program with frames of its own (a live camera) can read the camera,
//! model and start from a sequence folder without frames
//! ([`Sequence::open_without_frames`]) and make the tracker the command line
//! would ([`track::run::make_tracker`]).
//!
//! What each tracker takes:
//! - Every frame of a run has one size: a tracker with a camera
//!   ([`BlueTracker`], [`LoweTracker`], [`CondensationTracker`]) takes its
//!   camera's image size, [`MotionEdgeTracker`] its first frame's; another
//!   size is [`Error::Size`] ([`Tracker::accept_frame_size`]).
//! - [`CondensationTracker`] compares the hue of its sample windows
//!   ([`Tracker::wants_colour`]): give it colour frames ([`RgbImage`]) as
//!   bytes, not textures (a texture is refused with an error). Grey frames
//!   are accepted and tracked without hue, less well.
//! - A texture must belong to the backend's device: wgpu panics on a
//!   texture of another device, which pipetrack cannot detect first. A
//!   destroyed texture is [`Error::Texture`].
#![deny(missing_docs)]

pub mod backend;
pub mod bounds;
pub mod cli;
pub mod early;
pub mod error;
pub mod estimate;
pub mod geometry;
pub mod gpu;
pub mod image;
pub mod io;
pub mod synth;
pub mod testimage;
pub mod track;

pub use backend::{BackendKind, CpuBackend, EarlyVision, FrameFeatures, FrameRequest, GpuBackend, GpuStack};
pub use early::ingest::TEXTURE_FORMATS;
pub use error::{Error, Result};
pub use gpu::{GpuContext, GpuImage, required_features, required_limits};
pub use image::{FloatImage, GrayImage, Image, RgbImage};
pub use io::Sequence;
pub use io::formats::{Camera, FrameResult, InitState, Model, Pose, Status};
pub use track::run::{AsFrame, Frame, track_frames, track_step};
pub use track::{
    BlueParams, BlueTracker, CondensationParams, CondensationTracker, FrameOutcome, LoweParams, LoweTracker,
    MotionEdgeParams, MotionEdgeTracker, Observations, Phase, Tracked, Tracker,
};
