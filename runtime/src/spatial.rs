//! Spatial (6-D) vector algebra in Featherstone's convention: motion vectors `(ω, v)` and
//! force vectors `(n, f)` in one body frame, with transforms and inertias kept compact.
//!
//! A [`Transform`] is stored as the child's pose `(R, t)` in its parent, not as a 6×6
//! matrix, and a rigid-body [`Inertia`] as mass, first moment and rotational inertia: each
//! operation below costs tens of flops instead of the 36–432 of the dense forms.

/// A spatial motion or force vector.
pub type Vec6 = [f64; 6];
/// A 3-vector.
pub type Vec3 = [f64; 3];
/// A 3×3 matrix, rows.
pub type Mat3 = [[f64; 3]; 3];

/// `a × b`.
#[inline]
pub fn cross3(a: &Vec3, b: &Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
fn mat_vec3(m: &Mat3, v: &Vec3) -> Vec3 {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

#[inline]
fn mat_t_vec3(m: &Mat3, v: &Vec3) -> Vec3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

#[inline]
fn split(x: &Vec6) -> (Vec3, Vec3) {
    ([x[0], x[1], x[2]], [x[3], x[4], x[5]])
}

#[inline]
fn join(a: Vec3, b: Vec3) -> Vec6 {
    [a[0], a[1], a[2], b[0], b[1], b[2]]
}

/// The transform from a parent frame to a child frame whose pose in the parent is
/// `(rotation, translation)` (the child's axes and origin in parent coordinates). As a
/// motion transform it is `X = [Rᵀ 0; −Rᵀ[t]× Rᵀ]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Transform {
    /// `R`: the child's axes as columns, in parent coordinates.
    pub rotation: Mat3,
    /// `t`: the child's origin in parent coordinates.
    pub translation: Vec3,
}

impl Transform {
    /// `X m`: a motion vector of the parent frame in child coordinates,
    /// `(Rᵀ ω, Rᵀ (v − t × ω))`.
    #[inline]
    pub fn motion_to_child(&self, m: &Vec6) -> Vec6 {
        let (w, v) = split(m);
        let tw = cross3(&self.translation, &w);
        let moved = [v[0] - tw[0], v[1] - tw[1], v[2] - tw[2]];
        join(
            mat_t_vec3(&self.rotation, &w),
            mat_t_vec3(&self.rotation, &moved),
        )
    }

    /// `Xᵀ f`: a force vector of the child frame in parent coordinates,
    /// `(R n + t × R f, R f)`.
    #[inline]
    pub fn force_to_parent(&self, f: &Vec6) -> Vec6 {
        let (n, lin) = split(f);
        let rf = mat_vec3(&self.rotation, &lin);
        let rn = mat_vec3(&self.rotation, &n);
        let moment = cross3(&self.translation, &rf);
        join(
            [rn[0] + moment[0], rn[1] + moment[1], rn[2] + moment[2]],
            rf,
        )
    }
}

/// A rigid-body inertia about a frame's origin, in that frame's coordinates: as a 6×6
/// matrix `[[Ī, [h]×], [[h]×ᵀ, m 1]]` with `h = m c` (`c` the centre of mass).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inertia {
    /// `m` \[kg\].
    pub mass: f64,
    /// `h = m c` \[kg·m\].
    pub first_moment: Vec3,
    /// `Ī`: rotational inertia about the origin \[kg·m²\] (symmetric).
    pub rotational: Mat3,
}

impl Inertia {
    /// A body of `mass` with its centre of mass at `com` and rotational inertia
    /// `inertia` about the centre of mass (parallel-axis theorem).
    pub fn rigid_body(mass: f64, com: &Vec3, inertia: &Mat3) -> Inertia {
        let c = com;
        let c2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
        let mut rotational = *inertia;
        for (r, row) in rotational.iter_mut().enumerate() {
            for (k, entry) in row.iter_mut().enumerate() {
                // I_c + m (|c|² 1 − c cᵀ) = I_c + m [c]× [c]×ᵀ
                let identity = if r == k { c2 } else { 0.0 };
                *entry += mass * (identity - c[r] * c[k]);
            }
        }
        Inertia {
            mass,
            first_moment: [mass * c[0], mass * c[1], mass * c[2]],
            rotational,
        }
    }

