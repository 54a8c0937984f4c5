//! Errors that the caller's data can cause (contract violations such as wrong buffer lengths panic
//! instead, with `#[track_caller]` and a message naming the buffer).

/// What went wrong while building an assembly structure from user data.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum AssemblyError {
    /// A pinned vertex index is not a vertex of the mesh.
    #[error("pinned vertex {vertex} (entry {position} of the pinned list) is out of range: the mesh has {vertex_count} vertices")]
    PinnedOutOfRange {
        /// Position in the pinned list.
        position: usize,
        /// The offending vertex index.
        vertex: u32,
        /// Number of vertices of the mesh.
        vertex_count: usize,
    },
    /// The pinned list is not strictly increasing (unsorted, or a vertex listed twice).
    #[error("the pinned list must be strictly increasing: entry {position} is {vertex} after {previous}")]
    PinnedNotSorted {
        /// Position in the pinned list of the entry that breaks the order.
        position: usize,
        /// The entry before it.
        previous: u32,
        /// The offending entry.
        vertex: u32,
    },
    /// More vertices than 32-bit indices can address (springs store `u32` vertex indices).
    #[error("{count} vertices exceed the u32 index range")]
    TooManyVertices {
        /// The vertex count asked for.
        count: usize,
    },
}
