//! Making a dataset: simulate each video, render every capture, and write
//! the NeuS-layout folders, meshes and `truth.json`.

use crate::build::{
    body_object, build_bodies, build_static, field, resting_pose, unit_quat, Bodies, StaticScene, SynthError,
};
use crate::cameras::{framed_orbit, framing_distance, hemisphere_views, intrinsics, orbit, scale_mat};
use crate::desc::{Physics, SynthScene};
use crate::rapier_motion::simulate_with_rapier;
use crate::render::{render, render_instants, scene_distance, RenderScene, Rendered};
use geom::{Camera, TriMesh, Vec3};
use pganeus_io::{
    CameraMats, CaptureInfo, CaptureKind, CaptureSubject, Image, PlyEncoding, PlyMesh, Pose as IoPose, StaticCapture,
    Truth, TruthBody,
};
use sim::{BodyState, SimConfig, World};
use std::path::{Path, PathBuf};

/// The share of each image side left free around a scene's board and
/// obstacles in its background views.
const SCENE_BORDER: f64 = 0.06;

/// One capture to render: its cameras and what they see.
struct CapturePlan {
    name: String,
    kind: CaptureKind,
    /// What a static capture shows (written to capture.json).
    subject: Option<CaptureSubject>,
    fps: Option<f64>,
    cameras: Vec<Camera<f64>>,
    /// One scene per image (videos move), or one for all.
    scenes: Vec<RenderScene>,
    region: (Vec3<f64>, f64),
    /// Mask folders: `mask` holds these bodies; `mask_<name>` one each.
    mask_bodies: Vec<usize>,
    per_body_masks: bool,
    /// Raw footage of a video: each frame's instants over the raw shutter time (motion blur); empty otherwise.
    raw_instants: Vec<Vec<RenderScene>>,
    /// A camera-like video: each frame's instants over its shutter time, the middle one the frame's; empty
    /// otherwise.
    instants: Vec<Vec<RenderScene>>,
    /// A camera-like video's shutter time, seconds (capture.json's `shutter`).
    shutter: Option<f64>,
}

/// What `generate` made.
#[derive(Clone, Debug)]
pub struct Summary {
    pub captures: Vec<(String, usize)>,
    pub images: usize,
}

/// Progress: capture name, images done in it, images in it.
pub type OnImage<'a> = &'a mut dyn FnMut(&str, usize, usize);

/// Simulate the videos of `scene`. Returns the world and trajectory of each.
pub fn simulate_videos(scene: &SynthScene, base: &Path) -> Result<Vec<(World, sim::Trajectory<f64>)>, SynthError> {
    let stat = build_static(scene, base)?;
    let bodies = build_bodies(scene, base)?;
    simulate_built(scene, &stat, &bodies)
}

