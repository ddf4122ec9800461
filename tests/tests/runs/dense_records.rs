//! Dense records and a separate plant robot in simulation: rows between ticks that agree
//! with a run recorded at the ticks only, a lowest barrier taken over every row, figures
//! drawn and redrawn from a dense record, and a plant whose numbers differ from the
//! controller's robot (or whose structure does, which is refused).

use std::path::{Path, PathBuf};

use softcbf::model::Model;
use softcbf::plot::FigureOptions;
use softcbf::record::Record;
use softcbf::robot_file::load_robot;
use softcbf::scenario::{Scenario, ScenarioFile, between_ticks};
use softcbf::sim::{Run, simulate};

/// The paper's scenario at the hardware's 33 Hz with the hold correction (so that the
/// filter is active and stable at that rate), shortened to `seconds`.
fn slow_paper(seconds: f64) -> (Model, Scenario) {
    let model = Model::new(load_robot(None).unwrap()).unwrap();
    let text = format!(
        "duration = {seconds}\ncontrol_period = {}\nsafety = \"hold-correction\"\n\
         [reference]\nset_point = [0.08, 0, -0.05, 0, -0.06, -0.07]\n",
        1.0 / 33.0
    );
    let scenario = ScenarioFile::parse(&text, Path::new("slow.toml"))
        .unwrap()
        .resolve(&model)
        .unwrap();
    (model, scenario)
}

fn run(model: &Model, scenario: &Scenario) -> Run {
    let run = simulate(model, scenario, true, &mut |_| {}).unwrap();
    assert_eq!(run.summary.stopped, None);
    run
}

