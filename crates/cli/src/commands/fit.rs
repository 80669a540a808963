//! `fit`: a body's pose in every frame of a fixed-camera video and the physics
//! that explains it (Sec. 3.3–3.4): the first pose from a rough guess, PA,
//! GA with the contact penalty, and PGA (GA ↔ PGA while it helps). Each
//! stage's result is written as it ends, so a run that stops resumes at the
//! stage it was in (same settings; `--force` starts over).

use super::checkpoint_of;
use super::mesh_cmds::{bake_scene, world_cameras};
use super::objects::parse_objects;
use super::render_trajectory::{beside, read_mask, reference_frame, to8};
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, ValueEnum};
use geom::{Camera, Pose, Quat, Vec3};
use neus::checkpoint::load_field;
use neus::compose::{prerender_scene, render_composed, Behind, ComposedRay, Composer, Layer};
use neus::ObjectModel;
use pganeus_io::Image;
use recon::poses_from_video::carried_on;
use recon::video_fit::{
    evaluate_poses, fit_to_poses, ga_weights_of, launch_guess, lift_out, pose_from_guess, total_loss, TOUCHING,
};
use recon::{
    FramePose, FrameTarget, ImageLoss, MultiStart, PhysicsFitConfig, PhysicsFromVideo, PoseFitConfig, PoseFromImage,
    PosesFromVideo, StartContact, StartFrom, StartResult, ValueRange, VideoFitConfig,
};
use serde::{Deserialize, Serialize};
use serde_json::{json, Map, Value};
use sim::sdf::SdfGrid;
use sim::{BodyState, ContactParams, ContactSampling, MassSpec, RigidBody, SimConfig, World};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
#[command(after_help = "Examples:
  pganeus fit data/slide --scene runs/background --object toy=merged --init init.json --out fits/slide
  pganeus fit data/slide --scene runs/background --object toy=merged --init init.json --no-pa --out fits/slide_no_pa")]
pub struct FitArgs {
    /// The video: a capture in the NeuS layout from one fixed camera, with `mask/` (one body) or
    /// `mask_<NAME>/`, and `capture.json` giving the fps.
    pub video: PathBuf,
    /// The scene's run folder (its field renders the background).
    #[arg(long)]
    pub scene: PathBuf,
    /// The scene's baked grid for contacts (`bake` output); default: baked from the scene run into the
    /// output folder.
    #[arg(long)]
    pub scene_grid: Option<PathBuf>,
    /// The body: NAME=DIR, DIR a `merge` output (or a single run folder).
    #[arg(long)]
    pub object: Vec<String>,
    /// The first-pose guess (init.json, docs/formats.md), or `auto`: candidates from the first frame's mask and
    /// the body's resting sides, the best refined by the image terms (the pose found is written to
    /// `init_auto.json` in the fit folder, in the same format).
    #[arg(long)]
    pub init: PathBuf,
    /// The output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Stages to run (the earlier ones' results must be in the output folder); the fit stops after the last
    /// one named.
    #[arg(long, value_delimiter = ',')]
    pub stages: Option<Vec<Stage>>,
    /// Ablation: no PA; GA tracks frame by frame from the previous frame, then PGA.
    #[arg(long, conflicts_with = "no_ga")]
    pub no_pa: bool,
    /// Ablation: PA alone (no GA, no PGA).
    #[arg(long)]
    pub no_ga: bool,
    /// Settings of every stage (TOML; the sections and defaults are those of `config.toml` in a fit folder).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Use the first N frames of the video.
    #[arg(long)]
    pub frames: Option<usize>,
    /// Frames per second (default: the video's `capture.json`).
    #[arg(long)]
    pub fps: Option<f64>,
    /// Density of the body, kg/m³ (the motion against a static scene does not depend on it).
    #[arg(long, default_value_t = 1000.0)]
    pub density: f64,
    /// Start over even if the output folder holds a fit with other settings.
    #[arg(long)]
    pub force: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// The first pose from the guess, and the launch guess from the next frames.
    First,
    /// PA: physics from the rendered frames.
    Pa,
    /// GA: every frame's pose, with the contact penalty.
    Ga,
    /// PGA: physics from GA's poses (GA ↔ PGA while it helps), renders and the final trajectory.
    Pga,
}

/// An `init.json` entry.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Guess {
    capture: String,
    t: [f64; 3],
    q: [f64; 4],
}

/// What a fit folder was made with; a resumed run must match it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FitRecord {
    pub(super) inputs: RecordInputs,
    #[serde(default)]
    pub(super) fit: VideoFitConfig,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RecordInputs {
    pub(super) video: PathBuf,
    pub(super) scene: PathBuf,
    /// `NAME=DIR`, comma-separated with several bodies.
    pub(super) object: String,
    pub(super) init: PathBuf,
    pub(super) frames: usize,
    pub(super) fps: f64,
    pub(super) no_pa: bool,
    pub(super) no_ga: bool,
}

/// The first stage's result.
#[derive(Serialize, Deserialize)]
struct FirstPose {
    t: [f64; 3],
    q: [f64; 4],
    /// How far the guess was raised out of the scene, m.
    lift: f64,
    /// The launch guess from the next frames' poses.
    v: [f64; 3],
    omega: [f64; 3],
    touching: bool,
    /// How the body touches the scene in frame 0, which decides how its launch is fitted
    /// (`launch_in_plane`).
    #[serde(default)]
    start: StartContact,
    iou: f64,
    loss: f64,
    /// The video's brightness relative to the object's captures, measured at the first pose and kept for
    /// every later stage (`FrameTarget::exposure`); 1 in files written before it was measured.
    #[serde(default = "as_captured")]
    exposure: f64,
}

fn as_captured() -> f64 {
    1.0
}

/// Everything the stages read.
struct Job {
    name: String,
    object: ObjectModel,
    frames: Vec<FrameTarget>,
    scene_pre: Vec<ComposedRay>,
    world: World,
    fps: f64,
    capture: String,
    video: PathBuf,
    cfg: VideoFitConfig,
    out: PathBuf,
    log: std::fs::File,
}

impl Job {
    fn log(&mut self, v: Value) -> Result<()> {
        writeln!(self.log, "{v}").with_context(|| format!("cannot write {}", self.out.join("log.jsonl").display()))
    }

    fn stage_file(&self, name: &str) -> PathBuf {
        self.out.join(name)
    }
}

/// The video's frames for body `name`: images, the body's masks and the one fixed camera.
pub(super) fn read_video(
    dir: &Path,
    name: &str,
    single: bool,
    limit: Option<usize>,
) -> Result<(Vec<FrameTarget>, Option<f64>)> {
    let c = pganeus_io::open_capture(dir)?;
    let cameras = world_cameras(&c)?;
    let m0 = cameras[0].world_mat();
    let scale = m0.iter().flatten().map(|v| v.abs()).fold(1e-12, f64::max);
    for (k, cam) in cameras.iter().enumerate().skip(1) {
        let m = cam.world_mat();
        let diff = m
            .iter()
            .flatten()
            .zip(m0.iter().flatten())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if diff > 1e-9 * scale {
            bail!(
                "{}: world_mat_{k} differs from world_mat_0 (by {diff:.3e}): fit needs a video from one fixed camera",
                dir.join("cameras_sphere.npz").display()
            );
        }
    }
    let masks = match c.extra_masks.iter().find(|(n, _)| n == name) {
        Some((_, m)) => m.clone(),
        None => match (&c.masks, single) {
            (Some(m), true) => m.clone(),
            _ => bail!(
                "{}: no mask_{name}/ folder for body {name:?}{}",
                dir.display(),
                if single { " (nor mask/)" } else { "" }
            ),
        },
    };
    let n = limit.map_or(c.len(), |l| l.min(c.len()));
    if n < 2 {
        bail!("{}: fit needs at least 2 frames, the video has {n}", dir.display());
    }
    let mut frames = Vec::with_capacity(n);
    let mut empty = Vec::new();
    for k in 0..n {
        let mask = read_mask(&masks[k])?;
        if !mask.iter().any(|&m| m) {
            empty.push(k);
        }
        frames.push(FrameTarget {
            camera: cameras[0],
            rgb: reference_frame(&c.images[k])?,
            mask,
            exposure: 1.0,
        });
    }
    let mask_dir = masks[0].parent().unwrap_or(dir).display().to_string();
    if empty.len() == n {
        bail!("{mask_dir}: the masks of body {name:?} are empty in every frame");
    }
    if !empty.is_empty() {
        tracing::warn!("{mask_dir}: body {name:?} is not seen in frames {empty:?}: its image terms skip them");
    }
    Ok((frames, c.info.and_then(|i| i.fps)))
}

/// Where the body frame sat in capture `capture` (the object's reference capture or, for a merge, its other).
pub(super) fn capture_from_body(model: &ObjectModel, capture: &str) -> Option<Pose<f64>> {
    let name_of = |f: &neus::object_model::ObjectField| {
        f.field
            .capture
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    if capture == model.reference_capture {
        return Some(model.primary.capture_from_body);
    }
    model
        .other
        .as_ref()
        .filter(|o| name_of(o) == capture)
        .map(|o| o.capture_from_body)
}

/// Each body's pose in frame 0 from an `init.json` with one entry per body (and none for a body the fit
/// does not have).
pub(super) fn read_guesses(path: &Path, bodies: &[(&str, &ObjectModel)]) -> Result<Vec<Pose<f64>>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let all: BTreeMap<String, Guess> = serde_json::from_str(&text).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    if let Some(other) = all.keys().find(|k| !bodies.iter().any(|(n, _)| n == *k)) {
        bail!(
            "{}: a guess for body {other:?}, which the fit has no --object and the video no mask for",
            path.display()
        );
    }
    bodies
        .iter()
        .map(|&(name, model)| {
            let g = all
                .get(name)
                .ok_or_else(|| anyhow!("{}: no guess for body {name:?}", path.display()))?;
            if !(g.t.iter().chain(&g.q).all(|v| v.is_finite()) && g.q.iter().map(|v| v * v).sum::<f64>() > 1e-12) {
                bail!(
                    "{}: {name}: t must be finite and q a non-zero quaternion",
                    path.display()
                );
            }
            let from = capture_from_body(model, &g.capture).ok_or_else(|| {
                anyhow!(
                    "{}: {name}: capture {:?} is not one the object {} was built from ({})",
                    path.display(),
                    g.capture,
                    model.source.display(),
                    model.reference_capture
                )
            })?;
            Ok(pose_from_guess(&from, g.t, g.q))
        })
        .collect()
}