fn simulate_built(
    scene: &SynthScene,
    stat: &StaticScene,
    bodies: &Bodies,
) -> Result<Vec<(World, sim::Trajectory<f64>)>, SynthError> {
    let mut out = Vec::new();
    if scene.videos.is_empty() {
        return Err(field("videos", "the scene has no videos"));
    }
    for (vi, v) in scene.videos.iter().enumerate() {
        let f = format!("videos[{vi}] ({})", v.name);
        let cfg = SimConfig {
            fps: v.fps,
            frames: v.frames,
            substeps: v.substeps,
            ..SimConfig::default()
        };
        cfg.validate().map_err(|e| field(format!("{f}.{}", e.field), e.msg))?;
        v.contact
            .validate(&format!("{f}.contact"))
            .map_err(|e| field(e.field, e.msg))?;
        let pair_contact = v.pair_contact.unwrap_or(v.contact);
        if let Some(p) = &v.pair_contact {
            p.validate(&format!("{f}.pair_contact"))
                .map_err(|e| field(e.field, e.msg))?;
            // Rapier averages its colliders' values: the scene's side is `2 contact − pair_contact`.
            if scene.physics == Physics::Rapier
                && (2.0 * v.contact.restitution < p.restitution || 2.0 * v.contact.friction < p.friction)
            {
                return Err(field(
                    format!("{f}.pair_contact"),
                    "physics = \"rapier\" averages each collider's values: a pair value may be at most twice the scene's",
                ));
            }
        }
        let mut world = World::new(cfg, stat.shape.clone());
        if v.bodies.is_empty() {
            return Err(field(format!("{f}.bodies"), "a video needs at least one body"));
        }
        for (bi, vb) in v.bodies.iter().enumerate() {
            let bf = format!("{f}.bodies[{bi}] ({})", vb.name);
            let k = scene
                .bodies
                .iter()
                .position(|b| b.name == vb.name)
                .ok_or_else(|| field(&bf, "no body of this name in `bodies`"))?;
            if v.bodies[..bi].iter().any(|o| o.name == vb.name) {
                return Err(field(&bf, "the body appears twice"));
            }
            for (name, val) in [("t", vb.t), ("v", vb.v), ("omega", vb.omega)] {
                if val.iter().any(|x| !x.is_finite()) {
                    return Err(field(
                        format!("{bf}.{name}"),
                        format!("has NaN or infinite values: {val:?}"),
                    ));
                }
            }
            let q = unit_quat(&format!("{bf}.q"), vb.q)?;
            let state = BodyState::new(vb.t, q.to_array_re(), vb.v, vb.omega);
            world.add_body(bodies.bodies[k].clone(), state, v.contact, pair_contact);
        }
        check_start(&world, &f)?;
        let traj = match scene.physics {
            Physics::Pganeus => world.simulate(&world.params()),
            Physics::Rapier => simulate_with_rapier(scene, stat, v, &world),
        };
        out.push((world, traj));
    }
    Ok(out)
}

/// Bodies must not start inside the board, an obstacle or each other (1 mm slack).
fn check_start(world: &World, f: &str) -> Result<(), SynthError> {
    use sim::sdf::Sdf;
    for (b, body) in world.bodies.iter().enumerate() {
        let pose = world.initial[b].pose;
        let deepest = body
            .contact_points
            .iter()
            .map(|r| world.scene.distance_local(pose.transform_point(*r)))
            .fold(f64::INFINITY, f64::min);
        if deepest < -1e-3 {
            return Err(field(
                format!("{f}.bodies[{b}] ({})", body.name),
                format!("starts {:.1} mm inside the board or an obstacle", -deepest * 1e3),
            ));
        }
        for (o, other) in world.bodies.iter().enumerate().take(b) {
            let op = world.initial[o].pose;
            let d = body
                .contact_points
                .iter()
                .map(|r| other.sdf.distance(&op, pose.transform_point(*r)))
                .fold(f64::INFINITY, f64::min);
            if d < -1e-3 {
                return Err(field(
                    format!("{f}.bodies[{b}] ({})", body.name),
                    format!("starts {:.1} mm inside {}", -d * 1e3, other.name),
                ));
            }
        }
    }
    Ok(())
}

fn check_camera(cam: &Camera<f64>, scene: &RenderScene, f: &str) -> Result<(), SynthError> {
    let c = cam.center();
    let d = scene_distance(scene, c);
    if d < 1e-3 {
        return Err(field(
            f,
            format!("camera at {:?} is inside (or touching) the geometry", c.to_array()),
        ));
    }
    Ok(())
}

fn mesh_radius(m: &TriMesh) -> f64 {
    m.vertices.iter().map(|v| Vec3::cst(*v).norm()).fold(0.0, f64::max)
}

/// Everything a dataset holds, before rendering.
struct DatasetPlan {
    captures: Vec<CapturePlan>,
    truth: Truth,
    /// `<name>.ply` files: the background and each body (body frame).
    meshes: Vec<(String, TriMesh)>,
}

