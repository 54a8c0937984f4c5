//! Mesh files: the shipped data reads with the documented counts, writers round-trip, bad input gives
//! the right error (naming the file, and the line where the format has lines), no reader panics on
//! arbitrary bytes, and atomic saving leaves nothing half-written.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use hooke::mesh::io::{
    parse_msh, parse_obj, parse_stl, parse_tetgen, read_mesh, read_msh, read_obj, read_stl,
    read_tetgen, save_obj, save_vtk, write_atomically, write_obj, write_vtk, Frame, Mesh,
};
use hooke::mesh::proptest_support::{tet_mesh, tri_mesh};
use hooke::mesh::{ElementKind, MeshError, TetMesh, TriMesh, Vec2, Vec3};
use proptest::prelude::*;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/meshes")
        .join(name)
}

/// 64 cases unless PROPTEST_CASES says otherwise (set it high to fuzz harder locally).
fn config() -> ProptestConfig {
    let mut config = ProptestConfig::default();
    if std::env::var_os("PROPTEST_CASES").is_none() {
        config.cases = 64;
    }
    config
}

// ---------------------------------------------------------------------------------------------------
// The shipped data: counts as in data/meshes/SOURCES.md.

const SURFACES: [(&str, usize, usize); 6] = [
    ("cloth_30x30.obj", 961, 1_800),
    ("sphere_642.obj", 642, 1_280),
    ("torus.obj", 400, 800),
    ("cube.obj", 152, 300),
    ("bunny.obj", 785, 1_566),
    ("armadillo.obj", 1_053, 2_102),
];

/// (file, nodes, tetrahedra, volume as quoted in SOURCES.md, half a unit of its last digit).
const VOLUMES: [(&str, usize, usize, f64, f64); 3] = [
    ("sphere_tet.msh", 158, 503, 4.005, 5e-4),
    ("armadillo_4k.node", 1_180, 3_717, 1.8596, 5e-5),
    ("armadillo_4k.ele", 1_180, 3_717, 1.8596, 5e-5),
];

#[test]
fn every_shipped_mesh_reads_with_its_documented_counts() {
    let listed: BTreeSet<&str> = SURFACES
        .iter()
        .map(|s| s.0)
        .chain(VOLUMES.iter().map(|v| v.0))
        .chain(["SOURCES.md"])
        .collect();
    let present: BTreeSet<String> = std::fs::read_dir(data(""))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        present.iter().map(String::as_str).collect::<BTreeSet<_>>(),
        listed,
        "data/meshes and this test's tables must list the same files"
    );

    for (file, vertices, triangles) in SURFACES {
        let mesh = read_obj(&data(file)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(mesh.positions().len(), vertices, "{file}");
        assert_eq!(mesh.triangles().len(), triangles, "{file}");
        assert_eq!(read_mesh(&data(file)).unwrap(), Mesh::Surface(mesh));
    }
    for (file, nodes, tets, volume, tolerance) in VOLUMES {
        let mesh = match read_mesh(&data(file)).unwrap_or_else(|e| panic!("{e}")) {
            Mesh::Volume(mesh) => mesh,
            other => panic!("{file}: {other:?}"),
        };
        assert_eq!(mesh.positions().len(), nodes, "{file}");
        assert_eq!(mesh.tetrahedra().len(), tets, "{file}");
        let total: f64 = mesh.volumes().iter().sum();
        assert!(
            (total - volume).abs() <= tolerance,
            "{file}: volume {total}"
        );
        // SOURCES.md: every tetrahedron is positively oriented. A wrong node mapping would break this.
        for t in mesh.tetrahedra() {
            let [a, b, c, d] = t.map(|v| mesh.positions()[v as usize]);
            assert!(
                hooke::mesh::tetrahedron_signed_volume(&a, &b, &c, &d) > 0.0,
                "{file}"
            );
        }
    }
    assert_eq!(
        read_tetgen(&data("armadillo_4k.node")).unwrap(),
        read_tetgen(&data("armadillo_4k.ele")).unwrap()
    );
    assert_eq!(
        read_msh(&data("sphere_tet.msh")).unwrap().positions().len(),
        158
    );
}

#[test]
fn extension_dispatch_is_case_insensitive() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("SPHERE.OBJ");
    std::fs::copy(data("sphere_642.obj"), &path).unwrap();
    assert!(matches!(read_mesh(&path), Ok(Mesh::Surface(_))));
    let e = read_mesh(&dir.path().join("sphere.ply")).unwrap_err();
    assert!(matches!(e, MeshError::Parse { .. }));
    let text = e.to_string();
    assert!(
        text.contains("sphere.ply") && text.contains(".obj") && text.contains(".msh"),
        "{text}"
    );
}

// ---------------------------------------------------------------------------------------------------
// Round trips.

