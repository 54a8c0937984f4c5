//! Triangular solves with a simplicial LLᵀ factor for D interleaved right-hand sides (the D
//! coordinates of projective dynamics), split over two threads along the elimination tree.
//!
//! Two subtrees of the elimination tree do not depend on each other: the rows of L in a subtree
//! hold entries only in columns of that subtree, and the columns only in rows of the subtree or
//! its ancestors. So the tree is cut into a top S (closed upwards: every ancestor of a node of S is
//! in S) and the subtrees hanging below it, dealt into two bins of about equal work. The nodes are
//! renumbered bin 0, bin 1, S, each part in the factor's order: a topological order of the tree,
//! so the factor of the renumbered matrix is the same L with its rows and columns renumbered, and
//! each part is a contiguous range. Then
//! - forward, L z = b, row by row as a gather (z_i = (b_i − Σ_{j<i} L_ij z_j) / L_ii): the two
//!   bins at once, each reading only its own range and then summing its columns' part of the rows
//!   of S; then S, which adds the two parts in a fixed order;
//! - backward, Lᵀ x = z, column by column as a gather (x_j = (z_j − Σ_{i>j} L_ij x_i) / L_jj): S
//!   first, then the two bins at once, each reading its own range and S.
//!
//! Each right-hand side is a row of D values (one vertex's coordinates): one pass over L serves
//! all D columns, and a gather accumulates in registers instead of scattering into memory. The
//! columns are stored last first, so that the backward pass streams through memory forwards. The
//! arithmetic does not depend on whether the bins run on one thread or two: the same bits. The
//! layout depends on the pattern only: it is made once and refilled with each factorisation's
//! values. Measurements: `benches/results/issue15-pd-speed.md`.

use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use nalgebra::SVector;

/// The share of the solve's work the top S may reach before the search for a deeper cut stops:
/// S is solved on one thread, so a cut that deep could not pay.
const MAX_TOP_SHARE: f64 = 0.25;

/// The smallest factor (stored values) whose split solve runs its two bins on two threads:
/// below it the fork costs more than the second thread saves. Measured with `hooke bench --sweep
/// N=20,40,80,160 --solver pd:10` (three runs each, 2 cores): two threads are slower on cloth-20
/// (9,956 values; 0.92–0.96 ms against 0.35–0.51 ms for pd:10) and faster from cloth-40 (61,169
/// values; 1.7–2.7 against 3.4–3.9 ms) and cloth-80 (8.0–10.7 against 15.8–20.3 ms) up.
pub(crate) const SPLIT_MIN_VALUES: usize = 32_768;

/// Marks a diagonal entry in [`ForestSolve`]'s slots (and bounds the indices it can address).
const DIAGONAL: u32 = u32::MAX;

/// A simplicial LLᵀ factor laid out for the split solve (see the module documentation).
#[derive(Clone, Debug)]
pub(crate) struct ForestSolve<const D: usize> {
    /// `order[k]`: the unknown (in the caller's numbering) at position k of the solve's order.
    order: Vec<u32>,
    /// The end of bin 0 and of bin 1 in the solve's order (S is `bins[1]..n`).
    bins: [usize; 2],
    /// L by rows, strictly lower part: `row_ptr[i]..row_ptr[i + 1]` in `row_col` / `row_val`.
    row_ptr: Vec<u32>,
    row_col: Vec<u32>,
    row_val: Vec<f64>,
    /// L by columns, strictly lower part, the last column first: `col_ptr[j + 1]..col_ptr[j]` in
    /// `col_row` / `col_val`.
    col_ptr: Vec<u32>,
    col_row: Vec<u32>,
    col_val: Vec<f64>,
    /// The first entry of each column whose row is not in S (its rows are in decreasing order).
    col_mid: Vec<u32>,
    /// For each row of S, its first entry in a column of bin 1 and its first in a column of S
    /// (its columns are in increasing order: bin 0, bin 1, S).
    row_mid: Vec<[u32; 2]>,
    /// 1 / L_kk.
    inv_diag: Vec<f64>,
    /// Where each of faer's stored values goes: its slot in the rows and in the columns, or
    /// [`DIAGONAL`] and its position for a diagonal entry.
    slots: Vec<[u32; 2]>,
    /// Each bin's part of the sums of S's rows, Σ_{j in the bin} L_ij z_j, computed by the bin's
    /// thread after its forward substitution.
    partial: [Vec<SVector<f64, D>>; 2],
}

