//! Anderson-accelerated projective dynamics (Peng, Deng, Zhang, Liu, "Anderson Acceleration for
//! Geometry Optimization and Physics Simulation", ACM TOG 2018; docs/solvers.md §7.1).
//!
//! One PD iteration is a fixed-point map x ↦ G(x) (local step, then global solve; docs/model.md
//! §6.8). Anderson acceleration (type II) keeps the last m differences of the residuals
//! fᵢ = G(xᵢ) − xᵢ and of the map's values gᵢ = G(xᵢ),
//!
//! Δfᵢ = fᵢ₊₁ − fᵢ, Δgᵢ = gᵢ₊₁ − gᵢ (i = k − m … k − 1),
//!
//! finds the combination θ that minimises |f_k − ΔF θ|₂ (a least-squares problem solved by its
//! m × m normal equations), and proposes x_AA = g_k − ΔG θ, the point the secant model of G
//! predicts to be nearest the fixed point.
//!
//! PD decreases Φ at every iteration (docs/model.md §6.8); Anderson's point need not. The energy
//! guard: x_AA is accepted only if Φ(x_AA) ≤ Φ(G(x_k)), computed term by term
//! ([`ProjectiveDynamics::objective_change`], no cancellation of two values of Φ), so that every
//! accepted point is at least as good as the plain PD iterate it replaces. Otherwise the iterate is
//! the plain one, G(x_k), and the differences are dropped (the history restarts from the last
//! pair (f_k, g_k)). Hence Φ(x_{k+1}) ≤ Φ(G(x_k)) ≤ Φ(x_k): Φ never increases but for the rounding
//! of PD's global solve, as for plain PD.
//!
//! Stops are PD's: the iteration budget, or the estimated distance to the solution at most
//! `tolerance` · h by PD's own rule ([`FixedPointError`]). Anderson's changes are irregular and
//! their ratios underestimate the distance left, so the estimate on the accepted points' changes
//! only proposes a stop: twenty plain PD iterations from there must confirm it with PD's rule on
//! their changes (otherwise the acceleration resumes, its history kept).
//!
//! The history lives in the solver (2 m position vectors and an m × m matrix, sized at
//! construction): the iterations do not allocate. All sums are serial and in a fixed order, and
//! [`ProjectiveDynamics::objective_change`] is deterministic: the same input gives the same bits.

use std::time::{Duration, Instant};

use hooke_mesh::Spring;
use nalgebra::SVector;

use crate::chebyshev::largest_change;
use crate::params::{self, ParamError, HISTORY_RESERVE};
use crate::projective::{FixedPointError, PdError, ProjectiveDynamics};
use crate::report::StopReason;

/// Settings of [`AndersonPd`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AndersonParams {
    /// Iterations per step (each one PD iteration and, once a difference is stored, one
    /// evaluation of the change of Φ). Default 10.
    pub max_iterations: usize,
    /// m, the number of residual differences kept (the window). Default 8: on cloth-10, cloth-40
    /// and beam-4, windows 2, 3, 5, 8 and 12 at 10–100 iterations, 8 reached the lowest or
    /// nearly the lowest error at 20 iterations and beyond (benches/results/pd-anderson.md); a
    /// larger window costs two more vector passes per difference.
    pub window: usize,
    /// Stop when the estimated distance to the solution divided by h is at most `tolerance` (m/s),
    /// as [`crate::PdParams::tolerance`] ([`FixedPointError`] on the changes of the accepted
    /// iterates). Default 0: always run `max_iterations`.
    pub tolerance: f64,
    /// Record Φ after every iteration in the report (one more evaluation of the change of Φ per
    /// iteration). Default false: benchmarks measure the bare iteration.
    pub record_objective: bool,
}

impl Default for AndersonParams {
    fn default() -> Self {
        AndersonParams {
            max_iterations: 10,
            window: 8,
            tolerance: 0.0,
            record_objective: false,
        }
    }
}

/// The most iterations [`AndersonParams::max_iterations`] may ask for.
pub const ANDERSON_MAX_ITERATIONS: usize = 1 << 24;

/// The largest window [`AndersonParams::window`] may ask for: the normal equations of more
/// differences than this are too ill-conditioned to help, and each one costs two position
/// vectors of memory.
pub const ANDERSON_MAX_WINDOW: usize = 64;

/// A stored difference is dropped from the least-squares solve when the part of it not explained
/// by the newer ones has a squared norm below this fraction of its own (the differences are
/// normalised, so this is sin² of its angle to their span): the normal equations square the
/// condition number, and a nearly dependent difference would only amplify rounding.
const DEPENDENT_DIFFERENCE: f64 = 1e-10;

