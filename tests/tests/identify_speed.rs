//! The processor time of `softcbf identify` on the benchmark's hour of 100 Hz logs
//! (`cargo bench -p softcbf --bench identify` times the same in wall-clock time, which the
//! load of a shared machine moves by ±50 %; the processor time summed over threads moves
//! far less). A measurement: run with `--ignored --nocapture`.

use std::path::PathBuf;
use std::time::Instant;

use softcbf::hardware::log_description::LogDescription;
use softcbf::identify::synthetic::{Multisine, Phase, SyntheticRun, write_log};
use softcbf::identify::{
    ExperimentKind, Options, hardware_of, identify, logs::Expected, read_logs,
};
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

/// The benchmark's logs: 20 minutes of static tension sets, 40 of multisines.
fn generate(model: &Model) -> Vec<PathBuf> {
    let dir = std::env::temp_dir().join(format!("softcbf-identify-speed-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut run = SyntheticRun::new(model, model, 100.0, 1200.0);
    run.tolerances = Default::default();
    run.kind = Some(ExperimentKind::Static);
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
