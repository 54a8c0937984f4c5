//! PNG plots on log axes, drawn with plotters and the font shipped in `assets/fonts` (no system
//! font needed), written to a temporary file beside the target and renamed onto it.
//!
//! The axes are fitted to the data ([`fitted_log_range`]), and each point of a solver's curve is
//! labelled with its setting (`10 it`, `tol 1e-6`), so that the curve reads without the table.

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::combinators::{BindKeyPoints, IntoLogRange, LogCoord, WithKeyPoints};
use plotters::prelude::*;
use plotters::style::register_font;

use crate::bench::{BenchError, Record, SweepRow};

/// The family name the embedded font is registered under.
const FONT: &str = "sans-serif";
/// DejaVu Sans (see `assets/fonts/DejaVuSans-LICENSE.txt`).
static FONT_BYTES: &[u8] = include_bytes!("../../../../assets/fonts/DejaVuSans.ttf");

/// Twelve colours told apart at a glance, so that `hooke bench`'s default solver list (ten
/// solvers) draws no two curves alike.
const PALETTE: [RGBColor; 12] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(0, 0, 0),
    RGBColor(0, 0, 128),
];

fn font_ready() -> bool {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    *REGISTERED.get_or_init(|| register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok())
}

fn plot_error(path: &Path, e: impl std::fmt::Display) -> BenchError {
    BenchError::Output {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

/// A named series of (x, y) points, drawn as a line through the points in their order (a solver's
/// settings from loose to strict, or sizes from small to large), each point with its label
/// (empty: none).
struct Series {
    name: String,
    points: Vec<(f64, f64)>,
    labels: Vec<String>,
}

/// Group `(name, x, y, label)` by name (first-seen order), keeping positive finite values only.
fn group(
    items: impl IntoIterator<Item = (String, Option<f64>, Option<f64>, String)>,
) -> Vec<Series> {
    let mut series: Vec<Series> = Vec::new();
    for (name, x, y, label) in items {
        let (Some(x), Some(y)) = (x, y) else { continue };
        if !(x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite()) {
            continue;
        }
        match series.iter_mut().find(|s| s.name == name) {
            Some(s) => {
                s.points.push((x, y));
                s.labels.push(label);
            }
            None => series.push(Series {
                name,
                points: vec![(x, y)],
                labels: vec![label],
            }),
        }
    }
    series
}

/// A point's label from a record's `setting` (`10`, `1e-6`, `default`): `10 it`, `tol 1e-6`,
/// `default`.
fn setting_label(setting: &str) -> String {
    if setting.parse::<usize>().is_ok() {
        format!("{setting} it")
    } else if setting.parse::<f64>().is_ok() {
        format!("tol {setting}")
    } else {
        setting.to_string()
    }
}

/// The margin of a fitted log axis beyond its data, as a factor on each side: room for the
/// point markers and labels, not a decade of empty axis.
const LOG_MARGIN: f64 = 1.25;

/// A log axis range fitted to the positive finite `values`: from their smallest to their largest,
/// widened by [`LOG_MARGIN`] (and by a tenth of the span in log terms for wide data) on each
/// side. Without such values, 1e-3..1.
pub(crate) fn fitted_log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for v in values.filter(|v| v.is_finite() && *v > 0.0) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !(lo.is_finite() && hi > 0.0) {
        return 1e-3..1.0;
    }
    let margin = LOG_MARGIN.max((hi / lo).powf(0.05));
    lo / margin..hi * margin
}

/// The most labelled ticks a log axis gets: more would overlap on a 600-pixel axis.
const MAX_LOG_LABELS: usize = 12;

/// A log axis over `range` whose labelled ticks are 1, 2 and 5 × 10ᵏ (every digit × 10ᵏ when
/// that gives fewer than three), the light grid every digit × 10ᵏ: a fitted axis narrower than a
/// decade still reads. An axis over so many decades that 1, 2, 5 would give more than
/// [`MAX_LOG_LABELS`] labels is labelled at decades only (every second, third… decade if there are
/// still too many), with the light grid at every decade.
pub(crate) fn log_axis(range: std::ops::Range<f64>) -> WithKeyPoints<LogCoord<f64>> {
    let within = |digits: &[f64]| -> Vec<f64> {
        let (first, last) = (
            range.start.log10().floor() as i32,
            range.end.log10().ceil() as i32,
        );
        (first..=last)
            .flat_map(|k| digits.iter().map(move |d| d * 10f64.powi(k)))
            .filter(|v| range.contains(v))
            .collect()
    };
    let all: Vec<f64> = within(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    let mut bold = within(&[1.0, 2.0, 5.0]);
    let mut light = all.clone();
    if bold.len() < 3 {
        bold = all;
    } else if bold.len() > MAX_LOG_LABELS {
        let decades = within(&[1.0]);
        let every = decades.len().div_ceil(MAX_LOG_LABELS) as i32;
        bold = decades
            .iter()
            .copied()
            .filter(|v| (v.log10().round() as i32).rem_euclid(every) == 0)
            .collect();
        light = decades;
    }
    range
        .log_scale()
        .with_key_points(bold)
        .with_light_points(light)
}

/// A log axis' tick label, to one significant digit when that is exact, else two: plain between
/// 0.001 and 10⁵ (`0.002`, `2.5`, `40`), else in exponent form (`1e-5`, `2.5e6`).
pub(crate) fn log_tick_label(v: f64) -> String {
    let one = format!("{v:.0e}");
    let rounded = match one.parse::<f64>() {
        Ok(w) if (w - v).abs() <= 1e-9 * v.abs() => w,
        _ => format!("{v:.1e}").parse::<f64>().unwrap_or(v),
    };
    if (1e-3..1e5).contains(&rounded.abs()) {
        format!("{rounded}")
    } else if one.parse::<f64>().is_ok_and(|w| w == rounded) {
        one
    } else {
        format!("{v:.1e}")
    }
}

/// Draw one log-log chart of `series` into `area`.
fn chart(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    caption: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    legend: SeriesLabelPosition,
) -> Result<(), String> {
    let text = font_ready();
    let x = fitted_log_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let y = fitted_log_range(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let mut builder = ChartBuilder::on(area);
    builder
        .margin(12)
        .x_label_area_size(if text { 45 } else { 5 })
        .y_label_area_size(if text { 70 } else { 5 });
    if text {
        builder.caption(caption, (FONT, 20));
    }
    let mut c = builder
        .build_cartesian_2d(log_axis(x), log_axis(y))
        .map_err(|e| e.to_string())?;
    let mut mesh = c.configure_mesh();
    if text {
        mesh.x_desc(x_label)
            .y_desc(y_label)
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 15))
            .x_label_formatter(&|v| log_tick_label(*v))
            .y_label_formatter(&|v| log_tick_label(*v));
    } else {
        mesh.disable_x_mesh().disable_y_mesh();
    }
    mesh.draw().map_err(|e| e.to_string())?;
    let label_font = (FONT, 12).into_font();
    for (k, s) in series.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        let line = c
            .draw_series(LineSeries::new(
                s.points.iter().copied(),
                color.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?;
        if text {
            line.label(s.name.clone()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        }
        c.draw_series(s.points.iter().map(|&p| Circle::new(p, 4, color.filled())))
            .map_err(|e| e.to_string())?;
        if text {
            // Each point's setting above its marker: to its right, or to its left where the
            // label would run past the plotting area's right edge.
            let style = label_font.clone().color(&color);
            let right_edge = c.plotting_area().get_pixel_range().0.end;
            let placed: Vec<_> = s
                .points
                .iter()
                .zip(&s.labels)
                .filter(|(_, l)| !l.is_empty())
                .map(|(&p, l)| {
                    let width = label_font.box_size(l).map_or(0, |(w, _)| w as i32);
                    let x = c.backend_coord(&p).0;
                    let dx = if x + 6 + width > right_edge {
                        -6 - width
                    } else {
                        6
                    };
                    EmptyElement::at(p) + Text::new(l.clone(), (dx, -16), style.clone())
                })
                .collect();
            c.draw_series(placed).map_err(|e| e.to_string())?;
        }
    }
    if text && !series.is_empty() {
        c.configure_series_labels()
            .position(legend)
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.4))
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Render with `draw` into a PNG at `path`, atomically (see `crate::output::write_png`).
fn write_png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend, plotters::coord::Shift>) -> Result<(), String>,
) -> Result<(), BenchError> {
    crate::bench::output::create_parent(path)?;
    let mut pixels = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let area = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        area.fill(&WHITE).map_err(|e| plot_error(path, e))?;
        draw(&area).map_err(|e| plot_error(path, e))?;
        area.present().map_err(|e| plot_error(path, e))?;
    }
    crate::output::write_png(path, &pixels, size.0, size.1).map_err(|e| match e {
        crate::output::OutputError::Io { source, .. } => plot_error(path, source),
        e => plot_error(path, e),
    })
}

