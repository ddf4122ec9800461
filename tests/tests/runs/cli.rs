//! What `softcbf model` reads and prints: `--q`/`--qd` parsing (length, numbers, the state
//! domain), numbers checked by the shared limits, robot files that never end, and the
//! report's JSON keys, shapes and values against the hand-written reference evaluation.
//!
//! The binary itself is not run: `CARGO_BIN_EXE_softcbf` exists only for the runtime
//! package's own tests, so this tests the library functions `main` calls
//! (`softcbf::cli::parse_vector`, `softcbf::inspect::model_report`).

use serde_json::Value;
use std::path::Path;
use std::time::{Duration, Instant};

use softcbf::cli::{
    parse_coordinates, parse_integer, parse_number, parse_vector, parse_velocities,
};
use softcbf::hardware_description::limits as servo;
use softcbf::inspect::model_report;
use softcbf::model::Model;
use softcbf::robot_file::load_robot;
use softcbf::settings::check_number;
use softcbf_description::limits;
use softcbf_tests::reference::{self, Jet};

fn error_of(text: &str, expected: usize) -> String {
    match parse_vector("--q", text, expected) {
        Ok(values) => panic!("`{text}` accepted as {values:?}"),
        Err(message) => message,
    }
}

#[test]
fn parse_vector_reads_finite_numbers() {
    let got = parse_vector("--q", "0.01, -0.02,0,1e-3 ,-0, 3", 6).expect("valid input");
    assert_eq!(got, vec![0.01, -0.02, 0.0, 1e-3, 0.0, 3.0]);
    assert_eq!(
        parse_vector("--qd", "-5e-1", 1).expect("valid input"),
        [-0.5]
    );
}

#[test]
fn parse_vector_rejects_wrong_length() {
    for (text, given) in [("1,2,3", 3), ("1,2,3,4,5,6,7", 7), ("0", 1)] {
        let message = error_of(text, 6);
        assert!(
            message.contains("--q") && message.contains(&format!("{given} values given")),
            "`{text}`: {message}"
        );
        assert!(message.contains("6 coordinates"), "`{text}`: {message}");
    }
}

#[test]
fn parse_vector_rejects_non_numbers() {
    for (text, entry, item) in [
        ("0,abc,0,0,0,0", 2, "abc"),
        ("0,0,0,0,0,", 6, ""),
        ("", 1, ""),
        ("0;0;0;0;0;0", 1, "0;0;0;0;0;0"),
        ("1,2,0x10,4,5,6", 3, "0x10"),
    ] {
        let message = error_of(text, 6);
        assert!(
            message.contains(&format!("entry {entry} `{item}` is not a number")),
            "`{text}`: {message}"
        );
    }
}

#[test]
fn parse_vector_rejects_nan_and_infinity() {
    for (text, entry) in [
        ("NaN,0,0,0,0,0", 1),
        ("0,0,nan,0,0,0", 3),
        ("0,0,0,inf,0,0", 4),
        ("0,0,0,0,-infinity,0", 5),
        ("0,0,0,0,0,1e400", 6),
    ] {
        let message = error_of(text, 6);
        assert!(
            message.contains(&format!("entry {entry} is")) && message.contains("finite"),
            "`{text}`: {message}"
        );
    }
}

/// `--q` lies in the state domain of the paper robot (`d` = 0.04 m, `L0` = 0.1 m): a bend
/// of at most 1.5π·0.04 = 0.1885 m, an elongation of at most 1 m, a positive backbone
/// length `0.1 m + δL`.
#[test]
fn coordinates_lie_in_the_state_domain() {
    let robot = load_robot(None).expect("embedded robot");
    let q =
        parse_coordinates("--q", "0.108, 0.144, 1, 0, -0.188, -0.0999", &robot).expect("inside");
    assert_eq!(q, [0.108, 0.144, 1.0, 0.0, -0.188, -0.0999]);
    for (text, fragment) in [
        ("1e308,0,0,0,0,0", "--q: module 1 bends by θ = inf rad"),
        ("0,0,0,0.12,0.15,0", "--q: module 2 bends by"),
        (
            "0,0,0,0,0,1.5",
            "--q: entry 6 (δL of module 2) is 1.5e0 m; δL must be ≤ 1 m",
        ),
        // The example: a backbone of −0.1 m.
        (
            "0,0,-0.2,0,0,0",
            "--q: entry 3 (δL of module 1) is -0.2 m: the backbone length L0 + δL = -0.1 m is \
             not positive (L0 = 0.1 m); δL must be > -0.1 m",
        ),
        (
            "0,0,0,0,0,-0.1",
            "--q: entry 6 (δL of module 2) is -0.1 m: the backbone length L0 + δL = 0 m",
        ),
        (
            "0,0,nan,0,0,0",
            "--q: entry 3 is NaN; values must be finite",
        ),
        ("0,0,0", "--q: 3 values given, the robot has 6 coordinates"),
    ] {
        let message = parse_coordinates("--q", text, &robot).unwrap_err();
        assert!(message.starts_with(fragment), "`{text}`: {message}");
    }
    let qd = parse_velocities("--qd", "100,-100,0,0,0,0.5", &robot).expect("inside");
    assert_eq!(qd[1], -100.0);
    let message = parse_velocities("--qd", "0,0,0,0,-100.5,0", &robot).unwrap_err();
    assert!(
        message.starts_with("--qd: entry 5 is -1.005e2 m/s; speeds must be ≤ 100 m/s"),
        "{message}"
    );
}

