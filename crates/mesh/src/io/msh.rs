//! Gmsh MSH tetrahedral meshes: version 4.1 (ASCII and binary) through `mshio`, and version 2
//! (ASCII only) through a small parser of the `$Nodes` and `$Elements` sections.
//!
//! Only linear tetrahedra (element type 4) are kept, from every entity block; points, lines, triangles
//! and all other element types are ignored. Nodes are identified by their tags, which may be sparse and
//! in any order; the mesh keeps the nodes that some tetrahedron uses, in the file's order, numbered from
//! 0 (nodes used only by ignored elements, such as a geometry point, are dropped).
//!
//! `mshio` panics on a few malformed inputs (a zero node or element count in a section header, an
//! unsupported or overflowing `data-size` in the header). Those cases are detected and rejected before
//! `mshio` sees the bytes; as a last line of defence any other panic inside `mshio` is caught and turned
//! into a [`MeshError::Parse`]. When the node tags of a 4.1 file are contiguous, `mshio` does not keep
//! them and the nodes are taken to be numbered in file order from the section's minimum tag, which is
//! what Gmsh writes.

use std::collections::HashMap;
use std::path::Path;

use mshio::{ElementType, MshFile};

use super::{parse_error, quote, read_file};
use crate::{MeshError, TetMesh, Vec3};

/// Read a Gmsh MSH file (4.1 ASCII or binary, or 2.x ASCII) as a tetrahedral mesh (see [`parse_msh`]).
///
/// # Errors
/// [`MeshError::Io`] if the file cannot be read; otherwise as [`parse_msh`].
pub fn read_msh(path: &Path) -> Result<TetMesh, MeshError> {
    parse_msh(&read_file(path)?, path)
}

/// Parse the bytes of a Gmsh MSH file as a tetrahedral mesh; `name` is the file named in errors.
///
/// Versions 4.1 (ASCII and binary) and 2.x (ASCII) are read; other versions (including binary 2.x and
/// 4.0) are rejected with a message asking to re-save the file as 4.1. See the module documentation for
/// what is kept.
///
/// # Errors
/// - [`MeshError::Parse`]: not an MSH file, an unsupported version, a syntax error (with the 1-based
///   line for ASCII files, the byte offset for binary ones), a repeated node tag, or a tetrahedron that
///   refers to a node tag missing from `$Nodes`.
/// - [`MeshError::InFile`] wrapping the validation error of [`TetMesh::new`]: no nodes
///   ([`MeshError::Empty`]), no tetrahedra ([`MeshError::NoElements`]), a non-finite coordinate, a
///   tetrahedron that repeats a node, or a degenerate tetrahedron.
pub fn parse_msh(bytes: &[u8], name: &Path) -> Result<TetMesh, MeshError> {
    let header = Header::read(bytes, name)?;
    let (nodes, tetrahedra) = if header.version == 4.1 {
        read_v41(bytes, &header, name)?
    } else if (2.0..3.0).contains(&header.version) {
        if header.binary {
            return Err(parse_error(
                name,
                Some(header.line),
                format!(
                    "binary MSH version {} is not supported; re-save as 4.1 (e.g. `gmsh -save \
                     -format msh41`) or as ASCII",
                    header.version_text
                ),
            ));
        }
        read_v2(bytes, name)?
    } else {
        return Err(parse_error(
            name,
            Some(header.line),
            format!(
                "MSH version {} is not supported (4.1, and 2.x in ASCII, are); re-save as 4.1 (e.g. \
                 `gmsh -save -format msh41`)",
                quote(&header.version_text)
            ),
        ));
    };
    build(nodes, tetrahedra, name)
}

/// A tetrahedron as read: its four node tags, and where it is (for errors).
struct RawTet {
    tags: [u64; 4],
    element_tag: u64,
    line: Option<usize>,
}

