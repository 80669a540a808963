//! A ball launched rolling on a plane rolls on: rolling without slipping
//! loses no energy, so it neither slows nor hops. Its contact points are
//! samples of its surface; rolled over as they are, they make a polyhedron
//! that knocks at every sample, slows the ball and bounces it off the board
//! (`support_points = false`, the default: 0.9 → 0.5 m/s in a second, hops of millimetres).
use crate::common;
use common::*;
use sim::{BodyState, ContactSampling, MassSpec, RigidBody, SimConfig};

const RADIUS: f64 = 0.02;

fn roll(cfg: SimConfig, points: usize) -> Rolled {
    roll_body(cfg, sphere_body(RADIUS, 0.1, points), [1.0, 0.0, 0.0, 0.0])
}

fn with_supports(model: sim::ContactModel) -> SimConfig {
    SimConfig {
        support_points: true,
        ..config_in(model, 30.0, 31, 20)
    }
}

/// How a body of radius [`RADIUS`] launched rolling along x (about y) went over one second.
struct Rolled {
    /// Height above rest at worst, m.
    hop: f64,
    /// Speed after 1 s, m/s.
    speed: f64,
    /// Slip of the contact then, m/s.
    slip: f64,
}

impl Rolled {
    /// It neither hopped, nor slowed, nor slipped (rolling without slipping loses no energy).
    fn assert_rolls(&self, what: &str) {
        let Rolled { hop, speed, slip } = *self;
        eprintln!(
            "{what}: hop {:.3} mm, speed after 1 s {speed:.3} m/s, slip {slip:.4} m/s",
            hop * 1e3
        );
        assert!(hop < 3e-4, "{what}: hops {:.2} mm", hop * 1e3);
        assert!(
            (speed - 0.9).abs() < 0.03,
            "{what}: speed {speed:.3} m/s after 1 s (launched at 0.9)"
        );
        assert!(slip < 0.02, "{what}: slips at {slip:.3} m/s");
    }
}

fn roll_body(cfg: SimConfig, body: RigidBody, q: [f64; 4]) -> Rolled {
    let v0 = 0.9;
    let w = world_with(
        cfg,
        ground(),
        vec![(
            body,
            BodyState::new([0.0, 0.0, RADIUS], q, [v0, 0.0, 0.0], [0.0, v0 / RADIUS, 0.0]),
            contact(0.5, 0.3),
        )],
    );
    let traj = w.simulate(&w.params());
    let hop = traj
        .frames
        .iter()
        .map(|f| (f[0].pose.t.z - RADIUS).abs())
        .fold(0.0, f64::max);
    let last = traj.frames.last().unwrap()[0];
    Rolled {
        hop,
        speed: last.v.x,
        slip: (last.v.x - last.omega.y * RADIUS).abs(),
    }
}

#[test]
fn a_rolling_ball_neither_slows_nor_hops() {
    for model in MODELS {
        for points in [500, 2000] {
            roll(with_supports(model), points).assert_rolls(&format!("{model:?}, {points} points"));
        }
    }
}

/// The ball as a reconstructed object is: a mesh whose SDF is a baked grid (its trilinear normal jumps
/// from cell to cell; the supports are found on a smoothed one).
#[test]
fn a_rolling_ball_from_a_mesh_and_its_grid_rolls_too() {
    let sphere = sim::sdf::Shape::Sphere(sim::sdf::Sphere { radius: RADIUS });
    let mesh = sim::tessellate::shape_mesh(&sphere, 48).unwrap();
    let ball = RigidBody::from_mesh(
        "ball",
        &mesh,
        MassSpec::Mass(0.1),
        ContactSampling::Surface { count: 500, seed: 3 },
        None,
    )
    .unwrap();
    assert!(matches!(ball.sdf, sim::sdf::Shape::Grid(_)));
    for model in MODELS {
        roll_body(with_supports(model), ball.clone(), [1.0, 0.0, 0.0, 0.0]).assert_rolls(&format!("{model:?} grid"));
    }
}

/// A capsule lying on its side rolls across its axis: curved one way, straight along the axis, so its
/// supports slide round the cylinder only (the shape operator's flat direction takes no step).
#[test]
fn a_capsule_rolling_across_its_axis_rolls_too() {
    let capsule = RigidBody::from_shape(
        "capsule",
        &sim::sdf::Shape::Capsule(sim::sdf::Capsule {
            half_length: 0.03,
            radius: RADIUS,
        }),
        MassSpec::Mass(0.1),
        ContactSampling::Surface { count: 1000, seed: 5 },
    )
    .unwrap();
    // Its axis (z) turned onto y.
    let lying = [
        std::f64::consts::FRAC_1_SQRT_2,
        std::f64::consts::FRAC_1_SQRT_2,
        0.0,
        0.0,
    ];
    for model in MODELS {
        roll_body(with_supports(model), capsule.clone(), lying).assert_rolls(&format!("{model:?} capsule"));
    }
}

#[test]
fn rolled_over_its_samples_the_ball_slows() {
    // The reason for the supports, measured: without them the polyhedron of samples loses speed.
    let cfg = SimConfig {
        support_points: false,
        ..config_in(sim::ContactModel::MeanPoint, 30.0, 31, 20)
    };
    let speed = roll(cfg, 500).speed;
    assert!(speed < 0.8, "speed {speed:.3} m/s");
}
