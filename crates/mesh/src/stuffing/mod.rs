//! Tetrahedral meshing of closed surfaces by isosurface stuffing (F. Labelle and J. R. Shewchuk,
//! "Isosurface stuffing: fast tetrahedral meshes with good dihedral angles", SIGGRAPH 2007).
//!
//! The steps, each in its own module:
//!
//! 1. [`ClosedSurface::new`] checks the triangle surface (closed, manifold, consistently
//!    oriented; inside-out is turned outward) and builds parry3d's triangle mesh for queries.
//! 2. A body-centred cubic lattice of spacing h covers the surface's bounding box; every lattice
//!    vertex is classified inside or outside (in parallel, by blocks: a block far from the surface
//!    takes the sign of its centre).
//! 3. Every lattice edge whose ends are on opposite sides gets a cut point, where the surface
//!    crosses it. A lattice vertex closer to a cut point than α·(edge length) is *violated*
//!    (α = 0.24999 on long edges, 0.41189 on short ones, the paper's values for the uniform
//!    lattice) and is warped onto its nearest violating cut point, one vertex at a time (a warped
//!    vertex's cut points are discarded), in an order such that no vertex is warped toward a
//!    vertex that is warped too (see `warp`).
//! 4. The stencils fill each lattice tetrahedron by the signs of its vertices.
//!
//! With these parameters the paper proves every output dihedral angle is between 10.7° and
//! 164.8°. Warping in index order broke that (a vertex warped onto the cut point of an edge whose
//! other end was then warped elsewhere: 10.28° on a torus), and even with the ordered warping some
//! configurations the rules allow give a stencil tetrahedron just outside the bounds (10.56° next
//! to a sphere of radius 2.3 h, from an unwarped vertex 0.05 h from the surface whose cut points
//! all lie just beyond the thresholds). So every stencil tetrahedron is checked, and where one is
//! outside the bounds an unwarped vertex of it is warped onto its nearest cut point and the
//! lattice filled again (`keep_angle_bounds`); what that cannot clear is refused with
//! [`StuffingError::AngleBound`], never returned. A lattice tetrahedron whose four vertices were
//! all warped onto the surface is a free choice, made only among those within the angle bounds:
//! first by its centroid (kept if inside), then by the manifold repair (module `manifold`), so that
//! the boundary is a closed 2-manifold or the call fails with [`StuffingError::UnresolvedFeature`].
//! The output is deterministic: the same for any number of threads.
//!
//! ```
//! use hooke_mesh::stuffing::{tetrahedralize, ClosedSurface, StuffingOptions};
//! use hooke_mesh::{TriMesh, Vec3};
//!
//! // A unit cube, outward-facing triangles.
//! let corners: Vec<Vec3> = (0..8)
//!     .map(|c| Vec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, (c >> 2) as f64))
//!     .collect();
//! let triangles = vec![
//!     [0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
//!     [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5],
//! ];
//! let surface = ClosedSurface::new(&TriMesh::new(corners, triangles)?)?;
//! let stuffed = tetrahedralize(&surface, &StuffingOptions::new(0.1)?)?;
//! assert!(stuffed.report.min_dihedral_deg > 10.7);
//! assert!((stuffed.report.volume - 1.0).abs() < 0.05);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod error;
mod lattice;
mod manifold;
mod quality;
mod stencils;
mod surface;

use std::collections::HashMap;
use std::time::Instant;

use rayon::prelude::*;

pub use error::StuffingError;
pub use quality::{
    dihedral_angles, hausdorff_distance, quality_report, radius_ratio, QualityReport,
};
pub use surface::ClosedSurface;

use lattice::BccLattice;
use stencils::StencilLattice;

use crate::{tetrahedron_signed_volume, TetMesh, Vec3};

/// Violation threshold on long (axis-aligned, length h) lattice edges, as a fraction of the edge:
/// Labelle and Shewchuk's value for the uniform BCC lattice.
pub const ALPHA_LONG: f64 = 0.24999;
/// Violation threshold on short (diagonal, length √3/2·h) lattice edges, as a fraction of the edge.
pub const ALPHA_SHORT: f64 = 0.41189;
/// The smallest dihedral angle the paper proves for the uniform lattice with these thresholds (°).
pub const MIN_DIHEDRAL_BOUND_DEG: f64 = 10.7;
/// The largest dihedral angle the paper proves for the uniform lattice with these thresholds (°).
pub const MAX_DIHEDRAL_BOUND_DEG: f64 = 164.8;

