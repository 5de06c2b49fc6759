//! The fit's dense kernels on the shipped problems' real matrices, each implementation the fit
//! could use side by side: nalgebra (and the hand-written code) against faer.
//!
//! `cargo bench --bench kernels`. `KERNELS_ONLY=word` runs only the designs whose name contains
//! the word. Figures and the choices they led to are in BENCHMARKS.md ("Dense kernels: faer
//! where it wins").
//!
//! For every design the problem is assembled as `springfit fit` assembles it (`Prepared::new`),
//! and the kernels run on its rows A (m × p) and normal equations:
//!
//! - the normal equations G = AᵀA, c = Aᵀb (`Gram::from_rows`, or `Gram::from_sparse_rows` for
//!   designs with cams, whose B-spline rows are mostly zero);
//! - NNLS on the whole of G (the sparse selection's starting point and the `max_elements = 0`
//!   fit: hundreds of passive-set factorisations of growing sets), and 2000 NNLS of random
//!   12-column subsets (what the selection's refits solve), with the three passive-set
//!   factorisations;
//! - LU of a KKT system [G_PP Eᵀ; E 0] with |P| + rows of the sizes the QP's polish and
//!   active-set solves meet (17 for the sparse designs, 124–375 for the dense QP fits, 364 for
//!   the triple pendulum), G_PP taken from the design's scaled G;
//! - the Cholesky of the scaled G + ridge (the QP's factor form, once per QP solve), of a sparse
//!   fit's support (12 columns) and of all columns;
//! - VᵀV over one cam's columns (the tolerance-aware penalty's blocks).

mod common;

use std::hint::black_box;
use std::path::Path;

use nalgebra::{DMatrix, DVector};
use springfit::design::Design;
use springfit::elements::catalog::Catalog;
use springfit::fit::Prepared;
use springfit::solve::dense::{self, variants};
use springfit::solve::lsq::Gram;
use springfit::solve::nnls::{NnlsSettings, PassiveVariant, nnls_signed_variant};

use common::{ms, time};

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

fn row(label: &str, reps: usize, variants: &mut [(&str, &mut dyn FnMut())]) {
    let mut out = format!("{label}:");
    for (name, f) in variants.iter_mut() {
        let (med, min) = time(reps, f);
        let f = |d| if ms(d) < 1.0 { format!("{:.2} µs", ms(d) * 1e3) } else { format!("{:.2} ms", ms(d)) };
        out += &format!(" {name} {} / {};", f(med), f(min));
    }
    println!("{}", out.trim_end_matches(';'));
}

