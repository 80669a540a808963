//! truth.json / trajectory.json: the example of FORMATS.md, the checks on
//! reading and writing, quaternion normalisation and round trips of extra keys.

use std::path::{Path, PathBuf};

use pganeus_io::{
    read_trajectory, read_trajectory_bytes, read_truth, read_truth_bytes, write_trajectory, write_trajectory_bytes,
    write_truth, IoError, Pose, Trajectory,
};
use serde_json::json;

/// FORMATS.md's example, without the `"... one per frame"` placeholder.
const FORMATS_EXAMPLE: &str = include_str!("data/truth_example.json");

const TRUTH: &str = "truth.json";
const TRAJ: &str = "trajectory.json";

/// A trajectory.json with two bodies of three frames and extra keys everywhere.
fn trajectory_json() -> serde_json::Value {
    let pose = |x: f64| json!({"t": [x, 0.0, 0.03], "q": [1.0, 0.0, 0.0, 0.0]});
    let body = |name: &str| {
        json!({
            "name": name,
            "initial": {
                "t": [0.0, 0.0, 0.03], "q": [1.0, 0.0, 0.0, 0.0],
                "v": [0.8, 0.0, 0.0], "omega": [0.0, 0.0, 1.0]
            },
            "poses": [pose(0.0), pose(0.01), pose(0.02)],
            "pose_error": [0.0, 0.001, 0.002]
        })
    };
    json!({
        "capture": "slide",
        "fps": 30.0,
        "bodies": [body("toy"), body("box")],
        "contact": {
            "restitution": 0.3, "friction": 0.4, "model": "bullet",
            "pairwise": {"toy/box": {"restitution": 0.5}},
            "settings": {"substeps": 10}
        },
        "losses": [{"rgb": 0.1, "mask": 0.02}, {"rgb": 0.09, "mask": 0.01}, {"rgb": 0.08, "mask": 0.01}],
        "config": {"lr": 1e-3, "iters": 100}
    })
}

fn read_value(v: &serde_json::Value) -> pganeus_io::Result<Trajectory> {
    read_trajectory_bytes(v.to_string().as_bytes(), Path::new(TRAJ))
}

/// The field of an `Invalid` error; panics on any other outcome.
fn invalid_field<T: std::fmt::Debug>(r: pganeus_io::Result<T>) -> (String, String) {
    match r {
        Err(ref e @ IoError::Invalid { ref field, .. }) => (field.clone(), e.to_string()),
        other => panic!("expected an Invalid error, got {other:?}"),
    }
}

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pganeus_io_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn formats_md_example_parses() {
    let truth = read_truth_bytes(FORMATS_EXAMPLE.as_bytes(), Path::new(TRUTH)).unwrap();
    assert_eq!(truth.gravity, [0.0, 0.0, -9.81]);
    let bg = truth.background.as_ref().unwrap();
    assert_eq!(
        (bg.capture.as_str(), bg.mesh.as_str()),
        ("background", "background.ply")
    );
    let toy = truth.body("toy").unwrap();
    assert_eq!(toy.mesh, "toy.ply");
    assert_eq!(toy.mass, Some(0.05));
    assert_eq!(toy.static_captures.len(), 2);
    assert_eq!(toy.static_captures[1].capture, "toy_b");
    assert_eq!(toy.static_captures[1].pose.q, [0.0, 1.0, 0.0, 0.0]);
    let video = truth.video("slide").unwrap();
    assert_eq!(video.fps, 30.0);
    assert_eq!(video.contact.model, "pganeus");
    assert_eq!(video.contact.restitution, 0.3);
    assert_eq!(video.contact.friction, 0.4);
    let body = video.body("toy").unwrap();
    assert_eq!(body.initial.v, [0.8, 0.0, 0.0]);
    assert_eq!(
        body.poses,
        vec![Pose {
            t: [0.0, 0.0, 0.03],
            q: [1.0, 0.0, 0.0, 0.0]
        }]
    );
    assert!(truth.extra.is_empty() && video.extra.is_empty());
}

#[test]
fn a_videos_entry_reads_as_a_trajectory() {
    let v: serde_json::Value = serde_json::from_str(FORMATS_EXAMPLE).unwrap();
    let traj = read_value(&v["videos"][0]).unwrap();
    let truth = read_truth_bytes(FORMATS_EXAMPLE.as_bytes(), Path::new(TRUTH)).unwrap();
    assert_eq!(traj, truth.videos[0]);
}

