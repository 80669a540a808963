//! `fit`: each body's pose in every frame of a fixed-camera video and the physics that explains it
//! (Sec. 3.3–3.4): the first pose from a rough guess (or searched, `init = auto`), PA, GA with the contact
//! penalty of Eq. 10, and PGA (Eq. 11; GA ↔ PGA while it helps); with several bodies, the collision
//! schedule (`fit/several.rs`). Each stage's result is written to the run folder as it ends, so a run that stops
//! resumes at the stage it was in (same inputs and settings).
//!
//! ```no_run
//! use pipeline::fit::{FitInputs, FitRun, Stage};
//! use pipeline::{Quiet, Resume};
//!
//! let inputs = FitInputs::new("data/slide", "runs/scene", [("toy", "merged/toy")]);
//! let run = FitRun::open(inputs, recon::VideoFitConfig::default(), "fits/slide", Resume::Continue)?;
//! let outcome = run.run(&[Stage::First, Stage::Pa, Stage::Ga, Stage::Pga], &Quiet)?;
//! let world = outcome.world.expect("PGA ran");
//! println!("restitution {:.3}", world.scene_contact[0].restitution);
//! # Ok::<(), pipeline::Error>(())
//! ```

mod args;
mod several;
mod single;

pub use args::{run, FitArgs};

use crate::cameras::{fixed_camera, scene_through};
use crate::error::{err, fail, Context};
use crate::images::{read_mask, reference_frame};
use crate::run_folder::checkpoint_of;
use crate::{Error, Observer, Result, Resume, Task};
use geom::{Camera, Pose, Quat, Vec3};
use neus::checkpoint::load_field;
use neus::compose::{ComposedRay, Composer};
use neus::ObjectModel;
use pganeus_io::Image;
use recon::video_fit::pose_from_guess;
use recon::{
    FramePose, FrameTarget, ImageLoss, PoseFitConfig, PoseFromImage, ReportedPose, StartFrom, ValueRange,
    VideoFitConfig,
};
use serde::{Deserialize, Serialize};
use serde_json::{json, Map, Value};
use sim::sdf::SdfGrid;
use sim::{BodyState, ContactSampling, MassSpec, RigidBody, SimConfig, World};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// What a fit reads: the video, the scene, the bodies and the first-pose guess.
#[derive(Clone, Debug, PartialEq)]
pub struct FitInputs {
    /// The video: a capture in the NeuS layout from one fixed camera, with `mask/` (one body) or
    /// `mask_<NAME>/`, and `capture.json` giving the fps.
    pub video: PathBuf,
    /// The scene's run folder (its field renders the background).
    pub scene: PathBuf,
    /// The scene's baked grid for contacts (`bake` output); none: baked from the scene run into the run folder.
    pub scene_grid: Option<PathBuf>,
    /// Each body: its name (the video's `mask_<NAME>/`) and its `merge` output (or a single run folder).
    pub objects: Vec<(String, PathBuf)>,
    /// The first-pose guess (init.json), or `auto`: searched from the first frame's mask.
    pub init: PathBuf,
    /// Use the first N frames of the video (all when none).
    pub frames: Option<usize>,
    /// Frames per second (none: the video's `capture.json`).
    pub fps: Option<f64>,
    /// Seconds the shutter was open in each frame (none: the video's `capture.json`, an instant without one):
    /// a moving body is drawn over it. 0: every frame an instant.
    pub shutter: Option<f64>,
    /// Density of the bodies, kg/m³ (the motion against a static scene does not depend on it). Default 1000.
    pub density: f64,
    /// Ablation: no PA; GA tracks frame by frame from the previous frame, then PGA.
    pub no_pa: bool,
    /// Ablation: PA alone (no GA, no PGA).
    pub no_ga: bool,
}

