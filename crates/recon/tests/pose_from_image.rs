//! The first-pose stage: an object rendered in its scene at a known pose is
//! found again from a guess 2 cm off (a third of its size) and turned, by the
//! composed renderer's pose gradients of colour and silhouette.

use geom::Camera;
use geom::{Pose, Quat, Vec3};
use neus::compose::{prerender_scene, render_composed, Behind, ComposedImage, ComposedRay, Composer, Layer};
use neus::object_model::ObjectField;
use neus::untrained_field::untrained_field;
use neus::{FieldInit, ObjectModel};
use recon::{FrameError, FrameTarget, PoseFitConfig, PoseFitError, PoseFromImage};
use std::path::PathBuf;

use crate::sphere_toy;
use sphere_toy::{bounds_mesh, camera, sphere_centre, toy};

/// The sphere toy rendered on an untrained board at a known pose through a 96 × 72 camera: the camera, the
/// toy, the board pre-rendered through it, the true pose and the frame's colours and the toy's opacity.
fn toy_on_the_board() -> (Camera<f64>, ObjectModel, Vec<ComposedRay>, Pose<f64>, ComposedImage) {
    let cam = camera(96, 72);
    let scene = untrained_field(FieldInit::Board, Vec3::new(0.0, 0.0, 0.05), 0.3, 7);
    let toy = toy();
    let mut composer = Composer::default();
    let behind = prerender_scene(&scene, &cam, &mut composer);
    let truth = Pose::new(Quat::exp(Vec3::new(0.0, 0.0, 0.4)), Vec3::new(0.01, 0.02, 0.0));
    let layer = Layer::object(&toy.primary.field, &toy.primary.capture_from_body, &truth, 0);
    let img = render_composed(&[layer], 1, Behind::Scene(&behind), &cam, &mut composer);
    (cam, toy, behind, truth, img)
}

#[test]
fn the_first_pose_is_found_from_a_guess_two_centimetres_off() {
    let (cam, toy, behind, truth, img) = toy_on_the_board();
    let frame = FrameTarget {
        camera: cam,
        rgb: img.rgb.clone(),
        mask: img.object_opacity.iter().map(|&o| o > 0.5).collect(),
        exposure: 1.0,
        shutter: 0.0,
        mask_computed: false,
    };
    assert!(
        frame.mask.iter().filter(|&&m| m).count() > 300,
        "the toy covers a fair part of the image"
    );

    let guess = Pose::new(
        Quat::exp(Vec3::new(0.1, -0.15, 0.4 + 0.2)),
        truth.t + Vec3::new(0.015, -0.01, 0.008),
    );
    let cfg = PoseFitConfig {
        iterations: 80,
        rays_per_step: 512,
        ..PoseFitConfig::default()
    };
    let mut fit = PoseFromImage::new(cfg, &toy, &behind, &frame, guess).expect("a valid frame");
    let before = fit.evaluate();
    let stats = fit.run();
    let after = fit.evaluate();
    let (iou_before, iou_after) = (before.iou(), after.iou());
    let err = |p: &Pose<f64>| (sphere_centre(&toy, p) - sphere_centre(&toy, &truth)).norm();
    eprintln!(
        "loss {:.4} -> {:.4}, IoU {iou_before:.3} -> {iou_after:.3}, sphere centre off by {:.1} -> {:.1} mm ({} steps)",
        before.loss,
        after.loss,
        err(&guess) * 1e3,
        err(&fit.pose) * 1e3,
        stats.len()
    );
    assert!(
        iou_before < 0.7 && err(&guess) > 0.015,
        "the guess is well off: IoU {iou_before}"
    );
    assert!(
        after.loss < 0.2 * before.loss,
        "the loss falls: {} -> {}",
        before.loss,
        after.loss
    );
    assert!(iou_after > 0.95, "the silhouette is matched: IoU {iou_after}");
    assert!(
        err(&fit.pose) < 2e-3,
        "the object is back where it was: {} m",
        err(&fit.pose)
    );
}

