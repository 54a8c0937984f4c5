//! Quality measures of a tetrahedral mesh: dihedral angles, radius ratio, volume, and the
//! two-sided Hausdorff distance between its boundary and a reference surface.

use parry3d_f64::math::Vector as PVec;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::TriMesh as ParryMesh;

use super::ClosedSurface;
use crate::{tetrahedron_signed_volume, TetMesh, Vec3};

/// The quality of a tetrahedral mesh, and how well it fills its surface.
///
/// Angles are in degrees, lengths in metres, volumes in cubic metres, time in seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QualityReport {
    /// Number of tetrahedra.
    pub tets: usize,
    /// Number of vertices.
    pub vertices: usize,
    /// Smallest dihedral angle over all tetrahedra (°); 70.53° for a regular tetrahedron.
    pub min_dihedral_deg: f64,
    /// Largest dihedral angle over all tetrahedra (°).
    pub max_dihedral_deg: f64,
    /// Smallest radius ratio 3·r_in/r_circ over all tetrahedra: 1 for a regular tetrahedron, 0 for
    /// a flat one.
    pub min_radius_ratio: f64,
    /// Total volume of the tetrahedra (m³).
    pub volume: f64,
    /// Volume enclosed by the reference surface (m³), if there is one.
    pub surface_volume: Option<f64>,
    /// Two-sided Hausdorff distance between the mesh's boundary and the reference surface (m),
    /// sampled at vertices, edge midpoints and triangle centroids of both, if there is a surface.
    pub hausdorff: Option<f64>,
    /// Wall-clock time of the meshing (s), if the mesh was made here; 0 otherwise.
    pub seconds: f64,
}

