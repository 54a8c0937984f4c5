//! The PNG preview of a run's last frame.
//!
//! 3D meshes are seen through a fixed oblique orthographic camera (azimuth 35° about the y axis,
//! elevation 25°, y up in the picture), fitted into the image with their aspect ratio kept.
//! Triangles are filled back to front (painter's algorithm) with two-sided flat Lambert shading:
//! the side whose normal (by the triangle's winding) faces the camera is blue, the other side
//! orange, so that folds read clearly; a legend under the caption says which is which. Without
//! triangles the springs are drawn as lines, darker when nearer. Obstacles are drawn behind the
//! mesh: a ground plane as a gridded patch, a sphere as a shaded disc, a box (a container) as its
//! far walls, with its near edges drawn over the mesh. 2D scenes show their box, springs as lines
//! and particles as discs, y up. Pinned vertices are red in both.
//!
//! [`ScenePreview`] builds the picture's input, caption included, from a scene and a frame, so
//! that the counts the caption gives are the scene's.
//!
//! The picture is drawn at twice its size and averaged down (anti-aliasing). Text uses the
//! DejaVu Sans font embedded in the program, so no system font is needed. Non-finite positions
//! are skipped (with everything that touches them) and counted in the picture's caption.

use std::path::Path;
use std::sync::OnceLock;

use nalgebra::{SVector, Vector2, Vector3};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::register_font;

use super::{write_png, OutputError};
use crate::sim::{Integrator, Scene, Shape};

/// Default width of the preview, in pixels.
pub const PREVIEW_WIDTH: u32 = 800;
/// Default height of the preview, in pixels.
pub const PREVIEW_HEIGHT: u32 = 600;

/// Largest accepted width or height, in pixels.
const MAX_SIDE: u32 = 8192;
/// Supersampling factor: the picture is drawn this many times larger in each direction.
const SS: u32 = 2;
/// The font family name the embedded font is registered under.
const FONT: &str = "sans-serif";
/// DejaVu Sans (see `assets/fonts/DejaVuSans-LICENSE.txt`).
static FONT_BYTES: &[u8] = include_bytes!("../../../../assets/fonts/DejaVuSans.ttf");

/// Camera azimuth about the y axis, in degrees (0 looks along −z).
const AZIMUTH_DEG: f64 = 35.0;
/// Camera elevation above the x–z plane, in degrees.
const ELEVATION_DEG: f64 = 25.0;

// Colours.
const BACKGROUND: RGBColor = RGBColor(247, 248, 250);
const TEXT: RGBColor = RGBColor(30, 32, 36);
const TEXT_DIM: RGBColor = RGBColor(105, 110, 120);
const WARNING: RGBColor = RGBColor(190, 30, 30);
/// Cloth colour of the side whose normal faces the camera.
const FRONT: [f64; 3] = [80.0, 140.0, 215.0];
/// Cloth colour of the other side.
const BACK: [f64; 3] = [235.0, 165.0, 90.0];
const PINNED: RGBColor = RGBColor(220, 30, 30);
const PINNED_RIM: RGBColor = RGBColor(110, 0, 0);
const PARTICLE: RGBColor = RGBColor(40, 90, 160);
const SPRING_2D: RGBColor = RGBColor(120, 135, 160);
const BOX_EDGE: RGBColor = RGBColor(60, 64, 72);

const GROUND: RGBColor = RGBColor(214, 218, 210);
const GROUND_LINE: RGBColor = RGBColor(176, 182, 170);
const SPHERE: [f64; 3] = [150.0, 154.0, 162.0];
/// Fill of a box obstacle's far walls (seen from inside).
const BOX_WALL: RGBColor = RGBColor(226, 230, 236);
/// Edges of a box obstacle.
const BOX_WIRE: RGBColor = RGBColor(110, 116, 128);

/// An obstacle of a 3D contact scene, drawn behind the mesh (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PreviewObstacle {
    /// A plane through `point` with unit `normal`: drawn as a square patch under the mesh's
    /// footprint, with grid lines.
    Plane {
        /// A point of the plane, m.
        point: Vector3<f64>,
        /// Its unit normal.
        normal: Vector3<f64>,
    },
    /// A solid sphere, drawn as a shaded disc.
    Sphere {
        /// Centre, m.
        center: Vector3<f64>,
        /// Radius, m.
        radius: f64,
    },
    /// An axis-aligned box that keeps the mesh inside (a container): its three far walls are
    /// filled behind the mesh, its three near edges drawn over it.
    Box {
        /// Lower corner, m.
        min: Vector3<f64>,
        /// Upper corner, m.
        max: Vector3<f64>,
    },
}

/// Vertex positions of the frame to draw.
#[derive(Debug, Clone, Copy)]
pub enum PreviewPositions<'a> {
    /// A 2D scene (x right, y up).
    Two(&'a [Vector2<f64>]),
    /// A 3D scene (y up).
    Three(&'a [Vector3<f64>]),
}

impl PreviewPositions<'_> {
    /// Number of vertices.
    fn len(&self) -> usize {
        match self {
            PreviewPositions::Two(p) => p.len(),
            PreviewPositions::Three(p) => p.len(),
        }
    }
}

/// Everything the preview shows. Indices refer to `positions`; out-of-range indices are skipped.
#[derive(Debug, Clone, Copy)]
pub struct PreviewInput<'a> {
    /// Caption, e.g. `"cloth-40 · newton · t = 1.000 s"`.
    pub title: &'a str,
    /// Vertex positions, in metres.
    pub positions: PreviewPositions<'a>,
    /// Surface triangles (3D: filled and shaded; 2D: filled lightly). May be empty.
    pub triangles: &'a [[u32; 3]],
    /// Springs to draw. In 3D they are drawn only when there are no triangles.
    pub lines: &'a [[u32; 2]],
    /// The number of springs of the mesh, for the caption (a cloth's springs are not drawn, so
    /// `lines` may be empty).
    pub springs: usize,
    /// Pinned vertices, drawn as red dots.
    pub pinned: &'a [u32],
    /// The box of a 2D scene as (min, max) corners; the view is fitted to it. `None` fits the
    /// view to the particles. Ignored in 3D.
    pub bounds_2d: Option<([f64; 2], [f64; 2])>,
    /// Obstacles of a 3D scene, drawn behind the mesh; the view is fitted to them too. Ignored
    /// in 2D.
    pub obstacles: &'a [PreviewObstacle],
}

/// A mass-spring scene's frame, ready to draw: what [`PreviewInput`] borrows, taken from the scene
/// itself (its mesh, pins and obstacles) so that the picture and its caption cannot disagree with
/// it.
#[derive(Debug, Clone)]
pub struct ScenePreview<'a> {
    title: String,
    positions: OwnedPositions,
    triangles: &'a [[u32; 3]],
    lines: Vec<[u32; 2]>,
    springs: usize,
    pinned: &'a [u32],
    bounds_2d: Option<([f64; 2], [f64; 2])>,
    obstacles: Vec<PreviewObstacle>,
}

/// Positions copied into the preview's vector types.
#[derive(Debug, Clone)]
enum OwnedPositions {
    Two(Vec<Vector2<f64>>),
    Three(Vec<Vector3<f64>>),
}

