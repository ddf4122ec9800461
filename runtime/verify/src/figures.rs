//! Figures of `softcbf verify`: how low the barriers went over thousands of runs, per group
//! of safety mode and control period, as PNG and SVG.
//!
//! - `lowest_barrier.png`/`.svg`: the distribution of each run's lowest barrier, one
//!   histogram per group (semi-transparent bars under a step outline, the group's colour
//!   of [`PALETTE`]), the unsafe side of the threshold shaded, the legend counting the
//!   runs below the threshold.
//! - `lowest_vs_set_point.png`/`.svg`: each run's lowest barrier against the lowest barrier
//!   at its set point (negative: the set point lies outside the safe set and the filter
//!   must stop short of it), one small dot per run, drawn group by group.
//!
//! The lowest barriers span many orders of magnitude (tens of millimetres down to the
//! solver's tolerance, most of them within a micrometre of zero), so they are drawn on a
//! symmetric logarithmic axis `u = sign(b)·log10(1 + |b|/b₀)` with `b₀` =
//! [`LINEAR_WIDTH_MM`]: linear within about `±b₀` (which keeps the sign of the bulk
//! near zero visible), logarithmic beyond (which keeps the tails visible). Its ticks are
//! labelled in millimetres. The histogram's counts use the same scale with `b₀` = one run,
//! so that a bin with a single run still shows next to one with thousands.
//!
//! Text is drawn with the DejaVu Sans embedded in the binary ([`crate::plot`]), so the
//! figures come out the same on any machine.

use std::ops::Range;
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::RunRow;
use crate::plot::{PALETTE, PlotError, register_fonts, write_png};

/// Font family the figures use (the embedded DejaVu Sans, registered by
/// [`register_fonts`]).
const FONT: &str = "sans-serif";
/// Width of a figure \[px\].
const WIDTH: u32 = 1200;
/// Height of the title band \[px\].
const TITLE_HEIGHT: u32 = 48;
/// Height of the chart (plot, its tick labels and axis names) \[px\].
const CHART_HEIGHT: u32 = 680;
/// Line height of the legend \[px\].
const LEGEND_LINE: u32 = 22;
/// Room above and below the legend's lines \[px\].
const LEGEND_PAD: u32 = 12;
/// Width of the value labels left of the plot and height of those below it \[px\].
const Y_LABEL_WIDTH: u32 = 84;
const X_LABEL_HEIGHT: u32 = 58;
/// Margins around the chart \[px\].
const MARGIN_LEFT: u32 = 10;
const MARGIN_RIGHT: u32 = 28;
const MARGIN_TOP: u32 = 10;
const MARGIN_BOTTOM: u32 = 6;
/// Font sizes of the tick labels, the axis names, the in-plot notes and the legend \[px\].
const TICK_FONT: u32 = 14;
const AXIS_FONT: u32 = 16;
const NOTE_FONT: u32 = 14;
const LEGEND_FONT: u32 = 15;
/// Least distance between two labelled ticks of a logarithmic axis \[px\]: along x (labels
/// side by side) and along y (labels one above the other).
const X_TICK_GAP: f64 = 52.0;
const Y_TICK_GAP: f64 = 28.0;
/// Least width of a decade for its minor grid lines (2…9 × 10ᵏ) to be drawn \[px\].
const MINOR_DECADE: f64 = 40.0;

/// Half-width of the nearly linear part of the symmetric logarithmic barrier axis \[mm\].
pub const LINEAR_WIDTH_MM: f64 = 1e-3;
/// Width of a histogram bin on that axis, in decades (about a tenth of a decade; adjusted
/// so that the threshold falls on a bin edge, as zero does).
pub const BIN_DECADES: f64 = 0.1;
/// Colour of the unsafe region's shading and of the threshold line.
const UNSAFE: RGBColor = RGBColor(204, 51, 17);

type Area<DB> = DrawingArea<DB, Shift>;
type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<Axis, Axis>>;

/// The symmetric logarithm of `v` with linear width `x0`: `sign(v)·log10(1 + |v|/x0)`.
fn symlog(v: f64, x0: f64) -> f64 {
    v.signum() * (v.abs() / x0).ln_1p() / std::f64::consts::LN_10
}

/// The inverse of [`symlog`].
fn symexp(u: f64, x0: f64) -> f64 {
    u.signum() * x0 * (u.abs() * std::f64::consts::LN_10).exp_m1()
}

/// How an axis maps its values to pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Scale {
    /// Proportionally.
    Linear,
    /// By [`symlog`] with this linear width.
    SymLog(f64),
}

/// One axis of a chart: its range (in data units), scale and, for a logarithmic scale, the
/// labelled ticks and the minor grid lines.
#[derive(Clone, Debug)]
struct Axis {
    range: Range<f64>,
    scale: Scale,
    ticks: Vec<f64>,
    minor: Vec<f64>,
    /// The value standing for `-∞` (its tick is labelled so), if any.
    infinity: Option<f64>,
}

impl Axis {
    /// A linear axis over `range` (not empty), ticks chosen by plotters.
    fn linear(range: Range<f64>) -> Axis {
        Axis {
            range,
            scale: Scale::Linear,
            ticks: Vec::new(),
            minor: Vec::new(),
            infinity: None,
        }
    }

    /// A symmetric logarithmic axis over `range` (not empty) with linear width `x0`,
    /// about `pixels` long: ticks at 0 and at ±x0·10ᵏ, as many as fit `gap` pixels apart
    /// (zero first, then the largest magnitudes).
    fn symlog(range: Range<f64>, x0: f64, pixels: f64, gap: f64) -> Axis {
        let (a, b) = (symlog(range.start, x0), symlog(range.end, x0));
        let per_decade = pixels / (b - a).max(f64::MIN_POSITIVE);
        let largest = range.start.abs().max(range.end.abs());
        let inside = |v: f64| {
            let u = symlog(v, x0);
            u >= a - 1e-9 && u <= b + 1e-9
        };
        let mut decades = Vec::new();
        for k in 0..400 {
            let decade = x0 * 10f64.powi(k);
            if !decade.is_finite() || decade > largest * (1.0 + 1e-9) {
                break;
            }
            decades.push(decade);
        }
        let mut candidates = vec![0.0];
        for &decade in decades.iter().rev() {
            candidates.extend([decade, -decade]);
        }
        let mut ticks: Vec<f64> = Vec::new();
        for v in candidates {
            let u = symlog(v, x0);
            if inside(v)
                && ticks
                    .iter()
                    .all(|&t| (symlog(t, x0) - u).abs() * per_decade >= gap)
            {
                ticks.push(v);
            }
        }
        ticks.sort_by(f64::total_cmp);
        let mut minor = Vec::new();
        if per_decade >= MINOR_DECADE {
            for &decade in &decades {
                for m in 2..10 {
                    let v = decade * f64::from(m);
                    minor.extend([v, -v].into_iter().filter(|&v| inside(v)));
                }
            }
        }
        Axis {
            range,
            scale: Scale::SymLog(x0),
            ticks,
            minor,
            infinity: None,
        }
    }

