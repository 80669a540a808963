//! The two-body schedule on poses the simulator made itself: a box slides
//! into a block at rest and strikes it off-centre (the two-body synth video's
//! motion, analytic shapes), with values between the bodies unlike the
//! board's; from a world whose launch is 50 % slow (the collision frames
//! late) and whose contact values are all 0.5, the schedule finds the
//! collision frame and recovers the launch, the board's friction and the
//! pair's restitution and friction. (A head-on hit, the block's centre 1 cm
//! off the box's line, leaves the bodies sticking during the impact: the
//! pair's friction then changes nothing and no fit can tell it.)

use geom::{Pose, Vec3};
use recon::{fit_colliding_bodies, PhysicsFitConfig};
use sim::sdf::{Cuboid, Plane, Shape};
use sim::{BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};

/// The board's true values, and the pair's (unlike the board's).
const SCENE: ContactParams = ContactParams {
    restitution: 0.4,
    friction: 0.25,
};
const PAIR: ContactParams = ContactParams {
    restitution: 0.7,
    friction: 0.15,
};
/// Where the fits start: every contact value at 0.5.
const HALF: ContactParams = ContactParams {
    restitution: 0.5,
    friction: 0.5,
};

fn world(toy_v: [f64; 3], scene: ContactParams, pair: ContactParams) -> World {
    let ground = Shape::Plane(Plane {
        normal: [0.0, 0.0, 1.0],
        offset: 0.0,
    });
    let mut w = World::new(
        SimConfig {
            fps: 30.0,
            frames: 24,
            substeps: 20,
            ..SimConfig::default()
        },
        ground,
    );
    let body = |name: &str, half: [f64; 3], mass: f64| {
        RigidBody::from_shape(
            name,
            &Shape::Cuboid(Cuboid { half }),
            MassSpec::Mass(mass),
            ContactSampling::Surface { count: 500, seed: 1 },
        )
        .unwrap()
    };
    w.add_body(
        body("toy", [0.03, 0.022, 0.018], 0.08),
        BodyState::new([-0.15, 0.0, 0.0185], [1.0, 0.0, 0.0, 0.0], toy_v, [0.0; 3]),
        scene,
        pair,
    );
    w.add_body(
        body("block", [0.025, 0.025, 0.02], 0.1),
        BodyState::new([0.05, 0.02, 0.0205], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]),
        scene,
        pair,
    );
    w.validate().unwrap();
    w
}

#[test]
#[ignore = "slow: the collision schedule finds the collision frame and both contacts' values from poses, ~43 s"]
fn finds_the_collision_and_the_values_of_both_contacts() {
    let (scene, pair) = (SCENE, PAIR);
    let truth = world([1.3, 0.0, 0.0], scene, pair);
    let traj = truth.simulate(&truth.params());
    let touch = traj
        .contacts
        .iter()
        .position(|c| c.pairs[0])
        .expect("the box reaches the block");
    let poses: Vec<Vec<Pose<f64>>> = (0..2)
        .map(|b| traj.frames.iter().map(|f| f[b].pose).collect())
        .collect();
    let moved = (poses[1][23].t - poses[1][0].t).norm();
    assert!(moved > 0.02, "the block must be knocked on ({moved} m)");

    let start = world([0.65, 0.0, 0.0], HALF, HALF);
    let weights = vec![vec![1.0; 24]; 2];
    let t0 = std::time::Instant::now();
    let fit = fit_colliding_bodies(
        &PhysicsFitConfig {
            fit_initial_pose: true,
            // Rotations in metres at the bodies' size, as `fit` weighs them.
            rotation_weight: 0.03,
            ..PhysicsFitConfig::default()
        },
        true,
        start,
        recon::ObservedBodies::new(poses.clone(), weights),
        recon::LaunchSettings {
            frames: 3,
            in_plane: true,
        },
        &mut |_, _, _| {},
    )
    .unwrap();
    let secs = t0.elapsed().as_secs_f64();
    let w = &fit.world;
    let v = Vec3::cst(w.initial[0].v.to_array());
    let msg = format!(
        "contacts {:?} (simulator: {touch}); v0 {:?}; scene {:?}; pair {:?}; {secs:.1} s; steps {:?}",
        fit.contacts,
        v.to_array(),
        w.scene_contact[0],
        w.pair_contact[0],
        fit.steps
            .iter()
            .map(|s| (s.label.clone(), s.winner, s.loss))
            .collect::<Vec<_>>()
    );
    eprintln!("{msg}");
    assert_eq!(fit.contacts.len(), 1, "{msg}");
    assert!((fit.contacts[0].1 as i64 - touch as i64).abs() <= 1, "{msg}");
    // Measured (2026-11-25): frame 4 as the simulator's; v0 0.5 % off; board friction 0.253; pair 0.707 and
    // 0.150; every pose within 1 mm; 17 s. With the mean-point model's tilt hold (2026-11-30): v0 0.07 %
    // off, board friction 0.2500, pair 0.703 and 0.1506 (48 s beside other work).
    assert!((v - Vec3::new(1.3, 0.0, 0.0)).norm() < 0.05 * 1.3, "{msg}");
    assert!((w.pair_contact[0].restitution - pair.restitution).abs() < 0.1, "{msg}");
    assert!((w.pair_contact[0].friction - pair.friction).abs() < 0.1, "{msg}");
    assert!((w.scene_contact[0].friction - scene.friction).abs() < 0.1, "{msg}");
    assert_eq!(w.scene_contact[0], w.scene_contact[1], "one board, one pair of values");
    let sim = w.simulate(&w.params());
    for b in 0..2 {
        let worst = sim
            .frames
            .iter()
            .zip(&poses[b])
            .map(|(f, p)| (f[b].pose.t - p.t).norm())
            .fold(0.0, f64::max);
        assert!(worst < 0.002, "body {b}: worst {:.2} mm; {msg}", worst * 1e3);
    }
}

