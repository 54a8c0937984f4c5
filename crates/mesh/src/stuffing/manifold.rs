//! Which lattice tetrahedra whose four vertices were all warped onto the surface ("all-zero"
//! tetrahedra) to keep, so that the mesh's boundary is a closed 2-manifold.
//!
//! The stencils decide every other lattice tetrahedron from its signs alone, and that part of the
//! output can only fail to be manifold where two warped (zero) vertices meet: around an edge with a
//! `+` end, or at a cut point, every lattice tetrahedron contributes its piece, so those edges and
//! vertices are surrounded. Where the surface has a feature thinner than about a spacing (a thin
//! plate, a sharp crease, two sheets that nearly touch), vertices from both of its sides are
//! warped onto it and the pieces around a zero–zero edge can form two fans that meet only along that
//! edge (the edge lies in four boundary faces), or two cones that meet only at a zero vertex.
//!
//! The all-zero tetrahedra are the free choice: their vertices are all on the surface, so keeping
//! or dropping one keeps the boundary on the surface, and only those within the dihedral-angle
//! bounds are candidates. They start from the centroid rule (kept when the centroid is inside);
//! then, around each edge or vertex that is not manifold, candidates that close a gap between fans
//! or cones are added, and then kept ones that end a fan or cone are removed, each change accepted
//! only if it leaves that place no worse and breaks no manifold edge or vertex of the candidate.
//! Each phase changes a candidate at most once, so the repair ends. What it cannot mend is
//! reported by its vertex, for a typed error: the boundary is never silently non-manifold.

use std::collections::{HashMap, VecDeque};

/// A sorted vertex triple: a face's key.
fn face_key(mut face: [u32; 3]) -> [u32; 3] {
    face.sort_unstable();
    face
}

fn edge_key(a: u32, b: u32) -> [u32; 2] {
    [a.min(b), a.max(b)]
}

/// The four faces of a tetrahedron.
fn faces(t: &[u32; 4]) -> [[u32; 3]; 4] {
    let [a, b, c, d] = *t;
    [[a, b, c], [a, b, d], [a, c, d], [b, c, d]]
}

/// The six edges of a tetrahedron, each with the two other vertices (the faces at that edge).
fn edges(t: &[u32; 4]) -> [([u32; 2], [u32; 2]); 6] {
    let [a, b, c, d] = *t;
    [
        (edge_key(a, b), [c, d]),
        (edge_key(a, c), [b, d]),
        (edge_key(a, d), [b, c]),
        (edge_key(b, c), [a, d]),
        (edge_key(b, d), [a, c]),
        (edge_key(c, d), [a, b]),
    ]
}

/// A place where the boundary may fail to be manifold: a zero–zero edge or a zero vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Site {
    Edge([u32; 2]),
    Vertex(u32),
}

/// The ten sites of an all-zero tetrahedron.
fn sites(t: &[u32; 4]) -> [Site; 10] {
    let e = edges(t);
    std::array::from_fn(|i| {
        if i < 6 {
            Site::Edge(e[i].0)
        } else {
            Site::Vertex(t[i - 6])
        }
    })
}

/// The faces near the warped vertices and how many kept tetrahedra use each.
#[derive(Default)]
struct Boundary {
    /// Uses of every face with a zero vertex, by kept tetrahedra.
    face_uses: HashMap<[u32; 3], u32>,
    /// For every zero–zero edge, the third vertices of the faces at it (of any tetrahedron that
    /// may be kept).
    edge_faces: HashMap<[u32; 2], Vec<u32>>,
    /// For every zero vertex, the faces at it (of any tetrahedron that may be kept).
    vertex_faces: HashMap<u32, Vec<[u32; 3]>>,
}

impl Boundary {
    /// Count (`keep`) or uncount the faces of a kept tetrahedron `t`.
    fn count_faces(&mut self, t: &[u32; 4], is_zero: &impl Fn(u32) -> bool, keep: bool) {
        for f in faces(t) {
            if f.iter().any(|&v| is_zero(v)) {
                let count = self.face_uses.entry(face_key(f)).or_insert(0);
                if keep {
                    *count += 1;
                } else {
                    *count -= 1;
                }
            }
        }
    }

