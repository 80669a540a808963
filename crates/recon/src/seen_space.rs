//! The scene less the space GA saw a body in, for the simulation of PGA on:
//! a reconstructed scene is wrong most where bodies touch it (NeuS rounds a
//! wall's foot into a fillet 10–15 mm wide, [`sim::sdf::SdfGrid::carved`]),
//! and a simulated body that slides into that corner is kicked up and turned
//! by the fillet (the tabletop slide at the wall: 9–15° for four frames, and
//! its resting pose 2.6 mm and 1.6° off after it). GA's poses there, held on
//! the scene by nothing but the images where the fillet held them off it
//! ([`crate::PosesFromVideoConfig::unheld_ratio`]), tell that the fillet is
//! free space. Each pose cuts the body out, shrunk by the image's precision
//! along the scene's normal (the contact penalty's slack,
//! [`crate::contact_penalty`]): a pose that merely grazes the scene within
//! what its image tells cuts nothing.

use crate::{FramePose, ImagePrecision};
use geom::{Camera, Pose};
use sim::sdf::Shape;
use sim::World;
use std::sync::Arc;

/// `world`'s scene with each body of `seen` (its index, and GA's frames of it) cut out at every pose GA
/// fitted, shrunk by `slack` standard deviations of the precision `camera`'s image places it to along the
/// scene's normal; and the grid nodes raised. `None` when the scene is not a baked grid (an analytic scene
/// is taken as exact).
pub fn scene_less_seen(
    world: &World,
    seen: &[(usize, &[FramePose])],
    camera: &Camera<f64>,
    slack: f64,
) -> Option<(Shape, usize)> {
    let Shape::Grid(grid) = &world.scene else {
        return None;
    };
    let mut grid = Arc::clone(grid);
    let mut raised = 0;
    for &(body, ga) in seen {
        let b = &world.bodies[body];
        let mut fitted: Vec<(Pose<f64>, ImagePrecision)> = ga
            .iter()
            .filter(|r| r.fitted)
            .map(|r| (r.pose, ImagePrecision::of(camera, &r.pose, 2.0 * b.bounding_radius)))
            .collect();
        // A body at rest keeps one pose over many frames (GA's still frames): it cuts once.
        fitted.dedup_by(|a, b| a.0 == b.0);
        let poses: Vec<Pose<f64>> = fitted.iter().map(|(p, _)| *p).collect();
        let (carved, n) = grid.carved(&b.sdf, b.bounding_radius, &poses, |k, normal| {
            slack * fitted[k].1.along_direction(normal)
        });
        grid = Arc::new(carved);
        raised += n;
    }
    Some((Shape::Grid(grid), raised))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ImageLoss, StartFrom};
    use geom::{Camera, Intrinsics, Vec3};
    use sim::sdf::{Cuboid, Plane, Sdf, SdfGrid};
    use sim::{BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig};

    /// A board with a bump 4 mm high the reconstruction put where there is none, baked at 2 mm, or exact.
    fn world(baked: bool) -> World {
        let scene = Shape::Union(vec![
            Shape::Plane(Plane {
                normal: [0.0, 0.0, 1.0],
                offset: 0.0,
            }),
            Shape::Cuboid(Cuboid {
                half: [0.01, 0.01, 0.004],
            }),
        ]);
        let scene = if baked {
            let grid = SdfGrid::bake(&scene, [-0.1, -0.1, -0.04], [0.1, 0.1, 0.08], 0.002).expect("a grid");
            Shape::Grid(Arc::new(grid))
        } else {
            scene
        };
        let mut w = World::new(SimConfig::default(), scene);
        let block = RigidBody::from_shape(
            "block",
            &Shape::Cuboid(Cuboid { half: [0.02; 3] }),
            MassSpec::Mass(0.1),
            ContactSampling::default(),
        )
        .expect("a block");
        let rest = BodyState::new([0.0, 0.0, 0.02], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]);
        let contact = ContactParams {
            restitution: 0.5,
            friction: 0.5,
        };
        w.add_body(block, rest, contact, contact);
        w
    }

    fn seen_at(t: [f64; 3], fitted: bool) -> FramePose {
        FramePose {
            pose: Pose::from_translation(Vec3::new(t[0], t[1], t[2])),
            image: ImageLoss::default(),
            contact_penalty: 0.0,
            in_contact: false,
            fitted,
            start: StartFrom::Unheld,
        }
    }

    fn camera() -> Camera<f64> {
        let (w, h) = (320, 240);
        Camera::look_at(
            Vec3::new(0.0, -0.3, 0.3),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Intrinsics::centred(1.2 * w as f64, w, h),
            w,
            h,
        )
    }

    #[test]
    fn the_bump_the_images_saw_the_body_rest_on_is_cut_away() {
        let w = world(true);
        // Seen resting on the board over the bump; a frame GA did not fit, sunk deep, cuts nothing.
        let ga = [seen_at([0.0, 0.0, 0.02], true), seen_at([0.05, 0.0, 0.0], false)];
        let (scene, raised) = scene_less_seen(&w, &[(0, &ga)], &camera(), 1.0).expect("a baked scene");
        assert!(raised > 0);
        let d = |s: &Shape, x: f64, z: f64| s.distance_local(Vec3::new(x, 0.0, z));
        // The bump's top under the block: 4 mm inside the scene's surface before, free after.
        assert!(d(&w.scene, 0.0, 0.002) < -0.001);
        assert!(d(&scene, 0.0, 0.002) > 0.0, "{}", d(&scene, 0.0, 0.002));
        // The board under the unfitted frame, and away from the block, as it was.
        for x in [0.05, -0.06] {
            assert_eq!(d(&scene, x, -0.002), d(&w.scene, x, -0.002));
        }
        // An exact scene is not cut.
        assert!(scene_less_seen(&world(false), &[(0, &ga)], &camera(), 1.0).is_none());
    }
}
