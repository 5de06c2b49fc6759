//! Choosing at most K springs: greedy forward selection refined by exchange moves, random
//! restarts and 2-for-2 swaps.
//!
//! The best K-subset of a few hundred candidates is a combinatorial problem. Backward elimination
//! from the dense solution is cheap but myopic (it cannot undo an early removal). Here a greedy
//! forward pass builds a support one element at a time, each step trying every candidate with a
//! non-negative refit; exchange moves then try replacing each chosen element by each unchosen one
//! and take the best improving swap, until none improves. Every trial is a small non-negative
//! least-squares solve on the Gram matrix restricted to the trial support, so the cost is
//! (passes × K × p) solves of size ≤ K — milliseconds each pass for p ≈ 500. Trials of one step
//! run in parallel; the winner is the smallest objective with ties broken by candidate index, so
//! the result does not depend on the thread count.
//!
//! One exchange search stops in a local optimum: no single swap improves, yet two elements that
//! only help together (an antagonistic pair, two crank phases) are never tried. [`search`] adds
//! two remedies. *2-for-2 swaps*: when no single swap improves, every pair of chosen elements is
//! removed and the best two replacements are added greedily; an improvement resumes the exchange
//! moves. *Random restarts*: restart r replaces 1 + (r − 1) mod ⌈K/2⌉ elements of that optimum by
//! elements drawn from a pool (the dense solution's support) with its own SplitMix64 stream
//! (seed, r), and runs the exchange moves from there. Restarts run in parallel and the winner is
//! the smallest objective, ties broken by restart index: the result does not depend on the
//! thread count either. Refits are warm-started, and with a screen only the replacements that
//! lower the objective most to first order are refitted (`shortlist`), so one exchange pass costs
//! K·(shortlist + 1) refits instead of K·p.

use nalgebra::DMatrix;
use rayon::prelude::*;

use super::lsq::Gram;
use super::nnls::{NnlsSettings, nnls, nnls_warm};
use crate::error::Result;
use crate::rng::SplitMix64;

/// Stream offset of the restarts (the as-built builds use small stream indices of the same seed).
const RESTART_STREAM: u64 = 0x5e1e_c700_0000;

/// Settings of the sparse selection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectionSettings {
    /// At most this many elements.
    pub max_elements: usize,
    /// Most passes of exchange moves after the greedy build.
    pub swap_passes: usize,
    /// Random restarts of the local search besides the one from the given start (0: the single
    /// exchange search of [`select_from`]).
    pub restarts: usize,
    /// Also try 2-for-2 swaps when no single exchange improves.
    pub pair_swaps: bool,
    /// Seed of the restarts (restart r draws from its own stream).
    pub seed: u64,
    /// With a screen (see [`search`]): refit only this many replacements per removed element,
    /// the best by the screen's score (0: all).
    pub shortlist: usize,
}

/// A screen: given a support and its refitted stiffnesses, a score per candidate of how much
/// adding it would lower the objective (0 or less: not worth a refit). Used to shortlist the
/// replacements an exchange or pair move refits.
pub type Screen<'a> = &'a (dyn Fn(&[usize], &[f64]) -> Vec<f64> + Sync);

/// The `limit` best-scoring candidates outside `exclude` with a positive score, best first
/// (ties by index).
fn shortlist(scores: &[f64], exclude: &[usize], limit: usize) -> Vec<usize> {
    let mut c: Vec<usize> =
        (0..scores.len()).filter(|j| scores[*j] > 0.0 && scores[*j].is_finite() && !exclude.contains(j)).collect();
    c.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]).then(a.cmp(&b)));
    c.truncate(limit);
    c
}

/// The outcome of a selection.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Chosen candidate indices, ascending (elements refitted to zero are dropped).
    pub support: Vec<usize>,
    /// Objective of the refit on the support.
    pub objective: f64,
    /// Subset solves performed.
    pub evaluations: usize,
    /// Exchange moves accepted.
    pub swaps: usize,
}

