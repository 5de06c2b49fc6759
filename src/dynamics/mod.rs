//! The arm in motion: the paper's controllers, the closed-loop simulation, the scenarios a
//! design declares, with their metrics, and the backbone (period against energy per mode).

pub mod backbone;
pub mod control;
pub mod scenario;
pub mod simulate;
