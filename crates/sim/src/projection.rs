//! Contact (docs/model.md §7) as a projection after a step: positions are moved back onto the
//! allowed side and the velocity component into the obstacle is removed. Pinned vertices are never
//! touched.
//!
//! The explicit integrators project each vertex on its own ([`Contact::project`]) after every
//! substep, whose penetrations are tiny. (Newton, Newton-CG, L-BFGS and projective dynamics handle
//! contact inside their solves instead: docs/contact.md.) After an implicit step of a whole frame
//! (the linearised integrator) that is not enough: the solve knows nothing of the obstacles, and at
//! h = 1/30 s it moves vertices far into them. Projecting each such vertex on its own moves it by the
//! penetration depth d while its neighbours stay, which stores about ½ k d² in every spring to it:
//! cloth-12 (k = 1e3 N/m, 1 kg) falling on a sphere of radius 0.15 m under Newton went 0.058 m and
//! then 0.102 m into the sphere in frames 7 and 8, and the per-vertex projection raised the spring
//! energy from 0.34 J to 16.2 J and then 106 J (total energy +15.6 J and +105.5 J above the
//! initial 0 J). Energy is not created by the velocity update (removing the inward velocity only
//! lowers the kinetic energy) but by these independent position moves.
//!
//! So after an implicit step the projection is done for the mesh (`StepProjection`). Each vertex
//! that ended inside an obstacle (the active set) gets the normal displacement that puts it on the
//! surface, at the point [`Contact::project`] would give, and may still move in that point's
//! tangent plane; every free vertex then moves by the displacement Δ of least increase of the
//! step's objective Φ (docs/model.md §6.4) to second order, ½ Δᵀ (M + h² ∇²E) Δ, under those
//! constraints: one Newton step of the contact-constrained backward Euler problem from the
//! unconstrained solution x⁺ (the clamped spring Hessian at x⁺, so the system is positive definite;
//! solved by CG with Baraff and Witkin's per-vertex filter I − n nᵀ). A vertex that Δ leaves inside
//! an obstacle joins the active set and Δ is solved again (at most [`MAX_PROJECTION_ROUNDS`]
//! rounds); a last per-vertex pass puts anything still inside on the surface, so no vertex ends
//! inside (a vertex in contact with a sphere ends on its tangent plane, just outside it). Each
//! vertex's velocity becomes that of its projected position, v⁺ + Δ/h (times the drag factor where
//! the integrator applies drag to (x⁺ − x_n)/h), and at the active vertices the inward normal
//! component is removed and friction applied, as [`Contact::project`] does. Pinned vertices are not
//! unknowns, so nothing moves them.
//!
//! Measured on the same scene (`cargo run -p hooke-sim --example contact_probe -- newton`): the
//! energy now rises at most 1.57 J above E₀ (frame 8; spring energy 2.9 J), the cloth drapes over
//! the sphere and slides off, and it ends 3.2 J below E₀ after 45 frames; the linearised integrator
//! never rises above E₀. What is left is the error of the one Newton step
//! (the springs near the sphere turn by large angles in a frame): the projection does not make
//! contact part of the solve, and does not promise energy decrease.
//!
//! This module owns the projection of the whole mesh after a linearised implicit step
//! ([`StepProjection`]); the obstacles and their per-vertex projection are the sibling module
//! `contact_model`'s.

use hooke_assembly::{Definiteness, FreeDofs, HessianParams, HessianPattern, HessianWorkspace};
use hooke_solvers::{
    BlockJacobi, CgParams, ConjugateGradient, LinearOperator, Preconditioner, SolveError, Symmetric,
};
use nalgebra::SVector;

use crate::contact_model::Contact;
use crate::error::SimError;
use crate::Scene;

/// Rounds of the implicit steps' contact projection (see the module documentation): solve for
/// the displacement, then activate the vertices it left inside an obstacle.
pub const MAX_PROJECTION_ROUNDS: usize = 8;

/// The relative residual to which [`StepProjection`] solves for Δ: 1e-8 of the prescribed
/// displacements (m) leaves an error far below the penetration depths it corrects.
const PROJECTION_TOLERANCE: f64 = 1e-8;

/// Iteration limit of that solve (a solve that reaches it is kept: Δ is then less smooth, and the
/// final per-vertex pass still puts every vertex outside).
const PROJECTION_ITERATIONS: usize = 2000;

