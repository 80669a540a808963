//! Levenberg–Marquardt on small dense problems, with box bounds and
//! iteratively reweighted residual blocks (for the L1-of-norms loss of Eq. 11).

/// Residuals and their Jacobian at a point: `jac[row][param]`.
pub struct Linearization {
    pub residuals: Vec<f64>,
    pub jac: Vec<Vec<f64>>,
}

/// Solve `a x = b` (dense, small) by Gaussian elimination with partial
/// pivoting; `None` when singular.
pub fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        let (top, below) = a.split_at_mut(col + 1);
        let pivot = &top[col];
        for (r, row) in below.iter_mut().enumerate() {
            let f = row[col] / pivot[col];
            if f != 0.0 {
                for (x, p) in row[col..].iter_mut().zip(&pivot[col..]) {
                    *x -= f * p;
                }
                b[col + 1 + r] -= f * b[col];
            }
        }
    }
    let mut x = vec![0.0; n];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    Some(x)
}

/// The damped Gauss–Newton step `(JᵀJ + λ D) δ = −Jᵀ r`, `D = diag(JᵀJ)` floored.
pub fn lm_step(lin: &Linearization, lambda: f64) -> Option<Vec<f64>> {
    let n = lin.jac.first().map_or(0, |r| r.len());
    let mut jtj = vec![vec![0.0; n]; n];
    let mut jtr = vec![0.0; n];
    for (row, &r) in lin.jac.iter().zip(&lin.residuals) {
        for i in 0..n {
            if row[i] == 0.0 {
                continue;
            }
            jtr[i] -= row[i] * r;
            for j in 0..n {
                jtj[i][j] += row[i] * row[j];
            }
        }
    }
    let max_diag = (0..n).map(|i| jtj[i][i]).fold(0.0, f64::max).max(1e-12);
    for (i, row) in jtj.iter_mut().enumerate() {
        // Floor the scaling so parameters nothing depends on stay put.
        row[i] += lambda * row[i].max(1e-9 * max_diag);
    }
    solve_dense(jtj, jtr)
}

/// Lower and upper bound per parameter.
#[derive(Clone, Debug)]
pub struct Bounds {
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
}

impl Bounds {
    pub fn unbounded(n: usize) -> Self {
        Self {
            lo: vec![f64::NEG_INFINITY; n],
            hi: vec![f64::INFINITY; n],
        }
    }
    pub fn project(&self, x: &mut [f64]) {
        for (i, v) in x.iter_mut().enumerate() {
            *v = v.clamp(self.lo[i], self.hi[i]);
        }
    }
}
