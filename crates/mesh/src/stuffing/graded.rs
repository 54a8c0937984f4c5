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
//! A coarse cube is split while the surface comes within h/2 + 0.35671·h of it (`fine_margin`,
//! which derives the figure: h/2 is how far the half-pyramids reach into a finest cube, 0.35671·h
//! how far warping moves a vertex), decided by its box's distance to the surface. So the surface
//! crosses finest cubes only (up to the coarse cubes' edge), and every tetrahedron that meets it,
//! and every vertex that warping moves, belongs to BCC tetrahedra of the uniform lattice: the
//! uniform lattice's cut points, warping (same thresholds) and stencils apply to them unchanged,
//! and Table 1's proof covers them as it covers the uniform mesh. The coarser tetrahedra are
//! entirely inside (kept whole) or outside (dropped). That is checked, not assumed: a coarse
//! tetrahedron with vertices on both sides, or a warped vertex, is a typed error. The paper
//! (Section 5) also cuts and warps the transition tetrahedra (bisected BCC, half-pyramids), so that
//! only the cubes the surface crosses need be finest; this mesher does not (no harness here bounds
//! the stencils on those shapes), which costs the h/2 + 0.357h band. The paper states that Table
//! 1's bounds hold for graded meshes too, except for two entries of other rows (which deteriorate
//! to 158.1918° and 147.0470°); for the row in use the bounds are [`MIN_DIHEDRAL_BOUND_DEG`] and
//! [`MAX_DIHEDRAL_BOUND_DEG`], and the coarse tetrahedra's fixed shapes lie well inside them (BCC
//! 60°–90°, bisected BCC 45°–90°, half-pyramids 45°–90° and 45°–120°).
//!
//! [`MIN_DIHEDRAL_BOUND_DEG`]: super::MIN_DIHEDRAL_BOUND_DEG
//! [`MAX_DIHEDRAL_BOUND_DEG`]: super::MAX_DIHEDRAL_BOUND_DEG

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use rayon::prelude::*;

use super::lattice::BccLattice;
use super::{
    add_all_zero, assemble, edge_key, final_position, quality_report, reference_position, stencils,
    warp, Broken, ClosedSurface, Cut, Stuffed, Stuffing, StuffingError, StuffingOptions, ALPHA,
    PADDING,
};
use crate::{tetrahedron_signed_volume, Vec3};

/// The coarsest cubes have side 2^`GRADED_MAX_LEVEL`·h.
pub const GRADED_MAX_LEVEL: u32 = 4;

/// How close (in spacings) the surface may come to a coarse leaf (level ≥ 1): nearer, the leaf is
/// split. Derived so that no coarse tetrahedron meets the surface or has a vertex that warping
/// can move:
///
/// - a warped vertex moves onto a cut point of one of its lattice edges, closer than α times the
///   edge: at most `max(α_long·h, α_short·(√3/2)·h)` = 0.35671·h, so it lies that close to the
///   surface (`warp_reach`);
/// - the coarse tetrahedra (all but the BCC ones between two finest cubes) lie in the coarse
///   leaves, except the half-pyramids whose apex is the centre of a finest cube next to a coarse
///   one: those reach h/2 into the finest cube, so every coarse tetrahedron lies within h/2 of a
///   coarse leaf.
///
/// A coarse leaf at least `h/2 + warp_reach` from the surface thus keeps every coarse tetrahedron
/// at least `warp_reach` away: it does not meet the surface (its vertices are on one side) and no
/// warped vertex is one of its vertices. The surface can cross any finest cube, including those
/// next to coarse ones (the paper refines only the cubes it crosses; the h/2 + 0.357h here is what
/// keeping the cut, the warping and the stencils on BCC tetrahedra costs). Checked, not assumed:
/// a coarse tetrahedron with vertices on both sides (or warped) is a typed error.
fn fine_margin() -> f64 {
    let warp_reach = ALPHA.long.max(ALPHA.short * 0.75_f64.sqrt());
    0.5 + warp_reach
}

