//! Legacy VTK input of tetrahedral meshes, parsed by `vtkio`: the `UNSTRUCTURED_GRID` that
//! [`write_vtk`](super::write_vtk) writes, or any legacy file whose cells include tetrahedra (type 10;
//! other cell types are ignored).

use std::path::Path;

use vtkio::model::{CellType, DataSet, Piece, VertexNumbers, Vtk};

use super::read_file;
use crate::{MeshError, TetMesh, Vec3};

fn parse_error(name: &Path, message: impl Into<String>) -> MeshError {
    MeshError::Parse {
        path: name.to_path_buf(),
        line: None,
        message: message.into(),
    }
}

/// Read a legacy VTK file's tetrahedra (see [`parse_vtk`]).
///
/// # Errors
/// [`MeshError::Io`] if the file cannot be read; otherwise as [`parse_vtk`].
pub fn read_vtk(path: &Path) -> Result<TetMesh, MeshError> {
    parse_vtk(&read_file(path)?, path)
}

/// Parse a legacy VTK unstructured grid (ASCII or big-endian binary) as a tetrahedral mesh: every
/// point, and the cells of type 10 (tetrahedron), in file order.
///
/// # Errors
/// [`MeshError::Parse`] if `vtkio` cannot parse the file, the data set is not an unstructured grid,
/// the points are not triples, or a cell list is malformed; [`MeshError::InFile`] wrapping the
/// validation error of [`TetMesh::new`] (no tetrahedra, an index out of range, a degenerate
/// tetrahedron, a non-finite coordinate).
pub fn parse_vtk(bytes: &[u8], name: &Path) -> Result<TetMesh, MeshError> {
    // vtkio is a parser of untrusted input; keep any panic inside it from escaping.
    let parsed = std::panic::catch_unwind(|| Vtk::parse_legacy_be(bytes))
        .map_err(|_| parse_error(name, "the VTK parser failed on this file"))?
        .map_err(|e| parse_error(name, format!("not a legacy VTK file: {e}")))?;
    let DataSet::UnstructuredGrid { pieces, .. } = parsed.data else {
        return Err(parse_error(name, "not an UNSTRUCTURED_GRID data set"));
    };
    let mut positions = Vec::new();
    let mut tetrahedra = Vec::new();
    for piece in pieces {
        let Piece::Inline(piece) = piece else {
            return Err(parse_error(name, "a piece stored in another file"));
        };
        let base = positions.len() as u64;
        let coordinates: Vec<f64> = piece
            .points
            .cast_into()
            .ok_or_else(|| parse_error(name, "the points are not numbers"))?;
        if coordinates.len() % 3 != 0 {
            return Err(parse_error(name, "the point coordinates are not triples"));
        }
        positions.extend(
            coordinates
                .chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2])),
        );
        let types = &piece.cells.types;
        let lists: Vec<Vec<u64>> = match piece.cells.cell_verts {
            VertexNumbers::Legacy { vertices, .. } => {
                let mut lists = Vec::with_capacity(types.len());
                let mut at = 0usize;
                while at < vertices.len() {
                    let n = vertices[at] as usize;
                    let cell = vertices.get(at + 1..at + 1 + n).ok_or_else(|| {
                        parse_error(name, "a cell list runs past the end of CELLS")
                    })?;
                    lists.push(cell.iter().map(|&v| v as u64).collect());
                    at += 1 + n;
                }
                lists
            }
            VertexNumbers::XML {
                connectivity,
                offsets,
            } => {
                let mut start = 0usize;
                let mut lists = Vec::with_capacity(offsets.len());
                for &end in &offsets {
                    let cell = connectivity
                        .get(start..end as usize)
                        .ok_or_else(|| parse_error(name, "a cell offset is out of range"))?;
                    lists.push(cell.to_vec());
                    start = end as usize;
                }
                lists
            }
        };
        if lists.len() != types.len() {
            return Err(parse_error(
                name,
                "CELLS and CELL_TYPES disagree on the number of cells",
            ));
        }
        for (list, kind) in lists.iter().zip(types) {
            if *kind == CellType::Tetra {
                let [a, b, c, d] = <[u64; 4]>::try_from(list.as_slice())
                    .map_err(|_| parse_error(name, "a tetrahedron without 4 vertices"))?;
                let index = |v: u64| u32::try_from(v + base).unwrap_or(u32::MAX);
                tetrahedra.push([index(a), index(b), index(c), index(d)]);
            }
        }
    }
    TetMesh::new(positions, tetrahedra).map_err(|e| e.in_file(name))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{write_vtk, Frame};

    #[test]
    fn vtk_round_trips_and_garbage_is_an_error() {
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.3, 0.25, -0.9),
        ];
        let mesh = TetMesh::new(positions, vec![[0, 1, 2, 3], [0, 2, 1, 4]]).unwrap();
        let mut bytes = Vec::new();
        write_vtk(&Frame::from(&mesh), &mut bytes).unwrap();
        assert_eq!(parse_vtk(&bytes, Path::new("m.vtk")).unwrap(), mesh);
        assert!(parse_vtk(b"# vtk DataFile Version 4.2\nnope", Path::new("bad.vtk")).is_err());
        assert!(parse_vtk(&bytes[..bytes.len() / 2], Path::new("cut.vtk")).is_err());
    }
}
