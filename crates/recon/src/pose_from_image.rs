//! A body's pose from one frame of a fixed camera: Adam steps on the pose
//! tangent down the gradient of the image terms ([`crate::image_loss`]), each
//! on a random batch of the pixels around the mask and around where the body
//! projects now, plus (GA, Eq. 9–10) the contact penalty of the frame
//! ([`crate::contact_penalty`]) when one is given; without it, the first-pose
//! stage of `fit`. A pose tangent needs no norm penalty on the quaternion.

use crate::contact_penalty::ContactTerm;
use crate::image_loss::{FrameError, FrameTarget, ImageLoss, ImageLossWeights, Occluder, PreparedFrame};
use crate::shutter::Motion;
use geom::{Pose, Quat, SplitMix64, Vec3};
use neus::compose::{ComposedRay, PooledComposer};
use neus::ObjectModel;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PoseFitConfig {
    /// Adam steps. Default 150.
    pub iterations: usize,
    /// Pixels rendered per step. Default 1024.
    pub rays_per_step: usize,
    /// Adam step of the translation at the start, m (decays tenfold over the iterations). Default 0.003.
    pub lr_translation: f64,
    /// Adam step of the rotation at the start, rad. Default 0.03.
    pub lr_rotation: f64,
    pub weights: ImageLossWeights,
    pub seed: u64,
}

impl Default for PoseFitConfig {
    fn default() -> Self {
        Self {
            iterations: 150,
            rays_per_step: 1024,
            lr_translation: 0.003,
            lr_rotation: 0.03,
            weights: ImageLossWeights::default(),
            seed: 0,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PoseFitError {
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error("the body's mask is empty")]
    EmptyMask,
}

/// Adam on a pose tangent `(δt, δω)`, its step decaying tenfold over `iterations`.
pub(crate) struct PoseAdam {
    m: [f64; 6],
    v: [f64; 6],
    steps: usize,
}

impl PoseAdam {
    pub fn new() -> Self {
        Self {
            m: [0.0; 6],
            v: [0.0; 6],
            steps: 0,
        }
    }

    /// `pose` moved one step down `grad` (`[dL/dδt, dL/dδω]`).
    pub fn step(&mut self, pose: &Pose<f64>, grad: [f64; 6], lr: (f64, f64), iterations: usize) -> Pose<f64> {
        self.steps += 1;
        let (b1, b2, eps) = (0.9, 0.999, 1e-12);
        let decay = 0.1f64.powf(self.steps as f64 / iterations.max(1) as f64);
        let mut delta = [0.0; 6];
        for k in 0..6 {
            self.m[k] = b1 * self.m[k] + (1.0 - b1) * grad[k];
            self.v[k] = b2 * self.v[k] + (1.0 - b2) * grad[k] * grad[k];
            let m = self.m[k] / (1.0 - b1.powi(self.steps as i32));
            let v = self.v[k] / (1.0 - b2.powi(self.steps as i32));
            let lr = if k < 3 { lr.0 } else { lr.1 };
            delta[k] = -lr * decay * m / (v.sqrt() + eps);
        }
        let dt = Vec3::new(delta[0], delta[1], delta[2]);
        let dw = Vec3::new(delta[3], delta[4], delta[5]);
        Pose::new((Quat::exp(dw) * pose.q).normalize_or_identity(), pose.t + dt)
    }
}

/// The pose of one body from one frame, by gradient steps ([`Self::step`]).
pub struct PoseFromImage<'a> {
    cfg: PoseFitConfig,
    object: &'a ObjectModel,
    scene: &'a [ComposedRay],
    frame: PreparedFrame<'a>,
    pub pose: Pose<f64>,
    adam: PoseAdam,
    iteration: usize,
    composer: PooledComposer,
    rng: SplitMix64,
    contact: Option<ContactTerm<'a>>,
}

impl<'a> PoseFromImage<'a> {
    /// `scene`: the scene pre-rendered through `frame.camera` ([`neus::compose::prerender_scene`]).
    pub fn new(
        cfg: PoseFitConfig,
        object: &'a ObjectModel,
        scene: &'a [ComposedRay],
        frame: &'a FrameTarget,
        start: Pose<f64>,
    ) -> Result<Self, PoseFitError> {
        let frame = PreparedFrame::new(frame, scene)?;
        if !frame.has_mask() {
            return Err(PoseFitError::EmptyMask);
        }
        let rng = SplitMix64::new(cfg.seed);
        Ok(Self {
            cfg,
            object,
            scene,
            frame,
            pose: start,
            adam: PoseAdam::new(),
            iteration: 0,
            composer: PooledComposer::take(),
            rng,
            contact: None,
        })
    }

