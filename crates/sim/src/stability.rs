//! The explicit stability bound h ≤ c √(m/k) (docs/model.md §6.2), made precise for a whole mesh.
//!
//! For symplectic Euler on a linear damped oscillator ẍ = −ω² x − γ ẋ the step is stable when
//! ω² h² + 2 γ h ≤ 4, i.e. h ≤ 4 / (γ + √(γ² + 4 ω²)) (= 2/ω undamped, the c = 2 of a single mass
//! on a spring to a wall; c = √2 for two equal masses on one spring). For a mesh, ω² is the largest
//! eigenvalue of M⁻¹K with K the stiffness at rest. Two numbers are reported:
//! - `safe_step`: from Gershgorin's bound ω_i² ≤ 2 Σ_s k_s / m_i per vertex (and the same for the
//!   damping rates), a guaranteed lower bound on the stable step of the linearised rest state;
//! - `estimated_step`: from the largest eigenvalue of M^(−½) K M^(−½) by power iteration, close to the
//!   true bound and never below `safe_step`.
//!
//! Springs far from rest change the curvature (compressed springs soften, so the rest state is the
//! stiffest for tension-dominated motion); the bound is an estimate for the scene, not a proof for
//! every state.

use nalgebra::SVector;

use crate::forces::ExternalForce;
use crate::Scene;

/// The explicit stability bound of a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StabilityBound {
    /// A step (s) that is stable for the linearised rest state (Gershgorin bound).
    pub safe_step: f64,
    /// The estimated largest stable step (s), from power iteration; ≥ `safe_step`.
    pub estimated_step: f64,
    /// The free vertex with the highest Gershgorin frequency (the stiffest place).
    pub stiffest_vertex: usize,
    /// Gershgorin's upper bound on ω²_max, the largest eigenvalue of M⁻¹K (1/s²).
    pub omega_squared_bound: f64,
    /// The power-iteration estimate of ω²_max (1/s²), ≤ `omega_squared_bound`.
    pub omega_squared_estimate: f64,
}

/// Forward Euler's automatic substeps keep the fastest mode's energy growth under this fraction per
/// frame.
pub const FORWARD_EULER_GROWTH_PER_FRAME: f64 = 0.01;
/// Forward Euler is refused (unless forced) when the fastest mode's amplitude would more than
/// double each frame: that run is exploding, not merely inaccurate.
pub const FORWARD_EULER_REFUSED_GROWTH_PER_FRAME: f64 = 1.0;

impl StabilityBound {
    /// The (safe, estimated) largest substep (s) of `integrator` for frames of `frame_step` seconds.
    ///
    /// Symplectic Euler: the bounds above. Forward Euler has no stable step for an undamped spring
    /// (its amplification √(1 + h²ω²) exceeds 1 at every h); over a frame of length H the fastest
    /// mode grows by exp(H h ω² / 2), so its "safe" step keeps that growth under
    /// [`FORWARD_EULER_GROWTH_PER_FRAME`] and its refusal limit is growth beyond
    /// [`FORWARD_EULER_REFUSED_GROWTH_PER_FRAME`]. Damping is ignored there (conservative).
    pub fn for_integrator(&self, integrator: crate::Integrator, frame_step: f64) -> (f64, f64) {
        match integrator {
            crate::Integrator::ExplicitEuler => {
                let step = |growth: f64, omega_squared: f64| {
                    if omega_squared > 0.0 {
                        2.0 * growth.ln_1p() / (frame_step * omega_squared)
                    } else {
                        f64::INFINITY
                    }
                };
                (
                    step(FORWARD_EULER_GROWTH_PER_FRAME, self.omega_squared_bound)
                        .min(self.safe_step),
                    step(
                        FORWARD_EULER_REFUSED_GROWTH_PER_FRAME,
                        self.omega_squared_estimate,
                    )
                    .min(self.estimated_step),
                )
            }
            _ => (self.safe_step, self.estimated_step),
        }
    }
}

/// Power-iteration steps: enough to bring the Rayleigh quotient within a few per cent of the top
/// eigenvalue on the canonical meshes, at a cost of a few force evaluations.
const POWER_ITERATIONS: usize = 60;

fn step_for(omega_squared: f64, gamma: f64) -> f64 {
    let denominator = gamma + (gamma * gamma + 4.0 * omega_squared).sqrt();
    if denominator > 0.0 {
        4.0 / denominator
    } else {
        f64::INFINITY
    }
}

