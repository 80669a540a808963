//! `pganeus report`: one self-contained HTML page for a run's folder. It gathers what the stages left —
//! contact sheets, training logs, the fits' stage files, logs and `eval.json` — and adds what a reader needs
//! to judge them: turntables of the object meshes, each fit's motion from a camera the video never had,
//! charts of the paths (top view, height), of the per-frame IoU and PSNR of PGA against its ablations (the
//! paper's Fig. 6 and 10) and of every stage's loss. Charts are also written as PNG and SVG to `plots/`.

use crate::cameras::world_cameras;
use crate::error::{err, fail, Context};
use crate::Result;
use crate::{note, Observer};
use geom::{Camera, Intrinsics, Pose, TriMesh, Vec3};
use pganeus_io::{Image, Trajectory};
use report::run_page::{
    error_table, eval_path, f64_at, fmt, frame_charts, loss_charts, parameter_table, path_charts, simulation_chart,
    training_charts, GA, GUESS, LAUNCH, PA, PGA, TRUTH,
};
use report::{face_towards, turntable, Chart, Mark, Page, Paint, Raster, Series};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus report out/demo
  pganeus report fits/slide --out slide.html")
)]
pub struct ReportArgs {
    /// A demo's folder, a folder of fit folders (directly or under `fits/`), or one fit folder.
    pub dir: PathBuf,
    /// The page to write (default: DIR/report.html). Its charts also go to `plots/` beside it, as PNG and SVG.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: Option<PathBuf>,
    /// Width of each fit's novel-view animation, pixels.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 320))]
    pub view_width: u32,
}

impl ReportArgs {
    /// The page of `dir`, written to `dir/report.html`.
    pub fn new(dir: PathBuf) -> ReportArgs {
        ReportArgs {
            dir,
            out: None,
            view_width: 320,
        }
    }
}

/// A JSON file, or None when it is not there; an unreadable one is an error naming it.
fn read_value(p: &Path) -> Result<Option<Value>> {
    match std::fs::read_to_string(p) {
        Ok(s) => Ok(Some(
            serde_json::from_str(&s).with_context(|| format!("{}: not valid JSON", p.display()))?,
        )),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(err!(Input, "{}: {e}", p.display())),
    }
}

/// A path a stage recorded, found as given (absolute, or from the working folder) or under one of `bases`.
fn locate(recorded: &Path, bases: &[&Path]) -> Option<PathBuf> {
    if recorded.exists() {
        return Some(recorded.to_path_buf());
    }
    bases.iter().map(|b| b.join(recorded)).find(|p| p.exists())
}

/// The fit folders of `dir`: itself, its children, or the children of `dir/fits`.
fn find_fits(dir: &Path) -> Vec<PathBuf> {
    if dir.join("trajectory.json").is_file() {
        return vec![dir.to_path_buf()];
    }
    let mut out = Vec::new();
    for parent in [dir.to_path_buf(), dir.join("fits")] {
        let Ok(entries) = std::fs::read_dir(&parent) else {
            continue;
        };
        for e in entries.flatten() {
            if e.path().join("trajectory.json").is_file() {
                out.push(e.path());
            }
        }
    }
    out.sort();
    out
}

/// Charts on the page and in `plots/` as PNG and SVG.
struct Plots {
    dir: PathBuf,
    written: usize,
}

impl Plots {
    /// Draws the charts that have data, writes each to `plots/NAME.{png,svg}`, and puts them on the page.
    fn add(&mut self, page: &mut Page, charts: Vec<(String, Chart)>) -> Result<()> {
        let mut svgs = Vec::new();
        for (name, chart) in charts {
            if chart.is_empty() {
                continue;
            }
            let (w, h) = (480, 320);
            let svg = chart.svg(w, h).map_err(|e| err!(Stage, "{e}"))?;
            let png = chart.png(w, h).map_err(|e| err!(Stage, "{e}"))?;
            std::fs::create_dir_all(&self.dir).with_context(|| format!("{}", self.dir.display()))?;
            pganeus_io::write_atomic(&self.dir.join(format!("{name}.svg")), svg.as_bytes())?;
            pganeus_io::write_png(&self.dir.join(format!("{name}.png")), &png)?;
            self.written += 1;
            svgs.push(svg);
        }
        if !svgs.is_empty() {
            page.charts(&svgs);
        }
        Ok(())
    }
}

