//! A body at rest from the start until something moves it (a block a toy slides into): no launch, and
//! its resting pose on the scene from every still frame at once. Fitted like a launched body, such a body
//! took a launch from GA's jitter (0.3 m/s and a spin of 3 rad/s on the two-body video) and started
//! where frame 0 alone put it (8 mm over the board on another engine's video): it hopped off before it
//! was struck.

use crate::rest::{mean_pose, still_run, REST_FRAMES};
use crate::unknowns::StartContact;
use crate::video_fit::{settle_along_ray, start_contact, FACING_ANGLE};
use geom::{Camera, Pose, Quat, Vec3};
use sim::sdf::{Sdf, Shape};
use sim::RigidBody;

/// A body at rest from frame 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestingStart {
    /// Its resting pose on the scene.
    pub pose: Pose<f64>,
    /// The frames it stays still in from frame 0 (frame 0 counted).
    pub frames: usize,
    /// The scene's normal where it rests.
    pub normal: [f64; 3],
}

impl RestingStart {
    /// How it starts: at rest ([`StartContact::Rest`]).
    pub fn start(&self) -> StartContact {
        StartContact::Rest { normal: self.normal }
    }
}

/// Whether the body of `poses` (one per frame from frame 0, seen by `camera`) rests on the
/// scene from the start: still over at least [`REST_FRAMES`] frames ([`still_run`]) and touching the scene
/// there. Its resting pose is the still frames' mean pose ([`mean_pose`]: every still frame places it, not
/// frame 0 alone), levelled onto the face it lies on (a pose from images is a degree off, which leaves a
/// face's far edge in the air and the body rocking onto it) and settled along the line of sight onto the
/// scene (no gap, no penetration: [`settle_along_ray`]). `None` when it moves sooner or is not on the scene.
pub fn resting_start(
    body: &RigidBody,
    scene: &Shape,
    poses: &[Pose<f64>],
    camera: &Camera<f64>,
) -> Option<RestingStart> {
    let eye = camera.center();
    let frames = still_run(poses, camera, 2.0 * body.bounding_radius);
    if frames < REST_FRAMES {
        return None;
    }
    let settled = settle_along_ray(body, scene, eye, &mean_pose(&poses[..frames]))?;
    let (pose, normal) = match start_contact(body, scene, &settled) {
        StartContact::Free => return None,
        StartContact::Face { normal } => {
            let levelled = level_on_face(body, &settled, Vec3::cst(normal));
            (settle_along_ray(body, scene, eye, &levelled).unwrap_or(settled), normal)
        }
        StartContact::Touching { normal } | StartContact::Rest { normal } => (settled, normal),
    };
    Some(RestingStart { pose, frames, normal })
}

/// `pose` turned about the body's origin so that the face it lies on (its surface points facing the scene's
/// normal `n` within [`FACING_ANGLE`]) faces straight down `n`.
fn level_on_face(body: &RigidBody, pose: &Pose<f64>, n: Vec3<f64>) -> Pose<f64> {
    let n = n.normalize_or(Vec3::new(0.0, 0.0, 1.0));
    let zero = Vec3::new(0.0, 0.0, 0.0);
    let face = body
        .contact_points
        .iter()
        .map(|p| pose.q.rotate(body.sdf.distance_grad_local(*p).1).normalize_or(zero))
        .filter(|o| o.dot(n) <= -FACING_ANGLE.cos())
        .fold(zero, |a, o| a + o);
    let Some(face) = face.try_normalize() else {
        return *pose;
    };
    // The turn taking the face's normal onto −n.
    let axis = face.cross(n * -1.0);
    let (sin, cos) = (axis.norm(), face.dot(n * -1.0));
    let Some(axis) = axis.try_normalize() else {
        return *pose;
    };
    let turn = Quat::exp(axis * sin.atan2(cos));
    Pose::new((turn * pose.q).normalize_or_identity(), pose.t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::sdf::{Cuboid, Plane};
    use sim::{ContactSampling, MassSpec};

    fn block() -> RigidBody {
        RigidBody::from_shape(
            "block",
            &Shape::Cuboid(Cuboid {
                half: [0.025, 0.025, 0.02],
            }),
            MassSpec::Mass(0.1),
            ContactSampling::Surface { count: 500, seed: 1 },
        )
        .unwrap()
    }

    #[test]
    fn a_still_block_rests_flat_on_the_board_at_its_mean_pose_and_a_moving_one_does_not() {
        let board = Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        });
        let body = block();
        let camera = Camera::look_at(
            Vec3::new(0.0, -0.35, 0.3),
            Vec3::new(0.05, 0.02, 0.02),
            Vec3::new(0.0, 0.0, 1.0),
            geom::Intrinsics::centred(200.0, 160, 120),
            160,
            120,
        );
        let eye = camera.center();
        let yaw = 0.5;
        // GA's poses of a block at rest: tilted 1.2° about x, 2 mm too far along the line of sight (sunk into
        // the board), jittering 0.1 mm and 0.3° about z from frame to frame; still for 6 frames,
        // then struck.
        let truth = Pose::new(Quat::exp(Vec3::new(0.0, 0.0, yaw)), Vec3::new(0.05, 0.02, 0.02));
        let sight = (truth.t - eye).normalize_or(Vec3::new(0.0, 0.0, -1.0));
        let poses: Vec<Pose<f64>> = (0..9)
            .map(|k| {
                let j = if k % 2 == 0 { 1.0 } else { -1.0 };
                let push = if k < 6 { 0.0 } else { 0.01 * (k - 5) as f64 };
                let q = Quat::exp(Vec3::new(0.0, 0.0, yaw + 0.005 * j)) * Quat::exp(Vec3::new(0.021, 0.0, 0.0));
                Pose::new(q, truth.t + sight * 0.002 + Vec3::new(0.0001 * j + push, 0.0, 0.0))
            })
            .collect();
        let rest = resting_start(&body, &board, &poses, &camera).expect("at rest");
        assert_eq!(rest.frames, 6);
        assert!(matches!(rest.start(), StartContact::Rest { .. }));
        assert!(
            (Vec3::cst(rest.normal) - Vec3::new(0.0, 0.0, 1.0)).norm() < 1e-3,
            "{:?}",
            rest.normal
        );
        // Flat (its z axis up within 0.05°), yaw the still frames' mean, on the board without a gap.
        let up = rest.pose.q.rotate(Vec3::new(0.0, 0.0, 1.0));
        assert!(up.z > (0.05f64).to_radians().cos(), "{up:?}");
        let yaw_of = |q: Quat<f64>| {
            let x = q.rotate(Vec3::new(1.0, 0.0, 0.0));
            x.y.atan2(x.x)
        };
        assert!((yaw_of(rest.pose.q) - yaw).abs() < 0.002, "{}", yaw_of(rest.pose.q));
        let clear = crate::video_fit::clearance(&body, &board, &rest.pose);
        assert!(clear.abs() < 2e-4, "{clear}");
        assert!((rest.pose.t - truth.t).norm() < 0.0005, "{:?}", rest.pose.t - truth.t);
        // Struck in frame 1: not at rest.
        let struck: Vec<Pose<f64>> = poses[5..].to_vec();
        assert_eq!(resting_start(&body, &board, &struck, &camera), None);
        // Held 5 cm over the board (in a hand, on a thread): still, but not resting on the scene.
        let held: Vec<Pose<f64>> = poses[..6]
            .iter()
            .map(|p| Pose::new(p.q, p.t + Vec3::new(0.0, 0.0, 0.05)))
            .collect();
        assert_eq!(resting_start(&body, &board, &held, &camera), None);
    }
}
