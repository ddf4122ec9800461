//! Integration tests of the 3-D robot view: the backbone frames against the PCC arc in
//! closed form, the snapshots and active corners chosen from a record, the files written
//! (PNG size, SVG text, byte-identical output), edge cases (one row, NaN rows, times
//! outside the record, 1-, 3- and 4-module robots) and the animated GIF's frames.

use std::path::{Path, PathBuf};

use softcbf::model::Model;
use softcbf::plot::PlotError;
use softcbf::plot::robot_view::{
    AnimationOptions, Camera, ViewOptions, animate_robot, backbone_frames, draw_robot_views,
    plan_snapshots, snapshot_times,
};
use softcbf::record::{Record, Row};
use softcbf_description::robot::Robot;
use softcbf_tests::{reference, robots};

fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("robot-view-tests")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn paper() -> Model {
    Model::new(Robot::paper_sim()).unwrap()
}

/// `modules` paper modules stacked (hex_1, hex_4, …).
fn hexagons(modules: usize) -> Model {
    let robot =
        reference::paper_robot((0..modules).map(|_| reference::paper_module(0.0)).collect());
    Model::new(robot).unwrap()
}

fn three_square() -> Model {
    Model::new(Robot::load(&robots::path("three-square.toml")).unwrap()).unwrap()
}

/// A record of `(t, q, b)` rows (the other columns zero).
fn record(n: usize, m: usize, rows: &[(f64, Vec<f64>, Vec<f64>)]) -> Record {
    let mut record = Record::with_capacity(n, m, &[], rows.len()).unwrap();
    let zeros = vec![0.0; n];
    for (t, q, b) in rows {
        record
            .push_row(&Row {
                t: *t,
                q,
                qd: &zeros,
                tau: &zeros,
                tau_nom: &zeros,
                b,
                extra: &[],
            })
            .unwrap();
    }
    record
}

/// The model's barriers at `q`.
fn barriers(model: &Model, q: &[f64]) -> Vec<f64> {
    let mut b = vec![0.0; model.nb()];
    model.generated.barriers(&model.params, q, &mut b);
    b
}

/// A run of `rows` rows over `duration` seconds from rest to `target`, reached at 0.6 s
/// (`s = 1 − (1 − t/0.6)³`), with the model's barriers.
fn run_toward(model: &Model, target: &[f64], rows: usize, duration: f64) -> Record {
    let rows: Vec<(f64, Vec<f64>, Vec<f64>)> = (0..rows)
        .map(|k| {
            let t = duration * k as f64 / (rows.max(2) - 1) as f64;
            let s = 1.0 - (1.0 - (t / 0.6).min(1.0)).powi(3);
            let q: Vec<f64> = target.iter().map(|v| s * v).collect();
            let b = barriers(model, &q);
            (t, q, b)
        })
        .collect();
    record(model.nq(), model.nb(), &rows)
}

/// The paper's set point (docs/model.md §7), which drives corners through their plates.
const SET_POINT: [f64; 6] = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
/// The same bends with elongations that leave the lowest corner of each module about
/// 0.2 mm above its margin, as a filtered run ends.
const RESTING: [f64; 6] = [0.08, 0.0, 0.0115, 0.0, -0.06, -0.0272];

/// A run like the filter's (ending on the margins) and one like PD+'s (crossing them).
fn paper_runs(model: &Model) -> (Record, Record) {
    let filtered = run_toward(model, &RESTING, 2001, 2.0);
    let lowest = barriers(model, &RESTING)
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    assert!(lowest > 0.0 && lowest < 0.5e-3, "{lowest}");
    (filtered, run_toward(model, &SET_POINT, 2001, 2.0))
}

/// The origin of a pose, and the pose's inverse applied to a point.
fn origin(pose: &[[f64; 4]; 4]) -> [f64; 3] {
    [pose[0][3], pose[1][3], pose[2][3]]
}

