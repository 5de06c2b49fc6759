//! The fit: non-negative stiffnesses of catalogue elements that make every geodesic from the
//! equilibrium a strict mode as nearly as the catalogue allows. `run.rs` runs one fit through its
//! stages (prepare, solve, evaluate, bill), each in a file of its own. What `springfit fit` does
//! around it (the parts, a refit at their tolerances, the as-built builds, the files) is the fit
//! job, [`crate::jobs::fit`].

pub mod auto;
pub mod bill;
pub mod diagnosis;
pub mod evaluate;
pub mod hints;
pub mod mass;
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
