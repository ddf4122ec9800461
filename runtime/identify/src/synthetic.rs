//! Logs of a simulated robot, written as `softcbf run` writes them (`trajectory.csv` with
//! the hardware columns, `summary.json`): for tests and benchmarks of identification.
//!
//! A tension schedule (a closure, or later an experiment of `softcbf run --experiment`)
//! is asked for each tick's tensions from the exact state; they are clamped to the
//! file's tension limits and turned into goal-current registers with the file's actuator
//! gains, as the run loop does, while the plant (a robot file of the same structure,
//! with the "true" numbers) pulls with its own gains, `f = g·max(s·I, 0)`, held from the
//! command's landing to the next one. Readings are exact states, sampled `sampled`
//! seconds before the row's `t`.

use std::path::{Path, PathBuf};

use rand::SeedableRng;
use rand::rngs::Xoshiro256PlusPlus;
use softcbf_core::noise::SensorNoise;
use softcbf_core::noise::standard_normal;

use crate::dynamics::{BarrierTerms, DynamicsWorkspace, model_terms};
use crate::hardware::log::{Extra, extra_columns};
use crate::hardware::log_description::LogDescription;
use crate::hardware::mapping::TendonMap;
use crate::hardware::run_loop::command_wire_time;
use crate::hardware::summary_file::{Clamps, ExperimentDesign, ExperimentSummary, HardwareSummary};
use crate::integrator::Tolerances;
use crate::model::Model;
use crate::plant::Plant;
use crate::record::{Columns, CsvWriter, Row, as_strs, coordinate_names};

use super::logs::ExperimentKind;

/// The state a schedule sees at a tick.
#[derive(Clone, Copy, Debug)]
pub struct Tick<'a> {
    /// The row's time \[s\] (the reading was sampled `sampled` before it).
    pub t: f64,
    /// Generalized coordinates read \[m\].
    pub q: &'a [f64],
    /// Generalized velocities read \[m/s\].
    pub qd: &'a [f64],
}

/// What a schedule says about a tick, for the `step` and `rest` columns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phase {
    /// The experiment step (NaN: none).
    pub step: f64,
    /// The reading belongs to a static step's rest state.
    pub rest: bool,
}

/// How a synthetic run is made: robots, rate, duration, timing.
#[derive(Clone, Copy)]
pub struct SyntheticRun<'a> {
    /// The robot file the log is for: column names, tension limits, the gains that turn
    /// tensions into goal currents.
    pub file: &'a Model,
    /// The robot that moves: its dynamics and its actuator gains (same structure).
    pub plant: &'a Model,
    /// Loop rate \[Hz\].
    pub rate: f64,
    /// Length of the run \[s\].
    pub duration: f64,
    /// How long before a row's `t` the servos sampled its reading \[s\].
    pub sampled: f64,
    /// Time from the row's `t` to the command computed \[s\].
    pub compute: f64,
    /// Time to write the command \[s\]; it lands `compute + write` and its wire time after
    /// `t`.
    pub write: f64,
    /// The experiment `summary.json` names.
    pub kind: Option<ExperimentKind>,
    /// Integrator tolerances of the plant.
    pub tolerances: Tolerances,
    /// The plant's actuator gain of each servo \[N/mA\] (`None`: its robot file's).
    pub gains: Option<&'a [f64]>,
    /// Readings as the servos give them: angles with this Gaussian noise, rounded to
    /// Present Position and Present Velocity units, mapped back to `q`, `q̇` (`None`:
    /// exact states).
    pub servo_readings: Option<SensorNoise>,
}

impl<'a> SyntheticRun<'a> {
    /// A run of `plant` logged for `file` at `rate` for `duration`, with timing like the
    /// emulator's at 1 Mbit/s (sampled 0.4 ms before `t`, computed in 0.2 ms, written in
    /// 0.3 ms) and tight tolerances (`rtol` 1e-10, `atol` 1e-12: exact readings).
    pub fn new(file: &'a Model, plant: &'a Model, rate: f64, duration: f64) -> Self {
        SyntheticRun {
            file,
            plant,
            rate,
            duration,
            sampled: 4e-4,
            compute: 2e-4,
            write: 3e-4,
            kind: None,
            tolerances: Tolerances {
                rtol: 1e-10,
                atol: 1e-12,
                ..Tolerances::default()
            },
            gains: None,
            servo_readings: None,
        }
    }
}