/// Picks at most `settings.max_elements` of `p` candidates minimising `objective(support)`,
/// which returns the refit objective and the refitted stiffnesses (same order as `support`).
pub fn select<F>(p: usize, settings: SelectionSettings, objective: F) -> Result<Selection>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let k_max = settings.max_elements.min(p);
    let mut evaluations = 0usize;
    let mut support: Vec<usize> = Vec::new();
    let mut best = f64::INFINITY;
    // Greedy forward build. A refit may zero out earlier elements (the support shrinks), so the
    // loop is bounded by steps rather than by the support size alone.
    for _ in 0..3 * k_max {
        if support.len() >= k_max {
            break;
        }
        let trials: Vec<(usize, f64, Vec<usize>)> = (0..p)
            .into_par_iter()
            .filter(|j| !support.contains(j))
            .map(|j| {
                let mut s = support.clone();
                s.push(j);
                s.sort_unstable();
                let (obj, k) = objective(&s)?;
                Ok((j, obj, prune(&s, &k)))
            })
            .collect::<Result<Vec<_>>>()?;
        evaluations += trials.len();
        match pick(trials) {
            Some((_, obj, s)) if obj < best * (1.0 - 1e-12) || support.is_empty() => {
                best = obj;
                support = s;
            }
            _ => break,
        }
    }
    exchange(p, settings, objective, support, best, evaluations, None)
}

/// Exchange moves from a given support (e.g. one found by backward elimination).
pub fn select_from<F>(p: usize, settings: SelectionSettings, support: Vec<usize>, objective: F) -> Result<Selection>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let (best, _) = objective(&support)?;
    exchange(p, settings, objective, support, best, 1, None)
}

fn exchange<F>(
    p: usize,
    settings: SelectionSettings,
    objective: F,
    mut support: Vec<usize>,
    mut best: f64,
    mut evaluations: usize,
    screen: Option<Screen<'_>>,
) -> Result<Selection>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let k_max = settings.max_elements.min(p);
    let screen = screen.filter(|_| settings.shortlist > 0);
    // Exchange moves: best improving swap per pass.
    let mut swaps = 0;
    for _ in 0..settings.swap_passes {
        let out: Vec<usize> = (0..p).filter(|j| !support.contains(j)).collect();
        let (moves, adds): (Vec<(usize, usize)>, Vec<usize>) = match screen {
            None => (
                support.iter().flat_map(|&i| out.iter().map(move |&j| (i, j))).collect(),
                // Also allow plain additions while below the budget.
                if support.len() < k_max { out.clone() } else { Vec::new() },
            ),
            Some(sc) => {
                // Per removed element, only the replacements the screen ranks best.
                let per: Vec<Vec<(usize, usize)>> = support
                    .par_iter()
                    .map(|&i| {
                        let reduced: Vec<usize> = support.iter().copied().filter(|&x| x != i).collect();
                        let (_, k) = objective(&reduced)?;
                        let scores = sc(&reduced, &k);
                        Ok(shortlist(&scores, &support, settings.shortlist).into_iter().map(|j| (i, j)).collect())
                    })
                    .collect::<Result<Vec<_>>>()?;
                evaluations += support.len();
                let adds = if support.len() < k_max {
                    let (_, k) = objective(&support)?;
                    evaluations += 1;
                    shortlist(&sc(&support, &k), &support, settings.shortlist)
                } else {
                    Vec::new()
                };
                (per.concat(), adds)
            }
        };
        let mut trials: Vec<(usize, f64, Vec<usize>)> = moves
            .par_iter()
            .enumerate()
            .map(|(t, &(i, j))| {
                let mut s: Vec<usize> = support.iter().copied().filter(|&x| x != i).collect();
                s.push(j);
                s.sort_unstable();
                let (obj, k) = objective(&s)?;
                Ok((t, obj, prune(&s, &k)))
            })
            .collect::<Result<Vec<_>>>()?;
        let offset = moves.len();
        trials.extend(
            adds.par_iter()
                .enumerate()
                .map(|(t, &j)| {
                    let mut s = support.clone();
                    s.push(j);
                    s.sort_unstable();
                    let (obj, k) = objective(&s)?;
                    Ok((offset + t, obj, prune(&s, &k)))
                })
                .collect::<Result<Vec<_>>>()?,
        );
        evaluations += trials.len();
        match pick(trials) {
            Some((_, obj, s)) if obj < best * (1.0 - 1e-9) => {
                best = obj;
                support = s;
                swaps += 1;
            }
            _ => break,
        }
    }
    let (objective, k) = objective(&support)?;
    evaluations += 1;
    let support = prune(&support, &k);
    Ok(Selection { support, objective, evaluations, swaps })
}