fn assert_same_bits(a: &[Vec3], b: &[Vec3]) {
    assert_eq!(a.len(), b.len());
    for (k, (p, q)) in a.iter().zip(b).enumerate() {
        for axis in 0..3 {
            assert_eq!(
                p[axis].to_bits(),
                q[axis].to_bits(),
                "vertex {k} axis {axis}"
            );
        }
    }
}

fn obj_round_trip(positions: &[Vec3], triangles: &[[u32; 3]]) {
    let frame = Frame {
        triangles,
        ..Frame::points(positions)
    };
    let mut bytes = Vec::new();
    write_obj(&frame, &mut bytes).unwrap();
    let back = parse_obj(&bytes, Path::new("frame.obj")).unwrap();
    assert_same_bits(back.positions(), positions);
    assert_eq!(back.triangles(), triangles);
}

/// Read back with vtkio's own parser: points (as f64, bit for bit), cell lists and types.
fn vtk_read_back(bytes: &[u8]) -> (Vec<f64>, Vec<u32>, Vec<u8>) {
    use vtkio::model::{DataSet, Piece, VertexNumbers};
    let vtk = vtkio::Vtk::parse_legacy_be(bytes).expect("vtkio parses our file");
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an unstructured grid")
    };
    let Some(Piece::Inline(piece)) = pieces.into_iter().next() else {
        panic!("no inline piece")
    };
    let points = piece.points.into_vec::<f64>().expect("double points");
    let VertexNumbers::Legacy {
        num_cells,
        vertices,
    } = piece.cells.cell_verts
    else {
        panic!("legacy cells expected")
    };
    assert_eq!(num_cells as usize, piece.cells.types.len());
    let types = piece.cells.types.iter().map(|&t| t as u8).collect();
    (points, vertices, types)
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn obj_round_trips_triangle_meshes(mesh in tri_mesh(6)) {
        obj_round_trip(mesh.positions(), mesh.triangles());
    }

    #[test]
    fn obj_round_trips_tet_mesh_boundaries(mesh in tet_mesh(3)) {
        // OBJ has no volume cells: write the boundary. Interior vertices are written too (unused).
        obj_round_trip(mesh.positions(), &mesh.boundary_faces());
    }

    #[test]
    fn vtk_round_trips(tri in tri_mesh(4), tet in tet_mesh(2)) {
        // Triangles with their edges as lines.
        let edges = tri.edges();
        let frame = Frame { lines: &edges, ..Frame::from(&tri) };
        let mut bytes = Vec::new();
        write_vtk(&frame, &mut bytes).unwrap();
        let (points, cells, types) = vtk_read_back(&bytes);
        let expected: Vec<f64> = tri.positions().iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        prop_assert_eq!(points.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                        expected.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
        let mut expected_cells = Vec::new();
        for t in tri.triangles() { expected_cells.push(3); expected_cells.extend(t); }
        for e in &edges { expected_cells.push(2); expected_cells.extend(e); }
        prop_assert_eq!(cells, expected_cells);
        let mut expected_types = vec![5u8; tri.triangles().len()];
        expected_types.resize(tri.triangles().len() + edges.len(), 3);
        prop_assert_eq!(types, expected_types);

        // Tetrahedra win over triangles.
        let faces = tet.boundary_faces();
        let frame = Frame { triangles: &faces, ..Frame::from(&tet) };
        let mut bytes = Vec::new();
        write_vtk(&frame, &mut bytes).unwrap();
        let (points, cells, types) = vtk_read_back(&bytes);
        prop_assert_eq!(points.len(), 3 * tet.positions().len());
        prop_assert!(points.iter().zip(tet.positions().iter().flat_map(|p| [p.x, p.y, p.z]))
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        let expected_cells: Vec<u32> = tet.tetrahedra().iter()
            .flat_map(|t| [4, t[0], t[1], t[2], t[3]]).collect();
        prop_assert_eq!(cells, expected_cells);
        prop_assert_eq!(types, vec![10u8; tet.tetrahedra().len()]);
    }

    #[test]
    fn stl_round_trips_binary_and_ascii(mesh in tri_mesh(5)) {
        // STL stores f32 corners per triangle: compare corner coordinates after f32 rounding.
        let corners = |m: &TriMesh| -> Vec<[[f32; 3]; 3]> {
            m.triangles().iter().map(|t| t.map(|v| {
                let p = m.positions()[v as usize];
                [p.x as f32, p.y as f32, p.z as f32]
            })).collect()
        };
        let expected = corners(&mesh);
        let binary = binary_stl(&expected);
        let from_binary = parse_stl(&binary, Path::new("mesh.stl")).unwrap();
        prop_assert_eq!(corners(&from_binary), expected.clone());
        // Every grid vertex is used, and f32 rounding merges none of them.
        prop_assert_eq!(from_binary.positions().len(), mesh.positions().len());

        let mut ascii = String::from("solid hooke\n");
        for c in &expected {
            ascii.push_str("  facet normal 0 0 0\n    outer loop\n");
            for v in c {
                ascii.push_str(&format!("      vertex {} {} {}\n", v[0], v[1], v[2]));
            }
            ascii.push_str("    endloop\n  endfacet\n");
        }
        ascii.push_str("endsolid hooke\n");
        let from_ascii = parse_stl(ascii.as_bytes(), Path::new("mesh.stl")).unwrap();
        prop_assert_eq!(from_ascii, from_binary);
    }
}

#[test]
fn two_dimensional_frames_get_z_zero() {
    let p = [
        Vec2::new(0.5, -1.25),
        Vec2::new(2.0, 0.0),
        Vec2::new(0.0, 3.0),
    ];
    let frame = Frame {
        triangles: &[[0, 1, 2]],
        lines: &[[0, 1]],
        ..Frame::points(&p)
    };
    let mut bytes = Vec::new();
    write_obj(&frame, &mut bytes).unwrap();
    let text = String::from_utf8(bytes.clone()).unwrap();
    assert_eq!(
        text,
        "# hooke\nv 0.5 -1.25 0\nv 2 0 0\nv 0 3 0\nf 1 2 3\nl 1 2\n"
    );
    let mesh = parse_obj(&bytes, Path::new("2d.obj")).unwrap();
    assert!(mesh.positions().iter().all(|p| p.z == 0.0));
    let mut vtk = Vec::new();
    write_vtk(&frame, &mut vtk).unwrap();
    let (points, cells, types) = vtk_read_back(&vtk);
    assert_eq!(points, vec![0.5, -1.25, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0, 0.0]);
    assert_eq!(cells, vec![3, 0, 1, 2, 2, 0, 1]);
    assert_eq!(types, vec![5, 3]);
}

#[test]
fn writers_reject_invalid_frames() {
    let p = [Vec3::zeros(), Vec3::x(), Vec3::new(f64::NAN, 0.0, 0.0)];
    let bad_index = Frame {
        triangles: &[[0, 1, 3]],
        ..Frame::points(&p[..2])
    };
    let nan = Frame::points(&p);
    for frame in [bad_index, nan] {
        let mut out = Vec::new();
        let e = write_obj(&frame, &mut out).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
        assert!(out.is_empty(), "nothing is written");
        let e = write_vtk(&frame, &mut out).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
        assert!(out.is_empty(), "nothing is written");
    }
}

// ---------------------------------------------------------------------------------------------------
// Errors: the right variant, the file's name, and the line where the format has lines.

/// Write `bytes` as `dir/name` and read it back with `read_mesh`.
fn read_bytes(dir: &Path, name: &str, bytes: &[u8]) -> Result<Mesh, MeshError> {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    read_mesh(&path)
}

/// The validation error inside an `InFile`, after checking that it names `file`.
#[track_caller]
fn in_file<T: std::fmt::Debug>(result: Result<T, MeshError>, file: &str) -> MeshError {
    match result {
        Err(e @ MeshError::InFile { .. }) => {
            let text = e.to_string();
            assert!(text.contains(file), "{text} should name {file}");
            let MeshError::InFile { path, source } = e else {
                unreachable!()
            };
            assert!(path.ends_with(file), "{path:?} should be {file}");
            *source
        }
        other => panic!("expected an InFile error for {file}, got {other:?}"),
    }
}

/// The message of a `Parse` error, after checking that it names `file` and `line`.
#[track_caller]
fn parse_error<T: std::fmt::Debug>(
    result: Result<T, MeshError>,
    file: &str,
    line: Option<usize>,
) -> String {
    match result {
        Err(e @ MeshError::Parse { .. }) => {
            let text = e.to_string();
            let MeshError::Parse { path, line: l, .. } = &e else {
                unreachable!()
            };
            assert!(path.ends_with(file), "{path:?} should be {file}");
            assert_eq!(*l, line, "{text}");
            match line {
                Some(line) => assert!(text.contains(&format!("{file}:{line}: ")), "{text}"),
                None => assert!(text.contains(&format!("{file}: ")), "{text}"),
            }
            text
        }
        other => panic!("expected a Parse error for {file}, got {other:?}"),
    }
}

const TRIANGLE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

#[test]
fn obj_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = |text: String| read_bytes(d, "bad.obj", text.as_bytes());
    let e = in_file(
        obj("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n".into()),
        "bad.obj",
    );
    assert!(
        matches!(
            e,
            MeshError::NonFiniteCoordinate {
                vertex: 1,
                axis: 1,
                ..
            }
        ),
        "{e:?}"
    );
    let e = in_file(obj(format!("{TRIANGLE_OBJ}f 1 2 3\nf 1 2 4\n")), "bad.obj");
    assert!(
        matches!(
            e,
            MeshError::IndexOutOfRange {
                kind: ElementKind::Triangle,
                element: 1,
                index: 3,
                vertex_count: 3
            }
        ),
        "{e:?}"
    );
    let e = in_file(obj(format!("{TRIANGLE_OBJ}f 1 2 2\n")), "bad.obj");
    assert!(
        matches!(e, MeshError::RepeatedVertex { vertex: 1, .. }),
        "{e:?}"
    );
    let e = in_file(
        obj("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n".into()),
        "bad.obj",
    );
    assert!(
        matches!(
            e,
            MeshError::Degenerate {
                kind: ElementKind::Triangle,
                element: 0,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(matches!(
        in_file(obj(String::new()), "bad.obj"),
        MeshError::Empty
    ));
    assert!(matches!(
        in_file(obj(TRIANGLE_OBJ.into()), "bad.obj"),
        MeshError::NoElements {
            kind: ElementKind::Triangle
        }
    ));
    // Truncated mid-line: the vertex lacks its z, the face its third vertex.
    let text = parse_error(obj("v 0 0 0\nv 1 0".into()), "bad.obj", Some(2));
    assert!(text.contains("three numbers"), "{text}");
    let text = parse_error(obj(format!("{TRIANGLE_OBJ}f 1 2")), "bad.obj", Some(4));
    assert!(text.contains("at least three vertices"), "{text}");
    let text = parse_error(obj(format!("{TRIANGLE_OBJ}f 1 2 x\n")), "bad.obj", Some(4));
    assert!(text.contains("\"x\""), "{text}");
    // I/O: a missing file.
    let e = read_obj(&d.join("missing.obj")).unwrap_err();
    assert!(
        matches!(e, MeshError::Io { .. }) && e.to_string().contains("missing.obj"),
        "{e}"
    );
}

/// A binary STL written by hand (80-byte header, u32 count, 50 bytes per triangle: normal, three
/// corners, attribute count), independent of the reader's library. `stl_io`'s own writer is exercised
/// by the unit tests of `hooke_mesh::io` (it is not a dependency of this package).
fn binary_stl(triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut bytes = vec![0u8; 80];
    bytes.extend(u32::try_from(triangles.len()).unwrap().to_le_bytes());
    for t in triangles {
        for c in [0.0f32; 3].iter().chain(t.iter().flatten()) {
            bytes.extend(c.to_le_bytes());
        }
        bytes.extend([0u8; 2]);
    }
    bytes
}

fn ascii_stl(corners: [&str; 3]) -> String {
    format!(
        "solid s\nfacet normal 0 0 1\nouter loop\nvertex {}\nvertex {}\nvertex {}\nendloop\nendfacet\nendsolid s\n",
        corners[0], corners[1], corners[2]
    )
}

#[test]
fn stl_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let stl = |bytes: &[u8]| read_bytes(d, "bad.stl", bytes);
    let (o, x, y) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    assert!(stl(&binary_stl(&[[o, x, y]])).is_ok());
    // Binary NaN reaches validation; ASCII NaN is refused by stl_io's parser.
    let e = in_file(stl(&binary_stl(&[[o, x, [f32::NAN, 1.0, 0.0]]])), "bad.stl");
    assert!(
        matches!(e, MeshError::NonFiniteCoordinate { axis: 0, .. }),
        "{e:?}"
    );
    let text = parse_error(
        stl(ascii_stl(["0 0 0", "1 0 0", "NaN 1 0"]).as_bytes()),
        "bad.stl",
        None,
    );
    assert!(text.contains("ASCII STL"), "{text}");
    // STL has no indices: equal corners are the "repeated vertex" and the out-of-range case cannot occur.
    let e = in_file(stl(&binary_stl(&[[o, x, x]])), "bad.stl");
    assert!(
        matches!(
            e,
            MeshError::RepeatedVertex {
                kind: ElementKind::Triangle,
                ..
            }
        ),
        "{e:?}"
    );
    let e = in_file(
        stl(ascii_stl(["0 0 0", "1 0 0", "2 0 0"]).as_bytes()),
        "bad.stl",
    );
    assert!(matches!(e, MeshError::Degenerate { .. }), "{e:?}");
    let text = parse_error(stl(b""), "bad.stl", None);
    assert!(text.contains("empty"), "{text}");
    let e = in_file(stl(&binary_stl(&[])), "bad.stl");
    assert!(matches!(e, MeshError::Empty), "{e:?}");
    let full = binary_stl(&[[o, x, y], [o, y, [0.0, 0.0, 1.0]]]);
    let text = parse_error(stl(&full[..full.len() - 10]), "bad.stl", None);
    assert!(text.contains("truncated binary STL"), "{text}");
    let text = parse_error(stl(&full[..40]), "bad.stl", None);
    assert!(text.contains("84-byte header"), "{text}");
    let ascii = ascii_stl(["0 0 0", "1 0 0", "0 1 0"]);
    let text = parse_error(stl(&ascii.as_bytes()[..ascii.len() - 30]), "bad.stl", None);
    assert!(text.contains("ASCII STL"), "{text}");
    let e = read_stl(&d.join("missing.stl")).unwrap_err();
    assert!(
        matches!(e, MeshError::Io { .. }) && e.to_string().contains("missing.stl"),
        "{e}"
    );
}

/// A one-tetrahedron MSH 4.1 file with the given node coordinates and tetrahedron node tags.
fn msh41(nodes: [&str; 4], tet: &str) -> String {
    format!(
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n{}\n{}\n{}\n{}\n\
         $EndNodes\n$Elements\n1 1 1 1\n3 1 4 1\n1 {tet}\n$EndElements\n",
        nodes[0], nodes[1], nodes[2], nodes[3]
    )
}

const UNIT: [&str; 4] = ["0 0 0", "1 0 0", "0 1 0", "0 0 1"];

#[test]
fn msh_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let msh = |text: &str| read_bytes(d, "bad.msh", text.as_bytes());
    let good = msh41(UNIT, "1 2 3 4");
    let mesh = msh(&good).unwrap();
    assert!(matches!(mesh, Mesh::Volume(ref m) if m.tetrahedra() == [[0, 1, 2, 3]]));
    // Non-finite coordinates parse (in 4.1 through mshio, in 2.x through Rust's parser) and are
    // caught by validation.
    let e = in_file(
        msh(&msh41(["0 0 0", "nan 0 0", "0 1 0", "0 0 1"], "1 2 3 4")),
        "bad.msh",
    );
    assert!(
        matches!(
            e,
            MeshError::NonFiniteCoordinate {
                vertex: 1,
                axis: 0,
                ..
            }
        ),
        "{e:?}"
    );
    // A syntax error in a node's coordinates: the line is known in ASCII files.
    let text = parse_error(
        msh(&msh41(["0 0 0", "1 zero 0", "0 1 0", "0 0 1"], "1 2 3 4")),
        "bad.msh",
        Some(12),
    );
    assert!(text.contains("y coordinate"), "{text}");
    let v2 = |coordinate: &str, tet: &str| {
        format!(
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 {coordinate} 0 0\n3 0 1 0\n4 0 0 1\n\
             $EndNodes\n$Elements\n1\n1 4 2 0 1 {tet}\n$EndElements\n"
        )
    };
    assert!(msh(&v2("1", "1 2 3 4")).is_ok());
    let e = in_file(msh(&v2("NaN", "1 2 3 4")), "bad.msh");
    assert!(
        matches!(
            e,
            MeshError::NonFiniteCoordinate {
                vertex: 1,
                axis: 0,
                ..
            }
        ),
        "{e:?}"
    );
    // An unknown node tag: nodes are named by tags, not indices.
    let text = parse_error(msh(&msh41(UNIT, "1 2 3 9")), "bad.msh", None);
    assert!(text.contains("node 9"), "{text}");
    let text = parse_error(msh(&v2("1", "1 2 3 9")), "bad.msh", Some(13));
    assert!(text.contains("node 9"), "{text}");
    let e = in_file(msh(&msh41(UNIT, "1 2 3 3")), "bad.msh");
    assert!(
        matches!(
            e,
            MeshError::RepeatedVertex {
                kind: ElementKind::Tetrahedron,
                ..
            }
        ),
        "{e:?}"
    );
    let e = in_file(
        msh(&msh41(["0 0 0", "1 0 0", "0 1 0", "1 1 0"], "1 2 3 4")),
        "bad.msh",
    );
    assert!(
        matches!(
            e,
            MeshError::Degenerate {
                kind: ElementKind::Tetrahedron,
                ..
            }
        ),
        "{e:?}"
    );
    let text = parse_error(msh(""), "bad.msh", Some(1));
    assert!(text.contains("empty"), "{text}");
    // Truncated in the node coordinates: the error is at the end, on line 14.
    let text = parse_error(
        msh(&good[..good.find("0 0 1\n").unwrap()]),
        "bad.msh",
        Some(14),
    );
    assert!(text.contains("invalid MSH 4.1"), "{text}");
    // Only triangles: no tetrahedra.
    let triangles_only = good.replace("3 1 4 1\n1 1 2 3 4", "2 1 2 1\n1 1 2 3");
    let e = in_file(msh(&triangles_only), "bad.msh");
    assert!(
        matches!(
            e,
            MeshError::NoElements {
                kind: ElementKind::Tetrahedron
            }
        ),
        "{e:?}"
    );
    let text = parse_error(
        msh("$MeshFormat\n4.0 0 8\n$EndMeshFormat\n"),
        "bad.msh",
        Some(2),
    );
    assert!(text.contains("re-save as 4.1"), "{text}");
    let text = parse_error(msh("solid x\n"), "bad.msh", Some(1));
    assert!(text.contains("$MeshFormat"), "{text}");
}

#[test]
fn msh_binary_4_1() {
    // Built by hand as Gmsh writes it: little-endian, size_t = 8, int = 4, double = 8.
    let mut b: Vec<u8> = b"$MeshFormat\n4.1 1 8\n".to_vec();
    b.extend(1i32.to_le_bytes());
    b.extend(b"\n$EndMeshFormat\n$Nodes\n");
    for v in [1u64, 4, 10, 40] {
        b.extend(v.to_le_bytes()); // blocks, nodes, min tag, max tag (sparse)
    }
    b.extend(3i32.to_le_bytes());
    b.extend(1i32.to_le_bytes());
    b.extend(0i32.to_le_bytes());
    b.extend(4u64.to_le_bytes());
    for tag in [40u64, 30, 20, 10] {
        b.extend(tag.to_le_bytes());
    }
    for p in [
        [0.0f64, 0.0, 1.0],
        [0.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ] {
        for c in p {
            b.extend(c.to_le_bytes());
        }
    }
    b.extend(b"\n$EndNodes\n$Elements\n");
    for v in [1u64, 1, 7, 7] {
        b.extend(v.to_le_bytes());
    }
    b.extend(3i32.to_le_bytes());
    b.extend(1i32.to_le_bytes());
    b.extend(4i32.to_le_bytes());
    b.extend(1u64.to_le_bytes());
    for tag in [7u64, 10, 20, 30, 40] {
        b.extend(tag.to_le_bytes());
    }
    b.extend(b"\n$EndElements\n");
    let mesh = parse_msh(&b, Path::new("bin.msh")).unwrap();
    // Nodes in file order (tags 40, 30, 20, 10); the tetrahedron 10 20 30 40 maps to 3 2 1 0.
    assert_eq!(mesh.positions()[3], Vec3::zeros());
    assert_eq!(mesh.tetrahedra(), &[[3, 2, 1, 0]]);
    // Truncated: a Parse error with a byte offset, not a line.
    let text = parse_error(
        parse_msh(&b[..b.len() - 30], Path::new("bin.msh")),
        "bin.msh",
        None,
    );
    assert!(text.contains("at byte"), "{text}");
}

const NODE: &str = "# unit tetrahedron\n4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";

#[test]
fn tetgen_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let tetgen = |node: &str, ele: &str| {
        std::fs::write(d.join("bad.node"), node).unwrap();
        std::fs::write(d.join("bad.ele"), ele).unwrap();
        read_mesh(&d.join("bad.ele"))
    };
    assert!(tetgen(NODE, "1 4 0\n0 0 1 2 3\n").is_ok());
    let e = in_file(
        tetgen(&NODE.replace("2 0 1 0", "2 0 inf 0"), "1 4 0\n0 0 1 2 3\n"),
        "bad.node",
    );
    assert!(
        matches!(
            e,
            MeshError::NonFiniteCoordinate {
                vertex: 2,
                axis: 1,
                ..
            }
        ),
        "{e:?}"
    );
    let e = in_file(tetgen(NODE, "1 4 0\n0 0 1 2 4\n"), "bad.ele");
    assert!(
        matches!(
            e,
            MeshError::IndexOutOfRange {
                index: 4,
                vertex_count: 4,
                ..
            }
        ),
        "{e:?}"
    );
    let e = in_file(tetgen(NODE, "1 4 0\n0 0 1 2 2\n"), "bad.ele");
    assert!(
        matches!(e, MeshError::RepeatedVertex { vertex: 2, .. }),
        "{e:?}"
    );
    let flat = NODE.replace("3 0 0 1", "3 1 1 0");
    let e = in_file(tetgen(&flat, "1 4 0\n0 0 1 2 3\n"), "bad.ele");
    assert!(matches!(e, MeshError::Degenerate { .. }), "{e:?}");
    let text = parse_error(tetgen("", "1 4 0\n0 0 1 2 3\n"), "bad.node", Some(1));
    assert!(text.contains("header"), "{text}");
    let text = parse_error(tetgen(NODE, "\n# nothing\n"), "bad.ele", Some(2));
    assert!(text.contains("header"), "{text}");
    // Truncated: fewer entries than declared; and a line cut short.
    let text = parse_error(tetgen(NODE, "2 4 0\n0 0 1 2 3\n"), "bad.ele", Some(2));
    assert!(text.contains("unexpected end of file"), "{text}");
    let text = parse_error(
        tetgen(&NODE[..NODE.len() - 3], "1 4 0\n0 0 1 2 3\n"),
        "bad.node",
        Some(6),
    );
    assert!(text.contains("point line"), "{text}");
    let text = parse_error(tetgen(NODE, "1 4 0\n0 0 1 two 3\n"), "bad.ele", Some(2));
    assert!(text.contains("\"two\""), "{text}");
    let text = parse_error(
        tetgen(
            &NODE.replace("\n1 1 0 0", "\n5 1 0 0"),
            "1 4 0\n0 0 1 2 3\n",
        ),
        "bad.node",
        Some(4),
    );
    assert!(text.contains("expected point index 1"), "{text}");
    // A missing partner file is an I/O error naming it.
    std::fs::remove_file(d.join("bad.ele")).unwrap();
    let e = read_tetgen(&d.join("bad.node")).unwrap_err();
    assert!(
        matches!(e, MeshError::Io { .. }) && e.to_string().contains("bad.ele"),
        "{e}"
    );
    // parse_tetgen names the files after `name`.
    let e = parse_tetgen(NODE, "1 4 0\n0 0 1 2\n", Path::new("dir/stem")).unwrap_err();
    assert!(e.to_string().starts_with("dir/stem.ele:2: "), "{e}");
}

// ---------------------------------------------------------------------------------------------------
// No panics on arbitrary input. An Ok is allowed only if the mesh validates.

fn check_tri(result: Result<TriMesh, MeshError>) -> Result<(), TestCaseError> {
    if let Ok(mesh) = result {
        prop_assert!(TriMesh::new(mesh.positions().to_vec(), mesh.triangles().to_vec()).is_ok());
    }
    Ok(())
}

fn check_tet(result: Result<TetMesh, MeshError>) -> Result<(), TestCaseError> {
    if let Ok(mesh) = result {
        prop_assert!(TetMesh::new(mesh.positions().to_vec(), mesh.tetrahedra().to_vec()).is_ok());
    }
    Ok(())
}

/// Lines of tokens that the parsers look for, numbers of every kind included.
fn token_lines() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        Just("v"),
        Just("f"),
        Just("vt"),
        Just("#"),
        Just("1/2/3"),
        Just("-1"),
        Just("0"),
        Just("1"),
        Just("2"),
        Just("3"),
        Just("4"),
        Just("10"),
        Just("1e308"),
        Just("nan"),
        Just("-inf"),
        Just("0.5"),
        Just("18446744073709551615"),
        Just("99999999999999999999"),
        Just("solid"),
        Just("facet"),
        Just("normal"),
        Just("outer"),
        Just("loop"),
        Just("vertex"),
        Just("endloop"),
        Just("endfacet"),
        Just("endsolid"),
        Just("$MeshFormat"),
        Just("$EndMeshFormat"),
        Just("4.1"),
        Just("2.2"),
        Just("$Nodes"),
        Just("$EndNodes"),
        Just("$Elements"),
        Just("$EndElements"),
        Just("$Entities"),
        Just("$EndEntities"),
        Just("8"),
    ];
    proptest::collection::vec(proptest::collection::vec(token, 0..8), 0..40).prop_map(|lines| {
        lines
            .iter()
            .map(|l| l.join(" "))
            .collect::<Vec<_>>()
            .join("\n")
    })
}

