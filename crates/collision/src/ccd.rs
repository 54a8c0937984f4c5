//! Conservative continuous collision detection of a point–triangle or edge–edge pair whose four
//! vertices move along straight lines: additive CCD (Li, Kaufman and Jiang 2021, "Codimensional
//! Incremental Potential Contact", Algorithm 1).
//!
//! - [`point_triangle_ccd`], [`edge_edge_ccd`]: the largest time found up to which the pair stays
//!   apart, as a [`CcdOutcome`], with the [`CcdParams`] that bound the work.
//!
//! **Method.** Vertex i moves as xᵢ + α dᵢ for α ∈ [0, t_max]. Subtracting the mean displacement
//! of the four (which moves nothing relative to anything else) leaves d̃ᵢ, and
//! l_p = |d̃_p| + maxₖ |d̃_tk| (point–triangle) or max(|d̃_ea0|, |d̃_ea1|) + max(|d̃_eb0|, |d̃_eb1|)
//! (edge–edge) bounds how fast the distance can change: every point of a triangle or segment is a
//! convex combination of its corners, so it moves at most as fast as the fastest corner, and the
//! distance, a minimum over such pairs of points, changes at most at the sum of the two rates. With
//! a thickness ξ ≥ 0 the gap is g(α) = (d² − ξ²)/(d + ξ) = d − ξ, and
//! |g(α) − g(β)| ≤ l_p |α − β|. So an advance from α by less than g(α)/l_p cannot close the gap:
//! additive CCD advances by (1 − s)·g₀/l_p first and by 0.9·g/l_p after, from the gap at the time
//! reached, until the gap falls below s·g₀ (s = [`CcdParams::kept_share`]); it then returns the
//! last time at which the gap was not below s·g₀. An advance that would pass t_max is cut to t_max
//! and checked like the others, so the pair keeps s·g₀ at t_max too. Each advance is certified on
//! its own, so the answer never passes a contact; it may stop short of one (it always keeps
//! s·g₀), and it stops short when the iteration bound is reached, which keeps the time bounded on
//! degenerate motion (two sheets sliding on each other at a constant small gap, coplanar motion)
//! where exact root finding is slow.
//!
//! What this module leaves to others: the distances ([`crate::distance`]), which pairs to test
//! ([`crate::broad_phase`]), and how the times of many pairs become a step length (the line
//! search in `hooke-solvers` takes their minimum).
//!
//! Units: metres for positions, displacements and the thickness; times are dimensionless
//! fractions of the displacements (α = 1 is the whole step).
//!
//! No function here allocates or panics.

use nalgebra::Vector3;

/// The share of the gap each advance after the first leaves: advances are 0.9·g/l_p, so the gap
/// never falls below a tenth of its value at the start of an advance.
const ADVANCE_SHARE: f64 = 0.9;

/// The parameters of additive CCD.
///
/// **Invariants** (otherwise the outcome is time 0, the safe answer): 0 < `kept_share` < 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CcdParams {
    /// s (dimensionless, in (0, 1)): the share of the starting gap g₀ that the pair keeps at the
    /// returned time. Default 0.1: each pair keeps at least a tenth of its starting gap, the same
    /// safety fraction as the obstacles' line search, which stops at 0.9 of the time of impact.
    /// Smaller values get closer to the contact at the cost of more iterations.
    pub kept_share: f64,
    /// The largest number of advances (distance evaluations). On reaching it the time reached so
    /// far is returned, which is safe (every advance is certified), with
    /// [`CcdOutcome::limited`] set. Default 10,000, enough for a relative motion of about
    /// 9,000 times the gap; each advance costs one distance evaluation.
    pub max_iterations: u32,
}

impl Default for CcdParams {
    fn default() -> Self {
        CcdParams {
            kept_share: 0.1,
            max_iterations: 10_000,
        }
    }
}

