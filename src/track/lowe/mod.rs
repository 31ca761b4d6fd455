//! The `lowe` tracker (paper 001, Lowe 1992): the 6-DOF pose and joint
//! parameters of an articulated polyhedron, from straight line segments of
//! the LoG zero crossings, matched by probability and a best-first search,
//! fitted by stabilised Gauss–Newton.

pub mod estimation;
#[cfg(test)]
mod fixtures;
pub mod matching;
pub mod params;
pub mod projection;
pub mod search;
pub mod segments;