/// Error against wall time of the step on log axes, one line per solver through its settings in
/// the order given (its Pareto curve): objective error on the left, position error on the right. Records
/// without a time or with a non-positive error are left out.
///
/// # Errors
/// [`BenchError::Output`] naming the file.
pub fn plot_pareto(path: &Path, records: &[Record], title: &str) -> Result<(), BenchError> {
    let by = |f: fn(&Record) -> Option<f64>| {
        group(records.iter().map(|r| {
            (
                r.solver.clone(),
                r.wall_time_s,
                f(r),
                setting_label(&r.setting),
            )
        }))
    };
    let objective = by(|r| r.objective_error);
    let position = by(|r| r.position_error);
    write_png(path, (1400, 600), |area| {
        let (left, right) = area.split_horizontally(700);
        chart(
            &left,
            &format!("{title}: objective error"),
            "wall time of the step (s)",
            "(Φ(x) − Φ*) / (Φ(y) − Φ*)",
            &objective,
            // Fast and exact, the corner no solver reaches: the legend hides nothing there.
            SeriesLabelPosition::LowerLeft,
        )?;
        chart(
            &right,
            &format!("{title}: position error"),
            "wall time of the step (s)",
            "|x − x*| / |x* − x_n|",
            &position,
            SeriesLabelPosition::LowerLeft,
        )
    })
}

