//! Two sheets a fraction of d̂ apart, the self-contact tests' scene (included with `#[path]` by
//! the test binaries that use it).

use nalgebra::Vector3;

/// Two n×n sheets on the unit square in the xz-plane, the second `gap` above the first, shifted
/// by (`sx`, `sz`) spacings, every vertex moved by `jitter` (m) in a fixed pseudo-random pattern.
pub fn two_sheets(
    n: usize,
    gap: f64,
    sx: f64,
    sz: f64,
    jitter: f64,
) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let s = 1.0 / (n - 1) as f64;
    let mut positions = Vec::new();
    for (sheet, (dx, dy, dz)) in [(0.0, 0.0, 0.0), (sx * s, gap, sz * s)]
        .into_iter()
        .enumerate()
    {
        for j in 0..n {
            for i in 0..n {
                let k = (sheet * n * n + j * n + i) as f64;
                let wobble = Vector3::new((k * 1.7).sin(), (k * 2.3).sin(), (k * 3.1).sin());
                positions
                    .push(Vector3::new(i as f64 * s + dx, dy, j as f64 * s + dz) + wobble * jitter);
            }
        }
    }
    let mut triangles = Vec::new();
    for sheet in 0..2 {
        let o = (sheet * n * n) as u32;
        for j in 0..n as u32 - 1 {
            for i in 0..n as u32 - 1 {
                let (a, b) = (o + j * n as u32 + i, o + j * n as u32 + i + 1);
                let (c, d) = (a + n as u32, b + n as u32);
                triangles.push([a, c, b]);
                triangles.push([b, c, d]);
            }
        }
    }
    (positions, triangles)
}
