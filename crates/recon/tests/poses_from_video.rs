//! GA: every frame's pose of the tossed block from the images, starting from
//! a PA whose launch was 5 % slow (as PA leaves it: its poses up to 13 mm behind), with
//! the contact penalty in the frames where that simulation touched the board;
//! from a PA that lost the block at its landing (it bounces away where the
//! block slides); a block bouncing off the board, held to it only where it
//! touches it when the frame is taken; a block lost while hidden, found again
//! by searching the last frame; a last frame turned farther than its steps
//! reach, fitted on from its own pose, or again from a simulation that passes near the truth; a block at rest kept without fitting
//! (with and without a camera's noise) and fitted again once pushed; a block held off its pose by a bump
//! the reconstructed scene has and the images do not, fitted by the images alone; and the penalty's
//! gradient against finite differences.

use crate::common;
use common::*;
use geom::{Pose, Quat, Vec3};
use recon::{ContactPenaltyConfig, ContactTerm, PosesFromVideo, PosesFromVideoConfig};

/// GA with every start, each frame fitted in 24 steps of 256 pixels.
fn short_fits() -> PosesFromVideoConfig {
    PosesFromVideoConfig {
        pose: recon::PoseFitConfig {
            iterations: 24,
            rays_per_step: 256,
            ..PosesFromVideoConfig::default().pose
        },
        ..PosesFromVideoConfig::default()
    }
}

#[test]
#[ignore = "slow: GA follows the images where PA's launch was 5 % slow, every frame of a landing and slide, ~43 s"]
fn poses_from_a_slow_launch_are_corrected_frame_by_frame() {
    let ball = ball_model();
    let truth_world = world(V0, TRUTH);
    let (behind, frames) = film(&ball, &truth_world);
    let truth = truth_world.simulate(&truth_world.params());
    let slow_world = world(V0.map(|v| 0.95 * v), TRUTH);
    let pa = slow_world.simulate(&slow_world.params());
    let touching = pa.contacts.iter().filter(|c| c.scene[0]).count();
    assert!(
        touching >= 5,
        "the block lands and slides: {touching} frames in contact"
    );
    // PA's starts alone: this measures GA from a PA that converged; the starts from the images' own track
    // have their own test below (and would double this one's time).
    let cfg = PosesFromVideoConfig {
        pose: recon::PoseFitConfig {
            iterations: 60,
            rays_per_step: 512,
            ..PosesFromVideoConfig::default().pose
        },
        hypotheses: false,
        ..PosesFromVideoConfig::default()
    };
    let mut ga = PosesFromVideo::new(cfg, &ball, &behind, &frames, &slow_world, 0, &pa).expect("valid input");
    let results = ga.run().expect("every frame fits").to_vec();
    let mut errors = Vec::new();
    for (k, (r, t)) in results.iter().zip(&truth.frames).enumerate() {
        let err = (r.pose.t - t[0].pose.t).norm();
        let start = (pa.frames[k][0].pose.t - t[0].pose.t).norm();
        eprintln!(
            "frame {k}: {:.1} mm off (from {:.1}), IoU {:.3}, contact {} (penalty {:.2e})",
            err * 1e3,
            start * 1e3,
            r.image.iou(),
            r.in_contact,
            r.contact_penalty
        );
        errors.push((k, err, r.clone()));
    }
    // At 128 × 96 the block is 18 px across: 3 mm of depth changes its size by 0.13 px, so depth is what a
    // frame in flight pins worst; in contact the board pins it.
    let contact: Vec<f64> = errors.iter().filter(|e| e.2.in_contact).map(|e| e.1).collect();
    let mean_contact = contact.iter().sum::<f64>() / contact.len().max(1) as f64;
    assert!(
        mean_contact < 3e-3,
        "frames in contact: {:.1} mm on average",
        mean_contact * 1e3
    );
    for (k, err, r) in errors {
        assert!(r.fitted, "frame {k} has a mask");
        assert!(r.image.iou() > 0.95, "frame {k}: IoU {}", r.image.iou());
        assert!(err < 5e-3, "frame {k}: {:.1} mm from the truth", err * 1e3);
        assert!(r.contact_penalty < 0.01, "frame {k}: neither floating nor sunk");
    }
    assert!(
        results.iter().filter(|r| r.in_contact).count() >= 5,
        "the penalty applied where PA touched"
    );
}

