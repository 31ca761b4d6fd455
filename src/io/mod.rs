//! Everything that reads or writes files: sequence folders (SPEC §4) and
//! their frames, the file formats as serde types, ViSP `.cao` and Wavefront
//! `.obj` models, Y4M streams, JSON with one-line errors, atomic output
//! files, and overlays.

pub mod atomic;
pub mod cao;
pub mod formats;
pub mod frames;
pub mod json;
pub mod obj;
pub mod overlay;
pub mod sequence;
pub mod y4m;

pub use atomic::{AtomicFile, OutputFile, StagedDir};
pub use frames::{FrameSource, decode_gray, dynamic_to_gray, list_frames};
pub use json::{read_json, read_jsonl};
pub use sequence::Sequence;
