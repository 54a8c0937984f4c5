//! The one error type of the mesh crate.

use std::fmt;
use std::path::PathBuf;

/// What kind of element an error refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ElementKind {
    /// A triangle of a surface mesh.
    Triangle,
    /// A tetrahedron of a volume mesh.
    Tetrahedron,
    /// A spring (an edge of the spring graph).
    Spring,
}

impl fmt::Display for ElementKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ElementKind::Triangle => "triangle",
            ElementKind::Tetrahedron => "tetrahedron",
            ElementKind::Spring => "spring",
        })
    }
}

/// Everything that can be wrong with a mesh, a spring graph or a mesh file.
///
/// Every variant names what it is about (vertex, element, spring, file and line) so that a user can
/// find the offending datum. Errors found while reading a file are wrapped in [`MeshError::InFile`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// The mesh has no vertices.
    #[error("the mesh is empty: it has no vertices")]
    Empty,
    /// The mesh has vertices but no elements (triangles, tetrahedra or springs) joining them.
    #[error("the mesh has no {kind}s")]
    NoElements {
        /// The kind of element that was expected.
        kind: ElementKind,
    },
    /// A coordinate is NaN or infinite.
    #[error("vertex {vertex}: coordinate {axis} is not finite ({value})")]
    NonFiniteCoordinate {
        /// Index of the vertex.
        vertex: usize,
        /// 0 for x, 1 for y, 2 for z.
        axis: usize,
        /// The offending value.
        value: f64,
    },
    /// An element refers to a vertex that does not exist.
    #[error("{kind} {element}: vertex index {index} is out of range (the mesh has {vertex_count} vertices)")]
    IndexOutOfRange {
        /// Kind of the element.
        kind: ElementKind,
        /// Index of the element.
        element: usize,
        /// The offending vertex index.
        index: usize,
        /// Number of vertices in the mesh.
        vertex_count: usize,
    },
    /// An element uses the same vertex twice.
    #[error("{kind} {element} repeats vertex {vertex}")]
    RepeatedVertex {
        /// Kind of the element.
        kind: ElementKind,
        /// Index of the element.
        element: usize,
        /// The repeated vertex.
        vertex: usize,
    },
    /// An element has (relative to its own size) zero area or volume.
    #[error("{kind} {element} is degenerate: its {} is {measure:e}, against {scale:e} for its size", if matches!(kind, ElementKind::Tetrahedron) { "volume" } else { "area" })]
    Degenerate {
        /// Kind of the element.
        kind: ElementKind,
        /// Index of the element.
        element: usize,
        /// Its area (m²) or volume (m³), unsigned.
        measure: f64,
        /// The measure of a regular-ish element of the same longest edge (L² or L³).
        scale: f64,
    },
    /// A spring whose rest length is zero, negative or not finite.
    #[error("spring {spring} ({i}–{j}): rest length {rest_length} must be positive and finite")]
    InvalidRestLength {
        /// Index of the spring.
        spring: usize,
        /// First vertex.
        i: usize,
        /// Second vertex.
        j: usize,
        /// The offending rest length (m).
        rest_length: f64,
    },
    /// A spring whose stiffness is zero, negative or not finite.
    #[error("spring {spring} ({i}–{j}): stiffness {stiffness} N/m must be positive and finite")]
    InvalidStiffness {
        /// Index of the spring.
        spring: usize,
        /// First vertex.
        i: usize,
        /// Second vertex.
        j: usize,
        /// The offending stiffness (N/m).
        stiffness: f64,
    },
    /// A vertex mass that is zero, negative or not finite.
    #[error("vertex {vertex}: mass {mass} kg must be positive and finite")]
    InvalidMass {
        /// Index of the vertex.
        vertex: usize,
        /// The offending mass (kg).
        mass: f64,
    },
    /// A parameter of a generator or a mass model is out of its domain.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// Name of the parameter.
        name: &'static str,
        /// Its value, as text.
        value: String,
        /// Why it is rejected.
        reason: &'static str,
    },
    /// Two arrays that must have the same length do not.
    #[error("{what}: expected {expected} entries, got {actual}")]
    LengthMismatch {
        /// What was being compared.
        what: &'static str,
        /// The expected length.
        expected: usize,
        /// The length found.
        actual: usize,
    },
    /// More vertices than a `u32` index can address.
    #[error(
        "{count} vertices is more than the {} that a u32 index can address",
        u32::MAX
    )]
    TooManyVertices {
        /// Number of vertices.
        count: usize,
    },
    /// The file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The file's content could not be parsed.
    #[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Parse {
        /// The file.
        path: PathBuf,
        /// The 1-based line, where the format has lines and the parser knows it.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// A mesh read from a file failed validation.
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with its mesh.
        #[source]
        source: Box<MeshError>,
    },
}

impl MeshError {
    /// Attach a file path to a validation error (used by the readers).
    pub fn in_file(self, path: impl Into<PathBuf>) -> MeshError {
        match self {
            // Already names a file.
            e @ (MeshError::Io { .. } | MeshError::Parse { .. } | MeshError::InFile { .. }) => e,
            e => MeshError::InFile {
                path: path.into(),
                source: Box::new(e),
            },
        }
    }
}