/// Valid samples of each format, to mutate.
fn samples() -> Vec<(&'static str, Vec<u8>)> {
    let obj = format!("{TRIANGLE_OBJ}v 0 0 1\nf 1 2 3\nf 1 2/1 -1//2\n");
    vec![
        ("obj", obj.into_bytes()),
        ("stl", ascii_stl(["0 0 0", "1 0 0", "0 1 0"]).into_bytes()),
        (
            "stl",
            binary_stl(&[[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]),
        ),
        ("msh", msh41(UNIT, "1 2 3 4").into_bytes()),
        (
            "msh",
            std::fs::read(data("sphere_tet.msh")).unwrap()[..3000].to_vec(),
        ),
        ("node", NODE.as_bytes().to_vec()),
        ("ele", b"1 4 0\n0 0 1 2 3\n".to_vec()),
    ]
}

/// Byte edits: (position fraction, operation, byte).
fn mutations() -> impl Strategy<Value = Vec<(f64, u8, u8)>> {
    proptest::collection::vec((0.0f64..1.0, 0u8..3, any::<u8>()), 1..6)
}

fn mutate(mut bytes: Vec<u8>, edits: &[(f64, u8, u8)]) -> Vec<u8> {
    for &(at, op, byte) in edits {
        let i = ((at * bytes.len() as f64) as usize).min(bytes.len());
        match op {
            0 if i < bytes.len() => bytes[i] = byte,
            1 if i < bytes.len() => {
                bytes.remove(i);
            }
            _ => bytes.insert(i, byte),
        }
    }
    bytes
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..4096)) {
        let name = Path::new("random");
        check_tri(parse_obj(&bytes, name))?;
        check_tri(parse_stl(&bytes, name))?;
        check_tet(parse_msh(&bytes, name))?;
        let text = String::from_utf8_lossy(&bytes);
        let (a, b) = text.split_at(text.char_indices().nth(text.chars().count() / 2).map_or(0, |c| c.0));
        check_tet(parse_tetgen(a, b, name))?;
    }

    #[test]
    fn plausible_token_lines_never_panic(a in token_lines(), b in token_lines()) {
        let name = Path::new("tokens");
        check_tri(parse_obj(a.as_bytes(), name))?;
        check_tri(parse_stl(format!("solid x\n{a}").as_bytes(), name))?;
        check_tet(parse_msh(format!("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n{a}").as_bytes(), name))?;
        check_tet(parse_msh(format!("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n{a}").as_bytes(), name))?;
        check_tet(parse_tetgen(&a, &b, name))?;
        check_tet(parse_tetgen(&format!("4 3 0 0\n{a}"), &format!("1 4 0\n{b}"), name))?;
    }

    #[test]
    fn mutated_valid_files_never_panic(edits in mutations(), which in 0usize..7) {
        let name = Path::new("mutated");
        let (format, sample) = samples().swap_remove(which);
        let bytes = mutate(sample, &edits);
        match format {
            "obj" => check_tri(parse_obj(&bytes, name))?,
            "stl" => check_tri(parse_stl(&bytes, name))?,
            "msh" => check_tet(parse_msh(&bytes, name))?,
            "node" => check_tet(parse_tetgen(&String::from_utf8_lossy(&bytes), "1 4 0\n0 0 1 2 3\n", name))?,
            _ => check_tet(parse_tetgen(NODE, &String::from_utf8_lossy(&bytes), name))?,
        }
    }
}

