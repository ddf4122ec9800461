//! Rows of a record whose state lies outside the model's domain
//! (`softcbf_description::domain`: a backbone of no length, a bend past 1.5π, an
//! elongation past ten rest lengths, a speed past 100 m/s). The barrier values and shapes
//! computed there mean nothing, so the figures say so instead of drawing them as if they
//! did (a run whose state left the domain once showed a corner "+855 mm, clear"). A row
//! with values that are not finite is not one of them: nothing is drawn from it (a
//! hardware log's tick without a reading has NaN there).

use softcbf_description::domain::{self, StateProblem};
use softcbf_description::robot::Robot;

use crate::record::Record;

/// Why the finite state `(q, q̇)` of one row lies outside `robot`'s model's domain, in a
/// few words; `None` if it lies inside, if a value is not finite (nothing is drawn from
/// it), or without a robot to tell.
pub fn state_problem(robot: Option<&Robot>, q: &[f64], qd: &[f64]) -> Option<String> {
    let robot = robot?;
    let finite = q.iter().chain(qd).all(|v| v.is_finite());
    if !finite || q.len() != 3 * robot.modules.len() || qd.len() != q.len() {
        return None;
    }
    domain::state_problem(robot, q, qd).map(|problem| short(&problem))
}

/// A state problem in a few words, for a figure (`module 2: δL = 1.004 m > 1.000 m`).
fn short(problem: &StateProblem) -> String {
    match *problem {
        StateProblem::Length { got, expected } => format!("{got} values, not {expected}"),
        StateProblem::NonFinite { index, .. } => format!("entry {index} is not finite"),
        StateProblem::Bend { module, theta, .. } => {
            format!("module {module}: bend {theta:.2} rad > 1.5π")
        }
        StateProblem::NonPositiveLength { module, value, .. } => {
            format!("module {module}: no length left (δL = {value:.3} m)")
        }
        StateProblem::Elongation { module, value, max } => {
            format!("module {module}: δL = {value:.3} m > {max:.3} m")
        }
        StateProblem::Speed { index, value } => {
            format!("velocity {index}: {value:.0} m/s > 100 m/s")
        }
    }
}

/// The rows of one record with an invalid state.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InvalidRows {
    /// How many rows.
    pub count: usize,
    /// Of how many rows in all.
    pub rows: usize,
    /// Time \[s\] and problem of the first.
    pub first: Option<(f64, String)>,
    /// The time spans `[first, last]` \[s\] of consecutive invalid rows, in order.
    pub spans: Vec<(f64, f64)>,
}

impl InvalidRows {
    /// The rows of `record` with an invalid state ([`state_problem`]).
    pub fn of(record: &Record, robot: Option<&Robot>) -> InvalidRows {
        let mut found = InvalidRows {
            rows: record.len(),
            ..InvalidRows::default()
        };
        let mut open: Option<(f64, f64)> = None;
        for row in record.rows() {
            match state_problem(robot, row.q, row.qd) {
                Some(problem) => {
                    found.count += 1;
                    if found.first.is_none() {
                        found.first = Some((row.t, problem));
                    }
                    if row.t.is_finite() {
                        open = Some(open.map_or((row.t, row.t), |(start, _)| (start, row.t)));
                    }
                }
                None => found.spans.extend(open.take()),
            }
        }
        found.spans.extend(open);
        found
    }

    /// What a figure says of them, in two lines: `invalid state from t = 0.523 s, in 2342
    /// of 10001 rows (shaded): values there mean nothing` and the first problem; `None`
    /// when there are none.
    pub fn note(&self) -> Option<[String; 2]> {
        let (t, problem) = self.first.as_ref()?;
        Some([
            format!(
                "invalid state from t = {t:.3} s, in {} of {} rows (shaded): values there \
                 mean nothing",
                self.count, self.rows
            ),
            format!("first: {problem}"),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Columns;

    #[test]
    fn rows_outside_the_domain_are_counted_and_named() {
        let robot = Robot::paper_sim();
        let columns = Columns::new(6, 12, &[]).unwrap();
        let mut record = Record::for_columns(columns, 5);
        let zero = [0.0; 6];
        let b = [0.1; 12];
        let mut push = |t: f64, q: &[f64; 6], qd: &[f64; 6]| {
            record
                .push_row(&crate::record::Row {
                    t,
                    q,
                    qd,
                    tau: &zero,
                    tau_nom: &zero,
                    b: &b,
                    extra: &[],
                })
                .unwrap();
        };
        push(0.0, &zero, &zero);
        // δL₂ = −0.15 m: module 2's backbone would have no length (L0 = 0.1 m).
        push(0.5, &[0.0, 0.0, 0.0, 0.0, 0.0, -0.15], &zero);
        push(1.0, &zero, &[0.0, 0.0, 0.0, 0.0, 0.0, 120.0]);
        // No reading (a hardware log's NaN): nothing drawn, nothing to say.
        push(1.5, &[f64::NAN; 6], &[f64::NAN; 6]);
        push(2.0, &zero, &zero);
        let found = InvalidRows::of(&record, Some(&robot));
        assert_eq!((found.count, found.rows), (2, 5));
        let (t, problem) = found.first.clone().unwrap();
        assert_eq!(t, 0.5);
        assert_eq!(problem, "module 2: no length left (δL = -0.150 m)");
        assert_eq!(found.spans, [(0.5, 1.0)]);
        let [first, second] = found.note().unwrap();
        assert_eq!(
            first,
            "invalid state from t = 0.500 s, in 2 of 5 rows (shaded): values there mean nothing"
        );
        assert_eq!(second, "first: module 2: no length left (δL = -0.150 m)");
        // Without the robot there is no domain to tell.
        assert_eq!(InvalidRows::of(&record, None).count, 0);
        assert_eq!(InvalidRows::of(&record, None).note(), None);
    }
}
