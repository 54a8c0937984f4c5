//! hooke's proptest strategies (`hooke::mesh::proptest_support`, feature `proptest-support` of
//! `hooke-mesh`) in a user's own property test: random valid cloth meshes and perturbed states,
//! checking a property of the user's code, here a total spring energy written by hand against
//! hooke's per-spring energy and its sign.
//!
//! In your crate: `[dev-dependencies] hooke-mesh = { version = "0.1", features =
//! ["proptest-support"] }` and `proptest = "1"`. `cargo test` runs this example's properties.

use hooke::mesh::SpringMesh;
use nalgebra::Vector3;

/// The user's code under test: the total elastic energy ½ Σ k (|x_i − x_j| − l)² (J).
fn total_spring_energy(mesh: &SpringMesh<3>, x: &[Vector3<f64>]) -> f64 {
    mesh.springs()
        .iter()
        .map(|s| {
            let stretch = (x[s.i as usize] - x[s.j as usize]).norm() - s.rest_length;
            0.5 * s.stiffness * stretch * stretch
        })
        .sum()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mesh = hooke::mesh::generators::cloth(10, 1e3)?;
    let energy = total_spring_energy(&mesh, mesh.positions());
    println!("cloth-10 at rest: {energy} J; `cargo test --example proptest_user_test` checks more");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use hooke::assembly::spring;
    use hooke::mesh::proptest_support::{cloth_mesh, perturbed_positions};
    use proptest::prelude::*;

    /// A cloth mesh with a perturbed copy of its rest positions (up to 5 cm per coordinate).
    fn mesh_and_state() -> impl Strategy<Value = (SpringMesh<3>, Vec<Vector3<f64>>)> {
        cloth_mesh(2..=8, 1e1..=1e4).prop_flat_map(|mesh| {
            let rest = mesh.positions().to_vec();
            (Just(mesh), perturbed_positions(rest, 0.05))
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        #[test]
        fn the_energy_is_zero_at_rest_and_matches_hookes_springs((mesh, x) in mesh_and_state()) {
            prop_assert_eq!(total_spring_energy(&mesh, mesh.positions()), 0.0);
            let ours = total_spring_energy(&mesh, &x);
            let hookes: f64 = mesh
                .springs()
                .iter()
                .map(|s| {
                    spring::energy(s.stiffness, s.rest_length, &(x[s.i as usize] - x[s.j as usize]))
                })
                .sum();
            prop_assert!(ours >= 0.0);
            // The same terms in the same order: equal to the last bit.
            prop_assert_eq!(ours.to_bits(), hookes.to_bits(), "{} against {}", ours, hookes);
        }
    }
}
