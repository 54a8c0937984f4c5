//! Legacy VTK output (ParaView, VisIt), written with `vtkio`.
//!
//! `vtkio` 0.7.0-rc2 fits: it builds a legacy `UNSTRUCTURED_GRID` from an owned model and writes it as
//! ASCII through `AsciiWriter`, which takes any `std::fmt::Write`. A small adapter forwards that to the
//! caller's `std::io::Write` (keeping the underlying I/O error, which `fmt::Write` cannot carry), so the
//! file is streamed, not assembled in a `String`. Points are stored as `f64` (`POINTS n double`) and
//! `vtkio` prints them with Rust's `Display`, the shortest digits that read back to the same `f64`.
//! The file declares version 4.2, with the classic `CELLS n size` layout that every ParaView reads
//! (for 5.x `vtkio` would switch to the `OFFSETS`/`CONNECTIVITY` layout, which needs VTK 9). The cost
//! of going through `vtkio` is one owned copy of the frame (coordinates and cell lists) per write,
//! dropped when the write returns, and, since `Display` never uses an exponent, very small or very
//! large coordinates (below 1e-5 or above 1e16 m) are spelled out in full: long, but exact.
//!
//! `vtkio` writes each array (all points, all cell lists) on one line; VTK reads legacy data as white-
//! space-separated tokens, so line length does not matter.
//!
//! A frame may carry data ([`FrameData`]): per point the velocity (`VECTORS velocity double`, m/s)
//! and whether the vertex is pinned (`SCALARS pinned int`, 1 or 0), per cell the strain of each line
//! (`SCALARS strain double`, |r|/l − 1 of the spring the line draws). ParaView lists them as arrays to
//! colour by.

use std::io::Write;

use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, UnstructuredGridPiece, Version,
    VertexNumbers, Vtk,
};
use vtkio::writer::{AsciiWriter, WriteVtk};

use nalgebra::SVector;

use super::{xyz, Frame};

/// Data written with a VTK frame ([`write_vtk_with_data`]); each entry is optional.
#[derive(Clone, Copy, Debug)]
pub struct FrameData<'a, const D: usize> {
    /// One velocity per position (m/s), written as the point vectors `velocity` (2D with z = 0).
    pub velocities: Option<&'a [SVector<f64, D>]>,
    /// One flag per position, written as the point scalars `pinned` (1 pinned, 0 free).
    pub pinned: Option<&'a [bool]>,
    /// One strain per line of the frame (dimensionless: |r|/l − 1 of the spring the line draws,
    /// positive when stretched, negative when compressed), written as the cell scalars `strain`.
    /// The frame's other cells (triangles or tetrahedra) get 0 there: legacy VTK has one value per
    /// cell.
    pub line_strain: Option<&'a [f64]>,
}

impl<const D: usize> Default for FrameData<'_, D> {
    fn default() -> Self {
        FrameData {
            velocities: None,
            pinned: None,
            line_strain: None,
        }
    }
}

impl<const D: usize> FrameData<'_, D> {
    /// Check the data against the frame: one entry per position or per line, finite numbers.
    fn check(&self, frame: &Frame<D>) -> std::io::Result<()> {
        let invalid =
            |message: String| std::io::Error::new(std::io::ErrorKind::InvalidInput, message);
        let count = |what: &str, len: usize, expected: usize, per: &str| {
            if len == expected {
                Ok(())
            } else {
                Err(invalid(format!(
                    "{len} {what} for a frame of {expected} {per}"
                )))
            }
        };
        let points = frame.positions.len();
        if let Some(v) = self.velocities {
            count("velocities", v.len(), points, "vertices")?;
            if let Some(i) = v.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
                return Err(invalid(format!("vertex {i}: the velocity is not finite")));
            }
        }
        if let Some(p) = self.pinned {
            count("pinned flags", p.len(), points, "vertices")?;
        }
        if let Some(s) = self.line_strain {
            count("line strains", s.len(), frame.lines.len(), "lines")?;
            if let Some(i) = s.iter().position(|s| !s.is_finite()) {
                return Err(invalid(format!(
                    "line {i}: the strain {} is not finite",
                    s[i]
                )));
            }
        }
        Ok(())
    }

    /// The vtkio attributes; `cells_before_lines` cells precede the lines.
    fn attributes(&self, cells_before_lines: usize) -> Attributes {
        let mut attributes = Attributes::new();
        if let Some(v) = self.velocities {
            let data: Vec<f64> = v.iter().flat_map(xyz).collect();
            attributes
                .point
                .push(Attribute::vectors("velocity").with_data(data));
        }
        if let Some(p) = self.pinned {
            let data: Vec<i32> = p.iter().map(|&p| i32::from(p)).collect();
            attributes
                .point
                .push(Attribute::scalars("pinned", 1).with_data(data));
        }
        if let Some(s) = self.line_strain {
            let mut data = vec![0.0; cells_before_lines];
            data.extend_from_slice(s);
            attributes
                .cell
                .push(Attribute::scalars("strain", 1).with_data(data));
        }
        attributes
    }
}

