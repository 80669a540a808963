//! `eval`: a fit scored against the truth of a synthetic or evaluation scene.
//! The fit's body frame (its object's centre of mass, the axes of its
//! reference capture) is related to the truth's through `object.reference`
//! (docs/formats.md): `X = T_capture⁻¹ ∘ P_reference` takes fit-body points to
//! truth-body points, so the fit's pose of the true body is `F ∘ X⁻¹`.

use crate::cameras::world_cameras;
use crate::error::{err, fail, Context};
use crate::Result;
use crate::{note, Observer, Task};
use geom::{coverage_iou, silhouette, Camera, Pose, TriMesh, Vec3};
use mesh::SurfacePoints;
use pganeus_io::{Trajectory, Truth, TruthBody};
use report::run_page::range_pair;
use serde_json::{json, Value};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus eval fits/slide --truth data/tabletop/truth.json
  pganeus eval fits/drop --truth data/tabletop/truth.json --out fits/drop/eval.json --csv fits/drop/eval.csv")
)]
pub struct EvalArgs {
    /// A fit folder (`trajectory.json` and, when present, the stages' `pa.json`, `ga.json`, `pga.json`), or a
    /// trajectory file.
    pub fit: PathBuf,
    /// The scene's `truth.json` (its video with the fit's capture name is the reference).
    #[cfg_attr(feature = "clap", arg(long))]
    pub truth: PathBuf,
    /// The truth's video to compare with (default: the trajectory's `capture`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub video: Option<String>,
    /// Surface points per body for ADD and ADD-S.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 2000))]
    pub samples: usize,
    /// Where to write the scores (default: `eval.json` in the fit folder, or beside the trajectory file).
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: Option<PathBuf>,
    /// Per-frame rows as CSV (default: `--out` with the extension `.csv`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub csv: Option<PathBuf>,
}

impl EvalArgs {
    /// `fit` scored against `truth` (its video `video`, or the fit's own), written beside the fit.
    pub fn new(fit: PathBuf, truth: PathBuf, video: Option<String>) -> EvalArgs {
        EvalArgs {
            fit,
            truth,
            video,
            samples: 2000,
            out: None,
            csv: None,
        }
    }
}

/// What one body of the fit is measured with.
struct BodyRef<'a> {
    truth: &'a TruthBody,
    /// Fit body frame → truth body frame.
    to_truth: Pose<f64>,
    /// Whether the fit said where its body frame sat (else the frames are taken to be the same).
    related: bool,
    mesh: TriMesh,
    points: SurfacePoints,
}

fn num(v: f64, scale: f64, digits: i32) -> Value {
    let k = 10f64.powi(digits);
    json!((v * scale * k).round() / k)
}

/// The fit body frame → truth body frame map of one body entry (`extra.object.reference`).
fn relation(entry: &pganeus_io::VideoBody, truth: &TruthBody, file: &Path) -> Result<(Pose<f64>, bool)> {
    let Some(r) = entry.extra.get("object").and_then(|o| o.get("reference")) else {
        return Ok((Pose::identity(), false));
    };
    let capture = r["capture"].as_str().ok_or_else(|| {
        err!(
            Input,
            "{}: {}: object.reference.capture is not a string",
            file.display(),
            entry.name
        )
    })?;
    let pose: pganeus_io::Pose = serde_json::from_value(r["pose"].clone())
        .with_context(|| format!("{}: {}: object.reference.pose", file.display(), entry.name))?;
    let stat = truth
        .static_captures
        .iter()
        .find(|s| s.capture == capture)
        .ok_or_else(|| {
            err!(
                Input,
                "{}: body {:?} is expressed in capture {capture:?}, which the truth does not list for it",
                file.display(),
                entry.name
            )
        })?;
    Ok((stat.pose.to_geom().inverse().compose(&pose.to_geom()), true))
}

/// What [`score_poses`] finds: per-frame rows, a summary per body, and per body the path of the true
/// body's origin as the fit places it and as the truth does (for plots).
struct Scores {
    rows: Vec<Value>,
    summary: Value,
    fitted_path: serde_json::Map<String, Value>,
    true_path: serde_json::Map<String, Value>,
}

