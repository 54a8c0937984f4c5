//! Every parameter struct over extreme values (0, negative, NaN, ±∞, huge, tiny): either its
//! `validate()` refuses the value, naming the field, and the solver refuses it the same way before
//! computing anything, or the solve finishes within a bounded number of iterations (no hang, no
//! abort from an allocation sized by the limit, no panic).

use hooke_assembly::FreeDofs;
use hooke_mesh::generators;
use hooke_solvers::Convergence;
use hooke_solvers::{
    BackwardEulerStep, BlockJacobi, CgParams, ChebyshevParams, ChebyshevPd, CholeskyError,
    CholeskyParams, ConjugateGradient, Identity, IndefinitePolicy, Jacobi, JacobiParams, Lbfgs,
    LbfgsError, LbfgsParams, Newton, NewtonCg, NewtonCgError, NewtonCgParams, NewtonError,
    NewtonParams, NewtonProblem, ParamError, PdError, PdParams, ProjectiveDynamics, Relaxation,
    SolveError, SparseCholesky, StopReason,
};
use nalgebra::{DMatrix, Vector3};
use proptest::prelude::*;

use crate::common;
use common::inertial_target;

/// The same refusal (NaN values compare unequal, so compare what the error says).
fn same(a: &ParamError, b: &ParamError) -> bool {
    a.field() == b.field() && a.to_string() == b.to_string()
}

/// Every solve here finishes far below this many iterations; a test that hangs fails by timing out.
const BOUND: usize = 10_000;

fn extreme_real() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        Just(-0.0),
        Just(-1.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(1e300),
        Just(f64::MAX),
        Just(1e-300),
        Just(f64::MIN_POSITIVE),
        Just(1.0),
        Just(1.0 + f64::EPSILON),
        0.0f64..4.0,
        -1e3f64..1e3,
    ]
}

fn extreme_count() -> impl Strategy<Value = usize> {
    prop_oneof![
        Just(0usize),
        Just(1),
        Just(usize::MAX),
        Just(1usize << 40),
        Just(1_000_000_000_000),
        0usize..40,
    ]
}

/// cloth-4 with two pins, a backward Euler step pulled sideways and down: small, but it buckles
/// a little (the indefinite paths of Newton are taken).
fn cloth_problem() -> (BackwardEulerStep<3>, Vec<f64>, Vec<Vector3<f64>>) {
    let n = 4;
    let mesh = generators::cloth(n, 1e3).unwrap();
    let pinned = [0, n as u32 - 1];
    let h = 1.0 / 30.0;
    let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
    let y = inertial_target(mesh.positions(), &pinned, |_, x| {
        Vector3::new(-0.2 * x.x, -9.81 * h * h, 0.05)
    });
    let mut step = BackwardEulerStep::new(mesh.springs(), mesh.masses(), free, h);
    let mut unknowns = vec![0.0; step.dim()];
    step.set_step(&y, mesh.positions(), &mut unknowns);
    (step, unknowns, y)
}

/// Set the `field`-th real field of Newton's settings (relaxation included).
fn set_newton_real(p: &mut NewtonParams, field: usize, value: f64) -> &'static str {
    let r = &mut p.relaxation;
    let (slot, name): (&mut f64, _) = match field {
        0 => (&mut p.tolerance, "NewtonParams::tolerance"),
        1 => (&mut p.armijo, "NewtonParams::armijo"),
        2 => (&mut p.initial_shift, "NewtonParams::initial_shift"),
        3 => (&mut p.shift_factor, "NewtonParams::shift_factor"),
        4 => (&mut p.blend_factor, "NewtonParams::blend_factor"),
        5 => (&mut p.max_shift, "NewtonParams::max_shift"),
        6 => (&mut r.focus_share, "Relaxation::focus_share"),
        7 => (&mut r.trusted_model, "Relaxation::trusted_model"),
        8 => (&mut r.region_share, "Relaxation::region_share"),
        9 => (&mut r.patch_share, "Relaxation::patch_share"),
        10 => (&mut r.region_coverage, "Relaxation::region_coverage"),
        11 => (
            &mut r.region_concentration,
            "Relaxation::region_concentration",
        ),
        12 => (&mut r.region_tolerance, "Relaxation::region_tolerance"),
        _ => (&mut p.multilevel_fill, "NewtonParams::multilevel_fill"),
    };
    *slot = value;
    name
}
const NEWTON_REALS: usize = 14;

