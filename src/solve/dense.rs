//! The dense kernels of the solvers — normal-equation products, Cholesky and LU — with the
//! implementation a measurement chose for each (`cargo bench --bench kernels`, BENCHMARKS.md
//! "Dense kernels: faer where it wins").
//!
//! faer is called through views over nalgebra's column-major storage (no copies) and always
//! with `Par::Seq`; the crate is built without its `rayon` feature, so no faer call can split
//! its work across threads and a result's bits do not depend on the thread count.
//!
//! [`variants`] keeps the implementations that lost or that the others are checked against, for
//! the benchmark and the tests.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::matmul::triangular::BlockStructure;
use faer::{Accum, MatMut, MatRef, Par};
use nalgebra::{DMatrix, DVector};

fn view(m: &DMatrix<f64>) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(m.as_slice(), m.nrows(), m.ncols())
}

fn view_mut(m: &mut DMatrix<f64>) -> MatMut<'_, f64> {
    let (r, c) = m.shape();
    MatMut::from_column_major_slice_mut(m.as_mut_slice(), r, c)
}

/// The lower Cholesky factor L of the symmetric matrix `m` (L Lᵀ = m, the strict upper triangle
/// zero); None when a pivot is not positive (as nalgebra's `cholesky()`, which it replaced).
pub fn cholesky_lower(mut m: DMatrix<f64>) -> Option<DMatrix<f64>> {
    use faer::linalg::cholesky::llt::factor;
    let n = m.nrows();
    assert_eq!(n, m.ncols(), "cholesky_lower needs a square matrix");
    let par = Par::Seq;
    let mut buf = MemBuffer::new(factor::cholesky_in_place_scratch::<f64>(n, par, Default::default()));
    let stack = MemStack::new(&mut buf);
    factor::cholesky_in_place(view_mut(&mut m), Default::default(), par, stack, Default::default()).ok()?;
    for j in 1..n {
        for i in 0..j {
            m[(i, j)] = 0.0;
        }
    }
    Some(m)
}

/// The inverse of the symmetric positive definite `m` from faer's Cholesky factor (both
/// triangles filled); None when a pivot is not positive. The backward elimination's inverse of
/// thousands of columns (a tendon catalogue's cams), where nalgebra's LU inverse takes minutes.
pub fn spd_inverse(mut m: DMatrix<f64>) -> Option<DMatrix<f64>> {
    use faer::linalg::cholesky::llt::{factor, inverse};
    let n = m.nrows();
    assert_eq!(n, m.ncols(), "spd_inverse needs a square matrix");
    let par = Par::Seq;
    let req = factor::cholesky_in_place_scratch::<f64>(n, par, Default::default())
        .or(inverse::inverse_scratch::<f64>(n, par));
    let mut buf = MemBuffer::new(req);
    let stack = MemStack::new(&mut buf);
    factor::cholesky_in_place(view_mut(&mut m), Default::default(), par, stack, Default::default()).ok()?;
    for j in 1..n {
        for i in 0..j {
            m[(i, j)] = 0.0;
        }
    }
    let mut out = DMatrix::zeros(n, n);
    inverse::inverse(view_mut(&mut out), view(&m), par, stack);
    for j in 1..n {
        for i in 0..j {
            out[(i, j)] = out[(j, i)];
        }
    }
    Some(out)
}

/// L⁻¹ B for the lower triangular `l` by faer's blocked triangular solve (B overwritten).
pub fn solve_lower_in_place(l: &DMatrix<f64>, b: &mut DMatrix<f64>) {
    faer::linalg::triangular_solve::solve_lower_triangular_in_place(view(l), view_mut(b), Par::Seq);
}

/// AᵀA for rows `a` (m × p): the lower triangle by faer's triangular product, mirrored (half
/// the multiplications of a full product, no transposed copy of A).
pub fn gram_of(a: &DMatrix<f64>) -> DMatrix<f64> {
    let p = a.ncols();
    let mut g = DMatrix::zeros(p, p);
    let av = view(a);
    faer::linalg::matmul::triangular::matmul(
        view_mut(&mut g),
        BlockStructure::TriangularLower,
        Accum::Replace,
        av.transpose(),
        BlockStructure::Rectangular,
        av,
        BlockStructure::Rectangular,
        1.0,
        Par::Seq,
    );
    for j in 1..p {
        for i in 0..j {
            g[(i, j)] = g[(j, i)];
        }
    }
    g
}

