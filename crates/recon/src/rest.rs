//! A body at rest: when it stayed still between two frames, and how much a run of still frames counts.

use geom::{Pose, Vec3};

/// A frame is still when the body moved less than this share of its bounding radius across the camera's
/// line of sight since the frame before (0.4 mm for the 76 mm tabletop toy: GA places it to 0.05–0.2 mm
/// there), less than [`STILL_ALONG`] along it (where one view places it least) and turned less than
/// [`STILL_TURN`].
pub const STILL_ACROSS: f64 = 0.01;
/// See [`STILL_ACROSS`].
pub const STILL_ALONG: f64 = 0.05;
/// See [`STILL_ACROSS`], radians (1°).
pub const STILL_TURN: f64 = 0.0175;

/// Whether a body of bounding radius `radius` stayed still from pose `a` to pose `b` seen from `eye`
/// ([`STILL_ACROSS`]).
pub fn is_still(a: &Pose<f64>, b: &Pose<f64>, eye: Vec3<f64>, radius: f64) -> bool {
    let dir = (b.t - eye).normalize_or(Vec3::new(0.0, 0.0, -1.0));
    let step = b.t - a.t;
    let along = step.dot(dir);
    let across = (step - dir * along).norm();
    let turn = (b.q * a.q.conj()).normalize_or_identity().log().norm();
    across < STILL_ACROSS * radius && along.abs() < STILL_ALONG * radius && turn < STILL_TURN
}

/// Each frame's share in PGA's fit for a body at rest: the frames of a run of `m` frames in which it stays
/// still ([`STILL_ACROSS`]; the run's first frame, where it arrived, included) count `1 / √m` each, so the
/// run counts as `√m` frames, every other frame 1. A body at rest shows the same pose again, its errors
/// (the reconstruction's, the simulation's) the same in each: under PGA's L1 loss a long rest outvoted the
/// flight that decides the launch (the tabletop drop at 320×240: 34 frames at rest, 14 in flight; a
/// launch 0.1 m/s off, simulated 17 mm from GA's poses in flight and 1.5 mm at rest, beat one within
/// 2.5 mm in flight and 3 mm off at rest, and which won turned on the last digits of PA's result).
/// Frames not `fitted` break runs.
pub fn rest_discount(poses: &[Pose<f64>], fitted: &[bool], eye: Vec3<f64>, radius: f64) -> Vec<f64> {
    let n = poses.len();
    let still = |k: usize| k > 0 && fitted[k] && fitted[k - 1] && is_still(&poses[k - 1], &poses[k], eye, radius);
    let mut share = vec![1.0; n];
    let mut k = 0;
    while k < n {
        // The run starting at k: k and every still frame after it.
        let mut end = k + 1;
        while end < n && still(end) {
            end += 1;
        }
        let m = end - k;
        if m > 1 {
            for s in &mut share[k..end] {
                *s = 1.0 / (m as f64).sqrt();
            }
        }
        k = end;
    }
    share
}

#[cfg(test)]
mod tests {
    use super::*;
    use geom::Quat;

    #[test]
    fn a_body_at_rest_counts_as_the_root_of_its_frames() {
        // A body (radius 4 cm) 0.4 m in front of the camera falls 10 mm a frame for 3 frames, lands in
        // frame 3 and rests there for frames 3–11 (9 frames) with GA's jitter (0.2 mm across, 1 mm along,
        // 0.3°), then slides off 5 mm a frame.
        let eye = Vec3::new(0.0, -0.4, 0.0);
        let mut poses = Vec::new();
        for k in 0..15 {
            let t = if k < 3 {
                Vec3::new(0.0, 0.0, 0.03 - 0.01 * k as f64)
            } else if k < 12 {
                let j = if k % 2 == 0 { 1.0 } else { -1.0 };
                Vec3::new(0.0001 * j, 0.0005 * j, 0.0)
            } else {
                Vec3::new(0.005 * (k - 11) as f64, 0.0, 0.0)
            };
            let q = Quat::exp(Vec3::new(0.0, 0.0, if k % 2 == 0 { 0.0026 } else { 0.0 }));
            poses.push(Pose::new(q, t));
        }
        let mut fitted = vec![true; 15];
        let w = rest_discount(&poses, &fitted, eye, 0.04);
        let third = 1.0 / 3.0;
        for (k, &w) in w.iter().enumerate() {
            let want = if (3..12).contains(&k) { third } else { 1.0 };
            assert!((w - want).abs() < 1e-12, "frame {k}: {w}");
        }
        // A frame GA did not fit splits the rest in two runs (3–6 and 8–11, 4 frames each).
        fitted[7] = false;
        let w = rest_discount(&poses, &fitted, eye, 0.04);
        assert!(
            (w[3] - 0.5).abs() < 1e-12 && (w[8] - 0.5).abs() < 1e-12 && w[7] == 1.0,
            "{w:?}"
        );
        // Turning 2° a frame in place is not rest.
        let turning: Vec<Pose<f64>> = (0..5)
            .map(|k| {
                Pose::new(
                    Quat::exp(Vec3::new(0.0, 0.0, 0.035 * k as f64)),
                    Vec3::new(0.0, 0.0, 0.0),
                )
            })
            .collect();
        assert_eq!(rest_discount(&turning, &[true; 5], eye, 0.04), vec![1.0; 5]);
    }
}
