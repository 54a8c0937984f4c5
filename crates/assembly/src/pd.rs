//! Projective dynamics / fast mass-spring matrices (docs/model.md §6.8; Liu, Bargteil, O'Brien,
//! Kavan 2013).
//!
//! Local step: d_s = l_s r̂_s for every spring ([`local_step`]). Global step:
//! (M + h² L) x = h² J d + M y, with L = (Σ k_s A_s A_sᵀ) ⊗ I_D the stiffness-weighted graph Laplacian
//! and J = (Σ k_s A_s S_sᵀ) ⊗ I_D (A_s = e_i − e_j the spring's incidence vector, S_s its indicator).
//!
//! The Kronecker structure is kept: [`LaplacianPattern`] assembles the *scalar* n × n matrices L and
//! M + h² L (n_free × n_free with pinned vertices removed), to be factored once and applied to the D
//! coordinate columns as D right-hand sides. J is never formed on the solver path: [`j_times`]
//! computes (J d)_i = Σ_s k_s (A_s)_i d_s from the springs, and [`LaplacianPattern::rhs_into`] the
//! reduced right-hand side K (h² J d + M y − (M + h² L) b) of docs/model.md §5.2
//! directly. [`j_matrix`] builds J
//! as a matrix for tests.

use faer::sparse::{
    SparseColMat, SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef, Triplet,
};
use hooke_mesh::Spring;
use nalgebra::SVector;
use rayon::prelude::*;

use crate::forces::{Incidence, PARALLEL_THRESHOLD};
use crate::graph::{block_pattern, matrix_owned, matrix_ref, BlockGraph, Contribution};
use crate::spring::direction;
use crate::FreeDofs;

/// Vertices per parallel task.
const GRAIN: usize = 2048;

/// The fixed pattern of the scalar matrices L and M + h² L over the free vertices of a spring mesh.
///
/// Stored: the diagonal and every free vertex pair joined by at least one spring, in both triangles,
/// with sorted row indices. Row/column `f` is free vertex `f` of [`FreeDofs`]. Pinned vertices have
/// no row or column; a spring from a free vertex to a pinned one adds to the free vertex's diagonal
/// only, so the assembled matrices are K L Kᵀ and K (M + h² L) Kᵀ exactly.
#[derive(Clone, Debug)]
pub struct LaplacianPattern {
    graph: BlockGraph,
    symbolic: SymbolicSparseColMat<usize>,
}

impl LaplacianPattern {
    /// The pattern for `springs` over `vertex_count` vertices, on the free vertices of `free` (all
    /// vertices if `None`). O(s log d) time.
    ///
    /// # Panics
    /// If a spring has an end ≥ `vertex_count` or joins a vertex to itself, or `free` was built for
    /// another vertex count.
    #[track_caller]
    pub fn new(vertex_count: usize, springs: &[Spring], free: Option<&FreeDofs>) -> Self {
        let (graph, symbolic) = block_pattern::<1>(vertex_count, springs, free);
        LaplacianPattern { graph, symbolic }
    }

    /// The free-vertex map the pattern was built on.
    pub fn free_dofs(&self) -> &FreeDofs {
        self.graph.free()
    }

    /// Number of rows (= columns): the number of free vertices.
    pub fn size(&self) -> usize {
        self.graph.columns()
    }

    /// Number of stored values (both triangles).
    pub fn nnz(&self) -> usize {
        self.graph.blocks()
    }