/// Per-frame scores of `fit`'s poses of every body against the truth's video.
fn score_poses(fit: &Trajectory, video: &Trajectory, refs: &[BodyRef], camera: Option<&Camera<f64>>) -> Scores {
    let mut rows = Vec::new();
    let mut summary = serde_json::Map::new();
    let (mut fitted_path, mut true_path) = (serde_json::Map::new(), serde_json::Map::new());
    for (entry, r) in fit.bodies.iter().zip(refs) {
        let Some(truth) = video.body(&entry.name) else {
            continue;
        };
        let from_truth = r.to_truth.inverse();
        let n = entry.poses.len().min(truth.poses.len());
        let (mut pos, mut rot, mut rot_sym, mut add, mut adds, mut ious) =
            (vec![], vec![], vec![], vec![], vec![], vec![]);
        let (mut along, mut across) = (vec![], vec![]);
        let (mut fitted, mut true_) = (vec![], vec![]);
        // The fitted physics' own poses: how many frames report them, their distance from GA's and the truth.
        let (mut simulated, mut sim_from_ga, mut sim_pos, mut sim_rot) = (0usize, vec![], vec![], vec![]);
        let eye = camera.map(|c| c.center());
        for k in 0..n {
            let est = entry.poses[k].to_geom().compose(&from_truth);
            let tru = truth.poses[k].to_geom();
            let micrometres = |v: Vec3<f64>| v.to_array().map(|x| (x * 1e6).round() / 1e6);
            fitted.push(json!(micrometres(est.t)));
            true_.push(json!(micrometres(tru.t)));
            let e = r.points.errors(&est, &tru);
            let iou = camera.map(|c| coverage_iou(&silhouette(c, &r.mesh, &est), &silhouette(c, &r.mesh, &tru)));
            let mut row = json!({"body": entry.name, "frame": k,
                "position_mm": num(e.position, 1e3, 3), "rotation_deg": num(e.rotation.to_degrees(), 1.0, 3),
                "rotation_sym_deg": num(e.rotation_up_to_symmetry.to_degrees(), 1.0, 3),
                "add_mm": num(e.add, 1e3, 3), "add_s_mm": num(e.add_s, 1e3, 3)});
            if let Some(i) = iou {
                row["silhouette_iou"] = num(i, 1.0, 4);
                ious.push(i);
            }
            if let Some(eye) = eye {
                let (a, x) = sight_split(eye, &est, &tru);
                row["along_sight_mm"] = num(a, 1e3, 3);
                row["across_sight_mm"] = num(x, 1e3, 3);
                along.push(a.abs() * 1e3);
                across.push(x * 1e3);
            }
            // The fit's own image scores, where it wrote them (per body with several bodies).
            let own = entry.extra.get("frames").or_else(|| fit.extra.get("frames"));
            if let Some(f) = own.and_then(|f| f.get(k)) {
                for key in ["psnr", "iou", "pose", "sim_from_ga_mm", "sim_from_ga_deg"] {
                    if let Some(v) = f.get(key) {
                        row[format!("fit_{key}")] = v.clone();
                    }
                }
                simulated += usize::from(f["pose"] == "simulated");
                if let Some(d) = f["sim_from_ga_mm"].as_f64() {
                    sim_from_ga.push(d);
                }
                // Where the fitted physics draws the body, against the truth.
                if let Ok(sim) = serde_json::from_value::<pganeus_io::Pose>(f["simulated"].clone()) {
                    let e = r.points.errors(&sim.to_geom().compose(&from_truth), &tru);
                    row["sim_position_mm"] = num(e.position, 1e3, 3);
                    row["sim_rotation_deg"] = num(e.rotation_up_to_symmetry.to_degrees(), 1.0, 3);
                    sim_pos.push(e.position * 1e3);
                    sim_rot.push(e.rotation_up_to_symmetry.to_degrees());
                }
            }
            rows.push(row);
            pos.push(e.position * 1e3);
            rot.push(e.rotation.to_degrees());
            rot_sym.push(e.rotation_up_to_symmetry.to_degrees());
            add.push(e.add * 1e3);
            adds.push(e.add_s * 1e3);
        }
        let stat = |v: &[f64]| {
            let worst = v.iter().cloned().fold(0.0, f64::max);
            let at = v.iter().position(|&x| x == worst).unwrap_or(0);
            json!({"mean": num(v.iter().sum::<f64>() / v.len().max(1) as f64, 1.0, 3), "worst": num(worst, 1.0, 3), "worst_frame": at})
        };
        let mut s = json!({"frames": n, "position_mm": stat(&pos), "rotation_deg": stat(&rot),
            "rotation_sym_deg": stat(&rot_sym), "symmetries": r.points.symmetries(),
            "add_mm": stat(&add), "add_s_mm": stat(&adds)});
        if !sim_pos.is_empty() {
            s["simulated_frames"] = json!(simulated);
            s["sim_position_mm"] = stat(&sim_pos);
            s["sim_rotation_deg"] = stat(&sim_rot);
        }
        if !sim_from_ga.is_empty() {
            s["sim_from_ga_mm"] = stat(&sim_from_ga);
        }
        if !along.is_empty() {
            s["along_sight_mm"] = stat(&along);
            s["across_sight_mm"] = stat(&across);
        }
        if !ious.is_empty() {
            let worst = ious.iter().cloned().fold(1.0, f64::min);
            s["silhouette_iou"] =
                json!({"mean": num(ious.iter().sum::<f64>() / ious.len() as f64, 1.0, 4), "worst": num(worst, 1.0, 4)});
        }
        summary.insert(entry.name.clone(), s);
        fitted_path.insert(entry.name.clone(), json!(fitted));
        true_path.insert(entry.name.clone(), json!(true_));
    }
    Scores {
        rows,
        summary: Value::Object(summary),
        fitted_path,
        true_path,
    }
}

