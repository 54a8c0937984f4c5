//! The memory budget of the sparse Cholesky factor (docs/solvers.md §2.5): a factor above it is
//! refused with a typed error before it is allocated; Newton then takes the multilevel path (CG
//! preconditioned by AMG on the convexified Hessian) and reaches the direct path's answer; a
//! solver without a multilevel path (projective dynamics) is refused with the size and the budget.

use faer::sparse::{SparseColMat, SymbolicSparseColMatRef, Triplet};
use hooke_assembly::FreeDofs;
use hooke_mesh::generators;
use hooke_solvers::{
    BackwardEulerStep, CholeskyError, CholeskyParams, Convergence, GlobalSolveKind, MemoryBudget,
    Newton, NewtonError, NewtonParams, NewtonProblem, PdError, PdParams, ProjectiveDynamics,
    SparseCholesky, StopReason,
};
use nalgebra::Vector3;

type V = Vector3<f64>;

const H: f64 = 1.0 / 30.0;

/// The 1D Laplacian plus the identity, n × n, full storage: symmetric positive definite.
fn laplacian(n: usize) -> SparseColMat<usize, f64> {
    let mut triplets = Vec::new();
    for i in 0..n {
        triplets.push(Triplet::new(i, i, 3.0));
        if i + 1 < n {
            triplets.push(Triplet::new(i, i + 1, -1.0));
            triplets.push(Triplet::new(i + 1, i, -1.0));
        }
    }
    SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap()
}

fn with_budget(budget: MemoryBudget) -> CholeskyParams {
    CholeskyParams {
        memory_budget: budget,
        ..CholeskyParams::default()
    }
}

/// The budget bounds 8 bytes per stored value plus the numeric scratch: exactly that many bytes
/// pass, one fewer is refused with the sizes in the error and its message.
#[test]
fn a_factor_above_the_budget_is_refused_with_its_size() {
    let a = laplacian(200);
    let unlimited = SparseCholesky::analyze(a.symbolic(), with_budget(MemoryBudget::UNLIMITED))
        .expect("no limit");
    let (needed, _) =
        SparseCholesky::memory_needed(unlimited.symbolic(), with_budget(MemoryBudget::UNLIMITED));
    assert!(needed >= 8 * unlimited.factor_nnz() as u64, "{needed}");
    let mut exact = SparseCholesky::analyze(a.symbolic(), with_budget(MemoryBudget::Bytes(needed)))
        .expect("a budget of exactly the size needed is enough");
    exact.factorize(a.as_ref()).unwrap();
    let err = SparseCholesky::analyze(a.symbolic(), with_budget(MemoryBudget::Bytes(needed - 1)))
        .unwrap_err();
    assert_eq!(
        err,
        CholeskyError::OverBudget {
            dim: 200,
            needed,
            budget: needed - 1
        }
    );
    let message = err.to_string();
    for part in [
        "200×200",
        &format!("({needed} bytes)"),
        &format!("budget of {}", human(needed - 1)),
        "docs/solvers.md §2.5",
    ] {
        assert!(message.contains(part), "{part:?} not in {message:?}");
    }
}

/// What the error message writes for a byte count below 1 KiB or above.
fn human(bytes: u64) -> String {
    if bytes < 1024 {
        format!("{bytes} bytes")
    } else {
        format!("{:.1} KiB ({bytes} bytes)", bytes as f64 / 1024.0)
    }
}

/// The default budget is the machine's: half its memory, far above a small factor.
#[test]
fn the_default_budget_is_the_machines() {
    assert_eq!(
        CholeskyParams::default().memory_budget,
        MemoryBudget::Machine
    );
    let bytes = MemoryBudget::Machine.bytes();
    assert!(bytes >= 1 << 20, "{bytes}");
    let a = laplacian(50);
    SparseCholesky::analyze(a.symbolic(), CholeskyParams::default()).unwrap();
}

/// A beam-6 (25 × 7 × 7 vertices, k = 1e4 N/m, 1000 kg/m³: 3,528 unknowns, so that the AMG
/// hierarchy has levels below the finest, which a problem under 1000 unknowns would not) clamped
/// at x = 0, squashed to 70 % of its length and let go under gravity: its compressed springs make
/// the exact Hessian indefinite on the first steps, where the multilevel path solves with the
/// clamped one instead.
struct Beam {
    step: BackwardEulerStep<3>,
    x: Vec<V>,
    v: Vec<V>,
    pinned: Vec<bool>,
}

impl Beam {
    fn new() -> Self {
        let mesh = generators::beam(6).unwrap();
        let pinned: Vec<bool> = mesh.positions().iter().map(|p| p.x == 0.0).collect();
        let squashed = mesh
            .positions()
            .iter()
            .map(|p| V::new(0.7 * p.x, p.y, p.z))
            .collect();
        let pins: Vec<u32> = (0..pinned.len() as u32)
            .filter(|&v| pinned[v as usize])
            .collect();
        let free = FreeDofs::new(mesh.vertex_count(), &pins).unwrap();
        Beam {
            step: BackwardEulerStep::new(mesh.springs(), mesh.masses(), free, H),
            x: squashed,
            v: vec![V::zeros(); mesh.vertex_count()],
            pinned,
        }
    }

