//! Training a NeuS field on a capture: `NeusTrainer::new`, then `step()`.
//!
//! Per step: rays from random pixels of the training views; samples in the
//! occupied part of the unit sphere; the SDF at each sample and at three
//! points a small step away (finite-difference gradient, Neuralangelo-style:
//! normals and the eikonal term without second derivatives); colours; NeuS
//! rendering; losses (colour L1, eikonal, mask BCE); one backward pass
//! through rendering, the colour MLP, the SDF MLP and the hash grid; Adam
//! (sparse on the hash tables).

use crate::appearance::{recorded_l1, ViewAppearance};
use crate::background_field::{BackgroundField, BackgroundGrads, BackgroundScratch};
use crate::config::{CaptureSubject, TrainConfig};
use crate::dataset::Dataset;
use crate::field_pass::{FieldPass, ParamGrads, PassSettings, SampleGrads};
use crate::neus_field::{NeusField, SdfGrads, SdfPassScratch};
use crate::occupancy::{sample_ray, BatchMarch, Marching, OccupancyGrid};
use crate::param_average::ParamAverage;
use crate::regulariser_points::{RegulariserPoints, RegulariserWeights, REGULARISER_EVERY};
use crate::step_phases::{Lap, StepPhases};
use crate::stereo::stereo_points;
use crate::surface_band::CentreSdf;
use crate::volume::{render_ray, render_ray_backward, section_alpha, RayGrads, RayInputs, STOP_TRANSMITTANCE};
use field::ConfigError;
use field::{Adam, AdamConfig, GradMode, Touched};
use geom::SplitMix64;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The loss terms of a step (before weighting).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LossTerms {
    /// Mean absolute colour error (inside the mask when there are masks).
    pub rgb: f32,
    /// Mean (|∇s| − 1)² over the samples.
    pub eikonal: f32,
    /// Mean BCE between the rendered opacity and the mask (0 without masks).
    pub mask: f32,
    /// Mean |SDF| at a batch of stereo points (0 when the term is off).
    #[serde(default)]
    pub stereo: f32,
    /// Mean max(0, −∂s/∂z) over the samples.
    #[serde(default)]
    pub overhang: f32,
    /// Squared distance of the training views' mean gain from one, summed over channels (0 when the views'
    /// colour maps are not learned).
    #[serde(default)]
    pub appearance: f32,
}

