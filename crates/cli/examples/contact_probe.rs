//! Dev probe: how the motion of synth's contact scenes moves with the solvers' time steps and knobs, ours
//! and Rapier's (both deterministic, so every difference is the change made).
//!
//! ```sh
//! cargo run --release --example contact_probe -- self       # each scene: Rapier at 2x..16x its substeps, ours
//! cargo run --release --example contact_probe -- search 300 # random spinning drops onto the ramp (default 40)
//! cargo run --release --example contact_probe -- tumble 100 # the toy set down spinning on the ramp's slope
//! cargo run --release --example contact_probe -- lasting    # touching two frames apart: did it touch between?
//! cargo run --release --example contact_probe -- ramp-drop  # one scene: per-frame errors under our knobs
//! cargo run --release --example contact_probe -- preset:tabletop  # a preset's videos, the same spreads
//! cargo run --release --example contact_probe -- pga:tabletop  # PGA on the true poses, 50 % off, each model
//! ```
use geom::Pose;
use sim::ContactModel;
use std::path::Path;
use synth::{contact_scenes, simulate_videos, Physics};

fn errs(a: &[Pose<f64>], b: &[Pose<f64>]) -> String {
    a.iter()
        .zip(b)
        .map(|(p, q)| {
            format!(
                "{:.1}/{:.0}",
                (p.t - q.t).norm() * 1e3,
                geom::rotation_distance(p.q, q.q).to_degrees()
            )
        })
        .collect::<Vec<_>>()
        .join(" ")
}

fn max_err(a: &[Pose<f64>], b: &[Pose<f64>]) -> (f64, f64) {
    a.iter().zip(b).fold((0.0f64, 0.0f64), |(e, r), (p, q)| {
        (
            e.max((p.t - q.t).norm() * 1e3),
            r.max(geom::rotation_distance(p.q, q.q).to_degrees()),
        )
    })
}

fn rapier_poses(scene: &synth::SynthScene, factor: usize) -> Vec<Pose<f64>> {
    let mut s = scene.clone();
    s.physics = Physics::Rapier;
    s.videos[0].substeps *= factor;
    let t = simulate_videos(&s, Path::new(".")).unwrap();
    t[0].1.frames.iter().map(|f| f[0].pose).collect()
}

fn ours_poses(scene: &synth::SynthScene, model: ContactModel, factor: usize) -> Vec<Pose<f64>> {
    let mut w = simulate_videos(scene, Path::new(".")).unwrap()[0].0.clone();
    w.config.contact_model = model;
    w.config.substeps *= factor;
    w.simulate(&w.params()).frames.iter().map(|f| f[0].pose).collect()
}

/// Rapier against itself at finer steps, and ours against each.
fn self_consistency(scene: &synth::SynthScene) -> String {
    let r1 = rapier_poses(scene, 1);
    let r2 = rapier_poses(scene, 2);
    let r4 = rapier_poses(scene, 4);
    let r8 = rapier_poses(scene, 8);
    let r16 = rapier_poses(scene, 16);
    let o = ours_poses(scene, ContactModel::MultiPoint, 1);
    let o4 = ours_poses(scene, ContactModel::MultiPoint, 4);
    let f = |e: (f64, f64)| format!("{:.1} mm/{:.0}°", e.0, e.1);
    let turn = geom::rotation_distance(r1[0].q, r1[r1.len() - 1].q).to_degrees();
    format!(
        "rapier x2 vs x1 {} | x4 vs x2 {} | x8 vs x4 {} | x16 vs x8 {} | ours vs rapier x1 {} | ours vs x4 {} | ours x4 vs ours {} | turned {turn:.0}°",
        f(max_err(&r2, &r1)),
        f(max_err(&r4, &r2)),
        f(max_err(&r8, &r4)),
        f(max_err(&r16, &r8)),
        f(max_err(&o, &r1)),
        f(max_err(&o, &r4)),
        f(max_err(&o4, &o))
    )
}

