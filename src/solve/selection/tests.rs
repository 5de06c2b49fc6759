//! Tests of `selection`.

use super::*;

/// A separable toy objective: each candidate j alone reduces the objective by gain[j]; pairs
/// 1 and 2 reduce it further only together (greedy misses the pair, an exchange finds it).
fn toy(support: &[usize]) -> (f64, Vec<f64>) {
    let gain = [5.0, 4.0, 3.0, 1.0, 1.0, 0.5];
    let mut obj = 100.0 - support.iter().map(|&j| gain[j]).sum::<f64>();
    if support.contains(&1) && support.contains(&2) {
        obj -= 10.0;
    }
    (obj, vec![1.0; support.len()])
}

const NONE: SelectionSettings =
    SelectionSettings { max_elements: 0, swap_passes: 0, restarts: 0, pair_swaps: false, seed: 1 };

#[test]
fn exchange_moves_find_what_greedy_misses() {
    let settings = SelectionSettings { max_elements: 2, swap_passes: 10, ..NONE };
    let sel = select(6, settings, |s| Ok(toy(s))).unwrap();
    // Greedy picks {0, 1} (objective 91); swapping 0 for 2 gives the pair {1, 2} (83).
    assert_eq!(sel.support, vec![1, 2]);
    assert_eq!(sel.objective, 83.0);
    assert!(sel.swaps >= 1);
    let greedy_only = select(6, SelectionSettings { max_elements: 2, swap_passes: 0, ..NONE }, |s| Ok(toy(s))).unwrap();
    assert_eq!(greedy_only.support, vec![0, 1]);
}

#[test]
fn deterministic_across_thread_counts() {
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            select(6, SelectionSettings { max_elements: 3, swap_passes: 5, ..NONE }, |s| Ok(toy(s))).unwrap()
        })
    };
    assert_eq!(run(1), run(2));
}

/// A toy where only a triple helps: {3, 4} together with 5 beats everything, but from the
/// start {0, 1, 2} no single swap improves (each of 3, 4, 5 alone is worthless) and no pair
/// swap reaches the triple either; restarts that draw from the pool find it, and the answer
/// is the same on one thread and on two.
fn triple(support: &[usize]) -> (f64, Vec<f64>) {
    let gain = [3.0, 3.0, 3.0, 0.0, 0.0, 0.0, 0.1, 0.1];
    let mut obj = 100.0 - support.iter().map(|&j| gain[j]).sum::<f64>();
    if [3, 4, 5].iter().all(|j| support.contains(j)) {
        obj -= 50.0;
    }
    (obj, vec![1.0; support.len()])
}

#[test]
fn restarts_escape_what_single_and_pair_swaps_cannot() {
    let base = SelectionSettings { max_elements: 3, swap_passes: 20, ..NONE };
    let pool: Vec<usize> = (0..8).collect();
    let plain =
        search(8, SelectionSettings { pair_swaps: true, ..base }, vec![0, 1, 2], &pool, |s| Ok(triple(s)), None)
            .unwrap();
    assert_eq!(plain.support, vec![0, 1, 2]);
    let run = |threads| {
        let pool_t = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool_t.install(|| {
            search(
                8,
                SelectionSettings { restarts: 40, pair_swaps: true, ..base },
                vec![0, 1, 2],
                &pool,
                |s| Ok(triple(s)),
                None,
            )
            .unwrap()
        })
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one, two);
    assert_eq!(one.support, vec![3, 4, 5]);
    assert_eq!(one.objective, 50.0);
}

