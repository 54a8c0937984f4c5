//! Neighbour search on a uniform grid: particles are sorted by cell with a counting sort, so that
//! the particles of a cell, and of a row of adjacent cells, are contiguous.

use std::ops::Range;

use nalgebra::SVector;
use rayon::prelude::*;

use crate::SphError;

/// Relative margin by which a cell exceeds the search radius, so that two points closer than the
/// radius are never two cells apart however `floor` rounds their scaled coordinates (the rounding
/// error of a coordinate scaled to cells is below 1e-9 of a cell for grids of up to 10⁶ cells a side).
const CELL_MARGIN: f64 = 1e-9;

/// A uniform grid over an axis-aligned box, with cells at least as large as a search radius.
///
/// [`rebuild`](Self::rebuild) sorts particle indices by cell (stably, so the order within a cell is the
/// order of the indices); [`order`](Self::order) then lists them cell by cell, x fastest. All points
/// within the search radius of a point lie in the 3ᴰ cells around its cell, that is in 3ᴰ⁻¹ runs of
/// consecutive sorted slots ([`for_each_candidate_run`](Self::for_each_candidate_run)). Points outside
/// the box are counted in the nearest edge cell, which keeps the search exact only for points inside:
/// callers keep particles in the box.
#[derive(Debug, Clone)]
pub struct NeighbourGrid<const D: usize> {
    origin: SVector<f64, D>,
    inv_cell: f64,
    cell_size: f64,
    dims: [usize; D],
    strides: [usize; D],
    /// `cell_start[c]..cell_start[c + 1]` are the sorted slots of cell c.
    cell_start: Vec<u32>,
    /// Sorted slot → particle index.
    order: Vec<u32>,
    /// Particle index → cell (scratch of the sort).
    cell_of: Vec<u32>,
}

impl<const D: usize> NeighbourGrid<D> {
    /// A grid over the box [`min`, `max`] (m) whose cells are at least `radius` (m) wide.
    ///
    /// # Errors
    /// [`SphError::InvalidParameter`] if `radius` is not finite and positive or the box is empty or
    /// not finite; [`SphError::GridTooLarge`] if the grid would have more than `max_cells` cells
    /// (callers bound it by the particle count, so that no allocation is sized by the box alone).
    pub fn new(
        min: SVector<f64, D>,
        max: SVector<f64, D>,
        radius: f64,
        max_cells: usize,
    ) -> Result<Self, SphError> {
        if !(radius.is_finite() && radius > 0.0) {
            return Err(SphError::InvalidParameter {
                name: "search radius",
                value: radius,
                allowed: "finite and > 0 (m)",
            });
        }
        for a in 0..D {
            if !(min[a].is_finite() && max[a].is_finite() && max[a] > min[a]) {
                return Err(SphError::InvalidParameter {
                    name: "domain extent",
                    value: max[a] - min[a],
                    allowed: "finite and > 0 along every axis (m)",
                });
            }
        }
        let cell_size = radius * (1.0 + CELL_MARGIN);
        let mut dims = [1usize; D];
        let mut strides = [1usize; D];
        let mut cells: u128 = 1;
        for a in 0..D {
            let n = ((max[a] - min[a]) / cell_size).floor() + 1.0;
            if n > max_cells as f64 {
                return Err(SphError::GridTooLarge {
                    cells: u128::MAX,
                    limit: max_cells,
                });
            }
            dims[a] = n as usize;
            strides[a] = cells as usize;
            cells *= dims[a] as u128;
            if cells > max_cells as u128 {
                return Err(SphError::GridTooLarge {
                    cells,
                    limit: max_cells,
                });
            }
        }
        Ok(NeighbourGrid {
            origin: min,
            inv_cell: 1.0 / cell_size,
            cell_size,
            dims,
            strides,
            cell_start: vec![0; cells as usize + 1],
            order: Vec::new(),
            cell_of: Vec::new(),
        })
    }

    /// The width of a cell (m), a hair above the search radius.
    pub fn cell_size(&self) -> f64 {
        self.cell_size
    }

    /// The number of cells along each axis.
    pub fn dims(&self) -> [usize; D] {
        self.dims
    }

    /// The number of cells.
    pub fn cell_count(&self) -> usize {
        self.cell_start.len() - 1
    }

    /// The cell coordinates of `p`, clamped to the grid.
    #[inline]
    fn coords(&self, p: &SVector<f64, D>) -> [usize; D] {
        let mut c = [0usize; D];
        for a in 0..D {
            // Truncation is the floor for positive values (and no libm call on baseline x86-64);
            // NaN and negative values go to cell 0; values past the end to the last cell.
            let s = (p[a] - self.origin[a]) * self.inv_cell;
            c[a] = if s > 0.0 {
                (s as usize).min(self.dims[a] - 1)
            } else {
                0
            };
        }
        c
    }

