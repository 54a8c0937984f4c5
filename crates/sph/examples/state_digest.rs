//! Prints a digest of the state after a few steps of small scenes for every method combination:
//! a bit-for-bit comparison of two builds.
use hooke_sph::{scenes, DensityMethod, Fluid, Integrator, KernelKind};

fn digest(values: impl Iterator<Item = f64>) -> u64 {
    let mut h = 0xcbf29ce484222325u64;
    for v in values {
        h ^= v.to_bits();
        h = h.wrapping_mul(0x100000001b3);
    }
    h
}

fn main() {
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
            fluid.refresh();
            let d = digest(
                fluid
                    .positions()
                    .iter()
                    .chain(fluid.velocities())
                    .chain(fluid.accelerations())
                    .flat_map(|v| v.iter().copied().collect::<Vec<_>>())
                    .chain(fluid.densities().iter().copied())
                    .chain(fluid.pressures().iter().copied())
                    .chain(std::iter::once(fluid.time())),
            );
            println!("2d {kernel:?} {integrator:?} {density:?} {d:016x}");
        }
        let mut scene = scenes::dam_break_3d(0.04).unwrap();
        scene.setup.params.kernel = kernel;
        let mut fluid = Fluid::new(scene.setup).unwrap();
        for _ in 0..20 {
            fluid.step().unwrap();
        }
        fluid.refresh();
        let d = digest(
            fluid
                .positions()
                .iter()
                .chain(fluid.velocities())
                .chain(fluid.accelerations())
                .flat_map(|v| v.iter().copied().collect::<Vec<_>>())
                .chain(fluid.densities().iter().copied()),
        );
        println!("3d {kernel:?} {} {d:016x}", fluid.fluid_count());
    }
}
