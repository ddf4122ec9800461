//! Scenario files (`scenarios/*.toml`): what `softcbf simulate` runs — robot, initial
//! state, reference, gains, control period, duration, filter, integrator tolerances.
//!
//! Parsing follows the robot files: serde reads values with their spans, then every value is
//! checked, and sizes are checked against the robot once it is known
//! ([`ScenarioFile::resolve`]); every error names the file, the line and the field. The
//! format is documented in `scenarios/README.md`.

use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use softcbf_codegen::toml_file::{Checker, FileError, Rule};
use toml::Spanned;

use crate::control::ControllerSettings;
use crate::integrator::Tolerances;
use crate::model::Model;
use crate::qp::QpSettings;
use crate::reference::ReferenceSpec;

/// Text of `scenarios/paper-sim.toml`, compiled in as the default scenario.
pub const PAPER_SIM_SCENARIO: &str = include_str!("../../scenarios/paper-sim.toml");

/// A scenario ready to run against a model.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Name (defaults to the file stem).
    pub name: String,
    /// Initial `q` \[m\].
    pub initial_q: Vec<f64>,
    /// Initial `q̇` \[m/s\].
    pub initial_qd: Vec<f64>,
    /// What the nominal controller tracks.
    pub reference: ReferenceSpec,
    /// Gains, barrier gains, filter and QP settings.
    pub controller: ControllerSettings,
    /// Control period \[s\].
    pub control_period: f64,
    /// Simulated time \[s\].
    pub duration: f64,
    /// Also run plain PD+ for comparison.
    pub compare: bool,
    /// Integrator tolerances between ticks.
    pub tolerances: Tolerances,
}

/// A parsed scenario file whose sizes are not yet checked against a robot.
#[derive(Clone, Debug)]
pub struct ScenarioFile {
    text: String,
    path: PathBuf,
    raw: RawScenario,
}

