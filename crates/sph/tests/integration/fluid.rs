//! The fluid's conservation, determinism and error behaviour.

use hooke_sph::{
    scenes, DensityMethod, Fluid, FluidParams, FluidSetup, Integrator, KernelKind, SphError, Walls,
};
use nalgebra::SVector;

/// A small deterministic pseudo-random sequence in [0, 1) (no dependency needed for a test cloud).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A jittered lattice block of `side`ᴰ particles with random velocities and densities, no gravity,
/// no walls: every force is a pair force.
fn cloud<const D: usize>(side: usize, density: DensityMethod, kernel: KernelKind) -> FluidSetup<D> {
    let dx = 0.01;
    let mut rng = Lcg(7);
    let mut positions = Vec::new();
    let count = side.pow(D as u32);
    for k in 0..count {
        let mut rest = k;
        let p = SVector::<f64, D>::from_fn(|_, _| {
            let i = rest % side;
            rest /= side;
            (i as f64 + 0.5 + 0.3 * (rng.next() - 0.5)) * dx + 0.1
        });
        positions.push(p);
    }
    let velocities = (0..count)
        .map(|_| SVector::<f64, D>::from_fn(|_, _| rng.next() - 0.5))
        .collect();
    let densities = (0..count).map(|_| 990.0 + 20.0 * rng.next()).collect();
    FluidSetup {
        params: FluidParams {
            gravity: SVector::zeros(),
            smoothing_length: 1.3 * dx,
            sound_speed: 20.0,
            viscosity_alpha: 0.5,
            density,
            kernel,
            ..FluidParams::default()
        },
        domain_min: SVector::zeros(),
        domain_max: SVector::repeat(0.2 + side as f64 * dx),
        walls: Walls::Clamp,
        particle_mass: 1000.0 * dx.powi(D as i32),
        fluid_positions: positions,
        fluid_velocities: velocities,
        fluid_densities: densities,
        boundary_positions: Vec::new(),
        boundary_densities: Vec::new(),
    }
}

fn check_momentum<const D: usize>(setup: FluidSetup<D>) {
    let mut fluid = Fluid::new(setup).unwrap();
    let m = fluid.particle_mass();
    let e = fluid.evaluated();
    let total: SVector<f64, D> = e.accelerations().iter().map(|a| a * m).sum();
    let scale: f64 = e.accelerations().iter().map(|a| a.norm() * m).sum();
    // Pair forces cancel exactly in exact arithmetic; in floating point the sum of n terms of size
    // `scale`/n errs by about n·ε·scale at worst.
    let n = e.fluid().fluid_count() as f64;
    assert!(scale > 0.0);
    assert!(
        total.norm() <= 4.0 * n * f64::EPSILON * scale,
        "net force {} against a force scale {scale}",
        total.norm()
    );
}

#[test]
fn pressure_and_viscosity_forces_conserve_momentum() {
    for density in [DensityMethod::Summation, DensityMethod::Continuity] {
        for kernel in [KernelKind::CubicSpline, KernelKind::WendlandQuintic] {
            check_momentum(cloud::<2>(20, density, kernel));
            check_momentum(cloud::<3>(8, density, kernel));
        }
    }
}

#[test]
fn one_and_two_threads_agree_bit_for_bit() {
    for (integrator, density) in [
        (Integrator::SymplecticEuler, DensityMethod::Continuity),
        (Integrator::Leapfrog, DensityMethod::Continuity),
        (Integrator::SymplecticEuler, DensityMethod::Summation),
    ] {
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut scene = scenes::dam_break_2d(0.05).unwrap();
                scene.setup.params.integrator = integrator;
                scene.setup.params.density = density;
                let mut fluid = Fluid::new(scene.setup).unwrap();
                for _ in 0..60 {
                    fluid.step().unwrap();
                }
                let e = fluid.evaluated();
                (
                    e.positions().to_vec(),
                    e.velocities().to_vec(),
                    e.densities().to_vec(),
                    e.fluid().time(),
                )
            })
        };
        let (one, two) = (run(1), run(2));
        assert!(
            one.0 == two.0,
            "{integrator:?} {density:?}: positions differ"
        );
        assert!(
            one.1 == two.1,
            "{integrator:?} {density:?}: velocities differ"
        );
        assert!(
            one.2 == two.2,
            "{integrator:?} {density:?}: densities differ"
        );
        assert_eq!(one.3, two.3);
    }
}

