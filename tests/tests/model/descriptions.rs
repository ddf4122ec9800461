//! Description files under hostile input (issue 9): the ranges of `limits` keep the model and
//! the tick finite at their ends, endless files fail fast, mutated shipped files never panic.

use std::f64::consts::FRAC_1_SQRT_2;
use std::path::Path;
use std::time::{Duration, Instant};

use proptest::prelude::*;
use rand::RngExt;
use serde_json::Value;
use softcbf::control::{
    Controller, ControllerSettings, InvalidState, Reference, SafetyMode, TickStatus,
    scaled_identity, tick,
};
use softcbf::hardware_description::{self as description, Hardware};
use softcbf::inspect::model_report;
use softcbf::model::Model;
use softcbf::reference::{ReferenceSignal, ReferenceSpec};
use softcbf::scenario::ScenarioFile;
use softcbf_description::domain;
use softcbf_description::limits::{self, Limit};
use softcbf_description::robot::Robot;
use softcbf_description::toml_file::{self, FileError};
use softcbf_tests::TestRng;

// ---------------------------------------------------------------------------------------
// Helpers.

/// The lowest value `limit` allows (a tiny positive number for `> 0`).
fn lowest(limit: &Limit) -> f64 {
    if limit.min_inclusive {
        limit.min
    } else {
        assert_eq!(limit.min, 0.0, "only `> 0` ranges are open");
        1e-300
    }
}

/// One end of `limit`.
fn end(limit: &Limit, high: bool) -> f64 {
    if high { limit.max } else { lowest(limit) }
}

/// The first path in a JSON value whose number is not finite (serde_json writes NaN and
/// infinities as `null`), if any.
fn non_finite(value: &Value, path: &str) -> Option<String> {
    match value {
        Value::Null => Some(format!("{path} = null")),
        Value::Number(n) => match n.as_f64() {
            Some(x) if x.is_finite() => None,
            _ => Some(format!("{path} = {n}")),
        },
        Value::Array(items) => items
            .iter()
            .enumerate()
            .find_map(|(k, v)| non_finite(v, &format!("{path}[{k}]"))),
        Value::Object(map) => map
            .iter()
            .find_map(|(k, v)| non_finite(v, &format!("{path}.{k}"))),
        Value::Bool(_) | Value::String(_) => None,
    }
}

fn paper_model() -> Model {
    Model::new(Robot::paper_sim()).expect("the paper model is generated")
}

