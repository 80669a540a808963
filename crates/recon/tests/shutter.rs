//! A frame recorded over a shutter time: the image terms draw a moving body as the mean of its renders over
//! the shutter's sub-poses. Their pose gradient (each sub-pose's pulled back to the frame's pose) against
//! central differences, and a blurred frame's pose found again with the motion known and without it.

use geom::{Camera, Pose, Quat, SplitMix64, Vec3};
use neus::compose::{prerender_scene, render_composed, Behind, ComposedRay, Composer, Layer};
use neus::untrained_field::untrained_field;
use neus::{FieldInit, ObjectModel};
use recon::shutter::{shutter_poses, Motion};
use recon::{FrameTarget, ImageLossWeights, PoseFitConfig, PoseFromImage, PreparedFrame};

use crate::sphere_toy;
use sphere_toy::{camera, sphere_centre, toy};

const SHUTTER: f64 = 1.0 / 60.0;

/// The toy moving across the view at 0.9 m/s and turning: about 6 px of smear at 96 × 72 over 1/60 s.
fn motion() -> Motion {
    Motion {
        v: Vec3::new(0.6, 0.5, 0.4),
        omega: Vec3::new(3.0, -2.0, 5.0),
    }
}

/// The pose `dt` seconds after `pose` at `m` (held).
fn after(pose: &Pose<f64>, m: &Motion, dt: f64) -> Pose<f64> {
    Pose::new(
        (Quat::exp(m.omega * dt) * pose.q).normalize_or_identity(),
        pose.t + m.v * dt,
    )
}

/// The frame a camera records with the toy at `truth` moving at `m` over the shutter: the mean of renders at
/// 9 instants (finer than the fit's sub-poses); the mask where the body covers the pixel half the time.
fn blurred_frame(toy: &ObjectModel, behind: &[ComposedRay], cam: &Camera<f64>, truth: &Pose<f64>) -> FrameTarget {
    let m = motion();
    let mut composer = Composer::default();
    let instants = 9;
    let n = (cam.width * cam.height) as usize;
    let mut rgb = vec![[0.0f32; 3]; n];
    let mut cover = vec![0.0f32; n];
    for i in 0..instants {
        let pose = after(truth, &m, ((i as f64 + 0.5) / instants as f64 - 0.5) * SHUTTER);
        let layer = Layer::object(&toy.primary.field, &toy.primary.capture_from_body, &pose, 0);
        let img = render_composed(&[layer], 1, Behind::Scene(behind), cam, &mut composer);
        for (a, b) in rgb.iter_mut().zip(&img.rgb) {
            for k in 0..3 {
                a[k] += b[k] / instants as f32;
            }
        }
        for (c, o) in cover.iter_mut().zip(&img.object_opacity) {
            *c += o / instants as f32;
        }
    }
    let mask = cover.iter().map(|&c| c > 0.5).collect();
    FrameTarget {
        camera: *cam,
        rgb,
        mask,
        exposure: 1.0,
        shutter: SHUTTER,
        mask_computed: false,
    }
}

struct Rig {
    cam: Camera<f64>,
    toy: ObjectModel,
    behind: Vec<ComposedRay>,
    truth: Pose<f64>,
}

fn rig() -> Rig {
    let cam = camera(96, 72);
    let scene = untrained_field(FieldInit::Board, Vec3::new(0.0, 0.0, 0.05), 0.3, 7);
    let behind = prerender_scene(&scene, &cam, &mut Composer::default());
    Rig {
        cam,
        toy: toy(),
        behind,
        truth: Pose::new(Quat::exp(Vec3::new(0.0, 0.0, 0.4)), Vec3::new(0.01, 0.02, 0.0)),
    }
}

