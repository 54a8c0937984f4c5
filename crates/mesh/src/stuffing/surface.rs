//! A closed, consistently oriented triangle surface, checked, turned outward, and wrapped in
//! parry's triangle mesh for inside tests, closest points and segment crossings.

use std::collections::HashMap;

use parry3d_f64::math::Pose;
use parry3d_f64::math::Vector as PVec;
use parry3d_f64::query::{PointQuery, Ray, RayCast};
use parry3d_f64::shape::{Cuboid, TriMesh as ParryMesh, TriMeshFlags};

use super::StuffingError;
use crate::{TriMesh, Vec3};

/// A watertight, 2-manifold, consistently oriented triangle surface with outward normals, ready
/// for meshing.
///
/// Built by [`ClosedSurface::new`], which checks the surface and turns an inside-out one outward
/// (see [`ClosedSurface::was_inside_out`]). Geometric queries (inside test by angle-weighted
/// pseudo-normals, closest point, signed distance, segment crossing) are parry3d's, on its BVH.
pub struct ClosedSurface {
    surface: TriMesh,
    shape: ParryMesh,
    volume: f64,
    inside_out: bool,
    bounds: [Vec3; 2],
}

impl std::fmt::Debug for ClosedSurface {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClosedSurface")
            .field("vertices", &self.surface.positions().len())
            .field("triangles", &self.surface.triangles().len())
            .field("volume", &self.volume)
            .field("inside_out", &self.inside_out)
            .finish()
    }
}

fn to_parry(p: &Vec3) -> PVec {
    PVec::new(p.x, p.y, p.z)
}

fn from_parry(p: PVec) -> Vec3 {
    Vec3::new(p.x, p.y, p.z)
}

/// Check that every edge is shared by exactly two triangles that run it in opposite directions.
/// The error names the offending edge whose first triangle comes first in the input.
fn check_closed_manifold(triangles: &[[u32; 3]], renumber: &[u32]) -> Result<(), StuffingError> {
    // (undirected key, forward?, triangle), sorted so that an edge's uses are adjacent.
    let mut uses: Vec<(u64, bool, u32)> = Vec::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        for (p, q) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
            let (p, q) = (renumber[p as usize], renumber[q as usize]);
            let key = ((p.min(q) as u64) << 32) | p.max(q) as u64;
            uses.push((key, p < q, t as u32));
        }
    }
    uses.sort_unstable();
    let mut worst: Option<(u32, StuffingError)> = None;
    let mut start = 0;
    while start < uses.len() {
        let mut end = start + 1;
        while end < uses.len() && uses[end].0 == uses[start].0 {
            end += 1;
        }
        let group = &uses[start..end];
        let first = group.iter().map(|u| u.2).min().unwrap_or(0);
        let (lo, hi) = (
            (group[0].0 >> 32) as usize,
            (group[0].0 & 0xffff_ffff) as usize,
        );
        let error = match group.len() {
            1 => Some(StuffingError::OpenEdge {
                a: lo,
                b: hi,
                triangle: first as usize,
            }),
            2 if group[0].1 == group[1].1 => {
                let (a, b) = if group[0].1 { (lo, hi) } else { (hi, lo) };
                Some(StuffingError::InconsistentOrientation {
                    a,
                    b,
                    first: group[0].2.min(group[1].2) as usize,
                    second: group[0].2.max(group[1].2) as usize,
                })
            }
            2 => None,
            count => Some(StuffingError::NonManifoldEdge {
                a: lo,
                b: hi,
                count,
                triangle: first as usize,
            }),
        };
        if let Some(error) = error {
            if worst.as_ref().is_none_or(|(t, _)| first < *t) {
                worst = Some((first, error));
            }
        }
        start = end;
    }
    if let Some((_, error)) = worst {
        return Err(error);
    }
    let welded: Vec<[u32; 3]> = triangles
        .iter()
        .map(|t| t.map(|v| renumber[v as usize]))
        .collect();
    check_vertex_fans(&welded, &uses)
}

