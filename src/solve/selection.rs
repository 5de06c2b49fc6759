//! Choosing at most K elements: greedy forward selection or backward elimination for a start,
//! refined by exchange moves, 2-for-2 swaps and random restarts.
//!
//! The best K-subset of a few hundred candidates is a combinatorial problem. Backward elimination
//! from the dense solution is cheap but myopic (it cannot undo an early removal). Exchange moves
//! try replacing each chosen element by each unchosen one and take the best improving swap, until
//! none improves. Every trial is a small non-negative least-squares solve on the Gram matrix
//! restricted to the trial support. Trials run in parallel; the winner is the smallest objective
//! with ties broken by trial index, so the result does not depend on the thread count.
//!
//! **Bounds instead of a shortlist.** Refitting all K·p swaps of a pass is wasteful: most cannot
//! improve. Dropping the sign constraints can only lower a least-squares minimum, so the
//! unconstrained minimum over R ∪ {j} is a *lower bound* on the trial's refit, and for all j at
//! once it costs one Cholesky factor of G_RR and a triangular solve (see [`extension_bounds`]):
//! obj(R ∪ {j}) ≥ bᵀb − ‖L⁻¹c_R‖² − wⱼ²/sⱼ with wⱼ, sⱼ the residual correlation and the Schur
//! complement of j. It is exact whenever the unconstrained refit is non-negative, which is most
//! of the time. A pass therefore refits trials in increasing order of their bound and stops at
//! the first whose bound exceeds the best objective refitted so far (or the current objective):
//! the outcome is that of refitting every trial, at the cost of a few refits. (An earlier version
//! refitted a fixed shortlist of the 48 best first-order gains per element taken out: it missed
//! improving swaps and spent most of its time on refits that could not win.) Trials are refitted
//! in batches of a fixed size, so the counts reported do not depend on the thread count either.
//!
//! **Escaping local optima.** One exchange search stops in a local optimum: no single swap
//! improves, yet elements that only help together (an antagonistic pair, two crank phases) are
//! never tried. [`search`] adds two remedies. *2-for-2 swaps*: when no single swap improves,
//! every pair of chosen elements is removed and the best two replacements are added greedily; an
//! improvement resumes the exchange moves. *Random restarts*: iterated local search in a fixed
//! number of chains ([`CHAINS`], whatever the thread count). Each step of a chain replaces some
//! elements of the chain's best support by elements drawn from a pool (the dense solution's
//! support) with its own SplitMix64 stream (seed, step), runs the exchange moves from there (and
//! the pair swaps when that optimum is within 5 % of the chain's best) and keeps the result if it
//! improves on the chain's best. Chains run in parallel and
//! the winner is the smallest objective, ties broken by chain index: the result does not depend
//! on the thread count. Chaining matters: on the paper's catalogue with K = 12 most perturbations
//! of one optimum fall back into it, while a chain that moved on keeps exploring from there.
//!
//! **Groups.** The search counts *items*, not columns ([`Items`]): a spring is one column, a cam
//! all its basis columns, chosen or left out together and counted as one element.

use std::collections::HashMap;
use std::sync::Mutex;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::lsq::Gram;
use super::nnls::{NnlsSettings, nnls, nnls_warm};
use crate::error::{Error, Result};
use crate::numerics::rng::SplitMix64;

/// Stream offset of the restarts (the as-built builds use small stream indices of the same seed).
const RESTART_STREAM: u64 = 0x5e1e_c700_0000;

/// Chains of the iterated local search: the restarts are dealt out to this many chains, a fixed
/// number so that the result does not depend on the thread count.
pub const CHAINS: usize = 8;

/// A restart's local optimum is refined by pair swaps only if its objective is below this
/// multiple of its chain's best (pair swaps cost most of a restart; far worse optima rarely win).
const PAIR_WITHIN: f64 = 1.05;

/// From this many columns in a support the backward elimination's inverse and the extension
/// bounds' factor and triangular solve are faer's blocked kernels, not nalgebra's unblocked
/// ones: above every shipped design's selection (the largest, `ur5_six`, chooses from 1,230
/// columns), so their bits are as before; a tendon catalogue's cams reach thousands.
pub const LARGE_COLUMNS: usize = 2000;

/// Trials refitted together between two checks of the bound: fixed, so the number of refits
/// does not depend on the thread count.
const BATCH: usize = 8;

/// Settings of the sparse selection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectionSettings {
    /// At most this many elements (items: a cam counts once).
    pub max_elements: usize,
    /// Most passes of exchange moves after the greedy build.
    pub swap_passes: usize,
    /// Random restarts of the local search besides the one from the given start (0: the single
    /// exchange search of [`select_from`]), dealt out to [`CHAINS`] chains.
    pub restarts: usize,
    /// Also try 2-for-2 swaps when no single exchange improves.
    pub pair_swaps: bool,
    /// Seed of the restarts (restart r draws from its own stream).
    pub seed: u64,
}

