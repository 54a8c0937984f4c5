//! Isosurface stuffing: the output's validity and quality over generated closed surfaces (icospheres,
//! tori, boxes under random rotations, scalings and translations) and the data meshes; the volume's
//! convergence; the surface checks' typed errors; determinism across thread counts; no panics on
//! garbage input.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use hooke_mesh::io::{parse_obj, read_obj};
use hooke_mesh::stuffing::{
    dihedral_angles, tetrahedralize, tetrahedralize_graded, ClosedSurface, Stuffed, StuffingError,
    StuffingOptions, MAX_DIHEDRAL_BOUND_DEG, MIN_DIHEDRAL_BOUND_DEG,
};
use hooke_mesh::{tetrahedron_signed_volume, TriMesh, Vec3};
use nalgebra::{Rotation3, Unit};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Surfaces made here.

/// An icosphere of radius `r`: the icosahedron with every triangle split in four `level` times and
/// the vertices pushed onto the sphere. Outward-oriented.
fn icosphere(level: usize, r: f64) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5.0_f64.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::new(p[0], p[1], p[2]).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::new();
        let mut mid = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push(((positions[a as usize] + positions[b as usize]) * 0.5).normalize());
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(4 * triangles.len());
        for &[a, b, c] in &triangles {
            let (ab, bc, ca) = (
                mid(a, b, &mut positions),
                mid(b, c, &mut positions),
                mid(c, a, &mut positions),
            );
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    (positions.into_iter().map(|p| p * r).collect(), triangles)
}