fn main() {
    let name = std::env::args().nth(1).unwrap_or_else(|| "ramp-drop".into());
    if name == "self" {
        for s in contact_scenes() {
            println!("{:>14}: {}", s.name, self_consistency(&s));
        }
        return;
    }
    if let Some(preset) = name.strip_prefix("preset:") {
        // A preset's videos: Rapier against itself at 2× and 4× its substeps, and ours (multi-point) at 4×
        // against ours.
        let scene = synth::preset(preset, synth::Scale::Small).unwrap();
        let run = |physics: Physics, factor: usize, model: ContactModel| {
            let mut s = scene.clone();
            s.physics = physics;
            for v in &mut s.videos {
                v.substeps *= factor;
            }
            simulate_videos(&s, Path::new("."))
                .unwrap()
                .into_iter()
                .map(|(mut w, t)| {
                    if physics == Physics::Pganeus {
                        w.config.contact_model = model;
                        w.simulate(&w.params())
                    } else {
                        t
                    }
                })
                .map(|t| t.frames.iter().map(|f| f[0].pose).collect::<Vec<Pose<f64>>>())
                .collect::<Vec<_>>()
        };
        let r1 = run(Physics::Rapier, 1, ContactModel::MultiPoint);
        let r2 = run(Physics::Rapier, 2, ContactModel::MultiPoint);
        let r4 = run(Physics::Rapier, 4, ContactModel::MultiPoint);
        for model in [ContactModel::MeanPoint, ContactModel::MultiPoint] {
            let o1 = run(Physics::Pganeus, 1, model);
            let o4 = run(Physics::Pganeus, 4, model);
            for (i, v) in scene.videos.iter().enumerate() {
                let f = |e: (f64, f64)| format!("{:.1} mm/{:.0}°", e.0, e.1);
                println!(
                    "{} {model:?}: rapier x2 vs x1 {} | x4 vs x2 {} | ours vs rapier {} | ours x4 vs rapier x4 {} | ours x4 vs ours {}",
                    v.name,
                    f(max_err(&r2[i], &r1[i])),
                    f(max_err(&r4[i], &r2[i])),
                    f(max_err(&o1[i], &r1[i])),
                    f(max_err(&o4[i], &r4[i])),
                    f(max_err(&o4[i], &o1[i]))
                );
            }
        }
        return;
    }
    if let Some(preset) = name.strip_prefix("pga:") {
        pga_on_true_poses(preset);
        return;
    }
    if name == "search" {
        let base = contact_scenes().into_iter().find(|s| s.name == "ramp-drop").unwrap();
        let mut rng = geom::SplitMix64::new(5);
        let n: usize = std::env::args().nth(2).and_then(|a| a.parse().ok()).unwrap_or(40);
        for i in 0..n {
            let mut s = base.clone();
            let axis = geom::Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            let q = geom::Quat::exp(axis * 1.5);
            let b = &mut s.videos[0].bodies[0];
            // Rounded as a scene file would write them (the motion is that sensitive).
            let r = |v: f64, k: f64| (v * k).round() / k;
            b.q = [q.w, q.x, q.y, q.z].map(|v| r(v, 100.0));
            b.omega = [rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-2.0, 2.0)].map(|v| r(v, 10.0));
            b.t[0] = r(rng.range(-0.04, 0.04), 1000.0);
            let label = format!(
                "{i:>2} q {:?} omega {:?} x {:.3}",
                b.q.map(|v| (v * 100.0).round() / 100.0),
                b.omega.map(|v| (v * 10.0).round() / 10.0),
                b.t[0]
            );
            println!("{label}: {}", self_consistency(&s));
        }
        return;
    }
    if name == "lasting" {
        lasting_contacts();
        return;
    }
    if name == "tumble" {
        // Tumbles that need not be knife-edge: the toy lying on the slope's face a few centimetres above it,
        // rolled downhill about the slope's cross axis (a die thrown down a slope), its start varied a little.
        let base = contact_scenes().into_iter().find(|s| s.name == "ramp-drop").unwrap();
        // The ramp rises towards +x over its length `2 hx` by its height `2 hz` (sim's `Wedge`), placed at `t`.
        let ramp = &base.obstacles[0];
        let synth::desc::ShapeDesc::Wedge { half: [hx, _, hz] } = ramp.shape else {
            panic!("the ramp-drop scene's obstacle is its ramp");
        };
        let rise = hz / hx;
        let surface_z = |x: f64| ramp.t[2] + rise * (x - ramp.t[0]);
        let mut rng = geom::SplitMix64::new(7);
        let n: usize = std::env::args().nth(2).and_then(|a| a.parse().ok()).unwrap_or(40);
        let slope = rise.atan();
        for i in 0..n {
            let mut s = base.clone();
            let r = |v: f64, k: f64| (v * k).round() / k;
            let wobble = geom::Vec3::new(rng.range(-0.2, 0.2), rng.range(-0.2, 0.2), rng.range(-0.6, 0.6));
            let q = geom::Quat::exp(geom::Vec3::new(0.0, -slope, 0.0)) * geom::Quat::exp(wobble);
            let x = rng.range(0.0, 0.05);
            let lift = rng.range(0.01, 0.05);
            let spin = rng.range(-14.0, -4.0);
            let b = &mut s.videos[0].bodies[0];
            b.q = [q.w, q.x, q.y, q.z].map(|v| r(v, 100.0));
            // The toy's centre 3 cm over the slope (its half-height and a margin), lifted by `lift`.
            b.t = [r(x, 1000.0), 0.0, r(surface_z(x) + 0.03 + lift, 1000.0)];
            b.v = [r(rng.range(-0.4, 0.0), 100.0), 0.0, 0.0];
            b.omega = [rng.range(-1.0, 1.0), spin, rng.range(-1.0, 1.0)].map(|v| r(v, 10.0));
            let label = format!("{i:>2} q {:?} t {:?} v {:?} omega {:?}", b.q, b.t, b.v, b.omega);
            println!("{label}: {}", self_consistency(&s));
        }
        return;
    }
    let scene = contact_scenes().into_iter().find(|s| s.name == name).unwrap();
    let ours = simulate_videos(&scene, Path::new(".")).unwrap();
    let rapier = |substeps_factor: usize| {
        let mut s = scene.clone();
        s.physics = Physics::Rapier;
        s.videos[0].substeps *= substeps_factor;
        let t = simulate_videos(&s, Path::new(".")).unwrap();
        t[0].1.frames.iter().map(|f| f[0]).collect::<Vec<_>>()
    };
    let r1 = rapier(1);
    let poses: Vec<Pose<f64>> = r1.iter().map(|s| s.pose).collect();
    let r2: Vec<Pose<f64>> = rapier(2).iter().map(|s| s.pose).collect();
    let r4: Vec<Pose<f64>> = rapier(4).iter().map(|s| s.pose).collect();
    println!("rapier x2 substeps vs rapier: {}", errs(&r2, &poses));
    println!("rapier x4 substeps vs rapier: {}", errs(&r4, &poses));
    println!("rapier x4 vs rapier x2:       {}", errs(&r4, &r2));
    for (i, s) in r1.iter().enumerate().take(10) {
        println!("rapier frame {i}: t {:?} v {:?} w {:?}", s.pose.t, s.v, s.omega);
    }
    let base = ours[0].0.clone();
    type Knob = (&'static str, fn(&mut sim::World));
    let knobs: [Knob; 8] = [
        ("multi_point", |_| {}),
        ("mean_point", |w| w.config.contact_model = ContactModel::MeanPoint),
        ("substeps x4", |w| w.config.substeps *= 4),
        ("sweeps 50", |w| w.config.solver_sweeps = 50),
        ("threshold 2 mm", |w| w.config.contact_threshold = 0.002),
        ("no speculative", |w| w.config.speculative_contacts = false),
        ("restitution threshold 0", |w| {
            w.config.restitution_threshold = Some(0.0)
        }),
        ("substeps x4 sweeps 50", |w| {
            w.config.substeps *= 4;
            w.config.solver_sweeps = 50
        }),
    ];
    for (label, knob) in knobs {
        let mut w = base.clone();
        w.config.contact_model = ContactModel::MultiPoint;
        knob(&mut w);
        let t = w.simulate(&w.params());
        let p: Vec<Pose<f64>> = t.frames.iter().map(|f| f[0].pose).collect();
        println!("{label:>24}: {}", errs(&p, &poses));
        if label == "multi_point" {
            for (i, s) in t.frames.iter().enumerate().take(10) {
                println!("ours frame {i}: t {:?} v {:?} w {:?}", s[0].pose.t, s[0].v, s[0].omega);
            }
        }
    }
}

