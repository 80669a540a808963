//! GA (Eq. 9–10): every frame's pose from the images, with the contact
//! penalty in the frames where PA's simulation touched the scene (the points
//! it had within the contact threshold there). Frame k starts from PA's pose
//! of frame k moved by the correction GA made to frame k − 1 (PA's errors
//! grow smoothly along the video, so the last correction is the best guess of
//! the next; from PA's pose alone, a launch 15 % slow left the last frames
//! 2–4 cm away, too far for small steps). One frame per
//! [`PosesFromVideo::step`]; frames whose mask is empty keep their start and
//! say so.

use crate::contact_penalty::{ContactPenaltyConfig, ContactTerm};
use crate::image_loss::{FrameTarget, ImageLoss};
use crate::pose_from_image::{PoseFitConfig, PoseFitError, PoseFromImage};
use geom::Pose;
use neus::compose::ComposedRay;
use neus::ObjectModel;
use serde::{Deserialize, Serialize};
use sim::{points_near_scene, Trajectory, World};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PosesFromVideoConfig {
    /// The per-frame pose fit (its iterations are per frame). Default: 80 steps of 1,024 pixels, starting
    /// at 1 mm and 0.01 rad (PA's poses are near: Adam's first steps are full steps whatever the gradient,
    /// and the first pose's 3 mm knocked an exact start 2 mm off).
    pub pose: PoseFitConfig,
    pub contact: ContactPenaltyConfig,
    /// At most this many of PA's contact points per frame (the deepest). Default 16.
    pub contact_points: usize,
}

