//! Projective dynamics' global step, K (M + h² L) Kᵀ x_f = b for the D coordinates at once
//! (docs/solvers.md §6.1): by the prefactored matrix (a direct solve), or by conjugate gradients
//! preconditioned with a smoothed-aggregation V-cycle (the multilevel path, for systems whose
//! factor costs more than the cycles: no factor is stored).

use std::time::{Duration, Instant};

use faer::sparse::SparseColMatRef;
use faer::MatMut;
use nalgebra::SVector;

use super::PdError;
use crate::amg::{Amg, AmgColumns, AmgError, AmgParams};
use crate::cholesky::{CholeskyError, SparseCholesky};
use crate::forest_solve::{self, ForestSolve};
use crate::params::{self, ParamError};

/// How projective dynamics solves its global step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GlobalSolveKind {
    /// The multilevel path above [`MULTILEVEL_PD_UNKNOWNS`] free vertices, or when the factor
    /// would not fit in [`crate::CholeskyParams::memory_budget`]; the direct solve otherwise.
    #[default]
    Auto,
    /// The prefactored matrix (refused with [`CholeskyError::OverBudget`] when its factor would
    /// not fit in the memory budget).
    Direct,
    /// Conjugate gradients preconditioned with a V-cycle ([`PdMultilevelParams`]).
    Multilevel,
}

impl GlobalSolveKind {
    /// Every kind, in the order of their names' list.
    pub const ALL: [GlobalSolveKind; 3] = [
        GlobalSolveKind::Auto,
        GlobalSolveKind::Direct,
        GlobalSolveKind::Multilevel,
    ];

    /// The name in a scene file and on the command line: `auto`, `direct` or `multilevel`.
    pub fn name(self) -> &'static str {
        match self {
            GlobalSolveKind::Auto => "auto",
            GlobalSolveKind::Direct => "direct",
            GlobalSolveKind::Multilevel => "multilevel",
        }
    }
}

impl std::fmt::Display for GlobalSolveKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for GlobalSolveKind {
    type Err = String;

    /// One of the names of [`GlobalSolveKind::name`].
    fn from_str(text: &str) -> Result<Self, String> {
        GlobalSolveKind::ALL
            .into_iter()
            .find(|k| k.name() == text)
            .ok_or_else(|| format!("{text:?} is not a global solve: auto, direct or multilevel"))
    }
}

/// The free vertices (unknowns of the scalar global matrix) above which [`GlobalSolveKind::Auto`]
/// takes the multilevel path. Measured on this project's 2-core machine (docs/solvers.md §6.1):
/// on cloth-160 (25,598) ten PD iterations take about as long on either path, on cloth-320
/// (102,398) the multilevel path is 1.5–1.9× faster for PD, Chebyshev PD, Anderson PD and L-BFGS,
/// with a third less memory; the bound sits between, at the direct path's own switch from a
/// simplicial to a supernodal factor.
pub const MULTILEVEL_PD_UNKNOWNS: usize = 50_000;

/// The default [`crate::PdParams::multilevel_fill`]: 7. Measured on this project's 2-core machine
/// (docs/solvers.md §6.1): PD's factor fills 2–6 times its matrix on cloth and the beams up to
/// beam-8, where the factor's solves are as fast or faster (beam-8, fill 5.9: PD-10 5.5 ms against
/// 6.4 ms), and 8–19 times on the filled solids, where the multilevel path is the faster one
/// (bunny-drop, fill 8.1: 2× for the run; beam-16, fill 18: 2.9× per step and a set-up of 16 ms
/// against a 1.5 s factorisation).
pub const MULTILEVEL_PD_FILL: f64 = 7.0;

/// Settings of the multilevel global step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PdMultilevelParams {
    /// Stop each coordinate's CG when its residual is at most `tolerance` times its residual at
    /// the initial guess (the current iterate: that residual is A times the exact step, so this
    /// bounds the step's relative error). Default 0.5: one CG iteration a step on cloth-160 to
    /// cloth-640, whose ten PD iterations then end within 0.13 % of the direct path's decrease of
    /// Φ (0.1 takes twice the iterations for less than half that difference; docs/solvers.md
    /// §6.1).
    pub tolerance: f64,
    /// CG iterations per global step at most (the step is a descent step whatever the count).
    /// Default 20.
    pub max_iterations: usize,
    /// The hierarchy's settings (its near-nullspace is the constants), read when a hierarchy is
    /// built: by [`crate::ProjectiveDynamics::new`], and for contact's weighted matrix at the
    /// first step with an active vertex; a refill keeps them. `tolerance` and `max_iterations`
    /// are read at every solve.
    pub amg: AmgParams,
}