/// Plain PD iterations that check a proposed stop, PD's rule ([`FixedPointError`]) applied to the
/// last of them. Its rate estimate needs the slowest mode to dominate the changes, which takes
/// some iterations from an accelerated point: on cloth-10 (the anderson tests, window 8) the
/// stop after 10 left up to 2.07 T to go, after 20 at most 1.74 T (plain PD's own: 1.25 T).
const VERIFY_ITERATIONS: usize = 20;

impl AndersonParams {
    /// Check every field.
    ///
    /// # Errors
    /// [`ParamError`] naming the first field outside its range: `max_iterations` in
    /// 1..=[`ANDERSON_MAX_ITERATIONS`], `window` in 1..=[`ANDERSON_MAX_WINDOW`], `tolerance`
    /// finite and ≥ 0.
    pub fn validate(&self) -> Result<(), ParamError> {
        params::count_in(
            "AndersonParams::max_iterations",
            self.max_iterations,
            1,
            ANDERSON_MAX_ITERATIONS,
            "in 1 ..= 2^24",
        )?;
        params::count_in(
            "AndersonParams::window",
            self.window,
            1,
            ANDERSON_MAX_WINDOW,
            "in 1 ..= 64",
        )?;
        params::non_negative("AndersonParams::tolerance", self.tolerance)
    }
}

/// The account of one accelerated solve.
#[derive(Clone, Debug, PartialEq)]
pub struct AndersonReport {
    /// Iterations performed (each one PD iteration).
    pub iterations: usize,
    /// Iterations whose Anderson point was accepted.
    pub accepted: usize,
    /// Iterations whose Anderson point the energy guard refused (Φ(x_AA) > Φ(G(x_k)), or not
    /// finite): the plain PD iterate was taken and the differences dropped.
    pub rejected: usize,
    /// If [`AndersonParams::record_objective`]: Φ before the first iteration and after each one
    /// (J·s²), the first evaluated and the others accumulated from the exactly computed changes
    /// ([`ProjectiveDynamics::objective_change`]); empty otherwise.
    pub objectives: Vec<f64>,
    /// Largest position change (m) of each iteration's accepted point.
    pub changes: Vec<f64>,
    /// Why it stopped: [`StopReason::Converged`] (tolerance met), [`StopReason::IterationLimit`]
    /// (the budget, PD's usual stop) or [`StopReason::NonFinite`] (a position change is NaN or
    /// infinite).
    pub stop: StopReason,
    /// Wall time of the solve.
    pub wall_time: Duration,
}

/// Anderson-accelerated projective dynamics over a [`ProjectiveDynamics`] (whose factor and
/// iteration it uses), with its history kept in preallocated buffers across steps.
#[derive(Clone, Debug)]
pub struct AndersonPd<const D: usize> {
    params: AndersonParams,
    /// Vertices of the meshes this solver was sized for.
    vertex_count: usize,
    /// x_k, and the plain iterate G(x_k), per vertex.
    previous: Vec<SVector<f64, D>>,
    plain: Vec<SVector<f64, D>>,
    /// f and g of the last iterate, per vertex (free vertices only are read).
    last_f: Vec<SVector<f64, D>>,
    last_g: Vec<SVector<f64, D>>,
    /// The window's normalised differences Δf and Δg: column j at [j n, (j + 1) n), a ring whose
    /// newest column is `newest`.
    delta_f: Vec<SVector<f64, D>>,
    delta_g: Vec<SVector<f64, D>>,
    /// Columns stored (≤ m), and the ring slot of the newest one.
    stored: usize,
    newest: usize,
    /// ΔFᵀΔF over the ring's slots (m × m, row-major; entries of unstored slots are stale).
    gram: Vec<f64>,
    /// Cholesky factor of the Gram matrix in age order (newest first), the right-hand side
    /// ΔFᵀ f_k and the solution θ, in the same order.
    factor: Vec<f64>,
    theta: Vec<f64>,
    kept: Vec<bool>,
}

impl<const D: usize> AndersonPd<D> {
    /// Accelerated PD for meshes of `vertex_count` vertices.
    ///
    /// # Errors
    /// [`ParamError`] if `params` is invalid.
    pub fn new(vertex_count: usize, params: AndersonParams) -> Result<Self, ParamError> {
        params.validate()?;
        let m = params.window;
        let zeros = |len: usize| vec![SVector::<f64, D>::zeros(); len];
        Ok(AndersonPd {
            params,
            vertex_count,
            previous: zeros(vertex_count),
            plain: zeros(vertex_count),
            last_f: zeros(vertex_count),
            last_g: zeros(vertex_count),
            delta_f: zeros(m * vertex_count),
            delta_g: zeros(m * vertex_count),
            stored: 0,
            newest: 0,
            gram: vec![0.0; m * m],
            factor: vec![0.0; m * m],
            theta: vec![0.0; m],
            kept: vec![false; m],
        })
    }

    /// The settings.
    pub fn params(&self) -> AndersonParams {
        self.params
    }

