//! `softcbf emulate`'s realism options: the USB adapter's latency timer, the servos' Return
//! Delay Time register, readings and goal currents in register units, seeded sensor noise,
//! the physics of a second robot file (`--plant`) and the presets.
//!
//! Most tests drive the emulator's I/O-free core ([`Device`]) on a clock of their own, so
//! delivery times are exact and nothing depends on the machine's speed; the one test over a
//! pseudo-terminal only bounds times from below. Expected values come from the robot files'
//! numbers, FTDI's application note AN232B-04 and the XM430 e-Manual, written out here.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, mpsc};
use std::thread;
use std::time::{Duration, Instant};

use clap::Parser;
use serialport::{SerialPort, TTYPort};
use softcbf::hardware::cli::{EmulateArgs, emulator_settings, plant_robot};
use softcbf::hardware::control_table as table;
use softcbf::hardware::emulator::device::Device;
use softcbf::hardware::emulator::{self, EmulatorError, EmulatorSettings, Preset, StateReply};
use softcbf::hardware_description as description;
use softcbf::integrator::Tolerances;
use softcbf::noise::SensorNoise;
use softcbf::plant::Plant;
use softcbf::protocol::{Bus, encode_ping, encode_sync_read, encode_write};
use softcbf_description::robot::Robot;

const BAUD: u32 = 1_000_000;
const IDS: [u8; 6] = [1, 2, 3, 4, 5, 6];
const MS: Duration = Duration::from_millis(1);
const US: Duration = Duration::from_micros(1);

fn robot_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(name)
}

fn robot(name: &str) -> Robot {
    Robot::load(&robot_path(name)).unwrap()
}

fn packet(
    encode: impl FnOnce(&mut Vec<u8>) -> Result<(), softcbf::protocol::EncodeError>,
) -> Vec<u8> {
    let mut out = Vec::new();
    encode(&mut out).unwrap();
    out
}

/// Wire time of `bytes` bytes at 1 Mbit/s, 8N1: 10 µs each.
fn wire(bytes: u32) -> Duration {
    10 * bytes * US
}

/// Whether two instants are within 1 µs (the emulator sums durations from floating point).
fn close(a: Instant, b: Instant) -> bool {
    a.max(b).duration_since(a.min(b)) <= US
}