impl Default for PosesFromVideoConfig {
    fn default() -> Self {
        Self {
            pose: PoseFitConfig {
                iterations: 80,
                lr_translation: 0.001,
                lr_rotation: 0.01,
                ..PoseFitConfig::default()
            },
            contact: ContactPenaltyConfig::default(),
            contact_points: 16,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PosesFromVideoError {
    #[error("{frames} frames but PA's trajectory has {trajectory}")]
    FrameCount { frames: usize, trajectory: usize },
    #[error("body index {0} is out of range")]
    NoSuchBody(usize),
    #[error("frame {frame}: {error}")]
    Frame { frame: usize, error: PoseFitError },
}

/// One frame's outcome.
#[derive(Clone, Debug)]
pub struct FramePose {
    pub pose: Pose<f64>,
    /// The image terms over the window at the final pose.
    pub image: ImageLoss,
    pub contact_penalty: f64,
    /// Whether PA's simulation touched the scene in this frame (the penalty applied).
    pub in_contact: bool,
    /// False when the frame's mask was empty: the pose is PA's.
    pub fitted: bool,
}

/// The stage.
pub struct PosesFromVideo<'a> {
    cfg: PosesFromVideoConfig,
    object: &'a ObjectModel,
    scene: &'a [ComposedRay],
    frames: &'a [FrameTarget],
    world: &'a World,
    body: usize,
    starts: Vec<Pose<f64>>,
    contacts: Vec<Vec<usize>>,
    /// Without PA: starts carried on at the pace of the last two fitted frames.
    tracking: bool,
    pub results: Vec<FramePose>,
}

/// The pose after `b` at the pace from `a` to `b` (constant velocity and spin).
pub fn carried_on(a: &Pose<f64>, b: &Pose<f64>) -> Pose<f64> {
    Pose::new((b.q * a.q.conj() * b.q).normalize_or_identity(), b.t + (b.t - a.t))
}

impl<'a> PosesFromVideo<'a> {
    /// `world`: the scene's collision shape and the bodies (as PA simulated them); `pa`: PA's trajectory,
    /// one state per frame.
    pub fn new(
        cfg: PosesFromVideoConfig,
        object: &'a ObjectModel,
        scene: &'a [ComposedRay],
        frames: &'a [FrameTarget],
        world: &'a World,
        body: usize,
        pa: &Trajectory<f64>,
    ) -> Result<Self, PosesFromVideoError> {
        if body >= world.bodies.len() {
            return Err(PosesFromVideoError::NoSuchBody(body));
        }
        if pa.frames.len() != frames.len() {
            return Err(PosesFromVideoError::FrameCount {
                frames: frames.len(),
                trajectory: pa.frames.len(),
            });
        }
        let starts: Vec<Pose<f64>> = pa.frames.iter().map(|f| f[body].pose).collect();
        let contacts = starts
            .iter()
            .enumerate()
            .map(|(k, pose)| {
                let touched = pa.contacts[k].scene.get(body).copied().unwrap_or(false);
                if !touched {
                    return Vec::new();
                }
                points_near_scene(&world.bodies[body], pose, &world.scene, world.config.contact_threshold)
                    .into_iter()
                    .take(cfg.contact_points)
                    .map(|p| p.index)
                    .collect()
            })
            .collect();
        Ok(Self {
            cfg,
            object,
            scene,
            frames,
            world,
            body,
            starts,
            contacts,
            tracking: false,
            results: Vec::new(),
        })
    }

    /// Without PA (the paper's `--no-pa` ablation): frame 0 starts from `first`, every later frame from the
    /// previous frames' fitted poses carried on at their pace, and no frame has a contact penalty.
    pub fn tracking(
        cfg: PosesFromVideoConfig,
        object: &'a ObjectModel,
        scene: &'a [ComposedRay],
        frames: &'a [FrameTarget],
        world: &'a World,
        body: usize,
        first: Pose<f64>,
    ) -> Result<Self, PosesFromVideoError> {
        if body >= world.bodies.len() {
            return Err(PosesFromVideoError::NoSuchBody(body));
        }
        // Equal starts: the carried correction of frame k − 1 is then its fitted pose itself.
        Ok(Self {
            cfg,
            object,
            scene,
            frames,
            world,
            body,
            starts: vec![first; frames.len()],
            contacts: vec![Vec::new(); frames.len()],
            tracking: true,
            results: Vec::new(),
        })
    }

    /// Whether every frame is done.
    pub fn done(&self) -> bool {
        self.results.len() == self.frames.len()
    }

    /// Fit the next frame; its outcome (`None` once every frame is done).
    pub fn step(&mut self) -> Result<Option<&FramePose>, PosesFromVideoError> {
        let k = self.results.len();
        if k == self.frames.len() {
            return Ok(None);
        }
        let start = match self.results.last() {
            Some(prev) if self.tracking && k >= 2 => carried_on(&self.results[k - 2].pose, &prev.pose),
            // The previous frame's correction: p_GA = R_c p_PA + … , carried over.
            Some(prev) => {
                let before = self.starts[k - 1];
                let turn = prev.pose.q * before.q.conj();
                Pose::new(
                    (turn * self.starts[k].q).normalize_or_identity(),
                    self.starts[k].t + (prev.pose.t - before.t),
                )
            }
            None => self.starts[k],
        };
        let start = self.frames[k].centred_on_mask(&start);
        let in_contact = !self.contacts[k].is_empty();
        let cfg = PoseFitConfig {
            seed: self.cfg.pose.seed.wrapping_add(k as u64),
            ..self.cfg.pose.clone()
        };
        let fit = PoseFromImage::new(cfg, self.object, self.scene, &self.frames[k], start);
        let result = match fit {
            Err(PoseFitError::EmptyMask) => FramePose {
                pose: start,
                image: ImageLoss::default(),
                contact_penalty: 0.0,
                in_contact,
                fitted: false,
            },
            Err(error) => return Err(PosesFromVideoError::Frame { frame: k, error }),
            Ok(fit) => {
                let mut fit = if in_contact {
                    fit.with_contact(ContactTerm {
                        body: &self.world.bodies[self.body],
                        scene: &self.world.scene,
                        points: self.contacts[k].clone(),
                        cfg: self.cfg.contact.clone(),
                    })
                } else {
                    fit
                };
                fit.run();
                FramePose {
                    pose: fit.pose,
                    image: fit.evaluate(),
                    contact_penalty: fit.contact_penalty(),
                    in_contact,
                    fitted: true,
                }
            }
        };
        self.results.push(result);
        Ok(self.results.last())
    }

    /// Fit every frame left; all outcomes.
    pub fn run(&mut self) -> Result<&[FramePose], PosesFromVideoError> {
        while !self.done() {
            self.step()?;
        }
        Ok(&self.results)
    }
}
