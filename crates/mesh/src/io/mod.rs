//! Mesh files: readers for OBJ and STL surfaces, Gmsh MSH and TetGen volumes, and writers for OBJ and
//! legacy VTK frames.
//!
//! Coordinates are read and written as they are in the file, in metres by hooke's convention (no unit
//! conversion is done). Every reader validates the mesh it builds through [`TriMesh::new`] or
//! [`TetMesh::new`] and never panics, whatever the input:
//!
//! - a file that cannot be read gives [`MeshError::Io`];
//! - a file whose syntax is wrong gives [`MeshError::Parse`], with the file, the 1-based line where the
//!   format has lines and the reader knows it, and what was expected;
//! - a well-formed file whose mesh is invalid (non-finite coordinate, index out of range, repeated
//!   vertex, degenerate element, no vertices, no elements) gives [`MeshError::InFile`] wrapping the
//!   validation error.
//!
//! Writers take a borrowed [`Frame`]; [`save_obj`] and [`save_vtk`] write a file atomically through
//! [`write_atomically`], so that a reader never sees a half-written frame.
//!
//! ```
//! use hooke_mesh::io::{parse_obj, write_obj, Frame};
//! use std::path::Path;
//!
//! let mesh = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", Path::new("tri.obj"))?;
//! let mut bytes = Vec::new();
//! write_obj(&Frame::from(&mesh), &mut bytes)?;
//! assert_eq!(parse_obj(&bytes, Path::new("copy.obj"))?, mesh);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::path::{Path, PathBuf};

use nalgebra::SVector;

use crate::{MeshError, SpringMesh, TetMesh, TriMesh};

mod atomic;
mod msh;
mod obj;
mod stl;
mod tet_write;
mod tetgen;
mod vtk;
mod vtk_read;

pub use atomic::{is_temporary, remove_temporaries, remove_temporaries_of, write_atomically};
pub use msh::{parse_msh, read_msh};
pub use obj::{parse_obj, read_obj, write_obj};
pub use stl::{parse_stl, read_stl};
pub use tet_write::{save_msh, save_tetgen, write_msh, write_tetgen_ele, write_tetgen_node};
pub use tetgen::{parse_tetgen, read_tetgen};
pub use vtk::{write_vtk, write_vtk_with_data, FrameData};
pub use vtk_read::{parse_vtk, read_vtk};

/// A mesh read from a file of any supported format: a surface or a volume.
#[derive(Clone, Debug, PartialEq)]
pub enum Mesh {
    /// A triangle surface mesh (from `.obj` or `.stl`).
    Surface(TriMesh),
    /// A tetrahedral volume mesh (from `.msh`, or a TetGen `.node`/`.ele` pair).
    Volume(TetMesh),
}

/// Read a mesh file, choosing the reader by the extension (case-insensitive): `.obj` ([`read_obj`]) and
/// `.stl` ([`read_stl`]) give a [`Mesh::Surface`]; `.msh` ([`read_msh`]), `.node` or `.ele`
/// ([`read_tetgen`], which reads both files of the pair) and `.vtk` ([`read_vtk`]) give a
/// [`Mesh::Volume`].
///
/// # Errors
/// [`MeshError::Parse`] naming the file and the supported extensions if the extension is not one of
/// these; otherwise whatever the chosen reader returns.
pub fn read_mesh(path: &Path) -> Result<Mesh, MeshError> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("obj") => read_obj(path).map(Mesh::Surface),
        Some("stl") => read_stl(path).map(Mesh::Surface),
        Some("msh") => read_msh(path).map(Mesh::Volume),
        Some("node" | "ele") => read_tetgen(path).map(Mesh::Volume),
        Some("vtk") => read_vtk(path).map(Mesh::Volume),
        other => Err(MeshError::Parse {
            path: path.to_path_buf(),
            line: None,
            message: format!(
                "{}: supported mesh files are .obj and .stl (triangle surfaces), .msh (Gmsh \
                 tetrahedra), .node/.ele (TetGen tetrahedra) and .vtk (legacy VTK tetrahedra)",
                match other {
                    Some(e) => format!("unsupported extension \".{e}\""),
                    None => "no file extension".to_string(),
                }
            ),
        }),
    }
}

