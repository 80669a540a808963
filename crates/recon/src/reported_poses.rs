//! Which pose each frame of a fitted video reports: the simulated one (Eq. 11) wherever it explains the
//! frame, GA's pose (at a depth weighed with the simulation's, or its own) where the simulation clearly
//! misses the frame. A decision of the method with no I/O: the caller scores poses through a closure.

use crate::image_loss::ImageLoss;
use crate::poses_from_video::FramePose;
use geom::{Camera, Pose, Vec3};

/// A frame's simulated silhouette IoU at least this far below GA's is one the simulation misses. A small
/// body's IoU differs by several hundredths between poses millimetres apart, and GA, fitting the silhouette
/// alone, wins it by moving in depth (a 14 px ball: 0.88 simulated against 0.96 by GA, the simulated pose
/// 2 mm closer to the truth), so only a clear miss counts.
pub const SIMULATION_MISSES_BY: f64 = 0.1;
/// A frame whose image loss (GA's terms, per pixel) under the simulation is more than this
/// many times GA's is one the simulation misses too, even with its silhouette in place: a tumble the
/// simulator turned another way (the tabletop drop's bounces: 10–15° off, at 1.5–4 times GA's loss). Where
/// both explain the image alike, the simulation's pose is kept (depth from physics, not from a silhouette's
/// size). In a frame GA explains worse than the video's best frames, the simulation's excess over GA's loss
/// is held to the best frames' loss instead ([`loss_floor`], [`simulation_misses`]).
pub const SIMULATION_LOSS_RATIO: f64 = 1.5;

/// The loss of the frames a video's poses explain best: the lowest tenth of GA's fitted frames' image losses
/// ([`crate::poses_from_video::lowest_tenth_fitted_loss`]); `None` without fitted frames.
pub fn loss_floor(ga: &[FramePose]) -> Option<f64> {
    crate::poses_from_video::lowest_tenth_fitted_loss(ga.iter().map(|g| (g.image.loss, g.fitted)))
}

/// A simulated pose that draws its body this many pixels from GA's on average (its depth set to GA's) draws
/// it visibly elsewhere: four times the precision a silhouette's edge is placed to
/// ([`crate::image_precision::EDGE_PRECISION_PX`]). The silhouette margin above does not scale with the body's
/// size in the image: on a body 70 px wide it forgives a frame the simulation turned 5° and moved 2.6 mm
/// (2–3 px) off (the 320×240 tabletop drop's bounce: IoU 0.877 against GA's 0.961), where on a 14 px ball
/// it forgives a fraction of a pixel. Depth is left out: one view tells it least, and the simulation's is
/// weighed against GA's where GA's pose is reported.
pub const SIMULATION_MISSES_BY_PX: f64 = 4.0 * crate::image_precision::EDGE_PRECISION_PX;

/// How far apart two poses draw a body's `points` (body frame) through `camera`, in pixels on average,
/// `b`'s depth along its line of sight first set to `a`'s: what the image can tell of the difference.
pub fn apart_across_px(a: &Pose<f64>, b: &Pose<f64>, points: &[Vec3<f64>], camera: &Camera<f64>) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let b = crate::video_fit::toward_depth_of(b, a, camera.center(), 1.0);
    let sum: f64 = points
        .iter()
        .map(|p| {
            let (ua, va, _) = camera.project(a.transform_point(*p));
            let (ub, vb, _) = camera.project(b.transform_point(*p));
            (ua - ub).hypot(va - vb)
        })
        .sum();
    sum / points.len() as f64
}

/// Whether the simulation clearly misses a frame GA fitted (its silhouette or its image loss, above), so
/// that GA's pose is reported there instead of the simulated one. The image loss: the simulation's above
/// GA's by more than [`SIMULATION_LOSS_RATIO`] − 1 times GA's loss or the video's `floor`
/// ([`loss_floor`]), the smaller. A ratio to GA's own loss blunts as a frame's loss grows for reasons no
/// pose changes: on the camera-like drop (noise, JPEG, a 1/60 s shutter, 160 × 120) GA explained the frame
/// after a bounce at 0.033, twice the best frames' 0.017, and a simulation 4.8° off (3.2° GA's) at 0.047 was
/// kept at 1.43 times GA's loss, its silhouette's IoU with the true one 0.88.
pub fn simulation_misses(simulated: &ImageLoss, ga: &FramePose, floor: f64) -> bool {
    let silhouette_missed = simulated.iou() < ga.image.iou() - SIMULATION_MISSES_BY;
    let reference = ga.image.loss.min(floor.max(0.0));
    let image_missed = simulated.loss - ga.image.loss > (SIMULATION_LOSS_RATIO - 1.0) * reference;
    ga.fitted && simulated.pixels > 0 && (silhouette_missed || image_missed)
}