    /// The symbolic CSC structure.
    pub fn symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.symbolic.as_ref()
    }

    /// A zeroed value array of the right length.
    pub fn new_values(&self) -> Vec<f64> {
        vec![0.0; self.nnz()]
    }

    /// The matrix with this pattern and `values`, borrowed (no copy).
    ///
    /// # Panics
    /// If `values.len()` is not [`LaplacianPattern::nnz`].
    #[track_caller]
    pub fn matrix<'a>(&'a self, values: &'a [f64]) -> SparseColMatRef<'a, usize, f64> {
        matrix_ref(&self.symbolic, values, "LaplacianPattern::matrix")
    }

    /// An owned copy of the matrix with `values` (allocates).
    ///
    /// # Panics
    /// If `values.len()` is not [`LaplacianPattern::nnz`].
    #[track_caller]
    pub fn to_sparse_col_mat(&self, values: &[f64]) -> SparseColMat<usize, f64> {
        matrix_owned(
            &self.symbolic,
            values,
            "LaplacianPattern::to_sparse_col_mat",
        )
    }

    /// Fill `values` with K (diag(masses) + scale · L) Kᵀ: diagonal entry of free vertex v
    /// masses[v] + scale · Σ k_s over the springs at v; entry (v, w), v ≠ w: −scale · Σ k_s over the
    /// springs joining them. Sums in increasing spring order: exactly symmetric, deterministic.
    #[track_caller]
    fn fill(&self, springs: &[Spring], masses: Option<&[f64]>, scale: f64, values: &mut [f64]) {
        let free = self.graph.free();
        assert_eq!(
            springs.len(),
            self.graph.spring_count(),
            "LaplacianPattern: the springs are not those of the pattern"
        );
        if let Some(m) = masses {
            assert_eq!(
                m.len(),
                free.vertex_count(),
                "LaplacianPattern: one mass per vertex"
            );
        }
        assert_eq!(
            values.len(),
            self.nnz(),
            "LaplacianPattern: one value per stored entry"
        );
        let graph = &self.graph;
        let fill = |column: usize, out: &mut [f64]| {
            let mut diagonal = 0.0;
            for c in graph.contributions(column) {
                let k = springs[c.spring as usize].stiffness;
                diagonal += k;
                if c.slot != Contribution::PINNED_OTHER {
                    let v = -scale * k;
                    let dst = &mut out[c.slot as usize];
                    if c.first {
                        *dst = v;
                    } else {
                        *dst += v;
                    }
                }
            }
            let mass = masses.map_or(0.0, |m| m[free.free_vertices()[column] as usize]);
            out[graph.diagonal_slot(column)] = mass + scale * diagonal;
        };
        let parallel = springs.len() >= PARALLEL_THRESHOLD;
        graph.for_each_column::<1, _>(values, parallel, &fill);
    }

    /// Fill `values` with the reduced weighted Laplacian K L Kᵀ (N/m): L = Σ k_s A_s A_sᵀ.
    /// Without pins, L 1 = 0.
    ///
    /// # Panics
    /// If the number of springs or values does not match the pattern.
    #[track_caller]
    pub fn laplacian_into(&self, springs: &[Spring], values: &mut [f64]) {
        self.fill(springs, None, 1.0, values);
    }

    /// Fill `values` with K (M + h² L) Kᵀ (kg), the scalar matrix of the global step, constant while
    /// the topology, masses, stiffnesses and h are: factor it once. SPD when every mass is positive,
    /// or when each connected component of the spring graph has a pinned vertex.
    ///
    /// # Panics
    /// If the number of springs, masses (one per vertex of the full mesh) or values does not match.
    #[track_caller]
    pub fn system_into(&self, springs: &[Spring], masses: &[f64], h: f64, values: &mut [f64]) {
        self.fill(springs, Some(masses), h * h, values);
    }

    /// The right-hand side of the reduced global step, K (h² J d + M y − (M + h² L) b), one
    /// D-vector per free vertex (a column per coordinate, Kronecker structure), computed from the
    /// springs without forming J or L: for free vertex v,
    /// h² Σ_s k_s (A_s)_v d_s + m_v y_v + h² Σ_{s joins v to pinned p} k_s x_p.
    /// (b is zero at free vertices and x_p at pinned ones, so the mass term of M b vanishes.)
    ///
    /// `d` holds the local-step directions per spring (m), `y` the inertial target per vertex (m),
    /// `positions` the current positions per vertex (only the pinned ones, b, are read), `masses` kg.
    ///
    /// # Panics
    /// If the lengths of `springs`, `d` (one per spring), `y`, `positions`, `masses` (one per vertex)
    /// or `out` (one per free vertex) do not match.
    #[allow(clippy::too_many_arguments)]
    #[track_caller]
    pub fn rhs_into<const D: usize>(
        &self,
        springs: &[Spring],
        d: &[SVector<f64, D>],
        y: &[SVector<f64, D>],
        positions: &[SVector<f64, D>],
        masses: &[f64],
        h: f64,
        out: &mut [SVector<f64, D>],
    ) {
        let free = self.graph.free();
        let n = free.vertex_count();
        assert_eq!(
            springs.len(),
            self.graph.spring_count(),
            "rhs_into: the springs are not those of the pattern"
        );
        assert_eq!(
            d.len(),
            springs.len(),
            "rhs_into: one direction d_s per spring"
        );
        assert_eq!(y.len(), n, "rhs_into: one inertial target y per vertex");
        assert_eq!(positions.len(), n, "rhs_into: one position per vertex");
        assert_eq!(masses.len(), n, "rhs_into: one mass per vertex");
        assert_eq!(
            out.len(),
            free.free_count(),
            "rhs_into: one output per free vertex"
        );
        let h2 = h * h;
        let graph = &self.graph;
        let kernel = |(column, o): (usize, &mut SVector<f64, D>)| {
            let vertex = free.free_vertices()[column] as usize;
            let mut acc = SVector::<f64, D>::zeros();
            for c in graph.contributions(column) {
                let s = &springs[c.spring as usize];
                let (i, j) = s.ends();
                let (sign, other) = if i == vertex { (1.0, j) } else { (-1.0, i) };
                acc += d[c.spring as usize] * (sign * s.stiffness);
                if c.slot == Contribution::PINNED_OTHER {
                    acc += positions[other] * s.stiffness;
                }
            }
            *o = acc * h2 + y[vertex] * masses[vertex];
        };
        if springs.len() >= PARALLEL_THRESHOLD {
            out.par_iter_mut()
                .with_min_len(GRAIN)
                .enumerate()
                .for_each(kernel);
        } else {
            out.iter_mut().enumerate().for_each(kernel);
        }
    }
}

