//! Global spring forces and energies over a whole mesh, parallel and deterministic.
//!
//! Forces are computed once per spring into a buffer, then gathered per vertex from a fixed
//! incidence list. Each vertex sums its springs in the same order whatever the number of threads, so
//! the parallel result equals the serial one bit for bit (no atomics, no scatter races).

use hooke_mesh::Spring;
use nalgebra::SVector;
use rayon::prelude::*;

use crate::spring;

/// Below this many springs the parallel loops run serially: thread start-up costs more than the work.
pub(crate) const PARALLEL_THRESHOLD: usize = 8 * 1024;
/// Work items per rayon task: large enough to amortise scheduling, small enough to balance.
const CHUNK: usize = 2048;

/// For each vertex, the springs that touch it and on which end, in increasing spring order.
#[derive(Clone, Debug)]
pub struct Incidence {
    offsets: Vec<usize>,
    /// (spring index, +1.0 for its first vertex, −1.0 for its second).
    entries: Vec<(u32, f64)>,
}

impl Incidence {
    /// Build the incidence lists of `springs` over `vertex_count` vertices, in O(n + s).
    ///
    /// # Panics
    /// If a spring refers to a vertex ≥ `vertex_count` (a validated `SpringMesh` never does).
    #[track_caller]
    pub fn new(vertex_count: usize, springs: &[Spring]) -> Self {
        let mut offsets = vec![0usize; vertex_count + 1];
        for s in springs {
            offsets[s.i as usize + 1] += 1;
            offsets[s.j as usize + 1] += 1;
        }
        for v in 0..vertex_count {
            offsets[v + 1] += offsets[v];
        }
        let mut fill = offsets.clone();
        let mut entries = vec![(0u32, 0.0); 2 * springs.len()];
        for (index, s) in springs.iter().enumerate() {
            for (vertex, sign) in [(s.i, 1.0), (s.j, -1.0)] {
                entries[fill[vertex as usize]] = (index as u32, sign);
                fill[vertex as usize] += 1;
            }
        }
        Incidence { offsets, entries }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.offsets.len() - 1
    }

    /// The springs touching `vertex`, with the sign of their force on it.
    pub fn of(&self, vertex: usize) -> &[(u32, f64)] {
        &self.entries[self.offsets[vertex]..self.offsets[vertex + 1]]
    }

    /// Sum per-spring values into per-vertex values: out_v = Σ sign · `per_spring[s]`.
    ///
    /// # Panics
    /// If `out` does not have one entry per vertex.
    #[track_caller]
    pub fn gather<const D: usize>(
        &self,
        per_spring: &[SVector<f64, D>],
        out: &mut [SVector<f64, D>],
        parallel: bool,
    ) {
        assert_eq!(out.len(), self.vertex_count(), "one output per vertex");
        let sum = |(vertex, o): (usize, &mut SVector<f64, D>)| {
            let mut acc = SVector::<f64, D>::zeros();
            for &(s, sign) in self.of(vertex) {
                acc += per_spring[s as usize] * sign;
            }
            *o = acc;
        };
        if parallel && out.len() >= PARALLEL_THRESHOLD {
            out.par_iter_mut()
                .with_min_len(CHUNK)
                .enumerate()
                .for_each(sum);
        } else {
            out.iter_mut().enumerate().for_each(sum);
        }
    }
}

/// Damping applied along the springs: dashpot coefficient c (N·s/m) and the current velocities.
#[derive(Clone, Copy, Debug)]
pub struct Dashpot<'a, const D: usize> {
    /// Coefficient c in f_i = −c ((v_i − v_j)·r̂) r̂, N·s/m, ≥ 0.
    pub coefficient: f64,
    /// Velocities (m/s), one per vertex.
    pub velocities: &'a [SVector<f64, D>],
}

/// Computes the spring force on every vertex, reusing its buffers across calls (no allocation).
#[derive(Clone, Debug)]
pub struct SpringForces<const D: usize> {
    incidence: Incidence,
    per_spring: Vec<SVector<f64, D>>,
}

impl<const D: usize> SpringForces<D> {
    /// Workspace for `springs` over `vertex_count` vertices.
    pub fn new(vertex_count: usize, springs: &[Spring]) -> Self {
        SpringForces {
            incidence: Incidence::new(vertex_count, springs),
            per_spring: vec![SVector::zeros(); springs.len()],
        }
    }

    /// The incidence lists this workspace gathers with.
    pub fn incidence(&self) -> &Incidence {
        &self.incidence
    }

