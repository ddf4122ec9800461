//! Figures of a run like the paper's Fig. 4 (coordinates, applied τ, the filter's action
//! `τ − τ_nom`, barriers), as PNG and SVG, from one record or side by side from several.
//!
//! [`write_figures`] is the one entry point of `softcbf simulate`, `softcbf run` and
//! `softcbf plot`. The time axis is split where the motion settles ([`Split`]): the
//! transient gets most of the width, the rest of the run the remainder, on one shared
//! value axis. Barriers that reach zero are labelled (from the record's barrier labels)
//! in a column below the lowest of them, so the labels collide with nothing. A robot with
//! barriers beyond its plate corners gets one row of barrier panels per kind group
//! ([`KindGroup`]: plate corners, elongation limits, bend limits, obstacles), each with
//! its unit and zero line; the plate corners alone keep the one row of Fig. 4. A row whose
//! barriers come near zero gets a zoomed row under it, in millimetres, where the last
//! millimetres before the boundary and any dip past it show.
//!
//! Text is drawn with DejaVu Sans compiled into the binary (registered once with plotters'
//! `ab_glyph` backend), so a figure comes out byte-identical on any machine: no system
//! font or fontconfig is consulted. Long series are reduced to a min/max envelope per
//! pixel column ([`envelope`]) before drawing, which keeps every extremum visible and the
//! SVG small. The PNG is rendered into memory and encoded with the `png` crate.
//!
//! ```no_run
//! # use softcbf_core::record::Record;
//! # use softcbf_figures::plot::{FigureOptions, write_figures};
//! # fn demo(filtered: &Record, plain: &Record) -> Result<(), softcbf_figures::plot::PlotError> {
//! let set_point = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
//! let panels = [("safety filter (HOCBF-QP)", filtered), ("PD+ only", plain)];
//! let files = write_figures("out".as_ref(), &panels, &set_point, &FigureOptions::default())?;
//! assert_eq!(files.len(), 2); // out/figure.png, out/figure.svg
//! # Ok(()) }
//! ```

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

pub mod draw;
pub mod invalid;
pub mod robot_view;
mod series;
mod style;

use plotters::prelude::{BitMapBackend, FontStyle, IntoDrawingArea, IntoFont, SVGBackend};
use plotters::style::register_font;

use softcbf_description::barriers::{KIND_GROUPS, label as barrier_label};
use softcbf_generated::KindGroup;

use crate::model::Model;
use crate::record::Record;
use series::Range;
pub use series::{display_name, envelope, excursion, nice_ceil, settle_time, window};
pub use style::{
    BARRIER_PALETTE, DISTINCT_COORDINATES, LineStyle, PALETTE, SET_POINT_DASH, barrier_style,
    coordinate_style, module_dash,
};

/// Why figures could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// No record was given.
    #[error("no record to plot")]
    NoPanels,
    /// A record has no rows.
    #[error("record `{title}` has no rows")]
    EmptyRecord {
        /// Column title of the record.
        title: String,
    },
    /// A size does not match the first record's.
    #[error("record `{title}`: {what} is {found}, expected {expected}")]
    Mismatch {
        /// Column title of the record.
        title: String,
        /// What was compared.
        what: &'static str,
        /// The size expected.
        expected: usize,
        /// The size found.
        found: usize,
    },
    /// The embedded font could not be registered.
    #[error("the embedded DejaVu font could not be registered with plotters")]
    Font,
    /// A time window or split that cannot be drawn.
    #[error("{0}")]
    Time(String),
    /// Creating the output directory failed.
    #[error("{}: {source}", dir.display())]
    Io {
        /// The output directory.
        dir: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// Drawing or writing a figure failed.
    #[error("{}: {message}", file.display())]
    Draw {
        /// The figure file.
        file: PathBuf,
        /// The drawing backend's message.
        message: String,
    },
}

/// Font family name the figures use (registered with the embedded DejaVu Sans).
const FONT: &str = "sans-serif";
/// Width of one column of panels \[px\].
pub const COLUMN_WIDTH: u32 = 660;
/// Width of the legend strip at the right \[px\].
pub const LEGEND_WIDTH: u32 = 170;
/// Height of a figure with one row of barrier panels \[px\]; each further row (a robot
/// with barriers of several kind groups) adds [`ROW_HEIGHT`].
pub const FIGURE_HEIGHT: u32 = 1240;
/// Height of the column-title band \[px\].
const TITLE_HEIGHT: u32 = 44;
/// Rows of panels before the barriers: q, τ, τ − τ_nom.
const COORDINATE_ROWS: usize = 3;
/// Height of one row of panels \[px\].
pub const ROW_HEIGHT: u32 = (FIGURE_HEIGHT - TITLE_HEIGHT) / (COORDINATE_ROWS as u32 + 1);
/// Height of a panel's caption \[px\].
const CAPTION_HEIGHT: u32 = 26;
/// Height of the time-axis labels under a panel \[px\].
const X_LABEL_HEIGHT: u32 = 40;
/// Margin above and below a panel's plot \[px\].
const PLOT_MARGIN: u32 = 4;
/// Line height of the labels of the barriers that reach zero \[px\].
const LABEL_LINE: u32 = 17;

