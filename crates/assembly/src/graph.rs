//! The block sparsity structure shared by the Hessian ([`crate::hessian`]) and the projective
//! dynamics matrices ([`crate::pd`]): one block column per free vertex, one block per free vertex
//! pair joined by a spring plus the diagonal, and for every block column the list of springs that
//! contribute to it, in increasing spring order, with the slot they write to.
//!
//! Value layout for blocks of size D×D (D = 1 for scalar matrices), column-major CSC with both
//! triangles stored: block column `J` (free vertex J) holds `len_J` blocks with sorted block rows;
//! its D scalar columns are contiguous in the value array, starting at `D²·block_offset(J)`; scalar
//! column `D·J + b` has `D·len_J` entries, and entry (a, b) of the block in slot p is at
//! `D²·block_offset(J) + b·D·len_J + D·p + a`. So each block column owns one contiguous range of
//! values, which lets columns be filled in parallel without sharing.

use std::ops::Range;

use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use hooke_mesh::Spring;

use crate::FreeDofs;

/// One spring's contribution to a block column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Contribution {
    /// Spring index.
    pub spring: u32,
    /// Slot of the off-diagonal block this spring adds to, [`Contribution::PINNED_OTHER`] if its
    /// other end is pinned (it then only adds to the diagonal block).
    pub slot: u32,
    /// Whether this is the first spring writing to `slot` (write, not add: no zeroing pass).
    pub first: bool,
}

impl Contribution {
    /// `slot` of a spring whose other end is pinned.
    pub const PINNED_OTHER: u32 = u32::MAX;
}

/// Block structure of a symmetric matrix over the free vertices, from a spring graph.
#[derive(Clone, Debug)]
pub(crate) struct BlockGraph {
    /// Leaf boundaries: leaf k is columns `leaves[k]..leaves[k + 1]`.
    leaves: Vec<usize>,
    free: FreeDofs,
    spring_count: usize,
    /// Block column J's blocks are `block_offsets[J]..block_offsets[J + 1]` (len free + 1).
    block_offsets: Vec<usize>,
    /// Free block-row index of each block, sorted within a column.
    block_rows: Vec<u32>,
    /// Slot of the diagonal block within each block column.
    diagonal_slot: Vec<u32>,
    /// Block column J's contributions are `contribution_offsets[J]..contribution_offsets[J + 1]`.
    contribution_offsets: Vec<usize>,
    contributions: Vec<Contribution>,
}

impl BlockGraph {
    /// O(s log d) for s springs of largest vertex degree d.
    ///
    /// # Panics
    /// If `free` was built for a different vertex count, or a spring has an end out of range or
    /// twice the same end.
    #[track_caller]
    pub fn new(vertex_count: usize, springs: &[Spring], free: &FreeDofs) -> Self {
        Self::with_links(vertex_count, springs, &[], free)
    }

