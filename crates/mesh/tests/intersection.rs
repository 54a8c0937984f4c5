//! The public self-intersection and sphere queries of `hooke_mesh::intersection`, on hand-built
//! cases whose answers are counted by hand, and against brute-force oracles on random soups.

use hooke_mesh::generators::cloth;
use hooke_mesh::intersection::{intersecting_triangle_pairs, triangles_inside_sphere};
use hooke_mesh::Vec3;
use parry3d_f64::query::PointQuery;

fn v(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(x, y, z)
}

/// A deterministic stream of numbers in [0, 1) (a 64-bit LCG; the top 53 bits).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// An n×n grid on the unit square at height z (m), two triangles a cell, vertices numbered from
/// `first`.
fn sheet(n: u32, z: f64, first: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let h = 1.0 / (n - 1) as f64;
    let positions = (0..n)
        .flat_map(|i| (0..n).map(move |j| v(i as f64 * h, j as f64 * h, z)))
        .collect();
    let index = |i: u32, j: u32| first + i * n + j;
    let mut triangles = Vec::new();
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            triangles.push([index(i, j), index(i + 1, j), index(i + 1, j + 1)]);
            triangles.push([index(i, j), index(i + 1, j + 1), index(i, j + 1)]);
        }
    }
    (positions, triangles)
}

#[test]
fn two_crossing_triangles_are_one_pair() {
    let positions = vec![
        v(0.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.0, 1.0, 0.0),
        v(0.2, 0.2, -1.0),
        v(0.3, 0.2, 1.0),
        v(0.2, 0.3, 1.0),
    ];
    let pairs = intersecting_triangle_pairs(&positions, &[[0, 1, 2], [3, 4, 5]]).unwrap();
    assert_eq!(pairs, vec![[0, 1]]);
}

#[test]
fn parallel_sheets_a_hair_apart_do_not_intersect_and_touching_ones_do() {
    // One unit in the last place apart at z = 1 (2.2e-16 m against a 1 m sheet), and 1e-300 m
    // apart at z = 0: no tolerance could tell these from touching, the exact predicates do.
    for (z0, z1) in [(1.0, f64::from_bits(1.0f64.to_bits() + 1)), (0.0, 1e-300)] {
        let (mut positions, mut triangles) = sheet(12, z0, 0);
        let (upper, upper_triangles) = sheet(12, z1, positions.len() as u32);
        positions.extend(upper);
        triangles.extend(upper_triangles);
        assert!(
            intersecting_triangle_pairs(&positions, &triangles)
                .unwrap()
                .is_empty(),
            "sheets at z = {z0} and {z1}"
        );
        // Lower one vertex of the upper sheet onto the lower sheet: it touches the triangles of
        // the lower sheet around that point, and only through its own triangles at that vertex.
        let n = 12u32;
        let touching = (n * n + 5 * n + 5) as usize;
        positions[touching].z = z0;
        let pairs = intersecting_triangle_pairs(&positions, &triangles).unwrap();
        assert!(!pairs.is_empty());
        for [a, b] in &pairs {
            assert!(
                triangles[*b as usize].contains(&(touching as u32)),
                "{a}, {b}"
            );
            assert!((*a as usize) < triangles.len() / 2);
        }
        // The lower sheet's vertex (5, 5) is at the same spot: all six of its triangles are
        // touched by all six of the upper sheet's triangles at the lowered vertex.
        assert_eq!(pairs.len(), 36);
    }
}

#[test]
fn touching_counts_at_a_vertex_an_edge_and_in_the_plane() {
    let positions = vec![
        v(0.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.0, 1.0, 0.0),
        // A triangle above whose lowest vertex rests on 0–1–2's interior.
        v(0.25, 0.25, 0.0),
        v(0.25, 0.25, 1.0),
        v(0.5, 0.25, 1.0),
        // One whose edge touches 0–1–2's edge 1–2 at a point, from outside, in another plane.
        v(0.5, 0.5, -1.0),
        v(0.5, 0.5, 1.0),
        v(2.0, 2.0, 0.0),
        // A coplanar triangle sharing a stretch of the line x = 0 with edge 0–2, outside 0–1–2.
        v(0.0, 0.5, 0.0),
        v(0.0, 1.5, 0.0),
        v(-1.0, 1.0, 0.0),
        // A coplanar one a hair off that line.
        v(-1e-15, 0.5, 0.0),
        v(-1e-15, 1.5, 0.0),
        v(-1.0, 1.0, 0.0),
    ];
    let triangles = [[0, 1, 2], [3, 4, 5], [6, 7, 8], [9, 10, 11], [12, 13, 14]];
    let pairs = intersecting_triangle_pairs(&positions, &triangles).unwrap();
    // 4, 1e-15 m off the line x = 0, misses 0–1–2; it overlaps 3 (nearly the same triangle).
    assert_eq!(pairs, vec![[0, 1], [0, 2], [0, 3], [3, 4]]);
}

