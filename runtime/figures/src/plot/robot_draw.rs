//! Drawing the robot views and animation frames on a plotters backend: the painter's
//! algorithm for one robot and its obstacles, the cells, the edge-on zoom with its gap,
//! legends and captions.

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::super::FONT;
use super::shape::{self, Bounds, Point, Projection, Rect, Shape, Solid};
use super::{
    Camera, Scene, Snapshot, lowest, lowest_corner, tolerance_text, violated, zoom_camera,
};
use crate::model::Model;
use softcbf_generated::{BarrierInfo, BarrierKind, Point as Watch};

/// Width of a snapshot cell \[px\].
pub(super) const CELL_WIDTH: u32 = 270;
/// Width of the zoom cell \[px\].
pub(super) const ZOOM_WIDTH: u32 = 400;
/// Height of a row's cells \[px\].
pub(super) const CELL_HEIGHT: u32 = 480;
/// Height of the figure title band and of a row's title band \[px\].
pub(super) const TITLE_HEIGHT: u32 = 40;
pub(super) const ROW_TITLE_HEIGHT: u32 = 34;
/// Width of the legend's right block (scale bar, camera, axes) and of one of its
/// columns of entries \[px\].
const LEGEND_RIGHT: u32 = 290;
const LEGEND_COLUMN: u32 = 290;

/// Columns of legend entries in a figure `width` pixels wide (1 to 4).
fn legend_columns(width: u32) -> u32 {
    (width.saturating_sub(LEGEND_RIGHT) / LEGEND_COLUMN).clamp(1, 4)
}

/// Height of the legend strip of a figure `width` pixels wide with `entries` entries
/// \[px\]: 28 per row of entries, at least the right block's 76.
pub(super) fn legend_height(width: u32, entries: usize) -> u32 {
    (20 + 28 * (entries as u32).div_ceil(legend_columns(width))).max(76)
}
/// Room for the captions at the top of a cell \[px\].
pub(super) const CAPTION_HEIGHT: f64 = 46.0;
/// Room for the zoom's annotation at the bottom \[px\].
pub(super) const ZOOM_NOTE_HEIGHT: f64 = 58.0;
/// Animation cell size \[px\].
pub(super) const FRAME_CELL: (u32, u32) = (440, 470);
/// Height of the animation's bottom strip (time line and legend) \[px\].
pub(super) const FRAME_STRIP: u32 = 64;

pub(super) const BACKBONE: RGBColor = RGBColor(30, 30, 30);
pub(super) const TENDON: RGBColor = RGBColor(166, 118, 29);
pub(super) const PLATE_FILL: RGBColor = RGBColor(198, 219, 239);
pub(super) const PLATE_EDGE: RGBColor = RGBColor(33, 102, 172);
pub(super) const BASE_FILL: RGBColor = RGBColor(189, 189, 189);
pub(super) const BASE_EDGE: RGBColor = RGBColor(82, 82, 82);
pub(super) const ACTIVE: RGBColor = RGBColor(230, 145, 0);
pub(super) const VIOLATED: RGBColor = RGBColor(204, 30, 30);
pub(super) const CLEAR: RGBColor = RGBColor(0, 140, 100);
pub(super) const BAND: RGBColor = RGBColor(253, 219, 199);
pub(super) const FRAME: RGBColor = RGBColor(210, 210, 210);
pub(super) const TEXT: RGBColor = RGBColor(20, 20, 20);
pub(super) const MUTED: RGBColor = RGBColor(100, 100, 100);
pub(super) const SPHERE_FILL: RGBColor = RGBColor(148, 103, 189);
pub(super) const SPHERE_EDGE: RGBColor = RGBColor(84, 39, 143);
pub(super) const WALL_FILL: RGBColor = RGBColor(120, 180, 120);
pub(super) const WALL_EDGE: RGBColor = RGBColor(35, 110, 60);
pub(super) const WATCHED: RGBColor = RGBColor(0, 150, 160);

/// Every colour the drawings of a robot without obstacles use (the animation's palette
/// starts with these).
pub(super) const COLOURS: [RGBColor; 15] = [
    WHITE, BLACK, BACKBONE, TENDON, PLATE_FILL, PLATE_EDGE, BASE_FILL, BASE_EDGE, ACTIVE, VIOLATED,
    CLEAR, BAND, FRAME, TEXT, MUTED,
];
/// The further colours of obstacles and watched points.
pub(super) const OBSTACLE_COLOURS: [RGBColor; 5] =
    [SPHERE_FILL, SPHERE_EDGE, WALL_FILL, WALL_EDGE, WATCHED];
/// Opacity of a sphere's fill and of a half-space's patch.
const SPHERE_ALPHA: f64 = 0.45;
const WALL_ALPHA: f64 = 0.22;
/// Straight pieces of a drawn circle.
const CIRCLE_PIECES: usize = 72;

/// The obstacles of a robot as a figure draws them: each drawable one, and for a
/// half-space the patch of its plane across the scene.
pub(super) struct Scenery {
    /// Obstacles with finite geometry, with their plane patch (empty for a sphere, or a
    /// plane that misses the scene).
    pub solids: Vec<(Solid, Vec<Point>)>,
    /// Every obstacle in file order (`None`: not drawable), for the marks of active points.
    pub by_index: Vec<Option<Solid>>,
    /// Length of a half-space's normal arrow \[m\].
    pub arrow: f64,
    /// Whether the robot's barriers watch any point for an obstacle.
    pub watches: bool,
}

impl Scenery {
    /// The obstacles of `model` in a scene holding `shapes`.
    pub(super) fn new<'s>(model: &Model, shapes: impl Iterator<Item = &'s Shape>) -> Scenery {
        let by_index = shape::solids(model);
        // The scene's box, grown to reach every plane (where it is nearest the middle), so
        // that each half-space shows a patch.
        let bounds: Option<Bounds> = shape::scene_box(shapes).map(|(mut low, mut high)| {
            let middle: Point = std::array::from_fn(|k| 0.5 * (low[k] + high[k]));
            for solid in by_index.iter().flatten() {
                if let (Solid::HalfSpace { .. }, Some(foot)) = (solid, solid.nearest(middle)) {
                    for k in 0..3 {
                        low[k] = low[k].min(foot[k]);
                        high[k] = high[k].max(foot[k]);
                    }
                }
            }
            (low, high)
        });
        let arrow = bounds.map_or(0.03, |(low, high)| {
            0.12 * (0..3).map(|k| high[k] - low[k]).fold(0.0, f64::max)
        });
        let solids = by_index
            .iter()
            .flatten()
            .map(|&solid| {
                let patch = match (solid, &bounds) {
                    (Solid::HalfSpace { normal, offset, .. }, Some(bounds)) => {
                        shape::plane_patch(normal, offset, bounds)
                    }
                    _ => Vec::new(),
                };
                (solid, patch)
            })
            .collect();
        Scenery {
            solids,
            by_index,
            arrow,
            watches: model
                .generated
                .barrier_table()
                .iter()
                .any(|info| info.obstacle.is_some()),
        }
    }

    /// Whether there is anything to draw beyond the robot.
    pub(super) fn is_empty(&self) -> bool {
        self.by_index.is_empty() && !self.watches
    }

    fn has_sphere(&self) -> bool {
        self.solids
            .iter()
            .any(|(s, _)| matches!(s, Solid::Sphere { .. }))
    }

    fn has_half_space(&self) -> bool {
        self.solids
            .iter()
            .any(|(s, _)| matches!(s, Solid::HalfSpace { .. }))
    }

    /// The palette of the animation: [`COLOURS`], and when there are obstacles theirs
    /// with their translucent fills over white (a sphere, its light spot, a patch).
    pub(super) fn palette(&self) -> Vec<[u8; 3]> {
        let mut colours: Vec<[u8; 3]> = COLOURS.iter().map(|c| [c.0, c.1, c.2]).collect();
        if !self.is_empty() {
            colours.extend(OBSTACLE_COLOURS.iter().map(|c| [c.0, c.1, c.2]));
            let over = |c: [f64; 3], alpha: f64| c.map(|v| alpha * v + (1.0 - alpha) * 255.0);
            let rgb = |c: RGBColor| [c.0 as f64, c.1 as f64, c.2 as f64];
            let sphere = over(rgb(SPHERE_FILL), SPHERE_ALPHA);
            for blend in [sphere, over(sphere, 0.7), over(rgb(WALL_FILL), WALL_ALPHA)] {
                colours.push(blend.map(|v| v.round().clamp(0.0, 255.0) as u8));
            }
        }
        colours
    }
}

