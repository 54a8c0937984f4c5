//! Two sheets a gap apart, the self-contact tests' scene (included with `#[path]` by the test
//! binaries that use it).

use hooke_mesh::Spring;
use nalgebra::Vector3;

/// Two n×n sheets on the unit square of the xz-plane, the second `gap` above the first and
/// shifted by a third of a spacing; springs along the grid's edges.
pub fn two_sheets(n: usize, gap: f64) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>, Vec<Spring>) {
    let s = 1.0 / (n - 1) as f64;
    let mut positions = Vec::new();
    for (dy, d) in [(0.0, 0.0), (gap, s / 3.0)] {
        for j in 0..n {
            for i in 0..n {
                positions.push(Vector3::new(i as f64 * s + d, dy, j as f64 * s + d));
            }
        }
    }
    let (mut triangles, mut springs) = (Vec::new(), Vec::new());
    for sheet in 0..2 {
        let o = (sheet * n * n) as u32;
        let n = n as u32;
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let (a, b) = (o + j * n + i, o + j * n + i + 1);
                let (c, d) = (a + n, b + n);
                triangles.push([a, c, b]);
                triangles.push([b, c, d]);
                for (p, q) in [(a, b), (a, c), (b, c)] {
                    springs.push(Spring {
                        i: p,
                        j: q,
                        stiffness: 1e3,
                        rest_length: s,
                    });
                }
            }
        }
    }
    (positions, triangles, springs)
}
