//! Training settings: one struct, saved in every checkpoint.

use crate::background_field::BackgroundConfig;
use crate::neus_field::{FieldConfig, FieldInit};
use crate::stereo::StereoConfig;
use field::ConfigError;
pub use pganeus_io::CaptureSubject;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Object or scene. Default object.
    pub kind: CaptureSubject,
    /// Optimiser steps. Default 3000 (objects); half the object preset's for scenes: 1500 with `fast` (about
    /// 5 minutes at 320×240 on two cores), 10000 with `quality`.
    pub iterations: usize,
    /// Rays per step. Default 2048.
    pub batch_rays: usize,
    /// Peak learning rate (after warm-up). Default 0.01.
    pub lr: f32,
    /// Linear warm-up steps. Default 100.
    pub warmup: usize,
    /// The learning rate decays exponentially to `lr · lr_final_ratio` at the end. Default 0.1.
    pub lr_final_ratio: f32,
    /// Marching steps across the unit sphere's diameter. Default 512.
    pub steps_per_ray: usize,
    /// At most this many samples per ray (the occupied part is subsampled). Default 48.
    pub max_samples_per_ray: usize,
    /// Occupancy grid resolution (cells per axis over [-1, 1]). Default 64 for objects, 128 for scenes.
    pub occupancy_res: usize,
    /// Refresh the occupancy grid every this many steps. Default 16.
    pub occupancy_every: usize,
    /// Sample everywhere in the sphere for this many steps first. Default 200.
    pub occupancy_warmup: usize,
    /// Once the occupancy grid is in use, a training step keeps only the samples whose SDF, interpolated
    /// from the grid's refresh at the cells' centres, lies within the density's reach (4/s) plus this many
    /// cells of zero (`neus::surface_band`), and every fourth sample it drops is kept for the eikonal and
    /// no-overhang terms alone (`neus::regulariser_points`); 0 keeps every sample in an occupied cell.
    /// Default 0 for objects (measured: the profile notebook), 0.5 for scenes. Checkpoints written before the setting existed trained with 0, and load so.
    #[serde(default)]
    pub sample_band: f32,
    /// Steps over which NeuS's cosine annealing goes from 0 to 1. Default 500.
    pub anneal_end: usize,
    /// Colour ignores the view direction (only the constant spherical harmonic) for this many steps: the
    /// geometry forms first. Default 0 (objects); 1000 for scenes.
    pub view_independent_steps: usize,
    /// Weight of the eikonal term. Default 0.1.
    pub eikonal_weight: f32,
    /// Weight of the no-overhang term: the mean over the samples of max(0, −∂s/∂z), the SDF falling as it
    /// goes up. A tabletop scene seen from above is a height field over the board (boxes, ramps, the board
    /// itself), where ∂s/∂z ≥ 0 everywhere. What no camera sees well, such as a shadowed slot under the foot
    /// of a wall, otherwise stays as the flat start left it: hollow, and a body simulated against it slides
    /// in. Default 0 (objects; scenes with real overhangs); 0.1 for scenes.
    #[serde(default)]
    pub overhang_weight: f32,
    /// Weight of the stereo-point term (mean |SDF| at multi-view stereo points, `neus::stereo`) at the start;
    /// it falls linearly to 0 at `stereo_steps`. Default 0 (objects); 0.5 for scenes.
    pub stereo_weight: f32,
    /// The step where the stereo-point term ends (at the latest half-way through the run, so step 750 of a
    /// default 1500-step scene run). Default 0; 1000 for scenes.
    pub stereo_steps: usize,
    /// How the stereo points are found.
    pub stereo: StereoConfig,
    /// Weight of the mask BCE term (when the capture has masks). Default 0.1.
    pub mask_weight: f32,
    /// Rays pass through a random point of their pixel (true) or through its centre (false). Default false
    /// for objects: a mask labels a whole pixel by what its centre sees, so a ray through the edge of a
    /// pixel marked "object" that misses the object is taught to be opaque, and the rendered silhouette
    /// grows; true for scenes, whose pixels' colours are averages over the pixel. Checkpoints written
    /// before this setting existed trained with jitter, and load with it.
    #[serde(default = "jitter_before_the_setting")]
    pub pixel_jitter: bool,
    /// The trained field is the mean of the parameters over this last fraction of the steps (Polyak
    /// averaging, `neus::param_average`); 0 keeps the last step's. Default 0.2.
    /// Checkpoints written before the setting existed load with 0, as they trained.
    #[serde(default)]
    pub average_last: f32,
    /// Learn a colour map (a gain per channel) for each training view (`neus::appearance`), their mean held
    /// at one: a camera's exposure and white balance, which change from photo to photo, stay out of the
    /// field; held-out views are then scored with a map fitted on their left half.
    /// Default true. Checkpoints written before the setting existed trained without, and load so.
    #[serde(default)]
    pub per_view_appearance: bool,
    /// Weight of the pull of the views' mean gain toward one (squared distance, summed over channels).
    /// Default 1.
    #[serde(default = "default_appearance_weight")]
    pub appearance_weight: f32,
    /// Hash levels active at the start (progressive activation). Default 4.
    pub level_start: usize,
    /// One more level every this many steps (0 = all levels from the start). Default 100.
    pub level_every: usize,
    /// Hold out every k-th view for evaluation (0 = none). Default 8.
    pub holdout_every: usize,
    /// Write a checkpoint every this many steps. Default 500.
    pub checkpoint_every: usize,
    pub seed: u64,
    pub field: FieldConfig,
}