impl FitInputs {
    /// A fit of `objects` (name, folder) in `video` over the scene run `scene`, the first pose searched
    /// (`init = auto`), every frame, the video's fps, the whole method.
    pub fn new<N: Into<String>, P: Into<PathBuf>>(
        video: impl Into<PathBuf>,
        scene: impl Into<PathBuf>,
        objects: impl IntoIterator<Item = (N, P)>,
    ) -> FitInputs {
        FitInputs {
            video: video.into(),
            scene: scene.into(),
            scene_grid: None,
            objects: objects.into_iter().map(|(n, p)| (n.into(), p.into())).collect(),
            init: PathBuf::from("auto"),
            frames: None,
            fps: None,
            shutter: None,
            density: 1000.0,
            no_pa: false,
            no_ga: false,
        }
    }
}

/// The stages of a fit, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
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

impl Stage {
    /// Every stage, in order.
    pub const ALL: [Stage; 4] = [Stage::First, Stage::Pa, Stage::Ga, Stage::Pga];

    /// The stage's name in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Stage::First => "first",
            Stage::Pa => "pa",
            Stage::Ga => "ga",
            Stage::Pga => "pga",
        }
    }
}

/// What a fit ended with: the stages' results (as far as the run went) and the files it wrote.
#[derive(Clone, Debug, Default)]
pub struct FitOutcome {
    /// The run folder held this fit finished already: nothing was run (the results are in its files).
    pub finished_before: bool,
    /// Each body's pose in frame 0 (the first-pose stage's).
    pub first_poses: Vec<Pose<f64>>,
    /// PA's world (one body, when PA ran).
    pub pa: Option<World>,
    /// GA's poses, per body and frame: those reported beside the simulation.
    pub ga: Option<Vec<Vec<FramePose>>>,
    /// The fitted world (PGA's kept one; PA's with `no_ga`): its initial states and contact values are the
    /// fitted launch and physics. None when the run stopped before.
    pub world: Option<World>,
    /// Per body and frame, the pose `trajectory.json` reports and where it came from.
    pub reported: Option<Vec<Vec<ReportedFrame>>>,
    /// The contact values' ranges that the poses cannot tell apart.
    pub ranges: Vec<ValueRange>,
    /// The stage files read back from the run folder instead of run (a resumed fit), in order.
    pub read_back: Vec<PathBuf>,
    /// One line a user reads: the fitted values, the fit to the images, where the trajectory is.
    pub summary: String,
    /// `trajectory.json`, when the whole fit ran.
    pub trajectory: Option<PathBuf>,
    /// The files the run folder holds when the run ends (its stage files, log, renders' folder, ...), sorted.
    pub files: Vec<PathBuf>,
}

/// The pose a frame of the fit reports, and where it came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReportedFrame {
    pub pose: Pose<f64>,
    pub from: ReportedPose,
}

/// A fit's run folder, opened: the inputs read and checked, the folder holding this fit's record.
pub struct FitRun {
    inputs: FitInputs,
    config: VideoFitConfig,
    out: PathBuf,
    prepared: Prepared,
}

enum Prepared {
    One(Box<single::Prepared>),
    Several(Box<several::Prepared>),
}

impl FitRun {
    /// Reads and checks every input (the video, its masks, the objects, the guesses, the scene and the
    /// settings) before anything is written, then opens `out`: a new folder, the same fit to resume
    /// ([`Resume::Continue`]; a folder holding a fit with other inputs or settings is refused), or one
    /// emptied of stage results ([`Resume::StartOver`]).
    pub fn open(inputs: FitInputs, config: VideoFitConfig, out: impl Into<PathBuf>, resume: Resume) -> Result<FitRun> {
        let out = out.into();
        if inputs.objects.is_empty() {
            fail!(Settings, "a fit needs at least one body (--object NAME=DIR)");
        }
        if !(inputs.density.is_finite() && inputs.density > 0.0) {
            fail!(Settings, "--density must be positive, got {}", inputs.density);
        }
        let (prepared, record) = if inputs.objects.len() == 1 {
            let (p, r) = single::prepare(&inputs, &config)?;
            (Prepared::One(Box::new(p)), r)
        } else {
            let (p, r) = several::prepare(&inputs, &config)?;
            (Prepared::Several(Box::new(p)), r)
        };
        open_output(&out, &record, resume)?;
        Ok(FitRun {
            inputs,
            config,
            out,
            prepared,
        })
    }