/// Screen coordinates of world points in one cell: projection, centre and scale.
#[derive(Clone, Copy, Debug)]
pub(super) struct Mapping {
    pub projection: Projection,
    /// Screen coordinates \[m\] drawn at the centre of `rect`.
    pub centre: (f64, f64),
    /// Pixels per metre.
    pub scale: f64,
    /// The drawing's pixels, in the cell's coordinates.
    pub rect: Rect,
}

impl Mapping {
    /// Pixel position and depth of `p`.
    fn pixel(&self, p: Point) -> (f64, f64, f64) {
        let (x, y, depth) = self.projection.project(p);
        let cx = 0.5 * (self.rect.x0 + self.rect.x1);
        let cy = 0.5 * (self.rect.y0 + self.rect.y1);
        (
            cx + self.scale * (x - self.centre.0),
            cy - self.scale * (y - self.centre.1),
            depth,
        )
    }

    fn xy(&self, p: Point) -> (f64, f64) {
        let (x, y, _) = self.pixel(p);
        (x, y)
    }
}

/// A screen extent `(x range, y range)` \[m\].
pub(super) type Extent = ((f64, f64), (f64, f64));

/// The extent of shapes seen through `projection`, and of the spheres of `scenery` (each
/// with its margin) as far as they reach within half the shapes' size around them.
pub(super) fn extent<'s>(
    shapes: impl Iterator<Item = &'s Shape>,
    projection: &Projection,
    scenery: &Scenery,
) -> Option<Extent> {
    let mut bounds: Option<Extent> = None;
    let cover = |bounds: &mut Option<Extent>, x: f64, y: f64| {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        let b = bounds.get_or_insert(((x, x), (y, y)));
        b.0 = (b.0.0.min(x), b.0.1.max(x));
        b.1 = (b.1.0.min(y), b.1.1.max(y));
    };
    for p in shapes.flat_map(Shape::points) {
        let (x, y, _) = projection.project(p);
        cover(&mut bounds, x, y);
    }
    let robot = bounds?;
    let reach = 0.5 * (robot.0.1 - robot.0.0).max(robot.1.1 - robot.1.0);
    let (xs, ys) = (
        (robot.0.0 - reach, robot.0.1 + reach),
        (robot.1.0 - reach, robot.1.1 + reach),
    );
    for (solid, _) in &scenery.solids {
        if let Solid::Sphere {
            centre,
            radius,
            margin,
        } = *solid
        {
            let (x, y, _) = projection.project(centre);
            let r = radius + margin.max(0.0);
            for (dx, dy) in [(-r, -r), (r, r)] {
                cover(
                    &mut bounds,
                    (x + dx).clamp(xs.0, xs.1),
                    (y + dy).clamp(ys.0, ys.1),
                );
            }
        }
    }
    bounds
}

/// The mapping that fits `bounds` into `rect` with equal scales and a small margin.
pub(super) fn fit(projection: Projection, bounds: ((f64, f64), (f64, f64)), rect: Rect) -> Mapping {
    let (width, height) = (bounds.0.1 - bounds.0.0, bounds.1.1 - bounds.1.0);
    let room = ((rect.x1 - rect.x0) * 0.92, (rect.y1 - rect.y0) * 0.92);
    let scale = (room.0 / width.max(1e-6)).min(room.1 / height.max(1e-6));
    Mapping {
        projection,
        centre: (
            0.5 * (bounds.0.0 + bounds.0.1),
            0.5 * (bounds.1.0 + bounds.1.1),
        ),
        scale,
        rect,
    }
}

pub(super) type DrawResult = Result<(), String>;

pub(super) fn pixel(p: (f64, f64)) -> (i32, i32) {
    (p.0.round() as i32, p.1.round() as i32)
}

/// Draws the segment `a`–`b` (pixels) clipped to `rect`.
pub(super) fn segment<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    a: (f64, f64),
    b: (f64, f64),
    rect: &Rect,
    style: ShapeStyle,
    dashed: bool,
) -> DrawResult {
    let Some((a, b)) = shape::clip_segment(a, b, rect) else {
        return Ok(());
    };
    let points = [pixel(a), pixel(b)];
    let result = if dashed {
        area.draw(&DashedPathElement::new(points, 5, 4, style))
    } else {
        area.draw(&PathElement::new(points.to_vec(), style))
    };
    result.map_err(|e| e.to_string())
}

/// Draws a filled polygon with its outline, clipped to `rect`.
pub(super) fn polygon<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    points: &[(f64, f64)],
    rect: &Rect,
    fill: RGBColor,
    edge: Option<(RGBColor, u32)>,
) -> DrawResult {
    fill_clipped(area, points, rect, fill.filled())?;
    if let Some((colour, width)) = edge {
        for k in 0..points.len() {
            let next = points[(k + 1) % points.len()];
            segment(
                area,
                points[k],
                next,
                rect,
                colour.stroke_width(width),
                false,
            )?;
        }
    }
    Ok(())
}

/// Draws a translucent filled polygon (opacity `alpha`), clipped to `rect`.
pub(super) fn polygon_alpha<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    points: &[(f64, f64)],
    rect: &Rect,
    fill: RGBColor,
    alpha: f64,
) -> DrawResult {
    fill_clipped(area, points, rect, fill.mix(alpha).filled())
}

