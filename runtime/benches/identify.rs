//! Criterion benchmark of `softcbf identify` on one hour of 100 Hz logs of the example
//! robot (20 minutes of static tension sets, 40 minutes of multisine excitation), generated
//! once before timing: reading the logs, the fit (with the held-out predictions), and both.

use std::path::{Path, PathBuf};

use criterion::{Criterion, criterion_group, criterion_main};
use softcbf::hardware::log_description::LogDescription;
use softcbf::identify::synthetic::{Multisine, Phase, SyntheticRun, write_log};
use softcbf::identify::{
    ExperimentKind, Options, hardware_of, identify, logs::Expected, read_logs,
};
use softcbf::model::Model;
use softcbf_description::robot::Robot;

/// `robots/hardware-example.toml`.
fn example() -> Robot {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robots/hardware-example.toml"
    ));
    Robot::load(path).unwrap()
}

/// Writes the two logs into a fresh directory and returns their paths.
fn generate(model: &Model) -> Vec<PathBuf> {
    let dir = std::env::temp_dir().join(format!("softcbf-identify-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut run = SyntheticRun::new(model, model, 100.0, 1200.0);
    run.tolerances = Default::default();
    run.kind = Some(ExperimentKind::Static);
    // 400 tension sets of 3 s each, deterministic, in [0.3, 3] N.
    let hold = 3.0;
    write_log(&dir.join("static"), &run, |tick, tensions| {
        let step = (tick.t / hold) as usize;
        for (s, f) in tensions.iter_mut().enumerate() {
            let x = ((step * 7 + s * 13) % 17) as f64 / 16.0;
            *f = 0.3 + 2.7 * x;
        }
        let into = tick.t - step as f64 * hold;
        Phase {
            step: step as f64,
            rest: into > hold - 1.0,
        }
    })
    .unwrap();
    run.duration = 2400.0;
    run.kind = Some(ExperimentKind::Dynamic);
    let signals: Vec<Multisine> = (0..6)
        .map(|s| Multisine::new(8, 0.2, 4.0, 1.4, 1.7 * s as f64 + 0.3))
        .collect();
    write_log(&dir.join("dynamic"), &run, |tick, tensions| {
        for (f, signal) in tensions.iter_mut().zip(&signals) {
            *f = 1.8 + signal.at(tick.t);
        }
        Phase {
            step: 0.0,
            rest: false,
        }
    })
    .unwrap();
    vec![dir.join("static"), dir.join("dynamic")]
}

fn one_hour(c: &mut Criterion) {
    let robot = example();
    let model = Model::new(robot.clone()).unwrap();
    let dirs = generate(&model);
    let hardware = hardware_of(&robot).unwrap();
    let expected = Expected {
        name: &robot.name,
        file: &robot.source,
        nq: model.nq(),
        hardware: &hardware,
        description: LogDescription::of(&robot, &hardware),
    };
    let options = Options::default();
    let logs = read_logs(&dirs, &expected).unwrap();
    let mut group = c.benchmark_group("identify");
    group.sample_size(10);
    group.bench_function("read_one_hour_100hz", |b| {
        b.iter(|| read_logs(&dirs, &expected).unwrap())
    });
    group.bench_function("fit_one_hour_100hz", |b| {
        b.iter(|| identify(&robot, &logs, &options).unwrap())
    });
    group.bench_function("one_hour_100hz", |b| {
        b.iter(|| {
            let logs = read_logs(&dirs, &expected).unwrap();
            identify(&robot, &logs, &options).unwrap()
        })
    });
    group.finish();
    if let Some(dir) = dirs.first().and_then(|d| d.parent()) {
        let _ = std::fs::remove_dir_all(dir);
    }
}

criterion_group!(benches, one_hour);
criterion_main!(benches);
