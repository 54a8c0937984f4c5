//! Newton's factor reuse (`NewtonParams::factor_reuse`): a Newton system solved by CG preconditioned
//! with the factor of an earlier matrix must give the step a factorisation gives, within the
//! solve's own tolerance, and fall back to a factorisation whenever CG does not converge.

use hooke_assembly::FreeDofs;
use hooke_mesh::generators;
use hooke_solvers::{
    BackwardEulerStep, FactorReuse, Newton, NewtonError, NewtonParams, NewtonProblem, NewtonReport,
    ParamError, StopReason,
};
use nalgebra::Vector3;

type V = Vector3<f64>;

const H: f64 = 1.0 / 30.0;
/// The step-size tolerance of the solves compared, m/s: tight, so that two converged answers
/// differ by far less than the motion they compare.
const TOLERANCE: f64 = 1e-9;

/// A 12×12 cloth (k = 1e3 N/m) pinned at two corners, falling from rest under gravity: the first
/// steps move it a lot (the Newton matrix changes between iterations), the later ones less.
struct Trajectory {
    step: BackwardEulerStep<3>,
    x: Vec<V>,
    v: Vec<V>,
    pinned: Vec<u32>,
}

impl Trajectory {
    fn new() -> Self {
        let n = 12;
        let mesh = generators::cloth(n, 1e3).unwrap();
        let pinned = vec![0, (n - 1) as u32];
        let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
        Trajectory {
            step: BackwardEulerStep::new(mesh.springs(), mesh.masses(), free, H),
            x: mesh.positions().to_vec(),
            v: vec![V::zeros(); mesh.vertex_count()],
            pinned,
        }
    }

    /// The inertial target y = x + h v + h² g at the free vertices.
    fn target(&self) -> Vec<V> {
        let g = V::new(0.0, -9.81, 0.0);
        (0..self.x.len())
            .map(|i| {
                if self.pinned.contains(&(i as u32)) {
                    self.x[i]
                } else {
                    self.x[i] + H * self.v[i] + H * H * g
                }
            })
            .collect()
    }

    /// Solve the current step with `newton`; return the new positions and the report.
    fn solve(&mut self, newton: &mut Newton) -> (Vec<V>, NewtonReport) {
        let y = self.target();
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

fn params(factor_reuse: FactorReuse) -> NewtonParams {
    NewtonParams {
        tolerance: TOLERANCE,
        factor_reuse,
        ..NewtonParams::default()
    }
}

fn largest_difference(a: &[V], b: &[V]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).amax())
        .fold(0.0, f64::max)
}

/// Along 40 steps of a falling cloth, each step is solved from the same state with and without
/// reuse: the answers agree within the tolerance's displacement, and reuse replaces most
/// factorisations once the motion settles.
#[test]
fn reuse_gives_the_factored_answer_with_fewer_factorizations() {
    let mut trajectory = Trajectory::new();
    let mut factored = Newton::new(trajectory.step.pattern(), params(FactorReuse::OFF)).unwrap();
    let mut reusing = Newton::new(trajectory.step.pattern(), params(FactorReuse::DEFAULT)).unwrap();
    let (mut factorizations, mut reused, mut reused_steps_late) = (0, 0, 0);
    for k in 0..40 {
        let (reference, plain) = trajectory.solve(&mut factored);
        let (answer, report) = trajectory.solve(&mut reusing);
        assert_eq!(plain.reused_factors, 0, "reuse off: {plain:?}");
        // Both solves end with a step of at most TOLERANCE · h per coordinate, taken; what is
        // left is smaller still (Newton converges quadratically there), so two converged answers
        // lie within a few such steps of each other.
        let difference = largest_difference(&reference, &answer);
        assert!(
            difference <= 4.0 * TOLERANCE * H,
            "step {k}: answers {difference:e} m apart (reference {plain:?}, reusing {report:?})"
        );
        // Every iteration either factored or reused (failed attempts factor too).
        assert!(
            report.factorizations + report.reused_factors >= report.iterations,
            "{report:?}"
        );
        factorizations += report.factorizations;
        reused += report.reused_factors;
        if k >= 20 {
            reused_steps_late += usize::from(report.reused_factors > 0);
        }
        trajectory.advance(&reference);
    }
    assert!(reused > 0, "no system was solved on a held factor");
    assert!(
        reused_steps_late >= 15,
        "only {reused_steps_late} of the 20 settling steps reused a factor"
    );
    eprintln!("reusing: {factorizations} factorisations, {reused} steps on a held factor");
}

/// CG allowed a single iteration cannot solve the systems of a cloth starting to fall: the
/// attempts are counted as refused, the matrices are factored, and the answer is the factored one.
#[test]
fn a_reuse_that_does_not_converge_factors_the_matrix() {
    let mut trajectory = Trajectory::new();
    let mut factored = Newton::new(trajectory.step.pattern(), params(FactorReuse::OFF)).unwrap();
    let one_iteration = FactorReuse {
        max_iterations: 1,
        tolerance: 1e-12,
    };
    let mut reusing = Newton::new(trajectory.step.pattern(), params(one_iteration)).unwrap();
    let mut refused = 0;
    for k in 0..5 {
        let (reference, plain) = trajectory.solve(&mut factored);
        let (answer, report) = trajectory.solve(&mut reusing);
        refused += report.refused_reuses;
        // At most one attempt per iteration (a refused one ends reuse until the next full step).
        assert!(
            report.reused_factors + report.refused_reuses <= report.iterations,
            "step {k}: {report:?}"
        );
        assert!(
            report.reuse_iterations <= report.reused_factors + report.refused_reuses,
            "step {k}: at most one CG iteration per attempt: {report:?}"
        );
        let difference = largest_difference(&reference, &answer);
        assert!(
            difference <= 4.0 * TOLERANCE * H,
            "step {k}: answers {difference:e} m apart ({plain:?}, {report:?})"
        );
        trajectory.advance(&reference);
    }
    assert!(refused > 0, "no reuse was refused");
}

/// Out-of-range settings are refused before anything is computed, naming the field.
#[test]
fn factor_reuse_settings_are_checked() {
    let trajectory = Trajectory::new();
    for (reuse, field) in [
        (
            FactorReuse {
                tolerance: 0.0,
                ..FactorReuse::DEFAULT
            },
            "FactorReuse::tolerance",
        ),
        (
            FactorReuse {
                tolerance: 1.0,
                ..FactorReuse::DEFAULT
            },
            "FactorReuse::tolerance",
        ),
        (
            FactorReuse {
                tolerance: f64::NAN,
                ..FactorReuse::DEFAULT
            },
            "FactorReuse::tolerance",
        ),
        (
            FactorReuse {
                max_iterations: 10_001,
                ..FactorReuse::DEFAULT
            },
            "FactorReuse::max_iterations",
        ),
    ] {
        match Newton::new(trajectory.step.pattern(), params(reuse)) {
            Err(NewtonError::InvalidParameter(e)) => {
                assert_eq!(ParamError::field(&e), field, "{e}")
            }
            other => panic!("{reuse:?} accepted: {other:?}"),
        }
    }
}