/// GA-like poses of `truth`'s motion: each frame jittered by a few tenths of a millimetre across the line of
/// sight from `eye`, a millimetre along it and a few tenths of a degree (a fixed pseudo-random sequence).
fn jittered(poses: &[Vec<Pose<f64>>], eye: Vec3<f64>) -> Vec<Vec<Pose<f64>>> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    poses
        .iter()
        .map(|seq| {
            seq.iter()
                .map(|p| {
                    let sight = (p.t - eye).normalize_or(Vec3::new(0.0, 0.0, -1.0));
                    let across = Vec3::new(next(), next(), next()) * 0.0003;
                    let across = across - sight * across.dot(sight);
                    let t = p.t + across + sight * (0.001 * next());
                    let turn = Vec3::new(next(), next(), next()) * 0.3f64.to_radians();
                    Pose::new(geom::Quat::exp(turn) * p.q, t)
                })
                .collect()
        })
        .collect()
}

/// The push seen as GA sees it: the truth's world and motion, the frame of the collision, the exact poses,
/// and the jittered poses observed from the two-body video's camera at its small size (160 × 120, 0.5 m
/// off) with one image's precision at the toy (the launch window's noise floor, as `fit` gives it), the
/// bodies at rest settled.
struct Push {
    truth: World,
    touch: usize,
    exact: Vec<Vec<Pose<f64>>>,
    eye: Vec3<f64>,
    observed: recon::ObservedBodies,
    rests: Vec<Option<recon::RestingStart>>,
}

fn push() -> Push {
    let truth = world([1.3, 0.0, 0.0], SCENE, PAIR);
    let traj = truth.simulate(&truth.params());
    let touch = traj.contacts.iter().position(|c| c.pairs[0]).unwrap();
    let exact: Vec<Vec<Pose<f64>>> = (0..2)
        .map(|b| traj.frames.iter().map(|f| f[b].pose).collect())
        .collect();
    let camera = geom::Camera::look_at(
        Vec3::new(0.0, -0.4, 0.35),
        Vec3::new(0.0, 0.0, 0.02),
        Vec3::new(0.0, 0.0, 1.0),
        geom::Intrinsics::centred(200.0, 160, 120),
        160,
        120,
    );
    let eye = camera.center();
    let diameter = 2.0 * truth.bodies[0].bounding_radius;
    let mut observed = recon::ObservedBodies {
        eye: Some(eye.to_array()),
        precision: Some(recon::ImagePrecision::of(&camera, &exact[0][0], diameter).across),
        ..recon::ObservedBodies::new(jittered(&exact, eye), vec![vec![1.0; 24]; 2])
    };
    let rests = observed.settle_resting(&truth, &camera).to_vec();
    Push {
        truth,
        touch,
        exact,
        eye,
        observed,
        rests,
    }
}