/// The fitted origin's error split along the camera's line of sight through the true origin (signed:
/// positive where the fit is farther than the truth) and across it, m. One camera places a body across its
/// line of sight to a fraction of a pixel but along it only through the body's apparent size, so the two
/// parts say different things about a fit.
fn sight_split(eye: Vec3<f64>, est: &Pose<f64>, tru: &Pose<f64>) -> (f64, f64) {
    let d = est.t - tru.t;
    let to = tru.t - eye;
    let n = to.norm();
    if n < 1e-12 {
        return (0.0, d.norm());
    }
    let s = to * (1.0 / n);
    let a = d.dot(s);
    (a, (d - s * a).norm())
}

/// A true launch speed below this (m/s) is a body at rest: its v0 error has no percentage.
const AT_REST_M_S: f64 = 1e-6;

/// Launch and contact errors of the final trajectory (contact values only where the truth's model is the
/// project's own).
fn parameter_errors(fit: &Trajectory, video: &Trajectory, refs: &[BodyRef]) -> Value {
    let mut out = serde_json::Map::new();
    for (entry, r) in fit.bodies.iter().zip(refs) {
        let Some(truth) = video.body(&entry.name) else {
            continue;
        };
        // The velocity of the true body's origin: v + ω × (its offset from the fit's origin, in world axes).
        let offset = entry.poses[0].to_geom().q.rotate(r.to_truth.inverse().t);
        let tv = Vec3::cst(truth.initial.v);
        let launch = |v: [f64; 3], omega: [f64; 3]| {
            let omega = Vec3::cst(omega);
            let v = Vec3::cst(v) + omega.cross(offset);
            let dv = (v - tv).norm();
            // A share of a true speed only where there is one: a body at rest (the block a toy hits) has none.
            let percent = if tv.norm() > AT_REST_M_S {
                num(dv / tv.norm(), 100.0, 2)
            } else {
                Value::Null
            };
            let omega_error = num((omega - Vec3::cst(truth.initial.omega)).norm(), 1.0, 3);
            (v, num(dv, 1.0, 4), percent, omega_error)
        };
        let (v, dv, percent, omega_error) = launch(entry.initial.v, entry.initial.omega);
        let mut e = json!({
            "v0": v.to_array(), "v0_true": truth.initial.v,
            "v0_error_m_s": dv,
            "v0_error_percent": percent,
            "omega0_error_rad_s": omega_error,
        });
        // The launch fitted to the flight alone (`fit`'s flight test), beside the kept one.
        if let Some(f) = entry.extra.get("flight") {
            let three = |k: &str| serde_json::from_value::<[f64; 3]>(f[k].clone()).ok();
            if let (Some(fv), Some(fw)) = (three("v0"), three("omega0")) {
                let (v, dv, percent, omega_error) = launch(fv, fw);
                e["flight"] = json!({"frames": f["frames"], "bent": f["bent"], "held_kept": f.get("held_kept"),
                    "before": f["before"], "v0": v.to_array(),
                    "v0_error_m_s": dv, "v0_error_percent": percent, "omega0_error_rad_s": omega_error});
            }
        }
        if video.contact.model == "pganeus" {
            e["restitution"] = json!(fit.contact.restitution);
            e["restitution_true"] = json!(video.contact.restitution);
            e["restitution_error"] = num((fit.contact.restitution - video.contact.restitution).abs(), 1.0, 4);
            e["friction"] = json!(fit.contact.friction);
            e["friction_true"] = json!(video.contact.friction);
            e["friction_error"] = num((fit.contact.friction - video.contact.friction).abs(), 1.0, 4);
            add_ranges(&mut e, &fit.contact.extra);
        }
        out.insert(entry.name.clone(), e);
    }
    Value::Object(out)
}

/// The stage files of a fit folder that are scored beside the result (several bodies: the first round's PGA,
/// and the kept round's start and its state after the launches).
const STAGE_FILES: [&str; 6] = ["pa", "ga", "pga", "pga_tracked", "pga_guess", "pga_launch"];

