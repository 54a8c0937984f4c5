//! Fluid scene files: TOML with a `[fluid]` table, a water column in the corner of a box tank.
//!
//! ```toml
//! name = "dam-break-small"      # optional; default the file's stem
//!
//! [fluid]
//! tank = [1.0, 1.0]             # the tank's inside, [0, tank] (m); 2 or 3 numbers (the dimension)
//! column = [0.25, 0.5]          # the water column, [0, column] (m), inside the tank
//! dx = 0.025                    # lattice spacing (m), > 0
//! open_top = true               # optional: no wall at y = tank[1] (default true)
//! h_factor = 1.3                # optional: h = h_factor·dx, in [1, 3] (default 1.3, as the
//!                               # built-in scenes: docs/scenes.md §7)
//! c0 = 31.3                     # optional: speed of sound (m/s), > 0 (default 10·√(2gH))
//! alpha = 0.1                   # optional: Monaghan's artificial viscosity, >= 0 (default 0.1)
//! cfl = 0.4                     # optional: CFL number C, in (0, 1] (default 0.4)
//! force_factor = 0.25           # optional: the force condition's factor, in (0, 1] (default 0.25)
//! gamma = 7.0                   # optional: Tait exponent, >= 1 (default 7)
//! rest_density = 1000.0         # optional: ρ₀ (kg/m^D), > 0 (default 1000)
//! gravity = -9.81               # optional: gravity along y (m/s²), finite (default −9.81)
//! kernel = "cubic-spline"       # optional: cubic-spline or wendland-quintic
//! integrator = "symplectic-euler" # optional: symplectic-euler or leapfrog
//! density = "continuity"        # optional: continuity or summation
//! front = true                  # optional: report the dam-break front (default: column narrower
//!                               # than the tank)
//!
//! [run]                         # optional
//! duration = 0.5                # simulated time (s), > 0 (default 1)
//! frames = 25                   # frames written after the initial one, >= 1 (default 50)
//! ```
//!
//! Walls are three (or, for h_factor > 1.5, ⌈2·h_factor⌉) layers of boundary particles at x = 0,
//! x = tank[0], y = 0, (y = tank[1] unless `open_top`), and in 3D z = 0 and z = tank[2]. Unknown keys
//! and values of the wrong type are errors naming the key (with its line); values out of range are
//! errors naming the key (`[fluid.dx]: …`).

use std::path::Path;

use hooke_sph::scenes::{ColumnInTank, FluidScene, WALL_LAYERS};
use hooke_sph::{DensityMethod, FluidParams, Integrator, KernelKind};
use nalgebra::SVector;
use serde::Deserialize;

use super::run::AnyScene;
use super::SphCliError;

