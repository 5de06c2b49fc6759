//! Least squares in normal-equation form: the currency of the fit backends.
//!
//! ½‖A k − b‖² = ½ kᵀ G k − cᵀ k + ½ bᵀb with G = AᵀA and c = Aᵀb. Every solver and every one of
//! the thousands of subset refits of the sparse selection works on (G, c) — whose size is the
//! number of candidates, not the number of samples — so the rows are touched once.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Rows of one block of the blockwise normal equations ([`Gram::from_row_blocks`]), and the
/// most rows [`Gram::from_rows`] takes in one nalgebra product: 16 384, above the 11 520 rows of
/// the three-joint designs (144 directions × 40 samples × 2), so their fits keep their bits.
pub const GRAM_BLOCK: usize = 16_384;

/// Whether the normal equations of a fit of `dof` joints with `rows` tangentiality rows come from
/// the rows' factors ([`Gram::from_coupled_rows`]) rather than from the rows themselves: above
/// [`GRAM_BLOCK`] rows of two or more per sample, unless the columns are `grouped` (cams, whose
/// rows are mostly zero and go through [`Gram::from_sparse_rows`]). The fit then keeps no dense
/// rows unless something else reads them; the memory check asks the same question.
pub fn from_factors(dof: usize, rows: usize, grouped: bool) -> bool {
    !grouped && rows > GRAM_BLOCK && dof >= 3
}

/// Blocks computed in parallel at a time: fixed, so that memory does not grow with the thread
/// count or the rows.
pub const GRAM_WAVE: usize = 4;

/// Columns of G per parallel task of [`Gram::from_sparse_rows`]: small enough that the
/// triangle's uneven columns balance over the threads, large enough that each task's pass over
/// the rows' entries is worth it.
const SPARSE_COLUMNS: usize = 32;

/// For each column of `a`, the column it is the exact negation of in every row, if any: an
/// earlier column beside it in every run it is in, with every value negated, and in no other
/// run, itself no one's mirror. (A cam's − basis column follows its + column: the fit's
/// candidates list them in that order.) Checked value by value, so a column that merely
/// looks alike is not taken.
fn mirrors(a: &SparseRows) -> Vec<Option<usize>> {
    #[derive(Clone, Copy, PartialEq)]
    enum State {
        Unseen,
        Of(usize),
        No,
    }
    let mut state = vec![State::Unseen; a.columns];
    let mut runs_in = vec![0usize; a.columns];
    for run in &a.runs {
        let rows = run.rows;
        for (x, &j) in run.columns.iter().enumerate() {
            runs_in[j] += 1;
            let negates = x > 0 && {
                let (vi, vj) = (&run.values[(x - 1) * rows..x * rows], &run.values[x * rows..(x + 1) * rows]);
                vi.iter().zip(vj).all(|(u, v)| *v == -*u)
            };
            let here = if negates { State::Of(run.columns[x - 1]) } else { State::No };
            state[j] = match state[j] {
                State::Unseen => here,
                s if s == here => s,
                _ => State::No,
            };
        }
    }
    let mut mirror = vec![None; a.columns];
    for j in 0..a.columns {
        if let State::Of(i) = state[j]
            && runs_in[i] == runs_in[j]
            && mirror[i].is_none()
        {
            mirror[j] = Some(i);
        }
    }
    mirror
}

/// Consecutive rows with the same non-zero columns (a sample's n − 1 rows: one slope per
/// element, n − 1 directions), their values stored entry by entry so that a pair of columns reads
/// the run's products from two contiguous slices and G's entry is loaded and stored once per run
/// rather than once per row.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// The first row.
    pub first: usize,
    /// The number of rows.
    pub rows: usize,
    /// The columns, ascending.
    pub columns: Vec<usize>,
    /// The values, entry by entry: entry x of the run's row r at `x * rows + r`.
    pub values: Vec<f64>,
}