/// Contact after an implicit step, for the whole mesh (see the module documentation). Workspaces
/// are allocated once, in [`StepProjection::new`].
#[derive(Debug)]
pub(crate) struct StepProjection<const D: usize> {
    free: FreeDofs,
    pattern: HessianPattern<D>,
    workspace: HessianWorkspace<D>,
    values: Vec<f64>,
    blocks: BlockJacobi<D>,
    cg: ConjugateGradient,
    /// Per free vertex: the contact normal if it is in contact (its normal displacement is
    /// prescribed), zero otherwise.
    normals: Vec<SVector<f64, D>>,
    /// Per free vertex in contact: the point that was projected (for the velocity update).
    probe: Vec<SVector<f64, D>>,
    /// The unconstrained positions x⁺ (full numbering).
    start: Vec<SVector<f64, D>>,
    /// Per free DOF: the prescribed displacement (m) that puts a vertex in contact on the
    /// surface; zero elsewhere.
    prescribed: Vec<f64>,
    /// Per free DOF: the free part of the displacement (m), tangential at vertices in contact.
    follow: Vec<f64>,
    rhs: Vec<f64>,
}

/// S v: v without its component along the unit normal `n` (v itself where n = 0).
#[inline]
fn filter<const D: usize>(n: &SVector<f64, D>, v: &mut [f64]) {
    let along: f64 = (0..D).map(|a| n[a] * v[a]).sum();
    for a in 0..D {
        v[a] -= along * n[a];
    }
}

/// S A S + (I − S), S the per-vertex filter I − n nᵀ at the vertices in contact (Baraff and
/// Witkin's constraint filter): the objective's Hessian on the displacements that keep those
/// vertices on their tangent planes, and the identity across them. Symmetric positive definite
/// when A is.
struct Filtered<'a, const D: usize> {
    matrix: Symmetric<'a>,
    normals: &'a [SVector<f64, D>],
}

impl<const D: usize> LinearOperator for Filtered<'_, D> {
    fn dim(&self) -> usize {
        self.matrix.dim()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.matrix.apply(x, y);
        for (f, n) in self.normals.iter().enumerate() {
            if n.iter().any(|&c| c != 0.0) {
                let (x, y) = (&x[D * f..D * f + D], &mut y[D * f..D * f + D]);
                filter(n, y);
                // + (I − S) x = n (n·x): zero for the vectors CG forms, kept for definiteness.
                let along: f64 = (0..D).map(|a| n[a] * x[a]).sum();
                for a in 0..D {
                    y[a] += along * n[a];
                }
            }
        }
    }
}

/// S B⁻¹ S + (I − S), B the diagonal blocks of A: the block-Jacobi preconditioner of
/// [`Filtered`].
struct FilteredBlocks<'a, const D: usize> {
    blocks: &'a BlockJacobi<D>,
    normals: &'a [SVector<f64, D>],
}

impl<const D: usize> Preconditioner for FilteredBlocks<'_, D> {
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        for (f, (inverse, n)) in self.blocks.inverses().iter().zip(self.normals).enumerate() {
            let r = &r[D * f..D * f + D];
            let mut s = SVector::<f64, D>::from_column_slice(r);
            filter(n, s.as_mut_slice());
            let mut out = inverse * s;
            filter(n, out.as_mut_slice());
            let along: f64 = (0..D).map(|a| n[a] * r[a]).sum();
            out += n * along;
            z[D * f..D * f + D].copy_from_slice(out.as_slice());
        }
    }
}

