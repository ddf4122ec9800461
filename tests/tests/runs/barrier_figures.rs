//! The figures of a robot with every kind of barrier (the generated `every_barrier`
//! structure): a short closed-loop run drawn as Fig. 4 with a row of barrier panels per
//! kind group, the same rows found from the labels alone, and the 3-D view with its
//! obstacles and watched points (found in the pixels where the geometry puts them) and its
//! notes when the lowest barrier is not a plate corner.

use std::path::{Path, PathBuf};

use softcbf::model::Model;
use softcbf::plot::robot_view::{Camera, ViewOptions, draw_robot_views};
use softcbf::plot::{
    COLUMN_WIDTH, FIGURE_HEIGHT, FigureOptions, LEGEND_WIDTH, ROW_HEIGHT, draw_figures,
    write_figures,
};
use softcbf::record::{Columns, Record, Row};
use softcbf::scenario::ScenarioFile;
use softcbf::sim::simulate;
use softcbf_description::barriers::{
    BarrierKind, LimitFlags, Limits, Obstacle, Shape, Watched, WatchedPoint,
};
use softcbf_description::robot::Robot;

fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("barrier-figures")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The paper's simulation set point (docs/model.md §7).
const SET_POINT: [f64; 6] = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
/// Radius and margin of the sphere of [`every_barrier_robot`] \[m\].
const RADIUS: f64 = 0.03;
const SPHERE_MARGIN: f64 = 0.005;

/// The paper robot with the barriers of `softcbf_codegen::registry::every_barrier()`:
/// elongation and bend limits on both modules; a half-space `x ≤ 0.2 m` and a sphere
/// about `centre`, each watching corner 3, the centre, a listed point and two backbone
/// points of each module.
fn every_barrier_robot(centre: [f64; 3]) -> Robot {
    let mut robot = Robot::paper_sim();
    robot.name = "every-barrier".to_string();
    robot.limits = vec![
        Limits {
            elongation: [-0.05, 0.03],
            elongation_margin: 0.002,
            max_bend: 100f64.to_radians(),
            bend_margin: 0.02,
            gains: [None, None],
            written: LimitFlags {
                elongation: true,
                bend: true,
            },
            elongation_rate: 1.0,
        };
        2
    ];
    let watch: Vec<Watched> = (0..2)
        .flat_map(|module| {
            [
                WatchedPoint::Corner(2),
                WatchedPoint::Centre,
                WatchedPoint::Listed([0.0, 0.03, 0.01]),
                WatchedPoint::Arc(0.3),
                WatchedPoint::Arc(0.7),
            ]
            .map(|point| Watched { module, point })
        })
        .collect();
    robot.obstacles = vec![
        Obstacle {
            shape: Shape::HalfSpace {
                normal: [-1.0, 0.0, 0.0],
                offset: -0.2,
            },
            margin: 0.005,
            gains: [None, None],
            watch: watch.clone(),
        },
        Obstacle {
            shape: Shape::Sphere {
                center: centre,
                radius: RADIUS,
            },
            margin: SPHERE_MARGIN,
            gains: [None, None],
            watch,
        },
    ];
    robot
}

fn every_barrier_model(centre: [f64; 3]) -> Model {
    let robot = every_barrier_robot(centre);
    assert_eq!(
        robot.structure(),
        softcbf_codegen::registry::every_barrier()
    );
    Model::new(robot).expect("every_barrier is generated")
}

/// Where the sphere sits in the closed-loop runs: beside the path of module 2's plate.
const NEAR_THE_PATH: [f64; 3] = [0.11, 0.0, 0.13];

/// The paper's scenario on `model` for `seconds`, with the filter and without.
fn closed_loop(model: &Model, seconds: f64) -> (Record, Record) {
    let mut scenario = ScenarioFile::paper_sim().resolve(model).unwrap();
    scenario.duration = seconds;
    let filtered = simulate(model, &scenario, true, &mut |_| {}).unwrap();
    let plain = simulate(model, &scenario, false, &mut |_| {}).unwrap();
    (filtered.record, plain.record)
}

/// The model's barriers at `q`.
fn barriers(model: &Model, q: &[f64]) -> Vec<f64> {
    let mut b = vec![0.0; model.nb()];
    model.generated.barriers(&model.params, q, &mut b);
    b
}