/// Default simulated time of a scene file's run (s).
pub(crate) const DEFAULT_DURATION: f64 = 1.0;
/// Default number of frames of a scene file's run.
pub(crate) const DEFAULT_FRAMES: usize = 50;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Document {
    name: Option<String>,
    fluid: FluidTable,
    #[serde(default)]
    run: RunTable,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FluidTable {
    tank: Vec<f64>,
    column: Vec<f64>,
    dx: f64,
    open_top: Option<bool>,
    h_factor: Option<f64>,
    c0: Option<f64>,
    alpha: Option<f64>,
    cfl: Option<f64>,
    force_factor: Option<f64>,
    gamma: Option<f64>,
    rest_density: Option<f64>,
    gravity: Option<f64>,
    kernel: Option<String>,
    integrator: Option<String>,
    density: Option<String>,
    front: Option<bool>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RunTable {
    duration: Option<f64>,
    frames: Option<usize>,
}

/// Builds the scene of a fluid scene file's `text`; `path` names it in errors.
///
/// # Errors
/// [`SphCliError::Syntax`] (not TOML, an unknown key, a wrong type), [`SphCliError::Invalid`]
/// naming the key of a value out of range.
pub(crate) fn parse(text: &str, path: &Path) -> Result<AnyScene, SphCliError> {
    let doc: Document = toml::from_str(text).map_err(|source| SphCliError::Syntax {
        path: path.to_path_buf(),
        source: Box::new(source),
    })?;
    let invalid = |key: &str, reason: String| SphCliError::Invalid {
        path: path.to_path_buf(),
        key: key.to_string(),
        reason,
    };
    let name = doc.name.clone().unwrap_or_else(|| {
        path.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "fluid".into())
    });
    let f = &doc.fluid;
    let dimension = f.tank.len();
    if dimension != 2 && dimension != 3 {
        return Err(invalid(
            "fluid.tank",
            format!("has {dimension} numbers: expected 2 or 3 (the dimension)"),
        ));
    }
    if f.column.len() != dimension {
        return Err(invalid(
            "fluid.column",
            format!(
                "has {} numbers: expected {dimension}, as fluid.tank",
                f.column.len()
            ),
        ));
    }
    for (a, &t) in f.tank.iter().enumerate() {
        if !(t.is_finite() && t > 0.0) {
            return Err(invalid(
                "fluid.tank",
                format!("component {a} is {t}: must be finite and > 0 (m)"),
            ));
        }
        let c = f.column[a];
        if !(c.is_finite() && c > 0.0 && c <= t) {
            return Err(invalid(
                "fluid.column",
                format!("component {a} is {c}: must be > 0 and at most the tank's {t} (m)"),
            ));
        }
    }
    let positive = |key: &str, v: f64, unit: &str| {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(invalid(
                key,
                format!("{v} is out of range: must be > 0 ({unit})"),
            ))
        }
    };
    let dx = positive("fluid.dx", f.dx, "m")?;
    let smallest = f.tank.iter().copied().fold(f64::INFINITY, f64::min);
    if dx > smallest / 2.0 {
        return Err(invalid(
            "fluid.dx",
            format!(
                "{dx} is out of range: must be at most half the tank's smallest side, {smallest} m"
            ),
        ));
    }
    let in_range = |key: &str, v: Option<f64>, lo: f64, hi: f64, open_lo: bool, default: f64| {
        let v = v.unwrap_or(default);
        let ok = v.is_finite() && (if open_lo { v > lo } else { v >= lo }) && v <= hi;
        if ok {
            Ok(v)
        } else {
            let bracket = if open_lo { "(" } else { "[" };
            Err(invalid(
                key,
                format!("{v} is out of range: must be in {bracket}{lo}, {hi}]"),
            ))
        }
    };
    let defaults = FluidParams::<2>::default();
    let h_factor = in_range("fluid.h_factor", f.h_factor, 1.0, 3.0, false, 1.3)?;
    let alpha = in_range(
        "fluid.alpha",
        f.alpha,
        0.0,
        f64::MAX,
        false,
        defaults.viscosity_alpha,
    )?;
    let cfl = in_range("fluid.cfl", f.cfl, 0.0, 1.0, true, defaults.courant)?;
    let force_factor = in_range(
        "fluid.force_factor",
        f.force_factor,
        0.0,
        1.0,
        true,
        defaults.force_factor,
    )?;
    let gamma = in_range("fluid.gamma", f.gamma, 1.0, f64::MAX, false, defaults.gamma)?;
    let rest_density = positive(
        "fluid.rest_density",
        f.rest_density.unwrap_or(defaults.rest_density),
        "kg/m^D",
    )?;
    let c0 = match f.c0 {
        Some(c) => positive("fluid.c0", c, "m/s")?,
        None => 0.0, // the builder's 10·√(2 g H)
    };
    let gravity = f.gravity.unwrap_or(-hooke_sph::scenes::GRAVITY);
    if !gravity.is_finite() {
        return Err(invalid(
            "fluid.gravity",
            format!("{gravity} is not finite (m/s²)"),
        ));
    }
    let name_of = |key: &str, parsed: Result<(), hooke_sph::SphError>| {
        parsed.map_err(|e| invalid(key, e.to_string()))
    };
    let mut kernel = defaults.kernel;
    if let Some(k) = &f.kernel {
        name_of("fluid.kernel", k.parse::<KernelKind>().map(|k| kernel = k))?;
    }
    let mut integrator = defaults.integrator;
    if let Some(i) = &f.integrator {
        name_of(
            "fluid.integrator",
            i.parse::<Integrator>().map(|i| integrator = i),
        )?;
    }
    let mut density = defaults.density;
    if let Some(d) = &f.density {
        name_of(
            "fluid.density",
            d.parse::<DensityMethod>().map(|d| density = d),
        )?;
    }
    let duration = positive(
        "run.duration",
        doc.run.duration.unwrap_or(DEFAULT_DURATION),
        "s",
    )?;
    let frames = doc.run.frames.unwrap_or(DEFAULT_FRAMES);
    if frames == 0 {
        return Err(invalid(
            "run.frames",
            "0 is out of range: must be >= 1".into(),
        ));
    }
    let layers = WALL_LAYERS.max((2.0 * h_factor - 1e-9).ceil() as usize);
    let column = Column {
        name,
        tank: &f.tank,
        column: &f.column,
        open_top: f.open_top.unwrap_or(true),
        dx,
        layers,
        h_factor,
        duration,
        frames,
        front: f.front.unwrap_or(f.column[0] < f.tank[0]),
    };
    let setup_error = |e: hooke_sph::SphError| invalid("fluid", e.to_string());
    macro_rules! params {
        ($d:literal) => {{
            let mut g = SVector::<f64, $d>::zeros();
            g[1] = gravity;
            FluidParams::<$d> {
                rest_density,
                sound_speed: c0,
                gamma,
                viscosity_alpha: alpha,
                gravity: g,
                kernel,
                courant: cfl,
                force_factor,
                integrator,
                density,
                ..FluidParams::default()
            }
        }};
    }
    Ok(match dimension {
        2 => AnyScene::Two(column.build(params!(2)).map_err(setup_error)?),
        _ => AnyScene::Three(column.build(params!(3)).map_err(setup_error)?),
    })
}