#[test]
fn frames_that_do_not_fit_the_camera_are_refused() {
    let cam = camera(8, 6);
    let toy = toy();
    let scene = vec![neus::compose::ComposedRay::default(); 48];
    let good = FrameTarget {
        camera: cam,
        rgb: vec![[0.0; 3]; 48],
        mask: vec![false; 48],
        exposure: 1.0,
        shutter: 0.0,
        mask_computed: false,
    };
    let cfg = PoseFitConfig::default;
    assert_eq!(
        PoseFromImage::new(cfg(), &toy, &scene, &good, Pose::identity()).err(),
        Some(PoseFitError::EmptyMask)
    );
    let short = FrameTarget {
        rgb: vec![[0.0; 3]; 47],
        ..good
    };
    assert_eq!(
        PoseFromImage::new(cfg(), &toy, &scene, &short, Pose::identity()).err(),
        Some(PoseFitError::Frame(FrameError::ImageSize { got: 47, want: 48 }))
    );
}

/// A second ball between the camera and the toy, hiding part of it: the toy's mask is what shows. Drawn
/// where it stands (an occluder), it lets the toy's true pose explain the frame and the fit find it again;
/// without it, the hidden part of the toy covers pixels its mask leaves out.
#[test]
fn a_body_half_hidden_by_another_is_found_with_the_other_drawn() {
    use recon::image_loss::Occluder;
    let (w, h) = (96, 72);
    let cam = camera(w, h);
    let scene = untrained_field(FieldInit::Board, Vec3::new(0.0, 0.0, 0.05), 0.3, 7);
    let toy = toy();
    let ball = ObjectModel {
        source: PathBuf::from("untrained"),
        primary: ObjectField {
            field: untrained_field(FieldInit::Sphere, Vec3::new(0.0, 0.0, 0.03), 0.06, 5),
            capture_from_body: Pose::from_translation(Vec3::new(0.0, 0.0, 0.03)),
        },
        other: None,
        mesh: bounds_mesh(0.03),
        mesh_bounds: bounds_mesh(0.03).bounds(),
        volume: 1e-4,
        reference_capture: "ball_b".into(),
        reference_pose: Pose::identity(),
    };
    let mut composer = Composer::default();
    let behind = prerender_scene(&scene, &cam, &mut composer);
    let truth = Pose::new(Quat::exp(Vec3::new(0.0, 0.0, 0.4)), Vec3::new(0.01, 0.02, 0.0));
    // A quarter of the way to the camera, shifted sideways by most of the toy's width.
    let c = sphere_centre(&toy, &truth);
    let to_cam = cam.center() - c;
    let side = to_cam
        .cross(Vec3::new(0.0, 0.0, 1.0))
        .normalize_or(Vec3::new(1.0, 0.0, 0.0))
        * 0.035;
    let ball_pose = Pose::from_translation(c + to_cam * 0.25 + side);
    let layers = [
        Layer::object(&toy.primary.field, &toy.primary.capture_from_body, &truth, 0),
        Layer::object(&ball.primary.field, &ball.primary.capture_from_body, &ball_pose, 1),
    ];
    let img = render_composed(&layers, 2, Behind::Scene(&behind), &cam, &mut composer);
    let frame = FrameTarget {
        camera: cam,
        rgb: img.rgb.clone(),
        mask: (0..(w * h) as usize).map(|p| img.object_opacity[p * 2] > 0.5).collect(),
        exposure: 1.0,
        shutter: 0.0,
        mask_computed: false,
    };
    let shown = frame.mask.iter().filter(|&&m| m).count();
    let ball_shown = (0..(w * h) as usize)
        .filter(|&p| img.object_opacity[p * 2 + 1] > 0.5)
        .count();
    assert!(shown > 150 && ball_shown > 150, "{shown} {ball_shown}");
    let occluders = vec![Occluder {
        object: &ball,
        pose: ball_pose,
    }];
    let cfg = PoseFitConfig {
        iterations: 80,
        rays_per_step: 512,
        ..PoseFitConfig::default()
    };
    // At the truth, the frame is explained only with the ball drawn.
    let at_truth = |with: bool| {
        let f = PoseFromImage::new(cfg.clone(), &toy, &behind, &frame, truth).unwrap();
        let mut f = if with { f.with_occluders(occluders.clone()) } else { f };
        f.evaluate()
    };
    let (with, without) = (at_truth(true), at_truth(false));
    eprintln!(
        "at the truth: loss {:.4} (IoU {:.3}) with the ball drawn, {:.4} (IoU {:.3}) without",
        with.loss,
        with.iou(),
        without.loss,
        without.iou()
    );
    assert!(
        with.iou() > 0.97 && without.iou() < 0.9,
        "{} {}",
        with.iou(),
        without.iou()
    );
    // The ball is drawn once per pixel and kept (it stands still while the toy is fitted): the frame at the
    // truth is then the frame itself, bit for bit, as often as it is drawn.
    let mut at = PoseFromImage::new(cfg.clone(), &toy, &behind, &frame, truth)
        .unwrap()
        .with_occluders(occluders.clone());
    for _ in 0..2 {
        assert_eq!(at.evaluate().mse, 0.0, "the ball from the cache is the ball drawn");
    }
    let guess = Pose::new(
        Quat::exp(Vec3::new(0.05, -0.1, 0.4 + 0.15)),
        truth.t + Vec3::new(0.01, -0.008, 0.006),
    );
    let err = |p: &Pose<f64>| (sphere_centre(&toy, p) - sphere_centre(&toy, &truth)).norm();
    let mut fit = PoseFromImage::new(cfg.clone(), &toy, &behind, &frame, guess)
        .unwrap()
        .with_occluders(occluders.clone());
    fit.run();
    let e_with = err(&fit.pose);
    // Measured (2026-11-25): 14.4 mm off at the guess, 0.41 mm after; the same fit without the ball drawn
    // ended 6.8 mm off (the hidden half pulled toward the visible one).
    eprintln!(
        "sphere centre off by {:.1} mm from the guess, {:.2} mm after",
        err(&guess) * 1e3,
        e_with * 1e3
    );
    assert!(e_with < 2e-3, "{e_with} m");
}

