//! The control loop against the servo emulator over a pseudo-terminal, as `softcbf run`
//! and `softcbf emulate` use them: the paper's hardware set point on the example robot,
//! fault injection, and the safe stop. Checks use the emulator's own record of the bus.
//!
//! The emulator steps the plant in real time: run these optimized, as CI does
//! (`cargo test --release`); an unoptimized plant falls behind the wall clock.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use serialport::{SerialPort, TTYPort};
use softcbf::control::SafetyMode;
use softcbf::hardware::emulator::{self, EmulatorLog, EmulatorSettings, Faults};
use softcbf::hardware::log::{CsvLog, FIXED_EXTRA};
use softcbf::hardware::mapping::TendonMap;
use softcbf::hardware::run_loop::{
    self, RateRule, Row, RunLog, RunSettings, RunSummary, StopReason,
};
use softcbf::hardware_description::{self as description, Hardware, VelocitySource};
use softcbf::model::Model;
use softcbf::protocol::Bus;
use softcbf::record::Record;
use softcbf::verdict::{Limits, Verdict};
use softcbf_description::robot::Robot;

fn example() -> Robot {
    softcbf_tests::robots::hardware_example()
}

/// One loop against one emulator at a time: the timing of the loop is part of the result.
static SERIAL: Mutex<()> = Mutex::new(());

/// One logged row: time, `q`, barriers, extra columns.
type Kept = (f64, Vec<f64>, Vec<f64>, Vec<f64>);

/// Rows kept in memory.
#[derive(Default)]
struct MemoryLog {
    rows: Vec<Kept>,
    flushed: bool,
}

impl RunLog for MemoryLog {
    fn push(&mut self, row: &Row<'_>) -> Result<(), String> {
        self.rows
            .push((row.t, row.q.to_vec(), row.b.to_vec(), row.extra.to_vec()));
        Ok(())
    }
    fn flush(&mut self) -> Result<(), String> {
        self.flushed = true;
        Ok(())
    }
}

/// Rows to memory and to the CSV log `softcbf run` writes.
struct Tee<'a> {
    memory: &'a mut MemoryLog,
    csv: Option<&'a mut CsvLog>,
}

impl RunLog for Tee<'_> {
    fn push(&mut self, row: &Row<'_>) -> Result<(), String> {
        self.memory.push(row)?;
        self.csv.as_mut().map_or(Ok(()), |csv| csv.push(row))
    }
    fn flush(&mut self) -> Result<(), String> {
        self.memory.flush()?;
        self.csv.as_mut().map_or(Ok(()), |csv| csv.flush())
    }
}

struct Outcome {
    summary: RunSummary,
    log: MemoryLog,
    bus: EmulatorLog,
}

/// Runs the emulator in a thread and the loop on the other end of a pty.
fn run_against_emulator(faults: Faults, duration: f64) -> Outcome {
    run_with(example(), faults, duration, None)
}

/// Runs the emulator of `robot` in a thread and the loop on the other end of a pty; with
/// `out`, also writes the log and figures there as `softcbf run` does.
fn run_with(robot: Robot, faults: Faults, duration: f64, out: Option<&Path>) -> Outcome {
    let hardware = description::load(&robot).unwrap().unwrap();
    run_with_hardware(robot, hardware, faults, duration, out, 33.0)
}

/// The reply timeout of the tests not about it \[s\]: a machine loaded by other work (CI
/// shares its two cores) starves the emulator's thread for longer than the file's 10 ms.
const LOADED_REPLY_TIMEOUT: f64 = 0.1;

/// [`run_with`], the loop driving the servos through `hardware` (the robot file's, changed),
/// at `rate` Hz (every tick overruns when the bus cannot hold it), with a reply timeout of
/// [`LOADED_REPLY_TIMEOUT`].
fn run_with_hardware(
    robot: Robot,
    hardware: Hardware,
    faults: Faults,
    duration: f64,
    out: Option<&Path>,
    rate: f64,
) -> Outcome {
    run_with_timeout(
        robot,
        hardware,
        faults,
        duration,
        out,
        rate,
        LOADED_REPLY_TIMEOUT,
    )
}

