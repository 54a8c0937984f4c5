//! One backward Euler step solved two ways, projective dynamics and Newton, on hooke's own assembly:
//! both must reach the same minimiser of Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x).

use hooke_assembly::FreeDofs;
use hooke_mesh::{generators, SpringMesh};
use hooke_solvers::Convergence;
use hooke_solvers::{
    BackwardEulerStep, Newton, NewtonParams, NewtonProblem, PdParams, ProjectiveDynamics,
    StopReason,
};
use nalgebra::Vector3;

use crate::common;
use common::inertial_target;

type V = Vector3<f64>;

/// Solve one step from rest, under gravity, both ways; return (PD result, Newton result, |x* − x_n|).
fn both(mesh: &SpringMesh<3>, pinned: &[u32], h: f64) -> (Vec<V>, Vec<V>, f64) {
    let x_n = mesh.positions().to_vec();
    let g = V::new(0.0, -9.81, 0.0);
    let y = inertial_target(&x_n, pinned, |_, _| g * (h * h));
    let free = FreeDofs::new(mesh.vertex_count(), pinned).unwrap();
    // Projective dynamics to convergence, Φ recorded.
    let params = PdParams {
        max_iterations: 20_000,
        // m/s: an iteration that moves no coordinate by more than 1e-12 m/s · h (3.3e-14 m at
        // h = 1/30 s).
        tolerance: 1e-12,
        record_objective: true,
        ..Default::default()
    };
    let mut pd =
        ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, h, params).unwrap();
    let mut x_pd = y.clone();
    let report = pd.solve(mesh.springs(), &y, &mut x_pd).unwrap();
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
    let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, h);
    let mut xf = vec![0.0; step.dim()];
    step.set_step(&y, &x_n, &mut xf);
    let mut newton = Newton::new(
        step.pattern(),
        NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: 1e-12,
            ..Default::default()
        },
    )
    .unwrap();
    let report = newton.minimize(&mut step, &mut xf).unwrap();
    eprintln!(
        "Newton: {} iterations, relative gradient {:e}, {} shifted",
        report.iterations,
        report.gradient(),
        report.shifted_steps
    );
    // From rest the initial gradient is tiny (springs at rest), so 1e-12 of it can lie below the
    // round-off floor of the gradient; Newton then stops there (RoundOff, converged), which is
    // fine if it got within 1e-9.
    assert!(
        report.stop == StopReason::Converged
            || (report.stop == StopReason::RoundOff && report.gradient() <= 1e-9),
        "Newton: {report:?}"
    );
    let x_newton = step.positions(&xf).to_vec();
    let motion = x_newton
        .iter()
        .zip(&x_n)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt();
    (x_pd, x_newton, motion)
}

fn assert_same(name: &str, a: &[V], b: &[V], motion: f64) {
    let difference = a
        .iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm_squared())
        .sum::<f64>()
        .sqrt();
    // Newton stops at a relative gradient of 1e-12; PD when an iteration moves no coordinate by
    // more than 1e-12 m/s · h = 3.3e-14 m, and converges linearly at a rate ρ ≈ 0.997 here, so its
    // remaining error is about change / (1 − ρ) ≈ 1.1e-11 m per coordinate (measured 9.2e-10 m
    // over the mesh at ten times the tolerance), against 1e-8 of the step's motion, 8.5e-10 m.
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

/// Newton's robustness requirement on cloth-40: ten steps of exact backward Euler (relative
/// gradient 1e-10) from rest reach the speed-vs-error state (docs/scenes.md §8); from there, Newton
/// must reach 1e-8 in at most 25 iterations. The cloth buckles on the way (compressed springs: an
/// indefinite exact Hessian), so this also checks that every step of the run converges, with its
/// indefinite steps counted.
#[test]
fn newton_converges_fast_through_the_buckling_cloth_40_run() {
    let n = 40;
    let mesh = generators::cloth(n, 1e3).unwrap();
    let pinned = [0u32, n as u32 - 1];
    let h = 1.0 / 30.0;
    let gravity = V::new(0.0, -9.81, 0.0);
    let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
    let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, h);
    let exact = NewtonParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-10,
        ..Default::default()
    };
    let mut newton = Newton::new(step.pattern(), exact).unwrap();
    let mut x = mesh.positions().to_vec();
    let mut v = vec![V::zeros(); x.len()];
    let mut xf = vec![0.0; step.dim()];
    let mut not_convex = 0;
    for s in 0..=10 {
        if s == 10 {
            newton.params.tolerance = 1e-8;
            newton.params.convergence = Convergence::RelativeGradient;
        }
        let y = inertial_target(&x, &pinned, |i, _| v[i] * h + gravity * (h * h));
        step.set_step(&y, &x, &mut xf);
        let report = newton.minimize(&mut step, &mut xf).unwrap();
        assert_eq!(report.stop, StopReason::Converged, "step {s}: {report:#?}");
        // Measured with the defaults (convex blend, relaxation): 5–8 iterations per step (8 from
        // the speed-vs-error state), 25 blended steps and 32 failed attempts in steps 0–10.
        assert!(
            report.iterations <= 25,
            "step {s}: {} iterations",
            report.iterations
        );
        // Every failed attempt under the default policy is an indefinite matrix.
        not_convex += report.indefinite_steps + report.failed_factorizations;
        let next = step.positions(&xf).to_vec();
        for i in 0..x.len() {
            v[i] = (next[i] - x[i]) / h;
        }
        x = next;
    }
    assert!(
        not_convex > 0,
        "the run buckles: some Hessians must have been indefinite"
    );
}

