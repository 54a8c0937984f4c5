//! The fluid scenes of docs/scenes.md §7, and the water-column-in-a-tank builder behind them.

use nalgebra::SVector;

use crate::{FluidParams, FluidSetup, SphError, Walls};

/// Layers of boundary particles behind each wall: the cubic spline's support 2h = 2.6 Δx needs 3.
pub const WALL_LAYERS: usize = 3;
/// Smoothing length over spacing, h = 1.3 Δx (docs/scenes.md §7).
pub const H_OVER_DX: f64 = 1.3;
/// Gravity (m/s²), downwards along y.
pub const GRAVITY: f64 = 9.81;

/// A water column at rest in the corner of a box tank, with walls of boundary particles.
///
/// Particles sit at the centres of a lattice over the tank: along axis a the spacing is
/// `extent_a / round(extent_a / dx)`, which is `dx` wherever the tank's extent is a multiple of it
/// (every axis of the built-in scenes but the 3D tank's 0.5 m width, where Δx = 0.04 gives 13
/// layers 0.03846 m apart). Each particle has mass ρ₀ × the lattice cell's volume.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnInTank<const D: usize> {
    /// Lower corner of the tank's inside (m).
    pub tank_min: SVector<f64, D>,
    /// Upper corner of the tank's inside (m).
    pub tank_max: SVector<f64, D>,
    /// `walls[a] = [lower, upper]`: which faces are solid walls; the others are open (a particle
    /// crossing an open face leaves the domain, which is an error).
    pub walls: [[bool; 2]; D],
    /// Upper corner of the water column (m); its lower corner is `tank_min`.
    pub column_max: SVector<f64, D>,
    /// Lattice spacing Δx (m), > 0.
    pub dx: f64,
    /// Layers of boundary particles behind each wall.
    pub layers: usize,
    /// The fluid's parameters; `smoothing_length` is overwritten with 1.3 Δx and, unless it is
    /// positive already, `sound_speed` with 10·√(2 g H), H the column's height.
    pub params: FluidParams<D>,
}

/// A built scene: the setup and what a run of it needs to know.
#[derive(Debug, Clone, PartialEq)]
pub struct FluidScene<const D: usize> {
    /// The scene's name, e.g. `dam-break-2d`.
    pub name: String,
    /// What the fluid is built from.
    pub setup: FluidSetup<D>,
    /// Lower corner of the tank's inside (m): no fluid particle may leave the tank.
    pub tank_min: SVector<f64, D>,
    /// Upper corner of the tank's inside (m).
    pub tank_max: SVector<f64, D>,
    /// Which faces of the tank are walls, as [`ColumnInTank::walls`].
    pub walls: [[bool; 2]; D],
    /// The column's width L along x (m): the dam break's front is reported as Z = x_front / L.
    pub column_width: f64,
    /// The column's height H (m).
    pub column_height: f64,
    /// The lattice spacing Δx (m).
    pub dx: f64,
    /// Simulated time of a run (s).
    pub end_time: f64,
    /// Frames written over a run (besides the initial one).
    pub frames: usize,
    /// Whether the dam-break front is reported.
    pub dam_break: bool,
}