/// A computed mask takes every pixel a body touches, a ring of a pixel too large; fitted to it as to a drawn
/// mask, the silhouette pulls the body toward the camera to fill the ring. Marked as computed, its edge is
/// left to the colours, and the body stays where the image shows it.
#[test]
fn a_computed_masks_edge_is_left_to_the_colours() {
    let (cam, toy, behind, truth, img) = toy_on_the_board();
    let drawn: Vec<bool> = img.object_opacity.iter().map(|&o| o > 0.5).collect();
    let ring = geom::mask::dilate(&drawn, cam.width as usize, 1);
    let guess = Pose::new(truth.q, truth.t + Vec3::new(0.004, -0.003, 0.002));
    let cfg = PoseFitConfig {
        iterations: 80,
        rays_per_step: 512,
        ..PoseFitConfig::default()
    };
    let eye = cam.world_to_cam.inverse().t;
    let err = |p: &Pose<f64>| {
        let (a, b) = (sphere_centre(&toy, p), sphere_centre(&toy, &truth));
        // Along the line of sight, positive toward the camera.
        ((b - a).dot((eye - b) * (1.0 / (eye - b).norm())), (a - b).norm())
    };
    let fitted = |mask_computed: bool| {
        let frame = FrameTarget {
            camera: cam,
            rgb: img.rgb.clone(),
            mask: ring.clone(),
            exposure: 1.0,
            shutter: 0.0,
            mask_computed,
        };
        let mut fit = PoseFromImage::new(cfg.clone(), &toy, &behind, &frame, guess).expect("a valid frame");
        fit.run();
        err(&fit.pose)
    };
    let (drawn_like, computed) = (fitted(false), fitted(true));
    eprintln!(
        "toward the camera / off: as a drawn mask {:.2} / {:.2} mm, as a computed one {:.2} / {:.2} mm",
        -drawn_like.0 * 1e3,
        drawn_like.1 * 1e3,
        -computed.0 * 1e3,
        computed.1 * 1e3
    );
    assert!(
        computed.1 < 0.7 * drawn_like.1 && computed.1 < 1.5e-3,
        "as a computed mask {:.2} mm off, as a drawn one {:.2} mm",
        computed.1 * 1e3,
        drawn_like.1 * 1e3
    );
}