/// Lower bounds for the search: given a support, for every item a lower bound on the objective
/// of the support with that item added (anything for items already in the support). The search
/// refits only trials whose bound could beat the best objective found (see the module docs).
pub type Bound<'a> = &'a (dyn Fn(&[usize]) -> Vec<f64> + Sync);

/// The candidates as the selection counts them: item i stands for the columns `members[i]` of
/// the least-squares problem. A spring is one column; a cam is all its basis columns, chosen or
/// left out together and counted as one element.
#[derive(Debug, Clone, PartialEq)]
pub struct Items {
    members: Vec<Vec<usize>>,
}

impl Items {
    /// Every column its own item (item j is column j).
    pub fn singletons(p: usize) -> Items {
        Items { members: (0..p).map(|j| vec![j]).collect() }
    }

    /// Columns with the same group (`Some(g)`) form one item, the others one item each; items are
    /// numbered in order of their first column, so without groups item j is column j.
    pub fn from_groups(groups: &[Option<usize>]) -> Items {
        let mut members: Vec<Vec<usize>> = Vec::new();
        let mut item_of_group: Vec<(usize, usize)> = Vec::new();
        for (j, g) in groups.iter().enumerate() {
            match g {
                None => members.push(vec![j]),
                Some(g) => match item_of_group.iter().find(|(h, _)| h == g) {
                    Some(&(_, i)) => members[i].push(j),
                    None => {
                        item_of_group.push((*g, members.len()));
                        members.push(vec![j]);
                    }
                },
            }
        }
        Items { members }
    }

    /// Number of items.
    pub fn len(&self) -> usize {
        self.members.len()
    }

    /// Whether there are no items.
    pub fn is_empty(&self) -> bool {
        self.members.is_empty()
    }

    /// The columns of item `i`.
    pub fn members(&self, i: usize) -> &[usize] {
        &self.members[i]
    }

    /// The columns of the items in `support`, ascending.
    pub fn columns(&self, support: &[usize]) -> Vec<usize> {
        let mut c: Vec<usize> = support.iter().flat_map(|&i| self.members[i].iter().copied()).collect();
        c.sort_unstable();
        c
    }

    /// The items with at least one column for which `used` holds, ascending.
    pub fn touching(&self, used: impl Fn(usize) -> bool) -> Vec<usize> {
        (0..self.len()).filter(|&i| self.members[i].iter().any(|&j| used(j))).collect()
    }

    /// Per item of `support`, the largest of `k` (given per column of `columns`, ascending) over
    /// its columns: positive when the item is used.
    fn per_item(&self, support: &[usize], columns: &[usize], k: &[f64]) -> Vec<f64> {
        support
            .iter()
            .map(|&i| {
                self.members[i]
                    .iter()
                    .map(|j| columns.binary_search(j).map_or(0.0, |a| k[a]))
                    .fold(f64::NEG_INFINITY, f64::max)
            })
            .collect()
    }
}

/// The outcome of a selection.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Chosen items, ascending (items refitted to zero are dropped).
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
        let trials: Vec<Scored> = (0..p)
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
    exchange(p, settings, &objective, support, best, evaluations, None)
}

/// Exchange moves from a given support (e.g. one found by backward elimination).
pub fn select_from<F>(p: usize, settings: SelectionSettings, support: Vec<usize>, objective: F) -> Result<Selection>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let (best, _) = objective(&support)?;
    exchange(p, settings, &objective, support, best, 1, None)
}

/// A trial support before its refit: its index in the pass (for ties) and its lower bound.
struct Trial {
    index: usize,
    bound: f64,
    support: Vec<usize>,
}

/// A refitted trial: its index, objective and support without the elements refitted to zero.
type Scored = (usize, f64, Vec<usize>);

/// The trial with the smallest refitted objective below `threshold` (ties by index), and the
/// number of refits. With bounds, trials are refitted in increasing order of their bound, in
/// batches of [`BATCH`], until the next bound exceeds the best objective so far: no trial left
/// can beat it, so the outcome is that of refitting them all. Without bounds every trial is
/// refitted in one parallel sweep.
fn best_trial<F>(
    mut trials: Vec<Trial>,
    threshold: f64,
    objective: &F,
    bounded: bool,
) -> Result<(Option<Scored>, usize)>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    if bounded {
        trials.sort_by(|a, b| a.bound.total_cmp(&b.bound).then(a.index.cmp(&b.index)));
    }
    let batch = if bounded { BATCH } else { trials.len().max(1) };
    let mut best: Option<Scored> = None;
    let mut evaluations = 0;
    let mut at = 0;
    while at < trials.len() {
        let limit = best.as_ref().map_or(threshold, |b| b.1.min(threshold));
        let n = trials[at..].iter().take(batch).take_while(|t| may_beat(t.bound, limit)).count();
        if n == 0 {
            break;
        }
        let scored: Vec<Scored> = trials[at..at + n]
            .par_iter()
            .map(|t| {
                let (obj, k) = objective(&t.support)?;
                Ok((t.index, obj, prune(&t.support, &k)))
            })
            .collect::<Result<Vec<_>>>()?;
        at += n;
        evaluations += n;
        for s in scored {
            let better = best.as_ref().is_none_or(|b| s.1 < b.1 || (s.1 == b.1 && s.0 < b.0));
            if s.1.is_finite() && s.1 < threshold && better {
                best = Some(s);
            }
        }
    }
    Ok((best, evaluations))
}