/// A torus about the z axis: tube radius `r` around a circle of radius `big_r`, `n` × `m` quads.
fn torus(big_r: f64, r: f64, n: usize, m: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut positions = Vec::with_capacity(n * m);
    for i in 0..n {
        let u = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
        for j in 0..m {
            let v = 2.0 * std::f64::consts::PI * j as f64 / m as f64;
            let ring = big_r + r * v.cos();
            positions.push(Vec3::new(ring * u.cos(), ring * u.sin(), r * v.sin()));
        }
    }
    let id = |i: usize, j: usize| ((i % n) * m + (j % m)) as u32;
    let mut triangles = Vec::with_capacity(2 * n * m);
    for i in 0..n {
        for j in 0..m {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    (positions, triangles)
}

/// A box of sides `size`, centred at the origin, each face split in two triangles.
fn cuboid(size: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let positions = (0..8)
        .map(|c| {
            Vec3::new(
                ((c & 1) as f64 - 0.5) * size.x,
                (((c >> 1) & 1) as f64 - 0.5) * size.y,
                ((c >> 2) as f64 - 0.5) * size.z,
            )
        })
        .collect();
    let triangles = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (positions, triangles)
}

fn transformed(
    (positions, triangles): (Vec<Vec3>, Vec<[u32; 3]>),
    rotation: &Rotation3<f64>,
    scale: f64,
    shift: Vec3,
) -> TriMesh {
    let positions = positions
        .iter()
        .map(|p| rotation * p * scale + shift)
        .collect();
    TriMesh::new(positions, triangles).expect("generated surface is valid")
}

fn surface(mesh: &TriMesh) -> ClosedSurface {
    ClosedSurface::new(mesh).expect("generated surface is closed and manifold")
}

fn data_mesh(name: &str) -> TriMesh {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/meshes")
        .join(name);
    read_obj(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn diagonal(surface: &ClosedSurface) -> f64 {
    let [lo, hi] = surface.bounds();
    (hi - lo).norm()
}

// ---------------------------------------------------------------------------------------------
// The properties every output must have.

/// Checks everything the mesher promises of a stuffed mesh, with messages that say what failed.
/// `volume_tolerance` is the allowed relative volume error, or `None` where the spacing is too coarse
/// for the 2 % promise.
fn assert_valid(
    surface: &ClosedSurface,
    stuffed: &Stuffed,
    spacing: f64,
    volume_tolerance: Option<f64>,
) {
    assert_valid_with(surface, stuffed, spacing, volume_tolerance, true);
}

/// As [`assert_valid`]; `smooth` asks for the two-sided Hausdorff bound (half a spacing),
/// which sharp edges and corners (that the mesh bevels) and gaps narrower than the spacing (that it
/// bridges) do not meet: for them the one-sided bound (boundary to surface) is asserted.
fn assert_valid_with(
    surface: &ClosedSurface,
    stuffed: &Stuffed,
    spacing: f64,
    volume_tolerance: Option<f64>,
    smooth: bool,
) {
    let mesh = &stuffed.mesh;
    let positions = mesh.positions();
    let scale = spacing;
    for (t, tet) in mesh.tetrahedra().iter().enumerate() {
        let [a, b, c, d] = tet.map(|v| &positions[v as usize]);
        let volume = tetrahedron_signed_volume(a, b, c, d);
        // Positive, and not a sliver lost in round-off: the smallest output tetrahedra are a
        // fraction of h³, far above 1e-12·h³.
        assert!(
            volume > 1e-12 * scale.powi(3),
            "tetrahedron {t} has volume {volume:e}"
        );
        for angle in dihedral_angles(a, b, c, d) {
            let degrees = angle.to_degrees();
            assert!(
                (MIN_DIHEDRAL_BOUND_DEG..=MAX_DIHEDRAL_BOUND_DEG).contains(&degrees),
                "tetrahedron {t} {tet:?} has a dihedral angle of {degrees}°, outside [{MIN_DIHEDRAL_BOUND_DEG}°, {MAX_DIHEDRAL_BOUND_DEG}°]"
            );
        }
    }
    // Every face in one or two tetrahedra.
    let mut faces: Vec<[u32; 3]> = mesh
        .tetrahedra()
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, b, d], [a, c, d], [b, c, d]])
        .map(|mut f| {
            f.sort_unstable();
            f
        })
        .collect();
    faces.sort_unstable();
    let mut run = 1;
    for w in faces.windows(2) {
        if w[0] == w[1] {
            run += 1;
            assert!(
                run <= 2,
                "face {:?} is shared by more than two tetrahedra",
                w[0]
            );
        } else {
            run = 1;
        }
    }
    // The boundary faces form a closed, consistently oriented manifold (the surface checks say so).
    let boundary =
        TriMesh::new(positions.to_vec(), mesh.boundary_faces()).expect("boundary faces are valid");
    let closed = ClosedSurface::new(&boundary)
        .unwrap_or_else(|e| panic!("the boundary is not a closed manifold: {e}"));
    assert!(!closed.was_inside_out(), "the boundary faces point inward");
    // Boundary on the surface. Every boundary vertex is a cut point or a warped lattice vertex, both
    // computed on the surface: held to round-off (1e-9 of the spacing). Every other point of a
    // boundary triangle is then within the distance to its nearest corner, at most (longest edge)/√3
    // (the centroid of an equilateral triangle is the worst case), which bounds the one-sided
    // distance for any surface, creased or not; on a smooth surface it is below half a spacing.
    for (i, p) in samples(&boundary).into_iter().enumerate() {
        let distance = surface.signed_distance(&p).abs();
        let triangle = &boundary.triangles()[i / 7];
        let [a, b, c] = triangle.map(|v| positions[v as usize]);
        let longest = (a - b).norm().max((b - c).norm()).max((c - a).norm());
        let bound = if i % 7 < 3 {
            1e-9 * spacing
        } else {
            longest / 3.0_f64.sqrt()
        };
        assert!(
            distance <= bound,
            "boundary point {p:?} is {distance} from the surface (bound {bound}, spacing {spacing})"
        );
    }
    // The two-sided bound, surface to boundary as well, for smooth surfaces resolved by the
    // lattice: creases and corners are bevelled and gaps narrower than a spacing bridged, so there
    // the surface lies farther from the boundary.
    if smooth {
        let hausdorff = hooke_mesh::stuffing::hausdorff_distance(mesh, surface);
        assert!(
            hausdorff <= 0.5 * spacing,
            "Hausdorff distance {hausdorff} exceeds half the spacing {spacing}"
        );
    }
    if let Some(tolerance) = volume_tolerance {
        let error =
            (stuffed.report.volume - surface.enclosed_volume()).abs() / surface.enclosed_volume();
        assert!(
            error <= tolerance,
            "volume off by {:.3} % (tolerance {:.1} %)",
            100.0 * error,
            100.0 * tolerance
        );
    }
    assert_eq!(stuffed.report.tets, mesh.tetrahedra().len());
    assert!(stuffed.report.min_dihedral_deg >= MIN_DIHEDRAL_BOUND_DEG);
    assert!(stuffed.report.max_dihedral_deg <= MAX_DIHEDRAL_BOUND_DEG);
}

/// Corners, edge midpoints and centroids of a triangle mesh's triangles.
fn samples(mesh: &TriMesh) -> Vec<Vec3> {
    let p = mesh.positions();
    let mut points = Vec::with_capacity(7 * mesh.triangles().len());
    for t in mesh.triangles() {
        let [a, b, c] = t.map(|v| p[v as usize]);
        points.extend([
            a,
            b,
            c,
            (a + b) * 0.5,
            (b + c) * 0.5,
            (c + a) * 0.5,
            (a + b + c) / 3.0,
        ]);
    }
    points
}

fn stuff(surface: &ClosedSurface, spacing: f64) -> Stuffed {
    tetrahedralize(
        surface,
        &StuffingOptions::new(spacing).expect("positive spacing"),
    )
    .unwrap_or_else(|e| panic!("stuffing at spacing {spacing}: {e}"))
}

fn rotation() -> impl Strategy<Value = Rotation3<f64>> {
    (
        -1.0..1.0f64,
        -1.0..1.0f64,
        -1.0..1.0f64,
        0.0..std::f64::consts::TAU,
    )
        .prop_map(|(x, y, z, angle)| {
            let axis = Vec3::new(x, y, z);
            if axis.norm() < 1e-3 {
                Rotation3::identity()
            } else {
                Rotation3::from_axis_angle(&Unit::new_normalize(axis), angle)
            }
        })
}

fn placement() -> impl Strategy<Value = (Rotation3<f64>, f64, Vec3)> {
    (
        rotation(),
        0.01..100.0f64,
        -10.0..10.0f64,
        -10.0..10.0f64,
        -10.0..10.0f64,
    )
        .prop_map(|(r, s, x, y, z)| (r, s, Vec3::new(x, y, z) * s))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// Icospheres of 1 to 3 subdivisions, anywhere, at spacings from coarse to below 1/20 of the box.
    #[test]
    fn icospheres_are_filled_within_the_bounds(
        level in 1usize..4,
        (rotation, scale, shift) in placement(),
        fraction in 0.03..0.2f64,
    ) {
        let s = surface(&transformed(icosphere(level, 1.0), &rotation, scale, shift));
        let spacing = fraction * diagonal(&s);
        let stuffed = stuff(&s, spacing);
        let tolerance = (fraction < 0.05 / 3.0_f64.sqrt()).then_some(0.02);
        assert_valid(&s, &stuffed, spacing, tolerance);
    }

    /// Tori (genus 1) with tube radii from thick to thin.
    #[test]
    fn tori_are_filled_within_the_bounds(
        tube in 0.2..0.6f64,
        (rotation, scale, shift) in placement(),
        fraction in 0.025..0.1f64,
    ) {
        let s = surface(&transformed(torus(1.0, tube, 32, 16), &rotation, scale, shift));
        // The tube must be resolved (at most half its radius per spacing): a tube under 1.5 spacings
        // thick is bridged by boundary faces up to 0.6 spacing from the surface.
        let spacing = (fraction * diagonal(&s)).min(0.5 * tube * scale);
        assert_valid(&s, &stuff(&s, spacing), spacing, None);
    }

    /// Boxes of any proportions: sharp edges and corners, flat faces that lattice planes may touch.
    /// A box thinner than two spacings is not resolved by the lattice: vertices from both of its
    /// faces are warped onto it, and where the boundary would pinch the mesher refuses with
    /// `UnresolvedFeature`, or with `NoTetrahedra` where every lattice vertex inside it is warped
    /// onto its faces (a vertex deeper than 0.36 spacing from both faces is never violated, so
    /// this needs a box thinner than about 1.3 spacings; the warping never moves a vertex toward
    /// one that is warped too, and in such a plate that can leave no inside vertex, where the old
    /// index-order warping kept some by doing exactly that); a resolved box must always be filled.
    #[test]
    fn boxes_are_filled_within_the_bounds(
        sides in (0.3..3.0f64, 0.3..3.0f64, 0.3..3.0f64),
        (rotation, scale, shift) in placement(),
        fraction in 0.02..0.1f64,
    ) {
        let s = surface(&transformed(cuboid(Vec3::new(sides.0, sides.1, sides.2)), &rotation, scale, shift));
        let spacing = fraction * diagonal(&s);
        let thinnest = sides.0.min(sides.1).min(sides.2) * scale;
        match tetrahedralize(&s, &StuffingOptions::new(spacing).expect("positive spacing")) {
            Ok(stuffed) => assert_valid_with(&s, &stuffed, spacing, None, false),
            Err(StuffingError::UnresolvedFeature { point, .. }) => {
                prop_assert!(
                    thinnest < 2.0 * spacing,
                    "a box {thinnest} thick is refused at spacing {spacing} (near {point:?})"
                );
                let distance = s.signed_distance(&Vec3::from(point)).abs();
                prop_assert!(distance <= 1e-9 * spacing, "the pinch {point:?} is off the surface");
            }
            Err(StuffingError::NoTetrahedra { .. }) => {
                prop_assert!(
                    thinnest < 2.0 * spacing,
                    "a box {thinnest} thick gives no tetrahedra at spacing {spacing}"
                );
            }
            Err(e) => panic!("stuffing at spacing {spacing}: {e}"),
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 8, ..ProptestConfig::default() })]

    /// Graded meshes of boxes anywhere (flat faces and sharp corners that the octree's cubes may
    /// touch or nearly touch, so that the finest cubes' extent is tested where it is tightest): valid, within the bounds, with the uniform mesh's boundary, and no more
    /// tetrahedra. Boxes at least three spacings thick (the thin ones are the uniform test's).
    #[test]
    fn graded_boxes_are_valid_and_share_the_uniform_boundary(
        sides in (0.5..3.0f64, 0.5..3.0f64, 0.5..3.0f64),
        (rotation, scale, shift) in placement(),
        fraction in 0.02..0.06f64,
    ) {
        let s = surface(&transformed(cuboid(Vec3::new(sides.0, sides.1, sides.2)), &rotation, scale, shift));
        let spacing = fraction * diagonal(&s);
        prop_assume!(sides.0.min(sides.1).min(sides.2) * scale >= 3.0 * spacing);
        let options = StuffingOptions::new(spacing).expect("positive spacing");
        let graded = tetrahedralize_graded(&s, &options)
            .unwrap_or_else(|e| panic!("graded stuffing at spacing {spacing}: {e}"));
        let uniform = stuff(&s, spacing);
        assert_valid_with(&s, &graded, spacing, None, false);
        prop_assert_eq!(boundary_geometry(&graded), boundary_geometry(&uniform));
        prop_assert!(graded.report.tets <= uniform.report.tets);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]

    /// Graded meshes of tori anywhere (curved surfaces that cross the octree's coarse cubes at any
    /// angle, so that the rule keeping transition tetrahedra uncut and the bound check on warped
    /// ones meet many configurations): valid, within the bounds, with the uniform mesh's boundary
    /// and volume, and no more tetrahedra.
    #[test]
    fn graded_tori_are_valid_and_share_the_uniform_boundary(
        tube in 0.3..0.6f64,
        (rotation, scale, shift) in placement(),
        fraction in 0.02..0.05f64,
    ) {
        let s = surface(&transformed(torus(1.0, tube, 32, 16), &rotation, scale, shift));
        let spacing = (fraction * diagonal(&s)).min(0.5 * tube * scale);
        let options = StuffingOptions::new(spacing).expect("positive spacing");
        let graded = tetrahedralize_graded(&s, &options)
            .unwrap_or_else(|e| panic!("graded stuffing at spacing {spacing}: {e}"));
        let uniform = stuff(&s, spacing);
        assert_valid_with(&s, &graded, spacing, None, false);
        prop_assert_eq!(boundary_geometry(&graded), boundary_geometry(&uniform));
        // Same region: equal volumes up to round-off in the sums (1e-9 relative).
        prop_assert!((graded.report.volume - uniform.report.volume).abs() <= 1e-9 * uniform.report.volume);
        prop_assert!(graded.report.tets <= uniform.report.tets);
    }
}

