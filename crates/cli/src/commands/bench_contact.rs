//! How well each contact model explains motion another engine made: for each
//! of synth's contact scenes (`synth::contact_scenes`), Rapier moves the body;
//! the project's simulator, with the true shapes and the true start, is run
//! with the true contact values (`unfitted`) and then fitted to Rapier's poses
//! by `fit-physics` (v0, ω0, k_n, μ; multi-start unless `--single-start`).
//! One JSON line per scene and model: the pose error in every frame (mean,
//! max, max rotation) before and after the fit, and beside them Rapier's own
//! spread: its motion at half the time step against the reference. Where
//! Rapier at a half and a quarter of its step leaves the reference by more than
//! the bar (5 mm, 5°), the reference does not say where the body goes; the
//! frames before that (`converged_frames`) are where a model can be held to it:
//! the fit's error there, and a fit to those frames alone.

use anyhow::{anyhow, Result};
use clap::Args;
use geom::Pose;
use recon::{fit_multi_start, PhysicsFitConfig, CONTACT_STARTS};
use sim::{ContactModel, World};
use std::path::Path;
use synth::{contact_scenes, simulate_videos, Physics};

#[derive(Args)]
#[command(after_help = "Examples:
  pganeus bench-contact
  pganeus bench-contact --scene tipping-slide --per-frame")]
pub struct BenchContactArgs {
    /// Only these scenes (default: all of tipping-slide, ramp-drop, rocking, push).
    #[arg(long)]
    pub scene: Vec<String>,
    /// Fit only from the true contact values.
    #[arg(long)]
    pub single_start: bool,
    /// Maximum Levenberg–Marquardt iterations per fit.
    #[arg(long, default_value_t = 40)]
    pub iterations: usize,
    /// Also print each frame's error (mm, degrees) before and after the fit.
    #[arg(long)]
    pub per_frame: bool,
}

/// Mean and max translation error (m) and max rotation error (degrees) of `world` simulated with `params`
/// against `poses`.
fn errors(world: &World, params: &[f64], poses: &[Pose<f64>]) -> (f64, f64, f64) {
    let traj = world.simulate(params);
    pose_errors(traj.frames.iter().map(|f| &f[0].pose), poses)
}

/// Mean and max translation error (m) and max rotation error (degrees) of `moved` against `poses`.
fn pose_errors<'a>(moved: impl Iterator<Item = &'a Pose<f64>>, poses: &[Pose<f64>]) -> (f64, f64, f64) {
    let (mut sum, mut max, mut rot) = (0.0, 0.0f64, 0.0f64);
    for (m, p) in moved.zip(poses) {
        let e = (m.t - p.t).norm();
        sum += e;
        max = max.max(e);
        rot = rot.max(geom::rotation_distance(m.q, p.q).to_degrees());
    }
    (sum / poses.len() as f64, max, rot)
}

/// Each frame's translation error (mm) and rotation error (degrees), rounded.
fn per_frame(world: &World, params: &[f64], poses: &[Pose<f64>]) -> Vec<(f64, f64)> {
    let traj = world.simulate(params);
    traj.frames
        .iter()
        .zip(poses)
        .map(|(f, p)| {
            let e = (f[0].pose.t - p.t).norm() * 1e3;
            let r = geom::rotation_distance(f[0].pose.q, p.q).to_degrees();
            ((e * 10.0).round() / 10.0, (r * 10.0).round() / 10.0)
        })
        .collect()
}

/// The bar a model is held to against the reference in every frame (m, degrees).
const BAR: (f64, f64) = (0.005, 5.0);

/// How many leading frames every one of `finer` (the reference's motion at finer steps) stays within
/// [`BAR`] of `poses`.
fn converged_frames(poses: &[Pose<f64>], finer: &[Vec<Pose<f64>>]) -> usize {
    let within = |k: usize| {
        finer.iter().all(|f| {
            (f[k].t - poses[k].t).norm() <= BAR.0 && geom::rotation_distance(f[k].q, poses[k].q).to_degrees() <= BAR.1
        })
    };
    (0..poses.len()).take_while(|&k| within(k)).count()
}