    /// Record the faces of `t` at its zero–zero edges and zero vertices.
    fn index(&mut self, t: &[u32; 4], is_zero: &impl Fn(u32) -> bool) {
        for (e, others) in edges(t) {
            if is_zero(e[0]) && is_zero(e[1]) {
                let thirds = self.edge_faces.entry(e).or_default();
                for x in others {
                    if !thirds.contains(&x) {
                        thirds.push(x);
                    }
                }
            }
        }
        for f in faces(t) {
            let key = face_key(f);
            for v in f.into_iter().filter(|&v| is_zero(v)) {
                let list = self.vertex_faces.entry(v).or_default();
                if !list.contains(&key) {
                    list.push(key);
                }
            }
        }
    }

    fn is_boundary(&self, face: &[u32; 3]) -> bool {
        self.face_uses.get(face) == Some(&1)
    }

    /// How far a site is from manifold: 0 when it is; otherwise, for an edge, the number of
    /// boundary faces at it, and for a vertex, one less than the pieces its link falls into plus
    /// the link vertices not in exactly two link edges.
    fn badness(&self, site: Site) -> usize {
        match site {
            Site::Edge(e) => {
                let count = self.edge_faces.get(&e).map_or(0, |thirds| {
                    thirds
                        .iter()
                        .filter(|&&x| self.is_boundary(&face_key([e[0], e[1], x])))
                        .count()
                });
                if count == 0 || count == 2 {
                    0
                } else {
                    count
                }
            }
            Site::Vertex(v) => {
                let Some(list) = self.vertex_faces.get(&v) else {
                    return 0;
                };
                let link: Vec<[u32; 2]> = list
                    .iter()
                    .filter(|f| self.is_boundary(f))
                    .map(|f| {
                        let mut others = f.iter().copied().filter(|&x| x != v);
                        [others.next().unwrap_or(v), others.next().unwrap_or(v)]
                    })
                    .collect();
                link_badness(&link)
            }
        }
    }
}

/// 0 when the edges form one closed cycle or none; otherwise (pieces − 1) + (vertices not in
/// exactly two edges).
fn link_badness(link: &[[u32; 2]]) -> usize {
    if link.is_empty() {
        return 0;
    }
    // Union-find over the link's few vertices.
    let mut vertices: Vec<u32> = link.iter().flatten().copied().collect();
    vertices.sort_unstable();
    vertices.dedup();
    let index = |x: u32| vertices.binary_search(&x).unwrap_or(0);
    let mut parent: Vec<usize> = (0..vertices.len()).collect();
    let mut degree = vec![0usize; vertices.len()];
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for &[a, b] in link {
        let (i, j) = (index(a), index(b));
        degree[i] += 1;
        degree[j] += 1;
        let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
        parent[ri] = rj;
    }
    let pieces = (0..vertices.len())
        .filter(|&i| root(&mut parent, i) == i)
        .count();
    pieces - 1 + degree.iter().filter(|&&d| d != 2).count()
}

