//! Contact with static obstacles inside backward Euler's objective (docs/contact.md): for every
//! free vertex v and obstacle o, h² κ_v b(d_o(x_v)) with IPC's log barrier b (zero beyond d̂, +∞ at
//! the surface); with a surface given, for every triangle and sphere h² κ_t b(d) with d the
//! distance from the closed triangle to the sphere, so that no point of a triangle enters a sphere
//! (a plane's allowed side is convex: a triangle whose vertices are on it is on it); and h² times
//! the lagged friction potential of the contacts active at the step's start.
//!
//! This module owns the sums of these terms over the mesh and the line-search cap against the
//! obstacles (each free vertex's time of impact, and additive CCD of each triangle against each
//! sphere). The single terms are `hooke_assembly`'s (`barrier`, `surface_barrier`), the geometry
//! `hooke_collision`'s; self-contact is the sibling module `self_contact`; projective dynamics'
//! treatment of the same obstacles is `projective::collision_constraints`.

use hooke_assembly::barrier::{self, LaggedFriction, Obstacle};
use hooke_assembly::surface_barrier::{
    triangle_sphere_distance, triangle_sphere_energy, triangle_sphere_energy_change,
    triangle_sphere_terms,
};
use hooke_assembly::Definiteness;
use hooke_collision::ccd::{point_triangle_ccd, CcdParams};
use nalgebra::Vector3;
use nalgebra::{SMatrix, SVector};

/// The share of the time of impact a line search may go: after a step of this share of the way
/// to an obstacle, a vertex keeps a tenth of its distance, so no iterate reaches a surface.
pub const TIME_OF_IMPACT_SHARE: f64 = 0.9;

/// The contact model of a backward Euler step: obstacles with their friction coefficients, and the
/// barrier's and friction's parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactModel<const D: usize> {
    /// The obstacles (static), each with its friction coefficient μ ≥ 0 (0: frictionless).
    pub obstacles: Vec<(Obstacle<D>, f64)>,
    /// The barrier's reach d̂ (m, > 0): a vertex farther than d̂ from an obstacle feels nothing.
    pub distance: f64,
    /// The barrier's stiffness per unit of vertex mass, κ̂ (1/s², > 0): vertex v's barrier is
    /// κ_v b(d) with κ_v = κ̂ m_v (N/m), m_v the mass given with the model (kg).
    pub stiffness: f64,
    /// IPC's friction smoothing velocity ε_v (m/s, > 0): below this tangential speed friction
    /// acts as a stiff spring towards sticking, above it as Coulomb's μ λ.
    pub friction_velocity: f64,
}

/// The contact terms of [`super::BackwardEulerStep`], with the friction lagged at the step's start.
#[derive(Debug)]
pub(crate) struct StepContact<const D: usize> {
    pub(crate) model: ContactModel<D>,
    /// κ_v per vertex (N/m): the model's κ̂ m_v times the adaptive scale.
    stiffness: Vec<f64>,
    /// The model's κ̂ m_v per vertex (N/m), unscaled.
    base_stiffness: Vec<f64>,
    /// The adaptive scale s the stiffnesses carry (1: the model's).
    stiffness_scale: f64,
    /// The lagged frictional contacts of this step: (vertex, contact).
    friction: Vec<(u32, LaggedFriction<D>)>,
    /// ε_v h (m).
    friction_length: f64,
    /// The surface's triangles against the spheres ([`StepContact::set_surface`]).
    surface: Option<SphereSurface>,
}

/// The triangles of a surface, held off the spheres as wholes.
#[derive(Debug)]
struct SphereSurface {
    triangles: Vec<[u32; 3]>,
    /// κ_t = κ̂ × the mean mass of the triangle's vertices (N/m), times the adaptive scale.
    stiffness: Vec<f64>,
    /// κ_t unscaled (N/m).
    base_stiffness: Vec<f64>,
    /// Whether every pair of the triangle's free vertices is joined by a spring (the Hessian's
    /// pattern then holds its whole 9×9 block; otherwise only its vertex blocks are added, which
    /// keeps the sum positive semidefinite).
    coupled: Vec<bool>,
    /// The spheres (centre, radius).
    spheres: Vec<(Vector3<f64>, f64)>,
    /// Per vertex, whether it is free.
    free: Vec<bool>,
}

/// `p` as a 3-vector (triangle-level contact exists only in 3D).
#[inline]
fn v3<const D: usize>(p: &SVector<f64, D>) -> Vector3<f64> {
    Vector3::new(p[0], p[1], p[2])
}