fn mm(e: (f64, f64, f64)) -> serde_json::Value {
    serde_json::json!({
        "mean_mm": (e.0 * 1e4).round() / 10.0,
        "max_mm": (e.1 * 1e4).round() / 10.0,
        "max_rotation_deg": (e.2 * 10.0).round() / 10.0,
    })
}

pub fn run(a: BenchContactArgs) -> Result<()> {
    let scenes: Vec<_> = contact_scenes()
        .into_iter()
        .filter(|s| a.scene.is_empty() || a.scene.contains(&s.name))
        .collect();
    if scenes.is_empty() {
        return Err(anyhow!(
            "no scene named {:?} (scenes: {})",
            a.scene,
            synth::CONTACT_SCENES.join(", ")
        ));
    }
    for mut scene in scenes {
        let ours = simulate_videos(&scene, Path::new("."))?;
        scene.physics = Physics::Rapier;
        let theirs = simulate_videos(&scene, Path::new("."))?;
        let (world, _) = &ours[0];
        let poses: Vec<Pose<f64>> = theirs[0].1.frames.iter().map(|f| f[0].pose).collect();
        // The reference against itself at a half and a quarter of its time step: where a scene is so sensitive
        // that Rapier moves this far, no model can be held closer to it than that.
        let mut finer = Vec::new();
        for factor in [2, 4] {
            let mut s = scene.clone();
            s.videos[0].substeps *= factor;
            let t = simulate_videos(&s, Path::new("."))?;
            finer.push(t[0].1.frames.iter().map(|f| f[0].pose).collect::<Vec<_>>());
        }
        let spread = pose_errors(finer[0].iter(), &poses);
        let converged = converged_frames(&poses, &finer);
        for model in [ContactModel::MeanPoint, ContactModel::MultiPoint] {
            let mut w = world.clone();
            w.config.contact_model = model;
            let unfitted = errors(&w, &w.params(), &poses);
            let t0 = std::time::Instant::now();
            let cfg = PhysicsFitConfig {
                iterations: a.iterations,
                ..PhysicsFitConfig::default()
            };
            let starts: &[(f64, f64)] = if a.single_start { &[] } else { &CONTACT_STARTS };
            let multi = fit_multi_start(cfg.clone(), w.clone(), 0, poses.clone(), None, starts, &mut |_, _| {})
                .map_err(|e| anyhow!("{}: {e}", scene.name))?;
            let fitted_world = multi.best.fitted_world();
            let fitted = errors(&fitted_world, &fitted_world.params(), &poses);
            let p = multi.best.fitted_body_params();
            // The same fit's error over the frames the reference is converged in, and a fit to those alone.
            let while_converged = errors(&fitted_world, &fitted_world.params(), &poses[..converged]);
            let on_converged = if converged < 2 {
                serde_json::Value::Null
            } else if converged < poses.len() {
                let mut short = w.clone();
                short.config.frames = converged;
                let window = poses[..converged].to_vec();
                let m = fit_multi_start(cfg.clone(), short, 0, window.clone(), None, starts, &mut |_, _| {})
                    .map_err(|e| anyhow!("{}: {e}", scene.name))?;
                let fw = m.best.fitted_world();
                mm(errors(&fw, &fw.params(), &window))
            } else {
                mm(fitted)
            };
            println!(
                "{}",
                serde_json::json!({
                    "bench": "contact", "scene": scene.name, "model": match model {
                        ContactModel::MeanPoint => "mean_point",
                        ContactModel::MultiPoint => "multi_point",
                    },
                    "frames": poses.len(), "unfitted": mm(unfitted), "fitted": mm(fitted),
                    "rapier_half_step": mm(spread), "converged_frames": converged,
                    "fitted_while_converged": mm(while_converged), "fitted_on_converged": on_converged,
                    "restitution": p[6], "friction": p[7],
                    "true_contact": [scene.videos[0].contact.restitution, scene.videos[0].contact.friction],
                    "winner": multi.winner, "seconds": (t0.elapsed().as_secs_f64() * 10.0).round() / 10.0,
                })
            );
            if a.per_frame {
                println!(
                    "{}",
                    serde_json::json!({
                        "scene": scene.name,
                        "unfitted_per_frame": per_frame(&w, &w.params(), &poses),
                        "fitted_per_frame": per_frame(&fitted_world, &fitted_world.params(), &poses),
                    })
                );
            }
        }
    }
    Ok(())
}
