//! The regression rows of identification, built from the logs and reduced block by block:
//! one row per coordinate at each output instant (the filtered equation of motion) and at
//! each static rest state (the averaged equilibrium), in parallel over blocks of time.
//!
//! Per module `i` the unknowns are `κθ, κL, βθ, βL, g₁, g₂, g₃` (see
//! [`super::Parameter`]) and the row of coordinate `c` is
//! `K F[q] + D F[q̇] − A diag(F[u]) g = −(M(q̄) F[q̈] + F[1]·(h(q̄, v̄) + G(q̄)))`
//! with `u_k = max(s_k I_k, 0)` \[mA\], `q̄ = F[q]/F[1]`, `v̄ = F[q̇]/F[1]` (docs/model.md
//! §4); at rest `K q̄ − A diag(ū) g = −G(q̄)`.

use crate::dynamics::{DynamicsWorkspace, bias_and_gravity, mass_matrix, update_joints};
use crate::hardware_description::Hardware;
use crate::model::Model;

use super::filter::{Kernel, trapezoid_weight};
use super::logs::{ExperimentKind, Log};
use super::regression::{Accumulator, Reduced};
use super::{IdentifyError, PER_MODULE, parallel_map};

/// How rows are made from the logs.
#[derive(Clone, Copy, Debug)]
pub struct RowSettings {
    /// The filter kernel.
    pub kernel: Kernel,
    /// Least time between two output instants \[s\] (0: every reading).
    pub spacing: f64,
    /// Share of each dynamic log, at its end, kept out of the fit.
    pub holdout: f64,
    /// Number of blocks of time (for the jackknife).
    pub blocks: usize,
}

/// Static rows or dynamic rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowKind {
    /// Averaged rest states.
    Static,
    /// Filtered equation of motion.
    Dynamic,
}

/// The rows of all logs, reduced per block and group.
#[derive(Debug)]
pub struct Rows {
    /// `blocks[b][g]`: the rows of group `g` in block `b` (group `g = kind · n + module`,
    /// kind 0 static, 1 dynamic).
    pub blocks: Vec<Vec<Option<Reduced>>>,
    /// Number of modules.
    pub modules: usize,
    /// Output instants used.
    pub instants: usize,
    /// Rest states used.
    pub rest_states: usize,
    /// Static and dynamic rows.
    pub rows: [usize; 2],
}

impl Rows {
    /// The kind and module of group `g`.
    pub fn group(&self, g: usize) -> (RowKind, usize) {
        let kind = if g < self.modules {
            RowKind::Static
        } else {
            RowKind::Dynamic
        };
        (kind, g % self.modules)
    }

    /// Number of groups.
    pub fn groups(&self) -> usize {
        2 * self.modules
    }
}

/// One output instant (a reading's index) or one rest state (a range of readings).
#[derive(Clone, Copy, Debug)]
enum Item {
    Instant(usize),
    Rest(usize, usize),
}

/// The start of the held-out part of `log` \[s\]: the last `holdout` of a dynamic log's
/// readings; never for other logs.
pub fn holdout_start(log: &Log, holdout: f64) -> f64 {
    if !is_dynamic(log) || log.time.is_empty() {
        return f64::INFINITY;
    }
    let (first, last) = (log.time[0], log.time[log.time.len() - 1]);
    last - holdout * (last - first)
}

/// Whether a log is a dynamic experiment: so named, or unnamed and without rest states.
pub fn is_dynamic(log: &Log) -> bool {
    match log.kind {
        Some(kind) => kind == ExperimentKind::Dynamic,
        None => !log.rest.iter().any(|&r| r),
    }
}

/// The longest gap between readings a filter window may span: 2.5 median intervals.
fn gap_limit(log: &Log) -> f64 {
    let mut intervals: Vec<f64> = log.time.windows(2).map(|w| w[1] - w[0]).collect();
    if intervals.is_empty() {
        return 0.0;
    }
    let middle = intervals.len() / 2;
    let (_, median, _) = intervals.select_nth_unstable_by(middle, f64::total_cmp);
    2.5 * *median
}

