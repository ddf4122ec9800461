//! What the reports say about barriers of every kind, on a robot built in code with the
//! structure `softcbf_codegen::registry::every_barrier()`: the `barrier_info` list of
//! `softcbf model` against the robot's numbers, the CSV columns' units and their read-back,
//! and the lowest barrier per kind group of a short simulation against its record.

use std::f64::consts::PI;
use std::path::Path;

use serde_json::Value;
use softcbf::inspect::model_report;
use softcbf::model::Model;
use softcbf::output::one_line;
use softcbf::record::{Columns, Record, RecordError, Row};
use softcbf::scenario::ScenarioFile;
use softcbf::sim::{LowestByKind, Run, simulate};
use softcbf_description::Robot;
use softcbf_description::barriers::{LimitFlags, Limits, Obstacle, Shape, Watched, WatchedPoint};
use softcbf_description::robot::Module;
use softcbf_generated::{BarrierInfo, BarrierKind, KindGroup, Point};
use softcbf_tests::reference::paper_robot;

/// Elongation range \[m\], its margin \[m\], bend limit \[rad\] and its margin \[rad\] of
/// module `i` (different per module, so that a lookup of the wrong module shows).
fn limits(i: usize) -> Limits {
    let f = i as f64;
    Limits {
        elongation: [-0.05 + 0.01 * f, 0.03 + 0.005 * f],
        elongation_margin: 0.002 + 0.001 * f,
        max_bend: 1.2 - 0.1 * f,
        bend_margin: 0.02 + 0.01 * f,
        gains: [None, None],
        written: LimitFlags {
            elongation: true,
            bend: true,
        },
        elongation_rate: 1.0,
    }
}

/// Arc fractions of the two backbone points of module `i` watched by obstacle `o`.
fn arcs(o: usize, i: usize) -> [f64; 2] {
    [0.25 + 0.1 * o as f64 + 0.05 * i as f64, 0.75]
}

/// The listed point of module `i` watched by obstacle `o`, plate frame \[m\].
fn listed(o: usize, i: usize) -> [f64; 3] {
    [0.01 + 0.01 * o as f64, -0.02 * (i as f64 + 1.0), 0.005]
}

/// The points an obstacle watches, as `every_barrier()` lists them: per module corner 3,
/// the centre, a listed point and two backbone points.
fn watch(o: usize) -> Vec<Watched> {
    (0..2)
        .flat_map(|module| {
            let [s1, s2] = arcs(o, module);
            [
                WatchedPoint::Corner(2),
                WatchedPoint::Centre,
                WatchedPoint::Listed(listed(o, module)),
                WatchedPoint::Arc(s1),
                WatchedPoint::Arc(s2),
            ]
            .map(|point| Watched { module, point })
        })
        .collect()
}

/// Two paper modules with the second one's corners turned by 10° and margins per corner,
/// elongation and bend limits on both, a floor far below (half-space) and a sphere far to
/// the side: the structure of `every_barrier()`, nothing active at the straight start.
fn every_barrier_robot() -> Robot {
    let mut second = Module::paper();
    second.corner_radius = 0.045;
    for (j, angle) in second.corner_angles.iter_mut().enumerate() {
        *angle += PI / 18.0;
        second.margins[j] = 0.001 + 0.0001 * j as f64;
    }
    let mut robot = paper_robot(vec![Module::paper(), second]);
    robot.name = "every barrier".into();
    robot.limits = vec![limits(0), limits(1)];
    robot.obstacles = vec![
        Obstacle {
            shape: Shape::HalfSpace {
                normal: [0.0, 0.0, 1.0],
                offset: -0.5,
            },
            margin: 0.004,
            gains: [None, None],
            watch: watch(0),
        },
        Obstacle {
            shape: Shape::Sphere {
                center: [0.6, 0.1, 0.15],
                radius: 0.05,
            },
            margin: 0.006,
            gains: [None, None],
            watch: watch(1),
        },
    ];
    robot
}

fn every_barrier_model() -> Model {
    let robot = every_barrier_robot();
    assert_eq!(
        robot.structure(),
        softcbf_codegen::registry::every_barrier(),
        "the robot built here must have the structure of every_barrier()"
    );
    Model::new(robot).unwrap_or_else(|e| panic!("{e}"))
}

