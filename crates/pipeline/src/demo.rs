//! `pganeus demo`: the whole method on the embedded synthetic tabletop scene, one command. Each stage is
//! the subcommand a user would run (its command line is printed and recorded), so the demo is also the
//! recipe: synth → train the scene and the toy in its two poses → merge → bake → fit the slide and the drop
//! from `--init auto` → eval against the truth → a report. Stages that finished with the same command line
//! are skipped on a rerun; a stage stopped half way resumes (training from its checkpoint, `fit` from its
//! stage files).

use crate::error::{err, Context};
use crate::eval::EvalArgs;
use crate::fit::{FitInputs, FitRun, Stage};
use crate::import_session::ImportSessionArgs;
use crate::report_page::ReportArgs;
use crate::run_folder::read_json;
use crate::surfaces::{BakeArgs, MergeArgs};
use crate::synth::{PhysicsArg, RawBoardArg, ScaleArg, SynthArgs};
use crate::train::TrainArgs;
use crate::{note, Observer, Result, Resume};
use recon::VideoFitConfig;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, Clone)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus demo
  pganeus demo --quick --out out/demo-quick
  pganeus demo --preset backdrop --physics rapier
  pganeus demo --preset two-body
  pganeus demo --preset raw")
)]
pub struct DemoArgs {
    /// Short training and a light fit on the first 8 frames: the whole chain in about 3 minutes (a smoke
    /// run; its figures are far from the method's).
    #[cfg_attr(feature = "clap", arg(long, conflicts_with = "scale"))]
    pub quick: bool,
    /// The folder for everything: data/, runs/, merged/, scene.sdf, fits/, report.md, demo.json.
    /// Default: out/demo, with the preset, `rapier`, `large`, `camera` and `quick` added when given
    /// (out/demo-quick, out/demo-backdrop-rapier, ...).
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: Option<PathBuf>,
    /// Redo every stage, even those that finished.
    #[cfg_attr(feature = "clap", arg(long))]
    pub force: bool,
    /// The synthetic scene (`synth --preset`): tabletop (a toy slides into a wall and drops), backdrop (the
    /// same motion with another light, board, obstacles and a backdrop), two-body (a toy hits a block: the
    /// several-body fit), or raw: the tabletop as a camera films it (`synth --raw aruco-grid`: photos through a
    /// distorting lens with a printed board, no cameras, no masks), through `import` and `run`.
    #[cfg_attr(feature = "clap", arg(long, default_value = "tabletop"))]
    pub preset: String,
    /// What moves the bodies in the videos (`synth --physics`): the project's simulator (the preset's
    /// default) or Rapier, an engine the project did not write (then motion is compared, not parameters).
    #[cfg_attr(feature = "clap", arg(long, value_enum))]
    pub physics: Option<PhysicsArg>,
    /// small: 160×120, 30 frames (about 11 minutes for the tabletop); large: 320×240, 48 frames, longer
    /// training (about an hour).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value = "small"))]
    pub scale: ScaleArg,
    /// The captures as a camera makes them (`synth --camera-like`): exposure and white balance per photo,
    /// a video's drifting exposure, noise, JPEG and motion blur, the truth kept (the raw preset's footage
    /// is already so).
    #[cfg_attr(feature = "clap", arg(long))]
    pub camera_like: bool,
}

/// Each stage's expected seconds on two cores, measured alone (only for the ETA): the full tabletop demo
/// and `--quick` of 2026-12-08 (freed memory kept for reuse), the large tabletop of 2026-11-27 (/tmp runs of
/// `synth --scale large`, training 1500 steps) with its fits of 2026-12-07 (baked: the 48-frame slide and drop,
/// 180 and 262 s), the raw preset's synth and import of 2026-12-06. A fit is per body in the video.
pub(crate) struct Expected {
    synth: f64,
    /// synth with the raw footage (`--preset raw`), and its import.
    synth_raw: f64,
    import: f64,
    scene: f64,
    object: f64,
    merge: f64,
    bake: f64,
    fit_per_body: f64,
    eval: f64,
}

/// How the demo's sizes differ between `--quick`, the default and `--scale large`.
pub(crate) struct Plan {
    scale: ScaleArg,
    scene_steps: usize,
    object_steps: usize,
    bake_res: usize,
    /// Frames of each video the fit reads (all when None).
    frames: Option<usize>,
    /// `fit --config` settings (none: fit's defaults).
    fit_config: Option<&'static str>,
    /// `train --config` settings for the scene (none: the scene preset's).
    scene_config: Option<&'static str>,
    /// `train --config` settings for each object capture (none: the object preset's).
    object_config: Option<&'static str>,
    /// `merge --field-res` (none: merge's default).
    merge_field_res: Option<usize>,
    expected: Expected,
}

pub(crate) const QUICK: Plan = Plan {
    scale: ScaleArg::Small,
    scene_steps: 120,
    object_steps: 120,
    bake_res: 192,
    frames: Some(8),
    fit_config: Some(QUICK_FIT),
    scene_config: Some(
        "# demo --quick: half the rays per step, coarser stereo points\nbatch_rays = 1024\n\n[stereo]\nstride = 2\nhypotheses = 64\n",
    ),
    // At 120 steps the object preset's occupancy (refined from step 200) is still every cell, too many to bake
    // for the fit, which then reads the network at every sample.
    object_config: Some("# demo --quick: the occupancy refined from step 60, so the fit can bake the object\noccupancy_warmup = 60\n"),
    merge_field_res: Some(96),
    expected: Expected {
        synth: 8.0,
        synth_raw: 92.0,
        import: 8.0,
        scene: 24.0,
        object: 12.0,
        merge: 17.0,
        bake: 3.0,
        fit_per_body: 42.0,
        eval: 2.0,
    },
};

pub(crate) const FULL: Plan = Plan {
    scale: ScaleArg::Small,
    scene_steps: 1500,
    object_steps: 1000,
    bake_res: 256,
    frames: None,
    fit_config: None,
    scene_config: None,
    object_config: None,
    merge_field_res: None,
    expected: Expected {
        synth: 8.0,
        synth_raw: 92.0,
        import: 8.0,
        scene: 186.0,
        object: 50.0,
        merge: 19.0,
        bake: 3.0,
        fit_per_body: 62.0,
        eval: 2.0,
    },
};

