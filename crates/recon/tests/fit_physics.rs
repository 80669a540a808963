//! The PGA step recovers v0 (within 1 %) and k_n, mu (within 0.02) of a body
//! from a pose sequence the simulator made itself, starting 50 % off; and
//! from poses seen by one camera (their depth noisy), weighing depth least.
use geom::{Pose, Vec3};
use recon::{fit_multi_start, PhysicsFit, PhysicsFitConfig};
use sim::sdf::{Cuboid, Plane, Shape};
use sim::{BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};

/// A box thrown onto the table: it bounces (k_n), slides (mu) and hits a wall.
pub fn tabletop(v0: [f64; 3], omega0: [f64; 3], c: ContactParams) -> World {
    let ground = Shape::Plane(Plane {
        normal: [0.0, 0.0, 1.0],
        offset: 0.0,
    });
    let wall = Shape::Cuboid(Cuboid {
        half: [0.02, 0.3, 0.05],
    })
    .transformed(Pose::from_translation(Vec3::new(0.45, 0.0, 0.05)));
    let mut w = World::new(
        SimConfig {
            fps: 30.0,
            frames: 40,
            substeps: 20,
            ..SimConfig::default()
        },
        Shape::Union(vec![ground, wall]),
    );
    let body = RigidBody::from_shape(
        "toy",
        &Shape::Cuboid(Cuboid {
            half: [0.025, 0.02, 0.015],
        }),
        MassSpec::Mass(0.1),
        ContactSampling::Surface { count: 500, seed: 1 },
    )
    .unwrap();
    w.add_body(
        body,
        BodyState::new([0.0, 0.0, 0.08], [1.0, 0.0, 0.0, 0.0], v0, omega0),
        c,
        c,
    );
    w.validate().unwrap();
    w
}

fn poses_of(w: &World) -> Vec<Pose<f64>> {
    w.simulate(&w.params()).frames.iter().map(|f| f[0].pose).collect()
}

/// The toss both fits recover: its contact values, v0 and ω0.
const TOSS_CONTACT: ContactParams = ContactParams {
    restitution: 0.5,
    friction: 0.3,
};
const TOSS_V0: [f64; 3] = [1.6, 0.1, 0.6];
const TOSS_OMEGA0: [f64; 3] = [0.0, 0.0, 2.0];

/// The fitted launch's error relative to `v0` (`p`: a body's fitted parameters, v0 first).
fn launch_error(p: &[f64; 8], v0: [f64; 3]) -> f64 {
    let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    norm([p[0] - v0[0], p[1] - v0[1], p[2] - v0[2]]) / norm(v0)
}

#[test]
fn recovers_velocity_and_contact_parameters_from_its_own_poses() {
    let (truth, v0, w0) = (TOSS_CONTACT, TOSS_V0, TOSS_OMEGA0);
    let observed = poses_of(&tabletop(v0, w0, truth));
    // The body must really bounce off the ground and the wall.
    let xs: Vec<f64> = observed.iter().map(|p| p.t.x).collect();
    assert!(
        xs.windows(2).any(|w| w[1] < w[0] - 1e-3),
        "the box must rebound from the wall"
    );

    {
        let guess = ContactParams {
            restitution: 0.25,
            friction: 0.45,
        };
        let start = tabletop([0.8, 0.05, 0.3], [0.0, 0.0, 1.0], guess);
        let cfg = PhysicsFitConfig::default();
        let mut fit = PhysicsFit::new(cfg, start, 0, observed.clone(), None).unwrap();
        let t0 = std::time::Instant::now();
        let stats = fit.run();
        let secs = t0.elapsed().as_secs_f64();
        let p = fit.fitted_body_params();
        let v_err = launch_error(&p, v0);
        let msg = format!(
            "fitted {p:?} after {} iterations in {secs:.2} s, loss {}",
            stats.len(),
            fit.loss()
        );
        assert!(v_err < 0.01, "v0 off by {:.2} %: {msg}", v_err * 100.0);
        assert!((p[6] - truth.restitution).abs() < 0.02, "restitution: {msg}");
        assert!((p[7] - truth.friction).abs() < 0.02, "friction: {msg}");
        let worst = fit.pose_errors().iter().map(|e| e.translation).fold(0.0, f64::max);
        assert!(worst < 2e-3, "worst pose error {worst} m: {msg}");
        assert!(secs < 30.0, "{msg}");
    }
}

