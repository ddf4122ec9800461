//! Integration tests of the figures: files written, PNG of the documented size with the
//! lines drawn, SVG with the titles and the labels of the barriers that reach zero,
//! byte-identical output, distinct line styles, the split time axis, edge cases (one row,
//! NaN rows, constant series), the min/max envelope, and `softcbf plot`'s library part
//! (redrawing from the files `simulate` writes).

use std::path::{Path, PathBuf};

use rand::RngExt;
use softcbf::plot::{
    COLUMN_WIDTH, DISTINCT_COORDINATES, FIGURE_HEIGHT, FigureOptions, LEGEND_WIDTH, PlotError,
    ROW_HEIGHT, Split, TimeAxis, ZOOM_HIGH, barrier_style, coordinate_style, display_name,
    draw_figures, envelope, modules_from_labels, nice_ceil, settle_time, time_axis, window,
    write_figures,
};
use softcbf::record::{Columns, Record, Row};

/// The paper's simulation set point (docs/model.md §7).
const SET_POINT: [f64; 6] = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];

fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("plot-tests")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The paper robot's columns: `dx1 … dL2`, barriers `module 1 corner 1 … module 2 corner 6`.
fn paper_columns(extra: &[&str]) -> Columns {
    let labels: Vec<String> = (0..12)
        .map(|j| format!("module {} corner {}", j / 6 + 1, j % 6 + 1))
        .collect();
    let coordinates = softcbf::record::coordinate_names(6);
    Columns::named(
        &softcbf::record::as_strs(&coordinates),
        &softcbf::record::as_strs(&labels),
        extra,
    )
    .unwrap()
}

/// Draws `panels` with the default options into `dir` as `<stem>.png`/`.svg`.
fn draw(
    dir: &Path,
    stem: &str,
    panels: &[(&str, &Record)],
    set_point: &[f64],
) -> Result<Vec<PathBuf>, PlotError> {
    draw_figures(dir, stem, panels, set_point, &FigureOptions::default())
}

/// Barriers of one module (docs/model.md §3) for the paper's geometry: corner heights above
/// the bottom plate minus the margin.
fn module_barriers(q: &[f64]) -> [f64; 6] {
    let (l0, d, r, margin) = (0.1, 0.04, 0.05, 0.005);
    let theta = q[0].hypot(q[1]) / d;
    let sinc = if theta < 1e-8 {
        1.0
    } else {
        theta.sin() / theta
    };
    std::array::from_fn(|j| {
        let phi = j as f64 * std::f64::consts::PI / 3.0;
        sinc * (l0 + q[2] - r / d * (q[0] * phi.cos() + q[1] * phi.sin())) - margin
    })
}

/// Largest `s ∈ [0, 1]` with every barrier of `s · target` non-negative (bisection).
fn safe_fraction(target: &[f64]) -> f64 {
    let safe = |s: f64| {
        let q: Vec<f64> = target.iter().map(|v| s * v).collect();
        module_barriers(&q).iter().all(|&b| b >= 0.0)
    };
    if safe(1.0) {
        return 1.0;
    }
    let (mut low, mut high) = (0.0, 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (low + high);
        if safe(mid) { low = mid } else { high = mid }
    }
    low
}

/// A synthetic run resembling the paper's Fig. 4: each module moves toward its part of
/// the set point along a critically damped path; with `filtered` it stops where its first
/// corner reaches the margin, without it goes all the way (barriers below zero).
fn synthetic_run(filtered: bool) -> Record {
    let (rate, seconds) = (1000.0, 10.0);
    let rows = (rate * seconds) as usize + 1;
    let mut record = Record::for_columns(paper_columns(&[]), rows);
    let stiffness = [6250.0, 6250.0, 10.0, 6250.0, 6250.0, 10.0];
    let limits: Vec<f64> = SET_POINT
        .chunks(3)
        .map(|target| if filtered { safe_fraction(target) } else { 1.0 })
        .collect();
    let (mut q, mut qd, mut tau, mut tau_nom) = ([0.0; 6], [0.0; 6], [0.0; 6], [0.0; 6]);
    let mut b = [0.0; 12];
    for k in 0..rows {
        let t = k as f64 / rate;
        let x = t / 0.6;
        let s = 1.0 - (-x).exp() * (1.0 + x);
        let sd = x * (-x).exp() / 0.6;
        for i in 0..6 {
            let limit = limits[i / 3];
            let (fraction, rate) = if s < limit { (s, sd) } else { (limit, 0.0) };
            q[i] = fraction * SET_POINT[i];
            qd[i] = rate * SET_POINT[i];
            tau_nom[i] = stiffness[i] * q[i] + 5.0 * (SET_POINT[i] - q[i]) - qd[i];
            tau[i] = if s < limit {
                tau_nom[i]
            } else {
                stiffness[i] * q[i]
            };
        }
        b[..6].copy_from_slice(&module_barriers(&q[..3]));
        b[6..].copy_from_slice(&module_barriers(&q[3..]));
        record
            .push_row(&Row {
                t,
                q: &q,
                qd: &qd,
                tau: &tau,
                tau_nom: &tau_nom,
                b: &b,
                extra: &[],
            })
            .unwrap();
    }
    record
}