/// Cubes per side of the blocks that are classified at once when far from the surface.
const BLOCK: usize = 8;
/// Empty cubes between the surface's bounding box and the lattice's edge on every side, so that
/// the lattice's outer vertices are all outside.
const PADDING: usize = 2;

/// Parameters of [`tetrahedralize`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StuffingOptions {
    /// Lattice spacing h (m): the side of the lattice's cubes, the length of its long edges. Output
    /// edges are between about 0.2·h and 1.1·h long. Positive and finite.
    pub spacing: f64,
    /// The most lattice vertices the mesher may use (it needs about 2·(bounding box)/h³, plus a
    /// padding of two cubes per side); a larger lattice is refused before anything is allocated.
    /// Default 2·10⁸ (about 1 GB of working memory at most).
    pub max_lattice_vertices: u64,
}

impl StuffingOptions {
    /// Options with the given spacing (m) and the default limit.
    ///
    /// # Errors
    /// [`StuffingError::InvalidParameter`] if the spacing is not positive and finite.
    pub fn new(spacing: f64) -> Result<Self, StuffingError> {
        let options = StuffingOptions {
            spacing,
            max_lattice_vertices: 200_000_000,
        };
        options.validate()?;
        Ok(options)
    }

    /// Check every field's range.
    ///
    /// # Errors
    /// [`StuffingError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<(), StuffingError> {
        if !(self.spacing.is_finite() && self.spacing > 0.0) {
            return Err(StuffingError::InvalidParameter {
                name: "spacing",
                value: self.spacing.to_string(),
                reason: "the lattice spacing must be positive and finite (m)",
            });
        }
        if self.max_lattice_vertices == 0 {
            return Err(StuffingError::InvalidParameter {
                name: "max_lattice_vertices",
                value: "0".into(),
                reason: "the limit must be at least 1",
            });
        }
        Ok(())
    }
}

/// A tetrahedral mesh of a closed surface, and its quality report.
#[derive(Clone, Debug)]
pub struct Stuffed {
    /// The mesh; every tetrahedron positively oriented.
    pub mesh: TetMesh,
    /// Its quality, with the surface's volume and the Hausdorff distance to it, and the time taken.
    pub report: QualityReport,
}

/// A cut point: where the surface crosses the lattice edge `a`–`b` (`a < b`).
#[derive(Clone, Copy, Debug)]
struct Cut {
    a: u32,
    b: u32,
    point: Vec3,
}

/// The lattice and its cut points, as the stencils see them.
struct Stuffing<'a> {
    lattice: &'a BccLattice,
    cut_index: &'a HashMap<u64, u32>,
}

fn edge_key(a: u32, b: u32) -> u64 {
    ((a.min(b) as u64) << 32) | a.max(b) as u64
}

impl StencilLattice for Stuffing<'_> {
    fn cut(&self, a: u32, b: u32) -> u32 {
        // Every +/− edge of a lattice tetrahedron has a cut point: they were made from the same
        // signs, and warping only turns signs to zero.
        self.lattice.vertex_count() as u32 + self.cut_index[&edge_key(a, b)]
    }
    fn half_coords(&self, id: u32) -> [i64; 3] {
        self.lattice.half_coords(id)
    }
    fn is_red(&self, id: u32) -> bool {
        self.lattice.is_red(id)
    }
}

