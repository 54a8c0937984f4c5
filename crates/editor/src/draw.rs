//! Drawing an editor into a pixel buffer with tiny-skia: the walls, springs coloured by strain,
//! particles (pinned ones red with a ring), the pull's target, and a text overlay in DejaVu Sans
//! (rasterised by ab_glyph; the font ships in `assets/fonts`, so nothing needs system fonts).
//!
//! The overlay sits on a translucent band along the top or the bottom edge, whichever the
//! particles leave free (the top when both are, the one with fewer particles when neither is),
//! so that it does not hide the structure.

use std::path::Path;
use std::time::Duration;

use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
use tiny_skia::{
    Color, FillRule, Mask, Paint, PathBuilder, Pixmap, PremultipliedColorU8, Stroke, Transform,
};

use crate::{Editor, EditorError};

/// DejaVu Sans (Bitstream Vera licence, `assets/fonts/DejaVuSans-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

/// Spring colours by strain: `STRAIN_BUCKETS` buckets from compressed (blue) through rest (dark
/// grey, 0x444444) to stretched (red), saturating at |strain| = [`FULL_STRAIN`].
const STRAIN_BUCKETS: usize = 9;
/// The strain |r|/l − 1 drawn with the full colour.
pub const FULL_STRAIN: f64 = 0.25;

/// Smallest and largest frame side, pixels.
pub const FRAME_SIZES: std::ops::RangeInclusive<u32> = 64..=4096;

/// Draws editors into a square pixmap whose side is the unit box (y up). Keeps its paths and
/// font between frames.
pub struct Renderer {
    pixmap: Pixmap,
    font: FontRef<'static>,
    buckets: Vec<PathBuilder>,
    pinned_path: PathBuilder,
    discs: DiscStamps,
    text_cache: Vec<CachedLine>,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer")
            .field("size", &self.pixmap.width())
            .finish()
    }
}

fn rgb(hex: u32) -> Color {
    Color::from_rgba8((hex >> 16) as u8, (hex >> 8) as u8, hex as u8, 255)
}

/// The colour of strain bucket `b` (0 most compressed, middle at rest, last most stretched).
fn bucket_colour(b: usize) -> Color {
    let middle = (STRAIN_BUCKETS / 2) as f32;
    let t = (b as f32 - middle) / middle; // −1 … 1
    let rest = [0x44 as f32, 0x44 as f32, 0x44 as f32];
    let end = if t < 0.0 {
        [0x20 as f32, 0x60 as f32, 0xF0 as f32]
    } else {
        [0xE0 as f32, 0x20 as f32, 0x20 as f32]
    };
    let s = t.abs();
    let c = |a: usize| (rest[a] + (end[a] - rest[a]) * s).round() as u8;
    Color::from_rgba8(c(0), c(1), c(2), 255)
}

/// The colour of a free particle (0x111111).
const FREE_PARTICLE: u32 = 0x111111;

/// How far (pixels) along a spring of half-width `half_width` from a particle's centre the particle's
/// disc of `radius` covers the whole width of the stroke, less a margin of 0.75 px so that the
/// disc's anti-aliased rim still has the spring under it.
fn covered_length(radius: f32, half_width: f32) -> f32 {
    let inner = (radius - 0.75).max(0.0);
    (inner * inner - half_width * half_width).max(0.0).sqrt()
}

fn bucket_of(strain: f64) -> usize {
    let middle = (STRAIN_BUCKETS / 2) as f64;
    let t = (strain / FULL_STRAIN).clamp(-1.0, 1.0);
    ((middle + t * middle).round() as usize).min(STRAIN_BUCKETS - 1)
}

