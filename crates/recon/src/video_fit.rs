//! What joins the stages of `fit` for one body (Sec. 3.3–3.4): a rough guess
//! lifted out of the scene, a launch guess from the first frames' poses, the
//! image terms of a whole pose sequence (for reports and for GA ↔ PGA), PGA's
//! per-frame weights from GA's residuals, and PGA itself (Eq. 11 on GA's
//! poses). The stages are [`crate::PoseFromImage`] (first pose),
//! [`crate::PhysicsFromVideo`] (PA), [`crate::PosesFromVideo`] (GA) and
//! [`crate::PhysicsFit`] (PGA).

pub use crate::clearance::{clearance, TOUCHING};
use crate::first_pose_search::FirstPoseSearchConfig;
use crate::fit_physics::{
    fit_multi_start_bodies, FitError, MultiStart, Observed, PhysicsFitConfig, StartContact, StartsOn, CONTACT_STARTS,
};
use crate::image_loss::{FrameError, FrameTarget, ImageLoss, ImageLossWeights, Occluder, PreparedFrame};
use crate::image_precision::ImagePrecision;
use crate::physics_from_video::VideoPhysicsConfig;
use crate::pose_from_image::PoseFitConfig;
use crate::poses_from_video::PosesFromVideoConfig;
use crate::shutter::Motion;
use crate::value_ranges::RangeScan;
use geom::{Pose, Quat, Vec3};
use neus::compose::{ComposedRay, Composer};
use neus::ObjectModel;
use serde::{Deserialize, Serialize};
use sim::sdf::{Sdf, Shape};
use sim::{ContactParams, RigidBody, SimConfig, Trajectory, World};

/// Settings of every stage of `fit`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VideoFitConfig {
    /// The simulator (its `fps` and `frames` come from the video).
    pub sim: SimConfig,
    /// The first pose (and the poses of the launch frames).
    pub first_pose: PoseFitConfig,
    /// The search for the first pose without a guess (`--init auto`).
    pub auto_init: FirstPoseSearchConfig,
    /// Frames after the first whose poses, fitted as the first one, give the launch guess (fewer when one
    /// already touches the scene). Default 3: with gravity known, three frames pin the launch along the
    /// line of sight, where one silhouette tells depth least.
    pub launch_frames: usize,
    /// A body that the first frame shows on the scene launches along it: PA and PGA fit its launch velocity
    /// in the plane of the scene under it, and its spin about the normal only when it rests on a face
    /// ([`StartContact`]). Default true; off for a video whose body hops off the board at once.
    pub launch_in_plane: bool,
    /// Contact values PA starts from (and PGA with `--no-pa`). Default 0.5 and 0.5.
    pub start_contact: ContactParams,
    pub pa: VideoPhysicsConfig,
    pub ga: PosesFromVideoConfig,
    /// PGA (Eq. 11 on GA's poses). Its `rotation_weight` is in body radii here: a quaternion error counts
    /// as the arc it moves the body's surface, as PA and GA weigh turns (at the paper's λ_q = 1 a ball's
    /// spin, which its silhouette does not show, outweighed every centimetre of its path).
    pub pga: PhysicsFitConfig,
    /// PGA also starts from each contact pair of [`CONTACT_STARTS`] (the lowest loss wins; `fit` lets the images
    /// overrule it among the starts within a tenth of it, where they tell them apart by a tenth too). Default true.
    pub pga_multi_start: bool,
    /// PGA's launch is tested against the flight before the first contact ([`crate::flight`]): where it
    /// misses the flight by more than the poses' noise, the flight's launch is held, the contact values are
    /// fitted around it, and that world is kept if its simulation explains the video better. Default true.
    pub flight_test: bool,
    /// The ranges of the fitted contact values that the motion cannot tell apart ([`crate::value_ranges`]),
    /// the initial poses held at their fitted values (`steps = 0`: none).
    pub ranges: RangeScan,
    /// GA ↔ PGA rounds at most; a round is kept only if it lowers the image loss of the simulated
    /// trajectory. Default 1: on the tabletop slide a second round (another GA, 3 minutes of a 48-frame
    /// fit) never lowered it.
    pub rounds: usize,
    /// PGA and everything after it simulate in the scene less the space GA saw the body in
    /// ([`crate::seen_space`]): a reconstructed scene's fillet at a wall's foot otherwise kicks the simulated
    /// body up where the images show it pressed into the corner. Default true.
    pub carve_scene: bool,
    /// With several bodies: where the first PGA round's fitted motion does not converge in its step size
    /// over the video ([`crate::horizon`]: twice the substeps draw a body elsewhere), the second round's PGA
    /// (on GA's poses from the first round's simulation, at its own step) simulates at twice the substeps,
    /// and the images choose between the rounds as ever. A motion fitted at too coarse a step is tuned to
    /// that step's own collisions (the project's push at 10 substeps a frame: twice them drew the toy
    /// 14.4 px away, four times 20 px); the push's second round at 20 lowered the kept image loss from 4.09
    /// to 3.24. Default true.
    pub finer_step_round: bool,
    /// The objects' geometry baked this many lattice steps a cell of their occupancy grids before the fit
    /// (`neus::baked_geometry`: the SDF, the colour MLP's features and the normals read by trilinear
    /// interpolation in place of the hash grid and SDF MLP at every sample); 0: the network at every sample.
    /// The default 4 makes the demo's fits 1.7× faster and the 320 × 240 ones about 2× (profile notebook). A
    /// fit folder written before the bake has no key and reads 0 (it resumes as it began).
    #[serde(default)]
    pub bake_object: usize,
}

