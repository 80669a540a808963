//! PA: a block tossed onto the board, filmed by a fixed camera; its launch
//! velocity and friction come back from the frames alone (rendered with the
//! true values), through the renderer's pose gradients chained with the
//! simulator's exact derivatives. (Tossed from 2 cm up: a block launched
//! while touching the board has a launch speed into the board that nothing
//! shows, and friction turns it into a slower slide.) It slides to rest, so
//! friction shows in every frame after the landing (a ball would roll after
//! two frames whatever its friction).

use crate::common;
use common::*;
use geom::Vec3;
use recon::{FrameTarget, PhysicsFromVideo, VideoPhysicsConfig, VideoPhysicsError};
use sim::ContactParams;

#[test]
fn launch_velocity_and_friction_come_back_from_the_frames() {
    let ball = ball_model();
    let v0 = V0;
    let (behind, frames) = film(&ball, &world(v0, TRUTH));
    let shown = frames
        .iter()
        .filter(|f| f.mask.iter().filter(|&&m| m).count() > 100)
        .count();
    assert_eq!(shown, frames.len(), "the ball is in view in every frame");

    let guess = world(
        [0.42, 0.1, 0.15],
        ContactParams {
            restitution: 0.3,
            friction: 0.5,
        },
    );
    let cfg = VideoPhysicsConfig {
        iterations: 200,
        rays_per_frame: 256,
        window_steps: 40,
        fit_angular_velocity: false,
        fit_restitution: false,
        ..VideoPhysicsConfig::default()
    };
    let mut fit = PhysicsFromVideo::new(cfg, &ball, &behind, &frames, guess.clone(), 0).expect("valid frames");
    let before: f64 = fit.evaluate().iter().map(|l| l.loss).sum();
    let stats = fit.run();
    let after_frames = fit.evaluate();
    let after: f64 = after_frames.iter().map(|l| l.loss).sum();
    let fitted = fit.fitted_world();
    let p = fitted.params();
    let o = fitted.body_param_offset(0);
    let v = Vec3::new(p[o + 6], p[o + 7], p[o + 8]);
    let v_err = (v - Vec3::cst(v0)).norm() / Vec3::<f64>::cst(v0).norm();
    let worst_iou = after_frames.iter().map(|l| l.iou()).fold(1.0, f64::min);
    eprintln!(
        "loss {before:.4} -> {after:.4} ({} steps, last window {}); v0 {:?} (error {:.1} %), friction {:.3}, worst IoU {worst_iou:.3}",
        stats.len(),
        stats.last().map_or(0, |s| s.window),
        v.to_array(),
        v_err * 100.0,
        p[o + 13]
    );
    assert!(after < 0.3 * before, "the loss falls: {before} -> {after}");
    assert!(v_err < 0.05, "v0 within 5 %: {:?}", v.to_array());
    assert!((p[o + 13] - 0.3).abs() < 0.1, "friction within 0.1: {}", p[o + 13]);
    assert!(worst_iou > 0.9, "every frame's silhouette: worst IoU {worst_iou}");
    // Windows end once their loss stops falling (measured: 85 steps of the 200 allowed, the same loss and
    // v0 as all 200: 0.1031 against 0.1038, 3.7 % against 3.8 %).
    assert!(stats.len() < 150, "{} steps", stats.len());
}

#[test]
fn frames_of_the_wrong_size_are_refused_by_index() {
    let cam = camera();
    let ball = ball_model();
    let n = (cam.width * cam.height) as usize;
    let scene = vec![neus::compose::ComposedRay::default(); n];
    let frame = |pixels: usize| FrameTarget {
        camera: cam,
        rgb: vec![[0.0; 3]; pixels],
        mask: vec![false; n],
        exposure: 1.0,
        shutter: 0.0,
        mask_computed: false,
    };
    let frames = vec![frame(n), frame(n), frame(n - 1)];
    let c = ContactParams::default();
    let err = PhysicsFromVideo::new(
        VideoPhysicsConfig::default(),
        &ball,
        &scene,
        &frames,
        world([0.0; 3], c),
        0,
    )
    .err();
    assert!(
        matches!(err, Some(VideoPhysicsError::Frame { frame: 2, .. })),
        "{err:?}"
    );
    let one = vec![frame(n)];
    let err = PhysicsFromVideo::new(
        VideoPhysicsConfig::default(),
        &ball,
        &scene,
        &one,
        world([0.0; 3], c),
        0,
    )
    .err();
    assert_eq!(err, Some(VideoPhysicsError::TooFewFrames(1)));
}