/// Exchange moves from `support` (objective `best`) until none improves or `swap_passes` are
/// spent: per pass, every element out and every other in (and plain additions while below the
/// budget); the best improving trial is taken.
fn exchange<F>(
    p: usize,
    settings: SelectionSettings,
    objective: &F,
    mut support: Vec<usize>,
    mut best: f64,
    mut evaluations: usize,
    bound: Option<Bound<'_>>,
) -> Result<Selection>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let k_max = settings.max_elements.min(p);
    let mut swaps = 0;
    for _ in 0..settings.swap_passes {
        let threshold = best * (1.0 - 1e-9);
        let out: Vec<usize> = (0..p).filter(|j| !support.contains(j)).collect();
        // The bases the trials extend: the support without each element, and the support itself
        // (plain additions) while below the budget.
        let mut bases: Vec<Vec<usize>> =
            support.iter().map(|&i| support.iter().copied().filter(|&x| x != i).collect()).collect();
        if support.len() < k_max {
            bases.push(support.clone());
        }
        let bounds: Vec<Option<Vec<f64>>> = bases.par_iter().map(|r| bound.map(|b| b(r))).collect();
        let mut trials = Vec::new();
        let mut index = 0;
        for (r, b) in bases.iter().zip(&bounds) {
            for &j in &out {
                let lb = b.as_ref().map_or(f64::NEG_INFINITY, |b| b[j]);
                // A trial whose bound is above the threshold cannot improve.
                if may_beat(lb, threshold) {
                    let mut s = r.clone();
                    s.push(j);
                    s.sort_unstable();
                    trials.push(Trial { index, bound: lb, support: s });
                }
                index += 1;
            }
        }
        let (found, evals) = best_trial(trials, threshold, objective, bound.is_some())?;
        evaluations += evals;
        match found {
            Some((_, obj, s)) => {
                best = obj;
                support = s;
                swaps += 1;
            }
            None => break,
        }
    }
    let (objective, k) = objective(&support)?;
    evaluations += 1;
    let support = prune(&support, &k);
    Ok(Selection { support, objective, evaluations, swaps })
}

