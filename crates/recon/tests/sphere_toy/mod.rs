//! The first-pose tests' rig: a 96 × 72-class camera over the board and a 6 cm toy (the untrained sphere
//! field) whose body origin sits off the sphere's centre, so that turning it also moves its surface.

#![allow(dead_code)]

use geom::{Camera, Intrinsics, Pose, Quat, TriMesh, Vec3};
use neus::object_model::ObjectField;
use neus::untrained_field::untrained_field;
use neus::{FieldInit, ObjectModel};
use std::path::PathBuf;

/// A camera of `w × h` pixels looking down at the toy from the side.
pub fn camera(w: u32, h: u32) -> Camera<f64> {
    let k = Intrinsics::centred(1.2 * w as f64, w, h);
    Camera::look_at(
        Vec3::new(0.13, -0.16, 0.14),
        Vec3::new(0.0, 0.0, 0.03),
        Vec3::new(0.0, 0.0, 1.0),
        k,
        w,
        h,
    )
}

/// A box mesh (body frame) of half size `h` around the object's sphere: the loss only uses its bounds.
pub fn bounds_mesh(h: f64) -> TriMesh {
    let v: Vec<[f64; 3]> = (0..8)
        .map(|k| [0, 1, 2].map(|a| if k & (1 << a) == 0 { -h } else { h }))
        .collect();
    TriMesh::new(v, vec![[0, 1, 2], [1, 3, 2]])
}

/// The 6 cm toy.
pub fn toy() -> ObjectModel {
    ObjectModel {
        source: PathBuf::from("untrained"),
        primary: ObjectField {
            field: untrained_field(FieldInit::Sphere, Vec3::new(0.0, 0.0, 0.03), 0.06, 3),
            capture_from_body: Pose::new(Quat::exp(Vec3::new(0.1, -0.2, 0.3)), Vec3::new(0.008, -0.005, 0.03)),
        },
        other: None,
        mesh: bounds_mesh(0.04),
        mesh_bounds: bounds_mesh(0.04).bounds(),
        volume: 1e-4,
        reference_capture: "toy_b".into(),
        reference_pose: Pose::identity(),
    }
}

/// Where the sphere's centre is in the world with the body at `pose`.
pub fn sphere_centre(toy: &ObjectModel, pose: &Pose<f64>) -> Vec3<f64> {
    let of = &toy.primary;
    pose.transform_point(of.capture_from_body.inverse().transform_point(of.field.centre))
}