/// The output instants and rest states of `log`, in time order.
fn items(log: &Log, settings: &RowSettings) -> Vec<Item> {
    let n = log.readings();
    let t_half = settings.kernel.half_width();
    let end_of_fit = holdout_start(log, settings.holdout);
    let limit = gap_limit(log);
    let first_landing = log.landing.first().copied().unwrap_or(f64::INFINITY);
    let mut items = Vec::new();
    // The readings of a window [t − T, t + T] run from `lo` (the last at or before its
    // start) to `hi` (the first at or after its end); gaps are checked over that span.
    let mut lo = 0;
    let mut hi = 0;
    // Index of the first gap larger than the limit at or after `lo`.
    let gaps: Vec<usize> = (1..n)
        .filter(|&j| log.time[j] - log.time[j - 1] > limit)
        .collect();
    let mut gap = 0;
    let mut last_instant = f64::NEG_INFINITY;
    let mut rest_start: Option<usize> = None;
    for j in 0..n {
        let t = log.time[j];
        // Rest states: runs of rest readings with one step.
        let rest_here = log.rest[j] && t < end_of_fit;
        match rest_start {
            Some(start) if !rest_here || !same_step(log.step[start], log.step[j]) => {
                items.push(Item::Rest(start, j));
                rest_start = rest_here.then_some(j);
            }
            None if rest_here => rest_start = Some(j),
            _ => {}
        }
        if t - last_instant < settings.spacing {
            continue;
        }
        if t - t_half < log.time[0] || t - t_half < first_landing || t + t_half > end_of_fit {
            continue;
        }
        while lo + 1 < n && log.time[lo + 1] <= t - t_half {
            lo += 1;
        }
        while hi < n && log.time[hi] < t + t_half {
            hi += 1;
        }
        if hi >= n {
            break;
        }
        while gap < gaps.len() && gaps[gap] <= lo {
            gap += 1;
        }
        if gap < gaps.len() && gaps[gap] <= hi {
            continue;
        }
        items.push(Item::Instant(j));
        last_instant = t;
    }
    if let Some(start) = rest_start {
        items.push(Item::Rest(start, n));
    }
    items.sort_by(|a, b| item_time(log, a).total_cmp(&item_time(log, b)));
    items
}

fn same_step(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan())
}

fn item_time(log: &Log, item: &Item) -> f64 {
    match *item {
        Item::Instant(j) => log.time[j],
        Item::Rest(start, end) => log.time[end - 1].max(log.time[start]),
    }
}

/// What the row builder needs of the robot, per module: `d²` and `A`.
struct Geometry {
    d2: Vec<f64>,
    /// `a[i][c][k]`: row `c` (Δx, Δy, δL), tendon `k` of module `i`'s `A_i`.
    a: Vec<[[f64; 3]; 3]>,
    directions: Vec<f64>,
}

impl Geometry {
    fn new(model: &Model, hardware: &Hardware) -> Geometry {
        let modules = &model.robot.modules;
        Geometry {
            d2: modules.iter().map(|m| m.tendon_radius.powi(2)).collect(),
            a: modules
                .iter()
                .map(|m| {
                    let psi = &m.tendon_angles;
                    std::array::from_fn(|c| {
                        std::array::from_fn(|k| match c {
                            0 => psi[k].cos(),
                            1 => psi[k].sin(),
                            _ => -1.0,
                        })
                    })
                })
                .collect(),
            directions: hardware.modules.iter().flat_map(|m| m.directions).collect(),
        }
    }

    /// Writes the regression row of coordinate `r` into `row` (zeroed first): stiffness
    /// and damping columns from `fq`, `fqd`, gain columns from `fu`, right-hand side `y`.
    fn row(&self, r: usize, fq: f64, fqd: f64, fu: &[f64], y: f64, row: &mut [f64]) {
        row.fill(0.0);
        let (i, c) = (r / 3, r % 3);
        let base = PER_MODULE * i;
        if c < 2 {
            row[base] = fq / self.d2[i];
            row[base + 2] = fqd / self.d2[i];
        } else {
            row[base + 1] = fq;
            row[base + 3] = fqd;
        }
        for k in 0..3 {
            row[base + 4 + k] = -self.a[i][c][k] * fu[3 * i + k];
        }
        let p = row.len() - 1;
        row[p] = y;
    }
}