    /// Position of `v` on the axis's scale.
    fn to_scale(&self, v: f64) -> f64 {
        match self.scale {
            Scale::Linear => v,
            Scale::SymLog(x0) => symlog(v, x0),
        }
    }

    /// The label of tick `v`.
    fn label(&self, v: f64) -> String {
        if self.infinity == Some(v) {
            return "−∞".to_string();
        }
        match self.scale {
            Scale::SymLog(_) => decade_label(v),
            Scale::Linear => {
                let span = self.range.end - self.range.start;
                let step = span / 10.0;
                let decimals = if step.is_finite() && step > 0.0 {
                    (-step.log10().floor()).clamp(0.0, 9.0) as usize
                } else {
                    2
                };
                signed(&format!("{v:.decimals$}"))
            }
        }
    }
}

impl Ranged for Axis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let (a, b) = (
            self.to_scale(self.range.start),
            self.to_scale(self.range.end),
        );
        let t = (self.to_scale(*value) - a) / (b - a);
        let pixel = f64::from(limit.0) + t * f64::from(limit.1 - limit.0);
        // Far outside the plot (clipped anyway), or not a number: kept within i32.
        pixel.clamp(-1e7, 1e7).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        match self.scale {
            Scale::Linear => RangedCoordf64::from(self.range.clone()).key_points(hint),
            Scale::SymLog(_) if hint.weight().allow_light_points() => self.minor.clone(),
            Scale::SymLog(_) => self.ticks.clone(),
        }
    }

    fn range(&self) -> Range<f64> {
        self.range.clone()
    }
}

/// `text` with a true minus sign, and without the sign of a value that rounds to zero.
fn signed(text: &str) -> String {
    match text.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|c| c == b'0' || c == b'.') => rest.to_string(),
        Some(rest) => format!("−{rest}"),
        None => text.to_string(),
    }
}

/// The label of a tick at a power of ten (or zero): as many decimals as it needs.
fn decade_label(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return "0".to_string();
    }
    let decimals = (-v.abs().log10().round()).clamp(0.0, 12.0) as usize;
    signed(&format!("{v:.decimals$}"))
}

/// The threshold as the legend and the notes print it, in metres (`−1e-6 m`).
fn threshold_text(threshold: f64) -> String {
    if threshold == 0.0 {
        "0 m".to_string()
    } else if threshold.is_finite() {
        format!("{} m", signed(&format!("{threshold:e}")))
    } else {
        format!("{threshold} m")
    }
}

/// Colour of group `g`.
fn colour(g: usize) -> RGBColor {
    let (r, g, b) = PALETTE[g % PALETTE.len()];
    RGBColor(r, g, b)
}

/// How a legend entry's sample looks.
#[derive(Clone, Copy, Debug)]
enum Marker {
    /// A bar with its outline (histogram).
    Bar,
    /// A dot (scatter).
    Dot,
    /// A line (curve).
    Line,
}

/// One line of a legend: its colour, its sample and its text.
struct Entry {
    colour: RGBColor,
    marker: Marker,
    text: String,
}

/// What each group holds: its name, runs, runs below the threshold, and runs not drawn
/// because a value is not finite.
struct GroupCount {
    name: String,
    runs: usize,
    below: usize,
    non_finite: usize,
}

impl GroupCount {
    /// Legend text: `name: unsafe / runs below −1e-6 m[, k off the axis]` (unsafe: below
    /// the threshold, an invalid state, relaxed rows or stopped early).
    fn text(&self, threshold: &str) -> String {
        let mut text = format!(
            "{}: {} / {} unsafe (< {threshold})",
            self.name, self.below, self.runs
        );
        if self.runs == 0 {
            text.push_str(" (no runs)");
        }
        if self.non_finite > 0 {
            text.push_str(&format!(", {} invalid, not drawn", self.non_finite));
        }
        text
    }
}

/// The groups of `rows`: at least `groups.len()`, more if a row names a later group;
/// `skip(row)` says whether a row is not drawn (a value not finite).
fn count_groups(
    rows: &[RunRow],
    groups: &[String],
    threshold: f64,
    skip: impl Fn(&RunRow) -> bool,
) -> Vec<GroupCount> {
    let count = rows
        .iter()
        .map(|row| row.draw.group + 1)
        .max()
        .unwrap_or(0)
        .max(groups.len());
    let mut counts: Vec<GroupCount> = (0..count)
        .map(|g| GroupCount {
            name: groups
                .get(g)
                .cloned()
                .unwrap_or_else(|| format!("group {g}")),
            runs: 0,
            below: 0,
            non_finite: 0,
        })
        .collect();
    for row in rows {
        let group = &mut counts[row.draw.group];
        group.runs += 1;
        group.below += usize::from(crate::report::is_unsafe(row, threshold));
        group.non_finite += usize::from(skip(row));
    }
    counts
}

/// `"N runs"`, or `"1 run"`.
fn runs_text(n: usize) -> String {
    if n == 1 {
        "1 run".to_string()
    } else {
        format!("{n} runs")
    }
}

/// The distribution of the lowest barriers.
struct Histogram {
    title: String,
    x: Axis,
    y: Axis,
    /// The threshold \[mm\], if finite, and its text.
    threshold: Option<f64>,
    threshold_text: String,
    /// Width of a bin on the symmetric logarithmic scale.
    bin: f64,
    /// Per group: the index of its first bin (bin `k` spans `[k, k + 1)·bin` on the
    /// scale) and the counts of its bins from there to its last non-empty one.
    counts: Vec<(i64, Vec<usize>)>,
    legend: Vec<Entry>,
}