/// Pair swaps find a pair that only helps together when the budget is full.
#[test]
fn pair_swaps_find_cooperating_pairs() {
    let pair = |support: &[usize]| {
        let gain = [2.0, 2.0, 0.6, 0.0, 0.5];
        let mut obj = 10.0 - support.iter().map(|&j| gain[j]).sum::<f64>();
        if support.contains(&2) && support.contains(&3) {
            obj -= 8.0;
        }
        (obj, vec![1.0; support.len()])
    };
    let base = SelectionSettings { max_elements: 2, swap_passes: 10, ..NONE };
    let single = search(5, base, vec![0, 1], &[], |s| Ok(pair(s)), None).unwrap();
    assert_eq!(single.support, vec![0, 1]);
    let paired =
        search(5, SelectionSettings { pair_swaps: true, ..base }, vec![0, 1], &[], |s| Ok(pair(s)), None).unwrap();
    assert_eq!(paired.support, vec![2, 3]);
}

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

/// A least-squares problem with correlated columns (so that greedy choices mislead): 60 rows,
/// `p` columns mixing a few shared factors, right-hand side from a sparse non-negative mix
/// plus noise.
fn correlated(p: usize, seed: u64) -> Gram {
    let mut s = seed;
    let factors = DMatrix::from_fn(60, 6, |_, _| lcg(&mut s));
    let a = DMatrix::from_fn(60, p, |i, j| {
        factors[(i, j % 6)] + 0.6 * factors[(i, (j * 7 + 3) % 6)] * if j % 2 == 0 { 1.0 } else { -1.0 }
    }) + DMatrix::from_fn(60, p, |_, _| 0.4 * lcg(&mut s));
    let truth = DVector::from_fn(p, |j, _| if j % 5 == 1 { 1.0 + 0.3 * j as f64 / p as f64 } else { 0.0 });
    let b = &a * truth + DVector::from_fn(60, |_, _| 0.3 * lcg(&mut s));
    Gram::from_rows(&a, &b)
}

/// Every subset of at most `k` items, refitted by NNLS: the best objective.
fn brute_force(gram: &Gram, items: &Items, k: usize) -> f64 {
    let n = items.len();
    let mut best = f64::INFINITY;
    for mask in 1u32..(1 << n) {
        if mask.count_ones() as usize > k {
            continue;
        }
        let s: Vec<usize> = (0..n).filter(|i| mask & (1 << i) != 0).collect();
        best = best.min(subset_nnls(gram, items, &s).unwrap().0);
    }
    best
}

fn run_search(gram: &Gram, items: &Items, k: usize, restarts: usize) -> Selection {
    let n = items.len();
    let dense = nnls(gram, 0.0, &NnlsSettings::default()).unwrap();
    let pool = items.touching(|j| dense.k[j] > 0.0);
    let start = backward_elimination(gram, items, pool.clone(), k).unwrap();
    let settings = SelectionSettings { max_elements: k, swap_passes: 50, restarts, pair_swaps: true, seed: 3 };
    let bound = |s: &[usize]| extension_bounds(gram, items, s);
    search(n, settings, start, &pool, |s| subset_nnls_warm(gram, items, s), Some(&bound)).unwrap()
}

/// The bound is a lower bound on every refit, and exact where the unconstrained refit is
/// non-negative; for single columns and for groups of columns.
#[test]
fn extension_bounds_are_lower_bounds() {
    let gram = correlated(16, 21);
    let groups: Vec<Option<usize>> = (0..16).map(|j| if j >= 10 { Some(j / 3) } else { None }).collect();
    for items in [Items::singletons(16), Items::from_groups(&groups)] {
        let mut exact = 0;
        for support in [vec![], vec![1], vec![0, 3, 6], vec![2, 4, 5, 8]] {
            let support: Vec<usize> = support.into_iter().filter(|&i| i < items.len()).collect();
            let bounds = extension_bounds(&gram, &items, &support);
            for i in (0..items.len()).filter(|i| !support.contains(i)) {
                let mut s = support.clone();
                s.push(i);
                s.sort_unstable();
                let (obj, _) = subset_nnls(&gram, &items, &s).unwrap();
                assert!(bounds[i] <= obj * (1.0 + 1e-9) + 1e-9, "{support:?} + {i}: {} > {obj}", bounds[i]);
                if (obj - bounds[i]).abs() < 1e-6 * obj {
                    exact += 1;
                }
            }
            assert!(support.iter().all(|&i| bounds[i] == f64::INFINITY));
        }
        assert!(exact > 10, "the bound should be exact for many trials, was for {exact}");
    }
}