/// Whether every dihedral angle of the tetrahedron is within the paper's bounds.
fn within_bounds(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> bool {
    dihedral_angles(a, b, c, d).iter().all(|angle| {
        (MIN_DIHEDRAL_BOUND_DEG..=MAX_DIHEDRAL_BOUND_DEG).contains(&angle.to_degrees())
    })
}

/// Where vertex `id` of the stuffed mesh is: a cut point (ids past the lattice's vertices), a
/// lattice vertex warped onto a cut point, or a lattice vertex where it is.
fn vertex_position(
    id: u32,
    lattice: &BccLattice,
    cuts: &[Cut],
    warped: &HashMap<u32, Vec3>,
) -> Vec3 {
    let lattice_count = lattice.vertex_count() as u32;
    if id >= lattice_count {
        cuts[(id - lattice_count) as usize].point
    } else {
        warped
            .get(&id)
            .copied()
            .unwrap_or_else(|| lattice.position(id))
    }
}

/// [`within_bounds`] of tetrahedron `t`, its vertices placed by `position`.
fn tet_within_bounds(t: &[u32; 4], position: impl Fn(u32) -> Vec3) -> bool {
    let [a, b, c, d] = t.map(position);
    within_bounds(&a, &b, &c, &d)
}

/// Fill a closed surface with tetrahedra by isosurface stuffing on a BCC lattice of spacing
/// `options.spacing`.
///
/// The result's boundary lies on the surface (its vertices are cut points or warped lattice
/// vertices, on the surface); its dihedral angles are within the paper's bounds.
///
/// # Errors
/// [`StuffingError::InvalidParameter`] for bad options, [`StuffingError::LatticeTooLarge`] if the
/// lattice would exceed `options.max_lattice_vertices`, [`StuffingError::NoTetrahedra`] if the
/// solid is too thin for the spacing, [`StuffingError::UnresolvedFeature`] if a feature thinner
/// than the spacing would pinch the boundary, [`StuffingError::AngleBound`] if a tetrahedron
/// outside the angle bounds survives the extra warping (not seen on any test surface).
pub fn tetrahedralize(
    surface: &ClosedSurface,
    options: &StuffingOptions,
) -> Result<Stuffed, StuffingError> {
    let start = Instant::now();
    options.validate()?;
    let h = options.spacing;
    let [lo, hi] = surface.bounds();
    let extent = hi - lo;
    let cubes_f = extent.map(|e| (e / h).ceil() + 2.0 * PADDING as f64);
    // Vertex indices are u32 with room for the cut points; the count is estimated in floating point
    // first so that a tiny spacing cannot overflow the integer arithmetic (it saturates to +inf).
    let limit = options.max_lattice_vertices.min((u32::MAX / 2) as u64);
    let estimate = (cubes_f.x + 1.0) * (cubes_f.y + 1.0) * (cubes_f.z + 1.0)
        + cubes_f.x * cubes_f.y * cubes_f.z;
    if estimate.is_nan() || estimate > limit as f64 {
        return Err(StuffingError::LatticeTooLarge {
            spacing: h,
            vertices: estimate as u64,
            limit,
        });
    }
    let cubes = [cubes_f.x as usize, cubes_f.y as usize, cubes_f.z as usize];
    // Centre the surface's box in the lattice.
    let slack = Vec3::new(cubes[0] as f64, cubes[1] as f64, cubes[2] as f64) * h - extent;
    let lattice = BccLattice::new(lo - slack * 0.5, h, cubes);

    let mut signs = classify(&lattice, surface);
    let cuts = cut_points(&lattice, surface, &signs);
    let mut warped = warp(&lattice, &cuts, &mut signs);

    let cut_index: HashMap<u64, u32> = cuts
        .iter()
        .enumerate()
        .map(|(i, c)| (edge_key(c.a, c.b), i as u32))
        .collect();
    let (stenciled, all_zero) =
        keep_angle_bounds(&lattice, &cuts, &cut_index, &mut signs, &mut warped).map_err(
            |(point, min, max)| StuffingError::AngleBound {
                point: point.into(),
                min_deg: min,
                max_deg: max,
                spacing: h,
            },
        )?;
    let lattice_count = lattice.vertex_count() as u32;
    let position = |id: u32| vertex_position(id, &lattice, &cuts, &warped);
    // An all-zero tetrahedron may be kept only within the angle bounds; the centroid rule makes the
    // first choice, and the manifold repair the last.
    let candidates: Vec<[u32; 4]> = all_zero
        .into_iter()
        .filter(|t| tet_within_bounds(t, position))
        .collect();
    let mut kept: Vec<bool> = candidates
        .iter()
        .map(|t| {
            let [a, b, c, d] = t.map(position);
            surface.contains(&((a + b + c + d) / 4.0))
        })
        .collect();
    manifold::choose_all_zero(&stenciled, &candidates, &mut kept, |v| {
        v < lattice_count && signs[v as usize] == 0
    })
    .map_err(|v| StuffingError::UnresolvedFeature {
        point: position(v).into(),
        spacing: h,
    })?;
    let chunks = [
        stenciled,
        candidates
            .into_iter()
            .zip(kept)
            .filter_map(|(t, k)| k.then_some(t))
            .collect(),
    ];

    // Keep the vertices the tetrahedra use, numbered in lattice-then-cut order.
    let total = lattice.vertex_count() + cuts.len();
    let mut new_index = vec![u32::MAX; total];
    for tet in chunks.iter().flatten() {
        for &v in tet {
            new_index[v as usize] = 0;
        }
    }
    let mut positions = Vec::new();
    for (id, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = positions.len() as u32;
            positions.push(position(id as u32));
        }
    }
    let tetrahedra: Vec<[u32; 4]> = chunks
        .into_iter()
        .flatten()
        .map(|t| {
            let mut t = t.map(|v| new_index[v as usize]);
            let [a, b, c, d] = t.map(|v| &positions[v as usize]);
            if tetrahedron_signed_volume(a, b, c, d) < 0.0 {
                t.swap(2, 3);
            }
            t
        })
        .collect();
    if tetrahedra.is_empty() {
        return Err(StuffingError::NoTetrahedra { spacing: h });
    }
    let mesh = TetMesh::new(positions, tetrahedra)?;
    let seconds = start.elapsed().as_secs_f64();
    let mut report = quality_report(&mesh, None);
    report.surface_volume = Some(surface.enclosed_volume());
    report.seconds = seconds;
    Ok(Stuffed { mesh, report })
}

