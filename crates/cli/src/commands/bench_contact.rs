//! How well each contact model explains motion another engine made: for each
//! of synth's contact scenes (`synth::contact_scenes`), Rapier moves the body;
//! the project's simulator, with the true shapes and the true start, is run
//! with the true contact values (`unfitted`) and then fitted to Rapier's poses
//! by `fit-physics` (v0, ω0, k_n, μ; multi-start unless `--single-start`).
//! One JSON line per scene and model: the pose error in every frame (mean,
//! max, max rotation) before and after the fit, and beside them Rapier's own
//! spread: its motion at half the time step against the reference.

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
        // The reference against itself at half the time step: where a scene is so sensitive that Rapier
        // moves this far, no model can be held closer to it than that.
        let mut finer = scene.clone();
        finer.videos[0].substeps *= 2;
        let finer = simulate_videos(&finer, Path::new("."))?;
        let spread = pose_errors(finer[0].1.frames.iter().map(|f| &f[0].pose), &poses);
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
            let multi = fit_multi_start(cfg, w.clone(), 0, poses.clone(), None, starts, &mut |_, _| {})
                .map_err(|e| anyhow!("{}: {e}", scene.name))?;
            let fitted_world = multi.best.fitted_world();
            let fitted = errors(&fitted_world, &fitted_world.params(), &poses);
            let p = multi.best.fitted_body_params();
            println!(
                "{}",
                serde_json::json!({
                    "bench": "contact", "scene": scene.name, "model": match model {
                        ContactModel::MeanPoint => "mean_point",
                        ContactModel::MultiPoint => "multi_point",
                    },
                    "frames": poses.len(), "unfitted": mm(unfitted), "fitted": mm(fitted),
                    "rapier_half_step": mm(spread),
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