/// Each pair's contact values against the truth's, matched by the bodies' names (where the truth's model is
/// the project's own and both files name pairs).
fn pair_errors(fit: &Trajectory, video: &Trajectory) -> Option<Value> {
    if video.contact.model != "pganeus" {
        return None;
    }
    let ours = scene_file::contact_pairs(fit);
    let out: Vec<Value> = scene_file::contact_pairs(video)
        .into_iter()
        .filter_map(|(names, truth)| {
            let (_, c) = ours.iter().find(|(n, _)| *n == names)?;
            let (fe, fmu, e, mu) = (c.restitution, c.friction, truth.restitution, truth.friction);
            let mut row = json!({"bodies": names, "restitution": fe, "restitution_true": e,
                "restitution_error": num((fe - e).abs(), 1.0, 4), "friction": fmu, "friction_true": mu,
                "friction_error": num((fmu - mu).abs(), 1.0, 4)});
            if let Some(entry) = pair_entry(fit, &names) {
                add_ranges(&mut row, entry);
            }
            Some(row)
        })
        .collect();
    (!out.is_empty()).then(|| json!(out))
}

/// The `contact.pairs` entry of a trajectory file for the bodies `names` (sorted).
fn pair_entry<'a>(t: &'a Trajectory, names: &[String; 2]) -> Option<&'a serde_json::Map<String, Value>> {
    t.contact.extra.get("pairs")?.as_array()?.iter().find_map(|p| {
        let p = p.as_object()?;
        let b = p.get("bodies")?.as_array()?;
        let mut n = [b.first()?.as_str()?.to_string(), b.get(1)?.as_str()?.to_string()];
        n.sort();
        (n == *names).then_some(p)
    })
}

/// The fit's `restitution_range` and `friction_range` (`fit`'s value ranges) into an error row that holds the
/// true values, with whether each truth lies inside.
fn add_ranges(row: &mut Value, fitted: &serde_json::Map<String, Value>) {
    for value in ["restitution", "friction"] {
        let key = format!("{value}_range");
        let range = fitted.get(&key).and_then(range_pair);
        if let (Some([lo, hi]), Some(truth)) = (range, row[format!("{value}_true")].as_f64()) {
            row[key] = json!([lo, hi]);
            row[format!("{value}_true_in_range")] = json!((lo..=hi).contains(&truth));
        }
    }
}

/// `restitution 0.7 (true 0.7) [...], friction ...` of an error row.
fn values_text(row: &Value) -> String {
    format!(
        "restitution {} (true {}){}, friction {} (true {}){}",
        row["restitution"],
        row["restitution_true"],
        range_text(row, "restitution"),
        row["friction"],
        row["friction_true"],
        range_text(row, "friction")
    )
}

/// `"; the motion cannot tell 0.31–0.99 apart, the truth inside"` for an error row with ranges, else nothing.
fn range_text(row: &Value, value: &str) -> String {
    match (
        range_pair(&row[format!("{value}_range")]),
        row[format!("{value}_true_in_range")].as_bool(),
    ) {
        (Some([lo, hi]), Some(inside)) => format!(
            " [the motion cannot tell {lo:.3}–{hi:.3} apart: the truth {}]",
            if inside { "inside" } else { "outside" }
        ),
        _ => String::new(),
    }
}

/// A fit's scores against a truth: `eval.json`'s document (per frame and per body: position, rotation,
/// ADD(-S), silhouette IoU; the launch's and the contact values' errors; each stage file's poses; the object's
/// mesh against the true one).
#[derive(Clone, Debug, PartialEq)]
pub struct EvalReport {
    pub scores: Value,
}

impl EvalReport {
    /// The summary a user reads, a line per body, pair and stage.
    pub fn lines(&self) -> Vec<String> {
        summary_lines(&self.scores)
    }

    /// Body `body`'s summary (`position_mm`, `rotation_deg`, ...), if the fit has it.
    pub fn body(&self, body: &str) -> Option<&Value> {
        self.scores["summary"].get(body)
    }

    /// The fitted and true launch and contact values of body `body` and their errors.
    pub fn parameters(&self, body: &str) -> Option<&Value> {
        self.scores["parameters"].get(body)
    }
}