impl<'a> ScenePreview<'a> {
    /// Frame `frame` (its file's number) of `scene`, named `name`, at `time` (s), stepped by
    /// `integrator`, with vertex positions `positions` (m, one per mesh vertex).
    ///
    /// The caption's title names the scene, frame, time and integrator; its second line counts
    /// the mesh's vertices, triangles and springs (all springs, drawn or not: a cloth is drawn as
    /// its triangles) and the pinned vertices. A 3D scene's obstacles are drawn; a 2D scene's box
    /// is the view.
    pub fn of<const D: usize>(
        name: &str,
        scene: &'a Scene<D>,
        positions: &[SVector<f64, D>],
        frame: usize,
        time: f64,
        integrator: Integrator,
    ) -> Self {
        let mesh = scene.mesh();
        let lines = if mesh.triangles().is_empty() {
            mesh.springs().iter().map(|s| [s.i, s.j]).collect()
        } else {
            Vec::new()
        };
        let v3 = |p: &SVector<f64, D>| Vector3::new(p[0], p[1], p[2]);
        let (positions, bounds_2d, obstacles) = if D == 3 {
            let obstacles = scene
                .contacts()
                .iter()
                .filter_map(|c| match c.shape {
                    Shape::Plane { point, normal } => Some(PreviewObstacle::Plane {
                        point: v3(&point),
                        normal: v3(&normal),
                    }),
                    Shape::Sphere { center, radius } => Some(PreviewObstacle::Sphere {
                        center: v3(&center),
                        radius,
                    }),
                    Shape::Box { min, max } => Some(PreviewObstacle::Box {
                        min: v3(&min),
                        max: v3(&max),
                    }),
                    // A shape added to the library later is left out until it is drawn.
                    _ => None,
                })
                .collect();
            (
                OwnedPositions::Three(positions.iter().map(v3).collect()),
                None,
                obstacles,
            )
        } else {
            let bounds = scene.contacts().iter().find_map(|c| match c.shape {
                Shape::Box { min, max } => Some(([min[0], min[1]], [max[0], max[1]])),
                _ => None,
            });
            (
                OwnedPositions::Two(positions.iter().map(|p| Vector2::new(p[0], p[1])).collect()),
                bounds,
                Vec::new(),
            )
        };
        ScenePreview {
            title: format!("{name} · frame {frame} · t = {time:.3} s · {integrator}"),
            positions,
            triangles: mesh.triangles(),
            lines,
            springs: mesh.springs().len(),
            pinned: scene.pinned(),
            bounds_2d,
            obstacles,
        }
    }

    /// The input to [`render_preview`].
    pub fn input(&self) -> PreviewInput<'_> {
        PreviewInput {
            title: &self.title,
            positions: match &self.positions {
                OwnedPositions::Two(p) => PreviewPositions::Two(p),
                OwnedPositions::Three(p) => PreviewPositions::Three(p),
            },
            triangles: self.triangles,
            lines: &self.lines,
            springs: self.springs,
            pinned: self.pinned,
            bounds_2d: self.bounds_2d,
            obstacles: &self.obstacles,
        }
    }

    /// The caption's two lines: the title and the counts ([`detail_line`]).
    pub fn caption(&self) -> [String; 2] {
        [self.title.clone(), detail_line(&self.input())]
    }
}

/// The four corners of the patch of `plane` (point, unit normal) drawn under `positions`: their
/// footprint on the plane, grown by a quarter on every side (a unit square about the point if
/// there is none).
fn plane_patch(
    point: &Vector3<f64>,
    normal: &Vector3<f64>,
    positions: &[Vector3<f64>],
) -> [Vector3<f64>; 4] {
    let helper = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let t1 = normal.cross(&helper).normalize();
    let t2 = normal.cross(&t1);
    let (mut lo, mut hi) = (
        (f64::INFINITY, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for p in positions.iter().filter(|p| p.iter().all(|x| x.is_finite())) {
        let (a, b) = ((p - point).dot(&t1), (p - point).dot(&t2));
        lo = (lo.0.min(a), lo.1.min(b));
        hi = (hi.0.max(a), hi.1.max(b));
    }
    if lo.0.is_nan() || lo.0 > hi.0 {
        (lo, hi) = ((-0.5, -0.5), (0.5, 0.5));
    }
    let grow = 0.25 * (hi.0 - lo.0).max(hi.1 - lo.1).max(1e-3);
    let (lo, hi) = ((lo.0 - grow, lo.1 - grow), (hi.0 + grow, hi.1 + grow));
    [(lo.0, lo.1), (hi.0, lo.1), (hi.0, hi.1), (lo.0, hi.1)].map(|(a, b)| point + t1 * a + t2 * b)
}

/// Renders `input` to a [`PREVIEW_WIDTH`] × [`PREVIEW_HEIGHT`] PNG at `path`, atomically.
///
/// See [`render_preview_sized`].
pub fn render_preview(path: &Path, input: &PreviewInput) -> Result<(), OutputError> {
    render_preview_sized(path, input, PREVIEW_WIDTH, PREVIEW_HEIGHT)
}

/// Renders `input` to a `width` × `height` PNG at `path`, atomically.
///
/// The image is written to a temporary `.png` file in `path`'s directory and renamed onto `path`
/// when complete; on error nothing is left behind and an existing `path` is untouched. Empty
/// input, NaN or infinite positions and out-of-range indices do not fail: what cannot be drawn
/// is skipped. Sides outside 1..=8192 pixels are refused.
pub fn render_preview_sized(
    path: &Path,
    input: &PreviewInput,
    width: u32,
    height: u32,
) -> Result<(), OutputError> {
    if !(1..=MAX_SIDE).contains(&width) || !(1..=MAX_SIDE).contains(&height) {
        return Err(OutputError::plot(
            path,
            format!("image size {width}×{height} is outside 1..={MAX_SIDE} pixels a side"),
        ));
    }
    let pixels = rasterize(input, width, height).map_err(|m| OutputError::plot(path, m))?;
    write_png(path, &pixels, width, height)
}

/// Registers the embedded font once; `false` if it could not be (text is then left out).
fn font_ready() -> bool {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    *REGISTERED.get_or_init(|| register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok())
}

/// Draws the picture at `SS` times the size and averages it down to `width` × `height` RGB.
fn rasterize(input: &PreviewInput, width: u32, height: u32) -> Result<Vec<u8>, String> {
    let (big_w, big_h) = (width * SS, height * SS);
    let mut big = vec![0u8; big_w as usize * big_h as usize * 3];
    {
        let area = BitMapBackend::with_buffer(&mut big, (big_w, big_h)).into_drawing_area();
        area.fill(&BACKGROUND).map_err(|e| e.to_string())?;
        let layout = Layout::new(width, height, shows_sides(input));
        let caption = match input.positions {
            PreviewPositions::Three(p) => draw_3d(&area, &layout, input, p)?,
            PreviewPositions::Two(p) => draw_2d(&area, &layout, input, p)?,
        };
        if font_ready() {
            draw_caption(&area, &layout, input, &caption)?;
        }
        area.present().map_err(|e| e.to_string())?;
    }
    Ok(downsample(&big, width, height))
}

/// Averages each `SS` × `SS` block of `big` into one pixel.
fn downsample(big: &[u8], width: u32, height: u32) -> Vec<u8> {
    let (w, h, s) = (width as usize, height as usize, SS as usize);
    let big_w = w * s;
    let mut out = vec![0u8; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let mut sum = 0u32;
                for dy in 0..s {
                    let row = (y * s + dy) * big_w;
                    for dx in 0..s {
                        sum += u32::from(big[(row + x * s + dx) * 3 + c]);
                    }
                }
                let n = (s * s) as u32;
                out[(y * w + x) * 3 + c] = ((sum + n / 2) / n) as u8;
            }
        }
    }
    out
}

/// Where things go, in supersampled pixels.
struct Layout {
    /// Supersampled image size.
    size: (f64, f64),
    /// Size unit: one output pixel of an 800 × 600 image, scaled with the image.
    unit: f64,
    /// The rectangle the scene is fitted into: (left, top, right, bottom).
    plot: (f64, f64, f64, f64),
}

/// Whether the picture has shaded surfaces, whose two sides the legend names.
fn shows_sides(input: &PreviewInput) -> bool {
    matches!(input.positions, PreviewPositions::Three(_)) && !input.triangles.is_empty()
}