    /// The other bodies of the frame, drawn where they stand (several bodies in the video).
    pub fn with_occluders(mut self, occluders: Vec<Occluder<'a>>) -> Self {
        self.frame.set_occluders(occluders);
        self
    }

    /// The body's velocity at the frame's instant (`None`: drawn at its instant), for a frame with a shutter
    /// time ([`PreparedFrame::set_motion`]).
    pub fn with_motion(mut self, motion: Option<Motion>) -> Self {
        self.frame.set_motion(motion);
        self
    }

    /// Add the frame's contact penalty (GA).
    pub fn with_contact(mut self, term: ContactTerm<'a>) -> Self {
        self.contact = Some(term);
        self
    }

    /// The contact penalty at the current pose (0 without one).
    pub fn contact_penalty(&self) -> f64 {
        self.contact.as_ref().map_or(0.0, |c| c.evaluate(&self.pose).0)
    }

    /// One Adam step on a random batch of the window's pixels; the batch's loss before the step.
    pub fn step(&mut self) -> ImageLoss {
        let c = &self.cfg;
        let window = self
            .frame
            .window(self.object, &self.pose, c.weights.margin_px)
            .expect("the mask is in the image");
        let pixels = self.frame.pixels(window, c.rays_per_step.max(1), &mut self.rng);
        let (loss, mut g) = self.frame.loss(
            &mut self.composer,
            self.object,
            self.scene,
            &self.pose,
            &pixels,
            &c.weights,
            true,
        );
        if let Some(c) = &self.contact {
            let (_, gc) = c.evaluate(&self.pose);
            for (a, b) in g.iter_mut().zip(gc) {
                *a += b;
            }
        }
        self.iteration += 1;
        self.pose = self
            .adam
            .step(&self.pose, g, (c.lr_translation, c.lr_rotation), c.iterations);
        loss
    }

    /// Run the configured number of steps; the loss of each.
    pub fn run(&mut self) -> Vec<ImageLoss> {
        (0..self.cfg.iterations).map(|_| self.step()).collect()
    }

    /// The pixels this fit renders around the mask and the body at its current pose, `[x0, y0, x1, y1]`.
    pub fn window(&self) -> Option<[u32; 4]> {
        self.frame.window(self.object, &self.pose, self.cfg.weights.margin_px)
    }

    /// The image terms (no gradient) at the current pose on `count` random pixels of `window` drawn with
    /// `seed`: fits of one frame from other starts scored on the same pixels are compared fairly.
    pub fn score(&mut self, window: [u32; 4], count: usize, seed: u64) -> ImageLoss {
        let pixels = self.frame.pixels(window, count, &mut SplitMix64::new(seed));
        self.frame
            .loss(
                &mut self.composer,
                self.object,
                self.scene,
                &self.pose,
                &pixels,
                &self.cfg.weights,
                false,
            )
            .0
    }

    /// The frame's brightness relative to the object's captures, measured at the current pose over every
    /// pixel of the mask (the gain [`ImageLossWeights::exposure_gain`] fits; 1 where none is rendered).
    pub fn measure_exposure(&mut self) -> f64 {
        self.evaluate().measured_exposure()
    }

    /// The image terms over every pixel around the mask and the body at the current pose.
    pub fn evaluate(&mut self) -> ImageLoss {
        self.frame.evaluate(
            &mut self.composer,
            self.object,
            self.scene,
            &self.pose,
            &self.cfg.weights,
        )
    }
}
