//! `DIR/summary.json`: what a run was and how each step went.
//!
//! Units are SI throughout: energies in joules (J), times in seconds (s); `max_stretch` is
//! dimensionless. Wall times are not here but in `timings.json`: the summary holds only results,
//! the same, byte for byte, for every run of the same scene and settings. JSON has no NaN or infinity: `serde_json` writes a non-finite number as `null`,
//! and [`read_summary`] reads a `null` energy, stretch or time back as NaN (a `null`
//! `solver_residual` reads back as `None`, whatever it was).

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use serde::{Deserialize, Deserializer, Serialize};

use super::{write_json_atomically, OutputError};

/// The whole run: its setup and one record per recorded step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSummary {
    /// Scene name, e.g. `cloth-40` or `seed-2d`.
    pub scene: String,
    /// Integrator name, e.g. `newton` or `symplectic-euler`.
    pub integrator: String,
    /// Spatial dimension: 2 or 3.
    pub dimension: usize,
    /// Number of vertices (point masses).
    pub vertices: usize,
    /// Number of springs.
    pub springs: usize,
    /// Time step h of one step, in seconds (s); one step may be split into `substeps`.
    #[serde(deserialize_with = "f64_or_nan")]
    pub time_step: f64,
    /// Number of substeps per step (1 when steps are not split).
    pub substeps: usize,
    /// The settings of the integrator's solver (absent for explicit integrators and in older files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver_settings: Option<SolverSettingsRecord>,
    /// How the implicit integrators held the pinned vertices: `reduction` or `counter-force`
    /// (absent in older files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pin_method: Option<String>,
    /// What each step's `solver_residual` is, with its unit (absent for explicit integrators
    /// and in older files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver_residual: Option<ResidualRecord>,
    /// Chebyshev PD only: the ρ it used and where it came from (absent otherwise and in older
    /// files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chebyshev_rate: Option<RateRecord>,
    /// One record per step, in order.
    pub steps: Vec<StepRecord>,
}

/// The convergence rate ρ of plain PD that Chebyshev PD's schedule uses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RateRecord {
    /// ρ, in (0, 1).
    pub rate: f64,
    /// `estimated` (from plain PD iterations on the first step), `given` (the settings'), or
    /// `fallback` (the estimate did not form; the settings' ρ).
    pub source: String,
}

/// How the integrator's solver was set up; each entry is absent where the integrator has no such
/// setting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct SolverSettingsRecord {
    /// β of the linearised integrator, in [0, 1].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f64>,
    /// The linearised integrator's linear solver: `jacobi` or `cg`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub linear_solver: Option<String>,
    /// Iteration limit (linear solver, Newton) or iterations per step (projective dynamics).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
    /// Tolerance (linear solver: relative residual; newton, newton-cg, lbfgs: step size, m/s; PD:
    /// position change, m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Newton's relaxation preset: `none` or `buckling` (absent for other settings).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub relaxation: Option<String>,
    /// Newton's factor reuse: CG iterations allowed on a held factor (0: off; absent for other
    /// integrators).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub factor_reuse: Option<usize>,
    /// The memory budget of the sparse Cholesky factors (bytes, resolved: `machine` is written as
    /// the bytes it meant on this machine; docs/solvers.md §2.5); absent for integrators that
    /// factor nothing and in older files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub memory_budget: Option<u64>,
    /// How the PD matrix is solved: `auto`, `direct` or `multilevel` (pd, pd-chebyshev, lbfgs and
    /// newton-cg; absent for other integrators and in older files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pd_global_solve: Option<String>,
}

/// What a step's `solver_residual` measures: Newton's relative gradient (unit `1`), projective
/// dynamics' last position change (`m`), or the linearised integrator's relative linear residual
/// (`1`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResidualRecord {
    /// The quantity, in words (e.g. `relative gradient |grad Phi(x)| / |grad Phi(x0)|`).
    pub quantity: String,
    /// Its unit: `1` for a dimensionless ratio, `m` for metres.
    pub unit: String,
}

