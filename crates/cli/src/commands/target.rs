use anyhow::{anyhow, bail, Result};
use clap::Args;
use geom::Vec3;
use recon::{TargetConfig, TargetReach};
use scene_file::SceneFile;
use std::path::PathBuf;

#[derive(Args)]
#[command(after_help = "Examples:
  pganeus target --scene scenes/obstacle.toml --to 0.5,0.05,0.02 --frame 50 --out out/target.json")]
pub struct TargetArgs {
    /// Scene file; the body's `v` is the start guess.
    #[arg(long)]
    pub scene: PathBuf,
    /// The point to reach, "x,y,z" in metres.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, required = true)]
    pub to: Vec<f64>,
    /// The frame at which the body's centre must be there.
    #[arg(long)]
    pub frame: usize,
    /// The body to launch (default: the first).
    #[arg(long)]
    pub body: Option<String>,
    /// Also optimise the initial angular velocity.
    #[arg(long)]
    pub omega: bool,
    /// Maximum iterations.
    #[arg(long, default_value_t = 50)]
    pub iterations: usize,
    /// Skip the fan of launch velocities that gives the optimiser its start.
    #[arg(long)]
    pub no_global_start: bool,
    /// Where to write the trajectory that reaches the target.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(a: TargetArgs) -> Result<()> {
    let scene = SceneFile::load(&a.scene)?;
    let w = scene.world;
    let body = match &a.body {
        None => 0,
        Some(n) => w
            .bodies
            .iter()
            .position(|b| &b.name == n)
            .ok_or_else(|| anyhow!("--body: no body named \"{n}\" in {}", a.scene.display()))?,
    };
    if a.to.len() != 3 {
        bail!("--to takes three numbers \"x,y,z\", got {}", a.to.len());
    }
    let point = Vec3::new(a.to[0], a.to[1], a.to[2]);
    if !point.is_finite() {
        bail!("--to: the target has NaN or infinite values");
    }
    let cfg = TargetConfig {
        iterations: a.iterations,
        fit_angular_velocity: a.omega,
        global_start: !a.no_global_start,
        ..TargetConfig::default()
    };
    let mut stage = TargetReach::new(cfg, w, body, point, a.frame)?;
    println!("start: {:.5} m from the target", stage.distance());
    let pb = super::progress(a.iterations as u64, "iterations");
    loop {
        let s = stage.step();
        pb.set_position(s.iteration as u64);
        pb.set_message(format!("distance {:.5} m", s.distance));
        tracing::debug!("iteration {:3}: distance {:.5} m", s.iteration, s.distance);
        if s.converged {
            break;
        }
    }
    pb.finish_and_clear();
    let solved = stage.solved_world();
    let traj = solved.simulate(&solved.params());
    let s0 = solved.initial[body];
    let mut extra = serde_json::Map::new();
    extra.insert(
        "target".into(),
        serde_json::json!({"body": solved.bodies[body].name, "point": point.to_array(), "frame": a.frame, "distance": stage.distance()}),
    );
    pganeus_io::write_trajectory(
        &a.out,
        &scene_file::trajectory_file(&scene.name, &solved, &traj, sim::ENGINE, extra),
    )?;
    println!(
        "v0 = [{:.5}, {:.5}, {:.5}] m/s, omega0 = [{:.4}, {:.4}, {:.4}] rad/s; final distance {:.5} m; wrote {}",
        s0.v.x,
        s0.v.y,
        s0.v.z,
        s0.omega.x,
        s0.omega.y,
        s0.omega.z,
        stage.distance(),
        a.out.display()
    );
    Ok(())
}
