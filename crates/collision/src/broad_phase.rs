//! The broad phase of contact between triangle surfaces: which point–triangle and edge–edge pairs
//! of a surface are close enough that the narrow phase (the distances in [`crate::distance`], the
//! barrier in `hooke-assembly`, the collision detection in [`crate::ccd`]) must look at them.
//!
//! - [`SurfaceTopology`]: the surface's triangles, its unique edges, the points (vertices that
//!   belong to a triangle), the per-vertex adjacency, and the pairs excluded because they are
//!   already within reach at rest ([`SurfaceTopology::exclude_close_at_rest`]).
//! - [`BroadPhase`]: a reusable workspace whose [`find`](BroadPhase::find) writes the
//!   [`CandidatePairs`] whose axis-aligned boxes (at the positions, or swept along a motion) come
//!   within a reach of each other.
//!
//! **Method.** A uniform hash grid. Triangles and edges are entered into every cell their box
//! touches, grouped by cell by a counting sort through a hashed cell directory; each point and each
//! edge then reads the cells of its box grown by the reach. The cell size is the median largest
//! side of the edges' boxes plus the reach, so a typical primitive touches a few cells and a query
//! reads a few. A pair is reported only from the lowest cell that both boxes touch (three flag
//! bits per entry tell it), so it is met once, without a set or a sort of duplicates. A primitive
//! whose box touches more than [`MAX_CELLS`] cells (a fast or long one) is kept out of the grid and
//! tested by every query directly, and a query whose grown box touches more than [`MAX_CELLS`]
//! cells tests every primitive directly: the work stays bounded whatever the motion, and the
//! median keeps a few fast vertices from coarsening the grid. Cell coordinates wrap around modulo
//! 2²⁰ per axis, which is exact inside any range of fewer than 2²⁰ cells, so there is no origin to
//! choose and no far-away vertex widens the grid.
//!
//! The hash grid was chosen over parry3d's BVH: it needs no tree to rebuild or refit when
//! everything moves each step, its build is a parallel fill and one serial pass, its queries are
//! independent reads, and its result does not depend on the order of any tree's construction.
//! Measured on two 160×160 sheets 0.5 mm apart with a reach of 1 mm (release build, one thread,
//! a loaded two-core machine), parry3d's BVH (binned build and box queries) took 2.6–3.5× the
//! grid's time for the same pairs.
//!
//! **Determinism.** Queries run in parallel (rayon) over fixed blocks of query primitives; each
//! block writes its pairs in query order into its own buffer, each query's pairs sorted, and the
//! blocks are concatenated in order: the output is bit-identical to a serial run.
//!
//! What this module leaves to others: the distances of the pairs it finds, whether they are within
//! the barrier's reach d̂ (boxes within reach are a superset), the time of impact, and the choice of
//! the reach (typically d̂ for the barrier's pairs, d̂ plus the step's motion for collision detection,
//! which the `motion` argument covers exactly).
//!
//! Units: metres. Indices are `u32`: vertices index the positions, triangles index
//! [`SurfaceTopology::triangles`], edges index [`SurfaceTopology::edges`].

use nalgebra::Vector3;
use rayon::prelude::*;

/// A primitive whose box touches more grid cells than this is tested directly by every query
/// instead of being entered into the grid; a query whose reach-grown box touches more tests every
/// primitive directly. Bounds the grid's size and each query's work on fast or long primitives.
pub const MAX_CELLS: u64 = 1024;

/// Edges and triangles per surface, exclusive: a grid entry is a primitive's index times 8 plus
/// three flags in a u32.
const MAX_PRIMITIVES: usize = 1 << 29;

/// Query primitives per parallel block: the unit of work and of output buffering.
const QUERY_BLOCK: usize = 256;

/// Primitives per serial piece when the grid's entries are written in parallel.
const FILL_BLOCK: usize = 4096;

/// Bits per axis of a cell key; cell coordinates wrap modulo 2²⁰ (three axes and three flag bits
/// fill 63 bits of a u64).
const AXIS_BITS: u32 = 20;
/// The mask of one axis's bits: `i & AXIS_MASK` is i mod 2²⁰ for any i64 (two's complement).
const AXIS_MASK: i64 = (1 << AXIS_BITS) - 1;

