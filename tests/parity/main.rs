//! Early vision: every stage's GPU shader against its CPU twin on lavapipe
//! (one module per stage), both backends on whole frames, and naga validation
//! of every shader; stacked sequences against the CPU backend per sequence.

#[path = "../common/mod.rs"]
mod common;

mod backend;
mod compaction;
mod cpf;
mod frame_sum;
mod gaussian;
mod ingest;
mod log;
mod shader_validation;
mod sobel;
mod stack;
mod temporal_diff;
mod window_energy;
mod zero_crossing;
