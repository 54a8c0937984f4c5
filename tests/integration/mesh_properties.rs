//! Properties of the spring graphs and lumped masses built from generated meshes.

use std::collections::BTreeSet;

use hooke::mesh::generators::{beam_tet_mesh, cloth, cloth_spring_count};
use hooke::mesh::proptest_support::{cloth_mesh, mass_model, spring_mesh_3d, tet_mesh, tri_mesh};
use hooke::mesh::{Bending, MassModel, SpringMesh, TetMesh, TriMesh};
use proptest::prelude::*;

/// 64 cases unless PROPTEST_CASES says otherwise; the meshes are small, so the file runs in seconds.
fn config() -> ProptestConfig {
    let mut config = ProptestConfig::default();
    if std::env::var_os("PROPTEST_CASES").is_none() {
        config.cases = 64;
    }
    config
}

fn key([a, b]: [u32; 2]) -> [u32; 2] {
    [a.min(b), a.max(b)]
}

/// The undirected edges of some elements, computed here independently of the mesh crate.
fn edges_of<const K: usize>(elements: &[[u32; K]]) -> BTreeSet<[u32; 2]> {
    let mut edges = BTreeSet::new();
    for e in elements {
        for a in 0..K {
            for b in a + 1..K {
                edges.insert(key([e[a], e[b]]));
            }
        }
    }
    edges
}

/// The springs as undirected pairs, checking that none appears twice.
fn spring_set<const D: usize>(mesh: &SpringMesh<D>) -> Result<BTreeSet<[u32; 2]>, TestCaseError> {
    let set: BTreeSet<[u32; 2]> = mesh.springs().iter().map(|s| key([s.i, s.j])).collect();
    prop_assert_eq!(set.len(), mesh.springs().len(), "a spring appears twice");
    Ok(set)
}

/// Relative tolerance for sums of n positive terms: each addition rounds by at most half an ulp of the
/// partial sum (≤ total), so the error is below n·ε·total; 1e-12 leaves room for n up to ~4,500 terms,
/// and the meshes here have at most a few hundred vertices and elements.
const SUM_TOLERANCE: f64 = 1e-12;

