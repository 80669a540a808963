//! GA (Eq. 9–10): every frame's pose from the images, with the contact
//! penalty in the frames where PA's simulated body is on the scene when the
//! frame is taken (the points it had within the contact threshold there);
//! elsewhere a body near the scene is only kept from sinking into it, unless
//! the fitted frames around it touch it too (a contact that lasts). Frame k
//! starts from PA's pose
//! of frame k moved by the correction GA made to frame k − 1 (PA's errors
//! grow smoothly along the video, so the last correction is the best guess of
//! the next; from PA's pose alone, a launch 15 % slow left the last frames
//! 2–4 cm away, too far for small steps). Where PA lost the body, frames also
//! start from the images' own track (the last frames carried on, or moved on
//! by the simulator) and from PA's start slid along the line of sight to where
//! the body's silhouette has the mask's area, and a pass back over the video refits the frames
//! explained worst from the frames after them. Where the last frame is
//! explained far worse than the best ones (a tumble lost on the way leaves the
//! body at rest on the wrong face), it is searched afresh, as `--init auto`
//! searches the first, and the pass back then goes over every frame from there
//! while the frames carried back explain them better. Last, the frames still
//! explained worst are fitted on from their own poses (a start far off runs
//! out of steps). A frame after two in which the body stayed still keeps the
//! last fitted pose where that pose explains it as well (a body at rest).
//! One frame per [`PosesFromVideo::step`]; frames whose mask is empty keep
//! their start and say so.

use crate::contact_penalty::{contact_sides, faces, ContactPenaltyConfig, ContactTerm};
use crate::first_pose_search::{search_first_pose, FirstPoseSearchConfig};
use crate::image_loss::{window_union, FrameTarget, ImageLoss, ImageLossWeights, Occluder};
use crate::image_precision::ImagePrecision;
use crate::pose_from_image::{PoseFitConfig, PoseFitError, PoseFromImage};
use crate::shutter::Motion;
use geom::{Pose, Vec3};
use neus::compose::ComposedRay;
use neus::ObjectModel;
use serde::{Deserialize, Serialize};
use sim::{points_near_scene, BodyState, NearPoint, Trajectory, World};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PosesFromVideoConfig {
    /// The per-frame pose fit (its iterations are per frame). Default: 80 steps of 1,024 pixels, starting
    /// at 1 mm and 0.01 rad (PA's poses are near: Adam's first steps are full steps whatever the gradient,
    /// and the first pose's 3 mm knocked an exact start 2 mm off), with the chromaticity term weighed 5: a
    /// body turning in the video shows its faces to the light at angles the static captures did not (the
    /// tabletop drop's tumble: from 4–12° off in frames 5–8 to within 1°, the colour alone equal at the
    /// true pose and GA's).
    pub pose: PoseFitConfig,
    pub contact: ContactPenaltyConfig,
    /// At most this many of PA's contact points per frame (the deepest). Default 16.
    pub contact_points: usize,
    /// Besides PA's pose, start each frame from the previous fitted frames too: carried on at their pace,
    /// and moved one frame on by the simulator from the last one (a bounce). Where they differ from PA's
    /// start, each is fitted for a share of the steps, scored on the same pixels, and the best goes on.
    /// PA's start alone follows PA's simulation where it lost the body (a tumbling landing: 90° off for
    /// the rest of the video); the others follow the images. Default true.
    pub hypotheses: bool,
    /// The share of the steps each start gets before the best is chosen. Default 0.3.
    pub screen_fraction: f64,
    /// Starts that are not a trusted PA pose (from the previous frames, or PA's where it lost the body) take
    /// steps up to this many times larger, in proportion to how fast the body moved over the last frame
    /// (full at 15° or 15 mm): a tumbling body turns 15–30° a frame and its next pose is a rough guess,
    /// while from 40 steps of 0.01 rad decaying tenfold a fit moves at most about 9° (80: 18°); a body at rest keeps
    /// GA's small steps (with large ones its resting pose wandered by 5–10°). Default 3.
    pub wide_step_scale: f64,
    /// After the forward pass, where the last frame is explained this many times worse than the frames
    /// explained best (its image loss against the lowest tenth of the frames'), the last frame is searched
    /// afresh as `fit --init auto` searches the first ([`Self::end_search`]), and if the pose found explains
    /// it better, the pass back goes over every frame from there while the frames carried back win: a
    /// tumble lost on the way leaves the body at rest on the wrong face for the rest of the video (the
    /// tabletop drop Rapier made: 0.165 at rest against 0.023 in flight), and at rest the search finds it.
    /// With `hypotheses`. 0: never. Default 2.
    pub end_search_ratio: f64,
    /// The search of the last frame. Default: `--init auto`'s.
    pub end_search: FirstPoseSearchConfig,
    /// Last, every frame still explained this many times worse than the median frame (its image loss) is
    /// fitted on from its own pose, with the steps of a start again, and kept if it explains the frame
    /// better: a frame started far off can run out of steps before it converges (80 steps of 0.01 rad
    /// decaying tenfold move a pose about 18°, 40 about 9°, and a tumble turns 15–30° a frame; with `fit`'s
    /// former 40 steps the demo drop's frame 11 ended 6.5° off, its image loss twice the true pose's). With
    /// `hypotheses`. 0: never. Default 1.5 (the pass back's).
    pub continue_ratio: f64,
    /// Then, every frame held on the scene by the contact penalty that is still explained this many times
    /// worse than the median frame is fitted once more without the penalty, from its own pose and from the
    /// two frames before carried on, each kept where it explains the frame by a tenth (`SWITCH_MARGIN`) better
    /// than the pose it would replace (the start `unheld`): the penalty reads the reconstructed scene, and where that scene is wrong
    /// near the body (a concave foot of a wall rounded into a fillet 10–15 mm wide, as NeuS rounds the
    /// corners it sees at grazing angles), it holds the body off its true pose. The margin keeps the
    /// penalty where the images cannot tell (a drift along the line of sight changes the loss little).
    /// 0: never. Default 2.
    pub unheld_ratio: f64,
    /// A frame after two in which the body stayed still ([`crate::rest::is_still`]) keeps the last fitted
    /// frame's pose, without fitting, where that pose explains it within [`STILL_LOSS_SLACK`] of how it
    /// explained its own frame (its image loss over the window): a body at rest shows the same image
    /// again, and fitting it anew (80 steps from each start) took most of GA's time in a video that ends
    /// at rest (the tabletop drop: 34 of 48 frames). The start `still` in the results. Default true.
    pub keep_still: bool,
}