impl Renderer {
    /// A renderer of `size` × `size` pixels.
    ///
    /// # Errors
    /// [`EditorError::FrameSize`] outside [`FRAME_SIZES`].
    pub fn new(size: u32) -> Result<Self, EditorError> {
        if !FRAME_SIZES.contains(&size) {
            return Err(EditorError::FrameSize { size });
        }
        let pixmap = Pixmap::new(size, size).ok_or(EditorError::FrameSize { size })?;
        let font = FontRef::try_from_slice(FONT).expect("the bundled font parses");
        Ok(Renderer {
            pixmap,
            font,
            buckets: (0..STRAIN_BUCKETS).map(|_| PathBuilder::new()).collect(),
            pinned_path: PathBuilder::new(),
            discs: DiscStamps::new(5.0 * size as f32 / 512.0),
            text_cache: Vec::new(),
        })
    }

    /// Pixels per side.
    pub fn size(&self) -> u32 {
        self.pixmap.width()
    }

    /// The last frame drawn.
    pub fn pixmap(&self) -> &Pixmap {
        &self.pixmap
    }

    /// Draw `editor`. `frame_time` is the wall time of the last frame as the front end measured
    /// it (`None` in headless replays, whose frames must not depend on the machine). The overlay
    /// names the frame by its 0-based index, as a replay names its file (`frame_0000.png` is the
    /// frame after the first advance), and gives the simulated time a frame covers.
    pub fn render(&mut self, editor: &Editor, frame_time: Option<Duration>) -> &Pixmap {
        let size = self.pixmap.width() as f32;
        let scale = size / 512.0;
        let to_pixel = |p: &crate::Vec2| (p.x as f32 * size, (1.0 - p.y as f32) * size);
        self.pixmap.fill(rgb(0xDDDDDD));
        let mut paint = Paint {
            anti_alias: true,
            ..Paint::default()
        };
        // Walls: the unit box is the whole frame.
        let wall = (3.0 * scale).max(1.0);
        if let Some(rect) =
            tiny_skia::Rect::from_xywh(wall / 2.0, wall / 2.0, size - wall, size - wall)
        {
            let path = PathBuilder::from_rect(rect);
            paint.set_color(rgb(0x555555));
            let stroke = Stroke {
                width: wall,
                ..Stroke::default()
            };
            self.pixmap
                .stroke_path(&path, &paint, &stroke, Transform::identity(), None);
        }
        // Springs: one path per strain bucket, each spring the rectangle of its stroke between
        // the two discs that cover its ends (the parts under them never show, and in a dense net
        // they are most of every spring).
        let positions = editor.positions();
        let radius = 5.0 * scale;
        let half_width = scale;
        let hidden = covered_length(radius, half_width);
        for s in editor.springs() {
            let b = bucket_of(editor.strain(s));
            let (a, c) = (
                to_pixel(&positions[s.i as usize]),
                to_pixel(&positions[s.j as usize]),
            );
            let (dx, dy) = (c.0 - a.0, c.1 - a.1);
            let length = (dx * dx + dy * dy).sqrt();
            if length.is_nan() || length <= 2.0 * hidden {
                continue;
            }
            let (ux, uy) = (dx / length, dy / length);
            let (nx, ny) = (-uy * half_width, ux * half_width);
            let (a, c) = (
                (a.0 + ux * hidden, a.1 + uy * hidden),
                (c.0 - ux * hidden, c.1 - uy * hidden),
            );
            let path = &mut self.buckets[b];
            path.move_to(a.0 + nx, a.1 + ny);
            path.line_to(c.0 + nx, c.1 + ny);
            path.line_to(c.0 - nx, c.1 - ny);
            path.line_to(a.0 - nx, a.1 - ny);
            path.close();
        }
        for b in 0..STRAIN_BUCKETS {
            let builder = std::mem::take(&mut self.buckets[b]);
            if let Some(path) = builder.finish() {
                paint.set_color(bucket_colour(b));
                self.pixmap.fill_path(
                    &path,
                    &paint,
                    FillRule::Winding,
                    Transform::identity(),
                    None,
                );
                self.buckets[b] = path.clear();
            }
        }
        // Particles: free dark, stamped; pinned red with a ring (0x111111 and 0xFF0000,
        // radius 5).
        let mut pinned = std::mem::take(&mut self.pinned_path);
        // Stamped in order; the pinned discs go on top, as one path.
        for (p, &is_pinned) in positions.iter().zip(editor.pinned()) {
            let (x, y) = to_pixel(p);
            if is_pinned {
                pinned.push_circle(x, y, radius);
            } else {
                self.discs.stamp(&mut self.pixmap, x, y, FREE_PARTICLE);
            }
        }
        if let Some(path) = pinned.finish() {
            paint.set_color(rgb(0xFF0000));
            self.pixmap.fill_path(
                &path,
                &paint,
                FillRule::Winding,
                Transform::identity(),
                None,
            );
            paint.set_color(rgb(0x000000));
            let ring = Stroke {
                width: 1.5 * scale,
                ..Stroke::default()
            };
            self.pixmap
                .stroke_path(&path, &paint, &ring, Transform::identity(), None);
            self.pinned_path = path.clear();
        }
        // The pull's target and the dragged particle.
        let (cursor, attracting) = editor.cursor();
        if attracting {
            let (x, y) = to_pixel(&cursor);
            if let Some(path) = PathBuilder::from_circle(x, y, 8.0 * scale) {
                paint.set_color(rgb(0x2080FF));
                let ring = Stroke {
                    width: 1.5 * scale,
                    ..Stroke::default()
                };
                self.pixmap
                    .stroke_path(&path, &paint, &ring, Transform::identity(), None);
            }
        }
        if let Some(v) = editor.dragging() {
            let (x, y) = to_pixel(&positions[v]);
            if let Some(path) = PathBuilder::from_circle(x, y, radius + 3.0 * scale) {
                paint.set_color(rgb(0x20A040));
                let ring = Stroke {
                    width: 2.0 * scale,
                    ..Stroke::default()
                };
                self.pixmap
                    .stroke_path(&path, &paint, &ring, Transform::identity(), None);
            }
        }
        self.overlay(editor, frame_time, radius);
        &self.pixmap
    }