/// A record of `rows` rows over `duration` seconds from rest toward `target` (reached at
/// 0.6 s), with the model's barriers and labels; `last_b` rewrites the last row's.
fn run_toward(
    model: &Model,
    target: &[f64],
    rows: usize,
    duration: f64,
    last_b: impl Fn(&mut [f64]),
) -> Record {
    let mut record = Record::for_columns(Columns::for_model(model, &[]).unwrap(), rows);
    let zeros = vec![0.0; model.nq()];
    for k in 0..rows {
        let t = duration * k as f64 / (rows.max(2) - 1) as f64;
        let s = 1.0 - (1.0 - (t / 0.6).min(1.0)).powi(3);
        let q: Vec<f64> = target.iter().map(|v| s * v).collect();
        let mut b = barriers(model, &q);
        if k + 1 == rows {
            last_b(&mut b);
        }
        record
            .push_row(&Row {
                t,
                q: &q,
                qd: &zeros,
                tau: &zeros,
                tau_nom: &zeros,
                b: &b,
                extra: &[],
            })
            .unwrap();
    }
    record
}

/// Width, height and RGB pixels of a PNG file.
fn decode_png(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = png::Decoder::new(file).read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buffer).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let pixels = buffer[..info.buffer_size()]
        .chunks_exact(3)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    (info.width, info.height, pixels)
}

/// The pixels of exactly `colour` inside the rectangle `x0..x1`, `y0..y1`, as `(x, y)`.
fn find(
    (width, pixels): (u32, &[[u8; 3]]),
    colour: [u8; 3],
    (x0, x1): (u32, u32),
    (y0, y1): (u32, u32),
) -> Vec<(f64, f64)> {
    let mut found = Vec::new();
    for y in y0..y1 {
        for x in x0..x1 {
            if pixels[(y * width + x) as usize] == colour {
                found.push((x as f64, y as f64));
            }
        }
    }
    found
}

fn mean(points: &[(f64, f64)]) -> (f64, f64) {
    let n = points.len().max(1) as f64;
    (
        points.iter().map(|p| p.0).sum::<f64>() / n,
        points.iter().map(|p| p.1).sum::<f64>() / n,
    )
}

/// The colours robot_draw.rs draws with: sphere outline, half-space edge, watched points,
/// backbone.
const SPHERE_EDGE: [u8; 3] = [84, 39, 143];
const WALL_EDGE: [u8; 3] = [35, 110, 60];
const WATCHED: [u8; 3] = [0, 150, 160];
const BACKBONE: [u8; 3] = [30, 30, 30];

#[test]
fn a_closed_loop_run_draws_a_row_of_panels_per_kind_group() {
    let model = every_barrier_model(NEAR_THE_PATH);
    let (filtered, plain) = closed_loop(&model, 1.0);
    let dir = out_dir("closed-loop");
    let options = FigureOptions {
        model: Some(&model),
        animate: true,
        ..FigureOptions::default()
    };
    let panels = [
        ("safety filter (HOCBF-QP)", &filtered),
        ("PD+ only", &plain),
    ];
    let files = write_figures(&dir, &panels, &SET_POINT, &options).unwrap();
    let names: Vec<&str> = files
        .iter()
        .map(|f| f.file_name().unwrap().to_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "figure.png",
            "figure.svg",
            "robot.png",
            "robot.svg",
            "robot.gif"
        ]
    );
    // Four kind groups: three rows of barrier panels more than the paper's figure, and
    // under each, since each comes near zero, its zoomed row.
    let (width, height, _) = decode_png(&files[0]);
    assert_eq!(
        (width, height),
        (
            2 * COLUMN_WIDTH + LEGEND_WIDTH,
            FIGURE_HEIGHT + 7 * ROW_HEIGHT
        )
    );
    let svg = std::fs::read_to_string(&files[1]).unwrap();
    for text in [
        "(d) barrier values b: plate corners",
        "(e) the same plate corners near b = 0, zoomed (in mm)",
        "(f) barrier values b: elongation limits",
        "(h) barrier values b: bend limits",
        "(i) the same bend limits near b = 0, zoomed (in mrad)",
        "(j) barrier values b: obstacles",
        "(u) barrier values b: obstacles",
        "b [rad]",
        "b [mrad]",
        "elongation max",
        "obstacle 2 arc 1",
    ] {
        assert!(svg.contains(text), "{text} missing from the figure");
    }
    // PD+ drives module 2's listed point into the sphere: its label is shown.
    let lowest = (0..model.nb())
        .map(|j| (j, plain.b(j).fold(f64::INFINITY, f64::min)))
        .filter(|&(j, _)| model.generated.barrier_table()[j].kind == BarrierKind::Sphere)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    assert!(lowest.1 < 0.0, "{lowest:?}");
    let label = model.generated.barrier_table()[lowest.0].label;
    assert!(svg.contains(label), "{label} is not labelled");
    // The 3-D view: two rows of four snapshots and a zoom, the legend with three rows.
    let (width, height, _) = decode_png(&files[2]);
    assert_eq!((width, height), (270 * 4 + 400, 40 + 2 * 514 + 104));
    let svg = std::fs::read_to_string(&files[3]).unwrap();
    assert!(svg.contains("sphere (dashed: + margin ε)"));
    assert!(!svg.contains("nothing to zoom on"));
    let gif = gif::DecodeOptions::new()
        .read_info(std::fs::File::open(&files[4]).unwrap())
        .unwrap();
    assert_eq!((gif.width(), gif.height()), (2 * 440, 40 + 470 + 64));
}