/// Fraction of the largest excursion of a coordinate over the run within which the motion
/// counts as settled, for [`Split::Auto`].
pub const SETTLE_FRACTION: f64 = 0.05;
/// [`Split::Auto`] splits only if the transient takes at most this fraction of the window.
pub const SPLIT_AT_MOST: f64 = 0.45;
/// [`Split::Auto`] puts at least this many rows of every record before the split, so that a
/// slow log (a hardware run at 33 Hz) still shows its transient as a curve.
pub const SPLIT_MIN_ROWS: usize = 30;
/// Share of a panel's plot width given to the part before the split.
pub const SPLIT_SHARE: f64 = 0.64;
/// A barrier whose lowest value is at most this \[m\] (or 0.2 % of the barrier axis, if
/// larger) counts as reaching zero and gets a label.
pub const ACTIVE_TOLERANCE: f64 = 1e-4;
/// A row of barriers gets a zoomed row under it when one of its barriers comes this close
/// to zero \[m, or rad for a bend limit\], 5 mm, so that the last millimetres before the
/// boundary, and any dip past it, show (on the full row's axis, tenths of a metre, they do
/// not). The zoomed row reaches at least this far above zero.
pub const ZOOM_HIGH: f64 = 5e-3;
/// The zoomed row reaches below zero to the lowest barrier (5 % beyond it, rounded up to
/// 1, 1.5, 2, 2.5, 3, 4, 5, 6 or 8 × 10ᵏ), at least [`ZOOM_LOW_MIN`] and at most
/// [`ZOOM_LOW_MAX`], and as far above zero (at least [`ZOOM_HIGH`]): the approach to the
/// boundary and the dip past it on one scale. A barrier further below leaves the zoomed
/// panel at its edge (the full row above shows it whole).
pub const ZOOM_LOW_MIN: f64 = 1e-3;
/// See [`ZOOM_LOW_MIN`].
pub const ZOOM_LOW_MAX: f64 = 5e-2;
/// Clear space between the lowest labelled barrier and the block of labels under it \[px\],
/// so that the block never touches the lines that reach zero, nor the zero line.
const LABEL_GAP: u32 = 12;
/// Height of the two lines under a column's title that say its run has invalid states
/// \[px\].
const NOTE_HEIGHT: u32 = 36;

/// Where the time axis of every panel is split into the transient and the rest.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Split {
    /// Where the coordinates of every panel have settled to within [`SETTLE_FRACTION`] of
    /// their excursion (but after [`SPLIT_MIN_ROWS`] rows), rounded up to 1, 1.5, 2, 2.5,
    /// 3, 4, 5, 6 or 8 × 10ᵏ s from the window's start; no split if that is more than
    /// [`SPLIT_AT_MOST`] of the window.
    #[default]
    Auto,
    /// One time axis over the whole window.
    Off,
    /// At this time \[s\] (inside the window).
    At(f64),
}

/// How the figures are drawn, beyond the records and the set point.
#[derive(Clone, Copy, Default)]
pub struct FigureOptions<'a> {
    /// Time window `(start, end)` \[s\] (default: the records' whole time span).
    pub time_range: Option<(f64, f64)>,
    /// Where the time axis is split.
    pub split: Split,
    /// How many barriers each module owns, in order (e.g. `sim::barriers_per_module` of
    /// the model's table): how the one row of barrier panels of a robot with plate corners
    /// only is split into modules (rows per kind group take the module from the model or
    /// the labels). Empty: from the barrier labels (`module K …`), else evenly over the
    /// `n/3` modules, else one module.
    pub barriers_per_module: &'a [usize],
    /// The robot the records are of: with it, [`write_figures`] also draws the 3-D view
    /// (`robot.png`, `robot.svg`; [`robot_view::draw_robot_views`]).
    pub model: Option<&'a Model>,
    /// Also write the animation `robot.gif` ([`robot_view::animate_robot`]; about a
    /// second for the paper's run). Needs [`FigureOptions::model`].
    pub animate: bool,
}

