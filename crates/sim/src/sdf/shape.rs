//! A tree of shapes: the analytic primitives, baked grids, unions and rigid
//! placements. One enum so scenes are plain data (serde) and dispatch is static.

use super::{Capsule, Cuboid, Plane, RoundedBox, Sdf, SdfGrid, Sphere, Wedge};
use geom::{Pose, Real, Vec3};
use std::sync::Arc;

#[derive(Clone, Debug)]
pub enum Shape {
    Plane(Plane),
    Cuboid(Cuboid),
    Sphere(Sphere),
    RoundedBox(RoundedBox),
    Capsule(Capsule),
    Wedge(Wedge),
    /// A baked grid (from a field, a mesh, or any shape).
    Grid(Arc<SdfGrid>),
    /// The union (minimum distance) of the parts.
    Union(Vec<Shape>),
    /// `shape` placed by `pose` (shape frame to parent frame).
    Transformed {
        pose: Pose<f64>,
        shape: Box<Shape>,
    },
}

impl Shape {
    pub fn transformed(self, pose: Pose<f64>) -> Self {
        Shape::Transformed {
            pose,
            shape: Box::new(self),
        }
    }
}

impl Sdf for Shape {
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
        match self {
            Shape::Plane(s) => s.distance_grad_local(p),
            Shape::Cuboid(s) => s.distance_grad_local(p),
            Shape::Sphere(s) => s.distance_grad_local(p),
            Shape::RoundedBox(s) => s.distance_grad_local(p),
            Shape::Capsule(s) => s.distance_grad_local(p),
            Shape::Wedge(s) => s.distance_grad_local(p),
            Shape::Grid(g) => g.distance_grad_local(p),
            Shape::Union(parts) => {
                let mut best: Option<(S, Vec3<S>)> = None;
                for part in parts {
                    let (d, g) = part.distance_grad_local(p);
                    if best.as_ref().is_none_or(|b| d.re() < b.0.re()) {
                        best = Some((d, g));
                    }
                }
                best.unwrap_or((S::cst(f64::INFINITY), Vec3::cst([0.0, 0.0, 1.0])))
            }
            Shape::Transformed { pose, shape } => shape.distance_grad(&Pose::<S>::lift(*pose), p),
        }
    }

    fn lower_bound_in_ball(&self, centre: Vec3<f64>, radius: f64) -> f64 {
        match self {
            Shape::Grid(g) => g.lower_bound_in_ball(centre, radius),
            Shape::Union(parts) => parts
                .iter()
                .map(|part| part.lower_bound_in_ball(centre, radius))
                .fold(f64::INFINITY, f64::min),
            // A rigid placement keeps the ball's radius.
            Shape::Transformed { pose, shape } => {
                shape.lower_bound_in_ball(pose.inverse_transform_point(centre), radius)
            }
            // The analytic shapes are exact distances.
            _ => self.distance_local(centre) - radius,
        }
    }
}
