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
    let (fit, _, _) = fitted(truth, start_contact);
    fit.contact_value_ranges(RangeScan::default(), &|_, _| {})
}

/// The multi-start's winner on the truth's poses with noise, with its settings and observations.
fn fitted(truth: &World, start_contact: StartContact) -> (recon::PhysicsFit, PhysicsFitConfig, Observed) {
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
        cfg.clone(),
        start,
        vec![observed.clone()],
        &CONTACT_STARTS,
        StartsOn::Scene,
        &mut |_, _| {},
    )
    .unwrap()
    .best;
    (fit, cfg, observed)
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
    // 0.61 in 0.48–0.61, friction 0.31 in 0.10–0.999; with the bar from the best loss the profiles saw (below),
    // 0.53–0.61 and 0.13–0.999.
    let (r, f, msg) = restitution_and_friction([0.0; 3]);
    assert!(r.contains(0.6) && r.hi - r.lo < 0.2, "{msg}");
    assert!(f.hi - f.lo > 0.8, "nothing slides: {msg}");
}

/// A world handed in that is not the objective's optimum (its launch 20 % slow, as a world kept from a fit with
/// other settings): the profiles' refits find better next to the fitted values, and the bar comes from that,
/// not from the handed-in world's misfit (from which every value was within the bar: the backdrop's slide,
/// restitution 0.00–0.86 and friction 0.04–0.62 where the truth's grid gave 0.37–0.53 and 0.23–0.26).
#[test]
fn the_bar_comes_from_the_best_loss_the_profiles_see() {
    let truth = dropped_box([0.6, 0.0, 0.0]);
    let (fit, cfg, observed) = fitted(&truth, StartContact::Free);
    let mut slow = fit.fitted_world();
    slow.initial[0].v = slow.initial[0].v * 0.8;
    let cfg = PhysicsFitConfig {
        fit_initial_pose: false,
        ..cfg
    };
    let ranges = recon::contact_value_ranges(&cfg, slow, vec![observed], RangeScan::default(), &|_, _| {}).unwrap();
    // Measured: restitution 0.31–0.67, friction 0.097–0.83 (the profiles' first refits start from the slow
    // launch: wider than the fitted world's 0.35–0.61 and 0.18–0.999); with the bar from the handed-in world's
    // misfit, 0.001–0.92 and 0.026–0.999. (Before the handed-in world kept its own initial orientation, the
    // ranges were simulated from the first observed pose's: 0.26–0.66 and 0.14–0.72.)
    let (r, f) = (range(&ranges, false), range(&ranges, true));
    assert!(r.contains(0.6) && r.lo > 0.15 && r.hi < 0.8, "{ranges:?}");
    assert!(f.lo > 0.05, "{ranges:?}");
}

/// A kept world handed to the checks after PGA (the value ranges, the flight test: both rebuild a fit around
/// it, which takes the initial pose from the first observed one) is simulated from its own initial
/// orientation, not from the first observed pose's (PGA fits the initial pose a degree or so away from GA's
/// first frame): its own poses, the first seen 3° turned and weighed zero, are missed by nothing over the
/// flight. Simulated from the first observed orientation, as before 2026-12-01, every frame of the flight
/// was missed by the turn.
#[test]
fn a_world_handed_in_is_simulated_from_its_own_initial_orientation() {
    let world = dropped_box([0.6, 0.0, 0.0]);
    let poses: Vec<Pose<f64>> = world
        .simulate(&world.params())
        .frames
        .iter()
        .map(|f| f[0].pose)
        .collect();
    let mut seen = poses.clone();
    seen[0].q = Quat::exp(geom::Vec3::new(0.0, 3f64.to_radians(), 0.0)) * seen[0].q;
    let mut weights = vec![1.0; seen.len()];
    weights[0] = 0.0;
    let observed = vec![Observed::new(0, seen, Some(weights))];
    let check = recon::check_flight(&PhysicsFitConfig::default(), &world, &observed)
        .unwrap()
        .expect("the box flies before it lands");
    assert!(check.frames >= 3, "a flight of {} frames", check.frames);
    assert!(
        check.joint_squares < 1e-12,
        "its own poses missed over the flight: {}",
        check.joint_squares
    );
}

/// Two boxes thrown 30 cm apart never touch: no contact of the simulation uses their pair's values, so
/// their ranges are the bounds, said without a refit (the progress counts only the scene values' refits),
/// and the scene's values are still profiled.
#[test]
fn a_pair_that_never_touches_has_its_bounds_without_a_refit() {
    let mut world = dropped_box([0.6, 0.0, 0.0]);
    let second = world.bodies[0].clone();
    let c = world.scene_contact[0];
    world.add_body(
        second,
        BodyState::new([0.0, 0.3, 0.10], [1.0, 0.0, 0.0, 0.0], [-0.4, 0.0, 0.0], [0.0; 3]),
        c,
        c,
    );
    world.validate().unwrap();
    let trajectory = world.simulate(&world.params());
    assert!(
        trajectory.contacts.iter().all(|c| c.pairs.iter().all(|&p| !p)),
        "the boxes touch"
    );
    let observed: Vec<Observed> = (0..2)
        .map(|b| Observed::new(b, trajectory.frames.iter().map(|f| f[b].pose).collect(), None))
        .collect();
    let cfg = PhysicsFitConfig {
        rotation_weight: 0.03,
        ..PhysicsFitConfig::default()
    };
    let scan = RangeScan {
        steps: 5,
        iterations: 2,
    };
    let most = std::sync::atomic::AtomicUsize::new(0);
    let ranges = recon::contact_value_ranges(&cfg, world, observed, scan, &|_, total| {
        most.fetch_max(total, std::sync::atomic::Ordering::Relaxed);
    })
    .unwrap();
    assert_eq!(ranges.len(), 4, "{ranges:?}");
    let (lo, hi) = (cfg.bound_margin, 1.0 - cfg.bound_margin);
    for r in &ranges {
        match r.value {
            ContactValue::PairRestitution(0) | ContactValue::PairFriction(0) => {
                assert_eq!((r.lo, r.hi), (lo, hi), "{ranges:?}")
            }
            _ => assert!(
                r.contains(r.fitted) && r.hi - r.lo < hi - lo,
                "the scene's value unbounded: {ranges:?}"
            ),
        }
    }
    let refits = most.load(std::sync::atomic::Ordering::Relaxed);
    assert!(
        (1..=2 * scan.steps).contains(&refits),
        "{refits} refits for two values of five grid values"
    );
}