/// The relative safety on [`fine_margin`] for parry3d's box–triangle distance: GJK stops when its
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
/// `options.spacing`, as [`tetrahedralize`](super::tetrahedralize)) at the surface, coarser inside.
/// The boundary is the same as the uniform mesh's at that spacing (same cut points, warping and
/// stencils there); the angle bounds are the same.
///
/// # Errors
/// As [`tetrahedralize`](super::tetrahedralize); [`StuffingError::BrokenInvariant`] also if a
/// coarse tetrahedron meets the surface.
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
    let octree = build_octree(surface, origin, h, cubes.map(|c| c as i64));

    // The tetrahedra: BCC ones between finest cubes (for the stencils) and the coarse ones.
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
    let centre = |(level, c): Cube| -> u32 {
        if level == 0 {
            lattice.red_id(c.map(|x| x as usize))
        } else {
            let half = 1i64 << (level - 1);
            black(c.map(|x| x + half))
        }
    };
    type Chunks = Vec<Vec<[u32; 4]>>;
    let (fine, coarse): (Chunks, Chunks) = leaves
        .par_iter()
        .map(|&cube| {
            let (level, c) = cube;
            let s = 1i64 << level;
            let mut fine = Vec::new();
            let mut coarse = Vec::new();
            for axis in 0..3 {
                for outward in [false, true] {
                    // A point just beyond the face's centre finds the neighbour.
                    let mut probe = c.map(|x| x as f64 + 0.5 * s as f64);
                    probe[axis] += if outward {
                        0.5 * s as f64 + 0.25
                    } else {
                        -0.5 * s as f64 - 0.25
                    };
                    let Some(neighbour) = octree.leaf_at(probe) else {
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
        .unzip();
    let fine: Vec<[u32; 4]> = fine.into_iter().flatten().collect();
    let coarse: Vec<[u32; 4]> = coarse.into_iter().flatten().collect();

    // Signs of the vertices the tetrahedra use.
    let mut used: Vec<u32> = fine.iter().chain(&coarse).flatten().copied().collect();
    used.par_sort_unstable();
    used.dedup();
    // The corners and centres of leaves wholly on one side take that side; the others (near the
    // surface) are classified one by one, as in the uniform mesher.
    let mut signs = vec![0i8; lattice.vertex_count()];
    for &cube in &leaves {
        if let Some(&side) = octree.sides.get(&cube) {
            let (level, c) = cube;
            let s = 1i64 << level;
            for k in 0..8 {
                signs[black([
                    c[0] + s * (k & 1),
                    c[1] + s * ((k >> 1) & 1),
                    c[2] + s * (k >> 2),
                ]) as usize] = side;
            }
            signs[centre(cube) as usize] = side;
        }
    }
    let used: Vec<u32> = used
        .into_iter()
        .filter(|&id| signs[id as usize] == 0)
        .collect();
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
        signs[id as usize] = sign;
    }
    // Cut points on the BCC tetrahedra's edges that change sign.
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
    let cuts: Vec<Cut> = edges
        .par_iter()
        .map(|&(a, b)| {
            let (inside, outside) = if signs[a as usize] > 0 {
                (a, b)
            } else {
                (b, a)
            };
            Cut {
                a,
                b,
                point: surface.crossing(&lattice.position(inside), &lattice.position(outside)),
            }
        })
        .collect();
    let warped = warp(&lattice, &cuts, &mut signs, ALPHA).map_err(|b| b.at(h))?;
    let cut_index: HashMap<u64, u32> = cuts
        .iter()
        .enumerate()
        .map(|(i, c)| (edge_key(c.a, c.b), i as u32))
        .collect();
    let stuffing = Stuffing {
        lattice: &lattice,
        cut_index: &cut_index,
    };
    let reference = |id: u32| reference_position(&lattice, &cuts, id);
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
    for &tet in &fine {
        let s = tet.map(|v| signs[v as usize]);
        if s.iter().all(|&x| x < 0) {
            continue;
        }
        if s.iter().all(|&x| x == 0) {
            all_zero.push(orient(tet));
            continue;
        }
        let first = stenciled.len();
        stencils::fill(&stuffing, tet, s, &mut stenciled).map_err(|failure| {
            Broken {
                what: failure.describe(),
                point: centroid(&tet),
            }
            .at(h)
        })?;
        for t in &mut stenciled[first..] {
            *t = orient(*t);
        }
    }
    for &tet in &coarse {
        let s = tet.map(|v| signs[v as usize]);
        if s.iter().all(|&x| x > 0) {
            stenciled.push(orient(tet));
        } else if !s.iter().all(|&x| x < 0) {
            return Err(Broken {
                what: "a coarse tetrahedron of the graded grid meets the surface or has a warped vertex",
                point: centroid(&tet),
            }
            .at(h));
        }
    }

    // As in the uniform mesher: all-zero tetrahedra are a free choice within the bounds.
    add_all_zero(
        &mut stenciled,
        all_zero,
        (&lattice, &cuts, &warped, &signs),
        surface,
        h,
    )?;
    let position = |id: u32| final_position(&lattice, &cuts, &warped, id);
    let mesh = assemble(&stenciled, lattice.vertex_count() + cuts.len(), position, h)?;
    let seconds = start.elapsed().as_secs_f64();
    let mut report = quality_report(&mesh, None);
    report.surface_volume = Some(surface.enclosed_volume());
    report.seconds = seconds;
    Ok(Stuffed { mesh, report })
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
    let margin = fine_margin() * h;
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
    // Balance: a leaf more than twice the size of a leaf it touches (face, edge or corner) is split
    // (down to twice that size where they touch), finest leaves first. One pass per level is
    // enough: the splits make no leaf of the level being done (their cubes are at least twice its
    // size), so they cannot unbalance it or a finer level, and a leaf only ever gets smaller, so a
    // probe point once in a small enough leaf stays so. (Every leaf that touches a cube contains one
    // of its 26 probe points: in an aligned octree a larger neighbour covers the whole shared face,
    // edge or corner.) The tests' conformity checks would see a hanging vertex.
    for level in 0..GRADED_MAX_LEVEL {
        let mut at_level: Vec<Cube> = octree
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
                let octree = &octree;
                (0..27).filter(|&n| n != 13).filter_map(move |n| {
                    let d = [n % 3 - 1, (n / 3) % 3 - 1, n / 9 - 1];
                    let probe =
                        [0, 1, 2].map(|a| c[a] as f64 + 0.5 * s + d[a] as f64 * (0.5 * s + 0.25));
                    octree
                        .leaf_at(probe)
                        .filter(|other| other.0 > l + 1)
                        .map(|_| (probe, l + 1))
                })
            })
            .collect();
        // Split down to that level at once (one pass per level instead of one per halving).
        for (probe, level) in too_big {
            while let Some(cube) = octree.leaf_at(probe).filter(|c| c.0 > level) {
                octree.split(cube);
            }
        }
    }
    octree
}
