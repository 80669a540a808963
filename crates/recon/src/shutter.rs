//! A frame as a shutter records a moving body: not one instant but the average over the time the shutter is
//! open. A body at 1 m/s smears 17 mm over a 1/60 s shutter, several pixels at a video's size, and the frame
//! shows it wider and fainter at its edges than any one pose draws it. The image terms render such a frame as
//! the mean of the body drawn at a few poses spread over the shutter time, from its pose at the frame's
//! instant and its velocity then (held while the pose is fitted: the simulation, or PA's, knows it).

use geom::{Camera, Pose, Quat, Vec3};
use sim::BodyState;

/// A body's velocity at a frame's instant: `v` of its origin (the centre of mass), `omega` its turn about
/// that origin, both on world axes (the simulator's [`sim::BodyState`] convention).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motion {
    pub v: Vec3<f64>,
    pub omega: Vec3<f64>,
}

impl Motion {
    /// The motion that carries `a` to `b` in `dt` seconds (a body's pace between two frames).
    pub fn between(a: &Pose<f64>, b: &Pose<f64>, dt: f64) -> Self {
        Self {
            v: (b.t - a.t) * (1.0 / dt),
            omega: (b.q * a.q.conj()).log() * (1.0 / dt),
        }
    }

    /// The pose `dt` seconds after `pose` at this velocity (held), and the turn it adds.
    fn after(&self, pose: &Pose<f64>, dt: f64) -> SubPose {
        let turn = Quat::exp(self.omega * dt);
        SubPose {
            pose: Pose::new((turn * pose.q).normalize_or_identity(), pose.t + self.v * dt),
            turn,
        }
    }
}

impl From<&BodyState<f64>> for Motion {
    fn from(s: &BodyState<f64>) -> Self {
        Self { v: s.v, omega: s.omega }
    }
}

/// One pose of the body while the shutter is open, and the turn from the frame's pose to it.
#[derive(Clone, Copy, Debug)]
pub struct SubPose {
    pub pose: Pose<f64>,
    pub turn: Quat<f64>,
}

impl SubPose {
    /// The gradient with respect to the frame's pose (tangent `[δt, δω]`: world axes, the turn about the body's
    /// origin) of a term whose gradient with respect to this sub-pose is `g`. The sub-pose moves with the
    /// frame's pose by the same `δt`, and its rotation `exp(s ω) exp(δω) q = exp(R_s δω) exp(s ω) q`, so
    /// `dL/dδω = R_sᵀ dL/dδω_s`.
    pub fn to_frame_gradient(&self, g: [f64; 6]) -> [f64; 6] {
        let w = self.turn.conj().rotate(Vec3::new(g[3], g[4], g[5]));
        [g[0], g[1], g[2], w.x, w.y, w.z]
    }
}

/// Below this many pixels of motion over the shutter a frame is drawn at its instant.
pub const MIN_BLUR_PX: f64 = 1.0;
/// Sub-poses at most this many pixels apart.
pub const SUB_POSE_SPACING_PX: f64 = 2.0;
/// At most this many sub-poses (each one a render of the body).
pub const MAX_SUB_POSES: usize = 6;

/// How far (pixels) a corner of the box `bounds` (body frame) moves in `camera` between the shutter's opening
/// and its closing, `shutter` seconds apart around `pose` at `motion`.
pub fn blur_px(
    pose: &Pose<f64>,
    motion: &Motion,
    shutter: f64,
    camera: &Camera<f64>,
    bounds: ([f64; 3], [f64; 3]),
) -> f64 {
    let (a, b) = (
        motion.after(pose, -0.5 * shutter).pose,
        motion.after(pose, 0.5 * shutter).pose,
    );
    box_corners(bounds)
        .into_iter()
        .filter_map(|c| {
            let (ua, va, za) = camera.project(a.transform_point(c));
            let (ub, vb, zb) = camera.project(b.transform_point(c));
            (za > 0.0 && zb > 0.0).then(|| (ua - ub).hypot(va - vb))
        })
        .fold(0.0, f64::max)
}

/// The eight corners of the box `(lo, hi)`.
pub(crate) fn box_corners((lo, hi): ([f64; 3], [f64; 3])) -> [Vec3<f64>; 8] {
    std::array::from_fn(|k| {
        let [x, y, z] = [0, 1, 2].map(|a| if k & (1 << a) == 0 { lo[a] } else { hi[a] });
        Vec3::new(x, y, z)
    })
}