/// The local step: d_s = l_s (x_i − x_j) / |x_i − x_j| for every spring (m), the point of the sphere
/// of radius l_s nearest to the current spring vector. Where the spring has zero length (no
/// direction) d_s is left unchanged: every point of the sphere is then equally near, and keeping the
/// previous projection is the stable choice (initialise `d` with the rest configuration's vectors).
/// Deterministic, parallel above 8,192 springs if `parallel`.
///
/// # Panics
/// If `d` does not have one entry per spring.
#[track_caller]
pub fn local_step<const D: usize>(
    springs: &[Spring],
    positions: &[SVector<f64, D>],
    d: &mut [SVector<f64, D>],
    parallel: bool,
) {
    assert_eq!(
        d.len(),
        springs.len(),
        "local_step: one direction per spring"
    );
    let kernel = |(s, d): (&Spring, &mut SVector<f64, D>)| {
        let (i, j) = s.ends();
        if let Some((unit, _)) = direction(&(positions[i] - positions[j])) {
            *d = unit * s.rest_length;
        }
    };
    if parallel && springs.len() >= PARALLEL_THRESHOLD {
        springs
            .par_iter()
            .zip(d.par_iter_mut())
            .with_min_len(GRAIN)
            .for_each(kernel);
    } else {
        springs.iter().zip(d.iter_mut()).for_each(kernel);
    }
}