#[test]
fn leapfrog_and_symplectic_euler_agree_on_the_early_collapse() {
    // Both integrators are consistent: over the first 0.05 s of the dam break their fronts differ by
    // far less than a particle spacing.
    let front = |integrator| {
        let mut scene = scenes::dam_break_2d(0.05).unwrap();
        scene.setup.params.integrator = integrator;
        let mut fluid = Fluid::new(scene.setup).unwrap();
        fluid.advance_to(0.05).unwrap();
        fluid.front(0, 3).unwrap()
    };
    let (a, b) = (
        front(Integrator::SymplecticEuler),
        front(Integrator::Leapfrog),
    );
    assert!((a - b).abs() < 0.1 * 0.05, "fronts {a} and {b}");
}

fn small_setup() -> FluidSetup<2> {
    scenes::dam_break_2d(0.1).unwrap().setup
}

#[test]
fn bad_input_is_a_typed_error() {
    let mut s = small_setup();
    s.fluid_positions.clear();
    s.fluid_densities.clear();
    assert_eq!(Fluid::new(s).unwrap_err(), SphError::EmptyFluid);

    let mut s = small_setup();
    s.fluid_positions[3].x = f64::NAN;
    assert!(matches!(
        Fluid::new(s).unwrap_err(),
        SphError::BadParticleValue { index: 3, .. }
    ));

    let mut s = small_setup();
    s.fluid_positions[5].y = 4.5;
    let e = Fluid::new(s).unwrap_err();
    assert!(matches!(e, SphError::OutsideDomain { index: 5, .. }), "{e}");

    let mut s = small_setup();
    s.fluid_densities[2] = 0.0;
    assert!(matches!(
        Fluid::new(s).unwrap_err(),
        SphError::BadParticleValue { index: 2, .. }
    ));

    let mut s = small_setup();
    s.fluid_velocities = vec![SVector::zeros(); 2];
    assert!(matches!(
        Fluid::new(s).unwrap_err(),
        SphError::LengthMismatch { found: 2, .. }
    ));

    for (field, value) in [
        ("smoothing_length", -1.0),
        ("smoothing_length", 0.0),
        ("rest_density", 0.0),
        ("sound_speed", f64::NAN),
        ("courant", 1.5),
        ("viscosity_alpha", -0.1),
    ] {
        let mut s = small_setup();
        match field {
            "smoothing_length" => s.params.smoothing_length = value,
            "rest_density" => s.params.rest_density = value,
            "sound_speed" => s.params.sound_speed = value,
            "courant" => s.params.courant = value,
            _ => s.params.viscosity_alpha = value,
        }
        match Fluid::new(s).unwrap_err() {
            SphError::InvalidParameter { name, .. } => assert_eq!(name, field),
            e => panic!("{field}: {e}"),
        }
    }

    let mut s = small_setup();
    s.particle_mass = -1.0;
    assert!(matches!(
        Fluid::new(s).unwrap_err(),
        SphError::InvalidParameter {
            name: "particle_mass",
            ..
        }
    ));

    let mut s = small_setup();
    s.params.fixed_step = Some(0.0);
    assert!(Fluid::new(s).is_err());
    assert!(scenes::dam_break_2d(0.0).is_err());
}

