//! Criterion benchmark of one control-loop iteration's software, the bus wait excluded:
//! decoding the sync-read replies' bytes, mapping to `q`/`q̇`, the controller tick, the
//! tensions and currents, and encoding the sync-write packet (as `softcbf run` does).

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use softcbf::control::{self, Controller, ControllerSettings, Reference};
use softcbf::hardware::control_table::{self as table, ServoState};
use softcbf::hardware::mapping::TendonMap;
use softcbf::model::Model;
use softcbf::protocol::encode_sync_write;
use softcbf_description::robot::Robot;

/// `robots/hardware-example.toml`: six servos, IDs 1–6.
fn example() -> Robot {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robots/hardware-example.toml"
    ));
    Robot::load(path).unwrap()
}

fn iteration(c: &mut Criterion) {
    let robot = example();
    let map = TendonMap::new(&robot).unwrap();
    let set_point = map.hardware().set_point.clone();
    let model = Model::new(robot).unwrap();
    let mut controller = Controller::new(&model, ControllerSettings::paper(&model)).unwrap();
    let n = map.n_servos();
    // Two states the loop meets: at rest (no barrier active) and held at the barriers.
    for (name, q) in [
        ("rest", [0.0, 0.0, -0.0147, 0.0, 0.0, -0.0032]),
        ("at_barriers", [0.0, 0.0, -0.0556, 0.0, -0.0014, -0.0535]),
    ] {
        let qd_true = [0.01, -0.02, -0.05, 0.0, 0.03, -0.01];
        let (mut angles, mut rates) = (vec![0.0; n], vec![0.0; n]);
        map.angles_from_q(&q, &mut angles);
        map.rates_from_qd(&qd_true, &mut rates);
        let len = usize::from(table::STATE_LENGTH);
        let mut raw = vec![0u8; n * len];
        for k in 0..n {
            let state = ServoState {
                current: 0,
                velocity: map.velocity_from_rate(rates[k]),
                position: map.position_from_angle(angles[k]),
            };
            state.to_bytes(&mut raw[k * len..(k + 1) * len]);
        }
        let ids = map.hardware().servo_ids();
        let zeros = vec![0.0; 6];
        let (mut q_m, mut qd_m) = (vec![0.0; 6], vec![0.0; 6]);
        let (mut tensions, mut goal) = (vec![0.0; n], vec![[0u8; 2]; n]);
        let mut packet = Vec::with_capacity(64);
        c.bench_function(&format!("loop_software_{name}"), |b| {
            b.iter(|| {
                for k in 0..n {
                    let s = ServoState::from_bytes(&black_box(&raw)[k * len..(k + 1) * len]);
                    angles[k] = map.angle_from_position(s.position);
                    rates[k] = map.rate_from_velocity(s.velocity);
                }
                map.q_from_angles(&angles, &mut q_m);
                map.qd_from_rates(&rates, &mut qd_m);
                let status = control::tick(
                    &model,
                    &mut controller,
                    &q_m,
                    &qd_m,
                    Reference {
                        q: &set_point,
                        qd: &zeros,
                        qdd: &zeros,
                    },
                );
                map.tensions_from_tau(controller.tau(), &mut tensions);
                for k in 0..n {
                    goal[k] = map.current_from_tension(k, tensions[k]).to_le_bytes();
                }
                packet.clear();
                encode_sync_write(
                    table::GOAL_CURRENT,
                    2,
                    ids.iter().zip(&goal).map(|(&id, d)| (id, &d[..])),
                    &mut packet,
                )
                .unwrap();
                black_box((status, &packet));
            })
        });
    }
}

/// The state prediction `softcbf run` adds before the tick: the plant advanced by the age
/// of a reading under the command in force, from a state held at the barriers. A reading
/// is about 2 ms old on a healthy 1 Mbit/s bus; 33 ms when replies come 5 ms late.
fn prediction(c: &mut Criterion) {
    use softcbf::hardware::run_loop::prediction_tolerances;
    use softcbf::plant::Plant;
    let robot = example();
    let model = Model::new(robot).unwrap();
    let mut plant = Plant::new(&model, prediction_tolerances()).unwrap();
    let q = [0.0, 0.0, -0.0556, 0.0, -0.0014, -0.0535];
    let qd = [0.01, -0.02, -0.05, 0.0, 0.03, -0.01];
    let tau = [0.0, 0.0, -12.0, 0.0, -0.5, -5.0];
    for (name, age) in [("2ms", 0.002), ("33ms", 0.033)] {
        c.bench_function(&format!("state_prediction_{name}"), |b| {
            b.iter(|| {
                plant.reset(black_box(&q), black_box(&qd), 0.0);
                plant.tau_mut().copy_from_slice(&tau);
                plant.advance(black_box(age)).unwrap();
                black_box(plant.q()[0])
            })
        });
    }
}

criterion_group!(benches, iteration, prediction);
criterion_main!(benches);