/// A gain: a number (times the identity), a list (the diagonal) or a matrix (rows).
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
enum RawGain {
    Scalar(f64),
    Diagonal(Vec<f64>),
    Matrix(Vec<Vec<f64>>),
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    robot: Option<Spanned<String>>,
    duration: Option<Spanned<f64>>,
    control_period: Option<Spanned<f64>>,
    filter: Option<bool>,
    hold_correction: Option<bool>,
    compare: Option<bool>,
    #[serde(default)]
    initial: RawInitial,
    reference: Option<Spanned<RawReference>>,
    #[serde(default)]
    gains: RawGains,
    #[serde(default)]
    integrator: RawIntegrator,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInitial {
    q: Option<Spanned<Vec<f64>>>,
    qd: Option<Spanned<Vec<f64>>>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReference {
    set_point: Option<Spanned<Vec<f64>>>,
    waypoints: Option<Spanned<Vec<Spanned<RawWaypoint>>>>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWaypoint {
    t: f64,
    q: Vec<f64>,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGains {
    kp: Option<Spanned<RawGain>>,
    kd: Option<Spanned<RawGain>>,
    p1: Option<Spanned<f64>>,
    p2: Option<Spanned<f64>>,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawIntegrator {
    rtol: Option<Spanned<f64>>,
    atol: Option<Spanned<f64>>,
    h_initial: Option<Spanned<f64>>,
    max_steps: Option<Spanned<i64>>,
}

/// Default control period \[s\] (the paper's simulation ticks at 1 kHz).
pub const DEFAULT_CONTROL_PERIOD: f64 = 1e-3;
/// Default duration \[s\].
pub const DEFAULT_DURATION: f64 = 10.0;
/// The paper's gains: `K_P = 5·I` \[N/m\], `K_D = 1·I` \[N·s/m\].
pub const PAPER_GAINS: (f64, f64) = (5.0, 1.0);
/// Most ticks a scenario may ask for (a guard against typos such as `duration = 1e9`).
pub const MAX_TICKS: f64 = 1e8;

impl ScenarioFile {
    /// Reads a scenario file.
    pub fn load(path: &Path) -> Result<ScenarioFile, FileError> {
        let text = softcbf_codegen::toml_file::read(path, "scenario file")?;
        ScenarioFile::parse(&text, path)
    }

    /// The embedded paper scenario.
    pub fn paper_sim() -> ScenarioFile {
        ScenarioFile::parse(
            PAPER_SIM_SCENARIO,
            Path::new("<embedded scenarios/paper-sim.toml>"),
        )
        .expect("the embedded scenarios/paper-sim.toml is valid (tested)")
    }

    /// Parses scenario text; `path` names it in messages and anchors a relative `robot`.
    pub fn parse(text: &str, path: &Path) -> Result<ScenarioFile, FileError> {
        let checker = Checker { text, path };
        let raw: RawScenario = toml::from_str(text).map_err(|e| checker.syntax(&e))?;
        Ok(ScenarioFile {
            text: text.to_string(),
            path: path.to_path_buf(),
            raw,
        })
    }

    /// The file this scenario was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The robot file the scenario names, relative paths taken from the scenario's folder
    /// (`None`: the embedded paper robot).
    pub fn robot_path(&self) -> Option<PathBuf> {
        let robot = self.raw.robot.as_ref()?;
        let given = Path::new(robot.get_ref());
        Some(if given.is_absolute() {
            given.to_path_buf()
        } else {
            self.path.parent().unwrap_or(Path::new(".")).join(given)
        })
    }

    /// Checks every value and every size against `model` and builds the scenario.
    pub fn resolve(&self, model: &Model) -> Result<Scenario, FileError> {
        let c = Checker {
            text: &self.text,
            path: &self.path,
        };
        let raw = &self.raw;
        let nq = model.nq();
        let positive = |v: &Option<Spanned<f64>>, field: &str, default: f64, unit: &str| {
            v.as_ref()
                .map_or(Ok(default), |v| c.number(v, field, Rule::Positive, unit))
        };
        let control_period = positive(
            &raw.control_period,
            "control_period",
            DEFAULT_CONTROL_PERIOD,
            "s",
        )?;
        let duration = positive(&raw.duration, "duration", DEFAULT_DURATION, "s")?;
        if duration / control_period > MAX_TICKS {
            let span = raw.duration.as_ref().map_or(0..0, Spanned::span);
            return Err(c.invalid(
                &span,
                "duration",
                format!(
                    "{duration} s at a period of {control_period} s is {:.1e} ticks, more than {MAX_TICKS:.0e}",
                    duration / control_period
                ),
            ));
        }

        let zeros = vec![0.0; nq];
        let vector = |v: &Option<Spanned<Vec<f64>>>, field: &str, unit: &str| match v {
            Some(v) => sized(&c, v.get_ref(), &v.span(), field, nq, unit),
            None => Ok(zeros.clone()),
        };
        let initial_q = vector(&raw.initial.q, "initial.q", "m")?;
        let initial_qd = vector(&raw.initial.qd, "initial.qd", "m/s")?;

        let reference = self.reference(&c, nq)?;

        let (kp_default, kd_default) = PAPER_GAINS;
        let kp = gain(&c, raw.gains.kp.as_ref(), "gains.kp", nq, kp_default)?;
        let kd = gain(&c, raw.gains.kd.as_ref(), "gains.kd", nq, kd_default)?;
        let [p1_default, p2_default] = model.robot.barrier_gains;
        let p1 = positive(&raw.gains.p1, "gains.p1", p1_default, "1/s")?;
        let p2 = positive(&raw.gains.p2, "gains.p2", p2_default, "1/s")?;

        let mut tolerances = Tolerances::default();
        let integrator = &raw.integrator;
        tolerances.rtol = positive(&integrator.rtol, "integrator.rtol", tolerances.rtol, "")?;
        tolerances.atol = positive(&integrator.atol, "integrator.atol", tolerances.atol, "")?;
        tolerances.h_initial = positive(
            &integrator.h_initial,
            "integrator.h_initial",
            tolerances.h_initial,
            "s",
        )?;
        if let Some(max_steps) = &integrator.max_steps {
            let value = *max_steps.get_ref();
            tolerances.max_steps =
                usize::try_from(value)
                    .ok()
                    .filter(|&n| n >= 1)
                    .ok_or_else(|| {
                        c.invalid(
                            &max_steps.span(),
                            "integrator.max_steps",
                            format!("must be an integer ≥ 1, got {value}"),
                        )
                    })?;
        }
        tolerances.h_max = control_period;
        tolerances.h_initial = tolerances.h_initial.min(control_period);
        if let Err(error) = tolerances.validate() {
            let span = integrator.h_initial.as_ref().map_or(0..0, Spanned::span);
            return Err(c.invalid(&span, "integrator", error.to_string()));
        }

        let name = raw.name.clone().unwrap_or_else(|| {
            self.path.file_stem().map_or_else(
                || "scenario".to_string(),
                |s| s.to_string_lossy().into_owned(),
            )
        });
        Ok(Scenario {
            name,
            initial_q,
            initial_qd,
            reference,
            controller: ControllerSettings {
                kp,
                kd,
                barrier_gains: [p1, p2],
                filter: raw.filter.unwrap_or(true),
                hold_correction: if raw.hold_correction.unwrap_or(false) {
                    control_period
                } else {
                    0.0
                },
                input_limits: (Vec::new(), Vec::new()),
                qp: QpSettings::default(),
            },
            control_period,
            duration,
            compare: raw.compare.unwrap_or(false),
            tolerances,
        })
    }

    fn reference(&self, c: &Checker<'_>, nq: usize) -> Result<ReferenceSpec, FileError> {
        let Some(reference) = &self.raw.reference else {
            return Err(c.invalid(
                &(0..0),
                "reference",
                "missing: add a [reference] table with `set_point = [...]` or `waypoints`".into(),
            ));
        };
        let span = reference.span();
        match (
            &reference.get_ref().set_point,
            &reference.get_ref().waypoints,
        ) {
            (Some(point), None) => Ok(ReferenceSpec::SetPoint(sized(
                c,
                point.get_ref(),
                &point.span(),
                "reference.set_point",
                nq,
                "m",
            )?)),
            (None, Some(points)) => {
                if points.get_ref().is_empty() {
                    return Err(c.invalid(
                        &points.span(),
                        "reference.waypoints",
                        "needs at least one waypoint { t = …, q = […] }".into(),
                    ));
                }
                let mut out: Vec<(f64, Vec<f64>)> = Vec::new();
                for (k, point) in points.get_ref().iter().enumerate() {
                    let field = format!("reference.waypoints[{}]", k + 1);
                    let t = point.get_ref().t;
                    let t = c.check(
                        t,
                        &point.span(),
                        &format!("{field}.t"),
                        "",
                        Rule::NonNegative,
                        "s",
                    )?;
                    if let Some((previous, _)) = out.last()
                        && t <= *previous
                    {
                        return Err(c.invalid(
                            &point.span(),
                            &format!("{field}.t"),
                            format!("times must increase: {t} s follows {previous} s"),
                        ));
                    }
                    let q = sized(
                        c,
                        &point.get_ref().q,
                        &point.span(),
                        &format!("{field}.q"),
                        nq,
                        "m",
                    )?;
                    out.push((t, q));
                }
                Ok(ReferenceSpec::Waypoints(out))
            }
            (Some(_), Some(_)) => Err(c.invalid(
                &span,
                "reference",
                "give either `set_point` or `waypoints`, not both".into(),
            )),
            (None, None) => Err(c.invalid(
                &span,
                "reference",
                "needs `set_point = [...]` or `waypoints = [{ t = …, q = [...] }, …]`".into(),
            )),
        }
    }
}

/// Checks that `values` has `nq` finite entries.
fn sized(
    c: &Checker<'_>,
    values: &[f64],
    span: &Range<usize>,
    field: &str,
    nq: usize,
    unit: &str,
) -> Result<Vec<f64>, FileError> {
    if values.len() != nq {
        return Err(c.invalid(
            span,
            field,
            format!(
                "has {} entries, the robot has {nq} coordinates (3 per module: Δx, Δy, δL)",
                values.len()
            ),
        ));
    }
    for (k, &v) in values.iter().enumerate() {
        c.check(
            v,
            span,
            field,
            &format!("entry {} ", k + 1),
            Rule::Finite,
            unit,
        )?;
    }
    Ok(values.to_vec())
}

/// A gain matrix `nq × nq` (row-major) from a number, a diagonal or rows.
fn gain(
    c: &Checker<'_>,
    raw: Option<&Spanned<RawGain>>,
    field: &str,
    nq: usize,
    default: f64,
) -> Result<Vec<f64>, FileError> {
    let Some(raw) = raw else {
        return Ok(crate::control::scaled_identity(nq, default));
    };
    let span = raw.span();
    let mut matrix = vec![0.0; nq * nq];
    match raw.get_ref() {
        RawGain::Scalar(k) => {
            let k = c.check(*k, &span, field, "", Rule::NonNegative, "")?;
            matrix = crate::control::scaled_identity(nq, k);
        }
        RawGain::Diagonal(diagonal) => {
            let diagonal = sized(c, diagonal, &span, field, nq, "")?;
            for (i, k) in diagonal.iter().enumerate() {
                c.check(
                    *k,
                    &span,
                    field,
                    &format!("entry {} ", i + 1),
                    Rule::NonNegative,
                    "",
                )?;
                matrix[i * nq + i] = *k;
            }
        }
        RawGain::Matrix(rows) => {
            if rows.len() != nq {
                return Err(c.invalid(
                    &span,
                    field,
                    format!(
                        "has {} rows, expected {nq} (one per coordinate)",
                        rows.len()
                    ),
                ));
            }
            for (i, row) in rows.iter().enumerate() {
                let row = sized(c, row, &span, &format!("{field} row {}", i + 1), nq, "")?;
                matrix[i * nq..(i + 1) * nq].copy_from_slice(&row);
            }
        }
    }
    Ok(matrix)
}
