//! The safe controller of the paper (§III, docs/model.md §5): the PD+ nominal torque, one HOCBF
//! row `A τ ≥ b` per barrier, and the safety-filter QP, as one allocation-free [`tick`].
//!
//! For every barrier `b_k` (relative degree 2, class-K gains `p1`, `p2`) the HOCBF condition
//! `b̈ + (p1 + p2) ḃ + p1 p2 b ≥ 0` with `ḃ = J q̇`, `b̈ = J q̈ + J̇ q̇` and
//! `q̈ = M⁻¹ (τ − n)`, `n = h + G + K q + D q̇`, is linear in `τ`:
//!
//! ```text
//! (J M⁻¹) τ ≥ J M⁻¹ n − J̇ q̇ − (p1 + p2) J q̇ − p1 p2 b
//! ```
//!
//! That is the paper's row ([`SafetyMode::Paper`]); [`SafetyMode::HoldCorrection`] takes
//! the acceleration of an implicit Euler step over the hold instead, and
//! [`SafetyMode::Certified`] (the default) replaces the rows by rows that prove every barrier
//! non-negative over the whole hold for every plant in the declared box ([`certified`]), and
//! [`SafetyMode::Predicted`] (kept for comparison) by the barriers at samples of the hold,
//! predicted for the command being chosen ([`crate::hold`]), with a first-order margin for a
//! robot's declared uncertainty (docs/model.md §5).
//!
//! The tick is a pure function of (model, controller workspace, state, reference): it reads
//! no clock, touches no port and prints nothing, so simulation and hardware share it.

use std::ops::Range;

pub mod certified;
mod rates;

use certified::{CertifiedWorkspace, certified_filter};
pub use certified::{Uncertified, UncertifiedCounts};
use rates::{RATE_ROWS_PER_LIMIT, RateRows};

use softcbf_description::gains::PAPER_GAINS;
use softcbf_description::uncertainty::{self, ModuleFactors};

use crate::dynamics::{
    BarrierTerms, DynamicsError, DynamicsWorkspace, bias_and_gravity, factor_mass_matrix,
    mass_matrix, model_terms, update_joints,
};
use crate::hold::{HoldPrediction, comparison};
use crate::integrator::{Rosenbrock, Tolerances};
use crate::linalg::{cholesky_in_place, cholesky_inverse, cholesky_solve, dot, with_const_size};
use crate::model::Model;
use crate::plant::{PlantSystem, PlantWorkspace};
use crate::qp::{QpReport, QpSettings, QpSetupError, QpStatus, SafetyQp};

/// What the controller is asked to do: gains and whether the safety filter runs.
#[derive(Clone, Debug, PartialEq)]
pub struct ControllerSettings {
    /// `K_P`, row-major `nq × nq` \[N/m\]. Paper: `5·I` ([`PAPER_GAINS`]).
    pub kp: Vec<f64>,
    /// `K_D`, row-major `nq × nq` \[N·s/m\]. Paper: `1·I` ([`PAPER_GAINS`]).
    pub kd: Vec<f64>,
    /// HOCBF class-K gains `[p1, p2]` \[1/s\] of every barrier whose own table gives none
    /// (`Model::own_barrier_gains`). Default: the robot file's `[barrier]` gains.
    pub barrier_gains: [f64; 2],
    /// Run the safety filter (`false`: plain PD+, `τ = τ_nom`). Default `true`.
    pub filter: bool,
    /// Which rows keep the barriers (docs/model.md §5): the paper's continuous-time rows,
    /// the hold correction, or the sampled-data guarantee over the hold `hold`.
    pub safety: SafetyMode,
    /// Hold period `Δ` \[s\]: how long each command is held. The hold correction and the
    /// sampled-data guarantee use it; the paper's rows do not. `0` only with
    /// [`SafetyMode::Paper`].
    pub hold: f64,
    /// How the sampled-data rows sample the hold (used by [`SafetyMode::Predicted`]).
    pub sampled: SampledSettings,
    /// Constant limits on the command, `A_u τ ≥ b_u`: rows (row-major, `nq` columns) and
    /// right-hand sides, solved together with the barrier rows (e.g. cable tensions kept in
    /// `[f_min, f_max]`). Default: none.
    pub input_limits: (Vec<f64>, Vec<f64>),
    /// Settings of the safety QP.
    pub qp: QpSettings,
}

impl ControllerSettings {
    /// The one constructor of controller settings: the gains `kp`, `kd` (row-major
    /// `nq × nq`, \[N/m\] and \[N·s/m\]) and `barrier_gains` (`[p1, p2]` \[1/s\]), with
    /// the filter on, the paper's rows, no hold, the default sampling and QP settings and no
    /// input limits. A run changes the fields its settings give
    /// ([`crate::settings::Gains::controller_settings`]).
    pub fn new(kp: Vec<f64>, kd: Vec<f64>, barrier_gains: [f64; 2]) -> ControllerSettings {
        ControllerSettings {
            kp,
            kd,
            barrier_gains,
            filter: true,
            safety: SafetyMode::Paper,
            hold: 0.0,
            sampled: SampledSettings::default(),
            input_limits: (Vec::new(), Vec::new()),
            qp: QpSettings::default(),
        }
    }

    /// The paper's simulation gains ([`PAPER_GAINS`]: `K_P = 5·I`, `K_D = 1·I`) with the
    /// robot's barrier gains and the filter on.
    pub fn paper(model: &Model) -> ControllerSettings {
        let (kp, kd) = PAPER_GAINS;
        ControllerSettings::new(
            scaled_identity(model.nq(), kp),
            scaled_identity(model.nq(), kd),
            model.robot.barrier_gains(),
        )
    }

    /// Checks sizes and values for a model with `nq` coordinates.
    pub fn validate(&self, nq: usize) -> Result<(), ControllerError> {
        for (field, matrix) in [("kp", &self.kp), ("kd", &self.kd)] {
            if matrix.len() != nq * nq {
                return Err(ControllerError::Setting {
                    field,
                    reason: format!("has {} entries, expected {nq}×{nq}", matrix.len()),
                });
            }
            if let Some(k) = matrix.iter().position(|v| !v.is_finite()) {
                return Err(ControllerError::Setting {
                    field,
                    reason: format!("entry {} is {}; gains must be finite", k + 1, matrix[k]),
                });
            }
        }
        let (limit_rows, limit_rhs) = &self.input_limits;
        if limit_rows.len() != limit_rhs.len() * nq {
            return Err(ControllerError::Setting {
                field: "input_limits",
                reason: format!(
                    "has {} row entries for {} limits of {nq} columns",
                    limit_rows.len(),
                    limit_rhs.len()
                ),
            });
        }
        if limit_rows.iter().chain(limit_rhs).any(|v| !v.is_finite()) {
            return Err(ControllerError::Setting {
                field: "input_limits",
                reason: "must be finite".to_string(),
            });
        }
        if !(self.hold.is_finite() && self.hold >= 0.0) {
            return Err(ControllerError::Setting {
                field: "hold",
                reason: format!("must be finite and ≥ 0 s, got {}", self.hold),
            });
        }
        if self.safety.uses_hold() && self.hold <= 0.0 {
            return Err(ControllerError::Setting {
                field: "hold",
                reason: format!(
                    "must be > 0 s for the {} safety mode, got {}",
                    self.safety, self.hold
                ),
            });
        }
        if !(1..=MAX_HOLD_SAMPLES).contains(&self.sampled.samples) {
            return Err(ControllerError::Setting {
                field: "sampled.samples",
                reason: format!(
                    "must be 1 to {MAX_HOLD_SAMPLES}, got {}",
                    self.sampled.samples
                ),
            });
        }
        if self.sampled.early > MAX_EARLY_SAMPLES {
            return Err(ControllerError::Setting {
                field: "sampled.early",
                reason: format!(
                    "must be 0 to {MAX_EARLY_SAMPLES}, got {}",
                    self.sampled.early
                ),
            });
        }
        if !(1..=MAX_PASSES).contains(&self.sampled.passes) {
            return Err(ControllerError::Setting {
                field: "sampled.passes",
                reason: format!("must be 1 to {MAX_PASSES}, got {}", self.sampled.passes),
            });
        }
        for (field, gain) in [("p1", self.barrier_gains[0]), ("p2", self.barrier_gains[1])] {
            if !(gain.is_finite() && gain > 0.0) {
                return Err(ControllerError::Setting {
                    field,
                    reason: format!("must be finite and > 0 1/s, got {gain}"),
                });
            }
        }
        Ok(())
    }
}

/// How the safety filter keeps the barriers between the samples of the state
/// (docs/model.md §5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SafetyMode {
    /// The certified rows: every barrier proven non-negative over the whole hold, for every
    /// plant in the declared box ([`certified`]). The default.
    #[default]
    Certified,
    /// The paper's continuous-time HOCBF rows `A = J M⁻¹` at the sample.
    Paper,
    /// The paper's rows with the acceleration of one implicit Euler step over the hold.
    HoldCorrection,
    /// The barriers at samples of the hold, predicted without a bound between samples or
    /// on the prediction's remainder (the former default, `sampled`; kept for comparison).
    Predicted,
}

impl SafetyMode {
    /// Every mode, in the order the help lists them.
    pub const ALL: [SafetyMode; 4] = [
        SafetyMode::Certified,
        SafetyMode::Paper,
        SafetyMode::HoldCorrection,
        SafetyMode::Predicted,
    ];

    /// The name used in files, on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            SafetyMode::Certified => "certified",
            SafetyMode::Paper => "paper",
            SafetyMode::HoldCorrection => "hold-correction",
            SafetyMode::Predicted => "predicted",
        }
    }

    /// The mode named `name`, or an error listing the names.
    pub fn parse(name: &str) -> Result<SafetyMode, String> {
        if name == "sampled" {
            return Err(
                "`sampled` was renamed: give \"certified\" (the guarantee proven \
                        between samples, the default) or \"predicted\" (the former sampled rows, \
                        without a bound between samples)"
                    .to_string(),
            );
        }
        SafetyMode::ALL
            .into_iter()
            .find(|mode| mode.name() == name)
            .ok_or_else(|| {
                format!(
                    "`{name}` is not a safety mode; give one of {}",
                    SafetyMode::ALL
                        .map(|m| format!("\"{}\"", m.name()))
                        .join(", ")
                )
            })
    }

    /// Whether the mode predicts the hold (and needs a hold period `Δ > 0`).
    pub fn uses_hold(self) -> bool {
        self != SafetyMode::Paper
    }
}

impl std::fmt::Display for SafetyMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl serde::Serialize for SafetyMode {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

/// How the sampled-data rows sample a hold (docs/model.md §5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampledSettings {
    /// Even samples `m` per hold: the barriers are kept at `t = k Δ / m`, `k = 1 … m`.
    pub samples: usize,
    /// Early samples `L` before the first even one, at `t = 2^{−i} Δ / m`, `i = 1 … L`,
    /// where the velocity settles after a new command.
    pub early: usize,
    /// QP solves per tick: the first linearizes the barriers at the tick's state, each
    /// further one at the motion the previous one's command predicts.
    pub passes: usize,
}

/// Most samples per hold.
pub const MAX_HOLD_SAMPLES: usize = 64;
/// Most early samples per hold.
pub const MAX_EARLY_SAMPLES: usize = 20;
/// Most QP passes per tick.
pub const MAX_PASSES: usize = 4;

impl Default for SampledSettings {
    fn default() -> SampledSettings {
        SampledSettings {
            samples: 8,
            early: 6,
            passes: 2,
        }
    }
}

/// `c·I` of size `n × n`, row-major.
pub use softcbf_description::gains::scaled_identity;

