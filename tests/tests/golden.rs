//! The golden-file test: `generated/golden/paper_sim.rs` is exactly what the code generator
//! writes for `robots/paper-sim.toml`, byte-stable from run to run, and what the crate compiles.
//!
//! On an intended change of the generated code, update the checked-in copy with
//! `SOFTCBF_UPDATE_GOLDEN=1 cargo test --release -p softcbf-tests --test golden`, or with
//! `cargo run -p softcbf-codegen -- --robot robots/paper-sim.toml --out generated/golden/paper_sim.rs`
//! (run from the workspace root, so that the header names the robot file the same way).

use std::path::{Path, PathBuf};

use softcbf_description::robot::Robot;

/// The label `generated/build.rs` gives the paper robot: its path from the workspace root.
const LABEL: &str = "robots/paper-sim.toml";
const GOLDEN: &str = "generated/golden/paper_sim.rs";
const UPDATE_SWITCH: &str = "SOFTCBF_UPDATE_GOLDEN";

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ sits in the workspace")
        .to_path_buf()
}

/// The source the generator writes for the paper robot, as build.rs calls it.
fn regenerate() -> String {
    let path = workspace_root().join(LABEL);
    let robot = Robot::load(&path).unwrap_or_else(|error| panic!("{error}"));
    softcbf_codegen::generate(&robot.structure(), LABEL).text
}

/// `None` if equal, else the first differing line (1-based) with both versions of it.
fn first_difference(expected: &str, got: &str) -> Option<String> {
    if expected == got {
        return None;
    }
    let mut expected_lines = expected.split_inclusive('\n');
    let mut got_lines = got.split_inclusive('\n');
    for line in 1.. {
        match (expected_lines.next(), got_lines.next()) {
            (Some(a), Some(b)) if a == b => continue,
            (a, b) => {
                let show =
                    |x: Option<&str>| x.map_or("<end of file>".to_string(), |s| format!("{s:?}"));
                return Some(format!(
                    "line {line}:\n  checked in:  {}\n  regenerated: {}",
                    show(a),
                    show(b)
                ));
            }
        }
    }
    unreachable!("the loop returns at the first difference")
}

fn how_to_update() -> String {
    format!(
        "if the change is intended, update the golden file with\n  \
         {UPDATE_SWITCH}=1 cargo test --release -p softcbf-tests --test golden\nor\n  \
         cargo run -p softcbf-codegen -- --robot {LABEL} --out {GOLDEN}\n\
         (from the workspace root) and review the diff before committing it"
    )
}

/// Generation is deterministic: two runs in one process give the same bytes.
#[test]
fn generation_is_byte_stable() {
    let first = regenerate();
    let second = regenerate();
    if let Some(difference) = first_difference(&first, &second) {
        panic!("two generations of {LABEL} differ at {difference}");
    }
}

/// The checked-in copy equals a fresh generation.
#[test]
fn golden_file_matches_regenerated_source() {
    let golden_path = workspace_root().join(GOLDEN);
    let fresh = regenerate();
    if std::env::var_os(UPDATE_SWITCH).is_some_and(|v| v == "1") {
        std::fs::write(&golden_path, &fresh)
            .unwrap_or_else(|error| panic!("cannot write {}: {error}", golden_path.display()));
        eprintln!("{UPDATE_SWITCH}=1: wrote {}", golden_path.display());
        return;
    }
    let golden = std::fs::read_to_string(&golden_path).unwrap_or_else(|error| {
        panic!(
            "cannot read {}: {error}\n{}",
            golden_path.display(),
            how_to_update()
        )
    });
    if let Some(difference) = first_difference(&golden, &fresh) {
        panic!(
            "{GOLDEN} differs from the generated source at {difference}\n{}",
            how_to_update()
        );
    }
}

/// What build.rs wrote to OUT_DIR, and the crate compiled, is the golden file's text.
#[test]
fn compiled_model_is_the_golden_source() {
    let fresh = regenerate();
    if let Some(difference) = first_difference(&fresh, softcbf_generated::paper_sim::SOURCE) {
        panic!(
            "softcbf-generated was built from a different paper_sim source ({difference}); \
             build.rs must call softcbf_codegen::generate with the label {LABEL:?}"
        );
    }
}
