//! The `[hardware]` table of a robot file: serial settings, servo IDs and the calibration
//! that maps servo angles and currents to tendon lengths and tensions (§6 of the model notes).
//!
//! The description keeps the table as written ([`HardwareTable`]); [`load`] reads and
//! checks it with the description's errors, naming the file, line and field. The format is
//! documented in `robots/README.md`; the mapping itself is `softcbf::hardware::mapping`.

pub mod limits;

use std::ops::{Deref, Range};

use serde::Deserialize;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use softcbf_description::domain;
use softcbf_description::limits::{self as ranges, Limit};
use softcbf_description::robot::{HardwareTable, Module, Robot, Routing};
use softcbf_description::toml_file::{Checker, FileError};
use toml::Spanned;

use crate::control::SafetyMode;

/// Where the controller takes `q̇` from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VelocitySource {
    /// The servos' Present Velocity register, mapped like the angles.
    Servo,
    /// Differences of successive `q` readings, through a first-order low-pass filter.
    Difference,
}

/// One module's servos and their calibration. Tendon `k` is the module's
/// `tendon_angles_deg[k]`; every array has one entry per tendon (three).
#[derive(Clone, Debug, PartialEq)]
pub struct ModuleHardware {
    /// Servo ID driving each tendon (0..=252, unique on the bus).
    pub servo_ids: [u8; 3],
    /// `ρ`: radius of the pulley the tendon winds on \[m\].
    pub pulley_radius: f64,
    /// `θ_k0`: servo angle at the calibration pose \[rad\] (file: degrees).
    pub zero_angles: [f64; 3],
    /// `ℓ_k0`: tendon length at the calibration pose \[m\] (default: the rest length `L0`,
    /// i.e. calibrated straight and uncompressed).
    pub zero_lengths: [f64; 3],
    /// `s_k = ±1`: `+1` when a positive servo rotation (and a positive current) winds the
    /// tendon, shortening it; `−1` when it unwinds it.
    pub directions: [f64; 3],
    /// Tension per unit of motor current [N/mA] of each tendon's servo, identified on the
    /// robot (`softcbf identify`); the file gives one number for the module or one per
    /// tendon.
    pub actuator_gain: [f64; 3],
    /// `[f_min, f_max]`: tensions commanded are held in this range \[N\].
    pub tension_limits: [f64; 2],
}

/// The hardware description of a robot.
#[derive(Clone, Debug, PartialEq)]
pub struct Hardware {
    /// Serial baud rate [bit/s]; the servos' Baud Rate register must match.
    pub baud: u32,
    /// Longest wait for one status packet \[s\].
    pub reply_timeout: f64,
    /// Extra sync-read attempts within one tick after a failed one.
    pub retries: u32,
    /// Ticks in a row without a good reading before the safe stop.
    pub max_consecutive_errors: u32,
    /// Source of `q̇`.
    pub velocity_source: VelocitySource,
    /// Time constant of the low-pass filter on differences \[s\] (with `Difference`).
    pub velocity_filter: f64,
    /// Model number every servo must answer to a ping (e.g. 1020: XM430-W350).
    pub model_number: u16,
    /// Current unit of the Goal/Present Current registers \[mA\].
    pub current_unit: f64,
    /// Position unit of Present Position \[deg\].
    pub position_unit: f64,
    /// Velocity unit of Present Velocity [rev/min].
    pub velocity_unit: f64,
    /// Default set point `q̄` (length `3·modules`); zeros when not given.
    pub set_point: Vec<f64>,
    /// How the filter keeps the barriers between ticks (`safety = "certified" | "paper" |
    /// "predicted" | "hold-correction"`, or the older `hold_correction = true | false`); `None` when the
    /// file does not say (the run then uses [`SafetyMode::default`], the certified
    /// guarantee).
    pub safety: Option<SafetyMode>,
    /// One entry per module, base first.
    pub modules: Vec<ModuleHardware>,
}

/// Defaults of the `[hardware]` fields (X-series servos in current control mode).
pub mod defaults {
    /// 1 Mbit/s: fast enough for 33 Hz with margin, supported by every X-series servo.
    pub const BAUD: u32 = 1_000_000;
    /// Reply timeout \[ms\].
    pub const REPLY_TIMEOUT_MS: f64 = 10.0;
    /// Sync-read retries per tick.
    pub const RETRIES: u32 = 1;
    /// Failed ticks in a row before the safe stop.
    pub const MAX_CONSECUTIVE_ERRORS: u32 = 5;
    /// Velocity filter time constant \[ms\].
    pub const VELOCITY_FILTER_MS: f64 = 30.0;
    /// XM430-W350.
    pub const MODEL_NUMBER: u16 = 1020;
    /// Current unit of the XM430/XM540 \[mA\].
    pub const CURRENT_UNIT_MA: f64 = 2.69;
    /// Position unit, 360°/4096.
    pub const POSITION_UNIT_DEG: f64 = 0.087_890_625;
    /// Velocity unit [rev/min].
    pub const VELOCITY_UNIT_RPM: f64 = 0.229;
}

