//! The stacked least-squares problem of identification, held as QR-reduced blocks: rows
//! `[a | y]` of one group (static or dynamic rows of one module) in one block of time are
//! reduced to the triangular `R̃` of their QR factorization (faer), so that refits with
//! weights, parameters held at the file's values, tied gains and delete-one-block
//! jackknife refits all work on a few small matrices instead of the rows.
//!
//! `‖A θ − y‖² = ‖R̃ [θ; −1]‖²` for any `θ`, since `[A y] = Q R̃` with orthonormal `Q`.

use faer::Mat;
use faer::linalg::solvers::SolveLstsq;

/// Rows buffered before they are reduced.
const CHUNK_ROWS: usize = 512;

/// Rows of one group in one block, reduced.
#[derive(Clone, Debug)]
pub struct Reduced {
    /// `R̃`: at most `columns.len()` rows, one column per entry of `columns`.
    pub r: Mat<f64>,
    /// The parameter (or, last, the right-hand side) of each column of `r`, increasing: a
    /// group's rows are zero in every other parameter's column (another module's), which
    /// is left out of the factorization.
    pub columns: Vec<usize>,
    /// Rows reduced into it.
    pub rows: usize,
    /// Sum of the rows of each coordinate of a module (Δx, Δy, δL), all columns of the
    /// full row (parameters, then the right-hand side).
    pub sums: [Vec<f64>; 3],
    /// Number of rows of each coordinate.
    pub counts: [usize; 3],
}

/// Collects rows `[a | y]` and reduces them as they come, keeping only the columns it was
/// made for.
#[derive(Clone, Debug)]
pub struct Accumulator {
    /// The kept columns of the full row, increasing.
    columns: Vec<usize>,
    buffer: Mat<f64>,
    filled: usize,
    rows: usize,
    sums: [Vec<f64>; 3],
    counts: [usize; 3],
}

impl Accumulator {
    /// An accumulator of rows of `width` values (parameters and right-hand side).
    #[cfg(test)]
    pub fn new(width: usize) -> Accumulator {
        Accumulator::of_columns(width, (0..width).collect())
    }

    /// An accumulator of rows of `width` values that are zero outside `columns`
    /// (increasing, each below `width`); only those are reduced.
    pub fn of_columns(width: usize, columns: Vec<usize>) -> Accumulator {
        debug_assert!(columns.windows(2).all(|w| w[0] < w[1]));
        debug_assert!(columns.iter().all(|&c| c < width));
        let kept = columns.len();
        Accumulator {
            columns,
            buffer: Mat::zeros(CHUNK_ROWS + kept, kept),
            filled: 0,
            rows: 0,
            sums: std::array::from_fn(|_| vec![0.0; width]),
            counts: [0; 3],
        }
    }

    /// Adds one row of coordinate `coordinate` (0, 1, 2: Δx, Δy, δL of its module): the
    /// full row, `width` values, zero outside the accumulator's columns.
    pub fn push(&mut self, row: &[f64], coordinate: usize) {
        if self.filled == self.buffer.nrows() {
            self.reduce();
        }
        let sums = &mut self.sums[coordinate % 3];
        for (c, &k) in self.columns.iter().enumerate() {
            let value = row[k];
            self.buffer[(self.filled, c)] = value;
            sums[k] += value;
        }
        self.filled += 1;
        self.rows += 1;
        self.counts[coordinate % 3] += 1;
    }

    /// Adds one row already in the accumulator's columns (`columns.len()` values); it
    /// counts as a row of coordinate 0.
    fn push_kept(&mut self, row: impl Iterator<Item = f64>) {
        if self.filled == self.buffer.nrows() {
            self.reduce();
        }
        for (c, value) in row.enumerate() {
            self.buffer[(self.filled, c)] = value;
        }
        self.filled += 1;
        self.rows += 1;
    }