/// Choose the all-zero `candidates` to keep (`kept`, on entry the centroid rule's choice) so that
/// the boundary of `tets` plus the kept candidates is manifold at every zero vertex and zero–zero
/// edge. `is_zero` tells the warped lattice vertices. Deterministic: sites and candidates are
/// visited in a fixed order.
///
/// # Errors
/// A zero vertex where the boundary is still not manifold after the repair (the lowest such id).
pub(crate) fn choose_all_zero(
    tets: &[[u32; 4]],
    candidates: &[[u32; 4]],
    kept: &mut [bool],
    is_zero: impl Fn(u32) -> bool,
) -> Result<(), u32> {
    let mut boundary = Boundary::default();
    for t in tets.iter().filter(|t| t.iter().any(|&v| is_zero(v))) {
        boundary.count_faces(t, &is_zero, true);
        boundary.index(t, &is_zero);
    }
    let mut around: HashMap<Site, Vec<u32>> = HashMap::new();
    for (i, t) in candidates.iter().enumerate() {
        if kept[i] {
            boundary.count_faces(t, &is_zero, true);
        }
        boundary.index(t, &is_zero);
        for site in sites(t) {
            around.entry(site).or_default().push(i as u32);
        }
    }
    let all_sites = || -> Vec<Site> {
        let mut all: Vec<Site> = boundary
            .edge_faces
            .keys()
            .map(|&e| Site::Edge(e))
            .chain(boundary.vertex_faces.keys().map(|&v| Site::Vertex(v)))
            .collect();
        all.sort_unstable();
        all
    };
    let all = all_sites();

    // Phase 1 adds candidates, phase 2 removes kept ones; a candidate changes at most once in each.
    let mut changed = vec![false; candidates.len()];
    for adding in [true, false] {
        changed.iter_mut().for_each(|c| *c = false);
        let mut queue: VecDeque<Site> = all
            .iter()
            .copied()
            .filter(|&s| boundary.badness(s) > 0)
            .collect();
        while let Some(site) = queue.pop_front() {
            let Some(nearby) = around.get(&site) else {
                continue;
            };
            // Repeat until nothing more is accepted: closing a gap of two needs two additions.
            let mut progress = true;
            while progress && boundary.badness(site) > 0 {
                progress = false;
                for &c in nearby {
                    let c = c as usize;
                    if changed[c] || kept[c] == adding {
                        continue;
                    }
                    let t = &candidates[c];
                    let before = sites(t).map(|s| boundary.badness(s));
                    let here = boundary.badness(site);
                    boundary.count_faces(t, &is_zero, adding);
                    let no_worse = boundary.badness(site) <= here
                        && sites(t)
                            .iter()
                            .zip(&before)
                            .all(|(&s, &b)| b > 0 || boundary.badness(s) == 0);
                    if no_worse {
                        kept[c] = adding;
                        changed[c] = true;
                        progress = true;
                        queue.extend(
                            sites(t)
                                .into_iter()
                                .filter(|&s| s != site && boundary.badness(s) > 0),
                        );
                    } else {
                        boundary.count_faces(t, &is_zero, !adding);
                    }
                }
            }
        }
    }

    // What is left: a zero–zero edge in four or more boundary faces, or a zero vertex whose
    // boundary faces do not form one cycle around it (two cones meeting at a point).
    all.iter()
        .filter(|&&s| boundary.badness(s) > 0)
        .map(|s| match *s {
            Site::Edge(e) => e[0],
            Site::Vertex(v) => v,
        })
        .min()
        .map_or(Ok(()), Err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_are_told_from_two_cycles_and_paths() {
        assert_eq!(link_badness(&[]), 0);
        assert_eq!(link_badness(&[[1, 2], [2, 3], [3, 1]]), 0);
        assert_eq!(
            link_badness(&[[1, 2], [2, 3], [3, 1], [4, 5], [5, 6], [6, 4]]),
            1
        );
        assert_eq!(link_badness(&[[1, 2], [2, 3]]), 2);
    }

    /// Two tetrahedra sharing only the edge 0–1, with both ends warped (zero): the edge lies in
    /// four boundary faces. The all-zero candidates that fill the gap on one side mend it.
    #[test]
    fn a_gap_between_two_fans_is_closed() {
        // Around the edge 0–1, ring vertices 2..6 in order; the fans are (0,1,2,3) and (0,1,4,5),
        // the gap (0,1,3,4) is an all-zero candidate.
        let tets = [[0, 1, 2, 3], [0, 1, 4, 5]];
        let candidates = [[0, 1, 3, 4]];
        let mut kept = [false];
        let is_zero = |v: u32| v != 2 && v != 5;
        assert_eq!(
            choose_all_zero(&tets, &candidates, &mut kept, is_zero),
            Ok(())
        );
        assert_eq!(kept, [true]);
    }

    /// The same pinch with no candidate to close it is reported at the edge's vertex.
    #[test]
    fn an_unmendable_pinch_is_reported() {
        let tets = [[0, 1, 2, 3], [0, 1, 4, 5]];
        let is_zero = |v: u32| v < 2;
        assert_eq!(choose_all_zero(&tets, &[], &mut [], is_zero), Err(0));
    }
}
