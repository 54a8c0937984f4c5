//! Wavefront OBJ: triangle surfaces in, frames out.
//!
//! The reader is a small parser of its own rather than `tobj` (which the workspace also declares).
//! Three properties that hooke needs are out of `tobj`'s reach as configured (`default-features =
//! false`, no `use_f64`):
//!
//! - **f64 positions.** `tobj` stores `f32` unless its `use_f64` feature is on, so a frame written
//!   with full `f64` precision would not read back bit-exact.
//! - **Vertex numbering.** Without `single_index`, `tobj` renumbers each model's vertices in order of
//!   first use by a face and drops unused ones; with `single_index` it splits vertices that carry
//!   different texture coordinates or normals (the seams of `cloth_30x30.obj`, `torus.obj`). hooke
//!   keeps the file's vertex numbers, so that vertex `k` of the file (1-based) is vertex `k − 1` of the
//!   mesh: pins and scene files refer to vertices by number.
//! - **Line numbers.** `tobj`'s errors carry no position; these carry the file and the line.
//!
//! Supported: `v x y z [w]` (w and any further values such as vertex colours are ignored), and
//! `f` with `v`, `v/t`, `v//n` or `v/t/n` references, 1-based or negative (relative to the vertices
//! read so far). Polygons with more than three vertices are split into a fan of triangles
//! `(v1, vi, vi+1)`, as `tobj` does. Objects and groups are merged into one mesh: OBJ indices are global
//! to the file. Everything else (`vt`, `vn`, `o`, `g`, `s`, `l`, `mtllib`, `usemtl`, …) is ignored,
//! and `#` starts a comment anywhere on a line. Line continuation with `\` is not supported.

use std::io::Write;
use std::path::Path;

use super::{parse_error, quote, read_file, xyz, Frame, RoundTrip};
use crate::{MeshError, TriMesh, Vec3};

/// Read a Wavefront OBJ file as a triangle mesh (see [`parse_obj`]).
///
/// # Errors
/// [`MeshError::Io`] if the file cannot be read; otherwise as [`parse_obj`].
pub fn read_obj(path: &Path) -> Result<TriMesh, MeshError> {
    parse_obj(&read_file(path)?, path)
}

/// Parse the bytes of an OBJ file as a triangle mesh; `name` is the file named in errors.
///
/// Positions are read as `f64` in file order (vertex `k` of the file is vertex `k − 1` of the mesh,
/// unused vertices included) and triangles in file order, polygons fan-triangulated. See the module
/// documentation for the supported statements.
///
/// # Errors
/// - [`MeshError::Parse`] with the 1-based line: a `v` without three numbers, an `f` with fewer than
///   three vertices or a reference that is not a non-zero integer, or a negative reference before the
///   first vertex.
/// - [`MeshError::InFile`] wrapping the validation error of [`TriMesh::new`]: no vertices (e.g. an empty
///   file), no faces, a non-finite coordinate (`nan`, `inf`), a reference past the last vertex
///   ([`MeshError::IndexOutOfRange`]), a face that repeats a vertex, or a degenerate triangle.
pub fn parse_obj(bytes: &[u8], name: &Path) -> Result<TriMesh, MeshError> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut face: Vec<u32> = Vec::new();
    for (index, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = index + 1;
        let text = String::from_utf8_lossy(raw);
        let text = text.split('#').next().unwrap_or("");
        let mut tokens = text.split_whitespace();
        match tokens.next() {
            Some("v") => {
                let mut p = [0.0; 3];
                for (axis, value) in p.iter_mut().enumerate() {
                    let token = tokens.next().ok_or_else(|| {
                        parse_error(
                            name,
                            Some(line),
                            format!(
                                "expected a vertex `v x y z` with three numbers, found {}",
                                ["none", "one", "two"][axis]
                            ),
                        )
                    })?;
                    *value = token.parse().map_err(|_| {
                        parse_error(
                            name,
                            Some(line),
                            format!(
                                "expected coordinate {} of a vertex `v x y z` to be a number, found {}",
                                ["x", "y", "z"][axis],
                                quote(token)
                            ),
                        )
                    })?;
                }
                positions.push(Vec3::from(p));
            }
            Some("f") => {
                face.clear();
                for token in tokens {
                    face.push(vertex_reference(token, positions.len(), name, line)?);
                }
                if face.len() < 3 {
                    return Err(parse_error(
                        name,
                        Some(line),
                        format!(
                            "expected a face `f` with at least three vertices, found {}",
                            face.len()
                        ),
                    ));
                }
                for k in 1..face.len() - 1 {
                    triangles.push([face[0], face[k], face[k + 1]]);
                }
            }
            _ => {}
        }
    }
    TriMesh::new(positions, triangles).map_err(|e| e.in_file(name))
}