/// With every edge in exactly two triangles, check that the triangles at each vertex form one fan
/// (a bowtie vertex has two or more, joined only at the vertex). `triangles` are in welded
/// numbering; `uses` is [`check_closed_manifold`]'s sorted list of edge uses, two per edge.
fn check_vertex_fans(
    triangles: &[[u32; 3]],
    uses: &[(u64, bool, u32)],
) -> Result<(), StuffingError> {
    // Union-find over the corners (triangle, vertex): the two triangles of an edge join their
    // corners at both of its ends.
    let corner = |t: u32, v: u32| -> usize {
        let k = triangles[t as usize]
            .iter()
            .position(|&x| x == v)
            .unwrap_or(0);
        3 * t as usize + k
    };
    let mut parent: Vec<usize> = (0..3 * triangles.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for pair in uses.chunks_exact(2) {
        let (lo, hi) = ((pair[0].0 >> 32) as u32, (pair[0].0 & 0xffff_ffff) as u32);
        for v in [lo, hi] {
            let (a, b) = (corner(pair[0].2, v), corner(pair[1].2, v));
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            parent[ra] = rb;
        }
    }
    // Fans per vertex, and the lowest triangle at it: (vertex, root) pairs, deduplicated.
    let mut fans: Vec<(u32, usize, u32)> = Vec::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        for (k, &v) in tri.iter().enumerate() {
            fans.push((v, root(&mut parent, 3 * t + k), t as u32));
        }
    }
    fans.sort_unstable();
    let mut worst: Option<(usize, usize, usize)> = None;
    let mut start = 0;
    while start < fans.len() {
        let mut end = start + 1;
        while end < fans.len() && fans[end].0 == fans[start].0 {
            end += 1;
        }
        let group = &fans[start..end];
        let count = 1 + group.windows(2).filter(|w| w[0].1 != w[1].1).count();
        if count > 1 {
            let vertex = group[0].0 as usize;
            let triangle = group.iter().map(|f| f.2).min().unwrap_or(0) as usize;
            if worst.is_none_or(|(_, _, t)| triangle < t) {
                worst = Some((vertex, count, triangle));
            }
        }
        start = end;
    }
    match worst {
        Some((vertex, fans, triangle)) => Err(StuffingError::NonManifoldVertex {
            vertex,
            fans,
            triangle,
        }),
        None => Ok(()),
    }
}

/// The first pair of triangles (by the lower index, then the other) that intersect away from the
/// vertices they share, if any. Candidate pairs come from parry's BVH (bounding boxes that
/// overlap); each is decided by exact predicates (module `crate::intersection`).
fn first_self_intersection(
    shape: &ParryMesh,
    triangles: &[[u32; 3]],
    positions: &[Vec3],
) -> Option<(usize, usize)> {
    use rayon::prelude::*;
    let bvh = shape.bvh();
    (0..triangles.len())
        .into_par_iter()
        .filter_map(|i| {
            let aabb = shape.triangle(i as u32).local_aabb();
            let mut hits: Vec<u32> = bvh
                .intersect_aabb(&aabb)
                .filter(|&j| j as usize > i)
                .filter(|&j| {
                    crate::intersection::triangles_intersect(
                        triangles[i],
                        triangles[j as usize],
                        |v| positions[v as usize],
                    )
                })
                .collect();
            hits.sort_unstable();
            hits.first().map(|&j| (i, j as usize))
        })
        .min()
}

