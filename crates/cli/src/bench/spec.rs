//! Solver specifications: `NAME` or `NAME:V1,V2,…`, one run per value.

use std::fmt;
use std::str::FromStr;

use crate::bench::BenchError;

/// A solver family that `hooke bench` can time and measure, and what its values mean.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum SolverKind {
    /// `pd:K`: projective dynamics, K iterations from x⁰ = y (the factorisation is done once, apart).
    Pd,
    /// `pd-tol:T`: projective dynamics until the largest position change of an iteration divided
    /// by h is at most T m/s (at most 10,000 iterations).
    PdTol,
    /// `pd-amg:K`: as `pd`, with the global step on the multilevel path (CG with a smoothed-
    /// aggregation V-cycle, docs/solvers.md §6.1) whatever the size; `pd` takes that path only
    /// above the size where it pays.
    PdAmg,
    /// `newton:K`: Newton on Φ from x⁰ = y, exactly K iterations (fewer only if it stagnates at
    /// the round-off floor).
    Newton,
    /// `newton-tol:T`: Newton on Φ until the relative gradient ‖∇Φ(x)‖/‖∇Φ(y)‖ ≤ T (at most 500
    /// iterations).
    NewtonTol,
    /// `cg:K`: the linearised integrator (β = 1, one Newton step from x_n) with its linear system
    /// solved by block-Jacobi-preconditioned CG, K iterations.
    Cg,
    /// `cg-tol:T`: as `cg`, CG to a relative residual of T (at most 10,000 iterations).
    CgTol,
    /// `jacobi:K`: the linearised integrator (β = 1) with block Jacobi, K iterations.
    Jacobi,
    /// `jacobi-tol:T`: as `jacobi`, to a relative residual of T (at most 10,000 iterations).
    JacobiTol,
    /// `linearized-cg`: the linearised integrator (β = 1) with its default linear solve (CG to
    /// 1e-8).
    LinearizedCg,
    /// `linearized-jacobi`: the linearised integrator (β = 1) with block Jacobi to 1e-8.
    LinearizedJacobi,
    /// `lbfgs:K`: L-BFGS on Φ from x⁰ = y with PD's prefactored matrix as initial Hessian, K
    /// iterations (history 5; the factorisation is done once, apart, as PD's).
    Lbfgs,
    /// `lbfgs-tol:T`: as `lbfgs`, until the relative gradient ≤ T (at most 10,000 iterations).
    LbfgsTol,
    /// `chebyshev:K`: Chebyshev-accelerated PD, K iterations, ρ estimated once per scene from 20
    /// plain PD iterations of the step (not timed, as the factorisation).
    Chebyshev,
    /// `anderson:K`: Anderson-accelerated PD (window 8, energy guard against the plain iterate),
    /// K iterations.
    Anderson,
    /// `newton-cg:K`: inexact Newton (PCG on the exact Hessian, preconditioned by PD's factor,
    /// Eisenstat–Walker forcing), K Newton iterations.
    NewtonCg,
    /// `newton-cg-tol:T`: as `newton-cg`, until the relative gradient ≤ T (at most 500 iterations).
    NewtonCgTol,
    /// `newton-cg-amg:K`: as `newton-cg`, with PCG preconditioned by smoothed-aggregation AMG
    /// (docs/solvers.md §2.4) set up on the clamped Hessian at y, inside the timed step.
    NewtonCgAmg,
    /// `newton-cg-amg-tol:T`: as `newton-cg-amg`, until the relative gradient ≤ T (at most 500
    /// iterations).
    NewtonCgAmgTol,
    /// `newton-relaxed:K`: as `newton`, with the opt-in nonlinear relaxation
    /// ([`crate::solvers::Relaxation::BUCKLING`]) after every accepted step.
    NewtonRelaxed,
    /// `newton-relaxed-tol:T`: as `newton-tol`, with the relaxation.
    NewtonRelaxedTol,
    /// `newton-projected:K`: as `newton`, factoring the Hessian made positive definite spring by
    /// spring before the factorisation ([`crate::solvers::IndefinitePolicy::Projected`], the
    /// mass-split projection of docs/solvers.md §3.2) instead of the convex blend.
    NewtonProjected,
    /// `newton-projected-tol:T`: as `newton-tol`, with the projected Hessian.
    NewtonProjectedTol,
    /// `newton-projected-exact:K`: as `newton-projected`, switching to the exact Hessian after
    /// full steps ([`crate::solvers::IndefinitePolicy::ProjectedThenExact`]).
    NewtonProjectedExact,
    /// `newton-projected-exact-tol:T`: as `newton-tol`, with that policy.
    NewtonProjectedExactTol,
    /// `newton-projected-pcg:K`: as `newton`, the exact Newton system solved by CG preconditioned
    /// with the factor of the definite Hessian, one factorisation per iteration
    /// ([`crate::solvers::IndefinitePolicy::ProjectedPreconditioned`]).
    NewtonProjectedPcg,
    /// `newton-projected-pcg-tol:T`: as `newton-tol`, with that policy.
    NewtonProjectedPcgTol,
}