/// Set the `field`-th count of Newton's settings (relaxation and factorisation included).
fn set_newton_count(p: &mut NewtonParams, field: usize, value: usize) -> &'static str {
    let r = &mut p.relaxation;
    let (slot, name): (&mut usize, _) = match field {
        0 => (&mut p.max_iterations, "NewtonParams::max_iterations"),
        1 => (&mut p.max_halvings, "NewtonParams::max_halvings"),
        2 => (&mut r.sweeps, "Relaxation::sweeps"),
        3 => (&mut r.block_iterations, "Relaxation::block_iterations"),
        4 => (&mut r.focus_rings, "Relaxation::focus_rings"),
        5 => (&mut r.focus_sweeps, "Relaxation::focus_sweeps"),
        6 => (&mut r.patch_covers, "Relaxation::patch_covers"),
        7 => (&mut r.region_rings, "Relaxation::region_rings"),
        8 => (&mut r.region_iterations, "Relaxation::region_iterations"),
        9 => (&mut r.region_sweeps, "Relaxation::region_sweeps"),
        10 => (
            &mut p.cholesky.factor_threads,
            "CholeskyParams::factor_threads",
        ),
        _ => (
            &mut p.cholesky.solve_threads,
            "CholeskyParams::solve_threads",
        ),
    };
    *slot = value;
    name
}
const NEWTON_COUNTS: usize = 12;

/// The fields whose range depends on `field`'s value (the shift ladder's three settings, the
/// elimination's switch and its covers): a change of `field` may be reported on any of them.
fn related(field: &str) -> &'static [&'static str] {
    match field {
        "NewtonParams::initial_shift"
        | "NewtonParams::max_shift"
        | "NewtonParams::shift_factor"
        | "NewtonParams::blend_factor" => &[
            "NewtonParams::initial_shift",
            "NewtonParams::max_shift",
            "NewtonParams::shift_factor",
            "NewtonParams::blend_factor",
        ],
        "Relaxation::region_share" | "Relaxation::region_iterations" => &[
            "Relaxation::region_share",
            "Relaxation::region_iterations",
            "Relaxation::patch_covers",
        ],
        _ => &[],
    }
}