/// AᵀA and Aᵀb over the rows `r0 .. r0 + rows` of `a`: the lower triangle by faer's triangular
/// product on a view of the rows (no copy), mirrored, and Aᵀb by faer's product. One block of
/// [`crate::solve::lsq::Gram::from_row_blocks`].
pub fn gram_of_rows(a: &DMatrix<f64>, r0: usize, rows: usize, b: &DVector<f64>) -> (DMatrix<f64>, DVector<f64>) {
    let p = a.ncols();
    let av = view(a).subrows(r0, rows);
    let mut g = DMatrix::zeros(p, p);
    faer::linalg::matmul::triangular::matmul(
        view_mut(&mut g),
        BlockStructure::TriangularLower,
        Accum::Replace,
        av.transpose(),
        BlockStructure::Rectangular,
        av,
        BlockStructure::Rectangular,
        1.0,
        Par::Seq,
    );
    for j in 1..p {
        for i in 0..j {
            g[(i, j)] = g[(j, i)];
        }
    }
    let mut c = DVector::zeros(p);
    let bv = MatRef::from_column_major_slice(&b.as_slice()[r0..r0 + rows], rows, 1);
    let cv = MatMut::from_column_major_slice_mut(c.as_mut_slice(), p, 1);
    faer::linalg::matmul::matmul(cv, Accum::Replace, av.transpose(), bv, 1.0, Par::Seq);
    (g, c)
}

/// Samples per step of [`coupled_gram_chunk`]: the step's slopes and their scaled copy (128 ×
/// p values each, 1.5 MB at p = 1500) stay in the cache while every class reads them.
const COUPLED_STEP: usize = 128;

/// The upper triangle (in `order`) of the normal equations of coupled rows over the samples
/// `s0 .. s0 + count` (see [`crate::solve::lsq::CoupledRows`]): for each class a, the block row
/// G[J_a, J_≥a] += Φ[:, J_a]ᵀ (Φ[:, J_≥a] ⊙ v_a), where v_a(s, k) = Σ_c F[s·r + c, a] F[s·r + c,
/// class k] couples the classes within sample s. Columns are taken in `order` (sorted by
/// class, `starts[a]` the first of class a), so J_a and J_≥a are contiguous; faer's product,
/// sequential, summed step by step in sample order.
pub fn coupled_gram_chunk(
    rows: &crate::solve::lsq::CoupledRows,
    order: &[usize],
    starts: &[usize],
    s0: usize,
    count: usize,
) -> DMatrix<f64> {
    let p = order.len();
    let classes = starts.len() - 1;
    let per = rows.per_sample;
    let mut g = DMatrix::zeros(p, p);
    let mut phi = DMatrix::zeros(COUPLED_STEP, p);
    let mut psi = DMatrix::zeros(COUPLED_STEP, p);
    let mut v = vec![0.0; COUPLED_STEP];
    for t0 in (s0..s0 + count).step_by(COUPLED_STEP) {
        let steps = COUPLED_STEP.min(s0 + count - t0);
        for (col, &j) in phi.as_mut_slice().chunks_exact_mut(COUPLED_STEP).zip(order) {
            (rows.slopes)(j, t0, &mut col[..steps]);
        }
        for a in 0..classes {
            // Class a's columns J_a = first .. first + size, and J_≥a = first .. p.
            let (first, size) = (starts[a], starts[a + 1] - starts[a]);
            if size == 0 {
                continue;
            }
            let (r0, r1) = (t0 * per, (t0 + steps) * per);
            let fa = &rows.factors[a][r0..r1];
            for b in (a..classes).filter(|&b| starts[b + 1] > starts[b]) {
                let fb = &rows.factors[b][r0..r1];
                for (vt, (x, y)) in v.iter_mut().zip(fa.chunks_exact(per).zip(fb.chunks_exact(per))) {
                    *vt = x.iter().zip(y).map(|(x, y)| x * y).sum();
                }
                let (from, to) = (starts[b] * COUPLED_STEP, starts[b + 1] * COUPLED_STEP);
                for (out, col) in psi.as_mut_slice()[from..to]
                    .chunks_exact_mut(COUPLED_STEP)
                    .zip(phi.as_slice()[from..to].chunks_exact(COUPLED_STEP))
                {
                    for ((o, x), vt) in out.iter_mut().zip(col).zip(&v).take(steps) {
                        *o = x * vt;
                    }
                }
            }
            let width = p - first;
            let lhs = view(&phi).subrows(0, steps).subcols(first, size).transpose();
            let rhs = view(&psi).subrows(0, steps).subcols(first, width);
            faer::linalg::matmul::matmul(
                view_mut(&mut g).submatrix_mut(first, first, size, width),
                Accum::Add,
                lhs,
                rhs,
                1.0,
                Par::Seq,
            );
        }
    }
    g
}