/// Fills the polygon `points` (pixels) with `style`, clipped to `rect`.
fn fill_clipped<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    points: &[(f64, f64)],
    rect: &Rect,
    style: ShapeStyle,
) -> DrawResult {
    let clipped = shape::clip_polygon(points, rect);
    if clipped.len() >= 3 {
        let pixels: Vec<(i32, i32)> = clipped.iter().copied().map(pixel).collect();
        area.draw(&Polygon::new(pixels, style))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Draws the polyline `points` (pixels), clipped to `rect`; dashed along its whole length
/// when `dashed`.
pub(super) fn polyline<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    points: &[(f64, f64)],
    rect: &Rect,
    style: ShapeStyle,
    dashed: bool,
) -> DrawResult {
    // Runs of consecutive pieces inside the rectangle, each drawn as one path.
    let mut runs: Vec<Vec<(i32, i32)>> = Vec::new();
    let mut open = false;
    for pair in points.windows(2) {
        match shape::clip_segment(pair[0], pair[1], rect) {
            Some((a, b)) => {
                let (a, b) = (pixel(a), pixel(b));
                match runs.last_mut() {
                    Some(run) if open && run.last() == Some(&a) => run.push(b),
                    _ => runs.push(vec![a, b]),
                }
                // A piece cut at its end leaves the rectangle: the next one starts anew.
                open = pixel(pair[1]) == b;
            }
            None => open = false,
        }
    }
    for run in runs {
        let result = if dashed {
            area.draw(&DashedPathElement::new(run, 6, 4, style))
        } else {
            area.draw(&PathElement::new(run, style))
        };
        result.map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// The points (pixels) of a circle about `centre` of `radius` pixels, closed.
fn circle_points(centre: (f64, f64), radius: f64) -> Vec<(f64, f64)> {
    (0..=CIRCLE_PIECES)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / CIRCLE_PIECES as f64;
            (centre.0 + radius * a.cos(), centre.1 + radius * a.sin())
        })
        .collect()
}

/// Draws a sphere obstacle: a shaded disc of its radius with a lighter spot toward the
/// upper left, its equator as a wire, its outline, and a dashed outline at radius plus
/// margin.
fn draw_sphere<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    mapping: &Mapping,
    (centre, radius, margin): (Point, f64, f64),
    thin: bool,
) -> DrawResult {
    let rect = &mapping.rect;
    let c = mapping.xy(centre);
    let r = radius * mapping.scale;
    let disc = circle_points(c, r);
    polygon_alpha(area, &disc, rect, SPHERE_FILL, SPHERE_ALPHA)?;
    let spot = circle_points((c.0 - 0.3 * r, c.1 - 0.3 * r), 0.45 * r);
    polygon_alpha(area, &spot, rect, WHITE, 0.3)?;
    let equator: Vec<(f64, f64)> = (0..=CIRCLE_PIECES)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / CIRCLE_PIECES as f64;
            mapping.xy([
                centre[0] + radius * a.cos(),
                centre[1] + radius * a.sin(),
                centre[2],
            ])
        })
        .collect();
    polyline(
        area,
        &equator,
        rect,
        SPHERE_EDGE.mix(0.6).stroke_width(1),
        false,
    )?;
    polyline(
        area,
        &disc,
        rect,
        SPHERE_EDGE.stroke_width(if thin { 1 } else { 2 }),
        false,
    )?;
    if margin > 0.0 {
        let outer = circle_points(c, (radius + margin) * mapping.scale);
        polyline(area, &outer, rect, SPHERE_EDGE.stroke_width(1), true)?;
    }
    Ok(())
}

/// Draws a half-space obstacle's translucent patch of its plane with its outline.
fn draw_half_space<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    mapping: &Mapping,
    patch: &[Point],
) -> DrawResult {
    if patch.len() < 3 {
        return Ok(());
    }
    let rect = &mapping.rect;
    let mut points: Vec<(f64, f64)> = patch.iter().map(|&p| mapping.xy(p)).collect();
    polygon_alpha(area, &points, rect, WALL_FILL, WALL_ALPHA)?;
    points.push(points[0]);
    polyline(area, &points, rect, WALL_EDGE.stroke_width(1), false)
}

