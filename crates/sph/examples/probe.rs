use hooke_sph::{scenes, DensityMethod, Fluid};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let which = args[1].as_str();
    let dx: f64 = args[2].parse().unwrap();
    let method: DensityMethod = args[3].parse().unwrap();
    let mut scene = if which == "hydro" {
        scenes::hydrostatic_2d(dx).unwrap()
    } else {
        scenes::dam_break_2d(dx).unwrap()
    };
    scene.setup.params.density = method;
    let mut f = Fluid::new(scene.setup).unwrap();
    let t0 = std::time::Instant::now();
    let frames = 20;
    let end = if which == "hydro" { 2.0 } else { 0.7 };
    for k in 1..=frames {
        let t = end * k as f64 / frames as f64;
        let r = f.advance_to(t).unwrap();
        f.refresh();
        let front = f.front(0, 3).unwrap();
        println!("t {t:.3} T {:.3} Z {:.3} steps {} dt [{:.2e},{:.2e}] rho_err {:.4} ke {:.3e} vmax {:.3}", t * (2.0f64*9.81).sqrt(), front, f.steps(), r.min_dt, r.max_dt, f.max_density_error(), f.kinetic_energy(), f.max_speed());
    }
    if which == "hydro" {
        let top = f.positions().iter().map(|p| p.y).fold(f64::MIN, f64::max) + dx / 2.0;
        for band in 0..10 {
            let (d0, d1) = (band as f64 * 0.2, band as f64 * 0.2 + 0.2);
            let sel: Vec<f64> = f
                .positions()
                .iter()
                .zip(f.pressures())
                .filter(|(p, _)| {
                    let d = top - p.y;
                    d >= d0 && d < d1
                })
                .map(|(_, &p)| p)
                .collect();
            let mean = sel.iter().sum::<f64>() / sel.len() as f64;
            let exact = 1000.0 * 9.81 * (d0 + d1) / 2.0;
            println!(
                "band {d0:.1}-{d1:.1}: p {mean:.1} exact {exact:.1} rel {:.4}",
                mean / exact - 1.0
            );
        }
        let errs: Vec<f64> = f
            .densities()
            .iter()
            .map(|r| (r / 1000.0 - 1.0).abs())
            .collect();
        let top_y = f.positions().iter().map(|p| p.y).fold(f64::MIN, f64::max);
        println!(
            "max rho err {:.4}; top y {top_y}",
            errs.iter().cloned().fold(0.0, f64::max)
        );
    }
    eprintln!(
        "{:?} {:.2}s, {:?}",
        method,
        t0.elapsed().as_secs_f64(),
        f.timings()
    );
}
