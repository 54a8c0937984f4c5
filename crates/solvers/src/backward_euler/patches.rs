//! The nonlinear elimination of [`Relaxation::region_share`] over a fixed cover of the free
//! vertices by overlapping patches.
//!
//! Each patch is a cell of a partition of the free vertices with [`Relaxation::region_rings`]
//! rings of spring neighbours around it, and its problem (Φ as a function of the patch's
//! positions, everything else held) is built, with its symbolic factorisation, once per step
//! problem, in [`NewtonProblem::prepare_relaxation`]. An elimination then only loads the current
//! state into the patches it solves, so it allocates nothing. The cells are the graph Voronoi
//! cells (in spring hops) of seeds placed by farthest-point sampling: compact, of about equal size
//! on a uniform mesh, and made from the mesh's connectivity alone. There are
//! [`Relaxation::patch_covers`] such partitions, each next one seeded at the points farthest from
//! the seeds before, the corners of their cells.

use std::collections::VecDeque;

use hooke_assembly::FreeDofs;
use hooke_mesh::Spring;
use nalgebra::SVector;

use super::{BackwardEulerStep, REGION_NOISE_FACTOR};
use crate::newton::Failure;
use crate::{Newton, NewtonParams, NewtonProblem, NewtonReport, Relaxation, RelaxationWork};

/// No cell, or no distance yet.
const NONE: u32 = u32::MAX;

/// The patches of one step problem and the state of an elimination.
#[derive(Debug)]
pub(super) struct PatchCover<const D: usize> {
    /// The settings the cover was built for: the bits of [`Relaxation::patch_share`],
    /// [`Relaxation::patch_covers`], [`Relaxation::region_rings`] and
    /// [`Relaxation::region_iterations`].
    built_for: (u64, usize, usize, usize),
    /// One patch per cell (`None` where its symbolic analysis failed: never solved).
    patches: Vec<Option<Patch<D>>>,
    /// The patches whose cells hold each vertex (one per cover), vertex v's at
    /// `patches_of[patches_start[v]..patches_start[v + 1]]`.
    patches_of: Vec<u32>,
    patches_start: Vec<usize>,
    /// Per patch: the heat (Σ ‖∂Φ/∂x_v‖²) of the selected blocks in its cell that no patch
    /// solved so far in this elimination holds.
    patch_heat: Vec<f64>,
    /// Per vertex: whether it is a selected block that no patch solved so far holds (all false
    /// between eliminations).
    uncovered: Vec<bool>,
}

/// One patch: its problem, its inner Newton and their buffers.
#[derive(Debug)]
struct Patch<const D: usize> {
    /// Its cell (sorted free vertices).
    cell: Vec<u32>,
    /// The patch's vertices in the step problem: its own (the cell and its rings, sorted) first,
    /// then the held other ends of their springs.
    vertices: Vec<u32>,
    /// How many of `vertices` are the patch's own.
    own: usize,
    step: BackwardEulerStep<D>,
    newton: Newton,
    unknowns: Vec<f64>,
    gradient: Vec<f64>,
    /// The step problem's target, positions and dashpot start, gathered for the patch's vertices.
    y: Vec<SVector<f64, D>>,
    x: Vec<SVector<f64, D>>,
    start: Vec<SVector<f64, D>>,
    report: NewtonReport,
}

impl<const D: usize> PatchCover<D> {
    /// Whether the cover was built for the settings of `relaxation`.
    pub(super) fn is_for(&self, relaxation: &Relaxation) -> bool {
        self.built_for == settings(relaxation)
    }
}

/// The settings a cover depends on.
fn settings(relaxation: &Relaxation) -> (u64, usize, usize, usize) {
    (
        relaxation.patch_share.to_bits(),
        relaxation.patch_covers,
        relaxation.region_rings,
        relaxation.region_iterations,
    )
}