/// On problems small enough for brute force (16 columns, at most 4), the search with
/// restarts finds the best subset, and the same one on one thread and on four.
#[test]
fn search_finds_the_brute_force_optimum_whatever_the_threads() {
    for seed in [5, 17, 29] {
        let gram = correlated(16, seed);
        let items = Items::singletons(16);
        let best = brute_force(&gram, &items, 4);
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| run_search(&gram, &items, 4, 24))
        };
        let (one, four) = (run(1), run(4));
        assert_eq!(one, four);
        assert!(one.support.len() <= 4);
        assert!((one.objective - best).abs() <= 1e-9 * best, "seed {seed}: {} vs brute force {best}", one.objective);
    }
}

/// Groups count once: with columns 8..16 in groups of four (two "cams") and a budget of 3,
/// the selection returns at most 3 items, reaches the brute-force optimum over items, and
/// its columns are whole groups.
#[test]
fn groups_count_as_one_element() {
    let gram = correlated(16, 41);
    let groups: Vec<Option<usize>> = (0..16).map(|j| if j >= 8 { Some(j / 4) } else { None }).collect();
    let items = Items::from_groups(&groups);
    assert_eq!(items.len(), 10);
    assert_eq!(items.members(8), &[8, 9, 10, 11]);
    let sel = run_search(&gram, &items, 3, 16);
    assert!(sel.support.len() <= 3);
    let best = brute_force(&gram, &items, 3);
    assert!((sel.objective - best).abs() <= 1e-9 * best, "{} vs brute force {best}", sel.objective);
    let cols = items.columns(&sel.support);
    for g in [8, 9] {
        let m = items.members(g);
        assert!(m.iter().all(|j| cols.contains(j)) || m.iter().all(|j| !cols.contains(j)));
    }
}

/// A support refitted within a budget is the constrained optimum (worked by hand): G = I,
/// c = (1, 1), bᵀb = 2, mass k₁ + 2k₂ ≤ 0.5. The KKT conditions give k = (1 − μ, 1 − 2μ)₊ with the
/// mass at the budget: μ = 0.5, k = (0.5, 0), objective ‖k‖² − 2cᵀk + 2 = 1.25. A quadratic mass
/// (k₁² + k₂² ≤ 0.5) gives k = (0.5, 0.5) by symmetry, objective 0.5. A budget that does not bind
/// leaves the plain refit (k = (1, 1), objective 0) exactly.
#[test]
fn a_refit_within_the_budget_is_the_constrained_optimum() {
    let gram = Gram { g: DMatrix::identity(2, 2), c: DVector::from_vec(vec![1.0, 1.0]), bb: 2.0 };
    let items = Items::singletons(2);
    let linear = SubsetBudget { linear: &[1.0, 2.0], squared: &[], max: 0.5 };
    let (obj, k) = subset_nnls_within(&gram, &items, &[0, 1], &linear).unwrap();
    assert!((obj - 1.25).abs() < 1e-5 && (k[0] - 0.5).abs() < 1e-5 && k[1] == 0.0, "{obj} {k:?}");
    assert!(k[0] + 2.0 * k[1] <= 0.5, "over the budget: {k:?}");
    let squared = SubsetBudget { linear: &[0.0, 0.0], squared: &[1.0, 1.0], max: 0.5 };
    let (obj, k) = subset_nnls_within(&gram, &items, &[0, 1], &squared).unwrap();
    assert!((obj - 0.5).abs() < 1e-5 && (k[0] - 0.5).abs() < 1e-5 && (k[1] - 0.5).abs() < 1e-5, "{obj} {k:?}");
    assert!(k[0] * k[0] + k[1] * k[1] <= 0.5, "over the budget: {k:?}");
    let loose = SubsetBudget { linear: &[1.0, 2.0], squared: &[], max: 10.0 };
    assert_eq!(
        subset_nnls_within(&gram, &items, &[0, 1], &loose).unwrap(),
        subset_nnls_warm(&gram, &items, &[0, 1]).unwrap()
    );
}