impl SolverKind {
    /// Every kind, in the order the help and the tables list them.
    pub const ALL: &'static [SolverKind] = &[
        SolverKind::Pd,
        SolverKind::PdTol,
        SolverKind::PdAmg,
        SolverKind::Newton,
        SolverKind::NewtonTol,
        SolverKind::Cg,
        SolverKind::CgTol,
        SolverKind::Jacobi,
        SolverKind::JacobiTol,
        SolverKind::LinearizedCg,
        SolverKind::LinearizedJacobi,
        SolverKind::Lbfgs,
        SolverKind::LbfgsTol,
        SolverKind::Chebyshev,
        SolverKind::Anderson,
        SolverKind::NewtonCg,
        SolverKind::NewtonCgTol,
        SolverKind::NewtonCgAmg,
        SolverKind::NewtonCgAmgTol,
        SolverKind::NewtonRelaxed,
        SolverKind::NewtonRelaxedTol,
        SolverKind::NewtonProjected,
        SolverKind::NewtonProjectedTol,
        SolverKind::NewtonProjectedExact,
        SolverKind::NewtonProjectedExactTol,
        SolverKind::NewtonProjectedPcg,
        SolverKind::NewtonProjectedPcgTol,
    ];

    /// The name in a spec and in the records' `solver` field.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Pd => "pd",
            SolverKind::PdTol => "pd-tol",
            SolverKind::PdAmg => "pd-amg",
            SolverKind::Newton => "newton",
            SolverKind::NewtonTol => "newton-tol",
            SolverKind::Cg => "cg",
            SolverKind::CgTol => "cg-tol",
            SolverKind::Jacobi => "jacobi",
            SolverKind::JacobiTol => "jacobi-tol",
            SolverKind::LinearizedCg => "linearized-cg",
            SolverKind::LinearizedJacobi => "linearized-jacobi",
            SolverKind::Lbfgs => "lbfgs",
            SolverKind::LbfgsTol => "lbfgs-tol",
            SolverKind::Chebyshev => "chebyshev",
            SolverKind::Anderson => "anderson",
            SolverKind::NewtonCg => "newton-cg",
            SolverKind::NewtonCgTol => "newton-cg-tol",
            SolverKind::NewtonCgAmg => "newton-cg-amg",
            SolverKind::NewtonCgAmgTol => "newton-cg-amg-tol",
            SolverKind::NewtonRelaxed => "newton-relaxed",
            SolverKind::NewtonRelaxedTol => "newton-relaxed-tol",
            SolverKind::NewtonProjected => "newton-projected",
            SolverKind::NewtonProjectedTol => "newton-projected-tol",
            SolverKind::NewtonProjectedExact => "newton-projected-exact",
            SolverKind::NewtonProjectedExactTol => "newton-projected-exact-tol",
            SolverKind::NewtonProjectedPcg => "newton-projected-pcg",
            SolverKind::NewtonProjectedPcgTol => "newton-projected-pcg-tol",
        }
    }

    /// How the kind is written in a spec and what it runs, in a few words, for `hooke bench
    /// --help`: e.g. `pd:K,… (projective dynamics, K iterations)`.
    pub fn usage(self) -> String {
        let what = match self {
            SolverKind::Pd => "projective dynamics",
            SolverKind::PdTol => {
                "projective dynamics to an estimated distance of T m/s from the solution"
            }
            SolverKind::PdAmg => "projective dynamics, multilevel global step",
            SolverKind::Newton => "Newton",
            SolverKind::NewtonTol => "Newton to a relative gradient of T",
            SolverKind::Cg => "linearised step, CG",
            SolverKind::CgTol => "linearised step, CG to a relative residual of T",
            SolverKind::Jacobi => "linearised step, block Jacobi",
            SolverKind::JacobiTol => "linearised step, block Jacobi to a relative residual of T",
            SolverKind::LinearizedCg => "linearised step, CG to 1e-8",
            SolverKind::LinearizedJacobi => "linearised step, block Jacobi to 1e-8",
            SolverKind::Lbfgs => "L-BFGS on PD's factor",
            SolverKind::LbfgsTol => "L-BFGS to a relative gradient of T",
            SolverKind::Chebyshev => "Chebyshev PD",
            SolverKind::Anderson => "Anderson PD, window 8",
            SolverKind::NewtonCg => "inexact Newton, PCG",
            SolverKind::NewtonCgTol => "inexact Newton to a relative gradient of T",
            SolverKind::NewtonCgAmg => "inexact Newton, PCG with an AMG preconditioner",
            SolverKind::NewtonCgAmgTol => "inexact Newton with AMG to a relative gradient of T",
            SolverKind::NewtonRelaxed => "Newton with the buckling relaxation",
            SolverKind::NewtonRelaxedTol => "relaxed Newton to a relative gradient of T",
            SolverKind::NewtonProjected => "Newton on the spring-by-spring definite Hessian",
            SolverKind::NewtonProjectedTol => {
                "Newton on the definite Hessian to a relative gradient of T"
            }
            SolverKind::NewtonProjectedExact => {
                "Newton on the definite Hessian, exact after full steps"
            }
            SolverKind::NewtonProjectedExactTol => {
                "Newton, definite then exact, to a relative gradient of T"
            }
            SolverKind::NewtonProjectedPcg => {
                "Newton, exact system by CG on the definite Hessian's factor"
            }
            SolverKind::NewtonProjectedPcgTol => {
                "Newton, exact system by CG on the definite factor, to a relative gradient of T"
            }
        };
        match self.values() {
            Values::Iterations => format!("{}:K,… ({what}, K iterations)", self.name()),
            Values::Tolerances => format!("{}:T,… ({what})", self.name()),
            Values::None => format!("{} ({what})", self.name()),
        }
    }

    /// What the values of this kind are: iteration counts, tolerances, or none.
    fn values(self) -> Values {
        match self {
            SolverKind::Pd
            | SolverKind::PdAmg
            | SolverKind::Newton
            | SolverKind::Cg
            | SolverKind::Jacobi
            | SolverKind::Lbfgs
            | SolverKind::Chebyshev
            | SolverKind::Anderson
            | SolverKind::NewtonCg
            | SolverKind::NewtonCgAmg
            | SolverKind::NewtonRelaxed
            | SolverKind::NewtonProjected
            | SolverKind::NewtonProjectedExact
            | SolverKind::NewtonProjectedPcg => Values::Iterations,
            SolverKind::PdTol
            | SolverKind::NewtonTol
            | SolverKind::CgTol
            | SolverKind::JacobiTol
            | SolverKind::LbfgsTol
            | SolverKind::NewtonCgTol
            | SolverKind::NewtonCgAmgTol
            | SolverKind::NewtonRelaxedTol
            | SolverKind::NewtonProjectedTol
            | SolverKind::NewtonProjectedExactTol
            | SolverKind::NewtonProjectedPcgTol => Values::Tolerances,
            SolverKind::LinearizedCg | SolverKind::LinearizedJacobi => Values::None,
        }
    }

    /// The settings used when a spec names the kind without values.
    pub fn default_settings(self) -> Vec<Setting> {
        let iterations = |v: &[usize]| v.iter().map(|&k| Setting::Iterations(k)).collect();
        let tolerances = |v: &[f64]| v.iter().map(|&t| Setting::Tolerance(t)).collect();
        match self {
            SolverKind::Pd | SolverKind::PdAmg => iterations(&[1, 2, 5, 10, 20, 50, 100]),
            SolverKind::PdTol => tolerances(&[1e-2, 1e-3, 1e-4]),
            SolverKind::Newton => iterations(&[1, 2, 3, 5, 10]),
            SolverKind::NewtonTol => tolerances(&[1e-2, 1e-4, 1e-6, 1e-8]),
            SolverKind::Cg => iterations(&[1, 5, 20, 100]),
            SolverKind::CgTol => tolerances(&[1e-1, 1e-2, 1e-4, 1e-6]),
            SolverKind::Jacobi => iterations(&[10, 100]),
            SolverKind::JacobiTol => tolerances(&[1e-2, 1e-4]),
            SolverKind::LinearizedCg | SolverKind::LinearizedJacobi => vec![Setting::Default],
            SolverKind::Lbfgs => iterations(&[5, 10, 20, 50, 100, 200]),
            SolverKind::LbfgsTol => tolerances(&[1e-2, 1e-4, 1e-6, 1e-8]),
            SolverKind::Chebyshev => iterations(&[5, 10, 20, 50, 100]),
            SolverKind::Anderson => iterations(&[5, 10, 20, 50, 100]),
            SolverKind::NewtonCg => iterations(&[1, 2, 3, 5, 10]),
            SolverKind::NewtonCgTol => tolerances(&[1e-2, 1e-4, 1e-6, 1e-8]),
            SolverKind::NewtonCgAmg => iterations(&[1, 2, 3, 5, 10]),
            SolverKind::NewtonCgAmgTol => tolerances(&[1e-2, 1e-4, 1e-6, 1e-8]),
            SolverKind::NewtonRelaxed => iterations(&[1, 2, 3, 5, 10]),
            SolverKind::NewtonRelaxedTol => tolerances(&[1e-2, 1e-4, 1e-6, 1e-8]),
            SolverKind::NewtonProjected => iterations(&[1, 2, 3, 5, 10]),
            SolverKind::NewtonProjectedTol => tolerances(&[1e-2, 1e-4, 1e-6, 1e-8]),
            SolverKind::NewtonProjectedExact => iterations(&[1, 2, 3, 5, 10]),
            SolverKind::NewtonProjectedExactTol => tolerances(&[1e-2, 1e-4, 1e-6, 1e-8]),
            SolverKind::NewtonProjectedPcg => iterations(&[1, 2, 3, 5, 10]),
            SolverKind::NewtonProjectedPcgTol => tolerances(&[1e-2, 1e-4, 1e-6, 1e-8]),
        }
    }
}