impl Default for PdMultilevelParams {
    fn default() -> Self {
        PdMultilevelParams {
            tolerance: 0.5,
            max_iterations: 20,
            amg: AmgParams::default(),
        }
    }
}

impl PdMultilevelParams {
    /// Check the fields: `tolerance` finite in [0, 1), `max_iterations` ≥ 1, and
    /// [`AmgParams::validate`].
    ///
    /// # Errors
    /// [`ParamError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        params::real(
            "PdMultilevelParams::tolerance",
            self.tolerance,
            (0.0..1.0).contains(&self.tolerance),
            "in [0, 1)",
        )?;
        params::at_least(
            "PdMultilevelParams::max_iterations",
            self.max_iterations,
            1,
            "at least 1",
        )?;
        self.amg.validate()
    }
}

/// The global matrix, prepared for solves with D right-hand sides.
#[derive(Debug)]
pub(crate) enum GlobalSolve<const D: usize> {
    Direct(Box<DirectSolve<D>>),
    Multilevel(Box<MultilevelSolve<D>>),
}

impl<const D: usize> GlobalSolve<D> {
    /// Prepare `matrix` (the pattern of the analysis); a hierarchy built here takes the settings
    /// `params.amg`. After a failure no stale factor or hierarchy is used.
    pub(crate) fn factor(
        &mut self,
        matrix: SparseColMatRef<'_, usize, f64>,
        params: &PdMultilevelParams,
    ) -> Result<(), PdError> {
        match self {
            GlobalSolve::Direct(d) => Ok(d.factor(matrix)?),
            GlobalSolve::Multilevel(m) => Ok(m.prepare(matrix, &params.amg)?),
        }
    }

    /// Set the initial guess of the next solve to `guess(free index)` (the multilevel path
    /// starts there, by default from its last solution; the direct path needs none).
    pub(crate) fn guess(&mut self, guess: impl Fn(usize) -> SVector<f64, D>) {
        if let GlobalSolve::Multilevel(m) = self {
            for (f, x) in m.x.iter_mut().enumerate() {
                *x = guess(f);
            }
        }
    }

    /// Solve for the D columns of `rhs` (one D-vector per free vertex) and hand each solution to
    /// `out(free index, solution)`, on two threads if `threads` (same bits either way); the
    /// multilevel path stops its CG as `params` says.
    pub(crate) fn solve(
        &mut self,
        rhs: &[SVector<f64, D>],
        threads: bool,
        params: &PdMultilevelParams,
        out: impl FnMut(usize, SVector<f64, D>),
    ) {
        match self {
            GlobalSolve::Direct(d) => d.solve(rhs, threads, out),
            GlobalSolve::Multilevel(m) => m.solve(rhs, params, out),
        }
    }

    /// z ≈ A⁻¹ r as a fixed linear operator, for a preconditioner: the direct solve, or on the
    /// multilevel path one V-cycle (symmetric positive definite, like A⁻¹; a CG solve to a
    /// tolerance would not be linear in r). Each solution goes to `out(free index, z)`.
    pub(crate) fn precondition(
        &mut self,
        rhs: &[SVector<f64, D>],
        threads: bool,
        mut out: impl FnMut(usize, SVector<f64, D>),
    ) {
        match self {
            GlobalSolve::Direct(d) => d.solve(rhs, threads, out),
            GlobalSolve::Multilevel(m) => {
                let MultilevelSolve { hierarchy, z, .. } = &mut **m;
                let (amg, work) = ready(hierarchy);
                amg.apply_columns(work, rhs, z);
                for (f, z) in z.iter().enumerate() {
                    out(f, *z);
                }
            }
        }
    }

    /// The prefactored matrix, on the direct path.
    pub(crate) fn cholesky(&self) -> Option<&SparseCholesky> {
        match self {
            GlobalSolve::Direct(d) => Some(&d.cholesky),
            GlobalSolve::Multilevel(_) => None,
        }
    }

