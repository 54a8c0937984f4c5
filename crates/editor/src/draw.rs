//! Drawing an editor into a pixel buffer with tiny-skia: the walls, springs coloured by strain,
//! particles (pinned ones red with a ring), the pull's target, and a text overlay in DejaVu Sans
//! (rasterised by ab_glyph; the font ships in `assets/fonts`, so nothing needs system fonts).

use std::path::Path;
use std::time::Duration;

use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
use tiny_skia::{
    Color, FillRule, LineCap, Paint, PathBuilder, Pixmap, PremultipliedColorU8, Stroke, Transform,
};

use crate::{Editor, EditorError};

/// DejaVu Sans (Bitstream Vera licence, `assets/fonts/DejaVuSans-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

/// Spring colours by strain: `STRAIN_BUCKETS` buckets from compressed (blue) through rest (dark
/// grey, the seed's 0x444444) to stretched (red), saturating at |strain| = [`FULL_STRAIN`].
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
    /// it (`None` in headless replays, whose frames must not depend on the machine).
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
        // Springs, one path per strain bucket.
        let positions = editor.positions();
        for s in editor.springs() {
            let b = bucket_of(editor.strain(s));
            let (a, c) = (
                to_pixel(&positions[s.i as usize]),
                to_pixel(&positions[s.j as usize]),
            );
            self.buckets[b].move_to(a.0, a.1);
            self.buckets[b].line_to(c.0, c.1);
        }
        let stroke = Stroke {
            width: 2.0 * scale,
            line_cap: LineCap::Round,
            ..Stroke::default()
        };
        for b in 0..STRAIN_BUCKETS {
            let builder = std::mem::take(&mut self.buckets[b]);
            if let Some(path) = builder.finish() {
                paint.set_color(bucket_colour(b));
                self.pixmap
                    .stroke_path(&path, &paint, &stroke, Transform::identity(), None);
                self.buckets[b] = path.clear();
            }
        }
        // Particles: free dark, pinned red with a ring (seed: 0x111111 and 0xFF0000, radius 5).
        let radius = 5.0 * scale;
        let mut free = PathBuilder::new();
        let mut pinned = PathBuilder::new();
        for (p, &is_pinned) in positions.iter().zip(editor.pinned()) {
            let (x, y) = to_pixel(p);
            if is_pinned {
                pinned.push_circle(x, y, radius);
            } else {
                free.push_circle(x, y, radius);
            }
        }
        if let Some(path) = free.finish() {
            paint.set_color(rgb(0x111111));
            self.pixmap.fill_path(
                &path,
                &paint,
                FillRule::Winding,
                Transform::identity(),
                None,
            );
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
        self.overlay(editor, frame_time);
        &self.pixmap
    }

    fn overlay(&mut self, editor: &Editor, frame_time: Option<Duration>) {
        let size = self.pixmap.width() as f32;
        let px = 12.0 * size / 512.0;
        let line = px * 1.3;
        let margin = 6.0 * size / 512.0;
        let stats = editor.stats();
        let solver = match (stats.residual, editor.library_integrator().is_explicit()) {
            (_, true) => "solver: none (explicit)".to_string(),
            (Some(r), false) => format!(
                "solver: {} iterations this frame, last residual {r:.2e}{}",
                stats.iterations,
                if stats.clamped_substeps > 0 {
                    format!(", clamped Hessian in {}", stats.clamped_substeps)
                } else {
                    String::new()
                }
            ),
            (None, false) => "solver: -".to_string(),
        };
        let dashpot_note = if editor.integrator().models_dashpot() {
            ""
        } else {
            " (not modelled by pd)"
        };
        let time = match frame_time {
            Some(t) => format!("{:.1} ms", t.as_secs_f64() * 1e3),
            None => "-".to_string(),
        };
        let mut lines = vec![
            (
                "Left: add (shift: pinned, P: toggle pin); Right: attract; Middle: drag"
                    .to_string(),
                0x000000,
            ),
            (
                "C: clear; Space: pause; I: integrator; [ ]: substeps; S: save".to_string(),
                0x000000,
            ),
            (
                format!(
                    "integrator: {} ({} substeps of {:.2} ms)",
                    editor.integrator().name(),
                    editor.substeps(),
                    editor.substep() * 1e3
                ),
                0x000000,
            ),
            (solver, 0x000000),
            (format!("energy: {:.4} J", editor.energy()), 0x000000),
            (
                format!("Y: Young's modulus {:.1} N (k = Y/l)", editor.young()),
                0x000000,
            ),
            (format!("D: drag damping {:.2} /s", editor.drag()), 0x000000),
            (
                format!(
                    "X: dashpot damping {:.2} N s/m{dashpot_note}",
                    editor.dashpot()
                ),
                0x000000,
            ),
            (
                format!(
                    "{} particles, {} springs; frame {}; frame time {time}",
                    editor.particle_count(),
                    editor.springs().len(),
                    editor.frames()
                ),
                0x000000,
            ),
        ];
        if let Some(notice) = editor.notice() {
            lines.push((notice.to_string(), 0x804000));
        }
        if let Some(failure) = editor.failure() {
            let text = format!("FAILED, paused (space retries): {failure}");
            let width = size - 2.0 * margin;
            for piece in wrap(&self.font, px, &text, width) {
                lines.push((piece, 0xC00000));
            }
        } else if editor.is_paused() {
            lines.push(("PAUSED".to_string(), 0xC00000));
        }
        let mut baseline = margin + px;
        for (text, colour) in &lines {
            draw_text(
                &mut self.pixmap,
                &self.font,
                px,
                margin,
                baseline,
                text,
                *colour,
            );
            baseline += line;
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

/// Draw `text` with its baseline at `y`, starting at `x` (pixels), blending each glyph's coverage
/// over the (opaque) background.
fn draw_text(
    pixmap: &mut Pixmap,
    font: &FontRef<'_>,
    px: f32,
    x: f32,
    y: f32,
    text: &str,
    colour: u32,
) {
    let (w, h) = (pixmap.width() as i64, pixmap.height() as i64);
    let scaled = font.as_scaled(PxScale::from(px));
    let [r, g, b] = [(colour >> 16) as u8, (colour >> 8) as u8, colour as u8].map(f32::from);
    let pixels = pixmap.pixels_mut();
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
        outlined.draw(|gx, gy, coverage| {
            let (px_x, px_y) = (
                bounds.min.x as i64 + gx as i64,
                bounds.min.y as i64 + gy as i64,
            );
            if px_x < 0 || px_y < 0 || px_x >= w || px_y >= h {
                return;
            }
            let pixel = &mut pixels[(px_y * w + px_x) as usize];
            let a = coverage.clamp(0.0, 1.0);
            let mix = |dst: u8, src: f32| (src * a + f32::from(dst) * (1.0 - a)).round() as u8;
            if let Some(blended) = PremultipliedColorU8::from_rgba(
                mix(pixel.red(), r),
                mix(pixel.green(), g),
                mix(pixel.blue(), b),
                255,
            ) {
                *pixel = blended;
            }
        });
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
}