#[test]
fn binary_msh_headers_that_would_panic_mshio_are_refused() {
    // mshio computes `count - 1` on section headers and has no parser for odd integer sizes.
    for (header, body) in [("4.1 1 8", [1u64, 0, 1, 1]), ("4.1 1 8", [0u64, 0, 1, 1])] {
        let mut b = format!("$MeshFormat\n{header}\n").into_bytes();
        b.extend(1i32.to_le_bytes());
        b.extend(b"\n$EndMeshFormat\n$Nodes\n");
        for v in body {
            b.extend(v.to_le_bytes());
        }
        b.extend(b"\n$EndNodes\n");
        let e = in_file(parse_msh(&b, Path::new("zero.msh")), "zero.msh");
        assert!(matches!(e, MeshError::Empty), "{e:?}");
    }
    for header in ["4.1 1 3", "4.1 0 4294967296", "4.1 1 99999999999999999999"] {
        let text = format!("$MeshFormat\n{header}\n$EndMeshFormat\n");
        parse_error(
            parse_msh(text.as_bytes(), Path::new("size.msh")),
            "size.msh",
            Some(2),
        );
    }
}

// ---------------------------------------------------------------------------------------------------
// Atomic writing.

fn directory_entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn failed_writes_leave_nothing_behind() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("frame.obj");
    let fail = |out: &mut std::io::BufWriter<std::fs::File>| -> std::io::Result<()> {
        out.write_all(&vec![b'v'; 1 << 20])?; // more than the buffer: part of it reaches the disk
        Err(std::io::Error::other("simulated failure mid-way"))
    };
    let e = write_atomically(&target, fail).unwrap_err();
    assert!(matches!(e, MeshError::Io { .. }), "{e:?}");
    assert!(e.to_string().contains("frame.obj"), "{e}");
    assert!(
        directory_entries(dir.path()).is_empty(),
        "{:?}",
        directory_entries(dir.path())
    );

    // An existing target is left unchanged, by a failing closure and by an invalid frame.
    std::fs::write(&target, b"previous frame").unwrap();
    write_atomically(&target, fail).unwrap_err();
    let p = [Vec3::zeros(), Vec3::x(), Vec3::y()];
    let invalid = Frame {
        triangles: &[[0, 1, 7]],
        ..Frame::points(&p)
    };
    assert!(matches!(
        save_obj(&target, &invalid),
        Err(MeshError::Io { .. })
    ));
    assert!(matches!(
        save_vtk(&target, &invalid),
        Err(MeshError::Io { .. })
    ));
    assert_eq!(std::fs::read(&target).unwrap(), b"previous frame");
    assert_eq!(directory_entries(dir.path()), vec!["frame.obj"]);
}

#[test]
fn saved_frames_replace_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = read_obj(&data("sphere_642.obj")).unwrap();
    let obj = dir.path().join("sphere.obj");
    std::fs::write(&obj, b"old").unwrap();
    save_obj(&obj, &Frame::from(&mesh)).unwrap();
    assert_eq!(read_obj(&obj).unwrap(), mesh);
    let vtk = dir.path().join("sphere.vtk");
    save_vtk(&vtk, &Frame::from(&mesh)).unwrap();
    let (points, _, types) = vtk_read_back(&std::fs::read(&vtk).unwrap());
    assert_eq!(points.len(), 3 * 642);
    assert_eq!(types.len(), 1280);
    assert_eq!(
        directory_entries(dir.path()),
        vec!["sphere.obj", "sphere.vtk"]
    );
}
