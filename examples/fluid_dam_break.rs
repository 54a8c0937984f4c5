//! A fluid: the 2D dam break of docs/scenes.md §7 (`hooke::sph`, weakly compressible SPH,
//! docs/sph.md) at a coarse spacing, 0.3 s of its collapse. The fluid takes its own stable steps
//! between the frames asked for; its mass is constant and its front advances.
//!
//! `cargo run --release --example fluid_dam_break`; `cargo test` runs it too.

// README: begin
use hooke::sph::{scenes, Fluid};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A 1 m × 2 m water column in a 4 m tank, particles 5 cm apart (800 of them).
    let scene = scenes::dam_break_2d(0.05)?;
    let mut fluid = Fluid::new(scene.setup)?;
    let mass = fluid.total_mass();
    let start = fluid.front(0, 3).ok_or("the column has a front")?;
    for frame in 1..=6 {
        let report = fluid.advance_to(0.05 * frame as f64)?; // frames 0.05 s apart
        println!(
            "t = {:.2} s: {} steps, front x = {:.3} m, largest speed {:.2} m/s",
            fluid.time(),
            report.steps,
            fluid.front(0, 3).unwrap_or(f64::NAN),
            fluid.max_speed()
        );
    }
    let front = fluid.front(0, 3).ok_or("the fluid has a front")?;
    assert!(front > start, "the column collapses: its front moves out");
    assert_eq!(fluid.total_mass(), mass, "particles keep their mass");
    Ok(())
}
// README: end

#[test]
fn the_dam_breaks() {
    main().unwrap();
}
