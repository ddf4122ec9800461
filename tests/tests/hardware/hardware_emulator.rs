//! The servo emulator's Protocol 2.0 semantics and pacing, driven through the bus client
//! over a pseudo-terminal: what a real X-series servo would answer.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::thread;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};
use softcbf::hardware::control_table as table;
use softcbf::hardware::emulator::servos::Servos;
use softcbf::hardware::emulator::{self, EmulatorLog, EmulatorSettings, wire_time};
use softcbf::integrator::Tolerances;
use softcbf::plant::Plant;
use softcbf::protocol::{BROADCAST_ID, Bus, BusError, Instruction, PacketRef, StatusError};
use softcbf_description::robot::Robot;
use softcbf_tests::robots::{hardware_example, path};

/// Runs `body` against an emulator of the example robot at `baud`.
fn with_emulator(baud: u32, body: impl FnOnce(&mut Bus<TTYPort>)) {
    with_logged_emulator(baud, Arc::default(), body);
}

/// [`with_emulator`], the emulator keeping `log` up to date.
fn with_logged_emulator(
    baud: u32,
    log: Arc<Mutex<EmulatorLog>>,
    body: impl FnOnce(&mut Bus<TTYPort>),
) {
    let robot = softcbf_tests::robots::hardware_example();
    let (mut master, slave) = TTYPort::pair().unwrap();
    master.set_timeout(Duration::from_millis(20)).unwrap();
    let name = slave.name().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let server = {
        let stop = stop.clone();
        thread::spawn(move || {
            let settings = EmulatorSettings::new(baud);
            let mut ready = || tx.send(()).unwrap();
            emulator::serve(
                &robot,
                &settings,
                &mut master,
                &stop,
                &mut ready,
                Some(&*log),
            )
        })
    };
    rx.recv().unwrap();
    let port = serialport::new(&name, baud)
        .timeout(Duration::from_millis(1))
        .open_native()
        .unwrap();
    // Generous: a machine loaded by other work can starve the emulator's thread for
    // hundreds of milliseconds; the one timeout expected (a ping of an absent servo) waits
    // it out once.
    let mut bus = Bus::new(port, Duration::from_secs(1));
    body(&mut bus);
    stop.store(true, Ordering::Relaxed);
    server.join().unwrap().unwrap();
    drop(slave);
}

fn status_code(result: Result<StatusError, BusError>) -> u8 {
    match result {
        Ok(status) => status.code,
        Err(BusError::Status { error, .. }) => error.code,
        Err(other) => panic!("expected a status packet, got {other}"),
    }
}

#[test]
fn registers_answer_like_an_x_series_servo() {
    with_emulator(1_000_000, |bus| {
        let info = bus.ping(4).unwrap();
        assert_eq!(info.model_number, 1020);
        assert!(matches!(bus.ping(9), Err(BusError::Timeout { id: 9, .. })));
        let mut byte = [0u8];
        bus.read(2, table::ID, &mut byte).unwrap();
        assert_eq!(byte[0], 2);
        bus.read(2, table::BAUD_RATE, &mut byte).unwrap();
        assert_eq!(byte[0], 3, "1 Mbit/s");
        bus.read(2, table::OPERATING_MODE, &mut byte).unwrap();
        assert_eq!(byte[0], 3, "position control, as from the factory");
        // Operating Mode is writable with torque off only.
        assert_eq!(status_code(bus.write(2, table::OPERATING_MODE, &[0])), 0);
        assert_eq!(status_code(bus.write(2, table::TORQUE_ENABLE, &[1])), 0);
        assert_eq!(
            status_code(bus.write(2, table::OPERATING_MODE, &[3])),
            StatusError::ACCESS_ERROR
        );
        assert_eq!(
            status_code(bus.write(2, table::TORQUE_ENABLE, &[2])),
            StatusError::DATA_RANGE_ERROR
        );
        // Goal Current within ±Current Limit (1193).
        assert_eq!(
            status_code(bus.write(2, table::GOAL_CURRENT, &1193i16.to_le_bytes())),
            0
        );
        assert_eq!(
            status_code(bus.write(2, table::GOAL_CURRENT, &1194i16.to_le_bytes())),
            StatusError::DATA_LIMIT_ERROR
        );
        // Read-only and out-of-table addresses.
        assert_eq!(
            status_code(bus.write(2, table::PRESENT_POSITION, &[0; 4])),
            StatusError::ACCESS_ERROR
        );
        let mut far = [0u8; 4];
        assert!(matches!(
            bus.read(2, 200, &mut far),
            Err(BusError::Status { .. })
        ));
        // Present Current follows the goal while pulling; reboot drops torque and goal.
        let mut current = [0u8; 2];
        bus.read(2, table::PRESENT_CURRENT, &mut current).unwrap();
        assert_eq!(i16::from_le_bytes(current), 1193);
        assert_eq!(status_code(bus.reboot(2)), 0);
        bus.read(2, table::TORQUE_ENABLE, &mut byte).unwrap();
        assert_eq!(byte[0], 0);
        bus.read(2, table::PRESENT_CURRENT, &mut current).unwrap();
        assert_eq!(i16::from_le_bytes(current), 0);
        // A broadcast write is obeyed by all and answered by none.
        bus.write(BROADCAST_ID, table::TORQUE_ENABLE, &[1]).unwrap();
        for id in 1..=6 {
            bus.read(id, table::TORQUE_ENABLE, &mut byte).unwrap();
            assert_eq!(byte[0], 1, "servo {id}");
        }
        bus.write(BROADCAST_ID, table::TORQUE_ENABLE, &[0]).unwrap();
        assert_eq!(
            bus.counters().timeouts,
            1,
            "only the ping of the absent servo 9"
        );
    });
}