/// The JSON lines of a log (lines that do not parse are skipped: a log cut by a kill ends mid-line).
fn log_lines(p: &Path) -> Vec<Value> {
    std::fs::read_to_string(p)
        .map(|s| s.lines().filter_map(|l| serde_json::from_str(l).ok()).collect())
        .unwrap_or_default()
}

pub fn run(a: &ReportArgs, observer: &dyn Observer) -> Result<()> {
    if !a.dir.is_dir() {
        fail!(Input, "{}: not a folder", a.dir.display());
    }
    if a.view_width < 16 {
        fail!(Settings, "--view-width {}: at least 16 pixels", a.view_width);
    }
    let out = a.out.clone().unwrap_or_else(|| a.dir.join("report.html"));
    let plots_dir = out.parent().unwrap_or(Path::new(".")).join("plots");
    let fits = find_fits(&a.dir);
    let sheets: Vec<PathBuf> = ["data/contact_sheet.png", "contact_sheet.png"]
        .iter()
        .map(|p| a.dir.join(p))
        .filter(|p| p.is_file())
        .collect();
    let runs = training_runs(&a.dir);
    if fits.is_empty() && sheets.is_empty() && runs.is_empty() {
        fail!(
            Input,
            "{}: nothing to report: no fit folder (trajectory.json), training run (runs/*/log.jsonl) or contact sheet",
            a.dir.display()
        );
    }
    let mut page = Page::new(&format!("pganeus report: {}", a.dir.display()));
    page.heading(1, "pganeus report");
    page.note(&format!(
        "{}: {} fit(s), {} training run(s). Written by pganeus {}.",
        a.dir.display(),
        fits.len(),
        runs.len(),
        env!("CARGO_PKG_VERSION")
    ));
    let mut plots = Plots {
        dir: plots_dir,
        written: 0,
    };

    if !sheets.is_empty() {
        page.heading(2, "Inputs");
        for s in &sheets {
            let bytes = std::fs::read(s).with_context(|| format!("{}", s.display()))?;
            page.png(&bytes, "the captures: a few frames of each", 1);
        }
    }

    if !runs.is_empty() || !fits.is_empty() {
        page.heading(2, "Reconstruction");
    }
    if !runs.is_empty() {
        plots.add(&mut page, training_charts(&runs))?;
    }
    meshes(&mut page, &fits)?;

    for fit in &fits {
        let name = fit
            .file_name()
            .map_or("fit".into(), |n| n.to_string_lossy().into_owned());
        fit_section(&mut page, &mut plots, fit, &name, a).with_context(|| format!("the fit in {}", fit.display()))?;
    }

    if let Some(d) = read_value(&a.dir.join("demo.json"))? {
        if let Some(done) = d["done"].as_object() {
            page.heading(2, "Stages");
            let rows: Vec<Vec<String>> = done
                .iter()
                .map(|(k, v)| {
                    let argv: Vec<&str> = v["argv"]
                        .as_array()
                        .map(|a| a.iter().filter_map(Value::as_str).collect())
                        .unwrap_or_default();
                    vec![
                        k.clone(),
                        fmt(f64_at(v, "seconds"), 0),
                        format!("pganeus {}", argv.join(" ")),
                    ]
                })
                .collect();
            page.table(&["stage", "seconds", "command"], &rows);
        }
    }

    let images = page.image_count();
    pganeus_io::write_atomic(&out, page.finish().as_bytes())?;
    note(
        observer,
        format!(
            "wrote {} ({images} pictures, {} charts also in {})",
            out.display(),
            plots.written,
            plots.dir.display()
        ),
    );
    Ok(())
}

/// `runs/*/log.jsonl` with training records, by run name.
fn training_runs(dir: &Path) -> BTreeMap<String, Vec<Value>> {
    let mut out = BTreeMap::new();
    let Ok(entries) = std::fs::read_dir(dir.join("runs")) else {
        return out;
    };
    for e in entries.flatten() {
        let lines: Vec<Value> = log_lines(&e.path().join("log.jsonl"))
            .into_iter()
            .filter(|l| l.get("step").is_some())
            .collect();
        if !lines.is_empty() {
            out.insert(e.file_name().to_string_lossy().into_owned(), lines);
        }
    }
    out
}