    fn overlay(&mut self, editor: &Editor, frame_time: Option<Duration>, radius: f32) {
        let size = self.pixmap.width() as f32;
        let px = 12.0 * size / 512.0;
        let margin = 6.0 * size / 512.0;
        let line_height = px * 1.3;
        // Rare (the editor pauses on it): wrapping may allocate.
        let failure = editor.failure().map(|f| {
            wrap(
                &self.font,
                px,
                &format!("FAILED, paused (space retries): {f}"),
                size - 2.0 * margin,
            )
        });
        let lines = OVERLAY_LINES
            + usize::from(editor.notice().is_some())
            + failure
                .as_ref()
                .map_or(usize::from(editor.is_paused()), Vec::len);
        let band = 2.0 * margin + lines as f32 * line_height;
        let top = overlay_at_top(editor.positions(), size, band + radius);
        let band_top = if top { 0.0 } else { size - band };
        if let Some(rect) = tiny_skia::Rect::from_xywh(0.0, band_top, size, band) {
            let paint = Paint {
                shader: tiny_skia::Shader::SolidColor(Color::from_rgba8(0xF4, 0xF4, 0xF4, 0xC8)),
                ..Paint::default()
            };
            self.pixmap
                .fill_rect(rect, &paint, Transform::identity(), None);
        }
        let mut text = Text {
            pixmap: &mut self.pixmap,
            font: &self.font,
            cache: &mut self.text_cache,
            px,
            x: margin,
            line_height,
            // The descent of the last line stays inside the band.
            first_baseline: band_top + margin + px * 0.95,
            slot: 0,
        };
        const BLACK: u32 = 0x000000;
        const RED: u32 = 0xC00000;
        text.line(
            format_args!("Left: add (shift: pinned, P: toggle pin); Right: attract; Middle: drag"),
            BLACK,
        );
        text.line(
            format_args!("C: clear; Space: pause; I: integrator; [ ]: substeps; S: save"),
            BLACK,
        );
        let (integrator, substeps, substep) = (
            editor.integrator().name(),
            editor.substeps(),
            editor.substep() * 1e3,
        );
        let stats = editor.stats();
        match (stats.residual, editor.library_integrator().is_explicit()) {
            (_, true) => text.line(
                format_args!("{integrator}, {substeps} substeps of {substep:.2} ms; explicit"),
                BLACK,
            ),
            (Some(r), false) if stats.clamped_substeps > 0 => text.line(
                format_args!(
                    "{integrator}, {substeps} substeps of {substep:.2} ms; {} iterations, \
                     residual {r:.1e}, clamped Hessian in {}",
                    stats.iterations, stats.clamped_substeps
                ),
                BLACK,
            ),
            (Some(r), false) => text.line(
                format_args!(
                    "{integrator}, {substeps} substeps of {substep:.2} ms; {} iterations, \
                     residual {r:.1e}",
                    stats.iterations
                ),
                BLACK,
            ),
            (None, false) => text.line(
                format_args!("{integrator}, {substeps} substeps of {substep:.2} ms; solver: -"),
                BLACK,
            ),
        }
        text.line(
            format_args!(
                "Y: Young's modulus {:.1} N (k = Y/l); D: drag {:.2} /s",
                editor.young(),
                editor.drag()
            ),
            BLACK,
        );
        let dashpot_note = if editor.integrator().models_dashpot() {
            ""
        } else {
            " (not modelled by pd)"
        };
        text.line(
            format_args!(
                "X: dashpot {:.2} N s/m{dashpot_note}; energy {:.4} J",
                editor.dashpot(),
                editor.energy()
            ),
            BLACK,
        );
        let (particles, springs) = (editor.particle_count(), editor.springs().len());
        // The index of the frame shown: a replay's frame_NNNN.png is drawn after NNNN + 1 advances.
        let frame = editor.frames().saturating_sub(1);
        // The simulated time a frame covers; the window adds the wall time it took.
        let simulated = editor.params().frame_time * 1e3;
        match frame_time {
            Some(t) => text.line(
                format_args!(
                    "{particles} particles, {springs} springs; frame {frame}; frame time \
                     {simulated:.1} ms (took {:.1} ms)",
                    t.as_secs_f64() * 1e3
                ),
                BLACK,
            ),
            None => text.line(
                format_args!(
                    "{particles} particles, {springs} springs; frame {frame}; frame time \
                     {simulated:.1} ms"
                ),
                BLACK,
            ),
        }
        if let Some(notice) = editor.notice() {
            text.line(format_args!("{notice}"), 0x804000);
        }
        if let Some(failure) = failure {
            for piece in failure {
                text.line(format_args!("{piece}"), RED);
            }
        } else if editor.is_paused() {
            text.line(format_args!("PAUSED"), RED);
        }
    }