/// Why a controller could not be built.
#[derive(Debug, thiserror::Error)]
pub enum ControllerError {
    /// A setting has the wrong size or value.
    #[error("controller setting `{field}` {reason}")]
    Setting { field: &'static str, reason: String },
    /// The safety QP could not be set up.
    #[error("safety QP: {0}")]
    Qp(#[from] QpSetupError),
}

/// The reference the nominal controller tracks: `(q̄, q̄̇, q̄̈)`, each of length `nq`.
#[derive(Clone, Copy, Debug)]
pub struct Reference<'a> {
    /// Set point `q̄`.
    pub q: &'a [f64],
    /// `q̄̇` (zero for regulation).
    pub qd: &'a [f64],
    /// `q̄̈` (zero for regulation).
    pub qdd: &'a [f64],
}

/// Where a tick's nominal command comes from.
#[derive(Clone, Copy, Debug)]
pub enum Nominal<'a> {
    /// The PD+ controller toward a reference.
    Track(Reference<'a>),
    /// A given generalized force \[N\], `nq` entries (an identification experiment's
    /// feed-forward tensions): the filter alone acts on it.
    Force(&'a [f64]),
}

/// Outcome of one tick. Every variant leaves a finite command in [`Controller::tau`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TickStatus {
    /// Filter off: `τ = τ_nom`.
    Unfiltered,
    /// The QP was solved: `τ` satisfies every HOCBF row.
    Filtered,
    /// The rows had no common point: `τ` solves the slack-relaxed QP;
    /// [`Controller::qp_report`] lists the relaxed barriers.
    Relaxed,
    /// The QP gave no verified solution: `τ` is the safe command (zero).
    QpFailed,
    /// [`SafetyMode::Certified`] only: the command satisfies the rows of the prediction but
    /// could not be proven safe over the whole hold (why: [`Uncertified`]); `τ` is the best
    /// command found (the first pass's, or the certified pass's when only the hold's first
    /// instants could not be bounded).
    Uncertified(Uncertified),
    /// The state or reference was not finite, had a wrong length, or the dynamics failed:
    /// `τ` is the safe command (zero).
    InvalidState(InvalidState),
}

impl TickStatus {
    /// Whether `τ` is the safe fallback rather than a computed command.
    pub fn is_fallback(self) -> bool {
        matches!(self, TickStatus::QpFailed | TickStatus::InvalidState(_))
    }
}

/// Why the controller could not evaluate the state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InvalidState {
    /// `q`, `q̇` or the reference had a NaN or infinite entry.
    NonFinite,
    /// A setup error of the caller, not a state of the robot: `q`, `q̇` or a reference
    /// vector does not have `nq` entries, or the controller was built for another model.
    /// Every tick with the same buffers gives it again.
    Size {
        /// The argument.
        what: &'static str,
        /// Its length for this model.
        expected: usize,
        /// Its length as given.
        got: usize,
    },
    /// `M(q)` was not positive definite.
    MassMatrix,
    /// The model produced a non-finite barrier, torque or row.
    NonFiniteModel,
    /// `q` or `q̇` lies outside the model's domain (a bend beyond three quarters of a turn, a
    /// backbone length `L0 + δL ≤ 0`, an elongation beyond ten rest lengths, a speed above
    /// 100 m/s:
    /// `softcbf_description::domain`), where the model describes no robot.
    OutOfDomain,
}

/// Preallocated workspace of the controller for one model; [`tick`] writes into it.
pub struct Controller {
    settings: ControllerSettings,
    nq: usize,
    nb: usize,
    dynamics: DynamicsWorkspace,
    /// The state `(q, q̇)` at which `dynamics` holds `M`, its factor and `h + G`, if the
    /// last tick evaluated them.
    dynamics_state: Vec<f64>,
    dynamics_valid: bool,
    barrier_terms: BarrierTerms,
    /// HOCBF rows `A = J M⁻¹`, row-major `nb × nq`, then the input limits; and right-hand
    /// sides.
    rows: Vec<f64>,
    rhs: Vec<f64>,
    /// `n = h + G + K q + D q̇`, then `M⁻¹ n`.
    drift: Vec<f64>,
    /// `M⁻¹` (or `S⁻¹` with the hold correction), and `S`'s factor, row-major `nq × nq`.
    inverse_mass: Vec<f64>,
    hold_factor: Vec<f64>,
    scratch: Vec<f64>,
    tau_nom: Vec<f64>,
    tau: Vec<f64>,
    qp: SafetyQp,
    /// `[p1, p2]` of each barrier: its own, else the settings'.
    barrier_gains: Vec<[f64; 2]>,
    /// The factor every barrier's gains are used with (1 but for a loop slower than its
    /// nominal rate).
    gain_scale: f64,
    /// Rows that belong to barriers (the input limits follow): `nb`, or `nb (m + 1)` with
    /// the sampled-data rows (sample-major: row `j nb + k` is barrier `k` at sample `j`,
    /// row `m nb + k` its condition at the end of the hold).
    barrier_rows: usize,
    /// Workspace of the sampled-data rows ([`SafetyMode::Predicted`] only).
    sampled: Option<SampledWorkspace>,
    /// Workspace of the certified rows ([`SafetyMode::Certified`] only).
    certified: Option<Box<CertifiedWorkspace>>,
    /// How long before the tick the state was read when it was predicted to the tick by the
    /// model \[s\]: the robust margin covers the mismatch over it too.
    margin_age: f64,
    /// Seconds a certified tick may spend on attempts before it takes the predicted rows'
    /// command (infinite: no limit).
    compute_budget: f64,
    /// Which predicted rows gave way on the last tick.
    gave_way: GaveWay,
    /// The rate limits' rows (predicted and certified rows only).
    rates: Option<RateRows>,
}

/// What the sampled-data rows need besides the controller's own buffers.
struct SampledWorkspace {
    prediction: HoldPrediction,
    /// The hold's linear model, `n = h + G` linearized at the tick's state: `K̃ = K +
    /// ∂n/∂q` and `D̃ = D + ∂h/∂q̇` (row-major `nq × nq`), by central differences of `n`
    /// evaluated in `gravity`.
    stiffness: Vec<f64>,
    damping: Vec<f64>,
    /// `K + ∂G/∂q` alone: the robust margin's linear model (with the diagonal `D`).
    gravity_stiffness: Vec<f64>,
    gravity: DynamicsWorkspace,
    perturbed: Vec<f64>,
    perturbed_velocity: Vec<f64>,
    /// `g₀ = n₀ + K q₀ − (D̃ − D) q̇₀`, the linear model's constant forcing.
    offset: Vec<f64>,
    /// `n₀ + K q₀`: the robust margin's.
    plain_offset: Vec<f64>,
    /// The predicted state `q̂ = q₀ + e(t_j)` and the barrier terms there.
    point: Vec<f64>,
    values: Vec<f64>,
    jacobian: Vec<f64>,
    jdot_qd: Vec<f64>,
    zero: Vec<f64>,
    /// `max(ψ_k(t_j), 0)`, sample-major.
    floor: Vec<f64>,
    /// The command of the previous pass.
    guess: Vec<f64>,
    /// The nonlinear plant that predicts the motion under that command: its equations'
    /// workspace, integrator and state `(q, q̇)`.
    plant: PlantWorkspace,
    integrator: Rosenbrock,
    state: Vec<f64>,
    /// The robust margin for the declared uncertainty (`None` when none is declared).
    robust: Option<RobustMargin>,
    /// The rows' right-hand sides as written, while [`solve_giving_way`] changes them.
    written: Vec<f64>,
    /// The command whose integrated motion missed its rows least, of those checked, and
    /// the rows (and right-hand sides) it was solved for.
    best: Vec<f64>,
    best_rows: Vec<f64>,
    best_rhs: Vec<f64>,
    /// The rows the command being checked was solved for.
    solved_rows: Vec<f64>,
    solved_rhs: Vec<f64>,
    /// The barrier values at the samples under the last command (sample-major) and the
    /// state `(q, q̇)` the hold starts from.
    sample_values: Vec<f64>,
    /// `ḃ_k + p1 b_k` at the end of the hold under that command, one per barrier.
    end_values: Vec<f64>,
    start: Vec<f64>,
    /// The barriers at the tick, one per barrier.
    start_values: Vec<f64>,
    /// The barriers at a step of the plant's integration between two samples (scratch).
    dense_values: Vec<f64>,
    /// How far each barrier fell below its threshold between the last two samples
    /// integrated with watching on (`−∞`: nowhere): see [`SampledWorkspace::advance`].
    shortfall: Vec<f64>,
    /// The samples' rows' margins for what their barriers did between samples, raised by
    /// the check where the command's own motion dipped there (sample-major; zero at each
    /// tick's start).
    dip: Vec<f64>,
}

/// One plant at a corner of the declared box: one group of numbers off at a time.
enum Perturbation {
    /// `K` of coordinates `coordinates` times `stiffness` and their `D` times `damping`
    /// (one module's bending or axial numbers, at a corner of their square).
    Elastic {
        coordinates: Range<usize>,
        stiffness: f64,
        damping: f64,
    },
    /// One module's mass and inertia scaled: the plant's own model.
    Mass {
        plant: Box<Model>,
        module: usize,
        heavier: bool,
    },
}

/// The robust margin (docs/model.md §5): how much farther each barrier could move toward
/// its floor, at each sample, on a plant inside the declared box than on the nominal one.
struct RobustMargin {
    perturbations: Vec<Perturbation>,
    /// Whether each perturbation closes its group (the next one starts another), and how
    /// many groups there are.
    group_end: Vec<bool>,
    groups: usize,
    /// Per row, the worst member (an index into `perturbations`) of each group (`rows ×
    /// groups`), and the extra approach of the plant last predicted (`rows`).
    choice: Vec<usize>,
    approach: Vec<f64>,
    /// The unmodelled force's share of each row's margin (`rows`).
    force_share: Vec<f64>,
    /// The plant with every module's mass off at once, for each combination of ends (bit `i`
    /// set: module `i` heavier); empty without a mass box.
    mass_corners: Vec<Model>,
    force: f64,
    /// The factor on the groups' summed margins for the products the sum leaves out,
    /// `1 / (1 − σ)` with `σ` the box's widest fraction ([`RobustMargin::new`]).
    product_allowance: f64,
    prediction: HoldPrediction,
    dynamics: DynamicsWorkspace,
    stiffness: Vec<f64>,
    damping: Vec<f64>,
    inverse_mass: Vec<f64>,
    scratch: Vec<f64>,
    /// `τ − g₀` of the perturbed plant, and its excursion at a sample.
    forcing: Vec<f64>,
    excursion: Vec<f64>,
    /// The nominal excursions `e(t_j)` (`m × nq`) and end velocity under the guess.
    nominal: Vec<f64>,
    nominal_velocity: Vec<f64>,
    /// Per group of perturbed plants: the worst extra approach of each row over its members
    /// so far.
    worst: Vec<f64>,
    /// The margin of every barrier row, sample-major like the rows.
    margin: Vec<f64>,
}

