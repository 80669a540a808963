//! `fit` with several bodies (Sec. 3.4, "Reconstruction of multiple rigid
//! bodies", Fig. 8). One body hits another, the collision lasts about a
//! frame, and a launch that is off puts it at the wrong time, where it gives
//! no useful gradient. So, as the paper's schedule (made robust):
//!
//! 1. every body's first pose from its guess (or `--init auto`), each against
//!    its own mask with the others drawn where they stand;
//! 2. GA (tracked): every body's pose in every frame from the images, tracked frame by
//!    frame, the bodies in turn, each against its own mask and the others
//!    drawn at their current poses (mutual occlusion), with the contact
//!    penalty on the points that touch the scene at the frame's start;
//! 3. PGA on GA's poses by the collision schedule of
//!    [`recon::colliding_bodies`] (the collision frame from the poses, the
//!    launches before it, the board's values after it, each pair's values
//!    where its bodies meet, then everything);
//! 4. GA again, each body started at that simulation's poses with the
//!    contact penalty where it touches the scene (the one-body fit's GA from
//!    PA), and PGA on those poses; the round whose simulation explains the
//!    images better is kept, and where it misses a frame, the GA pose of
//!    either pass that explains the frame better stands in.
//!
//! PA (physics from rendered frames) is not run: before GA has found where
//! each body is, a launch guess puts the collision at the wrong frame and the
//! image loss has nothing to say about the pair; the paper's own multi-body
//! schedule starts from the tracked poses too.

use super::*;
use crate::images::{beside, strip, to8};
use crate::objects::load_objects;
use neus::compose::{render_composed, Behind, Layer};
use recon::image_loss::Occluder;
use recon::video_fit::{evaluate_poses, ga_weights_of, lift_out, simulated_motions};
use recon::{
    better_per_frame, colliding_value_ranges, fit_colliding_bodies, reported_poses, PhysicsFitConfig, PosesFromVideo,
    CONTACT_STARTS,
};

/// One body of the video.
struct Body {
    name: String,
    object: Arc<ObjectModel>,
    /// The video's frames with this body's masks.
    frames: Vec<FrameTarget>,
}

/// Everything the stages read.
struct Multi<'a> {
    bodies: Vec<Body>,
    scene_pre: Vec<ComposedRay>,
    /// Each frame's brightness relative to the first's (`super::video_drift`).
    drift: Vec<f64>,
    world: World,
    fps: f64,
    capture: String,
    video: PathBuf,
    cfg: VideoFitConfig,
    out: PathBuf,
    observer: &'a dyn Observer,
    t_start: Instant,
}

/// A several-body fit's inputs, read and checked.
pub(super) struct Prepared {
    bodies: Vec<Body>,
    fps: f64,
    guesses: Vec<Option<Pose<f64>>>,
    scene_field: neus::checkpoint::LoadedField,
    grid: Option<SdfGrid>,
    rigid: Vec<RigidBody>,
    /// Per body: its masks were computed (the video had none): written into the run folder for inspection.
    computed_masks: Vec<bool>,
}