/// The dashpot dissipation potential Ψ added by `set_dashpot`: its gradient and Hessian against
/// central differences, the exact objective change against the plain difference, and the Newton
/// solution against the backward Euler equation with the dashpot force written out.
#[test]
fn the_dashpot_term_is_consistent_and_enters_the_step() {
    use hooke_assembly::fd;
    let n = 5;
    let mesh = generators::cloth(n, 1e3).unwrap();
    let pinned = [0u32, n as u32 - 1];
    let h = 1.0 / 30.0;
    let c = 0.7; // N·s/m
    let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
    let x_n: Vec<V> = mesh
        .positions()
        .iter()
        .enumerate()
        .map(|(v, p)| p + V::new(0.01 * (v as f64).sin(), 0.02 * (v as f64 * 0.7).cos(), 0.0))
        .collect();
    let y = inertial_target(&x_n, &pinned, |v, _| {
        V::new(0.05, -0.03, 0.02) * (1.0 + 0.1 * v as f64).sin()
    });
    let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, h);
    let mut xf = vec![0.0; step.dim()];
    step.set_step(&y, &x_n, &mut xf);
    step.set_dashpot(c, &x_n);
    let dim = step.dim();
    // A point between x_n and y, so every term is non-trivial.
    let x0: Vec<f64> = xf
        .iter()
        .enumerate()
        .map(|(k, &v)| v - 0.3 * (k as f64 * 0.37).sin() * 1e-2)
        .collect();

    // Gradient: central differences with a step of 1e-6 m on positions of size ~1 m: truncation
    // ~1e-12 relative, round-off ~ε|Φ|/1e-6; 1e-6 of the gradient's norm bounds both.
    let cell = std::cell::RefCell::new(&mut step);
    let numeric = fd::gradient(|x| cell.borrow_mut().objective(x), &x0, 1e-6);
    let mut g = vec![0.0; dim];
    cell.borrow_mut().gradient(&x0, &mut g);
    let g_norm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
    let g_error = g
        .iter()
        .zip(&numeric)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        g_error <= 1e-6 * g_norm,
        "gradient vs differences: {g_error:e} (|g| = {g_norm:e})"
    );
    // Hessian: differences of the gradient, same reasoning on the Hessian's scale.
    let numeric = fd::jacobian(|x, out| cell.borrow_mut().gradient(x, out), &x0, dim, 1e-6);
    let step = cell.into_inner();
    let analytic = step.hessian(&x0).to_dense();
    let scale = numeric.norm();
    let mut h_error = 0.0f64;
    for r in 0..dim {
        for col in 0..dim {
            h_error = h_error.max((analytic[(r, col)] - numeric[(r, col)]).abs());
        }
    }
    assert!(
        h_error <= 1e-6 * scale,
        "Hessian vs differences: {h_error:e} (|H| = {scale:e})"
    );
    // The exact change equals the plain difference where the latter is accurate (a large step).
    let trial: Vec<f64> = x0.iter().map(|v| v + 1e-3).collect();
    let exact = step.objective_change(&x0, &trial);
    let plain = step.objective(&trial) - step.objective(&x0);
    assert!(
        (exact - plain).abs() <= 1e-9 * plain.abs(),
        "objective change {exact:e} vs difference {plain:e}"
    );

    // Newton's solution satisfies M (x − y) = h² (f_spring(x) + f_dashpot), with the dashpot force
    // −c ((v_i − v_j)·d) d at v = (x − x_n)/h and d the spring direction at x_n.
    let mut newton = Newton::new(
        step.pattern(),
        NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: 1e-12,
            ..Default::default()
        },
    )
    .unwrap();
    let report = newton.minimize(step, &mut xf).unwrap();
    assert!(report.gradient() <= 1e-11, "{report:#?}");
    let x = step.positions(&xf).to_vec();
    let mut force = vec![V::zeros(); x.len()];
    let mut largest = 0.0f64;
    for s in mesh.springs() {
        let (i, j) = s.ends();
        let f = hooke_assembly::spring::force(s.stiffness, s.rest_length, &(x[i] - x[j]));
        let d = (x_n[i] - x_n[j]).normalize();
        let v_rel = ((x[i] - x_n[i]) - (x[j] - x_n[j])) / h;
        let damping = d * (-c * v_rel.dot(&d));
        force[i] += f + damping;
        force[j] -= f + damping;
        largest = largest.max(f.norm()).max(damping.norm());
    }
    for v in 0..x.len() {
        if pinned.contains(&(v as u32)) {
            continue;
        }
        let residual = (x[v] - y[v]) * mesh.masses()[v] - force[v] * (h * h);
        // Newton stopped at 1e-12 of the initial gradient; the force terms are summed here in another
        // order: 1e-9 of the largest h²-scaled force term bounds both.
        assert!(
            residual.norm() <= 1e-9 * largest * h * h,
            "vertex {v}: residual {:e}",
            residual.norm()
        );
    }
}

