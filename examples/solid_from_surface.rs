//! A solid from a closed surface: the Stanford bunny (`data/meshes/bunny.obj`) filled with
//! tetrahedra by isosurface stuffing (`hooke::mesh::stuffing`, docs/mesher.md), springs on the
//! tetrahedra's edges, dropped onto the ground and stepped by projective dynamics. A coarse
//! spacing (a tenth of the bunny's size) keeps it to a few hundred vertices.
//!
//! `cargo run --release --example solid_from_surface`; `cargo test` runs it too.

// README: begin
use hooke::mesh::{io::read_obj, stuffing, MassModel, SpringMesh, TriMesh};
use hooke::nalgebra::Vector3;
use hooke::sim::{Contact, ExternalForce, Integrator, Scene, Settings, Shape, Simulation};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/data/meshes/bunny.obj");
    let bunny = read_obj(std::path::Path::new(file))?;
    // Turned y up, scaled to a 0.3 m diagonal, its lowest point 5 cm above the ground y = 0.
    let turned: Vec<_> = bunny
        .positions()
        .iter()
        .map(|p| Vector3::new(p.x, p.z, -p.y))
        .collect();
    let (lo, hi) = turned
        .iter()
        .fold((turned[0], turned[0]), |(l, h), p| (l.inf(p), h.sup(p)));
    let scale = 0.3 / (hi - lo).norm();
    let lift = Vector3::new(0.0, 0.05 - lo.y * scale, 0.0);
    let placed = turned.iter().map(|p| p * scale + lift).collect();
    let surface = TriMesh::new(placed, bunny.triangles().to_vec())?;
    let filled = stuffing::fill_surface(&surface, 0.03)?; // lattice spacing 3 cm
    let density = MassModel::Density {
        density: 1000.0,
        thickness: 1.0,
    }; // kg/m³
    let mesh = SpringMesh::from_tetrahedra(&filled.mesh, 1e4, density)?; // k = 1e4 N/m
    let ground = Contact::new(Shape::Plane {
        point: Vector3::zeros(),
        normal: Vector3::y(),
    });
    let gravity = ExternalForce::Gravity {
        acceleration: Vector3::new(0.0, -9.81, 0.0),
    };
    let scene = Scene::new(mesh, 1.0 / 60.0)?
        .with_forces(vec![gravity])?
        .with_contacts(vec![ground])?;
    let state = scene.initial_state();
    let settings = Settings {
        integrator: Integrator::ProjectiveDynamics,
        ..Settings::default()
    };
    let mut sim = Simulation::new(scene, state, settings)?;
    for _ in 0..30 {
        sim.step()?; // half a second: the fall and the landing
    }
    let positions = &sim.state().positions;
    let bottom = positions.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    println!(
        "{} vertices; after 0.5 s the lowest is at y = {bottom:.4} m",
        positions.len()
    );
    assert!(positions.iter().all(|p| p.iter().all(|c| c.is_finite())));
    assert!(
        (-1e-6..0.01).contains(&bottom),
        "the bunny rests on the ground"
    );
    Ok(())
}
// README: end

#[test]
fn the_stuffed_bunny_lands_on_the_ground() {
    main().unwrap();
}
