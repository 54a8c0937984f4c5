//! The kernels of hooke's implicit solvers, on cloth-40, cloth-80, cloth-160, cloth-320 and beam-8, generated
//! in code (docs/scenes.md; nothing is downloaded):
//!
//! - numeric factorisation (`SparseCholesky`) of PD's scalar matrix K(M + h²L)Kᵀ (Cholesky) and of
//!   the Newton Hessian M + h²∇²E on the free DOFs (LDLᵀ, as `Newton` factors it), with the
//!   factor's stored values printed at start-up;
//! - one projective dynamics iteration (`ProjectiveDynamics::solve` with one iteration) and its
//!   parts: the local step, the right-hand side, the 3-column solve. The target is an iteration
//!   costing at most 1.3 × the sum of its parts on cloth-160; the ratio is measured in interleaved
//!   rounds (each round times the iteration and each part once; medians over the rounds) and
//!   printed at start-up, beside criterion's own separate measurements;
//! - one CG iteration on the (clamped, so positive definite) Newton matrix with the block-Jacobi
//!   preconditioner, as the linearised integrator runs it;
//! - one Newton step (`Newton::minimize` with one iteration: Hessian refill, LDLᵀ, solve, line
//!   search on Φ).
//!
//! The state: the rest positions with a deterministic perturbation of 1 mm (so every spring has a
//! generic length and direction), inertial target y = x + h² g.
//!
//! Run: `cargo bench --bench solver_kernels` (a few minutes, most of it cloth-320), or some scenes:
//! `HOOKE_BENCH_SCENES=cloth-40,beam-8 cargo bench --bench solver_kernels`. Sample sizes are
//! small on purpose.

use hooke_solvers::Convergence;
use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use hooke_assembly::pd::{j_matrix, local_step, LaplacianPattern};
use hooke_assembly::{Definiteness, FreeDofs, HessianParams, HessianPattern};
use hooke_mesh::{Spring, SpringMesh};
use hooke_solvers::{
    BackwardEulerStep, BlockJacobi, CgParams, CholeskyParams, ConjugateGradient, Newton,
    NewtonParams, NewtonProblem, PdParams, ProjectiveDynamics, SparseCholesky, Symmetric,
};
use nalgebra::{Matrix3, Vector3};

const H: f64 = 1.0 / 30.0;

/// A scene's mesh, pins and the benchmark state.
struct Case {
    name: String,
    mesh: SpringMesh<3>,
    free: FreeDofs,
    x: Vec<Vector3<f64>>,
    y: Vec<Vector3<f64>>,
}

fn case(name: &str) -> Case {
    let (mesh, pinned): (SpringMesh<3>, Vec<u32>) = if let Some(n) = name.strip_prefix("cloth-") {
        let n: usize = n.parse().expect("cloth size");
        (
            hooke_mesh::generators::cloth(n, 1e3).expect("cloth"),
            vec![0, n as u32 - 1],
        )
    } else {
        let r: usize = name
            .strip_prefix("beam-")
            .and_then(|r| r.parse().ok())
            .expect("beam size");
        let mesh = hooke_mesh::generators::beam(r).expect("beam");
        let pinned = mesh
            .positions()
            .iter()
            .enumerate()
            .filter(|(_, p)| p.x == 0.0)
            .map(|(v, _)| v as u32)
            .collect();
        (mesh, pinned)
    };
    let n = mesh.vertex_count();
    let free = FreeDofs::new(n, &pinned).expect("pins in range");
    let x: Vec<Vector3<f64>> = mesh
        .positions()
        .iter()
        .enumerate()
        .map(|(k, p)| {
            if free.is_pinned(k) {
                return *p;
            }
            let k = k as f64;
            p + Vector3::new((k * 0.37).sin(), (k * 1.11).cos(), (k * 2.3).sin()) * 1e-3
        })
        .collect();
    let g = Vector3::new(0.0, -9.81, 0.0) * (H * H);
    let y = x
        .iter()
        .enumerate()
        .map(|(v, p)| if free.is_pinned(v) { *p } else { p + g })
        .collect();
    Case {
        name: name.to_string(),
        mesh,
        free,
        x,
        y,
    }
}

/// A dense n × 3 matrix to solve in place. The root package does not depend on faer, so it is
/// made from a faer value the workspace crates return: J of three springs, densified (its values
/// are overwritten before every solve).
fn three_columns(n_free: usize) -> impl FnMut(&[Vector3<f64>], &mut SparseCholesky) {
    let springs: Vec<Spring> = (0..3)
        .map(|c| Spring {
            i: c,
            j: c + 1,
            stiffness: 1.0,
            rest_length: 1.0,
        })
        .collect();
    let mut dense = j_matrix(n_free, &springs).to_dense();
    move |rhs: &[Vector3<f64>], cholesky: &mut SparseCholesky| {
        let mut m = dense.as_mut();
        for (f, r) in rhs.iter().enumerate() {
            for a in 0..3 {
                m[(f, a)] = r[a];
            }
        }
        cholesky.solve_in_place(m);
    }
}

