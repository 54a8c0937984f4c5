//! Self-contact (docs/contact.md), through the simulation API: a sheet dropped onto another on
//! the ground never passes through it in any frame (judged by the exact triangle–triangle test of
//! `hooke::mesh::intersection`, independent of the solver's distances), while the same run without
//! self-contact does; integrators that cannot model self-contact refuse it.

use hooke::mesh::intersection::intersecting_triangle_pairs;
use hooke::mesh::{Bending, MassModel, SpringMesh, TriMesh};
use hooke::sim::{
    Contact, ExternalForce, Integrator, Scene, SelfContact, Settings, SimError, Simulation, State,
};
use nalgebra::Vector3;

/// Two n×n sheets of one mesh (1 m × 1 m, k = 1e3 N/m, 1 kg each, no bending springs): one
/// lying 1 cm above the ground, the other 0.2 m above it, shifted by a third of a spacing in x and
/// z and falling at 2 m/s; gravity; h = 1/30 s. Without self-contact the upper sheet falls through
/// the lower one onto the ground.
fn sheet_drop(n: usize, self_contact: bool) -> (Scene<3>, State<3>) {
    let sheet = hooke::mesh::generators::cloth(n, 1e3).unwrap();
    let spacing = 1.0 / (n - 1) as f64;
    let count = sheet.vertex_count() as u32;
    let mut positions: Vec<Vector3<f64>> = sheet.positions().to_vec();
    positions.extend(
        sheet
            .positions()
            .iter()
            .map(|p| p + Vector3::new(spacing / 3.0, 0.2, spacing / 3.0)),
    );
    let mut triangles = sheet.triangles().to_vec();
    triangles.extend(sheet.triangles().iter().map(|t| t.map(|v| v + count)));
    let surface = TriMesh::new(positions, triangles).unwrap();
    let mesh = SpringMesh::from_triangles(
        &surface,
        1e3,
        Bending::None,
        MassModel::Uniform { total: 2.0 },
    )
    .unwrap();
    let scene = Scene::new(mesh, 1.0 / 30.0)
        .unwrap()
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: Vector3::new(0.0, -9.81, 0.0),
        }])
        .unwrap()
        .with_contacts(vec![Contact {
            shape: hooke::sim::Shape::Plane {
                point: Vector3::zeros(),
                normal: Vector3::y(),
            },
            friction: 0.3,
        }])
        .unwrap()
        .with_self_contact(self_contact.then(SelfContact::default))
        .unwrap();
    let mut state = scene.initial_state();
    for (v, (p, velocity)) in state
        .positions
        .iter_mut()
        .zip(state.velocities.iter_mut())
        .enumerate()
    {
        p.y += 0.01;
        if v as u32 >= count {
            velocity.y = -2.0;
        }
    }
    (scene, state)
}

/// The frames (1-based) whose triangles intersect, over `frames` frames.
fn intersecting_frames(
    sim: &mut Simulation<3>,
    triangles: &[[u32; 3]],
    frames: usize,
) -> Vec<usize> {
    let mut bad = Vec::new();
    for frame in 1..=frames {
        sim.step().unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        let pairs = intersecting_triangle_pairs(&sim.state().positions, triangles).unwrap();
        if !pairs.is_empty() {
            bad.push(frame);
        }
    }
    bad
}

#[test]
fn a_sheet_dropped_on_a_sheet_never_passes_through_it_with_self_contact() {
    let n = 10;
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    let (scene, state) = sheet_drop(n, false);
    let triangles = scene.mesh().triangles().to_vec();
    let mut without = Simulation::new(scene, state, settings).unwrap();
    // The control: without self-contact the upper sheet passes through the lower one, so the
    // scene tests something.
    assert!(
        !intersecting_frames(&mut without, &triangles, 30).is_empty(),
        "the sheets should pass through each other without self-contact"
    );
    let (scene, state) = sheet_drop(n, true);
    let mut with = Simulation::new(scene, state, settings).unwrap();
    let bad = intersecting_frames(&mut with, &triangles, 30);
    assert!(bad.is_empty(), "frames with an intersection: {bad:?}");
}

#[test]
fn integrators_without_a_barrier_refuse_self_contact() {
    let (scene, state) = sheet_drop(4, true);
    for integrator in [
        Integrator::ProjectiveDynamics,
        Integrator::ChebyshevPd,
        Integrator::Linearized,
        Integrator::SymplecticEuler,
    ] {
        let settings = Settings {
            integrator,
            allow_unstable: true,
            ..Settings::default()
        };
        match Simulation::new(scene.clone(), state.clone(), settings) {
            Err(SimError::Unsupported { what, .. }) => {
                assert!(what.contains("self-contact"), "{integrator}: {what}");
                assert!(what.contains("newton"), "{integrator}: {what}");
            }
            other => panic!("{integrator}: {:?}", other.map(|_| ())),
        }
    }
}