    /// [`BlockGraph::new`] with extra blocks: one for every pair of free vertices in `links`
    /// (vertex indices; pairs with a pinned or repeated end add nothing), with no contribution of
    /// their own. For terms that couple vertices no spring joins (self-contact pairs).
    ///
    /// # Panics
    /// As [`BlockGraph::new`], and if a link has an end out of range.
    #[track_caller]
    pub fn with_links(
        vertex_count: usize,
        springs: &[Spring],
        links: &[[u32; 2]],
        free: &FreeDofs,
    ) -> Self {
        assert_eq!(
            free.vertex_count(),
            vertex_count,
            "the free-DOF map was built for another vertex count"
        );
        assert!(
            springs.len() < u32::MAX as usize,
            "too many springs for u32 indices"
        );
        let n_free = free.free_count();
        // Incidence of free vertices, in increasing spring order.
        let mut contribution_offsets = vec![0usize; n_free + 1];
        for (index, s) in springs.iter().enumerate() {
            let (i, j) = s.ends();
            assert!(
                i < vertex_count && j < vertex_count,
                "spring {index} ({i}, {j}) has an end out of range (vertex count {vertex_count})"
            );
            assert!(i != j, "spring {index} joins vertex {i} to itself");
            for v in [i, j] {
                if let Some(f) = free.free_index(v) {
                    contribution_offsets[f + 1] += 1;
                }
            }
        }
        for f in 0..n_free {
            contribution_offsets[f + 1] += contribution_offsets[f];
        }
        let mut fill = contribution_offsets.clone();
        let mut contributions = vec![
            Contribution {
                spring: 0,
                slot: Contribution::PINNED_OTHER,
                first: false,
            };
            contribution_offsets[n_free]
        ];
        // Temporarily keep the other end's free index (or PINNED_OTHER) in `slot`.
        for (index, s) in springs.iter().enumerate() {
            let (i, j) = s.ends();
            let (fi, fj) = (free.free_index(i), free.free_index(j));
            for (this, other) in [(fi, fj), (fj, fi)] {
                if let Some(f) = this {
                    contributions[fill[f]] = Contribution {
                        spring: index as u32,
                        slot: other.map_or(Contribution::PINNED_OTHER, |o| o as u32),
                        first: false,
                    };
                    fill[f] += 1;
                }
            }
        }
        drop(fill);
        // The links' other ends per free column (free indices), both directions.
        let mut link_offsets = vec![0usize; n_free + 1];
        for &[a, b] in links {
            assert!(
                (a as usize) < vertex_count && (b as usize) < vertex_count,
                "link ({a}, {b}) has an end out of range (vertex count {vertex_count})"
            );
            if let (Some(fa), Some(fb)) = (free.free_index(a as usize), free.free_index(b as usize))
            {
                if fa != fb {
                    link_offsets[fa + 1] += 1;
                    link_offsets[fb + 1] += 1;
                }
            }
        }
        for f in 0..n_free {
            link_offsets[f + 1] += link_offsets[f];
        }
        let mut link_rows = vec![0u32; link_offsets[n_free]];
        let mut link_fill = link_offsets.clone();
        for &[a, b] in links {
            if let (Some(fa), Some(fb)) = (free.free_index(a as usize), free.free_index(b as usize))
            {
                if fa != fb {
                    link_rows[link_fill[fa]] = fb as u32;
                    link_fill[fa] += 1;
                    link_rows[link_fill[fb]] = fa as u32;
                    link_fill[fb] += 1;
                }
            }
        }
        drop(link_fill);
        // Leaves: contiguous column ranges, by halving down to a limit fixed by the size alone.
        let mut leaves = vec![0];
        split_leaves(
            0..n_free,
            n_free
                .div_ceil(LEAVES_WANTED)
                .clamp(MIN_LEAF_COLUMNS, MAX_LEAF_COLUMNS),
            &mut leaves,
        );
        // Block rows per column: the diagonal and the free neighbours, sorted, deduplicated.
        let mut block_offsets = Vec::with_capacity(n_free + 1);
        block_offsets.push(0);
        let mut block_rows = Vec::with_capacity(n_free + contributions.len());
        let mut diagonal_slot = Vec::with_capacity(n_free);
        let mut seen = Vec::new();
        for column in 0..n_free {
            let start = block_rows.len();
            block_rows.push(column as u32);
            let range = contribution_offsets[column]..contribution_offsets[column + 1];
            block_rows.extend(
                contributions[range.clone()]
                    .iter()
                    .filter(|c| c.slot != Contribution::PINNED_OTHER)
                    .map(|c| c.slot),
            );
            block_rows
                .extend_from_slice(&link_rows[link_offsets[column]..link_offsets[column + 1]]);
            block_rows[start..].sort_unstable();
            let mut unique = start;
            for k in start..block_rows.len() {
                if k == start || block_rows[k] != block_rows[unique - 1] {
                    block_rows[unique] = block_rows[k];
                    unique += 1;
                }
            }
            block_rows.truncate(unique);
            let rows = &block_rows[start..];
            diagonal_slot.push(
                rows.binary_search(&(column as u32))
                    .expect("the diagonal block is always present") as u32,
            );
            seen.clear();
            seen.resize(rows.len(), false);
            for c in &mut contributions[range] {
                if c.slot != Contribution::PINNED_OTHER {
                    let slot = rows
                        .binary_search(&c.slot)
                        .expect("every free neighbour has a block");
                    c.first = !seen[slot];
                    seen[slot] = true;
                    c.slot = slot as u32;
                }
            }
            block_offsets.push(block_rows.len());
        }
        BlockGraph {
            leaves,
            free: free.clone(),
            spring_count: springs.len(),
            block_offsets,
            block_rows,
            diagonal_slot,
            contribution_offsets,
            contributions,
        }
    }

