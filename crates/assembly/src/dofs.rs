//! Fixed-vertex reduction (docs/model.md §5.2): the map between the full vertex
//! numbering and the free vertices, x = Kᵀ x_f + b with K the identity with the pinned rows removed.
//!
//! Matrices over the free degrees of freedom are assembled directly on the free vertices (see
//! [`crate::hessian::HessianPattern`]); K is never formed and nothing is multiplied by it.

use crate::AssemblyError;

/// Marks a pinned vertex in [`FreeDofs`]' full → free table.
const PINNED: u32 = u32::MAX;

/// The free vertices of a mesh and their numbering: free vertex `f` is the `f`-th unpinned vertex in
/// increasing full index order. Vector-valued DOFs are numbered vertex-major: DOF `D·f + a` is
/// component `a` of free vertex `f`.
///
/// Invariants: the pinned list is strictly increasing and in range; `free_count + pinned.len() ==
/// vertex_count`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FreeDofs {
    /// Full vertex → free index, or `PINNED`.
    free_index: Vec<u32>,
    /// Free index → full vertex.
    free_vertices: Vec<u32>,
    /// Pinned vertices, strictly increasing.
    pinned: Vec<u32>,
}

impl FreeDofs {
    /// Every vertex free.
    ///
    /// # Panics
    /// If `vertex_count` exceeds the `u32` index range (use [`FreeDofs::new`] to get an error instead).
    #[track_caller]
    pub fn all_free(vertex_count: usize) -> Self {
        Self::new(vertex_count, &[]).expect("FreeDofs::all_free: too many vertices for u32 indices")
    }

    /// The free vertices of a mesh of `vertex_count` vertices with the vertices of `pinned` fixed.
    ///
    /// # Errors
    /// [`AssemblyError::PinnedNotSorted`] if `pinned` is not strictly increasing,
    /// [`AssemblyError::PinnedOutOfRange`] for an index ≥ `vertex_count`, and
    /// [`AssemblyError::TooManyVertices`] beyond the `u32` index range.
    pub fn new(vertex_count: usize, pinned: &[u32]) -> Result<Self, AssemblyError> {
        if vertex_count >= PINNED as usize {
            return Err(AssemblyError::TooManyVertices {
                count: vertex_count,
            });
        }
        for (position, &vertex) in pinned.iter().enumerate() {
            if vertex as usize >= vertex_count {
                return Err(AssemblyError::PinnedOutOfRange {
                    position,
                    vertex,
                    vertex_count,
                });
            }
            if position > 0 && pinned[position - 1] >= vertex {
                return Err(AssemblyError::PinnedNotSorted {
                    position,
                    previous: pinned[position - 1],
                    vertex,
                });
            }
        }
        let mut free_index = vec![0u32; vertex_count];
        let mut free_vertices = Vec::with_capacity(vertex_count - pinned.len());
        let mut next_pinned = pinned.iter().peekable();
        for (vertex, slot) in free_index.iter_mut().enumerate() {
            if next_pinned.peek().is_some_and(|&&p| p as usize == vertex) {
                next_pinned.next();
                *slot = PINNED;
            } else {
                *slot = free_vertices.len() as u32;
                free_vertices.push(vertex as u32);
            }
        }
        Ok(FreeDofs {
            free_index,
            free_vertices,
            pinned: pinned.to_vec(),
        })
    }

    /// Number of vertices of the full mesh.
    pub fn vertex_count(&self) -> usize {
        self.free_index.len()
    }

    /// Number of free vertices.
    pub fn free_count(&self) -> usize {
        self.free_vertices.len()
    }

    /// The pinned vertices, strictly increasing.
    pub fn pinned(&self) -> &[u32] {
        &self.pinned
    }

    /// The free vertices in free order: `free_vertices()[f]` is the full index of free vertex `f`.
    pub fn free_vertices(&self) -> &[u32] {
        &self.free_vertices
    }

    /// The free index of full vertex `vertex`, or `None` if it is pinned.
    ///
    /// # Panics
    /// If `vertex` is out of range.
    #[inline]
    #[track_caller]
    pub fn free_index(&self, vertex: usize) -> Option<usize> {
        match self.free_index[vertex] {
            PINNED => None,
            f => Some(f as usize),
        }
    }

    /// Whether full vertex `vertex` is pinned.
    ///
    /// # Panics
    /// If `vertex` is out of range.
    #[inline]
    #[track_caller]
    pub fn is_pinned(&self, vertex: usize) -> bool {
        self.free_index[vertex] == PINNED
    }

    /// K v: copy the entries of the free vertices of the per-vertex array `full` into `free`, in free
    /// order (positions, velocities, forces, masses...).
    ///
    /// # Panics
    /// If `full` does not have one entry per vertex or `free` one per free vertex.
    #[track_caller]
    pub fn reduce_vector<T: Copy>(&self, full: &[T], free: &mut [T]) {
        assert_eq!(
            full.len(),
            self.vertex_count(),
            "reduce_vector: `full` needs one entry per vertex"
        );
        assert_eq!(
            free.len(),
            self.free_count(),
            "reduce_vector: `free` needs one entry per free vertex"
        );
        for (out, &vertex) in free.iter_mut().zip(&self.free_vertices) {
            *out = full[vertex as usize];
        }
    }

    /// x = Kᵀ x_f + b: write the free entries `free` into their vertices of `full`, leaving the
    /// pinned entries of `full` as they are (set them to the prescribed values b first).
    ///
    /// # Panics
    /// If `full` does not have one entry per vertex or `free` one per free vertex.
    #[track_caller]
    pub fn expand_vector<T: Copy>(&self, free: &[T], full: &mut [T]) {
        assert_eq!(
            full.len(),
            self.vertex_count(),
            "expand_vector: `full` needs one entry per vertex"
        );
        assert_eq!(
            free.len(),
            self.free_count(),
            "expand_vector: `free` needs one entry per free vertex"
        );
        for (&value, &vertex) in free.iter().zip(&self.free_vertices) {
            full[vertex as usize] = value;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbering_and_round_trip() {
        let dofs = FreeDofs::new(6, &[0, 3]).unwrap();
        assert_eq!(dofs.free_vertices(), &[1, 2, 4, 5]);
        assert_eq!(dofs.free_index(4), Some(2));
        assert_eq!(dofs.free_index(3), None);
        let full = [10, 11, 12, 13, 14, 15];
        let mut free = [0; 4];
        dofs.reduce_vector(&full, &mut free);
        assert_eq!(free, [11, 12, 14, 15]);
        let mut back = [-1, 0, 0, -2, 0, 0];
        dofs.expand_vector(&free, &mut back);
        assert_eq!(back, [-1, 11, 12, -2, 14, 15]);
    }

    #[test]
    fn bad_pinned_lists_are_typed_errors() {
        assert_eq!(
            FreeDofs::new(4, &[1, 1]),
            Err(AssemblyError::PinnedNotSorted {
                position: 1,
                previous: 1,
                vertex: 1
            })
        );
        assert_eq!(
            FreeDofs::new(4, &[2, 1]),
            Err(AssemblyError::PinnedNotSorted {
                position: 1,
                previous: 2,
                vertex: 1
            })
        );
        assert_eq!(
            FreeDofs::new(4, &[4]),
            Err(AssemblyError::PinnedOutOfRange {
                position: 0,
                vertex: 4,
                vertex_count: 4
            })
        );
    }
}