/// Local search from `start` with 2-for-2 swaps and random restarts (see the module docs): the
/// exchange moves from `start`, refined by 2-for-2 swaps alternating with exchange moves, give a
/// first optimum; each restart perturbs it and runs exchange moves (in parallel); the best of
/// all, ties broken by restart index, is refined by pair swaps again (they cost K² shortlists a
/// round, too many to spend on every restart). `pool` holds the candidates restarts draw from
/// (all candidates when it has fewer than 2K). `screen` shortlists the replacements (see
/// [`gain_scores`]); without it every candidate is refitted.
pub fn search<F>(
    p: usize,
    settings: SelectionSettings,
    start: Vec<usize>,
    pool: &[usize],
    objective: F,
    screen: Option<Screen<'_>>,
) -> Result<Selection>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let k_max = settings.max_elements.min(p);
    let all: Vec<usize> = (0..p).collect();
    let pool: &[usize] = if pool.len() >= 2 * k_max { pool } else { &all };
    // The local optimum from the given start, refined by pair swaps.
    let (obj0, _) = objective(&start)?;
    let first = exchange(p, settings, &objective, start, obj0, 1, screen)?;
    let first = {
        let refined = pair_refine(p, settings, first.clone(), &objective, screen)?;
        Selection {
            evaluations: first.evaluations + refined.evaluations,
            swaps: first.swaps + refined.swaps,
            ..refined
        }
    };
    // Restarts from perturbations of it, in parallel.
    let centre = first.support.clone();
    let runs: Vec<Selection> = (1..=settings.restarts)
        .into_par_iter()
        .map(|r| {
            let mut rng = SplitMix64::stream(settings.seed, RESTART_STREAM + r as u64);
            // Perturbations of every size from one element to half the support, in turn: small
            // ones explore near the optimum, large ones farther away.
            let half = centre.len().div_ceil(2).max(1);
            let s = perturbed(&centre, pool, k_max, 1 + (r - 1) % half, &mut rng);
            let (obj, _) = objective(&s)?;
            exchange(p, settings, &objective, s, obj, 1, screen)
        })
        .collect::<Result<Vec<_>>>()?;
    let evaluations: usize = first.evaluations + runs.iter().map(|r| r.evaluations).sum::<usize>();
    let swaps: usize = first.swaps + runs.iter().map(|r| r.swaps).sum::<usize>();
    // The best, ties broken by restart index (the first search is index 0).
    let best = std::iter::once(first)
        .chain(runs)
        .enumerate()
        .filter(|(_, r)| r.objective.is_finite())
        .min_by(|a, b| a.1.objective.total_cmp(&b.1.objective).then(a.0.cmp(&b.0)));
    let Some((index, best)) = best else {
        return Err(crate::error::Error::numerical("sparse selection", "no finite objective"));
    };
    if index == 0 {
        return Ok(Selection { evaluations, swaps, ..best });
    }
    let refined = pair_refine(p, settings, best, &objective, screen)?;
    Ok(Selection { evaluations: evaluations + refined.evaluations, swaps: swaps + refined.swaps, ..refined })
}

/// `start` with `drop` of its elements replaced by random members of `pool`.
fn perturbed(start: &[usize], pool: &[usize], k_max: usize, drop: usize, rng: &mut SplitMix64) -> Vec<usize> {
    let mut s = start.to_vec();
    for _ in 0..drop {
        if s.is_empty() {
            break;
        }
        let i = (rng.next_u64() % s.len() as u64) as usize;
        s.remove(i);
    }
    let mut avail: Vec<usize> = pool.iter().copied().filter(|j| !start.contains(j)).collect();
    while s.len() < k_max && !avail.is_empty() {
        let i = (rng.next_u64() % avail.len() as u64) as usize;
        s.push(avail.swap_remove(i));
    }
    s.sort_unstable();
    s
}

/// 2-for-2 swaps (if enabled) alternating with exchange moves from a local optimum of the
/// exchange moves, until neither improves or `swap_passes` rounds are spent. The counts returned
/// are those of the refinement alone.
fn pair_refine<F>(
    p: usize,
    settings: SelectionSettings,
    from: Selection,
    objective: &F,
    screen: Option<Screen<'_>>,
) -> Result<Selection>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let mut sel = Selection { evaluations: 0, swaps: 0, ..from };
    if !settings.pair_swaps {
        return Ok(sel);
    }
    for _ in 0..settings.swap_passes {
        let (found, evals) = pair_swap(p, settings, &sel.support, sel.objective, objective, screen)?;
        sel.evaluations += evals;
        let Some((obj, s)) = found else { break };
        let next = exchange(p, settings, objective, s, obj, 0, screen)?;
        sel = Selection { evaluations: sel.evaluations + next.evaluations, swaps: sel.swaps + next.swaps + 1, ..next };
    }
    Ok(sel)
}

