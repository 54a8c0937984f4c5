//! Contact probe: cloth-12 swinging onto a sphere (centre (0.6, −0.35, 0.5) m, radius 0.15 m) and
//! the ground (y = −0.5 m), the scene of tests/integration/scenes.rs. Per frame: total energy minus the initial
//! one, kinetic, spring and gravitational energy (J), and how deep the unconstrained step (the same
//! state stepped without contacts) goes into the sphere and the ground (m), with the number of
//! vertices it leaves inside.
//!
//! `cargo run -p hooke-sim --example contact_probe -- [integrator (newton)] [frames (45)]`
use hooke_sim::{scenes, Contact, Integrator, Shape, Simulation};
use nalgebra::Vector3;

fn main() {
    let integrator: Integrator = std::env::args()
        .nth(1)
        .unwrap_or("newton".into())
        .parse()
        .unwrap();
    let frames: usize = std::env::args().nth(2).map_or(45, |s| s.parse().unwrap());
    let mut setup = scenes::cloth(12, false).unwrap();
    setup.settings.integrator = integrator;
    setup.settings.energy_limit = None;
    let center = Vector3::new(0.6, -0.35, 0.5);
    let radius = 0.15;
    let ground = -0.5;
    let free_scene = setup.scene.clone();
    let scene = setup
        .scene
        .with_contacts(vec![
            Contact::new(Shape::Plane {
                point: Vector3::new(0.0, ground, 0.0),
                normal: Vector3::y(),
            }),
            Contact::new(Shape::Sphere { center, radius }),
        ])
        .unwrap();
    let mut sim = Simulation::new(scene, setup.initial, setup.settings).unwrap();
    let e0 = sim.energy().total;
    println!("frame      E        K     elastic   gravity  | depth_sphere depth_ground n_in");
    for frame in 1..=frames {
        // The unconstrained step from the same state: how deep the solve goes before projection.
        let mut free =
            Simulation::new(free_scene.clone(), sim.state().clone(), sim.settings()).unwrap();
        free.step().unwrap();
        let (mut ds, mut dg, mut n_in) = (0.0f64, 0.0f64, 0);
        for p in &free.state().positions {
            let d = radius - (p - center).norm();
            let g = ground - p.y;
            if d > 0.0 || g > 0.0 {
                n_in += 1;
            }
            ds = ds.max(d);
            dg = dg.max(g);
        }
        sim.step().unwrap();
        let e = sim.energy();
        let elastic = hooke_assembly::spring_energy(
            sim.scene().mesh().springs(),
            &sim.state().positions,
            false,
        );
        println!(
            "{frame:5} {:8.4} {:8.4} {:8.4} {:9.4}  | {ds:8.4} {dg:8.4} {n_in:4}",
            e.total - e0,
            e.kinetic,
            elastic,
            e.potential - elastic
        );
    }
}
