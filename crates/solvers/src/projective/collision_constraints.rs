//! Contact with static obstacles inside projective dynamics' iterations (docs/contact.md).
//!
//! Projective dynamics' collision constraints (Bouaziz et al. 2014): the free vertices of a step's
//! *active set* (those whose straight way from the step's start x_n to y passes within the reach
//! d̂ of an obstacle) each add ½ w_v |x_v − p_v|² to Φ, where the target p_v is computed in the
//! local step from the current iterate: its projection onto the obstacle grown by the margin d̂
//! where it is inside that margin, with the tangential part of its displacement since x_n cut by μ
//! times that normal correction (Coulomb friction on the step's displacement: sticking inside the
//! cone, sliding on its edge), and the iterate itself where it is clear. The global step then
//! solves with K (M + W + h² L) Kᵀ, W = diag(w_v), factored once per active set: a step whose
//! active set is that of the step before (a body at rest, a cloth lying on the ground) factors
//! nothing. Local and global steps each lower this augmented Φ, so the iteration keeps PD's
//! monotone descent.
//!
//! Every iterate is kept outside the obstacles themselves: each vertex moves from the last iterate
//! towards its solution by at most [`TIME_OF_IMPACT_SHARE`] of the way to the first obstacle on
//! its path (and not at all if even that point rounds to inside). The step starts from the largest
//! share of the way to y common to all free vertices that keeps them out of the margins, so a
//! falling body arrives undeformed and a resting one starts where it rests.
//!
//! The weight w_v = c (m_v + h² Σ k_s) (c = [`PdContactModel::weight`]) is relative to the vertex's
//! diagonal of the global matrix, so that the penalty is stiff against the springs that press a
//! vertex into an obstacle. The price is PD's: the target is taken at the current iterate, so a
//! vertex in contact moves only part of its way in each iteration, and sliding along an obstacle
//! converges slowly within a fixed budget of iterations (it acts as extra friction; run PD to a
//! tolerance, or use Chebyshev's acceleration, where sliding matters).
//!
//! This module owns the constraints and the clamping of PD's iterates; the obstacles' geometry is
//! `hooke_collision::obstacle`'s, and backward Euler's barrier treatment of the same obstacles is
//! `backward_euler::obstacles`.

use hooke_assembly::pd::LaplacianPattern;
use hooke_collision::obstacle::Obstacle;
use hooke_mesh::Spring;
use nalgebra::SVector;

use super::{GlobalSolve, PdError, PdMultilevelParams};
use crate::backward_euler::TIME_OF_IMPACT_SHARE;
use crate::params::{self, ParamError};

/// The default weight c of an active vertex's contact target, in units of its diagonal entry of
/// the global matrix K (M + h² L) Kᵀ: 1, the smallest of those measured (0.03 to 100) that keeps
/// resting vertices off the obstacles' surfaces on the contact scenes (a larger one slows sliding
/// further; the measurements are in benches/results/contact-scenes.md).
pub const DEFAULT_CONTACT_WEIGHT: f64 = 1.0;

/// The contact model of [`super::ProjectiveDynamics`]: static obstacles with their friction
/// coefficients, the reach that makes a vertex take part in a step's contact solve, and the
/// weight of the contact targets.
#[derive(Clone, Debug, PartialEq)]
pub struct PdContactModel<const D: usize> {
    /// The obstacles, each with its friction coefficient μ ≥ 0 (0: frictionless).
    pub obstacles: Vec<(Obstacle<D>, f64)>,
    /// A free vertex whose straight way from its position at the step's start to its inertial
    /// target y comes within `reach` (m, ≥ 0) of an obstacle is active in the step.
    pub reach: f64,
    /// The weight of an active vertex's target relative to its diagonal entry of the global
    /// matrix (> 0, dimensionless). Default [`DEFAULT_CONTACT_WEIGHT`].
    pub weight: f64,
}

impl<const D: usize> PdContactModel<D> {
    /// The model for `obstacles` and `reach` (m) with the default weight.
    pub fn new(obstacles: Vec<(Obstacle<D>, f64)>, reach: f64) -> Self {
        PdContactModel {
            obstacles,
            reach,
            weight: DEFAULT_CONTACT_WEIGHT,
        }
    }