impl LossTerms {
    /// The weighted sum at (0-based) `step`.
    pub fn total(&self, cfg: &TrainConfig, step: usize) -> f32 {
        self.rgb
            + cfg.eikonal_weight * self.eikonal
            + cfg.mask_weight * self.mask
            + cfg.stereo_weight_at(step) * self.stereo
            + cfg.overhang_weight * self.overhang
            + cfg.appearance_weight * self.appearance
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
pub struct StepStats {
    pub step: usize,
    pub loss: LossTerms,
    /// PSNR of the batch's rays (inside the mask when there are masks), dB.
    pub psnr: f32,
    pub rays: usize,
    pub samples: usize,
    /// Rays the background field was run for: those whose light gets through their samples (0 without a
    /// background field).
    pub background_rays: usize,
    pub seconds: f64,
    pub lr: f32,
    pub inv_s: f32,
    pub active_levels: usize,
    pub occupied: f32,
}

/// Buffers reused across steps.
#[derive(Default)]
struct Scratch {
    rays_o: Vec<[f32; 3]>,
    rays_d: Vec<[f32; 3]>,
    gt: Vec<[f32; 3]>,
    mask: Vec<f32>,
    /// The view each ray comes from.
    view: Vec<usize>,
    offsets: Vec<usize>,
    t: Vec<f32>,
    dt: Vec<f32>,
    d_sdf0: Vec<f32>,
    d_cos: Vec<f32>,
    d_rgb: Vec<[f32; 3]>,
    /// The gradient of the colour behind each ray (which `bg.out` holds).
    d_behind: Vec<[f32; 3]>,
    bg_jitter: Vec<f32>,
    bg: BackgroundScratch,
    /// Each ray's jitter along its march, drawn before the rays are marched in parallel.
    march_jitter: Vec<f32>,
    march: BatchMarch,
    /// Regulariser points set aside among the samples the band drops (unit coordinates), and their term.
    regulariser_points: Vec<[f32; 3]>,
    regulariser: RegulariserPoints,
    /// Kept to the band, the rays whose march ended inside the surface (as the refresh's SDF at the cells'
    /// centres places it): the samples deeper in the solid, dropped, would have absorbed what light is left.
    ended_inside: Vec<std::sync::atomic::AtomicBool>,
    /// The rays whose light gets through their samples to the background, and their origins and directions.
    seen_behind: Vec<usize>,
    behind_o: Vec<[f32; 3]>,
    behind_d: Vec<[f32; 3]>,
    /// The colour behind each ray of the batch.
    behind: Vec<[f32; 3]>,
}

/// A refresh reads the cells within this many cells of an occupied one; the others (empty space, where
/// nothing samples the field) only in every [`FAR_SWEEP_EVERY`]-th sweep over the grid: on a scene at 128³
/// about nine in ten cells.
const NEAR_CELLS: usize = 4;
const FAR_SWEEP_EVERY: usize = 4;

/// Adam state, gradients and touched hash entries of the background field.
pub(crate) struct BackgroundOptim {
    pub(crate) adam: [Adam; 3],
    grads: [Vec<f32>; 3],
    touched: Touched,
}

impl BackgroundOptim {
    fn new(b: &BackgroundField) -> Self {
        let sizes = [b.grid_params.len(), b.density_params.len(), b.color_params.len()];
        Self {
            adam: sizes.map(Adam::new),
            grads: sizes.map(|n| vec![0.0; n]),
            touched: Touched::new(&b.grid),
        }
    }
}

/// The views' colour maps (three gains a view) with their Adam state and gradients.
pub(crate) struct AppearanceOptim {
    pub(crate) params: Vec<f32>,
    pub(crate) adam: Adam,
    grads: Vec<f32>,
}

impl AppearanceOptim {
    fn new(views: usize) -> Self {
        Self {
            params: vec![1.0; 3 * views],
            adam: Adam::new(3 * views),
            grads: vec![0.0; 3 * views],
        }
    }

    fn map(&self, view: usize) -> ViewAppearance {
        ViewAppearance {
            gain: [
                self.params[3 * view],
                self.params[3 * view + 1],
                self.params[3 * view + 2],
            ],
        }
    }
}

pub struct NeusTrainer {
    pub config: TrainConfig,
    pub field: NeusField,
    pub data: Dataset,
    pub train_views: Vec<usize>,
    pub holdout_views: Vec<usize>,
    pub occupancy: OccupancyGrid,
    /// The SDF the occupancy's refresh read at its cells' centres: where in a cell the surface lies.
    pub centre_sdf: CentreSdf,
    pub step: usize,
    pub(crate) adam: [Adam; 4],
    pub(crate) bg_optim: Option<BackgroundOptim>,
    /// Each view's colour map (`appearance`); the identity for held-out views.
    pub(crate) appearance: AppearanceOptim,
    pub(crate) rng: SplitMix64,
    /// The running mean of the parameters over the run's last steps (`average_last`), put into the field
    /// after the last step.
    pub average: ParamAverage,
    /// Seconds spent in each phase of the steps taken so far (not saved in checkpoints).
    pub phases: StepPhases,
    touched: Touched,
    grads: [Vec<f32>; 4],
    scratch: Scratch,
    /// The field at the step's samples, forward and backward.
    pass: FieldPass,
    /// Multi-view stereo points (unit coordinates), found at the first step that uses them.
    stereo_points: Option<Vec<[f32; 3]>>,
    stereo_scratch: StereoScratch,
}

/// Buffers of the stereo-point term's SDF pass.
#[derive(Default)]
struct StereoScratch {
    points: Vec<f32>,
    pass: SdfPassScratch,
}

/// Split `s` into consecutive pieces of the given lengths.
fn split_by<'a, T>(mut s: &'a mut [T], offsets: &[usize]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(offsets.len().saturating_sub(1));
    for w in offsets.windows(2) {
        let (a, b) = s.split_at_mut(w[1] - w[0]);
        out.push(a);
        s = b;
    }
    out
}

/// Why training could not start.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    #[error("config: {0}")]
    Config(ConfigError),
    #[error("{}: the capture has no views", .0.display())]
    NoViews(std::path::PathBuf),
    #[error(
        "{}: every mask is empty (no pixel above 127): an object capture needs the object marked; \
         if the masks mark nothing on purpose, train it as a scene (--kind scene)",
        .0.display()
    )]
    EmptyMasks(std::path::PathBuf),
    #[error(
        "{}: no masks: an object is trained on what its masks mark (`pganeus train` computes them from \
         the photos of an object resting on the board); or train the capture as a scene (--kind scene), \
         which also models what lies beyond the unit sphere",
        .0.display()
    )]
    NoMasks(std::path::PathBuf),
}