/// One frame to write: borrowed positions (m) in dimension `D` (2 or 3; 2D points are written with
/// z = 0) and the cells to draw, as 0-based indices into `positions`.
///
/// Writers check that every index is in range and every coordinate finite before writing anything.
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a, const D: usize> {
    /// Vertex positions (m).
    pub positions: &'a [SVector<f64, D>],
    /// Surface triangles.
    pub triangles: &'a [[u32; 3]],
    /// Volume tetrahedra (written to VTK only).
    pub tetrahedra: &'a [[u32; 4]],
    /// Line segments, e.g. springs or hair strands.
    pub lines: &'a [[u32; 2]],
}

impl<'a, const D: usize> Frame<'a, D> {
    /// A frame of points only, with no cells.
    pub fn points(positions: &'a [SVector<f64, D>]) -> Self {
        Frame {
            positions,
            triangles: &[],
            tetrahedra: &[],
            lines: &[],
        }
    }

    /// Check the frame before writing: dimension 2 or 3, indices in range, finite coordinates.
    pub(crate) fn check(&self) -> std::io::Result<()> {
        let invalid =
            |message: String| std::io::Error::new(std::io::ErrorKind::InvalidInput, message);
        if D != 2 && D != 3 {
            return Err(invalid(format!("frames are 2D or 3D, not {D}D")));
        }
        for (vertex, p) in self.positions.iter().enumerate() {
            if let Some(axis) = p.iter().position(|c| !c.is_finite()) {
                return Err(invalid(format!(
                    "vertex {vertex}: coordinate {axis} is not finite ({})",
                    p[axis]
                )));
            }
        }
        let n = self.positions.len();
        let check = |kind: &str, element: usize, indices: &[u32]| match indices
            .iter()
            .find(|&&i| usize::try_from(i).map_or(true, |i| i >= n))
        {
            Some(&i) => Err(invalid(format!(
                "{kind} {element}: vertex index {i} is out of range (the frame has {n} vertices)"
            ))),
            None => Ok(()),
        };
        for (e, t) in self.triangles.iter().enumerate() {
            check("triangle", e, t)?;
        }
        for (e, t) in self.tetrahedra.iter().enumerate() {
            check("tetrahedron", e, t)?;
        }
        for (e, l) in self.lines.iter().enumerate() {
            check("line", e, l)?;
        }
        Ok(())
    }
}

/// A point's coordinates padded to 3D with z = 0.
pub(crate) fn xyz<const D: usize>(p: &SVector<f64, D>) -> [f64; 3] {
    std::array::from_fn(|axis| if axis < D { p[axis] } else { 0.0 })
}

impl<'a> From<&'a TriMesh> for Frame<'a, 3> {
    /// The mesh's positions and triangles.
    fn from(mesh: &'a TriMesh) -> Self {
        Frame {
            triangles: mesh.triangles(),
            ..Frame::points(mesh.positions())
        }
    }
}

impl<'a> From<&'a TetMesh> for Frame<'a, 3> {
    /// The mesh's positions and tetrahedra.
    fn from(mesh: &'a TetMesh) -> Self {
        Frame {
            tetrahedra: mesh.tetrahedra(),
            ..Frame::points(mesh.positions())
        }
    }
}

impl<'a, const D: usize> From<&'a SpringMesh<D>> for Frame<'a, D> {
    /// The spring mesh's initial positions and its output triangles and tetrahedra (no lines: the
    /// springs are `Spring` structs, not index pairs; pass them in `lines` yourself if wanted).
    fn from(mesh: &'a SpringMesh<D>) -> Self {
        Frame {
            triangles: mesh.triangles(),
            tetrahedra: mesh.tetrahedra(),
            ..Frame::points(mesh.positions())
        }
    }
}

