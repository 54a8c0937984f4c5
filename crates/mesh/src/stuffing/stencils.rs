//! The stencils of isosurface stuffing: how one BCC tetrahedron whose vertices are inside (+),
//! outside (−) or on the surface (0) is filled with output tetrahedra.
//!
//! The output is the part of the tetrahedron on the inside of the cut points (the surface
//! crossings of its +/− edges). Where that part has a quadrilateral face, the face's diagonal is
//! decided by the face alone, so that the two lattice tetrahedra sharing it agree:
//!
//! - if the face's two + vertices share a short edge, the face's long edge runs from one of them to
//!   the − vertex, and the diagonal joins the cut point on that long edge to the other + vertex;
//! - if they share a long edge (the face is symmetric), Labelle and Shewchuk's parity rule picks the
//!   diagonal from the lattice coordinates.
//!
//! A prism (2 + and 2 −, or 3 + and 1 −) is split into three tetrahedra along the diagonals of its
//! faces on lattice faces; its one face on the surface, if free, takes the diagonal that makes the
//! split possible (exactly one does).

/// What the stencils need to know about the lattice and the cut points.
pub(crate) trait StencilLattice {
    /// The output vertex id of the cut point on the edge `a`–`b` (one +, one −); `None` if it has
    /// none, which the signs rule out.
    fn cut(&self, a: u32, b: u32) -> Option<u32>;
    /// Half-step lattice coordinates of vertex `id` (black: all even, red: all odd).
    fn half_coords(&self, id: u32) -> [i64; 3];
    /// Whether `id` is a red (cube-centre) vertex.
    fn is_red(&self, id: u32) -> bool;
}

/// Two local vertices of a BCC tetrahedron `[b0, b1, r0, r1]` share a long edge when they are
/// `0, 1` or `2, 3`.
fn is_long(i: usize, j: usize) -> bool {
    i ^ 1 == j
}

/// The parity rule for a face whose + vertices `a`, `b` share a long edge and whose third vertex
/// is the − vertex `n`: true when the diagonal joins `a` to the cut point on `b`–`n`, false when
/// it joins `b` to the cut point on `a`–`n`. Swapping `a` and `b` flips the answer, so both
/// tetrahedra that share the face choose the same diagonal.
fn parity_rule<L: StencilLattice>(lattice: &L, a: u32, b: u32, n: u32) -> bool {
    let (ha, hb, hn) = (
        lattice.half_coords(a),
        lattice.half_coords(b),
        lattice.half_coords(n),
    );
    let long_axis = (0..3).find(|&x| ha[x] != hb[x]).unwrap_or(0);
    // The number of axes along which a lies above the cut point on b–n (which is strictly between
    // b and n): along the long axis that is a above b, across it a above n.
    let mut count = (ha[long_axis] > hb[long_axis]) as u32;
    for x in (0..3).filter(|&x| x != long_axis) {
        count += (hn[x] < ha[x]) as u32;
    }
    let odd = count % 2 == 1;
    if lattice.is_red(a) {
        !odd
    } else {
        odd
    }
}

/// For the face of local + vertices `i`, `j` and local − vertex `n`: which of `i`, `j` the
/// quadrilateral's diagonal touches (the diagonal joins it to the cut point on the other's edge to
/// `n`).
fn face_diagonal<L: StencilLattice>(
    lattice: &L,
    tet: &[u32; 4],
    i: usize,
    j: usize,
    n: usize,
) -> usize {
    if is_long(i, j) {
        if parity_rule(lattice, tet[i], tet[j], tet[n]) {
            i
        } else {
            j
        }
    } else if is_long(i, n) {
        j
    } else {
        i
    }
}