/// The default's training and fit at 320×240, the objects trained as long as the scene.
const LARGE: Plan = Plan {
    scale: ScaleArg::Large,
    object_steps: 1500,
    expected: Expected {
        synth: 170.0,
        // Not measured: the small scale's raw footage and its import grown by their pixels (960 × 720
        // against 480 × 360).
        synth_raw: 370.0,
        import: 32.0,
        scene: 1130.0,
        object: 460.0,
        merge: 55.0,
        bake: 10.0,
        fit_per_body: 220.0,
        eval: 5.0,
    },
    ..FULL
};

/// A light fit: fewer steps and pixels in every stage, one GA⇄PGA round, no multi-start.
const QUICK_FIT: &str = r#"# demo --quick: fewer steps and pixels in every stage (a smoke run, not the method's accuracy)
rounds = 1
pga_multi_start = false
[first_pose]
iterations = 40
rays_per_step = 256
[pa]
iterations = 25
rays_per_frame = 128
window_steps = 10
[ga]
hypotheses = false
[ga.pose]
iterations = 12
rays_per_step = 256
[pga]
iterations = 15
[auto_init]
screened = 2
screen_iterations = 10
refined = 1
twin_iterations = 10
[auto_init.refine]
iterations = 40
rays_per_step = 256
"#;

/// What the demo runs on: the preset's scene, made by which engine, at which size.
struct Scene {
    preset: String,
    physics: Option<PhysicsArg>,
    camera_like: bool,
    /// The footage is raw (`--preset raw`): no cameras and no masks, `import` calibrates it.
    raw: bool,
    desc: synth::SynthScene,
}

/// The demo's preset of raw footage, and the synth scene it films.
const RAW_PRESET: &str = "raw";
const RAW_SCENE: &str = "tabletop";

impl Scene {
    fn new(a: &DemoArgs) -> Result<Scene> {
        let raw = a.preset == RAW_PRESET;
        if raw && a.camera_like {
            crate::error::fail!(
                Settings,
                "--camera-like with --preset raw: the raw footage is already as a camera makes it"
            );
        }
        let synth_preset = if raw { RAW_SCENE } else { a.preset.as_str() };
        Ok(Scene {
            preset: a.preset.clone(),
            physics: a.physics,
            camera_like: a.camera_like,
            raw,
            desc: crate::synth::named_preset(synth_preset, crate::synth::scale(a.scale))?,
        })
    }

    /// The `synth --preset` the scene is made with.
    fn synth_preset(&self) -> &str {
        if self.raw {
            RAW_SCENE
        } else {
            &self.preset
        }
    }

    /// The engine named on the command line (none: the preset's own).
    fn physics_name(&self) -> Option<String> {
        self.physics.map(|p| p.name().to_string())
    }
}

/// The default output folder: out/demo, with what differs from the default demo added.
pub fn default_out(a: &DemoArgs) -> PathBuf {
    let mut name = String::from("demo");
    if a.preset != "tabletop" {
        name += &format!("-{}", a.preset);
    }
    if matches!(a.physics, Some(PhysicsArg::Rapier)) {
        name += "-rapier";
    }
    if matches!(a.scale, ScaleArg::Large) {
        name += "-large";
    }
    if a.camera_like {
        name += "-camera";
    }
    if a.quick {
        name += "-quick";
    }
    PathBuf::from("out").join(name)
}

/// What one stage of the demo runs: a call of this library, typed.
#[derive(Clone, Debug, PartialEq)]
pub enum StageJob {
    Synth(SynthArgs),
    Import(ImportSessionArgs),
    Train(TrainArgs),
    Merge(MergeArgs),
    Bake(BakeArgs),
    /// A fit: its inputs, its settings file (over fit's defaults) and its run folder.
    Fit {
        inputs: FitInputs,
        config: Option<PathBuf>,
        out: PathBuf,
    },
    Eval(EvalArgs),
    Report(ReportArgs),
}

/// One stage: a name, the command line a user would type for it (printed and recorded: the demo is also the
/// recipe), what it runs, and its expected share of the time (seconds on two cores, only for the ETA).
#[derive(Clone, Debug)]
pub struct DemoStage {
    pub name: String,
    pub argv: Vec<String>,
    pub job: StageJob,
    pub expected_s: f64,
}

/// What finished: stage name → the command line it ran with and how long it took.
#[derive(Default, Serialize, Deserialize)]
pub(crate) struct Record {
    done: BTreeMap<String, Done>,
}