/// The `$MeshFormat` header: `version file-type data-size`.
struct Header {
    /// Where `$MeshFormat` starts (leading blank space is allowed).
    start: usize,
    /// The 1-based line of `version file-type data-size`.
    line: usize,
    version: f64,
    version_text: String,
    binary: bool,
    /// sizeof(size_t) in binary files: 4 or 8.
    data_size: usize,
    /// Little-endian binary data (detected from the integer 1 that follows the header line).
    little_endian: bool,
}

impl Header {
    fn read(bytes: &[u8], name: &Path) -> Result<Header, MeshError> {
        let start = bytes
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(bytes.len());
        let line_of = |offset: usize| 1 + bytes[..offset].iter().filter(|&&b| b == b'\n').count();
        let first_line = line_of(start);
        if start == bytes.len() {
            return Err(parse_error(
                name,
                Some(first_line),
                "the file is empty: expected a Gmsh MSH file starting with `$MeshFormat`",
            ));
        }
        let rest = &bytes[start..];
        let mut lines = rest.split(|&b| b == b'\n');
        let format_line = lines.next().unwrap_or_default();
        if format_line.trim_ascii() != b"$MeshFormat" {
            return Err(parse_error(
                name,
                Some(first_line),
                "expected `$MeshFormat`: not a Gmsh MSH file",
            ));
        }
        let header_line = lines.next().unwrap_or_default();
        let line = first_line + 1;
        let text = String::from_utf8_lossy(header_line);
        let tokens: Vec<&str> = text.split_whitespace().collect();
        let expected = "expected the MSH header `version file-type data-size`, e.g. `4.1 0 8`";
        let [version_text, file_type, data_size] = tokens[..] else {
            return Err(parse_error(
                name,
                Some(line),
                format!("{expected}; found {}", quote(&text)),
            ));
        };
        let version: f64 = version_text.parse().map_err(|_| {
            parse_error(
                name,
                Some(line),
                format!(
                    "{expected}; the version {} is not a number",
                    quote(version_text)
                ),
            )
        })?;
        let binary = match file_type {
            "0" => false,
            "1" => true,
            _ => {
                return Err(parse_error(
                    name,
                    Some(line),
                    format!(
                        "{expected}; the file type must be 0 (ASCII) or 1 (binary), found {}",
                        quote(file_type)
                    ),
                ))
            }
        };
        let data_size = match data_size.parse::<u32>() {
            Ok(4) => 4,
            Ok(8) => 8,
            _ => {
                return Err(parse_error(
                    name,
                    Some(line),
                    format!(
                        "{expected}; the data size (sizeof(size_t)) must be 4 or 8, found {}",
                        quote(data_size)
                    ),
                ))
            }
        };
        // In binary files the header line is followed by the integer 1 in the file's byte order.
        let after = start + format_line.len() + 1 + header_line.len() + 1;
        let one: Option<[u8; 4]> = bytes.get(after..after + 4).and_then(|s| s.try_into().ok());
        let little_endian = one.is_none_or(|b| i32::from_le_bytes(b) == 1);
        Ok(Header {
            start,
            line,
            version,
            version_text: version_text.to_string(),
            binary,
            data_size,
            little_endian,
        })
    }
}

/// Nodes as (tag, position) in file order, and tetrahedra.
type Raw = (Vec<(u64, Vec3)>, Vec<RawTet>);

