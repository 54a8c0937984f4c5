//! Per-spring weights that make M + h² ∇²E positive definite before any factorisation
//! (docs/solvers.md §3.2, "mass-split projection"): [`HessianPattern::definite_scales`].
//!
//! A compressed spring s = (i, j) (|r| < l) has the transverse eigenvalue k(1 − l/|r|) < 0; its
//! share of h² ∇²E, in that direction, is −d_s [1 −1; −1 1] with the demand
//! d_s = h² k (l/|r| − 1) > 0. Split a share θ of each vertex's mass among the compressed springs
//! at it in proportion to their demands, a_s = θ m_i d_s / D_i with D_i = Σ d over the compressed
//! springs at i. The 2×2 block [a_s − d', d'; d', b_s − d'] is positive semidefinite if and only
//! if d' ≤ a_s b_s / (a_s + b_s) = d_s θ / (L_i + L_j), L_v = D_v / m_v (the vertex's load). So
//! the demand weighted by σ_s = min(1, θ / (L_i + L_j)) keeps every spring's block, with its mass
//! shares, positive semidefinite: the exact block where L_i + L_j ≤ θ, a partial projection where
//! the ends are overloaded. The shares at a vertex add up to θ m_v, the rest (1 − θ) M is left
//! over, and every other term (the longitudinal eigenvalue k, stretched springs, the dashpot) is
//! positive semidefinite, so the sum is positive definite with smallest eigenvalue at least
//! (1 − θ) min m. A pinned end (no unknowns, or its rows replaced by counter-forces) has no
//! coupling to hold, and counts with L = 0.

use rayon::prelude::*;

use hooke_mesh::Spring;
use nalgebra::SVector;

use crate::forces::PARALLEL_THRESHOLD;
use crate::spring::{Definiteness, HessianTerms};
use crate::HessianPattern;

/// Work items per rayon task of the weight loops.
const CHUNK: usize = 2048;

/// The demand h² k (l/|r| − 1) of a compressed spring, 0 for a stretched one or one without a
/// direction (whose stand-in block is positive definite): the same terms as the assembly's.
#[inline]
fn demand<const D: usize>(spring: &Spring, positions: &[SVector<f64, D>], h2: f64) -> f64 {
    let (i, j) = spring.ends();
    let r = positions[i] - positions[j];
    let terms = HessianTerms::new(
        spring.stiffness,
        spring.rest_length,
        &r,
        Definiteness::Exact,
    );
    if terms.across < 0.0 {
        -h2 * terms.across
    } else {
        0.0
    }
}

