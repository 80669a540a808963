//! A ball dropped from h (no damping) rebounds to about k_n² h, within 10 %.
use crate::common;
use common::*;
use sim::BodyState;

#[test]
fn dropped_ball_rebounds_to_restitution_squared_height() {
    for model in MODELS {
        let r = 0.03;
        let h = 0.5;
        for k_n in [0.3, 0.5, 0.8] {
            let w = world_with(
                config_in(model, 120.0, 200, 10),
                ground(),
                vec![(
                    sphere_body(r, 0.1, 1000),
                    BodyState::new([0.0, 0.0, r + h], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]),
                    contact(k_n, 0.3),
                )],
            );
            let traj = w.simulate(&w.params());
            // Highest point after the first bounce (velocity turned upward).
            let zs: Vec<f64> = traj.frames.iter().map(|f| f[0].pose.t.z - r).collect();
            let bounce = zs.iter().position(|&z| z < 0.01).expect("ball reaches the ground");
            let peak = zs[bounce..].iter().cloned().fold(f64::MIN, f64::max);
            let expected = k_n * k_n * h;
            let err = (peak - expected).abs() / expected;
            assert!(
                err < 0.10,
                "{model:?}: k_n {k_n}: rebound {peak:.4} m, expected {expected:.4} m ({:.1} %)",
                err * 100.0
            );
        }
    }
}

/// A box sliding on the board into a wall bounces off the wall when its face reaches it, at the wall's
/// restitution, and stays flat on the board. The mean-point model averages each contact patch apart: the
/// board's and the wall's points averaged together lie nearer the board and took its normal, so the box
/// sank into the wall for ten substeps, pitching 1.6°, before the wall's points alone made it bounce.
#[test]
fn a_box_sliding_into_a_wall_bounces_off_it_when_it_reaches_it() {
    use geom::{Pose, Vec3};
    use sim::sdf::{Cuboid, Shape};
    let wall_face = 0.2;
    let scene = Shape::Union(vec![
        ground(),
        Shape::Cuboid(Cuboid {
            half: [0.02, 0.12, 0.035],
        })
        .transformed(Pose::from_translation(Vec3::new(wall_face + 0.02, 0.0, 0.035))),
    ]);
    let (half, restitution, v0) = ([0.03, 0.022, 0.018], 0.5, 0.5);
    for model in MODELS {
        // One substep per frame: every substep is seen.
        let w = world_with(
            config_in(model, 600.0, 150, 1),
            scene.clone(),
            vec![(
                cuboid_body(half, 0.08, 1000),
                BodyState::new(
                    [wall_face - half[0] - 0.03, 0.0, half[2]],
                    [1.0, 0.0, 0.0, 0.0],
                    [v0, 0.0, 0.0],
                    [0.0; 3],
                ),
                contact(restitution, 0.1),
            )],
        );
        let states: Vec<_> = w.simulate(&w.params()).frames.iter().map(|f| f[0]).collect();
        let touch = states
            .iter()
            .position(|s| s.pose.t.x + half[0] >= wall_face - 5e-4)
            .expect("the box reaches the wall");
        let turned = states.iter().position(|s| s.v.x < 0.0).expect("the box bounces");
        let v_in = states[touch - 1].v.x;
        let v_out = -states[turned..].iter().map(|s| s.v.x).fold(f64::MAX, f64::min);
        let tilt = states
            .iter()
            .map(|s| geom::rotation_distance(s.pose.q, geom::Quat::identity()).to_degrees())
            .fold(0.0, f64::max);
        assert!(
            turned <= touch + 2,
            "{model:?}: the face reached the wall at substep {touch}, the box turned at {turned}"
        );
        assert!(
            (v_out / v_in - restitution).abs() < 0.05,
            "{model:?}: rebound {v_out:.3} m/s from {v_in:.3} (ratio {:.3}, restitution {restitution})",
            v_out / v_in
        );
        assert!(tilt < 0.5, "{model:?}: the box tipped {tilt:.2}°");
    }
}
