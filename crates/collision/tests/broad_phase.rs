//! Tests of the broad phase (hooke_collision::broad_phase): the candidate pairs against a
//! brute-force enumeration of all pairs on random triangle soups and perturbed grids, with and
//! without motion, far from the origin (cell coordinates that wrap) and with fast vertices (boxes
//! kept out of the grid); no pair sharing a vertex; sorted output; the same bits on one and two
//! threads; no allocation by a warm workspace; the topology; and the exclusion of pairs close at
//! rest on a tiny grid. An ignored test times two 160×160 sheets.

use hooke_collision::broad_phase::{BroadPhase, CandidatePairs, SurfaceTopology};
use hooke_collision::distance::{edge_edge_distance_squared, point_triangle_distance_squared};
use nalgebra::Vector3;
use proptest::prelude::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::collections::BTreeSet;

/// Counts the allocations of the current thread (for the workspace's no-allocation test; other
/// tests run on other threads and do not disturb the count).
struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

type V = Vector3<f64>;

/// The box of a primitive's vertices at `x`, or swept to x + m.
fn primitive_box(vertices: &[u32], x: &[V], motion: Option<&[V]>) -> (V, V) {
    let mut lo = V::repeat(f64::INFINITY);
    let mut hi = V::repeat(f64::NEG_INFINITY);
    for &i in vertices {
        let i = i as usize;
        let end = motion.map_or(x[i], |m| x[i] + m[i]);
        lo = lo.inf(&x[i]).inf(&end);
        hi = hi.sup(&x[i]).sup(&end);
    }
    (lo, hi)
}

/// The Euclidean distance between two boxes (m).
fn box_distance(a: &(V, V), b: &(V, V)) -> f64 {
    let gap = (a.0 - b.1).sup(&(b.0 - a.1)).sup(&V::zeros());
    gap.norm()
}

/// Brute force: every point–triangle and edge–edge pair not sharing a vertex and not excluded
/// whose box distance is at most `limit`, with that distance.
#[allow(clippy::type_complexity)]
fn brute_force(
    topology: &SurfaceTopology,
    x: &[V],
    motion: Option<&[V]>,
    limit: f64,
) -> (Vec<([u32; 2], f64)>, Vec<([u32; 2], f64)>) {
    let excluded_pt: BTreeSet<[u32; 2]> =
        topology.excluded_point_triangle().iter().copied().collect();
    let excluded_ee: BTreeSet<[u32; 2]> = topology.excluded_edge_edge().iter().copied().collect();
    let triangle_boxes: Vec<_> = topology
        .triangles()
        .iter()
        .map(|t| primitive_box(t, x, motion))
        .collect();
    let edge_boxes: Vec<_> = topology
        .edges()
        .iter()
        .map(|e| primitive_box(e, x, motion))
        .collect();
    let mut pt = Vec::new();
    for &p in topology.points() {
        let b = primitive_box(&[p], x, motion);
        for (t, tri) in topology.triangles().iter().enumerate() {
            let distance = box_distance(&b, &triangle_boxes[t]);
            let pair = [p, t as u32];
            if distance <= limit && !tri.contains(&p) && !excluded_pt.contains(&pair) {
                pt.push((pair, distance));
            }
        }
    }
    let mut ee = Vec::new();
    let edges = topology.edges();
    for a in 0..edges.len() {
        for b in a + 1..edges.len() {
            let distance = box_distance(&edge_boxes[a], &edge_boxes[b]);
            let pair = [a as u32, b as u32];
            if distance <= limit
                && !edges[a].iter().any(|v| edges[b].contains(v))
                && !excluded_ee.contains(&pair)
            {
                ee.push((pair, distance));
            }
        }
    }
    (pt, ee)
}

