//! Plane-to-image homographies by the normalised direct linear transform (Hartley), and their use.

use geom::symmetric_eigen;

/// A 3 × 3 homography, row-major, mapping `(x, y, 1)` to a point up to scale.
pub type Homography = [[f64; 3]; 3];

/// `h` applied to `p`.
pub fn apply(h: &Homography, p: [f64; 2]) -> [f64; 2] {
    let w = h[2][0] * p[0] + h[2][1] * p[1] + h[2][2];
    [
        (h[0][0] * p[0] + h[0][1] * p[1] + h[0][2]) / w,
        (h[1][0] * p[0] + h[1][1] * p[1] + h[1][2]) / w,
    ]
}

/// The similarity that moves `points` to their centroid and scales their mean distance to √2.
fn normaliser(points: &[[f64; 2]]) -> [[f64; 3]; 3] {
    let n = points.len() as f64;
    let cx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let cy = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let mean = points
        .iter()
        .map(|p| ((p[0] - cx).powi(2) + (p[1] - cy).powi(2)).sqrt())
        .sum::<f64>()
        / n;
    let s = if mean > 0.0 {
        std::f64::consts::SQRT_2 / mean
    } else {
        1.0
    };
    [[s, 0.0, -s * cx], [0.0, s, -s * cy], [0.0, 0.0, 1.0]]
}

fn mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

/// The inverse of a 3 × 3 matrix (`None` if singular).
pub fn invert3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let c = |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    let cof = [
        [c(1, 2, 1, 2), -c(1, 2, 0, 2), c(1, 2, 0, 1)],
        [-c(0, 2, 1, 2), c(0, 2, 0, 2), -c(0, 2, 0, 1)],
        [c(0, 1, 1, 2), -c(0, 1, 0, 2), c(0, 1, 0, 1)],
    ];
    let det = m[0][0] * cof[0][0] + m[0][1] * cof[0][1] + m[0][2] * cof[0][2];
    if det.abs() < 1e-300 || !det.is_finite() {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            inv[i][j] = cof[j][i] / det;
        }
    }
    Some(inv)
}

/// The homography taking each `from[i]` to `to[i]` (four or more pairs, no three of four collinear), least
/// squares in the normalised algebraic error; `None` for degenerate input.
pub fn fit(from: &[[f64; 2]], to: &[[f64; 2]]) -> Option<Homography> {
    assert_eq!(from.len(), to.len());
    if from.len() < 4 {
        return None;
    }
    let (tf, tt) = (normaliser(from), normaliser(to));
    let mut ata = [[0.0f64; 9]; 9];
    for (p, q) in from.iter().zip(to) {
        let a = apply(&tf, *p);
        let b = apply(&tt, *q);
        let rows = [
            [a[0], a[1], 1.0, 0.0, 0.0, 0.0, -b[0] * a[0], -b[0] * a[1], -b[0]],
            [0.0, 0.0, 0.0, a[0], a[1], 1.0, -b[1] * a[0], -b[1] * a[1], -b[1]],
        ];
        for r in &rows {
            for i in 0..9 {
                for j in 0..9 {
                    ata[i][j] += r[i] * r[j];
                }
            }
        }
    }
    let (values, vectors) = symmetric_eigen(ata);
    let smallest = (0..9).min_by(|&i, &j| values[i].total_cmp(&values[j]))?;
    let h: Vec<f64> = (0..9).map(|k| vectors[k][smallest]).collect();
    let hn = [[h[0], h[1], h[2]], [h[3], h[4], h[5]], [h[6], h[7], h[8]]];
    let out = mul(&mul(&invert3(&tt)?, &hn), &tf);
    let scale = out[2][2];
    if !scale.is_finite() || scale.abs() < 1e-300 {
        return Some(out);
    }
    Some(out.map(|r| r.map(|v| v / scale)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_recovers_a_homography_from_exact_points() {
        let h = [[1.2, 0.1, 30.0], [-0.05, 0.9, 12.0], [1e-4, -2e-4, 1.0]];
        let from: Vec<[f64; 2]> = (0..12)
            .map(|i| [(i % 4) as f64 * 50.0, (i / 4) as f64 * 70.0])
            .collect();
        let to: Vec<[f64; 2]> = from.iter().map(|p| apply(&h, *p)).collect();
        let got = fit(&from, &to).unwrap();
        for p in &from {
            let (a, b) = (apply(&h, *p), apply(&got, *p));
            assert!((a[0] - b[0]).abs() < 1e-7 && (a[1] - b[1]).abs() < 1e-7);
        }
    }
}