/// Refuse a guess whose centre projects outside the image.
pub(super) fn check_guess_in_view(cam: &geom::Camera<f64>, guess: &Pose<f64>, name: &str, init: &Path) -> Result<()> {
    let (u, v, z) = cam.project(guess.t);
    if !(z > 0.0 && (0.0..cam.width as f64).contains(&u) && (0.0..cam.height as f64).contains(&v)) {
        bail!(
            "{}: the guess for {name:?} puts its centre outside the image (pixel ({u:.0}, {v:.0}), depth {z:.3} m)",
            init.display()
        );
    }
    Ok(())
}

pub fn run(a: FitArgs) -> Result<()> {
    let t_start = Instant::now();
    let objects = parse_objects(&a.object)?;
    if objects.len() > 1 {
        return super::fit_bodies::run(a, objects, t_start);
    }
    let (name, object_dir) = objects.into_iter().next().expect("one body");
    let cfg: VideoFitConfig = match &a.config {
        // Key by key over the defaults: `[ga.pose] iterations = 60` keeps fit's other GA settings.
        Some(p) => super::config_over(&VideoFitConfig::default(), p)?,
        None => VideoFitConfig::default(),
    };
    if !(a.density.is_finite() && a.density > 0.0) {
        bail!("--density must be positive, got {}", a.density);
    }
    // Every input is read and checked before anything is written.
    let (frames, fps_of_capture) = read_video(&a.video, &name, true, a.frames)?;
    let fps = video_fps(&a, fps_of_capture)?;
    let object = ObjectModel::load(&object_dir).map_err(|e| anyhow!("--object {name}: {e}"))?;
    let guess = if a.init.as_os_str() == "auto" {
        None
    } else {
        Some(read_guesses(&a.init, &[(name.as_str(), &object)])?[0])
    };
    let cam = frames[0].camera;
    if let Some(guess) = &guess {
        check_guess_in_view(&cam, guess, &name, &a.init)?;
    }
    let (scene_field, grid) = load_scene(&a)?;
    let body = rigid_body(&name, &object, &object_dir, a.density)?;
    check_sim_settings(fps, frames.len(), &cfg)?;
    let record = FitRecord {
        inputs: RecordInputs {
            video: a.video.clone(),
            scene: a.scene.clone(),
            object: format!("{name}={}", object_dir.display()),
            init: a.init.clone(),
            frames: frames.len(),
            fps,
            no_pa: a.no_pa,
            no_ga: a.no_ga,
        },
        fit: cfg.clone(),
    };

    if open_output(&a, &record)? {
        return Ok(());
    }
    let grid = scene_grid(grid, &scene_field, &a)?;
    let world = fit_world(grid, fps, frames.len(), &cfg, vec![body])?;
    let scene_pre = scene_through(&scene_field, &cam);
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(a.out.join("log.jsonl"))
        .with_context(|| format!("cannot open {}", a.out.join("log.jsonl").display()))?;
    let capture = a
        .video
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "video".into());
    let mut job = Job {
        name,
        object,
        frames,
        scene_pre,
        world,
        fps,
        capture,
        video: a.video.clone(),
        cfg,
        out: a.out.clone(),
        log,
    };
    let wanted = a
        .stages
        .clone()
        .unwrap_or_else(|| vec![Stage::First, Stage::Pa, Stage::Ga, Stage::Pga]);
    let mut timings = Map::new();
    let mut time = |stage: &str, t: Instant| {
        let s = t.elapsed().as_secs_f64();
        timings.insert(stage.into(), json!((s * 10.0).round() / 10.0));
        tracing::info!("{stage}: {s:.1} s");
    };

    let t = Instant::now();
    let first = stage_first(&mut job, guess, wanted.contains(&Stage::First))?;
    time("first_pose", t);
    for f in &mut job.frames {
        f.exposure = first.exposure;
    }
    let last = wanted.iter().copied().max().unwrap_or(Stage::Pga);
    if last == Stage::First {
        return Ok(());
    }
    let t = Instant::now();
    let pa = if a.no_pa {
        None
    } else {
        Some(stage_pa(&mut job, &first, wanted.contains(&Stage::Pa))?)
    };
    time("pa", t);
    if last == Stage::Pa && !a.no_pa {
        return Ok(());
    }
    if a.no_ga {
        let Some(pa) = pa else {
            unreachable!("--no-pa conflicts with --no-ga")
        };
        if wanted.contains(&Stage::Pga) || wanted.contains(&Stage::Ga) {
            finish(&mut job, &pa, None, &[], None, &timings, t_start)?;
        }
        return Ok(());
    }
    let t = Instant::now();
    let start_world = pa.unwrap_or_else(|| launch_world(&job, &first));
    let ga = stage_ga(&mut job, &start_world, a.no_pa, wanted.contains(&Stage::Ga), "ga.json")?;
    time("ga", t);
    if !wanted.contains(&Stage::Pga) {
        return Ok(());
    }
    let t = Instant::now();
    let start_world = carve_seen_space(&mut job, start_world, &ga)?;
    let pga = stage_pga(&mut job, start_world, ga, !a.no_pa, first.start)?;
    time("pga", t);
    timings.insert("pga_rounds".into(), json!(pga.rounds));
    finish(
        &mut job,
        &pga.world,
        Some(&pga.ga),
        &pga.ranges,
        pga.flight.as_ref(),
        &timings,
        t_start,
    )
}

/// The video's frame rate: `--fps` when given, else its `capture.json`'s.
pub(super) fn video_fps(a: &FitArgs, from_capture: Option<f64>) -> Result<f64> {
    match (a.fps, from_capture) {
        (Some(f), _) if f.is_finite() && f > 0.0 => Ok(f),
        (Some(f), _) => bail!("--fps must be positive, got {f}"),
        (None, Some(f)) => Ok(f),
        (None, None) => bail!(
            "{}: capture.json gives no fps: add it there or pass --fps",
            a.video.display()
        ),
    }
}

/// `--scene`'s field (a warning when it was trained as an object) and `--scene-grid` when given.
pub(super) fn load_scene(a: &FitArgs) -> Result<(neus::checkpoint::LoadedField, Option<SdfGrid>)> {
    let field = load_field(&checkpoint_of(&a.scene)).map_err(|e| anyhow!("--scene {}: {e}", a.scene.display()))?;
    if field.config.kind != neus::CaptureSubject::Scene {
        tracing::warn!(
            "--scene {}: trained as an object capture, not a scene",
            a.scene.display()
        );
    }
    let grid = match &a.scene_grid {
        Some(p) => Some(SdfGrid::load(p).map_err(|e| anyhow!("--scene-grid: {e}"))?),
        None => None,
    };
    Ok((field, grid))
}

/// The rigid body of `--object name=dir`, its density `--density`'s; its mesh must have its centre of mass
/// at the body's origin (as `merge` and `train` write it).
pub(super) fn rigid_body(name: &str, object: &ObjectModel, dir: &Path, density: f64) -> Result<RigidBody> {
    let body = RigidBody::from_mesh(
        name,
        &object.mesh,
        MassSpec::Density(density),
        ContactSampling::default(),
        None,
    )
    .map_err(|e| anyhow!("--object {name}: {}: its mesh: {e}", dir.display()))?;
    if body.mesh_offset.norm() > 1e-5 {
        bail!(
            "--object {name}: the mesh's centre of mass is {:?} from the body origin",
            body.mesh_offset.to_array()
        );
    }
    Ok(body)
}

/// The settings' simulator values (`[sim]` at the video's rate and length, `[start_contact]`) checked before
/// anything is written: [`fit_world`] checks them again with the scene and bodies in place.
pub(super) fn check_sim_settings(fps: f64, frames: usize, cfg: &VideoFitConfig) -> Result<()> {
    let sim_cfg = SimConfig {
        fps,
        frames,
        ..cfg.sim.clone()
    };
    sim_cfg
        .validate()
        .map_err(|e| anyhow!("settings: sim.{}: {}", e.field, e.msg))?;
    cfg.start_contact
        .validate("start_contact")
        .map_err(|e| anyhow!("settings: {}: {}", e.field, e.msg))
}

/// The world the stages simulate: the scene's grid and `bodies` at placeholder states (every stage starts
/// from the first poses), the settings' `[sim]` at the video's rate and length.
pub(super) fn fit_world(
    grid: SdfGrid,
    fps: f64,
    frames: usize,
    cfg: &VideoFitConfig,
    bodies: Vec<RigidBody>,
) -> Result<World> {
    let sim_cfg = SimConfig {
        fps,
        frames,
        ..cfg.sim.clone()
    };
    let mut world = World::new(sim_cfg, sim::sdf::Shape::Grid(Arc::new(grid)));
    for body in bodies {
        let placeholder = BodyState::new([0.0; 3], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]);
        world.add_body(body, placeholder, cfg.start_contact, cfg.start_contact);
    }
    world
        .validate()
        .map_err(|e| anyhow!("settings: sim.{}: {}", e.field, e.msg))?;
    Ok(world)
}

/// The scene through the video's fixed camera, once: what every render of the fit composes its bodies over.
pub(super) fn scene_through(scene: &neus::checkpoint::LoadedField, cam: &Camera<f64>) -> Vec<ComposedRay> {
    let t = Instant::now();
    let pre = prerender_scene(scene, cam, &mut Composer::default());
    tracing::info!(
        "the scene rendered through the video's camera in {:.1} s",
        t.elapsed().as_secs_f64()
    );
    pre
}

