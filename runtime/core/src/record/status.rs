//! The controller's outcome of a tick ([`TickStatus`]) as two numeric log columns, the
//! one table behind the `status` and `reason` columns of `softcbf simulate`'s
//! `trajectory.csv` and `softcbf run`'s log, and the names an MCAP log gives them.
//!
//! | `status` | name | `reason` (0: none) |
//! |---|---|---|
//! | −1 | `no-reading` | (a tick of `softcbf run` without a fresh reading: the command held) |
//! | 0 | `unfiltered` | |
//! | 1 | `filtered` | |
//! | 2 | `relaxed` | |
//! | 3 | `qp-failed` | |
//! | 4 | `invalid` | 6 `non-finite`, 7 `size`, 8 `mass-matrix`, 9 `non-finite-model`, 10 `out-of-domain` |
//! | 5 | `uncertified` | 1 `tube`, 2 `domain`, 3 `start`, 4 `bound`, 5 `budget` |
//!
//! A row between two ticks of a dense simulation carries the status of the tick before
//! it, whose command it holds.
//!
//! ```
//! use softcbf_core::control::{TickStatus, Uncertified};
//! use softcbf_core::record::status::{codes, reason_name, status_name};
//! let (status, reason) = codes(TickStatus::Uncertified(Uncertified::Budget));
//! assert_eq!((status_name(status), reason_name(reason)), (Some("uncertified"), Some("budget")));
//! assert_eq!(codes(TickStatus::Filtered), (1.0, 0.0));
//! assert_eq!(reason_name(0.0), None);
//! ```

use crate::control::{InvalidState, TickStatus, Uncertified};

/// The name of the status column.
pub const STATUS: &str = "status";
/// The name of the reason column.
pub const REASON: &str = "reason";
/// The status of a tick of `softcbf run` without a fresh reading (nothing computed).
pub const NO_READING: f64 = -1.0;
/// The reason of a status that has none.
pub const NO_REASON: f64 = 0.0;

/// The status names, from code −1 on.
const STATUS_NAMES: [&str; 7] = [
    "no-reading",
    "unfiltered",
    "filtered",
    "relaxed",
    "qp-failed",
    "invalid",
    "uncertified",
];

/// The reason names, from code 1 on.
const REASON_NAMES: [&str; 10] = [
    "tube",
    "domain",
    "start",
    "bound",
    "budget",
    "non-finite",
    "size",
    "mass-matrix",
    "non-finite-model",
    "out-of-domain",
];

/// The `status` and `reason` codes of `status`.
pub fn codes(status: TickStatus) -> (f64, f64) {
    match status {
        TickStatus::Unfiltered => (0.0, NO_REASON),
        TickStatus::Filtered => (1.0, NO_REASON),
        TickStatus::Relaxed => (2.0, NO_REASON),
        TickStatus::QpFailed => (3.0, NO_REASON),
        TickStatus::InvalidState(why) => (4.0, invalid_code(why)),
        TickStatus::Uncertified(why) => (5.0, uncertified_code(why)),
    }
}

fn uncertified_code(why: Uncertified) -> f64 {
    match why {
        Uncertified::Tube => 1.0,
        Uncertified::Domain => 2.0,
        Uncertified::Start => 3.0,
        Uncertified::Bound => 4.0,
        Uncertified::Budget => 5.0,
    }
}

fn invalid_code(why: InvalidState) -> f64 {
    match why {
        InvalidState::NonFinite => 6.0,
        InvalidState::Size { .. } => 7.0,
        InvalidState::MassMatrix => 8.0,
        InvalidState::NonFiniteModel => 9.0,
        InvalidState::OutOfDomain => 10.0,
    }
}

/// The position of a code among `names` that start at code `first`, if `code` is one.
fn lookup(names: &[&'static str], first: f64, code: f64) -> Option<&'static str> {
    let index = code - first;
    (index.fract() == 0.0 && index >= 0.0)
        .then(|| names.get(index as usize).copied())
        .flatten()
}

/// The name of a `status` code (`filtered`, `uncertified`, …); `None` for a value that is
/// no code (NaN, 2.5, 9).
pub fn status_name(code: f64) -> Option<&'static str> {
    lookup(&STATUS_NAMES, NO_READING, code)
}

/// The name of a `reason` code (`tube`, `out-of-domain`, …); `None` for [`NO_REASON`] and
/// for a value that is no code.
pub fn reason_name(code: f64) -> Option<&'static str> {
    lookup(&REASON_NAMES, 1.0, code)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_status_has_its_own_code_and_name() {
        let statuses = [
            TickStatus::Unfiltered,
            TickStatus::Filtered,
            TickStatus::Relaxed,
            TickStatus::QpFailed,
            TickStatus::InvalidState(InvalidState::NonFinite),
            TickStatus::InvalidState(InvalidState::Size {
                what: "q",
                expected: 6,
                got: 5,
            }),
            TickStatus::InvalidState(InvalidState::MassMatrix),
            TickStatus::InvalidState(InvalidState::NonFiniteModel),
            TickStatus::InvalidState(InvalidState::OutOfDomain),
            TickStatus::Uncertified(Uncertified::Tube),
            TickStatus::Uncertified(Uncertified::Domain),
            TickStatus::Uncertified(Uncertified::Start),
            TickStatus::Uncertified(Uncertified::Bound),
            TickStatus::Uncertified(Uncertified::Budget),
        ];
        let mut seen = Vec::new();
        for status in statuses {
            let (code, reason) = codes(status);
            assert!(status_name(code).is_some(), "{status:?}");
            assert!(
                !seen.contains(&(code, reason)),
                "{status:?} shares its codes"
            );
            seen.push((code, reason));
            if let TickStatus::Uncertified(why) = status {
                assert_eq!(reason_name(reason), Some(why.name()));
            }
        }
        assert_eq!(status_name(NO_READING), Some("no-reading"));
        assert_eq!(status_name(5.0), Some("uncertified"));
        for not_a_code in [f64::NAN, 2.5, 6.0, -2.0, f64::INFINITY] {
            assert_eq!(status_name(not_a_code), None, "{not_a_code}");
        }
        assert_eq!(reason_name(NO_REASON), None);
        assert_eq!(reason_name(10.0), Some("out-of-domain"));
        assert_eq!(reason_name(11.0), None);
    }
}