fn read_v41(bytes: &[u8], header: &Header, name: &Path) -> Result<Raw, MeshError> {
    let input = &bytes[header.start..];
    check_section_counts(input, header, name)?;
    let parsed = std::panic::catch_unwind(|| match mshio::parse_msh_bytes(input) {
        Ok(file) => Ok(file),
        Err(error) => Err(describe(&error, input)),
    });
    let file: MshFile<u64, i32, f64> = match parsed {
        Ok(Ok(file)) => file,
        Ok(Err((message, offset))) => {
            let (line, at) = match offset {
                Some(offset) if !header.binary => (
                    Some(
                        1 + bytes[..header.start + offset]
                            .iter()
                            .filter(|&&b| b == b'\n')
                            .count(),
                    ),
                    String::new(),
                ),
                Some(offset) => (None, format!(" at byte {}", header.start + offset)),
                None => (None, String::new()),
            };
            return Err(parse_error(
                name,
                line,
                format!("invalid MSH 4.1 file{at}: {message}"),
            ));
        }
        Err(_) => {
            return Err(parse_error(
                name,
                None,
                "invalid MSH 4.1 file: the MSH parser (mshio) failed on malformed input",
            ))
        }
    };
    let Some(node_section) = file.data.nodes else {
        return Err(MeshError::Empty.in_file(name));
    };
    let mut nodes = Vec::new();
    let mut next_tag = Some(node_section.min_node_tag);
    for block in &node_section.node_blocks {
        let tags: Vec<u64> = match &block.node_tags {
            Some(map) => {
                let mut tags = vec![None; block.nodes.len()];
                for (&tag, &index) in map {
                    if let Some(slot) = tags.get_mut(index) {
                        *slot = Some(tag);
                    }
                }
                tags.into_iter()
                    .collect::<Option<Vec<u64>>>()
                    .ok_or_else(|| {
                        parse_error(
                            name,
                            None,
                            format!(
                            "a $Nodes entity block (entity {} of dimension {}) repeats a node tag",
                            block.entity_tag, block.entity_dim
                        ),
                        )
                    })?
            }
            None => (0..block.nodes.len())
                .map(|_| {
                    let tag = next_tag.ok_or_else(|| {
                        parse_error(name, None, "node tags overflow a 64-bit integer")
                    })?;
                    next_tag = tag.checked_add(1);
                    Ok(tag)
                })
                .collect::<Result<_, MeshError>>()?,
        };
        for (tag, node) in tags.into_iter().zip(&block.nodes) {
            nodes.push((tag, Vec3::new(node.x, node.y, node.z)));
        }
    }
    let mut tetrahedra = Vec::new();
    if let Some(elements) = file.data.elements {
        for block in elements
            .element_blocks
            .iter()
            .filter(|b| b.element_type == ElementType::Tet4)
        {
            for element in &block.elements {
                let tags: [u64; 4] = element.nodes.as_slice().try_into().map_err(|_| {
                    parse_error(
                        name,
                        None,
                        format!(
                            "tetrahedron {} has {} nodes, expected 4",
                            element.element_tag,
                            element.nodes.len()
                        ),
                    )
                })?;
                tetrahedra.push(RawTet {
                    tags,
                    element_tag: element.element_tag,
                    line: None,
                });
            }
        }
    }
    Ok((nodes, tetrahedra))
}

/// `mshio`'s error as a message and the byte offset (into `input`) where it happened.
fn describe(error: &mshio::MshParserError<&[u8]>, input: &[u8]) -> (String, Option<usize>) {
    let errors: Vec<_> = error.filter_msh_errors().collect();
    let (at, mut message) = match (errors.first(), error.backtrace.first()) {
        (Some((at, kind)), _) => match kind.context() {
            Some(context) => (*at, format!("could not read the {context}")),
            None => (*at, kind.to_string()),
        },
        (None, Some((at, kind))) => (*at, format!("syntax error ({kind})")),
        (None, None) => return ("unknown error".to_string(), None),
    };
    let contexts: Vec<&str> = errors
        .iter()
        .skip(1)
        .filter_map(|(_, k)| k.context())
        .collect();
    if !contexts.is_empty() {
        message.push_str(" (in ");
        message.push_str(&contexts.join(", in "));
        message.push(')');
    }
    let offset = (at.as_ptr() as usize)
        .checked_sub(input.as_ptr() as usize)
        .filter(|&o| o <= input.len());
    (message, offset)
}