#[test]
fn gravity_defaults_and_optional_fields() {
    let truth = read_truth_bytes(br#"{"bodies": [{"name": "a", "mesh": "a.ply"}]}"#, Path::new(TRUTH)).unwrap();
    assert_eq!(truth.gravity, [0.0, 0.0, -9.81]);
    assert!(truth.background.is_none() && truth.videos.is_empty());
    assert_eq!(truth.bodies[0].mass, None);
    assert!(truth.bodies[0].static_captures.is_empty());
}

#[test]
fn extra_keys_round_trip() {
    let v = trajectory_json();
    let traj = read_value(&v).unwrap();
    assert_eq!(traj.extra["config"]["iters"], json!(100));
    assert_eq!(traj.contact.extra["pairwise"]["toy/box"]["restitution"], json!(0.5));
    assert_eq!(traj.bodies[1].extra["pose_error"][2], json!(0.002));

    let bytes = write_trajectory_bytes(&traj, Path::new(TRAJ)).unwrap();
    let back: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
    assert_eq!(back, v, "written JSON differs from what was read");
    assert_eq!(read_trajectory_bytes(&bytes, Path::new(TRAJ)).unwrap(), traj);

    // Extra keys at every level of a truth.json too.
    let mut t: serde_json::Value = serde_json::from_str(FORMATS_EXAMPLE).unwrap();
    t["scene"] = json!({"seed": 7});
    t["background"]["scale"] = json!(2.0);
    t["bodies"][0]["density"] = json!(1000.0);
    t["bodies"][0]["static_captures"][0]["note"] = json!("first");
    t["videos"][0] = v.clone();
    let dir = tempdir("truth_rt");
    let path = dir.join("truth.json");
    std::fs::write(&path, t.to_string()).unwrap();
    let truth = read_truth(&path).unwrap();
    write_truth(&path, &truth).unwrap();
    let back: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    // Integers written by hand come back as floats (1 -> 1.0) in typed fields,
    // so compare after a second read rather than as raw JSON.
    assert_eq!(read_truth(&path).unwrap(), truth);
    assert_eq!(back["scene"], json!({"seed": 7}));
    assert_eq!(back["background"]["scale"], json!(2.0));
    assert_eq!(back["bodies"][0]["density"], json!(1000.0));
    assert_eq!(back["bodies"][0]["static_captures"][0]["note"], json!("first"));
    assert_eq!(back["videos"][0], v);
    std::fs::remove_dir_all(dir).unwrap();
}

/// What a fit writes (every bit of a computed value, quaternions normalised in floating point) reads back
/// equal bit for bit: a fit resumed from its stage files goes on exactly as the uninterrupted one.
#[test]
fn computed_values_read_back_bit_for_bit() {
    let mut traj = read_value(&trajectory_json()).unwrap();
    let mut x = 0.1234_f64;
    let mut next = || {
        // Values spread over scales, with every mantissa bit in use.
        x = (x * 7.13 + 0.377).fract();
        (x - 0.5) * 10f64.powi((x * 8.0) as i32 - 4)
    };
    for body in &mut traj.bodies {
        for pose in &mut body.poses {
            pose.t = [next(), next(), next()];
            let q = [next(), next(), next(), next()];
            let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
            pose.q = q.map(|c| c / n);
        }
        body.initial.t = [next(), next(), next()];
        body.initial.q = body.poses[1].q;
        body.initial.v = [next(), next(), next()];
        body.initial.omega = [next(), next(), next()];
    }
    traj.contact.restitution = next().abs();
    traj.contact.friction = next().abs();
    let bytes = write_trajectory_bytes(&traj, Path::new(TRAJ)).unwrap();
    assert_eq!(read_trajectory_bytes(&bytes, Path::new(TRAJ)).unwrap(), traj);
}

#[test]
fn non_unit_quaternion_is_rejected_with_its_field() {
    let mut v = trajectory_json();
    v["bodies"][1]["poses"][2]["q"] = json!([1.0, 0.1, 0.0, 0.0]);
    let (field, msg) = invalid_field(read_value(&v));
    assert_eq!(field, "bodies[1].poses[2].q");
    assert!(msg.contains(TRAJ) && msg.contains("unit length"), "{msg}");

    let mut t: serde_json::Value = serde_json::from_str(FORMATS_EXAMPLE).unwrap();
    t["videos"][0]["bodies"][0]["initial"]["q"] = json!([0.5, 0.5, 0.5, 0.4]);
    let (field, _) = invalid_field(read_truth_bytes(t.to_string().as_bytes(), Path::new(TRUTH)));
    assert_eq!(field, "videos[0].bodies[0].initial.q");

    let mut t: serde_json::Value = serde_json::from_str(FORMATS_EXAMPLE).unwrap();
    t["bodies"][0]["static_captures"][1]["pose"]["q"] = json!([0, 0, 0, 0]);
    let (field, _) = invalid_field(read_truth_bytes(t.to_string().as_bytes(), Path::new(TRUTH)));
    assert_eq!(field, "bodies[0].static_captures[1].pose.q");
}

#[test]
fn nearly_unit_quaternions_are_normalised() {
    let mut v = trajectory_json();
    let s = 1.0 + 0.9e-3;
    v["bodies"][0]["poses"][1]["q"] = json!([0.6 * s, 0.0, 0.8 * s, 0.0]);
    v["bodies"][0]["initial"]["q"] = json!([0.0, 0.0, 0.0, 1.0 - 0.9e-3]);
    let traj = read_value(&v).unwrap();
    let q = traj.bodies[0].poses[1].q;
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!((n - 1.0).abs() < 1e-15, "|q| = {n}");
    assert!((q[0] - 0.6).abs() < 1e-15 && (q[2] - 0.8).abs() < 1e-15);
    assert_eq!(traj.bodies[0].initial.q, [0.0, 0.0, 0.0, 1.0]);
}

#[test]
fn non_finite_values_are_rejected_with_their_field() {
    // serde_json writes NaN as null.
    let mut v = trajectory_json();
    v["bodies"][0]["poses"][1]["t"][2] = json!(null);
    let (field, msg) = invalid_field(read_value(&v));
    assert_eq!(field, "bodies[0].poses[1].t[2]");
    assert!(msg.contains("finite"), "{msg}");

    // Python's json.dump writes bare NaN / Infinity, which is not JSON.
    let text = trajectory_json().to_string().replacen("0.8", "NaN", 1);
    let (field, _) = invalid_field(read_trajectory_bytes(text.as_bytes(), Path::new(TRAJ)));
    assert_eq!(field, "bodies[0].initial.v[0]");

    let text = trajectory_json()
        .to_string()
        .replacen("\"friction\":0.4", "\"friction\":-Infinity", 1);
    let (field, _) = invalid_field(read_trajectory_bytes(text.as_bytes(), Path::new(TRAJ)));
    assert_eq!(field, "contact.friction");

    // A "NaN" inside a string is just text.
    let mut v = trajectory_json();
    v["capture"] = json!("NaN Infinity");
    assert_eq!(read_value(&v).unwrap().capture, "NaN Infinity");

    let mut t: serde_json::Value = serde_json::from_str(FORMATS_EXAMPLE).unwrap();
    t["gravity"][1] = json!(null);
    let (field, _) = invalid_field(read_truth_bytes(t.to_string().as_bytes(), Path::new(TRUTH)));
    assert_eq!(field, "gravity[1]");
}

#[test]
fn fps_mass_and_pose_counts_are_checked() {
    let mut v = trajectory_json();
    v["fps"] = json!(0.0);
    assert_eq!(invalid_field(read_value(&v)).0, "fps");

    let mut v = trajectory_json();
    v["bodies"][1]["poses"].as_array_mut().unwrap().pop();
    let (field, msg) = invalid_field(read_value(&v));
    assert_eq!(field, "bodies[1].poses");
    assert!(msg.contains("one pose per frame"), "{msg}");

    let mut t: serde_json::Value = serde_json::from_str(FORMATS_EXAMPLE).unwrap();
    t["bodies"][0]["mass"] = json!(-1.0);
    let (field, _) = invalid_field(read_truth_bytes(t.to_string().as_bytes(), Path::new(TRUTH)));
    assert_eq!(field, "bodies[0].mass");
}

#[test]
fn malformed_json_reports_path_line_and_column() {
    let text = "{\n  \"capture\": \"slide\",\n  \"fps\": 30.0,\n  oops\n}";
    let err = read_trajectory_bytes(text.as_bytes(), Path::new(TRAJ)).unwrap_err();
    assert!(matches!(err, IoError::Json { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(
        msg.contains(TRAJ) && msg.contains("line 4") && msg.contains("column"),
        "{msg}"
    );

    // Wrong shape: a quaternion with three numbers.
    let text = trajectory_json()
        .to_string()
        .replacen("[1.0,0.0,0.0,0.0]", "[1.0,0.0,0.0]", 1);
    let err = read_trajectory_bytes(text.as_bytes(), Path::new(TRAJ)).unwrap_err();
    assert!(matches!(err, IoError::Json { .. }), "{err:?}");
    assert!(err.to_string().contains("length 4"), "{err}");

    // Missing required field.
    let mut v = trajectory_json();
    v.as_object_mut().unwrap().remove("contact");
    let err = read_value(&v).unwrap_err();
    assert!(err.to_string().contains("contact"), "{err}");
}

#[test]
fn invalid_trajectory_is_not_written() {
    let dir = tempdir("traj_write");
    let path = dir.join("out/trajectory.json");
    let good = read_value(&trajectory_json()).unwrap();
    write_trajectory(&path, &good).unwrap();
    assert_eq!(read_trajectory(&path).unwrap(), good);
    let before = std::fs::read(&path).unwrap();

    let mut bad = good.clone();
    bad.bodies[0].poses[2].t[0] = f64::NAN;
    let (field, msg) = invalid_field(write_trajectory(&path, &bad));
    assert_eq!(field, "bodies[0].poses[2].t[0]");
    assert!(msg.contains("trajectory.json"), "{msg}");
    assert_eq!(std::fs::read(&path).unwrap(), before, "target was touched");
    assert_eq!(
        testkit::sorted_file_names(path.parent().unwrap()),
        vec!["trajectory.json"]
    );

    // Nothing is created either when the target did not exist.
    let fresh = dir.join("fresh.json");
    assert!(write_trajectory(&fresh, &bad).is_err());
    assert!(!fresh.exists());
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn missing_file_is_an_open_error_naming_it() {
    let err = read_trajectory(Path::new("/nonexistent/dir/trajectory.json")).unwrap_err();
    assert!(matches!(err, IoError::Open { .. }), "{err:?}");
    assert!(err.to_string().contains("/nonexistent/dir/trajectory.json"), "{err}");
}