/// One expected barrier: kind, module (0-based), watched point, obstacle, label.
struct Expected {
    kind: BarrierKind,
    module: usize,
    point: Option<WatchedPoint>,
    obstacle: Option<usize>,
    label: String,
}

/// The barriers of [`every_barrier_robot`] in the documented order, written out from the
/// rules (corners, then limits module by module, then obstacles' points in file order).
fn expected_barriers(robot: &Robot) -> Vec<Expected> {
    let mut list = Vec::new();
    for i in 0..2 {
        for j in 0..6 {
            list.push(Expected {
                kind: BarrierKind::PlateCorner,
                module: i,
                point: Some(WatchedPoint::Corner(j)),
                obstacle: None,
                label: format!("module {} corner {}", i + 1, j + 1),
            });
        }
    }
    for i in 0..2 {
        for (kind, what) in [
            (BarrierKind::ElongationMin, "elongation min"),
            (BarrierKind::ElongationMax, "elongation max"),
            (BarrierKind::Bend, "bend"),
        ] {
            list.push(Expected {
                kind,
                module: i,
                point: None,
                obstacle: None,
                label: format!("module {} {what}", i + 1),
            });
        }
    }
    for (o, obstacle) in robot.obstacles.iter().enumerate() {
        let kind = match obstacle.shape {
            Shape::HalfSpace { .. } => BarrierKind::HalfSpace,
            Shape::Sphere { .. } => BarrierKind::Sphere,
        };
        for w in &obstacle.watch {
            let name = match w.point {
                WatchedPoint::Corner(j) => format!("corner {}", j + 1),
                WatchedPoint::Centre => "centre".to_string(),
                WatchedPoint::Listed(_) => "point 1".to_string(),
                WatchedPoint::Arc(s) => {
                    let n = if s == arcs(o, w.module)[0] { 1 } else { 2 };
                    format!("arc {n}")
                }
            };
            list.push(Expected {
                kind,
                module: w.module,
                point: Some(w.point),
                obstacle: Some(o),
                label: format!("obstacle {} module {} {name}", o + 1, w.module + 1),
            });
        }
    }
    list
}

fn number(value: &Value, what: &str) -> f64 {
    value
        .as_f64()
        .unwrap_or_else(|| panic!("{what}: not a number: {value}"))
}

fn triple(value: &Value, what: &str) -> [f64; 3] {
    let list = value
        .as_array()
        .unwrap_or_else(|| panic!("{what}: not a list: {value}"));
    assert_eq!(list.len(), 3, "{what}");
    [0, 1, 2].map(|c| number(&list[c], what))
}

/// The keys of a JSON object, sorted.
fn keys(value: &Value) -> Vec<&str> {
    let mut keys: Vec<&str> = value
        .as_object()
        .expect("an object")
        .keys()
        .map(String::as_str)
        .collect();
    keys.sort_unstable();
    keys
}

