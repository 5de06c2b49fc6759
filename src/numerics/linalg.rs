//! Small dense helpers for the hot loops.
//!
//! The geodesic and simulation right-hand sides factor an n × n mass matrix (n is 2 or 3 in
//! practice) millions of times. nalgebra's decompositions take owned matrices and would allocate
//! on every call; these routines work in place on column-major slices and allocate nothing.

/// Cholesky factorisation A = L Lᵀ in place (column-major, lower triangle used and overwritten;
/// the strict upper triangle is left untouched). Returns `false` if A is not positive definite.
///
/// Two and three joints get their own copies of the loops with n a constant (the compiler
/// unrolls them): the same operations in the same order, so the same bits, without the loop
/// overhead that dominated the 2 × 2 factorisations of every geodesic step.
#[inline]
pub fn cholesky_in_place(a: &mut [f64], n: usize) -> bool {
    match n {
        2 => cholesky_in_place_n(a, 2),
        3 => cholesky_in_place_n(a, 3),
        _ => cholesky_in_place_n(a, n),
    }
}

#[inline(always)]
fn cholesky_in_place_n(a: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j + n * j];
        for k in 0..j {
            d -= a[j + n * k] * a[j + n * k];
        }
        if d <= 0.0 || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        a[j + n * j] = d;
        for i in j + 1..n {
            let mut s = a[i + n * j];
            for k in 0..j {
                s -= a[i + n * k] * a[j + n * k];
            }
            a[i + n * j] = s / d;
        }
    }
    true
}

/// Solves L Lᵀ x = b in place given the factor from [`cholesky_in_place`] (n = 2 and 3 unrolled
/// as there).
#[inline]
pub fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    match n {
        2 => cholesky_solve_n(l, 2, b),
        3 => cholesky_solve_n(l, 3, b),
        _ => cholesky_solve_n(l, n, b),
    }
}

#[inline(always)]
fn cholesky_solve_n(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i + n * k] * b[k];
        }
        b[i] = s / l[i + n * i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[k + n * i] * b[k];
        }
        b[i] = s / l[i + n * i];
    }
}

/// The geodesic equation's first-order right-hand side ẏ = (q̇, −M⁻¹h) into `dy[..2n]`, given M
/// (overwritten by its Cholesky factor, which the Jacobi-field equations reuse) and the bias
/// h(q, q̇). Returns `false` if M is not positive definite. Shared by the planar and the spatial
/// chain, which differ only in how they compute M and h.
pub fn geodesic_accel(m: &mut [f64], h: &[f64], n: usize, qd: &[f64], dy: &mut [f64]) -> bool {
    if !cholesky_in_place(m, n) {
        return false;
    }
    dy[..n].copy_from_slice(qd);
    for (d, h) in dy[n..2 * n].iter_mut().zip(h) {
        *d = -h;
    }
    cholesky_solve(m, n, &mut dy[n..2 * n]);
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    #[test]
    fn solves_spd_systems() {
        let b = DMatrix::from_row_slice(3, 3, &[2.0, 0.3, -0.1, 0.3, 1.5, 0.2, -0.1, 0.2, 0.9]);
        let a = &b * b.transpose() + DMatrix::identity(3, 3);
        let x_true = DVector::from_vec(vec![0.5, -1.25, 2.0]);
        let rhs = &a * &x_true;
        let mut f = a.as_slice().to_vec();
        assert!(cholesky_in_place(&mut f, 3));
        let mut x = rhs.as_slice().to_vec();
        cholesky_solve(&f, 3, &mut x);
        for i in 0..3 {
            assert!((x[i] - x_true[i]).abs() < 1e-13);
        }
    }

    #[test]
    fn rejects_indefinite_matrices() {
        let mut a = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_in_place(&mut a, 2));
        let mut nan = vec![f64::NAN, 0.0, 0.0, 1.0];
        assert!(!cholesky_in_place(&mut nan, 2));
    }
}