/// Everything to render, checked: background, two static captures per body, videos.
fn plan(scene: &SynthScene, base: &Path) -> Result<DatasetPlan, SynthError> {
    let rig = &scene.cameras;
    if rig.width == 0 || rig.height == 0 {
        return Err(field("cameras.width", "image size must be positive"));
    }
    if rig.views == 0 {
        return Err(field("cameras.views", "must be at least 1"));
    }
    if rig.spp == 0 {
        return Err(field("cameras.spp", "must be at least 1"));
    }
    if !(rig.fov_deg > 1.0 && rig.fov_deg < 170.0) {
        return Err(field(
            "cameras.fov_deg",
            format!("must be between 1 and 170, got {}", rig.fov_deg),
        ));
    }
    for (name, e) in [
        ("cameras.background_elevation", rig.background_elevation),
        ("cameras.object_elevation", rig.object_elevation),
    ] {
        if !(e[0] > 0.0 && e[1] < 90.0 && e[0] <= e[1]) {
            return Err(field(
                name,
                format!("must satisfy 0 < low ≤ high < 90 degrees, got {e:?}"),
            ));
        }
    }
    if let Some(c) = &scene.camera_like {
        if !(c.noise >= 0.0 && c.exposure_jitter >= 0.0 && c.white_balance_jitter >= 0.0 && c.exposure_drift >= 0.0) {
            return Err(field("camera_like", "noise, jitters and drift must be zero or more"));
        }
        if !(1..=100).contains(&c.jpeg_quality) {
            return Err(field("camera_like.jpeg_quality", "must be 1 to 100"));
        }
        if c.sensor_scale == 0 || c.sensor_scale % 2 == 0 {
            return Err(field(
                "camera_like.sensor_scale",
                "must be odd (a capture pixel's centre is its middle sensor pixel's)",
            ));
        }
        if !(c.shutter >= 0.0) || c.blur_samples % 2 == 0 {
            return Err(field(
                "camera_like",
                "shutter must be zero or more and blur_samples odd (its middle instant is the frame's)",
            ));
        }
    }
    let stat = build_static(scene, base)?;
    let bodies = build_bodies(scene, base)?;
    let videos = simulate_built(scene, &stat, &bodies)?;
    // The board and the table alone, for the static captures of bodies.
    let bare: Vec<_> = stat.objects[..stat.board_and_table].to_vec();
    let k = intrinsics(rig.width, rig.height, rig.fov_deg);
    let (w, h) = (rig.width, rig.height);
    let light = scene.light.clone();
    let mut plans = Vec::new();

    // Background: the board and obstacles from the upper hemisphere.
    let bg_scene = RenderScene {
        objects: stat.objects.clone(),
        light: light.clone(),
    };
    let (centre, _) = stat.region;
    // What the views keep in frame: the obstacles and the disc inscribed in
    // the board (its corners may leave some views, as they do when a person
    // films a table from close by; other views see them).
    let half = scene.board.half;
    let disc = (0..64).map(|i| {
        let a = i as f64 * std::f64::consts::TAU / 64.0;
        Vec3::new(half[0] * a.cos(), half[1] * a.sin(), 0.0)
    });
    let obstacles = stat.meshes[1..]
        .iter()
        .flat_map(|m| m.vertices.iter().map(|v| Vec3::cst(*v)));
    let content: Vec<Vec3<f64>> = disc.chain(obstacles).collect();
    let mut hand = scene.raw.as_ref().map(|r| (r, geom::SplitMix64::new(r.seed)));
    if scene.raw.is_some() && scene.board.print.is_none() {
        return Err(field(
            "raw",
            "raw footage needs board.print: calibrate finds the cameras from the printed board",
        ));
    }
    let mut held = |cam: Camera<f64>, target: Vec3<f64>| match &mut hand {
        Some((r, rng)) => crate::raw::handheld(&cam, (cam.center() - target).norm(), r, rng),
        None => cam,
    };
    let cams: Vec<_> = hemisphere_views(rig.views, rig.background_elevation)
        .iter()
        .map(|&(e, a)| held(framed_orbit(centre, &content, e, a, SCENE_BORDER, k, w, h), centre))
        .collect();
    for (i, c) in cams.iter().enumerate() {
        check_camera(c, &bg_scene, &format!("background view {i}"))?;
    }
    plans.push(CapturePlan {
        name: "background".into(),
        kind: CaptureKind::Static,
        subject: Some(CaptureSubject::Scene),
        fps: None,
        cameras: cams,
        scenes: vec![bg_scene],
        region: stat.region,
        mask_bodies: vec![],
        per_body_masks: false,
        raw_instants: vec![],
        instants: vec![],
        shutter: None,
    });

    // Raw footage: close-ups of the printed board filling the frame from many sides, as a careful user shoots
    // before the scene (the lens's distortion and principal point need the board near the image's edges).
    if let (Some(r), Some(spec)) = (&scene.raw, &scene.board.print) {
        let board = calib::Board::new(spec.clone()).map_err(|e| field("board.print", e.to_string()))?;
        let mut rng = geom::SplitMix64::new(r.seed.wrapping_add(99));
        let half_fov = (0.5 * w as f64 / k.fx).atan().min((0.5 * h as f64 / k.fy).atan());
        let cams: Vec<Camera<f64>> = (0..r.calibration_views)
            .map(|_| {
                let fill = rng.range(0.55, 0.85);
                let distance = 0.5 * board.extent[0] / (fill * half_fov.tan());
                let target = Vec3::new(
                    rng.range(-0.2, 0.2) * board.extent[0],
                    rng.range(-0.2, 0.2) * board.extent[1],
                    0.0,
                );
                let cam = orbit(target, distance, rng.range(45.0, 82.0), rng.range(0.0, 360.0), k, w, h);
                let turned = crate::desc::RawDesc {
                    roll_deg: 90.0,
                    distance_jitter: 0.0,
                    ..r.clone()
                };
                crate::raw::handheld(&cam, distance, &turned, &mut rng)
            })
            .collect();
        plans.push(CapturePlan {
            name: "calibration".into(),
            kind: CaptureKind::Static,
            subject: Some(CaptureSubject::Scene),
            fps: None,
            cameras: cams,
            scenes: vec![RenderScene {
                objects: stat.objects.clone(),
                light: light.clone(),
            }],
            region: stat.region,
            mask_bodies: vec![],
            per_body_masks: false,
            raw_instants: vec![],
            instants: vec![],
            shutter: None,
        });
    }

    // Each body alone on the board, upright and turned over; views from above.
    let mut truth_bodies = Vec::new();
    let mut meshes = vec![("background".to_string(), concat(&stat.meshes))];
    for (bi, (desc, body)) in scene.bodies.iter().zip(&bodies.bodies).enumerate() {
        let mut statics = Vec::new();
        for (s, suffix) in ["a", "b"].iter().enumerate() {
            let q = unit_quat("static", desc.static_orientations[s]).expect("checked in build_bodies");
            let pose = resting_pose(body, q, [0.0, 0.0]);
            let mut objects = bare.clone();
            objects.push(body_object(body, &bodies.textures[bi], pose, bi));
            let rs = RenderScene {
                objects,
                light: light.clone(),
            };
            let r_obj = mesh_radius(&body.mesh);
            let dist = framing_distance(r_obj, &k, w, h, 1.6);
            let cams: Vec<_> = hemisphere_views(rig.views, rig.object_elevation)
                .iter()
                .map(|&(e, a)| held(orbit(pose.t, dist, e, a, k, w, h), pose.t))
                .collect();
            let name = format!("{}_{suffix}", desc.name);
            for (i, c) in cams.iter().enumerate() {
                check_camera(c, &rs, &format!("{name} view {i}"))?;
            }
            plans.push(CapturePlan {
                name: name.clone(),
                kind: CaptureKind::Static,
                subject: Some(CaptureSubject::Object),
                fps: None,
                cameras: cams,
                scenes: vec![rs],
                region: (pose.t, r_obj * 1.15 + 0.005),
                mask_bodies: vec![bi],
                per_body_masks: false,
                raw_instants: vec![],
                instants: vec![],
                shutter: None,
            });
            statics.push(StaticCapture {
                capture: name,
                pose: IoPose::from_geom(&pose),
                extra: Default::default(),
            });
        }
        truth_bodies.push(TruthBody {
            name: desc.name.clone(),
            mesh: format!("{}.ply", desc.name),
            mass: Some(body.mass),
            static_captures: statics,
            extra: Default::default(),
        });
        meshes.push((desc.name.clone(), body.mesh.clone()));
    }

    // Videos: one fixed camera, bodies where the simulator put them.
    let mut truth_videos = Vec::new();
    for ((vdesc, (world, traj)), vi) in scene.videos.iter().zip(&videos).zip(0..) {
        let f = format!("videos[{vi}] ({})", vdesc.name);
        let c = &vdesc.camera;
        if !(c.elevation_deg > 0.0 && c.elevation_deg < 90.0) {
            return Err(field(format!("{f}.camera.elevation_deg"), "must be between 0 and 90"));
        }
        if !(c.distance.is_finite() && c.distance > 0.0) {
            return Err(field(format!("{f}.camera.distance"), "must be positive"));
        }
        let cam = orbit(
            Vec3::cst(c.look_at),
            c.distance,
            c.elevation_deg,
            c.azimuth_deg,
            k,
            w,
            h,
        );
        let ids: Vec<usize> = vdesc
            .bodies
            .iter()
            .map(|vb| scene.bodies.iter().position(|b| b.name == vb.name).expect("checked"))
            .collect();
        let scenes: Vec<RenderScene> = traj
            .frames
            .iter()
            .map(|frame| {
                let mut objects = stat.objects.clone();
                for (slot, &bi) in ids.iter().enumerate() {
                    objects.push(body_object(
                        &bodies.bodies[bi],
                        &bodies.textures[bi],
                        frame[slot].pose,
                        bi,
                    ));
                }
                RenderScene {
                    objects,
                    light: light.clone(),
                }
            })
            .collect();
        check_camera(&cam, &scenes[0], &format!("{f}.camera"))?;
        // Each frame over a shutter time, the bodies where the motion puts them then (the middle instant is
        // the frame's own): for the raw footage and for camera-like captures, each with its shutter.
        let over_shutter = |shutter: f64, samples: usize| -> Vec<Vec<RenderScene>> {
            if shutter <= 0.0 || samples < 2 {
                return vec![];
            }
            (0..traj.frames.len())
                .map(|fi| {
                    (0..samples)
                        .map(|s| {
                            let t = fi as f64 + shutter * vdesc.fps * ((s as f64 + 0.5) / samples as f64 - 0.5);
                            let mut objects = stat.objects.clone();
                            for (slot, &bi) in ids.iter().enumerate() {
                                objects.push(body_object(
                                    &bodies.bodies[bi],
                                    &bodies.textures[bi],
                                    pose_at(traj, slot, t),
                                    bi,
                                ));
                            }
                            RenderScene {
                                objects,
                                light: light.clone(),
                            }
                        })
                        .collect()
                })
                .collect()
        };
        let raw_instants = scene
            .raw
            .as_ref()
            .map_or(vec![], |r| over_shutter(r.shutter, r.blur_samples));
        let (instants, shutter) = match &scene.camera_like {
            Some(c) => {
                if c.shutter * vdesc.fps > 1.0 {
                    return Err(field(
                        "camera_like.shutter",
                        format!("{} s is longer than a frame of {f} at {} fps", c.shutter, vdesc.fps),
                    ));
                }
                (over_shutter(c.shutter, c.blur_samples), Some(c.shutter))
            }
            None => (vec![], None),
        };
        plans.push(CapturePlan {
            name: vdesc.name.clone(),
            kind: CaptureKind::Video,
            subject: None,
            fps: Some(vdesc.fps),
            cameras: vec![cam; traj.frames.len()],
            scenes,
            region: stat.region,
            mask_bodies: ids.clone(),
            per_body_masks: true,
            raw_instants,
            instants,
            shutter,
        });
        truth_videos.push(scene_file::trajectory_file(
            &vdesc.name,
            world,
            traj,
            scene.physics.model(),
            Default::default(),
        ));
    }
    let truth = Truth {
        gravity: SimConfig::default().gravity,
        background: Some(pganeus_io::Background {
            capture: "background".into(),
            mesh: "background.ply".into(),
            extra: Default::default(),
        }),
        bodies: truth_bodies,
        videos: truth_videos,
        extra: Default::default(),
    };
    Ok(DatasetPlan {
        captures: plans,
        truth,
        meshes,
    })
}

