//! The PGA step (Eq. 11): the initial velocities and contact parameters of a
//! body that make the simulator reproduce a pose sequence,
//! `min Σ_k w_k (|q_k(θ) − q_k*| + |T_k(θ) − T_k*|)` with `0 < k_n, mu < 1`.
//!
//! Solved by Levenberg–Marquardt with exact dual-number Jacobians; the sum of
//! norms (L1) is minimised by reweighting each frame's blocks (IRLS). Plain
//! least squares was tried and dropped: on the tabletop test it stalls at the
//! first impact (its loss plateaus where impact timing is quantised by the
//! substep) while the L1 loss recovers the parameters exactly.

use crate::least_squares::{lm_step, Bounds, Linearization};
pub(crate) use crate::unknowns::probe_scale;
pub use crate::unknowns::StartContact;
use crate::unknowns::Unknowns;
use geom::{Pose, Quat, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sim::{simulate_with_gradients, World};

/// Settings of the physics fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PhysicsFitConfig {
    /// Maximum Levenberg–Marquardt iterations. Default 40.
    pub iterations: usize,
    /// Weight λ_q of the quaternion error against the translation error (m).
    /// Default 1, as Eq. 11.
    pub rotation_weight: f64,
    /// Fit v0. Default true.
    pub fit_velocity: bool,
    /// Fit omega0. Default true.
    pub fit_angular_velocity: bool,
    /// Fit k_n against the scene. Default true.
    pub fit_restitution: bool,
    /// Fit mu against the scene. Default true.
    pub fit_friction: bool,
    /// With several bodies: one k_n and one mu against the scene for all of them (one board), not one per
    /// body. Default true.
    pub share_scene_contact: bool,
    /// With several bodies: fit each pair's restitution. Default true.
    pub fit_pair_restitution: bool,
    /// With several bodies: fit each pair's friction. Default true.
    pub fit_pair_friction: bool,
    /// Also refine the initial pose (otherwise it is the first observed pose). Default false.
    pub fit_initial_pose: bool,
    /// The last window (the whole sequence) is done when an accepted step
    /// lowers the loss by less than this fraction (or the damping exceeds
    /// 1e4). Default 1e-6.
    pub tolerance: f64,
    /// The same for the windows before it: they only have to pin the launch
    /// well enough for the next window to start near its basin, and a
    /// least-absolute-error fit of a few ballistic frames creeps on by tiny
    /// gains for as long as it is let (the launch then never meets the
    /// contacts). Default 1e-3.
    pub window_tolerance: f64,
    /// k_n and mu stay within `[margin, 1 − margin]`. Default 1e-3.
    pub bound_margin: f64,
    /// Frames in the first fitting window. The window doubles each time the
    /// fit on it has converged, until it covers the sequence: early frames
    /// pin the launch velocity before contacts (whose timing is discrete and
    /// whose loss is rugged far from the answer) enter the loss, as the
    /// paper's multi-body schedule does. 0 = the whole sequence at once. Default 4.
    pub initial_window: usize,
}