    /// The index of the cell containing `p` (clamped to the grid).
    #[inline]
    pub fn cell_index(&self, p: &SVector<f64, D>) -> usize {
        let c = self.coords(p);
        (0..D).map(|a| c[a] * self.strides[a]).sum()
    }

    /// Sorts the particle indices of `positions` by cell, reusing the grid's buffers.
    ///
    /// # Panics
    /// If there are more than `u32::MAX` positions.
    pub fn rebuild(&mut self, positions: &[SVector<f64, D>]) {
        let n = positions.len();
        assert!(u32::try_from(n).is_ok(), "more than u32::MAX particles");
        self.cell_of.resize(n, 0);
        self.order.resize(n, 0);
        let mut cell_of = std::mem::take(&mut self.cell_of);
        let this = &*self;
        cell_of
            .par_iter_mut()
            .zip(positions.par_iter())
            .for_each(|(c, p)| *c = this.cell_index(p) as u32);
        // Counting sort: counts, exclusive prefix sums, a stable scatter that turns each start into
        // the next cell's start, and a shift back.
        let starts = &mut self.cell_start;
        starts.fill(0);
        for &c in &cell_of {
            starts[c as usize + 1] += 1;
        }
        for c in 1..starts.len() {
            starts[c] += starts[c - 1];
        }
        for (i, &c) in cell_of.iter().enumerate() {
            let slot = &mut starts[c as usize];
            self.order[*slot as usize] = i as u32;
            *slot += 1;
        }
        let last = starts.len() - 1;
        starts.copy_within(0..last, 1);
        starts[0] = 0;
        self.cell_of = cell_of;
    }

    /// As [`rebuild`](Self::rebuild), but ordering the particles within a cell by `keys` (distinct,
    /// one per position) instead of by index: a caller that stores its particles permuted keeps
    /// the grid order of its own numbering.
    ///
    /// # Panics
    /// If `keys` and `positions` differ in length, or as [`rebuild`](Self::rebuild).
    pub fn rebuild_by_key(&mut self, positions: &[SVector<f64, D>], keys: &[u32]) {
        assert_eq!(keys.len(), positions.len(), "one key per position");
        self.rebuild(positions);
        for c in 0..self.cell_count() {
            let members =
                &mut self.order[self.cell_start[c] as usize..self.cell_start[c + 1] as usize];
            if members
                .windows(2)
                .any(|w| keys[w[0] as usize] > keys[w[1] as usize])
            {
                members.sort_unstable_by_key(|&i| keys[i as usize]);
            }
        }
    }

    /// Sorted slot → particle index, cell by cell (after [`rebuild`](Self::rebuild)).
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// The sorted slots of cell `cell`.
    pub fn cell_slots(&self, cell: usize) -> Range<usize> {
        self.cell_start[cell] as usize..self.cell_start[cell + 1] as usize
    }