#[test]
fn rows_found_from_the_labels_alone_are_the_same() {
    // `softcbf plot` without the robot: the groups come from the barrier labels.
    let model = every_barrier_model(NEAR_THE_PATH);
    let (filtered, _) = closed_loop(&model, 0.3);
    let panels = [("safety filter (HOCBF-QP)", &filtered)];
    let dir = out_dir("labels");
    let with_model = FigureOptions {
        model: Some(&model),
        ..FigureOptions::default()
    };
    let by_model = draw_figures(&dir, "model", &panels, &SET_POINT, &with_model).unwrap();
    let by_labels = draw_figures(
        &dir,
        "labels",
        &panels,
        &SET_POINT,
        &FigureOptions::default(),
    )
    .unwrap();
    let (_, height, _) = decode_png(&by_labels[0]);
    assert_eq!(height, FIGURE_HEIGHT + 3 * ROW_HEIGHT);
    for (a, b) in by_model.iter().zip(&by_labels) {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{} and {} differ",
            a.display(),
            b.display()
        );
    }
    // Labels of no known kind: the one row of old.
    let mut unknown = filtered.clone();
    let labels: Vec<String> = (0..model.nb()).map(|j| format!("b{}", j + 1)).collect();
    let coordinates = softcbf::record::coordinate_names(6);
    unknown
        .relabel(
            Columns::named(
                &softcbf::record::as_strs(&coordinates),
                &softcbf::record::as_strs(&labels),
                &softcbf::record::as_strs(filtered.columns().extra_names()),
            )
            .unwrap(),
        )
        .unwrap();
    let files = draw_figures(
        &dir,
        "unknown",
        &[("run", &unknown)],
        &SET_POINT,
        &FigureOptions::default(),
    )
    .unwrap();
    let (_, height, _) = decode_png(&files[0]);
    assert_eq!(height, FIGURE_HEIGHT);
}

/// Snapshot cell `column` of the first run of a view with `times.len()` snapshots:
/// `(x range, y range)` in pixels (robot_draw.rs: 270 px wide cells under a 40 px title
/// and a 34 px row title, 480 px high).
fn cell(column: u32) -> ((u32, u32), (u32, u32)) {
    ((270 * column, 270 * (column + 1)), (74, 74 + 480))
}

#[test]
fn the_sphere_is_drawn_at_its_centre_with_its_radius_and_margin() {
    // Looking along −x (azimuth 0, elevation 0): world y is the screen's x, z its height.
    let options = ViewOptions {
        times: vec![0.0, 1.0],
        camera: Some(Camera {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
        }),
        ..ViewOptions::default()
    };
    let dir = out_dir("sphere");
    let mut offsets = Vec::new();
    for side in [1.0, -1.0] {
        let centre = [0.0, side * 0.12, 0.13];
        let model = every_barrier_model(centre);
        let run = run_toward(&model, &[0.0; 6], 11, 1.0, |_| {});
        let stem = if side > 0.0 { "plus-y" } else { "minus-y" };
        let files = draw_robot_views(&dir, stem, &model, &[("still", &run)], &options).unwrap();
        let (width, _, pixels) = decode_png(&files[0]);
        let image = (width, &pixels[..]);
        let (xs, ys) = cell(0);
        // The straight backbone from z = 0 to 0.2 m gives the scale and the origin.
        let backbone = find(image, BACKBONE, xs, ys);
        assert!(backbone.len() > 300, "{}", backbone.len());
        let (axis_x, _) = mean(&backbone);
        let top = backbone.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let bottom = backbone.iter().map(|p| p.1).fold(0.0, f64::max);
        let scale = (bottom - top) / 0.2;
        // The sphere's outline (solid at ρ, dashed at ρ + ε): centred on its centre, as
        // wide as the dashed circle.
        let outline = find(image, SPHERE_EDGE, xs, ys);
        assert!(outline.len() > 400, "{}", outline.len());
        let (x, y) = mean(&outline);
        let expected = (axis_x + side * 0.12 * scale, bottom - 0.13 * scale);
        assert!(
            (x - expected.0).abs() < 0.04 * 0.12 * scale,
            "{x} vs {expected:?}"
        );
        assert!(
            (y - expected.1).abs() < 0.04 * 0.13 * scale,
            "{y} vs {expected:?}"
        );
        let left = outline.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        let right = outline.iter().map(|p| p.0).fold(0.0, f64::max);
        let across = 2.0 * (RADIUS + SPHERE_MARGIN) * scale;
        assert!(
            ((right - left) - across).abs() < 0.05 * across + 2.0,
            "{left} {right}"
        );
        // Inside the outline, the shaded fill: purple, not white.
        let [r, g, b] =
            pixels[(expected.1.round() as u32 * width + expected.0.round() as u32) as usize];
        assert!(b > g + 15 && r > g + 5 && g < 235, "{r} {g} {b}");
        offsets.push(x - axis_x);
        // The half-space x ≤ 0.2 m is seen face-on (its arrow points away from the viewer:
        // only its foot shows), and the ten watched points as dots (five per module, both
        // obstacles watch the same ones).
        assert!(find(image, WALL_EDGE, xs, ys).len() > 20);
        let dots = find(image, WATCHED, xs, ys);
        assert!(dots.len() > 8 * 9, "{}", dots.len());
    }
    assert!(offsets[0] > 0.0 && offsets[1] < 0.0, "{offsets:?}");
}