impl Layout {
    /// The layout of a `width` × `height` output image; `legend`: room for the line naming the
    /// surface's two sides under the caption.
    fn new(width: u32, height: u32, legend: bool) -> Self {
        let (w, h) = (f64::from(width * SS), f64::from(height * SS));
        let unit = (f64::from(width) / 800.0)
            .min(f64::from(height) / 600.0)
            .clamp(0.25, 4.0)
            * f64::from(SS);
        let margin = 24.0 * unit;
        let top = if legend { 90.0 } else { 72.0 } * unit;
        let left = margin.min(w / 2.0 - 0.5);
        let right = (w - margin).max(left + 1.0);
        let top = top.min(h / 2.0 - 0.5).max(0.0);
        let bottom = (h - margin).max(top + 1.0);
        Layout {
            size: (w, h),
            unit,
            plot: (left, top, right, bottom),
        }
    }
}

/// Maps scene coordinates (u right, v up) onto the plot rectangle, keeping the aspect ratio.
struct Fit {
    scale: f64,
    centre: (f64, f64),
    pixel_centre: (f64, f64),
}

impl Fit {
    /// Fits the box `min`..`max` into `layout`'s plot rectangle. A degenerate or non-finite box
    /// still gives a usable (finite) map.
    fn new(min: (f64, f64), max: (f64, f64), layout: &Layout) -> Self {
        let (l, t, r, b) = layout.plot;
        let (pw, ph) = (r - l, b - t);
        let extent = |lo: f64, hi: f64| {
            let e = hi - lo;
            if e.is_finite() && e > 0.0 {
                Some(e)
            } else {
                None
            }
        };
        let scale = match (extent(min.0, max.0), extent(min.1, max.1)) {
            (Some(eu), Some(ev)) => (pw / eu).min(ph / ev),
            (Some(eu), None) => pw / eu,
            (None, Some(ev)) => ph / ev,
            (None, None) => pw.min(ph) / 2.0,
        };
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            1.0
        };
        let mid = |lo: f64, hi: f64| {
            let m = 0.5 * lo + 0.5 * hi;
            if m.is_finite() {
                m
            } else {
                0.0
            }
        };
        Fit {
            scale,
            centre: (mid(min.0, max.0), mid(min.1, max.1)),
            pixel_centre: (0.5 * (l + r), 0.5 * (t + b)),
        }
    }

    /// Supersampled pixel coordinates of scene point (u, v); y grows downwards.
    fn map(&self, u: f64, v: f64) -> (f64, f64) {
        (
            self.pixel_centre.0 + (u - self.centre.0) * self.scale,
            self.pixel_centre.1 - (v - self.centre.1) * self.scale,
        )
    }
}

/// Bounding box of the points; `None` if there are none.
fn bounding_box(points: impl Iterator<Item = (f64, f64)>) -> Option<((f64, f64), (f64, f64))> {
    points.fold(None, |acc, (u, v)| match acc {
        None => Some(((u, v), (u, v))),
        Some((lo, hi)) => Some(((lo.0.min(u), lo.1.min(v)), (hi.0.max(u), hi.1.max(v)))),
    })
}

/// Rounds a supersampled pixel coordinate that is known to be moderate.
fn px(p: (f64, f64)) -> (i32, i32) {
    (p.0.round() as i32, p.1.round() as i32)
}

/// Whether `p` lies within `pad` of the image.
fn near_image(p: (f64, f64), layout: &Layout, pad: f64) -> bool {
    p.0 >= -pad && p.1 >= -pad && p.0 <= layout.size.0 + pad && p.1 <= layout.size.1 + pad
}

/// Clips segment `a`–`b` to the image (plus a small border), Liang–Barsky.
fn clip_segment(a: (f64, f64), b: (f64, f64), layout: &Layout) -> Option<((i32, i32), (i32, i32))> {
    let pad = 4.0;
    let (xmin, ymin, xmax, ymax) = (-pad, -pad, layout.size.0 + pad, layout.size.1 + pad);
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - xmin),
        (dx, xmax - a.0),
        (-dy, a.1 - ymin),
        (dy, ymax - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    if t0.is_nan() || t1.is_nan() || t0 > t1 {
        return None;
    }
    let at = |t: f64| (a.0 + t * dx, a.1 + t * dy);
    let (p, q) = (at(t0), at(t1));
    [p.0, p.1, q.0, q.1]
        .iter()
        .all(|x| x.is_finite())
        .then(|| (px(p), px(q)))
}

/// Scales an RGB colour by `f` (0 = black, 1 = unchanged).
fn shade(rgb: [f64; 3], f: f64) -> RGBColor {
    let c = |x: f64| (x * f).round().clamp(0.0, 255.0) as u8;
    RGBColor(c(rgb[0]), c(rgb[1]), c(rgb[2]))
}

/// Linear blend of two colours, `t` = 0 gives `a`.
fn mix(a: RGBColor, b: RGBColor, t: f64) -> RGBColor {
    let c = |x: u8, y: u8| (f64::from(x) + (f64::from(y) - f64::from(x)) * t).round() as u8;
    RGBColor(c(a.0, b.0), c(a.1, b.1), c(a.2, b.2))
}

/// Draws plotters elements, turning errors into messages.
macro_rules! draw {
    ($area:expr, $element:expr) => {
        $area.draw(&$element).map_err(|e| e.to_string())?
    };
}

/// The fixed oblique orthographic camera.
struct Camera {
    /// Unit vector pointing right in the picture.
    right: Vector3<f64>,
    /// Unit vector pointing up in the picture.
    up: Vector3<f64>,
    /// Unit vector from the scene towards the viewer; larger `p · toward` is nearer.
    toward: Vector3<f64>,
    /// Unit direction towards the light.
    light: Vector3<f64>,
}

impl Camera {
    /// The camera at [`AZIMUTH_DEG`], [`ELEVATION_DEG`].
    fn new() -> Self {
        let (a, e) = (AZIMUTH_DEG.to_radians(), ELEVATION_DEG.to_radians());
        let toward = Vector3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos());
        let right = Vector3::new(a.cos(), 0.0, -a.sin());
        let up = toward.cross(&right);
        // A light above, slightly left of and in front of the viewer.
        let light = (toward + up * 0.5 + right * 0.3).normalize();
        Camera {
            right,
            up,
            toward,
            light,
        }
    }

    /// (u, v, depth) of `p`, or `None` if not finite.
    fn project(&self, p: &Vector3<f64>) -> Option<(f64, f64, f64)> {
        let q = (p.dot(&self.right), p.dot(&self.up), p.dot(&self.toward));
        (q.0.is_finite() && q.1.is_finite() && q.2.is_finite()).then_some(q)
    }
}

/// A triangle ready to paint.
struct Face {
    depth: f64,
    corners: [(f64, f64); 3],
    fill: RGBColor,
    edge: RGBColor,
}

/// A spring ready to draw: (depth, end, end).
type Segment = (f64, (f64, f64), (f64, f64));

/// What the caption reports besides the title.
struct Caption {
    detail: String,
    skipped: usize,
    axes: Option<Camera>,
}

/// `i` as an index into `n` vertices, or `None` if out of range.
fn index(i: u32, n: usize) -> Option<usize> {
    let i = i as usize;
    (i < n).then_some(i)
}

