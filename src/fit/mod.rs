//! The fit: non-negative stiffnesses of catalogue elements that make every geodesic from the
//! equilibrium a strict mode as nearly as the catalogue allows.

pub mod bill;
pub mod hints;
pub mod problem;
pub mod robust;
pub mod run;