/// Builds and reduces the rows of every log.
pub fn build(
    model: &Model,
    hardware: &Hardware,
    logs: &[Log],
    settings: &RowSettings,
) -> Result<Rows, IdentifyError> {
    let mut rows = build_shifted(model, hardware, logs, settings, &[0.0])?;
    rows.pop()
        .ok_or_else(|| IdentifyError::Fit("no rows were built".into()))
}

/// The rows of every log once per entry of `shifts`, each with every command's landing
/// moved by that much \[s\] (in one pass: the filtered readings and the model are shared).
pub fn build_shifted(
    model: &Model,
    hardware: &Hardware,
    logs: &[Log],
    settings: &RowSettings,
    shifts: &[f64],
) -> Result<Vec<Rows>, IdentifyError> {
    let modules = model.n_modules();
    let p = PER_MODULE * modules;
    let geometry = Geometry::new(model, hardware);
    let per_log: Vec<Vec<Item>> = parallel_map(logs.len(), |l| items(&logs[l], settings));
    for (log, items) in logs.iter().zip(&per_log) {
        if items.is_empty() {
            return Err(too_short(log, settings));
        }
    }
    let total: usize = per_log.iter().map(Vec::len).sum();
    let nq = model.nq();
    if total * nq < p + 1 {
        return Err(IdentifyError::TooShort {
            file: "the logs".into(),
            have: format!(
                "{} equations ({total} instants and rest states)",
                total * nq
            ),
            need: format!("more than the {p} unknowns"),
        });
    }
    let blocks = settings.blocks.clamp(1, total);
    // Work units: the items of one log in one block.
    let mut units: Vec<(usize, usize, std::ops::Range<usize>)> = Vec::new();
    let mut global = 0;
    for (l, items) in per_log.iter().enumerate() {
        let mut start = 0;
        while start < items.len() {
            let block = (global + start) * blocks / total;
            let mut end = start + 1;
            while end < items.len() && (global + end) * blocks / total == block {
                end += 1;
            }
            units.push((l, block, start..end));
            start = end;
        }
        global += items.len();
    }
    let inputs: Vec<Vec<f64>> = parallel_map(logs.len(), |l| tension_inputs(&logs[l], &geometry));
    let results = parallel_map(units.len(), |u| {
        let (l, _, ref range) = units[u];
        reduce_unit(
            model,
            &geometry,
            &logs[l],
            &inputs[l],
            &per_log[l][range.clone()],
            settings,
            shifts,
        )
    });
    let mut reduced: Vec<Vec<Vec<Option<Reduced>>>> = shifts
        .iter()
        .map(|_| {
            (0..blocks)
                .map(|_| (0..2 * modules).map(|_| None).collect())
                .collect()
        })
        .collect();
    for ((_, block, _), per_shift) in units.iter().zip(results) {
        for (variant, parts) in reduced.iter_mut().zip(per_shift?) {
            for (g, part) in parts.into_iter().enumerate() {
                let Some(part) = part else { continue };
                let slot = &mut variant[*block][g];
                *slot = Some(match slot.take() {
                    Some(existing) => existing.merge(part),
                    None => part,
                });
            }
        }
    }
    let (mut instants, mut rest_states) = (0, 0);
    for item in per_log.iter().flatten() {
        match item {
            Item::Instant(_) => instants += 1,
            Item::Rest(..) => rest_states += 1,
        }
    }
    Ok(reduced
        .into_iter()
        .map(|blocks| Rows {
            blocks,
            modules,
            instants,
            rest_states,
            rows: [rest_states * nq, instants * nq],
        })
        .collect())
}