/// Newton on one backward Euler step of cloth-10 (two corners pinned, one of them moved 5 cm
/// along its path for this step), pins removed (reduction) and pins held by counter-forces.
#[test]
fn counter_forces_give_the_reduced_newton_step() {
    let mesh = generators::cloth(10, 1e3).unwrap();
    let n = mesh.vertex_count();
    let h = 1.0 / 30.0;
    let pinned = [0u32, 9];
    let free = FreeDofs::new(n, &pinned).unwrap();
    let g = V::new(0.0, -9.81, 0.0);
    // A state in motion: the rest shape, waved, moving, and vertex 9 placed on its path.
    let mut x_n: Vec<V> = mesh
        .positions()
        .iter()
        .map(|p| p + V::new(0.0, 0.02 * (5.0 * p.x).sin(), 0.01 * (3.0 * p.z).cos()))
        .collect();
    x_n[9] += V::new(0.05, 0.0, 0.0);
    let y = inertial_target(&x_n, &pinned, |_, _| {
        V::new(0.1, 0.3, 0.0) * h + g * (h * h)
    });
    let params = NewtonParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-10,
        ..Default::default()
    };
    let solve = |mut step: BackwardEulerStep<3>| {
        let mut x = vec![0.0; step.dim()];
        step.set_step(&y, &x_n, &mut x);
        let start = x.clone();
        let mut newton = Newton::new(step.pattern(), params).unwrap();
        let report = newton.minimize(&mut step, &mut x).unwrap();
        assert_eq!(report.stop, StopReason::Converged, "{report:?}");
        (step.positions(&x).to_vec(), start, x, report.iterations)
    };
    let (reduced, _, _, reduced_iterations) = solve(BackwardEulerStep::new(
        mesh.springs(),
        mesh.masses(),
        free.clone(),
        h,
    ));
    let mut counter =
        BackwardEulerStep::with_counter_forces(mesh.springs(), mesh.masses(), free, h);
    assert!(counter.has_counter_forces());
    assert_eq!(counter.dim(), 3 * n, "every vertex is an unknown");
    // The modified gradient is zero at the pinned DOFs from the start.
    let mut start = vec![0.0; 3 * n];
    counter.set_step(&y, &x_n, &mut start);
    let mut gradient = vec![1.0; 3 * n];
    counter.gradient(&start, &mut gradient);
    for &p in &pinned {
        assert_eq!(&gradient[3 * p as usize..][..3], &[0.0; 3]);
    }
    let (full, start, end, counter_iterations) = solve(counter);
    eprintln!(
        "Newton iterations: reduction {reduced_iterations}, counter-force {counter_iterations}"
    );
    // Pinned DOFs never move: their unknowns keep the held positions bit for bit.
    for &p in &pinned {
        let p = p as usize;
        assert_eq!(&end[3 * p..3 * p + 3], &start[3 * p..3 * p + 3]);
        assert_eq!(&start[3 * p..3 * p + 3], x_n[p].as_slice());
        assert_eq!(full[p], x_n[p]);
    }
    let motion = reduced
        .iter()
        .zip(&x_n)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt();
    let difference = full
        .iter()
        .zip(&reduced)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt();
    eprintln!("counter-force vs reduction: {difference:e} m in a step of {motion:e} m");
    // Both solve the same free system (CounterForce's block-diagonal argument) and stop at a
    // relative gradient of 1e-10; the error left in each is about 1e-10 of the first Newton step,
    // itself of the order of the motion. 1e-9 of the motion bounds their difference with margin.
    assert!(
        difference <= 1e-9 * motion,
        "counter-force and reduction differ by {difference:e} m (the step moves {motion:e} m)"
    );
}

