//! TetGen `.node`/`.ele` pairs.
//!
//! `.node`: a header `<points> <dimension = 3> [<attributes> [<boundary markers 0|1>]]`, then one line
//! `<index> <x> <y> <z> [attributes…] [marker]` per point. `.ele`: a header
//! `<tetrahedra> <nodes per tetrahedron = 4|10> [<region attribute 0|1>]`, then one line
//! `<index> <n1> … <nk> [attribute]` per tetrahedron. `#` starts a comment anywhere on a line; blank
//! lines are skipped; tokens are separated by any white space. As in TetGen, the first point's index
//! (0 or 1) sets the numbering base of the pair; the points must then be numbered consecutively.
//! For 10-node (quadratic) tetrahedra the four corners, which come first, are kept. Attributes, markers
//! and anything after the declared entries is ignored.

use std::path::{Path, PathBuf};

use super::{parse_error, quote, read_file};
use crate::{MeshError, TetMesh, Vec3};

/// Read a TetGen mesh given either of its files: `path` may end in `.node` or `.ele` (or name the
/// common stem); both `<stem>.node` and `<stem>.ele` are read (see [`parse_tetgen`]). If `path`'s
/// extension is upper case, the partner's is too.
///
/// # Errors
/// [`MeshError::Io`] naming the file that cannot be read; otherwise as [`parse_tetgen`].
pub fn read_tetgen(path: &Path) -> Result<TetMesh, MeshError> {
    let (node_path, ele_path) = pair(path);
    let node = read_file(&node_path)?;
    let ele = read_file(&ele_path)?;
    parse_pair(
        &String::from_utf8_lossy(&node),
        &String::from_utf8_lossy(&ele),
        &node_path,
        &ele_path,
    )
}

/// Parse the texts of a TetGen `.node` and `.ele` pair. `name` is the mesh's path or stem: errors name
/// `name` with extension `.node` or `.ele`, whichever file is at fault. The mesh has every point of the
/// `.node` file, in order (point with index `base + k` is vertex `k`), and the tetrahedra of the `.ele`
/// file, in order.
///
/// # Errors
/// - [`MeshError::Parse`] naming the file and the 1-based line, saying what was expected: a missing or
///   malformed header, a dimension other than 3, 4 or 10 nodes per tetrahedron expected, a first
///   point index other than 0 or 1, a point index out of sequence, a missing or non-numeric value, a
///   node reference below the numbering base, or fewer entries than the header declares (the file is
///   truncated; the line is then the last one).
/// - [`MeshError::InFile`] wrapping the validation error of [`TetMesh::new`]: no points or no
///   tetrahedra, a non-finite coordinate (naming the `.node` file), or a node reference past the last
///   point ([`MeshError::IndexOutOfRange`]), a repeated node or a degenerate tetrahedron (naming the
///   `.ele` file). Vertex and element numbers in these errors are 0-based positions, whatever the
///   file's base.
pub fn parse_tetgen(node_text: &str, ele_text: &str, name: &Path) -> Result<TetMesh, MeshError> {
    let (node_path, ele_path) = pair(name);
    parse_pair(node_text, ele_text, &node_path, &ele_path)
}

/// The `.node` and `.ele` paths of a pair, given either one or the stem.
fn pair(path: &Path) -> (PathBuf, PathBuf) {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let upper = !extension.is_empty() && extension.chars().all(|c| c.is_ascii_uppercase());
    let is_pair_extension =
        extension.eq_ignore_ascii_case("node") || extension.eq_ignore_ascii_case("ele");
    let stem = if is_pair_extension {
        path.with_extension("")
    } else {
        path.to_path_buf()
    };
    let with = |e: &str| {
        let mut p = stem.clone().into_os_string();
        p.push(".");
        p.push(if upper {
            e.to_ascii_uppercase()
        } else {
            e.to_string()
        });
        PathBuf::from(p)
    };
    (with("node"), with("ele"))
}

fn parse_pair(
    node_text: &str,
    ele_text: &str,
    node_path: &Path,
    ele_path: &Path,
) -> Result<TetMesh, MeshError> {
    let (positions, base) = parse_nodes(node_text, node_path)?;
    let tetrahedra = parse_elements(ele_text, base, ele_path)?;
    TetMesh::new(positions, tetrahedra).map_err(|e| match e {
        MeshError::Empty
        | MeshError::NonFiniteCoordinate { .. }
        | MeshError::TooManyVertices { .. } => e.in_file(node_path),
        e => e.in_file(ele_path),
    })
}

/// The data lines of a file: (1-based line, tokens), comments and blank lines removed.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.lines().enumerate().filter_map(|(i, line)| {
        let data = line.split('#').next().unwrap_or("");
        let tokens: Vec<&str> = data.split_whitespace().collect();
        (!tokens.is_empty()).then_some((i + 1, tokens))
    })
}