/// Registers the embedded fonts with plotters, once per process.
pub fn register_fonts() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        let regular = register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok();
        let bold = register_font(FONT, FontStyle::Bold, dejavu::sans::bold()).is_ok();
        regular && bold
    });
    if ok { Ok(()) } else { Err(PlotError::Font) }
}

/// A barrier that reaches zero in one panel: its index, its lowest and its last value in
/// the window.
#[derive(Clone, Copy, Debug)]
struct Active {
    barrier: usize,
    low: f64,
    last: f64,
}

/// Width of the value labels left of a panel \[px\].
const Y_LABEL_WIDTH: u32 = 70;
/// Margins left and right of a panel's plot \[px\].
const MARGIN_LEFT: u32 = 6;
const MARGIN_RIGHT: u32 = 14;
/// Width of the line sample before a barrier's label, with its spacing \[px\].
const LABEL_SAMPLE: u32 = 34;
/// Font size of the barriers' labels \[px\].
const LABEL_FONT: u32 = 14;
/// Width allowed per character of a barrier's label if the font cannot measure it \[px\].
const LABEL_CHAR: u32 = 9;

/// How the labels of the barriers that reach zero are laid out in every panel: a block of
/// `columns` cells of `cell` pixels, filled row by row.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LabelGrid {
    columns: usize,
    cell: u32,
}

impl LabelGrid {
    /// A grid wide enough for the widest of `labels` (measured in the embedded font), as
    /// many cells as fit in a panel.
    fn new(labels: &[String]) -> LabelGrid {
        let font = (FONT, LABEL_FONT).into_font();
        let widest = labels
            .iter()
            .map(|label| {
                font.box_size(label)
                    .map_or(LABEL_CHAR * label.chars().count() as u32, |(w, _)| w)
            })
            .max()
            .unwrap_or(0);
        let cell = LABEL_SAMPLE + widest + 14;
        let usable = COLUMN_WIDTH - Y_LABEL_WIDTH - MARGIN_LEFT - MARGIN_RIGHT;
        LabelGrid {
            columns: (usable / cell.max(1)).max(1) as usize,
            cell,
        }
    }

    /// Rows of a block of `count` labels.
    fn rows(&self, count: usize) -> usize {
        count.div_ceil(self.columns)
    }
}

/// One row of barrier panels: the barriers it shows, their legend and value axis, and in
/// each column those that reach zero.
struct BarrierRow {
    /// The kind group of its barriers; `None` when one row shows every barrier and their
    /// kinds are not known (labels of no known kind).
    group: Option<KindGroup>,
    /// Whether it is the only row of barriers (then captioned as in the paper's Fig. 4).
    only: bool,
    /// Its barriers (record columns), in order.
    barriers: Vec<usize>,
    /// The modules (0-based) its barriers belong to, ascending: each has its dash.
    modules: Vec<usize>,
    /// Name of each barrier colour (the label without its `module K`).
    key_names: Vec<String>,
    /// Value range of the panels, shared by the columns.
    range: std::ops::Range<f64>,
    /// Per column, the barriers that reach zero, highest last value first.
    active: Vec<Vec<Active>>,
    /// Layout of their labels.
    grid: LabelGrid,
    /// Value range of the zoomed row near zero under this one, if one of its barriers
    /// comes within [`ZOOM_HIGH`] of zero.
    zoom: Option<std::ops::Range<f64>>,
}

impl BarrierRow {
    /// Caption and value-axis label of its panels.
    fn text(&self) -> (String, String) {
        let unit = self.group.map_or("m", KindGroup::unit);
        let caption = match self.group {
            Some(group) if !self.only => {
                format!(
                    "barrier values b: {} (those reaching 0 labelled)",
                    group.title()
                )
            }
            _ => "barrier values b (those reaching 0 labelled)".to_string(),
        };
        (caption, format!("b [{unit}]"))
    }

    /// Caption and value-axis label of its zoomed row (values shown in mm or mrad).
    fn zoom_text(&self) -> (String, String) {
        let unit = match self.group.map_or("m", KindGroup::unit) {
            "rad" => "mrad",
            _ => "mm",
        };
        let what = match self.group {
            Some(group) if !self.only => format!("{} ", group.title()),
            _ => String::new(),
        };
        (
            format!("the same {what}near b = 0, zoomed (in {unit})"),
            format!("b [{unit}]"),
        )
    }

    /// Title of its legend.
    fn legend_title(&self) -> &'static str {
        match self.group {
            Some(group) if !self.only => group.title(),
            _ => "barriers",
        }
    }
}

/// What one row of panels shows.
#[derive(Clone, Copy, Debug, PartialEq)]
enum RowKind {
    /// Row `k` of q, τ, τ − τ_nom.
    Coordinates(usize),
    /// Barrier row `k`.
    Barriers(usize),
    /// The zoomed row near zero of barrier row `k`.
    Zoom(usize),
}