/// Body `slot`'s pose at fractional frame `t`: between the two frames around it (translation linear,
/// rotation along the shortest arc), held at the ends.
fn pose_at(traj: &sim::Trajectory<f64>, slot: usize, t: f64) -> geom::Pose<f64> {
    let last = traj.frames.len() - 1;
    let t = t.clamp(0.0, last as f64);
    let j = (t.floor() as usize).min(last.saturating_sub(1));
    if last == 0 {
        return traj.frames[0][slot].pose;
    }
    let (a, b) = (traj.frames[j][slot].pose, traj.frames[j + 1][slot].pose);
    let alpha = t - j as f64;
    let turn = (a.q.conj() * b.q).log();
    geom::Pose::new((a.q * geom::Quat::exp(turn * alpha)).unit(), a.t + (b.t - a.t) * alpha)
}

fn concat(meshes: &[TriMesh]) -> TriMesh {
    let mut out = TriMesh::default();
    for m in meshes {
        let off = out.vertices.len() as u32;
        out.vertices.extend_from_slice(&m.vertices);
        out.faces.extend(m.faces.iter().map(|f| f.map(|i| i + off)));
    }
    out
}

fn rgb_image(r: &Rendered) -> Image {
    let mut img = Image::new(r.width, r.height, 3);
    for (px, c) in img.data.chunks_exact_mut(3).zip(&r.rgb) {
        for k in 0..3 {
            px[k] = crate::render::to_srgb8(c[k]);
        }
    }
    img
}

