//! Linear operators and preconditioners, so that an assembled matrix, a matrix-free product and a
//! factorisation all plug into the same iterative solvers.

use nalgebra::{DMatrix, SMatrix};

use crate::SolveError;

/// A square linear operator y = A x on vectors of length [`LinearOperator::dim`].
pub trait LinearOperator {
    /// The dimension n of the operator (n × n).
    fn dim(&self) -> usize;

    /// y = A x. `x` and `y` have length `dim()`; `y` is overwritten.
    fn apply(&self, x: &[f64], y: &mut [f64]);
}

/// An approximation of A⁻¹ applied to a residual: z = P⁻¹ r.
pub trait Preconditioner {
    /// z = P⁻¹ r; `r` and `z` have the operator's dimension; `z` is overwritten.
    fn apply(&self, r: &[f64], z: &mut [f64]);
}

impl LinearOperator for DMatrix<f64> {
    fn dim(&self) -> usize {
        assert_eq!(self.nrows(), self.ncols(), "a linear operator is square");
        self.nrows()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let result = self * nalgebra::DVectorView::from_slice(x, x.len());
        y.copy_from_slice(result.as_slice());
    }
}

impl<T: LinearOperator + ?Sized> LinearOperator for &T {
    fn dim(&self) -> usize {
        (**self).dim()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        (**self).apply(x, y)
    }
}

/// No preconditioning: z = r.
#[derive(Clone, Copy, Debug, Default)]
pub struct Identity;

impl Preconditioner for Identity {
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
    }
}

/// The inverted B × B diagonal blocks of a matrix (B = 3 for 3D vertices, as in seed 000):
/// z_i = A_ii⁻¹ r_i per block.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockJacobi<const B: usize> {
    inverses: Vec<SMatrix<f64, B, B>>,
}

impl<const B: usize> BlockJacobi<B> {
    /// Invert the given diagonal blocks.
    ///
    /// # Errors
    /// [`SolveError::SingularBlock`] naming the first block that cannot be inverted.
    pub fn from_blocks(
        blocks: impl IntoIterator<Item = SMatrix<f64, B, B>>,
    ) -> Result<Self, SolveError> {
        let inverses = blocks
            .into_iter()
            .enumerate()
            .map(|(block, m)| {
                m.try_inverse()
                    .filter(|inv| inv.iter().all(|c| c.is_finite()))
                    .ok_or(SolveError::SingularBlock { block })
            })
            .collect::<Result<_, _>>()?;
        Ok(BlockJacobi { inverses })
    }

    /// The diagonal blocks of a dense matrix (tests and small problems).
    ///
    /// # Errors
    /// As [`BlockJacobi::from_blocks`].
    ///
    /// # Panics
    /// If the matrix is not square with a size divisible by `B`.
    #[track_caller]
    pub fn from_dense(a: &DMatrix<f64>) -> Result<Self, SolveError> {
        assert!(
            a.is_square() && a.nrows() % B == 0,
            "a square matrix of whole {B}×{B} blocks"
        );
        Self::from_blocks(
            (0..a.nrows() / B).map(|k| a.fixed_view::<B, B>(B * k, B * k).into_owned()),
        )
    }

    /// The inverted blocks.
    pub fn inverses(&self) -> &[SMatrix<f64, B, B>] {
        &self.inverses
    }

    /// The dimension B × (number of blocks).
    pub fn dim(&self) -> usize {
        B * self.inverses.len()
    }
}

impl<const B: usize> Preconditioner for BlockJacobi<B> {
    #[track_caller]
    fn apply(&self, r: &[f64], z: &mut [f64]) {
        assert_eq!(r.len(), self.dim(), "residual length");
        for ((inv, r), z) in self
            .inverses
            .iter()
            .zip(r.chunks_exact(B))
            .zip(z.chunks_exact_mut(B))
        {
            let out = inv * nalgebra::SVectorView::<f64, B>::from_slice(r);
            z.copy_from_slice(out.as_slice());
        }
    }
}

/// Dot product summed in fixed chunks, so that the value does not depend on the thread count.
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    hooke_assembly::deterministic_sum(a.len(), true, |k| a[k] * b[k])
}