    /// The run folder.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// Runs `stages` (the earlier ones' results must be in the run folder; the fit stops after the last one
    /// named), each read back from its file where it finished before, reporting to `observer`.
    pub fn run(self, stages: &[Stage], observer: &dyn Observer) -> Result<FitOutcome> {
        let t_start = Instant::now();
        let whole = stages.contains(&Stage::Pga);
        let done = self.out.join("trajectory.json");
        if whole && done.exists() {
            tracing::info!("resuming the fit in {}: already finished", self.out.display());
            return Ok(FitOutcome {
                finished_before: true,
                files: folder_files(&self.out),
                summary: format!(
                    "resuming the fit in {}: already finished, {} is in place (--force to fit again)",
                    self.out.display(),
                    done.display()
                ),
                trajectory: Some(done),
                ..FitOutcome::default()
            });
        }
        let ctx = RunContext {
            inputs: &self.inputs,
            config: &self.config,
            out: &self.out,
            stages,
            observer,
            t_start,
        };
        let mut outcome = match self.prepared {
            Prepared::One(p) => single::run(*p, &ctx)?,
            Prepared::Several(p) => several::run(*p, &ctx)?,
        };
        outcome.files = folder_files(&self.out);
        Ok(outcome)
    }
}

/// The entries of `dir`, sorted (none if it cannot be read).
fn folder_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    files.sort();
    files
}

/// What every stage of a run reads besides its inputs.
struct RunContext<'a> {
    inputs: &'a FitInputs,
    config: &'a VideoFitConfig,
    out: &'a Path,
    stages: &'a [Stage],
    observer: &'a dyn Observer,
    t_start: Instant,
}

/// `OUT/log.jsonl`, one JSON object per line (appended to: a resumed fit adds to it).
struct Log {
    file: std::fs::File,
    path: PathBuf,
    /// The stage files read back instead of run, in order.
    read_back: Vec<PathBuf>,
}

impl Log {
    fn open(out: &Path) -> Result<Log> {
        let path = out.join("log.jsonl");
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .with_context(|| format!("cannot open {}", path.display()))?;
        Ok(Log {
            file,
            path,
            read_back: Vec::new(),
        })
    }

    /// `stage`'s result is read back from `file` (a resumed run).
    fn read_back(&mut self, stage: &str, file: &Path) {
        tracing::info!("{stage}: from {}", file.display());
        self.read_back.push(file.to_path_buf());
    }

    fn write(&mut self, v: Value) -> Result<()> {
        use std::io::Write;
        writeln!(self.file, "{v}").with_context(|| format!("cannot write {}", self.path.display()))
    }
}

/// `outcome` with the stage files `log` read back.
fn with_read_back(mut outcome: FitOutcome, log: &Log) -> FitOutcome {
    outcome.read_back = log.read_back.clone();
    outcome
}

/// A PGA start's result as a `log.jsonl` row: `row` (the stage and where in it) with the start's number and
/// its values.
fn start_row(mut row: Value, i: usize, r: &recon::StartResult) -> Value {
    row["start"] = json!(i);
    for (key, value) in [
        ("restitution", json!(r.restitution)),
        ("friction", json!(r.friction)),
        ("loss", json!(r.loss)),
        ("iterations", json!(r.iterations)),
        ("fitted_restitution", json!(r.fitted_restitution)),
        ("fitted_friction", json!(r.fitted_friction)),
    ] {
        row[key] = value;
    }
    row
}

/// The video's name in trajectory files: its folder's.
fn capture_name(video: &Path) -> String {
    video
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "video".into())
}

/// The record of an input set and settings (`config.toml`) for `frames` frames at `fps`.
fn record_of(inputs: &FitInputs, config: &VideoFitConfig, frames: usize, fps: f64, shutter: f64) -> FitRecord {
    FitRecord {
        inputs: RecordInputs {
            video: inputs.video.clone(),
            scene: inputs.scene.clone(),
            object: inputs
                .objects
                .iter()
                .map(|(n, d)| format!("{n}={}", d.display()))
                .collect::<Vec<_>>()
                .join(","),
            init: inputs.init.clone(),
            frames,
            fps,
            shutter,
            no_pa: inputs.no_pa,
            no_ga: inputs.no_ga,
        },
        fit: config.clone(),
    }
}