    /// Solve the step with inertial target `y` as [`ProjectiveDynamics::solve`] does (`x` the
    /// initial guess with the pinned vertices in place, or the step's start with contact, and the
    /// result), accelerated. With contact, Anderson's point is limited as PD's iterates are, so
    /// that every iterate is outside every obstacle.
    ///
    /// # Errors
    /// [`PdError::Factorization`] if the contact solve's matrix does not factor.
    ///
    /// # Panics
    /// If the lengths of `springs`, `y` or `x` do not match `pd`'s system or this solver's size.
    #[track_caller]
    pub fn solve(
        &mut self,
        pd: &mut ProjectiveDynamics<D>,
        springs: &[Spring],
        y: &[SVector<f64, D>],
        x: &mut [SVector<f64, D>],
    ) -> Result<AndersonReport, PdError> {
        assert_eq!(x.len(), self.vertex_count, "one position per vertex");
        let start = Instant::now();
        let p = self.params;
        let record = p.record_objective;
        let reserve = p.max_iterations.min(HISTORY_RESERVE);
        let mut report = AndersonReport {
            iterations: 0,
            accepted: 0,
            rejected: 0,
            objectives: Vec::with_capacity(if record { reserve + 1 } else { 0 }),
            changes: Vec::with_capacity(reserve),
            stop: StopReason::IterationLimit,
            wall_time: Duration::ZERO,
        };
        pd.begin_step(springs, y, x)?;
        let mut phi = 0.0;
        if record {
            phi = pd.objective(springs, y, x);
            report.objectives.push(phi);
        }
        // A new step: no pair yet.
        self.stored = 0;
        let mut has_last = false;
        let mut largest_displacement: f64 = 0.0;
        let tolerance = p.tolerance * pd.time_step();
        // The estimate on the accepted points' changes, which only proposes a stop: Anderson's
        // changes are irregular, and their ratios underestimate the distance left (12.7 T on
        // cloth-10 at T = 1e-2 m/s, the anderson tests). The stop itself is PD's rule on plain PD
        // iterations from the proposed point (`verify`, fresh for each proposal).
        let mut error = FixedPointError::default();
        let mut verify: Option<(FixedPointError, usize)> = None;
        while report.iterations < p.max_iterations {
            self.previous.copy_from_slice(x);
            let plain_change = pd.iteration(springs, y, x, &mut largest_displacement);
            report.iterations += 1;
            let mut change = plain_change;
            // x now holds g_k = G(x_k); f_k = g_k − x_k.
            if plain_change.is_finite() {
                if has_last {
                    self.push_difference(pd.free_vertices(), x);
                }
                self.remember(pd.free_vertices(), x);
                has_last = true;
                if verify.is_none()
                    && self.stored > 0
                    && self.solve_least_squares(pd.free_vertices())
                {
                    self.plain.copy_from_slice(x);
                    self.extrapolate(pd.free_vertices(), x);
                    pd.limit_moves(&self.previous, x);
                    // Φ(x_AA) − Φ(G(x_k)); NaN (a non-finite point) counts as a rise.
                    let rise = pd.objective_change(springs, y, &self.plain, x);
                    if rise <= 0.0 {
                        report.accepted += 1;
                        change = largest_change(pd.free_vertices(), &self.previous, x);
                    } else {
                        x.copy_from_slice(&self.plain);
                        report.rejected += 1;
                        self.stored = 0;
                    }
                }
            }
            if record {
                phi += pd.objective_change(springs, y, &self.previous, x);
                report.objectives.push(phi);
            }
            report.changes.push(change);
            if !change.is_finite() {
                report.stop = StopReason::NonFinite;
                break;
            }
            match &mut verify {
                None => {
                    if error.after(change) <= tolerance {
                        verify = Some((FixedPointError::default(), 0));
                    }
                }
                Some((plain, count)) => {
                    *count += 1;
                    let estimate = plain.after(change);
                    if *count >= VERIFY_ITERATIONS && estimate <= tolerance {
                        report.stop = StopReason::Converged;
                        break;
                    }
                    if *count >= VERIFY_ITERATIONS {
                        // PD's rule does not confirm: accelerate again.
                        verify = None;
                        error = FixedPointError::default();
                    }
                }
            }
        }
        report.wall_time = start.elapsed();
        Ok(report)
    }