fn into_frame(pose: &[[f64; 4]; 4], p: [f64; 3]) -> [f64; 3] {
    let d = [p[0] - pose[0][3], p[1] - pose[1][3], p[2] - pose[2][3]];
    std::array::from_fn(|c| (0..3).map(|r| pose[r][c] * d[r]).sum())
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

#[test]
fn backbone_points_lie_on_the_pcc_arc() {
    let model = paper();
    let (d, l0) = (0.04, 0.1);
    let q = [0.05, -0.03, -0.02, -0.02, 0.045, 0.03];
    let mut plates = vec![[[0.0; 4]; 4]; 2];
    model.generated.plate_poses(&model.params, &q, &mut plates);
    for s in [0.0, 0.1, 0.37, 0.5, 0.9, 1.0] {
        let frames = backbone_frames(&model, &q, s).unwrap();
        for module in 0..2 {
            let (dx, dy, dl) = (q[3 * module], q[3 * module + 1], q[3 * module + 2]);
            let theta = dx.hypot(dy) / d;
            let alpha = dy.atan2(dx);
            let length = l0 + dl;
            let radius = length / theta;
            // The point in the module's base frame (the world, or plate 1's frame).
            let point = if module == 0 {
                origin(&frames[0])
            } else {
                into_frame(&plates[0], origin(&frames[1]))
            };
            // On the circle of radius L/θ about (ρ cos α, ρ sin α, 0), in the bending plane,
            // at the chord 2ρ sin(sθ/2) from the base, and where the arc's formula says.
            let centre = [radius * alpha.cos(), radius * alpha.sin(), 0.0];
            let from_centre = [point[0] - centre[0], point[1] - centre[1], point[2]];
            assert!((norm(from_centre) - radius).abs() < 1e-12, "s = {s}");
            let chord = 2.0 * radius * (s * theta / 2.0).sin();
            assert!((norm(point) - chord).abs() < 1e-12, "s = {s}");
            assert!((point[0] * alpha.sin() - point[1] * alpha.cos()).abs() < 1e-14);
            let expected = [
                radius * (1.0 - (s * theta).cos()) * alpha.cos(),
                radius * (1.0 - (s * theta).cos()) * alpha.sin(),
                radius * (s * theta).sin(),
            ];
            for k in 0..3 {
                assert!((point[k] - expected[k]).abs() < 1e-12, "s = {s}, {k}");
            }
        }
        if s == 1.0 {
            for (frame, plate) in frames.iter().zip(&plates) {
                for r in 0..4 {
                    for c in 0..4 {
                        assert!((frame[r][c] - plate[r][c]).abs() < 1e-14);
                    }
                }
            }
        }
    }
}

#[test]
fn straight_backbones_are_straight_and_the_last_frame_is_the_plate_pose() {
    let model = hexagons(4);
    let q = [
        0.0, 0.0, -0.02, 0.0, 0.0, 0.03, 1e-12, 0.0, 0.0, 0.0, 0.0, 0.0,
    ];
    for s in [0.0, 0.25, 1.0] {
        let frames = backbone_frames(&model, &q, s).unwrap();
        let heights = [0.0, 0.08, 0.21, 0.31];
        let lengths = [0.08, 0.13, 0.1, 0.1];
        for (i, frame) in frames.iter().enumerate() {
            let p = origin(frame);
            assert!(p[0].abs() < 1e-11 && p[1].abs() < 1e-11, "{p:?}");
            assert!((p[2] - heights[i] - s * lengths[i]).abs() < 1e-14, "{p:?}");
        }
    }
    // Bent modules: the frames at s = 1 are the generated plate poses.
    let q = [
        0.03, 0.01, 0.0, -0.02, 0.05, 0.01, 0.0, -0.04, -0.03, 0.06, 0.02, 0.01,
    ];
    let mut plates = vec![[[0.0; 4]; 4]; 4];
    model.generated.plate_poses(&model.params, &q, &mut plates);
    let frames = backbone_frames(&model, &q, 1.0).unwrap();
    for (frame, plate) in frames.iter().zip(&plates) {
        for r in 0..4 {
            for c in 0..4 {
                assert!((frame[r][c] - plate[r][c]).abs() < 1e-14);
            }
        }
    }
    assert!(matches!(
        backbone_frames(&model, &q[..6], 1.0),
        Err(PlotError::Mismatch {
            expected: 12,
            found: 6,
            ..
        })
    ));
}

#[test]
fn active_corners_are_those_at_or_below_the_threshold() {
    let model = paper();
    let q = vec![0.0; 6];
    // Barrier j is (j − 3) mm in the record, whatever the model says; one is NaN.
    let mut b: Vec<f64> = (0..model.nb()).map(|j| (j as f64 - 3.0) * 1e-3).collect();
    let rows = vec![
        (0.0, q.clone(), b.clone()),
        (1.0, q.clone(), {
            b[11] = f64::NAN;
            b.clone()
        }),
    ];
    let record = record(6, model.nb(), &rows);
    let plan = plan_snapshots(&model, &[("run", &record)], &[0.0, 1.0], 0.5e-3).unwrap();
    assert_eq!(plan.len(), 1);
    let [first, second] = &plan[0][..] else {
        panic!("two snapshots expected")
    };
    assert_eq!(first.row, Some(0));
    assert_eq!(first.active, [0, 1, 2, 3]);
    assert_eq!(first.violated, [0, 1, 2]);
    // A NaN in the record is replaced by the model's value (straight: L0 − ε = 95 mm).
    assert_eq!(second.row, Some(1));
    assert!((second.b[11] - 0.095).abs() < 1e-15);
    assert_eq!(second.active, [0, 1, 2, 3]);
    // A threshold of 2 mm takes two more, zero none above zero.
    let plan = plan_snapshots(&model, &[("run", &record)], &[0.0], 2e-3).unwrap();
    assert_eq!(plan[0][0].active, [0, 1, 2, 3, 4, 5]);
    let plan = plan_snapshots(&model, &[("run", &record)], &[0.0], 0.0).unwrap();
    assert_eq!(plan[0][0].active, [0, 1, 2, 3]);
}

#[test]
fn snapshots_take_the_nearest_finite_row_and_skip_nan_rows() {
    let model = paper();
    let q = |x: f64| vec![x, 0.0, 0.0, 0.0, 0.0, 0.0];
    let nan = vec![f64::NAN; 6];
    let rows = vec![
        (0.0, q(0.0), barriers(&model, &q(0.0))),
        (0.5, nan.clone(), vec![f64::NAN; model.nb()]),
        (f64::NAN, q(0.02), barriers(&model, &q(0.02))),
        (1.0, q(0.03), barriers(&model, &q(0.03))),
    ];
    let record = record(6, model.nb(), &rows);
    let plan = plan_snapshots(
        &model,
        &[("run", &record)],
        &[-3.0, 0.5, 0.6, 99.0, f64::NAN],
        5e-4,
    )
    .unwrap();
    let rows: Vec<Option<usize>> = plan[0].iter().map(|s| s.row).collect();
    // NaN time asked: left out; 0.5 s is a NaN row: the nearest finite one (0 s, the first
    // of two at equal distance); outside the record: its ends.
    assert_eq!(rows, [Some(0), Some(0), Some(3), Some(3)]);
    assert_eq!(plan[0][3].t, 1.0);
    assert_eq!(plan[0][3].asked, 99.0);
    // A record with no finite row has no snapshot row, and still draws.
    let broken = record_of_nans(&model, 3);
    let plan = plan_snapshots(&model, &[("run", &broken)], &[0.0], 5e-4).unwrap();
    assert_eq!(plan[0][0].row, None);
    assert!(plan[0][0].active.is_empty());
    let files = draw_robot_views(
        &out_dir("nans"),
        "robot",
        &model,
        &[("broken", &broken), ("fine", &record)],
        &ViewOptions::default(),
    )
    .unwrap();
    assert!(std::fs::metadata(&files[0]).unwrap().len() > 1000);
}

fn record_of_nans(model: &Model, rows: usize) -> Record {
    let rows: Vec<(f64, Vec<f64>, Vec<f64>)> = (0..rows)
        .map(|k| {
            (
                k as f64,
                vec![f64::NAN; model.nq()],
                vec![f64::NAN; model.nb()],
            )
        })
        .collect();
    record(model.nq(), model.nb(), &rows)
}

#[test]
fn automatic_snapshots_go_where_the_robot_moves() {
    let model = paper();
    // At rest until 1 s, moving between 1 and 2 s, at rest until 10 s.
    let rows: Vec<(f64, Vec<f64>, Vec<f64>)> = (0..=1000)
        .map(|k| {
            let t = k as f64 * 0.01;
            let s = (t - 1.0).clamp(0.0, 1.0);
            let q = vec![0.05 * s, 0.0, -0.02 * s, 0.0, 0.0, 0.0];
            let b = barriers(&model, &q);
            (t, q, b)
        })
        .collect();
    let record = record(6, model.nb(), &rows);
    let times = snapshot_times(&model, &[("run", &record)], 4).unwrap();
    assert_eq!(times.len(), 4);
    assert_eq!((times[0], times[3]), (0.0, 10.0));
    assert!(
        times[1] > 1.0 && times[1] < times[2] && times[2] < 2.0,
        "{times:?}"
    );
    // Two significant digits.
    for t in &times[1..3] {
        assert!(((t * 100.0).round() - t * 100.0).abs() < 1e-9, "{t}");
    }
    // One snapshot: the start; a robot at rest: evenly spread.
    assert_eq!(
        snapshot_times(&model, &[("run", &record)], 1).unwrap(),
        [0.0]
    );
    let still = run_toward(&model, &[0.0; 6], 11, 10.0);
    let times = snapshot_times(&model, &[("still", &still)], 3).unwrap();
    assert_eq!(times, [0.0, 5.0, 10.0]);
}

/// Width, height and RGB pixels of a PNG file.
fn decode_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = png::Decoder::new(file).read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buffer).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buffer.truncate(info.buffer_size());
    (info.width, info.height, buffer)
}