impl SphereSurface {
    /// Call `f(triangle index, sphere)` for every triangle with a free vertex whose box comes within
    /// d̂ of a sphere's box (a cheap filter; the terms test the distance).
    fn for_each_near<const D: usize>(
        &self,
        x: &[SVector<f64, D>],
        d_hat: f64,
        mut f: impl FnMut(usize, &(Vector3<f64>, f64)),
    ) {
        for (k, t) in self.triangles.iter().enumerate() {
            if !t.iter().any(|&v| self.free[v as usize]) {
                continue;
            }
            let p = t.map(|v| v3(&x[v as usize]));
            let lo = p[0].inf(&p[1]).inf(&p[2]);
            let hi = p[0].sup(&p[1]).sup(&p[2]);
            for sphere in &self.spheres {
                let (c, r) = sphere;
                let reach = r + d_hat;
                if (0..3).all(|a| c[a] >= lo[a] - reach && c[a] <= hi[a] + reach) {
                    f(k, sphere);
                }
            }
        }
    }
}

impl<const D: usize> StepContact<D> {
    pub(crate) fn new(model: ContactModel<D>, masses: &[f64], h: f64) -> Self {
        let stiffness: Vec<f64> = masses.iter().map(|&m| model.stiffness * m).collect();
        let friction_length = model.friction_velocity * h;
        StepContact {
            base_stiffness: stiffness.clone(),
            stiffness,
            stiffness_scale: 1.0,
            friction: Vec::new(),
            friction_length,
            surface: None,
            model,
        }
    }

    /// Hold the triangles `triangles` of the surface off every sphere as wholes (not only their
    /// vertices). `free[v]`: whether vertex v is free; `joined(i, j)`: whether a spring joins i
    /// and j. κ_t is the mean of the vertices' κ_v. Nothing happens without a sphere or in 2D.
    pub(crate) fn set_surface(
        &mut self,
        triangles: Vec<[u32; 3]>,
        free: Vec<bool>,
        joined: impl Fn(u32, u32) -> bool,
    ) {
        let spheres: Vec<(Vector3<f64>, f64)> = self
            .model
            .obstacles
            .iter()
            .filter_map(|(o, _)| match o {
                Obstacle::SphereOutside { center, radius } if D == 3 => Some((v3(center), *radius)),
                _ => None,
            })
            .collect();
        if spheres.is_empty() || triangles.is_empty() {
            self.surface = None;
            return;
        }
        let base_stiffness: Vec<f64> = triangles
            .iter()
            .map(|t| {
                t.iter()
                    .map(|&v| self.base_stiffness[v as usize])
                    .sum::<f64>()
                    / 3.0
            })
            .collect();
        let stiffness = base_stiffness
            .iter()
            .map(|k| k * self.stiffness_scale)
            .collect();
        let coupled = triangles
            .iter()
            .map(|&[a, b, c]| {
                [(a, b), (b, c), (c, a)]
                    .iter()
                    .all(|&(i, j)| !(free[i as usize] && free[j as usize]) || joined(i, j))
            })
            .collect();
        self.surface = Some(SphereSurface {
            triangles,
            stiffness,
            base_stiffness,
            coupled,
            spheres,
            free,
        });
    }

    /// Multiply the model's stiffnesses by `scale` (the adaptive stiffness's s ≥ 1).
    pub(crate) fn set_stiffness_scale(&mut self, scale: f64) {
        if scale == self.stiffness_scale {
            return;
        }
        self.stiffness_scale = scale;
        for (k, base) in self.stiffness.iter_mut().zip(&self.base_stiffness) {
            *k = base * scale;
        }
        if let Some(surface) = &mut self.surface {
            for (k, base) in surface.stiffness.iter_mut().zip(&surface.base_stiffness) {
                *k = base * scale;
            }
        }
    }

    /// Multiply the lagged friction's normal forces by `scale` (lagged at the models' stiffnesses,
    /// they then carry the adaptive scale of the step's start).
    pub(crate) fn scale_friction(&mut self, scale: f64) {
        for (_, lagged) in &mut self.friction {
            lagged.normal_force *= scale;
        }
    }

    /// Lag the friction at the step's start `start` (free vertices `free`): every vertex within d̂
    /// of an obstacle with μ > 0 gets that contact's normal force and tangent plane.
    pub(crate) fn lag_friction(&mut self, free: &[u32], start: &[SVector<f64, D>]) {
        self.friction.clear();
        for &v in free {
            let x = &start[v as usize];
            for &(obstacle, mu) in &self.model.obstacles {
                if mu <= 0.0 {
                    continue;
                }
                if let Some(lagged) = barrier::lagged_friction(
                    &obstacle,
                    x,
                    self.model.distance,
                    self.stiffness[v as usize],
                    mu,
                ) {
                    self.friction.push((v, lagged));
                }
            }
        }
    }