    /// `I m`: the momentum (a force vector) of motion `m`, `(Ī ω + h × v, m v − h × ω)`.
    #[inline]
    pub fn apply(&self, m: &Vec6) -> Vec6 {
        let (w, v) = split(m);
        let h = &self.first_moment;
        let iw = mat_vec3(&self.rotational, &w);
        let hv = cross3(h, &v);
        let hw = cross3(h, &w);
        join(
            [iw[0] + hv[0], iw[1] + hv[1], iw[2] + hv[2]],
            [
                self.mass * v[0] - hw[0],
                self.mass * v[1] - hw[1],
                self.mass * v[2] - hw[2],
            ],
        )
    }

    /// Adds another inertia expressed in the same frame.
    #[inline]
    pub fn add(&mut self, other: &Inertia) {
        self.mass += other.mass;
        for k in 0..3 {
            self.first_moment[k] += other.first_moment[k];
            for c in 0..3 {
                self.rotational[k][c] += other.rotational[k][c];
            }
        }
    }

    /// `Xᵀ I X`: this inertia, given in the child frame of `x`, in the parent frame:
    /// `h' = R h + m t`, `Ī' = R Ī Rᵀ − [t]×[R h]× − [h']×[t]×`.
    pub fn to_parent(&self, x: &Transform) -> Inertia {
        let (r, t, m) = (&x.rotation, &x.translation, self.mass);
        let rh = mat_vec3(r, &self.first_moment);
        let h = [rh[0] + m * t[0], rh[1] + m * t[1], rh[2] + m * t[2]];
        // R Ī Rᵀ
        let mut ri = [[0.0; 3]; 3];
        for (a, row) in ri.iter_mut().enumerate() {
            for (b, entry) in row.iter_mut().enumerate() {
                *entry = (0..3).map(|k| r[a][k] * self.rotational[k][b]).sum();
            }
        }
        let mut rotational = [[0.0; 3]; 3];
        for (a, row) in rotational.iter_mut().enumerate() {
            for (b, entry) in row.iter_mut().enumerate() {
                *entry = (0..3).map(|k| ri[a][k] * r[b][k]).sum();
            }
        }
        // [x]×[y]× = y xᵀ − (x·y) 1.
        let t_rh = t[0] * rh[0] + t[1] * rh[1] + t[2] * rh[2];
        let h_t = h[0] * t[0] + h[1] * t[1] + h[2] * t[2];
        for a in 0..3 {
            for b in 0..3 {
                let identity = if a == b { t_rh + h_t } else { 0.0 };
                rotational[a][b] -= rh[a] * t[b] + t[a] * h[b] - identity;
            }
        }
        Inertia {
            mass: m,
            first_moment: h,
            rotational,
        }
    }
}

/// `a ×ₘ b`: motion cross product (the derivative of `b` in a frame moving with `a`).
#[inline]
pub fn cross_motion(a: &Vec6, b: &Vec6) -> Vec6 {
    let ((w, v), (bw, bv)) = (split(a), split(b));
    let top = cross3(&w, &bw);
    let wv = cross3(&w, &bv);
    let vw = cross3(&v, &bw);
    join(top, [wv[0] + vw[0], wv[1] + vw[1], wv[2] + vw[2]])
}

/// `a ×* f`: force cross product.
#[inline]
pub fn cross_force(a: &Vec6, f: &Vec6) -> Vec6 {
    let ((w, v), (n, lin)) = (split(a), split(f));
    let wn = cross3(&w, &n);
    let vf = cross3(&v, &lin);
    let wf = cross3(&w, &lin);
    join([wn[0] + vf[0], wn[1] + vf[1], wn[2] + vf[2]], wf)
}

#[cfg(test)]
mod tests {
    use super::*;

    type Mat6 = [[f64; 6]; 6];