#[test]
fn poses_after_a_landing_pa_got_wrong_follow_the_images() {
    let ball = ball_model();
    // Seven frames: the landing is at frame 3, and PA is 14–46 mm off over the next four.
    let short = |mut w: sim::World| {
        w.config.frames = 7;
        w
    };
    let truth_world = short(world(V0, TRUTH));
    let (behind, frames) = film(&ball, &truth_world);
    let truth = truth_world.simulate(&truth_world.params());
    // PA's block bounces off the board (restitution 0.95, no friction) where the true one lands and slides.
    let bouncy = short(world(
        V0,
        sim::ContactParams {
            restitution: 0.95,
            friction: 0.02,
        },
    ));
    let pa = bouncy.simulate(&bouncy.params());
    let off: Vec<f64> = (0..frames.len())
        .map(|k| (pa.frames[k][0].pose.t - truth.frames[k][0].pose.t).norm())
        .collect();
    assert!(
        off.iter().cloned().fold(0.0, f64::max) > 0.02,
        "PA loses the block: {off:?}"
    );
    let cfg = short_fits();
    let mut ga = PosesFromVideo::new(cfg, &ball, &behind, &frames, &bouncy, 0, &pa).expect("valid input");
    let with = ga.run().expect("every frame fits").to_vec();
    let e_with: Vec<f64> = with
        .iter()
        .zip(&truth.frames)
        .map(|(r, t)| (r.pose.t - t[0].pose.t).norm())
        .collect();
    for (k, (r, e)) in with.iter().zip(&e_with).enumerate() {
        eprintln!(
            "frame {k}: {:.1} mm off (PA {:.1}), start {:?}, IoU {:.3}",
            e * 1e3,
            off[k] * 1e3,
            r.start,
            r.image.iou()
        );
    }
    // A frame that followed PA's bounce would be centimetres off. Measured (7 frames, 24 steps): 0.1–0.7 mm,
    // 5.1 and 4.6 mm in the two frames after the landing (the 18 px block tells depth least: 3 mm changes its
    // size by 0.13 px), mean 1.7 mm, every frame from PA's start with the last correction carried over. Before
    // PA's contact held a frame only where PA's body was on the board when the frame was taken, some frames
    // after the landing went on from the images' own track instead.
    for (k, e) in e_with.iter().enumerate() {
        assert!(*e < 0.01, "frame {k}: {:.1} mm from the truth", e * 1e3);
    }
    let mean = e_with.iter().sum::<f64>() / e_with.len() as f64;
    assert!(mean < 0.0035, "{:.1} mm from the truth on average", mean * 1e3);
}

#[test]
fn a_body_bouncing_off_the_board_is_held_to_it_only_where_it_touches() {
    let ball = ball_model();
    // The block bounces off the board (restitution 0.8, little friction), and PA's simulation is the true
    // one. A frame is flagged for any contact since the one before: after a bounce, which lasts a substep,
    // the body is off the board when the frame is taken, and holding it there would pull it down along the
    // line of sight, where the 20 px block's size tells depth least.
    let bouncy = sim::ContactParams {
        restitution: 0.8,
        friction: 0.05,
    };
    let mut truth_world = world(V0, bouncy);
    truth_world.config.frames = 8;
    let (behind, frames) = film(&ball, &truth_world);
    let truth = truth_world.simulate(&truth_world.params());
    let clearance = |p: &Pose<f64>| recon::video_fit::clearance(&truth_world.bodies[0], &truth_world.scene, p);
    let cfg = short_fits();
    let mut ga = PosesFromVideo::new(cfg, &ball, &behind, &frames, &truth_world, 0, &truth).expect("valid input");
    let results = ga.run().expect("every frame fits").to_vec();
    let mut bounced = 0;
    for (k, (r, t)) in results.iter().zip(&truth.frames).enumerate() {
        let (e, above) = ((r.pose.t - t[0].pose.t).norm(), clearance(&t[0].pose));
        eprintln!(
            "frame {k}: {:.1} mm off, {:.1} mm above the board (truth {:.1}), held {}, flagged {}",
            e * 1e3,
            clearance(&r.pose) * 1e3,
            above * 1e3,
            r.in_contact,
            truth.contacts[k].scene[0]
        );
        assert!(e < 0.005, "frame {k}: {:.1} mm from the truth", e * 1e3);
        if truth.contacts[k].scene[0] && above > 0.003 {
            bounced += 1;
            assert!(
                !r.in_contact,
                "frame {k}: held to the board {:.1} mm under it",
                above * 1e3
            );
            // Measured 0.6 mm; 3.9 and 2.8 mm (frames 6 and 7) before the rule.
            assert!(e < 0.002, "frame {k}, after a bounce: {:.1} mm from the truth", e * 1e3);
        }
    }
    assert!(
        bounced > 0,
        "a frame flagged for a bounce finds the block off the board"
    );
}