/// The torus that `tori_are_filled_within_the_bounds` shrank to (tetrahedralize.proptest-regressions)
/// when the bounds were wrongly taken as 10.7°–164.8°: its 10.28° tetrahedron is legal for the
/// thresholds in use, whose proven bounds are 9.3171°–161.6432°.
#[test]
fn shrunk_torus_is_filled_within_the_bounds() {
    // The rotation as proptest printed it: nalgebra's column-major storage, each inner array a
    // column.
    let columns = [
        0.2669948592167069,
        -0.6741261404797939,
        -0.6886709605273539,
        0.7473637649323109,
        -0.306312614708956,
        0.5895930672390614,
        -0.608408701464774,
        -0.6721060398419135,
        0.4220335569477476,
    ];
    let rotation = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_column_slice(&columns));
    let (tube, scale, shift, fraction) =
        (0.5518670441040747, 0.01, Vec3::zeros(), 0.08806938445694196);
    let s = surface(&transformed(
        torus(1.0, tube, 32, 16),
        &rotation,
        scale,
        shift,
    ));
    let spacing = (fraction * diagonal(&s)).min(0.5 * tube * scale);
    let stuffed = stuff(&s, spacing);
    assert!(stuffed.report.min_dihedral_deg >= MIN_DIHEDRAL_BOUND_DEG);
    assert_valid(&s, &stuffed, spacing, None);
}

