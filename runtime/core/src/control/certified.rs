//! The certified safety rows (docs/model.md §5, "The certified guarantee"): rows on the
//! command whose satisfaction proves every barrier non-negative at every instant of the
//! hold, for every plant inside the declared box, with the prediction's nonlinear remainder
//! bounded, not measured.
//!
//! Over one hold `[0, Δ]` the excursion `e = q − q₀` is predicted by the linear model
//! `M₀ ë + D ė + K e = u + φ(t)` (`u = τ − g₀`; `φ` a correction held constant over each cell
//! between samples: the nominal model's force mismatch `g = (M₀ − M(q)) ë + f₀ − h(q, ė) −
//! G(q)` at the cell's start on the uncorrected prediction). The error `ξ = e − e_L` obeys,
//! with the plant's own mass and Coriolis matrices,
//!
//! ```text
//! M_p(q) ξ̈ + [C_p(q, q̇) + C_p(q, ė_L) + D_p] ξ̇ + K ξ = F
//! F = g_p(q, ė_L, ë_L) − φ − ΔK q − ΔD ė_L + w
//! ```
//!
//! in which only the linear model's velocity and acceleration appear. In the plant's metric
//! `E = ½ ξ̇ᵀ M_p ξ̇ + ½ ξᵀ K ξ` the skew-symmetry of `Ṁ_p − 2 C_p` leaves
//! `Ė ≤ ξ̇ᵀF − (1 − κ) ξ̇ᵀ D ξ̇` (`κ` bounds `½ |ξ̇ᵀ Ṁ_p(ė_L) ξ̇|` by the damping), so
//! `∫ ξ̇ᵀ D′ ξ̇ ≤ Φ = ∫ Σ F̄_i²/D′_i` and `|ξ_i(t)| ≤ min(√(t Φ(t)/D′_i), √(2 Φ(t)/K_i))`;
//! where a floor `λ` of the smallest eigenvalue of `S⁻¹ M_p S⁻¹` (`S = diag √M₀ᵢᵢ`) is known
//! over the tube, also `|ξ_i(t)| ≤ 1/(Sᵢ λ) ∫₀ᵗ (t − s) ‖S⁻¹F̄(s)‖ ds` (short holds). No
//! acceleration of the plant enters. `F̄` comes from jets of `g`
//! over groups of cells ([`crate::enclosure::enclose_mismatch`]): its rate along the hold
//! (times the cell's length) and its change across the spread of the commands and of `ξ`.
//! The tube of positions the jets range over is the prediction widened by `|ξ|`: a fixed
//! point, checked. Each barrier along the predicted motion is bounded at the samples (Taylor
//! with the Jacobian's enclosure) and between them (`h²/8 sup |b̈|`), and the true barrier
//! differs from it by at most `|J| |ξ|`.

// The bounds below walk several row-major matrices and per-cell arrays in step with one
// index; iterator chains over four or five of them would hide the formulas.
#![allow(clippy::needless_range_loop)]

use std::ops::Range;
use std::time::Instant;

use softcbf_generated::{Dual, Interval};

use crate::dynamics::{DynamicsWorkspace, bias_and_gravity, mass_matrix, update_joints};
use crate::enclosure::{EnclosureWorkspace, enclose_mass_rate, enclose_mismatch};
use crate::hold::{HoldPrediction, comparison};
use crate::linalg::{cholesky_inverse, dot};
use crate::model::Model;

use super::{Controller, InvalidState, SampledSettings, TickStatus, try_rows};

/// Why a tick's command could not be certified (its status is
/// [`TickStatus::Uncertified`]; the command is the best one found, see there).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Uncertified {
    /// The error bound did not close: the tube of states it assumes is not shown to hold
    /// the motion, or the Coriolis rate over it rivals the damping (`κ` too large).
    Tube,
    /// The predicted motion or its tube reaches outside the model's domain, or an
    /// enclosure is not finite.
    Domain,
    /// A barrier is so close to zero at the tick, with the command changing the motion so
    /// fast, that its first instants cannot be bounded above zero.
    Start,
    /// The bound for the command dips below zero within the hold, at both attempts (the
    /// proven margins grew beyond what the rows assumed): `τ` satisfies the prediction's
    /// rows tightened by the last proven margins.
    Bound,
    /// The tick's time for the bound ([`super::Controller::set_compute_budget`]) ran out
    /// before an attempt was proven.
    Budget,
}

impl Uncertified {
    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Uncertified::Tube => "tube",
            Uncertified::Domain => "domain",
            Uncertified::Start => "start",
            Uncertified::Bound => "bound",
            Uncertified::Budget => "budget",
        }
    }
}

/// How many ticks were not proven over their hold, per reason ([`Uncertified`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct UncertifiedCounts {
    pub tube: usize,
    pub domain: usize,
    pub start: usize,
    pub bound: usize,
    pub budget: usize,
}

impl UncertifiedCounts {
    /// Counts one tick not proven for `why`.
    pub fn add(&mut self, why: Uncertified) {
        *match why {
            Uncertified::Tube => &mut self.tube,
            Uncertified::Domain => &mut self.domain,
            Uncertified::Start => &mut self.start,
            Uncertified::Bound => &mut self.bound,
            Uncertified::Budget => &mut self.budget,
        } += 1;
    }