    /// The smallest distance (m) of any free vertex from any obstacle at `x` (∞ without obstacles).
    pub(crate) fn smallest_distance(&self, free: &[u32], x: &[SVector<f64, D>]) -> f64 {
        let mut smallest = f64::INFINITY;
        for &v in free {
            for (obstacle, _) in &self.model.obstacles {
                smallest = smallest.min(obstacle.distance(&x[v as usize]));
            }
        }
        if let Some(surface) = &self.surface {
            surface.for_each_near(x, self.model.distance, |k, (c, r)| {
                let t = surface.triangles[k].map(|v| v3(&x[v as usize]));
                smallest = smallest.min(triangle_sphere_distance(&t, c, *r));
            });
        }
        smallest
    }

    /// The barrier and friction energy at `x` (J; +∞ if a vertex is on or inside an obstacle),
    /// summed in vertex order.
    pub(crate) fn energy(&self, free: &[u32], x: &[SVector<f64, D>]) -> f64 {
        let d_hat = self.model.distance;
        let mut sum = 0.0;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                let d = obstacle.distance(&x[v]);
                if d < d_hat {
                    sum += self.stiffness[v] * barrier::barrier(d, d_hat);
                }
            }
        }
        for (v, lagged) in &self.friction {
            sum += lagged.terms(&x[*v as usize], self.friction_length).energy;
        }
        if let Some(surface) = &self.surface {
            surface.for_each_near(x, d_hat, |k, (c, r)| {
                let t = surface.triangles[k].map(|v| v3(&x[v as usize]));
                sum += triangle_sphere_energy(&t, c, *r, d_hat, surface.stiffness[k]);
            });
        }
        sum
    }

    /// The change of [`StepContact::energy`] from `x` to `x + delta` (J), term by term without
    /// subtracting two rounded energies.
    pub(crate) fn energy_change(
        &self,
        free: &[u32],
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        let d_hat = self.model.distance;
        let mut sum = 0.0;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                let d = obstacle.distance(&x[v]);
                let change = obstacle.distance_change(&x[v], &delta[v]);
                if d < d_hat || d + change < d_hat {
                    sum += self.stiffness[v] * barrier::barrier_change(d, change, d_hat);
                }
            }
        }
        for (v, lagged) in &self.friction {
            let v = *v as usize;
            sum += lagged.energy_change(&x[v], &delta[v], self.friction_length);
        }
        if let Some(surface) = &self.surface {
            // Triangles near either end (the boxes of both ends are tested).
            let mut changes = 0.0;
            for (k, tri) in surface.triangles.iter().enumerate() {
                if !tri.iter().any(|&v| surface.free[v as usize]) {
                    continue;
                }
                let start = tri.map(|v| v3(&x[v as usize]));
                let moves = tri.map(|v| v3(&delta[v as usize]));
                let end = [
                    start[0] + moves[0],
                    start[1] + moves[1],
                    start[2] + moves[2],
                ];
                for (c, r) in &surface.spheres {
                    let near = |p: &[Vector3<f64>; 3]| triangle_sphere_distance(p, c, *r) < d_hat;
                    if near(&start) || near(&end) {
                        let kappa = surface.stiffness[k];
                        changes +=
                            triangle_sphere_energy_change(&start, &moves, c, *r, d_hat, kappa);
                    }
                }
            }
            sum += changes;
        }
        sum
    }

    /// Add the contact forces' negative, ∇(energy) · `scale`, into `out` per vertex
    /// (`out[v] += scale ∇_v`); the lagged friction's too if `with_friction`.
    pub(crate) fn add_gradient(
        &self,
        free: &[u32],
        x: &[SVector<f64, D>],
        scale: f64,
        with_friction: bool,
        out: &mut [SVector<f64, D>],
    ) {
        let d_hat = self.model.distance;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                if let Some(terms) = barrier::vertex_barrier(
                    obstacle,
                    &x[v],
                    d_hat,
                    self.stiffness[v],
                    Definiteness::Clamped,
                ) {
                    out[v] += terms.gradient * scale;
                }
            }
        }
        for (v, lagged) in self.friction.iter().filter(|_| with_friction) {
            let v = *v as usize;
            out[v] += lagged.terms(&x[v], self.friction_length).gradient * scale;
        }
        if let Some(surface) = &self.surface {
            surface.for_each_near(x, d_hat, |k, (c, r)| {
                let tri = surface.triangles[k];
                let t = tri.map(|v| v3(&x[v as usize]));
                if let Some(terms) =
                    triangle_sphere_terms(&t, c, *r, d_hat, surface.stiffness[k], None)
                {
                    for (a, &v) in tri.iter().enumerate() {
                        if surface.free[v as usize] {
                            let target = &mut out[v as usize];
                            for (b, g) in terms.gradient.fixed_rows::<3>(3 * a).iter().enumerate() {
                                target[b] += scale * g;
                            }
                        }
                    }
                }
            });
        }
    }

    /// Call `add(i, j, block)` with `scale` times every block (i, j) of the contact Hessian:
    /// each vertex's (i = j; barrier with `definiteness`, and friction, which is positive
    /// semidefinite), and the triangles' against spheres (projected to positive semidefinite).
    pub(crate) fn for_each_hessian_block(
        &self,
        free: &[u32],
        x: &[SVector<f64, D>],
        scale: f64,
        definiteness: Definiteness,
        mut add: impl FnMut(usize, usize, SMatrix<f64, D, D>),
    ) {
        let d_hat = self.model.distance;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                if let Some(terms) =
                    barrier::vertex_barrier(obstacle, &x[v], d_hat, self.stiffness[v], definiteness)
                {
                    add(v, v, terms.hessian * scale);
                }
            }
        }
        for (v, lagged) in &self.friction {
            let v = *v as usize;
            add(
                v,
                v,
                lagged.terms(&x[v], self.friction_length).hessian * scale,
            );
        }
        if let Some(surface) = &self.surface {
            surface.for_each_near(x, d_hat, |k, (c, r)| {
                let tri = surface.triangles[k];
                let t = tri.map(|v| v3(&x[v as usize]));
                let Some(terms) = triangle_sphere_terms(
                    &t,
                    c,
                    *r,
                    d_hat,
                    surface.stiffness[k],
                    Some(definiteness),
                ) else {
                    return;
                };
                for (a, &i) in tri.iter().enumerate() {
                    for (b, &j) in tri.iter().enumerate() {
                        if !(surface.free[i as usize] && surface.free[j as usize])
                            || (a != b && !surface.coupled[k])
                        {
                            continue;
                        }
                        let mut block = SMatrix::<f64, D, D>::zeros();
                        for col in 0..3 {
                            for row in 0..3 {
                                block[(row, col)] =
                                    scale * terms.hessian[(3 * a + row, 3 * b + col)];
                            }
                        }
                        add(i as usize, j as usize, block);
                    }
                }
            });
        }
    }

    /// The longest share α ≤ 1 of the move `delta` (per vertex) from `x` that keeps every free
    /// vertex off every obstacle: [`TIME_OF_IMPACT_SHARE`] of the first time of impact.
    pub(crate) fn max_step(
        &self,
        free: &[u32],
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        let mut first = f64::INFINITY;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                if let Some(t) = obstacle.time_of_impact(&x[v], &delta[v]) {
                    first = first.min(t);
                }
            }
        }
        let mut longest = (TIME_OF_IMPACT_SHARE * first).min(1.0);
        if let Some(surface) = &self.surface {
            // Additive CCD of the sphere's (static) centre against each triangle, thickness r: it
            // keeps a tenth of each gap, as the vertices' cap does.
            let params = CcdParams::default();
            let still = Vector3::zeros();
            for tri in &surface.triangles {
                if !tri.iter().any(|&v| surface.free[v as usize]) {
                    continue;
                }
                let p = tri.map(|v| v3(&x[v as usize]));
                let d = tri.map(|v| v3(&delta[v as usize]));
                let (lo, hi) = (
                    p[0].inf(&p[1])
                        .inf(&p[2])
                        .inf(&(p[0] + d[0]))
                        .inf(&(p[1] + d[1]))
                        .inf(&(p[2] + d[2])),
                    p[0].sup(&p[1])
                        .sup(&p[2])
                        .sup(&(p[0] + d[0]))
                        .sup(&(p[1] + d[1]))
                        .sup(&(p[2] + d[2])),
                );
                for (c, r) in &surface.spheres {
                    // The swept box must come within the radius of the centre to meet the sphere.
                    if (0..3).any(|a| c[a] < lo[a] - r || c[a] > hi[a] + r) {
                        continue;
                    }
                    let outcome = point_triangle_ccd(
                        [c, &p[0], &p[1], &p[2]],
                        [&still, &d[0], &d[1], &d[2]],
                        longest,
                        *r,
                        &params,
                    );
                    longest = longest.min(outcome.time);
                }
            }
        }
        longest
    }
}