impl Default for PosesFromVideoConfig {
    fn default() -> Self {
        Self {
            pose: PoseFitConfig {
                iterations: 80,
                lr_translation: 0.001,
                lr_rotation: 0.01,
                weights: ImageLossWeights {
                    chromaticity: 5.0,
                    ..ImageLossWeights::default()
                },
                ..PoseFitConfig::default()
            },
            contact: ContactPenaltyConfig::default(),
            contact_points: 16,
            hypotheses: true,
            screen_fraction: 0.3,
            wide_step_scale: 3.0,
            end_search_ratio: 2.0,
            end_search: FirstPoseSearchConfig::default(),
            continue_ratio: BACKWARD_LOSS_RATIO,
            unheld_ratio: 2.0,
            keep_still: true,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PosesFromVideoError {
    #[error("{frames} frames but PA's trajectory has {trajectory}")]
    FrameCount { frames: usize, trajectory: usize },
    #[error("{frames} frames but {results} fitted poses given")]
    ResultCount { frames: usize, results: usize },
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
    /// Whether the body was held in contact with the scene: the penalty kept it from floating as well as
    /// from sinking, where the contact is known (PA's body on the scene when the frame is taken, or the
    /// fitted frames around it touching it); a body near the scene is always kept from sinking into it.
    pub in_contact: bool,
    /// False when the frame's mask was empty: the pose is PA's.
    pub fitted: bool,
    /// Where the fit that won started.
    pub start: StartFrom,
}

/// The median image loss of the `(loss, fitted)` frames that were fitted (the upper one of an even count);
/// `None` without any.
pub fn median_fitted_loss(frames: impl Iterator<Item = (f64, bool)>) -> Option<f64> {
    let mut losses: Vec<f64> = frames.filter(|&(_, fitted)| fitted).map(|(l, _)| l).collect();
    losses.sort_by(f64::total_cmp);
    losses.get(losses.len() / 2).copied()
}

/// The lowest tenth of the image losses of the `(loss, fitted)` frames that were fitted: how well the
/// video's best frames are explained (what noise, JPEG, blur and the reconstruction's own errors leave where
/// the pose is right); `None` without any.
pub fn lowest_tenth_fitted_loss(frames: impl Iterator<Item = (f64, bool)>) -> Option<f64> {
    let mut losses: Vec<f64> = frames.filter(|&(_, fitted)| fitted).map(|(l, _)| l).collect();
    losses.sort_by(f64::total_cmp);
    losses.get(losses.len().saturating_sub(1) / 10).copied()
}

/// Where a frame's pose fit started.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StartFrom {
    /// PA's pose moved by the previous frame's correction (or, tracking, the previous frames carried on).
    Physics,
    /// The previous fitted frames carried on at their pace.
    Tracked,
    /// The last fitted frame moved one frame on by the simulator, at the pace of the last two.
    Simulated,
    /// PA's start slid along the line of sight to where the body's silhouette has the mask's area.
    Sized,
    /// The pass back over the video: the next two fitted frames carried back at their pace.
    Backward,
    /// The last frame searched afresh ([`PosesFromVideoConfig::end_search`]).
    Searched,
    /// The frame's own fitted pose, fitted on ([`PosesFromVideoConfig::continue_ratio`]).
    Continued,
    /// Not fitted again: the body was still and the last fitted frame's pose explains this frame as well
    /// ([`PosesFromVideoConfig::keep_still`]).
    Still,
    /// PGA's simulation, after GA ([`PosesFromVideo::refit_worst_from_physics`]).
    Pga,
    /// The last pass, without the contact penalty ([`PosesFromVideoConfig::unheld_ratio`]).
    Unheld,
}

impl StartFrom {
    pub fn name(self) -> &'static str {
        match self {
            StartFrom::Physics => "physics",
            StartFrom::Tracked => "tracked",
            StartFrom::Simulated => "simulated",
            StartFrom::Sized => "sized",
            StartFrom::Backward => "backward",
            StartFrom::Searched => "searched",
            StartFrom::Continued => "continued",
            StartFrom::Still => "still",
            StartFrom::Pga => "pga",
            StartFrom::Unheld => "unheld",
        }
    }
}

/// A start for one frame's fit and the contact points its penalty holds.
struct Start {
    pose: Pose<f64>,
    contacts: Vec<usize>,
    /// The sides of the scene (its normals there, [`contact_sides`]) the contact is known on, empty where
    /// none is: PA's simulated body is on the scene at this frame's time near this pose, a tracked body
    /// holds the board, or the fitted frames around this one touch it ([`PosesFromVideo::sides_held_between`]:
    /// the two before it, or one on each side in the pass back). The penalty then keeps the body from
    /// floating off each of those sides as well as from sinking. Points that merely lie near the
    /// scene at a guessed start only keep it from sinking: a body bouncing off the board between two frames
    /// is near it at a guess carried on from the fall, and holding it there put the tabletop drop's frame
    /// after a bounce 10 mm off along the line of sight, where the image tells depth least.
    held: Vec<Vec3<f64>>,
    from: StartFrom,
    /// Far from a converged PA's pose: larger steps.
    wide: bool,
}

impl Start {
    /// Whether the body is held on the scene from this start (a known contact and points to hold).
    fn held(&self) -> bool {
        !self.held.is_empty() && !self.contacts.is_empty()
    }
}

/// The contact penalty of a refit ([`PosesFromVideo::replace_if_better_with`]).
enum Penalty {
    /// The points near the scene at the start kept from sinking, and held on these sides of it.
    Held(Vec<Vec3<f64>>),
    /// None: the images alone.
    None,
}

/// Starts closer than this (m, rad) to an earlier one are not fitted again.
const SAME_START: (f64, f64) = (0.0015, 0.035);
/// Whether two starts are close enough that the second need not be fitted ([`SAME_START`]).
fn same_start(a: &Pose<f64>, b: &Pose<f64>) -> bool {
    (a.t - b.t).norm() <= SAME_START.0 && geom::rotation_distance(a.q, b.q) <= SAME_START.1
}

/// How fast the body moved from `a` to `b` (one frame apart), 0–1: full at 15° or 15 mm.
fn pace(a: &Pose<f64>, b: &Pose<f64>) -> f64 {
    let turn = geom::rotation_distance(a.q, b.q) / 15f64.to_radians();
    turn.max((b.t - a.t).norm() / 0.015).min(1.0)
}

/// PA's touching points hold in a frame whose start is within this (m, rad) of PA's pose: a body's size
/// and a turn that keeps the same face down.
const PA_TRUSTED: (f64, f64) = (0.02, 0.26);
/// The pass back revisits frames whose image loss is over this many times the median frame's.
const BACKWARD_LOSS_RATIO: f64 = 1.5;
/// Another start replaces PA's only with a score this much lower (a share of PA's score).
const SWITCH_MARGIN: f64 = 0.1;
/// A still frame keeps the last fitted pose where that pose's image loss on it is within this share of the
/// loss on its own frame ([`PosesFromVideoConfig::keep_still`]). The loss is steep in the pose: moved
/// 0.1 px (0.25 mm), a 15-pixel block's rose by a quarter; two frames of a scene at rest differ by their
/// noise only. So a kept frame's pose is within a few hundredths of a pixel of the one a fit would find
/// there, finer than GA's own fits place the tabletop toy (0.04–0.15 px across the line of sight).
pub const STILL_LOSS_SLACK: f64 = 0.05;
/// A start (or, in the sizing pass, a fitted pose) whose silhouette's area is off the mask's by more than
/// this share gets a sized twin ([`StartFrom::Sized`]): 3 % of the area is 1.5 % of the depth (6 mm for the
/// tabletop toy at 0.41 m). A twin that is only the noise of a mask's border pixels or of a reconstructed
/// shape costs a fit and loses the comparison.
const SIZE_TOLERANCE: f64 = 0.03;
/// The pass back after a searched last frame stops after this many frames in a row that the frames carried
/// back did not explain better: the forward pass had them right (or the chain lost the body).
const CHAIN_MISSES: usize = 2;

/// The stage.
pub struct PosesFromVideo<'a> {
    cfg: PosesFromVideoConfig,
    object: &'a ObjectModel,
    scene: &'a [ComposedRay],
    frames: &'a [FrameTarget],
    world: &'a World,
    body: usize,
    starts: Vec<Pose<f64>>,
    /// PA's velocity in each frame: a frame with a shutter time draws the body over it (none when tracking).
    pa_motion: Vec<Option<Motion>>,
    /// PA's touching points in each frame, and the sides of the scene they touch (empty where PA's body is
    /// off the scene).
    contacts: Vec<Vec<usize>>,
    pa_sides: Vec<Vec<Vec3<f64>>>,
    /// Without PA: starts carried on at the pace of the last two fitted frames.
    tracking: bool,
    /// Tracking: the penalty holds the points touching the scene at each frame's start ([`Self::holding_contacts`]).
    hold_touching: bool,
    pub results: Vec<FramePose>,
    /// The pass back over the video (with `hypotheses`): the frames left to revisit, last first.
    backward: Vec<usize>,
    /// The last frame is still to be checked ([`PosesFromVideoConfig::end_search_ratio`]).
    end_pending: bool,
    /// The sizing pass is still to be planned (after the pass back).
    sizing_pending: bool,
    /// The sizing pass: the frames left whose fitted silhouette's area is off the mask's, last first, each
    /// with its pose slid to the mask's size.
    sizing: Vec<(usize, Pose<f64>)>,
    /// The last pass is still to be planned (after the sizing pass).
    continuing_pending: bool,
    /// The last pass: the frames left that are still explained poorly, to be fitted on from their own pose,
    /// last first ([`PosesFromVideoConfig::continue_ratio`]).
    continuing: Vec<usize>,
    /// The pass back follows the searched last frame: every frame is revisited while the frames carried
    /// back win; this counts the ones in a row that did not (at [`CHAIN_MISSES`] the chain ends).
    chain: Option<usize>,
    /// The video's other bodies in each frame ([`Self::set_occluders`]).
    occluders: Vec<Vec<Occluder<'a>>>,
}