    /// Write into `out` the total spring force (N) on each vertex at `positions`, plus the dashpot
    /// force if given. `parallel` picks rayon or a serial loop; both give identical bits.
    ///
    /// # Panics
    /// If `springs`, `positions` or `out` do not match the sizes this workspace was built for.
    #[track_caller]
    pub fn compute(
        &mut self,
        springs: &[Spring],
        positions: &[SVector<f64, D>],
        dashpot: Option<Dashpot<'_, D>>,
        out: &mut [SVector<f64, D>],
        parallel: bool,
    ) {
        assert_eq!(springs.len(), self.per_spring.len(), "springs changed size");
        assert_eq!(
            positions.len(),
            self.incidence.vertex_count(),
            "one position per vertex"
        );
        let kernel = |(s, f): (&Spring, &mut SVector<f64, D>)| {
            let (i, j) = s.ends();
            let r = positions[i] - positions[j];
            let mut total = spring::force(s.stiffness, s.rest_length, &r);
            if let Some(d) = dashpot {
                total +=
                    spring::dashpot_force(d.coefficient, &r, &(d.velocities[i] - d.velocities[j]));
            }
            *f = total;
        };
        if parallel && springs.len() >= PARALLEL_THRESHOLD {
            springs
                .par_iter()
                .zip(self.per_spring.par_iter_mut())
                .with_min_len(CHUNK)
                .for_each(kernel);
        } else {
            springs
                .iter()
                .zip(self.per_spring.iter_mut())
                .for_each(kernel);
        }
        self.incidence.gather(&self.per_spring, out, parallel);
    }
}

/// Sum `term(index)` over `0..count` in fixed chunks: each chunk serially, then the chunk sums in
/// order, so the result does not depend on the number of threads. Allocation-free: the parallel
/// path computes the chunk sums in batches of `SUM_BATCH` (64) into an array on the stack and adds
/// each batch to the total in order, which is the serial order of additions.
pub fn deterministic_sum(count: usize, parallel: bool, term: impl Fn(usize) -> f64 + Sync) -> f64 {
    deterministic_sum_lanes(count, parallel, |i| SVector::<f64, 1>::new(term(i)))[0]
}

/// [`deterministic_sum`] of D sums at once, in one pass over the terms (D dot products of the
/// same vectors, say): each lane's additions are those of [`deterministic_sum`] over that lane's
/// terms, in the same order, so each lane has its bits.
pub fn deterministic_sum_lanes<const D: usize>(
    count: usize,
    parallel: bool,
    term: impl Fn(usize) -> SVector<f64, D> + Sync,
) -> SVector<f64, D> {
    // `Iterator::sum` of f64 folds from -0.0; so does every sum here, so that an empty or
    // all-(-0.0) sum has the bits of the serial f64 sum.
    let negative_zero = SVector::<f64, D>::repeat(-0.0);
    let chunk_sum = |c: usize| {
        let end = ((c + 1) * CHUNK).min(count);
        (c * CHUNK..end).fold(negative_zero, |sum, i| sum + term(i))
    };
    let chunks = count.div_ceil(CHUNK);
    if parallel && count >= PARALLEL_THRESHOLD {
        let mut total = negative_zero;
        let mut partial = [negative_zero; SUM_BATCH];
        for first in (0..chunks).step_by(SUM_BATCH) {
            let batch = &mut partial[..SUM_BATCH.min(chunks - first)];
            batch
                .par_iter_mut()
                .enumerate()
                .for_each(|(k, p)| *p = chunk_sum(first + k));
            for p in batch.iter() {
                total += *p;
            }
        }
        total
    } else {
        (0..chunks)
            .map(chunk_sum)
            .fold(negative_zero, |sum, c| sum + c)
    }
}

/// Chunk sums computed per parallel batch in [`deterministic_sum`] (a stack array of this many).
const SUM_BATCH: usize = 64;

/// Total elastic energy Σ ½ k (|r| − l)² of the springs at `positions` (J).
pub fn spring_energy<const D: usize>(
    springs: &[Spring],
    positions: &[SVector<f64, D>],
    parallel: bool,
) -> f64 {
    deterministic_sum(springs.len(), parallel, |s| {
        let spring = &springs[s];
        let (i, j) = spring.ends();
        spring::energy(
            spring.stiffness,
            spring.rest_length,
            &(positions[i] - positions[j]),
        )
    })
}

