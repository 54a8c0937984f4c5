//! Writing a run's frames as legacy VTK files with point and cell data, for ParaView: per point the
//! velocity (m/s) and a pinned flag, per spring (drawn as a line) its strain |r|/l − 1.
//!
//! A 2D chain of 12 particles hangs from its first one and swings for 10 frames; the frames go to
//! `out/vtk_example/frame_NNNN.vtk` (`cargo run --example write_vtk_frames`), or to a temporary
//! directory when `cargo test` runs it, which reads a frame back with vtkio to check its arrays.

use std::path::{Path, PathBuf};

use hooke::mesh::io::{save_vtk_with_data, Frame, FrameData};
use hooke::mesh::SpringMesh;
use hooke::sim::{ExternalForce, Integrator, Pins, Scene, Settings, Simulation};
use nalgebra::Vector2;

/// Particles in the chain and frames to write.
const PARTICLES: usize = 12;
const FRAMES: usize = 10;

/// Runs the chain and writes frames 0..=FRAMES into `dir`; returns their paths.
fn write_frames(dir: &Path) -> Result<Vec<PathBuf>, Box<dyn std::error::Error>> {
    // A horizontal chain with 0.1 m links, 0.05 kg per particle, k = 200 N/m.
    let positions: Vec<Vector2<f64>> = (0..PARTICLES)
        .map(|i| Vector2::new(0.1 * i as f64, 0.0))
        .collect();
    let links: Vec<[u32; 2]> = (0..PARTICLES as u32 - 1).map(|i| [i, i + 1]).collect();
    let mesh = SpringMesh::from_pairs(positions, vec![0.05; PARTICLES], &links, 200.0)?;
    let scene = Scene::new(mesh, 1.0 / 60.0)?
        .with_pins(Pins::Vertices(vec![0]))?
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: Vector2::new(0.0, -9.81),
        }])?;
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    let initial = scene.initial_state();
    let mut sim = Simulation::new(scene, initial, settings)?;

    let lines: Vec<[u32; 2]> = sim
        .scene()
        .mesh()
        .springs()
        .iter()
        .map(|s| [s.i, s.j])
        .collect();
    let pinned = sim.scene().is_pinned().to_vec();
    std::fs::create_dir_all(dir)?;
    let mut paths = Vec::new();
    for frame in 0..=FRAMES {
        if frame > 0 {
            sim.step()?;
        }
        let state = sim.state();
        let strain: Vec<f64> = sim
            .scene()
            .mesh()
            .springs()
            .iter()
            .map(|s| {
                (state.positions[s.i as usize] - state.positions[s.j as usize]).norm()
                    / s.rest_length
                    - 1.0
            })
            .collect();
        let path = dir.join(format!("frame_{frame:04}.vtk"));
        save_vtk_with_data(
            &path,
            &Frame {
                lines: &lines,
                ..Frame::points(&state.positions)
            },
            &FrameData {
                velocities: Some(&state.velocities),
                pinned: Some(&pinned),
                line_strain: Some(&strain),
            },
        )?;
        paths.push(path);
    }
    Ok(paths)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let paths = write_frames(Path::new("out/vtk_example"))?;
    println!(
        "wrote {} frames, the last {}",
        paths.len(),
        paths[paths.len() - 1].display()
    );
    Ok(())
}

#[test]
fn frames_carry_velocity_pinned_and_strain() {
    use vtkio::model::{Attribute, DataSet, IOBuffer, Piece};

    let dir = tempfile::tempdir().unwrap();
    let paths = write_frames(dir.path()).unwrap();
    assert_eq!(paths.len(), FRAMES + 1);
    let bytes = std::fs::read(paths.last().unwrap()).unwrap();
    let vtk = vtkio::Vtk::parse_legacy_be(&bytes[..]).unwrap();
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("an unstructured grid");
    };
    let Some(Piece::Inline(piece)) = pieces.into_iter().next() else {
        panic!("an inline piece");
    };
    let array = |attributes: &[Attribute], name: &str| -> IOBuffer {
        attributes
            .iter()
            .find_map(|a| match a {
                Attribute::DataArray(d) if d.name == name => Some(d.data.clone()),
                _ => None,
            })
            .unwrap_or_else(|| panic!("no array {name}"))
    };
    let velocity: Vec<f64> = array(&piece.data.point, "velocity").into_vec().unwrap();
    let pinned: Vec<i32> = array(&piece.data.point, "pinned").into_vec().unwrap();
    let strain: Vec<f64> = array(&piece.data.cell, "strain").into_vec().unwrap();
    assert_eq!(velocity.len(), 3 * PARTICLES);
    assert_eq!(pinned[0], 1);
    assert!(pinned[1..].iter().all(|&p| p == 0));
    assert_eq!(strain.len(), PARTICLES - 1);
    // The chain has fallen and stretched: the particles move, the links are longer than at rest
    // (gravity pulls on each link with up to 11 particles' weight: ≈ 0.027 of a link's length).
    assert!(velocity.iter().any(|v| v.abs() > 0.1));
    assert!(strain.iter().all(|&s| s > 0.0), "{strain:?}");
    // The 2D frame is written with z = 0, velocities too.
    assert!(velocity.chunks(3).all(|v| v[2] == 0.0));
}