    /// Write the last frame as a PNG, atomically (a temporary file in the same directory, then a
    /// rename): an interrupted run never leaves half a frame.
    ///
    /// # Errors
    /// [`EditorError::Write`] naming the file.
    pub fn save_png(&self, path: &Path) -> Result<(), EditorError> {
        let bytes = self.pixmap.encode_png().map_err(|e| EditorError::Write {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        crate::write_atomically(path, &bytes)
    }
}

/// Lines the overlay always has: two of help, the integrator and solver, the parameters (two), the
/// counts and frame.
const OVERLAY_LINES: usize = 6;

/// Whether the overlay's band of `band` pixels (particle radius included) goes along the top edge
/// of a `size`-pixel frame: when no particle is in the top band, or when fewer are there than in
/// the bottom band.
fn overlay_at_top(positions: &[crate::Vec2], size: f32, band: f32) -> bool {
    let limit = f64::from(band / size);
    let (mut top, mut bottom) = (0usize, 0usize);
    for p in positions {
        top += usize::from(p.y >= 1.0 - limit);
        bottom += usize::from(p.y <= limit);
    }
    top == 0 || top <= bottom
}

/// Split `text` into lines no wider than `width` pixels, at spaces.
fn wrap(font: &FontRef<'_>, px: f32, text: &str, width: f32) -> Vec<String> {
    let mut lines = Vec::new();
    let mut current = String::new();
    for word in text.split(' ') {
        let candidate = if current.is_empty() {
            word.to_string()
        } else {
            format!("{current} {word}")
        };
        if !current.is_empty() && text_width(font, px, &candidate) > width {
            lines.push(std::mem::replace(&mut current, word.to_string()));
        } else {
            current = candidate;
        }
    }
    if !current.is_empty() {
        lines.push(current);
    }
    lines
}

fn text_width(font: &FontRef<'_>, px: f32, text: &str) -> f32 {
    let scaled = font.as_scaled(PxScale::from(px));
    text.chars()
        .map(|c| scaled.h_advance(font.glyph_id(c)))
        .sum()
}

/// Subpixel positions per axis at which the disc is rasterised in advance: a stamped disc is at
/// most 1/16 px from where it should be.
const PHASES: i32 = 8;

/// A particle's disc rasterised once per subpixel phase (tiny-skia's anti-aliased fill into a
/// coverage mask) and stamped at every free particle: a thousand discs cost a thousand small blends
/// instead of one anti-aliased path of four thousand conic edges, sorted and scanned.
struct DiscStamps {
    /// Pixels per side of every mask.
    side: i32,
    /// From a mask's top-left pixel to the pixel of the disc's centre at phase 0.
    offset: i32,
    /// Coverage masks, phase (px, py) at index py · PHASES + px.
    masks: Vec<Mask>,
}

impl DiscStamps {
    fn new(radius: f32) -> Self {
        let offset = radius.ceil() as i32 + 1;
        let side = 2 * offset + 2;
        let masks = (0..PHASES * PHASES)
            .map(|k| {
                let (px, py) = (k % PHASES, k / PHASES);
                let mut mask = Mask::new(side as u32, side as u32).expect("a small mask");
                let centre = |phase: i32| offset as f32 + phase as f32 / PHASES as f32;
                if let Some(path) = PathBuilder::from_circle(centre(px), centre(py), radius) {
                    mask.fill_path(&path, FillRule::Winding, true, Transform::identity());
                }
                mask
            })
            .collect();
        DiscStamps {
            side,
            offset,
            masks,
        }
    }

    /// Blend `colour` in the disc centred at (x, y) (pixels) over the opaque frame.
    fn stamp(&self, pixmap: &mut Pixmap, x: f32, y: f32, colour: u32) {
        // Saturating casts: a position far outside (or not finite) lands outside the frame.
        let (qx, qy) = (
            (x * PHASES as f32).round() as i64,
            (y * PHASES as f32).round() as i64,
        );
        let phase = qy.rem_euclid(PHASES.into()) * i64::from(PHASES) + qx.rem_euclid(PHASES.into());
        let mask = &self.masks[phase as usize];
        let left = qx.div_euclid(PHASES.into()) - i64::from(self.offset);
        let top = qy.div_euclid(PHASES.into()) - i64::from(self.offset);
        let (w, h) = (i64::from(pixmap.width()), i64::from(pixmap.height()));
        let side = i64::from(self.side);
        let columns = left.max(0)..(left + side).min(w);
        let rows = top.max(0)..(top + side).min(h);
        if columns.is_empty() || rows.is_empty() {
            return;
        }
        let rgb = channels(colour);
        let coverage = mask.data();
        let pixels = pixmap.pixels_mut();
        for row in rows {
            let mask_row = ((row - top) * side) as usize;
            let frame_row = (row * w) as usize;
            for column in columns.clone() {
                let c = coverage[mask_row + (column - left) as usize];
                if c != 0 {
                    mix(&mut pixels[frame_row + column as usize], rgb, c);
                }
            }
        }
    }
}

/// The red, green and blue of `0xRRGGBB`.
fn channels(colour: u32) -> [u8; 3] {
    [(colour >> 16) as u8, (colour >> 8) as u8, colour as u8]
}

/// `pixel` ← (`coverage` · colour + (255 − `coverage`) · `pixel`) / 255, rounded, opaque (integer
/// arithmetic: a float round per channel cost more than the rest of a stamp).
#[inline]
fn mix(pixel: &mut PremultipliedColorU8, [r, g, b]: [u8; 3], coverage: u8) {
    let c = u32::from(coverage);
    let blend =
        |dst: u8, src: u8| ((u32::from(src) * c + u32::from(dst) * (255 - c) + 127) / 255) as u8;
    if let Some(blended) = PremultipliedColorU8::from_rgba(
        blend(pixel.red(), r),
        blend(pixel.green(), g),
        blend(pixel.blue(), b),
        255,
    ) {
        *pixel = blended;
    }
}

/// One overlay line as last rasterised: its text and the coverage of every glyph pixel in drawing
/// order (pixel index, coverage 0–255), so that an unchanged line is blended again without
/// outlining a glyph, to the same bits.
#[derive(Default)]
struct CachedLine {
    text: String,
    /// The baseline the coverage was rasterised at (pixels): the overlay moves between edges.
    baseline: f32,
    coverage: Vec<(u32, u8)>,
}

/// The overlay being drawn: where the next line goes and the cache of the lines drawn before.
struct Text<'a> {
    pixmap: &'a mut Pixmap,
    font: &'a FontRef<'static>,
    cache: &'a mut Vec<CachedLine>,
    /// Font size, pixels.
    px: f32,
    /// Left edge of the text, pixels.
    x: f32,
    line_height: f32,
    first_baseline: f32,
    /// The next line's index.
    slot: usize,
}

impl Text<'_> {
    /// Draw the next line: formatted into the slot's cached text, rasterised only if it changed.
    fn line(&mut self, text: std::fmt::Arguments<'_>, colour: u32) {
        use std::fmt::Write as _;
        if self.cache.len() <= self.slot {
            self.cache.push(CachedLine::default());
        }
        let baseline = self.first_baseline + self.slot as f32 * self.line_height;
        let cached = &mut self.cache[self.slot];
        self.slot += 1;
        let previous_length = cached.text.len();
        // Append, then compare with what the slot held: no allocation once the capacity is there.
        write!(cached.text, "{text}").expect("formatting into a String does not fail");
        let (old, new) = cached.text.split_at(previous_length);
        if old != new || cached.baseline != baseline {
            cached.text.drain(..previous_length);
            cached.baseline = baseline;
            let (w, h) = (self.pixmap.width(), self.pixmap.height());
            rasterise(
                self.font,
                self.px,
                self.x,
                baseline,
                &cached.text,
                (w, h),
                &mut cached.coverage,
            );
        } else {
            cached.text.truncate(previous_length);
        }
        blend(self.pixmap, &cached.coverage, colour);
    }
}