    /// The reasons that occurred with their counts, most frequent first:
    /// `"bound 204, domain 23"` (empty when none did).
    pub fn describe(&self) -> String {
        let mut all = [
            (self.bound, Uncertified::Bound),
            (self.domain, Uncertified::Domain),
            (self.tube, Uncertified::Tube),
            (self.start, Uncertified::Start),
            (self.budget, Uncertified::Budget),
        ];
        all.sort_by_key(|(count, _)| std::cmp::Reverse(*count));
        all.iter()
            .filter(|(count, _)| *count > 0)
            .map(|(count, why)| format!("{} {count}", why.name()))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Why a bound failed; `place` names the step (for a reader of the code).
fn failed(why: Uncertified, place: &str) -> Uncertified {
    let _ = place;
    why
}

/// The error bound a fixed-point round assumes: the last computed one times this, plus
/// [`XI_FLOOR`].
const XI_INFLATION: f64 = 1.5;
/// \[m\]: keeps the assumed bound strictly above the computed one.
const XI_FLOOR: f64 = 1e-12;
/// Fixed-point rounds before the tube is given up.
const ROUNDS: usize = 6;
/// Largest `κ` (the Coriolis rate and the damping's uncertainty as a share of the
/// damping) the bound accepts.
const KAPPA_MAX: f64 = 0.9;
/// Early cells per group of jets (the early cells double in length; a group spans a factor
/// `2^GROUP` in time).
const GROUP: usize = 3;
/// The first cell is at most this fraction of the fastest mode's time constant long.
const FIRST_CELL: f64 = 0.25;
/// Inflation of quantities computed in floating point that a bound relies on (their
/// rounding is far below it).
const ROUNDING: f64 = 1.0 + 1e-12;

/// The linear model's motion over each cell for one command: boxes of `e`, `ė`, `ë`, `e⃛` over the cell, `nq` per cell.
struct Cells {
    e: Vec<Interval>,
    v: Vec<Interval>,
    a: Vec<Interval>,
    jerk: Vec<Interval>,
    /// `∫ |e⃛_i|` over the cell: at most `√(h E/D_i)`, since the unforced `(ë, e⃛)` system
    /// dissipates `∫ e⃛ᵀ D e⃛ ≤ E` of its energy `E` at the cell's start.
    jerk_variation: Vec<f64>,
}

impl Cells {
    fn new(len: usize) -> Cells {
        Cells {
            e: vec![Interval::ZERO; len],
            v: vec![Interval::ZERO; len],
            a: vec![Interval::ZERO; len],
            jerk: vec![Interval::ZERO; len],
            jerk_variation: vec![0.0; len],
        }
    }
}

/// Where a certified tick's time goes, summed over the ticks since the controller was made
/// \[s\]: the linear prediction and its correction (with the rows written from them), the
/// bound (error bound and barrier enclosures), the QPs, and on ticks no attempt proved, the
/// predicted rows' fallback command (its own prediction and QPs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CertifiedSplit {
    /// Ticks counted.
    pub ticks: u64,
    pub prediction: f64,
    pub bound: f64,
    pub qp: f64,
    pub fallback: f64,
    /// Ticks proven with a command between the predicted rows' and the backup (the state
    /// held), not the QP's.
    pub backups: u64,
}

/// Seconds since `mark`, and `mark` moved to now.
fn lap(mark: &mut Instant) -> f64 {
    let now = Instant::now();
    let elapsed = now.duration_since(*mark).as_secs_f64();
    *mark = now;
    elapsed
}

/// What the certified rows need besides the controller's own buffers.
pub(super) struct CertifiedWorkspace {
    nq: usize,
    /// Samples `S = L + m`; entry `j ∈ 0..=S` is time `t_j` (`t_0 = 0`, sample `j − 1`
    /// otherwise); cell `c ∈ 0..S` is `[t_c, t_{c+1}]`.
    samples: usize,
    /// Cells in groups that share one pair of jets (the early window's cells a few at a time,
    /// the rest together): the fine partition, and a coarse one of fewer, longer groups
    /// (cheaper, looser) that [`error_bounds`] uses when `coarse` is set.
    groups: Vec<Range<usize>>,
    coarse_groups: Vec<Range<usize>>,
    coarse: bool,
    /// Whether the next attempt tries the coarse partition first: while it proves the
    /// ticks (short holds), and again after `coarse_wait` fine attempts once it failed (a
    /// wait that doubles with every failure, from [`COARSE_RETRY`] up to [`COARSE_RETRY_MAX`],
    /// and halves with every success).
    coarse_first: bool,
    ticks_fine: usize,
    coarse_wait: usize,
    prediction: HoldPrediction,
    stiffness: Vec<f64>,
    /// `g₀ = f₀ + K q₀`.
    offset: Vec<f64>,
    /// Per entry (`(S + 1) × nq²`): `Γ` and `H = Γ̇`.
    gamma: Vec<f64>,
    h: Vec<f64>,
    /// Per entry (`(S + 1) × nq²`): `Γ₂ = ∫Γ = K⁻¹ (t I − M₀ H − D Γ)`, the response to a
    /// force growing as `t`.
    gamma2: Vec<f64>,
    /// Per entry (`(S + 1) × nq`): the free motion `a`, `ȧ` (`u = 0`, no correction).
    free: Vec<f64>,
    free_v: Vec<f64>,
    /// The correction `φ(t) = φ₀ + φ₁ t` (`nq` each) and, per entry, the mismatch `g` on the
    /// uncorrected center prediction and its residual `g − φ(t)` (`(S + 1) × nq`).
    phi0: Vec<f64>,
    phi1: Vec<f64>,
    mismatch: Vec<f64>,
    residual: Vec<f64>,
    /// The motion over each cell: the corrected prediction of the command, its uncorrected
    /// prediction, and the correction's own motion.
    center_cells: Cells,
    plain_cells: Cells,
    delta_cells: Cells,
    /// Per cell (`S × nq`): assumed and computed bounds on `|ξ|` over `[0, t_{c+1}]`, the
    /// forcing bound `F̄`, and `sup |ë_L|`.
    xi: Vec<f64>,
    xi_computed: Vec<f64>,
    force: Vec<f64>,
    /// Per cell: `‖S⁻¹F̄‖`.
    force_norm: Vec<f64>,
    /// Per cell: a lower bound of the plant's smallest mass eigenvalue over the cell's box
    /// (0 where none is known).
    mass_floor: Vec<f64>,
    /// A lower bound of `λ_min(S⁻¹ M₀ S⁻¹)`: `1/ρ(|S M₀⁻¹ S|)`, with `S = diag(√M₀ᵢᵢ)`
    /// (the scaling makes the floor one of the mass matrix's shape, not of its units).
    mass_floor0: f64,
    /// `S = diag(√M₀ᵢᵢ)` (`nq`).
    scale: Vec<f64>,
    acc_sup: Vec<f64>,
    /// The first attempt's command `u = τ − g₀`, and the box of later attempts (a fraction
    /// of it; infinite: no box).
    first_center: Vec<f64>,
    /// The predicted rows' command while [`backup`] tries the line from it.
    backup_tau: Vec<f64>,
    shrink: f64,
    /// The command being bounded, `u = τ − g₀`.
    center: Vec<f64>,
    /// Jets of one group and their result.
    q_jet: Vec<Dual>,
    v_jet: Vec<Dual>,
    a_jet: Vec<Dual>,
    g_jet: Vec<Dual>,
    /// Per group (`groups × nq`, `groups × nq²`): the rate of the residual along the
    /// uncorrected prediction and `|M₀ − M_p|` over its box, from the rate jet. They depend
    /// on the command and the partition, not on the tube, so the fixed point's later rounds
    /// reuse the first round's (`rates_ready`).
    group_rate: Vec<f64>,
    group_inertial: Vec<f64>,
    rates_ready: bool,
    enclosure: EnclosureWorkspace,
    /// The hold's hull of positions and of the linear velocities.
    hull_q: Vec<Interval>,
    hull_v: Vec<Interval>,
    /// `1 − κ`.
    damping_share: f64,
    /// `f64` model evaluations for the correction.
    dynamics: DynamicsWorkspace,
    /// Barrier enclosures over the hold's hull: values, Jacobian rows, `J̇q̇`.
    barrier_box: Vec<Interval>,
    jacobian_box: Vec<Interval>,
    jdot_box: Vec<Interval>,
    /// Barrier terms at the predicted points of the center command (`S × nb`,
    /// `S × nb × nq`).
    point: Vec<f64>,
    values: Vec<f64>,
    jacobian: Vec<f64>,
    jdot: Vec<f64>,
    zero: Vec<f64>,
    /// `max(ψ_k(t_j), 0)` and the row margins, sample-major (`S × nb`).
    floor: Vec<f64>,
    margin: Vec<f64>,
    /// Per sample row: how far the last proven lower bound lay below the linear prediction
    /// (the next first pass's tightening), the tightening the rows being bounded were
    /// written with, and the last error bounds (the next fixed point's start).
    estimate: Vec<f64>,
    row_estimate: Vec<f64>,
    /// Per barrier: the proven lower bound over the hold of the last command bounded, and
    /// whether the last tick's command is that command, proven.
    lowest: Vec<f64>,
    pub(super) proven: bool,
    last_xi: Vec<f64>,
    have_last: bool,
    scratch: Vec<f64>,
    vector: Vec<f64>,
    vector2: Vec<f64>,
    iterate: Vec<f64>,
    pub(super) split: CertifiedSplit,
}

impl CertifiedWorkspace {
    /// Early samples for `model` at hold `hold`: enough halvings of the first even step that
    /// the first cell is at most [`FIRST_CELL`] of the fastest velocity mode's time constant
    /// (`max_i Σ_j |M⁻¹|_ij D_j` at the rest configuration bounds its rate; bent states are
    /// taken as up to four times faster), and at least the settings' number.
    pub(super) fn early_samples(model: &Model, settings: &SampledSettings, hold: f64) -> usize {
        use crate::dynamics::factor_mass_matrix;
        let nq = model.nq();
        let mut ws = DynamicsWorkspace::new(model);
        let zero = vec![0.0; nq];
        let rate = update_joints(model, &mut ws, &zero, &zero)
            .and_then(|()| mass_matrix(model, &mut ws))
            .and_then(|()| factor_mass_matrix(&mut ws))
            .ok()
            .map(|()| {
                let mut inverse = vec![0.0; nq * nq];
                let mut work = vec![0.0; nq * nq];
                cholesky_inverse(&ws.cholesky, nq, &mut inverse, &mut work);
                (0..nq)
                    .map(|r| {
                        (0..nq)
                            .map(|c| inverse[r * nq + c].abs() * model.damping[c])
                            .sum::<f64>()
                    })
                    .fold(0.0, f64::max)
            })
            .unwrap_or(0.0);
        let even = hold / settings.samples.max(1) as f64;
        let wanted = if rate > 0.0 && even > 0.0 {
            ((even * 4.0 * rate / FIRST_CELL).log2().ceil()).max(0.0) as usize
        } else {
            0
        };
        wanted.max(settings.early).min(super::MAX_EARLY_SAMPLES)
    }

    pub(super) fn new(
        model: &Model,
        settings: &SampledSettings,
        early: usize,
    ) -> CertifiedWorkspace {
        let (nq, nb) = (model.nq(), model.nb());
        let samples = settings.samples + early;
        let s1 = samples + 1;
        let mut stiffness = vec![0.0; nq * nq];
        for (i, k) in model.stiffness.iter().enumerate() {
            stiffness[i * nq + i] = *k;
        }
        let early_cells = (early + 1).min(samples);
        let mut groups = Vec::new();
        let mut start = 0;
        while start < early_cells {
            let end = (start + GROUP).min(early_cells);
            groups.push(start..end);
            start = end;
        }
        // The rest of the hold in groups that double: the remains of the transient fade
        // early in it.
        let mut size = 1;
        while start < samples {
            let end = (start + size).min(samples);
            groups.push(start..end);
            start = end;
            size *= 2;
        }
        let coarse_groups = coarse_partition(&groups);
        let group_count = groups.len().max(coarse_groups.len());
        CertifiedWorkspace {
            nq,
            samples,
            groups,
            coarse_groups,
            coarse: false,
            coarse_first: true,
            ticks_fine: 0,
            coarse_wait: COARSE_RETRY,
            prediction: HoldPrediction::new(nq, settings.samples, early),
            stiffness,
            offset: vec![0.0; nq],
            gamma: vec![0.0; s1 * nq * nq],
            h: vec![0.0; s1 * nq * nq],
            gamma2: vec![0.0; s1 * nq * nq],
            free: vec![0.0; s1 * nq],
            free_v: vec![0.0; s1 * nq],
            phi0: vec![0.0; nq],
            phi1: vec![0.0; nq],
            mismatch: vec![0.0; s1 * nq],
            residual: vec![0.0; s1 * nq],
            center_cells: Cells::new(samples * nq),
            plain_cells: Cells::new(samples * nq),
            delta_cells: Cells::new(samples * nq),
            xi: vec![0.0; samples * nq],
            xi_computed: vec![0.0; samples * nq],
            force: vec![0.0; samples * nq],
            force_norm: vec![0.0; samples],
            mass_floor: vec![0.0; samples],
            mass_floor0: 0.0,
            scale: vec![0.0; nq],
            acc_sup: vec![0.0; samples * nq],
            first_center: vec![0.0; nq],
            backup_tau: vec![0.0; nq],
            shrink: f64::INFINITY,
            center: vec![0.0; nq],
            q_jet: vec![Dual::default(); nq],
            v_jet: vec![Dual::default(); nq],
            a_jet: vec![Dual::default(); nq],
            g_jet: vec![Dual::default(); nq],
            group_rate: vec![0.0; group_count * nq],
            group_inertial: vec![0.0; group_count * nq * nq],
            rates_ready: false,
            enclosure: EnclosureWorkspace::new(model),
            hull_q: vec![Interval::ZERO; nq],
            hull_v: vec![Interval::ZERO; nq],
            damping_share: 1.0,
            dynamics: DynamicsWorkspace::new(model),
            barrier_box: vec![Interval::ZERO; nb],
            jacobian_box: vec![Interval::ZERO; nb * nq],
            jdot_box: vec![Interval::ZERO; nb],
            point: vec![0.0; nq],
            values: vec![0.0; samples * nb],
            jacobian: vec![0.0; samples * nb * nq],
            jdot: vec![0.0; nb],
            zero: vec![0.0; nq],
            floor: vec![0.0; samples * nb],
            margin: vec![0.0; samples * nb],
            estimate: vec![0.0; samples * nb],
            row_estimate: vec![0.0; samples * nb],
            lowest: vec![f64::NAN; nb],
            proven: false,
            last_xi: vec![0.0; samples * nq],
            have_last: false,
            scratch: vec![0.0; nq * nq],
            vector: vec![0.0; 2 * nq],
            vector2: vec![0.0; 2 * nq],
            iterate: vec![0.0; 2 * nq],
            split: CertifiedSplit::default(),
        }
    }