impl<const D: usize> ForestSolve<D> {
    /// Lay out the simplicial LLᵀ factor `values` of `symbolic`; `None` if the factor is
    /// supernodal or has more stored entries than 32-bit indices address.
    pub(crate) fn new(symbolic: &SymbolicCholesky<usize>, values: &[f64]) -> Option<Self> {
        let mut forest = Self::layout(symbolic)?;
        forest.refill(values);
        Some(forest)
    }

    /// The layout of `symbolic`'s factor, its values still to be filled: the cut, the solve's
    /// order, both storages of L and where each of faer's stored entries goes. Depends on the
    /// pattern only, so it is made once and [`ForestSolve::refill`]ed for each factorisation.
    fn layout(symbolic: &SymbolicCholesky<usize>) -> Option<Self> {
        let SymbolicCholeskyRaw::Simplicial(s) = symbolic.raw() else {
            return None;
        };
        let n = symbolic.nrows();
        let (l_ptr, l_row) = (s.col_ptr(), s.row_idx());
        if l_row.len() >= DIAGONAL as usize || n >= DIAGONAL as usize {
            return None;
        }
        // The elimination tree: the parent of column j is its first off-diagonal row.
        let parent: Vec<usize> = (0..n)
            .map(|j| {
                let rows = &l_row[l_ptr[j] + 1..l_ptr[j + 1]];
                rows.iter().copied().min().unwrap_or(usize::MAX)
            })
            .collect();
        let weight: Vec<u64> = (0..n).map(|j| (l_ptr[j + 1] - l_ptr[j]) as u64).collect();
        let part = split_tree(&parent, &weight);
        // The solve's order: bin 0, bin 1, S, each in the factor's order.
        let mut position = vec![0u32; n];
        let mut by_position = Vec::with_capacity(n);
        let mut bins = [0usize; 2];
        for p in 0..3u8 {
            for k in (0..n).filter(|&k| part[k] == p) {
                position[k] = by_position.len() as u32;
                by_position.push(k);
            }
            if p < 2 {
                bins[p as usize] = by_position.len();
            }
        }
        let order: Vec<u32> = match symbolic.perm() {
            Some(perm) => by_position
                .iter()
                .map(|&k| perm.arrays().0[k] as u32)
                .collect(),
            None => by_position.iter().map(|&k| k as u32).collect(),
        };
        // Strictly lower entries: a topological renumbering keeps every row below its column.
        // Rows by prefix sums; columns by suffix sums, so that the backward substitution, which
        // visits the columns from the last to the first, streams through memory forwards.
        let mut row_ptr = vec![0u32; n + 1];
        let mut col_ptr = vec![0u32; n + 1];
        for j in 0..n {
            for &i in &l_row[l_ptr[j] + 1..l_ptr[j + 1]] {
                row_ptr[position[i] as usize + 1] += 1;
                col_ptr[position[j] as usize] += 1;
            }
        }
        for k in 0..n {
            row_ptr[k + 1] += row_ptr[k];
        }
        for k in (0..n).rev() {
            col_ptr[k] += col_ptr[k + 1];
        }
        let off = col_ptr[0] as usize;
        let mut row_col = vec![0u32; off];
        let mut col_row = vec![0u32; off];
        let mut slots = vec![[DIAGONAL, 0]; l_row.len()];
        let mut row_fill = row_ptr.clone();
        // Each column's rows in decreasing order: its segment is filled from the end.
        let mut col_fill = col_ptr[..n].to_vec();
        let mut entries: Vec<(u32, usize)> = Vec::new();
        // Columns in the new order, so that each row's entries come in increasing column order.
        for (nj, &j) in by_position.iter().enumerate() {
            slots[l_ptr[j]] = [DIAGONAL, nj as u32];
            entries.clear();
            entries.extend((l_ptr[j] + 1..l_ptr[j + 1]).map(|e| (position[l_row[e]], e)));
            entries.sort_unstable();
            for &(i, e) in &entries {
                let r = &mut row_fill[i as usize];
                row_col[*r as usize] = nj as u32;
                let c = &mut col_fill[nj];
                *c -= 1;
                col_row[*c as usize] = i;
                slots[e] = [*r, *c];
                *r += 1;
            }
        }
        let col_mid = (0..n)
            .map(|j| {
                let (from, to) = (col_ptr[j + 1] as usize, col_ptr[j] as usize);
                (from + col_row[from..to].partition_point(|&i| (i as usize) >= bins[1])) as u32
            })
            .collect();
        let row_mid = (bins[1]..n)
            .map(|i| {
                let (from, to) = (row_ptr[i] as usize, row_ptr[i + 1] as usize);
                let first = |end: usize| {
                    (from + row_col[from..to].partition_point(|&j| (j as usize) < end)) as u32
                };
                [first(bins[0]), first(bins[1])]
            })
            .collect();
        let top = n - bins[1];
        Some(ForestSolve {
            order,
            bins,
            row_ptr,
            row_col,
            row_val: vec![0.0; off],
            col_ptr,
            col_row,
            col_val: vec![0.0; off],
            col_mid,
            row_mid,
            inv_diag: vec![0.0; n],
            slots,
            partial: [vec![SVector::zeros(); top], vec![SVector::zeros(); top]],
        })
    }

