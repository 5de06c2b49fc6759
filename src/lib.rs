//! # springfit
//!
//! Designs spring layouts for robot arms (planar chains typed into a design file, or spatial
//! chains read from a URDF, see [`model`]) so that *strict normal modes are everywhere*:
//! released from rest anywhere in a region, the arm swings through its equilibrium on a fixed
//! geodesic of the inertia metric. See `docs/theory.md` for the maths and the words used here.
//!
//! ## Quick start
//!
//! Load a design, fit its springs from its catalogue, read the bill of materials:
//!
//! ```
//! use springfit::{Design, FitJob, FitRequest, Progress};
//!
//! # fn main() -> springfit::Result<()> {
//! // The arm, its equilibrium, the region and the catalogue it names (docs/design.md).
//! let design = Design::load("designs/double_pendulum.toml".as_ref())?;
//! // Everything that can be checked before any work; the catalogue is loaded once, here.
//! let checked = springfit::validate(&design)?;
//! let job = FitJob::new(&design, checked.catalog.as_ref(), FitRequest::default())?;
//! let run = job.run(Progress::none())?;
//!
//! // Residual angles (degrees) between ∇U through M⁻¹ and the geodesics, on held-out samples.
//! let p99 = run.outcome.metrics.stats.p99_abs;
//! assert!(p99 < 1.0, "p99 {p99}°");
//! // The bill: one row per spring (or cam coefficient), stiffness in the profile's unit.
//! for row in &run.outcome.bom {
//!     assert!(row.stiffness >= 0.0, "{} is a spring, not a motor", row.id);
//! }
//! # Ok(())
//! # }
//! ```
//!
//! `run.write(&design, claim)` writes what `springfit fit` writes (the claim comes from
//! [`report::output::check`], which refuses a folder another design's results are in), and
//! `examples/fit_and_control.rs` goes on to run the paper's controller on the fitted springs.
//!
//! ## Where things are
//!
//! What each command runs is a job of [`jobs`] (a typed request in, a typed run result with its
//! writer out); long calls report their stages through one [`Progress`]. Below the jobs, in the
//! order data flows (`docs/architecture.md` has the layers and every file):
//! [`design`] (the file, validated) → [`model`] (the arm's dynamics) → [`geodesic`] (the fan of
//! geodesics and the region check) → [`elements`] (catalogue and candidate springs) → [`fit`]
//! (the stiffnesses, by [`solve`]) → [`parts`] (wire and coils, by [`realise`]) → [`asbuilt`]
//! (tolerance builds and trims) → [`dynamics`] (simulation and controllers), [`studies`]
//! (sweeps, comparisons), [`identify`] (a built arm from its logs) → [`report`] and [`files`]
//! (what is written and read back), [`export`] (MuJoCo).
//!
//! The library never prints or exits: every failure is an [`Error`] naming the file, the field
//! and the reason.

// Index loops mirror the formulas (Σᵢ Mᵢⱼ q̇ⱼ …) and stay the clearest way to write them.
#![allow(clippy::needless_range_loop)]
#![warn(missing_docs, unreachable_pub)]

pub mod error;

pub mod asbuilt;
mod csv;
pub mod design;
pub mod dynamics;
pub mod elements;
pub mod export;
pub mod files;
pub mod fit;
pub mod geodesic;
pub mod identify;
mod input;
pub mod jobs;
mod limits;
pub mod model;
pub mod numerics;
pub mod parts;
pub mod potential;
pub mod progress;
pub mod realise;
pub mod report;
pub mod residual;
pub mod solve;
pub mod studies;
mod units;

// The front door: what the quick start and `examples/` use, named from the crate root.
pub use design::Design;
pub use design::validate::validate;
pub use dynamics::control::Controller;
pub use elements::catalog::Catalog;
pub use error::{Error, ErrorKind, Result};
pub use fit::FitOutcome;
pub use fit::bill::BomRow;
pub use jobs::fit::{FitJob, FitRequest, FitRun};
pub use progress::Progress;

/// The command line's limit on `--threads` (listed in `docs/limits.md`).
pub use limits::MAX_THREADS_PER_CORE;
