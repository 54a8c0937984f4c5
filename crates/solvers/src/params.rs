//! Validation of the solvers' parameter structs: every struct has a `validate()` that names the
//! first field out of its range, and every solver calls it where the struct enters (its
//! constructor, and again at the start of a solve, since the settings are public fields).

/// A parameter outside its allowed range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ParamError {
    /// A real-valued field out of range (NaN and ±∞ included where not allowed).
    #[error("{field} = {value:e} is out of range: it must be {allowed}")]
    Real {
        /// The field, as `Struct::field` (nested structs as `Outer::inner.field`).
        field: &'static str,
        /// The offending value.
        value: f64,
        /// The allowed range, in words.
        allowed: &'static str,
    },
    /// An integer field out of range.
    #[error("{field} = {value} is out of range: it must be {allowed}")]
    Count {
        /// The field, as `Struct::field`.
        field: &'static str,
        /// The offending value.
        value: usize,
        /// The allowed range, in words.
        allowed: &'static str,
    },
    /// A structured input that does not fit (an index out of range, a length mismatch, a
    /// dimension a model does not support).
    #[error("{field}: {problem}")]
    Input {
        /// The field, as `Struct::field`.
        field: &'static str,
        /// What is wrong, naming the offending entry.
        problem: String,
    },
}

impl ParamError {
    /// The field that was rejected.
    pub fn field(&self) -> &'static str {
        match self {
            ParamError::Real { field, .. }
            | ParamError::Count { field, .. }
            | ParamError::Input { field, .. } => field,
        }
    }
}

/// The most threads a factorisation may be asked for: far above any machine's cores, low enough
/// that a typo (or `usize::MAX`) is refused instead of spawning.
pub const MAX_THREADS: usize = 1024;

/// How many records a solver reserves for its history before a solve: the history grows beyond
/// it as iterations go (once per doubling), and a huge iteration limit reserves no more than this.
pub(crate) const HISTORY_RESERVE: usize = 1024;

/// `Ok` if `value` lies in `range` (NaN never does).
pub(crate) fn real(
    field: &'static str,
    value: f64,
    ok: bool,
    allowed: &'static str,
) -> Result<(), ParamError> {
    if ok && !value.is_nan() {
        Ok(())
    } else {
        Err(ParamError::Real {
            field,
            value,
            allowed,
        })
    }
}

/// `Ok` if `value` is finite and > 0.
pub(crate) fn positive(field: &'static str, value: f64) -> Result<(), ParamError> {
    real(
        field,
        value,
        value > 0.0 && value.is_finite(),
        "finite and > 0",
    )
}

/// `Ok` if `value` is finite and ≥ 0.
pub(crate) fn non_negative(field: &'static str, value: f64) -> Result<(), ParamError> {
    real(
        field,
        value,
        value >= 0.0 && value.is_finite(),
        "finite and >= 0",
    )
}

/// `Ok` if `value` ≥ `min`.
pub(crate) fn at_least(
    field: &'static str,
    value: usize,
    min: usize,
    allowed: &'static str,
) -> Result<(), ParamError> {
    if value >= min {
        Ok(())
    } else {
        Err(ParamError::Count {
            field,
            value,
            allowed,
        })
    }
}

/// `Ok` if `min` ≤ `value` ≤ `max`.
pub(crate) fn count_in(
    field: &'static str,
    value: usize,
    min: usize,
    max: usize,
    allowed: &'static str,
) -> Result<(), ParamError> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(ParamError::Count {
            field,
            value,
            allowed,
        })
    }
}
