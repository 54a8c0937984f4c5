//! One backward Euler step solved two ways, projective dynamics and Newton, on hooke's own assembly:
//! both must reach the same minimiser of Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x).

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use hooke_assembly::{FreeDofs, HessianParams, HessianPattern, HessianWorkspace, SpringForces};
use hooke_mesh::{generators, Spring, SpringMesh};
use hooke_solvers::{
    Newton, NewtonParams, NewtonProblem, PdParams, ProjectiveDynamics, StopReason,
};
use nalgebra::Vector3;

type V = Vector3<f64>;

/// Φ over the free DOFs, with the Hessian from `HessianPattern`.
struct Step<'a> {
    springs: &'a [Spring],
    masses: &'a [f64],
    free: FreeDofs,
    pattern: HessianPattern<3>,
    workspace: HessianWorkspace<3>,
    values: Vec<f64>,
    forces: SpringForces<3>,
    force: Vec<V>,
    y: Vec<V>,
    x: Vec<V>,
    h: f64,
    shift: Vec<f64>,
}

impl<'a> Step<'a> {
    fn new(mesh: &'a SpringMesh<3>, pinned: &[u32], y: Vec<V>, x_pinned: Vec<V>, h: f64) -> Self {
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, pinned).unwrap();
        let pattern = HessianPattern::new(n, mesh.springs(), Some(&free));
        let shift = free
            .free_vertices()
            .iter()
            .flat_map(|&v| [mesh.masses()[v as usize]; 3])
            .collect();
        Step {
            springs: mesh.springs(),
            masses: mesh.masses(),
            workspace: pattern.workspace(),
            values: pattern.new_values(),
            forces: SpringForces::new(n, mesh.springs()),
            force: vec![V::zeros(); n],
            free,
            pattern,
            y,
            x: x_pinned,
            h,
            shift,
        }
    }

    fn expand(&mut self, xf: &[f64]) {
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            self.x[v as usize] = V::new(xf[3 * f], xf[3 * f + 1], xf[3 * f + 2]);
        }
    }
}

impl NewtonProblem for Step<'_> {
    fn dim(&self) -> usize {
        3 * self.free.free_count()
    }

    fn objective(&mut self, xf: &[f64]) -> f64 {
        self.expand(xf);
        let inertia: f64 = self
            .free
            .free_vertices()
            .iter()
            .map(|&v| {
                0.5 * self.masses[v as usize]
                    * (self.x[v as usize] - self.y[v as usize]).norm_squared()
            })
            .sum();
        inertia + self.h * self.h * hooke_assembly::spring_energy(self.springs, &self.x, false)
    }

    fn gradient(&mut self, xf: &[f64], g: &mut [f64]) {
        self.expand(xf);
        self.forces
            .compute(self.springs, &self.x, None, &mut self.force, false);
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let v = v as usize;
            let gv = (self.x[v] - self.y[v]) * self.masses[v] - self.force[v] * (self.h * self.h);
            g[3 * f..3 * f + 3].copy_from_slice(gv.as_slice());
        }
    }

    fn pattern(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.pattern.symbolic()
    }

    fn hessian(&mut self, xf: &[f64]) -> SparseColMatRef<'_, usize, f64> {
        self.expand(xf);
        self.pattern.assemble_into(
            self.springs,
            &self.x,
            self.masses,
            self.h,
            HessianParams::default(),
            &mut self.workspace,
            &mut self.values,
        );
        self.pattern.matrix(&self.values)
    }

    fn shift_diagonal(&self) -> &[f64] {
        &self.shift
    }
}