/// Each run's lowest barrier against its set point's.
struct Scatter {
    title: String,
    x: Axis,
    y: Axis,
    threshold: Option<f64>,
    threshold_text: String,
    /// Per group: its points \[mm\].
    points: Vec<Vec<(f64, f64)>>,
    legend: Vec<Entry>,
}

/// A search's progress: the lowest barrier found so far against the runs spent.
struct Progress {
    title: String,
    x: Axis,
    y: Axis,
    threshold: Option<f64>,
    threshold_text: String,
    /// Per group: the steps of its lowest barrier so far, `(runs spent, mm)`; a run that
    /// left the model's domain is drawn at `floor`.
    curves: Vec<Vec<(f64, f64)>>,
    /// Where `-∞` is drawn \[mm\], if any run reached it.
    floor: Option<f64>,
    legend: Vec<Entry>,
}

/// One figure, ready to draw on any backend.
enum Figure {
    Histogram(Histogram),
    Scatter(Scatter),
    Progress(Progress),
}

/// Rows of the legend, and whether it is laid out in two columns.
fn legend_layout(entries: usize) -> (u32, u32) {
    let columns = if entries > 3 { 2 } else { 1 };
    (entries.div_ceil(columns) as u32, columns as u32)
}

/// Approximate length of the plot inside a chart area \[px\]: `(width, height)`.
fn plot_pixels() -> (f64, f64) {
    (
        f64::from(WIDTH - MARGIN_LEFT - MARGIN_RIGHT - Y_LABEL_WIDTH),
        f64::from(CHART_HEIGHT - MARGIN_TOP - MARGIN_BOTTOM - X_LABEL_HEIGHT),
    )
}

/// A range that covers `lo..hi` with room around (4 % of its span each side), at least
/// `least` wide.
fn padded(lo: f64, hi: f64, least: f64) -> Range<f64> {
    let span = hi - lo;
    let pad = (0.04 * span).max(0.5 * (least - span)).max(0.0);
    (lo - pad)..(hi + pad)
}

impl Figure {
    fn legend(&self) -> &[Entry] {
        match self {
            Figure::Histogram(h) => &h.legend,
            Figure::Scatter(s) => &s.legend,
            Figure::Progress(p) => &p.legend,
        }
    }

    fn title(&self) -> &str {
        match self {
            Figure::Histogram(h) => &h.title,
            Figure::Scatter(s) => &s.title,
            Figure::Progress(p) => &p.title,
        }
    }

    /// Height of the legend band \[px\].
    fn legend_height(&self) -> u32 {
        let (rows, _) = legend_layout(self.legend().len());
        rows * LEGEND_LINE + 2 * LEGEND_PAD
    }

    /// Size of the figure \[px\].
    fn size(&self) -> (u32, u32) {
        (WIDTH, TITLE_HEIGHT + self.legend_height() + CHART_HEIGHT)
    }

    /// The histogram of `rows`' lowest barriers.
    fn histogram(rows: &[RunRow], groups: &[String], threshold: f64) -> Figure {
        let x0 = LINEAR_WIDTH_MM;
        let shown = |row: &RunRow| row.lowest_barrier.is_finite();
        let count = count_groups(rows, groups, threshold, |row| !shown(row));
        let threshold_mm = threshold.is_finite().then_some(threshold * 1e3);
        // Bins a tenth of a decade wide, a whole number of them between zero and the
        // threshold, so that no bin holds runs on both sides of either.
        let bin = match threshold_mm.map(|t| symlog(t, x0).abs()) {
            Some(u) if u >= BIN_DECADES => u / (u / BIN_DECADES).round(),
            _ => BIN_DECADES,
        };
        let mut bins: Vec<Vec<i64>> = vec![Vec::new(); count.len()];
        for row in rows.iter().filter(|row| shown(row)) {
            let u = symlog(row.lowest_barrier * 1e3, x0);
            bins[row.draw.group].push((u / bin).floor() as i64);
        }
        let mut counts = Vec::with_capacity(bins.len());
        let (mut lo, mut hi) = (0.0f64, 0.0f64);
        let mut most = 0;
        for group in &bins {
            let (Some(&first), Some(&last)) = (group.iter().min(), group.iter().max()) else {
                counts.push((0, Vec::new()));
                continue;
            };
            let mut per_bin = vec![0usize; (last - first + 1) as usize];
            for &k in group {
                per_bin[(k - first) as usize] += 1;
            }
            most = most.max(per_bin.iter().copied().max().unwrap_or(0));
            lo = lo.min(first as f64 * bin);
            hi = hi.max((last + 1) as f64 * bin);
            counts.push((first, per_bin));
        }
        if let Some(t) = threshold_mm {
            let u = symlog(t, x0);
            lo = lo.min(u);
            hi = hi.max(u);
        }
        let (width, height) = plot_pixels();
        let u = padded(lo, hi, 1.0);
        let x = Axis::symlog(
            symexp(u.start, x0)..symexp(u.end, x0),
            x0,
            width,
            X_TICK_GAP,
        );
        let top = symexp(symlog(most.max(10) as f64, 1.0) + 0.25, 1.0);
        let y = Axis::symlog(0.0..top, 1.0, height, Y_TICK_GAP);
        let threshold_text = threshold_text(threshold);
        let legend = count
            .iter()
            .enumerate()
            .map(|(g, group)| Entry {
                colour: colour(g),
                marker: Marker::Bar,
                text: group.text(&threshold_text),
            })
            .collect();
        Figure::Histogram(Histogram {
            title: format!(
                "Lowest barrier over each run: distribution per group ({})",
                runs_text(rows.len())
            ),
            x,
            y,
            threshold: threshold_mm,
            threshold_text,
            bin,
            counts,
            legend,
        })
    }