impl RobustMargin {
    /// The perturbed plants of `model`'s declared box, in groups whose worst member counts
    /// ([`robust_margin`]): per module, its bending and its axial numbers each at the four
    /// corners of `κ ∈ 1 ± stiffness`, `β ∈ 1 ± damping` together (a softer module under a
    /// large static load creeps faster with less damping: taken one at a time, the two miss
    /// their product, 5 % of the elastic force at ±20 %, which let a corner of
    /// `paper-sim-uncertain.toml` creep 2.4 mm past its barrier), and its mass at
    /// `1 ± mass`; the models of every combination of the modules' mass ends for the
    /// combined plant ([`combined_plant`]); and the products' allowance `1 / (1 − σ)`.
    fn new(model: &Model, samples: &SampledSettings) -> Result<RobustMargin, ControllerError> {
        let (nq, nb) = (model.nq(), model.nb());
        let u = model.robot.uncertainty;
        let mut perturbations = Vec::new();
        let mut group_end = Vec::new();
        let ends = |fraction: f64| {
            if fraction > 0.0 {
                vec![1.0 + fraction, 1.0 - fraction]
            } else {
                vec![1.0]
            }
        };
        for i in 0..model.n_modules() {
            let bx = model.robot.module_box(i);
            for (kind, coordinates) in [3 * i..3 * i + 2, 3 * i + 2..3 * i + 3]
                .into_iter()
                .enumerate()
            {
                let (sigma_k, sigma_d) = (bx.stiffness[kind], bx.damping[kind]);
                if sigma_k <= 0.0 && sigma_d <= 0.0 {
                    continue;
                }
                for &stiffness in &ends(sigma_k) {
                    for &damping in &ends(sigma_d) {
                        perturbations.push(Perturbation::Elastic {
                            coordinates: coordinates.clone(),
                            stiffness,
                            damping,
                        });
                        group_end.push(false);
                    }
                }
                if let Some(last) = group_end.last_mut() {
                    *last = true;
                }
            }
            if bx.mass > 0.0 {
                for sign in [1.0, -1.0] {
                    let mut factors = vec![ModuleFactors::NOMINAL; model.n_modules()];
                    factors[i].mass = 1.0 + sign * bx.mass;
                    let plant = uncertainty::scaled(&model.robot, &factors)
                        .map_err(|e| robust_error(e.to_string()))?;
                    let plant = Model::with_generated(plant, model.generated)
                        .map_err(|e| robust_error(e.to_string()))?;
                    perturbations.push(Perturbation::Mass {
                        plant: Box::new(plant),
                        module: i,
                        heavier: sign > 0.0,
                    });
                    group_end.push(sign < 0.0);
                }
            }
        }
        let rows = nb * (samples.samples + samples.early + 1);
        let groups = group_end.iter().filter(|&&end| end).count();
        let mut mass_corners = Vec::new();
        if u.mass > 0.0 && model.n_modules() <= MASS_CORNER_MODULES {
            for corner in 0..1usize << model.n_modules() {
                let factors: Vec<ModuleFactors> = (0..model.n_modules())
                    .map(|i| {
                        let sign = if corner & (1 << i) != 0 { 1.0 } else { -1.0 };
                        ModuleFactors {
                            mass: 1.0 + sign * model.robot.module_box(i).mass,
                            ..ModuleFactors::NOMINAL
                        }
                    })
                    .collect();
                let plant = uncertainty::scaled(&model.robot, &factors)
                    .map_err(|e| robust_error(e.to_string()))?;
                mass_corners.push(
                    Model::with_generated(plant, model.generated)
                        .map_err(|e| robust_error(e.to_string()))?,
                );
            }
        }
        Ok(RobustMargin {
            choice: vec![0; rows * groups],
            approach: vec![0.0; rows],
            force_share: vec![0.0; rows],
            mass_corners,
            groups,
            product_allowance: 1.0 / (1.0 - u.stiffness.max(u.damping).max(u.mass).min(0.5)),
            perturbations,
            group_end,
            force: u.force,
            prediction: HoldPrediction::new(nq, samples.samples, samples.early),
            dynamics: DynamicsWorkspace::new(model),
            stiffness: vec![0.0; nq * nq],
            damping: vec![0.0; nq],
            inverse_mass: vec![0.0; nq * nq],
            scratch: vec![0.0; nq * nq],
            forcing: vec![0.0; nq],
            excursion: vec![0.0; nq],
            nominal: vec![0.0; (samples.samples + samples.early) * nq],
            nominal_velocity: vec![0.0; nq],
            worst: vec![0.0; rows],
            margin: vec![0.0; rows],
        })
    }
}

/// Most modules whose mass corners are all built for the combined plant ([`combined_plant`]:
/// `2^n` models); with more, the combined plant keeps the nominal masses.
const MASS_CORNER_MODULES: usize = 6;

fn robust_error(reason: String) -> ControllerError {
    ControllerError::Setting {
        field: "uncertainty",
        reason: format!("gives a plant the model cannot take: {reason}"),
    }
}

/// What a tick's robust margin is computed from ([`robust_margin`]): the model, the
/// horizon \[s\] (the hold plus the age of a predicted state), the nominal linear model's
/// stiffness `K + ∂G/∂q` and offset `n₀ + K q₀` (`nq × nq`, `nq`) with `h` frozen, the
/// mass-matrix inverse (`nq × nq`), the barriers' Jacobian (`nb × nq`) and class-K gains
/// with their scale, the command `guess` (`nq`, N) and the tick's state `(q, q̇)`.
#[derive(Clone, Copy)]
struct MarginInputs<'a> {
    model: &'a Model,
    horizon: f64,
    nominal_stiffness: &'a [f64],
    nominal_offset: &'a [f64],
    inverse_mass: &'a [f64],
    jacobian: &'a [f64],
    gains: &'a [[f64; 2]],
    scale: f64,
    guess: &'a [f64],
    q: &'a [f64],
    qd: &'a [f64],
}

/// Fills `robust.margin` for the command `guess`: for each perturbed plant
/// ([`RobustMargin::new`]: a module's bending or axial stiffness and damping at a corner of
/// their square, or its mass at an end), the extra approach `−J_k (e_v(t_j) − e(t_j))` of
/// every barrier row (and `−J_k (ė_v + p1 e_v − ė − p1 e)` at the end of the hold), the
/// worst of each group taken, the groups summed and the sum raised by the products'
/// allowance; plus the unmodelled force's `F Σ_i |(J_k Γ_j)_i|`; and at least the extra
/// approach on the plant with every group at its worst for the row with the least room
/// ([`combined_plant`]; `rows`, `rhs`: the rows `guess` was solved for). The deviations are
/// those of the linearized dynamics (docs/model.md §5), over `horizon`: the hold, plus the
/// age of a state predicted from an older reading ([`Controller::set_margin_age`]), sampled
/// like the hold. Allocates nothing.
fn robust_margin(
    robust: &mut RobustMargin,
    inputs: &MarginInputs<'_>,
    rows: &[f64],
    rhs: &[f64],
) -> bool {
    let MarginInputs {
        model,
        horizon,
        nominal_stiffness,
        nominal_offset,
        inverse_mass,
        jacobian,
        guess,
        q,
        qd,
        ..
    } = *inputs;
    let nq = q.len();
    let nb = jacobian.len() / nq.max(1);
    let m = robust.prediction.samples();
    // The nominal plant over the horizon, the same way as the perturbed ones below.
    if !robust
        .prediction
        .predict(inverse_mass, nominal_stiffness, &model.damping, qd, horizon)
    {
        return false;
    }
    for (u, (t, g)) in robust
        .forcing
        .iter_mut()
        .zip(guess.iter().zip(nominal_offset))
    {
        *u = t - g;
    }
    for j in 0..m {
        robust.prediction.excursion(
            j,
            &robust.forcing,
            &mut robust.nominal[j * nq..(j + 1) * nq],
        );
    }
    end_velocity(
        &robust.prediction,
        &robust.forcing,
        &mut robust.nominal_velocity,
    );
    robust.margin.fill(0.0);
    robust.force_share.fill(0.0);
    if robust.force > 0.0 {
        for j in 0..m {
            let forced = robust.prediction.forced(j);
            for k in 0..nb {
                let row = &jacobian[k * nq..(k + 1) * nq];
                let reach: f64 = (0..nq)
                    .map(|c| {
                        (0..nq)
                            .map(|i| row[i] * forced[i * nq + c])
                            .sum::<f64>()
                            .abs()
                    })
                    .sum();
                robust.force_share[j * nb + k] = robust.force * reach;
                robust.margin[j * nb + k] += robust.force * reach;
            }
        }
    }
    // The plants are read while the workspace is written: out of it for the while (moves,
    // no allocation).
    let perturbations = std::mem::take(&mut robust.perturbations);
    let mass_corners = std::mem::take(&mut robust.mass_corners);
    let done = group_margins(robust, &perturbations, inputs)
        && combined_plant(robust, &perturbations, &mass_corners, inputs, rows, rhs);
    robust.perturbations = perturbations;
    robust.mass_corners = mass_corners;
    done && robust.margin.iter().all(|v| v.is_finite())
}

/// Each group's worst extra approach per row, summed over the groups into `robust.margin`
/// (which holds the force's share already); remembers each row's worst member of each
/// group in `robust.choice`. `false` where a prediction fails.
fn group_margins(
    robust: &mut RobustMargin,
    perturbations: &[Perturbation],
    inputs: &MarginInputs<'_>,
) -> bool {
    let MarginInputs {
        model,
        horizon,
        nominal_stiffness,
        nominal_offset,
        inverse_mass,
        jacobian,
        gains,
        scale,
        guess,
        q,
        qd,
    } = *inputs;
    let groups = robust.groups;
    let mut group = 0;
    for (v, perturbation) in perturbations.iter().enumerate() {
        // Stiffness, damping, mass inverse and offset of the perturbed plant.
        robust.stiffness.copy_from_slice(nominal_stiffness);
        robust.damping.copy_from_slice(&model.damping);
        robust.inverse_mass.copy_from_slice(inverse_mass);
        robust.forcing.copy_from_slice(nominal_offset);
        match perturbation {
            Perturbation::Elastic {
                coordinates,
                stiffness,
                damping,
            } => perturb_elastic(robust, model, q, coordinates.clone(), *stiffness, *damping),
            Perturbation::Mass { plant, .. } => {
                if !perturb_mass(robust, model, plant, q, qd) {
                    return false;
                }
            }
        }
        if !plant_approach(robust, horizon, guess, jacobian, gains, scale, qd) {
            return false;
        }
        // The first of a group starts its worst approach; the last closes it.
        let first = v == 0 || robust.group_end[v - 1];
        let closes = robust.group_end[v];
        for r in 0..robust.margin.len() {
            let approach = robust.approach[r];
            if first || approach > robust.worst[r] {
                robust.worst[r] = approach;
                robust.choice[r * groups + group] = v;
            }
            if closes {
                robust.margin[r] += robust.product_allowance * robust.worst[r].max(0.0);
            }
        }
        if closes {
            group += 1;
        }
    }
    true
}

/// The groups' effects do not add where numbers of different groups multiply (two modules
/// both softer under a large static load, a module softer in bending and stiffer axially:
/// the falsifier found plants inside `paper-sim-uncertain.toml`'s box with corners 0.2 to
/// 0.9 mm below zero that way). So the plant at every group's worst member for the row the
/// guess meets with the least room (`rows · guess − rhs − margin`, the rows the guess was
/// solved for) is predicted as well, with all its numbers off at once, and every row's
/// margin is at least its extra approach on that plant. `false` where the prediction fails.
fn combined_plant(
    robust: &mut RobustMargin,
    perturbations: &[Perturbation],
    mass_corners: &[Model],
    inputs: &MarginInputs<'_>,
    rows: &[f64],
    rhs: &[f64],
) -> bool {
    let MarginInputs {
        model,
        horizon,
        nominal_stiffness,
        nominal_offset,
        inverse_mass,
        jacobian,
        gains,
        scale,
        guess,
        q,
        qd,
    } = *inputs;
    let (nq, groups) = (q.len(), robust.groups);
    if groups < 2 {
        return true;
    }
    let count = robust
        .margin
        .len()
        .min(rhs.len())
        .min(rows.len() / nq.max(1));
    let Some(critical) = (0..count).min_by(|&a, &b| {
        let room = |r: usize| dot(&rows[r * nq..(r + 1) * nq], guess) - rhs[r] - robust.margin[r];
        room(a).total_cmp(&room(b))
    }) else {
        return true;
    };
    robust.stiffness.copy_from_slice(nominal_stiffness);
    robust.damping.copy_from_slice(&model.damping);
    robust.inverse_mass.copy_from_slice(inverse_mass);
    robust.forcing.copy_from_slice(nominal_offset);
    // The masses first (their plant's M and h + G + K q), then the elastic numbers on top.
    // Which corner of the masses: bit `i` set where module `i`'s heavier plant is the
    // worse (the corners are built for every combination, `RobustMargin::new`).
    let mut masses = 0usize;
    for g in 0..groups {
        if let Perturbation::Mass {
            module, heavier, ..
        } = perturbations[robust.choice[critical * groups + g]]
            && heavier
        {
            masses |= 1 << module;
        }
    }
    if let Some(plant) = mass_corners.get(masses)
        && !perturb_mass(robust, model, plant, q, qd)
    {
        return false;
    }
    for g in 0..groups {
        if let Perturbation::Elastic {
            coordinates,
            stiffness,
            damping,
        } = &perturbations[robust.choice[critical * groups + g]]
        {
            perturb_elastic(robust, model, q, coordinates.clone(), *stiffness, *damping);
        }
    }
    if !plant_approach(robust, horizon, guess, jacobian, gains, scale, qd) {
        return false;
    }
    // The unmodelled force acts on the combined plant too.
    for ((margin, &approach), &force) in robust
        .margin
        .iter_mut()
        .zip(&robust.approach)
        .zip(&robust.force_share)
    {
        *margin = margin.max(approach + force);
    }
    true
}

