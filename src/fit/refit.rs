//! Refitting with some stiffnesses fixed (stock-rate snapping): what is left free compensates
//! what was fixed.

use super::problem::{Requirements, assemble};
use crate::design::Design;
use crate::design::fit::FitSettings;
use crate::elements::catalog::Candidate;
use crate::error::Result;
use crate::geodesic::Fan;
use crate::solve::lsq::Gram;
use crate::solve::nnls::{NnlsSettings, nnls};

/// Refits the stiffnesses of `elements` on the training fan with some of them fixed
/// (`fixed[j] = Some(k)`), by NNLS with the equalities weighted as in the fit: what is left free
/// compensates what was fixed (stock-rate snapping). Returns every element's stiffness.
pub fn refit_with_fixed(
    design: &Design,
    settings: &FitSettings,
    training: &Fan,
    elements: &[crate::elements::Element],
    fixed: &[Option<f64>],
) -> Result<Vec<f64>> {
    let candidates: Vec<Candidate> = elements.iter().map(|e| Candidate::bare(e.clone())).collect();
    let req = Requirements { omega: settings.frequency, hessian_match: settings.hessian_match, monotone: false };
    let problem = assemble(&design.chain, &design.q_eq, training, &candidates, req);
    let mut weighted = Gram::from_rows(&problem.rows, &problem.rhs);
    let weight = settings.equality_weight * (problem.rows.nrows().max(1) as f64).sqrt();
    for eq in &problem.equalities {
        weighted.add_weighted(&eq.matrix, &eq.rhs, weight);
    }
    let free: Vec<usize> = (0..elements.len()).filter(|&j| fixed[j].is_none()).collect();
    let fixed_idx: Vec<usize> = (0..elements.len()).filter(|&j| fixed[j].is_some()).collect();
    let values: Vec<f64> = fixed_idx.iter().map(|&j| fixed[j].unwrap_or(0.0)).collect();
    let mut k: Vec<f64> = fixed.iter().map(|f| f.unwrap_or(0.0)).collect();
    if !free.is_empty() {
        let sol = nnls(&weighted.fix(&free, &fixed_idx, &values), 0.0, &NnlsSettings::default())?;
        for (a, &j) in free.iter().enumerate() {
            k[j] = sol.k[a];
        }
    }
    Ok(k)
}