    /// The scatter of `rows`' lowest barriers against their set points'.
    fn scatter(rows: &[RunRow], groups: &[String], threshold: f64) -> Figure {
        let x0 = LINEAR_WIDTH_MM;
        let shown =
            |row: &RunRow| row.lowest_barrier.is_finite() && row.set_point_barrier.is_finite();
        let count = count_groups(rows, groups, threshold, |row| !shown(row));
        let threshold_mm = threshold.is_finite().then_some(threshold * 1e3);
        let mut points: Vec<Vec<(f64, f64)>> = vec![Vec::new(); count.len()];
        for row in rows.iter().filter(|row| shown(row)) {
            points[row.draw.group].push((row.set_point_barrier * 1e3, row.lowest_barrier * 1e3));
        }
        let all = || points.iter().flatten();
        let (mut x_lo, mut x_hi) = (0.0f64, 0.0f64);
        let (mut y_lo, mut y_hi) = (0.0f64, 0.0f64);
        for &(x, y) in all() {
            x_lo = x_lo.min(x);
            x_hi = x_hi.max(x);
            let u = symlog(y, x0);
            y_lo = y_lo.min(u);
            y_hi = y_hi.max(u);
        }
        if let Some(t) = threshold_mm {
            let u = symlog(t, x0);
            y_lo = y_lo.min(u);
            y_hi = y_hi.max(u);
        }
        let (_, height) = plot_pixels();
        let x = padded(x_lo, x_hi, 2.0);
        let u = padded(y_lo, y_hi, 1.0);
        let y = Axis::symlog(
            symexp(u.start, x0)..symexp(u.end, x0),
            x0,
            height,
            Y_TICK_GAP,
        );
        let threshold_text = threshold_text(threshold);
        let legend = count
            .iter()
            .enumerate()
            .map(|(g, group)| Entry {
                colour: colour(g),
                marker: Marker::Dot,
                text: group.text(&threshold_text),
            })
            .collect();
        Figure::Scatter(Scatter {
            title: format!(
                "Lowest barrier over the run against the set point's distance from the safe set ({})",
                runs_text(rows.len())
            ),
            x: Axis::linear(x),
            y,
            threshold: threshold_mm,
            threshold_text,
            points,
            legend,
        })
    }

    /// The progress of a search: `scores[g]` are group `g`'s runs' lowest barriers \[m\]
    /// in the order they were spent (`-∞`: the state left the model's domain).
    fn progress(scores: &[Vec<f64>], groups: &[String], threshold: f64) -> Figure {
        let x0 = LINEAR_WIDTH_MM;
        let threshold_mm = threshold.is_finite().then_some(threshold * 1e3);
        let mut steps: Vec<Vec<(f64, f64)>> = Vec::new();
        let (mut lo, mut hi) = (0.0f64, 0.0f64);
        let mut infinite = false;
        let mut most = 1usize;
        for group in scores {
            let mut best = f64::INFINITY;
            let mut curve = Vec::new();
            for (k, &v) in group.iter().enumerate() {
                let v = if v.is_nan() { f64::NEG_INFINITY } else { v };
                if v < best || k == 0 {
                    best = best.min(v);
                    curve.push(((k + 1) as f64, best * 1e3));
                }
            }
            if let Some(&(_, last)) = curve.last() {
                curve.push((group.len() as f64, last));
            }
            for &(_, y) in &curve {
                if y.is_finite() {
                    lo = lo.min(symlog(y, x0));
                    hi = hi.max(symlog(y, x0));
                } else {
                    infinite = true;
                }
            }
            most = most.max(group.len());
            steps.push(curve);
        }
        if let Some(t) = threshold_mm {
            lo = lo.min(symlog(t, x0));
            hi = hi.max(symlog(t, x0));
        }
        let (_, height) = plot_pixels();
        let u = padded(lo, hi, 1.0);
        // -∞ gets a row of its own, half a decade below everything finite, labelled so.
        let floor = infinite.then(|| symexp(u.start - 0.5, x0));
        let start = floor.map_or(u.start, |f| symlog(f, x0) - 0.05);
        let mut y = Axis::symlog(symexp(start, x0)..symexp(u.end, x0), x0, height, Y_TICK_GAP);
        if let Some(f) = floor {
            let finite = symexp(u.start, x0);
            y.ticks.retain(|&t| t >= finite);
            y.minor.retain(|&t| t >= finite);
            y.ticks.insert(0, f);
            y.infinity = Some(f);
            for curve in &mut steps {
                for point in curve.iter_mut() {
                    if !point.1.is_finite() {
                        point.1 = f;
                    }
                }
            }
        }
        let threshold_text = threshold_text(threshold);
        let legend = steps
            .iter()
            .enumerate()
            .map(|(g, curve)| {
                let name = groups
                    .get(g)
                    .cloned()
                    .unwrap_or_else(|| format!("group {g}"));
                let runs = scores.get(g).map_or(0, Vec::len);
                let first = scores.get(g).and_then(|s| {
                    s.iter()
                        .position(|&v| v.is_nan() || v < threshold)
                        .map(|k| k + 1)
                });
                let worst = curve.last().map(|p| p.1);
                let worst = match (worst, floor) {
                    (None, _) => "no runs".to_string(),
                    (Some(w), Some(f)) if w == f => "−∞ (left the model's domain)".to_string(),
                    (Some(w), _) => format!("{} m", signed(&format!("{:.2e}", w * 1e-3))),
                };
                let first = first.map_or_else(
                    || "none below the threshold".to_string(),
                    |k| format!("first below the threshold after {}", runs_text(k)),
                );
                Entry {
                    colour: colour(g),
                    marker: Marker::Line,
                    text: format!("{name}: lowest {worst} in {}; {first}", runs_text(runs)),
                }
            })
            .collect();
        let total: usize = scores.iter().map(Vec::len).sum();
        Figure::Progress(Progress {
            title: format!(
                "Search for the worst case: lowest barrier found so far ({})",
                runs_text(total)
            ),
            x: Axis::linear(0.0..(most as f64).max(1.0)),
            y,
            threshold: threshold_mm,
            threshold_text,
            curves: steps,
            floor,
            legend,
        })
    }

    /// Draws the figure on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &Area<DB>) -> Result<(), String> {
        let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
        root.fill(&WHITE).map_err(e)?;
        let (title, rest) = root.split_vertically(TITLE_HEIGHT);
        let (legend, chart) = rest.split_vertically(self.legend_height());
        let (w, h) = title.dim_in_pixel();
        title
            .draw(&Text::new(
                self.title().to_string(),
                (w as i32 / 2, h as i32 / 2 + 4),
                TextStyle::from((FONT, 22, FontStyle::Bold).into_font())
                    .pos(Pos::new(HPos::Center, VPos::Center)),
            ))
            .map_err(e)?;
        draw_legend(&legend, self.legend()).map_err(e)?;
        match self {
            Figure::Histogram(h) => draw_histogram(root, &chart, h),
            Figure::Scatter(s) => draw_scatter(root, &chart, s),
            Figure::Progress(p) => draw_progress(root, &chart, p),
        }
    }
}

