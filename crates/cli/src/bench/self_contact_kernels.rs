//! `hooke bench --contact A.obj B.obj`: the self-contact work of one Newton iteration, stage by
//! stage, on a surface read from two OBJ files with the same triangles (A the current
//! configuration, B a line search's trial), so that it can be set side by side with another
//! implementation's on the same files.
//!
//! The stages, each the median of `repeats` timed runs after one warm-up:
//! - **build**: the broad phase from scratch at A (hash grid, boxes grown by 1.5 d̂) and the
//!   distance of every candidate pair, counting those within d̂;
//! - **value**: the barrier energy Σ κ b(d) over the pairs;
//! - **gradient**: its gradient, into one vector of 3n entries;
//! - **hessian**: every pair's Hessian projected to positive semidefinite (the Gauss–Newton
//!   projection of `hooke_assembly::surface_barrier`) and the 3n × 3n sparse matrix assembled from
//!   them, from scratch: its block pattern from the vertex pairs they couple, then their blocks
//!   added in place (faer's compressed columns);
//! - **hessian (exact)**: the same with the exact pair Hessians (what Newton's matrix holds);
//!   reported apart, not in the total;
//! - **step**: the broad phase over the boxes swept from A to B and additive CCD on every pair it
//!   finds: the largest collision-free share of the move.
//!
//! κ is 1 N/m (the stages' cost does not depend on it). Every vertex is free. The pair counts are
//! hooke's: each point–triangle and edge–edge pair within d̂ counts once, as in IPC's sum (a
//! point near an edge shared by two triangles counts with each).

use std::path::Path;
use std::time::Instant;

use hooke_assembly::self_contact::{SelfContactBarrier, SelfContactModel};
use hooke_assembly::{Definiteness, HessianPattern};
use hooke_collision::ccd::CcdParams;
use hooke_solvers::backward_euler::collision_free_step;
use nalgebra::Vector3;

use crate::bench::BenchError;

/// What `hooke bench --contact` measured: the surface, the pairs, and each stage's median time.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ContactTimings {
    /// The configuration file (A).
    pub current: String,
    /// The trial configuration file (B).
    pub trial: String,
    /// Vertices of the surface.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// The barrier's reach d̂ (m).
    pub dhat: f64,
    /// Candidate pairs of the broad phase at A (point–triangle and edge–edge).
    pub candidates: usize,
    /// Point–triangle pairs within d̂ at A.
    pub point_triangle_pairs: usize,
    /// Edge–edge pairs within d̂ at A.
    pub edge_edge_pairs: usize,
    /// The smallest distance between the primitives of a pair at A (m).
    pub smallest_distance: f64,
    /// The collision-free share of the move from A to B (≤ 1).
    pub step: f64,
    /// rayon's threads.
    pub threads: usize,
    /// Timed repeats per stage (the median is reported).
    pub repeats: usize,
    /// Broad phase and distance filter (ms).
    pub build_ms: f64,
    /// Barrier value (ms).
    pub value_ms: f64,
    /// Gradient (ms).
    pub gradient_ms: f64,
    /// PSD-projected Hessian assembled into a sparse matrix (ms).
    pub hessian_ms: f64,
    /// Exact Hessian assembled into a sparse matrix (ms); not in the total.
    pub hessian_exact_ms: f64,
    /// Swept broad phase and CCD to the trial (ms).
    pub step_ms: f64,
    /// build + value + gradient + hessian + step (ms).
    pub total_ms: f64,
}

