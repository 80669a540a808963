//! How long a fitted motion is predictable: the frames over which the simulation of the fitted world
//! converges in its step size. After a tumbling contact, motion is chaotic: halving the time step moves it
//! by centimetres (Rapier's own tumbling drop by 13–25 mm), and no model can follow such frames, whoever
//! made them. A physicist holds a simulation to the measurements only where it has converged; the frames
//! after that say little about the launch or the contact values, and what is fitted on them is reported
//! as such.

use crate::image_precision::EDGE_PRECISION_PX;
use geom::Camera;
use sim::World;

/// A frame is past the horizon when the same world simulated with twice the substeps draws some body
/// farther from where the given step size draws it than this many pixels: three edge precisions
/// ([`EDGE_PRECISION_PX`]), what the images can tell apart.
pub const HORIZON_PX: f64 = 3.0 * EDGE_PRECISION_PX;

/// The predictable frames of a simulated world.
#[derive(Clone, Debug, PartialEq)]
pub struct Horizon {
    /// The frames `0..frames` over which the simulation converges (all of them: the world's frame count).
    pub frames: usize,
    /// Per frame, the largest step-size difference over the bodies, in pixels of `camera` at the body's
    /// depth (a body's points move at most its translation plus its bounding radius times its turn).
    pub spread_px: Vec<f64>,
}

impl Horizon {
    /// Whether the simulation stops converging before the last frame.
    pub fn ends_early(&self) -> bool {
        self.frames < self.spread_px.len()
    }
}

/// Where the simulation of `world` (its frame count and substeps) stops converging in its step size, seen
/// by `camera` ([`HORIZON_PX`]).
pub fn predictable_frames(world: &World, camera: &Camera<f64>) -> Horizon {
    let coarse = world.simulate(&world.params());
    let mut fine_world = world.clone();
    fine_world.config.substeps = 2 * world.config.substeps.max(1);
    let fine = fine_world.simulate(&fine_world.params());
    let eye = camera.center();
    let spread_px: Vec<f64> = coarse
        .frames
        .iter()
        .zip(&fine.frames)
        .map(|(a, b)| {
            a.iter()
                .zip(b)
                .zip(&world.bodies)
                .map(|((sa, sb), body)| {
                    let (pa, pb) = (sa.pose.re(), sb.pose.re());
                    let turn = (pb.q * pa.q.conj()).normalize_or_identity().log().norm();
                    let moved = (pb.t - pa.t).norm() + body.bounding_radius * turn;
                    let z = (pa.t - eye).norm().max(1e-9);
                    moved * camera.k.fx / z
                })
                .fold(0.0, f64::max)
        })
        .collect();
    let frames = spread_px
        .iter()
        .position(|&d| d > HORIZON_PX)
        .unwrap_or(spread_px.len());
    Horizon { frames, spread_px }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geom::{Intrinsics, Vec3};
    use sim::sdf::{Cuboid, Plane, Shape};
    use sim::{BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig};

    fn world(initial: BodyState<f64>) -> World {
        let board = Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        });
        let mut w = World::new(
            SimConfig {
                fps: 30.0,
                frames: 30,
                substeps: 10,
                ..SimConfig::default()
            },
            board,
        );
        let body = RigidBody::from_shape(
            "box",
            &Shape::Cuboid(Cuboid {
                half: [0.03, 0.02, 0.015],
            }),
            MassSpec::Mass(0.08),
            ContactSampling::Surface { count: 400, seed: 1 },
        )
        .unwrap();
        let contact = ContactParams {
            restitution: 0.5,
            friction: 0.3,
        };
        w.add_body(body, initial, contact, contact);
        w
    }

    #[test]
    fn a_slide_is_predictable_to_its_end_and_a_tumble_is_not() {
        let camera = Camera::look_at(
            Vec3::new(0.0, -0.4, 0.3),
            Vec3::new(0.0, 0.0, 0.02),
            Vec3::new(0.0, 0.0, 1.0),
            Intrinsics::centred(200.0, 160, 120),
            160,
            120,
        );
        // A box sliding on its face to a stop.
        let slide = world(BodyState::new(
            [-0.1, 0.0, 0.015],
            [1.0, 0.0, 0.0, 0.0],
            [0.8, 0.0, 0.0],
            [0.0; 3],
        ));
        let h = predictable_frames(&slide, &camera);
        assert_eq!(h.frames, 30, "{:?}", h.spread_px);
        // Dropped from 12 cm onto a corner, spinning: it tumbles.
        let q = geom::Quat::exp(Vec3::new(0.5, 0.4, 0.2)).to_array();
        let tumble = world(BodyState::new([0.0, 0.0, 0.12], q, [0.2, 0.0, 0.0], [6.0, -4.0, 3.0]));
        let h = predictable_frames(&tumble, &camera);
        assert!(h.frames < 30, "{:?}", h.spread_px);
        // Before its first landing it falls freely: predictable.
        assert!(h.frames >= 4, "{} {:?}", h.frames, h.spread_px);
    }
}