/// Checks `out` against the brute force: sorted strictly ascending (so no duplicates), every pair
/// with boxes within reach present, no other pair (pairs within rounding of the reach may go
/// either way), none sharing a vertex or excluded.
fn check_against_brute_force(
    topology: &SurfaceTopology,
    x: &[V],
    motion: Option<&[V]>,
    reach: f64,
    out: &CandidatePairs,
) {
    let slack = 1e-9 * (1.0 + reach);
    let (pt, ee) = brute_force(topology, x, motion, reach + slack);
    for (name, found, near) in [
        ("point–triangle", &out.point_triangle, pt),
        ("edge–edge", &out.edge_edge, ee),
    ] {
        assert!(
            found.windows(2).all(|w| w[0] < w[1]),
            "{name}: not sorted ascending without duplicates"
        );
        let found_set: BTreeSet<[u32; 2]> = found.iter().copied().collect();
        for &(pair, distance) in &near {
            if distance <= reach - slack {
                assert!(
                    found_set.contains(&pair),
                    "{name}: missing {pair:?} at box distance {distance:e} ≤ reach {reach:e}"
                );
            }
        }
        let near_set: BTreeSet<[u32; 2]> = near.iter().map(|&(pair, _)| pair).collect();
        for pair in found {
            assert!(
                near_set.contains(pair),
                "{name}: {pair:?} is beyond reach {reach:e}, shares a vertex or is excluded"
            );
        }
    }
}

/// A perturbed n×n grid of spacing h in the plane z = `height`, triangulated with alternating
/// diagonals, its vertices numbered from `first`.
fn grid(n: usize, h: f64, height: f64, first: u32) -> (Vec<V>, Vec<[u32; 3]>) {
    let mut x = Vec::new();
    for j in 0..n {
        for i in 0..n {
            x.push(V::new(i as f64 * h, j as f64 * h, height));
        }
    }
    let id = |i: usize, j: usize| first + (j * n + i) as u32;
    let mut triangles = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            } else {
                triangles.push([a, b, d]);
                triangles.push([b, c, d]);
            }
        }
    }
    (x, triangles)
}

/// A mesh for the property tests.
#[derive(Clone, Debug)]
struct Mesh {
    x: Vec<V>,
    triangles: Vec<[u32; 3]>,
    motion: Option<Vec<V>>,
    reach: f64,
}

fn coordinate() -> impl Strategy<Value = f64> {
    -1.0f64..=1.0
}

fn vector() -> impl Strategy<Value = V> {
    (coordinate(), coordinate(), coordinate()).prop_map(|(a, b, c)| V::new(a, b, c))
}

/// A triangle soup: up to 24 vertices in the unit cube, up to 30 triangles over them (shared
/// vertices, shared edges, unused vertices).
fn soup() -> impl Strategy<Value = (Vec<V>, Vec<[u32; 3]>)> {
    (4usize..=24).prop_flat_map(|n| {
        let triangle = proptest::sample::subsequence((0..n as u32).collect::<Vec<_>>(), 3)
            .prop_shuffle()
            .prop_map(|t| [t[0], t[1], t[2]]);
        (
            proptest::collection::vec(vector().prop_map(|v| v * 0.5), n),
            proptest::collection::vec(triangle, 1..=30),
        )
    })
}

/// Two perturbed grids of 3 to 7 vertices a side, one above the other.
fn sheets() -> impl Strategy<Value = (Vec<V>, Vec<[u32; 3]>)> {
    (
        3usize..=7,
        0.0f64..=0.3,
        proptest::collection::vec(vector(), 98),
    )
        .prop_map(|(n, gap, noise)| {
            let h = 1.0 / (n - 1) as f64;
            let (mut x, mut triangles) = grid(n, h, 0.0, 0);
            let (upper, upper_triangles) = grid(n, h, gap, (n * n) as u32);
            x.extend(upper);
            triangles.extend(upper_triangles);
            for (p, e) in x.iter_mut().zip(&noise) {
                *p += e * (0.3 * h);
            }
            (x, triangles)
        })
}