/// Width, height and RGBA pixels of a PNG file.
fn decode_png(path: &Path) -> (u32, u32, Vec<[u8; 4]>) {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let decoder = png::Decoder::new(file);
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![
        0;
        reader
            .output_buffer_size()
            .expect("PNG size fits in memory")
    ];
    let info = reader.next_frame(&mut buffer).unwrap();
    let channels = info.color_type.samples();
    let pixels = buffer[..info.buffer_size()]
        .chunks(channels)
        .map(|p| match channels {
            3 => [p[0], p[1], p[2], 255],
            4 => [p[0], p[1], p[2], p[3]],
            _ => [p[0], p[0], p[0], 255],
        })
        .collect();
    (info.width, info.height, pixels)
}

#[test]
fn coordinate_names_are_shown_as_in_the_paper() {
    assert_eq!(
        ["dx1", "dy1", "dL1", "dx2", "dy2", "dL2"].map(display_name),
        ["Δx₁", "Δy₁", "δL₁", "Δx₂", "Δy₂", "δL₂"]
    );
    assert_eq!(display_name("dx11"), "Δx₁₁");
    // Any other name as it is.
    for name in ["q1", "dx", "dxa", "x", "dL1b"] {
        assert_eq!(display_name(name), name);
    }
}

#[test]
fn nine_and_more_coordinates_get_distinct_styles() {
    let styles: Vec<_> = (0..DISTINCT_COORDINATES).map(coordinate_style).collect();
    for (a, first) in styles.iter().enumerate() {
        for (b, second) in styles.iter().enumerate().skip(a + 1) {
            assert_ne!(first, second, "coordinates {a} and {b} look alike");
        }
    }
    const { assert!(DISTINCT_COORDINATES >= 12) };
    // The three-square robot's nine coordinates: nine colours, all solid.
    let colours: std::collections::HashSet<_> =
        (0..9).map(|k| coordinate_style(k).colour).collect();
    assert_eq!(colours.len(), 9);
    assert!((0..9).all(|k| coordinate_style(k).dash.is_none()));
    // Barriers: a colour per barrier of a module, a dash per module.
    let mut barrier_styles = std::collections::HashSet::new();
    for module in 0..4 {
        for index in 0..8 {
            assert!(
                barrier_styles.insert(barrier_style(module, index)),
                "{module} {index}"
            );
        }
    }
}

