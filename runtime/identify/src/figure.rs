//! The figure of `softcbf identify`: measured `q` of a held-out part against the plant's
//! prediction with the identified numbers and with the file's, one panel per coordinate
//! (a row per module), as PNG and SVG in the style of the run figures.

use std::path::{Path, PathBuf};

use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use softcbf_description::robot::Robot;

use crate::plot::draw::draw_line;
use crate::plot::{LineStyle, PALETTE, display_name};
use crate::record::coordinate_names;

use super::holdout::Prediction;
use super::output::short;

/// Font family (the run figures' embedded DejaVu Sans, registered under this name).
const FONT: &str = "sans-serif";
/// Width of the figure \[px\].
const WIDTH: u32 = 1500;
/// Height of the title and legend band \[px\].
const HEADER: u32 = 84;
/// Height of one module's row of panels \[px\].
const ROW: u32 = 300;

/// The styles of measured, identified and file curves: colour, dash.
const MEASURED: LineStyle = LineStyle {
    colour: (0, 0, 0),
    dash: None,
};

fn plant_style(k: usize) -> LineStyle {
    LineStyle {
        colour: PALETTE[if k == 0 { 0 } else { 3 }],
        dash: if k == 0 { None } else { Some((8, 5)) },
    }
}

/// Draws `<stem>.png` and `<stem>.svg` of `prediction` into `dir` (created if missing).
pub fn draw(
    dir: &Path,
    stem: &str,
    prediction: &Prediction,
    robot: &Robot,
) -> Result<Vec<PathBuf>, String> {
    crate::plot::register_fonts().map_err(|e| e.to_string())?;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let modules = prediction.nq.div_ceil(3).max(1);
    let size = (WIDTH, HEADER + ROW * modules as u32);
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    let mut pixels = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        draw_on(&root, prediction, robot).map_err(|e| format!("{}: {e}", png.display()))?;
        root.present()
            .map_err(|e| format!("{}: {e}", png.display()))?;
    }
    crate::plot::write_png(&png, &pixels, size).map_err(|e| format!("{}: {e}", png.display()))?;
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw_on(&root, prediction, robot).map_err(|e| format!("{}: {e}", svg.display()))?;
        root.present()
            .map_err(|e| format!("{}: {e}", svg.display()))?;
    }
    Ok(vec![png, svg])
}

fn draw_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    p: &Prediction,
    robot: &Robot,
) -> Result<(), String> {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (header, body) = root.split_vertically(HEADER);
    let title = format!(
        "{}: held-out part of log {} predicted from its measured start",
        robot.name, p.log
    );
    header
        .draw(&Text::new(
            title,
            (WIDTH as i32 / 2, 22),
            TextStyle::from((FONT, 22, FontStyle::Bold).into_font())
                .pos(Pos::new(HPos::Center, VPos::Center)),
        ))
        .map_err(e)?;
    let labels = [
        ("measured".to_string(), MEASURED),
        (
            format!(
                "identified numbers (RMS error {} mm)",
                short(1e3 * p.rms[0])
            ),
            plant_style(0),
        ),
        (
            format!("file's numbers (RMS error {} mm)", short(1e3 * p.rms[1])),
            plant_style(1),
        ),
    ];
    let mut x = 150;
    for (label, style) in &labels {
        let y = 60;
        let (r, g, b) = style.colour;
        let shape = RGBColor(r, g, b).stroke_width(3);
        match &style.dash {
            None => header
                .draw(&PathElement::new(vec![(x, y), (x + 40, y)], shape))
                .map_err(e)?,
            Some((on, off)) => header
                .draw(&DashedPathElement::new(
                    vec![(x, y), (x + 40, y)],
                    *on,
                    *off,
                    shape,
                ))
                .map_err(e)?,
        }
        header
            .draw(&Text::new(
                label.clone(),
                (x + 50, y),
                TextStyle::from((FONT, 17).into_font()).pos(Pos::new(HPos::Left, VPos::Center)),
            ))
            .map_err(e)?;
        x += 430;
    }
    let names = coordinate_names(p.nq);
    let rows = p.nq.div_ceil(3).max(1);
    let areas = body.split_evenly((rows, 3));
    let n = p.t.len();
    let (t0, t1) = (p.t[0], p.t[n - 1].max(p.t[0] + 1e-3));
    for (r, area) in areas.iter().enumerate().take(p.nq) {
        let series = |values: &[f64]| -> Vec<(f64, f64)> {
            (0..n)
                .filter(|&j| values[j * p.nq + r].is_finite())
                .map(|j| (p.t[j], 1e3 * values[j * p.nq + r]))
                .collect()
        };
        let measured = series(&p.measured);
        let predicted: Vec<Vec<(f64, f64)>> = p.predicted.iter().map(|v| series(v)).collect();
        let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
        for (_, y) in measured.iter().chain(predicted.iter().flatten()) {
            low = low.min(*y);
            high = high.max(*y);
        }
        if !(low.is_finite() && high.is_finite()) {
            (low, high) = (-1.0, 1.0);
        }
        let pad = ((high - low) * 0.08).max(0.05);
        let rms: Vec<String> = p
            .predicted
            .iter()
            .map(|values| {
                let (mut sum, mut count) = (0.0, 0usize);
                for j in 0..n {
                    let e = values[j * p.nq + r] - p.measured[j * p.nq + r];
                    if e.is_finite() {
                        sum += e * e;
                        count += 1;
                    }
                }
                short(1e3 * (sum / count.max(1) as f64).sqrt())
            })
            .collect();
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!(
                    "{} [mm]   (RMS error {} | {} mm)",
                    display_name(&names[r]),
                    rms.first().map_or("", String::as_str),
                    rms.get(1).map_or("", String::as_str)
                ),
                (FONT, 17),
            )
            .margin(10)
            .x_label_area_size(38)
            .y_label_area_size(60)
            .build_cartesian_2d(t0..t1, (low - pad)..(high + pad))
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_labels(6)
            .y_labels(6)
            .x_desc("t [s]")
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 15))
            .bold_line_style(RGBColor(222, 222, 222))
            .light_line_style(RGBColor(244, 244, 244))
            .draw()
            .map_err(e)?;
        // The file's prediction below, the identified one, the measurement on top (thin,
        // so that a prediction on it still shows).
        for (k, points) in predicted.into_iter().enumerate().rev() {
            draw_line(&mut chart, points, plant_style(k), 3)?;
        }
        draw_line(&mut chart, measured, MEASURED, 1)?;
    }
    Ok(())
}
