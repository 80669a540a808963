//! `physics = "rapier"`: the synth videos' motion made by Rapier. Its motion
//! must be physical on its own (bodies fall at g, never sink into the board,
//! come to rest lying on it) and start like the project's simulator (the same
//! ballistic flight, the same first contact), while being a different engine
//! (not the same numbers after it).

use std::path::Path;
use synth::{contact_scenes, preset, simulate_videos, Physics, Scale, SynthScene};

fn both(name: &str) -> Vec<(String, sim::World, sim::Trajectory<f64>, sim::Trajectory<f64>)> {
    let scene = preset(name, Scale::Small)
        .or_else(|| contact_scenes().into_iter().find(|s| s.name == name))
        .expect("a preset or a contact scene");
    both_of(scene)
}

fn both_of(mut scene: SynthScene) -> Vec<(String, sim::World, sim::Trajectory<f64>, sim::Trajectory<f64>)> {
    let name = scene.name.clone();
    let ours = simulate_videos(&scene, Path::new(".")).expect("simulates");
    scene.physics = Physics::Rapier;
    let theirs = simulate_videos(&scene, Path::new(".")).expect("simulates with Rapier");
    ours.into_iter()
        .zip(theirs)
        .zip(&scene.videos)
        .map(|(((w, a), (_, b)), v)| (format!("{name}/{}", v.name), w, a, b))
        .collect()
}

fn first_contact(t: &sim::Trajectory<f64>, body: usize) -> Option<usize> {
    t.contacts
        .iter()
        .position(|c| c.scene.get(body).copied().unwrap_or(false))
}

#[test]
fn rapier_moves_the_synth_bodies_like_a_physical_engine() {
    let names = ["tabletop", "two-body", "backdrop"]
        .into_iter()
        .chain(synth::CONTACT_SCENES);
    for (video, world, ours, theirs) in names.flat_map(both) {
        let (fps, substeps) = (world.config.fps, world.config.substeps);
        let n = ours.frames.len();
        assert_eq!(theirs.frames.len(), n, "{video}");
        // The contact record has the simulator's shape in every frame (frame 0's was empty, and writing
        // truth.json indexed it: `synth --physics rapier` panicked).
        let shape = |t: &sim::Trajectory<f64>| {
            t.contacts
                .iter()
                .map(|c| (c.scene.len(), c.scene_points.len(), c.pairs.len()))
                .collect::<Vec<_>>()
        };
        assert_eq!(shape(&theirs), shape(&ours), "{video}");
        for b in 0..ours.frames[0].len() {
            let at = |t: &sim::Trajectory<f64>, k: usize| t.frames[k][b].pose.t;
            // Frame 0 is the given start in both.
            assert!((at(&ours, 0) - at(&theirs, 0)).norm() < 1e-12, "{video}: the start");
            let gap: Vec<f64> = (0..n).map(|k| (at(&ours, k) - at(&theirs, k)).norm()).collect();
            let (c_ours, c_theirs) = (first_contact(&ours, b), first_contact(&theirs, b));
            let last = theirs.frames[n - 1][b];
            eprintln!(
                "{video} body {b} ({}): first scene contact at frame {c_ours:?} (ours) vs {c_theirs:?} (Rapier); position gap max {:.1} mm, final {:.1} mm; Rapier's final height {:.1} mm, speed {:.3} m/s",
                world.bodies[b].name,
                gap.iter().cloned().fold(0.0, f64::max) * 1e3,
                gap[n - 1] * 1e3,
                last.pose.t.z * 1e3,
                last.v.norm()
            );
            // Before any contact both are ballistic: the same positions, up to the integrators' difference
            // (first order in the substep: |g| dt t at most).
            let free = c_ours.unwrap_or(n).min(c_theirs.unwrap_or(n)).saturating_sub(1);
            let dt = 1.0 / (fps * substeps as f64);
            for k in 0..free {
                let bound = 9.81 * dt * (k as f64 / fps) + 1e-9;
                assert!(
                    gap[k] <= bound,
                    "{video}: frame {k} before contact, {:.3} mm apart",
                    gap[k] * 1e3
                );
            }
            if let (Some(a), Some(c)) = (c_ours, c_theirs) {
                assert!(a.abs_diff(c) <= 1, "{video}: first contact at {a} vs {c}");
            }
            // Nothing sinks into the board (its top is z = 0), and the body ends at rest lying on it.
            let lowest = |k: usize| {
                let p = theirs.frames[k][b].pose;
                world.bodies[b]
                    .mesh
                    .vertices
                    .iter()
                    .map(|v| p.transform_point(geom::Vec3::cst(*v)).z)
                    .fold(f64::INFINITY, f64::min)
            };
            for k in 0..n {
                assert!(
                    lowest(k) > -1e-3,
                    "{video}: frame {k}, {:.1} mm into the board",
                    -lowest(k) * 1e3
                );
            }
            // (The ramp-drop may end on the ramp, still sliding: it is not checked for rest.)
            if !video.starts_with("ramp-drop") && last.pose.t.x.abs() < 0.25 && last.pose.t.y.abs() < 0.25 {
                assert!(
                    last.v.norm() < 0.01 && lowest(n - 1).abs() < 1e-3,
                    "{video}: not at rest on the board"
                );
            }
        }
        // A different engine: not the same numbers once contact begins.
        let differs = (0..n).any(|k| (ours.frames[k][0].pose.t - theirs.frames[k][0].pose.t).norm() > 1e-4);
        assert!(differs, "{video}: Rapier's motion equals ours exactly");
    }
}