    /// Take the values of a new factorisation on the same pattern (faer's simplicial storage,
    /// as [`ForestSolve::new`] was given): O(stored values), no analysis.
    ///
    /// # Panics
    /// If `values` is not of the layout's length.
    pub(crate) fn refill(&mut self, values: &[f64]) {
        assert_eq!(values.len(), self.slots.len(), "the factor's stored values");
        for (&[r, c], &v) in self.slots.iter().zip(values) {
            if r == DIAGONAL {
                self.inv_diag[c as usize] = 1.0 / v;
            } else {
                self.row_val[r as usize] = v;
                self.col_val[c as usize] = v;
            }
        }
    }

    /// The number of unknowns.
    pub(crate) fn dim(&self) -> usize {
        self.order.len()
    }

    /// `order[k]`: the unknown at position k of the solve's order.
    pub(crate) fn order(&self) -> &[u32] {
        &self.order
    }

    /// Solve L Lᵀ x = b in place, `x` in the solve's order ([`ForestSolve::order`]): on entry b,
    /// on return x. With `parallel`, the two bins run on two threads (the same bits).
    ///
    /// # Panics
    /// If `x` does not have [`ForestSolve::dim`] rows.
    pub(crate) fn solve_ordered(&mut self, x: &mut [SVector<f64, D>], parallel: bool) {
        assert_eq!(x.len(), self.dim(), "right-hand side rows");
        let [end0, end1] = self.bins;
        {
            let (bins, _) = x.split_at_mut(end1);
            let (b0, b1) = bins.split_at_mut(end0);
            // Moved out and back (no allocation) so that the bins may borrow the rest.
            let [mut p0, mut p1] = std::mem::take(&mut self.partial);
            let this = &*self;
            run_both(
                parallel,
                || this.forward_bin(0, b0, &mut p0),
                || this.forward_bin(1, b1, &mut p1),
            );
            self.partial = [p0, p1];
        }
        self.forward_top(x);
        self.backward_top(x);
        let (bins, top) = x.split_at_mut(end1);
        let (b0, b1) = bins.split_at_mut(end0);
        let top = &*top;
        run_both(
            parallel,
            || self.backward_bin(0, b0, top),
            || self.backward_bin(end0, b1, top),
        );
    }

    /// Forward substitution over the rows of bin `bin`, `part` its slice of z (every column its
    /// rows refer to is in the bin), then the bin's part of S's row sums into `partial`.
    fn forward_bin(
        &self,
        bin: usize,
        part: &mut [SVector<f64, D>],
        partial: &mut [SVector<f64, D>],
    ) {
        let start = if bin == 0 { 0 } else { self.bins[0] };
        for r in 0..part.len() {
            let i = start + r;
            let (from, to) = (self.row_ptr[i] as usize, self.row_ptr[i + 1] as usize);
            let sum = gather(
                &self.row_col[from..to],
                &self.row_val[from..to],
                part,
                start,
            );
            part[r] = (part[r] - sum) * self.inv_diag[i];
        }
        let top_start = self.bins[1];
        for (t, p) in partial.iter_mut().enumerate() {
            let i = top_start + t;
            let (from, to) = if bin == 0 {
                (self.row_ptr[i] as usize, self.row_mid[t][0] as usize)
            } else {
                (self.row_mid[t][0] as usize, self.row_mid[t][1] as usize)
            };
            *p = gather(
                &self.row_col[from..to],
                &self.row_val[from..to],
                part,
                start,
            );
        }
    }