/// The six dihedral angles of a tetrahedron (radians), at its edges ab, ac, ad, bc, bd, cd.
pub fn dihedral_angles(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> [f64; 6] {
    // At edge pq with the other vertices r, s: the angle between r and s seen along pq.
    let angle = |p: &Vec3, q: &Vec3, r: &Vec3, s: &Vec3| {
        let axis = q - p;
        let axis2 = axis.norm_squared();
        let u = (r - p) - axis * ((r - p).dot(&axis) / axis2);
        let v = (s - p) - axis * ((s - p).dot(&axis) / axis2);
        u.cross(&v).norm().atan2(u.dot(&v))
    };
    [
        angle(a, b, c, d),
        angle(a, c, b, d),
        angle(a, d, b, c),
        angle(b, c, a, d),
        angle(b, d, a, c),
        angle(c, d, a, b),
    ]
}

/// The radius ratio 3·r_in/r_circ of a tetrahedron: 1 when regular, 0 when flat.
pub fn radius_ratio(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> f64 {
    let volume = tetrahedron_signed_volume(a, b, c, d).abs();
    let area = |p: &Vec3, q: &Vec3, r: &Vec3| 0.5 * (q - p).cross(&(r - p)).norm();
    let faces = area(a, b, c) + area(a, b, d) + area(a, c, d) + area(b, c, d);
    let inradius = 3.0 * volume / faces;
    // Circumradius from the products of opposite edge lengths (Crelle's formula).
    let (p, q, r) = (
        (b - a).norm() * (d - c).norm(),
        (c - a).norm() * (d - b).norm(),
        (d - a).norm() * (c - b).norm(),
    );
    let product = (p + q + r) * (p + q - r) * (p - q + r) * (-p + q + r);
    let circumradius = product.max(0.0).sqrt() / (24.0 * volume);
    if circumradius > 0.0 && circumradius.is_finite() {
        3.0 * inradius / circumradius
    } else {
        0.0
    }
}

fn to_parry(p: &Vec3) -> PVec {
    PVec::new(p.x, p.y, p.z)
}

/// Points that stand for a triangle surface: its vertices, edge midpoints and centroids.
fn samples(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut points = positions.to_vec();
    for t in triangles {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        points.extend([
            (a + b) * 0.5,
            (b + c) * 0.5,
            (c + a) * 0.5,
            (a + b + c) / 3.0,
        ]);
    }
    points
}

/// The two-sided Hausdorff distance between a tetrahedral mesh's boundary and a closed surface
/// (m), sampled at the vertices, edge midpoints and centroids of both.
pub fn hausdorff_distance(mesh: &TetMesh, surface: &ClosedSurface) -> f64 {
    let boundary = mesh.boundary_faces();
    let positions = mesh.positions();
    let mut used = vec![false; positions.len()];
    for f in &boundary {
        for &v in f {
            used[v as usize] = true;
        }
    }
    let boundary_points: Vec<Vec3> = positions
        .iter()
        .zip(&used)
        .filter(|(_, &u)| u)
        .map(|(p, _)| *p)
        .collect();
    let mut forward: f64 = 0.0;
    for p in boundary_points
        .iter()
        .chain(samples(positions, &boundary).iter().skip(positions.len()))
    {
        forward = forward.max((surface.closest_point(p) - p).norm());
    }
    let Ok(shape) = ParryMesh::new(positions.iter().map(to_parry).collect(), boundary) else {
        return f64::INFINITY;
    };
    let reference = surface.triangle_mesh();
    let mut backward: f64 = 0.0;
    for p in samples(reference.positions(), reference.triangles()) {
        let projection = shape.project_local_point(to_parry(&p), false);
        let q = Vec3::new(projection.point.x, projection.point.y, projection.point.z);
        backward = backward.max((q - p).norm());
    }
    forward.max(backward)
}

/// The quality report of any tetrahedral mesh; with a `surface`, also its enclosed volume and the
/// Hausdorff distance to it. `seconds` is 0.
pub fn quality_report(mesh: &TetMesh, surface: Option<&ClosedSurface>) -> QualityReport {
    let positions = mesh.positions();
    let mut min_dihedral = f64::INFINITY;
    let mut max_dihedral: f64 = 0.0;
    let mut min_ratio = f64::INFINITY;
    let mut volume = 0.0;
    for t in mesh.tetrahedra() {
        let [a, b, c, d] = t.map(|v| &positions[v as usize]);
        for angle in dihedral_angles(a, b, c, d) {
            min_dihedral = min_dihedral.min(angle);
            max_dihedral = max_dihedral.max(angle);
        }
        min_ratio = min_ratio.min(radius_ratio(a, b, c, d));
        volume += tetrahedron_signed_volume(a, b, c, d).abs();
    }
    QualityReport {
        tets: mesh.tetrahedra().len(),
        vertices: positions.len(),
        min_dihedral_deg: min_dihedral.to_degrees(),
        max_dihedral_deg: max_dihedral.to_degrees(),
        min_radius_ratio: min_ratio,
        volume,
        surface_volume: surface.map(ClosedSurface::enclosed_volume),
        hausdorff: surface.map(|s| hausdorff_distance(mesh, s)),
        seconds: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_tetrahedron_has_known_angles_and_unit_ratio() {
        let [a, b, c, d] = [
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
        ];
        let regular = (1.0_f64 / 3.0).acos();
        for angle in dihedral_angles(&a, &b, &c, &d) {
            assert!((angle - regular).abs() < 1e-12, "{angle} against {regular}");
        }
        assert!((radius_ratio(&a, &b, &c, &d) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn corner_tetrahedron_angles() {
        // The corner of a cube: three right dihedral angles at the corner's edges, and
        // acos(1/√3) = 54.74° at the three edges of the slanted face.
        let o = Vec3::zeros();
        let (x, y, z) = (Vec3::x(), Vec3::y(), Vec3::z());
        let angles = dihedral_angles(&o, &x, &y, &z);
        let slanted = (1.0_f64 / 3.0_f64.sqrt()).acos();
        for (angle, expected) in angles.iter().zip([
            std::f64::consts::FRAC_PI_2,
            std::f64::consts::FRAC_PI_2,
            std::f64::consts::FRAC_PI_2,
            slanted,
            slanted,
            slanted,
        ]) {
            assert!(
                (angle - expected).abs() < 1e-12,
                "{angle} against {expected}"
            );
        }
    }
}