fn jitter_before_the_setting() -> bool {
    true
}

fn default_appearance_weight() -> f32 {
    1.0
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            kind: CaptureSubject::Object,
            iterations: 3000,
            batch_rays: 2048,
            lr: 0.01,
            warmup: 100,
            lr_final_ratio: 0.1,
            steps_per_ray: 512,
            max_samples_per_ray: 48,
            occupancy_res: 64,
            occupancy_every: 16,
            occupancy_warmup: 200,
            sample_band: 0.0,
            anneal_end: 500,
            view_independent_steps: 0,
            eikonal_weight: 0.1,
            overhang_weight: 0.0,
            stereo_weight: 0.0,
            stereo_steps: 0,
            stereo: StereoConfig::default(),
            mask_weight: 0.1,
            pixel_jitter: false,
            average_last: 0.2,
            per_view_appearance: true,
            appearance_weight: default_appearance_weight(),
            level_start: 4,
            level_every: 100,
            holdout_every: 8,
            checkpoint_every: 500,
            seed: 0,
            field: FieldConfig::default(),
        }
    }
}

impl TrainConfig {
    /// `fast` (the default) or `quality` (longer, bigger batches, more samples), for an object or a scene.
    pub fn preset(name: &str, kind: CaptureSubject) -> Option<Self> {
        let base = Self::preset_object(name)?;
        Some(match kind {
            CaptureSubject::Object => base,
            CaptureSubject::Scene => Self {
                kind,
                // A scene step costs 3–4 object steps (every ray meets the board): half the steps. With `fast`,
                // 1500 steps take about 5 minutes on two cores for the synth tabletop at 320×240 (held out
                // 28.60, 28.69 and 28.60 dB over three seeds, Chamfer 0.75–0.90 mm).
                iterations: base.iterations / 2,
                // A scene's rays cross the board at a slant: its samples lie in the occupied band around the
                // surface, over a cell and a half either side. Cells half as wide (128³) halve that band: on the
                // demo's tabletop 1500 steps took 312 s against 400 at 64³ for the same held-out PSNR and
                // Chamfer (28.15 against 28.13 dB, 1.09 against 1.07 mm), and the refresh's SDF evaluations
                // (a quarter of 2.1 M cells every 16 steps) cost a few per cent (profile notebook).
                occupancy_res: base.occupancy_res.max(128),
                // A step keeps the samples within half a cell of the density's reach of the surface (a ray's
                // 15 samples become 8) and sets every fourth dropped one aside for the eikonal and no-overhang
                // terms alone (`neus::regulariser_points`): without them the field a centimetre or two off the
                // surface, which the simulator reads, was no longer held to a distance (the gradient's length
                // 0.93 at 20 mm over the demo's board against 1.00; a backdrop slide fitted on such a scene
                // started 5.3 mm off). With them the demo's scene trains in 194–217 s against the build
                // before's 244 (4–14 % less than every sample on this build; 28.05–28.16
                // against 28.13 dB, Chamfer 1.09–1.13 against 1.07 mm; seed 1: 27.86 against 27.83 dB, 1.14
                // against 1.16 mm), the gradient 1.00 at 5–20 mm, and the backdrop's slide within 0.89 mm
                // (profile notebook).
                sample_band: 0.5,
                view_independent_steps: 1000,
                stereo_weight: 0.5,
                stereo_steps: 1000,
                overhang_weight: 0.1,
                pixel_jitter: true,
                field: FieldConfig {
                    init: FieldInit::Board,
                    background: Some(BackgroundConfig::default()),
                    ..base.field
                },
                ..base
            },
        })
    }

