//! Self-contact friction inside backward Euler's objective: with μ > 0 the step's Φ, gradient,
//! change and Hessian differ from the frictionless step's by exactly h² times the friction
//! potential lagged at the step's start (computed independently by
//! `hooke_assembly::self_friction`), also at an iterate where every pair has left d̂: the
//! pairs lagged at x_n keep their friction, and the Hessian's pattern keeps their blocks.

use hooke_assembly::self_contact::SelfContactBarrier;
use hooke_assembly::self_friction::SelfContactFriction;
use hooke_assembly::FreeDofs;
use hooke_solvers::backward_euler::SelfContactModel;
use hooke_solvers::{BackwardEulerStep, NewtonProblem};
use nalgebra::{DMatrix, Vector3};

use crate::sheets::two_sheets;

type V = Vector3<f64>;

const D_HAT: f64 = 1e-3;
const H: f64 = 1.0 / 30.0;
const MU: f64 = 0.3;

fn flatten(x: &[V]) -> Vec<f64> {
    x.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

#[test]
fn the_step_adds_h2_times_the_lagged_friction_also_where_pairs_leave_reach() {
    let (x0, triangles, springs) = two_sheets(5, 5e-4);
    let count = x0.len();
    let masses = vec![0.01; count];
    let model = |friction: f64| SelfContactModel {
        triangles: triangles.clone(),
        rest_positions: x0.clone(),
        distance: D_HAT,
        stiffness: 1e2,
        friction,
        friction_velocity: 1e-3,
    };
    let upper = |v: usize| v >= count / 2;
    let velocities: Vec<V> = (0..count)
        .map(|v| {
            if upper(v) {
                V::new(0.3, 0.0, 0.1)
            } else {
                V::zeros()
            }
        })
        .collect();
    let y: Vec<V> = x0.iter().zip(&velocities).map(|(x, v)| x + v * H).collect();
    let mut steps = [MU, 0.0].map(|mu| {
        let free = FreeDofs::new(count, &[]).unwrap();
        let mut step = BackwardEulerStep::<3>::new(&springs, &masses, free, H);
        step.set_self_contact(Some(model(mu))).unwrap();
        step
    });
    // The friction on its own, lagged at x_n.
    let free = vec![true; count];
    let mut barrier = SelfContactBarrier::new(model(MU), free.clone());
    let mut friction = SelfContactFriction::new(MU, 1e-3, free);
    friction.lag(&mut barrier, &x0, H);
    assert!(friction.pairs().len() > 10, "the sheets are within d̂");
    let eps = friction.smoothing_length();
    let h2 = H * H;

    // Near: the upper sheet slid by 3ε (Coulomb's regime for most pairs). Far: also lifted by
    // 5 d̂, where no pair is within d̂ and the barrier has no term.
    for lift in [0.0, 5.0 * D_HAT] {
        let x: Vec<V> = x0
            .iter()
            .enumerate()
            .map(|(v, p)| {
                if upper(v) {
                    p + V::new(3.0 * eps, lift, -eps)
                } else {
                    *p
                }
            })
            .collect();
        let xf = flatten(&x);
        let potential = friction.energy(&x);
        assert!(potential > 0.0);

        let [with, without] = &mut steps;
        // A new step for each iterate, so that this iterate's pattern update is the step's first
        // (it replaces the links of earlier steps).
        for step in [&mut *with, &mut *without] {
            let mut unknowns = vec![0.0; step.dim()];
            step.set_step_with_velocities(&y, &x0, Some(&velocities), &mut unknowns);
        }
        let difference = with.objective(&xf) - without.objective(&xf);
        // Φ's rounding is ~1e-16 of its size; the difference is compared on that scale.
        let scale = with.objective(&xf).abs();
        assert!(
            (difference - h2 * potential).abs() <= 1e-12 * scale,
            "lift {lift}: Φ differs by {difference:e}, h² D = {:e}",
            h2 * potential
        );

        let (mut g_with, mut g_without) = (vec![0.0; xf.len()], vec![0.0; xf.len()]);
        with.gradient(&xf, &mut g_with);
        without.gradient(&xf, &mut g_without);
        let mut g_friction = vec![V::zeros(); count];
        friction.add_gradient(&x, h2, &mut g_friction);
        let g_scale = g_with.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (k, (a, b)) in g_with.iter().zip(&g_without).enumerate() {
            let expected = g_friction[k / 3][k % 3];
            assert!(
                (a - b - expected).abs() <= 1e-12 * g_scale,
                "lift {lift}: gradient entry {k}: {:e} vs {expected:e}",
                a - b
            );
        }

        let delta: Vec<V> = (0..count)
            .map(|v| V::new((v as f64).sin(), 0.2, (v as f64).cos()) * (0.1 * eps))
            .collect();
        let trial: Vec<f64> = xf.iter().zip(flatten(&delta)).map(|(a, b)| a + b).collect();
        let change = with.objective_change(&xf, &trial) - without.objective_change(&xf, &trial);
        let expected = h2 * friction.energy_change(&x, &delta);
        assert!(
            (change - expected).abs() <= 1e-9 * expected.abs(),
            "lift {lift}: change {change:e} vs {expected:e}"
        );

        // The Hessians: the pattern update at this iterate (the step's first) keeps the lagged
        // pairs' blocks even where the barrier has no pair left (a missing block would trip the
        // assembly's debug assertion); the difference is h² ∇²D.
        with.update_pattern(&xf);
        without.update_pattern(&xf);
        let h_with = with.hessian(&xf).to_dense();
        let h_without = without.hessian(&xf).to_dense();
        let n = 3 * count;
        let mut expected = DMatrix::<f64>::zeros(n, n);
        friction.for_each_hessian_block(&x, h2, |i, j, block| {
            let mut view = expected.fixed_view_mut::<3, 3>(3 * i, 3 * j);
            view += block;
        });
        let h_scale = (0..n)
            .flat_map(|r| (0..n).map(move |c| (r, c)))
            .fold(0.0f64, |m, (r, c)| m.max(h_with[(r, c)].abs()));
        let mut coupling = 0.0f64;
        for r in 0..n {
            for c in 0..n {
                let d = h_with[(r, c)] - h_without[(r, c)];
                assert!(
                    (d - expected[(r, c)]).abs() <= 1e-12 * h_scale,
                    "lift {lift}: Hessian ({r}, {c}): {d:e} vs {:e}",
                    expected[(r, c)]
                );
                if upper(r / 3) != upper(c / 3) {
                    coupling = coupling.max(d.abs());
                }
            }
        }
        assert!(
            coupling > 0.0,
            "lift {lift}: friction couples the two sheets"
        );
    }
}
