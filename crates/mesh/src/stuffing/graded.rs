//! Graded isosurface stuffing: the paper's Section 5. The background grid is an octree of cubes,
//! finest (side h, the uniform lattice's cubes) near the surface and up to [`GRADED_MAX_LEVEL`] times
//! doubled inside and outside, balanced so that cubes that share a face, an edge or a corner differ
//! at most twofold in size. Its tetrahedra:
//!
//! - two leaf cubes of one size that share a face: the octahedron between their centres and the
//!   face, split around the centre–centre edge into four BCC tetrahedra; where a side of the face
//!   carries a midpoint (a smaller cube has a corner there), the tetrahedron on that side is
//!   bisected through it;
//! - a cube whose face meets four cubes of half its size: each quarter of the face is split along
//!   its diagonal through the face's centre, and both pyramids over it (apex the big cube's centre,
//!   and the small cube's) into two half-pyramids.
//!
//! Which cubes are finest (docs/mesher.md, "The graded variant"):
//!
//! 1. a coarse cube is split while its box comes within [`FINE_MARGIN`]·h of the surface, so the
//!    finest cubes are the 2h blocks the surface crosses, and every coarse leaf's closed box lies
//!    wholly on one side;
//! 2. the paper's rule keeps the transition tetrahedra uncut ([`enforce_uncut_transitions`]): a
//!    coarse leaf is split where a finest cube next to it has its centre on the other side;
//! 3. warping, the uniform mesher's, moves vertices of transition tetrahedra too (those on a
//!    coarse leaf's faces, and the centres of finest cubes next to one). Most shapes stay well
//!    inside the bounds whatever the warps; the half-pyramid over a finest cube's face, apex that
//!    cube's centre, does not (down to 8.4181° and up to 168.6219° at the corners of its
//!    configuration space, found by the tests' harness). So every transition tetrahedron kept with
//!    a warped vertex is checked against [`MIN_DIHEDRAL_BOUND_DEG`]–[`MAX_DIHEDRAL_BOUND_DEG`]
//!    (and for orientation), and where one fails the leaf that made it is split and the grid made
//!    again (a split changes no sign, cut point or warp: the warped vertex then has BCC tetrahedra
//!    of the uniform lattice around it, which Table 1's proof covers).
//!
//! Only the BCC tetrahedra between finest cubes are cut, by the uniform mesher's cut points and
//! stencils; the cut points, warping and so the boundary are the uniform mesher's at the same
//! spacing. Every output tetrahedron is within the row's bounds: the stencils' output by Table 1's
//! proof (the tests' harness reproduces it on graded grids), the transition tetrahedra by the
//! check above (unwarped, their fixed shapes are within 45°–120°), the all-zero ones by the same
//! filter as in the uniform mesher. A transition tetrahedron with vertices on both sides is a
//! typed error (the rule excludes it). The paper states that Table 1's bounds hold for graded
//! meshes too, except two entries of other rows (which deteriorate to 158.1918° and 147.0470°); the
//! harness finds the half-pyramids above outside the safe row's bounds when warped freely, which
//! is why the check exists.
//!
//! [`MIN_DIHEDRAL_BOUND_DEG`]: super::MIN_DIHEDRAL_BOUND_DEG
//! [`MAX_DIHEDRAL_BOUND_DEG`]: super::MAX_DIHEDRAL_BOUND_DEG

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use rayon::prelude::*;

use super::lattice::BccLattice;
use super::{
    edge_key, final_position, finish, reference_position, stencils, warp, within_bounds, Broken,
    ClosedSurface, Cut, Stuffed, Stuffing, StuffingError, StuffingOptions, ALPHA,
    MAX_DIHEDRAL_BOUND_DEG, MIN_DIHEDRAL_BOUND_DEG, PADDING,
};
use crate::{tetrahedron_signed_volume, Vec3};

/// The coarsest cubes have side 2^`GRADED_MAX_LEVEL`·h.
pub const GRADED_MAX_LEVEL: u32 = 4;

/// How close (in spacings) the surface may come to a coarse leaf (level ≥ 1) before it is split:
/// a thousandth of a spacing, so that a coarse leaf's closed box does not meet the surface and all
/// its points are on one side (its corners and centre take that side without an inside test).
/// The tolerance only has to exceed parry3d's box–triangle distance error (below, relative
/// 10⁻⁶); it costs nothing measurable. What the construction needs beyond the cubes the surface
/// crosses is not a distance but the rule of [`enforce_uncut_transitions`].
const FINE_MARGIN: f64 = 1e-3;

/// The relative safety on [`FINE_MARGIN`] for parry3d's box–triangle distance: GJK stops when its
/// bounds agree to √(10ε) ≈ 4.7·10⁻⁸ relative, and may overestimate by that much.
const GJK_SAFETY: f64 = 1e-6;

/// A leaf cube: its level (side 2^level·h) and its lowest corner in units of h.
type Cube = (u32, [i64; 3]);

/// A multiply-rotate hasher (as rustc's FxHash) for the octree's integer keys: the balancing makes
/// tens of look-ups per leaf, and the standard SipHash, built against adversarial keys, made it
/// the graded mesher's slowest step.
#[derive(Clone, Copy, Default)]
struct FastHasher(u64);

impl std::hash::Hasher for FastHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }
    fn write_u64(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(5) ^ word).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_u32(&mut self, word: u32) {
        self.write_u64(word as u64);
    }
    fn write_i64(&mut self, word: i64) {
        self.write_u64(word as u64);
    }
    fn write_usize(&mut self, word: usize) {
        self.write_u64(word as u64);
    }
}

type FastSet<T> = HashSet<T, std::hash::BuildHasherDefault<FastHasher>>;

/// The octree's leaves, by level and lowest corner.
struct Octree {
    leaves: FastSet<Cube>,
    /// The side of the surface (+1 inside, −1 outside) of the leaves that lie wholly on one side
    /// (every coarse leaf, and the finest ones in a cube found wholly on one side): their
    /// vertices need no inside test.
    sides: std::collections::HashMap<Cube, i8, std::hash::BuildHasherDefault<FastHasher>>,
    /// The domain in finest cubes per axis (a multiple of 2^GRADED_MAX_LEVEL).
    cubes: [i64; 3],
}

impl Octree {
    /// The leaf containing the point `p` (in units of h, not on a leaf's boundary), if inside the
    /// domain.
    fn leaf_at(&self, p: [f64; 3]) -> Option<Cube> {
        if (0..3).any(|a| p[a] < 0.0 || p[a] >= self.cubes[a] as f64) {
            return None;
        }
        (0..=GRADED_MAX_LEVEL).find_map(|level| {
            let size = (1i64 << level) as f64;
            let corner = p.map(|x| ((x / size).floor() * size) as i64);
            self.leaves
                .contains(&(level, corner))
                .then_some((level, corner))
        })
    }