/// The output folder: a new one (or, with `--force`, one emptied of stage results), or the same fit resumed;
/// `config.toml` records what it was made with. True when the same fit already finished there
/// (`trajectory.json`, written last, is in place): nothing is left to do.
pub(super) fn open_output(a: &FitArgs, record: &FitRecord) -> Result<bool> {
    let record_path = a.out.join("config.toml");
    let record_text = toml::to_string(record)?;
    if record_path.exists() && !a.force {
        let old = std::fs::read_to_string(&record_path)?;
        let same = toml::from_str::<FitRecord>(&old).is_ok_and(|r| r == *record);
        if !same {
            bail!(
                "{} holds a fit with other inputs or settings: give another --out, or --force to start over",
                a.out.display()
            );
        }
        let whole = a.stages.as_ref().is_none_or(|s| s.contains(&Stage::Pga));
        let done = a.out.join("trajectory.json");
        if whole && done.exists() {
            println!(
                "resuming the fit in {}: already finished, {} is in place (--force to fit again)",
                a.out.display(),
                done.display()
            );
            return Ok(true);
        }
        tracing::info!("resuming the fit in {}", a.out.display());
    } else {
        if a.force {
            for f in [
                "first_pose.json",
                "pa.json",
                "ga.json",
                "pga.json",
                "ga_tracked.json",
                "pga_tracked.json",
                "init_auto.json",
                "trajectory.json",
            ] {
                let _ = std::fs::remove_file(a.out.join(f));
            }
        }
        std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
        pganeus_io::write_atomic(&record_path, record_text.as_bytes())?;
    }
    Ok(false)
}

/// The scene's collision grid: `--scene-grid`'s, or baked from the scene run into the output folder once.
pub(super) fn scene_grid(
    given: Option<SdfGrid>,
    scene_field: &neus::checkpoint::LoadedField,
    a: &FitArgs,
) -> Result<SdfGrid> {
    if let Some(g) = given {
        return Ok(g);
    }
    let path = a.out.join("scene_grid.bin");
    if path.exists() {
        return Ok(SdfGrid::load(&path)?);
    }
    let t = Instant::now();
    let g = bake_scene(scene_field, &a.scene)?;
    g.save(&path)?;
    tracing::info!(
        "baked the scene's grid in {:.1} s: {}",
        t.elapsed().as_secs_f64(),
        path.display()
    );
    Ok(g)
}

/// `world` (and the job's) in the scene less the space GA saw the body in ([`carved_scene`]).
fn carve_seen_space(job: &mut Job, mut world: World, ga: &[FramePose]) -> Result<World> {
    let camera = job.frames[0].camera;
    if let Some((scene, raised)) = carved_scene(&world, &[(0, ga)], &camera, &job.cfg) {
        job.log(json!({"stage": "carve", "nodes_raised": raised}))?;
        world.scene = scene.clone();
        job.world.scene = scene;
        save_carved_scene(&world, &job.out)?;
    }
    Ok(world)
}

/// With `carve_scene`, `world`'s scene less the space GA saw each body of `seen` in ([`recon::seen_space`]),
/// and the grid nodes raised.
pub(super) fn carved_scene(
    world: &World,
    seen: &[(usize, &[FramePose])],
    camera: &Camera<f64>,
    cfg: &VideoFitConfig,
) -> Option<(sim::sdf::Shape, usize)> {
    if !cfg.carve_scene {
        return None;
    }
    let (scene, raised) = recon::scene_less_seen(world, seen, camera, cfg.ga.contact.image_slack)?;
    tracing::info!("the scene less the space GA saw the bodies in: {raised} grid nodes raised");
    Some((scene, raised))
}

/// The scene grid the final world simulates in, as `out/scene_carved.sdf` (`bake`'s format: a scene file's
/// `grid` shape replays the fit with it).
pub(super) fn save_carved_scene(world: &World, out: &Path) -> Result<()> {
    if let sim::sdf::Shape::Grid(grid) = &world.scene {
        grid.save(&out.join("scene_carved.sdf"))?;
    }
    Ok(())
}

/// The world at the first pose with the launch guess (PA's start, or PGA's with `--no-pa`).
fn launch_world(job: &Job, first: &FirstPose) -> World {
    let mut w = job.world.clone();
    w.initial[0] = BodyState::new(first.t, first.q, first.v, first.omega);
    w
}

pub(super) fn pose_of(t: [f64; 3], q: [f64; 4]) -> Pose<f64> {
    // A quaternion a stage wrote is kept bit for bit: a resumed fit goes on exactly.
    Pose::new(Quat::cst(q).unit(), Vec3::cst(t))
}

/// Stage 1: the first pose from the guess (lifted out of the scene), then the poses of the next frames the
/// same way, for the launch guess.
fn stage_first(job: &mut Job, guess: Option<Pose<f64>>, run: bool) -> Result<FirstPose> {
    let path = job.stage_file("first_pose.json");
    if path.exists() {
        let text = std::fs::read_to_string(&path)?;
        tracing::info!("first pose: from {}", path.display());
        return serde_json::from_str(&text).map_err(|e| anyhow!("{}: {e}", path.display()));
    }
    if !run {
        bail!("stage first has not run: {} is missing", path.display());
    }
    let searched = guess.is_none();
    let guess = match guess {
        Some(g) => g,
        None => auto_guess(job)?,
    };
    let body = &job.world.bodies[0];
    let (start, lift) = lift_out(body, &job.world.scene, guess);
    if lift > 0.0 {
        tracing::info!("the guess sank {:.1} mm into the scene: lifted out", lift * 1e3);
    }
    if searched {
        let exposure = exposure_at(&job.cfg.first_pose, &job.object, &job.scene_pre, &job.frames[0], start)?;
        for f in &mut job.frames {
            f.exposure = exposure;
        }
    }
    let cfg: &PoseFitConfig = &job.cfg.first_pose;
    let n = (1 + job.cfg.launch_frames).min(job.frames.len());
    let pb = super::progress(
        (cfg.iterations + cfg.iterations.div_ceil(2) * (n - 1)) as u64,
        "first pose",
    );
    let mut poses: Vec<Pose<f64>> = Vec::new();
    let mut first_eval = ImageLoss::default();
    for k in 0..n {
        // Frame 0 from the guess; the next ones carried on at the pace of the last two.
        let start_k = match k {
            0 => start,
            1 => poses[0],
            _ => carried_on(&poses[k - 2], &poses[k - 1]),
        };
        let start_k = job.frames[k].centred_on_mask(&start_k);
        // A launch frame starts at the pace of the frames before it, closer than a guess: half the steps.
        let cfg_k = PoseFitConfig {
            iterations: if k == 0 {
                cfg.iterations
            } else {
                cfg.iterations.div_ceil(2)
            },
            ..cfg.clone()
        };
        let steps = cfg_k.iterations;
        let mut fit = match PoseFromImage::new(cfg_k, &job.object, &job.scene_pre, &job.frames[k], start_k) {
            Ok(f) => f,
            Err(recon::PoseFitError::EmptyMask) if k == 0 => {
                bail!(
                    "{}: the body's mask is empty in frame 0: the first pose cannot be fitted",
                    job.video.display()
                )
            }
            Err(recon::PoseFitError::EmptyMask) => break,
            Err(e) => bail!("frame {k}: {e}"),
        };
        for i in 0..steps {
            let l = fit.step();
            if i % 10 == 0 {
                writeln!(
                    job.log,
                    "{}",
                    json!({"stage": "first_pose", "frame": k, "iteration": i, "loss": l.loss})
                )?;
            }
            pb.inc(1);
        }
        if k == 0 {
            first_eval = fit.evaluate();
        }
        // A launch frame where the body already touches the scene is past the flight the guess fits; the
        // second frame always counts (a slide whose first pose floats a millimetre has no other).
        let clear = |p: &Pose<f64>| recon::video_fit::clearance(&job.world.bodies[0], &job.world.scene, p);
        if k >= 2 && clear(&fit.pose) < TOUCHING && clear(&poses[0]) >= TOUCHING {
            break;
        }
        poses.push(fit.pose);
    }
    pb.finish_and_clear();
    // Any kept frame on the scene makes the launch a slide or a landing: no free fall to take out.
    let touching = poses
        .iter()
        .any(|p| recon::video_fit::clearance(&job.world.bodies[0], &job.world.scene, p) < TOUCHING);
    if touching {
        // On the scene from the start (a slide, a push): each pose within a centimetre of it is settled onto
        // it along the line of sight, where one view pins it least (the tabletop slide's first pose floated
        // 2.7 mm, 5.6 mm off along the ray, and PA's simulation started in the air, so GA's contact penalty
        // skipped frame 0 and PGA's launch rose at 0.1 m/s).
        let eye = job.frames[0].camera.world_to_cam.inverse().t;
        for (k, p) in poses.iter_mut().enumerate() {
            let c = recon::video_fit::clearance(&job.world.bodies[0], &job.world.scene, p);
            if c.abs() < recon::video_fit::SETTLE_BAND {
                if let Some(settled) =
                    recon::video_fit::settle_along_ray(&job.world.bodies[0], &job.world.scene, eye, p)
                {
                    tracing::info!(
                        "frame {k}: {:.1} mm {} the scene, settled onto it along the line of sight ({:.1} mm)",
                        c.abs() * 1e3,
                        if c >= 0.0 { "above" } else { "into" },
                        (settled.t - p.t).norm() * 1e3
                    );
                    *p = settled;
                }
            }
        }
    }
    let (v, omega) = launch_guess(&poses, job.fps, job.world.config.gravity, touching);
    let start = recon::video_fit::launch_start(
        &job.world.bodies[0],
        &job.world.scene,
        &poses[0],
        job.cfg.launch_in_plane,
    );
    let (v, omega) = start.allowed_launch(v, omega);
    if let StartContact::Touching { normal } | StartContact::Face { normal } = start {
        let face = matches!(start, StartContact::Face { .. });
        tracing::info!(
            "the body starts on the scene{} (normal {:?}): its launch is fitted along it{}",
            if face { " on a face" } else { "" },
            normal.map(|x| (x * 1e3).round() / 1e3),
            if face { ", its spin about the normal" } else { "" }
        );
    }
    let first = FirstPose {
        t: poses[0].t.to_array(),
        q: poses[0].q.to_array_re(),
        lift,
        v,
        omega,
        touching,
        start,
        iou: first_eval.iou(),
        loss: first_eval.loss,
        exposure: first_eval.measured_exposure(),
    };
    tracing::info!(
        "first pose: IoU {:.3}, launch guess v {:?} m/s{}; the video {:.2} times as bright as the object's captures",
        first.iou,
        v.map(|x| (x * 1e3).round() / 1e3),
        if touching { " (on the scene)" } else { "" },
        first.exposure
    );
    pganeus_io::write_atomic(&path, serde_json::to_string_pretty(&first)?.as_bytes())?;
    job.log(
        json!({"stage": "first_pose", "done": true, "iou": first.iou, "v": v, "omega": omega,
        "exposure": first.exposure}),
    )?;
    Ok(first)
}