/// Projective dynamics gives the same bits on one thread and two: cloth-160's factor (1.87 M
/// stored values) is large enough that its three-column solve is split over two threads along the
/// elimination tree, and the local step and right-hand side are parallel too.
#[test]
fn projective_dynamics_gives_the_same_bits_on_one_thread_and_two() {
    let n = 160;
    let mesh = generators::cloth(n, 1e3).unwrap();
    let pinned = [0, n as u32 - 1];
    let h = 1.0 / 30.0;
    let g = V::new(0.0, -9.81, 0.0);
    let y = inertial_target(mesh.positions(), &pinned, |_, _| g * (h * h));
    let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
    let run = |parallel: bool| {
        let params = PdParams {
            max_iterations: 3,
            parallel,
            ..PdParams::default()
        };
        let mut pd =
            ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, h, params).unwrap();
        let mut x = y.clone();
        pd.solve(mesh.springs(), &y, &mut x).unwrap();
        x
    };
    let (serial, parallel) = (run(false), run(true));
    assert!(serial != y, "PD moved nothing");
    for (i, (a, b)) in serial.iter().zip(&parallel).enumerate() {
        for k in 0..3 {
            assert_eq!(a[k].to_bits(), b[k].to_bits(), "vertex {i}, coordinate {k}");
        }
    }
}

/// With an obstacle in the way from x_n to y, the first iterate is x_n + h v_n where that way is
/// clear and Φ is lower there (a body sliding along the ground), x_n otherwise.
#[test]
fn a_blocked_step_starts_where_the_velocity_takes_the_mesh() {
    use hooke_assembly::barrier::Obstacle;
    use hooke_solvers::backward_euler::ContactModel;

    let mesh = generators::cloth(4, 1e3).unwrap();
    let h = 1.0 / 60.0;
    // The cloth 0.1 mm above the ground y = 0, within the barrier's reach (0.3 mm): gravity's
    // h² g = 2.7 mm takes y through the ground.
    let lowest = mesh
        .positions()
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    let x_n: Vec<V> = mesh
        .positions()
        .iter()
        .map(|p| p + V::new(0.0, 1e-4 - lowest, 0.0))
        .collect();
    let g = V::new(0.0, -9.81, 0.0);
    let free = FreeDofs::new(mesh.vertex_count(), &[]).unwrap();
    let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, h);
    let ground = Obstacle::half_space(V::zeros(), V::y()).unwrap();
    step.set_contact(
        Some(ContactModel {
            obstacles: vec![(ground, 0.0)],
            distance: 3e-4,
            stiffness: 1000.0 * 9.80665 / 3e-4,
            friction_velocity: 1e-3,
        }),
        mesh.masses(),
    );
    let flatten = |x: &[V]| x.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<f64>>();
    let mut unknowns = vec![0.0; step.dim()];
    for (velocity, moves) in [
        // Sliding along the ground: its way is clear, and Φ is lower there.
        (V::new(0.01, 0.0, -0.02), true),
        // Towards the ground at 1 m/s: h v_n crosses it.
        (V::new(0.0, -1.0, 0.0), false),
    ] {
        let v = vec![velocity; x_n.len()];
        let y: Vec<V> = x_n.iter().map(|p| p + velocity * h + g * (h * h)).collect();
        step.set_step(&y, &x_n, &mut unknowns);
        assert_eq!(unknowns, flatten(&x_n), "set_step starts at x_n");
        step.set_step_with_velocities(&y, &x_n, Some(&v), &mut unknowns);
        let moved: Vec<V> = x_n.iter().map(|p| p + velocity * h).collect();
        let expected = if moves {
            flatten(&moved)
        } else {
            flatten(&x_n)
        };
        assert_eq!(unknowns, expected, "velocity {velocity:?}");
    }
}