/// The lowest barrier value over every row of `record`.
fn lowest(record: &Record) -> f64 {
    (0..record.columns().m())
        .flat_map(|j| record.b(j))
        .fold(f64::INFINITY, f64::min)
}

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("softcbf-dense-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// 1/33 s is 30.3 ms: rows at 1, 2, …, 30 ms after each tick, then the next tick. A period
/// that is a whole multiple (30 ms) records 29 rows between ticks, none on the tick itself,
/// even where the quotient rounds below the integer (0.03 / 0.001 = 29.999999999999996).
#[test]
fn rows_fall_at_every_multiple_after_a_tick() {
    assert_eq!(between_ticks(1.0 / 33.0, 1e-3), 30);
    assert_eq!(between_ticks(0.03, 1e-3), 29);
    assert_eq!(between_ticks(0.3, 0.1), 2);
    assert_eq!(between_ticks(1e-3, 1e-3), 0);
    assert_eq!(between_ticks(1e-3, 2e-3), 0);
    assert_eq!(between_ticks(1e-3, 4e-4), 2);

    let (model, mut scenario) = slow_paper(0.2);
    scenario.record_period = Some(1e-3);
    let dense = run(&model, &scenario);
    // round(0.2 · 33) = 7 ticks (the 8th row is at 7/33 s).
    let ticks = 7;
    assert_eq!(dense.summary.counts.ticks, ticks + 1);
    assert_eq!(dense.record.len(), ticks * 31 + 1);
    let times: Vec<f64> = dense.record.times().collect();
    assert!(times.windows(2).all(|w| w[1] > w[0]), "times increase");
    for k in 0..ticks {
        let tick = k as f64 / 33.0;
        assert!((times[31 * k] - tick).abs() < 1e-15);
        for j in 1..=30 {
            let t = times[31 * k + j];
            assert!((t - (tick + j as f64 * 1e-3)).abs() < 1e-12, "{t}");
        }
    }
    assert!(dense.summary.dense);
    assert_eq!(dense.summary.record_period, Some(1e-3));
}

/// The rows of a dense run at the ticks are the rows of a run recorded at the ticks only,
/// to the integrator's tolerance: splitting each hold interval at the recorded instants
/// keeps every piece under error control. The lowest barrier of the dense run, taken over
/// every row, is at most the sparse run's (up to that tolerance), and rows between ticks
/// hold the tick's τ and τ_nom.
#[test]
fn tick_rows_of_a_dense_run_are_those_of_a_sparse_run() {
    let (model, scenario) = slow_paper(1.5);
    let sparse = run(&model, &scenario);
    assert!(!sparse.summary.dense);
    assert_eq!(sparse.summary.record_period, None);
    let mut dense_scenario = scenario.clone();
    dense_scenario.record_period = Some(1e-3);
    let dense = run(&model, &dense_scenario);
    assert!(sparse.summary.counts.active > 0, "the filter acts");

    let nq = model.nq();
    let per_tick = 31;
    assert_eq!(dense.record.len(), (sparse.record.len() - 1) * per_tick + 1);
    let mut worst_q = 0.0_f64;
    let mut worst_qd = 0.0_f64;
    for (k, tick) in sparse.record.rows().enumerate() {
        let row = dense.record.row(k * per_tick).unwrap();
        assert_eq!(row.t, tick.t);
        for i in 0..nq {
            worst_q = worst_q.max((row.q[i] - tick.q[i]).abs());
            worst_qd = worst_qd.max((row.qd[i] - tick.qd[i]).abs());
        }
        // Between this tick and the next: the held command of this tick.
        for j in 1..per_tick {
            let Some(between) = dense.record.row(k * per_tick + j) else {
                break;
            };
            assert_eq!(between.tau, row.tau);
            assert_eq!(between.tau_nom, row.tau_nom);
        }
    }
    eprintln!(
        "dense (1 ms) against sparse tick rows: |Δq| ≤ {worst_q:.2e} m, |Δq̇| ≤ {worst_qd:.2e} m/s"
    );
    // rtol 1e-6, atol 1e-9 on coordinates of a few centimetres over 50 ticks.
    assert!(worst_q < 1e-6, "{worst_q}");

    let (dense_low, sparse_low) = (lowest(&dense.record), lowest(&sparse.record));
    eprintln!("lowest barrier: dense {dense_low:.4e} m, sparse {sparse_low:.4e} m");
    assert_eq!(dense.summary.min_barrier.value, dense_low);
    assert_eq!(sparse.summary.min_barrier.value, sparse_low);
    assert!(dense_low <= sparse_low + 1e-8, "{dense_low} > {sparse_low}");
    let by_kind = dense.summary.lowest_by_kind.iter().next().unwrap().1;
    assert_eq!(by_kind.value, dense_low);
}

/// A record period equal to the control period records what a run without one records.
#[test]
fn a_record_period_of_one_tick_is_the_sparse_record() {
    let (model, scenario) = slow_paper(0.3);
    let sparse = run(&model, &scenario);
    let mut same = scenario.clone();
    same.record_period = Some(scenario.control_period);
    let same = run(&model, &same);
    assert_eq!(same.record, sparse.record);
    assert!(!same.summary.dense);
    assert_eq!(same.summary.record_period, Some(scenario.control_period));
}

/// The figures of a dense run are drawn, and `softcbf plot` redraws them from its files
/// byte for byte.
#[test]
fn figures_of_a_dense_run_come_back_from_its_files() {
    let (model, mut scenario) = slow_paper(0.5);
    scenario.record_period = Some(1e-3);
    let main = run(&model, &scenario);
    let pd = simulate(&model, &scenario, false, &mut |_| {}).unwrap();
    let dir = out_dir("figures");
    softcbf::output::write_outputs(&dir, &main, Some(&pd), &model, false).unwrap();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["dense"], true);
    assert_eq!(summary["record_period"], 1e-3);
    assert_eq!(summary["settings"]["record_period"]["value"], 1e-3);
    assert_eq!(summary["settings"]["plant"], serde_json::Value::Null);
    let figures = [dir.join("figure.png"), dir.join("figure.svg")];
    let drawn: Vec<Vec<u8>> = figures.iter().map(|f| std::fs::read(f).unwrap()).collect();
    let files = [dir.join("trajectory.csv"), dir.join("trajectory_pd.csv")];
    let redrawn = dir.join("again");
    softcbf::replot::replot(&files, Some(&redrawn), None, &FigureOptions::default()).unwrap();
    for (figure, bytes) in figures.iter().zip(&drawn) {
        let again = std::fs::read(redrawn.join(figure.file_name().unwrap())).unwrap();
        assert!(again == *bytes, "{} differs", figure.display());
    }
    let read = Record::read_csv(&files[0]).unwrap();
    assert_eq!(read, main.record);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The paper robot's text with both modules' axial stiffness `κL` set to `axial`.
fn paper_robot_with_axial_stiffness(axial: f64) -> String {
    let text = std::fs::read_to_string(repo("robots/paper-sim.toml")).unwrap();
    let changed = text.replace(
        "axial_stiffness = 10.0",
        &format!("axial_stiffness = {axial:?}"),
    );
    assert_eq!(
        changed
            .matches(&format!("axial_stiffness = {axial:?}"))
            .count(),
        2
    );
    changed
}

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

/// A plant robot 20 % stiffer axially moves differently under the same controller; the
/// controller's own robot as the plant moves exactly as without a plant.
#[test]
fn a_plant_with_another_stiffness_gives_another_trajectory() {
    let dir = out_dir("plant");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("stiff.toml"),
        paper_robot_with_axial_stiffness(12.0),
    )
    .unwrap();
    std::fs::write(
        dir.join("same.toml"),
        paper_robot_with_axial_stiffness(10.0),
    )
    .unwrap();
    let model = Model::new(load_robot(None).unwrap()).unwrap();
    let scenario = |plant: &str| {
        let text = format!(
            "duration = 0.5\n{plant}\n[reference]\nset_point = [0.02, 0, -0.03, 0, 0.01, -0.02]\n"
        );
        let path = dir.join("scenario.toml");
        std::fs::write(&path, &text).unwrap();
        ScenarioFile::load(&path).unwrap().resolve(&model).unwrap()
    };
    let none = run(&model, &scenario(""));
    let stiff_scenario = scenario("plant = \"stiff.toml\"");
    let stiff_robot = stiff_scenario.plant.as_ref().unwrap();
    assert_eq!(stiff_robot.modules[0].axial_stiffness, 12.0);
    let stiff = run(&model, &stiff_scenario);
    let same = run(&model, &scenario("plant = \"same.toml\""));
    // Not bit for bit: without a plant the plant takes the controller's evaluation of the
    // model at each tick's state (`Plant::use_evaluation`), which a plant of its own
    // (another model object) computes again, by another route, to rounding.
    assert_eq!(same.record.len(), none.record.len());
    let mut worst = 0.0_f64;
    for i in 0..model.nq() {
        for (a, b) in same.record.q(i).zip(none.record.q(i)) {
            worst = worst.max((a - b).abs());
        }
    }
    eprintln!("largest |Δq|, the controller's robot as the plant or no plant: {worst:.2e} m");
    assert!(worst < 1e-12, "{worst}");
    // δL₁ (column 3) settles where K_P and the plant's κL balance: the stiffer plant
    // stretches less; the controller's commands differ with it.
    let last = |run: &Run| run.record.row(run.record.len() - 1).unwrap().q[2];
    let (soft_dl, stiff_dl) = (last(&none), last(&stiff));
    eprintln!("δL₁ at 0.5 s: plant as modelled {soft_dl:.5} m, 20 % stiffer {stiff_dl:.5} m");
    assert!(
        stiff_dl.abs() < soft_dl.abs() - 1e-4,
        "{stiff_dl} vs {soft_dl}"
    );
    let settings = softcbf::sim::settings_report(&model, &stiff_scenario, true);
    let plant = settings.plant.unwrap();
    assert_eq!(
        plant.value.file,
        dir.join("stiff.toml").display().to_string()
    );
    assert!(settings_line_names_plant(&stiff.summary.settings.line()));
    let _ = std::fs::remove_dir_all(&dir);
}

