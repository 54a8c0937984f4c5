//! The README's library example: a 20×20 cloth pinned at two corners swings down for one second.
//!
//! `cargo run --release --example hanging_cloth`; `cargo test` runs it too.

// README: begin
use hooke::mesh::generators;
use hooke::sim::{ExternalForce, Pins, Scene, Settings, Simulation};
use nalgebra::Vector3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mesh = generators::cloth(20, 1e3)?; // 20×20 cloth on the unit square, k = 1e3 N/m, 1 kg
    let scene = Scene::new(mesh, 1.0 / 30.0)? // one frame = 1/30 s
        .with_pins(Pins::Vertices(vec![0, 19]))?
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: Vector3::new(0.0, -9.81, 0.0),
        }])?;
    let state = scene.initial_state();
    let mut sim = Simulation::new(scene, state, Settings::default())?; // symplectic Euler, auto substeps
    for frame in 1..=30 {
        let report = sim.step()?;
        let energy = sim.energy();
        println!(
            "frame {frame}: {} substeps, E = {:.4} J",
            report.substeps, energy.total
        );
    }
    let lowest = sim
        .state()
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    println!("after 1 s the cloth hangs down to y = {lowest:.3} m");
    Ok(())
}
// README: end

#[test]
fn the_cloth_hangs_for_a_second() {
    main().unwrap();
}