#[test]
fn window_settle_time_and_nice_steps() {
    // The part in the window, with the edges interpolated.
    let t = [0.0, 1.0, 2.0, 3.0];
    let y = [0.0, 10.0, 20.0, 30.0];
    assert_eq!(
        window(&t, &y, 0.5, 2.5),
        (vec![0.5, 1.0, 2.0, 2.5], vec![5.0, 10.0, 20.0, 25.0])
    );
    assert_eq!(window(&t, &y, 1.0, 2.0), (vec![1.0, 2.0], vec![10.0, 20.0]));
    assert_eq!(window(&t, &y, 1.2, 1.4), (vec![1.2, 1.4], vec![12.0, 14.0]));
    assert_eq!(window(&t, &y, 5.0, 6.0), (vec![], vec![]));
    // Settling: the last time a coordinate is further than the tolerance from its end.
    let t: Vec<f64> = (0..=100).map(|k| k as f64 * 0.1).collect();
    let fast: Vec<f64> = t.iter().map(|&s| 1.0 - (-3.0 * s).exp()).collect();
    let still = vec![0.5; t.len()];
    // Within 0.05 of the end (1 − e^(−3t) at 10 s): after t = ln(20)/3 ≈ 0.999 s.
    let settled = settle_time(&t, &[fast.clone(), still.clone()], 0.05).unwrap();
    assert!((settled - 0.9).abs() < 1e-12, "{settled}");
    assert_eq!(
        settle_time(&t, std::slice::from_ref(&fast), 0.5).unwrap(),
        0.2
    );
    assert_eq!(settle_time(&t, &[still], 0.05), Some(0.0));
    assert_eq!(settle_time(&t, &[vec![f64::NAN; t.len()]], 0.05), None);
    assert_eq!(settle_time(&[], &[], 0.05), None);
    let mut noisy = fast;
    noisy[95] = f64::NAN;
    assert_eq!(settle_time(&t, &[noisy], 0.05), Some(settled));
    for (x, up) in [
        (0.93, 1.0),
        (1.04, 1.5),
        (1.6, 2.0),
        (2.2, 2.5),
        (7.0, 8.0),
        (0.012, 0.015),
        (80.0, 80.0),
        (81.0, 100.0),
    ] {
        assert!((nice_ceil(x) - up).abs() < 1e-12, "{x} → {}", nice_ceil(x));
    }
}

#[test]
fn modules_come_from_the_labels() {
    let labels = |list: &[&str]| list.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert_eq!(
        modules_from_labels(&labels(&[
            "module 1 corner 1",
            "module 1 corner 2",
            "module 2 corner 1"
        ])),
        Some(vec![2, 1])
    );
    assert_eq!(
        modules_from_labels(&labels(&["module 2 corner 1"])),
        Some(vec![0, 1])
    );
    assert_eq!(
        modules_from_labels(&labels(&["module 2 a", "module 1 b"])),
        None
    );
    assert_eq!(modules_from_labels(&labels(&["barrier 1"])), None);
    assert_eq!(modules_from_labels(&labels(&["module 0 x"])), None);
    assert_eq!(modules_from_labels(&labels(&["module 12x"])), None);
    assert_eq!(modules_from_labels(&[]), None);
}

#[test]
fn envelope_keeps_extrema_and_bounds_the_points() {
    let mut rng = softcbf_tests::rng(11);
    for _ in 0..50 {
        let len = rng.random_range(1..5000usize);
        let buckets = rng.random_range(1..700usize);
        let t: Vec<f64> = (0..len).map(|k| k as f64 * 1e-3).collect();
        let y: Vec<f64> = (0..len)
            .map(|k| (k as f64 * 0.01).sin() + rng.random_range(-0.1..0.1))
            .collect();
        let segments = envelope(&t, &y, t[0], t[len - 1], buckets);
        assert_eq!(segments.len(), 1);
        let kept = &segments[0];
        assert!(kept.len() <= 2 * buckets && kept.len() <= len);
        assert!(
            kept.windows(2).all(|w| w[0].0 < w[1].0),
            "times must increase"
        );
        let min = y.iter().copied().fold(f64::INFINITY, f64::min);
        let max = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!(kept.iter().any(|p| p.1 == min) && kept.iter().any(|p| p.1 == max));
        // Every kept point is a point of the series.
        assert!(kept.iter().all(|p| y[(p.0 * 1e3).round() as usize] == p.1));
        // The first and last buckets' extremes are the series' there (a short series is kept whole).
        if len <= buckets {
            assert_eq!(kept.len(), len);
        }
    }
    // Non-finite values split the series.
    let t = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
    let y = [1.0, 2.0, f64::NAN, 3.0, f64::INFINITY, 4.0];
    assert_eq!(
        envelope(&t, &y, 0.0, 5.0, 100),
        vec![
            vec![(0.0, 1.0), (1.0, 2.0)],
            vec![(3.0, 3.0)],
            vec![(5.0, 4.0)]
        ]
    );
}

