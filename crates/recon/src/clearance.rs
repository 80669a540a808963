//! How far a body at a pose is from the scene: what decides whether it touches it (the first pose, GA's
//! contact frames, the launch guess).

use geom::Pose;
use sim::sdf::{Sdf, Shape};
use sim::RigidBody;

/// Closer than this to the scene (m), a body counts as touching it at the start (no free fall in the launch
/// guess).
pub const TOUCHING: f64 = 0.002;

/// The lowest signed distance of the body's contact points to the scene at `pose` (m; negative: sunk).
pub fn clearance(body: &RigidBody, scene: &Shape, pose: &Pose<f64>) -> f64 {
    body.contact_points
        .iter()
        .map(|p| scene.distance_local(pose.transform_point(*p)))
        .fold(f64::INFINITY, f64::min)
}