/// One module's bending or axial `K` and `D` of the perturbed plant in `robust` scaled by
/// `stiffness` and `damping` (its offset `K q` with them).
fn perturb_elastic(
    robust: &mut RobustMargin,
    model: &Model,
    q: &[f64],
    coordinates: Range<usize>,
    stiffness: f64,
    damping: f64,
) {
    let nq = q.len();
    for c in coordinates {
        let extra = (stiffness - 1.0) * model.stiffness[c];
        robust.stiffness[c * nq + c] += extra;
        robust.forcing[c] += extra * q[c];
        robust.damping[c] *= damping;
    }
}

/// The mass inverse and offset `h + G + K q` of `plant` (a model whose masses are off) at
/// `(q, q̇)` into the perturbed plant of `robust`. `false` where they cannot be evaluated.
fn perturb_mass(
    robust: &mut RobustMargin,
    model: &Model,
    plant: &Model,
    q: &[f64],
    qd: &[f64],
) -> bool {
    let nq = q.len();
    let evaluated = update_joints(plant, &mut robust.dynamics, q, qd)
        .and_then(|()| mass_matrix(plant, &mut robust.dynamics))
        .and_then(|()| bias_and_gravity(plant, &mut robust.dynamics, qd))
        .and_then(|()| factor_mass_matrix(&mut robust.dynamics));
    if evaluated.is_err() {
        return false;
    }
    cholesky_inverse(
        &robust.dynamics.cholesky,
        nq,
        &mut robust.inverse_mass,
        &mut robust.scratch,
    );
    for (c, f) in robust.forcing.iter_mut().enumerate() {
        *f = robust.dynamics.nonlinear[c] + model.stiffness[c] * q[c];
    }
    true
}

/// Predicts the perturbed plant set up in `robust` (stiffness, damping, mass inverse, and
/// its offset in `robust.forcing`) under `guess` over `horizon`, and writes each row's
/// extra approach over the nominal prediction into `robust.approach`: `−J_k (e_v(t_j) −
/// e(t_j))` at the samples, `−J_k (ė_v − ė + p1 (e_v − e))` at the end of the hold.
#[allow(clippy::too_many_arguments)]
fn plant_approach(
    robust: &mut RobustMargin,
    horizon: f64,
    guess: &[f64],
    jacobian: &[f64],
    gains: &[[f64; 2]],
    scale: f64,
    qd: &[f64],
) -> bool {
    let nq = qd.len();
    let nb = jacobian.len() / nq.max(1);
    let m = robust.prediction.samples();
    if !robust.prediction.predict(
        &robust.inverse_mass,
        &robust.stiffness,
        &robust.damping,
        qd,
        horizon,
    ) {
        return false;
    }
    // forcing ← τ − g₀ of this plant.
    for (f, t) in robust.forcing.iter_mut().zip(guess) {
        *f = t - *f;
    }
    for j in 0..=m {
        if j < m {
            robust
                .prediction
                .excursion(j, &robust.forcing, &mut robust.excursion);
            for (e, n) in robust
                .excursion
                .iter_mut()
                .zip(&robust.nominal[j * nq..(j + 1) * nq])
            {
                *e -= n;
            }
        } else {
            // ė_v + p1 e_v − ė − p1 e at the end, p1 per barrier below.
            end_velocity(
                &robust.prediction,
                &robust.forcing,
                &mut robust.scratch[..nq],
            );
            robust
                .prediction
                .excursion(m - 1, &robust.forcing, &mut robust.excursion);
            for c in 0..nq {
                robust.excursion[c] -= robust.nominal[(m - 1) * nq + c];
                robust.scratch[c] -= robust.nominal_velocity[c];
            }
        }
        for k in 0..nb {
            let row = &jacobian[k * nq..(k + 1) * nq];
            let mut approach = -dot(row, &robust.excursion);
            if j == m {
                approach = -dot(row, &robust.scratch[..nq]) + gains[k][0] * scale * approach;
            }
            robust.approach[j * nb + k] = approach;
        }
    }
    robust.approach.iter().all(|v| v.is_finite())
}

/// `ė(Δ) = ȧ + Γ̇ u` of a prediction for the held `u = τ − g₀`.
fn end_velocity(prediction: &HoldPrediction, u: &[f64], out: &mut [f64]) {
    let nq = u.len();
    let (free, forced) = (
        prediction.end_velocity_free(),
        prediction.end_velocity_forced(),
    );
    for i in 0..nq {
        out[i] = free[i] + dot(&forced[i * nq..(i + 1) * nq], u);
    }
}

/// Error control of the prediction between samples: far tighter than the barriers'
/// tolerance of 1e-6 m, and the first step short enough for the velocity transient.
fn prediction_tolerances() -> Tolerances {
    Tolerances {
        rtol: 1e-7,
        atol: 1e-10,
        h_initial: 1e-6,
        max_steps: 10_000,
        ..Tolerances::default()
    }
}

impl SampledWorkspace {
    /// Integrates the plant (its command set in `plant`) from `*time` to the hold's sample
    /// `j`, moving `*time` there, and evaluates the barrier terms at the state reached
    /// (`point`, `values`, `jacobian`). `false` where the integration fails, the state
    /// leaves the model's domain or a barrier term is not finite.
    ///
    /// With `watch`, also the barriers at every step the integrator takes between the two
    /// samples: `shortfall[k]` becomes how far barrier `k` fell below
    /// `min(0, floor before, floor after)` there (the floor before sample 0 is the barrier
    /// at the tick), `−∞` where it did not come below. The steps are the integrator's own
    /// (watching does not change them); a barrier that is not a number at a step (a state
    /// outside the domain) is left to the sample's check.
    fn advance(&mut self, model: &Model, time: &mut f64, j: usize, watch: bool) -> bool {
        let nq = self.point.len();
        let nb = self.values.len();
        let next = self.prediction.time(j);
        let mut system = PlantSystem {
            model,
            workspace: &mut self.plant,
        };
        let integrated = if watch {
            self.shortfall.fill(f64::NEG_INFINITY);
            let (floor, start_values) = (&self.floor, &self.start_values);
            let (dense, shortfall) = (&mut self.dense_values, &mut self.shortfall);
            self.integrator
                .integrate_observed(&mut system, *time, next, &mut self.state, |_, x| {
                    model.generated.barriers(&model.params, &x[..nq], dense);
                    for k in 0..nb {
                        let before = if j == 0 {
                            start_values[k]
                        } else {
                            floor[(j - 1) * nb + k]
                        };
                        let threshold = before.min(floor[j * nb + k]).min(0.0);
                        let below = threshold - dense[k];
                        if below > shortfall[k] {
                            shortfall[k] = below;
                        }
                    }
                })
        } else {
            self.integrator
                .integrate(&mut system, *time, next, &mut self.state)
        };
        if integrated.is_err() {
            return false;
        }
        *time = next;
        self.point.copy_from_slice(&self.state[..nq]);
        if softcbf_description::domain::state_problem(&model.robot, &self.point, &self.zero)
            .is_some()
        {
            return false;
        }
        model.generated.barrier_terms(
            &model.params,
            &self.point,
            &self.zero,
            &mut self.values,
            &mut self.jacobian,
            &mut self.jdot_qd,
        );
        all_finite(&self.values) && all_finite(&self.jacobian)
    }

    fn new(model: &Model, settings: &SampledSettings) -> SampledWorkspace {
        let (nq, nb) = (model.nq(), model.nb());
        let samples = settings.samples + settings.early;
        SampledWorkspace {
            prediction: HoldPrediction::new(nq, settings.samples, settings.early),
            stiffness: vec![0.0; nq * nq],
            gravity: DynamicsWorkspace::new(model),
            damping: vec![0.0; nq * nq],
            gravity_stiffness: vec![0.0; nq * nq],
            perturbed: vec![0.0; nq],
            perturbed_velocity: vec![0.0; nq],
            offset: vec![0.0; nq],
            plain_offset: vec![0.0; nq],
            point: vec![0.0; nq],
            values: vec![0.0; nb],
            jacobian: vec![0.0; nb * nq],
            jdot_qd: vec![0.0; nb],
            zero: vec![0.0; nq],
            floor: vec![0.0; nb * samples],
            guess: vec![0.0; nq],
            plant: PlantWorkspace::new(model),
            integrator: Rosenbrock::new(2 * nq, prediction_tolerances())
                .expect("the prediction's tolerances are valid"),
            state: vec![0.0; 2 * nq],
            robust: None,
            written: vec![0.0; nb * (samples + 1)],
            best: vec![0.0; nq],
            best_rows: vec![0.0; nb * (samples + 1) * nq],
            best_rhs: vec![0.0; nb * (samples + 1)],
            solved_rows: vec![0.0; nb * (samples + 1) * nq],
            solved_rhs: vec![0.0; nb * (samples + 1)],
            sample_values: vec![0.0; nb * samples],
            end_values: vec![0.0; nb],
            start: vec![0.0; 2 * nq],
            start_values: vec![0.0; nb],
            dense_values: vec![0.0; nb],
            shortfall: vec![f64::NEG_INFINITY; nb],
            dip: vec![0.0; nb * samples],
        }
    }
}

