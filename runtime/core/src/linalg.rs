//! Small dense factorizations on preallocated row-major slices, for the mass matrix and the
//! integrators' W matrices: Cholesky for symmetric positive definite, LU with pivoting else.

/// `with_const_size!(n, [sizes…], |n| kernel(…, n))` calls the closure with `n` a
/// compile-time constant when it is one of `sizes`, so that the kernel's loops over `n`
/// unroll and vectorize without per-row bookkeeping; any other `n` runs the same code with
/// `n` at run time. The arithmetic is the same either way. The sizes used are those of the
/// robots of one to four three-coordinate modules (`nq` = 3, 6, 9, 12; states of `2 nq`).
macro_rules! with_const_size {
    ($n:expr, [$($size:literal),*], $kernel:expr) => {
        match $n {
            $($size => ($kernel)($size),)*
            n => ($kernel)(n),
        }
    };
}
pub(crate) use with_const_size;

/// `aᵀ b` over the common length of `a` and `b`: the one dot product of the runtime.
#[inline]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Cholesky factorization `A = L Lᵀ` in place (row-major `n×n`, only the lower triangle is
/// read; `L` is written to the lower triangle, the strict upper triangle is left as it was).
/// Returns `false` if `A` is not (numerically) positive definite or holds a non-finite
/// entry. Rows are taken as slices, so the inner products run without index checks.
pub fn cholesky_in_place(a: &mut [f64], n: usize) -> bool {
    with_const_size!(n, [3, 6, 9, 12], |n| cholesky_in_place_sized(a, n))
}

#[inline(always)]
fn cholesky_in_place_sized(a: &mut [f64], n: usize) -> bool {
    let a = &mut a[..n * n];
    for j in 0..n {
        let (row_j, below) = a[j * n..].split_at_mut(n);
        let d = row_j[j] - dot(&row_j[..j], &row_j[..j]);
        // NaN is not finite, so it is rejected too.
        if !d.is_finite() || d <= 0.0 {
            return false;
        }
        let ljj = d.sqrt();
        row_j[j] = ljj;
        for row_i in below.chunks_exact_mut(n) {
            row_i[j] = (row_i[j] - dot(&row_i[..j], &row_j[..j])) / ljj;
        }
    }
    true
}

/// Solves `L Lᵀ y = b` in place with the factor from [`cholesky_in_place`].
pub fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    with_const_size!(n, [3, 6, 9, 12], |n| cholesky_solve_sized(l, b, n))
}

