//! Signed distance functions: the only thing the simulator knows of geometry.
//!
//! The [`Sdf`] trait asks for local-frame queries and supplies world-frame
//! ones (parry's `PointQuery` habit). Every query is generic over [`Real`], so
//! the normal at a contact carries derivatives (its Hessian-vector products)
//! into the impulse.

mod carve;
mod planes;
mod sdf_grid;
mod sdf_mesh;
mod shape;
mod shapes;

pub use planes::{Crease, PlaneReport, PlaneSettings, ScenePlane};
pub use sdf_grid::{GridError, SdfGrid};
pub use sdf_mesh::{MeshDistance, MeshSdfError};
pub use shape::Shape;
pub use shapes::{Capsule, Cuboid, Plane, RoundedBox, Sphere, Wedge};

use geom::{Pose, Real, Vec3};

/// A signed distance: negative inside, positive outside, gradient pointing out.
pub trait Sdf: Send + Sync {
    /// Distance and gradient at `p`, in the shape's own frame.
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>);

    /// Distance at `p`, in the shape's own frame.
    fn distance_local<S: Real>(&self, p: Vec3<S>) -> S {
        self.distance_grad_local(p).0
    }

    /// A lower bound of the distance over the ball of `radius` about `centre` (shape frame): what lets
    /// contact detection skip a cluster of points with one query. An exact distance changes no faster than
    /// the point moves, so the default is the centre's distance less the radius; a shape whose values are not
    /// an exact distance (a baked grid) overrides it.
    fn lower_bound_in_ball(&self, centre: Vec3<f64>, radius: f64) -> f64 {
        self.distance_local(centre) - radius
    }

    /// Distance and world-frame gradient at world point `p`, for the shape
    /// placed at `pose` (shape frame to world).
    fn distance_grad<S: Real>(&self, pose: &Pose<S>, p: Vec3<S>) -> (S, Vec3<S>) {
        let (d, g) = self.distance_grad_local(pose.inverse_transform_point(p));
        (d, pose.transform_vector(g))
    }

    /// Distance at world point `p` for the shape placed at `pose`.
    fn distance<S: Real>(&self, pose: &Pose<S>, p: Vec3<S>) -> S {
        self.distance_local(pose.inverse_transform_point(p))
    }
}
