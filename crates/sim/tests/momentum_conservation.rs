//! Two bodies with no gravity conserve total linear momentum (and angular
//! momentum about the origin) through their collision.
use crate::common;
use common::*;
use sim::{BodyState, SimConfig, World};

fn two_body_world(model: sim::ContactModel, mu: f64) -> World {
    let cfg = SimConfig {
        gravity: [0.0; 3],
        ..config_in(model, 60.0, 60, 10)
    };
    let mut w = World::new(cfg, ground());
    let a = sphere_body(0.03, 0.1, 800);
    let b = cuboid_body([0.03, 0.025, 0.02], 0.25, 800);
    // Off-centre hit so rotation and friction take part.
    w.add_body(
        a,
        BodyState::new(
            [-0.2, 0.01, 0.5],
            [1.0, 0.0, 0.0, 0.0],
            [1.2, 0.0, 0.0],
            [0.0, 0.0, 2.0],
        ),
        contact(0.5, 0.5),
        contact(0.6, mu),
    );
    w.add_body(
        b,
        BodyState::new([0.0, 0.0, 0.5], [0.96, 0.0, 0.0, 0.28], [-0.3, 0.0, 0.0], [0.0; 3]),
        contact(0.5, 0.5),
        contact(0.6, mu),
    );
    w
}

#[test]
fn linear_momentum_is_conserved_through_a_collision() {
    for model in MODELS {
        for mu in [1e-9, 0.3] {
            let w = two_body_world(model, mu);
            let traj = w.simulate(&w.params());
            let masses: Vec<f64> = w.bodies.iter().map(|b| b.mass).collect();
            let p = |k: usize| {
                traj.frames[k]
                    .iter()
                    .zip(&masses)
                    .fold(geom::Vec3::zero(), |acc, (s, m)| acc + s.v * *m)
            };
            let p0 = p(0);
            assert!(
                traj.contacts.iter().any(|c| c.pairs[0]),
                "{model:?}: the bodies never collided (mu {mu})"
            );
            for k in 0..traj.frames.len() {
                assert!(
                    (p(k) - p0).norm() < 1e-12,
                    "{model:?}: frame {k}: momentum {:?} vs {p0:?}",
                    p(k)
                );
            }
            // The collision really exchanged momentum.
            let last = traj.frames.last().unwrap();
            assert!((last[0].v - traj.frames[0][0].v).norm() > 0.1);
            // Angular momentum about the origin (orbital + spin) is conserved too.
            let l = |k: usize| {
                traj.frames[k]
                    .iter()
                    .zip(&w.bodies)
                    .fold(geom::Vec3::zero(), |acc, (s, b)| {
                        let r = s.pose.q.to_mat();
                        let spin = r.mul_mat(&b.inertia).mul_mat(&r.transpose()).mul_vec(s.omega);
                        acc + s.pose.t.cross(s.v * b.mass) + spin
                    })
            };
            let l0 = l(0);
            // Positional correction moves bodies without impulse, so allow a small change.
            assert!(
                (l(traj.frames.len() - 1) - l0).norm() < 2e-3 * l0.norm().max(1e-3),
                "{model:?}: angular momentum {:?} vs {l0:?}",
                l(traj.frames.len() - 1)
            );
        }
    }
}
