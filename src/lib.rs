//! pipetrack: model-based visual tracking with early vision on the GPU
//! (WGSL compute shaders through wgpu) and a CPU twin of every stage.
#![deny(missing_docs)]

pub mod backend;
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

pub use error::{Error, Result};
pub use gpu::{GpuContext, GpuImage};
pub use image::{FloatImage, GrayImage, Image};