/// Local search from `start` with 2-for-2 swaps and random restarts (see the module docs): the
/// exchange moves from `start`, refined by 2-for-2 swaps alternating with exchange moves, give a
/// first optimum; `restarts` steps of iterated local search, dealt out to [`CHAINS`] chains that
/// run in parallel, each perturb their chain's best and run the exchange moves and pair swaps
/// from there; the best of all, ties broken by chain index, is returned. `pool` holds the
/// candidates restarts draw from (all candidates when it has fewer than 2K). `bound` gives lower
/// bounds on trial objectives (see [`extension_bounds`]); without it every trial is refitted.
pub fn search<F>(
    p: usize,
    settings: SelectionSettings,
    start: Vec<usize>,
    pool: &[usize],
    objective: F,
    bound: Option<Bound<'_>>,
) -> Result<Selection>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let k_max = settings.max_elements.min(p);
    let all: Vec<usize> = (0..p).collect();
    let pool: &[usize] = if pool.len() >= 2 * k_max { pool } else { &all };
    // The local optimum from the given start, refined by pair swaps.
    let (obj0, _) = objective(&start)?;
    let first = exchange(p, settings, &objective, start, obj0, 1, bound)?;
    let first = pair_refine(p, settings, first, &objective, bound)?;
    // The pair swaps from each local optimum, by its support: restarts often fall back into an
    // optimum found before, and the pair swaps from there (K²/2 greedy refills, most of a
    // restart's refits) would repeat the same refits to the same end. A hit returns that end and
    // counts the refits it took, so the selection and its counts are as without the memo.
    let memo: Mutex<HashMap<(Vec<usize>, u64), Selection>> = Mutex::new(HashMap::new());
    let refine = |local: Selection| -> Result<Selection> {
        // Keyed by the objective's bits too: the pair swaps' threshold is relative to it.
        let key = (local.support.clone(), local.objective.to_bits());
        let known = memo.lock().unwrap_or_else(|e| e.into_inner()).get(&key).cloned();
        let end = match known {
            Some(end) => end,
            None => {
                let from = Selection { evaluations: 0, swaps: 0, ..local.clone() };
                let end = pair_refine(p, settings, from, &objective, bound)?;
                memo.lock().unwrap_or_else(|e| e.into_inner()).insert(key, end.clone());
                end
            }
        };
        Ok(Selection { evaluations: local.evaluations + end.evaluations, swaps: local.swaps + end.swaps, ..end })
    };
    // Chains of iterated local search, in parallel; restart r belongs to chain (r − 1) mod CHAINS.
    let chains: Vec<Selection> = (0..CHAINS.min(settings.restarts))
        .into_par_iter()
        .map(|c| {
            let mut current = Selection { evaluations: 0, swaps: 0, ..first.clone() };
            let (mut evaluations, mut swaps) = (0, 0);
            for r in (c + 1..=settings.restarts).step_by(CHAINS) {
                let mut rng = SplitMix64::stream(settings.seed, RESTART_STREAM + r as u64);
                // Perturbations of every size from one element to half the support, in turn:
                // small ones explore near the optimum, large ones farther away.
                let centre = &current.support;
                let half = centre.len().div_ceil(2).max(1);
                let step = (r - 1) / CHAINS;
                let s = perturbed(centre, pool, k_max, 1 + step % half, &mut rng);
                let (obj, _) = objective(&s)?;
                let local = exchange(p, settings, &objective, s, obj, 1, bound)?;
                // Pair swaps cost K²/2 greedy refills: spent only on optima near the chain's best.
                let local = if local.objective < current.objective * PAIR_WITHIN { refine(local)? } else { local };
                evaluations += local.evaluations;
                swaps += local.swaps;
                if local.objective < current.objective * (1.0 - 1e-9) {
                    current = local;
                }
            }
            Ok(Selection { evaluations, swaps, ..current })
        })
        .collect::<Result<Vec<_>>>()?;
    let evaluations: usize = first.evaluations + chains.iter().map(|r| r.evaluations).sum::<usize>();
    let swaps: usize = first.swaps + chains.iter().map(|r| r.swaps).sum::<usize>();
    // The best, ties broken by chain index (the first search is index 0).
    let best = std::iter::once(first)
        .chain(chains)
        .enumerate()
        .filter(|(_, r)| r.objective.is_finite())
        .min_by(|a, b| a.1.objective.total_cmp(&b.1.objective).then(a.0.cmp(&b.0)));
    let Some((_, best)) = best else {
        return Err(Error::numerical("sparse selection", "no finite objective"));
    };
    Ok(Selection { evaluations, swaps, ..best })
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
/// include those of `from`.
fn pair_refine<F>(
    p: usize,
    settings: SelectionSettings,
    from: Selection,
    objective: &F,
    bound: Option<Bound<'_>>,
) -> Result<Selection>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let mut sel = from;
    if !settings.pair_swaps {
        return Ok(sel);
    }
    for _ in 0..settings.swap_passes {
        let (found, evals) = pair_swap(p, settings, &sel.support, sel.objective, objective, bound)?;
        sel.evaluations += evals;
        let Some((obj, s)) = found else { break };
        let next = exchange(p, settings, objective, s, obj, 0, bound)?;
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
    bound: Option<Bound<'_>>,
) -> Result<(Option<Candidate>, usize)>
where
    F: Fn(&[usize]) -> Result<(f64, Vec<f64>)> + Sync,
{
    let k_max = settings.max_elements.min(p);
    let threshold = best * (1.0 - 1e-9);
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
            for step in 0..2 {
                if s.len() >= k_max {
                    break;
                }
                // Only the last addition has to beat the threshold; the first may be anything.
                let last = step == 1 || s.len() + 1 >= k_max;
                let limit = if last { threshold } else { f64::INFINITY };
                let lb = bound.map(|b| b(&s));
                // Only the trials that may beat the limit are built (a support each).
                let tries: Vec<Trial> = (0..p)
                    .filter(|j| !s.contains(j) && !removed.contains(j))
                    .map(|j| (j, lb.as_ref().map_or(f64::NEG_INFINITY, |b| b[j])))
                    .filter(|&(_, bound)| may_beat(bound, limit))
                    .map(|(j, bound)| {
                        let mut trial = s.clone();
                        trial.push(j);
                        trial.sort_unstable();
                        Trial { index: j, bound, support: trial }
                    })
                    .collect();
                let (found, e) = best_trial(tries, limit, objective, bound.is_some())?;
                evals += e;
                let Some((_, o, next)) = found else {
                    obj = f64::INFINITY;
                    break;
                };
                obj = o;
                s = next;
            }
            Ok((t, obj, s, evals))
        })
        .collect::<Result<Vec<_>>>()?;
    let evals = trials.iter().map(|t| t.3).sum();
    let winner = pick(trials.into_iter().map(|(t, o, s, _)| (t, o, s)).collect());
    Ok((winner.filter(|(_, o, _)| *o < threshold).map(|(_, o, s)| (o, s)), evals))
}