    pub fn free(&self) -> &FreeDofs {
        &self.free
    }

    pub fn spring_count(&self) -> usize {
        self.spring_count
    }

    /// Number of block columns (free vertices).
    pub fn columns(&self) -> usize {
        self.block_offsets.len() - 1
    }

    /// Number of stored blocks.
    pub fn blocks(&self) -> usize {
        self.block_rows.len()
    }

    /// The blocks of column `column`, as a range of block indices.
    #[inline]
    pub fn column_blocks(&self, column: usize) -> Range<usize> {
        self.block_offsets[column]..self.block_offsets[column + 1]
    }

    /// The free block-row indices of the blocks of column `column`, sorted.
    #[inline]
    pub fn block_rows(&self, column: usize) -> &[u32] {
        &self.block_rows[self.column_blocks(column)]
    }

    #[inline]
    pub fn diagonal_slot(&self, column: usize) -> usize {
        self.diagonal_slot[column] as usize
    }

    #[inline]
    pub fn contributions(&self, column: usize) -> &[Contribution] {
        &self.contributions[self.contribution_range(column)]
    }

    /// The positions of column `column`'s contributions in the list of all contributions (column
    /// by column).
    #[inline]
    pub fn contribution_range(&self, column: usize) -> Range<usize> {
        self.contribution_offsets[column]..self.contribution_offsets[column + 1]
    }

    /// Total number of contributions (springs counted once per free end).
    pub fn contribution_count(&self) -> usize {
        self.contributions.len()
    }

    /// Leaf boundaries: leaf k is the columns `leaves()[k]..leaves()[k + 1]`.
    pub fn leaves(&self) -> &[usize] {
        &self.leaves
    }