    /// Forward substitution over the rows of S, after the bins: their sums over the bins' columns
    /// are the bins' partial sums, in a fixed order.
    fn forward_top(&self, x: &mut [SVector<f64, D>]) {
        let top_start = self.bins[1];
        for i in top_start..x.len() {
            let t = i - top_start;
            let (from, to) = (self.row_mid[t][1] as usize, self.row_ptr[i + 1] as usize);
            let sum = gather(&self.row_col[from..to], &self.row_val[from..to], x, 0);
            x[i] = (x[i] - self.partial[0][t] - self.partial[1][t] - sum) * self.inv_diag[i];
        }
    }

    /// Backward substitution over the columns of S, before the bins: their rows are in S.
    fn backward_top(&self, x: &mut [SVector<f64, D>]) {
        for j in (self.bins[1]..x.len()).rev() {
            let (from, to) = (self.col_ptr[j + 1] as usize, self.col_ptr[j] as usize);
            let sum = gather(&self.col_row[from..to], &self.col_val[from..to], x, 0);
            x[j] = (x[j] - sum) * self.inv_diag[j];
        }
    }

    /// Backward substitution over the columns of a bin starting at `start`, `part` its slice of
    /// x, `top` S's (solved): a column's rows in S come first (up to `col_mid`), then the bin's.
    fn backward_bin(&self, start: usize, part: &mut [SVector<f64, D>], top: &[SVector<f64, D>]) {
        let top_start = self.bins[1];
        for r in (0..part.len()).rev() {
            let j = start + r;
            let (from, mid, to) = (
                self.col_ptr[j + 1] as usize,
                self.col_mid[j] as usize,
                self.col_ptr[j] as usize,
            );
            let sum = gather(
                &self.col_row[from..mid],
                &self.col_val[from..mid],
                top,
                top_start,
            ) + gather(&self.col_row[mid..to], &self.col_val[mid..to], part, start);
            part[r] = (part[r] - sum) * self.inv_diag[j];
        }
    }
}

/// Σ_e `values[e]` · x[`indices[e]` − `offset`], in two interleaved partial sums (entries 0, 2, 4,
/// … and 1, 3, 5, …) added at the end: two chains of dependent additions instead of one.
#[inline(always)]
fn gather<const D: usize>(
    indices: &[u32],
    values: &[f64],
    x: &[SVector<f64, D>],
    offset: usize,
) -> SVector<f64, D> {
    let mut even = [0.0; D];
    let mut odd = [0.0; D];
    let mut pairs = indices.chunks_exact(2).zip(values.chunks_exact(2));
    for (i, v) in pairs.by_ref() {
        let (x0, x1) = (&x[i[0] as usize - offset], &x[i[1] as usize - offset]);
        for a in 0..D {
            even[a] += v[0] * x0[a];
            odd[a] += v[1] * x1[a];
        }
    }
    if let (Some(&i), Some(&v)) = (indices.last(), values.last()) {
        if indices.len() % 2 == 1 {
            let xi = &x[i as usize - offset];
            for a in 0..D {
                even[a] += v * xi[a];
            }
        }
    }
    SVector::from_fn(|a, _| even[a] + odd[a])
}

/// Run `a` and `b`, on two threads if `parallel`.
fn run_both(parallel: bool, a: impl FnOnce() + Send, b: impl FnOnce() + Send) {
    if parallel {
        rayon::join(a, b);
    } else {
        a();
        b();
    }
}

