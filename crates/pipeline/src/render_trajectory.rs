//! `render --trajectory`: every frame of a motion, with reconstructed objects
//! at its poses inside a reconstructed scene, written as a video capture in
//! the NeuS layout (so it is itself an input of `train`, `fit` and NeuS tools)
//! plus an animation.

use super::objects::{load_objects, parse_objects};
use crate::cameras::{read_cameras, world_cameras};
use crate::error::{err, fail, Context};
use crate::images::{beside, read_mask, reference_frame, to8};
use crate::run_folder::checkpoint_of;
use crate::Result;
use crate::{note, Observer, Task};
use geom::{Pose, Quat, Vec3};
use neus::checkpoint::{load_field, LoadedField};
use neus::compose::{prerender_scene, render_composed, Behind, ComposedImage, Composer, Layer};
use neus::render_view::psnr;
use neus::ObjectModel;
use pganeus_io::{CameraMats, CaptureInfo, CaptureKind, Image};
use std::path::Path;
use std::sync::Arc;

/// What `render --trajectory` needs (parsed by `render`'s arguments).
pub struct TrajectoryJob<'a> {
    pub trajectory: &'a Path,
    pub video: Option<&'a str>,
    pub scene: Option<&'a Path>,
    pub objects: &'a [String],
    pub views: Option<&'a Path>,
    pub camera: Option<&'a Path>,
    pub side_by_side: Option<&'a Path>,
    pub orbit_deg: Option<f64>,
    pub reference_compositing: bool,
    /// Where to write (a staged folder swapped in by the caller).
    pub out: &'a Path,
    /// The folder as the user named it, for messages.
    pub shown_as: &'a Path,
}

/// One body's poses, in its object folder's body frame.
pub struct BodyMotion {
    pub name: String,
    pub poses: Vec<Pose<f64>>,
}