/// Each object mesh the fits used, once: a turntable strip and its scores against the truth.
fn meshes(page: &mut Page, fits: &[PathBuf]) -> Result<()> {
    let mut seen = std::collections::BTreeSet::new();
    for fit in fits {
        let bases: Vec<&Path> = fit.ancestors().skip(1).collect();
        let Some(t) = read_value(&fit.join("trajectory.json"))? else {
            continue;
        };
        let eval = read_value(&fit.join("eval.json"))?;
        for b in t["bodies"].as_array().into_iter().flatten() {
            let Some(mesh) = b["object"]["mesh"].as_str() else {
                continue;
            };
            let source = b["object"]["source"].as_str().unwrap_or(mesh).to_string();
            // The same object named from two working folders is one object.
            let key = locate(Path::new(&source), &bases)
                .and_then(|p| p.canonicalize().ok())
                .unwrap_or_else(|| fit.join(mesh));
            if !seen.insert(key) {
                continue;
            }
            let path = fit.join(mesh);
            let m = pganeus_io::read_mesh(&path)?;
            let strip = turntable(&m, 6, 160, [0.86, 0.55, 0.3]);
            let name = b["name"].as_str().unwrap_or("body");
            let mut caption = format!("{name}: the object from {source} ({} triangles)", m.faces.len());
            if let Some(s) = eval.as_ref().map(|e| &e["meshes"][name]).filter(|s| s.is_object()) {
                caption += &format!(
                    "; against the true mesh: Chamfer mean {} mm, 95th percentile {} mm, volume IoU {}",
                    fmt(f64_at(s, "chamfer_mean_mm"), 3),
                    fmt(f64_at(s, "chamfer_p95_mm"), 3),
                    fmt(f64_at(s, "volume_iou"), 3)
                );
            }
            page.png(&pganeus_io::encode_png(&strip), &caption, 1);
        }
    }
    Ok(())
}

/// A stage's trajectory file in the fit folder, when the stage ran.
fn stage_file(fit: &Path, stage: &str) -> Result<Option<Trajectory>> {
    let p = fit.join(format!("{stage}.json"));
    if !p.is_file() {
        return Ok(None);
    }
    Ok(Some(pganeus_io::read_trajectory(&p)?))
}

fn fit_section(page: &mut Page, plots: &mut Plots, fit: &Path, name: &str, a: &ReportArgs) -> Result<()> {
    let traj = pganeus_io::read_trajectory(&fit.join("trajectory.json"))?;
    let eval = read_value(&fit.join("eval.json"))?;
    let stages: Vec<(&str, [u8; 3], Option<Trajectory>)> = vec![
        ("PA", PA, stage_file(fit, "pa")?),
        ("GA", GA, stage_file(fit, "ga")?),
        ("PGA", PGA, stage_file(fit, "pga")?),
    ];
    page.heading(2, &format!("Fit: {name}"));
    page.note(&format!(
        "{}: video {:?}, {} frames at {} fps, {} bod{}.",
        fit.display(),
        traj.capture,
        traj.bodies.first().map_or(0, |b| b.poses.len()),
        traj.fps,
        traj.bodies.len(),
        if traj.bodies.len() == 1 { "y" } else { "ies" }
    ));
    parameter_table(page, &traj, eval.as_ref());
    if let Some(e) = &eval {
        error_table(page, e);
    }

    page.heading(3, "Motion");
    let anim = fit.join("animation.png");
    if anim.is_file() {
        let bytes = std::fs::read(&anim).with_context(|| format!("{}", anim.display()))?;
        page.png(
            &bytes,
            "the input video (left) and the fit rendered in the reconstructed scene (right)",
            2,
        );
    }
    match novel_view(fit, &traj, eval.as_ref(), a.view_width) {
        Ok(frames) => {
            let p = fit.join("novel_view.png");
            pganeus_io::write_apng(&p, &frames, traj.fps)?;
            let truth = if eval.is_some() {
                ", the truth as a green ghost"
            } else {
                ""
            };
            page.png(
                &std::fs::read(&p)?,
                &format!("the fit from a novel view (60° round from the video's camera){truth}"),
                1,
            );
        }
        Err(e) => page.note(&format!("No novel view: {e:#}.")),
    }

    page.heading(3, "Charts");
    let mut charts = path_charts(name, &traj, &stages, eval.as_ref());
    charts.extend(schedule_charts(name, &traj, fit, eval.as_ref())?);
    charts.extend(frame_charts(name, &traj, &stages));
    if let Some((key, chart, note)) = simulation_chart(name, &traj, eval.as_ref()) {
        page.note(&note);
        charts.push((key, chart));
    }
    charts.extend(loss_charts(name, &log_lines(&fit.join("log.jsonl"))));
    plots.add(page, charts)?;
    Ok(())
}

