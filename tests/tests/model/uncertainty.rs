//! Plant robots drawn inside a robot's declared uncertainty (`softcbf_tests::robots::
//! draw_within`): inside the box, spread over it, reproducible, and a model of their own.

use softcbf::model::Model;
use softcbf_description::Robot;
use softcbf_description::uncertainty::{self, Uncertainty};
use softcbf_tests::robots::{draw_factors, draw_within, paper_sim_uncertain};

/// Every drawn plant lies inside the declared box, and its factors reach towards each edge.
#[test]
fn drawn_plants_stay_inside_the_declared_box() {
    let nominal = paper_sim_uncertain();
    assert_eq!(nominal.uncertainty.stiffness, 0.2);
    let (mut lowest, mut highest) = (f64::INFINITY, f64::NEG_INFINITY);
    for seed in 0..200 {
        let plant = draw_within(&nominal, seed);
        assert!(
            uncertainty::contains(&nominal, &plant),
            "seed {seed}: {:?}",
            uncertainty::outside(&nominal, &plant)
        );
        assert_eq!(plant.structure().key(), nominal.structure().key());
        for (p, n) in plant.modules.iter().zip(&nominal.modules) {
            // Independent of the crate's test: each ratio by hand, within [0.8, 1.2].
            let ratios = [
                p.bending_stiffness / n.bending_stiffness,
                p.axial_stiffness / n.axial_stiffness,
                p.bending_damping / n.bending_damping,
                p.axial_damping / n.axial_damping,
                p.mass / n.mass,
            ];
            for r in ratios {
                assert!((0.8 - 1e-12..=1.2 + 1e-12).contains(&r), "seed {seed}: {r}");
                lowest = lowest.min(r);
                highest = highest.max(r);
            }
            // The inertia follows the mass.
            for (i, i0) in p.inertia.iter().zip(n.inertia) {
                assert!((i / i0 - p.mass / n.mass).abs() < 1e-12);
            }
        }
    }
    // 2000 uniform draws: both ends of the box are approached within 1 %.
    assert!(lowest < 0.81 && highest > 1.19, "{lowest} .. {highest}");
}

#[test]
fn draws_are_reproducible_and_differ_between_seeds() {
    let nominal = paper_sim_uncertain();
    assert_eq!(draw_within(&nominal, 7), draw_within(&nominal, 7));
    assert_ne!(draw_within(&nominal, 7), draw_within(&nominal, 8));
    // Each module and each number gets its own factor.
    let factors = draw_factors(&nominal, &mut softcbf_tests::rng(3));
    assert_eq!(factors.len(), 2);
    assert_ne!(factors[0], factors[1]);
    assert_ne!(factors[0].stiffness[0], factors[0].stiffness[1]);
    assert!(factors.iter().all(|f| nominal.uncertainty.admits(f)));
}

/// Without a declaration the only plant inside the box is the robot itself.
#[test]
fn nothing_declared_draws_the_nominal_robot() {
    let exact = Robot::paper_sim();
    assert_eq!(exact.uncertainty, Uncertainty::default());
    assert_eq!(draw_within(&exact, 11), exact);
}

/// A drawn plant is a robot the runtime builds a model of, with the nominal generated model
/// and geometry, and its own stiffness and damping.
#[test]
fn a_drawn_plant_has_a_model() {
    let nominal = paper_sim_uncertain();
    let plant = draw_within(&nominal, 5);
    let (a, b) = (
        Model::new(nominal).expect("nominal model"),
        Model::new(plant).expect("plant model"),
    );
    assert_eq!(a.generated.name(), b.generated.name());
    assert_eq!(a.params, b.params);
    for (k, k0) in b.stiffness.iter().zip(&a.stiffness) {
        assert!(
            k != k0 && (k / k0 - 1.0).abs() <= 0.2 + 1e-12,
            "{k} against {k0}"
        );
    }
    for (d, d0) in b.damping.iter().zip(&a.damping) {
        assert!(
            d != d0 && (d / d0 - 1.0).abs() <= 0.2 + 1e-12,
            "{d} against {d0}"
        );
    }
}

/// `softcbf model` reports the declared uncertainty (zeros when none is declared).
#[test]
fn the_model_report_names_the_declared_uncertainty() {
    let report = |robot: Robot| {
        let model = Model::new(robot).expect("model");
        softcbf::inspect::model_report(&model, &[0.0; 6], &[0.0; 6]).expect("state of size 6")
    };
    let declared = report(paper_sim_uncertain());
    let u = &declared["uncertainty"];
    assert_eq!(
        [&u["stiffness"], &u["damping"], &u["mass"], &u["force"]].map(|v| v.as_f64()),
        [Some(0.2), Some(0.2), Some(0.2), Some(0.05)]
    );
    let none = report(Robot::paper_sim());
    assert_eq!(none["uncertainty"]["stiffness"].as_f64(), Some(0.0));
    assert_eq!(none["uncertainty"]["force"].as_f64(), Some(0.0));
}
