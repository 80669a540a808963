//! Builders shared by the simulator tests.
#![allow(dead_code)]

use sim::sdf::{Cuboid, Plane, Shape, Sphere};
use sim::{BodyState, ContactModel, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};

pub fn ground() -> Shape {
    Shape::Plane(Plane {
        normal: [0.0, 0.0, 1.0],
        offset: 0.0,
    })
}

pub fn cuboid_body(half: [f64; 3], mass: f64, points: usize) -> RigidBody {
    RigidBody::from_shape(
        "box",
        &Shape::Cuboid(Cuboid { half }),
        MassSpec::Mass(mass),
        ContactSampling::Surface { count: points, seed: 7 },
    )
    .unwrap()
}

pub fn sphere_body(radius: f64, mass: f64, points: usize) -> RigidBody {
    RigidBody::from_shape(
        "ball",
        &Shape::Sphere(Sphere { radius }),
        MassSpec::Mass(mass),
        ContactSampling::Surface { count: points, seed: 3 },
    )
    .unwrap()
}

pub fn config(fps: f64, frames: usize, substeps: usize) -> SimConfig {
    SimConfig {
        fps,
        frames,
        substeps,
        ..SimConfig::default()
    }
}

/// Both contact models: the physics laws hold for each.
pub const MODELS: [ContactModel; 2] = [ContactModel::MeanPoint, ContactModel::MultiPoint];

pub fn config_in(model: ContactModel, fps: f64, frames: usize, substeps: usize) -> SimConfig {
    SimConfig {
        contact_model: model,
        ..config(fps, frames, substeps)
    }
}

pub fn world_with(cfg: SimConfig, scene: Shape, bodies: Vec<(RigidBody, BodyState<f64>, ContactParams)>) -> World {
    let mut w = World::new(cfg, scene);
    for (b, s, c) in bodies {
        w.add_body(b, s, c, ContactParams::default());
    }
    w.validate().unwrap();
    w
}

pub fn contact(restitution: f64, friction: f64) -> ContactParams {
    ContactParams { restitution, friction }
}