    /// Replaces the buffered rows by their `R̃`.
    fn reduce(&mut self) {
        if self.filled <= self.columns.len() {
            return;
        }
        let qr = self.buffer.get(..self.filled, ..).qr();
        let r = qr.thin_R();
        let k = r.nrows();
        for j in 0..self.columns.len() {
            for i in 0..k {
                self.buffer[(i, j)] = if i <= j { r[(i, j)] } else { 0.0 };
            }
        }
        self.filled = k;
    }

    /// The reduced rows (`None` when no row was pushed).
    pub fn finish(mut self) -> Option<Reduced> {
        if self.rows == 0 {
            return None;
        }
        self.reduce();
        Some(Reduced {
            r: self.buffer.get(..self.filled, ..).to_owned(),
            columns: self.columns,
            rows: self.rows,
            sums: self.sums,
            counts: self.counts,
        })
    }
}

impl Reduced {
    /// Two reductions of rows of the same group (the same columns) as one.
    pub fn merge(self, other: Reduced) -> Reduced {
        debug_assert_eq!(self.columns, other.columns);
        let width = self.sums[0].len();
        let mut accumulator = Accumulator::of_columns(width, self.columns.clone());
        for part in [&self, &other] {
            for i in 0..part.r.nrows() {
                accumulator.push_kept((0..part.r.ncols()).map(|j| part.r[(i, j)]));
            }
        }
        accumulator.reduce();
        let mut sums = self.sums;
        for (sum, other) in sums.iter_mut().zip(&other.sums) {
            for (a, b) in sum.iter_mut().zip(other) {
                *a += b;
            }
        }
        let counts = std::array::from_fn(|c| self.counts[c] + other.counts[c]);
        Reduced {
            r: accumulator.buffer.get(..accumulator.filled, ..).to_owned(),
            columns: self.columns,
            rows: self.rows + other.rows,
            sums,
            counts,
        }
    }

    /// The column of `r` holding parameter `j`, if kept.
    fn column_of(&self, j: usize) -> Option<usize> {
        self.columns.binary_search(&j).ok()
    }

    /// `‖A θ − y‖²` of these rows (`theta` has one value per parameter).
    pub fn residual_squares(&self, theta: &[f64]) -> f64 {
        let Some((&last, parameters)) = self.columns.split_last() else {
            return 0.0;
        };
        debug_assert_eq!(last, theta.len());
        let y = parameters.len();
        (0..self.r.nrows())
            .map(|i| {
                let v: f64 = parameters
                    .iter()
                    .enumerate()
                    .map(|(c, &j)| self.r[(i, c)] * theta[j])
                    .sum::<f64>()
                    - self.r[(i, y)];
                v * v
            })
            .sum()
    }

    /// `Σ s²` over the rows of `s = a_S · θ_S`, the part of each row the parameters
    /// `columns` explain (for the sum of squares of the tendon forces).
    pub fn explained_squares(&self, theta: &[f64], columns: &[usize]) -> f64 {
        let kept: Vec<(usize, usize)> = columns
            .iter()
            .filter_map(|&j| self.column_of(j).map(|c| (c, j)))
            .collect();
        (0..self.r.nrows())
            .map(|i| {
                let v: f64 = kept.iter().map(|&(c, j)| self.r[(i, c)] * theta[j]).sum();
                v * v
            })
            .sum()
    }
}

/// Which values are unknown: each unknown is one value shared by a set of parameters (a
/// single parameter, or a module's three tied gains); every other parameter is held at a
/// given value.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// Parameters sharing each unknown.
    pub unknowns: Vec<Vec<usize>>,
    /// Held parameters and their values.
    pub held: Vec<(usize, f64)>,
}

impl Config {
    /// The full parameter vector of `p` entries for unknowns `x`.
    pub fn theta(&self, x: &[f64], p: usize) -> Vec<f64> {
        let mut theta = vec![0.0; p];
        for &(j, value) in &self.held {
            theta[j] = value;
        }
        for (members, &value) in self.unknowns.iter().zip(x) {
            for &j in members {
                theta[j] = value;
            }
        }
        theta
    }
}