/// Backward elimination over `items` from `start` down to at most `k_max` items on the normal
/// equations: each step refits by NNLS (warm-started from the previous support) and removes the
/// items whose removal raises the objective least by the least-squares deletion estimate
/// k_Gᵀ ((G_S⁻¹)_GG)⁻¹ k_G (kⱼ² / (G_S⁻¹)ⱼⱼ for a single column; items refitted to zero go
/// first). While the support is much larger than the budget, an eighth of the excess goes per
/// step; the last steps remove one at a time. From [`LARGE_COLUMNS`] columns each refit is
/// warm-started from the last solution's positive columns and the estimates come from the passive
/// set's system only (`large_elimination_costs`).
pub fn backward_elimination(gram: &Gram, items: &Items, start: Vec<usize>, k_max: usize) -> Result<Vec<usize>> {
    let settings = NnlsSettings::default();
    let mut support = start;
    // The columns of the last refit's solution that were positive (the large path's warm start).
    let mut positive: Vec<usize> = Vec::new();
    loop {
        let cols = items.columns(&support);
        let sub = gram.subset(&cols);
        let n = cols.len();
        if n >= LARGE_COLUMNS {
            // Thousands of columns (a tendon catalogue's cams): warm-started from the last
            // solution's positive columns, not from every column (a cam's ± columns cannot both be
            // positive, so that start always failed and cost a dense factor of them all), and the
            // deletion estimates from the passive set's own system (see `large_elimination_costs`).
            let start: Vec<usize> = positive.iter().filter_map(|j| cols.binary_search(j).ok()).collect();
            let sol = nnls_warm(&sub, 0.0, &settings, &start)?;
            positive = (0..n).filter(|&a| sol.k[a] > 0.0).map(|a| cols[a]).collect();
            let kept = prune(&support, &items.per_item(&support, &cols, sol.k.as_slice()));
            if kept.len() < support.len() {
                support = kept;
                continue;
            }
            if support.len() <= k_max {
                return Ok(support);
            }
            let cost = large_elimination_costs(&sub, items, &support, &cols, &sol.k);
            remove_cheapest(&mut support, cost, k_max);
            continue;
        }
        let all: Vec<usize> = (0..cols.len()).collect();
        let sol = nnls_warm(&sub, 0.0, &settings, &all)?;
        let kept = prune(&support, &items.per_item(&support, &cols, sol.k.as_slice()));
        if kept.len() < support.len() {
            support = kept;
            continue;
        }
        if support.len() <= k_max {
            return Ok(support);
        }
        let mut g = sub.g.clone();
        let ridge = 1e-12 * g.diagonal().amax().max(1e-300);
        for a in 0..n {
            g[(a, a)] += ridge;
        }
        // Below `LARGE_COLUMNS` (the shipped designs' eliminations and their bits): nalgebra's
        // inverse of the whole support's system, as before.
        let inv = g.try_inverse().unwrap_or_else(|| DMatrix::identity(n, n));
        let cost: Vec<(usize, f64)> = support
            .iter()
            .enumerate()
            .map(|(a, &i)| {
                let at: Vec<usize> = items.members(i).iter().map(|j| cols.binary_search(j).unwrap_or(0)).collect();
                if let [c] = at[..] {
                    return (a, sol.k[c] * sol.k[c] / inv[(c, c)].max(1e-300));
                }
                let k = DVector::from_fn(at.len(), |r, _| sol.k[at[r]]);
                let mut block = DMatrix::from_fn(at.len(), at.len(), |r, s| inv[(at[r], at[s])]);
                let scale = block.diagonal().amax().max(1e-300);
                for r in 0..at.len() {
                    block[(r, r)] += 1e-12 * scale;
                }
                let cost = block.cholesky().map_or(f64::INFINITY, |ch| k.dot(&ch.solve(&k)));
                (a, cost)
            })
            .collect();
        remove_cheapest(&mut support, cost, k_max);
    }
}

/// Removes from `support` the items of least cost ((position, cost) pairs): an eighth of the excess
/// over `k_max` while that is more than eight, else one.
fn remove_cheapest(support: &mut Vec<usize>, mut cost: Vec<(usize, f64)>, k_max: usize) {
    cost.sort_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)));
    let excess = support.len() - k_max;
    let remove = if excess > 8 { excess / 8 } else { 1 };
    let mut victims: Vec<usize> = cost.iter().take(remove).map(|c| c.0).collect();
    victims.sort_unstable_by(|a, b| b.cmp(a));
    for v in victims {
        support.remove(v);
    }
}

