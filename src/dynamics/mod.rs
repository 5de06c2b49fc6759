//! The arm in motion: the paper's controllers, the closed-loop simulation and the scenarios a
//! design declares, with their metrics.

pub mod control;
pub mod scenario;
pub mod simulate;