/// Check a triangle surface ([`ClosedSurface::new`]) and fill it ([`tetrahedralize`]) at lattice
/// spacing `spacing` (m) with the default limits: what a scene file's `fill = { spacing = … }` does.
///
/// # Errors
/// As [`ClosedSurface::new`], [`StuffingOptions::new`] and [`tetrahedralize`].
pub fn fill_surface(mesh: &crate::TriMesh, spacing: f64) -> Result<Stuffed, StuffingError> {
    let options = StuffingOptions::new(spacing)?;
    tetrahedralize(&ClosedSurface::new(mesh)?, &options)
}

/// +1 inside, −1 outside, for every lattice vertex. Blocks of `BLOCK`³ cubes whose bounding ball
/// misses the surface take the sign of their centre; the others are classified vertex by vertex.
fn classify(lattice: &BccLattice, surface: &ClosedSurface) -> Vec<i8> {
    let cubes = lattice.cubes();
    let blocks = cubes.map(|c| c / BLOCK + 1);
    let h = lattice.spacing();
    let origin = lattice.position(0);
    let radius = 0.5 * 3.0_f64.sqrt() * (BLOCK as f64 + 1.0) * h;
    let block_signs: Vec<Option<i8>> = (0..blocks[0] * blocks[1] * blocks[2])
        .into_par_iter()
        .map(|b| {
            let index = [
                b % blocks[0],
                (b / blocks[0]) % blocks[1],
                b / (blocks[0] * blocks[1]),
            ];
            let centre = origin
                + Vec3::new(
                    ((index[0] * BLOCK) as f64 + 0.5 * BLOCK as f64) * h,
                    ((index[1] * BLOCK) as f64 + 0.5 * BLOCK as f64) * h,
                    ((index[2] * BLOCK) as f64 + 0.5 * BLOCK as f64) * h,
                );
            let distance = surface.signed_distance(&centre);
            (distance.abs() > radius).then_some(if distance < 0.0 { 1 } else { -1 })
        })
        .collect();
    (0..lattice.vertex_count() as u32)
        .into_par_iter()
        .map(|id| {
            let [i, j, k] = lattice.indices(id).map(|c| c / BLOCK);
            let block = i + blocks[0] * (j + blocks[1] * k);
            block_signs[block].unwrap_or_else(|| {
                if surface.contains(&lattice.position(id)) {
                    1
                } else {
                    -1
                }
            })
        })
        .collect()
}