#[test]
fn a_step_above_the_bound_is_refused_with_the_bound() {
    let mut s = small_setup();
    s.params.fixed_step = Some(1e-2);
    let mut fluid = Fluid::new(s).unwrap();
    let e = fluid.step().unwrap_err();
    let SphError::StepAboveBound { step, bound, .. } = e else {
        panic!("{e}")
    };
    assert_eq!(step, 1e-2);
    // The acoustic bound C·h/c₀ = 0.4 · 0.13 / 62.6.
    assert!((bound - 0.4 * 0.13 / (10.0 * (2.0 * 9.81 * 2.0f64).sqrt())).abs() < 1e-9);
    assert!(e.to_string().contains(&format!("{bound:e}")));
    assert_eq!(fluid.steps(), 0);

    let mut s = small_setup();
    s.params.fixed_step = Some(1e-4);
    let mut fluid = Fluid::new(s).unwrap();
    let r = fluid.step().unwrap();
    assert_eq!(r.dt, 1e-4);
}

#[test]
fn leaving_the_domain_stops_the_step_and_moves_nothing() {
    let mut s = small_setup();
    let top = s.fluid_positions.len() - 1;
    s.fluid_positions[top].y = 3.95;
    s.fluid_velocities = vec![SVector::zeros(); s.fluid_positions.len()];
    s.fluid_velocities[top].y = 1e4;
    let before = s.fluid_positions.clone();
    let mut fluid = Fluid::new(s.clone()).unwrap();
    // The fast particle limits the step by CFL, but one step still carries it out of the open top.
    let e = fluid.step().unwrap_err();
    assert!(
        matches!(e, SphError::LeftDomain { index, step: 1, .. } if index == top),
        "{e}"
    );
    assert_eq!(fluid.positions(), &before[..]);

    // With the clamp onto the domain's faces the particle stays on the domain's face instead.
    s.walls = Walls::Clamp;
    let mut fluid = Fluid::new(s).unwrap();
    fluid.step().unwrap();
    let (lo, hi) = fluid.domain();
    assert!(fluid
        .positions()
        .iter()
        .all(|p| (0..2).all(|a| p[a] >= lo[a] && p[a] <= hi[a])));
    assert_eq!(fluid.positions()[top].y, hi.y);
    assert_eq!(fluid.velocities()[top].y, 0.0);
}

#[test]
fn advance_lands_on_the_end_time() {
    let mut fluid = Fluid::new(small_setup()).unwrap();
    let r = fluid.advance_to(0.0123).unwrap();
    assert_eq!(fluid.time(), 0.0123);
    assert!(r.steps >= 1 && r.min_dt <= r.max_dt);
    assert_eq!(fluid.advance_to(0.001).unwrap().steps, 0);
    assert!(fluid.advance_to(f64::NAN).is_err());
}

/// Everything a step may change, bit for bit: positions, velocities, densities, pressures and
/// accelerations (fluid and boundary), time and step count.
type Snapshot = (Vec<u64>, f64, u64);

fn snapshot(fluid: &mut Fluid<2>) -> Snapshot {
    let e = fluid.evaluated();
    let vectors = e
        .positions()
        .iter()
        .chain(e.velocities())
        .chain(e.accelerations())
        .flat_map(|v| [v.x.to_bits(), v.y.to_bits()]);
    let scalars = e
        .densities()
        .iter()
        .chain(e.boundary_densities())
        .chain(e.pressures())
        .chain(e.boundary_pressures())
        .map(|x| x.to_bits());
    let bits = vectors.chain(scalars).collect();
    (bits, e.fluid().time(), e.fluid().steps())
}

