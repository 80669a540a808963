//! The fit of one body: its pose in every frame of a fixed-camera video and the physics that explains it
//! (Sec. 3.3–3.4): the first pose from a rough guess, PA, GA with the contact penalty, and PGA (GA ↔ PGA
//! while it helps). Each stage's result is written as it ends, so a run that stops resumes at the stage it
//! was in (same settings; [`crate::Resume::StartOver`] starts over).

use super::*;
use crate::images::{beside, strip, to8};
use neus::compose::{render_composed, Behind, Layer};
use recon::poses_from_video::carried_on;
use recon::video_fit::{
    evaluate_poses, fit_to_poses, ga_weights_of, launch_guess, lift_out, simulated_motions, total_loss, TOUCHING,
};
use recon::{
    among_ties, reported_poses, MultiStart, PhysicsFitConfig, PhysicsFromVideo, PosesFromVideo, StartContact,
    StartResult, PGA_TIE,
};
use sim::ContactParams;

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
struct Job<'a> {
    name: String,
    object: ObjectModel,
    frames: Vec<FrameTarget>,
    scene_pre: Vec<ComposedRay>,
    /// Each frame's brightness relative to the first's (`super::video_drift`).
    drift: Vec<f64>,
    world: World,
    fps: f64,
    capture: String,
    video: PathBuf,
    cfg: VideoFitConfig,
    out: PathBuf,
    log: Log,
    observer: &'a dyn Observer,
    t_start: Instant,
}

impl Job<'_> {
    fn stage_file(&self, name: &str) -> PathBuf {
        self.out.join(name)
    }
}

/// A one-body fit's inputs, read and checked.
pub(super) struct Prepared {
    name: String,
    object: ObjectModel,
    frames: Vec<FrameTarget>,
    fps: f64,
    guess: Option<Pose<f64>>,
    scene_field: neus::checkpoint::LoadedField,
    grid: Option<SdfGrid>,
    body: RigidBody,
    /// The masks were computed (the video had none): written into the run folder for inspection.
    computed_masks: bool,
}

/// Every input read and checked, and the record of the fit.
pub(super) fn prepare(a: &FitInputs, cfg: &VideoFitConfig) -> Result<(Prepared, FitRecord)> {
    let (name, object_dir) = a.objects[0].clone();
    let (scene_field, grid) = load_scene(a)?;
    // A video without masks: the moving body found against the scene rendered through its camera.
    let capture = pganeus_io::open_capture(&a.video)?;
    let computed = if has_masks(&capture, &name, true) {
        None
    } else {
        tracing::info!(
            "{}: no mask_{name}/ nor mask/: computing the masks from the frames and the scene",
            a.video.display()
        );
        Some(crate::video_masks::compute(&a.video, &capture, &scene_field, &crate::Quiet)?.masks)
    };
    let (mut frames, fps_of_capture) = read_video(&a.video, &capture, &name, true, a.frames, computed.as_deref())?;
    let fps = video_fps(a, fps_of_capture)?;
    let shutter = set_shutter(a, &mut frames, fps)?;
    let mut object = ObjectModel::load(&object_dir).with_context(|| format!("--object {name}"))?;
    object
        .bake(cfg.bake_object)
        .with_context(|| format!("--object {name}"))?;
    let guess = if is_auto(&a.init) {
        None
    } else {
        Some(read_guesses(&a.init, &[(name.as_str(), &object)])?[0])
    };
    let cam = frames[0].camera;
    if let Some(guess) = &guess {
        check_guess_in_view(&cam, guess, &name, &a.init)?;
    }
    let body = rigid_body(&name, &object, &object_dir, a.density)?;
    check_sim_settings(fps, frames.len(), cfg)?;
    let record = record_of(a, cfg, frames.len(), fps, shutter);
    let prepared = Prepared {
        name,
        object,
        frames,
        fps,
        guess,
        scene_field,
        grid,
        body,
        computed_masks: computed.is_some(),
    };
    Ok((prepared, record))
}