/// Split the prism with triangles `a` and `b` (edges `a[i]–b[i]`) into three tetrahedra.
/// `diagonals[q]` for the quadrilaterals `(0,1)`, `(0,2)`, `(1,2)` (in that order) is
/// `Some(true)` for the diagonal `a[i]–b[j]`, `Some(false)` for `a[j]–b[i]`, `None` if free.
/// Returns false (and writes nothing) if the fixed diagonals form a cycle.
fn split_prism(
    a: [u32; 3],
    b: [u32; 3],
    diagonals: [Option<bool>; 3],
    out: &mut Vec<[u32; 4]>,
) -> bool {
    const QUADS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];
    let free_count = diagonals.iter().filter(|d| d.is_none()).count();
    for choice in 0..(1u32 << free_count) {
        // The free diagonals take the bits of `choice` in order: `a[j]–b[i]` (0) first.
        let mut d = [false; 3];
        let mut bit = 0;
        for q in 0..3 {
            d[q] = diagonals[q].unwrap_or_else(|| {
                bit += 1;
                choice >> (bit - 1) & 1 == 1
            });
        }
        // Is the diagonal of the quad (x, y) the one from a[x] to b[y]?
        let a_to_b = |x: usize, y: usize| -> bool {
            let q = QUADS
                .iter()
                .position(|&p| p == (x.min(y), x.max(y)))
                .unwrap_or(0);
            if x < y {
                d[q]
            } else {
                !d[q]
            }
        };
        for apex in 0..3 {
            let (j, k) = ((apex + 1) % 3, (apex + 2) % 3);
            if a_to_b(apex, j) && a_to_b(apex, k) {
                // a[apex] sees the triangle b and the quad (j, k).
                out.push([a[apex], b[apex], b[j], b[k]]);
                if a_to_b(j, k) {
                    out.push([a[apex], a[j], a[k], b[k]]);
                    out.push([a[apex], a[j], b[k], b[j]]);
                } else {
                    out.push([a[apex], a[j], a[k], b[j]]);
                    out.push([a[apex], a[k], b[k], b[j]]);
                }
                return true;
            }
            if a_to_b(j, apex) && a_to_b(k, apex) {
                // b[apex] sees the triangle a and the quad (j, k).
                out.push([b[apex], a[apex], a[j], a[k]]);
                if a_to_b(j, k) {
                    out.push([b[apex], a[j], b[k], b[j]]);
                    out.push([b[apex], a[j], a[k], b[k]]);
                } else {
                    out.push([b[apex], a[j], a[k], b[j]]);
                    out.push([b[apex], a[k], b[k], b[j]]);
                }
                return true;
            }
        }
    }
    false
}

/// Why a stencil could not be applied: both are excluded by construction, and reported rather than
/// assumed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StencilFailure {
    /// A +/− edge without a cut point.
    MissingCut,
    /// A prism whose fixed face diagonals form a cycle.
    CyclicPrism,
}

impl StencilFailure {
    pub(crate) fn describe(self) -> &'static str {
        match self {
            StencilFailure::MissingCut => {
                "a lattice edge with an inside and an outside end has no cut point"
            }
            StencilFailure::CyclicPrism => {
                "a prism's face diagonals form a cycle, so it cannot be split into tetrahedra"
            }
        }
    }
}

