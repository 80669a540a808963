//! `pganeus eval`: the truth scores as zero error, a 4 mm shift as 4 mm (split along the camera's line of
//! sight and across it), a fit in another body frame is related through `object.reference`, and bad inputs
//! are refused.

use geom::{Pose, Quat, Vec3};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

use crate::common;
use common::{bin, flight_3_cm_s_fast, tabletop, text};

/// The tabletop preset at 64×48 with four frames per video.
fn dataset(d: &Path) -> PathBuf {
    tabletop(d, (64, 48), 3, 4, &[])
}

fn pose(p: &Value) -> Pose<f64> {
    let a = |v: &Value| -> Vec<f64> { v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect() };
    let (t, q) = (a(&p["t"]), a(&p["q"]));
    Pose::new(Quat::new(q[0], q[1], q[2], q[3]), Vec3::new(t[0], t[1], t[2]))
}

fn put(p: &Pose<f64>) -> Value {
    json!({"t": p.t.to_array(), "q": p.q.to_array_re()})
}

/// Evaluate `fit` (a trajectory file) and return eval.json.
fn eval(fit: &Value, dir: &Path, truth: &Path) -> Value {
    eval_printing(fit, dir, truth).0
}

/// `eval` of `fit` written into `dir`: its eval.json and what it printed.
fn eval_printing(fit: &Value, dir: &Path, truth: &Path) -> (Value, String) {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("trajectory.json"), fit.to_string()).unwrap();
    let o = bin().arg("eval").arg(dir).arg("--truth").arg(truth).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(dir.join("eval.csv").exists());
    let report = serde_json::from_str(&std::fs::read_to_string(dir.join("eval.json")).unwrap()).unwrap();
    (report, text(&o))
}