/// Axis-aligned boxes whose faces lie exactly on lattice planes: the degenerate case where lattice
/// vertices sit on the surface.
#[test]
fn lattice_aligned_box_is_filled_within_the_bounds() {
    let s = surface(
        &TriMesh::new(
            cuboid(Vec3::new(1.0, 1.0, 1.0)).0,
            cuboid(Vec3::new(1.0, 1.0, 1.0)).1,
        )
        .unwrap(),
    );
    for spacing in [0.1, 0.125, 1.0 / 7.0] {
        let stuffed = stuff(&s, spacing);
        assert_valid_with(&s, &stuffed, spacing, Some(0.02), false);
    }
}

#[test]
fn data_meshes_are_filled_within_the_bounds() {
    // (mesh, spacing as a fraction of the diagonal, smooth enough for the two-sided bound). The
    // bunny's ears and the armadillo's fingers are thinner than these spacings and are bevelled
    // (two-sided distance measured 1.2 h and 1.9–2.7 h), so they get the one-sided bound. The
    // armadillo at diagonal/30 loses 4.5 % of its volume in those features: it is tested from /60.
    for (name, divisions, smooth) in [
        ("bunny.obj", 30.0, false),
        ("torus.obj", 30.0, true),
        ("sphere_642.obj", 30.0, true),
        ("cube.obj", 30.0, false),
        ("armadillo.obj", 60.0, false),
    ] {
        let s = surface(&data_mesh(name));
        let spacing = diagonal(&s) / divisions;
        let stuffed = stuff(&s, spacing);
        let error = stuffed.report.volume / s.enclosed_volume() - 1.0;
        eprintln!(
            "{name} at diagonal/{divisions}: {} tetrahedra, volume {:+.2} %, hausdorff {:.3} h",
            stuffed.report.tets,
            100.0 * error,
            hooke_mesh::stuffing::hausdorff_distance(&stuffed.mesh, &s) / spacing,
        );
        assert_valid_with(&s, &stuffed, spacing, Some(0.02), smooth);
    }
}