/// A soup or sheets, moved far from the origin half the time (cell coordinates beyond 2²¹ that
/// wrap), with a motion half the time (a few vertices fast enough to leave the grid), and a
/// reach from 0 to 0.3.
fn mesh() -> impl Strategy<Value = Mesh> {
    (
        prop_oneof![soup(), sheets()],
        prop_oneof![Just(V::zeros()), vector().prop_map(|v| v * 1e7)],
        proptest::option::of((proptest::collection::vec(vector(), 98), 0.0f64..=0.3)),
        prop_oneof![Just(0.0), 0.0f64..=0.3],
    )
        .prop_map(|((mut x, triangles), offset, motion, reach)| {
            for p in &mut x {
                *p += offset;
            }
            let motion = motion.map(|(m, scale)| {
                (0..x.len())
                    .map(|i| {
                        // Every tenth vertex 100 times faster: a swept box over thousands of cells.
                        let fast = if i % 10 == 3 { 100.0 } else { 1.0 };
                        m[i % m.len()] * (scale * fast)
                    })
                    .collect()
            });
            Mesh {
                x,
                triangles,
                motion,
                reach,
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The pairs are exactly the brute force's pairs within reach (up to rounding at the reach),
    /// sorted, none sharing a vertex; a second call on the same workspace gives the same pairs.
    #[test]
    fn finds_every_pair_within_reach(mesh in mesh()) {
        let topology = SurfaceTopology::new(mesh.x.len(), &mesh.triangles);
        let mut broad = BroadPhase::new();
        let mut out = CandidatePairs::new();
        let motion = mesh.motion.as_deref();
        broad.find(&topology, &mesh.x, motion, mesh.reach, &mut out);
        check_against_brute_force(&topology, &mesh.x, motion, mesh.reach, &out);
        let mut again = CandidatePairs::new();
        broad.find(&topology, &mesh.x, motion, mesh.reach, &mut again);
        prop_assert_eq!(&out, &again);
    }

    /// The same with exclusions recorded at the starting positions.
    #[test]
    fn excluded_pairs_are_never_output(mesh in mesh(), rest_reach in 0.0f64..=0.5) {
        let mut topology = SurfaceTopology::new(mesh.x.len(), &mesh.triangles);
        topology.exclude_close_at_rest(&mesh.x, rest_reach);
        let mut out = CandidatePairs::new();
        let motion = mesh.motion.as_deref();
        BroadPhase::new().find(&topology, &mesh.x, motion, mesh.reach, &mut out);
        check_against_brute_force(&topology, &mesh.x, motion, mesh.reach, &out);
    }
}

/// Two perturbed 32×32 sheets 0.005 apart (2,048 vertices, 5,859 edges: several query blocks and
/// grid fill blocks), with a motion.
fn large_sheets() -> (Vec<V>, Vec<[u32; 3]>, Vec<V>) {
    let n = 32;
    let h = 1.0 / (n - 1) as f64;
    let (mut x, mut triangles) = grid(n, h, 0.0, 0);
    let (upper, upper_triangles) = grid(n, h, 0.005, (n * n) as u32);
    x.extend(upper);
    triangles.extend(upper_triangles);
    // A fixed pseudo-random perturbation and motion (a linear congruential sequence).
    let mut state: u64 = 12345;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    for p in &mut x {
        *p += V::new(next(), next(), next()) * (0.2 * h);
    }
    let motion = (0..x.len())
        .map(|_| V::new(next(), next(), next()) * 0.01)
        .collect();
    (x, triangles, motion)
}

#[test]
fn serial_and_parallel_runs_give_the_same_bits() {
    let (x, triangles, motion) = large_sheets();
    let mut topology = SurfaceTopology::new(x.len(), &triangles);
    topology.exclude_close_at_rest(&x, 0.02);
    let run = |threads: usize, motion: Option<&[V]>| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut out = CandidatePairs::new();
            BroadPhase::new().find(&topology, &x, motion, 0.02, &mut out);
            out
        })
    };
    for motion in [None, Some(&motion[..])] {
        let serial = run(1, motion);
        let parallel = run(2, motion);
        assert!(!serial.point_triangle.is_empty() && !serial.edge_edge.is_empty());
        assert_eq!(serial, parallel);
        check_against_brute_force(&topology, &x, motion, 0.02, &parallel);
    }
}