impl<const D: usize> ColumnInTank<D> {
    /// Builds the particles.
    ///
    /// # Errors
    /// [`SphError::InvalidParameter`] for a spacing that is not positive, a tank or column that is
    /// empty or not finite, a column that sticks out of the tank, or more than 10⁸ particles.
    pub fn build(&self) -> Result<FluidSetup<D>, SphError> {
        let invalid = |name, value, allowed| SphError::InvalidParameter {
            name,
            value,
            allowed,
        };
        if !(self.dx.is_finite() && self.dx > 0.0) {
            return Err(invalid("dx", self.dx, "finite and > 0 (m)"));
        }
        let mut counts = [0i64; D];
        let mut column_counts = [0i64; D];
        let mut spacing = [0.0; D];
        let mut total: f64 = 1.0;
        for a in 0..D {
            let extent = self.tank_max[a] - self.tank_min[a];
            if !(extent.is_finite() && extent > 0.0) {
                return Err(invalid("tank extent", extent, "finite and > 0 (m)"));
            }
            let column = self.column_max[a] - self.tank_min[a];
            if !(column.is_finite() && column > 0.0 && column <= extent * (1.0 + 1e-12)) {
                return Err(invalid(
                    "column extent",
                    column,
                    "> 0 and within the tank (m)",
                ));
            }
            let n = (extent / self.dx).round().max(1.0);
            total *= n + 2.0 * self.layers as f64;
            if total > 1e8 {
                return Err(invalid(
                    "dx",
                    self.dx,
                    "large enough for at most 1e8 lattice sites over the tank and its walls",
                ));
            }
            counts[a] = n as i64;
            spacing[a] = extent / n;
            column_counts[a] = (column / spacing[a]).round().max(1.0) as i64;
        }
        let mut params = self.params;
        params.smoothing_length = H_OVER_DX * self.dx;
        let height = self.column_max[1] - self.tank_min[1];
        if params.sound_speed.is_nan() || params.sound_speed <= 0.0 {
            params.sound_speed = 10.0 * (2.0 * GRAVITY * height).sqrt();
        }
        let volume: f64 = spacing.iter().product();
        let site = |index: &[i64; D]| {
            SVector::<f64, D>::from_fn(|a, _| {
                self.tank_min[a] + (index[a] as f64 + 0.5) * spacing[a]
            })
        };
        let b = params.tait_stiffness();
        let top = self.column_max[1];
        let g = -params.gravity[1];
        // Hydrostatic densities, ρ = ρ₀ (1 + ρ₀ g d / B)^(1/γ) at depth d below the column's top:
        // the continuity method starts in equilibrium with them.
        let hydrostatic = |x: &SVector<f64, D>| {
            let depth = (top - x[1]).max(0.0);
            params.rest_density
                * (1.0 + params.rest_density * g * depth / b).powf(1.0 / params.gamma)
        };

        let mut fluid = Vec::new();
        let mut index = [0i64; D];
        loop {
            fluid.push(site(&index));
            if !odometer(&mut index, &[0; D], &column_counts) {
                break;
            }
        }
        let layers = self.layers as i64;
        let mut boundary = Vec::new();
        let lo = [-layers; D];
        let hi: [i64; D] = std::array::from_fn(|a| counts[a] + layers);
        let mut index = lo;
        loop {
            let mut in_wall = false;
            let mut beyond_open = false;
            for a in 0..D {
                let below = index[a] < 0;
                let above = index[a] >= counts[a];
                if (below && self.walls[a][0]) || (above && self.walls[a][1]) {
                    in_wall = true;
                }
                if (below && !self.walls[a][0]) || (above && !self.walls[a][1]) {
                    beyond_open = true;
                }
            }
            if in_wall && !beyond_open {
                boundary.push(site(&index));
            }
            if !odometer(&mut index, &lo, &hi) {
                break;
            }
        }
        let margin = |a: usize, side: usize| {
            if self.walls[a][side] {
                self.layers as f64 * spacing[a]
            } else {
                0.0
            }
        };
        let domain_min = SVector::<f64, D>::from_fn(|a, _| self.tank_min[a] - margin(a, 0));
        let domain_max = SVector::<f64, D>::from_fn(|a, _| self.tank_max[a] + margin(a, 1));
        Ok(FluidSetup {
            params,
            domain_min,
            domain_max,
            walls: Walls::BoundaryParticles,
            particle_mass: params.rest_density * volume,
            fluid_densities: fluid.iter().map(hydrostatic).collect(),
            fluid_velocities: Vec::new(),
            boundary_densities: boundary.iter().map(hydrostatic).collect(),
            fluid_positions: fluid,
            boundary_positions: boundary,
        })
    }
}

/// Advances `index` over the box [lo, hi) with axis 0 fastest; false after the last.
fn odometer<const D: usize>(index: &mut [i64; D], lo: &[i64; D], hi: &[i64; D]) -> bool {
    for a in 0..D {
        index[a] += 1;
        if index[a] < hi[a] {
            return true;
        }
        index[a] = lo[a];
    }
    false
}

fn vector<const D: usize>(values: [f64; D]) -> SVector<f64, D> {
    SVector::from(values)
}

/// The dam break in 2D (docs/scenes.md §7): a 1 m × 2 m column in the corner of a 4 m × 4 m tank
/// with walls at x = 0, x = 4 and y = 0 (open top), ρ₀ = 1000, c₀ = 10·√(2gH), h = 1.3 Δx, α = 0.1,
/// run to 1 s. Its Δx is 0.02 m (5,000 fluid particles); 0.01 and 0.005 for convergence.
///
/// # Errors
/// As [`ColumnInTank::build`].
pub fn dam_break_2d(dx: f64) -> Result<FluidScene<2>, SphError> {
    column_scene(
        "dam-break-2d",
        vector([0.0, 0.0]),
        vector([4.0, 4.0]),
        [[true, true], [true, false]],
        vector([1.0, 2.0]),
        dx,
        1.0,
        50,
        true,
    )
}