/// An axis-aligned box (m), `lo[a] ≤ hi[a]` for finite input.
#[derive(Clone, Copy, Debug, Default)]
struct Aabb {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Aabb {
    /// The box of the segment from `x` to `x + m` (a point when m = 0).
    #[inline]
    fn swept(x: &Vector3<f64>, m: Option<&Vector3<f64>>) -> Aabb {
        let mut b = Aabb {
            lo: [x.x, x.y, x.z],
            hi: [x.x, x.y, x.z],
        };
        if let Some(m) = m {
            let end = x + m;
            for a in 0..3 {
                b.lo[a] = b.lo[a].min(end[a]);
                b.hi[a] = b.hi[a].max(end[a]);
            }
        }
        b
    }

    #[inline]
    fn union(&self, other: &Aabb) -> Aabb {
        let mut b = *self;
        for a in 0..3 {
            b.lo[a] = b.lo[a].min(other.lo[a]);
            b.hi[a] = b.hi[a].max(other.hi[a]);
        }
        b
    }

    /// The largest side (m).
    #[inline]
    fn max_extent(&self) -> f64 {
        (self.hi[0] - self.lo[0])
            .max(self.hi[1] - self.lo[1])
            .max(self.hi[2] - self.lo[2])
    }

    /// The box grown by `grow` (m) on every side.
    #[inline]
    fn grown(&self, grow: f64) -> Aabb {
        Aabb {
            lo: self.lo.map(|x| x - grow),
            hi: self.hi.map(|x| x + grow),
        }
    }

    /// Whether the closed boxes overlap.
    #[inline]
    fn overlaps(&self, other: &Aabb) -> bool {
        (0..3).all(|a| self.lo[a] <= other.hi[a] && other.lo[a] <= self.hi[a])
    }

    /// The squared Euclidean distance between two boxes (m²), 0 when they overlap.
    #[inline]
    fn distance_squared(&self, other: &Aabb) -> f64 {
        let mut sum = 0.0;
        for a in 0..3 {
            let gap = (self.lo[a] - other.hi[a])
                .max(other.lo[a] - self.hi[a])
                .max(0.0);
            sum += gap * gap;
        }
        sum
    }
}

/// The surface whose pairs the broad phase finds: triangles, unique edges, points, per-vertex
/// adjacency and the excluded pairs.
///
/// **Invariants** (established by [`SurfaceTopology::new`]): every index is below the vertex
/// count; no triangle repeats a vertex; `edges` holds each edge of a triangle once, as
/// `[a, b]` with a < b, sorted ascending; `points` is the sorted list of vertices that belong to
/// a triangle; the exclusion lists are sorted, without duplicates, and hold no pair sharing a
/// vertex.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SurfaceTopology {
    vertex_count: usize,
    triangles: Vec<[u32; 3]>,
    edges: Vec<[u32; 2]>,
    points: Vec<u32>,
    /// CSR: the edges incident to vertex v are `vertex_edges[vertex_edge_start[v]..[v + 1]]`.
    vertex_edge_start: Vec<u32>,
    vertex_edges: Vec<u32>,
    /// CSR: the triangles incident to vertex v, likewise.
    vertex_triangle_start: Vec<u32>,
    vertex_triangles: Vec<u32>,
    excluded_point_triangle: Vec<[u32; 2]>,
    excluded_edge_edge: Vec<[u32; 2]>,
}

/// Compressed rows from (row, value) pairs sorted by row: row starts (rows + 1 entries) and
/// values.
fn compressed_rows(rows: usize, pairs: &[(u32, u32)]) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; rows + 1];
    for &(r, _) in pairs {
        start[r as usize + 1] += 1;
    }
    for r in 0..rows {
        start[r + 1] += start[r];
    }
    (start, pairs.iter().map(|&(_, v)| v).collect())
}

impl SurfaceTopology {
    /// The topology of the triangles `triangles` over `vertex_count` vertices: the unique edges
    /// (sorted), the points, the incident edges and triangles of every vertex, and empty
    /// exclusion lists. Orientation is irrelevant; vertices in no triangle are not points.
    ///
    /// # Panics
    ///
    /// If a triangle has a vertex index ≥ `vertex_count` or repeats a vertex, or if there are
    /// `u32::MAX` or more vertices, or 2²⁹ or more edges or triangles (a grid entry keeps three
    /// flag bits beside the primitive's index).
    pub fn new(vertex_count: usize, triangles: &[[u32; 3]]) -> Self {
        assert!(
            vertex_count < u32::MAX as usize && triangles.len() < MAX_PRIMITIVES,
            "SurfaceTopology::new: too many vertices or triangles"
        );
        for (t, tri) in triangles.iter().enumerate() {
            assert!(
                tri.iter().all(|&v| (v as usize) < vertex_count),
                "SurfaceTopology::new: triangle {t} has a vertex index ≥ {vertex_count}"
            );
            assert!(
                tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2],
                "SurfaceTopology::new: triangle {t} repeats a vertex"
            );
        }
        let mut edges: Vec<[u32; 2]> = triangles
            .iter()
            .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        edges.sort_unstable();
        edges.dedup();
        assert!(
            edges.len() < MAX_PRIMITIVES,
            "SurfaceTopology::new: too many edges"
        );