/// Draws the legend `entries` in `area`, in one column or two.
fn draw_legend<DB: DrawingBackend>(
    area: &Area<DB>,
    entries: &[Entry],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (rows, columns) = legend_layout(entries.len());
    let (width, _) = area.dim_in_pixel();
    let left = (MARGIN_LEFT + Y_LABEL_WIDTH) as i32;
    let column_width = (width as i32 - left) / columns.max(1) as i32;
    let font =
        TextStyle::from((FONT, LEGEND_FONT).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    for (k, entry) in entries.iter().enumerate() {
        let (row, column) = (k as u32 % rows.max(1), k as u32 / rows.max(1));
        let x = left + column as i32 * column_width;
        let y = (LEGEND_PAD + row * LEGEND_LINE + LEGEND_LINE / 2) as i32;
        match entry.marker {
            Marker::Bar => {
                area.draw(&Rectangle::new(
                    [(x, y - 7), (x + 28, y + 7)],
                    entry.colour.mix(0.25).filled(),
                ))?;
                area.draw(&Rectangle::new(
                    [(x, y - 7), (x + 28, y + 7)],
                    entry.colour.stroke_width(2),
                ))?;
            }
            Marker::Dot => {
                area.draw(&Circle::new((x + 14, y), 5, entry.colour.filled()))?;
            }
            Marker::Line => {
                area.draw(&PathElement::new(
                    vec![(x, y), (x + 28, y)],
                    entry.colour.stroke_width(3),
                ))?;
            }
        }
        area.draw(&Text::new(entry.text.clone(), (x + 38, y), font.clone()))?;
    }
    Ok(())
}

/// Builds the chart of `x` and `y` on `area`, with its grid, tick labels and axis names.
fn build_chart<'a, DB: DrawingBackend>(
    area: &'a Area<DB>,
    x: &Axis,
    y: &Axis,
    x_desc: &str,
    y_desc: &str,
) -> Result<Chart<'a, DB>, String> {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    let mut chart = ChartBuilder::on(area)
        .margin_left(MARGIN_LEFT)
        .margin_right(MARGIN_RIGHT)
        .margin_top(MARGIN_TOP)
        .margin_bottom(MARGIN_BOTTOM)
        .x_label_area_size(X_LABEL_HEIGHT)
        .y_label_area_size(Y_LABEL_WIDTH)
        .build_cartesian_2d(x.clone(), y.clone())
        .map_err(e)?;
    let x_format = |v: &f64| x.label(*v);
    let y_format = |v: &f64| y.label(*v);
    chart
        .configure_mesh()
        .x_labels(12)
        .y_labels(8)
        .x_label_formatter(&x_format)
        .y_label_formatter(&y_format)
        .label_style((FONT, TICK_FONT))
        .axis_desc_style((FONT, AXIS_FONT))
        .bold_line_style(RGBColor(215, 215, 215))
        .light_line_style(RGBColor(240, 240, 240))
        .x_desc(x_desc)
        .y_desc(y_desc)
        .draw()
        .map_err(e)?;
    Ok(chart)
}

/// Draws `text` at `(x, y)` (pixels of `root`) on a white ground, anchored at `pos`.
fn note<DB: DrawingBackend>(
    root: &Area<DB>,
    text: &str,
    (x, y): (i32, i32),
    pos: Pos,
    colour: RGBColor,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let font = (FONT, NOTE_FONT).into_font();
    let (w, h) = font.box_size(text).map_or(
        (8 * text.chars().count() as i32, NOTE_FONT as i32),
        |(w, h)| (w as i32, h as i32),
    );
    let left = match pos.h_pos {
        HPos::Left => x,
        HPos::Center => x - w / 2,
        HPos::Right => x - w,
    };
    let top = match pos.v_pos {
        VPos::Top => y,
        VPos::Center => y - h / 2,
        VPos::Bottom => y - h,
    };
    root.draw(&Rectangle::new(
        [(left - 3, top - 2), (left + w + 3, top + h + 2)],
        WHITE.mix(0.85).filled(),
    ))?;
    root.draw(&Text::new(
        text.to_string(),
        (x, y),
        TextStyle::from(font).pos(pos).color(&colour),
    ))
}

/// Width of `text` in the notes' font \[px\].
fn note_width(text: &str) -> i32 {
    (FONT, NOTE_FONT)
        .into_font()
        .box_size(text)
        .map_or(8 * text.chars().count() as i32, |(w, _)| w as i32)
}