#[test]
fn neighbours_sharing_vertices_or_edges_are_not_reported() {
    // The cloth generator's flat grid, then the same grid crumpled smoothly (a height field, so
    // it cannot cross itself): neighbours meet only at their shared vertices and edges.
    let mesh = cloth(30, 1.0).unwrap();
    let triangles = mesh.triangles().to_vec();
    let flat = mesh.positions().to_vec();
    assert!(intersecting_triangle_pairs(&flat, &triangles)
        .unwrap()
        .is_empty());
    let crumpled: Vec<Vec3> = flat
        .iter()
        .map(|p| v(p.x, 0.3 * (9.0 * p.x).sin() * (7.0 * p.z).cos(), p.z))
        .collect();
    assert!(intersecting_triangle_pairs(&crumpled, &triangles)
        .unwrap()
        .is_empty());
    // A fan folded shut (all triangles around a vertex, alternately up and down, like a
    // pleated skirt) meets only along shared edges.
    let mut fan = vec![v(0.0, 0.0, 0.0)];
    for k in 0..12 {
        let angle = k as f64 * std::f64::consts::TAU / 12.0;
        let z = if k % 2 == 0 { 0.5 } else { -0.5 };
        fan.push(v(angle.cos(), angle.sin(), z));
    }
    let fan_triangles: Vec<[u32; 3]> = (0..12).map(|k| [0, 1 + k, 1 + (k + 1) % 12]).collect();
    assert!(intersecting_triangle_pairs(&fan, &fan_triangles)
        .unwrap()
        .is_empty());
}

#[test]
fn a_folded_through_cloth_strip_is_caught_where_it_passes_through() {
    // A strip of width 1 (y from 0 to 1) along a path in the x–z plane that runs out along z = 0
    // and folds back down through itself: path segment 4, from (2.2, 0.5) to (1.5, −0.5), crosses
    // z = 0 at x = 1.85, inside segment 1 (x from 1 to 2). The crossing is the line x = 1.85,
    // z = 0 across the strip. Segment s's quad has vertices 2s, 2s + 1 (y = 0, 1), 2s + 2, 2s + 3
    // and triangles 2s = (2s, 2s+2, 2s+3), 2s + 1 = (2s, 2s+3, 2s+1). On the crossing line,
    // triangle 2 covers y ∈ [0, 0.85] and 3 covers [0.85, 1]; triangle 8 covers [0, 0.5] and 9
    // covers [0.5, 1]: the pairs (2, 8), (2, 9), (3, 9). The folds at path points 3 and 4 share
    // edges and are not reported.
    let path = [
        (0.0, 0.0),
        (1.0, 0.0),
        (2.0, 0.0),
        (3.0, 0.0),
        (2.2, 0.5),
        (1.5, -0.5),
    ];
    let positions: Vec<Vec3> = path
        .iter()
        .flat_map(|&(x, z)| [v(x, 0.0, z), v(x, 1.0, z)])
        .collect();
    let mut triangles = Vec::new();
    for s in 0..path.len() as u32 - 1 {
        triangles.push([2 * s, 2 * s + 2, 2 * s + 3]);
        triangles.push([2 * s, 2 * s + 3, 2 * s + 1]);
    }
    let pairs = intersecting_triangle_pairs(&positions, &triangles).unwrap();
    assert_eq!(pairs, vec![[2, 8], [2, 9], [3, 9]]);
    // Straightened so that the last segment ends above the strip: nothing.
    let mut lifted = positions.clone();
    lifted[10].z = 0.25;
    lifted[11].z = 0.25;
    assert!(intersecting_triangle_pairs(&lifted, &triangles)
        .unwrap()
        .is_empty());
}

#[test]
fn the_bvh_search_finds_what_all_pairs_find_whatever_the_threads() {
    // A random soup of 500 small triangles (about 0.1 m) in a unit box, every third sharing a
    // vertex with the one before: each pair checked on its own (through the same public function,
    // so this checks the candidate search) against the search over all of them.
    let mut random = Lcg(7);
    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    for t in 0..500 {
        let centre = v(random.next(), random.next(), random.next());
        let mut corner = || {
            centre
                + v(
                    random.next() - 0.5,
                    random.next() - 0.5,
                    random.next() - 0.5,
                ) * 0.15
        };
        let first = if t % 3 == 2 {
            triangles[t - 1][0]
        } else {
            positions.push(corner());
            positions.len() as u32 - 1
        };
        let (b, c) = (corner(), corner());
        positions.extend([b, c]);
        let n = positions.len() as u32;
        triangles.push([first, n - 2, n - 1]);
    }
    let found = intersecting_triangle_pairs(&positions, &triangles).unwrap();
    // Triangles whose bounding boxes are apart cannot meet; every other pair is asked alone.
    let boxes: Vec<[Vec3; 2]> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|k| positions[k as usize]);
            [a.inf(&b).inf(&c), a.sup(&b).sup(&c)]
        })
        .collect();
    let mut brute = Vec::new();
    for i in 0..triangles.len() {
        for j in i + 1..triangles.len() {
            let apart =
                (0..3).any(|k| boxes[i][1][k] < boxes[j][0][k] || boxes[j][1][k] < boxes[i][0][k]);
            if !apart
                && !intersecting_triangle_pairs(&positions, &[triangles[i], triangles[j]])
                    .unwrap()
                    .is_empty()
            {
                brute.push([i as u32, j as u32]);
            }
        }
    }
    assert!(brute.len() > 50, "{} pairs", brute.len());
    assert_eq!(found, brute);
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| intersecting_triangle_pairs(&positions, &triangles).unwrap());
    assert_eq!(one_thread, found);
}

