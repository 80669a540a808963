//! PA (the paper's physics-aware stage): a body's launch and contact values
//! from the frames of a fixed camera, through the simulator. Each step
//! simulates the frames of the current window with exact derivatives (the
//! simulator's dual numbers), renders every frame's body at its simulated pose
//! on a random batch of pixels ([`crate::image_loss`]), and chains each
//! frame's pose gradient with the pose's derivatives to the parameters:
//!
//! `dL/dp = Σ_k [dL/dδt_k · dt_k/dp + dL/dδω_k · dω_k/dp]`, with
//! `dω_k/dp = 2 vec(dq_k/dp ⊗ q_k*)` (the left tangent of the quaternion).
//!
//! The step is taken in pose space, not parameter by parameter: each frame's
//! pose is asked to move down its image gradient by at most `pose_step`
//! (the frame with the steepest gradient moves that far, the others in
//! proportion), and one damped Gauss–Newton solve finds the parameter change
//! whose poses move so (`J δp ≈ d`, rotations weighed by the body's size).
//! The simulator's Jacobian then does the conditioning: a parameter the poses
//! barely depend on barely moves. (Adam, moving every parameter at the same
//! pace whatever its effect, sent a sliding block's v0 upward into hops: in
//! the image, up and forward look alike from a camera above.) The window of
//! frames doubles every `window_steps` steps, so the launch is pinned by the
//! frames before the first contact, as [`crate::PhysicsFit`] does with poses.

use crate::fit_physics::{probe_scale, StartContact};
use crate::image_loss::{FrameError, FrameTarget, ImageLoss, ImageLossWeights, PreparedFrame};
use crate::least_squares::{lm_step, Linearization};
use crate::shutter::Motion;
use crate::unknowns::Unknowns;
use geom::{Quat, SplitMix64};
use neus::compose::{ComposedRay, Composer};
use neus::ObjectModel;
use serde::{Deserialize, Serialize};
use sim::{simulate_with_gradients, World};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VideoPhysicsConfig {
    /// Steps. Default 200.
    pub iterations: usize,
    /// Pixels rendered per frame per step (a random batch of the window around the body and its mask; 0:
    /// all of it). Default 256.
    pub rays_per_frame: usize,
    /// Frames in the first window (it doubles every `window_steps` steps). Default 4.
    pub initial_window: usize,
    /// Steps per window at most before it doubles. Default 40.
    pub window_steps: usize,
    /// A window also ends once its loss has stopped falling: the mean batch loss of its last
    /// [`LOSS_RUN`] steps is above `1 − window_tolerance` times the mean of the [`LOSS_RUN`] before them
    /// (the last window ends the run). On the tabletop videos the loss of the 32- and 48-frame windows,
    /// three quarters of PA's renders, moved by 0–10 % over their 40 steps, and a drop's first window not
    /// at all. 0: every window runs `window_steps`. Default 0.02.
    pub window_tolerance: f64,
    /// How far the frame with the steepest image gradient is asked to move per step at the start, m
    /// (a turn counts as the body's size times its angle); it decays tenfold over the run. Default 0.003.
    pub pose_step: f64,
    /// Damping of the Gauss–Newton solve, relative to the diagonal. Default 1e-3.
    pub damping: f64,
    pub fit_initial_pose: bool,
    pub fit_velocity: bool,
    pub fit_angular_velocity: bool,
    pub fit_restitution: bool,
    pub fit_friction: bool,
    pub weights: ImageLossWeights,
    pub seed: u64,
}

