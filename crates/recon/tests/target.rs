//! Target reaching (Fig. 7): a body on one side of an obstacle reaches a point
//! behind it at frame N within 5 mm in at most 50 iterations.
use geom::{Pose, Vec3};
use recon::{TargetConfig, TargetReach};
use sim::sdf::{Cuboid, Plane, Shape};
use sim::{BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};

#[test]
fn reaches_a_target_behind_an_obstacle() {
    let ground = Shape::Plane(Plane {
        normal: [0.0, 0.0, 1.0],
        offset: 0.0,
    });
    let wall = Shape::Cuboid(Cuboid {
        half: [0.02, 0.3, 0.06],
    })
    .transformed(Pose::from_translation(Vec3::new(0.25, 0.0, 0.06)));
    let mut w = World::new(
        SimConfig {
            fps: 60.0,
            frames: 51,
            substeps: 10,
            ..SimConfig::default()
        },
        Shape::Union(vec![ground, wall.clone()]),
    );
    let body = RigidBody::from_shape(
        "toy",
        &Shape::Cuboid(Cuboid {
            half: [0.02, 0.02, 0.02],
        }),
        MassSpec::Mass(0.1),
        ContactSampling::Surface { count: 500, seed: 2 },
    )
    .unwrap();
    let c = ContactParams {
        restitution: 0.3,
        friction: 0.4,
    };
    // Start: pushed gently towards the wall, it cannot clear it.
    w.add_body(
        body,
        BodyState::new([0.0, 0.0, 0.02], [1.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0; 3]),
        c,
        c,
    );
    let target = Vec3::new(0.5, 0.05, 0.02);
    let mut stage = TargetReach::new(TargetConfig::default(), w.clone(), 0, target, 50).unwrap();
    let start = stage.distance();
    let stats = stage.run();
    let d = stage.distance();
    assert!(
        d < 5e-3,
        "ended {d} m from the target after {} iterations (start {start} m)",
        stats.len()
    );
    assert!(stats.len() <= 50);
    // The found trajectory really passes over the wall: the body never enters it.
    let solved = stage.solved_world();
    let traj = solved.simulate(&solved.params());
    use sim::sdf::Sdf;
    let crossed = traj.frames.iter().any(|f| f[0].pose.t.x > 0.3);
    assert!(crossed);
    for f in &traj.frames {
        assert!(
            wall.distance_local(f[0].pose.t) > 0.0,
            "the centre went through the wall"
        );
    }
}