/// The state after one step and what the step cost.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepRecord {
    /// Step number, counted from 1 for the first step taken (0 may record the initial state).
    pub step: usize,
    /// Simulated time at the end of the step, in seconds (s).
    #[serde(deserialize_with = "f64_or_nan")]
    pub time: f64,
    /// Kinetic energy ½ Σ mᵢ |vᵢ|², in joules (J).
    #[serde(deserialize_with = "f64_or_nan")]
    pub kinetic_energy: f64,
    /// Potential energy (springs plus conservative external forces such as gravity), in joules (J).
    #[serde(deserialize_with = "f64_or_nan")]
    pub potential_energy: f64,
    /// The contact barrier's energy, in joules (J): present for the integrators whose contact is
    /// part of their objective (newton, newton-cg, lbfgs) on scenes with obstacles, absent
    /// otherwise and in older files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_energy: Option<f64>,
    /// Kinetic plus potential (plus contact, where present) energy, in joules (J).
    #[serde(deserialize_with = "f64_or_nan")]
    pub total_energy: f64,
    /// The smallest signed distance of a free vertex from an obstacle, in metres (m): negative
    /// inside one; absent for scenes without obstacles and in older files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_distance: Option<f64>,
    /// Self-contact at the end of the step (scenes with self-contact; absent otherwise and in older
    /// files): the smallest distance between two primitives of the surface (m), the pairs within
    /// d̂ and the barrier's stiffness κ (N/m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub self_contact: Option<SelfContactRecord>,
    /// The scale s (dimensionless, ≥ 1) on every barrier's stiffness at the end of the step under
    /// the adaptive stiffness (`[barrier] adaptive_stiffness`): κ̂ s per unit mass against
    /// obstacles, `self_contact.stiffness` already includes it. Absent when it is off and in older
    /// files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub barrier_stiffness_scale: Option<f64>,
    /// Tetrahedra turned inside out (signed volume of the opposite sign to the rest mesh's, or
    /// zero): present for tetrahedral meshes, absent otherwise and in older files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inverted_tetrahedra: Option<usize>,
    /// Largest spring stretch ratio maxₛ |r|/l (current over rest length), dimensionless:
    /// 1 at rest, above 1 when stretched.
    #[serde(deserialize_with = "f64_or_nan")]
    pub max_stretch: f64,
    /// Iterations of the step's solver (Newton, conjugate gradient, projective dynamics…), summed
    /// over substeps; `None` for explicit integrators, which solve nothing.
    pub solver_iterations: Option<usize>,
    /// The solver's final residual: the quantity, with its unit, that the run's
    /// `solver_residual` record names; `None` for explicit integrators.
    pub solver_residual: Option<f64>,
    /// Why the solver stopped: `converged` (its criterion holds), `round-off` (at the proven
    /// rounding floor above the criterion: not converged), `iteration-limit`, `stagnated` or
    /// `non-finite`; `None` for explicit integrators. A linear
    /// solve that stopped at its limit is kept and marked so here.
    #[serde(default)]
    pub solver_stop: Option<String>,
    /// Whether the solver converged in this step (`solver_stop` is `converged` in every piece of
    /// the step, and `solver_residual` is within the tolerance); `None` for explicit integrators and in older files. Projective
    /// dynamics with its fixed iteration budget (tolerance 0) reports `false`.
    #[serde(default)]
    pub solver_converged: Option<bool>,
    /// The linearised integrator solved this step with the clamped Hessian because the exact one
    /// gave a system that is not positive definite.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub clamped_hessian: bool,
    /// Backward Euler by Newton did not finish this step and redid it as this many smaller steps
    /// (adaptive halving); `solver_iterations` then includes the given-up attempts. Absent when the
    /// step was not split.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub halved_into: Option<usize>,
    // Wall times are in `timings.json` (see `super::timings`): a summary holds only results, so
    // that a run resumed from a checkpoint writes the same summary as one that was not stopped.
}

/// Self-contact at the end of a step ([`StepRecord::self_contact`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SelfContactRecord {
    /// The smallest distance between the primitives of a pair (m), among the pairs within 1.5 d̂;
    /// `null` (∞) when no pair is that close.
    pub smallest_distance: Option<f64>,
    /// Point–triangle pairs within d̂.
    pub point_triangle_pairs: usize,
    /// Edge–edge pairs within d̂.
    pub edge_edge_pairs: usize,
    /// The barrier's stiffness κ (N/m).
    pub stiffness: f64,
}

/// Reads a number that `serde_json` may have written as `null` (NaN or ±infinity) as NaN.
fn f64_or_nan<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::NAN))
}

/// Writes `summary` to `path` as pretty-printed JSON, atomically.
///
/// The JSON goes to a temporary file in `path`'s directory, which is flushed, synced and then
/// renamed onto `path`; on any error the temporary file is removed and `path` is left as it was.
/// Non-finite numbers are written as `null` (see the module documentation).
pub fn write_summary(path: &Path, summary: &RunSummary) -> Result<(), OutputError> {
    write_json_atomically(path, summary, true)
}