/// The motion to render: a `trajectory.json` (poses of each object's own body frame) or a `videos[]` entry
/// of a `truth.json` (poses of the true meshes' frames, carried onto each object's body frame through the
/// static capture the object's reference was taken in).
pub fn read_motion(
    path: &Path,
    video: Option<&str>,
    objects: &[(String, Arc<ObjectModel>)],
) -> Result<(f64, String, Vec<BodyMotion>)> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let value: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{}", path.display()))?;
    if value.get("videos").is_none() {
        if video.is_some() {
            fail!(
                Input,
                "{}: --video picks a video of a truth.json; this is a trajectory",
                path.display()
            );
        }
        let t = pganeus_io::read_trajectory_bytes(text.as_bytes(), path)?;
        let bodies = t
            .bodies
            .iter()
            .map(|b| BodyMotion {
                name: b.name.clone(),
                poses: b.poses.iter().map(pganeus_io::Pose::to_geom).collect(),
            })
            .collect();
        return Ok((t.fps, t.capture, bodies));
    }
    let truth = pganeus_io::read_truth_bytes(text.as_bytes(), path)?;
    let v = match video {
        Some(name) => truth
            .video(name)
            .ok_or_else(|| err!(Input, "{}: no video named {name:?}", path.display()))?,
        None if truth.videos.len() == 1 => &truth.videos[0],
        None => fail!(
            Input,
            "{}: a truth.json with {} videos: pick one with --video ({})",
            path.display(),
            truth.videos.len(),
            truth
                .videos
                .iter()
                .map(|v| v.capture.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut bodies = Vec::new();
    for b in &v.bodies {
        let Some((_, model)) = objects.iter().find(|(n, _)| *n == b.name) else {
            bodies.push(BodyMotion {
                name: b.name.clone(),
                poses: vec![],
            });
            continue;
        };
        let tb = truth.body(&b.name).ok_or_else(|| {
            err!(
                Input,
                "{}: body {:?} of the video is not in bodies[]",
                path.display(),
                b.name
            )
        })?;
        let sc = tb
            .static_captures
            .iter()
            .find(|s| s.capture == model.reference_capture)
            .ok_or_else(|| {
                err!(
                    Input,
                    "{}: body {:?} has no static capture named {:?} (the capture the object {} was reconstructed in)",
                    path.display(),
                    b.name,
                    model.reference_capture,
                    model.source.display()
                )
            })?;
        // world_k = H_k · truth_body = H_k · P_capture⁻¹ · reference · object_body.
        let to_object = sc.pose.to_geom().inverse().compose(&model.reference_pose);
        bodies.push(BodyMotion {
            name: b.name.clone(),
            poses: b.poses.iter().map(|p| p.to_geom().compose(&to_object)).collect(),
        });
    }
    Ok((v.fps, v.capture.clone(), bodies))
}

fn mask_image(w: u32, h: u32, inside: impl Fn(usize) -> bool) -> Image {
    let mut m = Image::new(w, h, 1);
    for (p, v) in m.data.iter_mut().enumerate() {
        *v = if inside(p) { 255 } else { 0 };
    }
    m
}

/// Intersection over union of two binary masks (1 when both are empty).
fn iou(a: &[bool], b: &[bool]) -> f64 {
    let inter = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let union = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

pub fn run(job: TrajectoryJob<'_>, observer: &dyn Observer) -> Result<()> {
    let t0 = std::time::Instant::now();
    if job.objects.is_empty() {
        fail!(Stage, "give at least one --object NAME=DIR");
    }
    let named = parse_objects(job.objects)?;
    let objects = load_objects(&named, 0)?;
    for ((name, dir), (_, model)) in named.iter().zip(&objects) {
        tracing::info!(
            "object {name}: {} ({}; body frame at the centre of mass in {})",
            dir.display(),
            if model.other.is_some() {
                "two fields, switched by the camera's side"
            } else {
                "one field"
            },
            model.reference_capture
        );
    }
    let (fps, capture_name, motion) = read_motion(job.trajectory, job.video, &objects)?;
    for (name, _) in &objects {
        if !motion.iter().any(|m| &m.name == name) {
            fail!(
                Input,
                "{}: no body named {name:?} (bodies: {})",
                job.trajectory.display(),
                motion.iter().map(|m| m.name.as_str()).collect::<Vec<_>>().join(", ")
            );
        }
    }
    // Bodies of the motion without an object folder are left out, and said so.
    let bodies: Vec<(&BodyMotion, &ObjectModel)> = motion
        .iter()
        .filter_map(|m| {
            let o = objects.iter().find(|(n, _)| *n == m.name).map(|(_, o)| o);
            if o.is_none() {
                tracing::warn!("body {:?} has no --object: not rendered", m.name);
            }
            o.map(|o| (m, &**o))
        })
        .collect();
    let frames = bodies.iter().map(|(m, _)| m.poses.len()).max().unwrap_or(0);
    if frames == 0 || bodies.iter().any(|(m, _)| m.poses.len() != frames) {
        fail!(
            Input,
            "{}: every body needs the same number of poses (at least one)",
            job.trajectory.display()
        );
    }
    let (mut reference, mut cameras) = match (job.views, job.camera) {
        (Some(dir), None) => {
            let c = pganeus_io::open_capture(dir)?;
            let cams = world_cameras(&c)?;
            (Some((dir.to_path_buf(), c)), cams)
        }
        (None, Some(path)) => (None, read_cameras(path)?),
        _ => fail!(Stage, "give --views VIDEO_CAPTURE or --camera cams.json"),
    };
    if let Some(deg) = job.orbit_deg {
        // A new viewpoint: nothing to compare with.
        reference = None;
        let turn = Pose::new(
            Quat::exp(Vec3::new(0.0, 0.0, deg.to_radians())),
            Vec3::new(0.0, 0.0, 0.0),
        );
        for c in &mut cameras {
            c.world_to_cam = c.world_to_cam.compose(&turn.inverse());
        }
    }
    if cameras.len() != 1 && cameras.len() != frames {
        fail!(
            Input,
            "{} cameras for {frames} frames: give one camera, or one per frame",
            cameras.len()
        );
    }
    let scene: Option<LoadedField> = job.scene.map(|p| load_field(&checkpoint_of(p))).transpose()?;
    let background = [1.0f32; 3];
    // A fixed camera sees the same scene in every frame: render it once and composite the objects over it.
    let fixed = cameras.iter().all(|c| c.world_mat() == cameras[0].world_mat());
    let mut composer = Composer::default();
    let prerendered = match &scene {
        Some(s) if fixed && !job.reference_compositing => {
            let t = std::time::Instant::now();
            let pre = prerender_scene(s, &cameras[0], &mut composer);
            tracing::info!(
                "fixed camera: the scene rendered once ({:.1} s), objects composited over it",
                t.elapsed().as_secs_f64()
            );
            Some(pre)
        }
        _ => None,
    };

    let out = job.out;
    let images = out.join("image");
    std::fs::create_dir_all(&images).with_context(|| format!("cannot create {}", images.display()))?;
    let (w, h) = (cameras[0].width, cameras[0].height);
    let pb = Task::start(observer, "render", frames as u64);
    let mut anim = Vec::with_capacity(frames);
    let mut mats = Vec::with_capacity(frames);
    let mut rows = Vec::new();
    let (centre, radius) = scene
        .as_ref()
        .map_or((Vec3::new(0.0, 0.0, 0.0), 1.0), |s| (s.centre, s.radius));
    let scale_mat = [
        [radius, 0.0, 0.0, centre.x],
        [0.0, radius, 0.0, centre.y],
        [0.0, 0.0, radius, centre.z],
        [0.0, 0.0, 0.0, 1.0],
    ];
    for k in 0..frames {
        let cam = cameras[if cameras.len() == 1 { 0 } else { k }];
        if (cam.width, cam.height) != (w, h) {
            fail!(Stage, "camera {k} is {}×{}, camera 0 {w}×{h}", cam.width, cam.height);
        }
        let (mut layers, behind): (Vec<Layer<'_>>, _) = match &prerendered {
            Some(pre) => (Vec::new(), Behind::Scene(pre)),
            None => (scene.iter().map(Layer::scene).collect(), Behind::Colour(background)),
        };
        for (i, (m, model)) in bodies.iter().enumerate() {
            let routed = model.route(&m.poses[k], &cam);
            layers.push(Layer::object(&routed.field, &routed.capture_from_body, &m.poses[k], i));
        }
        let img: ComposedImage = render_composed(&layers, bodies.len(), behind, &cam, &mut composer);
        let file = format!("{k:03}.png");
        let mut rgb = Image::new(w, h, 3);
        for (p, c) in img.rgb.iter().enumerate() {
            rgb.data[p * 3..p * 3 + 3].copy_from_slice(&c.map(to8));
        }
        let n_obj = bodies.len();
        let visible = |p: usize, i: usize| img.object_opacity[p * n_obj + i] > 0.5;
        pganeus_io::write_png(&images.join(&file), &rgb)?;
        pganeus_io::write_png(
            &out.join("mask").join(&file),
            &mask_image(w, h, |p| (0..n_obj).any(|i| visible(p, i))),
        )?;
        for (i, (m, _)) in bodies.iter().enumerate() {
            pganeus_io::write_png(
                &out.join(format!("mask_{}", m.name)).join(&file),
                &mask_image(w, h, |p| visible(p, i)),
            )?;
        }
        mats.push(CameraMats {
            world_mat: cam.world_mat(),
            scale_mat,
        });
        // Against the video, where it was given.
        if let Some((_, c)) = &reference {
            if let Some(path) = c.images.get(k) {
                let gt = reference_frame(path)?;
                let p = psnr(&img.rgb, &gt, None);
                let mut row = serde_json::json!({"frame": k, "psnr": (p as f64 * 100.0).round() / 100.0});
                for (i, (m, _)) in bodies.iter().enumerate() {
                    // The body's own mask folder, or `mask/` when the video has one body.
                    let own = c.extra_masks.iter().find(|(n, _)| *n == m.name).map(|(_, v)| &v[k]);
                    let single = (bodies.len() == 1).then(|| c.masks.as_ref().map(|v| &v[k])).flatten();
                    if let Some(path) = own.or(single) {
                        let truth = read_mask(path)?;
                        let ours: Vec<bool> = (0..(w * h) as usize).map(|p| visible(p, i)).collect();
                        row[format!("iou_{}", m.name)] = serde_json::json!((iou(&ours, &truth) * 1e4).round() / 1e4);
                    }
                }
                rows.push(row);
            }
        }
        anim.push(rgb);
        pb.inc(1);
    }
    pb.finish();
    pganeus_io::write_cameras_npz(&out.join("cameras_sphere.npz"), &mats)?;
    pganeus_io::write_capture_info(
        &out.join("capture.json"),
        &CaptureInfo {
            kind: CaptureKind::Video,
            subject: None,
            fps: Some(fps),
            shutter: None,
            extra: Default::default(),
        },
    )?;
    let anim_frames = match job.side_by_side {
        Some(dir) => side_by_side(dir, &anim)?,
        None => anim,
    };
    pganeus_io::write_apng(&out.join("animation.png"), &anim_frames, fps)?;
    let mp4 = encode_mp4(out, fps);
    if !rows.is_empty() {
        let mean = |key: &str| {
            let v: Vec<f64> = rows.iter().filter_map(|r| r[key].as_f64()).collect();
            (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
        };
        let mut summary = serde_json::json!({"capture": capture_name, "frames": rows, "mean_psnr": mean("psnr")});
        for (m, _) in &bodies {
            let key = format!("iou_{}", m.name);
            let v: Vec<f64> = rows.iter().filter_map(|r| r[&key].as_f64()).collect();
            if !v.is_empty() {
                summary[format!("mean_{key}")] = serde_json::json!(v.iter().sum::<f64>() / v.len() as f64);
                summary[format!("min_{key}")] = serde_json::json!(v.iter().cloned().fold(f64::INFINITY, f64::min));
            }
        }
        pganeus_io::write_atomic(
            &out.join("metrics.json"),
            serde_json::to_string_pretty(&summary)?.as_bytes(),
        )?;
        note(
            observer,
            format!(
                "against {}: mean PSNR {:.2} dB{}",
                reference
                    .as_ref()
                    .map(|(d, _)| d.display().to_string())
                    .unwrap_or_default(),
                mean("psnr").unwrap_or(f64::NAN),
                bodies
                    .iter()
                    .filter_map(|(m, _)| {
                        let k = format!("iou_{}", m.name);
                        summary
                            .get(format!("mean_{k}"))
                            .and_then(|v| v.as_f64())
                            .map(|v| format!(", {} IoU mean {v:.3} min {:.3}", m.name, summary[format!("min_{k}")]))
                    })
                    .collect::<String>()
            ),
        );
    }
    note(
        observer,
        format!(
            "rendered {frames} frames of {w}×{h} in {:.1} s into {} (animation.png{})",
            t0.elapsed().as_secs_f64(),
            job.shown_as.display(),
            if mp4 { ", video.mp4" } else { "" }
        ),
    );
    Ok(())
}

/// Each rendered frame beside the same frame of a capture (same height).
fn side_by_side(dir: &Path, ours: &[Image]) -> Result<Vec<Image>> {
    let c = pganeus_io::open_capture(dir)?;
    if c.images.len() < ours.len() {
        fail!(
            Settings,
            "--side-by-side {}: {} images for {} frames",
            dir.display(),
            c.images.len(),
            ours.len()
        );
    }
    ours.iter()
        .zip(&c.images)
        .map(|(a, path)| {
            let b = pganeus_io::read_image(path)?;
            if b.height != a.height {
                fail!(
                    Settings,
                    "--side-by-side {}: images are {} high, the rendering {}",
                    dir.display(),
                    b.height,
                    a.height
                );
            }
            Ok(beside(&b, a))
        })
        .collect()
}

/// `video.mp4` from `image/` when ffmpeg is on PATH (true if written).
fn encode_mp4(out: &Path, fps: f64) -> bool {
    let status = std::process::Command::new("ffmpeg")
        .args(["-y", "-loglevel", "error", "-framerate"])
        .arg(format!("{fps}"))
        .arg("-i")
        .arg(out.join("image").join("%03d.png"))
        .args(["-pix_fmt", "yuv420p", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2"])
        .arg(out.join("video.mp4"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status();
    matches!(status, Ok(s) if s.success())
}
