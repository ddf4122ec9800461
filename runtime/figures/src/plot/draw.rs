//! Drawing one figure on a plotters backend (PNG or SVG): the column titles, the panels of
//! each column (q, τ, τ − τ_nom, then a row of barriers per kind group; time axis split or
//! not), the labels of the barriers that reach zero, and the legend strip.

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::series::{clip, envelope, tick_decimals, window};
use super::style::{LineStyle, SET_POINT_DASH, barrier_style, coordinate_style, module_dash};
use super::{
    BarrierRow, CAPTION_HEIGHT, COLUMN_WIDTH, COORDINATE_ROWS, FONT, Figure, LABEL_FONT, LABEL_GAP,
    LABEL_LINE, LABEL_SAMPLE, LEGEND_WIDTH, MARGIN_LEFT, MARGIN_RIGHT, PLOT_MARGIN, RowKind,
    SPLIT_SHARE, TITLE_HEIGHT, X_LABEL_HEIGHT, Y_LABEL_WIDTH,
};
use crate::record::Record;

/// Gap between the two parts of a split time axis \[px\].
const SPLIT_GAP: u32 = 12;
/// On the part of a split time axis after the split, no time is labelled closer than this
/// to its start \[px\]: the part before ends with the split's own label (`2.0`), which a
/// `2` just across the gap would run into.
const SPLIT_LABEL_CLEARANCE: f64 = 36.0;
/// Colour of the note that a column's run has invalid states.
const NOTE_COLOUR: RGBColor = RGBColor(204, 30, 30);
/// Shade of the time spans with an invalid state.
const INVALID_SHADE: RGBColor = RGBColor(253, 226, 226);

pub type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;
type Area<DB> = DrawingArea<DB, Shift>;

/// What each row of coordinate panels shows: caption and value-axis label.
const ROW_TEXT: [(&str, &str); COORDINATE_ROWS] = [
    ("generalized coordinates q (set points dotted)", "q [m]"),
    ("applied generalized force τ", "τ [N]"),
    ("filter action τ − τ_nom", "τ − τ_nom [N]"),
];

/// What row `r` of panels shows.
fn row_kind(figure: &Figure, r: usize) -> RowKind {
    figure
        .row_kinds
        .get(r)
        .copied()
        .unwrap_or(RowKind::Coordinates(COORDINATE_ROWS - 1))
}

/// Caption and value-axis label of row `r`.
fn row_text(figure: &Figure, r: usize) -> (String, String) {
    let row = barrier_row(figure, r);
    match (row_kind(figure, r), row) {
        (RowKind::Barriers(_), Some(row)) => row.text(),
        (RowKind::Zoom(_), Some(row)) => row.zoom_text(),
        (RowKind::Coordinates(k), _) => {
            let (caption, axis) = ROW_TEXT[k.min(COORDINATE_ROWS - 1)];
            (caption.to_string(), axis.to_string())
        }
        (_, None) => (String::new(), String::new()),
    }
}

/// The barrier row that row `r` of panels shows (whole or zoomed), if it shows one.
fn barrier_row<'f>(figure: &'f Figure, r: usize) -> Option<&'f BarrierRow> {
    match row_kind(figure, r) {
        RowKind::Barriers(k) | RowKind::Zoom(k) => figure.barrier_rows.get(k),
        RowKind::Coordinates(_) => None,
    }
}

/// Value range of row `r`.
fn row_range(figure: &Figure, r: usize) -> std::ops::Range<f64> {
    let row = barrier_row(figure, r);
    match (row_kind(figure, r), row) {
        (RowKind::Barriers(_), Some(row)) => row.range.clone(),
        (RowKind::Zoom(_), Some(row)) => row.zoom.clone().unwrap_or(row.range.clone()),
        (RowKind::Coordinates(k), _) => figure.rows[k.min(COORDINATE_ROWS - 1)].clone(),
        (_, None) => 0.0..1.0,
    }
}