#[test]
fn sphere_reports_triangles_dipping_in_and_not_those_touching_it() {
    let center = v(0.0, 0.0, 0.0);
    let positions = vec![
        // 0: a large triangle in the plane z = 0.5, all vertices far outside the unit sphere.
        v(-10.0, -10.0, 0.5),
        v(10.0, -10.0, 0.5),
        v(0.0, 10.0, 0.5),
        // 1: the plane z = 1, tangent to the sphere at (0, 0, 1), which is inside the triangle
        // (all arithmetic exact: edges of length 4, the normal (0, 0, 16)).
        v(-2.0, -2.0, 1.0),
        v(2.0, -2.0, 1.0),
        v(-2.0, 2.0, 1.0),
        // 2: a triangle whose edge passes 0.5 from the centre, vertices outside.
        v(-3.0, 0.5, 0.0),
        v(3.0, 0.5, 0.0),
        v(0.0, 3.0, 0.0),
        // 3: one with a vertex inside.
        v(0.1, 0.1, 0.1),
        v(5.0, 5.0, 5.0),
        v(5.0, -5.0, 5.0),
        // 4: one wholly outside, its nearest point a vertex at 1.5.
        v(1.5, 0.0, 0.0),
        v(3.0, 1.0, 0.0),
        v(3.0, -1.0, 0.0),
    ];
    let triangles: Vec<[u32; 3]> = (0..5).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    assert_eq!(
        triangles_inside_sphere(&positions, &triangles, &center, 1.0).unwrap(),
        vec![0, 2, 3]
    );
    // Just past the tangency, the tangent triangle dips in; 4 comes in past 1.5.
    assert_eq!(
        triangles_inside_sphere(&positions, &triangles, &center, 1.0 + 1e-12).unwrap(),
        vec![0, 1, 2, 3]
    );
    assert_eq!(
        triangles_inside_sphere(&positions, &triangles, &center, 1.5).unwrap(),
        vec![0, 1, 2, 3]
    );
    assert_eq!(
        triangles_inside_sphere(&positions, &triangles, &center, 1.5 + 1e-12).unwrap(),
        vec![0, 1, 2, 3, 4]
    );
    // The centre away from the origin: the same answer translated (coordinates are taken
    // relative to the centre, so no precision is lost to the offset).
    let offset = v(1e3, -2e3, 5e2);
    let moved: Vec<Vec3> = positions.iter().map(|p| p + offset).collect();
    assert_eq!(
        triangles_inside_sphere(&moved, &triangles, &(center + offset), 0.75).unwrap(),
        vec![0, 2, 3]
    );
    assert!(
        triangles_inside_sphere(&positions, &triangles, &center, 0.0)
            .unwrap()
            .is_empty()
    );
}

#[test]
fn sphere_agrees_with_parry_away_from_the_surface() {
    // Random triangles of all shapes against parry3d's own point–triangle distance: the same
    // answer wherever the distance is farther than 1e-9 (relative to the 1 m scene) from the
    // radius.
    let mut random = Lcg(11);
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for t in 0..3000u32 {
        for _ in 0..3 {
            positions.push(v(
                4.0 * random.next() - 2.0,
                4.0 * random.next() - 2.0,
                4.0 * random.next() - 2.0,
            ));
        }
        triangles.push([3 * t, 3 * t + 1, 3 * t + 2]);
    }
    let center = v(0.1, -0.2, 0.05);
    let radius = 0.8;
    let found = triangles_inside_sphere(&positions, &triangles, &center, radius).unwrap();
    let mut checked = 0;
    for (i, t) in triangles.iter().enumerate() {
        let [a, b, c] = t.map(|k| {
            let p = positions[k as usize];
            parry3d_f64::math::Vector::new(p.x, p.y, p.z)
        });
        let triangle = parry3d_f64::shape::Triangle::new(a, b, c);
        let distance = triangle.distance_to_local_point(
            parry3d_f64::math::Vector::new(center.x, center.y, center.z),
            true,
        );
        if (distance - radius).abs() > 1e-9 {
            checked += 1;
            assert_eq!(
                found.binary_search(&(i as u32)).is_ok(),
                distance < radius,
                "triangle {i} at {distance}"
            );
        }
    }
    assert!(found.len() > 300 && found.len() < 2700, "{}", found.len());
    assert!(checked > 2990);
}