/// Draws a half-space obstacle's normal: an arrow `arrow` metres long into the allowed
/// side, from low in the part of its patch in view (away from the middle, where the robot
/// mostly is).
fn draw_normal_arrow<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    mapping: &Mapping,
    normal: Point,
    patch: &[Point],
    arrow: f64,
) -> DrawResult {
    let rect = &mapping.rect;
    let points: Vec<(f64, f64)> = patch.iter().map(|&p| mapping.xy(p)).collect();
    let seen = shape::clip_polygon(&points, rect);
    if seen.is_empty() {
        return Ok(());
    }
    // Every point of the patch's image is the image of a point of the plane, and the
    // projection is orthographic: the arrow's image is the same from any of them.
    let n = seen.len() as f64;
    let middle = (
        seen.iter().map(|p| p.0).sum::<f64>() / n,
        seen.iter().map(|p| p.1).sum::<f64>() / n,
    );
    // Seven tenths of the way to the lowest corner in view: inside, as the patch is convex.
    let low = seen
        .iter()
        .copied()
        .max_by(|p, q| p.1.total_cmp(&q.1))
        .unwrap_or(middle);
    let a = (
        middle.0 + 0.7 * (low.0 - middle.0),
        middle.1 + 0.7 * (low.1 - middle.1),
    );
    let (right, up, _) = mapping.projection.project(normal);
    let b = (
        a.0 + arrow * mapping.scale * right,
        a.1 - arrow * mapping.scale * up,
    );
    let style = WALL_EDGE.stroke_width(2);
    segment(area, a, b, rect, style, false)?;
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let length = dx.hypot(dy);
    if length > 4.0 {
        let (ux, uy) = (dx / length, dy / length);
        let head = 8.0_f64.min(0.5 * length);
        for side in [-1.0, 1.0] {
            let end = (
                b.0 - head * ux + side * 0.5 * head * uy,
                b.1 - head * uy - side * 0.5 * head * ux,
            );
            segment(area, b, end, rect, style, false)?;
        }
    }
    if inside(a, rect) {
        area.draw(&Circle::new(pixel(a), 3, WALL_EDGE.filled()))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

pub(super) fn text<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    content: &str,
    at: (i32, i32),
    size: u32,
    colour: RGBColor,
    bold: bool,
    anchor: HPos,
) -> DrawResult {
    let style = if bold {
        FontStyle::Bold
    } else {
        FontStyle::Normal
    };
    let font = TextStyle::from((FONT, size, style).into_font())
        .color(&colour)
        .pos(Pos::new(anchor, VPos::Top));
    area.draw(&Text::new(content.to_string(), at, font))
        .map_err(|e| e.to_string())
}

/// What the painter's algorithm draws, far to near.
pub(super) enum Piece {
    Plate(usize),
    Backbone(usize, usize),
    Tendon(usize, usize, usize),
    /// Entry `k` of [`Scenery::solids`], a sphere.
    Sphere(usize),
}

/// Draws the robot of `shape` through `mapping`: the half-space patches of `scenery`
/// behind everything, then plates, backbones, tendons and spheres from far to near, the
/// watched points, and the highlighted corners and points of `snapshot` on top with their
/// drops to the plate below or lines to the obstacle. With `only = Some(i)`, just module
/// `i` (0-based): its segment, the plates at its two ends and its watched points. `thin`
/// draws lines narrower (the animation's smaller cells).
pub(super) fn draw_robot<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    shape: &Shape,
    snapshot: &Snapshot,
    mapping: &Mapping,
    only: Option<usize>,
    thin: bool,
    scenery: Option<&Scenery>,
) -> DrawResult {
    let rect = &mapping.rect;
    let mut pieces: Vec<(f64, Piece)> = Vec::new();
    let depth = |points: &[Point]| {
        points.iter().map(|&p| mapping.pixel(p).2).sum::<f64>() / points.len().max(1) as f64
    };
    let module_shown = |i: usize| only.is_none_or(|m| m == i);
    if let Some(scenery) = scenery {
        for (k, (solid, patch)) in scenery.solids.iter().enumerate() {
            match *solid {
                Solid::HalfSpace { .. } => draw_half_space(area, mapping, patch)?,
                Solid::Sphere { centre, .. } => {
                    pieces.push((depth(&[centre]), Piece::Sphere(k)));
                }
            }
        }
    }
    for (k, plate) in shape.plates.iter().enumerate() {
        if only.is_none_or(|m| k == m || k == m + 1) {
            pieces.push((depth(plate), Piece::Plate(k)));
        }
    }
    for (i, backbone) in shape.backbones.iter().enumerate() {
        if !module_shown(i) {
            continue;
        }
        for k in 1..backbone.len() {
            pieces.push((depth(&backbone[k - 1..=k]), Piece::Backbone(i, k)));
        }
    }
    for (i, tendons) in shape.tendons.iter().enumerate() {
        if !module_shown(i) {
            continue;
        }
        for (t, tendon) in tendons.iter().enumerate() {
            for k in 1..tendon.len() {
                pieces.push((depth(&tendon[k - 1..=k]), Piece::Tendon(i, t, k)));
            }
        }
    }
    pieces.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (backbone_width, tendon_width, edge_width) = if thin { (2, 1, 1) } else { (3, 1, 2) };
    for (_, piece) in &pieces {
        match *piece {
            Piece::Plate(k) => {
                let points: Vec<(f64, f64)> =
                    shape.plates[k].iter().map(|&p| mapping.xy(p)).collect();
                let (fill, edge) = if k == 0 {
                    (BASE_FILL, BASE_EDGE)
                } else {
                    (PLATE_FILL, PLATE_EDGE)
                };
                polygon(area, &points, rect, fill, Some((edge, edge_width)))?;
            }
            Piece::Backbone(i, k) => {
                let line = &shape.backbones[i];
                segment(
                    area,
                    mapping.xy(line[k - 1]),
                    mapping.xy(line[k]),
                    rect,
                    BACKBONE.stroke_width(backbone_width),
                    false,
                )?;
            }
            Piece::Tendon(i, t, k) => {
                let line = &shape.tendons[i][t];
                segment(
                    area,
                    mapping.xy(line[k - 1]),
                    mapping.xy(line[k]),
                    rect,
                    TENDON.stroke_width(tendon_width),
                    false,
                )?;
            }
            Piece::Sphere(k) => {
                if let Some((
                    Solid::Sphere {
                        centre,
                        radius,
                        margin,
                    },
                    _,
                )) = scenery.and_then(|s| s.solids.get(k))
                {
                    draw_sphere(area, mapping, (*centre, *radius, *margin), thin)?;
                }
            }
        }
    }
    for (solid, patch) in scenery.iter().flat_map(|s| &s.solids) {
        if let (Solid::HalfSpace { normal, .. }, Some(scenery)) = (solid, scenery) {
            draw_normal_arrow(area, mapping, *normal, patch, scenery.arrow)?;
        }
    }
    let dot = if thin { 2 } else { 3 };
    for mark in shape.watched.iter().flatten() {
        let at = mapping.xy(mark.at);
        if module_shown(mark.module) && inside(at, rect) {
            // A point on the (dark) backbone is ringed in white, one on a plate in black.
            let ring = if mark.arc { WHITE } else { BLACK };
            area.draw(&Circle::new(pixel(at), dot, WATCHED.filled()))
                .map_err(|e| e.to_string())?;
            area.draw(&Circle::new(pixel(at), dot, ring.stroke_width(1)))
                .map_err(|e| e.to_string())?;
        }
    }
    for &j in &snapshot.active {
        // A corner drops to the plate below; a watched point reaches for its obstacle.
        let (from, to) = if let Some(gap) = shape.corner(j) {
            if !module_shown(gap.module) {
                continue;
            }
            (gap.corner, Some(gap.foot))
        } else if let Some(Some(mark)) = shape.watched.get(j) {
            if !module_shown(mark.module) {
                continue;
            }
            let solid = scenery.and_then(|s| s.by_index.get(mark.obstacle).copied().flatten());
            (mark.at, solid.and_then(|s| s.nearest(mark.at)))
        } else {
            continue;
        };
        let colour = if snapshot.violated.contains(&j) {
            VIOLATED
        } else {
            ACTIVE
        };
        let corner = mapping.xy(from);
        if let Some(to) = to {
            let foot = mapping.xy(to);
            segment(area, corner, foot, rect, colour.stroke_width(2), true)?;
            if inside(foot, rect) {
                area.draw(&Circle::new(pixel(foot), 2, colour.filled()))
                    .map_err(|e| e.to_string())?;
            }
        }
        if inside(corner, rect) {
            let radius = if thin { 4 } else { 6 };
            area.draw(&Circle::new(pixel(corner), radius, colour.filled()))
                .map_err(|e| e.to_string())?;
            area.draw(&Circle::new(pixel(corner), radius, BLACK.stroke_width(1)))
                .map_err(|e| e.to_string())?;
        }
    }
    Ok(())
}

pub(super) fn inside(p: (f64, f64), rect: &Rect) -> bool {
    p.0 >= rect.x0 && p.0 <= rect.x1 && p.1 >= rect.y0 && p.1 <= rect.y1
}

