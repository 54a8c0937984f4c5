//! Graded against uniform isosurface stuffing of the bunny (`data/meshes/bunny.obj`) at spacings
//! given as divisions of its bounding-box diagonal (default 60 and 120): tetrahedron counts,
//! dihedral angles, and wall-clock and user CPU seconds (all threads; Linux, from /proc), one run
//! each. Quicker than the criterion bench for a
//! single figure:
//!
//! `cargo run --release -p hooke-mesh --example graded_bunny -- 60 120`

use std::path::PathBuf;

use hooke_mesh::io::read_obj;
use hooke_mesh::stuffing::{tetrahedralize, tetrahedralize_graded, ClosedSurface, StuffingOptions};

/// User CPU time of this process so far (s, all threads), from /proc/self/stat (Linux; the kernel
/// counts in ticks of 1/100 s); 0 elsewhere.
fn user_cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            // Fields after the command name (in parentheses): utime is the 12th.
            let rest = &s[s.rfind(')')? + 2..];
            rest.split_whitespace().nth(11)?.parse::<f64>().ok()
        })
        .map_or(0.0, |ticks| ticks / 100.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/meshes/bunny.obj");
    let surface = ClosedSurface::new(&read_obj(&path)?)?;
    let [lo, hi] = surface.bounds();
    let diagonal = (hi - lo).norm();
    let mut divisions: Vec<u32> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    if divisions.is_empty() {
        divisions = vec![60, 120];
    }
    for n in divisions {
        let options = StuffingOptions::new(diagonal / n as f64)?;
        let cpu = user_cpu_seconds();
        let graded = tetrahedralize_graded(&surface, &options)?;
        let graded_cpu = user_cpu_seconds() - cpu;
        let cpu = user_cpu_seconds();
        let uniform = tetrahedralize(&surface, &options)?;
        let uniform_cpu = user_cpu_seconds() - cpu;
        println!(
            "diagonal/{n}: graded {} tets {} vertices ({:.2}× fewer than uniform's {} tets {} vertices), dihedral {:.3}°–{:.3}° (uniform {:.3}°–{:.3}°), volume {:+.3} % (uniform {:+.3} %), {:.3} s against {:.3} s wall, {:.2} s against {:.2} s user CPU",
            graded.report.tets,
            graded.report.vertices,
            uniform.report.tets as f64 / graded.report.tets as f64,
            uniform.report.tets,
            uniform.report.vertices,
            graded.report.min_dihedral_deg,
            graded.report.max_dihedral_deg,
            uniform.report.min_dihedral_deg,
            uniform.report.max_dihedral_deg,
            100.0 * (graded.report.volume / surface.enclosed_volume() - 1.0),
            100.0 * (uniform.report.volume / surface.enclosed_volume() - 1.0),
            graded.report.seconds,
            uniform.report.seconds,
            graded_cpu,
            uniform_cpu,
        );
    }
    Ok(())
}
