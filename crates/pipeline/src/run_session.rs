//! `pganeus run`: the whole method on a data folder `import` wrote (its `session.json`): train the scene,
//! train each object in its two poses (their masks computed from the photos where the captures have none),
//! merge them, bake the scene, fit each video from `--init auto` (its masks computed against the scene
//! where it has none), `eval` where a truth is given, and the report. The same stages, command lines and
//! resuming as `demo` (which is `synth` + these stages on its own scene).

use std::path::PathBuf;

use crate::demo::{execute, method_stages, Contents, DemoStage, Plan, StageRunner, FULL, QUICK};
use crate::error::fail;
use crate::import_session::{read_session, Session};
use crate::{note, Observer, Result};

/// `pganeus run` arguments.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus import session --out data && pganeus run data --out out/session
  pganeus run data --out out/session --truth data/truth.json
  pganeus run data --out out/session-quick --quick")
)]
pub struct RunArgs {
    /// The data folder `pganeus import` wrote (its session.json names the scene, objects and videos).
    pub data: PathBuf,
    /// The folder for everything the method writes: runs/, merged/, scene.sdf, fits/, report.html, run.json.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// A truth (truth.json, as `synth` writes it): each fit is scored against it.
    #[cfg_attr(feature = "clap", arg(long))]
    pub truth: Option<PathBuf>,
    /// Short training and a light fit on the first 8 frames (a smoke run, as `demo --quick`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub quick: bool,
    /// Redo every stage, even those that finished.
    #[cfg_attr(feature = "clap", arg(long))]
    pub force: bool,
}

impl RunArgs {
    /// The flags' defaults for `data` run into `out`.
    pub fn new(data: impl Into<PathBuf>, out: impl Into<PathBuf>) -> Self {
        RunArgs {
            data: data.into(),
            out: out.into(),
            truth: None,
            quick: false,
            force: false,
        }
    }
}

/// What the method runs on, from the session's file: the bodies each video shows are those `video_bodies`
/// names for it, else every object of the session.
pub fn contents(a: &RunArgs, session: &Session) -> Contents {
    let objects: Vec<String> = session.objects.iter().map(|o| o.name.clone()).collect();
    Contents {
        data: a.data.clone(),
        scene: session.scene.clone(),
        objects: session
            .objects
            .iter()
            .map(|o| (o.name.clone(), o.captures.clone()))
            .collect(),
        videos: session
            .videos
            .iter()
            .map(|v| (v.clone(), session.video_bodies.get(v).unwrap_or(&objects).clone()))
            .collect(),
        truth: a.truth.clone(),
    }
}

/// The stages `a` asks for, in order.
pub fn plan(a: &RunArgs) -> Result<Vec<DemoStage>> {
    let session = read_session(&a.data)?;
    for capture in std::iter::once(&session.scene)
        .chain(session.objects.iter().flat_map(|o| o.captures.iter()))
        .chain(&session.videos)
    {
        if !a.data.join(capture).join("cameras_sphere.npz").exists() {
            fail!(
                Input,
                "{}: the session names the capture {capture:?}, which is not there (import the session again)",
                a.data.join(capture).display()
            );
        }
    }
    for (video, bodies) in &session.video_bodies {
        if !session.videos.contains(video) {
            fail!(
                Input,
                "{}: video_bodies names {video:?}, not a video of the session",
                a.data.join(crate::import_session::SESSION_FILE).display()
            );
        }
        if let Some(b) = bodies.iter().find(|b| !session.objects.iter().any(|o| &o.name == *b)) {
            fail!(
                Input,
                "{}: video_bodies gives {video:?} the body {b:?}, not an object of the session",
                a.data.join(crate::import_session::SESSION_FILE).display()
            );
        }
    }
    if let Some(t) = &a.truth {
        if !t.is_file() {
            fail!(Input, "--truth {}: no such file", t.display());
        }
    }
    Ok(stages_for(a, &session))
}

/// The stages of `a` on `session` (without checking the data).
pub fn stages_for(a: &RunArgs, session: &Session) -> Vec<DemoStage> {
    method_stages(sizes(a), &contents(a, session), &a.out)
}

/// The demo's sizes `a` asks for: `--quick`'s or the default's.
fn sizes(a: &RunArgs) -> &'static Plan {
    if a.quick {
        &QUICK
    } else {
        &FULL
    }
}

/// `pganeus run`: the path of the report page.
pub fn run(a: &RunArgs, runner: &dyn StageRunner, observer: &dyn Observer) -> Result<PathBuf> {
    let t0 = std::time::Instant::now();
    let all = plan(a)?;
    let title = format!("run{} of {}", if a.quick { " --quick" } else { "" }, a.data.display());
    execute(&all, sizes(a), &a.out, "run.json", a.force, &title, runner, observer)?;
    let report = a.out.join("report.html");
    note(
        observer,
        format!(
            "finished in {:.1} min (this run); report: {}",
            t0.elapsed().as_secs_f64() / 60.0,
            report.display()
        ),
    );
    Ok(report)
}
