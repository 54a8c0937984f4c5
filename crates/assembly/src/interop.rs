//! Conversions of assembled faer matrices to other sparse matrix crates (cargo features
//! `nalgebra-sparse` and `sprs`). Each copies the structure and values once (O(nnz)); use them at
//! the boundary of a program, not in its time loop.

use faer::sparse::SparseColMatRef;

/// The column pointers, row indices and values of `m` as three owned vectors, compressed (columns
/// back to back) whatever faer's storage.
#[cfg(any(feature = "nalgebra-sparse", feature = "sprs"))]
fn csc_parts(m: SparseColMatRef<'_, usize, f64>) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
    let symbolic = m.symbolic();
    let mut col_ptr = Vec::with_capacity(m.ncols() + 1);
    col_ptr.push(0);
    let mut rows = Vec::with_capacity(symbolic.row_idx().len());
    let mut values = Vec::with_capacity(symbolic.row_idx().len());
    for j in 0..m.ncols() {
        let range = symbolic.col_range(j);
        rows.extend_from_slice(&symbolic.row_idx()[range.clone()]);
        values.extend_from_slice(&m.val()[range]);
        col_ptr.push(rows.len());
    }
    (col_ptr, rows, values)
}

/// Copy a faer CSC matrix (for example [`crate::HessianPattern::matrix`]) into a nalgebra-sparse
/// [`nalgebra_sparse::CscMatrix`], entry for entry.
///
/// # Panics
/// If a column of `m` repeats a row index (faer allows it; no matrix of this crate has it).
#[cfg(feature = "nalgebra-sparse")]
#[track_caller]
pub fn to_nalgebra_sparse(m: SparseColMatRef<'_, usize, f64>) -> nalgebra_sparse::CscMatrix<f64> {
    let (col_ptr, rows, values) = csc_parts(m);
    nalgebra_sparse::CscMatrix::try_from_unsorted_csc_data(
        m.nrows(),
        m.ncols(),
        col_ptr,
        rows,
        values,
    )
    .expect("to_nalgebra_sparse: a column repeats a row index")
}

/// Copy a faer CSC matrix (for example [`crate::HessianPattern::matrix`]) into a sprs
/// [`sprs::CsMat`] in CSC storage, entry for entry.
///
/// # Panics
/// If the row indices of a column of `m` are not strictly increasing (faer allows unsorted columns;
/// every matrix of this crate has sorted ones).
#[cfg(feature = "sprs")]
#[track_caller]
pub fn to_sprs(m: SparseColMatRef<'_, usize, f64>) -> sprs::CsMat<f64> {
    let (col_ptr, rows, values) = csc_parts(m);
    sprs::CsMat::try_new_csc((m.nrows(), m.ncols()), col_ptr, rows, values)
        .map_err(|(_, _, _, e)| e)
        .expect("to_sprs: row indices must be sorted and unique in each column")
}

#[cfg(all(test, feature = "nalgebra-sparse", feature = "sprs"))]
mod tests {
    //! The matrices of this crate against the same matrices built independently from per-spring
    //! triplets through COO → CSC (duplicates summed) in nalgebra-sparse and in sprs.

    use super::*;
    use crate::spring::hessian_block;
    use crate::{Definiteness, FreeDofs, HessianParams, HessianPattern, LaplacianPattern};
    use hooke_mesh::generators::{beam, cloth};
    use hooke_mesh::SpringMesh;
    use nalgebra::Vector3;

    /// Triplets of K (M + h² ∇²E) Kᵀ, four blocks per spring plus the masses, unsummed.
    fn hessian_triplets(
        mesh: &SpringMesh<3>,
        x: &[Vector3<f64>],
        free: &FreeDofs,
        h: f64,
    ) -> Vec<(usize, usize, f64)> {
        let mut t = Vec::new();
        for (f, &v) in free.free_vertices().iter().enumerate() {
            for a in 0..3 {
                t.push((3 * f + a, 3 * f + a, mesh.masses()[v as usize]));
            }
        }
        for s in mesh.springs() {
            let (i, j) = s.ends();
            let block = hessian_block(
                s.stiffness,
                s.rest_length,
                &(x[i] - x[j]),
                Definiteness::Exact,
            );
            for (p, q, sign) in [(i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)] {
                if let (Some(fp), Some(fq)) = (free.free_index(p), free.free_index(q)) {
                    for a in 0..3 {
                        for b in 0..3 {
                            t.push((3 * fp + a, 3 * fq + b, sign * h * h * block[(a, b)]));
                        }
                    }
                }
            }
        }
        t
    }

