use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use geom::Pose;
use recon::{fit_multi_start, PhysicsFitConfig, CONTACT_STARTS};
use scene_file::SceneFile;
use std::path::PathBuf;

#[derive(Args)]
#[command(after_help = "Examples:
  pganeus fit-physics --poses out/tabletop.json --scene scenes/tabletop_guess.toml --out out/fitted.json")]
pub struct FitPhysicsArgs {
    /// The observed poses: a trajectory.json (one pose per frame).
    #[arg(long)]
    pub poses: PathBuf,
    /// Scene file: the static scene, the body, and the start guess (v, omega, contact).
    #[arg(long)]
    pub scene: PathBuf,
    /// The body to fit (default: the scene's first body).
    #[arg(long)]
    pub body: Option<String>,
    /// Per-frame weights w_i of Eq. 11: a JSON array with one number per frame.
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Maximum iterations.
    #[arg(long, default_value_t = 40)]
    pub iterations: usize,
    /// Weight of the quaternion error against the translation error (Eq. 11 uses 1).
    #[arg(long, default_value_t = 1.0)]
    pub rotation_weight: f64,
    /// Keep v0 at the start guess.
    #[arg(long)]
    pub fix_velocity: bool,
    /// Keep omega0 at the start guess.
    #[arg(long)]
    pub fix_omega: bool,
    /// Keep the restitution at the start guess.
    #[arg(long)]
    pub fix_restitution: bool,
    /// Keep the friction at the start guess.
    #[arg(long)]
    pub fix_friction: bool,
    /// Also refine the initial pose.
    #[arg(long)]
    pub fit_pose: bool,
    /// Fit only from the scene file's contact values (no multi-start over restitution × friction).
    #[arg(long)]
    pub single_start: bool,
    /// Where to write the fitted trajectory.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(a: FitPhysicsArgs) -> Result<()> {
    let scene = SceneFile::load(&a.scene)?;
    let mut world = scene.world;
    let obs = pganeus_io::read_trajectory(&a.poses)?;
    let body = match &a.body {
        None => 0,
        Some(n) => world
            .bodies
            .iter()
            .position(|b| &b.name == n)
            .ok_or_else(|| anyhow!("--body: no body named \"{n}\" in {}", a.scene.display()))?,
    };
    let name = world.bodies[body].name.clone();
    let observed = match obs.body(&name) {
        Some(b) => b,
        None if obs.bodies.len() == 1 => &obs.bodies[0],
        None => bail!(
            "{}: no body named \"{name}\" (bodies: {:?})",
            a.poses.display(),
            obs.bodies.iter().map(|b| &b.name).collect::<Vec<_>>()
        ),
    };
    let poses: Vec<Pose<f64>> = observed.poses.iter().map(pganeus_io::Pose::to_geom).collect();
    let weights = match &a.weights {
        None => None,
        Some(p) => {
            let text = std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?;
            let w: Vec<f64> = serde_json::from_str(&text)
                .map_err(|e| anyhow!("{}: expected a JSON array of numbers: {e}", p.display()))?;
            Some(w)
        }
    };
    // The simulator steps at the video's frame rate (Sec. 4.1).
    world.config.fps = obs.fps;
    let cfg = PhysicsFitConfig {
        iterations: a.iterations,
        rotation_weight: a.rotation_weight,
        fit_velocity: !a.fix_velocity,
        fit_angular_velocity: !a.fix_omega,
        fit_restitution: !a.fix_restitution,
        fit_friction: !a.fix_friction,
        fit_initial_pose: a.fit_pose,
        ..PhysicsFitConfig::default()
    };
    let t0 = std::time::Instant::now();
    // The scene file's contact values, then a grid over restitution × friction (unless fixed or asked not to).
    let starts: &[(f64, f64)] = if a.single_start || a.fix_restitution || a.fix_friction {
        &[]
    } else {
        &CONTACT_STARTS
    };
    // The scene file's values, then each start of the grid.
    let pb = super::progress(1 + starts.len() as u64, "starts");
    let multi = fit_multi_start(cfg, world, body, poses, weights, starts, &mut |i, r| {
        pb.suspend(|| {
            println!(
                "start {i:2} (restitution {:.2}, friction {:.2}): loss {:.6e} after {} iterations",
                r.restitution, r.friction, r.loss, r.iterations
            )
        });
        pb.inc(1);
    })
    .map_err(|e| anyhow!("{}: {e}", a.poses.display()))?;
    pb.finish_and_clear();
    let (fit, history) = (&multi.best, &multi.history);
    if !starts.is_empty() {
        let w = &multi.starts[multi.winner];
        println!(
            "best: start {} (restitution {:.2}, friction {:.2}{})",
            multi.winner,
            w.restitution,
            w.friction,
            if multi.winner == 0 { ", the scene file's" } else { "" }
        );
    }
    for s in history {
        tracing::debug!(
            "iteration {:3}: loss {:.6e} (frames 0..{}, damping {:.1e})",
            s.iteration,
            s.loss,
            s.window,
            s.lambda
        );
    }
    let p = fit.fitted_body_params();
    let errors = fit.pose_errors();
    let mean_t = errors.iter().map(|e| e.translation).sum::<f64>() / errors.len() as f64;
    let max_t = errors.iter().map(|e| e.translation).fold(0.0, f64::max);
    let max_r = errors.iter().map(|e| e.rotation_deg).fold(0.0, f64::max);
    println!("fitted {name} in {:.2} s:", t0.elapsed().as_secs_f64());
    println!("  v0          = [{:.5}, {:.5}, {:.5}] m/s", p[0], p[1], p[2]);
    println!("  omega0      = [{:.5}, {:.5}, {:.5}] rad/s", p[3], p[4], p[5]);
    println!("  restitution = {:.4}", p[6]);
    println!("  friction    = {:.4}", p[7]);
    println!(
        "  pose error  = mean {:.3} mm, max {:.3} mm, max rotation {:.3}°",
        mean_t * 1e3,
        max_t * 1e3,
        max_r
    );
    if let Some(out) = &a.out {
        let w = fit.fitted_world();
        let traj = w.simulate(&w.params());
        let mut extra = serde_json::Map::new();
        extra.insert(
            "fit".into(),
            serde_json::json!({"history": history, "pose_errors": errors, "poses": a.poses,
                "starts": multi.starts, "winner": multi.winner}),
        );
        pganeus_io::write_trajectory(
            out,
            &scene_file::trajectory_file(&obs.capture, &w, &traj, sim::ENGINE, extra),
        )?;
        println!("wrote {}", out.display());
    }
    Ok(())
}
