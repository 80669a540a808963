//! A box placed on the ground stays put: drift < 1 mm, rotation < 0.5° over 2 s.
use crate::common;
use common::*;
use geom::rotation_distance;
use sim::BodyState;

#[test]
fn box_resting_on_plane_stays_put() {
    for model in MODELS {
        for (k_n, mu) in [(0.3, 0.4), (0.8, 0.1), (0.05, 0.9)] {
            let half = [0.03, 0.02, 0.015];
            let w = world_with(
                config_in(model, 60.0, 121, 10),
                ground(),
                vec![(
                    cuboid_body(half, 0.2, 1000),
                    BodyState::new([0.1, 0.2, half[2]], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]),
                    contact(k_n, mu),
                )],
            );
            let traj = w.simulate(&w.params());
            let start = traj.frames[0][0].pose;
            for (k, f) in traj.frames.iter().enumerate() {
                let p = f[0].pose;
                let drift = (p.t - start.t).norm();
                let rot = rotation_distance(p.q, start.q).to_degrees();
                assert!(drift < 1e-3, "{model:?}: k_n {k_n} mu {mu}: frame {k} drift {drift} m");
                assert!(rot < 0.5, "{model:?}: k_n {k_n} mu {mu}: frame {k} rotation {rot}°");
            }
            let last = traj.frames.last().unwrap()[0];
            assert!(last.v.norm() < 0.02, "{model:?}: still moving at {:?}", last.v);
        }
    }
}

/// A ball stands on the few contact points nearest its bottom, ~3 mm apart for
/// 1000 points on a 3 cm ball, so it behaves like a fine polyhedron: it may
/// rock onto a facet, then it settles. It must not roll away.
#[test]
fn ball_placed_on_plane_settles() {
    for model in MODELS {
        let w = world_with(
            config_in(model, 60.0, 121, 10),
            ground(),
            vec![(
                sphere_body(0.03, 0.1, 1000),
                BodyState::new([0.0, 0.0, 0.03], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]),
                contact(0.5, 0.5),
            )],
        );
        let traj = w.simulate(&w.params());
        let start = traj.frames[0][0].pose;
        for f in &traj.frames {
            assert!((f[0].pose.t - start.t).norm() < 1e-2, "{model:?}: the ball rolls away");
        }
        let last = traj.frames.last().unwrap()[0];
        assert!(last.v.norm() < 5e-3, "{model:?}: still moving at {:?}", last.v);
    }
}