    /// The next attempt after one that failed: the rows without the last tick's margins
    /// (they may be stale), or, without those already, a command held closer to holding the
    /// state (the box shrunk by [`SHRINK`]).
    fn retreat(&mut self) {
        if self.have_last {
            self.have_last = false;
        } else {
            self.shrink = if self.shrink.is_finite() {
                self.shrink * SHRINK
            } else {
                SHRINK
            };
        }
    }

    /// Which partition to try first from the next tick on, after `coarse` did (`proven`)
    /// or did not prove this one.
    fn note_partition(&mut self, coarse: bool, proven: bool) {
        if coarse {
            self.coarse_first = proven;
            self.ticks_fine = 0;
            self.coarse_wait = if proven {
                (self.coarse_wait / 2).max(COARSE_RETRY)
            } else {
                (self.coarse_wait * 2).min(COARSE_RETRY_MAX)
            };
        } else if !self.coarse_first {
            self.ticks_fine += 1;
            self.coarse_first = self.ticks_fine >= self.coarse_wait;
        }
    }

    /// Samples per hold (early and even).
    pub(super) fn samples(&self) -> usize {
        self.samples
    }

    /// Rows the certified mode adds after the barrier rows: the box of a later attempt,
    /// two per coordinate.
    pub(super) fn box_rows(nq: usize) -> usize {
        2 * nq
    }

    /// Per barrier, the proven lower bound of the barrier over the hold for the last command
    /// bounded \[m\] (`nb` entries).
    pub(super) fn lowest(&self) -> &[f64] {
        &self.lowest
    }

    /// Time of entry `j` \[s\] (`t_0 = 0`).
    fn time(&self, j: usize) -> f64 {
        if j == 0 {
            0.0
        } else {
            self.prediction.time(j - 1)
        }
    }

