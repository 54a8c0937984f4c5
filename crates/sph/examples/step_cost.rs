//! Cost of a 2D WCSPH step against particle count, split by phase (the same measurement as
//! `hooke bench --sph`, without the command's plot).
//!
//! `cargo run --release -p hooke-sph --example step_cost -- [--shuffle] 10000 100000 1000000`
use hooke_sph::scenes::step_cost_column;
use hooke_sph::Fluid;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    // --shuffle numbers the fluid particles in a random order, as a long run's mixing leaves them
    // (the column is built row by row, which is nearly the grid's order).
    let shuffle = args.iter().any(|a| a == "--shuffle");
    let counts: Vec<usize> = args
        .iter()
        .filter(|a| *a != "--shuffle")
        .map(|s| s.parse::<f64>().map(|n| n as usize))
        .collect::<Result<_, _>>()?;
    let steps = 5u32;
    println!(
        "threads {}{}",
        rayon::current_num_threads(),
        if shuffle { ", particles shuffled" } else { "" }
    );
    println!(
        "N,boundary,ms_per_step,particle_steps_per_s,search_ms,density_ms,forces_ms,update_ms"
    );
    for n in counts {
        let spec = step_cost_column(n);
        let mut setup = spec.build()?;
        if shuffle {
            // Fisher-Yates with a fixed LCG: the same order every run.
            let mut state = 0x2545f4914f6cdd1du64;
            for i in (1..setup.fluid_positions.len()).rev() {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let j = ((state >> 33) % (i as u64 + 1)) as usize;
                setup.fluid_positions.swap(i, j);
                if !setup.fluid_velocities.is_empty() {
                    setup.fluid_velocities.swap(i, j);
                }
                if !setup.fluid_densities.is_empty() {
                    setup.fluid_densities.swap(i, j);
                }
            }
        }
        let mut fluid = Fluid::new(setup)?;
        fluid.step()?;
        fluid.step()?;
        fluid.reset_timings();
        let start = std::time::Instant::now();
        for _ in 0..steps {
            fluid.step()?;
        }
        let per = start.elapsed().as_secs_f64() / steps as f64;
        let t = fluid.timings();
        let ms = |d: std::time::Duration| 1e3 * d.as_secs_f64() / steps as f64;
        println!(
            "{},{},{:.3},{:.4e},{:.3},{:.3},{:.3},{:.3}",
            fluid.fluid_count(),
            fluid.boundary_count(),
            1e3 * per,
            fluid.fluid_count() as f64 / per,
            ms(t.neighbour_search),
            ms(t.density),
            ms(t.forces),
            ms(t.integration)
        );
    }
    Ok(())
}