impl NeusTrainer {
    pub fn new(config: TrainConfig, data: Dataset) -> Result<Self, TrainError> {
        config.validate().map_err(TrainError::Config)?;
        if data.views.is_empty() {
            return Err(TrainError::NoViews(data.dir.clone()));
        }
        // An object is trained on what its masks mark: masks marking nothing in any view would have it fit
        // empty space for minutes. A scene's masks mark what is not scene, so empty ones are fine there.
        if config.kind == CaptureSubject::Object && !data.has_masks() {
            return Err(TrainError::NoMasks(data.dir.join(pganeus_io::MASK_DIR)));
        }
        let empty = data.empty_masks();
        if config.kind == CaptureSubject::Object && !empty.is_empty() {
            let folder = data.dir.join(pganeus_io::MASK_DIR);
            if empty.len() == data.views.len() {
                return Err(TrainError::EmptyMasks(folder));
            }
            tracing::warn!(
                "{}: the masks of {} of {} views mark nothing: {:?}",
                folder.display(),
                empty.len(),
                data.views.len(),
                empty
            );
        }
        let (mut train_views, mut holdout_views) = (Vec::new(), Vec::new());
        for i in 0..data.views.len() {
            if config.holdout_every > 0 && data.views.len() > 2 && i % config.holdout_every == config.holdout_every / 2
            {
                holdout_views.push(i);
            } else {
                train_views.push(i);
            }
        }
        tracing::debug!(
            "training the {} field: {} steps of {} rays, {} training and {} held-out views of {}×{}, \
             unit sphere at {:?} radius {:.3} m, {} grid levels, background {}",
            config.kind.name(),
            config.iterations,
            config.batch_rays,
            train_views.len(),
            holdout_views.len(),
            data.width,
            data.height,
            data.centre.to_array(),
            data.radius,
            config.field.grid.levels,
            if config.field.background.is_some() {
                "field"
            } else {
                "colour"
            }
        );
        // The world's plane z = 0 (the board) in unit coordinates, where a scene field starts.
        let board_height = (-data.centre.z / data.radius) as f32;
        let mut field = NeusField::new(&config.field, config.seed, board_height);
        if config.view_independent_steps > 0 {
            field.zero_view_weights();
        }
        let bg_optim = field.background.as_ref().map(BackgroundOptim::new);
        let adam = [
            Adam::new(field.grid_params.len()),
            Adam::new(field.sdf_params.len()),
            Adam::new(field.color_params.len()),
            Adam::new(field.extra.len()),
        ];
        let grads = [
            vec![0.0; field.grid_params.len()],
            vec![0.0; field.sdf_params.len()],
            vec![0.0; field.color_params.len()],
            vec![0.0; field.extra.len()],
        ];
        let touched = Touched::new(&field.grid);
        let data_views = data.views.len();
        Ok(Self {
            occupancy: OccupancyGrid::full(config.occupancy_res),
            centre_sdf: CentreSdf::unknown(config.occupancy_res),
            rng: SplitMix64::new(config.seed ^ 0xA5A5),
            config,
            field,
            data,
            train_views,
            holdout_views,
            step: 0,
            adam,
            bg_optim,
            appearance: AppearanceOptim::new(data_views),
            average: ParamAverage::default(),
            phases: StepPhases::default(),
            touched,
            grads,
            scratch: Scratch::default(),
            pass: FieldPass::default(),
            stereo_points: None,
            stereo_scratch: StereoScratch::default(),
        })
    }

    /// View `i`'s colour map: learned for a training view (with `per_view_appearance`), else the identity.
    pub fn view_appearance(&self, i: usize) -> ViewAppearance {
        self.appearance.map(i)
    }

    /// The stereo points the term pulls onto the zero level (found now if not yet).
    pub fn stereo_points(&mut self) -> &[[f32; 3]] {
        let (data, views, kind, cfg) = (&self.data, &self.train_views, self.config.kind, &self.config.stereo);
        self.stereo_points
            .get_or_insert_with(|| stereo_points(data, views, kind, cfg))
    }