#[test]
#[ignore = "slow: GA finds a body again after frames it was hidden in, ~38 s"]
fn a_body_lost_while_hidden_is_found_again_from_the_last_frame() {
    let ball = ball_model();
    // The block rests on the board for 8 frames, hidden in frames 3–5 (their masks empty). PA turned it a
    // quarter turn onto another face from frame 3 on, as a tumble another engine made can leave it: the
    // hidden frames keep PA's poses, and frames 6–7 have no start but PA's, which holds the wrong face on
    // the board.
    let mut truth_world = world([0.0; 3], TRUTH);
    truth_world.config.frames = 8;
    let rest = Quat::exp(Vec3::new(0.0, 0.0, 0.4));
    truth_world.initial[0] = sim::BodyState::new([-0.02, 0.01, RADIUS], rest.to_array_re(), [0.0; 3], [0.0; 3]);
    let (behind, mut frames) = film(&ball, &truth_world);
    for f in &mut frames[3..6] {
        f.mask.iter_mut().for_each(|m| *m = false);
    }
    let truth = truth_world.simulate(&truth_world.params());
    let mut pa = truth.clone();
    let quarter = Quat::exp(Vec3::new(std::f64::consts::FRAC_PI_2, 0.0, 0.0));
    for f in &mut pa.frames[3..] {
        f[0].pose.q = (f[0].pose.q * quarter).normalize_or_identity();
    }
    let off = |r: &recon::FramePose, k: usize| {
        (
            (r.pose.t - truth.frames[k][0].pose.t).norm(),
            geom::rotation_distance(r.pose.q, truth.frames[k][0].pose.q).to_degrees(),
        )
    };
    // The search in short: every candidate 8 steps of 256 pixels, the best two 60 in all, no half-turns.
    let search = recon::FirstPoseSearchConfig {
        screen_iterations: 8,
        refined: 2,
        refine: recon::PoseFitConfig {
            iterations: 60,
            rays_per_step: 256,
            ..recon::FirstPoseSearchConfig::default().refine
        },
        twin_iterations: 0,
        ..recon::FirstPoseSearchConfig::default()
    };
    let run = |ratio: f64| {
        let cfg = PosesFromVideoConfig {
            end_search_ratio: ratio,
            end_search: search.clone(),
            ..short_fits()
        };
        let mut ga = PosesFromVideo::new(cfg, &ball, &behind, &frames, &truth_world, 0, &pa).expect("valid input");
        ga.run().expect("every frame fits").to_vec()
    };
    let t0 = std::time::Instant::now();
    let without = run(0.0);
    let t1 = std::time::Instant::now();
    let with = run(PosesFromVideoConfig::default().end_search_ratio);
    let secs = (t1.elapsed().as_secs_f64(), (t1 - t0).as_secs_f64());
    for (k, (a, b)) in with.iter().zip(&without).enumerate() {
        let ((ea, ra), (eb, rb)) = (off(a, k), off(b, k));
        eprintln!(
            "frame {k}: {:.1} mm, {ra:.1}° from {:?}, loss {:.4} (without the search: {:.1} mm, {rb:.1}°, loss {:.4})",
            ea * 1e3,
            a.start,
            a.image.loss,
            eb * 1e3,
            b.image.loss
        );
    }
    eprintln!("{:.1} s with the search, {:.1} s without", secs.0, secs.1);
    // Without the search the last frames stay on the wrong face.
    assert!(off(&without[7], 7).1 > 45.0, "PA's face is kept without the search");
    // With it the last frame is found again and the one before it carried back from there.
    // (The sizing pass after it may refit it again from its own pose slid along the line of sight.)
    assert!(
        matches!(with[7].start, recon::StartFrom::Searched | recon::StartFrom::Sized),
        "frame 7 from {:?}",
        with[7].start
    );
    // The 20 px block's depth is what its image tells least (frames 0–2: 2–4 mm).
    for k in [0, 1, 2, 6, 7] {
        let (e, r) = off(&with[k], k);
        assert!(with[k].fitted, "frame {k} has a mask");
        assert!(
            e < 0.006 && r < 10.0,
            "frame {k}: {:.1} mm, {r:.1}° from the truth",
            e * 1e3
        );
    }
}