/// Whether `init` asks for the first pose to be searched.
fn is_auto(init: &Path) -> bool {
    init.as_os_str() == "auto"
}

/// Where the simulation of the fitted `world` stops converging in its step size, seen by `camera`
/// ([`recon::horizon`]), logged when that is before the video's end.
fn horizon_of(world: &World, camera: &Camera<f64>, log: &mut Log) -> Result<recon::Horizon> {
    let h = recon::predictable_frames(world, camera);
    let n = h.spread_px.len();
    if h.ends_early() {
        tracing::info!(
            "the fitted motion converges in its step size over frames 0-{} of {n} only (twice the substeps draw \
             it {:.1} px away by the end): the frames after cannot tell the physics, whatever made them; the \
             value ranges widen to what the frames before allow",
            h.frames.saturating_sub(1),
            h.spread_px.last().copied().unwrap_or(0.0)
        );
    }
    log.write(json!({"stage": "horizon", "predictable_frames": h.frames, "frames": n,
        "step_spread_px": h.spread_px.iter().map(|d| (d * 100.0).round() / 100.0).collect::<Vec<_>>()}))?;
    Ok(h)
}

/// `trajectory.json`'s record of the motion's predictable horizon ([`horizon_of`]).
fn horizon_entry(h: &recon::Horizon) -> Value {
    json!({"predictable_frames": h.frames, "threshold_px": recon::HORIZON_PX,
        "step_spread_px": h.spread_px.iter().map(|d| (d * 100.0).round() / 100.0).collect::<Vec<_>>()})
}

/// A frame's row of `trajectory.json` with where the simulation draws the body (its pose, as the body's
/// poses are written) and, where GA fitted the frame, how far that is from GA's pose: what `eval` and the
/// report show of how much of the motion the fitted physics explains.
pub(crate) fn with_simulation(mut row: Value, sim: &Pose<f64>, ga: Option<&FramePose>) -> Value {
    row["simulated"] = json!({"t": sim.t.to_array(), "q": sim.q.to_array_re()});
    if let Some(ga) = ga.filter(|g| g.fitted) {
        let turn = (sim.q * ga.pose.q.conj()).normalize_or_identity().log().norm();
        row["sim_from_ga_mm"] = json!(((sim.t - ga.pose.t).norm() * 1e6).round() / 1e3);
        row["sim_from_ga_deg"] = json!((turn.to_degrees() * 1e3).round() / 1e3);
    }
    row
}

/// An `init.json` entry.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Guess {
    capture: String,
    t: [f64; 3],
    q: [f64; 4],
}

/// What a fit folder was made with; a resumed run must match it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FitRecord {
    pub(crate) inputs: RecordInputs,
    #[serde(default)]
    pub(crate) fit: VideoFitConfig,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RecordInputs {
    pub(crate) video: PathBuf,
    pub(crate) scene: PathBuf,
    /// `NAME=DIR`, comma-separated with several bodies.
    pub(crate) object: String,
    pub(crate) init: PathBuf,
    pub(crate) frames: usize,
    pub(crate) fps: f64,
    /// Seconds; 0 for an instant (and in fit folders written before the shutter was read).
    #[serde(default)]
    pub(crate) shutter: f64,
    pub(crate) no_pa: bool,
    pub(crate) no_ga: bool,
}

/// Whether the video `c` has masks for body `name` (its `mask_<NAME>/`, or with one body `mask/`).
pub(crate) fn has_masks(c: &pganeus_io::CaptureIndex, name: &str, single: bool) -> bool {
    c.extra_masks.iter().any(|(n, _)| n == name) || (single && c.masks.is_some())
}

/// Body `name`'s masks, computed (the video had none), written into the fit folder `out` as `mask_<name>/`
/// for inspection.
pub(crate) fn write_computed_masks(out: &Path, name: &str, frames: &[FrameTarget]) -> Result<()> {
    let masks: Vec<Vec<bool>> = frames.iter().map(|f| f.mask.clone()).collect();
    let dir = out.join(format!("mask_{name}"));
    let width = frames.first().map_or(1, |f| f.camera.width as usize);
    crate::video_masks::write_masks(&dir, &masks, width)?;
    tracing::info!("the computed masks of {name}: {}", dir.display());
    Ok(())
}