impl Default for PhysicsFitConfig {
    fn default() -> Self {
        Self {
            iterations: 40,
            rotation_weight: 1.0,
            fit_velocity: true,
            fit_angular_velocity: true,
            fit_restitution: true,
            fit_friction: true,
            share_scene_contact: true,
            fit_pair_restitution: true,
            fit_pair_friction: true,
            fit_initial_pose: false,
            tolerance: 1e-6,
            window_tolerance: 1e-3,
            bound_margin: 1e-3,
            initial_window: 4,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FitError {
    #[error("body index {0} is out of range")]
    NoSuchBody(usize),
    #[error("need at least 2 observed poses, got {0}")]
    TooFewPoses(usize),
    #[error("{poses} poses but {weights} weights")]
    WeightCount { poses: usize, weights: usize },
    #[error("{poses} poses but {held} depth_held flags")]
    HeldCount { poses: usize, held: usize },
    #[error("weight {0} is negative or not finite")]
    BadWeight(usize),
    #[error("pose {0} has NaN or infinite values")]
    BadPose(usize),
    #[error("nothing to fit: every fit_* switch is off")]
    NothingToFit,
    #[error("{bodies} bodies, {poses} pose sequences, {weights} weight sequences: one of each per body")]
    SequenceCount {
        bodies: usize,
        poses: usize,
        weights: usize,
    },
    #[error("body {body} has {poses} poses, body {first} {frames}: one video, one frame count")]
    FrameCount {
        body: usize,
        poses: usize,
        first: usize,
        frames: usize,
    },
    #[error("rotation_weight must be ≥ 0, got {0}")]
    RotationWeight(f64),
    #[error("no body pair {0}")]
    NoSuchPair(usize),
    #[error("the world: {0}")]
    World(sim::ConfigError),
}

/// One iteration's outcome.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitStats {
    pub iteration: usize,
    /// Eq. 11 loss after the step (summed over frames).
    pub loss: f64,
    pub lambda: f64,
    pub accepted: bool,
    /// No further progress is possible or needed.
    pub converged: bool,
    /// Frames in the fitting window when the step was taken.
    pub window: usize,
}

/// Per-frame error of a fitted trajectory against the observations.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseError {
    /// |ΔT|, m.
    pub translation: f64,
    /// Rotation angle between the two orientations, degrees.
    pub rotation_deg: f64,
}

/// One body's observed poses (one per frame, frame 0 first) and their weights (default 1), for a fit of
/// several bodies at once.
#[derive(Clone, Debug)]
pub struct Observed {
    pub body: usize,
    pub poses: Vec<Pose<f64>>,
    pub weights: Option<Vec<f64>>,
    /// How the body touches the scene in the first frame: what its launch may be.
    pub start: StartContact,
    /// The centre of the fixed camera the poses were seen from, if they were: each frame's translation error
    /// along the line of sight then counts `d / z` of the error across it (the body's bounding diameter `d`
    /// over its distance `z`). A silhouette places a body across the line of sight `z / d` times more
    /// precisely than along it (its size in pixels against the focal length), so with this weighing the
    /// physics (gravity, where contacts happen) says the depth and the images say the rest.
    pub eye: Option<[f64; 3]>,
    /// Frames whose depth the scene pinned (GA held the body on it: where it touches, the board says how far
    /// it is): their errors count alike in every direction. Empty: none.
    pub depth_held: Vec<bool>,
}

impl Observed {
    /// A body's poses, weights default, launch free.
    pub fn new(body: usize, poses: Vec<Pose<f64>>, weights: Option<Vec<f64>>) -> Self {
        Self {
            body,
            poses,
            weights,
            start: StartContact::Free,
            eye: None,
            depth_held: Vec::new(),
        }
    }
}

/// How a frame's translation error is weighed: `e − (1 − α) s (s · e)`, the unit line of sight `s` and the
/// weight `α` of the error along it ([`Observed::eye`]).
#[derive(Clone, Copy, Debug)]
struct Sight {
    s: Vec3<f64>,
    alpha: f64,
}

impl Sight {
    fn of(eye: Option<[f64; 3]>, body_diameter: f64, at: Vec3<f64>) -> Option<Self> {
        let d = at - Vec3::cst(eye?);
        let z = d.norm();
        (z > body_diameter).then(|| Sight {
            s: d * (1.0 / z),
            alpha: body_diameter / z,
        })
    }

    /// The weighed vector (the map is linear and symmetric: it also maps Jacobian columns).
    fn apply(&self, e: Vec3<f64>) -> Vec3<f64> {
        e - self.s * ((1.0 - self.alpha) * self.s.dot(e))
    }
}

/// The fit as a stage: `new`, then `step()` until `converged`.
#[derive(Clone)]
pub struct PhysicsFit {
    cfg: PhysicsFitConfig,
    world: World,
    /// The observed bodies, their poses and weights (every body the same number of frames).
    bodies: Vec<usize>,
    poses: Vec<Vec<Pose<f64>>>,
    weights: Vec<Vec<f64>>,
    /// Each observed body's lines of sight, per frame ([`Observed::eye`]).
    sights: Vec<Vec<Option<Sight>>>,
    frames: usize,
    params: Vec<f64>,
    unknowns: Unknowns,
    bounds: Bounds,
    lambda: f64,
    loss: f64,
    iteration: usize,
    converged: bool,
    /// Frames currently in the loss (the simulation runs only this far).
    window: usize,
    /// The pattern search's step, as a multiple of each parameter's probe scale (reset per window).
    probe: f64,
    /// Which unknowns are contact values, and which ones ([`crate::value_ranges`]).
    contact_values: Vec<(usize, ContactValue)>,
}

/// A contact value a fit can move.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactValue {
    /// The restitution against the scene: shared by every observed body (`None`) or of one body.
    SceneRestitution(Option<usize>),
    /// The friction against the scene, the same way.
    SceneFriction(Option<usize>),
    /// The restitution of pair `p` ([`World::pairs`]).
    PairRestitution(usize),
    /// The friction of pair `p`.
    PairFriction(usize),
}

impl StartContact {
    /// The launch `(v0, ω0)` nearest to the given one that this start allows (the parts it rules out
    /// taken away): the same subspace PA and PGA fit in; a part no value of the start sets is zero (all of
    /// a body at rest's launch).
    pub fn allowed_launch(&self, v: [f64; 3], omega: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let mut u = Unknowns::default();
        u.push_launch(0, *self, true, true);
        let given: Vec<f64> = v.iter().chain(&omega).copied().collect();
        let mut p = vec![0.0; 6];
        u.set(&mut p, &u.values(&given));
        ([p[0], p[1], p[2]], [p[3], p[4], p[5]])
    }
}

