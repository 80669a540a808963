//! A box sliding with v0 on a plane stops after v0² / (2 mu g), within 3 %.
use crate::common;
use common::*;
use sim::BodyState;

#[test]
fn sliding_box_stops_at_friction_distance() {
    for model in MODELS {
        for (v0, mu, k_n) in [(1.0, 0.4, 0.3), (0.6, 0.2, 0.1), (1.5, 0.6, 0.5)] {
            let half = [0.03, 0.03, 0.015];
            let w = world_with(
                config_in(model, 60.0, 120, 10),
                ground(),
                vec![(
                    cuboid_body(half, 0.2, 1000),
                    BodyState::new([0.0, 0.0, half[2]], [1.0, 0.0, 0.0, 0.0], [v0, 0.0, 0.0], [0.0; 3]),
                    contact(k_n, mu),
                )],
            );
            let traj = w.simulate(&w.params());
            let last = traj.frames.last().unwrap()[0];
            assert!(last.v.norm() < 1e-3, "{model:?}: box still moves at {:?}", last.v);
            let expected = v0 * v0 / (2.0 * mu * 9.81);
            let got = last.pose.t.x;
            let err = (got - expected).abs() / expected;
            assert!(
                err < 0.03,
                "{model:?}: v0 {v0} mu {mu}: slid {got:.4} m, expected {expected:.4} m ({:.1} %)",
                err * 100.0
            );
            assert!(
                last.pose.t.y.abs() < 0.01 * expected,
                "{model:?}: sideways drift {}",
                last.pose.t.y
            );
            // At rest the pose holds still (contact jitter stays below 0.1° and 0.1 mm).
            let before = traj.frames[traj.frames.len() - 31][0];
            let turned = geom::rotation_distance(before.pose.q, last.pose.q).to_degrees();
            assert!(turned < 0.1, "{model:?}: turned {turned}° in the last 0.5 s");
            assert!((before.pose.t - last.pose.t).norm() < 1e-4);
        }
    }
}
