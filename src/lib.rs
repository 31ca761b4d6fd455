//! pipetrack: model-based visual tracking with early vision on the GPU
//! (WGSL compute shaders through wgpu) and a CPU twin of every stage.
//!
//! The early-vision stages live in [`early`], the GPU plumbing in [`gpu`],
//! and the two interchangeable backends in [`backend`].
#![deny(missing_docs)]

pub mod backend;
pub mod bench;
pub mod cao;
pub mod early;
pub mod error;
pub mod estimate;
pub mod fit;
pub mod formats;
pub mod gpu;
pub mod image;
pub mod overlay;
pub mod predict;
pub mod reproduce;
pub mod run;
pub mod score;
pub mod sequence;
pub mod synth;
pub mod testimage;
pub mod track;
pub mod y4m;

pub use error::{Error, Result};
pub use gpu::{GpuContext, GpuImage};
pub use image::{FloatImage, GrayImage, Image};
