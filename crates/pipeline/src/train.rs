//! `train`: a NeuS field (SDF + colour) from a capture (Sec. 3.2, Eq. 1–2): an object (masked, a sphere
//! start) or a scene (a board-plane start, a background field beyond the unit sphere), with checkpoints it
//! resumes from, a log and a preview mesh.

use crate::error::{err, fail};
use crate::Result;
use crate::{note, Observer, Task};
use neus::{checkpoint, CaptureSubject, Dataset, NeusTrainer, TrainConfig};
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus train data/tabletop/toy_a --out runs/toy_a
  pganeus train data/tabletop/background --out runs/scene --kind scene --iterations 1500")
)]
pub struct TrainArgs {
    /// The capture (NeuS layout: image/, mask/, cameras_sphere.npz).
    pub capture: PathBuf,
    /// The run folder: checkpoint.safetensors, config.toml, log.jsonl, preview.ply.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// fast (default) or quality.
    #[cfg_attr(feature = "clap", arg(long, default_value = "fast"))]
    pub preset: String,
    /// What the capture shows: `object` (sphere start; masks mark the object) or `scene` (board-plane
    /// start, a background field beyond the unit sphere; masks mark what is not scene). Default: capture.json's
    /// "subject", else object when the capture has masks and scene when it has none.
    #[cfg_attr(feature = "clap", arg(long, value_parser = parse_kind))]
    pub kind: Option<CaptureSubject>,
    /// A TOML file with TrainConfig fields, over the preset.
    #[cfg_attr(feature = "clap", arg(long))]
    pub config: Option<PathBuf>,
    /// Override the number of steps.
    #[cfg_attr(feature = "clap", arg(long))]
    pub iterations: Option<usize>,
    /// Continue from the run's checkpoint.
    #[cfg_attr(feature = "clap", arg(long, conflicts_with = "force"))]
    pub resume: bool,
    /// Start over even if the run folder has a checkpoint (its checkpoint and log are replaced).
    #[cfg_attr(feature = "clap", arg(long))]
    pub force: bool,
    /// Skip the marching-tetrahedra preview of the zero level.
    #[cfg_attr(feature = "clap", arg(long))]
    pub no_preview: bool,
    /// Grid resolution of the preview mesh.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 128))]
    pub preview_res: usize,
}

impl TrainArgs {
    /// Training of `capture` into the run folder `out` with the command's defaults (the `fast` preset, the
    /// kind from the capture, a preview mesh at 128³).
    pub fn new(capture: PathBuf, out: PathBuf) -> TrainArgs {
        TrainArgs {
            capture,
            out,
            preset: "fast".into(),
            kind: None,
            config: None,
            iterations: None,
            resume: false,
            force: false,
            no_preview: false,
            preview_res: 128,
        }
    }
}

/// `--kind`'s parser (the flag exists with the clap feature only).
#[cfg(feature = "clap")]
fn parse_kind(s: &str) -> Result<CaptureSubject, String> {
    match s {
        "object" => Ok(CaptureSubject::Object),
        "scene" => Ok(CaptureSubject::Scene),
        _ => Err(format!("\"{s}\" is not object or scene")),
    }
}

/// The subject of a capture: the user's choice, else capture.json's, else object with masks, scene without.
/// Says which and why in the log.
pub fn capture_kind(given: Option<CaptureSubject>, data: &Dataset) -> CaptureSubject {
    let (kind, why) = match (given, data.subject) {
        (Some(k), _) => (k, "--kind"),
        (None, Some(k)) => (k, "capture.json"),
        (None, None) if data.has_masks() => (CaptureSubject::Object, "the capture has masks"),
        (None, None) => (CaptureSubject::Scene, "the capture has no masks"),
    };
    tracing::info!("training the {} field ({why})", kind.name());
    kind
}

/// A preset for a kind of capture with a config file's fields laid over it.
pub fn load_config(preset: &str, kind: CaptureSubject, file: Option<&Path>) -> Result<TrainConfig> {
    let base = TrainConfig::preset(preset, kind)
        .ok_or_else(|| err!(Settings, "--preset: unknown preset \"{preset}\" (fast, quality)"))?;
    let Some(file) = file else { return Ok(base) };
    crate::run_folder::config_over(&base, file)
}