/// The stages `ctx.stages` asks for.
pub(super) fn run(p: Prepared, ctx: &RunContext) -> Result<FitOutcome> {
    let (a, t_start) = (ctx.inputs, ctx.t_start);
    let cam = p.frames[0].camera;
    if p.computed_masks {
        write_computed_masks(ctx.out, &p.name, &p.frames)?;
    }
    let grid = scene_grid(p.grid, &p.scene_field, &a.scene, ctx.out, ctx.observer)?;
    let world = fit_world(grid, p.fps, p.frames.len(), ctx.config, vec![p.body])?;
    let scene_pre = scene_through(&p.scene_field, &cam);
    let drift = video_drift(&p.frames, |k| p.frames[k].mask.clone(), &scene_pre);
    let mut job = Job {
        name: p.name,
        object: p.object,
        frames: p.frames,
        scene_pre,
        drift,
        world,
        fps: p.fps,
        capture: capture_name(&a.video),
        video: a.video.clone(),
        cfg: ctx.config.clone(),
        out: ctx.out.to_path_buf(),
        log: Log::open(ctx.out)?,
        observer: ctx.observer,
        t_start,
    };
    let guess = p.guess;
    let mut outcome = FitOutcome::default();
    let wanted = ctx.stages;
    let mut timings = Map::new();
    let mut time = |stage: &str, t: Instant| {
        let s = t.elapsed().as_secs_f64();
        timings.insert(stage.into(), json!((s * 10.0).round() / 10.0));
        tracing::info!("{stage}: {s:.1} s");
    };

    let t = Instant::now();
    let first = stage_first(&mut job, guess, wanted.contains(&Stage::First))?;
    time("first_pose", t);
    outcome.first_poses = vec![pose_of(first.t, first.q)];
    set_exposures(&mut job.frames, first.exposure, &job.drift);
    let last = wanted.iter().copied().max().unwrap_or(Stage::Pga);
    if last == Stage::First {
        return Ok(with_read_back(outcome, &job.log));
    }
    let t = Instant::now();
    let pa = if a.no_pa {
        None
    } else {
        Some(stage_pa(&mut job, &first, wanted.contains(&Stage::Pa))?)
    };
    time("pa", t);
    outcome.pa = pa.clone();
    if last == Stage::Pa && !a.no_pa {
        return Ok(with_read_back(outcome, &job.log));
    }
    if a.no_ga {
        let Some(pa) = pa else {
            unreachable!("no_pa and no_ga are refused together")
        };
        if wanted.contains(&Stage::Pga) || wanted.contains(&Stage::Ga) {
            finish(&mut job, &pa, None, &timings, &mut outcome)?;
            outcome.world = Some(pa);
        }
        return Ok(with_read_back(outcome, &job.log));
    }
    let t = Instant::now();
    let start_world = pa.unwrap_or_else(|| launch_world(&job, &first));
    let ga = stage_ga(&mut job, &start_world, a.no_pa, wanted.contains(&Stage::Ga), "ga.json")?;
    time("ga", t);
    if !wanted.contains(&Stage::Pga) {
        outcome.ga = Some(vec![ga]);
        return Ok(with_read_back(outcome, &job.log));
    }
    let t = Instant::now();
    let start_world = carve_seen_space(&mut job, start_world, &ga)?;
    let pga = stage_pga(&mut job, start_world, ga, !a.no_pa, first.start)?;
    time("pga", t);
    timings.insert("pga_rounds".into(), json!(pga.rounds));
    finish(&mut job, &pga.world, Some(&pga), &timings, &mut outcome)?;
    outcome.ga = Some(vec![pga.ga]);
    outcome.ranges = pga.ranges;
    outcome.world = Some(pga.world);
    Ok(with_read_back(outcome, &job.log))
}

