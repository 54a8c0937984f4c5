//! The grid-ordered, pair-list evaluation against an O(n²) evaluation of the same formulas over
//! every pair, from the public state alone: densities (summation), pressures and accelerations
//! after a few steps of a small dam break, for both kernels, both density methods, 2D and 3D; and
//! the same flow with the particles numbered in another order, and with 1 and 2 threads.

use hooke_sph::{scenes, DensityMethod, Evaluated, Fluid, FluidSetup, KernelKind};
use nalgebra::SVector;

/// Densities (by summation, or the state's with continuity), pressures and accelerations of every
/// fluid particle by brute force.
fn brute<const D: usize>(e: Evaluated<D>) -> (Vec<f64>, Vec<f64>, Vec<SVector<f64, D>>) {
    let fluid = e.fluid();
    let p = fluid.params();
    let kernel = fluid.kernel();
    let m = fluid.particle_mass();
    let nf = fluid.fluid_count();
    let x: Vec<_> = fluid
        .positions()
        .iter()
        .chain(fluid.boundary_positions())
        .copied()
        .collect();
    let mut v = fluid.velocities().to_vec();
    v.resize(x.len(), SVector::zeros());
    let summation = p.density == DensityMethod::Summation;
    let support = kernel.support_radius();
    let rho: Vec<f64> = if summation {
        (0..x.len())
            .map(|i| {
                m * (0..x.len())
                    .map(|j| (x[i] - x[j]).norm())
                    .filter(|&r| r < support)
                    .map(|r| kernel.value(r))
                    .sum::<f64>()
            })
            .collect()
    } else {
        e.densities()
            .iter()
            .chain(e.boundary_densities())
            .copied()
            .collect()
    };
    let b = p.tait_stiffness();
    let pressure: Vec<f64> = rho
        .iter()
        .enumerate()
        .map(|(i, &r)| {
            let q = b * ((r / p.rest_density).powf(p.gamma) - 1.0);
            if summation || i >= nf {
                q.max(0.0)
            } else {
                q
            }
        })
        .collect();
    let h = p.smoothing_length;
    let acc = (0..nf)
        .map(|i| {
            let mut a = p.gravity;
            for j in 0..x.len() {
                let rij = x[i] - x[j];
                let r = rij.norm();
                if j == i || r >= support {
                    continue;
                }
                let mut c = pressure[i] / (rho[i] * rho[i]) + pressure[j] / (rho[j] * rho[j]);
                let approach = (v[i] - v[j]).dot(&rij);
                if approach < 0.0 {
                    let mu = h * approach / (r * r + 0.01 * h * h);
                    c -= p.viscosity_alpha * p.sound_speed * mu / (0.5 * (rho[i] + rho[j]));
                }
                a -= kernel.gradient(&rij) * (m * c);
            }
            a
        })
        .collect();
    (rho[..nf].to_vec(), pressure[..nf].to_vec(), acc)
}

fn check<const D: usize>(setup: FluidSetup<D>, steps: usize, what: &str) {
    let mut fluid = Fluid::new(setup).unwrap();
    for _ in 0..steps {
        fluid.step().unwrap();
    }
    let e = fluid.evaluated();
    let (rho, pressure, acc) = brute(e);
    let a_scale = acc.iter().map(|a| a.norm()).fold(0.0, f64::max);
    let p_scale = pressure.iter().map(|p| p.abs()).fold(0.0, f64::max);
    // (With summation on the coarse 3D lattice every pressure is clamped to 0.)
    assert!(a_scale > 0.0, "{what}: a trivial state");
    let p_scale = p_scale.max(1.0);
    for i in 0..e.fluid().fluid_count() {
        // Only the order of the sums and powi against powf differ: round-off.
        assert!(
            (e.densities()[i] - rho[i]).abs() <= 1e-12 * rho[i],
            "{what}: density {i}: {} against {}",
            e.densities()[i],
            rho[i]
        );
        assert!(
            (e.pressures()[i] - pressure[i]).abs() <= 1e-9 * p_scale,
            "{what}: pressure {i}: {} against {}",
            e.pressures()[i],
            pressure[i]
        );
        assert!(
            (e.accelerations()[i] - acc[i]).norm() <= 1e-9 * a_scale,
            "{what}: acceleration {i}: {:?} against {:?}",
            e.accelerations()[i],
            acc[i]
        );
    }
}

