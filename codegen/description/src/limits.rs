//! The valid range of every number a user gives softcbf, in a description file or on the
//! command line: one definition per setting, so that both are checked by the same rule.
//!
//! A [`Limit`] says what a value must be (finite, between bounds, perhaps an integer) and
//! builds the message when it is not; the file checker (`toml_file`) adds the file, line
//! and field, the command line adds the option's name. The ranges are physical: a bound
//! says where a value stops describing a robot (a reply that takes more than a second, a
//! module longer than 10 m), not where the arithmetic happens to break, and every value
//! inside them leaves the model's arithmetic finite (`tests/tests/model/descriptions.rs`).
//!
//! The state domain of the model (`q`, `q̇`) is bounded in the same spirit by
//! [`crate::domain`]; the limits every module has where its robot file writes none, which
//! keep the controller inside that domain, are defined here too
//! ([`DEFAULT_MIN_LENGTH_FRACTION`] and what follows it).

/// What a number must be: finite, within `[min, max]` (or `(min, max]`), perhaps an
/// integer. `unit` is for messages.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limit {
    /// Lower bound.
    pub min: f64,
    /// Whether `min` itself is allowed (`false`: the value must exceed it).
    pub min_inclusive: bool,
    /// Upper bound (always allowed).
    pub max: f64,
    /// Whether the value must be a whole number.
    pub integer: bool,
    /// Unit shown in messages (`""` for none).
    pub unit: &'static str,
}

impl Limit {
    /// `min ≤ value ≤ max`.
    pub const fn closed(min: f64, max: f64, unit: &'static str) -> Limit {
        Limit {
            min,
            min_inclusive: true,
            max,
            integer: false,
            unit,
        }
    }

    /// `min < value ≤ max`.
    pub const fn above(min: f64, max: f64, unit: &'static str) -> Limit {
        Limit {
            min,
            min_inclusive: false,
            max,
            integer: false,
            unit,
        }
    }

    /// The same range mirrored to negative values, `-max ≤ value ≤ max` (for entries whose
    /// sign is free, such as the off-diagonal entries of a gain matrix).
    pub const fn either_sign(self) -> Limit {
        Limit {
            min: -self.max,
            min_inclusive: true,
            ..self
        }
    }

    /// A whole number in `min..=max`.
    pub const fn integer(min: i64, max: i64) -> Limit {
        Limit {
            min: min as f64,
            min_inclusive: true,
            max: max as f64,
            integer: true,
            unit: "",
        }
    }

    /// Whether `value` is allowed.
    pub fn contains(&self, value: f64) -> bool {
        let low = if self.min_inclusive {
            value >= self.min
        } else {
            value > self.min
        };
        value.is_finite() && low && value <= self.max && (!self.integer || value.fract() == 0.0)
    }

    /// The allowed range in words: `> 0 and ≤ 1000 ms`, `an integer in 1..=1000`.
    pub fn describe(&self) -> String {
        if self.integer {
            return format!("an integer in {}..={}", self.min, self.max);
        }
        let unit = match self.unit {
            "" => String::new(),
            "°" => "°".to_string(),
            unit => format!(" {unit}"),
        };
        let low = if self.min_inclusive { "≥" } else { ">" };
        format!("{low} {} and ≤ {}{unit}", short(self.min), short(self.max))
    }

    /// `Ok(value)` if allowed, else the message (without the field's name):
    /// `must be > 0 and ≤ 1000 ms, got 1e300`.
    pub fn check(&self, value: f64) -> Result<f64, String> {
        if self.contains(value) {
            return Ok(value);
        }
        if value.is_nan() || (!self.integer && value.is_infinite()) {
            return Err(format!(
                "must be a finite number {}, got {value}",
                self.describe()
            ));
        }
        Err(format!("must be {}, got {}", self.describe(), short(value)))
    }

    /// [`Limit::check`] for an integer setting, returned as `i64`.
    pub fn check_integer(&self, value: i64) -> Result<i64, String> {
        if self.contains(value as f64) {
            Ok(value)
        } else {
            Err(format!("must be {}, got {value}", self.describe()))
        }
    }
}

