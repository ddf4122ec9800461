//! What one `softcbf run` does: its rate (fixed, or chosen from the bus), minimum rate,
//! duration, set point or experiment, filter, prediction, Bus Watchdog and gains, with
//! defaults and checks.

use softcbf_description::limits::{self, Limit};

use crate::bus_check::RateRule;
use crate::experiment::ExperimentSettings;
use crate::hardware_description::limits as servo;
use crate::settings::Gains;

/// Commands over which the achieved rate and the hold period are measured.
pub const RATE_WINDOW: usize = 8;

/// The shortest Bus Watchdog `softcbf run` arms by default \[s\].
pub const DEFAULT_BUS_WATCHDOG_FLOOR: f64 = 0.1;

/// The highest default minimum rate of a run whose rate is chosen from the bus
/// ([`RateRule::Adapt`]) \[Hz\]: half the paper's 33 Hz. Half of a fast rate (hundreds of Hz),
/// averaged over 8 commands, would stop the run at the first stall of a few ms of the host,
/// though the loop then still ticks faster than the paper's.
pub const AUTO_MIN_RATE: f64 = 16.5;

/// What one run does.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSettings {
    /// Loop rate \[Hz\] (the paper: 33); with [`RateRule::Adapt`], the highest rate the run
    /// may choose.
    pub rate: f64,
    /// What the start does when the bus cannot hold `rate`
    /// ([`crate::bus_check::choose_rate`]): refuse (default), or adapt
    /// (`--rate auto`).
    pub rate_rule: RateRule,
    /// Lowest rate the loop may fall to, averaged over
    /// [`RATE_WINDOW`] commands, before it stops
    /// \[Hz\]; `None`: half of the rate run at, with [`RateRule::Adapt`] at most
    /// [`AUTO_MIN_RATE`] ([`RunSettings::min_rate`]).
    pub min_rate: Option<f64>,
    /// Stop after this long \[s\]; `None`: until interrupted.
    pub duration: Option<f64>,
    /// Set point `q̄` (length `nq`).
    pub set_point: Vec<f64>,
    /// Run the safety filter (`false`: plain PD+).
    pub filter: bool,
    /// Compute each command at the state predicted for when it reaches the servos
    /// (`false`: at the state read). Default `true`.
    pub predict: bool,
    /// Bus Watchdog of the servos \[s\]: a servo stops by itself when no instruction has
    /// come for this long (a killed or crashed host); `0` leaves it off (firmware older
    /// than v38 has none); `None`: [`RunSettings::default_bus_watchdog`] of the minimum
    /// rate ([`RunSettings::bus_watchdog`]).
    pub bus_watchdog: Option<f64>,
    /// `K_P`, `K_D`, `p1`, `p2` with their sources; `None`: the robot file's, else the
    /// built-in paper gains ([`crate::settings::resolve_gains`] without options).
    pub gains: Option<Gains>,
    /// An identification experiment ([`crate::experiment`]) instead of PD+
    /// toward the set point: its tensions, through the safety filter, until it is over.
    pub experiment: Option<ExperimentSettings>,
}

impl RunSettings {
    /// `rate` toward `set_point` with the defaults: no duration, filter and prediction on,
    /// `min_rate = rate / 2`, the default Bus Watchdog, the robot file's gains.
    pub fn new(rate: f64, set_point: Vec<f64>) -> RunSettings {
        RunSettings {
            rate,
            rate_rule: RateRule::Hold,
            min_rate: None,
            duration: None,
            set_point,
            filter: true,
            predict: true,
            bus_watchdog: None,
            gains: None,
            experiment: None,
        }
    }

    /// These settings at the loop rate `rate` decided at the start.
    pub fn at_rate(&self, rate: f64) -> RunSettings {
        RunSettings {
            rate,
            ..self.clone()
        }
    }