/// A block resting on the board for 4 frames and turned 12° about the vertical in the last (as a tumble
/// turns a body between two frames), filmed; PA (the world's simulation) keeps it at rest.
struct TurnedLast {
    rest_world: sim::World,
    pa: sim::Trajectory<f64>,
    poses: Vec<Pose<f64>>,
    last: usize,
    behind: Vec<neus::compose::ComposedRay>,
    frames: Vec<recon::FrameTarget>,
}

fn turned_last(ball: &neus::ObjectModel) -> TurnedLast {
    let mut rest_world = world([0.0; 3], TRUTH);
    rest_world.config.frames = 5;
    let rest = Quat::exp(Vec3::new(0.0, 0.0, 0.4));
    rest_world.initial[0] = sim::BodyState::new([-0.02, 0.01, RADIUS], rest.to_array_re(), [0.0; 3], [0.0; 3]);
    let pa = rest_world.simulate(&rest_world.params());
    let mut poses: Vec<Pose<f64>> = pa.frames.iter().map(|f| f[0].pose).collect();
    let last = poses.len() - 1;
    let turned = Quat::exp(Vec3::new(0.0, 0.0, 12f64.to_radians()));
    poses[last].q = (turned * poses[last].q).normalize_or_identity();
    let (behind, frames) = film_poses(ball, &poses);
    TurnedLast {
        rest_world,
        pa,
        poses,
        last,
        behind,
        frames,
    }
}

#[test]
fn a_frame_that_ran_out_of_steps_is_fitted_on_from_its_own_pose() {
    let ball = ball_model();
    // The block rests on the board for 4 frames and is turned 12° about the vertical in the last (as a
    // tumble turns a body between two frames). PA keeps it at rest, so every start of the last frame is 12°
    // off, farther than 24 steps of 0.01 rad decaying tenfold move it (about 5.6°); the pass back does not
    // reach the last frame, and the search of a lost last frame is off here.
    let TurnedLast {
        rest_world,
        pa,
        poses,
        last,
        behind,
        frames,
    } = turned_last(&ball);
    let run = |ratio: f64| {
        let cfg = PosesFromVideoConfig {
            end_search_ratio: 0.0,
            continue_ratio: ratio,
            ..short_fits()
        };
        let mut ga = PosesFromVideo::new(cfg, &ball, &behind, &frames, &rest_world, 0, &pa).expect("valid input");
        ga.run().expect("every frame fits").to_vec()
    };
    let without = run(0.0);
    let with = run(PosesFromVideoConfig::default().continue_ratio);
    let turn = |r: &recon::FramePose, k: usize| geom::rotation_distance(r.pose.q, poses[k].q).to_degrees();
    for (k, (a, b)) in with.iter().zip(&without).enumerate() {
        eprintln!(
            "frame {k}: {:.1}° from {:?}, loss {:.4} (without the last pass: {:.1}° from {:?}, loss {:.4})",
            turn(a, k),
            a.start,
            a.image.loss,
            turn(b, k),
            b.start,
            b.image.loss
        );
    }
    // Measured: 7.4° off without the last pass, its loss 2.3 times the worst resting frame's (0.0239 against
    // 0.0103); 1.4° with it, its loss 1.13 times theirs (0.0116). The untrained sphere field's faint colours
    // tell its turn to about 3° (the resting frames: 0.0–0.1°). (Before the contact penalty left the depth
    // to the image within its precision: 9.5° and 5.0°, losses 0.0277 and 0.0128 against 0.0151.)
    let worst_rest = with[..last].iter().map(|r| r.image.loss).fold(0.0, f64::max);
    assert!(turn(&without[last], last) > 6.0, "the steps run out 12° off");
    assert!(
        without[last].image.loss > 1.3 * worst_rest,
        "and the frame is explained poorly"
    );
    assert_eq!(with[last].start, recon::StartFrom::Continued);
    assert!(
        turn(&with[last], last) < 0.7 * turn(&without[last], last),
        "fitted on: {:.1}°",
        turn(&with[last], last)
    );
    assert!(
        with[last].image.loss < 1.2 * worst_rest,
        "as well explained as the resting frames: {:.4} against {worst_rest:.4}",
        with[last].image.loss
    );
}