impl Default for VideoFitConfig {
    fn default() -> Self {
        Self {
            sim: SimConfig::default(),
            first_pose: PoseFitConfig::default(),
            auto_init: FirstPoseSearchConfig::default(),
            launch_frames: 3,
            launch_in_plane: true,
            start_contact: ContactParams {
                restitution: 0.5,
                friction: 0.5,
            },
            pa: VideoPhysicsConfig::default(),
            // 80 steps of 512 pixels a frame (the library's 80 of 1,024 took 8.5 of a 48-frame fit's 23
            // minutes for IoU 0.972 against 40 of 512's 0.967). With 40 steps, a frame started 10–15° off (a tumble, a hit) ran out of steps:
            // GA's poses were further from the truth where the images said so (the demo drop's frame 11:
            // 6.5° off, its image loss twice the true pose's; 0.3° at 80 steps).
            ga: PosesFromVideoConfig {
                pose: PoseFitConfig {
                    iterations: 80,
                    rays_per_step: 512,
                    ..PosesFromVideoConfig::default().pose
                },
                ..PosesFromVideoConfig::default()
            },
            pga: PhysicsFitConfig {
                fit_initial_pose: true,
                ..PhysicsFitConfig::default()
            },
            pga_multi_start: true,
            flight_test: true,
            ranges: RangeScan::default(),
            rounds: 1,
            carve_scene: true,
            finer_step_round: true,
            bake_object: 4,
        }
    }
}

/// Contact points within this of the lowest one (m) make the support a body rests on.
const SUPPORT_BAND: f64 = 0.001;
/// A support whose narrower RMS half-width is at least this fraction of the body's bounding radius is a
/// face; narrower, a point or an edge. A ball's cap within [`SUPPORT_BAND`] is `√(2 r · 1 mm) / 2` wide:
/// 0.16 of a 2 cm ball's radius, 0.22 of a 1 cm one's; the tabletop toy's flat side, reconstructed and
/// merged, measured 0.32 (the slide's first frame, `RUST_LOG=recon::video_fit=debug`).
const FACE_WIDTH: f64 = 0.25;