impl<const D: usize> StepProjection<D> {
    /// Workspaces for `scene` (its mesh and pins).
    pub(crate) fn new(scene: &Scene<D>) -> Result<Self, SimError> {
        let mesh = scene.mesh();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, scene.pinned())
            .map_err(|e| SimError::invalid("pins", "", e.to_string()))?;
        let pattern = HessianPattern::new(n, mesh.springs(), Some(&free));
        let count = free.free_count();
        let dim = D * count;
        Ok(StepProjection {
            workspace: pattern.workspace(),
            values: pattern.new_values(),
            blocks: BlockJacobi::identity(count),
            cg: ConjugateGradient::new(CgParams {
                tolerance: PROJECTION_TOLERANCE,
                max_iterations: PROJECTION_ITERATIONS,
            }),
            normals: vec![SVector::zeros(); count],
            probe: vec![SVector::zeros(); count],
            start: vec![SVector::zeros(); n],
            prescribed: vec![0.0; dim],
            follow: vec![0.0; dim],
            rhs: vec![0.0; dim],
            free,
            pattern,
        })
    }

    /// Project the state after an implicit step: `positions` are the solver's x⁺, `velocities` its
    /// v⁺ = (x⁺ − x_n)/h · `velocity_scale` (the drag factor where it was applied to that quotient,
    /// else 1). Both are updated in place (see the module documentation); pinned vertices are not
    /// read or written. Returns the number of vertices in contact.
    ///
    /// # Errors
    /// [`SimError::Solver`] if the solve for Δ meets NaN or a singular block.
    pub(crate) fn apply(
        &mut self,
        scene: &Scene<D>,
        positions: &mut [SVector<f64, D>],
        velocities: &mut [SVector<f64, D>],
        velocity_scale: f64,
        parallel: bool,
    ) -> Result<usize, SimError> {
        let contacts = scene.contacts();
        if contacts.is_empty() {
            return Ok(0);
        }
        self.normals.fill(SVector::zeros());
        self.prescribed.fill(0.0);
        self.follow.fill(0.0);
        self.start.copy_from_slice(positions);
        let touched = self.activate_penetrating(contacts);
        if touched == 0 {
            return Ok(0);
        }
        let mut touched = touched;
        let h = scene.time_step();
        let mesh = scene.mesh();
        self.pattern.assemble_into(
            mesh.springs(),
            &self.start,
            mesh.masses(),
            h,
            HessianParams {
                definiteness: Definiteness::Clamped,
                parallel,
            },
            &mut self.workspace,
            &mut self.values,
        );
        self.blocks
            .refill(self.pattern.diagonal_blocks(&self.values))
            .map_err(SimError::solver)?;
        for _ in 0..MAX_PROJECTION_ROUNDS {
            self.solve().map_err(SimError::solver)?;
            let joined = self.activate_penetrating(contacts);
            touched += joined;
            if joined == 0 {
                break;
            }
        }
        let scale = velocity_scale / h;
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let v = v as usize;
            let delta = SVector::<f64, D>::from_fn(|a, _| {
                self.prescribed[D * f + a] + self.follow[D * f + a]
            });
            positions[v] = self.start[v] + delta;
            velocities[v] += delta * scale;
            if self.normals[f].iter().any(|&c| c != 0.0) {
                let mut probe = self.probe[f];
                for contact in contacts {
                    contact.project(&mut probe, &mut velocities[v]);
                }
            }
            // Whatever the rounds left inside (a vertex slid into a second obstacle, or the round
            // limit), each contact puts on its surface, as after an explicit step.
            let mut unused = SVector::zeros();
            for contact in contacts {
                contact.project(&mut positions[v], &mut unused);
            }
        }
        Ok(touched)
    }

    /// Put in contact every free vertex not yet in contact that x⁺ + Δ leaves inside an
    /// obstacle: its displacement becomes the one to the surface point, plus a tangential part
    /// to be solved for. Returns how many joined.
    fn activate_penetrating(&mut self, contacts: &[Contact<D>]) -> usize {
        let mut joined = 0;
        for f in 0..self.free.free_count() {
            if self.normals[f].iter().any(|&c| c != 0.0) {
                continue;
            }
            let start = self.start[self.free.free_vertices()[f] as usize];
            let x = start
                + SVector::<f64, D>::from_fn(|a, _| {
                    self.prescribed[D * f + a] + self.follow[D * f + a]
                });
            let Some(moved) = surface_point(contacts, &x) else {
                continue;
            };
            let push = moved - x;
            let depth = push.norm();
            if depth == 0.0 {
                continue;
            }
            self.normals[f] = push / depth;
            self.probe[f] = x;
            let delta = moved - start;
            self.prescribed[D * f..D * f + D].copy_from_slice(delta.as_slice());
            self.follow[D * f..D * f + D].fill(0.0);
            joined += 1;
        }
        joined
    }

    /// The free part z of the displacement for the current contacts: S A S z = −S A Δ_prescribed,
    /// from the previous rounds' z.
    fn solve(&mut self) -> Result<(), SolveError> {
        let matrix = Symmetric(self.pattern.matrix(&self.values));
        matrix.apply(&self.prescribed, &mut self.rhs);
        for (r, n) in self.rhs.chunks_exact_mut(D).zip(&self.normals) {
            for r in r.iter_mut() {
                *r = -*r;
            }
            filter(n, r);
        }
        let operator = Filtered {
            matrix,
            normals: &self.normals,
        };
        let mut preconditioner = FilteredBlocks {
            blocks: &self.blocks,
            normals: &self.normals,
        };
        self.cg
            .solve(&operator, &mut preconditioner, &self.rhs, &mut self.follow)?;
        Ok(())
    }
}

/// Where the contacts put `x` (each in turn, as [`Contact::project`] does), or `None` if it is
/// outside every obstacle.
fn surface_point<const D: usize>(
    contacts: &[Contact<D>],
    x: &SVector<f64, D>,
) -> Option<SVector<f64, D>> {
    let mut p = *x;
    let mut v = SVector::zeros();
    let mut hit = false;
    for contact in contacts {
        hit |= contact.project(&mut p, &mut v);
    }
    hit.then_some(p)
}