        let mut incidence: Vec<(u32, u32)> = edges
            .iter()
            .enumerate()
            .flat_map(|(e, &[a, b])| [(a, e as u32), (b, e as u32)])
            .collect();
        incidence.sort_unstable();
        let (vertex_edge_start, vertex_edges) = compressed_rows(vertex_count, &incidence);

        let mut incidence: Vec<(u32, u32)> = triangles
            .iter()
            .enumerate()
            .flat_map(|(t, tri)| tri.map(|v| (v, t as u32)))
            .collect();
        incidence.sort_unstable();
        let (vertex_triangle_start, vertex_triangles) = compressed_rows(vertex_count, &incidence);

        let points = (0..vertex_count as u32)
            .filter(|&v| vertex_triangle_start[v as usize + 1] > vertex_triangle_start[v as usize])
            .collect();

        SurfaceTopology {
            vertex_count,
            triangles: triangles.to_vec(),
            edges,
            points,
            vertex_edge_start,
            vertex_edges,
            vertex_triangle_start,
            vertex_triangles,
            excluded_point_triangle: Vec::new(),
            excluded_edge_edge: Vec::new(),
        }
    }

    /// The number of vertices (the length `positions` must have).
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The triangles, as given to [`SurfaceTopology::new`].
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The unique edges of the triangles, `[a, b]` with a < b, sorted ascending. Edge indices in
    /// [`CandidatePairs::edge_edge`] index this slice.
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// The vertices that belong to at least one triangle, ascending: the points of the
    /// point–triangle pairs.
    pub fn points(&self) -> &[u32] {
        &self.points
    }

    /// The edges incident to vertex `v` (indices into [`SurfaceTopology::edges`]), ascending.
    ///
    /// # Panics
    ///
    /// If `v` ≥ the vertex count.
    pub fn vertex_edges(&self, v: u32) -> &[u32] {
        let v = v as usize;
        let range = self.vertex_edge_start[v] as usize..self.vertex_edge_start[v + 1] as usize;
        &self.vertex_edges[range]
    }

    /// The triangles incident to vertex `v` (indices into [`SurfaceTopology::triangles`]),
    /// ascending.
    ///
    /// # Panics
    ///
    /// If `v` ≥ the vertex count.
    pub fn vertex_triangles(&self, v: u32) -> &[u32] {
        let v = v as usize;
        let range =
            self.vertex_triangle_start[v] as usize..self.vertex_triangle_start[v + 1] as usize;
        &self.vertex_triangles[range]
    }

    /// The excluded (vertex, triangle) pairs, sorted ascending.
    pub fn excluded_point_triangle(&self) -> &[[u32; 2]] {
        &self.excluded_point_triangle
    }

    /// The excluded (edge a, edge b) pairs, a < b, sorted ascending.
    pub fn excluded_edge_edge(&self) -> &[[u32; 2]] {
        &self.excluded_edge_edge
    }

    /// Empties both exclusion lists.
    pub fn clear_exclusions(&mut self) {
        self.excluded_point_triangle.clear();
        self.excluded_edge_edge.clear();
    }

    /// Excludes from the broad phase every pair that is on the same triangle fan and already
    /// within `reach` (m) at rest, adding to the exclusion lists (sorted, without duplicates).
    ///
    /// **The rule.** A point–triangle or edge–edge pair that shares no vertex is excluded when
    ///
    /// 1. some vertex of one primitive is joined by a mesh edge to some vertex of the other (this
    ///    includes two vertices that share a triangle, whose sides are mesh edges), and
    /// 2. its distance at the rest positions `rest` (the true point–triangle or segment–segment
    ///    distance, [`crate::distance`]) is below `reach`: squared distance < reach².
    ///
    /// Why: such a pair starts inside the barrier's reach, so the barrier would push the mesh apart
    /// at rest. Neighbours of a neighbour are close only because the mesh is fine relative to the
    /// reach; the elasticity keeps them apart, not the contact. Pairs further apart on the surface
    /// are never excluded, even if close at rest (a fold in the rest shape is a real contact).
    /// Pairs sharing a vertex need no entry: [`BroadPhase::find`] never outputs them.
    ///
    /// # Panics
    ///
    /// If `rest.len()` differs from the vertex count.
    pub fn exclude_close_at_rest(&mut self, rest: &[Vector3<f64>], reach: f64) {
        assert_eq!(
            rest.len(),
            self.vertex_count,
            "exclude_close_at_rest: one rest position per vertex"
        );
        let reach_squared = reach * reach;

        let mut point_triangle = Vec::new();
        for &v in &self.points {
            for &e in self.vertex_edges(v) {
                let [a, b] = self.edges[e as usize];
                let u = if a == v { b } else { a };
                for &t in self.vertex_triangles(u) {
                    if !self.triangles[t as usize].contains(&v) {
                        point_triangle.push([v, t]);
                    }
                }
            }
        }
        point_triangle.sort_unstable();
        point_triangle.dedup();
        point_triangle.retain(|&[v, t]| {
            let [t0, t1, t2] = self.triangles[t as usize].map(|i| &rest[i as usize]);
            crate::distance::point_triangle_distance_squared(&rest[v as usize], t0, t1, t2)
                < reach_squared
        });

        let mut edge_edge = Vec::new();
        for (a, &edge) in self.edges.iter().enumerate() {
            for w in edge {
                for &e in self.vertex_edges(w) {
                    let [p, q] = self.edges[e as usize];
                    let u = if p == w { q } else { p };
                    for &b in self.vertex_edges(u) {
                        let other = self.edges[b as usize];
                        let shares = other.iter().any(|x| edge.contains(x));
                        if b as usize > a && !shares {
                            edge_edge.push([a as u32, b]);
                        }
                    }
                }
            }
        }
        edge_edge.sort_unstable();
        edge_edge.dedup();
        edge_edge.retain(|&[a, b]| {
            let [a0, a1] = self.edges[a as usize].map(|i| &rest[i as usize]);
            let [b0, b1] = self.edges[b as usize].map(|i| &rest[i as usize]);
            crate::distance::edge_edge_distance_squared(a0, a1, b0, b1) < reach_squared
        });

        for (list, new) in [
            (&mut self.excluded_point_triangle, point_triangle),
            (&mut self.excluded_edge_edge, edge_edge),
        ] {
            list.extend(new);
            list.sort_unstable();
            list.dedup();
        }
    }
}