/// A scene file's column, before the dimension is fixed.
struct Column<'a> {
    name: String,
    tank: &'a [f64],
    column: &'a [f64],
    open_top: bool,
    dx: f64,
    layers: usize,
    h_factor: f64,
    duration: f64,
    frames: usize,
    front: bool,
}

impl Column<'_> {
    fn build<const D: usize>(
        &self,
        params: FluidParams<D>,
    ) -> Result<FluidScene<D>, hooke_sph::SphError> {
        let tank_min = SVector::<f64, D>::zeros();
        let tank_max = SVector::<f64, D>::from_fn(|a, _| self.tank[a]);
        let column_max = SVector::<f64, D>::from_fn(|a, _| self.column[a]);
        let walls: [[bool; 2]; D] = std::array::from_fn(|a| [true, !(a == 1 && self.open_top)]);
        let spec = ColumnInTank {
            tank_min,
            tank_max,
            walls,
            column_max,
            dx: self.dx,
            layers: self.layers,
            params,
        };
        let mut setup = spec.build()?;
        setup.params.smoothing_length = self.h_factor * self.dx;
        Ok(FluidScene {
            name: self.name.clone(),
            setup,
            tank_min,
            tank_max,
            walls,
            column_width: column_max[0],
            column_height: column_max[1],
            dx: self.dx,
            end_time: self.duration,
            frames: self.frames,
            dam_break: self.front,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_text(text: &str) -> Result<AnyScene, SphCliError> {
        parse(text, Path::new("test.toml"))
    }

    const SMALL: &str = "[fluid]\ntank = [1.0, 1.0]\ncolumn = [0.25, 0.5]\ndx = 0.05\n";

    #[test]
    fn a_small_column_parses() {
        let AnyScene::Two(s) = parse_text(SMALL).unwrap() else {
            panic!("2D");
        };
        assert_eq!(s.name, "test");
        assert_eq!(s.setup.fluid_positions.len(), 5 * 10);
        assert!(s.dam_break);
        assert_eq!(s.frames, DEFAULT_FRAMES);
        assert!((s.setup.params.smoothing_length - 0.065).abs() < 1e-15);
        let c0 = 10.0 * (2.0 * 9.81 * 0.5f64).sqrt();
        assert!((s.setup.params.sound_speed - c0).abs() < 1e-12);
    }

    #[test]
    fn three_d_and_options() {
        let text = "name = \"box\"\n[fluid]\ntank = [1.0, 1.0, 0.5]\ncolumn = [0.5, 0.5, 0.5]\n\
                    dx = 0.1\nc0 = 20.0\nh_factor = 2.0\nintegrator = \"leapfrog\"\n\
                    [run]\nduration = 0.1\nframes = 2\n";
        let AnyScene::Three(s) = parse_text(text).unwrap() else {
            panic!("3D");
        };
        assert_eq!(s.name, "box");
        assert_eq!(s.setup.params.sound_speed, 20.0);
        assert_eq!(s.setup.params.integrator, Integrator::Leapfrog);
        assert_eq!((s.end_time, s.frames), (0.1, 2));
    }

    #[test]
    fn errors_name_the_key() {
        let cases = [
            (format!("{SMALL}colour = 1\n"), "colour"),
            (SMALL.replace("0.05", "-0.05"), "fluid.dx"),
            (SMALL.replace("0.05", "0.9"), "fluid.dx"),
            (SMALL.replace("0.05", "\"big\""), "dx"),
            (format!("{SMALL}cfl = 1.5\n"), "fluid.cfl"),
            (format!("{SMALL}kernel = \"gauss\"\n"), "fluid.kernel"),
            (SMALL.replace("[0.25, 0.5]", "[2.0, 0.5]"), "fluid.column"),
            (SMALL.replace("[1.0, 1.0]", "[1.0]"), "fluid.tank"),
            (format!("{SMALL}[run]\nframes = 0\n"), "run.frames"),
            (format!("{SMALL}[run]\nduration = -1.0\n"), "run.duration"),
        ];
        for (text, key) in cases {
            let err = parse_text(&text).expect_err(&text).to_string();
            assert!(err.contains(key), "{text}: {err}");
        }
    }
}