/// The result of a CCD query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CcdOutcome {
    /// The time reached, in [0, t_max]: for every α in [0, `time`] the pair is apart (distance
    /// above the thickness, in exact arithmetic: see the rounding caveat on
    /// [`point_triangle_ccd`]). `time == t_max`: no contact found up to t_max. Otherwise there may
    /// be a contact after `time`, or the search stopped short (`limited`). 0 when the pair
    /// touches at the start or an input is invalid.
    pub time: f64,
    /// The number of advances made (distance evaluations after the starting one).
    pub iterations: u32,
    /// Whether the search stopped before the gap fell below s·g₀ or t_max was reached: the
    /// iteration bound was hit, or advances fell below the rounding of the time. `time` is still
    /// safe, but may be far below the first contact.
    pub limited: bool,
}

impl CcdOutcome {
    #[inline]
    fn at(time: f64, iterations: u32, limited: bool) -> Self {
        CcdOutcome {
            time,
            iterations,
            limited,
        }
    }
}

/// Additive CCD on four vertices already moved to a local frame: `x` relative to the pair's first
/// vertex, `d` with the mean displacement removed, `l_p` the rate bound, `distance_squared` the
/// pair's squared distance of four positions.
fn additive(
    x: &[Vector3<f64>; 4],
    d: &[Vector3<f64>; 4],
    l_p: f64,
    t_max: f64,
    thickness: f64,
    params: &CcdParams,
    distance_squared: impl Fn(&[Vector3<f64>; 4]) -> f64,
) -> CcdOutcome {
    let s = params.kept_share;
    // Invalid inputs (NaN anywhere included) get the safe answer: no motion allowed.
    if !(thickness >= 0.0 && s > 0.0 && s < 1.0 && t_max >= 0.0) || l_p.is_nan() {
        return CcdOutcome::at(0.0, 0, false);
    }
    let thickness_squared = thickness * thickness;
    let gap = |squared: f64| (squared - thickness_squared) / (squared.sqrt() + thickness);
    let start = distance_squared(x);
    if start.is_nan() || start <= thickness_squared {
        // Touching already (or NaN positions).
        return CcdOutcome::at(0.0, 0, false);
    }
    if l_p == 0.0 {
        // No relative motion: the distance never changes.
        return CcdOutcome::at(t_max, 0, false);
    }
    if !l_p.is_finite() || t_max == 0.0 {
        return CcdOutcome::at(0.0, 0, false);
    }
    let start_gap = gap(start);
    let target = s * start_gap;
    let at_time = |t: f64| -> [Vector3<f64>; 4] { std::array::from_fn(|i| x[i] + d[i] * t) };

    let mut t = 0.0;
    // The first advance is certified to keep g ≥ g₀ − (1 − s)g₀ = s·g₀; it is accepted if the
    // computed gap is positive, since a pair closing at the full rate l_p lands exactly on s·g₀
    // and rounding would otherwise stop it at 0.
    let mut advance = (1.0 - s) * start_gap / l_p;
    let mut first = true;
    let mut iterations = 0;
    loop {
        if iterations >= params.max_iterations {
            return CcdOutcome::at(t, iterations, true);
        }
        iterations += 1;
        let (next, last) = if t + advance >= t_max {
            (t_max, true)
        } else {
            (t + advance, false)
        };
        if next <= t {
            // The advance is below the rounding of t: no progress is possible.
            return CcdOutcome::at(t, iterations, true);
        }
        let g = gap(distance_squared(&at_time(next)));
        // NaN fails both tests and stops.
        let kept = if first { g > 0.0 } else { g >= target };
        if !kept {
            return CcdOutcome::at(t, iterations, false);
        }
        if last {
            return CcdOutcome::at(t_max, iterations, false);
        }
        t = next;
        first = false;
        advance = ADVANCE_SHARE * g / l_p;
    }
}