#[derive(Serialize, Deserialize, Clone)]
struct Done {
    argv: Vec<String>,
    seconds: f64,
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// The stages in order, their arguments written out as a user would type them: synth, the scene's training,
/// each body's two static captures and their merge, the bake, then each video's fit and eval, the report.
fn stages(plan: &Plan, scene: &Scene, out: &Path) -> Vec<DemoStage> {
    let data = out.join("data");
    let mut v = Vec::new();
    let mut synth_args: Vec<String> = vec![
        "synth".into(),
        "--preset".into(),
        scene.synth_preset().into(),
        "--scale".into(),
        plan.scale.name().into(),
        "--out".into(),
        s(&data),
        "--contact-sheet".into(),
    ];
    if let Some(p) = scene.physics_name() {
        synth_args.extend(["--physics".into(), p]);
    }
    if scene.camera_like {
        synth_args.push("--camera-like".into());
    }
    if scene.raw {
        synth_args.extend(["--raw".into(), "aruco-grid".into()]);
    }
    let synth_job = SynthArgs {
        preset: Some(scene.synth_preset().into()),
        scene: None,
        scale: plan.scale,
        out: Some(data.clone()),
        force: false,
        contact_sheet: true,
        physics: scene.physics,
        print_preset: None,
        raw: scene.raw.then_some(RawBoardArg::ArucoGrid),
        camera_like: scene.camera_like,
        raw_seed: 1,
        raw_size: None,
    };
    v.push(DemoStage {
        name: "synth".into(),
        argv: synth_args,
        job: StageJob::Synth(synth_job),
        expected_s: if scene.raw {
            plan.expected.synth_raw
        } else {
            plan.expected.synth
        },
    });
    // Raw footage is calibrated on its board into captures the method reads, at the captures' width.
    let method_data = if scene.raw {
        let imported = out.join("imported");
        let width = scene.desc.cameras.width;
        let mut job = ImportSessionArgs::new(data.join("raw"), &imported);
        job.width = Some(width);
        v.push(DemoStage {
            name: "import".into(),
            argv: vec![
                "import".into(),
                s(&data.join("raw")),
                "--out".into(),
                s(&imported),
                "--width".into(),
                width.to_string(),
            ],
            job: StageJob::Import(job),
            expected_s: plan.expected.import,
        });
        imported
    } else {
        data.clone()
    };
    let contents = Contents {
        data: method_data,
        scene: "background".into(),
        objects: scene
            .desc
            .bodies
            .iter()
            .map(|b| (b.name.clone(), [format!("{}_a", b.name), format!("{}_b", b.name)]))
            .collect(),
        videos: scene
            .desc
            .videos
            .iter()
            .map(|v| (v.name.clone(), v.bodies.iter().map(|b| b.name.clone()).collect()))
            .collect(),
        truth: Some(data.join("truth.json")),
    };
    v.extend(method_stages(plan, &contents, out));
    v
}

/// What the method runs on once the data exist: the data folder, the scene's capture, each object's two
/// captures (resting in two poses), each video with the bodies it shows, and the truth where there is one.
#[derive(Clone, Debug, PartialEq)]
pub struct Contents {
    pub data: PathBuf,
    pub scene: String,
    pub objects: Vec<(String, [String; 2])>,
    pub videos: Vec<(String, Vec<String>)>,
    pub truth: Option<PathBuf>,
}

/// The method's stages on `contents`, their arguments written out as a user would type them: the scene's
/// training, each object's two trainings and their merge, the bake, then each video's fit (and eval where
/// there is a truth), the report. Everything is written under `out` (runs/, merged/, scene.sdf, fits/).
pub(crate) fn method_stages(plan: &Plan, contents: &Contents, out: &Path) -> Vec<DemoStage> {
    let data = &contents.data;
    let runs = out.join("runs");
    let merged = |body: &str| out.join("merged").join(body);
    let grid = out.join("scene.sdf");
    let x = &plan.expected;
    let mut v = Vec::new();
    let mut add = |name: &str, expected_s: f64, argv: Vec<String>, job: StageJob| {
        v.push(DemoStage {
            name: name.to_string(),
            argv,
            job,
            expected_s,
        })
    };
    let mut train = vec![(contents.scene.clone(), "scene".to_string(), plan.scene_steps, x.scene)];
    for (_, captures) in &contents.objects {
        for capture in captures {
            train.push((capture.clone(), capture.clone(), plan.object_steps, x.object));
        }
    }
    for (capture, run, steps, expected) in train {
        let mut args: Vec<String> = vec![
            "train".into(),
            s(&data.join(&capture)),
            "--out".into(),
            s(&runs.join(&run)),
            "--iterations".into(),
            steps.to_string(),
        ];
        let mut job = TrainArgs::new(data.join(&capture), runs.join(&run));
        job.iterations = Some(steps);
        let config = if run == "scene" {
            plan.scene_config.map(|_| "train_scene.toml")
        } else {
            plan.object_config.map(|_| "train_object.toml")
        };
        if let Some(file) = config {
            args.extend(["--config".into(), s(&out.join(file))]);
            job.config = Some(out.join(file));
        }
        add(&format!("train {run}"), expected, args, StageJob::Train(job));
    }
    for (body, [a, b]) in &contents.objects {
        let mut args: Vec<String> = vec![
            "merge".into(),
            s(&runs.join(a)),
            s(&runs.join(b)),
            "--out".into(),
            s(&merged(body)),
            "--capture-a".into(),
            s(&data.join(a)),
            "--capture-b".into(),
            s(&data.join(b)),
        ];
        let mut job = MergeArgs::new(runs.join(a), runs.join(b), merged(body));
        job.capture_a = Some(data.join(a));
        job.capture_b = Some(data.join(b));
        if let Some(r) = plan.merge_field_res {
            args.extend(["--field-res".into(), r.to_string()]);
            job.field_res = r;
        }
        add(&format!("merge {body}"), x.merge, args, StageJob::Merge(job));
    }
    let mut bake = BakeArgs::new(runs.join("scene"), grid.clone());
    bake.res = Some(plan.bake_res);
    add(
        "bake",
        x.bake,
        vec![
            "bake".into(),
            s(&runs.join("scene")),
            "--out".into(),
            s(&grid),
            "--res".into(),
            plan.bake_res.to_string(),
        ],
        StageJob::Bake(bake),
    );
    for (video, bodies) in &contents.videos {
        let fit_dir = out.join("fits").join(video);
        let mut args: Vec<String> = vec![
            "fit".into(),
            s(&data.join(video)),
            "--scene".into(),
            s(&runs.join("scene")),
            "--scene-grid".into(),
            s(&grid),
        ];
        for body in bodies {
            args.extend(["--object".into(), format!("{body}={}", s(&merged(body)))]);
        }
        args.extend(["--init".into(), "auto".into(), "--out".into(), s(&fit_dir)]);
        let mut inputs = FitInputs::new(
            data.join(video),
            runs.join("scene"),
            bodies.iter().map(|b| (b.clone(), merged(b))),
        );
        inputs.scene_grid = Some(grid.clone());
        if let Some(n) = plan.frames {
            args.extend(["--frames".into(), n.to_string()]);
            inputs.frames = Some(n);
        }
        let mut config = None;
        if plan.fit_config.is_some() {
            args.extend(["--config".into(), s(&out.join("fit.toml"))]);
            config = Some(out.join("fit.toml"));
        }
        add(
            &format!("fit {video}"),
            x.fit_per_body * bodies.len() as f64,
            args,
            StageJob::Fit {
                inputs,
                config,
                out: fit_dir.clone(),
            },
        );
        if let Some(truth) = &contents.truth {
            add(
                &format!("eval {video}"),
                x.eval,
                vec![
                    "eval".into(),
                    s(&fit_dir),
                    "--truth".into(),
                    s(truth),
                    "--video".into(),
                    video.clone(),
                ],
                StageJob::Eval(EvalArgs::new(fit_dir.clone(), truth.clone(), Some(video.clone()))),
            );
        }
    }
    add(
        "report",
        x.eval,
        vec!["report".into(), s(out)],
        StageJob::Report(ReportArgs::new(out.to_path_buf())),
    );
    v
}

/// The stages `a` asks for, in order, and the folder they write to.
pub fn plan(a: &DemoArgs) -> Result<(Vec<DemoStage>, PathBuf)> {
    let out = out_of(a);
    Ok((stages(plan_of(a), &Scene::new(a)?, &out), out))
}

/// The folder the demo writes to: `--out`, else [`default_out`].
fn out_of(a: &DemoArgs) -> PathBuf {
    a.out.clone().unwrap_or_else(|| default_out(a))
}

fn plan_of(a: &DemoArgs) -> &'static Plan {
    match (a.quick, a.scale) {
        (true, _) => &QUICK,
        (false, ScaleArg::Small) => &FULL,
        (false, ScaleArg::Large) => &LARGE,
    }
}