/// The error of a log that yields no row.
fn too_short(log: &Log, settings: &RowSettings) -> IdentifyError {
    let span = match (log.time.first(), log.time.last()) {
        (Some(a), Some(b)) => b - a,
        _ => 0.0,
    };
    let window = 2.0 * settings.kernel.half_width();
    let need = if is_dynamic(log) {
        format!(
            "one filter window of {window:.3} s of readings after the first command lands, \
             in the first {:.0} % of the log (the rest is held out): at least {:.3} s",
            100.0 * (1.0 - settings.holdout),
            window / (1.0 - settings.holdout).max(1e-9)
        )
    } else {
        format!(
            "one rest state, or one filter window of {window:.3} s of readings after the \
             first command lands"
        )
    };
    IdentifyError::TooShort {
        file: log.file.clone(),
        have: format!("{span:.3} s of readings ({} rows)", log.readings()),
        need,
    }
}

/// `u = max(s·I, 0)` \[mA\] of every command of `log`, one per servo.
fn tension_inputs(log: &Log, geometry: &Geometry) -> Vec<f64> {
    log.current
        .chunks_exact(log.servos.max(1))
        .flat_map(|currents| {
            currents
                .iter()
                .zip(&geometry.directions)
                .map(|(&current, &s)| (s * current).max(0.0))
        })
        .collect()
}