/// `robots/hardware-example.toml`'s servos, moved by `settings.plant` or by it, driven on
/// the test's clock, and the instant they start serving.
fn with_device<T>(
    settings: EmulatorSettings,
    body: impl FnOnce(&mut Device<'_>, Instant) -> T,
) -> T {
    let (map, model) = emulator::physics(&robot("hardware-example.toml"), &settings).unwrap();
    let mut plant = Plant::new(&model, Tolerances::default()).unwrap();
    plant.advance(settings.settle).unwrap();
    let start = Instant::now();
    let mut device = Device::new(map, plant, &settings, start).unwrap();
    body(&mut device, start)
}

/// Every delivery to the host by `until`: its time and size.
fn deliveries(device: &mut Device<'_>, until: Instant) -> Vec<(Instant, usize)> {
    device.poll(until).unwrap();
    let mut out = Vec::new();
    while let Some(d) = device.take_due(until) {
        out.push((d.at, d.bytes.len()));
    }
    out
}

/// A sync read of the state block of every servo (20 bytes on the wire).
fn state_read() -> Vec<u8> {
    packet(|o| encode_sync_read(table::STATE_ADDRESS, table::STATE_LENGTH, &IDS, o))
}

// ---------------------------------------------------------------------------------------
// The adapter's latency timer

#[test]
fn replies_reach_the_host_on_latency_timer_expiries_or_when_a_usb_packet_fills() {
    let mut settings = EmulatorSettings::new(BAUD);
    settings.latency_timer = 16 * MS;
    with_device(settings, |device, start| {
        // A ping (10 bytes) at 3 ms; its reply (14 bytes) has crossed the bus by 3.24 ms
        // and waits for the timer's first expiry, 16 ms after power-up.
        device
            .receive(&packet(|o| encode_ping(1, o)), start + 3 * MS)
            .unwrap();
        assert_eq!(deliveries(device, start + 15 * MS), vec![]);
        let got = deliveries(device, start + 30 * MS);
        assert_eq!(got.len(), 1, "{got:?}");
        assert!(close(got[0].0, start + 16 * MS), "{got:?}");
        assert_eq!(got[0].1, 14);

        // A sync read at 40 ms ends on the bus at 40.2 ms; six replies of 21 bytes follow
        // back to back (Return Delay Time 0), byte k ending at 40.2 ms + (k + 1) · 10 µs.
        // Bytes 62 and 124 each fill a USB packet at once; the last 2 wait one whole
        // period after the second packet, which restarted the timer.
        let sent = start + 40 * MS;
        device.receive(&state_read(), sent).unwrap();
        let request_end = sent + wire(20);
        let got = deliveries(device, start + 80 * MS);
        let sizes: Vec<usize> = got.iter().map(|d| d.1).collect();
        assert_eq!(sizes, vec![62, 62, 2], "{got:?}");
        assert!(close(got[0].0, request_end + wire(62)), "{got:?}");
        assert!(close(got[1].0, request_end + wire(124)), "{got:?}");
        assert!(
            close(got[2].0, request_end + wire(124) + 16 * MS),
            "{got:?}"
        );
    });
}

#[test]
fn without_a_latency_timer_each_reply_leaves_when_its_last_byte_has_crossed() {
    with_device(EmulatorSettings::new(BAUD), |device, start| {
        device.receive(&state_read(), start).unwrap();
        let got = deliveries(device, start + 10 * MS);
        assert_eq!(got.len(), 6);
        for (k, &(at, size)) in got.iter().enumerate() {
            assert_eq!(size, 21);
            let end = start + wire(20) + wire(21 * (k as u32 + 1));
            assert!(close(at, end), "reply {k}: {got:?}");
        }
    });
}

/// Back-to-back pings through a pseudo-terminal with a 16 ms timer: each reply comes one
/// whole period after the previous one reached the host (the timer restarts there), so
/// `n` of them take at least `(n − 1)` periods, however fast the machine. Only a lower
/// bound is checked.
#[test]
fn through_a_port_back_to_back_replies_are_a_latency_period_apart() {
    let (mut master, slave) = TTYPort::pair().unwrap();
    master.set_timeout(20 * MS).unwrap();
    let name = slave.name().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready_rx) = mpsc::channel();
    let server = {
        let stop = stop.clone();
        thread::spawn(move || {
            let mut settings = EmulatorSettings::new(BAUD);
            settings.latency_timer = 16 * MS;
            settings.settle = 0.0;
            let mut ready = || ready_tx.send(()).unwrap();
            let robot = robot("hardware-example.toml");
            emulator::serve(&robot, &settings, &mut master, &stop, &mut ready, None)
                .map(|log| log.requests)
        })
    };
    ready_rx.recv().unwrap();
    let port = serialport::new(&name, BAUD)
        .timeout(MS)
        .open_native()
        .unwrap();
    let mut bus = Bus::new(port, Duration::from_secs(1));
    bus.ping(1).unwrap();
    let first = Instant::now();
    let pings = 5;
    for k in 0..pings {
        let info = bus.ping(IDS[k % 6]).unwrap();
        assert_eq!(info.model_number, 1020);
    }
    let elapsed = first.elapsed();
    stop.store(true, Ordering::Relaxed);
    assert_eq!(server.join().unwrap().unwrap(), 1 + pings as u64);
    drop(slave);
    // The timer of the first of these replies started when the reply before them was
    // delivered, a little before this clock started (measured up to 1.8 ms on a busy
    // machine): only `pings − 1` whole periods are sure to lie inside.
    assert!(
        elapsed >= 16 * MS * (pings as u32 - 1),
        "{pings} pings after a first one took {elapsed:?}, less than {} latency periods",
        pings - 1
    );
}

// ---------------------------------------------------------------------------------------
// Return Delay Time