    /// The leaf across the face of `cube` normal to `axis` (on its upper side if `outward`): the
    /// leaf containing a point just beyond the face's centre, if inside the domain.
    fn face_neighbour(&self, (level, c): Cube, axis: usize, outward: bool) -> Option<Cube> {
        let s = (1i64 << level) as f64;
        let mut probe = c.map(|x| x as f64 + 0.5 * s);
        probe[axis] += if outward {
            0.5 * s + 0.25
        } else {
            -0.5 * s - 0.25
        };
        self.leaf_at(probe)
    }

    /// Set the signs of the corners and centres of the leaves known to lie wholly on one side.
    fn side_signs(&self, lattice: &BccLattice, signs: &mut [i8]) {
        for (&cube, &side) in &self.sides {
            let (level, c) = cube;
            let s = 1i64 << level;
            for k in 0..8 {
                let p = [
                    c[0] + s * (k & 1),
                    c[1] + s * ((k >> 1) & 1),
                    c[2] + s * (k >> 2),
                ];
                signs[lattice.black_id(p.map(|x| x as usize)) as usize] = side;
            }
            signs[octree_centre(lattice, cube) as usize] = side;
        }
    }

    /// Balance: a leaf more than twice the size of a leaf it touches (face, edge or corner) is split
    /// (down to twice that size where they touch), finest leaves first. One pass per level is
    /// enough: the splits make no leaf of the level being done (their cubes are at least twice its
    /// size), so they cannot unbalance it or a finer level, and a leaf only ever gets smaller, so a
    /// probe point once in a small enough leaf stays so. (Every leaf that touches a cube contains
    /// one of its 26 probe points: in an aligned octree a larger neighbour covers the whole shared
    /// face, edge or corner.) The tests' conformity checks would see a hanging vertex.
    fn balance(&mut self) {
        for level in 0..GRADED_MAX_LEVEL {
            let mut at_level: Vec<Cube> = self
                .leaves
                .iter()
                .copied()
                .filter(|&(l, _)| l == level)
                .collect();
            at_level.sort_unstable();
            // Where a leaf touches one too big: the point beyond it, and the level it needs there.
            let too_big: Vec<([f64; 3], u32)> = at_level
                .par_iter()
                .flat_map_iter(|&(l, c)| {
                    let s = (1i64 << l) as f64;
                    let octree = &*self;
                    (0..27).filter(|&n| n != 13).filter_map(move |n| {
                        let d = [n % 3 - 1, (n / 3) % 3 - 1, n / 9 - 1];
                        let probe = [0, 1, 2]
                            .map(|a| c[a] as f64 + 0.5 * s + d[a] as f64 * (0.5 * s + 0.25));
                        octree
                            .leaf_at(probe)
                            .filter(|other| other.0 > l + 1)
                            .map(|_| (probe, l + 1))
                    })
                })
                .collect();
            // Split down to that level at once (one pass per level instead of one per halving).
            for (probe, level) in too_big {
                while let Some(cube) = self.leaf_at(probe).filter(|c| c.0 > level) {
                    self.split(cube);
                }
            }
        }
    }

    /// Split `cube` into its eight children.
    fn split(&mut self, (level, corner): Cube) {
        self.leaves.remove(&(level, corner));
        let side = self.sides.remove(&(level, corner));
        let half = 1i64 << (level - 1);
        for c in 0..8 {
            let child = [
                corner[0] + half * (c & 1),
                corner[1] + half * ((c >> 1) & 1),
                corner[2] + half * (c >> 2),
            ];
            self.leaves.insert((level - 1, child));
            if let Some(side) = side {
                self.sides.insert((level - 1, child), side);
            }
        }
    }
}

/// Fill a closed surface with tetrahedra by graded isosurface stuffing: finest (spacing
/// `options.spacing`, as [`tetrahedralize`](super::tetrahedralize)) where the surface crosses the
/// grid, coarser inside. The cut points, warping and stencils are the uniform mesher's, so the
/// boundary is the uniform mesh's at the same spacing, and every dihedral angle is within the same
/// bounds ([`MIN_DIHEDRAL_BOUND_DEG`](super::MIN_DIHEDRAL_BOUND_DEG),
/// [`MAX_DIHEDRAL_BOUND_DEG`](super::MAX_DIHEDRAL_BOUND_DEG); docs/mesher.md, "The graded
/// variant").
///
/// # Errors
/// As [`tetrahedralize`](super::tetrahedralize); [`StuffingError::BrokenInvariant`] also if a
/// transition or coarse tetrahedron has vertices on both sides of the surface (the octree's
/// refinement excludes it).
pub fn tetrahedralize_graded(
    surface: &ClosedSurface,
    options: &StuffingOptions,
) -> Result<Stuffed, StuffingError> {
    let start = Instant::now();
    options.validate()?;
    let h = options.spacing;
    let [lo, hi] = surface.bounds();
    let extent = hi - lo;
    let step = (1u64 << GRADED_MAX_LEVEL) as f64;
    // The uniform mesher's lattice (same origin, so the same points near the surface), extended at
    // its upper ends to whole coarsest cubes.
    let uniform = extent.map(|e| (e / h).ceil() + 2.0 * PADDING as f64);
    let cubes_f = uniform.map(|c| (c / step).ceil() * step);
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
    let slack = uniform * h - extent;
    let origin = lo - slack * 0.5;
    let lattice = BccLattice::new(origin, h, cubes);
    let mut octree = build_octree(surface, origin, h, cubes.map(|c| c as i64));
    enforce_uncut_transitions(&mut octree, &lattice, surface);

    // Inside tests and cut points, kept across the rounds below (a split changes neither).
    let mut known = vec![0i8; lattice.vertex_count()];
    let mut crossings: HashMap<u64, Vec3> = HashMap::new();
    let (cuts, filled, signs) = loop {
        let (fine, coarse, owners) = grid_tetrahedra(&octree, &lattice);
        // Signs of the vertices the tetrahedra use: the corners and centres of leaves wholly on
        // one side take that side; the others (near the surface) are classified one by one, as in
        // the uniform mesher.
        let mut signs = vec![0i8; lattice.vertex_count()];
        octree.side_signs(&lattice, &mut signs);
        let mut used: Vec<u32> = fine
            .iter()
            .chain(&coarse)
            .flatten()
            .copied()
            .filter(|&id| signs[id as usize] == 0 && known[id as usize] == 0)
            .collect();
        used.par_sort_unstable();
        used.dedup();
        let classified: Vec<i8> = used
            .par_iter()
            .map(|&id| {
                if surface.contains(&lattice.position(id)) {
                    1
                } else {
                    -1
                }
            })
            .collect();
        for (&id, &sign) in used.iter().zip(&classified) {
            known[id as usize] = sign;
        }
        for (sign, &k) in signs.iter_mut().zip(&known) {
            if *sign == 0 {
                *sign = k;
            }
        }
        // Cut points on the BCC tetrahedra's edges that change sign.
        let edges = cut_edges(&fine, &signs);
        let missing: Vec<(u32, u32)> = edges
            .iter()
            .copied()
            .filter(|&(a, b)| !crossings.contains_key(&edge_key(a, b)))
            .collect();
        let points: Vec<Vec3> = missing
            .par_iter()
            .map(|&(a, b)| {
                let (inside, outside) = if signs[a as usize] > 0 {
                    (a, b)
                } else {
                    (b, a)
                };
                surface.crossing(&lattice.position(inside), &lattice.position(outside))
            })
            .collect();
        for (&(a, b), point) in missing.iter().zip(points) {
            crossings.insert(edge_key(a, b), point);
        }
        let cuts: Vec<Cut> = edges
            .iter()
            .map(|&(a, b)| Cut {
                a,
                b,
                point: crossings[&edge_key(a, b)],
            })
            .collect();
        let filled =
            fill_graded(&lattice, &fine, &coarse, &mut signs, &cuts).map_err(|b| b.at(h))?;
        // A transition tetrahedron kept whole with a warped vertex is held to the bounds; where it
        // falls outside (only the half-pyramids over a finest cube's face can: docs/mesher.md), the
        // leaf that made it is split and the grid made again.
        let mut split =
            failing_transitions(&lattice, &coarse, &owners, &signs, &cuts, &filled.warped);
        if split.is_empty() {
            break (cuts, filled, signs);
        }
        split.sort_unstable();
        split.dedup();
        for cube in split {
            if octree.leaves.contains(&cube) {
                octree.split(cube);
            }
        }
        octree.balance();
        // The split cubes' children and the balancing's take their parents' sides, so the rule
        // holds again; applied anyway, it costs a pass over the finest cubes in a rare round.
        enforce_uncut_transitions(&mut octree, &lattice, surface);
    };
    let GradedFill {
        stenciled: mut tetrahedra,
        transition,
        all_zero,
        warped,
    } = filled;
    tetrahedra.extend(transition);
    // As in the uniform mesher: all-zero tetrahedra are a free choice within the bounds.
    finish(
        tetrahedra,
        all_zero,
        (&lattice, &cuts, &warped, &signs),
        surface,
        h,
        start,
    )
}