/// Runs one stage of the demo. `redo`: its inputs or its command line changed since it last ran (or the
/// demo was asked to redo everything): it starts over instead of resuming what it left.
pub trait StageRunner {
    fn run_stage(&self, stage: &DemoStage, redo: bool, observer: &dyn Observer) -> Result<()>;
}

/// Runs each stage through this library.
pub struct Library;

impl StageRunner for Library {
    fn run_stage(&self, stage: &DemoStage, redo: bool, observer: &dyn Observer) -> Result<()> {
        match &stage.job {
            StageJob::Synth(a) => {
                // synth replaces its folder whole.
                let a = SynthArgs {
                    force: true,
                    ..a.clone()
                };
                crate::synth::run(&a, observer)
            }
            // import replaces its folder whole (the old one kept until the new one is complete).
            StageJob::Import(a) => {
                let a = ImportSessionArgs {
                    force: true,
                    ..a.clone()
                };
                crate::import_session::run(&a, observer).map(|_| ())
            }
            StageJob::Train(a) => {
                // Training resumes from its checkpoint when one is there, unless it must start over.
                let resume = !redo && a.out.join("checkpoint.safetensors").exists();
                let a = TrainArgs {
                    resume,
                    force: !resume,
                    ..a.clone()
                };
                crate::train::run(&a, observer)
            }
            StageJob::Merge(a) => crate::surfaces::merge(a, observer),
            StageJob::Bake(a) => crate::surfaces::bake(a, observer),
            StageJob::Fit { inputs, config, out } => {
                let config = match config {
                    Some(file) => crate::run_folder::config_over(&VideoFitConfig::default(), file)?,
                    None => VideoFitConfig::default(),
                };
                let resume = if redo { Resume::StartOver } else { Resume::Continue };
                let outcome = FitRun::open(inputs.clone(), config, out, resume)?.run(&Stage::ALL, observer)?;
                note(observer, &outcome.summary);
                Ok(())
            }
            StageJob::Eval(a) => crate::eval::run(a, observer).map(|_| ()),
            StageJob::Report(a) => crate::report_page::run(a, observer),
        }
    }
}

/// Runs the demo (each stage through `runner`: [`Library`] runs them in this process) and writes
/// `report.md`; its path.
pub fn run(a: &DemoArgs, runner: &dyn StageRunner, observer: &dyn Observer) -> Result<PathBuf> {
    let t0 = Instant::now();
    let plan = plan_of(a);
    let scene = Scene::new(a)?;
    let out = out_of(a);
    let all = stages(plan, &scene, &out);
    let title = format!(
        "demo{} of the {} scene",
        if a.quick { " --quick" } else { "" },
        scene.preset
    );
    let record = execute(&all, plan, &out, "demo.json", a.force, &title, runner, observer)?;
    let report = write_report(&out, plan, &scene, a.quick, &all, &record)?;
    note(
        observer,
        format!(
            "demo finished in {} (this run); report: {}",
            minutes(t0.elapsed().as_secs_f64()),
            report.display()
        ),
    );
    Ok(report)
}