#[test]
fn a_return_delay_time_written_by_the_host_delays_the_next_replies() {
    with_device(EmulatorSettings::new(BAUD), |device, start| {
        // Ping (10 bytes) then its reply (14 bytes), no delay.
        device
            .receive(&packet(|o| encode_ping(1, o)), start)
            .unwrap();
        let got = deliveries(device, start + 5 * MS);
        assert!(close(got[0].0, start + wire(10) + wire(14)), "{got:?}");

        // Return Delay Time 100 (× 2 µs): an EEPROM item, writable with torque off (12-byte
        // Write, 11-byte status, both without delay: the servo answers with its old value).
        let t = start + 10 * MS;
        let write = packet(|o| encode_write(1, table::RETURN_DELAY_TIME, &[100], o));
        assert_eq!(write.len(), 13);
        device.receive(&write, t).unwrap();
        let got = deliveries(device, t + 5 * MS);
        assert!(close(got[0].0, t + wire(13) + wire(11)), "{got:?}");

        let t = start + 20 * MS;
        device.receive(&packet(|o| encode_ping(1, o)), t).unwrap();
        let got = deliveries(device, t + 5 * MS);
        assert!(
            close(got[0].0, t + wire(10) + 200 * US + wire(14)),
            "{got:?}"
        );
        // Servo 2 keeps its own register: no delay.
        device
            .receive(&packet(|o| encode_ping(2, o)), t + 5 * MS)
            .unwrap();
        let got = deliveries(device, t + 10 * MS);
        assert!(close(got[0].0, t + 5 * MS + wire(24)), "{got:?}");
    });
}

#[test]
fn the_factory_return_delay_spaces_the_replies_of_a_sync_read() {
    let mut settings = EmulatorSettings::new(BAUD);
    Preset::Factory.apply(&mut settings);
    settings.latency_timer = Duration::ZERO;
    with_device(settings, |device, start| {
        assert_eq!(
            device.servos().table(0)[usize::from(table::RETURN_DELAY_TIME)],
            250
        );
        device.receive(&state_read(), start).unwrap();
        let got = deliveries(device, start + 20 * MS);
        assert_eq!(got.len(), 6);
        for (k, &(at, _)) in got.iter().enumerate() {
            // Each servo waits 500 µs after the bus is free, then sends 21 bytes.
            let end = start + wire(20) + (k as u32 + 1) * (500 * US + wire(21));
            assert!(close(at, end), "reply {k}: {got:?}");
        }
    });
}

// ---------------------------------------------------------------------------------------
// Readings and goal currents in register units

/// The servo angles \[deg\] and rates \[rev/min\] of `robots/hardware-example.toml` at `q`,
/// `q̇`, written from the file: tendon angles 90°, 210°, 330°, L0 = 0.06 m, pulley 45 mm,
/// zero angle 180° at length L0, directions [1, −1, 1] and [1, 1, −1]. A tendon of module
/// i has length ℓ = L0 + δL − Δx cos ψ − Δy sin ψ; the servo turns by −(ℓ − L0)/(ρ s).
fn expected_angles_and_rates(q: &[f64], qd: &[f64]) -> ([f64; 6], [f64; 6]) {
    let psi = [90f64, 210.0, 330.0].map(f64::to_radians);
    let directions = [1.0, -1.0, 1.0, 1.0, 1.0, -1.0];
    let (rho, rest) = (0.045, 0.06);
    let (mut angles, mut rates) = ([0.0; 6], [0.0; 6]);
    for servo in 0..6 {
        let (i, k) = (servo / 3, servo % 3);
        let tendon = |v: &[f64], base: f64| {
            base + v[3 * i + 2] - v[3 * i] * psi[k].cos() - v[3 * i + 1] * psi[k].sin()
        };
        let length = tendon(q, rest);
        let speed = tendon(qd, 0.0);
        let s = directions[servo];
        angles[servo] = 180.0 + (-(length - rest) / (rho * s)).to_degrees();
        rates[servo] = -speed / (rho * s) * 60.0 / std::f64::consts::TAU;
    }
    (angles, rates)
}

const POSITION_UNIT_DEG: f64 = 360.0 / 4096.0;
const VELOCITY_UNIT_RPM: f64 = 0.229;

/// Turns torque on in current control and pulls with goal currents `currents`.
fn pull(device: &mut Device<'_>, at: Instant, currents: [i16; 6]) {
    let mut t = at;
    for (k, &id) in IDS.iter().enumerate() {
        for (addr, data) in [
            (table::OPERATING_MODE, vec![table::CURRENT_CONTROL_MODE]),
            (table::TORQUE_ENABLE, vec![1]),
            (table::GOAL_CURRENT, currents[k].to_le_bytes().to_vec()),
        ] {
            device
                .receive(&packet(|o| encode_write(id, addr, &data, o)), t)
                .unwrap();
            t += MS;
            device.poll(t).unwrap();
        }
    }
}