/// Write a frame as a legacy ASCII VTK unstructured grid (`# vtk DataFile Version 4.2`, title
/// `hooke`), which ParaView opens directly.
///
/// Points: every position, 2D frames with z = 0, as `double` with shortest round-trip digits. Cells:
/// the tetrahedra (VTK type 10) if there are any, otherwise the triangles (type 5); then the lines
/// (type 3); a frame with none of these gets one vertex cell (type 1) per point so that the points
/// are visible. No point or cell data (see [`write_vtk_with_data`]). Output goes out in many small
/// writes: pass a buffered writer (as [`super::save_vtk`] does).
///
/// # Errors
/// An error of kind [`std::io::ErrorKind::InvalidInput`] before anything is written if an index is out
/// of range, a coordinate is not finite or the frame has more than `u32::MAX` cells; the errors of
/// `out`; or, if `vtkio` itself fails, an error of kind [`std::io::ErrorKind::Other`] with its message.
pub fn write_vtk<const D: usize>(frame: &Frame<D>, out: &mut impl Write) -> std::io::Result<()> {
    write_vtk_with_data(frame, &FrameData::default(), out)
}

/// [`write_vtk`] with point and cell data: the velocities and pinned flags of `data` as point data,
/// its line strains as cell data (see [`FrameData`]).
///
/// # Errors
/// As [`write_vtk`]; also an error of kind [`std::io::ErrorKind::InvalidInput`] before anything is
/// written if an array of `data` does not have one entry per position (velocities, flags) or per line
/// (strains), or holds a non-finite number.
pub fn write_vtk_with_data<const D: usize>(
    frame: &Frame<D>,
    data: &FrameData<D>,
    out: &mut impl Write,
) -> std::io::Result<()> {
    frame.check()?;
    data.check(frame)?;
    let too_many = || {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the frame has more cells than a legacy VTK file can count (u32)",
        )
    };
    let points: Vec<f64> = frame.positions.iter().flat_map(xyz).collect();
    let mut vertices: Vec<u32> = Vec::new();
    let mut types: Vec<CellType> = Vec::new();
    if !frame.tetrahedra.is_empty() {
        vertices.reserve(5 * frame.tetrahedra.len());
        for t in frame.tetrahedra {
            vertices.push(4);
            vertices.extend_from_slice(t);
        }
        types.resize(frame.tetrahedra.len(), CellType::Tetra);
    } else {
        vertices.reserve(4 * frame.triangles.len());
        for t in frame.triangles {
            vertices.push(3);
            vertices.extend_from_slice(t);
        }
        types.resize(frame.triangles.len(), CellType::Triangle);
    }
    let cells_before_lines = types.len();
    for l in frame.lines {
        vertices.push(2);
        vertices.extend_from_slice(l);
        types.push(CellType::Line);
    }
    if types.is_empty() {
        for i in 0..frame.positions.len() {
            vertices.push(1);
            // The frame check bounds the count by the indices' u32 range only for cells; guard here.
            vertices.push(u32::try_from(i).map_err(|_| too_many())?);
            types.push(CellType::Vertex);
        }
    }
    let num_cells = u32::try_from(types.len()).map_err(|_| too_many())?;
    // The legacy header's `size` (cells + their vertices) must fit too.
    u32::try_from(vertices.len()).map_err(|_| too_many())?;
    let vtk = Vtk {
        version: Version::new_legacy(4, 2),
        title: "hooke".to_string(),
        byte_order: ByteOrder::BigEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: points.into(),
            cells: Cells {
                cell_verts: VertexNumbers::Legacy {
                    num_cells,
                    vertices,
                },
                types,
            },
            data: data.attributes(cells_before_lines),
        }),
    };
    let mut adapter = FmtToIo { out, error: None };
    let result = AsciiWriter(&mut adapter).write_vtk(vtk).map(|_| ());
    match (result, adapter.error) {
        (_, Some(error)) => Err(error),
        (Ok(()), None) => Ok(()),
        (Err(error), None) => Err(std::io::Error::other(format!("vtkio: {error}"))),
    }
}

