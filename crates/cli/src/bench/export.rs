//! `hooke bench SCENE --export-system DIR`: the linear systems of the measured step (docs/model.md
//! §9, the speed-vs-error state of docs/scenes.md §8) as MatrixMarket files, so that other
//! implementations (and the multigrid preconditioner's measurements, docs/solvers.md §2.4) can be
//! run on exactly the matrices hooke solves.
//!
//! Everything is taken at x = y, the inertial target and every solver's initial guess, over the
//! free DOFs (pinned vertices removed; free vertex f has the unknowns 3f, 3f + 1, 3f + 2):
//!
//! | file | what | size | units |
//! |---|---|---|---|
//! | `hessian_clamped.mtx` | ∇²Φ(y) with the clamped spring blocks (SPD) | 3n × 3n | kg |
//! | `hessian_exact.mtx` | ∇²Φ(y) with the exact spring blocks (may be indefinite) | 3n × 3n | kg |
//! | `gradient.mtx` | ∇Φ(y) = −h² f(y) | 3n × 1 | kg·m |
//! | `pd_matrix.mtx` | M + h² L, projective dynamics' global matrix (one coordinate) | n × n | kg |
//! | `free_vertices.mtx` | the mesh vertex (0-based) of each free vertex | n × 1 | – |
//! | `positions.mtx` | y at each free vertex (for rigid-body modes) | n × 3 | m |
//! | `README.json` | this table, the scene, h, and the sizes | | |
//!
//! Sparse matrices are written in coordinate format with both triangles (`general`), dense ones in
//! array format (column-major), every number in Rust's shortest round-trip form, so reading a file
//! back gives the same bits. Every file is written atomically.

use std::io::Write;
use std::path::{Path, PathBuf};

use hooke_assembly::LaplacianPattern;
use hooke_solvers::faer::sparse::{SparseColMat, SparseColMatRef};
use hooke_solvers::{BackwardEulerStep, NewtonProblem};

use crate::bench::{BenchError, BenchProblem};

/// The systems of one step at x = y, in memory (what [`export_system`] writes).
#[derive(Clone, Debug)]
pub struct StepSystems {
    /// The scene's name.
    pub scene: String,
    /// The time step h, s.
    pub time_step: f64,
    /// Vertices of the whole mesh.
    pub vertex_count: usize,
    /// The mesh vertex of each free vertex, in unknown order.
    pub free_vertices: Vec<u32>,
    /// y at each free vertex, m, 3 per vertex (x, y, z).
    pub positions: Vec<f64>,
    /// ∇²Φ(y) with the clamped spring blocks, kg (3n × 3n, symmetric positive definite).
    pub hessian_clamped: SparseColMat<usize, f64>,
    /// ∇²Φ(y) with the exact spring blocks, kg (3n × 3n, symmetric).
    pub hessian_exact: SparseColMat<usize, f64>,
    /// ∇Φ(y), kg·m (3n).
    pub gradient: Vec<f64>,
    /// M + h² L over the free vertices, kg (n × n, symmetric positive definite).
    pub pd_matrix: SparseColMat<usize, f64>,
}

/// The file names [`export_system`] writes, in the order of the table in the module docs.
pub const EXPORT_FILES: [&str; 7] = [
    "hessian_clamped.mtx",
    "hessian_exact.mtx",
    "gradient.mtx",
    "pd_matrix.mtx",
    "free_vertices.mtx",
    "positions.mtx",
    "README.json",
];

impl StepSystems {
    /// Assemble the systems of `problem`'s step at x = y.
    pub fn assemble(problem: &BenchProblem) -> Self {
        let mesh = problem.scene.mesh();
        let h = problem.scene.time_step();
        let free = problem.free();
        let free_vertices = free.free_vertices().to_vec();
        let mut objective = BackwardEulerStep::new(mesh.springs(), mesh.masses(), free.clone(), h);
        let mut y = vec![0.0; objective.dim()];
        objective.set_step(&problem.y, &problem.start.positions, &mut y);
        let mut gradient = vec![0.0; y.len()];
        objective.gradient(&y, &mut gradient);
        let owned = |m: SparseColMatRef<'_, usize, f64>| {
            SparseColMat::new(
                m.symbolic().to_owned().expect("allocation"),
                m.val().to_vec(),
            )
        };
        let hessian_exact = owned(objective.hessian(&y));
        let hessian_clamped = owned(
            objective
                .convexified_hessian(&y)
                .expect("backward Euler has a clamped Hessian"),
        );
        let laplacian = LaplacianPattern::new(mesh.vertex_count(), mesh.springs(), Some(&free));
        let mut values = laplacian.new_values();
        laplacian.system_into(mesh.springs(), mesh.masses(), h, &mut values);
        let pd_matrix = laplacian.to_sparse_col_mat(&values);
        StepSystems {
            scene: problem.name.clone(),
            time_step: h,
            vertex_count: mesh.vertex_count(),
            positions: y,
            free_vertices,
            hessian_clamped,
            hessian_exact,
            gradient,
            pd_matrix,
        }
    }
}