/// [`run_with_hardware`] with a reply timeout of `timeout` seconds.
fn run_with_timeout(
    robot: Robot,
    hardware: Hardware,
    faults: Faults,
    duration: f64,
    out: Option<&Path>,
    rate: f64,
    timeout: f64,
) -> Outcome {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (mut master, slave) = TTYPort::pair().expect("a pseudo-terminal");
    master.set_timeout(Duration::from_millis(20)).unwrap();
    let path = slave.name().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let shared = Arc::new(Mutex::new(EmulatorLog::default()));
    let mut settings = EmulatorSettings::new(1_000_000);
    settings.faults = faults;
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let server = {
        let (robot, stop, shared) = (robot.clone(), stop.clone(), shared.clone());
        thread::spawn(move || {
            let mut ready = || ready_tx.send(()).unwrap();
            emulator::serve(
                &robot,
                &settings,
                &mut master,
                &stop,
                &mut ready,
                Some(&shared),
            )
        })
    };
    ready_rx.recv().expect("the emulator starts serving");
    let port = serialport::new(&path, 1_000_000)
        .timeout(Duration::from_millis(1))
        .open_native()
        .unwrap();
    let mut bus = Bus::new(port, Duration::from_secs_f64(timeout));
    let map = TendonMap::with_hardware(&robot, hardware.clone()).unwrap();
    let model = Model::new(robot).unwrap();
    let mut settings = RunSettings::new(rate, hardware.set_point.clone());
    // These runs are not about --min-rate (runtime/tests/cli/hardware_cli.rs): a loaded machine
    // may tick slower than half the rate, and the loop goes on.
    settings.min_rate = Some(1.0);
    settings.duration = Some(duration);
    // 33 Hz also on a bus too slow for it (late replies): every tick then overruns. The
    // refusal of such a rate is tested in runtime/tests/cli/bus_check_cli.rs.
    settings.rate_rule = RateRule::Overrun;
    let mut log = MemoryLog::default();
    let mut csv = out.map(|dir| softcbf::hardware::log::open(dir, &model, map.hardware()).unwrap());
    let never = AtomicBool::new(false);
    let mut tee = Tee {
        memory: &mut log,
        csv: csv.as_mut(),
    };
    let summary = run_loop::run(&model, &map, &mut bus, &settings, &mut tee, &never).unwrap();
    if let (Some(csv), Some(dir)) = (csv, out) {
        softcbf::hardware::log::finish(csv, dir, true, &settings.set_point, &model).unwrap();
    }
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap().unwrap();
    drop(slave);
    let bus = shared.lock().unwrap().clone();
    Outcome { summary, log, bus }
}

/// The tolerance on the example robot's lowest barrier (tension limits in the filter's QP,
/// the sampled-data rows with the file's ±10 % margin): measured +6.7e-3 m (release build,
/// 1 Mbit/s, 33 Hz); with the hold correction it was −0.12e-3 to −0.23e-3 m, on module 1's
/// lower limit (docs/hardware.md); the hardware issue's target was −1e-3 m.
const BARRIER_TOLERANCE: f64 = -1e-3;

/// Without the hold correction (velocity from filtered differences): measured −0.4e-3 to
/// −1.9e-3 m, with margin for a loaded CI machine.
const BARRIER_TOLERANCE_UNCORRECTED: f64 = -3e-3;

fn min_barrier(log: &MemoryLog) -> f64 {
    log.rows
        .iter()
        .flat_map(|r| r.2.iter())
        .fold(f64::INFINITY, |a, b| a.min(*b))
}