/// Draws a 3D frame: shaded triangles, else springs, else dots; then the pinned vertices.
fn draw_3d(
    area: &DrawingArea<BitMapBackend, Shift>,
    layout: &Layout,
    input: &PreviewInput,
    positions: &[Vector3<f64>],
) -> Result<Caption, String> {
    let cam = Camera::new();
    let n = positions.len();
    let projected: Vec<Option<(f64, f64, f64)>> =
        positions.iter().map(|p| cam.project(p)).collect();
    let skipped = projected.iter().filter(|p| p.is_none()).count();
    // Obstacles in the camera's coordinates: plane patches as projected corners, spheres as
    // (centre, radius).
    let mut patches = Vec::new();
    let mut discs = Vec::new();
    let mut boxes = Vec::new();
    for obstacle in input.obstacles {
        match *obstacle {
            PreviewObstacle::Box { min, max } => {
                if let Some(b) = BoxView::new(&cam, &min, &max) {
                    boxes.push(b);
                }
            }
            PreviewObstacle::Plane { point, normal } => {
                let corners = plane_patch(&point, &normal, positions).map(|c| cam.project(&c));
                if let [Some(a), Some(b), Some(c), Some(d)] = corners {
                    patches.push([a, b, c, d]);
                }
            }
            PreviewObstacle::Sphere { center, radius } => {
                if let Some(c) = cam.project(&center).filter(|_| radius.is_finite()) {
                    discs.push((c, radius));
                }
            }
        }
    }
    let obstacle_points = patches
        .iter()
        .flat_map(|p| p.iter().map(|&(u, v, _)| (u, v)))
        .chain(
            discs
                .iter()
                .flat_map(|&((u, v, _), r)| [(u - r, v - r), (u + r, v + r)]),
        )
        .chain(boxes.iter().flat_map(|b| b.corners.map(|(u, v, _)| (u, v))));
    let (min, max) = bounding_box(
        projected
            .iter()
            .flatten()
            .map(|&(u, v, _)| (u, v))
            .chain(obstacle_points),
    )
    .unwrap_or(((0.0, 0.0), (0.0, 0.0)));
    let fit = Fit::new(min, max, layout);
    for patch in &patches {
        let pts: Vec<(i32, i32)> = patch.iter().map(|&(u, v, _)| px(fit.map(u, v))).collect();
        draw!(area, Polygon::new(pts.clone(), GROUND.filled()));
        // Grid lines: eight across each way.
        for k in 0..=8 {
            let t = k as f64 / 8.0;
            let lerp = |a: (f64, f64, f64), b: (f64, f64, f64)| {
                px(fit.map(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)))
            };
            let width = (layout.unit * 0.5).round().max(1.0) as u32;
            for (a, b, c, d) in [
                (patch[0], patch[1], patch[3], patch[2]),
                (patch[0], patch[3], patch[1], patch[2]),
            ] {
                draw!(
                    area,
                    PathElement::new(
                        vec![lerp(a, b), lerp(c, d)],
                        GROUND_LINE.stroke_width(width)
                    )
                );
            }
        }
    }
    let wire = (layout.unit * 1.2).round().max(1.0) as u32;
    for b in &boxes {
        b.draw_far(area, &fit, wire)?;
    }
    for &((u, v, _), r) in &discs {
        let centre = fit.map(u, v);
        let radius = dist(centre, fit.map(u + r, v));
        // A disc shaded in rings towards the light's side.
        for ring in 0..12 {
            let f = 1.0 - ring as f64 / 12.0;
            let shift = (1.0 - f) * 0.35 * radius;
            let c = (centre.0 - shift, centre.1 - shift);
            let colour = shade(SPHERE, 0.75 + 0.35 * (1.0 - f));
            draw!(
                area,
                Circle::new(px(c), (radius * f).round() as i32, colour.filled())
            );
        }
    }
    let screen: Vec<Option<((f64, f64), f64)>> = projected
        .iter()
        .map(|p| p.map(|(u, v, d)| (fit.map(u, v), d)))
        .collect();
    let at = |i: u32| index(i, n).and_then(|i| screen[i]);

    if !input.triangles.is_empty() {
        let mut faces = Vec::with_capacity(input.triangles.len());
        let mut edge_length = 0.0;
        for tri in input.triangles {
            let (Some(a), Some(b), Some(c)) = (at(tri[0]), at(tri[1]), at(tri[2])) else {
                continue;
            };
            // All three indices are valid here.
            let [pa, pb, pc] = tri.map(|i| positions[i as usize]);
            let normal = (pb - pa).cross(&(pc - pa));
            let len = normal.norm();
            let (lambert, front) = if len > 0.0 && len.is_finite() {
                let normal = normal / len;
                (normal.dot(&cam.light).abs(), normal.dot(&cam.toward) >= 0.0)
            } else {
                (0.5, true)
            };
            let base = if front { FRONT } else { BACK };
            let f = 0.45 + 0.6 * lambert;
            let corners = [a.0, b.0, c.0];
            edge_length += dist(corners[0], corners[1])
                + dist(corners[1], corners[2])
                + dist(corners[2], corners[0]);
            faces.push(Face {
                depth: (a.1 + b.1 + c.1) / 3.0,
                corners,
                fill: shade(base, f),
                edge: shade(base, f * 0.8),
            });
        }
        faces.sort_by(|x, y| x.depth.total_cmp(&y.depth));
        // Outline the triangles only when they are big enough for the lines not to swamp them.
        let mean_edge = edge_length / (3.0 * faces.len().max(1) as f64) / layout.unit;
        let outline = mean_edge >= 6.0;
        let edge_width = (layout.unit * 0.5).round().max(1.0) as u32;
        for face in &faces {
            let pts: Vec<(i32, i32)> = face.corners.iter().map(|&p| px(p)).collect();
            draw!(area, Polygon::new(pts.clone(), face.fill.filled()));
            let mut ring = pts;
            ring.push(ring[0]);
            // Without outlines, a thin stroke in the fill colour closes rasterisation cracks.
            let (colour, width) = if outline {
                (face.edge, edge_width)
            } else {
                (face.fill, 1)
            };
            draw!(area, PathElement::new(ring, colour.stroke_width(width)));
        }
    } else if !input.lines.is_empty() {
        let mut segments: Vec<Segment> = input
            .lines
            .iter()
            .filter_map(|l| {
                let (a, b) = (at(l[0])?, at(l[1])?);
                Some((0.5 * (a.1 + b.1), a.0, b.0))
            })
            .collect();
        segments.sort_by(|x, y| x.0.total_cmp(&y.0));
        let (near, far) = (RGBColor(20, 45, 90), RGBColor(165, 185, 210));
        let (dmin, dmax) = segments
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
                (lo.min(s.0), hi.max(s.0))
            });
        let width = if segments.len() > 5000 {
            SS
        } else {
            (1.5 * layout.unit).round().max(1.0) as u32
        };
        for (depth, a, b) in segments {
            let t = if dmax > dmin {
                (dmax - depth) / (dmax - dmin)
            } else {
                0.0
            };
            if let Some((a, b)) = clip_segment(a, b, layout) {
                let colour = mix(near, far, t.clamp(0.0, 1.0) * 0.85);
                draw!(
                    area,
                    PathElement::new(vec![a, b], colour.stroke_width(width))
                );
            }
        }
    } else {
        // Only vertices: small dots.
        let r = (1.5 * layout.unit).round().max(1.0) as i32;
        for &(p, _) in screen.iter().flatten() {
            draw!(area, Circle::new(px(p), r, PARTICLE.filled()));
        }
    }

    for b in &boxes {
        b.draw_near(area, &fit, wire)?;
    }
    draw_pinned(area, layout, input.pinned, 4.5 * layout.unit, |i| {
        at(i).map(|s| s.0)
    })?;
    Ok(Caption {
        detail: detail_line(input),
        skipped,
        axes: Some(cam),
    })
}

/// The caption's second line: what the frame holds, from `input` alone (the counts, and in 3D the
/// size of the finite vertices' bounding box).
pub fn detail_line(input: &PreviewInput) -> String {
    match input.positions {
        PreviewPositions::Three(positions) => {
            let mut detail = format!(
                "3D · {} vertices · {} triangles · {} springs · {} pinned",
                positions.len(),
                input.triangles.len(),
                input.springs,
                input.pinned.len()
            );
            let finite = positions.iter().filter(|p| p.iter().all(|x| x.is_finite()));
            if let Some((lo, hi)) =
                finite.fold(None, |acc: Option<(Vector3<f64>, Vector3<f64>)>, p| {
                    Some(acc.map_or((*p, *p), |(lo, hi)| (lo.inf(p), hi.sup(p))))
                })
            {
                let size = hi - lo;
                detail.push_str(&format!(
                    " · size {} × {} × {} m",
                    format_length(size.x),
                    format_length(size.y),
                    format_length(size.z)
                ));
            }
            detail
        }
        PreviewPositions::Two(positions) => format!(
            "2D · {} particles · {} springs · {} pinned",
            positions.len(),
            input.springs,
            input.pinned.len()
        ),
    }
}

