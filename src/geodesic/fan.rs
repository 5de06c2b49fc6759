//! A fan of geodesics from the equilibrium, traced in parallel.

use nalgebra::DVector;
use rayon::prelude::*;

use super::Geodesic;
use super::directions::{MetricFrame, unit_vectors};
use super::shoot::{Shooter, Stop};
use crate::error::Result;
use crate::model::Chain;
use crate::numerics::ode::OdeSettings;

/// What fan to trace.
#[derive(Debug, Clone, Copy)]
pub struct FanSpec<'r> {
    /// Number of directions.
    pub count: usize,
    /// Offset of the directions in units of their spacing (0.5: directions halfway between those
    /// of phase 0, for held-out evaluation sets). For n ≥ 3 any non-zero phase gives a disjoint
    /// low-discrepancy set.
    pub phase: f64,
    /// Where each geodesic stops.
    pub stop: Stop<'r>,
    /// Arc-length spacing of the samples.
    pub spacing: f64,
}

/// Geodesics from one equilibrium in a set of directions.
#[derive(Debug, Clone)]
pub struct Fan {
    /// The equilibrium.
    pub q_eq: DVector<f64>,
    /// Direction of each geodesic in the metric frame (Euclidean unit vectors u; the initial joint
    /// velocity is `frame.to_joint(u)`).
    pub frame_directions: Vec<DVector<f64>>,
    /// The geodesics, in direction order.
    pub geodesics: Vec<Geodesic>,
}

impl Fan {
    /// Traces the fan in parallel. The result does not depend on the number of threads: each
    /// geodesic is integrated on its own, results are collected in direction order, and the
    /// first failing direction (in that order) is the error reported.
    pub fn trace(chain: &Chain, q_eq: &DVector<f64>, spec: FanSpec<'_>, ode: OdeSettings) -> Result<Fan> {
        let frame = MetricFrame::new(&chain.mass_matrix(q_eq))?;
        let dirs = unit_vectors(chain.dof(), spec.count, spec.phase);
        let results: Vec<Result<Geodesic>> = dirs
            .par_iter()
            .map_init(
                || Shooter::new(chain, q_eq, ode),
                |shooter, u| shooter.trace(&frame.to_joint(u), spec.stop, spec.spacing),
            )
            .collect();
        let geodesics = results.into_iter().collect::<Result<Vec<_>>>()?;
        Ok(Fan { q_eq: q_eq.clone(), frame_directions: dirs, geodesics })
    }

    /// Total number of samples over all geodesics.
    pub fn sample_count(&self) -> usize {
        self.geodesics.iter().map(Geodesic::len).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn fan_is_deterministic_across_thread_counts() {
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
        let spec = FanSpec { count: 64, phase: 0.0, stop: Stop::Arc(2.0), spacing: 0.1 };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| Fan::trace(&chain, &q_eq, spec, OdeSettings::default()).unwrap())
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a.geodesics, b.geodesics);
        assert_eq!(a.geodesics.len(), 64);
        assert_eq!(a.sample_count(), 64 * 20);
    }
}