#[test]
fn a_warm_workspace_does_not_allocate() {
    // On a one-thread pool everything runs on the pool's thread, whose allocations are counted.
    let (x, triangles, motion) = large_sheets();
    let mut topology = SurfaceTopology::new(x.len(), &triangles);
    topology.exclude_close_at_rest(&x, 0.02);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let counts = pool.install(|| {
        let mut broad = BroadPhase::new();
        let mut out = CandidatePairs::new();
        let mut counts = Vec::new();
        for _ in 0..2 {
            for m in [Some(&motion[..]), None] {
                let before = ALLOCATIONS.with(Cell::get);
                broad.find(&topology, &x, m, 0.02, &mut out);
                counts.push(ALLOCATIONS.with(Cell::get) - before);
            }
        }
        counts
    });
    // The first call allocates; the static call after the larger swept one, and both repeats, not.
    assert!(counts[0] > 0, "{counts:?}");
    assert_eq!(&counts[1..], &[0, 0, 0], "{counts:?}");
}

#[test]
fn topology_of_a_grid() {
    let n = 5;
    let (x, triangles) = grid(n, 1.0, 0.0, 0);
    let topology = SurfaceTopology::new(x.len() + 2, &triangles);
    assert_eq!(topology.vertex_count(), n * n + 2);
    assert_eq!(topology.triangles(), &triangles[..]);
    // Rows, columns and one diagonal per square.
    assert_eq!(topology.edges().len(), 2 * n * (n - 1) + (n - 1) * (n - 1));
    assert!(topology.edges().windows(2).all(|w| w[0] < w[1]));
    assert!(topology.edges().iter().all(|e| e[0] < e[1]));
    // The two extra vertices are in no triangle: not points.
    assert_eq!(
        topology.points(),
        &(0..(n * n) as u32).collect::<Vec<_>>()[..]
    );
    for v in 0..(n * n + 2) as u32 {
        for &e in topology.vertex_edges(v) {
            assert!(topology.edges()[e as usize].contains(&v));
        }
        for &t in topology.vertex_triangles(v) {
            assert!(topology.triangles()[t as usize].contains(&v));
        }
    }
    // The centre of the grid (2, 2) has the corner diagonal pattern: 8 edges, 8 triangles.
    assert_eq!(topology.vertex_edges(12).len(), 8);
    assert_eq!(topology.vertex_triangles(12).len(), 8);
    assert!(topology.vertex_edges(25).is_empty());
}

