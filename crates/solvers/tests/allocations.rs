//! No allocation per iteration: every solver's allocations during a solve must not grow with the
//! number of iterations it runs (a solve may allocate its report once, sized up front). Measured
//! with a counting global allocator; one test function, so no other test allocates concurrently.
//! The count is process-wide (parallel projective dynamics allocates, if at all, on rayon's
//! threads), and the test harness's own thread allocates a few times on its own schedule (seen in
//! about one run in three), so each figure is the fewest of three identical measurements: an
//! allocation per iteration shows in every one of them.

use faer::sparse::{SparseColMat, Triplet};
use hooke_assembly::FreeDofs;
use hooke_mesh::generators;
use hooke_solvers::{
    Amg, AmgParams, AndersonParams, AndersonPd, BackwardEulerStep, BlockJacobi, CgParams,
    ChebyshevParams, ChebyshevPd, ConjugateGradient, GlobalSolveKind, Jacobi, JacobiParams, Newton,
    NewtonParams, NewtonProblem, PdParams, Preconditioner, ProjectiveDynamics, Relaxation,
    Symmetric,
};
use nalgebra::{Matrix3, Vector3};

mod common;
use common::inertial_target;

#[path = "common/counting.rs"]
mod counting;
use counting::allocations;

/// Runs `f` on one of rayon's threads. The solvers' parallel loops and sums (above 8,192 terms)
/// started from a thread outside rayon's pool go through its shared job queue, whose storage grows
/// by a block for every 63 jobs: rayon's allocation, amortised, not the solver's. Started on a
/// pool thread they go to that thread's own deque, which keeps its storage: measured there, any
/// allocation that grows with the iterations is the solver's own.
fn in_rayon_pool(f: impl FnOnce() + Send) {
    rayon::scope(|_| f())
}

/// The fewest allocations of three runs of the same measurement (see the module documentation).
fn fewest(mut measure: impl FnMut() -> usize) -> usize {
    (0..3).map(|_| measure()).min().expect("three runs")
}