#[test]
fn a_slide_launched_in_the_plane_of_the_board_stays_in_it() {
    // Both contact models: the derivatives of each hold a face flat on the board (the mean-point model's
    // through its tilt hold; without it they drifted once the box slid, and this fit stalled with v0 6.7 % off).
    for model in [sim::ContactModel::MeanPoint, sim::ContactModel::MultiPoint] {
        slide_in_the_plane_of_the_board(model);
    }
}

fn slide_in_the_plane_of_the_board(model: sim::ContactModel) {
    let truth = ContactParams {
        restitution: 0.5,
        friction: 0.3,
    };
    // Resting on the board (half height 0.015 m), pushed along it.
    let on_board = |v0: [f64; 3], w0: [f64; 3], c: ContactParams| {
        let mut w = tabletop(v0, w0, c);
        w.initial[0].pose.t.z = 0.015;
        w.config.frames = 16;
        w.config.contact_model = model;
        w
    };
    let (v0, w0) = ([1.2, 0.2, 0.0], [0.0, 0.0, 2.0]);
    let observed = poses_of(&on_board(v0, w0, truth));
    // The guess rises off the board, as a launch fitted to one view's poses may.
    let start = on_board([0.8, 0.1, 0.3], [0.0, 0.0, 1.0], ContactParams::default());
    let obs = recon::Observed {
        start: recon::StartContact::Face {
            normal: [0.0, 0.0, 1.0],
        },
        ..recon::Observed::new(0, observed, None)
    };
    let mut fit = recon::PhysicsFit::new_bodies(PhysicsFitConfig::default(), start, vec![obs]).unwrap();
    // From the first step on, the launch has no part along the normal.
    fit.step();
    assert_eq!(fit.fitted_body_params()[2], 0.0);
    let stats = fit.run();
    let p = fit.fitted_body_params();
    let msg = format!("{model:?}: {} steps, loss {}", stats.len(), fit.loss());
    assert_eq!(p[2], 0.0, "{p:?}: {msg}");
    let err = ((p[0] - v0[0]).powi(2) + (p[1] - v0[1]).powi(2)).sqrt() / (v0[0] * v0[0] + v0[1] * v0[1]).sqrt();
    assert!(err < 0.01, "v0 off by {:.2} %: {p:?}: {msg}", err * 100.0);
    assert!((p[7] - truth.friction).abs() < 0.02, "friction: {p:?}: {msg}");
    let worst = fit.pose_errors().iter().map(|e| e.translation).fold(0.0, f64::max);
    assert!(worst < 1e-3, "worst pose error {worst} m: {p:?}: {msg}");
}

