//! `preview.png` of a fluid run: the last frame's particles coloured by speed (dark blue at rest
//! through green to yellow at the frame's largest speed, a colour bar at the right), the wall
//! particles in grey and the tank's inside outlined (open where the top is open), y up. A 3D scene is seen from the side
//! (looking along −z, x right, y up), nearer particles drawn last, without the walls across z. Text uses the DejaVu Sans font
//! embedded in the program. The PNG is written to a temporary file beside the target and renamed
//! onto it when complete.

use std::path::Path;
use std::sync::OnceLock;

use nalgebra::SVector;
use plotters::prelude::*;
use plotters::style::register_font;

use super::SphCliError;
use crate::output::OutputError;

/// Image size, in pixels.
const WIDTH: u32 = 800;
const HEIGHT: u32 = 600;
const FONT: &str = "sans-serif";
/// DejaVu Sans (see `assets/fonts/DejaVuSans-LICENSE.txt`).
static FONT_BYTES: &[u8] = include_bytes!("../../../../assets/fonts/DejaVuSans.ttf");

const BACKGROUND: RGBColor = RGBColor(247, 248, 250);
const TEXT: RGBColor = RGBColor(30, 32, 36);
const WALL: RGBColor = RGBColor(150, 154, 162);
const TANK: RGBColor = RGBColor(60, 64, 72);

/// Colour stops of the speed map (viridis-like), from 0 to the largest speed.
const STOPS: [[f64; 3]; 5] = [
    [68.0, 1.0, 84.0],
    [59.0, 82.0, 139.0],
    [33.0, 145.0, 140.0],
    [94.0, 201.0, 98.0],
    [253.0, 231.0, 37.0],
];

/// The colour of `f` in [0, 1] on the speed map (NaN gives the lowest colour).
fn colour(f: f64) -> RGBColor {
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = f * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let t = x - i as f64;
    let c = |k: usize| (STOPS[i][k] * (1.0 - t) + STOPS[i + 1][k] * t).round() as u8;
    RGBColor(c(0), c(1), c(2))
}

/// What the preview shows.
pub(crate) struct Input<'a, const D: usize> {
    /// Caption.
    pub title: &'a str,
    /// Fluid positions (m).
    pub positions: &'a [SVector<f64, D>],
    /// Fluid speeds (m/s), one per position.
    pub speeds: &'a [f64],
    /// Wall particle positions (m).
    pub walls: &'a [SVector<f64, D>],
    /// The tank's inside (m).
    pub tank_min: SVector<f64, D>,
    /// The tank's inside (m).
    pub tank_max: SVector<f64, D>,
    /// Whether the tank has a lid (y = tank_max[1] is a wall); its outline is drawn open otherwise.
    pub lid: bool,
}

pub(crate) fn font_ready() -> bool {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    *REGISTERED.get_or_init(|| register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok())
}

