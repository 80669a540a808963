//! A body at rest: when it stayed still between two frames, how much a run of still frames counts, and a
//! body that rests from the start until something moves it.

use crate::image_precision::ImagePrecision;
use geom::{Camera, Pose, Quat, Vec3};

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

/// A body still over at least this many frames from frame 0 (two steps) starts at rest ([`still_run`]):
/// one still step can be a launch's turning point (a toss at its top), two in a row are not.
pub const REST_FRAMES: usize = 3;

/// A body from frame 0 is still while it stays within this many of its image's precisions
/// ([`ImagePrecision`]: across the line of sight, along it, and turned by the across precision over half
/// its bounding radius, the lever most of its surface has) of frame 0's pose and of the frame before's:
/// what one image tells, not the body's size ([`is_still`]'s share of the radius is GA's precision at
/// 320 × 240; the two-body demo at 160 × 120, f = 145 px, tracks its resting block 0.8–1.8 mm across and
/// 2–5.6° apart from frame to frame, within 2.2 mm and 6°).
pub const REST_SIGMAS: f64 = 3.0;

/// How many frames from frame 0 the body of `diameter` seen by `camera` stays still in (frame 0 counted):
/// each frame within [`REST_SIGMAS`] of the frame before and of frame 0, so that a slow creep does not pass
/// for rest. 1 when it moves at once.
pub fn still_run(poses: &[Pose<f64>], camera: &Camera<f64>, diameter: f64) -> usize {
    let near = |a: &Pose<f64>, b: &Pose<f64>| {
        let p = ImagePrecision::of(camera, b, diameter);
        let step = b.t - a.t;
        let along = step.dot(p.sight);
        let across = (step - p.sight * along).norm();
        let turn = (b.q * a.q.conj()).normalize_or_identity().log().norm();
        across < REST_SIGMAS * p.across
            && along.abs() < REST_SIGMAS * p.along
            && turn < REST_SIGMAS * p.across / (0.25 * diameter).max(1e-9)
    };
    (1..poses.len())
        .find(|&k| !(near(&poses[k - 1], &poses[k]) && near(&poses[0], &poses[k])))
        .unwrap_or(poses.len())
}

/// The mean of poses a few degrees apart: their translations averaged, their orientations by the
/// normalised sum of their quaternions on frame 0's hemisphere (the rotation nearest to all of them in the
/// chordal sense; for spreads of a few degrees, their mean to a tiny fraction of that spread).
pub fn mean_pose(poses: &[Pose<f64>]) -> Pose<f64> {
    let n = poses.len().max(1) as f64;
    let t = poses.iter().fold(Vec3::new(0.0, 0.0, 0.0), |a, p| a + p.t) * (1.0 / n);
    let first = poses.first().map_or([1.0, 0.0, 0.0, 0.0], |p| p.q.to_array());
    let mut sum = [0.0; 4];
    for p in poses {
        let q = p.q.to_array();
        let sign = if q.iter().zip(&first).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
            -1.0
        } else {
            1.0
        };
        for (s, v) in sum.iter_mut().zip(q) {
            *s += sign * v;
        }
    }
    Pose::new(Quat::cst(sum).normalize_or_identity(), t)
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

    #[test]
    fn a_body_still_from_the_start_is_found_and_its_mean_pose_is_the_middle() {
        // 160 × 120 at f = 200 px, 0.5 m from a body 80 mm across: 0.63 mm across the line of sight.
        let camera = Camera::look_at(
            Vec3::new(0.0, -0.4, 0.3),
            Vec3::new(0.0, 0.0, 0.02),
            Vec3::new(0.0, 0.0, 1.0),
            geom::Intrinsics::centred(200.0, 160, 120),
            160,
            120,
        );
        // Still for 5 frames with GA's jitter (0.4 mm across, 0.6°), then pushed 5 mm a frame.
        let poses: Vec<Pose<f64>> = (0..9)
            .map(|k| {
                let j = if k % 2 == 0 { 1.0 } else { -1.0 };
                let x = if k < 5 { 0.0002 * j } else { 0.005 * (k - 4) as f64 };
                Pose::new(Quat::exp(Vec3::new(0.0, 0.0, 0.5 + 0.005 * j)), Vec3::new(x, 0.0, 0.02))
            })
            .collect();
        assert_eq!(still_run(&poses, &camera, 0.08), 5);
        let mean = mean_pose(&poses[..4]);
        assert!((mean.t - Vec3::new(0.0, 0.0, 0.02)).norm() < 1e-12, "{:?}", mean.t);
        assert!((mean.q.log().z - 0.5).abs() < 1e-6, "{:?}", mean.q.log());
        // A quaternion's sign does not move the mean.
        let mut flipped = poses[..4].to_vec();
        flipped[1].q = Quat::cst(flipped[1].q.to_array().map(|v| -v));
        assert!((mean_pose(&flipped).q.log() - mean.q.log()).norm() < 1e-12);
        // A creep of 1.2 mm a frame (36 mm/s) passes each step (under 1.9 mm) but not against frame 0 by
        // frame 2.
        let creep: Vec<Pose<f64>> = (0..6)
            .map(|k| Pose::new(Quat::identity(), Vec3::new(0.0012 * k as f64, 0.0, 0.02)))
            .collect();
        assert_eq!(still_run(&creep, &camera, 0.08), 2);
        // Moving at once: a run of one.
        assert_eq!(still_run(&poses[4..], &camera, 0.08), 1);
    }
}