    /// Length of cell `c` \[s\].
    fn cell(&self, c: usize) -> f64 {
        self.time(c + 1) - self.time(c)
    }
}

/// The coarse partition of the cells: the fine groups joined in runs of [`COARSE_JOIN`]
/// (the same cells, fewer enclosures, each over a longer stretch of the hold).
fn coarse_partition(fine: &[Range<usize>]) -> Vec<Range<usize>> {
    fine.chunks(COARSE_JOIN)
        .filter_map(|run| Some(run.first()?.start..run.last()?.end))
        .collect()
}

/// Fine groups per coarse group.
const COARSE_JOIN: usize = 4;
/// After the coarse partition failed to prove a tick, attempts with the fine one before it
/// is tried first again: at least this many, at most [`COARSE_RETRY_MAX`].
const COARSE_RETRY: usize = 16;
const COARSE_RETRY_MAX: usize = 1024;

/// `out = a b` for row-major `n × n` matrices.
fn product(a: &[f64], b: &[f64], out: &mut [f64], n: usize) {
    for r in 0..n {
        for c in 0..n {
            out[r * n + c] = (0..n).map(|k| a[r * n + k] * b[k * n + c]).sum();
        }
    }
}

/// `out = a x` (`a` row-major `n × n`, `n = x.len()`).
fn apply(a: &[f64], x: &[f64], out: &mut [f64]) {
    let n = x.len();
    for (r, o) in out.iter_mut().enumerate().take(n) {
        *o = dot(&a[r * n..(r + 1) * n], x);
    }
}

/// The controller's certified tick after the model terms and `τ_nom`: rows, passes, QP.
pub(super) fn certified_filter(
    model: &Model,
    controller: &mut Controller,
    q: &[f64],
    qd: &[f64],
) -> TickStatus {
    let mut mark = Instant::now();
    let mut split = CertifiedSplit {
        ticks: 1,
        ..CertifiedSplit::default()
    };
    let status = certified_attempts(model, controller, q, qd, &mut mark, &mut split);
    if let Some(ws) = controller.certified.as_mut() {
        let total = &mut ws.split;
        total.ticks += split.ticks;
        total.prediction += split.prediction;
        total.bound += split.bound;
        total.qp += split.qp;
        total.fallback += split.fallback + lap(&mut mark);
        total.backups += split.backups;
    }
    status
}

/// The attempts of [`certified_filter`], timing each part into `split` from `mark`.
fn certified_attempts(
    model: &Model,
    controller: &mut Controller,
    q: &[f64],
    qd: &[f64],
    mark: &mut Instant,
    split: &mut CertifiedSplit,
) -> TickStatus {
    let (nq, nb) = (controller.nq, controller.nb);
    cholesky_inverse(
        &controller.dynamics.cholesky,
        nq,
        &mut controller.inverse_mass,
        &mut controller.scratch,
    );
    let hold = controller.settings.hold;
    let scale = controller.gain_scale;
    let Some(ws) = controller.certified.as_mut() else {
        return controller.fallback(InvalidState::NonFiniteModel);
    };
    if !ws.prediction.predict(
        &controller.inverse_mass,
        &ws.stiffness,
        &model.damping,
        qd,
        hold,
    ) {
        return controller.fallback(InvalidState::NonFiniteModel);
    }
    for i in 0..nq {
        ws.offset[i] = controller.dynamics.nonlinear[i] + model.stiffness[i] * q[i];
    }
    // The linear model's response, once per tick: every attempt bounds a command against it.
    response(model, ws, &controller.dynamics.mass_matrix, qd);
    let s = ws.samples;
    // Floors: the comparison curve of each barrier, never below zero while it is above.
    let barriers = &controller.barrier_terms;
    for k in 0..nb {
        let [p1, p2] = controller.barrier_gains[k].map(|p| p * scale);
        let b = barriers.values()[k];
        let b_dot = dot(&barriers.jacobian()[k * nq..(k + 1) * nq], qd).min(-p1 * b);
        let lowest = if b >= 0.0 { 0.0 } else { f64::NEG_INFINITY };
        for j in 0..s {
            let t = ws.prediction.time(j);
            ws.floor[j * nb + k] = comparison(b, b_dot, p1, p2, t).max(lowest);
        }
    }

    // The command of the prediction's rows, tightened by an estimate of how far the true
    // barrier may lie below the linear prediction (zero at first, then what the last bound
    // found); then the bound for exactly that command. A later attempt uses the margins
    // just proven, or, where the bound did not close (a motion too large for the
    // prediction), a command closer to holding the state (`u = 0`).
    let mut outcome = TickStatus::Uncertified(Uncertified::Bound);
    ws.shrink = f64::INFINITY;
    let started = Instant::now();
    for attempt in 0..ATTEMPTS {
        if attempt > 0 && started.elapsed().as_secs_f64() > controller.compute_budget {
            outcome = TickStatus::Uncertified(Uncertified::Budget);
            break;
        }
        first_pass_rows(controller, qd);
        split.prediction += lap(mark);
        let first = try_rows(controller);
        split.qp += lap(mark);
        let Some(ws) = controller.certified.as_mut() else {
            return controller.fallback(InvalidState::NonFiniteModel);
        };
        match first {
            Some(TickStatus::Filtered) => {}
            Some(status) => return status,
            // The first rows have no common point: those without the last tick's margins,
            // or else a command closer to holding the state, as where a bound does not
            // close; a later attempt's rows (the box, the new margins): give up on them.
            None if attempt == 0 => {
                // The box of a later attempt scales with the nominal command then.
                for i in 0..nq {
                    ws.first_center[i] = controller.tau_nom[i] - ws.offset[i];
                }
                ws.retreat();
                continue;
            }
            None => break,
        }
        for i in 0..nq {
            ws.center[i] = controller.tau[i] - ws.offset[i];
        }
        if !ws.shrink.is_finite() {
            ws.first_center.copy_from_slice(&ws.center);
        }
        let had_last = ws.have_last;
        let bounded = bound_command(model, controller, q, qd, mark, split);
        split.bound += lap(mark);
        let check = match bounded {
            Ok(check) => check,
            Err(why) => {
                if attempt == 0 {
                    outcome = TickStatus::Uncertified(why);
                }
                let Some(ws) = controller.certified.as_mut() else {
                    return controller.fallback(InvalidState::NonFiniteModel);
                };
                // (A coarse pass that proved nothing leaves the margins of its own bound.)
                ws.have_last = had_last;
                ws.retreat();
                continue;
            }
        };
        match check {
            Check::Proven => {
                if let Some(ws) = controller.certified.as_mut() {
                    ws.proven = true;
                }
                return TickStatus::Filtered;
            }
            Check::Start if attempt == 0 => {
                outcome = TickStatus::Uncertified(Uncertified::Start);
            }
            Check::Below if attempt == 0 => {
                outcome = TickStatus::Uncertified(Uncertified::Bound);
            }
            _ => {}
        }
    }
    // No attempt was proven: the predicted rows' command (both passes and, with a declared
    // box, their robust margin; the margins that tightened the attempts may be stale).
    let Some(ws) = controller.certified.as_mut() else {
        return controller.fallback(InvalidState::NonFiniteModel);
    };
    ws.have_last = false;
    ws.shrink = f64::INFINITY;
    // Every row of the certified layout inactive; the predicted rows write their own.
    let end = controller.barrier_rows + CertifiedWorkspace::box_rows(nq);
    for r in 0..end {
        controller.rows[r * nq..(r + 1) * nq].fill(0.0);
        controller.rhs[r] = INACTIVE;
    }
    let status = super::sampled_filter(model, controller, q, qd);
    // (Its time is the fallback's, not the backup's prediction.)
    split.fallback += lap(mark);
    if !matches!(status, TickStatus::Filtered | TickStatus::Relaxed) {
        return status;
    }
    // Then the line from that command to the backup, the command that holds the state
    // (`u = 0`: the tick's acceleration is the damping's alone): the first of its points
    // whose bound proves it and that meets the input limits.
    if backup(model, controller, q, qd, started, mark, split) {
        return TickStatus::Filtered;
    }
    // None: the predicted rows' command, reported with why the first attempt's bound failed.
    match status {
        TickStatus::Filtered => outcome,
        status => status,
    }
}

/// The bound of the command `ws.center` (`u`, with `controller.tau` its `τ`): the
/// correction, the linear cells, the error bound on the coarse partition first where it
/// has been proving the ticks, then on the fine one (the same command, rows and
/// correction: only the enclosures' grouping differs), and the barriers' check.
fn bound_command(
    model: &Model,
    controller: &mut Controller,
    q: &[f64],
    qd: &[f64],
    mark: &mut Instant,
    split: &mut CertifiedSplit,
) -> Result<Check, Uncertified> {
    let Some(ws) = controller.certified.as_mut() else {
        return Err(Uncertified::Domain);
    };
    let dynamics = &controller.dynamics;
    let inverse_mass = &controller.inverse_mass;
    let (mass, nonlinear) = (&dynamics.mass_matrix, &dynamics.nonlinear);
    let mut bounded = correction(model, ws, inverse_mass, mass, nonlinear, q).map(|()| {
        linear_cells(model, ws, inverse_mass, mass);
        split.prediction += lap(mark);
        Check::Below
    });
    if bounded.is_ok() {
        for coarse in [true, false] {
            let Some(ws) = controller.certified.as_mut() else {
                return Err(Uncertified::Domain);
            };
            if coarse && !(ws.coarse_first && ws.coarse_groups != ws.groups) {
                continue;
            }
            ws.coarse = coarse;
            let dynamics = &controller.dynamics;
            let (mass, nonlinear) = (&dynamics.mass_matrix, &dynamics.nonlinear);
            bounded = error_bounds(model, ws, &controller.inverse_mass, mass, nonlinear, q)
                .map(|()| certify(model, controller, q, qd));
            if let Some(ws) = controller.certified.as_mut() {
                ws.note_partition(coarse, bounded == Ok(Check::Proven));
            }
            if bounded == Ok(Check::Proven) {
                break;
            }
        }
    }
    bounded
}

/// Whether a point of the line from the predicted rows' command `controller.tau` to the
/// backup `u = 0` (`τ = n(q₀, q̇₀) + K q₀`: the tick's acceleration is the damping's alone,
/// `M q̈ = −D q̇₀`) is proven over the hold and meets the input limits, trying
/// [`BACKUP_STEPS`] in turn (none after the compute budget, counted from `started`); the
/// first that is becomes `controller.tau`, else it is left as it was. The proof is the same bound as for any command (`certify`), so the statement of
/// docs/model.md §5 covers it; what the backup gives up is the nominal command, for this
/// tick. Where the QP's rows have no common point (the barriers of a crowded state pull
/// the command apart) or its command cannot be proven, the state can often still be held.
#[allow(clippy::too_many_arguments)]
fn backup(
    model: &Model,
    controller: &mut Controller,
    q: &[f64],
    qd: &[f64],
    started: Instant,
    mark: &mut Instant,
    split: &mut CertifiedSplit,
) -> bool {
    let nq = controller.nq;
    let Some(ws) = controller.certified.as_mut() else {
        return false;
    };
    ws.backup_tau.copy_from_slice(&controller.tau);
    let rows = controller.rows.len() / nq;
    let limits_start = rows - controller.settings.input_limits.1.len();
    let mut proven = false;
    for (step, &lambda) in BACKUP_STEPS.iter().enumerate() {
        // A loop with a deadline: no step starts after the attempts' budget.
        if started.elapsed().as_secs_f64() > controller.compute_budget {
            break;
        }
        let Some(ws) = controller.certified.as_mut() else {
            return false;
        };
        for i in 0..nq {
            ws.center[i] = lambda * (ws.backup_tau[i] - ws.offset[i]);
            controller.tau[i] = ws.offset[i] + ws.center[i];
        }
        // (The QP's own answer meets its limit rows to its tolerance, not exactly.)
        let within = (limits_start..rows).all(|r| {
            let rhs = controller.rhs[r];
            dot(&controller.rows[r * nq..(r + 1) * nq], &controller.tau)
                >= rhs - LIMIT_TOLERANCE * (1.0 + rhs.abs())
        });
        if !within {
            continue;
        }
        // Without the margins of the attempts (their rows are the certified layout's).
        ws.have_last = false;
        proven = bound_command(model, controller, q, qd, mark, split) == Ok(Check::Proven);
        split.bound += lap(mark);
        if proven {
            split.backups += u64::from(step > 0);
            break;
        }
    }
    let Some(ws) = controller.certified.as_mut() else {
        return false;
    };
    // The next tick's first rows start without margins: these were bounded against the
    // predicted rows' layout.
    ws.have_last = false;
    ws.proven = proven;
    if !proven {
        controller.tau.copy_from_slice(&ws.backup_tau);
    }
    proven
}

/// The points of the line from the predicted rows' command (`1`) to the backup (`0`) that
/// [`backup`] tries, in order.
const BACKUP_STEPS: [f64; 3] = [1.0, 0.5, 0.0];
/// How far (relative) a command of [`backup`] may fall short of an input-limit row: the
/// QP's feasibility tolerance, far below a tension that matters (1e-9 of 1 + |rhs| N).
const LIMIT_TOLERANCE: f64 = 1e-9;

/// Attempts at a command whose bound holds.
const ATTEMPTS: usize = 5;
/// Where the bound did not close, the next attempt's command is held within this fraction
/// of the first attempt's (per entry of `u`).
const SHRINK: f64 = 0.3;
/// Smallest half-width of that box \[N\].
const SHRINK_FLOOR: f64 = 1e-3;

/// What [`certify`] found for the command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Check {
    /// Every barrier non-negative at every instant of the hold.
    Proven,
    /// Proven except over the first instants (see [`Uncertified::Start`]).
    Start,
    /// The bound dips below zero somewhere in the hold.
    Below,
}

/// The first pass's rows: `b_k + J_k (a_j + Γ_j u) ≥ floor + margin estimate` at every
/// sample, the end of the hold, and the trust rows left inactive.
fn first_pass_rows(controller: &mut Controller, qd: &[f64]) {
    let (nq, nb) = (controller.nq, controller.nb);
    let scale = controller.gain_scale;
    let Some(ws) = controller.certified.as_mut() else {
        return;
    };
    let barriers = &controller.barrier_terms;
    let s = ws.samples;
    for j in 0..s {
        let (free, forced) = (ws.prediction.free(j), ws.prediction.forced(j));
        for k in 0..nb {
            let jacobian_row = &barriers.jacobian()[k * nq..(k + 1) * nq];
            let r = j * nb + k;
            let row = &mut controller.rows[r * nq..(r + 1) * nq];
            super::forced_row(jacobian_row, forced, nq, row);
            let estimate = if ws.have_last { ws.estimate[r] } else { 0.0 };
            ws.row_estimate[r] = estimate;
            controller.rhs[r] =
                ws.floor[r] + estimate - barriers.values()[k] - dot(jacobian_row, free)
                    + dot(row, &ws.offset);
        }
    }
    let end = super::EndRows {
        prediction: &ws.prediction,
        barriers,
        gains: &controller.barrier_gains,
        scale,
        offset: &ws.offset,
    };
    end.write(s, &mut controller.rows, &mut controller.rhs);
    if let Some(rates) = controller.rates.as_ref() {
        rates.write_linear(
            &ws.prediction,
            &ws.offset,
            qd,
            &mut controller.rows,
            &mut controller.rhs,
        );
    }
    // Rows the predicted rows' fallback uses beyond these: inactive here.
    for r in (s + 1) * nb..controller.barrier_rows {
        controller.rows[r * nq..(r + 1) * nq].fill(0.0);
        controller.rhs[r] = INACTIVE;
    }
    // The box |u_i| ≤ shrink |u_first,i| (inactive at the first attempt).
    let first = controller.barrier_rows;
    for i in 0..nq {
        let half = if ws.shrink.is_finite() {
            ws.shrink * ws.first_center[i].abs() + SHRINK_FLOOR
        } else {
            f64::INFINITY
        };
        for (sign, r) in [(1.0, first + 2 * i), (-1.0, first + 2 * i + 1)] {
            let row = &mut controller.rows[r * nq..(r + 1) * nq];
            row.fill(0.0);
            row[i] = sign;
            // sign τ_i ≥ sign g₀_i − half.
            controller.rhs[r] = if half.is_finite() {
                sign * ws.offset[i] - half
            } else {
                INACTIVE
            };
        }
    }
}

/// The right-hand side of a row that never binds.
const INACTIVE: f64 = -1e12;