    /// Check the fields: `reach` finite and ≥ 0, `weight` finite and > 0, every friction
    /// coefficient finite and ≥ 0.
    ///
    /// # Errors
    /// [`ParamError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        params::non_negative("PdContactModel::reach", self.reach)?;
        params::positive("PdContactModel::weight", self.weight)?;
        for (_, mu) in &self.obstacles {
            params::non_negative("PdContactModel::obstacles (friction)", *mu)?;
        }
        Ok(())
    }
}

/// The contact state of a [`super::ProjectiveDynamics`]: the model, the step's active set, the
/// weighted factor and the buffers of the iterations.
#[derive(Debug)]
pub(crate) struct PdContact<const D: usize> {
    pub(crate) model: PdContactModel<D>,
    /// The diagonal of K (M + h² L) Kᵀ per free vertex (kg).
    diagonal: Vec<f64>,
    /// This step's target weight per free vertex (kg): 0 where inactive.
    weights: Vec<f64>,
    /// The weights the weighted factor was made with; `None` before the first factorisation,
    /// after a failed one, and after the matrix changed.
    factored: Option<Vec<f64>>,
    weighted: GlobalSolve<D>,
    values: Vec<f64>,
    /// Masses plus weights, per vertex of the full mesh (kg): M + W on the pattern's diagonal.
    boosted: Vec<f64>,
    masses: Vec<f64>,
    h: f64,
    active: Vec<u32>,
    /// Positions at the step's start, per vertex (m).
    start: Vec<SVector<f64, D>>,
    /// The global step's solution per free vertex (m).
    solution: Vec<SVector<f64, D>>,
    /// The right-hand side of the weighted solve.
    rhs: Vec<SVector<f64, D>>,
    /// Factorisations of the weighted matrix so far.
    pub(crate) factorizations: usize,
}

impl<const D: usize> PdContact<D> {
    pub(crate) fn new(
        model: PdContactModel<D>,
        weighted: GlobalSolve<D>,
        pattern: &LaplacianPattern,
        springs: &[Spring],
        masses: &[f64],
        h: f64,
    ) -> Self {
        let n_free = pattern.size();
        let mut contact = PdContact {
            model,
            diagonal: vec![0.0; n_free],
            weights: vec![0.0; n_free],
            factored: None,
            weighted,
            values: pattern.new_values(),
            boosted: masses.to_vec(),
            masses: masses.to_vec(),
            h,
            active: Vec::new(),
            start: vec![SVector::zeros(); masses.len()],
            solution: vec![SVector::zeros(); n_free],
            rhs: vec![SVector::zeros(); n_free],
            factorizations: 0,
        };
        contact.rebuild(pattern, springs, masses, h);
        contact
    }

    /// The global matrix changed (h, stiffnesses or masses): recompute the diagonal and refactor
    /// at the next step.
    pub(crate) fn rebuild(
        &mut self,
        pattern: &LaplacianPattern,
        springs: &[Spring],
        masses: &[f64],
        h: f64,
    ) {
        let free = pattern.free_dofs();
        self.masses.copy_from_slice(masses);
        self.h = h;
        for (d, &v) in self.diagonal.iter_mut().zip(free.free_vertices()) {
            *d = masses[v as usize];
        }
        for s in springs {
            let (i, j) = s.ends();
            for v in [i, j] {
                if let Some(f) = free.free_index(v) {
                    self.diagonal[f] += h * h * s.stiffness;
                }
            }
        }
        self.factored = None;
    }

    /// Free vertices active in this step.
    pub(crate) fn active_count(&self) -> usize {
        self.active.len()
    }