/// Numbers of the command line are checked by the same limits as the files.
#[test]
fn numbers_are_checked_by_the_shared_limits() {
    assert_eq!(
        parse_number("--timeout-ms", "1e300", &servo::REPLY_TIMEOUT_MS).unwrap_err(),
        "--timeout-ms: must be > 0 and ≤ 1000 ms, got 1e300"
    );
    assert_eq!(
        parse_number("--timeout-ms", " 25 ", &servo::REPLY_TIMEOUT_MS),
        Ok(25.0)
    );
    assert_eq!(
        parse_number("--rate", "fast", &limits::RATE_HZ).unwrap_err(),
        "--rate: `fast` is not a number"
    );
    assert_eq!(
        check_number("--rate", -33.0, &limits::RATE_HZ).unwrap_err(),
        "--rate: must be ≥ 1 and ≤ 10000 Hz, got -33"
    );
    assert_eq!(
        parse_integer("--retries", "1000", &servo::RETRIES),
        Ok(1000)
    );
    assert_eq!(
        parse_integer("--retries", "5000", &servo::RETRIES).unwrap_err(),
        "--retries: must be an integer in 0..=1000, got 5000"
    );
    assert_eq!(
        parse_integer("--max-errors", "2.5", &servo::MAX_CONSECUTIVE_ERRORS).unwrap_err(),
        "--max-errors: `2.5` is not a whole number"
    );
    assert!(
        parse_integer("--id", "99999999999999999999", &servo::SERVO_ID)
            .unwrap_err()
            .contains("is not a whole number")
    );
}

/// `--robot /dev/zero` grew to 1.9 GB: it now fails at once, naming the file and the limit.
#[test]
fn an_endless_robot_file_fails_fast() {
    let zero = Path::new("/dev/zero");
    if !zero.exists() {
        return;
    }
    let started = Instant::now();
    let message = load_robot(Some(zero)).unwrap_err().to_string();
    assert_eq!(
        message,
        "/dev/zero: cannot read robot file: larger than 1048576 bytes (1 MiB), the most a \
         description file may have"
    );
    assert!(started.elapsed() < Duration::from_secs(5));
}

fn numbers(value: &Value, what: &str) -> Vec<f64> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("{what} is not an array"))
        .iter()
        .map(|x| {
            x.as_f64()
                .unwrap_or_else(|| panic!("{what}: {x} not a number"))
        })
        .collect()
}

fn matrix(value: &Value, what: &str, rows: usize, columns: usize) -> Vec<Vec<f64>> {
    let out: Vec<Vec<f64>> = value
        .as_array()
        .unwrap_or_else(|| panic!("{what} is not an array"))
        .iter()
        .map(|row| numbers(row, what))
        .collect();
    assert_eq!(out.len(), rows, "{what}: rows");
    assert!(out.iter().all(|r| r.len() == columns), "{what}: columns");
    out
}

/// `|got − exact| ≤ 1e-12·scale + 1e-9·|exact|` (docs/model.md §8).
fn close(got: f64, exact: f64, scale: f64) -> bool {
    (got - exact).abs() <= 1e-12 * scale + 1e-9 * exact.abs()
}