/// The linear model's response at every entry: `Γ`, the impulse response `H = Γ̇`, the ramp
/// response `Γ₂ = ∫Γ = K⁻¹ (t I − M₀ H − D Γ)` (from `M₀ Γ₂″ + D Γ₂′ + K Γ₂ = t I`),
/// and the free motion `a`, `ȧ`.
fn response(model: &Model, ws: &mut CertifiedWorkspace, mass: &[f64], qd: &[f64]) {
    let nq = ws.nq;
    let nn = nq * nq;
    let (d, k) = (&model.damping, &model.stiffness);
    ws.h[..nn].fill(0.0);
    ws.gamma[..nn].fill(0.0);
    ws.free[..nq].fill(0.0);
    ws.free_v[..nq].copy_from_slice(qd);
    for j in 0..ws.samples {
        let at = (j + 1) * nn;
        ws.h[at..at + nn].copy_from_slice(ws.prediction.forced_velocity(j));
        ws.gamma[at..at + nn].copy_from_slice(ws.prediction.forced(j));
        let v = (j + 1) * nq;
        ws.free[v..v + nq].copy_from_slice(ws.prediction.free(j));
        ws.free_v[v..v + nq].copy_from_slice(ws.prediction.free_velocity(j));
    }
    for j in 0..=ws.samples {
        let at = j * nn;
        let t = ws.time(j);
        product(mass, &ws.h[at..at + nn], &mut ws.scratch, nq);
        for r in 0..nq {
            for c in 0..nq {
                let identity = if r == c { t } else { 0.0 };
                ws.gamma2[at + r * nq + c] =
                    (identity - ws.scratch[r * nq + c] - d[r] * ws.gamma[at + r * nq + c]) / k[r];
            }
        }
    }
}

/// `M₀⁻¹ (f − D v − K e)` into `out`, all `nq` long.
fn acceleration(
    model: &Model,
    inverse_mass: &[f64],
    force: &[f64],
    e: &[f64],
    v: &[f64],
    scratch: &mut [f64],
    out: &mut [f64],
) {
    let nq = force.len();
    for i in 0..nq {
        scratch[i] = force[i] - model.damping[i] * v[i] - model.stiffness[i] * e[i];
    }
    apply(inverse_mass, &scratch[..nq], out);
}

/// The correction `φ(t) = φ₀ + φ₁ t`: the nominal model's force mismatch
/// `g = (M₀ − M(q)) ë + f₀ − h(q, ė) − G(q)` on the uncorrected prediction of the center
/// command at every sample (it is zero at the tick), fitted by least squares; its motion is
/// `Γ φ₀ + Γ₂ φ₁`.
fn correction(
    model: &Model,
    ws: &mut CertifiedWorkspace,
    inverse_mass: &[f64],
    mass: &[f64],
    nonlinear: &[f64],
    q0: &[f64],
) -> Result<(), crate::control::Uncertified> {
    let nq = ws.nq;
    let nn = nq * nq;
    let s = ws.samples;
    ws.mismatch[..nq].fill(0.0);
    for j in 1..=s {
        let (at, v) = (j * nn, j * nq);
        for i in 0..nq {
            let row = i * nq..(i + 1) * nq;
            ws.vector[i] = ws.free[v + i] + dot(&ws.gamma[at..at + nn][row.clone()], &ws.center);
            ws.vector[nq + i] = ws.free_v[v + i] + dot(&ws.h[at..at + nn][row], &ws.center);
        }
        for i in 0..nq {
            ws.point[i] = q0[i] + ws.vector[i];
        }
        let (e, rest) = ws.vector.split_at(nq);
        let mut acc = [0.0; 64];
        if nq > acc.len() {
            return Err(failed(Uncertified::Domain, "size"));
        }
        acceleration(
            model,
            inverse_mass,
            &ws.center,
            e,
            &rest[..nq],
            &mut ws.vector2,
            &mut acc[..nq],
        );
        if softcbf_description::domain::state_problem(&model.robot, &ws.point, &rest[..nq])
            .is_some()
        {
            return Err(failed(Uncertified::Domain, "prediction outside the domain"));
        }
        let evaluated = update_joints(model, &mut ws.dynamics, &ws.point, &rest[..nq])
            .and_then(|()| mass_matrix(model, &mut ws.dynamics))
            .and_then(|()| bias_and_gravity(model, &mut ws.dynamics, &rest[..nq]));
        if evaluated.is_err() {
            return Err(failed(Uncertified::Domain, "model at the prediction"));
        }
        for i in 0..nq {
            let inertial: f64 = (0..nq)
                .map(|k| (mass[i * nq + k] - ws.dynamics.mass_matrix[i * nq + k]) * acc[k])
                .sum();
            ws.mismatch[v + i] = inertial + nonlinear[i] - ws.dynamics.nonlinear[i];
        }
    }
    // Least squares of g_j ≈ φ₀ + φ₁ t_j over the entries, per coordinate.
    let (mut st, mut stt) = (0.0, 0.0);
    let count = (s + 1) as f64;
    for j in 0..=s {
        let t = ws.time(j);
        st += t;
        stt += t * t;
    }
    let determinant = count * stt - st * st;
    for i in 0..nq {
        let (mut sg, mut stg) = (0.0, 0.0);
        for j in 0..=s {
            let (t, g) = (ws.time(j), ws.mismatch[j * nq + i]);
            sg += g;
            stg += t * g;
        }
        let (phi0, phi1) = if determinant > 0.0 {
            (
                (stt * sg - st * stg) / determinant,
                (count * stg - st * sg) / determinant,
            )
        } else {
            (0.0, 0.0)
        };
        ws.phi0[i] = phi0;
        ws.phi1[i] = phi1;
        for j in 0..=s {
            ws.residual[j * nq + i] = ws.mismatch[j * nq + i] - (phi0 + phi1 * ws.time(j));
        }
    }
    if ws
        .phi0
        .iter()
        .chain(&ws.phi1)
        .chain(&ws.residual)
        .all(|x| x.is_finite())
    {
        Ok(())
    } else {
        Err(failed(Uncertified::Domain, "correction not finite"))
    }
}

/// Which motion [`derivatives`] gives.
#[derive(Clone, Copy, PartialEq)]
enum Motion {
    /// The corrected prediction of the command.
    Corrected,
    /// The uncorrected prediction of the center command.
    Plain,
    /// The correction's own motion (`Γ φ₀ + Γ₂ φ₁`, …).
    Correction,
}

/// The motion `(e, ė, ë, e⃛, e⁗)` of kind `motion` at entry `j` for the command `center`:
/// boxes (the value widened by its rounding), `nq` each, into `out[i][order]`. With the correction `φ(t)`
/// held, `ë = M₀⁻¹ (u + φ − D ė − K e)`, `e⃛ = M₀⁻¹ (φ₁ − D ë − K ė)`, `e⁗ = −M₀⁻¹ (D e⃛ + K ë)`.
#[allow(clippy::too_many_arguments)]
fn derivatives(
    model: &Model,
    ws: &CertifiedWorkspace,
    inverse_mass: &[f64],
    j: usize,
    motion: Motion,
    out: &mut [[Interval; 5]; 64],
) {
    let nq = ws.nq;
    let nn = nq * nq;
    let (at, v) = (j * nn, j * nq);
    let t = ws.time(j);
    let (d, k) = (&model.damping, &model.stiffness);
    let (free, correct, centered) = match motion {
        Motion::Corrected => (true, true, true),
        Motion::Plain => (true, false, true),
        Motion::Correction => (false, true, false),
    };
    // The parts that do not depend on z: position and velocity, then the derivatives by the
    // model with the force u_c (if centered) + φ (if corrected).
    let mut e = [0.0; 64];
    let mut ve = [0.0; 64];
    let mut force = [0.0; 64];
    for i in 0..nq {
        let g = &ws.gamma[at + i * nq..at + (i + 1) * nq];
        let g2 = &ws.gamma2[at + i * nq..at + (i + 1) * nq];
        let hv = &ws.h[at + i * nq..at + (i + 1) * nq];
        if free {
            e[i] += ws.free[v + i];
            ve[i] += ws.free_v[v + i];
        }
        if centered {
            e[i] += dot(g, &ws.center);
            ve[i] += dot(hv, &ws.center);
            force[i] += ws.center[i];
        }
        if correct {
            e[i] += dot(g, &ws.phi0) + dot(g2, &ws.phi1);
            ve[i] += dot(hv, &ws.phi0) + dot(g, &ws.phi1);
            force[i] += ws.phi0[i] + ws.phi1[i] * t;
        }
    }
    let mut scratch = [0.0; 64];
    let mut acc = [0.0; 64];
    let mut jerk = [0.0; 64];
    let mut snap = [0.0; 64];
    acceleration(
        model,
        inverse_mass,
        &force[..nq],
        &e[..nq],
        &ve[..nq],
        &mut scratch,
        &mut acc[..nq],
    );
    for i in 0..nq {
        let ramp = if correct { ws.phi1[i] } else { 0.0 };
        scratch[i] = ramp - d[i] * acc[i] - k[i] * ve[i];
    }
    apply(inverse_mass, &scratch[..nq], &mut jerk[..nq]);
    for i in 0..nq {
        scratch[i] = -(d[i] * jerk[i] + k[i] * acc[i]);
    }
    apply(inverse_mass, &scratch[..nq], &mut snap[..nq]);
    let values: [&[f64]; 5] = [&e, &ve, &acc, &jerk, &snap];
    for order in 0..5 {
        for i in 0..nq {
            let value = values[order][i];
            let slack = value.abs() * 1e-12 + 1e-300;
            out[i][order] = Interval::around(value, slack * ROUNDING);
        }
    }
}

