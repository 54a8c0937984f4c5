//! Projective dynamics' multilevel global step (docs/solvers.md §6.1): it reaches Newton's
//! minimiser, every iteration lowers Φ, ten iterations land where the direct path's do, its
//! preconditioner (one V-cycle) drives L-BFGS to x*, the result does not depend on the thread
//! count, and `GlobalSolveKind::Auto` takes it by size and over the memory budget.

use hooke_assembly::FreeDofs;
use hooke_mesh::{generators, SpringMesh};
use hooke_solvers::{
    AmgParams, CholeskyError, CholeskyParams, Convergence, GlobalSolveKind, Lbfgs, LbfgsParams,
    MemoryBudget, NewtonProblem, PdError, PdMultilevelParams, PdParams, ProjectiveDynamics,
    StopReason, MULTILEVEL_PD_UNKNOWNS,
};

use crate::chebyshev::{step, Step, V};
use crate::common::on_threads;
use crate::waved_step;

const H: f64 = 1.0 / 30.0;

/// PD parameters on the multilevel path, with a hierarchy of several levels even on these small
/// meshes (the default stops coarsening at 1000 unknowns).
fn multilevel() -> PdParams {
    PdParams {
        global_solve: GlobalSolveKind::Multilevel,
        multilevel: PdMultilevelParams {
            amg: AmgParams {
                max_coarse: 20,
                ..AmgParams::default()
            },
            ..PdMultilevelParams::default()
        },
        ..PdParams::default()
    }
}

fn pd(mesh: &SpringMesh<3>, pinned: &[u32], params: PdParams) -> ProjectiveDynamics<3> {
    let free = FreeDofs::new(mesh.vertex_count(), pinned).unwrap();
    ProjectiveDynamics::new(mesh.springs(), mesh.masses(), &free, H, params).unwrap()
}

/// The waved step of the Chebyshev tests with its PD on the multilevel path.
fn multilevel_step(mesh: SpringMesh<3>, pinned: &[u32]) -> Step {
    let mut s = step(mesh, pinned, H, 0.05);
    s.pd = pd(&s.mesh, pinned, multilevel());
    assert_eq!(s.pd.global_solve(), GlobalSolveKind::Multilevel);
    assert_eq!(s.pd.factor_nnz(), 0, "the multilevel path stores no factor");
    s
}

fn reaches_newton(mesh: SpringMesh<3>, pinned: &[u32]) {
    let mut s = multilevel_step(mesh, pinned);
    let (x, report) = s.solve_plain(PdParams {
        max_iterations: 40_000,
        tolerance: 1e-9,
        ..multilevel()
    });
    let error = s.objective_error(&x);
    eprintln!(
        "{} iterations, {} CG iterations, {:?}, objective error {error:e}",
        report.iterations, report.linear_iterations, report.stop
    );
    assert_eq!(report.stop, StopReason::Converged);
    assert!(report.linear_iterations >= report.iterations);
    // docs/model.md §9.2's objective error; the bound these tests hold solvers to.
    assert!(error.abs() <= 1e-10, "objective error {error:e}");
}

#[test]
fn multilevel_pd_reaches_newtons_solution_on_cloth_10() {
    reaches_newton(generators::cloth(10, 1e3).unwrap(), &[0, 9]);
}

#[test]
fn multilevel_pd_reaches_newtons_solution_on_beam_2() {
    let mesh = generators::beam(2).unwrap();
    let clamped = waved_step::clamped(&mesh);
    reaches_newton(mesh, &clamped);
}