    /// The symbolic CSC structure of the scalar matrix with D×D blocks (layout in the module docs).
    pub fn symbolic<const D: usize>(&self) -> SymbolicSparseColMat<usize> {
        let n = D * self.columns();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::with_capacity(D * D * self.blocks());
        col_ptr.push(0);
        for column in 0..self.columns() {
            let rows = &self.block_rows[self.column_blocks(column)];
            for _ in 0..D {
                for &row in rows {
                    row_idx.extend((0..D).map(|a| D * row as usize + a));
                }
                col_ptr.push(row_idx.len());
            }
        }
        SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx)
    }

    /// Fill the values of every block column with `fill_column(column, values_of_column)`, leaf by
    /// leaf (in parallel by recursive halving of the leaf list if `parallel`), each leaf's columns in
    /// increasing order by one task. Each column is filled by one call, so the result does not depend
    /// on the number of threads.
    pub fn for_each_column<const D: usize, F>(
        &self,
        values: &mut [f64],
        parallel: bool,
        fill_column: &F,
    ) where
        F: Fn(usize, &mut [f64]) + Sync,
    {
        let fill_leaf = |columns: Range<usize>, values: &mut [f64], _: &mut [()]| {
            let mut rest = values;
            for column in columns {
                let len = D * D * self.column_blocks(column).len();
                let (this, tail) = rest.split_at_mut(len);
                fill_column(column, this);
                rest = tail;
            }
        };
        self.for_each_leaf::<D, (), _>(values, &mut [], None, parallel, &fill_leaf);
    }

    /// Fill the values of every leaf with `fill_leaf(columns, values_of_columns, scratch_of_leaf)`,
    /// one task per leaf (in parallel by recursive halving of the leaf list if `parallel`). Leaf k's
    /// scratch is `scratch[scratch_offsets[k]..scratch_offsets[k + 1]]` (empty without offsets).
    /// Each leaf is filled by one call, so the result does not depend on the number of threads.
    ///
    /// # Panics
    /// If `values` does not have D² values per block, or `scratch_offsets` one entry per leaf and
    /// one more, ending at `scratch.len()`.
    #[track_caller]
    pub fn for_each_leaf<const D: usize, T: Send, F>(
        &self,
        values: &mut [f64],
        scratch: &mut [T],
        scratch_offsets: Option<&[usize]>,
        parallel: bool,
        fill_leaf: &F,
    ) where
        F: Fn(Range<usize>, &mut [f64], &mut [T]) + Sync,
    {
        assert_eq!(
            values.len(),
            D * D * self.blocks(),
            "one value per stored entry"
        );
        if let Some(offsets) = scratch_offsets {
            assert_eq!(
                offsets.len(),
                self.leaves.len(),
                "one scratch range per leaf"
            );
            assert_eq!(offsets.last(), Some(&scratch.len()), "scratch length");
        }
        let leaves = 0..self.leaves.len() - 1;
        self.leaves_range::<D, T, F>(
            leaves,
            values,
            scratch,
            scratch_offsets,
            parallel,
            fill_leaf,
        );
    }

    fn leaves_range<const D: usize, T: Send, F>(
        &self,
        leaves: Range<usize>,
        values: &mut [f64],
        scratch: &mut [T],
        scratch_offsets: Option<&[usize]>,
        parallel: bool,
        fill_leaf: &F,
    ) where
        F: Fn(Range<usize>, &mut [f64], &mut [T]) + Sync,
    {
        if leaves.len() == 1 {
            let columns = self.leaves[leaves.start]..self.leaves[leaves.end];
            fill_leaf(columns, values, scratch);
        } else if !parallel {
            let (mut values, mut scratch) = (values, scratch);
            for leaf in leaves {
                let columns = self.leaves[leaf]..self.leaves[leaf + 1];
                let len =
                    D * D * (self.block_offsets[columns.end] - self.block_offsets[columns.start]);
                let scratch_len = scratch_offsets.map_or(0, |o| o[leaf + 1] - o[leaf]);
                let (this, rest) = values.split_at_mut(len);
                let (this_scratch, rest_scratch) = scratch.split_at_mut(scratch_len);
                fill_leaf(columns, this, this_scratch);
                (values, scratch) = (rest, rest_scratch);
            }
        } else if !leaves.is_empty() {
            let mid = leaves.start + leaves.len() / 2;
            let first = self.leaves[leaves.start];
            let split = D * D * (self.block_offsets[self.leaves[mid]] - self.block_offsets[first]);
            let scratch_split = scratch_offsets.map_or(0, |o| o[mid] - o[leaves.start]);
            let (left, right) = values.split_at_mut(split);
            let (left_scratch, right_scratch) = scratch.split_at_mut(scratch_split);
            rayon::join(
                || {
                    let leaves = leaves.start..mid;
                    self.leaves_range::<D, T, F>(
                        leaves,
                        left,
                        left_scratch,
                        scratch_offsets,
                        true,
                        fill_leaf,
                    )
                },
                || {
                    let leaves = mid..leaves.end;
                    self.leaves_range::<D, T, F>(
                        leaves,
                        right,
                        right_scratch,
                        scratch_offsets,
                        true,
                        fill_leaf,
                    )
                },
            );
        }
    }
}