/// A body whose surface facing the scene (its outward normal within this of the scene's, opposite) spreads
/// as a face ([`FACE_WIDTH`]) near the scene lies on that face: a pose fitted to one image is a degree or
/// two off (the tabletop slide's first pose from a guess 15° off touched along an edge, which freed a spin
/// about the board's axes that the fit then took: 3.65 rad/s off, 0.31 on the face, 320 × 240), and a reconstructed face's normals are
/// a degree or two rough. A ball's cap that faces within it is `sin 5°` = 0.09 of its radius wide.
pub(crate) const FACING_ANGLE: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// The narrower RMS half-width of `points` in the plane spanned by `a` and `b` (the square root of the
/// smaller eigenvalue of their 2 × 2 covariance); 0 without points.
fn narrower_half_width(points: &[Vec3<f64>], a: Vec3<f64>, b: Vec3<f64>) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let count = points.len() as f64;
    let mean = points.iter().fold(Vec3::new(0.0, 0.0, 0.0), |s, p| s + *p) * (1.0 / count);
    let (mut saa, mut sab, mut sbb) = (0.0, 0.0, 0.0);
    for p in points {
        let (x, y) = ((*p - mean).dot(a), (*p - mean).dot(b));
        saa += x * x / count;
        sab += x * y / count;
        sbb += y * y / count;
    }
    let narrow = 0.5 * (saa + sbb) - (0.25 * (saa - sbb).powi(2) + sab * sab).sqrt();
    narrow.max(0.0).sqrt()
}

/// [`start_contact`] when `in_plane` (the `launch_in_plane` switch), else [`StartContact::Free`].
pub fn launch_start(body: &RigidBody, scene: &Shape, pose: &Pose<f64>, in_plane: bool) -> StartContact {
    if in_plane {
        start_contact(body, scene, pose)
    } else {
        StartContact::Free
    }
}

/// How the body at `pose` touches the scene ([`StartContact`]): off it when its lowest contact point is
/// [`TOUCHING`] or more above it; else the scene's normal there (the mean of its gradients at the
/// support's points), and a face when the support spreads in both directions of the tangent plane, or the
/// part of the body's surface near the scene that faces it within 5° does.
pub fn start_contact(body: &RigidBody, scene: &Shape, pose: &Pose<f64>) -> StartContact {
    // Each contact point placed, with its distance to the scene and the scene's gradient there (queried once).
    let placed: Vec<(Vec3<f64>, f64, Vec3<f64>)> = body
        .contact_points
        .iter()
        .map(|p| {
            let at = pose.transform_point(*p);
            let (d, g) = scene.distance_grad_local(at);
            (at, d, g)
        })
        .collect();
    let lowest = placed.iter().map(|&(_, d, _)| d).fold(f64::INFINITY, f64::min);
    if !(lowest < TOUCHING) {
        return StartContact::Free;
    }
    let mut sum = Vec3::new(0.0, 0.0, 0.0);
    let mut support = Vec::new();
    for &(at, d, g) in &placed {
        if d < lowest + SUPPORT_BAND {
            sum += g.normalize_or(Vec3::new(0.0, 0.0, 0.0));
            support.push(at);
        }
    }
    // Normals that mostly cancel (a body wedged in a groove) give no plane to launch along.
    if sum.norm() < 0.5 * support.len() as f64 {
        return StartContact::Free;
    }
    let n = sum.normalize_or(Vec3::new(0.0, 0.0, 1.0));
    let normal = n.to_array();
    // The support's spread in the tangent plane: the smaller eigenvalue of its 2 × 2 covariance.
    let [a, b] = crate::unknowns::tangent_basis(normal).map(Vec3::cst);
    let width = narrower_half_width(&support, a, b) / body.bounding_radius;
    // A pose fitted to one image is a degree or two off: a body sliding on its face then touches along its
    // lower edge only. What it lies on is the part of its surface that faces the scene, near it.
    let heights: Vec<f64> = placed.iter().map(|&(_, d, _)| d).collect();
    let points: Vec<Vec3<f64>> = placed.iter().map(|&(at, _, _)| at).collect();
    let facing = facing_points(body, pose, n, &points, &heights, FACING_ANGLE);
    let facing_width = narrower_half_width(&facing, a, b) / body.bounding_radius;
    tracing::debug!(
        "start contact: {} support points, narrower RMS half-width {width:.3} of the radius; {} facing the \
         scene, {facing_width:.3}",
        support.len(),
        facing.len()
    );
    if width >= FACE_WIDTH || facing_width >= FACE_WIDTH {
        StartContact::Face { normal }
    } else {
        StartContact::Touching { normal }
    }
}

