//! Exports of a design and its springs to other simulators, so that an engineer can check the
//! design in the simulator they already trust before cutting metal.

pub mod mujoco;