/// Which pose a frame of the final trajectory reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReportedPose {
    /// The simulation's (Eq. 11): it explains the frame.
    Simulated,
    /// GA's pose slid along its line of sight toward the simulation's depth, GA's and the simulation's depth
    /// weighed by what each tells ([`crate::video_fit::depth_share`]): the simulation misses the frame (a
    /// turn the simulator cannot make), and the weighed pose explains it.
    GaAtWeighedDepth,
    /// GA's own pose: neither of the above explains the frame.
    Ga,
}

impl ReportedPose {
    pub fn name(self) -> &'static str {
        match self {
            ReportedPose::Simulated => "simulated",
            ReportedPose::GaAtWeighedDepth => "ga_at_weighed_depth",
            ReportedPose::Ga => "ga",
        }
    }
}

/// The pose each frame reports, and which: the simulated one wherever it explains the frame; where it
/// clearly misses it ([`simulation_misses`]), GA's pose at a depth between its own and the simulation's
/// where that pose explains the frame, else GA's own. One view tells a body's depth least: GA's poses
/// wander along the line of sight where the image cannot tell (the demo's drop at 160×120: 1.7 mm on
/// average, 7.5 at worst, against 0.1–0.2 mm across), while the simulation, which follows gravity and the
/// contacts, is off by about as much along it as it is off GA's pose across it, even in frames whose turn
/// it misses. The two depths are weighed by those errors ([`crate::video_fit::depth_share`]: GA's
/// from the body's apparent size in `camera`'s pixels and the frame's loss against the median frame's,
/// the simulation's from how far it is from GA across the line of sight in the frame and the frames
/// beside it). A switch to the simulation's depth wherever it followed the body across the line of
/// sight was right at 160×120 and wrong at 320×240, where GA's depth is the better one (the drop: 0.9 mm
/// against the simulation's 1.6). The simulation also misses a frame it draws the body visibly elsewhere in
/// than GA ([`SIMULATION_MISSES_BY_PX`] across the line of sight, its image loss above GA's). `radius`:
/// the body's bounding radius; `points`: points on its surface (body frame). `score` gives the image terms
/// of poses, one per frame (the frames not asked about are scored at the simulated pose and ignored).
pub fn reported_poses<E>(
    simulated: &[Pose<f64>],
    simulated_losses: &[ImageLoss],
    ga: &[FramePose],
    camera: &Camera<f64>,
    (radius, points): (f64, &[Vec3<f64>]),
    score: impl Fn(&[Pose<f64>]) -> std::result::Result<Vec<ImageLoss>, E>,
) -> std::result::Result<(Vec<Pose<f64>>, Vec<ReportedPose>), E> {
    let n = simulated.len();
    let eye = camera.center();
    // How far the simulation is from GA across the line of sight, m (frames GA did not fit: nothing): its
    // origin, and the body's points on average (a simulation turned away from GA's pose is off by its turn
    // however near its origin: the two-body block resting turned 28°, its origin 2.5 mm across and 6.8 mm
    // along the line of sight from the truth).
    // How far apart the two draw the body's points, px (frames GA did not fit: nothing).
    let apart_px: Vec<f64> = (0..n)
        .map(|k| {
            if ga[k].fitted {
                apart_across_px(&ga[k].pose, &simulated[k], points, camera)
            } else {
                0.0
            }
        })
        .collect();
    let across: Vec<f64> = (0..n)
        .map(|k| {
            if ga[k].fitted {
                let slid = crate::video_fit::toward_depth_of(&ga[k].pose, &simulated[k], eye, 1.0);
                let z = (ga[k].pose.t - eye).norm();
                (simulated[k].t - slid.t).norm().max(apart_px[k] * z / camera.k.fx)
            } else {
                0.0
            }
        })
        .collect();
    let median_loss =
        crate::poses_from_video::median_fitted_loss(ga.iter().map(|g| (g.image.loss, g.fitted))).unwrap_or(0.0);
    let weighed = |k: usize| {
        let z = (ga[k].pose.t - eye).norm();
        let loss_ratio = if median_loss > 0.0 {
            ga[k].image.loss / median_loss
        } else {
            1.0
        };
        let sim_across = across[k.saturating_sub(1)..(k + 2).min(n)]
            .iter()
            .cloned()
            .fold(0.0, f64::max);
        let share = crate::video_fit::depth_share(z, 2.0 * radius, camera.k.fx, loss_ratio, sim_across);
        crate::video_fit::toward_depth_of(&ga[k].pose, &simulated[k], eye, share)
    };
    let floor = loss_floor(ga).unwrap_or(f64::INFINITY);
    let missed: Vec<bool> = (0..n)
        .map(|k| {
            let (s, g) = (&simulated_losses[k], &ga[k]);
            let drawn_elsewhere =
                g.fitted && s.pixels > 0 && s.loss > g.image.loss && apart_px[k] > SIMULATION_MISSES_BY_PX;
            let misses = simulation_misses(s, g, floor);
            if g.fitted {
                tracing::debug!(
                    "frame {k}: simulated loss {:.5} IoU {:.3}, GA's {:.5} IoU {:.3}, floor {floor:.5}, apart {:.2} px{}",
                    s.loss,
                    s.iou(),
                    g.image.loss,
                    g.image.iou(),
                    apart_px[k],
                    if misses { ": missed (image)" } else if drawn_elsewhere { ": missed (drawn elsewhere)" } else { "" }
                );
            }
            misses || drawn_elsewhere
        })
        .collect();
    let mut poses = simulated.to_vec();
    let mut source = vec![ReportedPose::Simulated; n];
    if !missed.iter().any(|&m| m) {
        return Ok((poses, source));
    }
    // Scored where they may be reported; the other frames at the simulated pose, not looked at.
    let candidates: Vec<Pose<f64>> = (0..n)
        .map(|k| if missed[k] { weighed(k) } else { simulated[k] })
        .collect();
    let weighed_losses = score(&candidates)?;
    for k in (0..n).filter(|&k| missed[k]) {
        (poses[k], source[k]) = if simulation_misses(&weighed_losses[k], &ga[k], floor) {
            (ga[k].pose, ReportedPose::Ga)
        } else {
            (candidates[k], ReportedPose::GaAtWeighedDepth)
        };
    }
    Ok((poses, source))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::poses_from_video::StartFrom;
    use geom::Quat;

    fn ga_at(t: Vec3<f64>, loss: f64) -> FramePose {
        FramePose {
            pose: Pose::new(Quat::identity(), t),
            image: ImageLoss {
                loss,
                intersection: 95,
                union: 100,
                pixels: 400,
                ..ImageLoss::default()
            },
            contact_penalty: 0.0,
            in_contact: false,
            fitted: true,
            start: StartFrom::Physics,
        }
    }

    /// A 320 × 240 camera at the origin looking along +z, f = 290 px.
    fn camera_down_z() -> Camera<f64> {
        Camera {
            k: geom::Intrinsics::centred(290.0, 320, 240),
            world_to_cam: Pose::identity(),
            width: 320,
            height: 240,
        }
    }

    /// The corners of a box 60 × 40 × 40 mm (body frame).
    fn box_corners() -> Vec<Vec3<f64>> {
        (0..8)
            .map(|i| {
                let s = |bit: usize, h: f64| if i >> bit & 1 == 1 { h } else { -h };
                Vec3::new(s(0, 0.03), s(1, 0.02), s(2, 0.02))
            })
            .collect()
    }

    /// Image terms with the loss `loss` and GA's silhouette.
    fn terms(loss: f64) -> ImageLoss {
        ga_at(Vec3::new(0.0, 0.0, 0.0), loss).image
    }

    #[test]
    fn a_missed_frame_reports_ga_at_a_depth_weighed_by_what_ga_and_the_simulation_tell() {
        // The camera at the origin looks along +z (f = 290 px) at a body 0.4 m off (bounding radius 38 mm):
        // an edge is placed to 0.34 mm, GA's depth to 1.8 mm.
        let camera = camera_down_z();
        let radius = 0.038;
        let ga: Vec<FramePose> = (0..7)
            .map(|k| ga_at(Vec3::new(0.01 * k as f64, 0.0, 0.4), if k == 3 { 0.03 } else { 0.02 }))
            .collect();
        // The simulation: 10 mm deeper than GA everywhere; 1 mm across it in frames 0–3, 10 mm from frame 5.
        let simulated: Vec<Pose<f64>> = (0..7)
            .map(|k| {
                let across = if k >= 5 { 0.01 } else { 0.001 };
                Pose::new(Quat::identity(), ga[k].pose.t + Vec3::new(0.0, across, 0.01))
            })
            .collect();
        // It explains frame 0 (its own loss within 1.5 times GA's) and misses the others.
        let simulated_losses: Vec<ImageLoss> = (0..7).map(|k| terms(if k == 0 { 0.025 } else { 0.05 })).collect();
        let scored = std::cell::Cell::new(0);
        let score = |poses: &[Pose<f64>]| -> Result<Vec<ImageLoss>, ()> {
            scored.set(scored.get() + 1);
            // Slid poses explain their frames as GA's do, except frame 2's.
            Ok((0..poses.len())
                .map(|k| terms(if k == 2 { 0.05 } else { 0.021 }))
                .collect())
        };
        let (poses, source) =
            reported_poses(&simulated, &simulated_losses, &ga, &camera, (radius, &[]), score).unwrap();
        assert_eq!(scored.get(), 1);
        use ReportedPose::*;
        assert_eq!(
            source,
            vec![
                Simulated,
                GaAtWeighedDepth,
                Ga,
                GaAtWeighedDepth,
                GaAtWeighedDepth,
                GaAtWeighedDepth,
                GaAtWeighedDepth
            ]
        );
        assert_eq!(poses[0].t.to_array(), simulated[0].t.to_array());
        assert_eq!(poses[2].t.to_array(), ga[2].pose.t.to_array());
        // Every weighed pose on GA's line of sight, the share of the way to the simulation's depth told by
        // what each depth tells: most of it where the simulation follows across to 1 mm, more in frame 3
        // (GA explains it 1.5 times worse than the median frame: its depth counts less), little where the
        // simulation is 10 mm off across (frame 4 is beside frame 5).
        let share = |k: usize| {
            let dir = ga[k].pose.t * (1.0 / ga[k].pose.t.norm());
            assert!(
                dir.cross(poses[k].t * (1.0 / poses[k].t.norm())).norm() < 1e-12,
                "frame {k}"
            );
            (poses[k].t - ga[k].pose.t).dot(dir) / (simulated[k].t - ga[k].pose.t).dot(dir)
        };
        assert!(share(1) > 0.7 && share(1) < 0.8, "{}", share(1));
        assert!(share(3) > share(1) + 0.05, "{} {}", share(3), share(1));
        for k in 4..7 {
            assert!(share(k) < 0.05, "frame {k}: {}", share(k));
        }
    }

    #[test]
    fn a_simulation_drawing_the_body_elsewhere_misses_the_frame_whatever_its_silhouette_margin() {
        // The camera at the origin looks along +z (f = 290 px) at a box 60 × 40 × 40 mm, 0.4 m off: about
        // 45 px wide. The simulation explains every frame within the IoU margin and 1.5 times GA's loss.
        let (camera, corners) = (camera_down_z(), box_corners());
        let ga: Vec<FramePose> = (0..4).map(|_| ga_at(Vec3::new(0.0, 0.0, 0.4), 0.02)).collect();
        let turned = |deg: f64| Quat::exp(Vec3::new(0.0, 0.0, deg.to_radians()));
        let simulated = vec![
            // Turned 6° in the image (the corners 2.7 px off): drawn elsewhere.
            Pose::new(turned(6.0), ga[0].pose.t),
            // 10 mm deeper: the image tells that least, and it is weighed elsewhere.
            Pose::new(Quat::identity(), ga[1].pose.t + Vec3::new(0.0, 0.0, 0.01)),
            // Turned 1°: within an edge's precision.
            Pose::new(turned(1.0), ga[2].pose.t),
            // Turned 6° but explaining the image better than GA: kept.
            Pose::new(turned(6.0), ga[3].pose.t),
        ];
        let simulated_losses: Vec<ImageLoss> = [0.024, 0.024, 0.024, 0.019].map(terms).to_vec();
        let score = |poses: &[Pose<f64>]| -> Result<Vec<ImageLoss>, ()> { Ok(vec![terms(0.02); poses.len()]) };
        let apart = apart_across_px(&ga[0].pose, &simulated[0], &corners, &camera);
        assert!(apart > 2.5 && apart < 3.0, "{apart}");
        assert!(apart_across_px(&ga[1].pose, &simulated[1], &corners, &camera) < 1e-9);
        let (_, source) =
            reported_poses(&simulated, &simulated_losses, &ga, &camera, (0.036, &corners), score).unwrap();
        use ReportedPose::*;
        assert_eq!(source, vec![GaAtWeighedDepth, Simulated, Simulated, Simulated]);
        // Without the body's points (a caller that has none) only the margins count.
        let (_, source) = reported_poses(&simulated, &simulated_losses, &ga, &camera, (0.036, &[]), score).unwrap();
        assert_eq!(source, vec![Simulated; 4]);
    }

    #[test]
    fn a_simulation_turned_away_from_ga_tells_its_depth_little() {
        // The camera at the origin looks along +z (f = 290 px) at a box 60 × 40 × 40 mm, 0.4 m off. The
        // simulation misses the frame, 10 mm deeper than GA with its origin on GA's line of sight, turned 20°.
        let (camera, corners) = (camera_down_z(), box_corners());
        let ga = vec![ga_at(Vec3::new(0.0, 0.0, 0.4), 0.02)];
        let turned = Quat::exp(Vec3::new(0.0, 0.0, 20f64.to_radians()));
        let simulated = vec![Pose::new(turned, ga[0].pose.t + Vec3::new(0.0, 0.0, 0.01))];
        let simulated_losses = vec![terms(0.05)];
        let score = |poses: &[Pose<f64>]| -> Result<Vec<ImageLoss>, ()> { Ok(vec![terms(0.021); poses.len()]) };
        let share = |points: &[Vec3<f64>]| {
            let (poses, source) =
                reported_poses(&simulated, &simulated_losses, &ga, &camera, (0.036, points), score).unwrap();
            assert_eq!(source, vec![ReportedPose::GaAtWeighedDepth]);
            (poses[0].t.z - ga[0].pose.t.z) / 0.01
        };
        // Its corners are drawn about 10 mm from GA's: its depth counts little against GA's.
        assert!(share(&corners) < 0.05, "{}", share(&corners));
        // Without the body's points only its origin is compared, which GA's line of sight passes through.
        assert!(share(&[]) > 0.9, "{}", share(&[]));
    }

    #[test]
    fn in_a_frame_explained_worse_than_the_best_the_simulations_excess_is_held_to_the_best_frames_loss() {
        // Nine frames GA explains at 0.017 and one (a bounce under blur) at 0.033: the floor is 0.017.
        let mut ga: Vec<FramePose> = (0..10).map(|_| ga_at(Vec3::new(0.0, 0.0, 0.4), 0.017)).collect();
        ga[8].image.loss = 0.033;
        assert_eq!(loss_floor(&ga), Some(0.017));
        let floor = 0.017;
        // 0.047 is 1.42 times GA's 0.033, but 0.014 above it: more than half the best frames' loss.
        assert!(simulation_misses(&terms(0.047), &ga[8], floor));
        // 0.005 above it: within.
        assert!(!simulation_misses(&terms(0.038), &ga[8], floor));
        // In a frame explained as well as the best, the ratio to GA's own loss, as before.
        assert!(!simulation_misses(&terms(0.025), &ga[0], floor));
        assert!(simulation_misses(&terms(0.026), &ga[0], floor));
        // No floor (nothing fitted): GA's own loss.
        assert!(!simulation_misses(&terms(0.047), &ga[8], f64::INFINITY));
        assert_eq!(loss_floor(&[]), None);
    }
}