/// Estimate the explicit stability bound of `scene` (pinned vertices excluded).
pub fn stability_bound<const D: usize>(scene: &Scene<D>) -> StabilityBound {
    let mesh = scene.mesh();
    let masses = mesh.masses();
    let free = |v: usize| !scene.is_pinned()[v];
    let n = mesh.vertex_count();
    // Per vertex: Σ k and Σ dashpot over incident springs.
    let mut stiffness_sum = vec![0.0; n];
    for s in mesh.springs() {
        let (i, j) = s.ends();
        stiffness_sum[i] += s.stiffness;
        stiffness_sum[j] += s.stiffness;
    }
    let springs_at = {
        let mut count = vec![0usize; n];
        for s in mesh.springs() {
            count[s.i as usize] += 1;
            count[s.j as usize] += 1;
        }
        count
    };
    let mut attractor = 0.0;
    let mut wind = 0.0;
    for f in scene.forces().as_slice() {
        match f {
            ExternalForce::Attractor { strength, .. } => attractor += strength,
            ExternalForce::Wind { coefficient, .. } => wind += coefficient,
            _ => {}
        }
    }
    let damping = scene.damping();
    let gamma_at = |v: usize| {
        (damping.viscous + wind + 2.0 * damping.dashpot * springs_at[v] as f64) / masses[v]
    };
    let mut safe_step = f64::INFINITY;
    let mut stiffest_vertex = 0;
    let mut gamma_max: f64 = 0.0;
    let mut omega_squared_bound: f64 = 0.0;
    for v in (0..n).filter(|&v| free(v)) {
        let omega_squared = 2.0 * stiffness_sum[v] / masses[v] + attractor;
        omega_squared_bound = omega_squared_bound.max(omega_squared);
        let gamma = gamma_at(v);
        gamma_max = gamma_max.max(gamma);
        let h = step_for(omega_squared, gamma);
        if h < safe_step {
            safe_step = h;
            stiffest_vertex = v;
        }
    }
    // Power iteration on A = M^(−½) K M^(−½) over free DOFs, K = Σ k (a aᵀ) ⊗ (r̂ r̂ᵀ) at rest.
    let inv_sqrt_mass: Vec<f64> = masses.iter().map(|m| 1.0 / m.sqrt()).collect();
    let positions = mesh.positions();
    let directions: Vec<SVector<f64, D>> = mesh
        .springs()
        .iter()
        .map(|s| {
            let (i, j) = s.ends();
            hooke_assembly::spring::direction(&(positions[i] - positions[j]))
                .map(|(d, _)| d)
                .unwrap_or_else(SVector::zeros)
        })
        .collect();
    // A deterministic, sign-varying start that overlaps the high-frequency modes.
    let mut u: Vec<SVector<f64, D>> = (0..n)
        .map(|v| {
            if free(v) {
                SVector::from_fn(|a, _| {
                    let t = ((v * 7 + a * 13) % 17) as f64 - 8.0;
                    if (v + a) % 2 == 0 {
                        t + 0.5
                    } else {
                        -t - 0.5
                    }
                })
            } else {
                SVector::zeros()
            }
        })
        .collect();
    let mut y = vec![SVector::<f64, D>::zeros(); n];
    let mut lambda: f64 = 0.0;
    for _ in 0..POWER_ITERATIONS {
        let norm = u.iter().map(|x| x.norm_squared()).sum::<f64>().sqrt();
        if norm == 0.0 || !norm.is_finite() {
            break;
        }
        u.iter_mut().for_each(|x| *x /= norm);
        y.iter_mut().for_each(|x| *x = SVector::zeros());
        for (s, d) in mesh.springs().iter().zip(&directions) {
            let (i, j) = s.ends();
            let stretch = d.dot(&(u[i] * inv_sqrt_mass[i] - u[j] * inv_sqrt_mass[j]));
            let z = d * (s.stiffness * stretch);
            y[i] += z * inv_sqrt_mass[i];
            y[j] -= z * inv_sqrt_mass[j];
        }
        for v in 0..n {
            if free(v) {
                y[v] += u[v] * attractor;
            } else {
                y[v] = SVector::zeros();
            }
        }
        lambda = u.iter().zip(&y).map(|(a, b)| a.dot(b)).sum();
        std::mem::swap(&mut u, &mut y);
    }
    let estimated_step = step_for(lambda, gamma_max).max(safe_step);
    StabilityBound {
        safe_step,
        estimated_step,
        stiffest_vertex,
        omega_squared_bound,
        omega_squared_estimate: lambda.min(omega_squared_bound),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hooke_mesh::{Spring, SpringMesh};
    use nalgebra::Vector3;

    #[test]
    fn two_masses_on_a_spring() {
        // Two unit masses, k = 100: ω² = 2k/m = 200 exactly, so the bound is 2/√200 for both numbers.
        let mesh = SpringMesh::new(
            vec![Vector3::zeros(), Vector3::x()],
            vec![1.0, 1.0],
            vec![Spring {
                i: 0,
                j: 1,
                stiffness: 100.0,
                rest_length: 1.0,
            }],
        )
        .unwrap();
        let scene = Scene::new(mesh, 0.1).unwrap();
        let b = stability_bound(&scene);
        let exact = 2.0 / 200f64.sqrt();
        assert!((b.safe_step - exact).abs() < 1e-12 * exact);
        assert!((b.estimated_step - exact).abs() < 1e-9 * exact);
    }

    #[test]
    fn cloth_estimate_brackets() {
        let mesh = hooke_mesh::generators::cloth(20, 1e3).unwrap();
        let scene = Scene::new(mesh, 1.0 / 30.0).unwrap();
        let b = stability_bound(&scene);
        assert!(b.safe_step <= b.estimated_step);
        // Gershgorin overestimates ω² by at most a factor of 2 on this lattice (diagonal dominance):
        assert!(b.estimated_step <= 2.0 * b.safe_step, "{b:?}");
    }
}