/// A box obstacle in the camera's coordinates.
struct BoxView {
    /// The eight corners as (u, v, depth); corner k has x = max.x if bit 0 of k is set, y = max.y
    /// if bit 1 is, z = max.z if bit 2 is, else the min's.
    corners: [(f64, f64, f64); 8],
    /// Whether each wall, indexed `2 · axis + side` (side 1 is the max side), is a far wall: one
    /// whose outward normal points away from the viewer, so that its inside faces the camera.
    far: [bool; 6],
}

impl BoxView {
    /// The box `min`..`max` seen by `cam`; `None` if a corner is not finite.
    fn new(cam: &Camera, min: &Vector3<f64>, max: &Vector3<f64>) -> Option<Self> {
        let mut corners = [(0.0, 0.0, 0.0); 8];
        for (k, corner) in corners.iter_mut().enumerate() {
            let pick = |axis: usize| {
                if k >> axis & 1 == 1 {
                    max[axis]
                } else {
                    min[axis]
                }
            };
            *corner = cam.project(&Vector3::new(pick(0), pick(1), pick(2)))?;
        }
        let far = std::array::from_fn(|wall| {
            let (axis, side) = (wall / 2, wall % 2);
            let outward = if side == 1 { 1.0 } else { -1.0 };
            outward * cam.toward[axis] < 0.0
        });
        Some(BoxView { corners, far })
    }

    /// The corners of wall `2 · axis + side`, in order around it.
    fn wall(&self, axis: usize, side: usize) -> [(f64, f64, f64); 4] {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        [(0, 0), (1, 0), (1, 1), (0, 1)].map(|(i, j)| self.corners[side << axis | i << b | j << c])
    }

    /// The twelve edges as (corner, corner, the two walls they bound).
    fn edges() -> impl Iterator<Item = (usize, usize, [usize; 2])> {
        (0..8usize).flat_map(|k| {
            (0..3usize)
                .filter(move |&axis| k >> axis & 1 == 0)
                .map(move |axis| {
                    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
                    let walls = [2 * b + (k >> b & 1), 2 * c + (k >> c & 1)];
                    (k, k | 1 << axis, walls)
                })
        })
    }

    /// Fills the far walls and draws the edges that bound one (behind the mesh).
    fn draw_far(
        &self,
        area: &DrawingArea<BitMapBackend, Shift>,
        fit: &Fit,
        width: u32,
    ) -> Result<(), String> {
        for wall in (0..6).filter(|&w| self.far[w]) {
            let pts: Vec<(i32, i32)> = self
                .wall(wall / 2, wall % 2)
                .iter()
                .map(|&(u, v, _)| px(fit.map(u, v)))
                .collect();
            draw!(area, Polygon::new(pts, BOX_WALL.filled()));
        }
        for (a, b, _) in Self::edges().filter(|e| e.2.iter().any(|&w| self.far[w])) {
            self.draw_edge(area, fit, a, b, width)?;
        }
        Ok(())
    }

    /// Draws the edges between two near walls (over the mesh).
    fn draw_near(
        &self,
        area: &DrawingArea<BitMapBackend, Shift>,
        fit: &Fit,
        width: u32,
    ) -> Result<(), String> {
        for (a, b, _) in Self::edges().filter(|e| e.2.iter().all(|&w| !self.far[w])) {
            self.draw_edge(area, fit, a, b, width)?;
        }
        Ok(())
    }

    /// Draws the edge from corner `a` to corner `b`.
    fn draw_edge(
        &self,
        area: &DrawingArea<BitMapBackend, Shift>,
        fit: &Fit,
        a: usize,
        b: usize,
        width: u32,
    ) -> Result<(), String> {
        let (p, q) = (self.corners[a], self.corners[b]);
        draw!(
            area,
            PathElement::new(
                vec![px(fit.map(p.0, p.1)), px(fit.map(q.0, q.1))],
                BOX_WIRE.stroke_width(width)
            )
        );
        Ok(())
    }
}

/// A length for the caption: fixed-point when moderate, scientific otherwise.
fn format_length(x: f64) -> String {
    if x == 0.0 || (1e-3..1e4).contains(&x.abs()) {
        format!("{x:.3}")
    } else {
        format!("{x:.2e}")
    }
}

/// Distance between two pixel positions.
fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

/// Red dots of `radius` (supersampled pixels) on the pinned vertices.
fn draw_pinned(
    area: &DrawingArea<BitMapBackend, Shift>,
    layout: &Layout,
    pinned: &[u32],
    radius: f64,
    at: impl Fn(u32) -> Option<(f64, f64)>,
) -> Result<(), String> {
    let r = radius.round().max(2.0) as i32;
    let rim = (layout.unit * 0.8).round().max(1.0) as i32;
    for &i in pinned {
        let Some(p) = at(i) else { continue };
        if !near_image(p, layout, f64::from(r)) {
            continue;
        }
        draw!(area, Circle::new(px(p), r, PINNED_RIM.filled()));
        draw!(area, Circle::new(px(p), (r - rim).max(1), PINNED.filled()));
    }
    Ok(())
}

/// Draws a 2D frame: the box, triangles, springs, particles and pinned particles.
fn draw_2d(
    area: &DrawingArea<BitMapBackend, Shift>,
    layout: &Layout,
    input: &PreviewInput,
    positions: &[Vector2<f64>],
) -> Result<Caption, String> {
    let n = positions.len();
    let finite = |p: &Vector2<f64>| p.x.is_finite() && p.y.is_finite();
    let skipped = positions.iter().filter(|p| !finite(p)).count();
    let bounds = input.bounds_2d.filter(|(lo, hi)| {
        lo.iter().chain(hi).all(|x| x.is_finite()) && hi[0] > lo[0] && hi[1] > lo[1]
    });
    let (min, max) = match bounds {
        Some((lo, hi)) => ((lo[0], lo[1]), (hi[0], hi[1])),
        None => {
            let (lo, hi) = bounding_box(positions.iter().filter(|p| finite(p)).map(|p| (p.x, p.y)))
                .unwrap_or(((0.0, 0.0), (1.0, 1.0)));
            // Leave room for the discs around the outermost particles.
            let pad = 0.05 * (hi.0 - lo.0).max(hi.1 - lo.1);
            let pad = if pad.is_finite() && pad > 0.0 {
                pad
            } else {
                0.5
            };
            ((lo.0 - pad, lo.1 - pad), (hi.0 + pad, hi.1 + pad))
        }
    };
    let fit = Fit::new(min, max, layout);
    let screen: Vec<Option<(f64, f64)>> = positions
        .iter()
        .map(|p| finite(p).then(|| fit.map(p.x, p.y)))
        .collect();
    let at = |i: u32| index(i, n).and_then(|i| screen[i]);

    if bounds.is_some() {
        let (a, b) = (px(fit.map(min.0, max.1)), px(fit.map(max.0, min.1)));
        draw!(area, Rectangle::new([a, b], WHITE.filled()));
        let w = (1.5 * layout.unit).round().max(1.0) as u32;
        draw!(area, Rectangle::new([a, b], BOX_EDGE.stroke_width(w)));
    }

    let far = 2.0 * layout.size.0.max(layout.size.1);
    for tri in input.triangles {
        let (Some(a), Some(b), Some(c)) = (at(tri[0]), at(tri[1]), at(tri[2])) else {
            continue;
        };
        if ![a, b, c].iter().all(|&p| near_image(p, layout, far)) {
            continue;
        }
        let pts = vec![px(a), px(b), px(c)];
        draw!(area, Polygon::new(pts, RGBColor(205, 220, 240).filled()));
    }

    let spring_width = (1.3 * layout.unit).round().max(1.0) as u32;
    for l in input.lines {
        let (Some(a), Some(b)) = (at(l[0]), at(l[1])) else {
            continue;
        };
        if let Some((a, b)) = clip_segment(a, b, layout) {
            draw!(
                area,
                PathElement::new(vec![a, b], SPRING_2D.stroke_width(spring_width))
            );
        }
    }

    // Disc radius from the typical spacing of the particles, within 1.5..6 output pixels.
    let (l, t, r, b) = layout.plot;
    let spacing = ((r - l) * (b - t) / (n.max(1) as f64)).sqrt();
    let radius = (0.3 * spacing).clamp(1.5 * layout.unit, 6.0 * layout.unit);
    let radius_px = radius.round().max(1.0) as i32;
    for &p in screen.iter().flatten() {
        if near_image(p, layout, radius) {
            draw!(area, Circle::new(px(p), radius_px, PARTICLE.filled()));
        }
    }
    let pinned_radius = (1.2 * radius).max(3.0 * layout.unit);
    draw_pinned(area, layout, input.pinned, pinned_radius, at)?;

    Ok(Caption {
        detail: detail_line(input),
        skipped,
        axes: None,
    })
}