/// The sides of the scene a body touches, from all its points (nearest first, [`PosesFromVideo::points`]):
/// none when the nearest is farther than `threshold`, else those of the points within
/// [`crate::clearance::TOUCHING`] of the nearest. A body on the board beside a wall a few millimetres off
/// touches the board only; one floating a little over the board still has that side.
fn sides_touched(points: &[NearPoint<f64>], threshold: f64) -> Vec<Vec3<f64>> {
    let Some(first) = points.first().filter(|p| p.distance <= threshold) else {
        return Vec::new();
    };
    let within = (first.distance + crate::clearance::TOUCHING).min(threshold);
    contact_sides(points.iter().take_while(|p| p.distance <= within).map(|p| p.gradient))
}

/// Points on each side a body touching the scene's sides needs at least this many of its own in the penalty.
const POINTS_PER_SIDE: usize = 4;

/// The points the penalty holds, from all the body's points (nearest first): the `count` nearest within
/// `threshold`, and on each of `sides` that none of them faces, the nearest few facing it
/// ([`POINTS_PER_SIDE`], however far: a body pressed into a wall has its nearest points all on the wall,
/// and a start carried back from frames that floated may be more than the threshold over the board).
fn pick_points(points: &[NearPoint<f64>], threshold: f64, sides: &[Vec3<f64>], count: usize) -> Vec<usize> {
    let near = points.iter().take_while(|p| p.distance <= threshold).count();
    let mut picked: Vec<usize> = (0..near.min(count)).collect();
    for &side in sides {
        if !picked.iter().any(|&i| faces(points[i].gradient, side)) {
            let facing = (0..points.len()).filter(|&i| faces(points[i].gradient, side));
            picked.extend(facing.take(POINTS_PER_SIDE));
        }
    }
    picked.into_iter().map(|i| points[i].index).collect()
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
        let pa_motion = pa.frames.iter().map(|f| Some(Motion::from(&f[body]))).collect();
        // PA's contact holds a frame where PA's body is on the scene at the frame's own time. Not every frame
        // PA flags: a frame is flagged for any contact since the one before, and after a bounce, which lasts a
        // substep, the body is off the scene again when the frame is taken.
        let (contacts, pa_sides) = starts
            .iter()
            .enumerate()
            .map(|(k, pose)| {
                let touched = pa.contacts[k].scene.get(body).copied().unwrap_or(false);
                if !touched {
                    return (Vec::new(), Vec::new());
                }
                let points = points_near_scene(&world.bodies[body], pose, &world.scene, f64::INFINITY);
                if points.first().is_none_or(|p| p.distance > crate::clearance::TOUCHING) {
                    return (Vec::new(), Vec::new());
                }
                let threshold = world.config.contact_threshold;
                let sides = sides_touched(&points, threshold);
                (pick_points(&points, threshold, &sides, cfg.contact_points), sides)
            })
            .unzip();
        Ok(Self {
            cfg,
            object,
            scene,
            frames,
            world,
            body,
            starts,
            pa_motion,
            contacts,
            pa_sides,
            tracking: false,
            hold_touching: false,
            results: Vec::new(),
            backward: Vec::new(),
            end_pending: false,
            sizing_pending: false,
            sizing: Vec::new(),
            continuing_pending: false,
            continuing: Vec::new(),
            chain: None,
            occluders: vec![Vec::new(); frames.len()],
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
            pa_motion: vec![None; frames.len()],
            contacts: vec![Vec::new(); frames.len()],
            pa_sides: vec![Vec::new(); frames.len()],
            tracking: true,
            hold_touching: false,
            results: Vec::new(),
            backward: Vec::new(),
            end_pending: false,
            sizing_pending: false,
            sizing: Vec::new(),
            continuing_pending: false,
            continuing: Vec::new(),
            chain: None,
            occluders: vec![Vec::new(); frames.len()],
        })
    }

    /// Tracking with the contact penalty on the points that touch the scene at each frame's start (the
    /// previous frames carried on): a body resting or rolling on the board stays on it instead of drifting
    /// along the line of sight, where a small silhouette tells depth least (a ball tracked without it sank
    /// 14 mm into the board in ten frames). Geometry, not physics: no simulation is consulted.
    pub fn holding_contacts(mut self) -> Self {
        self.hold_touching = true;
        self
    }

    /// The video's other bodies in frame `k`, where they stand (their fitted or best-guessed poses): drawn in
    /// front of or behind this body as the frame shows them. Set before the frame is fitted.
    pub fn set_occluders(&mut self, k: usize, occluders: Vec<Occluder<'a>>) {
        if let Some(o) = self.occluders.get_mut(k) {
            *o = occluders;
        }
    }

    /// The body's velocity at frame `k` for a frame with a shutter time: PA's (the simulation's at that instant);
    /// when tracking, the pace of the two fitted frames before it (none before two).
    fn motion_at(&self, k: usize) -> Option<Motion> {
        if !self.tracking {
            return self.pa_motion.get(k).copied().flatten();
        }
        let (a, b) = (self.results.get(k.checked_sub(2)?)?, self.results.get(k - 1)?);
        (a.fitted && b.fitted).then(|| Motion::between(&a.pose, &b.pose, 1.0 / self.world.config.fps))
    }

    /// The pose frame `k` starts from before it is fitted (the physics start); its fitted pose once it is.
    pub fn current_pose(&self, k: usize) -> Pose<f64> {
        match self.results.get(k) {
            Some(r) => r.pose,
            None if k == self.results.len() => self.starts_of(k)[0].pose,
            None => self.starts[k],
        }
    }

    /// Whether every frame is done (and, with `hypotheses`, the end check, the pass back, the sizing pass and
    /// the last pass).
    pub fn done(&self) -> bool {
        self.results.len() == self.frames.len()
            && self.backward.is_empty()
            && !self.end_pending
            && !self.sizing_pending
            && self.sizing.is_empty()
            && !self.continuing_pending
            && self.continuing.is_empty()
    }

    /// Steps left: frames to fit, then frames to revisit (a bound for progress bars).
    pub fn steps_left(&self) -> usize {
        let left = self.frames.len() - self.results.len();
        // Before the end check the pass back is not planned yet: at most every frame but the last.
        let back = if self.cfg.hypotheses && !self.tracking && (left > 0 || self.end_pending) {
            self.frames.len().saturating_sub(1)
        } else {
            self.backward.len()
        };
        // The end check, the sizing pass and the last pass (at most every frame each) once the forward pass
        // is done.
        let after = if self.cfg.hypotheses && !self.tracking && left > 0 {
            1 + 2 * self.frames.len()
        } else {
            let planned = |pending: bool, left: usize| if pending { self.frames.len() } else { left };
            usize::from(self.end_pending)
                + planned(self.sizing_pending, self.sizing.len())
                + planned(self.continuing_pending, self.continuing.len())
        };
        left + back + after
    }

    /// The fitted frames whose image loss is over `ratio` times the median fitted frame's, in order.
    fn explained_worse_than(&self, ratio: f64) -> Vec<usize> {
        let Some(median) = median_fitted_loss(self.results.iter().map(|r| (r.image.loss, r.fitted))) else {
            return Vec::new();
        };
        (0..self.results.len())
            .filter(|&k| self.results[k].fitted && self.results[k].image.loss > ratio * median)
            .collect()
    }

    /// The fitted frames still explained [`PosesFromVideoConfig::continue_ratio`] times worse than the median
    /// frame, in order (none when it is 0): the last pass's and the refit's from PGA's simulation. A still
    /// frame explained as well as its anchor explains its own follows the anchor; one explained worse (an
    /// offer it turned down, a creep `is_still` let pass) is fitted.
    fn poorly_explained(&self) -> Vec<usize> {
        if self.cfg.continue_ratio <= 0.0 {
            return Vec::new();
        }
        self.explained_worse_than(self.cfg.continue_ratio)
            .into_iter()
            .filter(|&k| !self.follows_its_anchor(k))
            .collect()
    }

    /// The frames the pass back revisits, last first: fitted, with an image loss over
    /// [`BACKWARD_LOSS_RATIO`] times the median fitted frame's (a bounce the forward starts missed), and the
    /// next frame fitted (the start is carried back from it).
    fn frames_to_revisit(&self) -> Vec<usize> {
        let n = self.results.len();
        self.explained_worse_than(BACKWARD_LOSS_RATIO)
            .into_iter()
            .filter(|&k| k + 1 < n && self.results[k + 1].fitted)
            .collect()
    }

    /// Frame `k` fitted on from its own pose (the last pass), its steps scaled by the pace between it and the
    /// frames beside it; held where it was, on the sides its pose touches. Whether it explains the frame
    /// better.
    fn continue_fit(&mut self, k: usize) -> Result<bool, PosesFromVideoError> {
        let pose = self.results[k].pose;
        let held = self.sides_held_at(k);
        let scale = self.step_scale(self.pace_around(k));
        self.replace_if_better(k, pose, scale, held, StartFrom::Continued, 0.0)
    }

    /// The pace between fitted frame `k` and the fitted frames beside it, the faster.
    fn pace_around(&self, k: usize) -> f64 {
        let pose = self.results[k].pose;
        let fitted = |j: usize| self.results.get(j).filter(|r| r.fitted).map(|r| r.pose);
        let before = k.checked_sub(1).and_then(fitted).map_or(0.0, |p| pace(&p, &pose));
        let after = fitted(k + 1).map_or(0.0, |p| pace(&pose, &p));
        before.max(after)
    }

    /// Whether fitted frame `k` was held on the scene and is explained
    /// [`PosesFromVideoConfig::unheld_ratio`] times worse than the median frame.
    fn held_and_poorly_explained(&self, k: usize) -> bool {
        self.cfg.unheld_ratio > 0.0
            && self.results[k].in_contact
            && self.explained_worse_than(self.cfg.unheld_ratio).contains(&k)
    }

    /// Frame `k` fitted without the contact penalty from its own pose and from the two frames before it
    /// carried on ([`PosesFromVideoConfig::unheld_ratio`]); each kept where it explains the frame by
    /// [`SWITCH_MARGIN`] better than the pose it would replace.
    fn fit_unheld(&mut self, k: usize) -> Result<(), PosesFromVideoError> {
        let mut starts = vec![self.results[k].pose];
        if k >= 2 && self.results[k - 2].fitted && self.results[k - 1].fitted {
            let carried = carried_on(&self.results[k - 2].pose, &self.results[k - 1].pose);
            starts.push(self.frames[k].centred_on_mask(&carried));
        }
        for start in starts {
            let scale = self.step_scale(pace(&self.results[k].pose, &start).max(self.pace_around(k)));
            // `replace_if_better_with` logs the two losses.
            self.replace_if_better_with(k, start, scale, Penalty::None, StartFrom::Unheld, SWITCH_MARGIN)?;
        }
        Ok(())
    }

    /// Frame `k` fitted again from the next two frames carried back; kept if it explains the image better.
    /// Whether it was.
    fn revisit(&mut self, k: usize) -> Result<bool, PosesFromVideoError> {
        let n = self.results.len();
        let next = self.results[k + 1].pose;
        let start = if k + 2 < n && self.results[k + 2].fitted {
            carried_on(&self.results[k + 2].pose, &next)
        } else {
            next
        };
        let start = self.frames[k].centred_on_mask(&start);
        if same_start(&start, &self.results[k].pose) {
            return Ok(false);
        }
        let after = if k + 2 < n { self.results[k + 2].pose } else { next };
        let scale = self.step_scale(pace(&next, &after));
        let held = if k > 0 {
            self.sides_held_between(k - 1, k + 1)
        } else {
            Vec::new()
        };
        self.replace_if_better(k, start, scale, held, StartFrom::Backward, 0.0)
    }

    /// Frame `k` fitted from `start` (steps scaled by `scale`; the contact held on the sides `held`) and scored
    /// against its current pose on the same pixels: it replaces it if its loss is lower by `margin` (a share
    /// of the current one's). Whether it did.
    fn replace_if_better(
        &mut self,
        k: usize,
        start: Pose<f64>,
        scale: f64,
        held: Vec<Vec3<f64>>,
        from: StartFrom,
        margin: f64,
    ) -> Result<bool, PosesFromVideoError> {
        self.replace_if_better_with(k, start, scale, Penalty::Held(held), from, margin)
    }

    /// [`Self::replace_if_better`] with the contact penalty `penalty`.
    fn replace_if_better_with(
        &mut self,
        k: usize,
        start: Pose<f64>,
        scale: f64,
        penalty: Penalty,
        from: StartFrom,
        margin: f64,
    ) -> Result<bool, PosesFromVideoError> {
        let n = self.results.len();
        let cfg = PoseFitConfig {
            seed: self.cfg.pose.seed.wrapping_add((n + k) as u64),
            lr_translation: self.cfg.pose.lr_translation * scale,
            lr_rotation: self.cfg.pose.lr_rotation * scale,
            ..self.cfg.pose.clone()
        };
        let frame = &self.frames[k];
        let (contacts, held) = match penalty {
            Penalty::Held(held) => (self.touching(&start, &held), held),
            Penalty::None => (Vec::new(), Vec::new()),
        };
        let holds = !held.is_empty();
        let new = PoseFromImage::new(cfg.clone(), self.object, self.scene, frame, start)
            .map_err(|error| PosesFromVideoError::Frame { frame: k, error })?
            .with_occluders(self.occluders[k].clone())
            .with_motion(self.motion_at(k));
        let mut new = if contacts.is_empty() {
            new
        } else {
            new.with_contact(self.contact_term(k, &start, contacts.clone(), held.clone()))
        };
        new.run();
        let mut old = PoseFromImage::new(cfg.clone(), self.object, self.scene, frame, self.results[k].pose)
            .map_err(|error| PosesFromVideoError::Frame { frame: k, error })?
            .with_occluders(self.occluders[k].clone())
            .with_motion(self.motion_at(k));
        let window = match (new.window(), old.window()) {
            (Some(a), Some(b)) => window_union(a, b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => return Ok(false),
        };
        let seed = cfg.seed ^ 0x9e37_79b9_7f4a_7c15;
        let count = cfg.rays_per_step.max(256) * 2;
        let (ours, theirs) = (new.score(window, count, seed).loss, old.score(window, count, seed).loss);
        tracing::debug!("frame {k}: from {from:?} {ours:.4} against {theirs:.4}");
        if ours >= theirs * (1.0 - margin) {
            return Ok(false);
        }
        self.results[k] = FramePose {
            pose: new.pose,
            image: new.evaluate(),
            contact_penalty: new.contact_penalty(),
            in_contact: holds && !contacts.is_empty(),
            fitted: true,
            start: from,
        };
        self.offer_to_still_frames_after(k)?;
        Ok(true)
    }

    /// The still frames right after frame `k` ([`StartFrom::Still`]: kept at its pose in the forward pass) take
    /// its new pose where it explains them at least as well, whichever pass replaced it: a body at rest shows
    /// the same image again, so the sizing and last passes do not refit them one by one.
    fn offer_to_still_frames_after(&mut self, k: usize) -> Result<(), PosesFromVideoError> {
        let anchor = self.results[k].clone();
        for j in k + 1..self.results.len() {
            if self.results[j].start != StartFrom::Still {
                break;
            }
            let mut at = PoseFromImage::new(
                self.cfg.pose.clone(),
                self.object,
                self.scene,
                &self.frames[j],
                anchor.pose,
            )
            .map_err(|error| PosesFromVideoError::Frame { frame: j, error })?
            .with_occluders(self.occluders[j].clone())
            .with_motion(self.motion_at(j));
            let image = at.evaluate();
            if image.loss <= self.results[j].image.loss {
                self.results[j] = FramePose {
                    image,
                    start: StartFrom::Still,
                    ..anchor.clone()
                };
            }
        }
        Ok(())
    }

    /// Whether the last frame is explained [`PosesFromVideoConfig::end_search_ratio`] times worse than the
    /// fitted frames' lowest tenth.
    fn last_frame_lost(&self) -> bool {
        let Some(last) = self.results.last().filter(|r| r.fitted) else {
            return false;
        };
        // The lowest tenth: where a tumble was lost early, most frames after it are as poorly explained as
        // the last (the drop Rapier made: 40 of 48).
        let reference = lowest_tenth_fitted_loss(self.results.iter().map(|r| (r.image.loss, r.fitted)))
            .expect("the last frame is fitted");
        self.cfg.end_search_ratio > 0.0 && last.image.loss > self.cfg.end_search_ratio * reference
    }

    /// The check of the last frame after the forward pass: searched afresh where it is explained poorly, the
    /// pose found kept if it explains it clearly better, and then the pass back chained from it; else the
    /// pass back over the frames explained worst.
    fn check_last_frame(&mut self) -> Result<(), PosesFromVideoError> {
        self.end_pending = false;
        let k = self.results.len() - 1;
        if k >= 2 && self.last_frame_lost() {
            let frame = &self.frames[k];
            let body = &self.world.bodies[self.body];
            let found = search_first_pose(
                body,
                &self.world.scene,
                self.object,
                self.scene,
                frame,
                &self.cfg.end_search,
                || {},
            );
            match found {
                Ok((pose, _)) => {
                    let held = self.sides_held_between(k - 2, k - 1);
                    tracing::debug!(
                        "frame {k}: explained poorly ({:.4}); searched afresh",
                        self.results[k].image.loss
                    );
                    if self.replace_if_better(k, pose, 1.0, held, StartFrom::Searched, SWITCH_MARGIN)? {
                        // Popped from the end: every fitted frame before the last whose next frame is fitted
                        // too (the start is carried back from it), the last but one first.
                        self.backward = (0..k)
                            .filter(|&i| self.results[i].fitted && self.results[i + 1].fitted)
                            .collect();
                        self.chain = Some(0);
                        return Ok(());
                    }
                }
                Err(PoseFitError::EmptyMask) => {}
                Err(error) => return Err(PosesFromVideoError::Frame { frame: k, error }),
            }
        }
        self.backward = self.frames_to_revisit();
        Ok(())
    }

    /// The sides of the scene that fitted frames `a` and `b` both have the body touching (`b`'s normals;
    /// empty where there are none): a contact that lasted over a frame (resting, sliding, rolling) is taken
    /// to go on in the frames between and after them, where a bounce lasts less than a frame. Without it the
    /// tabletop drop's rolling frame 12 floated 7.6 mm toward the camera. Touching is within the simulator's
    /// contact threshold (5 mm by default), as the points the penalty holds are chosen: GA's frames kept only
    /// from sinking may sit a few millimetres off ([`sides_touched`]).
    fn sides_held_between(&self, a: usize, b: usize) -> Vec<Vec3<f64>> {
        let sides = |k: usize| match self.results.get(k) {
            Some(r) if r.fitted => self.sides_at(&r.pose),
            _ => Vec::new(),
        };
        let before = sides(a);
        sides(b)
            .into_iter()
            .filter(|&s| before.iter().any(|&t| faces(t, s)))
            .collect()
    }

    /// Frame `k`'s contact penalty for a fit started at `start`: `points` held on the scene's `held` sides
    /// (whole where the contact is known, [`Start::holds`]; else without its floating term, the body only
    /// kept from sinking), with the slack of the frame's image at `start`.
    fn contact_term(&self, k: usize, start: &Pose<f64>, points: Vec<usize>, held: Vec<Vec3<f64>>) -> ContactTerm<'a> {
        let body = &self.world.bodies[self.body];
        ContactTerm {
            body,
            scene: &self.world.scene,
            points,
            cfg: ContactPenaltyConfig {
                lambda_out: if held.is_empty() {
                    0.0
                } else {
                    self.cfg.contact.lambda_out
                },
                ..self.cfg.contact.clone()
            },
            sides: held,
            seen: Some(ImagePrecision::of(
                &self.frames[k].camera,
                start,
                2.0 * body.bounding_radius,
            )),
        }
    }

    /// Every contact point of the body with its distance to the scene at `pose`, nearest first.
    fn points(&self, pose: &Pose<f64>) -> Vec<NearPoint<f64>> {
        let w = self.world;
        points_near_scene(&w.bodies[self.body], pose, &w.scene, f64::INFINITY)
    }

    /// Where fitted frame `k`'s body was held on the scene: the sides its pose touches (the sizing and the
    /// last pass refit it held where it was); none where it was not held.
    fn sides_held_at(&self, k: usize) -> Vec<Vec3<f64>> {
        let r = &self.results[k];
        if r.in_contact {
            self.sides_at(&r.pose)
        } else {
            Vec::new()
        }
    }

    /// The sides of the scene the body touches at `pose` ([`sides_touched`]).
    fn sides_at(&self, pose: &Pose<f64>) -> Vec<Vec3<f64>> {
        sides_touched(&self.points(pose), self.world.config.contact_threshold)
    }

    /// The contact points of the body near the scene at `pose` (the penalty of a start that is not PA's),
    /// with points on each side in `held` ([`pick_points`]).
    fn touching(&self, pose: &Pose<f64>, held: &[Vec3<f64>]) -> Vec<usize> {
        pick_points(
            &self.points(pose),
            self.world.config.contact_threshold,
            held,
            self.cfg.contact_points,
        )
    }

    /// The starts of frame `k`: PA's (or, tracking, the carried-on one) first, then with `hypotheses` the
    /// ones from the previous fitted frames that differ from it.
    fn starts_of(&self, k: usize) -> Vec<Start> {
        let frame = &self.frames[k];
        let physics = match self.results.last() {
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
        let physics = frame.centred_on_mask(&physics);
        // PA's touching points name points of the body: where the images put the body far from PA's pose
        // (PA lost it: a tumble that went another way), they are the wrong points, and the penalty would pin
        // a wrong face to the board; the points touching at the start are used instead.
        let pa = &self.starts[k];
        let trusted = self.tracking
            || ((physics.t - pa.t).norm() <= PA_TRUSTED.0 && geom::rotation_distance(physics.q, pa.q) <= PA_TRUSTED.1);
        let holding = self.tracking && self.hold_touching;
        let pa_holds = !self.tracking && trusted && !self.contacts[k].is_empty();
        // Tracking without holding (the paper's `--no-pa`): no penalty at all.
        let penalised = !self.tracking || holding;
        // A contact that lasted over the two fitted frames before (the same for every start of this frame).
        let lasting = if penalised && k >= 2 {
            self.sides_held_between(k - 2, k - 1)
        } else {
            Vec::new()
        };
        let mut held = lasting.clone();
        if pa_holds {
            held.extend(&self.pa_sides[k]);
        }
        if holding {
            held.extend(self.sides_at(&physics));
        }
        let held = contact_sides(held);
        let contacts = if pa_holds {
            // PA's points, and points on the sides held that PA's body does not touch (a wall the images put
            // the body against).
            let mut points = self.contacts[k].clone();
            let missing: Vec<Vec3<f64>> = held
                .iter()
                .copied()
                .filter(|&s| !self.pa_sides[k].iter().any(|&t| faces(t, s)))
                .collect();
            let threshold = self.world.config.contact_threshold;
            for i in pick_points(&self.points(&physics), threshold, &missing, 0) {
                if !points.contains(&i) {
                    points.push(i);
                }
            }
            points
        } else if penalised {
            self.touching(&physics, &held)
        } else {
            Vec::new()
        };
        let mut out = vec![Start {
            pose: physics,
            contacts,
            held,
            from: StartFrom::Physics,
            wide: !trusted,
        }];
        if !self.cfg.hypotheses || self.tracking || k < 2 {
            return out;
        }
        let (a, b) = (&self.results[k - 2], &self.results[k - 1]);
        if !(a.fitted && b.fitted) {
            return out;
        }
        let add = |pose: Pose<f64>, from: StartFrom, out: &mut Vec<Start>| {
            let pose = frame.centred_on_mask(&pose);
            if !out.iter().any(|s| same_start(&s.pose, &pose)) {
                out.push(Start {
                    contacts: self.touching(&pose, &lasting),
                    held: lasting.clone(),
                    pose,
                    from,
                    wide: true,
                });
            }
        };
        add(carried_on(&a.pose, &b.pose), StartFrom::Tracked, &mut out);
        add(self.one_frame_on(&a.pose, &b.pose), StartFrom::Simulated, &mut out);
        // A start at the wrong depth with the right turn fits to a silhouette of the wrong size, which the
        // image terms barely pull on along the line of sight (the drop Rapier made: its landing frame 19 mm
        // too far, IoU 0.94).
        if let Some(sized) = frame.sized_to_mask(&self.world.bodies[self.body].mesh, &out[0].pose, SIZE_TOLERANCE) {
            add(sized, StartFrom::Sized, &mut out);
        }
        out
    }

    /// Fitted frame `k`'s pose slid along the line of sight to the mask's size, where its silhouette's area
    /// is off by more than [`SIZE_TOLERANCE`] (the sizing pass: a pose that fitted its silhouette at the
    /// wrong depth, which the image terms hardly pull on).
    fn sized_start(&self, k: usize) -> Option<Pose<f64>> {
        let r = self.results.get(k).filter(|r| r.fitted)?;
        self.frames[k].sized_to_mask(&self.world.bodies[self.body].mesh, &r.pose, SIZE_TOLERANCE)
    }

    /// The step scale of a wide start in frame `k`: 1 for a body that stood still over the last fitted
    /// frames, up to `wide_step_scale` for one that turned 15° or moved 15 mm.
    fn wide_scale(&self, k: usize) -> f64 {
        let p = match k {
            0 | 1 => 1.0,
            _ => pace(&self.results[k - 2].pose, &self.results[k - 1].pose),
        };
        self.step_scale(p)
    }

    /// The step scale at pace `p` (0–1).
    fn step_scale(&self, p: f64) -> f64 {
        1.0 + (self.cfg.wide_step_scale - 1.0).max(0.0) * p
    }

    /// The body at `b` moved one frame on by the simulator (PA's contact values), at the pace from `a` to
    /// `b` (one frame apart): the mid-frame velocity plus half a frame of gravity, the mean turn rate.
    fn one_frame_on(&self, a: &Pose<f64>, b: &Pose<f64>) -> Pose<f64> {
        let mut w = self.world.clone();
        let fps = w.config.fps;
        let dt = 1.0 / fps;
        let g = Vec3::cst(w.config.gravity);
        let v = (b.t - a.t) * fps + g * (0.5 * dt);
        let omega = (b.q * a.q.conj()).normalize_or_identity().log() * fps;
        w.config.frames = 2;
        w.initial[self.body] = BodyState::new(b.t.to_array(), b.q.to_array_re(), v.to_array(), omega.to_array());
        let traj = w.simulate(&w.params());
        traj.frames[1][self.body].pose
    }

    /// Fit the next frame; its outcome (`None` once every frame is done).
    pub fn step(&mut self) -> Result<Option<&FramePose>, PosesFromVideoError> {
        let k = self.results.len();
        if k == self.frames.len() {
            if self.end_pending {
                self.check_last_frame()?;
                return Ok(self.results.last());
            }
            return match self.backward.pop() {
                Some(j) => {
                    let replaced = self.revisit(j)?;
                    if let Some(misses) = self.chain {
                        let misses = if replaced { 0 } else { misses + 1 };
                        self.chain = Some(misses);
                        if misses >= CHAIN_MISSES {
                            // The chain ends: the frames before it as the pass back takes any video.
                            self.chain = None;
                            self.backward = self.frames_to_revisit().into_iter().filter(|&i| i < j).collect();
                        }
                    }
                    Ok(Some(&self.results[j]))
                }
                None => {
                    self.chain = None;
                    // Still frames follow their anchor ([`Self::offer_to_still_frames_after`]) in this pass and
                    // the next, instead of being refitted one by one: the image of a body at rest is the same.
                    if std::mem::take(&mut self.sizing_pending) {
                        self.sizing = (0..k)
                            .filter(|&j| !self.follows_its_anchor(j))
                            .filter_map(|j| self.sized_start(j).map(|p| (j, p)))
                            .collect();
                    }
                    if let Some((j, start)) = self.sizing.pop() {
                        let held = self.sides_held_at(j);
                        self.replace_if_better(j, start, 1.0, held, StartFrom::Sized, 0.0)?;
                        return Ok(Some(&self.results[j]));
                    }
                    if std::mem::take(&mut self.continuing_pending) {
                        self.continuing = self.poorly_explained();
                    }
                    match self.continuing.pop() {
                        Some(j) => {
                            self.continue_fit(j)?;
                            if self.held_and_poorly_explained(j) {
                                self.fit_unheld(j)?;
                            }
                            Ok(Some(&self.results[j]))
                        }
                        None => Ok(None),
                    }
                }
            };
        }
        if let Some(kept) = self.kept_still(k)? {
            self.push(kept);
            return Ok(self.results.last());
        }
        let starts = self.starts_of(k);
        let cfg = PoseFitConfig {
            seed: self.cfg.pose.seed.wrapping_add(k as u64),
            ..self.cfg.pose.clone()
        };
        let mut fits = Vec::with_capacity(starts.len());
        for s in &starts {
            let scale = if s.wide { self.wide_scale(k) } else { 1.0 };
            let cfg_s = PoseFitConfig {
                lr_translation: cfg.lr_translation * scale,
                lr_rotation: cfg.lr_rotation * scale,
                ..cfg.clone()
            };
            let fit = match PoseFromImage::new(cfg_s, self.object, self.scene, &self.frames[k], s.pose) {
                Err(PoseFitError::EmptyMask) => {
                    let first = &starts[0];
                    let unfitted = FramePose {
                        pose: first.pose,
                        image: ImageLoss::default(),
                        contact_penalty: 0.0,
                        in_contact: first.held(),
                        fitted: false,
                        start: first.from,
                    };
                    self.push(unfitted);
                    return Ok(self.results.last());
                }
                Err(error) => return Err(PosesFromVideoError::Frame { frame: k, error }),
                Ok(fit) => fit
                    .with_occluders(self.occluders[k].clone())
                    .with_motion(self.motion_at(k)),
            };
            fits.push(if s.contacts.is_empty() {
                fit
            } else {
                fit.with_contact(self.contact_term(k, &s.pose, s.contacts.clone(), s.held.clone()))
            });
        }
        let mut best = 0;
        if fits.len() > 1 {
            // Each start a share of the steps, then all scored on the same pixels of their windows' union.
            let screen = ((cfg.iterations as f64 * self.cfg.screen_fraction).ceil() as usize).clamp(1, cfg.iterations);
            let mut window: Option<[u32; 4]> = None;
            for f in &mut fits {
                for _ in 0..screen {
                    f.step();
                }
                if let Some(w) = f.window() {
                    window = Some(window.map_or(w, |u| window_union(u, w)));
                }
            }
            if let Some(window) = window {
                let seed = cfg.seed ^ 0x9e37_79b9_7f4a_7c15;
                let scores: Vec<f64> = fits
                    .iter_mut()
                    .map(|f| f.score(window, cfg.rays_per_step.max(256) * 2, seed).loss)
                    .collect();
                // Another start must beat a trusted PA's clearly: on a small body, depth moves the score
                // little, and a near tie is noise in the pixel batch, not a lost track. Where PA lost the body
                // its start is one guess among the others.
                let margin = if starts[0].wide { 0.0 } else { SWITCH_MARGIN };
                let other = (1..fits.len())
                    .min_by(|&i, &j| scores[i].total_cmp(&scores[j]))
                    .unwrap_or(0);
                if scores[other] < scores[0] * (1.0 - margin) {
                    best = other;
                }
                tracing::debug!(
                    "frame {k}: {} starts scored {:?} ({:?}); kept {:?}",
                    starts.len(),
                    scores,
                    starts.iter().map(|s| s.from).collect::<Vec<_>>(),
                    starts[best].from
                );
            }
            let f = &mut fits[best];
            for _ in screen..cfg.iterations {
                f.step();
            }
        } else {
            fits[0].run();
        }
        let fit = &mut fits[best];
        let result = FramePose {
            pose: fit.pose,
            image: fit.evaluate(),
            contact_penalty: fit.contact_penalty(),
            in_contact: starts[best].held(),
            fitted: true,
            start: starts[best].from,
        };
        self.push(result);
        Ok(self.results.last())
    }

    /// Frame `k` at the last fitted frame's pose, not fitted, where the body stayed still over the two frames
    /// before and that pose explains frame `k` as well as its own ([`PosesFromVideoConfig::keep_still`]).
    fn kept_still(&self, k: usize) -> Result<Option<FramePose>, PosesFromVideoError> {
        if !self.cfg.keep_still || k < 2 {
            return Ok(None);
        }
        let (a, b) = (&self.results[k - 2], &self.results[k - 1]);
        let eye = self.frames[k].camera.center();
        let radius = self.world.bodies[self.body].bounding_radius;
        if !(a.fitted && b.fitted && crate::rest::is_still(&a.pose, &b.pose, eye, radius)) {
            return Ok(None);
        }
        // The frame the kept pose was fitted to (the frames kept since hold its pose).
        let Some(anchor) = self.results[..k].iter().rev().find(|r| r.start != StartFrom::Still) else {
            return Ok(None);
        };
        let mut at_anchor = match PoseFromImage::new(
            self.cfg.pose.clone(),
            self.object,
            self.scene,
            &self.frames[k],
            anchor.pose,
        ) {
            Err(PoseFitError::EmptyMask) => return Ok(None),
            Err(error) => return Err(PosesFromVideoError::Frame { frame: k, error }),
            Ok(fit) => fit
                .with_occluders(self.occluders[k].clone())
                .with_motion(self.motion_at(k)),
        };
        let image = at_anchor.evaluate();
        if !(image.loss <= anchor.image.loss * (1.0 + STILL_LOSS_SLACK)) {
            return Ok(None);
        }
        Ok(Some(FramePose {
            pose: anchor.pose,
            image,
            contact_penalty: anchor.contact_penalty,
            in_contact: anchor.in_contact,
            fitted: true,
            start: StartFrom::Still,
        }))
    }

    /// Whether frame `j` is a still frame explained within [`STILL_LOSS_SLACK`] of how its anchor (the last
    /// frame before it that is not still) explains its own frame.
    fn follows_its_anchor(&self, j: usize) -> bool {
        let r = &self.results[j];
        r.start == StartFrom::Still
            && self.results[..j]
                .iter()
                .rev()
                .find(|a| a.start != StartFrom::Still)
                .is_some_and(|a| r.image.loss <= a.image.loss * (1.0 + STILL_LOSS_SLACK))
    }

    /// The forward pass's outcome for the next frame; after the last one (with `hypotheses`), the last
    /// frame's check, the pass back, the sizing pass and the last pass are due.
    fn push(&mut self, result: FramePose) {
        self.results.push(result);
        if self.results.len() == self.frames.len() && self.cfg.hypotheses && !self.tracking {
            self.end_pending = true;
            self.sizing_pending = true;
            self.continuing_pending = true;
        }
    }

    /// GA's frames as fitted before (one per frame, as `ga.json` holds them), every pass taken as done: a
    /// stage built on another trajectory (PGA's simulation) to refit from it the frames they explain worst
    /// ([`Self::refit_worst_from_physics`]).
    pub fn with_results(mut self, results: Vec<FramePose>) -> Result<Self, PosesFromVideoError> {
        if results.len() != self.frames.len() {
            return Err(PosesFromVideoError::ResultCount {
                frames: self.frames.len(),
                results: results.len(),
            });
        }
        self.results = results;
        self.end_pending = false;
        self.sizing_pending = false;
        self.continuing_pending = false;
        Ok(self)
    }

    /// The fitted frames explained [`PosesFromVideoConfig::continue_ratio`] times worse than the median frame
    /// (still frames that follow their anchor aside), each fitted again from this stage's trajectory (PGA's
    /// simulation, held on the sides of the scene it touches in that frame) where it starts elsewhere than
    /// the frame's pose, and kept where it explains the frame better by a tenth (a fit started
    /// at the simulation's pose stays near it where the image barely tells them apart, and on the tabletop
    /// drop four near ties, 0–3 % lower, moved frames toward the simulation's basin, 3.2 → 4.0 mm and
    /// 2.3 → 3.4° at worst). Every start of GA's passes comes from
    /// the frame's own fit or its neighbours', so a tumble that GA turned the wrong way over a few frames
    /// stays so (the drop Rapier made, 320 × 240: frame 9 13.4° off, image loss 0.083; from PGA's simulation
    /// 0.064 and 3.7°); the simulation fitted to the whole video is an independent start there. `on_frame` is told
    /// after each frame tried. The frames replaced, in order.
    pub fn refit_worst_from_physics(&mut self, mut on_frame: impl FnMut()) -> Result<Vec<usize>, PosesFromVideoError> {
        let mut replaced = Vec::new();
        for k in self.poorly_explained() {
            let start = self.frames[k].centred_on_mask(&self.starts[k]);
            let pose = self.results[k].pose;
            if !same_start(&start, &pose) {
                // Steps as a start that far off takes (full scale at 15° or 15 mm).
                let scale = self.step_scale(pace(&pose, &start));
                let held = self.pa_sides[k].clone();
                if self.replace_if_better(k, start, scale, held, StartFrom::Pga, SWITCH_MARGIN)? {
                    replaced.push(k);
                }
            }
            on_frame();
        }
        Ok(replaced)
    }

    /// Fit every frame left; all outcomes.
    pub fn run(&mut self) -> Result<&[FramePose], PosesFromVideoError> {
        while !self.done() {
            self.step()?;
        }
        Ok(&self.results)
    }
}