impl Controller {
    /// A controller for `model` with validated `settings`.
    pub fn new(model: &Model, settings: ControllerSettings) -> Result<Controller, ControllerError> {
        let (nq, nb) = (model.nq(), model.nb());
        settings.validate(nq)?;
        let (limit_rows, limit_rhs) = &settings.input_limits;
        // The certified rows keep the predicted rows' workspace too: a tick they cannot
        // prove takes the predicted rows' command (both passes, the robust margin).
        let sampled = matches!(
            settings.safety,
            SafetyMode::Predicted | SafetyMode::Certified
        )
        .then(|| SampledWorkspace::new(model, &settings.sampled));
        let mut sampled = sampled;
        if let Some(sampled) = sampled.as_mut()
            && model.robot.uncertainty.is_declared()
        {
            sampled.robust = Some(RobustMargin::new(model, &settings.sampled)?);
        }
        let certified = (settings.safety == SafetyMode::Certified).then(|| {
            let early = CertifiedWorkspace::early_samples(model, &settings.sampled, settings.hold);
            Box::new(CertifiedWorkspace::new(model, &settings.sampled, early))
        });
        // With the predicted and certified rows, one row per barrier and sample, then one per
        // barrier for the end of the hold; the certified rows add a box on the command.
        let samples = settings.sampled.samples + settings.sampled.early;
        let (barrier_rows, extra_rows) = match settings.safety {
            SafetyMode::Predicted => (nb * (samples + 1), 0),
            SafetyMode::Certified => (
                nb * (certified
                    .as_ref()
                    .map_or(samples, |c| c.samples())
                    .max(samples)
                    + 1),
                CertifiedWorkspace::box_rows(nq),
            ),
            SafetyMode::Paper | SafetyMode::HoldCorrection => (nb, 0),
        };
        // Every module's elongation rate (docs/model.md §5, "Rate limits").
        let rate_limits: Vec<(usize, f64)> = match settings.safety {
            SafetyMode::Predicted | SafetyMode::Certified => model
                .robot
                .limits
                .iter()
                .enumerate()
                .map(|(i, limits)| (3 * i + 2, limits.elongation_rate))
                .collect(),
            SafetyMode::Paper | SafetyMode::HoldCorrection => Vec::new(),
        };
        let rate_start = barrier_rows + extra_rows;
        let limits_start = rate_start + RATE_ROWS_PER_LIMIT * rate_limits.len();
        let rates = (!rate_limits.is_empty()).then(|| RateRows {
            limits: rate_limits,
            start: rate_start,
            gain: settings.barrier_gains[0],
        });
        let rows = limits_start + limit_rhs.len();
        let qp = SafetyQp::new(nq, rows, settings.qp)?;
        let mut constraint_rows = vec![0.0; rows * nq];
        constraint_rows[limits_start * nq..].copy_from_slice(limit_rows);
        let mut constraint_rhs = vec![0.0; rows];
        constraint_rhs[limits_start..].copy_from_slice(limit_rhs);
        let [p1, p2] = settings.barrier_gains;
        let barrier_gains = (0..nb)
            .map(|k| {
                let [own1, own2] = model.own_barrier_gains.get(k).copied().unwrap_or_default();
                [own1.unwrap_or(p1), own2.unwrap_or(p2)]
            })
            .collect();
        Ok(Controller {
            settings,
            nq,
            nb,
            dynamics: DynamicsWorkspace::new(model),
            dynamics_state: vec![f64::NAN; 2 * nq],
            dynamics_valid: false,
            barrier_terms: BarrierTerms::new(model),
            rows: constraint_rows,
            rhs: constraint_rhs,
            drift: vec![0.0; nq],
            inverse_mass: vec![0.0; nq * nq],
            hold_factor: vec![0.0; nq * nq],
            scratch: vec![0.0; nq * nq],
            tau_nom: vec![0.0; nq],
            tau: vec![0.0; nq],
            qp,
            barrier_gains,
            gain_scale: 1.0,
            barrier_rows,
            sampled,
            certified,
            margin_age: 0.0,
            compute_budget: f64::INFINITY,
            gave_way: GaveWay::Nothing,
            rates,
        })
    }

    /// The settings in use.
    pub fn settings(&self) -> &ControllerSettings {
        &self.settings
    }

    /// Turns the safety filter on or off.
    pub fn set_filter(&mut self, on: bool) {
        self.settings.filter = on;
    }

    /// Scales every barrier's HOCBF class-K gains by `scale` (e.g. to a loop's achieved
    /// period: `nominal / achieved`), relative to the gains the controller was built with.
    /// A scale that is not finite and > 0 is refused (`false`) and the previous one kept.
    pub fn set_barrier_gain_scale(&mut self, scale: f64) -> bool {
        let valid = scale.is_finite() && scale > 0.0;
        if valid {
            self.gain_scale = scale;
        }
        valid
    }

    /// The class-K gains `[p1, p2]` \[1/s\] barrier `k` is used with now (its own, else the
    /// settings', times the gain scale).
    pub fn barrier_gains(&self, k: usize) -> Option<[f64; 2]> {
        let [p1, p2] = *self.barrier_gains.get(k)?;
        Some([p1 * self.gain_scale, p2 * self.gain_scale])
    }

    /// Changes the hold period `Δ` \[s\] (for a loop whose real period differs from its
    /// nominal one). A value that is not finite and > 0 is refused (`false`) and the
    /// previous one kept.
    pub fn set_hold(&mut self, hold: f64) -> bool {
        let valid = hold.is_finite() && hold > 0.0;
        if valid {
            self.settings.hold = hold;
        }
        valid
    }

    /// Tells the robust margin that the state of the next ticks was predicted by the model
    /// from a reading `age` seconds old (a hardware loop's latency): the margin then covers
    /// the plant's deviation over `age` plus the hold. `0` (the default) for a state read at
    /// the tick. A value that is not finite and ≥ 0 is refused (`false`).
    pub fn set_margin_age(&mut self, age: f64) -> bool {
        let valid = age.is_finite() && age >= 0.0;
        if valid {
            self.margin_age = age;
        }
        valid
    }

    /// Limits the time a certified tick spends on its attempts \[s\]: once an attempt ends
    /// past it, no further attempt starts, and the tick takes the predicted rows' command
    /// with the status `uncertified (budget)`. For a loop with a deadline (the hardware
    /// loop); the default, infinite, keeps a simulation's results independent of the
    /// machine's speed. A value that is not positive (or NaN) is refused (`false`).
    pub fn set_compute_budget(&mut self, seconds: f64) -> bool {
        let valid = seconds > 0.0;
        if valid {
            self.compute_budget = seconds;
        }
        valid
    }

    /// The command of the last tick \[N\]: the one to apply.
    pub fn tau(&self) -> &[f64] {
        &self.tau
    }

    /// The nominal PD+ torque of the last tick \[N\] (NaN after an invalid state).
    pub fn tau_nom(&self) -> &[f64] {
        &self.tau_nom
    }

    /// Barrier values of the last tick \[m\] (NaN after an invalid state).
    pub fn barriers(&self) -> &[f64] {
        self.barrier_terms.values()
    }

    /// Barrier Jacobian of the last tick, row-major `nb × nq`.
    pub fn barrier_jacobian(&self) -> &[f64] {
        self.barrier_terms.jacobian()
    }

    /// The safety rows (row-major, `nq` columns) and right-hand sides `b` of the last tick:
    /// the filtered `τ` satisfies `A τ ≥ b`. First the barriers' rows
    /// ([`Controller::barrier_of_row`]: the HOCBF rows `A = J M⁻¹`, one per barrier, or the
    /// sampled-data rows, one per barrier and sample), then the input limits.
    pub fn constraints(&self) -> (&[f64], &[f64]) {
        (&self.rows, &self.rhs)
    }

    /// The barrier a safety row keeps (`None` for an input limit's row).
    pub fn barrier_of_row(&self, row: usize) -> Option<usize> {
        (row < self.barrier_rows).then(|| row % self.nb.max(1))
    }

    /// [`SafetyMode::Certified`], after a tick whose status is [`TickStatus::Filtered`]: per
    /// barrier (`nb` entries, in the order of [`Controller::barriers`]) the proven lower
    /// bound of the barrier over the whole hold under the command sent \[m\], every one ≥ 0
    /// for a barrier that was ≥ 0 at the tick (docs/model.md §5). `None` otherwise.
    pub fn certified_bound(&self) -> Option<&[f64]> {
        self.certified
            .as_ref()
            .filter(|certified| certified.proven)
            .map(|certified| certified.lowest())
    }

    /// [`SafetyMode::Certified`]: where its ticks' time went, summed since the controller
    /// was made (`None` in the other modes).
    pub fn certified_split(&self) -> Option<certified::CertifiedSplit> {
        self.certified.as_ref().map(|certified| certified.split)
    }

    /// Which of the predicted rows gave way on the last tick where they had no common
    /// point ([`GaveWay`]; `Nothing` in the other modes).
    pub fn gave_way(&self) -> GaveWay {
        self.gave_way
    }

    /// Report of the last QP solve (statuses, iterations, relaxed rows).
    pub fn qp_report(&self) -> &QpReport {
        self.qp.report()
    }

    /// The dynamics evaluated at the last tick's state (`M` and `h + G` in `nonlinear`).
    pub fn dynamics(&self) -> &DynamicsWorkspace {
        &self.dynamics
    }

    /// The state `(q, q̇)` (`2 nq` entries) at which [`Controller::dynamics`] holds `M`, its
    /// Cholesky factor and `h + G`, all evaluated by the last tick; `None` if that tick did
    /// not evaluate them (an invalid state, or a failed evaluation).
    pub fn dynamics_state(&self) -> Option<&[f64]> {
        self.dynamics_valid.then_some(&self.dynamics_state[..])
    }

    fn fallback(&mut self, why: InvalidState) -> TickStatus {
        self.tau.fill(0.0);
        self.tau_nom.fill(f64::NAN);
        self.barrier_terms.invalidate();
        TickStatus::InvalidState(why)
    }
}

fn all_finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

/// The first argument of a tick whose length differs from the model's.
#[inline]
fn size_problem(
    model: &Model,
    controller: &Controller,
    q: &[f64],
    qd: &[f64],
    nominal: &Nominal<'_>,
) -> Option<InvalidState> {
    let nq = model.nq();
    let (a, b, c) = match nominal {
        Nominal::Track(reference) => (
            ("reference q̄", reference.q.len()),
            ("reference q̄̇", reference.qd.len()),
            ("reference q̄̈", reference.qdd.len()),
        ),
        Nominal::Force(force) => (
            ("nominal τ", force.len()),
            ("nominal τ", force.len()),
            ("nominal τ", force.len()),
        ),
    };
    [
        (
            "controller (built for another model): nq",
            controller.nq,
            nq,
        ),
        (
            "controller (built for another model): nb",
            controller.nb,
            model.nb(),
        ),
        ("q", q.len(), nq),
        ("q̇", qd.len(), nq),
        (a.0, a.1, nq),
        (b.0, b.1, nq),
        (c.0, c.1, nq),
    ]
    .into_iter()
    .find(|(_, got, expected)| got != expected)
    .map(|(what, got, expected)| InvalidState::Size {
        what,
        expected,
        got,
    })
}

/// One control tick at state `(q, q̇)` toward `reference`: evaluates `M`, `h`, `G`, the
/// barriers with their Jacobians and `J̇ q̇` (one [`model_terms`] call), the PD+ torque
/// `τ_nom = M q̄̈ + h + G + K q̄ + D q̄̇ + K_P (q̄ − q) + K_D (q̄̇ − q̇)` (docs/model.md §5) and,
/// with the filter on, the HOCBF rows and the QP. The command lands in
/// [`Controller::tau`] \[N\]; it is always finite (zero, the unactuated robot, when no
/// computed command can be trusted, or when the state lies outside the model's domain).
/// Allocates nothing.
///
/// Arguments: `model` is the one `controller` was built for; `q` \[m\] and `q̇` \[m/s\]
/// have `nq` entries each, and so do the reference's `q̄` \[m\], `q̄̇` \[m/s\] and `q̄̈`
/// \[m/s²\]. A wrong length is [`InvalidState::Size`] (checked first: a few compares).
pub fn tick(
    model: &Model,
    controller: &mut Controller,
    q: &[f64],
    qd: &[f64],
    reference: Reference<'_>,
) -> TickStatus {
    tick_nominal(model, controller, q, qd, Nominal::Track(reference))
}

/// [`tick`] with the nominal command given as a generalized force `tau_nom` \[N\] instead
/// of the PD+ law: the filter (if on) keeps the barriers over it, as over PD+. An
/// identification experiment's feed-forward tensions pass through here.
pub fn tick_feedforward(
    model: &Model,
    controller: &mut Controller,
    q: &[f64],
    qd: &[f64],
    tau_nom: &[f64],
) -> TickStatus {
    tick_nominal(model, controller, q, qd, Nominal::Force(tau_nom))
}