/// Each CG iteration from the current iterate lowers the global step's quadratic, so Φ never
/// rises, even with a single CG iteration per global step. The recorded Φ are rounded values of
/// a sum of about |Φ|: a rise within 8 ε |Φ| is rounding.
#[test]
fn every_iteration_lowers_the_objective() {
    for tolerance in [0.0, 0.5, 0.99] {
        let mut s = multilevel_step(generators::cloth(24, 1e3).unwrap(), &[0, 23]);
        let (_, report) = s.solve_plain(PdParams {
            max_iterations: 60,
            record_objective: true,
            multilevel: PdMultilevelParams {
                tolerance,
                max_iterations: if tolerance == 0.0 { 3 } else { 20 },
                ..multilevel().multilevel
            },
            ..multilevel()
        });
        let phi = &report.objectives;
        for (k, w) in phi.windows(2).enumerate() {
            assert!(
                w[1] <= w[0] + 8.0 * f64::EPSILON * w[0].abs(),
                "tolerance {tolerance}: Φ rose at iteration {}: {:e} -> {:e}",
                k + 1,
                w[0],
                w[1]
            );
        }
        assert!(phi[phi.len() - 1] < phi[0]);
    }
}

/// Ten iterations on the multilevel path lower Φ within 1 % of what the direct path's ten do
/// (0.13 % measured on cloth-160 to cloth-640 with the default tolerance; docs/solvers.md §6.1).
#[test]
fn ten_iterations_land_where_the_direct_paths_do() {
    let mesh = generators::cloth(40, 1e3).unwrap();
    let mut s = step(mesh, &[0, 39], H, 0.05);
    let (direct, _) = s.solve_plain(PdParams::default());
    s.pd = pd(&s.mesh, &[0, 39], multilevel());
    let (cycled, report) = s.solve_plain(multilevel());
    assert_eq!(report.iterations, 10);
    let springs = s.mesh.springs();
    let gap = s.pd.objective_change(springs, &s.y, &direct, &cycled);
    let decrease = -s.pd.objective_change(springs, &s.y, &s.y, &direct);
    eprintln!(
        "{} CG iterations; Φ(multilevel) − Φ(direct) = {:e} of the direct decrease",
        report.linear_iterations,
        gap / decrease
    );
    assert!(decrease > 0.0);
    assert!(gap.abs() <= 0.01 * decrease, "{gap:e} of {decrease:e}");
}

/// L-BFGS with the multilevel PD as its initial Hessian (one V-cycle, a fixed SPD operator)
/// reaches Newton's minimiser.
#[test]
fn lbfgs_with_a_v_cycle_as_initial_hessian_reaches_newton() {
    let mesh = generators::cloth(10, 1e3).unwrap();
    let mut s = waved_step::step(&mesh, &[0, 9], H, 0.05);
    s.pd = pd(&mesh, &[0, 9], multilevel());
    let solution = waved_step::newton_solution(&mut s);
    let params = LbfgsParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-11,
        max_iterations: 3000,
        ..Default::default()
    };
    let mut lbfgs = Lbfgs::new(s.problem.dim(), params).unwrap();
    let mut x = s.start.clone();
    let report = lbfgs.minimize(&mut s.problem, &mut s.pd, &mut x).unwrap();
    let error = waved_step::objective_error(&mut s, &x, &solution);
    eprintln!(
        "{} iterations, objective error {error:e}",
        report.iterations
    );
    assert!(
        matches!(report.stop, StopReason::Converged | StopReason::RoundOff),
        "{:?}",
        report.stop
    );
    assert!(error.abs() <= 1e-10, "objective error {error:e}");
}

/// On cloth-96 (9,214 unknowns: above the sizes where the products and the sums go parallel) the
/// same bits on one thread and two.
#[test]
fn the_same_bits_on_one_and_two_threads() {
    let mesh = generators::cloth(96, 1e3).unwrap();
    let s = step(mesh, &[0, 95], H, 0.05);
    let run = |threads: usize| {
        on_threads(threads, || {
            let mut pd = pd(&s.mesh, &[0, 95], default_multilevel());
            let mut x = s.y.clone();
            let report = pd.solve(s.mesh.springs(), &s.y, &mut x).unwrap();
            assert!(report.linear_iterations >= 10);
            x
        })
    };
    let bits = |x: &[V]| -> Vec<u64> {
        x.iter()
            .flat_map(|p| p.iter().map(|c| c.to_bits()))
            .collect()
    };
    assert_eq!(bits(&run(1)), bits(&run(2)));
}