/// A support with its objective.
type Candidate = (f64, Vec<usize>);

/// The best 2-for-2 swap: every pair of chosen elements out, two others in (the first the best
/// single addition, the second the best addition after it). Returns the improved support, if any
/// improves on `best`, and the number of refits.
fn pair_swap<F>(
    p: usize,
    settings: SelectionSettings,
    support: &[usize],
    best: f64,
    objective: &F,
    screen: Option<Screen<'_>>,
) -> Result<(Option<Candidate>, usize)>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let k_max = settings.max_elements.min(p);
    let screen = screen.filter(|_| settings.shortlist > 0);
    let pairs: Vec<(usize, usize)> =
        (0..support.len()).flat_map(|a| (a + 1..support.len()).map(move |b| (a, b))).collect();
    let trials: Vec<(usize, f64, Vec<usize>, usize)> = pairs
        .par_iter()
        .enumerate()
        .map(|(t, &(a, b))| {
            let removed = [support[a], support[b]];
            let mut s: Vec<usize> = support.iter().copied().filter(|x| !removed.contains(x)).collect();
            let mut obj = f64::INFINITY;
            let mut evals = 0;
            for _ in 0..2 {
                if s.len() >= k_max {
                    break;
                }
                let mut step: Option<(f64, usize, Vec<usize>)> = None;
                let tries: Vec<usize> = match screen {
                    None => (0..p).filter(|j| !s.contains(j) && !removed.contains(j)).collect(),
                    Some(sc) => {
                        let (_, k) = objective(&s)?;
                        evals += 1;
                        let mut exclude = s.clone();
                        exclude.extend_from_slice(&removed);
                        shortlist(&sc(&s, &k), &exclude, settings.shortlist)
                    }
                };
                for j in tries {
                    let mut trial = s.clone();
                    trial.push(j);
                    trial.sort_unstable();
                    let (o, k) = objective(&trial)?;
                    evals += 1;
                    if o.is_finite() && step.as_ref().is_none_or(|(bo, _, _)| o < *bo) {
                        step = Some((o, j, prune(&trial, &k)));
                    }
                }
                let Some((o, _, next)) = step else { break };
                obj = o;
                s = next;
            }
            Ok((t, obj, s, evals))
        })
        .collect::<Result<Vec<_>>>()?;
    let evals = trials.iter().map(|t| t.3).sum();
    let winner = pick(trials.into_iter().map(|(t, o, s, _)| (t, o, s)).collect());
    Ok((winner.filter(|(_, o, _)| *o < best * (1.0 - 1e-9)).map(|(_, o, s)| (o, s)), evals))
}

/// Backward elimination from `start` down to at most `k_max` elements on the normal equations:
/// each step refits by NNLS (warm-started from the previous support) and removes the elements
/// whose removal raises the objective least by the least-squares deletion estimate
/// kⱼ² / (G_S⁻¹)ⱼⱼ (elements refitted to zero go first). While the support is much larger than
/// the budget, an eighth of the excess goes per step; the last steps remove one at a time.
pub fn backward_elimination(gram: &Gram, start: Vec<usize>, k_max: usize) -> Result<Vec<usize>> {
    let settings = NnlsSettings::default();
    let mut support = start;
    loop {
        let sub = gram.subset(&support);
        let all: Vec<usize> = (0..support.len()).collect();
        let sol = nnls_warm(&sub, 0.0, &settings, &all)?;
        let kept = prune(&support, sol.k.as_slice());
        if kept.len() < support.len() {
            support = kept;
            continue;
        }
        if support.len() <= k_max {
            return Ok(support);
        }
        let n = support.len();
        let mut g = sub.g.clone();
        let ridge = 1e-12 * g.diagonal().amax().max(1e-300);
        for a in 0..n {
            g[(a, a)] += ridge;
        }
        let inv = g.try_inverse().unwrap_or_else(|| DMatrix::identity(n, n));
        let mut cost: Vec<(usize, f64)> = (0..n).map(|a| (a, sol.k[a] * sol.k[a] / inv[(a, a)].max(1e-300))).collect();
        cost.sort_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)));
        let excess = n - k_max;
        let remove = if excess > 8 { excess / 8 } else { 1 };
        let mut victims: Vec<usize> = cost.iter().take(remove).map(|c| c.0).collect();
        victims.sort_unstable_by(|a, b| b.cmp(a));
        for v in victims {
            support.remove(v);
        }
    }
}