impl<const D: usize> HessianPattern<D> {
    /// The weights σ_s (one per spring, in [0, 1]) of [`HessianPattern::assemble_scaled_into`] that
    /// make the matrix positive definite with the share `share` = θ ∈ [0, 1) of the masses (see
    /// the module documentation): σ_s = min(1, θ / (L_i + L_j)) for a compressed spring, 1 for
    /// every other. `loads` (one per block column of the pattern, [`HessianPattern::dof_count`] / D)
    /// receives the loads L_v = D_v / m_v (dimensionless; +∞ for a massless vertex with a
    /// compressed spring). Returns how many compressed springs have σ_s < 1 (projected, partly or
    /// wholly). `springs`, `positions`, `masses` and `h` as for
    /// [`HessianPattern::assemble_into`]; the same bits serial or parallel (each load sums its
    /// column's springs in their fixed order), no allocation.
    ///
    /// # Panics
    /// If the springs, positions or masses do not match the pattern, or `loads` or `scales` have
    /// the wrong length.
    #[allow(clippy::too_many_arguments)] // the state (springs, positions, masses, h, θ) and the buffers
    #[track_caller]
    pub fn definite_scales(
        &self,
        springs: &[Spring],
        positions: &[SVector<f64, D>],
        masses: &[f64],
        h: f64,
        share: f64,
        parallel: bool,
        loads: &mut [f64],
        scales: &mut [f64],
    ) -> usize {
        let graph = self.graph();
        let free = graph.free();
        assert_eq!(
            springs.len(),
            graph.spring_count(),
            "definite_scales: the springs are not those of the pattern"
        );
        assert_eq!(
            positions.len(),
            free.vertex_count(),
            "definite_scales: one position per vertex"
        );
        assert_eq!(
            masses.len(),
            free.vertex_count(),
            "definite_scales: one mass per vertex"
        );
        assert_eq!(
            loads.len(),
            graph.columns(),
            "definite_scales: one load per block column"
        );
        assert_eq!(
            scales.len(),
            springs.len(),
            "definite_scales: one weight per spring"
        );
        let h2 = h * h;
        let load = |(column, l): (usize, &mut f64)| {
            let total: f64 = graph
                .contributions(column)
                .iter()
                .map(|c| demand(&springs[c.spring as usize], positions, h2))
                .sum();
            *l = if total > 0.0 {
                total / masses[free.free_vertices()[column] as usize]
            } else {
                0.0
            };
        };
        let parallel = parallel && springs.len() >= PARALLEL_THRESHOLD;
        if parallel {
            loads
                .par_iter_mut()
                .enumerate()
                .with_min_len(CHUNK)
                .for_each(load);
        } else {
            loads.iter_mut().enumerate().for_each(load);
        }
        let loads = &*loads;
        // A pinned end of a reduced pattern has no column; a pattern under counter-forces has
        // every vertex free, and its pinned ends count their loads (only more cautious).
        let load_of = |vertex: usize| free.free_index(vertex).map_or(0.0, |c| loads[c]);
        let weigh = |(s, sigma): (usize, &mut f64)| -> usize {
            let spring = &springs[s];
            let (i, j) = spring.ends();
            let total = load_of(i) + load_of(j);
            // Stretched springs and springs whose ends can hold them keep their exact block.
            if total <= share || demand(spring, positions, h2) == 0.0 {
                *sigma = 1.0;
                0
            } else {
                *sigma = share / total;
                1
            }
        };
        if parallel {
            scales
                .par_iter_mut()
                .enumerate()
                .with_min_len(CHUNK)
                .map(weigh)
                .sum()
        } else {
            scales.iter_mut().enumerate().map(weigh).sum()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FreeDofs, HessianParams};
    use hooke_mesh::generators::cloth;
    use nalgebra::{DMatrix, Vector3};

    fn assemble_with(
        pattern: &HessianPattern<3>,
        springs: &[Spring],
        x: &[Vector3<f64>],
        masses: &[f64],
        scales: Option<&[f64]>,
        definiteness: Definiteness,
    ) -> Vec<f64> {
        let mut workspace = pattern.workspace();
        let mut values = pattern.new_values();
        match scales {
            Some(scales) => pattern.assemble_scaled_into(
                springs,
                x,
                masses,
                0.01,
                scales,
                true,
                &mut workspace,
                &mut values,
            ),
            None => pattern.assemble_into(
                springs,
                x,
                masses,
                0.01,
                HessianParams {
                    definiteness,
                    parallel: true,
                },
                &mut workspace,
                &mut values,
            ),
        }
        values
    }

    /// A cloth crushed to 70 % and bent, with a zero-length, a very short and a very long spring
    /// (the stand-in and the slow path of the refill).
    fn state() -> (hooke_mesh::SpringMesh<3>, Vec<Vector3<f64>>) {
        let mesh = cloth(5, 100.0).unwrap();
        let l = mesh.springs()[0].rest_length;
        let mut x: Vec<Vector3<f64>> = mesh
            .positions()
            .iter()
            .map(|p| Vector3::new(0.7 * p.x, 0.05 * (7.0 * p.x + 3.0 * p.z).sin(), 0.7 * p.z))
            .collect();
        x[1] = x[0];
        x[7] = x[6] + Vector3::new(1e-6 * l, 0.0, 0.0);
        x[24] += Vector3::new(1e3 * l, -2e3 * l, 0.0);
        (mesh, x)
    }

    #[test]
    fn weights_one_and_zero_give_the_exact_and_clamped_hessians() {
        let (mesh, x) = state();
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), None);
        let springs = mesh.springs();
        let masses = mesh.masses();
        let ones = vec![1.0; springs.len()];
        let zeros = vec![0.0; springs.len()];
        let exact = assemble_with(&pattern, springs, &x, masses, None, Definiteness::Exact);
        let clamped = assemble_with(&pattern, springs, &x, masses, None, Definiteness::Clamped);
        let one = assemble_with(
            &pattern,
            springs,
            &x,
            masses,
            Some(&ones),
            Definiteness::Exact,
        );
        let zero = assemble_with(
            &pattern,
            springs,
            &x,
            masses,
            Some(&zeros),
            Definiteness::Exact,
        );
        assert!(exact
            .iter()
            .zip(&one)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        // σ = 0 writes −0.0 · h² for the transverse term where the clamp writes +0.0: equal values.
        assert_eq!(clamped, zero);
    }