/// What a synthetic run wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticLog {
    /// `trajectory.csv`.
    pub trajectory: PathBuf,
    /// Rows written.
    pub rows: usize,
    /// Rows marked as rest.
    pub rest_rows: usize,
    /// Tensions clamped at a limit (low, high), summed over the rows.
    pub clamps: (u32, u32),
}

/// The identify benchmark's hour of 100 Hz logs of `model` (its own plant, exact
/// readings) in `dir/static` and `dir/dynamic`: 20 minutes of deterministic static
/// tension sets (400 of 3 s each, in \[0.3, 3\] N, the last second of each at rest) and 40
/// minutes of multisines (8 lines each from 0.2 to 4 Hz around 1.8 N). Shared by
/// `cargo bench --bench identify` and `tests/tests/identify_speed.rs`, which time the same
/// logs. Returns the two log directories.
pub fn benchmark_logs(model: &Model, dir: &Path) -> Result<[PathBuf; 2], String> {
    let mut run = SyntheticRun::new(model, model, 100.0, 1200.0);
    run.tolerances = Default::default();
    run.kind = Some(ExperimentKind::Static);
    let hold = 3.0;
    let (static_dir, dynamic_dir) = (dir.join("static"), dir.join("dynamic"));
    write_log(&static_dir, &run, |tick, tensions| {
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
    })?;
    run.duration = 2400.0;
    run.kind = Some(ExperimentKind::Dynamic);
    let signals: Vec<Multisine> = (0..6)
        .map(|s| Multisine::new(8, 0.2, 4.0, 1.4, 1.7 * s as f64 + 0.3))
        .collect();
    write_log(&dynamic_dir, &run, |tick, tensions| {
        for (f, signal) in tensions.iter_mut().zip(&signals) {
            *f = 1.8 + signal.at(tick.t);
        }
        Phase {
            step: 0.0,
            rest: false,
        }
    })?;
    Ok([static_dir, dynamic_dir])
}