#[test]
fn figures_are_drawn_with_both_columns() {
    let filtered = synthetic_run(true);
    let plain = synthetic_run(false);
    // The synthetic runs are what they claim: barriers held with the filter, crossed without.
    let min_b = |r: &Record| (0..12).flat_map(|j| r.b(j)).fold(f64::INFINITY, f64::min);
    assert!(min_b(&filtered) >= 0.0 && min_b(&filtered) < 1e-6);
    assert!(min_b(&plain) < -0.01);

    let dir = out_dir("compare");
    let panels = [
        ("safety filter (HOCBF-QP)", &filtered),
        ("PD+ only", &plain),
    ];
    let files = draw(&dir, "trajectory", &panels, &SET_POINT).unwrap();
    assert_eq!(
        files,
        [dir.join("trajectory.png"), dir.join("trajectory.svg")]
    );

    let (width, height, pixels) = decode_png(&files[0]);
    // Barriers reach zero: a zoomed row near zero under the barrier row.
    assert_eq!(
        (width, height),
        (2 * COLUMN_WIDTH + LEGEND_WIDTH, FIGURE_HEIGHT + ROW_HEIGHT)
    );
    assert_eq!((width, height), (1490, 1539));
    // The lines are there: many pixels in the first palette colour (Δx₁, corner 1) and
    // the background is white.
    let blue = pixels.iter().filter(|p| **p == [0, 114, 178, 255]).count();
    let white = pixels
        .iter()
        .filter(|p| **p == [255, 255, 255, 255])
        .count();
    assert!(blue > 2000, "only {blue} pixels of the first line colour");
    assert!(white > pixels.len() / 2);

    let svg = std::fs::read_to_string(&files[1]).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("width=\"1490\"") && svg.contains("height=\"1539\""));
    for text in [
        "safety filter (HOCBF-QP)",
        "PD+ only",
        "(a) generalized coordinates q",
        "(c) filter action τ − τ_nom",
        "(e) the same near b = 0, zoomed (in mm)",
        "(i) barrier values b",
        "t [s]",
        "τ − τ_nom [N]",
        "Δx₁",
        "δL₂",
        "corner 6",
        "module 2",
        "\nset point\n",
    ] {
        assert!(svg.contains(text), "SVG lacks `{text}`");
    }
    // The barriers that reach zero are labelled by their full labels (the legend says only
    // `corner k`); the filtered run's stay ≥ 0 and touch, the plain run's cross.
    // (Plotters writes a text on its own line.)
    let lowest = |j| min_of(filtered.b(j)).min(min_of(plain.b(j)));
    let reaching: Vec<usize> = (0..12).filter(|&j| lowest(j) <= 1e-4).collect();
    let away: Vec<usize> = (0..12).filter(|&j| lowest(j) > 0.01).collect();
    assert!(
        !reaching.is_empty() && !away.is_empty(),
        "{reaching:?} {away:?}"
    );
    for j in 0..12 {
        let label = format!("\nmodule {} corner {}\n", j / 6 + 1, j % 6 + 1);
        if reaching.contains(&j) {
            assert!(svg.contains(&label), "{label} is not labelled");
        }
        if away.contains(&j) {
            assert!(!svg.contains(&label), "{label} is labelled");
        }
    }
    assert!(svg.len() < 4_000_000, "SVG is {} bytes", svg.len());
}

#[test]
fn figures_are_byte_identical_when_drawn_twice() {
    let filtered = synthetic_run(true);
    let plain = synthetic_run(false);
    let panels = [
        ("safety filter (HOCBF-QP)", &filtered),
        ("PD+ only", &plain),
    ];
    let first = draw(&out_dir("twice-1"), "fig", &panels, &SET_POINT).unwrap();
    let second = draw(&out_dir("twice-2"), "fig", &panels, &SET_POINT).unwrap();
    for (a, b) in first.iter().zip(&second) {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{} differs",
            a.display()
        );
    }
}

fn min_of(values: impl Iterator<Item = f64>) -> f64 {
    values.fold(f64::INFINITY, f64::min)
}