    /// Solve the current step with `newton` from y; the new positions and the report.
    fn solve(&mut self, newton: &mut Newton) -> (Vec<V>, hooke_solvers::NewtonReport) {
        let g = V::new(0.0, -9.81, 0.0);
        let y: Vec<V> = (0..self.x.len())
            .map(|i| {
                if self.pinned[i] {
                    self.x[i]
                } else {
                    self.x[i] + H * self.v[i] + H * H * g
                }
            })
            .collect();
        let mut unknowns = vec![0.0; self.step.dim()];
        self.step.set_step(&y, &self.x, &mut unknowns);
        let report = newton.minimize(&mut self.step, &mut unknowns).unwrap();
        assert_eq!(report.stop, StopReason::Converged, "{report:?}");
        (self.step.positions(&unknowns).to_vec(), report)
    }

    fn advance(&mut self, to: &[V]) {
        for ((x, v), new) in self.x.iter_mut().zip(&mut self.v).zip(to) {
            *v = (new - *x) / H;
            *x = *new;
        }
    }
}

fn newton_params(budget: MemoryBudget) -> NewtonParams {
    NewtonParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-10,
        cholesky: with_budget(budget),
        ..NewtonParams::default()
    }
}

/// A budget of 0 bytes routes Newton to the multilevel path; along 4 steps of the squashed beam
/// its answers agree with the direct path's, and the hierarchy is built once and refilled.
#[test]
fn a_tiny_budget_takes_the_multilevel_path_to_the_same_answer() {
    let mut beam = Beam::new();
    let mut direct =
        Newton::new(beam.step.pattern(), newton_params(MemoryBudget::Machine)).unwrap();
    let mut multilevel =
        Newton::new(beam.step.pattern(), newton_params(MemoryBudget::Bytes(0))).unwrap();
    assert!(direct.multilevel().is_none());
    let path = multilevel.multilevel().expect("over the budget");
    assert!(path.factor_bytes() > 0 && path.budget() == 0);
    let mut compressed_steps = 0;
    for k in 0..4 {
        let (reference, plain) = beam.solve(&mut direct);
        let (answer, report) = beam.solve(&mut multilevel);
        // The scale of the step: how far it moves the beam.
        let motion = largest_difference(&reference, &beam.x);
        // Both solves end at a relative gradient of 1e-10; the distance to x* is at most
        // cond(H) times that relative to the step's size, and H here (masses plus h²K of a
        // beam of 4×2×2 cubes) has a condition number of a few hundred: 1e-7 of the motion
        // leaves a margin of a few hundred over that.
        let difference = largest_difference(&reference, &answer);
        assert!(
            difference <= 1e-7 * motion,
            "step {k}: answers {difference:e} m apart, motion {motion:e} m \
             (direct {plain:?}, multilevel {report:?})"
        );
        // The direct path met negative curvature (a blend above 0) or not: count the steps
        // where the exact Hessian was indefinite, to show the test covers them.
        compressed_steps += usize::from(plain.shifted_steps > 0);
        beam.advance(&reference);
    }
    let path = multilevel.multilevel().unwrap();
    let stats = path.stats();
    // The hierarchy has coarse levels, and was built once (a set-up on an exact Hessian whose
    // diagonal block is indefinite fails, and the next matrix, blended, builds it), then refilled.
    assert!(path.level_sizes().len() >= 2, "{:?}", path.level_sizes());
    assert!(stats.setups <= 3, "{stats:?}");
    assert!(stats.refreshes >= 4 && stats.solves >= 4, "{stats:?}");
    assert_eq!(stats.limit_hits, 0, "{stats:?}");
    // Negative curvature was met and blended away, as the direct path's indefinite factors.
    assert!(stats.negative_curvature > 0, "{stats:?}");
    assert!(
        compressed_steps > 0,
        "the direct path never met an indefinite Hessian"
    );
    eprintln!("multilevel: {stats:?}; {compressed_steps} steps with an indefinite exact Hessian");
}

fn largest_difference(a: &[V], b: &[V]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).amax())
        .fold(0.0, f64::max)
}