/// Every input read and checked, and the record of the fit.
pub(super) fn prepare(a: &FitInputs, cfg: &VideoFitConfig) -> Result<(Prepared, FitRecord)> {
    if a.no_ga {
        fail!(Settings, "--no-ga: with several bodies fit starts from GA's poses (the paper's multi-body schedule); PA alone is for one body");
    }
    let objects = &a.objects;
    let mut bodies = Vec::new();
    let mut fps_of_capture = None;
    let mut videos = Vec::new();
    let capture = pganeus_io::open_capture(&a.video)?;
    let loaded = load_objects(objects, cfg.bake_object)?;
    let (scene_field, grid) = load_scene(a)?;
    let guesses: Vec<Option<Pose<f64>>> = if is_auto(&a.init) {
        vec![None; loaded.len()]
    } else {
        let named: Vec<(&str, &ObjectModel)> = loaded.iter().map(|(n, o)| (n.as_str(), &**o)).collect();
        read_guesses(&a.init, &named)?.into_iter().map(Some).collect()
    };
    // A video without a body's masks: what moves, found against the scene, split among the bodies.
    let missing: Vec<bool> = objects.iter().map(|(n, _)| !has_masks(&capture, n, false)).collect();
    let computed = if missing.iter().any(|&m| m) {
        tracing::info!(
            "{}: no mask_<body>/ for {}: computing the bodies' masks from the frames, the scene and their looks",
            a.video.display(),
            objects
                .iter()
                .zip(&missing)
                .filter(|(_, &m)| m)
                .map(|((n, _), _)| n.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
        let models: Vec<&ObjectModel> = loaded.iter().map(|(_, o)| &**o).collect();
        // Bodies that look alike are told apart by where their guessed first poses put them.
        Some(crate::video_masks::compute_for_bodies(
            &a.video,
            &capture,
            &scene_field,
            &models,
            &guesses,
            &crate::Quiet,
        )?)
    } else {
        None
    };
    for (i, (name, _)) in objects.iter().enumerate() {
        let own = computed.as_ref().filter(|_| missing[i]).map(|c| c[i].as_slice());
        let (frames, fps) = read_video(&a.video, &capture, name, false, a.frames, own)?;
        fps_of_capture = fps_of_capture.or(fps);
        videos.push(frames);
    }
    for ((name, object), frames) in loaded.into_iter().zip(videos) {
        bodies.push(Body { name, object, frames });
    }
    let n = bodies[0].frames.len();
    let fps = video_fps(a, fps_of_capture)?;
    let cam = bodies[0].frames[0].camera;
    for (b, g) in bodies.iter().zip(&guesses) {
        if let Some(g) = g {
            check_guess_in_view(&cam, g, &b.name, &a.init)?;
        }
    }
    let rigid = bodies
        .iter()
        .zip(objects)
        .map(|(b, (_, dir))| rigid_body(&b.name, &b.object, dir, a.density))
        .collect::<Result<Vec<_>>>()?;
    check_sim_settings(fps, n, cfg)?;
    let mut shutter = 0.0;
    for b in &mut bodies {
        shutter = set_shutter(a, &mut b.frames, fps)?;
    }
    let record = record_of(a, cfg, n, fps, shutter);
    let prepared = Prepared {
        bodies,
        fps,
        guesses,
        scene_field,
        grid,
        rigid,
        computed_masks: missing.into_iter().map(|m| m && computed.is_some()).collect(),
    };
    Ok((prepared, record))
}

/// The stages `ctx.stages` asks for (PA is not one of them: [the module's note](self)).
pub(super) fn run(p: Prepared, ctx: &RunContext) -> Result<FitOutcome> {
    if ctx.stages.contains(&Stage::Pa) && ctx.stages != Stage::ALL {
        fail!(
            Settings,
            "--stages pa: with several bodies there is no PA stage (first, ga, pga)"
        );
    }
    let (a, t_start) = (ctx.inputs, ctx.t_start);
    let n = p.bodies[0].frames.len();
    let cam = p.bodies[0].frames[0].camera;
    for (b, _) in p.bodies.iter().zip(&p.computed_masks).filter(|(_, &c)| c) {
        write_computed_masks(ctx.out, &b.name, &b.frames)?;
    }
    let grid = scene_grid(p.grid, &p.scene_field, &a.scene, ctx.out, ctx.observer)?;
    let world = fit_world(grid, p.fps, n, ctx.config, p.rigid)?;
    let scene_pre = scene_through(&p.scene_field, &cam);
    // Where any body is in frame k: the union of the bodies' masks.
    let any_body = |k: usize| {
        let mut union = p.bodies[0].frames[k].mask.clone();
        for b in &p.bodies[1..] {
            for (u, m) in union.iter_mut().zip(&b.frames[k].mask) {
                *u |= *m;
            }
        }
        union
    };
    let drift = video_drift(&p.bodies[0].frames, any_body, &scene_pre);
    let mut log = Log::open(ctx.out)?;
    let guesses = p.guesses;
    let mut outcome = FitOutcome::default();
    let mut m = Multi {
        bodies: p.bodies,
        scene_pre,
        drift,
        world,
        fps: p.fps,
        capture: capture_name(&a.video),
        video: a.video.clone(),
        cfg: ctx.config.clone(),
        out: ctx.out.to_path_buf(),
        observer: ctx.observer,
        t_start,
    };
    let wanted = ctx.stages;
    let mut timings = Map::new();
    let mut time = |stage: &str, t: Instant| {
        let s = t.elapsed().as_secs_f64();
        timings.insert(stage.into(), json!((s * 10.0).round() / 10.0));
        tracing::info!("{stage}: {s:.1} s");
    };
    let t = Instant::now();
    let (first, exposures): (Vec<Pose<f64>>, Vec<f64>) =
        stage_first(&mut m, &mut log, &guesses, wanted.contains(&Stage::First))?
            .into_iter()
            .unzip();
    time("first_pose", t);
    for (body, exposure) in m.bodies.iter_mut().zip(exposures) {
        set_exposures(&mut body.frames, exposure, &m.drift);
    }
    outcome.first_poses = first.clone();
    if !wanted.iter().any(|s| *s > Stage::First) {
        return Ok(with_read_back(outcome, &log));
    }
    let t = Instant::now();
    let tracked = stage_ga(
        &m,
        &mut log,
        &first,
        None,
        "ga_tracked.json",
        wanted.contains(&Stage::Ga),
    )?;
    time("ga_tracked", t);
    if !wanted.contains(&Stage::Pga) {
        outcome.ga = Some(tracked);
        return Ok(with_read_back(outcome, &log));
    }
    let t = Instant::now();
    carve_seen_space(&mut m, &mut log, &tracked)?;
    let first_round = stage_pga(&m, &mut log, &tracked, "pga_tracked.json")?;
    time("pga_tracked", t);
    finer_step_for_second_round(&mut m, &mut log, &first_round.world)?;
    // GA again from that simulation (the one-body fit's GA from PA), then PGA on its poses; the round whose
    // simulation explains the images better is kept.
    let t = Instant::now();
    let ga = stage_ga(&m, &mut log, &first, Some(&first_round.world), "ga.json", true)?;
    time("ga", t);
    let t = Instant::now();
    carve_seen_space(&mut m, &mut log, &ga)?;
    let second_round = stage_pga(&m, &mut log, &ga, "pga.json")?;
    time("pga", t);
    let (first_losses, second_losses) = (
        simulated_losses(&m, &first_round.world)?,
        simulated_losses(&m, &second_round.world)?,
    );
    let total = |l: &[Vec<ImageLoss>]| l.iter().map(|b| recon::video_fit::total_loss(b)).sum::<f64>();
    let (before, after) = (total(&first_losses), total(&second_losses));
    log.write(json!({"stage": "pga", "image_loss_tracked": before, "image_loss": after}))?;
    // Where the kept simulation misses a frame, a GA pose stands in: of the two GA passes, the one that
    // explains that frame better. The second pass, started from a simulation, usually does even where its
    // round's simulation is not kept (the two-body collision: IoU ≥ 0.969 against the tracked pass's 0.77).
    let stand_ins = better_per_frame(&tracked, &ga);
    let (kept, kept_ga, losses) = if after <= before {
        (second_round, &ga, second_losses)
    } else {
        tracing::info!(
            "PGA on GA from the simulation explains the images worse ({after:.4} > {before:.4}): kept the first round"
        );
        (first_round, &tracked, first_losses)
    };
    kept.write_schedule(&m)?;
    if m.cfg.carve_scene {
        save_carved_scene(&kept.world, &m.out)?;
    }
    let t = Instant::now();
    let (ranges, horizon) = value_ranges(&m, &mut log, &kept.world, kept_ga, &kept.steps)?;
    time("ranges", t);
    let rests = pga_observed(&m, kept_ga).resting;
    let reported = Reported {
        ga: &stand_ins,
        sim_losses: losses,
        ranges: &ranges,
        rests: &rests,
        horizon: &horizon,
        window: kept.window.as_ref(),
    };
    finish(&m, &kept.world, reported, &timings, &mut outcome)?;
    outcome.ga = Some(stand_ins);
    outcome.ranges = ranges;
    outcome.world = Some(kept.world);
    Ok(with_read_back(outcome, &log))
}

/// Twice the substeps for the second round where the first round's fitted motion does not converge in its
/// step size over the video (`finer_step_round`). Decided from the first round's world alone, so a resumed
/// fit decides the same.
fn finer_step_for_second_round(m: &mut Multi, log: &mut Log, first: &World) -> Result<()> {
    if !m.cfg.finer_step_round {
        return Ok(());
    }
    let horizon = recon::predictable_frames(first, &m.bodies[0].frames[0].camera);
    if !horizon.ends_early() {
        return Ok(());
    }
    let n = horizon.spread_px.len();
    let substeps = 2 * first.config.substeps.max(1);
    tracing::info!(
        "the first round's motion converges in its step size over frames 0-{} of {n} only (twice the substeps \
         draw it {:.1} px away): the second round simulates at {substeps} substeps a frame",
        horizon.frames.saturating_sub(1),
        horizon.spread_px.iter().copied().fold(0.0, f64::max)
    );
    log.write(json!({"stage": "pga", "first_round_predictable_frames": horizon.frames,
        "second_round_substeps": substeps}))?;
    m.world.config.substeps = substeps;
    Ok(())
}

/// The scene less the space GA (`ga`, per body) saw every body in, for the PGA round after it
/// ([`carved_scene`]; each round's world keeps the scene it was fitted in).
fn carve_seen_space(m: &mut Multi, log: &mut Log, ga: &[Vec<FramePose>]) -> Result<()> {
    let seen: Vec<(usize, &[FramePose])> = ga.iter().enumerate().map(|(b, g)| (b, g.as_slice())).collect();
    let camera = m.bodies[0].frames[0].camera;
    if let Some((scene, raised)) = carved_scene(&m.world, &seen, &camera, &m.cfg) {
        log.write(json!({"stage": "carve", "nodes_raised": raised}))?;
        m.world.scene = scene;
    }
    Ok(())
}

/// Each body's pose in every frame of a simulation.
fn body_poses(traj: &sim::Trajectory<f64>, nb: usize) -> Vec<Vec<Pose<f64>>> {
    (0..nb)
        .map(|b| traj.frames.iter().map(|f| f[b].pose).collect())
        .collect()
}

/// The image terms of every body's frames under `world`'s simulation, the others drawn where it puts them.
fn simulated_losses(m: &Multi, world: &World) -> Result<Vec<Vec<ImageLoss>>> {
    let nb = m.bodies.len();
    let traj = world.simulate(&world.params());
    let poses = body_poses(&traj, nb);
    let mut all = Vec::with_capacity(nb);
    for (b, body) in m.bodies.iter().enumerate() {
        let others = others_along(m, b, &poses);
        all.push(evaluate_poses(
            &body.object,
            &m.scene_pre,
            &body.frames,
            &poses[b],
            &simulated_motions(&traj, b),
            &others,
            // GA's terms: `simulation_misses` compares these with GA's own losses (and the choice between
            // the two rounds above is made on them too).
            &m.cfg.ga.pose.weights,
        )?);
    }
    Ok(all)
}

/// The bodies other than `b` with their poses in every frame (`poses[o]`), as `evaluate_poses` takes them.
fn others_along<'a>(m: &'a Multi, b: usize, poses: &'a [Vec<Pose<f64>>]) -> Vec<(&'a ObjectModel, &'a [Pose<f64>])> {
    (0..m.bodies.len())
        .filter(|&o| o != b)
        .map(|o| (&*m.bodies[o].object, poses[o].as_slice()))
        .collect()
}

/// The other bodies as occluders of body `b`, at `pose_of(o)`.
fn others<'a>(m: &'a Multi, b: usize, pose_of: impl Fn(usize) -> Pose<f64>) -> Vec<Occluder<'a>> {
    (0..m.bodies.len())
        .filter(|&o| o != b)
        .map(|o| Occluder {
            object: &m.bodies[o].object,
            pose: pose_of(o),
        })
        .collect()
}