/// Largest stretch ratio |r| / l over the springs (dimensionless; 1 at rest, 0 for no springs).
pub fn max_stretch<const D: usize>(springs: &[Spring], positions: &[SVector<f64, D>]) -> f64 {
    springs
        .iter()
        .map(|s| {
            let (i, j) = s.ends();
            spring::stretch(s.rest_length, &(positions[i] - positions[j]))
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hooke_mesh::generators::cloth;
    use nalgebra::Vector3;

    fn wobble(p: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        p.iter()
            .enumerate()
            .map(|(k, x)| {
                x + Vector3::new(
                    (k as f64 * 0.37).sin(),
                    (k as f64 * 0.11).cos(),
                    (k as f64).sin(),
                ) * 0.01
            })
            .collect()
    }

    #[test]
    fn serial_and_parallel_agree_bit_for_bit() {
        let mesh = cloth(80, 1e3).unwrap(); // 37,602 springs: above the parallel threshold
        let x = wobble(mesh.positions());
        let v: Vec<_> = x.iter().map(|p| p * 0.5).collect();
        let mut work = SpringForces::new(mesh.vertex_count(), mesh.springs());
        let mut serial = vec![Vector3::zeros(); x.len()];
        let mut parallel = serial.clone();
        let dashpot = Some(Dashpot {
            coefficient: 2.0,
            velocities: &v,
        });
        work.compute(mesh.springs(), &x, dashpot, &mut serial, false);
        work.compute(mesh.springs(), &x, dashpot, &mut parallel, true);
        assert_eq!(serial, parallel);
        assert_eq!(
            spring_energy(mesh.springs(), &x, false).to_bits(),
            spring_energy(mesh.springs(), &x, true).to_bits()
        );
    }

    /// The documented order written out: chunks of `CHUNK` terms summed serially from -0.0, then
    /// the chunk sums in order.
    fn chunked_sum(count: usize, term: impl Fn(usize) -> f64) -> f64 {
        (0..count.div_ceil(CHUNK))
            .map(|c| {
                (c * CHUNK..((c + 1) * CHUNK).min(count))
                    .map(&term)
                    .sum::<f64>()
            })
            .sum()
    }

    #[test]
    fn lane_sums_have_the_bits_of_the_chunked_sum_of_each_lane() {
        // Terms of mixed sign and magnitude, so that any other order of additions shows in the
        // bits; counts below one chunk, below the parallel threshold, and over several batches.
        let term = |i: usize| {
            let t = i as f64;
            Vector3::new(
                (t * 0.37).sin() * 1e8_f64.powf((t * 0.013).cos()),
                1.0 / (1.0 + t) - 0.5 * (t * 0.71).cos(),
                if i % 3 == 0 {
                    -0.0
                } else {
                    (t * 1.3).sin() * 1e-9
                },
            )
        };
        let batches = 3 * SUM_BATCH * CHUNK + 77;
        for count in [0, 7, CHUNK + 3, PARALLEL_THRESHOLD + 5_000, batches] {
            for parallel in [false, true] {
                let lanes = deterministic_sum_lanes(count, parallel, term);
                for a in 0..3 {
                    let expected = chunked_sum(count, |i| term(i)[a]);
                    assert_eq!(
                        lanes[a].to_bits(),
                        expected.to_bits(),
                        "lane {a}, {count} terms, parallel {parallel}"
                    );
                    assert_eq!(
                        deterministic_sum(count, parallel, |i| term(i)[a]).to_bits(),
                        expected.to_bits()
                    );
                }
            }
        }
        // A sum of nothing, or of negative zeros only, is -0.0 as f64's own sum is.
        let zeros = deterministic_sum_lanes(3 * CHUNK, true, |_| Vector3::repeat(-0.0));
        assert!(zeros.iter().all(|z| z.to_bits() == (-0.0f64).to_bits()));
    }

    #[test]
    fn forces_sum_to_zero_and_match_the_energy_gradient() {
        let mesh = cloth(6, 50.0).unwrap();
        let x = wobble(mesh.positions());
        let mut work = SpringForces::new(mesh.vertex_count(), mesh.springs());
        let mut f = vec![Vector3::zeros(); x.len()];
        work.compute(mesh.springs(), &x, None, &mut f, false);
        let total: Vector3<f64> = f.iter().sum();
        let scale: f64 = f.iter().map(|v| v.norm()).fold(0.0, f64::max);
        // Internal forces cancel pairwise; only round-off of O(ε · largest force · springs per vertex) remains.
        assert!(total.norm() <= 1e-12 * scale, "net internal force {total}");
        // Central differences, step 1e-6 on forces of size `scale`: see spring.rs for the bound.
        for vertex in [0, 7, 20, 35] {
            for axis in 0..3 {
                let mut plus = x.clone();
                let mut minus = x.clone();
                plus[vertex][axis] += 1e-6;
                minus[vertex][axis] -= 1e-6;
                let numeric = -(spring_energy(mesh.springs(), &plus, false)
                    - spring_energy(mesh.springs(), &minus, false))
                    / 2e-6;
                assert!(
                    (numeric - f[vertex][axis]).abs() <= 1e-6 * scale,
                    "vertex {vertex} axis {axis}: {numeric} vs {}",
                    f[vertex][axis]
                );
            }
        }
    }
}
