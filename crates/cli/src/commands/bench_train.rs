//! Training benchmark on a synthetic object or scene capture: every N steps a JSON line
//! with wall time, rays/s, samples/s, held-out PSNR and the Chamfer distance
//! of the zero level to the true mesh (for a scene also its SDF over the free board, `off_surface`); peak memory
//! at the end.

use anyhow::{Context, Result};
use clap::Args;
use geom::TriMesh;
use neus::holdout::holdout;
use neus::{Dataset, NeusTrainer};
use pipeline::surfaces::{capture_truth, zero_level_mesh};
use pipeline::train::{capture_kind, load_config};
use std::path::PathBuf;

#[derive(Args)]
#[command(after_help = "Examples:
  pganeus bench-train --dataset data/tabletop_large --capture toy_a --iterations 3000 --every 500")]
pub struct BenchTrainArgs {
    /// A dataset from `pganeus synth` (e.g. --preset tabletop --scale large).
    #[arg(long)]
    pub dataset: PathBuf,
    /// The capture in it (an object's, or the scene's: `background`).
    #[arg(long, default_value = "toy_a")]
    pub capture: String,
    #[arg(long, default_value = "fast")]
    pub preset: String,
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Training steps (default: the preset's for the capture's kind: 3000 for an object, 1500 for a scene).
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Report every this many steps.
    #[arg(long, default_value_t = 250)]
    pub every: usize,
    /// Stop after this many seconds of training.
    #[arg(long)]
    pub max_seconds: Option<f64>,
    /// Grid resolution of the zero level for the Chamfer distance.
    #[arg(long, default_value_t = 192)]
    pub mesh_res: usize,
    /// Start from this run's checkpoint (a run `--out` or `train` wrote) instead of from nothing: with
    /// `--iterations` at its step, only the figures of the run as it is.
    #[arg(long)]
    pub from: Option<PathBuf>,
    /// Also keep the trained run here (checkpoint.safetensors and config.toml,
    /// as `train` writes them), for `bake`, `mesh` or `render`.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// The faces whose vertices are all at least `z` above the board.
fn above(m: &TriMesh, z: f64) -> TriMesh {
    mesh::faces_where(m, |corners| corners.iter().all(|v| v[2] >= z))
}

fn peak_memory_mib() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

pub fn run(a: BenchTrainArgs) -> Result<()> {
    // A scene is compared over its footprint (its truth is already the visible part); an object whole and
    // above the board, which is what the cameras saw.
    let (truth_mesh, _, region) = capture_truth(&a.dataset.join("truth.json"), &a.capture)?;
    let truth_visible = match region {
        Some(_) => truth_mesh.clone(),
        None => above(&truth_mesh, 0.003),
    };
    let diameter = {
        let (lo, hi) = truth_mesh.bounds();
        (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt()
    };
    let capture = a.dataset.join(&a.capture);
    let data = Dataset::load(&capture).with_context(|| format!("loading {}", capture.display()))?;
    let kind = capture_kind(None, &data);
    let mut cfg = load_config(&a.preset, kind, a.config.as_deref())?;
    if let Some(n) = a.iterations {
        cfg.iterations = n;
    }
    let iterations = cfg.iterations;
    let mut t = match &a.from {
        Some(run) => {
            let mut t = neus::checkpoint::resume(&run.join("checkpoint.safetensors"), data)?;
            t.config.iterations = iterations;
            t
        }
        None => NeusTrainer::new(cfg, data)?,
    };
    let start = t.step;
    let (mut total_secs, mut window_secs, mut rays, mut samples) = (0.0f64, 0.0f64, 0usize, 0usize);
    let wall = std::time::Instant::now();
    loop {
        let s = if t.step < iterations {
            t.step()
        } else if t.step == start {
            // Nothing to train: the figures of the run as it is.
            neus::StepStats {
                step: t.step,
                ..Default::default()
            }
        } else {
            break;
        };
        total_secs += s.seconds;
        window_secs += s.seconds;
        rays += s.rays;
        samples += s.samples;
        let done = t.step >= iterations || a.max_seconds.is_some_and(|m| total_secs >= m);
        if t.step % a.every == 0 || done {
            let held_out = holdout(&t);
            let psnr = held_out.psnr;
            let levels = t.config.active_levels(t.step);
            let m = zero_level_mesh(
                &t.field,
                levels,
                t.data.centre,
                t.data.radius,
                a.mesh_res,
                &super::Bars::default(),
            );
            let (full, visible) = match region {
                _ if m.faces.is_empty() => (f64::INFINITY, f64::INFINITY),
                Some(r) => {
                    let c = mesh::chamfer(&r.crop(&m), &truth_visible, 20000, 1).mean;
                    (c, c)
                }
                None => (
                    mesh::chamfer(&m, &truth_mesh, 20000, 1).mean,
                    mesh::chamfer(&above(&m, 0.003), &truth_visible, 20000, 1).mean,
                ),
            };
            // Where the simulator reads a scene: its SDF 5, 10 and 20 mm over the free board.
            let off_surface = region.map(|r| {
                pipeline::off_surface::off_surface(
                    &t.field,
                    levels,
                    t.data.centre,
                    t.data.radius,
                    &truth_mesh,
                    &r,
                    &[0.005, 0.01, 0.02],
                )
            });
            let round = |v: f64, k: f64| (v * k).round() / k;
            println!(
                "{}",
                serde_json::json!({
                    "bench": "train", "step": t.step, "train_seconds": round(total_secs, 10.0),
                    "wall_seconds": round(wall.elapsed().as_secs_f64(), 10.0),
                    "rays_per_s": (rays as f64 / window_secs).round(),
                    "samples_per_s": (samples as f64 / window_secs).round(),
                    "heldout_psnr": round(psnr as f64, 100.0),
                    "heldout_psnr_fitted": round(held_out.psnr_fitted as f64, 100.0),
                    "heldout_silhouette_area_percent": held_out.silhouette.area_excess_percent().map(|v| round(v, 100.0)),
                    "chamfer_mm": round(full * 1e3, 100.0), "chamfer_visible_mm": round(visible * 1e3, 100.0),
                    "chamfer_pct_diameter": round(full / diameter * 100.0, 100.0),
                    "chamfer_visible_pct_diameter": round(visible / diameter * 100.0, 100.0),
                    "loss": s.loss, "inv_s": s.inv_s, "occupied": s.occupied, "off_surface": off_surface,
                })
            );
            (window_secs, rays, samples) = (0.0, 0, 0);
        }
        if done {
            break;
        }
    }
    if let Some(out) = &a.out {
        std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
        pganeus_io::write_atomic(&out.join("config.toml"), toml::to_string(&t.config)?.as_bytes())?;
        neus::checkpoint::save(&t, &out.join("checkpoint.safetensors"))?;
    }
    // Where the steps' time went, phase by phase (seconds over the whole run).
    println!(
        "{}",
        serde_json::json!({"bench": "train", "phases_s": t.phases, "phases_total_s": t.phases.total()})
    );
    println!(
        "{}",
        serde_json::json!({"bench": "train", "peak_memory_mib": peak_memory_mib()})
    );
    Ok(())
}