#[test]
fn a_frame_turned_the_wrong_way_is_fitted_again_from_the_simulation() {
    let ball = ball_model();
    // The resting block of the test above, turned 12° in the last frame; GA without its last pass leaves that
    // frame where its steps ran out. Then a trajectory that passes within 2° of the truth there (as PGA's
    // simulation, fitted to the whole video, may where GA's frames went another way) starts it again.
    let TurnedLast {
        rest_world,
        pa,
        poses,
        last,
        behind,
        frames,
    } = turned_last(&ball);
    let cfg = PosesFromVideoConfig {
        end_search_ratio: 0.0,
        continue_ratio: 0.0,
        ..short_fits()
    };
    let mut ga = PosesFromVideo::new(cfg.clone(), &ball, &behind, &frames, &rest_world, 0, &pa).expect("valid input");
    let before = ga.run().expect("every frame fits").to_vec();
    let mut simulated = pa.clone();
    let near = Quat::exp(Vec3::new(0.0, 0.0, 10f64.to_radians()));
    simulated.frames[last][0].pose.q = (near * pa.frames[last][0].pose.q).normalize_or_identity();
    let refit = |ratio: f64| {
        let cfg = PosesFromVideoConfig {
            continue_ratio: ratio,
            ..cfg.clone()
        };
        let mut again = PosesFromVideo::new(cfg, &ball, &behind, &frames, &rest_world, 0, &simulated)
            .and_then(|s| s.with_results(before.clone()))
            .expect("valid input");
        let mut told = 0;
        let replaced = again.refit_worst_from_physics(|| told += 1).expect("every frame fits");
        (replaced, told, again.results)
    };
    let turn = |r: &recon::FramePose, k: usize| geom::rotation_distance(r.pose.q, poses[k].q).to_degrees();
    let (replaced, told, after) = refit(PosesFromVideoConfig::default().continue_ratio);
    for (k, (a, b)) in after.iter().zip(&before).enumerate() {
        eprintln!(
            "frame {k}: {:.1}° from {:?}, loss {:.4} (before: {:.1}°, loss {:.4})",
            turn(a, k),
            a.start,
            a.image.loss,
            turn(b, k),
            b.image.loss
        );
    }
    assert!(turn(&before[last], last) > 6.0, "GA's steps run out 12° off");
    assert_eq!(replaced, vec![last], "only the frame explained poorly is fitted again");
    assert_eq!(told, 1);
    assert_eq!(after[last].start, recon::StartFrom::Pga);
    assert!(
        turn(&after[last], last) < 3.0,
        "from the simulation: {:.1}°",
        turn(&after[last], last)
    );
    assert!(after[last].image.loss < before[last].image.loss);
    for k in 0..last {
        assert_eq!(after[k].pose, before[k].pose, "frame {k} is explained well and kept");
    }
    // Without a ratio nothing is fitted again.
    let (none, told, _) = refit(0.0);
    assert!(none.is_empty() && told == 0);
}

/// A camera 0.4 m off looking down at 53° (f = 290 px): the image's precision on a body 50 mm across.
fn seen_obliquely() -> recon::ImagePrecision {
    recon::ImagePrecision::at_distance(Vec3::new(0.6, 0.0, -0.8), 0.4, 0.05, 290.0)
}