/// The local frame of four moving vertices: positions relative to the first vertex's start (so
/// that the distances are computed on small coordinates) and displacements less their mean.
#[inline]
fn local_frame(
    x: [&Vector3<f64>; 4],
    d: [&Vector3<f64>; 4],
) -> ([Vector3<f64>; 4], [Vector3<f64>; 4]) {
    let origin = *x[0];
    let mean = (d[0] + d[1] + d[2] + d[3]) * 0.25;
    (x.map(|p| p - origin), d.map(|v| v - mean))
}

/// Additive CCD of the point `x[0]` against the triangle (`x[1]`, `x[2]`, `x[3]`), each vertex
/// moving as xᵢ + α dᵢ (m) for α ∈ [0, `t_max`], with thickness ξ = `thickness` (m, ≥ 0): 0 for
/// self-contact, the radius when the point is a static sphere's centre. The pair is apart while
/// the point–triangle distance exceeds ξ.
///
/// **Guarantee.** For every α in [0, time] the pair is apart; when time > 0, the gap there is at
/// least s·g₀ (s = [`CcdParams::kept_share`], g₀ the starting gap). `time == t_max`: no contact
/// up to t_max. The search may stop short of the first contact (by at least the kept share, and
/// further when motion and approach differ: a pair sliding past at speed l_p while closing slowly
/// takes many advances), and returns the time reached with `limited` set when it hits
/// [`CcdParams::max_iterations`]; it never passes a contact. Why: each advance is below g/l_p at
/// the time it starts from, and l_p bounds how fast the gap can close (module documentation).
///
/// A pair that touches or overlaps at α = 0 (d ≤ ξ) gets time 0. Any NaN input, a negative or
/// NaN `thickness` or `t_max`, an infinite displacement, or a `kept_share` outside (0, 1) gives
/// time 0 (never a false "free" answer). No relative motion gives t_max.
///
/// **Rounding.** The guarantee holds for the computed gaps: distances are computed in a frame at
/// the pair's first vertex moving with the pair's mean displacement, so they carry errors of a
/// few ulps of the pair's size plus its motion, and each advance's 10 % margin absorbs the
/// rounding of the advance itself. A gap comparable to those errors (or to the rounding of the
/// caller's own coordinates, where the caller evaluates distances again) is not certified; keep
/// gaps and thicknesses well above about 1e-12 times the coordinates.
pub fn point_triangle_ccd(
    x: [&Vector3<f64>; 4],
    d: [&Vector3<f64>; 4],
    t_max: f64,
    thickness: f64,
    params: &CcdParams,
) -> CcdOutcome {
    let (x, d) = local_frame(x, d);
    let l_p = d[0].norm() + d[1].norm().max(d[2].norm()).max(d[3].norm());
    additive(&x, &d, l_p, t_max, thickness, params, |p| {
        crate::distance::point_triangle_distance_squared(&p[0], &p[1], &p[2], &p[3])
    })
}

/// Additive CCD of the segment (`x[0]`, `x[1]`) against the segment (`x[2]`, `x[3]`), each vertex
/// moving as xᵢ + α dᵢ (m) for α ∈ [0, `t_max`], with thickness ξ = `thickness` (m, ≥ 0; 0 for
/// self-contact). The pair is apart while the segment–segment distance exceeds ξ.
///
/// The guarantee, the special cases and the rounding caveat are those of
/// [`point_triangle_ccd`], with l_p = max(|d̃_ea0|, |d̃_ea1|) + max(|d̃_eb0|, |d̃_eb1|). Parallel
/// and coplanar segments need no special case: the distance is that of closed segments.
pub fn edge_edge_ccd(
    x: [&Vector3<f64>; 4],
    d: [&Vector3<f64>; 4],
    t_max: f64,
    thickness: f64,
    params: &CcdParams,
) -> CcdOutcome {
    let (x, d) = local_frame(x, d);
    let l_p = d[0].norm().max(d[1].norm()) + d[2].norm().max(d[3].norm());
    additive(&x, &d, l_p, t_max, thickness, params, |p| {
        crate::distance::edge_edge_distance_squared(&p[0], &p[1], &p[2], &p[3])
    })
}