impl Default for VideoPhysicsConfig {
    fn default() -> Self {
        Self {
            iterations: 200,
            rays_per_frame: 256,
            initial_window: 4,
            window_steps: 40,
            window_tolerance: 0.02,
            pose_step: 0.003,
            damping: 1e-3,
            fit_initial_pose: false,
            fit_velocity: true,
            fit_angular_velocity: true,
            fit_restitution: true,
            fit_friction: true,
            weights: ImageLossWeights::default(),
            seed: 0,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VideoPhysicsError {
    #[error("frame {frame}: {error}")]
    Frame { frame: usize, error: FrameError },
    #[error("need at least 2 frames, got {0}")]
    TooFewFrames(usize),
    #[error("body index {0} is out of range")]
    NoSuchBody(usize),
    #[error("nothing to fit: every fit_* switch is off")]
    NothingToFit,
    #[error("the world: {0}")]
    World(sim::ConfigError),
}

/// Steps whose mean batch loss is compared with the steps before them ([`VideoPhysicsConfig::window_tolerance`]):
/// a batch of 256 pixels per frame swings by a third from step to step.
pub const LOSS_RUN: usize = 10;

/// One step's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct VideoPhysicsStats {
    pub iteration: usize,
    pub window: usize,
    /// Mean over the window's frames of the batch loss, before the step.
    pub loss: f64,
}

/// What [`PhysicsFromVideo::finish`] returns.
pub struct VideoPhysicsResult {
    /// Every frame's world (the fitted parameters, or the start's).
    pub world: World,
    /// Each frame's image terms at its simulated pose.
    pub losses: Vec<ImageLoss>,
    /// Whether the start explained the video better than the fit and was kept.
    pub kept_start: bool,
}

/// The stage: `new`, then [`Self::step`] (or [`Self::run`]), then [`Self::finish`].
pub struct PhysicsFromVideo<'a> {
    cfg: VideoPhysicsConfig,
    object: &'a ObjectModel,
    scene: &'a [ComposedRay],
    frames: Vec<PreparedFrame<'a>>,
    world: World,
    body: usize,
    params: Vec<f64>,
    /// The parameters it started from (what [`Self::finish`] falls back to).
    start: Vec<f64>,
    unknowns: Unknowns,
    /// The body's size: a turn of one radian moves its surface this far, m.
    size: f64,
    window: usize,
    iteration: usize,
    /// The batch losses of the current window's steps.
    window_losses: Vec<f64>,
    composer: Composer,
    rng: SplitMix64,
}

impl<'a> PhysicsFromVideo<'a> {
    /// `world` holds the scene's collision shape, the bodies and the start guess of body `body`'s initial
    /// state and contact values; `frames` (one per video frame, all through one fixed camera) and `scene`
    /// (the scene pre-rendered through that camera) are what its renders are compared with.
    pub fn new(
        cfg: VideoPhysicsConfig,
        object: &'a ObjectModel,
        scene: &'a [ComposedRay],
        frames: &'a [FrameTarget],
        world: World,
        body: usize,
    ) -> Result<Self, VideoPhysicsError> {
        if body >= world.bodies.len() {
            return Err(VideoPhysicsError::NoSuchBody(body));
        }
        if frames.len() < 2 {
            return Err(VideoPhysicsError::TooFewFrames(frames.len()));
        }
        let prepared = frames
            .iter()
            .enumerate()
            .map(|(frame, f)| PreparedFrame::new(f, scene).map_err(|error| VideoPhysicsError::Frame { frame, error }))
            .collect::<Result<Vec<_>, _>>()?;
        world.validate().map_err(VideoPhysicsError::World)?;
        let unknowns = Self::unknowns_of(&cfg, &world, body, StartContact::Free);
        if unknowns.is_empty() {
            return Err(VideoPhysicsError::NothingToFit);
        }
        let params = world.params();
        let size = world.bodies[body].bounding_radius.max(1e-3);
        let mut fit = Self {
            rng: SplitMix64::new(cfg.seed),
            cfg,
            object,
            scene,
            frames: prepared,
            world,
            body,
            start: params.clone(),
            params,
            unknowns,
            size,
            window: 0,
            iteration: 0,
            window_losses: Vec::new(),
            composer: Composer::default(),
        };
        fit.set_window(fit.cfg.initial_window);
        Ok(fit)
    }