#[test]
fn the_contact_penalty_gradient_matches_finite_differences() {
    let w = world(V0, TRUTH);
    let body = &w.bodies[0];
    // Bottom corners of the cube (its points lowest in z).
    let mut points: Vec<usize> = (0..body.contact_points.len()).collect();
    points.sort_by(|&a, &b| body.contact_points[a].z.total_cmp(&body.contact_points[b].z));
    points.truncate(12);
    let tilt = Quat::exp(Vec3::new(0.05, -0.08, 0.3));
    // At the surface and with the image's slack; floating 1.5 mm beyond it, and sunk 1 mm.
    for seen in [None, Some(seen_obliquely())] {
        let term = ContactTerm {
            body,
            scene: &w.scene,
            points: points.clone(),
            sides: Vec::new(),
            seen,
            cfg: ContactPenaltyConfig::default(),
        };
        let slack = seen.map_or(0.0, |p| p.along_direction(Vec3::new(0.0, 0.0, 1.0)));
        // The tilted cube's lowest point below its centre.
        let drop = points
            .iter()
            .map(|&i| -tilt.rotate(body.contact_points[i]).z)
            .fold(0.0, f64::max);
        for lift in [drop + slack + 0.0015, drop - slack - 0.001] {
            let pose = Pose::new(tilt, Vec3::new(0.01, -0.02, lift));
            let (value, grad) = term.evaluate(&pose);
            assert!(value > 0.0, "a penalty at lift {lift}");
            let h = 1e-6;
            for k in 0..6 {
                let moved = |s: f64| {
                    let mut d = [0.0; 6];
                    d[k] = s * h;
                    let dt = Vec3::new(d[0], d[1], d[2]);
                    let dw = Vec3::new(d[3], d[4], d[5]);
                    let p = Pose::new((Quat::exp(dw) * pose.q).normalize_or_identity(), pose.t + dt);
                    term.evaluate(&p).0
                };
                let fd = (moved(1.0) - moved(-1.0)) / (2.0 * h);
                assert!(
                    (fd - grad[k]).abs() <= 1e-4 * (1.0 + fd.abs()),
                    "slack {slack}, lift {lift}, component {k}: analytic {} vs finite difference {fd}",
                    grad[k]
                );
            }
        }
    }
}

#[test]
fn the_contact_penalty_leaves_to_the_image_what_it_can_tell() {
    let w = world(V0, TRUTH);
    let body = &w.bodies[0];
    let points: Vec<usize> = (0..body.contact_points.len()).collect();
    let seen = seen_obliquely();
    let term = |seen: Option<recon::ImagePrecision>, image_slack: f64| ContactTerm {
        body,
        scene: &w.scene,
        points: points.clone(),
        sides: Vec::new(),
        seen,
        cfg: ContactPenaltyConfig {
            image_slack,
            ..ContactPenaltyConfig::default()
        },
    };
    // The image places the cube to 2.2 mm along the board's normal, seen at 53°.
    let slack = seen.along_direction(Vec3::new(0.0, 0.0, 1.0));
    assert!(slack > 0.002 && slack < 0.0025, "{slack}");
    let at = |dz: f64| Pose::new(Quat::identity(), Vec3::new(0.0, 0.0, RADIUS + dz));
    for dz in [0.001, -0.001, 0.9 * slack, -0.9 * slack] {
        assert_eq!(
            term(Some(seen), 1.0).evaluate(&at(dz)),
            (0.0, [0.0; 6]),
            "{dz} m: within the slack"
        );
        assert!(term(None, 1.0).evaluate(&at(dz)).0 > 0.0, "{dz} m: held at the surface");
        assert!(
            term(Some(seen), 0.0).evaluate(&at(dz)).0 > 0.0,
            "{dz} m: no slack asked for"
        );
    }
    // Beyond the slack the penalty grows as it did from the surface, and pulls back.
    let (up, g_up) = term(Some(seen), 1.0).evaluate(&at(slack + 0.002));
    let (from_surface, _) = term(None, 1.0).evaluate(&at(0.002));
    assert!(
        (up - from_surface).abs() < 1e-9 * from_surface,
        "{up} against {from_surface}"
    );
    assert!(g_up[2] > 0.0, "pulled down: {g_up:?}");
    let (_, g_down) = term(Some(seen), 1.0).evaluate(&at(-slack - 0.002));
    assert!(g_down[2] < 0.0, "pushed up: {g_down:?}");
}

#[test]
fn a_body_against_a_wall_is_held_on_the_board_too() {
    let w = world(V0, TRUTH);
    let body = &w.bodies[0];
    // The board (z = 0) and a wall facing −x at x = 0.1.
    let scene = sim::sdf::Shape::Union(vec![
        sim::sdf::Shape::Plane(sim::sdf::Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        }),
        sim::sdf::Shape::Plane(sim::sdf::Plane {
            normal: [-1.0, 0.0, 0.0],
            offset: -0.1,
        }),
    ]);
    // The cube's bottom and its +x face: the points within 5 mm of either at the pose touching both.
    let touching = Pose::new(Quat::identity(), Vec3::new(0.1 - RADIUS, 0.0, RADIUS));
    let near = sim::points_near_scene(body, &touching, &scene, 0.005);
    let points: Vec<usize> = near.iter().map(|p| p.index).collect();
    let sides = recon::contact_sides(near.iter().map(|p| p.gradient));
    assert_eq!(sides.len(), 2, "board and wall: {sides:?}");
    let term = |sides: Vec<Vec3<f64>>| ContactTerm {
        body,
        scene: &scene,
        points: points.clone(),
        sides,
        seen: None,
        cfg: ContactPenaltyConfig::default(),
    };
    // Slid 4 mm up the wall (toward a camera looking down at it): the wall still touches.
    let floating = Pose::new(Quat::identity(), touching.t + Vec3::new(0.0, 0.0, 0.004));
    let (any_side, _) = term(Vec::new()).evaluate(&floating);
    let (both_sides, grad) = term(sides.clone()).evaluate(&floating);
    assert!(
        any_side < 1e-12,
        "one nearest point for the whole scene: the wall holds it ({any_side})"
    );
    assert!(both_sides > 0.1, "held on the board too: {both_sides}");
    assert!(grad[2] > 0.0, "the penalty pulls it down: {grad:?}");
    assert!(
        term(sides).evaluate(&touching).0 < 1e-12,
        "no penalty where it touches both"
    );
}