#[test]
fn a_failed_step_leaves_the_fluid_as_it_was() {
    // A lone fluid particle of enormous density (its Tait pressure overflows to +inf, harmless
    // while it has no neighbour) flies at the column, 0.29 m from its right edge: one step of
    // at most C·h = 0.052 m brings it within the support 2h = 0.26 m of a column particle, and
    // the forces at the new positions are then non-finite. Symplectic Euler finds this at the
    // start of the next step, before anything moves; leapfrog finds it in the same step's
    // second half-kick, after the drift, and must put the state back.
    let injected = |integrator| {
        let mut s = small_setup();
        s.params.integrator = integrator;
        s.fluid_velocities = vec![SVector::zeros(); s.fluid_positions.len()];
        s.fluid_positions
            .push(SVector::<f64, 2>::new(0.95 + 0.29, 0.55));
        s.fluid_velocities.push(SVector::<f64, 2>::new(-1e4, 0.0));
        s.fluid_densities.push(1e100);
        Fluid::new(s).unwrap()
    };

    let mut fluid = injected(Integrator::Leapfrog);
    let before = snapshot(&mut fluid);
    let e = fluid.step().unwrap_err();
    assert!(
        matches!(
            e,
            SphError::NonFiniteState {
                what: "velocity",
                step: 1,
                ..
            }
        ),
        "{e}"
    );
    assert!(
        snapshot(&mut fluid) == before,
        "leapfrog: the failed step moved the fluid"
    );
    // The same failure again, and the fluid still as it was: nothing was left half done.
    assert!(fluid.step().is_err());
    assert!(snapshot(&mut fluid) == before);

    let mut fluid = injected(Integrator::SymplecticEuler);
    fluid.step().unwrap();
    let before = snapshot(&mut fluid);
    let e = fluid.step().unwrap_err();
    // (The non-finite forces make the force condition's bound 0, so this may be reported as
    // the step collapsing.)
    assert!(
        matches!(
            e,
            SphError::NonFiniteState { step: 2, .. } | SphError::StepCollapsed { .. }
        ),
        "{e}"
    );
    assert!(
        snapshot(&mut fluid) == before,
        "symplectic Euler: the failed step moved the fluid"
    );

    // advance_to keeps the steps before the failing one and nothing of it.
    let mut fluid = injected(Integrator::Leapfrog);
    let before = snapshot(&mut fluid);
    assert!(fluid.advance_to(0.01).is_err());
    assert!(snapshot(&mut fluid) == before);
}

#[test]
fn the_evaluated_view_is_of_the_current_state() {
    // After a symplectic Euler step the last evaluation is of the previous positions; the view
    // evaluates the current ones, so its densities (summation) are those of a fluid built anew
    // from the moved particles.
    let mut s = small_setup();
    s.params.density = DensityMethod::Summation;
    let mut fluid = Fluid::new(s.clone()).unwrap();
    for _ in 0..5 {
        fluid.step().unwrap();
    }
    let mut fresh_setup = s;
    fresh_setup.fluid_positions = fluid.positions().to_vec();
    fresh_setup.fluid_velocities = fluid.velocities().to_vec();
    let mut fresh = Fluid::new(fresh_setup).unwrap();
    let (e, f) = (fluid.evaluated(), fresh.evaluated());
    assert!(e.densities() == f.densities());
    assert!(e.pressures() == f.pressures());
    assert!(e.accelerations() == f.accelerations());
}

#[test]
fn the_stable_step_includes_the_viscous_condition() {
    // At rest the CFL bound is the acoustic step C·h/c₀ and the force bound f·√(h/g) is far
    // larger. At α = 0.1 the viscous bound (D + 2) h / (4 α c₀) is 25 times the acoustic step
    // and does not bind; at α = 5 it is half of it and does.
    let mut fluid = Fluid::new(small_setup()).unwrap();
    let acoustic = fluid.acoustic_step();
    assert!((fluid.viscous_step() / acoustic - 25.0).abs() < 1e-12);
    assert_eq!(fluid.evaluated().stable_step(), acoustic);
    let mut s = small_setup();
    s.params.viscosity_alpha = 5.0;
    let mut fluid = Fluid::new(s).unwrap();
    let viscous = fluid.viscous_step();
    assert!((viscous / acoustic - 0.5).abs() < 1e-12);
    assert_eq!(fluid.evaluated().stable_step(), viscous);
    assert_eq!(fluid.step().unwrap().dt, viscous);
    s = small_setup();
    s.params.viscosity_alpha = 0.0;
    assert_eq!(Fluid::new(s).unwrap().viscous_step(), f64::INFINITY);
}