fn output_error(path: &Path, e: impl std::fmt::Display) -> BenchError {
    BenchError::Output {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

fn write_file(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), BenchError> {
    hooke_mesh::io::write_atomically(path, write).map_err(|e| match e {
        hooke_mesh::MeshError::Io { source, .. } => output_error(path, source),
        e => output_error(path, e),
    })
}

fn write_sparse(path: &Path, m: &SparseColMat<usize, f64>) -> Result<(), BenchError> {
    let m = hooke_assembly::interop::to_sprs(m.as_ref());
    write_file(path, |out| {
        sprs::io::write_matrix_market_to_bufwrite(out, &m)
    })
}

/// A dense column-major `rows × cols` array in MatrixMarket array format.
fn write_dense<T: std::fmt::Debug>(
    path: &Path,
    field: &str,
    rows: usize,
    cols: usize,
    column_major: impl Iterator<Item = T>,
) -> Result<(), BenchError> {
    write_file(path, |out| {
        writeln!(out, "%%MatrixMarket matrix array {field} general")?;
        writeln!(out, "{rows} {cols}")?;
        for v in column_major {
            writeln!(out, "{v:?}")?;
        }
        Ok(())
    })
}

/// Write `problem`'s systems at x = y into `dir` (created if missing), as listed in the module docs,
/// and return them.
///
/// # Errors
/// [`BenchError::Output`] naming the file that cannot be written.
pub fn export_system(problem: &BenchProblem, dir: &Path) -> Result<StepSystems, BenchError> {
    std::fs::create_dir_all(dir).map_err(|e| output_error(dir, e))?;
    let systems = StepSystems::assemble(problem);
    let file = |name: &str| -> PathBuf { dir.join(name) };
    write_sparse(&file(EXPORT_FILES[0]), &systems.hessian_clamped)?;
    write_sparse(&file(EXPORT_FILES[1]), &systems.hessian_exact)?;
    let n = systems.free_vertices.len();
    write_dense(
        &file(EXPORT_FILES[2]),
        "real",
        3 * n,
        1,
        systems.gradient.iter(),
    )?;
    write_sparse(&file(EXPORT_FILES[3]), &systems.pd_matrix)?;
    write_dense(
        &file(EXPORT_FILES[4]),
        "integer",
        n,
        1,
        systems.free_vertices.iter(),
    )?;
    write_dense(
        &file(EXPORT_FILES[5]),
        "real",
        n,
        3,
        (0..3).flat_map(|a| systems.positions.iter().skip(a).step_by(3)),
    )?;
    let readme = serde_json::json!({
        "scene": systems.scene,
        "time_step_s": systems.time_step,
        "vertices": systems.vertex_count,
        "free_vertices": n,
        "unknowns": 3 * n,
        "state": "the speed-vs-error state (10 exact backward Euler steps from rest, docs/scenes.md §8); every system is taken at x = y, the inertial target of the next step",
        "numbering": "free vertex f (row f of free_vertices.mtx) has the unknowns 3f, 3f+1, 3f+2 (x, y, z); MatrixMarket indices are 1-based",
        "files": {
            "hessian_clamped.mtx": "Newton's Hessian of Phi(x) = 1/2 (x-y)^T M (x-y) + h^2 E(x) at x = y with every spring's transverse factor clamped at 0: M + h^2 sum k [rr^T + max(0, 1 - l/|r|)(I - rr^T)]; symmetric positive definite; kg",
            "hessian_exact.mtx": "the same with the exact spring blocks (may be indefinite where springs are compressed); kg",
            "gradient.mtx": "grad Phi(y) = -h^2 f(y), the right-hand side of Newton's first step is its negative; kg m",
            "pd_matrix.mtx": "projective dynamics' global matrix M + h^2 L (L the spring-stiffness-weighted graph Laplacian) over the free vertices, one coordinate (the 3D matrix is it Kronecker I3); kg",
            "free_vertices.mtx": "the mesh vertex (0-based) of each free vertex",
            "positions.mtx": "y at each free vertex (columns x, y, z), for the rigid-body modes of a multigrid near-nullspace; m",
        },
        "format": "sparse: coordinate real general (both triangles); dense: array, column-major; numbers in shortest round-trip form",
    });
    let text = serde_json::to_string_pretty(&readme).map_err(|e| output_error(dir, e))?;
    write_file(&file(EXPORT_FILES[6]), |out| writeln!(out, "{text}"))?;
    Ok(systems)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::{load_setup, PrepareOptions, StartState};

    /// Read a dense MatrixMarket array file back (the format [`write_dense`] writes).
    fn read_dense(path: &Path) -> (usize, usize, Vec<f64>) {
        let text = std::fs::read_to_string(path).unwrap();
        let mut lines = text.lines().filter(|l| !l.starts_with('%'));
        let size: Vec<usize> = lines
            .next()
            .unwrap()
            .split_whitespace()
            .map(|s| s.parse().unwrap())
            .collect();
        let values: Vec<f64> = lines.map(|l| l.trim().parse().unwrap()).collect();
        assert_eq!(values.len(), size[0] * size[1]);
        (size[0], size[1], values)
    }

    /// The files read back by sprs hold the in-memory matrices bit for bit (same entries, same
    /// values), on cloth-10's speed-vs-error step.
    #[test]
    fn exported_files_read_back_equal_the_matrices() {
        let setup = load_setup("cloth-10").unwrap();
        let problem = BenchProblem::prepare(
            &setup,
            &PrepareOptions {
                start: StartState::SpeedVsError,
                reference: false,
                cache_dir: None,
            },
            &mut |_| {},
        )
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let systems = export_system(&problem, dir.path()).unwrap();
        for name in EXPORT_FILES {
            assert!(dir.path().join(name).is_file(), "{name} written");
        }
        let n = systems.free_vertices.len();
        assert!(n > 0 && n < systems.vertex_count, "cloth-10 has pins");
        for (name, m) in [
            ("hessian_clamped.mtx", &systems.hessian_clamped),
            ("hessian_exact.mtx", &systems.hessian_exact),
            ("pd_matrix.mtx", &systems.pd_matrix),
        ] {
            let read: sprs::TriMat<f64> =
                sprs::io::read_matrix_market(dir.path().join(name)).unwrap();
            let read: sprs::CsMat<f64> = read.to_csc();
            let expected = hooke_assembly::interop::to_sprs(m.as_ref());
            assert_eq!(read.shape(), expected.shape(), "{name}");
            assert_eq!(read.indptr(), expected.indptr(), "{name}");
            assert_eq!(read.indices(), expected.indices(), "{name}");
            assert_eq!(read.data(), expected.data(), "{name}: values bit for bit");
        }
        assert_eq!(systems.hessian_clamped.nrows(), 3 * n);
        assert_eq!(systems.pd_matrix.nrows(), n);
        let (rows, cols, g) = read_dense(&dir.path().join("gradient.mtx"));
        assert_eq!((rows, cols), (3 * n, 1));
        assert_eq!(g, systems.gradient);
        assert!(g.iter().any(|&v| v != 0.0), "the step is not at rest");
        let (rows, cols, p) = read_dense(&dir.path().join("positions.mtx"));
        assert_eq!((rows, cols), (n, 3));
        for f in 0..n {
            for a in 0..3 {
                assert_eq!(p[a * n + f], systems.positions[3 * f + a]);
                assert_eq!(
                    p[a * n + f],
                    problem.y[systems.free_vertices[f] as usize][a]
                );
            }
        }
        let (rows, cols, v) = read_dense(&dir.path().join("free_vertices.mtx"));
        assert_eq!((rows, cols), (n, 1));
        let expected: Vec<f64> = systems.free_vertices.iter().map(|&v| v as f64).collect();
        assert_eq!(v, expected);
        let readme: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("README.json")).unwrap())
                .unwrap();
        assert_eq!(readme["unknowns"], 3 * n);
        assert_eq!(readme["scene"], "cloth-10");
    }
}