/// The volume of a fine icosphere (level 5, whose own volume is within 0.06 % of the sphere's)
/// converges as the spacing halves; the rate is about 2 (the boundary interpolates the surface
/// linearly).
#[test]
fn sphere_volume_converges_at_second_order() {
    let r = 1.0;
    let s = surface(&TriMesh::new(icosphere(5, r).0, icosphere(5, r).1).unwrap());
    let sphere = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let polyhedron = s.enclosed_volume();
    assert!(
        (polyhedron - sphere).abs() / sphere < 6e-4,
        "the icosphere is {polyhedron}, the sphere {sphere}"
    );
    let errors: Vec<f64> = [0.4, 0.2, 0.1]
        .iter()
        .map(|&h| (stuff(&s, h * r).report.volume - polyhedron).abs() / polyhedron)
        .collect();
    let rates: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    eprintln!("sphere volume errors at h = 0.4, 0.2, 0.1 r: {errors:?}; rates {rates:?}");
    // A second-order method's observed rates scatter around 2 at these few cells; 1.5 tells it from
    // first order.
    for rate in &rates {
        assert!(*rate > 1.5, "convergence rate {rate} (errors {errors:?})");
    }
    assert!(errors[2] < 0.01);
}

// ---------------------------------------------------------------------------------------------
// The graded variant.