/// Title, detail line, warning about skipped vertices and (3D) the axis hint.
fn draw_caption(
    area: &DrawingArea<BitMapBackend, Shift>,
    layout: &Layout,
    input: &PreviewInput,
    caption: &Caption,
) -> Result<(), String> {
    let u = layout.unit;
    let x = (16.0 * u).round() as i32;
    let title = (FONT, 21.0 * u).into_font().color(&TEXT);
    draw!(
        area,
        Text::new(input.title.to_string(), (x, (12.0 * u) as i32), title)
    );
    let small = (FONT, 13.0 * u).into_font();
    let mut detail = caption.detail.clone();
    if caption.skipped > 0 {
        detail.push_str(" · ");
    }
    draw!(
        area,
        Text::new(
            detail.clone(),
            (x, (42.0 * u) as i32),
            small.clone().color(&TEXT_DIM)
        )
    );
    if caption.skipped > 0 {
        let offset = area
            .estimate_text_size(&detail, &small.clone().color(&TEXT_DIM))
            .map_err(|e| e.to_string())?
            .0 as i32;
        let warning = format!(
            "{} {} not finite (skipped)",
            caption.skipped,
            if caption.skipped == 1 {
                "vertex"
            } else {
                "vertices"
            }
        );
        draw!(
            area,
            Text::new(
                warning,
                (x + offset, (42.0 * u) as i32),
                small.clone().color(&WARNING)
            )
        );
    }
    if shows_sides(input) {
        draw_side_legend(area, layout, (x, (62.0 * u) as i32))?;
    }
    if input.positions.len() > 0 {
        if let Some(cam) = &caption.axes {
            draw_axes(area, layout, cam)?;
        }
    }
    Ok(())
}

/// The legend of the surface's colours, from `at` (supersampled pixels) rightwards: which colour
/// is the side whose normal (by the triangles' vertex order) faces the viewer.
fn draw_side_legend(
    area: &DrawingArea<BitMapBackend, Shift>,
    layout: &Layout,
    at: (i32, i32),
) -> Result<(), String> {
    let u = layout.unit;
    let font = (FONT, 13.0 * u).into_font().color(&TEXT_DIM);
    let swatch = (12.0 * u).round() as i32;
    let mut x = at.0;
    for (colour, label) in [
        (FRONT, "front side (the triangles' normals point out of it)"),
        (BACK, "back side"),
    ] {
        let (top, bottom) = (at.1 + (1.0 * u) as i32, at.1 + (1.0 * u) as i32 + swatch);
        draw!(
            area,
            Rectangle::new(
                [(x, top), (x + swatch, bottom)],
                shade(colour, 1.0).filled()
            )
        );
        x += swatch + (6.0 * u) as i32;
        draw!(area, Text::new(label, (x, at.1), font.clone()));
        let advance = area
            .estimate_text_size(label, &font)
            .map_err(|e| e.to_string())?
            .0 as i32;
        x += advance + (18.0 * u) as i32;
    }
    Ok(())
}

