//! The evaluation of a potential on held-out geodesics: the residual angles users compare and
//! the checks at the equilibrium (gradient, Hessian match, monotonicity).

use super::outcome::Evaluation;
use crate::design::Design;
use crate::error::Result;
use crate::geodesic::Fan;
use crate::potential::{CouplingSet, Potential, SpringSet};
use crate::residual::{band_stats, fan_angles_and_descents, stats};

/// Residuals and checks of a spring set on a fan (held-out geodesics): the figures users compare.
pub fn evaluate(design: &Design, omega: f64, bands: usize, springs: &SpringSet, fan: &Fan) -> Result<Evaluation> {
    let chain = &design.chain;
    let q0 = design.q_eq.as_slice();
    // Grouped by coupling for the hundreds of thousands of samples (one sine and one axpy per
    // coupling, see `CouplingSet`); the checks at q_eq element by element, as before.
    let coupled = CouplingSet::new(springs);
    let (residuals, monotone_violations) = fan_angles_and_descents(chain, fan, &coupled)?;
    let grad = springs.gradient(q0)? + chain.gravity_gradient(q0);
    let hess = springs.hessian(q0)? + chain.gravity_hessian(q0);
    let target = chain.mass_matrix(&design.q_eq) * omega.powi(2);
    let extent = fan.geodesics.iter().map(|g| g.length()).fold(0.0, f64::max);
    Ok(Evaluation {
        stats: stats(&residuals),
        bands: band_stats(&residuals, extent, bands),
        residuals,
        equilibrium_gradient_norm: grad.norm(),
        hessian_rel_error: (hess - &target).norm() / target.norm(),
        monotone_violations,
    })
}