/// The boundary triangles of a mesh as sorted coordinate triples (bit patterns), so that two meshes
/// numbered differently can be compared.
fn boundary_geometry(stuffed: &Stuffed) -> Vec<[[u64; 3]; 3]> {
    let p = stuffed.mesh.positions();
    let mut out: Vec<[[u64; 3]; 3]> = stuffed
        .mesh
        .boundary_faces()
        .iter()
        .map(|f| {
            let mut t = f.map(|v| {
                let q = p[v as usize];
                [q.x.to_bits(), q.y.to_bits(), q.z.to_bits()]
            });
            t.sort_unstable();
            t
        })
        .collect();
    out.sort_unstable();
    out
}

/// Graded meshes pass every check of the uniform ones (orientation, the row's angle bounds, faces,
/// a closed manifold boundary on the surface, volume), have the uniform mesh's boundary at the
/// same spacing (the grid is the uniform lattice's BCC tetrahedra wherever it is cut or warped
/// around a cut, and the cut points and warps are the uniform mesher's), and fewer tetrahedra by
/// at least the case's factor. The counts are deterministic; measured: sphere 2.93× (40 spacings
/// across, room to grade), torus 2.02× (its tube is 17 spacings thick), bunny at 1/40 of its
/// diagonal 1.50× (ears and paws are nearly all finest). With the former band of finest cubes
/// (every coarse cube within 0.857 spacings of the surface split) they were 2.47×, 1.64× and 1.27×.
#[test]
fn graded_meshes_are_valid_and_share_the_uniform_boundary() {
    let cases = [
        (
            surface(&TriMesh::new(icosphere(4, 1.0).0, icosphere(4, 1.0).1).unwrap()),
            0.05,
            true,
            2.9,
        ),
        (
            surface(&transformed(
                torus(1.0, 0.5, 48, 24),
                &Rotation3::from_euler_angles(0.3, 0.2, 0.1),
                1.0,
                Vec3::zeros(),
            )),
            0.06,
            true,
            2.0,
        ),
        (surface(&data_mesh("bunny.obj")), 0.0, false, 1.5),
    ];
    for (s, spacing, smooth, factor) in cases {
        let spacing = if spacing > 0.0 {
            spacing
        } else {
            diagonal(&s) / 40.0
        };
        let options = StuffingOptions::new(spacing).unwrap();
        let graded = tetrahedralize_graded(&s, &options)
            .unwrap_or_else(|e| panic!("graded stuffing at spacing {spacing}: {e}"));
        let uniform = stuff(&s, spacing);
        eprintln!(
            "graded {} tetrahedra ({:.2}°–{:.2}°) against uniform {} at spacing {spacing}",
            graded.report.tets,
            graded.report.min_dihedral_deg,
            graded.report.max_dihedral_deg,
            uniform.report.tets
        );
        assert_valid_with(&s, &graded, spacing, Some(0.02), smooth);
        assert_eq!(boundary_geometry(&graded), boundary_geometry(&uniform));
        // Both fill the same region: equal volumes up to round-off in the sums (1e-9 relative).
        assert!(
            (graded.report.volume - uniform.report.volume).abs() <= 1e-9 * uniform.report.volume
        );
        assert!(
            graded.report.tets as f64 * factor <= uniform.report.tets as f64,
            "graded {} tetrahedra, not {factor}× fewer than uniform {}",
            graded.report.tets,
            uniform.report.tets
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Surface checks.

fn closed_surface(
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
) -> Result<ClosedSurface, StuffingError> {
    ClosedSurface::new(&TriMesh::new(positions, triangles)?)
}

#[test]
fn open_surface_names_its_edge() {
    let (p, mut t) = icosphere(1, 1.0);
    let removed = t.remove(7);
    match closed_surface(p, t) {
        Err(StuffingError::OpenEdge { a, b, .. }) => {
            assert!(
                removed.contains(&(a as u32)) && removed.contains(&(b as u32)),
                "edge {a}–{b} is not the hole's"
            );
        }
        other => panic!("expected OpenEdge, got {other:?}"),
    }
}

#[test]
fn non_manifold_edge_names_its_edge() {
    let (mut p, mut t) = icosphere(1, 1.0);
    let [a, b, _] = t[0];
    p.push(Vec3::new(3.0, 3.0, 3.0));
    t.push([b, a, p.len() as u32 - 1]);
    match closed_surface(p, t) {
        Err(StuffingError::NonManifoldEdge {
            a: x,
            b: y,
            count,
            triangle,
        }) => {
            assert_eq!((x.min(y), x.max(y)), (a.min(b) as usize, a.max(b) as usize));
            assert_eq!(count, 3);
            assert_eq!(triangle, 0);
        }
        other => panic!("expected NonManifoldEdge, got {other:?}"),
    }
}

#[test]
fn inconsistent_orientation_names_its_triangles() {
    let (p, mut t) = icosphere(1, 1.0);
    t[5].swap(1, 2);
    match closed_surface(p, t) {
        Err(StuffingError::InconsistentOrientation { first, second, .. }) => {
            assert!(first == 5 || second == 5, "triangles {first} and {second}");
        }
        other => panic!("expected InconsistentOrientation, got {other:?}"),
    }
}

/// Two cubes that share only a corner: every edge is in two triangles, but the corner's triangles
/// form two fans. No spacing resolves it, and the message says what it is.
#[test]
fn bowtie_vertex_is_named() {
    let (mut p, mut t) = cuboid(Vec3::new(1.0, 1.0, 1.0));
    // The second cube, shifted by (1, 1, 1), reuses corner 7 (0.5, 0.5, 0.5) as its corner 0.
    let (q, u) = cuboid(Vec3::new(1.0, 1.0, 1.0));
    let offset = p.len() as u32;
    p.extend(q.iter().map(|x| x + Vec3::new(1.0, 1.0, 1.0)));
    t.extend(u.iter().map(|f| f.map(|v| v + offset)));
    match closed_surface(p, t) {
        Err(e @ StuffingError::NonManifoldVertex { vertex, fans, .. }) => {
            // Corner 7 and its bit-identical copy (the second cube's corner 0) are one vertex.
            assert_eq!((vertex, fans), (7, 2));
            assert!(e.to_string().contains("non-manifold vertex"), "{e}");
        }
        other => panic!("expected NonManifoldVertex, got {other:?}"),
    }
}

/// Two overlapping spheres in one mesh: closed and manifold, but self-intersecting. Refused by name
/// (not as a feature thinner than the spacing), naming two triangles that do intersect.
#[test]
fn self_intersecting_surface_is_named() {
    let (p, t) = icosphere(2, 1.0);
    let mut positions: Vec<Vec3> = p.clone();
    positions.extend(p.iter().map(|q| q + Vec3::new(0.7, 0.1, 0.05)));
    let offset = p.len() as u32;
    let mut triangles = t.clone();
    triangles.extend(t.iter().map(|f| f.map(|v| v + offset)));
    match closed_surface(positions, triangles.clone()) {
        Err(e @ StuffingError::SelfIntersecting { first, second }) => {
            assert!(e.to_string().contains("self-intersecting"), "{e}");
            assert!(first < second);
            // One triangle of each sphere.
            assert!(first < t.len() && second >= t.len(), "{first}, {second}");
        }
        other => panic!("expected SelfIntersecting, got {other:?}"),
    }
}

#[test]
fn empty_and_nan_surfaces_are_refused() {
    assert!(matches!(
        closed_surface(vec![], vec![]),
        Err(StuffingError::Mesh(hooke_mesh::MeshError::Empty))
    ));
    let (mut p, t) = icosphere(1, 1.0);
    p[3].y = f64::NAN;
    assert!(matches!(
        closed_surface(p, t),
        Err(StuffingError::Mesh(
            hooke_mesh::MeshError::NonFiniteCoordinate {
                vertex: 3,
                axis: 1,
                ..
            }
        ))
    ));
}

#[test]
fn bad_spacing_is_refused() {
    for spacing in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            StuffingOptions::new(spacing),
            Err(StuffingError::InvalidParameter {
                name: "spacing",
                ..
            })
        ));
    }
    let s = surface(&TriMesh::new(icosphere(1, 1.0).0, icosphere(1, 1.0).1).unwrap());
    assert!(matches!(
        tetrahedralize(&s, &StuffingOptions::new(1e-9).unwrap()),
        Err(StuffingError::LatticeTooLarge { .. })
    ));
    // Coarser than the solid: nothing inside.
    assert!(matches!(
        tetrahedralize(&s, &StuffingOptions::new(50.0).unwrap()),
        Err(StuffingError::NoTetrahedra { .. })
    ));
}