/// The hydrostatic tank (docs/scenes.md §7): the same column in a 1 m wide tank (walls at x = 0,
/// x = 1, y = 0), at rest, run for 2 s.
///
/// # Errors
/// As [`ColumnInTank::build`].
pub fn hydrostatic_2d(dx: f64) -> Result<FluidScene<2>, SphError> {
    column_scene(
        "hydrostatic-2d",
        vector([0.0, 0.0]),
        vector([1.0, 4.0]),
        [[true, true], [true, false]],
        vector([1.0, 2.0]),
        dx,
        2.0,
        40,
        false,
    )
}

/// The dam break in 3D (docs/scenes.md §7): the 2D case extruded to 0.5 m in z, with walls at z = 0
/// and 0.5; its Δx is 0.04 m.
///
/// # Errors
/// As [`ColumnInTank::build`].
pub fn dam_break_3d(dx: f64) -> Result<FluidScene<3>, SphError> {
    column_scene(
        "dam-break-3d",
        vector([0.0, 0.0, 0.0]),
        vector([4.0, 4.0, 0.5]),
        [[true, true], [true, false], [true, true]],
        vector([1.0, 2.0, 0.5]),
        dx,
        1.0,
        50,
        true,
    )
}

/// The built-in fluid scenes: name, its spacing (docs/scenes.md §7) and a description.
pub const BUILTIN: [(&str, f64, &str); 3] = [
    (
        "dam-break-2d",
        0.02,
        "WCSPH dam break, 1 x 2 m column in a 4 x 4 m tank, dx = 0.02 (5,000 particles), 1 s",
    ),
    (
        "hydrostatic-2d",
        0.02,
        "WCSPH water column at rest in a 1 m wide tank, dx = 0.02, 2 s",
    ),
    (
        "dam-break-3d",
        0.04,
        "WCSPH dam break extruded to 0.5 m in z, dx = 0.04, 1 s",
    ),
];

#[allow(clippy::too_many_arguments)]
fn column_scene<const D: usize>(
    name: &str,
    tank_min: SVector<f64, D>,
    tank_max: SVector<f64, D>,
    walls: [[bool; 2]; D],
    column_max: SVector<f64, D>,
    dx: f64,
    end_time: f64,
    frames: usize,
    dam_break: bool,
) -> Result<FluidScene<D>, SphError> {
    let params = FluidParams::<D> {
        sound_speed: 0.0,
        ..FluidParams::default()
    };
    let spec = ColumnInTank {
        tank_min,
        tank_max,
        walls,
        column_max,
        dx,
        layers: WALL_LAYERS,
        params,
    };
    let setup = spec.build()?;
    Ok(FluidScene {
        name: name.to_string(),
        setup,
        tank_min,
        tank_max,
        walls,
        column_width: column_max[0] - tank_min[0],
        column_height: column_max[1] - tank_min[1],
        dx,
        end_time,
        frames,
        dam_break,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dam_break_counts_as_scenes_md() {
        let s = dam_break_2d(0.02).unwrap();
        assert_eq!(s.setup.fluid_positions.len(), 5000);
        assert!((s.setup.particle_mass - 1000.0 * 0.02 * 0.02).abs() < 1e-12);
        assert!((s.setup.params.smoothing_length - 0.026).abs() < 1e-15);
        let c0 = 10.0 * (2.0 * 9.81 * 2.0f64).sqrt();
        assert!((s.setup.params.sound_speed - c0).abs() < 1e-12);
        // Walls: left and right 3 × 200 rows plus the floor's 3 × 206 (corners included).
        assert_eq!(s.setup.boundary_positions.len(), 2 * 3 * 200 + 3 * 206);
        assert_eq!(
            dam_break_2d(0.01).unwrap().setup.fluid_positions.len(),
            20_000
        );
        let s3 = dam_break_3d(0.04).unwrap();
        assert_eq!(s3.setup.fluid_positions.len(), 25 * 50 * 13);
    }

    #[test]
    fn bad_spacing_is_an_error() {
        for dx in [0.0, -0.1, f64::NAN, 1e-7] {
            assert!(dam_break_2d(dx).is_err(), "dx = {dx}");
        }
    }
}