/// Reject the section headers on which `mshio` would panic: a `$Nodes` or `$Elements` section that
/// declares zero entries (mshio computes `count - 1` unchecked). Every occurrence of the section tag
/// is checked, which covers the ones mshio parses; an empty section means an empty mesh anyway.
fn check_section_counts(input: &[u8], header: &Header, name: &Path) -> Result<(), MeshError> {
    for (tag, empty) in [
        (&b"$Nodes"[..], MeshError::Empty),
        (
            &b"$Elements"[..],
            MeshError::NoElements {
                kind: crate::ElementKind::Tetrahedron,
            },
        ),
    ] {
        let mut from = 0;
        while let Some(found) = find(&input[from..], tag) {
            let after_tag = from + found + tag.len();
            from = after_tag;
            let rest = &input[after_tag..];
            let body = if let Some(r) = rest.strip_prefix(b"\r\n") {
                r
            } else if let Some(r) = rest.strip_prefix(b"\n") {
                r
            } else {
                continue;
            };
            // The header is `numEntityBlocks numEntries minTag maxTag`.
            let count = if header.binary {
                body.get(header.data_size..2 * header.data_size).map(|b| {
                    let mut word = [0u8; 8];
                    if header.little_endian {
                        word[..b.len()].copy_from_slice(b);
                        u64::from_le_bytes(word)
                    } else {
                        word[8 - b.len()..].copy_from_slice(b);
                        u64::from_be_bytes(word)
                    }
                })
            } else {
                body.split(|b| b.is_ascii_whitespace())
                    .filter(|t| !t.is_empty())
                    .nth(1)
                    .and_then(|t| std::str::from_utf8(t).ok()?.parse::<u64>().ok())
            };
            if count == Some(0) {
                return Err(empty.in_file(name));
            }
        }
    }
    Ok(())
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// MSH 2.x ASCII: `$Nodes` (count, then `tag x y z` lines) and `$Elements` (count, then `tag type
/// ntags tags… nodes…` lines); other sections are skipped.
fn read_v2(bytes: &[u8], name: &Path) -> Result<Raw, MeshError> {
    let text = String::from_utf8_lossy(bytes);
    let mut lines = Lines {
        iter: text.lines().enumerate(),
        last: 0,
        name,
    };
    let mut nodes = Vec::new();
    let mut tetrahedra = Vec::new();
    // Skip the header: `$MeshFormat`, `version file-type data-size`, `$EndMeshFormat`.
    while lines.next("`$EndMeshFormat`")?.1 != "$EndMeshFormat" {}
    while let Some((line, section)) = lines.iter.next().map(|(i, l)| (i + 1, l.trim())) {
        lines.last = line;
        match section {
            "" => {}
            "$Nodes" => {
                for _ in 0..lines.count("nodes")? {
                    let (line, text) = lines.next("a node line `tag x y z`")?;
                    nodes.push(node_v2(text).ok_or_else(|| {
                        parse_error(
                            name,
                            Some(line),
                            format!("expected a node line `tag x y z`, found {}", quote(text)),
                        )
                    })?);
                }
                lines.expect("$EndNodes")?;
            }
            "$Elements" => {
                for _ in 0..lines.count("elements")? {
                    let (line, text) =
                        lines.next("an element line `tag type ntags tags… nodes…`")?;
                    if let Some(tet) = tet_v2(text, line, name)? {
                        tetrahedra.push(tet);
                    }
                }
                lines.expect("$EndElements")?;
            }
            other if other.starts_with('$') && !other.starts_with("$End") => {
                let end = format!("$End{}", &other[1..]);
                while lines.next(&format!("`{end}`"))?.1 != end {}
            }
            other => {
                return Err(parse_error(
                    name,
                    Some(line),
                    format!(
                        "expected a section such as `$Nodes` or `$Elements`, found {}",
                        quote(other)
                    ),
                ))
            }
        }
    }
    Ok((nodes, tetrahedra))
}

/// Numbered, trimmed lines of an ASCII file, with errors at the end of file.
struct Lines<'t, 'n, I: Iterator<Item = (usize, &'t str)>> {
    iter: I,
    /// The last line read (1-based), for end-of-file errors.
    last: usize,
    name: &'n Path,
}

impl<'t, I: Iterator<Item = (usize, &'t str)>> Lines<'t, '_, I> {
    fn next(&mut self, what: &str) -> Result<(usize, &'t str), MeshError> {
        match self.iter.next() {
            Some((index, text)) => {
                self.last = index + 1;
                Ok((index + 1, text.trim()))
            }
            None => Err(parse_error(
                self.name,
                Some(self.last),
                format!("unexpected end of file: expected {what}"),
            )),
        }
    }