/// What one figure shows: validated input, shared axis ranges, the time split and the
/// barriers to label.
struct Figure<'a> {
    panels: &'a [(&'a str, &'a Record)],
    set_point: &'a [f64],
    /// Line style of each barrier: colour per barrier of a module within its row, dash
    /// per module.
    barrier_styles: Vec<LineStyle>,
    /// Time window and split point.
    window: (f64, f64),
    split: Option<f64>,
    /// Value ranges of the rows q, τ, τ − τ_nom, shared by all columns.
    rows: [std::ops::Range<f64>; COORDINATE_ROWS],
    /// The rows of barrier panels, top to bottom.
    barrier_rows: Vec<BarrierRow>,
    /// Every row of panels, top to bottom.
    row_kinds: Vec<RowKind>,
    /// Names of the coordinates as shown (`Δx₁`).
    labels: Vec<String>,
    /// Per column, its rows with an invalid state: the two lines its title says of them
    /// and the time spans its panels shade.
    invalid: Vec<invalid::InvalidRows>,
}

/// The values of one series of `record` within the window.
fn windowed(times: &[f64], values: impl Iterator<Item = f64>, window: (f64, f64)) -> Vec<f64> {
    let values: Vec<f64> = values.collect();
    series::window(times, &values, window.0, window.1).1
}

/// The time axis of a figure: its window \[s\] and where it splits, if it does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeAxis {
    /// `(start, end)` \[s\].
    pub window: (f64, f64),
    /// The time \[s\] where the axis splits into the transient and the rest.
    pub split: Option<f64>,
}

/// The time axis the figures of `panels` get with `options`: the window given, else the
/// records' whole time span; the split per [`FigureOptions::split`]. Refuses a window that
/// is empty, not finite or holds no row of some record, and a split outside the window.
pub fn time_axis(
    panels: &[(&str, &Record)],
    options: &FigureOptions,
) -> Result<TimeAxis, PlotError> {
    let mut span = Range::EMPTY;
    for (_, record) in panels {
        span.cover(record.times());
    }
    let window = match options.time_range {
        Some((start, end)) => {
            if !(start.is_finite() && end.is_finite() && start < end) {
                return Err(PlotError::Time(format!(
                    "time range {start}..{end} s: the start must be below the end, both finite"
                )));
            }
            (start, end)
        }
        None => {
            let range = span.exact_or_padded();
            (range.start, range.end)
        }
    };
    let mut settled: Option<f64> = None;
    // The time of the `SPLIT_MIN_ROWS`-th row in the window, over all records.
    let mut enough_rows = window.0;
    for (title, record) in panels {
        let times: Vec<f64> = record.times().collect();
        let clipped_times = series::window(&times, &times, window.0, window.1).0;
        if clipped_times.is_empty() {
            return Err(PlotError::Time(format!(
                "record `{title}` has no rows in the time range {}..{} s",
                window.0, window.1
            )));
        }
        let n = record.columns().n();
        // The tolerance is a fraction of the whole run's motion, so that a window after
        // the motion has settled shows no transient.
        let whole: Vec<Vec<f64>> = (0..n).map(|i| record.q(i).collect()).collect();
        let tolerance = SETTLE_FRACTION * series::excursion(&whole);
        let coordinates: Vec<Vec<f64>> = (0..n)
            .map(|i| windowed(&times, record.q(i), window))
            .collect();
        let row = SPLIT_MIN_ROWS.min(clipped_times.len() - 1);
        enough_rows = enough_rows.max(clipped_times[row]);
        if let Some(time) = series::settle_time(&clipped_times, &coordinates, tolerance) {
            settled = Some(settled.map_or(time, |s| s.max(time)));
        }
    }
    let split = match options.split {
        Split::Off => None,
        Split::At(at) => {
            if !(at.is_finite() && window.0 < at && at < window.1) {
                return Err(PlotError::Time(format!(
                    "split at {at} s: it must lie inside the time range {}..{} s",
                    window.0, window.1
                )));
            }
            Some(at)
        }
        Split::Auto => settled.and_then(|time| {
            let at = window.0 + nice_ceil(time.max(enough_rows) - window.0);
            let length = window.1 - window.0;
            (time > window.0 && at - window.0 <= SPLIT_AT_MOST * length).then_some(at)
        }),
    };

    Ok(TimeAxis { window, split })
}

/// How the barriers of a figure are grouped into rows of panels: per row its group (if
/// known), its barriers, and per barrier its module and colour index within the row.
struct Grouping {
    rows: Vec<(Option<KindGroup>, Vec<usize>)>,
    module: Vec<usize>,
    key: Vec<usize>,
    /// Per row, the name of each colour index.
    key_names: Vec<Vec<String>>,
}

