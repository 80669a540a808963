//! Target reaching (Sec. 4.1, Fig. 7): the initial velocity (and optionally
//! angular velocity) that brings a body's centre to a point at a given frame.
//!
//! A fan of launch velocities gives a global start; then each iteration takes
//! a Levenberg–Marquardt step through the differentiable simulator, or, where
//! contacts make the loss too rugged for the gradient, a pattern-search step.

use crate::least_squares::{lm_step, Linearization};
use geom::Vec3;
use serde::{Deserialize, Serialize};
use sim::{simulate_with_gradients, World};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TargetConfig {
    /// Maximum iterations. Default 50.
    pub iterations: usize,
    /// Also optimise omega0. Default false.
    pub fit_angular_velocity: bool,
    /// Stop once the centre is this close to the target, m. Default 1e-4.
    pub tolerance: f64,
    /// Before the gradient steps, try a fan of launch velocities towards the
    /// target (elevations 0–80°, speeds 0.2–8 m/s, three headings) with plain
    /// forward runs and start from the best, if it beats the given v0. A body
    /// that slides into an obstacle gets no gradient telling it to jump, so
    /// gradient steps alone stall at the obstacle. Default true.
    pub global_start: bool,
}

impl Default for TargetConfig {
    fn default() -> Self {
        Self {
            iterations: 50,
            fit_angular_velocity: false,
            tolerance: 1e-4,
            global_start: true,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetStats {
    pub iteration: usize,
    /// Distance from the centre at the target frame to the target, m.
    pub distance: f64,
    pub lambda: f64,
    pub converged: bool,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TargetError {
    #[error("body index {0} is out of range")]
    NoSuchBody(usize),
    #[error("target frame {frame} is outside 1..{frames}")]
    Frame { frame: usize, frames: usize },
    #[error("the target point has NaN or infinite values")]
    BadPoint,
}

pub struct TargetReach {
    cfg: TargetConfig,
    world: World,
    body: usize,
    point: Vec3<f64>,
    frame: usize,
    params: Vec<f64>,
    wrt: Vec<usize>,
    lambda: f64,
    distance: f64,
    iteration: usize,
    converged: bool,
    /// Step of the pattern search used when gradient steps fail, m/s or rad/s.
    probe: f64,
}

impl TargetReach {
    /// `world.config.frames` is raised to `frame + 1` if needed.
    pub fn new(
        cfg: TargetConfig,
        mut world: World,
        body: usize,
        point: Vec3<f64>,
        frame: usize,
    ) -> Result<Self, TargetError> {
        if body >= world.bodies.len() {
            return Err(TargetError::NoSuchBody(body));
        }
        if !point.is_finite() {
            return Err(TargetError::BadPoint);
        }
        if frame == 0 {
            return Err(TargetError::Frame {
                frame,
                frames: world.config.frames,
            });
        }
        world.config.frames = world.config.frames.max(frame + 1);
        let o = world.body_param_offset(body);
        let mut wrt: Vec<usize> = (o + 6..o + 9).collect();
        if cfg.fit_angular_velocity {
            wrt.extend(o + 9..o + 12);
        }
        let params = world.params();
        let mut t = Self {
            cfg,
            world,
            body,
            point,
            frame,
            params,
            wrt,
            lambda: 1e-2,
            distance: f64::INFINITY,
            iteration: 0,
            converged: false,
            probe: 0.05,
        };
        t.distance = t.distance_at(&t.params.clone());
        if t.cfg.global_start {
            t.global_start();
        }
        Ok(t)
    }

    /// Launch velocities to try: headings around the direction to the target,
    /// elevations and speeds on a grid.
    fn launch_candidates(&self) -> Vec<Vec3<f64>> {
        let start = self.world.initial[self.body].pose.t;
        let to = self.point - start;
        let heading = to.y.atan2(to.x);
        let mut out = Vec::new();
        for dh in [-0.2f64, 0.0, 0.2] {
            for e in 0..9 {
                let elev = (e as f64 * 10.0).to_radians();
                for k in 0..12 {
                    let speed = 0.2 * (40.0f64).powf(k as f64 / 11.0);
                    let h = heading + dh;
                    out.push(Vec3::new(h.cos() * elev.cos(), h.sin() * elev.cos(), elev.sin()) * speed);
                }
            }
        }
        out
    }

    /// Replace v0 by the best launch candidate when it is closer than the start.
    fn global_start(&mut self) {
        let o = self.world.body_param_offset(self.body);
        for v in self.launch_candidates() {
            let mut p = self.params.clone();
            p[o + 6..o + 9].copy_from_slice(&v.to_array());
            let d = self.distance_at(&p);
            if d < self.distance {
                self.distance = d;
                self.params = p;
            }
        }
    }

    fn distance_at(&self, p: &[f64]) -> f64 {
        let traj = self.world.simulate(p);
        (traj.frames[self.frame][self.body].pose.t - self.point).norm()
    }

    pub fn step(&mut self) -> TargetStats {
        self.iteration += 1;
        if self.converged || self.distance <= self.cfg.tolerance {
            self.converged = true;
            return self.stats();
        }
        let before = self.distance;
        self.gradient_step();
        if self.distance > 0.9 * before {
            self.lambda = 1e-2;
            self.pattern_step();
        }
        self.converged |= self.distance <= self.cfg.tolerance || self.iteration >= self.cfg.iterations;
        self.stats()
    }

    /// One Levenberg–Marquardt step (up to 12 damping increases).
    fn gradient_step(&mut self) {
        let g = simulate_with_gradients(&self.world, &self.params, &self.wrt);
        let t = g.frames[self.frame][self.body].pose.t;
        let lin = Linearization {
            residuals: (t - self.point).to_array().to_vec(),
            jac: (0..3).map(|c| g.row(self.frame, self.body, c).to_vec()).collect(),
        };
        for _ in 0..12 {
            if let Some(delta) = lm_step(&lin, self.lambda) {
                let mut trial = self.params.clone();
                for (&i, d) in self.wrt.iter().zip(&delta) {
                    trial[i] += d;
                }
                let dist = self.distance_at(&trial);
                if dist < self.distance {
                    self.params = trial;
                    self.distance = dist;
                    self.lambda = (self.lambda / 3.0).max(1e-9);
                    return;
                }
            }
            self.lambda *= 4.0;
        }
    }

    /// Where contacts make the path rugged (a landing, a slide to rest), the
    /// local gradient may not point downhill at any step length: probe ± the
    /// step along each parameter, keep the best, halve the step on failure.
    fn pattern_step(&mut self) {
        let mut best: Option<(f64, Vec<f64>)> = None;
        for &i in &self.wrt {
            for sign in [-1.0, 1.0] {
                let mut trial = self.params.clone();
                trial[i] += sign * self.probe;
                let d = self.distance_at(&trial);
                if d < best.as_ref().map_or(self.distance, |b| b.0) {
                    best = Some((d, trial));
                }
            }
        }
        match best {
            Some((d, p)) => {
                self.distance = d;
                self.params = p;
            }
            None => {
                self.probe *= 0.5;
                if self.probe < 1e-7 {
                    self.converged = true;
                }
            }
        }
    }

    fn stats(&self) -> TargetStats {
        TargetStats {
            iteration: self.iteration,
            distance: self.distance,
            lambda: self.lambda,
            converged: self.converged,
        }
    }

    pub fn run(&mut self) -> Vec<TargetStats> {
        let mut all = Vec::new();
        while !self.converged && self.iteration < self.cfg.iterations {
            all.push(self.step());
        }
        all
    }

    pub fn distance(&self) -> f64 {
        self.distance
    }

    /// The world with the found initial velocities.
    pub fn solved_world(&self) -> World {
        let mut w = self.world.clone();
        w.set_params(&self.params);
        w
    }
}