/// `softcbf model`'s `barrier_info`: one entry per barrier in barrier order, each with its
/// kind's key, 1-based module, label, margin and unit, the limits, the obstacle and its
/// geometry, and the watched point, all equal to the robot's own numbers.
#[test]
fn model_json_describes_every_barrier_with_the_robots_numbers() {
    let model = every_barrier_model();
    let robot = &model.robot;
    let q = [0.01, -0.005, 0.004, -0.006, 0.008, -0.01];
    let report = model_report(&model, &q, &[0.0; 6]).expect("state of the right length");
    let info = report["barrier_info"]
        .as_array()
        .expect("barrier_info is a list");
    let expected = expected_barriers(robot);
    assert_eq!(info.len(), expected.len());
    assert_eq!(info.len(), 12 + 6 + 20);
    // The keys the report had before stay.
    for key in [
        "barrier_table",
        "barriers",
        "barrier_jacobian",
        "mass_matrix",
    ] {
        assert!(report.get(key).is_some(), "{key}");
    }
    assert_eq!(report["barrier_table"].as_array().map(Vec::len), Some(38));

    for (k, (entry, want)) in info.iter().zip(&expected).enumerate() {
        let at = format!("barrier_info[{k}] = {entry}");
        let module = &robot.modules[want.module];
        let limits = &robot.limits[want.module];
        let key = match want.kind {
            BarrierKind::PlateCorner => "plate_corner",
            BarrierKind::ElongationMin => "elongation_min",
            BarrierKind::ElongationMax => "elongation_max",
            BarrierKind::Bend => "bend",
            BarrierKind::HalfSpace => "half_space",
            BarrierKind::Sphere => "sphere",
        };
        assert_eq!(entry["kind"], key, "{at}");
        assert_eq!(entry["module"], want.module + 1, "{at}");
        assert_eq!(entry["label"], want.label.as_str(), "{at}");
        let unit = if want.kind == BarrierKind::Bend {
            "rad"
        } else {
            "m"
        };
        assert_eq!(entry["unit"], unit, "{at}");
        let margin = match (want.kind, want.obstacle, want.point) {
            (_, Some(o), _) => robot.obstacles[o].margin,
            (BarrierKind::PlateCorner, _, Some(WatchedPoint::Corner(j))) => module.margins[j],
            (BarrierKind::Bend, ..) => limits.bend_margin,
            _ => limits.elongation_margin,
        };
        assert_eq!(number(&entry["margin"], &at), margin, "{at}");

        // Exactly the keys of its kind, nothing of another kind's.
        let mut want_keys = vec!["kind", "label", "margin", "module", "unit"];
        match want.kind {
            BarrierKind::ElongationMin | BarrierKind::ElongationMax => {
                let [min, max] = limits.elongation;
                assert_eq!(number(&entry["min"], &at), min, "{at}");
                assert_eq!(number(&entry["max"], &at), max, "{at}");
                // This robot writes every limit: none is the domain's default.
                assert_eq!(entry["domain_default"], false, "{at}");
                want_keys.extend(["domain_default", "max", "min"]);
            }
            BarrierKind::Bend => {
                let max_bend = limits.max_bend;
                assert_eq!(number(&entry["max_bend"], &at), max_bend, "{at}");
                assert_eq!(entry["domain_default"], false, "{at}");
                want_keys.extend(["domain_default", "max_bend"]);
            }
            _ => {}
        }
        if let Some(o) = want.obstacle {
            assert_eq!(entry["obstacle"], o + 1, "{at}");
            want_keys.push("obstacle");
            match robot.obstacles[o].shape {
                Shape::HalfSpace { normal, offset } => {
                    assert_eq!(triple(&entry["normal"], &at), normal, "{at}");
                    assert_eq!(number(&entry["offset"], &at), offset, "{at}");
                    want_keys.extend(["normal", "offset"]);
                }
                Shape::Sphere { center, radius } => {
                    assert_eq!(triple(&entry["center"], &at), center, "{at}");
                    assert_eq!(number(&entry["radius"], &at), radius, "{at}");
                    want_keys.extend(["center", "radius"]);
                }
            }
        }
        match want.point {
            Some(WatchedPoint::Corner(j)) => {
                // r cos φ_j, r sin φ_j, 0 in the top plate's frame.
                let (r, phi) = (module.corner_radius, module.corner_angles[j]);
                let point = triple(&entry["point"], &at);
                let exact = [r * phi.cos(), r * phi.sin(), 0.0];
                for c in 0..3 {
                    assert!((point[c] - exact[c]).abs() <= 1e-15, "{at}");
                }
                assert_eq!(entry["corner"], j + 1, "{at}");
                want_keys.extend(["corner", "point"]);
            }
            Some(WatchedPoint::Centre) => {
                assert_eq!(triple(&entry["point"], &at), [0.0; 3], "{at}");
                want_keys.push("point");
            }
            Some(WatchedPoint::Listed(p)) => {
                assert_eq!(triple(&entry["point"], &at), p, "{at}");
                want_keys.push("point");
            }
            Some(WatchedPoint::Arc(s)) => {
                assert_eq!(number(&entry["arc_fraction"], &at), s, "{at}");
                want_keys.push("arc_fraction");
            }
            None => {}
        }
        want_keys.sort_unstable();
        assert_eq!(keys(entry), want_keys, "{at}");
    }

    // The generated table agrees with the order written out here.
    let table = model.generated.barrier_table();
    for (info, want) in table.iter().zip(&expected) {
        assert_eq!(info.label, want.label);
        assert_eq!(info.kind, want.kind, "{}", want.label);
        assert_eq!(info.obstacle, want.obstacle, "{}", want.label);
    }
}