/// The partners excluded for query primitive `q`: the second entries of the pairs `[q, _]` of a
/// sorted exclusion list, as a sorted sub-slice.
#[inline]
fn excluded_for(list: &[[u32; 2]], q: u32) -> &[[u32; 2]] {
    let start = list.partition_point(|p| p[0] < q);
    let end = start + list[start..].partition_point(|p| p[0] == q);
    &list[start..end]
}

/// The output of [`BroadPhase::find`]: candidate pairs, each list sorted ascending without
/// duplicates.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CandidatePairs {
    /// (vertex, triangle) pairs; the vertex is not a corner of the triangle.
    pub point_triangle: Vec<[u32; 2]>,
    /// (edge a, edge b) pairs with a < b, indices into [`SurfaceTopology::edges`]; the edges share
    /// no vertex.
    pub edge_edge: Vec<[u32; 2]>,
}

impl CandidatePairs {
    /// No pairs.
    pub fn new() -> Self {
        Self::default()
    }

    /// Empties both lists, keeping their storage.
    pub fn clear(&mut self) {
        self.point_triangle.clear();
        self.edge_edge.clear();
    }
}

/// The cell key of cell (i, j, k): each coordinate modulo 2²⁰, k most significant, so the cells of
/// one row (j, k) are consecutive keys in i.
#[inline]
fn cell_key(i: i64, j: i64, k: i64) -> u64 {
    (((k & AXIS_MASK) as u64) << (2 * AXIS_BITS))
        | (((j & AXIS_MASK) as u64) << AXIS_BITS)
        | ((i & AXIS_MASK) as u64)
}