/// Pixels of exactly `colour`.
fn count(pixels: &[u8], colour: [u8; 3]) -> usize {
    pixels.chunks_exact(3).filter(|p| *p == colour).count()
}

/// The orange and red of highlighted corners (robot_draw.rs's ACTIVE and VIOLATED).
const ORANGE: [u8; 3] = [230, 145, 0];
const RED: [u8; 3] = [204, 30, 30];

#[test]
fn views_are_written_with_the_documented_size_and_are_byte_stable() {
    let model = paper();
    let (filtered, plain) = paper_runs(&model);
    let panels = [
        ("safety filter (HOCBF-QP)", &filtered),
        ("PD+ only", &plain),
    ];
    let dir = out_dir("paper");
    let files = draw_robot_views(&dir, "robot", &model, &panels, &ViewOptions::default()).unwrap();
    assert_eq!(files, [dir.join("robot.png"), dir.join("robot.svg")]);
    let (width, height, pixels) = decode_png(&files[0]);
    assert_eq!((width, height), (270 * 4 + 400, 40 + 2 * 514 + 76));
    let (red, orange) = (count(&pixels, RED), count(&pixels, ORANGE));
    let svg = std::fs::read_to_string(&files[1]).unwrap();
    assert!(svg.starts_with("<svg"));
    for text in [
        "safety filter (HOCBF-QP)",
        "PD+ only",
        "t = 0 s",
        "t = 2 s",
        "lowest b",
    ] {
        assert!(svg.contains(text), "{text} missing from the SVG");
    }
    // The same input gives the same bytes.
    let png = std::fs::read(&files[0]).unwrap();
    let again = draw_robot_views(&dir, "again", &model, &panels, &ViewOptions::default()).unwrap();
    assert_eq!(std::fs::read(&again[0]).unwrap(), png);
    assert_eq!(std::fs::read_to_string(&again[1]).unwrap(), svg);

    // A filtered run that never comes near its margin shows no highlighted corner; with
    // the threshold raised to 0.1 m every corner is highlighted.
    let calm = run_toward(&model, &[0.01, 0.0, 0.0, 0.0, 0.0, 0.0], 101, 1.0);
    let options = ViewOptions {
        times: vec![0.0, 1.0],
        ..ViewOptions::default()
    };
    let files = draw_robot_views(&dir, "calm", &model, &[("calm", &calm)], &options).unwrap();
    let (width, height, pixels) = decode_png(&files[0]);
    assert_eq!((width, height), (940, 40 + 514 + 132));
    // The legend's marks only.
    let (legend_red, legend_orange) = (count(&pixels, RED), count(&pixels, ORANGE));
    assert!(legend_red > 50 && legend_red < 200 && legend_orange < 200);
    // The plain run crosses its barriers (red corners), and the filtered one rests on them.
    assert!(red > legend_red + 100, "{red}");
    assert!(orange > legend_orange + 100, "{orange}");
    let legend_only = legend_orange;
    let options = ViewOptions {
        active_below: 0.1,
        ..options
    };
    let files = draw_robot_views(&dir, "calm-all", &model, &[("calm", &calm)], &options).unwrap();
    let (_, _, pixels) = decode_png(&files[0]);
    assert!(count(&pixels, ORANGE) > legend_only + 500);
}

