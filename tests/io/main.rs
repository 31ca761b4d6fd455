//! Files and commands: sequence folders and their errors, scoring, the
//! synthetic scenes, and the `pipetrack` binary on good and bad input.

#[path = "../common/mod.rs"]
mod common;

mod batch;
mod bounds;
mod cli;
mod fuzz;
mod import_visp;
mod model_files;
mod plot;
mod score;
mod sequence_io;
mod synth;
mod synth_boxes;
mod synth_target3dof;