fn mask_image(r: &Rendered, keep: impl Fn(usize) -> bool) -> Image {
    let mut img = Image::new(r.width, r.height, 1);
    for (px, id) in img.data.iter_mut().zip(&r.ids) {
        *px = if id.is_some_and(&keep) { 255 } else { 0 };
    }
    img
}

/// File name of image `i` of `n`: zero-padded to at least three digits.
pub fn frame_name(i: usize, n: usize) -> String {
    let digits = n.saturating_sub(1).to_string().len().max(3);
    format!("{i:0digits$}.png")
}

/// Render and write every capture of `scene` into `out` (which must not exist
/// or be empty), with `truth.json`, meshes and the scene description.
pub fn generate(scene: &SynthScene, base: &Path, out: &Path, on_image: OnImage) -> Result<Summary, SynthError> {
    let DatasetPlan {
        captures: plans,
        mut truth,
        meshes,
    } = plan(scene, base)?;
    std::fs::create_dir_all(out).map_err(|e| SynthError::File {
        path: out.display().to_string(),
        msg: e.to_string(),
    })?;
    let mut summary = Summary {
        captures: vec![],
        images: 0,
    };
    let mut gains = serde_json::Map::new();
    for p in &plans {
        if let Some(g) = write_capture(p, out, scene, on_image)? {
            gains.insert(p.name.clone(), serde_json::json!(g));
        }
        summary.captures.push((p.name.clone(), p.cameras.len()));
        summary.images += p.cameras.len();
    }
    if !gains.is_empty() {
        // The truth of a camera's exposure and white balance: what per-view appearance and a fit's
        // brightness drift should find (docs/formats.md).
        truth.extra.insert(IMAGE_GAINS.into(), serde_json::Value::Object(gains));
    }
    for (name, m) in &meshes {
        pganeus_io::write_ply(
            &out.join(format!("{name}.ply")),
            &PlyMesh::from_mesh(m.clone()),
            PlyEncoding::BinaryLittleEndian,
        )?;
    }
    pganeus_io::write_truth(&out.join("truth.json"), &truth)?;
    if let Some(raw) = &scene.raw {
        write_raw(&plans, scene, raw, out, on_image)?;
    }
    let desc = toml::to_string(scene).map_err(|e| field("scene", e.to_string()))?;
    pganeus_io::write_atomic(&out.join("synth.toml"), desc.as_bytes())?;
    Ok(summary)
}