/// `t` in seconds to the millisecond, without trailing zeros: `0.16 s`, `10 s`.
pub(super) fn format_time(t: f64) -> String {
    let text = format!("{t:.3}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    let text = if text == "-0" { "0" } else { text };
    format!("{} s", text.replace('-', "−"))
}

/// A length in millimetres with a sign, `+0.00 mm`.
pub(super) fn format_mm(value: f64) -> String {
    let mm = 1000.0 * value;
    if mm.abs() < 0.005 {
        "0.00 mm".to_string()
    } else {
        format!("{mm:+.2} mm").replace('-', "−")
    }
}

/// A barrier's value with its unit: millimetres (`+0.00 mm`), or radians for a bend limit
/// (`+0.123 rad`).
pub(super) fn format_barrier(value: f64, info: Option<&BarrierInfo>) -> String {
    if info.is_some_and(|info| info.kind == BarrierKind::Bend) {
        if value.abs() < 0.0005 {
            "0.000 rad".to_string()
        } else {
            format!("{value:+.3} rad").replace('-', "−")
        }
    } else {
        format_mm(value)
    }
}

/// Captions of a snapshot cell: the time (and the time asked, when the record has no row
/// near it) and the lowest barrier.
pub(super) fn captions(scene: &Scene, model: &Model) -> (String, String) {
    let snapshot = &scene.snapshot;
    if snapshot.row.is_none() || scene.shape.is_none() {
        return (
            format!("t = {}", format_time(snapshot.asked)),
            "no finite state in the record".to_string(),
        );
    }
    let mut first = format!("t = {}", format_time(snapshot.t));
    let tolerance = 1e-6 * snapshot.asked.abs().max(1.0);
    if (snapshot.t - snapshot.asked).abs() > tolerance.max(0.5e-3) {
        first.push_str(&format!(" (asked {})", format_time(snapshot.asked)));
    }
    if snapshot.invalid.is_some() {
        return (first, "invalid state:".to_string());
    }
    let second = match lowest(snapshot) {
        Some((j, b)) => {
            let info = model.generated.barrier_table().get(j);
            let label = info.map(short_label).unwrap_or_default();
            format!("lowest b = {} ({label})", format_barrier(b, info))
        }
        None => "no barrier".to_string(),
    };
    (first, second)
}

/// Colour and weight of a snapshot's second caption: red and bold for an invalid state.
pub(super) fn caption_style(snapshot: &Snapshot) -> (RGBColor, bool) {
    if snapshot.invalid.is_some() {
        (VIOLATED, true)
    } else {
        (MUTED, false)
    }
}

/// A short name of a barrier, 1-based: `m1 c3` (module 1, corner 3), `m2 δL max`,
/// `m1 bend`, `o1 m2 c3` (obstacle 1, module 2's corner 3), `o2 m1 centre`, `o1 m1 arc 2`.
pub(super) fn short_label(info: &BarrierInfo) -> String {
    let m = info.module + 1;
    match info.kind {
        BarrierKind::PlateCorner => match info.corner() {
            Some(j) => format!("m{m} c{}", j + 1),
            None => info.label.to_string(),
        },
        BarrierKind::ElongationMin => format!("m{m} δL min"),
        BarrierKind::ElongationMax => format!("m{m} δL max"),
        BarrierKind::Bend => format!("m{m} bend"),
        BarrierKind::HalfSpace | BarrierKind::Sphere => {
            let point = match info.point {
                Some(Watch::Corner(j)) => format!("c{}", j + 1),
                // `point 1`, `arc 2`, `centre`: the label's words after the module.
                _ => {
                    let words: Vec<&str> = info.label.split(' ').collect();
                    match words.iter().position(|w| *w == "module") {
                        Some(k) if k + 2 <= words.len() => words[k + 2..].join(" "),
                        _ => info.label.to_string(),
                    }
                }
            };
            match info.obstacle {
                Some(o) => format!("o{} m{m} {point}", o + 1),
                None => format!("m{m} {point}"),
            }
        }
    }
}

/// The zoom on a final state: its mapping and the barrier it annotates.
pub(super) struct Zoom {
    mapping: Mapping,
    barrier: usize,
}

/// Half the side of the zoom window \[m\], the same for every run: room for the largest
/// corner height and its margin, and at least half a corner radius.
pub(super) fn zoom_half_size(scenes: &[&Scene], model: &Model) -> f64 {
    let radius = model
        .robot
        .modules
        .iter()
        .map(|m| m.corner_radius)
        .fold(0.0, f64::max);
    let mut half = 0.5 * radius;
    for scene in scenes {
        if let (Some(shape), Some((j, _))) = (&scene.shape, lowest_corner(scene))
            && let Some(gap) = shape.corner(j)
        {
            half = half.max(0.8 * gap.height.abs() + gap.margin + 0.006);
        }
    }
    half
}

pub(super) fn zoom(scene: &Scene, main: &Projection, half: f64, rect: Rect) -> Option<Zoom> {
    let shape = scene.shape.as_ref()?;
    let (barrier, _) = lowest_corner(scene)?;
    let projection = zoom_camera(shape, barrier, main)?;
    let gap = shape.corner(barrier)?;
    let (cx, cy, _) = projection.project(gap.corner);
    let (fx, fy, _) = projection.project(gap.foot);
    let side = (rect.x1 - rect.x0).min(rect.y1 - rect.y0);
    Some(Zoom {
        mapping: Mapping {
            projection,
            centre: (0.5 * (cx + fx), 0.5 * (cy + fy)),
            scale: side / (2.0 * half),
            rect,
        },
        barrier,
    })
}

/// Draws the zoom on a final state: the margin band above the lower plate, the robot, and
/// the lowest barrier as a dimension line with its value.
pub(super) fn draw_zoom<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    scene: &Scene,
    zoom: &Zoom,
    active_below: f64,
    model: &Model,
) -> DrawResult {
    let Some(shape) = &scene.shape else {
        return Ok(());
    };
    let Some(gap) = shape.corner(zoom.barrier) else {
        return Ok(());
    };
    let mapping = &zoom.mapping;
    let rect = &mapping.rect;
    let lower = gap.module;
    let normal = shape::rotate(&shape.poses[lower], [0.0, 0.0, 1.0]);
    let lift = |p: Point, h: f64| {
        [
            p[0] + h * normal[0],
            p[1] + h * normal[1],
            p[2] + h * normal[2],
        ]
    };
    // The plane of the plate below, edge-on, across the window, and the margin above it.
    let reach = 4.0 * (rect.x1 - rect.x0 + rect.y1 - rect.y0) / mapping.scale;
    let along = mapping.projection.right;
    let across = |h: f64, side: f64| {
        mapping.xy(lift(
            [
                gap.foot[0] + side * reach * along[0],
                gap.foot[1] + side * reach * along[1],
                gap.foot[2] + side * reach * along[2],
            ],
            h,
        ))
    };
    let band = [
        across(0.0, -1.0),
        across(0.0, 1.0),
        across(gap.margin, 1.0),
        across(gap.margin, -1.0),
    ];
    polygon(area, &band, rect, BAND, None)?;
    segment(
        area,
        across(0.0, -1.0),
        across(0.0, 1.0),
        rect,
        MUTED.stroke_width(1),
        true,
    )?;
    draw_robot(
        area,
        shape,
        &scene.snapshot,
        mapping,
        Some(lower),
        false,
        None,
    )?;
    let b = scene
        .snapshot
        .b
        .get(zoom.barrier)
        .copied()
        .unwrap_or(f64::NAN);
    let colour = if violated(b) {
        VIOLATED
    } else if b <= active_below {
        ACTIVE
    } else {
        CLEAR
    };
    let corner = mapping.xy(gap.corner);
    let top = mapping.xy(lift(gap.foot, gap.margin));
    let foot = mapping.xy(gap.foot);
    segment(area, foot, top, rect, MUTED.stroke_width(1), false)?;
    segment(area, corner, top, rect, colour.stroke_width(3), false)?;
    for end in [corner, top] {
        segment(
            area,
            (end.0 - 7.0, end.1),
            (end.0 + 7.0, end.1),
            rect,
            colour.stroke_width(2),
            false,
        )?;
    }
    // The value beside the dimension line, on the side away from the upper plate.
    let upper = mapping.xy(shape::apply(&shape.poses[lower + 1], [0.0; 3]));
    let (anchor, dx) = if upper.0 > corner.0 {
        (HPos::Right, -12.0)
    } else {
        (HPos::Left, 12.0)
    };
    let label_at = (
        (0.5 * (corner.0 + top.0) + dx).clamp(rect.x0 + 130.0, rect.x1 - 130.0),
        (0.5 * (corner.1 + top.1) - 9.0).clamp(rect.y0, rect.y1 - 20.0),
    );
    text(
        area,
        &format!("b = {}", format_mm(b)),
        pixel(label_at),
        16,
        colour,
        true,
        anchor,
    )?;
    // Scale bar: 10 mm (or the round length nearest a fifth of the window).
    let bar = nice_length(0.2 * (rect.x1 - rect.x0) / mapping.scale);
    let y = rect.y1 - 10.0;
    let x0 = rect.x0 + 10.0;
    segment(
        area,
        (x0, y),
        (x0 + bar * mapping.scale, y),
        rect,
        BLACK.stroke_width(2),
        false,
    )?;
    text(
        area,
        &format!("{} mm", (bar * 1000.0).round()),
        pixel((x0, y - 20.0)),
        13,
        TEXT,
        false,
        HPos::Left,
    )?;
    let table = model.generated.barrier_table();
    let info = table.get(zoom.barrier);
    let (_, h) = area.dim_in_pixel();
    let note_top = h as f64 - ZOOM_NOTE_HEIGHT + 6.0;
    let status = |b: f64| {
        if violated(b) {
            "below its margin"
        } else if b <= active_below {
            "on its margin"
        } else {
            "clear"
        }
    };
    let height = format_mm(gap.height);
    let margin = format_mm(gap.margin);
    let (height, margin) = (
        height.trim_start_matches('+'),
        margin.trim_start_matches('+'),
    );
    // The lowest barrier of any kind; the zoom shows the lowest corner's gap.
    let (first, second) = match lowest(&scene.snapshot) {
        Some((j, low)) if j != zoom.barrier => {
            let other = table.get(j);
            (
                format!(
                    "lowest: {} b = {}, {}",
                    other.map(short_label).unwrap_or_default(),
                    format_barrier(low, other),
                    status(low)
                ),
                format!(
                    "lowest corner {}: c = {height}, ε = {margin}",
                    info.map(short_label).unwrap_or_default()
                ),
            )
        }
        _ => (
            format!(
                "lowest: {}, {}",
                info.map(|i| i.label).unwrap_or(""),
                status(b)
            ),
            format!(
                "height above plate {} c = {height}, margin ε = {margin}",
                gap.module
            ),
        ),
    };
    text(
        area,
        &first,
        (8, note_top as i32),
        14,
        TEXT,
        true,
        HPos::Left,
    )?;
    text(
        area,
        &second,
        (8, note_top as i32 + 20),
        13,
        MUTED,
        false,
        HPos::Left,
    )?;
    Ok(())
}

