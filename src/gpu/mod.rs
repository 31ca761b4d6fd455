//! GPU plumbing shared by every stage: the context (device, queue, adapter
//! name), the pipeline cache, a recorder that batches many dispatches into one
//! submission, and readback.
//!
//! Every stage module in [`crate::early`] owns a [`ShaderDef`] pointing at its
//! `shaders/<stage>.wgsl` file and declaring the bindings and workgroup size
//! of each entry point, and records its passes through a `Recorder`.

mod context;
mod recorder;
mod shader;

pub use context::{GpuContext, default_compaction_run, required_features, required_limits};
pub use recorder::GpuImage;
pub(crate) use recorder::{FrameArena, Recorder, run_once, workgroups_2d};
pub use shader::{Binding, EntryPoint, Include, ShaderDef};

/// Workgroup edge of the 2-D image shaders (16×16 invocations).
pub const TILE: u32 = 16;

/// Timeout for one GPU wait; lavapipe can be slow on big frames.
pub(crate) const POLL_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(30);