/// The paper robot's `barrier_info`: twelve corners with the 5 mm margin of
/// `robots/paper-sim.toml` (`margin = 0.005`), in metres, then the three limits of each
/// module at the domain's defaults (the file writes none): `δL ∈ [−0.95 L0, 4 L0]` and
/// `θ ≤ 1.25π` with `L0 = 0.1 m`, marked `domain_default`; no obstacles.
#[test]
fn model_json_of_the_paper_robot_lists_its_corners_and_domain_limits() {
    let model = Model::new(softcbf::robot_file::load_robot(None).expect("embedded robot")).unwrap();
    let report = model_report(&model, &[0.0; 6], &[0.0; 6]).unwrap();
    let info = report["barrier_info"].as_array().expect("a list");
    assert_eq!(info.len(), model.generated.barrier_table().len());
    let (corners, limits) = info.split_at(12);
    for (k, entry) in limits.iter().enumerate() {
        let what = ["elongation_min", "elongation_max", "bend"][k % 3];
        assert_eq!(entry["kind"], what, "{entry}");
        assert_eq!(entry["module"], k / 3 + 1);
        assert_eq!(entry["domain_default"], true, "{entry}");
        assert_eq!(number(&entry["margin"], "margin"), 0.0);
        if what == "bend" {
            let max = number(&entry["max_bend"], "max_bend");
            assert!((max - 1.25 * std::f64::consts::PI).abs() < 1e-15, "{max}");
            assert_eq!(entry["unit"], "rad");
        } else {
            assert!((number(&entry["min"], "min") + 0.095).abs() < 1e-15);
            assert!((number(&entry["max"], "max") - 0.4).abs() < 1e-15);
            assert_eq!(entry["unit"], "m");
        }
    }
    for (k, entry) in corners.iter().enumerate() {
        assert_eq!(entry["kind"], "plate_corner");
        assert_eq!(entry["module"], k / 6 + 1);
        assert_eq!(entry["corner"], k % 6 + 1);
        assert_eq!(entry["unit"], "m");
        assert_eq!(number(&entry["margin"], "margin"), 0.005);
        assert!(entry.get("obstacle").is_none() && entry.get("min").is_none());
    }
}

/// The CSV names a barrier column `b <label> [<unit>]` with its kind's unit (`rad` for a
/// bend limit, `m` else) and reads the units back.
#[test]
fn csv_columns_carry_each_barriers_unit_and_read_back() {
    let model = every_barrier_model();
    let columns = Columns::for_model(&model, &["loop [us]"]).unwrap();
    let expected = expected_barriers(&model.robot);
    let header = columns.header();
    let names: Vec<&str> = header.split(',').collect();
    let barriers = &names[1 + 4 * 6..1 + 4 * 6 + expected.len()];
    for (name, want) in barriers.iter().zip(&expected) {
        let unit = if want.label.ends_with(" bend") {
            "rad"
        } else {
            "m"
        };
        assert_eq!(*name, format!("b {} [{unit}]", want.label));
    }
    assert_eq!(names.last(), Some(&"loop [us]"));
    assert_eq!(
        barriers.iter().filter(|n| n.ends_with("[rad]")).count(),
        2,
        "{header}"
    );

    let b: Vec<f64> = (0..expected.len()).map(|k| 0.001 * k as f64).collect();
    let mut record = Record::for_columns(columns.clone(), 1);
    record
        .push_row(&Row {
            t: 0.0,
            q: &[0.0; 6],
            qd: &[0.0; 6],
            tau: &[0.0; 6],
            tau_nom: &[0.0; 6],
            b: &b,
            extra: &[1.0],
        })
        .unwrap();
    let mut text = Vec::new();
    record.write_csv_to(&mut text).unwrap();
    let read = Record::parse_csv(&String::from_utf8(text).unwrap(), Path::new("t.csv")).unwrap();
    assert_eq!(read.columns(), &columns);
    assert_eq!(read, record);
    let bend = columns
        .index_of("b module 2 bend [rad]")
        .expect("the bend column");
    assert_eq!(read.column(bend).collect::<Vec<_>>(), [b[17]]);
}