    #[test]
    fn weighted_blocks_are_the_weighted_spring_hessians() {
        let (mesh, x) = state();
        let pinned = [0u32, 4];
        let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), Some(&free));
        let springs = mesh.springs();
        // Weights in [0, 1], 1 on every fifth spring.
        let scales: Vec<f64> = (0..springs.len())
            .map(|s| {
                if s % 5 == 0 {
                    1.0
                } else {
                    (s % 7) as f64 / 7.0
                }
            })
            .collect();
        let values = assemble_with(
            &pattern,
            springs,
            &x,
            mesh.masses(),
            Some(&scales),
            Definiteness::Exact,
        );
        let got = DMatrix::from_fn(pattern.dof_count(), pattern.dof_count(), |r, c| {
            let m = pattern.matrix(&values);
            m.row_idx_of_col(c)
                .zip(m.val_of_col(c))
                .find(|(i, _)| *i == r)
                .map_or(0.0, |(_, v)| *v)
        });
        // By hand, dense: M + h² Σ H'_s on the free vertices.
        let n = pattern.dof_count();
        let mut expected = DMatrix::zeros(n, n);
        for (f, &v) in free.free_vertices().iter().enumerate() {
            for a in 0..3 {
                expected[(3 * f + a, 3 * f + a)] += mesh.masses()[v as usize];
            }
        }
        for (s, spring) in springs.iter().enumerate() {
            let (i, j) = spring.ends();
            let block = HessianTerms::new(
                spring.stiffness,
                spring.rest_length,
                &(x[i] - x[j]),
                Definiteness::Exact,
            )
            .with_across_scale(spring.stiffness, scales[s])
            .block()
                * 1e-4;
            for (p, q, sign) in [(i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)] {
                if let (Some(p), Some(q)) = (free.free_index(p), free.free_index(q)) {
                    for b in 0..3 {
                        for a in 0..3 {
                            expected[(3 * p + a, 3 * q + b)] += sign * block[(a, b)];
                        }
                    }
                }
            }
        }
        // Sums of a few terms in another order: rounding of the largest entry's size.
        let scale = expected.amax();
        assert!((&got - &expected).amax() <= 1e-12 * scale);
    }

    #[test]
    fn weights_follow_the_loads() {
        let (mesh, x) = state();
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), None);
        let springs = mesh.springs();
        let mut loads = vec![0.0; pattern.dof_count() / 3];
        let mut scales = vec![0.0; springs.len()];
        let h = 0.01;
        let projected = pattern.definite_scales(
            springs,
            &x,
            mesh.masses(),
            h,
            0.5,
            true,
            &mut loads,
            &mut scales,
        );
        assert_eq!(projected, scales.iter().filter(|&&w| w < 1.0).count());
        for (s, spring) in springs.iter().enumerate() {
            let (i, j) = spring.ends();
            let d = demand(spring, &x, h * h);
            let total = loads[i] + loads[j];
            let expected = if d > 0.0 && total > 0.5 {
                0.5 / total
            } else {
                1.0
            };
            assert_eq!(scales[s], expected, "spring {s}");
        }
        // Loads: Σ demand / mass per vertex.
        for (v, load) in loads.iter().enumerate() {
            let total: f64 = springs
                .iter()
                .filter(|s| s.ends().0 == v || s.ends().1 == v)
                .map(|s| demand(s, &x, h * h))
                .sum();
            assert!((load - total / mesh.masses()[v]).abs() <= 1e-14 * load.abs().max(1.0));
        }
    }
}