#[test]
fn replies_are_paced_by_wire_time() {
    // At 57600 bit/s a sync read of six 10-byte blocks is 20 + 6 × 21 bytes on the wire.
    let baud = 57_600;
    with_emulator(baud, |bus| {
        let ids = [1, 2, 3, 4, 5, 6];
        let mut out = [0u8; 60];
        let start = Instant::now();
        bus.sync_read(table::STATE_ADDRESS, table::STATE_LENGTH, &ids, &mut out)
            .unwrap();
        let elapsed = start.elapsed();
        let wire = wire_time(20 + 6 * 21, baud);
        assert!(elapsed >= wire, "{elapsed:?} < wire time {wire:?}");
    });
}

#[test]
fn a_servo_stops_on_its_own_when_the_controller_falls_silent() {
    let log = Arc::new(Mutex::new(EmulatorLog::default()));
    with_logged_emulator(1_000_000, log.clone(), |bus| {
        assert_eq!(status_code(bus.write(3, table::OPERATING_MODE, &[0])), 0);
        let goal = 200i16.to_le_bytes();
        assert_eq!(status_code(bus.write(3, table::GOAL_CURRENT, &goal)), 0);
        assert_eq!(status_code(bus.write(3, table::TORQUE_ENABLE, &[1])), 0);
        // Bus Watchdog 3: 60 ms without an instruction packet stops the servo.
        assert_eq!(status_code(bus.write(3, table::BUS_WATCHDOG, &[3])), 0);
        let requests = log.lock().unwrap().requests;
        // Say nothing until the emulator reports the stop (it checks its clock without
        // being asked); the bound only keeps a failure from hanging.
        let give_up = Instant::now() + Duration::from_secs(10);
        while log.lock().unwrap().watchdog_stops.is_empty() && Instant::now() < give_up {
            thread::sleep(Duration::from_millis(10));
        }
        let seen = log.lock().unwrap().clone();
        assert_eq!(seen.watchdog_stops.len(), 1, "the servo stopped");
        assert_eq!(seen.watchdog_stops[0].1, 3);
        assert_eq!(
            seen.requests, requests,
            "with no packet since the watchdog was set"
        );
        let mut byte = [0u8];
        bus.read(3, table::BUS_WATCHDOG, &mut byte).unwrap();
        assert_eq!(byte[0] as i8, -1);
        let mut current = [0u8; 2];
        bus.read(3, table::PRESENT_CURRENT, &mut current).unwrap();
        assert_eq!(i16::from_le_bytes(current), 0, "pulls with nothing");
        bus.write(BROADCAST_ID, table::TORQUE_ENABLE, &[0]).unwrap();
    });
}