    /// The dense motion transform `[Rᵀ 0; −Rᵀ[t]× Rᵀ]`, written out as in RBDA.
    fn dense_transform(x: &Transform) -> Mat6 {
        let (r, t) = (&x.rotation, &x.translation);
        let tx = [[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]];
        let mut out = [[0.0; 6]; 6];
        for a in 0..3 {
            for b in 0..3 {
                out[a][b] = r[b][a];
                out[3 + a][3 + b] = r[b][a];
                out[3 + a][b] = -(0..3).map(|k| r[k][a] * tx[k][b]).sum::<f64>();
            }
        }
        out
    }

    fn dense_inertia(i: &Inertia) -> Mat6 {
        let h = &i.first_moment;
        let hx = [[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]];
        let mut out = [[0.0; 6]; 6];
        for a in 0..3 {
            for b in 0..3 {
                out[a][b] = i.rotational[a][b];
                out[a][3 + b] = hx[a][b];
                out[3 + a][b] = hx[b][a];
            }
            out[3 + a][3 + a] = i.mass;
        }
        out
    }

    fn mul(a: &Mat6, b: &Mat6) -> Mat6 {
        let mut out = [[0.0; 6]; 6];
        for r in 0..6 {
            for c in 0..6 {
                out[r][c] = (0..6).map(|k| a[r][k] * b[k][c]).sum();
            }
        }
        out
    }

    fn transpose(a: &Mat6) -> Mat6 {
        let mut out = [[0.0; 6]; 6];
        for r in 0..6 {
            for c in 0..6 {
                out[r][c] = a[c][r];
            }
        }
        out
    }

    fn times(a: &Mat6, v: &Vec6) -> Vec6 {
        std::array::from_fn(|r| (0..6).map(|k| a[r][k] * v[k]).sum())
    }

    /// A rotation about an unnormalized axis (Rodrigues) and an offset.
    fn sample_transform(seed: f64) -> Transform {
        let axis = [0.3 + seed, -0.7, 0.5 * seed];
        let norm = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
        let k = axis.map(|a| a / norm);
        let angle = 0.4 + 2.0 * seed;
        let (s, c) = angle.sin_cos();
        let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
        let mut rotation = [[0.0; 3]; 3];
        for a in 0..3 {
            for b in 0..3 {
                let kk: f64 = (0..3).map(|j| kx[a][j] * kx[j][b]).sum();
                rotation[a][b] = f64::from(u8::from(a == b)) + s * kx[a][b] + (1.0 - c) * kk;
            }
        }
        Transform {
            rotation,
            translation: [0.02 - seed, 0.05, 0.11 * seed],
        }
    }

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() < 1e-13 * (1.0 + y.abs()))
    }

    #[test]
    fn compact_operations_match_dense_matrices() {
        let body = Inertia::rigid_body(
            0.7,
            &[0.01, -0.02, 0.03],
            &[
                [0.02, 0.001, 0.0],
                [0.001, 0.03, -0.002],
                [0.0, -0.002, 0.04],
            ],
        );
        let m: Vec6 = [0.3, -1.2, 0.7, 2.0, 0.1, -0.4];
        for seed in [0.0, 0.3, 0.9] {
            let x = sample_transform(seed);
            let dx = dense_transform(&x);
            assert!(close(&x.motion_to_child(&m), &times(&dx, &m)));
            assert!(close(&x.force_to_parent(&m), &times(&transpose(&dx), &m)));
            let moved = dense_inertia(&body.to_parent(&x));
            let expected = mul(&transpose(&dx), &mul(&dense_inertia(&body), &dx));
            for (a, b) in moved.iter().zip(&expected) {
                assert!(close(a, b), "{a:?} vs {b:?}");
            }
        }
        assert!(close(&body.apply(&m), &times(&dense_inertia(&body), &m)));
    }

    #[test]
    fn parallel_axis_theorem() {
        // A point mass 2 kg at (0, 0, 0.5): Ī = diag(0.5, 0.5, 0), h = (0, 0, 1).
        let i = Inertia::rigid_body(2.0, &[0.0, 0.0, 0.5], &[[0.0; 3]; 3]);
        assert_eq!(i.first_moment, [0.0, 0.0, 1.0]);
        assert_eq!(
            i.rotational,
            [[0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.0]]
        );
    }
}