/// Draws the histogram `h` in `area` (a part of `root`).
fn draw_histogram<DB: DrawingBackend>(
    root: &Area<DB>,
    area: &Area<DB>,
    h: &Histogram,
) -> Result<(), String> {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    let x_desc = format!(
        "lowest barrier over the run [mm]  (symmetric log scale: sign(b)·log10(1 + |b| / {} mm))",
        decade_label(LINEAR_WIDTH_MM)
    );
    let mut chart = build_chart(area, &h.x, &h.y, &x_desc, "number of runs (log scale)")?;
    let (x_range, y_range) = (h.x.range.clone(), h.y.range.clone());
    if let Some(t) = h.threshold.filter(|&t| t > x_range.start) {
        chart
            .draw_series([Rectangle::new(
                [(x_range.start, y_range.start), (t, y_range.end)],
                UNSAFE.mix(0.07).filled(),
            )])
            .map_err(e)?;
    }
    let edge = |k: i64| symexp(k as f64 * h.bin, LINEAR_WIDTH_MM);
    for (g, (first, counts)) in h.counts.iter().enumerate() {
        let fill = colour(g).mix(0.2).filled();
        let bars = counts
            .iter()
            .enumerate()
            .filter(|&(_, &c)| c > 0)
            .map(|(i, &c)| {
                let k = first + i as i64;
                Rectangle::new([(edge(k), 0.0), (edge(k + 1), c as f64)], fill)
            });
        chart.draw_series(bars).map_err(e)?;
    }
    // The outlines over every group's bars, so that none hides another's.
    for (g, (first, counts)) in h.counts.iter().enumerate() {
        if counts.is_empty() {
            continue;
        }
        let mut outline = vec![(edge(*first), 0.0)];
        for (i, &c) in counts.iter().enumerate() {
            let k = first + i as i64;
            outline.extend([(edge(k), c as f64), (edge(k + 1), c as f64)]);
        }
        outline.push((edge(first + counts.len() as i64), 0.0));
        chart
            .draw_series(LineSeries::new(outline, colour(g).stroke_width(2)))
            .map_err(e)?;
    }
    chart
        .draw_series(LineSeries::new(
            [(0.0, y_range.start), (0.0, y_range.end)],
            BLACK.stroke_width(1),
        ))
        .map_err(e)?;
    if let Some(t) = h.threshold {
        chart
            .draw_series(DashedLineSeries::new(
                [(t, y_range.start), (t, y_range.end)],
                8,
                5,
                UNSAFE.stroke_width(2),
            ))
            .map_err(e)?;
        let (px, py) = chart.backend_coord(&(t, y_range.end));
        let (plot_x, _) = chart.plotting_area().get_pixel_range();
        let text = format!("threshold {}: unsafe to the left", h.threshold_text);
        let y = py + 14;
        if px - plot_x.start >= note_width(&text) + 12 {
            note(
                root,
                &text,
                (px - 6, y),
                Pos::new(HPos::Right, VPos::Center),
                UNSAFE,
            )
        } else {
            note(
                root,
                &text,
                (px + 6, y),
                Pos::new(HPos::Left, VPos::Center),
                UNSAFE,
            )
        }
        .map_err(e)?;
    }
    Ok(())
}

/// Draws the scatter `s` in `area` (a part of `root`).
fn draw_scatter<DB: DrawingBackend>(
    root: &Area<DB>,
    area: &Area<DB>,
    s: &Scatter,
) -> Result<(), String> {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    let y_desc = format!(
        "lowest barrier over the run [mm]  (symmetric log, linear within ±{} mm)",
        decade_label(LINEAR_WIDTH_MM)
    );
    let mut chart = build_chart(
        area,
        &s.x,
        &s.y,
        "lowest barrier at the set point [mm]  (< 0: set point outside the safe set)",
        &y_desc,
    )?;
    let (x_range, y_range) = (s.x.range.clone(), s.y.range.clone());
    if let Some(t) = s.threshold.filter(|&t| t > y_range.start) {
        chart
            .draw_series([Rectangle::new(
                [(x_range.start, y_range.start), (x_range.end, t)],
                UNSAFE.mix(0.07).filled(),
            )])
            .map_err(e)?;
    }
    chart
        .draw_series(LineSeries::new(
            [(0.0, y_range.start), (0.0, y_range.end)],
            BLACK.stroke_width(1),
        ))
        .map_err(e)?;
    chart
        .draw_series(LineSeries::new(
            [(x_range.start, 0.0), (x_range.end, 0.0)],
            RGBColor(120, 120, 120).stroke_width(1),
        ))
        .map_err(e)?;
    for (g, points) in s.points.iter().enumerate() {
        let style = colour(g).mix(0.55).filled();
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 2, style)))
            .map_err(e)?;
    }
    let (plot_x, plot_y) = chart.plotting_area().get_pixel_range();
    if let Some(t) = s.threshold {
        chart
            .draw_series(DashedLineSeries::new(
                [(x_range.start, t), (x_range.end, t)],
                8,
                5,
                UNSAFE.stroke_width(2),
            ))
            .map_err(e)?;
        let (_, py) = chart.backend_coord(&(x_range.end, t));
        let text = format!("threshold {}: unsafe below", s.threshold_text);
        note(
            root,
            &text,
            (plot_x.end - 6, py + 5),
            Pos::new(HPos::Right, VPos::Top),
            UNSAFE,
        )
        .map_err(e)?;
    }
    // Which side of x = 0 is which, at the top of the plot, where there is room.
    let (px, _) = chart.backend_coord(&(0.0, y_range.end));
    let y = plot_y.start + 14;
    let grey = RGBColor(60, 60, 60);
    let outside = "← set point outside the safe set";
    if px - plot_x.start >= note_width(outside) + 12 {
        note(
            root,
            outside,
            (px - 6, y),
            Pos::new(HPos::Right, VPos::Center),
            grey,
        )
        .map_err(e)?;
    }
    let inside = "set point inside the safe set →";
    if plot_x.end - px >= note_width(inside) + 12 {
        note(
            root,
            inside,
            (px + 6, y),
            Pos::new(HPos::Left, VPos::Center),
            grey,
        )
        .map_err(e)?;
    }
    Ok(())
}

/// Draws the progress `p` in `area` (a part of `root`).
fn draw_progress<DB: DrawingBackend>(
    root: &Area<DB>,
    area: &Area<DB>,
    p: &Progress,
) -> Result<(), String> {
    let e = |error: DrawingAreaErrorKind<DB::ErrorType>| error.to_string();
    let y_desc = format!(
        "lowest barrier found so far [mm]  (symmetric log, linear within ±{} mm)",
        decade_label(LINEAR_WIDTH_MM)
    );
    let mut chart = build_chart(
        area,
        &p.x,
        &p.y,
        "runs spent on the group (generation by generation)",
        &y_desc,
    )?;
    let (x_range, y_range) = (p.x.range.clone(), p.y.range.clone());
    if let Some(t) = p.threshold.filter(|&t| t > y_range.start) {
        chart
            .draw_series([Rectangle::new(
                [(x_range.start, y_range.start), (x_range.end, t)],
                UNSAFE.mix(0.07).filled(),
            )])
            .map_err(e)?;
    }
    chart
        .draw_series(LineSeries::new(
            [(x_range.start, 0.0), (x_range.end, 0.0)],
            RGBColor(120, 120, 120).stroke_width(1),
        ))
        .map_err(e)?;
    let (plot_x, _) = chart.plotting_area().get_pixel_range();
    if let Some(f) = p.floor {
        chart
            .draw_series(DashedLineSeries::new(
                [(x_range.start, f), (x_range.end, f)],
                3,
                4,
                BLACK.stroke_width(1),
            ))
            .map_err(e)?;
        let (_, py) = chart.backend_coord(&(x_range.end, f));
        note(
            root,
            "−∞: the state left the model's domain",
            (plot_x.end - 6, py - 4),
            Pos::new(HPos::Right, VPos::Bottom),
            BLACK,
        )
        .map_err(e)?;
    }
    for (g, curve) in p.curves.iter().enumerate() {
        // A step: each lowest holds until the next.
        let mut path = Vec::new();
        for (k, &(x, y)) in curve.iter().enumerate() {
            if k > 0 {
                path.push((x, path.last().map_or(y, |p: &(f64, f64)| p.1)));
            }
            path.push((x, y));
        }
        chart
            .draw_series(LineSeries::new(path, colour(g).stroke_width(3)))
            .map_err(e)?;
        chart
            .draw_series(
                curve
                    .iter()
                    .take(curve.len().saturating_sub(1))
                    .map(|&pt| Circle::new(pt, 4, colour(g).filled())),
            )
            .map_err(e)?;
    }
    if let Some(t) = p.threshold {
        chart
            .draw_series(DashedLineSeries::new(
                [(x_range.start, t), (x_range.end, t)],
                8,
                5,
                UNSAFE.stroke_width(2),
            ))
            .map_err(e)?;
        let (_, py) = chart.backend_coord(&(x_range.end, t));
        let text = format!("threshold {}: unsafe below", p.threshold_text);
        note(
            root,
            &text,
            (plot_x.end - 6, py + 5),
            Pos::new(HPos::Right, VPos::Top),
            UNSAFE,
        )
        .map_err(e)?;
    }
    Ok(())
}