/// ⌊v⌋ as an integer, saturating at the ends of i64 and 0 for NaN (what `v.floor() as i64` gives,
/// without the call to libm's floor that the default x86-64 target makes). Monotone in v.
#[inline]
fn floor(v: f64) -> i64 {
    // Truncation towards zero, corrected by one below zero; saturation keeps it monotone.
    let t = v as i64;
    t.saturating_sub(i64::from((t as f64) > v))
}

/// The grid: cell size h (through its inverse) and the map x ↦ ⌊x/h⌋, which is monotone in x, so
/// two boxes that overlap touch a common cell.
#[derive(Clone, Copy, Debug)]
struct Cells {
    inverse_size: f64,
}

impl Cells {
    /// The cells touched by `b`: the lowest and highest (i, j, k), and their number (saturating).
    #[inline]
    fn range(&self, b: &Aabb) -> ([i64; 3], [i64; 3], u64) {
        let mut lo = [0i64; 3];
        let mut hi = [0i64; 3];
        let mut count: u64 = 1;
        for a in 0..3 {
            lo[a] = floor(b.lo[a] * self.inverse_size);
            hi[a] = floor(b.hi[a] * self.inverse_size);
            let span = (hi[a] as i128 - lo[a] as i128 + 1).clamp(1, u64::MAX as i128) as u64;
            count = count.saturating_mul(span);
        }
        (lo, hi, count)
    }
}

/// One grid: primitives entered into the cells their boxes touch.
///
/// An entry is primitive · 8 + flags, where flag bit a says that the cell is the primitive's
/// lowest along axis a. A pair is reported from the lowest cell both boxes touch,
/// max(query's lowest, primitive's lowest) per axis; a cell c of both ranges is that one exactly
/// when, on every axis, c is the query's lowest or the primitive's lowest: the flags answer the
/// second half without reading the primitive.
///
/// The entries are grouped by cell by a counting sort through the cell directory (no comparison
/// sort), each cell's run in ascending primitive order, so that a query for primitives ≥ some
/// index skips the others by a binary search within the run.
#[derive(Clone, Debug, Default)]
struct Grid {
    /// (cell key · 8 + flags, primitive) in primitive order, as written by [`fill`].
    staged: Vec<(u64, u32)>,
    /// The entries (primitive · 8 + flags), grouped by cell.
    entries: Vec<u32>,
    /// Per primitive: the number of cells it is entered into (0 when it is in `large`).
    counts: Vec<u64>,
    /// Per primitive: the start of its staged entries (primitives + 1 entries).
    offsets: Vec<usize>,
    /// The primitives not in the grid (more than [`MAX_CELLS`] cells), ascending.
    large: Vec<u32>,
    /// The cell directory, an open-addressing hash table (linear probing, a power of two long,
    /// at most half full): (cell key, start, end) of each occupied cell's run of entries, or
    /// [`EMPTY`] in the key. One lookup per cell instead of a search over all entries.
    directory: Vec<(u64, usize, usize)>,
    /// The number of occupied directory slots.
    occupied: usize,
}

/// An empty slot of the cell directory (cell keys are below 2⁶⁰).
const EMPTY: u64 = u64::MAX;

/// The directory slot where the search for `cell` starts: Fibonacci hashing into `mask + 1` slots.
#[inline]
fn slot_of(cell: u64, mask: usize) -> usize {
    (cell.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 32) as usize & mask
}

