//! Criterion benchmarks of the safe controller and the simulator (issue 4): one control
//! tick of the paper robot (model, HOCBF rows, QP), one tick of each safety mode at 33 Hz
//! (issue 13), and the paper's whole 10 s scenario.
//!
//! The ticks are taken at the states of the paper scenario's filtered run (every 10th
//! tick of 10 s), cycled, so the QP sees its real mix of active sets. Run with
//! `cargo bench -p softcbf --bench control`; the simulator bench also prints the split
//! between control ticks and integration of one run, and the certified ticks the split
//! between prediction, bound, QP and the fallback of unproven ticks.

use std::hint::black_box;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, criterion_group, criterion_main};
use softcbf::control::{Controller, Reference, SafetyMode, tick};
use softcbf::model::Model;
use softcbf::robot_file::load_robot;
use softcbf::scenario::{Scenario, ScenarioFile};
use softcbf::sim::simulate;

fn paper() -> (Model, Scenario) {
    let model = Model::new(load_robot(None).expect("embedded robot")).expect("paper model");
    let scenario = ScenarioFile::paper_sim()
        .resolve(&model)
        .expect("paper scenario");
    (model, scenario)
}

fn bench_tick(c: &mut Criterion) {
    let (model, scenario) = paper();
    let run = simulate(&model, &scenario, true, &mut |_| {}).expect("simulation");
    let states: Vec<(Vec<f64>, Vec<f64>)> = (0..run.record.len())
        .step_by(10)
        .filter_map(|k| run.record.row(k))
        .map(|row| (row.q.to_vec(), row.qd.to_vec()))
        .collect();
    let set_point = scenario.reference.final_target().to_vec();
    let mut group = c.benchmark_group("control_tick");
    for (name, filter) in [("filter", true), ("pd_only", false)] {
        let mut settings = scenario.controller.clone();
        settings.filter = filter;
        let controller = Controller::new(&model, settings).expect("controller");
        bench_cycle(&mut group, name, &model, controller, &states, &set_point);
    }
    group.finish();
}

/// Benchmarks `name`: one tick of `controller` per iteration, cycling through `states`
/// toward the set point `set_point`.
fn bench_cycle(
    group: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    model: &Model,
    mut controller: Controller,
    states: &[(Vec<f64>, Vec<f64>)],
    set_point: &[f64],
) {
    let zero = vec![0.0; model.nq()];
    let mut k = 0;
    group.bench_function(name, |bench| {
        bench.iter(|| {
            let (q, qd) = &states[k % states.len()];
            k += 1;
            let reference = Reference {
                q: set_point,
                qd: &zero,
                qdd: &zero,
            };
            black_box(tick(
                model,
                &mut controller,
                black_box(q),
                black_box(qd),
                reference,
            ))
        })
    });
    if let Some(split) = controller.certified_split().filter(|split| split.ticks > 0) {
        let per_tick = |seconds: f64| seconds / split.ticks as f64 * 1e6;
        let total = split.prediction + split.bound + split.qp + split.fallback;
        eprintln!(
            "{name}: mean over {} ticks {:.0} µs: prediction {:.0} µs, bound {:.0} µs, QP {:.0} µs, \
             fallback of unproven ticks {:.0} µs",
            split.ticks,
            per_tick(total),
            per_tick(split.prediction),
            per_tick(split.bound),
            per_tick(split.qp),
            per_tick(split.fallback),
        );
    }
}

fn bench_scenario(c: &mut Criterion) {
    let (model, scenario) = paper();
    let run = simulate(&model, &scenario, true, &mut |_| {}).expect("simulation");
    let s = &run.summary;
    eprintln!(
        "paper scenario, one run: {:.3} s wall ({:.0}× real time); control ticks {:.3} s \
         ({:.2} µs/tick), integration {:.3} s ({:.2} µs/tick, {:.1} right-hand sides/tick)",
        s.wall_time,
        s.real_time_factor,
        s.control_time,
        s.control_time / s.counts.ticks as f64 * 1e6,
        s.integration_time,
        s.integration_time / s.counts.ticks as f64 * 1e6,
        s.integrator_rhs_evals as f64 / s.counts.ticks as f64,
    );
    let mut group = c.benchmark_group("paper_scenario_10s");
    group.sample_size(10);
    for (name, filter) in [("filter", true), ("pd_only", false)] {
        group.bench_function(name, |bench| {
            bench.iter(|| simulate(&model, &scenario, filter, &mut |_| {}).expect("simulation"))
        });
    }
    group.finish();
}

/// One tick at 33 Hz in each safety mode, at the states of a certified run toward the paper's
/// set point; `*_uncertain` on the paper robot declaring ±20 %.
fn bench_safety_modes(c: &mut Criterion) {
    let (model, mut scenario) = paper();
    let period = 1.0 / 33.0;
    scenario.control_period = period;
    scenario.tolerances.h_max = period;
    scenario.controller.safety = SafetyMode::Certified;
    scenario.controller.hold = period;
    let run = simulate(&model, &scenario, true, &mut |_| {}).expect("simulation");
    let states: Vec<(Vec<f64>, Vec<f64>)> = (0..run.record.len())
        .filter_map(|k| run.record.row(k))
        .map(|row| (row.q.to_vec(), row.qd.to_vec()))
        .collect();
    let set_point = scenario.reference.final_target().to_vec();
    let mut uncertain = model.robot.clone();
    uncertain.uncertainty = softcbf_description::uncertainty::Uncertainty {
        stiffness: 0.2,
        damping: 0.2,
        mass: 0.2,
        force: 0.0,
    };
    let uncertain = Model::new(uncertain).expect("paper model");
    let mut group = c.benchmark_group("tick_33hz");
    for (name, safety, model) in [
        ("paper", SafetyMode::Paper, &model),
        ("hold_correction", SafetyMode::HoldCorrection, &model),
        ("predicted", SafetyMode::Predicted, &model),
        ("predicted_uncertain", SafetyMode::Predicted, &uncertain),
        ("certified", SafetyMode::Certified, &model),
        ("certified_uncertain", SafetyMode::Certified, &uncertain),
    ] {
        let mut settings = scenario.controller.clone();
        settings.safety = safety;
        let controller = Controller::new(model, settings).expect("controller");
        bench_cycle(&mut group, name, model, controller, &states, &set_point);
    }
    group.finish();
}

criterion_group!(benches, bench_tick, bench_safety_modes, bench_scenario);
criterion_main!(benches);