/// Factor from a row's values to the numbers its value axis prints: 1000 in a zoomed row
/// (mm, mrad), else 1.
fn axis_scale(figure: &Figure, r: usize) -> f64 {
    match row_kind(figure, r) {
        RowKind::Zoom(_) => 1e3,
        _ => 1.0,
    }
}

fn rgb(style: LineStyle) -> RGBColor {
    let (r, g, b) = style.colour;
    RGBColor(r, g, b)
}

/// `v` with `decimals` decimals, without the sign of a value that rounds to zero.
fn tick_label(v: f64, decimals: usize) -> String {
    let text = format!("{v:.decimals$}");
    match text.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|c| c == b'0' || c == b'.') => rest.to_string(),
        _ => text,
    }
}

/// Draws `points` as a line of `style`, `width` pixels wide.
pub fn draw_line<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    points: Vec<(f64, f64)>,
    style: LineStyle,
    width: u32,
) -> Result<(), String> {
    let shape = rgb(style).stroke_width(width);
    let result = match style.dash {
        None => chart
            .draw_series(LineSeries::new(points, shape))
            .map(|_| ()),
        Some((on, off)) => chart
            .draw_series(DashedLineSeries::new(points, on, off, shape))
            .map(|_| ()),
    };
    result.map_err(|e| e.to_string())
}

/// Draws the series `(times, values)` over the chart's time span, thinned to its width and
/// cut at the edges of its value range, so that nothing is drawn outside the panel.
fn draw_series<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    times: &[f64],
    values: &[f64],
    style: LineStyle,
) -> Result<(), String> {
    let span = chart.x_range();
    let range = chart.y_range();
    let (t, y) = window(times, values, span.start, span.end);
    let buckets = chart.plotting_area().dim_in_pixel().0.max(1) as usize;
    for segment in envelope(&t, &y, span.start, span.end, buckets) {
        for part in clip(&segment, range.start, range.end) {
            draw_line(chart, part, style, 2)?;
        }
    }
    Ok(())
}

/// Draws the figure on `root`.
pub(super) fn draw<DB: DrawingBackend>(root: &Area<DB>, figure: &Figure) -> Result<(), String> {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    root.fill(&WHITE).map_err(e)?;
    let columns = figure.panels.len();
    let (titles, body) = root.split_vertically(figure.title_height());
    let (charts, legend) = body.split_horizontally(COLUMN_WIDTH * columns as u32);
    let title_cells = titles.split_evenly((1, columns));
    let column_areas = charts.split_evenly((1, columns));
    for (c, ((title, record), (cell, column))) in figure
        .panels
        .iter()
        .zip(title_cells.iter().zip(&column_areas))
        .enumerate()
    {
        let title_style = TextStyle::from((FONT, 24, FontStyle::Bold).into_font())
            .pos(Pos::new(HPos::Center, VPos::Center));
        let (w, _) = cell.dim_in_pixel();
        cell.draw(&Text::new(
            title.to_string(),
            (w as i32 / 2, TITLE_HEIGHT as i32 / 2 + 4),
            title_style,
        ))
        .map_err(e)?;
        if let Some([first, second]) = figure.invalid.get(c).and_then(|rows| rows.note()) {
            for (k, (line, weight)) in [(first, FontStyle::Bold), (second, FontStyle::Normal)]
                .into_iter()
                .enumerate()
            {
                let style = TextStyle::from((FONT, 14, weight).into_font())
                    .color(&NOTE_COLOUR)
                    .pos(Pos::new(HPos::Center, VPos::Center));
                cell.draw(&Text::new(
                    fit_text(&line, w.saturating_sub(16), 14, weight),
                    (w as i32 / 2, TITLE_HEIGHT as i32 + 17 * k as i32 + 2),
                    style,
                ))
                .map_err(e)?;
            }
        }
        let times: Vec<f64> = record.times().collect();
        let rows = figure.row_count();
        for (r, area) in column.split_evenly((rows, 1)).iter().enumerate() {
            draw_panel(root, area, figure, c, r, record, &times)?;
        }
    }
    let (_, height) = legend.dim_in_pixel();
    let row_height = height / figure.row_count() as u32;
    let (upper, lower) = legend.split_vertically(row_height * COORDINATE_ROWS as u32);
    draw_coordinate_legend(&upper, figure).map_err(e)?;
    // Each barrier row's legend beside it and its zoomed row.
    let mut top = 0;
    for row in &figure.barrier_rows {
        let rows = if row.zoom.is_some() { 2 } else { 1 };
        let block = lower
            .clone()
            .shrink((0, top), (LEGEND_WIDTH, row_height * rows));
        draw_barrier_legend(&block, row).map_err(e)?;
        top += row_height * rows;
    }
    Ok(())
}