/// NNLS of every problem in `grams` with each passive-set factorisation.
fn nnls_row(label: &str, reps: usize, grams: &[Gram]) {
    let settings = NnlsSettings::default();
    let run = |kind| {
        move || {
            for g in grams {
                black_box(nnls_signed_variant(g, 0.0, &settings, &[], &[], kind).unwrap());
            }
        }
    };
    let (mut hand, mut hand_faer, mut faer) =
        (run(PassiveVariant::HandWritten), run(PassiveVariant::HandWrittenFaerSolve), run(PassiveVariant::Faer));
    row(
        label,
        reps,
        &mut [("hand-written", &mut hand), ("hand-written + faer solves", &mut hand_faer), ("faer", &mut faer)],
    );
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    println!("dense kernels, hand-written/nalgebra vs faer (median / min over repeats, 1 thread)");
    let only = std::env::var("KERNELS_ONLY").ok();
    for name in [
        "double_pendulum",
        "double_pendulum_dense",
        "ur5_pan_lift_elbow",
        "triple_pendulum",
        "double_pendulum_paper_window_cams",
    ] {
        if only.as_deref().is_some_and(|o| !name.contains(o)) {
            continue;
        }
        let design = Design::load(&root.join(format!("designs/{name}.toml"))).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let prepared = Prepared::new(&design, &catalog, &design.fit, springfit::progress::Progress::none()).unwrap();
        let problem = prepared.problem();
        let (a, b) = (&problem.rows, &problem.rhs);
        let (m, p) = a.shape();
        let grouped = prepared.grouping().any();
        println!("== {name}: A {m} × {p}{}", if grouped { " (cams: sparse rows)" } else { "" });
        let reps = if m * p * p > 2_000_000_000 { 3 } else { 7 };

        // Normal equations.
        if grouped {
            let nnz = a.iter().filter(|v| **v != 0.0).count();
            row(
                &format!("G = AᵀA, c = Aᵀb ({:.1} % non-zero)", 100.0 * nnz as f64 / (m * p) as f64),
                reps,
                &mut [
                    ("hand-written sparse rows", &mut || {
                        black_box(Gram::from_sparse_rows(a, b));
                    }),
                    ("faer triangular (dense)", &mut || {
                        black_box((dense::gram_of(a), variants::transpose_times_faer(a, b)));
                    }),
                ],
            );
        } else {
            row(
                "G = AᵀA, c = Aᵀb",
                reps,
                &mut [
                    ("nalgebra", &mut || {
                        black_box((variants::gram_of_nalgebra(a), variants::transpose_times_nalgebra(a, b)));
                    }),
                    ("faer full", &mut || {
                        black_box((variants::gram_of_faer_full(a), variants::transpose_times_faer(a, b)));
                    }),
                    ("faer triangular", &mut || {
                        black_box((dense::gram_of(a), variants::transpose_times_faer(a, b)));
                    }),
                ],
            );
        }

        // NNLS on the whole problem (the equalities folded in as the NNLS fit folds them).
        let gram = prepared.gram();
        let mut weighted = gram.clone();
        let weight = design.fit.equality_weight * (m.max(1) as f64).sqrt();
        for eq in &problem.equalities {
            weighted.add_weighted(&eq.matrix, &eq.rhs, weight);
        }
        let settings = NnlsSettings::default();
        let kinds = [
            ("hand-written", PassiveVariant::HandWritten),
            ("hand-written + faer solves", PassiveVariant::HandWrittenFaerSolve),
            ("faer", PassiveVariant::Faer),
        ];
        let mut outcome = Vec::new();
        for (label, kind) in kinds {
            let sol = nnls_signed_variant(&weighted, 0.0, &settings, &[], &[], kind).unwrap();
            outcome.push(format!(
                "{label}: {} iterations, {} positive",
                sol.iterations,
                sol.k.iter().filter(|v| **v > 0.0).count()
            ));
        }
        nnls_row(
            &format!("NNLS of all {p} columns ({})", outcome.join("; ")),
            reps.min(3),
            std::slice::from_ref(&weighted),
        );

        // 2000 NNLS of random 12-column subsets.
        let mut seed = 7u64;
        let subsets: Vec<Gram> = (0..2000)
            .map(|_| {
                let mut idx: Vec<usize> = Vec::new();
                while idx.len() < 12.min(p) {
                    let j = (lcg(&mut seed) * p as f64) as usize % p;
                    if !idx.contains(&j) {
                        idx.push(j);
                    }
                }
                idx.sort_unstable();
                weighted.subset(&idx)
            })
            .collect();
        nnls_row("2000 NNLS of 12-column subsets", reps.min(5), &subsets);

        // The scaled G (unit diagonal), as the QP sees it.
        let d: Vec<f64> =
            (0..p).map(|j| if gram.g[(j, j)] > 0.0 { 1.0 / gram.g[(j, j)].sqrt() } else { 1.0 }).collect();
        let scaled = DMatrix::from_fn(p, p, |i, j| gram.g[(i, j)] * d[i] * d[j] + if i == j { 1e-10 } else { 0.0 });
        // The final QP of a sparse fit sees its support (12–16 columns); a dense fit all of them.
        let chol_sizes: Vec<usize> =
            if name == "double_pendulum_dense" { vec![12, 16, 24, 32, 48, 96, 200, p] } else { vec![12.min(p), p] };
        for n in chol_sizes {
            let sub = scaled.view((0, 0), (n, n)).into_owned();
            row(
                &format!("Cholesky of the scaled G ({n} × {n})"),
                if n < 50 { 2000 } else { reps },
                &mut [
                    ("nalgebra", &mut || {
                        black_box(variants::cholesky_lower_nalgebra(sub.clone()));
                    }),
                    ("faer", &mut || {
                        black_box(dense::cholesky_lower(sub.clone()));
                    }),
                ],
            );
        }

        // KKT systems of the sizes the QP meets.
        let sizes: &[usize] = match name {
            "double_pendulum_dense" => &[17, 32, 64, 124, 250, 375],
            "triple_pendulum" => &[364],
            _ => &[17],
        };
        for &n in sizes {
            let ne = 3.min(n - 1);
            let ns = (n - ne).min(p);
            let step = p as f64 / ns as f64;
            let idx: Vec<usize> = (0..ns).map(|a| ((a as f64 * step) as usize).min(p - 1)).collect();
            let mut kkt = DMatrix::zeros(ns + ne, ns + ne);
            for (x, &i) in idx.iter().enumerate() {
                for (y, &j) in idx.iter().enumerate() {
                    kkt[(x, y)] = scaled[(i, j)];
                }
                kkt[(x, x)] += 1e-13;
            }
            for r in 0..ne {
                for x in 0..ns {
                    let v = lcg(&mut seed) - 0.5;
                    kkt[(ns + r, x)] = v;
                    kkt[(x, ns + r)] = v;
                }
            }
            let rhs = DVector::from_fn(ns + ne, |_, _| lcg(&mut seed));
            let reps_n = if n < 100 { 2000 } else { reps };
            row(
                &format!("KKT LU solve, {ns} + {ne} unknowns"),
                reps_n,
                &mut [
                    ("nalgebra", &mut || {
                        black_box(variants::lu_solve_nalgebra(kkt.clone(), &rhs));
                    }),
                    ("faer", &mut || {
                        black_box(variants::lu_solve_faer(kkt.clone(), &rhs));
                    }),
                ],
            );
        }

        // VᵀV over one cam's columns (the robust penalty's blocks).
        if let Some(group) = prepared.grouping().groups.first() {
            let v = DMatrix::from_columns(
                &group.columns.iter().map(|&j| problem.rows.column(j).into_owned()).collect::<Vec<_>>(),
            );
            row(
                &format!("VᵀV, one cam's columns ({} × {})", v.nrows(), v.ncols()),
                reps,
                &mut [
                    ("nalgebra", &mut || {
                        black_box(variants::gram_of_nalgebra(&v));
                    }),
                    ("faer triangular", &mut || {
                        black_box(dense::gram_of(&v));
                    }),
                ],
            );
        }
    }
}
