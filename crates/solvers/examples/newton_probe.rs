//! Newton on the backward Euler steps of cloth-N (docs/scenes.md §1: k = 1e3 N/m, pins 0 and N−1,
//! gravity, h = 1/30 s, from rest), each step solved to a relative gradient of 1e-10 from x⁰ = y,
//! printing the iterations, shifts and indefinite steps of every step and the full history of the
//! last one. The 11th step (index 10) starts from the speed-vs-error state (docs/scenes.md §8).
//!
//! `cargo run --release -p hooke-solvers --example newton_probe -- [N=40] [steps=11] [policy]`
//! (`policy`: `shift` or `descent` for `IndefinitePolicy::Shift` or `NewtonIfDescent` instead of
//! the default `ConvexBlend`; `HOOKE_SWEEPS`, `HOOKE_BLOCK_ITERATIONS`, `HOOKE_FOCUS_SHARE`,
//! `HOOKE_FOCUS_RINGS`, `HOOKE_FOCUS_SWEEPS`, `HOOKE_TRUSTED_MODEL`, `HOOKE_SHIFT_FACTOR`,
//! `HOOKE_BLEND_FACTOR`, `HOOKE_INITIAL_SHIFT` and `HOOKE_REGION_*`, `HOOKE_PATCH_SHARE` override those settings). With `HOOKE_STATE=file` the
//! state after 10 steps is saved to `file`, or loaded from it if it exists (cloth-160 takes minutes
//! to get there). `HOOKE_START=stretch3` or `crush` starts from the hard-case states
//! (docs/scenes.md §6: ×3 in x and z; crushed to 1 %). `HOOKE_SUBSTEPS=k` uses h = 1/(30 k)
//! (`HOOKE_DT`: another h than 1/30 s before the division; `HOOKE_STIFFNESS`: another k than
//! 1e3 N/m); `HOOKE_DEFINITENESS=clamped` factors the clamped Hessian in every iteration.
//! `HOOKE_EIG=1` prints the inertia of the Hessian at the last step's solution and its smallest
//! generalised eigenvalues λ (H v = λ M v, in units of the masses), by inverse iteration.
//! `HOOKE_SPRINGS=1` prints the distribution of |r|/l over the springs at the last step's solution
//! (how compressed the most compressed springs are).

use hooke_assembly::FreeDofs;
use hooke_mesh::generators;
use hooke_solvers::Convergence;
use hooke_solvers::{
    BackwardEulerStep, IndefinitePolicy, Newton, NewtonParams, NewtonProblem, Relaxation,
    SparseCholesky,
};
use nalgebra::Vector3;

