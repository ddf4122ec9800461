//! Drawing one figure on a plotters backend (PNG or SVG): the column titles, the three
//! panels of each column and the legend strip.

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::series::{envelope, tick_decimals};
use super::{COLUMN_WIDTH, FONT, Figure, TITLE_HEIGHT};

/// Line colours (colour-blind-friendly, after Tol's "bright" and "muted" schemes).
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(230, 159, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 51, 17),
    RGBColor(120, 94, 240),
    RGBColor(86, 180, 233),
    RGBColor(136, 34, 85),
    RGBColor(90, 90, 90),
];

fn colour(k: usize) -> RGBColor {
    PALETTE[k % PALETTE.len()]
}

/// Dash pattern `(on, off)` \[px\] of module `module` (0-based): module 1 solid (`None`),
/// module 2 dashed 9/6, further modules with shorter dashes, each different.
fn dash(module: usize) -> Option<(i32, i32)> {
    match module {
        0 => None,
        1 => Some((9, 6)),
        _ => Some(((12 / module as i32).max(1), 4)),
    }
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// `v` with `decimals` decimals, without the sign of a value that rounds to zero.
fn tick_label(v: f64, decimals: usize) -> String {
    let text = format!("{v:.decimals$}");
    match text.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|c| c == b'0' || c == b'.') => rest.to_string(),
        _ => text,
    }
}

/// Draws `points` as a line in the dash pattern of `module`.
fn draw_line<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    points: Vec<(f64, f64)>,
    style: ShapeStyle,
    module: usize,
) -> Result<(), String> {
    let result = match dash(module) {
        None => chart
            .draw_series(LineSeries::new(points, style))
            .map(|_| ()),
        Some((on, off)) => chart
            .draw_series(DashedLineSeries::new(points, on, off, style))
            .map(|_| ()),
    };
    result.map_err(|e| e.to_string())
}

/// Draws the figure on `root`.
pub(super) fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    figure: &Figure,
) -> Result<(), String> {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (titles, body) = root.split_vertically(TITLE_HEIGHT);
    let (charts, legend) = body.split_horizontally(COLUMN_WIDTH * figure.panels.len() as u32);
    let title_cells = titles.split_evenly((1, figure.panels.len()));
    let columns = charts.split_evenly((1, figure.panels.len()));
    let legend_rows = legend.split_evenly((3, 1));
    let captions = [
        "generalized coordinates q",
        "applied generalized force τ",
        "barrier values b",
    ];
    let units = ["q [m]", "τ [N]", "b [m]"];
    let buckets = COLUMN_WIDTH as usize;
    for (c, ((title, record), (cell, column))) in figure
        .panels
        .iter()
        .zip(title_cells.iter().zip(&columns))
        .enumerate()
    {
        let title_style = TextStyle::from((FONT, 24, FontStyle::Bold).into_font())
            .pos(Pos::new(HPos::Center, VPos::Center));
        let (w, h) = cell.dim_in_pixel();
        cell.draw(&Text::new(
            title.to_string(),
            (w as i32 / 2, h as i32 / 2 + 4),
            title_style,
        ))
        .map_err(e)?;
        let times: Vec<f64> = record.times().collect();
        for (r, area) in column.split_evenly((3, 1)).iter().enumerate() {
            let letter = (b'a' + (3 * c + r) as u8) as char;
            let y_range = figure.rows[r].clone();
            let decimals = tick_decimals(y_range.end - y_range.start);
            let x_decimals = tick_decimals(figure.time.end - figure.time.start);
            let y_format = |v: &f64| tick_label(*v, decimals);
            let x_format = |v: &f64| tick_label(*v, x_decimals);
            let mut chart = ChartBuilder::on(area)
                .caption(format!("({letter}) {}", captions[r]), (FONT, 19))
                .margin_left(6)
                .margin_right(14)
                .margin_top(4)
                .margin_bottom(4)
                .x_label_area_size(42)
                .y_label_area_size(70)
                .build_cartesian_2d(figure.time.clone(), y_range)
                .map_err(e)?;
            chart
                .configure_mesh()
                .x_desc("t [s]")
                .y_desc(units[r])
                .x_labels(8)
                .y_labels(6)
                .x_label_formatter(&x_format)
                .y_label_formatter(&y_format)
                .label_style((FONT, 14))
                .axis_desc_style((FONT, 16))
                .bold_line_style(RGBColor(222, 222, 222))
                .light_line_style(RGBColor(244, 244, 244))
                .draw()
                .map_err(e)?;
            let span = (figure.time.start, figure.time.end);
            match r {
                0 | 1 => {
                    for i in 0..record.columns().n() {
                        let values: Vec<f64> = if r == 0 {
                            record.q(i).collect()
                        } else {
                            record.tau(i).collect()
                        };
                        let style = colour(i).stroke_width(2);
                        for segment in envelope(&times, &values, span.0, span.1, buckets) {
                            draw_line(&mut chart, segment, style, 0)?;
                        }
                        if r == 0 && i < figure.set_point.len() {
                            let target = figure.set_point[i];
                            draw_line(
                                &mut chart,
                                vec![(span.0, target), (span.1, target)],
                                style,
                                1,
                            )?;
                        }
                    }
                }
                _ => {
                    chart
                        .draw_series(LineSeries::new(
                            [(span.0, 0.0), (span.1, 0.0)],
                            BLACK.stroke_width(1),
                        ))
                        .map_err(e)?;
                    for j in 0..record.columns().m() {
                        let values: Vec<f64> = record.b(j).collect();
                        let style = colour(figure.barrier_index(j)).stroke_width(2);
                        for segment in envelope(&times, &values, span.0, span.1, buckets) {
                            draw_line(&mut chart, segment, style, figure.barrier_module[j])?;
                        }
                    }
                }
            }
        }
    }
    for (r, area) in legend_rows.iter().enumerate() {
        draw_legend(area, figure, r).map_err(e)?;
    }
    Ok(())
}