/// [`tick`] for either kind of nominal command.
pub fn tick_nominal(
    model: &Model,
    controller: &mut Controller,
    q: &[f64],
    qd: &[f64],
    nominal: Nominal<'_>,
) -> TickStatus {
    controller.dynamics_valid = false;
    if let Some(certified) = controller.certified.as_mut() {
        certified.proven = false;
    }
    if let Some(why) = size_problem(model, controller, q, qd, &nominal) {
        return controller.fallback(why);
    }
    let nq = controller.nq;
    let finite = match nominal {
        Nominal::Track(reference) => [q, qd, reference.q, reference.qd, reference.qdd],
        Nominal::Force(force) => [q, qd, force, force, force],
    };
    if !finite.into_iter().all(all_finite) {
        return controller.fallback(InvalidState::NonFinite);
    }
    if softcbf_description::domain::state_problem(&model.robot, q, qd).is_some() {
        return controller.fallback(InvalidState::OutOfDomain);
    }

    let evaluated = model_terms(
        model,
        &mut controller.dynamics,
        &mut controller.barrier_terms,
        q,
        qd,
    )
    .and_then(|()| factor_mass_matrix(&mut controller.dynamics));
    if let Err(error) = evaluated {
        return controller.fallback(match error {
            DynamicsError::NotPositiveDefinite => InvalidState::MassMatrix,
            DynamicsError::NonFinite => InvalidState::NonFiniteModel,
            DynamicsError::Size {
                what,
                expected,
                got,
            } => InvalidState::Size {
                what,
                expected,
                got,
            },
        });
    }
    let (state_q, state_qd) = controller.dynamics_state.split_at_mut(nq);
    state_q.copy_from_slice(q);
    state_qd.copy_from_slice(qd);
    controller.dynamics_valid = true;
    let barriers = &controller.barrier_terms;

    // τ_nom, and n = h + G + K q + D q̇.
    let settings = &controller.settings;
    let ws = &controller.dynamics;
    let (tau_nom, drift) = (&mut controller.tau_nom, &mut controller.drift);
    with_const_size!(nq, [3, 6, 9, 12], |nq| {
        nominal_and_drift(model, settings, ws, q, qd, nominal, tau_nom, drift, nq)
    });
    if !(all_finite(&controller.tau_nom)
        && all_finite(&controller.drift)
        && all_finite(barriers.values())
        && all_finite(barriers.jacobian())
        && all_finite(barriers.jdot_qd()))
    {
        return controller.fallback(InvalidState::NonFiniteModel);
    }
    if !settings.filter {
        controller.tau.copy_from_slice(&controller.tau_nom);
        return TickStatus::Unfiltered;
    }
    if controller.certified.is_some() {
        return certified_filter(model, controller, q, qd);
    }
    if controller.sampled.is_some() {
        return sampled_filter(model, controller, q, qd);
    }

    // Rows A_k = J_k M⁻¹ and right-hand sides J_k M⁻¹ n − J̇q̇_k − (p1+p2) J_k q̇ − p1 p2 b_k
    // (with the hold correction: S⁻¹ for M⁻¹ and n + Δ K q̇ for n).
    // A barrier depends on few coordinates (its module's), so zero entries of J are skipped.
    let hold = match settings.safety {
        SafetyMode::Paper => 0.0,
        SafetyMode::HoldCorrection | SafetyMode::Predicted | SafetyMode::Certified => settings.hold,
    };
    let scale = controller.gain_scale;
    let factor = if hold > 0.0 {
        // S = M + Δ D + Δ² K, and n + Δ K q̇ (K, D diagonal).
        controller.hold_factor.copy_from_slice(&ws.mass_matrix);
        let diagonals = model.stiffness.iter().zip(&model.damping).zip(qd);
        for (i, ((k, d), v)) in diagonals.enumerate() {
            controller.hold_factor[i * nq + i] += hold * d + hold * hold * k;
            controller.drift[i] += hold * k * v;
        }
        if !cholesky_in_place(&mut controller.hold_factor, nq) {
            return controller.fallback(InvalidState::MassMatrix);
        }
        &controller.hold_factor
    } else {
        &ws.cholesky
    };
    cholesky_solve(factor, nq, &mut controller.drift);
    cholesky_inverse(
        factor,
        nq,
        &mut controller.inverse_mass,
        &mut controller.scratch,
    );
    let paper = PaperRows {
        nb: controller.nb,
        jacobian: barriers.jacobian(),
        jdot_qd: barriers.jdot_qd(),
        values: barriers.values(),
        gains: &controller.barrier_gains,
        scale,
        inverse_mass: &controller.inverse_mass,
        drift: &controller.drift,
        qd,
    };
    let (rows, rhs) = (&mut controller.rows, &mut controller.rhs);
    with_const_size!(nq, [3, 6, 9, 12], |nq| paper.write(rows, rhs, nq));
    solve_rows(controller)
}

/// `τ_nom` (PD+ toward the reference, or the given force) and `n = h + G + K q + D q̇` of
/// [`tick_nominal`], with `nq` a compile-time constant for the usual sizes
/// ([`with_const_size`]).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn nominal_and_drift(
    model: &Model,
    settings: &ControllerSettings,
    ws: &DynamicsWorkspace,
    q: &[f64],
    qd: &[f64],
    nominal: Nominal<'_>,
    tau_nom: &mut [f64],
    drift: &mut [f64],
    nq: usize,
) {
    let (q, qd) = (&q[..nq], &qd[..nq]);
    for i in 0..nq {
        tau_nom[i] = match nominal {
            Nominal::Track(reference) => {
                let (r_q, r_qd) = (&reference.q[..nq], &reference.qd[..nq]);
                let row = i * nq..(i + 1) * nq;
                let inertial = dot(&ws.mass_matrix[row], &reference.qdd[..nq]);
                let mut feedback = 0.0;
                for j in 0..nq {
                    feedback += settings.kp[i * nq + j] * (r_q[j] - q[j])
                        + settings.kd[i * nq + j] * (r_qd[j] - qd[j]);
                }
                inertial
                    + ws.nonlinear[i]
                    + model.stiffness[i] * r_q[i]
                    + model.damping[i] * r_qd[i]
                    + feedback
            }
            Nominal::Force(force) => force[i],
        };
        drift[i] = ws.nonlinear[i] + model.stiffness[i] * q[i] + model.damping[i] * qd[i];
    }
}

/// What the paper's rows are made of (see [`tick_nominal`]).
struct PaperRows<'a> {
    /// Barriers: the first `nb` rows (input limits follow).
    nb: usize,
    jacobian: &'a [f64],
    jdot_qd: &'a [f64],
    values: &'a [f64],
    gains: &'a [[f64; 2]],
    scale: f64,
    inverse_mass: &'a [f64],
    drift: &'a [f64],
    qd: &'a [f64],
}

impl PaperRows<'_> {
    /// Writes the rows `J_k M⁻¹` and right-hand sides of every barrier `k`, with `nq` a
    /// compile-time constant for the usual sizes ([`with_const_size`]).
    #[inline(always)]
    fn write(&self, rows: &mut [f64], rhs: &mut [f64], nq: usize) {
        let (drift, qd) = (&self.drift[..nq], &self.qd[..nq]);
        let inverse_mass = &self.inverse_mass[..nq * nq];
        for (k, (jacobian_row, row)) in self
            .jacobian
            .chunks_exact(nq)
            .zip(rows.chunks_exact_mut(nq))
            .enumerate()
            .take(self.nb)
        {
            let [p1, p2] = self.gains[k].map(|p| p * self.scale);
            row.fill(0.0);
            for (&j, inverse_row) in jacobian_row.iter().zip(inverse_mass.chunks_exact(nq)) {
                if j != 0.0 {
                    for (a, m) in row.iter_mut().zip(inverse_row) {
                        *a += j * m;
                    }
                }
            }
            rhs[k] = dot(jacobian_row, drift)
                - self.jdot_qd[k]
                - (p1 + p2) * dot(jacobian_row, qd)
                - p1 * p2 * self.values[k];
        }
    }
}