/// The last sync read's replies.
fn last_read(device: &Device<'_>) -> Vec<StateReply> {
    device.log().state_reads.last().unwrap().1.clone()
}

#[test]
fn readings_are_the_plants_angles_and_rates_rounded_to_register_units() {
    with_device(EmulatorSettings::new(BAUD), |device, start| {
        pull(device, start, [60, -60, 60, 20, 20, -20]);
        let mut moving = 0;
        for step in 1..=40 {
            let t = start + 20 * MS + step * 7 * MS;
            device.receive(&state_read(), t).unwrap();
            device.poll(t + 5 * MS).unwrap();
            let plant = device.servos().plant();
            let (angles, rates) = expected_angles_and_rates(plant.q(), plant.qd());
            for (servo, reply) in last_read(device).iter().enumerate() {
                let exact_position = angles[servo] / POSITION_UNIT_DEG;
                let exact_velocity = rates[servo] / VELOCITY_UNIT_RPM;
                assert!(
                    (f64::from(reply.state.position) - exact_position).abs() <= 0.5 + 1e-6,
                    "servo {servo}: {} for {exact_position}",
                    reply.state.position
                );
                assert!(
                    (f64::from(reply.state.velocity) - exact_velocity).abs() <= 0.5 + 1e-6,
                    "servo {servo}: {} for {exact_velocity}",
                    reply.state.velocity
                );
                moving += usize::from(reply.state.velocity != 0);
            }
        }
        assert!(moving > 0, "the pull moved the robot");
    });
}

#[test]
fn goal_currents_pull_in_whole_current_units() {
    with_device(EmulatorSettings::new(BAUD), |device, start| {
        // One current unit of the XM430 is 2.69 mA; the actuator gain 0.04 N/mA: every
        // tension is a whole multiple of 0.1076 N. Servo 2 winds the other way.
        let currents = [37, -37, 1, 250, 0, -9];
        pull(device, start, currents);
        let directions = [1.0, -1.0, 1.0, 1.0, 1.0, -1.0];
        for (servo, &current) in currents.iter().enumerate() {
            let expected = (directions[servo] * f64::from(current) * 0.1076).max(0.0);
            let got = device.servos().tension(servo);
            assert!((got - expected).abs() < 1e-12, "servo {servo}: {got} N");
        }
        // A negative current unwinds: the cable goes slack.
        pull(device, start + 100 * MS, [-5, 5, 0, 0, 0, 0]);
        assert_eq!(device.servos().tension(0), 0.0);
        assert_eq!(device.servos().tension(1), 0.0);
    });
}

// ---------------------------------------------------------------------------------------
// Sensor noise

/// Deviations (reading − exact value, in register units) of `reads` state reads of every
/// servo 5 ms apart, at rest (torque off), with `noise`.
fn deviations(noise: SensorNoise, reads: u32) -> (Vec<f64>, Vec<f64>, Vec<StateReply>) {
    let mut settings = EmulatorSettings::new(BAUD);
    settings.noise = noise;
    with_device(settings, |device, start| {
        let (mut positions, mut velocities, mut replies) = (Vec::new(), Vec::new(), Vec::new());
        for step in 0..reads {
            let t = start + step * 5 * MS;
            device.receive(&state_read(), t).unwrap();
            device.poll(t + 4 * MS).unwrap();
            let plant = device.servos().plant();
            let (angles, rates) = expected_angles_and_rates(plant.q(), plant.qd());
            for (servo, reply) in last_read(device).into_iter().enumerate() {
                positions.push(f64::from(reply.state.position) - angles[servo] / POSITION_UNIT_DEG);
                velocities.push(f64::from(reply.state.velocity) - rates[servo] / VELOCITY_UNIT_RPM);
                replies.push(reply);
            }
        }
        (positions, velocities, replies)
    })
}

fn mean_and_deviation(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let variance = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, variance.sqrt())
}