/// Fill one BCC tetrahedron `tet` (`[b0, b1, r0, r1]`) with vertex signs `signs` (+1 inside,
/// −1 outside, 0 on the surface), appending output tetrahedra (any orientation) to `out`.
///
/// # Errors
/// [`StencilFailure`] (and nothing written for the prism) if a cut point is missing or a prism
/// cannot be split, which the signs and the face rules rule out.
pub(crate) fn fill<L: StencilLattice>(
    lattice: &L,
    tet: [u32; 4],
    signs: [i8; 4],
    out: &mut Vec<[u32; 4]>,
) -> Result<(), StencilFailure> {
    let mut plus = [0usize; 4];
    let mut minus = [0usize; 4];
    let mut zero = [0usize; 4];
    let (mut np, mut nn, mut nz) = (0, 0, 0);
    for (i, &s) in signs.iter().enumerate() {
        match s.signum() {
            1 => {
                plus[np] = i;
                np += 1;
            }
            -1 => {
                minus[nn] = i;
                nn += 1;
            }
            _ => {
                zero[nz] = i;
                nz += 1;
            }
        }
    }
    let v = |i: usize| tet[i];
    let cut = |i: usize, j: usize| {
        lattice
            .cut(tet[i], tet[j])
            .ok_or(StencilFailure::MissingCut)
    };
    match (np, nn) {
        // Nothing inside; a tetrahedron with all four vertices on the surface is the caller's choice.
        (0, _) => {}
        (_, 0) => out.push(tet),
        (1, 3) => {
            let p = plus[0];
            out.push([
                v(p),
                cut(p, minus[0])?,
                cut(p, minus[1])?,
                cut(p, minus[2])?,
            ]);
        }
        (1, 2) => {
            let p = plus[0];
            out.push([v(p), v(zero[0]), cut(p, minus[0])?, cut(p, minus[1])?]);
        }
        (1, 1) => {
            let p = plus[0];
            out.push([v(p), v(zero[0]), v(zero[1]), cut(p, minus[0])?]);
        }
        (2, 1) => {
            // A pyramid with apex the zero vertex over the quad in the face (p0, p1, n).
            let n = minus[0];
            let touched = face_diagonal(lattice, &tet, plus[0], plus[1], n);
            let other = if touched == plus[0] { plus[1] } else { plus[0] };
            let z = v(zero[0]);
            let (cut_other, cut_touched) = (cut(other, n)?, cut(touched, n)?);
            out.push([z, v(touched), v(other), cut_other]);
            out.push([z, v(touched), cut_other, cut_touched]);
        }
        (2, 2) => {
            let (p0, p1) = (plus[0], plus[1]);
            let (n0, n1) = (minus[0], minus[1]);
            let a = [v(p0), cut(p0, n0)?, cut(p0, n1)?];
            let b = [v(p1), cut(p1, n0)?, cut(p1, n1)?];
            let d01 = face_diagonal(lattice, &tet, p0, p1, n0) == p0;
            let d02 = face_diagonal(lattice, &tet, p0, p1, n1) == p0;
            if !split_prism(a, b, [Some(d01), Some(d02), None], out) {
                return Err(StencilFailure::CyclicPrism);
            }
        }
        (3, 1) => {
            let n = minus[0];
            let a = [v(plus[0]), v(plus[1]), v(plus[2])];
            let b = [cut(plus[0], n)?, cut(plus[1], n)?, cut(plus[2], n)?];
            let rule =
                |i: usize, j: usize| face_diagonal(lattice, &tet, plus[i], plus[j], n) == plus[i];
            if !split_prism(
                a,
                b,
                [Some(rule(0, 1)), Some(rule(0, 2)), Some(rule(1, 2))],
                out,
            ) {
                return Err(StencilFailure::CyclicPrism);
            }
        }
        _ => {}
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lattice that has lost every cut point.
    struct NoCuts;

    impl StencilLattice for NoCuts {
        fn cut(&self, _: u32, _: u32) -> Option<u32> {
            None
        }
        fn half_coords(&self, id: u32) -> [i64; 3] {
            [[0, 0, 0], [2, 0, 0], [1, 1, -1], [1, 1, 1]][id as usize]
        }
        fn is_red(&self, id: u32) -> bool {
            id >= 2
        }
    }

    /// A missing cut point is an error, not a panic, in every stencil that needs one; the stencils
    /// that need none still apply.
    #[test]
    fn a_missing_cut_point_is_reported() {
        let mut out = Vec::new();
        for signs in [
            [1, -1, -1, -1],
            [1, 1, -1, 0],
            [1, 1, -1, -1],
            [1, 1, 1, -1],
        ] {
            assert_eq!(
                fill(&NoCuts, [0, 1, 2, 3], signs, &mut out),
                Err(StencilFailure::MissingCut),
                "{signs:?}"
            );
        }
        assert_eq!(fill(&NoCuts, [0, 1, 2, 3], [1, 1, 0, 0], &mut out), Ok(()));
        assert_eq!(out, vec![[0, 1, 2, 3]]);
    }
}
