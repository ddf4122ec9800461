//! The golden-file test: `generated/golden/paper_sim.rs` is exactly what the code generator
//! writes for `robots/paper-sim.toml`, byte-stable from run to run, and what the crate compiles.
//!
//! On an intended change of the generated code, update the checked-in copy with
//! `SOFTCBF_UPDATE_GOLDEN=1 cargo test --release -p softcbf-tests --test model golden::`, or with
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
         {UPDATE_SWITCH}=1 cargo test --release -p softcbf-tests --test model golden::\nor\n  \
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

/// The fused `model_terms` gives bit for bit what `joint_terms` and `barrier_terms` give
/// (one program of the same expressions), at states on both sides of the series switch.
#[test]
fn model_terms_is_joint_terms_and_barrier_terms() {
    use softcbf_generated::GeneratedModel;
    let model = &softcbf_generated::paper_sim::Model;
    let robot =
        Robot::load(&workspace_root().join(LABEL)).unwrap_or_else(|error| panic!("{error}"));
    let p = softcbf_description::layout::pack_params(&robot);
    let (n, nq, nb) = (model.n_modules(), model.nq(), model.nb());
    let states: [[f64; 6]; 3] = [
        [0.0; 6],
        [1e-4, -2e-4, 1e-3, 3e-5, 1e-5, -2e-3],
        [0.012, -0.007, 0.004, -0.02, 0.015, -0.01],
    ];
    for q in &states {
        let qd = [0.3, -0.2, 0.05, 0.1, 0.4, -0.03];
        let mut separate = (
            vec![[[0.0; 3]; 3]; n],
            vec![[0.0; 3]; n],
            vec![[[0.0; 3]; 6]; n],
            vec![[0.0; 6]; n],
            vec![0.0; nb],
            vec![0.0; nb * nq],
            vec![0.0; nb],
        );
        let mut fused = separate.clone();
        let s = &mut separate;
        model.joint_terms(&p, q, &qd, &mut s.0, &mut s.1, &mut s.2, &mut s.3);
        model.barrier_terms(&p, q, &qd, &mut s.4, &mut s.5, &mut s.6);
        let f = &mut fused;
        model.model_terms(
            &p, q, &qd, &mut f.0, &mut f.1, &mut f.2, &mut f.3, &mut f.4, &mut f.5, &mut f.6,
        );
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let flat3 = |v: &[[[f64; 3]; 3]]| v.iter().flatten().flatten().copied().collect::<Vec<_>>();
        let flat6 = |v: &[[[f64; 3]; 6]]| v.iter().flatten().flatten().copied().collect::<Vec<_>>();
        assert_eq!(bits(&flat3(&s.0)), bits(&flat3(&f.0)), "rotation at {q:?}");
        assert_eq!(
            bits(s.1.as_flattened()),
            bits(f.1.as_flattened()),
            "translation"
        );
        assert_eq!(bits(&flat6(&s.2)), bits(&flat6(&f.2)), "motion subspace");
        assert_eq!(
            bits(s.3.as_flattened()),
            bits(f.3.as_flattened()),
            "bias acceleration"
        );
        assert_eq!(bits(&s.4), bits(&f.4), "barriers");
        assert_eq!(bits(&s.5), bits(&f.5), "jacobian");
        assert_eq!(bits(&s.6), bits(&f.6), "jdot_qd");
    }
}

/// The barrier table names every barrier of the paper robot, module-major and
/// corner-minor, then each module's three limits (the robot file writes none: the
/// domain's), with the parameters each expression reads.
#[test]
fn barrier_table_describes_the_plate_corners_and_limits() {
    use softcbf_generated::{BarrierKind, GeneratedModel, Point};
    let model = &softcbf_generated::paper_sim::Model;
    let table = model.barrier_table();
    let modules = model.corners().len();
    assert_eq!(
        table.len(),
        model.corners().iter().sum::<usize>() + 3 * modules
    );
    assert_eq!(model.nb(), table.len());
    let names = model.param_names();
    let mut k = 0;
    for (i, &corners) in model.corners().iter().enumerate() {
        for j in 0..corners {
            let b = &table[k];
            assert_eq!(b.kind, BarrierKind::PlateCorner);
            assert_eq!(
                (b.module, b.point, b.obstacle),
                (i, Some(Point::Corner(j)), None)
            );
            assert_eq!(b.label, format!("module {} corner {}", i + 1, j + 1));
            let read: Vec<&str> = b.params.iter().map(|&p| names[p]).collect();
            let expected = [
                format!("rest_length_{i}"),
                format!("tendon_radius_{i}"),
                format!("corner_radius_{i}"),
                format!("corner_cos_{i}_{j}"),
                format!("corner_sin_{i}_{j}"),
                format!("margin_{i}_{j}"),
            ];
            assert_eq!(read, expected, "barrier {k}");
            k += 1;
        }
    }
    for i in 0..modules {
        let limits = [
            (
                BarrierKind::ElongationMin,
                "elongation min",
                "elongation_min",
            ),
            (
                BarrierKind::ElongationMax,
                "elongation max",
                "elongation_max",
            ),
        ];
        for (kind, label, value) in limits {
            let b = &table[k];
            assert_eq!(
                (b.kind, b.module, b.point, b.obstacle),
                (kind, i, None, None)
            );
            assert_eq!(b.label, format!("module {} {label}", i + 1));
            let read: Vec<&str> = b.params.iter().map(|&p| names[p]).collect();
            assert_eq!(
                read,
                [format!("{value}_{i}"), format!("elongation_margin_{i}")]
            );
            k += 1;
        }
        let b = &table[k];
        assert_eq!((b.kind, b.module), (BarrierKind::Bend, i));
        assert_eq!(b.label, format!("module {} bend", i + 1));
        let mut read: Vec<&str> = b.params.iter().map(|&p| names[p]).collect();
        read.sort_unstable();
        let mut expected = [
            format!("tendon_radius_{i}"),
            format!("max_bend_{i}"),
            format!("bend_margin_{i}"),
        ];
        expected.sort_unstable();
        assert_eq!(read, expected);
        k += 1;
    }
    assert_eq!(k, table.len());
}