/// Solve one step from rest, under gravity, both ways; return (PD result, Newton result, |x* − x_n|).
fn both(mesh: &SpringMesh<3>, pinned: &[u32], h: f64) -> (Vec<V>, Vec<V>, f64) {
    let x_n = mesh.positions().to_vec();
    let g = V::new(0.0, -9.81, 0.0);
    let y: Vec<V> = x_n
        .iter()
        .enumerate()
        .map(|(v, x)| {
            if pinned.contains(&(v as u32)) {
                *x
            } else {
                x + g * (h * h)
            }
        })
        .collect();
    let free = FreeDofs::new(mesh.vertex_count(), pinned).unwrap();
    // Projective dynamics to convergence, Φ recorded.
    let params = PdParams {
        max_iterations: 20_000,
        tolerance: 1e-10,
        record_objective: true,
        ..Default::default()
    };
    let mut pd =
        ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, h, params).unwrap();
    let mut x_pd = y.clone();
    let report = pd.solve(mesh.springs(), &y, &mut x_pd);
    let c = &report.changes;
    let at = |k: usize| c[k.min(c.len() - 1)];
    eprintln!(
        "PD: {} iterations; changes after 1, 10, 100, 1000 and the last: {:e} {:e} {:e} {:e} {:e}",
        report.iterations,
        at(0),
        at(9),
        at(99),
        at(999),
        at(c.len() - 1)
    );
    assert_eq!(
        report.stop,
        StopReason::Converged,
        "PD did not converge in {} iterations",
        report.iterations
    );
    // Φ never increases along PD, up to the round-off of evaluating Φ: near rest, each spring term
    // ½ k (|r| − l)² loses digits to the cancellation in |r| − l, so Φ is good to about 1e-13 of its
    // size here; changes below 1e-12 of Φ⁰ are noise, not increase.
    let floor = 1e-12 * report.objectives[0];
    for (k, w) in report.objectives.windows(2).enumerate() {
        assert!(
            w[1] <= w[0] + floor,
            "iteration {k}: Φ rose from {} to {}",
            w[0],
            w[1]
        );
    }
    // Newton to a relative gradient of 1e-12.
    let mut step = Step::new(mesh, pinned, y.clone(), x_n.clone(), h);
    let mut newton = Newton::new(
        step.pattern(),
        NewtonParams {
            tolerance: 1e-12,
            ..Default::default()
        },
    )
    .unwrap();
    let mut xf: Vec<f64> = free
        .free_vertices()
        .iter()
        .flat_map(|&v| y[v as usize].as_slice().to_vec())
        .collect();
    let report = newton.minimize(&mut step, &mut xf).unwrap();
    eprintln!(
        "Newton: {} iterations, relative gradient {:e}, {} shifted",
        report.iterations,
        report.gradient(),
        report.shifted_steps
    );
    // From rest the initial gradient is tiny (springs at rest), so 1e-12 of it can lie below the
    // round-off floor of the gradient; Newton then reports stagnation, which is fine if it got
    // within 1e-9.
    assert!(
        report.stop == StopReason::Converged
            || (report.stop == StopReason::Stagnated && report.gradient() <= 1e-9),
        "Newton: {report:?}"
    );
    step.expand(&xf);
    let motion = step
        .x
        .iter()
        .zip(&x_n)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt();
    (x_pd, step.x, motion)
}

fn assert_same(name: &str, a: &[V], b: &[V], motion: f64) {
    let difference = a
        .iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm_squared())
        .sum::<f64>()
        .sqrt();
    // Newton stops at a relative gradient of 1e-12; PD when an iteration moves no position by more
    // than 1e-10 of the largest displacement, and converges linearly at a rate ρ ≈ 0.997 here, so
    // its remaining error is about change / (1 − ρ) ≈ 3e-8 of the displacement, itself a fraction of
    // the step's motion: 1e-8 of the motion is a bound with margin for both.
    assert!(
        difference <= 1e-8 * motion,
        "{name}: PD and Newton differ by {difference:e} m (the step moves {motion:e} m)"
    );
}

#[test]
fn projective_dynamics_and_newton_reach_the_same_cloth_step() {
    let mesh = generators::cloth(8, 1e3).unwrap();
    let (pd, newton, motion) = both(&mesh, &[0, 7], 1.0 / 30.0);
    assert_same("cloth-8", &pd, &newton, motion);
}

#[test]
fn projective_dynamics_and_newton_reach_the_same_beam_step() {
    let mesh = generators::beam(1).unwrap();
    let clamped: Vec<u32> = (0..mesh.vertex_count() as u32)
        .filter(|&v| mesh.positions()[v as usize].x == 0.0)
        .collect();
    let (pd, newton, motion) = both(&mesh, &clamped, 1.0 / 30.0);
    assert_same("beam-1", &pd, &newton, motion);
}
