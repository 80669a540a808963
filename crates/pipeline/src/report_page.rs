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

/// The colours of the paper's figures: truth, PA, GA, PGA, and the fit as reported.
const TRUTH: [u8; 3] = [30, 30, 30];
const PA: [u8; 3] = [31, 119, 180];
const GA: [u8; 3] = [44, 160, 44];
const PGA: [u8; 3] = [214, 39, 40];
const REPORTED: [u8; 3] = [255, 127, 14];
const GUESS: [u8; 3] = [148, 103, 189];
const LAUNCH: [u8; 3] = [140, 86, 75];

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

fn f64_at(v: &Value, key: &str) -> Option<f64> {
    v.get(key).and_then(Value::as_f64)
}

fn fmt(v: Option<f64>, digits: usize) -> String {
    v.filter(|x| x.is_finite())
        .map_or("–".into(), |x| format!("{x:.digits$}"))
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

fn training_charts(runs: &BTreeMap<String, Vec<Value>>) -> Vec<(String, Chart)> {
    let mut psnr = Chart::new("training: PSNR on the batch", "step", "PSNR (dB)");
    let mut loss = Chart::new("training: colour loss", "step", "log10 loss");
    for (name, lines) in runs {
        let pts = |f: &dyn Fn(&Value) -> Option<f64>| -> Vec<(f64, f64)> {
            lines.iter().filter_map(|l| Some((f64_at(l, "step")?, f(l)?))).collect()
        };
        psnr.series
            .push(Series::new(name.clone(), pts(&|l| f64_at(l, "psnr")), Mark::Line));
        loss.series.push(Series::new(
            name.clone(),
            pts(&|l| f64_at(&l["loss"], "rgb").filter(|x| *x > 0.0).map(f64::log10)),
            Mark::Line,
        ));
    }
    vec![("training_psnr".into(), psnr), ("training_loss".into(), loss)]
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
    charts.extend(loss_charts(name, &fit.join("log.jsonl")));
    plots.add(page, charts)?;
    Ok(())
}

/// `" in 0.48–0.55"`: the range `fit` wrote beside a contact value (`key`), or nothing.
pub fn range_text(range: Option<&Value>) -> String {
    match range.and_then(super::eval::range_pair) {
        Some([lo, hi]) => format!(" in {lo:.2}–{hi:.2}"),
        None => String::new(),
    }
}

/// A body's rotation error, mean / worst, from an eval summary: up to the shape's symmetries where it has
/// any, followed by the error as is where the fit chose a twin the shape cannot tell apart (a texture
/// might).
pub fn rotation_text(summary: &Value) -> String {
    let pair = |k: &str| {
        let s = &summary[k];
        (f64_at(s, "mean"), f64_at(s, "worst"))
    };
    let text = |(m, w): (Option<f64>, Option<f64>)| format!("{} / {}", fmt(m, 2), fmt(w, 2));
    let raw = pair("rotation_deg");
    let sym = pair("rotation_sym_deg");
    let symmetric = summary["symmetries"].as_u64().is_some_and(|k| k > 1) && sym.1.is_some();
    if !symmetric {
        return text(raw);
    }
    match (raw.1, sym.1) {
        (Some(r), Some(s)) if r - s > 0.01 => format!("{} (as is {})", text(sym), text(raw)),
        _ => text(sym),
    }
}

fn parameter_table(page: &mut Page, traj: &Trajectory, eval: Option<&Value>) {
    let mut rows = Vec::new();
    for b in &traj.bodies {
        let e = eval.map(|e| &e["parameters"][&b.name]).filter(|v| v.is_object());
        let with_truth = |fitted: Option<f64>, key: &str| {
            let t = e.and_then(|e| f64_at(e, &format!("{key}_true")));
            match t {
                Some(t) => format!("{} ({})", fmt(fitted, 3), fmt(Some(t), 3)),
                None => fmt(fitted, 3),
            }
        };
        let contact = b.extra.get("contact");
        let restitution = contact
            .and_then(|c| f64_at(c, "restitution"))
            .or(Some(traj.contact.restitution));
        let friction = contact
            .and_then(|c| f64_at(c, "friction"))
            .or(Some(traj.contact.friction));
        let v = b.initial.v;
        let w = b.initial.omega;
        let mut v0 = format!("[{:.3}, {:.3}, {:.3}]", v[0], v[1], v[2]);
        if let Some(t) = e.and_then(|e| e["v0_true"].as_array()) {
            let t: Vec<f64> = t.iter().filter_map(Value::as_f64).collect();
            if t.len() == 3 {
                v0 += &format!(" ([{:.3}, {:.3}, {:.3}])", t[0], t[1], t[2]);
            }
        }
        rows.push(vec![
            b.name.clone(),
            v0,
            fmt(e.and_then(|e| f64_at(e, "v0_error_percent")), 1),
            format!("[{:.2}, {:.2}, {:.2}]", w[0], w[1], w[2]),
            with_truth(restitution, "restitution") + &range_text(traj.contact.extra.get("restitution_range")),
            with_truth(friction, "friction") + &range_text(traj.contact.extra.get("friction_range")),
            fmt(b.extra.get("mass").and_then(Value::as_f64), 4),
        ]);
        // The launch fitted to the flight alone (`fit`'s flight test), beside the kept one.
        if let Some(f) = b.extra.get("flight") {
            let three = |k: &str| serde_json::from_value::<[f64; 3]>(f[k].clone()).ok();
            if let (Some(v), Some(w)) = (three("v0"), three("omega0")) {
                let verdict = if f["bent"].as_bool() == Some(true) {
                    "the kept launch misses it"
                } else {
                    "the kept launch stands against it"
                };
                rows.push(vec![
                    format!("{}: the flight alone ({} frames; {verdict})", b.name, f["frames"]),
                    format!("[{:.3}, {:.3}, {:.3}]", v[0], v[1], v[2]),
                    fmt(e.and_then(|e| f64_at(&e["flight"], "v0_error_percent")), 1),
                    format!("[{:.2}, {:.2}, {:.2}]", w[0], w[1], w[2]),
                    "—".into(),
                    "—".into(),
                    "—".into(),
                ]);
            }
        }
    }
    page.heading(3, "Fitted physics");
    page.table(
        &[
            "body",
            "v0 m/s (true)",
            "v0 error %",
            "ω0 rad/s",
            "restitution (true), the range the motion cannot tell apart",
            "friction (true), the range",
            "mass kg",
        ],
        &rows,
    );
}

fn error_table(page: &mut Page, e: &Value) {
    let mut rows = Vec::new();
    let mut add = |stage: &str, per_body: &Value| {
        for (body, s) in per_body.as_object().into_iter().flatten() {
            let pair = |k: &str| format!("{} / {}", fmt(f64_at(&s[k], "mean"), 2), fmt(f64_at(&s[k], "worst"), 2));
            rows.push(vec![
                stage.to_string(),
                body.clone(),
                pair("position_mm"),
                format!(
                    "{} / {}",
                    fmt(f64_at(&s["along_sight_mm"], "mean"), 2),
                    fmt(f64_at(&s["across_sight_mm"], "mean"), 2)
                ),
                rotation_text(s),
                fmt(f64_at(&s["add_s_mm"], "mean"), 2),
                pair("silhouette_iou"),
            ]);
        }
    };
    for (key, label) in [("pa", "PA"), ("ga", "GA"), ("pga", "PGA")] {
        add(label, &e["stages"][key]);
    }
    add("reported", &e["summary"]);
    if rows.is_empty() {
        return;
    }
    page.heading(3, "Against the truth");
    page.table(
        &[
            "stage",
            "body",
            "position mm (mean / worst)",
            "along (absolute) / across the line of sight mm (mean)",
            "rotation ° (mean / worst; up to the shape's symmetries)",
            "ADD-S mm (mean)",
            "silhouette IoU (mean / worst)",
        ],
        &rows,
    );
    page.note(
        "Reported: each frame's simulated pose, or GA's where the simulation misses the video. Along / across: \
         the position error's part along the camera's line of sight (depth, which one camera sees only through \
         the body's apparent size) and across it.",
    );
}

/// Per body and source, the path of the body: eval's (the true body's origin as each places it, beside the
/// truth) when there is one, else the trajectories' own.
fn paths(traj: &Trajectory, stages: &[(&str, [u8; 3], Option<Trajectory>)], eval: Option<&Value>) -> Vec<PathSet> {
    let mut out = Vec::new();
    for b in &traj.bodies {
        let mut set = PathSet {
            body: b.name.clone(),
            paths: Vec::new(),
        };
        let from_eval = |key: &str| eval_path(eval, key, &b.name);
        if let Some(t) = from_eval("truth") {
            set.paths.push(Track {
                label: "truth".into(),
                color: TRUTH,
                mark: Mark::Line,
                points: t,
            });
        }
        for (label, color, stage) in stages {
            let key = label.to_lowercase();
            let p = from_eval(&key).or_else(|| {
                let s = stage.as_ref()?.body(&b.name)?;
                Some(s.poses.iter().map(|p| p.t).collect())
            });
            if let Some(points) = p {
                set.paths.push(Track {
                    label: label.to_string(),
                    color: *color,
                    mark: Mark::Line,
                    points,
                });
            }
        }
        let reported = from_eval("fit").unwrap_or_else(|| b.poses.iter().map(|p| p.t).collect());
        set.paths.push(Track {
            label: "reported".into(),
            color: REPORTED,
            mark: Mark::Dashed,
            points: reported,
        });
        out.push(set);
    }
    out
}

/// Where `eval.json` put the true body's origin (`paths_m`) in the stage `key` for `body` (the fit's body frame
/// related to the truth's).
fn eval_path(eval: Option<&Value>, key: &str, body: &str) -> Option<Vec<[f64; 3]>> {
    let arr = eval?["paths_m"][key][body].as_array()?;
    Some(
        arr.iter()
            .filter_map(|p| {
                let v: Vec<f64> = p.as_array()?.iter().filter_map(Value::as_f64).collect();
                (v.len() == 3).then(|| [v[0], v[1], v[2]])
            })
            .collect(),
    )
}

/// One body's paths: truth, the stages, the reported motion.
struct PathSet {
    body: String,
    paths: Vec<Track>,
}

/// A path drawn in the charts.
struct Track {
    label: String,
    color: [u8; 3],
    mark: Mark,
    points: Vec<[f64; 3]>,
}

fn path_charts(
    name: &str,
    traj: &Trajectory,
    stages: &[(&str, [u8; 3], Option<Trajectory>)],
    eval: Option<&Value>,
) -> Vec<(String, Chart)> {
    let fps = if traj.fps > 0.0 { traj.fps } else { 30.0 };
    let mut out = Vec::new();
    for set in paths(traj, stages, eval) {
        let mut top = Chart::new(format!("{}: top view", set.body), "x (m)", "y (m)");
        top.equal_axes = true;
        let mut height = Chart::new(format!("{}: height", set.body), "time (s)", "z (m)");
        for t in &set.paths {
            let top_view = t.points.iter().map(|v| (v[0], v[1])).collect();
            top.series
                .push(Series::new(t.label.clone(), top_view, t.mark).colored(t.color));
            let over_time = t
                .points
                .iter()
                .enumerate()
                .map(|(k, v)| (k as f64 / fps, v[2]))
                .collect();
            height
                .series
                .push(Series::new(t.label.clone(), over_time, t.mark).colored(t.color));
        }
        out.push((format!("{name}_{}_top_view", set.body), top));
        out.push((format!("{name}_{}_height", set.body), height));
    }
    out
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

/// A stage file's own per-frame rows.
fn own_rows(stage: &Option<Trajectory>) -> Option<&Value> {
    stage.as_ref().and_then(|t| t.extra.get("frames"))
}

/// The per-frame image terms (`iou`, `psnr_window`) of PA, GA and PGA, each measured the same way (the
/// object's window of the render against the video).
fn frame_charts(name: &str, traj: &Trajectory, stages: &[(&str, [u8; 3], Option<Trajectory>)]) -> Vec<(String, Chart)> {
    let rows = |v: Option<&Value>| -> Vec<Value> { v.and_then(Value::as_array).cloned().unwrap_or_default() };
    let final_stage = |key: &str| traj.extra.get("stages").and_then(|s| s.get(key));
    // GA's rows as the fit measured them at the end, else from its own stage file.
    let sources: Vec<(&str, [u8; 3], Vec<Value>)> = vec![
        ("PA", PA, rows(own_rows(&stages[0].2))),
        ("GA", GA, rows(final_stage("ga").or_else(|| own_rows(&stages[1].2)))),
        ("PGA", PGA, rows(final_stage("simulated"))),
    ];
    let mut iou = Chart::new("silhouette IoU per frame", "frame", "IoU");
    let mut psnr = Chart::new("PSNR per frame (object window)", "frame", "PSNR (dB)");
    for (label, color, rows) in &sources {
        let pts = |key: &str| -> Vec<(f64, f64)> {
            rows.iter()
                .enumerate()
                .filter(|(_, r)| r.get("seen").and_then(Value::as_bool) != Some(false))
                .filter_map(|(k, r)| Some((f64_at(r, "frame").unwrap_or(k as f64), f64_at(r, key)?)))
                .collect()
        };
        iou.series
            .push(Series::new(*label, pts("iou"), Mark::Line).colored(*color));
        psnr.series
            .push(Series::new(*label, pts("psnr_window"), Mark::Line).colored(*color));
    }
    vec![(format!("{name}_iou"), iou), (format!("{name}_psnr"), psnr)]
}

/// Every stage's loss from the fit's log: the first pose's iterations per frame, PA's iterations over its
/// growing windows, GA's loss per frame, and each PGA start's final loss.
fn loss_charts(name: &str, log: &Path) -> Vec<(String, Chart)> {
    let lines = log_lines(log);
    let stage = |s: &'static str| lines.iter().filter(move |l| l["stage"] == s);
    let lg = |l: &Value| f64_at(l, "loss").filter(|x| *x > 0.0).map(f64::log10);
    let mut first = Chart::new("first pose: image loss", "iteration", "log10 loss");
    let mut by_frame: BTreeMap<i64, Vec<(f64, f64)>> = BTreeMap::new();
    for l in stage("first_pose") {
        if let (Some(k), Some(i), Some(y)) = (l["frame"].as_i64(), f64_at(l, "iteration"), lg(l)) {
            by_frame.entry(k).or_default().push((i, y));
        }
    }
    for (k, pts) in by_frame {
        first.series.push(Series::new(format!("frame {k}"), pts, Mark::Line));
    }
    let pa: Vec<(f64, f64)> = stage("pa")
        .filter_map(lg)
        .enumerate()
        .map(|(i, y)| (i as f64, y))
        .collect();
    let pa = Chart::new("PA: image loss (windows in turn)", "iteration", "log10 loss")
        .with(Series::new("PA", pa, Mark::Line).colored(PA));
    let ga: Vec<(f64, f64)> = stage("ga")
        .filter_map(|l| Some((f64_at(l, "frame")?, lg(l)?)))
        .collect();
    let pga: Vec<(f64, f64)> = stage("pga")
        .filter(|l| l.get("start").is_some())
        .filter_map(lg)
        .enumerate()
        .map(|(i, y)| (i as f64, y))
        .collect();
    let ga = Chart::new("GA per frame, PGA per start: final loss", "frame / start", "log10 loss")
        .with(Series::new("GA (frame)", ga, Mark::Points).colored(GA))
        .with(Series::new("PGA (start)", pga, Mark::Points).colored(PGA));
    vec![
        (format!("{name}_loss_first_pose"), first),
        (format!("{name}_loss_pa"), pa),
        (format!("{name}_loss_ga_pga"), ga),
    ]
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

    #[test]
    fn a_rotation_is_shown_up_to_symmetry_and_as_is_where_they_differ() {
        let raw = json!({"mean": 89.7, "worst": 90.67});
        let sym = json!({"mean": 1.2, "worst": 2.0});
        // No symmetry (or an eval from before symmetries were counted): the angle as is.
        assert_eq!(rotation_text(&json!({"rotation_deg": raw})), "89.70 / 90.67");
        assert_eq!(
            rotation_text(&json!({"rotation_deg": raw, "rotation_sym_deg": sym, "symmetries": 1})),
            "89.70 / 90.67"
        );
        assert_eq!(
            rotation_text(&json!({"rotation_deg": raw, "rotation_sym_deg": sym, "symmetries": 8})),
            "1.20 / 2.00 (as is 89.70 / 90.67)"
        );
        // The fit kept the shape's own orientation: one figure.
        assert_eq!(
            rotation_text(&json!({"rotation_deg": sym, "rotation_sym_deg": sym, "symmetries": 8})),
            "1.20 / 2.00"
        );
    }

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