fn kernels(c: &mut Criterion) {
    // The set-up (patterns, factorisations, the interleaved PD measurement) runs before
    // criterion's name filter applies: choose scenes with HOOKE_BENCH_SCENES to skip it.
    let chosen = std::env::var("HOOKE_BENCH_SCENES").ok();
    for name in ["cloth-40", "cloth-80", "cloth-160", "cloth-320", "beam-8"] {
        if chosen
            .as_deref()
            .is_none_or(|list| list.split(',').any(|s| s.trim() == name))
        {
            scene(c, &case(name));
        }
    }
}

fn scene(c: &mut Criterion, case: &Case) {
    let springs = case.mesh.springs();
    let masses = case.mesh.masses();
    let n = case.mesh.vertex_count();
    let n_free = case.free.free_count();
    let large = n > 50_000;
    let mut group = c.benchmark_group(&case.name);
    group.sample_size(10);
    group.warm_up_time(Duration::from_millis(if large { 500 } else { 1000 }));
    group.measurement_time(Duration::from_secs(if large { 10 } else { 3 }));

    // --- PD's matrix K(M + h²L)Kᵀ: Cholesky.
    let laplacian = LaplacianPattern::new(n, springs, Some(&case.free));
    let mut values = laplacian.new_values();
    laplacian.system_into(springs, masses, H, &mut values);
    // The factor kind projective dynamics itself chooses for this size, so that the 3-column solve
    // measured alone is the one inside its iteration (simplicial up to 50,000 unknowns).
    let pd_params = CholeskyParams {
        kind: ProjectiveDynamics::<3>::factor_kind_for(n_free),
        ..CholeskyParams::default()
    };
    let mut pd_cholesky =
        SparseCholesky::analyze(laplacian.symbolic(), pd_params).expect("symbolic analysis");
    pd_cholesky
        .factorize(laplacian.matrix(&values))
        .expect("M + h²L is positive definite");
    eprintln!(
        "{}: {n} vertices, {} springs; PD matrix {n_free}×{n_free}, factor {} values ({}, analysis {:.1} ms)",
        case.name,
        springs.len(),
        pd_cholesky.factor_nnz(),
        if pd_cholesky.is_supernodal() { "supernodal" } else { "simplicial" },
        pd_cholesky.analysis_time().as_secs_f64() * 1e3,
    );
    group.bench_function(BenchmarkId::new("factorize", "pd_matrix"), |b| {
        b.iter(|| pd_cholesky.factorize(laplacian.matrix(black_box(&values))))
    });

    // --- The Newton Hessian M + h²∇²E: LDLᵀ, as Newton factors it.
    let hessian = HessianPattern::<3>::new(n, springs, Some(&case.free));
    let mut h_values = hessian.new_values();
    let mut workspace = hessian.workspace();
    hessian.assemble_into(
        springs,
        &case.x,
        masses,
        H,
        HessianParams::default(),
        &mut workspace,
        &mut h_values,
    );
    let mut h_cholesky = SparseCholesky::analyze(hessian.symbolic(), CholeskyParams::default())
        .expect("symbolic analysis");
    let inertia = h_cholesky
        .factorize_ldlt(hessian.matrix(&h_values))
        .expect("LDLᵀ");
    eprintln!(
        "{}: Newton Hessian {}×{} ({} stored), LDLᵀ factor {} values, {} negative eigenvalue(s)",
        case.name,
        3 * n_free,
        3 * n_free,
        hessian.nnz(),
        h_cholesky.factor_nnz(),
        inertia.negative,
    );
    group.bench_function(BenchmarkId::new("factorize", "newton_hessian_ldlt"), |b| {
        b.iter(|| h_cholesky.factorize_ldlt(hessian.matrix(black_box(&h_values))))
    });

    // --- One PD iteration, and its parts.
    let mut pd = ProjectiveDynamics::<3>::new(
        springs,
        masses,
        &case.free,
        H,
        PdParams {
            max_iterations: 1,
            ..PdParams::default()
        },
    )
    .expect("PD factors");
    let mut x = case.y.clone();
    let mut d: Vec<Vector3<f64>> = springs
        .iter()
        .map(|s| Vector3::new(s.rest_length, 0.0, 0.0))
        .collect();
    let mut rhs = vec![Vector3::zeros(); n_free];
    let mut solve3 = three_columns(n_free);
    local_step(springs, &case.x, &mut d, true);
    laplacian.rhs_into(springs, &d, &case.y, &case.x, masses, H, &mut rhs);
    {
        // Interleaved rounds: every round times one iteration, each part once and the parts back to
        // back, so that all five see the same state of a shared machine (a slow spell lands on all
        // of them, not on whichever was being timed then). Medians over the rounds, and the median
        // of the rounds' own ratios.
        let rounds = if large { 41 } else { 101 };
        let time = |f: &mut dyn FnMut()| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64()
        };
        let mut samples: [Vec<f64>; 6] = Default::default();
        for round in 0..=rounds {
            let iteration = time(&mut || {
                black_box(pd.solve(springs, &case.y, &mut x).unwrap());
            });
            let local = time(&mut || local_step(springs, &case.x, &mut d, true));
            let right = time(&mut || {
                laplacian.rhs_into(springs, &d, &case.y, &case.x, masses, H, &mut rhs)
            });
            let solve = time(&mut || solve3(&rhs, &mut pd_cholesky));
            // The three parts back to back, as the iteration runs them: what is left between this
            // and the iteration is PD's own code; between this and the sum of the parts alone, the
            // parts evicting each other's data from the caches.
            let back_to_back = time(&mut || {
                local_step(springs, &case.x, &mut d, true);
                laplacian.rhs_into(springs, &d, &case.y, &case.x, masses, H, &mut rhs);
                solve3(&rhs, &mut pd_cholesky);
            });
            if round > 0 {
                // Round 0 warms the caches and rayon's pool.
                let ratio = iteration / (local + right + solve);
                for (v, t) in
                    samples
                        .iter_mut()
                        .zip([iteration, local, right, solve, back_to_back, ratio])
                {
                    v.push(t);
                }
            }
        }
        let [iteration, local, right, solve, back_to_back, ratio] = samples.map(|mut v| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        });
        let sum = local + right + solve;
        eprintln!(
            "{}: PD iteration {:.3} ms; parts: local {:.3} + rhs {:.3} + 3-column solve {:.3} = {:.3} ms; iteration / parts = {:.2}, median of the rounds' ratios {:.2} (target: ≤ 1.3 on cloth-160); the parts back to back {:.3} ms ({:.2} of their sum alone); medians of {rounds} interleaved rounds",
            case.name,
            iteration * 1e3,
            local * 1e3,
            right * 1e3,
            solve * 1e3,
            sum * 1e3,
            iteration / sum,
            ratio,
            back_to_back * 1e3,
            back_to_back / sum,
        );
    }
    group.bench_function(BenchmarkId::new("pd", "iteration"), |b| {
        b.iter(|| pd.solve(springs, &case.y, &mut x).unwrap())
    });
    group.bench_function(BenchmarkId::new("pd", "local_step"), |b| {
        b.iter(|| local_step(springs, black_box(&case.x), &mut d, true))
    });
    group.bench_function(BenchmarkId::new("pd", "rhs"), |b| {
        b.iter(|| {
            laplacian.rhs_into(
                springs,
                &d,
                black_box(&case.y),
                &case.x,
                masses,
                H,
                &mut rhs,
            )
        })
    });
    group.bench_function(BenchmarkId::new("pd", "solve_3_columns"), |b| {
        b.iter(|| solve3(black_box(&rhs), &mut pd_cholesky))
    });

    // --- One CG iteration on the clamped Newton matrix, block-Jacobi preconditioned.
    hessian.assemble_into(
        springs,
        &case.x,
        masses,
        H,
        HessianParams {
            definiteness: Definiteness::Clamped,
            ..HessianParams::default()
        },
        &mut workspace,
        &mut h_values,
    );
    let dense_diagonal = |f: usize| {
        // The 3×3 diagonal block of free vertex f, from the sparse matrix's columns.
        let m = hessian.matrix(&h_values);
        Matrix3::from_fn(|a, b| {
            let col = 3 * f + b;
            let rows = m.symbolic().row_idx_of_col_raw(col);
            let start = m.symbolic().col_ptr()[col];
            rows.iter()
                .position(|&r| r == 3 * f + a)
                .map_or(0.0, |k| h_values[start + k])
        })
    };
    let mut preconditioner =
        BlockJacobi::<3>::from_blocks((0..n_free).map(dense_diagonal)).expect("blocks invert");
    let b_vec: Vec<f64> = (0..3 * n_free).map(|k| ((k as f64) * 0.7).sin()).collect();
    let mut unknowns = vec![0.0; 3 * n_free];
    let mut cg = ConjugateGradient::new(CgParams {
        tolerance: 0.0,
        max_iterations: 1,
    });
    group.bench_function(BenchmarkId::new("cg", "iteration"), |b| {
        b.iter(|| {
            unknowns.iter_mut().for_each(|u| *u = 0.0);
            cg.solve(
                &Symmetric(hessian.matrix(&h_values)),
                &mut preconditioner,
                black_box(&b_vec),
                &mut unknowns,
            )
        })
    });

    // --- One Newton step on Φ from y.
    let mut objective = BackwardEulerStep::new(springs, masses, case.free.clone(), H);
    let mut newton = Newton::new(
        objective.pattern(),
        NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: 0.0,
            max_iterations: 1,
            ..NewtonParams::default()
        },
    )
    .expect("analysis");
    let mut xf = vec![0.0; objective.dim()];
    group.bench_function(BenchmarkId::new("newton", "step"), |b| {
        b.iter(|| {
            objective.set_step(&case.y, &case.x, &mut xf);
            newton.minimize(&mut objective, &mut xf)
        })
    });
    group.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
