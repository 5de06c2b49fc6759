//! Monomials in n variables by a parent recursion, their values and gradients: what the fitted
//! log maps evaluate ([`super::logfit`] over the whole ball, [`super::logcells`] per cell).

use nalgebra::DMatrix;

/// Number of monomials of total degree ≤ d in n variables, C(n + d, d).
pub fn monomial_count(n: usize, d: usize) -> usize {
    (1..=d).fold(1usize, |acc, k| acc * (n + k) / k)
}

/// The monomials of degree ≤ d in n variables as (parent, variable), by increasing degree;
/// each is listed once (variables non-decreasing along the chain of parents).
pub fn monomials(n: usize, d: usize) -> Vec<(usize, usize)> {
    // (parent, variable, last variable) with the constant first.
    let mut list: Vec<(usize, usize, usize)> = vec![(0, 0, 0)];
    let mut level = vec![0usize];
    for deg in 1..=d {
        let mut next = Vec::new();
        for &p in &level {
            let from = if deg == 1 { 0 } else { list[p].2 };
            for var in from..n {
                list.push((p, var, var));
                next.push(list.len() - 1);
            }
        }
        level = next;
    }
    list.into_iter().map(|(p, v, _)| (p, v)).collect()
}

/// Values (column 0) and gradients (columns 1 … n) of the monomials at x, into `basis`.
pub fn fill_basis(monomials: &[(usize, usize)], x: &[f64], basis: &mut DMatrix<f64>) {
    let n = x.len();
    basis[(0, 0)] = 1.0;
    for j in 0..n {
        basis[(0, 1 + j)] = 0.0;
    }
    for (k, &(p, var)) in monomials.iter().enumerate().skip(1) {
        let parent = basis[(p, 0)];
        basis[(k, 0)] = parent * x[var];
        for j in 0..n {
            basis[(k, 1 + j)] = basis[(p, 1 + j)] * x[var];
        }
        basis[(k, 1 + var)] += parent;
    }
}

/// Row-major n × n product a·b into `out` (the fits' changes of frame, ∂w/∂x from ∂v/∂q).
pub fn mat_mul(a: &[f64], b: &[f64], n: usize, out: &mut [f64]) {
    for i in 0..n {
        for j in 0..n {
            out[i * n + j] = (0..n).map(|k| a[i * n + k] * b[k * n + j]).sum();
        }
    }
}