/// `world` (and the job's) in the scene less the space GA saw the body in ([`carved_scene`]).
fn carve_seen_space(job: &mut Job, mut world: World, ga: &[FramePose]) -> Result<World> {
    let camera = job.frames[0].camera;
    if let Some((scene, raised)) = carved_scene(&world, &[(0, ga)], &camera, &job.cfg) {
        job.log.write(json!({"stage": "carve", "nodes_raised": raised}))?;
        world.scene = scene.clone();
        job.world.scene = scene;
        save_carved_scene(&world, &job.out)?;
    }
    Ok(world)
}

/// The world at the first pose with the launch guess (PA's start, or PGA's with `--no-pa`).
fn launch_world(job: &Job, first: &FirstPose) -> World {
    let mut w = job.world.clone();
    w.initial[0] = BodyState::new(first.t, first.q, first.v, first.omega);
    w
}

/// Stage 1: the first pose from the guess (lifted out of the scene), then the poses of the next frames the
/// same way, for the launch guess.
fn stage_first(job: &mut Job, guess: Option<Pose<f64>>, run: bool) -> Result<FirstPose> {
    let path = job.stage_file("first_pose.json");
    if path.exists() {
        let text = std::fs::read_to_string(&path)?;
        job.log.read_back("first pose", &path);
        return serde_json::from_str(&text).with_context(|| format!("{}", path.display()));
    }
    if !run {
        fail!(Stage, "stage first has not run: {} is missing", path.display());
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
        let frame = job.frames[0].with_whole_outline();
        let exposure = exposure_at(&job.cfg.first_pose, &job.object, &job.scene_pre, &frame, start)?;
        set_exposures(&mut job.frames, exposure, &job.drift);
    }
    let cfg: &PoseFitConfig = &job.cfg.first_pose;
    let n = (1 + job.cfg.launch_frames).min(job.frames.len());
    let pb = Task::start(
        job.observer,
        "first pose",
        (cfg.iterations + cfg.iterations.div_ceil(2) * (n - 1)) as u64,
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
        // Over the shutter at the pace of the two frames before (unknown before them).
        let motion = (k >= 2).then(|| recon::Motion::between(&poses[k - 2], &poses[k - 1], 1.0 / job.fps));
        let mut fit = match PoseFromImage::new(cfg_k, &job.object, &job.scene_pre, &job.frames[k], start_k) {
            Ok(f) => f.with_motion(motion),
            Err(recon::PoseFitError::EmptyMask) if k == 0 => {
                fail!(
                    Input,
                    "{}: the body's mask is empty in frame 0: the first pose cannot be fitted",
                    job.video.display()
                )
            }
            Err(recon::PoseFitError::EmptyMask) => break,
            Err(e) => fail!(Stage, "frame {k}: {e}"),
        };
        for i in 0..steps {
            let l = fit.step();
            if i % 10 == 0 {
                job.log
                    .write(json!({"stage": "first_pose", "frame": k, "iteration": i, "loss": l.loss}))?;
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
    pb.finish();
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
    job.log.write(
        json!({"stage": "first_pose", "done": true, "iou": first.iou, "v": v, "omega": omega,
        "exposure": first.exposure, "brightness_drift": rounded(&job.drift)}),
    )?;
    Ok(first)
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
        &job.frames[0].with_whole_outline(),
        &job.name,
        &job.video,
        &job.out,
        &mut rows,
        job.observer,
    );
    for r in rows {
        job.log.write(r)?;
    }
    pose
}

/// The world of a trajectory file this command wrote (its initial state and contact values).
fn world_from_file(job: &Job, path: &Path) -> Result<World> {
    let t = pganeus_io::read_trajectory(path)?;
    let b = t
        .bodies
        .first()
        .ok_or_else(|| err!(Input, "{}: no body", path.display()))?;
    let mut w = job.world.clone();
    w.initial[0] = BodyState::new(b.initial.t, b.initial.q, b.initial.v, b.initial.omega);
    w.scene_contact[0] = ContactParams {
        restitution: t.contact.restitution,
        friction: t.contact.friction,
    };
    Ok(w)
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
        job.log.read_back("PA", &path);
        return world_from_file(job, &path);
    }
    if !run {
        fail!(Stage, "stage pa has not run: {} is missing", path.display());
    }
    let start = launch_world(job, first);
    let cfg = job.cfg.pa.clone();
    let pb = Task::start(job.observer, "PA", cfg.iterations as u64);
    let (world, losses) = {
        let mut pa =
            PhysicsFromVideo::new(cfg.clone(), &job.object, &job.scene_pre, &job.frames, start, 0).context("PA")?;
        pa = pa.with_start(first.start);
        let mut rows = Vec::new();
        while !pa.done() {
            let s = pa.step();
            rows.push(json!({"stage": "pa", "iteration": s.iteration, "window": s.window, "loss": s.loss}));
            pb.inc(1);
        }
        pb.finish();
        for r in rows {
            job.log.write(r)?;
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

/// Stage 3, GA: every frame's pose from `start`'s simulation (PA's or the last PGA's), or tracked frame by
/// frame without PA.
fn stage_ga(job: &mut Job, start: &World, tracking: bool, run: bool, file: &str) -> Result<Vec<FramePose>> {
    let path = job.stage_file(file);
    if path.exists() {
        job.log.read_back("GA", &path);
        return read_ga(&path, job.frames.len());
    }
    if !run {
        fail!(Stage, "stage ga has not run: {} is missing", path.display());
    }
    let traj = start.simulate(&start.params());
    let pb = Task::start(job.observer, "GA", job.frames.len() as u64);
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
        .context("GA")?;
        // Every frame, then (with GA's `hypotheses`) the pass back over the frames it explains worst.
        pb.set_length(ga.steps_left() as u64);
        while !ga.done() {
            ga.step().context("GA")?;
            pb.inc(1);
            pb.set_length(pb.position() + ga.steps_left() as u64);
        }
        pb.finish();
        ga.results.clone()
    };
    for (k, r) in results.iter().enumerate() {
        job.log.write(
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
    let b = t
        .bodies
        .first()
        .ok_or_else(|| err!(Input, "{}: no body", path.display()))?;
    let rows = t
        .extra
        .get("ga")
        .and_then(|v| v.as_array())
        .cloned()
        .unwrap_or_default();
    if b.poses.len() != frames || rows.len() != frames {
        fail!(Input, "{}: {} poses for {frames} frames", path.display(), b.poses.len());
    }
    Ok(frame_poses(&b.poses, &rows))
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
    /// The frames over which the world's simulation converges in its step size.
    horizon: recon::Horizon,
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
        job.log
            .write(json!({"stage": "pga", "round": "pa", "image_loss": total}))?;
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
        let pb = Task::start(job.observer, "PGA", starts as u64);
        let mut start_rows = Vec::new();
        let pga_cfg = pga_config(job);
        let observed = pga_observed(job, &ga, start_contact);
        let fit = fit_to_poses(&pga_cfg, multi, from.clone(), observed, &mut |i, r| {
            start_rows.push(start_row(json!({"stage": "pga", "round": round}), i, r));
            pb.inc(1);
        })
        .context("PGA")?;
        pb.finish();
        for r in start_rows {
            job.log.write(r)?;
        }
        let (winner, sim_losses) = winner_by_images(job, &fit, json!({"stage": "pga", "round": round}))?;
        let total = total_loss(&sim_losses);
        let world = fit.worlds[winner].clone();
        report_stage(&format!("PGA round {}", round + 1), &world, &sim_losses);
        job.log.write(
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
                .context("PGA after GA's refit")?;
            let again = fit.worlds[fit.winner].clone();
            let losses = simulation_losses(job, &again, &weights_cfg)?;
            let again_total = total_loss(&losses);
            let better = again_total < total;
            job.log
                .write(json!({"stage": "pga_after_refit", "image_loss": again_total, "kept": better}))?;
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
    // What the frames the simulation can predict allow, where they end before the video does.
    let horizon = horizon_of(&world, &job.frames[0].camera, &mut job.log)?;
    if horizon.frames >= 2 && horizon.frames < ranges_ga.len() {
        let within = value_ranges(job, &world, &ranges_ga[..horizon.frames], start_contact)?;
        recon::widen_by_ranges(&mut ranges, &within);
    }
    report_ranges(&ranges, &mut |row| job.log.write(row))?;
    Ok(PgaResult {
        world,
        ga,
        rounds: kept,
        ranges,
        flight,
        horizon,
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
    let check =
        recon::check_flight(&cfg, world, std::slice::from_ref(&observed)).context("PGA's launch against the flight")?;
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
    job.log.write(
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
    let pb = Task::start(job.observer, "PGA, launch held", 1 + starts.len() as u64);
    let held = recon::fit_holding_launch(&cfg, check.flight_world.clone(), vec![observed], starts, &mut |_, _| {
        pb.inc(1)
    });
    pb.finish();
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
        Err(e) => fail!(Stage, "PGA with the flight's launch: {e}"),
    };
    let total = total_loss(&losses);
    let kept = total < kept_total;
    report_stage("PGA, the flight's launch held", &world, &losses);
    tracing::info!(
        "the flight's launch held: image loss {total:.3} against {kept_total:.3}: {}",
        if kept { "kept" } else { "not kept" }
    );
    job.log
        .write(json!({"stage": "pga_flight", "image_loss": total, "kept": kept,
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
        &simulated_motions(&traj, 0),
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
            job.log.read_back("GA from PGA's simulation", &path);
            let replaced = (0..r.len()).filter(|&k| r[k].start == StartFrom::Pga).collect();
            return Ok((r, replaced));
        }
        tracing::warn!("{}: from another GA run; fitted again", path.display());
    }
    let traj = world.simulate(&world.params());
    let pb = Task::start(job.observer, "GA from PGA", 0);
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
        .context("GA from PGA's simulation")?;
        let replaced = stage
            .refit_worst_from_physics(|| pb.inc(1))
            .context("GA from PGA's simulation")?;
        pb.finish();
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
        job.log.write(row)?;
    }
    write_ga(job, &path, &results)?;
    Ok((results, replaced))
}

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
        job.log.write(r)?;
        scored[i] = Some(losses);
        Ok(total)
    })?
    .ok_or_else(|| err!(Stage, "no start ended with a finite loss"))?;
    // The pick is within the tie of itself: always scored.
    let losses = scored[winner].take().expect("the winner was scored");
    Ok((winner, losses))
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
    let pb = Task::start(job.observer, "value ranges", 0);
    let ranges = recon::contact_value_ranges(&cfg, world.clone(), vec![observed], job.cfg.ranges, &pb.follow())
        .context("PGA's value ranges")?;
    pb.finish();
    tracing::info!("value ranges: {:.1} s", t.elapsed().as_secs_f64());
    Ok(ranges)
}

/// The final trajectory (simulated, where it explains the video; GA's pose where it clearly does not),
/// renders, the strip and the animation.
fn finish(
    job: &mut Job,
    world: &World,
    pga: Option<&PgaResult>,
    timings: &Map<String, Value>,
    outcome: &mut FitOutcome,
) -> Result<()> {
    let t_finish = Instant::now();
    let ga = pga.map(|p| p.ga.as_slice());
    let traj = world.simulate(&world.params());
    let n = job.frames.len();
    let sim_poses: Vec<Pose<f64>> = traj.frames.iter().map(|f| f[0].pose).collect();
    // Scored with GA's terms: `simulation_misses` compares these with GA's own losses.
    let weights = job.cfg.ga.pose.weights.clone();
    // At the simulated velocities: GA's poses (slid in depth) are scored moving as the simulation moves.
    let motions = simulated_motions(&traj, 0);
    let sim_losses = evaluate_poses(
        &job.object,
        &job.scene_pre,
        &job.frames,
        &sim_poses,
        &motions,
        &[],
        &weights,
    )?;
    // The reported pose is the simulated one (Eq. 11) wherever it explains the frame: GA's poses follow
    // each image alone and, where the image cannot tell depth (a small object far off), wander by
    // centimetres that the physics does not. Where the simulation clearly misses the body's silhouette
    // (motion the simulator cannot make), GA's pose is reported instead; both stay in pga.json and ga.json
    // (and ga_pga.json: GA's after the frames refitted from the simulation).
    let (reported, source) = match ga {
        Some(ga) => {
            let at_depth = |poses: &[Pose<f64>]| {
                evaluate_poses(&job.object, &job.scene_pre, &job.frames, poses, &motions, &[], &weights)
            };
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
    let t_scored = t_finish.elapsed().as_secs_f64();
    outcome.reported = Some(vec![reported
        .iter()
        .zip(&source)
        .map(|(&pose, &from)| ReportedFrame { pose, from })
        .collect()]);
    let source: Vec<&str> = source.iter().map(|s| s.name()).collect();
    // Renders of the reported poses over the pre-rendered scene.
    let (w, h) = (job.frames[0].camera.width, job.frames[0].camera.height);
    std::fs::create_dir_all(job.out.join("render"))?;
    let pb = Task::start(job.observer, "render", n as u64);
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
        let row = json!({"frame": k, "psnr": (psnr * 100.0).round() / 100.0, "iou": (iou * 1e4).round() / 1e4,
            "pose": source[k], "brightness": (job.drift[k] * 1e4).round() / 1e4});
        rows.push(with_simulation(row, &sim_poses[k], ga.and_then(|g| g.get(k))));
        let mut input = Image::new(w, h, 3);
        for (p, c) in f.rgb.iter().enumerate() {
            input.data[p * 3..p * 3 + 3].copy_from_slice(&c.map(to8));
        }
        pairs.push(beside(&input, &rgb));
        pb.inc(1);
    }
    pb.finish();
    let t_rendered = t_finish.elapsed().as_secs_f64();
    pganeus_io::write_apng(&job.out.join("animation.png"), &pairs, job.fps)?;
    pganeus_io::write_png(&job.out.join("strip.png"), &strip(&pairs, 6))?;
    tracing::info!(
        "outputs: {:.1} s (the simulation and GA's poses scored {t_scored:.1} s, the frames rendered {:.1} s, \
         the animation and the strip {:.1} s)",
        t_finish.elapsed().as_secs_f64(),
        t_rendered - t_scored,
        t_finish.elapsed().as_secs_f64() - t_rendered
    );

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
    let horizon = match pga {
        Some(p) => p.horizon.clone(),
        None => recon::predictable_frames(world, &job.frames[0].camera),
    };
    extra.insert("horizon".into(), horizon_entry(&horizon));
    let mut t = scene_file::trajectory_file(&job.capture, world, &traj, sim::ENGINE, extra);
    write_ranges(&mut t, pga.map_or(&[], |p| p.ranges.as_slice()));
    for (pose, r) in t.bodies[0].poses.iter_mut().zip(&reported) {
        *pose = pganeus_io::Pose::from_geom(r);
    }
    t.bodies[0].extra.extend(object_entry(&job.object, "object.ply"));
    if let Some(f) = pga.and_then(|p| p.flight.as_ref()) {
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
    outcome.trajectory = Some(job.out.join("trajectory.json"));
    outcome.summary = format!(
        "fitted {n} frames in {:.1} s: v0 {:?} m/s, omega0 {:?} rad/s, restitution {:.3}, friction {:.3}; \
         PSNR {:.2} dB, IoU against the masks mean {:.3} worst {:.3}; {} frames reported from GA (the simulation misses them), \
         {} of them at a depth weighed with the simulation's; wrote {}",
        job.t_start.elapsed().as_secs_f64(),
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