#[test]
fn inside_out_surface_is_turned_outward() {
    let (p, t) = icosphere(2, 1.0);
    let reversed: Vec<[u32; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
    let outward = surface(&TriMesh::new(p.clone(), t).unwrap());
    let inward = surface(&TriMesh::new(p, reversed).unwrap());
    assert!(!outward.was_inside_out());
    assert!(inward.was_inside_out());
    assert_eq!(inward.enclosed_volume(), outward.enclosed_volume());
    assert_eq!(stuff(&inward, 0.2).mesh, stuff(&outward, 0.2).mesh);
}

/// Two spheres a hair apart (TetGen's known failure): a valid mesh within the bounds.
#[test]
fn nearly_touching_surface_gives_a_valid_mesh() {
    let (p, t) = icosphere(3, 1.0);
    let gap = 1e-6;
    let mut positions: Vec<Vec3> = p
        .iter()
        .map(|q| q - Vec3::x() * (1.0 + gap / 2.0))
        .collect();
    positions.extend(p.iter().map(|q| q + Vec3::x() * (1.0 + gap / 2.0)));
    let offset = p.len() as u32;
    let mut triangles = t.clone();
    triangles.extend(t.iter().map(|f| f.map(|v| v + offset)));
    let s = surface(&TriMesh::new(positions, triangles).unwrap());
    for spacing in [0.1, 0.13] {
        let stuffed = stuff(&s, spacing);
        assert_valid_with(&s, &stuffed, spacing, Some(0.02), false);
    }
}

#[test]
fn one_and_two_threads_give_the_same_mesh() {
    // Both meshers, uniform and graded.
    let s = surface(&data_mesh("bunny.obj"));
    let spacing = diagonal(&s) / 25.0;
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let options = StuffingOptions::new(spacing).unwrap();
                let graded = tetrahedralize_graded(&s, &options).expect("graded bunny");
                (stuff(&s, spacing).mesh, graded.mesh)
            })
    };
    assert_eq!(run(1), run(2));
}

// ---------------------------------------------------------------------------------------------
// Garbage in: a typed error or a valid mesh, never a panic.

const CUBE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n\
f 1 3 2\nf 2 3 4\nf 5 6 7\nf 6 8 7\nf 1 2 5\nf 2 6 5\nf 3 7 4\nf 4 7 8\nf 1 5 3\nf 3 5 7\nf 2 4 6\nf 4 8 6\n";

fn mesh_anything(bytes: &[u8]) {
    let Ok(mesh) = parse_obj(bytes, Path::new("fuzz.obj")) else {
        return;
    };
    let Ok(s) = ClosedSurface::new(&mesh) else {
        return;
    };
    let spacing = diagonal(&s) / 6.0;
    if let Ok(options) = StuffingOptions::new(spacing) {
        let _ = tetrahedralize(&s, &options);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 8, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        mesh_anything(&bytes);
    }

    #[test]
    fn mutated_obj_never_panics(edits in proptest::collection::vec((0usize..CUBE_OBJ.len(), any::<u8>()), 1..6)) {
        let mut bytes = CUBE_OBJ.as_bytes().to_vec();
        for (at, byte) in edits {
            bytes[at] = byte;
        }
        mesh_anything(&bytes);
    }
}
