//! Which of a body's contact points are near the scene at a given pose, with
//! their distances and the surface's gradient there: what the contact
//! penalty of Eq. 10 needs of each frame (the frames in contact and how deep
//! their points sit), outside a simulation. Generic over the scalar, so a
//! penalty built on it can carry derivatives with respect to the pose.

use crate::sdf::{Sdf, Shape};
use crate::RigidBody;
use geom::{Pose, Real, Vec3};

/// One contact point of the body near the scene.
#[derive(Clone, Copy, Debug)]
pub struct NearPoint<S> {
    /// Its index in [`RigidBody::contact_points`].
    pub index: usize,
    /// Where it is in the world.
    pub world: Vec3<S>,
    /// Its signed distance to the scene (negative inside).
    pub distance: S,
    /// The scene distance's gradient there (the outward normal where the SDF is exact).
    pub gradient: Vec3<S>,
}

/// The body's contact points within `within` of the scene (at most that far outside, or inside) with the
/// body at `pose`, deepest first.
pub fn points_near_scene<S: Real>(body: &RigidBody, pose: &Pose<S>, scene: &Shape, within: f64) -> Vec<NearPoint<S>> {
    // The scene is a distance bound: no point is near when the centre is farther than the body's radius.
    if scene.distance_local(pose.t.re()) > body.bounding_radius + within {
        return Vec::new();
    }
    let rot = pose.q.to_mat();
    let mut near: Vec<NearPoint<S>> = body
        .contact_points
        .iter()
        .enumerate()
        .filter_map(|(index, r)| {
            let world = pose.t + rot.mul_vec(Vec3::lift(*r));
            let (distance, gradient) = scene.distance_grad_local(world);
            (distance.re() <= within).then_some(NearPoint {
                index,
                world,
                distance,
                gradient,
            })
        })
        .collect();
    near.sort_by(|a, b| a.distance.re().total_cmp(&b.distance.re()));
    near
}