    fn count(&mut self, what: &str) -> Result<usize, MeshError> {
        let (line, text) = self.next(&format!("the number of {what}"))?;
        text.parse().map_err(|_| {
            parse_error(
                self.name,
                Some(line),
                format!("expected the number of {what}, found {}", quote(text)),
            )
        })
    }

    fn expect(&mut self, end: &str) -> Result<(), MeshError> {
        let (line, text) = self.next(&format!("`{end}`"))?;
        if text == end {
            Ok(())
        } else {
            Err(parse_error(
                self.name,
                Some(line),
                format!("expected `{end}`, found {}", quote(text)),
            ))
        }
    }
}

/// A version 2 node line `tag x y z`.
fn node_v2(text: &str) -> Option<(u64, Vec3)> {
    let tokens: Vec<&str> = text.split_whitespace().collect();
    let [tag, x, y, z] = tokens[..] else {
        return None;
    };
    Some((
        tag.parse().ok()?,
        Vec3::new(x.parse().ok()?, y.parse().ok()?, z.parse().ok()?),
    ))
}

/// A version 2 element line `tag type ntags tags… nodes…`: the tetrahedron if the type is 4.
fn tet_v2(text: &str, line: usize, name: &Path) -> Result<Option<RawTet>, MeshError> {
    let bad = || {
        parse_error(
            name,
            Some(line),
            format!(
                "expected an element line `tag type ntags tags… nodes…` of integers, found {}",
                quote(text)
            ),
        )
    };
    let numbers: Vec<u64> = text
        .split_whitespace()
        .map(|t| t.parse::<u64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    let [element_tag, element_type, ntags, ..] = numbers[..] else {
        return Err(bad());
    };
    if element_type != 4 {
        return Ok(None);
    }
    let first = usize::try_from(ntags).ok().and_then(|n| n.checked_add(3));
    let tags: [u64; 4] = first
        .and_then(|f| numbers.get(f..)?.try_into().ok())
        .ok_or_else(|| {
            parse_error(
                name,
                Some(line),
                format!(
                    "expected a tetrahedron line `tag 4 ntags tags… n1 n2 n3 n4` with {ntags} tags \
                     and 4 nodes, found {}",
                    quote(text)
                ),
            )
        })?;
    Ok(Some(RawTet {
        tags,
        element_tag,
        line: Some(line),
    }))
}

/// Map node tags to indices, keep the nodes used by tetrahedra (in file order), validate.
fn build(
    nodes: Vec<(u64, Vec3)>,
    tetrahedra: Vec<RawTet>,
    name: &Path,
) -> Result<TetMesh, MeshError> {
    let mut index_of: HashMap<u64, usize> = HashMap::with_capacity(nodes.len());
    for (index, &(tag, _)) in nodes.iter().enumerate() {
        if index_of.insert(tag, index).is_some() {
            return Err(parse_error(
                name,
                None,
                format!("node tag {tag} appears twice in $Nodes"),
            ));
        }
    }
    let mut used = vec![false; nodes.len()];
    let mut tets = Vec::with_capacity(tetrahedra.len());
    for tet in &tetrahedra {
        let mut t = [0usize; 4];
        for (slot, &tag) in t.iter_mut().zip(&tet.tags) {
            *slot = *index_of.get(&tag).ok_or_else(|| {
                parse_error(
                    name,
                    tet.line,
                    format!(
                        "tetrahedron {} refers to node {tag}, which is not in $Nodes",
                        tet.element_tag
                    ),
                )
            })?;
            used[*slot] = true;
        }
        tets.push(t);
    }
    let mut new_index = vec![u32::MAX; nodes.len()];
    let mut positions = Vec::new();
    for (old, (_, p)) in nodes.iter().enumerate() {
        if used[old] {
            new_index[old] = u32::try_from(positions.len())
                .map_err(|_| MeshError::TooManyVertices { count: nodes.len() }.in_file(name))?;
            positions.push(*p);
        }
    }
    if positions.is_empty() && tets.is_empty() && !nodes.is_empty() {
        // Nodes but no tetrahedra: report the missing elements, not missing vertices.
        return Err(MeshError::NoElements {
            kind: crate::ElementKind::Tetrahedron,
        }
        .in_file(name));
    }
    let tets = tets.into_iter().map(|t| t.map(|v| new_index[v])).collect();
    TetMesh::new(positions, tets).map_err(|e| e.in_file(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<TetMesh, MeshError> {
        parse_msh(text.as_bytes(), Path::new("t.msh"))
    }

    const V41: &str =
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n2 5 10 50\n0 1 0 1\n10\n9 9 9\n\
                       3 1 0 4\n20\n30\n40\n50\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n$Elements\n\
                       2 2 1 2\n0 1 15 1\n1 10\n3 1 4 1\n2 20 30 40 50\n$EndElements\n";

    #[test]
    fn sparse_tags_and_ignored_elements() {
        let m = parse(V41).unwrap();
        assert_eq!(m.positions().len(), 4, "the point node is dropped");
        assert_eq!(m.tetrahedra(), &[[0, 1, 2, 3]]);
        assert_eq!(m.positions()[3], Vec3::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn version_2() {
        let m = parse(
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"v\"\n$EndPhysicalNames\n\
             $Nodes\n5\n7 0 0 0\n8 1 0 0\n9 0 1 0\n10 0 0 1\n11 5 5 5\n$EndNodes\n$Elements\n2\n\
             1 15 2 0 1 11\n2 4 2 1 1 7 8 9 10\n$EndElements\n",
        )
        .unwrap();
        assert_eq!(m.positions().len(), 4);
        assert_eq!(m.tetrahedra(), &[[0, 1, 2, 3]]);
        let e = parse("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n1\n1 0 0\n$EndNodes\n")
            .unwrap_err();
        assert!(
            e.to_string().starts_with("t.msh:6: expected a node line"),
            "{e}"
        );
    }

    #[test]
    fn header_errors() {
        for (text, line, needle) in [
            ("", 1, "empty"),
            ("\n\nhello", 3, "$MeshFormat"),
            (
                "$MeshFormat\n4.0 0 8\n$EndMeshFormat\n",
                2,
                "re-save as 4.1",
            ),
            (
                "$MeshFormat\n2.2 1 8\n$EndMeshFormat\n",
                2,
                "re-save as 4.1",
            ),
            (
                "$MeshFormat\n4.1 0 99999999999\n$EndMeshFormat\n",
                2,
                "data size",
            ),
            ("$MeshFormat\n4.1 1 3\n$EndMeshFormat\n", 2, "data size"),
        ] {
            match parse(text) {
                Err(e @ MeshError::Parse { line: Some(l), .. }) => {
                    assert_eq!(l, line, "{text:?}: {e}");
                    assert!(e.to_string().contains(needle), "{text:?}: {e}");
                }
                other => panic!("{text:?}: {other:?}"),
            }
        }
    }

    #[test]
    fn zero_counts_do_not_reach_mshio() {
        let e = parse("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 0 1 1\n$EndNodes\n")
            .unwrap_err();
        assert!(
            matches!(e, MeshError::InFile { ref source, .. } if matches!(**source, MeshError::Empty)),
            "{e:?}"
        );
    }

    #[test]
    fn mshio_errors_have_lines() {
        let broken = V41.replace("0 1 0\n0 0 1", "0 1 0\n0 x 1");
        let e = parse(&broken).unwrap_err();
        assert!(
            matches!(e, MeshError::Parse { line: Some(17), .. }),
            "{e:?}\n{e}"
        );
    }
}