    /// Store the newest normalised differences Δf = f_k − f_(k−1), Δg = g_k − g_(k−1) (with
    /// f_k = g_k − x_k, `g` = g_k and x_k in `previous`) in the ring, and their Gram row. A zero
    /// or non-finite difference (no change of the residual) empties the ring instead: the slot it
    /// was written to may have held the oldest stored difference.
    fn push_difference(&mut self, free: &[u32], g: &[SVector<f64, D>]) {
        let (n, m) = (self.vertex_count, self.params.window);
        let slot = if self.stored == 0 {
            0
        } else {
            (self.newest + 1) % m
        };
        let column = slot * n;
        let mut norm2 = 0.0;
        for &v in free {
            let v = v as usize;
            let df = (g[v] - self.previous[v]) - self.last_f[v];
            self.delta_f[column + v] = df;
            self.delta_g[column + v] = g[v] - self.last_g[v];
            norm2 += df.norm_squared();
        }
        if !(norm2 > 0.0 && norm2.is_finite()) {
            self.stored = 0;
            return;
        }
        let scale = 1.0 / norm2.sqrt();
        for &v in free {
            let v = v as usize;
            self.delta_f[column + v] *= scale;
            self.delta_g[column + v] *= scale;
        }
        self.newest = slot;
        self.stored = (self.stored + 1).min(m);
        // The new slot's inner products with every stored slot (itself included).
        for age in 0..self.stored {
            let other = self.slot_of(age);
            let value = if other == slot {
                1.0
            } else {
                let o = other * n;
                free.iter()
                    .map(|&v| {
                        let v = v as usize;
                        self.delta_f[column + v].dot(&self.delta_f[o + v])
                    })
                    .sum()
            };
            self.gram[slot * m + other] = value;
            self.gram[other * m + slot] = value;
        }
    }

    /// f_k and g_k of the iterate just made, for the next difference.
    fn remember(&mut self, free: &[u32], g: &[SVector<f64, D>]) {
        for &v in free {
            let v = v as usize;
            self.last_f[v] = g[v] - self.previous[v];
            self.last_g[v] = g[v];
        }
    }

    /// The ring slot of the difference `age` iterations old (0 the newest).
    fn slot_of(&self, age: usize) -> usize {
        let m = self.params.window;
        (self.newest + m - age) % m
    }

    /// θ minimising |f_k − ΔF θ| (f_k in `last_f`) from the normal equations ΔFᵀΔF θ = ΔFᵀ f_k by
    /// a Cholesky factorisation in age order (newest first) that drops a difference nearly in the
    /// span of the newer ones (θ = 0 for it). Returns false if no difference is usable or θ is
    /// not finite.
    fn solve_least_squares(&mut self, free: &[u32]) -> bool {
        let (n, m, k) = (self.vertex_count, self.params.window, self.stored);
        // Right-hand side ΔFᵀ f_k, in age order.
        for age in 0..k {
            let column = self.slot_of(age) * n;
            self.theta[age] = free
                .iter()
                .map(|&v| {
                    let v = v as usize;
                    self.delta_f[column + v].dot(&self.last_f[v])
                })
                .sum();
        }
        // Cholesky L Lᵀ of the Gram matrix in age order, row by row (L in `factor`, row-major).
        let mut any = false;
        for i in 0..k {
            let si = self.slot_of(i);
            for j in 0..=i {
                let sj = self.slot_of(j);
                let mut sum = self.gram[si * m + sj];
                for l in 0..j {
                    sum -= self.factor[i * m + l] * self.factor[j * m + l];
                }
                if j < i {
                    self.factor[i * m + j] = if self.kept[j] {
                        sum / self.factor[j * m + j]
                    } else {
                        0.0
                    };
                } else {
                    // The diagonal: the squared norm of difference i beyond the kept newer ones
                    // (its own squared norm is 1).
                    self.kept[i] = sum > DEPENDENT_DIFFERENCE;
                    self.factor[i * m + i] = if self.kept[i] { sum.sqrt() } else { 1.0 };
                    any |= self.kept[i];
                }
            }
        }
        if !any {
            return false;
        }
        // Forward and back substitution on the kept rows (dropped ones have θ = 0).
        for i in 0..k {
            if !self.kept[i] {
                self.theta[i] = 0.0;
                continue;
            }
            let mut sum = self.theta[i];
            for l in 0..i {
                sum -= self.factor[i * m + l] * self.theta[l];
            }
            self.theta[i] = sum / self.factor[i * m + i];
        }
        for i in (0..k).rev() {
            if !self.kept[i] {
                continue;
            }
            let mut sum = self.theta[i];
            for l in i + 1..k {
                sum -= self.factor[l * m + i] * self.theta[l];
            }
            self.theta[i] = sum / self.factor[i * m + i];
        }
        self.theta[..k].iter().all(|t| t.is_finite())
    }

    /// x ← g_k − ΔG θ on the free vertices (x holds g_k).
    fn extrapolate(&self, free: &[u32], x: &mut [SVector<f64, D>]) {
        let n = self.vertex_count;
        for &v in free {
            let v = v as usize;
            let mut correction = SVector::<f64, D>::zeros();
            for age in 0..self.stored {
                correction += self.delta_g[self.slot_of(age) * n + v] * self.theta[age];
            }
            x[v] -= correction;
        }
    }
}