/// `text` cut to fit `width` pixels in the figures' font of `size` and `weight` (with an
/// ellipsis).
fn fit_text(text: &str, width: u32, size: u32, weight: FontStyle) -> String {
    let font = (FONT, size, weight).into_font();
    let fits = |t: &str| font.box_size(t).map_or(true, |(w, _)| w <= width);
    if fits(text) {
        return text.to_string();
    }
    let chars: Vec<char> = text.chars().collect();
    for end in (0..chars.len()).rev() {
        let cut: String = chars[..end].iter().collect::<String>() + "…";
        if fits(&cut) {
            return cut;
        }
    }
    String::new()
}

/// Builds one chart of a panel over the times `span` with the panel's value range; the
/// first part of a panel carries the value labels.
fn build_chart<'a, DB: DrawingBackend>(
    area: &'a Area<DB>,
    figure: &Figure,
    r: usize,
    span: std::ops::Range<f64>,
    first: bool,
) -> Result<Chart<'a, DB>, String> {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    let y_range = row_range(figure, r);
    // About one time label per 80 px.
    let x_labels = (area.dim_in_pixel().0 / 80).clamp(2, 10) as usize;
    let y_labels = 6;
    let x_decimals = tick_decimals(span.end - span.start, x_labels);
    let scale = axis_scale(figure, r);
    let y_decimals = tick_decimals(scale * (y_range.end - y_range.start), y_labels - 1);
    // After a split, no label right at the start: the part before ends with it.
    let width = area.dim_in_pixel().0.max(1) as f64;
    let clearance = if first {
        0.0
    } else {
        SPLIT_LABEL_CLEARANCE * (span.end - span.start) / width
    };
    let start = span.start;
    let mut builder = ChartBuilder::on(area);
    builder
        .margin_top(PLOT_MARGIN)
        .margin_bottom(PLOT_MARGIN)
        .x_label_area_size(X_LABEL_HEIGHT);
    if first {
        builder
            .margin_left(MARGIN_LEFT)
            .y_label_area_size(Y_LABEL_WIDTH);
    } else {
        builder.margin_left(SPLIT_GAP);
    }
    let last = !first || figure.split.is_none();
    builder.margin_right(if last { MARGIN_RIGHT } else { 0 });
    let mut chart = builder
        .build_cartesian_2d(span.clone(), y_range)
        .map_err(e)?;
    let x_format = |v: &f64| {
        if *v < start + clearance {
            String::new()
        } else {
            tick_label(*v, x_decimals)
        }
    };
    let y_format = |v: &f64| tick_label(scale * *v, y_decimals);
    let mut mesh = chart.configure_mesh();
    mesh.x_labels(x_labels)
        .y_labels(y_labels)
        .x_label_formatter(&x_format)
        .y_label_formatter(&y_format)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .bold_line_style(RGBColor(222, 222, 222))
        .light_line_style(RGBColor(244, 244, 244));
    let (_, axis) = row_text(figure, r);
    if first {
        mesh.y_desc(axis);
    }
    mesh.draw().map_err(e)?;
    Ok(chart)
}