/// Write `frame` as OBJ to `path`, atomically (see [`write_atomically`] and [`write_obj`]).
///
/// # Errors
/// [`MeshError::Io`] naming `path` if the frame is invalid (index out of range, non-finite coordinate)
/// or the file cannot be written; the target is then left as it was.
pub fn save_obj<const D: usize>(path: &Path, frame: &Frame<D>) -> Result<(), MeshError> {
    write_atomically(path, |out| write_obj(frame, out))
}

/// Write `frame` as legacy ASCII VTK to `path`, atomically (see [`write_atomically`] and
/// [`write_vtk`]).
///
/// # Errors
/// [`MeshError::Io`] naming `path` if the frame is invalid (index out of range, non-finite coordinate)
/// or the file cannot be written; the target is then left as it was.
pub fn save_vtk<const D: usize>(path: &Path, frame: &Frame<D>) -> Result<(), MeshError> {
    write_atomically(path, |out| write_vtk(frame, out))
}

/// Write `frame` with point and cell data as legacy ASCII VTK to `path`, atomically (see
/// [`write_atomically`] and [`write_vtk_with_data`]).
///
/// # Errors
/// [`MeshError::Io`] naming `path` if the frame or its data is invalid (index out of range,
/// non-finite value, an array of the wrong length) or the file cannot be written; the target is then
/// left as it was.
pub fn save_vtk_with_data<const D: usize>(
    path: &Path,
    frame: &Frame<D>,
    data: &FrameData<D>,
) -> Result<(), MeshError> {
    write_atomically(path, |out| write_vtk_with_data(frame, data, out))
}

/// Read a whole file, mapping failure to [`MeshError::Io`].
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, MeshError> {
    std::fs::read(path).map_err(|source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// A [`MeshError::Parse`] for `path`.
pub(crate) fn parse_error(
    path: &Path,
    line: Option<usize>,
    message: impl Into<String>,
) -> MeshError {
    MeshError::Parse {
        path: PathBuf::from(path),
        line,
        message: message.into(),
    }
}

/// A token for an error message: quoted, and cut to a readable length (random input can hold a
/// megabyte-long "token").
pub(crate) fn quote(token: &str) -> String {
    const MAX: usize = 40;
    match token.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{:?}…", &token[..cut]),
        None => format!("{token:?}"),
    }
}

/// `f64` formatting that round-trips exactly and stays short: Rust's shortest round-trip digits, in
/// positional notation for ordinary magnitudes and in scientific notation for very large or very
/// small ones (positional `{}` would spell 1e-300 with 300 zeros).
pub(crate) struct RoundTrip(pub f64);

impl std::fmt::Display for RoundTrip {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let magnitude = self.0.abs();
        if magnitude == 0.0 || (1e-5..1e16).contains(&magnitude) || !magnitude.is_finite() {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_formatting_is_exact() {
        for x in [
            0.0,
            -0.0,
            1.0,
            0.1,
            1.0 / 3.0,
            -2.5e-7,
            1e-300,
            5e-324,
            1.7976931348623157e308,
            123456789.123,
            1e16,
            f64::from_bits(1e16f64.to_bits() - 1),
        ] {
            let text = RoundTrip(x).to_string();
            let back: f64 = text.parse().unwrap();
            assert_eq!(back.to_bits(), x.to_bits(), "{x} written as {text}");
            assert!(text.len() < 30, "{text}");
        }
    }

    #[test]
    fn quote_cuts_long_tokens() {
        assert_eq!(quote("abc"), "\"abc\"");
        let long = "é".repeat(100);
        assert!(quote(&long).chars().count() < 50);
    }

    #[test]
    fn read_mesh_rejects_unknown_extensions() {
        for name in ["mesh.ply", "mesh", "mesh.off"] {
            let e = read_mesh(Path::new(name)).unwrap_err();
            let text = e.to_string();
            assert!(matches!(e, MeshError::Parse { line: None, .. }), "{e:?}");
            assert!(text.contains(name) && text.contains(".obj"), "{text}");
        }
    }
}
