//! # springfit
//!
//! Designs spring layouts for robot arms (planar chains typed into a design file, or spatial
//! chains read from a URDF, see [`model`]) so that *strict normal modes are everywhere*:
//! released from rest anywhere in a region, the arm swings through its equilibrium on a fixed
//! geodesic of the inertia metric. See `docs/theory.md` for the maths and the words used here.
//!
//! What each command runs is a job of [`jobs`] (a typed request in, a typed run result with its
//! writer out); long calls report their stages through one [`progress::Progress`].

// Index loops mirror the formulas (Σᵢ Mᵢⱼ q̇ⱼ …) and stay the clearest way to write them.
#![allow(clippy::needless_range_loop)]
#![warn(missing_docs, unreachable_pub)]

pub mod error;

pub use error::{Error, ErrorKind, Result};
/// The command line's limit on `--threads` (listed in `docs/limits.md`).
///
pub use limits::MAX_THREADS_PER_CORE;
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
