//! The pieces of a run's page drawn from its records: the fitted values and their errors as tables, the
//! paths, frames and losses of each stage as charts, in the colours of the paper's figures. The data come
//! in as read (trajectory files, `eval.json`, log lines); finding and reading them is the caller's.

use crate::{Chart, Mark, Page, Series};
use pganeus_io::Trajectory;
use serde_json::Value;
use std::collections::BTreeMap;

/// The colours of the paper's figures: truth, PA, GA, PGA, and the fit as reported.
pub const TRUTH: [u8; 3] = [30, 30, 30];

pub const PA: [u8; 3] = [31, 119, 180];

pub const GA: [u8; 3] = [44, 160, 44];

pub const PGA: [u8; 3] = [214, 39, 40];

pub const REPORTED: [u8; 3] = [255, 127, 14];

pub const GUESS: [u8; 3] = [148, 103, 189];

pub const LAUNCH: [u8; 3] = [140, 86, 75];

/// The number at `key` of a JSON object.
pub fn f64_at(v: &Value, key: &str) -> Option<f64> {
    v.get(key).and_then(Value::as_f64)
}

/// `v` with `digits` decimals, or `–` where there is none.
pub fn fmt(v: Option<f64>, digits: usize) -> String {
    v.filter(|x| x.is_finite())
        .map_or("–".into(), |x| format!("{x:.digits$}"))
}