    /// The stereo-point term: mean |SDF| over a batch of stereo points, its gradient (times `weight`) added to
    /// the SDF MLP's and the grid's. Returns the mean.
    fn stereo_term(&mut self, weight: f32, levels: usize) -> f32 {
        self.stereo_points();
        let pts = self.stereo_points.as_deref().unwrap_or_default();
        if pts.is_empty() {
            return 0.0;
        }
        let k = self.config.batch_rays.min(pts.len());
        let sc = &mut self.stereo_scratch;
        sc.points.clear();
        for _ in 0..k {
            sc.points.extend(pts[(self.rng.next_u64() % pts.len() as u64) as usize]);
        }
        let width = 1 + self.config.field.feature_dim;
        let out = self.field.sdf_forward(
            &sc.points,
            levels,
            &mut sc.pass.unit01,
            &mut sc.pass.enc,
            &mut sc.pass.input,
            &mut sc.pass.mlp,
        );
        sc.pass.d_out.clear();
        sc.pass.d_out.resize(k * width, 0.0);
        let mut sum = 0.0;
        for i in 0..k {
            let f = out[i * width];
            sum += f.abs();
            sc.pass.d_out[i * width] = weight * f.signum() / k as f32;
        }
        let [grid, sdf, ..] = &mut self.grads;
        self.field.sdf_backward(
            &sc.pass.unit01,
            &mut sc.pass.mlp,
            &sc.pass.d_out,
            GradMode::Accumulate,
            &mut sc.pass.back,
            Some(SdfGrads {
                grid,
                sdf,
                touched: &mut self.touched,
            }),
            None,
            levels,
        );
        sum / k as f32
    }

    /// The finite-difference step at a level count: the finest active cell, in unit coordinates.
    pub fn fd_eps(&self, levels: usize) -> f32 {
        let g = &self.config.field.grid;
        let res = g.base_resolution as f64 * g.growth_factor().powi(levels.max(1) as i32 - 1);
        (2.0 / res as f32).max(g.finest_cell())
    }