/// The leaves to split so that no transition tetrahedron kept whole with a warped vertex falls
/// outside the bounds or is inverted: for each such tetrahedron of `coarse` (signs after warping;
/// kept: an inside vertex), the leaf that made it (`owners`). Only the half-pyramids over a finest
/// cube's face (apex its centre) can fail (docs/mesher.md, "The graded variant").
fn failing_transitions(
    lattice: &BccLattice,
    coarse: &[[u32; 4]],
    owners: &[Cube],
    signs: &[i8],
    cuts: &[Cut],
    warped: &HashMap<u32, Vec3>,
) -> Vec<Cube> {
    let position = |id: u32| final_position(lattice, cuts, warped, id);
    coarse
        .par_iter()
        .zip(owners)
        .filter(|(t, _)| {
            let s = t.map(|v| signs[v as usize]);
            s.iter().any(|&x| x > 0) && s.contains(&0) && {
                let [a, b, c, d] = t.map(position);
                let [ra, rb, rc, rd] = t.map(|v| lattice.position(v));
                let reference = tetrahedron_signed_volume(&ra, &rb, &rc, &rd);
                !(tetrahedron_signed_volume(&a, &b, &c, &d) * reference.signum() > 0.0
                    && within_bounds(
                        &a,
                        &b,
                        &c,
                        &d,
                        (MIN_DIHEDRAL_BOUND_DEG, MAX_DIHEDRAL_BOUND_DEG),
                    ))
            }
        })
        .map(|(_, &owner)| owner)
        .collect()
}

/// The edges (`a < b`) of the BCC tetrahedra `fine` whose ends have opposite signs, sorted: the
/// edges that get cut points. Only BCC tetrahedra between finest cubes are ever cut.
fn cut_edges(fine: &[[u32; 4]], signs: &[i8]) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32)> = fine
        .iter()
        .flat_map(|t| {
            [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
                .map(|(i, j)| (t[i].min(t[j]), t[i].max(t[j])))
        })
        .filter(|&(a, b)| signs[a as usize] * signs[b as usize] < 0)
        .collect();
    edges.par_sort_unstable();
    edges.dedup();
    edges
}

/// What [`fill_graded`] makes: the stencils' output of the BCC tetrahedra between finest cubes,
/// the transition and coarse tetrahedra kept whole, the all-zero ones (the caller's choice), and
/// the warped positions. All oriented positively at the reference positions (before warping).
pub(crate) struct GradedFill {
    pub(crate) stenciled: Vec<[u32; 4]>,
    pub(crate) transition: Vec<[u32; 4]>,
    pub(crate) all_zero: Vec<[u32; 4]>,
    pub(crate) warped: HashMap<u32, Vec3>,
}