/// The body's contact points (`placed` at `pose`, each `heights` above the scene) near the scene and facing
/// it: within [`SUPPORT_BAND`] and a face's reach tilted by [`FACING_ANGLE`] of the lowest, their outward
/// normals within `cone` of the scene's normal `n` turned around. What a body lying on a face lies on.
pub(crate) fn facing_points(
    body: &RigidBody,
    pose: &Pose<f64>,
    n: Vec3<f64>,
    placed: &[Vec3<f64>],
    heights: &[f64],
    cone: f64,
) -> Vec<Vec3<f64>> {
    let lowest = heights.iter().copied().fold(f64::INFINITY, f64::min);
    let band = lowest + SUPPORT_BAND + FACING_ANGLE.tan() * 2.0 * body.bounding_radius;
    body.contact_points
        .iter()
        .zip(placed.iter().zip(heights))
        .filter(|&(_, (_, &h))| h < band)
        .filter_map(|(p, (&at, _))| {
            let outward = pose.q.rotate(body.sdf.distance_grad_local(*p).1);
            let faces = outward.norm() > 0.0 && outward.dot(n) <= -cone.cos() * outward.norm();
            faces.then_some(at)
        })
        .collect()
}

/// A rough guess raised along +z until no contact point is inside the scene (a guess from markers may sink
/// into the board; that is normal, not an error); the lift, m.
pub fn lift_out(body: &RigidBody, scene: &Shape, pose: Pose<f64>) -> (Pose<f64>, f64) {
    let mut p = pose;
    // A few rounds: under a slope, rising moves the deepest point.
    for _ in 0..8 {
        let c = clearance(body, scene, &p);
        if c >= 0.0 {
            break;
        }
        p.t.z += -c + 1e-4;
    }
    (p, p.t.z - pose.t.z)
}

/// Within this of the scene (m), a body that the first frames show on the scene is settled onto it
/// ([`settle_along_ray`]); further off, it is taken to hop.
pub const SETTLE_BAND: f64 = 0.01;

/// A pose on the scene's surface, moved along the line of sight: the body slid along the ray from the camera
/// `eye` through its origin until its lowest contact point touches the scene (clearance 0, within 0.1 mm).
/// One view pins a body's depth least, and a body resting or sliding on the board touches it: moving along
/// the ray keeps its image in place (up to its size, a fraction of a percent per millimetre at table
/// distances) and puts it on the board, where the contact penalty of the next stages holds it. `None`
/// when no point within 3 cm along the ray touches (the body is elsewhere).
pub fn settle_along_ray(body: &RigidBody, scene: &Shape, eye: Vec3<f64>, pose: &Pose<f64>) -> Option<Pose<f64>> {
    let dir = (pose.t - eye).normalize_or(Vec3::new(0.0, 0.0, -1.0));
    let at = |s: f64| Pose::new(pose.q, pose.t + dir * s);
    let clear = |s: f64| clearance(body, scene, &at(s));
    // Bracket the root: the clearance falls moving away from a camera that looks down on the board.
    let (mut a, mut b) = (-0.03, 0.03);
    let (fa, fb) = (clear(a), clear(b));
    if !(fa.is_finite() && fb.is_finite()) || fa.signum() == fb.signum() {
        return None;
    }
    for _ in 0..40 {
        let m = 0.5 * (a + b);
        let fm = clear(m);
        if fm.abs() < 1e-4 {
            return Some(at(m));
        }
        if fm.signum() == fa.signum() {
            a = m;
        } else {
            b = m;
        }
    }
    Some(at(0.5 * (a + b)))
}

/// `pose` slid along the line of sight from the camera `eye` through its origin by `share` of the way to the
/// depth of `other`'s origin (0: `pose`, 1: at `other`'s depth; the rotation kept): the image places a body
/// across its line of sight `z / d` times more precisely than along it (its size changes by a fraction of
/// a percent per millimetre), so where GA's pose and the simulation's disagree, GA's says where the body is
/// across the line of sight and the two depths are weighed by what each tells ([`depth_share`]).
pub fn toward_depth_of(pose: &Pose<f64>, other: &Pose<f64>, eye: Vec3<f64>, share: f64) -> Pose<f64> {
    let dir = (pose.t - eye).normalize_or(Vec3::new(0.0, 0.0, -1.0));
    Pose::new(pose.q, pose.t + dir * ((other.t - pose.t).dot(dir) * share))
}