#[test]
fn eval_scores_the_truth_as_zero_and_a_shift_as_its_length() {
    let d = testkit::scratch_dir("cli", "eval");
    let data = dataset(&d);
    let truth_path = data.join("truth.json");
    let truth: Value = serde_json::from_str(&std::fs::read_to_string(&truth_path).unwrap()).unwrap();
    let video = truth["videos"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["capture"] == "drop")
        .unwrap()
        .clone();
    let toy_b = pose(&truth["bodies"][0]["static_captures"][1]["pose"]);
    assert_eq!(truth["bodies"][0]["static_captures"][1]["capture"], "toy_b");

    // The truth itself, its body frame said to sit where the truth's stood in toy_b.
    let mut fit = video.clone();
    fit["bodies"][0]["object"] = json!({"mesh": "none.ply", "reference": {"capture": "toy_b", "pose": put(&toy_b)}});
    let r = eval(&fit, &d.join("same"), &truth_path);
    let s = &r["summary"]["toy"];
    for k in ["position_mm", "rotation_deg", "add_mm", "add_s_mm"] {
        assert_eq!(s[k]["worst"].as_f64().unwrap(), 0.0, "{k}: {s}");
    }
    assert_eq!(s["silhouette_iou"]["worst"].as_f64().unwrap(), 1.0, "{s}");
    assert_eq!(r["parameters"]["toy"]["v0_error_m_s"].as_f64().unwrap(), 0.0);
    assert_eq!(r["parameters"]["toy"]["restitution_error"].as_f64().unwrap(), 0.0);

    // The launch `fit` fitted to the flight alone is scored beside the kept one: here 3 cm/s faster along x.
    let mut with_flight = fit.clone();
    with_flight["bodies"][0]["flight"] = flight_3_cm_s_fast(&video);
    let (r, printed) = eval_printing(&with_flight, &d.join("flight"), &truth_path);
    let p = &r["parameters"]["toy"];
    assert_eq!(p["v0_error_m_s"].as_f64().unwrap(), 0.0, "the kept launch: {p}");
    assert!(
        (p["flight"]["v0_error_m_s"].as_f64().unwrap() - 0.03).abs() < 1e-4,
        "{p}"
    );
    assert!(
        printed.contains(
            "the launch fitted to the flight alone (4 frames before the first contact; the kept launch misses it)"
        ),
        "{printed}"
    );

    // Every pose 4 mm off: 4 mm in position and ADD, a silhouette IoU below 1.
    // The fit's rows say the simulation drew the body at the truth, 4 mm from GA's poses, and that three of
    // the four frames are reported from it.
    let mut shifted = fit.clone();
    let mut rows = Vec::new();
    for (k, p) in shifted["bodies"][0]["poses"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .enumerate()
    {
        let moved = pose(p);
        rows.push(
            json!({"frame": k, "pose": if k < 3 { "simulated" } else { "ga" }, "simulated": put(&moved),
            "sim_from_ga_mm": 4.0, "sim_from_ga_deg": 0.0}),
        );
        *p = put(&Pose::new(moved.q, moved.t + Vec3::new(0.0, 0.0024, 0.0032)));
    }
    shifted["bodies"][0]["frames"] = json!(rows);
    // And that twice the substeps draw it elsewhere from frame 2 on.
    shifted["horizon"] = json!({"predictable_frames": 2, "threshold_px": 0.75, "step_spread_px": [0.0, 0.1, 2.0, 9.0]});
    let (r, printed) = eval_printing(&shifted, &d.join("shifted"), &truth_path);
    let s = &r["summary"]["toy"];
    assert_eq!(s["simulated_frames"], 3, "{s}");
    assert_eq!(s["sim_position_mm"]["worst"].as_f64().unwrap(), 0.0, "{s}");
    assert_eq!(s["sim_from_ga_mm"]["mean"].as_f64().unwrap(), 4.0, "{s}");
    assert!(
        printed.contains("toy: 3 of 4 frames reported from the simulation of the fitted physics"),
        "{printed}"
    );
    assert!(
        printed.contains("the fitted motion converges in its step size over frames 0-1 of 4 only"),
        "{printed}"
    );
    assert_eq!(r["horizon"]["predictable_frames"], 2);
    let csv = std::fs::read_to_string(d.join("shifted/eval.csv")).unwrap();
    // The simulation's distance from the truth (position, rotation) and from GA's pose close each row.
    assert!(csv.lines().nth(1).unwrap().ends_with(",0.0,0.0,4.0"), "{csv}");
    for k in ["position_mm", "add_mm"] {
        for m in ["mean", "worst"] {
            assert!((s[k][m].as_f64().unwrap() - 4.0).abs() < 1e-3, "{k} {m}: {s}");
        }
    }
    assert!(s["add_s_mm"]["mean"].as_f64().unwrap() <= 4.0 + 1e-3, "{s}");
    assert!(s["silhouette_iou"]["worst"].as_f64().unwrap() < 0.99, "{s}");
    // The paths for the report's charts: the fitted one 4 mm from the true one in every frame.
    let path = |who: &str| -> Vec<Vec3<f64>> {
        let a = r["paths_m"][who]["toy"].as_array().unwrap();
        a.iter()
            .map(|p| {
                let v: Vec<f64> = p.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
                Vec3::new(v[0], v[1], v[2])
            })
            .collect()
    };
    let (fitted, true_path) = (path("fit"), path("truth"));
    assert_eq!(fitted.len(), 4);
    for (f, t) in fitted.iter().zip(&true_path) {
        assert!(((*f - *t).norm() - 0.004).abs() < 2e-6, "{f:?} {t:?}");
    }
    // Its parts along the camera's line of sight and across it make up the 4 mm.
    for row in r["frames"].as_array().unwrap() {
        let part = |k: &str| row[k].as_f64().unwrap();
        let whole = part("along_sight_mm").hypot(part("across_sight_mm"));
        assert!((whole - 4.0).abs() < 2e-3, "{row}");
    }

    // Every pose 3 mm farther from the camera along its line of sight and 1 mm across it: split so.
    let capture = pganeus_io::open_capture(&data.join("drop")).unwrap();
    let eye = geom::Camera::from_world_mat(&capture.cameras[0].world_mat, capture.width, capture.height)
        .unwrap()
        .center();
    let mut deeper = fit.clone();
    for p in deeper["bodies"][0]["poses"].as_array_mut().unwrap() {
        let at = pose(p);
        let s = (at.t - eye) * (1.0 / (at.t - eye).norm());
        let side = s.cross(Vec3::new(0.0, 0.0, 1.0));
        let side = side * (1.0 / side.norm());
        *p = put(&Pose::new(at.q, at.t + s * 0.003 + side * 0.001));
    }
    let r = eval(&deeper, &d.join("deeper"), &truth_path);
    let s = &r["summary"]["toy"];
    for m in ["mean", "worst"] {
        assert!((s["along_sight_mm"][m].as_f64().unwrap() - 3.0).abs() < 2e-3, "{s}");
        assert!((s["across_sight_mm"][m].as_f64().unwrap() - 1.0).abs() < 2e-3, "{s}");
    }
    for row in r["frames"].as_array().unwrap() {
        assert!(
            row["along_sight_mm"].as_f64().unwrap() > 0.0,
            "farther is positive: {row}"
        );
    }
    let csv = std::fs::read_to_string(d.join("deeper/eval.csv")).unwrap();
    assert!(
        csv.lines().next().unwrap().ends_with(
            ",along_sight_mm,across_sight_mm,rotation_sym_deg,sim_position_mm,sim_rotation_deg,sim_from_ga_mm"
        ),
        "{csv}"
    );
    let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    assert_eq!(row.len(), 16, "{csv}");
    let cell = |i: usize| row[i].parse::<f64>().unwrap();
    assert!((cell(10) - 3.0).abs() < 2e-3 && (cell(11) - 1.0).abs() < 2e-3, "{csv}");

    // The same motion in another body frame (origin 7 mm off, axes turned): related through
    // object.reference, it scores as zero again.
    let y = Pose::new(Quat::exp(Vec3::new(0.3, -0.2, 1.1)), Vec3::new(0.004, -0.003, 0.005));
    let mut other = fit.clone();
    other["bodies"][0]["object"]["reference"]["pose"] = put(&toy_b.compose(&y));
    for p in other["bodies"][0]["poses"].as_array_mut().unwrap() {
        *p = put(&pose(p).compose(&y));
    }
    let r = eval(&other, &d.join("other"), &truth_path);
    let s = &r["summary"]["toy"];
    for k in ["position_mm", "rotation_deg", "add_mm"] {
        assert!(s[k]["worst"].as_f64().unwrap() < 1e-3, "{k}: {s}");
    }

    // The toy (a rounded brick) turned half a turn about its long axis shows the same surface: 180° as is,
    // none up to its four symmetries, and a further 3° as 3°.
    let half = Pose::new(Quat::exp(Vec3::new(std::f64::consts::PI, 0.0, 0.0)), Vec3::zero());
    let tilt = Pose::new(Quat::exp(Vec3::new(0.0, 3f64.to_radians(), 0.0)), Vec3::zero());
    for (name, turn, expected) in [("turned", half, 0.0), ("turned_tilted", half.compose(&tilt), 3.0)] {
        let mut turned = fit.clone();
        for p in turned["bodies"][0]["poses"].as_array_mut().unwrap() {
            *p = put(&pose(p).compose(&turn));
        }
        let r = eval(&turned, &d.join(name), &truth_path);
        let s = &r["summary"]["toy"];
        assert_eq!(s["symmetries"], 4, "{s}");
        assert!(s["rotation_deg"]["worst"].as_f64().unwrap() > 170.0, "{s}");
        let sym = s["rotation_sym_deg"]["worst"].as_f64().unwrap();
        assert!((sym - expected).abs() < 0.3, "{name}: {s}");
        assert!(s["position_mm"]["worst"].as_f64().unwrap() < 1e-3, "{s}");
    }

    // Against a truth whose body starts at rest (as a block a toy hits does), the launch error has no
    // percentage: a share of no speed is no figure.
    let mut resting = truth.clone();
    for v in resting["videos"].as_array_mut().unwrap() {
        if v["capture"] == "drop" {
            v["bodies"][0]["initial"]["v"] = json!([0.0, 0.0, 0.0]);
        }
    }
    let resting_path = data.join("truth_at_rest.json");
    std::fs::write(&resting_path, resting.to_string()).unwrap();
    let (r, printed) = eval_printing(&fit, &d.join("at_rest"), &resting_path);
    let p = &r["parameters"]["toy"];
    assert!(p["v0_error_percent"].is_null(), "{p}");
    let speed = |v: &Value| {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap().powi(2))
            .sum::<f64>()
            .sqrt()
    };
    assert!(
        (p["v0_error_m_s"].as_f64().unwrap() - speed(&video["bodies"][0]["initial"]["v"])).abs() < 1e-3,
        "{p}"
    );
    assert!(printed.contains("the truth is at rest"), "{printed}");

    // Refused, each naming the problem: a video the truth does not have, a body it does not have.
    let refused = |wrong: &Value, needle: &str| {
        std::fs::write(d.join("same/trajectory.json"), wrong.to_string()).unwrap();
        let o = bin()
            .arg("eval")
            .arg(d.join("same"))
            .arg("--truth")
            .arg(&truth_path)
            .output()
            .unwrap();
        assert!(!o.status.success() && text(&o).contains(needle), "{}", text(&o));
    };
    let mut wrong = fit.clone();
    wrong["capture"] = json!("nothing");
    refused(&wrong, "no video \"nothing\"");
    let mut wrong = fit.clone();
    wrong["bodies"][0]["name"] = json!("ghost");
    refused(&wrong, "\"ghost\"");
    let _ = std::fs::remove_dir_all(&d);
}