/// The implementations the kernels above are measured and checked against: nalgebra's (the
/// code before faer) and faer's where the hand-written or nalgebra code stayed. Not part of the
/// library's interface; public for `benches/kernels.rs`.
#[doc(hidden)]
pub mod variants {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::{Accum, MatMut, MatRef, Par};
    use nalgebra::{DMatrix, DVector};

    /// Solves the square system M x = b by faer's LU with partial pivoting; None when a pivot is
    /// exactly zero (as nalgebra's `lu().solve()`). 3–4.5× nalgebra's from about 100 unknowns,
    /// slower below 30; not used: its rounding changes the QP's polished vertices (see
    /// `qp::kkt_solve`).
    pub fn lu_solve_faer(mut m: DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
        use faer::linalg::lu::partial_pivoting::{factor, solve};
        let n = m.nrows();
        assert_eq!(n, m.ncols(), "lu_solve needs a square matrix");
        assert_eq!(n, b.len(), "lu_solve: right-hand side of the wrong length");
        let mut x = b.clone();
        if n == 0 {
            return Some(x);
        }
        let (mut perm, mut perm_inv) = (vec![0usize; n], vec![0usize; n]);
        let par = Par::Seq;
        let req = factor::lu_in_place_scratch::<usize, f64>(n, n, par, Default::default())
            .or(solve::solve_in_place_scratch::<usize, f64>(n, 1, par));
        let mut buf = MemBuffer::new(req);
        let stack = MemStack::new(&mut buf);
        let mut lu = super::view_mut(&mut m);
        let (_, p) = factor::lu_in_place(lu.as_mut(), &mut perm, &mut perm_inv, par, stack, Default::default());
        if (0..n).any(|i| lu[(i, i)] == 0.0) {
            return None;
        }
        let rhs = MatMut::from_column_major_slice_mut(x.as_mut_slice(), n, 1);
        solve::solve_in_place(lu.as_ref(), lu.as_ref(), p, rhs, par, stack);
        Some(x)
    }

    /// Aᵀb by faer's product.
    pub fn transpose_times_faer(a: &DMatrix<f64>, b: &DVector<f64>) -> DVector<f64> {
        let mut c = DVector::zeros(a.ncols());
        let bv = MatRef::from_column_major_slice(b.as_slice(), b.len(), 1);
        let cv = MatMut::from_column_major_slice_mut(c.as_mut_slice(), a.ncols(), 1);
        faer::linalg::matmul::matmul(cv, Accum::Replace, super::view(a).transpose(), bv, 1.0, Par::Seq);
        c
    }

    /// nalgebra's LU with partial pivoting (the QP's KKT solve).
    pub fn lu_solve_nalgebra(m: DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
        m.lu().solve(b)
    }

    /// nalgebra's Cholesky (the QP's factor form before faer).
    pub fn cholesky_lower_nalgebra(m: DMatrix<f64>) -> Option<DMatrix<f64>> {
        m.cholesky().map(|c| c.l())
    }

    /// AᵀA by nalgebra: a transposed copy and matrixmultiply's product (`Gram::from_rows`).
    pub fn gram_of_nalgebra(a: &DMatrix<f64>) -> DMatrix<f64> {
        a.transpose() * a
    }

    /// Aᵀb by nalgebra (`Gram::from_rows`).
    pub fn transpose_times_nalgebra(a: &DMatrix<f64>, b: &DVector<f64>) -> DVector<f64> {
        a.transpose() * b
    }

