//! Settings of the safety QP (documented defaults, `validate`) and the setup error
//! returned by `SafetyQp::new`.

use std::fmt;

/// Settings of [`SafetyQp`](super::SafetyQp). Tolerances are relative to the
/// problem scale `1 + max(‖τ_nom‖∞, ‖τ‖∞, max |bᵢ|/‖aᵢ‖)` and apply to unit-norm rows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QpSettings {
    /// Use the dual active-set fast path first (clarabel only on its failure).
    /// Default `true`.
    pub use_fast_path: bool,
    /// Fast path: a row is violated when its scaled slack is below
    /// `−feasibility_tol · (1 + |b̂ᵢ| + ‖τ‖∞)`. Default `1e-10`.
    pub feasibility_tol: f64,
    /// Fast path: a row whose unit normal lies closer than this to the span of the
    /// active rows is treated as linearly dependent on them. Default `1e-10`.
    pub dependence_tol: f64,
    /// Fast path: maximum number of add/drop steps per solve. Default `500`.
    pub max_iterations: usize,
    /// Clarabel: maximum interior-point iterations. Default `100`.
    pub clarabel_max_iter: u32,
    /// Clarabel: duality-gap (absolute and relative) and feasibility tolerance.
    /// Default `1e-10`.
    pub clarabel_tol: f64,
    /// KKT acceptance tolerance (primal and dual feasibility, complementarity,
    /// stationarity) checked before reporting `Solved`/`Relaxed`. Default `1e-7`.
    pub kkt_tol: f64,
    /// Weight ρ of the relaxed problem's `½ ρ ‖s‖²` (slacks of unit-norm rows, τ
    /// units). A row pushed with multiplier λ̂ then carries a violation λ̂/ρ.
    /// Range `[1, 1e12]`. Default `1e8`.
    pub slack_penalty: f64,
    /// A row is reported in `relaxed_rows` when its violation (τ units) exceeds
    /// this. Default `1e-6`.
    pub relaxed_row_tol: f64,
}

impl Default for QpSettings {
    fn default() -> Self {
        Self {
            use_fast_path: true,
            feasibility_tol: 1e-10,
            dependence_tol: 1e-10,
            max_iterations: 500,
            clarabel_max_iter: 100,
            clarabel_tol: 1e-10,
            kkt_tol: 1e-7,
            slack_penalty: 1e8,
            relaxed_row_tol: 1e-6,
        }
    }
}

impl QpSettings {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), QpSetupError> {
        let positive_small = |field: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 && v < 1.0 {
                Ok(())
            } else {
                Err(QpSetupError::Setting {
                    field,
                    reason: "must be in (0, 1)",
                })
            }
        };
        positive_small("feasibility_tol", self.feasibility_tol)?;
        positive_small("dependence_tol", self.dependence_tol)?;
        positive_small("kkt_tol", self.kkt_tol)?;
        positive_small("clarabel_tol", self.clarabel_tol)?;
        if !(self.relaxed_row_tol.is_finite() && self.relaxed_row_tol >= 0.0) {
            return Err(QpSetupError::Setting {
                field: "relaxed_row_tol",
                reason: "must be finite and ≥ 0",
            });
        }
        if !(1.0..=1e12).contains(&self.slack_penalty) {
            return Err(QpSetupError::Setting {
                field: "slack_penalty",
                reason: "must be in [1, 1e12]",
            });
        }
        if self.max_iterations == 0 {
            return Err(QpSetupError::Setting {
                field: "max_iterations",
                reason: "must be ≥ 1",
            });
        }
        if self.clarabel_max_iter == 0 {
            return Err(QpSetupError::Setting {
                field: "clarabel_max_iter",
                reason: "must be ≥ 1",
            });
        }
        Ok(())
    }
}

/// Why a [`SafetyQp`](super::SafetyQp) could not be built.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum QpSetupError {
    /// A settings field is out of range.
    Setting {
        /// Field name in [`QpSettings`].
        field: &'static str,
        /// Accepted range.
        reason: &'static str,
    },
    /// `n = 0`: nothing to filter.
    NoInputs,
    /// Clarabel rejected the problem structure.
    Clarabel,
}

impl fmt::Display for QpSetupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Setting { field, reason } => write!(f, "QpSettings.{field} {reason}"),
            Self::NoInputs => write!(f, "the safety QP needs at least one input (n = 0)"),
            Self::Clarabel => write!(f, "clarabel rejected the safety QP structure"),
        }
    }
}

impl std::error::Error for QpSetupError {}
