use anyhow::Result;
use clap::Args;
use scene_file::SceneFile;
use std::path::PathBuf;

#[derive(Args)]
#[command(after_help = "Examples:
  pganeus simulate --scene scenes/two_body.toml --out out/two_body.json --frames 120")]
pub struct SimulateArgs {
    /// Scene file (TOML, or JSON by extension).
    #[arg(long)]
    pub scene: PathBuf,
    /// Where to write trajectory.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Override the scene's frame count.
    #[arg(long)]
    pub frames: Option<usize>,
}

pub fn run(a: SimulateArgs) -> Result<()> {
    let mut scene = SceneFile::load(&a.scene)?;
    if let Some(f) = a.frames {
        scene.world.config.frames = f;
        scene.world.validate().map_err(|e| anyhow::anyhow!("--frames: {e}"))?;
    }
    let w = &scene.world;
    tracing::info!(
        "{}: {} bodies, {} frames at {} fps, {} substeps",
        scene.name,
        w.bodies.len(),
        w.config.frames,
        w.config.fps,
        w.config.substeps
    );
    let pb = super::progress(w.config.frames as u64, "simulate");
    let t0 = std::time::Instant::now();
    let traj = w.simulate_with_progress(&w.params(), &mut |k| pb.set_position(k as u64 + 1));
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let out = scene_file::trajectory_file(&scene.name, w, &traj, sim::ENGINE, Default::default());
    pganeus_io::write_trajectory(&a.out, &out)?;
    for (b, body) in w.bodies.iter().enumerate() {
        let last = traj.frames.last().expect("frame 0 exists")[b];
        let hits = traj.contacts.iter().filter(|c| c.scene[b]).count();
        println!(
            "{}: final t = [{:.4}, {:.4}, {:.4}] m, |v| = {:.4} m/s, scene contact in {hits} frames",
            body.name,
            last.pose.t.x,
            last.pose.t.y,
            last.pose.t.z,
            last.v.norm()
        );
    }
    println!(
        "simulated {} frames in {:.3} s; wrote {}",
        w.config.frames,
        secs,
        a.out.display()
    );
    Ok(())
}