/// The video's frames for body `name` (the capture `c`, opened from `dir`): images, the body's masks
/// (`computed` where the video has none) and the one fixed camera.
pub(crate) fn read_video(
    dir: &Path,
    c: &pganeus_io::CaptureIndex,
    name: &str,
    single: bool,
    limit: Option<usize>,
    computed: Option<&[Vec<bool>]>,
) -> Result<(Vec<FrameTarget>, Option<f64>)> {
    let camera = fixed_camera(dir, c)?;
    let masks = match c.extra_masks.iter().find(|(n, _)| n == name) {
        Some((_, m)) => Some(m.clone()),
        None => match (&c.masks, single, computed) {
            (Some(m), true, _) => Some(m.clone()),
            (_, _, Some(_)) => None,
            _ => fail!(
                Input,
                "{}: no mask_{name}/ folder for body {name:?}{}",
                dir.display(),
                if single { " (nor mask/)" } else { "" }
            ),
        },
    };
    let n = limit.map_or(c.len(), |l| l.min(c.len()));
    if n < 2 {
        fail!(
            Input,
            "{}: fit needs at least 2 frames, the video has {n}",
            dir.display()
        );
    }
    let shutter = c.info.as_ref().and_then(|i| i.shutter).unwrap_or(0.0);
    let mut frames = Vec::with_capacity(n);
    let mut empty = Vec::new();
    for k in 0..n {
        let mask = match (&masks, computed) {
            (Some(m), _) => read_mask(&m[k])?,
            (None, Some(c)) => c[k].clone(),
            (None, None) => unreachable!("no masks is refused above"),
        };
        if !mask.iter().any(|&m| m) {
            empty.push(k);
        }
        frames.push(FrameTarget {
            camera,
            rgb: reference_frame(&c.images[k])?,
            mask,
            exposure: 1.0,
            shutter,
            mask_computed: masks.is_none(),
        });
    }
    let mask_dir = match &masks {
        Some(m) => m[0].parent().unwrap_or(dir).display().to_string(),
        None => format!("{} (masks computed from the scene)", dir.display()),
    };
    if empty.len() == n {
        fail!(Input, "{mask_dir}: the masks of body {name:?} are empty in every frame");
    }
    if !empty.is_empty() {
        tracing::warn!("{mask_dir}: body {name:?} is not seen in frames {empty:?}: its image terms skip them");
    }
    Ok((frames, c.info.as_ref().and_then(|i| i.fps)))
}