/// PGA (Eq. 11, as `fit` runs it: the initial pose refined, the multi-start) on the true poses of a preset's
/// videos (scale large), from v0 and ω0 50 % off and the contact values of a guess, for each maker of the
/// motion (our two models, Rapier) and each fitting model: how far the fitted simulation ends from the truth.
fn pga_on_true_poses(preset: &str) {
    let scene = synth::preset(preset, synth::Scale::Large).unwrap();
    let made: [(&str, Physics, ContactModel); 3] = [
        ("mean_point", Physics::Pganeus, ContactModel::MeanPoint),
        ("multi_point", Physics::Pganeus, ContactModel::MultiPoint),
        ("rapier", Physics::Rapier, ContactModel::MeanPoint),
    ];
    for (maker, physics, model) in made {
        let mut s = scene.clone();
        s.physics = physics;
        for (i, (world, traj)) in simulate_videos(&s, Path::new(".")).unwrap().into_iter().enumerate() {
            let truth: Vec<Pose<f64>> = if physics == Physics::Pganeus {
                let mut w = world.clone();
                w.config.contact_model = model;
                w.simulate(&w.params()).frames.iter().map(|f| f[0].pose).collect()
            } else {
                traj.frames.iter().map(|f| f[0].pose).collect()
            };
            let true_v = world.initial[0].v;
            for fit_model in [ContactModel::MeanPoint, ContactModel::MultiPoint] {
                let mut w = world.clone();
                w.config.contact_model = fit_model;
                w.initial[0].v = world.initial[0].v * 1.5;
                w.initial[0].omega = world.initial[0].omega * 1.5;
                w.scene_contact[0] = sim::ContactParams {
                    restitution: 0.25,
                    friction: 0.375,
                };
                let cfg = recon::PhysicsFitConfig {
                    fit_initial_pose: true,
                    rotation_weight: w.bodies[0].bounding_radius,
                    ..Default::default()
                };
                let t0 = std::time::Instant::now();
                let multi =
                    recon::fit_multi_start(cfg, w, 0, truth.clone(), None, &recon::CONTACT_STARTS, &mut |_, _| {})
                        .unwrap();
                let fitted = multi.best.fitted_world();
                let poses: Vec<Pose<f64>> = fitted
                    .simulate(&fitted.params())
                    .frames
                    .iter()
                    .map(|f| f[0].pose)
                    .collect();
                let (mean, _) = poses
                    .iter()
                    .zip(&truth)
                    .fold((0.0, 0), |(m, n), (p, q)| (m + (p.t - q.t).norm() * 1e3, n + 1));
                let (worst_t, worst_r) = max_err(&poses, &truth);
                let v = fitted.initial[0].v;
                let c = fitted.scene_contact[0];
                println!(
                    "{} made by {maker:>11}, fitted by {fit_model:?}: mean {:.2} mm, worst {worst_t:.2} mm / {worst_r:.1}°; v0 {:.1} % off; k_n {:.3}, mu {:.3}; start {} won; {:.0} s",
                    s.videos[i].name,
                    mean / poses.len() as f64,
                    (v - true_v).norm() / true_v.norm() * 100.0,
                    c.restitution,
                    c.friction,
                    multi.winner,
                    t0.elapsed().as_secs_f64()
                );
            }
        }
    }
}

