//! `preview.png` of a fluid run: the last frame's particles coloured by speed (dark blue at rest
//! through green to yellow), a colour bar in m/s at the right, the wall particles in grey and the
//! tank's inside outlined (open where the top is open), with axes in metres, y up. A 3D scene is
//! seen from the side (looking along −z, x right, y up), nearer particles drawn last, without the
//! walls across z. Text uses the DejaVu Sans font embedded in the program. The PNG is written to a
//! temporary file beside the target and renamed onto it when complete.
//!
//! The colour bar runs from 0 to the frame's largest speed, but never less than
//! [`SPEED_FLOOR`] × the scene's speed scale √(2 g H) (H the column's height, the speed of a fall
//! from it; docs/sph.md): a fluid at rest, whose speeds are mm/s noise, stays dark instead of
//! showing its noise as hot spots. The largest speed is marked on the bar with its value.

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
const TEXT_DIM: RGBColor = RGBColor(105, 110, 120);
const WALL: RGBColor = RGBColor(150, 154, 162);
const TANK: RGBColor = RGBColor(60, 64, 72);

/// The smallest top of the colour bar, as a fraction of the speed scale √(2 g H): a tenth of the
/// speed of a fall from the column's height. A dam break's fluid moves at about the scale; a
/// settled column's noise (mm/s) is far below a tenth of it.
pub(crate) const SPEED_FLOOR: f64 = 0.1;

/// Colour stops of the speed map (viridis-like), from 0 to the bar's top.
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
    /// The scene's speed scale √(2 g H) (m/s), H the column's height: sets the colour bar's
    /// smallest top ([`SPEED_FLOOR`]). 0 (or not finite) sets no floor.
    pub speed_scale: f64,
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

/// The colour bar's top (m/s): the largest finite speed, floored at [`SPEED_FLOOR`] ×
/// `speed_scale`; 1 m/s when both are 0.
pub(crate) fn bar_top(speeds: &[f64], speed_scale: f64) -> f64 {
    let largest = speeds
        .iter()
        .copied()
        .filter(|s| s.is_finite())
        .fold(0.0, f64::max);
    let floor = if speed_scale.is_finite() {
        SPEED_FLOOR * speed_scale.max(0.0)
    } else {
        0.0
    };
    let top = largest.max(floor);
    if top > 0.0 {
        top
    } else {
        1.0
    }
}

/// The step and the values of ticks in `lo`..=`hi`: multiples of a step of 1, 2 or 5 × 10ᵏ, the
/// smallest giving at most `intervals` (at least 1) intervals over the span. A span that is not
/// positive and finite gets the single tick `lo`.
pub(crate) fn ticks(lo: f64, hi: f64, intervals: usize) -> (f64, Vec<f64>) {
    let intervals = intervals.max(1) as f64;
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) {
        return (1.0, vec![lo]);
    }
    let decade = 10f64.powf((span / intervals).log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * decade)
        .find(|&s| span / s <= intervals + 1e-9)
        .unwrap_or(10.0 * decade);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (step, (first..=last).map(|k| k as f64 * step).collect())
}

/// A tick's label: as many decimals as the step needs (`0`, `0.5`, `0.02`), no more.
pub(crate) fn tick_label(value: f64, step: f64) -> String {
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    let text = format!("{value:.decimals$}");
    if text
        .trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        "0".into()
    } else {
        text
    }
}

/// A speed to three significant figures (`6.25`, `0.0123`, `1.20e-5`).
pub(crate) fn speed_label(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-4..1e4).contains(&v.abs()) {
        let decimals = (2 - v.abs().log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.2e}")
    }
}

