//! `hooke mesh`: fill a closed surface with tetrahedra (`tetrahedralize`) and report the quality of
//! any tetrahedral mesh (`quality`).

use std::path::{Path, PathBuf};

use crate::mesh::io::{
    read_mesh, remove_temporaries_of, save_msh, save_tetgen, save_vtk, write_atomically, Frame,
    Mesh,
};
use crate::mesh::stuffing::{
    quality_report, tetrahedralize, tetrahedralize_graded, ClosedSurface, QualityReport,
    StuffingError, StuffingOptions,
};
use crate::mesh::MeshError;

/// `hooke mesh …`.
#[derive(clap::Args)]
pub(crate) struct MeshArgs {
    #[command(subcommand)]
    command: MeshCommand,
}

#[derive(clap::Subcommand)]
enum MeshCommand {
    /// Fill a closed OBJ/STL surface with tetrahedra by isosurface stuffing (dihedral angles
    /// between 9.3171° and 161.6432°, Labelle and Shewchuk's proven bounds for the thresholds in
    /// use), write the mesh and print its quality report.
    Tetrahedralize {
        /// The closed surface (.obj or .stl).
        input: PathBuf,
        /// Lattice spacing h in the surface's units (m): output edges are about 0.2·h to 1.1·h long.
        #[arg(long, allow_negative_numbers = true)]
        spacing: f64,
        /// A graded mesh (the paper's octree variant): tetrahedra of the spacing at the surface, up to
        /// 16 times larger inside; same boundary and angle bounds as the uniform mesh.
        #[arg(long)]
        graded: bool,
        /// Output mesh: .vtk (legacy VTK), .node (TetGen, with the .ele beside it) or .msh (Gmsh 4.1).
        #[arg(long)]
        out: PathBuf,
        /// Also write the report as JSON.
        #[arg(long, value_name = "REPORT.json")]
        json: Option<PathBuf>,
    },
    /// Print the quality report of a tetrahedral mesh (.vtk, .node/.ele or .msh).
    Quality {
        /// The mesh.
        mesh: PathBuf,
        /// Also write the report as JSON.
        #[arg(long, value_name = "REPORT.json")]
        json: Option<PathBuf>,
    },
}

/// What `hooke mesh` can fail with.
#[derive(Debug, thiserror::Error)]
pub(crate) enum MeshCommandError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("{}: {source}", path.display())]
    Surface {
        path: PathBuf,
        source: StuffingError,
    },
    #[error("{}: {what}", path.display())]
    Input { path: PathBuf, what: String },
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Run `hooke mesh …`.
pub(crate) fn run(args: &MeshArgs) -> Result<(), MeshCommandError> {
    match &args.command {
        MeshCommand::Tetrahedralize {
            input,
            spacing,
            graded,
            out,
            json,
        } => {
            let out_kind = extension(out);
            if !matches!(out_kind.as_str(), "vtk" | "node" | "msh") {
                return Err(MeshCommandError::Input {
                    path: out.clone(),
                    what: "the output must end in .vtk, .node or .msh".into(),
                });
            }
            let surface_error = |source| MeshCommandError::Surface {
                path: input.clone(),
                source,
            };
            let options = StuffingOptions::new(*spacing).map_err(surface_error)?;
            // The temporary files a killed earlier write of these outputs left beside them.
            let mut outputs = match out_kind.as_str() {
                "node" => vec![out.with_extension("node"), out.with_extension("ele")],
                _ => vec![out.clone()],
            };
            outputs.extend(json.iter().cloned());
            for output in &outputs {
                remove_temporaries_of(output)?;
            }
            let mesh = match read_mesh(input)? {
                Mesh::Surface(mesh) => mesh,
                Mesh::Volume(_) => return Err(MeshCommandError::Input {
                    path: input.clone(),
                    what:
                        "a tetrahedral mesh: tetrahedralize needs a closed surface (.obj or .stl)"
                            .into(),
                }),
            };
            let surface = ClosedSurface::new(&mesh).map_err(surface_error)?;
            if surface.was_inside_out() {
                eprintln!(
                    "{}: the surface was inside out (negative enclosed volume); turned outward",
                    input.display()
                );
            }
            let stuffed = if *graded {
                tetrahedralize_graded(&surface, &options)
            } else {
                tetrahedralize(&surface, &options)
            }
            .map_err(surface_error)?;
            let mut report = stuffed.report;
            report.hausdorff = Some(crate::mesh::stuffing::hausdorff_distance(
                &stuffed.mesh,
                &surface,
            ));
            match out_kind.as_str() {
                "vtk" => save_vtk(out, &Frame::from(&stuffed.mesh))?,
                "node" => save_tetgen(out, &stuffed.mesh)?,
                _ => save_msh(out, &stuffed.mesh)?,
            }
            print_report(&report);
            if let Some(path) = json {
                save_json(path, &report)?;
            }
            Ok(())
        }
        MeshCommand::Quality { mesh, json } => {
            if let Some(path) = json {
                remove_temporaries_of(path)?;
            }
            let tets =
                match read_mesh(mesh)? {
                    Mesh::Volume(tets) => tets,
                    Mesh::Surface(_) => return Err(MeshCommandError::Input {
                        path: mesh.clone(),
                        what:
                            "a surface: quality needs a tetrahedral mesh (.vtk, .node/.ele or .msh)"
                                .into(),
                    }),
                };
            let report = quality_report(&tets, None);
            print_report(&report);
            if let Some(path) = json {
                save_json(path, &report)?;
            }
            Ok(())
        }
    }
}

fn print_report(report: &QualityReport) {
    println!("tetrahedra        {}", report.tets);
    println!("vertices          {}", report.vertices);
    println!("min dihedral      {:.3}°", report.min_dihedral_deg);
    println!("max dihedral      {:.3}°", report.max_dihedral_deg);
    println!("min radius ratio  {:.4}", report.min_radius_ratio);
    println!("volume            {:.6e}", report.volume);
    if let Some(v) = report.surface_volume {
        println!(
            "surface volume    {v:.6e} ({:+.3} %)",
            100.0 * (report.volume - v) / v
        );
    }
    if let Some(h) = report.hausdorff {
        println!("hausdorff         {h:.4e}");
    }
    if report.seconds > 0.0 {
        println!(
            "seconds           {:.3} ({:.0} tetrahedra/s)",
            report.seconds,
            report.tets as f64 / report.seconds
        );
    }
}

/// The JSON report (docs/formats.md §8): `null` where a value does not apply.
fn report_json(report: &QualityReport) -> serde_json::Value {
    serde_json::json!({
        "tets": report.tets,
        "vertices": report.vertices,
        "min_dihedral_deg": report.min_dihedral_deg,
        "max_dihedral_deg": report.max_dihedral_deg,
        "min_radius_ratio": report.min_radius_ratio,
        "volume": report.volume,
        "surface_volume": report.surface_volume,
        "hausdorff": report.hausdorff,
        "seconds": report.seconds,
    })
}

fn save_json(path: &Path, report: &QualityReport) -> Result<(), MeshError> {
    let text = serde_json::to_string_pretty(&report_json(report)).unwrap_or_default();
    write_atomically(path, |out| {
        use std::io::Write;
        writeln!(out, "{text}")
    })
}