/// Newton with `params` on the cloth problem: refused with the field named, or finished.
fn check_newton(params: NewtonParams, field: &'static str) -> Result<(), TestCaseError> {
    let (mut step, mut unknowns, _) = cloth_problem();
    let validated = params.validate();
    let built = Newton::new(step.pattern(), params);
    match validated {
        Err(e) => {
            prop_assert!(
                e.field() == field || related(field).contains(&e.field()),
                "{field} changed, {} refused: {e}",
                e.field()
            );
            prop_assert!(e.to_string().contains(e.field()), "{e}");
            prop_assert!(
                matches!(&built, Err(NewtonError::InvalidParameter(b)) if same(b, &e)),
                "{built:?}"
            );
            // Settings made invalid after construction are refused by the solve as well.
            let mut newton = Newton::new(step.pattern(), NewtonParams::default()).unwrap();
            newton.params = params;
            let solved = newton.minimize(&mut step, &mut unknowns);
            prop_assert!(
                matches!(&solved, Err(NewtonError::InvalidParameter(b)) if same(b, &e)),
                "{solved:?}"
            );
        }
        Ok(()) => {
            let mut newton = built.unwrap();
            match newton.minimize(&mut step, &mut unknowns) {
                Ok(report) => {
                    prop_assert!(report.iterations <= params.max_iterations.min(BOUND));
                    prop_assert_eq!(report.history.len(), report.iterations);
                    if report.stop.is_converged() {
                        prop_assert!(
                            report.gradient() <= params.tolerance
                                || report.stop == StopReason::RoundOff,
                            "{report:?}"
                        );
                    }
                }
                Err(e) => {
                    let report = e.report().expect("a solve error carries its report");
                    prop_assert!(report.iterations <= BOUND, "{e}");
                    prop_assert!(!report.stop.is_converged(), "{e}");
                }
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn newton_real_settings_are_refused_or_finish(
        field in 0..NEWTON_REALS,
        value in extreme_real(),
        policy in prop_oneof![
            Just(IndefinitePolicy::ConvexBlend),
            Just(IndefinitePolicy::NewtonIfDescent),
            Just(IndefinitePolicy::Shift),
            Just(IndefinitePolicy::Projected),
            Just(IndefinitePolicy::ProjectedThenExact),
        ],
    ) {
        let mut params = NewtonParams { indefinite: policy, ..NewtonParams::default() };
        let name = set_newton_real(&mut params, field, value);
        check_newton(params, name)?;
    }

    #[test]
    fn newton_counts_are_refused_or_finish(field in 0..NEWTON_COUNTS, value in extreme_count()) {
        let mut params = NewtonParams::default();
        let name = set_newton_count(&mut params, field, value);
        check_newton(params, name)?;
    }

    #[test]
    fn cg_and_jacobi_settings_are_refused_or_finish(
        field in 0..6usize,
        real in extreme_real(),
        count in extreme_count(),
    ) {
        // A small block diagonally dominant SPD system: CG and Jacobi both converge on it.
        let n = 6;
        let a = DMatrix::from_fn(n, n, |i, j| {
            if i == j { 4.0 } else if i.abs_diff(j) == 1 { -1.0 } else { 0.0 }
        });
        let b = vec![1.0; n];
        let mut cg = CgParams::default();
        let mut jacobi = JacobiParams::default();
        let name = match field {
            0 => { cg.tolerance = real; "CgParams::tolerance" }
            1 => { cg.max_iterations = count; "CgParams::max_iterations" }
            2 => { jacobi.tolerance = real; "JacobiParams::tolerance" }
            3 => { jacobi.max_iterations = count; "JacobiParams::max_iterations" }
            4 => { jacobi.weight = real; "JacobiParams::weight" }
            _ => { jacobi.divergence_factor = real; "JacobiParams::divergence_factor" }
        };
        let blocks = BlockJacobi::<3>::from_dense(&a).unwrap();
        let checks = [
            (cg.validate(), {
                let mut x = vec![0.0; n];
                ConjugateGradient::new(cg).solve(&a, &mut Identity, &b, &mut x)
            }),
            (jacobi.validate(), {
                let mut x = vec![0.0; n];
                Jacobi::new(jacobi).solve(&a, &blocks, &b, &mut x)
            }),
        ];
        for (validated, solved) in checks {
            match validated {
                Err(e) => {
                    prop_assert_eq!(e.field(), name);
                    prop_assert!(
                        matches!(&solved, Err(SolveError::InvalidParameter(b)) if same(b, &e)),
                        "{solved:?}"
                    );
                }
                Ok(()) => match solved {
                    Ok(report) => prop_assert!(report.iterations <= BOUND, "{report:?}"),
                    Err(e) => prop_assert!(false, "a valid setting failed on an SPD system: {e}"),
                },
            }
        }
    }

    #[test]
    fn pd_and_cholesky_settings_are_refused_or_finish(
        field in 0..4usize,
        real in extreme_real(),
        count in extreme_count(),
    ) {
        let n = 4;
        let mesh = generators::cloth(n, 1e3).unwrap();
        let pinned = [0, n as u32 - 1];
        let h = 1.0 / 30.0;
        let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
        let y = inertial_target(mesh.positions(), &pinned, |_, _| Vector3::new(0.0, -0.01, 0.0));
        // A tolerance, so that a huge iteration budget still ends (PD runs its whole budget at
        // tolerance 0, by design).
        let mut params = PdParams { tolerance: 1e-6, ..PdParams::default() };
        let name = match field {
            0 => { params.max_iterations = count; "PdParams::max_iterations" }
            1 => { params.tolerance = real; "PdParams::tolerance" }
            2 => { params.cholesky.factor_threads = count; "CholeskyParams::factor_threads" }
            _ => { params.cholesky.solve_threads = count; "CholeskyParams::solve_threads" }
        };
        let built = ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, h, params);
        match params.validate() {
            Err(e) => {
                prop_assert_eq!(e.field(), name);
                prop_assert!(
                    matches!(&built, Err(PdError::InvalidParameter(b)) if same(b, &e)),
                    "{built:?}"
                );
                if name.starts_with("CholeskyParams") {
                    let chol = SparseCholesky::analyze(
                        hooke_assembly::pd::LaplacianPattern::new(
                            free.vertex_count(), mesh.springs(), Some(&free)
                        ).symbolic(),
                        params.cholesky,
                    );
                    prop_assert!(
                        matches!(&chol, Err(CholeskyError::InvalidParameter(b)) if same(b, &e)),
                        "{:?}", chol.err()
                    );
                }
            }
            Ok(()) => {
                let mut pd = built.unwrap();
                let mut x = y.clone();
                // A huge budget only ends by the tolerance; 0 would run it all.
                if params.tolerance == 0.0 && params.max_iterations > BOUND {
                    return Ok(());
                }
                let report = pd.solve(mesh.springs(), &y, &mut x).unwrap();
                prop_assert!(report.iterations <= params.max_iterations.min(BOUND));
                prop_assert!(x.iter().all(|p| p.iter().all(|c| c.is_finite())));
            }
        }
    }

    #[test]
    fn quasi_newton_and_accelerated_pd_settings_are_refused_or_finish(
        field in 0..17usize,
        real in extreme_real(),
        count in extreme_count(),
    ) {
        let (mut step, start, y) = cloth_problem();
        let n = 4;
        let mesh = generators::cloth(n, 1e3).unwrap();
        let free = FreeDofs::new(mesh.vertex_count(), &[0, n as u32 - 1]).unwrap();
        let mut pd = ProjectiveDynamics::<3>::new(
            mesh.springs(), mesh.masses(), &free, 1.0 / 30.0, PdParams::default(),
        ).unwrap();
        let mut lbfgs = LbfgsParams::default();
        let mut cg = NewtonCgParams::default();
        let mut cheb = ChebyshevParams { tolerance: 1e-9, ..ChebyshevParams::default() };
        let name = match field {
            0 => { lbfgs.max_iterations = count; "LbfgsParams::max_iterations" }
            1 => { lbfgs.tolerance = real; "LbfgsParams::tolerance" }
            2 => { lbfgs.history = count; "LbfgsParams::history" }
            3 => { lbfgs.armijo = real; "LbfgsParams::armijo" }
            4 => { lbfgs.max_halvings = count; "LbfgsParams::max_halvings" }
            5 => { cg.max_iterations = count; "NewtonCgParams::max_iterations" }
            6 => { cg.max_cg_iterations = count; "NewtonCgParams::max_cg_iterations" }
            7 => { cg.tolerance = real; "NewtonCgParams::tolerance" }
            8 => { cg.forcing_max = real; "NewtonCgParams::forcing_max" }
            9 => { cg.forcing_gamma = real; "NewtonCgParams::forcing_gamma" }
            10 => { cg.forcing_alpha = real; "NewtonCgParams::forcing_alpha" }
            11 => { cg.armijo = real; "NewtonCgParams::armijo" }
            12 => { cg.max_halvings = count; "NewtonCgParams::max_halvings" }
            13 => { cheb.max_iterations = count; "ChebyshevParams::max_iterations" }
            14 => { cheb.rate = real; "ChebyshevParams::rate" }
            15 => { cheb.under_relaxation = real; "ChebyshevParams::under_relaxation" }
            _ => { cheb.tolerance = real; "ChebyshevParams::tolerance" }
        };
        let dim = step.dim();
        if field < 5 {
            let built = Lbfgs::new(dim, lbfgs);
            match lbfgs.validate() {
                Err(e) => {
                    prop_assert_eq!(e.field(), name);
                    prop_assert!(matches!(&built, Err(b) if same(b, &e)), "{built:?}");
                }
                Ok(()) => {
                    // A zero tolerance runs to the limit (or the round-off floor): bound it.
                    if lbfgs.max_iterations > BOUND && lbfgs.tolerance == 0.0 {
                        return Ok(());
                    }
                    let mut x = start.clone();
                    match built.unwrap().minimize(&mut step, &mut pd, &mut x) {
                        Ok(r) => prop_assert!(r.iterations <= lbfgs.max_iterations.min(BOUND)),
                        // A search of zero halvings may find no decrease: a typed error.
                        Err(LbfgsError::LineSearchFailed { report }) => {
                            prop_assert_eq!(report.stop, StopReason::LineSearchFailed);
                        }
                        Err(e) => prop_assert!(false, "{e}"),
                    }
                }
            }
        } else if field < 13 {
            let built = NewtonCg::new(dim, cg);
            match cg.validate() {
                Err(e) => {
                    prop_assert_eq!(e.field(), name);
                    prop_assert!(matches!(&built, Err(b) if same(b, &e)), "{built:?}");
                }
                Ok(()) => {
                    if cg.max_iterations > BOUND && cg.tolerance == 0.0 {
                        return Ok(());
                    }
                    let mut x = start.clone();
                    match built.unwrap().minimize(&mut step, &mut pd, &mut x) {
                        Ok(r) => prop_assert!(r.iterations <= cg.max_iterations.min(BOUND)),
                        Err(NewtonCgError::LineSearchFailed { report }) => {
                            prop_assert_eq!(report.stop, StopReason::LineSearchFailed);
                        }
                        Err(e) => prop_assert!(false, "{e}"),
                    }
                }
            }
        } else {
            let built = ChebyshevPd::<3>::new(mesh.vertex_count(), cheb);
            match cheb.validate() {
                Err(e) => {
                    prop_assert_eq!(e.field(), name);
                    prop_assert!(matches!(&built, Err(b) if same(b, &e)), "{built:?}");
                }
                Ok(()) => {
                    if cheb.max_iterations > BOUND && cheb.tolerance == 0.0 {
                        return Ok(());
                    }
                    let mut x = y.clone();
                    let r = built
                        .unwrap()
                        .solve(&mut pd, mesh.springs(), &y, &mut x)
                        .unwrap();
                    prop_assert!(r.iterations <= cheb.max_iterations.min(BOUND));
                    prop_assert!(x.iter().all(|p| p.iter().all(|c| c.is_finite())));
                }
            }
        }
    }
}

#[test]
fn the_values_of_issue_19_are_refused_with_the_field_and_its_range() {
    let refused = |p: NewtonParams| p.validate().unwrap_err();
    let d = NewtonParams::default();
    for (params, field, range) in [
        (
            NewtonParams {
                blend_factor: 1.0,
                ..d
            },
            "NewtonParams::blend_factor",
            "> 1",
        ),
        (
            NewtonParams {
                blend_factor: 0.5,
                ..d
            },
            "NewtonParams::blend_factor",
            "> 1",
        ),
        (
            NewtonParams {
                initial_shift: 0.0,
                ..d
            },
            "NewtonParams::initial_shift",
            "> 0",
        ),
        (
            NewtonParams {
                max_shift: f64::INFINITY,
                ..d
            },
            "NewtonParams::max_shift",
            "finite",
        ),
        (
            NewtonParams {
                shift_factor: 1.0,
                indefinite: IndefinitePolicy::Shift,
                ..d
            },
            "NewtonParams::shift_factor",
            "> 1",
        ),
        (
            NewtonParams {
                max_iterations: 0,
                ..d
            },
            "NewtonParams::max_iterations",
            "at least 1",
        ),
        (
            NewtonParams {
                convergence: Convergence::RelativeGradient,
                tolerance: f64::NAN,
                ..d
            },
            "NewtonParams::tolerance",
            ">= 0",
        ),
    ] {
        let e = refused(params);
        assert_eq!(e.field(), field, "{e}");
        let message = e.to_string();
        assert!(
            message.contains(field) && message.contains(range),
            "{message}"
        );
    }
    assert!(matches!(
        PdParams {
            max_iterations: 0,
            ..PdParams::default()
        }
        .validate(),
        Err(ParamError::Count {
            field: "PdParams::max_iterations",
            value: 0,
            ..
        })
    ));
    // Without a tolerance PD runs its whole budget: one that cannot end is refused.
    assert!(matches!(
        PdParams {
            max_iterations: usize::MAX,
            tolerance: 0.0,
            ..PdParams::default()
        }
        .validate(),
        Err(ParamError::Count {
            field: "PdParams::max_iterations",
            value: usize::MAX,
            ..
        })
    ));
    assert!(PdParams {
        max_iterations: hooke_solvers::PD_MAX_ITERATIONS,
        ..PdParams::default()
    }
    .validate()
    .is_ok());
    assert!(CholeskyParams::default().validate().is_ok());
    assert!(Relaxation::NONE.validate().is_ok() && Relaxation::BUCKLING.validate().is_ok());
    assert!(NewtonParams::default().validate().is_ok());
}

#[test]
fn a_huge_iteration_limit_allocates_nothing_by_it_and_finishes() {
    // 10¹² iterations (48 TB of history if reserved by the limit) and usize::MAX: the solve
    // converges in a few iterations and the history holds only those.
    for limit in [1_000_000_000_000, usize::MAX] {
        let (mut step, mut unknowns, _) = cloth_problem();
        let params = NewtonParams {
            max_iterations: limit,
            ..NewtonParams::default()
        };
        let mut newton = Newton::new(step.pattern(), params).unwrap();
        let report = newton.minimize(&mut step, &mut unknowns).unwrap();
        assert_eq!(report.stop, StopReason::Converged, "{report:?}");
        assert!(
            report.history.capacity() <= 1024,
            "{}",
            report.history.capacity()
        );
    }
}

/// The elimination's inner solves never meet settings they refuse: [`Relaxation::validate`] checks
/// them ([`Relaxation::inner_params`]) where the relaxation enters, over extreme values of every
/// field; and a direct [`NewtonProblem::relax`] call with unchecked settings that the inner Newton
/// refuses reports the patches it could not solve ([`RelaxationWork::refused_regions`]) instead of
/// skipping them silently.
#[test]
fn the_eliminations_inner_settings_are_checked_where_the_relaxation_enters() {
    let reals = [0.0, -1.0, f64::NAN, f64::INFINITY, 1e300, 1e-300, 0.5, 2.0];
    let counts = [0, 1, 3, 10_000, 10_001, usize::MAX];
    let mut checked = 0;
    let mut settings = Vec::new();
    // From the relaxation preset (the default relaxes nothing, so has no inner settings).
    let relaxed = NewtonParams {
        relaxation: Relaxation::BUCKLING,
        ..NewtonParams::default()
    };
    for field in 0..NEWTON_COUNTS {
        for &value in &counts {
            let mut params = relaxed;
            set_newton_count(&mut params, field, value);
            settings.push(params);
        }
    }
    for field in 0..NEWTON_REALS {
        for &value in &reals {
            let mut params = relaxed;
            set_newton_real(&mut params, field, value);
            settings.push(params);
        }
    }
    for params in settings {
        {
            let relaxation = params.relaxation;
            if relaxation.validate().is_ok() && relaxation.region_blocks(1) > 0 {
                assert_eq!(
                    relaxation.inner_params().validate(),
                    Ok(()),
                    "{relaxation:?}"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 0, "some extreme settings keep the elimination on");

    // Inner sweeps beyond the limit: refused on entry, naming the field...
    let n = 8;
    let mesh = generators::cloth(n, 1e3).unwrap();
    let pinned = [0u32, n as u32 - 1];
    let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
    let relaxation = Relaxation {
        sweeps: 0,
        focus_share: 0.0,
        region_concentration: 0.0,
        region_sweeps: hooke_solvers::MAX_RELAXATION_COUNT + 1,
        ..Relaxation::BUCKLING
    };
    assert_eq!(
        relaxation.validate().map_err(|e| e.field()),
        Err("Relaxation::region_sweeps")
    );
    // ...and, given to `relax` unchecked, reported patch by patch (the same state with valid
    // settings solves patches: see `the_elimination_leaves_a_region_of_round_off_alone`).
    let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, 1.0 / 30.0);
    let mut y = mesh.positions().to_vec();
    y.iter_mut().skip(1).step_by(2).for_each(|p| p.y += 0.01);
    for (relaxation, refused) in [
        (relaxation, true),
        (
            Relaxation {
                region_sweeps: 10,
                ..relaxation
            },
            false,
        ),
    ] {
        let mut x = vec![0.0; step.dim()];
        step.set_step(&y, mesh.positions(), &mut x);
        let before = x.clone();
        let work = step.relax(&mut x, relaxation).unwrap();
        if refused {
            assert!(work.refused_regions > 0, "{work:?}");
            assert_eq!(work.region_solves, 0, "{work:?}");
            assert_eq!(x, before, "a refused patch does not move");
        } else {
            assert_eq!(work.refused_regions, 0, "{work:?}");
            assert!(work.region_solves > 0, "{work:?}");
        }
    }
}
