//! Spatial (6-D) vector algebra in Featherstone's convention: motion vectors are `(ω, v)`,
//! force vectors `(n, f)`, both in the coordinates of one body frame.

/// A spatial motion or force vector.
pub type Vec6 = [f64; 6];
/// A 6×6 matrix (spatial inertia or transform), rows.
pub type Mat6 = [[f64; 6]; 6];
/// A 3×3 matrix, rows.
pub type Mat3 = [[f64; 3]; 3];

/// `a × b` for 3-vectors.
pub fn cross3(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The motion transform from a parent frame to a child frame whose pose in the parent is
/// `(rotation, translation)`: `X = [Rᵀ 0; −Rᵀ[t]× Rᵀ]`.
pub fn motion_transform(rotation: &Mat3, translation: &[f64; 3]) -> Mat6 {
    let mut x = [[0.0; 6]; 6];
    let t = translation;
    // [t]× rows.
    let tx = [[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]];
    for r in 0..3 {
        for c in 0..3 {
            let rt = rotation[c][r];
            x[r][c] = rt;
            x[3 + r][3 + c] = rt;
            // (−Rᵀ[t]×)[r][c] = −Σ_k R[k][r] tx[k][c]
            x[3 + r][c] = -(0..3).map(|k| rotation[k][r] * tx[k][c]).sum::<f64>();
        }
    }
    x
}

/// `X m` (motion vector into the child frame).
pub fn apply(x: &Mat6, m: &Vec6) -> Vec6 {
    let mut out = [0.0; 6];
    for (o, row) in out.iter_mut().zip(x) {
        *o = row.iter().zip(m).map(|(a, b)| a * b).sum();
    }
    out
}

/// `Xᵀ f` (force vector from the child frame into the parent frame).
pub fn apply_transpose(x: &Mat6, f: &Vec6) -> Vec6 {
    let mut out = [0.0; 6];
    for (r, row) in x.iter().enumerate() {
        for (o, a) in out.iter_mut().zip(row) {
            *o += a * f[r];
        }
    }
    out
}

/// `a ×ₘ b`: motion cross product (the derivative of `b` in a frame moving with `a`).
pub fn cross_motion(a: &Vec6, b: &Vec6) -> Vec6 {
    let (w, v) = ([a[0], a[1], a[2]], [a[3], a[4], a[5]]);
    let (bw, bv) = ([b[0], b[1], b[2]], [b[3], b[4], b[5]]);
    let top = cross3(&w, &bw);
    let wv = cross3(&w, &bv);
    let vw = cross3(&v, &bw);
    [
        top[0],
        top[1],
        top[2],
        wv[0] + vw[0],
        wv[1] + vw[1],
        wv[2] + vw[2],
    ]
}

/// `a ×* f`: force cross product.
pub fn cross_force(a: &Vec6, f: &Vec6) -> Vec6 {
    let (w, v) = ([a[0], a[1], a[2]], [a[3], a[4], a[5]]);
    let (n, lin) = ([f[0], f[1], f[2]], [f[3], f[4], f[5]]);
    let wn = cross3(&w, &n);
    let vf = cross3(&v, &lin);
    let wf = cross3(&w, &lin);
    [
        wn[0] + vf[0],
        wn[1] + vf[1],
        wn[2] + vf[2],
        wf[0],
        wf[1],
        wf[2],
    ]
}

/// `A b` for a 6×6 matrix.
pub fn mat_vec(a: &Mat6, b: &Vec6) -> Vec6 {
    apply(a, b)
}

/// The spatial inertia, about the frame origin, of a body of mass `mass` whose centre of
/// mass is at `com` with rotational inertia `inertia` about the centre of mass.
pub fn rigid_body_inertia(mass: f64, com: &[f64; 3], inertia: &Mat3) -> Mat6 {
    let c = com;
    let cx = [[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]];
    let mut out = [[0.0; 6]; 6];
    for r in 0..3 {
        for col in 0..3 {
            // I_c + m [c]× [c]×ᵀ
            let cxcxt: f64 = (0..3).map(|k| cx[r][k] * cx[col][k]).sum();
            out[r][col] = inertia[r][col] + mass * cxcxt;
            out[r][3 + col] = mass * cx[r][col];
            out[3 + r][col] = mass * cx[col][r];
        }
        out[3 + r][3 + r] = mass;
    }
    out
}

/// `Xᵀ I X`: an inertia expressed in the child frame moved to the parent frame.
pub fn congruence(x: &Mat6, inertia: &Mat6) -> Mat6 {
    let mut ix = [[0.0; 6]; 6];
    for r in 0..6 {
        for c in 0..6 {
            ix[r][c] = (0..6).map(|k| inertia[r][k] * x[k][c]).sum();
        }
    }
    let mut out = [[0.0; 6]; 6];
    for r in 0..6 {
        for c in 0..6 {
            out[r][c] = (0..6).map(|k| x[k][r] * ix[k][c]).sum();
        }
    }
    out
}