/// `fit` (a fit folder or a trajectory file) scored against `truth` (its video `video`, or the one with the
/// fit's capture name), `samples` surface points per body for ADD and ADD-S.
pub fn score(
    fit: &Path,
    truth: &Path,
    video: Option<&str>,
    samples: usize,
    observer: &dyn Observer,
) -> Result<EvalReport> {
    let a = ScoreInputs {
        fit,
        truth,
        video,
        samples,
    };
    let (dir, file) = if a.fit.is_dir() {
        (a.fit.to_path_buf(), a.fit.join("trajectory.json"))
    } else {
        (
            a.fit.parent().unwrap_or(Path::new(".")).to_path_buf(),
            a.fit.to_path_buf(),
        )
    };
    let fit = pganeus_io::read_trajectory(&file)?;
    let truth: Truth = pganeus_io::read_truth(a.truth)?;
    let truth_dir = a.truth.parent().unwrap_or(Path::new("."));
    let name = a.video.map(str::to_string).unwrap_or_else(|| fit.capture.clone());
    let video = truth.video(&name).ok_or_else(|| {
        err!(
            Input,
            "{}: no video {name:?} (it has {:?}); name it with --video",
            a.truth.display(),
            truth.videos.iter().map(|v| &v.capture).collect::<Vec<_>>()
        )
    })?;
    if fit.bodies.is_empty() {
        fail!(Input, "{}: no bodies", file.display());
    }
    let mut refs = Vec::new();
    for entry in &fit.bodies {
        let tb = truth.body(&entry.name).ok_or_else(|| {
            err!(
                Input,
                "{}: body {:?} is not in {}",
                file.display(),
                entry.name,
                a.truth.display()
            )
        })?;
        if video.body(&entry.name).is_none() {
            fail!(
                Input,
                "{}: body {:?} does not move in video {name:?}",
                a.truth.display(),
                entry.name
            );
        }
        let (to_truth, related) = relation(entry, tb, &file)?;
        let mesh_path = truth_dir.join(&tb.mesh);
        let mesh = pganeus_io::read_mesh(&mesh_path).with_context(|| format!("the true mesh of {:?}", tb.name))?;
        let points = SurfacePoints::new(&mesh, a.samples, 7);
        refs.push(BodyRef {
            truth: tb,
            to_truth,
            related,
            mesh,
            points,
        });
    }
    // The video's camera, for the silhouettes of the true mesh at the fitted and the true poses.
    let camera = match pganeus_io::open_capture(&truth_dir.join(&name)) {
        Ok(c) => world_cameras(&c)?.first().copied(),
        Err(e) => {
            tracing::warn!("no silhouette IoU: {e}");
            None
        }
    };
    // Steps: the reported poses, each stage file, each body's mesh.
    let pb = Task::start(observer, "eval", (1 + STAGE_FILES.len() + fit.bodies.len()) as u64);
    let scores = score_poses(&fit, video, &refs, camera.as_ref());
    pb.inc(1);
    // Where each fit put the true body's origin, frame by frame, beside the truth (the report's plots).
    let mut paths = serde_json::Map::new();
    paths.insert("truth".into(), Value::Object(scores.true_path));
    paths.insert("fit".into(), Value::Object(scores.fitted_path));
    let mut report = json!({
        "fit": file, "truth": a.truth, "video": name, "truth_model": video.contact.model,
        "summary": scores.summary,
        "parameters": parameter_errors(&fit, video, &refs),
        "frames": scores.rows,
    });
    if let Some(p) = pair_errors(&fit, video) {
        report["pairs"] = p;
    }
    if let Some(h) = fit.extra.get("horizon") {
        report["horizon"] = json!({"predictable_frames": h["predictable_frames"],
            "frames": h["step_spread_px"].as_array().map_or(0, Vec::len)});
    }
    if let Some(b) = brightness_errors(&fit, &truth, &name) {
        report["brightness"] = b;
    }
    // The stages' own poses, where the fit folder has them.
    let mut stages = serde_json::Map::new();
    for stage in STAGE_FILES {
        let p = dir.join(format!("{stage}.json"));
        if a.fit.is_dir() && p.exists() {
            let t = pganeus_io::read_trajectory(&p)?;
            let s = score_poses(&t, video, &refs, camera.as_ref());
            stages.insert(stage.into(), s.summary);
            paths.insert(stage.into(), Value::Object(s.fitted_path));
        }
        pb.inc(1);
    }
    if !stages.is_empty() {
        report["stages"] = Value::Object(stages);
    }
    report["paths_m"] = Value::Object(paths);
    // The object's mesh against the true one, in the true body frame.
    let mut meshes = serde_json::Map::new();
    for (entry, r) in fit.bodies.iter().zip(&refs) {
        pb.inc(1);
        let Some(m) = entry.extra.get("object").and_then(|o| o["mesh"].as_str()) else {
            continue;
        };
        let path = dir.join(m);
        let Ok(mut ours) = pganeus_io::read_mesh(&path) else {
            tracing::warn!("{}: not readable: no mesh scores for {}", path.display(), entry.name);
            continue;
        };
        for v in &mut ours.vertices {
            *v = r.to_truth.transform_point(Vec3::cst(*v)).to_array();
        }
        let c = mesh::chamfer(&ours, &r.mesh, 20_000, 3);
        meshes.insert(
            entry.name.clone(),
            json!({"chamfer_mean_mm": num(c.mean, 1e3, 3), "chamfer_p95_mm": num(c.p95, 1e3, 3),
                "volume_iou": num(mesh::volume_iou(&ours, &r.mesh, 200_000, 5), 1.0, 4)}),
        );
    }
    pb.finish();
    if !meshes.is_empty() {
        report["meshes"] = Value::Object(meshes);
    }
    let unrelated: Vec<&str> = refs
        .iter()
        .filter(|r| !r.related)
        .map(|r| r.truth.name.as_str())
        .collect();
    if !unrelated.is_empty() {
        tracing::warn!("{unrelated:?}: no object.reference in the fit: its body frame is taken to be the truth's");
        report["frame_assumed_identical"] = json!(unrelated);
    }
    Ok(EvalReport { scores: report })
}