#[test]
fn solvers_do_not_allocate_per_iteration() {
    // The counter sees allocations at all.
    assert!(allocations(|| drop(std::hint::black_box(vec![0u8; 64]))) >= 1);
    let n = 16;
    let mesh = generators::cloth(n, 1e3).unwrap();
    let pinned = [0, n as u32 - 1];
    let h = 1.0 / 30.0;
    let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
    let y = inertial_target(mesh.positions(), &pinned, |_, x| {
        Vector3::new(0.0, -9.81 * h * h, 0.0) + Vector3::new(0.0, 0.0, 0.01 * x.x)
    });

    // Projective dynamics, serial and parallel local steps; the direct path on cloth-16, the
    // multilevel one on cloth-16 (one level: the coarsest solve alone) and on cloth-96 (two
    // levels, and above the sizes where its products and sums go parallel).
    let big = generators::cloth(96, 1e3).unwrap();
    let big_free = FreeDofs::new(big.vertex_count(), &[0, 95]).unwrap();
    let big_y = inertial_target(big.positions(), &[0, 95], |_, x| {
        Vector3::new(0.0, -9.81 * h * h, 0.0) + Vector3::new(0.0, 0.0, 0.01 * x.x)
    });
    for (global_solve, mesh, free, y) in [
        (GlobalSolveKind::Direct, &mesh, &free, &y),
        (GlobalSolveKind::Multilevel, &mesh, &free, &y),
        (GlobalSolveKind::Multilevel, &big, &big_free, &big_y),
    ] {
        for parallel in [false, true] {
            let mut pd = ProjectiveDynamics::<3>::new(
                mesh.springs(),
                mesh.masses(),
                free,
                h,
                PdParams {
                    parallel,
                    global_solve,
                    ..Default::default()
                },
            )
            .unwrap();
            let mut run = |iterations: usize| {
                pd.params.max_iterations = iterations;
                let mut x = y.clone();
                let mut count = 0;
                // Inside rayon's pool (see `in_rayon_pool`): the multilevel path's products
                // and sums fork on cloth-96.
                in_rayon_pool(|| {
                    count = allocations(|| {
                        pd.solve(mesh.springs(), y, &mut x).unwrap();
                    })
                });
                count
            };
            run(3); // warm-up: rayon's pool and any lazily sized buffer
            let (few, many) = (fewest(|| run(2)), fewest(|| run(40)));
            assert_eq!(
                few,
                many,
                "PD {global_solve:?} on {} vertices (parallel: {parallel}): {few} allocations in \
                 2 iterations, {many} in 40",
                mesh.vertex_count()
            );
        }
    }

    // Chebyshev PD (Φ checked every few iterations, with rollbacks possible) and Anderson PD (its
    // window's history preallocated), on cloth-16 serial and parallel, and on cloth-48, whose
    // 13,000 springs are above the size where the change of Φ sums in parallel (8,192), on a
    // rayon thread (see `in_rayon_pool`).
    for (n, parallel) in [(16, false), (16, true), (48, true)] {
        let mesh = generators::cloth(n, 1e3).unwrap();
        let pinned = [0, n as u32 - 1];
        let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
        let y = inertial_target(mesh.positions(), &pinned, |_, x| {
            Vector3::new(0.0, -9.81 * h * h, 0.0) + Vector3::new(0.0, 0.0, 0.01 * x.x)
        });
        let pd_params = PdParams {
            parallel,
            ..Default::default()
        };
        let mut pd =
            ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, h, pd_params)
                .unwrap();
        let mut x = y.clone();
        // The solvers are built outside the measurement: their construction sizes every buffer.
        let mut measure = |solver: &str, max_iterations: usize| {
            x.copy_from_slice(&y);
            let mut chebyshev = ChebyshevPd::<3>::new(
                mesh.vertex_count(),
                ChebyshevParams {
                    max_iterations,
                    rate: 0.99,
                    ..Default::default()
                },
            )
            .unwrap();
            let mut anderson = AndersonPd::<3>::new(
                mesh.vertex_count(),
                AndersonParams {
                    max_iterations,
                    ..Default::default()
                },
            )
            .unwrap();
            let mut count = 0;
            in_rayon_pool(|| {
                count = allocations(|| {
                    let iterations = if solver == "chebyshev" {
                        let r = chebyshev.solve(&mut pd, mesh.springs(), &y, &mut x);
                        r.unwrap().iterations
                    } else {
                        let r = anderson.solve(&mut pd, mesh.springs(), &y, &mut x).unwrap();
                        assert!(max_iterations < 10 || r.accepted > 0, "{r:?}");
                        r.iterations
                    };
                    assert_eq!(iterations, max_iterations);
                })
            });
            count
        };
        for solver in ["chebyshev", "anderson"] {
            measure(solver, 3); // warm-up
            let (few, many) = (
                fewest(|| measure(solver, 2)),
                fewest(|| measure(solver, 40)),
            );
            assert_eq!(
                few, many,
                "{solver} on cloth-{n} (parallel: {parallel}): {few} allocations in 2 iterations, {many} in 40"
            );
        }
    }

    // Newton on backward Euler, with the default relaxation and with one that never skips and
    // eliminates wherever the error is (the steps from rest may all be trusted, or their error
    // spread out, which would leave the sweeps and the elimination unmeasured). The elimination's
    // patches are built once, before the first iteration of the first solve.
    for relaxation in [
        Relaxation::BUCKLING,
        Relaxation {
            trusted_model: 0.0,
            region_concentration: 0.0,
            ..Relaxation::BUCKLING
        },
    ] {
        let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free.clone(), h);
        let params = NewtonParams {
            relaxation,
            ..NewtonParams::default()
        };
        let mut newton = Newton::new(step.pattern(), params).unwrap();
        let mut unknowns = vec![0.0; step.dim()];
        let mut run = |iterations: usize| {
            newton.params.max_iterations = iterations;
            newton.params.tolerance = 0.0;
            step.set_step(&y, mesh.positions(), &mut unknowns);
            allocations(|| {
                let report = newton.minimize(&mut step, &mut unknowns).unwrap();
                assert_eq!(report.iterations, iterations);
                if relaxation.trusted_model == 0.0 {
                    assert_eq!(report.relaxation_sweeps, iterations * relaxation.sweeps);
                    assert!(report.region_solves >= iterations, "{report:#?}");
                }
            })
        };
        run(2);
        let (few, many) = (fewest(|| run(1)), fewest(|| run(4)));
        assert_eq!(
            few, many,
            "Newton ({relaxation:?}): {few} allocations in 1 iteration, {many} in 4"
        );
    }

    // Newton on the Hessian made definite spring by spring (its loads and weights are buffers of
    // the step), and the progressive policy that switches to the exact Hessian.
    for indefinite in [
        hooke_solvers::IndefinitePolicy::Projected,
        hooke_solvers::IndefinitePolicy::ProjectedThenExact,
    ] {
        let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free.clone(), h);
        let params = NewtonParams {
            indefinite,
            ..NewtonParams::default()
        };
        let mut newton = Newton::new(step.pattern(), params).unwrap();
        let mut unknowns = vec![0.0; step.dim()];
        let mut run = |iterations: usize| {
            newton.params.max_iterations = iterations;
            newton.params.tolerance = 0.0;
            step.set_step(&y, mesh.positions(), &mut unknowns);
            allocations(|| {
                let report = newton.minimize(&mut step, &mut unknowns).unwrap();
                assert_eq!(report.iterations, iterations);
            })
        };
        run(2);
        let (few, many) = (fewest(|| run(1)), fewest(|| run(4)));
        assert_eq!(
            few, many,
            "Newton ({indefinite:?}): {few} allocations in 1 iteration, {many} in 4"
        );
    }

    // Once its patches are built, an elimination allocates nothing at all: not in its set-up,
    // whose work does not depend on the inner iterations, nor in the inner Newton's iterations.
    {
        let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free.clone(), h);
        let mut start = vec![0.0; step.dim()];
        step.set_step(&y, mesh.positions(), &mut start);
        let mut run = |region_iterations: usize| {
            let relaxation = Relaxation {
                region_iterations,
                region_tolerance: 0.0,
                // Solve the patches however the error is spread.
                region_concentration: 0.0,
                ..Relaxation::BUCKLING
            };
            step.prepare_relaxation(relaxation);
            let mut x = start.clone();
            allocations(|| {
                let work = step.relax(&mut x, relaxation).unwrap();
                assert!(work.region_solves >= 1, "{work:?}");
                assert!(work.region_iterations <= work.region_solves * region_iterations);
                if region_iterations > 1 {
                    assert!(work.region_iterations > work.region_solves, "{work:?}");
                }
            })
        };
        for region_iterations in [1, 6] {
            run(region_iterations); // builds the cover for this iteration limit
            let count = fewest(|| run(region_iterations));
            assert_eq!(
                count, 0,
                "an elimination with {region_iterations} inner iterations: {count} allocations"
            );
        }
    }

    // CG and block Jacobi on a 3×3-block diagonally dominant system with more unknowns (9,000)
    // than the size above which dot products and norms sum in parallel (8,192), so that their
    // parallel path is measured too.
    let blocks = 3000;
    let dim = 3 * blocks;
    let mut triplets = Vec::new();
    let mut diagonal = Vec::new();
    for b in 0..blocks {
        let block = Matrix3::new(8.0, 1.0, 0.5, 1.0, 7.0, 0.25, 0.5, 0.25, 9.0);
        diagonal.push(block);
        for r in 0..3 {
            for c in 0..3 {
                triplets.push(Triplet::new(3 * b + r, 3 * b + c, block[(r, c)]));
            }
        }
        if b + 1 < blocks {
            for a in 0..3 {
                triplets.push(Triplet::new(3 * b + a, 3 * b + 3 + a, -1.0));
                triplets.push(Triplet::new(3 * b + 3 + a, 3 * b + a, -1.0));
            }
        }
    }
    let matrix = SparseColMat::try_new_from_triplets(dim, dim, &triplets).unwrap();
    let operator = Symmetric(matrix.as_ref());
    let mut preconditioner = BlockJacobi::<3>::from_blocks(diagonal.iter().copied()).unwrap();
    let b: Vec<f64> = (0..dim).map(|i| ((i * 7) % 11) as f64 - 5.0).collect();
    let mut cg = ConjugateGradient::new(CgParams::default());
    let mut run = |iterations: usize| {
        cg.params.max_iterations = iterations;
        cg.params.tolerance = 0.0;
        let mut x = vec![0.0; dim];
        // On one of rayon's threads: a parallel sum started from outside the pool goes through
        // rayon's shared job queue, which allocates a block of its own storage for every 63 jobs;
        // inside the pool the jobs go to the thread's own deque (see `in_rayon_pool`).
        allocations(|| {
            in_rayon_pool(|| {
                let _ = cg.solve(&operator, &mut preconditioner, &b, &mut x);
            })
        })
    };
    run(3);
    let (few, many) = (fewest(|| run(2)), fewest(|| run(20)));
    assert_eq!(
        few, many,
        "CG: {few} allocations in 2 iterations, {many} in 20"
    );

    let inverses = BlockJacobi::<3>::from_blocks(diagonal.iter().copied()).unwrap();
    let mut jacobi = Jacobi::new(JacobiParams::default());
    let mut run = |iterations: usize| {
        jacobi.params.max_iterations = iterations;
        jacobi.params.tolerance = 0.0;
        let mut x = vec![0.0; dim];
        allocations(|| {
            in_rayon_pool(|| {
                let _ = jacobi.solve(&operator, &inverses, &b, &mut x);
            })
        })
    };
    run(3);
    let (few, many) = (fewest(|| run(2)), fewest(|| run(20)));
    assert_eq!(
        few, many,
        "Jacobi: {few} allocations in 2 iterations, {many} in 20"
    );

    // Across steps: the diagonal blocks are refilled in place with new values (a new matrix on the
    // same pattern, as the linearised integrator does every step). The refill allocates nothing, so
    // 40 steps of refill + solve allocate 40 times what one solve does (its report), however many
    // iterations each runs.
    let mut diagonal_blocks = BlockJacobi::<3>::identity(blocks);
    let mut block_values = diagonal.clone();
    let mut refill = |step: usize| {
        let scale = 1.0 + 0.01 * step as f64;
        for (value, block) in block_values.iter_mut().zip(&diagonal) {
            *value = block * scale;
        }
        allocations(|| {
            diagonal_blocks
                .refill(block_values.iter().copied())
                .unwrap()
        })
    };
    for step in 0..40 {
        let count = fewest(|| refill(step));
        assert_eq!(count, 0, "BlockJacobi::refill allocated {count} times");
    }
    let mut steps = |count: usize, iterations: usize| {
        jacobi.params.max_iterations = iterations;
        jacobi.params.tolerance = 0.0;
        let mut x = vec![0.0; dim];
        let mut block_values = diagonal.clone();
        allocations(|| {
            in_rayon_pool(|| {
                for step in 0..count {
                    let scale = 1.0 + 0.01 * step as f64;
                    for (value, block) in block_values.iter_mut().zip(&diagonal) {
                        *value = block * scale;
                    }
                    diagonal_blocks
                        .refill(block_values.iter().copied())
                        .unwrap();
                    let _ = jacobi.solve(&operator, &diagonal_blocks, &b, &mut x);
                }
            })
        })
    };
    steps(2, 3);
    let (two, forty) = (fewest(|| steps(2, 2)), fewest(|| steps(40, 20)));
    assert_eq!(
        20 * two,
        forty,
        "Jacobi with refilled blocks: {two} allocations in 2 steps of 2 iterations, {forty} in 40 \
         steps of 20"
    );
    assert_eq!(
        two,
        2 * few,
        "Jacobi with refilled blocks: {two} allocations in 2 steps, {few} in one solve"
    );

    // AMG: no allocation in a V-cycle, nor per PCG iteration with it.
    let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free.clone(), h);
    let mut unknowns = vec![0.0; step.dim()];
    step.set_step(&y, mesh.positions(), &mut unknowns);
    let hessian = step.convexified_hessian(&unknowns).unwrap();
    let hessian = SparseColMat::new(
        hessian.symbolic().to_owned().unwrap(),
        hessian.val().to_vec(),
    );
    let modes = Amg::rigid_body_modes(&unknowns);
    let amg_params = AmgParams {
        max_coarse: 40,
        ..AmgParams::default()
    };
    let mut amg = Amg::new(hessian.as_ref(), 3, &modes, amg_params).unwrap();
    assert!(amg.level_count() >= 3);
    let r: Vec<f64> = (0..step.dim()).map(|i| (i as f64 * 0.37).sin()).collect();
    let mut z = vec![0.0; r.len()];
    let cycles = fewest(|| {
        allocations(|| {
            for _ in 0..20 {
                Preconditioner::apply(&mut amg, &r, &mut z);
            }
        })
    });
    assert_eq!(cycles, 0, "20 V-cycles allocated {cycles} times");
    let mut amg_cg = ConjugateGradient::new(CgParams::default());
    let mut pcg = |iterations: usize| {
        amg_cg.params.max_iterations = iterations;
        amg_cg.params.tolerance = 0.0;
        let mut x = vec![0.0; r.len()];
        allocations(|| {
            let _ = amg_cg.solve(&Symmetric(hessian.as_ref()), &mut amg, &r, &mut x);
        })
    };
    pcg(3);
    let (few, many) = (fewest(|| pcg(2)), fewest(|| pcg(30)));
    assert_eq!(
        few, many,
        "PCG with AMG: {few} allocations in 2 iterations, {many} in 30"
    );
}