/// Stage 1: each body's pose in frame 0 from its guess (lifted out of the scene), the bodies in turn, each
/// with the others drawn at their fitted pose (or, not yet fitted, their guess); with the video's
/// brightness relative to each body's captures, fitted there (`FrameTarget::exposure`).
fn stage_first(
    m: &mut Multi,
    log: &mut Log,
    guesses: &[Option<Pose<f64>>],
    run: bool,
) -> Result<Vec<(Pose<f64>, f64)>> {
    let path = m.out.join("first_pose.json");
    if path.exists() {
        log.read_back("first poses", &path);
        let text = std::fs::read_to_string(&path)?;
        let v: Value = serde_json::from_str(&text).with_context(|| format!("{}", path.display()))?;
        return m
            .bodies
            .iter()
            .map(|b| {
                let e = &v["bodies"][&b.name];
                let t: [f64; 3] = serde_json::from_value(e["t"].clone())?;
                let q: [f64; 4] = serde_json::from_value(e["q"].clone())?;
                // 1 (as captured) in files written before the exposure was fitted.
                Ok((pose_of(t, q), e["exposure"].as_f64().unwrap_or(1.0)))
            })
            .collect::<Result<_>>()
            .map_err(|e: Error| err!(Input, "{}: {}", path.display(), e.chain()));
    }
    if !run {
        fail!(Stage, "stage first has not run: {} is missing", path.display());
    }
    let mut starts = Vec::new();
    for (b, (body, guess)) in m.bodies.iter().zip(guesses).enumerate() {
        let guess = match guess {
            Some(g) => *g,
            None => auto_guess(m, log, b)?,
        };
        let (start, lift) = lift_out(&m.world.bodies[b], &m.world.scene, guess);
        if lift > 0.0 {
            tracing::info!(
                "{}: the guess sank {:.1} mm into the scene: lifted out",
                body.name,
                lift * 1e3
            );
        }
        starts.push((body.frames[0].centred_on_mask(&start), lift));
    }
    // A searched body's brightness, measured at the search's winner, holds for its first-pose fit too.
    for (b, guess) in guesses.iter().enumerate() {
        if guess.is_none() {
            let body = &m.bodies[b];
            let exposure = exposure_at(
                &m.cfg.first_pose,
                &body.object,
                &m.scene_pre,
                &body.frames[0].with_whole_outline(),
                starts[b].0,
            )?;
            set_exposures(&mut m.bodies[b].frames, exposure, &m.drift);
        }
    }
    let m = &*m;
    let cfg = &m.cfg.first_pose;
    let pb = Task::start(m.observer, "first poses", (cfg.iterations * m.bodies.len()) as u64);
    let mut fitted: Vec<(Pose<f64>, f64)> = Vec::new();
    let mut entries = Map::new();
    for (b, body) in m.bodies.iter().enumerate() {
        let occluders = others(m, b, |o| fitted.get(o).map_or(starts[o].0, |f| f.0));
        let mut fit = match PoseFromImage::new(cfg.clone(), &body.object, &m.scene_pre, &body.frames[0], starts[b].0) {
            Ok(f) => f.with_occluders(occluders),
            Err(recon::PoseFitError::EmptyMask) => fail!(
                Input,
                "{}: body {:?}'s mask is empty in frame 0: its first pose cannot be fitted",
                m.video.display(),
                body.name
            ),
            Err(e) => fail!(Input, "{}: frame 0: {e}", body.name),
        };
        for i in 0..cfg.iterations {
            let l = fit.step();
            if i % 10 == 0 {
                log.write(json!({"stage": "first_pose", "body": body.name, "iteration": i, "loss": l.loss}))?;
            }
            pb.inc(1);
        }
        let e = fit.evaluate();
        let exposure = e.measured_exposure();
        tracing::info!(
            "{}: first pose IoU {:.3}; the video {exposure:.2} times as bright as its captures",
            body.name,
            e.iou(),
        );
        entries.insert(
            body.name.clone(),
            json!({"t": fit.pose.t.to_array(), "q": fit.pose.q.to_array_re(), "lift": starts[b].1,
                   "iou": e.iou(), "loss": e.loss, "exposure": exposure}),
        );
        fitted.push((fit.pose, exposure));
    }
    pb.finish();
    let doc = json!({ "bodies": entries, "brightness_drift": rounded(&m.drift) });
    pganeus_io::write_atomic(&path, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    log.write(json!({"stage": "first_pose", "done": true}))?;
    Ok(fitted)
}

/// `--init auto` for body `b`: the first pose searched from its own mask in frame 0 and its resting sides.
fn auto_guess(m: &Multi, log: &mut Log, b: usize) -> Result<Pose<f64>> {
    let body = &m.bodies[b];
    let mut rows = Vec::new();
    let pose = search_first_pose_of(
        &m.cfg.auto_init,
        &m.world.bodies[b],
        &m.world.scene,
        &body.object,
        &m.scene_pre,
        &body.frames[0].with_whole_outline(),
        &body.name,
        &m.video,
        &m.out,
        &mut rows,
        m.observer,
    );
    for r in rows {
        log.write(r)?;
    }
    pose
}

/// Stage 2, GA: every frame of every body; in each frame the bodies in turn, each with the others drawn at
/// their poses of that frame (fitted, or their start). Tracked frame by frame from the first poses, or,
/// given `from` (PGA's world), started at its simulation's poses with the contact penalty where it touches
/// the scene, as the one-body GA starts from PA's (then its pass back over the frames explained worst).
fn stage_ga(
    m: &Multi,
    log: &mut Log,
    first: &[Pose<f64>],
    from: Option<&World>,
    file: &str,
    run: bool,
) -> Result<Vec<Vec<FramePose>>> {
    let path = m.out.join(file);
    let n = m.bodies[0].frames.len();
    if path.exists() {
        log.read_back("GA", &path);
        return read_ga(m, &path, n);
    }
    if !run {
        fail!(Stage, "stage ga has not run: {} is missing", path.display());
    }
    let mut world = from.cloned().unwrap_or_else(|| m.world.clone());
    if from.is_none() {
        for (b, p) in first.iter().enumerate() {
            world.initial[b].pose = *p;
        }
    }
    let traj = world.simulate(&world.params());
    let mut gas = m
        .bodies
        .iter()
        .enumerate()
        .map(|(b, body)| {
            let (object, frames) = (&body.object, &body.frames);
            match from {
                None => PosesFromVideo::tracking(m.cfg.ga.clone(), object, &m.scene_pre, frames, &world, b, first[b])
                    .map(PosesFromVideo::holding_contacts),
                Some(_) => PosesFromVideo::new(m.cfg.ga.clone(), object, &m.scene_pre, frames, &world, b, &traj),
            }
            .with_context(|| format!("GA: {}", body.name))
        })
        .collect::<Result<Vec<_>>>()?;
    let pb = Task::start(
        m.observer,
        "GA",
        gas.iter().map(|g| g.steps_left()).sum::<usize>() as u64,
    );
    for k in 0..n {
        for b in 0..m.bodies.len() {
            let occluders = others(m, b, |o| gas[o].current_pose(k));
            gas[b].set_occluders(k, occluders);
            gas[b].step().with_context(|| format!("GA: {}", m.bodies[b].name))?;
            pb.inc(1);
        }
    }
    // The pass back over each body's frames explained worst (the others where the forward pass left them).
    for (b, g) in gas.iter_mut().enumerate() {
        while !g.done() {
            g.step().with_context(|| format!("GA: {}", m.bodies[b].name))?;
            pb.inc(1);
        }
    }
    pb.finish();
    let results: Vec<Vec<FramePose>> = gas.into_iter().map(|g| g.results).collect();
    for (body, rs) in m.bodies.iter().zip(&results) {
        for (k, r) in rs.iter().enumerate() {
            log.write(
                json!({"stage": "ga", "body": body.name, "frame": k, "loss": r.image.loss,
                "iou": r.image.iou(), "fitted": r.fitted}),
            )?;
        }
        let seen: Vec<f64> = rs.iter().filter(|r| r.fitted).map(|r| r.image.iou()).collect();
        tracing::info!(
            "GA: {}: IoU mean {:.3}, worst {:.3}",
            body.name,
            seen.iter().sum::<f64>() / seen.len().max(1) as f64,
            seen.iter().cloned().fold(f64::INFINITY, f64::min)
        );
    }
    write_ga(m, &path, &results)?;
    Ok(results)
}

/// GA's poses of every body as a trajectory file (poses only).
fn write_ga(m: &Multi, path: &Path, results: &[Vec<FramePose>]) -> Result<()> {
    let bodies = m
        .bodies
        .iter()
        .zip(results)
        .map(|(body, rs)| {
            let mut extra = object_entry(&body.object, &format!("object_{}.ply", body.name));
            extra.insert(
                "frames".into(),
                metric_rows(&rs.iter().map(|r| r.image.clone()).collect::<Vec<_>>()),
            );
            extra.insert("ga".into(), json!(rs.iter().map(ga_row).collect::<Vec<_>>()));
            pganeus_io::VideoBody {
                name: body.name.clone(),
                initial: pganeus_io::BodyState::from_geom(&rs[0].pose, Vec3::zero(), Vec3::zero()),
                poses: rs.iter().map(|r| pganeus_io::Pose::from_geom(&r.pose)).collect(),
                extra,
            }
        })
        .collect();
    let t = pganeus_io::Trajectory {
        capture: m.capture.clone(),
        fps: m.fps,
        bodies,
        contact: pganeus_io::Contact {
            restitution: 0.0,
            friction: 0.0,
            model: "none".into(),
            extra: Map::new(),
        },
        extra: Map::new(),
    };
    pganeus_io::write_trajectory(path, &t)?;
    Ok(())
}

fn read_ga(m: &Multi, path: &Path, frames: usize) -> Result<Vec<Vec<FramePose>>> {
    let t = pganeus_io::read_trajectory(path)?;
    m.bodies
        .iter()
        .map(|body| {
            let b = t
                .bodies
                .iter()
                .find(|b| b.name == body.name)
                .ok_or_else(|| err!(Input, "{}: no body {:?}", path.display(), body.name))?;
            let rows = b
                .extra
                .get("ga")
                .and_then(|v| v.as_array())
                .cloned()
                .unwrap_or_default();
            if b.poses.len() != frames || rows.len() != frames {
                fail!(
                    Input,
                    "{}: {}: {} poses for {frames} frames",
                    path.display(),
                    body.name,
                    b.poses.len()
                );
            }
            Ok(frame_poses(&b.poses, &rows))
        })
        .collect()
}

/// One PGA round: the fitted world, and, when it was fitted rather than read back, the schedule's steps and
/// the worlds it started from and reached after the launches (the paper's Fig. 8).
struct PgaRound {
    world: World,
    steps: Vec<recon::ScheduleStep>,
    guess: Option<World>,
    after_launch: Option<World>,
    /// The launch window's test and the launches it tells ([`launches_from_window`]'s record).
    window: Option<Value>,
}

impl PgaRound {
    /// `pga_guess.json` and `pga_launch.json`: the simulations of the worlds the kept round started from and
    /// reached after the launches, beside `pga.json` (`eval` scores them; the report draws them).
    fn write_schedule(&self, m: &Multi) -> Result<()> {
        for (name, w) in [("pga_guess.json", &self.guess), ("pga_launch.json", &self.after_launch)] {
            if let Some(w) = w {
                write_simulation(m, w, &m.out.join(name), Map::new())?;
            }
        }
        Ok(())
    }
}

/// Stage 3, PGA on GA's poses: the launches before the first contact between bodies, then each pair that
/// meets from a grid of starts, with every value over the whole video ([`recon::colliding_bodies`]); read
/// back from `file` when it exists.
fn stage_pga(m: &Multi, log: &mut Log, ga: &[Vec<FramePose>], file: &str) -> Result<PgaRound> {
    let path = m.out.join(file);
    if path.exists() {
        log.read_back("PGA", &path);
        let extra = pganeus_io::read_trajectory(&path)?.extra;
        return Ok(PgaRound {
            world: world_from_file(m, &path)?,
            steps: schedule_of(&extra, &path),
            guess: None,
            after_launch: None,
            window: extra.get(WINDOW_KEY).cloned(),
        });
    }
    let cfg = pga_config(m);
    let pairs = m.world.pairs();
    let observed = pga_observed(m, ga);
    for (body, rest) in m.bodies.iter().zip(&observed.resting) {
        if let Some(rest) = rest {
            tracing::info!(
                "{}: still in frames 0-{}: at rest on the scene until struck (no launch; its pose from those frames)",
                body.name,
                rest.frames - 1
            );
            log.write(json!({"stage": "pga", "body": body.name, "at_rest_frames": rest.frames,
                "rest_pose": {"t": rest.pose.t.to_array(), "q": rest.pose.q.to_array_re()}}))?;
        }
    }
    // At most: the launch, the frames after the first collision, each pair, the final joint fit.
    let steps = 3 + pairs.len();
    let per_step = if m.cfg.pga_multi_start {
        1 + CONTACT_STARTS.len()
    } else {
        1
    };
    let pb = Task::start(m.observer, "PGA", (steps * per_step) as u64);
    let mut rows = Vec::new();
    let fit = fit_colliding_bodies(
        &cfg,
        m.cfg.pga_multi_start,
        m.world.clone(),
        observed.clone(),
        launch_settings(m),
        &mut |label, i, r| {
            rows.push(start_row(json!({"stage": "pga", "step": label}), i, r));
            pb.inc(1);
        },
    )
    .context("PGA")?;
    pb.finish();
    let (fit, window) = launches_from_window(m, log, &cfg, observed, fit, &mut rows)?;
    for &(p, k) in &fit.contacts {
        let (i, j) = pairs[p];
        tracing::info!("GA: {} and {} meet in frame {k}", m.bodies[i].name, m.bodies[j].name);
        log.write(json!({"stage": "pga", "pair": [m.bodies[i].name, m.bodies[j].name], "first_contact": k}))?;
    }
    for r in rows {
        log.write(r)?;
    }
    for s in &fit.steps {
        log.write(json!({"stage": "pga", "step": s.label, "winner": s.winner, "loss": s.loss}))?;
    }
    let mut extra = schedule_extra(&fit.steps)?;
    if let Some(w) = &window {
        extra.insert(WINDOW_KEY.into(), w.clone());
    }
    write_simulation(m, &fit.world, &path, extra)?;
    // The world as the file holds it (the simulation's first state, its quaternion normalised to the last
    // bit), so that a resumed fit goes on from exactly the world this one does.
    Ok(PgaRound {
        world: world_from_file(m, &path)?,
        steps: fit.steps,
        guess: Some(fit.guess),
        after_launch: fit.after_launch,
        window,
    })
}

/// The schedule's fit, or the same schedule with the launches held at those the frames before the first
/// collision tell alone, where the fit's launches miss those frames by more than their noise
/// ([`recon::CollidingFit::window`]) and the held fit's simulation explains the video's images better (the
/// one-body fit's flight test, [`super::single`]'s `launch_from_flight`: the test alone also flags launches
/// the collisions did not bend, since GA's errors over a few frames are not independent).
fn launches_from_window(
    m: &Multi,
    log: &mut Log,
    cfg: &PhysicsFitConfig,
    observed: recon::ObservedBodies,
    fit: recon::CollidingFit,
    rows: &mut Vec<Value>,
) -> Result<(recon::CollidingFit, Option<Value>)> {
    let Some(window) = &fit.window else {
        return Ok((fit, None));
    };
    let bent = window.bent();
    // Per body: the launch the window tells (`null` for a body at rest, which has none to test).
    let launches: Vec<Value> = window
        .flight_world
        .initial
        .iter()
        .zip(&observed.resting)
        .map(|(s, rest)| match rest {
            Some(_) => Value::Null,
            None => json!({"v0": s.v.to_array(), "omega0": s.omega.to_array(),
                "pose": {"t": s.pose.t.to_array(), "q": s.pose.q.to_array_re()}}),
        })
        .collect();
    let mut record = json!({"frames": window.frames, "statistic": window.statistic, "critical": window.critical,
        "bent": bent, "bodies": launches});
    tracing::info!(
        "the launches against the {} frames before the first collision: χ² {:.1} against {:.1} at 1 %: {}",
        window.frames,
        window.statistic,
        window.critical,
        if bent {
            "they miss them; the launches those frames tell, held, are tried"
        } else {
            "they stand"
        }
    );
    let v0 = |w: &World| w.initial.iter().map(|s| s.v.to_array()).collect::<Vec<_>>();
    log.write(json!({"stage": "pga_window", "frames": window.frames, "statistic": window.statistic,
        "critical": window.critical, "bent": bent, "squares": window.joint_squares, "window_squares": window.flight_squares,
        "dof": window.dof, "unknowns": window.unknowns, "v0": v0(&fit.world), "window_v0": v0(&window.flight_world)}))?;
    if !bent {
        return Ok((fit, Some(record)));
    }
    let per_step = if m.cfg.pga_multi_start {
        1 + CONTACT_STARTS.len()
    } else {
        1
    };
    let pb = Task::start(
        m.observer,
        "PGA, launches held",
        ((2 + m.world.pairs().len()) * per_step) as u64,
    );
    let held = recon::fit_colliding_bodies_holding_launch(
        cfg,
        m.cfg.pga_multi_start,
        &window.flight_world,
        observed,
        launch_settings(m),
        &mut |label, i, r| {
            rows.push(start_row(json!({"stage": "pga_window", "step": label}), i, r));
            pb.inc(1);
        },
    );
    pb.finish();
    // A check of the kept fit: where it cannot run, the kept fit stands.
    let held = match held {
        Ok(h) => h,
        Err(e) => {
            tracing::warn!("PGA with the launches held did not run ({e}): the launches fitted with the rest stand");
            record["held_kept"] = json!(false);
            return Ok((fit, Some(record)));
        }
    };
    let total = |w: &World| -> Result<f64> {
        Ok(simulated_losses(m, w)?
            .iter()
            .map(|b| recon::video_fit::total_loss(b))
            .sum())
    };
    let (joint, kept) = (total(&fit.world)?, total(&held.world)?);
    let keep_held = kept < joint;
    tracing::info!(
        "the launches held: image loss {kept:.4} against {joint:.4}: {}",
        if keep_held { "kept" } else { "not kept" }
    );
    log.write(json!({"stage": "pga_window", "image_loss": kept, "image_loss_joint": joint, "kept": keep_held}))?;
    record["held_kept"] = json!(keep_held);
    // Kept, the held fit takes the joint schedule's first worlds along (`pga_guess.json`: the launches
    // guessed from GA's first frames; `pga_launch.json`: fitted to the frames before the collision) and its
    // test.
    let fit = if keep_held {
        recon::CollidingFit {
            guess: fit.guess,
            after_launch: fit.after_launch,
            window: fit.window,
            ..held
        }
    } else {
        fit
    };
    Ok((fit, Some(record)))
}

/// The key of a PGA stage file that holds its launch window's test.
const WINDOW_KEY: &str = "launch_window";

/// The key of a PGA stage file that holds its schedule's steps (their starts widen the value ranges).
const SCHEDULE_KEY: &str = "schedule";

/// A PGA stage file's keys that keep its schedule's steps.
fn schedule_extra(steps: &[recon::ScheduleStep]) -> Result<Map<String, Value>> {
    let mut extra = Map::new();
    extra.insert(SCHEDULE_KEY.into(), serde_json::to_value(steps)?);
    Ok(extra)
}

/// The schedule's steps kept in a PGA stage file's `extra` keys: none (with a warning) in a file from before
/// they were kept, or whose steps do not read (a resumed fit then widens its ranges by no starts).
fn schedule_of(extra: &Map<String, Value>, path: &Path) -> Vec<recon::ScheduleStep> {
    let Some(v) = extra.get(SCHEDULE_KEY) else {
        tracing::warn!(
            "{}: no schedule kept (an older stage file): the value ranges are not widened by its starts",
            path.display()
        );
        return Vec::new();
    };
    serde_json::from_value(v.clone()).unwrap_or_else(|e| {
        tracing::warn!(
            "{}: its \"{SCHEDULE_KEY}\" does not read ({e}): the value ranges are not widened by its starts",
            path.display()
        );
        Vec::new()
    })
}

/// `world`'s simulation as a trajectory file at `path`, each body with its object entry, with `extra` keys.
fn write_simulation(m: &Multi, world: &World, path: &Path, extra: Map<String, Value>) -> Result<()> {
    let traj = world.simulate(&world.params());
    let mut t = scene_file::trajectory_file(&m.capture, world, &traj, sim::ENGINE, extra);
    for (tb, body) in t.bodies.iter_mut().zip(&m.bodies) {
        tb.extra
            .extend(object_entry(&body.object, &format!("object_{}.ply", body.name)));
    }
    pganeus_io::write_trajectory(path, &t)?;
    Ok(())
}

/// PGA's settings: rotations in metres at the bodies' mean radius, as the one-body fit weighs them.
fn pga_config(m: &Multi) -> PhysicsFitConfig {
    let radius = m.world.bodies.iter().map(|b| b.bounding_radius).sum::<f64>() / m.world.bodies.len() as f64;
    PhysicsFitConfig {
        rotation_weight: m.cfg.pga.rotation_weight * radius,
        ..m.cfg.pga.clone()
    }
}

/// GA's poses as PGA observes them: weighed by GA's residuals and rests, each body's depth counting least
/// where GA did not hold it on the scene closer than its image tells the depth, as in the one-body fit.
fn pga_observed(m: &Multi, ga: &[Vec<FramePose>]) -> recon::ObservedBodies {
    let poses: Vec<Vec<Pose<f64>>> = ga.iter().map(|rs| rs.iter().map(|r| r.pose).collect()).collect();
    let eye = m.bodies[0].frames[0].camera.center();
    let weights: Vec<Vec<f64>> = ga
        .iter()
        .zip(&m.world.bodies)
        .map(|(rs, body)| ga_weights_of(rs, eye, body.bounding_radius))
        .collect();
    let pinned = m.cfg.ga.contact.pins_depth();
    let camera = m.bodies[0].frames[0].camera;
    let mut observed = recon::ObservedBodies {
        eye: Some(camera.center().to_array()),
        depth_held: ga
            .iter()
            .map(|rs| rs.iter().map(|r| r.in_contact && pinned).collect())
            .collect(),
        ..recon::ObservedBodies::new(poses, weights)
    };
    observed.settle_resting(&m.world, &camera);
    // One image's precision across the line of sight, at the launched bodies' mean distance in the first
    // frame (the launch window's test leaves the resting ones out).
    let launched: Vec<f64> = (0..observed.poses.len())
        .filter(|&b| observed.resting.get(b).copied().flatten().is_none())
        .map(|b| {
            let diameter = 2.0 * m.world.bodies[b].bounding_radius;
            recon::ImagePrecision::of(&camera, &observed.poses[b][0], diameter).across
        })
        .collect();
    observed.precision = (!launched.is_empty()).then(|| launched.iter().sum::<f64>() / launched.len() as f64);
    observed
}

fn launch_settings(m: &Multi) -> recon::LaunchSettings {
    recon::LaunchSettings {
        frames: m.cfg.launch_frames,
        in_plane: m.cfg.launch_in_plane,
    }
}

/// The ranges of the reported world's contact values that the GA poses it was fitted to cannot tell apart,
/// widened by the starts of the schedule's steps over the whole video that ended within their bar
/// (`steps`: none for a world read back; logged), and the predictable horizon they honour.
fn value_ranges(
    m: &Multi,
    log: &mut Log,
    world: &World,
    ga: &[Vec<FramePose>],
    steps: &[recon::ScheduleStep],
) -> Result<(Vec<ValueRange>, recon::Horizon)> {
    let t = Instant::now();
    let pb = Task::start(m.observer, "value ranges", 0);
    let observed = pga_observed(m, ga);
    let mut ranges = colliding_value_ranges(
        &pga_config(m),
        world,
        &observed,
        launch_settings(m),
        m.cfg.ranges,
        &pb.follow(),
    )
    .context("PGA's value ranges")?;
    for step in steps.iter().filter(|s| s.whole_video) {
        recon::widen_by_starts(&mut ranges, &step.starts, step.on, step.loss);
    }
    // What the frames the simulation can predict allow, where they end before the video does.
    let horizon = horizon_of(world, &m.bodies[0].frames[0].camera, log)?;
    let n = ga.first().map_or(0, Vec::len);
    if horizon.frames >= 2 && horizon.frames < n {
        let within = colliding_value_ranges(
            &pga_config(m),
            world,
            &observed.before(horizon.frames),
            launch_settings(m),
            m.cfg.ranges,
            &pb.follow(),
        )
        .context("PGA's value ranges over the predictable frames")?;
        recon::widen_by_ranges(&mut ranges, &within);
    }
    pb.finish();
    tracing::info!("value ranges: {:.1} s", t.elapsed().as_secs_f64());
    report_ranges(&ranges, &mut |row| log.write(row))?;
    Ok((ranges, horizon))
}

/// The world of a PGA file this command wrote: each body's initial state, the scene's and the pairs' values.
fn world_from_file(m: &Multi, path: &Path) -> Result<World> {
    let t = pganeus_io::read_trajectory(path)?;
    let mut w = m.world.clone();
    // Simulated at the step it was fitted at (`finer_step_round`).
    if let Some(substeps) = t
        .extra
        .get("sim")
        .and_then(|s| s.get("substeps"))
        .and_then(Value::as_u64)
    {
        w.config.substeps = substeps as usize;
    }
    for (b, body) in m.bodies.iter().enumerate() {
        let e = t
            .bodies
            .iter()
            .find(|x| x.name == body.name)
            .ok_or_else(|| err!(Input, "{}: no body {:?}", path.display(), body.name))?;
        let i = &e.initial;
        w.initial[b] = BodyState::new(i.t, i.q, i.v, i.omega);
        w.scene_contact[b] = sim::ContactParams {
            restitution: t.contact.restitution,
            friction: t.contact.friction,
        };
    }
    let pairs = scene_file::contact_pairs(&t);
    for (p, (i, j)) in w.pairs().into_iter().enumerate() {
        let mut names = [m.bodies[i].name.clone(), m.bodies[j].name.clone()];
        names.sort();
        if let Some((_, c)) = pairs.iter().find(|(n, _)| *n == names) {
            w.pair_contact[p] = *c;
        }
    }
    Ok(w)
}

/// What `finish` reports beside the world: GA's stand-in poses, the simulation's image terms, the value
/// ranges, the bodies at rest from the start and the predictable horizon.
struct Reported<'a> {
    ga: &'a [Vec<FramePose>],
    sim_losses: Vec<Vec<ImageLoss>>,
    ranges: &'a [ValueRange],
    rests: &'a [Option<recon::RestingStart>],
    horizon: &'a recon::Horizon,
    window: Option<&'a Value>,
}