/// Draws `figure` into `<stem>.png` and `<stem>.svg` in `dir` and returns their paths.
fn write_figure(dir: &Path, stem: &str, figure: &Figure) -> Result<Vec<PathBuf>, PlotError> {
    let size = figure.size();
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    let failed = |file: &Path| {
        let file = file.to_path_buf();
        move |message: String| PlotError::Draw { file, message }
    };
    let mut pixels = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        figure.draw(&root).map_err(failed(&png))?;
        root.present()
            .map_err(|e| e.to_string())
            .map_err(failed(&png))?;
    }
    write_png(&png, &pixels, size).map_err(failed(&png))?;
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        figure.draw(&root).map_err(failed(&svg))?;
        root.present()
            .map_err(|e| e.to_string())
            .map_err(failed(&svg))?;
    }
    Ok(vec![png, svg])
}

/// Draws the batch's figures into `dir` (created if missing) and returns the paths
/// written: `lowest_barrier.png`/`.svg` (the distribution of each run's lowest barrier, a
/// histogram per group) and `lowest_vs_set_point.png`/`.svg` (each run's lowest barrier
/// against the lowest barrier at its set point). `groups[g]` names group `g` (rows with
/// `row.draw.group == g`); a run is unsafe when its lowest barrier is below `threshold`
/// \[m\], and the legends count those per group. Values that are not finite are left out
/// (and counted in the legend). Any input, even no rows, gives valid figures.
pub fn write_figures(
    dir: &Path,
    rows: &[RunRow],
    groups: &[String],
    threshold: f64,
) -> Result<Vec<PathBuf>, PlotError> {
    register_fonts()?;
    std::fs::create_dir_all(dir).map_err(|source| PlotError::Io {
        dir: dir.to_path_buf(),
        source,
    })?;
    let mut written = write_figure(
        dir,
        "lowest_barrier",
        &Figure::histogram(rows, groups, threshold),
    )?;
    written.extend(write_figure(
        dir,
        "lowest_vs_set_point",
        &Figure::scatter(rows, groups, threshold),
    )?);
    Ok(written)
}

/// Draws the figure of a search into `dir` (created if missing) and returns the paths
/// written, `search.png` and `search.svg`: per group, the lowest barrier found so far
/// against the runs spent. `scores[g]` are group `g`'s (named `groups[g]`) runs' lowest
/// barriers \[m\] in the order they were spent, `-∞` (or NaN) for a run whose state left
/// the model's domain; `threshold` \[m\] is drawn. Any input gives a valid figure.
pub fn write_search_figure(
    dir: &Path,
    scores: &[Vec<f64>],
    groups: &[String],
    threshold: f64,
) -> Result<Vec<PathBuf>, PlotError> {
    register_fonts()?;
    std::fs::create_dir_all(dir).map_err(|source| PlotError::Io {
        dir: dir.to_path_buf(),
        source,
    })?;
    write_figure(dir, "search", &Figure::progress(scores, groups, threshold))
}

#[cfg(test)]
mod tests {
    use softcbf_description::uncertainty::ModuleFactors;

    use super::*;
    use crate::control::SafetyMode;
    use crate::draw::Draw;

    /// A run of group `group` with these barriers \[m\].
    fn row(run: usize, group: usize, set_point_barrier: f64, lowest_barrier: f64) -> RunRow {
        RunRow {
            run,
            draw: Draw {
                seed: run as u64,
                group,
                safety: SafetyMode::Paper,
                control_period: 1e-3,
                set_point: vec![0.0; 6],
                initial_q: vec![0.0; 6],
                initial_qd: vec![0.0; 6],
                factors: vec![ModuleFactors::NOMINAL; 2],
                noise_seed: 0,
            },
            set_point_barrier,
            lowest_barrier,
            lowest_label: "module 1 corner 1".to_string(),
            lowest_t: 0.5,
            set_point_error: 1e-3,
            max_abs_tau: 1.0,
            counts: crate::sim::TickCounts {
                ticks: 1000,
                qp_solves: 1000,
                active: 10,
                ..Default::default()
            },
            integrator_steps: 2000,
            stopped: String::new(),
        }
    }