    /// The lowest rate before the run stops \[Hz\]: the one given, else half of `rate` (with
    /// [`RateRule::Adapt`], at most [`AUTO_MIN_RATE`]), never below the slowest loop rate
    /// (a loop of 1–2 Hz, which `--rate auto` may choose on a slow bus, stops below 1 Hz).
    pub fn min_rate(&self) -> f64 {
        self.min_rate.unwrap_or(
            match self.rate_rule {
                RateRule::Adapt => (self.rate / 2.0).min(AUTO_MIN_RATE),
                RateRule::Hold | RateRule::Overrun => self.rate / 2.0,
            }
            .max(limits::RATE_HZ.min.min(self.rate)),
        )
    }

    /// The servos' Bus Watchdog \[s\] (`0`: off): the one given, else the default of the
    /// minimum rate.
    pub fn bus_watchdog(&self) -> f64 {
        self.bus_watchdog
            .unwrap_or_else(|| RunSettings::default_bus_watchdog(self.min_rate()))
    }

    /// Three periods at `min_rate`, at least [`DEFAULT_BUS_WATCHDOG_FLOOR`], rounded up to
    /// the register's 20 ms unit and capped at its largest value \[s\].
    pub fn default_bus_watchdog(min_rate: f64) -> f64 {
        let unit = servo::BUS_WATCHDOG_UNIT_MS / 1000.0;
        let seconds = (3.0 / min_rate).max(DEFAULT_BUS_WATCHDOG_FLOOR);
        let units = (seconds / unit).ceil().clamp(1.0, 127.0);
        if units.is_finite() {
            units * unit
        } else {
            127.0 * unit
        }
    }

    /// The gains of the run: [`RunSettings::gains`], else `robot`'s file's, else the
    /// built-in paper gains.
    pub fn gains_for(&self, robot: &softcbf_description::Robot) -> Gains {
        self.gains.clone().unwrap_or_else(|| {
            crate::settings::resolve_gains(
                &crate::settings::GainOptions::default(),
                &crate::settings::ScenarioGains::default(),
                robot,
            )
        })
    }

    /// The Bus Watchdog register value (units of 20 ms; `0`: off).
    pub fn bus_watchdog_units(&self) -> u8 {
        let units = (self.bus_watchdog() * 1000.0 / servo::BUS_WATCHDOG_UNIT_MS).ceil();
        units.clamp(0.0, 127.0) as u8
    }