#[test]
fn the_zoom_shows_the_lowest_corner_when_another_kind_is_lowest() {
    let model = every_barrier_model(NEAR_THE_PATH);
    let table = model.generated.barrier_table();
    let bend = table
        .iter()
        .position(|info| info.kind == BarrierKind::Bend && info.module == 0)
        .unwrap();
    let target = [0.03, 0.0, -0.01, 0.0, -0.02, -0.01];
    // The last row: module 1's bend at −0.01 rad, below every other barrier.
    let run = run_toward(&model, &target, 201, 1.0, |b| b[bend] = -0.01);
    let dir = out_dir("zoom");
    let files = draw_robot_views(
        &dir,
        "robot",
        &model,
        &[("run", &run)],
        &ViewOptions::default(),
    )
    .unwrap();
    let svg = std::fs::read_to_string(&files[1]).unwrap();
    for text in [
        "lowest b = −0.010 rad (m1 bend)",
        "lowest: m1 bend b = −0.010 rad, below its margin",
        "lowest corner m",
        "gap, edge-on",
    ] {
        assert!(svg.contains(text), "{text} missing from the view");
    }
    assert!(!svg.contains("nothing to zoom on"));
    // The lowest corner is the one the zoom measures.
    let b = barriers(&model, &target);
    let corner = (0..model.nb())
        .filter(|&j| table[j].kind == BarrierKind::PlateCorner)
        .min_by(|&i, &j| b[i].total_cmp(&b[j]))
        .unwrap();
    let short = format!(
        "lowest corner m{} c{}:",
        table[corner].module + 1,
        table[corner].corner().unwrap() + 1
    );
    assert!(svg.contains(&short), "{short}");

    // An obstacle's point lowest, on a path clear of every barrier: named in the caption,
    // the one point ringed in red.
    let point = table
        .iter()
        .position(|info| info.kind == BarrierKind::Sphere)
        .unwrap();
    let away = [-0.03, 0.0, -0.01, 0.0, 0.02, -0.01];
    assert!(barriers(&model, &away).iter().all(|&b| b > 1e-3));
    let run = run_toward(&model, &away, 201, 1.0, |b| b[point] = -0.004);
    let files = draw_robot_views(
        &dir,
        "obstacle",
        &model,
        &[("run", &run)],
        &ViewOptions {
            times: vec![1.0],
            ..ViewOptions::default()
        },
    )
    .unwrap();
    let svg = std::fs::read_to_string(&files[1]).unwrap();
    assert!(
        svg.contains("lowest b = −4.00 mm (o2 m1 c3)"),
        "the sphere's first watched point is module 1's corner 3"
    );
    let (width, _, pixels) = decode_png(&files[0]);
    let red = find((width, &pixels), [204, 30, 30], cell(0).0, cell(0).1);
    assert!(red.len() > 50, "{}", red.len());
    let orange = find((width, &pixels), [230, 145, 0], cell(0).0, cell(0).1);
    assert!(orange.is_empty(), "{}", orange.len());
}

#[test]
fn odd_records_of_every_barrier_draw_without_panicking() {
    let model = every_barrier_model(NEAR_THE_PATH);
    let dir = out_dir("odd");
    let one_row = run_toward(&model, &SET_POINT, 1, 0.0, |_| {});
    let nans = run_toward(&model, &SET_POINT, 3, 1.0, |b| b.fill(f64::NAN));
    let files = draw_robot_views(
        &dir,
        "robot",
        &model,
        &[("one row", &one_row), ("nans", &nans)],
        &ViewOptions {
            times: vec![-1.0, 0.5, 100.0],
            ..ViewOptions::default()
        },
    )
    .unwrap();
    assert!(std::fs::metadata(&files[0]).unwrap().len() > 1000);
    let files = write_figures(
        &dir,
        &[("one row", &one_row), ("nans", &nans)],
        &[],
        &FigureOptions {
            model: Some(&model),
            animate: true,
            ..FigureOptions::default()
        },
    )
    .unwrap();
    assert_eq!(files.len(), 5);
}
