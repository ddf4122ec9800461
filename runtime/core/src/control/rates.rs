//! Rate limits of the predicted and certified rows (docs/model.md §5, "Rate limits").

use crate::hold::HoldPrediction;
use crate::linalg::dot;

/// Rate limits `|q̇_c| ≤ v̄_c` of some coordinates, kept at two samples of the hold (the one
/// nearest its middle and its end) as rows of the predicted and certified rows (after the
/// barriers' rows and the certified box): `v̄ − s q̇_c(t_j) ≥ min(v̄ − s q̇_c(0), 0) e^{−p t_j}`
/// for `s = ±1`, so that a rate already beyond its limit is brought back at the rate `p`
/// \[1/s\] rather than at once. They are a means of the filter, not part of the guarantee: a
/// coordinate moving fast in one hold leaves the next in a state no command can keep
/// (docs/model.md §5, "Rate limits").
pub(super) struct RateRows {
    /// `(coordinate, v̄ [m/s])`.
    pub limits: Vec<(usize, f64)>,
    /// The first row of the rate rows.
    pub start: usize,
    /// Their rate `p` \[1/s\].
    pub gain: f64,
}

/// Rows per limit: two signs at two samples.
pub(super) const RATE_ROWS_PER_LIMIT: usize = 4;

impl RateRows {
    /// The two samples (indices into `prediction`) the rates are kept at.
    pub(super) fn samples(prediction: &HoldPrediction) -> [usize; 2] {
        let last = prediction.samples() - 1;
        let half = 0.5 * prediction.time(last);
        let mid = (0..last)
            .find(|&j| prediction.time(j) >= half)
            .unwrap_or(last);
        [mid, last]
    }

    /// Writes the rows for the linear prediction: `q̇(t_j) = ȧ_j + Γ̇_j (τ − g₀)`, the rows
    /// linearized at `τ = g₀` (`offset`), whose motion has the free velocity `ȧ_j`.
    pub(super) fn write_linear(
        &self,
        prediction: &HoldPrediction,
        offset: &[f64],
        qd: &[f64],
        rows: &mut [f64],
        rhs: &mut [f64],
    ) {
        for (slot, &j) in Self::samples(prediction).iter().enumerate() {
            let free = prediction.free_velocity(j);
            self.write_at(prediction, slot, [qd, free], offset, rows, rhs);
        }
    }

    /// The first of limit `l`'s two rows at sample slot `slot`.
    fn first_row(&self, l: usize, slot: usize) -> usize {
        self.start + RATE_ROWS_PER_LIMIT * l + 2 * slot
    }

    /// Writes the rows of sample slot `slot` (0: middle, 1: end) linearized at the command
    /// `guess`, from `[q̇ at the tick, q̇ of guess's motion at the sample]` (`nq` each).
    pub(super) fn write_at(
        &self,
        prediction: &HoldPrediction,
        slot: usize,
        [qd, velocity]: [&[f64]; 2],
        guess: &[f64],
        rows: &mut [f64],
        rhs: &mut [f64],
    ) {
        let nq = guess.len();
        let j = Self::samples(prediction)[slot];
        let forced = prediction.forced_velocity(j);
        for (l, &(c, limit)) in self.limits.iter().enumerate() {
            let gamma = &forced[c * nq..(c + 1) * nq];
            let pair = RatePair {
                limit,
                start_rate: qd[c],
                t: prediction.time(j),
                rate: velocity[c],
            };
            self.write_pair(self.first_row(l, slot), &pair, gamma, guess, rows, rhs);
        }
    }

    /// `v̄ − s (v + γ·(τ − τ₀)) ≥ floor` for `s = ±1`: `−s γ·τ ≥ floor − v̄ + s v − s γ·τ₀`
    /// (rows `first` and `first + 1`), with `γ = ∂q̇_c(t_j)/∂τ` and `τ₀`
    /// (`about`) the command the rate `v` belongs to.
    fn write_pair(
        &self,
        first: usize,
        pair: &RatePair,
        gamma: &[f64],
        about: &[f64],
        rows: &mut [f64],
        rhs: &mut [f64],
    ) {
        let nq = about.len();
        let decay = (-self.gain * pair.t).exp();
        for (n, sign) in [1.0_f64, -1.0].into_iter().enumerate() {
            let r = first + n;
            let floor = (pair.limit - sign * pair.start_rate).min(0.0) * decay;
            let row = &mut rows[r * nq..(r + 1) * nq];
            for (a, g) in row.iter_mut().zip(gamma) {
                *a = -sign * g;
            }
            rhs[r] = floor - pair.limit + sign * pair.rate + dot(row, about);
        }
    }
}

/// One limit at one sample: its bound, the rate at the tick, the sample's time and the
/// rate predicted there.
struct RatePair {
    /// `v̄` \[m/s\].
    limit: f64,
    /// `q̇_c` at the tick \[m/s\].
    start_rate: f64,
    /// The sample's time in the hold \[s\].
    t: f64,
    /// `q̇_c(t_j)` for the command the row is linearized at \[m/s\].
    rate: f64,
}