/// The video's brightness relative to `object`'s captures at a searched first pose (`--init auto`): the
/// search's winner covers its mask, so the gain measured there holds for the first-pose fit too; a guess
/// from markers, centimetres off, is refined as captured and measured after.
pub(super) fn exposure_at(
    cfg: &PoseFitConfig,
    object: &ObjectModel,
    scene_pre: &[ComposedRay],
    frame: &FrameTarget,
    pose: Pose<f64>,
) -> Result<f64> {
    Ok(PoseFromImage::new(cfg.clone(), object, scene_pre, frame, pose)
        .map_err(|e| anyhow!("frame 0: {e}"))?
        .measure_exposure())
}

/// `--init auto`: the first pose searched from frame 0's mask and the body's resting sides; written to
/// `init_auto.json` as a guess relative to the object's reference capture, every candidate to the log.
fn auto_guess(job: &mut Job) -> Result<Pose<f64>> {
    let mut rows = Vec::new();
    let pose = search_first_pose_of(
        &job.cfg.auto_init,
        &job.world.bodies[0],
        &job.world.scene,
        &job.object,
        &job.scene_pre,
        &job.frames[0],
        &job.name,
        &job.video,
        &job.out,
        &mut rows,
    );
    for r in rows {
        job.log(r)?;
    }
    pose
}

/// `--init auto` for body `name`: its first pose searched from `frame`'s mask and its resting sides, each
/// candidate a row of `rows` (for the log), the pose added to `OUT/init_auto.json` as a guess relative to
/// the object's reference capture (the `init.json` format).
#[allow(clippy::too_many_arguments)]
pub(super) fn search_first_pose_of(
    cfg: &recon::FirstPoseSearchConfig,
    body: &RigidBody,
    scene: &sim::sdf::Shape,
    object: &ObjectModel,
    scene_pre: &[ComposedRay],
    frame: &FrameTarget,
    name: &str,
    video: &Path,
    out: &Path,
    rows: &mut Vec<Value>,
) -> Result<Pose<f64>> {
    let pb = super::progress(cfg.steps() as u64, &format!("first pose search: {name}"));
    let found = recon::search_first_pose(body, scene, object, scene_pre, frame, cfg, || pb.inc(1));
    pb.finish_and_clear();
    let (pose, candidates) = match found {
        Ok(f) => f,
        Err(recon::PoseFitError::EmptyMask) => bail!(
            "{}: body {name:?}'s mask is empty in frame 0: its first pose cannot be searched",
            video.display()
        ),
        Err(e) => bail!("{name}: frame 0: {e}"),
    };
    for c in &candidates {
        rows.push(
            json!({"stage": "first_pose_search", "body": name, "t": c.pose.t.to_array(),
            "q": c.pose.q.to_array_re(), "silhouette_iou": c.silhouette_iou, "depth_from": c.depth_from,
            "refined_loss": c.refined_loss}),
        );
    }
    let screened = candidates.iter().filter(|c| c.refined_loss.is_some()).count();
    tracing::info!(
        "{name}: first pose search: {} candidates, {screened} screened; the best at {:?} m",
        candidates.len(),
        pose.t.to_array().map(|x| (x * 1e4).round() / 1e4)
    );
    let path = out.join("init_auto.json");
    let mut all: Map<String, Value> = std::fs::read_to_string(&path)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or_default();
    let g = pose.compose(&object.primary.capture_from_body.inverse());
    all.insert(
        name.to_string(),
        json!({"capture": object.reference_capture, "t": g.t.to_array(), "q": g.q.to_array_re()}),
    );
    pganeus_io::write_atomic(&path, serde_json::to_string_pretty(&all)?.as_bytes())?;
    Ok(pose)
}

/// The world of a trajectory file this command wrote (its initial state and contact values).
fn world_from_file(job: &Job, path: &Path) -> Result<World> {
    let t = pganeus_io::read_trajectory(path)?;
    let b = t.bodies.first().ok_or_else(|| anyhow!("{}: no body", path.display()))?;
    let mut w = job.world.clone();
    w.initial[0] = BodyState::new(b.initial.t, b.initial.q, b.initial.v, b.initial.omega);
    w.scene_contact[0] = ContactParams {
        restitution: t.contact.restitution,
        friction: t.contact.friction,
    };
    Ok(w)
}

/// Per-frame image terms as JSON rows.
pub(super) fn metric_rows(losses: &[ImageLoss]) -> Value {
    json!(losses
        .iter()
        .enumerate()
        .map(|(k, l)| json!({
            "frame": k,
            "loss": l.loss,
            "psnr_window": (l.psnr() * 100.0).round() / 100.0,
            "iou": (l.iou() * 1e4).round() / 1e4,
            "seen": l.pixels > 0,
        }))
        .collect::<Vec<_>>())
}

fn write_world(job: &Job, path: &Path, world: &World, losses: &[ImageLoss], extra: Map<String, Value>) -> Result<()> {
    let traj = world.simulate(&world.params());
    let mut e = extra;
    e.insert("frames".into(), metric_rows(losses));
    let mut t = scene_file::trajectory_file(&job.capture, world, &traj, sim::ENGINE, e);
    t.bodies[0].extra.extend(object_entry(&job.object, "object.ply"));
    pganeus_io::write_trajectory(path, &t)?;
    Ok(())
}

/// Stage 2, PA.
fn stage_pa(job: &mut Job, first: &FirstPose, run: bool) -> Result<World> {
    let path = job.stage_file("pa.json");
    if path.exists() {
        tracing::info!("PA: from {}", path.display());
        return world_from_file(job, &path);
    }
    if !run {
        bail!("stage pa has not run: {} is missing", path.display());
    }
    let start = launch_world(job, first);
    let cfg = job.cfg.pa.clone();
    let pb = super::progress(cfg.iterations as u64, "PA");
    let (world, losses) = {
        let mut pa = PhysicsFromVideo::new(cfg.clone(), &job.object, &job.scene_pre, &job.frames, start, 0)
            .map_err(|e| anyhow!("PA: {e}"))?;
        pa = pa.with_start(first.start);
        let mut rows = Vec::new();
        while !pa.done() {
            let s = pa.step();
            rows.push(json!({"stage": "pa", "iteration": s.iteration, "window": s.window, "loss": s.loss}));
            pb.inc(1);
        }
        pb.finish_and_clear();
        for r in rows {
            writeln!(job.log, "{r}")?;
        }
        let r = pa.finish();
        if r.kept_start {
            tracing::warn!("PA: the launch guess explains the video better than PA's fit: kept");
        }
        (r.world, r.losses)
    };
    report_stage("PA", &world, &losses);
    write_world(job, &path, &world, &losses, Map::new())?;
    Ok(world)
}

pub(super) fn report_stage(stage: &str, world: &World, losses: &[ImageLoss]) {
    let seen: Vec<&ImageLoss> = losses.iter().filter(|l| l.pixels > 0).collect();
    let mean_iou = seen.iter().map(|l| l.iou()).sum::<f64>() / seen.len().max(1) as f64;
    let min_iou = seen.iter().map(|l| l.iou()).fold(f64::INFINITY, f64::min);
    let s = &world.initial[0];
    tracing::info!(
        "{stage}: IoU mean {mean_iou:.3}, worst {min_iou:.3}; v0 {:?} m/s, restitution {:.3}, friction {:.3}",
        s.v.to_array().map(|x| (x * 1e3).round() / 1e3),
        world.scene_contact[0].restitution,
        world.scene_contact[0].friction
    );
}

/// Stage 3, GA: every frame's pose from `start`'s simulation (PA's or the last PGA's), or tracked frame by
/// frame without PA.
fn stage_ga(job: &mut Job, start: &World, tracking: bool, run: bool, file: &str) -> Result<Vec<FramePose>> {
    let path = job.stage_file(file);
    if path.exists() {
        tracing::info!("GA: from {}", path.display());
        return read_ga(&path, job.frames.len());
    }
    if !run {
        bail!("stage ga has not run: {} is missing", path.display());
    }
    let traj = start.simulate(&start.params());
    let pb = super::progress(job.frames.len() as u64, "GA");
    let results = {
        let mut ga = if tracking {
            PosesFromVideo::tracking(
                job.cfg.ga.clone(),
                &job.object,
                &job.scene_pre,
                &job.frames,
                start,
                0,
                traj.frames[0][0].pose,
            )
        } else {
            PosesFromVideo::new(
                job.cfg.ga.clone(),
                &job.object,
                &job.scene_pre,
                &job.frames,
                start,
                0,
                &traj,
            )
        }
        .map_err(|e| anyhow!("GA: {e}"))?;
        // Every frame, then (with GA's `hypotheses`) the pass back over the frames it explains worst.
        pb.set_length(ga.steps_left() as u64);
        while !ga.done() {
            ga.step().map_err(|e| anyhow!("GA: {e}"))?;
            pb.inc(1);
            pb.set_length(pb.position() + ga.steps_left() as u64);
        }
        pb.finish_and_clear();
        ga.results.clone()
    };
    for (k, r) in results.iter().enumerate() {
        job.log(
            json!({"stage": "ga", "frame": k, "loss": r.image.loss, "iou": r.image.iou(),
            "contact_penalty": r.contact_penalty, "in_contact": r.in_contact, "fitted": r.fitted,
            "start": r.start.name()}),
        )?;
    }
    let losses: Vec<ImageLoss> = results.iter().map(|r| r.image.clone()).collect();
    let seen: Vec<f64> = losses.iter().filter(|l| l.pixels > 0).map(|l| l.iou()).collect();
    tracing::info!(
        "GA: IoU mean {:.3}, worst {:.3}",
        seen.iter().sum::<f64>() / seen.len().max(1) as f64,
        seen.iter().cloned().fold(f64::INFINITY, f64::min)
    );
    write_ga(job, &path, &results)?;
    Ok(results)
}

