//! STL (ASCII and binary) triangle surfaces, read with `stl_io`.
//!
//! STL stores every triangle with its own three corners; `stl_io` merges corners with identical
//! coordinates into shared vertices. hooke merges once more so that `-0.0` and `0.0` (which `stl_io`
//! keeps apart, comparing bit patterns) become one vertex: exporters write both, and a split vertex
//! would cut the surface. STL coordinates are `f32` (ASCII ones are parsed as `f32` too); they are
//! widened exactly to `f64`.
//!
//! A binary file whose 80-byte header happens to start with `solid ` (some exporters write that) is
//! recognised by its size (84 + 50 × triangles bytes) when it does not parse as ASCII.
//!
//! `stl_io` does not report line numbers, so errors in ASCII files name the file and what was wrong
//! (the offending tokens) but not the line.

use std::collections::HashMap;
use std::io::Cursor;
use std::path::Path;

use super::{parse_error, read_file};
use crate::{MeshError, TriMesh, Vec3};

/// Read an STL file (ASCII or binary) as a triangle mesh (see [`parse_stl`]).
///
/// # Errors
/// [`MeshError::Io`] if the file cannot be read; otherwise as [`parse_stl`].
pub fn read_stl(path: &Path) -> Result<TriMesh, MeshError> {
    parse_stl(&read_file(path)?, path)
}

/// Parse the bytes of an STL file, ASCII (starting with `solid `) or binary; `name` is the file named in
/// errors. Corners with equal coordinates become one vertex, numbered in order of first appearance;
/// triangles keep the file's order and winding. Normals are ignored.
///
/// # Errors
/// - [`MeshError::Parse`] (without a line number): an empty file, a file too short for a binary header,
///   a binary file shorter than its declared triangle count needs, an ASCII syntax error, or a
///   non-finite coordinate in an ASCII file (which `stl_io` rejects while parsing).
/// - [`MeshError::InFile`] wrapping the validation error of [`TriMesh::new`]: no triangles, a
///   non-finite coordinate in a binary file, a triangle with two equal corners
///   ([`MeshError::RepeatedVertex`]) or a degenerate triangle.
pub fn parse_stl(bytes: &[u8], name: &Path) -> Result<TriMesh, MeshError> {
    if bytes.is_empty() {
        return Err(parse_error(
            name,
            None,
            "the file is empty: expected an ASCII or binary STL",
        ));
    }
    // stl_io recognises ASCII by "solid " with a space; accept a bare "solid" line too.
    let original = bytes;
    let spaced;
    let bytes = if bytes.starts_with(b"solid\n") || bytes.starts_with(b"solid\r\n") {
        spaced = [&b"solid "[..], &bytes[5..]].concat();
        &spaced[..]
    } else {
        bytes
    };
    let ascii = bytes.starts_with(b"solid ");
    let indexed = match stl_io::read_stl(&mut Cursor::new(bytes)) {
        Ok(mesh) => mesh,
        Err(error) if ascii && binary_size_matches(original) => {
            // A binary file with a header starting "solid": blank the header's first bytes so that
            // stl_io takes the binary path (the header carries no data).
            let mut copy = original.to_vec();
            copy[..6].fill(b' ');
            stl_io::read_stl(&mut Cursor::new(copy))
                .map_err(|_| parse_error(name, None, format!("invalid ASCII STL: {error}")))?
        }
        Err(error) if ascii => {
            return Err(parse_error(
                name,
                None,
                format!("invalid ASCII STL: {error}"),
            ))
        }
        Err(error) => return Err(parse_error(name, None, binary_message(bytes, &error))),
    };
    // Merge again, treating -0.0 and 0.0 as equal (adding 0.0 turns -0.0 into 0.0).
    let mut merged: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions: Vec<Vec3> = Vec::new();
    let mut renumber: Vec<u32> = Vec::with_capacity(indexed.vertices.len());
    for v in &indexed.vertices {
        let key = v.0.map(|c| (c + 0.0).to_bits());
        let next = positions.len();
        let index = *merged.entry(key).or_insert_with(|| {
            positions.push(Vec3::new(
                f64::from(v.0[0]),
                f64::from(v.0[1]),
                f64::from(v.0[2]),
            ));
            u32::try_from(next).unwrap_or(u32::MAX)
        });
        renumber.push(index);
    }
    if positions.len() > u32::MAX as usize {
        return Err(MeshError::TooManyVertices {
            count: positions.len(),
        }
        .in_file(name));
    }
    let mut triangles = Vec::with_capacity(indexed.faces.len());
    for face in &indexed.faces {
        let mut t = [0u32; 3];
        for (corner, &v) in t.iter_mut().zip(&face.vertices) {
            // stl_io's indices are into its own vertex list; guard anyway.
            *corner = *renumber.get(v).ok_or_else(|| {
                parse_error(
                    name,
                    None,
                    format!("vertex index {v} out of range in stl_io's mesh"),
                )
            })?;
        }
        triangles.push(t);
    }
    TriMesh::new(positions, triangles).map_err(|e| e.in_file(name))
}

