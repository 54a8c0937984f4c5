//! Linear operators and preconditioners, so that an assembled matrix, a matrix-free product and a
//! factorisation all plug into the same iterative solvers.

use faer::sparse::{SparseColMat, SparseColMatRef};
use nalgebra::{DMatrix, SMatrix};
use rayon::prelude::*;

use crate::SolveError;

/// A square linear operator y = A x on vectors of length [`LinearOperator::dim`].
pub trait LinearOperator {
    /// The dimension n of the operator (n × n).
    fn dim(&self) -> usize;

    /// y = A x. `x` and `y` have length `dim()`; `y` is overwritten.
    fn apply(&self, x: &[f64], y: &mut [f64]);
}

/// An approximation of A⁻¹ applied to a residual: z = P⁻¹ r. `&mut self`, because a preconditioner
/// may own scratch memory (a factorisation does).
pub trait Preconditioner {
    /// z = P⁻¹ r; `r` and `z` have the operator's dimension; `z` is overwritten.
    fn apply(&mut self, r: &[f64], z: &mut [f64]);
}

impl<P: Preconditioner + ?Sized> Preconditioner for &mut P {
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        (**self).apply(r, z)
    }
}

/// y = A x for a general sparse matrix in faer's CSC format (serial scatter over columns).
impl LinearOperator for SparseColMatRef<'_, usize, f64> {
    #[track_caller]
    fn dim(&self) -> usize {
        assert_eq!(self.nrows(), self.ncols(), "a linear operator is square");
        self.nrows()
    }

    #[track_caller]
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        assert!(
            x.len() == self.ncols() && y.len() == self.nrows(),
            "vector lengths"
        );
        y.fill(0.0);
        for (j, &xj) in x.iter().enumerate() {
            for (&i, &v) in self.row_idx_of_col_raw(j).iter().zip(self.val_of_col(j)) {
                y[i] += v * xj;
            }
        }
    }
}

impl LinearOperator for SparseColMat<usize, f64> {
    fn dim(&self) -> usize {
        self.as_ref().dim()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.as_ref().apply(x, y)
    }
}

/// A symmetric sparse matrix in full storage, applied as y_j = (column j)·x: because A = Aᵀ this is
/// A x, and each output entry is a gather, so the product runs in parallel and gives the same bits
/// whatever the thread count. The caller vouches for the symmetry (hooke's assembled Hessians and
/// M + h²L are symmetric by construction).
#[derive(Clone, Copy, Debug)]
pub struct Symmetric<'a>(pub SparseColMatRef<'a, usize, f64>);

impl LinearOperator for Symmetric<'_> {
    #[track_caller]
    fn dim(&self) -> usize {
        self.0.dim()
    }

    #[track_caller]
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let a = self.0;
        assert!(
            x.len() == a.ncols() && y.len() == a.nrows(),
            "vector lengths"
        );
        let column = |(j, yj): (usize, &mut f64)| {
            *yj = a
                .row_idx_of_col_raw(j)
                .iter()
                .zip(a.val_of_col(j))
                .map(|(&i, &v)| v * x[i])
                .sum();
        };
        if y.len() >= 4096 {
            y.par_iter_mut()
                .enumerate()
                .with_min_len(1024)
                .for_each(column);
        } else {
            y.iter_mut().enumerate().for_each(column);
        }
    }
}

/// A Cholesky factorisation (of A, or of a nearby matrix such as M + h²L for a Newton system) as a
/// preconditioner: z = L⁻ᵀ L⁻¹ r.
impl Preconditioner for crate::SparseCholesky {
    #[track_caller]
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
        self.solve_slice(z);
    }
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
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
    }
}

/// The inverted B × B diagonal blocks of a matrix (B = 3 for 3D vertices; docs/solvers.md §2.2):
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
            .map(|(block, m)| invert(block, m))
            .collect::<Result<_, _>>()?;
        Ok(BlockJacobi { inverses })
    }

    /// `count` identity blocks: a preconditioner of the right size that does nothing yet, to be
    /// filled by [`BlockJacobi::refill`] before each solve (allocates once, here).
    pub fn identity(count: usize) -> Self {
        BlockJacobi {
            inverses: vec![SMatrix::identity(); count],
        }
    }

    /// Invert new diagonal blocks into the existing storage: the same number of blocks, new values
    /// (a matrix refilled on a fixed pattern, a new step). No allocation.
    ///
    /// # Errors
    /// [`SolveError::SingularBlock`] naming the first block that cannot be inverted. The blocks
    /// before it then hold the new inverses and the others the old ones: refill again before
    /// applying the preconditioner.
    ///
    /// # Panics
    /// If `blocks` yields another number of blocks than [`BlockJacobi::block_count`].
    #[track_caller]
    pub fn refill(
        &mut self,
        blocks: impl IntoIterator<Item = SMatrix<f64, B, B>>,
    ) -> Result<(), SolveError> {
        let count = self.inverses.len();
        let mut blocks = blocks.into_iter();
        for (block, inverse) in self.inverses.iter_mut().enumerate() {
            let m = blocks
                .next()
                .unwrap_or_else(|| panic!("BlockJacobi::refill: {block} blocks given for {count}"));
            *inverse = invert(block, m)?;
        }
        assert!(
            blocks.next().is_none(),
            "BlockJacobi::refill: more than {count} blocks given"
        );
        Ok(())
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

    /// The number of blocks.
    pub fn block_count(&self) -> usize {
        self.inverses.len()
    }

    /// The dimension B × (number of blocks).
    pub fn dim(&self) -> usize {
        B * self.inverses.len()
    }
}

/// The inverse of diagonal block number `block`, if it exists and is finite.
fn invert<const B: usize>(
    block: usize,
    m: SMatrix<f64, B, B>,
) -> Result<SMatrix<f64, B, B>, SolveError> {
    m.try_inverse()
        .filter(|inv| inv.iter().all(|c| c.is_finite()))
        .ok_or(SolveError::SingularBlock { block })
}

impl<const B: usize> Preconditioner for BlockJacobi<B> {
    #[track_caller]
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        self.apply_blocks(r, z)
    }
}

impl<const B: usize> BlockJacobi<B> {
    /// z_i = A_ii⁻¹ r_i for every block.
    ///
    /// # Panics
    /// If `r` or `z` is not of length [`BlockJacobi::dim`].
    #[track_caller]
    pub fn apply_blocks(&self, r: &[f64], z: &mut [f64]) {
        assert_eq!(z.len(), self.dim(), "output length");
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