/// The cut points of every lattice edge with ends of opposite signs, in a fixed order (by the edge's
/// owner vertex, then the edge's slot).
fn cut_points(lattice: &BccLattice, surface: &ClosedSurface, signs: &[i8]) -> Vec<Cut> {
    // Slots per vertex: 3 long edges (+x, +y, +z) for every vertex, and 8 short edges to the
    // corners for a red one.
    const SLOTS: usize = 11;
    let edge = |id: u32, slot: usize| -> Option<(u32, u32)> {
        let other = if slot < 3 {
            lattice.step(id, slot)?
        } else if lattice.is_red(id) {
            lattice.corners(id)[slot - 3]
        } else {
            return None;
        };
        (signs[id as usize] * signs[other as usize] < 0).then_some((id, other))
    };
    (0..lattice.vertex_count() * SLOTS)
        .into_par_iter()
        .filter_map(|e| edge((e / SLOTS) as u32, e % SLOTS))
        .map(|(p, q)| {
            let (inside, outside) = if signs[p as usize] > 0 {
                (p, q)
            } else {
                (q, p)
            };
            let point = surface.crossing(&lattice.position(inside), &lattice.position(outside));
            Cut {
                a: p.min(q),
                b: p.max(q),
                point,
            }
        })
        .collect()
}

/// A violation: (violated vertex, other end of the edge, distance, cut point index).
type Violation = (u32, u32, f64, u32);