fn take<T: Copy>(perm: &[usize], v: &[T]) -> Vec<T> {
    perm.iter().map(|&i| v[i]).collect()
}

/// Numbers the fluid particles in a scrambled order (a fixed permutation).
fn scrambled<const D: usize>(mut setup: FluidSetup<D>) -> (FluidSetup<D>, Vec<usize>) {
    let n = setup.fluid_positions.len();
    // i ↦ 7919·i mod n is a permutation when n is not a multiple of 7919.
    let perm: Vec<usize> = (0..n).map(|i| (i * 7919) % n).collect();
    assert!(n % 7919 != 0);
    setup.fluid_positions = take(&perm, &setup.fluid_positions);
    if !setup.fluid_velocities.is_empty() {
        setup.fluid_velocities = take(&perm, &setup.fluid_velocities);
    }
    if !setup.fluid_densities.is_empty() {
        setup.fluid_densities = take(&perm, &setup.fluid_densities);
    }
    (setup, perm)
}

#[test]
fn evaluation_matches_brute_force() {
    for kernel in [KernelKind::CubicSpline, KernelKind::WendlandQuintic] {
        for density in [DensityMethod::Continuity, DensityMethod::Summation] {
            let mut s2 = scenes::dam_break_2d(0.05).unwrap().setup;
            s2.params.kernel = kernel;
            s2.params.density = density;
            check(s2.clone(), 40, &format!("2D {kernel:?} {density:?}"));
            let (shuffled, _) = scrambled(s2);
            check(
                shuffled,
                40,
                &format!("2D scrambled {kernel:?} {density:?}"),
            );
            let mut s3 = scenes::dam_break_3d(0.1).unwrap().setup;
            s3.params.kernel = kernel;
            s3.params.density = density;
            check(s3, 10, &format!("3D {kernel:?} {density:?}"));
        }
    }
}

#[test]
fn accessors_follow_the_setup_numbering() {
    // The same flow numbered in another order: particle perm[i] of the first run is particle i of
    // the second, to round-off (only the order of each particle's sums within a cell differs).
    let setup = scenes::dam_break_2d(0.05).unwrap().setup;
    let (other, perm) = scrambled(setup.clone());
    let mut a = Fluid::new(setup).unwrap();
    let mut b = Fluid::new(other).unwrap();
    for _ in 0..30 {
        a.step().unwrap();
        b.step().unwrap();
    }
    for (i, &j) in perm.iter().enumerate() {
        assert!(
            (a.positions()[j] - b.positions()[i]).norm() < 1e-9,
            "particle {j} / {i}"
        );
        assert!((a.velocities()[j] - b.velocities()[i]).norm() < 1e-7);
        assert!((a.evaluated().densities()[j] - b.evaluated().densities()[i]).abs() < 1e-7);
    }
    assert_eq!(a.boundary_positions(), b.boundary_positions());
}

#[test]
fn scrambled_and_3d_runs_agree_bit_for_bit_on_1_and_2_threads() {
    fn run<const D: usize>(setup: &FluidSetup<D>, steps: usize, threads: usize) -> Vec<u64> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut fluid = Fluid::new(setup.clone()).unwrap();
            for _ in 0..steps {
                fluid.step().unwrap();
            }
            let e = fluid.evaluated();
            let vectors = e
                .positions()
                .iter()
                .chain(e.velocities())
                .chain(e.accelerations());
            vectors
                .flat_map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
                .chain(e.densities().iter().map(|x| x.to_bits()))
                .chain(e.pressures().iter().map(|x| x.to_bits()))
                .collect()
        })
    }
    for density in [DensityMethod::Continuity, DensityMethod::Summation] {
        let mut s2 = scenes::dam_break_2d(0.05).unwrap().setup;
        s2.params.density = density;
        let (s2, _) = scrambled(s2);
        assert!(
            run(&s2, 60, 1) == run(&s2, 60, 2),
            "2D scrambled {density:?}"
        );
        let mut s3 = scenes::dam_break_3d(0.1).unwrap().setup;
        s3.params.density = density;
        assert!(run(&s3, 15, 1) == run(&s3, 15, 2), "3D {density:?}");
    }
}
