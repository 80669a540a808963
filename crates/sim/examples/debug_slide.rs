use sim::sdf::{Cuboid, Plane, Shape};
use sim::*;
fn main() {
    let half = [0.03, 0.03, 0.015];
    let mut w = World::new(
        SimConfig {
            frames: 120,
            ..Default::default()
        },
        Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        }),
    );
    let b = RigidBody::from_shape(
        "box",
        &Shape::Cuboid(Cuboid { half }),
        MassSpec::Mass(0.2),
        ContactSampling::Surface { count: 1000, seed: 7 },
    )
    .unwrap();
    w.add_body(
        b,
        BodyState::new([0.0, 0.0, half[2]], [1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0; 3]),
        ContactParams {
            restitution: 0.3,
            friction: 0.4,
        },
        ContactParams::default(),
    );
    let tr = w.simulate(&w.params());
    for (k, f) in tr.frames.iter().enumerate().step_by(5) {
        let s = f[0];
        println!(
            "{k:3} t=({:.4},{:.5},{:.5}) v=({:.4},{:.4},{:.4}) w=({:.3},{:.3},{:.3}) q=({:.4},{:.4},{:.4},{:.4})",
            s.pose.t.x,
            s.pose.t.y,
            s.pose.t.z,
            s.v.x,
            s.v.y,
            s.v.z,
            s.omega.x,
            s.omega.y,
            s.omega.z,
            s.pose.q.w,
            s.pose.q.x,
            s.pose.q.y,
            s.pose.q.z
        );
    }
}