#[test]
fn serial_and_parallel_runs_give_the_same_frames() {
    let frames = |parallel: bool| {
        let (scene, state) = sheet_drop(6, true);
        let settings = Settings {
            integrator: Integrator::Newton,
            parallel,
            ..Settings::default()
        };
        let mut sim = Simulation::new(scene, state, settings).unwrap();
        (0..12)
            .map(|_| {
                sim.step().unwrap();
                sim.state().positions.clone()
            })
            .collect::<Vec<_>>()
    };
    assert!(
        frames(true) == frames(false),
        "serial and parallel frames differ"
    );
}

#[test]
fn a_start_that_intersects_itself_is_refused() {
    let (scene, mut state) = sheet_drop(4, true);
    // Pull the upper sheet's first vertex through the lower sheet (still above the ground).
    let first_upper = state.positions.len() / 2;
    state.positions[first_upper].y = 0.005;
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    match Simulation::new(scene, state, settings) {
        Err(SimError::InvalidParameter { name, value, .. }) => {
            assert_eq!(name, "initial positions");
            assert!(value.contains("intersect"), "{value}");
        }
        other => panic!("{:?}", other.map(|_| ())),
    }
}

/// cloth-10 (spacing 0.11 m) dropped onto a sphere of radius 3 cm under the middle of a cell: with
/// vertex contact alone the sphere would pass between the vertices. No point of any triangle is
/// ever inside the sphere (exact closest points), and every frame converges.
#[test]
fn a_cloth_on_a_small_sphere_keeps_every_triangle_outside() {
    let spacing = 1.0 / 9.0;
    let center = Vector3::new(4.5 * spacing, -0.1, 4.5 * spacing);
    let radius = 0.03;
    let mesh = hooke::mesh::generators::cloth(10, 1e3).unwrap();
    let scene = Scene::new(mesh, 1.0 / 30.0)
        .unwrap()
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: Vector3::new(0.0, -9.81, 0.0),
        }])
        .unwrap()
        .with_contacts(vec![Contact {
            shape: hooke::sim::Shape::Sphere { center, radius },
            friction: 0.0,
        }])
        .unwrap();
    let triangles = scene.mesh().triangles().to_vec();
    let state = scene.initial_state();
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    let mut sim = Simulation::new(scene, state, settings).unwrap();
    let mut touched = false;
    for frame in 1..=20 {
        let report = sim.step().unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        assert_eq!(report.converged, Some(true), "frame {frame}");
        let positions = &sim.state().positions;
        let inside = hooke::mesh::intersection::triangles_inside_sphere(
            positions, &triangles, &center, radius,
        )
        .unwrap();
        assert!(
            inside.is_empty(),
            "frame {frame}: triangles {inside:?} inside the sphere"
        );
        // The cloth reaches the sphere (within the barrier's reach of its top).
        touched |= positions
            .iter()
            .any(|p| (p - center).norm() < radius + 0.05);
    }
    assert!(touched, "the cloth never came near the sphere");
}

/// The built-in contact scenes at a small size, every frame judged exactly: no two triangles of
/// the cloth intersect, no point of a triangle is inside the sphere (cloth-drape-10 over its 60
/// frames; cloth-twist-8 over its first 60, a turn and a half, where the cloth wrings itself).
#[test]
fn the_built_in_contact_scenes_never_intersect() {
    for (setup, frames) in [
        (hooke::sim::scenes::cloth_drape(10).unwrap(), 60),
        (hooke::sim::scenes::cloth_twist(8).unwrap(), 60),
    ] {
        let name = setup.name.clone();
        let triangles = setup.scene.mesh().triangles().to_vec();
        let spheres: Vec<(Vector3<f64>, f64)> = setup
            .scene
            .contacts()
            .iter()
            .filter_map(|c| match c.shape {
                hooke::sim::Shape::Sphere { center, radius } => Some((center, radius)),
                _ => None,
            })
            .collect();
        let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings).unwrap();
        let mut most_pairs = 0;
        for frame in 1..=frames {
            sim.step()
                .unwrap_or_else(|e| panic!("{name} frame {frame}: {e}"));
            let state = sim.self_contact_state().expect("self-contact is on");
            most_pairs = most_pairs.max(state.point_triangle_pairs + state.edge_edge_pairs);
            let positions = &sim.state().positions;
            let pairs = intersecting_triangle_pairs(positions, &triangles).unwrap();
            assert!(
                pairs.is_empty(),
                "{name} frame {frame}: {pairs:?} intersect"
            );
            for (center, radius) in &spheres {
                let inside = hooke::mesh::intersection::triangles_inside_sphere(
                    positions, &triangles, center, *radius,
                )
                .unwrap();
                assert!(
                    inside.is_empty(),
                    "{name} frame {frame}: {inside:?} in the sphere"
                );
            }
        }
    }
}
