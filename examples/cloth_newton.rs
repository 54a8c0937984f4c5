//! A cloth by backward Euler solved by Newton's method: the README's "Choosing an integrator".
//! The same 20×20 cloth as `hanging_cloth`, at the frame step itself (no substeps), with a stiff
//! k = 1e5 N/m that symplectic Euler could only take in hundreds of substeps per frame.
//!
//! `cargo run --release --example cloth_newton`; `cargo test` runs it too.

// README: begin
use hooke::mesh::generators;
use hooke::nalgebra::Vector3;
use hooke::sim::{ExternalForce, Integrator, Pins, Scene, Settings, Simulation};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mesh = generators::cloth(20, 1e5)?; // stiff: k = 1e5 N/m
    let scene = Scene::new(mesh, 1.0 / 30.0)?
        .with_pins(Pins::Vertices(vec![0, 19]))?
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: Vector3::new(0.0, -9.81, 0.0),
        }])?;
    let state = scene.initial_state();
    let settings = Settings {
        integrator: Integrator::Newton, // backward Euler by Newton, one solve per frame
        ..Settings::default()
    };
    let mut sim = Simulation::new(scene, state, settings)?;
    let mut energy = sim.energy().total;
    for frame in 1..=30 {
        let report = sim.step()?;
        let solver = report.solver.ok_or("an implicit step reports its solve")?;
        let now = sim.energy().total;
        println!(
            "frame {frame}: {} Newton iterations, E = {now:.5} J",
            solver.iterations
        );
        // Backward Euler dissipates: the energy never rises. The margin, a millionth of the
        // energy (or of 1 J near 0), is for round-off and the solve's tolerance; a frame here
        // changes the energy by about 1 %.
        assert!(now <= energy + 1e-6 * energy.abs().max(1.0), "energy rose");
        energy = now;
    }
    Ok(())
}
// README: end

#[test]
fn a_newton_cloth_loses_energy_every_frame() {
    main().unwrap();
}