/// The raw session: `raw/board.toml` and a folder of JPEGs per capture (no cameras, no masks), and
/// `camera_truth.json` beside `raw/`.
fn write_raw(
    plans: &[CapturePlan],
    scene: &SynthScene,
    raw: &crate::desc::RawDesc,
    out: &Path,
    on_image: OnImage,
) -> Result<(), SynthError> {
    let rig = &scene.cameras;
    if raw.width * rig.height != raw.height * rig.width {
        return Err(field(
            "raw",
            format!(
                "the sensor's {}x{} must have the captures' aspect ({}x{})",
                raw.width, raw.height, rig.width, rig.height
            ),
        ));
    }
    if !(raw.noise >= 0.0 && raw.exposure_jitter >= 0.0 && raw.white_balance_jitter >= 0.0 && raw.shutter >= 0.0) {
        return Err(field("raw", "noise, jitters and shutter must be zero or more"));
    }
    let lens = crate::raw::raw_lens(scene, raw);
    let dir = out.join("raw");
    let spec = scene.board.print.as_ref().expect("checked in plan");
    let board_toml = toml::to_string(spec).map_err(|e| field("board.print", e.to_string()))?;
    crate::raw::write_text(&dir, "board.toml", &board_toml)?;
    let mut rng = geom::SplitMix64::new(raw.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(7));
    let mut listed = Vec::new();
    for p in plans {
        let video = p.kind == CaptureKind::Video;
        let n = p.cameras.len();
        let video_gain = crate::raw::photo_gain(raw.exposure_jitter, raw.white_balance_jitter, &mut rng);
        let mut files = Vec::with_capacity(n);
        for (i, cam) in p.cameras.iter().enumerate() {
            let single;
            let scenes: &[RenderScene] = if !p.raw_instants.is_empty() {
                &p.raw_instants[i]
            } else {
                single = [if p.scenes.len() == 1 {
                    p.scenes[0].clone()
                } else {
                    p.scenes[i].clone()
                }];
                &single
            };
            let r = crate::raw::render_raw(scenes, &cam.world_to_cam, &lens, raw, rig.spp);
            let gain = if video {
                video_gain
            } else {
                crate::raw::photo_gain(raw.exposure_jitter, raw.white_balance_jitter, &mut rng)
            };
            let image = crate::raw::develop(&r, gain, raw.noise, &mut rng);
            let file = crate::raw::raw_name(&p.name, video, i);
            pganeus_io::write_jpeg(&dir.join(&p.name).join(&file), &image, raw.jpeg_quality)?;
            files.push(file);
            on_image(&format!("raw/{}", p.name), i + 1, n);
        }
        listed.push((p.name.clone(), files));
    }
    let truth = crate::raw::camera_truth(&lens, raw, &listed);
    let text = serde_json::to_string_pretty(&truth).map_err(|e| field("raw", e.to_string()))?;
    crate::raw::write_text(out, "camera_truth.json", &text)?;
    Ok(())
}

