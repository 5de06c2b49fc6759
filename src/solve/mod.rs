//! Least-squares solvers that know columns, groups of columns, equalities and inequalities, and
//! nothing of springs, cams or catalogues: normal equations ([`lsq`]), non-negative least
//! squares ([`nnls`]), the same with exact equality rows on an updated factor
//! ([`lawson_hanson`]), the Clarabel QP with exact constraints ([`qp`]), the same QP on a working
//! set for many candidates ([`screen`]) and the choice of at most K items ([`selection`]).
//! The fit turns candidates into these columns.

pub mod constraint;
pub mod dense;
pub mod lawson_hanson;
pub mod lsq;
pub mod nnls;
pub mod qp;
pub mod screen;
pub mod selection;

pub use constraint::LinearGroup;

/// What the solvers' unit tests build their random problems from.
#[cfg(test)]
mod test_problems {
    use nalgebra::{DMatrix, DVector};

    use super::LinearGroup;

    /// Uniform on [−1, 1) from a linear congruential generator: the same problems on every
    /// machine.
    pub(super) fn lcg(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// A named group of constraint rows.
    pub(super) fn group(name: &str, m: DMatrix<f64>, rhs: DVector<f64>) -> LinearGroup {
        LinearGroup { name: name.into(), description: format!("{name} rows"), matrix: m, rhs }
    }
}