/// Several bodies (the paper's Fig. 8): how far each body is from where it started, frame by frame, in the
/// schedule's initial guess (`pga_guess.json`), after its launch fit (`pga_launch.json`), in PGA's final
/// simulation and in the truth. When a body starts moving, and how far it goes, shows the collision's time
/// and its exchange of momentum.
fn schedule_charts(name: &str, traj: &Trajectory, fit: &Path, eval: Option<&Value>) -> Result<Vec<(String, Chart)>> {
    if traj.bodies.len() < 2 {
        return Ok(Vec::new());
    }
    // The kept round's PGA: the second (`pga.json`) unless the log says its simulation explained the images
    // worse than the first's (`pga_tracked.json`).
    let first_kept = log_lines(&fit.join("log.jsonl"))
        .iter()
        .any(|l| matches!((f64_at(l, "image_loss_tracked"), f64_at(l, "image_loss")), (Some(a), Some(b)) if b > a));
    let last = if first_kept { "pga_tracked" } else { "pga" };
    let files = [
        ("initial guess", GUESS, "pga_guess", stage_file(fit, "pga_guess")?),
        (
            "after the launch fit",
            LAUNCH,
            "pga_launch",
            stage_file(fit, "pga_launch")?,
        ),
        ("final (PGA)", PGA, last, stage_file(fit, last)?),
    ];
    if files[0].3.is_none() {
        return Ok(Vec::new());
    }
    let fps = if traj.fps > 0.0 { traj.fps } else { 30.0 };
    let mut out = Vec::new();
    for b in &traj.bodies {
        let from_eval = |key: &str| eval_path(eval, key, &b.name);
        let mut chart = Chart::new(
            format!("{}: distance from its start (Fig. 8)", b.name),
            "time (s)",
            "distance (m)",
        );
        let mut add = |label: &str, color: [u8; 3], mark: Mark, points: Vec<[f64; 3]>| {
            let Some(p0) = points.first().copied() else {
                return;
            };
            let d = points
                .iter()
                .enumerate()
                .map(|(k, p)| {
                    let e = [p[0] - p0[0], p[1] - p0[1], p[2] - p0[2]];
                    (k as f64 / fps, (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt())
                })
                .collect();
            chart.series.push(Series::new(label, d, mark).colored(color));
        };
        if let Some(t) = from_eval("truth") {
            add("truth", TRUTH, Mark::Line, t);
        }
        for (label, color, key, stage) in &files {
            let points = from_eval(key).or_else(|| {
                let s = stage.as_ref()?.body(&b.name)?;
                Some(s.poses.iter().map(|p| p.t).collect())
            });
            if let Some(points) = points {
                add(label, *color, Mark::Dashed, points);
            }
        }
        out.push((format!("{name}_{}_schedule", b.name), chart));
    }
    Ok(out)
}

/// The fit drawn from a camera turned 60° about the vertical round the motion's centre: the scene's
/// extracted surface, the fitted bodies, and the truth as a ghost when `eval` names it.
fn novel_view(fit: &Path, traj: &Trajectory, eval: Option<&Value>, width: u32) -> Result<Vec<Image>> {
    let bases: Vec<&Path> = fit.ancestors().skip(1).collect();
    let video = traj
        .extra
        .get("video")
        .and_then(Value::as_str)
        .ok_or_else(|| err!(Stage, "trajectory.json does not name its video"))?;
    let video = locate(Path::new(video), &bases).ok_or_else(|| err!(Stage, "the video {video:?} is not found"))?;
    let capture = pganeus_io::open_capture(&video)?;
    let cam = *world_cameras(&capture)?
        .first()
        .ok_or_else(|| err!(Input, "{}: no camera", video.display()))?;
    // The scene run the fit rendered against (config.toml), through its extracted surface.
    let config: toml::Value = toml::from_str(
        &std::fs::read_to_string(fit.join("config.toml")).with_context(|| format!("{}/config.toml", fit.display()))?,
    )
    .with_context(|| format!("{}/config.toml", fit.display()))?;
    let scene = config
        .get("inputs")
        .and_then(|i| i.get("scene"))
        .and_then(|s| s.as_str())
        .ok_or_else(|| err!(Stage, "config.toml has no inputs.scene"))?;
    let scene = locate(Path::new(scene), &bases).ok_or_else(|| err!(Stage, "the scene {scene:?} is not found"))?;
    let scene_mesh = if scene.is_dir() {
        scene.join("preview.ply")
    } else {
        scene
    };
    let mut scene_mesh = pganeus_io::read_mesh(&scene_mesh)?;
    face_towards(&mut scene_mesh, cam.center());

    let mut bodies: Vec<(TriMesh, Vec<Pose<f64>>)> = Vec::new();
    for b in &traj.bodies {
        let mesh = b
            .extra
            .get("object")
            .and_then(|o| o["mesh"].as_str())
            .ok_or_else(|| err!(Stage, "body {:?} names no object mesh", b.name))?;
        let m = pganeus_io::read_mesh(&fit.join(mesh))?;
        bodies.push((m, b.poses.iter().map(pganeus_io::Pose::to_geom).collect()));
    }
    let ghosts = truth_ghosts(traj, eval, &bases).unwrap_or_else(|e| {
        tracing::warn!("no truth in the novel view: {e:#}");
        Vec::new()
    });

    // Turn the video's eye 60° about the vertical through the motion's centre.
    let positions: Vec<Vec3<f64>> = bodies.iter().flat_map(|(_, p)| p.iter().map(|p| p.t)).collect();
    let centre = positions
        .iter()
        .fold(Vec3::zero(), |s, &p| s + p)
        .scale(1.0 / positions.len().max(1) as f64);
    let d = cam.center() - centre;
    let (s, c) = 60f64.to_radians().sin_cos();
    let eye = centre + Vec3::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z);
    let scale = width as f64 / cam.width as f64;
    let height = ((cam.height as f64 * scale).round() as u32).max(1);
    // Zoom in (never out) until the motion, with a body's size around it, spans about 60 % of the width.
    let reach = positions.iter().map(|&p| (p - centre).norm()).fold(0.0, f64::max)
        + bodies.iter().map(|(m, _)| mesh_radius(m)).fold(0.0, f64::max);
    let fit_focal = 0.3 * width as f64 * d.norm() / reach.max(1e-6);
    let zoom = (fit_focal / (cam.k.fx * scale)).max(1.0);
    let k = Intrinsics {
        fx: cam.k.fx * scale * zoom,
        fy: cam.k.fy * scale * zoom,
        cx: 0.5 * width as f64,
        cy: 0.5 * height as f64,
        skew: 0.0,
    };
    let view = Camera::look_at(eye, centre, Vec3::new(0.0, 0.0, 1.0), k, width, height);
    let n = bodies.iter().map(|(_, p)| p.len()).max().unwrap_or(0);
    if n == 0 {
        fail!(Stage, "no frames");
    }
    let mut frames = Vec::with_capacity(n);
    for f in 0..n {
        let mut r = Raster::new(view, [0.82, 0.86, 0.92]);
        r.draw(
            &scene_mesh,
            &Pose::identity(),
            Paint::solid([0.75, 0.75, 0.72]).front_faces(),
        );
        for (m, poses) in &bodies {
            if let Some(p) = poses.get(f) {
                r.draw(m, p, Paint::solid([0.9, 0.5, 0.2]));
            }
        }
        for (m, poses) in &ghosts {
            if let Some(p) = poses.get(f) {
                r.draw(m, p, Paint::ghost([0.1, 0.8, 0.2], 0.45));
            }
        }
        frames.push(r.image());
    }
    Ok(frames)
}