fn settings_line_names_plant(line: &str) -> bool {
    line.contains("; plant paper-sim (") && line.contains("stiff.toml) (scenario)")
}

/// A plant of another structure is refused at the scenario's `plant` field, with the file,
/// the line and what differs.
#[test]
fn a_plant_of_another_structure_is_refused() {
    let model = Model::new(load_robot(None).unwrap()).unwrap();
    let dir = out_dir("structure");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scenario.toml");
    let resolve = |plant: &Path| {
        let text = format!(
            "duration = 0.5\nplant = \"{}\"\n[reference]\nset_point = [0, 0, 0, 0, 0, 0]\n",
            plant.display()
        );
        std::fs::write(&path, &text).unwrap();
        ScenarioFile::load(&path).unwrap().resolve(&model)
    };
    let refused = |plant: &Path| resolve(plant).unwrap_err().to_string();
    let accepted = |plant: &Path| {
        if let Err(error) = resolve(plant) {
            panic!("{}: {error}", plant.display())
        }
    };
    // Limits are numbers (every module has them): a plant with other limits is accepted.
    accepted(&repo("robots/paper-sim-limits.toml"));
    let obstacle = refused(&repo("robots/paper-sim-obstacle.toml"));
    let prefix = format!("{}:2: field `plant`: the plant robot ", path.display());
    assert!(obstacle.starts_with(&prefix), "{obstacle}");
    assert!(
        obstacle.contains("differs in structure from the controller's robot"),
        "{obstacle}"
    );
    assert!(
        obstacle.contains("1 obstacles, the controller's robot 0"),
        "{obstacle}"
    );
    let three = refused(&repo("robots/three-square.toml"));
    assert!(
        three.contains(": it has 3 modules, the controller's robot 2"),
        "{three}"
    );
    let missing = refused(Path::new("nope.toml"));
    assert!(
        missing.starts_with(&format!(
            "{}:2: field `plant`: cannot read the plant robot file {}",
            path.display(),
            dir.join("nope.toml").display()
        )),
        "{missing}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