/// The key of `truth.json` under which camera-like footage keeps, for every capture, the gain on each
/// channel each image was developed with (exposure × white balance; a video's drifting).
pub const IMAGE_GAINS: &str = "image_gains";

/// Render and write one capture; camera-like footage returns the gain each image was developed with.
fn write_capture(
    p: &CapturePlan,
    out: &Path,
    scene: &SynthScene,
    on_image: OnImage,
) -> Result<Option<Vec<[f64; 3]>>, SynthError> {
    let dir = out.join(&p.name);
    let n = p.cameras.len();
    let mut mats = Vec::with_capacity(n);
    let smat = scale_mat(p.region.0, p.region.1);
    let mut camera = scene.camera_like.as_ref().map(|c| CameraEffects::new(c, p));
    for (i, cam) in p.cameras.iter().enumerate() {
        let rs = if p.scenes.len() == 1 {
            &p.scenes[0]
        } else {
            &p.scenes[i]
        };
        let file = frame_name(i, n);
        let (r, image) = match &mut camera {
            None => {
                let r = render(rs, cam, scene.cameras.spp);
                let image = rgb_image(&r);
                (r, image)
            }
            Some(effects) => {
                let instants = if p.instants.is_empty() {
                    std::slice::from_ref(rs)
                } else {
                    &p.instants[i]
                };
                // The sensor: the capture's camera `k` times over, sampled as finely in all.
                let k = effects.desc.sensor_scale.max(1);
                let sensor = Camera {
                    k: geom::Intrinsics {
                        fx: cam.k.fx * k as f64,
                        fy: cam.k.fy * k as f64,
                        cx: cam.k.cx * k as f64,
                        cy: cam.k.cy * k as f64,
                        skew: cam.k.skew * k as f64,
                    },
                    width: cam.width * k,
                    height: cam.height * k,
                    ..*cam
                };
                let ray = |u: f64, v: f64| sensor.ray(u, v);
                let spp = scene.cameras.spp.div_ceil((k * k) as usize).max(1);
                let r = render_instants(
                    instants,
                    sensor.width,
                    sensor.height,
                    spp,
                    Some(instants.len() / 2),
                    &ray,
                );
                let image = effects.develop(&r, i, &dir.join("image").join(&file))?;
                let image = crate::contact_sheet::resize(&image, cam.width, cam.height);
                // A capture pixel's mask is what its centre sees: the middle sensor pixel's (k is odd).
                let (sw, half) = (sensor.width as usize, (k / 2) as usize);
                let ids = (0..(cam.width * cam.height) as usize)
                    .map(|q| {
                        let (x, y) = (q % cam.width as usize, q / cam.width as usize);
                        r.ids[(y * k as usize + half) * sw + x * k as usize + half]
                    })
                    .collect();
                let at_capture = Rendered {
                    width: cam.width,
                    height: cam.height,
                    rgb: Vec::new(),
                    ids,
                };
                (at_capture, image)
            }
        };
        pganeus_io::write_png(&dir.join("image").join(&file), &image)?;
        if !p.mask_bodies.is_empty() {
            let ids = &p.mask_bodies;
            pganeus_io::write_png(&dir.join("mask").join(&file), &mask_image(&r, |id| ids.contains(&id)))?;
            if p.per_body_masks {
                for &b in ids {
                    let sub: PathBuf = dir.join(format!("mask_{}", scene.bodies[b].name)).join(&file);
                    pganeus_io::write_png(&sub, &mask_image(&r, |id| id == b))?;
                }
            }
        }
        mats.push(CameraMats {
            world_mat: cam.world_mat(),
            scale_mat: smat,
        });
        on_image(&p.name, i + 1, n);
    }
    pganeus_io::write_cameras_npz(&dir.join("cameras_sphere.npz"), &mats)?;
    let info = CaptureInfo {
        kind: p.kind,
        subject: p.subject,
        fps: p.fps,
        shutter: p.shutter,
        extra: Default::default(),
    };
    pganeus_io::write_capture_info(&dir.join("capture.json"), &info)?;
    Ok(camera.map(|c| c.gains))
}