    /// One optimisation step.
    pub fn step(&mut self) -> StepStats {
        let t0 = std::time::Instant::now();
        let mut lap = Lap::start();
        let cfg = self.config.clone();
        let step = self.step;
        let lr = cfg.lr_at(step);
        let levels = cfg.active_levels(step);
        let anneal = (step as f32 / cfg.anneal_end.max(1) as f32).min(1.0);
        let eps = self.fd_eps(levels);
        let masked = self.data.has_masks();
        // An object's masks say where it is (mask loss); a scene's say what is not scene (left out).
        let scene = cfg.kind == CaptureSubject::Scene;
        let object_masks = masked && !scene;
        let sc = &mut self.scratch;

        // Rays from random pixels of the training views.
        let r = cfg.batch_rays;
        sc.rays_o.clear();
        sc.rays_d.clear();
        sc.gt.clear();
        sc.mask.clear();
        sc.view.clear();
        sc.bg_jitter.clear();
        let (w, h) = (self.data.width as f64, self.data.height as f64);
        for _ in 0..r {
            // A scene's masked pixels are drawn again (a few times), so rays are not wasted on them.
            let mut tries = 0;
            let (v, x, y, px, weight) = loop {
                let v = self.train_views[(self.rng.next_u64() % self.train_views.len() as u64) as usize];
                let (mut x, mut y) = (self.rng.next_f64() * w, self.rng.next_f64() * h);
                if !cfg.pixel_jitter {
                    (x, y) = (x.floor() + 0.5, y.floor() + 0.5);
                }
                let px = (y as usize).min(h as usize - 1) * w as usize + (x as usize).min(w as usize - 1);
                let m = self.data.views[v].mask.as_ref().map_or(1.0, |m| m[px]);
                let weight = if scene && masked { 1.0 - m } else { m };
                tries += 1;
                if weight > 0.0 || !scene || tries == 8 {
                    break (v, x, y, px, weight);
                }
            };
            let ray = self.data.ray(v, x, y);
            sc.rays_o.push(ray.origin);
            sc.rays_d.push(ray.dir);
            sc.gt.push(self.data.views[v].rgb[px]);
            sc.mask.push(weight);
            sc.view.push(v);
            sc.bg_jitter.push(self.rng.next_f64() as f32);
        }

        lap.charge(&mut self.phases.rays);

        // Samples where the occupancy grid allows.
        let everywhere;
        let grid = if step < cfg.occupancy_warmup {
            everywhere = OccupancyGrid::full(1);
            &everywhere
        } else {
            &self.occupancy
        };
        sc.t.clear();
        sc.dt.clear();
        sc.offsets.clear();
        sc.offsets.push(0);
        let march = Marching {
            steps: cfg.steps_per_ray,
            cap: cfg.max_samples_per_ray,
            anchored: false,
        };
        // Within the density's reach of the surface and a margin for the centres' age and interpolation.
        let reach = (step >= cfg.occupancy_warmup && cfg.sample_band > 0.0)
            .then(|| 4.0 / self.field.inv_s() + cfg.sample_band * self.occupancy.cell_size());
        // The jitters drawn in ray order first, so the parallel march draws the stream a serial one would.
        sc.march_jitter.clear();
        for _ in 0..r {
            sc.march_jitter.push(self.rng.next_f64() as f32);
        }
        let (rays_o, rays_d, jitters, centre_sdf) = (&sc.rays_o, &sc.rays_d, &sc.march_jitter, &self.centre_sdf);
        sc.regulariser_points.clear();
        sc.ended_inside.clear();
        sc.ended_inside.resize_with(r, Default::default);
        let ended_inside = &sc.ended_inside;
        sc.march.run_with_points(
            r,
            |i, t, dt, points| {
                let from = t.len();
                let (o, d) = (rays_o[i], rays_d[i]);
                sample_ray(grid, o, d, march, jitters[i], t, dt);
                if let Some(reach) = reach {
                    // Every REGULARISER_EVERY-th dropped sample, from a phase of the ray's own jitter.
                    let mut k = (jitters[i] * 7919.0).fract() * REGULARISER_EVERY as f32;
                    let last = t.last().copied();
                    centre_sdf.keep_near_surface(o, d, reach, from, t, dt, |s, sdf| {
                        if Some(s) == last {
                            // The march's last sample, dropped: deeper than the band in the solid, or outside.
                            ended_inside[i].store(sdf < 0.0, std::sync::atomic::Ordering::Relaxed);
                        }
                        k += 1.0;
                        if k >= REGULARISER_EVERY as f32 {
                            k -= REGULARISER_EVERY as f32;
                            points.push([o[0] + s * d[0], o[1] + s * d[1], o[2] + s * d[2]]);
                        }
                    });
                }
            },
            &mut sc.offsets,
            &mut sc.t,
            &mut sc.dt,
            &mut sc.regulariser_points,
        );
        lap.charge(&mut self.phases.march);
        let m = sc.t.len();
        if m == 0 {
            // Every ray missed the occupied region: nothing to learn from this batch.
            self.step += 1;
            return StepStats {
                step: self.step,
                loss: LossTerms::default(),
                psnr: 0.0,
                rays: r,
                samples: 0,
                background_rays: 0,
                seconds: t0.elapsed().as_secs_f64(),
                lr,
                inv_s: self.field.inv_s(),
                active_levels: levels,
                occupied: self.occupancy.occupied_fraction(),
            };
        }

        // The SDF at each sample and a step away along x, y, z; gradients, cosines, normals, colours.
        let pass_settings = PassSettings {
            active_levels: levels,
            fd_eps: eps,
            view_independent: step < cfg.view_independent_steps,
        };
        self.pass
            .forward(&self.field, &sc.rays_o, &sc.rays_d, &sc.offsets, &sc.t, pass_settings);
        let (eik, overhang) = (self.pass.eikonal_sum, self.pass.overhang_sum);
        lap.charge(&mut self.phases.field_forward);

        // What lies behind each ray's samples: the background field's colour where light gets through them.
        // A ray whose transmittance falls below rendering's stopping point would add less than a thousandth
        // (a quarter of an 8-bit step) to its pixel: it takes the constant colour at infinity, as a rendered
        // ray stopped there does. On a tabletop most rays end on the board inside the sphere.
        let inv_s = self.field.inv_s();
        sc.seen_behind.clear();
        if self.field.background.is_some() {
            let (offsets, sdf0, cos, dt) = (&sc.offsets, &self.pass.sdf, &self.pass.cos, &sc.dt);
            let ended_inside = &sc.ended_inside;
            sc.seen_behind.extend((0..r).filter(|&i| {
                let (a, b) = (offsets[i], offsets[i + 1]);
                if ended_inside[i].load(std::sync::atomic::Ordering::Relaxed) {
                    return false;
                }
                let mut t = 1.0f32;
                for s in a..b {
                    t *= 1.0 - section_alpha(sdf0[s], cos[s], dt[s], inv_s, anneal);
                    if t < STOP_TRANSMITTANCE {
                        return false;
                    }
                }
                true
            }));
        } else {
            sc.seen_behind.extend(0..r);
        }
        sc.behind_o.clear();
        sc.behind_d.clear();
        for &i in &sc.seen_behind {
            sc.behind_o.push(sc.rays_o[i]);
            sc.behind_d.push(sc.rays_d[i]);
        }
        let (jit, seen) = (&sc.bg_jitter, &sc.seen_behind);
        self.field
            .colour_behind(&sc.behind_o, &sc.behind_d, |j| jit[seen[j]], &mut sc.bg);
        sc.behind.clear();
        sc.behind.resize(r, self.field.background());
        for (&i, &c) in sc.seen_behind.iter().zip(&sc.bg.out) {
            sc.behind[i] = c;
        }
        lap.charge(&mut self.phases.background_forward);

        // Render, losses and their gradients, ray by ray.
        let count = if masked {
            sc.mask.iter().sum::<f32>().max(1.0)
        } else {
            r as f32
        };
        sc.d_sdf0.resize(m, 0.0);
        sc.d_cos.resize(m, 0.0);
        sc.d_rgb.resize(m, [0.0; 3]);
        let ds = split_by(&mut sc.d_sdf0, &sc.offsets);
        let dc = split_by(&mut sc.d_cos, &sc.offsets);
        let dr = split_by(&mut sc.d_rgb, &sc.offsets);
        let (offsets, sdf0, cos, dt, tt, rgb, gt, mask, behind, view) = (
            &sc.offsets,
            &self.pass.sdf,
            &self.pass.cos,
            &sc.dt,
            &sc.t,
            &self.pass.rgb,
            &sc.gt,
            &sc.mask,
            &sc.behind,
            &sc.view,
        );
        let mask_w = cfg.mask_weight;
        let learn_appearance = cfg.per_view_appearance;
        let appearance = &self.appearance;
        type RayOut = (f32, f32, f32, f32, [f32; 3], [f32; 3]);
        let per_ray: Vec<RayOut> = ds
            .into_par_iter()
            .zip(dc)
            .zip(dr)
            .enumerate()
            .map_init(
                || (Vec::new(), Vec::new()),
                |(alpha, trans), (i, ((ds, dc), dr))| {
                    let (a, b) = (offsets[i], offsets[i + 1]);
                    let x = RayInputs {
                        sdf: &sdf0[a..b],
                        cos: &cos[a..b],
                        dt: &dt[a..b],
                        t: &tt[a..b],
                        rgb: &rgb[a..b],
                        inv_s,
                        anneal,
                        background: behind[i],
                    };
                    alpha.resize(b - a, 0.0);
                    trans.resize(b - a, 0.0);
                    let o = render_ray(&x, alpha, trans);
                    let wm = mask[i];
                    // The colour the ray's view records: through its colour map when learned.
                    let map = if learn_appearance {
                        appearance.map(view[i])
                    } else {
                        ViewAppearance::IDENTITY
                    };
                    let (l1, d_rgb, d_map) = recorded_l1(&map, o.rgb, gt[i], wm);
                    let (d_rgb, d_map) = (d_rgb.map(|d| d / count), d_map.map(|d| d / count));
                    let recorded = map.apply(o.rgb);
                    let se: f32 = (0..3).map(|k| wm * (recorded[k] - gt[i][k]).powi(2) / 3.0).sum();
                    let (mut bce, mut d_op) = (0.0, 0.0);
                    if object_masks {
                        let op = o.opacity.clamp(1e-3, 1.0 - 1e-3);
                        bce = -(wm * op.ln() + (1.0 - wm) * (1.0 - op).ln());
                        if o.opacity > 1e-3 && o.opacity < 1.0 - 1e-3 {
                            d_op = mask_w * (op - wm) / (op * (1.0 - op)) / r as f32;
                        }
                    }
                    let mut d_inv_s = 0.0;
                    let mut d_bg = [0.0; 3];
                    render_ray_backward(
                        &x,
                        d_rgb,
                        d_op,
                        0.0,
                        alpha,
                        trans,
                        RayGrads {
                            sdf: ds,
                            cos: dc,
                            rgb: dr,
                            inv_s: &mut d_inv_s,
                            background: &mut d_bg,
                        },
                    );
                    (l1, se, bce, d_inv_s, d_bg, d_map)
                },
            )
            .collect();
        let mut loss = LossTerms::default();
        let mut sq = 0.0f32;
        let mut d_inv_s = 0.0f32;
        sc.d_behind.clear();
        let app = &mut self.appearance;
        if learn_appearance {
            app.grads.iter_mut().for_each(|g| *g = 0.0);
        }
        for ((l1, se, bce, dis, _, dmap), &v) in per_ray.iter().zip(&sc.view) {
            loss.rgb += l1;
            sq += se;
            loss.mask += bce;
            d_inv_s += dis;
            if learn_appearance {
                for (g, d) in app.grads[3 * v..3 * v + 3].iter_mut().zip(dmap) {
                    *g += d;
                }
            }
        }
        if learn_appearance {
            // The gauge: all gains up and the field's colour down render the same, so the gains' mean over
            // the training views is pulled to one (the field keeps the views' mean exposure).
            let n = self.train_views.len() as f32;
            for k in 0..3 {
                let mean = self.train_views.iter().map(|&v| app.params[3 * v + k]).sum::<f32>() / n;
                loss.appearance += (mean - 1.0).powi(2);
                for &v in &self.train_views {
                    app.grads[3 * v + k] += 2.0 * cfg.appearance_weight * (mean - 1.0) / n;
                }
            }
        }
        lap.charge(&mut self.phases.render);
        // Through the background field to the colour at infinity (from the rays it was run for).
        sc.d_behind.extend(sc.seen_behind.iter().map(|&i| per_ray[i].4));
        let d_bg = match (&self.field.background, &mut self.bg_optim) {
            (Some(b), Some(opt)) => {
                let [gg, gd, gc] = &mut opt.grads;
                b.backward(
                    &mut sc.bg,
                    &sc.d_behind,
                    BackgroundGrads {
                        grid: gg,
                        touched: &mut opt.touched,
                        density: gd,
                        color: gc,
                    },
                )
            }
            _ => sc
                .d_behind
                .iter()
                .fold([0.0f32; 3], |a, d| [a[0] + d[0], a[1] + d[1], a[2] + d[2]]),
        };
        lap.charge(&mut self.phases.background_backward);
        // The eikonal and no-overhang terms are means over the samples marched, those the band dropped
        // included: each regulariser point stands for REGULARISER_EVERY of them.
        let n_reg = sc.regulariser_points.len();
        let m_all = (m + REGULARISER_EVERY * n_reg).max(1);
        loss.rgb /= count;
        loss.mask /= r as f32;
        let psnr = -10.0 * (sq / count).max(1e-10).log10();

        // Back through the colour and SDF networks and the grid to the parameters.
        let [grid, sdf, color, _] = &mut self.grads;
        self.pass.backward(
            &self.field,
            SampleGrads {
                sdf: &sc.d_sdf0,
                cos: &sc.d_cos,
                rgb: &sc.d_rgb,
                eikonal: cfg.eikonal_weight / m_all as f32,
                overhang: cfg.overhang_weight / m_all as f32,
            },
            Some(ParamGrads {
                grid,
                sdf,
                color,
                touched: &mut self.touched,
            }),
            None,
        );
        lap.charge(&mut self.phases.field_backward);
        let [grid, sdf, ..] = &mut self.grads;
        let per_point = REGULARISER_EVERY as f32 / m_all as f32;
        let reg = sc.regulariser.run(
            &self.field,
            &sc.regulariser_points,
            levels,
            eps,
            RegulariserWeights {
                eikonal: cfg.eikonal_weight * per_point,
                overhang: cfg.overhang_weight * per_point,
            },
            SdfGrads {
                grid,
                sdf,
                touched: &mut self.touched,
            },
        );
        let every = REGULARISER_EVERY as f64;
        loss.eikonal = ((eik + every * reg.eikonal) / m_all as f64) as f32;
        loss.overhang = ((overhang + every * reg.overhang) / m_all as f64) as f32;
        lap.charge(&mut self.phases.regulariser);
        let stereo_w = cfg.stereo_weight_at(step);
        if stereo_w > 0.0 {
            self.stereo_points();
            lap.charge(&mut self.phases.stereo_start);
            loss.stereo = self.stereo_term(stereo_w, levels);
        }
        lap.charge(&mut self.phases.stereo);
        // inv_s = exp(10 v): dv = 10 inv_s d(inv_s); the background is clamped to [0, 1].
        self.grads[3][0] = d_inv_s * 10.0 * inv_s;
        for k in 0..3 {
            let raw = self.field.extra[1 + k];
            self.grads[3][1 + k] = if (0.0..=1.0).contains(&raw) { d_bg[k] } else { 0.0 };
        }

        // Adam.
        let adam_cfg = AdamConfig {
            lr,
            beta1: 0.9,
            beta2: 0.99,
            eps: 1e-15,
            weight_decay: 0.0,
        };
        let [ga, gs, gc, ge] = &mut self.grads;
        let [aa, as_, ac, ae] = &mut self.adam;
        aa.step_sparse(
            &adam_cfg,
            lr,
            &mut self.field.grid_params,
            ga,
            &mut self.touched,
            &self.field.grid,
        );
        as_.step_dense(&adam_cfg, lr, &mut self.field.sdf_params, gs);
        ac.step_dense(&adam_cfg, lr, &mut self.field.color_params, gc);
        ae.step_dense(&adam_cfg, lr * 0.1, &mut self.field.extra, ge);
        if learn_appearance {
            let AppearanceOptim { params, adam, grads } = &mut self.appearance;
            adam.step_dense(&adam_cfg, lr, params, grads);
        }
        if let (Some(b), Some(opt)) = (&mut self.field.background, &mut self.bg_optim) {
            let [gg, gd, gc] = &mut opt.grads;
            let [ag, ad, ac] = &mut opt.adam;
            ag.step_sparse(&adam_cfg, lr, &mut b.grid_params, gg, &mut opt.touched, &b.grid);
            ad.step_dense(&adam_cfg, lr, &mut b.density_params, gd);
            ac.step_dense(&adam_cfg, lr, &mut b.color_params, gc);
        }

        lap.charge(&mut self.phases.adam);

        self.step += 1;
        let averaged = self.step > cfg.average_start() && self.step <= cfg.iterations;
        if averaged {
            self.average.add(&self.field);
        }
        lap.charge(&mut self.phases.average);
        if averaged && self.step == cfg.iterations {
            tracing::debug!(
                "the field is the mean of the last {} steps' parameters",
                self.average.count
            );
            std::mem::take(&mut self.average).apply(&mut self.field);
            // The mean's surface is not any iterate's: every cell again (once the grid is in use at all).
            if self.step >= cfg.occupancy_warmup {
                for part in 0..4 {
                    self.refresh_occupancy_part(part, true);
                }
            }
        } else if self.step >= cfg.occupancy_warmup && self.step.is_multiple_of(cfg.occupancy_every) {
            self.refresh_occupancy();
        }
        lap.charge(&mut self.phases.occupancy);
        if self.step.is_multiple_of(100) {
            tracing::debug!(
                "step {}: {:.1} samples per ray, {} active levels, 1/s {:.0}, lr {:.2e}, {:.1} ms",
                self.step,
                m as f64 / r.max(1) as f64,
                levels,
                inv_s,
                lr,
                t0.elapsed().as_secs_f64() * 1e3
            );
        }
        StepStats {
            step: self.step,
            loss,
            psnr,
            rays: r,
            samples: m,
            background_rays: if self.field.background.is_some() {
                self.scratch.seen_behind.len()
            } else {
                0
            },
            seconds: t0.elapsed().as_secs_f64(),
            lr,
            inv_s,
            active_levels: levels,
            occupied: self.occupancy.occupied_fraction(),
        }
    }