    /// Time of the last factorisation or hierarchy set-up.
    pub(crate) fn prepare_time(&self) -> Duration {
        match self {
            GlobalSolve::Direct(d) => d.cholesky.factor_time(),
            GlobalSolve::Multilevel(m) => m.prepare_time,
        }
    }

    /// CG iterations of the last solve (0 on the direct path).
    pub(crate) fn last_iterations(&self) -> usize {
        match self {
            GlobalSolve::Direct(_) => 0,
            GlobalSolve::Multilevel(m) => m.last_iterations,
        }
    }

    /// Whether the direct split solve pays for a fork: a factor of at least
    /// [`forest_solve::SPLIT_MIN_VALUES`] stored values.
    pub(crate) fn is_large(&self) -> bool {
        match self {
            GlobalSolve::Direct(d) => d.cholesky.factor_nnz() >= forest_solve::SPLIT_MIN_VALUES,
            GlobalSolve::Multilevel(_) => false,
        }
    }
}

/// The prefactored global matrix and the buffers of its D-column solve.
#[derive(Debug)]
pub(crate) struct DirectSolve<const D: usize> {
    pub(crate) cholesky: SparseCholesky,
    /// Column-major right-hand sides for the supernodal solve.
    columns: Vec<f64>,
    /// The factor laid out for the split solve of the D coordinates (simplicial factors), and
    /// the right-hand sides in its order.
    forest: Option<ForestSolve<D>>,
    ordered: Vec<SVector<f64, D>>,
}

impl<const D: usize> DirectSolve<D> {
    pub(crate) fn new(cholesky: SparseCholesky) -> Self {
        let n = cholesky.dim();
        DirectSolve {
            cholesky,
            columns: vec![0.0; D * n],
            forest: None,
            ordered: Vec::new(),
        }
    }

    fn factor(&mut self, matrix: SparseColMatRef<'_, usize, f64>) -> Result<(), CholeskyError> {
        // The layout is kept across factorisations (the pattern does not change), but only a
        // successful one refills it.
        let layout = self.forest.take();
        self.cholesky.factorize(matrix)?;
        self.forest = match (layout, self.cholesky.llt_values()) {
            (Some(mut forest), Some(values)) => {
                forest.refill(values);
                Some(forest)
            }
            _ => self.cholesky.forest_solve(),
        };
        let rows = self.forest.as_ref().map_or(0, ForestSolve::dim);
        self.ordered.resize(rows, SVector::zeros());
        Ok(())
    }

    fn solve(
        &mut self,
        rhs: &[SVector<f64, D>],
        threads: bool,
        mut out: impl FnMut(usize, SVector<f64, D>),
    ) {
        let n = rhs.len();
        if let Some(forest) = &mut self.forest {
            for (o, &f) in self.ordered.iter_mut().zip(forest.order()) {
                *o = rhs[f as usize];
            }
            forest.solve_ordered(&mut self.ordered, threads);
            for (new, &f) in self.ordered.iter().zip(forest.order()) {
                out(f as usize, *new);
            }
        } else {
            for (f, r) in rhs.iter().enumerate() {
                for a in 0..D {
                    self.columns[a * n + f] = r[a];
                }
            }
            self.cholesky
                .solve_in_place(MatMut::from_column_major_slice_mut(&mut self.columns, n, D));
            for f in 0..n {
                out(
                    f,
                    SVector::<f64, D>::from_fn(|a, _| self.columns[a * n + f]),
                );
            }
        }
    }
}

/// The multilevel global step: the D coordinates' conjugate gradients in lockstep (one product
/// with the matrix and one V-cycle of [`Amg::apply_columns`] per iteration serve all D), each
/// coordinate with its own step lengths and its own stop. Started from the current iterate, every
/// CG iteration lowers the global step's quadratic, so projective dynamics keeps its monotone
/// descent whatever the iteration count.
#[derive(Debug)]
pub(crate) struct MultilevelSolve<const D: usize> {
    /// The hierarchy and its D-column cycle's buffers, once built and while its last refill
    /// succeeded.
    hierarchy: Option<(Amg, AmgColumns<D>)>,
    x: Vec<SVector<f64, D>>,
    r: Vec<SVector<f64, D>>,
    z: Vec<SVector<f64, D>>,
    p: Vec<SVector<f64, D>>,
    ap: Vec<SVector<f64, D>>,
    prepare_time: Duration,
    last_iterations: usize,
}