/// The motions of [`Motion`] over each cell. Within a cell (within the hold) the force
/// `u + φ(t)` is linear in time, so `ë` and its derivatives solve the unforced model, whose
/// energy never grows: `E = ½ yᵀ M₀ y + ½ xᵀ K x` at the cell's start, for `(x, y)` = `(ë, e⃛)`
/// or `(e⃛, e⁗)`, bounds `|y_i| ≤ √(2 E (M₀⁻¹)_ii)` over the cell. Then `ë` over the cell lies
/// within its endpoints' hull widened by `h²/8 sup |e⁗|` (and within the start ± `h sup |e⃛|`),
/// `e` and `ė` within their chords widened by `h²/8 sup |ë|`, `h²/8 sup |e⃛|`, and `e⃛`
/// within the start's ± `h sup |e⁗|`.
fn linear_cells(model: &Model, ws: &mut CertifiedWorkspace, inverse_mass: &[f64], mass: &[f64]) {
    let nq = ws.nq;
    if nq > 64 {
        return;
    }
    let k = &model.stiffness;
    let mut left = [[Interval::ZERO; 5]; 64];
    let mut right = [[Interval::ZERO; 5]; 64];
    let energy = |x: &[[Interval; 5]; 64], high: usize| -> f64 {
        let mut total = 0.0;
        for r in 0..nq {
            let low = x[r][high - 1].mag();
            total += 0.5 * k[r] * low * low;
            for s in 0..nq {
                total += 0.5 * x[r][high].mag() * mass[r * nq + s].abs() * x[s][high].mag();
            }
        }
        total
    };
    for motion in [Motion::Corrected, Motion::Plain, Motion::Correction] {
        derivatives(model, ws, inverse_mass, 0, motion, &mut left);
        for c in 0..ws.samples {
            let h = ws.cell(c);
            derivatives(model, ws, inverse_mass, c + 1, motion, &mut right);
            let (jerk_energy, snap_energy) = (energy(&left, 3), energy(&left, 4));
            let cells = match motion {
                Motion::Corrected => &mut ws.center_cells,
                Motion::Plain => &mut ws.plain_cells,
                Motion::Correction => &mut ws.delta_cells,
            };
            for i in 0..nq {
                let minv = inverse_mass[i * nq + i].max(0.0);
                let sup_jerk = (2.0 * jerk_energy * minv).sqrt();
                let sup_snap = (2.0 * snap_energy * minv).sqrt();
                let (acc_left, acc_right) = (left[i][2], right[i][2]);
                let chord = acc_left.hull(acc_right).widened(0.125 * h * h * sup_snap);
                let from_start = acc_left.widened(h * sup_jerk);
                let acc = Interval::new(
                    chord.lo().max(from_start.lo()),
                    chord.hi().min(from_start.hi()),
                );
                let at = c * nq + i;
                let potential = (2.0 * jerk_energy / k[i]).sqrt();
                let acc = Interval::new(acc.lo().max(-potential), acc.hi().min(potential));
                cells.a[at] = acc;
                let sup_acc = acc.mag() * ROUNDING;
                // Each level two ways: the chord between the cell's ends widened by h²/8 of
                // the bound on its second derivative, and the left end plus h times the range
                // of its first derivative; the motion lies in both.
                let rise = |start: Interval, rate: Interval| {
                    start
                        + Interval::new(
                            (h * rate.lo() * ROUNDING).min(0.0),
                            (h * rate.hi() * ROUNDING).max(0.0),
                        )
                };
                let velocity = meet(
                    left[i][1]
                        .hull(right[i][1])
                        .widened(0.125 * h * h * sup_jerk),
                    rise(left[i][1], acc),
                );
                cells.v[at] = velocity;
                cells.e[at] = meet(
                    left[i][0]
                        .hull(right[i][0])
                        .widened(0.125 * h * h * sup_acc),
                    rise(left[i][0], velocity),
                );
                cells.jerk_variation[at] =
                    ((h * jerk_energy / model.damping[i]).sqrt()).min(h * sup_jerk) * ROUNDING;
                let from_jerk_start = left[i][3].widened(h * sup_snap);
                cells.jerk[at] = Interval::new(
                    from_jerk_start.lo().max(-sup_jerk),
                    from_jerk_start.hi().min(sup_jerk),
                );
                if motion == Motion::Corrected {
                    ws.acc_sup[at] = sup_acc;
                }
            }
            std::mem::swap(&mut left, &mut right);
        }
    }
}

/// The intersection of two enclosures of one quantity (both hold, so their meet does; the
/// wider of the two where rounding leaves them disjoint).
fn meet(a: Interval, b: Interval) -> Interval {
    let (lo, hi) = (a.lo().max(b.lo()), a.hi().min(b.hi()));
    if lo <= hi {
        Interval::new(lo, hi)
    } else {
        a.hull(b)
    }
}

/// The domain check of a box of coordinates: every state in it must be one the model
/// describes (a bend below 1.5π, a positive backbone up to eleven rest lengths, speeds
/// within 100 m/s).
fn box_in_domain(model: &Model, q: &[Interval], v: &[Interval]) -> bool {
    use softcbf_description::domain::{MAX_BEND_RAD, MAX_ELONGATION_RATIO, MAX_SPEED};
    for (i, module) in model.robot.modules.iter().enumerate() {
        let (dx, dy, dl) = (q[3 * i], q[3 * i + 1], q[3 * i + 2]);
        let bend = (dx.mag().powi(2) + dy.mag().powi(2)).sqrt() / module.tendon_radius;
        let rest = module.rest_length;
        if !(bend < MAX_BEND_RAD && rest + dl.lo() > 0.0 && dl.mag() <= MAX_ELONGATION_RATIO * rest)
        {
            return false;
        }
    }
    v.iter().all(|x| x.mag() <= MAX_SPEED)
}

/// An upper bound of the Perron root of the non-negative `nq × nq` matrix `p` (row-major):
/// after a few power steps from the ones vector, `max_i (p x)_i / x_i` (Collatz–Wielandt).
fn perron_bound(p: &[f64], nq: usize, work: &mut [f64]) -> f64 {
    let (x, y) = work.split_at_mut(nq);
    x.fill(1.0);
    for _ in 0..8 {
        for r in 0..nq {
            y[r] = dot(&p[r * nq..(r + 1) * nq], x);
        }
        let top = y[..nq].iter().cloned().fold(0.0, f64::max);
        if !(top > 0.0 && top.is_finite()) {
            return if top == 0.0 { 0.0 } else { f64::INFINITY };
        }
        for (a, b) in x.iter_mut().zip(y.iter()) {
            *a = (b / top).max(1e-12);
        }
    }
    for r in 0..nq {
        y[r] = dot(&p[r * nq..(r + 1) * nq], x);
    }
    (0..nq).map(|r| y[r] / x[r]).fold(0.0, f64::max) * (1.0 + 1e-10)
}

/// [`enclose_mismatch`] on the workspace's jets (`q_jet`, `v_jet`, `a_jet`) into `g_jet`.
fn mismatch_on_jets(
    model: &Model,
    ws: &mut CertifiedWorkspace,
    mass: &[f64],
    nonlinear: &[f64],
) -> bool {
    enclose_mismatch(
        model,
        &mut ws.enclosure,
        &ws.q_jet,
        &ws.v_jet,
        &ws.a_jet,
        mass,
        nonlinear,
        &mut ws.g_jet,
    )
}