/// Each training run's PSNR on the batch and colour loss over its steps (the lines of its `log.jsonl`).
pub fn training_charts(runs: &BTreeMap<String, Vec<Value>>) -> Vec<(String, Chart)> {
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

/// `" in 0.48–0.55"`: the range `fit` wrote beside a contact value (`key`), or nothing.
pub fn range_text(range: Option<&Value>) -> String {
    match range.and_then(range_pair) {
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

/// The fitted launch and contact values of each body of `traj`, beside the truth's and their errors where
/// `eval` has them.
pub fn parameter_table(page: &mut Page, traj: &Trajectory, eval: Option<&Value>) {
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
                rows.push(vec![
                    format!(
                        "{}: the flight alone ({} frames before {}; {})",
                        b.name,
                        f["frames"],
                        flight_before(f),
                        flight_verdict(f)
                    ),
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

/// The pose errors of an `eval.json` per body, and per stage where it scored the stage files.
pub fn error_table(page: &mut Page, e: &Value) {
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
pub fn eval_path(eval: Option<&Value>, key: &str, body: &str) -> Option<Vec<[f64; 3]>> {
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

/// Each body's path from above and its height over time: the truth, each stage and the reported motion.
pub fn path_charts(
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

/// A stage file's own per-frame rows.
pub fn own_rows(stage: &Option<Trajectory>) -> Option<&Value> {
    stage.as_ref().and_then(|t| t.extra.get("frames"))
}

/// The per-frame image terms (`iou`, `psnr_window`) of PA, GA and PGA, each measured the same way (the
/// object's window of the render against the video).
pub fn frame_charts(
    name: &str,
    traj: &Trajectory,
    stages: &[(&str, [u8; 3], Option<Trajectory>)],
) -> Vec<(String, Chart)> {
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

/// Per body, how far the simulation of the fitted physics draws the body from GA's pose in each frame
/// (`trajectory.json`'s rows) and, with `eval`, from the truth; with a sentence that counts the frames
/// reported from the simulation. None for a fit written before these rows.
pub fn simulation_chart(name: &str, traj: &Trajectory, eval: Option<&Value>) -> Option<(String, Chart, String)> {
    let mut chart = Chart::new(
        "the simulation of the fitted physics against GA and the truth",
        "frame",
        "distance (mm)",
    );
    let mut counts = Vec::new();
    for (i, b) in traj.bodies.iter().enumerate() {
        let rows = b
            .extra
            .get("frames")
            .or_else(|| traj.extra.get("frames"))
            .and_then(Value::as_array)?;
        let from_ga: Vec<(f64, f64)> = rows
            .iter()
            .filter_map(|r| Some((f64_at(r, "frame")?, f64_at(r, "sim_from_ga_mm")?)))
            .collect();
        if from_ga.is_empty() {
            return None;
        }
        let simulated = rows.iter().filter(|r| r["pose"] == "simulated").count();
        counts.push(format!(
            "{}: {simulated} of {} frames from the simulation",
            b.name,
            rows.len()
        ));
        let shade = |c: [u8; 3]| c.map(|v| (v as usize * 2 / (2 + i)) as u8);
        chart
            .series
            .push(Series::new(format!("{}: from GA", b.name), from_ga, Mark::Line).colored(shade(GA)));
        let truth: Vec<(f64, f64)> = eval
            .and_then(|e| e["frames"].as_array())
            .into_iter()
            .flatten()
            .filter(|r| r["body"] == b.name.as_str())
            .filter_map(|r| Some((f64_at(r, "frame")?, f64_at(r, "sim_position_mm")?)))
            .collect();
        if !truth.is_empty() {
            chart
                .series
                .push(Series::new(format!("{}: from the truth", b.name), truth, Mark::Line).colored(shade(PGA)));
        }
    }
    let mut note = format!(
        "Reported from the simulation of the fitted physics: {}; the other frames from GA, where the simulation \
         misses the video.",
        counts.join("; ")
    );
    let h = traj.extra.get("horizon");
    if let (Some(k), Some(n)) = (
        h.and_then(|h| h["predictable_frames"].as_u64()),
        h.and_then(|h| h["step_spread_px"].as_array()).map(Vec::len),
    ) {
        if (k as usize) < n {
            note.push_str(&format!(
                " The simulation converges in its step size over frames 0–{} of {n} only: after that the motion \
                 is chaotic (twice the substeps draw it elsewhere), no model can follow it, and the contact \
                 values' ranges are those the frames before allow.",
                k.saturating_sub(1)
            ));
        }
    }
    Some((format!("{name}_simulation"), chart, note))
}

/// A `[lo, hi]` range as `fit` writes it (`restitution_range`, `friction_range`), if `v` is one.
pub fn range_pair(v: &Value) -> Option<[f64; 2]> {
    match v.as_array()?.as_slice() {
        [lo, hi] => Some([lo.as_f64()?, hi.as_f64()?]),
        _ => None,
    }
}

/// Every stage's loss from the lines of a fit's `log.jsonl`: the first pose's iterations per frame, PA's iterations over its
/// growing windows, GA's loss per frame, and each PGA start's final loss.
pub fn loss_charts(name: &str, lines: &[Value]) -> Vec<(String, Chart)> {
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

/// What a `flight` entry of a trajectory was fitted before: the first collision (several bodies' launch
/// window) or the first contact (one body's flight).
pub fn flight_before(flight: &Value) -> &str {
    flight["before"].as_str().unwrap_or("the first contact")
}

/// What the fit did with a `flight` entry's launch: the kept launch stands against it, misses it, or is it
/// (the world with the flight's launch held was kept).
pub fn flight_verdict(flight: &Value) -> &'static str {
    match (flight["bent"].as_bool(), flight["held_kept"].as_bool()) {
        (Some(true), Some(true)) => "its launch held and kept",
        (Some(true), _) => "the kept launch misses it",
        _ => "the kept launch stands against it",
    }
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

    #[test]
    fn the_simulation_chart_counts_the_simulated_frames_and_draws_both_distances_per_body() {
        let rows = |b: &str| {
            json!([{"frame": 0, "pose": "simulated", "sim_from_ga_mm": 0.5, "body": b},
                   {"frame": 1, "pose": "ga", "sim_from_ga_mm": 7.0},
                   {"frame": 2, "pose": "simulated", "sim_from_ga_mm": 1.0}])
        };
        let body = |name: &str, frames: Value| {
            json!({"name": name, "initial": {"t": [0.0, 0.0, 0.0], "q": [1.0, 0.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0],
                   "omega": [0.0, 0.0, 0.0]}, "poses": [], "frames": frames})
        };
        let trajectory = |bodies: Vec<Value>| -> Trajectory {
            serde_json::from_value(json!({"capture": "collide", "fps": 30.0, "bodies": bodies,
                "contact": {"restitution": 0.5, "friction": 0.3, "model": "pganeus"}}))
            .unwrap()
        };
        let traj = trajectory(vec![body("toy", rows("toy")), body("block", rows("block"))]);
        let eval = json!({"frames": [{"body": "toy", "frame": 0, "sim_position_mm": 0.7},
                                     {"body": "toy", "frame": 1, "sim_position_mm": 9.0}]});
        let (key, chart, note) = simulation_chart("collide", &traj, Some(&eval)).unwrap();
        assert_eq!(key, "collide_simulation");
        assert!(
            note.contains("toy: 2 of 3 frames from the simulation; block: 2 of 3"),
            "{note}"
        );
        let labels: Vec<&str> = chart.series.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(labels, ["toy: from GA", "toy: from the truth", "block: from GA"]);
        assert_eq!(chart.series[1].points, [(0.0, 0.7), (1.0, 9.0)]);
        assert!(!note.contains("converges"), "{note}");
        // A motion that stops converging in its step size after frame 1: the note says so.
        let mut chaotic = traj.clone();
        chaotic.extra.insert(
            "horizon".into(),
            json!({"predictable_frames": 2, "step_spread_px": [0.0, 0.2, 4.0]}),
        );
        let (_, _, note) = simulation_chart("collide", &chaotic, None).unwrap();
        assert!(
            note.contains("converges in its step size over frames 0–1 of 3 only"),
            "{note}"
        );
        // A fit written before these rows: no chart.
        let old = trajectory(vec![body("toy", json!([{"frame": 0, "pose": "simulated"}]))]);
        assert!(simulation_chart("collide", &old, None).is_none());
    }
}