pub fn run(a: &TrainArgs, observer: &dyn Observer) -> Result<()> {
    let ckpt = a.out.join("checkpoint.safetensors");
    let mut data = Dataset::load(&a.capture)?;
    tracing::info!(
        "{}: {} views of {}×{}{}",
        a.capture.display(),
        data.views.len(),
        data.width,
        data.height,
        if data.has_masks() { " with masks" } else { "" }
    );
    // An object capture without masks: computed from its photos (the board they agree on, and the views
    // agreeing on what stands on it), written into the run for inspection.
    let kind = capture_kind(a.kind, &data);
    let computed_masks = if kind == CaptureSubject::Object && !data.has_masks() {
        let pb = Task::start(observer, "object masks", 1);
        let (masks, stats) = crate::object_masks::compute(&data)?;
        pb.finish();
        note(
            observer,
            format!(
                "{}: no mask/, the object's masks computed from the photos ({:.0} px a view on average)",
                a.capture.display(),
                stats.areas.iter().sum::<usize>() as f64 / stats.areas.len().max(1) as f64,
            ),
        );
        for (view, m) in data.views.iter_mut().zip(&masks) {
            view.mask = Some(m.iter().map(|&x| if x { 1.0 } else { 0.0 }).collect());
        }
        Some(masks)
    } else {
        None
    };
    let mut trainer = if a.resume {
        if !ckpt.exists() {
            fail!(Settings, "--resume: {} does not exist", ckpt.display());
        }
        let mut t = checkpoint::resume(&ckpt, data)?;
        if let Some(n) = a.iterations {
            t.config.iterations = n;
        }
        tracing::info!("resuming {} at step {}", ckpt.display(), t.step);
        t
    } else {
        if ckpt.exists() && !a.force {
            fail!(
                OutputTaken,
                "{} exists: pass --resume to continue it, --force to start over, or choose another --out",
                ckpt.display()
            );
        }
        let mut cfg = load_config(&a.preset, kind, a.config.as_deref())?;
        if let Some(n) = a.iterations {
            cfg.iterations = n;
        }
        NeusTrainer::new(cfg, data)?
    };
    std::fs::create_dir_all(&a.out)?;
    pganeus_io::write_atomic(&a.out.join("config.toml"), toml::to_string(&trainer.config)?.as_bytes())?;
    if let Some(masks) = &computed_masks {
        let dir = a.out.join("mask");
        crate::video_masks::write_masks(&dir, masks, trainer.data.width as usize)?;
        tracing::info!("the computed masks are in {}", dir.display());
    }
    // A run started over (--force) replaces its log; a resumed one adds to it.
    let mut log = std::fs::OpenOptions::new()
        .create(true)
        .write(true)
        .append(a.resume)
        .truncate(!a.resume)
        .open(a.out.join("log.jsonl"))?;
    let total = trainer.config.iterations;
    if trainer.config.stereo_weight_at(trainer.step) > 0.0 {
        let t0 = std::time::Instant::now();
        let n = trainer.stereo_points().len();
        tracing::info!(
            "{n} multi-view stereo points in {:.1} s (pulled onto the zero level until step {})",
            t0.elapsed().as_secs_f64(),
            trainer.config.stereo_steps
        );
    }
    let pb = Task::start(observer, "train", total as u64);
    pb.set_position(trainer.step as u64);
    let (mut rays, mut secs) = (0usize, 0.0f64);
    while trainer.step < total {
        let s = trainer.step();
        rays += s.rays;
        secs += s.seconds;
        pb.set_position(s.step as u64);
        pb.set_status(&format!(
            "loss {:.4} psnr {:.1} {:.0} rays/s",
            s.loss.total(&trainer.config, s.step - 1),
            s.psnr,
            rays as f64 / secs
        ));
        if s.step % 50 == 0 || s.step == total {
            writeln!(log, "{}", serde_json::to_string(&s)?)?;
        }
        if s.step % trainer.config.checkpoint_every == 0 || s.step == total {
            checkpoint::save(&trainer, &ckpt)?;
        }
    }
    pb.finish();
    note(
        observer,
        format!(
            "trained {total} steps: {:.0} rays/s on average",
            rays as f64 / secs.max(1e-9)
        ),
    );
    if !trainer.holdout_views.is_empty() {
        let h = neus::holdout::holdout(&trainer);
        note(
            observer,
            format!(
                "held-out PSNR {:.2} dB over {} views",
                h.psnr,
                trainer.holdout_views.len()
            ),
        );
        if let Some(area) = h.silhouette.area_excess_percent() {
            note(
                observer,
                format!(
                    "held-out silhouette: area {area:+.2} % of the masks', IoU {:.4}",
                    h.silhouette.iou()
                ),
            );
        }
    }
    if !a.no_preview {
        let loaded = checkpoint::load_field(&ckpt)?;
        let levels = loaded.config.field.grid.levels;
        let mesh = crate::surfaces::zero_level_mesh(
            &loaded.field,
            levels,
            loaded.centre,
            loaded.radius,
            a.preview_res,
            observer,
        );
        if mesh.faces.is_empty() {
            tracing::warn!("the field has no zero level inside the unit sphere: no preview.ply");
        } else {
            let path = a.out.join("preview.ply");
            pganeus_io::write_ply(
                &path,
                &pganeus_io::PlyMesh::from_mesh(mesh),
                pganeus_io::PlyEncoding::BinaryLittleEndian,
            )?;
            note(observer, format!("wrote {}", path.display()));
        }
    }
    Ok(())
}