    /// Begin a step from `x` (the step's start, outside every obstacle) towards the inertial
    /// target `y`: choose the active set, refactor the weighted matrix if the set changed, and
    /// write the initial guess into `x` (free vertices): y where the way from the start is clear,
    /// else [`TIME_OF_IMPACT_SHARE`] of the way to the first obstacle.
    pub(crate) fn begin_step(
        &mut self,
        pattern: &LaplacianPattern,
        springs: &[Spring],
        y: &[SVector<f64, D>],
        x: &mut [SVector<f64, D>],
        params: &PdMultilevelParams,
    ) -> Result<(), PdError> {
        self.start.copy_from_slice(x);
        let start = &self.start;
        self.active.clear();
        let free = pattern.free_dofs().free_vertices();
        for (f, &v) in free.iter().enumerate() {
            let (a, b) = (&start[v as usize], &y[v as usize]);
            let near = self
                .model
                .obstacles
                .iter()
                .any(|(o, _)| closest_distance(o, a, b) <= self.model.reach);
            self.weights[f] = if near {
                self.active.push(f as u32);
                self.model.weight * self.diagonal[f]
            } else {
                0.0
            };
        }
        if !self.active.is_empty() && self.factored.as_deref() != Some(&self.weights[..]) {
            self.factored = None;
            self.boosted.copy_from_slice(&self.masses);
            for (f, &v) in free.iter().enumerate() {
                self.boosted[v as usize] += self.weights[f];
            }
            pattern.system_into(springs, &self.boosted, self.h, &mut self.values);
            self.weighted.factor(pattern.matrix(&self.values), params)?;
            self.factorizations += 1;
            self.factored = Some(self.weights.clone());
        }
        // The start moves every free vertex the same share of its way to y, the largest that
        // keeps them all out of the obstacles' margins (or none, if a vertex inside a margin
        // moves further in): a falling body arrives undeformed, and a resting one starts where
        // it rests. Moving each vertex as far as its own way allows would crush the layer that
        // reaches an obstacle (tetrahedra inverted in the initial guess stay inverted: PD's
        // local step keeps a spring's direction).
        let mut share: f64 = 1.0;
        for &v in free {
            let v = v as usize;
            let step = y[v] - self.start[v];
            for (o, _) in &self.model.obstacles {
                let t = time_to_margin(o, self.model.reach, &self.start[v], &step);
                share = if t.is_nan() {
                    0.0
                } else {
                    share.min(TIME_OF_IMPACT_SHARE * t)
                };
            }
        }
        for &v in free {
            let v = v as usize;
            let guess = self.start[v] + (y[v] - self.start[v]) * share;
            x[v] = self.feasible_move(&self.start[v], &guess);
        }
        Ok(())
    }

    /// The global step with contact: with no active vertex the plain solve with `global`;
    /// otherwise the solve with the weighted matrix, each active vertex pulled towards its
    /// contact target from the current iterate `x` ([`contact_target`]; the iterate itself where
    /// it is clear of the margin). The result is in [`PdContact::solution`].
    pub(crate) fn global_step(
        &mut self,
        global: &mut GlobalSolve<D>,
        rhs: &[SVector<f64, D>],
        free: &[u32],
        x: &[SVector<f64, D>],
        threads: bool,
        params: &PdMultilevelParams,
    ) {
        let solution = &mut self.solution;
        if self.active.is_empty() {
            // (`global` starts from `x`: the caller set its guess.)
            global.solve(rhs, threads, params, |f, new| solution[f] = new);
            return;
        }
        self.rhs.copy_from_slice(rhs);
        for &f in &self.active {
            let f = f as usize;
            let v = free[f] as usize;
            let target = contact_target(
                &self.model.obstacles,
                self.model.reach,
                &self.start[v],
                &x[v],
            )
            .unwrap_or(x[v]);
            self.rhs[f] += target * self.weights[f];
        }
        self.weighted.guess(|f| x[free[f] as usize]);
        self.weighted
            .solve(&self.rhs, threads, params, |f, new| solution[f] = new);
    }

    /// CG iterations of the last weighted solve (0 on the direct path).
    pub(crate) fn last_linear_iterations(&self) -> usize {
        self.weighted.last_iterations()
    }

    /// The global step's solution per free vertex.
    pub(crate) fn solution(&self) -> &[SVector<f64, D>] {
        &self.solution
    }

    /// Where a vertex at `from` (outside every obstacle) may go on its way to `to`: `to` if the
    /// way is clear, else [`TIME_OF_IMPACT_SHARE`] of the way to the first obstacle; `from` itself
    /// if the computed point would be inside one (rounding), so the result is always outside.
    pub(crate) fn feasible_move(
        &self,
        from: &SVector<f64, D>,
        to: &SVector<f64, D>,
    ) -> SVector<f64, D> {
        feasible_move(&self.model.obstacles, from, to)
    }

