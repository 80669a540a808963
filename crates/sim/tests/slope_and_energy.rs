//! A block on a slope below its friction angle stays put; above it, it slides
//! down with acceleration g (sin θ − μ cos θ). A spinning box dropped on the
//! ground never gains energy. Both contact models.
use crate::common;
use common::*;
use geom::{Quat, Vec3};
use sim::sdf::{Plane, Shape};
use sim::BodyState;

/// The plane through the origin tilted by `theta` about y (downhill: +x).
fn slope(theta: f64) -> Shape {
    Shape::Plane(Plane {
        normal: [theta.sin(), 0.0, theta.cos()],
        offset: 0.0,
    })
}

/// A block lying on the slope at rest, its base centred on the origin.
fn block_on_slope(theta: f64, half: [f64; 3]) -> BodyState<f64> {
    let q = Quat::exp(Vec3::new(0.0, theta, 0.0));
    let n = Vec3::new(theta.sin(), 0.0, theta.cos());
    BodyState::new((n * half[2]).to_array(), q.to_array_re(), [0.0; 3], [0.0; 3])
}

#[test]
fn a_block_below_the_friction_angle_stays_and_above_it_slides_at_the_right_rate() {
    let half = [0.03, 0.025, 0.015];
    let g = 9.81;
    for model in MODELS {
        for (theta_deg, mu) in [(15.0f64, 0.5), (30.0, 0.2), (25.0, 0.3)] {
            let theta = theta_deg.to_radians();
            let fps = 60.0;
            let w = world_with(
                config_in(model, fps, 61, 10),
                slope(theta),
                vec![(
                    cuboid_body(half, 0.2, 1000),
                    block_on_slope(theta, half),
                    contact(0.3, mu),
                )],
            );
            let traj = w.simulate(&w.params());
            let start = traj.frames[0][0].pose.t;
            let downhill = Vec3::new(theta.cos(), 0.0, -theta.sin());
            let along = |k: usize| (traj.frames[k][0].pose.t - start).dot(downhill);
            if mu > theta.tan() {
                for k in 0..traj.frames.len() {
                    let moved = (traj.frames[k][0].pose.t - start).norm();
                    assert!(
                        moved < 1e-3,
                        "{model:?} {theta_deg}° mu {mu}: frame {k} moved {moved} m"
                    );
                }
            } else {
                // Distance after 1 s against ½ a t².
                let a = g * (theta.sin() - mu * theta.cos());
                let t = (traj.frames.len() - 1) as f64 / fps;
                let expected = 0.5 * a * t * t;
                let got = along(traj.frames.len() - 1);
                let err = (got - expected).abs() / expected;
                assert!(
                    err < 0.03,
                    "{model:?} {theta_deg}° mu {mu}: slid {got:.4} m in {t} s, expected {expected:.4} m ({:.1} %)",
                    err * 100.0
                );
                // It slides, it does not tumble.
                let turned = geom::rotation_distance(traj.frames[0][0].pose.q, traj.frames.last().unwrap()[0].pose.q);
                assert!(turned.to_degrees() < 1.0, "{model:?}: turned {}°", turned.to_degrees());
            }
        }
    }
}

#[test]
fn a_spinning_box_dropped_on_the_ground_never_gains_energy() {
    let half = [0.03, 0.02, 0.015];
    for model in MODELS {
        for (k_n, mu) in [(0.5, 0.3), (0.8, 0.1), (0.2, 0.8)] {
            let w = world_with(
                config_in(model, 60.0, 90, 10),
                ground(),
                vec![(
                    cuboid_body(half, 0.2, 1000),
                    BodyState::new(
                        [0.0, 0.0, 0.12],
                        [0.92, 0.2, 0.3, 0.1],
                        [0.3, -0.1, 0.0],
                        [6.0, 3.0, 1.5],
                    ),
                    contact(k_n, mu),
                )],
            );
            let traj = w.simulate(&w.params());
            let body = &w.bodies[0];
            let energy = |k: usize| {
                let s = traj.frames[k][0];
                let r = s.pose.q.to_mat();
                let iw = r.mul_mat(&body.inertia).mul_mat(&r.transpose());
                0.5 * body.mass * s.v.norm_sq() + 0.5 * s.omega.dot(iw.mul_vec(s.omega)) + body.mass * 9.81 * s.pose.t.z
            };
            let e0 = energy(0);
            let mut highest = e0;
            for k in 1..traj.frames.len() {
                let e = energy(k);
                // Positional correction may lift a sunk body by a fraction of a millimetre: 1 mJ of slack.
                assert!(
                    e <= highest + 1e-3 * body.mass * 9.81,
                    "{model:?} k_n {k_n} mu {mu}: frame {k} energy {e:.6} J above the earlier {highest:.6} J"
                );
                highest = highest.max(e);
            }
            assert!(traj.contacts.iter().any(|c| c.scene[0]), "{model:?}: the box must land");
            assert!(
                energy(traj.frames.len() - 1) < 0.9 * e0,
                "{model:?}: the landing must dissipate"
            );
        }
    }
}