/// GA's poses as a trajectory file (poses only; the initial velocity is not GA's to say).
fn write_ga(job: &Job, path: &Path, results: &[FramePose]) -> Result<()> {
    let mut extra = Map::new();
    extra.insert(
        "frames".into(),
        metric_rows(&results.iter().map(|r| r.image.clone()).collect::<Vec<_>>()),
    );
    extra.insert("ga".into(), json!(results.iter().map(ga_row).collect::<Vec<_>>()));
    let t = pganeus_io::Trajectory {
        capture: job.capture.clone(),
        fps: job.fps,
        bodies: vec![pganeus_io::VideoBody {
            name: job.name.clone(),
            initial: pganeus_io::BodyState::from_geom(&results[0].pose, Vec3::zero(), Vec3::zero()),
            poses: results.iter().map(|r| pganeus_io::Pose::from_geom(&r.pose)).collect(),
            extra: object_entry(&job.object, "object.ply"),
        }],
        contact: pganeus_io::Contact {
            restitution: 0.0,
            friction: 0.0,
            model: "none".into(),
            extra: Map::new(),
        },
        extra,
    };
    pganeus_io::write_trajectory(path, &t)?;
    Ok(())
}

fn read_ga(path: &Path, frames: usize) -> Result<Vec<FramePose>> {
    let t = pganeus_io::read_trajectory(path)?;
    let b = t.bodies.first().ok_or_else(|| anyhow!("{}: no body", path.display()))?;
    let rows = t
        .extra
        .get("ga")
        .and_then(|v| v.as_array())
        .cloned()
        .unwrap_or_default();
    if b.poses.len() != frames || rows.len() != frames {
        bail!("{}: {} poses for {frames} frames", path.display(), b.poses.len());
    }
    Ok(frame_poses(&b.poses, &rows))
}

/// One GA frame as a row of `ga.json`'s `ga` list (what [`frame_poses`] reads back).
pub(super) fn ga_row(r: &FramePose) -> Value {
    json!({"in_contact": r.in_contact, "fitted": r.fitted, "start": r.start, "contact_penalty": r.contact_penalty,
        "loss": r.image.loss, "intersection": r.image.intersection, "union": r.image.union,
        "pixels": r.image.pixels, "mse": r.image.mse})
}

/// GA's frames from a `ga.json` body's poses and its rows ([`ga_row`]).
pub(super) fn frame_poses(poses: &[pganeus_io::Pose], rows: &[Value]) -> Vec<FramePose> {
    poses
        .iter()
        .zip(rows)
        .map(|(p, r)| {
            let f = |k: &str| r[k].as_f64().unwrap_or(0.0);
            let u = |k: &str| r[k].as_u64().unwrap_or(0) as usize;
            FramePose {
                pose: pose_of(p.t, p.q),
                image: ImageLoss {
                    loss: f("loss"),
                    mse: f("mse"),
                    intersection: u("intersection"),
                    union: u("union"),
                    pixels: u("pixels"),
                    ..ImageLoss::default()
                },
                contact_penalty: f("contact_penalty"),
                in_contact: r["in_contact"].as_bool().unwrap_or(false),
                fitted: r["fitted"].as_bool().unwrap_or(false),
                start: serde_json::from_value(r["start"].clone()).unwrap_or(StartFrom::Physics),
            }
        })
        .collect()
}

/// What stage 4 keeps.
struct PgaResult {
    /// The best world.
    world: World,
    /// GA's poses to report (those the world was fitted to, but for the frames the refit moved).
    ga: Vec<FramePose>,
    /// The GA ↔ PGA rounds kept.
    rounds: usize,
    ranges: Vec<ValueRange>,
    /// The launch over the flight alone and its test ([`launch_from_flight`]), where there is a flight.
    flight: Option<Value>,
}

/// Stage 4, PGA on GA's poses, then GA ↔ PGA while the simulated trajectory's image loss falls, then GA's
/// worst frames again from the kept world's simulation ([`stage_ga_from_pga`]).
fn stage_pga(
    job: &mut Job,
    start: World,
    ga: Vec<FramePose>,
    from_pa: bool,
    start_contact: StartContact,
) -> Result<PgaResult> {
    let weights_cfg = job.cfg.pa.weights.clone();
    // The kept round: its world, GA's poses, the image loss of its simulation, and its multi-start's starts
    // with the winner's loss (none for PA's world).
    type Kept = (World, Vec<FramePose>, f64, Option<FitStarts>);
    let mut best: Option<Kept> = None;
    if from_pa {
        // PA's own simulation is the bar: PGA fits GA's poses, and where GA is noisier than PA was (depth
        // from a small silhouette), a round that explains the images worse is not kept.
        let total = total_loss(&simulation_losses(job, &start, &weights_cfg)?);
        job.log(json!({"stage": "pga", "round": "pa", "image_loss": total}))?;
        best = Some((start.clone(), ga.clone(), total, None));
    }
    let mut ga = ga;
    let mut from = start;
    let mut kept = 0;
    for round in 0..job.cfg.rounds.max(1) {
        if round > 0 {
            let file = format!("ga_round{round}.json");
            ga = stage_ga(job, &from, false, true, &file)?;
        }
        let multi = job.cfg.pga_multi_start && round == 0;
        let starts = if multi { 1 + recon::CONTACT_STARTS.len() } else { 1 };
        let pb = super::progress(starts as u64, "PGA");
        let mut start_rows = Vec::new();
        let pga_cfg = pga_config(job);
        let observed = pga_observed(job, &ga, start_contact);
        let fit = fit_to_poses(&pga_cfg, multi, from.clone(), observed, &mut |i, r| {
            start_rows.push(
                json!({"stage": "pga", "round": round, "start": i, "restitution": r.restitution,
                "friction": r.friction, "loss": r.loss, "iterations": r.iterations,
                "fitted_restitution": r.fitted_restitution, "fitted_friction": r.fitted_friction}),
            );
            pb.inc(1);
        })
        .map_err(|e| anyhow!("PGA: {e}"))?;
        pb.finish_and_clear();
        for r in start_rows {
            job.log(r)?;
        }
        let (winner, sim_losses) = winner_by_images(job, &fit, json!({"stage": "pga", "round": round}))?;
        let total = total_loss(&sim_losses);
        let world = fit.worlds[winner].clone();
        report_stage(&format!("PGA round {}", round + 1), &world, &sim_losses);
        job.log(
            json!({"stage": "pga", "round": round, "winner": winner, "pga_winner": fit.winner,
            "image_loss": total}),
        )?;
        if best.as_ref().is_some_and(|(_, _, b, _)| total >= *b) {
            tracing::info!(
                "GA ↔ PGA: round {} did not lower the image loss; kept {}",
                round + 1,
                if kept == 0 {
                    "PA's".to_string()
                } else {
                    format!("round {kept}")
                }
            );
            break;
        }
        kept = round + 1;
        best = Some((
            world.clone(),
            ga.clone(),
            total,
            Some((fit.starts.clone(), fit.starts[winner].loss)),
        ));
        from = world;
    }
    let (mut world, fitted_ga, mut total, mut starts) = best.expect("at least one round");
    // The GA poses the reported world was fitted to (its value ranges are profiled on them), and GA's
    // poses to report.
    let (mut ranges_ga, mut ga) = (fitted_ga.clone(), fitted_ga);
    if kept > 0 && from_pa {
        let (refit, replaced) = stage_ga_from_pga(job, &world, &ga)?;
        ga = refit;
        if !replaced.is_empty() {
            // GA's poses moved where the simulation showed the way: PGA once more from its own winner, kept if
            // its simulation explains the video better (GA's new poses are kept either way: they explain
            // their frames better by construction).
            let observed = pga_observed(job, &ga, start_contact);
            let fit = fit_to_poses(&pga_config(job), false, world.clone(), observed, &mut |_, _| {})
                .map_err(|e| anyhow!("PGA after GA's refit: {e}"))?;
            let again = fit.worlds[fit.winner].clone();
            let losses = simulation_losses(job, &again, &weights_cfg)?;
            let again_total = total_loss(&losses);
            let better = again_total < total;
            job.log(json!({"stage": "pga_after_refit", "image_loss": again_total, "kept": better}))?;
            if better {
                report_stage("PGA after GA's refit", &again, &losses);
                world = again;
                total = again_total;
                ranges_ga = ga.clone();
                // The multi-start's starts were fitted to the poses before.
                starts = None;
            }
        }
    }
    let mut flight = None;
    if job.cfg.flight_test {
        let (held, record) = launch_from_flight(job, &world, total, &ranges_ga, start_contact)?;
        if let Some((held, held_total, held_starts)) = held {
            (world, total, starts) = (held, held_total, held_starts);
        }
        flight = record;
    }
    tracing::debug!("PGA: kept image loss {total:.4}");
    let mut ranges = value_ranges(job, &world, &ranges_ga, start_contact)?;
    if let Some((starts, loss)) = starts {
        recon::widen_by_starts(&mut ranges, &starts, recon::StartsOn::Scene, loss);
    }
    report_ranges(&ranges, &mut |row| job.log(row))?;
    Ok(PgaResult {
        world,
        ga,
        rounds: kept,
        ranges,
        flight,
    })
}

/// A multi-start's starts and the winner's loss (a range widens to the values its starts ended at).
type FitStarts = (Vec<StartResult>, f64);

/// The world with the flight's launch held, its simulation's image loss and its multi-start's starts.
type HeldLaunch = (World, f64, Option<FitStarts>);