/// Runs `all` in order into `out` (creating it and the plan's settings files), each through `runner`,
/// skipping the stages `out/<record_file>` says finished with the same command line (unless `force`),
/// and keeping that record as stages finish; the record. `title` opens the log.
#[allow(clippy::too_many_arguments)]
pub(crate) fn execute(
    all: &[DemoStage],
    plan: &Plan,
    out: &Path,
    record_file: &str,
    force: bool,
    title: &str,
    runner: &dyn StageRunner,
    observer: &dyn Observer,
) -> Result<Record> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let record_path = out.join(record_file);
    let mut record: Record = if force || !record_path.exists() {
        Record::default()
    } else {
        let text =
            std::fs::read_to_string(&record_path).with_context(|| format!("cannot read {}", record_path.display()))?;
        serde_json::from_str(&text).map_err(|e| {
            err!(
                Input,
                "{}: {e} (not a run record: give another --out, or --force)",
                record_path.display()
            )
        })?
    };
    if let Some(cfg) = plan.fit_config {
        pganeus_io::write_atomic(&out.join("fit.toml"), cfg.as_bytes())?;
    }
    if let Some(cfg) = plan.scene_config {
        pganeus_io::write_atomic(&out.join("train_scene.toml"), cfg.as_bytes())?;
    }
    if let Some(cfg) = plan.object_config {
        pganeus_io::write_atomic(&out.join("train_object.toml"), cfg.as_bytes())?;
    }
    let total_expected: f64 = all.iter().map(|s| s.expected_s).sum();
    // Expected seconds of the stages done or skipped, and of those run here (with the time they took).
    let (mut expected_done, mut expected_run, mut spent) = (0.0, 0.0, 0.0);
    note(
        observer,
        format!(
            "{title}: {} stages into {} (about {} on two cores)",
            all.len(),
            out.display(),
            minutes(total_expected)
        ),
    );
    // Once a stage runs, every later one runs too: its inputs changed.
    let mut upstream_ran = false;
    for (i, stage) in all.iter().enumerate() {
        let head = format!("[{}/{}] {}", i + 1, all.len(), stage.name);
        if !upstream_ran && record.done.get(&stage.name).is_some_and(|d| d.argv == stage.argv) {
            note(observer, format!("{head}: done before, skipped"));
            expected_done += stage.expected_s;
            continue;
        }
        // The time left, scaled by how this machine compares with the expected times so far (a minute of
        // the expected pace mixed in, so one quick stage does not halve the estimate).
        let pace = (spent + 60.0) / (expected_run + 60.0);
        note(
            observer,
            format!(
                "{head}: pganeus {} (ETA {})",
                stage.argv.join(" "),
                minutes((total_expected - expected_done) * pace)
            ),
        );
        let redo = force || upstream_ran || record.done.contains_key(&stage.name);
        upstream_ran = true;
        // What the later stages made came from this stage's old outputs: forget it, so that a stop further on
        // cannot leave them marked done.
        for later in &all[i + 1..] {
            record.done.remove(&later.name);
        }
        pganeus_io::write_atomic(&record_path, serde_json::to_string_pretty(&record)?.as_bytes())?;
        let t = Instant::now();
        runner
            .run_stage(stage, redo, observer)
            .with_context(|| format!("stage {:?} failed", stage.name))?;
        let seconds = t.elapsed().as_secs_f64();
        note(observer, format!("{head}: done in {seconds:.0} s"));
        spent += seconds;
        expected_run += stage.expected_s;
        expected_done += stage.expected_s;
        record.done.insert(
            stage.name.clone(),
            Done {
                argv: stage.argv.clone(),
                seconds: (seconds * 10.0).round() / 10.0,
            },
        );
        pganeus_io::write_atomic(&record_path, serde_json::to_string_pretty(&record)?.as_bytes())?;
    }
    Ok(record)
}

/// The flags a stage's command line gets for a rerun: training resumes from its checkpoint when one is there,
/// `fit` from its stage files, synth replaces its folder (merge, bake and eval always write anew). `redo`:
/// its inputs or its command line changed since (or `--force`): everything starts over.
pub fn resume_flags(stage: &DemoStage, redo: bool) -> Vec<String> {
    match &stage.job {
        StageJob::Train(a) => {
            if !redo && a.out.join("checkpoint.safetensors").exists() {
                vec!["--resume".into()]
            } else {
                vec!["--force".into()]
            }
        }
        StageJob::Synth(_) | StageJob::Import(_) => vec!["--force".into()],
        StageJob::Fit { .. } if redo => vec!["--force".into()],
        _ => vec![],
    }
}

fn minutes(s: f64) -> String {
    if s < 90.0 {
        format!("{s:.0} s")
    } else {
        format!("{:.1} min", s / 60.0)
    }
}

/// The raw footage's part of the report: the cameras `import` found and the masks the method computed,
/// against the truth.
fn raw_section(md: &mut String, out: &Path) -> Result<()> {
    let (imported, data) = (out.join("imported"), out.join("data"));
    let c = crate::session_truth::cameras(&imported, &data)?;
    writeln!(
        md,
        "## From raw footage\n\nThe cameras from the printed board against the truth: the lens's focal length \
         {:.2} % off, its principal point {:.2} px; {} cameras ({} photos and frames, the rest left out) \
         within {:.2} mm (mean {:.2}) and {:.3}° (mean {:.3}).\n",
        c.focal_percent,
        c.principal_px,
        c.cameras,
        c.photos,
        c.centre_mm[1],
        c.centre_mm[0],
        c.turn_deg[1],
        c.turn_deg[0]
    )?;
    let masks = crate::session_truth::masks(&imported, &out.join("runs"), &out.join("fits"), &data)?;
    writeln!(
        md,
        "The computed masks against the true silhouettes (the true mesh at its true pose through the photo's \
         true camera, with the imported image's intrinsics; video frames where the body covers at least {} \
         pixels):\n\n| capture | body | views | IoU mean | IoU worst (view) |\n\
         | --- | --- | --- | --- | --- |",
        crate::session_truth::VIDEO_MIN_PIXELS
    )?;
    for m in &masks {
        let worst = m.worst().map_or("–".into(), |(i, w)| format!("{w:.3} ({i})"));
        writeln!(
            md,
            "| {} | {} | {} | {:.3} | {worst} |",
            m.capture,
            m.body,
            m.views.len(),
            m.mean()
        )?;
    }
    writeln!(md)?;
    Ok(())
}