    /// Triplets of K L Kᵀ.
    fn laplacian_triplets(mesh: &SpringMesh<3>, free: &FreeDofs) -> Vec<(usize, usize, f64)> {
        let mut t = Vec::new();
        for s in mesh.springs() {
            let (i, j) = s.ends();
            for (p, q, sign) in [(i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)] {
                if let (Some(fp), Some(fq)) = (free.free_index(p), free.free_index(q)) {
                    t.push((fp, fq, sign * s.stiffness));
                }
            }
        }
        t
    }

    fn via_nalgebra(n: usize, t: &[(usize, usize, f64)]) -> nalgebra_sparse::CscMatrix<f64> {
        let mut coo = nalgebra_sparse::CooMatrix::new(n, n);
        for &(r, c, v) in t {
            coo.push(r, c, v);
        }
        nalgebra_sparse::CscMatrix::from(&coo)
    }

    fn via_sprs(n: usize, t: &[(usize, usize, f64)]) -> sprs::CsMat<f64> {
        let mut tri = sprs::TriMat::new((n, n));
        for &(r, c, v) in t {
            tri.add_triplet(r, c, v);
        }
        tri.to_csc()
    }

    /// Same pattern, values equal up to `tolerance` × the largest entry (the triplet sums run in
    /// another order than ours; with integer inputs pass 0).
    fn assert_close_nalgebra(
        a: &nalgebra_sparse::CscMatrix<f64>,
        b: &nalgebra_sparse::CscMatrix<f64>,
        tolerance: f64,
    ) {
        assert_eq!(a.pattern(), b.pattern(), "nalgebra-sparse: patterns differ");
        let scale = a.values().iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (k, (x, y)) in a.values().iter().zip(b.values()).enumerate() {
            assert!((x - y).abs() <= tolerance * scale, "value {k}: {x} vs {y}");
        }
    }

    fn assert_close_sprs(a: &sprs::CsMat<f64>, b: &sprs::CsMat<f64>, tolerance: f64) {
        assert_eq!(a.indptr(), b.indptr(), "sprs: column pointers differ");
        assert_eq!(a.indices(), b.indices(), "sprs: row indices differ");
        let scale = a.data().iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (k, (x, y)) in a.data().iter().zip(b.data()).enumerate() {
            assert!((x - y).abs() <= tolerance * scale, "value {k}: {x} vs {y}");
        }
    }

    #[test]
    fn hessian_equals_coo_assembly_in_nalgebra_sparse_and_sprs() {
        for (mesh, pinned) in [
            (cloth(6, 40.0).unwrap(), vec![0u32, 5]),
            (beam(1).unwrap(), vec![]),
        ] {
            let x: Vec<Vector3<f64>> = mesh
                .positions()
                .iter()
                .enumerate()
                .map(|(k, p)| {
                    p + Vector3::new((k as f64).sin(), (k as f64 * 0.3).cos(), 0.5) * 0.02
                })
                .collect();
            let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
            let pattern =
                HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), Some(&free));
            let mut values = pattern.new_values();
            let mut workspace = pattern.workspace();
            pattern.assemble_into(
                mesh.springs(),
                &x,
                mesh.masses(),
                0.01,
                HessianParams::default(),
                &mut workspace,
                &mut values,
            );
            let t = hessian_triplets(&mesh, &x, &free, 0.01);
            let n = pattern.dof_count();
            // A few ε of the largest entry: the same terms, summed in a different order.
            assert_close_nalgebra(
                &to_nalgebra_sparse(pattern.matrix(&values)),
                &via_nalgebra(n, &t),
                1e-14,
            );
            assert_close_sprs(&to_sprs(pattern.matrix(&values)), &via_sprs(n, &t), 1e-14);
        }
    }

    #[test]
    fn laplacian_equals_coo_assembly_exactly_with_integer_stiffness() {
        let mesh = cloth(7, 1.0)
            .unwrap()
            .map_stiffness(|s, _| (1 + s % 5) as f64)
            .unwrap();
        let free = FreeDofs::new(mesh.vertex_count(), &[0, 6, 20]).unwrap();
        let pattern = LaplacianPattern::new(mesh.vertex_count(), mesh.springs(), Some(&free));
        let mut values = pattern.new_values();
        pattern.laplacian_into(mesh.springs(), &mut values);
        let t = laplacian_triplets(&mesh, &free);
        let n = pattern.size();
        assert_close_nalgebra(
            &to_nalgebra_sparse(pattern.matrix(&values)),
            &via_nalgebra(n, &t),
            0.0,
        );
        assert_close_sprs(&to_sprs(pattern.matrix(&values)), &via_sprs(n, &t), 0.0);
    }
}
