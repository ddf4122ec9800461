//! Small dense factorizations used by the W-matrix solvers, on preallocated row-major slices.
//! Cholesky for symmetric positive definite matrices, LU with partial pivoting otherwise.

/// Cholesky factorization `A = L Lᵀ` in place (row-major `n×n`, only the lower triangle is
/// read; `L` is written to the lower triangle). Returns `false` if `A` is not (numerically)
/// positive definite or holds a non-finite entry.
pub(crate) fn cholesky_in_place(a: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let ljj = d.sqrt();
        a[j * n + j] = ljj;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / ljj;
        }
    }
    true
}

/// Solves `L Lᵀ y = b` in place with the factor from [`cholesky_in_place`].
pub(crate) fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * n + k] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[k * n + i] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
}

/// LU factorization with partial pivoting in place (row-major `n×n`): `P A = L U`, unit
/// lower `L` below the diagonal, `U` on and above it, row `i` of `P A` is row `piv[i]` of
/// `A`. Returns `false` on an exactly zero or non-finite pivot.
pub(crate) fn lu_in_place(a: &mut [f64], n: usize, piv: &mut [usize]) -> bool {
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
pub(crate) fn lu_solve(lu: &[f64], n: usize, piv: &[usize], b: &mut [f64], tmp: &mut [f64]) {
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
        let mut not_spd = [1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_in_place(&mut not_spd, 2));
        let mut singular = [1.0, 2.0, 2.0, 4.0];
        assert!(!lu_in_place(&mut singular, 2, &mut piv[..2]));
    }
}