/// A problem without a convexified Hessian has no multilevel path: Newton over the budget
/// refuses it, naming the factor's size and the budget.
#[test]
fn newton_without_a_convexified_hessian_is_refused_over_the_budget() {
    struct Quadratic {
        matrix: SparseColMat<usize, f64>,
        diagonal: Vec<f64>,
    }
    impl NewtonProblem for Quadratic {
        fn dim(&self) -> usize {
            self.matrix.nrows()
        }
        /// ½ xᵀAx − Σ x.
        fn objective(&mut self, x: &[f64]) -> f64 {
            let mut g = vec![0.0; x.len()];
            self.gradient(x, &mut g);
            x.iter().zip(&g).map(|(x, g)| 0.5 * x * (g + 1.0) - x).sum()
        }
        /// A x − 1 (A is symmetric: its column j is its row j).
        fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
            let a = self.matrix.as_ref();
            for (j, gj) in g.iter_mut().enumerate() {
                *gj = -1.0;
                for (i, v) in a.row_idx_of_col(j).zip(a.val_of_col(j)) {
                    *gj += v * x[i];
                }
            }
        }
        fn pattern(&self) -> SymbolicSparseColMatRef<'_, usize> {
            self.matrix.symbolic()
        }
        fn hessian(&mut self, _x: &[f64]) -> faer::sparse::SparseColMatRef<'_, usize, f64> {
            self.matrix.as_ref()
        }
        fn shift_diagonal(&self) -> &[f64] {
            &self.diagonal
        }
    }
    let mut problem = Quadratic {
        matrix: laplacian(30),
        diagonal: vec![1.0; 30],
    };
    // Within the budget it is solved.
    let mut x = vec![0.0; 30];
    let mut direct = Newton::new(problem.pattern(), NewtonParams::default()).unwrap();
    direct.minimize(&mut problem, &mut x).unwrap();
    let mut x = vec![0.0; 30];
    let mut newton =
        Newton::new(problem.pattern(), newton_params(MemoryBudget::Bytes(16))).unwrap();
    let err = newton.minimize(&mut problem, &mut x).unwrap_err();
    let NewtonError::Factorization(CholeskyError::Multilevel(message)) = &err else {
        panic!("{err:?}");
    };
    let needed = newton.multilevel().unwrap().factor_bytes();
    for part in [
        "30×30",
        &format!("({needed} bytes)"),
        "budget of 16 bytes",
        "no convexified",
    ] {
        assert!(message.contains(part), "{part:?} not in {message:?}");
    }
    // Within the budget, a fill limit the factor exceeds takes the multilevel path; for this
    // problem, which it cannot solve, Newton falls back to the factor, to the same answer.
    let mut newton = Newton::new(
        problem.pattern(),
        NewtonParams {
            multilevel_fill: 0.1,
            ..NewtonParams::default()
        },
    )
    .unwrap();
    assert!(newton.multilevel().is_some_and(|m| m.for_fill()));
    let mut y = vec![0.0; 30];
    newton.minimize(&mut problem, &mut y).unwrap();
    assert!(newton.multilevel().is_none(), "fell back to the factor");
    let solved = {
        let mut x = vec![0.0; 30];
        direct.minimize(&mut problem, &mut x).unwrap();
        x
    };
    assert_eq!(solved, y);
}

/// A factor that fills more than `NewtonParams::multilevel_fill` times the matrix takes the
/// multilevel path within the budget (the path a solid's factor takes by default), to the direct
/// path's answers on the squashed beam; the default keeps the beam (fill 2.7) on the factor.
#[test]
fn a_factor_that_fills_too_much_takes_the_multilevel_path_within_the_budget() {
    let mut beam = Beam::new();
    let mut direct =
        Newton::new(beam.step.pattern(), newton_params(MemoryBudget::Machine)).unwrap();
    assert!(direct.multilevel().is_none());
    let mut filled = Newton::new(
        beam.step.pattern(),
        NewtonParams {
            multilevel_fill: 1.0,
            ..newton_params(MemoryBudget::Machine)
        },
    )
    .unwrap();
    let path = filled.multilevel().expect("the fill is above 1");
    assert!(path.for_fill() && path.factor_bytes() <= path.budget());
    for k in 0..2 {
        let (reference, _) = beam.solve(&mut direct);
        let (answer, _) = beam.solve(&mut filled);
        // As for the budget's multilevel path (the test above): 1e-7 of the motion.
        let motion = largest_difference(&reference, &beam.x);
        let difference = largest_difference(&reference, &answer);
        assert!(
            difference <= 1e-7 * motion,
            "step {k}: {difference:e} of {motion:e} m"
        );
        beam.advance(&reference);
    }
    assert!(filled.multilevel().is_some_and(|m| m.stats().solves >= 2));
}

/// Projective dynamics' direct path, asked for by name: its prefactored matrix over the budget is
/// refused with the size needed and the budget (`Auto` takes the multilevel path instead:
/// tests/integration/pd_multilevel.rs).
#[test]
fn projective_dynamics_direct_over_the_budget_is_refused() {
    let mesh = generators::cloth(12, 1e3).unwrap();
    let free = FreeDofs::new(mesh.vertex_count(), &[0, 11]).unwrap();
    let params = PdParams {
        global_solve: GlobalSolveKind::Direct,
        cholesky: CholeskyParams {
            memory_budget: MemoryBudget::Bytes(1000),
            ..PdParams::default().cholesky
        },
        ..PdParams::default()
    };
    let err =
        ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, H, params).unwrap_err();
    let PdError::Factorization(CholeskyError::OverBudget { needed, budget, .. }) = err.clone()
    else {
        panic!("{err:?}");
    };
    assert_eq!(budget, 1000);
    assert!(needed > 1000);
    assert!(err
        .to_string()
        .contains("above the memory budget of 1000 bytes"));
    // Within a budget of what it needs, it is built.
    let params = PdParams {
        cholesky: CholeskyParams {
            memory_budget: MemoryBudget::Bytes(needed),
            ..params.cholesky
        },
        ..params
    };
    ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, H, params).unwrap();
}
