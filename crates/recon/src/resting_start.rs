//! A body at rest from the start until something moves it (a block a toy slides into): no launch, and
//! its resting pose on the scene from every still frame at once. Fitted like a launched body, such a body
//! took a launch from GA's jitter (0.3 m/s and a spin of 3 rad/s on the two-body video) and started
//! where frame 0 alone put it (8 mm over the board on another engine's video): it hopped off before it
//! was struck.

use crate::rest::{mean_pose, still_run, REST_FRAMES};
use crate::unknowns::StartContact;
use crate::video_fit::{facing_points, settle_along_ray, start_contact};
use geom::{Camera, Pose, Quat, Vec3};
use sim::sdf::Shape;
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

/// Outward normals within this of facing the scene count as the face a body lies on when it is levelled: the
/// sides (at a right angle) are left out, a reconstructed face's bumps are not.
const FACE_CONE: f64 = 30.0 * std::f64::consts::PI / 180.0;

/// `pose` turned about the body's origin so that the face it lies on faces straight down the scene's normal
/// `n`. The face is the plane through its points (the contact points near the scene whose outward normals
/// face it within [`FACE_CONE`]), fitted to their positions, not their normals: a reconstructed face is
/// bumpy at its field's resolution and its normals scatter by more than the tilt to take out (the two-body
/// video's merged block: 5 of its underside's points within 5° of facing down, and their mean normal left it
/// 1.7° tilted, 1.6 mm over its resting height).
fn level_on_face(body: &RigidBody, pose: &Pose<f64>, n: Vec3<f64>) -> Pose<f64> {
    let n = n.normalize_or(Vec3::new(0.0, 0.0, 1.0));
    let placed: Vec<Vec3<f64>> = body.contact_points.iter().map(|p| pose.transform_point(*p)).collect();
    // Heights along the normal: the face's plane is what is sought, the scene's distance is not needed.
    let heights: Vec<f64> = placed.iter().map(|p| p.dot(n)).collect();
    let face = facing_points(body, pose, n, &placed, &heights, FACE_CONE);
    if face.len() < 3 {
        return *pose;
    }
    let (_, cov) = geom::point_covariance(&face);
    let (values, vectors) = geom::symmetric_eigen(cov.m);
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    // A line of points (an edge) spans no plane.
    if !(values[order[1]] > 4.0 * values[order[0]].max(0.0)) {
        return *pose;
    }
    let normal = Vec3::new(vectors[0][order[0]], vectors[1][order[0]], vectors[2][order[0]]);
    let up = if normal.dot(n) < 0.0 { normal * -1.0 } else { normal };
    // The turn taking the face's plane normal onto n.
    let axis = up.cross(n);
    let (sin, cos) = (axis.norm(), up.dot(n));
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

    fn board() -> Shape {
        Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        })
    }

    /// The two-body video's camera at its small size, looking at the block.
    fn camera() -> Camera<f64> {
        Camera::look_at(
            Vec3::new(0.0, -0.35, 0.3),
            Vec3::new(0.05, 0.02, 0.02),
            Vec3::new(0.0, 0.0, 1.0),
            geom::Intrinsics::centred(200.0, 160, 120),
            160,
            120,
        )
    }

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
        let board = board();
        let body = block();
        let camera = camera();
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

    /// A reconstructed block: its underside bumpy by ±0.3 mm over 2 mm (a field's ripples at a small
    /// capture's resolution), so that its normals there scatter by well over the tilt to take out.
    fn bumpy_block() -> RigidBody {
        let mut mesh = sim::tessellate::shape_mesh(
            &Shape::Cuboid(Cuboid {
                half: [0.025, 0.025, 0.02],
            }),
            96,
        )
        .unwrap();
        let mut rng = geom::SplitMix64::new(7);
        for v in &mut mesh.vertices {
            let bump = rng.range(-3e-4, 3e-4);
            // The underside's inner vertices only: the mesh stays closed.
            if v[2] < -0.0199 && v[0].abs() < 0.0249 && v[1].abs() < 0.0249 {
                v[2] += bump;
            }
        }
        RigidBody::from_mesh(
            "block",
            &mesh,
            MassSpec::Mass(0.1),
            ContactSampling::Surface { count: 1000, seed: 1 },
            None,
        )
        .unwrap()
    }

    #[test]
    fn a_bumpy_underside_is_levelled_by_its_plane_not_by_its_normals() {
        let board = board();
        let body = bumpy_block();
        let camera = camera();
        // GA's poses: tilted 1.5° about x and 1° about y, still for 5 frames.
        let q = Quat::exp(Vec3::new(0.0, 0.0, 0.5)) * Quat::exp(Vec3::new(0.026, 0.017, 0.0));
        let poses = vec![Pose::new(q, Vec3::new(0.05, 0.02, 0.021)); 5];
        let rest = resting_start(&body, &board, &poses, &camera).expect("at rest");
        let up = rest.pose.q.rotate(Vec3::new(0.0, 0.0, 1.0));
        let tilt = up.z.clamp(-1.0, 1.0).acos().to_degrees();
        assert!(tilt < 0.2, "tilted {tilt:.2}° after levelling");
        let clear = crate::video_fit::clearance(&body, &board, &rest.pose);
        assert!(clear.abs() < 2e-4, "{clear}");
    }
}