/// The forcing bound `F̄` of every cell (`ws.force`) for the tube the workspace assumes
/// (`ws.xi` around the corrected prediction), group by group of cells: the fit's residual
/// `g − φ` on the uncorrected prediction (its values at the samples plus half a cell of its
/// rate from a jet along that prediction, and the jerk term's integral), the change of `g`
/// across the spread of the commands, of the correction and of `ξ` (a jet across it), and
/// the declared box; and per cell a floor of the plant's smallest scaled mass eigenvalue
/// over the group's box (`ws.mass_floor`). `mass`, `nonlinear`: `M₀` (row-major `nq × nq`)
/// and `f₀` at the tick; `q0` \[m\].
fn group_forcing(
    model: &Model,
    ws: &mut CertifiedWorkspace,
    mass: &[f64],
    nonlinear: &[f64],
    q0: &[f64],
) -> Result<(), Uncertified> {
    let nq = ws.nq;
    let nn = nq * nq;
    let u = model.robot.uncertainty;
    let join = |acc: &mut Interval, x: Interval| {
        *acc = if acc.is_valid() { acc.hull(x) } else { x };
    };
    // Each coordinate's stiffness and damping fractions (its module's box).
    let mut boxes = [(0.0, 0.0); 64];
    for (i, slot) in boxes.iter_mut().enumerate().take(nq) {
        *slot = model.robot.module_box(i / 3).coordinate(i);
    }
    let count = if ws.coarse {
        ws.coarse_groups.len()
    } else {
        ws.groups.len()
    };
    for g in 0..count {
        let group = if ws.coarse {
            ws.coarse_groups[g].clone()
        } else {
            ws.groups[g].clone()
        };
        let mut plain = [[Interval::NAN; 4]; 64];
        let mut base = [[Interval::NAN; 3]; 64];
        let mut spread = [[0.0f64; 3]; 64];
        for c in group.clone() {
            for i in 0..nq {
                let at = c * nq + i;
                let (p, f) = (&ws.plain_cells, &ws.center_cells);
                for (k, x) in [p.e[at] + q0[i], p.v[at], p.a[at], p.jerk[at]]
                    .into_iter()
                    .enumerate()
                {
                    join(&mut plain[i][k], x);
                }
                let full = [f.e[at].widened(ws.xi[at]) + q0[i], f.v[at], f.a[at]];
                for k in 0..3 {
                    join(&mut base[i][k], full[k]);
                    join(&mut base[i][k], plain[i][k]);
                }
                let d = &ws.delta_cells;
                let now = [d.e[at].mag() + ws.xi[at], d.v[at].mag(), d.a[at].mag()];
                for k in 0..3 {
                    spread[i][k] = spread[i][k].max(now[k]);
                }
            }
        }
        let (mut positions, mut velocities) = ([Interval::ZERO; 64], [Interval::ZERO; 64]);
        for i in 0..nq {
            (positions[i], velocities[i]) = (base[i][0], base[i][1]);
        }
        if !box_in_domain(model, &positions[..nq], &velocities[..nq]) {
            return Err(failed(Uncertified::Domain, "group outside the domain"));
        }
        // The rate of g along the uncorrected prediction but for its jerk term (q̇ = ė,
        // q̈ = ë there); the jerk's share, (M₀ − M) e⃛, is taken by its integral below. Both
        // come from the uncorrected prediction alone: computed in the first round, reused.
        if !ws.rates_ready {
            for i in 0..nq {
                ws.q_jet[i] = Dual::new(plain[i][0], plain[i][1]);
                ws.v_jet[i] = Dual::new(plain[i][1], plain[i][2]);
                ws.a_jet[i] = Dual::constant(plain[i][2]);
            }
            if !mismatch_on_jets(model, ws, mass, nonlinear) {
                return Err(failed(Uncertified::Domain, "rate jet"));
            }
            let (rate, inertial) = (
                &mut ws.group_rate[g * nq..(g + 1) * nq],
                &mut ws.group_inertial[g * nn..(g + 1) * nn],
            );
            for i in 0..nq {
                rate[i] = (ws.g_jet[i].slope - ws.phi1[i]).mag();
            }
            // |M₀ − M_p| over the uncorrected prediction's box, for the jerk's share.
            for r in 0..nq {
                for c in 0..nq {
                    let e = r * nq + c;
                    let mut total = Interval::ZERO;
                    let mut magnitude = 0.0;
                    for b in 0..ws.enclosure.modules() {
                        total += ws.enclosure.mass_shares[b * nn + e];
                        magnitude += ws.enclosure.mass_shares[b * nn + e].mag();
                    }
                    inertial[e] = (total - mass[e]).mag() + u.mass * magnitude;
                }
            }
        }
        // The change of g across the spread.
        for i in 0..nq {
            ws.q_jet[i] = Dual::new(base[i][0], Interval::around(0.0, spread[i][0]));
            ws.v_jet[i] = Dual::new(base[i][1], Interval::around(0.0, spread[i][1]));
            ws.a_jet[i] = Dual::new(base[i][2], Interval::around(0.0, spread[i][2]));
        }
        if !mismatch_on_jets(model, ws, mass, nonlinear) {
            return Err(failed(Uncertified::Domain, "spread jet"));
        }
        // λ_min(S⁻¹M_pS⁻¹) ≥ (1 − σ_m) (λ_min(S⁻¹M₀S⁻¹) − ‖S⁻¹(M(Q) − M₀)S⁻¹‖_F) over
        // the group's box.
        for e in 0..nn {
            let mut total = Interval::ZERO;
            for b in 0..ws.enclosure.modules() {
                total += ws.enclosure.mass_shares[b * nn + e];
            }
            ws.scratch[e] = (total - mass[e]).mag() / (ws.scale[e / nq] * ws.scale[e % nq]);
        }
        // ‖S⁻¹(M(Q) − M₀)S⁻¹‖₂ ≤ ρ(|S⁻¹(M(Q) − M₀)S⁻¹|).
        let deviation = perron_bound(&ws.scratch, nq, &mut ws.iterate);
        let floor = (1.0 - u.mass) * (ws.mass_floor0 - deviation * ROUNDING);
        for c in group.clone() {
            ws.mass_floor[c] = floor.max(0.0);
        }
        let (rate, inertial) = (
            &ws.group_rate[g * nq..(g + 1) * nq],
            &ws.group_inertial[g * nn..(g + 1) * nn],
        );
        for c in group.clone() {
            let h = ws.cell(c);
            for i in 0..nq {
                let (sigma_k, sigma_d) = boxes[i];
                let residual = ws.residual[c * nq + i]
                    .abs()
                    .max(ws.residual[(c + 1) * nq + i].abs());
                let jerk_share: f64 = (0..nq)
                    .map(|k| inertial[i * nq + k] * ws.plain_cells.jerk_variation[c * nq + k])
                    .sum();
                let value = residual
                    + 0.5 * rate[i] * h
                    + jerk_share
                    + ws.g_jet[i].slope.mag()
                    + u.mass * ws.enclosure.per_body[i]
                    + sigma_k * model.stiffness[i] * base[i][0].mag()
                    + sigma_d * model.damping[i] * base[i][1].mag()
                    + u.force;
                ws.force[c * nq + i] = value * ROUNDING;
            }
        }
    }
    ws.rates_ready = true;
    Ok(())
}

/// The tube and the error bound. For the assumed `|ξ|` (`ws.xi`), bound the forcing `F̄`
/// of every cell — the fit's residual `g − φ` on the uncorrected prediction (its values at the
/// samples, plus half a cell of its rate from a jet along that prediction), the change of
/// `g` across the spread of the commands, of the correction and of `ξ` (a jet across it), and
/// the declared uncertainty — then `κ`, `Φ` and the computed `|ξ|`; repeat until the
/// computed bound lies strictly below the assumed one (the assumed tube then holds the
/// motion: the bound on `ξ` on `[0, t]` uses the forcing on `[0, t]` only, which the tube
/// bounds as long as the motion stays in it, and it stays strictly inside). Then the
/// barriers' enclosures over the tube's hull.
fn error_bounds(
    model: &Model,
    ws: &mut CertifiedWorkspace,
    inverse_mass: &[f64],
    mass: &[f64],
    nonlinear: &[f64],
    q0: &[f64],
) -> Result<(), Uncertified> {
    let nq = ws.nq;
    let nn = nq * nq;
    let s = ws.samples;
    let u = model.robot.uncertainty;
    // The last tick's bound, inflated, is the first guess; where that guess is too wide for
    // the domain or for κ, the guess starts again from the floor (once).
    let mut seeded = ws.have_last;
    if seeded {
        for (x, last) in ws.xi.iter_mut().zip(&ws.last_xi) {
            *x = last * XI_INFLATION + XI_FLOOR;
        }
    } else {
        ws.xi.fill(XI_FLOOR);
    }
    for i in 0..nq {
        ws.scale[i] = mass[i * nq + i].max(0.0).sqrt();
    }
    // λ_max(S M₀⁻¹ S) ≤ ρ(|S M₀⁻¹ S|), the Perron root of the entries' magnitudes.
    for e in 0..nn {
        ws.scratch[e] = (inverse_mass[e] * ws.scale[e / nq] * ws.scale[e % nq]).abs();
    }
    let top = perron_bound(&ws.scratch, nq, &mut ws.iterate);
    ws.mass_floor0 = if top > 0.0 && top.is_finite() && ws.scale.iter().all(|x| *x > 0.0) {
        1.0 / (top * ROUNDING)
    } else {
        0.0
    };
    let join = |acc: &mut Interval, x: Interval| {
        *acc = if acc.is_valid() { acc.hull(x) } else { x };
    };
    // The rate jets belong to this command and partition.
    ws.rates_ready = false;
    for _ in 0..ROUNDS {
        // |ξ| is bounded on [0, t]: the assumed bound must not shrink along the hold.
        for j in 1..s {
            for i in 0..nq {
                let previous = ws.xi[(j - 1) * nq + i];
                let own = &mut ws.xi[j * nq + i];
                *own = own.max(previous);
            }
        }
        // The tube's hull, κ over it.
        for i in 0..nq {
            let (mut qh, mut vh) = (Interval::NAN, Interval::NAN);
            for c in 0..s {
                let at = c * nq + i;
                join(&mut qh, ws.center_cells.e[at].widened(ws.xi[at]) + q0[i]);
                join(&mut vh, ws.center_cells.v[at]);
            }
            ws.hull_q[i] = qh;
            ws.hull_v[i] = vh;
        }
        let in_domain = box_in_domain(model, &ws.hull_q, &ws.hull_v)
            && enclose_mass_rate(model, &mut ws.enclosure, &ws.hull_q, &ws.hull_v);
        if !in_domain && seeded {
            seeded = false;
            ws.xi.fill(XI_FLOOR);
            continue;
        }
        if !box_in_domain(model, &ws.hull_q, &ws.hull_v) {
            return Err(failed(Uncertified::Domain, "tube outside the domain"));
        }
        if !in_domain {
            return Err(failed(Uncertified::Domain, "mass rate"));
        }
        let n = ws.enclosure.modules();
        for e in 0..nn {
            let mut total = Interval::ZERO;
            let mut magnitude = 0.0;
            for i in 0..n {
                let share = ws.enclosure.mass_rate_shares[i * nn + e];
                total += share;
                magnitude += share.mag();
            }
            let (r, c) = (e / nq, e % nq);
            let weight = 0.5 / (model.damping[r] * model.damping[c]).sqrt();
            ws.scratch[e] = (total.mag() + u.mass * magnitude) * weight;
        }
        let kappa = perron_bound(&ws.scratch, nq, &mut ws.iterate) + u.damping;
        if !(kappa.is_finite() && kappa <= KAPPA_MAX) {
            if seeded {
                seeded = false;
                ws.xi.fill(XI_FLOOR);
                continue;
            }
            return Err(failed(Uncertified::Tube, "kappa"));
        }
        ws.damping_share = 1.0 - kappa;
        group_forcing(model, ws, mass, nonlinear, q0)?;
        // Φ and the computed |ξ| at the end of each cell: the smallest of the dissipative
        // bound √(t Φ/D′_i), the elastic bound √(2Φ/K_i) and the inertial bound
        // 1/(Sᵢ λ_low) ∫₀ᵗ (t − s) ‖S⁻¹F̄(s)‖ ds, λ_low a floor of λ_min(S⁻¹M_pS⁻¹) (from
        // d/dt √(2E) ≤ ‖F‖_{M_p⁻¹} ≤ ‖S⁻¹F‖/√λ_low and |ξ̇ᵢ| ≤ √(2E)/(Sᵢ √λ_low)).
        let mut phi = 0.0;
        let mut closed = true;
        let mut lowest_mass = f64::INFINITY;
        // ‖S⁻¹F̄‖ per cell, for the inertial bound's moments.
        for c in 0..s {
            let mut n2 = 0.0;
            for i in 0..nq {
                n2 += (ws.force[c * nq + i] / ws.scale[i]).powi(2);
            }
            ws.force_norm[c] = n2.sqrt();
        }
        for c in 0..s {
            let (h, t) = (ws.cell(c), ws.time(c + 1));
            let mut sum = 0.0;
            for i in 0..nq {
                let f = ws.force[c * nq + i];
                sum += f * f / (ws.damping_share * model.damping[i]);
            }
            phi += h * sum * ROUNDING;
            lowest_mass = lowest_mass.min(ws.mass_floor[c]);
            // ∫₀^{t} (t − s) ‖F̄(s)‖ ds over the cells so far.
            let mut moment = 0.0;
            for c2 in 0..=c {
                let middle = 0.5 * (ws.time(c2) + ws.time(c2 + 1));
                moment += ws.force_norm[c2] * ws.cell(c2) * (t - middle);
            }
            let inertial = if lowest_mass > 0.0 {
                moment / lowest_mass * ROUNDING
            } else {
                f64::INFINITY
            };
            for i in 0..nq {
                let dissipation = (t * phi / (ws.damping_share * model.damping[i])).sqrt();
                let elastic = (2.0 * phi / model.stiffness[i]).sqrt();
                let value = dissipation.min(elastic).min(inertial / ws.scale[i]) * ROUNDING;
                ws.xi_computed[c * nq + i] = value;
                closed &= value < ws.xi[c * nq + i];
            }
        }
        if closed {
            // The computed bound holds (it is below the assumed one, which held the tube the
            // enclosures were taken over, and ξ starts at zero): it is the one the margins use,
            // and the next tick's start.
            ws.xi.copy_from_slice(&ws.xi_computed);
            return barrier_enclosures(model, ws);
        }
        for (assumed, computed) in ws.xi.iter_mut().zip(&ws.xi_computed) {
            *assumed = assumed.max(computed * XI_INFLATION + XI_FLOOR);
        }
    }
    Err(failed(Uncertified::Tube, "rounds"))
}