#[test]
fn noise_has_its_deviation_and_follows_its_seed() {
    let noise = SensorNoise {
        position: 2.0,
        velocity: 3.0,
        seed: 7,
    };
    let (positions, velocities, replies) = deviations(noise, 200);
    // Gaussian noise of σ, then rounding (uniform within ±½ unit, variance 1/12): 1200
    // samples put the sample deviation within a few percent of √(σ² + 1/12).
    for (what, x, sigma) in [
        ("position", &positions, 2.0),
        ("velocity", &velocities, 3.0),
    ] {
        let (mean, deviation) = mean_and_deviation(x);
        let expected = (sigma * sigma + 1.0 / 12.0f64).sqrt();
        assert!(mean.abs() < 0.3, "{what}: mean {mean}");
        assert!(
            (deviation / expected - 1.0).abs() < 0.15,
            "{what}: deviation {deviation}, expected {expected}"
        );
    }
    // The same seed draws the same readings; another seed others.
    assert_eq!(deviations(noise, 20).2, replies[..120].to_vec());
    let other = SensorNoise { seed: 8, ..noise };
    assert_ne!(deviations(other, 20).2, replies[..120].to_vec());
    // Without noise every reading is within half a unit.
    let (positions, velocities, _) = deviations(SensorNoise::NONE, 20);
    assert!(
        positions
            .iter()
            .chain(&velocities)
            .all(|d| d.abs() <= 0.5 + 1e-6)
    );
}

// ---------------------------------------------------------------------------------------
// The plant's robot file

#[test]
fn the_plant_file_moves_the_servos_and_the_robot_file_maps_them() {
    // At rest with slack cables, module 1's spring carries both plates and module 2's its
    // own: δL₁ = −(m₁ + m₂) g / κL, δL₂ = −m₂ g / κL.
    let sag = |settings: EmulatorSettings| {
        with_device(settings, |device, _| {
            let q = device.servos().plant().q();
            (q[2], q[5])
        })
    };
    let g = 9.81;
    let nominal = sag(EmulatorSettings::new(BAUD));
    let mut settings = EmulatorSettings::new(BAUD);
    settings.plant = Some(robot("hardware-example-true.toml"));
    let true_robot = sag(settings.clone());
    for ((got, expected), what) in [
        (nominal.0, -(0.35 + 0.1) * g / 300.0),
        (nominal.1, -0.1 * g / 300.0),
        (true_robot.0, -(0.385 + 0.11) * g / 270.0),
        (true_robot.1, -0.11 * g / 270.0),
    ]
    .into_iter()
    .zip(["nominal δL₁", "nominal δL₂", "true δL₁", "true δL₂"])
    {
        assert!(
            (got / expected - 1.0).abs() < 1e-3,
            "{what}: {got} m, expected {expected} m"
        );
    }
    // The servos are the robot file's: IDs 1–6, and they read the true robot's sag.
    with_device(settings, |device, start| {
        assert_eq!(device.servos().ids(), &IDS);
        device.receive(&state_read(), start).unwrap();
        device.poll(start + 5 * MS).unwrap();
        let plant = device.servos().plant();
        let (angles, _) = expected_angles_and_rates(plant.q(), plant.qd());
        for (servo, reply) in last_read(device).iter().enumerate() {
            let exact = angles[servo] / POSITION_UNIT_DEG;
            assert!((f64::from(reply.state.position) - exact).abs() <= 0.5 + 1e-6);
        }
    });
}

#[test]
fn a_plant_of_another_structure_is_refused_naming_its_file() {
    let servos = robot("hardware-example.toml");
    for (file, difference) in [
        (
            "three-square.toml",
            "modules: 3 where the servos' robot has 2",
        ),
        // Limits are numbers (every module has them), obstacles are structure.
        ("paper-sim-obstacle.toml", "obstacles:"),
    ] {
        let mut settings = EmulatorSettings::new(BAUD);
        settings.plant = Some(robot(file));
        let error = match emulator::physics(&servos, &settings) {
            Err(e @ EmulatorError::PlantStructure { .. }) => e.to_string(),
            Err(other) => panic!("{file}: {other}"),
            Ok(_) => panic!("{file}: accepted"),
        };
        assert!(error.contains(file), "{error}");
        assert!(error.contains("hardware-example.toml"), "{error}");
        assert!(error.contains(difference), "{error}");
    }
}

// ---------------------------------------------------------------------------------------
// Presets and options

#[derive(Parser)]
struct Command {
    #[command(flatten)]
    emulate: EmulateArgs,
}

