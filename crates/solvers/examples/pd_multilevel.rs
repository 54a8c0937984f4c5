//! Projective dynamics' global step on the direct and the multilevel path, side by side on
//! cloth-N's first step from rest (docs/solvers.md §6.1): the set-up (factorisation or hierarchy),
//! the step of `iterations` PD iterations, the multilevel path's CG iterations, and how far the two
//! results are apart (the largest coordinate difference, m) and from the step's start.
//!
//! `cargo run --release -p hooke-solvers --example pd_multilevel -- [N=320] [iterations=10]
//! [tolerance=0.5] [paths=direct,multilevel] [repeats=3] [smoother parts=default]`

use std::time::Instant;

use hooke_assembly::FreeDofs;
use hooke_mesh::generators;
use hooke_solvers::{AmgParams, GlobalSolveKind, PdMultilevelParams, PdParams, ProjectiveDynamics};
use nalgebra::Vector3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or(default.to_string());
    let n: usize = arg(0, "320").parse()?;
    let iterations: usize = arg(1, "10").parse()?;
    let tolerance: f64 = arg(2, "0.5").parse()?;
    let paths = arg(3, "direct,multilevel");
    let repeats: usize = arg(4, "3").parse()?;
    let defaults = PdMultilevelParams::default();
    let parts: usize = match args.get(5) {
        Some(p) => p.parse()?,
        None => defaults.amg.smoother_parts,
    };
    let mesh = generators::cloth(n, 1e3)?;
    let free = FreeDofs::new(mesh.vertex_count(), &[0, n as u32 - 1])?;
    let h = 1.0 / 30.0;
    let gravity = Vector3::new(0.0, -9.81, 0.0);
    let start: Vec<Vector3<f64>> = mesh.positions().to_vec();
    // The first step from rest: y = x_n + h v_n + h² g, pins kept.
    let mut y = start.clone();
    for &v in free.free_vertices() {
        y[v as usize] += gravity * h * h;
    }
    let mut results = Vec::new();
    for path in paths.split(',') {
        let kind = match path {
            "direct" => GlobalSolveKind::Direct,
            "multilevel" => GlobalSolveKind::Multilevel,
            other => return Err(format!("unknown path {other}").into()),
        };
        let params = PdParams {
            max_iterations: iterations,
            global_solve: kind,
            multilevel: PdMultilevelParams {
                tolerance,
                amg: AmgParams {
                    smoother_parts: parts,
                    ..defaults.amg
                },
                ..defaults
            },
            ..PdParams::default()
        };
        let t = Instant::now();
        let mut pd = ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, h, params)?;
        let setup = t.elapsed();
        let mut times = Vec::new();
        let mut x = y.clone();
        let mut linear = 0;
        for _ in 0..repeats {
            x.copy_from_slice(&y);
            let report = pd.solve(mesh.springs(), &y, &mut x)?;
            times.push(report.wall_time);
            linear = report.linear_iterations;
        }
        times.sort();
        println!(
            "cloth-{n} {path:>10}: set-up {:8.1} ms, step {:8.1} ms (median of {repeats}), {linear} CG iterations",
            setup.as_secs_f64() * 1e3,
            times[times.len() / 2].as_secs_f64() * 1e3,
        );
        results.push((x, pd));
    }
    if let [(a, pd), (b, _)] = &results[..] {
        let apart = a
            .iter()
            .zip(b)
            .map(|(p, q)| (p - q).amax())
            .fold(0.0, f64::max);
        let moved = a
            .iter()
            .zip(&start)
            .map(|(p, q)| (p - q).amax())
            .fold(0.0, f64::max);
        // Φ(second) − Φ(first) over the first's decrease from y: how much less (< 0) or more
        // (> 0) the second result lowered the step's objective.
        let gain = pd.objective_change(mesh.springs(), &y, a, b);
        let decrease = -pd.objective_change(mesh.springs(), &y, &y, a);
        println!(
            "largest difference {apart:.3e} m; largest move from the start {moved:.3e} m; \
             Φ(second) − Φ(first) = {:.3e} of the first's decrease from y",
            gain / decrease
        );
    }
    Ok(())
}