#[test]
fn edge_cases_draw_without_panicking() {
    let dir = out_dir("edges");
    for (name, model) in [
        ("hex_1", hexagons(1)),
        ("three-square", three_square()),
        ("hex_4", hexagons(4)),
    ] {
        let n = model.nq();
        let target: Vec<f64> = (0..n)
            .map(|k| match k % 3 {
                0 => 0.06,
                1 => -0.02,
                _ => -0.03,
            })
            .collect();
        let run = run_toward(&model, &target, 501, 1.0);
        let one_row = run_toward(&model, &target, 1, 0.0);
        let files = draw_robot_views(
            &dir,
            name,
            &model,
            &[("run", &run)],
            &ViewOptions::default(),
        )
        .unwrap();
        let (width, height, _) = decode_png(&files[0]);
        assert_eq!((width, height), (270 * 4 + 400, 40 + 514 + 76), "{name}");
        let options = ViewOptions {
            times: vec![-1.0, 0.5, 100.0],
            camera: Some(Camera {
                azimuth_deg: 30.0,
                elevation_deg: 90.0,
            }),
            ..ViewOptions::default()
        };
        let panels = [
            ("one row", &one_row),
            ("run", &run),
            ("nans", &record_of_nans(&model, 2)),
        ];
        let files =
            draw_robot_views(&dir, &format!("{name}-odd"), &model, &panels, &options).unwrap();
        let (width, height, _) = decode_png(&files[0]);
        assert_eq!(
            (width, height),
            (270 * 3 + 400, 40 + 3 * 514 + 104),
            "{name}"
        );
        let svg = std::fs::read_to_string(&files[1]).unwrap();
        assert!(svg.contains("asked 100 s"), "{name}");
        assert!(svg.contains("no finite state"), "{name}");
    }
}