/// `std::fmt::Write` over a `std::io::Write`, keeping the first I/O error.
struct FmtToIo<'a, W: Write> {
    out: &'a mut W,
    error: Option<std::io::Error>,
}

impl<W: Write> std::fmt::Write for FmtToIo<'_, W> {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        if self.error.is_some() {
            return Err(std::fmt::Error);
        }
        self.out.write_all(s.as_bytes()).map_err(|e| {
            self.error = Some(e);
            std::fmt::Error
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;

    #[test]
    fn tetrahedron_and_line() {
        let p = [
            Vec3::zeros(),
            Vec3::x(),
            Vec3::y(),
            Vec3::new(0.1, 0.2, 1.0 / 3.0),
        ];
        let frame = Frame {
            positions: &p,
            triangles: &[[0, 1, 2]],
            tetrahedra: &[[0, 1, 2, 3]],
            lines: &[[0, 3]],
        };
        let mut bytes = Vec::new();
        write_vtk(&frame, &mut bytes).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        assert!(
            text.starts_with("# vtk DataFile Version 4.2\nhooke\nASCII\n"),
            "{text}"
        );
        assert!(text.contains("POINTS 4 double\n"), "{text}");
        assert!(text.contains("0.3333333333333333"), "{text}");
        assert!(text.contains("CELLS 2 8\n4 0 1 2 3 2 0 3\n"), "{text}");
        assert!(text.contains("CELL_TYPES 2\n10\n3\n"), "{text}");
    }

    #[test]
    fn point_and_cell_data_are_written_and_checked() {
        let p = [Vec3::zeros(), Vec3::x(), Vec3::y()];
        let v = [Vec3::new(0.5, -1.0, 0.0), Vec3::zeros(), Vec3::z()];
        let frame = Frame {
            triangles: &[[0, 1, 2]],
            lines: &[[0, 1], [1, 2]],
            ..Frame::points(&p)
        };
        let data = FrameData {
            velocities: Some(&v),
            pinned: Some(&[true, false, false]),
            line_strain: Some(&[0.25, -0.125]),
        };
        let mut bytes = Vec::new();
        write_vtk_with_data(&frame, &data, &mut bytes).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        assert!(text.contains("POINT_DATA 3\n"), "{text}");
        assert!(text.contains("VECTORS velocity double\n"), "{text}");
        assert!(text.contains("0.5 -1 0 0 0 0 0 0 1"), "{text}");
        assert!(text.contains("SCALARS pinned int 1\n"), "{text}");
        assert!(text.contains("CELL_DATA 3\n"), "{text}");
        assert!(text.contains("SCALARS strain double 1\n"), "{text}");
        // The triangle's strain is 0, the lines' follow.
        assert!(text.contains("0 0.25 -0.125"), "{text}");

        // Wrong lengths and non-finite values are refused before anything is written.
        let bad = [
            FrameData {
                velocities: Some(&v[..2]),
                ..FrameData::default()
            },
            FrameData {
                pinned: Some(&[true]),
                ..FrameData::default()
            },
            FrameData {
                line_strain: Some(&[0.0]),
                ..FrameData::default()
            },
            FrameData {
                line_strain: Some(&[0.0, f64::NAN]),
                ..FrameData::default()
            },
        ];
        for data in bad {
            let mut bytes = Vec::new();
            let e = write_vtk_with_data(&frame, &data, &mut bytes).unwrap_err();
            assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput, "{e}");
            assert!(bytes.is_empty());
        }
    }

    #[test]
    fn io_errors_come_through() {
        struct Full;
        impl Write for Full {
            fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
                Err(std::io::Error::new(
                    std::io::ErrorKind::StorageFull,
                    "disk full",
                ))
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let p = [Vec3::zeros()];
        let e = write_vtk(&Frame::points(&p), &mut Full).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::StorageFull);
    }
}