/// The shipped description files, read from the repository.
fn shipped(relative: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(relative);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

// ---------------------------------------------------------------------------------------
// The ranges are enough.

/// Module fields whose range is one `Limit`, written at one of its ends.
const MODULE_NUMBERS: [(&str, Limit); 10] = [
    ("rest_length", limits::LENGTH_M),
    ("tendon_radius", limits::LENGTH_M),
    ("corner_radius", limits::LENGTH_M),
    ("mass", limits::MASS_KG),
    ("com_offset", limits::COM_OFFSET_M),
    ("bending_stiffness", limits::BENDING_STIFFNESS),
    ("axial_stiffness", limits::AXIAL_STIFFNESS),
    ("bending_damping", limits::BENDING_DAMPING),
    ("axial_damping", limits::AXIAL_DAMPING),
    ("margin", limits::MARGIN_M),
];

/// The two generated structures: the paper's (2 modules, hexagons) and three-square's (3
/// modules, squares), with angles written at the ends of their range (the same directions
/// as the shipped files: −360° ≡ 0°, −270° ≡ 90°).
const STRUCTURES: [(usize, &str); 2] = [
    (2, "[-360, -300, -240, -180, -120, -60]"),
    (3, "[-315, -225, -135, -45]"),
];

/// How each number of a robot is chosen.
#[derive(Clone, Copy, Debug)]
enum Pick {
    /// Every number at its lower end.
    Low,
    /// Every number at its upper end.
    High,
    /// Module `i` at the lower end when `i` is even, at the upper end when odd.
    Alternate,
    /// Lengths at the upper end, everything else at the lower end (a huge light robot).
    LongAndLight,
    /// Lengths at the lower end, everything else at the upper end (a tiny heavy stiff one).
    ShortAndHeavy,
    /// Each number at a random end.
    Random,
}

/// A robot file with every number at an end of its range, as `pick` chooses.
fn extreme_robot(modules: usize, corners: &str, pick: Pick, rng: &mut TestRng) -> String {
    let mut choose = |module: usize, name: &str| -> bool {
        let length = matches!(name, "rest_length" | "tendon_radius" | "corner_radius");
        match pick {
            Pick::Low => false,
            Pick::High => true,
            Pick::Alternate => module % 2 == 1,
            Pick::LongAndLight => length,
            Pick::ShortAndHeavy => !length,
            Pick::Random => rng.random::<bool>(),
        }
    };
    let gravity: Vec<String> = (0..3)
        .map(|k| {
            let high = choose(k, "gravity");
            let g = end(&limits::GRAVITY_M_S2, high);
            g.to_string()
        })
        .collect();
    let gain = |high: bool| end(&limits::BARRIER_GAIN_PER_S, high);
    let mut text = format!(
        "gravity = [{}]\n[barrier]\np1 = {:e}\np2 = {:e}\n",
        gravity.join(", "),
        gain(choose(0, "p1")),
        gain(choose(1, "p2")),
    );
    for i in 0..modules {
        text += &format!(
            "[[module]]\ncorner_angles_deg = {corners}\ntendon_angles_deg = [-270, -150, -30]\n"
        );
        for (name, limit) in &MODULE_NUMBERS {
            text += &format!("{name} = {:e}\n", end(limit, choose(i, name)));
        }
        let inertia = &limits::INERTIA_KG_M2;
        // The inertia: the default polygon (from mass and radius), or given at an end.
        match (choose(i, "inertia given"), choose(i, "inertia")) {
            (false, _) => {}
            (true, high) => {
                let moment = end(inertia, high);
                text += &format!("inertia = [{moment:e}, {moment:e}, {moment:e}]\n");
            }
        }
    }
    text
}

/// States at the corners of the domain of `robot`: each module bent by (just under) the
/// largest bend in one of several directions, or straight, or barely bent (the small-θ
/// series), elongated by ten rest lengths or compressed to a millionth of its rest length;
/// velocities at ±100 m/s.
fn corner_states(robot: &Robot, rng: &mut TestRng, count: usize) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut states = Vec::new();
    for k in 0..count {
        let mut q = Vec::new();
        let mut qd = Vec::new();
        for module in &robot.modules {
            let full = domain::MAX_BEND_RAD * module.tendon_radius * (1.0 - 1e-12);
            let bend = match (k + rng.random_range(0..4)) % 4 {
                0 => [full, 0.0],
                1 => [-full * FRAC_1_SQRT_2, full * FRAC_1_SQRT_2],
                2 => [0.0, 0.0],
                _ => [1e-9 * module.tendon_radius, 0.0],
            };
            let stretch = domain::MAX_ELONGATION_RATIO * module.rest_length;
            let squeeze = -(1.0 - 1e-6) * module.rest_length;
            let elongation = [stretch, squeeze, 0.0][rng.random_range(0..3)];
            q.extend([bend[0], bend[1], elongation]);
            for _ in 0..3 {
                qd.push([domain::MAX_SPEED, -domain::MAX_SPEED, 0.0][rng.random_range(0..3)]);
            }
        }
        assert!(
            domain::state_problem(robot, &q, &qd).is_none(),
            "{q:?} {qd:?}"
        );
        states.push((q, qd));
    }
    states
}