/// The kept world's launch against the flight before its first contact ([`recon::flight`]): where it misses
/// the flight by more than GA's poses' noise, the world with the flight's launch held and the contact values
/// fitted around it (from the kept world's values and, with `pga_multi_start`, each of
/// [`recon::CONTACT_STARTS`]; the images choose among the starts within [`PGA_TIE`] as in PGA), kept if its
/// simulation explains the video better than the kept world's (image loss `kept_total`), with that loss and
/// its starts (none where the settings fit no contact value: the flight's world as it is); `None` where the
/// launch stands. Beside it, where there is a flight to test, its record for the trajectory's body entry
/// (`"flight"`): the launch fitted to the flight alone, the test and whether the held world was kept. The
/// flight's launch owes nothing to the contact model; the kept one explains the whole video (a launch bent
/// by contacts the model cannot make, or one the few frames of flight pin less well than all of them: the
/// note below), so both are reported.
///
/// The images decide, not the test alone: the flight's launch is fitted to a few of GA's poses, whose errors
/// are not independent from frame to frame (a depth that drifts over the flight), so the test flags a
/// launch that the contacts did not bend as well (the tabletop drop from `--init auto`: χ² 124 against 26,
/// its launch 0.9 % off and the flight's 5.8 %, whose simulation's image loss was twice as high).
fn launch_from_flight(
    job: &mut Job,
    world: &World,
    kept_total: f64,
    ga: &[FramePose],
    start_contact: StartContact,
) -> Result<(Option<HeldLaunch>, Option<Value>)> {
    let cfg = pga_config(job);
    let observed = pga_observed(job, ga, start_contact);
    let check = recon::check_flight(&cfg, world, std::slice::from_ref(&observed))
        .map_err(|e| anyhow!("PGA's launch against the flight: {e}"))?;
    let Some(check) = check else {
        return Ok((None, None));
    };
    let bent = check.bent();
    let flight = &check.flight_world.initial[0];
    let mut record = json!({"frames": check.frames, "statistic": check.statistic, "critical": check.critical,
        "bent": bent, "v0": flight.v.to_array(), "omega0": flight.omega.to_array(),
        "pose": {"t": flight.pose.t.to_array(), "q": flight.pose.q.to_array()}});
    tracing::info!(
        "the launch against the flight of {} frames: χ² {:.1} against {:.1} at 1 %: {}",
        check.frames,
        check.statistic,
        check.critical,
        if bent {
            "it misses the flight; the flight's launch held is tried"
        } else {
            "it stands"
        }
    );
    let v = |w: &World| w.initial[0].v.to_array();
    job.log(
        json!({"stage": "pga_flight", "frames": check.frames, "statistic": check.statistic,
        "critical": check.critical, "bent": bent, "v0": v(world), "flight_v0": v(&check.flight_world)}),
    )?;
    if !bent {
        return Ok((None, Some(record)));
    }
    let starts: &[(f64, f64)] = if job.cfg.pga_multi_start {
        &recon::CONTACT_STARTS
    } else {
        &[]
    };
    let pb = super::progress(1 + starts.len() as u64, "PGA, launch held");
    let held = recon::fit_holding_launch(&cfg, check.flight_world.clone(), vec![observed], starts, &mut |_, _| {
        pb.inc(1)
    });
    pb.finish_and_clear();
    let (world, losses, fit_starts) = match held {
        Ok(fit) => {
            let (winner, losses) = winner_by_images(job, &fit, json!({"stage": "pga_flight"}))?;
            let starts = (fit.starts.clone(), fit.starts[winner].loss);
            (fit.worlds[winner].clone(), losses, Some(starts))
        }
        // The settings hold the contact values too: the flight's world as it is.
        Err(recon::FitError::NothingToFit) => {
            let losses = simulation_losses(job, &check.flight_world, &job.cfg.pa.weights)?;
            (check.flight_world, losses, None)
        }
        Err(e) => bail!("PGA with the flight's launch: {e}"),
    };
    let total = total_loss(&losses);
    let kept = total < kept_total;
    report_stage("PGA, the flight's launch held", &world, &losses);
    tracing::info!(
        "the flight's launch held: image loss {total:.3} against {kept_total:.3}: {}",
        if kept { "kept" } else { "not kept" }
    );
    job.log(json!({"stage": "pga_flight", "image_loss": total, "kept": kept,
        "restitution": world.scene_contact[0].restitution, "friction": world.scene_contact[0].friction}))?;
    record["held_kept"] = json!(kept);
    Ok((kept.then_some((world, total, fit_starts)), Some(record)))
}

/// The image terms of the body's simulated poses in every frame of the video.
fn simulation_losses(job: &Job, world: &World, weights: &recon::ImageLossWeights) -> Result<Vec<ImageLoss>> {
    let traj = world.simulate(&world.params());
    let poses: Vec<Pose<f64>> = traj.frames.iter().map(|f| f[0].pose).collect();
    Ok(evaluate_poses(
        &job.object,
        &job.scene_pre,
        &job.frames,
        &poses,
        &[],
        weights,
    )?)
}

/// GA's frames explained worst fitted again from the kept PGA world's simulation
/// ([`PosesFromVideo::refit_worst_from_physics`]), resumed from `ga_pga.json`; GA's frames after it and
/// the frames replaced.
fn stage_ga_from_pga(job: &mut Job, world: &World, ga: &[FramePose]) -> Result<(Vec<FramePose>, Vec<usize>)> {
    let path = job.stage_file("ga_pga.json");
    if path.exists() {
        let r = read_ga(&path, job.frames.len())?;
        // The file holds GA's poses but where it replaced them (and the still frames that followed a replaced
        // frame): from another GA (rerun), it is stale.
        let mut moved = false;
        let same = r.iter().zip(ga).all(|(a, b)| {
            match a.start {
                StartFrom::Pga => moved = true,
                StartFrom::Still => {}
                _ => moved = false,
            }
            moved || a.pose == b.pose
        });
        if same {
            tracing::info!("GA from PGA's simulation: from {}", path.display());
            let replaced = (0..r.len()).filter(|&k| r[k].start == StartFrom::Pga).collect();
            return Ok((r, replaced));
        }
        tracing::warn!("{}: from another GA run; fitted again", path.display());
    }
    let traj = world.simulate(&world.params());
    let pb = super::progress(0, "GA from PGA");
    let (results, replaced, rows) = {
        let mut stage = PosesFromVideo::new(
            job.cfg.ga.clone(),
            &job.object,
            &job.scene_pre,
            &job.frames,
            world,
            0,
            &traj,
        )
        .and_then(|s| s.with_results(ga.to_vec()))
        .map_err(|e| anyhow!("GA from PGA's simulation: {e}"))?;
        let replaced = stage
            .refit_worst_from_physics(|| pb.inc(1))
            .map_err(|e| anyhow!("GA from PGA's simulation: {e}"))?;
        pb.finish_and_clear();
        tracing::info!(
            "GA from PGA's simulation: {} frames explained better ({replaced:?})",
            replaced.len()
        );
        let rows: Vec<Value> = replaced
            .iter()
            .map(|&k| {
                let r = &stage.results[k];
                json!({"stage": "ga_from_pga", "frame": k, "loss": r.image.loss, "iou": r.image.iou(),
                "contact_penalty": r.contact_penalty, "in_contact": r.in_contact, "was": ga[k].image.loss})
            })
            .collect();
        (stage.results, replaced, rows)
    };
    for row in rows {
        job.log(row)?;
    }
    write_ga(job, &path, &results)?;
    Ok((results, replaced))
}

/// PGA's starts that end within this share of the best one's loss fit GA's poses alike (the drop Rapier
/// made at 320×240: 0.0641 against 0.0680, launches 20 % apart), and the one whose simulation explains the
/// video best (its image loss over every frame) is kept: GA's poses are a proxy for the images. The same
/// share of the image loss is a tie too: the images overrule PGA's own pick only where they tell the starts
/// apart (the Rapier drop: 2.76 against 3.47; the backdrop slide's 0.748 against 0.755 do not, and the pick
/// they would have overruled had the launch spin right).
const PGA_TIE: f64 = 0.1;

/// The start of a PGA multi-start to keep: the starts that ended within [`PGA_TIE`] of the best fit GA's
/// poses alike, so the images choose among them ([`among_ties`]); with its simulation's image terms. Each
/// scored start is logged (`row` and the start's image loss and launch).
fn winner_by_images(job: &mut Job, fit: &MultiStart, row: Value) -> Result<(usize, Vec<ImageLoss>)> {
    let weights = job.cfg.pa.weights.clone();
    let pga_losses: Vec<f64> = fit.starts.iter().map(|r| r.loss).collect();
    let mut scored: Vec<Option<Vec<ImageLoss>>> = vec![None; pga_losses.len()];
    let winner = among_ties(&pga_losses, PGA_TIE, |i| -> Result<f64> {
        let w = &fit.worlds[i];
        let losses = simulation_losses(job, w, &weights)?;
        let total = total_loss(&losses);
        let mut r = row.clone();
        r["start"] = json!(i);
        r["tied_image_loss"] = json!(total);
        r["v0"] = json!(w.initial[0].v.to_array());
        r["omega0"] = json!(w.initial[0].omega.to_array());
        job.log(r)?;
        scored[i] = Some(losses);
        Ok(total)
    })?;
    // The pick is within the tie of itself: always scored.
    let losses = scored[winner].take().expect("the winner was scored");
    Ok((winner, losses))
}

/// The start to keep of a multi-start whose starts ended at `losses`: PGA's own pick (the lowest; the first
/// of equal ones) unless, of the starts within `tie` of it (`(1 + tie)` times its loss), the one `image_loss`
/// scores lowest beats the pick's score by more than `tie` too (each start scored once, in order).
fn among_ties(losses: &[f64], tie: f64, mut image_loss: impl FnMut(usize) -> Result<f64>) -> Result<usize> {
    let lowest = losses.iter().cloned().fold(f64::INFINITY, f64::min);
    let pick = losses
        .iter()
        .position(|&l| l == lowest)
        .ok_or_else(|| anyhow!("no start ended with a finite loss"))?;
    let mut pick_score = None;
    let mut best: Option<(usize, f64)> = None;
    for (i, &l) in losses.iter().enumerate() {
        if !(l <= lowest * (1.0 + tie)) {
            continue;
        }
        let score = image_loss(i)?;
        if i == pick {
            pick_score = Some(score);
        }
        if best.is_none_or(|(_, b)| score < b) {
            best = Some((i, score));
        }
    }
    Ok(match (best, pick_score) {
        (Some((i, b)), Some(p)) if p > b * (1.0 + tie) => i,
        _ => pick,
    })
}

