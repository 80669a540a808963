//! How a simulated box converges in its step size, for each contact model: the largest difference over 30
//! frames (translation plus the bounding radius times the turn, mm) between S and 2S substeps, for a slide,
//! a flat drop, a drop tilted 6° and a tumble (docs/notebook/physics-trust.md).
//!
//! `cargo run --release -p sim --example step_convergence [RESTITUTION_THRESHOLD_M_S]`

use geom::{Quat, Vec3};
use sim::sdf::{Cuboid, Plane, Shape};
use sim::{BodyState, ContactModel, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};

fn world(model: ContactModel, substeps: usize, threshold: Option<f64>, initial: BodyState<f64>) -> World {
    let board = Shape::Plane(Plane {
        normal: [0.0, 0.0, 1.0],
        offset: 0.0,
    });
    let config = SimConfig {
        fps: 30.0,
        frames: 30,
        substeps,
        contact_model: model,
        restitution_threshold: threshold,
        ..SimConfig::default()
    };
    let mut w = World::new(config, board);
    let body = RigidBody::from_shape(
        "box",
        &Shape::Cuboid(Cuboid {
            half: [0.03, 0.02, 0.015],
        }),
        MassSpec::Mass(0.08),
        ContactSampling::Surface { count: 400, seed: 1 },
    )
    .expect("a box is a valid body");
    let c = ContactParams {
        restitution: 0.4,
        friction: 0.3,
    };
    w.add_body(body, initial, c, c);
    w
}

/// Per frame, how far `substeps` and twice as many draw the box apart, mm.
fn spread(model: ContactModel, substeps: usize, threshold: Option<f64>, initial: BodyState<f64>) -> Vec<f64> {
    let a = world(model, substeps, threshold, initial);
    let b = world(model, 2 * substeps, threshold, initial);
    let (ta, tb) = (a.simulate(&a.params()), b.simulate(&b.params()));
    let r = a.bodies[0].bounding_radius;
    ta.frames
        .iter()
        .zip(&tb.frames)
        .map(|(x, y)| {
            let (pa, pb) = (x[0].pose.re(), y[0].pose.re());
            let turn = (pb.q * pa.q.conj()).normalize_or_identity().log().norm();
            1000.0 * ((pb.t - pa.t).norm() + r * turn)
        })
        .collect()
}

fn main() {
    let threshold: Option<f64> = std::env::args().nth(1).map(|s| s.parse().expect("a speed in m/s"));
    let flat = BodyState::new([0.0, 0.0, 0.1], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]);
    let tilt = Quat::exp(Vec3::new(0.1, 0.05, 0.0)).to_array();
    let tilted = BodyState::new([0.0, 0.0, 0.1], tilt, [0.3, 0.0, 0.0], [0.0; 3]);
    let corner = Quat::exp(Vec3::new(0.5, 0.4, 0.2)).to_array();
    let tumble = BodyState::new([0.0, 0.0, 0.12], corner, [0.2, 0.0, 0.0], [6.0, -4.0, 3.0]);
    let slide = BodyState::new(
        [-0.1, 0.0, 0.015],
        [1.0, 0.0, 0.0, 0.0],
        [0.8, 0.0, 0.0],
        [0.0, 0.0, 2.0],
    );
    for (name, initial) in [
        ("slide", slide),
        ("flat drop", flat),
        ("tilted drop", tilted),
        ("tumble", tumble),
    ] {
        for model in [ContactModel::MeanPoint, ContactModel::MultiPoint] {
            let mut row = format!("{name:12} {model:?}:");
            for s in [10, 20, 40, 80, 160] {
                let d = spread(model, s, threshold, initial);
                let worst = d.iter().copied().fold(0.0, f64::max);
                let first = d.iter().position(|&x| x > 1.0).map_or("-".into(), |f| f.to_string());
                row += &format!("  {s} v {}: {worst:6.2} mm (> 1 mm from frame {first})", 2 * s);
            }
            println!("{row}");
        }
    }
}
