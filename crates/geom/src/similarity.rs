//! Similarity transforms (scale, rotation, translation) and their least-squares fit to point pairs:
//! what puts a reconstruction made in arbitrary units and axes into a metric world.

use crate::{Pose, Quat, Vec3};

/// `p ↦ scale · rotation(p) + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Similarity {
    pub scale: f64,
    pub rotation: Quat<f64>,
    pub translation: Vec3<f64>,
}

impl Similarity {
    pub fn identity() -> Self {
        Similarity {
            scale: 1.0,
            rotation: Quat::identity(),
            translation: Vec3::zero(),
        }
    }

    pub fn apply(&self, p: Vec3<f64>) -> Vec3<f64> {
        self.rotation.rotate(p) * self.scale + self.translation
    }

    /// A camera's world-to-camera pose in the old world → the same camera's in the new world (its frame keeps
    /// its axes; distances in it are scaled).
    pub fn move_camera(&self, world_to_cam: &Pose<f64>) -> Pose<f64> {
        // p_cam' = s (R_c x + t_c) with x = Rᵀ (y - t) / s: rotation R_c Rᵀ, translation s t_c - R_c Rᵀ t.
        let q = world_to_cam.q * self.rotation.conj();
        Pose::new(q, world_to_cam.t * self.scale - q.rotate(self.translation))
    }

    /// The similarity that maps `from[i]` nearest `to[i]` in the least-squares sense (Horn's closed form for
    /// the rotation, Umeyama's scale); `None` for fewer than three points or points all on one line.
    pub fn fit(from: &[Vec3<f64>], to: &[Vec3<f64>]) -> Option<Similarity> {
        let n = from.len();
        if n < 3 || to.len() != n {
            return None;
        }
        let mean = |p: &[Vec3<f64>]| p.iter().fold(Vec3::zero(), |s, &v| s + v) * (1.0 / n as f64);
        let (ca, cb) = (mean(from), mean(to));
        let mut s = [[0.0; 3]; 3];
        let mut spread = 0.0;
        for (a, b) in from.iter().zip(to) {
            let (a, b) = ((*a - ca).to_array(), (*b - cb).to_array());
            for i in 0..3 {
                for j in 0..3 {
                    s[i][j] += a[i] * b[j];
                }
            }
            spread += a.iter().map(|v| v * v).sum::<f64>();
        }
        let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
        let horn = [
            [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
            [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
            [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
            [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
        ];
        let (values, vectors) = crate::symmetric_eigen(horn);
        let mut order = [0, 1, 2, 3];
        order.sort_by(|&i, &j| values[j].total_cmp(&values[i]));
        // Points on one line leave the rotation about it free: the two largest eigenvalues meet.
        let scale_of_values = values.iter().map(|v| v.abs()).fold(0.0, f64::max);
        if spread <= 0.0 || values[order[0]] - values[order[1]] <= 1e-9 * scale_of_values {
            return None;
        }
        let k = order[0];
        let rotation = Quat::new(vectors[0][k], vectors[1][k], vectors[2][k], vectors[3][k]).unit();
        let turned: f64 = from
            .iter()
            .zip(to)
            .map(|(a, b)| rotation.rotate(*a - ca).dot(*b - cb))
            .sum();
        let scale = turned / spread;
        if !(scale > 0.0) {
            return None;
        }
        Some(Similarity {
            scale,
            rotation,
            translation: cb - rotation.rotate(ca) * scale,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_recovers_a_similarity_and_moves_cameras_with_it() {
        let truth = Similarity {
            scale: 0.037,
            rotation: Quat::exp(Vec3::new(2.1, -0.7, 0.4)),
            translation: Vec3::new(0.3, -1.2, 0.05),
        };
        // Points on a plane (a board) are enough.
        let from: Vec<Vec3<f64>> = (0..12)
            .map(|i| Vec3::new((i % 4) as f64 * 3.0 - 2.0, (i / 4) as f64 * 5.0, 7.0))
            .collect();
        let to: Vec<Vec3<f64>> = from.iter().map(|p| truth.apply(*p)).collect();
        let found = Similarity::fit(&from, &to).unwrap();
        assert!((found.scale / truth.scale - 1.0).abs() < 1e-12);
        assert!(crate::rotation_distance(found.rotation, truth.rotation) < 1e-9);
        assert!((found.translation - truth.translation).norm() < 1e-12);

        // A camera seeing a point sees it at the same place, scaled, after the move.
        let cam = Pose::new(Quat::exp(Vec3::new(0.1, 0.9, -0.3)), Vec3::new(1.0, 2.0, 30.0));
        let moved = truth.move_camera(&cam);
        for p in &from {
            let before = cam.transform_point(*p) * truth.scale;
            let after = moved.transform_point(truth.apply(*p));
            assert!((before - after).norm() < 1e-12);
        }

        let line: Vec<Vec3<f64>> = (0..5).map(|i| Vec3::new(i as f64, 2.0 * i as f64, 0.0)).collect();
        let line_to: Vec<Vec3<f64>> = line.iter().map(|p| truth.apply(*p)).collect();
        assert!(Similarity::fit(&line, &line_to).is_none());
    }
}