/// Draws panel `r` of column `c` (record `record`, times `times`) into `area`.
fn draw_panel<DB: DrawingBackend>(
    root: &Area<DB>,
    area: &Area<DB>,
    figure: &Figure,
    c: usize,
    r: usize,
    record: &Record,
    times: &[f64],
) -> Result<(), String> {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    let (caption, plot) = area.split_vertically(CAPTION_HEIGHT);
    let letter = (b'a' + ((figure.row_count() * c + r) % 26) as u8) as char;
    let (w, h) = caption.dim_in_pixel();
    let (text, _) = row_text(figure, r);
    caption
        .draw(&Text::new(
            format!("({letter}) {text}"),
            (w as i32 / 2, h as i32 / 2 + 2),
            TextStyle::from((FONT, 18).into_font()).pos(Pos::new(HPos::Center, VPos::Center)),
        ))
        .map_err(e)?;
    let (start, end) = figure.window;
    let (width, height) = plot.dim_in_pixel();
    let mut charts = Vec::with_capacity(2);
    match figure.split {
        Some(at) => {
            let inner =
                width.saturating_sub(Y_LABEL_WIDTH + MARGIN_LEFT + MARGIN_RIGHT + SPLIT_GAP);
            let left_width = Y_LABEL_WIDTH + MARGIN_LEFT + (inner as f64 * SPLIT_SHARE) as u32;
            let (left, right) = plot.split_horizontally(left_width);
            // The areas must outlive the charts built on them: keep them in a Vec first.
            charts.push((left, start..at, true));
            charts.push((right, at..end, false));
        }
        None => charts.push((plot.clone(), start..end, true)),
    }
    let mut built = Vec::with_capacity(charts.len());
    for (area, span, first) in &charts {
        built.push(build_chart(area, figure, r, span.clone(), *first)?);
    }
    for chart in &mut built {
        shade_invalid(chart, figure, c)?;
        draw_data(chart, figure, r, record, times)?;
    }
    // The time axis's name, once under the middle of the plot.
    let middle =
        Y_LABEL_WIDTH + MARGIN_LEFT + (width.saturating_sub(Y_LABEL_WIDTH + MARGIN_LEFT)) / 2;
    plot.draw(&Text::new(
        "t [s]",
        (middle as i32, height as i32 - 12),
        TextStyle::from((FONT, 16).into_font()).pos(Pos::new(HPos::Center, VPos::Center)),
    ))
    .map_err(e)?;
    if let [left, right] = &built[..] {
        draw_break(root, left, right).map_err(e)?;
    }
    if let (RowKind::Barriers(_), Some(row)) = (row_kind(figure, r), barrier_row(figure, r))
        && let (Some(first), Some(last)) = (built.first(), built.last())
    {
        draw_active_labels(root, first, last, figure, row, c).map_err(e)?;
    }
    Ok(())
}

/// Shades the time spans where column `c`'s run had an invalid state (light red, across
/// the panel), so that values drawn there are not read as the robot's.
fn shade_invalid<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    figure: &Figure,
    c: usize,
) -> Result<(), String> {
    let Some(rows) = figure.invalid.get(c) else {
        return Ok(());
    };
    let (span, range) = (chart.x_range(), chart.y_range());
    // At least a pixel wide: a single invalid row is a span of no length.
    let pixel = (span.end - span.start) / chart.plotting_area().dim_in_pixel().0.max(1) as f64;
    for &(start, end) in &rows.spans {
        let (start, end) = (
            start.max(span.start),
            (end.max(start + pixel)).min(span.end),
        );
        if start >= end {
            continue;
        }
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(start, range.start), (end, range.end)],
                INVALID_SHADE.filled(),
            )))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Draws the lines of row `r` on `chart`.