/// Pattern steps end when the step has halved this many times without progress.
const PROBE_HALVINGS: i32 = 6;

impl PhysicsFit {
    /// `world` holds the scene, the bodies and the start guess; body `body`'s
    /// initial pose is replaced by `poses[0]` and frames by `poses.len()`.
    pub fn new(
        cfg: PhysicsFitConfig,
        world: World,
        body: usize,
        poses: Vec<Pose<f64>>,
        weights: Option<Vec<f64>>,
    ) -> Result<Self, FitError> {
        Self::new_bodies(cfg, world, vec![Observed::new(body, poses, weights)])
    }

    /// Several bodies of one video at once: each observed body's initial pose is replaced by its first
    /// observed pose; its launch and the contact values against the scene are fitted as the switches say
    /// (one pair of scene values shared by every observed body with `share_scene_contact`), and so are the
    /// values of each pair of observed bodies (`fit_pair_*`). Bodies of the world not observed keep theirs.
    pub fn new_bodies(cfg: PhysicsFitConfig, mut world: World, observed: Vec<Observed>) -> Result<Self, FitError> {
        let frames = observed.first().map_or(0, |o| o.poses.len());
        let mut bodies = Vec::new();
        let mut poses = Vec::new();
        let mut weights = Vec::new();
        let mut starts = Vec::new();
        let mut sights = Vec::new();
        for o in observed {
            if o.body >= world.bodies.len() || bodies.contains(&o.body) {
                return Err(FitError::NoSuchBody(o.body));
            }
            if o.poses.len() < 2 {
                return Err(FitError::TooFewPoses(o.poses.len()));
            }
            if o.poses.len() != frames {
                return Err(FitError::FrameCount {
                    body: o.body,
                    poses: o.poses.len(),
                    first: bodies[0],
                    frames,
                });
            }
            let w = o.weights.unwrap_or_else(|| vec![1.0; frames]);
            if w.len() != frames {
                return Err(FitError::WeightCount {
                    poses: frames,
                    weights: w.len(),
                });
            }
            if !o.depth_held.is_empty() && o.depth_held.len() != frames {
                return Err(FitError::HeldCount {
                    poses: frames,
                    held: o.depth_held.len(),
                });
            }
            if let Some(i) = w.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
                return Err(FitError::BadWeight(i));
            }
            if let Some(i) = o
                .poses
                .iter()
                .position(|p| !(p.t.is_finite() && p.q.to_array().iter().all(|v| v.is_finite())))
            {
                return Err(FitError::BadPose(i));
            }
            world.initial[o.body].pose = Pose::new(o.poses[0].q.normalize_or_identity(), o.poses[0].t);
            // A body at rest has no launch, fitted or held (no value sets it: the launch guess would stay).
            if let StartContact::Rest { .. } = o.start {
                let state = &mut world.initial[o.body];
                (state.v, state.omega) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.0));
            }
            let diameter = 2.0 * world.bodies[o.body].bounding_radius;
            sights.push(
                o.poses
                    .iter()
                    .enumerate()
                    .map(|(k, p)| {
                        let held = o.depth_held.get(k).copied().unwrap_or(false);
                        Sight::of(o.eye.filter(|_| !held), diameter, p.t)
                    })
                    .collect(),
            );
            bodies.push(o.body);
            poses.push(o.poses);
            weights.push(w);
            starts.push(o.start);
        }
        if bodies.is_empty() {
            return Err(FitError::TooFewPoses(0));
        }
        if !(cfg.rotation_weight.is_finite() && cfg.rotation_weight >= 0.0) {
            return Err(FitError::RotationWeight(cfg.rotation_weight));
        }
        world.config.frames = frames;
        let mut unknowns = Unknowns::default();
        let mut contact_values = Vec::new();
        for (&b, &start) in bodies.iter().zip(&starts) {
            let o = world.body_param_offset(b);
            match start {
                // A body at rest stays on the face it rests on (its resting pose levelled and settled on the
                // scene): it may slide along the scene and turn about its normal, as a resting body can be
                // placed. Held entirely, the error of its resting pose went into the body that struck it (the
                // three balls' rolling ball 12 mm off in frame 0); free, it traded a tilt against the frames
                // after it was struck (the two-body video's block: 2.5°, dropped flat in the simulation's
                // first frame).
                StartContact::Rest { normal } if cfg.fit_initial_pose => {
                    let at = world.initial[b].pose.t.to_array();
                    unknowns.push_in_plane_at(o, normal, at, probe_scale(0));
                    unknowns.push_along(o + 3, normal, probe_scale(3));
                }
                _ if cfg.fit_initial_pose => {
                    for k in 0..6 {
                        unknowns.push_param(o + k, probe_scale(k), false);
                    }
                }
                _ => {}
            }
            unknowns.push_launch(o + 6, start, cfg.fit_velocity, cfg.fit_angular_velocity);
        }
        // The scene's values: one per body, or one tied to every body's copy.
        for (k, on) in [(12, cfg.fit_restitution), (13, cfg.fit_friction)] {
            if !on {
                continue;
            }
            let members: Vec<usize> = bodies.iter().map(|&b| world.body_param_offset(b) + k).collect();
            let value = |body: Option<usize>| {
                if k == 12 {
                    ContactValue::SceneRestitution(body)
                } else {
                    ContactValue::SceneFriction(body)
                }
            };
            if cfg.share_scene_contact {
                // Tied values start equal: the first body's.
                let first = world.params()[members[0]];
                let mut p = world.params();
                for &m in &members {
                    p[m] = first;
                }
                world.set_params(&p);
                let terms: Vec<(usize, f64)> = members.iter().map(|&m| (m, 1.0)).collect();
                contact_values.push((unknowns.len(), value(None)));
                unknowns.push(&terms, probe_scale(k), true);
            } else {
                for (&b, m) in bodies.iter().zip(members) {
                    contact_values.push((unknowns.len(), value(Some(b))));
                    unknowns.push_param(m, probe_scale(k), true);
                }
            }
        }
        for (pi, &(i, j)) in world.pairs().iter().enumerate() {
            if !(bodies.contains(&i) && bodies.contains(&j)) {
                continue;
            }
            let o = world.pair_param_offset(pi);
            for (k, on) in [(0, cfg.fit_pair_restitution), (1, cfg.fit_pair_friction)] {
                if on {
                    let value = if k == 0 {
                        ContactValue::PairRestitution(pi)
                    } else {
                        ContactValue::PairFriction(pi)
                    };
                    contact_values.push((unknowns.len(), value));
                    unknowns.push_param(o + k, probe_scale(12 + k), true);
                }
            }
        }
        world.validate().map_err(FitError::World)?;
        if unknowns.is_empty() {
            return Err(FitError::NothingToFit);
        }
        let mut bounds = Bounds::unbounded(unknowns.len());
        for i in 0..unknowns.len() {
            if unknowns.bounded(i) {
                bounds.lo[i] = cfg.bound_margin;
                bounds.hi[i] = 1.0 - cfg.bound_margin;
            }
        }
        // A launch kept in a plane (or a spin on an axis) starts there.
        let mut params = world.params();
        let x = unknowns.values(&params);
        unknowns.set(&mut params, &x);
        let mut fit = Self {
            cfg,
            world,
            bodies,
            poses,
            weights,
            sights,
            frames,
            params,
            unknowns,
            bounds,
            lambda: 1e-3,
            loss: f64::INFINITY,
            iteration: 0,
            converged: false,
            window: 0,
            probe: 1.0,
            contact_values,
        };
        fit.set_window(fit.cfg.initial_window);
        Ok(fit)
    }

    /// Fit frames `0..window` (clamped to the sequence); recomputes the loss.
    fn set_window(&mut self, window: usize) {
        let n = self.frames;
        self.window = if window < 2 { n } else { window.min(n) };
        self.world.config.frames = self.window;
        self.lambda = 1e-3;
        self.probe = 1.0;
        self.loss = self.loss_at(&self.params.clone());
    }

    /// Frames in the current fitting window.
    pub fn window(&self) -> usize {
        self.window
    }

    /// The quaternion error block, with the sign of the observation chosen
    /// to match (q and −q are one rotation).
    fn quat_error(q: Quat<f64>, obs: Quat<f64>) -> [f64; 4] {
        let (a, b) = (q.to_array_re(), obs.to_array_re());
        let s = if a.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>() < 0.0 {
            -1.0
        } else {
            1.0
        };
        std::array::from_fn(|i| a[i] - s * b[i])
    }

    /// The unknowns' current values.
    pub(crate) fn values(&self) -> Vec<f64> {
        self.unknowns.values(&self.params)
    }

    /// The parameters with the unknowns set to `x`.
    fn with_values(&self, x: &[f64]) -> Vec<f64> {
        let mut p = self.params.clone();
        self.unknowns.set(&mut p, x);
        p
    }

    /// The `i`-th observed body's translation error in frame `k` as the loss weighs it ([`Observed::eye`]).
    fn translation_error(&self, i: usize, k: usize, e: Vec3<f64>) -> Vec3<f64> {
        match self.sights[i][k] {
            Some(sight) => sight.apply(e),
            None => e,
        }
    }

    fn loss_at(&self, p: &[f64]) -> f64 {
        self.loss_in(&self.world, p)
    }

    /// Each observed body's errors in each frame `world` simulates with parameters `p`: the frame's weight, its
    /// translation error as the loss weighs it ([`Observed::eye`]) and its rotation error (the quaternion
    /// error's norm times `rotation_weight`). Frame 0 counts too: it is the initial pose, fitted with
    /// `fit_initial_pose` (without it, a constant).
    fn frame_errors(&self, world: &World, p: &[f64]) -> Vec<(f64, f64, f64)> {
        let traj = world.simulate(p);
        let lq = self.cfg.rotation_weight;
        let mut out = Vec::with_capacity(traj.frames.len() * self.bodies.len());
        for (k, f) in traj.frames.iter().enumerate() {
            for (i, &b) in self.bodies.iter().enumerate() {
                let s = f[b];
                let obs = &self.poses[i][k];
                let et = self.translation_error(i, k, s.pose.t - obs.t).norm();
                let eq = Self::quat_error(s.pose.q, obs.q)
                    .iter()
                    .map(|v| v * v)
                    .sum::<f64>()
                    .sqrt()
                    * lq;
                out.push((self.weights[i][k], et, eq));
            }
        }
        out
    }

    /// Eq. 11's loss of parameters `p` over the frames `world` simulates, summed over the observed bodies.
    fn loss_in(&self, world: &World, p: &[f64]) -> f64 {
        self.frame_errors(world, p)
            .iter()
            .map(|&(w, et, eq)| w * (et + eq))
            .sum()
    }

    /// Residual rows (reweighted for L1) and their Jacobian at the current parameters.
    fn linearize(&self) -> Linearization {
        let g = simulate_with_gradients(&self.world, &self.params, self.unknowns.columns());
        let lq = self.cfg.rotation_weight;
        let mut residuals = Vec::new();
        let mut jac = Vec::new();
        for k in 0..g.frames.len() {
            for (i, &b) in self.bodies.iter().enumerate() {
                let s = g.frames[k][b];
                let obs = &self.poses[i][k];
                let et: Vec<f64> = self.translation_error(i, k, s.pose.t - obs.t).to_array().to_vec();
                let eq: Vec<f64> = Self::quat_error(s.pose.q, obs.q).iter().map(|v| v * lq).collect();
                // The translation rows weighed as their errors are (the map is linear).
                let rows: Vec<Vec<f64>> = (0..7).map(|comp| self.unknowns.chain(g.row(k, b, comp))).collect();
                let cols: Vec<[f64; 3]> = (0..rows[0].len())
                    .map(|j| {
                        let col = Vec3::new(rows[0][j], rows[1][j], rows[2][j]);
                        self.translation_error(i, k, col).to_array()
                    })
                    .collect();
                let t_rows: Vec<Vec<f64>> = (0..3).map(|c| cols.iter().map(|col| col[c]).collect()).collect();
                for (block, block_rows, scale) in [(et, &t_rows[..], 1.0), (eq, &rows[3..7], lq)] {
                    let norm = block.iter().map(|v| v * v).sum::<f64>().sqrt();
                    // IRLS: w |e|² / |e| has the gradient of w |e| at this point.
                    let c = (self.weights[i][k] / norm.max(1e-7)).sqrt();
                    for (e, row) in block.iter().zip(block_rows) {
                        residuals.push(c * e);
                        jac.push(row.iter().map(|d| c * scale * d).collect());
                    }
                }
            }
        }
        Linearization { residuals, jac }
    }

    /// One Levenberg–Marquardt iteration (with up to 10 damping increases).
    pub fn step(&mut self) -> FitStats {
        self.iteration += 1;
        if self.converged {
            return self.stats(false);
        }
        let lin = self.linearize();
        for _ in 0..10 {
            let Some(delta) = lm_step(&lin, self.lambda) else {
                self.lambda *= 10.0;
                continue;
            };
            let mut x = self.values();
            for (xi, d) in x.iter_mut().zip(&delta) {
                *xi += d;
            }
            self.bounds.project(&mut x);
            let trial = self.with_values(&x);
            let loss = self.loss_at(&trial);
            if loss < self.loss {
                let gain = (self.loss - loss) / self.loss.max(1e-300);
                self.params = trial;
                self.loss = loss;
                self.lambda = (self.lambda / 3.0).max(1e-12);
                let tolerance = if self.window >= self.frames {
                    self.cfg.tolerance
                } else {
                    self.cfg.window_tolerance
                };
                if gain < tolerance || self.lambda > 1e4 {
                    self.window_done();
                }
                self.converged |= self.iteration >= self.cfg.iterations;
                return self.stats(true);
            }
            self.lambda *= 4.0;
        }
        // No damping gave a lower loss: probe the parameters one by one before giving up on the window.
        let accepted = self.pattern_step();
        if !accepted && self.probe < 0.5f64.powi(PROBE_HALVINGS) {
            self.window_done();
        }
        self.converged |= self.iteration >= self.cfg.iterations;
        self.stats(accepted)
    }

    /// Probe each fitted value at ± its scale × the current step; keep the best if it lowers the loss,
    /// else halve the step.
    fn pattern_step(&mut self) -> bool {
        let mut best: Option<(f64, Vec<f64>)> = None;
        for j in 0..self.unknowns.len() {
            for sign in [-1.0, 1.0] {
                let mut x = self.values();
                x[j] += sign * self.probe * self.unknowns.probe(j);
                self.bounds.project(&mut x);
                let trial = self.with_values(&x);
                let loss = self.loss_at(&trial);
                if loss < best.as_ref().map_or(self.loss, |b| b.0) {
                    best = Some((loss, trial));
                }
            }
        }
        match best {
            Some((loss, p)) => {
                self.params = p;
                self.loss = loss;
                self.lambda = 1e-3;
                true
            }
            None => {
                self.probe *= 0.5;
                false
            }
        }
    }

    /// The fit on the current window has converged: widen it, or finish.
    fn window_done(&mut self) {
        tracing::debug!(
            "physics fit: window of {} of {} frames done at iteration {}, loss {:.4e}, parameters {:?}",
            self.window,
            self.frames,
            self.iteration,
            self.loss,
            self.values()
        );
        if tracing::enabled!(tracing::Level::TRACE) {
            let e: Vec<String> = self
                .pose_errors()
                .iter()
                .map(|e| format!("{:.1}/{:.0}", e.translation * 1e3, e.rotation_deg))
                .collect();
            tracing::trace!("physics fit: per-frame errors (mm/°) {}", e.join(" "));
        }
        if self.window >= self.frames {
            self.converged = true;
        } else {
            self.set_window(2 * self.window);
        }
    }

    fn stats(&self, accepted: bool) -> FitStats {
        FitStats {
            iteration: self.iteration,
            loss: self.loss,
            lambda: self.lambda,
            accepted,
            converged: self.converged,
            window: self.window,
        }
    }

    /// Run `step()` until convergence or the iteration limit; the stats of every step.
    pub fn run(&mut self) -> Vec<FitStats> {
        let mut all = Vec::new();
        while !self.converged && self.iteration < self.cfg.iterations {
            all.push(self.step());
        }
        all
    }

    pub fn loss(&self) -> f64 {
        self.loss
    }

    /// The loss of the current parameters over the whole sequence (whatever the window).
    pub fn full_loss(&self) -> f64 {
        let mut w = self.world.clone();
        w.config.frames = self.frames;
        self.loss_in(&w, &self.params)
    }

    /// The world with the fitted parameters in place, over the whole sequence.
    pub fn fitted_world(&self) -> World {
        let mut w = self.world.clone();
        w.config.frames = self.frames;
        w.set_params(&self.params);
        w
    }

    /// The contact values among the unknowns: `(unknown index, which value)`.
    pub(crate) fn contact_values(&self) -> &[(usize, ContactValue)] {
        &self.contact_values
    }

    /// Whether a contact of the fitted simulation over the whole sequence uses a value: an impulse of an
    /// observed body against the scene (of that body, for a value of one body), or between the pair.
    pub(crate) fn values_in_contact(&self) -> impl Fn(ContactValue) -> bool {
        let contacts = self.fitted_world().simulate(&self.params).contacts;
        let bodies = self.bodies.clone();
        move |value| {
            contacts.iter().any(|c| match value {
                ContactValue::SceneRestitution(None) | ContactValue::SceneFriction(None) => {
                    bodies.iter().any(|&b| c.scene.get(b).copied().unwrap_or(false))
                }
                ContactValue::SceneRestitution(Some(b)) | ContactValue::SceneFriction(Some(b)) => {
                    c.scene.get(b).copied().unwrap_or(false)
                }
                ContactValue::PairRestitution(p) | ContactValue::PairFriction(p) => {
                    c.pairs.get(p).copied().unwrap_or(false)
                }
            })
        }
    }

    /// This fit's values but the `u`-th, refitted for at most `iterations` steps over the whole sequence from
    /// the values `x`, with the `u`-th held at `v`: the loss it ends at and every value (the `u`-th `v`).
    pub(crate) fn refit_holding(&self, u: usize, v: f64, x: &[f64], iterations: usize) -> (f64, Vec<f64>) {
        let mut x = x.to_vec();
        x[u] = v;
        // This fit over the whole sequence, restarted, with one value fewer.
        let mut held = self.clone();
        held.cfg.iterations = iterations;
        held.params = self.with_values(&x);
        held.unknowns = self.unknowns.without(u);
        held.bounds.lo.remove(u);
        held.bounds.hi.remove(u);
        held.contact_values.clear();
        held.iteration = 0;
        held.converged = false;
        held.set_window(0);
        if !held.unknowns.is_empty() && iterations > 0 {
            held.run();
        }
        (held.loss, self.unknowns.values(&held.params))
    }

    /// The weighed squared errors over the current window at the current parameters (each frame's weight
    /// times its translation error, weighed along the line of sight as the loss does, squared, plus its
    /// rotation error's), and their degrees of freedom: 6 per observed body and frame whose pose the fit
    /// can miss (frame 0 only with `fit_initial_pose`: otherwise it is the observation itself).
    pub(crate) fn squares(&self) -> (f64, usize) {
        let errors = self.frame_errors(&self.world, &self.params);
        let sum = errors.iter().map(|&(w, et, eq)| w * (et * et + eq * eq)).sum();
        let first = usize::from(!self.cfg.fit_initial_pose);
        let dof = 6 * self.bodies.len() * self.window.saturating_sub(first);
        (sum, dof)
    }

    /// The number of values this fit moves.
    pub(crate) fn unknown_count(&self) -> usize {
        self.unknowns.len()
    }

    /// The bounds the contact values keep to.
    pub(crate) fn contact_bounds(&self) -> (f64, f64) {
        (self.cfg.bound_margin, 1.0 - self.cfg.bound_margin)
    }

    /// The fit with its parameters replaced by `world`'s (a world from this fit's world, whose values a later
    /// step moved), its initial orientations too: a parameter vector holds each as a turn about the world's
    /// own (none in `world.params()`), and this fit's world took them from the first observed poses, which a
    /// fit of the initial pose leaves (a kept launch simulated from GA's first orientation, a degree off,
    /// missed the poses it was fitted to eight times over after its bounces).
    pub(crate) fn with_params_of(mut self, world: &World) -> Self {
        for (mine, theirs) in self.world.initial.iter_mut().zip(&world.initial) {
            mine.pose.q = theirs.pose.q;
        }
        self.params = world.params();
        self.loss = self.loss_at(&self.params.clone());
        self
    }

    /// The fitted parameters of the first observed body: `[v(3), omega(3), restitution, friction]`.
    pub fn fitted_body_params(&self) -> [f64; 8] {
        let o = self.world.body_param_offset(self.bodies[0]);
        std::array::from_fn(|i| self.params[o + 6 + i])
    }

    /// Per-frame errors of the first observed body's fitted trajectory.
    pub fn pose_errors(&self) -> Vec<PoseError> {
        self.pose_errors_of(0)
    }

    /// Per-frame errors of the `i`-th observed body's fitted trajectory.
    pub fn pose_errors_of(&self, i: usize) -> Vec<PoseError> {
        let mut w = self.world.clone();
        w.config.frames = self.frames;
        let traj = w.simulate(&self.params);
        let b = self.bodies[i];
        traj.frames
            .iter()
            .zip(&self.poses[i])
            .map(|(f, obs)| {
                let s = f[b].pose;
                PoseError {
                    translation: (s.t - obs.t).norm(),
                    rotation_deg: geom::rotation_distance(s.q, obs.q).to_degrees(),
                }
            })
            .collect()
    }
}