#[test]
fn the_exclusion_rule_on_a_tiny_grid() {
    // Spacing 1, reach 1.5: the one-ring's triangles and edges are within reach, and so are some
    // pairs two rings apart, which must stay.
    let n = 5;
    let reach = 1.5;
    let (x, triangles) = grid(n, 1.0, 0.0, 0);
    let mut topology = SurfaceTopology::new(x.len(), &triangles);
    topology.exclude_close_at_rest(&x, reach);

    // The rule, by brute force: on the same fan (some vertex of one joined by an edge to some
    // vertex of the other, computed from the triangles' sides) and closer than the reach.
    let mut joined = BTreeSet::new();
    for t in &triangles {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            joined.insert((a, b));
            joined.insert((b, a));
        }
    }
    let on_fan = |p: &[u32], q: &[u32]| {
        p.iter()
            .any(|a| q.iter().any(|b| joined.contains(&(*a, *b))))
    };
    let mut pt = Vec::new();
    let mut close_pt_off_fan = 0;
    for v in 0..x.len() as u32 {
        for (t, tri) in triangles.iter().enumerate() {
            if tri.contains(&v) {
                continue;
            }
            let [a, b, c] = tri.map(|i| x[i as usize]);
            let close = point_triangle_distance_squared(&x[v as usize], &a, &b, &c) < reach * reach;
            if close && on_fan(&[v], tri) {
                pt.push([v, t as u32]);
            } else if close {
                close_pt_off_fan += 1;
            }
        }
    }
    let edges = topology.edges();
    let mut ee = Vec::new();
    let mut close_ee_off_fan = 0;
    for a in 0..edges.len() {
        for b in a + 1..edges.len() {
            let (ea, eb) = (edges[a], edges[b]);
            if ea.iter().any(|v| eb.contains(v)) {
                continue;
            }
            let [a0, a1] = ea.map(|i| x[i as usize]);
            let [b0, b1] = eb.map(|i| x[i as usize]);
            let close = edge_edge_distance_squared(&a0, &a1, &b0, &b1) < reach * reach;
            if close && on_fan(&ea, &eb) {
                ee.push([a as u32, b as u32]);
            } else if close {
                close_ee_off_fan += 1;
            }
        }
    }
    assert_eq!(topology.excluded_point_triangle(), &pt[..]);
    assert_eq!(topology.excluded_edge_edge(), &ee[..]);
    assert!(!pt.is_empty() && !ee.is_empty());
    assert!(
        close_pt_off_fan > 0 && close_ee_off_fan > 0,
        "the reach reaches past the fan"
    );

    // The broad phase at rest with that reach keeps exactly the close pairs off the fan (boxes
    // within reach include them) and none on it.
    let mut out = CandidatePairs::new();
    BroadPhase::new().find(&topology, &x, None, reach, &mut out);
    check_against_brute_force(&topology, &x, None, reach, &out);
    let excluded: BTreeSet<_> = pt.iter().collect();
    assert!(out.point_triangle.iter().all(|p| !excluded.contains(p)));

    // A vertex and the triangle across its neighbour: vertex (0, 0) = 0 and the triangles of
    // vertex (1, 0) = 1 that do not contain 0 are within 1 of it, so excluded.
    for &t in topology.vertex_triangles(1) {
        if !triangles[t as usize].contains(&0) {
            assert!(topology.excluded_point_triangle().contains(&[0, t]));
        }
    }

    // Adding again changes nothing; a smaller reach on a fresh topology excludes fewer.
    let before = topology.clone();
    topology.exclude_close_at_rest(&x, reach);
    assert_eq!(topology, before);
    let mut tight = SurfaceTopology::new(x.len(), &triangles);
    tight.exclude_close_at_rest(&x, 0.5);
    assert!(tight.excluded_point_triangle().is_empty() && tight.excluded_edge_edge().is_empty());
    topology.clear_exclusions();
    assert!(topology.excluded_point_triangle().is_empty());
}

#[test]
fn empty_and_isolated_inputs() {
    let mut out = CandidatePairs {
        point_triangle: vec![[1, 2]],
        edge_edge: vec![[3, 4]],
    };
    let topology = SurfaceTopology::new(3, &[]);
    BroadPhase::new().find(&topology, &[V::zeros(); 3], None, 1.0, &mut out);
    assert_eq!(out, CandidatePairs::new());
    // One triangle: every pair shares a vertex. All vertices at one point: zero-size boxes.
    let topology = SurfaceTopology::new(3, &[[0, 1, 2]]);
    BroadPhase::new().find(&topology, &[V::zeros(); 3], None, 0.0, &mut out);
    assert_eq!(out, CandidatePairs::new());
    // Two triangles on the same point, reach 0: touching boxes count.
    let topology = SurfaceTopology::new(6, &[[0, 1, 2], [3, 4, 5]]);
    BroadPhase::new().find(&topology, &[V::zeros(); 6], None, 0.0, &mut out);
    assert_eq!(out.point_triangle.len(), 6);
    assert_eq!(out.edge_edge.len(), 9);
    // An infinite reach: every pair.
    let x: Vec<V> = (0..6).map(|i| V::new(i as f64 * 1e3, 0.0, 0.0)).collect();
    BroadPhase::new().find(&topology, &x, None, f64::INFINITY, &mut out);
    assert_eq!(out.point_triangle.len(), 6);
    assert_eq!(out.edge_edge.len(), 9);
}

#[test]
#[should_panic(expected = "one position per vertex")]
fn wrong_position_count_panics() {
    let topology = SurfaceTopology::new(3, &[[0, 1, 2]]);
    BroadPhase::new().find(
        &topology,
        &[V::zeros(); 2],
        None,
        0.0,
        &mut CandidatePairs::new(),
    );
}