/// A round length (1, 2 or 5 × 10ⁿ m) near `length`.
pub(super) fn nice_length(length: f64) -> f64 {
    if !(length.is_finite() && length > 0.0) {
        return 0.01;
    }
    let unit = 10f64.powf(length.log10().floor());
    let mantissa = length / unit;
    let step = if mantissa < 1.5 {
        1.0
    } else if mantissa < 3.5 {
        2.0
    } else if mantissa < 7.5 {
        5.0
    } else {
        10.0
    };
    step * unit
}

/// Everything one figure draws.
pub(super) struct Figure<'a> {
    pub model: &'a Model,
    pub titles: Vec<&'a str>,
    pub scenes: Vec<Vec<Scene>>,
    /// The final state of each run.
    pub finals: Vec<Scene>,
    pub projection: Projection,
    pub camera: Camera,
    pub active_below: f64,
    /// The robot's obstacles in the scene of every snapshot.
    pub scenery: Scenery,
}

impl Figure<'_> {
    fn columns(&self) -> usize {
        self.scenes.first().map_or(0, Vec::len)
    }

    pub(super) fn size(&self) -> (u32, u32) {
        let width = (CELL_WIDTH * self.columns() as u32 + ZOOM_WIDTH).max(900);
        let rows = self.scenes.len() as u32;
        (
            width,
            TITLE_HEIGHT
                + rows * (ROW_TITLE_HEIGHT + CELL_HEIGHT)
                + legend_height(
                    width,
                    legend_entries(self.active_below, &self.scenery).len(),
                ),
        )
    }
}

pub(super) fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    figure: &Figure,
) -> DrawResult {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (width, height) = root.dim_in_pixel();
    let (header, rest) = root.split_vertically(TITLE_HEIGHT);
    let entries = legend_entries(figure.active_below, &figure.scenery);
    let (rows, legend) =
        rest.split_vertically(height - TITLE_HEIGHT - legend_height(width, entries.len()));
    text(
        &header,
        &format!(
            "{}: the robot at {} snapshot times and its final gaps",
            figure.model.robot.name,
            figure.columns(),
        ),
        (12, 10),
        19,
        TEXT,
        true,
        HPos::Left,
    )?;
    // One scale for every snapshot cell: the extent of all of them.
    let all = figure
        .scenes
        .iter()
        .flatten()
        .filter_map(|s| s.shape.as_ref());
    let cell_rect = Rect {
        x0: 4.0,
        y0: CAPTION_HEIGHT,
        x1: CELL_WIDTH as f64 - 4.0,
        y1: CELL_HEIGHT as f64 - 6.0,
    };
    let bounds =
        extent(all, &figure.projection, &figure.scenery).unwrap_or(((-0.1, 0.1), (0.0, 0.2)));
    let mapping = fit(figure.projection, bounds, cell_rect);
    let zoom_rect = Rect {
        x0: 4.0,
        y0: CAPTION_HEIGHT,
        x1: ZOOM_WIDTH as f64 - 4.0,
        y1: CELL_HEIGHT as f64 - ZOOM_NOTE_HEIGHT,
    };
    let finals: Vec<&Scene> = figure.finals.iter().collect();
    let half = zoom_half_size(&finals, figure.model);
    let row_areas = rows.split_evenly((figure.scenes.len().max(1), 1));
    for ((title, scenes), (area, last)) in figure
        .titles
        .iter()
        .zip(&figure.scenes)
        .zip(row_areas.iter().zip(&figure.finals))
    {
        let (band, cells) = area.split_vertically(ROW_TITLE_HEIGHT);
        band.fill(&RGBColor(243, 243, 243)).map_err(e)?;
        text(&band, title, (12, 6), 20, TEXT, true, HPos::Left)?;
        let (snapshots, zoom_area) = cells.split_horizontally(CELL_WIDTH * scenes.len() as u32);
        for (scene, cell) in scenes
            .iter()
            .zip(snapshots.split_evenly((1, scenes.len().max(1))).iter())
        {
            draw_cell_frame(cell)?;
            let (first, second) = captions(scene, figure.model);
            text(cell, &first, (10, 6), 17, TEXT, true, HPos::Left)?;
            let (colour, bold) = caption_style(&scene.snapshot);
            text(cell, &second, (10, 27), 13, colour, bold, HPos::Left)?;
            if let Some(problem) = &scene.snapshot.invalid {
                text(cell, problem, (10, 44), 13, VIOLATED, false, HPos::Left)?;
            }
            if let Some(shape) = &scene.shape {
                draw_robot(
                    cell,
                    shape,
                    &scene.snapshot,
                    &mapping,
                    None,
                    false,
                    Some(&figure.scenery),
                )?;
            }
        }
        draw_cell_frame(&zoom_area)?;
        let caption = if last.snapshot.invalid.is_some() {
            format!("end, t = {}: invalid state", format_time(last.snapshot.t))
        } else if last.snapshot.row.is_some() {
            format!("end, t = {}: gap, edge-on", format_time(last.snapshot.t))
        } else {
            "end: no finite state".to_string()
        };
        text(&zoom_area, &caption, (10, 6), 17, TEXT, true, HPos::Left)?;
        let zoomed = if last.snapshot.invalid.is_some() {
            None
        } else {
            zoom(last, &figure.projection, half, zoom_rect)
        };
        match zoomed {
            Some(z) => {
                text(
                    &zoom_area,
                    &format!(
                        "along the bend axis of module {}, {:.1}× the snapshots",
                        figure
                            .model
                            .generated
                            .barrier_table()
                            .get(z.barrier)
                            .map_or(0, |i| i.module + 1),
                        z.mapping.scale / mapping.scale
                    ),
                    (10, 27),
                    13,
                    MUTED,
                    false,
                    HPos::Left,
                )?;
                draw_zoom(&zoom_area, last, &z, figure.active_below, figure.model)?;
            }
            None => match &last.snapshot.invalid {
                Some(problem) => {
                    let lines = [
                        problem.clone(),
                        "The state left the model's domain: its barrier".to_string(),
                        "values and shape mean nothing, no gap is shown.".to_string(),
                    ];
                    for (k, line) in lines.iter().enumerate() {
                        text(
                            &zoom_area,
                            line,
                            (10, 27 + 20 * k as i32),
                            13,
                            if k == 0 { VIOLATED } else { MUTED },
                            k == 0,
                            HPos::Left,
                        )?;
                    }
                }
                None => {
                    text(
                        &zoom_area,
                        "nothing to zoom on",
                        (10, 27),
                        13,
                        MUTED,
                        false,
                        HPos::Left,
                    )?;
                }
            },
        }
    }
    draw_legend(&legend, &entries, &mapping, figure.camera)?;
    Ok(())
}