/// Wall time of one step against the vertex count on log axes, one line per solver setting.
///
/// # Errors
/// [`BenchError::Output`] naming the file.
pub fn plot_sweep(path: &Path, rows: &[SweepRow], title: &str) -> Result<(), BenchError> {
    let series = group(rows.iter().map(|row| {
        let r = &row.outcome.record;
        (
            format!("{}:{}", r.solver, r.setting),
            Some(row.vertices as f64),
            r.wall_time_s,
            String::new(),
        )
    }));
    let peak = rows.iter().filter_map(|r| r.peak_memory_bytes).max();
    let caption = match peak {
        Some(b) => format!(
            "{title} (peak memory {:.0} MB, whole process)",
            b as f64 / 1e6
        ),
        None => title.to_string(),
    };
    write_png(path, (900, 600), |area| {
        chart(
            area,
            &caption,
            "vertices",
            "wall time of one step (s)",
            &series,
            // Few vertices and a long step: the corner time growing with size leaves empty.
            SeriesLabelPosition::UpperLeft,
        )
    })
}

/// The dam-break front Z = x_front/L against T = t·√(2g/L) on linear axes: one line per named
/// series (a run at one spacing), and `experiment`'s points as black crosses.
///
/// # Errors
/// [`BenchError::Output`] naming the file.
pub fn plot_fronts(
    path: &Path,
    runs: &[(String, Vec<(f64, f64)>)],
    experiment: &[(f64, f64)],
    title: &str,
) -> Result<(), BenchError> {
    let all = || {
        runs.iter()
            .flat_map(|(_, p)| p.iter())
            .chain(experiment)
            .filter(|p| p.0.is_finite() && p.1.is_finite())
    };
    let t_max = all().map(|p| p.0).fold(0.0, f64::max).max(1.0);
    let z_max = all().map(|p| p.1).fold(0.0, f64::max).max(1.0);
    write_png(path, (900, 600), |area| {
        let text = font_ready();
        let mut builder = ChartBuilder::on(area);
        builder
            .margin(12)
            .x_label_area_size(if text { 45 } else { 5 })
            .y_label_area_size(if text { 55 } else { 5 });
        if text {
            builder.caption(title, (FONT, 20));
        }
        let mut c = builder
            .build_cartesian_2d(0.0..t_max * 1.02, 0.9..z_max * 1.05)
            .map_err(|e| e.to_string())?;
        let mut mesh = c.configure_mesh();
        if text {
            mesh.x_desc("T = t √(2g/L)")
                .y_desc("Z = x_front / L")
                .label_style((FONT, 13))
                .axis_desc_style((FONT, 15));
        } else {
            mesh.disable_x_mesh().disable_y_mesh();
        }
        mesh.draw().map_err(|e| e.to_string())?;
        for (k, (name, points)) in runs.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            let line = c
                .draw_series(LineSeries::new(
                    points.iter().copied().filter(|p| p.1.is_finite()),
                    color.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?;
            if text {
                line.label(name.clone()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
            }
        }
        let crosses = c
            .draw_series(
                experiment
                    .iter()
                    .map(|&p| Cross::new(p, 5, BLACK.stroke_width(2))),
            )
            .map_err(|e| e.to_string())?;
        if text {
            crosses
                .label("experiment (Koshizuka & Oka 1996)")
                .legend(|(x, y)| Cross::new((x + 9, y), 5, BLACK.stroke_width(2)));
            c.configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .label_font((FONT, 13))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.4))
                .draw()
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_axes_fit_their_data() {
        // Times of an SPH sweep: 2.1 ms to 48 ms. The axis holds every value, with at most the
        // margin beyond the extremes (the decade-rounded axis ran 1 ms to 100 ms).
        let values = [2.1e-3, 7.7e-3, 4.8e-2, f64::NAN, -1.0, 0.0];
        let r = fitted_log_range(values.iter().copied());
        assert!(r.start <= 2.1e-3 && r.end >= 4.8e-2, "{r:?}");
        let margin = LOG_MARGIN.max((4.8e-2f64 / 2.1e-3).powf(0.05));
        assert!((2.1e-3 / r.start - margin).abs() < 1e-12 * margin, "{r:?}");
        assert!((r.end / 4.8e-2 - margin).abs() < 1e-12 * margin, "{r:?}");
        assert!(margin < 1.3);
        // One value: a usable range around it; none: a default.
        let one = fitted_log_range([5.0].into_iter());
        assert!(one.start < 5.0 && one.end > 5.0);
        assert_eq!(fitted_log_range(std::iter::empty()), 1e-3..1.0);
        // A fitted axis narrower than a decade still has at least three labelled ticks.
        let narrow = fitted_log_range([5.77e-2, 9.86e-2].into_iter());
        let axis = log_axis(narrow.clone());
        assert!(axis.bold_points().len() >= 3, "{:?}", axis.bold_points());
        assert!(axis.bold_points().iter().all(|v| narrow.contains(v)));
        let wide = log_axis(fitted_log_range([1e-4, 1e-1].into_iter()));
        assert!(wide.bold_points().contains(&1e-3) && wide.bold_points().contains(&2e-3));
        // Thirty decades (an objective error down to round-off) get decade labels, few enough
        // to read, and all of them powers of ten.
        let deep = log_axis(fitted_log_range([1e-31, 0.1].into_iter()));
        let labels = deep.bold_points();
        assert!((3..=MAX_LOG_LABELS).contains(&labels.len()), "{labels:?}");
        assert!(labels
            .iter()
            .all(|v| (v.log10() - v.log10().round()).abs() < 1e-9));
    }

    #[test]
    fn points_are_labelled_with_their_setting() {
        assert_eq!(setting_label("10"), "10 it");
        assert_eq!(setting_label("1e-6"), "tol 1e-6");
        assert_eq!(setting_label("default"), "default");
        let series = group([
            ("pd".to_string(), Some(1e-3), Some(0.5), setting_label("1")),
            ("pd".to_string(), Some(2e-3), Some(0.1), setting_label("10")),
            ("pd".to_string(), None, Some(0.1), setting_label("100")),
            (
                "newton".to_string(),
                Some(5e-3),
                Some(1e-6),
                setting_label("1"),
            ),
        ]);
        assert_eq!(series.len(), 2);
        assert_eq!(series[0].labels, ["1 it", "10 it"]);
        assert_eq!(series[0].points.len(), series[0].labels.len());
        assert_eq!(log_tick_label(2e-3), "0.002");
        assert_eq!(log_tick_label(2.5e-3), "0.0025");
        assert_eq!(log_tick_label(6.0), "6");
        assert_eq!(log_tick_label(1e-5), "1e-5");
        assert_eq!(log_tick_label(2.5e6), "2.5e6");
    }
}