/// The sampled-data rows and their QP passes (docs/model.md §5): for every barrier `k` and
/// sample `t_j` of the hold, `b_k(q(t_j)) ≥ max(ψ_k(t_j), 0)`, linearized in `τ` with the
/// sensitivity `Γ_j = ∂q(t_j)/∂τ` of [`HoldPrediction`]. The first pass predicts `q(t_j)`
/// by the linearized dynamics (`q₀ + a_j + Γ_j (τ − g₀)`); each further pass integrates the
/// nonlinear plant under the previous pass's command `τ'` and keeps
/// `b_k(q'(t_j)) + J_k(q'(t_j)) Γ_j (τ − τ') ≥ max(ψ_k(t_j), 0)`.
pub(super) fn sampled_filter(
    model: &Model,
    controller: &mut Controller,
    q: &[f64],
    qd: &[f64],
) -> TickStatus {
    let (nq, nb) = (controller.nq, controller.nb);
    let Some(sampled) = controller.sampled.as_mut() else {
        return controller.fallback(InvalidState::NonFiniteModel);
    };
    let ws = &controller.dynamics;
    cholesky_inverse(
        &ws.cholesky,
        nq,
        &mut controller.inverse_mass,
        &mut controller.scratch,
    );
    let hold = controller.settings.hold;
    if !hold_linearization(model, sampled, q, qd)
        || (sampled.robust.is_some() && !gravity_stiffness(model, sampled, q))
    {
        return controller.fallback(InvalidState::NonFiniteModel);
    }
    let predicted = sampled.prediction.predict(
        &controller.inverse_mass,
        &sampled.stiffness,
        &sampled.damping,
        qd,
        hold,
    );
    if !predicted {
        return controller.fallback(InvalidState::NonFiniteModel);
    }
    for i in 0..nq {
        // n(q₀ + e, q̇) ≈ n₀ + N_q e + N_v (q̇ − q̇₀), N_v = ∂h/∂q̇ = D̃ − D: the constant
        // part of the linear model's forcing is g₀ = n₀ + K q₀ − N_v q̇₀.
        sampled.plain_offset[i] = ws.nonlinear[i] + model.stiffness[i] * q[i];
        let row = &sampled.damping[i * nq..(i + 1) * nq];
        sampled.offset[i] = sampled.plain_offset[i] - dot(row, qd) + model.damping[i] * qd[i];
    }
    let m = sampled.prediction.samples();
    let barriers = &controller.barrier_terms;
    let scale = controller.gain_scale;
    for k in 0..nb {
        let [p1, p2] = controller.barrier_gains[k].map(|p| p * scale);
        let b = barriers.values()[k];
        // The floor decays at the rate p1; an approach already faster than p1·b (from the
        // previous command) is given the time 1/p2 to slow down, and no credit is taken for
        // a barrier moving away.
        let b_dot = dot(&barriers.jacobian()[k * nq..(k + 1) * nq], qd).min(-p1 * b);
        // Below zero already (a disturbance, a plant off the model), the floor is the
        // comparison curve itself: back toward zero at the rate p1, not at once.
        let lowest = if b >= 0.0 { 0.0 } else { f64::NEG_INFINITY };
        for j in 0..m {
            let t = sampled.prediction.time(j);
            sampled.floor[j * nb + k] = comparison(b, b_dot, p1, p2, t).max(lowest);
        }
        sampled.start_values[k] = b;
    }
    sampled.dip.fill(0.0);

    // Pass 1: b_k(q₀ + e) ≈ b_k + J_k e.
    for j in 0..m {
        let (free, forced) = (sampled.prediction.free(j), sampled.prediction.forced(j));
        for k in 0..nb {
            let jacobian_row = &barriers.jacobian()[k * nq..(k + 1) * nq];
            let r = j * nb + k;
            let row = &mut controller.rows[r * nq..(r + 1) * nq];
            forced_row(jacobian_row, forced, nq, row);
            controller.rhs[r] = sampled.floor[r] - barriers.values()[k] - dot(jacobian_row, free)
                + dot(row, &sampled.offset);
        }
    }
    // The end of the hold: ḃ + p1 b ≥ 0 there, with ḃ ≈ J (ȧ + Γ̇ u), b ≈ b + J (a + Γ u).
    let end = EndRows {
        prediction: &sampled.prediction,
        barriers,
        gains: &controller.barrier_gains,
        scale,
        offset: &sampled.offset,
    };
    end.write(m, &mut controller.rows, &mut controller.rhs);
    if let Some(rates) = controller.rates.as_ref() {
        rates.write_linear(
            &sampled.prediction,
            &sampled.offset,
            qd,
            &mut controller.rows,
            &mut controller.rhs,
        );
    }
    let mut status = solve_giving_way(controller, m);
    // Each pass integrates the plant under the last command and linearizes the rows there.
    // After the settings' passes, a command is kept only once its own integrated motion
    // meets its samples' rows (within CHECK_TOLERANCE): a last solve may move the command
    // so far that the linearization misses (tens of newtons on a bending coordinate, a few
    // millimetres of a corner) and its end row too; then further passes follow, and if none
    // is met the command that missed least is kept (the samples' rows first, then the end
    // row).
    let passes = controller.settings.sampled.passes;
    let mut best_miss = (true, f64::INFINITY);
    let mut best_gave_way = GaveWay::Nothing;
    for pass in 1..passes + CHECK_PASSES {
        // A relaxed problem misses its rows by design: no check.
        // A loop with a deadline (the hardware loop) keeps the settings' passes only: the
        // check's further passes may take several integrations each.
        let checking = passes > 1
            && pass >= passes
            && status == TickStatus::Filtered
            && controller.compute_budget.is_infinite();
        if status.is_fallback() || (pass >= passes && !checking) {
            break;
        }
        let Some(sampled) = controller.sampled.as_mut() else {
            break;
        };
        sampled.guess.copy_from_slice(&controller.tau);
        let written = (m + 1) * nb;
        if checking {
            // The rows the command was solved for, kept while this pass rewrites them.
            sampled.solved_rows[..written * nq].copy_from_slice(&controller.rows[..written * nq]);
            sampled.solved_rhs[..written].copy_from_slice(&controller.rhs[..written]);
        }
        // The robust margin at the settings' passes' commands; a check keeps it, so that
        // the rows it measures against do not move with the command.
        if let Some(robust) = sampled.robust.as_mut().filter(|_| !checking) {
            let inputs = MarginInputs {
                model,
                horizon: controller.settings.hold + controller.margin_age,
                nominal_stiffness: &sampled.gravity_stiffness,
                nominal_offset: &sampled.plain_offset,
                inverse_mass: &controller.inverse_mass,
                jacobian: controller.barrier_terms.jacobian(),
                gains: &controller.barrier_gains,
                scale,
                guess: &sampled.guess,
                q,
                qd,
            };
            let computed = robust_margin(robust, &inputs, &controller.rows, &controller.rhs);
            if !computed {
                return controller.fallback(InvalidState::NonFiniteModel);
            }
        }
        sampled.plant.tau_mut().copy_from_slice(&controller.tau);
        sampled.state[..nq].copy_from_slice(q);
        sampled.state[nq..].copy_from_slice(qd);
        sampled.start.copy_from_slice(&sampled.state);
        sampled.integrator.reset();
        let mut time = 0.0;
        // How far the command's own motion misses its samples' rows [m] (infinite where
        // the integration stops short).
        let mut miss = f64::NEG_INFINITY;
        let mut end_miss = f64::NEG_INFINITY;
        for j in 0..m {
            // The motion under the previous command, integrated to t_j; where the
            // integration fails or leaves the model's domain, the rows of the previous pass
            // stay for this sample and every later one.
            if !sampled.advance(model, &mut time, j, checking) {
                miss = f64::INFINITY;
                break;
            }
            if checking {
                // Between the samples: where the motion dipped below zero (below the
                // floors, for a barrier already below), the rows of the two samples around
                // the dip are raised by more than its depth for the next pass.
                for k in 0..nb {
                    let below = sampled.shortfall[k];
                    if below > CHECK_TOLERANCE {
                        miss = miss.max(below);
                        let raise = DIP_INFLATION * below;
                        sampled.dip[j * nb + k] += raise;
                        if j > 0 {
                            let r = (j - 1) * nb + k;
                            sampled.dip[r] += raise;
                            controller.rhs[r] += raise;
                        }
                    }
                }
            }
            let forced = sampled.prediction.forced(j);
            for k in 0..nb {
                let jacobian_row = &sampled.jacobian[k * nq..(k + 1) * nq];
                let r = j * nb + k;
                let margin = sampled
                    .robust
                    .as_ref()
                    .map_or(0.0, |robust| robust.margin[r])
                    + sampled.dip[r];
                miss = miss.max(sampled.floor[r] + margin - sampled.values[k]);
                sampled.sample_values[r] = sampled.values[k];
                let row = &mut controller.rows[r * nq..(r + 1) * nq];
                forced_row(jacobian_row, forced, nq, row);
                controller.rhs[r] =
                    sampled.floor[r] - sampled.values[k] + dot(row, &sampled.guess) + margin;
            }
            if let Some(rates) = controller.rates.as_ref() {
                let slots = RateRows::samples(&sampled.prediction);
                for (slot, &at) in slots.iter().enumerate() {
                    if at == j {
                        rates.write_at(
                            &sampled.prediction,
                            slot,
                            [qd, &sampled.state[nq..]],
                            &sampled.guess,
                            &mut controller.rows,
                            &mut controller.rhs,
                        );
                    }
                }
            }
            if j + 1 == m {
                let forced_velocity = sampled.prediction.end_velocity_forced();
                let velocity = &sampled.state[nq..];
                for k in 0..nb {
                    let p1 = controller.barrier_gains[k][0] * scale;
                    let jacobian_row = &sampled.jacobian[k * nq..(k + 1) * nq];
                    let r = m * nb + k;
                    let margin = sampled
                        .robust
                        .as_ref()
                        .map_or(0.0, |robust| robust.margin[r]);
                    // The end row's miss in metres: how far `ḃ + p1 b` falls short, over p1.
                    let psi = dot(jacobian_row, velocity) + p1 * sampled.values[k];
                    end_miss = end_miss.max((margin - psi) / p1);
                    sampled.end_values[k] = psi;
                    let row = &mut controller.rows[r * nq..(r + 1) * nq];
                    end_row(jacobian_row, forced, forced_velocity, p1, nq, row);
                    controller.rhs[r] = -dot(jacobian_row, velocity) - p1 * sampled.values[k]
                        + dot(row, &sampled.guess)
                        + sampled
                            .robust
                            .as_ref()
                            .map_or(0.0, |robust| robust.margin[r]);
                }
            }
        }
        if checking {
            if miss <= CHECK_TOLERANCE && end_miss <= CHECK_TOLERANCE {
                // The command stays, with the rows it was solved for.
                controller.rows[..written * nq]
                    .copy_from_slice(&sampled.solved_rows[..written * nq]);
                controller.rhs[..written].copy_from_slice(&sampled.solved_rhs[..written]);
                break;
            }
            // The samples' rows first (they keep the barriers over this hold), then the end
            // row (it keeps the next hold's start where its floors ask nothing the velocity
            // does not give).
            let key = if miss <= CHECK_TOLERANCE {
                (false, end_miss)
            } else {
                (true, miss)
            };
            if key < best_miss {
                best_miss = key;
                sampled.best.copy_from_slice(&sampled.guess);
                sampled.best_rows[..written * nq]
                    .copy_from_slice(&sampled.solved_rows[..written * nq]);
                sampled.best_rhs[..written].copy_from_slice(&sampled.solved_rhs[..written]);
                best_gave_way = controller.gave_way;
            }
            if miss.is_finite() && pass + 1 < passes + CHECK_PASSES {
                // The next solve takes the samples' rows' sensitivity to the command from
                // the plant itself (the linear model's was not good enough here).
                sensitivity_rows(model, controller, m);
            }
            let Some(sampled) = controller.sampled.as_mut() else {
                break;
            };
            if pass + 1 == passes + CHECK_PASSES {
                // No command met its rows: the one that missed least, with its rows.
                if best_miss.1.is_finite() {
                    controller.tau.copy_from_slice(&sampled.best);
                    controller.rows[..written * nq]
                        .copy_from_slice(&sampled.best_rows[..written * nq]);
                    controller.rhs[..written].copy_from_slice(&sampled.best_rhs[..written]);
                    controller.gave_way = best_gave_way;
                } else {
                    controller.rows[..written * nq]
                        .copy_from_slice(&sampled.solved_rows[..written * nq]);
                    controller.rhs[..written].copy_from_slice(&sampled.solved_rhs[..written]);
                }
                break;
            }
        }
        status = solve_giving_way(controller, m);
        if checking && pass > passes && status == TickStatus::Filtered {
            // From the second step on the plant's own sensitivity, half the step: where the
            // first step missed, full steps can alternate between two commands that each
            // miss (on robots/three-square.toml two commands 50 N apart on a bending
            // coordinate, each 10 µm short of a corner's rows, and the corner 10 µm below
            // zero; with half steps 7e-8 m, docs/model.md §5).
            if let Some(sampled) = controller.sampled.as_ref() {
                for (t, g) in controller.tau.iter_mut().zip(&sampled.guess) {
                    *t = 0.5 * (*t + g);
                }
            }
        }
    }
    status
}

/// The samples' rows `b_k(q'(t_j)) + S_kj (τ − τ') ≥ floor + margin` (and the end rows,
/// `ψ_k(Δ) + S_k (τ − τ') ≥ margin` with `ψ = ḃ + p1 b`, alike) with the sensitivity
/// `S_kj = ∂b_k(q(t_j))/∂τ` of the plant itself at the last command `τ'` (the guess), by
/// forward differences: one integration of the plant over the hold per coordinate, under
/// `τ'` with that coordinate's entry raised by `SENSITIVITY_STEP` (relative). Where such an
/// integration stops short, the columns of the later samples keep the linear model's
/// `J_k Γ_j`. Needs the barrier values at the samples under `τ'` in `sample_values` (`m`
/// samples, `nb` each), `ψ_k(Δ)` under `τ'` in `end_values`, and the rows written for `τ'`.
fn sensitivity_rows(model: &Model, controller: &mut Controller, m: usize) {
    let (nq, nb) = (controller.nq, controller.nb);
    let Some(sampled) = controller.sampled.as_mut() else {
        return;
    };
    for c in 0..nq {
        let step = SENSITIVITY_STEP * (1.0 + sampled.guess[c].abs());
        sampled.plant.tau_mut().copy_from_slice(&sampled.guess);
        sampled.plant.tau_mut()[c] += step;
        sampled.state[..nq].copy_from_slice(&sampled.start[..nq]);
        sampled.state[nq..].copy_from_slice(&sampled.start[nq..]);
        sampled.integrator.reset();
        let mut time = 0.0;
        for j in 0..m {
            if !sampled.advance(model, &mut time, j, false) {
                break;
            }
            for k in 0..nb {
                let r = j * nb + k;
                controller.rows[r * nq + c] = (sampled.values[k] - sampled.sample_values[r]) / step;
            }
            if j + 1 == m {
                // The end row's `ḃ + p1 b`: its sensitivity too (the linear model's end
                // velocity can be far off where the plant is stiff and the motion large).
                let velocity = &sampled.state[nq..];
                for k in 0..nb {
                    let p1 = controller.barrier_gains[k][0] * controller.gain_scale;
                    let jacobian_row = &sampled.jacobian[k * nq..(k + 1) * nq];
                    let psi = dot(jacobian_row, velocity) + p1 * sampled.values[k];
                    let r = m * nb + k;
                    controller.rows[r * nq + c] = (psi - sampled.end_values[k]) / step;
                }
            }
        }
    }
    for r in 0..(m + 1) * nb {
        let margin = sampled
            .robust
            .as_ref()
            .map_or(0.0, |robust| robust.margin[r]);
        let row = &controller.rows[r * nq..(r + 1) * nq];
        let (floor, value) = if r < m * nb {
            (sampled.floor[r] + sampled.dip[r], sampled.sample_values[r])
        } else {
            (0.0, sampled.end_values[r - m * nb])
        };
        controller.rhs[r] = floor - value + dot(row, &sampled.guess) + margin;
    }
}