    /// `n` runs over `groups` groups, set points from 30 mm outside to 20 mm inside the
    /// safe set, lowest barriers mostly within a micrometre of zero with tails of tens of
    /// millimetres, a few below the threshold, one not finite.
    fn synthetic(n: usize, groups: usize) -> Vec<RunRow> {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|run| {
                let group = run % groups;
                let set_point = -0.03 + 0.05 * uniform();
                let lowest = if set_point < 0.0 {
                    // Stopped short: near zero, some groups slightly below.
                    let spread = 10f64.powf(-9.0 + 4.0 * uniform());
                    spread * (uniform() - 0.2 * group as f64)
                } else {
                    set_point.min(0.02 * uniform())
                };
                let lowest = if run == 7 { f64::NAN } else { lowest };
                row(run, group, set_point, lowest)
            })
            .collect()
    }

    fn temp_dir(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!(
            "softcbf-verify-figures-{name}-{}",
            std::process::id()
        ))
    }

    fn assert_written(files: &[PathBuf], dir: &Path) {
        let names: Vec<String> = files
            .iter()
            .map(|f| f.strip_prefix(dir).unwrap().display().to_string())
            .collect();
        assert_eq!(
            names,
            [
                "lowest_barrier.png",
                "lowest_barrier.svg",
                "lowest_vs_set_point.png",
                "lowest_vs_set_point.svg",
            ]
        );
        for file in files {
            let len = std::fs::metadata(file).unwrap().len();
            assert!(len > 0, "{} is empty", file.display());
        }
    }

    #[test]
    fn figures_of_a_batch_are_written() {
        let dir = temp_dir("batch");
        let rows = synthetic(400, 3);
        let groups: Vec<String> = ["paper @ 1000 Hz", "hold @ 33.3 Hz", "sampled @ 33.3 Hz"]
            .map(String::from)
            .to_vec();
        let files = write_figures(&dir, &rows, &groups, -1e-6).unwrap();
        assert_written(&files, &dir);
        // Rendering into a fixed place, for a person to look at.
        if let Some(out) = std::env::var_os("SOFTCBF_VERIFY_FIGURES") {
            write_figures(Path::new(&out), &synthetic(10_000, 3), &groups, -1e-6).unwrap();
            write_figures(&Path::new(&out).join("empty"), &[], &groups, -1e-6).unwrap();
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn empty_and_degenerate_input_still_gives_figures() {
        let dir = temp_dir("empty");
        let groups = vec![
            "paper @ 1000 Hz".to_string(),
            "sampled @ 33.3 Hz".to_string(),
        ];
        // No rows at all, with and without group names.
        assert_written(&write_figures(&dir, &[], &groups, -1e-6).unwrap(), &dir);
        assert_written(&write_figures(&dir, &[], &[], -1e-6).unwrap(), &dir);
        // All values equal; a group with no rows; a row of a group without a name.
        let equal: Vec<RunRow> = (0..50).map(|run| row(run, 0, 0.0, 0.0)).collect();
        assert_written(&write_figures(&dir, &equal, &groups, -1e-6).unwrap(), &dir);
        let odd = vec![row(0, 3, 0.01, 0.002)];
        assert_written(&write_figures(&dir, &odd, &groups, -1e-6).unwrap(), &dir);
        // Nothing finite, and a threshold that is not.
        let infinite = vec![
            row(0, 0, f64::INFINITY, f64::NAN),
            row(1, 1, f64::NAN, f64::NEG_INFINITY),
        ];
        assert_written(
            &write_figures(&dir, &infinite, &groups, -1e-6).unwrap(),
            &dir,
        );
        assert_written(
            &write_figures(&dir, &equal, &groups, f64::NAN).unwrap(),
            &dir,
        );
        assert_written(&write_figures(&dir, &equal, &groups, 0.0).unwrap(), &dir);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn search_figures_of_any_input_are_written() {
        let dir = temp_dir("search");
        let groups = vec![
            "paper @ 1000 Hz".to_string(),
            "sampled @ 33.3 Hz".to_string(),
        ];
        let cases: Vec<Vec<Vec<f64>>> = vec![
            vec![],
            vec![vec![], vec![0.0; 3]],
            vec![
                vec![0.02, 1e-4, -3e-6, f64::NEG_INFINITY, 0.01],
                vec![0.03, 0.01, f64::NAN, 2e-11],
            ],
            vec![vec![f64::NEG_INFINITY; 4]],
        ];
        for scores in &cases {
            let files = write_search_figure(&dir, scores, &groups, -1e-6).unwrap();
            assert_eq!(files.len(), 2);
            for file in &files {
                assert!(std::fs::metadata(file).unwrap().len() > 0);
            }
        }
        // The -∞ row is labelled as such, below every finite value.
        let Figure::Progress(p) = Figure::progress(&cases[2], &groups, -1e-6) else {
            panic!("not a progress figure");
        };
        let floor = p.floor.unwrap();
        assert_eq!(p.y.label(floor), "−∞");
        assert!(p.y.ticks.iter().all(|&t| t >= floor));
        assert!(floor < -3e-3 && p.y.range.start < floor);
        // Each curve steps down to the lowest so far: group 1 reaches -∞ at its NaN.
        assert_eq!(p.curves[1].last().unwrap(), &(4.0, floor));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn counts_and_labels() {
        let rows = vec![
            row(0, 0, 0.01, -2e-6),
            row(1, 0, 0.01, 0.0),
            row(2, 1, 0.01, f64::NAN),
            row(3, 1, 0.01, -1e-3),
        ];
        let groups = vec!["a".to_string(), "b".to_string(), "c".to_string()];
        let counts = count_groups(&rows, &groups, -1e-6, |r| !r.lowest_barrier.is_finite());
        let threshold = threshold_text(-1e-6);
        assert_eq!(threshold, "−1e-6 m");
        let texts: Vec<String> = counts.iter().map(|c| c.text(&threshold)).collect();
        assert_eq!(
            texts,
            [
                "a: 1 / 2 unsafe (< −1e-6 m)",
                "b: 2 / 2 unsafe (< −1e-6 m), 1 invalid, not drawn",
                "c: 0 / 0 unsafe (< −1e-6 m) (no runs)",
            ]
        );
        assert_eq!(decade_label(1e-3), "0.001");
        assert_eq!(decade_label(-10.0), "−10");
        assert_eq!(decade_label(0.0), "0");
        for v in [-30.0, -1e-3, 0.0, 2e-4, 20.0] {
            assert!((symexp(symlog(v, 1e-3), 1e-3) - v).abs() <= 1e-12 * v.abs().max(1.0));
        }
        // Ticks: zero and decades, within the range, far enough apart.
        let axis = Axis::symlog(-30.0..20.0, 1e-3, 1000.0, X_TICK_GAP);
        assert!(axis.ticks.contains(&0.0));
        assert!(axis.ticks.iter().all(|t| (-30.0..=20.0).contains(t)));
        assert!(axis.ticks.len() >= 7, "{:?}", axis.ticks);
    }
}