    /// Clamp every free vertex's move from `from` to `x` as [`PdContact::feasible_move`] does.
    pub(crate) fn limit_moves(
        &self,
        free: &[u32],
        from: &[SVector<f64, D>],
        x: &mut [SVector<f64, D>],
    ) {
        for &v in free {
            let v = v as usize;
            x[v] = self.feasible_move(&from[v], &x[v]);
        }
    }
}

/// Where a vertex at `from` (outside every obstacle of `obstacles`) may go on its way to `to`:
/// `to` if the way is clear, else [`TIME_OF_IMPACT_SHARE`] of the way to the first obstacle;
/// `from` itself if the computed point would be inside one (rounding), so the result is always
/// outside. A vertex on a surface may leave it or move along it (a plane's or a sphere's outside is
/// not entered by a move whose direction has no inward normal part), not move in.
fn feasible_move<const D: usize>(
    obstacles: &[(Obstacle<D>, f64)],
    from: &SVector<f64, D>,
    to: &SVector<f64, D>,
) -> SVector<f64, D> {
    let step = to - from;
    let mut first = f64::INFINITY;
    for (o, _) in obstacles {
        let t = if o.distance(from) > 0.0 {
            o.time_of_impact(from, &step).unwrap_or(f64::INFINITY)
        } else if o.normal(from).dot(&step) >= 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
        // NaN (non-finite input) stops the vertex.
        first = if t.is_nan() { 0.0 } else { first.min(t) };
    }
    let new = if first > 1.0 {
        *to
    } else {
        from + step * (TIME_OF_IMPACT_SHARE * first)
    };
    if obstacles.iter().all(|(o, _)| o.distance(&new) >= 0.0) {
        new
    } else {
        *from
    }
}

/// The share of `step` after which a vertex at `from` reaches the surface at distance `margin`
/// (m) outside `obstacle`: 0 if it is within the margin and moves further in, ∞ if it never
/// reaches it, NaN for non-finite input.
fn time_to_margin<const D: usize>(
    obstacle: &Obstacle<D>,
    margin: f64,
    from: &SVector<f64, D>,
    step: &SVector<f64, D>,
) -> f64 {
    let grown = match *obstacle {
        Obstacle::HalfSpace { point, normal } => Obstacle::HalfSpace {
            point: point + normal * margin,
            normal,
        },
        Obstacle::SphereOutside { center, radius } => Obstacle::SphereOutside {
            center,
            radius: radius + margin,
        },
    };
    if grown.distance(from) <= 0.0 {
        let rate = grown.normal(from).dot(step);
        return if rate.is_nan() {
            f64::NAN
        } else if rate >= 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
    }
    grown.time_of_impact(from, step).unwrap_or(f64::INFINITY)
}

/// The smallest signed distance (m) from `obstacle` of a point of the segment from `a` to `b`.
fn closest_distance<const D: usize>(
    obstacle: &Obstacle<D>,
    a: &SVector<f64, D>,
    b: &SVector<f64, D>,
) -> f64 {
    let ends = obstacle.distance(a).min(obstacle.distance(b));
    match obstacle {
        // A plane's distance is linear along the segment: an end is nearest.
        Obstacle::HalfSpace { .. } => ends,
        Obstacle::SphereOutside { center, .. } => {
            let p = b - a;
            let length2 = p.norm_squared();
            if length2 == 0.0 {
                return ends;
            }
            let t = (-(a - center).dot(&p) / length2).clamp(0.0, 1.0);
            ends.min(obstacle.distance(&(a + p * t)))
        }
    }
}