/// The setting in environment variable `name`, or `default` where it is unset.
fn setting<T: std::str::FromStr>(name: &str, default: T) -> Result<T, Box<dyn std::error::Error>>
where
    T::Err: std::error::Error + 'static,
{
    Ok(std::env::var(name).map_or(Ok(default), |s| s.parse())?)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(Ok(40), |s| s.parse())?;
    let steps: usize = args.get(2).map_or(Ok(11), |s| s.parse())?;
    let indefinite = match args.get(3).map(String::as_str) {
        Some("shift") => IndefinitePolicy::Shift,
        Some("descent") => IndefinitePolicy::NewtonIfDescent,
        _ => IndefinitePolicy::ConvexBlend,
    };
    let defaults = NewtonParams::default();
    let r = defaults.relaxation;
    let relaxation = Relaxation {
        sweeps: setting("HOOKE_SWEEPS", r.sweeps)?,
        block_iterations: setting("HOOKE_BLOCK_ITERATIONS", r.block_iterations)?,
        focus_share: setting("HOOKE_FOCUS_SHARE", r.focus_share)?,
        focus_rings: setting("HOOKE_FOCUS_RINGS", r.focus_rings)?,
        focus_sweeps: setting("HOOKE_FOCUS_SWEEPS", r.focus_sweeps)?,
        trusted_model: setting("HOOKE_TRUSTED_MODEL", r.trusted_model)?,
        region_share: setting("HOOKE_REGION_SHARE", r.region_share)?,
        patch_share: setting("HOOKE_PATCH_SHARE", r.patch_share)?,
        patch_covers: setting("HOOKE_PATCH_COVERS", r.patch_covers)?,
        region_rings: setting("HOOKE_REGION_RINGS", r.region_rings)?,
        region_coverage: setting("HOOKE_REGION_COVERAGE", r.region_coverage)?,
        region_concentration: setting("HOOKE_REGION_CONCENTRATION", r.region_concentration)?,
        region_tolerance: setting("HOOKE_REGION_TOLERANCE", r.region_tolerance)?,
        region_iterations: setting("HOOKE_REGION_ITERATIONS", r.region_iterations)?,
        region_sweeps: setting("HOOKE_REGION_SWEEPS", r.region_sweeps)?,
    };
    let shift_factor = setting("HOOKE_SHIFT_FACTOR", defaults.shift_factor)?;
    let blend_factor = setting("HOOKE_BLEND_FACTOR", defaults.blend_factor)?;
    let initial_shift = setting("HOOKE_INITIAL_SHIFT", defaults.initial_shift)?;
    // HOOKE_STIFFNESS=k (N/m) and HOOKE_DT=h (s): the stiff variant (1e5) or its hard case's
    // h = 1/5.
    let mesh = generators::cloth(n, setting("HOOKE_STIFFNESS", 1e3)?)?;
    let pinned = [0u32, n as u32 - 1];
    // HOOKE_SUBSTEPS=k: h = 1/(30 k) instead of 1/30.
    let substeps: f64 = setting("HOOKE_SUBSTEPS", 1.0)?;
    let h = setting("HOOKE_DT", 1.0 / 30.0)? / substeps;
    let gravity = Vector3::new(0.0, -9.81, 0.0);
    let free = FreeDofs::new(mesh.vertex_count(), &pinned)?;
    let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, h);
    let params = NewtonParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-10,
        max_iterations: 300,
        indefinite,
        relaxation,
        shift_factor,
        blend_factor,
        initial_shift,
        ..Default::default()
    };
    // HOOKE_DEFINITENESS=clamped: factor the clamped Hessian in every iteration instead.
    if std::env::var("HOOKE_DEFINITENESS").as_deref() == Ok("clamped") {
        step.set_definiteness(hooke_assembly::Definiteness::Clamped);
    }
    let mut newton = Newton::new(step.pattern(), params)?;
    let mut x = mesh.positions().to_vec();
    // HOOKE_START=stretch3 | crush: the hard-case starts (docs/scenes.md §6: ×3 in x and z;
    // to 1 %).
    match std::env::var("HOOKE_START").as_deref() {
        Ok("stretch3") => x.iter_mut().for_each(|p| {
            p.x *= 3.0;
            p.z *= 3.0
        }),
        Ok("crush") => x.iter_mut().for_each(|p| *p *= 0.01),
        _ => {}
    }
    let mut v = vec![Vector3::zeros(); x.len()];
    let mut unknowns = vec![0.0; step.dim()];
    // HOOKE_STATE=file: load the state after 10 steps from `file` if it exists (and start at step
    // 10), else save it there when step 10 begins. Little-endian f64: positions, then velocities.
    let state_file = std::env::var("HOOKE_STATE").ok();
    let mut first = 0;
    if let Some(bytes) = state_file.as_ref().and_then(|f| std::fs::read(f).ok()) {
        let values: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        let count = x.len();
        for i in 0..count {
            x[i] = Vector3::from_column_slice(&values[3 * i..3 * i + 3]);
            v[i] = Vector3::from_column_slice(&values[3 * (count + i)..3 * (count + i) + 3]);
        }
        first = 10;
    }
    for s in first..steps {
        if let (10, 0, Some(file)) = (s, first, &state_file) {
            let bytes: Vec<u8> = x
                .iter()
                .chain(&v)
                .flat_map(|p| p.iter().flat_map(|c| c.to_le_bytes()).collect::<Vec<_>>())
                .collect();
            std::fs::write(file, bytes)?;
        }
        let y: Vec<_> = (0..x.len())
            .map(|i| {
                if pinned.contains(&(i as u32)) {
                    x[i]
                } else {
                    x[i] + v[i] * h + gravity * (h * h)
                }
            })
            .collect();
        step.set_step(&y, &x, &mut unknowns);
        let r = newton.minimize(&mut step, &mut unknowns)?;
        let to_1e8 = r
            .history
            .iter()
            .position(|it| it.gradient <= 1e-8)
            .map_or(r.iterations, |k| k + 1);
        println!(
            "step {s}: {} iterations ({to_1e8} to 1e-8), {:?}, gradient {:.2e}, {} shifted, \
             {} indefinite, {} failed attempts, {} factorizations, {} sweeps + {} focused ({} block visits, {} skipped), \
             {} patches, {} skipped ({} vertices, {} inner iterations, {} inner factorizations), {:.2?} \
             ({:.2?} factoring, {:.2?} relaxing)",
            r.iterations,
            r.stop,
            r.gradient(),
            r.shifted_steps,
            r.indefinite_steps,
            r.failed_factorizations,
            r.factorizations,
            r.relaxation_sweeps,
            r.focused_sweeps,
            r.relaxed_blocks,
            r.skipped_relaxations,
            r.region_solves,
            r.skipped_regions,
            r.region_blocks,
            r.region_iterations,
            r.region_factorizations,
            r.wall_time,
            r.factor_time,
            r.relaxation_time
        );
        if s + 1 == steps {
            for (k, it) in r.history.iter().enumerate() {
                println!(
                    "  {k:3}: gradient {:.3e}, Φ {:.12e}, μ {:.0e}, failed {}, negative {}, α {}",
                    it.gradient,
                    it.objective,
                    it.shift,
                    it.failed_factorizations,
                    it.negative_eigenvalues,
                    it.step_length
                );
            }
        }
        if s + 1 == steps && std::env::var("HOOKE_EIG").is_ok() {
            smallest_eigenvalues(&mut step, &unknowns, 4)?;
        }
        let next = step.positions(&unknowns).to_vec();
        if s + 1 == steps && std::env::var("HOOKE_SPRINGS").is_ok() {
            spring_ratios(mesh.springs(), &next);
        }
        for i in 0..x.len() {
            v[i] = (next[i] - x[i]) / h;
        }
        x = next;
    }
    Ok(())
}