/// The contact values a multi-start begins from besides the scene file's guess: restitution × friction on a
/// 3 × 3 grid, from dead to bouncy and from slippery to grippy. The loss over contact-rich frames is rugged
/// (a contact moves by a whole substep, a body tips one way or the other), so one start may end in the
/// wrong basin.
pub const CONTACT_STARTS: [(f64, f64); 9] = [
    (0.15, 0.1),
    (0.15, 0.35),
    (0.15, 0.7),
    (0.45, 0.1),
    (0.45, 0.35),
    (0.45, 0.7),
    (0.75, 0.1),
    (0.75, 0.35),
    (0.75, 0.7),
];

/// One start of [`fit_multi_start`] and where it ended.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct StartResult {
    pub restitution: f64,
    pub friction: f64,
    /// Eq. 11's loss over the whole sequence when its fit stopped.
    pub loss: f64,
    pub iterations: usize,
    /// The values it ended at (the scene's, or the pair's, as the starts set them).
    pub fitted_restitution: f64,
    pub fitted_friction: f64,
}

/// The winner of a multi-start fit.
pub struct MultiStart {
    pub best: PhysicsFit,
    /// Which start won (0: the world's own contact values, then `starts` in order).
    pub winner: usize,
    pub starts: Vec<StartResult>,
    /// Each start's fitted world, in the order of `starts`.
    pub worlds: Vec<World>,
    /// The winner's steps.
    pub history: Vec<FitStats>,
}