/// The share of the way from a pose fitted to one image to the simulation's depth that the two are best
/// weighed at: each depth counts by the inverse of its variance. The fitted pose's depth is known to
/// the image's precision along the line of sight ([`ImagePrecision`]), scaled by `loss_ratio` (the frame's image loss over the
/// median frame's, at least 1: a frame the fit explains badly tells its depth worse); the simulation's to
/// about how far it is from the fitted pose across the line of sight (`sim_across`, where the image says
/// where the body is), at least one edge precision. `z`: the distance from the camera, `diameter`: the
/// body's, `focal_px`: the camera's focal length in pixels.
pub fn depth_share(z: f64, diameter: f64, focal_px: f64, loss_ratio: f64, sim_across: f64) -> f64 {
    let image = ImagePrecision::at_distance(Vec3::new(0.0, 0.0, 1.0), z, diameter, focal_px);
    let sigma_fit = image.along * loss_ratio.max(1.0);
    let sigma_sim = sim_across.max(image.across);
    let (a, b) = (sigma_fit * sigma_fit, sigma_sim * sigma_sim);
    if (a + b).is_finite() && a + b > 0.0 {
        a / (a + b)
    } else {
        0.0
    }
}

/// The launch `(v0, ω0)` (world frame) of poses one frame apart: least squares over `poses` of
/// `t_k = t_0 + v0 k dt + ½ g (k dt)²` (without the gravity term when the body starts on the scene), and the
/// mean turn rate.
pub fn launch_guess(poses: &[Pose<f64>], fps: f64, gravity: [f64; 3], touching: bool) -> ([f64; 3], [f64; 3]) {
    if poses.len() < 2 || !(fps > 0.0) {
        return ([0.0; 3], [0.0; 3]);
    }
    let dt = 1.0 / fps;
    let g = if touching {
        Vec3::new(0.0, 0.0, 0.0)
    } else {
        Vec3::cst(gravity)
    };
    let (mut num, mut den) = (Vec3::new(0.0, 0.0, 0.0), 0.0);
    for (k, p) in poses.iter().enumerate().skip(1) {
        let s = k as f64 * dt;
        num += (p.t - poses[0].t - g * (0.5 * s * s)) * s;
        den += s * s;
    }
    let v = num * (1.0 / den);
    let last = poses.len() - 1;
    let turn = (poses[last].q * poses[0].q.conj()).normalize_or_identity().log();
    let omega = turn * (1.0 / (last as f64 * dt));
    (v.to_array(), omega.to_array())
}

/// Body `body`'s velocity in every frame of `traj` (for frames with a shutter time).
pub fn simulated_motions(traj: &Trajectory<f64>, body: usize) -> Vec<Option<Motion>> {
    traj.frames.iter().map(|f| f.get(body).map(Motion::from)).collect()
}

/// The image terms of every frame with the body at `poses[k]` (every pixel of each frame's window; frames
/// whose mask is empty give the default, zero pixels), moving at `motions[k]` where a frame has a shutter
/// time (none, or beyond the slice: drawn at its instant). `others`: the video's other bodies and their
/// poses, drawn where they stand.
#[allow(clippy::too_many_arguments)]
pub fn evaluate_poses(
    object: &ObjectModel,
    scene: &[ComposedRay],
    frames: &[FrameTarget],
    poses: &[Pose<f64>],
    motions: &[Option<Motion>],
    others: &[(&ObjectModel, &[Pose<f64>])],
    weights: &ImageLossWeights,
) -> Result<Vec<ImageLoss>, FrameError> {
    // Frames side by side, each with its own composer: a frame's window is a few thousand rays, too few to
    // keep two cores busy alone.
    use rayon::prelude::*;
    frames
        .par_iter()
        .zip(poses)
        .enumerate()
        .map_init(Composer::default, |composer, (k, (f, pose))| {
            let mut prepared = PreparedFrame::new(f, scene)?;
            prepared.set_motion(motions.get(k).copied().flatten());
            prepared.set_occluders(
                others
                    .iter()
                    .filter_map(|(object, poses)| poses.get(k).map(|&pose| Occluder { object, pose }))
                    .collect(),
            );
            Ok(if prepared.has_mask() {
                prepared.evaluate(composer, object, scene, pose, weights)
            } else {
                ImageLoss::default()
            })
        })
        .collect()
}