#[test]
fn one_column_and_bad_input() {
    let run = synthetic_run(true);
    let dir = out_dir("single");
    let files = write_figures(
        &dir,
        &[("safety filter (HOCBF-QP)", &run)],
        &[],
        &FigureOptions::default(),
    )
    .unwrap();
    assert_eq!(files, [dir.join("figure.png"), dir.join("figure.svg")]);
    let (width, height, _) = decode_png(&files[0]);
    assert_eq!(
        (width, height),
        (COLUMN_WIDTH + LEGEND_WIDTH, FIGURE_HEIGHT + ROW_HEIGHT)
    );

    let empty = Record::with_capacity(6, 12, &[], 0).unwrap();
    let mut small = Record::with_capacity(3, 6, &[], 1).unwrap();
    let z = [0.0; 6];
    let row = Row {
        t: 0.0,
        q: &z[..3],
        qd: &z[..3],
        tau: &z[..3],
        tau_nom: &z[..3],
        b: &z,
        extra: &[],
    };
    small.push_row(&row).unwrap();
    let dir = out_dir("bad");
    let error_with = |panels: &[(&str, &Record)], set_point: &[f64], options: &FigureOptions| {
        draw_figures(&dir, "x", panels, set_point, options).unwrap_err()
    };
    let error = |panels: &[(&str, &Record)], set_point: &[f64], modules: &[usize]| {
        let options = FigureOptions {
            barriers_per_module: modules,
            ..FigureOptions::default()
        };
        error_with(panels, set_point, &options)
    };
    assert!(matches!(error(&[], &[], &[]), PlotError::NoPanels));
    assert!(matches!(
        error(&[("e", &empty)], &[], &[]),
        PlotError::EmptyRecord { .. }
    ));
    assert!(matches!(
        error(&[("a", &run), ("b", &small)], &[], &[]),
        PlotError::Mismatch {
            what: "the number of coordinates",
            ..
        }
    ));
    assert!(matches!(
        error(&[("a", &run)], &[0.0; 5], &[]),
        PlotError::Mismatch {
            expected: 6,
            found: 5,
            ..
        }
    ));
    let message = error(&[("a", &run)], &[], &[6, 5]).to_string();
    assert_eq!(
        message,
        "record `a`: the barriers summed over modules is 11, expected 12"
    );
    let time = |time_range, split| {
        let options = FigureOptions {
            time_range,
            split,
            ..FigureOptions::default()
        };
        error_with(&[("a", &run)], &[], &options).to_string()
    };
    assert_eq!(
        time(Some((2.0, 1.0)), Split::Auto),
        "time range 2..1 s: the start must be below the end, both finite"
    );
    assert_eq!(
        time(Some((0.0, f64::NAN)), Split::Auto),
        "time range 0..NaN s: the start must be below the end, both finite"
    );
    assert_eq!(
        time(Some((20.0, 30.0)), Split::Auto),
        "record `a` has no rows in the time range 20..30 s"
    );
    assert_eq!(
        time(None, Split::At(12.0)),
        "split at 12 s: it must lie inside the time range 0..10 s"
    );
}

/// The time axis splits where the motion settles, rounded up, and only when the transient
/// is short; it can be forced or switched off; a window restricts it.
#[test]
fn time_axis_splits_after_the_transient() {
    let filtered = synthetic_run(true);
    let plain = synthetic_run(false);
    let panels = [("f", &filtered), ("p", &plain)];
    let axis = |time_range, split| {
        time_axis(
            &panels,
            &FigureOptions {
                time_range,
                split,
                ..FigureOptions::default()
            },
        )
        .unwrap()
    };
    // The synthetic runs move along 1 − e^(−x)(1 + x), x = t/0.6: within 5 % after ≈ 2.8 s.
    let auto = axis(None, Split::Auto);
    assert_eq!(auto.window, (0.0, 10.0));
    assert_eq!(auto.split, Some(3.0));
    assert_eq!(
        axis(None, Split::Off),
        TimeAxis {
            window: (0.0, 10.0),
            split: None
        }
    );
    assert_eq!(axis(None, Split::At(1.5)).split, Some(1.5));
    // Within the first 4 s the transient takes most of the window: no split.
    assert_eq!(
        axis(Some((0.0, 4.0)), Split::Auto),
        TimeAxis {
            window: (0.0, 4.0),
            split: None
        }
    );
    // A window after the motion has settled: nothing to split.
    assert_eq!(axis(Some((5.0, 10.0)), Split::Auto).split, None);

    // The figures differ with and without the split, and the split one is drawn.
    let dir = out_dir("split");
    let with = write_figures(
        &dir.join("auto"),
        &panels,
        &SET_POINT,
        &FigureOptions::default(),
    )
    .unwrap();
    let off = FigureOptions {
        split: Split::Off,
        ..FigureOptions::default()
    };
    let without = write_figures(&dir.join("off"), &panels, &SET_POINT, &off).unwrap();
    assert_ne!(
        std::fs::read(&with[0]).unwrap(),
        std::fs::read(&without[0]).unwrap()
    );
    let window = FigureOptions {
        time_range: Some((0.0, 1.0)),
        ..FigureOptions::default()
    };
    write_figures(&dir.join("window"), &panels, &SET_POINT, &window).unwrap();
}