/// Reduces the rows of `items` of `log` into one accumulator per group, once per landing
/// shift.
fn reduce_unit(
    model: &Model,
    geometry: &Geometry,
    log: &Log,
    inputs: &[f64],
    items: &[Item],
    settings: &RowSettings,
    shifts: &[f64],
) -> Result<Vec<Vec<Option<Reduced>>>, IdentifyError> {
    let modules = model.n_modules();
    let nq = model.nq();
    let p = PER_MODULE * modules;
    let servos = log.servos;
    let kernel = &settings.kernel;
    let t_half = kernel.half_width();

    let mut accumulators: Vec<Vec<Accumulator>> = shifts
        .iter()
        .map(|_| {
            (0..2 * modules)
                .map(|g| {
                    // A group's rows are zero outside its module's parameters.
                    let base = PER_MODULE * (g % modules);
                    let columns = (base..base + PER_MODULE).chain([p]).collect();
                    Accumulator::of_columns(p + 1, columns)
                })
                .collect()
        })
        .collect();
    let mut ws = DynamicsWorkspace::new(model);
    let (mut fq, mut fqd, mut fqdd) = (vec![0.0; nq], vec![0.0; nq], vec![0.0; nq]);
    let mut fu = vec![0.0; servos];
    let command_inputs = |m: usize| &inputs[m * servos..(m + 1) * servos];
    let (mut q_bar, mut v_bar, mut known) = (vec![0.0; nq], vec![0.0; nq], vec![0.0; nq]);
    let mut row = vec![0.0; p + 1];
    let n = log.readings();
    let mut lo = 0;
    // Per shift: the first command in force at the current window's start.
    let mut commands = vec![0usize; shifts.len()];
    let state_error = |j: usize, what: String| IdentifyError::Value {
        file: log.file.clone(),
        line: log.line[j],
        column: "dx1 [m]".into(),
        what,
    };
    for item in items {
        match *item {
            Item::Instant(j) => {
                let t = log.time[j];
                while lo + 1 < n && log.time[lo + 1] <= t - t_half {
                    lo += 1;
                }
                fq.fill(0.0);
                fqd.fill(0.0);
                fqdd.fill(0.0);
                let mut f1 = 0.0;
                let mut k = lo;
                while k < n && log.time[k] < t + t_half {
                    let [k0, k1, k2] = kernel.values(t - log.time[k]);
                    if k0 > 0.0 {
                        let w = trapezoid_weight(&log.time, k);
                        let (w0, w1, w2) = (w * k0, w * k1, w * k2);
                        f1 += w0;
                        let q = log.q_of(k);
                        for (((a, b), c), &q) in fq.iter_mut().zip(&mut fqd).zip(&mut fqdd).zip(q) {
                            *a += w0 * q;
                            *b += w1 * q;
                            *c += w2 * q;
                        }
                    }
                    k += 1;
                }
                for r in 0..nq {
                    q_bar[r] = fq[r] / f1;
                    v_bar[r] = fqd[r] / f1;
                }
                update_joints(model, &mut ws, &q_bar, &v_bar)
                    .and_then(|()| mass_matrix(model, &mut ws))
                    .and_then(|()| bias_and_gravity(model, &mut ws, &v_bar))
                    .map_err(|e| state_error(j, format!("the model fails here: {e}")))?;
                for (r, slot) in known.iter_mut().enumerate() {
                    let row = &ws.mass_matrix[r * nq..(r + 1) * nq];
                    let inertia: f64 = row.iter().zip(&fqdd).map(|(m, a)| m * a).sum();
                    *slot = inertia + f1 * (ws.bias[r] + ws.gravity[r]);
                }
                if !known.iter().all(|v| v.is_finite()) {
                    return Err(state_error(j, "the model gives a non-finite force".into()));
                }
                for ((&shift, command), accumulators) in
                    shifts.iter().zip(&mut commands).zip(&mut accumulators)
                {
                    // Commands in force over the window: from the last landing at or
                    // before its start to the last one before its end.
                    let landing = |m: usize| log.landing[m] + shift;
                    while *command + 1 < log.landing.len() && landing(*command + 1) <= t - t_half {
                        *command += 1;
                    }
                    fu.fill(0.0);
                    let mut m = *command;
                    let mut before = kernel.cumulative(t - landing(m));
                    while m < log.landing.len() && landing(m) < t + t_half {
                        let hold_end = if m + 1 < log.landing.len() {
                            landing(m + 1)
                        } else {
                            log.end
                        };
                        let after = kernel.cumulative(t - hold_end);
                        let weight = before - after;
                        for (slot, value) in fu.iter_mut().zip(command_inputs(m)) {
                            *slot += weight * value;
                        }
                        before = after;
                        m += 1;
                    }
                    if !fu.iter().all(|v| v.is_finite()) {
                        return Err(state_error(j, "a non-finite goal current".into()));
                    }
                    for r in 0..nq {
                        geometry.row(r, fq[r], fqd[r], &fu, -known[r], &mut row);
                        accumulators[modules + r / 3].push(&row, r % 3);
                    }
                }
            }
            Item::Rest(start, end) => {
                q_bar.fill(0.0);
                fu.fill(0.0);
                let mut count = 0usize;
                let mut m = 0usize;
                for j in start..end {
                    // The command in force at the reading: the last landed before it.
                    while m + 1 < log.landing.len() && log.landing[m + 1] <= log.time[j] {
                        m += 1;
                    }
                    if log.landing.first().is_none_or(|&l| l > log.time[j]) {
                        continue;
                    }
                    for (slot, value) in fu.iter_mut().zip(command_inputs(m)) {
                        *slot += value;
                    }
                    for (slot, value) in q_bar.iter_mut().zip(log.q_of(j)) {
                        *slot += value;
                    }
                    count += 1;
                }
                if count == 0 {
                    continue;
                }
                let scale = 1.0 / count as f64;
                q_bar.iter_mut().for_each(|v| *v *= scale);
                fu.iter_mut().for_each(|v| *v *= scale);
                v_bar.fill(0.0);
                update_joints(model, &mut ws, &q_bar, &v_bar)
                    .and_then(|()| bias_and_gravity(model, &mut ws, &v_bar))
                    .map_err(|e| state_error(start, format!("the model fails here: {e}")))?;
                if !ws.gravity.iter().all(|v| v.is_finite()) {
                    return Err(state_error(
                        start,
                        "the model gives a non-finite force".into(),
                    ));
                }
                for r in 0..nq {
                    geometry.row(r, q_bar[r], 0.0, &fu, -ws.gravity[r], &mut row);
                    for accumulators in &mut accumulators {
                        accumulators[r / 3].push(&row, r % 3);
                    }
                }
            }
        }
    }
    Ok(accumulators
        .into_iter()
        .map(|groups| groups.into_iter().map(Accumulator::finish).collect())
        .collect())
}