/// PGA's settings: rotations in metres, as PA and GA weigh them (a quaternion error counts at the body's
/// radius).
fn pga_config(job: &Job) -> PhysicsFitConfig {
    PhysicsFitConfig {
        rotation_weight: job.cfg.pga.rotation_weight * job.world.bodies[0].bounding_radius,
        ..job.cfg.pga.clone()
    }
}

/// GA's poses as PGA observes them: weighed by GA's residuals and rests, each frame's depth counting least
/// where GA did not hold the body on the scene closer than its image tells the depth
/// ([`recon::ContactPenaltyConfig::pins_depth`]).
fn pga_observed(job: &Job, ga: &[FramePose], start_contact: StartContact) -> recon::Observed {
    let eye = job.frames[0].camera.center();
    let weights = ga_weights_of(ga, eye, job.world.bodies[0].bounding_radius);
    let poses: Vec<Pose<f64>> = ga.iter().map(|r| r.pose).collect();
    let pinned = job.cfg.ga.contact.pins_depth();
    recon::Observed {
        start: start_contact,
        eye: job.frames.first().map(|f| f.camera.center().to_array()),
        depth_held: ga.iter().map(|r| r.in_contact && pinned).collect(),
        ..recon::Observed::new(0, poses, Some(weights))
    }
}

/// The ranges of the reported world's contact values that GA's poses cannot tell apart (logged). The launch is
/// refitted with them even where the flight's is held: holding it would hide what its own uncertainty lets
/// the contact values do (the tabletop drop from a guess: restitution 0.452–0.483 held, the truth 0.5 outside).
fn value_ranges(
    job: &mut Job,
    world: &World,
    ga: &[FramePose],
    start_contact: StartContact,
) -> Result<Vec<ValueRange>> {
    let t = Instant::now();
    let cfg = PhysicsFitConfig {
        fit_initial_pose: false,
        ..pga_config(job)
    };
    let observed = pga_observed(job, ga, start_contact);
    let pb = super::progress(0, "value ranges");
    let ranges = recon::contact_value_ranges(&cfg, world.clone(), vec![observed], job.cfg.ranges, &super::follow(&pb))
        .map_err(|e| anyhow!("PGA's value ranges: {e}"))?;
    pb.finish_and_clear();
    tracing::info!("value ranges: {:.1} s", t.elapsed().as_secs_f64());
    Ok(ranges)
}

/// The value ranges in the log and in `log.jsonl` (through `write`).
pub(super) fn report_ranges(ranges: &[ValueRange], write: &mut dyn FnMut(Value) -> Result<()>) -> Result<()> {
    for r in ranges {
        tracing::info!(
            "{:?}: {:.3}, the motion cannot tell it from {:.3}–{:.3}",
            r.value,
            r.fitted,
            r.lo,
            r.hi
        );
        write(json!({"stage": "pga", "range": r}))?;
    }
    Ok(())
}

/// `"object"` of a body entry: the mesh and where the body frame sat in the reference capture.
pub(super) fn object_entry(object: &ObjectModel, mesh: &str) -> Map<String, Value> {
    let p = object.reference_pose;
    let mut e = Map::new();
    e.insert(
        "object".into(),
        json!({"mesh": mesh, "source": object.source,
            "reference": {"capture": object.reference_capture,
                "pose": {"t": p.t.to_array(), "q": p.q.to_array_re()}}}),
    );
    e
}

/// A frame's simulated silhouette IoU at least this far below GA's is one the simulation misses. A small
/// body's IoU differs by several hundredths between poses millimetres apart, and GA, fitting the silhouette
/// alone, wins it by moving in depth (a 14 px ball: 0.88 simulated against 0.96 by GA, the simulated pose
/// 2 mm closer to the truth), so only a clear miss counts.
const SIMULATION_MISSES_BY: f64 = 0.1;
/// A frame whose image loss (GA's terms, per pixel) under the simulation is more than this
/// many times GA's is one the simulation misses too, even with its silhouette in place: a tumble the
/// simulator turned another way (the tabletop drop's bounces: 10–15° off, at 1.5–4 times GA's loss). Where
/// both explain the image alike, the simulation's pose is kept (depth from physics, not from a silhouette's
/// size).
const SIMULATION_LOSS_RATIO: f64 = 1.5;

/// A simulated pose that draws its body this many pixels from GA's on average (its depth set to GA's) draws
/// it visibly elsewhere: four times the precision a silhouette's edge is placed to
/// ([`recon::image_precision::EDGE_PRECISION_PX`]). The silhouette margin above does not scale with the body's
/// size in the image: on a body 70 px wide it forgives a frame the simulation turned 5° and moved 2.6 mm
/// (2–3 px) off (the 320×240 tabletop drop's bounce: IoU 0.877 against GA's 0.961), where on a 14 px ball
/// it forgives a fraction of a pixel. Depth is left out: one view tells it least, and the simulation's is
/// weighed against GA's where GA's pose is reported.
const SIMULATION_MISSES_BY_PX: f64 = 4.0 * recon::image_precision::EDGE_PRECISION_PX;

/// How far apart two poses draw a body's `points` (body frame) through `camera`, in pixels on average,
/// `b`'s depth along its line of sight first set to `a`'s: what the image can tell of the difference.
pub(super) fn apart_across_px(a: &Pose<f64>, b: &Pose<f64>, points: &[Vec3<f64>], camera: &Camera<f64>) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let b = recon::video_fit::toward_depth_of(b, a, camera.center(), 1.0);
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
/// that GA's pose is reported there instead of the simulated one.
pub(super) fn simulation_misses(simulated: &ImageLoss, ga: &FramePose) -> bool {
    let silhouette_missed = simulated.iou() < ga.image.iou() - SIMULATION_MISSES_BY;
    let image_missed = simulated.loss > SIMULATION_LOSS_RATIO * ga.image.loss;
    ga.fitted && simulated.pixels > 0 && (silhouette_missed || image_missed)
}

/// Which pose a frame of the final trajectory reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ReportedPose {
    /// The simulation's (Eq. 11): it explains the frame.
    Simulated,
    /// GA's pose slid along its line of sight toward the simulation's depth, GA's and the simulation's depth
    /// weighed by what each tells ([`recon::video_fit::depth_share`]): the simulation misses the frame (a
    /// turn the simulator cannot make), and the weighed pose explains it.
    GaAtWeighedDepth,
    /// GA's own pose: neither of the above explains the frame.
    Ga,
}

impl ReportedPose {
    pub(super) fn name(self) -> &'static str {
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
/// it misses. The two depths are weighed by those errors ([`recon::video_fit::depth_share`]: GA's
/// from the body's apparent size in `camera`'s pixels and the frame's loss against the median frame's,
/// the simulation's from how far it is from GA across the line of sight in the frame and the frames
/// beside it). A switch to the simulation's depth wherever it followed the body across the line of
/// sight was right at 160×120 and wrong at 320×240, where GA's depth is the better one (the drop: 0.9 mm
/// against the simulation's 1.6). The simulation also misses a frame it draws the body visibly elsewhere in
/// than GA ([`SIMULATION_MISSES_BY_PX`] across the line of sight, its image loss above GA's). `radius`:
/// the body's bounding radius; `points`: points on its surface (body frame). `score` gives the image terms
/// of poses, one per frame (the frames not asked about are scored at the simulated pose and ignored).
pub(super) fn reported_poses<E>(
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
                let slid = recon::video_fit::toward_depth_of(&ga[k].pose, &simulated[k], eye, 1.0);
                let z = (ga[k].pose.t - eye).norm();
                (simulated[k].t - slid.t).norm().max(apart_px[k] * z / camera.k.fx)
            } else {
                0.0
            }
        })
        .collect();
    let median_loss =
        recon::poses_from_video::median_fitted_loss(ga.iter().map(|g| (g.image.loss, g.fitted))).unwrap_or(0.0);
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
        let share = recon::video_fit::depth_share(z, 2.0 * radius, camera.k.fx, loss_ratio, sim_across);
        recon::video_fit::toward_depth_of(&ga[k].pose, &simulated[k], eye, share)
    };
    let missed: Vec<bool> = (0..n)
        .map(|k| {
            let (s, g) = (&simulated_losses[k], &ga[k]);
            let drawn_elsewhere =
                g.fitted && s.pixels > 0 && s.loss > g.image.loss && apart_px[k] > SIMULATION_MISSES_BY_PX;
            simulation_misses(s, g) || drawn_elsewhere
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
        (poses[k], source[k]) = if simulation_misses(&weighed_losses[k], &ga[k]) {
            (ga[k].pose, ReportedPose::Ga)
        } else {
            (candidates[k], ReportedPose::GaAtWeighedDepth)
        };
    }
    Ok((poses, source))
}