impl<const D: usize> BackwardEulerStep<D> {
    /// The free spring neighbours of vertex `v`.
    fn free_neighbours(&self, v: usize) -> impl Iterator<Item = u32> + '_ {
        self.incident[self.incident_start[v]..self.incident_start[v + 1]]
            .iter()
            .map(|&(_, other)| other)
            .filter(|&other| !self.free.is_pinned(other as usize))
    }

    /// Add `rings` rings of free spring neighbours to `region` (distinct vertices), marking them in
    /// `focus_mark`, which must hold exactly the vertices of `region` on entry; it does on return.
    pub(super) fn grow_rings(&mut self, region: &mut Vec<u32>, rings: usize) {
        let mut mark = std::mem::take(&mut self.focus_mark);
        let mut ring_start = 0;
        for _ in 0..rings {
            let ring_end = region.len();
            for i in ring_start..ring_end {
                for other in self.free_neighbours(region[i] as usize) {
                    if !mark[other as usize] {
                        mark[other as usize] = true;
                        region.push(other);
                    }
                }
            }
            ring_start = ring_end;
        }
        self.focus_mark = mark;
    }

    /// Up to `count` seeds by farthest-point sampling in spring hops over the free vertices: the
    /// first free vertex first, then each time the one farthest from all seeds so far (ties to the
    /// lower index; a vertex no seed reaches is the farthest). Deterministic; O(count × free
    /// vertices) time.
    fn seeds(&self, count: usize) -> Vec<u32> {
        let free = self.free.free_vertices();
        let mut distance = vec![NONE; self.free.vertex_count()];
        let mut seeds: Vec<u32> = Vec::with_capacity(count);
        let mut queue = VecDeque::new();
        while seeds.len() < count {
            let next = if seeds.is_empty() {
                free[0]
            } else {
                // `free` is sorted: max_by_key keeps the last maximum, so search from the back.
                let (_, v) = free
                    .iter()
                    .rev()
                    .map(|&v| (distance[v as usize], v))
                    .max_by_key(|&(d, _)| d)
                    .expect("a free vertex");
                if distance[v as usize] == 0 {
                    break; // every vertex is a seed
                }
                v
            };
            seeds.push(next);
            // Lower the distances from the new seed, as far as they drop.
            distance[next as usize] = 0;
            queue.push_back(next);
            while let Some(v) = queue.pop_front() {
                let d = distance[v as usize] + 1;
                for other in self.free_neighbours(v as usize) {
                    if distance[other as usize] > d {
                        distance[other as usize] = d;
                        queue.push_back(other);
                    }
                }
            }
        }
        seeds
    }

    /// The graph Voronoi cells of `seeds` (in spring hops over the free vertices): each free
    /// vertex in the cell of its nearest seed, by a breadth-first search from all seeds at once in
    /// seed order; a part of the mesh no seed reaches is a cell of its own. Returns the cell of
    /// every vertex (`NONE` for a pinned one).
    fn voronoi(&self, seeds: &[u32]) -> Vec<u32> {
        let free = self.free.free_vertices();
        let mut cell_of = vec![NONE; self.free.vertex_count()];
        let mut queue = VecDeque::new();
        for (c, &seed) in seeds.iter().enumerate() {
            cell_of[seed as usize] = c as u32;
            queue.push_back(seed);
        }
        loop {
            while let Some(v) = queue.pop_front() {
                let c = cell_of[v as usize];
                for other in self.free_neighbours(v as usize) {
                    if cell_of[other as usize] == NONE {
                        cell_of[other as usize] = c;
                        queue.push_back(other);
                    }
                }
            }
            let Some(&v) = free.iter().find(|&&v| cell_of[v as usize] == NONE) else {
                break;
            };
            let cell = cell_of
                .iter()
                .filter(|&&c| c != NONE)
                .max()
                .map_or(0, |&c| c + 1);
            cell_of[v as usize] = cell;
            queue.push_back(v);
        }
        cell_of
    }

    /// Build the covers of [`Relaxation::patch_share`]-sized cells with their rings
    /// ([`Relaxation::patch_covers`] of them, the seeds of each next one the points farthest from
    /// the seeds before: the corners of the cells before, so that a fold at a corner of one
    /// cover's cells lies inside a cell of the next), and each patch's problem and symbolic
    /// analysis.
    pub(super) fn build_cover(&mut self, relaxation: &Relaxation) -> PatchCover<D> {
        let free_count = self.free.free_count();
        // A share that is not positive: one cell of every free vertex.
        let cell_size = match relaxation.patch_blocks(free_count) {
            0 => free_count,
            size => size,
        };
        let per_cover = free_count.div_ceil(cell_size.max(1));
        let covers = relaxation.patch_covers.max(1);
        let seeds = if free_count == 0 {
            Vec::new()
        } else {
            self.seeds(per_cover * covers)
        };
        let mut cells: Vec<Vec<u32>> = Vec::new();
        for cover_seeds in seeds.chunks(per_cover.max(1)) {
            let cell_of = self.voronoi(cover_seeds);
            let count = cell_of
                .iter()
                .filter(|&&c| c != NONE)
                .max()
                .map_or(0, |&c| c as usize + 1);
            let first = cells.len();
            cells.resize(first + count, Vec::new());
            for &v in self.free.free_vertices() {
                cells[first + cell_of[v as usize] as usize].push(v);
            }
        }
        let patches: Vec<Option<Patch<D>>> = cells
            .into_iter()
            .map(|cell| {
                let mut own = cell.clone();
                for &v in &own {
                    self.focus_mark[v as usize] = true;
                }
                self.grow_rings(&mut own, relaxation.region_rings);
                for &v in &own {
                    self.focus_mark[v as usize] = false;
                }
                own.sort_unstable();
                self.patch(cell, own, relaxation)
            })
            .collect();
        let n = self.free.vertex_count();
        let mut patches_start = vec![0usize; n + 1];
        for patch in patches.iter().flatten() {
            for &v in &patch.cell {
                patches_start[v as usize + 1] += 1;
            }
        }
        for v in 0..n {
            patches_start[v + 1] += patches_start[v];
        }
        let mut patches_of = vec![0u32; patches_start[n]];
        let mut next = patches_start.clone();
        for (p, patch) in patches.iter().enumerate() {
            for &v in patch.iter().flat_map(|patch| &patch.cell) {
                patches_of[next[v as usize]] = p as u32;
                next[v as usize] += 1;
            }
        }
        let count = patches.len();
        PatchCover {
            built_for: settings(relaxation),
            patches,
            patches_of,
            patches_start,
            patch_heat: vec![0.0; count],
            uncovered: vec![false; n],
        }
    }

    /// The patch of the free vertices `own` (sorted): Φ as a function of their positions, the
    /// others held — a small [`BackwardEulerStep`] over the springs at `own`, whose held ends are
    /// its pinned vertices (numbered after its own), with the same masses and time step — and its
    /// inner Newton. `None` if its symbolic analysis fails.
    fn patch(
        &mut self,
        cell: Vec<u32>,
        own: Vec<u32>,
        relaxation: &Relaxation,
    ) -> Option<Patch<D>> {
        // `region_local` is NONE everywhere between calls.
        let mut local = std::mem::take(&mut self.region_local);
        let mut vertices = own.clone();
        for (k, &v) in own.iter().enumerate() {
            local[v as usize] = k as u32;
        }
        let mut springs = Vec::new();
        let mut held = Vec::new();
        for &v in &own {
            let v = v as usize;
            for &(s, other) in &self.incident[self.incident_start[v]..self.incident_start[v + 1]] {
                let o = other as usize;
                if local[o] == NONE {
                    local[o] = vertices.len() as u32;
                    held.push(vertices.len() as u32);
                    vertices.push(other);
                }
                // Each spring once: from its lower end in the patch, or from its only end there.
                if o < v && (local[o] as usize) < own.len() {
                    continue;
                }
                let spring = self.springs[s as usize];
                springs.push(Spring {
                    i: local[spring.i as usize],
                    j: local[spring.j as usize],
                    ..spring
                });
            }
        }
        for &v in &vertices {
            local[v as usize] = NONE;
        }
        self.region_local = local;
        let masses: Vec<f64> = vertices.iter().map(|&v| self.masses[v as usize]).collect();
        let free = FreeDofs::new(vertices.len(), &held).ok()?;
        let mut step = BackwardEulerStep::<D>::new(&springs, &masses, free, self.h);
        step.set_parallel(self.parallel);
        let params = NewtonParams {
            max_iterations: relaxation.region_iterations,
            factor_reuse: relaxation.inner_params().factor_reuse,
            ..NewtonParams::default()
        };
        let newton = Newton::new(step.pattern(), params).ok()?;
        let dim = step.dim();
        let m = vertices.len();
        Some(Patch {
            cell,
            own: own.len(),
            vertices,
            step,
            newton,
            unknowns: vec![0.0; dim],
            gradient: vec![0.0; dim],
            y: vec![SVector::zeros(); m],
            x: vec![SVector::zeros(); m],
            start: vec![SVector::zeros(); m],
            report: NewtonReport::with_capacity(relaxation.region_iterations),
        })
    }

    /// The elimination (see [`Relaxation::region_share`]) over `cover`, after
    /// [`BackwardEulerStep::select_hottest`] put the `count` hottest free vertices, the selected
    /// blocks, first in `focus_heat` (`total`: the sum of their heat); added to `work`. Greedily,
    /// as in a set cover: the patch whose cell holds the most heat of the selected blocks that no
    /// patch solved so far holds is solved next (ties to the lower index), and then every
    /// selected block among its own vertices counts as held, until the cells' heat counted at
    /// each choice reaches [`Relaxation::region_coverage`] of `total` (the heat in the chosen
    /// patches' rings is not counted: the rule errs towards solving one patch more). Counting a cell's heat rather than its patch's prefers the patch
    /// whose middle holds a fold over one that has the fold at its held edge. Every accepted inner
    /// step and relaxation lowers Φ, so Φ never rises; an inner solve that fails keeps its last
    /// accepted iterate (or, on non-finite values, the patch's start). A patch whose gradient is
    /// round-off is not solved (counted as skipped): there is nothing to eliminate. Allocates
    /// nothing.
    pub(super) fn eliminate(
        &mut self,
        cover: &mut PatchCover<D>,
        count: usize,
        total: f64,
        relaxation: Relaxation,
        work: &mut RelaxationWork,
    ) {
        for &(_, v) in &self.focus_heat[..count] {
            cover.uncovered[v as usize] = true;
        }
        let mut covered = 0.0;
        while covered < relaxation.region_coverage * total {
            // The uncovered heat of every patch, summed afresh (exact; the selection is small).
            cover.patch_heat.fill(0.0);
            for &(heat, v) in &self.focus_heat[..count] {
                if cover.uncovered[v as usize] {
                    let v = v as usize;
                    for &p in &cover.patches_of[cover.patches_start[v]..cover.patches_start[v + 1]]
                    {
                        cover.patch_heat[p as usize] += heat;
                    }
                }
            }
            // The hottest, ties to the lower index.
            let (mut best, mut heat) = (0, 0.0);
            for (p, &h) in cover.patch_heat.iter().enumerate() {
                if h > heat {
                    (best, heat) = (p, h);
                }
            }
            if heat <= 0.0 {
                break; // the rest of the selection is in no analysed patch
            }
            let patch = cover.patches[best]
                .as_mut()
                .expect("only analysed patches hold heat");
            match self.solve_patch(patch, relaxation) {
                PatchSolve::Solved => {
                    work.region_solves += 1;
                    work.region_blocks += patch.own;
                    work.region_iterations += patch.report.iterations;
                    work.region_factorizations += patch.report.factorizations;
                }
                PatchSolve::Skipped => work.skipped_regions += 1,
                PatchSolve::Refused => work.refused_regions += 1,
            }
            for &v in &patch.vertices[..patch.own] {
                cover.uncovered[v as usize] = false;
            }
            covered += heat;
        }
        for &(_, v) in &self.focus_heat[..count] {
            cover.uncovered[v as usize] = false;
        }
    }

    /// Load the current state into `patch`, solve it and move its own vertices in `x`; whether it
    /// was solved (not if its gradient is round-off or not finite, nor if its settings are refused).
    fn solve_patch(&mut self, patch: &mut Patch<D>, relaxation: Relaxation) -> PatchSolve {
        for (k, &v) in patch.vertices.iter().enumerate() {
            let v = v as usize;
            patch.y[k] = self.y[v];
            patch.x[k] = self.x[v];
        }
        let step = &mut patch.step;
        step.set_step(&patch.y, &patch.x, &mut patch.unknowns);
        for (k, p) in patch.x[..patch.own].iter().enumerate() {
            patch.unknowns[D * k..D * k + D].copy_from_slice(p.as_slice());
        }
        if self.dashpot > 0.0 {
            for (k, &v) in patch.vertices.iter().enumerate() {
                patch.start[k] = self.dashpot_start[v as usize];
            }
        }
        step.set_dashpot(self.dashpot, &patch.start);
        step.definiteness = self.definiteness;
        step.gradient(&patch.unknowns, &mut patch.gradient);
        let norm = patch.gradient.iter().map(|g| g * g).sum::<f64>().sqrt();
        let floor = REGION_NOISE_FACTOR * step.gradient_round_off(&patch.unknowns);
        // (A NaN norm, too: nothing finite to solve.)
        if norm.is_nan() || norm <= floor {
            return PatchSolve::Skipped;
        }
        // Valid when the relaxation came through `Relaxation::validate` (Newton's path), which
        // checks `inner_params`; raising the tolerance to the floor (finite, as norm > floor)
        // keeps it so. Only a direct `relax` call with unchecked settings meets `Refused`.
        patch.newton.params = NewtonParams {
            tolerance: relaxation.region_tolerance.max(floor / norm),
            ..relaxation.inner_params()
        };
        match patch
            .newton
            .minimize_into(step, &mut patch.unknowns, &mut patch.report)
        {
            Ok(()) | Err(Failure::LineSearchFailed) | Err(Failure::NotPositiveDefinite { .. }) => {}
            // Non-finite values or a failed factorisation: the patch keeps its start.
            Err(Failure::NonFinite | Failure::Factorization(_)) => return PatchSolve::Skipped,
            Err(Failure::InvalidParameter(_)) => return PatchSolve::Refused,
        }
        for (k, &v) in patch.vertices[..patch.own].iter().enumerate() {
            self.x[v as usize] = SVector::from_column_slice(&patch.unknowns[D * k..D * k + D]);
        }
        PatchSolve::Solved
    }
}

