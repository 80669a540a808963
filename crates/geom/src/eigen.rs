//! Eigen-decomposition of small symmetric matrices, and the covariance of a point cloud that is most often
//! decomposed.

use crate::{Mat3, Vec3};

/// The centroid of `points` and their covariance about it (divided by their count; the zero matrix for
/// none): the principal axes of a cloud, or the normal of the plane through it (the eigenvector of the
/// smallest eigenvalue, [`symmetric_eigen`]).
pub fn point_covariance(points: &[Vec3<f64>]) -> (Vec3<f64>, Mat3<f64>) {
    let n = points.len().max(1) as f64;
    let c = points.iter().fold(Vec3::zero(), |a, p| a + *p) * (1.0 / n);
    let mut cov = Mat3::<f64>::zero();
    for p in points {
        cov = cov.add(&Mat3::outer(*p - c, *p - c));
    }
    (c, cov.scale(1.0 / n))
}

/// Eigen-decomposition of a symmetric N×N matrix (Jacobi rotations): values
/// and vectors (as columns).
pub fn symmetric_eigen<const N: usize>(m: [[f64; N]; N]) -> ([f64; N], [[f64; N]; N]) {
    let mut a = m;
    let mut v = [[0.0; N]; N];
    for (k, row) in v.iter_mut().enumerate() {
        row[k] = 1.0;
    }
    for _ in 0..50 * N * N {
        let (mut p, mut q, mut off) = (0, 1, 0.0f64);
        for i in 0..N {
            for j in i + 1..N {
                if a[i][j].abs() > off {
                    (p, q, off) = (i, j, a[i][j].abs());
                }
            }
        }
        if off < 1e-300 {
            break;
        }
        let theta = 0.5 * (a[q][q] - a[p][p]) / a[p][q];
        let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
        let t = if theta == 0.0 { 1.0 } else { t };
        let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
        for k in 0..N {
            let (akp, akq) = (a[k][p], a[k][q]);
            a[k][p] = c * akp - s * akq;
            a[k][q] = s * akp + c * akq;
        }
        for k in 0..N {
            let (apk, aqk) = (a[p][k], a[q][k]);
            a[p][k] = c * apk - s * aqk;
            a[q][k] = s * apk + c * aqk;
        }
        for row in v.iter_mut() {
            let (vp, vq) = (row[p], row[q]);
            row[p] = c * vp - s * vq;
            row[q] = s * vp + c * vq;
        }
    }
    (std::array::from_fn(|k| a[k][k]), v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigenpairs_of_a_rotated_diagonal_matrix() {
        // R diag(3, 2, 1) Rᵀ for a rotation R about a tilted axis: its eigenvectors are R's columns.
        let r = crate::Quat::exp(crate::Vec3::new(0.3, -0.5, 0.8)).to_mat();
        let d = crate::Mat3::from_rows([[3.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]]);
        let m = r.mul_mat(&d).mul_mat(&r.transpose());
        let (values, vectors) = symmetric_eigen(m.m);
        let vectors = crate::Mat3::from_rows(vectors);
        for k in 0..3 {
            let v = vectors.col(k);
            let mv = m.mul_vec(v);
            assert!((mv - v * values[k]).norm() < 1e-12, "pair {k}");
            assert!((v.norm() - 1.0).abs() < 1e-12);
        }
        let mut sorted = values;
        sorted.sort_by(f64::total_cmp);
        for (a, b) in sorted.iter().zip([1.0, 2.0, 3.0]) {
            assert!((a - b).abs() < 1e-12, "{values:?}");
        }
    }
}
