//! The processor time of `softcbf identify` on the benchmark's hour of 100 Hz logs
//! (`cargo bench -p softcbf --bench identify` times the same in wall-clock time, which the
//! load of a shared machine moves by ±50 %; the processor time summed over threads moves
//! far less). A measurement: run with `--ignored --nocapture`.

use std::path::PathBuf;
use std::time::Instant;

use softcbf::hardware::log_description::LogDescription;
use softcbf::identify::synthetic::benchmark_logs;
use softcbf::identify::{Options, hardware_of, identify, logs::Expected, read_logs};
use softcbf::model::Model;
use softcbf_tests::robots;

/// User and system time of this process so far \[s\] (all threads), from `/proc/self/stat`.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap();
    // Fields after the command's closing parenthesis: utime and stime are the 12th and
    // 13th, in clock ticks (100 per second on Linux).
    let rest = &stat[stat.rfind(')').unwrap() + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields[11].parse::<f64>().unwrap() + fields[12].parse::<f64>().unwrap();
    ticks / 100.0
}

/// The benchmark's logs (`identify::synthetic::benchmark_logs`) in a fresh directory.
fn generate(model: &Model) -> Vec<PathBuf> {
    let dir = std::env::temp_dir().join(format!("softcbf-identify-speed-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    benchmark_logs(model, &dir).unwrap().to_vec()
}

#[test]
#[ignore]
fn processor_time_of_one_hour_of_logs() {
    let robot = robots::hardware_example_model().robot.clone();
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
    let (mut read, mut fit, mut wall) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..7 {
        let (c0, w0) = (cpu_seconds(), Instant::now());
        let logs = read_logs(&dirs, &expected).unwrap();
        let c1 = cpu_seconds();
        let id = identify(&robot, &logs, &options).unwrap();
        assert!(!id.fit.theta.is_empty());
        read.push(c1 - c0);
        fit.push(cpu_seconds() - c1);
        wall.push(w0.elapsed().as_secs_f64());
    }
    for (what, mut values) in [("read", read), ("fit", fit), ("wall", wall)] {
        values.sort_by(f64::total_cmp);
        println!(
            "{what}: median {:.3} s, range {:.3}–{:.3} s over {} runs{}",
            values[values.len() / 2],
            values[0],
            values[values.len() - 1],
            values.len(),
            if what == "wall" {
                ""
            } else {
                " (processor time, all threads)"
            }
        );
    }
    if let Some(dir) = dirs.first().and_then(|d| d.parent()) {
        let _ = std::fs::remove_dir_all(dir);
    }
}
