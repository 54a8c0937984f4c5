//! The dam-break front against time at one spacing, as CSV on stdout: `t,T,Z,steps,max_density_error`.
//!
//! `cargo run --release -p hooke-sph --example dam_break_fronts -- 0.01 0.7 > front.csv`
//! (spacing Δx in m, end time in s; dam-break-2d's, docs/scenes.md §7, otherwise).
//! T = t·√(2g/L), Z = x_front/L.
use hooke_sph::{scenes, Fluid};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dx: f64 = args.next().as_deref().unwrap_or("0.02").parse()?;
    let end: f64 = args.next().as_deref().unwrap_or("0.7").parse()?;
    let scene = scenes::dam_break_2d(dx)?;
    let l = scene.column_width;
    let mut fluid = Fluid::new(scene.setup)?;
    let frames = (end / 0.01).round() as usize;
    let start = std::time::Instant::now();
    println!("t,T,Z,steps,max_density_error");
    for k in 0..=frames {
        fluid.advance_to(end * k as f64 / frames as f64)?;
        let t = fluid.time();
        let z = fluid.front(0, 3).unwrap_or(f64::NAN) / l;
        let err = fluid.evaluated().max_density_error();
        println!(
            "{t:.4},{:.4},{z:.4},{},{err:.5}",
            t * (2.0 * 9.81 / l).sqrt(),
            fluid.steps()
        );
    }
    eprintln!(
        "dx = {dx}: {} fluid + {} boundary particles, {} steps in {:.1} s; {:?}",
        fluid.fluid_count(),
        fluid.boundary_count(),
        fluid.steps(),
        start.elapsed().as_secs_f64(),
        fluid.timings()
    );
    Ok(())
}
