//! No allocation per iteration with self-contact and its friction: after a step is set (the lag
//! sizes its buffers), evaluating backward Euler's Φ, its change, gradient and Hessian at new
//! iterates allocates no more for ten iterations than for one, serially and in parallel, with and
//! without friction (measured: none at all). Measured with a
//! counting global allocator, in one test function (no other test allocates concurrently), the
//! fewest of three identical measurements (the harness's thread allocates on its own schedule).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use hooke_assembly::FreeDofs;
use hooke_mesh::Spring;
use hooke_solvers::backward_euler::{AdaptiveStiffness, SelfContactModel};
use hooke_solvers::{BackwardEulerStep, NewtonProblem};
use nalgebra::Vector3;

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    f();
    ALLOCATIONS.load(Ordering::SeqCst) - before
}

/// Two n×n sheets on the unit square of the xz-plane, the second `gap` above the first and
/// shifted by a third of a spacing; springs along the grid's edges.
fn two_sheets(n: usize, gap: f64) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>, Vec<Spring>) {
    let s = 1.0 / (n - 1) as f64;
    let mut positions = Vec::new();
    for (dy, d) in [(0.0, 0.0), (gap, s / 3.0)] {
        for j in 0..n {
            for i in 0..n {
                positions.push(Vector3::new(i as f64 * s + d, dy, j as f64 * s + d));
            }
        }
    }
    let (mut triangles, mut springs) = (Vec::new(), Vec::new());
    for sheet in 0..2 {
        let o = (sheet * n * n) as u32;
        let n = n as u32;
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let (a, b) = (o + j * n + i, o + j * n + i + 1);
                let (c, d) = (a + n, b + n);
                triangles.push([a, c, b]);
                triangles.push([b, c, d]);
                for (p, q) in [(a, b), (a, c), (b, c)] {
                    springs.push(Spring {
                        i: p,
                        j: q,
                        stiffness: 1e3,
                        rest_length: s,
                    });
                }
            }
        }
    }
    (positions, triangles, springs)
}

#[test]
fn self_contact_friction_does_not_allocate_per_iteration() {
    assert!(allocations(|| drop(std::hint::black_box(vec![0u8; 64]))) >= 1);
    let (n, gap, h) = (6, 5e-4, 1.0 / 30.0);
    let (x0, triangles, springs) = two_sheets(n, gap);
    let count = x0.len();
    // The adaptive stiffness's gap check after every iterate too, where it is on.
    for (parallel, mu, adaptive) in [(true, 0.0, false), (false, 0.3, true), (true, 0.3, true)] {
        let free = FreeDofs::new(count, &[]).unwrap();
        let mut step = BackwardEulerStep::<3>::new(&springs, &vec![0.01; count], free, h);
        step.set_parallel(parallel);
        step.set_self_contact(Some(SelfContactModel {
            triangles: triangles.clone(),
            rest_positions: x0.clone(),
            distance: 1e-3,
            stiffness: 1e2,
            friction: mu,
            friction_velocity: 1e-3,
        }))
        .unwrap();
        step.set_adaptive_stiffness(adaptive.then(AdaptiveStiffness::default))
            .unwrap();
        // The upper sheet slides along x.
        let velocities: Vec<Vector3<f64>> = (0..count)
            .map(|v| Vector3::new(if v >= count / 2 { 0.3 } else { 0.0 }, 0.0, 0.0))
            .collect();
        let y: Vec<Vector3<f64>> = x0.iter().zip(&velocities).map(|(x, v)| x + v * h).collect();
        let mut unknowns = vec![0.0; step.dim()];
        step.set_step_with_velocities(&y, &x0, Some(&velocities), &mut unknowns);
        let start = unknowns.clone();
        let mut gradient = vec![0.0; unknowns.len()];
        // Iterates a few µm apart, the gap staying within d̂ (no new candidates are searched).
        let mut round = |k: usize, trial: &mut Vec<f64>, x: &mut Vec<f64>| {
            for (i, (t, s)) in x.iter_mut().zip(&start).enumerate() {
                *t = s + 1e-6 * ((i * 7 + k) as f64).sin();
            }
            for (i, (t, s)) in trial.iter_mut().zip(x.iter()).enumerate() {
                *t = s + 1e-7 * ((i * 3 + k) as f64).cos();
            }
            std::hint::black_box(step.objective(x));
            std::hint::black_box(step.objective_change(x, trial));
            step.gradient(x, &mut gradient);
            step.update_pattern(x);
            std::hint::black_box(step.hessian(x).val()[0]);
            std::hint::black_box(step.convexified_hessian(x).unwrap().val()[0]);
            std::hint::black_box(step.after_iterate(x));
        };
        let (mut x, mut trial) = (start.clone(), start.clone());
        // Warm-up: buffers sized, the pattern holding the pairs.
        for k in 0..3 {
            round(k, &mut trial, &mut x);
        }
        let mut measure = |rounds: usize| {
            let mut fewest = usize::MAX;
            for _ in 0..3 {
                let mut count = 0;
                rayon::scope(|_| {
                    count = allocations(|| {
                        for k in 0..rounds {
                            round(k, &mut trial, &mut x);
                        }
                    })
                });
                fewest = fewest.min(count);
            }
            fewest
        };
        let (one, ten) = (measure(1), measure(10));
        assert_eq!(
            one, ten,
            "μ = {mu}, parallel {parallel}, adaptive {adaptive}: {one} allocations in one \
             iteration, {ten} in ten"
        );
    }
}