/// A record of `rows` rows (t = 0, 0.01, …) whose every series is given by `value(k, column)`.
fn record_of(rows: usize, value: impl Fn(usize, usize) -> f64) -> Record {
    let mut record = Record::for_columns(paper_columns(&["read [us]"]), rows);
    for k in 0..rows {
        let v: Vec<f64> = (0..50).map(|c| value(k, c)).collect();
        record
            .push_row(&Row {
                t: k as f64 * 0.01,
                q: &v[0..6],
                qd: &v[6..12],
                tau: &v[12..18],
                tau_nom: &v[18..24],
                b: &v[24..36],
                extra: &v[36..37],
            })
            .unwrap();
    }
    record
}

/// Degenerate records are drawn without a panic: one row, constant series, zero series,
/// a column all NaN, rows all NaN but the time, huge values.
#[test]
fn edge_cases_are_drawn() {
    let cases = [
        ("one-row", record_of(1, |_, c| c as f64 * 1e-3)),
        ("constant", record_of(50, |_, _| 0.02)),
        ("zero", record_of(50, |_, _| 0.0)),
        (
            "nan-column",
            record_of(50, |k, c| if c == 3 { f64::NAN } else { k as f64 * 1e-3 }),
        ),
        (
            "nan-rows",
            record_of(50, |k, _| {
                if k % 7 == 3 {
                    f64::NAN
                } else {
                    (k as f64).sin()
                }
            }),
        ),
        ("all-nan", record_of(20, |_, _| f64::NAN)),
        (
            "huge",
            record_of(30, |k, c| if c == 14 { 1e300 * k as f64 } else { -1e-300 }),
        ),
    ];
    for (name, record) in &cases {
        let dir = out_dir(&format!("edge-{name}"));
        let files = write_figures(
            &dir,
            &[(name, record)],
            &[0.01; 6],
            &FigureOptions::default(),
        )
        .unwrap_or_else(|e| panic!("{name}: {e}"));
        let (width, height, _) = decode_png(&files[0]);
        // A zoomed row near zero when a barrier comes within ZOOM_HIGH of it.
        let lowest = (0..record.columns().m())
            .flat_map(|j| record.b(j))
            .filter(|b| b.is_finite())
            .fold(f64::INFINITY, f64::min);
        let zoom = if lowest <= ZOOM_HIGH { ROW_HEIGHT } else { 0 };
        assert_eq!(
            (width, height),
            (COLUMN_WIDTH + LEGEND_WIDTH, FIGURE_HEIGHT + zoom),
            "{name}"
        );
    }
}

#[test]
fn a_hardware_log_with_gaps_is_drawn() {
    // 33 Hz for 5 s with the hardware run's extra columns; a failed tick leaves NaN in τ
    // and one reading is infinite: the figure is still drawn from the finite values.
    let mut record = Record::for_columns(paper_columns(&["loop [us]", "overrun", "clamps"]), 166);
    for k in 0..166 {
        let t = k as f64 / 33.0;
        let q = [
            0.0,
            0.0,
            -0.15 * (1.0 - (-t).exp()),
            0.0,
            -0.065 * (1.0 - (-t).exp()),
            0.0,
        ];
        let tau = if k == 40 {
            [f64::NAN; 6]
        } else {
            [1.0, -1.0, 0.5 * t, 0.0, 0.2, -0.3]
        };
        let mut b = [0.0; 12];
        b[..6].copy_from_slice(&module_barriers(&q[..3]));
        b[6..].copy_from_slice(&module_barriers(&q[3..]));
        if k == 80 {
            b[3] = f64::INFINITY;
        }
        let extra = [850.0, 0.0, (k / 50) as f64];
        let row = Row {
            t,
            q: &q,
            qd: &[0.0; 6],
            tau: &tau,
            tau_nom: &tau,
            b: &b,
            extra: &extra,
        };
        record.push_row(&row).unwrap();
    }
    let dir = out_dir("hardware");
    let files = draw(
        &dir,
        "run",
        &[("HOCBF-QP, 33 Hz", &record)],
        &[0.0, 0.0, -0.15, 0.0, -0.065, 0.0],
    )
    .unwrap();
    let (width, height, _) = decode_png(&files[0]);
    assert_eq!(
        (width, height),
        (COLUMN_WIDTH + LEGEND_WIDTH, FIGURE_HEIGHT + ROW_HEIGHT)
    );
    assert!(
        std::fs::read_to_string(&files[1])
            .unwrap()
            .contains("HOCBF-QP, 33 Hz")
    );
}