/// A small x/y/z triad in the lower left corner showing the camera's orientation.
fn draw_axes(
    area: &DrawingArea<BitMapBackend, Shift>,
    layout: &Layout,
    cam: &Camera,
) -> Result<(), String> {
    let u = layout.unit;
    let origin = (34.0 * u, layout.size.1 - 34.0 * u);
    let length = 24.0 * u;
    let width = (1.5 * u).round().max(1.0) as u32;
    let font = (FONT, 12.0 * u).into_font();
    let axes = [
        ("x", Vector3::x(), RGBColor(200, 50, 50)),
        ("y", Vector3::y(), RGBColor(40, 150, 60)),
        ("z", Vector3::z(), RGBColor(50, 90, 210)),
    ];
    for (name, axis, colour) in axes {
        let d = (axis.dot(&cam.right), -axis.dot(&cam.up));
        let tip = (origin.0 + d.0 * length, origin.1 + d.1 * length);
        draw!(
            area,
            PathElement::new(vec![px(origin), px(tip)], colour.stroke_width(width))
        );
        let label = (
            origin.0 + d.0 * (length + 9.0 * u) - 3.5 * u,
            origin.1 + d.1 * (length + 9.0 * u) - 6.0 * u,
        );
        draw!(
            area,
            Text::new(name.to_string(), px(label), font.clone().color(&colour))
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Width and height from a PNG's IHDR chunk, after checking the signature.
    fn png_size(path: &Path) -> (u32, u32) {
        let bytes = std::fs::read(path).unwrap();
        assert!(bytes.len() > 24, "PNG too short: {} bytes", bytes.len());
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "not a PNG signature");
        assert_eq!(&bytes[12..16], b"IHDR");
        let be = |o: usize| u32::from_be_bytes(bytes[o..o + 4].try_into().unwrap());
        (be(16), be(20))
    }

    type Mesh = (Vec<Vector3<f64>>, Vec<[u32; 3]>, Vec<[u32; 2]>);

    /// An N × N cloth hanging from two pinned corners, roughly as cloth-N looks after a second.
    fn hanging_cloth(n: usize) -> Mesh {
        let mut positions = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                let s = i as f64 / (n - 1) as f64; // distance down from the pinned edge
                let t = j as f64 / (n - 1) as f64; // across
                let across = t - 0.5;
                // The free corners fall and swing in; the middle sags.
                let z = 0.5 + across * (1.0 - 0.35 * s.powf(0.7));
                let y =
                    -0.9 * s - 0.25 * (1.0 - (2.0 * across).powi(2)) * (1.0 - (1.0 - s).powi(3));
                let x = 0.18 * s * (std::f64::consts::PI * t).sin() + 0.05 * (5.0 * s).sin();
                positions.push(Vector3::new(x, y, z));
            }
        }
        let id = |i: usize, j: usize| (i * n + j) as u32;
        let mut triangles = Vec::new();
        let mut lines = Vec::new();
        for i in 0..n {
            for j in 0..n {
                if i + 1 < n {
                    lines.push([id(i, j), id(i + 1, j)]);
                }
                if j + 1 < n {
                    lines.push([id(i, j), id(i, j + 1)]);
                }
                if i + 1 < n && j + 1 < n {
                    triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                    triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
                }
            }
        }
        (positions, triangles, lines)
    }

    fn cloth_input<'a>(
        positions: &'a [Vector3<f64>],
        triangles: &'a [[u32; 3]],
        lines: &'a [[u32; 2]],
        pinned: &'a [u32],
    ) -> PreviewInput<'a> {
        PreviewInput {
            title: "cloth-20 · newton · t = 1.000 s",
            positions: PreviewPositions::Three(positions),
            triangles,
            lines,
            springs: lines.len(),
            pinned,
            bounds_2d: None,
            obstacles: &[],
        }
    }

    /// The caption's detail line for `input`, drawn at a small size.
    fn caption_detail(input: &PreviewInput) -> String {
        let (width, height) = (80, 60);
        let mut big = vec![0u8; (width * SS * height * SS * 3) as usize];
        let area =
            BitMapBackend::with_buffer(&mut big, (width * SS, height * SS)).into_drawing_area();
        let layout = Layout::new(width, height, shows_sides(input));
        let caption = match input.positions {
            PreviewPositions::Three(p) => draw_3d(&area, &layout, input, p),
            PreviewPositions::Two(p) => draw_2d(&area, &layout, input, p),
        };
        caption.unwrap().detail
    }

    #[test]
    fn the_caption_counts_the_mesh_springs_even_when_none_are_drawn() {
        // A cloth draws its triangles, not its springs: the caption still counts the springs.
        let (p, t, l) = hanging_cloth(6);
        let cloth = PreviewInput {
            lines: &[],
            springs: 157,
            ..cloth_input(&p, &t, &l, &[0, 5])
        };
        let detail = caption_detail(&cloth);
        let counts = format!(
            "3D · 36 vertices · {} triangles · 157 springs · 2 pinned · size ",
            t.len()
        );
        assert!(detail.starts_with(&counts), "{detail}");
        let flat: Vec<Vector2<f64>> = p.iter().map(|q| Vector2::new(q.x, q.y)).collect();
        let particles = PreviewInput {
            positions: PreviewPositions::Two(&flat),
            ..cloth
        };
        assert!(
            caption_detail(&particles).starts_with("2D · 36 particles · 157 springs · 2 pinned"),
            "{}",
            caption_detail(&particles)
        );
    }

    #[test]
    fn font_registers() {
        assert!(font_ready());
    }

    #[test]
    fn renders_3d_cloth() {
        let dir = tempfile::tempdir().unwrap();
        let (p, t, l) = hanging_cloth(20);
        let pinned = [0, 19];
        let path = dir.path().join("preview.png");
        render_preview(&path, &cloth_input(&p, &t, &l, &pinned)).unwrap();
        assert_eq!(png_size(&path), (PREVIEW_WIDTH, PREVIEW_HEIGHT));
        // Only the final file remains.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

        // Springs only, at another size.
        let path = dir.path().join("springs.png");
        render_preview_sized(&path, &cloth_input(&p, &[], &l, &pinned), 640, 360).unwrap();
        assert_eq!(png_size(&path), (640, 360));
    }

    #[test]
    fn renders_2d_particles() {
        let dir = tempfile::tempdir().unwrap();
        let positions: Vec<Vector2<f64>> = (0..30)
            .map(|k| {
                let a = k as f64 * 0.7;
                Vector2::new(
                    0.5 + 0.3 * a.cos() * (k as f64 / 30.0),
                    0.2 + 0.02 * k as f64,
                )
            })
            .collect();
        let lines: Vec<[u32; 2]> = (0..29).map(|k| [k, k + 1]).collect();
        let input = PreviewInput {
            title: "seed-2d · symplectic-euler · t = 0.500 s",
            positions: PreviewPositions::Two(&positions),
            triangles: &[],
            lines: &lines,
            springs: lines.len(),
            pinned: &[0, 7],
            bounds_2d: Some(([0.0, 0.0], [1.0, 1.0])),
            obstacles: &[],
        };
        let path = dir.path().join("seed.png");
        render_preview(&path, &input).unwrap();
        assert_eq!(png_size(&path), (800, 600));

        let unboxed = PreviewInput {
            bounds_2d: None,
            obstacles: &[],
            ..input
        };
        render_preview_sized(&path, &unboxed, 300, 500).unwrap();
        assert_eq!(png_size(&path), (300, 500));
    }

    #[test]
    fn survives_bad_input() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.png");
        let (mut p, t, l) = hanging_cloth(6);
        p[3] = Vector3::new(f64::NAN, 0.0, 0.0);
        p[8] = Vector3::new(f64::INFINITY, 1.0, 0.0);
        p[9] = Vector3::new(1e300, -1e300, 1e300);
        let mut t = t;
        t.push([0, 1, 1000]); // out of range
        let pinned = [0, 3, 5, 77];
        for input in [
            cloth_input(&p, &t, &l, &pinned),
            cloth_input(&p, &[], &l, &pinned),
            cloth_input(&p, &[], &[], &pinned),
            cloth_input(&[], &[], &[], &[]),
            cloth_input(&[], &t, &l, &pinned),
        ] {
            render_preview_sized(&path, &input, 200, 150).unwrap();
            assert_eq!(png_size(&path), (200, 150));
        }
        // All vertices at one point: a degenerate bounding box.
        let same = vec![Vector3::new(1.0, 2.0, 3.0); 4];
        render_preview(
            &path,
            &cloth_input(&same, &[[0, 1, 2], [1, 2, 3]], &[], &[0]),
        )
        .unwrap();

        let p2 = [
            Vector2::new(f64::NAN, 0.5),
            Vector2::new(0.5, 0.5),
            Vector2::new(1e12, -1e12),
            Vector2::new(0.5, f64::NEG_INFINITY),
        ];
        for bounds in [
            None,
            Some(([0.0, 0.0], [1.0, 1.0])),
            Some(([1.0, 0.0], [1.0, 1.0])),
            Some(([f64::NAN, 0.0], [1.0, 1.0])),
        ] {
            for pts in [&p2[..], &p2[1..2], &[]] {
                let input = PreviewInput {
                    title: "",
                    positions: PreviewPositions::Two(pts),
                    triangles: &[[0, 1, 2], [1, 2, 3]],
                    lines: &[[0, 1], [1, 2], [2, 3], [1, 9]],
                    springs: 4,
                    pinned: &[1, 2, 42],
                    bounds_2d: bounds,
                    obstacles: &[],
                };
                render_preview_sized(&path, &input, 120, 90).unwrap();
                assert_eq!(png_size(&path), (120, 90));
            }
        }
        // Tiny images still work.
        render_preview_sized(&path, &cloth_input(&p, &t, &l, &pinned), 1, 1).unwrap();
        assert_eq!(png_size(&path), (1, 1));
    }

    #[test]
    fn failed_write_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let (p, t, l) = hanging_cloth(5);
        let input = cloth_input(&p, &t, &l, &[0, 4]);

        // Destination is a directory: the final rename fails, the temporary file is removed.
        let path = dir.path().join("preview.png");
        std::fs::create_dir(&path).unwrap();
        let err = render_preview(&path, &input).unwrap_err();
        assert!(err.to_string().contains("preview.png"), "{err}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        assert!(path.is_dir());

        // Missing directory.
        let missing = dir.path().join("nope").join("preview.png");
        assert!(matches!(
            render_preview(&missing, &input),
            Err(OutputError::Io { .. })
        ));
        assert!(!missing.exists());

        // Refused size: nothing written.
        let path = dir.path().join("huge.png");
        let err = render_preview_sized(&path, &input, 0, 600).unwrap_err();
        assert!(matches!(err, OutputError::Plot { .. }));
        assert!(err.to_string().contains("huge.png"), "{err}");
        assert!(!path.exists());
    }

    #[test]
    fn overwrites_existing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("preview.png");
        std::fs::write(&path, b"old").unwrap();
        let (p, t, l) = hanging_cloth(4);
        render_preview(&path, &cloth_input(&p, &t, &l, &[0, 3])).unwrap();
        assert_eq!(png_size(&path), (800, 600));
    }

    /// The 3D setup of a built-in scene or a scene file's text.
    fn setup_3d(setup: crate::sim::scenes::AnySetup) -> crate::sim::scenes::Setup<3> {
        match setup {
            crate::sim::scenes::AnySetup::Three(s) => s,
            crate::sim::scenes::AnySetup::Two(_) => panic!("a 2D scene"),
        }
    }

    #[test]
    fn the_caption_of_cloth_40_counts_its_scene() {
        let setup = setup_3d(crate::sim::scenes::builtin("cloth-40").unwrap().unwrap());
        let (scene, mesh) = (&setup.scene, setup.scene.mesh());
        let preview = ScenePreview::of(
            &setup.name,
            scene,
            &setup.initial.positions,
            100,
            1.0,
            Integrator::Newton,
        );
        let [title, detail] = preview.caption();
        assert_eq!(title, "cloth-40 · frame 100 · t = 1.000 s · newton");
        // The counts are the scene's: a cloth draws its triangles, but counts its springs.
        assert!(!mesh.springs().is_empty() && !mesh.triangles().is_empty());
        let counts = format!(
            "3D · {} vertices · {} triangles · {} springs · {} pinned · size ",
            mesh.vertex_count(),
            mesh.triangles().len(),
            mesh.springs().len(),
            scene.pinned().len()
        );
        assert!(detail.starts_with(&counts), "{detail}");
        assert!(!detail.contains(" 0 springs"), "{detail}");
        // The picture is drawn from the same input.
        let pixels = rasterize(&preview.input(), 160, 120).unwrap();
        assert_eq!(pixels.len(), 160 * 120 * 3);
    }

    #[test]
    fn a_scene_with_springs_never_shows_0_springs() {
        for name in ["cloth-20", "cloth-fall-40", "beam-2", "seed-2d"] {
            let Some(Ok(setup)) = crate::sim::scenes::builtin(name) else {
                panic!("{name} is not a built-in scene");
            };
            let [_, detail] = match &setup {
                crate::sim::scenes::AnySetup::Two(s) => ScenePreview::of(
                    &s.name,
                    &s.scene,
                    &s.initial.positions,
                    0,
                    0.0,
                    s.settings.integrator,
                )
                .caption(),
                crate::sim::scenes::AnySetup::Three(s) => ScenePreview::of(
                    &s.name,
                    &s.scene,
                    &s.initial.positions,
                    0,
                    0.0,
                    s.settings.integrator,
                )
                .caption(),
            };
            let springs = match &setup {
                crate::sim::scenes::AnySetup::Two(s) => s.scene.mesh().springs().len(),
                crate::sim::scenes::AnySetup::Three(s) => s.scene.mesh().springs().len(),
            };
            assert!(springs > 0, "{name}");
            assert!(
                detail.contains(&format!(" {springs} springs")),
                "{name}: {detail}"
            );
            assert!(!detail.contains(" 0 springs"), "{name}: {detail}");
        }
    }

    #[test]
    fn a_box_obstacle_is_drawn() {
        // A cloth in a 3D box (a container): the scene's box reaches the preview, its far walls
        // are filled and its edges drawn, none of which a bare picture has.
        let text = r#"
name = "cloth-in-a-box"
[mesh]
generator = "cloth"
n = 6
stiffness = 1000.0
[forces]
gravity = [0.0, -9.81, 0.0]
[[contact]]
shape = "box"
min = [-0.5, -1.0, -0.5]
max = [1.5, 0.5, 1.5]
[integrator]
method = "newton"
time_step = 0.01
[run]
steps = 1
"#;
        let file = crate::sim::file::parse_scene(text, Path::new("cloth-in-a-box.toml")).unwrap();
        let setup = setup_3d(file.setup);
        let preview = ScenePreview::of(
            &setup.name,
            &setup.scene,
            &setup.initial.positions,
            0,
            0.0,
            Integrator::Newton,
        );
        assert_eq!(
            preview.input().obstacles,
            [PreviewObstacle::Box {
                min: Vector3::new(-0.5, -1.0, -0.5),
                max: Vector3::new(1.5, 0.5, 1.5),
            }]
        );
        let count = |pixels: &[u8], c: RGBColor| {
            pixels
                .chunks_exact(3)
                .filter(|p| (p[0], p[1], p[2]) == (c.0, c.1, c.2))
                .count()
        };
        let with = rasterize(&preview.input(), 800, 600).unwrap();
        let bare = rasterize(
            &PreviewInput {
                obstacles: &[],
                ..preview.input()
            },
            800,
            600,
        )
        .unwrap();
        assert!(
            count(&with, BOX_WALL) > 10_000,
            "{}",
            count(&with, BOX_WALL)
        );
        assert_eq!(count(&bare, BOX_WALL), 0);
        // The box alone: its edges are the only dark pixels between the caption band and the
        // axis triad (rows 100..520); the twelve edges of a box filling the picture run over
        // thousands of pixels.
        let alone = PreviewInput {
            positions: PreviewPositions::Three(&[]),
            triangles: &[],
            lines: &[],
            pinned: &[],
            ..preview.input()
        };
        let dark = |pixels: &[u8]| {
            pixels[100 * 800 * 3..520 * 800 * 3]
                .chunks_exact(3)
                .filter(|p| p.iter().all(|&c| c < 190))
                .count()
        };
        let edges = dark(&rasterize(&alone, 800, 600).unwrap());
        assert!(edges > 1500, "{edges}");
        let nothing = PreviewInput {
            obstacles: &[],
            ..alone
        };
        assert_eq!(dark(&rasterize(&nothing, 800, 600).unwrap()), 0);
        // Three far walls and three near ones, whichever way the camera looks.
        let view = BoxView::new(&Camera::new(), &Vector3::zeros(), &Vector3::repeat(1.0)).unwrap();
        assert_eq!(view.far.iter().filter(|&&f| f).count(), 3);
        assert_eq!(BoxView::edges().count(), 12);
    }

    #[test]
    fn the_legend_names_the_two_sides_only_for_surfaces() {
        // Both colours appear in the caption band of a cloth's picture (the swatches), whatever
        // the cloth shows; a spring-only picture has no legend.
        let (p, t, l) = hanging_cloth(6);
        let band = |input: &PreviewInput| {
            let pixels = rasterize(input, 800, 600).unwrap();
            // Rows 60..76: the legend's line.
            let rows = &pixels[60 * 800 * 3..76 * 800 * 3];
            let has = |c: RGBColor| {
                rows.chunks_exact(3)
                    .any(|p| (p[0], p[1], p[2]) == (c.0, c.1, c.2))
            };
            (has(shade(FRONT, 1.0)), has(shade(BACK, 1.0)))
        };
        assert_eq!(band(&cloth_input(&p, &t, &l, &[])), (true, true));
        assert_eq!(band(&cloth_input(&p, &[], &l, &[])), (false, false));
    }

    #[test]
    fn obstacles_are_drawn_behind_the_mesh() {
        // A ground plane under the cloth and a sphere beside it: both change the picture, the
        // ground's grey appears where the bare picture has background, and the cloth keeps its
        // pixels' colours where it covers them.
        let (p, t, l) = hanging_cloth(6);
        let bare = rasterize(&cloth_input(&p, &t, &l, &[]), 160, 120).unwrap();
        let obstacles = [
            PreviewObstacle::Plane {
                point: Vector3::new(0.0, -1.0, 0.0),
                normal: Vector3::y(),
            },
            PreviewObstacle::Sphere {
                center: Vector3::new(2.0, -0.5, 0.5),
                radius: 0.3,
            },
        ];
        let with = rasterize(
            &PreviewInput {
                obstacles: &obstacles,
                ..cloth_input(&p, &t, &l, &[])
            },
            160,
            120,
        )
        .unwrap();
        assert_eq!(bare.len(), with.len());
        let ground = with
            .chunks_exact(3)
            .filter(|c| (c[0], c[1], c[2]) == (GROUND.0, GROUND.1, GROUND.2))
            .count();
        assert!(ground > 100, "{ground} ground pixels");
        assert_eq!(
            bare.chunks_exact(3)
                .filter(|c| (c[0], c[1], c[2]) == (GROUND.0, GROUND.1, GROUND.2))
                .count(),
            0
        );
    }
}
