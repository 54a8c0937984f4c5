use hooke_sph::{scenes, DensityMethod, Fluid, Integrator};
fn main() {
    let mut scene = scenes::hydrostatic_2d(0.04).unwrap();
    scene.setup.params.density = DensityMethod::Continuity;
    if std::env::args().nth(1).as_deref() == Some("lf") {
        scene.setup.params.integrator = Integrator::Leapfrog;
    }
    let mut f = Fluid::new(scene.setup).unwrap();
    for s in 0..300 {
        if let Err(e) = f.step() {
            println!("{e}");
            break;
        }
        if s % 10 == 0 {
            let (i, v) = f
                .velocities()
                .iter()
                .enumerate()
                .map(|(i, v)| (i, v.norm()))
                .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
            let bmin = f
                .boundary_densities()
                .iter()
                .cloned()
                .fold(f64::MAX, f64::min);
            let bmax = f.boundary_densities().iter().cloned().fold(0.0, f64::max);
            println!("step {s} t {:.4} vmax {v:.4} at {i} {:?} rho {:.2} p {:.1} ; boundary rho [{bmin:.2},{bmax:.2}] fluid err {:.4}", f.time(), f.positions()[i].as_slice(), f.densities()[i], f.pressures()[i], f.max_density_error());
        }
    }
}