/// `report.md`: what ran, how long, and how the fits compare with the truth (from each fit's eval.json),
/// with the pictures each stage wrote.
fn write_report(
    out: &Path,
    plan: &Plan,
    scene: &Scene,
    quick: bool,
    all: &[DemoStage],
    record: &Record,
) -> Result<PathBuf> {
    let mut md = String::new();
    let bodies: Vec<&str> = scene.desc.bodies.iter().map(|b| b.name.as_str()).collect();
    writeln!(
        md,
        "# pganeus demo{}\n\nThe whole method on a synthetic scene (`synth --preset {} --scale {}{}`): \
         the scene trained for {} steps, each body ({}) in two poses for {} steps each, merged, the scene baked \
         at {}³, then `fit` from `--init auto` on each video{} and `eval` against the truth.\n",
        if quick { " --quick" } else { "" },
        scene.synth_preset(),
        plan.scale.name(),
        scene
            .physics_name()
            .map(|p| format!(" --physics {p}"))
            .unwrap_or_default()
            + if scene.camera_like { " --camera-like" } else { "" }
            + if scene.raw { " --raw aruco-grid" } else { "" },
        plan.scene_steps,
        bodies.join(", "),
        plan.object_steps,
        plan.bake_res,
        plan.frames
            .map(|n| format!(" (its first {n} frames)"))
            .unwrap_or_default()
    )?;
    if scene.raw {
        writeln!(
            md,
            "The method saw only the raw footage (`data/raw/`: photos and videos through a distorting lens, \
             with a printed board, per-photo exposure, noise, JPEG and motion blur): `import` found the lens and \
             every camera on the board, `train` computed the objects' masks, `fit` the videos' masks against \
             the trained scene. The truth scores them below.\n"
        )?;
    }
    if quick {
        writeln!(
            md,
            "`--quick` is a smoke run: short training and a light fit. Its figures show the chain works, not \
             the method's accuracy (run `pganeus demo` for that).\n"
        )?;
    }
    if matches!(scene.physics, Some(PhysicsArg::Rapier)) {
        writeln!(
            md,
            "Rapier made the videos' motion: the truth has no restitution or friction of the project's \
             model to compare with, so the motion is what counts.\n"
        )?;
    }
    writeln!(
        md,
        "The full report, with the fits' motion from a novel view and the charts, is \
         [report.html](report.html) (one file, offline); the charts are also in `plots/` as PNG and SVG.\n"
    )?;
    writeln!(md, "![inputs](data/contact_sheet.png)\n")?;
    writeln!(
        md,
        "## Fits against the truth\n\n| video | body | position mm (mean / worst) | rotation ° (mean / worst; up to the shape's symmetries) | \
         ADD-S mm (mean) | silhouette IoU (worst) | v0 error | restitution (true) and its range | friction (true) and its range | \
         poses reported: simulated / GA's at a weighed depth / GA's |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    )?;
    let f = |v: &Value| v.as_f64().map_or("–".to_string(), |x| format!("{x:.2}"));
    let mut mesh_lines = BTreeMap::new();
    let mut pair_lines = Vec::new();
    for video in &scene.desc.videos {
        let p = out.join("fits").join(&video.name).join("eval.json");
        let e = read_json(&p)?;
        let summary = e["summary"]
            .as_object()
            .filter(|m| !m.is_empty())
            .ok_or_else(|| err!(Input, "{}: no body in the summary", p.display()))?;
        for (body, sum) in summary {
            let par = &e["parameters"][body];
            // Which pose each frame reports (`fit`'s choice, in eval's rows).
            let reported = |source: &str| {
                e["frames"].as_array().map_or(0, |rows| {
                    rows.iter()
                        .filter(|r| r["fit_pose"] == source && r["body"].as_str().is_none_or(|b| b == body))
                        .count()
                })
            };
            let v0 = match par["v0_error_percent"].as_f64() {
                Some(pc) => format!("{pc:.2} %"),
                None => "at rest".into(),
            };
            writeln!(
                md,
                "| {} | {body} | {} / {} | {} | {} | {} | {v0} | {} ({}){} | {} ({}){} | {} / {} / {} |",
                video.name,
                f(&sum["position_mm"]["mean"]),
                f(&sum["position_mm"]["worst"]),
                report::run_page::rotation_text(sum),
                f(&sum["add_s_mm"]["mean"]),
                f(&sum["silhouette_iou"]["worst"]),
                f(&par["restitution"]),
                f(&par["restitution_true"]),
                report::run_page::range_text(par.get("restitution_range")),
                f(&par["friction"]),
                f(&par["friction_true"]),
                report::run_page::range_text(par.get("friction_range")),
                reported("simulated"),
                reported("ga_at_weighed_depth"),
                reported("ga"),
            )?;
        }
        for pair in e["pairs"].as_array().into_iter().flatten() {
            pair_lines.push(format!(
                "| {} | {} and {} | {} ({}){} | {} ({}){} |",
                video.name,
                pair["bodies"][0].as_str().unwrap_or("?"),
                pair["bodies"][1].as_str().unwrap_or("?"),
                f(&pair["restitution"]),
                f(&pair["restitution_true"]),
                report::run_page::range_text(pair.get("restitution_range")),
                f(&pair["friction"]),
                f(&pair["friction_true"]),
                report::run_page::range_text(pair.get("friction_range")),
            ));
        }
        for (body, m) in e["meshes"].as_object().into_iter().flatten() {
            mesh_lines.entry(body.clone()).or_insert_with(|| {
                format!(
                    "The merged {body} against the true mesh: Chamfer mean {} mm (95th percentile {} mm), volume IoU {}.",
                    f(&m["chamfer_mean_mm"]),
                    f(&m["chamfer_p95_mm"]),
                    f(&m["volume_iou"])
                )
            });
        }
    }
    writeln!(md)?;
    if !pair_lines.is_empty() {
        writeln!(
            md,
            "Between the bodies:\n\n| video | pair | restitution (true) and its range | friction (true) and its range |\n\
             | --- | --- | --- | --- |\n{}\n",
            pair_lines.join("\n")
        )?;
    }
    for l in mesh_lines.values() {
        writeln!(md, "{l}\n")?;
    }
    if scene.raw {
        raw_section(&mut md, out)?;
    }
    for video in &scene.desc.videos {
        let v = &video.name;
        writeln!(
            md,
            "## {v}\n\nInput (left) and the fit rendered in the reconstructed scene (right): \
             [animation](fits/{v}/animation.png), per-frame errors in `fits/{v}/eval.csv`.\n\n\
             ![{v}](fits/{v}/strip.png)\n"
        )?;
    }
    writeln!(md, "## Stages\n\n| stage | seconds | command |\n| --- | --- | --- |")?;
    for stage in all {
        if let Some(d) = record.done.get(&stage.name) {
            writeln!(
                md,
                "| {} | {:.0} | `pganeus {}` |",
                stage.name,
                d.seconds,
                d.argv.join(" ")
            )?;
        }
    }
    let path = out.join("report.md");
    pganeus_io::write_atomic(&path, md.as_bytes())?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    /// A stand-in for the stages: records each command line (with the flags a rerun adds), writes the eval
    /// files the report reads, and fails at `fail_at` (a stage's subcommand and first argument's end).
    struct Fake<'a> {
        calls: &'a RefCell<Vec<Vec<String>>>,
        fail_at: Option<&'a str>,
    }

    impl StageRunner for Fake<'_> {
        fn run_stage(&self, stage: &DemoStage, redo: bool, _: &dyn Observer) -> Result<()> {
            let mut argv = stage.argv.clone();
            argv.extend(resume_flags(stage, redo));
            self.calls.borrow_mut().push(argv.clone());
            let line = argv.join(" ");
            if self.fail_at.is_some_and(|f| line.starts_with(f)) {
                crate::error::fail!(Stage, "stopped in {line}");
            }
            if argv[0] == "eval" {
                let e = serde_json::json!({
                    "summary": {"toy": {"position_mm": {"mean": 1.0, "worst": 2.0},
                        "rotation_deg": {"mean": 0.5, "worst": 1.5}, "add_s_mm": {"mean": 0.7},
                        "silhouette_iou": {"worst": 0.95}}},
                    "parameters": {"toy": {"v0_error_percent": 3.0, "restitution": 0.48,
                        "restitution_true": 0.5, "friction": 0.26, "friction_true": 0.25}},
                    "meshes": {"toy": {"chamfer_mean_mm": 0.9, "chamfer_p95_mm": 2.0, "volume_iou": 0.93}},
                    "frames": [{"fit_pose": "simulated"}, {"fit_pose": "ga_at_weighed_depth"},
                        {"fit_pose": "ga"}, {"fit_pose": "simulated"}]
                });
                let dir = PathBuf::from(&argv[1]);
                std::fs::create_dir_all(&dir)?;
                std::fs::write(dir.join("eval.json"), e.to_string())?;
            }
            Ok(())
        }
    }

    fn fake<'a>(calls: &'a RefCell<Vec<Vec<String>>>, fail_at: Option<&'a str>) -> Fake<'a> {
        Fake { calls, fail_at }
    }

    fn args(out: &Path, force: bool) -> DemoArgs {
        DemoArgs {
            quick: true,
            out: Some(out.to_path_buf()),
            force,
            preset: "tabletop".into(),
            physics: None,
            scale: ScaleArg::Small,
            camera_like: false,
        }
    }

    fn names(calls: &RefCell<Vec<Vec<String>>>) -> Vec<String> {
        calls
            .borrow()
            .iter()
            .map(|c| format!("{} {}", c[0], c[1].rsplit('/').next().unwrap_or("")))
            .collect()
    }

    #[test]
    fn stages_run_once_resume_where_stopped_and_redo_what_follows_a_change() {
        let dir = testkit::scratch_dir("cli", "demo");
        let report_call = format!("report {}", dir.file_name().unwrap().to_string_lossy());
        // Stopped in the drop's fit: everything before it is recorded, the report is not written.
        let calls = RefCell::new(Vec::new());
        let drop_fit = format!("fit {}", dir.join("data").join("drop").display());
        let e = run(&args(&dir, false), &fake(&calls, Some(&drop_fit)), &crate::Quiet).unwrap_err();
        assert!(format!("{e:#}").contains("fit drop"), "{e:#}");
        assert_eq!(calls.borrow().len(), 9);
        assert!(!dir.join("report.md").exists());
        // Rerun: only the drop's fit (resuming its own stage files: no --force) and its eval run.
        let calls = RefCell::new(Vec::new());
        run(&args(&dir, false), &fake(&calls, None), &crate::Quiet).unwrap();
        assert_eq!(names(&calls), ["fit drop", "eval drop", report_call.as_str()]);
        assert!(!calls.borrow()[0].contains(&"--force".to_string()));
        let report = std::fs::read_to_string(dir.join("report.md")).unwrap();
        assert!(
            report.contains(
                "| slide | toy | 1.00 / 2.00 | 0.50 / 1.50 | 0.70 | 0.95 | 3.00 % | 0.48 (0.50) | 0.26 (0.25) | 2 / 1 / 1 |"
            ),
            "{report}"
        );
        assert!(
            report.contains("The merged toy against the true mesh: Chamfer mean 0.90 mm"),
            "{report}"
        );
        // Nothing left to do.
        let calls = RefCell::new(Vec::new());
        run(&args(&dir, false), &fake(&calls, None), &crate::Quiet).unwrap();
        assert!(calls.borrow().is_empty());
        // A stage whose command line changed (the object's training) runs again from scratch, and so does
        // every stage after it; those before it are kept.
        let mut record: Record =
            serde_json::from_str(&std::fs::read_to_string(dir.join("demo.json")).unwrap()).unwrap();
        record.done.get_mut("train toy_a").unwrap().argv.push("--old".into());
        std::fs::write(dir.join("demo.json"), serde_json::to_string(&record).unwrap()).unwrap();
        let calls = RefCell::new(Vec::new());
        run(&args(&dir, false), &fake(&calls, None), &crate::Quiet).unwrap();
        assert_eq!(calls.borrow().len(), 9, "{:?}", names(&calls));
        assert_eq!(names(&calls)[0], "train toy_a");
        for c in calls.borrow().iter().filter(|c| c[0] == "train" || c[0] == "fit") {
            assert!(c.contains(&"--force".to_string()), "{c:?}");
        }
        // Changed again and stopped in the drop's fit: the drop's fit and eval from the earlier runs are
        // stale, so the next run does them (and only them).
        let mut record: Record =
            serde_json::from_str(&std::fs::read_to_string(dir.join("demo.json")).unwrap()).unwrap();
        record.done.get_mut("merge toy").unwrap().argv.push("--old".into());
        std::fs::write(dir.join("demo.json"), serde_json::to_string(&record).unwrap()).unwrap();
        let calls = RefCell::new(Vec::new());
        assert!(run(&args(&dir, false), &fake(&calls, Some(&drop_fit)), &crate::Quiet).is_err());
        let calls = RefCell::new(Vec::new());
        run(&args(&dir, false), &fake(&calls, None), &crate::Quiet).unwrap();
        assert_eq!(names(&calls), ["fit drop", "eval drop", report_call.as_str()]);
        // --force redoes everything.
        let calls = RefCell::new(Vec::new());
        run(&args(&dir, true), &fake(&calls, None), &crate::Quiet).unwrap();
        assert_eq!(calls.borrow().len(), 11);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_two_body_preset_trains_merges_and_fits_every_body_and_reports_the_pair() {
        let dir = testkit::scratch_dir("cli", "demo_two_body");
        let mut a = args(&dir, false);
        a.preset = "two-body".into();
        a.physics = Some(PhysicsArg::Rapier);
        let scene = Scene::new(&a).unwrap();
        let all = stages(&QUICK, &scene, &dir);
        let names: Vec<&str> = all.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "synth",
                "train scene",
                "train toy_a",
                "train toy_b",
                "train block_a",
                "train block_b",
                "merge toy",
                "merge block",
                "bake",
                "fit collide",
                "eval collide",
                "report"
            ]
        );
        assert!(all[0].argv.ends_with(&["--physics".to_string(), "rapier".to_string()]));
        let fit = &all[9].argv;
        assert_eq!(fit.iter().filter(|x| *x == "--object").count(), 2, "{fit:?}");
        assert!(
            fit.iter().any(|x| x.starts_with("toy=") && x.ends_with("toy")),
            "{fit:?}"
        );
        assert!(
            fit.iter().any(|x| x.starts_with("block=") && x.ends_with("block")),
            "{fit:?}"
        );
        // Two bodies in the fit: expected twice a one-body fit's time.
        assert_eq!(all[9].expected_s, 2.0 * QUICK.expected.fit_per_body);
        assert_eq!(default_out(&a), PathBuf::from("out/demo-two-body-rapier-quick"));
        // Camera-like captures: synth makes them, the folder says so.
        a.camera_like = true;
        let camera = stages(&QUICK, &Scene::new(&a).unwrap(), &dir);
        assert!(
            camera[0].argv.iter().any(|x| x == "--camera-like"),
            "{:?}",
            camera[0].argv
        );
        assert!(matches!(&camera[0].job, StageJob::Synth(s) if s.camera_like));
        assert_eq!(default_out(&a), PathBuf::from("out/demo-two-body-rapier-camera-quick"));
        a.camera_like = false;
        // At 320×240 the objects train as long as the scene; the rest is the default's.
        let large = stages(&LARGE, &scene, &dir);
        assert!(large[0].argv.windows(2).any(|w| w == ["--scale", "large"]));
        for s in &large[1..6] {
            assert!(s.argv.windows(2).any(|w| w == ["--iterations", "1500"]), "{:?}", s.argv);
        }
        assert!(large[8].argv.windows(2).any(|w| w == ["--res", "256"]));
        let e = serde_json::json!({
            "summary": {
                "block": {"position_mm": {"mean": 0.4, "worst": 0.9}, "rotation_deg": {"mean": 0.1, "worst": 0.3}},
                "toy": {"position_mm": {"mean": 1.0, "worst": 2.0}, "rotation_deg": {"mean": 0.5, "worst": 1.5}}},
            "parameters": {"toy": {"v0_error_percent": 3.0}, "block": {}},
            "pairs": [{"bodies": ["block", "toy"], "restitution": 0.66, "restitution_true": 0.7,
                "friction": 0.2, "friction_true": 0.15}],
            "frames": [{"body": "toy", "fit_pose": "simulated"}, {"body": "block", "fit_pose": "ga"},
                {"body": "block", "fit_pose": "ga"}]
        });
        let fit_dir = dir.join("fits").join("collide");
        std::fs::create_dir_all(&fit_dir).unwrap();
        std::fs::write(fit_dir.join("eval.json"), e.to_string()).unwrap();
        let report =
            std::fs::read_to_string(write_report(&dir, &QUICK, &scene, true, &all, &Record::default()).unwrap())
                .unwrap();
        assert!(
            report.contains("`synth --preset two-body --scale small --physics rapier`"),
            "{report}"
        );
        assert!(
            report.contains("| collide | block | 0.40 / 0.90 | 0.10 / 0.30 | – | – | at rest |"),
            "{report}"
        );
        assert!(report.contains("| collide | toy | 1.00 / 2.00 |"), "{report}");
        assert!(
            report.contains("| 1 / 0 / 0 |") && report.contains("| 0 / 0 / 2 |"),
            "{report}"
        );
        assert!(
            report.contains("| collide | block and toy | 0.66 (0.70) | 0.20 (0.15) |"),
            "{report}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_raw_preset_imports_the_raw_footage_and_runs_the_method_on_what_import_wrote() {
        let dir = PathBuf::from("out/x");
        let mut a = args(&dir, false);
        a.preset = "raw".into();
        a.quick = false;
        let scene = Scene::new(&a).unwrap();
        let all = stages(&FULL, &scene, &dir);
        let names: Vec<&str> = all.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "synth",
                "import",
                "train scene",
                "train toy_a",
                "train toy_b",
                "merge toy",
                "bake",
                "fit slide",
                "eval slide",
                "fit drop",
                "eval drop",
                "report"
            ]
        );
        assert!(all[0].argv.windows(2).any(|w| w == ["--preset", "tabletop"]));
        assert!(all[0].argv.windows(2).any(|w| w == ["--raw", "aruco-grid"]));
        assert!(matches!(&all[0].job, StageJob::Synth(s) if s.raw == Some(RawBoardArg::ArucoGrid)));
        assert_eq!(
            all[1].argv,
            ["import", "out/x/data/raw", "--out", "out/x/imported", "--width", "160"]
        );
        // Every later stage reads what import wrote, and is scored against synth's truth.
        for s in &all[2..all.len() - 1] {
            let reads_data = s.argv.iter().any(|x| x.starts_with("out/x/data"));
            let scored = s.argv.iter().any(|x| x == "out/x/data/truth.json");
            assert!(!reads_data || scored, "{:?}", s.argv);
        }
        assert!(all[2].argv[1] == "out/x/imported/background", "{:?}", all[2].argv);
        assert_eq!(default_out(&a), PathBuf::from("out/demo-raw"));
        // A rerun replaces the imported folder whole.
        assert_eq!(resume_flags(&all[1], false), ["--force"]);
        // Raw footage is already camera-like: asking for both is a mistake, said as such.
        a.camera_like = true;
        let e = Scene::new(&a).err().unwrap();
        assert!(format!("{e}").contains("--camera-like with --preset raw"), "{e}");
    }
}