/// Reads a summary written by [`write_summary`]; `null` numbers read back as NaN.
#[allow(dead_code)] // Part of the module's API for tests and tools; the binary only writes.
pub fn read_summary(path: &Path) -> Result<RunSummary, OutputError> {
    let file = File::open(path).map_err(|e| OutputError::io(path, e))?;
    serde_json::from_reader(BufReader::new(file)).map_err(|source| OutputError::Json {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> RunSummary {
        RunSummary {
            scene: "cloth-10".into(),
            integrator: "newton".into(),
            dimension: 3,
            vertices: 100,
            springs: 502,
            time_step: 1.0 / 30.0,
            substeps: 1,
            solver_settings: Some(SolverSettingsRecord {
                iterations: Some(50),
                tolerance: Some(1e-8),
                ..Default::default()
            }),
            pin_method: Some("counter-force".into()),
            solver_residual: Some(ResidualRecord {
                quantity: "relative gradient".into(),
                unit: "1".into(),
            }),
            chebyshev_rate: None,
            steps: vec![
                StepRecord {
                    step: 1,
                    time: 1.0 / 30.0,
                    kinetic_energy: 0.125,
                    potential_energy: -0.5,
                    contact_energy: None,
                    total_energy: -0.375,
                    contact_distance: None,
                    barrier_stiffness_scale: None,
                    self_contact: None,
                    inverted_tetrahedra: None,
                    max_stretch: 1.0625,
                    solver_iterations: Some(7),
                    solver_residual: Some(3.5e-11),
                    solver_stop: Some("converged".into()),
                    solver_converged: Some(true),
                    clamped_hessian: true,
                    halved_into: Some(4),
                },
                StepRecord {
                    step: 2,
                    time: 2.0 / 30.0,
                    kinetic_energy: 0.25,
                    potential_energy: -0.75,
                    contact_energy: None,
                    total_energy: -0.5,
                    contact_distance: None,
                    barrier_stiffness_scale: None,
                    self_contact: None,
                    inverted_tetrahedra: None,
                    max_stretch: 1.1,
                    solver_iterations: None,
                    solver_residual: None,
                    solver_stop: None,
                    solver_converged: None,
                    clamped_hessian: false,
                    halved_into: None,
                },
            ],
        }
    }

    #[test]
    fn round_trip_in_memory() {
        let s = sample();
        let json = serde_json::to_string_pretty(&s).unwrap();
        let back: RunSummary = serde_json::from_str(&json).unwrap();
        assert_eq!(back, s);
    }

    #[test]
    fn round_trip_through_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("summary.json");
        let s = sample();
        write_summary(&path, &s).unwrap();
        assert_eq!(read_summary(&path).unwrap(), s);
        // Overwriting works too, and leaves no temporary file behind.
        write_summary(&path, &s).unwrap();
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("summary.json")]);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\"kinetic_energy\": 0.125"), "{text}");
        assert!(text.ends_with("}\n"));
    }

    #[test]
    fn non_finite_numbers_become_null_and_read_back_as_nan() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("summary.json");
        let mut s = sample();
        s.steps[0].total_energy = f64::NAN;
        s.steps[0].max_stretch = f64::INFINITY;
        s.steps[0].solver_residual = Some(f64::NAN);
        write_summary(&path, &s).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\"total_energy\": null"), "{text}");
        let back = read_summary(&path).unwrap();
        assert!(back.steps[0].total_energy.is_nan());
        assert!(back.steps[0].max_stretch.is_nan());
        assert_eq!(back.steps[0].solver_residual, None);
        assert_eq!(back.steps[1], s.steps[1]);
    }

    #[test]
    fn failed_write_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        // The destination is a directory: the final rename fails.
        let path = dir.path().join("summary.json");
        std::fs::create_dir(&path).unwrap();
        let err = write_summary(&path, &sample()).unwrap_err();
        assert!(err.to_string().contains("summary.json"), "{err}");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("summary.json")]);
        assert!(path.is_dir());

        // The directory does not exist: nothing is created.
        let missing = dir.path().join("no-such-dir").join("summary.json");
        let err = write_summary(&missing, &sample()).unwrap_err();
        assert!(matches!(err, OutputError::Io { .. }));
        assert!(!missing.exists());
    }
}
