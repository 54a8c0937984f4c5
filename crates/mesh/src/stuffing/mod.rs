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
//!    lattice) and is warped onto its nearest violating cut point.
//! 4. The stencils fill each lattice tetrahedron by the signs of its vertices.
//!
//! With these parameters the paper proves every output dihedral angle is between 10.7° and
//! 164.8°. A lattice tetrahedron whose four vertices were all warped onto the surface is a free
//! choice, made only among those within the angle bounds: first by its centroid (kept if inside),
//! then by the manifold repair (module `manifold`), so that the boundary is a closed 2-manifold or
//! the call fails with [`StuffingError::UnresolvedFeature`]. The output is deterministic: the same
//! for any number of threads.
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
/// than the spacing would pinch the boundary.
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
    let warped = warp(&lattice, &cuts, &mut signs);

    let cut_index: HashMap<u64, u32> = cuts
        .iter()
        .enumerate()
        .map(|(i, c)| (edge_key(c.a, c.b), i as u32))
        .collect();
    let lattice_count = lattice.vertex_count() as u32;
    let position = |id: u32| -> Vec3 {
        if id >= lattice_count {
            cuts[(id - lattice_count) as usize].point
        } else {
            warped
                .get(&id)
                .copied()
                .unwrap_or_else(|| lattice.position(id))
        }
    };
    let stuffing = Stuffing {
        lattice: &lattice,
        cut_index: &cut_index,
    };
    let black = lattice.black_count() as u32;
    // The stencils' output, and apart from it the lattice tetrahedra whose four vertices were all
    // warped onto the surface: those are chosen below.
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
    let stenciled: Vec<[u32; 4]> = stenciled.into_iter().flatten().collect();
    // An all-zero tetrahedron may be kept only within the angle bounds; the centroid rule makes the
    // first choice, and the manifold repair the last.
    let candidates: Vec<[u32; 4]> = all_zero
        .into_iter()
        .flatten()
        .filter(|t| {
            let [a, b, c, d] = t.map(position);
            within_bounds(&a, &b, &c, &d)
        })
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

/// Warp every violated lattice vertex onto its nearest violating cut point and set its sign to 0,
/// visiting vertices in index order (a warped vertex's edges lose their cut points, which can
/// relieve later vertices). Returns the warped positions.
fn warp(lattice: &BccLattice, cuts: &[Cut], signs: &mut [i8]) -> HashMap<u32, Vec3> {
    let h = lattice.spacing();
    let short = 0.5 * 3.0_f64.sqrt() * h;
    let mut incident: Vec<(u32, u32)> = Vec::with_capacity(2 * cuts.len());
    for (i, c) in cuts.iter().enumerate() {
        incident.push((c.a, i as u32));
        incident.push((c.b, i as u32));
    }
    incident.sort_unstable();
    let mut warped = HashMap::new();
    let mut start = 0;
    while start < incident.len() {
        let v = incident[start].0;
        let mut end = start;
        let mut best: Option<(f64, Vec3)> = None;
        let here = lattice.position(v);
        while end < incident.len() && incident[end].0 == v {
            let cut = &cuts[incident[end].1 as usize];
            let other = if cut.a == v { cut.b } else { cut.a };
            end += 1;
            if signs[other as usize] == 0 {
                continue; // the other end was warped: this cut point is gone
            }
            let long = lattice.is_red(v) == lattice.is_red(other);
            let threshold = if long {
                ALPHA_LONG * h
            } else {
                ALPHA_SHORT * short
            };
            let distance = (cut.point - here).norm();
            if distance < threshold && best.is_none_or(|(d, _)| distance < d) {
                best = Some((distance, cut.point));
            }
        }
        if let Some((_, point)) = best {
            signs[v as usize] = 0;
            warped.insert(v, point);
        }
        start = end;
    }
    warped
}