/// A video's true brightness of every frame relative to the first, as the fit measures it: `gains` the
/// gain each frame was developed with (`truth.json`'s `image_gains`), on the light; the fit compares the
/// stored (sRGB-encoded) values, on which a gain `g` on the light is about `g^(1/2.2)` (the curve's slope
/// through the mid-tones), so the mean of the channels' gains relative to the first frame's is carried
/// there. Empty without frames or with a black first frame.
pub fn true_brightness_drift(gains: &[[f64; 3]]) -> Vec<f64> {
    let level = |g: &[f64; 3]| g.iter().sum::<f64>() / 3.0;
    match gains.first().map(level) {
        Some(first) if first > 0.0 => gains.iter().map(|g| (level(g) / first).powf(1.0 / 2.2)).collect(),
        _ => Vec::new(),
    }
}

/// The fit's brightness of every frame relative to the first (trajectory rows' `brightness`, measured on
/// the scene) against the truth's ([`true_brightness_drift`]), where camera-like footage recorded the gain
/// each frame was developed with.
fn brightness_errors(fit: &Trajectory, truth: &Truth, video: &str) -> Option<Value> {
    let gains: Vec<[f64; 3]> = serde_json::from_value(truth.extra.get(synth::IMAGE_GAINS)?.get(video)?.clone()).ok()?;
    let rows = fit
        .extra
        .get("frames")
        .or_else(|| fit.bodies.first()?.extra.get("frames"))?
        .as_array()?;
    let fitted: Vec<f64> = rows.iter().map_while(|r| r["brightness"].as_f64()).collect();
    let truth = true_brightness_drift(&gains);
    let n = fitted.len().min(truth.len());
    if n == 0 {
        return None;
    }
    let (mut worst, mut worst_frame, mut sum) = (0.0f64, 0usize, 0.0);
    for (k, (f, t)) in fitted.iter().zip(&truth).enumerate() {
        let e = (f / t - 1.0).abs();
        sum += e;
        if e > worst {
            (worst, worst_frame) = (e, k);
        }
    }
    let (lo, hi) = truth[..n]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &t| (l.min(t), h.max(t)));
    Some(
        json!({"frames": n, "error_percent": {"mean": num(sum / n as f64, 100.0, 2),
        "worst": num(worst, 100.0, 2), "worst_frame": worst_frame},
        "true_percent": {"low": num(lo - 1.0, 100.0, 2), "high": num(hi - 1.0, 100.0, 2)}}),
    )
}

/// What [`score`] reads.
struct ScoreInputs<'a> {
    fit: &'a Path,
    truth: &'a Path,
    video: Option<&'a str>,
    samples: usize,
}