/// The bounds of the refits within a budget are lower bounds on those refits (weak duality at
/// the base's multiplier), for a straight-line and a curved mass, and where the budget binds
/// they are tighter than the unconstrained bounds on a share of the trials (9 of 22, 8 of 28:
/// what makes them worth having; never looser, being the larger of the two); a search with
/// them finds the brute-force optimum within the budget.
#[test]
fn budget_bounds_are_lower_bounds_of_the_refits_within_the_budget() {
    let gram = correlated(12, 33);
    let items = Items::singletons(12);
    let linear: Vec<f64> = (0..12).map(|j| 0.5 + 0.1 * j as f64).collect();
    let squared: Vec<f64> = (0..12).map(|j| 0.05 * (j % 3) as f64).collect();
    for (squared, max) in [(&[][..], 1.0), (&squared[..], 1.0), (&squared[..], 0.4)] {
        let budget = SubsetBudget { linear: &linear, squared, max };
        let (mut tighter, mut trials) = (0, 0);
        for support in [vec![1], vec![0, 3, 6], vec![2, 4, 5, 8]] {
            let bounds = budget_bounds(&gram, &items, &support, &budget);
            let plain = extension_bounds(&gram, &items, &support);
            let binds = budget_multiplier(&gram, &items, &support, &budget).unwrap() > 0.0;
            for i in (0..12).filter(|i| !support.contains(i)) {
                let mut s = support.clone();
                s.push(i);
                s.sort_unstable();
                let (obj, _) = subset_nnls_within(&gram, &items, &s, &budget).unwrap();
                assert!(bounds[i] <= obj * (1.0 + 1e-9) + 1e-9, "{support:?} + {i}: {} > {obj}", bounds[i]);
                // Where the budget binds on the base (its multiplier above 0) and on the trial
                // (its refit above the plain one), the bound should be above the unconstrained one.
                if binds && obj > subset_nnls(&gram, &items, &s).unwrap().0 * (1.0 + 1e-6) {
                    trials += 1;
                    if bounds[i] > plain[i] + 1e-6 * obj {
                        tighter += 1;
                    }
                }
            }
            assert!(support.iter().all(|&i| bounds[i] == f64::INFINITY));
        }
        assert!(tighter > 0 && tighter >= trials / 4, "tighter on {tighter} of {trials} binding trials (max {max})");
        // The search with these bounds reaches the best support of at most 3 within the budget
        // (to the refits' own precision: their multiplier is found to 1e-6 of the budget).
        let mut best = f64::INFINITY;
        for mask in 1u32..(1 << 12) {
            if mask.count_ones() <= 3 {
                let s: Vec<usize> = (0..12).filter(|i| mask & (1 << i) != 0).collect();
                best = best.min(subset_nnls_within(&gram, &items, &s, &budget).unwrap().0);
            }
        }
        let settings = SelectionSettings { max_elements: 3, swap_passes: 50, restarts: 16, pair_swaps: true, seed: 3 };
        let bound = |s: &[usize]| budget_bounds(&gram, &items, s, &budget);
        let all: Vec<usize> = (0..12).collect();
        let sel =
            search(12, settings, vec![0, 1, 2], &all, |s| subset_nnls_within(&gram, &items, s, &budget), Some(&bound))
                .unwrap();
        assert!((sel.objective - best).abs() <= 1e-6 * best, "max {max}: {} vs brute force {best}", sel.objective);
    }
}
