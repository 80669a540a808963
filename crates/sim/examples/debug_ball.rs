use sim::sdf::{Plane, Shape, Sphere};
use sim::*;
fn main() {
    let mut w = World::new(
        SimConfig {
            frames: 121,
            ..Default::default()
        },
        Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        }),
    );
    let b = RigidBody::from_shape(
        "ball",
        &Shape::Sphere(Sphere { radius: 0.03 }),
        MassSpec::Mass(0.1),
        ContactSampling::Surface { count: 1000, seed: 3 },
    )
    .unwrap();
    w.add_body(
        b,
        BodyState::new([0.0, 0.0, 0.03], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]),
        ContactParams {
            restitution: 0.5,
            friction: 0.5,
        },
        ContactParams::default(),
    );
    let tr = w.simulate(&w.params());
    for (k, f) in tr.frames.iter().enumerate().step_by(10) {
        let s = f[0];
        println!(
            "{k:3} t=({:.5},{:.5},{:.5}) v=({:.4},{:.4},{:.4}) w=({:.3},{:.3},{:.3}) c={}",
            s.pose.t.x,
            s.pose.t.y,
            s.pose.t.z,
            s.v.x,
            s.v.y,
            s.v.z,
            s.omega.x,
            s.omega.y,
            s.omega.z,
            tr.contacts[k].scene[0]
        );
    }
}