/// (J d)_v = Σ_s k_s (A_s)_v d_s for every vertex v of the full mesh (N), without forming J:
/// +k_s d_s at the spring's first vertex, −k_s d_s at its second. Sums in increasing spring order
/// from the incidence lists: deterministic, parallel above 8,192 vertices if `parallel`.
///
/// # Panics
/// If `d` does not have one entry per spring, `out` one per vertex of `incidence`, or `incidence`
/// refers to springs beyond `springs`.
#[track_caller]
pub fn j_times<const D: usize>(
    incidence: &Incidence,
    springs: &[Spring],
    d: &[SVector<f64, D>],
    out: &mut [SVector<f64, D>],
    parallel: bool,
) {
    assert_eq!(d.len(), springs.len(), "j_times: one direction per spring");
    assert_eq!(
        out.len(),
        incidence.vertex_count(),
        "j_times: one output per vertex"
    );
    let kernel = |(vertex, o): (usize, &mut SVector<f64, D>)| {
        let mut acc = SVector::<f64, D>::zeros();
        for &(s, sign) in incidence.of(vertex) {
            acc += d[s as usize] * (sign * springs[s as usize].stiffness);
        }
        *o = acc;
    };
    if parallel && out.len() >= PARALLEL_THRESHOLD {
        out.par_iter_mut()
            .with_min_len(GRAIN)
            .enumerate()
            .for_each(kernel);
    } else {
        out.iter_mut().enumerate().for_each(kernel);
    }
}

/// The scalar matrix Σ_s k_s A_s S_sᵀ (vertex count × spring count; column s holds +k_s at row i
/// and −k_s at row j), J without its ⊗ I_D factor. For tests and small problems: the solver path
/// uses [`j_times`].
///
/// # Panics
/// If a spring has an end ≥ `vertex_count`.
#[track_caller]
pub fn j_matrix(vertex_count: usize, springs: &[Spring]) -> SparseColMat<usize, f64> {
    let triplets: Vec<Triplet<usize, usize, f64>> = springs
        .iter()
        .enumerate()
        .flat_map(|(s, spring)| {
            let (i, j) = spring.ends();
            [
                Triplet::new(i, s, spring.stiffness),
                Triplet::new(j, s, -spring.stiffness),
            ]
        })
        .collect();
    SparseColMat::try_new_from_triplets(vertex_count, springs.len(), &triplets)
        .expect("j_matrix: spring ends must be below the vertex count")
}

#[cfg(test)]
mod tests {
    use super::*;
    use hooke_mesh::generators::{beam, cloth};
    use hooke_mesh::proptest_support::{pinned_set, spring_mesh_3d};
    use nalgebra::{DMatrix, DVector, Vector3};
    use proptest::prelude::*;

    fn dense(m: SparseColMatRef<'_, usize, f64>) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(m.nrows(), m.ncols());
        for t in m.triplet_iter() {
            out[(t.row, t.col)] += *t.val;
        }
        out
    }

    /// cloth-5 with integer stiffnesses 1..=7, so that sums of stiffnesses are exact.
    fn integer_cloth() -> hooke_mesh::SpringMesh<3> {
        cloth(5, 1.0)
            .unwrap()
            .map_stiffness(|s, _| (1 + s % 7) as f64)
            .unwrap()
    }

    #[test]
    fn laplacian_annihilates_constants() {
        let mesh = integer_cloth();
        let pattern = LaplacianPattern::new(mesh.vertex_count(), mesh.springs(), None);
        let mut values = pattern.new_values();
        pattern.laplacian_into(mesh.springs(), &mut values);
        let l = dense(pattern.matrix(&values));
        // Integer stiffnesses: each row sum Σk − Σk is exact.
        assert_eq!(
            &l * DVector::from_element(l.ncols(), 1.0),
            DVector::zeros(l.nrows())
        );
        assert_eq!(l, l.transpose());
        // With real stiffnesses the row sums vanish up to round-off of Σ|entries|.
        let mesh = beam(2)
            .unwrap()
            .map_stiffness(|s, _| 1.0 + (s as f64).sin().abs() * 1e3)
            .unwrap();
        let pattern = LaplacianPattern::new(mesh.vertex_count(), mesh.springs(), None);
        let mut values = pattern.new_values();
        pattern.laplacian_into(mesh.springs(), &mut values);
        let l = dense(pattern.matrix(&values));
        for r in 0..l.nrows() {
            let row = l.row(r);
            assert!(
                row.sum().abs() <= 1e-14 * row.abs().sum(),
                "row {r} sums to {}",
                row.sum()
            );
        }
    }