#[test]
fn paper_set_point_barriers_held_against_the_emulator() {
    let dir = std::env::temp_dir().join(format!("softcbf-hardware-loop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = run_with(example(), Faults::default(), 4.0, Some(&dir));
    let s = &out.summary;
    println!("{s:#?}");
    assert_eq!(s.stop, StopReason::Duration);
    assert!(!s.stop.is_fault());
    // The log is complete: one row per tick, flushed, every row fresh.
    assert!(out.log.flushed);
    assert_eq!(out.log.rows.len() as u64, s.ticks);
    // 33 Hz for 4 s, unless the machine (loaded by other work) did not keep the period,
    // which its own deadlines tell.
    if s.deadlines.deadline_overruns * 20 <= s.ticks {
        assert!(s.ticks >= 120, "{} ticks in 4 s at 33 Hz", s.ticks);
    } else {
        println!(
            "loaded machine: {} of {} deadlines missed, the tick count not checked",
            s.deadlines.deadline_overruns, s.ticks
        );
    }
    assert_eq!((s.held, s.commands), (0, s.ticks));
    assert!(out.log.rows.iter().all(|r| r.3[0] == 1.0));
    // The CSV on disk has every row with the simulate columns first, and the figures exist.
    let record = Record::read_csv(&dir.join("trajectory.csv")).unwrap();
    assert_eq!(record.len() as u64, s.ticks);
    let header = record.columns().header();
    assert!(
        header.starts_with("t [s],dx1 [m],dy1 [m],dL1 [m],dx2 [m],dy2 [m],dL2 [m],dx1/dt [m/s],"),
        "{header}"
    );
    assert!(header.contains(",b module 1 corner 1 [m],"), "{header}");
    assert!(header.ends_with(",fresh,status,reason,attempts,comm_errors,read [us],compute [us],write [us],late [us],overrun,clamp_low,clamp_high,age [us],period [us],hold [us],hold_excess [us],gain_scale,sampled [us],step,rest,f module 1 tendon 1 [N],f module 1 tendon 2 [N],f module 1 tendon 3 [N],f module 2 tendon 1 [N],f module 2 tendon 2 [N],f module 2 tendon 3 [N],qpred dx1 [m],qpred dy1 [m],qpred dL1 [m],qpred dx2 [m],qpred dy2 [m],qpred dL2 [m],I module 1 tendon 1 [mA],I module 1 tendon 2 [mA],I module 1 tendon 3 [mA],I module 2 tendon 1 [mA],I module 2 tendon 2 [mA],I module 2 tendon 3 [mA]"), "{header}");
    for (k, row) in out.log.rows.iter().enumerate() {
        assert_eq!(record.row(k).unwrap().q, &row.1[..], "row {k}");
    }
    for figure in ["figure.png", "figure.svg"] {
        let size = std::fs::metadata(dir.join(figure))
            .map(|m| m.len())
            .unwrap_or(0);
        assert!(size > 10_000, "{figure}: {size} bytes");
    }
    std::fs::remove_dir_all(&dir).unwrap();
    // Torque is off on every servo after the stop, confirmed and in the emulator.
    assert!(s.torque_off.iter().all(|(_, ok)| *ok));
    assert!(out.bus.torque.iter().all(|on| !on));
    // The set point violates both modules' barriers; the filter holds them.
    let min = min_barrier(&out.log);
    println!("minimum barrier {min:e}");
    assert!(min >= BARRIER_TOLERANCE, "minimum barrier {min}");
    // ... and module 1 was compressed toward its elongation limit δL_min + ε = −0.028 m, but
    // stopped short of it by the robust margin of the file's ±10 % (measured −0.0212 m;
    // the set point's −0.04 m is not reached).
    let last = &out.log.rows.last().unwrap().1;
    assert!(last[2] < -0.015 && last[2] > -0.028, "δL1 = {}", last[2]);
}

/// Every command sent in the loop was computed from a reading in which every servo's reply
/// arrived intact, a different one for each command, and the `q` the controller used is
/// the one those replies encode.
fn assert_commands_from_fresh_readings(out: &Outcome) {
    let map = TendonMap::new(&example()).unwrap();
    let fresh_rows: Vec<_> = out.log.rows.iter().filter(|r| r.3[0] == 1.0).collect();
    assert_eq!(fresh_rows.len() as u64, out.summary.commands);
    // Goal writes with a non-zero current: the taut-cable write of the safe start, then one
    // per command (the safe start's and safe stop's zero writes are excluded).
    let commands: Vec<usize> = (0..out.bus.goal_writes.len())
        .filter(|&w| out.bus.goal_writes[w].1.iter().any(|(_, c)| *c != 0))
        .collect();
    assert_eq!(commands.len(), fresh_rows.len() + 1);
    let mut previous_read = None;
    for (j, &w) in commands.iter().enumerate() {
        let read = out.bus.read_before_write[w].expect("a reading precedes every command");
        let (_, replies) = &out.bus.state_reads[read];
        assert!(
            replies.iter().all(|r| r.fate.intact()),
            "command {j} follows a reading with {replies:?}"
        );
        assert!(
            previous_read.is_none_or(|p| read > p),
            "command {j} reuses reading {read}"
        );
        previous_read = Some(read);
        if j == 0 {
            continue;
        }
        let row = fresh_rows[j - 1];
        let q = q_of(&map, replies);
        assert_eq!(
            q, row.1,
            "command {j}: q used ≠ q of the last intact reading"
        );
        let tensions = &row.3[FIXED_EXTRA..FIXED_EXTRA + 6];
        for (k, (id, current)) in out.bus.goal_writes[w].1.iter().enumerate() {
            assert_eq!(*id, replies[k].id);
            assert_eq!(
                *current,
                map.current_from_tension(k, tensions[k]),
                "command {j}, servo {id}"
            );
        }
    }
}

#[test]
fn dropped_corrupt_and_late_replies_are_retried_and_never_commanded_from() {
    // Delays of 15 ms exceed the 10 ms reply timeout: the late packets must be rejected.
    let faults = Faults {
        drop: 0.03,
        corrupt: 0.03,
        delay: Duration::from_millis(15),
        delay_fraction: 0.02,
        seed: 5,
        ..Faults::default()
    };
    let robot = example();
    let hardware = description::load(&robot).unwrap().unwrap();
    let timeout = hardware.reply_timeout;
    let out = run_with_timeout(robot, hardware, faults, 3.0, None, 33.0, timeout);
    let s = &out.summary;
    println!("{s:#?}\nfates {:?}", out.bus.fates);
    // With the file's 10 ms reply timeout (the late packets must come after it), a machine
    // loaded by other work may lose the emulator's replies five ticks in a row: a stop the
    // loop makes rightly, which this test then only reports.
    assert_eq!(out.log.rows.len() as u64, s.ticks);
    assert_commands_from_fresh_readings(&out);
    assert!(out.bus.torque.iter().all(|on| !on));
    if let StopReason::CommunicationLost { .. } = s.stop {
        println!("loaded machine, the faults' counts not checked: {}", s.stop);
        return;
    }
    assert_eq!(s.stop, StopReason::Duration);
    assert!(s.commands > s.ticks / 2);
    let fates = out.bus.fates;
    assert!(
        fates[1] > 0 && fates[2] > 0 && fates[3] > 0,
        "faults were injected: {fates:?}"
    );
    assert!(s.bus.timeouts > 0, "dropped replies time out");
    assert!(s.bus.crc_errors > 0, "corrupt replies are seen");
    assert!(s.bus.retries > 0, "and retried");
    assert_eq!(s.commands + s.held, s.ticks);
}

#[test]
fn fault_free_commands_also_come_from_their_own_readings() {
    let out = run_against_emulator(Faults::default(), 1.0);
    assert_commands_from_fresh_readings(&out);
}

#[test]
fn a_silent_servo_triggers_the_safe_stop_with_torque_off() {
    let faults = Faults {
        silent_servo: Some(5),
        silent_after: Duration::from_millis(1500),
        ..Faults::default()
    };
    let out = run_against_emulator(faults, 10.0);
    let s = &out.summary;
    println!("{s:#?}");
    let StopReason::CommunicationLost { ticks, .. } = &s.stop else {
        panic!("expected a communication loss, got {:?}", s.stop);
    };
    assert_eq!(*ticks, 5, "max_consecutive_errors of the example");
    assert!(s.stop.is_fault());
    assert!(
        s.elapsed < 5.0,
        "stopped soon after the servo fell silent: {} s",
        s.elapsed
    );
    // Torque off everywhere (the silent servo obeys the broadcast), confirmed where it can be.
    assert!(out.bus.torque.iter().all(|on| !on), "{:?}", out.bus.torque);
    for (id, confirmed) in &s.torque_off {
        assert_eq!(*confirmed, *id != 5, "servo {id}");
    }
    // The held ticks sent nothing: the last command precedes the silence.
    assert_commands_from_fresh_readings(&out);
    assert_eq!(
        out.log
            .rows
            .iter()
            .rev()
            .take(5)
            .filter(|r| r.3[0] == 0.0)
            .count(),
        5
    );
}

#[test]
fn velocity_from_filtered_differences_also_holds_the_barriers() {
    let robot = example();
    let mut hardware = description::load(&robot).unwrap().unwrap();
    hardware.velocity_source = VelocitySource::Difference;
    // The hold correction leans on q̇ over the whole tick; the filtered difference lags
    // by about a tick, and with it the corrected rows did worse (−9.6 mm) than the paper's
    // (−0.4 mm) here, as robots/README.md says.
    hardware.safety = Some(SafetyMode::Paper);
    let out = run_with_hardware(robot, hardware, Faults::default(), 3.0, None, 33.0);
    println!("{:#?}", out.summary);
    assert_eq!(out.summary.stop, StopReason::Duration);
    let min = min_barrier(&out.log);
    println!("minimum barrier {min:e}");
    assert!(
        min >= BARRIER_TOLERANCE_UNCORRECTED,
        "minimum barrier {min}"
    );
}

/// `q` from one sync read's replies, as the loop maps it.
fn q_of(map: &TendonMap, replies: &[softcbf::hardware::emulator::StateReply]) -> Vec<f64> {
    let angles: Vec<f64> = replies
        .iter()
        .map(|r| map.angle_from_position(r.state.position))
        .collect();
    let mut q = vec![0.0; 6];
    map.q_from_angles(&angles, &mut q);
    q
}

#[test]
fn late_readings_are_predicted_to_when_the_command_lands() {
    // Every reply 5 ms late: a reading of six servos takes 30 ms, and is 33 ms old when
    // the command computed from it reaches the servos. The loop then reads again at once
    // (every tick overruns), so the next reading shows the state at that moment.
    let faults = Faults {
        delay: Duration::from_millis(5),
        ..Faults::default()
    };
    // Without the file's declared uncertainty: the robust margin stops the robot early, and
    // the prediction is compared while the robot moves.
    let mut robot = example();
    robot.uncertainty = Default::default();
    let out = run_with(robot, faults, 3.0, None);
    println!("{:#?}", out.summary);
    assert_eq!(out.summary.stop, StopReason::Duration);
    assert!(out.summary.max_age > 0.030, "age {}", out.summary.max_age);
    let map = TendonMap::new(&example()).unwrap();
    let fresh_rows: Vec<_> = out.log.rows.iter().filter(|r| r.3[0] == 1.0).collect();
    let commands: Vec<usize> = (0..out.bus.goal_writes.len())
        .filter(|&w| out.bus.goal_writes[w].1.iter().any(|(_, c)| *c != 0))
        .collect();
    let (mut predicted_error, mut stale_error, mut compared) = (0.0, 0.0, 0);
    for (j, &w) in commands.iter().enumerate().skip(1) {
        let Some(read) = out.bus.read_before_write[w] else {
            continue;
        };
        let Some((_, next)) = out.bus.state_reads.get(read + 1) else {
            continue;
        };
        let landed = q_of(&map, next);
        let row = fresh_rows[j - 1];
        let predicted = &row.3[FIXED_EXTRA + 6..FIXED_EXTRA + 12];
        for i in 0..6 {
            predicted_error += (predicted[i] - landed[i]).powi(2);
            stale_error += (row.1[i] - landed[i]).powi(2);
        }
        compared += 1;
    }
    let rms = |sum: f64| (sum / (6 * compared) as f64).sqrt();
    println!(
        "{compared} commands: RMS error of the predicted state {:.2e} m, of the state read {:.2e} m",
        rms(predicted_error),
        rms(stale_error)
    );
    // The emulator runs in real time: a loaded machine fits fewer commands into the run (40
    // of 2 s once, with the certified attempts out of their budget on 27 ticks). 20 are
    // enough for the two RMS errors below; 3 s leave room for three times fewer than idle.
    assert!(compared >= 20, "{compared} commands compared");
    // The position resolution of the servos is 0.07 mm of tendon.
    assert!(rms(predicted_error) < 3e-4, "{:e}", rms(predicted_error));
    // The prediction's floor is the resolution; the reading's error is the motion over
    // 33 ms, which the sampled rows keep smaller than the paper's did (measured: 1.2e-4 m
    // against 5.8e-4 m; with the hold correction the ratio was below 0.2).
    assert!(rms(predicted_error) < rms(stale_error) / 3.0);
}

#[test]
fn the_safe_start_retries_missed_replies_like_the_loop() {
    // 6 % of all status packets lost. Each start-up transaction of one servo (pings,
    // register writes) is tried up to (1 + retries) · max_consecutive_errors = 10 times and
    // fails with probability 0.06¹⁰ ≈ 6e-13; the first reading needs all six replies of one
    // sync read (probability 0.94⁶ ≈ 0.69) and is tried up to 11 times: it fails with
    // probability 0.31¹¹ ≈ 3e-6. So the start succeeds whatever the seed (a failed start
    // would be an error, and `run_with` unwraps the summary); the loop then holds some
    // ticks. In 3 s at 33 Hz about 640 replies are sent, about 38 of them dropped (standard
    // deviation 6): more than 10 whatever the seed.
    let faults = Faults {
        drop: 0.06,
        seed: 11,
        ..Faults::default()
    };
    let out = run_against_emulator(faults, 3.0);
    println!("{:#?}", out.summary);
    assert!(out.summary.ticks > 0);
    assert!(
        out.bus.fates[2] > 10,
        "replies dropped: {:?}",
        out.bus.fates
    );
    assert!(out.bus.torque.iter().all(|on| !on));
}

/// Deadlines missed beyond the allowed fraction make the verdict unsafe, whatever the
/// barriers did: at 2000 Hz, far beyond the ideal bus's 500 Hz or so (and beyond any
/// loaded machine's), every tick overruns.
#[test]
fn missed_deadlines_are_in_the_verdict() {
    let robot = example();
    let hardware = description::load(&robot).unwrap().unwrap();
    let out = run_with_hardware(robot, hardware, Faults::default(), 1.0, None, 2000.0);
    let s = &out.summary;
    // Hundreds of commands on an idle machine, a few on a loaded one: all overrun.
    assert!(s.commands > 0, "{} commands", s.commands);
    assert!(
        s.deadlines.deadline_overruns * 10 >= s.ticks * 9,
        "{} of {} ticks overran",
        s.deadlines.deadline_overruns,
        s.ticks
    );
    let limits = Limits::new(-1e-3);
    let verdict = s.verdict(&limits);
    assert_eq!(verdict.status(), softcbf::exit::UNSAFE, "{verdict:?}");
    assert!(
        verdict.line().contains("ticks overran their deadline"),
        "{verdict:?}"
    );
    // Allowed by the operator, the same run is judged on its barriers and rows alone
    // (whether they held depends on the load: every command stays in force longer than the
    // hold it was computed for, which the guarantee does not cover).
    let all_allowed = Limits {
        max_overrun_fraction: 1.0,
        ..limits
    };
    let verdict = s.verdict(&all_allowed);
    assert!(
        !verdict.line().contains("overran"),
        "overruns allowed: {verdict:?}"
    );
    // Relaxed ticks (rows without a common point: 28 of 29 in one run on a loaded machine)
    // make it unsafe too.
    if min_barrier(&out.log) >= -1e-3 && s.relaxed == 0 {
        assert_eq!(verdict, Verdict::Safe);
    } else {
        assert!(
            verdict.line().contains("lowest barrier")
                || verdict.line().contains("ticks relaxed barrier rows"),
            "{verdict:?}"
        );
    }
}