/// The summed loss of a sequence's frames (what GA ↔ PGA rounds compare).
pub fn total_loss(losses: &[ImageLoss]) -> f64 {
    losses.iter().map(|l| l.loss).sum()
}

/// PGA's weight of each of GA's frames as `PosesFromVideo` returns them: [`ga_weights`] times
/// [`crate::rest::rest_discount`] (`eye`: the camera's centre, `radius`: the body's bounding radius).
pub fn ga_weights_of(frames: &[crate::FramePose], eye: Vec3<f64>, radius: f64) -> Vec<f64> {
    let losses: Vec<ImageLoss> = frames.iter().map(|r| r.image.clone()).collect();
    let fitted: Vec<bool> = frames.iter().map(|r| r.fitted).collect();
    let poses: Vec<Pose<f64>> = frames.iter().map(|r| r.pose).collect();
    let rest = crate::rest::rest_discount(&poses, &fitted, eye, radius);
    ga_weights(&losses, &fitted)
        .into_iter()
        .zip(rest)
        .map(|(w, r)| w * r)
        .collect()
}

/// PGA's weight of each GA pose: 0 where GA had no mask, else `min(1, median / residual)` of the image
/// losses, so frames GA could not explain (occlusion, blur, a wrong basin) count less than the rest.
pub fn ga_weights(losses: &[ImageLoss], fitted: &[bool]) -> Vec<f64> {
    let pairs = losses.iter().zip(fitted).map(|(l, &f)| (l.loss, f));
    let Some(median) = crate::poses_from_video::median_fitted_loss(pairs) else {
        return vec![0.0; losses.len()];
    };
    let median = median.max(1e-12);
    losses
        .iter()
        .zip(fitted)
        .map(|(l, &f)| if f { (median / l.loss.max(1e-12)).min(1.0) } else { 0.0 })
        .collect()
}

/// PGA (Eq. 11): a body's physics fitted to GA's poses (`observed`: its poses, their weights, how it starts
/// on the scene), from the world's own values (PA's) and, with `multi_start`, from
/// each of [`CONTACT_STARTS`]. `on_start` hears each start's end.
pub fn fit_to_poses(
    cfg: &PhysicsFitConfig,
    multi_start: bool,
    world: World,
    observed: Observed,
    on_start: &mut dyn FnMut(usize, &crate::StartResult),
) -> Result<MultiStart, FitError> {
    let starts: &[(f64, f64)] = if multi_start { &CONTACT_STARTS } else { &[] };
    fit_multi_start_bodies(cfg.clone(), world, vec![observed], starts, StartsOn::Scene, on_start)
}