impl fmt::Display for SolverKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Values {
    Iterations,
    Tolerances,
    None,
}

/// One setting of a solver: an iteration count, a tolerance, or the solver's default.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Setting {
    /// A fixed iteration count (at least 1).
    Iterations(usize),
    /// A relative tolerance (finite, in (0, 1)).
    Tolerance(f64),
    /// The solver's own defaults.
    Default,
}

impl fmt::Display for Setting {
    /// As in the records' `setting` field: `10`, `1e-6`, `default`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Setting::Iterations(k) => write!(f, "{k}"),
            Setting::Tolerance(t) => write!(f, "{t:e}"),
            Setting::Default => f.write_str("default"),
        }
    }
}

/// A parsed `--solver` argument: a kind and its settings, in the order given.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverSpec {
    /// The solver family.
    pub kind: SolverKind,
    /// One run per setting.
    pub settings: Vec<Setting>,
}

impl SolverSpec {
    /// The specs `hooke bench` uses when none is given, so that the table shows the whole front
    /// from a rough step to Newton's answer: PD, Chebyshev PD, Anderson PD and L-BFGS by iteration
    /// count, Newton by iteration count and by tolerance, Newton-CG with AMG by tolerance, the linearised
    /// integrator with CG by tolerance, with Jacobi by iteration count, and with its default solve.
    pub fn defaults() -> Vec<SolverSpec> {
        [
            SolverKind::Pd,
            SolverKind::Chebyshev,
            SolverKind::Anderson,
            SolverKind::Lbfgs,
            SolverKind::Newton,
            SolverKind::NewtonTol,
            SolverKind::NewtonCgAmgTol,
            SolverKind::CgTol,
            SolverKind::Jacobi,
            SolverKind::LinearizedCg,
        ]
        .into_iter()
        .map(SolverSpec::all_defaults)
        .collect()
    }

