//! A ball launched rolling on a plane rolls on: rolling without slipping
//! loses no energy, so it neither slows nor hops. Its contact points are
//! samples of its surface; rolled over as they are, they make a polyhedron
//! that knocks at every sample, slows the ball and bounces it off the board
//! (`support_points = false`, the default: 0.9 → 0.5 m/s in a second, hops of millimetres).
mod common;
use common::*;
use sim::{BodyState, ContactSampling, MassSpec, RigidBody, SimConfig};

const RADIUS: f64 = 0.02;

fn roll(cfg: SimConfig, points: usize) -> (f64, f64, f64) {
    roll_body(cfg, sphere_body(RADIUS, 0.1, points))
}

fn with_supports(model: sim::ContactModel) -> SimConfig {
    SimConfig {
        support_points: true,
        ..config_in(model, 30.0, 31, 20)
    }
}

/// Height above rest at worst, speed after 1 s and slip then.
fn roll_body(cfg: SimConfig, ball: RigidBody) -> (f64, f64, f64) {
    let radius = RADIUS;
    let v0 = 0.9;
    let w = world_with(
        cfg,
        ground(),
        vec![(
            ball,
            BodyState::new(
                [0.0, 0.0, radius],
                [1.0, 0.0, 0.0, 0.0],
                [v0, 0.0, 0.0],
                [0.0, v0 / radius, 0.0],
            ),
            contact(0.5, 0.3),
        )],
    );
    let traj = w.simulate(&w.params());
    let hop = traj
        .frames
        .iter()
        .map(|f| (f[0].pose.t.z - radius).abs())
        .fold(0.0, f64::max);
    let last = traj.frames.last().unwrap()[0];
    let slip = (last.v.x - last.omega.y * radius).abs();
    (hop, last.v.x, slip)
}

#[test]
fn a_rolling_ball_neither_slows_nor_hops() {
    for model in MODELS {
        for points in [500, 2000] {
            let (hop, v, slip) = roll(with_supports(model), points);
            eprintln!(
                "{model:?} {points} points: hop {:.3} mm, speed after 1 s {v:.3} m/s, slip {slip:.4} m/s",
                hop * 1e3
            );
            assert!(
                hop < 3e-4,
                "{model:?}, {points} points: the ball hops {:.2} mm",
                hop * 1e3
            );
            assert!(
                (v - 0.9).abs() < 0.03,
                "{model:?}, {points} points: speed {v:.3} m/s after 1 s (launched at 0.9)"
            );
            assert!(slip < 0.02, "{model:?}, {points} points: slips at {slip:.3} m/s");
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
        let (hop, v, slip) = roll_body(with_supports(model), ball.clone());
        eprintln!(
            "{model:?} grid: hop {:.3} mm, speed after 1 s {v:.3} m/s, slip {slip:.4} m/s",
            hop * 1e3
        );
        assert!(hop < 3e-4, "{model:?}: the ball hops {:.2} mm", hop * 1e3);
        assert!(
            (v - 0.9).abs() < 0.03,
            "{model:?}: speed {v:.3} m/s after 1 s (launched at 0.9)"
        );
        assert!(slip < 0.02, "{model:?}: slips at {slip:.3} m/s");
    }
}

#[test]
fn rolled_over_its_samples_the_ball_slows() {
    // The reason for the supports, measured: without them the polyhedron of samples loses speed.
    let cfg = SimConfig {
        support_points: false,
        ..config_in(sim::ContactModel::MeanPoint, 30.0, 31, 20)
    };
    let (_, v, _) = roll(cfg, 500);
    assert!(v < 0.8, "speed {v:.3} m/s");
}