fn draw<const D: usize>(pixels: &mut [u8], input: &Input<D>) -> Result<(), String> {
    let area = BitMapBackend::with_buffer(pixels, (WIDTH, HEIGHT)).into_drawing_area();
    let err = |e: DrawingAreaErrorKind<_>| e.to_string();
    area.fill(&BACKGROUND).map_err(err)?;
    let text = font_ready();
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
    // Room for the axes' labels at the left and bottom, the colour bar at the right.
    let (left, top, right, bottom) = (
        70.0,
        60.0,
        f64::from(WIDTH) - 150.0,
        f64::from(HEIGHT) - 55.0,
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
    let largest = input
        .speeds
        .iter()
        .copied()
        .filter(|s| s.is_finite())
        .fold(0.0, f64::max);
    let bar = bar_top(input.speeds, input.speed_scale);
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
        area.draw(&Circle::new(
            map(p[0], p[1]),
            radius,
            colour(s / bar).filled(),
        ))
        .map_err(err)?;
    }
    // The axes, in metres, along the view's left and bottom edges.
    let (view_left, view_bottom) = map(lo[0], lo[1]);
    let (view_right, view_top) = map(hi[0], hi[1]);
    // Clear of the outermost wall particles' discs.
    let (axis_x, axis_y) = (view_left - radius - 6, view_bottom + radius + 6);
    area.draw(&PathElement::new(
        vec![(view_left, axis_y), (view_right, axis_y)],
        TANK.stroke_width(1),
    ))
    .map_err(err)?;
    area.draw(&PathElement::new(
        vec![(axis_x, view_bottom), (axis_x, view_top)],
        TANK.stroke_width(1),
    ))
    .map_err(err)?;
    let small = (FONT, 14).into_font().color(&TEXT);
    let dim = (FONT, 13).into_font().color(&TEXT_DIM);
    // A labelled tick every 60 pixels at most.
    let intervals = |pixels: i32| (pixels / 60).clamp(1, 7) as usize;
    let (x_step, x_ticks) = ticks(lo[0], hi[0], intervals(view_right - view_left));
    for &x in &x_ticks {
        let (px, _) = map(x, lo[1]);
        area.draw(&PathElement::new(
            vec![(px, axis_y), (px, axis_y + 5)],
            TANK.stroke_width(1),
        ))
        .map_err(err)?;
        if text {
            let label = tick_label(x, x_step);
            let w = area.estimate_text_size(&label, &small).map_err(err)?.0 as i32;
            area.draw(&Text::new(label, (px - w / 2, axis_y + 8), small.clone()))
                .map_err(err)?;
        }
    }
    let (y_step, y_ticks) = ticks(lo[1], hi[1], intervals(view_bottom - view_top));
    let mut widest = 0;
    for &y in &y_ticks {
        let (_, py) = map(lo[0], y);
        area.draw(&PathElement::new(
            vec![(axis_x - 5, py), (axis_x, py)],
            TANK.stroke_width(1),
        ))
        .map_err(err)?;
        if text {
            let label = tick_label(y, y_step);
            let w = area.estimate_text_size(&label, &small).map_err(err)?.0 as i32;
            widest = widest.max(w);
            area.draw(&Text::new(label, (axis_x - 8 - w, py - 8), small.clone()))
                .map_err(err)?;
        }
    }
    // The colour bar.
    let (bx, by0, by1) = (f64::from(WIDTH) - 120.0, top + 30.0, bottom - 10.0);
    let bar_height = by1 - by0;
    for y in by0 as i32..=by1 as i32 {
        let f = (by1 - f64::from(y)) / bar_height;
        area.draw(&Rectangle::new(
            [(bx as i32, y), (bx as i32 + 20, y + 1)],
            colour(f).filled(),
        ))
        .map_err(err)?;
    }
    let (bar_step, bar_ticks) = ticks(0.0, bar, 7);
    for &v in &bar_ticks {
        let y = (by1 - v / bar * bar_height).round() as i32;
        area.draw(&PathElement::new(
            vec![(bx as i32 + 20, y), (bx as i32 + 25, y)],
            TANK.stroke_width(1),
        ))
        .map_err(err)?;
        if text {
            area.draw(&Text::new(
                tick_label(v, bar_step),
                (bx as i32 + 28, y - 8),
                small.clone(),
            ))
            .map_err(err)?;
        }
    }
    // The largest speed, marked at its level.
    let marker = (by1 - (largest / bar).clamp(0.0, 1.0) * bar_height).round() as i32;
    area.draw(&Polygon::new(
        vec![
            (bx as i32 - 9, marker - 5),
            (bx as i32 - 1, marker),
            (bx as i32 - 9, marker + 5),
        ],
        TEXT.filled(),
    ))
    .map_err(err)?;
    if text {
        let title = (FONT, 18).into_font().color(&TEXT);
        area.draw(&Text::new(input.title.to_string(), (20, 20), title))
            .map_err(err)?;
        area.draw(&Text::new(
            "speed (m/s)",
            (bx as i32 - 14, by0 as i32 - 44),
            small.clone(),
        ))
        .map_err(err)?;
        area.draw(&Text::new(
            format!("▶ largest {}", speed_label(largest)),
            (bx as i32 - 14, by0 as i32 - 25),
            dim.clone(),
        ))
        .map_err(err)?;
        area.draw(&Text::new(
            "x (m)",
            ((view_left + view_right) / 2 - 15, axis_y + 28),
            small.clone(),
        ))
        .map_err(err)?;
        area.draw(&Text::new(
            "y (m)",
            (
                (axis_x - widest - 56).max(4),
                (view_top + view_bottom) / 2 - 8,
            ),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fluid_at_rest_stays_dark_and_a_moving_one_fills_the_bar() {
        // Hydrostatic column H = 2 m: scale √(2 g H) ≈ 6.26 m/s; speeds of a few mm/s of noise.
        let scale = (2.0 * 9.81 * 2.0f64).sqrt();
        let noise = [0.001, 0.004, 0.0025];
        let top = bar_top(&noise, scale);
        assert_eq!(top, SPEED_FLOOR * scale);
        // The noisiest particle is in the bar's darkest tenth or less.
        assert!(0.004 / top < 0.01, "{}", 0.004 / top);
        // A dam break's speeds exceed the floor: the bar runs to the largest.
        assert_eq!(bar_top(&[0.5, 4.2, f64::NAN, 3.0], scale), 4.2);
        // Nothing known: a usable bar.
        assert_eq!(bar_top(&[], 0.0), 1.0);
        assert_eq!(bar_top(&[f64::NAN], f64::INFINITY), 1.0);
    }

    #[test]
    fn ticks_are_round_and_labelled_with_the_digits_they_need() {
        let (step, t) = ticks(0.0, 0.626, 7);
        assert_eq!(step, 0.1);
        assert_eq!(t.len(), 7);
        assert_eq!(tick_label(t[3], step), "0.3");
        assert_eq!(tick_label(0.0, step), "0");
        let (step, t) = ticks(-0.075, 4.075, 7);
        assert_eq!(step, 1.0);
        assert_eq!(t, vec![0.0, 1.0, 2.0, 3.0, 4.0]);
        assert_eq!(tick_label(2.0, step), "2");
        let (step, t) = ticks(0.0, 0.012, 7);
        assert_eq!(step, 0.002);
        assert_eq!(tick_label(t[5], step), "0.010");
        for (lo, hi) in [(0.0, 1.0), (-3.0, 7.5), (0.0, 6.26e-3), (1e3, 5e3)] {
            let (_, t) = ticks(lo, hi, 7);
            assert!((3..=10).contains(&t.len()), "{lo}..{hi}: {t:?}");
            assert!(
                t.iter().all(|&v| v >= lo - 1e-12 && v <= hi + 1e-12),
                "{t:?}"
            );
        }
        // A narrow axis gets fewer ticks: a 1 m wide tank over 140 pixels, at most two intervals.
        let (step, t) = ticks(-0.075, 1.075, 2);
        assert_eq!((step, t), (1.0, vec![0.0, 1.0]));
        assert_eq!(speed_label(0.00423), "0.00423");
        assert_eq!(speed_label(5.2214e-4), "0.000522");
        assert_eq!(speed_label(6.2641), "6.26");
        assert_eq!(speed_label(0.0), "0");
    }
}