impl Grid {
    /// Enters the primitives with boxes `boxes` into the grid `cells`.
    fn build(&mut self, boxes: &[Aabb], cells: Cells) {
        let n = boxes.len();
        self.counts.resize(n, 0);
        boxes
            .par_iter()
            .zip(self.counts.par_iter_mut())
            .for_each(|(b, count)| {
                let (_, _, c) = cells.range(b);
                *count = if c > MAX_CELLS { 0 } else { c };
            });
        self.offsets.clear();
        self.large.clear();
        let mut total = 0usize;
        for (p, &c) in self.counts.iter().enumerate() {
            self.offsets.push(total);
            if c == 0 {
                self.large.push(p as u32);
            }
            total += c as usize;
        }
        self.offsets.push(total);
        self.staged.resize(total, (0, 0));
        fill(
            &mut self.staged,
            boxes,
            &self.counts,
            &self.offsets,
            0..n,
            cells,
        );

        // Counting sort by cell, serial (the same layout on any number of threads): count each
        // cell's entries (the end field counts), turn the counts into starts, then place the
        // entries in primitive order (the end field is the cursor, and ends as the run's end).
        let slots = self.directory.len().max(16);
        self.directory.clear();
        self.directory.resize(slots, (EMPTY, 0, 0));
        self.occupied = 0;
        for i in 0..self.staged.len() {
            let slot = self.find_or_insert(self.staged[i].0 >> 3);
            self.directory[slot].2 += 1;
        }
        let mut start = 0;
        for slot in &mut self.directory {
            if slot.0 != EMPTY {
                let count = slot.2;
                (slot.1, slot.2) = (start, start);
                start += count;
            }
        }
        self.entries.resize(total, 0);
        let mask = self.directory.len() - 1;
        for &(key, p) in &self.staged {
            let mut slot = slot_of(key >> 3, mask);
            while self.directory[slot].0 != key >> 3 {
                slot = (slot + 1) & mask;
            }
            let cursor = &mut self.directory[slot].2;
            self.entries[*cursor] = (p << 3) | (key & 7) as u32;
            *cursor += 1;
        }
    }

    /// The directory slot of `cell`, inserted (with a zero count) if absent; doubles the
    /// directory first if it would become more than half full.
    #[inline]
    fn find_or_insert(&mut self, cell: u64) -> usize {
        let mut mask = self.directory.len() - 1;
        let mut slot = slot_of(cell, mask);
        loop {
            let key = self.directory[slot].0;
            if key == cell {
                return slot;
            }
            if key == EMPTY {
                break;
            }
            slot = (slot + 1) & mask;
        }
        if 2 * (self.occupied + 1) > self.directory.len() {
            // Rehash into twice the slots (only while the directory first grows to its size).
            let old = std::mem::take(&mut self.directory);
            self.directory.resize(2 * old.len(), (EMPTY, 0, 0));
            mask = self.directory.len() - 1;
            for entry in old.into_iter().filter(|e| e.0 != EMPTY) {
                let mut s = slot_of(entry.0, mask);
                while self.directory[s].0 != EMPTY {
                    s = (s + 1) & mask;
                }
                self.directory[s] = entry;
            }
            slot = slot_of(cell, mask);
            while self.directory[slot].0 != EMPTY {
                slot = (slot + 1) & mask;
            }
        }
        self.directory[slot] = (cell, 0, 0);
        self.occupied += 1;
        slot
    }

    /// The entries of the cell with key `cell` (empty if none).
    #[inline]
    fn cell_entries(&self, cell: u64) -> &[u32] {
        if self.directory.is_empty() {
            return &[];
        }
        let mask = self.directory.len() - 1;
        let mut slot = slot_of(cell, mask);
        loop {
            let (key, start, end) = self.directory[slot];
            if key == cell {
                return &self.entries[start..end];
            }
            if key == EMPTY {
                return &[];
            }
            slot = (slot + 1) & mask;
        }
    }

    /// Calls `visit(p)` once for every primitive p ≥ `first` whose box overlaps `query` grown by
    /// `reach` (m) and is within `reach` of it (squared box distance ≤ reach²), in an unspecified
    /// order. The overlap is tested on the same grown box whose cells are read, so every
    /// primitive that passes shares a cell with it (the cell map is monotone): the grid loses
    /// none to rounding.
    #[inline]
    fn for_each_near(
        &self,
        boxes: &[Aabb],
        cells: Cells,
        query: &Aabb,
        reach: f64,
        first: u32,
        mut visit: impl FnMut(u32),
    ) {
        let reach_squared = reach * reach;
        let grown = query.grown(reach);
        let mut test = |p: u32| {
            let b = &boxes[p as usize];
            if b.overlaps(&grown) && b.distance_squared(query) <= reach_squared {
                visit(p);
            }
        };
        let (lo, hi, count) = cells.range(&grown);
        if count > MAX_CELLS {
            (first..boxes.len() as u32).for_each(test);
            return;
        }
        let large = &self.large[self.large.partition_point(|&p| p < first)..];
        for &p in large {
            test(p);
        }
        // Fewer than 2²⁰ cells per axis here, so no two cells of the range share a key.
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    // The flags a pair must have here: away from the query's lowest cell on an
                    // axis, the cell must be the primitive's lowest on it.
                    let needs = u32::from(i != lo[0])
                        | (u32::from(j != lo[1]) << 1)
                        | (u32::from(k != lo[2]) << 2);
                    let run = self.cell_entries(cell_key(i, j, k));
                    let run = &run[run.partition_point(|&e| e >> 3 < first)..];
                    for &entry in run {
                        if entry & needs == needs {
                            test(entry >> 3);
                        }
                    }
                }
            }
        }
    }
}