fn draw_data<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    figure: &Figure,
    r: usize,
    record: &Record,
    times: &[f64],
) -> Result<(), String> {
    let span = chart.x_range();
    let n = record.columns().n();
    let row = barrier_row(figure, r);
    if r == 2 || row.is_some() {
        let zero = if row.is_some() {
            BLACK.stroke_width(1)
        } else {
            RGBColor(120, 120, 120).stroke_width(1)
        };
        chart
            .draw_series(LineSeries::new([(span.start, 0.0), (span.end, 0.0)], zero))
            .map_err(|e| e.to_string())?;
    }
    match row {
        None => {
            for i in 0..n {
                let values: Vec<f64> = match r {
                    0 => record.q(i).collect(),
                    1 => record.tau(i).collect(),
                    _ => record
                        .tau(i)
                        .zip(record.tau_nom(i))
                        .map(|(a, b)| a - b)
                        .collect(),
                };
                let style = coordinate_style(i);
                draw_series(chart, times, &values, style)?;
                if r == 0
                    && let Some(&target) = figure.set_point.get(i)
                {
                    let dotted = LineStyle {
                        dash: Some(SET_POINT_DASH),
                        ..style
                    };
                    draw_line(
                        chart,
                        vec![(span.start, target), (span.end, target)],
                        dotted,
                        2,
                    )?;
                }
            }
        }
        Some(row) => {
            for &j in &row.barriers {
                let values: Vec<f64> = record.b(j).collect();
                draw_series(chart, times, &values, figure.barrier_styles[j])?;
            }
        }
    }
    Ok(())
}

/// Two slanted strokes on the time axis between the parts of a split axis.
fn draw_break<DB: DrawingBackend>(
    root: &Area<DB>,
    left: &Chart<DB>,
    right: &Chart<DB>,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (left_x, left_y) = left.plotting_area().get_pixel_range();
    let (right_x, _) = right.plotting_area().get_pixel_range();
    let style = BLACK.stroke_width(1);
    for y in [left_y.start, left_y.end - 1] {
        for x in [left_x.end, right_x.start] {
            root.draw(&PathElement::new(
                vec![(x - 4, y + 6), (x + 4, y - 6)],
                style,
            ))?;
        }
    }
    Ok(())
}