/// Units other than `m` and `rad` are refused where a layout is made; a header with a
/// barrier in `rad` is read; an extra column may not look like a barrier in either unit.
#[test]
fn barrier_units_are_checked() {
    let refused = Columns::named_with_units(&["x"], &["a", "b"], &["m", "deg"], &[]);
    assert!(
        matches!(&refused, Err(RecordError::ColumnName { what: "barrier unit", name, .. }) if name == "deg"),
        "{refused:?}"
    );
    let short = Columns::named_with_units(&["x"], &["a", "b"], &["m"], &[]);
    assert!(matches!(
        short,
        Err(RecordError::UnitCount {
            expected: 2,
            found: 1
        })
    ));
    for extra in ["b near [m]", "b near [rad]"] {
        let error = Columns::named(&["x"], &[], &[extra]).unwrap_err();
        assert!(matches!(
            error,
            RecordError::ColumnName {
                what: "extra column name",
                ..
            }
        ));
    }

    let text = "t [s],x [m],x/dt [m/s],tau x [N],tau_nom x [N],b near [m],b tilt [rad],\
                b odd [deg],loop [us]\n0,1,2,3,4,5,6,7,8\n";
    let read = Record::parse_csv(text, Path::new("t.csv")).unwrap();
    let columns = read.columns();
    assert_eq!(columns.barrier_labels(), ["near", "tilt"]);
    assert_eq!(columns.barrier_units(), ["m", "rad"]);
    // `b odd [deg]` is not a barrier column: it is an extra, kept as written.
    assert_eq!(columns.extra_names(), ["b odd [deg]", "loop [us]"]);
    assert_eq!(read.b(1).collect::<Vec<_>>(), [6.0]);
    assert_eq!(columns.header(), text.lines().next().unwrap());
}

/// A short closed-loop run of `model` toward a set point that presses the first module's
/// elongation limit.
fn short_run(model: &Model, duration: f64) -> Run {
    let text = format!(
        "name = \"short\"\nduration = {duration}\ncontrol_period = 0.001\ncompare = false\n\
         [initial]\nq = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\nqd = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n\
         [reference]\nset_point = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07]\n"
    );
    let scenario = ScenarioFile::parse(&text, Path::new("short.toml"))
        .and_then(|file| file.resolve(model))
        .unwrap_or_else(|e| panic!("{e}"));
    let run = simulate(model, &scenario, true, &mut |_| {}).expect("the run starts");
    assert_eq!(run.summary.stopped, None);
    run
}

/// The group of a barrier read from its label alone (independent of the kind table).
fn group_of_label(label: &str) -> &'static str {
    if label.starts_with("obstacle ") {
        "obstacle"
    } else if label.contains(" elongation ") {
        "elongation"
    } else if label.ends_with(" bend") {
        "bend"
    } else {
        assert!(label.contains(" corner "), "{label}");
        "plate_corner"
    }
}

/// The summary's lowest barrier per kind group equals the lowest value of that group's
/// columns in the run's record, at the time and in the column it names; `summary.json`
/// has every group with its unit, the overall lowest is the lowest of them, and the
/// printed line names each group.
#[test]
fn summary_has_the_lowest_barrier_of_each_kind() {
    let model = every_barrier_model();
    let run = short_run(&model, 0.4);
    let summary = &run.summary;
    let columns = run.record.columns();
    let times: Vec<f64> = run.record.times().collect();

    let json = serde_json::to_value(summary).unwrap();
    let by_kind = &json["lowest_by_kind"];
    let groups = keys(by_kind);
    assert_eq!(groups, ["bend", "elongation", "obstacle", "plate_corner"]);

    let mut overall = f64::INFINITY;
    for group in groups {
        let (mut lowest, mut column, mut row) = (f64::INFINITY, 0, 0);
        for (j, label) in columns.barrier_labels().iter().enumerate() {
            if group_of_label(label) != group {
                continue;
            }
            for (i, b) in run.record.b(j).enumerate() {
                if b < lowest {
                    (lowest, column, row) = (b, j, i);
                }
            }
        }
        let entry = &by_kind[group];
        assert_eq!(number(&entry["value"], group), lowest, "{group}: {entry}");
        assert_eq!(entry["label"], columns.barrier_labels()[column].as_str());
        assert_eq!(number(&entry["t"], group), times[row], "{group}");
        let unit = if group == "bend" { "rad" } else { "m" };
        assert_eq!(entry["unit"], unit);
        assert_eq!(columns.barrier_units()[column], unit);
        overall = overall.min(lowest);
    }
    assert_eq!(summary.min_barrier.value, overall);
    assert_eq!(json["min_barrier"]["value"].as_f64(), Some(overall));
    // The set point pulls δL₁ toward its lower limit: the lowest elongation barrier is
    // met after the start, not at it.
    let elongation = summary.lowest_by_kind.get(KindGroup::Elongation).unwrap();
    assert!(elongation.t > 0.0, "{elongation:?}");

    let line = one_line(summary);
    assert!(line.contains("lowest per kind: plate corners "), "{line}");
    for title in ["elongation limits", "bend limits", "obstacles"] {
        assert!(line.contains(title), "{line}");
    }
    assert!(line.contains(" rad ("), "{line}");
}

