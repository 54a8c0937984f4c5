//! Set-up shared by the solver test crates.

use nalgebra::Vector3;

/// The inertial target y of a backward Euler step: every vertex's position `x[v]` moved by
/// `offset(v, x[v])` (m), the pinned vertices left where they are.
pub fn inertial_target(
    x: &[Vector3<f64>],
    pinned: &[u32],
    offset: impl Fn(usize, &Vector3<f64>) -> Vector3<f64>,
) -> Vec<Vector3<f64>> {
    x.iter()
        .enumerate()
        .map(|(v, p)| {
            if pinned.contains(&(v as u32)) {
                *p
            } else {
                p + offset(v, p)
            }
        })
        .collect()
}

/// Run `f` in a rayon pool of `threads` threads (for the tests that compare the bits of one
/// thread and two).
#[allow(dead_code)] // Not every test crate that includes this module compares thread counts.
pub fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a rayon pool")
        .install(f)
}
