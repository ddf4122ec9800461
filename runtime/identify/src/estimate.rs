//! The estimates from the reduced rows: which parameters the logs excite, group weights,
//! the weighted least-squares solution, delete-one-block jackknife standard errors, the
//! parameters held at the file's values (with the reason) and the gains tied per module.

use super::regression::{Config, Reduced, solve, spectrum, stack, textbook_variances};
use super::rows::{RowKind, Rows};
use super::{PER_MODULE, Parameter};

/// A direction of the column-scaled regressor whose singular value is below this share
/// of the largest is not excited (numerically rank-deficient, e.g. proportional currents).
pub const RANK_TOLERANCE: f64 = 1e-8;
/// A column whose force at the file's value is below this share of the largest tendon
/// force column is zero (a coordinate that never moved).
pub const ZERO_COLUMN: f64 = 1e-9;
/// An estimate whose standard error exceeds this share of it is not excited enough to be
/// written.
pub const MAX_RELATIVE_ERROR: f64 = 0.5;
/// A module's three gains are written per servo only when two of them differ by more
/// than twice their combined standard error and by more than this share of their mean.
pub const GAIN_SPREAD: f64 = 0.01;
/// A group's weight is `1/RMS` of its residual, the RMS floored at this share of the
/// largest group's.
pub const WEIGHT_FLOOR: f64 = 1e-6;

/// Why a parameter was not identified.
#[derive(Clone, Debug, PartialEq)]
pub enum Status {
    /// Estimated from the logs.
    Identified,
    /// Kept at the file's value, for this reason.
    Kept(String),
}

/// Residual statistics of one kind of rows at the estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KindStats {
    /// Rows of this kind.
    pub rows: usize,
    /// Root mean square of the residual \[N\].
    pub rms: f64,
    /// `1 − SS_res/SS_tot`, `SS_tot` the centred sum of squares of the tendon forces
    /// `A diag(F[u]) g` (per coordinate); NaN without rows.
    pub r_squared: f64,
}

/// The outcome of the fit.
#[derive(Clone, Debug)]
pub struct Fit {
    /// Every parameter's value: the estimate, or the file's where kept.
    pub theta: Vec<f64>,
    /// Standard error of each estimate (NaN where kept): the jackknife's, combined with
    /// the timing, filter and noise parts (root sum of squares) once they are known.
    pub se: Vec<f64>,
    /// The delete-one-block jackknife's standard error (the statistical part).
    pub jackknife_se: Vec<f64>,
    /// The systematic part from the commands' landing times: half the change of the
    /// estimate when every landing moves from `−σ` to `+σ` (NaN: not computed).
    pub timing_error: Vec<f64>,
    /// The systematic part from the filter: the change of the estimate when the kernel's
    /// half-width grows by half (NaN: not computed).
    pub filter_error: Vec<f64>,
    /// The systematic part from the readings' noise: the change of the estimate when as
    /// much noise again is added to the readings (NaN: not computed).
    pub noise_error: Vec<f64>,
    /// The unknowns the estimate solved for (what is held and tied).
    pub(crate) config: Config,
    /// The weight of each group of rows.
    pub(crate) weights: Vec<f64>,
    /// The textbook standard error `σ √((XᵀX)⁻¹)ⱼⱼ` of the weighted rows (too optimistic
    /// for filtered rows, which are correlated; reported for comparison).
    pub textbook_se: Vec<f64>,
    /// Each parameter's status.
    pub status: Vec<Status>,
    /// Per module: its three gains share one value.
    pub tied: Vec<bool>,
    /// Notes on ties and holds, in the order they were decided.
    pub notes: Vec<String>,
    /// Static and dynamic rows at the estimate.
    pub stats: [KindStats; 2],
    /// Condition number of the column-scaled, weighted regressor of the unknowns.
    pub condition: f64,
    /// Blocks of the jackknife.
    pub blocks: usize,
}

