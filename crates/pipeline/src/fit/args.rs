//! `fit`'s settings as a front end gives them (the command's flags, a binding's keywords), turned into a
//! [`FitRun`]: the same fit whichever front end asks for it.

use super::{FitInputs, FitOutcome, FitRun, Stage};
use crate::{Observer, Result, Resume};
use recon::VideoFitConfig;
use std::path::PathBuf;

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus fit data/slide --scene runs/background --object toy=merged --init init.json --out fits/slide
  pganeus fit data/slide --scene runs/background --object toy=merged --init init.json --no-pa --out fits/slide_no_pa")
)]
pub struct FitArgs {
    /// The video: a capture in the NeuS layout from one fixed camera, with `mask/` (one body) or
    /// `mask_<NAME>/`, and `capture.json` giving the fps.
    pub video: PathBuf,
    /// The scene's run folder (its field renders the background).
    #[cfg_attr(feature = "clap", arg(long))]
    pub scene: PathBuf,
    /// The scene's baked grid for contacts (`bake` output); default: baked from the scene run into the
    /// output folder.
    #[cfg_attr(feature = "clap", arg(long))]
    pub scene_grid: Option<PathBuf>,
    /// The body: NAME=DIR, DIR a `merge` output (or a single run folder).
    #[cfg_attr(feature = "clap", arg(long))]
    pub object: Vec<String>,
    /// The first-pose guess (init.json, docs/formats.md), or `auto`: candidates from the first frame's mask and
    /// the body's resting sides, the best refined by the image terms (the pose found is written to
    /// `init_auto.json` in the fit folder, in the same format).
    #[cfg_attr(feature = "clap", arg(long))]
    pub init: PathBuf,
    /// The output folder.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// Stages to run (the earlier ones' results must be in the output folder); the fit stops after the last
    /// one named.
    #[cfg_attr(feature = "clap", arg(long, value_delimiter = ','))]
    pub stages: Option<Vec<Stage>>,
    /// Ablation: no PA; GA tracks frame by frame from the previous frame, then PGA.
    #[cfg_attr(feature = "clap", arg(long, conflicts_with = "no_ga"))]
    pub no_pa: bool,
    /// Ablation: PA alone (no GA, no PGA).
    #[cfg_attr(feature = "clap", arg(long))]
    pub no_ga: bool,
    /// Settings of every stage (TOML; the sections and defaults are those of `config.toml` in a fit folder).
    #[cfg_attr(feature = "clap", arg(long))]
    pub config: Option<PathBuf>,
    /// Use the first N frames of the video.
    #[cfg_attr(feature = "clap", arg(long))]
    pub frames: Option<usize>,
    /// Frames per second (default: the video's `capture.json`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub fps: Option<f64>,
    /// Seconds the shutter was open in each frame (default: the video's `capture.json`, else an instant): a
    /// body moving more than a pixel in that time is drawn over it. 0: every frame an instant.
    #[cfg_attr(feature = "clap", arg(long))]
    pub shutter: Option<f64>,
    /// Density of the body, kg/m³ (the motion against a static scene does not depend on it).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 1000.0))]
    pub density: f64,
    /// Start over even if the output folder holds a fit with other settings.
    #[cfg_attr(feature = "clap", arg(long))]
    pub force: bool,
}

impl FitArgs {
    /// The fit of the bodies `objects` (`NAME=DIR`) in `video` over the scene run `scene` into `out`, with
    /// the command's defaults: the first pose searched (`init = auto`), every frame and stage, the video's
    /// fps and shutter, density 1000.
    pub fn new(
        video: impl Into<PathBuf>,
        scene: impl Into<PathBuf>,
        objects: &[&str],
        out: impl Into<PathBuf>,
    ) -> FitArgs {
        FitArgs {
            video: video.into(),
            scene: scene.into(),
            scene_grid: None,
            object: objects.iter().map(|s| s.to_string()).collect(),
            init: PathBuf::from("auto"),
            out: out.into(),
            stages: None,
            no_pa: false,
            no_ga: false,
            config: None,
            frames: None,
            fps: None,
            shutter: None,
            density: 1000.0,
            force: false,
        }
    }

    /// What the fit reads.
    pub fn inputs(&self) -> Result<FitInputs> {
        Ok(FitInputs {
            video: self.video.clone(),
            scene: self.scene.clone(),
            scene_grid: self.scene_grid.clone(),
            objects: crate::parse_objects(&self.object)?,
            init: self.init.clone(),
            frames: self.frames,
            fps: self.fps,
            shutter: self.shutter,
            density: self.density,
            no_pa: self.no_pa,
            no_ga: self.no_ga,
        })
    }

    /// The settings: the defaults, and over them, key by key, the `config` file's (`[ga.pose] iterations =
    /// 60` keeps fit's other GA settings).
    pub fn config(&self) -> Result<VideoFitConfig> {
        match &self.config {
            Some(p) => crate::run_folder::config_over(&VideoFitConfig::default(), p),
            None => Ok(VideoFitConfig::default()),
        }
    }
}

/// Runs the fit `a` asks for: its stages (all when none are named) into its output folder, going on with the
/// run there unless `force` starts it over.
pub fn run(a: &FitArgs, observer: &dyn Observer) -> Result<FitOutcome> {
    let resume = if a.force { Resume::StartOver } else { Resume::Continue };
    let stages: Vec<Stage> = a.stages.clone().unwrap_or_else(|| Stage::ALL.to_vec());
    FitRun::open(a.inputs()?, a.config()?, &a.out, resume)?.run(&stages, observer)
}
