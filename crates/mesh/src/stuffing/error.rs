//! The error type of the tetrahedral mesher.

use crate::MeshError;

/// Everything that can stop [`tetrahedralize`](super::tetrahedralize) or
/// [`ClosedSurface::new`](super::ClosedSurface::new).
///
/// Surface checks name the first offending edge (its two vertex indices, in the input's numbering)
/// and the triangle(s) that use it, so that a user can find the defect in a modelling program.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StuffingError {
    /// The triangle mesh itself is invalid (empty, a NaN or infinite coordinate, an index out of
    /// range, a repeated vertex, a zero-area triangle).
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// An edge used by only one triangle: the surface has a hole and encloses no volume.
    #[error("the surface is open: edge {a}–{b} belongs only to triangle {triangle}")]
    OpenEdge {
        /// First vertex of the edge.
        a: usize,
        /// Second vertex of the edge.
        b: usize,
        /// The one triangle that uses it.
        triangle: usize,
    },
    /// An edge used by three or more triangles: the surface is not a 2-manifold there.
    #[error(
        "the surface is not manifold: edge {a}–{b} belongs to {count} triangles (the first is {triangle})"
    )]
    NonManifoldEdge {
        /// First vertex of the edge.
        a: usize,
        /// Second vertex of the edge.
        b: usize,
        /// How many triangles use it (3 or more).
        count: usize,
        /// The first triangle (lowest index) that uses it.
        triangle: usize,
    },
    /// Two triangles that share an edge traverse it in the same direction: their normals disagree, so
    /// the surface has no consistent inside.
    #[error(
        "the surface's orientation is inconsistent: triangles {first} and {second} both run edge {a}→{b} the same way"
    )]
    InconsistentOrientation {
        /// The edge's start vertex, as both triangles run it.
        a: usize,
        /// The edge's end vertex.
        b: usize,
        /// The first triangle.
        first: usize,
        /// The second triangle.
        second: usize,
    },
    /// The closed surface encloses (relative to its size) no volume.
    #[error(
        "the surface encloses no volume: {volume:e} m³ against {scale:e} m³ for its bounding box"
    )]
    ZeroVolume {
        /// Its enclosed volume (m³), unsigned.
        volume: f64,
        /// The volume of its bounding box (m³).
        scale: f64,
    },
    /// A parameter of the mesher is out of its domain.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// The field's name.
        name: &'static str,
        /// Its value, as text.
        value: String,
        /// The allowed range.
        reason: &'static str,
    },
    /// The lattice that the spacing asks for is larger than the limit.
    #[error(
        "a lattice spacing of {spacing} m over this surface needs {vertices} lattice vertices, more than the limit of {limit} (raise StuffingOptions::max_lattice_vertices or the spacing)"
    )]
    LatticeTooLarge {
        /// The spacing asked for (m).
        spacing: f64,
        /// The number of lattice vertices it needs.
        vertices: u64,
        /// The limit.
        limit: u64,
    },
    /// No lattice vertex falls inside the surface: the spacing is too coarse for so thin a solid.
    #[error("no tetrahedra: no lattice vertex at spacing {spacing} m lies inside the surface; use a smaller spacing")]
    NoTetrahedra {
        /// The spacing used (m).
        spacing: f64,
    },
    /// The surface has a feature thinner than about a spacing (a thin plate or tube, a sharp crease,
    /// two sheets that nearly touch) where lattice vertices from both sides were warped onto it and
    /// the mesh's boundary would pinch (not be a manifold) even after the repair.
    #[error(
        "the surface has a feature thinner than the spacing {spacing} m near ({:.6e}, {:.6e}, {:.6e}): the mesh's boundary would pinch there; use a smaller spacing",
        point[0], point[1], point[2]
    )]
    UnresolvedFeature {
        /// Where (m): a warped lattice vertex at the pinch, on the surface.
        point: [f64; 3],
        /// The spacing used (m).
        spacing: f64,
    },
    /// A vertex where the surface's triangles form two or more fans that meet only at that vertex
    /// (a "bowtie": two solids touching at a point, or a cone pinched to a point). Every edge may be
    /// manifold, but the surface is not a 2-manifold there, and no lattice spacing resolves it.
    #[error(
        "the surface is not manifold: non-manifold vertex {vertex}: its triangles form {fans} fans that meet only at this vertex (one of them contains triangle {triangle})"
    )]
    NonManifoldVertex {
        /// The vertex (in the input's numbering, the first of bit-identical copies).
        vertex: usize,
        /// How many fans of triangles meet there (2 or more).
        fans: usize,
        /// The lowest-numbered triangle at the vertex.
        triangle: usize,
    },
    /// Two triangles of the surface intersect (or touch) away from the vertices and edges they
    /// share: the surface is self-intersecting and bounds no well-defined solid. No lattice spacing
    /// resolves it; the surface must be repaired.
    #[error("the surface is self-intersecting: triangles {first} and {second} intersect")]
    SelfIntersecting {
        /// The lower-numbered triangle of the first intersecting pair found (by that number, then
        /// the other's).
        first: usize,
        /// The other triangle.
        second: usize,
    },
    /// parry3d could not build its query structure (triangle BVH and pseudo-normals) over the
    /// surface.
    #[error("the surface's query structure could not be built: {reason}")]
    SurfaceQuery {
        /// parry3d's message.
        reason: String,
    },
    /// An output tetrahedron whose volume is not positive once its vertices are warped: it would
    /// overlap its neighbours. The paper's angle bounds exclude this; the mesher refuses rather
    /// than reorient it.
    #[error(
        "internal error: a tetrahedron near ({:.6e}, {:.6e}, {:.6e}) is inverted (volume {volume:e} m³) at spacing {spacing} m",
        point[0], point[1], point[2]
    )]
    InvertedTetrahedron {
        /// Its centroid (m).
        point: [f64; 3],
        /// Its signed volume (m³), zero or negative.
        volume: f64,
        /// The spacing used (m).
        spacing: f64,
    },
    /// An invariant of the algorithm does not hold (a bug, not a property of the input): the
    /// mesher refuses rather than return a mesh it cannot vouch for.
    #[error(
        "internal error: {what}, near ({:.6e}, {:.6e}, {:.6e}) at spacing {spacing} m",
        point[0], point[1], point[2]
    )]
    BrokenInvariant {
        /// What failed.
        what: &'static str,
        /// Where (m).
        point: [f64; 3],
        /// The spacing used (m).
        spacing: f64,
    },
}
