//! The commands of SPEC §5 that are more than a call into [`crate::track`]:
//! the demo, scoring a run against the truth, benchmarking the backends, reproducing a
//! paper's tables. `src/main.rs` parses the command line and calls these.

pub mod batch;
pub mod bench;
pub mod bench_windows;
pub mod demo;
pub mod import_visp;
pub mod plot;
pub mod reproduce;
pub mod reproduce_condensation;
pub mod roundtrip;
pub mod score;
pub mod tracker_bench;