/// The unknowns given what is held and tied.
fn config(p: usize, held: &[Option<String>], tied: &[bool], file: &[f64]) -> Config {
    let mut unknowns = Vec::new();
    for j in 0..p {
        if held[j].is_some() {
            continue;
        }
        let (module, parameter) = Parameter::of_index(j);
        match parameter {
            Parameter::ActuatorGain(_) if tied[module] => {
                // One unknown for the module's free gains, placed at the first of them.
                let base = PER_MODULE * module + 4;
                let members: Vec<usize> = (base..base + 3).filter(|&k| held[k].is_none()).collect();
                if members.first() == Some(&j) {
                    unknowns.push(members);
                }
            }
            _ => unknowns.push(vec![j]),
        }
    }
    let held = (0..p)
        .filter(|&j| held[j].is_some())
        .map(|j| (j, file[j]))
        .collect();
    Config { unknowns, held }
}

/// Every reduced part with its group's weight, optionally without block `skip`.
fn parts<'a>(
    rows: &'a Rows,
    weights: &'a [f64],
    skip: Option<usize>,
) -> impl Iterator<Item = (&'a Reduced, f64)> + 'a {
    rows.blocks
        .iter()
        .enumerate()
        .filter(move |(b, _)| Some(*b) != skip)
        .flat_map(move |(_, groups)| {
            groups
                .iter()
                .zip(weights)
                .filter_map(|(part, &w)| part.as_ref().map(|part| (part, w)))
        })
}

/// Holds or ties what the rows cannot determine: zero columns, then directions of tiny
/// singular value (a module's gains only: tie them; otherwise hold the parameter most in
/// that direction). Returns the resulting configuration.
fn excite(
    rows: &Rows,
    weights: &[f64],
    file: &[f64],
    held: &mut [Option<String>],
    tied: &mut [bool],
    notes: &mut Vec<String>,
) -> Config {
    let p = file.len();
    loop {
        let cfg = config(p, held, tied, file);
        if cfg.unknowns.is_empty() {
            return cfg;
        }
        let stacked = stack(parts(rows, weights, None), &cfg);
        let Some(s) = spectrum(&stacked) else {
            return cfg;
        };
        // Zero columns: the force of the unknown at its file value against the largest
        // tendon force.
        let reference = |u: usize| {
            let j = cfg.unknowns[u][0];
            if file[j] > 0.0 { file[j] } else { 1.0 }
        };
        let force_scale = (0..cfg.unknowns.len())
            .filter(|&u| {
                matches!(
                    Parameter::of_index(cfg.unknowns[u][0]).1,
                    Parameter::ActuatorGain(_)
                )
            })
            .map(|u| s.norms[u] * reference(u))
            .fold(0.0, f64::max);
        let force_scale = if force_scale > 0.0 {
            force_scale
        } else {
            (0..cfg.unknowns.len())
                .map(|u| s.norms[u] * reference(u))
                .fold(0.0, f64::max)
        };
        let zero: Vec<usize> = (0..cfg.unknowns.len())
            .filter(|&u| {
                let force = s.norms[u] * reference(u);
                force.is_nan() || force <= ZERO_COLUMN * force_scale
            })
            .collect();
        if !zero.is_empty() {
            for u in zero {
                for &j in &cfg.unknowns[u] {
                    held[j] = Some(
                        "not excited by these logs (its column of the regressor is zero: \
                                    the motion or input it multiplies never occurred)"
                            .into(),
                    );
                }
            }
            continue;
        }
        let largest = s.values.first().copied().unwrap_or(0.0);
        let Some(k) = (0..s.values.len())
            .rev()
            .find(|&k| s.values[k] < RANK_TOLERANCE * largest)
        else {
            return cfg;
        };
        let v = &s.vectors[k];
        let involved: Vec<usize> = (0..v.len()).filter(|&u| v[u].abs() > 0.1).collect();
        let gain_module = |u: usize| match Parameter::of_index(cfg.unknowns[u][0]) {
            (module, Parameter::ActuatorGain(_)) if cfg.unknowns[u].len() == 1 => Some(module),
            _ => None,
        };
        if let Some(module) = involved.first().and_then(|&u| gain_module(u))
            && involved.iter().all(|&u| gain_module(u) == Some(module))
            && !tied[module]
        {
            tied[module] = true;
            notes.push(format!(
                "module {}: these logs cannot tell its three actuator gains apart (their \
                 currents moved together); one gain for the module",
                module + 1
            ));
            continue;
        }
        let Some(&worst) = involved
            .iter()
            .max_by(|&&a, &&b| v[a].abs().total_cmp(&v[b].abs()))
        else {
            return cfg;
        };
        let others: Vec<String> = involved
            .iter()
            .filter(|&&u| u != worst)
            .map(|&u| Parameter::describe(cfg.unknowns[u][0]))
            .collect();
        for &j in &cfg.unknowns[worst] {
            held[j] = Some(format!(
                "not excited by these logs: its effect cannot be told from {} (singular \
                 value {:.1e} of the largest)",
                if others.is_empty() {
                    "nothing".to_string()
                } else {
                    others.join(", ")
                },
                s.values[k] / largest
            ));
        }
    }
}

/// Residual sum of squares per group at `theta`, and row counts.
fn group_squares(rows: &Rows, theta: &[f64]) -> Vec<(f64, usize)> {
    let mut out = vec![(0.0, 0); rows.groups()];
    for groups in &rows.blocks {
        for (g, part) in groups.iter().enumerate() {
            if let Some(part) = part {
                out[g].0 += part.residual_squares(theta);
                out[g].1 += part.rows;
            }
        }
    }
    out
}

/// Weights `1/RMS` per group from the residual at `theta`.
fn weights_from(rows: &Rows, theta: &[f64]) -> Vec<f64> {
    let squares = group_squares(rows, theta);
    let rms: Vec<f64> = squares
        .iter()
        .map(|&(ss, n)| if n > 0 { (ss / n as f64).sqrt() } else { 0.0 })
        .collect();
    let largest = rms
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    if largest <= 0.0 {
        return vec![1.0; rms.len()];
    }
    rms.iter()
        .map(|&r| 1.0 / r.max(WEIGHT_FLOOR * largest))
        .collect()
}

/// Delete-one-block jackknife standard errors of the unknowns of `cfg`: infinite where a
/// refit without some block fails.
fn jackknife(rows: &Rows, weights: &[f64], cfg: &Config) -> Vec<f64> {
    let b = rows.blocks.len();
    let n = cfg.unknowns.len();
    if b < 2 {
        return vec![f64::NAN; n];
    }
    let mut estimates = Vec::with_capacity(b);
    for skip in 0..b {
        match solve(&stack(parts(rows, weights, Some(skip)), cfg)) {
            Some(x) => estimates.push(x),
            None => return vec![f64::INFINITY; n],
        }
    }
    (0..n)
        .map(|u| {
            let mean = estimates.iter().map(|x| x[u]).sum::<f64>() / b as f64;
            let spread: f64 = estimates.iter().map(|x| (x[u] - mean).powi(2)).sum();
            ((b - 1) as f64 / b as f64 * spread).sqrt()
        })
        .collect()
}

/// The fit, from the reduced rows and the file's values (the order of
/// [`Parameter::of_index`]).
pub fn fit(rows: &Rows, file: &[f64]) -> Result<Fit, String> {
    let p = file.len();
    let modules = rows.modules;
    let mut held: Vec<Option<String>> = vec![None; p];
    let mut tied = vec![false; modules];
    let mut notes = Vec::new();
    // A first, unweighted fit gives the groups' residuals and so their weights.
    let ones = vec![1.0; rows.groups()];
    let cfg = excite(rows, &ones, file, &mut held, &mut tied, &mut notes);
    let x = solve(&stack(parts(rows, &ones, None), &cfg))
        .ok_or("the least-squares problem could not be solved (no rows, or non-finite ones)")?;
    let weights = weights_from(rows, &cfg.theta(&x, p));
    let mut last = None;
    for _ in 0..2 * p + 2 {
        let cfg = excite(rows, &weights, file, &mut held, &mut tied, &mut notes);
        let stacked = stack(parts(rows, &weights, None), &cfg);
        let Some(x) = solve(&stacked) else {
            return Err("the weighted least-squares problem could not be solved".into());
        };
        let se = jackknife(rows, &weights, &cfg);
        let mut changed = false;
        for (u, members) in cfg.unknowns.iter().enumerate() {
            let (module, parameter) = Parameter::of_index(members[0]);
            let is_gain = matches!(parameter, Parameter::ActuatorGain(_));
            if x[u].is_nan() || x[u] <= 0.0 {
                for &j in members {
                    held[j] = Some(format!(
                        "the estimate {:.4e} is not positive (physically impossible)",
                        x[u]
                    ));
                }
                changed = true;
            } else if se[u].is_nan() || se[u] > MAX_RELATIVE_ERROR * x[u] {
                if is_gain && !tied[module] {
                    tied[module] = true;
                    notes.push(format!(
                        "module {}: its per-servo gains are poorly determined ({} ± {:.2e}); \
                         one gain for the module",
                        module + 1,
                        Parameter::describe(members[0]),
                        se[u]
                    ));
                } else {
                    for &j in members {
                        held[j] = Some(format!(
                            "poorly excited by these logs: {:.4e} ± {:.1e}",
                            x[u], se[u]
                        ));
                    }
                }
                changed = true;
            }
        }
        if changed {
            continue;
        }
        // Per-servo gains are kept only when they differ beyond their errors.
        for (module, tie) in tied.iter_mut().enumerate() {
            if *tie {
                continue;
            }
            let base = PER_MODULE * module + 4;
            let free: Vec<(f64, f64)> = (base..base + 3)
                .filter_map(|j| {
                    cfg.unknowns
                        .iter()
                        .position(|m| m == &vec![j])
                        .map(|u| (x[u], se[u]))
                })
                .collect();
            if free.len() < 2 {
                continue;
            }
            let mean = free.iter().map(|g| g.0).sum::<f64>() / free.len() as f64;
            let apart = free.iter().enumerate().any(|(a, ga)| {
                free[a + 1..].iter().any(|gb| {
                    let difference = (ga.0 - gb.0).abs();
                    difference > 2.0 * (ga.1.powi(2) + gb.1.powi(2)).sqrt()
                        && difference > GAIN_SPREAD * mean
                })
            });
            if !apart {
                *tie = true;
                changed = true;
                notes.push(format!(
                    "module {}: its three gains agree within {:.0} % or their standard \
                     errors; one gain for the module",
                    module + 1,
                    100.0 * GAIN_SPREAD
                ));
            }
        }
        if !changed {
            last = Some((cfg, x, se, stacked));
            break;
        }
    }
    let Some((cfg, x, se_unknowns, stacked)) = last else {
        return Err("the fit did not settle on which parameters to identify".into());
    };
    let theta = cfg.theta(&x, p);
    let mut se = vec![f64::NAN; p];
    let mut textbook_se = vec![f64::NAN; p];
    let total_rows: usize = rows.rows.iter().sum();
    let weighted_squares: f64 = stacked
        .iter()
        .map(|row| {
            let fitted: f64 = row.iter().zip(&x).map(|(a, b)| a * b).sum();
            (fitted - row[x.len()]).powi(2)
        })
        .sum();
    let dof = total_rows.saturating_sub(x.len()).max(1) as f64;
    let variances = textbook_variances(&stacked);
    for (u, members) in cfg.unknowns.iter().enumerate() {
        for &j in members {
            se[j] = se_unknowns[u];
            if let Some(v) = &variances {
                textbook_se[j] = (weighted_squares / dof * v[u]).sqrt();
            }
        }
    }
    let status = held
        .into_iter()
        .map(|h| h.map_or(Status::Identified, Status::Kept))
        .collect();
    let condition = spectrum(&stacked)
        .and_then(|s| {
            let (first, last) = (s.values.first()?, s.values.last()?);
            Some(first / last)
        })
        .unwrap_or(f64::NAN);
    Ok(Fit {
        stats: kind_stats(rows, &theta),
        theta,
        jackknife_se: se.clone(),
        se,
        timing_error: vec![f64::NAN; p],
        filter_error: vec![f64::NAN; p],
        noise_error: vec![f64::NAN; p],
        config: cfg,
        weights,
        textbook_se,
        status,
        tied,
        notes,
        condition,
        blocks: rows.blocks.len(),
    })
}

/// The estimate from other rows (the same logs with a different landing time or filter)
/// with `fit`'s unknowns and weights; `None` when it cannot be solved.
pub fn refit(rows: &Rows, fit: &Fit) -> Option<Vec<f64>> {
    let x = solve(&stack(parts(rows, &fit.weights, None), &fit.config))?;
    let theta = fit.config.theta(&x, fit.theta.len());
    theta.iter().all(|v| v.is_finite()).then_some(theta)
}

/// The refits of [`add_systematic`], each `None` where not computed.
#[derive(Default)]
pub struct Refits {
    /// With every landing moved by `−σ` and by `+σ`.
    pub timing: Option<(Vec<f64>, Vec<f64>)>,
    /// With the wider kernel.
    pub filter: Option<Vec<f64>>,
    /// With as much noise again added to the readings.
    pub noise: Option<Vec<f64>>,
}

/// Sets the systematic parts from the refits and makes each identified parameter's
/// standard error the root sum of squares of its parts. A part not computed counts as
/// zero and stays NaN in its own column.
pub fn add_systematic(fit: &mut Fit, refits: &Refits) {
    for j in 0..fit.theta.len() {
        if fit.status[j] != Status::Identified {
            continue;
        }
        if let Some((minus, plus)) = &refits.timing {
            fit.timing_error[j] = 0.5 * (plus[j] - minus[j]).abs();
        }
        if let Some(wide) = &refits.filter {
            fit.filter_error[j] = (wide[j] - fit.theta[j]).abs();
        }
        if let Some(noisy) = &refits.noise {
            fit.noise_error[j] = (noisy[j] - fit.theta[j]).abs();
        }
        let part = |v: f64| if v.is_nan() { 0.0 } else { v * v };
        fit.se[j] = (part(fit.jackknife_se[j])
            + part(fit.timing_error[j])
            + part(fit.filter_error[j])
            + part(fit.noise_error[j]))
        .sqrt();
        if fit.jackknife_se[j].is_nan() {
            fit.se[j] = f64::NAN;
        }
    }
}

/// Residual RMS and R² of the static and dynamic rows at `theta`.
fn kind_stats(rows: &Rows, theta: &[f64]) -> [KindStats; 2] {
    let mut out = [KindStats {
        rows: 0,
        rms: f64::NAN,
        r_squared: f64::NAN,
    }; 2];
    let groups = rows.groups();
    let mut residual = [0.0; 2];
    let mut total = [0.0; 2];
    for g in 0..groups {
        let (kind, module) = rows.group(g);
        let k = usize::from(kind == RowKind::Dynamic);
        let gains: Vec<usize> = (0..3).map(|c| PER_MODULE * module + 4 + c).collect();
        let (mut squares, mut sums, mut counts) = (0.0, [0.0; 3], [0usize; 3]);
        for groups in &rows.blocks {
            let Some(part) = &groups[g] else { continue };
            out[k].rows += part.rows;
            residual[k] += part.residual_squares(theta);
            squares += part.explained_squares(theta, &gains);
            for c in 0..3 {
                sums[c] += gains
                    .iter()
                    .map(|&j| part.sums[c][j] * theta[j])
                    .sum::<f64>();
                counts[c] += part.counts[c];
            }
        }
        let means: f64 = (0..3)
            .filter(|&c| counts[c] > 0)
            .map(|c| sums[c] * sums[c] / counts[c] as f64)
            .sum();
        total[k] += squares - means;
    }
    for k in 0..2 {
        if out[k].rows > 0 {
            out[k].rms = (residual[k] / out[k].rows as f64).sqrt();
            out[k].r_squared = 1.0 - residual[k] / total[k];
        }
    }
    out
}