pub(super) fn draw_cell_frame<DB: DrawingBackend>(cell: &DrawingArea<DB, Shift>) -> DrawResult {
    let (w, h) = cell.dim_in_pixel();
    cell.draw(&Rectangle::new(
        [(0, 0), (w as i32 - 1, h as i32 - 1)],
        FRAME.stroke_width(1),
    ))
    .map_err(|e| e.to_string())
}

/// The mark a legend entry shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Mark {
    Backbone,
    Tendon,
    Plate,
    BasePlate,
    Active,
    Violated,
    Drop,
    Band,
    Sphere,
    HalfSpace,
    Watched,
}

/// The legend's entries: the robot's lines and marks, and the obstacles' and watched
/// points' when the robot has them.
pub(super) fn legend_entries(active_below: f64, scenery: &Scenery) -> Vec<(String, Mark)> {
    let below = format_mm(active_below);
    let below = below.trim_start_matches('+');
    let plain = scenery.is_empty();
    let (point, drop) = if plain {
        ("corner", "drop to the plate below")
    } else {
        ("point", "drop to the plate or obstacle")
    };
    let mut entries = vec![
        ("backbone (PCC arc)".to_string(), Mark::Backbone),
        ("tendon".to_string(), Mark::Tendon),
        ("plate".to_string(), Mark::Plate),
        ("base plate".to_string(), Mark::BasePlate),
        (format!("{point} with b ≤ {below}"), Mark::Active),
        (
            format!("{point} with b < −{}", tolerance_text()),
            Mark::Violated,
        ),
        (drop.to_string(), Mark::Drop),
        ("margin ε over the plane below".to_string(), Mark::Band),
    ];
    if scenery.has_sphere() {
        entries.push(("sphere (dashed: + margin ε)".to_string(), Mark::Sphere));
    }
    if scenery.has_half_space() {
        entries.push((
            "half-space (arrow: allowed side)".to_string(),
            Mark::HalfSpace,
        ));
    }
    if scenery.watches {
        entries.push(("point an obstacle watches".to_string(), Mark::Watched));
    }
    entries
}

/// The legend strip: one entry per kind of line and mark (in as many columns as fit),
/// then at the right the scale bar of the snapshot cells, the camera and the world axes
/// as it sees them.
pub(super) fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, Mark)],
    mapping: &Mapping,
    camera: Camera,
) -> DrawResult {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    let (width, height) = area.dim_in_pixel();
    let rect = Rect {
        x0: 0.0,
        y0: 0.0,
        x1: width as f64,
        y1: height as f64,
    };
    let columns = legend_columns(width) as i32;
    for (k, (label, kind)) in entries.iter().enumerate() {
        let x = 14 + LEGEND_COLUMN as i32 * (k as i32 % columns);
        let y = 12 + 28 * (k as i32 / columns);
        let (xf, yf) = (x as f64, y as f64 + 8.0);
        let line = |colour: RGBColor, width: u32, dashed: bool| {
            segment(
                area,
                (xf, yf),
                (xf + 34.0, yf),
                &rect,
                colour.stroke_width(width),
                dashed,
            )
        };
        let parallelogram = [
            (xf, yf + 6.0),
            (xf + 10.0, yf - 6.0),
            (xf + 34.0, yf - 6.0),
            (xf + 24.0, yf + 6.0),
        ];
        match kind {
            Mark::Backbone => line(BACKBONE, 3, false)?,
            Mark::Tendon => line(TENDON, 1, false)?,
            Mark::Plate | Mark::BasePlate | Mark::Band => {
                let (fill, edge) = match kind {
                    Mark::Plate => (PLATE_FILL, Some((PLATE_EDGE, 2))),
                    Mark::BasePlate => (BASE_FILL, Some((BASE_EDGE, 2))),
                    _ => (BAND, None),
                };
                polygon(area, &parallelogram, &rect, fill, edge)?;
            }
            Mark::Active | Mark::Violated => {
                let colour = if *kind == Mark::Active {
                    ACTIVE
                } else {
                    VIOLATED
                };
                let c = (x + 17, y + 8);
                area.draw(&Circle::new(c, 6, colour.filled())).map_err(e)?;
                area.draw(&Circle::new(c, 6, BLACK.stroke_width(1)))
                    .map_err(e)?;
            }
            Mark::Drop => line(ACTIVE, 2, true)?,
            Mark::Sphere => {
                let c = (xf + 17.0, yf);
                let disc = circle_points(c, 7.0);
                polygon_alpha(area, &disc, &rect, SPHERE_FILL, SPHERE_ALPHA)?;
                polyline(area, &disc, &rect, SPHERE_EDGE.stroke_width(2), false)?;
                let outer = circle_points(c, 10.5);
                polyline(area, &outer, &rect, SPHERE_EDGE.stroke_width(1), true)?;
            }
            Mark::HalfSpace => {
                polygon_alpha(area, &parallelogram, &rect, WALL_FILL, 2.0 * WALL_ALPHA)?;
                let mut outline = parallelogram.to_vec();
                outline.push(parallelogram[0]);
                polyline(area, &outline, &rect, WALL_EDGE.stroke_width(1), false)?;
                let style = WALL_EDGE.stroke_width(2);
                let (a, b) = ((xf + 17.0, yf), (xf + 17.0, yf - 11.0));
                segment(area, a, b, &rect, style, false)?;
                for side in [-3.0, 3.0] {
                    segment(area, b, (b.0 + side, b.1 + 4.0), &rect, style, false)?;
                }
            }
            Mark::Watched => {
                let c = (x + 17, y + 8);
                area.draw(&Circle::new(c, 3, WATCHED.filled())).map_err(e)?;
                area.draw(&Circle::new(c, 3, BLACK.stroke_width(1)))
                    .map_err(e)?;
            }
        }
        text(area, label, (x + 44, y), 15, TEXT, false, HPos::Left)?;
    }
    // The right block: scale bar, camera, axes.
    let left = width as f64 - LEGEND_RIGHT as f64 + 10.0;
    let bar = nice_length(60.0 / mapping.scale);
    let bar_end = left + bar * mapping.scale;
    segment(
        area,
        (left, 20.0),
        (bar_end, 20.0),
        &rect,
        BLACK.stroke_width(2),
        false,
    )?;
    text(
        area,
        &format!("{} mm", (bar * 1000.0).round()),
        pixel((bar_end + 8.0, 12.0)),
        13,
        TEXT,
        false,
        HPos::Left,
    )?;
    let degrees = |v: f64| format!("{v:.0}°").replace('-', "−");
    for (k, line) in [
        "orthographic view, equal scales,".to_string(),
        format!(
            "azimuth {}, elevation {}",
            degrees(camera.azimuth_deg),
            degrees(camera.elevation_deg)
        ),
    ]
    .iter()
    .enumerate()
    {
        text(
            area,
            line,
            (left as i32, 32 + 17 * k as i32),
            12,
            MUTED,
            false,
            HPos::Left,
        )?;
    }
    let origin = (width as f64 - 40.0, 42.0);
    for (axis, name) in [
        ([1.0, 0.0, 0.0], "x"),
        ([0.0, 1.0, 0.0], "y"),
        ([0.0, 0.0, 1.0], "z"),
    ] {
        let (dx, dy, _) = mapping.projection.project(axis);
        let end = (origin.0 + 22.0 * dx, origin.1 - 22.0 * dy);
        segment(area, origin, end, &rect, MUTED.stroke_width(2), false)?;
        text(
            area,
            name,
            pixel((end.0 + 8.0 * dx - 4.0, end.1 - 8.0 * dy - 8.0)),
            13,
            TEXT,
            false,
            HPos::Left,
        )?;
    }
    Ok(())
}