/// The multilevel path with the default hierarchy (two levels on cloth-96).
fn default_multilevel() -> PdParams {
    PdParams {
        global_solve: GlobalSolveKind::Multilevel,
        ..PdParams::default()
    }
}

/// Auto takes the multilevel path above the size constant, and when the factor would not fit in
/// the memory budget; the direct path asked for by name is refused over the budget instead.
#[test]
fn auto_takes_the_multilevel_path_by_size_and_over_the_budget() {
    assert_eq!(
        ProjectiveDynamics::<3>::global_solve_for(MULTILEVEL_PD_UNKNOWNS),
        GlobalSolveKind::Direct
    );
    assert_eq!(
        ProjectiveDynamics::<3>::global_solve_for(MULTILEVEL_PD_UNKNOWNS + 1),
        GlobalSolveKind::Multilevel
    );
    let mesh = generators::cloth(12, 1e3).unwrap();
    let tight = |global_solve| PdParams {
        global_solve,
        cholesky: CholeskyParams {
            memory_budget: MemoryBudget::Bytes(1000),
            ..PdParams::default().cholesky
        },
        ..PdParams::default()
    };
    assert_eq!(
        pd(&mesh, &[0, 11], PdParams::default()).global_solve(),
        GlobalSolveKind::Direct
    );
    assert_eq!(
        pd(&mesh, &[0, 11], tight(GlobalSolveKind::Auto)).global_solve(),
        GlobalSolveKind::Multilevel
    );
    let free = FreeDofs::new(mesh.vertex_count(), &[0, 11]).unwrap();
    let err = ProjectiveDynamics::<3>::new(
        mesh.springs(),
        mesh.masses(),
        &free,
        H,
        tight(GlobalSolveKind::Direct),
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            PdError::Factorization(CholeskyError::OverBudget { .. })
        ),
        "{err:?}"
    );
}

/// Auto takes the multilevel path when the factor fills more than `multilevel_fill` times the
/// matrix: a cloth (fill about 3) stays on its factor, a filled solid (beam-12, fill above 7)
/// goes multilevel, and a bound of +∞ or a global solve named outright decides by itself.
#[test]
fn auto_takes_the_multilevel_path_for_a_filling_factor() {
    let cloth = generators::cloth(12, 1e3).unwrap();
    let with_fill = |multilevel_fill| PdParams {
        multilevel_fill,
        ..PdParams::default()
    };
    assert_eq!(
        pd(&cloth, &[0, 11], PdParams::default()).global_solve(),
        GlobalSolveKind::Direct
    );
    assert_eq!(
        pd(&cloth, &[0, 11], with_fill(1.0)).global_solve(),
        GlobalSolveKind::Multilevel
    );
    let beam = generators::beam(12).unwrap();
    let pinned = waved_step::clamped(&beam);
    assert_eq!(
        pd(&beam, &pinned, PdParams::default()).global_solve(),
        GlobalSolveKind::Multilevel
    );
    assert_eq!(
        pd(&beam, &pinned, with_fill(f64::INFINITY)).global_solve(),
        GlobalSolveKind::Direct
    );
    let direct = PdParams {
        global_solve: GlobalSolveKind::Direct,
        ..with_fill(1.0)
    };
    assert_eq!(
        pd(&cloth, &[0, 11], direct).global_solve(),
        GlobalSolveKind::Direct
    );
    let refused = PdParams {
        multilevel_fill: 0.0,
        ..PdParams::default()
    };
    assert!(refused.validate().is_err());
}

/// A free component with zero mass and no pin makes the matrix singular: a typed error from the
/// hierarchy's set-up, not a panic or NaN.
#[test]
fn a_singular_matrix_is_a_typed_error() {
    let mesh = generators::cloth(8, 1e3).unwrap();
    let free = FreeDofs::new(mesh.vertex_count(), &[]).unwrap();
    let zero = vec![0.0; mesh.vertex_count()];
    let err =
        ProjectiveDynamics::<3>::new(mesh.springs(), &zero, &free, H, multilevel()).unwrap_err();
    assert!(matches!(err, PdError::Multilevel(_)), "{err:?}");
    assert!(err.to_string().contains("multilevel"), "{err}");
}