/// One reduced block's rows in the unknowns of `config`: `[X | z]` with `X` the summed
/// columns of each unknown and `z = y − A θ_held`, scaled by `weight`.
fn project(reduced: &Reduced, config: &Config, weight: f64, out: &mut Vec<Vec<f64>>) {
    let Some((_, parameters)) = reduced.columns.split_last() else {
        return;
    };
    let y = parameters.len();
    // Per kept column: its unknown, or its held value (a column in neither multiplies a
    // parameter of no unknown: none, as every parameter is one or the other).
    let mut unknown_of: Vec<Option<usize>> = vec![None; parameters.len()];
    let mut held_of: Vec<Option<f64>> = vec![None; parameters.len()];
    for (u, members) in config.unknowns.iter().enumerate() {
        for &j in members {
            if let Some(c) = reduced.column_of(j) {
                unknown_of[c] = Some(u);
            }
        }
    }
    for &(j, value) in &config.held {
        if let Some(c) = reduced.column_of(j) {
            held_of[c] = Some(value);
        }
    }
    for i in 0..reduced.r.nrows() {
        let mut row = vec![0.0; config.unknowns.len() + 1];
        let mut held = 0.0;
        for c in 0..parameters.len() {
            let r = reduced.r[(i, c)];
            if let Some(u) = unknown_of[c] {
                row[u] += r;
            } else if let Some(value) = held_of[c] {
                held += r * value;
            }
        }
        for value in row.iter_mut() {
            *value *= weight;
        }
        row[config.unknowns.len()] = weight * (reduced.r[(i, y)] - held);
        out.push(row);
    }
}

/// The stacked projected rows of `parts` (each a reduction and its weight).
pub fn stack<'a>(
    parts: impl Iterator<Item = (&'a Reduced, f64)>,
    config: &Config,
) -> Vec<Vec<f64>> {
    let mut rows = Vec::new();
    for (reduced, weight) in parts {
        project(reduced, config, weight, &mut rows);
    }
    rows
}