/// The rigid motion `p_frame0 = R(q) p_capture + t` of an `init.json` entry applied to where the body frame
/// sat in that capture: the body's pose in frame 0.
pub fn pose_from_guess(capture_from_body: &Pose<f64>, t: [f64; 3], q: [f64; 4]) -> Pose<f64> {
    Pose::new(Quat::cst(q).normalize_or_identity(), Vec3::cst(t)).compose(capture_from_body)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn launch_guess_recovers_a_parabola_and_a_spin() {
        let (v0, w0, g) = (Vec3::new(0.4, -0.2, 0.9), Vec3::new(0.0, 2.0, -1.0), [0.0, 0.0, -9.81]);
        let fps = 30.0;
        let poses: Vec<Pose<f64>> = (0..4)
            .map(|k| {
                let s = k as f64 / fps;
                Pose::new(
                    Quat::exp(w0 * s),
                    Vec3::new(0.1, 0.0, 0.2) + v0 * s + Vec3::cst(g) * (0.5 * s * s),
                )
            })
            .collect();
        let (v, w) = launch_guess(&poses, fps, g, false);
        for k in 0..3 {
            assert!((v[k] - v0.to_array()[k]).abs() < 1e-9, "{v:?}");
            assert!((w[k] - w0.to_array()[k]).abs() < 1e-9, "{w:?}");
        }
        // On the board, the gravity term is left out.
        let (v, _) = launch_guess(&poses[..2], fps, g, true);
        assert!((v[2] - (v0.z - 0.5 * 9.81 / fps)).abs() < 1e-9);
    }

    #[test]
    fn a_pose_slid_toward_another_depth_stays_on_its_line_of_sight() {
        let eye = Vec3::new(0.0, -0.5, 0.4);
        let ga = Pose::new(Quat::exp(Vec3::new(0.1, 0.2, 0.3)), Vec3::new(0.05, 0.02, 0.03));
        let sim = Pose::new(Quat::identity(), Vec3::new(0.04, 0.05, 0.01));
        let unit = |v: Vec3<f64>| v * (1.0 / v.norm());
        let dir = unit(ga.t - eye);
        for share in [1.0, 0.25] {
            let slid = toward_depth_of(&ga, &sim, eye, share);
            assert!(dir.cross(unit(slid.t - eye)).norm() < 1e-12, "on GA's line of sight");
            let left = (sim.t - slid.t).dot(dir);
            assert!(
                (left - (1.0 - share) * (sim.t - ga.t).dot(dir)).abs() < 1e-12,
                "{share} of the way"
            );
            assert_eq!(slid.q.to_array_re(), ga.q.to_array_re());
        }
        assert!((toward_depth_of(&ga, &sim, eye, 0.0).t - ga.t).norm() < 1e-15);
    }

    #[test]
    fn depths_are_weighed_by_what_each_tells() {
        // A 76 mm body 0.4 m off, f = 290 px: an edge is placed to 0.34 mm, the depth to 1.8 mm.
        let (z, d, f) = (0.4, 0.076, 290.0);
        let half = depth_share(z, d, f, 1.0, z / d * 0.25 * z / f);
        assert!((half - 0.5).abs() < 1e-12, "{half}");
        // A simulation that follows the body across to a millimetre is trusted with its depth mostly...
        let close = depth_share(z, d, f, 1.0, 0.001);
        assert!(close > 0.7, "{close}");
        // ...one 10 mm off hardly; a frame the fit explains three times worse than the median trusts its own
        // depth less; twice the resolution, more.
        assert!(depth_share(z, d, f, 1.0, 0.01) < 0.05);
        assert!(depth_share(z, d, f, 3.0, 0.01) > 2.0 * depth_share(z, d, f, 1.0, 0.01));
        assert!(depth_share(z, d, 2.0 * f, 1.0, 0.001) < close);
        // A simulation on top of the fitted pose: the floor of one edge precision, not a division by zero.
        assert!(depth_share(z, d, f, 1.0, 0.0) > 0.9);
    }

    #[test]
    fn a_floating_pose_settles_onto_the_board_along_the_line_of_sight() {
        use sim::sdf::{Cuboid, Plane};
        use sim::{ContactSampling, MassSpec};
        let board = Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        });
        let half = 0.02;
        let body = RigidBody::from_shape(
            "block",
            &Shape::Cuboid(Cuboid { half: [half; 3] }),
            MassSpec::Mass(0.1),
            ContactSampling::default(),
        )
        .unwrap();
        let eye = Vec3::new(0.0, -0.5, 0.4);
        // 3 mm above the board, turned about the vertical.
        let floating = Pose::new(Quat::exp(Vec3::new(0.0, 0.0, 0.3)), Vec3::new(0.05, 0.02, half + 0.003));
        let settled = settle_along_ray(&body, &board, eye, &floating).unwrap();
        assert!(clearance(&body, &board, &settled).abs() < 1e-4);
        assert!((settled.t.z - half).abs() < 1e-4, "{:?}", settled.t);
        // On the same line of sight, further from the camera, the same way up.
        let unit = |v: Vec3<f64>| v * (1.0 / v.norm());
        let (d0, d1) = (unit(floating.t - eye), unit(settled.t - eye));
        assert!(d0.cross(d1).norm() < 1e-9);
        assert!((settled.t - eye).norm() > (floating.t - eye).norm());
        assert_eq!(settled.q.to_array_re(), floating.q.to_array_re());
        // Sunk 2 mm: raised toward the camera.
        let sunk = Pose::new(floating.q, Vec3::new(0.05, 0.02, half - 0.002));
        let raised = settle_along_ray(&body, &board, eye, &sunk).unwrap();
        assert!((raised.t.z - half).abs() < 1e-4 && (raised.t - eye).norm() < (sunk.t - eye).norm());
        // Far above the board (a toss): nothing along 3 cm of the ray touches.
        let flying = Pose::new(floating.q, Vec3::new(0.05, 0.02, 0.2));
        assert!(settle_along_ray(&body, &board, eye, &flying).is_none());
    }

    #[test]
    fn a_box_on_its_face_a_ball_and_a_tossed_box_start_on_a_face_a_point_and_off_the_scene() {
        use sim::sdf::{Cuboid, Plane, Sphere};
        use sim::{ContactSampling, MassSpec};
        // A slope, so the normal is not an axis.
        let normal = Vec3::new(0.2, 0.0, 1.0).normalize_or(Vec3::new(0.0, 0.0, 1.0));
        let slope = Shape::Plane(Plane {
            normal: normal.to_array(),
            offset: 0.0,
        });
        let body =
            |shape: Shape| RigidBody::from_shape("b", &shape, MassSpec::Mass(0.1), ContactSampling::default()).unwrap();
        let half = [0.025, 0.02, 0.015];
        let block = body(Shape::Cuboid(Cuboid { half }));
        let ball = body(Shape::Sphere(Sphere { radius: 0.02 }));
        // Lying on the slope: turned so its face is parallel to it, its centre half a height along the normal.
        let tilt = Quat::exp(Vec3::new(0.0, 0.2f64.atan(), 0.0));
        let on_face = Pose::new(tilt, normal * half[2]);
        let close = |a: [f64; 3]| (0..3).all(|i| (a[i] - normal.to_array()[i]).abs() < 1e-3);
        match start_contact(&block, &slope, &on_face) {
            StartContact::Face { normal } => assert!(close(normal), "{normal:?}"),
            other => panic!("the block on its face: {other:?}"),
        }
        match start_contact(&ball, &slope, &Pose::new(Quat::identity(), normal * 0.02)) {
            StartContact::Touching { normal } => assert!(close(normal), "{normal:?}"),
            other => panic!("the ball: {other:?}"),
        }
        // Lying on its face turned 2.5° about its longer side, as a pose fitted to one image may be: along one
        // edge within a millimetre, its face within 2 mm. A face; turned 8°, an edge.
        let settle = |q: Quat<f64>| {
            let lifted = lift_out(&block, &slope, Pose::new(q, normal * 0.03)).0;
            Pose::new(lifted.q, lifted.t - normal * clearance(&block, &slope, &lifted))
        };
        for (degrees, face) in [(2.5f64, true), (8.0, false)] {
            let turned = settle(tilt * Quat::exp(Vec3::new(degrees.to_radians(), 0.0, 0.0)));
            let found = start_contact(&block, &slope, &turned);
            assert_eq!(
                matches!(found, StartContact::Face { .. }),
                face,
                "turned {degrees}°: {found:?}"
            );
        }
        // On an edge: touching, not a face.
        assert!(matches!(
            start_contact(&block, &slope, &settle(tilt * Quat::exp(Vec3::new(0.6, 0.0, 0.0)))),
            StartContact::Touching { .. }
        ));
        // 5 mm above the slope: off it.
        let tossed = Pose::new(tilt, normal * (half[2] + 0.005));
        assert_eq!(start_contact(&block, &slope, &tossed), StartContact::Free);
        // Wedged in a slot as tall as it is: the normals cancel, no plane to launch along.
        let slot = Shape::Union(vec![
            Shape::Plane(Plane {
                normal: [0.0, 0.0, 1.0],
                offset: 0.0,
            }),
            Shape::Plane(Plane {
                normal: [0.0, 0.0, -1.0],
                offset: -2.0 * half[2],
            }),
        ]);
        let wedged = Pose::new(Quat::identity(), Vec3::new(0.0, 0.0, half[2]));
        assert_eq!(start_contact(&block, &slot, &wedged), StartContact::Free);
    }

    #[test]
    fn weights_favour_the_frames_ga_explains() {
        let l = |loss| ImageLoss {
            loss,
            ..ImageLoss::default()
        };
        let w = ga_weights(&[l(0.1), l(0.1), l(0.4), l(0.05)], &[true, true, true, false]);
        assert_eq!(w, vec![1.0, 1.0, 0.25, 0.0]);
    }
}