/// The labels of column `c`'s barriers of `row` that reach zero, each with a sample of its line:
/// a block right-aligned in the panel (from `first` part to `last`) just below the lowest
/// value of these barriers, hence below every line, on a white ground.
fn draw_active_labels<DB: DrawingBackend>(
    root: &Area<DB>,
    first: &Chart<DB>,
    last: &Chart<DB>,
    figure: &Figure,
    row: &BarrierRow,
    c: usize,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let Some(active) = row.active.get(c) else {
        return Ok(());
    };
    let Some(lowest) = active.iter().map(|a| a.low).reduce(f64::min) else {
        return Ok(());
    };
    let labels = figure.panels[c].1.columns().barrier_labels();
    let (left_x, _) = first.plotting_area().get_pixel_range();
    let (right_x, y_range) = last.plotting_area().get_pixel_range();
    let (_, top) = first.backend_coord(&(first.x_range().start, lowest));
    let font =
        TextStyle::from((FONT, LABEL_FONT).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    let grid = row.grid;
    let line = LABEL_LINE as i32;
    let columns = grid.columns.min(active.len()).max(1);
    let block_left = (right_x.end - 4 - columns as i32 * grid.cell as i32).max(left_x.start);
    let block_top =
        (top + LABEL_GAP as i32).min(y_range.end - line * grid.rows(active.len()) as i32);
    root.draw(&Rectangle::new(
        [
            (block_left, block_top),
            (
                right_x.end - 2,
                block_top + line * grid.rows(active.len()) as i32,
            ),
        ],
        WHITE.mix(0.85).filled(),
    ))?;
    for (k, a) in active.iter().enumerate() {
        let x = block_left + (k % columns) as i32 * grid.cell as i32 + 4;
        let y = block_top + line / 2 + line * (k / columns) as i32;
        let style = figure.barrier_styles[a.barrier];
        let shape = rgb(style).stroke_width(2);
        let points = vec![(x, y), (x + LABEL_SAMPLE as i32 - 8, y)];
        match style.dash {
            None => root.draw(&PathElement::new(points, shape))?,
            Some((on, off)) => root.draw(&DashedPathElement::new(points, on, off, shape))?,
        }
        let text = labels.get(a.barrier).cloned().unwrap_or_default();
        root.draw(&Text::new(text, (x + LABEL_SAMPLE as i32, y), font.clone()))?;
    }
    Ok(())
}

/// One legend entry: name, colour and dash, line width.
type Entry = (String, RGBColor, Option<(u32, u32)>, u32);

/// Draws `entries` one under another from the top of `area`.
fn draw_entries<DB: DrawingBackend>(
    area: &Area<DB>,
    title: &str,
    entries: Vec<Entry>,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let top = 48;
    area.draw(&Text::new(
        title.to_string(),
        (8, top - 30),
        (FONT, 15, FontStyle::Bold).into_font(),
    ))?;
    // Entries 22 px apart, closer if that is needed to fit them all.
    let (_, height) = area.dim_in_pixel();
    let room = (height as i32 - top - 8).max(0);
    let line_height = (room / entries.len().max(1) as i32).clamp(8, 22);
    // Names too long for the strip are all drawn smaller (down to 11 px) to fit.
    let fits = |size: u32| {
        let font = (FONT, size).into_font();
        entries.iter().all(|(label, ..)| {
            font.box_size(label)
                .map_or(true, |(w, _)| w + 52 + 4 <= LEGEND_WIDTH)
        })
    };
    let size = (11..=16).rev().find(|&size| fits(size)).unwrap_or(11);
    let shift = (16 - size as i32) / 2;
    for (k, (label, colour, dash, width)) in entries.into_iter().enumerate() {
        let y = top + line_height * k as i32;
        let points = vec![(8, y), (44, y)];
        let style = colour.stroke_width(width);
        match dash {
            None => area.draw(&PathElement::new(points, style))?,
            Some((on, off)) => area.draw(&DashedPathElement::new(points, on, off, style))?,
        }
        area.draw(&Text::new(
            label,
            (52, y - 9 + shift),
            (FONT, size).into_font(),
        ))?;
    }
    Ok(())
}

/// The legend of the coordinates (rows a–c), with the set point.
fn draw_coordinate_legend<DB: DrawingBackend>(
    area: &Area<DB>,
    figure: &Figure,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let mut entries: Vec<Entry> = figure
        .labels
        .iter()
        .enumerate()
        .map(|(i, label)| {
            let style = coordinate_style(i);
            (label.clone(), rgb(style), style.dash, 2)
        })
        .collect();
    if !figure.set_point.is_empty() {
        entries.push((
            "set point".to_string(),
            RGBColor(90, 90, 90),
            Some(SET_POINT_DASH),
            2,
        ));
    }
    draw_entries(area, "coordinates", entries)
}

/// The legend of a row of barriers: the dash of each module, the colour of each barrier
/// within a module, the zero line.
fn draw_barrier_legend<DB: DrawingBackend>(
    area: &Area<DB>,
    row: &BarrierRow,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let mut entries: Vec<Entry> = Vec::new();
    if row.modules.len() > 1 || row.modules.iter().any(|&module| module > 0) {
        for &module in &row.modules {
            entries.push((
                format!("module {}", module + 1),
                RGBColor(60, 60, 60),
                module_dash(module),
                2,
            ));
        }
    }
    for (k, name) in row.key_names.iter().enumerate() {
        entries.push((name.clone(), rgb(barrier_style(0, k)), None, 2));
    }
    entries.push(("b = 0".to_string(), BLACK, None, 1));
    draw_entries(area, row.legend_title(), entries)
}