/// The backward elimination's deletion estimates on thousands of columns: for each item of
/// `support`, k_Gᵀ ((G_PP⁻¹)_GG)⁻¹ k_G over its columns G in the passive set P (the columns the
/// NNLS solution `k` holds positive), the exact rise of the objective when those columns leave
/// the unconstrained refit on P. Only P's system is inverted (faer's Cholesky), not every column's
/// of the support: a cam's ± columns make that system singular but for the ridge, and it is
/// several times larger than P. An item with no positive column costs nothing to remove.
fn large_elimination_costs(
    sub: &Gram,
    items: &Items,
    support: &[usize],
    cols: &[usize],
    k: &DVector<f64>,
) -> Vec<(usize, f64)> {
    let passive: Vec<usize> = (0..cols.len()).filter(|&a| k[a] > 0.0).collect();
    let m = passive.len();
    let mut g = DMatrix::from_fn(m, m, |r, s| sub.g[(passive[r], passive[s])]);
    let ridge = 1e-12 * g.diagonal().amax().max(1e-300);
    for a in 0..m {
        g[(a, a)] += ridge;
    }
    let inv =
        super::dense::spd_inverse(g.clone()).or_else(|| g.try_inverse()).unwrap_or_else(|| DMatrix::identity(m, m));
    support
        .iter()
        .enumerate()
        .map(|(a, &i)| {
            let at: Vec<usize> = items
                .members(i)
                .iter()
                .filter_map(|j| cols.binary_search(j).ok())
                .filter_map(|c| passive.binary_search(&c).ok())
                .collect();
            if at.is_empty() {
                return (a, 0.0);
            }
            let kg = DVector::from_fn(at.len(), |r, _| k[passive[at[r]]]);
            let mut block = DMatrix::from_fn(at.len(), at.len(), |r, s| inv[(at[r], at[s])]);
            let scale = block.diagonal().amax().max(1e-300);
            for r in 0..at.len() {
                block[(r, r)] += 1e-12 * scale;
            }
            (a, block.cholesky().map_or(f64::INFINITY, |ch| kg.dot(&ch.solve(&kg))))
        })
        .collect()
}

/// The objective of the NNLS refit of `gram` on the columns of the items in `support`, and per
/// item its largest stiffness (the usual objective for [`select`] and [`select_from`]).
pub fn subset_nnls(gram: &Gram, items: &Items, support: &[usize]) -> Result<(f64, Vec<f64>)> {
    let cols = items.columns(support);
    let sol = nnls(&gram.subset(&cols), 0.0, &NnlsSettings::default())?;
    Ok((sol.objective, items.per_item(support, &cols, sol.k.as_slice())))
}

/// [`subset_nnls`] warm-started with the whole support passive: the exchange and pair trials
/// differ from a solved support by one or two elements, so one passive-set solve usually settles
/// them (same answer as the cold start up to round-off, several times faster).
pub fn subset_nnls_warm(gram: &Gram, items: &Items, support: &[usize]) -> Result<(f64, Vec<f64>)> {
    let cols = items.columns(support);
    let all: Vec<usize> = (0..cols.len()).collect();
    let sol = nnls_warm(&gram.subset(&cols), 0.0, &NnlsSettings::default(), &all)?;
    Ok((sol.objective, items.per_item(support, &cols, sol.k.as_slice())))
}

/// A budget on the refits of the selection: Σ aⱼkⱼ + bⱼkⱼ² ≤ `max` over the columns (the springs'
/// mass by `fit::mass`'s curves, a and b per column of the Gram matrix).
#[derive(Debug, Clone, Copy)]
pub struct SubsetBudget<'a> {
    /// aⱼ per column.
    pub linear: &'a [f64],
    /// bⱼ per column (empty: none).
    pub squared: &'a [f64],
    /// The budget.
    pub max: f64,
}

impl SubsetBudget<'_> {
    /// `sub` (the Gram matrix restricted to the columns `cols`) with the budget's term at
    /// multiplier μ: c − μa, and 2μbⱼ on G's diagonal.
    pub fn weigh(&self, sub: &Gram, cols: &[usize], mu: f64) -> Gram {
        let mut shifted = sub.clone();
        for (a, &j) in cols.iter().enumerate() {
            shifted.c[a] -= mu * self.linear[j];
            shifted.g[(a, a)] += 2.0 * mu * self.squared.get(j).copied().unwrap_or(0.0);
        }
        shifted
    }

    /// Σ aⱼkⱼ + bⱼkⱼ² over `cols`, `k` given per column of `cols`.
    fn of(&self, cols: &[usize], k: &DVector<f64>) -> f64 {
        cols.iter()
            .zip(k.iter())
            .map(|(&j, k)| self.linear[j] * k + self.squared.get(j).map_or(0.0, |b| b * k * k))
            .sum()
    }
}

/// Steps that bracket and then narrow the multiplier of a subset's budget.
const BUDGET_ROOT_STEPS: usize = 60;

/// [`subset_nnls_warm`] with the refit held within `budget`: the least objective over the
/// support's columns with k ≥ 0 and Σ aⱼkⱼ + bⱼkⱼ² ≤ M, which is what the selection should
/// compare when the budget binds. Comparing supports by the penalised objective ‖Ak − b‖² +
/// 2μ·mass at one multiplier μ (the weight that brought the chosen support within the budget)
/// trades residual for mass at one fixed rate on every support, so a support that is accurate
/// near the budget but heavier unconstrained loses to one that is lighter and less accurate;
/// here each support gets its own multiplier, the one that puts its refit at the budget (the
/// budget's KKT conditions on that support), and supports are compared by objective at equal
/// mass. The mass is convex in k and non-increasing in μ along the refits, so the multiplier is
/// bracketed by growth and found by regula falsi (Illinois), its upper end kept: the refit
/// returned is always within the budget. A support whose refit cannot come within it has an
/// infinite objective. The objective returned is that of `gram` itself (the budget's term is
/// not in it).
pub fn subset_nnls_within(
    gram: &Gram,
    items: &Items,
    support: &[usize],
    budget: &SubsetBudget<'_>,
) -> Result<(f64, Vec<f64>)> {
    refit_within(gram, items, support, budget).map(|(objective, k, _)| (objective, k))
}