fn settings_of(options: &[&str]) -> Result<EmulatorSettings, String> {
    let path = robot_path("hardware-example.toml");
    let mut args = vec!["emulate", "--robot", path.to_str().unwrap()];
    args.extend_from_slice(options);
    let args = Command::try_parse_from(args)
        .map_err(|e| e.to_string())?
        .emulate;
    let robot = robot("hardware-example.toml");
    let hardware = description::load(&robot).unwrap().unwrap();
    let mut settings = emulator_settings(&args, &hardware)?;
    settings.plant = plant_robot(&args, &robot)?;
    Ok(settings)
}

#[test]
fn the_factory_preset_is_an_ftdi_adapter_and_x_series_servos_as_shipped() {
    let ideal = settings_of(&[]).unwrap();
    assert_eq!(ideal, EmulatorSettings::new(BAUD), "ideal is the default");
    assert_eq!(settings_of(&["--preset", "ideal"]).unwrap(), ideal);

    let factory = settings_of(&["--preset", "factory"]).unwrap();
    assert_eq!(factory.latency_timer, 16 * MS);
    assert_eq!(factory.return_delay, 500 * US);
    assert_eq!((factory.noise.position, factory.noise.velocity), (1.0, 1.0));
    assert_eq!(settings_of(&["--preset", "realistic"]).unwrap(), factory);

    // An option given wins over the preset; the others keep the preset's values.
    let tuned = settings_of(&["--preset", "factory", "--latency-timer-ms", "1"]).unwrap();
    assert_eq!(tuned.latency_timer, MS);
    assert_eq!(tuned.return_delay, 500 * US);
    let quiet = settings_of(&[
        "--preset",
        "factory",
        "--noise-position",
        "0",
        "--return-delay-us",
        "0",
        "--seed",
        "9",
    ])
    .unwrap();
    assert_eq!(quiet.noise.position, 0.0);
    assert_eq!(quiet.noise.velocity, 1.0);
    assert_eq!(quiet.noise.seed, 9);
    assert_eq!(quiet.return_delay, Duration::ZERO);
    assert_eq!(quiet.latency_timer, 16 * MS);

    let plant = settings_of(&[
        "--plant",
        robot_path("hardware-example-true.toml").to_str().unwrap(),
    ])
    .unwrap();
    assert_eq!(plant.plant.unwrap().name, "hardware-example-true");
}

#[test]
fn realism_options_out_of_range_are_refused_by_name() {
    for (options, expected) in [
        (
            &["--latency-timer-ms", "256"][..],
            "--latency-timer-ms: must be an integer in 0..=255",
        ),
        (
            &["--latency-timer-ms", "-1"],
            "--latency-timer-ms: must be an integer in 0..=255",
        ),
        (
            &["--noise-position", "-0.5"],
            "--noise-position: must be ≥ 0 and ≤ 1000",
        ),
        (
            &["--noise-velocity", "1e9"],
            "--noise-velocity: must be ≥ 0 and ≤ 1000",
        ),
        (&["--noise-velocity", "NaN"], "--noise-velocity: must be"),
        (
            &["--return-delay-us", "509"],
            "--return-delay-us: must be ≥ 0 and ≤ 508",
        ),
        (&["--preset", "perfect"], "`perfect` is not a preset"),
    ] {
        let error = settings_of(options).unwrap_err();
        assert!(error.contains(expected), "{options:?}: {error}");
    }
    let missing = robot_path("no-such-robot.toml");
    let error = settings_of(&["--plant", missing.to_str().unwrap()]).unwrap_err();
    assert!(
        error.starts_with("--plant: ") && error.contains("no-such-robot.toml"),
        "{error}"
    );
    // The library refuses what the command line cannot give either.
    let refusal = |settings: &EmulatorSettings| {
        emulator::physics(&robot("hardware-example.toml"), settings)
            .and_then(|(map, model)| {
                let plant = Plant::new(&model, Tolerances::default())?;
                Device::new(map, plant, settings, Instant::now()).map(|_| ())
            })
            .unwrap_err()
            .to_string()
    };
    let mut settings = EmulatorSettings::new(BAUD);
    settings.latency_timer = 300 * MS;
    let error = refusal(&settings);
    assert!(error.contains("latency timer 300 ms"), "{error}");
    settings.latency_timer = Duration::ZERO;
    settings.noise.position = f64::NAN;
    let error = refusal(&settings);
    assert!(error.contains("position noise"), "{error}");
}