#[test]
#[ignore = "slow: 13 evaluations of some 3,000 pixels at four sub-poses, ~30 s"]
fn the_blurred_loss_gradient_matches_central_differences() {
    let r = rig();
    let frame = blurred_frame(&r.toy, &r.behind, &r.cam, &r.truth);
    let mut prepared = PreparedFrame::new(&frame, &r.behind).unwrap();
    prepared.set_motion(Some(motion()));
    // Off the truth, so that every term pulls.
    let pose = Pose::new(
        Quat::exp(Vec3::new(0.05, -0.04, 0.03)) * r.truth.q,
        r.truth.t + Vec3::new(0.003, -0.002, 0.002),
    );
    let subs = shutter_poses(&pose, Some(&motion()), SHUTTER, &r.cam, r.toy.mesh.bounds());
    assert!(subs.len() >= 3, "the toy smears over {} sub-poses", subs.len());
    // Every pixel of the window (in chunks, as `evaluate` renders them), every term: the silhouette terms
    // alone differ from differences by up to 80 % even drawn at the instant, since the renderer's samples
    // along a ray move with the pose (a 20 µm step shifts them); the colour terms dominate and are smooth
    // enough over some 3,000 pixels.
    let weights = ImageLossWeights {
        chromaticity: 5.0,
        ..ImageLossWeights::default()
    };
    let window = prepared.window(&r.toy, &pose, weights.margin_px).unwrap();
    let pixels = prepared.pixels(window, 0, &mut SplitMix64::new(0));
    let loss = |composer: &mut Composer, p: &Pose<f64>, grad: bool| {
        let mut total = (0.0, [0.0; 6]);
        for chunk in pixels.chunks(512) {
            let (l, g) = prepared.loss(composer, &r.toy, &r.behind, p, chunk, &weights, grad);
            let share = chunk.len() as f64 / pixels.len() as f64;
            total.0 += share * l.loss;
            for (a, b) in total.1.iter_mut().zip(g) {
                *a += share * b;
            }
        }
        total
    };
    let mut composer = Composer::default();
    let (_, analytic) = loss(&mut composer, &pose, true);
    // Central differences over steps large enough that the f32 renderer's noise stays small.
    let offsets = [-1.0, 1.0];
    for k in 0..6 {
        let base = if k < 3 { 4e-5 } else { 8e-4 };
        let mut slope = 0.0;
        for s in offsets {
            let mut e = [0.0; 6];
            e[k] = s * base;
            let p = Pose::new(
                Quat::exp(Vec3::new(e[3], e[4], e[5])) * pose.q,
                pose.t + Vec3::new(e[0], e[1], e[2]),
            );
            slope += s * loss(&mut composer, &p, false).0;
        }
        let fd = slope / (base * offsets.iter().map(|s| s * s).sum::<f64>());
        let block = if k < 3 { 0..3 } else { 3..6 };
        let scale = analytic[block].iter().map(|v| v * v).sum::<f64>().sqrt();
        let err = (analytic[k] - fd).abs() / scale;
        eprintln!(
            "component {k}: analytic {:.5e}, differences {fd:.5e}, error {err:.2e}",
            analytic[k]
        );
        assert!(
            err < 0.03,
            "component {k}: analytic {:.5e}, differences {fd:.5e}",
            analytic[k]
        );
    }
}

#[test]
fn a_blurred_frame_is_fitted_with_its_motion() {
    let r = rig();
    let frame = blurred_frame(&r.toy, &r.behind, &r.cam, &r.truth);
    let guess = Pose::new(
        Quat::exp(Vec3::new(0.05, -0.05, 0.1)) * r.truth.q,
        r.truth.t + Vec3::new(0.006, -0.004, 0.003),
    );
    let cfg = PoseFitConfig {
        iterations: 80,
        rays_per_step: 512,
        ..PoseFitConfig::default()
    };
    let off = |motion: Option<Motion>| {
        let mut fit = PoseFromImage::new(cfg.clone(), &r.toy, &r.behind, &frame, guess)
            .unwrap()
            .with_motion(motion);
        fit.run();
        let off = sphere_centre(&r.toy, &fit.pose) - sphere_centre(&r.toy, &r.truth);
        (off.norm(), fit.evaluate().iou())
    };
    let (with, iou_with) = off(Some(motion()));
    let (without, iou_without) = off(None);
    eprintln!(
        "sphere centre off by {:.2} mm with the motion (IoU {iou_with:.3}), {:.2} mm drawn at the instant (IoU {iou_without:.3})",
        with * 1e3,
        without * 1e3
    );
    assert!(with < 1.5e-3, "with the motion: {with} m");
    assert!(with < 0.7 * without, "the motion helps: {with} against {without} m");
}