/// Where the body frame sat in capture `capture` (the object's reference capture or, for a merge, its other).
pub(crate) fn capture_from_body(model: &ObjectModel, capture: &str) -> Option<Pose<f64>> {
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
pub(crate) fn read_guesses(path: &Path, bodies: &[(&str, &ObjectModel)]) -> Result<Vec<Pose<f64>>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let all: BTreeMap<String, Guess> = serde_json::from_str(&text).with_context(|| format!("{}", path.display()))?;
    if let Some(other) = all.keys().find(|k| !bodies.iter().any(|(n, _)| n == *k)) {
        fail!(
            Input,
            "{}: a guess for body {other:?}, which the fit has no --object and the video no mask for",
            path.display()
        );
    }
    bodies
        .iter()
        .map(|&(name, model)| {
            let g = all
                .get(name)
                .ok_or_else(|| err!(Input, "{}: no guess for body {name:?}", path.display()))?;
            if !(g.t.iter().chain(&g.q).all(|v| v.is_finite()) && g.q.iter().map(|v| v * v).sum::<f64>() > 1e-12) {
                fail!(
                    Settings,
                    "{}: {name}: t must be finite and q a non-zero quaternion",
                    path.display()
                );
            }
            let from = capture_from_body(model, &g.capture).ok_or_else(|| {
                err!(
                    Input,
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
pub(crate) fn check_guess_in_view(cam: &geom::Camera<f64>, guess: &Pose<f64>, name: &str, init: &Path) -> Result<()> {
    let (u, v, z) = cam.project(guess.t);
    if !(z > 0.0 && (0.0..cam.width as f64).contains(&u) && (0.0..cam.height as f64).contains(&v)) {
        fail!(
            Input,
            "{}: the guess for {name:?} puts its centre outside the image (pixel ({u:.0}, {v:.0}), depth {z:.3} m)",
            init.display()
        );
    }
    Ok(())
}

/// The video's frame rate: `--fps` when given, else its `capture.json`'s.
fn video_fps(inputs: &FitInputs, from_capture: Option<f64>) -> Result<f64> {
    match (inputs.fps, from_capture) {
        (Some(f), _) if f.is_finite() && f > 0.0 => Ok(f),
        (Some(f), _) => fail!(Settings, "--fps must be positive, got {f}"),
        (None, Some(f)) => Ok(f),
        (None, None) => fail!(
            Input,
            "{}: capture.json gives no fps: add it there or pass --fps",
            inputs.video.display()
        ),
    }
}

/// The shutter time every frame is drawn with: `--shutter` over the video's `capture.json` (already in
/// `frames`); checked to fit in a frame's time. Logged where a frame is drawn over it.
fn set_shutter(inputs: &FitInputs, frames: &mut [FrameTarget], fps: f64) -> Result<f64> {
    if let Some(s) = inputs.shutter {
        if !(s.is_finite() && s >= 0.0) {
            fail!(Settings, "--shutter must be 0 or more seconds, got {s}");
        }
        for f in frames.iter_mut() {
            f.shutter = s;
        }
    }
    let shutter = frames.first().map_or(0.0, |f| f.shutter);
    if shutter > 1.0 / fps + 1e-9 {
        fail!(
            Input,
            "{}: a shutter of {shutter} s is longer than a frame at {fps} fps: give --shutter (seconds, at most 1/fps)",
            inputs.video.display()
        );
    }
    if shutter > 0.0 {
        tracing::info!("shutter {shutter:.5} s: a body moving over a pixel in that time is drawn over it");
    }
    Ok(shutter)
}

/// `--scene`'s field (a warning when it was trained as an object) and `--scene-grid` when given.
fn load_scene(a: &FitInputs) -> Result<(neus::checkpoint::LoadedField, Option<SdfGrid>)> {
    let field = load_field(&checkpoint_of(&a.scene)).with_context(|| format!("--scene {}", a.scene.display()))?;
    if field.config.kind != neus::CaptureSubject::Scene {
        tracing::warn!(
            "--scene {}: trained as an object capture, not a scene",
            a.scene.display()
        );
    }
    let grid = match &a.scene_grid {
        Some(p) => Some(SdfGrid::load(p).context("--scene-grid")?),
        None => None,
    };
    Ok((field, grid))
}

/// The rigid body of `--object name=dir`, its density `--density`'s; its mesh must have its centre of mass
/// at the body's origin (as `merge` and `train` write it).
pub(crate) fn rigid_body(name: &str, object: &ObjectModel, dir: &Path, density: f64) -> Result<RigidBody> {
    let body = RigidBody::from_mesh(
        name,
        &object.mesh,
        MassSpec::Density(density),
        ContactSampling::default(),
        None,
    )
    .with_context(|| format!("--object {name}: {}: its mesh", dir.display()))?;
    if body.mesh_offset.norm() > 1e-5 {
        fail!(
            Settings,
            "--object {name}: the mesh's centre of mass is {:?} from the body origin",
            body.mesh_offset.to_array()
        );
    }
    Ok(body)
}

/// The settings' simulator values (`[sim]` at the video's rate and length, `[start_contact]`) checked before
/// anything is written: [`fit_world`] checks them again with the scene and bodies in place.
pub(crate) fn check_sim_settings(fps: f64, frames: usize, cfg: &VideoFitConfig) -> Result<()> {
    let sim_cfg = SimConfig {
        fps,
        frames,
        ..cfg.sim.clone()
    };
    sim_cfg
        .validate()
        .map_err(|e| err!(Settings, "settings: sim.{}: {}", e.field, e.msg))?;
    cfg.start_contact
        .validate("start_contact")
        .map_err(|e| err!(Settings, "settings: {}: {}", e.field, e.msg))
}

/// The world the stages simulate: the scene's grid and `bodies` at placeholder states (every stage starts
/// from the first poses), the settings' `[sim]` at the video's rate and length.
pub(crate) fn fit_world(
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
        .map_err(|e| err!(Settings, "settings: sim.{}: {}", e.field, e.msg))?;
    Ok(world)
}

/// The output folder: a new one (or, starting over, one emptied of stage results), or the same fit resumed;
/// `config.toml` records what it was made with.
fn open_output(out: &Path, record: &FitRecord, resume: Resume) -> Result<()> {
    let record_path = out.join("config.toml");
    let record_text = toml::to_string(record)?;
    if record_path.exists() && resume == Resume::Continue {
        let old =
            std::fs::read_to_string(&record_path).with_context(|| format!("cannot read {}", record_path.display()))?;
        let same = toml::from_str::<FitRecord>(&old).is_ok_and(|r| r == *record);
        if !same {
            fail!(
                OutputTaken,
                "{} holds a fit with other inputs or settings: give another --out, or --force to start over",
                out.display()
            );
        }
        tracing::info!("resuming the fit in {}", out.display());
    } else {
        if resume == Resume::StartOver {
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
                let _ = std::fs::remove_file(out.join(f));
            }
        }
        std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
        pganeus_io::write_atomic(&record_path, record_text.as_bytes())?;
    }
    Ok(())
}

/// The scene's collision grid: `--scene-grid`'s, or baked from the scene run into the output folder once.
pub(crate) fn scene_grid(
    given: Option<SdfGrid>,
    scene_field: &neus::checkpoint::LoadedField,
    scene: &Path,
    out: &Path,
    observer: &dyn Observer,
) -> Result<SdfGrid> {
    if let Some(g) = given {
        return Ok(g);
    }
    let path = out.join("scene_grid.bin");
    if path.exists() {
        return Ok(SdfGrid::load(&path)?);
    }
    let t = Instant::now();
    let g = crate::surfaces::bake_scene(scene_field, scene, observer)?;
    g.save(&path)?;
    tracing::info!(
        "baked the scene's grid in {:.1} s: {}",
        t.elapsed().as_secs_f64(),
        path.display()
    );
    Ok(g)
}

/// With `carve_scene`, `world`'s scene less the space GA saw each body of `seen` in ([`recon::seen_space`]),
/// and the grid nodes raised.
pub(crate) fn carved_scene(
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
pub(crate) fn save_carved_scene(world: &World, out: &Path) -> Result<()> {
    if let sim::sdf::Shape::Grid(grid) = &world.scene {
        grid.save(&out.join("scene_carved.sdf"))?;
    }
    Ok(())
}

pub(crate) fn pose_of(t: [f64; 3], q: [f64; 4]) -> Pose<f64> {
    // A quaternion a stage wrote is kept bit for bit: a resumed fit goes on exactly.
    Pose::new(Quat::cst(q).unit(), Vec3::cst(t))
}

/// The video's brightness in each frame relative to its first, measured on the scene around the bodies
/// (`recon::brightness_drift`): `bodies_in(k)` marks where any body is in frame `k`. Logged when it moves.
pub(crate) fn video_drift(
    frames: &[FrameTarget],
    bodies_in: impl Fn(usize) -> Vec<bool>,
    scene_pre: &[ComposedRay],
) -> Vec<f64> {
    let scene: Vec<[f32; 3]> = scene_pre.iter().map(|r| r.rgb).collect();
    let rgb: Vec<&[[f32; 3]]> = frames.iter().map(|f| f.rgb.as_slice()).collect();
    let masks: Vec<Vec<bool>> = (0..frames.len()).map(bodies_in).collect();
    let width = frames.first().map_or(1, |f| f.camera.width as usize);
    let drift = recon::brightness_drift(&rgb, &masks, &scene, width);
    let (lo, hi) = drift.iter().fold((1.0f64, 1.0f64), |(l, h), &d| (l.min(d), h.max(d)));
    if hi - lo > 0.005 {
        tracing::info!(
            "the video's brightness drifts from {:+.1} % to {:+.1} % of its first frame's (measured on the scene): each frame's exposure follows it",
            100.0 * (lo - 1.0),
            100.0 * (hi - 1.0)
        );
    }
    drift
}

/// Values to four decimals, for the logs.
pub(crate) fn rounded(values: &[f64]) -> Vec<f64> {
    values.iter().map(|v| (v * 1e4).round() / 1e4).collect()
}

/// Every frame's exposure: `first`, the first frame's (measured at the first pose), times the frame's drift.
pub(crate) fn set_exposures(frames: &mut [FrameTarget], first: f64, drift: &[f64]) {
    for (f, d) in frames.iter_mut().zip(drift) {
        f.exposure = first * d;
    }
}

/// The video's brightness relative to `object`'s captures at a searched first pose (`--init auto`): the
/// search's winner covers its mask, so the gain measured there holds for the first-pose fit too; a guess
/// from markers, centimetres off, is refined as captured and measured after.
pub(crate) fn exposure_at(
    cfg: &PoseFitConfig,
    object: &ObjectModel,
    scene_pre: &[ComposedRay],
    frame: &FrameTarget,
    pose: Pose<f64>,
) -> Result<f64> {
    Ok(PoseFromImage::new(cfg.clone(), object, scene_pre, frame, pose)
        .context("frame 0")?
        .measure_exposure())
}

/// `--init auto` for body `name`: its first pose searched from `frame`'s mask and its resting sides, each
/// candidate a row of `rows` (for the log), the pose added to `OUT/init_auto.json` as a guess relative to
/// the object's reference capture (the `init.json` format).
#[allow(clippy::too_many_arguments)]
pub(crate) fn search_first_pose_of(
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
    observer: &dyn Observer,
) -> Result<Pose<f64>> {
    let task = Task::start(observer, &format!("first pose search: {name}"), cfg.steps() as u64);
    let found = recon::search_first_pose(body, scene, object, scene_pre, frame, cfg, || task.inc(1));
    task.finish();
    let (pose, candidates) = match found {
        Ok(f) => f,
        Err(recon::PoseFitError::EmptyMask) => fail!(
            Input,
            "{}: body {name:?}'s mask is empty in frame 0: its first pose cannot be searched",
            video.display()
        ),
        Err(e) => fail!(Input, "{name}: frame 0: {e}"),
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

/// Per-frame image terms as JSON rows.
pub(crate) fn metric_rows(losses: &[ImageLoss]) -> Value {
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

pub(crate) fn report_stage(stage: &str, world: &World, losses: &[ImageLoss]) {
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

/// One GA frame as a row of `ga.json`'s `ga` list (what [`frame_poses`] reads back).
pub(crate) fn ga_row(r: &FramePose) -> Value {
    json!({"in_contact": r.in_contact, "fitted": r.fitted, "start": r.start, "contact_penalty": r.contact_penalty,
        "loss": r.image.loss, "intersection": r.image.intersection, "union": r.image.union,
        "pixels": r.image.pixels, "mse": r.image.mse})
}

/// GA's frames from a `ga.json` body's poses and its rows ([`ga_row`]).
pub(crate) fn frame_poses(poses: &[pganeus_io::Pose], rows: &[Value]) -> Vec<FramePose> {
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

/// The value ranges in the log and in `log.jsonl` (through `write`).
pub(crate) fn report_ranges(ranges: &[ValueRange], write: &mut dyn FnMut(Value) -> Result<()>) -> Result<()> {
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
pub(crate) fn object_entry(object: &ObjectModel, mesh: &str) -> Map<String, Value> {
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

/// Each contact value's range ([`recon::value_ranges`]) beside the value in a trajectory file:
/// `restitution_range` and `friction_range`, `[lo, hi]`, in `contact` (the scene's), in a body entry (the
/// scene's against one body, when not shared) or in a `contact.pairs` entry.
pub(crate) fn write_ranges(t: &mut pganeus_io::Trajectory, ranges: &[ValueRange]) {
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
