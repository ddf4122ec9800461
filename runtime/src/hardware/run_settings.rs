//! What one `softcbf run` does: its rate, minimum rate, duration, set point, filter,
//! prediction, Bus Watchdog and gains, with their defaults and the checks they must pass.

use softcbf_description::limits::{self, Limit};

use crate::hardware::limits as servo;
use crate::settings::Gains;

/// The shortest Bus Watchdog `softcbf run` arms by default \[s\].
pub const DEFAULT_BUS_WATCHDOG_FLOOR: f64 = 0.1;

/// What one run does.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSettings {
    /// Loop rate \[Hz\] (the paper: 33).
    pub rate: f64,
    /// Lowest rate the loop may fall to, averaged over [`RATE_WINDOW`](crate::hardware::run_loop::RATE_WINDOW) commands, before it
    /// stops \[Hz\]. Default: half of `rate`.
    pub min_rate: f64,
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
    /// than v38 has none). Default: [`RunSettings::default_bus_watchdog`].
    pub bus_watchdog: f64,
    /// `K_P`, `K_D`, `p1`, `p2` with their sources; `None`: the robot file's, else the
    /// built-in paper gains ([`crate::settings::resolve_gains`] without options).
    pub gains: Option<Gains>,
}

impl RunSettings {
    /// `rate` toward `set_point` with the defaults: no duration, filter and prediction on,
    /// `min_rate = rate / 2`, the default Bus Watchdog, the robot file's gains.
    pub fn new(rate: f64, set_point: Vec<f64>) -> RunSettings {
        let min_rate = rate / 2.0;
        RunSettings {
            rate,
            min_rate,
            duration: None,
            set_point,
            filter: true,
            predict: true,
            bus_watchdog: RunSettings::default_bus_watchdog(min_rate),
            gains: None,
        }
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
        let units = (self.bus_watchdog * 1000.0 / servo::BUS_WATCHDOG_UNIT_MS).ceil();
        units.clamp(0.0, 127.0) as u8
    }

    /// Checks every setting against its range and the others, for a robot with `nq`
    /// coordinates. Messages name the command-line option.
    pub fn validate(&self, nq: usize) -> Result<(), String> {
        let check = |name: &str, value: f64, limit: &Limit| {
            limit.check(value).map_err(|m| format!("{name}: {m}"))
        };
        check("--rate", self.rate, &limits::RATE_HZ)?;
        check("--min-rate", self.min_rate, &limits::RATE_HZ)?;
        if self.min_rate > self.rate {
            return Err(format!(
                "--min-rate: {} Hz is above the loop rate {} Hz",
                self.min_rate, self.rate
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
        if self.set_point.len() != nq || self.set_point.iter().any(|v| !v.is_finite()) {
            return Err(format!("--set-point: needs {nq} finite values"));
        }
        check(
            "--bus-watchdog-ms",
            self.bus_watchdog * 1000.0,
            &servo::BUS_WATCHDOG_MS,
        )?;
        let unit = servo::BUS_WATCHDOG_UNIT_MS / 1000.0;
        if self.bus_watchdog > 0.0 && self.bus_watchdog < unit {
            return Err(format!(
                "--bus-watchdog-ms: {} ms is shorter than the register's unit of 20 ms; \
                 give 0 (off) or 20 to 2540 ms",
                self.bus_watchdog * 1000.0
            ));
        }
        let longest_gap = 2.0 / self.min_rate;
        if self.bus_watchdog > 0.0 && self.bus_watchdog < longest_gap {
            return Err(format!(
                "--bus-watchdog-ms: {} ms is shorter than two periods at the minimum rate \
                 ({:.0} ms at {} Hz): the servos would stop between ticks; give at least \
                 {:.0} ms, or lower --min-rate",
                self.bus_watchdog * 1000.0,
                longest_gap * 1000.0,
                self.min_rate,
                (longest_gap * 1000.0 / servo::BUS_WATCHDOG_UNIT_MS).ceil()
                    * servo::BUS_WATCHDOG_UNIT_MS
            ));
        }
        Ok(())
    }
}