/// Resolve one face vertex reference (`v`, `v/t`, `v//n`, `v/t/n`) to a 0-based index. Indices past the
/// last vertex are returned as they are, for [`TriMesh::new`] to report as out of range.
fn vertex_reference(token: &str, read: usize, name: &Path, line: usize) -> Result<u32, MeshError> {
    let position = token.split('/').next().unwrap_or("");
    let bad = |what: &str| {
        parse_error(
            name,
            Some(line),
            format!(
                "expected a face vertex `v`, `v/t`, `v//n` or `v/t/n` with v a non-zero integer, \
                 found {}: {what}",
                quote(token)
            ),
        )
    };
    let value: i64 = position.parse().map_err(|_| bad("not an integer"))?;
    let index = if value > 0 {
        value - 1
    } else if value < 0 {
        // Relative: -1 is the last vertex read so far.
        let read = i64::try_from(read).map_err(|_| bad("too many vertices"))?;
        let index = read + value;
        if index < 0 {
            return Err(bad(&format!(
                "the relative reference goes before the first vertex ({read} read so far)"
            )));
        }
        index
    } else {
        return Err(bad("OBJ vertex numbers start at 1"));
    };
    u32::try_from(index).map_err(|_| bad("larger than a u32 vertex index"))
}

/// Write a frame as Wavefront OBJ: a `# hooke` header line, then `v x y z` for every vertex (2D frames
/// get z = 0), `f a b c` for every triangle and `l a b` for every line, with 1-based indices.
/// Tetrahedra are not written (OBJ has no volume cells). Coordinates are written with the shortest
/// digits that read back to the same `f64`, so [`parse_obj`] returns the positions bit for bit.
/// Output goes out one line per write: pass a buffered writer (as [`super::save_obj`] does).
///
/// # Errors
/// An error of kind [`std::io::ErrorKind::InvalidInput`] before anything is written if an index is out
/// of range or a coordinate is not finite; otherwise the errors of `out`.
pub fn write_obj<const D: usize>(frame: &Frame<D>, out: &mut impl Write) -> std::io::Result<()> {
    frame.check()?;
    writeln!(out, "# hooke")?;
    for p in frame.positions {
        let [x, y, z] = xyz(p);
        writeln!(out, "v {} {} {}", RoundTrip(x), RoundTrip(y), RoundTrip(z))?;
    }
    for &[a, b, c] in frame.triangles {
        writeln!(
            out,
            "f {} {} {}",
            u64::from(a) + 1,
            u64::from(b) + 1,
            u64::from(c) + 1
        )?;
    }
    for &[a, b] in frame.lines {
        writeln!(out, "l {} {}", u64::from(a) + 1, u64::from(b) + 1)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ElementKind, MeshError};

    fn parse(text: &str) -> Result<TriMesh, MeshError> {
        parse_obj(text.as_bytes(), Path::new("test.obj"))
    }

    #[test]
    fn quads_polygons_and_references() {
        let m = parse(
            "# a comment\no square\nv 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\n\
             vt 0 0\nvn 0 0 1\ng g\nf 1/1/1 2/1/1 3//1 4\nf -4 -2 -1 # relative\n",
        )
        .unwrap();
        assert_eq!(m.positions().len(), 4);
        assert_eq!(m.triangles(), &[[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
    }

    #[test]
    fn crlf_and_missing_final_newline() {
        let m = parse("v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3").unwrap();
        assert_eq!(m.triangles(), &[[0, 1, 2]]);
    }

    #[test]
    fn errors_name_file_and_line() {
        let cases = [
            ("v 0 0 0\nv 1 0\n", 2),
            ("v 0 0 0\nv 1 0 x\n", 2),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", 4),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", 4),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n", 4),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999\n", 4),
        ];
        for (text, expected) in cases {
            match parse(text) {
                Err(e @ MeshError::Parse { line: Some(l), .. }) => {
                    assert_eq!(l, expected, "{text:?}: {e}");
                    assert!(e.to_string().starts_with(&format!("test.obj:{expected}: ")));
                }
                other => panic!("{text:?}: {other:?}"),
            }
        }
    }

    #[test]
    fn validation_errors_are_in_file() {
        let e = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err();
        match e {
            MeshError::InFile { path, source } => {
                assert_eq!(path, Path::new("test.obj"));
                assert!(matches!(
                    *source,
                    MeshError::IndexOutOfRange {
                        kind: ElementKind::Triangle,
                        index: 3,
                        ..
                    }
                ));
            }
            other => panic!("{other:?}"),
        }
        assert!(
            matches!(parse(""), Err(MeshError::InFile { source, .. }) if matches!(*source, MeshError::Empty))
        );
    }
}