/// Warp, then fill: the BCC tetrahedra `fine` by the stencils, exactly as the uniform mesher fills
/// its lattice; the transition and coarse tetrahedra `coarse`, which the octree's refinement keeps
/// from having vertices on both sides (a typed error otherwise), whole where they have an inside
/// vertex (their other vertices inside or warped onto the surface), and left out where they have
/// none. A warped vertex of a transition tetrahedron moves it: the harness in the tests bounds the
/// angles this gives (docs/mesher.md, "The graded variant").
///
/// # Errors
/// A [`Broken`] invariant: from the warping or the stencils as in the uniform mesher, or a
/// transition or coarse tetrahedron with vertices on both sides.
pub(crate) fn fill_graded(
    lattice: &BccLattice,
    fine: &[[u32; 4]],
    coarse: &[[u32; 4]],
    signs: &mut [i8],
    cuts: &[Cut],
) -> Result<GradedFill, Broken> {
    let warped = warp(lattice, cuts, signs, ALPHA)?;
    let cut_index: HashMap<u64, u32> = cuts
        .iter()
        .enumerate()
        .map(|(i, c)| (edge_key(c.a, c.b), i as u32))
        .collect();
    let stuffing = Stuffing {
        lattice,
        cut_index: &cut_index,
    };
    let reference = |id: u32| reference_position(lattice, cuts, id);
    let orient = |mut t: [u32; 4]| {
        let [a, b, c, d] = t.map(reference);
        if tetrahedron_signed_volume(&a, &b, &c, &d) < 0.0 {
            t.swap(2, 3);
        }
        t
    };
    let centroid = |t: &[u32; 4]| t.iter().map(|&v| lattice.position(v)).sum::<Vec3>() / 4.0;
    let mut stenciled = Vec::new();
    let mut all_zero = Vec::new();
    for &tet in fine {
        let s = tet.map(|v| signs[v as usize]);
        if s.iter().all(|&x| x < 0) {
            continue;
        }
        if s.iter().all(|&x| x == 0) {
            all_zero.push(orient(tet));
            continue;
        }
        let first = stenciled.len();
        stencils::fill(&stuffing, tet, s, &mut stenciled).map_err(|failure| Broken {
            what: failure.describe(),
            point: centroid(&tet),
        })?;
        for t in &mut stenciled[first..] {
            *t = orient(*t);
        }
    }
    let mut transition = Vec::new();
    for &tet in coarse {
        let s = tet.map(|v| signs[v as usize]);
        let inside = s.iter().any(|&x| x > 0);
        if inside && s.iter().any(|&x| x < 0) {
            return Err(Broken {
                what: "a transition tetrahedron of the graded grid has vertices on both sides of the surface",
                point: centroid(&tet),
            });
        }
        if inside {
            transition.push(orient(tet));
        } else if s.iter().all(|&x| x == 0) {
            all_zero.push(orient(tet));
        }
    }
    Ok(GradedFill {
        stenciled,
        transition,
        all_zero,
        warped,
    })
}

/// The tetrahedra of the graded grid: the BCC ones between two finest cubes (first; the stencils
/// cut them) and the others (transition and coarse; never cut), each once, in an order that
/// depends only on the octree.
fn grid_tetrahedra(octree: &Octree, lattice: &BccLattice) -> GridTetrahedra {
    let leaves: Vec<Cube> = {
        let mut all: Vec<Cube> = octree.leaves.iter().copied().collect();
        all.sort_unstable();
        all
    };
    let corners: FastSet<[i64; 3]> = leaves
        .iter()
        .flat_map(|&(level, c)| {
            let s = 1i64 << level;
            (0..8).map(move |k| {
                [
                    c[0] + s * (k & 1),
                    c[1] + s * ((k >> 1) & 1),
                    c[2] + s * (k >> 2),
                ]
            })
        })
        .collect();
    let black = |p: [i64; 3]| lattice.black_id(p.map(|x| x as usize));
    let centre = |cube: Cube| octree_centre(lattice, cube);
    type Tetrahedra = Vec<[u32; 4]>;
    let chunks: Vec<(Tetrahedra, Tetrahedra)> = leaves
        .par_iter()
        .map(|&cube| {
            let (level, c) = cube;
            let s = 1i64 << level;
            let mut fine = Vec::new();
            let mut coarse = Vec::new();
            for axis in 0..3 {
                for outward in [false, true] {
                    let Some(neighbour) = octree.face_neighbour(cube, axis, outward) else {
                        continue;
                    };
                    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                    let mut face = c;
                    if outward {
                        face[axis] += s;
                    }
                    let at = |du: i64, dv: i64| {
                        let mut p = face;
                        p[u] += du;
                        p[v] += dv;
                        p
                    };
                    if neighbour.0 == level && outward {
                        if level == 0 {
                            let red = lattice.red_id(c.map(|x| x as usize));
                            fine.extend(lattice.tetrahedra_along(red, axis).into_iter().flatten());
                            continue;
                        }
                        let (c1, c2) = (centre(cube), centre(neighbour));
                        let sides = [
                            (at(0, 0), at(s, 0)),
                            (at(0, s), at(s, s)),
                            (at(0, 0), at(0, s)),
                            (at(s, 0), at(s, s)),
                        ];
                        for (e0, e1) in sides {
                            let m = [0, 1, 2].map(|a| (e0[a] + e1[a]) / 2);
                            if corners.contains(&m) {
                                coarse.push([black(e0), black(m), c1, c2]);
                                coarse.push([black(m), black(e1), c1, c2]);
                            } else {
                                coarse.push([black(e0), black(e1), c1, c2]);
                            }
                        }
                    } else if neighbour.0 + 1 == level {
                        // Four half-size cubes beyond: each quarter face split through the face's
                        // centre, both pyramids over it halved.
                        let half = s / 2;
                        let mid = at(half, half);
                        for (du, dv) in [(0, 0), (half, 0), (0, half), (half, half)] {
                            let q = [
                                at(du, dv),
                                at(du + half, dv),
                                at(du + half, dv + half),
                                at(du, dv + half),
                            ];
                            let far = *q
                                .iter()
                                .max_by_key(|p| (0..3).map(|a| (p[a] - mid[a]).abs()).sum::<i64>())
                                .unwrap_or(&q[0]);
                            // The quarter's two other corners: the neighbours of `far` in it.
                            let at_far = q.iter().position(|&p| p == far).unwrap_or(0);
                            let others = [q[(at_far + 1) % 4], q[(at_far + 3) % 4]];
                            let mut probe = [0, 1, 2].map(|a| (q[0][a] + q[2][a]) as f64 / 2.0);
                            probe[axis] += if outward { 0.25 } else { -0.25 };
                            let Some(small) = octree.leaf_at(probe) else {
                                continue;
                            };
                            for apex in [centre(cube), centre(small)] {
                                for &o in &others {
                                    coarse.push([black(mid), black(far), black(o), apex]);
                                }
                            }
                        }
                    }
                }
            }
            (fine, coarse)
        })
        .collect();
    let mut out = (Vec::new(), Vec::new(), Vec::new());
    for ((fine, coarse), &cube) in chunks.into_iter().zip(&leaves) {
        out.0.extend(fine);
        out.2.extend(std::iter::repeat_n(cube, coarse.len()));
        out.1.extend(coarse);
    }
    out
}

/// The graded grid's BCC tetrahedra between finest cubes, its other (transition and coarse)
/// tetrahedra, and for each of the latter the leaf that made it (whose split replaces it).
type GridTetrahedra = (Vec<[u32; 4]>, Vec<[u32; 4]>, Vec<Cube>);

/// The lattice vertex at a leaf's centre: red for a finest cube, black (a lattice corner) for a
/// coarser one.
fn octree_centre(lattice: &BccLattice, (level, c): Cube) -> u32 {
    if level == 0 {
        lattice.red_id(c.map(|x| x as usize))
    } else {
        let half = 1i64 << (level - 1);
        lattice.black_id(c.map(|x| (x + half) as usize))
    }
}

