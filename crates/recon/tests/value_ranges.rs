//! The ranges of fitted contact values say what the motion pins: a box thrown
//! onto the board pins its restitution and its friction; one dropped flat
//! pins its restitution and leaves its friction open. Poses made by the
//! simulator, 1 mm and 1° of noise added, fitted with the multi-start.

use geom::{Pose, Quat, SplitMix64};
use recon::{
    fit_multi_start_bodies, ContactValue, Observed, PhysicsFitConfig, RangeScan, StartContact, StartsOn, ValueRange,
    CONTACT_STARTS,
};
use sim::sdf::{Cuboid, Plane, Shape};
use sim::{BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};

/// A box released 12 cm above the board at `v0`; restitution 0.6, friction 0.3.
fn dropped_box(v0: [f64; 3]) -> World {
    let ground = Shape::Plane(Plane {
        normal: [0.0, 0.0, 1.0],
        offset: 0.0,
    });
    let mut w = World::new(
        SimConfig {
            fps: 30.0,
            frames: 30,
            substeps: 20,
            ..SimConfig::default()
        },
        ground,
    );
    let body = RigidBody::from_shape(
        "box",
        &Shape::Cuboid(Cuboid {
            half: [0.025, 0.02, 0.015],
        }),
        MassSpec::Mass(0.1),
        ContactSampling::Surface { count: 500, seed: 1 },
    )
    .unwrap();
    let c = ContactParams {
        restitution: 0.6,
        friction: 0.3,
    };
    w.add_body(
        body,
        BodyState::new([0.0, 0.0, 0.12], [1.0, 0.0, 0.0, 0.0], v0, [0.0; 3]),
        c,
        c,
    );
    w.validate().unwrap();
    w
}

/// The truth's poses with noise, fitted from 0.5 / 0.5 and the other starts (the launch as `start`
/// allows); the fitted values' ranges.
fn ranges_of(truth: &World, start_contact: StartContact) -> Vec<ValueRange> {
    let mut rng = SplitMix64::new(3);
    let poses: Vec<Pose<f64>> = truth
        .simulate(&truth.params())
        .frames
        .iter()
        .map(|f| {
            let p = f[0].pose;
            let turn = Quat::exp(rng.vec(1f64.to_radians()));
            Pose::new((turn * p.q).normalize_or_identity(), p.t + rng.vec(0.001))
        })
        .collect();
    let mut start = truth.clone();
    start.scene_contact[0] = ContactParams {
        restitution: 0.5,
        friction: 0.5,
    };
    let cfg = PhysicsFitConfig {
        rotation_weight: 0.03,
        fit_initial_pose: true,
        ..PhysicsFitConfig::default()
    };
    let observed = Observed {
        start: start_contact,
        ..Observed::new(0, poses, None)
    };
    let fit = fit_multi_start_bodies(
        cfg,
        start,
        vec![observed],
        &CONTACT_STARTS,
        StartsOn::Scene,
        &mut |_, _| {},
    )
    .unwrap()
    .best;

    fit.contact_value_ranges(RangeScan::default(), &|_, _| {})
}

fn range(ranges: &[ValueRange], friction: bool) -> ValueRange {
    *ranges
        .iter()
        .find(|r| matches!(r.value, ContactValue::SceneFriction(_)) == friction)
        .expect("both values fitted")
}

/// The truth's values' ranges, printed.
fn restitution_and_friction(v0: [f64; 3]) -> (ValueRange, ValueRange, String) {
    let ranges = ranges_of(&dropped_box(v0), StartContact::Free);
    let msg = format!("{ranges:?}");
    eprintln!("{msg}");
    (range(&ranges, false), range(&ranges, true), msg)
}

#[test]
fn a_throw_bounds_both_values() {
    // Measured: restitution 0.600 in 0.45–0.61, friction 0.22 in 0.17–0.41. With the mean-point model's tilt
    // hold (2026-11-30) the refits of the other values at each grid value follow the sliding box better, and
    // the ranges widen: restitution 0.600 in 0.34–0.61, friction 0.22 in 0.17–0.999 (the motion bounds
    // friction from below only).
    let (r, f, msg) = restitution_and_friction([0.6, 0.0, 0.0]);
    assert!(r.contains(0.6) && r.hi - r.lo < 0.3, "{msg}");
    assert!(f.contains(0.3) && f.lo > 0.1, "{msg}");
}

#[test]
fn a_straight_drop_leaves_the_friction_open() {
    // Dropped flat without a sideways speed: it bounces in place, and nothing slides. Measured: restitution
    // 0.61 in 0.48–0.61, friction 0.31 in 0.10–0.999.
    let (r, f, msg) = restitution_and_friction([0.0; 3]);
    assert!(r.contains(0.6) && r.hi - r.lo < 0.2, "{msg}");
    assert!(f.hi - f.lo > 0.8, "nothing slides: {msg}");
}