/// The multiplier μ ≥ 0 of the budget on the refit of `support` ([`subset_nnls_within`]): 0 where
/// the budget does not bind, ∞ where no multiplier brings the refit within it.
pub fn budget_multiplier(gram: &Gram, items: &Items, support: &[usize], budget: &SubsetBudget<'_>) -> Result<f64> {
    refit_within(gram, items, support, budget).map(|(_, _, mu)| mu)
}

/// [`subset_nnls_within`] with the multiplier it found.
fn refit_within(
    gram: &Gram,
    items: &Items,
    support: &[usize],
    budget: &SubsetBudget<'_>,
) -> Result<(f64, Vec<f64>, f64)> {
    let cols = items.columns(support);
    let sub = gram.subset(&cols);
    let all: Vec<usize> = (0..cols.len()).collect();
    let settings = NnlsSettings::default();
    let at = |mu: f64| -> Result<DVector<f64>> {
        if mu == 0.0 {
            return Ok(nnls_warm(&sub, 0.0, &settings, &all)?.k);
        }
        Ok(nnls_warm(&budget.weigh(&sub, &cols, mu), 0.0, &settings, &all)?.k)
    };
    let done = |k: DVector<f64>, mu: f64| (sub.objective(&k), items.per_item(support, &cols, k.as_slice()), mu);
    let k0 = at(0.0)?;
    let over = |k: &DVector<f64>| budget.of(&cols, k) - budget.max;
    let (mut f_lo, mut lo) = (over(&k0), 0.0);
    if f_lo <= 1e-9 * budget.max {
        return Ok(done(k0, 0.0));
    }
    // Bracket: a multiplier of the order of the objective of no springs per unit of budget, grown
    // 4× until the refit is within the budget.
    let mut hi = 0.5 * sub.bb.max(f64::MIN_POSITIVE) / budget.max;
    let mut k_hi = None;
    for _ in 0..BUDGET_ROOT_STEPS {
        let k = at(hi)?;
        let f = over(&k);
        if f <= 0.0 {
            k_hi = Some((f, k));
            break;
        }
        (lo, f_lo, hi) = (hi, f, 4.0 * hi);
    }
    let Some((mut f_hi, mut k_hi)) = k_hi else {
        return Ok((f64::INFINITY, vec![0.0; support.len()], f64::INFINITY));
    };
    // Regula falsi with the Illinois halving (of the interpolation's end values only), to 1e-6
    // of the budget or 1e-9 of the multiplier.
    let mut slack = -f_hi;
    let mut side = 0i8;
    for _ in 0..BUDGET_ROOT_STEPS {
        if slack <= 1e-6 * budget.max || hi - lo <= 1e-9 * hi {
            break;
        }
        let mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
        let mid = if mid > lo && mid < hi { mid } else { 0.5 * (lo + hi) };
        let k = at(mid)?;
        let f = over(&k);
        if f <= 0.0 {
            (hi, f_hi, k_hi, slack) = (mid, f, k, -f);
            if side == -1 {
                f_lo *= 0.5;
            }
            side = -1;
        } else {
            (lo, f_lo) = (mid, f);
            if side == 1 {
                f_hi *= 0.5;
            }
            side = 1;
        }
    }
    Ok(done(k_hi, hi))
}