/// The default robot's report at a bent, moving state: every key of issues 2 and 3, with
/// the right shapes, and values equal to the jets of `softcbf_tests::reference`.
#[test]
fn model_report_has_every_key_with_reference_values() {
    const N: usize = 6;
    let robot = load_robot(None).expect("embedded robot");
    let model = Model::new(robot.clone()).unwrap_or_else(|e| panic!("{e}"));
    let q: [f64; N] = [0.012, -0.02, 0.01, -0.03, 0.006, -0.012];
    let qd: [f64; N] = [0.05, 0.02, -0.03, -0.04, 0.06, 0.01];
    let report = model_report(&model, &q, &qd).expect("state of the right length");

    assert_eq!(report["n"], 2);
    assert_eq!(numbers(&report["q"], "q"), q);
    assert_eq!(numbers(&report["qd"], "qd"), qd);

    let chain = reference::chain(&robot, &q, &qd);
    let poses = report["plate_poses"].as_array().expect("plate_poses array");
    assert_eq!(poses.len(), 2);
    for (i, pose) in poses.iter().enumerate() {
        let pose = matrix(pose, "plate_poses[i]", 4, 4);
        let rotation = reference::mat_value(&chain.world_rotation[i]);
        let position = chain.world_position[i].map(|x| x.v);
        for r in 0..3 {
            for c in 0..3 {
                assert!(close(pose[r][c], rotation[r][c], 1.0), "W_{i}[{r}][{c}]");
            }
            assert!(close(pose[r][3], position[r], 0.2), "W_{i}[{r}][3]");
        }
        assert_eq!(pose[3], [0.0, 0.0, 0.0, 1.0]);
    }

    // Every barrier, the twelve corners and each module's three limits (the domain's).
    let exact: Vec<Jet<N>> = reference::all_barriers(&robot, &q, &qd);
    let nb = exact.len();
    assert_eq!(nb, 12 + 2 * 3);
    let barriers = numbers(&report["barriers"], "barriers");
    let jacobian = matrix(&report["barrier_jacobian"], "barrier_jacobian", nb, N);
    let jdot_qd = numbers(&report["barrier_jdot_qd"], "barrier_jdot_qd");
    assert_eq!((barriers.len(), jdot_qd.len()), (nb, nb));
    for (r, b) in exact.iter().enumerate() {
        assert!(close(barriers[r], b.v, 0.2), "barrier {r}");
        for (k, (got, exact)) in jacobian[r].iter().zip(&b.g).enumerate() {
            assert!(close(*got, *exact, 2.0), "J[{r}][{k}]");
        }
        assert!(close(jdot_qd[r], b.dd, 0.1), "J̇q̇[{r}]");
    }

    let dynamics = reference::dynamics(&robot, &q, &qd);
    let mass = matrix(&report["mass_matrix"], "mass_matrix", N, N);
    let scale_m = mass.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
    for (i, (row, exact_row)) in mass.iter().zip(&dynamics.mass_matrix).enumerate() {
        for (j, (got, exact)) in row.iter().zip(exact_row).enumerate() {
            assert!(close(*got, *exact, scale_m), "M[{i}][{j}]");
        }
    }
    let bias = numbers(&report["bias"], "bias");
    let gravity = numbers(&report["gravity"], "gravity");
    let elastic = numbers(&report["elastic"], "elastic");
    let damping = numbers(&report["damping"], "damping");
    let scale_h = dynamics.bias.iter().fold(1e-6_f64, |m, v| m.max(v.abs()));
    let scale_g = dynamics.gravity.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    for k in 0..N {
        let module = &robot.modules[k / 3];
        let d2 = module.tendon_radius * module.tendon_radius;
        // docs/model.md §4: K = diag(κθ/d², κθ/d², κL), D = diag(βθ/d², βθ/d², βL) per module.
        let (stiffness, damping_k) = if k % 3 == 2 {
            (module.axial_stiffness, module.axial_damping)
        } else {
            (module.bending_stiffness / d2, module.bending_damping / d2)
        };
        assert!(close(bias[k], dynamics.bias[k], scale_h), "h[{k}]");
        assert!(close(gravity[k], dynamics.gravity[k], scale_g), "G[{k}]");
        assert!(close(elastic[k], stiffness * q[k], 0.0), "K q [{k}]");
        assert!(close(damping[k], damping_k * qd[k], 0.0), "D q̇ [{k}]");
    }

    let energy = &report["energy"];
    let kinetic = energy["kinetic"].as_f64().expect("energy.kinetic");
    let gravity_energy = energy["gravity"].as_f64().expect("energy.gravity");
    let elastic_energy = energy["elastic"].as_f64().expect("energy.elastic");
    assert!(close(kinetic, dynamics.kinetic_energy, 0.0));
    assert!(close(gravity_energy, dynamics.gravity_energy, 0.0));
    let half_q_k_q: f64 = 0.5 * q.iter().zip(&elastic).map(|(x, f)| x * f).sum::<f64>();
    assert!(close(elastic_energy, half_q_k_q, 0.0));
}