/// The poses a frame is drawn at: `pose` alone without a shutter time or a motion, or where the body moves
/// less than [`MIN_BLUR_PX`]; else poses at the middles of equal parts of the shutter time (a box shutter),
/// at most [`SUB_POSE_SPACING_PX`] apart and at most [`MAX_SUB_POSES`].
pub fn shutter_poses(
    pose: &Pose<f64>,
    motion: Option<&Motion>,
    shutter: f64,
    camera: &Camera<f64>,
    bounds: ([f64; 3], [f64; 3]),
) -> Vec<SubPose> {
    let instant = vec![SubPose {
        pose: *pose,
        turn: Quat::identity(),
    }];
    let Some(motion) = motion.filter(|_| shutter > 0.0) else {
        return instant;
    };
    let blur = blur_px(pose, motion, shutter, camera, bounds);
    if !(blur >= MIN_BLUR_PX) {
        return instant;
    }
    let count = ((blur / SUB_POSE_SPACING_PX).ceil() as usize + 1).clamp(2, MAX_SUB_POSES);
    (0..count)
        .map(|i| motion.after(pose, ((i as f64 + 0.5) / count as f64 - 0.5) * shutter))
        .collect()
}

/// `pose` and, with a shutter time and a motion, the body's poses at the shutter's opening and closing: the
/// poses whose projections bound what the frame can show of the body.
pub fn shutter_ends(pose: &Pose<f64>, motion: Option<&Motion>, shutter: f64) -> Vec<Pose<f64>> {
    let mut poses = vec![*pose];
    if let Some(m) = motion.filter(|_| shutter > 0.0) {
        poses.extend([-0.5, 0.5].map(|s| m.after(pose, s * shutter).pose));
    }
    poses
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera<f64> {
        // 160 x 120 with a 150 px focal length, 0.58 m from the origin, looking down at it.
        let k = geom::Intrinsics::centred(150.0, 160, 120);
        Camera::look_at(
            Vec3::new(0.0, -0.3, 0.5),
            Vec3::default(),
            Vec3::new(0.0, 0.0, 1.0),
            k,
            160,
            120,
        )
    }

    #[test]
    fn still_or_instant_frames_are_one_pose() {
        let pose = Pose::new(Quat::identity(), Vec3::new(0.0, 0.0, 0.02));
        let bounds = ([-0.02; 3], [0.02; 3]);
        let moving = Motion {
            v: Vec3::new(1.0, 0.0, 0.0),
            omega: Vec3::new(0.0, 0.0, 3.0),
        };
        assert_eq!(shutter_poses(&pose, None, 1.0 / 60.0, &camera(), bounds).len(), 1);
        assert_eq!(shutter_poses(&pose, Some(&moving), 0.0, &camera(), bounds).len(), 1);
        let crawling = Motion {
            v: Vec3::new(0.001, 0.0, 0.0),
            omega: Vec3::default(),
        };
        assert_eq!(
            shutter_poses(&pose, Some(&crawling), 1.0 / 60.0, &camera(), bounds).len(),
            1
        );
        let subs = shutter_poses(&pose, Some(&moving), 1.0 / 60.0, &camera(), bounds);
        assert!(subs.len() >= 3, "{}", subs.len());
        // Spread evenly over the shutter, centred on the frame's pose.
        let mean = subs.iter().fold(Vec3::default(), |a, s| a + s.pose.t) * (1.0 / subs.len() as f64);
        assert!((mean - pose.t).norm() < 1e-12);
        let span = (subs[subs.len() - 1].pose.t - subs[0].pose.t).x;
        let want = (1.0 - 1.0 / subs.len() as f64) / 60.0;
        assert!((span - want).abs() < 1e-12, "{span} {want}");
    }

    #[test]
    fn frame_gradient_is_the_sub_poses_pulled_back() {
        // L(sub-pose) = a·t + b·(rotation vector of q_s q_ref⁻¹) near a reference: differentiate through the
        // frame's pose by finite differences and compare with the mapped tangent gradient.
        let pose = Pose::new(Quat::exp(Vec3::new(0.3, -0.2, 0.5)), Vec3::new(0.01, 0.02, 0.03));
        let motion = Motion {
            v: Vec3::new(0.5, -0.2, 1.0),
            omega: Vec3::new(4.0, 2.0, -3.0),
        };
        let dt = 0.012;
        let (a, b) = (Vec3::new(0.3, -1.0, 0.7), Vec3::new(-0.4, 0.9, 0.2));
        let reference = motion.after(&pose, dt).pose.q;
        let loss = |p: &Pose<f64>| {
            let s = motion.after(p, dt).pose;
            a.dot(s.t) + b.dot((s.q * reference.conj()).log())
        };
        let sub = motion.after(&pose, dt);
        // At the sub-pose itself the rotation term's tangent gradient is b (log's derivative at identity).
        let g = sub.to_frame_gradient([a.x, a.y, a.z, b.x, b.y, b.z]);
        let h = 1e-6;
        for c in 0..6 {
            let mut d = [0.0; 6];
            d[c] = h;
            let step = |s: f64| {
                let dw = Vec3::new(d[3], d[4], d[5]) * s;
                Pose::new(
                    (Quat::exp(dw) * pose.q).normalize_or_identity(),
                    pose.t + Vec3::new(d[0], d[1], d[2]) * s,
                )
            };
            let fd = (loss(&step(1.0)) - loss(&step(-1.0))) / (2.0 * h);
            assert!(
                (fd - g[c]).abs() < 1e-6,
                "component {c}: finite difference {fd}, mapped {}",
                g[c]
            );
        }
    }
}