/// `eval`: the fit scored ([`score`]) and written to `eval.json` (or `--out`) and a CSV of its frames.
pub fn run(a: &EvalArgs, observer: &dyn Observer) -> Result<EvalReport> {
    let evaluated = score(&a.fit, &a.truth, a.video.as_deref(), a.samples, observer)?;
    let report = &evaluated.scores;
    let dir = if a.fit.is_dir() {
        a.fit.clone()
    } else {
        a.fit.parent().unwrap_or(Path::new(".")).to_path_buf()
    };
    let out = a.out.clone().unwrap_or_else(|| dir.join("eval.json"));
    let csv_path = a.csv.clone().unwrap_or_else(|| out.with_extension("csv"));
    let mut csv =
        String::from("body,frame,position_mm,rotation_deg,add_mm,add_s_mm,silhouette_iou,fit_iou,fit_psnr,fit_pose,along_sight_mm,across_sight_mm,rotation_sym_deg,sim_position_mm,sim_rotation_deg,sim_from_ga_mm\n");
    for r in report["frames"].as_array().into_iter().flatten() {
        let f = |k: &str| match &r[k] {
            Value::Null => String::new(),
            Value::String(s) => s.clone(),
            v => v.to_string(),
        };
        writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            f("body"),
            f("frame"),
            f("position_mm"),
            f("rotation_deg"),
            f("add_mm"),
            f("add_s_mm"),
            f("silhouette_iou"),
            f("fit_iou"),
            f("fit_psnr"),
            f("fit_pose"),
            f("along_sight_mm"),
            f("across_sight_mm"),
            f("rotation_sym_deg"),
            f("sim_position_mm"),
            f("sim_rotation_deg"),
            f("fit_sim_from_ga_mm")
        )?;
    }
    pganeus_io::write_atomic(&out, serde_json::to_string_pretty(&report)?.as_bytes())?;
    pganeus_io::write_atomic(&csv_path, csv.as_bytes())?;
    for line in evaluated.lines() {
        note(observer, line);
    }
    note(observer, format!("wrote {} and {}", out.display(), csv_path.display()));
    Ok(evaluated)
}