    /// Re-evaluate the SDF at the centres of a quarter of the cells (a
    /// different quarter each time); mark those within reach of the surface.
    /// Cells far from every occupied one are read in every fourth sweep only.
    pub fn refresh_occupancy(&mut self) {
        let refresh = self.step / self.config.occupancy_every.max(1);
        self.refresh_occupancy_part(refresh % 4, (refresh / 4).is_multiple_of(FAR_SWEEP_EVERY));
    }

    /// Re-evaluate the quarter `part` (0–3) of the occupancy cells: all of them, or those near an occupied
    /// cell (a grid that starts full is read whole until its empty space shows).
    fn refresh_occupancy_part(&mut self, part: usize, every_cell: bool) {
        let cells = self.occupancy.cells().len();
        let near = (!every_cell).then(|| self.occupancy.near_occupied(NEAR_CELLS));
        let idx: Vec<usize> = (part..cells)
            .step_by(4)
            .filter(|&i| near.as_ref().is_none_or(|n| n[i]))
            .collect();
        let pts: Vec<f32> = idx.iter().flat_map(|&i| self.occupancy.centre(i)).collect();
        let sdf = self.field.sdf_values(&pts, self.config.active_levels(self.step));
        // Within a cell's half-diagonal plus the width of the NeuS density (a few 1/s).
        let band = 0.5 * 3f32.sqrt() * self.occupancy.cell_size() * 1.5 + 4.0 / self.field.inv_s();
        self.occupancy.update(&idx, &sdf, band);
        self.centre_sdf.record(&idx, &sdf);
        tracing::debug!(
            "step {}: occupancy refreshed on {} cells, band {:.4} (unit), {:.1} % occupied",
            self.step,
            idx.len(),
            band,
            100.0 * self.occupancy.occupied_fraction()
        );
    }
}
