//! The order in which a Hessian refill computes spring blocks and where it keeps them (see
//! [`crate::hessian::HessianPattern::assemble_into`]).
//!
//! A refill walks each leaf of the block graph column by column. At each column it first computes
//! the blocks of the springs that column is the first to need (one tight loop over springs, whose
//! square roots and divisions overlap), writing them one after the other into a small ring buffer
//! owned by the leaf; then it gathers the blocks of its contributions, in increasing spring order,
//! from the ring into its values. A spring whose two ends are free and in the same leaf is computed
//! once, at its lower column, and read again at its higher one (computes run in batches, up to
//! `BATCH − 1` ahead of the column that needs them); a spring with a pinned end, or with
//! its ends in different leaves, is computed by each free end. The ring is sized at build time so
//! that no block is overwritten before its last reader: on meshes with a banded numbering (cloth-N:
//! columns at most 2N apart) that is a few thousand blocks, which stay in cache, instead of one block
//! per spring in memory.

use std::ops::Range;

use crate::graph::{BlockGraph, Contribution};
use crate::hessian::BATCH;

/// Where a contribution's block is, and where it goes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Gather {
    /// Ring slot of the block, relative to the leaf's ring.
    pub ring: u32,
    /// The offset of the block within each scalar column of its block column (D × its slot), with
    /// [`Gather::FIRST`] set if it is the first (write, not add), or [`Gather::NO_TARGET`] if the
    /// other end is pinned (diagonal only).
    pub target: u32,
}

impl Gather {
    /// Flag of `target`: the first contribution to its block.
    pub const FIRST: u32 = 1 << 31;
    /// `target` of a contribution whose other end is pinned.
    pub const NO_TARGET: u32 = u32::MAX;
}

/// What a refill needs to know of one block column, in one record.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct ColumnPlan {
    /// The computes of the column's leaf up to and including this column.
    pub computes_end: u32,
    /// The number of gathers (contributions) of the column.
    pub gathers: u32,
    /// Values per scalar column: D × the number of blocks.
    pub len: u32,
    /// The offset of the diagonal block within each scalar column (D × its slot).
    pub diagonal: u32,
    /// The column's vertex (full index, for its mass).
    pub vertex: u32,
    /// Whether every gather of the column has a target and is the first to write it (no pinned
    /// other end, no parallel springs).
    pub simple: bool,
}

/// The compute and gather order of a refill over a [`BlockGraph`].
///
/// Invariants: `compute_offsets` has one entry per column and one more; the computes of each leaf
/// are consecutive, and the k-th compute of a leaf writes ring slot k mod R (R the leaf's ring
/// length, a multiple of `BATCH`); `gathers` is parallel to the graph's contributions; every gather reads a slot written by
/// a compute of its column or of an earlier column of its leaf and not overwritten since.
#[derive(Clone, Debug)]
pub(crate) struct RefillSchedule {
    /// Leaf k's ring is slots `ring_offsets[k]..ring_offsets[k + 1]` of the workspace.
    ring_offsets: Vec<usize>,
    /// Column c's computes are `computes[compute_offsets[c]..compute_offsets[c + 1]]`.
    compute_offsets: Vec<usize>,
    /// Spring indices, in compute order.
    computes: Vec<u32>,
    /// One per column.
    plans: Vec<ColumnPlan>,
    gathers: Vec<Gather>,
}