/// The kind group and module (0-based) of each barrier: from the model's barrier table when
/// it has `labels.len()` rows, else from the labels as the table writes them; `None` if
/// some barrier's kind cannot be told.
fn kinds_of(labels: &[String], model: Option<&Model>) -> Option<Vec<(KindGroup, usize)>> {
    if let Some(model) = model
        && model.nb() == labels.len()
    {
        return Some(
            model
                .generated
                .barrier_table()
                .iter()
                .map(|info| (info.kind.group(), info.module))
                .collect(),
        );
    }
    labels
        .iter()
        .map(|label| barrier_label::kind_group(label))
        .collect()
}

impl Grouping {
    /// One row of every barrier, split into modules by `per_module` (the paper's Fig. 4).
    fn single(per_module: &[usize], labels: &[String], group: Option<KindGroup>) -> Grouping {
        let module: Vec<usize> = per_module
            .iter()
            .enumerate()
            .flat_map(|(module, &count)| std::iter::repeat_n(module, count))
            .collect();
        let key: Vec<usize> = per_module.iter().flat_map(|&count| 0..count).collect();
        let most = per_module.iter().copied().max().unwrap_or(0);
        let names = (0..most)
            .map(|k| {
                let j = key.iter().position(|&index| index == k);
                j.and_then(|j| strip_module(&labels[j]))
                    .map_or_else(|| format!("#{}", k + 1), str::to_string)
            })
            .collect();
        Grouping {
            rows: vec![(group, (0..module.len()).collect())],
            module,
            key,
            key_names: vec![names],
        }
    }

    /// One row per kind group present, in the order of [`KIND_GROUPS`]; within a row a
    /// colour per distinct label without its module (`corner 3`, `elongation max`).
    fn by_kind(kinds: &[(KindGroup, usize)], labels: &[String]) -> Grouping {
        let mut grouping = Grouping {
            rows: Vec::new(),
            module: kinds.iter().map(|&(_, module)| module).collect(),
            key: vec![0; kinds.len()],
            key_names: Vec::new(),
        };
        for group in KIND_GROUPS {
            let barriers: Vec<usize> = (0..kinds.len()).filter(|&j| kinds[j].0 == group).collect();
            if barriers.is_empty() {
                continue;
            }
            let mut names: Vec<String> = Vec::new();
            for &j in &barriers {
                let name = labels.get(j).map_or_else(
                    || format!("#{}", j + 1),
                    |label| barrier_label::without_module(label),
                );
                grouping.key[j] = match names.iter().position(|n| *n == name) {
                    Some(k) => k,
                    None => {
                        names.push(name);
                        names.len() - 1
                    }
                };
            }
            grouping.rows.push((Some(group), barriers));
            grouping.key_names.push(names);
        }
        grouping
    }
}

impl<'a> Figure<'a> {
    fn new(
        panels: &'a [(&'a str, &'a Record)],
        set_point: &'a [f64],
        options: &FigureOptions,
    ) -> Result<Figure<'a>, PlotError> {
        let (first_title, first) = panels.first().ok_or(PlotError::NoPanels)?;
        let (n, m) = (first.columns().n(), first.columns().m());
        let mismatch = |title: &str, what, expected, found| PlotError::Mismatch {
            title: title.to_string(),
            what,
            expected,
            found,
        };
        for (title, record) in panels {
            if record.is_empty() {
                return Err(PlotError::EmptyRecord {
                    title: title.to_string(),
                });
            }
            let columns = record.columns();
            if columns.n() != n {
                return Err(mismatch(title, "the number of coordinates", n, columns.n()));
            }
            if columns.m() != m {
                return Err(mismatch(title, "the number of barriers", m, columns.m()));
            }
        }
        if !set_point.is_empty() && set_point.len() != n {
            return Err(mismatch(
                first_title,
                "the set point's length",
                n,
                set_point.len(),
            ));
        }
        let TimeAxis { window, split } = time_axis(panels, options)?;
        let labels = first.columns().barrier_labels();
        let per_module = if !options.barriers_per_module.is_empty() {
            options.barriers_per_module.to_vec()
        } else {
            modules_from_labels(labels).unwrap_or_else(|| default_modules(n, m))
        };
        let total: usize = per_module.iter().sum();
        if total != m {
            return Err(mismatch(
                first_title,
                "the barriers summed over modules",
                m,
                total,
            ));
        }
        let grouping = match kinds_of(labels, options.model) {
            Some(kinds) if kinds.iter().any(|&(g, _)| g != KindGroup::PlateCorner) => {
                Grouping::by_kind(&kinds, labels)
            }
            Some(kinds) if !kinds.is_empty() => {
                Grouping::single(&per_module, labels, Some(KindGroup::PlateCorner))
            }
            _ => Grouping::single(&per_module, labels, None),
        };

