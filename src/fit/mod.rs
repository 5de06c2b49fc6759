//! The fit: non-negative stiffnesses of catalogue elements that make every geodesic from the
//! equilibrium a strict mode as nearly as the catalogue allows.

pub mod lsq;
pub mod nnls;
pub mod problem;
pub mod qp;
pub mod robust;
pub mod run;
pub mod selection;
pub mod settings;
