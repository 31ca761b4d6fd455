//! Straight line segments from the LoG zero crossings (001, "Real-time line
//! detection").