    /// The fitted values: each parameter the switches name, the launch as the body's start allows.
    fn unknowns_of(cfg: &VideoPhysicsConfig, world: &World, body: usize, start: StartContact) -> Unknowns {
        let o = world.body_param_offset(body);
        let mut u = Unknowns::default();
        if cfg.fit_initial_pose {
            (0..6).for_each(|k| u.push_param(o + k, probe_scale(k), false));
        }
        u.push_launch(o + 6, start, cfg.fit_velocity, cfg.fit_angular_velocity);
        if cfg.fit_restitution {
            u.push_param(o + 12, probe_scale(12), true);
        }
        if cfg.fit_friction {
            u.push_param(o + 13, probe_scale(13), true);
        }
        u
    }

    /// How the body touches the scene in the first frame ([`StartContact`]): its launch is fitted as that
    /// allows, from the start's launch with what it does not allow taken out.
    pub fn with_start(mut self, start: StartContact) -> Self {
        self.unknowns = Self::unknowns_of(&self.cfg, &self.world, self.body, start);
        let x = self.unknowns.values(&self.params);
        self.unknowns.set(&mut self.params, &x);
        // What `finish` falls back to is a launch the fit could reach.
        self.start = self.params.clone();
        self
    }

    fn set_window(&mut self, window: usize) {
        let n = self.frames.len();
        self.window = if window < 2 { n } else { window.min(n) };
        self.world.config.frames = self.window;
        self.window_losses.clear();
    }

    /// Whether the current window is done: its steps are used up, or its loss stopped falling.
    fn window_done(&self) -> bool {
        let l = &self.window_losses;
        if l.len() >= self.cfg.window_steps.max(1) {
            return true;
        }
        if self.cfg.window_tolerance <= 0.0 || l.len() < 2 * LOSS_RUN {
            return false;
        }
        let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
        let (before, last) = (
            mean(&l[l.len() - 2 * LOSS_RUN..l.len() - LOSS_RUN]),
            mean(&l[l.len() - LOSS_RUN..]),
        );
        last > (1.0 - self.cfg.window_tolerance) * before
    }

    /// Whether the run is over: the last window (the whole video) is done, or the steps are used up.
    pub fn done(&self) -> bool {
        self.iteration >= self.cfg.iterations || (self.window == self.frames.len() && self.window_done())
    }

    /// Frames in the current window.
    pub fn window(&self) -> usize {
        self.window
    }