/// Least squares `X x ≈ z` of stacked rows `[X | z]` (columns scaled to unit norm for the
/// factorization): `None` when there are fewer rows than unknowns, a zero column or a
/// non-finite result.
pub fn solve(rows: &[Vec<f64>]) -> Option<Vec<f64>> {
    let n = rows.first()?.len() - 1;
    if n == 0 {
        return Some(Vec::new());
    }
    if rows.len() < n {
        return None;
    }
    let norms: Vec<f64> = (0..n)
        .map(|j| rows.iter().map(|r| r[j] * r[j]).sum::<f64>().sqrt())
        .collect();
    if norms.iter().any(|&c| !(c > 0.0 && c.is_finite())) {
        return None;
    }
    let a = Mat::from_fn(rows.len(), n, |i, j| rows[i][j] / norms[j]);
    let mut z = Mat::from_fn(rows.len(), 1, |i, _| rows[i][n]);
    a.qr().solve_lstsq_in_place(&mut z);
    let x: Vec<f64> = (0..n).map(|j| z[(j, 0)] / norms[j]).collect();
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Singular values (largest first) and right singular vectors (as columns, in the scaled
/// coordinates) of `X` with its columns scaled to unit norm, and the column norms.
pub struct Spectrum {
    /// Singular values, non-increasing.
    pub values: Vec<f64>,
    /// `v[k][j]`: component `j` of the `k`-th right singular vector.
    pub vectors: Vec<Vec<f64>>,
    /// Norms of the columns of `X` before scaling.
    pub norms: Vec<f64>,
}

/// The spectrum of the unknowns' columns of stacked rows `[X | z]` (zero columns keep
/// scale 1); `None` if the SVD fails.
pub fn spectrum(rows: &[Vec<f64>]) -> Option<Spectrum> {
    let n = rows.first()?.len() - 1;
    let norms: Vec<f64> = (0..n)
        .map(|j| rows.iter().map(|r| r[j] * r[j]).sum::<f64>().sqrt())
        .collect();
    if n == 0 {
        return Some(Spectrum {
            values: Vec::new(),
            vectors: Vec::new(),
            norms,
        });
    }
    let m = rows.len().max(n);
    let a = Mat::from_fn(m, n, |i, j| {
        let scale = if norms[j] > 0.0 { norms[j] } else { 1.0 };
        rows.get(i).map_or(0.0, |r| r[j] / scale)
    });
    let svd = a.thin_svd().ok()?;
    let s = svd.S().column_vector();
    let v = svd.V();
    let values: Vec<f64> = (0..n).map(|k| s[k]).collect();
    let vectors = (0..n)
        .map(|k| (0..n).map(|j| v[(j, k)]).collect())
        .collect();
    Some(Spectrum {
        values,
        vectors,
        norms,
    })
}

/// `R` of the QR factorization of stacked rows `[X | z]` with unit-norm columns, for the
/// textbook covariance `σ² (XᵀX)⁻¹`: its diagonal, unscaled to the unknowns' units.
pub fn textbook_variances(rows: &[Vec<f64>]) -> Option<Vec<f64>> {
    let n = rows.first()?.len() - 1;
    if rows.len() <= n || n == 0 {
        return None;
    }
    let norms: Vec<f64> = (0..n)
        .map(|j| rows.iter().map(|r| r[j] * r[j]).sum::<f64>().sqrt())
        .collect();
    if norms.iter().any(|&c| c.is_nan() || c <= 0.0) {
        return None;
    }
    let a = Mat::from_fn(rows.len(), n, |i, j| rows[i][j] / norms[j]);
    let qr = a.qr();
    let r = qr.thin_R();
    // (RᵀR)⁻¹ = R⁻¹ R⁻ᵀ: its diagonal is the squared row norms of R⁻¹.
    let mut inverse = Mat::<f64>::identity(n, n);
    r.get(..n, ..n)
        .solve_upper_triangular_in_place(inverse.as_mut());
    Some(
        (0..n)
            .map(|i| {
                let row: f64 = (0..n).map(|j| inverse[(i, j)].powi(2)).sum();
                row / (norms[i] * norms[i])
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows `[a | y]` of `y = 2 a₀ − 3 a₁ + 0.5` with `a₂ = 1` (three unknowns).
    fn rows(n: usize) -> Vec<Vec<f64>> {
        (0..n)
            .map(|i| {
                let (a0, a1) = ((i as f64 * 0.37).sin(), (i as f64 * 0.11).cos() * 3.0);
                vec![a0, a1, 1.0, 2.0 * a0 - 3.0 * a1 + 0.5]
            })
            .collect()
    }

    #[test]
    fn reduced_blocks_give_the_least_squares_of_all_rows() {
        let all = rows(2000);
        let mut accumulator = Accumulator::new(4);
        let mut second = Accumulator::new(4);
        for (i, row) in all.iter().enumerate() {
            // Residuals so that the fit is not exact.
            let mut row = row.clone();
            row[3] += if i % 2 == 0 { 0.01 } else { -0.01 };
            if i < 1300 {
                accumulator.push(&row, i % 3);
            } else {
                second.push(&row, i % 3);
            }
        }
        let reduced = accumulator
            .finish()
            .unwrap()
            .merge(second.finish().unwrap());
        assert_eq!(reduced.rows, 2000);
        assert!(reduced.r.nrows() <= 4);
        let config = Config {
            unknowns: vec![vec![0], vec![1], vec![2]],
            held: vec![],
        };
        let x = solve(&stack(std::iter::once((&reduced, 1.0)), &config)).unwrap();
        for (got, want) in x.iter().zip([2.0, -3.0, 0.5]) {
            assert!((got - want).abs() < 1e-3, "{x:?}");
        }
        // The residual of the alternating ±0.01 is 0.01 per row, whatever the fit.
        let theta = config.theta(&x, 3);
        let rms = (reduced.residual_squares(&theta) / 2000.0).sqrt();
        assert!((rms - 0.01).abs() < 1e-4, "{rms}");
        // Holding a₁'s parameter at its true value and tying nothing changes nothing.
        let held = Config {
            unknowns: vec![vec![0], vec![2]],
            held: vec![(1, -3.0)],
        };
        let x = solve(&stack(std::iter::once((&reduced, 1.0)), &held)).unwrap();
        assert!((x[0] - 2.0).abs() < 1e-3 && (x[1] - 0.5).abs() < 1e-3);
    }

    #[test]
    fn rows_reduced_in_their_nonzero_columns_give_what_all_columns_give() {
        // Rows of width 6 whose parameters 0, 2, 4 are always zero (another module's):
        // reduced in columns 1, 3 and the right-hand side 5, against all six.
        let mut kept = Accumulator::of_columns(6, vec![1, 3, 5]);
        let mut all = Accumulator::new(6);
        for i in 0..1500 {
            let (a, b) = ((i as f64 * 0.37).sin(), (i as f64 * 0.11).cos());
            let noise = if i % 2 == 0 { 0.01 } else { -0.01 };
            let row = [0.0, a, 0.0, b, 0.0, 1.5 * a - 0.5 * b + noise];
            kept.push(&row, i % 3);
            all.push(&row, i % 3);
        }
        let (kept, all) = (kept.finish().unwrap(), all.finish().unwrap());
        assert_eq!(kept.r.ncols(), 3);
        assert_eq!((kept.rows, kept.counts), (all.rows, all.counts));
        assert_eq!(kept.sums, all.sums);
        // The other parameters held (at any value: their columns are zero).
        let config = Config {
            unknowns: vec![vec![1], vec![3]],
            held: vec![(0, 7.0), (2, -1.0), (4, 0.3)],
        };
        let x = solve(&stack(std::iter::once((&kept, 1.0)), &config)).unwrap();
        let y = solve(&stack(std::iter::once((&all, 1.0)), &config)).unwrap();
        for (a, b) in x.iter().zip(&y) {
            assert!((a - b).abs() < 1e-12 * b.abs(), "{x:?} {y:?}");
        }
        let theta = config.theta(&x, 5);
        let (rk, ra) = (kept.residual_squares(&theta), all.residual_squares(&theta));
        assert!((rk - ra).abs() < 1e-12 * ra, "{rk} {ra}");
        let (ek, ea) = (
            kept.explained_squares(&theta, &[1, 2]),
            all.explained_squares(&theta, &[1, 2]),
        );
        assert!((ek - ea).abs() < 1e-12 * ea, "{ek} {ea}");
        // Merged halves are the whole.
        let mut first = Accumulator::of_columns(6, vec![1, 3, 5]);
        let mut second = Accumulator::of_columns(6, vec![1, 3, 5]);
        for i in 0..1500 {
            let (a, b) = ((i as f64 * 0.37).sin(), (i as f64 * 0.11).cos());
            let noise = if i % 2 == 0 { 0.01 } else { -0.01 };
            let row = [0.0, a, 0.0, b, 0.0, 1.5 * a - 0.5 * b + noise];
            if i < 700 {
                first.push(&row, i % 3);
            } else {
                second.push(&row, i % 3);
            }
        }
        let merged = first.finish().unwrap().merge(second.finish().unwrap());
        assert_eq!(merged.rows, 1500);
        let z = solve(&stack(std::iter::once((&merged, 1.0)), &config)).unwrap();
        for (a, b) in z.iter().zip(&y) {
            assert!((a - b).abs() < 1e-12 * b.abs(), "{z:?} {y:?}");
        }
    }

    #[test]
    fn a_zero_column_is_found_by_its_norm_and_a_dependent_pair_by_the_spectrum() {
        let rows: Vec<Vec<f64>> = (0..50)
            .map(|i| {
                let a = (i as f64).sin();
                vec![a, 2.0 * a, 0.0, a]
            })
            .collect();
        let s = spectrum(&rows).unwrap();
        assert_eq!(s.norms[2], 0.0);
        assert!(s.values[1] < 1e-12 * s.values[0], "{:?}", s.values);
        assert!(solve(&rows).is_none());
    }
}
