//! The state domain of a model: the coordinates and velocities it describes (a bend of at
//! most three quarters of a turn, a positive backbone length `L0 + δL` up to eleven rest
//! lengths, speeds within 100 m/s), and the problem of a state outside it, located in a
//! file when one gave it.
//!
//! The domain is also a constraint of the controller: every module always has its three
//! limit barriers (docs/model.md §3), and where its robot file writes no limit, the
//! domain's defaults (`crate::limits::DEFAULT_MIN_LENGTH_FRACTION` and its neighbours,
//! [`crate::barriers::Limits::domain`]) keep the state well inside the domain, so that the
//! safety filter cannot keep one barrier by driving another coordinate out of the model.

use crate::robot::Robot;

pub use crate::module_domain::{
    MAX_BEND_RAD, MAX_ELONGATION_RATIO, MAX_SPEED, StateProblem, modules_coordinates_problem,
};

/// The first problem of coordinates `q` of `robot` (length, finiteness, bend, elongation),
/// or `None` when `q` lies in the model's domain. Allocates nothing.
pub fn coordinates_problem(robot: &Robot, q: &[f64]) -> Option<StateProblem> {
    modules_coordinates_problem(&robot.modules, q)
}

/// The first problem of velocities `qd` of `robot` (length, finiteness, speed), or `None`.
/// Allocates nothing.
pub fn velocities_problem(robot: &Robot, qd: &[f64]) -> Option<StateProblem> {
    let expected = 3 * robot.modules.len();
    if qd.len() != expected {
        return Some(StateProblem::Length {
            got: qd.len(),
            expected,
        });
    }
    qd.iter().enumerate().find_map(|(k, &value)| {
        if !value.is_finite() {
            Some(StateProblem::NonFinite {
                index: k + 1,
                value,
            })
        } else if value.abs() > MAX_SPEED {
            Some(StateProblem::Speed {
                index: k + 1,
                value,
            })
        } else {
            None
        }
    })
}

/// The first problem of the state `(q, q̇)`, or `None` when it lies in the model's domain.
pub fn state_problem(robot: &Robot, q: &[f64], qd: &[f64]) -> Option<StateProblem> {
    coordinates_problem(robot, q).or_else(|| velocities_problem(robot, qd))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn state_problems_point_at_their_entry() {
        let robot = Robot::paper_sim();
        let bend = MAX_BEND_RAD * 0.04;
        let q = [0.0, 0.0, 0.0, 0.0, 1.01 * bend, 0.0];
        let problem = coordinates_problem(&robot, &q).unwrap();
        // The bend of module 2 is reported at its Δx, entry 4.
        assert_eq!(problem.entry(), Some(4));
        assert_eq!(
            modules_coordinates_problem(&robot.modules, &q),
            Some(problem)
        );
        let q = [0.0, 0.0, 1.5, 0.0, 0.0, 0.0];
        assert_eq!(coordinates_problem(&robot, &q).unwrap().entry(), Some(3));
        let qd = [0.0, 0.0, 0.0, 0.0, f64::NAN, 0.0];
        assert_eq!(velocities_problem(&robot, &qd).unwrap().entry(), Some(5));
        assert_eq!(coordinates_problem(&robot, &[0.0]).unwrap().entry(), None);
    }

    #[test]
    fn the_state_domain_bounds_bend_elongation_and_speed() {
        let robot = Robot::paper_sim();
        let d = robot.modules[0].tendon_radius;
        let mut q = vec![0.0; 6];
        assert_eq!(coordinates_problem(&robot, &q), None);
        q[3] = 0.999 * MAX_BEND_RAD * d;
        assert_eq!(coordinates_problem(&robot, &q), None);
        q[3] = 1.001 * MAX_BEND_RAD * d;
        assert!(matches!(
            coordinates_problem(&robot, &q),
            Some(StateProblem::Bend { module: 2, .. })
        ));
        q[3] = 0.0;
        q[2] = 1.01;
        let problem = coordinates_problem(&robot, &q).unwrap();
        assert!(matches!(
            problem,
            StateProblem::Elongation { module: 1, .. }
        ));
        assert!(problem.to_string().contains("entry 3"), "{problem}");
        // A backbone of zero or negative length: L0 = 0.1 m.
        q[2] = -0.0999;
        assert_eq!(coordinates_problem(&robot, &q), None);
        for dl in [-0.1, -0.2, -1.01] {
            q[2] = dl;
            let problem = coordinates_problem(&robot, &q).unwrap();
            assert!(
                matches!(problem, StateProblem::NonPositiveLength { module: 1, .. }),
                "{problem:?}"
            );
            assert!(problem.to_string().contains("not positive"), "{problem}");
        }
        q[2] = 1e308;
        assert!(coordinates_problem(&robot, &q).is_some());
        q[2] = f64::NAN;
        assert!(matches!(
            coordinates_problem(&robot, &q),
            Some(StateProblem::NonFinite { index: 3, .. })
        ));
        let mut qd = vec![0.0; 6];
        qd[5] = -100.0;
        assert_eq!(velocities_problem(&robot, &qd), None);
        qd[5] = -100.5;
        assert!(matches!(
            velocities_problem(&robot, &qd),
            Some(StateProblem::Speed { index: 6, .. })
        ));
        assert!(matches!(
            state_problem(&robot, &[0.0; 3], &qd),
            Some(StateProblem::Length {
                got: 3,
                expected: 6
            })
        ));
    }
}
