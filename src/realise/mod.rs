//! Realisations: the hardware that gives an element's potential (the disc cam of a cam
//! profile), with its geometry and the limits a maker checks.

pub mod accuracy;
pub mod cam;
pub mod duty;
pub mod material;
pub mod mechanism;
pub mod placement;
pub mod sketch;
pub mod spring;
pub mod transmission;