/// The contact target of a vertex that started the step at `start` and is now at `point`: `None`
/// if `point` is at least `margin` (m) outside every obstacle; otherwise `point` moved onto the
/// surface at distance `margin` of each obstacle it is within (along the normal, in the
/// obstacles' order), with its tangential move since `start` reduced by μ times the normal
/// correction, and cancelled where that is enough (Coulomb friction on the step's displacement:
/// sticking within the cone, sliding on its edge).
fn contact_target<const D: usize>(
    obstacles: &[(Obstacle<D>, f64)],
    margin: f64,
    start: &SVector<f64, D>,
    point: &SVector<f64, D>,
) -> Option<SVector<f64, D>> {
    let mut target = *point;
    let mut inside = false;
    for (o, mu) in obstacles {
        let d = o.distance(&target) - margin;
        if d.is_nan() || d >= 0.0 {
            continue;
        }
        inside = true;
        let surface = match o {
            Obstacle::HalfSpace { normal, .. } => target - normal * d,
            Obstacle::SphereOutside { center, radius } => {
                center + o.normal(&target) * (*radius + margin)
            }
        };
        let n = o.normal(&surface);
        let moved = surface - start;
        let slip = moved - n * moved.dot(&n);
        let slip_length = slip.norm();
        let limit = mu * -d;
        target = if slip_length <= limit {
            surface - slip
        } else {
            surface - slip * (limit / slip_length)
        };
    }
    inside.then_some(target)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use proptest::prelude::*;

    fn scene() -> Vec<(Obstacle<3>, f64)> {
        vec![
            (
                Obstacle::half_space(Vector3::zeros(), Vector3::y()).unwrap(),
                0.5,
            ),
            (
                Obstacle::sphere_outside(Vector3::new(0.0, 0.5, 0.0), 0.2).unwrap(),
                0.0,
            ),
        ]
    }

    fn outside(obstacles: &[(Obstacle<3>, f64)], x: &Vector3<f64>) -> bool {
        obstacles.iter().all(|(o, _)| o.distance(x) >= 0.0)
    }

    proptest! {
        /// From any point outside, the move ends outside, exactly; a clear way is taken whole.
        /// Starting points are drawn above the ground (below it is inside), so that only those
        /// in the sphere are rejected: half the draws were, and more cases hit proptest's
        /// reject limit.
        #[test]
        fn a_move_never_ends_inside(
            from in (-1.0f64..1.0, 0.0f64..1.0, -1.0f64..1.0),
            to in prop::array::uniform3(-1.0f64..1.0),
        ) {
            let obstacles = scene();
            let from = Vector3::new(from.0, from.1, from.2);
            let to = Vector3::from(to);
            prop_assume!(outside(&obstacles, &from));
            let new = feasible_move(&obstacles, &from, &to);
            prop_assert!(outside(&obstacles, &new), "{new:?}");
            let clear = obstacles.iter().all(|(o, _)| {
                o.time_of_impact(&from, &(to - from)).is_none_or(|t| t > 1.0)
            });
            if clear {
                prop_assert_eq!(new, to);
            }
        }
    }

    #[test]
    fn a_vertex_on_a_surface_leaves_it_or_slides_but_does_not_enter() {
        let obstacles = scene();
        let on_ground = Vector3::new(0.7, 0.0, 0.0);
        let up = Vector3::new(0.7, 0.1, 0.0);
        assert_eq!(feasible_move(&obstacles, &on_ground, &up), up);
        let along = Vector3::new(0.9, 0.0, 0.1);
        assert_eq!(feasible_move(&obstacles, &on_ground, &along), along);
        let down = Vector3::new(0.7, -0.1, 0.0);
        assert_eq!(feasible_move(&obstacles, &on_ground, &down), on_ground);
    }

    #[test]
    fn friction_sticks_inside_the_cone_and_slides_on_its_edge() {
        // Ground y = 0 with μ = 0.5 and a margin of 1 mm; the vertex started at x = 0, 2 mm up.
        let obstacles = &scene()[..1];
        let margin = 1e-3;
        let start = Vector3::new(0.0, 2e-3, 0.0);
        // 0.5 mm inside the margin and 0.1 mm downhill: 0.1 ≤ 0.5 · 0.5, so it sticks where it
        // started along the ground, on the margin's surface.
        let stuck = contact_target(obstacles, margin, &start, &Vector3::new(1e-4, 5e-4, 0.0));
        assert_eq!(stuck, Some(Vector3::new(0.0, margin, 0.0)));
        // 0.4 mm inside and 1 mm along: the tangential move is cut by 0.5 · 0.4 = 0.2 mm.
        let slid =
            contact_target(obstacles, margin, &start, &Vector3::new(1e-3, 6e-4, 0.0)).unwrap();
        assert!(
            (slid - Vector3::new(8e-4, margin, 0.0)).norm() < 1e-15,
            "{slid:?}"
        );
        // Clear of the margin: no target.
        assert_eq!(
            contact_target(obstacles, margin, &start, &Vector3::new(0.3, 2e-3, 0.0)),
            None
        );
    }
}