        let mut rows = [Range::EMPTY; COORDINATE_ROWS];
        rows[0].cover(set_point.iter().copied());
        rows[2].cover([0.0]);
        // Per record, each barrier's lowest and last finite value in the window.
        let mut lowest = Vec::with_capacity(panels.len());
        let mut ranges = vec![Range::EMPTY; m];
        for (_, record) in panels {
            let times: Vec<f64> = record.times().collect();
            for i in 0..n {
                rows[0].cover(windowed(&times, record.q(i), window));
                rows[1].cover(windowed(&times, record.tau(i), window));
                let action = record.tau(i).zip(record.tau_nom(i)).map(|(a, b)| a - b);
                rows[2].cover(windowed(&times, action, window));
            }
            let mut minima = Vec::with_capacity(m);
            for (j, whole) in ranges.iter_mut().enumerate() {
                let b = windowed(&times, record.b(j), window);
                whole.cover(b.iter().copied());
                let mut range = Range::EMPTY;
                range.cover(b.iter().copied());
                let last = b.iter().rev().copied().find(|v| v.is_finite());
                minima.push((range.low, last));
            }
            lowest.push(minima);
        }
        let only = grouping.rows.len() == 1;
        let barrier_rows = grouping
            .rows
            .into_iter()
            .zip(grouping.key_names)
            .map(|((group, barriers), key_names)| {
                let mut range = Range::EMPTY;
                range.cover([0.0]);
                for &j in &barriers {
                    range.cover([ranges[j].low, ranges[j].high]);
                }
                let row_lowest = barriers
                    .iter()
                    .map(|&j| ranges[j].low)
                    .filter(|v| v.is_finite())
                    .fold(f64::INFINITY, f64::min);
                let zoom = (row_lowest <= ZOOM_HIGH).then(|| {
                    let depth = nice_ceil((-1.05 * row_lowest).clamp(ZOOM_LOW_MIN, ZOOM_LOW_MAX));
                    let depth = depth.min(ZOOM_LOW_MAX);
                    -depth..depth.max(ZOOM_HIGH)
                });
                let range = range.padded();
                let tolerance = ACTIVE_TOLERANCE.max(0.002 * (range.end - range.start));
                let active: Vec<Vec<Active>> = lowest
                    .iter()
                    .map(|minima| {
                        let mut active: Vec<Active> = barriers
                            .iter()
                            .filter_map(|&barrier| {
                                let (low, last) = minima[barrier];
                                (low <= tolerance).then_some(Active {
                                    barrier,
                                    low,
                                    last: last.unwrap_or(low),
                                })
                            })
                            .collect();
                        active.sort_by(|a, b| {
                            b.last.total_cmp(&a.last).then(a.barrier.cmp(&b.barrier))
                        });
                        active
                    })
                    .collect();
                let row_labels: Vec<String> = barriers.iter().map(|&j| labels[j].clone()).collect();
                let grid = LabelGrid::new(&row_labels);
                let mut modules: Vec<usize> =
                    barriers.iter().map(|&j| grouping.module[j]).collect();
                modules.sort_unstable();
                modules.dedup();
                if group.is_none() || only {
                    // The paper's figure: every module of the split, even one without barriers.
                    modules = (0..per_module.len().max(1)).collect();
                }
                BarrierRow {
                    group,
                    only,
                    barriers,
                    modules,
                    key_names,
                    range: room_for_labels(range, &active, grid),
                    active,
                    grid,
                    zoom,
                }
            })
            .collect::<Vec<BarrierRow>>();
        let mut row_kinds: Vec<RowKind> = (0..COORDINATE_ROWS).map(RowKind::Coordinates).collect();
        for (k, row) in barrier_rows.iter().enumerate() {
            row_kinds.push(RowKind::Barriers(k));
            if row.zoom.is_some() {
                row_kinds.push(RowKind::Zoom(k));
            }
        }
        let robot = options.model.map(|model| &model.robot);
        let invalid = panels
            .iter()
            .map(|(_, record)| invalid::InvalidRows::of(record, robot))
            .collect();
        let barrier_styles = (0..m)
            .map(|j| barrier_style(grouping.module[j], grouping.key[j]))
            .collect();
        Ok(Figure {
            panels,
            set_point,
            barrier_styles,
            window,
            split,
            rows: rows.map(Range::padded),
            barrier_rows,
            row_kinds,
            invalid,
            labels: first
                .columns()
                .coordinate_names()
                .iter()
                .map(|name| display_name(name))
                .collect(),
        })
    }

    /// Rows of panels: q, τ, τ − τ_nom, the barrier rows and their zoomed rows.
    fn row_count(&self) -> usize {
        self.row_kinds.len()
    }

    /// Height of the band of column titles \[px\]: with a line for the notes of invalid
    /// states if a column has one.
    fn title_height(&self) -> u32 {
        if self.invalid.iter().any(|rows| rows.count > 0) {
            TITLE_HEIGHT + NOTE_HEIGHT
        } else {
            TITLE_HEIGHT
        }
    }

    fn size(&self) -> (u32, u32) {
        (
            COLUMN_WIDTH * self.panels.len() as u32 + LEGEND_WIDTH,
            self.title_height() + ROW_HEIGHT * self.row_count() as u32,
        )
    }
}

