//! The fit: non-negative stiffnesses of catalogue elements that make every geodesic from the
//! equilibrium a strict mode as nearly as the catalogue allows. `run.rs` is the pipeline; each
//! stage has a file of its own.

pub mod bill;
pub mod evaluate;
pub mod hints;
pub mod outcome;
pub mod prepare;
pub mod problem;
pub mod refit;
pub mod robust;
pub mod run;
pub mod smoothing;
pub mod solve;

pub use outcome::{Evaluation, FitOutcome, SolveReport, SolveStatus, Solver, Timings};
pub use prepare::Prepared;
pub use run::{exact_reference, fit};