/// Writes the staged entries (cell key · 8 + flags, primitive) of primitives `range` into `staged`
/// (which starts at the range's first offset), splitting the range in parallel down to
/// [`FILL_BLOCK`] primitives.
fn fill(
    staged: &mut [(u64, u32)],
    boxes: &[Aabb],
    counts: &[u64],
    offsets: &[usize],
    range: std::ops::Range<usize>,
    cells: Cells,
) {
    if range.len() > FILL_BLOCK {
        let mid = range.start + range.len() / 2;
        let (left, right) = staged.split_at_mut(offsets[mid] - offsets[range.start]);
        rayon::join(
            || fill(left, boxes, counts, offsets, range.start..mid, cells),
            || fill(right, boxes, counts, offsets, mid..range.end, cells),
        );
        return;
    }
    let mut slot = 0;
    for p in range {
        if counts[p] == 0 {
            continue;
        }
        let (lo, hi, _) = cells.range(&boxes[p]);
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    let flags = u64::from(i == lo[0])
                        | (u64::from(j == lo[1]) << 1)
                        | (u64::from(k == lo[2]) << 2);
                    staged[slot] = ((cell_key(i, j, k) << 3) | flags, p as u32);
                    slot += 1;
                }
            }
        }
    }
}

/// The broad phase's reusable workspace: boxes, the two grids and per-block output buffers.
/// After a first call of [`find`](BroadPhase::find) on a surface it allocates again only where a
/// buffer must grow (more entries or pairs than before).
#[derive(Clone, Debug, Default)]
pub struct BroadPhase {
    vertex_boxes: Vec<Aabb>,
    edge_boxes: Vec<Aabb>,
    triangle_boxes: Vec<Aabb>,
    /// Scratch: the largest side of each edge box, for the cell size.
    extents: Vec<f64>,
    triangle_grid: Grid,
    edge_grid: Grid,
    point_triangle_blocks: Vec<Vec<[u32; 2]>>,
    edge_edge_blocks: Vec<Vec<[u32; 2]>>,
}