    #[test]
    fn pinned_system_is_spd_and_unpinned_laplacian_is_singular() {
        let mesh = integer_cloth();
        let n = mesh.vertex_count();
        let zero = vec![0.0; n];
        // Zero masses isolate the Laplacian: one pin removes its null space (the graph is connected).
        let free = FreeDofs::new(n, &[0]).unwrap();
        let pinned = LaplacianPattern::new(n, mesh.springs(), Some(&free));
        let mut values = pinned.new_values();
        pinned.system_into(mesh.springs(), &zero, 0.1, &mut values);
        assert!(
            dense(pinned.matrix(&values)).cholesky().is_some(),
            "K L Kᵀ with a pin is not SPD"
        );
        let full = LaplacianPattern::new(n, mesh.springs(), None);
        let mut values = full.new_values();
        full.laplacian_into(mesh.springs(), &mut values);
        let eig = dense(full.matrix(&values)).symmetric_eigen().eigenvalues;
        assert!(
            eig.min().abs() <= 1e-12 * eig.max(),
            "L has no null vector: {}",
            eig.min()
        );
        // With the scene's masses M + h² L is SPD even without pins.
        let mut values = full.new_values();
        full.system_into(mesh.springs(), mesh.masses(), 0.01, &mut values);
        assert!(dense(full.matrix(&values)).cholesky().is_some());
    }

    #[test]
    fn j_times_is_the_explicit_j_product() {
        let mesh = integer_cloth();
        let n = mesh.vertex_count();
        // Integer d: every product and sum is exact, so the comparison is exact.
        let d: Vec<Vector3<f64>> = (0..mesh.springs().len())
            .map(|s| Vector3::new((s % 5) as f64 - 2.0, (s % 3) as f64, -((s % 4) as f64)))
            .collect();
        let incidence = Incidence::new(n, mesh.springs());
        let mut out = vec![Vector3::zeros(); n];
        j_times(&incidence, mesh.springs(), &d, &mut out, true);
        let j = dense(j_matrix(n, mesh.springs()).as_ref());
        for a in 0..3 {
            let column = DVector::from_iterator(d.len(), d.iter().map(|v| v[a]));
            let expected = &j * column;
            for v in 0..n {
                assert_eq!(out[v][a], expected[v], "vertex {v} axis {a}");
            }
        }
    }