/// The coverage of `text` with its baseline at `y`, starting at `x` (pixels), glyph by glyph in
/// drawing order, pixels outside a `width` × `height` frame left out.
fn rasterise(
    font: &FontRef<'_>,
    px: f32,
    x: f32,
    y: f32,
    text: &str,
    (width, height): (u32, u32),
    coverage: &mut Vec<(u32, u8)>,
) {
    coverage.clear();
    let (w, h) = (i64::from(width), i64::from(height));
    let scaled = font.as_scaled(PxScale::from(px));
    let mut caret = x;
    let mut previous = None;
    for c in text.chars() {
        let id = font.glyph_id(c);
        if let Some(p) = previous {
            caret += scaled.kern(p, id);
        }
        previous = Some(id);
        let glyph = id.with_scale_and_position(PxScale::from(px), ab_glyph::point(caret, y));
        caret += scaled.h_advance(id);
        let Some(outlined) = font.outline_glyph(glyph) else {
            continue;
        };
        let bounds = outlined.px_bounds();
        outlined.draw(|gx, gy, a| {
            let (px_x, px_y) = (
                bounds.min.x as i64 + i64::from(gx),
                bounds.min.y as i64 + i64::from(gy),
            );
            let a = (a.clamp(0.0, 1.0) * 255.0).round() as u8;
            if px_x < 0 || px_y < 0 || px_x >= w || px_y >= h || a == 0 {
                return;
            }
            coverage.push(((px_y * w + px_x) as u32, a));
        });
    }
}