/// How [`BackwardEulerStep::solve_patch`] ended.
enum PatchSolve {
    /// Solved: its own vertices moved in `x`.
    Solved,
    /// Not solved: its gradient is round-off or not finite, or the inner solve met non-finite
    /// values or a failed factorisation (the patch keeps its start).
    Skipped,
    /// Not solved: the inner settings ([`Relaxation::inner_params`]) were refused.
    Refused,
}

#[cfg(test)]
mod tests {
    use hooke_assembly::FreeDofs;
    use hooke_mesh::generators;

    use crate::{BackwardEulerStep, Relaxation};

    /// Each cover's cells partition the free vertices (pinned ones in none), in the number asked
    /// for and of about equal size on a uniform cloth; each patch is its cell and its rings.
    #[test]
    fn the_covers_partition_the_free_vertices_into_compact_cells() {
        let n = 24;
        let mesh = generators::cloth(n, 1e3).unwrap();
        let pinned = [0u32, n as u32 - 1];
        let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
        let free_count = free.free_count();
        let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, 0.01);
        for (share, covers, rings) in [
            (1.0 / 16.0, 1, 0),
            (1.0 / 16.0, 2, 2),
            (0.3, 3, 1),
            (1.0, 2, 3),
        ] {
            let relaxation = Relaxation {
                patch_share: share,
                patch_covers: covers,
                region_rings: rings,
                ..Relaxation::BUCKLING
            };
            let cover = step.build_cover(&relaxation);
            assert!(cover.is_for(&relaxation));
            let cells = free_count.div_ceil(relaxation.patch_blocks(free_count));
            assert_eq!(cover.patches.len(), covers * cells, "share {share}");
            let patches: Vec<_> = cover
                .patches
                .iter()
                .map(|p| p.as_ref().expect("every patch is analysed"))
                .collect();
            for (k, group) in patches.chunks(cells).enumerate() {
                let mut count = vec![0usize; mesh.vertex_count()];
                for patch in group {
                    for &v in &patch.cell {
                        count[v as usize] += 1;
                    }
                }
                for (v, &c) in count.iter().enumerate() {
                    let expected = usize::from(!pinned.contains(&(v as u32)));
                    assert_eq!(c, expected, "cover {k}, vertex {v}");
                }
                let mean = free_count as f64 / cells as f64;
                let largest = group.iter().map(|p| p.cell.len()).max().unwrap() as f64;
                assert!(
                    largest <= 2.5 * mean,
                    "share {share}, cover {k}: largest cell {largest}"
                );
            }
            for (c, patch) in patches.iter().enumerate() {
                let own = &patch.vertices[..patch.own];
                assert!(own.windows(2).all(|w| w[0] < w[1]), "sorted and distinct");
                // Its cell, grown ring by ring.
                let mut expected = patch.cell.clone();
                for _ in 0..rings {
                    let mut next = expected.clone();
                    for spring in mesh.springs() {
                        let (i, j) = (spring.i, spring.j);
                        for (a, b) in [(i, j), (j, i)] {
                            if expected.binary_search(&a).is_ok() && !pinned.contains(&b) {
                                next.push(b);
                            }
                        }
                    }
                    next.sort_unstable();
                    next.dedup();
                    expected = next;
                }
                assert_eq!(own, &expected[..], "patch {c}");
                // Its held vertices are the other ends of its springs, outside it.
                assert!(patch.vertices[patch.own..]
                    .iter()
                    .all(|v| own.binary_search(v).is_err()));
            }
        }
    }
}