/// The block graph of `springs` over `vertex_count` vertices on the free vertices of `free` (all if
/// `None`), and the symbolic CSC structure of its scalar matrix with D×D blocks: the construction
/// [`crate::HessianPattern`] and [`crate::LaplacianPattern`] share.
///
/// # Panics
/// As [`BlockGraph::new`].
#[track_caller]
pub(crate) fn block_pattern<const D: usize>(
    vertex_count: usize,
    springs: &[Spring],
    free: Option<&FreeDofs>,
) -> (BlockGraph, SymbolicSparseColMat<usize>) {
    let graph = match free {
        Some(free) => BlockGraph::new(vertex_count, springs, free),
        None => BlockGraph::new(vertex_count, springs, &FreeDofs::all_free(vertex_count)),
    };
    let symbolic = graph.symbolic::<D>();
    (graph, symbolic)
}

/// [`block_pattern`] with the extra blocks of `links` ([`BlockGraph::with_links`]).
///
/// # Panics
/// As [`BlockGraph::with_links`].
#[track_caller]
pub(crate) fn block_pattern_with_links<const D: usize>(
    vertex_count: usize,
    springs: &[Spring],
    links: &[[u32; 2]],
    free: Option<&FreeDofs>,
) -> (BlockGraph, SymbolicSparseColMat<usize>) {
    let graph = match free {
        Some(free) => BlockGraph::with_links(vertex_count, springs, links, free),
        None => BlockGraph::with_links(
            vertex_count,
            springs,
            links,
            &FreeDofs::all_free(vertex_count),
        ),
    };
    let symbolic = graph.symbolic::<D>();
    (graph, symbolic)
}

/// `values` on the structure `symbolic`, borrowed (no copy).
///
/// # Panics
/// If there is not one value per stored entry; the message starts with `what` (the caller's name).
#[track_caller]
pub(crate) fn matrix_ref<'a>(
    symbolic: &'a SymbolicSparseColMat<usize>,
    values: &'a [f64],
    what: &str,
) -> SparseColMatRef<'a, usize, f64> {
    assert_eq!(
        values.len(),
        symbolic.row_idx().len(),
        "{what}: one value per stored entry"
    );
    SparseColMatRef::new(symbolic.as_ref(), values)
}

/// An owned copy of `values` on the structure `symbolic` (allocates).
///
/// # Panics
/// As [`matrix_ref`].
#[track_caller]
pub(crate) fn matrix_owned(
    symbolic: &SymbolicSparseColMat<usize>,
    values: &[f64],
    what: &str,
) -> SparseColMat<usize, f64> {
    matrix_ref(symbolic, values, what);
    SparseColMat::new(symbolic.clone(), values.to_vec())
}

/// About this many leaves on large meshes, to balance the load over a few threads.
const LEAVES_WANTED: usize = 16;
/// Leaves are halved down to at most ⌈columns / LEAVES_WANTED⌉ columns (rounded up: rounded down,
/// the halves of a column count that is not a multiple of LEAVES_WANTED exceed the limit by a
/// fraction and are halved once more, giving twice as many leaves), kept within these bounds:
/// large enough that few springs cross a leaf boundary on meshes with a banded numbering (cloth-N
/// joins columns up to 2N apart; a crossing spring's block is computed twice), small enough for
/// load balance.
const MIN_LEAF_COLUMNS: usize = 1024;
const MAX_LEAF_COLUMNS: usize = 8192;

/// Append the end of each leaf of `columns` to `boundaries`, halving until ≤ `limit` columns.
fn split_leaves(columns: Range<usize>, limit: usize, boundaries: &mut Vec<usize>) {
    if columns.len() <= limit {
        boundaries.push(columns.end);
    } else {
        let mid = columns.start + columns.len() / 2;
        split_leaves(columns.start..mid, limit, boundaries);
        split_leaves(mid..columns.end, limit, boundaries);
    }
}