impl RefillSchedule {
    /// The schedule for blocks of size D×D. O(s) time for s springs, plus a temporary index per
    /// spring.
    ///
    /// # Panics
    /// If a column has 2³¹ values or more per scalar column (u32 offsets with a flag bit).
    pub fn new<const D: usize>(graph: &BlockGraph) -> Self {
        let columns = graph.columns();
        let leaves = graph.leaves();
        let mut ring_offsets = Vec::with_capacity(leaves.len());
        ring_offsets.push(0);
        let mut compute_offsets = Vec::with_capacity(columns + 1);
        compute_offsets.push(0);
        let mut computes = Vec::with_capacity(graph.spring_count());
        let mut gathers = vec![Gather::default(); graph.contribution_count()];
        // Per spring, the leaf-local compute index of its block while it waits for its other end.
        let mut kept = vec![u32::MAX; graph.spring_count()];
        // Per leaf-local compute index, the column of its last reader; per column, the number of
        // computes of its leaf up to and including it.
        let mut last_reader = Vec::new();
        let mut computed_by = vec![0usize; columns];
        let mut plans = Vec::with_capacity(columns);
        let free_vertices = graph.free().free_vertices();
        #[allow(clippy::needless_range_loop)] // columns index three arrays and the graph
        for leaf in leaves.windows(2) {
            let (first_column, end_column) = (leaf[0], leaf[1]);
            let leaf_start = computes.len();
            last_reader.clear();
            for column in first_column..end_column {
                let contributions = graph.contributions(column);
                let positions = graph.contribution_range(column);
                for (c, gather) in contributions.iter().zip(&mut gathers[positions]) {
                    let other = c.slot;
                    // The other end's column (the graph stores it until slots are resolved below).
                    let index = if other == Contribution::PINNED_OTHER {
                        None
                    } else {
                        Some(graph.block_rows(column)[other as usize] as usize)
                    };
                    let shared = index.filter(|o| (first_column..end_column).contains(o));
                    let k = match shared {
                        Some(o) if o < column => {
                            let k = kept[c.spring as usize];
                            debug_assert_ne!(k, u32::MAX, "kept before it is read");
                            k as usize
                        }
                        _ => {
                            let k = computes.len() - leaf_start;
                            computes.push(c.spring);
                            last_reader.push(column);
                            if shared.is_some() {
                                kept[c.spring as usize] = k as u32;
                            }
                            k
                        }
                    };
                    last_reader[k] = column;
                    gather.ring = k as u32;
                    gather.target = match index {
                        None => Gather::NO_TARGET,
                        Some(_) => (D as u32 * other) | if c.first { Gather::FIRST } else { 0 },
                    };
                }
                compute_offsets.push(computes.len());
                computed_by[column] = computes.len() - leaf_start;
                let len = D * graph.column_blocks(column).len();
                assert!(len < Gather::FIRST as usize, "column {column} too long");
                plans.push(ColumnPlan {
                    computes_end: u32::try_from(computed_by[column]).expect("u32 computes"),
                    gathers: contributions.len() as u32,
                    len: len as u32,
                    diagonal: (D * graph.diagonal_slot(column)) as u32,
                    vertex: free_vertices[column],
                    simple: contributions
                        .iter()
                        .all(|c| c.slot != Contribution::PINNED_OTHER && c.first),
                });
            }
            // Slot k is overwritten by compute k + R: it must not happen before k's last reader,
            // even when computes run up to BATCH − 1 ahead of the column that needs them. R is a
            // multiple of BATCH so that each batch writes BATCH consecutive slots.
            let ring = last_reader
                .iter()
                .enumerate()
                .map(|(k, &reader)| computed_by[reader] - k + (BATCH - 1))
                .max()
                .unwrap_or(0)
                .next_multiple_of(BATCH);
            if end_column > first_column {
                let positions = graph.contribution_range(first_column).start
                    ..graph.contribution_range(end_column - 1).end;
                for gather in &mut gathers[positions] {
                    gather.ring = (gather.ring as usize % ring) as u32;
                }
            }
            ring_offsets.push(ring_offsets.last().unwrap() + ring);
        }
        RefillSchedule {
            ring_offsets,
            compute_offsets,
            computes,
            plans,
            gathers,
        }
    }

    /// The plans of the columns `columns`.
    #[inline]
    pub fn plans(&self, columns: Range<usize>) -> &[ColumnPlan] {
        &self.plans[columns]
    }

    /// Ring slots per leaf (one entry per leaf and one more).
    pub fn ring_offsets(&self) -> &[usize] {
        &self.ring_offsets
    }

    /// Total ring slots.
    pub fn ring_len(&self) -> usize {
        *self.ring_offsets.last().expect("at least one leaf")
    }

    /// The springs whose blocks the columns `columns` compute, in order.
    #[inline]
    pub fn computes(&self, columns: Range<usize>) -> &[u32] {
        &self.computes[self.compute_range(columns)]
    }

    /// The positions in the compute list of the computes of the columns `columns`.
    #[inline]
    pub fn compute_range(&self, columns: Range<usize>) -> Range<usize> {
        self.compute_offsets[columns.start]..self.compute_offsets[columns.end]
    }

    /// The gathers of `graph`'s contributions at the positions `range`.
    #[inline]
    pub fn gathers(&self, range: Range<usize>) -> &[Gather] {
        &self.gathers[range]
    }
}
