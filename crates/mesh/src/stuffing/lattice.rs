//! The body-centred cubic lattice: black vertices at the corners of a cubic grid of spacing h,
//! red vertices at the cube centres, and its tetrahedra.
//!
//! Every BCC tetrahedron joins two black vertices one grid step apart (a black long edge) with the
//! centres of the two cubes that share the face containing that edge (a red long edge); its other
//! four edges are short (√3/2 h). Vertices are numbered black first, then red, so that a vertex's
//! colour and position follow from its index alone.

use crate::Vec3;

/// A BCC lattice over a box of `n` cubes per axis with its lowest corner at `origin`.
#[derive(Clone, Debug)]
pub(crate) struct BccLattice {
    origin: Vec3,
    spacing: f64,
    cubes: [usize; 3],
    black_count: usize,
    red_count: usize,
}

impl BccLattice {
    pub(crate) fn new(origin: Vec3, spacing: f64, cubes: [usize; 3]) -> Self {
        let [x, y, z] = cubes;
        BccLattice {
            origin,
            spacing,
            cubes,
            black_count: (x + 1) * (y + 1) * (z + 1),
            red_count: x * y * z,
        }
    }

    pub(crate) fn spacing(&self) -> f64 {
        self.spacing
    }

    pub(crate) fn cubes(&self) -> [usize; 3] {
        self.cubes
    }

    pub(crate) fn vertex_count(&self) -> usize {
        self.black_count + self.red_count
    }

    pub(crate) fn black_count(&self) -> usize {
        self.black_count
    }

    pub(crate) fn is_red(&self, id: u32) -> bool {
        id as usize >= self.black_count
    }

    pub(crate) fn black_id(&self, [i, j, k]: [usize; 3]) -> u32 {
        let [x, y, _] = self.cubes;
        (i + (x + 1) * (j + (y + 1) * k)) as u32
    }

    pub(crate) fn red_id(&self, [i, j, k]: [usize; 3]) -> u32 {
        let [x, y, _] = self.cubes;
        (self.black_count + i + x * (j + y * k)) as u32
    }

    /// Grid indices of a black vertex (corner indices) or of a red vertex (cube indices).
    pub(crate) fn indices(&self, id: u32) -> [usize; 3] {
        let [x, y, _] = self.cubes;
        let (mut r, nx, ny) = if self.is_red(id) {
            (id as usize - self.black_count, x, y)
        } else {
            (id as usize, x + 1, y + 1)
        };
        let i = r % nx;
        r /= nx;
        [i, r % ny, r / ny]
    }

    /// Coordinates in half-steps: black vertices are even on every axis, red ones odd.
    pub(crate) fn half_coords(&self, id: u32) -> [i64; 3] {
        let red = self.is_red(id) as i64;
        self.indices(id).map(|c| 2 * c as i64 + red)
    }

    /// The unwarped position of a lattice vertex (m).
    pub(crate) fn position(&self, id: u32) -> Vec3 {
        let [i, j, k] = self.half_coords(id);
        self.origin + Vec3::new(i as f64, j as f64, k as f64) * (0.5 * self.spacing)
    }

    /// The neighbour of a red or black vertex one grid step along `axis`, if it exists.
    pub(crate) fn step(&self, id: u32, axis: usize) -> Option<u32> {
        let mut c = self.indices(id);
        c[axis] += 1;
        if self.is_red(id) {
            (c[axis] < self.cubes[axis]).then(|| self.red_id(c))
        } else {
            (c[axis] <= self.cubes[axis]).then(|| self.black_id(c))
        }
    }

    /// The eight corners (black) of the cube whose centre is the red vertex `red`.
    pub(crate) fn corners(&self, red: u32) -> [u32; 8] {
        let [i, j, k] = self.indices(red);
        std::array::from_fn(|c| self.black_id([i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2)]))
    }

    /// The four BCC tetrahedra around the red long edge from `red` one step along `axis`, or
    /// `None` at the lattice's end. Each is `[b0, b1, r0, r1]`: `b0–b1` and `r0–r1` are its long
    /// edges, the other four short.
    pub(crate) fn tetrahedra_along(&self, red: u32, axis: usize) -> Option<[[u32; 4]; 4]> {
        let next = self.step(red, axis)?;
        let mut base = self.indices(red);
        base[axis] += 1;
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let corner = |du: usize, dv: usize| {
            let mut c = base;
            c[u] += du;
            c[v] += dv;
            self.black_id(c)
        };
        let (c00, c10, c01, c11) = (corner(0, 0), corner(1, 0), corner(0, 1), corner(1, 1));
        Some([
            [c00, c10, red, next],
            [c01, c11, red, next],
            [c00, c01, red, next],
            [c10, c11, red, next],
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_round_trip_and_tetrahedra_tile_the_interior() {
        let lattice = BccLattice::new(Vec3::zeros(), 1.0, [3, 4, 5]);
        for id in 0..lattice.vertex_count() as u32 {
            let c = lattice.indices(id);
            let back = if lattice.is_red(id) {
                lattice.red_id(c)
            } else {
                lattice.black_id(c)
            };
            assert_eq!(back, id);
        }
        // Every tetrahedron is a BCC tetrahedron of volume h³/12.
        let mut volume = 0.0;
        for red in lattice.black_count() as u32..lattice.vertex_count() as u32 {
            for axis in 0..3 {
                for t in lattice.tetrahedra_along(red, axis).into_iter().flatten() {
                    let [a, b, c, d] = t.map(|v| lattice.position(v));
                    let v = crate::tetrahedron_signed_volume(&a, &b, &c, &d).abs();
                    assert!((v - 1.0 / 12.0).abs() < 1e-12, "BCC tetrahedron volume {v}");
                    volume += v;
                }
            }
        }
        // Four tetrahedra of h³/12 around each red long edge.
        let red_edges = 2 * 4 * 5 + 3 * 3 * 5 + 3 * 4 * 4;
        assert!((volume - red_edges as f64 / 3.0).abs() < 1e-9, "{volume}");
    }
}