/// The multilevel settings are validated with the field named.
#[test]
fn invalid_multilevel_settings_are_refused() {
    for (params, field) in [
        (
            PdMultilevelParams {
                tolerance: 1.0,
                ..Default::default()
            },
            "PdMultilevelParams::tolerance",
        ),
        (
            PdMultilevelParams {
                tolerance: f64::NAN,
                ..Default::default()
            },
            "PdMultilevelParams::tolerance",
        ),
        (
            PdMultilevelParams {
                max_iterations: 0,
                ..Default::default()
            },
            "PdMultilevelParams::max_iterations",
        ),
    ] {
        let err = PdParams {
            multilevel: params,
            ..PdParams::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!(err.field(), field);
    }
}

/// Contact on the multilevel path (its weighted matrix gets a hierarchy of its own): a free cloth
/// thrown at the ground and a sphere ends every iteration outside both, contact or not, and lands
/// where the direct path's contact solve lands.
#[test]
fn contact_on_the_multilevel_path_keeps_every_vertex_outside() {
    use hooke_assembly::barrier::Obstacle;
    use hooke_solvers::PdContactModel;
    let mesh = generators::cloth(24, 1e3).unwrap();
    let lift = V::new(0.0, 0.02, 0.0);
    let x_n: Vec<V> = mesh.positions().iter().map(|p| p + lift).collect();
    // 3 m/s down: y passes 8 cm below the ground.
    let fall = V::new(0.0, -3.0 * H, 0.0) + V::new(0.0, -9.81, 0.0) * (H * H);
    let y: Vec<V> = x_n.iter().map(|p| p + fall).collect();
    let obstacles = vec![
        (Obstacle::half_space(V::zeros(), V::y()).unwrap(), 0.3),
        // Its top 1 cm above the ground, under the cloth's middle.
        (
            Obstacle::sphere_outside(V::new(0.5, -0.24, 0.5), 0.25).unwrap(),
            0.0,
        ),
    ];
    let run = |params: PdParams| {
        let mut pd = pd(
            &mesh,
            &[],
            PdParams {
                max_iterations: 30,
                ..params
            },
        );
        pd.set_contact(
            mesh.springs(),
            Some(PdContactModel::new(obstacles.clone(), 0.01)),
        )
        .unwrap();
        let mut x = x_n.clone();
        pd.solve(mesh.springs(), &y, &mut x).unwrap();
        assert!(pd.contact_vertices() > 0);
        for p in &x {
            for (o, _) in &obstacles {
                assert!(o.distance(p) >= 0.0, "{p:?} inside {o:?}");
            }
        }
        (x, pd.global_solve())
    };
    let (direct, kind) = run(PdParams::default());
    assert_eq!(kind, GlobalSolveKind::Direct);
    let (cycled, kind) = run(multilevel());
    assert_eq!(kind, GlobalSolveKind::Multilevel);
    // The paths differ by the inexact global steps only, whose steps are within a share of the
    // exact ones (the tolerance 0.5): a tenth of the largest move is far above that and far below
    // a wrong contact (the cloth would stop 8 cm lower).
    let moved = direct
        .iter()
        .zip(&x_n)
        .map(|(p, q)| (p - q).amax())
        .fold(0.0, f64::max);
    let apart = direct
        .iter()
        .zip(&cycled)
        .map(|(p, q)| (p - q).amax())
        .fold(0.0, f64::max);
    eprintln!("largest move {moved:e} m, paths apart {apart:e} m");
    assert!(apart <= 0.1 * moved, "{apart:e} m apart, {moved:e} m moved");
}

/// In 2D (two coordinates in lockstep): a 30 × 30 sheet of springs pinned at two corners lands
/// where the direct path lands (Φ within 1 % of the direct decrease, as in 3D), and Φ never rises.
#[test]
fn two_dimensions_land_where_the_direct_path_does() {
    use hooke_mesh::SpringMesh;
    use nalgebra::Vector2;
    let n = 30;
    let spacing = 1.0 / (n - 1) as f64;
    let positions: Vec<Vector2<f64>> = (0..n * n)
        .map(|v| Vector2::new((v % n) as f64, (v / n) as f64) * spacing)
        .collect();
    let mut pairs = Vec::new();
    for r in 0..n {
        for c in 0..n {
            let v = (r * n + c) as u32;
            if c + 1 < n {
                pairs.push([v, v + 1]);
            }
            if r + 1 < n {
                pairs.push([v, v + n as u32]);
            }
            if c + 1 < n && r + 1 < n {
                pairs.push([v, v + n as u32 + 1]);
            }
        }
    }
    let mesh = SpringMesh::<2>::from_pairs(
        positions.clone(),
        vec![1.0 / (n * n) as f64; n * n],
        &pairs,
        1e3,
    )
    .unwrap();
    let pinned = [(n * n - n) as u32, (n * n - 1) as u32];
    let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
    let y: Vec<Vector2<f64>> = positions
        .iter()
        .enumerate()
        .map(|(v, p)| {
            if pinned.contains(&(v as u32)) {
                *p
            } else {
                p + Vector2::new(0.02 * p.y, -9.81 * H * H)
            }
        })
        .collect();
    let run = |params: PdParams| {
        let mut pd =
            ProjectiveDynamics::<2>::new(mesh.springs(), mesh.masses(), &free, H, params).unwrap();
        let mut x = y.clone();
        let report = pd.solve(mesh.springs(), &y, &mut x).unwrap();
        (x, report, pd)
    };
    let steps = |params: PdParams| PdParams {
        max_iterations: 30,
        record_objective: true,
        ..params
    };
    let (direct, _, pd) = run(steps(PdParams::default()));
    let (cycled, report, _) = run(steps(multilevel()));
    assert!(report.linear_iterations >= 30);
    for w in report.objectives.windows(2) {
        assert!(
            w[1] <= w[0] + 8.0 * f64::EPSILON * w[0].abs(),
            "Φ rose: {w:?}"
        );
    }
    let springs = mesh.springs();
    let gap = pd.objective_change(springs, &y, &direct, &cycled);
    let decrease = -pd.objective_change(springs, &y, &y, &direct);
    eprintln!(
        "2D: Φ(multilevel) − Φ(direct) = {:e} of the decrease",
        gap / decrease
    );
    assert!(decrease > 0.0);
    assert!(gap.abs() <= 0.01 * decrease, "{gap:e} of {decrease:e}");
}

/// After a refactor that failed (here a singular matrix: a free cloth without mass), the
/// hierarchy is gone, and a solve says so instead of using a stale one.
#[test]
#[should_panic(expected = "needs a successful refactor first")]
fn a_solve_after_a_failed_refactor_says_why() {
    let mesh = generators::cloth(8, 1e3).unwrap();
    let mut pd = pd(&mesh, &[], multilevel());
    let zero = vec![0.0; mesh.vertex_count()];
    assert!(pd.refactor(mesh.springs(), &zero, H).is_err());
    let y = mesh.positions().to_vec();
    let mut x = y.clone();
    let _ = pd.solve(mesh.springs(), &y, &mut x);
}

/// The CG's stop is read at every solve: settings changed after construction take effect (the
/// bench and the simulation set `params` on a built solver).
#[test]
fn the_cg_stop_is_read_at_every_solve() {
    let mut s = multilevel_step(generators::cloth(24, 1e3).unwrap(), &[0, 23]);
    let (_, loose) = s.solve_plain(PdParams {
        max_iterations: 5,
        ..multilevel()
    });
    let (_, fixed) = s.solve_plain(PdParams {
        max_iterations: 5,
        multilevel: PdMultilevelParams {
            tolerance: 0.0,
            max_iterations: 7,
            ..multilevel().multilevel
        },
        ..multilevel()
    });
    assert_eq!(fixed.linear_iterations, 5 * 7);
    assert!(
        loose.linear_iterations < 5 * 7,
        "{}",
        loose.linear_iterations
    );
}