/// Which contact values the starts of [`fit_multi_start_bodies`] set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StartsOn {
    /// Every observed body's values against the scene.
    Scene,
    /// The values of pair `p` ([`World::pairs`]).
    Pair(usize),
}

/// A full windowed fit from the world's own contact values and from each `(restitution, friction)` of
/// `starts` (other parameters from the world); the lowest loss over the whole sequence wins (the first of
/// them on a tie). The starts run side by side; `on_start` is told each start's result in start order, as
/// soon as it and the starts before it have ended.
pub fn fit_multi_start(
    cfg: PhysicsFitConfig,
    world: World,
    body: usize,
    poses: Vec<Pose<f64>>,
    weights: Option<Vec<f64>>,
    starts: &[(f64, f64)],
    on_start: &mut dyn FnMut(usize, &StartResult),
) -> Result<MultiStart, FitError> {
    let observed = vec![Observed::new(body, poses, weights)];
    fit_multi_start_bodies(cfg, world, observed, starts, StartsOn::Scene, on_start)
}

/// [`fit_multi_start`] for several bodies: the starts set the values `on` names.
pub fn fit_multi_start_bodies(
    cfg: PhysicsFitConfig,
    world: World,
    observed: Vec<Observed>,
    starts: &[(f64, f64)],
    on: StartsOn,
    on_start: &mut dyn FnMut(usize, &StartResult),
) -> Result<MultiStart, FitError> {
    if let Some(o) = observed.iter().find(|o| o.body >= world.bodies.len()) {
        return Err(FitError::NoSuchBody(o.body));
    }
    let own = match on {
        StartsOn::Scene => world.scene_contact[observed.first().map_or(0, |o| o.body)],
        StartsOn::Pair(p) => *world.pair_contact.get(p).ok_or(FitError::NoSuchPair(p))?,
    };
    let all: Vec<(f64, f64)> = std::iter::once((own.restitution, own.friction))
        .chain(starts.iter().copied())
        .collect();
    let fit_from =
        |&(restitution, friction): &(f64, f64)| -> Result<(PhysicsFit, Vec<FitStats>, StartResult, World), FitError> {
            let mut w = world.clone();
            let c = sim::ContactParams { restitution, friction };
            match on {
                StartsOn::Scene => {
                    for o in &observed {
                        w.scene_contact[o.body] = c;
                    }
                }
                StartsOn::Pair(p) => w.pair_contact[p] = c,
            }
            let mut fit = PhysicsFit::new_bodies(cfg.clone(), w, observed.clone())?;
            let history = fit.run();
            let end = fit.fitted_world();
            let ended = match on {
                StartsOn::Scene => end.scene_contact[observed.first().map_or(0, |o| o.body)],
                StartsOn::Pair(p) => end.pair_contact[p],
            };
            let r = StartResult {
                restitution,
                friction,
                loss: fit.full_loss(),
                iterations: history.len(),
                fitted_restitution: ended.restitution,
                fitted_friction: ended.friction,
            };
            Ok((fit, history, r, end))
        };
    // The starts side by side (each is one thread's work: a simulation with up to 16 derivatives is one
    // dual-number pass) on rayon's global pool, which the calling thread waits for: call this from outside
    // that pool. The winner is the one a loop over them in order would keep (the first of the lowest loss),
    // so the result does not depend on which ends first; a start that fails does not stop the others, and
    // the first failure in start order is returned.
    let (ended_tx, ended_rx) = std::sync::mpsc::channel::<(usize, StartResult)>();
    let ended = std::thread::scope(|s| {
        let all = &all;
        let fit_from = &fit_from;
        let worker = s.spawn(move || {
            all.par_iter()
                .enumerate()
                .map(|(i, start)| {
                    let out = fit_from(start);
                    if let Ok((_, _, r, _)) = &out {
                        // The receiver lives until every start has ended.
                        let _ = ended_tx.send((i, r.clone()));
                    }
                    out
                })
                .collect::<Vec<_>>()
        });
        // Told in start order, each as soon as it and every start before it have ended: the same calls,
        // in the same order, whichever thread ends first (a log of the starts reads the same every run).
        let mut waiting = std::collections::BTreeMap::new();
        let mut next = 0;
        for (i, r) in ended_rx {
            waiting.insert(i, r);
            while let Some(r) = waiting.remove(&next) {
                on_start(next, &r);
                next += 1;
            }
        }
        worker.join().unwrap_or_else(|e| std::panic::resume_unwind(e))
    });
    let mut best: Option<(PhysicsFit, Vec<FitStats>, usize)> = None;
    let mut results = Vec::new();
    let mut worlds = Vec::new();
    for (i, out) in ended.into_iter().enumerate() {
        let (fit, history, r, end) = out?;
        worlds.push(end);
        if best.as_ref().is_none_or(|(b, _, _)| r.loss < b.full_loss()) {
            best = Some((fit, history, i));
        }
        results.push(r);
    }
    let (best, history, winner) = best.expect("at least the world's own start");
    Ok(MultiStart {
        best,
        winner,
        starts: results,
        worlds,
        history,
    })
}