    /// The spec for `kind` with its default settings.
    pub fn all_defaults(kind: SolverKind) -> SolverSpec {
        SolverSpec {
            kind,
            settings: kind.default_settings(),
        }
    }
}

impl FromStr for SolverSpec {
    type Err = BenchError;

    /// `NAME` (the kind's default settings) or `NAME:V1,V2,…`.
    fn from_str(spec: &str) -> Result<Self, Self::Err> {
        let (name, list) = match spec.split_once(':') {
            Some((name, list)) => (name.trim(), Some(list)),
            None => (spec.trim(), None),
        };
        let kind = SolverKind::ALL
            .iter()
            .copied()
            .find(|k| k.name() == name)
            .ok_or_else(|| BenchError::UnknownSolver {
                spec: spec.to_string(),
                name: name.to_string(),
            })?;
        let bad = |value: &str, reason: &str| BenchError::BadSetting {
            spec: spec.to_string(),
            value: value.to_string(),
            reason: reason.to_string(),
        };
        let Some(list) = list else {
            return Ok(SolverSpec::all_defaults(kind));
        };
        let settings = match kind.values() {
            Values::None => {
                return Err(bad(
                    list,
                    &format!("{name} takes no values (write just `{name}`)"),
                ))
            }
            Values::Iterations => list
                .split(',')
                .map(|v| {
                    let v = v.trim();
                    match v.parse::<usize>() {
                        Ok(k) if k >= 1 => Ok(Setting::Iterations(k)),
                        _ => Err(bad(v, "expected an iteration count, a whole number ≥ 1")),
                    }
                })
                .collect::<Result<Vec<_>, _>>()?,
            Values::Tolerances => list
                .split(',')
                .map(|v| {
                    let v = v.trim();
                    match v.parse::<f64>() {
                        Ok(t) if t > 0.0 && t < 1.0 => Ok(Setting::Tolerance(t)),
                        _ => Err(bad(v, "expected a relative tolerance in (0, 1), e.g. 1e-6")),
                    }
                })
                .collect::<Result<Vec<_>, _>>()?,
        };
        Ok(SolverSpec { kind, settings })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_lists_and_defaults() {
        let s: SolverSpec = "pd:1,2,5".parse().unwrap();
        assert_eq!(s.kind, SolverKind::Pd);
        assert_eq!(
            s.settings,
            vec![
                Setting::Iterations(1),
                Setting::Iterations(2),
                Setting::Iterations(5)
            ]
        );
        let s: SolverSpec = "newton-tol:1e-2, 1e-6".parse().unwrap();
        assert_eq!(
            s.settings,
            vec![Setting::Tolerance(1e-2), Setting::Tolerance(1e-6)]
        );
        let s: SolverSpec = "linearized-cg".parse().unwrap();
        assert_eq!(s.settings, vec![Setting::Default]);
        let s: SolverSpec = "pd".parse().unwrap();
        assert_eq!(s.settings.len(), 7);
        assert_eq!(Setting::Tolerance(1e-6).to_string(), "1e-6");
    }

    #[test]
    fn refuses_bad_specs_with_a_message() {
        for (spec, needle) in [
            ("pdx:1", "unknown solver"),
            ("pd:0", "iteration count"),
            ("pd:1,,2", "iteration count"),
            ("newton-tol:2", "tolerance"),
            ("cg-tol:nan", "tolerance"),
            ("linearized-cg:3", "takes no values"),
        ] {
            let e = spec.parse::<SolverSpec>().unwrap_err().to_string();
            assert!(e.contains(needle), "{spec}: {e}");
        }
    }
}