/// Warp the violated lattice vertices onto cut points and set their signs to 0. Returns the warped
/// positions.
///
/// A cut point *violates* the end of its edge that it is closer to than α·(edge length) (it cannot
/// violate both, α < ½). Warping a vertex discards the cut points on its edges, which relieves the
/// vertices they violated, so which vertices end up warped depends on the order: the paper warps
/// one violated vertex at a time, onto its nearest violating cut point that is still there. Taken
/// in index order, a vertex could be warped onto the cut point of its edge to a neighbour that was
/// then warped elsewhere (still violated by another cut point): both ends of that lattice edge
/// moved, and the torus of `tests/tetrahedralize.rs` got a 10.28° lattice tetrahedron from it (one
/// black vertex moved 0.40 of the way to a red one, which moved 0.41 of a short edge away, with
/// the second red vertex warped too). The order here rules that out: the violations form a
/// directed graph (v → w when the cut point on v–w violates v), and the unwarped vertices are a
/// kernel of it (no violation between two unwarped vertices, every warped vertex violated toward
/// an unwarped one), which exists because the graph is bipartite (violations join opposite signs).
/// It is found by retrograde analysis: a vertex with no violation left stays unwarped, and a vertex
/// violated toward an unwarped one is warped (which takes its cut points away from the vertices
/// violated toward it); the vertices this leaves undecided lie on even cycles of violations, where
/// every inside vertex stays and every outside one is warped. Each warped vertex goes to its
/// nearest violating cut point toward an unwarped vertex (its other cut points are discarded, as
/// warping their other ends first would do). This is the paper's one-at-a-time warping in an order
/// that depends only on the cut points, so it is deterministic. It does not by itself keep every
/// stencil tetrahedron within the bounds: [`keep_angle_bounds`] checks them.
fn warp(lattice: &BccLattice, cuts: &[Cut], signs: &mut [i8]) -> HashMap<u32, Vec3> {
    let h = lattice.spacing();
    let short = 0.5 * 3.0_f64.sqrt() * h;
    // Violations as (violated vertex, other end, distance, cut), and the same by other end.
    let mut arcs: Vec<Violation> = Vec::new();
    for (i, c) in cuts.iter().enumerate() {
        let long = lattice.is_red(c.a) == lattice.is_red(c.b);
        let threshold = if long {
            ALPHA_LONG * h
        } else {
            ALPHA_SHORT * short
        };
        for (v, w) in [(c.a, c.b), (c.b, c.a)] {
            let distance = (c.point - lattice.position(v)).norm();
            if distance < threshold {
                arcs.push((v, w, distance, i as u32));
            }
        }
    }
    if arcs.is_empty() {
        return HashMap::new();
    }
    // Local numbering of the vertices in violations, in index order.
    let mut ids: Vec<u32> = arcs.iter().flat_map(|a| [a.0, a.1]).collect();
    ids.sort_unstable();
    ids.dedup();
    let local = |v: u32| ids.binary_search(&v).unwrap_or(0);
    let n = ids.len();
    // Out-arcs (violations of a vertex) and in-arcs, as CSR lists.
    let csr = |key: &dyn Fn(&Violation) -> usize| -> (Vec<usize>, Vec<usize>) {
        let mut start = vec![0usize; n + 1];
        for a in &arcs {
            start[key(a) + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut list = vec![0usize; arcs.len()];
        for (j, a) in arcs.iter().enumerate() {
            let k = key(a);
            list[fill[k]] = j;
            fill[k] += 1;
        }
        (start, list)
    };
    let (out_start, out_list) = csr(&|a| local(a.0));
    let (in_start, in_list) = csr(&|a| local(a.1));

    #[derive(Clone, Copy, PartialEq)]
    enum State {
        Undecided,
        Stays,
        Warped,
    }
    let mut state = vec![State::Undecided; n];
    // Violations of each vertex toward vertices not (yet) known to be warped.
    let mut live: Vec<usize> = (0..n).map(|v| out_start[v + 1] - out_start[v]).collect();
    let mut queue: std::collections::VecDeque<usize> = (0..n).filter(|&v| live[v] == 0).collect();
    for &v in &queue {
        state[v] = State::Stays;
    }
    while let Some(u) = queue.pop_front() {
        // Everything violated toward u is warped (u stays).
        for &j in &in_list[in_start[u]..in_start[u + 1]] {
            let p = local(arcs[j].0);
            if state[p] != State::Undecided {
                continue;
            }
            state[p] = State::Warped;
            // p's cut points are discarded: the vertices violated toward p lose that violation.
            for &k in &in_list[in_start[p]..in_start[p + 1]] {
                let q = local(arcs[k].0);
                live[q] -= 1;
                if live[q] == 0 && state[q] == State::Undecided {
                    state[q] = State::Stays;
                    queue.push_back(q);
                }
            }
        }
    }
    for (v, s) in state.iter_mut().enumerate() {
        if *s == State::Undecided {
            *s = if signs[ids[v] as usize] > 0 {
                State::Stays
            } else {
                State::Warped
            };
        }
    }

    let mut warped = HashMap::new();
    for v in 0..n {
        if state[v] != State::Warped {
            continue;
        }
        let best = out_list[out_start[v]..out_start[v + 1]]
            .iter()
            .map(|&j| arcs[j])
            .filter(|a| state[local(a.1)] == State::Stays)
            .min_by(|x, y| x.2.total_cmp(&y.2).then(x.3.cmp(&y.3)));
        let Some((_, _, _, cut)) = best else {
            debug_assert!(
                false,
                "a warped vertex without a violation toward a kept one"
            );
            continue;
        };
        signs[ids[v] as usize] = 0;
        warped.insert(ids[v], cuts[cut as usize].point);
    }
    debug_assert!(arcs
        .iter()
        .all(|a| { state[local(a.0)] == State::Warped || state[local(a.1)] == State::Warped }));
    warped
}

/// The stencils' output, and the all-zero lattice tetrahedra.
type Filled = (Vec<[u32; 4]>, Vec<[u32; 4]>);

/// The stencils' output for every lattice tetrahedron with an inside vertex, and apart from it the
/// lattice tetrahedra whose four vertices were all warped onto the surface (the caller's choice).
fn fill_lattice(lattice: &BccLattice, cut_index: &HashMap<u64, u32>, signs: &[i8]) -> Filled {
    let stuffing = Stuffing { lattice, cut_index };
    let black = lattice.black_count() as u32;
    let lattice_count = lattice.vertex_count() as u32;
    type Chunks = Vec<Vec<[u32; 4]>>;
    let (stenciled, all_zero): (Chunks, Chunks) = (black..lattice_count)
        .into_par_iter()
        .fold(
            || (Vec::new(), Vec::new()),
            |(mut out, mut zero), red| {
                for axis in 0..3 {
                    for tet in lattice.tetrahedra_along(red, axis).into_iter().flatten() {
                        let s = tet.map(|v| signs[v as usize]);
                        if s.iter().all(|&x| x < 0) {
                            continue;
                        }
                        if s.iter().all(|&x| x == 0) {
                            zero.push(tet);
                            continue;
                        }
                        let split = stencils::fill(&stuffing, tet, s, &mut out);
                        debug_assert!(split, "a prism with cyclic diagonals in {tet:?}");
                    }
                }
                (out, zero)
            },
        )
        .unzip();
    (
        stenciled.into_iter().flatten().collect(),
        all_zero.into_iter().flatten().collect(),
    )
}

/// Rounds of extra warping [`keep_angle_bounds`] may make before it gives up.
const ANGLE_REPAIR_ROUNDS: usize = 8;

/// Fill the lattice ([`fill_lattice`]) and make sure every stenciled tetrahedron is within the
/// angle bounds.
///
/// Lattice configurations that the warping rule allows can still give stencil tetrahedra outside
/// the bounds. Measured: a sphere of radius 2.3 h (exact cut points, on a small test lattice) gave
/// 10.56°, a tetrahedron of the one-inside-one-outside stencil whose unwarped inside vertex lies
/// 0.05 h from the surface with its cut point 0.256 of a long edge away (just beyond α), next to
/// two red vertices warped 0.41 of a short edge. The paper's proof should exclude this, and which
/// of its rules does is not known here; so, where such a tetrahedron appears, the unwarped lattice
/// vertex of it nearest (relative to the edge's length) to one of its remaining cut points is
/// warped onto that cut point as well, and the lattice is filled again. This goes beyond the
/// paper: the extra warp moves a vertex farther than α. Warping more only discards cut points, so
/// still no remaining cut point violates a vertex, and every new tetrahedron is checked in the
/// next round. Returns the stencils' output and the all-zero tetrahedra, or (the centroid of a bad
/// tetrahedron, its smallest and largest dihedral angles in degrees) when
/// [`ANGLE_REPAIR_ROUNDS`] rounds do not clear them.
fn keep_angle_bounds(
    lattice: &BccLattice,
    cuts: &[Cut],
    cut_index: &HashMap<u64, u32>,
    signs: &mut [i8],
    warped: &mut HashMap<u32, Vec3>,
) -> Result<Filled, (Vec3, f64, f64)> {
    let lattice_count = lattice.vertex_count() as u32;
    let mut incident: HashMap<u32, Vec<u32>> = HashMap::new();
    for (i, c) in cuts.iter().enumerate() {
        incident.entry(c.a).or_default().push(i as u32);
        incident.entry(c.b).or_default().push(i as u32);
    }
    for round in 0.. {
        let (stenciled, all_zero) = fill_lattice(lattice, cut_index, signs);
        let position = |id: u32| vertex_position(id, lattice, cuts, warped);
        let bad: Vec<[u32; 4]> = stenciled
            .par_iter()
            .filter(|t| !tet_within_bounds(t, position))
            .copied()
            .collect();
        let Some(first) = bad.first() else {
            return Ok((stenciled, all_zero));
        };
        let failure = || {
            let [a, b, c, d] = first.map(position);
            let angles = dihedral_angles(&a, &b, &c, &d).map(f64::to_degrees);
            (
                (a + b + c + d) / 4.0,
                angles.iter().copied().fold(f64::INFINITY, f64::min),
                angles.iter().copied().fold(0.0, f64::max),
            )
        };
        if round == ANGLE_REPAIR_ROUNDS {
            return Err(failure());
        }
        // For each bad tetrahedron, its unwarped lattice vertex nearest (relative to the edge) to a
        // remaining cut point, and that cut point.
        let frozen: &[i8] = signs;
        let mut extra: Vec<(u32, u32)> = bad
            .iter()
            .filter_map(|t| {
                t.iter()
                    .filter(|&&v| v < lattice_count && frozen[v as usize] != 0)
                    .flat_map(|&v| {
                        incident
                            .get(&v)
                            .into_iter()
                            .flatten()
                            .filter_map(move |&i| {
                                let c = &cuts[i as usize];
                                let other = if c.a == v { c.b } else { c.a };
                                (frozen[other as usize] != 0).then(|| {
                                    let here = lattice.position(v);
                                    let ratio = (c.point - here).norm()
                                        / (lattice.position(other) - here).norm();
                                    (ratio, v, i)
                                })
                            })
                    })
                    .min_by(|x, y| x.0.total_cmp(&y.0).then((x.1, x.2).cmp(&(y.1, y.2))))
                    .map(|(_, v, i)| (v, i))
            })
            .collect();
        extra.sort_unstable();
        extra.dedup_by_key(|e| e.0);
        if extra.is_empty() {
            return Err(failure());
        }
        for (v, i) in extra {
            // An earlier warp of this round may have taken the cut point away.
            let c = &cuts[i as usize];
            let other = if c.a == v { c.b } else { c.a };
            if signs[v as usize] != 0 && signs[other as usize] != 0 {
                signs[v as usize] = 0;
                warped.insert(v, c.point);
            }
        }
    }
    unreachable!("the loop returns")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every lattice edge once, as (owner, other end).
    fn edges(lattice: &BccLattice) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for id in 0..lattice.vertex_count() as u32 {
            out.extend(
                (0..3)
                    .filter_map(|axis| lattice.step(id, axis))
                    .map(|o| (id, o)),
            );
            if lattice.is_red(id) {
                out.extend(lattice.corners(id).map(|o| (id, o)));
            }
        }
        out
    }

    /// Random signs and cut points on a small lattice, a third of the cut points within 10⁻⁶ of a
    /// violation threshold on either side: configurations of any isosurface, more adversarial than
    /// smooth surfaces give. The warping leaves no cut point violating a vertex and warps no vertex
    /// toward one that is warped too; the stencils' output is within the angle bounds (the
    /// ordered warping alone leaves 288 of these 4000 runs with a stencil tetrahedron outside them,
    /// each cleared by one round of extra warping).
    #[test]
    fn adversarial_configurations_stay_within_the_bounds() {
        let lattice = BccLattice::new(Vec3::zeros(), 1.0, [3, 3, 3]);
        let n = lattice.vertex_count();
        let all_edges = edges(&lattice);
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        let mut unit = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..4000 {
            let inside = 0.2 + 0.6 * unit();
            let mut signs: Vec<i8> = (0..n)
                .map(|_| if unit() < inside { 1 } else { -1 })
                .collect();
            let mut cuts = Vec::new();
            for &(id, o) in &all_edges {
                if signs[id as usize] * signs[o as usize] >= 0 {
                    continue;
                }
                let long = lattice.is_red(id) == lattice.is_red(o);
                let alpha = if long { ALPHA_LONG } else { ALPHA_SHORT };
                let near = 1e-6 * unit();
                let t = match (6.0 * unit()) as u32 {
                    0 => alpha - near,
                    1 => alpha + near,
                    2 => 1.0 - alpha + near,
                    3 => 1.0 - alpha - near,
                    _ => unit(),
                };
                let (p, q) = (lattice.position(id), lattice.position(o));
                cuts.push(Cut {
                    a: id.min(o),
                    b: id.max(o),
                    point: p + (q - p) * t,
                });
            }
            let original = signs.clone();
            let mut warped = warp(&lattice, &cuts, &mut signs);
            for c in &cuts {
                let (a, b) = (c.a as usize, c.b as usize);
                let length = (lattice.position(c.b) - lattice.position(c.a)).norm();
                let alpha = if lattice.is_red(c.a) == lattice.is_red(c.b) {
                    ALPHA_LONG
                } else {
                    ALPHA_SHORT
                };
                if signs[a] != 0 && signs[b] != 0 {
                    for v in [c.a, c.b] {
                        let d = (c.point - lattice.position(v)).norm();
                        assert!(d >= alpha * length, "a cut point left violating {v}");
                    }
                }
            }
            for (&v, point) in &warped {
                assert_ne!(original[v as usize], 0);
                let target = cuts
                    .iter()
                    .find(|c| (c.a == v || c.b == v) && c.point == *point)
                    .map(|c| if c.a == v { c.b } else { c.a })
                    .expect("warped onto a cut point of its own edge");
                assert_ne!(
                    signs[target as usize], 0,
                    "{v} warped toward warped {target}"
                );
            }
            let cut_index: HashMap<u64, u32> = cuts
                .iter()
                .enumerate()
                .map(|(i, c)| (edge_key(c.a, c.b), i as u32))
                .collect();
            let (stenciled, _) =
                keep_angle_bounds(&lattice, &cuts, &cut_index, &mut signs, &mut warped)
                    .unwrap_or_else(|(p, lo, hi)| panic!("{lo}°–{hi}° at {p:?}"));
            let position = |id: u32| vertex_position(id, &lattice, &cuts, &warped);
            for t in &stenciled {
                assert!(tet_within_bounds(t, position), "{t:?}");
            }
        }
    }
}