impl BroadPhase {
    /// An empty workspace.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes into `out` (replacing its contents) the candidate pairs of `topology`: every
    /// point–triangle and edge–edge pair whose axis-aligned boxes are within `reach` (m) of each
    /// other in Euclidean distance (squared box distance ≤ reach²), where a primitive's box is the
    /// box of its vertices at `positions`, or, with `motion`, the box of its vertices' segments
    /// from x to x + motion (every position the primitive takes on the straight-line motion).
    ///
    /// Guarantees: no such pair is missing; no pair shares a vertex; no pair is in the topology's
    /// exclusion lists; both lists are sorted ascending without duplicates (edge pairs a < b);
    /// the output is the same, bit for bit, on any number of threads. Reported pairs are exactly
    /// those whose boxes pass the distance test, so there are no other false positives than the
    /// boxes' own. Non-finite positions or motions give unspecified pairs (no panic).
    ///
    /// # Panics
    ///
    /// If `positions` (or `motion`) does not have one entry per vertex, or `reach` is negative or
    /// NaN.
    pub fn find(
        &mut self,
        topology: &SurfaceTopology,
        positions: &[Vector3<f64>],
        motion: Option<&[Vector3<f64>]>,
        reach: f64,
        out: &mut CandidatePairs,
    ) {
        let n = topology.vertex_count;
        assert_eq!(
            positions.len(),
            n,
            "BroadPhase::find: one position per vertex"
        );
        if let Some(m) = motion {
            assert_eq!(m.len(), n, "BroadPhase::find: one motion per vertex");
        }
        assert!(reach >= 0.0, "BroadPhase::find: reach must be ≥ 0 (m)");
        out.clear();
        if topology.triangles.is_empty() {
            return;
        }

        let BroadPhase {
            vertex_boxes,
            edge_boxes,
            triangle_boxes,
            extents,
            triangle_grid,
            edge_grid,
            point_triangle_blocks,
            edge_edge_blocks,
        } = self;

        vertex_boxes.resize(n, Aabb::default());
        vertex_boxes
            .par_iter_mut()
            .enumerate()
            .for_each(|(v, b)| *b = Aabb::swept(&positions[v], motion.map(|m| &m[v])));
        let vertex_boxes = &vertex_boxes[..];
        edge_boxes.resize(topology.edges.len(), Aabb::default());
        edge_boxes
            .par_iter_mut()
            .zip(topology.edges.par_iter())
            .for_each(|(b, &[p, q])| {
                *b = vertex_boxes[p as usize].union(&vertex_boxes[q as usize]);
            });
        triangle_boxes.resize(topology.triangles.len(), Aabb::default());
        triangle_boxes
            .par_iter_mut()
            .zip(topology.triangles.par_iter())
            .for_each(|(b, t)| {
                let [p, q, r] = t.map(|v| &vertex_boxes[v as usize]);
                *b = p.union(q).union(r);
            });

        // Cell size: the median largest side of the edge boxes plus the reach. Any positive size
        // is correct; this one keeps typical primitives to a few cells each, and a few fast
        // vertices (whose boxes leave the grid) cannot coarsen it, as they would a mean. The
        // median is one value whatever the thread count.
        extents.resize(edge_boxes.len(), 0.0);
        extents
            .par_iter_mut()
            .zip(edge_boxes.par_iter())
            .for_each(|(e, b)| *e = b.max_extent());
        let middle = extents.len() / 2;
        let (_, median, _) = extents.select_nth_unstable_by(middle, f64::total_cmp);
        let mut size = *median + reach;
        if !(size > 0.0 && size.is_finite()) {
            size = 1.0;
        }
        let cells = Cells {
            inverse_size: 1.0 / size,
        };

        triangle_grid.build(triangle_boxes, cells);
        edge_grid.build(edge_boxes, cells);
        let (triangle_boxes, edge_boxes) = (&triangle_boxes[..], &edge_boxes[..]);

        let points = &topology.points;
        let blocks = points.len().div_ceil(QUERY_BLOCK);
        if point_triangle_blocks.len() < blocks {
            point_triangle_blocks.resize_with(blocks, Vec::new);
        }
        point_triangle_blocks[..blocks]
            .par_iter_mut()
            .enumerate()
            .for_each(|(block, buffer)| {
                buffer.clear();
                let end = ((block + 1) * QUERY_BLOCK).min(points.len());
                for &v in &points[block * QUERY_BLOCK..end] {
                    let start = buffer.len();
                    let excluded = excluded_for(&topology.excluded_point_triangle, v);
                    let query = &vertex_boxes[v as usize];
                    triangle_grid.for_each_near(triangle_boxes, cells, query, reach, 0, |t| {
                        if !topology.triangles[t as usize].contains(&v)
                            && excluded.binary_search_by_key(&t, |p| p[1]).is_err()
                        {
                            buffer.push([v, t]);
                        }
                    });
                    buffer[start..].sort_unstable();
                }
            });
        for buffer in &point_triangle_blocks[..blocks] {
            out.point_triangle.extend_from_slice(buffer);
        }

        let edges = &topology.edges;
        let blocks = edges.len().div_ceil(QUERY_BLOCK);
        if edge_edge_blocks.len() < blocks {
            edge_edge_blocks.resize_with(blocks, Vec::new);
        }
        edge_edge_blocks[..blocks]
            .par_iter_mut()
            .enumerate()
            .for_each(|(block, buffer)| {
                buffer.clear();
                let end = ((block + 1) * QUERY_BLOCK).min(edges.len());
                for a in (block * QUERY_BLOCK) as u32..end as u32 {
                    let start = buffer.len();
                    let excluded = excluded_for(&topology.excluded_edge_edge, a);
                    let [a0, a1] = edges[a as usize];
                    let query = &edge_boxes[a as usize];
                    edge_grid.for_each_near(edge_boxes, cells, query, reach, a + 1, |b| {
                        let [b0, b1] = edges[b as usize];
                        if a0 != b0
                            && a0 != b1
                            && a1 != b0
                            && a1 != b1
                            && excluded.binary_search_by_key(&b, |p| p[1]).is_err()
                        {
                            buffer.push([a, b]);
                        }
                    });
                    buffer[start..].sort_unstable();
                }
            });
        for buffer in &edge_edge_blocks[..blocks] {
            out.edge_edge.extend_from_slice(buffer);
        }
    }
}