/// What one animation frame shows.
pub(super) struct AnimationFrame<'a> {
    pub model: &'a Model,
    pub titles: &'a [&'a str],
    pub scenes: &'a [&'a Scene],
    pub mapping: &'a Mapping,
    pub t: f64,
    pub span: (f64, f64),
    /// Robot seconds per second of playback.
    pub speed: f64,
    pub active_below: f64,
    /// The robot's obstacles.
    pub scenery: &'a Scenery,
}

pub(super) fn draw_frame<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    frame: &AnimationFrame,
) -> DrawResult {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (width, height) = root.dim_in_pixel();
    let (header, rest) = root.split_vertically(TITLE_HEIGHT);
    let (cells, strip) = rest.split_vertically(height - TITLE_HEIGHT - FRAME_STRIP);
    let speed = if frame.speed.is_finite() && frame.speed > 0.0 {
        format!("  (playing at {:.2}× real time)", frame.speed)
    } else {
        String::new()
    };
    text(
        &header,
        &format!(
            "{}: t = {}{speed}",
            frame.model.robot.name,
            format_time(frame.t)
        ),
        (12, 10),
        18,
        TEXT,
        true,
        HPos::Left,
    )?;
    for ((title, scene), cell) in frame
        .titles
        .iter()
        .zip(frame.scenes)
        .zip(cells.split_evenly((1, frame.scenes.len().max(1))).iter())
    {
        draw_cell_frame(cell)?;
        text(cell, title, (10, 6), 16, TEXT, true, HPos::Left)?;
        let (_, second) = captions(scene, frame.model);
        let (colour, bold) = caption_style(&scene.snapshot);
        text(cell, &second, (10, 28), 13, colour, bold, HPos::Left)?;
        if let Some(problem) = &scene.snapshot.invalid {
            text(cell, problem, (10, 45), 13, VIOLATED, false, HPos::Left)?;
        }
        if let Some(shape) = &scene.shape {
            draw_robot(
                cell,
                shape,
                &scene.snapshot,
                frame.mapping,
                None,
                true,
                Some(frame.scenery),
            )?;
        }
    }
    // Time line.
    let (t0, t1) = frame.span;
    let share = if t1 > t0 {
        ((frame.t - t0) / (t1 - t0)).clamp(0.0, 1.0)
    } else {
        1.0
    };
    let x0 = 14.0;
    let x1 = width as f64 - 14.0;
    let rect = Rect {
        x0: 0.0,
        y0: 0.0,
        x1: width as f64,
        y1: FRAME_STRIP as f64,
    };
    segment(
        &strip,
        (x0, 10.0),
        (x1, 10.0),
        &rect,
        FRAME.stroke_width(4),
        false,
    )?;
    segment(
        &strip,
        (x0, 10.0),
        (x0 + share * (x1 - x0), 10.0),
        &rect,
        PLATE_EDGE.stroke_width(4),
        false,
    )?;
    text(
        &strip,
        &format_time(t0),
        (14, 18),
        12,
        MUTED,
        false,
        HPos::Left,
    )?;
    text(
        &strip,
        &format_time(t1),
        (width as i32 - 14, 18),
        12,
        MUTED,
        false,
        HPos::Right,
    )?;
    let below = format_mm(frame.active_below);
    let below = below.trim_start_matches('+');
    let lines = if frame.scenery.is_empty() {
        vec![format!(
            "orange: corner with b ≤ {below}   red: b < −{}   dashed: drop to the plate below",
            tolerance_text()
        )]
    } else {
        vec![
            format!(
                "orange: point with b ≤ {below}   red: b < −{}   dots: watched points",
                tolerance_text()
            ),
            "dashed: drop to the plate below, or to the obstacle".to_string(),
        ]
    };
    let first_line = if lines.len() == 1 { 36 } else { 29 };
    for (k, line) in lines.iter().enumerate() {
        text(
            &strip,
            line,
            (width as i32 / 2, first_line + 16 * k as i32),
            13,
            TEXT,
            false,
            HPos::Center,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_read_without_trailing_zeros() {
        assert_eq!(format_time(0.16), "0.16 s");
        assert_eq!(format_time(10.0), "10 s");
        assert_eq!(format_time(0.0), "0 s");
        assert_eq!(format_time(-0.0001), "0 s");
        assert_eq!(format_time(2.5004), "2.5 s");
    }

    #[test]
    fn nice_lengths_are_one_two_or_five() {
        assert_eq!(nice_length(0.012), 0.01);
        assert!((nice_length(0.03) - 0.02).abs() < 1e-12);
        assert!((nice_length(0.06) - 0.05).abs() < 1e-12);
        assert_eq!(nice_length(f64::NAN), 0.01);
    }

    #[test]
    fn short_labels_name_kind_module_and_point() {
        let info = |kind, module, point, obstacle, label| BarrierInfo {
            kind,
            module,
            point,
            obstacle,
            label,
            params: &[],
        };
        let cases = [
            (
                info(
                    BarrierKind::PlateCorner,
                    0,
                    Some(Watch::Corner(2)),
                    None,
                    "module 1 corner 3",
                ),
                "m1 c3",
            ),
            (
                info(
                    BarrierKind::ElongationMax,
                    1,
                    None,
                    None,
                    "module 2 elongation max",
                ),
                "m2 δL max",
            ),
            (
                info(
                    BarrierKind::ElongationMin,
                    0,
                    None,
                    None,
                    "module 1 elongation min",
                ),
                "m1 δL min",
            ),
            (
                info(BarrierKind::Bend, 1, None, None, "module 2 bend"),
                "m2 bend",
            ),
            (
                info(
                    BarrierKind::Sphere,
                    1,
                    Some(Watch::Corner(3)),
                    Some(0),
                    "obstacle 1 module 2 corner 4",
                ),
                "o1 m2 c4",
            ),
            (
                info(
                    BarrierKind::HalfSpace,
                    0,
                    Some(Watch::Arc(4)),
                    Some(1),
                    "obstacle 2 module 1 arc 2",
                ),
                "o2 m1 arc 2",
            ),
            (
                info(
                    BarrierKind::HalfSpace,
                    0,
                    Some(Watch::Centre),
                    Some(1),
                    "obstacle 2 module 1 centre",
                ),
                "o2 m1 centre",
            ),
        ];
        for (info, short) in cases {
            assert_eq!(short_label(&info), short);
        }
        let bend = info(BarrierKind::Bend, 0, None, None, "module 1 bend");
        assert_eq!(format_barrier(-0.0923, Some(&bend)), "−0.092 rad");
        assert_eq!(format_barrier(1e-5, Some(&bend)), "0.000 rad");
        assert_eq!(format_barrier(0.0051, None), "+5.10 mm");
    }

    #[test]
    fn millimetres_have_a_sign_except_zero() {
        assert_eq!(format_mm(-0.02773), "−27.73 mm");
        assert_eq!(format_mm(1e-9), "0.00 mm");
        assert_eq!(format_mm(0.0051), "+5.10 mm");
    }
}