#[test]
fn bad_inputs_are_errors() {
    let model = paper();
    let dir = out_dir("errors");
    let (run, _) = paper_runs(&model);
    let draw = |panels: &[(&str, &Record)], options: &ViewOptions| {
        draw_robot_views(&dir, "robot", &model, panels, options)
    };
    let defaults = ViewOptions::default();
    assert!(matches!(draw(&[], &defaults), Err(PlotError::NoPanels)));
    let empty = record(6, model.nb(), &[]);
    assert!(matches!(
        draw(&[("empty", &empty)], &defaults),
        Err(PlotError::EmptyRecord { title }) if title == "empty"
    ));
    let small = run_toward(&hexagons(1), &[0.01, 0.0, 0.0], 3, 1.0);
    assert!(matches!(
        draw(&[("run", &run), ("small", &small)], &defaults),
        Err(PlotError::Mismatch {
            expected: 6,
            found: 3,
            ..
        })
    ));
    for options in [
        ViewOptions {
            active_below: f64::NAN,
            ..ViewOptions::default()
        },
        ViewOptions {
            snapshots: 0,
            ..ViewOptions::default()
        },
        ViewOptions {
            camera: Some(Camera {
                azimuth_deg: 0.0,
                elevation_deg: 91.0,
            }),
            ..ViewOptions::default()
        },
    ] {
        let error = draw(&[("run", &run)], &options).unwrap_err();
        assert!(
            matches!(&error, PlotError::Draw { file, .. } if file.ends_with("robot.png")),
            "{error}"
        );
    }
    let gif = dir.join("robot.gif");
    for options in [
        AnimationOptions {
            fps: 0.0,
            ..AnimationOptions::default()
        },
        AnimationOptions {
            duration: f64::INFINITY,
            ..AnimationOptions::default()
        },
        AnimationOptions {
            uniform: 1.5,
            ..AnimationOptions::default()
        },
    ] {
        let error = animate_robot(&gif, &model, &[("run", &run)], &options).unwrap_err();
        assert!(matches!(error, PlotError::Draw { .. }), "{error}");
    }
}

#[test]
fn animation_has_one_frame_per_tick_of_playback() {
    let model = paper();
    let (filtered, plain) = paper_runs(&model);
    let path = out_dir("gif").join("run.gif");
    let options = AnimationOptions {
        fps: 20.0,
        duration: 2.0,
        ..AnimationOptions::default()
    };
    let panels = [("filter", &filtered), ("PD+", &plain)];
    let written = animate_robot(&path, &model, &panels, &options).unwrap();
    assert_eq!(written, path);
    let mut decoding = gif::DecodeOptions::new();
    decoding.set_color_output(gif::ColorOutput::Indexed);
    let mut decoder = decoding
        .clone()
        .read_info(std::fs::File::open(&path).unwrap())
        .unwrap();
    assert_eq!(
        (decoder.width(), decoder.height()),
        (2 * 440, 40 + 470 + 64)
    );
    assert_eq!(decoder.repeat(), gif::Repeat::Infinite);
    let mut frames = 0;
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        assert_eq!(frame.delay, 5, "1/20 s");
        frames += 1;
    }
    assert_eq!(frames, 40);
    let bytes = std::fs::read(&path).unwrap();
    animate_robot(&path, &model, &panels, &options).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), bytes, "byte-stable");

    // One row, one frame.
    let one_row = run_toward(&model, &SET_POINT, 1, 0.0);
    let options = AnimationOptions {
        fps: 10.0,
        duration: 0.1,
        ..AnimationOptions::default()
    };
    animate_robot(&path, &model, &[("one", &one_row)], &options).unwrap();
    let mut decoder = decoding
        .read_info(std::fs::File::open(&path).unwrap())
        .unwrap();
    let mut frames = 0;
    while decoder.read_next_frame().unwrap().is_some() {
        frames += 1;
    }
    assert_eq!(frames, 1);
}