/// Blend `colour` over the (opaque) frame with each pixel's coverage, in order.
fn blend(pixmap: &mut Pixmap, coverage: &[(u32, u8)], colour: u32) {
    let rgb = channels(colour);
    let pixels = pixmap.pixels_mut();
    for &(index, a) in coverage {
        mix(&mut pixels[index as usize], rgb, a);
    }
}

/// The frame as 0RGB words, as minifb shows them.
pub fn to_0rgb(pixmap: &Pixmap, out: &mut Vec<u32>) {
    out.clear();
    out.extend(
        pixmap.pixels().iter().map(|p| {
            (u32::from(p.red()) << 16) | (u32::from(p.green()) << 8) | u32::from(p.blue())
        }),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strain_buckets_span_blue_to_red() {
        assert_eq!(bucket_of(0.0), STRAIN_BUCKETS / 2);
        assert_eq!(bucket_of(-10.0), 0);
        assert_eq!(bucket_of(10.0), STRAIN_BUCKETS - 1);
        let rest = bucket_colour(STRAIN_BUCKETS / 2);
        assert_eq!(rest, rgb(0x444444));
        let stretched = bucket_colour(STRAIN_BUCKETS - 1).to_color_u8();
        assert!(stretched.red() > 200 && stretched.blue() < 50);
        let compressed = bucket_colour(0).to_color_u8();
        assert!(compressed.blue() > 200 && compressed.red() < 50);
    }

    #[test]
    fn the_overlay_goes_to_the_edge_the_particles_leave_free() {
        let at = |points: &[(f64, f64)]| {
            let positions: Vec<crate::Vec2> = points
                .iter()
                .map(|&(x, y)| crate::Vec2::new(x, y))
                .collect();
            // A band of 100 px of a 512 px frame: y above 0.805 is under a top band.
            overlay_at_top(&positions, 512.0, 100.0)
        };
        assert!(at(&[]));
        // Fallen to the floor: the top is free.
        assert!(at(&[(0.3, 0.05), (0.5, 0.1)]));
        // Hanging from the top: the bottom is free.
        assert!(!at(&[(0.3, 0.95), (0.5, 0.5)]));
        // Both edges used: the one with fewer particles.
        assert!(!at(&[(0.3, 0.95), (0.4, 0.9), (0.5, 0.05)]));
        assert!(at(&[(0.3, 0.95), (0.4, 0.05), (0.5, 0.1)]));
    }

    #[test]
    fn the_overlay_band_is_drawn_where_the_particles_are_not() {
        // The seed's three particles sit low (y 0.3 to 0.4): the band is along the top, and the
        // frame's bottom rows keep the background.
        let editor = Editor::seed(crate::EditorParams::default()).unwrap();
        let mut renderer = Renderer::new(512).unwrap();
        let frame = renderer.render(&editor, None);
        let pixel = |x: u32, y: u32| frame.pixel(x, y).unwrap();
        let background = rgb(0xDDDDDD).to_color_u8().premultiply();
        // Right of the text, inside the walls: the band's translucent white over the background.
        assert!(
            pixel(505, 20).red() > background.red(),
            "{:?}",
            pixel(505, 20)
        );
        assert_eq!(pixel(505, 400), background);
    }
}