/// The final trajectory (simulated, where it explains the video; GA's pose where it clearly does not),
/// renders, the strip and the animation.
fn finish(
    job: &mut Job,
    world: &World,
    ga: Option<&[FramePose]>,
    ranges: &[ValueRange],
    flight: Option<&Value>,
    timings: &Map<String, Value>,
    t_start: Instant,
) -> Result<()> {
    let traj = world.simulate(&world.params());
    let n = job.frames.len();
    let sim_poses: Vec<Pose<f64>> = traj.frames.iter().map(|f| f[0].pose).collect();
    // Scored with GA's terms: `simulation_misses` compares these with GA's own losses.
    let weights = job.cfg.ga.pose.weights.clone();
    let sim_losses = evaluate_poses(&job.object, &job.scene_pre, &job.frames, &sim_poses, &[], &weights)?;
    // The reported pose is the simulated one (Eq. 11) wherever it explains the frame: GA's poses follow
    // each image alone and, where the image cannot tell depth (a small object far off), wander by
    // centimetres that the physics does not. Where the simulation clearly misses the body's silhouette
    // (motion the simulator cannot make), GA's pose is reported instead; both stay in pga.json and ga.json
    // (and ga_pga.json: GA's after the frames refitted from the simulation).
    let (reported, source) = match ga {
        Some(ga) => {
            let at_depth =
                |poses: &[Pose<f64>]| evaluate_poses(&job.object, &job.scene_pre, &job.frames, poses, &[], &weights);
            reported_poses(
                &sim_poses,
                &sim_losses,
                ga,
                &job.frames[0].camera,
                (world.bodies[0].bounding_radius, &world.bodies[0].contact_points),
                at_depth,
            )?
        }
        None => (sim_poses.clone(), vec![ReportedPose::Simulated; n]),
    };
    let source: Vec<&str> = source.iter().map(|s| s.name()).collect();
    // Renders of the reported poses over the pre-rendered scene.
    let (w, h) = (job.frames[0].camera.width, job.frames[0].camera.height);
    std::fs::create_dir_all(job.out.join("render"))?;
    let pb = super::progress(n as u64, "render");
    let mut composer = Composer::default();
    let mut rows = Vec::with_capacity(n);
    let mut pairs = Vec::with_capacity(n);
    for k in 0..n {
        let f = &job.frames[k];
        let routed = job.object.route(&reported[k], &f.camera);
        let layer = Layer::object(&routed.field, &routed.capture_from_body, &reported[k], 0);
        let img = render_composed(&[layer], 1, Behind::Scene(&job.scene_pre), &f.camera, &mut composer);
        let mut rgb = Image::new(w, h, 3);
        for (p, c) in img.rgb.iter().enumerate() {
            rgb.data[p * 3..p * 3 + 3].copy_from_slice(&c.map(to8));
        }
        pganeus_io::write_png(&job.out.join("render").join(format!("{k:03}.png")), &rgb)?;
        let psnr = neus::render_view::psnr(&img.rgb, &f.rgb, None) as f64;
        let ours: Vec<bool> = img.object_opacity.iter().map(|&o| o > 0.5).collect();
        let inter = ours.iter().zip(&f.mask).filter(|(a, b)| **a && **b).count();
        let union = ours.iter().zip(&f.mask).filter(|(a, b)| **a || **b).count();
        let iou = if union == 0 { 1.0 } else { inter as f64 / union as f64 };
        rows.push(
            json!({"frame": k, "psnr": (psnr * 100.0).round() / 100.0, "iou": (iou * 1e4).round() / 1e4,
            "pose": source[k]}),
        );
        let mut input = Image::new(w, h, 3);
        for (p, c) in f.rgb.iter().enumerate() {
            input.data[p * 3..p * 3 + 3].copy_from_slice(&c.map(to8));
        }
        pairs.push(beside(&input, &rgb));
        pb.inc(1);
    }
    pb.finish_and_clear();
    pganeus_io::write_apng(&job.out.join("animation.png"), &pairs, job.fps)?;
    pganeus_io::write_png(&job.out.join("strip.png"), &strip(&pairs, 6))?;

    let mut extra = Map::new();
    extra.insert("frames".into(), json!(rows));
    let mut stages = Map::new();
    stages.insert("simulated".into(), metric_rows(&sim_losses));
    if let Some(ga) = ga {
        stages.insert(
            "ga".into(),
            metric_rows(&ga.iter().map(|r| r.image.clone()).collect::<Vec<_>>()),
        );
    }
    extra.insert("stages".into(), Value::Object(stages));
    extra.insert("timings_s".into(), Value::Object(timings.clone()));
    extra.insert("video".into(), json!(job.video));
    let mut t = scene_file::trajectory_file(&job.capture, world, &traj, sim::ENGINE, extra);
    write_ranges(&mut t, ranges);
    for (pose, r) in t.bodies[0].poses.iter_mut().zip(&reported) {
        *pose = pganeus_io::Pose::from_geom(r);
    }
    t.bodies[0].extra.extend(object_entry(&job.object, "object.ply"));
    if let Some(f) = flight {
        t.bodies[0].extra.insert("flight".into(), f.clone());
    }
    // The object's mesh beside the trajectory, in the body frame.
    pganeus_io::write_ply(
        &job.out.join("object.ply"),
        &pganeus_io::PlyMesh {
            mesh: job.object.mesh.clone(),
            colors: None,
            normals: None,
        },
        pganeus_io::PlyEncoding::BinaryLittleEndian,
    )?;
    if ga.is_some() {
        let mut simulated = scene_file::trajectory_file(&job.capture, world, &traj, sim::ENGINE, Map::new());
        simulated.bodies[0]
            .extra
            .extend(object_entry(&job.object, "object.ply"));
        pganeus_io::write_trajectory(&job.out.join("pga.json"), &simulated)?;
    }
    pganeus_io::write_trajectory(&job.out.join("trajectory.json"), &t)?;
    let psnr: Vec<f64> = rows.iter().filter_map(|r| r["psnr"].as_f64()).collect();
    let ious: Vec<f64> = rows.iter().filter_map(|r| r["iou"].as_f64()).collect();
    let s = &world.initial[0];
    println!(
        "fitted {n} frames in {:.1} s: v0 {:?} m/s, omega0 {:?} rad/s, restitution {:.3}, friction {:.3}; \
         PSNR {:.2} dB, IoU against the masks mean {:.3} worst {:.3}; {} frames reported from GA (the simulation misses them), \
         {} of them at a depth weighed with the simulation's; wrote {}",
        t_start.elapsed().as_secs_f64(),
        s.v.to_array().map(|x| (x * 1e3).round() / 1e3),
        s.omega.to_array().map(|x| (x * 1e3).round() / 1e3),
        world.scene_contact[0].restitution,
        world.scene_contact[0].friction,
        psnr.iter().sum::<f64>() / psnr.len().max(1) as f64,
        ious.iter().sum::<f64>() / ious.len().max(1) as f64,
        ious.iter().cloned().fold(f64::INFINITY, f64::min),
        source.iter().filter(|s| **s != "simulated").count(),
        source
            .iter()
            .filter(|s| **s == ReportedPose::GaAtWeighedDepth.name())
            .count(),
        job.out.join("trajectory.json").display()
    );
    Ok(())
}

/// Each contact value's range ([`recon::value_ranges`]) beside the value in a trajectory file:
/// `restitution_range` and `friction_range`, `[lo, hi]`, in `contact` (the scene's), in a body entry (the
/// scene's against one body, when not shared) or in a `contact.pairs` entry.
pub(super) fn write_ranges(t: &mut pganeus_io::Trajectory, ranges: &[ValueRange]) {
    use recon::ContactValue as C;
    for r in ranges {
        let key = match r.value {
            C::SceneRestitution(_) | C::PairRestitution(_) => "restitution_range",
            C::SceneFriction(_) | C::PairFriction(_) => "friction_range",
        };
        let entry = json!([r.lo, r.hi]);
        match r.value {
            C::SceneRestitution(None) | C::SceneFriction(None) => {
                t.contact.extra.insert(key.into(), entry);
            }
            C::SceneRestitution(Some(b)) | C::SceneFriction(Some(b)) => {
                if let Some(body) = t.bodies.get_mut(b) {
                    body.extra.insert(key.into(), entry);
                }
            }
            C::PairRestitution(p) | C::PairFriction(p) => {
                if let Some(pair) = t
                    .contact
                    .extra
                    .get_mut("pairs")
                    .and_then(|v| v.as_array_mut())
                    .and_then(|a| a.get_mut(p))
                    .and_then(|v| v.as_object_mut())
                {
                    pair.insert(key.into(), entry);
                }
            }
        }
    }
}

/// Up to `count` frames, evenly spaced, one above the other.
pub(super) fn strip(pairs: &[Image], count: usize) -> Image {
    let n = pairs.len();
    let picks: Vec<usize> = if n <= count {
        (0..n).collect()
    } else {
        (0..count).map(|i| i * (n - 1) / (count - 1)).collect()
    };
    let (w, h) = (pairs[0].width, pairs[0].height);
    let mut out = Image::new(w, h * picks.len() as u32, 3);
    for (row, &k) in picks.iter().enumerate() {
        let len = (w * h * 3) as usize;
        let at = row * len;
        out.data[at..at + len].copy_from_slice(&pairs[k].to_rgb().data);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let score = |poses: &[Pose<f64>]| -> Result<Vec<ImageLoss>> {
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
        let score = |poses: &[Pose<f64>]| -> Result<Vec<ImageLoss>> { Ok(vec![terms(0.02); poses.len()]) };
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
        let score = |poses: &[Pose<f64>]| -> Result<Vec<ImageLoss>> { Ok(vec![terms(0.021); poses.len()]) };
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
    fn the_images_choose_among_starts_that_fit_the_poses_alike() {
        // Starts 1 and 2 tie (within a tenth); start 3 explains the images best but fits the poses worse.
        let pga = [1.0, 0.50, 0.54, 0.9];
        let image = [3.0, 2.5, 2.0, 1.0];
        let mut asked = Vec::new();
        let chosen = among_ties(&pga, 0.1, |i| {
            asked.push(i);
            Ok(image[i])
        })
        .unwrap();
        assert_eq!((chosen, asked), (2, vec![1, 2]));
        // Images that tie too (2.4 against 2.5: within a tenth) leave PGA's own pick.
        let image = [3.0, 2.5, 2.4, 1.0];
        assert_eq!(among_ties(&pga, 0.1, |i| Ok(image[i])).unwrap(), 1);
        // PGA's pick is the first of equal losses.
        assert_eq!(among_ties(&[0.5, 0.5], 0.1, |_| Ok(1.0)).unwrap(), 0);
        // Without a tie the lowest loss wins, scored once.
        assert_eq!(among_ties(&pga, 0.0, |_| Ok(0.0)).unwrap(), 1);
        assert!(among_ties(&[f64::NAN], 0.1, |_| Ok(0.0)).is_err());
    }
}