fn plot_error(path: &Path, e: impl std::fmt::Display) -> SphCliError {
    SphCliError::Output(OutputError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Renders `input` to an 800 × 600 PNG at `path`, atomically.
pub(crate) fn render<const D: usize>(path: &Path, input: &Input<D>) -> Result<(), SphCliError> {
    let mut pixels = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    draw(&mut pixels, input).map_err(|e| plot_error(path, e))?;
    Ok(crate::output::write_png(path, &pixels, WIDTH, HEIGHT)?)
}

fn draw<const D: usize>(pixels: &mut [u8], input: &Input<D>) -> Result<(), String> {
    let area = BitMapBackend::with_buffer(pixels, (WIDTH, HEIGHT)).into_drawing_area();
    let err = |e: DrawingAreaErrorKind<_>| e.to_string();
    area.fill(&BACKGROUND).map_err(err)?;
    let finite = |p: &&SVector<f64, D>| p[0].is_finite() && p[1].is_finite();
    // In 3D the walls across z (behind and in front of the fluid) are left out, so that the
    // fluid can be seen.
    let shown = |p: &&SVector<f64, D>| {
        finite(p)
            && (D < 3 || (p[D - 1] >= input.tank_min[D - 1] && p[D - 1] <= input.tank_max[D - 1]))
    };
    // The view: the tank and its walls.
    let (mut lo, mut hi) = (
        [input.tank_min[0], input.tank_min[1]],
        [input.tank_max[0], input.tank_max[1]],
    );
    for p in input.walls.iter().filter(finite) {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let (left, top, right, bottom) = (
        20.0,
        60.0,
        f64::from(WIDTH) - 110.0,
        f64::from(HEIGHT) - 20.0,
    );
    let span = [(hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9)];
    let scale = ((right - left) / span[0]).min((bottom - top) / span[1]);
    let x0 = left + 0.5 * ((right - left) - scale * span[0]);
    let y0 = bottom - 0.5 * ((bottom - top) - scale * span[1]);
    let map = |x: f64, y: f64| {
        (
            (x0 + (x - lo[0]) * scale).round() as i32,
            (y0 - (y - lo[1]) * scale).round() as i32,
        )
    };
    // A particle's disc: the lattice spacing's worth, at least one pixel.
    let spacing = spacing_estimate(input.walls, input.positions);
    let radius = ((0.5 * spacing * scale).round() as i32).clamp(1, 12);
    for p in input.walls.iter().filter(shown) {
        area.draw(&Circle::new(map(p[0], p[1]), radius, WALL.filled()))
            .map_err(err)?;
    }
    let corners = [
        map(input.tank_min[0], input.tank_min[1]),
        map(input.tank_max[0], input.tank_min[1]),
        map(input.tank_max[0], input.tank_max[1]),
        map(input.tank_min[0], input.tank_max[1]),
    ];
    // From the top left corner down, along the floor and up: the lid only if there is one.
    let mut outline = vec![corners[3], corners[0], corners[1], corners[2]];
    if input.lid {
        outline.push(corners[3]);
    }
    area.draw(&PathElement::new(outline, TANK.stroke_width(2)))
        .map_err(err)?;
    let max_speed = input
        .speeds
        .iter()
        .copied()
        .filter(|s| s.is_finite())
        .fold(0.0, f64::max);
    let mut order: Vec<usize> = (0..input.positions.len())
        .filter(|&i| finite(&&input.positions[i]))
        .collect();
    if D == 3 {
        // Far (small z) first.
        order.sort_by(|&i, &j| input.positions[i][D - 1].total_cmp(&input.positions[j][D - 1]));
    }
    for i in order {
        let p = &input.positions[i];
        let s = input.speeds.get(i).copied().unwrap_or(0.0);
        let f = if max_speed > 0.0 { s / max_speed } else { 0.0 };
        area.draw(&Circle::new(map(p[0], p[1]), radius, colour(f).filled()))
            .map_err(err)?;
    }
    // The colour bar.
    let (bx, by0, by1) = (f64::from(WIDTH) - 80.0, top + 20.0, bottom - 20.0);
    let steps = 100;
    for k in 0..steps {
        let f = k as f64 / (steps - 1) as f64;
        let y = by1 - f * (by1 - by0);
        area.draw(&Rectangle::new(
            [(bx as i32, y as i32 - 3), (bx as i32 + 20, y as i32 + 3)],
            colour(f).filled(),
        ))
        .map_err(err)?;
    }
    if font_ready() {
        let style = (FONT, 18).into_font().color(&TEXT);
        area.draw(&Text::new(input.title.to_string(), (20, 20), style))
            .map_err(err)?;
        let small = (FONT, 14).into_font().color(&TEXT);
        area.draw(&Text::new(
            format!("{max_speed:.2}"),
            (bx as i32 - 10, by0 as i32 - 22),
            small.clone(),
        ))
        .map_err(err)?;
        area.draw(&Text::new(
            "0",
            (bx as i32 + 6, by1 as i32 + 6),
            small.clone(),
        ))
        .map_err(err)?;
        area.draw(&Text::new(
            "speed, m/s",
            (bx as i32 - 20, by0 as i32 - 40),
            small,
        ))
        .map_err(err)?;
    }
    area.present().map_err(err)?;
    Ok(())
}

/// The particles' spacing: the distance between the first wall particle and its nearest
/// neighbour among a few (or, without walls, the first two fluid particles').
fn spacing_estimate<const D: usize>(walls: &[SVector<f64, D>], fluid: &[SVector<f64, D>]) -> f64 {
    let points = if walls.len() >= 2 { walls } else { fluid };
    let Some(first) = points.first() else {
        return 0.0;
    };
    points
        .iter()
        .skip(1)
        .take(64)
        .map(|p| (p - first).norm())
        .filter(|d| d.is_finite() && *d > 0.0)
        .fold(f64::INFINITY, f64::min)
        .min(1e9)
}
