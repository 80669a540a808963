use sim::sdf::{Cuboid, Plane, Shape};
use sim::tessellate::cuboid_mesh;
use sim::*;
fn main() {
    let c = Cuboid {
        half: [0.03, 0.02, 0.015],
    };
    let b = RigidBody::from_mesh(
        "box",
        &cuboid_mesh(&c, 1),
        MassSpec::Mass(0.2),
        ContactSampling::Vertices,
        Some(Shape::Cuboid(c)),
    )
    .unwrap();
    let mut w = World::new(
        SimConfig {
            frames: 14,
            ..Default::default()
        },
        Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        }),
    );
    let cp = ContactParams {
        restitution: 0.4,
        friction: 0.3,
    };
    w.add_body(
        b,
        BodyState::new(
            [0.0, 0.0, 0.06],
            [0.93, 0.25, 0.2, 0.18],
            [0.8, 0.2, -1.0],
            [1.0, -2.0, 0.5],
        ),
        cp,
        cp,
    );
    let p = w.params();
    let col: usize = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(2);
    let g = simulate_with_gradients(&w, &p, &[col]);
    for eps in [1e-6, 1e-7, 1e-8] {
        let mut pp = p.clone();
        pp[col] += eps;
        let a = w.simulate(&pp);
        let mut pm = p.clone();
        pm[col] -= eps;
        let b = w.simulate(&pm);
        println!("eps {eps}");
        for k in 0..g.frames.len() {
            let fd = (a.frames[k][0].pose.t.z - b.frames[k][0].pose.t.z) / (2.0 * eps);
            let fdx = (a.frames[k][0].v.x - b.frames[k][0].v.x) / (2.0 * eps);
            println!(
                "{k:2} contact={} z={:.5} dz: an {:.6} fd {:.6} | dvx: an {:.6} fd {:.6}",
                g.contacts[k].scene[0],
                g.frames[k][0].pose.t.z,
                g.d(k, 0, 2, 0),
                fd,
                g.d(k, 0, 7, 0),
                fdx
            );
        }
    }
}
