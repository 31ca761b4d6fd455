//! The trackers: their paper steps on hand-made features (`*_logic`) and
//! end to end on rendered sequences through both backends (`*_e2e`).

#[path = "../common/mod.rs"]
mod common;

mod batch;
mod blue_e2e;
mod blue_logic;
mod condensation_e2e;
mod embed;
mod finite;
mod lowe_e2e;
mod motion_edge_e2e;
mod motion_edge_logic;
mod roundtrip;
mod status;
