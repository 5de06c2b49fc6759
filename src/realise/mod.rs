//! Realisations: the hardware that gives an element's potential (today the disc cam of a cam
//! profile), with its geometry and the limits a maker checks.

pub mod cam;