#[test]
fn poses_seen_from_one_camera_count_their_depth_least() {
    let (truth, v0, w0) = (TOSS_CONTACT, TOSS_V0, TOSS_OMEGA0);
    let true_poses = poses_of(&tabletop(v0, w0, truth));
    // Seen from a camera 0.6 m away: each pose off along its line of sight by up to 8 mm (what GA's
    // silhouettes leave of a 6 cm body's depth), and 0.3 mm across it.
    let eye = Vec3::new(0.1, -0.55, 0.3);
    let mut rng = geom::SplitMix64::new(7);
    let observed: Vec<Pose<f64>> = true_poses
        .iter()
        .map(|p| {
            let s = (p.t - eye) * (1.0 / (p.t - eye).norm());
            let across = rng.vec(0.0003);
            let along = rng.range(-0.008, 0.008);
            Pose::new(p.q, p.t + s * along + (across - s * s.dot(across)))
        })
        .collect();
    let fit_with = |eye: Option<[f64; 3]>| {
        let guess = ContactParams {
            restitution: 0.25,
            friction: 0.45,
        };
        let start = tabletop([0.8, 0.05, 0.3], [0.0, 0.0, 1.0], guess);
        let cfg = PhysicsFitConfig {
            fit_initial_pose: true,
            ..PhysicsFitConfig::default()
        };
        let obs = recon::Observed {
            eye,
            ..recon::Observed::new(0, observed.clone(), None)
        };
        let mut fit = PhysicsFit::new_bodies(cfg, start, vec![obs]).unwrap();
        fit.run();
        let p = fit.fitted_body_params();
        let v_err = launch_error(&p, v0);
        let w = fit.fitted_world();
        let errors: Vec<f64> = poses_of(&w)
            .iter()
            .zip(&true_poses)
            .map(|(a, b)| (a.t - b.t).norm())
            .collect();
        // The flight and the first landing, before the wall (whose glancing hit turns a friction 0.03 off
        // into centimetres).
        let before_wall = &errors[..8];
        let mean = before_wall.iter().sum::<f64>() / before_wall.len() as f64;
        let worst = before_wall.iter().cloned().fold(0.0, f64::max);
        eprintln!(
            "eye {eye:?}: v0 {:.2} % off, restitution {:.3}, friction {:.3}, from the true poses before the wall \
             {:.2} mm mean, {:.2} worst",
            v_err * 100.0,
            p[6],
            p[7],
            mean * 1e3,
            worst * 1e3
        );
        (v_err, p, mean, worst)
    };
    let (v_err, p, mean, worst) = fit_with(Some(eye.to_array()));
    let (_, _, mean_flat, _) = fit_with(None);
    // Measured: v0 1.5 % off, restitution 0.499, friction 0.325; 9.5 mm from the true poses on average over
    // the whole toss (22.8 weighing depth as the rest: the start sat 19 mm off along the line of sight), 4.3
    // mm at worst before the wall. With the mean-point model's tilt hold (2026-11-30) the values are the same
    // to the digits above, but after the wall's glancing hit the toss ends 28 mm off (34 weighing depth as
    // the rest), so the two are compared before the wall: 4.9 mm on average, 6.4 at worst, against 27.2
    // weighing depth as the rest; the worst is held to the depth noise of the poses (8 mm).
    assert!(v_err < 0.03, "v0 off by {:.2} %", v_err * 100.0);
    assert!((p[6] - truth.restitution).abs() < 0.05, "restitution {}", p[6]);
    assert!((p[7] - truth.friction).abs() < 0.05, "friction {}", p[7]);
    assert!(
        worst < 8e-3,
        "{:.2} mm from the true poses before the wall",
        worst * 1e3
    );
    assert!(
        mean < 0.4 * mean_flat,
        "weighing depth least: {:.2} mm from the true poses before the wall, against {:.2} mm weighing it as the \
         rest",
        mean * 1e3,
        mean_flat * 1e3
    );
}

/// The starts run side by side: each is told once, in start order, ends where it would alone, and the winner
/// is the first start of the lowest loss (what a loop over the starts in order keeps).
#[test]
fn a_multi_start_tells_every_start_and_keeps_the_first_of_the_lowest_loss() {
    let observed = poses_of(&tabletop(TOSS_V0, TOSS_OMEGA0, TOSS_CONTACT));
    let guess = ContactParams {
        restitution: 0.25,
        friction: 0.45,
    };
    let start = tabletop([1.2, 0.05, 0.45], [0.0, 0.0, 1.5], guess);
    let cfg = PhysicsFitConfig {
        iterations: 10,
        ..PhysicsFitConfig::default()
    };
    // The last start is the world's own again: a tie, which the first of the two must win if it is lowest.
    let starts = [
        (0.15, 0.1),
        (0.75, 0.7),
        (0.45, 0.35),
        (guess.restitution, guess.friction),
    ];
    let mut told = Vec::new();
    let multi = fit_multi_start(
        cfg.clone(),
        start.clone(),
        0,
        observed.clone(),
        None,
        &starts,
        &mut |i, r| told.push((i, r.clone())),
    )
    .unwrap();
    assert_eq!(
        told.iter().map(|(i, _)| *i).collect::<Vec<_>>(),
        [0, 1, 2, 3, 4],
        "told once each, in start order"
    );
    assert_eq!(
        multi.starts[4].loss, multi.starts[0].loss,
        "the same start ends the same"
    );
    let all: Vec<(f64, f64)> = std::iter::once((guess.restitution, guess.friction))
        .chain(starts)
        .collect();
    for (i, r) in multi.starts.iter().enumerate() {
        assert_eq!((r.restitution, r.friction), all[i], "start {i}");
        assert_eq!(told[i].1.loss, r.loss, "start {i}: told another loss");
        let c = multi.worlds[i].scene_contact[0];
        assert_eq!((c.restitution, c.friction), (r.fitted_restitution, r.fitted_friction));
        // Alone, the same start ends at the same loss, bit for bit.
        let mut w = start.clone();
        w.scene_contact[0] = ContactParams {
            restitution: all[i].0,
            friction: all[i].1,
        };
        let mut alone = PhysicsFit::new(cfg.clone(), w, 0, observed.clone(), None).unwrap();
        alone.run();
        assert_eq!(alone.full_loss(), r.loss, "start {i} alone");
    }
    let lowest = multi.starts.iter().map(|r| r.loss).fold(f64::INFINITY, f64::min);
    let first_lowest = multi.starts.iter().position(|r| r.loss == lowest).unwrap();
    assert_eq!(multi.winner, first_lowest);
    assert_eq!(multi.best.full_loss(), lowest);
}