/// The median wall time (ms) of `repeats` runs of `run` after one warm-up run.
fn median_ms(repeats: usize, mut run: impl FnMut()) -> f64 {
    run();
    let mut times: Vec<f64> = (0..repeats.max(1))
        .map(|_| {
            let start = Instant::now();
            run();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

fn read(path: &Path) -> Result<hooke_mesh::TriMesh, BenchError> {
    hooke_mesh::io::read_obj(path).map_err(|e| BenchError::Scene(e.to_string()))
}

/// The Hessian of `barrier` at `x` with `definiteness`, assembled into a 3n × 3n sparse matrix
/// from scratch: its block pattern from the vertex pairs the pairs within d̂ couple (as Newton's
/// matrix grows when pairs appear), then every pair's blocks added in place. Returns the number
/// of stored entries.
fn assemble_hessian(
    barrier: &mut SelfContactBarrier,
    x: &[Vector3<f64>],
    definiteness: Definiteness,
    links: &mut Vec<[u32; 2]>,
) -> usize {
    links.clear();
    barrier.links(x, links);
    let pattern = HessianPattern::<3>::with_links(x.len(), &[], links, None);
    let mut values = pattern.new_values();
    let complete = barrier.add_hessian_into(x, 1.0, definiteness, &pattern, Some, &mut values);
    debug_assert!(complete, "the pattern holds every pair's blocks");
    std::hint::black_box(pattern.matrix(&values)).compute_nnz()
}

/// Time the self-contact stages on the surface of `current` moving to `trial` with reach `dhat`
/// (m), `repeats` timed runs per stage.
///
/// # Errors
/// [`BenchError::Scene`] if a file cannot be read as OBJ, the two meshes differ in vertices or
/// triangles, `dhat` is not finite and positive, or two primitives touch at `current`.
pub fn contact_kernels(
    current: &Path,
    trial: &Path,
    dhat: f64,
    repeats: usize,
) -> Result<ContactTimings, BenchError> {
    if !(dhat.is_finite() && dhat > 0.0) {
        return Err(BenchError::Scene(format!(
            "--dhat {dhat}: the barrier's reach must be finite and positive (m)"
        )));
    }
    let (a, b) = (read(current)?, read(trial)?);
    if a.triangles() != b.triangles() || a.positions().len() != b.positions().len() {
        return Err(BenchError::Scene(format!(
            "{} and {} are not the same surface: the trial must have the same vertices and \
             triangles, only moved",
            current.display(),
            trial.display()
        )));
    }
    let x: Vec<Vector3<f64>> = a.positions().to_vec();
    let delta: Vec<Vector3<f64>> = b.positions().iter().zip(&x).map(|(q, p)| q - p).collect();
    let model = SelfContactModel {
        triangles: a.triangles().to_vec(),
        // The current configuration as the rest state: no pair of two sheets is excluded.
        rest_positions: x.clone(),
        distance: dhat,
        stiffness: 1.0,
        // The barrier's kernels alone: no friction.
        friction: 0.0,
        friction_velocity: 1e-3,
    };
    let mut barrier = SelfContactBarrier::new(model, vec![true; x.len()]);
    let candidates = barrier.pairs_near(&x).len();
    let (point_triangle_pairs, edge_edge_pairs) = barrier.active_counts(&x);
    let smallest_distance = barrier.smallest_distance(&x);
    if smallest_distance <= 0.0 {
        return Err(BenchError::Scene(format!(
            "{}: two primitives of the surface touch or cross",
            current.display()
        )));
    }
    let build_ms = median_ms(repeats, || {
        barrier.forget_pairs();
        std::hint::black_box(barrier.active_counts(&x));
    });
    let value_ms = median_ms(repeats, || {
        std::hint::black_box(barrier.energy(&x));
    });
    let mut gradient = vec![Vector3::zeros(); x.len()];
    let gradient_ms = median_ms(repeats, || {
        gradient.fill(Vector3::zeros());
        barrier.add_gradient(&x, 1.0, &mut gradient);
        std::hint::black_box(&gradient);
    });
    let mut links = Vec::new();
    let hessian_ms = median_ms(repeats, || {
        std::hint::black_box(assemble_hessian(
            &mut barrier,
            &x,
            Definiteness::Clamped,
            &mut links,
        ));
    });
    let hessian_exact_ms = median_ms(repeats, || {
        std::hint::black_box(assemble_hessian(
            &mut barrier,
            &x,
            Definiteness::Exact,
            &mut links,
        ));
    });
    let ccd = CcdParams::default();
    let mut step = 1.0;
    let step_ms = median_ms(repeats, || {
        barrier.forget_pairs();
        step = collision_free_step(&mut barrier, &x, &delta, &ccd);
    });
    Ok(ContactTimings {
        current: current.display().to_string(),
        trial: trial.display().to_string(),
        vertices: x.len(),
        triangles: a.triangles().len(),
        dhat,
        candidates,
        point_triangle_pairs,
        edge_edge_pairs,
        smallest_distance,
        step,
        threads: rayon::current_num_threads(),
        repeats,
        build_ms,
        value_ms,
        gradient_ms,
        hessian_ms,
        hessian_exact_ms,
        step_ms,
        total_ms: build_ms + value_ms + gradient_ms + hessian_ms + step_ms,
    })
}

/// The timings as the table `hooke bench --contact` prints.
pub fn format_contact(t: &ContactTimings) -> String {
    format!(
        "vertices {}, triangles {}, d̂ {} m, threads {}, median of {}\n\
         candidates {}, within d̂: {} point-triangle + {} edge-edge = {} pairs; \
         smallest distance {:.3e} m; collision-free step {:.4}\n\
         build              {:10.2} ms\n\
         value              {:10.2} ms\n\
         gradient           {:10.2} ms\n\
         hessian (PSD)      {:10.2} ms\n\
         step (CCD)         {:10.2} ms\n\
         total              {:10.2} ms per Newton iteration\n\
         hessian (exact)    {:10.2} ms (not in the total)\n",
        t.vertices,
        t.triangles,
        t.dhat,
        t.threads,
        t.repeats,
        t.candidates,
        t.point_triangle_pairs,
        t.edge_edge_pairs,
        t.point_triangle_pairs + t.edge_edge_pairs,
        t.smallest_distance,
        t.step,
        t.build_ms,
        t.value_ms,
        t.gradient_ms,
        t.hessian_ms,
        t.step_ms,
        t.total_ms,
        t.hessian_exact_ms,
    )
}
