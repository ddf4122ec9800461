//! Figures of a run like the paper's Fig. 4 (coordinates, applied τ, barriers), as PNG and
//! SVG, from one record or side by side from several (e.g. safety filter and plain PD+).
//!
//! Text is drawn with DejaVu Sans compiled into the binary (registered once with plotters'
//! `ab_glyph` backend), so a figure comes out byte-identical on any machine: no system
//! font or fontconfig is consulted. Long series are reduced to a min/max envelope per
//! pixel column ([`envelope`]) before drawing, which keeps every extremum visible and the
//! SVG small. The PNG is rendered into memory and encoded with the `png` crate.
//!
//! ```no_run
//! # use softcbf::record::Record;
//! # fn demo(filtered: &Record, plain: &Record) -> Result<(), softcbf::plot::PlotError> {
//! let set_point = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
//! let panels = [("safety filter (HOCBF-QP)", filtered), ("PD+ only", plain)];
//! let files = softcbf::plot::draw_figures("out".as_ref(), "trajectory", &panels, &set_point, &[6, 6])?;
//! assert_eq!(files.len(), 2); // out/trajectory.png, out/trajectory.svg
//! # Ok(()) }
//! ```

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

mod draw;
pub mod robot_view;
mod series;

use plotters::prelude::{BitMapBackend, FontStyle, IntoDrawingArea, SVGBackend};
use plotters::style::register_font;

use crate::record::Record;
use series::Range;
pub use series::{coordinate_labels, envelope};

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
pub const COLUMN_WIDTH: u32 = 620;
/// Width of the legend strip at the right \[px\].
pub const LEGEND_WIDTH: u32 = 160;
/// Height of a figure \[px\].
pub const FIGURE_HEIGHT: u32 = 1000;
/// Height of the column-title band \[px\].
const TITLE_HEIGHT: u32 = 44;

/// Registers the embedded fonts with plotters, once per process.
fn register_fonts() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        let regular = register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok();
        let bold = register_font(FONT, FontStyle::Bold, dejavu::sans::bold()).is_ok();
        regular && bold
    });
    if ok { Ok(()) } else { Err(PlotError::Font) }
}

/// What one figure shows: validated input and shared axis ranges.
struct Figure<'a> {
    panels: &'a [(&'a str, &'a Record)],
    set_point: &'a [f64],
    /// Module of each barrier.
    barrier_module: Vec<usize>,
    modules: usize,
    time: std::ops::Range<f64>,
    /// Value ranges of the rows (q, τ, b), shared by all columns.
    rows: [std::ops::Range<f64>; 3],
    labels: Vec<String>,
}

impl<'a> Figure<'a> {
    fn new(
        panels: &'a [(&'a str, &'a Record)],
        set_point: &'a [f64],
        barriers_per_module: &[usize],
    ) -> Result<Figure<'a>, PlotError> {
        let (_, first) = panels.first().ok_or(PlotError::NoPanels)?;
        let (n, m) = (first.columns().n(), first.columns().m());
        let mismatch = |title: &str, what, expected, found| PlotError::Mismatch {
            title: title.to_string(),
            what,
            expected,
            found,
        };
        let (mut time, mut q, mut tau, mut b) =
            (Range::EMPTY, Range::EMPTY, Range::EMPTY, Range::EMPTY);
        b.cover([0.0]);
        q.cover(set_point.iter().copied());
        for (title, record) in panels {
            if record.is_empty() {
                return Err(PlotError::EmptyRecord {
                    title: title.to_string(),
                });
            }
            if record.columns().n() != n {
                return Err(mismatch(
                    title,
                    "the number of coordinates",
                    n,
                    record.columns().n(),
                ));
            }
            if record.columns().m() != m {
                return Err(mismatch(
                    title,
                    "the number of barriers",
                    m,
                    record.columns().m(),
                ));
            }
            time.cover(record.times());
            for i in 0..n {
                q.cover(record.q(i));
                tau.cover(record.tau(i));
            }
            for j in 0..m {
                b.cover(record.b(j));
            }
        }
        if !set_point.is_empty() && set_point.len() != n {
            return Err(mismatch(
                panels[0].0,
                "the set point's length",
                n,
                set_point.len(),
            ));
        }
        let per_module: Vec<usize> = if barriers_per_module.is_empty() {
            default_modules(n, m)
        } else {
            barriers_per_module.to_vec()
        };
        let total: usize = per_module.iter().sum();
        if total != m {
            return Err(mismatch(
                panels[0].0,
                "the barriers summed over modules",
                m,
                total,
            ));
        }
        let barrier_module = per_module
            .iter()
            .enumerate()
            .flat_map(|(module, &count)| std::iter::repeat_n(module, count))
            .collect();
        let time = time.exact_or_padded();
        Ok(Figure {
            panels,
            set_point,
            barrier_module,
            modules: per_module.len(),
            time,
            rows: [q.padded(), tau.padded(), b.padded()],
            labels: coordinate_labels(n),
        })
    }

    /// Index of barrier `j` within its module.
    fn barrier_index(&self, j: usize) -> usize {
        self.barrier_module[..j]
            .iter()
            .filter(|&&module| module == self.barrier_module[j])
            .count()
    }

    fn size(&self) -> (u32, u32) {
        (
            COLUMN_WIDTH * self.panels.len() as u32 + LEGEND_WIDTH,
            FIGURE_HEIGHT,
        )
    }
}
/// Writes 8-bit RGB `pixels` (row-major, `size` = width × height) as a PNG file.
fn write_png(path: &Path, pixels: &[u8], size: (u32, u32)) -> Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| e.to_string())?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), size.0, size.1);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(pixels).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

/// How `m` barriers split into modules when the caller does not say: evenly over the
/// `n / 3` modules if they divide, else all in one.
fn default_modules(n: usize, m: usize) -> Vec<usize> {
    let modules = n / 3;
    if n.is_multiple_of(3) && modules > 0 && m.is_multiple_of(modules) {
        vec![m / modules; modules]
    } else {
        vec![m]
    }
}

/// Draws `<stem>.png` and `<stem>.svg` in `out_dir` (created if missing) and returns their
/// paths. `panels` are the columns, left to right, each a title and its record (all with
/// the same `n` and `m`); `set_point` (n values, or empty for none) is drawn dashed in the
/// colour of its coordinate; `barriers_per_module` gives how the `m` barriers split into
/// modules, in order (empty: evenly over the `n/3` modules if that divides `m`, else
/// one module); module 1 is drawn solid, module 2 dashed, further modules in other dashes.
/// The figure is `620·columns + 160` × 1000 pixels; the y range of each row of panels is
/// shared by the columns so they compare at a glance.
pub fn draw_figures(
    out_dir: &Path,
    stem: &str,
    panels: &[(&str, &Record)],
    set_point: &[f64],
    barriers_per_module: &[usize],
) -> Result<Vec<PathBuf>, PlotError> {
    register_fonts()?;
    let figure = Figure::new(panels, set_point, barriers_per_module)?;
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