/// The rule that keeps the transition tetrahedra uncut (the paper's Section 5: a finest cube whose
/// centre and a corner differ in sign has finest neighbours across the faces at that corner).
///
/// After [`build_octree`], every coarse leaf's closed box misses the surface, so its corners and
/// centre, the corners of the transition tetrahedra on its faces, and the centres of the coarse
/// leaves next to it are all on its side. The one vertex of a transition tetrahedron that is not a
/// point of a coarse leaf's closed box is the apex of a half-pyramid over a face of a finest cube
/// next to a coarse leaf: the finest cube's centre, h/2 from the coarse leaf. Where that centre is
/// on the other side, the half-pyramid would be cut, so the coarse leaf is split (then balanced
/// again: its children, on its side, make no new case). Every transition and coarse tetrahedron
/// then has its vertices on one side; `fill_graded` checks it.
fn enforce_uncut_transitions(octree: &mut Octree, lattice: &BccLattice, surface: &ClosedSurface) {
    loop {
        let mut finest: Vec<Cube> = octree
            .leaves
            .iter()
            .copied()
            .filter(|&(l, _)| l == 0)
            .collect();
        finest.sort_unstable();
        let octree_ref = &*octree;
        let mut split: Vec<Cube> = finest
            .par_iter()
            .flat_map_iter(|&cube| {
                let coarse: Vec<Cube> = (0..6)
                    .filter_map(|n| octree_ref.face_neighbour(cube, n / 2, n % 2 == 1))
                    .filter(|c| c.0 > 0)
                    .collect();
                let sign = if coarse.is_empty() {
                    0
                } else {
                    octree_ref.sides.get(&cube).copied().unwrap_or_else(|| {
                        if surface.contains(&lattice.position(octree_centre(lattice, cube))) {
                            1
                        } else {
                            -1
                        }
                    })
                };
                coarse
                    .into_iter()
                    .filter(move |c| octree_ref.sides.get(c) != Some(&sign))
            })
            .collect();
        if split.is_empty() {
            return;
        }
        split.sort_unstable();
        split.dedup();
        for cube in split {
            if octree.leaves.contains(&cube) {
                octree.split(cube);
            }
        }
        octree.balance();
    }
}

