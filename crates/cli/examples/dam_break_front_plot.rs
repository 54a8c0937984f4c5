//! Plot dam-break fronts against the experiment: reads CSV files with columns `T` and `Z` (as the
//! hooke-sph example `dam_break_fronts` writes them) and the experiment's `T,Z` file, and writes a
//! PNG with one line per run, labelled by the file name.
//!
//! `cargo run --release -p hooke-cli --example dam_break_front_plot -- OUT.png \
//!  data/sph/dam_break_koshizuka_oka.csv benches/results/sph-front-dx0.02.csv …`
use std::path::Path;

fn read(path: &str) -> Result<Vec<(f64, f64)>, Box<dyn std::error::Error>> {
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(path)?;
    let headers = reader.headers()?.clone();
    let column = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("{path}: no column {name}"))
    };
    let (t, z) = (column("T")?, column("Z")?);
    let mut points = Vec::new();
    for record in reader.records() {
        let record = record?;
        points.push((record[t].parse()?, record[z].parse()?));
    }
    Ok(points)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [out, experiment, runs @ ..] = args.as_slice() else {
        return Err("usage: dam_break_front_plot OUT.png EXPERIMENT.csv RUN.csv…".into());
    };
    let runs = runs
        .iter()
        .map(|path| {
            let name = Path::new(path)
                .file_stem()
                .map_or(path.clone(), |s| s.to_string_lossy().into_owned());
            read(path).map(|points| (name, points))
        })
        .collect::<Result<Vec<_>, _>>()?;
    hooke_cli::bench::plot_fronts(
        Path::new(out),
        &runs,
        &read(experiment)?,
        "dam-break-2d: front against the experiment",
    )?;
    Ok(())
}
