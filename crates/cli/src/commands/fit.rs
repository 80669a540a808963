//! `pganeus fit`: the arguments of a fit, handed to [`pipeline::fit`].

use anyhow::Result;
use clap::{Args, ValueEnum};
use pipeline::fit::{FitInputs, FitRun, Stage};
use pipeline::{Observer, Resume};
use recon::VideoFitConfig;
use std::path::PathBuf;

#[derive(Args)]
#[command(after_help = "Examples:
  pganeus fit data/slide --scene runs/background --object toy=merged --init init.json --out fits/slide
  pganeus fit data/slide --scene runs/background --object toy=merged --init init.json --no-pa --out fits/slide_no_pa")]
pub struct FitArgs {
    /// The video: a capture in the NeuS layout from one fixed camera, with `mask/` (one body) or
    /// `mask_<NAME>/`, and `capture.json` giving the fps.
    pub video: PathBuf,
    /// The scene's run folder (its field renders the background).
    #[arg(long)]
    pub scene: PathBuf,
    /// The scene's baked grid for contacts (`bake` output); default: baked from the scene run into the
    /// output folder.
    #[arg(long)]
    pub scene_grid: Option<PathBuf>,
    /// The body: NAME=DIR, DIR a `merge` output (or a single run folder).
    #[arg(long)]
    pub object: Vec<String>,
    /// The first-pose guess (init.json, docs/formats.md), or `auto`: candidates from the first frame's mask and
    /// the body's resting sides, the best refined by the image terms (the pose found is written to
    /// `init_auto.json` in the fit folder, in the same format).
    #[arg(long)]
    pub init: PathBuf,
    /// The output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Stages to run (the earlier ones' results must be in the output folder); the fit stops after the last
    /// one named.
    #[arg(long, value_delimiter = ',')]
    pub stages: Option<Vec<StageArg>>,
    /// Ablation: no PA; GA tracks frame by frame from the previous frame, then PGA.
    #[arg(long, conflicts_with = "no_ga")]
    pub no_pa: bool,
    /// Ablation: PA alone (no GA, no PGA).
    #[arg(long)]
    pub no_ga: bool,
    /// Settings of every stage (TOML; the sections and defaults are those of `config.toml` in a fit folder).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Use the first N frames of the video.
    #[arg(long)]
    pub frames: Option<usize>,
    /// Frames per second (default: the video's `capture.json`).
    #[arg(long)]
    pub fps: Option<f64>,
    /// Seconds the shutter was open in each frame (default: the video's `capture.json`, else an instant): a
    /// body moving more than a pixel in that time is drawn over it. 0: every frame an instant.
    #[arg(long)]
    pub shutter: Option<f64>,
    /// Density of the body, kg/m³ (the motion against a static scene does not depend on it).
    #[arg(long, default_value_t = 1000.0)]
    pub density: f64,
    /// Start over even if the output folder holds a fit with other settings.
    #[arg(long)]
    pub force: bool,
}

/// A stage on the command line.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum StageArg {
    /// The first pose from the guess, and the launch guess from the next frames.
    First,
    /// PA: physics from the rendered frames.
    Pa,
    /// GA: every frame's pose, with the contact penalty.
    Ga,
    /// PGA: physics from GA's poses (GA ↔ PGA while it helps), renders and the final trajectory.
    Pga,
}

impl From<StageArg> for Stage {
    fn from(s: StageArg) -> Stage {
        match s {
            StageArg::First => Stage::First,
            StageArg::Pa => Stage::Pa,
            StageArg::Ga => Stage::Ga,
            StageArg::Pga => Stage::Pga,
        }
    }
}

impl FitArgs {
    /// What the fit reads.
    pub fn inputs(&self) -> Result<FitInputs> {
        Ok(FitInputs {
            video: self.video.clone(),
            scene: self.scene.clone(),
            scene_grid: self.scene_grid.clone(),
            objects: pipeline::parse_objects(&self.object)?,
            init: self.init.clone(),
            frames: self.frames,
            fps: self.fps,
            shutter: self.shutter,
            density: self.density,
            no_pa: self.no_pa,
            no_ga: self.no_ga,
        })
    }
}

pub fn run(a: FitArgs, observer: &dyn Observer) -> Result<()> {
    let config = match &a.config {
        // Key by key over the defaults: `[ga.pose] iterations = 60` keeps fit's other GA settings.
        Some(p) => pipeline::run_folder::config_over(&VideoFitConfig::default(), p)?,
        None => VideoFitConfig::default(),
    };
    let resume = if a.force { Resume::StartOver } else { Resume::Continue };
    let stages: Vec<Stage> = match &a.stages {
        Some(s) => s.iter().map(|&s| s.into()).collect(),
        None => Stage::ALL.to_vec(),
    };
    let outcome = FitRun::open(a.inputs()?, config, &a.out, resume)?.run(&stages, observer)?;
    if !outcome.summary.is_empty() {
        println!("{}", outcome.summary);
    }
    Ok(())
}