/// The balanced octree over `cubes` finest cubes per axis (multiples of 2^GRADED_MAX_LEVEL) from
/// `origin` (m) at spacing `h` (m).
fn build_octree(surface: &ClosedSurface, origin: Vec3, h: f64, cubes: [i64; 3]) -> Octree {
    let top = 1i64 << GRADED_MAX_LEVEL;
    // Each cube to decide, with its side if an ancestor was found wholly on one side.
    let mut pending: Vec<(Cube, Option<i8>)> = Vec::new();
    for k in 0..cubes[2] / top {
        for j in 0..cubes[1] / top {
            for i in 0..cubes[0] / top {
                pending.push(((GRADED_MAX_LEVEL, [i * top, j * top, k * top]), None));
            }
        }
    }
    // Refine by distance, level by level (each level's queries in parallel). A cube is split when
    // the surface comes nearer than the margin: decided by its centre's distance when that settles
    // it (within the margin, or beyond it plus the half-diagonal), else by the box's own distance.
    // A cube whose centre is farther than its half-diagonal is wholly on one side, and so are its
    // children: their vertices then need no inside test.
    let margin = FINE_MARGIN * h;
    let mut leaves = FastSet::default();
    let mut sides = std::collections::HashMap::default();
    while !pending.is_empty() {
        let decided: Vec<(Cube, bool, Option<i8>)> = pending
            .par_iter()
            .map(|&((level, c), known)| {
                if level == 0 {
                    return ((level, c), false, known);
                }
                let s = (1i64 << level) as f64;
                let lo = origin + Vec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * h;
                let hi = lo + Vec3::new(s, s, s) * h;
                let distance = surface.signed_distance(&((lo + hi) * 0.5));
                let sign = if distance < 0.0 { 1 } else { -1 };
                let half_diagonal = 0.5 * 3.0_f64.sqrt() * s * h;
                let far = if distance.abs() < margin {
                    false
                } else if distance.abs() >= half_diagonal + margin {
                    true
                } else {
                    surface.box_distance(&lo, &hi) >= margin * (1.0 + GJK_SAFETY)
                };
                // A far cube's box does not meet the surface: its centre's side is all of it.
                let side = known.or((far || distance.abs() > half_diagonal).then_some(sign));
                ((level, c), !far, side)
            })
            .collect();
        pending = Vec::new();
        for ((level, c), split, side) in decided {
            if split {
                let half = 1i64 << (level - 1);
                for k in 0..8 {
                    let child = [
                        c[0] + half * (k & 1),
                        c[1] + half * ((k >> 1) & 1),
                        c[2] + half * (k >> 2),
                    ];
                    pending.push(((level - 1, child), side));
                }
            } else {
                leaves.insert((level, c));
                if let Some(side) = side {
                    sides.insert((level, c), side);
                }
            }
        }
    }
    let mut octree = Octree {
        leaves,
        sides,
        cubes,
    };
    octree.balance();
    octree
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stuffing::{dihedral_angles, within_bounds, MAX_DIHEDRAL_BOUND_DEG};
    use crate::stuffing::{ALPHA_LONG, ALPHA_SHORT, MIN_DIHEDRAL_BOUND_DEG};

    /// A xorshift generator: uniform numbers in [0, 1).
    struct Rng(u64);

    impl Rng {
        fn unit(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A random balanced octree over 8³ finest cubes: each 4h block is a leaf (level 2) with
    /// probability `p2`, else split, and each 2h block then a leaf (level 1) with probability
    /// `p1`, else split into finest cubes; then balanced as the mesher balances.
    fn random_octree(rng: &mut Rng, p2: f64, p1: f64) -> Octree {
        let mut octree = Octree {
            leaves: FastSet::default(),
            sides: HashMap::default(),
            cubes: [8, 8, 8],
        };
        for b in 0..8i64 {
            let corner = [4 * (b & 1), 4 * ((b >> 1) & 1), 4 * (b >> 2)];
            if rng.unit() < p2 {
                octree.leaves.insert((2, corner));
                continue;
            }
            for k in 0..8i64 {
                let sub = [
                    corner[0] + 2 * (k & 1),
                    corner[1] + 2 * ((k >> 1) & 1),
                    corner[2] + 2 * (k >> 2),
                ];
                octree.leaves.insert((1, sub));
                if rng.unit() >= p1 {
                    octree.split((1, sub));
                }
            }
        }
        octree.balance();
        octree
    }

    /// Extreme dihedral angles (°) of a set of tetrahedra, and how many there were.
    #[derive(Clone, Copy, Debug)]
    struct Range {
        min: f64,
        max: f64,
        count: usize,
    }

    impl Range {
        fn new() -> Self {
            Range {
                min: f64::INFINITY,
                max: 0.0,
                count: 0,
            }
        }
        fn add(&mut self, [a, b, c, d]: [Vec3; 4]) {
            for angle in dihedral_angles(&a, &b, &c, &d) {
                self.min = self.min.min(angle.to_degrees());
                self.max = self.max.max(angle.to_degrees());
            }
            self.count += 1;
        }
    }

    /// What [`graded_extremes`] measured.
    struct GradedExtremes {
        /// The stencils' output of the BCC tetrahedra between finest cubes.
        stencil: Range,
        /// The transition and coarse tetrahedra kept whole with at least one warped vertex.
        warped_transition: Range,
        /// All transition and coarse tetrahedra kept whole.
        transition: Range,
        /// All-zero tetrahedra (BCC or transition) outside the row's bounds or inverted.
        zero_outside: usize,
    }

    /// The harness of the uniform lattice (`harness_reproduces_table_1` in `stuffing`), on graded
    /// grids: `runs` random balanced octrees ([`random_octree`]), random signs where the
    /// mesher's construction leaves them free, and adversarial cut points, then the mesher's own
    /// warping and filling ([`fill_graded`]).
    ///
    /// The signs respect what the construction guarantees (`enforce_uncut_transitions`): every
    /// point of a coarse leaf's closed box, its centre, and the centre of every finest cube next to
    /// a coarse leaf are on one side (the run's); every other lattice vertex is inside with a
    /// probability drawn per run. Cut points are drawn as in the uniform harness: just inside or
    /// outside either threshold (t = α ∓ δ, 1 − α ± δ), at an end (δ, 1 − δ), or uniform, with
    /// δ < 10⁻⁹. Every output tetrahedron must be positively oriented after warping.
    fn graded_extremes(runs: usize, seed: u64) -> GradedExtremes {
        let mut rng = Rng(seed);
        let lattice = BccLattice::new(Vec3::zeros(), 1.0, [8, 8, 8]);
        let n = lattice.vertex_count();
        let mut out = GradedExtremes {
            stencil: Range::new(),
            warped_transition: Range::new(),
            transition: Range::new(),
            zero_outside: 0,
        };
        for _ in 0..runs {
            let p2 = 0.3 * rng.unit();
            let p1 = 0.2 + 0.6 * rng.unit();
            let octree = random_octree(&mut rng, p2, p1);
            let (fine, coarse, _) = grid_tetrahedra(&octree, &lattice);
            let side: i8 = if rng.unit() < 0.5 { 1 } else { -1 };
            let inside = 0.2 + 0.6 * rng.unit();
            let mut signs: Vec<i8> = (0..n)
                .map(|_| if rng.unit() < inside { 1 } else { -1 })
                .collect();
            for v in coarse_side_points(&octree, &lattice) {
                signs[v as usize] = side;
            }
            let cuts: Vec<Cut> = cut_edges(&fine, &signs)
                .into_iter()
                .map(|(a, b)| {
                    let long = lattice.is_red(a) == lattice.is_red(b);
                    let alpha = if long { ALPHA_LONG } else { ALPHA_SHORT };
                    let near = 1e-9 * (0.5 + 0.5 * rng.unit());
                    let t = match (10.0 * rng.unit()) as u32 {
                        0 => alpha - near,
                        1 => alpha + near,
                        2 => 1.0 - alpha + near,
                        3 => 1.0 - alpha - near,
                        4 => near,
                        5 => 1.0 - near,
                        _ => rng.unit(),
                    };
                    let (p, q) = (lattice.position(a), lattice.position(b));
                    Cut {
                        a,
                        b,
                        point: p + (q - p) * t,
                    }
                })
                .collect();
            let filled = fill_graded(&lattice, &fine, &coarse, &mut signs, &cuts)
                .unwrap_or_else(|b| panic!("{} at {:?}", b.what, b.point));
            let place =
                |t: &[u32; 4]| t.map(|id| final_position(&lattice, &cuts, &filled.warped, id));
            let positive =
                |p: &[Vec3; 4]| tetrahedron_signed_volume(&p[0], &p[1], &p[2], &p[3]) > 0.0;
            for t in &filled.stenciled {
                let p = place(t);
                assert!(positive(&p), "stencil tetrahedron {t:?} inverted");
                out.stencil.add(p);
            }
            for t in &filled.transition {
                let p = place(t);
                assert!(positive(&p), "transition tetrahedron {t:?} inverted: {p:?}");
                out.transition.add(p);
                if t.iter().any(|v| filled.warped.contains_key(v)) {
                    out.warped_transition.add(p);
                }
            }
            for t in &filled.all_zero {
                let [a, b, c, d] = place(t);
                if !(positive(&[a, b, c, d])
                    && within_bounds(
                        &a,
                        &b,
                        &c,
                        &d,
                        (MIN_DIHEDRAL_BOUND_DEG, MAX_DIHEDRAL_BOUND_DEG),
                    ))
                {
                    out.zero_outside += 1;
                }
            }
        }
        out
    }

    /// The points that the construction puts on the coarse leaves' side (docs/mesher.md, "The
    /// graded variant"): every lattice point of a coarse leaf's closed box, and the centre of every
    /// finest cube next to a coarse leaf.
    fn coarse_side_points(octree: &Octree, lattice: &BccLattice) -> FastSet<u32> {
        let mut points = FastSet::default();
        for &cube in &octree.leaves {
            let (level, c) = cube;
            if level == 0 {
                if (0..6).any(|k| {
                    octree
                        .face_neighbour(cube, k / 2, k % 2 == 1)
                        .is_some_and(|o| o.0 > 0)
                }) {
                    points.insert(octree_centre(lattice, cube));
                }
                continue;
            }
            let s = 1i64 << level;
            for k in 0..(s + 1).pow(3) {
                let p = [
                    c[0] + k % (s + 1),
                    c[1] + (k / (s + 1)) % (s + 1),
                    c[2] + k / ((s + 1) * (s + 1)),
                ];
                points.insert(lattice.black_id(p.map(|x| x as usize)));
            }
        }
        points
    }

    /// Where the warping can take a vertex of a transition tetrahedron, exhaustively at the
    /// corners of the configuration space: over `octrees` random balanced octrees, every distinct
    /// transition or coarse tetrahedron (its shape and the edges its vertices can be warped along),
    /// and every combination of its vertices' warps that leaves at least one unwarped (else it is
    /// an all-zero tetrahedron, kept only within the bounds). A vertex can be warped only along an
    /// edge of a BCC tetrahedron between finest cubes (only those are cut) to a vertex the
    /// construction leaves free to be on the other side (not a point of a coarse leaf's box or a
    /// finest centre next to one), by less than α of the edge; each vertex stays, or moves a
    /// fraction `t` of one such edge for every `t` in `fractions` (of α). Returns the range of the
    /// kept tetrahedra's dihedral angles by shape (the sorted squared edge lengths before warping,
    /// times 4, in h²), and the number of distinct tetrahedra.
    fn transition_corners(
        octrees: usize,
        fractions: &[f64],
        seed: u64,
    ) -> (std::collections::BTreeMap<Vec<i64>, Range>, usize) {
        let mut rng = Rng(seed);
        let lattice = BccLattice::new(Vec3::zeros(), 1.0, [8, 8, 8]);
        let mut seen: std::collections::HashSet<Vec<i64>> = Default::default();
        let mut shapes: std::collections::BTreeMap<Vec<i64>, Range> = Default::default();
        for _ in 0..octrees {
            let p2 = 0.3 * rng.unit();
            let p1 = 0.2 + 0.6 * rng.unit();
            let octree = random_octree(&mut rng, p2, p1);
            let (fine, coarse, _) = grid_tetrahedra(&octree, &lattice);
            let fixed = coarse_side_points(&octree, &lattice);
            let mut edges: HashMap<u32, Vec<u32>> = HashMap::new();
            for t in &fine {
                for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                    for (a, b) in [(t[i], t[j]), (t[j], t[i])] {
                        if !fixed.contains(&b) {
                            let list = edges.entry(a).or_default();
                            if !list.contains(&b) {
                                list.push(b);
                            }
                        }
                    }
                }
            }
            for tet in &coarse {
                for v in tet {
                    assert!(
                        fixed.contains(v),
                        "a transition vertex {:?} off the coarse side",
                        lattice.half_coords(*v)
                    );
                }
                let base = lattice.half_coords(tet[0]);
                let mut key = Vec::new();
                for &v in tet {
                    let h = lattice.half_coords(v);
                    key.extend((0..3).map(|a| h[a] - base[a]));
                    let mut to: Vec<[i64; 3]> = edges
                        .get(&v)
                        .map(|l| {
                            l.iter()
                                .map(|&w| {
                                    let g = lattice.half_coords(w);
                                    [g[0] - h[0], g[1] - h[1], g[2] - h[2]]
                                })
                                .collect()
                        })
                        .unwrap_or_default();
                    to.sort_unstable();
                    key.push(i64::MAX);
                    key.extend(to.into_iter().flatten());
                }
                if !seen.insert(key) {
                    continue;
                }
                let options: Vec<Vec<(Vec3, bool)>> = tet
                    .iter()
                    .map(|&v| {
                        let p = lattice.position(v);
                        let mut list = vec![(p, false)];
                        for &w in edges.get(&v).into_iter().flatten() {
                            let q = lattice.position(w);
                            let long = lattice.is_red(v) == lattice.is_red(w);
                            let alpha = if long { ALPHA_LONG } else { ALPHA_SHORT };
                            for &f in fractions {
                                list.push((p + (q - p) * (f * alpha), true));
                            }
                        }
                        list
                    })
                    .collect();
                let reference = tet.map(|v| lattice.position(v));
                let mut shape: Vec<i64> = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
                    .iter()
                    .map(|&(i, j)| {
                        (4.0 * (reference[i] - reference[j]).norm_squared()).round() as i64
                    })
                    .collect();
                shape.sort_unstable();
                let by_shape = shapes.entry(shape).or_insert_with(Range::new);
                let sign = tetrahedron_signed_volume(
                    &reference[0],
                    &reference[1],
                    &reference[2],
                    &reference[3],
                )
                .signum();
                for a in &options[0] {
                    for b in &options[1] {
                        for c in &options[2] {
                            for d in &options[3] {
                                if a.1 && b.1 && c.1 && d.1 {
                                    continue;
                                }
                                let p = [a.0, b.0, c.0, d.0];
                                let volume =
                                    sign * tetrahedron_signed_volume(&p[0], &p[1], &p[2], &p[3]);
                                assert!(volume > 0.0, "transition tetrahedron inverted: {p:?}");
                                by_shape.add(p);
                            }
                        }
                    }
                }
            }
        }
        (shapes, seen.len())
    }

    /// The transition and coarse tetrahedra with warped vertices, at the corners of the
    /// configuration space ([`transition_corners`]; the extremes are the same with 200 octrees and
    /// each warp also at ¼, ½ and ¾ of α, and with 1,500 octrees). Measured (4·squared edge
    /// lengths in h² name the shapes):
    ///
    /// - half-pyramid over a finest cube's face, apex its centre ([3, 3, 3, 4, 4, 8]):
    ///   8.418109°–168.621933°, outside the row's 9.3171°–161.6432°, so the mesher checks every
    ///   such tetrahedron it keeps with a warped vertex and splits the coarse cube where one falls
    ///   outside (`tetrahedralize_graded`);
    /// - quadrisected BCC, the half-pyramids of a 2h cube over a quarter of its face
    ///   ([4, 4, 4, 8, 8, 12]): 23.671738°–115.214552°;
    /// - bisected BCC of 2h cubes ([4, 8, 8, 12, 12, 16]): 38.660032°–103.577619°;
    /// - BCC of 2h cubes ([12, 12, 12, 12, 16, 16]): 56.484957°–102.679936°;
    /// - the shapes of 4h cubes and coarser are never warped (their vertices touch no finest
    ///   cube): 45°–120° (the half-pyramid over a 2h cube's face next to a 4h cube, apex its
    ///   centre, reaches 120°), as unwarped ones of every shape.
    ///
    /// None is inverted at any corner.
    #[test]
    fn transition_corners_are_bounded() {
        let (shapes, distinct) = transition_corners(300, &[1.0 - 1e-9], 0x2545_F491_4F6C_DD1D);
        assert!(distinct > 1000, "only {distinct} distinct tetrahedra");
        let half_pyramid = shapes[&vec![3, 3, 3, 4, 4, 8]];
        eprintln!("half-pyramid {half_pyramid:?}");
        assert!(
            (half_pyramid.min - 8.418109).abs() < 1e-5
                && (half_pyramid.max - 168.621933).abs() < 1e-5,
            "{half_pyramid:?}"
        );
        for (shape, range) in &shapes {
            eprintln!("{shape:?}: {range:?}");
            if *shape != vec![3, 3, 3, 4, 4, 8] {
                assert!(
                    range.min >= 23.671738 - 1e-5 && range.max <= 120.0 + 1e-9,
                    "{shape:?}: {range:?}"
                );
            }
        }
        let quadrisected = shapes[&vec![4, 4, 4, 8, 8, 12]];
        assert!(
            (quadrisected.min - 23.671738).abs() < 1e-5
                && (quadrisected.max - 115.214552).abs() < 1e-5,
            "{quadrisected:?}"
        );
    }

    /// On graded grids the stencils' output stays within the row's bounds and reaches them
    /// (to 10⁻⁴°, as on the uniform lattice: the cut tetrahedra are the uniform lattice's), no
    /// output tetrahedron is inverted, and no transition tetrahedron has vertices on both sides.
    /// Measured with this seed: stencils 9.317120°–161.643118°; the transition tetrahedra kept
    /// with a warped vertex (before the mesher's check) 18.794142°–154.172144° here, which random
    /// runs approach only slowly (15.708°–158.088° in 20,000 runs): [`transition_corners_are_bounded`]
    /// enumerates their extremes instead.
    #[test]
    fn harness_bounds_the_graded_grid() {
        let found = graded_extremes(4000, 0x9E37_79B9_7F4A_7C15);
        eprintln!(
            "stencils {:?}\ntransition {:?}\nwarped transition {:?}\nall-zero outside {}",
            found.stencil, found.transition, found.warped_transition, found.zero_outside
        );
        let (lo, hi) = (found.stencil.min, found.stencil.max);
        let (min, max) = (MIN_DIHEDRAL_BOUND_DEG, MAX_DIHEDRAL_BOUND_DEG);
        assert!(lo >= min - 5e-5 && hi <= max + 5e-5, "{lo}°–{hi}°");
        assert!(lo - min < 1e-4 && max - hi < 1e-4, "{lo}°–{hi}°");
        assert!(found.warped_transition.count > 10_000);
    }

    /// The worst corner of [`transition_corners_are_bounded`], built on a grid: a 2h cube with
    /// finest cubes around it, and cut points that warp three vertices of a half-pyramid over a
    /// finest cube's face (its apex and two base corners) by α − 10⁻⁹ of their edges. The check
    /// of `tetrahedralize_graded` names the 2h cube; split, the grid is all finest cubes there and
    /// every output tetrahedron is within the bounds (Table 1's configuration).
    #[test]
    fn a_half_pyramid_outside_the_bounds_splits_its_coarse_cube() {
        let lattice = BccLattice::new(Vec3::zeros(), 1.0, [8, 8, 8]);
        let coarse_cube: Cube = (1, [4, 2, 0]);
        let mut octree = Octree {
            leaves: FastSet::default(),
            sides: HashMap::default(),
            cubes: [8, 8, 8],
        };
        octree.leaves.insert(coarse_cube);
        for k in 0..512i64 {
            let c = [k % 8, (k / 8) % 8, k / 64];
            if !(4..6).contains(&c[0]) || !(2..4).contains(&c[1]) || !(0..2).contains(&c[2]) {
                octree.leaves.insert((0, c));
            }
        }
        octree.balance();
        let black = |p: [usize; 3]| lattice.black_id(p);
        let red = |c: [usize; 3]| lattice.red_id(c);
        // Outside: a corner and two cube centres; everything else inside.
        let mut original = vec![1i8; lattice.vertex_count()];
        for v in [black([7, 3, 1]), red([6, 1, 1]), red([6, 2, 2])] {
            original[v as usize] = -1;
        }
        // Warped: the base corner (6, 3, 1) along +x, the apex (6.5, 2.5, 1.5) along −y, the base
        // corner (6, 2, 2) toward (6.5, 2.5, 2.5); every other cut point at mid-edge.
        let targets = [
            (black([6, 3, 1]), black([7, 3, 1])),
            (red([6, 2, 1]), red([6, 1, 1])),
            (black([6, 2, 2]), red([6, 2, 2])),
        ];
        let cuts_for = |fine: &[[u32; 4]], signs: &[i8]| -> Vec<Cut> {
            cut_edges(fine, signs)
                .into_iter()
                .map(|(a, b)| {
                    let (inside, outside) = if signs[a as usize] > 0 {
                        (a, b)
                    } else {
                        (b, a)
                    };
                    let long = lattice.is_red(a) == lattice.is_red(b);
                    let alpha = if long { ALPHA_LONG } else { ALPHA_SHORT };
                    let t = if targets.contains(&(inside, outside)) {
                        alpha - 1e-9
                    } else {
                        0.5
                    };
                    let (p, q) = (lattice.position(inside), lattice.position(outside));
                    Cut {
                        a,
                        b,
                        point: p + (q - p) * t,
                    }
                })
                .collect()
        };
        let (fine, coarse, owners) = grid_tetrahedra(&octree, &lattice);
        let mut signs = original.clone();
        let cuts = cuts_for(&fine, &signs);
        let filled = fill_graded(&lattice, &fine, &coarse, &mut signs, &cuts).expect("fills");
        for (v, _) in targets {
            assert!(
                filled.warped.contains_key(&v),
                "{:?} not warped",
                lattice.half_coords(v)
            );
        }
        let half_pyramid = [
            black([6, 3, 1]),
            black([6, 2, 2]),
            black([6, 3, 2]),
            red([6, 2, 1]),
        ];
        let kept = filled
            .transition
            .iter()
            .find(|t| {
                let mut a = **t;
                let mut b = half_pyramid;
                a.sort_unstable();
                b.sort_unstable();
                a == b
            })
            .expect("the half-pyramid is kept");
        let [a, b, c, d] = kept.map(|v| final_position(&lattice, &cuts, &filled.warped, v));
        let mut range = Range::new();
        range.add([a, b, c, d]);
        assert!(
            (range.min - 8.418109).abs() < 1e-5 && (range.max - 168.621933).abs() < 1e-5,
            "{range:?}"
        );
        let split = failing_transitions(&lattice, &coarse, &owners, &signs, &cuts, &filled.warped);
        assert_eq!(split, vec![coarse_cube]);

        octree.split(coarse_cube);
        octree.balance();
        let (fine, coarse, owners) = grid_tetrahedra(&octree, &lattice);
        assert!(coarse.is_empty(), "all finest now");
        let mut signs = original;
        let cuts = cuts_for(&fine, &signs);
        let filled = fill_graded(&lattice, &fine, &coarse, &mut signs, &cuts).expect("fills");
        assert!(
            failing_transitions(&lattice, &coarse, &owners, &signs, &cuts, &filled.warped)
                .is_empty()
        );
        for t in filled.stenciled.iter().chain(&filled.transition) {
            let [a, b, c, d] = t.map(|v| final_position(&lattice, &cuts, &filled.warped, v));
            assert!(tetrahedron_signed_volume(&a, &b, &c, &d) > 0.0);
            assert!(within_bounds(
                &a,
                &b,
                &c,
                &d,
                (MIN_DIHEDRAL_BOUND_DEG, MAX_DIHEDRAL_BOUND_DEG)
            ));
        }
    }
}