/// The objective and stiffnesses of the NNLS refit of `gram` on `support` (the usual objective
/// for [`select`] and [`select_from`]).
pub fn subset_nnls(gram: &Gram, support: &[usize]) -> Result<(f64, Vec<f64>)> {
    let sol = nnls(&gram.subset(support), 0.0, &NnlsSettings::default())?;
    Ok((sol.objective, sol.k.iter().copied().collect()))
}

/// [`subset_nnls`] warm-started with the whole support passive: the exchange and pair trials
/// differ from a solved support by one or two elements, so one passive-set solve usually settles
/// them (same answer as the cold start up to round-off, several times faster).
pub fn subset_nnls_warm(gram: &Gram, support: &[usize]) -> Result<(f64, Vec<f64>)> {
    let all: Vec<usize> = (0..support.len()).collect();
    let sol = nnls_warm(&gram.subset(support), 0.0, &NnlsSettings::default(), &all)?;
    Ok((sol.objective, sol.k.iter().copied().collect()))
}

/// A [`Screen`] for the least-squares problem `gram`: the drop of the unconstrained objective
/// when candidate j joins `support` (stiffnesses `k`), wⱼ² / (Gⱼⱼ − G_jS G_SS⁻¹ G_Sj) with
/// w = c − G_{:,S} k; 0 where wⱼ ≤ 0 (with kⱼ ≥ 0 it cannot help to first order).
pub fn gain_scores(gram: &Gram, support: &[usize], k: &[f64]) -> Vec<f64> {
    let p = gram.dim();
    let ns = support.len();
    let mut w = gram.c.clone();
    for (a, &i) in support.iter().enumerate() {
        if k[a] != 0.0 {
            w -= gram.g.column(i) * k[a];
        }
    }
    let gs = DMatrix::from_fn(ns, p, |a, j| gram.g[(support[a], j)]);
    let x = if ns == 0 {
        None
    } else {
        let mut gss = DMatrix::from_fn(ns, ns, |a, b| gram.g[(support[a], support[b])]);
        let ridge = 1e-12 * gss.diagonal().amax().max(1e-300);
        for a in 0..ns {
            gss[(a, a)] += ridge;
        }
        gss.cholesky().map(|c| c.solve(&gs))
    };
    (0..p)
        .map(|j| {
            let gjj = gram.g[(j, j)];
            if w[j] <= 0.0 || gjj <= 0.0 {
                return 0.0;
            }
            let schur = match &x {
                Some(x) => gjj - (0..ns).map(|a| gs[(a, j)] * x[(a, j)]).sum::<f64>(),
                None => gjj,
            };
            if schur <= 1e-12 * gjj { 0.0 } else { w[j] * w[j] / schur }
        })
        .collect()
}

/// The trial with the smallest objective, ties broken by trial index.
fn pick(trials: Vec<(usize, f64, Vec<usize>)>) -> Option<(usize, f64, Vec<usize>)> {
    trials.into_iter().filter(|t| t.1.is_finite()).min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
}

/// The support without elements refitted to exactly zero.
fn prune(support: &[usize], k: &[f64]) -> Vec<usize> {
    support.iter().zip(k).filter(|(_, k)| **k > 0.0).map(|(s, _)| *s).collect()
}

#[cfg(test)]
mod tests {
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
        SelectionSettings { max_elements: 0, swap_passes: 0, restarts: 0, pair_swaps: false, seed: 1, shortlist: 0 };

    #[test]
    fn exchange_moves_find_what_greedy_misses() {
        let settings = SelectionSettings { max_elements: 2, swap_passes: 10, ..NONE };
        let sel = select(6, settings, |s| Ok(toy(s))).unwrap();
        // Greedy picks {0, 1} (objective 91); swapping 0 for 2 gives the pair {1, 2} (83).
        assert_eq!(sel.support, vec![1, 2]);
        assert_eq!(sel.objective, 83.0);
        assert!(sel.swaps >= 1);
        let greedy_only =
            select(6, SelectionSettings { max_elements: 2, swap_passes: 0, ..NONE }, |s| Ok(toy(s))).unwrap();
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
}