/// Print the inertia of H at `x` and its `count` smallest generalised eigenvalues H v = λ M v (M the
/// shift diagonal, the masses), by inverse iteration with M-orthogonal deflation (200 iterations
/// each; enough to show their size, not to resolve clusters).
fn smallest_eigenvalues(
    step: &mut BackwardEulerStep<3>,
    x: &[f64],
    count: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut cholesky = SparseCholesky::analyze(step.pattern(), Default::default())?;
    let values = step.hessian(x).val().to_vec();
    let inertia =
        cholesky.factorize_ldlt(faer::sparse::SparseColMatRef::new(step.pattern(), &values))?;
    println!("  inertia at the solution: {inertia:?}");
    let mass = step.shift_diagonal().to_vec();
    let m_dot = |a: &[f64], b: &[f64]| -> f64 {
        a.iter()
            .zip(b)
            .zip(&mass)
            .map(|((a, b), m)| a * b * m)
            .sum()
    };
    let mut found: Vec<Vec<f64>> = Vec::new();
    for _ in 0..count {
        // A fixed, non-smooth start, so that no low mode is missing from it.
        let mut v: Vec<f64> = (0..mass.len())
            .map(|i| (i * 7919 % 1000) as f64 / 1000.0 - 0.5)
            .collect();
        let mut lambda = 0.0;
        for _ in 0..200 {
            for u in &found {
                let c = m_dot(u, &v);
                v.iter_mut().zip(u).for_each(|(a, b)| *a -= c * b);
            }
            let norm = m_dot(&v, &v).sqrt();
            v.iter_mut().for_each(|a| *a /= norm);
            // w = H⁻¹ M v; vᵀ M w → 1/λ.
            let mut w: Vec<f64> = v.iter().zip(&mass).map(|(a, m)| a * m).collect();
            cholesky.solve_slice(&mut w);
            lambda = 1.0 / m_dot(&v, &w);
            v = w;
        }
        let norm = m_dot(&v, &v).sqrt();
        v.iter_mut().for_each(|a| *a /= norm);
        let peak = v.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        println!("  λ ≈ {lambda:.4e} M (mode's largest entry {peak:.3e}, ‖v‖_M = 1)");
        found.push(v);
    }
    Ok(())
}

/// The distribution of the stretch |r|/l over `springs` at `positions`: its smallest values and
/// quantiles, and how many springs are compressed below a half and a tenth of their rest length.
fn spring_ratios(springs: &[hooke_mesh::Spring], positions: &[Vector3<f64>]) {
    let mut ratios: Vec<f64> = springs
        .iter()
        .map(|spring| {
            let (i, j) = spring.ends();
            (positions[i] - positions[j]).norm() / spring.rest_length
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    let quantile = |q: f64| ratios[((ratios.len() - 1) as f64 * q) as usize];
    let below = |t: f64| ratios.iter().take_while(|&&r| r < t).count();
    println!(
        "  |r|/l at the solution: smallest {:?}; 0.1 % {:.3}, 1 % {:.3}, median {:.3}, largest {:.3}; \
         {} below 0.5, {} below 0.1 (of {})",
        &ratios[..5.min(ratios.len())],
        quantile(0.001),
        quantile(0.01),
        quantile(0.5),
        ratios[ratios.len() - 1],
        below(0.5),
        below(0.1),
        ratios.len()
    );
}
