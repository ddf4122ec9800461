//! The calibration walk-through of docs/hardware.md end to end: both identification
//! experiments against the emulator's factory preset moving `robots/calibration-true.toml`,
//! then `softcbf identify`, compared with the numbers of that file.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::{BIN, Emulator, robot, start_run, temp_dir, wait_for};
use softcbf::hardware::description;
use softcbf_description::robot::Robot;

fn true_robot() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/calibration-true.toml")
}

/// Per module: κθ, κL, βθ, βL and the three actuator gains.
fn numbers(path: &Path) -> Vec<[f64; 7]> {
    let robot = Robot::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let hardware = description::load(&robot).unwrap().unwrap();
    robot
        .modules
        .iter()
        .zip(&hardware.modules)
        .map(|(m, h)| {
            let g = h.actuator_gain;
            [
                m.bending_stiffness,
                m.axial_stiffness,
                m.bending_damping,
                m.axial_damping,
                g[0],
                g[1],
                g[2],
            ]
        })
        .collect()
}

#[test]
fn the_walk_through_finds_the_true_robot() {
    let dir = temp_dir("identify_cli");
    let plant = true_robot();
    let plant = plant.to_str().unwrap();
    let emulators: Vec<Emulator> = ["7", "8"]
        .iter()
        .map(|seed| Emulator::start(&["--plant", plant, "--preset", "factory", "--seed", seed]))
        .collect();
    let runs: Vec<_> = ["static", "dynamic"]
        .iter()
        .zip(&emulators)
        .map(|(kind, emulator)| {
            let out = dir.join(kind);
            let run = start_run(
                &emulator.port,
                &out,
                &["--experiment", kind, "--reply-timeout-ms", "40", "--quiet"],
            );
            (kind, out, run)
        })
        .collect();
    let mut logs = Vec::new();
    for (kind, out, mut run) in runs {
        let status = wait_for(&mut run.child, Duration::from_secs(240), kind);
        assert_eq!(status.code(), Some(0), "the {kind} experiment ends safe");
        logs.push(out);
    }
    drop(emulators);
    let identified = dir.join("identified.toml");
    let output = Command::new(BIN)
        .arg("identify")
        .arg("--robot")
        .arg(robot())
        .args(&logs)
        .arg("--out")
        .arg(&identified)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "identify: {stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    println!("{stdout}");
    let truth = numbers(&true_robot());
    let found = numbers(&identified);
    let names = ["κθ", "κL", "βθ", "βL", "g1", "g2", "g3"];
    for (module, (t, f)) in truth.iter().zip(&found).enumerate() {
        for (k, name) in names.iter().enumerate() {
            let error = (f[k] - t[k]) / t[k];
            // Stiffness and gains within 5 %; damping within 25 % (at 33 Hz module 2's
            // bending damping comes out about 15 % high: docs/hardware.md).
            let tolerance = if k == 2 || k == 3 { 0.25 } else { 0.05 };
            assert!(
                error.abs() < tolerance,
                "module {} {name}: identified {} against the true {} ({:+.1} %)",
                module + 1,
                f[k],
                t[k],
                100.0 * error
            );
        }
    }
    assert!(dir.join("identify.png").exists());
}