/// The relative step of [`sensitivity_rows`]' differences (of `1 + |τ_c|` newtons).
const SENSITIVITY_STEP: f64 = 1e-5;

/// Passes after the settings' ones, where the command's own motion misses its rows. From
/// the second on each moves half the way, which about halves a miss per pass where the
/// plant's sensitivity is right; with four, `tests/data/three-square-check-passes.toml`
/// kept a command whose corner went 1.59e-6 m below zero (docs/model.md §5).
const CHECK_PASSES: usize = 8;
/// How far a command's integrated motion may miss its samples' rows and be kept \[m\]:
/// the rows are linearized at the previous command, and a command that meets them misses
/// by the linearization's second-order remainder.
const CHECK_TOLERANCE: f64 = 1e-8;
/// Where the check finds a barrier dipping between two samples, the two samples' rows are
/// raised by this times the dip's depth (the dip of the next command's motion is about as
/// deep as this one's, lifted by what the samples are).
const DIP_INFLATION: f64 = 1.5;

/// Which of the predicted rows gave way on the last tick, where they had no common point:
/// the end-of-hold rows' robust margins first, before any row is relaxed (docs/model.md §5,
/// "When the rows have no common point").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GaveWay {
    /// None: the command meets every row as written.
    #[default]
    Nothing,
    /// The end-of-hold rows' robust margins (the command meets every other row as
    /// written, and the end rows without their margins).
    EndMargins,
}

/// Solves the predicted rows (`m` samples and the end of the hold, `nb` barriers each);
/// where they have no common point, the end-of-hold rows' robust margins give way before
/// any row is relaxed. Those rows do not keep a barrier over this hold: they keep the next
/// hold's first samples from asking more than the velocity gives (a floor is never below
/// zero while its barrier is above it, whatever the velocity, docs/model.md §5), and their
/// margin asks that of every plant in the box; the samples' rows, which keep the barriers
/// over this hold with their margins, stay as written. Only if those rows have no common
/// point either is the problem relaxed (status `Relaxed`). The samples' floors do not give
/// way: letting them go (keeping only `b ≥ 0` at the samples) was tried on the hardware
/// walk-through and drove module 1 10–17 mm past its limit, because cables that only pull
/// cannot brake an approach the floors did not slow in time. Which rows gave way is in
/// [`Controller::gave_way`].
fn solve_giving_way(controller: &mut Controller, m: usize) -> TickStatus {
    controller.gave_way = GaveWay::Nothing;
    if let Some(status) = try_rows(controller) {
        return status;
    }
    let written = (m + 1) * controller.nb;
    if let Some(sampled) = controller.sampled.as_mut()
        && let Some(robust) = sampled.robust.as_ref()
    {
        sampled.written[..written].copy_from_slice(&controller.rhs[..written]);
        for r in m * controller.nb..written {
            controller.rhs[r] -= robust.margin[r];
        }
        if let Some(status) = try_rows(controller) {
            controller.gave_way = GaveWay::EndMargins;
            return status;
        }
        if let Some(sampled) = controller.sampled.as_ref() {
            controller.rhs[..written].copy_from_slice(&sampled.written[..written]);
        }
    }
    solve_rows(controller)
}

/// Step of the central differences of `n = h + G` \[m, m/s\]: their truncation error
/// (`~δ² n‴`; none in the speeds, in which `h` is quadratic) and rounding error
/// (`~ε n / δ`) are both far below 1e-9 of `n` here.
const GRAVITY_STEP: f64 = 1e-6;

/// The hold's linear model at the tick's state `(q, q̇)` (`nq` each, m and m/s) into
/// `sampled.stiffness` (`K̃ = K + ∂n/∂q` \[N/m\]) and `sampled.damping` (`D̃ = D + ∂h/∂q̇`
/// \[N·s/m\]), `n = h + G`, both row-major `nq × nq`, by central differences of `n` (steps
/// `GRAVITY_STEP` in each coordinate and speed). The Coriolis and centrifugal terms' share
/// matters where modules move fast: on `robots/three-square.toml` (soft in elongation) a
/// prediction without it missed its own rows by millimetres over a 30 ms hold. `false`
/// where the dynamics cannot be evaluated.
fn hold_linearization(
    model: &Model,
    sampled: &mut SampledWorkspace,
    q: &[f64],
    qd: &[f64],
) -> bool {
    let nq = q.len();
    sampled.stiffness.fill(0.0);
    sampled.damping.fill(0.0);
    for c in 0..nq {
        for speed in [false, true] {
            for (sign, weight) in [(1.0, 0.5 / GRAVITY_STEP), (-1.0, -0.5 / GRAVITY_STEP)] {
                sampled.perturbed.copy_from_slice(q);
                sampled.perturbed_velocity.copy_from_slice(qd);
                if speed {
                    sampled.perturbed_velocity[c] += sign * GRAVITY_STEP;
                } else {
                    sampled.perturbed[c] += sign * GRAVITY_STEP;
                }
                let evaluated = update_joints(
                    model,
                    &mut sampled.gravity,
                    &sampled.perturbed,
                    &sampled.perturbed_velocity,
                )
                .and_then(|()| {
                    bias_and_gravity(model, &mut sampled.gravity, &sampled.perturbed_velocity)
                });
                if evaluated.is_err() || !all_finite(&sampled.gravity.nonlinear) {
                    return false;
                }
                let target = if speed {
                    &mut sampled.damping
                } else {
                    &mut sampled.stiffness
                };
                for r in 0..nq {
                    target[r * nq + c] += weight * sampled.gravity.nonlinear[r];
                }
            }
        }
    }
    for i in 0..nq {
        sampled.stiffness[i * nq + i] += model.stiffness[i];
        sampled.damping[i * nq + i] += model.damping[i];
    }
    true
}

/// `K + ∂G/∂q` at `q` into `sampled.gravity_stiffness` (the robust margin's), column by column from central
/// differences of `G`; `false` if a perturbed state leaves the domain or `G` is not finite.
fn gravity_stiffness(model: &Model, sampled: &mut SampledWorkspace, q: &[f64]) -> bool {
    let nq = q.len();
    sampled.gravity_stiffness.fill(0.0);
    for c in 0..nq {
        for (sign, weight) in [(1.0, 0.5 / GRAVITY_STEP), (-1.0, -0.5 / GRAVITY_STEP)] {
            sampled.perturbed.copy_from_slice(q);
            sampled.perturbed[c] += sign * GRAVITY_STEP;
            let evaluated = update_joints(
                model,
                &mut sampled.gravity,
                &sampled.perturbed,
                &sampled.zero,
            )
            .and_then(|()| bias_and_gravity(model, &mut sampled.gravity, &sampled.zero));
            if evaluated.is_err() || !all_finite(&sampled.gravity.gravity) {
                return false;
            }
            for r in 0..nq {
                sampled.gravity_stiffness[r * nq + c] += weight * sampled.gravity.gravity[r];
            }
        }
    }
    for (i, k) in model.stiffness.iter().enumerate() {
        sampled.gravity_stiffness[i * nq + i] += k;
    }
    true
}

/// `row = J_k Γ_j` (`Γ_j` row-major `nq × nq`), skipping the zero entries of `J_k`.
fn forced_row(jacobian_row: &[f64], forced: &[f64], nq: usize, row: &mut [f64]) {
    row.fill(0.0);
    for (c, &j) in jacobian_row.iter().enumerate() {
        if j != 0.0 {
            for (a, g) in row.iter_mut().zip(&forced[c * nq..(c + 1) * nq]) {
                *a += j * g;
            }
        }
    }
}

/// The rows `ḃ_k + p1 b_k ≥ 0` at the end of the hold, one per barrier, after `samples`
/// rows per barrier (the predicted and the certified rows alike): `J_k (Γ̇ + p1 Γ) τ ≥
/// −J_k ȧ − p1 (b_k + J_k a) + J_k (Γ̇ + p1 Γ) g₀`, with `a`, `Γ` at the last sample.
struct EndRows<'a> {
    prediction: &'a HoldPrediction,
    barriers: &'a BarrierTerms,
    gains: &'a [[f64; 2]],
    /// The loop's gain scale (nominal / achieved period).
    scale: f64,
    /// `g₀`, the command's offset `τ = u + g₀`.
    offset: &'a [f64],
}

impl EndRows<'_> {
    fn write(&self, samples: usize, rows: &mut [f64], rhs: &mut [f64]) {
        let nq = self.offset.len();
        let nb = self.gains.len();
        let p = self.prediction;
        let (free, forced) = (p.free(samples - 1), p.forced(samples - 1));
        let (free_velocity, forced_velocity) = (p.end_velocity_free(), p.end_velocity_forced());
        for k in 0..nb {
            let p1 = self.gains[k][0] * self.scale;
            let jacobian_row = &self.barriers.jacobian()[k * nq..(k + 1) * nq];
            let r = samples * nb + k;
            let row = &mut rows[r * nq..(r + 1) * nq];
            end_row(jacobian_row, forced, forced_velocity, p1, nq, row);
            rhs[r] = -dot(jacobian_row, free_velocity)
                - p1 * (self.barriers.values()[k] + dot(jacobian_row, free))
                + dot(row, self.offset);
        }
    }
}

/// `row = J_k (Γ̇ + p1 Γ)`: how `ḃ + p1 b` at the end of the hold moves with `τ`.
fn end_row(
    jacobian_row: &[f64],
    forced: &[f64],
    forced_velocity: &[f64],
    p1: f64,
    nq: usize,
    row: &mut [f64],
) {
    row.fill(0.0);
    for (c, &j) in jacobian_row.iter().enumerate() {
        if j != 0.0 {
            let columns = c * nq..(c + 1) * nq;
            for ((a, g), v) in row
                .iter_mut()
                .zip(&forced[columns.clone()])
                .zip(&forced_velocity[columns])
            {
                *a += j * (v + p1 * g);
            }
        }
    }
}

/// Checks the rows and solves the safety QP into `τ`.
fn solve_rows(controller: &mut Controller) -> TickStatus {
    if !(all_finite(&controller.rows) && all_finite(&controller.rhs)) {
        return controller.fallback(InvalidState::NonFiniteModel);
    }
    let status = controller
        .qp
        .solve(
            &controller.tau_nom,
            &controller.rows,
            &controller.rhs,
            &mut controller.tau,
        )
        .status;
    status_of(controller, status)
}

/// [`solve_rows`] for a command that is only tried (the certified attempts): where the rows
/// have no common point the relaxed problem is not solved and the status is `None` (`τ` is
/// then not a command; the caller computes another).
fn try_rows(controller: &mut Controller) -> Option<TickStatus> {
    if !(all_finite(&controller.rows) && all_finite(&controller.rhs)) {
        return Some(controller.fallback(InvalidState::NonFiniteModel));
    }
    let report = controller.qp.solve_strict(
        &controller.tau_nom,
        &controller.rows,
        &controller.rhs,
        &mut controller.tau,
    );
    (report.status == QpStatus::Solved).then_some(TickStatus::Filtered)
}

/// The tick's status for a QP's: a failed QP leaves the zero command.
fn status_of(controller: &mut Controller, status: QpStatus) -> TickStatus {
    match status {
        QpStatus::Solved => TickStatus::Filtered,
        QpStatus::Relaxed => TickStatus::Relaxed,
        QpStatus::Failed => {
            controller.tau.fill(0.0);
            TickStatus::QpFailed
        }
    }
}
