//! The solvers' paths for thousands of columns (a tendon catalogue's cams, issue 49): NNLS with its
//! passive set in entry order (`solve::nnls::ORDERED_FROM`) and the selection's extension bounds
//! by faer's kernels (`solve::selection::LARGE_COLUMNS`) give optimal, consistent answers.

use nalgebra::{DMatrix, DVector};
use springfit::solve::lsq::Gram;
use springfit::solve::nnls::{NnlsSettings, ORDERED_FROM, nnls};
use springfit::solve::selection::{Items, LARGE_COLUMNS, extension_bounds, subset_nnls};

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

/// A least-squares problem of `p` columns over `m` rows whose target mixes a few hundred columns
/// with positive and negative weights, so that NNLS brings hundreds of columns in and drops some.
fn problem(m: usize, p: usize, seed: u64) -> Gram {
    let mut s = seed;
    let a = DMatrix::from_fn(m, p, |_, _| lcg(&mut s));
    let truth = DVector::from_fn(p, |j, _| if j % 7 == 0 { lcg(&mut s) } else { 0.0 });
    let noise = DVector::from_fn(m, |_, _| 0.05 * lcg(&mut s));
    let b = &a * truth + noise;
    Gram::from_rows(&a, &b)
}

#[test]
fn nnls_in_entry_order_meets_the_optimality_conditions() {
    let p = ORDERED_FROM + 100;
    let gram = problem(p + 400, p, 7);
    let sol = nnls(&gram, 0.0, &NnlsSettings::default()).unwrap();
    let k = &sol.k;
    let positive = k.iter().filter(|v| **v > 0.0).count();
    assert!(positive > 100 && positive < p, "{positive} of {p} columns in the solution");
    assert!(k.iter().all(|v| *v >= 0.0 && v.is_finite()));
    // KKT: the gradient c − G k is zero on the support and non-positive off it (relative to c).
    let w = &gram.c - &gram.g * k;
    let scale = gram.c.amax();
    for j in 0..p {
        if k[j] > 0.0 {
            assert!(w[j].abs() <= 1e-8 * scale, "column {j} in the support: gradient {:.3e}", w[j]);
        } else {
            assert!(w[j] <= 1e-8 * scale, "column {j} at zero would lower the objective: {:.3e}", w[j]);
        }
    }
    // The objective reported is the one of the solution, and a refit of its support alone
    // (below the threshold: the sorted path) reaches the same.
    assert!((sol.objective - gram.objective(k)).abs() <= 1e-9 * gram.bb);
    let support: Vec<usize> = (0..p).filter(|&j| k[j] > 0.0).collect();
    assert!(support.len() < ORDERED_FROM);
    let items = Items::singletons(p);
    let (refit, _) = subset_nnls(&gram, &items, &support).unwrap();
    assert!((refit - sol.objective).abs() <= 1e-9 * gram.bb, "{refit} against {}", sol.objective);
}

#[test]
fn large_extension_bounds_are_exact_where_the_refit_is_unconstrained() {
    // A support past the threshold: the bound of adding one more column is the unconstrained
    // minimum over the support and that column, which a dense solve gives directly.
    let p = LARGE_COLUMNS + 60;
    let gram = problem(p + 300, p, 11);
    let items = Items::singletons(p);
    let support: Vec<usize> = (0..LARGE_COLUMNS + 10).collect();
    let bounds = extension_bounds(&gram, &items, &support);
    assert!(support.iter().all(|&j| bounds[j] == f64::INFINITY));
    for j in [LARGE_COLUMNS + 11, LARGE_COLUMNS + 35, p - 1] {
        let mut cols = support.clone();
        cols.push(j);
        let sub = gram.subset(&cols);
        let k = sub.g.clone().cholesky().expect("positive definite").solve(&sub.c);
        let exact = sub.objective(&k);
        let scale = gram.bb;
        assert!(
            (bounds[j] - exact).abs() <= 1e-8 * scale,
            "column {j}: bound {} against the unconstrained minimum {exact}",
            bounds[j]
        );
    }
}

#[test]
fn mirrored_pairs_are_solved_as_signed_unknowns_to_the_same_optimum() {
    // A cam's ± basis columns (each − column the exact negation of the + column before it), more
    // than `ORDERED_FROM` of them, and some plain columns: NNLS solves each pair as one unknown
    // free of sign. The answer must still meet the optimality conditions of the problem as posed
    // (every column k ≥ 0, the gradient zero on the support and ≤ 0 off it), hold at most one
    // column of each pair positive, and reach the objective it reports.
    let pairs = ORDERED_FROM / 2 + 40;
    let plain = 120;
    let p = 2 * pairs + plain;
    let m = pairs + plain + 300;
    let mut s = 19;
    let base = DMatrix::from_fn(m, pairs + plain, |_, _| lcg(&mut s));
    let a = DMatrix::from_fn(m, p, |i, j| {
        if j < 2 * pairs {
            let v = base[(i, j / 2)];
            if j % 2 == 0 { v } else { -v }
        } else {
            base[(i, j - pairs)]
        }
    });
    let truth = DVector::from_fn(pairs + plain, |j, _| if j % 5 == 0 { lcg(&mut s) } else { 0.0 });
    let b = &base * truth + DVector::from_fn(m, |_, _| 0.05 * lcg(&mut s));
    let gram = Gram::from_rows(&a, &b);
    let sol = nnls(&gram, 0.0, &NnlsSettings::default()).unwrap();
    let k = &sol.k;
    assert!(k.iter().all(|v| *v >= 0.0 && v.is_finite()));
    for q in 0..pairs {
        assert!(k[2 * q] == 0.0 || k[2 * q + 1] == 0.0, "pair {q}: both columns positive");
    }
    let negative = (0..pairs).filter(|&q| k[2 * q + 1] > 0.0).count();
    let positive = (0..pairs).filter(|&q| k[2 * q] > 0.0).count();
    assert!(negative > 100 && positive > 100, "{positive} pairs positive, {negative} negative");
    let plain_in = (2 * pairs..p).filter(|&j| k[j] > 0.0).count();
    assert!(plain_in > 0 && plain_in < plain, "{plain_in} of {plain} plain columns in the solution");
    let w = &gram.c - &gram.g * k;
    let scale = gram.c.amax();
    for j in 0..p {
        if k[j] > 0.0 {
            assert!(w[j].abs() <= 1e-8 * scale, "column {j} in the support: gradient {:.3e}", w[j]);
        } else {
            assert!(w[j] <= 1e-8 * scale, "column {j} at zero would lower the objective: {:.3e}", w[j]);
        }
    }
    assert!((sol.objective - gram.objective(k)).abs() <= 1e-9 * gram.bb);
}