/// Declared triangle count of a binary STL, if the file is long enough to hold the header.
fn declared_triangles(bytes: &[u8]) -> Option<u64> {
    let count: [u8; 4] = bytes.get(80..84)?.try_into().ok()?;
    Some(u64::from(u32::from_le_bytes(count)))
}

/// Whether the file has exactly the size of a binary STL with its declared triangle count.
fn binary_size_matches(bytes: &[u8]) -> bool {
    declared_triangles(bytes).is_some_and(|n| 84 + 50 * n == bytes.len() as u64)
}

fn binary_message(bytes: &[u8], error: &std::io::Error) -> String {
    match declared_triangles(bytes) {
        None => format!(
            "not an STL file: it does not start with `solid ` (ASCII) and its {} bytes are too few \
             for a binary STL's 84-byte header",
            bytes.len()
        ),
        Some(n) if 84 + 50 * n > bytes.len() as u64 => format!(
            "truncated binary STL: the header declares {n} triangles, which need {} bytes, but the \
             file has {}",
            84 + 50 * n,
            bytes.len()
        ),
        Some(_) => format!("invalid binary STL: {error}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n\
                         vertex 0 1 0\nendloop\nendfacet\nfacet normal 0 0 1\nouter loop\n\
                         vertex 1 0 0\nvertex 1 1 0\nvertex -0 1 0\nendloop\nendfacet\nendsolid t\n";

    #[test]
    fn ascii_merges_signed_zeros() {
        let m = parse_stl(ASCII.as_bytes(), Path::new("t.stl")).unwrap();
        assert_eq!(m.positions().len(), 4);
        assert_eq!(m.triangles(), &[[0, 1, 2], [1, 3, 2]]);
    }

    #[test]
    fn binary_with_solid_header() {
        let m = parse_stl(ASCII.as_bytes(), Path::new("t.stl")).unwrap();
        let triangles: Vec<stl_io::Triangle> = m
            .triangles()
            .iter()
            .map(|t| stl_io::Triangle {
                normal: stl_io::Normal::new([0.0, 0.0, 1.0]),
                vertices: t.map(|v| {
                    let p = m.positions()[v as usize];
                    stl_io::Vertex::new([p.x as f32, p.y as f32, p.z as f32])
                }),
            })
            .collect();
        let mut bytes = Vec::new();
        stl_io::write_stl(&mut bytes, triangles.iter()).unwrap();
        bytes[..9].copy_from_slice(b"solid bin");
        let back = parse_stl(&bytes, Path::new("t.stl")).unwrap();
        assert_eq!(back, m);
        let e = parse_stl(&bytes[..bytes.len() - 1], Path::new("t.stl")).unwrap_err();
        assert!(e.to_string().contains("invalid ASCII STL"), "{e}");
        bytes[..9].copy_from_slice(b"binary   ");
        let e = parse_stl(&bytes[..bytes.len() - 1], Path::new("t.stl")).unwrap_err();
        assert!(
            e.to_string().starts_with("t.stl: truncated binary STL"),
            "{e}"
        );
    }
}