    fn preset_object(name: &str) -> Option<Self> {
        match name {
            "fast" => Some(Self::default()),
            "quality" => Some(Self {
                iterations: 20000,
                batch_rays: 4096,
                max_samples_per_ray: 64,
                steps_per_ray: 1024,
                occupancy_res: 128,
                anneal_end: 2000,
                level_every: 500,
                checkpoint_every: 1000,
                ..Self::default()
            }),
            _ => None,
        }
    }

    /// Check ranges; keys are named as in the config file (`field.grid.levels`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let positive = [
            ("iterations", self.iterations),
            ("batch_rays", self.batch_rays),
            ("steps_per_ray", self.steps_per_ray),
            ("max_samples_per_ray", self.max_samples_per_ray),
            ("occupancy_res", self.occupancy_res),
            ("occupancy_every", self.occupancy_every),
            ("level_start", self.level_start),
            ("checkpoint_every", self.checkpoint_every),
        ];
        for (name, v) in positive {
            if v == 0 {
                return Err(ConfigError::new(name, "must be at least 1"));
            }
        }
        for (name, v) in [("lr", self.lr), ("lr_final_ratio", self.lr_final_ratio)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(ConfigError::new(name, format!("must be positive, got {v}")));
            }
        }
        if !(self.average_last.is_finite() && (0.0..=1.0).contains(&self.average_last)) {
            return Err(ConfigError::new(
                "average_last",
                format!("must be 0 to 1, got {}", self.average_last),
            ));
        }
        for (name, v) in [
            ("sample_band", self.sample_band),
            ("eikonal_weight", self.eikonal_weight),
            ("overhang_weight", self.overhang_weight),
            ("stereo_weight", self.stereo_weight),
            ("mask_weight", self.mask_weight),
            ("appearance_weight", self.appearance_weight),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ConfigError::new(name, format!("must be ≥ 0, got {v}")));
            }
        }
        self.field.grid.validate().map_err(|e| e.within("field.grid"))?;
        if self.field.feature_dim == 0 {
            return Err(ConfigError::new("field.feature_dim", "must be at least 1"));
        }
        if self.field.init == FieldInit::Board && self.field.sdf_hidden.len() != 1 {
            return Err(ConfigError::new(
                "field.sdf_hidden",
                format!(
                    "field.init = \"board\" needs exactly one hidden layer, got {:?}",
                    self.field.sdf_hidden
                ),
            ));
        }
        if let Some(b) = &self.field.background {
            b.validate().map_err(|e| e.within("field.background"))?;
        }
        self.stereo.validate().map_err(|e| e.within("stereo"))
    }

    /// Weight of the stereo-point term at `step`: it ends at `stereo_steps` or half-way through the run,
    /// whichever comes first (the points are coarser than what the images resolve by then).
    pub fn stereo_weight_at(&self, step: usize) -> f32 {
        let end = self.stereo_steps.min(self.iterations / 2);
        if step >= end {
            return 0.0;
        }
        self.stereo_weight * (1.0 - step as f32 / end as f32)
    }

    /// Learning rate at `step`: linear warm-up, then exponential decay.
    pub fn lr_at(&self, step: usize) -> f32 {
        if step < self.warmup {
            return self.lr * (step + 1) as f32 / self.warmup as f32;
        }
        let p = (step - self.warmup) as f32 / (self.iterations.saturating_sub(self.warmup)).max(1) as f32;
        self.lr * self.lr_final_ratio.powf(p.min(1.0))
    }

    /// The first step whose result enters the parameter average: the mean is over the results of steps
    /// `average_start() + 1 ..= iterations` (none when `average_last` is 0).
    pub fn average_start(&self) -> usize {
        let n = (self.average_last as f64 * self.iterations as f64).round() as usize;
        self.iterations - n.min(self.iterations)
    }

    /// Hash levels active at `step`.
    pub fn active_levels(&self, step: usize) -> usize {
        let all = self.field.grid.levels;
        if self.level_every == 0 {
            return all;
        }
        (self.level_start + step / self.level_every).min(all)
    }
}