/// `simulate`'s outputs for the paper scenario shortened to `seconds`, written into `dir`:
/// `trajectory.csv`, `trajectory_pd.csv`, `summary.json`, `figure.png`, `figure.svg`, the
/// 3-D view `robot.png`, `robot.svg`.
fn simulate_into(dir: &Path, seconds: f64) {
    use softcbf::model::Model;
    use softcbf::robot_file::load_robot;
    use softcbf::scenario::ScenarioFile;
    use softcbf::sim::simulate;
    let model = Model::new(load_robot(None).unwrap()).unwrap();
    let mut scenario = ScenarioFile::paper_sim().resolve(&model).unwrap();
    scenario.duration = seconds;
    let main = simulate(&model, &scenario, true, &mut |_| {}).unwrap();
    let pd = simulate(&model, &scenario, false, &mut |_| {}).unwrap();
    softcbf::output::write_outputs(dir, &main, Some(&pd), &model, false).unwrap();
}

/// `softcbf plot`'s library part: the figures `simulate` drew come back from its files,
/// the same bytes; titles and set point from `summary.json`; errors name the file.
#[test]
fn figures_are_redrawn_from_the_files() {
    use softcbf::replot::{ReplotError, replot};
    let dir = out_dir("replot");
    simulate_into(&dir, 0.5);
    let figures = [dir.join("figure.png"), dir.join("figure.svg")];
    let drawn: Vec<Vec<u8>> = figures.iter().map(|f| std::fs::read(f).unwrap()).collect();
    for figure in &figures {
        std::fs::remove_file(figure).unwrap();
    }
    let files = [dir.join("trajectory.csv"), dir.join("trajectory_pd.csv")];
    let written = replot(&files, None, None, &FigureOptions::default()).unwrap();
    assert_eq!(written, figures);
    // The same figure as `simulate` drew: titles and set point from summary.json.
    for (figure, bytes) in figures.iter().zip(&drawn) {
        assert!(
            std::fs::read(figure).unwrap() == *bytes,
            "{} differs",
            figure.display()
        );
    }

    // One file, elsewhere, without a summary: one column titled by the file name.
    let alone = out_dir("replot-alone");
    std::fs::create_dir_all(&alone).unwrap();
    let copy = alone.join("run-7.csv");
    std::fs::copy(&files[1], &copy).unwrap();
    let written = replot(
        std::slice::from_ref(&copy),
        None,
        None,
        &FigureOptions::default(),
    )
    .unwrap();
    let (width, _, _) = decode_png(&written[0]);
    assert_eq!(width, COLUMN_WIDTH + LEGEND_WIDTH);
    let svg = std::fs::read_to_string(&written[1]).unwrap();
    assert!(svg.contains("\nrun-7.csv\n") && !svg.contains("\nset point\n"));
    // The same file twice: the columns are told apart by their paths.
    let out = alone.join("twice");
    let written = replot(
        &[copy.clone(), copy.clone()],
        Some(&out),
        None,
        &FigureOptions::default(),
    )
    .unwrap();
    assert_eq!(written[0], out.join("figure.png"));

    // Errors name the file (and the line).
    let message = |files: &[PathBuf]| {
        replot(files, Some(&alone), None, &FigureOptions::default())
            .unwrap_err()
            .to_string()
    };
    assert!(matches!(
        replot(&[], None, None, &FigureOptions::default()),
        Err(ReplotError::NoFiles)
    ));
    let missing = alone.join("missing.csv");
    assert!(message(std::slice::from_ref(&missing)).starts_with(&missing.display().to_string()));
    let broken = alone.join("broken.csv");
    let text = std::fs::read_to_string(&copy).unwrap();
    let mut lines: Vec<&str> = text.lines().take(5).collect();
    lines.push("0.1,oops");
    std::fs::write(&broken, lines.join("\n")).unwrap();
    let header_fields = text.lines().next().unwrap().split(',').count();
    assert_eq!(
        message(std::slice::from_ref(&broken)),
        format!(
            "{}:6: 2 fields, the header has {header_fields}",
            broken.display()
        )
    );
    let three = alone.join("three.csv");
    Record::with_capacity(9, 12, &[], 0)
        .unwrap()
        .write_csv(&three)
        .unwrap();
    assert_eq!(
        message(&[copy.clone(), three.clone()]),
        format!(
            "{}: 9 coordinates, but {} has 6",
            three.display(),
            copy.display()
        )
    );
    std::fs::write(
        alone.join("summary.json"),
        "{\n  \"controller\": \"pd\",\n  oops\n}\n",
    )
    .unwrap();
    let summary = message(std::slice::from_ref(&copy));
    assert!(
        summary.starts_with(&format!("{}:3: ", alone.join("summary.json").display())),
        "{summary}"
    );
    std::fs::write(
        alone.join("summary.json"),
        r#"{"controller": "pd", "set_point": "high"}"#,
    )
    .unwrap();
    assert!(
        message(std::slice::from_ref(&copy))
            .ends_with("field `set_point`: expected an array of numbers")
    );
}

