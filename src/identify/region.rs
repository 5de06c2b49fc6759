//! Whether logged angles lie in the design's region.
//!
//! A log far outside the region is almost always a wrong log (angles in degrees, another joint
//! order, an encoder zero off by a turn): the elements are only known where the design was
//! fitted, and a rate identified from motion elsewhere would say little about the arm there. A
//! log may reach a margin beyond the region (`[identify] region_margin`).
//!
//! For a box the test is per coordinate. For a geodesic ball r(q) ≤ R it needs the log map, tens
//! of microseconds per point, too slow for every sample of a minute at 1 kHz; but r is
//! 1-Lipschitz in the metric, r(q_b) ≤ r(q_a) + ℓ(a → b) with ℓ the metric length of the logged
//! path between the two samples. So r is evaluated at a sample, and the next evaluation is due
//! only where r there plus the path length walked since could reach the limit: few evaluations
//! while the arm swings near q_eq, every sample only where it comes close to the boundary. (The
//! path length uses M at each sample, to first order in the sampling interval.)

use nalgebra::DVector;

use crate::design::Design;
use crate::error::Result;
use crate::geodesic::logmap::LogSettings;
use crate::geodesic::{LogMap, Region};

/// Where a sample lies against the region.
#[derive(Debug, Clone, PartialEq)]
pub struct Outside {
    /// The sample's index.
    pub sample: usize,
    /// Why it is outside, in words.
    pub reason: String,
}

/// Tests samples against a design's region enlarged by a margin.
pub struct RegionTest<'a> {
    design: &'a Design,
    margin: f64,
    log: Option<LogMap<'a>>,
}

impl<'a> RegionTest<'a> {
    /// The test of `design`'s region enlarged by `margin` (a fraction of its extent).
    pub fn new(design: &'a Design, margin: f64) -> RegionTest<'a> {
        let log = matches!(design.region, Region::Ball { .. } | Region::Clipped { .. })
            .then(|| LogMap::new(&design.chain, &design.q_eq, design.geodesics.ode, LogSettings::default()));
        RegionTest { design, margin, log }
    }

    /// The first of the samples `q` (sample-major, n per sample) outside the region, if any.
    pub fn first_outside(&self, q: &[f64]) -> Result<Option<Outside>> {
        let n = self.design.dof();
        let count = q.len() / n;
        let sample = |i: usize| &q[i * n..(i + 1) * n];
        let text = |i: usize| {
            let v: Vec<String> = sample(i).iter().map(|x| format!("{x:.4}")).collect();
            format!("({})", v.join(", "))
        };
        match &self.design.region {
            Region::Box { lower, upper } => {
                for i in 0..count {
                    for (j, &x) in sample(i).iter().enumerate() {
                        let pad = self.margin * (upper[j] - lower[j]);
                        if x < lower[j] - pad || x > upper[j] + pad {
                            return Ok(Some(Outside {
                                sample: i,
                                reason: format!(
                                    "q{} = {x:.4} rad lies outside the region's q{} ∈ [{}, {}] (with the {} % margin)",
                                    j + 1,
                                    j + 1,
                                    lower[j],
                                    upper[j],
                                    100.0 * self.margin
                                ),
                            }));
                        }
                    }
                }
                Ok(None)
            }
            // A clipped ball is judged by its radius: a logged pose beyond a joint's stop cannot happen.
            Region::Ball { radius } | Region::Clipped { radius, .. } => {
                let Some(log) = &self.log else { return Ok(None) };
                let limit = radius * (1.0 + self.margin);
                let chain = &self.design.chain;
                let mut shooter = log.shooter();
                let mut guess: Option<DVector<f64>> = None;
                let mut i = 0;
                while i < count {
                    let qi = DVector::from_column_slice(sample(i));
                    let r = match log.solve(&mut shooter, &qi, guess.as_ref()) {
                        Ok(p) => {
                            guess = Some(p.v);
                            p.r
                        }
                        Err(_) => {
                            return Ok(Some(Outside {
                                sample: i,
                                reason: format!(
                                    "{} rad is not reached by any geodesic from q_eq inside the region (radius {radius})",
                                    text(i)
                                ),
                            }));
                        }
                    };
                    if r > limit {
                        return Ok(Some(Outside {
                            sample: i,
                            reason: format!(
                                "{} rad lies at metric distance r = {r:.3} from q_eq, outside the region's radius {radius} \
                                 (with the {} % margin)",
                                text(i),
                                100.0 * self.margin
                            ),
                        }));
                    }
                    // Walk on while r plus the path walked stays below the limit.
                    let mut walked = 0.0;
                    let mut j = i + 1;
                    while j < count {
                        let a = DVector::from_column_slice(sample(j - 1));
                        let b = DVector::from_column_slice(sample(j));
                        let d = &b - &a;
                        walked += d.dot(&(chain.mass_matrix(&b) * &d)).max(0.0).sqrt();
                        if r + walked >= limit {
                            break;
                        }
                        j += 1;
                    }
                    i = j;
                }
                Ok(None)
            }
        }
    }
}