impl ClosedSurface {
    /// Check a triangle surface and prepare it for meshing.
    ///
    /// Vertices with bit-identical coordinates are treated as one (as an STL file needs); indices in
    /// errors are the first such vertex's index in `mesh`. An inside-out surface (negative enclosed
    /// volume) is turned outward by reversing every triangle, and
    /// [`was_inside_out`](Self::was_inside_out) says so.
    ///
    /// # Errors
    /// [`StuffingError::OpenEdge`] (an edge in one triangle), [`StuffingError::NonManifoldEdge`]
    /// (in three or more), [`StuffingError::InconsistentOrientation`] (two neighbours disagree),
    /// naming the offending edge whose lowest triangle index is smallest;
    /// [`StuffingError::NonManifoldVertex`] for a vertex whose triangles form two or more fans
    /// (the one whose lowest triangle index is smallest); [`StuffingError::ZeroVolume`] for a flat
    /// closed surface; [`StuffingError::SelfIntersecting`] for two triangles that meet away from
    /// their shared vertices (decided exactly); [`StuffingError::SurfaceQuery`] if parry3d cannot
    /// build its query structure. Empty input and NaN coordinates are refused earlier, by
    /// [`TriMesh::new`].
    pub fn new(mesh: &TriMesh) -> Result<Self, StuffingError> {
        let positions = mesh.positions();
        // Weld bit-identical positions: the first index of each position stands for all.
        let mut first_index: HashMap<[u64; 3], u32> = HashMap::with_capacity(positions.len());
        let renumber: Vec<u32> = positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                *first_index
                    .entry([p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
                    .or_insert(i as u32)
            })
            .collect();
        check_closed_manifold(mesh.triangles(), &renumber)?;

        let mut triangles: Vec<[u32; 3]> = mesh
            .triangles()
            .iter()
            .map(|t| t.map(|v| renumber[v as usize]))
            .collect();
        let signed_volume: f64 = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| positions[v as usize]);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum();
        let mut lo = positions[0];
        let mut hi = positions[0];
        for p in positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let extent = hi - lo;
        let scale = extent.x * extent.y * extent.z;
        if signed_volume.abs() <= crate::DEGENERACY_TOLERANCE * extent.norm().powi(3) {
            return Err(StuffingError::ZeroVolume {
                volume: signed_volume.abs(),
                scale,
            });
        }
        let inside_out = signed_volume < 0.0;
        if inside_out {
            for t in &mut triangles {
                t.swap(1, 2);
            }
        }
        let vertices: Vec<PVec> = positions.iter().map(to_parry).collect();
        let shape = ParryMesh::with_flags(vertices, triangles.clone(), TriMeshFlags::ORIENTED)
            .map_err(|e| StuffingError::SurfaceQuery {
                reason: e.to_string(),
            })?;
        if let Some((first, second)) = first_self_intersection(&shape, &triangles, positions) {
            return Err(StuffingError::SelfIntersecting { first, second });
        }
        let surface = TriMesh::new(positions.to_vec(), triangles)?;
        Ok(ClosedSurface {
            surface,
            shape,
            volume: signed_volume.abs(),
            inside_out,
            bounds: [lo, hi],
        })
    }

    /// The surface, oriented outward (triangles reversed if the input was inside out).
    pub fn triangle_mesh(&self) -> &TriMesh {
        &self.surface
    }

    /// Whether the input was inside out (negative enclosed volume) and has been turned outward.
    pub fn was_inside_out(&self) -> bool {
        self.inside_out
    }

    /// The enclosed volume (m³), positive.
    pub fn enclosed_volume(&self) -> f64 {
        self.volume
    }

    /// The axis-aligned bounding box of the surface's vertices, `[min, max]` (m).
    pub fn bounds(&self) -> [Vec3; 2] {
        self.bounds
    }

    /// Whether `p` lies inside the surface (by the angle-weighted pseudo-normal at its closest
    /// point; points on the surface may go either way).
    pub fn contains(&self, p: &Vec3) -> bool {
        self.shape.project_local_point(to_parry(p), false).is_inside
    }

    /// The closest point of the surface to `p`.
    pub fn closest_point(&self, p: &Vec3) -> Vec3 {
        from_parry(self.shape.project_local_point(to_parry(p), false).point)
    }

    /// Signed distance from `p` to the surface (m): negative inside, positive outside.
    pub fn signed_distance(&self, p: &Vec3) -> f64 {
        let projection = self.shape.project_local_point(to_parry(p), false);
        let distance = (from_parry(projection.point) - p).norm();
        if projection.is_inside {
            -distance
        } else {
            distance
        }
    }

    /// Distance (m) from the axis-aligned box `[lo, hi]` to the surface (its triangles: a box wholly
    /// inside the solid is at a positive distance); 0 where they meet. parry3d's box–triangle
    /// distance (GJK, to its convergence tolerance) over the triangles its BVH does not rule out;
    /// 0 (the cautious answer) should parry refuse the query.
    pub(crate) fn box_distance(&self, lo: &Vec3, hi: &Vec3) -> f64 {
        let centre = (lo + hi) * 0.5;
        let cuboid = Cuboid::new(to_parry(&((hi - lo) * 0.5)));
        let pose = Pose::translation(centre.x, centre.y, centre.z);
        parry3d_f64::query::distance(&Pose::IDENTITY, &self.shape, &pose, &cuboid)
            .map_or(0.0, |d| d.distance)
    }

    /// Where the segment from `inside` (a point inside) to `outside` (a point outside) first leaves
    /// the solid: the first surface crossing seen from `inside`, found by a ray cast, or by bisection
    /// on the inside test where round-off makes the ray miss.
    pub(crate) fn crossing(&self, inside: &Vec3, outside: &Vec3) -> Vec3 {
        let direction = outside - inside;
        let ray = Ray::new(to_parry(inside), to_parry(&direction));
        if let Some(t) = self.shape.cast_local_ray(&ray, 1.0, false) {
            if t.is_finite() && (0.0..=1.0).contains(&t) {
                return inside + direction * t;
            }
        }
        // 60 halvings take the bracket below f64 resolution of any edge.
        let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if self.contains(&(inside + direction * mid)) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        inside + direction * (0.5 * (lo + hi))
    }
}
