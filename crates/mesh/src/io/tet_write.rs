//! Writers for tetrahedral meshes: TetGen `.node`/`.ele` pairs and Gmsh MSH 4.1 ASCII, the formats
//! that [`read_tetgen`](super::read_tetgen) and [`read_msh`](super::read_msh) read back. (`mshio`
//! only parses, so the few lines of MSH are written here.)

use std::io::Write;
use std::path::Path;

use super::write_atomically;
use crate::{MeshError, TetMesh};

/// Write a TetGen `.node` file: `<points> 3 0 0`, then `<index> <x> <y> <z>` per vertex, 0-based.
/// Coordinates are written with Rust's shortest round-trip formatting, so they read back exactly.
pub fn write_tetgen_node(mesh: &TetMesh, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(out, "# written by hooke")?;
    writeln!(out, "{} 3 0 0", mesh.positions().len())?;
    for (i, p) in mesh.positions().iter().enumerate() {
        writeln!(out, "{i} {:?} {:?} {:?}", p.x, p.y, p.z)?;
    }
    Ok(())
}

/// Write a TetGen `.ele` file: `<tetrahedra> 4 0`, then `<index> <n1> <n2> <n3> <n4>`, 0-based.
pub fn write_tetgen_ele(mesh: &TetMesh, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(out, "# written by hooke")?;
    writeln!(out, "{} 4 0", mesh.tetrahedra().len())?;
    for (i, [a, b, c, d]) in mesh.tetrahedra().iter().enumerate() {
        writeln!(out, "{i} {a} {b} {c} {d}")?;
    }
    Ok(())
}

/// Write `mesh` as a TetGen pair: `path` with its extension replaced by `.node` and by `.ele`, each
/// atomically (the `.node` first).
///
/// # Errors
/// [`MeshError::Io`] naming the file that could not be written.
pub fn save_tetgen(path: &Path, mesh: &TetMesh) -> Result<(), MeshError> {
    write_atomically(&path.with_extension("node"), |out| {
        write_tetgen_node(mesh, out)
    })?;
    write_atomically(&path.with_extension("ele"), |out| {
        write_tetgen_ele(mesh, out)
    })
}

/// Write `mesh` as Gmsh MSH 4.1 ASCII: one volume entity holding every node (tags 1…n) and every
/// tetrahedron (element type 4, tags 1…m).
pub fn write_msh(mesh: &TetMesh, out: &mut impl Write) -> std::io::Result<()> {
    let positions = mesh.positions();
    let (n, m) = (positions.len(), mesh.tetrahedra().len());
    let mut lo = positions[0];
    let mut hi = positions[0];
    for p in positions {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    writeln!(out, "$MeshFormat\n4.1 0 8\n$EndMeshFormat")?;
    writeln!(out, "$Entities\n0 0 0 1")?;
    writeln!(
        out,
        "1 {:?} {:?} {:?} {:?} {:?} {:?} 0 0",
        lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
    )?;
    writeln!(out, "$EndEntities")?;
    writeln!(out, "$Nodes\n1 {n} 1 {n}\n3 1 0 {n}")?;
    for tag in 1..=n {
        writeln!(out, "{tag}")?;
    }
    for p in positions {
        writeln!(out, "{:?} {:?} {:?}", p.x, p.y, p.z)?;
    }
    writeln!(out, "$EndNodes")?;
    writeln!(out, "$Elements\n1 {m} 1 {m}\n3 1 4 {m}")?;
    for (i, t) in mesh.tetrahedra().iter().enumerate() {
        let [a, b, c, d] = t.map(|v| v as usize + 1);
        writeln!(out, "{} {a} {b} {c} {d}", i + 1)?;
    }
    writeln!(out, "$EndElements")
}

/// Write `mesh` as Gmsh MSH 4.1 ASCII to `path`, atomically (see [`write_msh`]).
///
/// # Errors
/// [`MeshError::Io`] naming `path`.
pub fn save_msh(path: &Path, mesh: &TetMesh) -> Result<(), MeshError> {
    write_atomically(path, |out| write_msh(mesh, out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{parse_msh, parse_tetgen};
    use crate::Vec3;

    fn two_tetrahedra() -> TetMesh {
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.1 + 1.0 / 3.0, 1.0 / 7.0, -0.9),
        ];
        TetMesh::new(positions, vec![[0, 1, 2, 3], [0, 2, 1, 4]]).unwrap()
    }

    #[test]
    fn tetgen_round_trips_exactly() {
        let mesh = two_tetrahedra();
        let (mut node, mut ele) = (Vec::new(), Vec::new());
        write_tetgen_node(&mesh, &mut node).unwrap();
        write_tetgen_ele(&mesh, &mut ele).unwrap();
        let back = parse_tetgen(
            std::str::from_utf8(&node).unwrap(),
            std::str::from_utf8(&ele).unwrap(),
            Path::new("m"),
        )
        .unwrap();
        assert_eq!(back, mesh);
    }

    #[test]
    fn msh_round_trips_exactly() {
        let mesh = two_tetrahedra();
        let mut bytes = Vec::new();
        write_msh(&mesh, &mut bytes).unwrap();
        assert_eq!(parse_msh(&bytes, Path::new("m.msh")).unwrap(), mesh);
    }

    #[test]
    fn save_tetgen_writes_both_files() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.node");
        save_tetgen(&path, &two_tetrahedra()).unwrap();
        assert_eq!(crate::io::read_tetgen(&path).unwrap(), two_tetrahedra());
        save_msh(&dir.path().join("out.msh"), &two_tetrahedra()).unwrap();
        assert_eq!(
            crate::io::read_msh(&dir.path().join("out.msh")).unwrap(),
            two_tetrahedra()
        );
    }
}