impl Run {
    /// The runs of consecutive rows with the same columns among rows given by their non-zeros:
    /// row i's (column, value) pairs, in column order, are `flat[start[i] .. start[i + 1]]`, and
    /// row i is row `first + i` of the matrix.
    pub fn of_rows(first: usize, start: &[usize], flat: &[(usize, f64)]) -> Vec<Run> {
        let m = start.len() - 1;
        let mut runs: Vec<Run> = Vec::new();
        let mut i = 0;
        while i < m {
            let columns: Vec<usize> = flat[start[i]..start[i + 1]].iter().map(|&(j, _)| j).collect();
            let same = |r: usize| {
                start[r + 1] - start[r] == columns.len()
                    && flat[start[r]..start[r + 1]].iter().zip(&columns).all(|(&(j, _), &c)| j == c)
            };
            let mut end = i + 1;
            while end < m && same(end) {
                end += 1;
            }
            let rows = end - i;
            let mut values = vec![0.0; columns.len() * rows];
            for r in 0..rows {
                for (x, &(_, v)) in flat[start[i + r]..start[i + r + 1]].iter().enumerate() {
                    values[x * rows + r] = v;
                }
            }
            runs.push(Run { first: first + i, rows, columns, values });
            i = end;
        }
        runs
    }
}

/// How the fit keeps its tangentiality rows (`fit::problem::assemble_factored` writes them so).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RowsOut {
    /// The dense m × p matrix.
    Dense,
    /// No rows: each column is formed in a buffer of its own, only for its product with the
    /// right-hand side (for [`Gram::from_coupled_rows`]).
    ProductOnly,
    /// Their non-zeros by runs ([`SparseRows`]), for columns that are mostly zero (a cam's
    /// B-spline basis). The entries are those of the dense rows, bit for bit.
    Sparse,
}

impl RowsOut {
    /// What a fit of `dof` joints and `rows` rows keeps: dense rows where a tolerance-aware pass
    /// will read them (`tolerance`) or a small fit forms G from them; for cams (`grouped`) their
    /// non-zeros; where G comes from the rows' factors ([`from_factors`]) none, unless trims are
    /// folded into the right-hand side after the assembly (`trims`), which the product with it
    /// taken during the assembly would miss. The fit and the memory check before it both ask this.
    pub fn for_fit(dof: usize, rows: usize, grouped: bool, trims: bool, tolerance: bool) -> RowsOut {
        if tolerance {
            RowsOut::Dense
        } else if grouped {
            RowsOut::Sparse
        } else if from_factors(dof, rows, grouped) && !trims {
            RowsOut::ProductOnly
        } else {
            RowsOut::Dense
        }
    }
}

/// Rows that are mostly zero (a cam's B-spline columns), as their non-zeros by runs of rows in
/// row order: what [`Gram::from_sparse_rows`] gathers from a dense matrix, or what the fit's
/// assembly writes directly without the dense matrix (`fit::problem::assemble_factored`). Rows
/// no run names are zero.
#[derive(Debug, Clone, PartialEq)]
pub struct SparseRows {
    /// Number of rows m.
    pub rows: usize,
    /// Number of columns p.
    pub columns: usize,
    /// The runs, in row order.
    pub runs: Vec<Run>,
}

impl SparseRows {
    /// The number of non-zero entries.
    pub fn nnz(&self) -> usize {
        self.runs.iter().map(|r| r.rows * r.columns.len()).sum()
    }

    /// The dense m × p matrix.
    pub fn to_dense(&self) -> DMatrix<f64> {
        let mut a = DMatrix::zeros(self.rows, self.columns);
        for run in &self.runs {
            for (x, &j) in run.columns.iter().enumerate() {
                for r in 0..run.rows {
                    a[(run.first + r, j)] = run.values[x * run.rows + r];
                }
            }
        }
        a
    }
}

/// Samples per parallel chunk of [`Gram::from_coupled_rows`]: fixed, so that the chunks, and the
/// order their sums are added in, do not depend on the thread count.
const COUPLED_CHUNK: usize = 4096;