#[test]
fn a_still_body_keeps_its_pose_and_one_that_moves_on_is_fitted() {
    let ball = ball_model();
    // The block rests on the board for 6 frames (filmed at one pose: a body at rest shows the same image),
    // then is pushed 8 mm along x in frame 6 and 8 more in frame 7. PA keeps it at rest throughout. Its
    // rotation is not fitted (the sphere's faint colours tell it to a few degrees only), so the resting
    // fits differ by their translations alone.
    let rest_world = resting_world(8, [-0.02, 0.01]);
    let pa = rest_world.simulate(&rest_world.params());
    let mut poses = vec![pa.frames[0][0].pose; 8];
    poses[6].t.x += 0.008;
    poses[7].t.x += 0.016;
    let (behind, clean) = film_poses(&ball, &poses);
    // Noise-free (a renderer's frames at rest are equal) and with a camera's noise, different in every frame
    // (±2.5/255 in each channel): a still scene never shows the same image twice.
    for noise in [0.0, 0.01] {
        eprintln!("noise ±{noise}");
        let frames = with_noise(&clean, noise);
        still_frames_are_kept(&ball, &behind, &frames, &rest_world, &pa, &poses);
    }
}

/// `frames` with uniform noise of ±`amplitude` added to every colour channel, another draw in each frame.
fn with_noise(frames: &[recon::FrameTarget], amplitude: f64) -> Vec<recon::FrameTarget> {
    let mut rng = geom::SplitMix64::new(11);
    frames
        .iter()
        .map(|f| recon::FrameTarget {
            camera: f.camera,
            rgb: f
                .rgb
                .iter()
                .map(|c| c.map(|v| (v + rng.range(-amplitude, amplitude) as f32).clamp(0.0, 1.0)))
                .collect(),
            mask: f.mask.clone(),
            exposure: f.exposure,
            shutter: f.shutter,
            mask_computed: f.mask_computed,
        })
        .collect()
}

fn still_frames_are_kept(
    ball: &neus::ObjectModel,
    behind: &[neus::compose::ComposedRay],
    frames: &[recon::FrameTarget],
    rest_world: &sim::World,
    pa: &sim::Trajectory<f64>,
    poses: &[Pose<f64>],
) {
    let cfg = PosesFromVideoConfig {
        pose: recon::PoseFitConfig {
            lr_rotation: 0.0,
            ..short_fits().pose
        },
        end_search_ratio: 0.0,
        ..short_fits()
    };
    let mut ga = PosesFromVideo::new(cfg, ball, behind, frames, rest_world, 0, pa).expect("valid input");
    let kept = ga.run().expect("every frame fits").to_vec();
    let off = |k: usize| (kept[k].pose.t - poses[k].t).norm() * 1e3;
    for (k, r) in kept.iter().enumerate() {
        eprintln!(
            "frame {k}: {:.2} mm from {:?}, loss {:.4}",
            off(k),
            r.start,
            r.image.loss
        );
    }
    let still: Vec<usize> = (0..poses.len())
        .filter(|&k| kept[k].start == recon::StartFrom::Still)
        .collect();
    // Measured (noise-free): frame 0 fitted 0.07 mm off, frames 1–5 0.27 mm off and 2–5 kept.
    assert!(
        still.len() >= 2,
        "the resting frames after two still ones are kept: {still:?}"
    );
    for &k in &still {
        assert!((2..6).contains(&k), "only resting frames are kept: {still:?}");
        assert_eq!(
            kept[k].pose.t.to_array(),
            kept[k - 1].pose.t.to_array(),
            "frame {k} holds the pose before"
        );
        assert!(off(k) < 0.5, "and it is right: {:.2} mm", off(k));
        assert!(kept[k].image.loss <= kept[k - 1].image.loss * (1.0 + recon::STILL_LOSS_SLACK));
    }
    // The pushed frames (8 and 16 mm on) are fitted, to the image's precision (measured 0.35 and 0.53 mm:
    // the contact penalty leaves the depth to the image within it).
    for k in 6..8 {
        assert_ne!(kept[k].start, recon::StartFrom::Still);
        assert!(off(k) < 1.0, "frame {k}: {:.2} mm", off(k));
    }
}

