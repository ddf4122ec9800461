//! Criterion benchmark of `softcbf identify` on one hour of 100 Hz logs of the example
//! robot (20 minutes of static tension sets, 40 minutes of multisine excitation), generated
//! once before timing: reading the logs, the fit (with the held-out predictions), and both.

use std::path::{Path, PathBuf};

use criterion::{Criterion, criterion_group, criterion_main};
use softcbf::hardware::log_description::LogDescription;
use softcbf::identify::synthetic::benchmark_logs;
use softcbf::identify::{Options, hardware_of, identify, logs::Expected, read_logs};
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

/// The benchmark's logs (`identify::synthetic::benchmark_logs`) in a fresh directory.
fn generate(model: &Model) -> Vec<PathBuf> {
    let dir = std::env::temp_dir().join(format!("softcbf-identify-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    benchmark_logs(model, &dir).unwrap().to_vec()
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