    /// Calls `visit` with each run of consecutive sorted slots that together hold every particle in
    /// the 3ᴰ cells around the cell of `p`: 3ᴰ⁻¹ runs (fewer at the grid's edges), in a fixed order.
    #[inline]
    pub fn for_each_candidate_run(&self, p: &SVector<f64, D>, mut visit: impl FnMut(Range<usize>)) {
        let c = self.coords(p);
        let x_lo = c[0].saturating_sub(1);
        let x_hi = (c[0] + 1).min(self.dims[0] - 1);
        // Odometer over the offsets −1, 0, 1 of axes 1..D.
        let combos = 3usize.pow(D as u32 - 1);
        'combo: for combo in 0..combos {
            let mut rest = combo;
            let mut base = 0usize;
            for ((&ca, &dim), &stride) in c.iter().zip(&self.dims).zip(&self.strides).skip(1) {
                let offset = (rest % 3) as isize - 1;
                rest /= 3;
                let ca = ca as isize + offset;
                if ca < 0 || ca >= dim as isize {
                    continue 'combo;
                }
                base += ca as usize * stride;
            }
            let start = self.cell_start[base + x_lo] as usize;
            let end = self.cell_start[base + x_hi + 1] as usize;
            if start < end {
                visit(start..end);
            }
        }
    }

    /// The indices j ≠ `i` with |xⱼ − xᵢ| < `radius`, ascending: a convenience for tests and tools
    /// (it allocates). The grid must have been rebuilt on `positions` with cells ≥ `radius`.
    ///
    /// # Panics
    /// If `radius` exceeds the cell size or `i` is out of range.
    pub fn neighbours(&self, positions: &[SVector<f64, D>], i: usize, radius: f64) -> Vec<u32> {
        assert!(radius <= self.cell_size, "radius above the cell size");
        let p = positions[i];
        let mut out = Vec::new();
        self.for_each_candidate_run(&p, |run| {
            for &j in &self.order[run] {
                if j as usize != i && (positions[j as usize] - p).norm_squared() < radius * radius {
                    out.push(j);
                }
            }
        });
        out.sort_unstable();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    type V2 = SVector<f64, 2>;
    type V3 = SVector<f64, 3>;

    fn brute<const D: usize>(p: &[SVector<f64, D>], i: usize, radius: f64) -> Vec<u32> {
        (0..p.len())
            .filter(|&j| j != i && (p[j] - p[i]).norm_squared() < radius * radius)
            .map(|j| j as u32)
            .collect()
    }

    /// Coordinates in [0, 1]: half on multiples of radius/4 (so exactly on cell faces, and at
    /// distance exactly `radius` from each other), half anywhere.
    fn coordinate(radius: f64) -> impl Strategy<Value = f64> {
        let steps = (1.0 / (radius / 4.0)).floor() as u32;
        prop_oneof![
            (0..=steps).prop_map(move |k| k as f64 * radius / 4.0),
            0.0..=1.0f64,
        ]
    }

    proptest! {
        #[test]
        fn matches_brute_force_2d(
            radius in 0.05..0.4f64,
            seeds in prop::collection::vec((0..1000u32, 0..1000u32), 1..150),
            on_lattice in prop::collection::vec(any::<bool>(), 150),
        ) {
            let step = radius / 4.0;
            let points: Vec<V2> = seeds.iter().enumerate().map(|(k, &(a, b))| {
                if on_lattice[k] {
                    // Multiples of radius/4 exactly, clamped into the box.
                    V2::new(((a as f64 * step) % 1.0 / step).floor() * step,
                            ((b as f64 * step) % 1.0 / step).floor() * step)
                } else {
                    V2::new(a as f64 / 999.0, b as f64 / 999.0)
                }
            }).collect();
            let mut grid = NeighbourGrid::<2>::new(V2::zeros(), V2::repeat(1.0), radius, 1 << 20).unwrap();
            grid.rebuild(&points);
            for i in 0..points.len() {
                prop_assert_eq!(grid.neighbours(&points, i, radius), brute(&points, i, radius), "particle {}", i);
            }
        }

        #[test]
        fn matches_brute_force_3d(
            radius in 0.1..0.5f64,
            points in prop::collection::vec((coordinate(0.2), coordinate(0.2), coordinate(0.2)), 1..120),
        ) {
            let points: Vec<V3> = points.into_iter().map(|(x, y, z)| V3::new(x, y, z)).collect();
            let radius = radius.max(0.2);
            let mut grid = NeighbourGrid::<3>::new(V3::zeros(), V3::repeat(1.0), radius, 1 << 20).unwrap();
            grid.rebuild(&points);
            for i in 0..points.len() {
                prop_assert_eq!(grid.neighbours(&points, i, radius), brute(&points, i, radius), "particle {}", i);
            }
        }
    }

    #[test]
    fn exactly_on_cell_faces() {
        // A lattice whose spacing is the radius: every point is on cell faces, and axis neighbours
        // are exactly at the radius (not neighbours: the search is strict).
        let r = 0.125;
        let points: Vec<V2> = (0..9)
            .flat_map(|i| (0..9).map(move |j| V2::new(i as f64 * r, j as f64 * r)))
            .collect();
        let mut grid = NeighbourGrid::<2>::new(V2::zeros(), V2::repeat(1.0), r, 1 << 20).unwrap();
        grid.rebuild(&points);
        let slightly = r * (1.0 + 1e-12);
        for i in 0..points.len() {
            assert_eq!(grid.neighbours(&points, i, r), brute(&points, i, r));
            assert_eq!(
                grid.neighbours(&points, i, slightly.min(grid.cell_size())),
                brute(&points, i, slightly.min(grid.cell_size()))
            );
        }
    }

    #[test]
    fn order_is_a_stable_permutation() {
        let points: Vec<V2> = (0..500)
            .map(|k| V2::new((k * 37 % 101) as f64 / 100.0, (k * 53 % 97) as f64 / 96.0))
            .collect();
        let mut grid = NeighbourGrid::<2>::new(V2::zeros(), V2::repeat(1.0), 0.1, 1 << 20).unwrap();
        grid.rebuild(&points);
        let mut seen = vec![false; points.len()];
        for c in 0..grid.cell_count() {
            let slots = grid.cell_slots(c);
            let members = &grid.order()[slots];
            assert!(
                members.windows(2).all(|w| w[0] < w[1]),
                "stable within a cell"
            );
            for &i in members {
                assert_eq!(grid.cell_index(&points[i as usize]), c);
                seen[i as usize] = true;
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn bad_grids_are_errors() {
        let z = V2::zeros();
        let one = V2::repeat(1.0);
        assert!(NeighbourGrid::<2>::new(z, one, 0.0, 100).is_err());
        assert!(NeighbourGrid::<2>::new(z, one, f64::NAN, 100).is_err());
        assert!(NeighbourGrid::<2>::new(one, z, 0.1, 100).is_err());
        assert!(matches!(
            NeighbourGrid::<2>::new(z, V2::repeat(1e9), 1e-9, 1 << 20),
            Err(SphError::GridTooLarge { .. })
        ));
    }
}