/// Simulates `run`, asking `schedule` for each tick's tensions \[N\] (one per servo, servo
/// `3i + k` pulls tendon `k` of module `i`), and writes `dir/trajectory.csv` and
/// `dir/summary.json` (`dir` is created if missing).
pub fn write_log(
    dir: &Path,
    run: &SyntheticRun<'_>,
    mut schedule: impl FnMut(&Tick<'_>, &mut [f64]) -> Phase,
) -> Result<SyntheticLog, String> {
    let (file, plant_model) = (run.file, run.plant);
    let period = 1.0 / run.rate;
    if !(run.rate > 0.0 && run.duration >= 0.0 && period.is_finite() && run.duration.is_finite()) {
        return Err(format!(
            "rate {} Hz and duration {} s",
            run.rate, run.duration
        ));
    }
    if !(run.sampled >= 0.0 && run.compute >= 0.0 && run.write >= 0.0)
        || run.sampled + run.compute + run.write >= period
    {
        return Err(format!(
            "sampled + compute + write = {} s must be shorter than the period {period} s",
            run.sampled + run.compute + run.write
        ));
    }
    if file.robot.structure() != plant_model.robot.structure() {
        return Err(format!(
            "{} and {} have different structures",
            file.robot.source.display(),
            plant_model.robot.source.display()
        ));
    }
    let map = TendonMap::new(&file.robot).map_err(|e| e.to_string())?;
    let plant_map = TendonMap::new(&plant_model.robot).map_err(|e| e.to_string())?;
    let (nq, servos) = (file.nq(), map.n_servos());
    if run.gains.is_some_and(|g| g.len() != servos) {
        return Err(format!("{servos} plant gains needed"));
    }
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    // What a run writes beside its log: the hardware description it was taken with.
    LogDescription::of(&file.robot, map.hardware())
        .write(dir)
        .map_err(|e| e.to_string())?;
    let names = extra_columns(servos, &coordinate_names(nq));
    let columns = Columns::for_model(file, &as_strs(&names)).map_err(|e| e.to_string())?;
    let path = dir.join("trajectory.csv");
    let mut writer = CsvWriter::create(&path, columns).map_err(|e| e.to_string())?;

    let mut plant = Plant::new(plant_model, run.tolerances).map_err(|e| e.to_string())?;
    let zeros = vec![0.0; nq];
    plant.reset(&zeros, &zeros, -run.sampled);
    let mut ws = DynamicsWorkspace::new(file);
    let mut barriers = BarrierTerms::new(file);
    let (mut wanted, mut tensions, mut applied) =
        (vec![0.0; servos], vec![0.0; servos], vec![0.0; servos]);
    let (mut registers, mut currents) = (vec![0i16; servos], vec![0.0; servos]);
    let mut tau = vec![0.0; nq];
    let mut extra = vec![0.0; names.len()];
    let unit = map.hardware().current_unit;
    // A command lands when its last byte has crossed the bus, as `read_logs` assumes.
    let wire = command_wire_time(map.hardware().servo_ids().len(), map.hardware().baud);
    let ticks = (run.duration * run.rate).floor() as usize + 1;
    let mut draws =
        Xoshiro256PlusPlus::seed_from_u64(run.servo_readings.map_or(1, |noise| noise.seed));
    let mut summary = SyntheticLog {
        trajectory: path.clone(),
        rows: 0,
        rest_rows: 0,
        clamps: (0, 0),
    };
    let fail = |plant: &Plant, what: String| {
        format!(
            "the plant failed at t = {:.4} s ({what}{})",
            plant.time(),
            plant
                .last_dynamics_error()
                .map_or(String::new(), |e| format!(": {e}"))
        )
    };
    for j in 0..ticks {
        let t = j as f64 * period;
        let sample_time = t - run.sampled;
        plant
            .advance(sample_time - plant.time())
            .map_err(|e| fail(&plant, e.to_string()))?;
        let (mut q, mut qd) = (plant.q().to_vec(), plant.qd().to_vec());
        if let Some(noise) = &run.servo_readings {
            read_like_servos(&map, noise, &mut draws, &mut q, &mut qd);
        }
        wanted.fill(0.0);
        let phase = schedule(&Tick { t, q: &q, qd: &qd }, &mut wanted);
        let (mut low, mut high) = (0u32, 0u32);
        for (s, (&f, slot)) in wanted.iter().zip(&mut tensions).enumerate() {
            let [f_min, f_max] = map.hardware().modules[s / 3].tension_limits;
            *slot = if f.is_nan() || f < f_min {
                low += 1;
                f_min
            } else if f > f_max {
                high += 1;
                f_max
            } else {
                f
            };
            registers[s] = map.current_from_tension(s, *slot);
            currents[s] = f64::from(registers[s]) * unit;
            applied[s] = match run.gains {
                Some(gains) => {
                    let direction = plant_map.hardware().modules[s / 3].directions[s % 3];
                    gains[s] * (direction * currents[s]).max(0.0)
                }
                None => plant_map.tension_from_current(s, registers[s]).max(0.0),
            };
        }
        summary.clamps.0 += low;
        summary.clamps.1 += high;
        map.tau_from_tensions(&tensions, &mut tau);
        model_terms(file, &mut ws, &mut barriers, &q, &qd).map_err(|e| e.to_string())?;
        let us = |s: f64| s * 1e6;
        // Every fixed column by name, as the run loop writes them.
        let fixed = Extra::ALL.map(|column| match column {
            Extra::Fresh => 1.0,
            Extra::Status => 0.0,
            Extra::Reason => 0.0,
            Extra::Attempts => 1.0,
            Extra::CommErrors => 0.0,
            Extra::Read => us(run.sampled),
            Extra::Compute => us(run.compute),
            Extra::Write => us(run.write),
            Extra::Late => 0.0,
            Extra::Overrun => 0.0,
            Extra::ClampLow => f64::from(low),
            Extra::ClampHigh => f64::from(high),
            Extra::Age => us(run.sampled + run.compute + run.write),
            Extra::Period => us(period),
            Extra::Hold => us(period),
            Extra::HoldExcess => 0.0,
            Extra::GainScale => 1.0,
            Extra::Sampled => us(run.sampled),
            Extra::Step => phase.step,
            Extra::Rest => {
                if phase.rest {
                    1.0
                } else {
                    0.0
                }
            }
        });
        let (head, rest) = extra.split_at_mut(fixed.len());
        head.copy_from_slice(&fixed);
        rest[..servos].copy_from_slice(&tensions);
        rest[servos..servos + nq].copy_from_slice(&q);
        rest[servos + nq..].copy_from_slice(&currents);
        writer
            .push_row(&Row {
                t,
                q: &q,
                qd: &qd,
                tau: &tau,
                tau_nom: &tau,
                b: barriers.values(),
                extra: &extra,
            })
            .map_err(|e| e.to_string())?;
        summary.rows += 1;
        summary.rest_rows += usize::from(phase.rest);
        // The command lands, and holds until the next one.
        let landing = t + run.compute + run.write + wire;
        plant
            .advance(landing - plant.time())
            .map_err(|e| fail(&plant, e.to_string()))?;
        plant_map.tau_from_tensions(&applied, plant.tau_mut());
    }
    writer.finish().map_err(|e| e.to_string())?;
    // The summary a run of the robot would write, without what a synthetic run has not
    // got (a bus, deadlines, a verdict), which reads back as the defaults.
    let experiment = run.kind.map(|kind| ExperimentSummary {
        synthetic: true,
        design: ExperimentDesign::unknown(match kind {
            ExperimentKind::Static => crate::hardware::experiment::ExperimentKind::Static,
            ExperimentKind::Dynamic => crate::hardware::experiment::ExperimentKind::Dynamic,
        }),
        ..ExperimentSummary::default()
    });
    let file_summary = HardwareSummary {
        controller: "filter".to_string(),
        robot: file.robot.name.clone(),
        hardware: true,
        loop_rate: Some(run.rate),
        experiment,
        clamps: Clamps {
            low: u64::from(summary.clamps.0),
            high: u64::from(summary.clamps.1),
        },
        ..HardwareSummary::default()
    };
    file_summary.write(dir)?;
    Ok(summary)
}

/// A multisine: `a Σ_k sin(2π f_k t + φ_k)` with `components` frequencies spread
/// logarithmically over `[low, high]` \[Hz\] and Schroeder phases (a low crest factor),
/// with the RMS of a single sine of amplitude `amplitude` (`a = amplitude/√components`;
/// its peaks stay near 1.5 times `amplitude`).
#[derive(Clone, Debug)]
pub struct Multisine {
    frequencies: Vec<f64>,
    phases: Vec<f64>,
    scale: f64,
}

impl Multisine {
    /// The multisine of `components` frequencies in `[low, high]`, its phases shifted by
    /// `shift` (different shifts decorrelate several channels).
    pub fn new(components: usize, low: f64, high: f64, amplitude: f64, shift: f64) -> Multisine {
        let n = components.max(1);
        let frequencies: Vec<f64> = (0..n)
            .map(|k| {
                if n == 1 {
                    low
                } else {
                    low * (high / low).powf(k as f64 / (n - 1) as f64)
                }
            })
            .collect();
        let phases: Vec<f64> = (0..n)
            .map(|k| {
                -std::f64::consts::PI * (k * (k + 1)) as f64 / n as f64 + shift * (k + 1) as f64
            })
            .collect();
        Multisine {
            frequencies,
            phases,
            scale: amplitude / (n as f64).sqrt(),
        }
    }

    /// The value at `t` \[s\].
    pub fn at(&self, t: f64) -> f64 {
        let tau = std::f64::consts::TAU;
        self.frequencies
            .iter()
            .zip(&self.phases)
            .map(|(f, p)| (tau * f * t + p).sin())
            .sum::<f64>()
            * self.scale
    }
}

/// `q`, `q̇` as the servos report them: each angle and rate with `noise` (in register
/// units), rounded to the registers' units and mapped back.
fn read_like_servos(
    map: &TendonMap,
    noise: &SensorNoise,
    draws: &mut Xoshiro256PlusPlus,
    q: &mut [f64],
    qd: &mut [f64],
) {
    let servos = map.n_servos();
    let (mut angles, mut rates) = (vec![0.0; servos], vec![0.0; servos]);
    map.angles_from_q(q, &mut angles);
    map.rates_from_qd(qd, &mut rates);
    let (position_unit, velocity_unit) = (map.angle_from_position(1), map.rate_from_velocity(1));
    for s in 0..servos {
        let [position, velocity] = [(); 2].map(|_| standard_normal(draws));
        let angle = angles[s] + noise.position * position_unit * position;
        let rate = rates[s] + noise.velocity * velocity_unit * velocity;
        angles[s] = map.angle_from_position(map.position_from_angle(angle));
        rates[s] = map.rate_from_velocity(map.velocity_from_rate(rate));
    }
    map.q_from_angles(&angles, q);
    map.qd_from_rates(&rates, qd);
}