/// Height of the plot of one panel \[px\] (the row less its caption, time labels, margins).
fn plot_height() -> u32 {
    ROW_HEIGHT - CAPTION_HEIGHT - X_LABEL_HEIGHT - 2 * PLOT_MARGIN
}

/// The barrier axis `range` lowered so that, in every panel, the labels of the barriers that
/// reach zero fit in a block (`grid`) below the lowest value of them: below every line.
fn room_for_labels(
    range: std::ops::Range<f64>,
    active: &[Vec<Active>],
    grid: LabelGrid,
) -> std::ops::Range<f64> {
    let mut low = range.start;
    let high = range.end;
    for panel in active {
        let Some(lowest) = panel.iter().map(|a| a.low).reduce(f64::min) else {
            continue;
        };
        // Fraction of the plot height the labels need below `lowest`, with the gap above.
        let block = LABEL_GAP + LABEL_LINE * grid.rows(panel.len()) as u32 + LABEL_LINE / 2;
        let need = block as f64 / plot_height() as f64;
        if need < 0.8 && lowest.is_finite() {
            // (lowest − low') / (high − low') = need.
            low = low.min((lowest - need * high) / (1.0 - need));
        }
    }
    low..high
}

/// The label without its `module K ` prefix (`module 2 corner 6` → `corner 6`), if it has one.
fn strip_module(label: &str) -> Option<&str> {
    let (module, rest) = barrier_label::split_module(label)?;
    (module > 0).then_some(rest)
}

/// How many barriers each module owns, from labels that begin with `module K` (1-based, in
/// non-decreasing order, as the model's barrier table writes them): counts for modules
/// `1..=K_max`. `None` if a label does not begin so, or the modules are out of order.
pub fn modules_from_labels(labels: &[String]) -> Option<Vec<usize>> {
    let mut counts: Vec<usize> = Vec::new();
    for label in labels {
        let (module, _) = barrier_label::split_module(label)?;
        if module < counts.len() {
            return None;
        }
        counts.resize(module, 0);
        counts[module - 1] += 1;
    }
    (!counts.is_empty()).then_some(counts)
}

/// Writes 8-bit RGB `pixels` (row-major, `size` = width × height) as a PNG file.
pub fn write_png(path: &Path, pixels: &[u8], size: (u32, u32)) -> Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| e.to_string())?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), size.0, size.1);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(pixels).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

/// How `m` barriers split into modules when nothing says: evenly over the `n / 3` modules
/// if they divide, else all in one.
fn default_modules(n: usize, m: usize) -> Vec<usize> {
    let modules = n / 3;
    if n.is_multiple_of(3) && modules > 0 && m.is_multiple_of(modules) {
        vec![m / modules; modules]
    } else {
        vec![m]
    }
}

/// Writes every figure of a run into `out_dir` (created if missing) and returns the files:
/// `figure.png` and `figure.svg` ([`draw_figures`] with the stem `figure`); with
/// [`FigureOptions::model`], the 3-D view `robot.png`, `robot.svg` (and `robot.gif` when
/// [`FigureOptions::animate`]) of the same runs. `panels`
/// are the columns, left to right (a title and a record each, all with the same `n` and
/// `m`); `set_point` has `n` values or none. This is the one function `softcbf simulate`,
/// `softcbf run` and `softcbf plot` call, so that a new figure appears in all three.
pub fn write_figures(
    out_dir: &Path,
    panels: &[(&str, &Record)],
    set_point: &[f64],
    options: &FigureOptions,
) -> Result<Vec<PathBuf>, PlotError> {
    let mut written = draw_figures(out_dir, "figure", panels, set_point, options)?;
    if let Some(model) = options.model {
        written.extend(robot_view::draw_robot_views(
            out_dir,
            "robot",
            model,
            panels,
            &robot_view::ViewOptions::default(),
        )?);
        if options.animate {
            written.push(robot_view::animate_robot(
                &out_dir.join("robot.gif"),
                model,
                panels,
                &robot_view::AnimationOptions::default(),
            )?);
        }
    }
    Ok(written)
}

