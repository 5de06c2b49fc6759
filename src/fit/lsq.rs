//! Least squares in normal-equation form: the currency of the fit backends.
//!
//! ½‖A k − b‖² = ½ kᵀ G k − cᵀ k + ½ bᵀb with G = AᵀA and c = Aᵀb. Every solver and every one of
//! the thousands of subset refits of the sparse selection works on (G, c) — whose size is the
//! number of candidates, not the number of samples — so the rows are touched once.

use nalgebra::{DMatrix, DVector};

/// A least-squares problem as its normal equations.
#[derive(Debug, Clone, PartialEq)]
pub struct Gram {
    /// G = AᵀA (p × p, symmetric positive semi-definite).
    pub g: DMatrix<f64>,
    /// c = Aᵀb.
    pub c: DVector<f64>,
    /// bᵀb.
    pub bb: f64,
}

impl Gram {
    /// The normal equations of rows `a` (m × p) and right-hand side `b`.
    ///
    /// Computed with nalgebra's single-threaded matrix product, so the result is bit-identical
    /// whatever the thread count (a parallel product would change the summation order).
    pub fn from_rows(a: &DMatrix<f64>, b: &DVector<f64>) -> Gram {
        let at = a.transpose();
        Gram { g: &at * a, c: &at * b, bb: b.dot(b) }
    }

    /// Number of unknowns.
    pub fn dim(&self) -> usize {
        self.c.len()
    }

    /// ‖A k − b‖² (not halved), clamped at 0 against round-off.
    pub fn objective(&self, k: &DVector<f64>) -> f64 {
        (k.dot(&(&self.g * k)) - 2.0 * self.c.dot(k) + self.bb).max(0.0)
    }

    /// The problem restricted to the unknowns `idx` (the others fixed at zero).
    pub fn subset(&self, idx: &[usize]) -> Gram {
        Gram {
            g: DMatrix::from_fn(idx.len(), idx.len(), |a, b| self.g[(idx[a], idx[b])]),
            c: DVector::from_fn(idx.len(), |a, _| self.c[idx[a]]),
            bb: self.bb,
        }
    }

    /// Adds `weight² · ‖E k − f‖²` (weighted equations folded into the least squares).
    pub fn add_weighted(&mut self, e: &DMatrix<f64>, f: &DVector<f64>, weight: f64) {
        let w2 = weight * weight;
        let et = e.transpose();
        self.g += &et * e * w2;
        self.c += &et * f * w2;
        self.bb += f.dot(f) * w2;
    }

    /// Moves the unknowns `fixed` to the right-hand side at the values `values`: the problem in
    /// the remaining unknowns `free` (ascending, disjoint from `fixed`).
    pub fn fix(&self, free: &[usize], fixed: &[usize], values: &[f64]) -> Gram {
        let kf = DVector::from_column_slice(values);
        let gff = DMatrix::from_fn(fixed.len(), fixed.len(), |a, b| self.g[(fixed[a], fixed[b])]);
        let mut sub = self.subset(free);
        for (a, &i) in free.iter().enumerate() {
            let coupling: f64 = fixed.iter().zip(values).map(|(&j, v)| self.g[(i, j)] * v).sum();
            sub.c[a] -= coupling;
        }
        let cf: f64 = fixed.iter().zip(values).map(|(&j, v)| self.c[j] * v).sum();
        sub.bb = self.bb - 2.0 * cf + kf.dot(&(gff * &kf));
        sub
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn objective_matches_the_rows() {
        let a = DMatrix::from_row_slice(4, 3, &[1.0, 2.0, 0.0, 0.5, -1.0, 1.0, 2.0, 0.0, 1.0, -1.0, 1.0, 3.0]);
        let b = DVector::from_vec(vec![1.0, -2.0, 0.5, 3.0]);
        let gram = Gram::from_rows(&a, &b);
        let k = DVector::from_vec(vec![0.3, -0.7, 1.1]);
        let direct = (&a * &k - &b).norm_squared();
        assert!((gram.objective(&k) - direct).abs() < 1e-12);
        // Fixing unknown 1 at −0.7 leaves the same objective for the others.
        let fixed = gram.fix(&[0, 2], &[1], &[-0.7]);
        let kf = DVector::from_vec(vec![0.3, 1.1]);
        assert!((fixed.objective(&kf) - direct).abs() < 1e-12);
        // Weighted equations add their squared residual.
        let e = DMatrix::from_row_slice(1, 3, &[1.0, 1.0, 1.0]);
        let f = DVector::from_vec(vec![2.0]);
        let mut with = gram.clone();
        with.add_weighted(&e, &f, 3.0);
        let extra = 9.0 * (k.sum() - 2.0).powi(2);
        assert!((with.objective(&k) - direct - extra).abs() < 1e-12);
    }
}