    fn mesh_and_pins() -> impl Strategy<Value = (hooke_mesh::SpringMesh<3>, Vec<u32>)> {
        spring_mesh_3d(3).prop_flat_map(|mesh| {
            let n = mesh.vertex_count();
            (Just(mesh), pinned_set(n))
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// The reduced matrix and right-hand side equal the full ones with pinned rows eliminated, and
        /// the reduced solve equals the full solve with the pinned values imposed.
        #[test]
        fn reduced_global_step_matches_the_full_one((mesh, pinned) in mesh_and_pins()) {
            let n = mesh.vertex_count();
            let h = 0.02;
            let free = FreeDofs::new(n, &pinned).unwrap();
            let full_pattern = LaplacianPattern::new(n, mesh.springs(), None);
            let mut full_values = full_pattern.new_values();
            full_pattern.system_into(mesh.springs(), mesh.masses(), h, &mut full_values);
            let a = dense(full_pattern.matrix(&full_values));
            let pattern = LaplacianPattern::new(n, mesh.springs(), Some(&free));
            let mut values = pattern.new_values();
            pattern.system_into(mesh.springs(), mesh.masses(), h, &mut values);
            let reduced = dense(pattern.matrix(&values));
            for (g, &w) in free.free_vertices().iter().enumerate() {
                for (f, &v) in free.free_vertices().iter().enumerate() {
                    prop_assert_eq!(reduced[(f, g)].to_bits(), a[(v as usize, w as usize)].to_bits());
                }
            }
            // A state, its local step and inertial target.
            let x: Vec<Vector3<f64>> = mesh.positions().iter().enumerate()
                .map(|(k, p)| p + Vector3::new((k as f64).sin(), (k as f64 * 0.7).cos(), 0.3) * 0.05)
                .collect();
            let y: Vec<Vector3<f64>> = x.iter().map(|p| p + Vector3::new(0.0, -0.01, 0.002)).collect();
            let mut d = vec![Vector3::zeros(); mesh.springs().len()];
            local_step(mesh.springs(), &x, &mut d, false);
            let mut rhs = vec![Vector3::zeros(); free.free_count()];
            pattern.rhs_into(mesh.springs(), &d, &y, &x, mesh.masses(), h, &mut rhs);
            // Full: h² J d + M y − (M + h² L) b with explicit matrices.
            let j = dense(j_matrix(n, mesh.springs()).as_ref());
            for axis in 0..3 {
                let dv = DVector::from_iterator(d.len(), d.iter().map(|v| v[axis]));
                let yv = DVector::from_iterator(n, y.iter().zip(mesh.masses()).map(|(p, m)| p[axis] * m));
                let b = DVector::from_iterator(n, (0..n).map(|v| if free.is_pinned(v) { x[v][axis] } else { 0.0 }));
                let unreduced = &j * dv * (h * h) + yv;
                let full_rhs = &unreduced - &a * &b;
                // Same terms summed in another order: agree to round-off of the largest term.
                let scale = full_rhs.amax().max(1.0);
                for (f, &v) in free.free_vertices().iter().enumerate() {
                    prop_assert!((rhs[f][axis] - full_rhs[v as usize]).abs() <= 1e-12 * scale);
                }
                // Full solve with the pinned rows replaced by x_p = b_p, against the reduced solve.
                let mut imposed = a.clone();
                // Rows of free vertices keep (M + h² L) x = h² J d + M y; pinned rows say x_p = b_p.
                let mut imposed_rhs = unreduced.clone();
                for &p in free.pinned() {
                    let p = p as usize;
                    // x_p = b_p, scaled like the row it replaces to keep the system well conditioned.
                    let diagonal = a[(p, p)];
                    imposed.row_mut(p).fill(0.0);
                    imposed[(p, p)] = diagonal;
                    imposed_rhs[p] = diagonal * b[p];
                }
                let full_x = imposed.lu().solve(&imposed_rhs).expect("the full system is regular");
                let reduced_rhs = DVector::from_iterator(free.free_count(), rhs.iter().map(|v| v[axis]));
                let reduced_x = reduced.clone().cholesky().expect("K (M + h² L) Kᵀ is SPD").solve(&reduced_rhs);
                let scale = full_x.amax().max(1.0);
                for (f, &v) in free.free_vertices().iter().enumerate() {
                    prop_assert!((reduced_x[f] - full_x[v as usize]).abs() <= 1e-9 * scale,
                        "free vertex {} axis {}: reduced {} vs full {}", v, axis, reduced_x[f], full_x[v as usize]);
                }
                for &p in free.pinned() {
                    // LU with pivoting reproduces an identity row only up to round-off amplified by
                    // the condition number, as for the free entries above.
                    prop_assert!((full_x[p as usize] - x[p as usize][axis]).abs() <= 1e-9 * scale);
                }
            }
        }
    }

    #[test]
    fn local_step_keeps_d_at_zero_length() {
        let mesh = cloth(3, 1.0).unwrap();
        let mut x = mesh.positions().to_vec();
        x[1] = x[0];
        let mut d = vec![Vector3::new(9.0, 9.0, 9.0); mesh.springs().len()];
        local_step(mesh.springs(), &x, &mut d, true);
        for (s, spring) in mesh.springs().iter().enumerate() {
            if (spring.i, spring.j) == (0, 1) {
                assert_eq!(d[s], Vector3::new(9.0, 9.0, 9.0));
            } else {
                assert!((d[s].norm() - spring.rest_length).abs() <= 1e-15 * spring.rest_length);
            }
        }
    }
}