/// Settings at the ends of their ranges: the stiffest gains, the robot's barrier gains,
/// the hold correction of the slowest loop.
fn extreme_settings(model: &Model, rng: &mut TestRng) -> ControllerSettings {
    let nq = model.nq();
    let mut settings = ControllerSettings::paper(model);
    settings.kp = scaled_identity(nq, end(&limits::KP_N_PER_M, rng.random::<bool>()));
    settings.kd = scaled_identity(nq, end(&limits::KD_N_S_PER_M, rng.random::<bool>()));
    settings.hold = limits::CONTROL_PERIOD_S.max;
    settings.safety = if rng.random::<bool>() {
        SafetyMode::HoldCorrection
    } else {
        SafetyMode::Paper
    };
    settings
}

/// With every robot number at an end of its range (several combinations), at the corners
/// of the state domain, `softcbf model` reports only finite numbers and the control tick
/// computes a command (no non-finite model, no failed factorization), toward a reference
/// at another corner with the largest acceleration the waypoint spacing allows.
#[test]
fn the_ranges_keep_the_model_and_the_tick_finite() {
    let mut rng = softcbf_tests::rng(0x5EED_CBF0_0009);
    let picks = [
        Pick::Low,
        Pick::High,
        Pick::Alternate,
        Pick::LongAndLight,
        Pick::ShortAndHeavy,
    ];
    let mut statuses: Vec<(String, TickStatus)> = Vec::new();
    let mut robots = 0;
    for (modules, corners) in STRUCTURES {
        let random = std::iter::repeat_n(Pick::Random, 24);
        for pick in picks.into_iter().chain(random) {
            let text = extreme_robot(modules, corners, pick, &mut rng);
            let robot = Robot::parse(&text, Path::new("extreme.toml")).unwrap_or_else(|e| {
                panic!("{pick:?}: the ends of the ranges are refused: {e}\n{text}")
            });
            let model = Model::new(robot.clone()).expect("a generated structure");
            let settings = extreme_settings(&model, &mut rng);
            let mut controller = Controller::new(&model, settings).expect("valid settings");
            let states = corner_states(&robot, &mut rng, 12);
            for (k, (q, qd)) in states.iter().enumerate() {
                let report = model_report(&model, q, qd).expect("state of the right length");
                if let Some(bad) = non_finite(&report, "report") {
                    panic!("{pick:?}: {bad} at q = {q:?}, q̇ = {qd:?}\n{text}");
                }
                // Toward another corner, at the steepest point of the shortest blend.
                let (target, _) = &states[(k + 1) % states.len()];
                let period = limits::CONTROL_PERIOD_S.min;
                let mut signal = ReferenceSignal::new(ReferenceSpec::Waypoints(vec![
                    (0.0, q.clone()),
                    (period, target.clone()),
                ]));
                let reference: Reference<'_> = signal.sample(0.2113 * period);
                assert!(reference.qdd.iter().all(|x| x.is_finite()));
                let status = tick(&model, &mut controller, q, qd, reference);
                assert!(
                    controller.tau().iter().all(|t| t.is_finite()),
                    "{pick:?}: τ = {:?}",
                    controller.tau()
                );
                statuses.push((format!("{pick:?} robot {robots} state {k}"), status));
            }
            robots += 1;
        }
    }
    let failed: Vec<&(String, TickStatus)> = statuses
        .iter()
        .filter(|(_, s)| {
            matches!(
                s,
                TickStatus::InvalidState(InvalidState::NonFiniteModel | InvalidState::MassMatrix)
            )
        })
        .collect();
    assert!(
        failed.is_empty(),
        "{} of {} ticks could not compute a command: {:?}",
        failed.len(),
        statuses.len(),
        &failed[..failed.len().min(10)]
    );
    assert!(robots >= 58 && statuses.len() >= 58 * 12);
}

