//! Exact intersection tests between triangles, and two queries on triangle surfaces built on them:
//! [`intersecting_triangle_pairs`] (a self-intersection check) and [`triangles_inside_sphere`].
//!
//! Every sign comes from Shewchuk's adaptive exact predicates (`robust`), so two sheets a hair
//! apart are told from two that touch, whatever the scale. Triangles are closed: touching counts as
//! intersecting, except at the vertices (and the edge) that two triangles share. Degenerate
//! triangles (collinear or coincident vertices) are decided exactly too, as the segment or point
//! they are. The signs are exact for finite coordinates as long as the predicates' intermediate
//! products neither overflow nor underflow (coordinates between about 1e-100 and 1e100 m apart).

use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector as PVec;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy};
use rayon::prelude::*;
use robust::{orient2d, orient3d, Coord, Coord3D};

use crate::elements::{check_finite, check_indices};
use crate::{ElementKind, MeshError, Vec3, DEGENERACY_TOLERANCE};

fn c3(p: &Vec3) -> Coord3D<f64> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

fn sign(value: f64) -> i8 {
    if value > 0.0 {
        1
    } else if value < 0.0 {
        -1
    } else {
        0
    }
}

/// The sign of the orientation of `d` against the plane through `a`, `b`, `c`: exact.
fn orient(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> i8 {
    sign(orient3d(c3(a), c3(b), c3(c), c3(d)))
}

/// The exact 2D orientation of `c` against the line `a`–`b` (its sign is exact).
fn orient_2d_value(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    orient2d(
        Coord { x: a[0], y: a[1] },
        Coord { x: b[0], y: b[1] },
        Coord { x: c[0], y: c[1] },
    )
}

fn orient_2d(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> i8 {
    sign(orient_2d_value(a, b, c))
}

/// `p` with coordinate `axis` dropped: exact.
fn drop_axis(p: &Vec3, axis: usize) -> [f64; 2] {
    match axis {
        0 => [p.y, p.z],
        1 => [p.z, p.x],
        _ => [p.x, p.y],
    }
}

/// A coordinate whose dropping keeps the triangle `a`, `b`, `c` non-degenerate, or `None` if it is
/// degenerate (collinear or coincident vertices). Exact: the 2D orientation in the projection that
/// drops axis k is the k-th component of the triangle's normal, so the projection is one-to-one on
/// the triangle's plane exactly when it is non-zero.
fn plane_axis(a: &Vec3, b: &Vec3, c: &Vec3) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for axis in 0..3 {
        let value =
            orient_2d_value(drop_axis(a, axis), drop_axis(b, axis), drop_axis(c, axis)).abs();
        if value > 0.0 && best.is_none_or(|(_, b)| value > b) {
            best = Some((axis, value));
        }
    }
    best.map(|(axis, _)| axis)
}

/// For coplanar points, a coordinate whose dropping is one-to-one on their affine hull (a plane, a
/// line or a point).
fn hull_axis(points: &[Vec3]) -> usize {
    for i in 0..points.len() {
        for j in i + 1..points.len() {
            for k in j + 1..points.len() {
                if let Some(axis) = plane_axis(&points[i], &points[j], &points[k]) {
                    return axis;
                }
            }
        }
    }
    // All collinear: keep a coordinate along which two of them differ (the difference of distinct
    // floats is never rounded to zero).
    for i in 0..points.len() {
        for j in i + 1..points.len() {
            let d = points[j] - points[i];
            if d != Vec3::zeros() {
                return (d.iamax() + 1) % 3;
            }
        }
    }
    0
}

/// Whether `x` lies in the closed box spanned by `s` and `t` (2D).
fn in_box_2d(x: [f64; 2], s: [f64; 2], t: [f64; 2]) -> bool {
    (0..2).all(|k| x[k] >= s[k].min(t[k]) && x[k] <= s[k].max(t[k]))
}

/// Whether the closed 2D segments `p`–`q` and `a`–`b` meet (either may be a point).
fn segments_meet_2d(p: [f64; 2], q: [f64; 2], a: [f64; 2], b: [f64; 2]) -> bool {
    let (o1, o2) = (orient_2d(p, q, a), orient_2d(p, q, b));
    let (o3, o4) = (orient_2d(a, b, p), orient_2d(a, b, q));
    if o1 * o2 < 0 && o3 * o4 < 0 {
        return true;
    }
    // Touching or collinear: an end on the other segment.
    (o1 == 0 && in_box_2d(a, p, q))
        || (o2 == 0 && in_box_2d(b, p, q))
        || (o3 == 0 && in_box_2d(p, a, b))
        || (o4 == 0 && in_box_2d(q, a, b))
}

/// Whether the 2D point `x` lies in the closed, non-degenerate triangle `t`.
fn in_triangle_2d(x: [f64; 2], t: [[f64; 2]; 3]) -> bool {
    let o = [
        orient_2d(t[0], t[1], x),
        orient_2d(t[1], t[2], x),
        orient_2d(t[2], t[0], x),
    ];
    o.iter().all(|&s| s >= 0) || o.iter().all(|&s| s <= 0)
}

/// Whether `x` lies on the closed segment `a`–`b` (exact; the segment may be a point).
fn on_segment(x: &Vec3, a: &Vec3, b: &Vec3) -> bool {
    plane_axis(a, b, x).is_none()
        && (0..3).all(|k| x[k] >= a[k].min(b[k]) && x[k] <= a[k].max(b[k]))
}

/// Whether the closed segments `p`–`q` and `a`–`b` meet (either may be a point).
fn segments_meet(p: &Vec3, q: &Vec3, a: &Vec3, b: &Vec3) -> bool {
    if orient(p, q, a, b) != 0 {
        return false;
    }
    let axis = hull_axis(&[*p, *q, *a, *b]);
    segments_meet_2d(
        drop_axis(p, axis),
        drop_axis(q, axis),
        drop_axis(a, axis),
        drop_axis(b, axis),
    )
}

/// Whether the closed segment `p`–`q` meets the closed triangle `t` (either may be degenerate).
fn segment_meets_triangle(p: &Vec3, q: &Vec3, t: &[Vec3; 3]) -> bool {
    let Some(axis) = plane_axis(&t[0], &t[1], &t[2]) else {
        // A degenerate triangle is the union of its edges.
        return (0..3).any(|i| segments_meet(p, q, &t[i], &t[(i + 1) % 3]));
    };
    let (sp, sq) = (
        orient(&t[0], &t[1], &t[2], p),
        orient(&t[0], &t[1], &t[2], q),
    );
    if sp * sq > 0 {
        return false;
    }
    if sp == 0 && sq == 0 {
        // In the triangle's plane: a 2D test, in a projection one-to-one on that plane.
        let (p2, q2) = (drop_axis(p, axis), drop_axis(q, axis));
        let t2 = t.map(|v| drop_axis(&v, axis));
        return in_triangle_2d(p2, t2)
            || in_triangle_2d(q2, t2)
            || (0..3).any(|i| segments_meet_2d(p2, q2, t2[i], t2[(i + 1) % 3]));
    }
    // The segment crosses or touches the plane (so p ≠ q): the crossing lies in the triangle iff
    // the line p–q passes inside (or on) all three edges.
    let o = [
        orient(p, q, &t[0], &t[1]),
        orient(p, q, &t[1], &t[2]),
        orient(p, q, &t[2], &t[0]),
    ];
    o.iter().all(|&s| s >= 0) || o.iter().all(|&s| s <= 0)
}

/// Whether the closed triangles `t` and `u` meet at all.
fn closed_triangles_meet(t: &[Vec3; 3], u: &[Vec3; 3]) -> bool {
    // Two meeting triangles have an edge of one meeting the other (a degenerate one is the union
    // of its edges; of two non-degenerate ones, the intersection's ends lie on edges).
    (0..3).any(|i| segment_meets_triangle(&t[i], &t[(i + 1) % 3], u))
        || (0..3).any(|i| segment_meets_triangle(&u[i], &u[(i + 1) % 3], t))
}

/// Whether the triangles (s, a, b) and (s, c, d), which share the vertex `s`, meet anywhere else.
///
/// With s off the segment a–b, every point of (s, a, b) lies on a segment from s to a point of a–b,
/// so the furthest point of the triangle along any ray from s is on a–b: the two triangles meet
/// beyond s iff a–b meets (s, c, d) or c–d meets (s, a, b). A degenerate triangle with s on its
/// opposite side is the union of the segments s–a and s–b, each of which is such a triangle.
fn meet_beyond_vertex(s: &Vec3, others_t: [Vec3; 2], others_u: [Vec3; 2]) -> bool {
    let opposite_sides = |[a, b]: [Vec3; 2]| -> Vec<[Vec3; 2]> {
        if on_segment(s, &a, &b) {
            [a, b]
                .into_iter()
                .filter(|v| v != s)
                .map(|v| [v, v])
                .collect()
        } else {
            vec![[a, b]]
        }
    };
    let sides_t = opposite_sides(others_t);
    let sides_u = opposite_sides(others_u);
    sides_t.iter().any(|[a, b]| {
        sides_u.iter().any(|[c, d]| {
            segment_meets_triangle(a, b, &[*s, *c, *d])
                || segment_meets_triangle(c, d, &[*s, *a, *b])
        })
    })
}

/// Whether the triangles (p, q, x) and (p, q, y), which share the edge p–q, meet anywhere off it.
fn meet_beyond_edge(p: &Vec3, q: &Vec3, x: &Vec3, y: &Vec3) -> bool {
    if p == q {
        // The shared edge is a point: two triangles sharing a vertex.
        return meet_beyond_vertex(p, [*q, *x], [*q, *y]);
    }
    if orient(p, q, x, y) != 0 {
        // Two planes through p–q: each triangle meets the line p–q in the edge.
        return false;
    }
    match (plane_axis(p, q, x), plane_axis(p, q, y)) {
        // Coplanar: they overlap iff their third vertices are on the same side of p–q.
        (Some(axis), Some(_)) => {
            let (a, b) = (drop_axis(p, axis), drop_axis(q, axis));
            orient_2d(a, b, drop_axis(x, axis)) * orient_2d(a, b, drop_axis(y, axis)) > 0
        }
        // A segment on the line p–q against a triangle, which meets that line in p–q only.
        (Some(_), None) | (None, Some(_)) => false,
        // Two segments on the line p–q: they overlap off p–q iff both reach past the same end.
        // Along the line, order is the order of a coordinate along which p and q differ.
        (None, None) => {
            let m = (q - p).iamax();
            let beyond = |v: &Vec3, from: &Vec3, end: &Vec3| {
                let (out, along) = (v[m] - end[m], end[m] - from[m]);
                (out > 0.0 && along > 0.0) || (out < 0.0 && along < 0.0)
            };
            (beyond(x, p, q) && beyond(y, p, q)) || (beyond(x, q, p) && beyond(y, q, p))
        }
    }
}

/// Whether two triangles of a surface meet anywhere but where they share vertices. `t` and `u` are
/// the triangles' vertex ids (each with three distinct ids) and `position` places them; vertices
/// are compared by id, so two ids at one position touch. Two triangles with the same three ids
/// meet.
pub(crate) fn triangles_intersect(
    t: [u32; 3],
    u: [u32; 3],
    position: impl Fn(u32) -> Vec3,
) -> bool {
    let shared: Vec<usize> = (0..3).filter(|&i| u.contains(&t[i])).collect();
    let pt = t.map(&position);
    let pu = u.map(&position);
    let index_in_u = |id: u32| u.iter().position(|&v| v == id).unwrap_or(0);
    match shared.as_slice() {
        [] => closed_triangles_meet(&pt, &pu),
        &[i] => {
            let k = index_in_u(t[i]);
            meet_beyond_vertex(
                &pt[i],
                [pt[(i + 1) % 3], pt[(i + 2) % 3]],
                [pu[(k + 1) % 3], pu[(k + 2) % 3]],
            )
        }
        &[i, j] => {
            let x = 3 - i - j;
            let y = 3 - index_in_u(t[i]) - index_in_u(t[j]);
            meet_beyond_edge(&pt[i], &pt[j], &pt[x], &pu[y])
        }
        _ => true,
    }
}

/// Check a triangle soup for the queries: finite coordinates, indices in range, three distinct
/// vertices per triangle, and triangle numbers that fit in a `u32`.
fn check_soup(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<(), MeshError> {
    check_finite(positions)?;
    if triangles.len() > u32::MAX as usize {
        return Err(MeshError::InvalidParameter {
            name: "triangles",
            value: triangles.len().to_string(),
            reason: "more triangles than a u32 index can address",
        });
    }
    for (element, t) in triangles.iter().enumerate() {
        check_indices(ElementKind::Triangle, element, t, positions.len())?;
    }
    Ok(())
}

fn to_parry(p: &Vec3) -> PVec {
    PVec::new(p.x, p.y, p.z)
}

/// Every pair of triangles that meet anywhere but at the vertices (or the edge) they share, as
/// `[lower index, higher index]`, sorted.
///
/// Triangles are closed, so touching counts (a vertex on another triangle, two edges crossing,
/// coplanar overlap); two triangles that share a vertex are reported only if they meet somewhere
/// else too, and two that share an edge only if they overlap off it (folded flat onto each other).
/// Sharing is by vertex index: two indices at one position are two vertices that touch. Two
/// triangles with the same three vertices are reported. Each candidate pair (bounding boxes that
/// overlap, from parry3d's BVH) is decided exactly (see the module documentation), degenerate
/// triangles included, so the answer does not depend on a tolerance or on the scale. The pairs are
/// checked in parallel; the output is the same for any number of threads.
///
/// # Errors
/// [`MeshError::NonFiniteCoordinate`] for a NaN or infinite coordinate (of any vertex),
/// [`MeshError::IndexOutOfRange`] or [`MeshError::RepeatedVertex`] for a triangle that names a
/// vertex that does not exist or one vertex twice, [`MeshError::InvalidParameter`] for more than
/// `u32::MAX` triangles; each names the first offender.
pub fn intersecting_triangle_pairs(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
) -> Result<Vec<[u32; 2]>, MeshError> {
    check_soup(positions, triangles)?;
    if triangles.len() < 2 {
        return Ok(Vec::new());
    }
    // Boxes from the vertex coordinates (exact min and max), compared inclusively by the BVH, so
    // touching triangles are always candidates.
    let boxes: Vec<Aabb> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            Aabb::new(to_parry(&a.inf(&b).inf(&c)), to_parry(&a.sup(&b).sup(&c)))
        })
        .collect();
    let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &boxes);
    let pairs = (0..triangles.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let mut hits: Vec<u32> = bvh
                .intersect_aabb(&boxes[i])
                .filter(|&j| j as usize > i)
                .filter(|&j| {
                    triangles_intersect(triangles[i], triangles[j as usize], |v| {
                        positions[v as usize]
                    })
                })
                .collect();
            hits.sort_unstable();
            hits.into_iter().map(move |j| [i as u32, j])
        })
        .collect();
    Ok(pairs)
}