/// The legend of row `r` in the strip at the right.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    figure: &Figure,
    r: usize,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let mut entries: Vec<(String, RGBColor, usize)> = Vec::new();
    match r {
        0 | 1 => {
            for (i, label) in figure.labels.iter().enumerate() {
                entries.push((label.clone(), colour(i), 0));
            }
            if r == 0 && !figure.set_point.is_empty() {
                entries.push(("set point".to_string(), RGBColor(90, 90, 90), 1));
            }
        }
        _ => {
            let most = (0..figure.barrier_module.len())
                .map(|j| figure.barrier_index(j) + 1)
                .max()
                .unwrap_or(0);
            for module in 0..figure.modules {
                entries.push((
                    format!("module {}", module + 1),
                    RGBColor(60, 60, 60),
                    module,
                ));
            }
            for k in 0..most {
                entries.push((format!("corner {}", k + 1), colour(k), 0));
            }
            entries.push(("b = 0".to_string(), BLACK, 0));
        }
    }
    let font = (FONT, 16).into_font();
    // Entries 22 px apart, closer if that is needed to fit them all in the row.
    let top = 48;
    let (_, height) = area.dim_in_pixel();
    let room = (height as i32 - top - 8).max(0);
    let line_height = (room / entries.len().max(1) as i32).clamp(8, 22);
    for (k, (label, colour, module)) in entries.into_iter().enumerate() {
        let y = top + line_height * k as i32;
        let points = vec![(8, y), (44, y)];
        let width = if label == "b = 0" { 1 } else { 2 };
        let style = colour.stroke_width(width);
        match dash(module) {
            None => area.draw(&PathElement::new(points, style))?,
            Some((on, off)) => area.draw(&DashedPathElement::new(points, on, off, style))?,
        }
        area.draw(&Text::new(label, (52, y - 9), font.clone()))?;
    }
    Ok(())
}