/// The tension each emulated servo pulls with when every servo is switched to current
/// control, its torque enabled and its Goal Current set to `goal`, for the robot and
/// plant of `settings` ([`emulator::physics`], as `softcbf emulate` builds them).
fn tensions_at_goal_current(robot: &Robot, settings: &EmulatorSettings, goal: i16) -> Vec<f64> {
    let (map, model) = emulator::physics(robot, settings).unwrap();
    let ids = map.hardware().servo_ids();
    let plant = Plant::new(&model, Tolerances::default()).unwrap();
    let mut servos = Servos::new(map, plant, 3, 0);
    let mut replies = Vec::new();
    let mut write = |servos: &mut Servos, id: u8, addr: u16, data: &[u8]| {
        let params: Vec<u8> = addr
            .to_le_bytes()
            .into_iter()
            .chain(data.iter().copied())
            .collect();
        let packet = PacketRef {
            id,
            instruction: Instruction::Write,
            error: None,
            params: &params,
        };
        servos.execute(&packet, 0.0, &mut replies).unwrap();
    };
    for &id in &ids {
        write(
            &mut servos,
            id,
            table::OPERATING_MODE,
            &[table::CURRENT_CONTROL_MODE],
        );
        write(&mut servos, id, table::GOAL_CURRENT, &goal.to_le_bytes());
        write(&mut servos, id, table::TORQUE_ENABLE, &[1]);
    }
    assert!(replies.iter().all(|r| r.error == 0), "every write accepted");
    (0..ids.len()).map(|s| servos.tension(s)).collect()
}

/// With a plant file that has a `[hardware]` table, the servos pull with the plant's
/// actuator gains, per tendon; its servo IDs, signs and units are not used (the
/// controller's robot file gives them). Without one, the controller's gains stay.
#[test]
fn the_plant_file_gives_the_servos_their_true_actuator_gains() {
    let robot = hardware_example();
    let text = std::fs::read_to_string(path("calibration-true.toml")).unwrap();
    // Other IDs, signs and current unit in the plant's table: ignored.
    let other = text
        .replace("servo_ids = [1, 2, 3]", "servo_ids = [11, 12, 13]")
        .replace("direction = [1, -1, 1]", "direction = [-1, -1, -1]")
        .replace("current_unit_ma = 2.69", "current_unit_ma = 1.0");
    let mut settings = EmulatorSettings::new(1_000_000);
    settings.plant = Some(Robot::parse(&other, &path("calibration-true.toml")).unwrap());
    let goal = 100;
    // 100 units of 2.69 mA (the controller's unit) on gains 0.030, 0.052, 0.050 and 0.048,
    // 0.030, 0.056 N/mA (the plant's). A unit of 1 mA would give 3.0, 5.2, 5.0, … N.
    let true_tensions = [8.07, 13.988, 13.45, 12.912, 8.07, 15.064];
    // Servos 2 and 6 unwind on a positive current (signs −1 in the controller's file):
    // their cables are slack at this goal. At the opposite goal the other four are.
    let pulled = tensions_at_goal_current(&robot, &settings, goal);
    let pulled_back = tensions_at_goal_current(&robot, &settings, -goal);
    let winds = [true, false, true, true, true, false];
    for s in 0..6 {
        let (tight, slack) = if winds[s] {
            (pulled[s], pulled_back[s])
        } else {
            (pulled_back[s], pulled[s])
        };
        assert!(
            (tight - true_tensions[s]).abs() < 1e-12,
            "servo {}: {tight}",
            s + 1
        );
        assert_eq!(slack, 0.0, "servo {}", s + 1);
    }
    // A plant without a [hardware] table: the controller's 0.04 N/mA for every servo,
    // 100 · 2.69 mA · 0.04 N/mA = 10.76 N.
    settings.plant = Some(Robot::load(&path("hardware-example-true.toml")).unwrap());
    let pulled = tensions_at_goal_current(&robot, &settings, goal);
    for s in [0, 2, 3, 4] {
        assert!(
            (pulled[s] - 10.76).abs() < 1e-12,
            "servo {}: {}",
            s + 1,
            pulled[s]
        );
    }
}

/// A plant whose `[hardware]` table is invalid is refused, naming the plant's file, line
/// and field, before anything is served.
#[test]
fn an_invalid_plant_hardware_table_is_refused() {
    let robot = hardware_example();
    let text = std::fs::read_to_string(path("calibration-true.toml")).unwrap();
    let bad = text.replace("[0.030, 0.052, 0.050]", "[0.030, 0.052]");
    let line = 1 + bad[..bad.find("[0.030, 0.052]").unwrap()]
        .matches('\n')
        .count();
    let plant = Robot::parse(&bad, std::path::Path::new("true.toml")).unwrap();
    let expected = format!(
        "true.toml:{line}: field `hardware.module[1].actuator_gain`: has 2 entries; give one \
         gain per tendon (3), or a single number for all three"
    );
    let error = emulator::check_plant(&robot, &plant).unwrap_err();
    assert_eq!(error.to_string(), expected);
    let mut settings = EmulatorSettings::new(1_000_000);
    settings.plant = Some(plant);
    match emulator::physics(&robot, &settings) {
        Err(error) => assert_eq!(error.to_string(), expected),
        Ok(_) => panic!("the plant's invalid [hardware] table was accepted"),
    }
}