/// The next data line of a file whose header declares `count` records of `what`, `k` read so far;
/// a [`MeshError::Parse`] at `end_line` if the file ends first.
fn next_record<'a>(
    lines: &mut impl Iterator<Item = (usize, Vec<&'a str>)>,
    path: &Path,
    end_line: usize,
    count: u64,
    k: u64,
    what: &str,
) -> Result<(usize, Vec<&'a str>), MeshError> {
    lines.next().ok_or_else(|| {
        parse_error(
            path,
            Some(end_line),
            format!(
                "unexpected end of file: the header declares {count} {what}, found {k} (truncated?)"
            ),
        )
    })
}

/// The header's `index`-th value, if present, as an integer; `default` if absent.
fn header_value(
    tokens: &[&str],
    index: usize,
    default: Option<u64>,
    what: &str,
    path: &Path,
    line: usize,
) -> Result<u64, MeshError> {
    match (tokens.get(index), default) {
        (Some(token), _) => token.parse().map_err(|_| {
            parse_error(
                path,
                Some(line),
                format!(
                    "expected the {what} in the header, a non-negative integer; found {}",
                    quote(token)
                ),
            )
        }),
        (None, Some(default)) => Ok(default),
        (None, None) => Err(parse_error(
            path,
            Some(line),
            format!("expected the {what} in the header"),
        )),
    }
}

/// A count from a header, as `usize` (capacity is reserved for at most a modest number, since the file
/// may lie).
fn reserve<T>(count: u64) -> Vec<T> {
    Vec::with_capacity(usize::try_from(count).unwrap_or(0).min(1 << 16))
}

fn parse_nodes(text: &str, path: &Path) -> Result<(Vec<Vec3>, u64), MeshError> {
    let total_lines = text.lines().count().max(1);
    let mut lines = data_lines(text);
    let Some((line, header)) = lines.next() else {
        return Err(parse_error(
            path,
            Some(total_lines),
            "expected the header `<points> <dimension> [<attributes> [<markers>]]`; the file has no data",
        ));
    };
    let count = header_value(&header, 0, None, "number of points", path, line)?;
    let dimension = header_value(&header, 1, Some(3), "dimension", path, line)?;
    if dimension != 3 {
        return Err(parse_error(
            path,
            Some(line),
            format!("expected dimension 3 in the header (a tetrahedral mesh), found {dimension}"),
        ));
    }
    header_value(&header, 2, Some(0), "number of attributes", path, line)?;
    header_value(&header, 3, Some(0), "boundary marker flag", path, line)?;
    let mut positions = reserve(count);
    let mut base = 0;
    let mut last_line = line;
    for k in 0..count {
        let (line, tokens) = next_record(
            &mut lines,
            path,
            total_lines.max(last_line),
            count,
            k,
            "points",
        )?;
        last_line = line;
        let index: u64 = tokens[0].parse().map_err(|_| {
            parse_error(
                path,
                Some(line),
                format!(
                    "expected a point index (an integer), found {}",
                    quote(tokens[0])
                ),
            )
        })?;
        if k == 0 {
            if index > 1 {
                return Err(parse_error(
                    path,
                    Some(line),
                    format!("expected the first point's index to be 0 or 1, found {index}"),
                ));
            }
            base = index;
        } else if Some(index) != base.checked_add(k) {
            return Err(parse_error(
                path,
                Some(line),
                format!(
                    "expected point index {} (points are numbered consecutively from {base}), found {index}",
                    base + k
                ),
            ));
        }
        let mut p = [0.0; 3];
        for (axis, value) in p.iter_mut().enumerate() {
            let token = tokens.get(axis + 1).ok_or_else(|| {
                parse_error(
                    path,
                    Some(line),
                    format!(
                        "expected a point line `<index> <x> <y> <z>`, found {} value(s)",
                        tokens.len()
                    ),
                )
            })?;
            *value = token.parse().map_err(|_| {
                parse_error(
                    path,
                    Some(line),
                    format!(
                        "expected coordinate {} of point {index} to be a number, found {}",
                        ["x", "y", "z"][axis],
                        quote(token)
                    ),
                )
            })?;
        }
        positions.push(Vec3::from(p));
    }
    Ok((positions, base))
}