/// A log written before the columns were named (and before every module had its limit
/// barriers): drawn with numbered barriers, and with the robot file's labels and modules
/// when one is given.
#[test]
fn old_logs_are_redrawn_with_the_robots_labels() {
    use softcbf::model::Model;
    use softcbf::replot::replot;
    use softcbf::robot_file::load_robot;
    let dir = out_dir("replot-old");
    std::fs::create_dir_all(&dir).unwrap();
    let run = synthetic_run(true);
    let mut old = format!(
        "t,{},{},{},{},{}\n",
        (0..6)
            .map(|i| format!("q{i}"))
            .collect::<Vec<_>>()
            .join(","),
        (0..6)
            .map(|i| format!("qd{i}"))
            .collect::<Vec<_>>()
            .join(","),
        (0..6)
            .map(|i| format!("tau{i}"))
            .collect::<Vec<_>>()
            .join(","),
        (0..6)
            .map(|i| format!("taunom{i}"))
            .collect::<Vec<_>>()
            .join(","),
        (0..12)
            .map(|j| format!("b{j}"))
            .collect::<Vec<_>>()
            .join(",")
    );
    let mut new = Vec::new();
    run.write_csv_to(&mut new).unwrap();
    for line in String::from_utf8(new).unwrap().lines().skip(1) {
        old += line;
        old += "\n";
    }
    let path = dir.join("old.csv");
    std::fs::write(&path, old).unwrap();
    let svg = |files: &[PathBuf]| std::fs::read_to_string(&files[1]).unwrap();
    let plain = replot(
        std::slice::from_ref(&path),
        Some(&dir.join("plain")),
        None,
        &FigureOptions::default(),
    )
    .unwrap();
    assert!(svg(&plain).contains("\nbarrier 1\n"), "numbered labels");
    let model = Model::new(load_robot(None).unwrap()).unwrap();
    let named = replot(
        std::slice::from_ref(&path),
        Some(&dir.join("named")),
        Some(&model),
        &FigureOptions::default(),
    )
    .unwrap();
    let text = svg(&named);
    assert!(text.contains("\nmodule 1 corner 1\n") && !text.contains("\nbarrier 1\n"));
    // The log predates the domain's limit rows of every module: they are computed from its
    // coordinates and drawn in their own rows.
    assert!(text.contains("elongation limits") && text.contains("bend limits"));
    // A robot of another size is refused, naming the file and the robot.
    let three = Model::new(
        load_robot(Some(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/three-square.toml"),
        ))
        .unwrap(),
    )
    .unwrap();
    let error = replot(
        std::slice::from_ref(&path),
        Some(&dir),
        Some(&three),
        &FigureOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert_eq!(
        error,
        format!(
            "{}: 6 coordinates, but the robot `{}` has 9",
            path.display(),
            three.robot.name
        )
    );
}