    /// Checks every setting against its range and the others, for a robot with `nq`
    /// coordinates. Messages name the command-line option. With [`RateRule::Adapt`] the
    /// checks against the rate use its ceiling; [`RunSettings::at_rate`] is checked again.
    pub fn validate(&self, nq: usize) -> Result<(), String> {
        let check = |name: &str, value: f64, limit: &Limit| {
            limit.check(value).map_err(|m| format!("{name}: {m}"))
        };
        check("--rate", self.rate, &limits::RATE_HZ)?;
        let min_rate = self.min_rate();
        check("--min-rate", min_rate, &limits::RATE_HZ)?;
        if min_rate > self.rate {
            return Err(format!(
                "--min-rate: {min_rate} Hz is above the loop rate, {} Hz",
                self.rate
            ));
        }
        if let Some(duration) = self.duration {
            check("--duration", duration, &limits::DURATION_S)?;
            if duration * self.rate < 1.0 {
                return Err(format!(
                    "--duration: {duration} s is shorter than one tick at {} Hz ({} s)",
                    self.rate,
                    1.0 / self.rate
                ));
            }
        }
        if let Some(experiment) = &self.experiment {
            experiment.validate()?;
        }
        if self.set_point.len() != nq || self.set_point.iter().any(|v| !v.is_finite()) {
            return Err(format!("--set-point: needs {nq} finite values"));
        }
        let watchdog = self.bus_watchdog();
        check(
            "--bus-watchdog-ms",
            watchdog * 1000.0,
            &servo::BUS_WATCHDOG_MS,
        )?;
        let unit = servo::BUS_WATCHDOG_UNIT_MS / 1000.0;
        if watchdog > 0.0 && watchdog < unit {
            return Err(format!(
                "--bus-watchdog-ms: {} ms is shorter than the register's unit of 20 ms; \
                 give 0 (off) or 20 to 2540 ms",
                watchdog * 1000.0
            ));
        }
        let longest_gap = 2.0 / min_rate;
        if watchdog > 0.0 && watchdog < longest_gap {
            return Err(format!(
                "--bus-watchdog-ms: {} ms is shorter than two periods at the minimum rate \
                 ({:.0} ms at {} Hz): the servos would stop between ticks; give at least \
                 {:.0} ms, or lower --min-rate",
                watchdog * 1000.0,
                longest_gap * 1000.0,
                min_rate,
                (longest_gap * 1000.0 / servo::BUS_WATCHDOG_UNIT_MS).ceil()
                    * servo::BUS_WATCHDOG_UNIT_MS
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_loop_as_slow_as_auto_may_choose_has_valid_defaults() {
        // `--rate auto` on a bus that allows 1.25–2.5 Hz runs at 1 Hz: the default minimum
        // rate and watchdog must hold for it (they once asked for 0.5 Hz, below the range).
        let mut slow = RunSettings::new(limits::RATE_HZ.max, vec![0.0; 6]);
        slow.rate_rule = RateRule::Adapt;
        let slow = slow.at_rate(1.0);
        assert_eq!(slow.min_rate(), 1.0);
        assert_eq!(slow.validate(6), Ok(()));
        assert_eq!(slow.at_rate(3.0).min_rate(), 1.5);
    }

    #[test]
    fn the_minimum_rate_and_the_watchdog_follow_the_rate_chosen_unless_given() {
        let mut auto = RunSettings::new(limits::RATE_HZ.max, vec![0.0; 6]);
        auto.rate_rule = RateRule::Adapt;
        assert_eq!(auto.validate(6), Ok(()));
        // Half of a slow rate; half the paper's rate below a fast one.
        let at = auto.at_rate(20.0);
        assert_eq!((at.rate, at.min_rate()), (20.0, 10.0));
        // Three periods at 10 Hz, 300 ms, in whole 20 ms units.
        assert!(
            (at.bus_watchdog() - 0.3).abs() < 1e-12,
            "{}",
            at.bus_watchdog()
        );
        assert_eq!(at.bus_watchdog_units(), 15);
        assert_eq!(at.validate(6), Ok(()));
        let at = auto.at_rate(400.0);
        assert_eq!(at.min_rate(), 16.5);
        // Three periods at 16.5 Hz, 182 ms, in whole 20 ms units: 200 ms.
        assert_eq!(at.bus_watchdog_units(), 10);
        assert_eq!(at.validate(6), Ok(()));
        // A rate asked for keeps half of it.
        let fixed = RunSettings::new(400.0, vec![0.0; 6]);
        assert_eq!(fixed.min_rate(), 200.0);
        // Given ones stay.
        auto.min_rate = Some(5.0);
        auto.bus_watchdog = Some(0.0);
        let at = auto.at_rate(40.0);
        assert_eq!((at.min_rate(), at.bus_watchdog()), (5.0, 0.0));
        assert_eq!(at.bus_watchdog_units(), 0);
    }

    #[test]
    fn settings_that_fit_the_ceiling_but_not_the_rate_chosen_are_refused_then() {
        let mut auto = RunSettings::new(limits::RATE_HZ.max, vec![0.0; 6]);
        auto.rate_rule = RateRule::Adapt;
        auto.min_rate = Some(50.0);
        auto.duration = Some(0.05);
        assert_eq!(auto.validate(6), Ok(()));
        let error = auto.at_rate(40.0).validate(6).unwrap_err();
        assert_eq!(error, "--min-rate: 50 Hz is above the loop rate, 40 Hz");
        auto.min_rate = None;
        let error = auto.at_rate(10.0).validate(6).unwrap_err();
        assert!(
            error.starts_with("--duration: 0.05 s is shorter than one tick"),
            "{error}"
        );
    }
}
