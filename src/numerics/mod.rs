//! Numerics every layer above uses: small dense linear algebra for the hot loops, the
//! Runge–Kutta integrators with dense output and event location, and the deterministic random
//! numbers of the Monte Carlo builds.

pub mod linalg;
pub mod ode;
pub mod ode853;
pub mod rng;
