//! The time loop does not allocate its buffers per step: a step of an implicit integrator (linearised
//! with block Jacobi or CG, Newton, projective dynamics) allocates only its solver's report (the
//! residual history, reserved once per solve so that the iterations never allocate), whatever the
//! step; an explicit step allocates nothing. Measured with a counting global allocator that counts
//! only the allocations of the thread being measured: the steps run serially (`parallel: false`),
//! and the process's other threads (the test harness's) allocate on their own schedule, which made
//! a process-wide count fail about one run in three (4 foreign allocations in a step).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use hooke_mesh::generators;
use hooke_sim::{
    ExternalForce, Integrator, LinearSolver, PinMethod, Pins, Scene, Settings, Simulation,
};
use nalgebra::Vector3;

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Whether this thread's allocations are counted (const-initialised: reading it never
    /// allocates, so the allocator may).
    static COUNTED: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTED.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTED.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made by `f` on this thread.
fn allocations(f: impl FnOnce()) -> usize {
    COUNTED.with(|c| c.set(true));
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    f();
    let count = ALLOCATIONS.load(Ordering::SeqCst) - before;
    COUNTED.with(|c| c.set(false));
    count
}

#[test]
fn steps_allocate_only_the_solver_report() {
    // The counter sees allocations at all.
    assert!(allocations(|| drop(std::hint::black_box(vec![0u8; 64]))) >= 1);
    // cloth-8 with k = 10 N/m at h = 1/100 s: β h² k / m = 0.064, block diagonally dominant, so
    // block Jacobi converges (to 1e-8 in a few tens of iterations) and never falls back to the
    // clamped Hessian; the iteration count varies from step to step, which the count must not see.
    let n = 8;
    let mesh = generators::cloth(n, 10.0).unwrap();
    let scene = Scene::new(mesh, 0.01)
        .unwrap()
        .with_pins(Pins::Vertices(vec![0, n as u32 - 1]))
        .unwrap()
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: Vector3::new(0.0, -9.81, 0.0),
        }])
        .unwrap();
    for (solver, pins) in [
        (LinearSolver::Jacobi, PinMethod::Reduction),
        (LinearSolver::ConjugateGradient, PinMethod::Reduction),
        (LinearSolver::Jacobi, PinMethod::CounterForce),
        (LinearSolver::ConjugateGradient, PinMethod::CounterForce),
    ] {
        let mut settings = Settings {
            integrator: Integrator::Linearized,
            pins,
            // Serial: rayon's pool would allocate on its own schedule.
            parallel: false,
            ..Settings::default()
        };
        settings.linearized.solver = solver;
        let mut sim = Simulation::new(scene.clone(), scene.initial_state(), settings).unwrap();
        sim.step().unwrap(); // warm-up: the solvers size their workspaces on the first solve
        let mut iterations = Vec::new();
        for step in 2..=12 {
            let mut report = None;
            let count = allocations(|| report = Some(sim.step().unwrap()));
            let report = report.unwrap();
            assert!(
                !report.clamped_hessian,
                "{solver}, {pins}, step {step}: clamped"
            );
            let summary = report
                .solver
                .expect("the linearised step reports its solve");
            iterations.push(summary.iterations);
            assert_eq!(
                count, 1,
                "{solver}, {pins}, step {step}: {count} allocations (expected 1, the solve's \
                 report), {} iterations",
                summary.iterations
            );
        }
        assert!(
            iterations.iter().all(|&i| i > 1) && iterations.iter().any(|&i| i != iterations[0]),
            "{solver}, {pins}: the steps should iterate, by varying counts: {iterations:?}"
        );
    }
    for (integrator, pins, expected) in [
        (Integrator::Newton, PinMethod::Reduction, 1),
        (Integrator::Newton, PinMethod::CounterForce, 1),
        (Integrator::ProjectiveDynamics, PinMethod::Reduction, 1),
        (Integrator::SymplecticEuler, PinMethod::Reduction, 0),
    ] {
        let settings = Settings {
            integrator,
            pins,
            parallel: false,
            ..Settings::default()
        };
        let mut sim = Simulation::new(scene.clone(), scene.initial_state(), settings).unwrap();
        sim.step().unwrap();
        for step in 2..=6 {
            let count = allocations(|| {
                sim.step().unwrap();
            });
            assert_eq!(
                count, expected,
                "{integrator}, {pins}, step {step}: {count} allocations, expected {expected}"
            );
        }
    }
}