/// What a camera does to one capture's images (`[camera_like]`): a gain per photo, or a video's gain
/// drifting over its frames; noise; JPEG.
struct CameraEffects<'a> {
    desc: &'a crate::desc::CameraLike,
    rng: geom::SplitMix64,
    video: bool,
    frames: usize,
    /// A video's gain before its drift, and the drift's phase.
    base_gain: [f64; 3],
    phase: f64,
    /// The gain each image so far was developed with.
    gains: Vec<[f64; 3]>,
}

impl<'a> CameraEffects<'a> {
    fn new(desc: &'a crate::desc::CameraLike, p: &CapturePlan) -> Self {
        // Each capture's own draws, whatever captures come before it.
        let name_hash = p.name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
        });
        let mut rng = geom::SplitMix64::new(desc.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ name_hash);
        let base_gain = crate::raw::photo_gain(desc.exposure_jitter, desc.white_balance_jitter, &mut rng);
        let phase = rng.range(0.0, std::f64::consts::TAU);
        CameraEffects {
            desc,
            rng,
            video: p.kind == CaptureKind::Video,
            frames: p.cameras.len(),
            base_gain,
            phase,
            gains: Vec::new(),
        }
    }

    /// Image `i` as the camera records it, through JPEG (`path` names it in errors).
    fn develop(&mut self, r: &Rendered, i: usize, path: &Path) -> Result<Image, SynthError> {
        let d = self.desc;
        let gain = if self.video {
            // Auto exposure: a slow swing over the video, up to `exposure_drift`.
            let u = i as f64 / self.frames.saturating_sub(1).max(1) as f64;
            let drift = 1.0 + d.exposure_drift * (self.phase + 1.5 * std::f64::consts::PI * u).sin();
            self.base_gain.map(|g| g * drift)
        } else {
            crate::raw::photo_gain(d.exposure_jitter, d.white_balance_jitter, &mut self.rng)
        };
        let image = crate::raw::develop(r, gain, d.noise, &mut self.rng);
        self.gains.push(gain);
        let bytes =
            pganeus_io::encode_jpeg(&image, d.jpeg_quality).map_err(|e| field("camera_like.jpeg_quality", e))?;
        Ok(pganeus_io::read_jpeg_bytes(&bytes, path)?)
    }
}