/// Poses with noise as GA leaves them: `sigma` millimetres and degrees.
fn seen(true_poses: &[Pose<f64>], sigma: f64) -> Vec<Pose<f64>> {
    let mut rng = geom::SplitMix64::new(11);
    true_poses
        .iter()
        .map(|p| {
            Pose::new(
                geom::Quat::exp(rng.vec(sigma.to_radians())) * p.q,
                p.t + rng.vec(sigma * 1e-3),
            )
        })
        .collect()
}

/// A launch that the frames after the first contact bent (made by another contact model, which the fit's
/// cannot follow) misses the flight by more than its noise and is taken from the flight, the contact values
/// fitted around it; where the fit's simulator makes every frame, the launch over all of them stands.
#[test]
fn a_launch_the_contacts_bent_is_taken_from_the_flight() {
    let (truth, v0, w0) = (TOSS_CONTACT, TOSS_V0, TOSS_OMEGA0);
    let cfg = PhysicsFitConfig {
        fit_initial_pose: true,
        ..PhysicsFitConfig::default()
    };
    // The toss up to just after it meets the wall (it lands at frame 6, hops, slides and meets the wall at
    // 9), seen with 0.1 mm / 0.1° of noise. Its tumble off the wall turns on the last tenth of a degree
    // (0.3° in the first pose moves its end by 8 cm): seen to its end, even with the very model that made
    // it, the fit over every frame follows the noise with a launch that misses the flight (statistic 589
    // against 26 at 0.3 mm / 0.3°, 71 at 0.03 mm / 0.03°), and the check takes the launch from the flight
    // (0.1 % off), as it should. The noise is a third of GA's: at 0.3 mm / 0.3° these 12 frames are called
    // bent with the same model too (statistic 92), and over 9 frames (before the wall) the other model is
    // not told (25 against 26); at GA's noise the check tells a bend only where the contacts differ by more
    // than the chaos amplifies the noise.
    let frames = 12;
    for other_model in [false, true] {
        let mut world = tabletop(v0, w0, truth);
        world.config.frames = frames;
        if other_model {
            world.config.contact_model = sim::ContactModel::MultiPoint;
        }
        let landing = recon::first_contact_frame(&world, &[0]).expect("the toss lands");
        let observed = vec![recon::Observed::new(0, seen(&poses_of(&world), 0.1), None)];
        let guess = ContactParams {
            restitution: 0.25,
            friction: 0.45,
        };
        let mut start = tabletop([0.8, 0.05, 0.3], [0.0, 0.0, 1.0], guess);
        start.config.frames = frames;
        let mut fit = PhysicsFit::new_bodies(cfg.clone(), start, observed.clone()).unwrap();
        fit.run();
        let joint = fit.fitted_world();
        let joint_error = launch_error(&fit.fitted_body_params(), v0);
        let check = recon::check_flight(&cfg, &joint, &observed)
            .unwrap()
            .expect("a flight to check");
        let v = check.flight_world.initial[0].v.to_array();
        let flight_error = launch_error(&[v[0], v[1], v[2], 0.0, 0.0, 0.0, 0.0, 0.0], v0);
        eprintln!(
            "other model {other_model}: flight of {} frames, statistic {:.1} against {:.1}; v0 off {:.2} % over every frame, \
             {:.2} % over the flight",
            check.frames,
            check.statistic,
            check.critical,
            joint_error * 100.0,
            flight_error * 100.0
        );
        assert_eq!(check.frames, landing, "the flight ends where the truth lands");
        let launch_held = PhysicsFitConfig {
            fit_velocity: false,
            fit_angular_velocity: false,
            fit_initial_pose: false,
            ..cfg.clone()
        };
        assert!(
            recon::check_flight(&launch_held, &joint, &observed).unwrap().is_none(),
            "settings that hold the launch leave nothing to test"
        );
        assert_eq!(
            check.bent(),
            other_model,
            "bent: statistic {} against {}",
            check.statistic,
            check.critical
        );
        if other_model {
            let contact_held = PhysicsFitConfig {
                fit_restitution: false,
                fit_friction: false,
                ..cfg.clone()
            };
            let nothing = recon::fit_holding_launch(
                &contact_held,
                check.flight_world.clone(),
                observed.clone(),
                &[],
                &mut |_, _| {},
            );
            assert!(
                matches!(nothing, Err(recon::FitError::NothingToFit)),
                "no contact value to fit"
            );
            let held =
                recon::fit_holding_launch(&cfg, check.flight_world.clone(), observed, &[], &mut |_, _| {}).unwrap();
            let w = &held.worlds[held.winner];
            let v = w.initial[0].v.to_array();
            assert_eq!(v, check.flight_world.initial[0].v.to_array(), "the launch is held");
            let c = w.scene_contact[0];
            eprintln!("held: restitution {:.3}, friction {:.3}", c.restitution, c.friction);
            assert!(
                flight_error < 0.01,
                "v0 off by {:.2} % over the flight",
                flight_error * 100.0
            );
            // The flight test tells the bend (above) even where the joint launch is close: with the
            // mean-point model's tilt hold the fit over every frame follows the other model's slide well
            // enough to keep the launch within 0.3 % (before it, over three times the flight's error),
            // yet it misses the flight by more than the poses' noise.
            assert!(
                joint_error < 0.05,
                "the joint launch stays near: {:.2} %",
                joint_error * 100.0
            );
        }
    }
}