    /// AᵀA by faer's full (rectangular) product.
    pub fn gram_of_faer_full(a: &DMatrix<f64>) -> DMatrix<f64> {
        let p = a.ncols();
        let mut g = DMatrix::zeros(p, p);
        let av = super::view(a);
        faer::linalg::matmul::matmul(super::view_mut(&mut g), Accum::Replace, av.transpose(), av, 1.0, Par::Seq);
        g
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::DVector;

    use super::variants::*;
    use super::*;

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    #[test]
    fn faer_lu_solves_as_nalgebras_does() {
        let mut seed = 3;
        // A KKT-like system: symmetric positive block, constraint rows, zero block.
        for (ns, ne) in [(1, 0), (7, 2), (40, 5), (130, 12)] {
            let a = DMatrix::from_fn(ns + 3, ns, |_, _| lcg(&mut seed));
            let rows = DMatrix::from_fn(ne, ns, |_, _| lcg(&mut seed));
            let n = ns + ne;
            let mut k = DMatrix::zeros(n, n);
            k.view_mut((0, 0), (ns, ns)).copy_from(&(a.transpose() * &a));
            k.view_mut((ns, 0), (ne, ns)).copy_from(&rows);
            k.view_mut((0, ns), (ns, ne)).copy_from(&rows.transpose());
            let b = DVector::from_fn(n, |_, _| lcg(&mut seed));
            let (mine, theirs) = (lu_solve_faer(k.clone(), &b).unwrap(), lu_solve_nalgebra(k.clone(), &b).unwrap());
            let scale = theirs.amax().max(1.0);
            assert!((&mine - &theirs).amax() <= 1e-10 * scale, "{ns}+{ne}: {}", (&mine - &theirs).amax());
            assert!((&k * &mine - &b).amax() < 1e-9);
        }
        // An exactly singular system (a zero row and column): None, as from nalgebra.
        let mut s = DMatrix::identity(4, 4);
        s[(2, 2)] = 0.0;
        let b = DVector::from_element(4, 1.0);
        assert!(lu_solve_faer(s.clone(), &b).is_none() && lu_solve_nalgebra(s, &b).is_none());
        assert_eq!(lu_solve_faer(DMatrix::zeros(0, 0), &DVector::zeros(0)).unwrap().len(), 0);
    }

    #[test]
    fn faer_cholesky_is_nalgebras_factor() {
        let mut seed = 5;
        for n in [1, 3, 17, 90] {
            let a = DMatrix::from_fn(n + 2, n, |_, _| lcg(&mut seed));
            let m = a.transpose() * &a + DMatrix::identity(n, n) * 1e-3;
            let (mine, theirs) = (cholesky_lower(m.clone()).unwrap(), cholesky_lower_nalgebra(m.clone()).unwrap());
            assert!((&mine - &theirs).amax() <= 1e-12 * theirs.amax(), "n = {n}");
            assert!((0..n).all(|j| (0..j).all(|i| mine[(i, j)] == 0.0)));
        }
        let mut indefinite = DMatrix::identity(3, 3);
        indefinite[(1, 1)] = -1.0;
        assert!(cholesky_lower(indefinite.clone()).is_none() && cholesky_lower_nalgebra(indefinite).is_none());
    }

    #[test]
    fn spd_inverse_and_triangular_solve_match_nalgebras() {
        let mut seed = 11;
        for n in [1, 4, 33, 120] {
            let a = DMatrix::from_fn(n + 5, n, |_, _| lcg(&mut seed));
            let m = a.transpose() * &a + DMatrix::identity(n, n) * 1e-2;
            let inv = spd_inverse(m.clone()).unwrap();
            let want = m.clone().try_inverse().unwrap();
            assert!((&inv - &want).amax() <= 1e-9 * want.amax(), "n = {n}: {}", (&inv - &want).amax());
            assert_eq!(inv, inv.transpose());
            let l = cholesky_lower(m.clone()).unwrap();
            let mut b = DMatrix::from_fn(n, 7, |_, _| lcg(&mut seed));
            let want = l.solve_lower_triangular(&b).unwrap();
            solve_lower_in_place(&l, &mut b);
            assert!((&b - &want).amax() <= 1e-9 * want.amax().max(1.0), "n = {n}");
        }
        let mut indefinite = DMatrix::identity(3, 3);
        indefinite[(2, 2)] = -1.0;
        assert!(spd_inverse(indefinite).is_none());
    }

    #[test]
    fn faer_normal_equations_match_nalgebras() {
        let mut seed = 9;
        let a = DMatrix::from_fn(300, 37, |_, _| lcg(&mut seed));
        let b = DVector::from_fn(300, |_, _| lcg(&mut seed));
        let (g, g0) = (gram_of(&a), gram_of_nalgebra(&a));
        assert!((&g - &g0).amax() <= 1e-12 * g0.amax());
        assert_eq!(g, g.transpose());
        assert!((gram_of_faer_full(&a) - &g0).amax() <= 1e-12 * g0.amax());
        let (c, c0) = (transpose_times_faer(&a, &b), transpose_times_nalgebra(&a, &b));
        assert!((&c - &c0).amax() <= 1e-12 * c0.amax());
    }
}