/// `x` in the shortest readable form: `1000`, `0.25`, `1e300`, `1e-9`.
pub fn short(x: f64) -> String {
    let magnitude = x.abs();
    if x == 0.0 || !x.is_finite() || (1e-4..1e7).contains(&magnitude) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// `x` to nine significant digits, in the shortest form (`-0.05`, not
/// `-0.04999999999999999`): for lengths computed from written ones.
pub(crate) fn rounded(x: f64) -> String {
    let nine: f64 = format!("{x:.8e}").parse().unwrap_or(x);
    short(nine)
}

// ---------------------------------------------------------------------------------------
// The robot file: modules, gravity, barrier gains.

/// Largest `modules = N` accepted: a guard against typos, not a limit of the model.
pub const MAX_MODULES: usize = 1000;
/// Number of modules of a robot (`modules = N`): a guard against typos, not a limit of the
/// model.
pub const MODULES: Limit = Limit::integer(1, MAX_MODULES as i64);
/// A length or radius of a module \[m\] (`rest_length`, `tendon_radius`, `corner_radius`,
/// a tendon's `zero_length`): from a tenth of a millimetre (below, foam and plates are no
/// longer rigid bodies on a backbone) to 10 m (no soft module is longer).
pub const LENGTH_M: Limit = Limit::closed(1e-4, 10.0, "m");
/// Mass lumped in a plate \[kg\]: a milligram to ten tonnes.
pub const MASS_KG: Limit = Limit::closed(1e-6, 1e4, "kg");
/// A principal moment of inertia of a plate \[kg·m²\]: from a milligram disc of 0.1 mm
/// radius (`m r²/8 ≈ 1e-15`) to ten tonnes at ten metres (`m r² = 1e6`).
pub const INERTIA_KG_M2: Limit = Limit::closed(1e-16, 1e6, "kg·m²");
/// Offset of a plate's centre of mass along its normal \[m\]: within a module's length.
pub const COM_OFFSET_M: Limit = Limit::closed(-10.0, 10.0, "m");
/// A corner or tendon angle \[deg\]: one turn either way covers every direction.
pub const ANGLE_DEG: Limit = Limit::closed(-360.0, 360.0, "°");
/// Bending stiffness `κθ` \[N·m/rad\]: soft modules have 0.01–10; 1e4 is a steel rod.
pub const BENDING_STIFFNESS: Limit = Limit::closed(0.0, 1e4, "N·m/rad");
/// Axial stiffness `κL` \[N/m\]: soft modules have 10–1e4; 1e7 is a steel spring.
pub const AXIAL_STIFFNESS: Limit = Limit::closed(0.0, 1e7, "N/m");
/// Bending damping `βθ` \[N·m·s/rad\]: as the bending stiffness, at most 1e4.
pub const BENDING_DAMPING: Limit = Limit::closed(0.0, 1e4, "N·m·s/rad");
/// Axial damping `βL` \[N·s/m\]: an industrial shock absorber has 1e5.
pub const AXIAL_DAMPING: Limit = Limit::closed(0.0, 1e6, "N·s/m");
/// Barrier margin of a corner \[m\]: a safety distance of more than a metre between
/// plates describes no contact.
pub const MARGIN_M: Limit = Limit::closed(0.0, 1.0, "m");
/// A component of gravity \[m/s²\]: ten times the Earth's covers every planet and a
/// centrifuge.
pub const GRAVITY_M_S2: Limit = Limit::closed(-100.0, 100.0, "m/s²");
/// HOCBF class-K gains `p1`, `p2` \[1/s\] (robot `[barrier]`, scenario `[gains]`): above
/// 1e4 1/s a barrier would be corrected within 0.1 ms, faster than any actuator.
pub const BARRIER_GAIN_PER_S: Limit = Limit::above(0.0, 1e4, "1/s");

// ---------------------------------------------------------------------------------------
// The limits every module has where its robot file writes none: the model's domain as a
// constraint of the controller (docs/model.md §3). One place for all of them; a file may
// tighten them, not loosen them. First the model's own domain (crate::domain re-exports
// these three), which every state and every limit a file writes lies within.

/// Largest bend `θ = √(Δx² + Δy²)/d` of a segment \[rad\]: three quarters of a turn
/// (270°). At a full turn the plate comes back onto its base whatever the bend's direction
/// and the segment's length, so `M(q)` is singular there (its smallest Cholesky pivot
/// falls as `(2π − θ)²`: 4e-3 of the largest at 1.5π, 2e-6 at 1.99π for the paper robot);
/// no module bends that far without its plates meeting.
pub const MAX_BEND_RAD: f64 = 1.5 * std::f64::consts::PI;
/// Largest `|δL|` as a multiple of the segment's rest length `L0`.
pub const MAX_ELONGATION_RATIO: f64 = 10.0;
/// Largest `|q̇|` entry \[m/s\]: far beyond any soft robot, small enough that every product
/// of the dynamics stays finite.
pub const MAX_SPEED: f64 = 100.0;

/// The domain's default lower bound on a backbone's length, as a fraction `λ_min` of its
/// rest length: `L0 + δL ≥ λ_min L0`, the elongation limit `δL_min = −(1 − λ_min) L0`
/// that a module has when its robot file writes none, and the lowest `δL_min` a file may
/// write. At `L → 0` the segment and its tendons describe nothing physical, and the
/// plate-corner barriers no longer keep the state away from it once the corner margins
/// are zero. 0.05 lies below what the paper's robot ever reaches: its set points go down
/// to `δL = −0.07 m` on `L0 = 0.1 m` (`λ = 0.3`), users write −0.09 m (`λ = 0.1`), and its
/// corner margins of 5 mm keep a straight backbone at `L ≥ 5 mm` already (a bent one is
/// kept longer), so this row is never the first to bind there.
pub const DEFAULT_MIN_LENGTH_FRACTION: f64 = 0.05;
/// The domain's default upper elongation limit, as a multiple of the rest length:
/// `δL_max = 4 L0`, and the largest `δL_max` a robot file may write. The paper's own
/// filter stretches module 2 to `δL = 0.242 m = 2.42 L0`, at up to 3.2 m/s, in its
/// simulation (`scenarios/paper-sim.toml`), and this row must leave that alone: at `3 L0`
/// it binds there with [`DOMAIN_BARRIER_GAINS`] (the run moves by 6 mm) and would need
/// stiffer gains, which the paper's rows at 33 Hz overshoot more often. No module of the
/// repository comes near `4 L0`; [`MAX_ELONGATION_RATIO`], the domain
/// itself, is ten.
pub const DEFAULT_MAX_ELONGATION_RATIO: f64 = 4.0;
/// The domain's default bend limit \[rad\]: `θ ≤ 1.25π` (225°), and the largest bend limit
/// a robot file may write. It keeps the state an eighth of a turn inside the domain's
/// [`MAX_BEND_RAD`], where the mass matrix is still well conditioned; the
/// plates of any real module meet long before (the paper's at `θ = (L0 + δL)/r = 2 rad`,
/// 115°, straight).
pub const DEFAULT_MAX_BEND_RAD: f64 = 1.25 * std::f64::consts::PI;
/// The class-K gains `[p1, p2]` \[1/s\] of a limit barrier at its domain default (a limit
/// the robot file writes keeps its table's gains, or the run's). With the robot's gains
/// (the paper's 10 1/s) the upper elongation row binds at the first tick of the paper's
/// simulation, where the paper's filter asks for `δL̈₁ = 215 m/s²` from rest and the row
/// allows `p1 p2 (δL_max − δL) = 40 m/s²` (360 m/s² with these gains); the run moves by
/// 0.12 m. Stiffer rows leave motion alone until it comes closer to the limit, but at long
/// holds the paper's continuous-time rows overshoot them: with the paper's rows at 33 Hz
/// on 100 draws of `scenarios/verify-paper.toml`, gains of 30 1/s leave the QP relaxed in
/// 24 runs and stop none, 50 1/s relax it in 97 and stop 4 (the plant integrated into a
/// singular mass matrix). 30 1/s is the measured compromise (docs/model.md §3); the rows
/// never bind in the paper's simulation (`tests/tests/model/domain_limits.rs`).
pub const DOMAIN_BARRIER_GAINS: [f64; 2] = [30.0, 30.0];

/// The default bound on each module's elongation rate `|δL̇|`, in rest lengths per second:
/// `|δL̇| ≤ 10 L0/s` (1 m/s for `L0 = 0.1 m`), and the largest rate a robot file may write is
/// the domain's speed, [`MAX_SPEED`]. It is a row of the predicted and
/// certified rows only (docs/model.md §5, "Rate limits"): the filter may not buy a corner by
/// stretching a module faster, since a module thrashing between its limits at several
/// metres per second leaves the next hold in a state from which no command keeps every
/// barrier (`robots/three-square.toml`: 2.3 to 6 m/s, a corner 3 mm past contact, before
/// this row). The paper's scenario with the certified rows stays below 0.14 m/s; the
/// paper's own rows (3.2 m/s on module 2 in its simulation) do not have this row.
pub const DEFAULT_ELONGATION_RATE_PER_L0: f64 = 10.0;

/// An elongation rate bound `|δL̇| ≤ v̄` \[m/s\] (`[limits] elongation_rate`).
pub const ELONGATION_RATE_M_S: Limit = Limit::above(0.0, MAX_SPEED, "m/s");

/// The domain's default elongation limits `[δL_min, δL_max]` \[m\] of a module of rest
/// length `L0` \[m\]: `[−(1 − λ_min) L0, 4 L0]`, the widest a robot file may write.
pub fn default_elongation(rest_length: f64) -> [f64; 2] {
    [
        DEFAULT_MIN_LENGTH_FRACTION * rest_length - rest_length,
        DEFAULT_MAX_ELONGATION_RATIO * rest_length,
    ]
}

/// An elongation limit `δL_min` or `δL_max` \[m\] (`[limits] elongation`): within the
/// domain's defaults of any module of at most 10 m; for every module it applies to, the
/// robot file also needs `δL_min ≥ −(1 − λ_min) L0` and `δL_max ≤ 4 L0`
/// ([`default_elongation`]): a file may tighten the domain's limits, not loosen them.
pub const ELONGATION_LIMIT_M: Limit = Limit::closed(-100.0, 100.0, "m");
/// A bend limit `θ_max` \[deg\] (`[limits] max_bend_deg`): up to the domain's default of
/// 225° ([`DEFAULT_MAX_BEND_RAD`], 1.25π): a file may tighten it, not loosen it.
pub const MAX_BEND_DEG: Limit = Limit::above(0.0, 225.0, "°");
/// The margin of a bend limit \[deg\]; it must also stay below the limit itself.
pub const BEND_MARGIN_DEG: Limit = Limit::closed(0.0, 225.0, "°");
/// A coordinate of an obstacle in the world \[m\] (a sphere's centre, a plane's offset):
/// 100 m is far beyond any soft robot's reach.
pub const POSITION_M: Limit = Limit::closed(-100.0, 100.0, "m");
/// A sphere obstacle's radius \[m\]: positive, at most 100 m.
pub const OBSTACLE_RADIUS_M: Limit = Limit::above(0.0, 100.0, "m");
/// A component of a half-space's normal (any length; it is normalized, and must not be
/// zero).
pub const NORMAL_COMPONENT: Limit = Limit::closed(-1e6, 1e6, "");
/// A coordinate of a watched point in its plate's frame \[m\]: within the largest module.
pub const PLATE_POINT_M: Limit = Limit::closed(-10.0, 10.0, "m");
/// The arc fraction `s` of a watched backbone point: `0 < s ≤ 1` (1 is the top plate's
/// origin; the base itself never moves).
pub const ARC_FRACTION: Limit = Limit::above(0.0, 1.0, "");

/// A relative uncertainty of the robot file's `[uncertainty]` table (`stiffness`, `damping`,
/// `mass`; 0.2 is ±20 %): the true number lies within `(1 ± fraction)` times the file's.
/// Below 1, because the lower end `1 − fraction` must stay positive: at 1 a plate could be
/// massless (a singular mass matrix, unbounded accelerations) and a robust margin that
/// divides by `1 − fraction` unbounded; beyond ±90 % the file no longer knows the number.
pub const UNCERTAINTY_FRACTION: Limit = Limit::closed(0.0, 0.9, "");
/// Bound on the unmodelled generalized force on each coordinate \[N\] (`[uncertainty]
/// force`): up to 1e4 N, the weight of a tonne; a larger force is a missing part of the
/// model, not an uncertainty of it.
pub const UNMODELLED_FORCE_N: Limit = Limit::closed(0.0, 1e4, "N");

// ---------------------------------------------------------------------------------------
// The scenario file (with DURATION_S below).

/// Control period of a simulation \[s\]: 1 µs (1 MHz) to 1 s (the slowest loop,
/// [`RATE_HZ`]).
pub const CONTROL_PERIOD_S: Limit = Limit::closed(1e-6, 1.0, "s");
/// Time of a waypoint \[s\]: within the longest run ([`DURATION_S`]).
pub const WAYPOINT_TIME_S: Limit = Limit::closed(0.0, 1e6, "s");
/// A diagonal entry (or the scalar) of `K_P` \[N/m\]: 1e6 N/m moves a 10 t plate at 1.6 Hz
/// and a milligram one far beyond any servo; off-diagonal entries lie within `±max`.
pub const KP_N_PER_M: Limit = Limit::closed(0.0, 1e6, "N/m");
/// A diagonal entry (or the scalar) of `K_D` \[N·s/m\]; off-diagonal entries within `±max`.
pub const KD_N_S_PER_M: Limit = Limit::closed(0.0, 1e6, "N·s/m");
/// Relative tolerance of the plant integration: above 1 nothing is controlled; below
/// 1e-12 it asks for more than double precision can give.
pub const RTOL: Limit = Limit::closed(1e-12, 1.0, "");
/// Absolute tolerance of the plant integration \[m, m/s\]: a femtometre to a metre.
pub const ATOL: Limit = Limit::closed(1e-15, 1.0, "");
/// First step of the plant integration \[s\]: from the integrator's smallest step
/// (1e-12 s) to the longest control period.
pub const H_INITIAL_S: Limit = Limit::closed(1e-12, 1.0, "s");
/// Step attempts of the plant integration within one tick.
pub const MAX_STEPS: Limit = Limit::integer(1, 10_000_000);

// ---------------------------------------------------------------------------------------
// The hardware loop (`softcbf run`); the servo and bus settings are the runtime's
// (`softcbf::hardware_description::limits`).

/// Loop rate \[Hz\]: below 1 Hz a soft robot moves a barrier's width between ticks; above
/// 10 kHz no servo bus answers (6 servos at 4.5 Mbit/s: ≈ 2 kHz).
pub const RATE_HZ: Limit = Limit::closed(1.0, 10_000.0, "Hz");
/// Duration of a run or a simulation \[s\] (up to about 11 days).
pub const DURATION_S: Limit = Limit::above(0.0, 1e6, "s");
/// Lowest barrier a run may reach and still count as safe \[m\].
pub const BARRIER_THRESHOLD_M: Limit = Limit::closed(-1.0, 1.0, "m");
/// Default of [`BARRIER_THRESHOLD_M`] for a hardware run (`softcbf run`): one millimetre of
/// penetration of the margin. Its barriers are taken at the states read, which carry the
/// encoders' quantization and the model's error against the robot.
pub const DEFAULT_BARRIER_THRESHOLD: f64 = -1e-3;
/// Default of [`BARRIER_THRESHOLD_M`] for `softcbf simulate`: [`BARRIER_TOLERANCE_M`] below
/// zero, as `softcbf verify` judges its runs and the figures draw them. A simulation's plant
/// is the model (or a declared plant), integrated to `atol` 1e-9, so a barrier further below
/// zero is a violation, not a reading's error.
pub const DEFAULT_SIMULATION_THRESHOLD: f64 = -BARRIER_TOLERANCE_M;
/// How far below zero a barrier may be and still count as held at zero \[m\]: a filter that
/// holds a barrier on its boundary ends within rounding of zero, on either side (−1.6e-12 m
/// and +5e-14 m were seen), and the integrator's tolerance (`atol` 1e-9) is far smaller.
/// `softcbf verify` counts a run unsafe below `−BARRIER_TOLERANCE_M` (its default
/// threshold), and the figures and the 3-D view draw a barrier as violated (red, "below its
/// margin") only below it: one tolerance for the verdict and the picture.
pub const BARRIER_TOLERANCE_M: f64 = 1e-6;
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_accept_their_range_and_name_it_otherwise() {
        assert_eq!(RATE_HZ.check(33.0), Ok(33.0));
        assert_eq!(RATE_HZ.check(10_000.0), Ok(10_000.0));
        assert_eq!(
            DURATION_S.check(1e300).unwrap_err(),
            "must be > 0 and ≤ 1000000 s, got 1e300"
        );
        assert!(DURATION_S.check(0.0).unwrap_err().contains("> 0"));
        assert!(DURATION_S.check(f64::NAN).unwrap_err().contains("finite"));
        assert!(RATE_HZ.check(f64::INFINITY).unwrap_err().contains("finite"));
        assert_eq!(MAX_STEPS.check_integer(10_000_000), Ok(10_000_000));
        assert_eq!(
            MODULES.check_integer(100_000).unwrap_err(),
            "must be an integer in 1..=1000, got 100000"
        );
        assert!(MODULES.check(2.5).is_err());
        assert!(RATE_HZ.check(1e-9).is_err());
        assert!(RATE_HZ.check(-33.0).is_err());
    }

    /// Every range is a proper interval with finite ends (integer ranges with whole ends),
    /// and its description is what the READMEs print.
    #[test]
    fn every_range_is_a_proper_interval_described_in_short_numbers() {
        let all = [
            RATE_HZ,
            DURATION_S,
            BARRIER_THRESHOLD_M,
            MODULES,
            LENGTH_M,
            MASS_KG,
            INERTIA_KG_M2,
            COM_OFFSET_M,
            ANGLE_DEG,
            BENDING_STIFFNESS,
            AXIAL_STIFFNESS,
            BENDING_DAMPING,
            AXIAL_DAMPING,
            MARGIN_M,
            GRAVITY_M_S2,
            BARRIER_GAIN_PER_S,
            CONTROL_PERIOD_S,
            WAYPOINT_TIME_S,
            KP_N_PER_M,
            KD_N_S_PER_M,
            RTOL,
            ATOL,
            H_INITIAL_S,
            MAX_STEPS,
        ];
        for limit in all {
            assert!(limit.min.is_finite() && limit.max.is_finite() && limit.min < limit.max);
            assert!(limit.contains(limit.max), "{limit:?}");
            assert_eq!(limit.contains(limit.min), limit.min_inclusive, "{limit:?}");
            if limit.integer {
                assert_eq!((limit.min.fract(), limit.max.fract()), (0.0, 0.0));
            }
        }
        // The bend limit a file may write ends at the domain's default.
        assert!((MAX_BEND_DEG.max.to_radians() - DEFAULT_MAX_BEND_RAD).abs() < 1e-15);
        assert_eq!(BEND_MARGIN_DEG.max, MAX_BEND_DEG.max);
        assert_eq!(INERTIA_KG_M2.describe(), "≥ 1e-16 and ≤ 1000000 kg·m²");
        assert_eq!(ANGLE_DEG.describe(), "≥ -360 and ≤ 360°");
        assert_eq!(AXIAL_STIFFNESS.describe(), "≥ 0 and ≤ 1e7 N/m");
        assert_eq!(RTOL.describe(), "≥ 1e-12 and ≤ 1");
        assert_eq!(
            KP_N_PER_M.either_sign().check(-1.5e6).unwrap_err(),
            "must be ≥ -1000000 and ≤ 1000000 N/m, got -1500000"
        );
        assert_eq!(KP_N_PER_M.either_sign().check(-1e6), Ok(-1e6));
        assert_eq!(
            MODULES.check_integer(i64::MIN).unwrap_err(),
            "must be an integer in 1..=1000, got -9223372036854775808"
        );
    }
}

// ---------------------------------------------------------------------------------------
// Dense records of a simulation (scenario `record_period`, `--record-period`).

/// Time between recorded rows of a simulation \[s\] (`record_period`): 1 µs, the shortest
/// control period ([`CONTROL_PERIOD_S`]), to 1 s; a scenario also needs it no longer than
/// its control period.
pub const RECORD_PERIOD_S: Limit = Limit::closed(1e-6, 1.0, "s");

#[cfg(test)]
mod record_period_tests {
    use super::*;

    #[test]
    fn the_record_period_spans_the_control_periods() {
        assert_eq!(RECORD_PERIOD_S.min, CONTROL_PERIOD_S.min);
        assert_eq!(RECORD_PERIOD_S.max, CONTROL_PERIOD_S.max);
        assert_eq!(RECORD_PERIOD_S.check(1e-3), Ok(1e-3));
        assert_eq!(
            RECORD_PERIOD_S.check(0.0).unwrap_err(),
            "must be ≥ 1e-6 and ≤ 1 s, got 0"
        );
        assert!(
            RECORD_PERIOD_S
                .check(f64::NAN)
                .unwrap_err()
                .contains("finite")
        );
    }
}