/// The paper robot's summary: the lowest corner is the overall lowest, in metres, and the
/// domain's limits every module has are reported per kind beside it, far from zero.
#[test]
fn paper_summary_reports_the_corners_and_the_domain_limits() {
    let model = Model::new(softcbf::robot_file::load_robot(None).expect("embedded robot")).unwrap();
    let run = short_run(&model, 0.2);
    let summary = &run.summary;
    assert_eq!(summary.lowest_by_kind.len(), 3);
    let corners = summary
        .lowest_by_kind
        .get(KindGroup::PlateCorner)
        .expect("corners");
    assert_eq!(corners, &summary.min_barrier);
    assert_eq!((corners.kind, corners.unit), ("plate_corner", "m"));
    for group in [KindGroup::Elongation, KindGroup::Bend] {
        let lowest = summary.lowest_by_kind.get(group).expect("limits");
        assert!(lowest.value > 0.05, "{lowest:?}");
    }
    let json = serde_json::to_value(summary).unwrap();
    assert_eq!(
        keys(&json["lowest_by_kind"]),
        ["bend", "elongation", "plate_corner"]
    );
    let line = one_line(summary);
    assert!(line.contains("lowest per kind: plate corners "), "{line}");
    assert!(line.contains(" m (module "), "{line}");
}

/// Observing values one by one: a group keeps its lowest (NaN never replaces it, `-∞`
/// does), groups the table lacks stay absent, and a row past the table is ignored.
#[test]
fn lowest_by_kind_keeps_each_groups_lowest() {
    const fn row(kind: BarrierKind, module: usize, label: &'static str) -> BarrierInfo {
        BarrierInfo {
            kind,
            module,
            point: None,
            obstacle: None,
            label,
            params: &[],
        }
    }
    let mut corner = row(BarrierKind::PlateCorner, 0, "module 1 corner 1");
    corner.point = Some(Point::Corner(0));
    let table = [
        corner,
        row(BarrierKind::Bend, 0, "module 1 bend"),
        row(BarrierKind::Bend, 1, "module 2 bend"),
    ];
    let mut lowest = LowestByKind::new(&table);
    assert_eq!(lowest.len(), 2);
    assert!(lowest.get(KindGroup::Obstacle).is_none());
    assert!(lowest.get(KindGroup::Elongation).is_none());
    assert_eq!(lowest.get(KindGroup::Bend).unwrap().unit, "rad");
    assert!(lowest.line().is_some());

    lowest.observe_all(&table, &[0.3, 0.2, 0.1], 1.0);
    lowest.observe_all(&table, &[0.4, f64::NAN, 0.15], 2.0);
    lowest.observe(&table, 7, -5.0, 3.0);
    let bend = lowest.get(KindGroup::Bend).unwrap();
    assert_eq!(
        (bend.value, bend.label, bend.t, bend.module),
        (0.1, "module 2 bend", 1.0, 2)
    );
    assert_eq!(bend.corner, 0);
    let corner = lowest.get(KindGroup::PlateCorner).unwrap();
    assert_eq!(
        (corner.value, corner.corner, corner.kind),
        (0.3, 1, "plate_corner")
    );

    lowest.observe(&table, 1, f64::NEG_INFINITY, 4.0);
    let bend = lowest.get(KindGroup::Bend).unwrap();
    assert_eq!(
        (bend.value, bend.label),
        (f64::NEG_INFINITY, "module 1 bend")
    );
    let json = serde_json::to_value(&lowest).unwrap();
    assert_eq!(keys(&json), ["bend", "plate_corner"]);
    assert_eq!(json["bend"]["value"], Value::Null);
}