/// The summary lines of an `eval.json` document.
fn summary_lines(report: &Value) -> Vec<String> {
    let mut lines = Vec::new();
    for (body, s) in report["summary"].as_object().into_iter().flatten() {
        lines.push(format!(
            "{body}: position mm mean {} worst {} (frame {}); rotation ° mean {} worst {} (frame {}); ADD mm mean {}; ADD-S mm mean {}{}",
            s["position_mm"]["mean"],
            s["position_mm"]["worst"],
            s["position_mm"]["worst_frame"],
            s["rotation_deg"]["mean"],
            s["rotation_deg"]["worst"],
            s["rotation_deg"]["worst_frame"],
            s["add_mm"]["mean"],
            s["add_s_mm"]["mean"],
            s.get("silhouette_iou")
                .map(|i| format!("; silhouette IoU mean {} worst {}", i["mean"], i["worst"]))
                .unwrap_or_default()
        ));
        if s["symmetries"].as_u64().is_some_and(|k| k > 1) {
            lines.push(format!(
                "{body}: the shape has {} proper symmetries (the identity counted); up to them, rotation ° mean {} worst {} (frame {})",
                s["symmetries"], s["rotation_sym_deg"]["mean"], s["rotation_sym_deg"]["worst"], s["rotation_sym_deg"]["worst_frame"]
            ));
        }
        if let (Some(a), Some(x)) = (s.get("along_sight_mm"), s.get("across_sight_mm")) {
            lines.push(format!(
                "{body}: position along the camera's line of sight (absolute) mm mean {} worst {} (frame {}); across it mean {} worst {} (frame {})",
                a["mean"], a["worst"], a["worst_frame"], x["mean"], x["worst"], x["worst_frame"]
            ));
        }
        if let Some(k) = s["simulated_frames"].as_u64() {
            lines.push(format!(
                "{body}: {k} of {} frames reported from the simulation of the fitted physics; it draws the body {} mm from GA's poses (mean; worst {}, frame {}) and {} mm from the truth (worst {}, frame {}; rotation mean {}°, worst {}°)",
                s["frames"],
                s["sim_from_ga_mm"]["mean"],
                s["sim_from_ga_mm"]["worst"],
                s["sim_from_ga_mm"]["worst_frame"],
                s["sim_position_mm"]["mean"],
                s["sim_position_mm"]["worst"],
                s["sim_position_mm"]["worst_frame"],
                s["sim_rotation_deg"]["mean"],
                s["sim_rotation_deg"]["worst"]
            ));
        }
        let p = &report["parameters"][body];
        let share = match p["v0_error_percent"].as_f64() {
            Some(pc) => format!("{pc} %"),
            None => "the truth is at rest".into(),
        };
        lines.push(format!(
            "{body}: v0 off by {} m/s ({share}), omega0 by {} rad/s{}",
            p["v0_error_m_s"],
            p["omega0_error_rad_s"],
            if p.get("restitution_error").is_some() {
                format!("; {}", values_text(p))
            } else {
                String::new()
            }
        ));
        if let Some(f) = p.get("flight") {
            lines.push(format!(
                "{body}: the launch fitted to the flight alone ({} frames before {}; {}): \
                 v0 off by {} m/s ({} %), omega0 by {} rad/s",
                f["frames"],
                report::run_page::flight_before(f),
                report::run_page::flight_verdict(f),
                f["v0_error_m_s"],
                f["v0_error_percent"],
                f["omega0_error_rad_s"]
            ));
        }
    }
    if let (Some(k), Some(n)) = (
        report["horizon"]["predictable_frames"].as_u64(),
        report["horizon"]["frames"].as_u64(),
    ) {
        if k < n {
            lines.push(format!(
                "the fitted motion converges in its step size over frames 0-{} of {n} only: the frames after are chaotic",
                k.saturating_sub(1)
            ));
        }
    }
    for p in report["pairs"].as_array().into_iter().flatten() {
        lines.push(format!("{} and {}: {}", p["bodies"][0], p["bodies"][1], values_text(p)));
    }
    if let Some(b) = report.get("brightness") {
        lines.push(format!(
            "the video's brightness, frame to frame: the fit's within {} % of the truth's on average, {} % at worst (frame {}); the truth drifts {} % to {} %",
            b["error_percent"]["mean"],
            b["error_percent"]["worst"],
            b["error_percent"]["worst_frame"],
            b["true_percent"]["low"],
            b["true_percent"]["high"]
        ));
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pair_range_is_read_by_the_bodies_names_and_the_truth_placed_in_it() {
        let mut fit: Trajectory = serde_json::from_value(json!({
            "capture": "collide", "fps": 30.0, "bodies": [],
            "contact": {"restitution": 0.3, "friction": 0.26, "model": "pganeus",
                "restitution_range": [0.02, 0.81], "friction_range": [0.256, 0.3],
                "pairs": [{"bodies": ["toy", "block"], "restitution": 0.71, "friction": 0.999,
                    "restitution_range": [0.41, 0.88], "friction_range": [0.001, 0.999]}]}
        }))
        .unwrap();
        let names = ["block".to_string(), "toy".to_string()];
        let entry = pair_entry(&fit, &names).expect("the pair, its names sorted");
        let mut row = json!({"restitution_true": 0.7, "friction_true": 0.15});
        add_ranges(&mut row, entry);
        assert_eq!(row["restitution_range"], json!([0.41, 0.88]));
        assert_eq!(row["restitution_true_in_range"], json!(true));
        assert!(range_text(&row, "friction").contains("the truth inside"));
        // The scene's values: the true friction 0.25 lies below the range.
        let mut row = json!({"restitution_true": 0.4, "friction_true": 0.25});
        add_ranges(&mut row, &fit.contact.extra);
        assert_eq!(row["friction_true_in_range"], json!(false));
        assert!(range_text(&row, "friction").contains("outside"));
        // No ranges in the file (an older fit): nothing added, nothing printed.
        fit.contact.extra.remove("restitution_range");
        let mut row = json!({"restitution_true": 0.4});
        add_ranges(&mut row, &fit.contact.extra);
        assert!(row.get("restitution_range").is_none() && range_text(&row, "restitution").is_empty());
        assert!(pair_entry(&fit, &["ball".to_string(), "toy".to_string()]).is_none());
    }

    #[test]
    fn the_fitted_brightness_is_held_to_the_truths_gains_carried_into_the_stored_values() {
        // The truth's light doubles by frame 2 (white balance off per channel, its mean 2); the stored values
        // then grow by 2^(1/2.2) = 1.37. The fit reads 1.37 there, 1.02 where the truth is steady.
        let truth: Truth = serde_json::from_value(json!({
            "image_gains": {"drop": [[1.0, 0.9, 1.1], [1.0, 1.0, 1.0], [2.0, 1.8, 2.2]]}
        }))
        .unwrap();
        let fit: Trajectory = serde_json::from_value(json!({
            "capture": "drop", "fps": 30.0, "bodies": [], "contact": {"restitution": 0.5, "friction": 0.25, "model": "pganeus"},
            "frames": [{"frame": 0, "brightness": 1.0}, {"frame": 1, "brightness": 1.02},
                       {"frame": 2, "brightness": 2f64.powf(1.0 / 2.2)}]
        }))
        .unwrap();
        let b = brightness_errors(&fit, &truth, "drop").expect("gains and brightness");
        assert_eq!(b["frames"], json!(3));
        assert_eq!(b["error_percent"]["worst"], json!(2.0));
        assert_eq!(b["error_percent"]["worst_frame"], json!(1));
        assert_eq!(b["true_percent"]["high"].as_f64().map(|h| h.round()), Some(37.0));
        // Another video, or a truth without gains: nothing to score.
        assert!(brightness_errors(&fit, &truth, "slide").is_none());
        assert!(brightness_errors(&fit, &Truth::default(), "drop").is_none());
    }
}