/// Rows that factor by coupling, as the fit's tangentiality rows do. Sample s owns the rows
/// s·r … s·r + r − 1, and column j's entry in row s·r + c is φ[s, j] · F[s·r + c, class_j]: a
/// scalar of the column at the sample (the element's slope u′ there) times a factor of the row
/// shared by every column of the class (the coupling's a·M⁻¹p_c, row-weighted). Then
/// G[j, k] = Σ_s φ[s, j] φ[s, k] Σ_c F[s·r + c, class_j] F[s·r + c, class_k]: one product per
/// sample where the rows need r.
pub struct CoupledRows<'a> {
    /// φ[s0 .., j] into `out` for (j, s0, out): computed where needed, as the rows were (at seven
    /// joints φ would take a gigabyte, and fresh memory is slow to touch on a virtual machine).
    pub slopes: &'a (dyn Fn(usize, usize, &mut [f64]) + Sync),
    /// F: per class, its factor at every row (samples × r).
    pub factors: &'a [Vec<f64>],
    /// The class of every column.
    pub class_of: &'a [usize],
    /// r, the rows per sample.
    pub per_sample: usize,
}

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
    /// Up to [`GRAM_BLOCK`] rows (every shipped design of up to three joints) with nalgebra's
    /// single-threaded matrix product, bit-identical whatever the thread count. faer's triangular
    /// product ([`super::dense::gram_of`]) is 2.3× faster on the default design's 2880 × 402 rows
    /// (23 → 10 ms, `cargo bench --bench kernels`) but its other summation order changes G in the
    /// last bits, and the fits are that sensitive: of the 11 shipped designs without cams, 7
    /// chose other springs, the others' rates moved by 3e-10 to 3e-6 (BENCHMARKS.md, "Dense
    /// kernels").
    ///
    /// More rows go blockwise ([`Gram::from_row_blocks`]): the fits of four or more joints have
    /// 10⁵ rows and more, where the transposed copy nalgebra's product needs doubles the memory
    /// and one thread takes minutes. The fit itself takes such rows, when they come two or more
    /// per sample, from their factors instead ([`Gram::from_coupled_rows`]).
    pub fn from_rows(a: &DMatrix<f64>, b: &DVector<f64>) -> Gram {
        if a.nrows() > GRAM_BLOCK {
            return Gram::from_row_blocks(a, b);
        }
        let at = a.transpose();
        Gram { g: &at * a, c: &at * b, bb: b.dot(b) }
    }

    /// The normal equations of `a` (the rows `coupled` describes) and `b`, G from the factors:
    /// r times fewer multiplications than AᵀA from the rows (r = n − 1 rows per sample in the
    /// fit: at seven joints 6×). Chunks of `COUPLED_CHUNK` samples, [`GRAM_WAVE`] at a time
    /// in parallel, added in chunk order: the bits do not depend on the thread count. They are
    /// not those of [`Gram::from_rows`] (another summation order), which is why the fit uses
    /// this only above [`GRAM_BLOCK`] rows, where the blockwise product had already changed
    /// them. Aᵀb is given (`c`): the rows need not be kept for it (see
    /// `fit::problem::assemble_factored`). On the seven-link chain's default sampling (552 960
    /// rows, 1510 columns, 111 couplings) 6.2 s against the blockwise product's 14.0 s on two
    /// threads (BENCHMARKS.md, "Fit time against the number of joints").
    pub fn from_coupled_rows(coupled: &CoupledRows, c: DVector<f64>, b: &DVector<f64>) -> Gram {
        let p = coupled.class_of.len();
        if coupled.per_sample == 0 {
            // No rows (one joint: no direction across γ̇).
            return Gram { g: DMatrix::zeros(p, p), c, bb: b.dot(b) };
        }
        let classes = coupled.factors.len();
        let mut order: Vec<usize> = (0..p).collect();
        order.sort_by_key(|&j| coupled.class_of[j]);
        let mut starts = vec![0usize; classes + 1];
        for &c in coupled.class_of {
            starts[c + 1] += 1;
        }
        for c in 0..classes {
            starts[c + 1] += starts[c];
        }
        let samples = coupled.factors.first().map_or(0, |f| f.len() / coupled.per_sample);
        let chunks: Vec<usize> = (0..samples).step_by(COUPLED_CHUNK).collect();
        let mut upper = DMatrix::zeros(p, p);
        for wave in chunks.chunks(GRAM_WAVE) {
            let parts: Vec<DMatrix<f64>> = wave
                .par_iter()
                .map(|&s0| {
                    super::dense::coupled_gram_chunk(coupled, &order, &starts, s0, COUPLED_CHUNK.min(samples - s0))
                })
                .collect();
            for part in parts {
                upper += part;
            }
        }
        // The upper triangle in class order, mirrored, back to the columns' own order.
        let mut g = DMatrix::zeros(p, p);
        for y in 0..p {
            for x in 0..=y {
                let value = upper[(x, y)];
                g[(order[x], order[y])] = value;
                g[(order[y], order[x])] = value;
            }
        }
        Gram { g, c, bb: b.dot(b) }
    }

    /// The normal equations summed over blocks of [`GRAM_BLOCK`] rows: each block's AᵀA by
    /// faer's triangular product and its Aᵀb (views into `a`, no copies), [`GRAM_WAVE`] blocks
    /// at a time in parallel, and the blocks' sums added in block order. Every block is computed
    /// sequentially and the order of the additions is fixed, so the bits do not depend on the
    /// thread count; memory beyond `a` is [`GRAM_WAVE`] + 1 p × p matrices.
    pub fn from_row_blocks(a: &DMatrix<f64>, b: &DVector<f64>) -> Gram {
        let (m, p) = a.shape();
        let starts: Vec<usize> = (0..m).step_by(GRAM_BLOCK).collect();
        let mut g = DMatrix::zeros(p, p);
        let mut c = DVector::zeros(p);
        for wave in starts.chunks(GRAM_WAVE) {
            let parts: Vec<(DMatrix<f64>, DVector<f64>)> = wave
                .par_iter()
                .map(|&r0| {
                    let rows = GRAM_BLOCK.min(m - r0);
                    super::dense::gram_of_rows(a, r0, rows, b)
                })
                .collect();
            for (gb, cb) in parts {
                g += gb;
                c += cb;
            }
        }
        Gram { g, c, bb: b.dot(b) }
    }

    /// [`Gram::from_rows`] for rows that are mostly zero (a cam's B-spline columns: 4 of its
    /// N + 2 basis functions are non-zero at any x), by accumulating the outer product of each
    /// row's non-zero entries: O(m·nnz²) instead of O(m·p²) — for eight cams on 15 000 rows
    /// about 100× less work than the dense product. Falls back to the dense product when more
    /// than a quarter of the entries are non-zero. Deterministic (fixed summation order).
    ///
    /// The non-zeros are gathered row by row first and the sums run down contiguous columns of
    /// the lower triangle: on the window cams' 8871 × 512 rows 130 ms against 314 ms reading
    /// rows in place, and against faer's dense triangular product's 225 ms (which would also
    /// change all four cam designs' fits, by 2e-6 to 0.2 in the bill, the 16-cam window's cam
    /// profiles by up to their own size). Every entry adds the same terms in the same order as
    /// the row-by-row product, so the bits are those of the earlier code.
    pub fn from_sparse_rows(a: &DMatrix<f64>, b: &DVector<f64>) -> Gram {
        let (m, p) = a.shape();
        // The rows' non-zeros gathered column by column (the matrix is column-major: reading a row
        // in place strides through every column), each row's in column order as before. The
        // counts per row, summed, are the offsets of the rows and the number of non-zeros.
        let mut start = vec![0usize; m + 1];
        for col in a.column_iter() {
            for (i, &v) in col.iter().enumerate() {
                if v != 0.0 {
                    start[i + 1] += 1;
                }
            }
        }
        for i in 0..m {
            start[i + 1] += start[i];
        }
        let nnz = start[m];
        if nnz * 4 > m * p {
            return Gram::from_rows(a, b);
        }
        let mut next = start.clone();
        let mut flat = vec![(0usize, 0.0f64); nnz];
        for (j, col) in a.column_iter().enumerate() {
            for (i, &v) in col.iter().enumerate() {
                if v != 0.0 {
                    flat[next[i]] = (j, v);
                    next[i] += 1;
                }
            }
        }
        let runs = Run::of_rows(0, &start, &flat);
        drop(flat);
        Gram::from_runs(&SparseRows { rows: m, columns: p, runs }, b)
    }

    /// [`Gram::from_sparse_rows`] of rows given by their non-zeros, and by the dense product
    /// where more than a quarter of the entries are non-zero, as there: the same bits as
    /// [`Gram::from_sparse_rows`] of [`SparseRows::to_dense`].
    pub fn from_sparse(a: &SparseRows, b: &DVector<f64>) -> Gram {
        if a.nnz() * 4 > a.rows * a.columns {
            return Gram::from_rows(&a.to_dense(), b);
        }
        Gram::from_runs(a, b)
    }

    /// The normal equations of the runs. Each run's rows are added to G and c one by one in row
    /// order, so every sum is the row-by-row one, term for term, however the rows are cut into
    /// runs.
    ///
    /// A column that is another's exact negation in every row (a cam's negative basis column
    /// beside its positive one, [`mirrors`]) is not multiplied out: its entries of G and c are the other's negated,
    /// which are the bits its own products would sum to (negation is exact and the terms come in
    /// the same order). For a bill of cams, half the columns: a quarter of the products (the
    /// 148 tendon couplings of `catalogs/ur5_tendons.toml`, 9,472 columns, spent nearly all of
    /// their assembly here).
    fn from_runs(a: &SparseRows, b: &DVector<f64>) -> Gram {
        let (p, runs) = (a.columns, &a.runs);
        let mirror = mirrors(a);
        let is_mirror = |j: usize| mirror[j].is_some();
        // Columns of the lower triangle in blocks of SPARSE_COLUMNS, in parallel: a block reads
        // every run's entries from its first column on and owns its columns of G and c, so each
        // entry sums its terms in row order whatever the thread count.
        let mut g = DMatrix::zeros(p, p);
        let mut c = DVector::zeros(p);
        let bs = b.as_slice();
        g.as_mut_slice()
            .par_chunks_mut(p * SPARSE_COLUMNS)
            .zip(c.as_mut_slice().par_chunks_mut(SPARSE_COLUMNS))
            .enumerate()
            .for_each(|(block, (g_cols, c_cols))| {
                let j0 = block * SPARSE_COLUMNS;
                let j1 = j0 + c_cols.len();
                for run in runs {
                    let rows = run.rows;
                    let b_run = &bs[run.first..run.first + rows];
                    let from = run.columns.partition_point(|&j| j < j0);
                    for x in from..run.columns.len() {
                        let j = run.columns[x];
                        if j >= j1 {
                            break;
                        }
                        if is_mirror(j) {
                            continue;
                        }
                        let vj = &run.values[x * rows..(x + 1) * rows];
                        for (v, bi) in vj.iter().zip(b_run) {
                            c_cols[j - j0] += v * bi;
                        }
                        // Down column j (contiguous in memory); the sums are those of the upper
                        // triangle, term for term.
                        let column = &mut g_cols[(j - j0) * p..(j - j0 + 1) * p];
                        for (y, &k) in run.columns.iter().enumerate().skip(x) {
                            if is_mirror(k) {
                                continue;
                            }
                            let vk = &run.values[y * rows..(y + 1) * rows];
                            let mut sum = column[k];
                            for (a, b) in vj.iter().zip(vk) {
                                sum += a * b;
                            }
                            column[k] = sum;
                        }
                    }
                }
            });
        // A mirror's entries from its original's (both of a pair's originals are unmirrored, and
        // their entry of the lower triangle is filled above). −0 is written as +0: the products'
        // sum starts at +0 and never ends at −0.
        // Only the entries with a mirror on either side are visited: none on a bill without cams.
        let negated = |v: f64, flip: bool| if flip && v != 0.0 { -v } else { v };
        let base = |j: usize| mirror[j].map_or((j, false), |i| (i, true));
        let mirrored: Vec<usize> = (0..p).filter(|&j| is_mirror(j)).collect();
        for j in 0..p {
            let (bj, fj) = base(j);
            if fj {
                c[j] = negated(c[bj], true);
            }
            let mut fill = |k: usize| {
                let (bk, fk) = base(k);
                g[(k, j)] = negated(g[(bk.max(bj), bk.min(bj))], fj != fk);
            };
            if fj {
                (j..p).for_each(&mut fill);
            } else {
                mirrored.iter().filter(|&&k| k >= j).for_each(|&k| fill(k));
            }
        }
        for k in 0..p {
            for j in 0..k {
                g[(j, k)] = g[(k, j)];
            }
        }
        Gram { g, c, bb: b.dot(b) }
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

    /// Adds ‖E k − f‖² for rows E that are mostly zero (a cam's smoothing rows touch four of its
    /// coefficients each), by [`Gram::from_sparse_rows`]: the dense product of
    /// [`Gram::add_weighted`] multiplies every column by every other, 15 GFLOP for 40 cams'
    /// 1160 rows against their 2560 columns, repeated for every weight the automatic smoothing
    /// tries.
    pub fn add_sparse_rows(&mut self, e: &DMatrix<f64>, f: &DVector<f64>) {
        let extra = Gram::from_sparse_rows(e, f);
        self.g += extra.g;
        self.c += extra.c;
        self.bb += extra.bb;
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

    /// G from the factors is AᵀA of the rows they describe (to rounding, and exactly
    /// symmetric), over chunks and steps of every size: 9000 samples (three chunks, the last
    /// short), three rows each, five classes of which one has no column.
    #[test]
    fn coupled_rows_give_the_normal_equations_of_their_rows() {
        let mut rng = crate::numerics::rng::SplitMix64::new(11);
        let (samples, per, classes, p) = (9000, 3, 5, 17);
        let class_of: Vec<usize> = (0..p).map(|j| [0, 1, 3, 4][(j * 7) % 4]).collect();
        let phi = DMatrix::from_fn(samples, p, |_, _| rng.uniform() - 0.5);
        let factors: Vec<Vec<f64>> =
            (0..classes).map(|_| (0..samples * per).map(|_| rng.uniform() - 0.5).collect()).collect();
        let a = DMatrix::from_fn(samples * per, p, |r, j| phi[(r / per, j)] * factors[class_of[j]][r]);
        let b = DVector::from_fn(samples * per, |_, _| rng.uniform());
        let slopes =
            |j: usize, s0: usize, out: &mut [f64]| out.copy_from_slice(&phi.column(j).as_slice()[s0..s0 + out.len()]);
        let coupled = CoupledRows { slopes: &slopes, factors: &factors, class_of: &class_of, per_sample: per };
        let got = Gram::from_coupled_rows(&coupled, a.tr_mul(&b), &b);
        let want = Gram::from_rows(&a, &b);
        assert!((&got.g - &want.g).amax() < 1e-12 * want.g.amax(), "{}", (&got.g - &want.g).amax());
        assert_eq!(got.g, got.g.transpose());
        assert_eq!(got.bb, want.bb);
        // Classes matter: with every factor of class 3 doubled, the blocks it touches change.
        let mut doubled = factors.clone();
        doubled[3].iter_mut().for_each(|f| *f *= 2.0);
        let coupled = CoupledRows { factors: &doubled, ..coupled };
        let g2 = Gram::from_coupled_rows(&coupled, a.tr_mul(&b), &b).g;
        let (j3, j0) = ((0..p).find(|&j| class_of[j] == 3).unwrap(), (0..p).find(|&j| class_of[j] == 0).unwrap());
        assert!((g2[(j3, j3)] / want.g[(j3, j3)] - 4.0).abs() < 1e-9);
        assert!((g2[(j0, j3)] / want.g[(j0, j3)] - 2.0).abs() < 1e-9);
        assert_eq!(g2[(j0, j0)], got.g[(j0, j0)]);
    }

    /// A column that negates another in every row is found and its entries of G and c are the
    /// other's negated, bit for bit the sums of its own products in row order; columns that only
    /// look alike (equal, or negated in some rows) are multiplied out.
    #[test]
    fn mirrored_columns_give_the_bits_of_their_own_products() {
        let mut rng = crate::numerics::rng::SplitMix64::new(5);
        let (m, p) = (60, 16);
        // Row r is non-zero on the pair of columns 2w, 2w + 1 of window w = r % 8 and on one of
        // the columns 12–15 (windows 6 and 7, no pair): three entries of 16 at most, sparse
        // enough for the runs.
        let mut a = DMatrix::zeros(m, p);
        for r in 0..m {
            let w = r % 8;
            let v = rng.uniform() - 0.5;
            a[(r, 2 * w)] = v;
            a[(r, 2 * w + 1)] = match w {
                0 | 2 | 5 => -v,            // mirrors of 0, 4, 10
                3 => v,                     // equal, not negated
                4 if r % 3 == 0 => 0.5 * v, // negated in some rows only
                _ => rng.uniform() - 0.5,
            };
            a[(r, 12 + (r / 8) % 4)] += rng.uniform();
        }
        let b = DVector::from_fn(m, |_, _| rng.uniform() - 0.5);
        let (mut start, mut flat) = (vec![0usize], Vec::new());
        for r in 0..m {
            flat.extend((0..p).filter(|&j| a[(r, j)] != 0.0).map(|j| (j, a[(r, j)])));
            start.push(flat.len());
        }
        let sparse = SparseRows { rows: m, columns: p, runs: Run::of_rows(0, &start, &flat) };
        let mirror = mirrors(&sparse);
        let found: Vec<(usize, usize)> = mirror.iter().enumerate().filter_map(|(j, i)| Some(((*i)?, j))).collect();
        assert_eq!(found, vec![(0, 1), (4, 5), (10, 11)]);
        let got = Gram::from_runs(&sparse, &b);
        // The row-by-row sums, term for term.
        for j in 0..p {
            let mut cj = 0.0;
            for r in 0..m {
                if a[(r, j)] != 0.0 {
                    cj += a[(r, j)] * b[r];
                }
            }
            assert_eq!(got.c[j].to_bits(), cj.to_bits(), "c[{j}]");
            for k in 0..p {
                let mut g = 0.0;
                for r in 0..m {
                    if a[(r, j)] != 0.0 && a[(r, k)] != 0.0 {
                        g += a[(r, j)] * a[(r, k)];
                    }
                }
                assert_eq!(got.g[(j, k)].to_bits(), g.to_bits(), "G[{j}, {k}]");
            }
        }
    }

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

    /// Rows over more than one block: the blockwise sum is the one-product normal equations up
    /// to round-off, and its bits are the same on one thread and on three.
    #[test]
    fn row_blocks_sum_to_the_normal_equations_whatever_the_threads() {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let m = 2 * GRAM_BLOCK + 77;
        let a = DMatrix::from_fn(m, 9, |_, _| next());
        let b = DVector::from_fn(m, |_, _| next());
        let at = a.transpose();
        let (g0, c0) = (&at * &a, &at * &b);
        let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
        let one = pool(1).install(|| Gram::from_rows(&a, &b));
        let three = pool(3).install(|| Gram::from_rows(&a, &b));
        assert_eq!(one, three);
        assert!((&one.g - &g0).amax() < 1e-11 * g0.amax() && (&one.c - &c0).amax() < 1e-11 * c0.amax());
        assert_eq!(one.g, one.g.transpose());
        // At most one block: today's single product, bit for bit.
        let (a1, b1) = (a.rows(0, GRAM_BLOCK).into_owned(), b.rows(0, GRAM_BLOCK).into_owned());
        let t1 = a1.transpose();
        assert_eq!(Gram::from_rows(&a1, &b1).g, &t1 * &a1);
    }

    #[test]
    fn sparse_rows_give_the_dense_normal_equations() {
        // Banded rows like a cam's B-spline columns (4 non-zeros in 20), plus one dense column.
        let mut seed = 1u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let a = DMatrix::from_fn(200, 21, |i, j| if j == 20 || (j + 4 > i % 20 && j <= i % 20) { next() } else { 0.0 });
        let b = DVector::from_fn(200, |_, _| next());
        let (dense, sparse) = (Gram::from_rows(&a, &b), Gram::from_sparse_rows(&a, &b));
        assert!((&dense.g - &sparse.g).amax() < 1e-12 && (&dense.c - &sparse.c).amax() < 1e-12);
        assert_eq!(sparse.g, sparse.g.transpose());
        assert!(a.iter().filter(|v| **v != 0.0).count() * 4 <= a.len(), "the test must take the sparse path");
    }

    #[test]
    fn sparse_rows_sum_row_by_row_whatever_the_threads() {
        // Runs of three rows with one pattern (a sample's rows), single rows, a row of zeros, and
        // more columns than one parallel block.
        let mut seed = 5u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let (m, p) = (240, 3 * SPARSE_COLUMNS + 5);
        let band = |i: usize| if i < 150 { (i / 3 * 7) % (p - 4) } else { (i * 11) % (p - 4) };
        let a = DMatrix::from_fn(m, p, |i, j| if i != 77 && j >= band(i) && j < band(i) + 4 { next() } else { 0.0 });
        let b = DVector::from_fn(m, |_, _| next());
        // The definition: every row's products added to G and c in row order.
        let mut g = DMatrix::<f64>::zeros(p, p);
        let mut c = DVector::<f64>::zeros(p);
        for i in 0..m {
            for j in 0..p {
                if a[(i, j)] != 0.0 {
                    c[j] += a[(i, j)] * b[i];
                    for k in j..p {
                        if a[(i, k)] != 0.0 {
                            g[(k, j)] += a[(i, j)] * a[(i, k)];
                        }
                    }
                }
            }
        }
        let g = DMatrix::from_fn(p, p, |i, j| if i >= j { g[(i, j)] } else { g[(j, i)] });
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let sparse = pool.install(|| Gram::from_sparse_rows(&a, &b));
            assert_eq!((&sparse.g, &sparse.c), (&g, &c), "{threads} threads");
        }
    }
}