/// Cut the elimination forest `parent` (`usize::MAX` at roots; node k weighted by `weight[k]`,
/// the stored entries of its column) into bin 0, bin 1 and the top S (part 2). S grows from the
/// roots by cutting the heaviest hanging subtree's root, as long as that root has children and S
/// holds at most [`MAX_TOP_SHARE`] of the work; the cut kept is the one whose critical path, S
/// plus the lower bound max(heaviest subtree, half the hanging work) of the heavier bin, is
/// least. Its hanging subtrees are then dealt largest first to the lighter bin. O(n log n).
/// Returns each node's part.
fn split_tree(parent: &[usize], weight: &[u64]) -> Vec<u8> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let n = parent.len();
    // Children lists; parents come after their children in a factor's order.
    let mut child_start = vec![0usize; n + 1];
    for &p in parent {
        if p != usize::MAX {
            child_start[p + 1] += 1;
        }
    }
    for k in 0..n {
        child_start[k + 1] += child_start[k];
    }
    let mut children = vec![0usize; child_start[n]];
    let mut fill = child_start.clone();
    for (k, &p) in parent.iter().enumerate() {
        if p != usize::MAX {
            children[fill[p]] = k;
            fill[p] += 1;
        }
    }
    let children_of = |k: usize| &children[child_start[k]..child_start[k + 1]];
    let mut subtree = weight.to_vec();
    for k in 0..n {
        if parent[k] != usize::MAX {
            subtree[parent[k]] += subtree[k];
        }
    }
    let roots = || (0..n).filter(|&k| parent[k] == usize::MAX);
    let total: u64 = roots().map(|k| subtree[k]).sum();
    // Hanging subtrees, heaviest first (ties: the lower index).
    let mut hanging: BinaryHeap<(u64, Reverse<usize>)> =
        roots().map(|k| (subtree[k], Reverse(k))).collect();
    let mut top: Vec<usize> = Vec::new();
    let mut top_weight = 0u64;
    let (mut best_cost, mut best_cut) = (u64::MAX, 0usize);
    while let Some(&(heaviest, Reverse(root))) = hanging.peek() {
        let cost = top_weight + heaviest.max((total - top_weight).div_ceil(2));
        if cost < best_cost {
            (best_cost, best_cut) = (cost, top.len());
        }
        if children_of(root).is_empty() || top_weight as f64 > MAX_TOP_SHARE * total as f64 {
            break;
        }
        hanging.pop();
        top.push(root);
        top_weight += weight[root];
        hanging.extend(children_of(root).iter().map(|&c| (subtree[c], Reverse(c))));
    }
    // S is the first `best_cut` roots cut; the subtrees hanging from it (or roots outside it)
    // are dealt largest first to the lighter bin.
    let mut part = vec![2u8; n];
    let mut in_top = vec![false; n];
    for &k in &top[..best_cut] {
        in_top[k] = true;
    }
    let mut dealt: Vec<usize> = (0..n)
        .filter(|&k| !in_top[k] && (parent[k] == usize::MAX || in_top[parent[k]]))
        .collect();
    dealt.sort_by_key(|&k| (Reverse(subtree[k]), k));
    let mut bins = [0u64; 2];
    for &k in &dealt {
        let b = usize::from(bins[1] < bins[0]);
        bins[b] += subtree[k];
        part[k] = b as u8;
    }
    // Every other node below S takes its parent's part (parents first: reverse order).
    for k in (0..n).rev() {
        if !in_top[k] && part[k] == 2 && parent[k] != usize::MAX {
            part[k] = part[parent[k]];
        }
    }
    part
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cholesky::{CholeskyParams, FactorKind, SparseCholesky};
    use faer::MatMut;
    use hooke_assembly::{FreeDofs, LaplacianPattern};
    use hooke_mesh::generators;
    use nalgebra::Vector3;

    /// PD's matrix K (M + h² L) Kᵀ of cloth-n (pins 0 and n − 1), factored simplicial LLᵀ.
    fn cloth_factor(n: usize) -> SparseCholesky {
        cloth_factor_at(n, 1.0 / 30.0)
    }

    /// The same at time step `h`.
    fn cloth_factor_at(n: usize, h: f64) -> SparseCholesky {
        let mesh = generators::cloth(n, 1e3).unwrap();
        let free = FreeDofs::new(mesh.vertex_count(), &[0, n as u32 - 1]).unwrap();
        let pattern = LaplacianPattern::new(mesh.vertex_count(), mesh.springs(), Some(&free));
        let mut values = pattern.new_values();
        pattern.system_into(mesh.springs(), mesh.masses(), h, &mut values);
        let mut cholesky = SparseCholesky::analyze(
            pattern.symbolic(),
            CholeskyParams {
                kind: FactorKind::Simplicial,
                ..CholeskyParams::default()
            },
        )
        .unwrap();
        cholesky.factorize(pattern.matrix(&values)).unwrap();
        cholesky
    }

    /// The split solve agrees with faer's solve to round-off (the same factor, summed in another
    /// order: the difference is a few ulps of the solution times the factor's condition), and
    /// gives the same bits on one thread and two.
    #[test]
    fn split_solve_matches_the_direct_solve() {
        for n in [3, 10, 40, 80] {
            let mut cholesky = cloth_factor(n);
            let mut forest = cholesky.forest_solve::<3>().expect("simplicial LLᵀ");
            let dim = forest.dim();
            let b: Vec<Vector3<f64>> = (0..dim)
                .map(|i| {
                    let t = i as f64;
                    Vector3::new((0.37 * t).sin(), (1.3 * t).cos() + 0.5, 1e-3 * t - 0.2)
                })
                .collect();
            // faer: column-major, the caller's order.
            let mut columns = vec![0.0; 3 * dim];
            for (i, v) in b.iter().enumerate() {
                for a in 0..3 {
                    columns[a * dim + i] = v[a];
                }
            }
            cholesky.solve_in_place(MatMut::from_column_major_slice_mut(&mut columns, dim, 3));
            let mut results = Vec::new();
            for parallel in [false, true] {
                let mut ordered: Vec<Vector3<f64>> =
                    forest.order().iter().map(|&i| b[i as usize]).collect();
                forest.solve_ordered(&mut ordered, parallel);
                let mut x = vec![Vector3::zeros(); dim];
                for (o, &i) in ordered.iter().zip(forest.order()) {
                    x[i as usize] = *o;
                }
                results.push(x);
            }
            assert_eq!(
                results[0], results[1],
                "cloth-{n}: one thread and two differ"
            );
            let scale = columns.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let worst = (0..dim)
                .flat_map(|i| (0..3).map(move |a| (i, a)))
                .map(|(i, a)| (results[0][i][a] - columns[a * dim + i]).abs())
                .fold(0.0f64, f64::max);
            // M + h²L has a condition number of about 1 + 8 h² k / m ≈ 1e4 on cloth-80: 1e-12
            // of the solution's scale leaves room for that times a few ulps.
            assert!(worst <= 1e-12 * scale, "cloth-{n}: {worst:e} of {scale:e}");
        }
    }

    /// The cut deals every node to exactly one part, and on cloth (the matrices projective
    /// dynamics factors) the two threads' critical path, the heavier bin plus S, is at most 65 %
    /// of the serial solve's work (50 % is the ideal; measured 58 %, 60 % and 54 % on cloth-40,
    /// 80 and 160 with faer's AMD order): a split that does not save a third would not pay.
    #[test]
    fn the_cut_balances_the_bins_of_a_cloth() {
        for n in [40, 80, 160] {
            let cholesky = cloth_factor(n);
            let forest = cholesky.forest_solve::<3>().unwrap();
            let mut seen = forest.order().to_vec();
            seen.sort_unstable();
            assert!(seen.iter().enumerate().all(|(k, &i)| k == i as usize));
            let work = |range: std::ops::Range<usize>| -> f64 {
                range
                    .map(|j| (forest.col_ptr[j] - forest.col_ptr[j + 1]) as f64 + 1.0)
                    .sum()
            };
            let [end0, end1] = forest.bins;
            let (w0, w1, top) = (work(0..end0), work(end0..end1), work(end1..forest.dim()));
            let critical = (w0.max(w1) + top) / (w0 + w1 + top);
            assert!(
                critical <= 0.65,
                "cloth-{n}: bins {w0} and {w1}, top {top}: critical path {critical}"
            );
        }
    }

    /// A layout refilled with another factorisation of the same pattern solves as a layout made
    /// for it: the same bits.
    #[test]
    fn a_refilled_layout_is_a_new_one() {
        let mut refilled = cloth_factor(20).forest_solve::<3>().unwrap();
        let other = cloth_factor_at(20, 1.0 / 7.0);
        refilled.refill(other.llt_values().unwrap());
        let mut fresh = other.forest_solve::<3>().unwrap();
        let b: Vec<Vector3<f64>> = (0..fresh.dim())
            .map(|i| Vector3::new(i as f64, 1.0, -0.5 * i as f64))
            .collect();
        let (mut x, mut y) = (b.clone(), b);
        refilled.solve_ordered(&mut x, false);
        fresh.solve_ordered(&mut y, false);
        assert!(x
            .iter()
            .zip(&y)
            .all(|(a, b)| a.iter().zip(b).all(|(p, q)| p.to_bits() == q.to_bits())));
        assert_ne!(x[0], Vector3::new(0.0, 1.0, 0.0), "the solve did nothing");
    }

    /// A tree that is a single chain has nothing to split: everything may end in one part, and
    /// the solve is still right (cloth-3 above); a forest of two equal trees splits exactly.
    #[test]
    fn split_tree_deals_a_forest_of_two_trees_to_two_bins() {
        // Two chains 0 → 1 → 2 and 3 → 4 → 5.
        let parent = [1, 2, usize::MAX, 4, 5, usize::MAX];
        let part = split_tree(&parent, &[1; 6]);
        assert_eq!(&part[..3], &[part[0]; 3]);
        assert_eq!(&part[3..], &[part[3]; 3]);
        assert_ne!(part[0], part[3]);
        assert!(part.iter().all(|&p| p < 2));
    }
}