/// Over the truth of every preset's videos (both scales, both engines) and the contact scenes: each frame
/// whose frames before and after touch the same side of the scene, how the parts of the body touching
/// there compare, and whether the body touched in the frame between.
fn lasting_contacts() {
    let mut scenes: Vec<(String, synth::SynthScene)> = Vec::new();
    for preset in ["tabletop", "backdrop", "two-body"] {
        for (scale, sn) in [(synth::Scale::Small, "small"), (synth::Scale::Large, "large")] {
            for physics in [Physics::Pganeus, Physics::Rapier] {
                let mut s = synth::preset(preset, scale).unwrap();
                s.physics = physics;
                scenes.push((format!("{preset}/{sn}/{physics:?}"), s));
            }
        }
    }
    for s in contact_scenes() {
        let mut r = s.clone();
        r.physics = Physics::Rapier;
        scenes.push((s.name.clone(), r));
    }
    for (label, scene) in scenes {
        for (vi, (world, traj)) in simulate_videos(&scene, Path::new(".")).unwrap().into_iter().enumerate() {
            let threshold = world.config.contact_threshold;
            for (b, body) in world.bodies.iter().enumerate() {
                // Each frame's touching points, as GA's `sides_touched` takes them: within the contact
                // threshold and within `TOUCHING` of the lowest.
                let near: Vec<Vec<sim::NearPoint<f64>>> = traj
                    .frames
                    .iter()
                    .map(|f| {
                        let pts = sim::points_near_scene(body, &f[b].pose, &world.scene, threshold);
                        let within = pts
                            .first()
                            .map_or(0.0, |p| p.distance + recon::video_fit::TOUCHING)
                            .min(threshold);
                        pts.into_iter().filter(|p| p.distance <= within).collect()
                    })
                    .collect();
                for k in 1..traj.frames.len() - 1 {
                    let (a, c) = (&near[k - 1], &near[k + 1]);
                    if a.is_empty() || c.is_empty() {
                        continue;
                    }
                    // Pairs facing the same side: the body-frame chord and the world distance.
                    let mut best_chord = f64::INFINITY;
                    let mut best_slack = f64::INFINITY;
                    for p in a {
                        for q in c {
                            if !recon::contact_penalty::faces(p.gradient, q.gradient) {
                                continue;
                            }
                            let chord = (body.contact_points[p.index] - body.contact_points[q.index]).norm();
                            let world_d = (p.world - q.world).norm();
                            best_chord = best_chord.min(chord);
                            best_slack = best_slack.min(chord - world_d);
                        }
                    }
                    if !best_chord.is_finite() {
                        continue;
                    }
                    let between = traj.frames[k][b].pose;
                    let gap = recon::video_fit::clearance(body, &world.scene, &between);
                    let turn = geom::rotation_distance(traj.frames[k - 1][b].pose.q, traj.frames[k + 1][b].pose.q);
                    println!(
                        "{label} {} {} frame {k}: chord {:.1} mm, chord - travel {:.1} mm, turned {:.0}°, gap between {:.1} mm{}",
                        scene.videos[vi].name,
                        body.name,
                        best_chord * 1e3,
                        best_slack * 1e3,
                        turn.to_degrees(),
                        gap * 1e3,
                        if gap > threshold { "  <- off" } else { "" }
                    );
                }
            }
        }
    }
}