fn check_masses(
    masses: &[f64],
    model: MassModel,
    measure: f64,
    is_surface: bool,
) -> Result<(), TestCaseError> {
    let total: f64 = masses.iter().sum();
    prop_assert!(masses.iter().all(|&m| m > 0.0));
    let expected = match model {
        MassModel::Uniform { total } => total,
        // Σ area × thickness × density for sheets; Σ volume × density for solids (thickness ignored).
        // Each element's mass is split into equal shares, so the shares add back to the same sum up to
        // the rounding bound above (the product ρ·t·A is rounded in a different order: a few ε more).
        MassModel::Density { density, thickness } if is_surface => density * thickness * measure,
        MassModel::Density { density, .. } => density * measure,
    };
    prop_assert!(
        (total - expected).abs() <= SUM_TOLERANCE * expected,
        "total mass {} against {}",
        total,
        expected
    );
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn triangle_edges_become_springs_exactly_once(mesh in tri_mesh(6), model in mass_model()) {
        let springs = SpringMesh::from_triangles(&mesh, 100.0, Bending::None, model).unwrap();
        let expected = edges_of(mesh.triangles());
        prop_assert_eq!(spring_set(&springs)?, expected.clone());
        prop_assert_eq!(mesh.edges(), expected.into_iter().collect::<Vec<_>>());
        prop_assert_eq!(springs.triangles(), mesh.triangles());
    }

    #[test]
    fn tetrahedron_edges_become_springs_exactly_once(mesh in tet_mesh(3), model in mass_model()) {
        let springs = SpringMesh::from_tetrahedra(&mesh, 100.0, model).unwrap();
        let expected = edges_of(mesh.tetrahedra());
        prop_assert_eq!(spring_set(&springs)?, expected.clone());
        prop_assert_eq!(mesh.edges(), expected.into_iter().collect::<Vec<_>>());
        prop_assert_eq!(springs.tetrahedra(), mesh.tetrahedra());
    }

    #[test]
    fn bending_pairs_are_not_edges_on_a_grid(mesh in tri_mesh(6)) {
        // On a grid triangulation the two vertices opposite an interior edge are never joined by an
        // edge themselves (they are the far corners of a cell, or two cells apart).
        let edges = edges_of(mesh.triangles());
        let pairs = mesh.bending_pairs();
        prop_assert!(pairs.iter().all(|p| !edges.contains(p)));
        let springs =
            SpringMesh::from_triangles(&mesh, 1.0, Bending::InteriorEdges, MassModel::Uniform { total: 1.0 })
                .unwrap();
        prop_assert_eq!(springs.springs().len(), edges.len() + pairs.len());
        let set = spring_set(&springs)?;
        prop_assert!(pairs.iter().all(|p| set.contains(p)));
    }

    #[test]
    fn surface_masses_sum_to_the_total(mesh in tri_mesh(6), model in mass_model()) {
        let springs = SpringMesh::from_triangles(&mesh, 1.0, Bending::None, model).unwrap();
        let area: f64 = mesh.areas().iter().sum();
        check_masses(springs.masses(), model, area, true)?;
    }

    #[test]
    fn volume_masses_sum_to_the_total(mesh in tet_mesh(3), model in mass_model()) {
        let springs = SpringMesh::from_tetrahedra(&mesh, 1.0, model).unwrap();
        let volume: f64 = mesh.volumes().iter().sum();
        check_masses(springs.masses(), model, volume, false)?;
    }

    #[test]
    fn generated_spring_meshes_are_valid(mesh in spring_mesh_3d(3)) {
        // Rebuilding through the validating constructor must succeed, and rest lengths match the
        // initial distances (relative 1e-12: one subtraction and one norm, a few ε).
        prop_assert!(SpringMesh::new(mesh.positions().to_vec(), mesh.masses().to_vec(), mesh.springs().to_vec()).is_ok());
        for s in mesh.springs() {
            let d = (mesh.positions()[s.i as usize] - mesh.positions()[s.j as usize]).norm();
            prop_assert!((d - s.rest_length).abs() <= 1e-12 * s.rest_length);
        }
        let set = spring_set(&mesh)?;
        prop_assert!(!set.is_empty());
    }

    #[test]
    fn cloth_strategy_matches_its_formula(mesh in cloth_mesh(2..=12, 1.0..=1e4)) {
        let n = (mesh.vertex_count() as f64).sqrt().round() as usize;
        prop_assert_eq!(n * n, mesh.vertex_count());
        prop_assert_eq!(mesh.springs().len(), cloth_spring_count(n));
        spring_set(&mesh)?;
    }
}

#[test]
fn cloth_spring_counts_follow_the_formula() {
    for n in 2..=30 {
        let mesh = cloth(n, 1e3).unwrap();
        assert_eq!(mesh.springs().len(), cloth_spring_count(n), "cloth-{n}");
        let unique: BTreeSet<[u32; 2]> = mesh.springs().iter().map(|s| key([s.i, s.j])).collect();
        assert_eq!(
            unique.len(),
            mesh.springs().len(),
            "cloth-{n} repeats a spring"
        );
        // Uniform 1 kg: the sum of n² equal shares is 1 within n²·ε (≤ 2e-13 for n = 30).
        assert!(
            (mesh.total_mass() - 1.0).abs() <= SUM_TOLERANCE,
            "cloth-{n}"
        );
    }
}

#[test]
fn beam_volume_is_four_cubic_metres() {
    for r in 1..=3 {
        let mesh: TetMesh = beam_tet_mesh(r).unwrap();
        let volume: f64 = mesh.volumes().iter().sum();
        // 24 R³ tetrahedra of exactly representable corners (multiples of 1/R; for R = 3 the corners
        // are rounded, by at most ε relative): each volume is off by a few ε, the sum by n·ε·4.
        assert!(
            (volume - 4.0).abs() <= SUM_TOLERANCE * 4.0,
            "R = {r}: {volume}"
        );
    }
}

#[test]
fn grid_meshes_have_the_expected_counts() {
    // A deterministic sanity check of the strategies' shapes: a tri_mesh of c_x × c_y cells has
    // (c_x + 1)(c_y + 1) vertices and 2 c_x c_y triangles; check through Euler's formula for a disc:
    // V − E + F = 1.
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    runner
        .run(&tri_mesh(5), |mesh: TriMesh| {
            let v = mesh.positions().len() as i64;
            let e = mesh.edges().len() as i64;
            let f = mesh.triangles().len() as i64;
            prop_assert_eq!(v - e + f, 1);
            Ok(())
        })
        .unwrap();
}