/// A box pushed along the board into the wall, the paper's mean-point model: it slides (mu), rebounds off
/// the wall (k_n) and slides to rest. From a launch 1/3 off and the default contact values, PGA with the
/// multi-start `fit` runs recovers the rebound (one start alone may end in a neighbouring basin: the
/// impact moves by whole substeps). Before the model's tilt hold its derivatives drifted while the box
/// slid, and the multi-start fit of the tabletop slide's exact poses ended with the box stopping short of
/// the wall (restitution 0.15, friction 0.35 against 0.5 and 0.25; 24 mm off).
#[test]
fn a_slide_into_the_wall_gives_back_its_restitution() {
    let truth = ContactParams {
        restitution: 0.5,
        friction: 0.3,
    };
    let against_wall = |v0: [f64; 3], w0: [f64; 3], c: ContactParams| {
        let mut w = tabletop(v0, w0, c);
        w.initial[0].pose.t = Vec3::new(0.2, 0.0, 0.015);
        w.config.frames = 24;
        w
    };
    let (v0, w0) = ([1.2, 0.05, 0.0], [0.0, 0.0, 0.3]);
    let world = against_wall(v0, w0, truth);
    let traj = world.simulate(&world.params());
    let xs: Vec<f64> = traj.frames.iter().map(|f| f[0].pose.t.x).collect();
    let back = xs.iter().copied().fold(f64::MIN, f64::max) - xs[xs.len() - 1];
    // Face-on it rebounds 5.1 mm. Met corner first (ω0 1.0 rad/s, turned 14°) it rebounded 2.4 mm, and
    // the multi-start fit ended at restitution 0.467 with loss 0.014 where the truth's is 0: the corner hit
    // tells restitution little, and the fit does not reach the truth there.
    assert!(back > 0.004, "the box rebounds off the wall: {:.1} mm back", back * 1e3);
    let start = against_wall([0.8, 0.03, 0.0], [0.0, 0.0, 0.15], ContactParams::default());
    let obs = recon::Observed {
        start: recon::StartContact::Face {
            normal: [0.0, 0.0, 1.0],
        },
        ..recon::Observed::new(0, poses_of(&world), None)
    };
    let multi = recon::fit_multi_start_bodies(
        PhysicsFitConfig::default(),
        start,
        vec![obs],
        &recon::CONTACT_STARTS,
        recon::StartsOn::Scene,
        &mut |_, _| {},
    )
    .unwrap();
    let fit = multi.best;
    let p = fit.fitted_body_params();
    let msg = format!("{p:?}: start {}, loss {}", multi.winner, fit.loss());
    assert!(launch_error(&p, v0) < 0.01, "v0: {msg}");
    assert!((p[6] - truth.restitution).abs() < 0.02, "restitution: {msg}");
    assert!((p[7] - truth.friction).abs() < 0.02, "friction: {msg}");
    let worst = fit.pose_errors().iter().map(|e| e.translation).fold(0.0, f64::max);
    assert!(worst < 1e-3, "worst pose error {worst} m: {msg}");
}
