//! Integration tests of the figures: files written, PNG of the documented size with the
//! lines drawn, SVG with the titles, byte-identical output, and the min/max envelope.

use std::path::{Path, PathBuf};

use rand::RngExt;
use softcbf::plot::{
    COLUMN_WIDTH, FIGURE_HEIGHT, LEGEND_WIDTH, PlotError, coordinate_labels, draw_figures, envelope,
};
use softcbf::record::{Record, Row};

/// The paper's simulation set point (docs/model.md §7).
const SET_POINT: [f64; 6] = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];

fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("plot-tests")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
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
    let mut record = Record::with_capacity(6, 12, &[], rows).unwrap();
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
fn coordinate_labels_follow_the_paper() {
    assert_eq!(
        coordinate_labels(6),
        ["Δx₁", "Δy₁", "δL₁", "Δx₂", "Δy₂", "δL₂"]
    );
    assert_eq!(coordinate_labels(33)[30], "Δx₁₁");
    assert_eq!(coordinate_labels(4), ["q0", "q1", "q2", "q3"]);
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
    let files = draw_figures(&dir, "trajectory", &panels, &SET_POINT, &[6, 6]).unwrap();
    assert_eq!(
        files,
        [dir.join("trajectory.png"), dir.join("trajectory.svg")]
    );

    let (width, height, pixels) = decode_png(&files[0]);
    assert_eq!(
        (width, height),
        (2 * COLUMN_WIDTH + LEGEND_WIDTH, FIGURE_HEIGHT)
    );
    assert_eq!((width, height), (1400, 1000));
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
    assert!(svg.contains("width=\"1400\"") && svg.contains("height=\"1000\""));
    for text in [
        "safety filter (HOCBF-QP)",
        "PD+ only",
        "(a) generalized coordinates q",
        "(f) barrier values b",
        "t [s]",
        "Δx₁",
        "δL₂",
        "corner 6",
        "module 2",
    ] {
        assert!(svg.contains(text), "SVG lacks `{text}`");
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
    let first = draw_figures(&out_dir("twice-1"), "fig", &panels, &SET_POINT, &[6, 6]).unwrap();
    let second = draw_figures(&out_dir("twice-2"), "fig", &panels, &SET_POINT, &[6, 6]).unwrap();
    for (a, b) in first.iter().zip(&second) {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{} differs",
            a.display()
        );
    }
}

#[test]
fn one_column_and_bad_input() {
    let run = synthetic_run(true);
    let dir = out_dir("single");
    let files = draw_figures(&dir, "run", &[("safety filter (HOCBF-QP)", &run)], &[], &[]).unwrap();
    let (width, height, _) = decode_png(&files[0]);
    assert_eq!(
        (width, height),
        (COLUMN_WIDTH + LEGEND_WIDTH, FIGURE_HEIGHT)
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
    let error = |panels: &[(&str, &Record)], set_point: &[f64], modules: &[usize]| {
        draw_figures(&dir, "x", panels, set_point, modules).unwrap_err()
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
}

#[test]
fn a_hardware_log_with_gaps_is_drawn() {
    // 33 Hz for 5 s with the hardware run's extra columns; a failed tick leaves NaN in τ
    // and one reading is infinite: the figure is still drawn from the finite values.
    let mut record = Record::with_capacity(6, 12, &["loop_us", "overrun", "clamps"], 166).unwrap();
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
    let files = draw_figures(
        &dir,
        "run",
        &[("HOCBF-QP, 33 Hz", &record)],
        &[0.0, 0.0, -0.15, 0.0, -0.065, 0.0],
        &[6, 6],
    )
    .unwrap();
    let (width, height, _) = decode_png(&files[0]);
    assert_eq!(
        (width, height),
        (COLUMN_WIDTH + LEGEND_WIDTH, FIGURE_HEIGHT)
    );
    assert!(
        std::fs::read_to_string(&files[1])
            .unwrap()
            .contains("HOCBF-QP, 33 Hz")
    );
}