/// The largest distance of a mesh's vertices from its body origin.
fn mesh_radius(m: &TriMesh) -> f64 {
    m.vertices.iter().map(|v| Vec3::cst(*v).norm()).fold(0.0, f64::max)
}

/// The true bodies (mesh in the truth's body frame, poses of the video) that `eval` scored the fit against.
fn truth_ghosts(traj: &Trajectory, eval: Option<&Value>, bases: &[&Path]) -> Result<Vec<(TriMesh, Vec<Pose<f64>>)>> {
    let Some(e) = eval else { return Ok(Vec::new()) };
    let path = e["truth"]
        .as_str()
        .ok_or_else(|| err!(Stage, "eval.json names no truth"))?;
    let path = locate(Path::new(path), bases).ok_or_else(|| err!(Input, "{path}: not found"))?;
    let truth = pganeus_io::read_truth(&path)?;
    let name = e["video"].as_str().unwrap_or(&traj.capture);
    let video = truth
        .video(name)
        .ok_or_else(|| err!(Input, "{}: no video {name:?}", path.display()))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for b in &traj.bodies {
        let (Some(tb), Some(tv)) = (truth.body(&b.name), video.body(&b.name)) else {
            continue;
        };
        let m = pganeus_io::read_mesh(&dir.join(&tb.mesh))?;
        out.push((m, tv.poses.iter().map(pganeus_io::Pose::to_geom).collect()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// A trajectory file of bodies `a` and `b`, each moving along x by `step[body]` a frame.
    fn file(d: &Path, name: &str, step: [f64; 2]) -> Trajectory {
        let bodies: Vec<Value> = ["a", "b"]
            .iter()
            .zip(step)
            .map(|(n, s)| {
                let poses: Vec<Value> = (0..4)
                    .map(|k| json!({"t": [s * k as f64, 0.0, 0.0], "q": [1.0, 0.0, 0.0, 0.0]}))
                    .collect();
                json!({"name": n, "initial": {"t": [0.0, 0.0, 0.0], "q": [1.0, 0.0, 0.0, 0.0],
                    "v": [0.0, 0.0, 0.0], "omega": [0.0, 0.0, 0.0]}, "poses": poses})
            })
            .collect();
        let t = json!({"capture": "collide", "fps": 30.0, "bodies": bodies,
            "contact": {"restitution": 0.5, "friction": 0.5, "model": "pganeus"}});
        std::fs::write(d.join(name), t.to_string()).unwrap();
        serde_json::from_value(t).unwrap()
    }

    #[test]
    fn several_bodies_get_the_schedule_chart_of_the_kept_round() {
        let d = testkit::scratch_dir("cli", "schedule_charts");
        let traj = file(&d, "trajectory.json", [0.01, 0.02]);
        file(&d, "pga.json", [0.01, 0.02]);
        // Without the schedule's files: no chart.
        assert!(schedule_charts("f", &traj, &d, None).unwrap().is_empty());
        file(&d, "pga_guess.json", [0.03, 0.0]);
        file(&d, "pga_launch.json", [0.02, 0.01]);
        file(&d, "pga_tracked.json", [0.05, 0.05]);
        // The first round kept (its simulation explained the images better): its PGA is the final one.
        std::fs::write(
            d.join("log.jsonl"),
            "{\"stage\":\"pga\",\"image_loss_tracked\":1.0,\"image_loss\":2.0}\n",
        )
        .unwrap();
        let charts = schedule_charts("f", &traj, &d, None).unwrap();
        assert_eq!(charts.len(), 2);
        let (name, chart) = &charts[1];
        assert_eq!(name, "f_b_schedule");
        let labels: Vec<&str> = chart.series.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(labels, ["initial guess", "after the launch fit", "final (PGA)"]);
        // Body b's distance from its start in the last frame: 0 in the guess, 3 × 0.05 in the kept round's.
        let last = |i: usize| chart.series[i].points.last().unwrap().1;
        assert!(
            last(0).abs() < 1e-12 && (last(2) - 0.15).abs() < 1e-12,
            "{:?}",
            chart.series
        );
        // One body: none.
        let one: Trajectory = serde_json::from_value(json!({"capture": "c", "fps": 30.0,
            "bodies": [serde_json::to_value(&traj.bodies[0]).unwrap()],
            "contact": {"restitution": 0.5, "friction": 0.5, "model": "pganeus"}}))
        .unwrap();
        assert!(schedule_charts("f", &one, &d, None).unwrap().is_empty());
        let _ = std::fs::remove_dir_all(&d);
    }
}