// ---------------------------------------------------------------------------------------
// The table as serde reads it.

type Num = Option<Spanned<f64>>;
type List = Option<Spanned<Vec<Spanned<f64>>>>;

/// The robot file as the hardware path reads it: the `[hardware]` table only (the rest is
/// the description's, and already checked).
#[derive(Deserialize)]
struct HardwareOfFile {
    hardware: RawHardware,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHardware {
    baud: Option<Spanned<i64>>,
    reply_timeout_ms: Num,
    retries: Option<Spanned<i64>>,
    max_consecutive_errors: Option<Spanned<i64>>,
    velocity: Option<RawVelocity>,
    velocity_filter_ms: Num,
    operating_mode: Option<Spanned<String>>,
    model_number: Option<Spanned<i64>>,
    current_unit_ma: Num,
    position_unit_deg: Num,
    velocity_unit_rpm: Num,
    set_point: List,
    safety: Option<Spanned<String>>,
    hold_correction: Option<Spanned<bool>>,
    module: Option<Spanned<Vec<RawModuleHardware>>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "lowercase")]
enum RawVelocity {
    Servo,
    Difference,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawModuleHardware {
    servo_ids: Spanned<Vec<Spanned<i64>>>,
    pulley_radius: Spanned<f64>,
    zero_angle_deg: Spanned<Vec<Spanned<f64>>>,
    zero_length: List,
    direction: Spanned<Vec<Spanned<i64>>>,
    actuator_gain: Spanned<RawGain>,
    tension_limits: Spanned<Vec<Spanned<f64>>>,
}

/// `actuator_gain` as written: one number for the module's three servos, or one per tendon.
enum RawGain {
    All(f64),
    Each(Vec<Spanned<f64>>),
}

impl<'de> Deserialize<'de> for RawGain {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct GainVisitor;
        impl<'de> Visitor<'de> for GainVisitor {
            type Value = RawGain;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number [N/mA] or an array of three numbers, one per tendon")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<RawGain, E> {
                Ok(RawGain::All(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<RawGain, E> {
                Ok(RawGain::All(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<RawGain, E> {
                Ok(RawGain::All(v as f64))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<RawGain, A::Error> {
                let mut each = Vec::new();
                while let Some(value) = seq.next_element::<Spanned<f64>>()? {
                    each.push(value);
                }
                Ok(RawGain::Each(each))
            }
        }
        deserializer.deserialize_any(GainVisitor)
    }
}

// ---------------------------------------------------------------------------------------
// Checking.

/// The hardware of `robot`, read from its `[hardware]` table and checked against its
/// modules; `None` when the file has no such table. Errors name the robot file, the line
/// and the field, as the description's do.
pub fn load(robot: &Robot) -> Result<Option<Hardware>, FileError> {
    let Some(table) = &robot.hardware else {
        return Ok(None);
    };
    let checker = TableChecker(table.checker(&robot.source));
    let file: HardwareOfFile = checker.deserialize()?;
    checker
        .hardware(&file.hardware, table, &robot.modules, robot.routing)
        .map(Some)
}

/// The description's [`Checker`] over the robot file, with the checks of this table.
struct TableChecker<'a>(Checker<'a>);

impl<'a> Deref for TableChecker<'a> {
    type Target = Checker<'a>;
    fn deref(&self) -> &Checker<'a> {
        &self.0
    }
}

impl TableChecker<'_> {
    /// Checks the `[hardware]` table against the robot's modules.
    fn hardware(
        &self,
        raw: &RawHardware,
        table: &HardwareTable,
        modules: &[Module],
        routing: Routing,
    ) -> Result<Hardware, FileError> {
        let baud = match &raw.baud {
            Some(v) => limits::check_baud(*v.get_ref())
                .map_err(|message| self.invalid(&v.span(), "hardware.baud", message))?,
            None => defaults::BAUD,
        };
        let number = |v: &Num, field: &str, limit: &Limit, default: f64| {
            v.as_ref()
                .map_or(Ok(default), |v| self.within(v, field, limit))
        };
        let reply_timeout = number(
            &raw.reply_timeout_ms,
            "hardware.reply_timeout_ms",
            &limits::REPLY_TIMEOUT_MS,
            defaults::REPLY_TIMEOUT_MS,
        )? / 1000.0;
        let velocity_filter = number(
            &raw.velocity_filter_ms,
            "hardware.velocity_filter_ms",
            &limits::VELOCITY_FILTER_MS,
            defaults::VELOCITY_FILTER_MS,
        )? / 1000.0;
        // The limits fit the types: counts ≤ 1000, model numbers ≤ 65535 (tested).
        let count = |v: &Option<Spanned<i64>>, field: &str, limit: &Limit, default: u32| {
            v.as_ref().map_or(Ok(default), |v| {
                Ok(self
                    .integer_within(v, field, limit)?
                    .clamp(0, i64::from(u32::MAX)) as u32)
            })
        };
        let retries = count(
            &raw.retries,
            "hardware.retries",
            &limits::RETRIES,
            defaults::RETRIES,
        )?;
        let max_consecutive_errors = count(
            &raw.max_consecutive_errors,
            "hardware.max_consecutive_errors",
            &limits::MAX_CONSECUTIVE_ERRORS,
            defaults::MAX_CONSECUTIVE_ERRORS,
        )?;
        let model_number = count(
            &raw.model_number,
            "hardware.model_number",
            &limits::MODEL_NUMBER,
            u32::from(defaults::MODEL_NUMBER),
        )?
        .min(u32::from(u16::MAX)) as u16;
        let current_unit = number(
            &raw.current_unit_ma,
            "hardware.current_unit_ma",
            &limits::CURRENT_UNIT_MA,
            defaults::CURRENT_UNIT_MA,
        )?;
        let position_unit = number(
            &raw.position_unit_deg,
            "hardware.position_unit_deg",
            &limits::POSITION_UNIT_DEG,
            defaults::POSITION_UNIT_DEG,
        )?;
        let velocity_unit = number(
            &raw.velocity_unit_rpm,
            "hardware.velocity_unit_rpm",
            &limits::VELOCITY_UNIT_RPM,
            defaults::VELOCITY_UNIT_RPM,
        )?;
        if let Some(mode) = &raw.operating_mode
            && mode.get_ref() != "current"
        {
            return Err(self.invalid(
                &mode.span(),
                "hardware.operating_mode",
                format!(
                    "`{}` is not supported; the hardware path commands tensions through the \
                     servos' current control (`operating_mode = \"current\"`)",
                    mode.get_ref()
                ),
            ));
        }
        let nq = 3 * modules.len();
        let set_point = match &raw.set_point {
            Some(v) => {
                let values = self.finite_list(v.get_ref(), "hardware.set_point")?;
                if values.len() != nq {
                    return Err(self.invalid(
                        &v.span(),
                        "hardware.set_point",
                        format!(
                            "has {} entries, the robot has {nq} coordinates (Δx, Δy, δL per module)",
                            values.len()
                        ),
                    ));
                }
                let problem = domain::modules_coordinates_problem(modules, &values);
                self.state(problem, v, "hardware.set_point")?;
                values
            }
            None => vec![0.0; nq],
        };
        if routing != Routing::Local {
            return Err(self.invalid(
                &table.span,
                "hardware",
                "the hardware path supports `routing = \"local\"` only (each module's tendons \
                 anchored at its own plates)"
                    .into(),
            ));
        }
        let Some(tables) = &raw.module else {
            return Err(self.invalid(
                &table.span,
                "hardware.module",
                format!(
                    "give one [[hardware.module]] table per module ({})",
                    modules.len()
                ),
            ));
        };
        if tables.get_ref().len() != modules.len() {
            return Err(self.invalid(
                &tables.span(),
                "hardware.module",
                format!(
                    "has {} tables, the robot has {} modules; give one per module, base first",
                    tables.get_ref().len(),
                    modules.len()
                ),
            ));
        }
        let mut seen: Vec<(u8, String)> = Vec::new();
        let mut out = Vec::with_capacity(modules.len());
        for (i, (raw, module)) in tables.get_ref().iter().zip(modules).enumerate() {
            let prefix = format!("hardware.module[{}]", i + 1);
            let hardware = self.module_hardware(raw, module, &prefix)?;
            for (k, id) in hardware.servo_ids.iter().enumerate() {
                if let Some((_, other)) = seen.iter().find(|(s, _)| s == id) {
                    return Err(self.invalid(
                        &raw.servo_ids.get_ref()[k].span(),
                        &format!("{prefix}.servo_ids"),
                        format!("servo ID {id} is already used by {other}; IDs must be unique"),
                    ));
                }
                seen.push((*id, format!("{prefix} tendon {}", k + 1)));
            }
            out.push(hardware);
        }
        Ok(Hardware {
            baud,
            reply_timeout,
            retries,
            max_consecutive_errors,
            velocity_source: match raw.velocity {
                None | Some(RawVelocity::Servo) => VelocitySource::Servo,
                Some(RawVelocity::Difference) => VelocitySource::Difference,
            },
            velocity_filter,
            model_number,
            current_unit,
            position_unit,
            velocity_unit,
            set_point,
            safety: match (&raw.safety, &raw.hold_correction) {
                (Some(_), Some(old)) => {
                    return Err(self.invalid(
                        &old.span(),
                        "hardware.hold_correction",
                        "give either `safety` or the older `hold_correction`, not both".to_string(),
                    ));
                }
                (Some(name), None) => Some(
                    SafetyMode::parse(name.get_ref())
                        .map_err(|m| self.invalid(&name.span(), "hardware.safety", m))?,
                ),
                (None, Some(old)) => Some(if *old.get_ref() {
                    SafetyMode::HoldCorrection
                } else {
                    SafetyMode::Paper
                }),
                (None, None) => None,
            },
            modules: out,
        })
    }

    fn module_hardware(
        &self,
        raw: &RawModuleHardware,
        module: &Module,
        prefix: &str,
    ) -> Result<ModuleHardware, FileError> {
        let field = |name: &str| format!("{prefix}.{name}");
        if module.tendon_angles.len() != 3 {
            return Err(self.invalid(
                &raw.servo_ids.span(),
                &field("servo_ids"),
                format!(
                    "the module has {} tendons; the hardware path needs exactly 3 per module",
                    module.tendon_angles.len()
                ),
            ));
        }
        let three_of = |len: usize, span: &Range<usize>, name: &str, what: &str| {
            if len == 3 {
                Ok(())
            } else {
                Err(self.invalid(
                    span,
                    &field(name),
                    format!("needs 3 {what} (one per tendon), got {len} entries"),
                ))
            }
        };
        let ids = raw.servo_ids.get_ref();
        three_of(ids.len(), &raw.servo_ids.span(), "servo_ids", "servo IDs")?;
        let mut servo_ids = [0u8; 3];
        for (slot, id) in servo_ids.iter_mut().zip(ids) {
            let id = self.integer_within(id, &field("servo_ids"), &limits::SERVO_ID)?;
            *slot = u8::try_from(id).unwrap_or(u8::MAX);
        }
        let pulley_radius = self.within(
            &raw.pulley_radius,
            &field("pulley_radius"),
            &limits::PULLEY_RADIUS_M,
        )?;
        let angles = self.list_within(
            raw.zero_angle_deg.get_ref(),
            &field("zero_angle_deg"),
            &limits::ZERO_ANGLE_DEG,
        )?;
        three_of(
            angles.len(),
            &raw.zero_angle_deg.span(),
            "zero_angle_deg",
            "angles",
        )?;
        let zero_angles = [
            angles[0].to_radians(),
            angles[1].to_radians(),
            angles[2].to_radians(),
        ];
        let zero_lengths = match &raw.zero_length {
            Some(v) => {
                let values =
                    self.list_within(v.get_ref(), &field("zero_length"), &ranges::LENGTH_M)?;
                three_of(values.len(), &v.span(), "zero_length", "lengths")?;
                [values[0], values[1], values[2]]
            }
            None => [module.rest_length; 3],
        };
        let signs = raw.direction.get_ref();
        three_of(signs.len(), &raw.direction.span(), "direction", "signs")?;
        let mut directions = [0.0; 3];
        for (slot, sign) in directions.iter_mut().zip(signs) {
            *slot = match *sign.get_ref() {
                1 => 1.0,
                -1 => -1.0,
                other => {
                    return Err(self.invalid(
                        &sign.span(),
                        &field("direction"),
                        format!("each sign must be 1 or -1, got {other}"),
                    ));
                }
            };
        }
        let gain_field = field("actuator_gain");
        let actuator_gain = match raw.actuator_gain.get_ref() {
            RawGain::All(g) => {
                [self.limited(
                    *g,
                    &raw.actuator_gain.span(),
                    &gain_field,
                    "",
                    &limits::ACTUATOR_GAIN_N_PER_MA,
                )?; 3]
            }
            RawGain::Each(each) => {
                let gains = self.list_within(each, &gain_field, &limits::ACTUATOR_GAIN_N_PER_MA)?;
                <[f64; 3]>::try_from(gains.as_slice()).map_err(|_| {
                    self.invalid(
                        &raw.actuator_gain.span(),
                        &gain_field,
                        format!(
                            "has {} entries; give one gain per tendon (3), or a single number \
                             for all three",
                            gains.len()
                        ),
                    )
                })?
            }
        };
        let tensions = self.list_within(
            raw.tension_limits.get_ref(),
            &field("tension_limits"),
            &limits::TENSION_N,
        )?;
        let [f_min, f_max] = <[f64; 2]>::try_from(tensions.as_slice())
            .ok()
            .filter(|[low, high]| low < high)
            .ok_or_else(|| {
                self.invalid(
                    &raw.tension_limits.span(),
                    &field("tension_limits"),
                    format!("needs [f_min, f_max] with 0 ≤ f_min < f_max in N, got {tensions:?}"),
                )
            })?;
        Ok(ModuleHardware {
            servo_ids,
            pulley_radius,
            zero_angles,
            zero_lengths,
            directions,
            actuator_gain,
            tension_limits: [f_min, f_max],
        })
    }
}

impl Hardware {
    /// Every servo ID, module by module, tendon by tendon (the bus order).
    pub fn servo_ids(&self) -> Vec<u8> {
        self.modules.iter().flat_map(|m| m.servo_ids).collect()
    }