#[inline(always)]
fn cholesky_solve_sized(l: &[f64], b: &mut [f64], n: usize) {
    let (l, b) = (&l[..n * n], &mut b[..n]);
    for (i, row) in l.chunks_exact(n).enumerate() {
        b[i] = (b[i] - dot(&row[..i], &b[..i])) / row[i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[k * n + i] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
}

/// `A⁻¹` (row-major `n×n`, symmetric) from the factor of [`cholesky_in_place`]: the inverse
/// of `L` by forward substitution, then `A⁻¹ = L⁻ᵀ L⁻¹`. `work` is scratch of `n×n`.
pub fn cholesky_inverse(l: &[f64], n: usize, inverse: &mut [f64], work: &mut [f64]) {
    with_const_size!(n, [3, 6, 9, 12], |n| {
        cholesky_inverse_sized(l, inverse, work, n)
    })
}

#[inline(always)]
fn cholesky_inverse_sized(l: &[f64], inverse: &mut [f64], work: &mut [f64], n: usize) {
    let (l, inverse, work) = (&l[..n * n], &mut inverse[..n * n], &mut work[..n * n]);
    // work = L⁻¹ (lower triangular), column by column.
    work.fill(0.0);
    for c in 0..n {
        work[c * n + c] = 1.0 / l[c * n + c];
        for r in c + 1..n {
            let mut s = 0.0;
            for k in c..r {
                s -= l[r * n + k] * work[k * n + c];
            }
            work[r * n + c] = s / l[r * n + r];
        }
    }
    // inverse[a][b] = Σ_{k ≥ max(a, b)} L⁻¹[k][a] L⁻¹[k][b].
    for a in 0..n {
        for b in a..n {
            let mut s = 0.0;
            for k in b..n {
                s += work[k * n + a] * work[k * n + b];
            }
            inverse[a * n + b] = s;
            inverse[b * n + a] = s;
        }
    }
}

/// LU factorization with partial pivoting in place (row-major `n×n`): `P A = L U`, unit
/// lower `L` below the diagonal, `U` on and above it, row `i` of `P A` is row `piv[i]` of
/// `A`. Returns `false` on an exactly zero or non-finite pivot.
pub fn lu_in_place(a: &mut [f64], n: usize, piv: &mut [usize]) -> bool {
    for (i, p) in piv.iter_mut().enumerate().take(n) {
        *p = i;
    }
    for k in 0..n {
        let mut p = k;
        let mut best = a[k * n + k].abs();
        for i in k + 1..n {
            let v = a[i * n + k].abs();
            if v > best {
                best = v;
                p = i;
            }
        }
        if !(best > 0.0 && best.is_finite()) {
            return false;
        }
        if p != k {
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
            piv.swap(k, p);
        }
        let pivot = a[k * n + k];
        for i in k + 1..n {
            let l = a[i * n + k] / pivot;
            a[i * n + k] = l;
            if l != 0.0 {
                for j in k + 1..n {
                    a[i * n + j] -= l * a[k * n + j];
                }
            }
        }
    }
    true
}

/// Solves `A y = b` with the factor from [`lu_in_place`]; `tmp` is scratch of length `n`.
pub fn lu_solve(lu: &[f64], n: usize, piv: &[usize], b: &mut [f64], tmp: &mut [f64]) {
    for i in 0..n {
        tmp[i] = b[piv[i]];
    }
    for i in 0..n {
        let mut s = tmp[i];
        for k in 0..i {
            s -= lu[i * n + k] * tmp[k];
        }
        tmp[i] = s;
    }
    for i in (0..n).rev() {
        let mut s = tmp[i];
        for k in i + 1..n {
            s -= lu[i * n + k] * tmp[k];
        }
        tmp[i] = s / lu[i * n + i];
    }
    b[..n].copy_from_slice(&tmp[..n]);
}

/// `exp(A)` of a row-major `n×n` matrix by scaling and squaring with the diagonal (6, 6)
/// Padé approximant (Moler and Van Loan's method 3): `A` is scaled by `2⁻ˢ` until its
/// 1-norm is at most ½, where the approximant's relative error is below 1e-16, and the
/// result is squared `s` times. Preallocated for one size; allocates nothing per call.
pub struct MatrixExponential {
    n: usize,
    scaled: Vec<f64>,
    square: Vec<f64>,
    fourth: Vec<f64>,
    sixth: Vec<f64>,
    odd: Vec<f64>,
    even: Vec<f64>,
    pivots: Vec<usize>,
    column: Vec<f64>,
    tmp: Vec<f64>,
}

/// Coefficients `c_k` of the (6, 6) Padé approximant of `exp`:
/// `c_0 = 1`, `c_k = c_{k−1} (q − k + 1) / (k (2q − k + 1))` with `q = 6`.
const PADE_6: [f64; 7] = [
    1.0,
    0.5,
    5.0 / 44.0,
    1.0 / 66.0,
    1.0 / 792.0,
    1.0 / 15840.0,
    1.0 / 665280.0,
];

impl MatrixExponential {
    /// Workspace for `n×n` matrices.
    pub fn new(n: usize) -> MatrixExponential {
        let square = || vec![0.0; n * n];
        MatrixExponential {
            n,
            scaled: square(),
            square: square(),
            fourth: square(),
            sixth: square(),
            odd: square(),
            even: square(),
            pivots: vec![0; n],
            column: vec![0.0; n],
            tmp: vec![0.0; n],
        }
    }

    /// Writes `exp(a)` into `out` (both row-major `n×n`). Returns `false`, leaving `out`
    /// unspecified, when `a` has a non-finite entry, the sizes differ from the workspace's,
    /// or the Padé denominator is singular (it is not for a finite `a`).
    pub fn compute(&mut self, a: &[f64], out: &mut [f64]) -> bool {
        let n = self.n;
        if a.len() != n * n || out.len() != n * n || !a.iter().all(|v| v.is_finite()) {
            return false;
        }
        let norm = (0..n)
            .map(|c| (0..n).map(|r| a[r * n + c].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let squarings = if norm > 0.5 {
            (norm / 0.5).log2().ceil() as i32
        } else {
            0
        };
        let scale = 0.5_f64.powi(squarings);
        for (s, v) in self.scaled.iter_mut().zip(a) {
            *s = v * scale;
        }
        multiply(&self.scaled, &self.scaled, &mut self.square, n);
        multiply(&self.square, &self.square, &mut self.fourth, n);
        multiply(&self.fourth, &self.square, &mut self.sixth, n);
        let c = PADE_6;
        // even = c0 I + c2 X² + c4 X⁴ + c6 X⁶; tmp-matrix (in `out`) = c1 I + c3 X² + c5 X⁴.
        let powers = self.square.iter().zip(&self.fourth).zip(&self.sixth);
        for ((even, odd), ((x2, x4), x6)) in self.even.iter_mut().zip(out.iter_mut()).zip(powers) {
            *even = c[2] * x2 + c[4] * x4 + c[6] * x6;
            *odd = c[3] * x2 + c[5] * x4;
        }
        for i in 0..n {
            self.even[i * n + i] += c[0];
            out[i * n + i] += c[1];
        }
        multiply(&self.scaled, out, &mut self.odd, n);
        // Denominator V − U (LU in `square`), numerator V + U (in `fourth`).
        let parts = self.even.iter().zip(&self.odd);
        for ((denominator, numerator), (v, u)) in self
            .square
            .iter_mut()
            .zip(self.fourth.iter_mut())
            .zip(parts)
        {
            *denominator = v - u;
            *numerator = v + u;
        }
        if !lu_in_place(&mut self.square, n, &mut self.pivots) {
            return false;
        }
        for col in 0..n {
            for r in 0..n {
                self.column[r] = self.fourth[r * n + col];
            }
            lu_solve(
                &self.square,
                n,
                &self.pivots,
                &mut self.column,
                &mut self.tmp,
            );
            for r in 0..n {
                out[r * n + col] = self.column[r];
            }
        }
        for _ in 0..squarings {
            self.sixth.copy_from_slice(out);
            multiply(&self.sixth, &self.sixth, out, n);
        }
        out.iter().all(|v| v.is_finite())
    }
}

/// `c = a b` for row-major `n×n` matrices.
pub fn multiply(a: &[f64], b: &[f64], c: &mut [f64], n: usize) {
    c[..n * n].fill(0.0);
    for i in 0..n {
        for k in 0..n {
            let aik = a[i * n + k];
            if aik != 0.0 {
                let (row_b, row_c) = (&b[k * n..(k + 1) * n], &mut c[i * n..(i + 1) * n]);
                for (x, y) in row_c.iter_mut().zip(row_b) {
                    *x += aik * y;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factorizations_solve_a_known_system() {
        // A = B Bᵀ + I with B fixed: SPD; solution chosen, right side computed by product.
        let n = 4;
        let bm = [
            1.0, 2.0, 0.0, -1.0, 0.5, 1.0, 3.0, 0.0, -2.0, 0.0, 1.0, 1.0, 0.0, 1.0, -1.0, 2.0,
        ];
        let mut a = vec![0.0; 16];
        for i in 0..n {
            for j in 0..n {
                let mut s = if i == j { 1.0 } else { 0.0 };
                for k in 0..n {
                    s += bm[i * n + k] * bm[j * n + k];
                }
                a[i * n + j] = s;
            }
        }
        let y = [1.0, -2.0, 0.5, 3.0];
        let mut rhs = [0.0; 4];
        for i in 0..n {
            rhs[i] = (0..n).map(|j| a[i * n + j] * y[j]).sum();
        }
        let mut l = a.clone();
        assert!(cholesky_in_place(&mut l, n));
        let mut b1 = rhs;
        cholesky_solve(&l, n, &mut b1);
        let mut lu = bm.to_vec(); // non-symmetric, needs pivoting (zero at (1,1) after step)
        let mut piv = [0; 4];
        assert!(lu_in_place(&mut lu, n, &mut piv));
        let mut rb = [0.0; 4];
        for i in 0..n {
            rb[i] = (0..n).map(|j| bm[i * n + j] * y[j]).sum();
        }
        let mut tmp = [0.0; 4];
        lu_solve(&lu, n, &piv, &mut rb, &mut tmp);
        for i in 0..n {
            assert!((b1[i] - y[i]).abs() < 1e-12);
            assert!((rb[i] - y[i]).abs() < 1e-12);
        }
        let mut inverse = vec![0.0; 16];
        let mut work = vec![0.0; 16];
        cholesky_inverse(&l, n, &mut inverse, &mut work);
        for i in 0..n {
            for j in 0..n {
                let product: f64 = (0..n).map(|k| a[i * n + k] * inverse[k * n + j]).sum();
                let identity = if i == j { 1.0 } else { 0.0 };
                assert!((product - identity).abs() < 1e-12, "({i},{j}) {product}");
            }
        }
        let mut not_spd = [1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_in_place(&mut not_spd, 2));
        let mut singular = [1.0, 2.0, 2.0, 4.0];
        assert!(!lu_in_place(&mut singular, 2, &mut piv[..2]));
    }
}