/// The final trajectory of every body (simulated where it explains the video, GA's pose where it clearly
/// does not), renders with every body, the strip and the animation.
fn finish(
    m: &Multi,
    world: &World,
    reported: Reported,
    timings: &Map<String, Value>,
    outcome: &mut FitOutcome,
) -> Result<()> {
    let Reported {
        ga,
        sim_losses,
        ranges,
        rests,
        horizon,
        window,
    } = reported;
    let n = m.bodies[0].frames.len();
    let nb = m.bodies.len();
    let traj = world.simulate(&world.params());
    let sim_poses = body_poses(&traj, nb);
    let camera = m.bodies[0].frames[0].camera;
    let mut reported = Vec::with_capacity(nb);
    let mut source = Vec::with_capacity(nb);
    let mut sources = Vec::with_capacity(nb);
    for (b, body) in m.bodies.iter().enumerate() {
        // Scored as `sim_losses` were: the other bodies where the simulation puts them.
        let others = others_along(m, b, &sim_poses);
        let motions = simulated_motions(&traj, b);
        let score = |poses: &[Pose<f64>]| {
            evaluate_poses(
                &body.object,
                &m.scene_pre,
                &body.frames,
                poses,
                &motions,
                &others,
                &m.cfg.ga.pose.weights,
            )
        };
        let body_shape = (
            world.bodies[b].bounding_radius,
            world.bodies[b].contact_points.as_slice(),
        );
        let (poses, from) = reported_poses(&sim_poses[b], &sim_losses[b], &ga[b], &camera, body_shape, score)?;
        sources.push(
            poses
                .iter()
                .zip(&from)
                .map(|(&pose, &from)| ReportedFrame { pose, from })
                .collect(),
        );
        reported.push(poses);
        source.push(from.iter().map(|s| s.name()).collect::<Vec<_>>());
    }
    // Renders of the reported poses, every body over the pre-rendered scene.
    let cam = m.bodies[0].frames[0].camera;
    let (w, h) = (cam.width, cam.height);
    std::fs::create_dir_all(m.out.join("render"))?;
    let pb = Task::start(m.observer, "render", n as u64);
    let mut composer = Composer::default();
    let mut rows: Vec<Vec<Value>> = vec![Vec::with_capacity(n); nb];
    let mut strips = Vec::with_capacity(n);
    for k in 0..n {
        let layers: Vec<Layer> = m
            .bodies
            .iter()
            .enumerate()
            .map(|(b, body)| {
                let pose = reported[b][k];
                let routed = body.object.route(&pose, &cam);
                Layer::object(&routed.field, &routed.capture_from_body, &pose, b)
            })
            .collect();
        let img = render_composed(&layers, nb, Behind::Scene(&m.scene_pre), &cam, &mut composer);
        let frame_rgb = &m.bodies[0].frames[k].rgb;
        let psnr = neus::render_view::psnr(&img.rgb, frame_rgb, None) as f64;
        for (b, body) in m.bodies.iter().enumerate() {
            let mask = &body.frames[k].mask;
            let ours = |p: usize| img.object_opacity[p * nb + b] > 0.5;
            let inter = (0..mask.len()).filter(|&p| ours(p) && mask[p]).count();
            let union = (0..mask.len()).filter(|&p| ours(p) || mask[p]).count();
            let iou = if union == 0 { 1.0 } else { inter as f64 / union as f64 };
            let row = json!({"frame": k, "psnr": (psnr * 100.0).round() / 100.0,
                "iou": (iou * 1e4).round() / 1e4, "pose": source[b][k],
                "brightness": (m.drift[k] * 1e4).round() / 1e4});
            rows[b].push(with_simulation(row, &sim_poses[b][k], ga[b].get(k)));
        }
        let mut rgb = Image::new(w, h, 3);
        let mut input = Image::new(w, h, 3);
        for (p, (c, f)) in img.rgb.iter().zip(frame_rgb).enumerate() {
            rgb.data[p * 3..p * 3 + 3].copy_from_slice(&c.map(to8));
            input.data[p * 3..p * 3 + 3].copy_from_slice(&f.map(to8));
        }
        pganeus_io::write_png(&m.out.join("render").join(format!("{k:03}.png")), &rgb)?;
        strips.push(beside(&input, &rgb));
        pb.inc(1);
    }
    pb.finish();
    pganeus_io::write_apng(&m.out.join("animation.png"), &strips, m.fps)?;
    pganeus_io::write_png(&m.out.join("strip.png"), &strip(&strips, 6))?;

    let mut extra = Map::new();
    extra.insert("timings_s".into(), Value::Object(timings.clone()));
    extra.insert("video".into(), json!(m.video));
    extra.insert("horizon".into(), horizon_entry(horizon));
    let mut t = scene_file::trajectory_file(&m.capture, world, &traj, sim::ENGINE, extra);
    write_ranges(&mut t, ranges);
    for (b, body) in m.bodies.iter().enumerate() {
        let mesh = format!("object_{}.ply", body.name);
        let tb = &mut t.bodies[b];
        for (pose, r) in tb.poses.iter_mut().zip(&reported[b]) {
            *pose = pganeus_io::Pose::from_geom(r);
        }
        tb.extra.extend(object_entry(&body.object, &mesh));
        if let Some(rest) = rests.get(b).copied().flatten() {
            let mut start = serde_json::to_value(rest.start())?;
            start["still_frames"] = json!(rest.frames);
            tb.extra.insert("start".into(), start);
        }
        // The launch the frames before the first collision tell, beside the kept one (`eval` scores both).
        if let Some(w) = window.filter(|w| !w["bodies"][b].is_null()) {
            let mut flight = w["bodies"][b].clone();
            for key in ["frames", "bent", "statistic", "critical", "held_kept"] {
                if let Some(v) = w.get(key) {
                    flight[key] = v.clone();
                }
            }
            flight["before"] = json!("the first collision");
            tb.extra.insert("flight".into(), flight);
        }
        tb.extra.insert("frames".into(), json!(rows[b]));
        let mut stages = Map::new();
        stages.insert("simulated".into(), metric_rows(&sim_losses[b]));
        stages.insert(
            "ga".into(),
            metric_rows(&ga[b].iter().map(|r| r.image.clone()).collect::<Vec<_>>()),
        );
        tb.extra.insert("stages".into(), Value::Object(stages));
        pganeus_io::write_ply(
            &m.out.join(&mesh),
            &pganeus_io::PlyMesh {
                mesh: body.object.mesh.clone(),
                colors: None,
                normals: None,
            },
            pganeus_io::PlyEncoding::BinaryLittleEndian,
        )?;
    }
    pganeus_io::write_trajectory(&m.out.join("trajectory.json"), &t)?;
    let mut summary = Vec::new();
    for (b, body) in m.bodies.iter().enumerate() {
        let s = &world.initial[b];
        let ious: Vec<f64> = rows[b].iter().filter_map(|r| r["iou"].as_f64()).collect();
        summary.push(format!(
            "{}: v0 {:?} m/s, IoU against the masks worst {:.3}, {} frames from GA ({} at a weighed depth)",
            body.name,
            s.v.to_array().map(|x| (x * 1e3).round() / 1e3),
            ious.iter().cloned().fold(f64::INFINITY, f64::min),
            source[b].iter().filter(|s| **s != "simulated").count(),
            source[b]
                .iter()
                .filter(|s| **s == ReportedPose::GaAtWeighedDepth.name())
                .count()
        ));
    }
    for (p, (i, j)) in world.pairs().into_iter().enumerate() {
        let c = world.pair_contact[p];
        summary.push(format!(
            "{} and {}: restitution {:.3}, friction {:.3}",
            m.bodies[i].name, m.bodies[j].name, c.restitution, c.friction
        ));
    }
    outcome.reported = Some(sources);
    outcome.trajectory = Some(m.out.join("trajectory.json"));
    outcome.summary = format!(
        "fitted {n} frames of {nb} bodies in {:.1} s; scene restitution {:.3}, friction {:.3}; {}; wrote {}",
        m.t_start.elapsed().as_secs_f64(),
        world.scene_contact[0].restitution,
        world.scene_contact[0].friction,
        summary.join("; "),
        m.out.join("trajectory.json").display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PGA stage file keeps its schedule's steps exactly (a resumed fit widens its ranges by the same
    /// starts as the uninterrupted one).
    #[test]
    fn the_schedule_reads_back_from_its_stage_file_exactly() {
        let start = |r: f64, f: f64| recon::StartResult {
            restitution: r,
            friction: f,
            loss: 0.1 + 0.2,
            iterations: 7,
            fitted_restitution: 1.0 / 3.0,
            fitted_friction: std::f64::consts::PI / 10.0,
        };
        let steps = vec![
            recon::ScheduleStep {
                label: "launch, frames 0-3".into(),
                starts: vec![start(0.5, 0.5), start(0.2, 0.8)],
                winner: 1,
                loss: 2.0f64.sqrt() / 7.0,
                on: recon::StartsOn::Scene,
                whole_video: false,
            },
            recon::ScheduleStep {
                label: "pair 0".into(),
                starts: vec![start(0.9, 0.1)],
                winner: 0,
                loss: 1e-7 / 3.0,
                on: recon::StartsOn::Pair(0),
                whole_video: true,
            },
        ];
        let text = serde_json::to_string(&Value::Object(schedule_extra(&steps).unwrap())).unwrap();
        let extra: Map<String, Value> = serde_json::from_str(&text).unwrap();
        let path = Path::new("pga.json");
        assert_eq!(schedule_of(&extra, path), steps);
        assert!(schedule_of(&Map::new(), path).is_empty(), "an older file: no steps");
    }

    fn frame(x: f64, loss: f64, fitted: bool) -> FramePose {
        FramePose {
            pose: Pose::new(geom::Quat::identity(), Vec3::new(x, 0.0, 0.0)),
            image: ImageLoss {
                loss,
                ..ImageLoss::default()
            },
            contact_penalty: 0.0,
            in_contact: false,
            fitted,
            start: recon::StartFrom::Physics,
        }
    }

    #[test]
    fn the_stand_in_is_the_pass_that_explains_the_frame_better() {
        let tracked = vec![vec![
            frame(1.0, 0.2, true),
            frame(2.0, 0.1, true),
            frame(3.0, 0.0, false),
        ]];
        let second = vec![vec![
            frame(-1.0, 0.1, true),
            frame(-2.0, 0.3, true),
            frame(-3.0, 0.5, true),
        ]];
        let picked: Vec<f64> = better_per_frame(&tracked, &second)[0]
            .iter()
            .map(|f| f.pose.t.x)
            .collect();
        // Lower loss wins; an unfitted frame (no mask) loses to a fitted one whatever its loss.
        assert_eq!(picked, vec![-1.0, 2.0, -3.0]);
    }
}