/// The smallest pivot of the Cholesky factorization of the symmetric matrix `m`, relative
/// to its largest diagonal entry (negative or zero: not positive definite).
fn relative_pivot(m: &[Vec<f64>]) -> f64 {
    let n = m.len();
    let mut l = vec![vec![0.0; n]; n];
    let scale = (0..n).fold(0.0_f64, |s, i| s.max(m[i][i]));
    let mut lowest = f64::INFINITY;
    for j in 0..n {
        let d = m[j][j] - (0..j).map(|k| l[j][k] * l[j][k]).sum::<f64>();
        lowest = lowest.min(d / scale);
        if d <= 0.0 {
            return lowest;
        }
        l[j][j] = d.sqrt();
        for i in j + 1..n {
            let s = m[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            l[i][j] = s / l[j][j];
        }
    }
    lowest
}

fn mass_matrix(model: &Model, q: &[f64]) -> Vec<Vec<f64>> {
    let report = model_report(model, q, &vec![0.0; q.len()]).expect("state of the right length");
    let rows = report["mass_matrix"].as_array().expect("mass_matrix rows");
    rows.iter()
        .map(|row| {
            let row = row.as_array().expect("a row");
            row.iter().map(|x| x.as_f64().expect("a number")).collect()
        })
        .collect()
}

/// Why the bend stops at 1.5π: at a full turn the plate is back on its base whatever the
/// direction of the bend and the length, so the mass matrix loses rank; at the bound it is
/// still well conditioned.
#[test]
fn the_largest_bend_stays_clear_of_the_full_turn_singularity() {
    let model = paper_model();
    let d = model.robot.modules[1].tendon_radius;
    let bent = |theta: f64| {
        let mut q = vec![0.0; 6];
        q[3] = theta * d;
        relative_pivot(&mass_matrix(&model, &q))
    };
    let full_turn = bent(2.0 * std::f64::consts::PI);
    assert!(
        full_turn < 1e-25,
        "M at a full turn: relative pivot {full_turn:e}"
    );
    let at_bound = bent(domain::MAX_BEND_RAD);
    assert!(
        at_bound > 1e-3,
        "M at the largest bend: relative pivot {at_bound:e}"
    );
    assert!(bent(0.5 * domain::MAX_BEND_RAD) > at_bound);
}

// ---------------------------------------------------------------------------------------
// The minimum-jerk reference at the smallest waypoint spacing.

/// Waypoints one shortest control period apart, late in the longest run, between opposite
/// corners of the domain, read from a scenario file: every sample of the blend is finite,
/// and the tick on it computes a command. (Before the spacing rule, waypoints at 0 and
/// 1e-300 s gave a NaN tick.)
#[test]
fn the_shortest_blend_between_far_corners_stays_finite() {
    let model = paper_model();
    let d = model.robot.modules[0].tendon_radius;
    let bend = domain::MAX_BEND_RAD * d * (1.0 - 1e-12);
    let stretch = domain::MAX_ELONGATION_RATIO * model.robot.modules[0].rest_length;
    let squeeze = -(1.0 - 1e-6) * model.robot.modules[0].rest_length;
    let a = [bend, 0.0, stretch, 0.0, -bend, squeeze];
    let b = [-bend, 0.0, squeeze, 0.0, bend, stretch];
    let list = |q: &[f64]| {
        let items: Vec<String> = q.iter().map(|x| format!("{x:e}")).collect();
        items.join(", ")
    };
    let (period, t_end) = (limits::CONTROL_PERIOD_S.min, limits::WAYPOINT_TIME_S.max);
    let t_start = t_end - period;
    let text = format!(
        "duration = 10\ncontrol_period = {period:e}\n\
         [reference]\nwaypoints = [\n  {{ t = {t_start:.6}, q = [{}] }},\n  {{ t = {t_end:e}, q = [{}] }},\n]\n\
         [gains]\nkp = {:e}\nkd = {:e}\np1 = {:e}\np2 = {:e}\n",
        list(&a),
        list(&b),
        limits::KP_N_PER_M.max,
        limits::KD_N_S_PER_M.max,
        limits::BARRIER_GAIN_PER_S.max,
        limits::BARRIER_GAIN_PER_S.max,
    );
    let scenario = ScenarioFile::parse(&text, Path::new("scenarios/blend.toml"))
        .and_then(|file| file.resolve(&model))
        .unwrap_or_else(|e| panic!("{e}\n{text}"));
    let ReferenceSpec::Waypoints(points) = &scenario.reference else {
        panic!("waypoints expected");
    };
    let span = points[1].0 - points[0].0;
    assert!(
        span >= period * (1.0 - 1e-9) && span < 1.1 * period,
        "{span:e}"
    );
    let mut signal = ReferenceSignal::new(scenario.reference.clone());
    let mut controller = Controller::new(&model, scenario.controller.clone()).unwrap();
    let mut steepest = 0.0_f64;
    for k in 0..=200 {
        let t = points[0].0 + span * (f64::from(k) / 200.0 - 0.25) * 1.5;
        let reference = signal.sample(t);
        let values = reference.q.iter().chain(reference.qd).chain(reference.qdd);
        assert!(values.clone().all(|x| x.is_finite()), "t = {t}");
        steepest = values.fold(steepest, |m, x| m.max(x.abs()));
        let status = tick(&model, &mut controller, &a, &[0.0; 6], reference);
        assert!(controller.tau().iter().all(|x| x.is_finite()));
        assert!(
            !matches!(status, TickStatus::InvalidState(_)),
            "t = {t}: {status:?}"
        );
    }
    // The largest acceleration of a minimum-jerk blend is 10/√3·Δq/T² (at σ = 1/2 − √3/6):
    // here Δq = 1.1 m (δL₁ from its largest stretch to its deepest squeeze) over ~1e-6 s,
    // about 6e12 m/s², far from overflowing.
    let bound = 10.0 / 3f64.sqrt() * (stretch - squeeze) / (span * span);
    assert!(steepest <= bound * (1.0 + 1e-6), "{steepest:e} > {bound:e}");
    assert!(steepest > 0.9 * bound, "{steepest:e} vs {bound:e}");
}

// ---------------------------------------------------------------------------------------
// Files that never end.

#[track_caller]
fn assert_too_large(error: FileError, path: &Path) {
    let message = error.to_string();
    assert!(
        message.starts_with(&format!("{}: cannot read", path.display()))
            && message.contains("larger than 1048576 bytes (1 MiB)"),
        "{message}"
    );
}

/// `--robot /dev/zero` grew to 1.9 GB in 4 s: reading now stops after 1 MiB, for robot and
/// scenario files alike, and for a pipe whose writer never stops.
#[test]
fn endless_files_fail_fast_with_the_file_and_the_limit() {
    let zero = Path::new("/dev/zero");
    if zero.exists() {
        let started = Instant::now();
        assert_too_large(Robot::load(zero).unwrap_err(), zero);
        assert_too_large(ScenarioFile::load(zero).unwrap_err(), zero);
        assert!(started.elapsed() < Duration::from_secs(5));
    }
    endless_pipe();
}

/// A FIFO fed by a writer that never stops (Unix, when `mkfifo` is available).
fn endless_pipe() {
    let dir = std::env::temp_dir().join(format!("softcbf-descriptions-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("endless.toml");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|status| status.success()) {
        eprintln!("mkfifo unavailable: the pipe case is skipped");
        let _ = std::fs::remove_dir_all(&dir);
        return;
    }
    let writer_path = fifo.clone();
    // The writer stops when the reader closes its end (EPIPE: Rust ignores SIGPIPE).
    std::thread::spawn(move || {
        use std::io::Write;
        if let Ok(mut pipe) = std::fs::OpenOptions::new().write(true).open(&writer_path) {
            let line = b"# an endless comment\n".repeat(1000);
            while pipe.write_all(&line).is_ok() {}
        }
    });
    let started = Instant::now();
    assert_too_large(Robot::load(&fifo).unwrap_err(), &fifo);
    assert!(started.elapsed() < Duration::from_secs(5));
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------
// Random mutations of the shipped files.

/// Text that replaces a number or a value: extremes, signed zeros, NaN, huge integers,
/// wrong types, empty and nested arrays.
const HOSTILE: [&str; 28] = [
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "4.9e-324",
    "-0",
    "-0.0",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "0",
    "-1",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999999",
    "0x7FFFFFFF",
    "1_000",
    "\"text\"",
    "\"\"",
    "[]",
    "[[]]",
    "[1e308, -1e308, nan]",
    "[[1, 2], [3, 4]]",
    "{}",
    "{ t = 0, q = [] }",
    "true",
    "1979-05-27T07:32:00Z",
    "[0, 0, 0, 0, 0, 0, 0, 0, 0]",
];

/// One change to a file's bytes; indices are taken modulo what the file has.
#[derive(Clone, Debug)]
enum Mutation {
    /// XOR one byte with a non-zero mask (may leave invalid UTF-8).
    FlipByte(usize, u8),
    /// Remove a line.
    DeleteLine(usize),
    /// Repeat a line (duplicate keys and tables).
    DuplicateLine(usize),
    /// Replace the k-th number of the file.
    ReplaceNumber(usize, &'static str),
    /// Replace the value of the k-th `key = value` line.
    ReplaceValue(usize, &'static str),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let hostile = proptest::sample::select(&HOSTILE[..]);
    prop_oneof![
        (any::<usize>(), 1..=255u8).prop_map(|(at, mask)| Mutation::FlipByte(at, mask)),
        any::<usize>().prop_map(Mutation::DeleteLine),
        any::<usize>().prop_map(Mutation::DuplicateLine),
        (any::<usize>(), hostile.clone()).prop_map(|(k, v)| Mutation::ReplaceNumber(k, v)),
        (any::<usize>(), hostile).prop_map(|(k, v)| Mutation::ReplaceValue(k, v)),
    ]
}

/// Byte ranges of the numbers written in `text` (outside names such as `p1`).
fn numbers(text: &[u8]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let starts = text[i].is_ascii_digit()
            || (matches!(text[i], b'-' | b'+') && text.get(i + 1).is_some_and(u8::is_ascii_digit));
        let after_name = i > 0 && (text[i - 1].is_ascii_alphanumeric() || text[i - 1] == b'_');
        if starts && !after_name {
            let start = i;
            i += 1;
            while i < text.len()
                && (text[i].is_ascii_digit() || matches!(text[i], b'.' | b'e' | b'E' | b'_'))
                || (i < text.len()
                    && matches!(text[i], b'-' | b'+')
                    && matches!(text[i - 1], b'e' | b'E'))
            {
                i += 1;
            }
            out.push(start..i);
        } else {
            i += 1;
        }
    }
    out
}

fn apply(original: &str, mutations: &[Mutation]) -> Vec<u8> {
    let mut bytes = original.as_bytes().to_vec();
    for mutation in mutations {
        let lines: Vec<&[u8]> = bytes.split(|&b| b == b'\n').collect();
        let joined = |lines: Vec<&[u8]>| lines.join(&b'\n');
        bytes = match *mutation {
            Mutation::FlipByte(at, mask) if !bytes.is_empty() => {
                let mut changed = bytes.clone();
                let at = at % changed.len();
                changed[at] ^= mask;
                changed
            }
            Mutation::DeleteLine(k) if !lines.is_empty() => {
                let mut lines = lines;
                let k = k % lines.len();
                lines.remove(k);
                joined(lines)
            }
            Mutation::DuplicateLine(k) if !lines.is_empty() => {
                let mut lines = lines;
                let k = k % lines.len();
                lines.insert(k, lines[k]);
                joined(lines)
            }
            Mutation::ReplaceNumber(k, with) => {
                let found = numbers(&bytes);
                if found.is_empty() {
                    bytes
                } else {
                    let range = found[k % found.len()].clone();
                    let mut changed = bytes[..range.start].to_vec();
                    changed.extend_from_slice(with.as_bytes());
                    changed.extend_from_slice(&bytes[range.end..]);
                    changed
                }
            }
            Mutation::ReplaceValue(k, with) => {
                let assignments: Vec<usize> = (0..lines.len())
                    .filter(|&i| lines[i].contains(&b'=') && !lines[i].starts_with(b"#"))
                    .collect();
                if assignments.is_empty() {
                    bytes
                } else {
                    let i = assignments[k % assignments.len()];
                    let equals = lines[i].iter().position(|&b| b == b'=').unwrap_or(0);
                    let line = [&lines[i][..=equals], b" ", with.as_bytes()].concat();
                    let mut lines = lines;
                    lines[i] = &line;
                    joined(lines)
                }
            }
            _ => bytes,
        };
    }
    bytes
}

/// An error names the file, and a line within the file where it has one.
fn check_error(error: &FileError, path: &Path, text: Option<&str>) -> Result<(), TestCaseError> {
    let message = error.to_string();
    let name = path.display().to_string();
    prop_assert!(
        message.starts_with(&format!("{name}:")),
        "does not name the file: {message}"
    );
    let lines = text.map_or(usize::MAX, |t| t.split('\n').count());
    match error {
        FileError::Syntax { line, column, .. } => {
            prop_assert!(*line >= 1 && *line <= lines && *column >= 1, "{message}");
        }
        FileError::Invalid { line, field, .. } => {
            prop_assert!(*line >= 1 && *line <= lines, "{message}");
            prop_assert!(!field.is_empty(), "{message}");
        }
        FileError::Io { .. } => prop_assert!(false, "no file was read: {message}"),
    }
    Ok(())
}

/// An accepted robot gives a finite model at rest, straight and at its set point, and a
/// computed command.
fn check_robot(robot: Robot, hardware: Option<Hardware>) -> Result<(), TestCaseError> {
    let Ok(model) = Model::new(robot) else {
        return Ok(()); // a structure this build has no model for: refused elsewhere
    };
    let nq = model.nq();
    let mut states = vec![vec![0.0; nq]];
    if let Some(hardware) = &hardware {
        states.push(hardware.set_point.clone());
    }
    let mut controller = Controller::new(&model, ControllerSettings::paper(&model))
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    for q in &states {
        let report = model_report(&model, q, &vec![0.0; nq]).expect("state of the right length");
        prop_assert!(
            non_finite(&report, "report").is_none(),
            "{:?}",
            non_finite(&report, "")
        );
        let zeros = vec![0.0; nq];
        let reference = Reference {
            q: &zeros,
            qd: &zeros,
            qdd: &zeros,
        };
        let status = tick(&model, &mut controller, q, &zeros, reference);
        prop_assert!(controller.tau().iter().all(|t| t.is_finite()));
        prop_assert!(!matches!(status, TickStatus::InvalidState(_)), "{status:?}");
    }
    Ok(())
}

/// The shipped robot files and the scenario files with the model each one runs on.
struct Shipped {
    robots: Vec<(&'static str, String)>,
    scenarios: Vec<(&'static str, String, Model)>,
}

fn shipped_files() -> &'static Shipped {
    static FILES: std::sync::OnceLock<Shipped> = std::sync::OnceLock::new();
    FILES.get_or_init(|| {
        let robots: Vec<(&'static str, String)> = [
            "robots/paper-sim.toml",
            "robots/three-square.toml",
            "robots/hardware-example.toml",
        ]
        .into_iter()
        .map(|path| (path, shipped(path)))
        .collect();
        let model = |path: &str| {
            let text = shipped(path);
            Model::new(Robot::parse(&text, Path::new(path)).unwrap()).unwrap()
        };
        let scenarios = vec![
            (
                "scenarios/paper-sim.toml",
                shipped("scenarios/paper-sim.toml"),
                model("robots/paper-sim.toml"),
            ),
            (
                "scenarios/three-square.toml",
                shipped("scenarios/three-square.toml"),
                model("robots/three-square.toml"),
            ),
        ];
        Shipped { robots, scenarios }
    })
}

proptest! {
    // About 0.1 ms a case in release builds: about a second for both properties.
    #![proptest_config(ProptestConfig { cases: 4000, ..ProptestConfig::default() })]

    /// Mutated robot files: never a panic; an error names the file and a line in it; an
    /// accepted robot has a finite model and a computed command.
    #[test]
    fn mutated_robot_files_are_refused_or_safe(
        file in 0..3usize,
        mutations in proptest::collection::vec(mutation(), 1..4),
    ) {
        let (name, original) = &shipped_files().robots[file];
        let path = Path::new(name);
        let bytes = apply(original, &mutations);
        match toml_file::decode(bytes, path) {
            Err(error) => check_error(&error, path, None)?,
            Ok(text) => match Robot::parse(&text, path)
                .and_then(|robot| Ok((description::load(&robot)?, robot)))
            {
                Err(error) => check_error(&error, path, Some(&text))?,
                Ok((hardware, robot)) => check_robot(robot, hardware)?,
            },
        }
    }

    /// Mutated scenario files, resolved against their robot: never a panic; an error names
    /// the file and a line in it; an accepted scenario has a finite reference over the run
    /// and the tick at its initial state computes a command.
    #[test]
    fn mutated_scenario_files_are_refused_or_safe(
        file in 0..2usize,
        mutations in proptest::collection::vec(mutation(), 1..4),
    ) {
        let (name, original, model) = &shipped_files().scenarios[file];
        let path = Path::new(name);
        let bytes = apply(original, &mutations);
        let text = match toml_file::decode(bytes, path) {
            Err(error) => return check_error(&error, path, None),
            Ok(text) => text,
        };
        let scenario = match ScenarioFile::parse(&text, path).and_then(|f| f.resolve(model)) {
            Err(error) => return check_error(&error, path, Some(&text)),
            Ok(scenario) => scenario,
        };
        prop_assert!(scenario.duration >= scenario.control_period);
        prop_assert!(domain::state_problem(&model.robot, &scenario.initial_q, &scenario.initial_qd).is_none());
        let mut signal = ReferenceSignal::new(scenario.reference.clone());
        let mut controller = Controller::new(model, scenario.controller.clone())
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        for k in 0..=8 {
            let t = scenario.duration * f64::from(k) / 8.0;
            let reference = signal.sample(t);
            let status = tick(model, &mut controller, &scenario.initial_q, &scenario.initial_qd, reference);
            prop_assert!(controller.tau().iter().all(|x| x.is_finite()));
            prop_assert!(!matches!(status, TickStatus::InvalidState(_)), "t = {}: {:?}", t, status);
        }
    }
}

#[test]
fn scenario_syntax_errors_name_the_field_like_robot_files() {
    // Scenario files go through the same reader: a TOML syntax error names the field being
    // written, its table, and how to write it.
    let path = Path::new("scenarios/x.toml");
    let cases = [
        (
            "duration = 10 s\n",
            "scenarios/x.toml:1:12: field `duration`: `10 s` is not a value; write text in \
             quotes (\"10 s\"), numbers as digits (0.1, 2e-3), true or false, or a list [a, b]",
        ),
        (
            "[reference]\nset_point = [0.08 0.0, -0.05, 0.0, -0.06, -0.07]\n",
            "scenarios/x.toml:2:14: field `reference.set_point`, entry 1: `0.08 0.0` is not one \
             value; separate the entries of a list with commas: 0.08, 0.0",
        ),
        (
            "[gains]\nkp = 5 5 5 5 5 5\n",
            "scenarios/x.toml:2:6: field `gains.kp`: `5 5 5 5 5 5` is not a number; write one \
             number, or a list as [5, 5, 5, 5, 5, 5]",
        ),
        (
            "[reference]\nwaypoints = [{ t = 0.0, q = [0, 0, 0, 0, 0, 0] },\n  { t = 2.0, q = [0, 0 0] }]\n",
            "scenarios/x.toml:3:22: field `reference.waypoints[2].q`, entry 2: `0 0` is not one \
             value; separate the entries of a list with commas: 0, 0",
        ),
    ];
    for (text, expected) in cases {
        match ScenarioFile::parse(text, path) {
            Ok(_) => panic!("accepted: {text}"),
            Err(error) => assert_eq!(error.to_string(), expected, "{text}"),
        }
    }
}
