//! The tossed block of the video tests: a block (a cube colliding with the
//! board) shown as the untrained sphere field around it (the image only
//! follows the pose), filmed by a fixed camera, and its frames rendered in the
//! untrained board scene.

#![allow(dead_code)]

use geom::{Camera, Intrinsics, Pose, TriMesh, Vec3};
use neus::compose::{prerender_scene, render_composed, Behind, ComposedRay, Composer, Layer};
use neus::object_model::ObjectField;
use neus::untrained_field::untrained_field;
use neus::{FieldInit, ObjectModel};
use recon::FrameTarget;
use sim::sdf::{Cuboid, Plane, Shape};
use sim::{BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};
use std::path::PathBuf;

/// The untrained sphere field's surface: 0.45 of its 6 cm unit radius.
pub const RADIUS: f64 = 0.027;

pub fn camera() -> Camera<f64> {
    let (w, h) = (128, 96);
    let k = Intrinsics::centred(1.2 * w as f64, w, h);
    Camera::look_at(
        Vec3::new(0.1, -0.3, 0.25),
        Vec3::new(0.05, 0.02, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
        k,
        w,
        h,
    )
}

pub fn ball_model() -> ObjectModel {
    let h = RADIUS;
    let v: Vec<[f64; 3]> = (0..8)
        .map(|k| {
            [
                if k & 1 == 0 { -h } else { h },
                if k & 2 == 0 { -h } else { h },
                if k & 4 == 0 { -h } else { h },
            ]
        })
        .collect();
    ObjectModel {
        source: PathBuf::from("untrained"),
        primary: ObjectField {
            field: untrained_field(FieldInit::Sphere, Vec3::new(0.0, 0.0, 0.03), 0.06, 3),
            // The body origin is the sphere's centre.
            capture_from_body: Pose::from_translation(Vec3::new(0.0, 0.0, 0.03)),
        },
        other: None,
        mesh_bounds: geom::bounding_box(v.iter().copied()),
        mesh: TriMesh::new(v, vec![[0, 1, 2]]),
        volume: 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3),
        reference_capture: "toy_b".into(),
        reference_pose: Pose::identity(),
    }
}

pub fn world(v0: [f64; 3], contact: ContactParams) -> World {
    let cfg = SimConfig {
        fps: 30.0,
        frames: 10,
        substeps: 10,
        ..SimConfig::default()
    };
    let mut w = World::new(
        cfg,
        Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        }),
    );
    let ball = RigidBody::from_shape(
        "block",
        &Shape::Cuboid(Cuboid { half: [RADIUS; 3] }),
        MassSpec::Mass(0.1),
        ContactSampling::default(),
    )
    .expect("a ball");
    let start = BodyState::new([-0.04, 0.0, RADIUS + 0.02], [1.0, 0.0, 0.0, 0.0], v0, [0.0; 3]);
    w.add_body(ball, start, contact, contact);
    w
}

/// The block resting unturned on the board at `(x, y)` for `frames` frames.
pub fn resting_world(frames: usize, [x, y]: [f64; 2]) -> World {
    let mut w = world([0.0; 3], TRUTH);
    w.config.frames = frames;
    w.initial[0] = BodyState::new([x, y, RADIUS], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]);
    w
}

/// The scene pre-rendered through the camera, and each frame of `world`'s simulation rendered over it
/// (mask: the body's opacity above ½).
pub fn film(ball: &ObjectModel, world: &World) -> (Vec<ComposedRay>, Vec<FrameTarget>) {
    let traj = world.simulate(&world.params());
    let poses: Vec<Pose<f64>> = traj.frames.iter().map(|f| f[0].pose).collect();
    film_poses(ball, &poses)
}

/// The scene pre-rendered through the camera, and the body rendered over it at each of `poses`.
pub fn film_poses(ball: &ObjectModel, poses: &[Pose<f64>]) -> (Vec<ComposedRay>, Vec<FrameTarget>) {
    let cam = camera();
    let scene = untrained_field(FieldInit::Board, Vec3::new(0.0, 0.0, 0.05), 0.3, 7);
    let mut composer = Composer::default();
    let behind = prerender_scene(&scene, &cam, &mut composer);
    let frames = poses
        .iter()
        .map(|pose| {
            let layer = Layer::object(&ball.primary.field, &ball.primary.capture_from_body, pose, 0);
            let img = render_composed(&[layer], 1, Behind::Scene(&behind), &cam, &mut composer);
            FrameTarget {
                camera: cam,
                rgb: img.rgb,
                mask: img.object_opacity.iter().map(|&o| o > 0.5).collect(),
                exposure: 1.0,
                shutter: 0.0,
                mask_computed: false,
            }
        })
        .collect();
    (behind, frames)
}

/// The true launch and contact values.
pub const V0: [f64; 3] = [0.6, 0.15, 0.3];
pub const TRUTH: ContactParams = ContactParams {
    restitution: 0.3,
    friction: 0.3,
};