/// The barriers' enclosures over the tube's hull (`ws.hull_q`, `ws.hull_v`): values,
/// Jacobian rows and `J̇q̇`.
fn barrier_enclosures(model: &Model, ws: &mut CertifiedWorkspace) -> Result<(), Uncertified> {
    model.generated.barrier_terms_interval(
        &model.params,
        &ws.hull_q,
        &ws.hull_v,
        &mut ws.barrier_box,
        &mut ws.jacobian_box,
        &mut ws.jdot_box,
    );
    let finite = ws
        .barrier_box
        .iter()
        .chain(&ws.jacobian_box)
        .chain(&ws.jdot_box)
        .all(|x| x.is_finite());
    if finite {
        Ok(())
    } else {
        Err(failed(Uncertified::Domain, "barrier enclosure"))
    }
}

/// Bounds every barrier over the hold for the first pass's command (`ws.center`), and sets
/// the next first pass's estimates: per row, how far the proven lower bound at the sample
/// lies below the pass's linear prediction.
fn certify(model: &Model, controller: &mut Controller, q: &[f64], qd: &[f64]) -> Check {
    let (nq, nb) = (controller.nq, controller.nb);
    let Some(ws) = controller.certified.as_mut() else {
        return Check::Below;
    };
    let nn = nq * nq;
    let s = ws.samples;
    // Barrier terms at the corrected prediction of the command.
    for j in 0..s {
        let (at, v) = ((j + 1) * nn, (j + 1) * nq);
        for i in 0..nq {
            let row = &ws.gamma[at + i * nq..at + (i + 1) * nq];
            let g2 = &ws.gamma2[at + i * nq..at + (i + 1) * nq];
            ws.point[i] = q[i]
                + ws.free[v + i]
                + dot(row, &ws.phi0)
                + dot(g2, &ws.phi1)
                + dot(row, &ws.center);
        }
        model.generated.barrier_terms(
            &model.params,
            &ws.point,
            &ws.zero,
            &mut ws.values[j * nb..(j + 1) * nb],
            &mut ws.jacobian[j * nb * nq..(j + 1) * nb * nq],
            &mut ws.jdot,
        );
    }
    // Per cell c (between entries c and c + 1): the predicted motion's barrier curvature
    // h²/8 sup |b̈|, the error's share |J| |ξ| (ξ bounded on [0, t_{c+1}]), and the
    // prediction's own floating-point error (PREDICTION_SLACK). Over the cell the barrier is
    // at least the smaller endpoint value less the cell's margin.
    let mut start_covered = true;
    let barriers = &controller.barrier_terms;
    ws.lowest.fill(f64::INFINITY);
    for c in 0..s {
        let h = ws.cell(c);
        for k in 0..nb {
            let jac = &ws.jacobian_box[k * nq..(k + 1) * nq];
            let (mut curvature, mut error) = (ws.jdot_box[k].mag(), 0.0);
            for i in 0..nq {
                curvature += jac[i].mag() * ws.acc_sup[c * nq + i];
                error += jac[i].mag() * ws.xi[c * nq + i];
            }
            let b0 = barriers.values()[k];
            let slack = PREDICTION_SLACK * (1.0 + (ws.values[c * nb + k] - b0).abs());
            let cell_margin = (0.125 * h * h * curvature + error + slack) * ROUNDING;
            ws.margin[c * nb + k] = cell_margin;
            let end = ws.values[c * nb + k];
            let mut lower = if c == 0 {
                b0.min(end)
            } else {
                ws.values[(c - 1) * nb + k].min(end)
            } - cell_margin;
            if c == 0 {
                // The first cell from the tick's exact state: the endpoint bound, or Taylor
                // from the exact ḃ₀.
                let b_dot = dot(&barriers.jacobian()[k * nq..(k + 1) * nq], qd);
                let taylor = (b0 + b_dot * h - 0.5 * curvature * h * h).min(b0) - error - slack;
                lower = lower.max(taylor);
                start_covered &= lower >= proven_floor(b0);
            }
            ws.lowest[k] = ws.lowest[k].min(lower);
        }
    }
    // A sample ends its cell and starts the next: the larger margin.
    for j in 0..s.saturating_sub(1) {
        for k in 0..nb {
            let next = ws.margin[(j + 1) * nb + k];
            let own = &mut ws.margin[j * nb + k];
            *own = own.max(next);
        }
    }
    let mut proven = true;
    for j in 0..s {
        for k in 0..nb {
            let r = j * nb + k;
            let lower = ws.values[r] - ws.margin[r];
            if lower < proven_floor(barriers.values()[k]) {
                proven = false;
            }
            // The first pass's linear prediction at the command: a·τ − rhs + floor + estimate.
            let row = &controller.rows[r * nq..(r + 1) * nq];
            let old = ws.row_estimate[r];
            let linear = dot(row, &controller.tau) - controller.rhs[r] + ws.floor[r] + old;
            ws.estimate[r] = ((linear - lower) * ESTIMATE_INFLATION).max(0.0);
        }
    }
    ws.last_xi.copy_from_slice(&ws.xi);
    ws.have_last = true;
    match (proven, start_covered) {
        (true, true) => Check::Proven,
        (true, false) => Check::Start,
        _ => Check::Below,
    }
}

/// What a proven hold keeps barrier `b0` \[m\] (its value at the tick) above: zero where it
/// starts at or above zero; a barrier already below zero (the predicted rows of an earlier
/// tick meet their last sample within `CHECK_TOLERANCE`, 1e-8 m, and a plant off the model
/// can push it further) may go no deeper than [`BELOW_ZERO_SLACK`] below where it started.
/// Until issue 27's sixth session such a barrier was left out of the proof: on
/// `robots/three-square.toml` a tick that read a corner at −3e-10 m was proven for a
/// command under which it fell to −2.6 µm (its bound, −5.1 µm, was right), and the
/// comparison curve of the next ticks let it settle at −11 µm.
fn proven_floor(b0: f64) -> f64 {
    if b0 >= 0.0 {
        0.0
    } else {
        b0 - BELOW_ZERO_SLACK
    }
}

/// How much deeper a proven hold may take a barrier that is below zero at its tick \[m\].
const BELOW_ZERO_SLACK: f64 = 1e-9;

/// The prediction's floating-point error \[m\] (absolute, and relative to the excursion of
/// the barrier): the computed linear motion and barrier values stand in for exact ones, and
/// differ from them by rounding far below this (the hold prediction agrees with a plain
/// integration to 1e-10 relative, tests/tests/controller/sampled_data.rs).
const PREDICTION_SLACK: f64 = 1e-12;

/// The first pass's estimate is the last proven gap times this (a little room for the gap
/// to grow with the command).
const ESTIMATE_INFLATION: f64 = 1.05;