#[test]
#[ignore = "slow: the collision schedule on jittered poses with a block at rest until struck, ~40 s"]
fn a_block_at_rest_until_struck_starts_at_rest_on_the_board() {
    let Push {
        touch,
        exact,
        observed,
        rests,
        ..
    } = push();
    assert!(rests[0].is_none(), "the toy slides from the start: {:?}", rests[0]);
    let rest = rests[1].expect("the block rests until struck");
    assert!(
        rest.frames >= 3 && rest.frames <= touch + 1,
        "still frames {} (struck in frame {touch})",
        rest.frames
    );
    let start = world([0.65, 0.0, 0.0], HALF, HALF);
    let fit = fit_colliding_bodies(
        &PhysicsFitConfig {
            fit_initial_pose: true,
            rotation_weight: 0.03,
            ..PhysicsFitConfig::default()
        },
        true,
        start,
        observed,
        recon::LaunchSettings {
            frames: 3,
            in_plane: true,
        },
        &mut |_, _, _| {},
    )
    .unwrap();
    let w = &fit.world;
    let block = w.initial[1];
    let msg = format!(
        "block start {:?}, v {:?}, omega {:?}; toy v {:?}; contacts {:?}",
        block.pose, block.v, block.omega, w.initial[0].v, fit.contacts
    );
    // No launch at all, and its resting pose: flat on the board, where the truth rests (the still frames'
    // mean: their jitter averages out; the truth starts half a millimetre over the board and rests on it
    // from the frame after).
    assert_eq!(block.v.to_array(), [0.0; 3], "{msg}");
    assert_eq!(block.omega.to_array(), [0.0; 3], "{msg}");
    let truth_block = exact[1][touch - 1];
    assert!((block.pose.t - truth_block.t).norm() < 0.0005, "{msg}");
    let turned = (block.pose.q * truth_block.q.conj())
        .normalize_or_identity()
        .log()
        .norm();
    assert!(
        turned < 0.3f64.to_radians(),
        "turned {:.3}°; {msg}",
        turned.to_degrees()
    );
    let sim = w.simulate(&w.params());
    for (k, f) in sim.frames.iter().enumerate().take(touch) {
        let moved = (f[1].pose.t - block.pose.t).norm();
        assert!(
            moved < 2e-4,
            "frame {k}: the resting block moved {:.2} mm; {msg}",
            moved * 1e3
        );
    }
    let v = Vec3::cst(w.initial[0].v.to_array());
    assert!((v - Vec3::new(1.3, 0.0, 0.0)).norm() < 0.05 * 1.3, "{msg}");
    // The launch window: the frames before the collision, the toy's launch alone (its pose, v0 along the
    // board, ω0 about its normal, the board's two values: 11; the resting block's three would make 14), and
    // a launch within 5 % of the truth's stands against them.
    let window = fit.window.as_ref().expect("four frames before the collision");
    assert_eq!(window.frames, fit.contacts[0].1, "{msg}");
    assert_eq!(window.unknowns, 11, "{msg}");
    assert!(
        !window.bent(),
        "χ² {:.1} against {:.1}; {msg}",
        window.statistic,
        window.critical
    );
}

/// The launch window's test and the schedule that holds what it tells: on GA-like poses of the push, the
/// true world's launches stand against the frames before the collision, a toy's launch 8 % fast misses them,
/// and the schedule with the launches the window tells held keeps them exactly and finds the pair's values
/// around them.
#[test]
fn a_launch_the_frames_before_the_collision_refute_is_caught_and_can_be_held() {
    let Push {
        truth,
        touch,
        observed,
        rests,
        eye,
        ..
    } = push();
    let rest = rests[1].expect("the block rests until struck");
    let cfg = PhysicsFitConfig {
        fit_initial_pose: true,
        rotation_weight: 0.03,
        ..PhysicsFitConfig::default()
    };
    // What the schedule's window fits: the launches and the board's values, no pair's.
    let window_cfg = PhysicsFitConfig {
        fit_pair_restitution: false,
        fit_pair_friction: false,
        ..cfg.clone()
    };
    // The launched toy alone, as the schedule tests it (the resting block holds its pose: nothing to test).
    let obs = [recon::Observed {
        eye: Some(eye.to_array()),
        start: recon::video_fit::launch_start(&truth.bodies[0], &truth.scene, &observed.poses[0][0], true),
        ..recon::Observed::new(0, observed.poses[0].clone(), Some(vec![1.0; 24]))
    }];
    let mut true_start = truth.clone();
    true_start.initial[1].pose = rest.pose;
    // One image's precision across the line of sight at the toy (a quarter pixel: 0.6 mm here).
    let precision = observed.precision.expect("the push's floor");
    let stands = recon::check_window(&window_cfg, &true_start, &obs, touch, Some(precision))
        .unwrap()
        .expect("a window of four frames");
    assert!(
        !stands.bent(),
        "the true launch: χ² {:.1} against {:.1}",
        stands.statistic,
        stands.critical
    );
    let mut fast = true_start.clone();
    fast.initial[0].v = fast.initial[0].v * 1.08;
    let check = recon::check_window(&window_cfg, &fast, &obs, touch, Some(precision))
        .unwrap()
        .unwrap();
    assert!(
        check.bent(),
        "8 % fast: χ² {:.1} against {:.1}",
        check.statistic,
        check.critical
    );
    let window_v = Vec3::cst(check.flight_world.initial[0].v.to_array());
    assert!(
        (window_v - Vec3::new(1.3, 0.0, 0.0)).norm() < 0.03 * 1.3,
        "the window's own launch {:?}",
        window_v.to_array()
    );
    // The held schedule from the window's world with the contact values all at 0.5 and the grid of starts (as
    // `fit` runs it): it must find the pair's.
    let mut from = check.flight_world.clone();
    from.pair_contact = vec![HALF];
    from.scene_contact = vec![HALF; 2];
    let held = recon::fit_colliding_bodies_holding_launch(
        &cfg,
        true,
        &from,
        observed,
        recon::LaunchSettings {
            frames: 3,
            in_plane: true,
        },
        &mut |_, _, _| {},
    )
    .unwrap();
    let w = &held.world;
    for b in 0..2 {
        assert_eq!(w.initial[b], from.initial[b], "body {b}'s launch held");
    }
    assert!(held.window.is_none(), "a held fit is not tested again");
    let msg = format!("pair {:?}, scene {:?}", w.pair_contact[0], w.scene_contact[0]);
    assert!((w.pair_contact[0].restitution - PAIR.restitution).abs() < 0.1, "{msg}");
    assert!((w.pair_contact[0].friction - PAIR.friction).abs() < 0.1, "{msg}");
}