/// A [`Bound`] for the least-squares problem `gram`: for every item g outside `support`, a lower
/// bound on the NNLS objective of the support with g added, the unconstrained minimum over the
/// same columns, bᵀb − ‖y‖² − w_Gᵀ S_G⁻¹ w_G with L Lᵀ = G_RR (R the support's columns),
/// y = L⁻¹ c_R, V = L⁻¹ G_RG, w_G = c_G − Vᵀ y and S_G = G_GG − Vᵀ V (the Schur complement). One
/// factorisation and one triangular solve against all columns serve every item. A small margin
/// (relative to bᵀb, whose cancellation limits the accuracy of every objective) keeps round-off
/// from pruning a trial that ties. `+∞` for items in the support and for empty columns.
pub fn extension_bounds(gram: &Gram, items: &Items, support: &[usize]) -> Vec<f64> {
    let p = gram.dim();
    let cols = items.columns(support);
    let n = cols.len();
    // G_RR with the NNLS solver's ridge (1e-12 of each diagonal entry).
    let mut grr = DMatrix::from_fn(n, n, |a, b| gram.g[(cols[a], cols[b])]);
    for a in 0..n {
        grr[(a, a)] *= 1.0 + 1e-12;
    }
    // Thousands of support columns (a tendon catalogue's cams): faer's blocked factor and
    // triangular solve, nalgebra's unblocked ones taking tens of seconds a bound there.
    let large = n >= LARGE_COLUMNS;
    let factor = if large { super::dense::cholesky_lower(grr) } else { grr.cholesky().map(|c| c.l()) };
    let Some(l) = factor else {
        // Degenerate support: no bound (every trial is refitted).
        return (0..items.len())
            .map(|i| if support.contains(&i) { f64::INFINITY } else { f64::NEG_INFINITY })
            .collect();
    };
    let cr = DVector::from_fn(n, |a, _| gram.c[cols[a]]);
    let y = l.solve_lower_triangular(&cr).unwrap_or_else(|| DVector::zeros(n));
    let grp = DMatrix::from_fn(n, p, |a, j| gram.g[(cols[a], j)]);
    let v = if large {
        let mut v = grp;
        super::dense::solve_lower_in_place(&l, &mut v);
        v
    } else {
        l.solve_lower_triangular(&grp).unwrap_or_else(|| DMatrix::zeros(n, p))
    };
    let base = gram.bb - y.norm_squared();
    let margin = 1e-12 * gram.bb.abs() + 1e-9 * base.abs();
    // Per column: wⱼ = cⱼ − vⱼ·y.
    let w = DVector::from_fn(p, |j, _| gram.c[j] - v.column(j).dot(&y));
    (0..items.len())
        .map(|i| {
            if support.contains(&i) {
                return f64::INFINITY;
            }
            let m = items.members(i);
            if m.iter().all(|&j| gram.g[(j, j)] <= 0.0) {
                return f64::INFINITY;
            }
            let gain = if let [j] = m[..] {
                let s = gram.g[(j, j)] - v.column(j).norm_squared();
                if s <= 1e-12 * gram.g[(j, j)] { 0.0 } else { w[j] * w[j] / s }
            } else {
                let q = m.len();
                let mut s = DMatrix::from_fn(q, q, |a, b| gram.g[(m[a], m[b])] - v.column(m[a]).dot(&v.column(m[b])));
                let scale = (0..q).map(|a| gram.g[(m[a], m[a])]).fold(0.0, f64::max);
                for a in 0..q {
                    s[(a, a)] += 1e-12 * scale;
                }
                let wg = DVector::from_fn(q, |a, _| w[m[a]]);
                // A Schur complement that is not positive definite (round-off in a dependent
                // block): no bound for this item.
                s.cholesky().map_or(f64::INFINITY, |ch| wg.dot(&ch.solve(&wg)))
            };
            base - gain - margin
        })
        .collect()
}

/// A [`Bound`] for the refits within `budget` ([`subset_nnls_within`]): for every item g outside
/// `support`, a lower bound on the objective of the support with g added, refitted within the
/// budget. By weak duality, for any multiplier μ ≥ 0 the least objective with k ≥ 0 and
/// mass(k) ≤ M is at least min over k of ‖Ak − b‖² + 2μ(mass(k) − M), and dropping k ≥ 0 lowers
/// it further: the unconstrained bound of [`extension_bounds`] on `gram` weighed at μ
/// ([`SubsetBudget::weigh`], whose objective is ‖Ak − b‖² + 2μ·mass(k)), less 2μM. μ is the
/// multiplier of `support` itself ([`budget_multiplier`]), which a trial that adds one element
/// needs about as much of. At μ = 0 this is [`extension_bounds`]' bound, which the budget's
/// refits are far above when it binds, so that nearly every trial was refitted (each refit a
/// root search of its own multiplier); the outcome of the search is the same, bounds only skip
/// trials that cannot win. A support whose refit cannot come within the budget (μ = ∞) gets
/// the unconstrained bound; every bound is the larger of the two.
pub fn budget_bounds(gram: &Gram, items: &Items, support: &[usize], budget: &SubsetBudget<'_>) -> Vec<f64> {
    let mu = budget_multiplier(gram, items, support, budget).unwrap_or(0.0);
    if !(mu.is_finite() && mu > 0.0) {
        return extension_bounds(gram, items, support);
    }
    let every: Vec<usize> = (0..gram.dim()).collect();
    let weighed = budget.weigh(gram, &every, mu);
    let charge = 2.0 * mu * budget.max;
    // Both bounds hold; the dual one is below the plain one where μ is far above what a trial
    // needs (the dual function is concave in μ and the plain bound is its value at 0).
    let plain = extension_bounds(gram, items, support);
    extension_bounds(&weighed, items, support).into_iter().zip(plain).map(|(b, p)| (b - charge).max(p)).collect()
}

/// Whether a trial with lower bound `bound` may reach `limit` (a NaN bound bounds nothing).
fn may_beat(bound: f64, limit: f64) -> bool {
    bound <= limit || bound.is_nan()
}

/// The trial with the smallest objective, ties broken by trial index.
fn pick(trials: Vec<Scored>) -> Option<Scored> {
    trials.into_iter().filter(|t| t.1.is_finite()).min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
}

/// The support without elements refitted to exactly zero (or below: a group's largest
/// coefficient).
fn prune(support: &[usize], k: &[f64]) -> Vec<usize> {
    support.iter().zip(k).filter(|(_, k)| **k > 0.0).map(|(s, _)| *s).collect()
}

#[cfg(test)]
mod tests;