    /// The Baud Rate register value (0..=7) of [`Hardware::baud`].
    pub fn baud_register(&self) -> u8 {
        limits::baud_register(self.baud).unwrap_or(3)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    const EXAMPLE: &str = include_str!("../../../../robots/hardware-example.toml");

    /// The hardware of a robot file's text.
    fn hardware_of(text: &str, path: &str) -> Result<Hardware, FileError> {
        let robot = Robot::parse(text, Path::new(path))?;
        Ok(load(&robot)?.expect("the text has a [hardware] table"))
    }

    /// A one-module robot with `hardware` appended after `[hardware]`.
    fn parse(hardware: &str) -> Result<Hardware, FileError> {
        hardware_of(
            &format!("[[module]]\n[hardware]\n{hardware}"),
            "robots/x.toml",
        )
    }

    const MODULE: &str = "[[hardware.module]]\nservo_ids = [1, 2, 3]\npulley_radius = 0.02\n\
                          zero_angle_deg = [180, 180, 180]\ndirection = [1, -1, 1]\n\
                          actuator_gain = 0.08\ntension_limits = [0.2, 40]\n";

    /// Asserts that `hardware` fails validation at `line` on `field`, with `fragment` in the
    /// message.
    #[track_caller]
    fn assert_invalid(hardware: &str, line: usize, field: &str, fragment: &str) {
        match parse(hardware) {
            Err(FileError::Invalid {
                line: l,
                field: f,
                message,
                ..
            }) => {
                assert_eq!((l, f.as_str()), (line, field), "message: {message}");
                assert!(message.contains(fragment), "`{message}` lacks `{fragment}`");
            }
            other => panic!("expected an Invalid error on {field}, got {other:?}"),
        }
    }

    #[test]
    fn example_file_parses_with_its_values() {
        let robot = Robot::parse(EXAMPLE, Path::new("robots/hardware-example.toml")).unwrap();
        let hw = load(&robot)
            .unwrap()
            .expect("the example has a [hardware] table");
        assert_eq!(hw.baud, 1_000_000);
        assert_eq!(hw.baud_register(), 3);
        assert_eq!(hw.servo_ids(), vec![1, 2, 3, 4, 5, 6]);
        assert_eq!(hw.set_point, vec![0.0, 0.0, -0.04, 0.0, -0.065, 0.0]);
        assert_eq!(hw.velocity_source, VelocitySource::Servo);
        assert!((hw.reply_timeout - 0.010).abs() < 1e-15);
        assert_eq!(hw.modules[0].directions, [1.0, -1.0, 1.0]);
        assert_eq!(hw.modules[1].directions, [1.0, 1.0, -1.0]);
        assert!((hw.modules[0].zero_angles[0] - std::f64::consts::PI).abs() < 1e-15);
        // The zero length defaults to the module's rest length.
        assert_eq!(hw.modules[1].zero_lengths, [0.06; 3]);
        // The paper's modules, with elongation and bend limits written for each.
        let structure = robot.structure();
        assert_eq!(
            (&structure.corners, &structure.tendons),
            (&vec![6, 6], &vec![3, 3])
        );
        assert!(
            robot
                .limits
                .iter()
                .all(|l| l.written.elongation && l.written.bend)
        );
    }

    #[test]
    fn defaults_fill_the_optional_fields() {
        let hw = parse(MODULE).unwrap();
        assert_eq!(hw.baud, defaults::BAUD);
        assert_eq!(hw.retries, defaults::RETRIES);
        assert_eq!(hw.max_consecutive_errors, defaults::MAX_CONSECUTIVE_ERRORS);
        assert_eq!(hw.model_number, 1020);
        assert_eq!(hw.set_point, vec![0.0; 3]);
        assert_eq!(hw.current_unit, 2.69);
        assert!((hw.velocity_filter - 0.03).abs() < 1e-15);
        assert_eq!(hw.modules[0].zero_lengths, [0.1; 3]);
        let robot = Robot::parse("[[module]]\n", Path::new("x.toml")).unwrap();
        assert!(robot.hardware.is_none());
        assert_eq!(load(&robot).unwrap(), None);
    }

    #[test]
    fn values_are_checked_with_file_line_and_field() {
        assert_invalid(
            &format!("baud = 1234\n{MODULE}"),
            3,
            "hardware.baud",
            "not an X-series baud rate",
        );
        assert_invalid(
            &format!("reply_timeout_ms = 0\n{MODULE}"),
            3,
            "hardware.reply_timeout_ms",
            "must be > 0 and ≤ 1000 ms, got 0",
        );
        // Accepted before the ranges, and a panic converting to a Duration later.
        assert_invalid(
            &format!("reply_timeout_ms = 1e300\n{MODULE}"),
            3,
            "hardware.reply_timeout_ms",
            "must be > 0 and ≤ 1000 ms, got 1e300",
        );
        assert_invalid(
            &format!("max_consecutive_errors = 0\n{MODULE}"),
            3,
            "hardware.max_consecutive_errors",
            "1..=1000",
        );
        assert_invalid(
            &format!("operating_mode = \"pwm\"\n{MODULE}"),
            3,
            "hardware.operating_mode",
            "`pwm` is not supported",
        );
        assert!(parse(&format!("operating_mode = \"current\"\n{MODULE}")).is_ok());
        assert_invalid(
            &format!("set_point = [0, 0]\n{MODULE}"),
            3,
            "hardware.set_point",
            "has 2 entries, the robot has 3",
        );
        let module = |from: &str, to: &str| MODULE.replace(from, to);
        // MODULE starts on line 3: servo_ids line 4, pulley 5, zero angles 6, direction 7,
        // gain 8, limits 9.
        assert_invalid(
            &module("[1, 2, 3]", "[1, 2, 253]"),
            4,
            "hardware.module[1].servo_ids",
            "0..=252, got 253",
        );
        assert_invalid(
            &module("[1, 2, 3]", "[1, 2, 2]"),
            4,
            "hardware.module[1].servo_ids",
            "servo ID 2 is already used",
        );
        assert_invalid(
            &module("[1, 2, 3]", "[1, 2]"),
            4,
            "hardware.module[1].servo_ids",
            "needs 3 servo IDs",
        );
        assert_invalid(
            &module("0.02", "-0.02"),
            5,
            "hardware.module[1].pulley_radius",
            "must be ≥ 0.0001 and ≤ 1 m, got -0.02",
        );
        assert_invalid(
            &module("[180, 180, 180]", "[180, nan, 180]"),
            6,
            "hardware.module[1].zero_angle_deg",
            "entry 2",
        );
        assert_invalid(
            &module("[1, -1, 1]", "[1, 0, 1]"),
            7,
            "hardware.module[1].direction",
            "1 or -1, got 0",
        );
        assert_invalid(
            &module("0.08", "0"),
            8,
            "hardware.module[1].actuator_gain",
            "must be ≥ 1e-6 and ≤ 100 N/mA, got 0",
        );
        assert_invalid(
            &module("[0.2, 40]", "[40, 0.2]"),
            9,
            "hardware.module[1].tension_limits",
            "f_min < f_max",
        );
        assert_invalid(
            &module("[0.2, 40]", "[-1, 40]"),
            9,
            "hardware.module[1].tension_limits",
            "entry 1 must be ≥ 0 and ≤ 100000 N, got -1",
        );
        assert_invalid(
            &module("[0.2, 40]", "[0.2, 1e300]"),
            9,
            "hardware.module[1].tension_limits",
            "entry 2 must be ≥ 0 and ≤ 100000 N, got 1e300",
        );
        assert_invalid(
            &module("[0.2, 40]", "[0.2, 40, 50]"),
            9,
            "hardware.module[1].tension_limits",
            "f_min < f_max",
        );
        assert_invalid(
            "baud = 57600\n",
            2,
            "hardware.module",
            "one [[hardware.module]] table per module",
        );
        assert_invalid(
            &format!("{MODULE}{MODULE}"),
            3,
            "hardware.module",
            "has 2 tables, the robot has 1 modules",
        );
    }

    /// Every number of the table outside its physical range, with the message's range
    /// written out by hand.
    #[test]
    fn numbers_lie_in_their_physical_ranges() {
        for (line, field, fragment) in [
            (
                "retries = 1001",
                "retries",
                "an integer in 0..=1000, got 1001",
            ),
            ("retries = -1", "retries", "got -1"),
            (
                "max_consecutive_errors = 9223372036854775807",
                "max_consecutive_errors",
                "an integer in 1..=1000, got 9223372036854775807",
            ),
            (
                "velocity_filter_ms = 1e300",
                "velocity_filter_ms",
                "must be > 0 and ≤ 1000 ms, got 1e300",
            ),
            ("velocity_filter_ms = 0", "velocity_filter_ms", "got 0"),
            (
                "model_number = 65536",
                "model_number",
                "an integer in 0..=65535, got 65536",
            ),
            (
                "current_unit_ma = 1e-300",
                "current_unit_ma",
                "must be ≥ 0.001 and ≤ 100 mA, got 1e-300",
            ),
            (
                "position_unit_deg = 361",
                "position_unit_deg",
                "must be ≥ 0.0001 and ≤ 360°, got 361",
            ),
            (
                "velocity_unit_rpm = -nan",
                "velocity_unit_rpm",
                "must be a finite number ≥ 0.0001 and ≤ 100 rev/min, got NaN",
            ),
            ("baud = -1", "baud", "not an X-series baud rate"),
        ] {
            assert_invalid(
                &format!("{line}\n{MODULE}"),
                3,
                &format!("hardware.{field}"),
                fragment,
            );
        }
        let module = |from: &str, to: &str| MODULE.replace(from, to);
        assert_invalid(
            &module("0.02", "1e300"),
            5,
            "hardware.module[1].pulley_radius",
            "≤ 1 m, got 1e300",
        );
        assert_invalid(
            &module("[180, 180, 180]", "[180, 180, 1e300]"),
            6,
            "hardware.module[1].zero_angle_deg",
            "entry 3 must be ≥ -36000 and ≤ 36000°, got 1e300",
        );
        assert_invalid(
            &format!("{MODULE}zero_length = [0.1, 0, 0.1]\n"),
            10,
            "hardware.module[1].zero_length",
            "entry 2 must be ≥ 0.0001 and ≤ 10 m, got 0",
        );
        assert_invalid(
            &module("0.08", "1e308"),
            8,
            "hardware.module[1].actuator_gain",
            "≤ 100 N/mA, got 1e308",
        );
        // The bounds themselves are accepted.
        let hw = parse(&format!(
            "reply_timeout_ms = 1000\nvelocity_filter_ms = 1000\nretries = 1000\n\
             max_consecutive_errors = 1000\nmodel_number = 65535\ncurrent_unit_ma = 100\n\
             position_unit_deg = 360\nvelocity_unit_rpm = 0.0001\n{}",
            module("[0.2, 40]", "[0, 1e5]").replace("0.02", "1")
        ))
        .unwrap();
        assert_eq!(hw.reply_timeout, 1.0);
        assert_eq!((hw.retries, hw.max_consecutive_errors), (1000, 1000));
        assert_eq!(hw.model_number, 65535);
        assert_eq!(hw.modules[0].tension_limits, [0.0, 1e5]);
        assert_eq!(hw.modules[0].pulley_radius, 1.0);
    }

    /// The set point lies in the state domain of the robot: bends of at most 1.5π, a
    /// positive backbone length, elongations of at most ten rest lengths (the default
    /// module: `d` = 0.04 m, `L0` = 0.1 m).
    #[test]
    fn set_point_lies_in_the_state_domain() {
        assert_invalid(
            &format!("set_point = [1e308, 0, 0]\n{MODULE}"),
            3,
            "hardware.set_point",
            "module 1 bends by",
        );
        assert_invalid(
            &format!("set_point = [0,\n 0,\n 1.5]\n{MODULE}"),
            5,
            "hardware.set_point",
            "entry 3 (δL of module 1) is 1.5e0 m; δL must be ≤ 1 m",
        );
        assert_invalid(
            &format!("set_point = [0,\n 0,\n -0.15]\n{MODULE}"),
            5,
            "hardware.set_point",
            "entry 3 (δL of module 1) is -0.15 m: the backbone length L0 + δL = -0.05",
        );
        assert_invalid(
            &format!("set_point = [0, inf, 0]\n{MODULE}"),
            3,
            "hardware.set_point",
            "entry 2 must be a finite number, got inf",
        );
        // 1.5π·0.04 m = 0.1885 m of bend is allowed (√(0.108² + 0.144²) = 0.18), 0.192 m
        // is not.
        assert!(parse(&format!("set_point = [0.108, 0.144, 1.0]\n{MODULE}")).is_ok());
        assert_invalid(
            &format!("set_point = [0.12, 0.15, 0]\n{MODULE}"),
            3,
            "hardware.set_point",
            "more than three quarters of a turn",
        );
    }

    #[test]
    fn unknown_and_mistyped_fields_are_syntax_errors() {
        let error = parse(&format!("baud_rate = 57600\n{MODULE}")).unwrap_err();
        let text = error.to_string();
        assert!(
            text.starts_with(
                "robots/x.toml:3:1: field `hardware.baud_rate`: unknown field `baud_rate`"
            ),
            "{text}"
        );
        let error = parse(&MODULE.replace("pulley_radius", "pully_radius")).unwrap_err();
        let text = error.to_string();
        assert!(
            text.contains("field `hardware.module[1].pully_radius`: unknown field `pully_radius`"),
            "{text}"
        );
        let error = parse(&format!("velocity = \"guess\"\n{MODULE}")).unwrap_err();
        assert!(
            error
                .to_string()
                .contains("expected `servo` or `difference`"),
            "{error}"
        );
    }

    /// `actuator_gain`: one number for the three servos, or one per tendon in the order of
    /// `tendon_angles_deg`, each in 1e-6..=100 N/mA; MODULE's gain is on line 8.
    #[test]
    fn actuator_gain_is_one_number_or_one_per_tendon() {
        let module = |gain: &str| MODULE.replace("actuator_gain = 0.08", gain);
        assert_eq!(parse(MODULE).unwrap().modules[0].actuator_gain, [0.08; 3]);
        let hw = parse(&module("actuator_gain = [0.03, 0.052, 5]")).unwrap();
        assert_eq!(hw.modules[0].actuator_gain, [0.03, 0.052, 5.0]);
        // Integers are numbers too.
        let hw = parse(&module("actuator_gain = [1, 2, 3]")).unwrap();
        assert_eq!(hw.modules[0].actuator_gain, [1.0, 2.0, 3.0]);
        // A bad entry is named with its place, on its own line.
        assert_invalid(
            &module("actuator_gain = [0.04,\n 0,\n 0.04]"),
            9,
            "hardware.module[1].actuator_gain",
            "entry 2 must be ≥ 1e-6 and ≤ 100 N/mA, got 0",
        );
        assert_invalid(
            &module("actuator_gain = [0.04, 0.04, 101]"),
            8,
            "hardware.module[1].actuator_gain",
            "entry 3 must be ≥ 1e-6 and ≤ 100 N/mA, got 101",
        );
        assert_invalid(
            &module("actuator_gain = [0.04, nan, 0.04]"),
            8,
            "hardware.module[1].actuator_gain",
            "entry 2 must be a finite number",
        );
        for (gains, n) in [
            ("[0.04, 0.04]", 2),
            ("[0.04, 0.04, 0.04, 0.04]", 4),
            ("[]", 0),
        ] {
            assert_invalid(
                &module(&format!("actuator_gain = {gains}")),
                8,
                "hardware.module[1].actuator_gain",
                &format!("has {n} entries; give one gain per tendon (3)"),
            );
        }
        // The second module's gains are its own.
        let second = MODULE
            .replace("[1, 2, 3]", "[4, 5, 6]")
            .replace("actuator_gain = 0.08", "actuator_gain = [0.01, 0.02, 0.03]");
        let text = format!("[[module]]\n[[module]]\n[hardware]\n{MODULE}{second}");
        let hw = hardware_of(&text, "robots/x.toml").unwrap();
        assert_eq!(hw.modules[0].actuator_gain, [0.08; 3]);
        assert_eq!(hw.modules[1].actuator_gain, [0.01, 0.02, 0.03]);
        let bad = second.replace("0.02, 0.03]", "0.02, -1]");
        let error = hardware_of(
            &format!("[[module]]\n[[module]]\n[hardware]\n{MODULE}{bad}"),
            "robots/x.toml",
        )
        .unwrap_err();
        assert_eq!(
            error.to_string(),
            "robots/x.toml:16: field `hardware.module[2].actuator_gain`: entry 3 must be ≥ \
             1e-6 and ≤ 100 N/mA, got -1"
        );
        // Neither a number nor an array of numbers.
        for gains in ["\"0.04\"", "[0.04, \"x\", 0.04]", "[[0.04], 0.04, 0.04]"] {
            let error = parse(&module(&format!("actuator_gain = {gains}"))).unwrap_err();
            let text = error.to_string();
            assert!(
                text.contains("robots/x.toml:8:") && text.contains("actuator_gain"),
                "{text}"
            );
        }
    }

    #[test]
    fn through_routing_and_four_tendons_are_refused() {
        let text = format!("routing = \"through\"\n[[module]]\n[hardware]\n{MODULE}");
        let error = hardware_of(&text, "x.toml").unwrap_err();
        assert!(
            error.to_string().contains("`routing = \"local\"` only"),
            "{error}"
        );
        let text =
            format!("[[module]]\ntendon_angles_deg = [0, 90, 180, 270]\n[hardware]\n{MODULE}");
        let error = hardware_of(&text, "x.toml").unwrap_err();
        assert!(
            error.to_string().contains("exactly 3 per module"),
            "{error}"
        );
    }
    #[test]
    fn a_missing_module_field_names_the_module() {
        // Every required field of [[hardware.module]], left out of the second module: the
        // error names the module and the field, at that table's header (line 12).
        for field in [
            "servo_ids",
            "pulley_radius",
            "zero_angle_deg",
            "direction",
            "actuator_gain",
            "tension_limits",
        ] {
            let second: String = MODULE
                .replace("[1, 2, 3]", "[4, 5, 6]")
                .lines()
                .filter(|line| !line.starts_with(field))
                .map(|line| format!("{line}\n"))
                .collect();
            let text =
                format!("[[module]]\n[[module]]\n[hardware]\nbaud = 57600\n{MODULE}{second}");
            let error = hardware_of(&text, "robots/x.toml").unwrap_err();
            assert_eq!(
                error.to_string(),
                format!(
                    "robots/x.toml:12:1: field `hardware.module[2].{field}`: missing; every \
                     [[hardware.module]] table must give it"
                )
            );
        }
        // The optional `zero_length` may be left out.
        assert!(parse(MODULE).is_ok());
    }
}
