//! One backward Euler step by Newton and one by projective dynamics on a cloth read from a file
//! (`data/meshes/cloth_30x30.obj`, a 31×31 sheet of side 1 m), pinned at its two back corners and
//! falling under gravity.
//!
//! `cargo run --release --example newton_and_pd_from_file`; `cargo test` runs it too.

use std::path::Path;

use hooke::mesh::io::read_obj;
use hooke::mesh::{Bending, MassModel, SpringMesh};
use hooke::sim::{ExternalForce, Integrator, Pins, Scene, Settings, Simulation, State};
use hooke::solvers::StopReason;
use nalgebra::Vector3;

/// Stiffness of every spring (N/m), total mass (kg) and frame time step (s).
const STIFFNESS: f64 = 1e3;
const MASS: f64 = 1.0;
const TIME_STEP: f64 = 1.0 / 30.0;

/// The cloth scene: the OBJ's triangles become springs, the two corners at the largest z are held.
fn scene() -> Result<Scene<3>, Box<dyn std::error::Error>> {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/meshes/cloth_30x30.obj");
    let surface = read_obj(&file)?;
    let mesh = SpringMesh::from_triangles(
        &surface,
        STIFFNESS,
        Bending::None,
        MassModel::Uniform { total: MASS },
    )?;
    // The back corners: largest z, then smallest and largest x.
    let p = mesh.positions();
    let z_max = p.iter().map(|q| q.z).fold(f64::NEG_INFINITY, f64::max);
    let back: Vec<usize> = (0..p.len()).filter(|&i| p[i].z == z_max).collect();
    let by_x = |a: &&usize, b: &&usize| p[**a].x.total_cmp(&p[**b].x);
    let left = *back.iter().min_by(by_x).ok_or("no back edge")?;
    let right = *back.iter().max_by(by_x).ok_or("no back edge")?;
    Ok(Scene::new(mesh, TIME_STEP)?
        .with_pins(Pins::Vertices(vec![left as u32, right as u32]))?
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: Vector3::new(0.0, -9.81, 0.0),
        }])?)
}

/// One step with `integrator` from the scene's initial state; the state after it.
fn one_step(integrator: Integrator) -> Result<(State<3>, StopReason), Box<dyn std::error::Error>> {
    let scene = scene()?;
    let initial = scene.initial_state();
    let settings = Settings {
        integrator,
        ..Settings::default()
    };
    let mut sim = Simulation::new(scene, initial, settings)?;
    let report = sim.step()?;
    let solver = report.solver.ok_or("an implicit step reports its solver")?;
    println!(
        "{integrator}: {} iterations, stop {:?}, residual {:.2e}",
        solver.iterations, solver.stop, solver.residual
    );
    Ok((sim.state().clone(), solver.stop))
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let start = scene()?.initial_state();
    let (newton, newton_stop) = one_step(Integrator::Newton)?;
    let (pd, _) = one_step(Integrator::ProjectiveDynamics)?;
    // Both solve the same backward Euler step: Newton to its gradient tolerance, PD with its fixed
    // 10 local/global iterations. Compare PD's displacement with Newton's, relative to the size of
    // the step's displacement (a fall of g h² ≈ 1 cm, plus the springs' pull).
    let size: f64 = newton
        .positions
        .iter()
        .zip(&start.positions)
        .map(|(x, x0)| (x - x0).norm_squared())
        .sum::<f64>()
        .sqrt();
    let gap: f64 = newton
        .positions
        .iter()
        .zip(&pd.positions)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt();
    println!(
        "PD's step differs from Newton's by {:.2} % of the step",
        100.0 * gap / size
    );
    assert_eq!(newton_stop, StopReason::Converged);
    // Ten PD iterations on a soft cloth at 1/30 s get the step to within a few per cent of the
    // converged solution (measured: see the printout); a wrong PD step would be off by ~100 %.
    assert!(
        gap < 0.1 * size,
        "PD {gap:.3e} m from Newton over a {size:.3e} m step"
    );
    // The cloth falls: its mean height goes down by about g h² (all but two vertices free).
    let mean_y =
        |s: &State<3>| s.positions.iter().map(|p| p.y).sum::<f64>() / s.positions.len() as f64;
    let drop = mean_y(&start) - mean_y(&newton);
    assert!(
        drop > 0.5 * 9.81 * TIME_STEP * TIME_STEP,
        "mean drop {drop:.3e} m"
    );
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    run()
}

#[test]
fn newton_and_pd_steps_agree_on_a_cloth_read_from_a_file() {
    run().unwrap();
}
