//! Exact intersection tests between the triangles of a surface, for the self-intersection check of
//! [`ClosedSurface::new`](super::ClosedSurface::new).
//!
//! Every sign comes from Shewchuk's adaptive exact predicates (`robust`), so two sheets a hair
//! apart are told from two that touch, whatever the scale. Triangles are closed: touching counts as
//! intersecting, except at the vertices (and the edge) that two triangles share.

use robust::{orient2d, orient3d, Coord, Coord3D};

use crate::Vec3;

fn c3(p: &Vec3) -> Coord3D<f64> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// The sign of the orientation of `d` against the plane through `a`, `b`, `c`: exact.
fn orient(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> i8 {
    let value = orient3d(c3(a), c3(b), c3(c), c3(d));
    if value > 0.0 {
        1
    } else if value < 0.0 {
        -1
    } else {
        0
    }
}

/// The sign of the 2D orientation of `c` against the line `a`–`b`: exact.
fn orient_2d(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> i8 {
    let value = orient2d(
        Coord { x: a[0], y: a[1] },
        Coord { x: b[0], y: b[1] },
        Coord { x: c[0], y: c[1] },
    );
    if value > 0.0 {
        1
    } else if value < 0.0 {
        -1
    } else {
        0
    }
}

/// Drop the coordinate along which the triangle's normal is largest: the projection keeps the
/// triangle non-degenerate, and is exact (it only drops a coordinate).
fn projection(triangle: &[Vec3; 3]) -> impl Fn(&Vec3) -> [f64; 2] {
    let normal = (triangle[1] - triangle[0]).cross(&(triangle[2] - triangle[0]));
    let axis = normal.iamax();
    move |p: &Vec3| match axis {
        0 => [p.y, p.z],
        1 => [p.z, p.x],
        _ => [p.x, p.y],
    }
}

/// Whether the closed 2D segments `p`–`q` and `a`–`b` meet.
fn segments_meet_2d(p: [f64; 2], q: [f64; 2], a: [f64; 2], b: [f64; 2]) -> bool {
    let (o1, o2) = (orient_2d(p, q, a), orient_2d(p, q, b));
    let (o3, o4) = (orient_2d(a, b, p), orient_2d(a, b, q));
    if o1 * o2 < 0 && o3 * o4 < 0 {
        return true;
    }
    // Touching or collinear: an end on the other segment.
    let on = |s: [f64; 2], t: [f64; 2], x: [f64; 2], o: i8| {
        o == 0
            && x[0] >= s[0].min(t[0])
            && x[0] <= s[0].max(t[0])
            && x[1] >= s[1].min(t[1])
            && x[1] <= s[1].max(t[1])
    };
    on(p, q, a, o1) || on(p, q, b, o2) || on(a, b, p, o3) || on(a, b, q, o4)
}

/// Whether the 2D point `x` lies in the closed triangle `t`.
fn in_triangle_2d(x: [f64; 2], t: [[f64; 2]; 3]) -> bool {
    let o = [
        orient_2d(t[0], t[1], x),
        orient_2d(t[1], t[2], x),
        orient_2d(t[2], t[0], x),
    ];
    o.iter().all(|&s| s >= 0) || o.iter().all(|&s| s <= 0)
}

/// Whether the closed segment `p`–`q` meets the closed (non-degenerate) triangle `t`.
pub(crate) fn segment_meets_triangle(p: &Vec3, q: &Vec3, t: &[Vec3; 3]) -> bool {
    let (sp, sq) = (
        orient(&t[0], &t[1], &t[2], p),
        orient(&t[0], &t[1], &t[2], q),
    );
    if sp * sq > 0 {
        return false;
    }
    if sp == 0 && sq == 0 {
        // In the triangle's plane: a 2D test.
        let project = projection(t);
        let (p2, q2) = (project(p), project(q));
        let t2 = t.map(|v| project(&v));
        return in_triangle_2d(p2, t2)
            || in_triangle_2d(q2, t2)
            || (0..3).any(|i| segments_meet_2d(p2, q2, t2[i], t2[(i + 1) % 3]));
    }
    // The segment crosses or touches the plane: the crossing lies in the triangle iff the line
    // p–q passes inside (or on) all three edges.
    let o = [
        orient(p, q, &t[0], &t[1]),
        orient(p, q, &t[1], &t[2]),
        orient(p, q, &t[2], &t[0]),
    ];
    o.iter().all(|&s| s >= 0) || o.iter().all(|&s| s <= 0)
}

/// Whether two triangles of a surface meet anywhere but where they share vertices. `t` and `u` are
/// the triangles' vertex ids and `position` places them; vertices are compared by id (the surface
/// has welded bit-identical positions).
pub(crate) fn triangles_intersect(
    t: [u32; 3],
    u: [u32; 3],
    position: impl Fn(u32) -> Vec3,
) -> bool {
    let shared: Vec<u32> = t.iter().copied().filter(|v| u.contains(v)).collect();
    let pt = t.map(&position);
    let pu = u.map(&position);
    match shared.len() {
        0 => {
            (0..3).any(|i| segment_meets_triangle(&pt[i], &pt[(i + 1) % 3], &pu))
                || (0..3).any(|i| segment_meets_triangle(&pu[i], &pu[(i + 1) % 3], &pt))
        }
        1 => {
            // Beyond the shared vertex, the two meet along a segment that leaves one of them
            // through its edge opposite that vertex.
            let opposite = |ids: [u32; 3], p: [Vec3; 3]| {
                let k = ids.iter().position(|&v| v == shared[0]).unwrap_or(0);
                (p[(k + 1) % 3], p[(k + 2) % 3])
            };
            let (a, b) = opposite(t, pt);
            let (c, d) = opposite(u, pu);
            segment_meets_triangle(&a, &b, &pu) || segment_meets_triangle(&c, &d, &pt)
        }
        2 => {
            // Two triangles on one edge overlap only when folded flat onto each other: their third
            // vertices coplanar with the edge and on the same side of it.
            let third = |ids: [u32; 3], p: [Vec3; 3]| {
                p[ids.iter().position(|v| !shared.contains(v)).unwrap_or(0)]
            };
            let (x, y) = (third(t, pt), third(u, pu));
            let (s0, s1) = (position(shared[0]), position(shared[1]));
            if orient(&s0, &s1, &x, &y) != 0 {
                return false;
            }
            let project = projection(&pt);
            let (a, b) = (project(&s0), project(&s1));
            orient_2d(a, b, project(&x)) * orient_2d(a, b, project(&y)) > 0
        }
        _ => true,
    }
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
}