/// Squared distance (m²) from the origin to the segment `a`–`b`.
fn segment_squared_distance(a: &Vec3, b: &Vec3) -> f64 {
    let ab = b - a;
    let length2 = ab.norm_squared();
    let t = if length2 > 0.0 {
        (-a.dot(&ab) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * t).norm_squared()
}

/// Squared distance (m²) from the origin to the closed triangle `a`, `b`, `c`: the nearest of its
/// vertices and edges, or the foot of the perpendicular on its plane if that lies in it. The face
/// is not consulted for a triangle flat to [`DEGENERACY_TOLERANCE`], whose plane is ill-defined;
/// its edges are then within that tolerance of every point of it.
fn triangle_squared_distance(a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    let nearest_vertex = a.norm_squared().min(b.norm_squared()).min(c.norm_squared());
    let nearest_edge = segment_squared_distance(a, b)
        .min(segment_squared_distance(b, c))
        .min(segment_squared_distance(c, a));
    let nearest = nearest_vertex.min(nearest_edge);
    let normal = (b - a).cross(&(c - a));
    let normal2 = normal.norm_squared();
    let longest2 = (b - a)
        .norm_squared()
        .max((c - b).norm_squared())
        .max((a - c).norm_squared());
    // |normal| = 2·area; flat if area ≤ tolerance·longest².
    let flat = 2.0 * DEGENERACY_TOLERANCE * longest2;
    if normal2.is_nan() || normal2 <= flat * flat {
        return nearest;
    }
    let foot = normal * (a.dot(&normal) / normal2);
    let inside = (b - a).cross(&(foot - a)).dot(&normal) >= 0.0
        && (c - b).cross(&(foot - b)).dot(&normal) >= 0.0
        && (a - c).cross(&(foot - c)).dot(&normal) >= 0.0;
    if inside {
        nearest.min(foot.norm_squared())
    } else {
        nearest
    }
}

/// The triangles with a point strictly inside the sphere of centre `center` (m) and radius
/// `radius` (m): those whose closest point to the centre (of the closed triangle: vertex, edge or
/// interior) is at a distance below `radius`. A triangle whose vertices are all outside but whose
/// interior or an edge dips into the sphere is included; one that only touches it is not. Sorted
/// by index; computed in parallel, the same for any number of threads.
///
/// Rounding: unlike [`intersecting_triangle_pairs`], this is decided in floating point. Coordinates
/// are taken relative to the centre, and the squared distance to the nearest vertex, edge and
/// (for a triangle not flat to [`DEGENERACY_TOLERANCE`]) face is compared with `radius²`. For a
/// well-shaped triangle the computed distance is within a few units of round-off (about 1e-15)
/// relative to the triangle's size plus its distance from the centre, so only a triangle whose
/// closest point is that close to the sphere's surface may go either way; for a sliver the face's
/// error grows as its longest edge² over its area. A vertex whose computed distance is below
/// `radius` always makes its triangle count. Callers that must not miss a triangle at the
/// surface should grow `radius` by that margin.
///
/// # Errors
/// As [`intersecting_triangle_pairs`] for the positions and triangles;
/// [`MeshError::InvalidParameter`] for a centre with a non-finite coordinate (`center`) or a
/// radius that is negative, NaN or infinite (`radius`).
pub fn triangles_inside_sphere(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    center: &Vec3,
    radius: f64,
) -> Result<Vec<u32>, MeshError> {
    check_soup(positions, triangles)?;
    if !center.iter().all(|c| c.is_finite()) {
        return Err(MeshError::InvalidParameter {
            name: "center",
            value: format!("[{}, {}, {}]", center.x, center.y, center.z),
            reason: "the sphere's centre must have finite coordinates",
        });
    }
    if !(radius.is_finite() && radius >= 0.0) {
        return Err(MeshError::InvalidParameter {
            name: "radius",
            value: radius.to_string(),
            reason: "the sphere's radius must be finite and not negative",
        });
    }
    let radius2 = radius * radius;
    Ok((0..triangles.len())
        .into_par_iter()
        .filter(|&i| {
            let [a, b, c] = triangles[i].map(|v| positions[v as usize] - center);
            triangle_squared_distance(&a, &b, &c) < radius2
        })
        .map(|i| i as u32)
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(points: &[[f64; 3]]) -> impl Fn(u32) -> Vec3 + '_ {
        move |i| {
            let p = points[i as usize];
            Vec3::new(p[0], p[1], p[2])
        }
    }

    fn vecs(points: &[[f64; 3]]) -> Vec<Vec3> {
        points.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect()
    }

    #[test]
    fn crossing_touching_and_separate_triangles() {
        // A triangle in z = 0 and one piercing it, one a hair above it, one touching its edge.
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.2, 0.2, -1.0],
            [0.3, 0.2, 1.0],
            [0.2, 0.3, 1.0],
            [0.2, 0.2, 1e-12],
            [0.3, 0.2, 1e-12],
            [0.2, 0.3, 1e-12],
            [0.5, 0.0, 0.0],
            [0.5, -1.0, 1.0],
            [0.6, -1.0, 1.0],
        ];
        let p = at(&points);
        assert!(triangles_intersect([0, 1, 2], [3, 4, 5], &p));
        assert!(!triangles_intersect([0, 1, 2], [6, 7, 8], &p));
        assert!(triangles_intersect([0, 1, 2], [9, 10, 11], &p));
    }

    #[test]
    fn coplanar_triangles_overlap_only_when_they_do() {
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [0.1, 0.1, 0.0],
            [0.2, 0.1, 0.0],
            [0.1, 0.2, 0.0],
        ];
        let p = at(&points);
        assert!(!triangles_intersect([0, 1, 2], [3, 4, 5], &p));
        // One inside the other.
        assert!(triangles_intersect([0, 1, 2], [6, 7, 8], &p));
    }

    #[test]
    fn shared_vertices_and_edges() {
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.5, 0.5, 1.0],
            [0.3, 0.1, 0.0],
            [0.5, 0.2, -1.0],
            [0.3, 0.3, 0.5],
            [0.4, 0.4, 0.0],
        ];
        let p = at(&points);
        // A flat neighbour across the edge 0–1, and one folded up: both only share the edge.
        assert!(!triangles_intersect([0, 1, 2], [1, 0, 3], &p));
        assert!(!triangles_intersect([0, 1, 2], [1, 0, 4], &p));
        // Folded flat onto the same side.
        assert!(triangles_intersect([0, 1, 2], [1, 0, 8], &p));
        // Sharing vertex 0: one that dips through the triangle, one that only touches at 0.
        assert!(triangles_intersect([0, 1, 2], [0, 7, 6], &p));
        assert!(!triangles_intersect([0, 1, 2], [0, 3, 6], &p));
    }

    #[test]
    fn degenerate_triangles_are_the_segments_or_points_they_are() {
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            // 3–5: all at one point in the plane z = 0 but outside the triangle 0–1–2.
            [2.0, 2.0, 0.0],
            [2.0, 2.0, 0.0],
            [2.0, 2.0, 0.0],
            // 6–8: a collinear triangle piercing 0–1–2, and 9–11 one passing beside it.
            [0.2, 0.2, -1.0],
            [0.2, 0.2, 0.5],
            [0.2, 0.2, 1.0],
            [0.8, 0.8, -1.0],
            [0.8, 0.8, 0.5],
            [0.8, 0.8, 1.0],
            // 12–18: on the lines x = ±y of the plane z = 0; 13 is at vertex 0's position.
            [-1.0, -1.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.25, 0.25, 0.0],
            [-1.0, 1.0, 0.0],
            [1.0, -1.0, 0.0],
            [0.5, 0.5, 0.0],
            [-0.5, -0.5, 0.0],
        ];
        let p = at(&points);
        assert!(!triangles_intersect([0, 1, 2], [3, 4, 5], &p));
        assert!(triangles_intersect([0, 1, 2], [6, 7, 8], &p));
        assert!(!triangles_intersect([0, 1, 2], [9, 10, 11], &p));
        // Another id at vertex 0's position: touching.
        assert!(triangles_intersect([0, 1, 2], [12, 13, 9], &p));
        // Sharing vertex 0, which lies between the other two: outside but for 0, or reaching in.
        assert!(!triangles_intersect([0, 1, 2], [15, 0, 16], &p));
        assert!(triangles_intersect([0, 1, 2], [12, 0, 14], &p));
        // Sharing the edge 0–14 on one line: reaching past opposite ends, or past the same one;
        // and against a proper triangle on that edge.
        assert!(!triangles_intersect([0, 14, 12], [0, 14, 17], &p));
        assert!(triangles_intersect([0, 14, 12], [14, 0, 18], &p));
        assert!(!triangles_intersect([0, 14, 12], [0, 14, 2], &p));
    }

    #[test]
    fn public_pairs_match_the_hand_counted_cases() {
        // 0: a triangle in z = 0; 1: one piercing it; 2: one touching 0's edge at a point;
        // 3: one a hair above 0 (away from 1); 4: a neighbour of 0 across its edge.
        let positions = vecs(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.2, 0.2, -1.0],
            [0.3, 0.2, 1.0],
            [0.2, 0.3, 1.0],
            [0.5, 0.0, 0.0],
            [0.5, -1.0, 1.0],
            [0.6, -1.0, 1.0],
            [0.6, 0.1, 1e-12],
            [0.7, 0.1, 1e-12],
            [0.6, 0.2, 1e-12],
            [1.0, 1.0, 0.0],
        ]);
        let triangles = [[0, 1, 2], [3, 4, 5], [6, 7, 8], [9, 10, 11], [1, 12, 2]];
        let pairs = intersecting_triangle_pairs(&positions, &triangles).unwrap();
        assert_eq!(pairs, vec![[0, 1], [0, 2]]);
    }

    #[test]
    fn bad_input_is_refused_with_the_offender_named() {
        let positions = vecs(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        assert!(matches!(
            intersecting_triangle_pairs(&positions, &[[0, 1, 2], [0, 1, 3]]),
            Err(MeshError::IndexOutOfRange {
                element: 1,
                index: 3,
                ..
            })
        ));
        assert!(matches!(
            intersecting_triangle_pairs(&positions, &[[0, 1, 1]]),
            Err(MeshError::RepeatedVertex {
                element: 0,
                vertex: 1,
                ..
            })
        ));
        let mut nan = positions.clone();
        nan[2].y = f64::NAN;
        assert!(matches!(
            triangles_inside_sphere(&nan, &[[0, 1, 2]], &Vec3::zeros(), 1.0),
            Err(MeshError::NonFiniteCoordinate {
                vertex: 2,
                axis: 1,
                ..
            })
        ));
        for radius in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                triangles_inside_sphere(&positions, &[[0, 1, 2]], &Vec3::zeros(), radius),
                Err(MeshError::InvalidParameter { name: "radius", .. })
            ));
        }
        assert!(matches!(
            triangles_inside_sphere(
                &positions,
                &[[0, 1, 2]],
                &Vec3::new(0.0, f64::INFINITY, 0.0),
                1.0
            ),
            Err(MeshError::InvalidParameter { name: "center", .. })
        ));
        assert!(intersecting_triangle_pairs(&[], &[]).unwrap().is_empty());
    }
}