/// The hierarchy of a successful preparation.
fn ready<const D: usize>(
    hierarchy: &mut Option<(Amg, AmgColumns<D>)>,
) -> (&mut Amg, &mut AmgColumns<D>) {
    let (amg, work) = hierarchy
        .as_mut()
        .expect("the multilevel global step needs a successful refactor first");
    (amg, work)
}

impl<const D: usize> MultilevelSolve<D> {
    pub(crate) fn new(n: usize) -> Self {
        let zero = || vec![SVector::zeros(); n];
        MultilevelSolve {
            hierarchy: None,
            x: zero(),
            r: zero(),
            z: zero(),
            p: zero(),
            ap: zero(),
            prepare_time: Duration::ZERO,
            last_iterations: 0,
        }
    }

    /// Build the hierarchy for `matrix` with `params` (the first time), or refill it (same
    /// pattern, the settings it was built with).
    fn prepare(
        &mut self,
        matrix: SparseColMatRef<'_, usize, f64>,
        params: &AmgParams,
    ) -> Result<(), AmgError> {
        let start = Instant::now();
        let result = match self.hierarchy.take() {
            Some((mut amg, work)) => amg.refresh(matrix).map(|()| (amg, work)),
            None => {
                let ones = vec![1.0; matrix.nrows()];
                Amg::new(matrix, 1, &ones, *params).map(|amg| {
                    let work = amg.columns_workspace();
                    (amg, work)
                })
            }
        };
        self.prepare_time = start.elapsed();
        // A failed refill leaves a hierarchy that must not be applied: it is dropped.
        self.hierarchy = Some(result?);
        Ok(())
    }

    /// Solve from the guess in `x` (the last solution unless [`GlobalSolve::guess`] set one).
    fn solve(
        &mut self,
        rhs: &[SVector<f64, D>],
        params: &PdMultilevelParams,
        mut out: impl FnMut(usize, SVector<f64, D>),
    ) {
        let (amg, work) = ready(&mut self.hierarchy);
        amg.product_columns(&self.x, &mut self.r);
        for (r, b) in self.r.iter_mut().zip(rhs) {
            *r = b - *r;
        }
        let norms = |v: &[SVector<f64, D>]| column_dots(v, v).map(f64::sqrt);
        let start = norms(&self.r);
        let target = start * params.tolerance;
        // Done where the residual is at the target already (or not a number: the NaN reaches the
        // caller's iterate through the solution).
        let above = |residual: f64, target: f64| residual > target;
        let mut done = SVector::<bool, D>::from_fn(|a, _| !above(start[a], target[a]));
        let mut rz = SVector::<f64, D>::zeros();
        let mut iterations = 0;
        while iterations < params.max_iterations && !done.iter().all(|&d| d) {
            amg.apply_columns(work, &self.r, &mut self.z);
            let rz_next = column_dots(&self.r, &self.z);
            let beta = SVector::<f64, D>::from_fn(|a, _| {
                if iterations == 0 || done[a] {
                    0.0
                } else {
                    rz_next[a] / rz[a]
                }
            });
            rz = rz_next;
            for (p, z) in self.p.iter_mut().zip(&self.z) {
                *p = z + p.component_mul(&beta);
            }
            amg.product_columns(&self.p, &mut self.ap);
            let curvature = column_dots(&self.p, &self.ap);
            let alpha =
                SVector::<f64, D>::from_fn(|a, _| if done[a] { 0.0 } else { rz[a] / curvature[a] });
            for ((x, r), (p, ap)) in self
                .x
                .iter_mut()
                .zip(self.r.iter_mut())
                .zip(self.p.iter().zip(&self.ap))
            {
                *x += p.component_mul(&alpha);
                *r -= ap.component_mul(&alpha);
            }
            iterations += 1;
            let residual = norms(&self.r);
            for a in 0..D {
                done[a] = done[a] || !above(residual[a], target[a]);
            }
        }
        self.last_iterations = iterations;
        for (f, x) in self.x.iter().enumerate() {
            out(f, *x);
        }
    }
}

/// Per column a, Σ_i u_i[a] v_i[a], each a deterministic sum (the same bits on any thread count),
/// all D in one pass over u and v.
fn column_dots<const D: usize>(u: &[SVector<f64, D>], v: &[SVector<f64, D>]) -> SVector<f64, D> {
    hooke_assembly::deterministic_sum_lanes(u.len(), true, |i| u[i].component_mul(&v[i]))
}
