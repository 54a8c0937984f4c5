//! Prints a digest of the state after a few steps of small scenes for every method combination:
//! a bit-for-bit comparison of two builds.
use hooke_sph::{scenes, DensityMethod, Evaluated, Fluid, Integrator, KernelKind};

fn digest(values: impl Iterator<Item = f64>) -> u64 {
    let mut h = 0xcbf29ce484222325u64;
    for v in values {
        h ^= v.to_bits();
        h = h.wrapping_mul(0x100000001b3);
    }
    h
}

/// The digest of every position, velocity, acceleration and density of `e`, then of `more`.
fn motion_digest<const D: usize>(e: &Evaluated<D>, more: impl Iterator<Item = f64>) -> u64 {
    digest(
        e.positions()
            .iter()
            .chain(e.velocities())
            .chain(e.accelerations())
            .flat_map(|v| v.iter().copied().collect::<Vec<_>>())
            .chain(e.densities().iter().copied())
            .chain(more),
    )
}

fn main() {
    // The default method (symplectic Euler, continuity) over 2,000 steps, to t = 0.3 s, when the
    // front has run along the floor: every fluid and boundary density and the front.
    let mut fluid = Fluid::new(scenes::dam_break_2d(0.02).unwrap().setup).unwrap();
    for _ in 0..2000 {
        fluid.step().unwrap();
    }
    let front = fluid.front(0, 3).unwrap();
    let e = fluid.evaluated();
    let d = digest(
        e.positions()
            .iter()
            .chain(e.velocities())
            .flat_map(|v| v.iter().copied().collect::<Vec<_>>())
            .chain(e.densities().iter().copied())
            .chain(e.boundary_densities().iter().copied())
            .chain([e.fluid().time(), front]),
    );
    println!("2d long run, boundary densities included {d:016x}");
    for kernel in [KernelKind::CubicSpline, KernelKind::WendlandQuintic] {
        for (integrator, density) in [
            (Integrator::SymplecticEuler, DensityMethod::Continuity),
            (Integrator::Leapfrog, DensityMethod::Continuity),
            (Integrator::SymplecticEuler, DensityMethod::Summation),
            (Integrator::Leapfrog, DensityMethod::Summation),
        ] {
            let mut scene = scenes::dam_break_2d(0.02).unwrap();
            scene.setup.params.integrator = integrator;
            scene.setup.params.density = density;
            scene.setup.params.kernel = kernel;
            let mut fluid = Fluid::new(scene.setup).unwrap();
            for _ in 0..200 {
                fluid.step().unwrap();
            }
            let e = fluid.evaluated();
            let d = motion_digest(
                &e,
                e.pressures()
                    .iter()
                    .copied()
                    .chain(std::iter::once(e.fluid().time())),
            );
            println!("2d {kernel:?} {integrator:?} {density:?} {d:016x}");
        }
        let mut scene = scenes::dam_break_3d(0.04).unwrap();
        scene.setup.params.kernel = kernel;
        let mut fluid = Fluid::new(scene.setup).unwrap();
        for _ in 0..20 {
            fluid.step().unwrap();
        }
        let e = fluid.evaluated();
        let d = motion_digest(&e, std::iter::empty());
        println!("3d {kernel:?} {} {d:016x}", fluid.fluid_count());
    }
}