/// Draws `<stem>.png` and `<stem>.svg` in `out_dir` (created if missing) and returns their
/// paths. Rows of panels per column: (a) the coordinates with their set points dotted,
/// (b) the applied `τ`, (c) the filter's action `τ − τ_nom`, (d) the barriers, the ones
/// that reach zero labelled. A robot with barriers beyond its plate corners (kinds from
/// [`FigureOptions::model`]'s barrier table, else from the barrier labels) gets a row of
/// barrier panels per [`KindGroup`] present instead of (d), in the order of
/// [`KIND_GROUPS`], each with its unit and zero line. Coordinates are told apart by
/// [`coordinate_style`]; barriers by colour within a module and dash per module
/// ([`barrier_style`], colours none of the coordinates have). Under a row of barriers
/// one of which comes within [`ZOOM_HIGH`] of zero, a zoomed row shows them near zero in
/// millimetres (milliradians for a bend limit; [`ZOOM_LOW_MIN`]). Every line is cut at the
/// edges of its panel; the times of rows whose state the model cannot use are shaded and
/// the column's title says so ([`invalid`]). The figure is `660·columns + 170` ×
/// `1240 + 299·(rows − 4)` pixels ([`FIGURE_HEIGHT`], [`ROW_HEIGHT`]; rows: q, τ,
/// τ − τ_nom, the barrier rows and their zoomed rows), 36 more with invalid states; the
/// value range of each row is shared by the columns so they compare at a glance, and so
/// is the time axis, split per `options`.
pub fn draw_figures(
    out_dir: &Path,
    stem: &str,
    panels: &[(&str, &Record)],
    set_point: &[f64],
    options: &FigureOptions,
) -> Result<Vec<PathBuf>, PlotError> {
    register_fonts()?;
    let figure = Figure::new(panels, set_point, options)?;
    std::fs::create_dir_all(out_dir).map_err(|source| PlotError::Io {
        dir: out_dir.to_path_buf(),
        source,
    })?;
    let size = figure.size();
    let png = out_dir.join(format!("{stem}.png"));
    let svg = out_dir.join(format!("{stem}.svg"));
    let failed = |file: &Path| {
        let file = file.to_path_buf();
        move |message: String| PlotError::Draw { file, message }
    };
    let mut pixels = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        draw::draw(&root, &figure).map_err(failed(&png))?;
        root.present()
            .map_err(|e| e.to_string())
            .map_err(failed(&png))?;
    }
    write_png(&png, &pixels, size).map_err(failed(&png))?;
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw::draw(&root, &figure).map_err(failed(&svg))?;
        root.present()
            .map_err(|e| e.to_string())
            .map_err(failed(&svg))?;
    }
    Ok(vec![png, svg])
}

/// The column title of a run by its controller as `summary.json` names it (`filter`,
/// `pd`); any other name is shown as it is.
pub fn controller_title(controller: &str) -> &str {
    match controller {
        "filter" => "safety filter (HOCBF-QP)",
        "pd" => "PD+ only",
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_group_barriers_by_kind_with_a_colour_per_name() {
        let labels: Vec<String> = [
            "module 1 corner 1",
            "module 2 corner 1",
            "module 1 bend",
            "module 2 bend",
            "obstacle 1 module 2 centre",
            "obstacle 1 module 1 arc 1",
        ]
        .map(String::from)
        .to_vec();
        let kinds: Vec<(KindGroup, usize)> = labels
            .iter()
            .map(|l| barrier_label::kind_group(l).unwrap())
            .collect();
        let grouping = Grouping::by_kind(&kinds, &labels);
        let rows: Vec<(Option<KindGroup>, Vec<usize>)> = grouping.rows.clone();
        assert_eq!(
            rows,
            [
                (Some(KindGroup::PlateCorner), vec![0, 1]),
                (Some(KindGroup::Bend), vec![2, 3]),
                (Some(KindGroup::Obstacle), vec![4, 5]),
            ]
        );
        assert_eq!(grouping.module, [0, 1, 0, 1, 1, 0]);
        // Same name in two modules: one colour, told apart by the module's dash.
        assert_eq!(grouping.key, [0, 0, 0, 0, 0, 1]);
        assert_eq!(
            grouping.key_names[2],
            ["obstacle 1 centre", "obstacle 1 arc 1"]
        );
    }
}