#[test]
fn a_frame_held_off_its_pose_by_a_wrongly_reconstructed_scene_is_fitted_by_the_images_alone() {
    let ball = ball_model();
    // The block rests on the board for 4 frames and, in the last, rests 10 cm away (as the existing tests
    // turn it); PA has it right. The scene the contact penalty reads has a bump 8 mm high under the block's
    // last place alone (as a reconstructed scene rounds the foot of a wall into a fillet the body truly
    // presses into); the images show the block on the board.
    let truth = resting_world(5, [-0.04, 0.02]);
    let mut pa = truth.simulate(&truth.params());
    let bumped = pa.frames.len() - 1;
    pa.frames[bumped][0].pose.t.x += 0.1;
    let poses: Vec<Pose<f64>> = pa.frames.iter().map(|f| f[0].pose).collect();
    let (behind, frames) = film_poses(&ball, &poses);
    let at = poses[bumped].t;
    let mut reconstructed = truth.clone();
    reconstructed.scene = sim::sdf::Shape::Union(vec![
        truth.scene.clone(),
        sim::sdf::Shape::Cuboid(sim::sdf::Cuboid {
            half: [0.012, 0.02, 0.008],
        })
        .transformed(Pose::from_translation(Vec3::new(at.x, at.y, 0.0))),
    ]);
    let run = |ratio: f64| {
        let cfg = PosesFromVideoConfig {
            end_search_ratio: 0.0,
            unheld_ratio: ratio,
            ..short_fits()
        };
        let mut ga = PosesFromVideo::new(cfg, &ball, &behind, &frames, &reconstructed, 0, &pa).expect("valid input");
        ga.run().expect("every frame fits").to_vec()
    };
    let held = run(0.0);
    // At this camera's 128 × 96 pixels the block held 3.7 mm off is explained 1.8 times worse than the
    // resting frames (the tabletop slide's wall frame at 320 × 240: 5 times), under the default's 2.
    let freed = run(1.5);
    let off = |r: &recon::FramePose, k: usize| (r.pose.t - poses[k].t).norm() * 1e3;
    for (k, (a, b)) in freed.iter().zip(&held).enumerate() {
        eprintln!(
            "frame {k}: {:.2} mm from {:?}, loss {:.4} (held: {:.2} mm from {:?}, loss {:.4}, penalty {:.4} {})",
            off(a, k),
            a.start,
            a.image.loss,
            off(b, k),
            b.start,
            b.image.loss,
            b.contact_penalty,
            b.in_contact
        );
    }
    assert!(off(&held[bumped], bumped) > 3.0, "held off by the bump");
    assert_eq!(freed[bumped].start, recon::StartFrom::Unheld);
    assert!(!freed[bumped].in_contact);
    // Measured: 3.74 mm off held (its loss 1.8 times the resting frames'), 2.39 mm by the images alone (1.26
    // times: the rest is depth, which this camera's pixels tell to about 3 mm).
    assert!(
        off(&freed[bumped], bumped) < 0.7 * off(&held[bumped], bumped),
        "by the images alone: {:.2} mm",
        off(&freed[bumped], bumped)
    );
    let worst_rest = held[..bumped].iter().map(|r| r.image.loss).fold(0.0, f64::max);
    assert!(held[bumped].image.loss > 1.5 * worst_rest);
    assert!(
        freed[bumped].image.loss < 1.3 * worst_rest,
        "explained about as well as the resting frames: {:.4} against {worst_rest:.4}",
        freed[bumped].image.loss
    );
    for k in (0..poses.len()).filter(|&k| k != bumped) {
        assert_eq!(
            freed[k].start, held[k].start,
            "frame {k} is explained as well and not refitted"
        );
    }
}