fn parse_elements(text: &str, base: u64, path: &Path) -> Result<Vec<[u32; 4]>, MeshError> {
    let total_lines = text.lines().count().max(1);
    let mut lines = data_lines(text);
    let Some((line, header)) = lines.next() else {
        return Err(parse_error(
            path,
            Some(total_lines),
            "expected the header `<tetrahedra> <nodes per tetrahedron> [<region attribute>]`; the file \
             has no data",
        ));
    };
    let count = header_value(&header, 0, None, "number of tetrahedra", path, line)?;
    let corners = header_value(
        &header,
        1,
        Some(4),
        "number of nodes per tetrahedron",
        path,
        line,
    )?;
    if corners != 4 && corners != 10 {
        return Err(parse_error(
            path,
            Some(line),
            format!("expected 4 or 10 nodes per tetrahedron in the header, found {corners}"),
        ));
    }
    header_value(&header, 2, Some(0), "region attribute flag", path, line)?;
    let mut tetrahedra = reserve(count);
    let mut last_line = line;
    for k in 0..count {
        let (line, tokens) = next_record(
            &mut lines,
            path,
            total_lines.max(last_line),
            count,
            k,
            "tetrahedra",
        )?;
        last_line = line;
        // `corners` is 4 or 10, so this cannot truncate.
        let needed = 1 + corners as usize;
        if tokens.len() < needed {
            return Err(parse_error(
                path,
                Some(line),
                format!(
                    "expected a tetrahedron line `<index>` and {corners} node numbers, found {} value(s)",
                    tokens.len()
                ),
            ));
        }
        let mut tet = [0u32; 4];
        for (slot, token) in tet.iter_mut().zip(&tokens[1..5]) {
            let number: u64 = token.parse().map_err(|_| {
                parse_error(
                    path,
                    Some(line),
                    format!(
                        "expected a node number (a non-negative integer), found {}",
                        quote(token)
                    ),
                )
            })?;
            let index = number.checked_sub(base).ok_or_else(|| {
                parse_error(
                    path,
                    Some(line),
                    format!("node number {number} is below the first point's index {base}"),
                )
            })?;
            *slot = u32::try_from(index).map_err(|_| {
                parse_error(
                    path,
                    Some(line),
                    format!("node number {number} is larger than a u32 vertex index"),
                )
            })?;
        }
        tetrahedra.push(tet);
    }
    Ok(tetrahedra)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ElementKind;

    const NODE: &str =
        "# comment\n4 3 1 1\n\n1 0 0 0 7.5 1\n2 1 0 0 7.5 1 # x\n3 0 1 0 7.5 0\n4 0 0 1 7.5 0\n";
    const ELE: &str = "1 4 1\n1 1 2 3 4 -1\n";

    #[test]
    fn one_based_with_attributes_and_markers() {
        let m = parse_tetgen(NODE, ELE, Path::new("dir/t")).unwrap();
        assert_eq!(m.positions().len(), 4);
        assert_eq!(m.tetrahedra(), &[[0, 1, 2, 3]]);
    }

    #[test]
    fn ten_node_tetrahedra_keep_the_corners() {
        let node = "5 3\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 0.5 0 0\n";
        let m = parse_tetgen(node, "1 10\n0 0 1 2 3 4 4 4 4 4 4\n", Path::new("t.ele")).unwrap();
        assert_eq!(m.tetrahedra(), &[[0, 1, 2, 3]]);
    }

    #[test]
    fn pair_paths() {
        assert_eq!(
            pair(Path::new("a/b.c.node")),
            (PathBuf::from("a/b.c.node"), PathBuf::from("a/b.c.ele"))
        );
        assert_eq!(
            pair(Path::new("B.ELE")),
            (PathBuf::from("B.NODE"), PathBuf::from("B.ELE"))
        );
        assert_eq!(
            pair(Path::new("stem")),
            (PathBuf::from("stem.node"), PathBuf::from("stem.ele"))
        );
    }

    #[test]
    fn errors_name_the_right_file_and_line() {
        let cases: [(&str, &str, &str); 6] = [
            ("4 2 0 0\n", ELE, "t.node:1:"),
            ("4 3 1 1\n1 0 0 0\n3 1 0 0\n", ELE, "t.node:3:"),
            ("4 3 1 1\n1 0 0 0\n2 1 0\n", ELE, "t.node:3:"),
            (
                "4 3 1 1\n1 0 0 0\n2 1 0 0\n",
                ELE,
                "t.node:3: unexpected end of file",
            ),
            (NODE, "1 4 1\n1 1 2 3\n", "t.ele:2:"),
            (
                NODE,
                "1 4 1\n1 0 1 2 3\n",
                "t.ele:2: node number 0 is below",
            ),
        ];
        for (node, ele, prefix) in cases {
            let e = parse_tetgen(node, ele, Path::new("t.node")).unwrap_err();
            assert!(matches!(e, MeshError::Parse { .. }), "{e:?}");
            assert!(e.to_string().starts_with(prefix), "{prefix}: {e}");
        }
        let e = parse_tetgen(NODE, "1 4 1\n1 1 2 3 5\n", Path::new("t.node")).unwrap_err();
        match e {
            MeshError::InFile { path, source } => {
                assert_eq!(path, Path::new("t.ele"));
                assert!(matches!(
                    *source,
                    MeshError::IndexOutOfRange {
                        kind: ElementKind::Tetrahedron,
                        index: 4,
                        ..
                    }
                ));
            }
            other => panic!("{other:?}"),
        }
    }
}