    /// One step over the window's frames.
    pub fn step(&mut self) -> VideoPhysicsStats {
        if self.window_done() && self.window < self.frames.len() {
            self.set_window(2 * self.window);
        }
        let g = simulate_with_gradients(&self.world, &self.params, self.unknowns.columns());
        let n = self.unknowns.columns().len();
        // Per frame: its pose gradient and the Jacobian of its pose tangent (rotations in metres).
        let mut rows: Vec<([f64; 6], Vec<[f64; 6]>)> = Vec::new();
        let mut total = 0.0;
        for k in 1..self.window {
            let state = &g.frames[k][self.body];
            let pose = state.pose;
            let frame = &mut self.frames[k];
            // Drawn over the shutter at the simulated velocity (held for the step).
            frame.set_motion(Some(Motion::from(state)));
            // A frame whose mask is empty (out of view, hidden) has no image terms.
            if !frame.has_mask() {
                continue;
            }
            let Some(window) = frame.window(self.object, &pose, self.cfg.weights.margin_px) else {
                continue;
            };
            let pixels = frame.pixels(window, self.cfg.rays_per_frame, &mut self.rng);
            let (loss, gp) = frame.loss(
                &mut self.composer,
                self.object,
                self.scene,
                &pose,
                &pixels,
                &self.cfg.weights,
                true,
            );
            total += loss.loss;
            let qc = pose.q.conj();
            let jac = (0..n)
                .map(|j| {
                    let d = |c: usize| g.d(k, self.body, c, j);
                    let dq = Quat::new(d(3), d(4), d(5), d(6));
                    let dw = (dq * qc).vec() * (2.0 * self.size);
                    [d(0), d(1), d(2), dw.x, dw.y, dw.z]
                })
                .collect();
            let gp = [
                gp[0],
                gp[1],
                gp[2],
                gp[3] / self.size,
                gp[4] / self.size,
                gp[5] / self.size,
            ];
            rows.push((gp, jac));
        }
        self.iteration += 1;
        let steepest = rows
            .iter()
            .map(|(gp, _)| gp.iter().map(|v| v * v).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        if steepest > 0.0 {
            let decay = 0.1f64.powf(self.iteration as f64 / self.cfg.iterations.max(1) as f64);
            let eta = self.cfg.pose_step * decay / steepest;
            // Residual r = −d (the wanted pose change d = −η ∇), so the step solves J δ ≈ d; and a trust
            // region: moving a parameter by its scale costs as much as missing a pose by the step (a
            // parameter the poses barely depend on would otherwise take a huge step to move them a little).
            let unknowns = &self.unknowns;
            let mut residuals: Vec<f64> = rows.iter().flat_map(|(gp, _)| gp.map(|v| eta * v)).collect();
            let mut jac: Vec<Vec<f64>> = rows
                .iter()
                .flat_map(|(_, jac)| {
                    (0..6).map(move |c| unknowns.chain(&jac.iter().map(|r| r[c]).collect::<Vec<f64>>()))
                })
                .collect();
            let m = unknowns.len();
            for j in 0..m {
                let mut row = vec![0.0; m];
                row[j] = self.cfg.pose_step * decay / unknowns.probe(j);
                jac.push(row);
                residuals.push(0.0);
            }
            let lin = Linearization { residuals, jac };
            if let Some(delta) = lm_step(&lin, self.cfg.damping) {
                let mut x = unknowns.values(&self.params);
                for (j, (xj, d)) in x.iter_mut().zip(&delta).enumerate() {
                    *xj += d;
                    if unknowns.bounded(j) {
                        *xj = xj.clamp(1e-3, 1.0 - 1e-3);
                    }
                }
                unknowns.set(&mut self.params, &x);
            }
        }
        let counted = rows.len();
        self.window_losses.push(total / counted.max(1) as f64);
        VideoPhysicsStats {
            iteration: self.iteration,
            window: self.window,
            loss: total / counted.max(1) as f64,
        }
    }

    /// Step until [`Self::done`]; the stats of each step.
    pub fn run(&mut self) -> Vec<VideoPhysicsStats> {
        let mut stats = Vec::new();
        while !self.done() {
            stats.push(self.step());
        }
        stats
    }

    /// The world with the fitted parameters in place, over every frame.
    pub fn fitted_world(&self) -> World {
        let mut w = self.world.clone();
        w.config.frames = self.frames.len();
        w.set_params(&self.params);
        w
    }

    /// The image terms of every frame (every pixel around the mask and the body) at the simulated poses.
    pub fn evaluate(&mut self) -> Vec<ImageLoss> {
        let w = self.fitted_world();
        self.evaluate_world(&w)
    }

    /// The fitted world and its image terms, or the start's where the start explains the video better (the
    /// steps follow gradients of random pixel batches with no line search; a chaotic landing can lead them
    /// astray from a launch guess that was right): the lower sum of every frame's full image loss wins.
    pub fn finish(&mut self) -> VideoPhysicsResult {
        let fitted = self.fitted_world();
        let losses = self.evaluate_world(&fitted);
        let mut start = fitted.clone();
        start.set_params(&self.start);
        let start_losses = self.evaluate_world(&start);
        let total = |l: &[ImageLoss]| l.iter().map(|l| l.loss).sum::<f64>();
        if total(&start_losses) < total(&losses) {
            VideoPhysicsResult {
                world: start,
                losses: start_losses,
                kept_start: true,
            }
        } else {
            VideoPhysicsResult {
                world: fitted,
                losses,
                kept_start: false,
            }
        }
    }

    fn evaluate_world(&mut self, w: &World) -> Vec<ImageLoss> {
        let traj = w.simulate(&w.params());
        self.frames
            .iter_mut()
            .zip(&traj.frames)
            .map(|(f, s)| {
                f.set_motion(Some(Motion::from(&s[self.body])));
                f.evaluate(
                    &mut self.composer,
                    self.object,
                    self.scene,
                    &s[self.body].pose,
                    &self.cfg.weights,
                )
            })
            .collect()
    }
}
