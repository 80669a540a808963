//! The `pganeus` binary end to end: simulate → fit-physics, target, and the
//! bad-input contract (a message naming the file and field, a non-zero exit,
//! no output written and earlier outputs intact).
use std::path::{Path, PathBuf};

use crate::common;
use common::{bin, repo, tabletop, text};

fn scratch(name: &str) -> PathBuf {
    testkit::scratch_dir("cli", name)
}

const GOOD_BODY: &str = r#"
[[scene]]
shape = "plane"

[[body]]
name = "toy"
mass = 0.1
t = [0.0, 0.0, 0.05]
[body.shape]
shape = "box"
half = [0.02, 0.02, 0.02]
"#;

#[test]
fn simulate_then_fit_physics_recovers_the_launch() {
    let d = scratch("fit");
    let traj = d.join("tabletop.json");
    let o = bin()
        .args(["simulate", "--scene"])
        .arg(repo().join("scenes/tabletop.toml"))
        .arg("--out")
        .arg(&traj)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let t = pganeus_io::read_trajectory(&traj).unwrap();
    assert_eq!(t.bodies[0].poses.len(), 40);
    assert_eq!(t.contact.model, "pganeus");
    let fitted = d.join("fitted.json");
    let o = bin()
        .args(["fit-physics", "--poses"])
        .arg(&traj)
        .arg("--scene")
        .arg(repo().join("scenes/tabletop_guess.toml"))
        .arg("--out")
        .arg(&fitted)
        .output()
        .unwrap();
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    let f = pganeus_io::read_trajectory(&fitted).unwrap();
    let v = f.bodies[0].initial.v;
    assert!((v[0] - 1.6).abs() < 0.016 && (v[2] - 0.6).abs() < 0.006, "{out}");
    let c = &f.bodies[0].extra["contact"];
    assert!((c["restitution"].as_f64().unwrap() - 0.5).abs() < 0.02, "{out}");
    assert!((c["friction"].as_f64().unwrap() - 0.3).abs() < 0.02, "{out}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn simulate_two_bodies_records_their_collision() {
    let d = scratch("two");
    let out = d.join("two.json");
    let o = bin()
        .args(["simulate", "--scene"])
        .arg(repo().join("scenes/two_body.toml"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let t = pganeus_io::read_trajectory(&out).unwrap();
    let hits = t.contact.extra["pairs"][0]["contact"].as_array().unwrap();
    assert!(hits.iter().any(|h| h.as_bool().unwrap()), "box and ball must collide");
    let ball = t.body("ball").unwrap();
    assert!(
        ball.poses.last().unwrap().t[0] > ball.poses[0].t[0] + 0.05,
        "the ball is pushed away"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// Run `simulate` on a scene text; expect failure naming `needles`, and that
/// an existing output file is left as it was.
fn expect_rejected(name: &str, scene: &str, needles: &[&str]) {
    let d = scratch(name);
    let file = d.join("scene.toml");
    std::fs::write(&file, scene).unwrap();
    let out = d.join("out.json");
    std::fs::write(&out, "previous output").unwrap();
    let o = bin()
        .args(["simulate", "--scene"])
        .arg(&file)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let msg = text(&o);
    assert!(!o.status.success(), "{name}: accepted a bad scene:\n{msg}");
    assert!(
        msg.contains("scene.toml"),
        "{name}: the message does not name the file:\n{msg}"
    );
    for n in needles {
        assert!(msg.contains(n), "{name}: the message does not mention {n:?}:\n{msg}");
    }
    assert_eq!(
        std::fs::read_to_string(&out).unwrap(),
        "previous output",
        "{name}: earlier output damaged"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name())
        .collect();
    assert_eq!(leftovers.len(), 2, "{name}: stray files {leftovers:?}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn bad_scenes_are_rejected_with_the_field_named() {
    expect_rejected(
        "restitution",
        &format!("[contact]\nrestitution = 1.5\nfriction = 0.3\n{GOOD_BODY}"),
        &["contact.restitution", "between 0 and 1"],
    );
    expect_rejected(
        "friction0",
        &format!("[contact]\nrestitution = 0.5\nfriction = 0.0\n{GOOD_BODY}"),
        &["contact.friction"],
    );
    expect_rejected(
        "nan",
        &GOOD_BODY.replace("t = [0.0, 0.0, 0.05]", "t = [nan, 0.0, 0.05]"),
        &["body[0] (toy).t", "NaN"],
    );
    expect_rejected(
        "inf",
        &GOOD_BODY.replace("half = [0.02, 0.02, 0.02]", "half = [inf, 0.02, 0.02]"),
        &["body[0] (toy).shape.half"],
    );
    expect_rejected(
        "zero-mass",
        &GOOD_BODY.replace("mass = 0.1", "mass = 0.0"),
        &["body[0] (toy).mass", "positive"],
    );
    expect_rejected(
        "unknown-shape",
        &GOOD_BODY.replace("shape = \"box\"", "shape = \"torus\""),
        &["body[0] (toy).shape.shape", "unknown shape \"torus\""],
    );
    expect_rejected(
        "unknown-field",
        &GOOD_BODY.replace("mass = 0.1", "mass = 0.1\nmas = 2"),
        &["unknown field `mas`"],
    );
    expect_rejected(
        "missing-mesh",
        &GOOD_BODY.replace(
            "[body.shape]\nshape = \"box\"\nhalf = [0.02, 0.02, 0.02]",
            "mesh = \"nowhere.ply\"",
        ),
        &["nowhere.ply"],
    );
    expect_rejected("no-fps", &format!("[sim]\nfps = 0\n{GOOD_BODY}"), &["sim.fps"]);
    expect_rejected("no-frames", &format!("[sim]\nframes = 0\n{GOOD_BODY}"), &["sim.frames"]);
}

#[test]
fn an_open_mesh_is_rejected() {
    let d = scratch("open-mesh");
    // A box with one face missing.
    let mut ply = String::from("ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\nelement face 11\nproperty list uchar int vertex_indices\nend_header\n");
    for i in 0..8 {
        ply += &format!(
            "{} {} {}\n",
            (i & 1) as f64 * 0.04 - 0.02,
            ((i >> 1) & 1) as f64 * 0.04 - 0.02,
            ((i >> 2) & 1) as f64 * 0.04 - 0.02
        );
    }
    for f in [
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6],
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3],
        [0, 4, 6],
        [0, 6, 2],
        [1, 3, 7],
    ] {
        ply += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
    }
    std::fs::write(d.join("open.ply"), ply).unwrap();
    let scene = GOOD_BODY.replace(
        "[body.shape]\nshape = \"box\"\nhalf = [0.02, 0.02, 0.02]",
        "mesh = \"open.ply\"",
    );
    std::fs::write(d.join("scene.toml"), scene).unwrap();
    let out = d.join("out.json");
    let o = bin()
        .args(["simulate", "--scene"])
        .arg(d.join("scene.toml"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let msg = text(&o);
    assert!(!o.status.success(), "{msg}");
    assert!(msg.contains("open.ply") && msg.contains("not closed"), "{msg}");
    assert!(!out.exists());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn fit_physics_rejects_a_bad_pose_file() {
    let d = scratch("bad-poses");
    let poses = d.join("poses.json");
    std::fs::write(&poses, r#"{"capture": "x", "fps": 30, "bodies": [{"name": "toy", "initial": {"t": [0,0,0], "q": [1,0,0,0], "v": [0,0,0], "omega": [0,0,0]}, "poses": [{"t": [0,0,0], "q": [2,0,0,0]}]}], "contact": {"restitution": 0.5, "friction": 0.5, "model": "pganeus"}}"#).unwrap();
    let o = bin()
        .args(["fit-physics", "--poses"])
        .arg(&poses)
        .arg("--scene")
        .arg(repo().join("scenes/tabletop.toml"))
        .output()
        .unwrap();
    let msg = text(&o);
    assert!(!o.status.success());
    assert!(msg.contains("poses.json") && msg.contains("poses[0].q"), "{msg}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn synth_refuses_a_bad_scene_and_keeps_the_old_dataset() {
    let d = scratch("synth-bad");
    let printed = bin().args(["synth", "--print-preset", "tabletop"]).output().unwrap();
    assert!(printed.status.success());
    let good = String::from_utf8(printed.stdout).unwrap();
    let bad = good.replacen("frames = 30", "frames = 0", 1);
    assert_ne!(good, bad);
    std::fs::write(d.join("scene.toml"), bad).unwrap();
    let out = d.join("data");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("keep.txt"), "old").unwrap();
    let o = bin()
        .args(["synth", "--scene"])
        .arg(d.join("scene.toml"))
        .arg("--out")
        .arg(&out)
        .arg("--force")
        .output()
        .unwrap();
    let msg = text(&o);
    assert!(!o.status.success(), "{msg}");
    assert!(
        msg.contains("scene.toml") && msg.contains("videos[0] (slide).frames"),
        "{msg}"
    );
    assert_eq!(std::fs::read_to_string(out.join("keep.txt")).unwrap(), "old");
    let leftovers: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name())
        .collect();
    assert_eq!(leftovers.len(), 2, "no partial folder left: {leftovers:?}");
    let o = bin()
        .args(["synth", "--preset", "tabletop", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        !o.status.success() && text(&o).contains("--force"),
        "an existing dataset is not replaced without --force"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// The tabletop preset rendered by `pganeus synth` into `d/data` at `width`×`height` with `views` views per
/// static capture and one frame per video.
fn tiny_dataset(d: &Path, width: u32, height: u32, views: usize) -> PathBuf {
    tabletop(d, (width, height), views, 1, &[])
}

/// A tiny capture of the tabletop toy.
fn tiny_capture(d: &Path) -> PathBuf {
    tiny_dataset(d, 48, 36, 6).join("toy_a")
}

const TINY_TRAIN: &str = r#"
batch_rays = 128
steps_per_ray = 64
max_samples_per_ray = 16
occupancy_res = 16
occupancy_warmup = 10
checkpoint_every = 10
level_every = 5
[field]
sdf_hidden = [16]
color_hidden = [16]
[field.grid]
levels = 4
log2_table_size = 12
base_resolution = 8
max_resolution = 64
"#;

#[test]
fn train_render_and_resume_end_to_end() {
    let d = scratch("train");
    let capture = tiny_capture(&d);
    std::fs::write(d.join("tiny.toml"), TINY_TRAIN).unwrap();
    let run = d.join("run");
    let train = |extra: &[&str]| {
        bin()
            .arg("train")
            .arg(&capture)
            .arg("--out")
            .arg(&run)
            .arg("--config")
            .arg(d.join("tiny.toml"))
            .args(extra)
            .output()
            .unwrap()
    };
    let o = train(&["--iterations", "20", "--preview-res", "32"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        run.join("checkpoint.safetensors").exists()
            && run.join("config.toml").exists()
            && run.join("log.jsonl").exists()
    );
    // A second run into the same folder must ask for --resume.
    let o = train(&["--iterations", "20"]);
    assert!(!o.status.success() && text(&o).contains("--resume"), "{}", text(&o));
    let o = train(&["--iterations", "30", "--resume", "--no-preview"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("resuming") && text(&o).contains("at step 20"),
        "{}",
        text(&o)
    );
    // --force starts over: a fresh checkpoint and a fresh log (15 steps' worth, not 30 and 15 more).
    let lines = |p: &Path| std::fs::read_to_string(p).unwrap().lines().count();
    let resumed = lines(&run.join("log.jsonl"));
    let o = train(&["--iterations", "15", "--force", "--no-preview"]);
    assert!(o.status.success() && !text(&o).contains("resuming"), "{}", text(&o));
    assert!(lines(&run.join("log.jsonl")) < resumed, "the log was not started over");
    let out = d.join("renders");
    let o = bin()
        .arg("render")
        .arg(&run)
        .arg("--views")
        .arg(&capture)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("mean PSNR"));
    for sub in ["rgb", "normal", "depth"] {
        assert_eq!(
            std::fs::read_dir(out.join(sub)).unwrap().count(),
            if sub == "depth" { 12 } else { 6 },
            "{sub}"
        );
    }
    // Cameras from a JSON file, in world coordinates.
    let cams = pganeus_io::read_cameras_npz(&capture.join("cameras_sphere.npz"), 6).unwrap();
    let json = serde_json::json!([{"width": 48, "height": 36, "world_mat": cams[1].world_mat}]);
    std::fs::write(d.join("cams.json"), json.to_string()).unwrap();
    let out2 = d.join("renders2");
    let o = bin()
        .arg("render")
        .arg(&run)
        .arg("--camera")
        .arg(d.join("cams.json"))
        .arg("--out")
        .arg(&out2)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    // The same camera renders the same image as through the capture.
    assert_eq!(
        std::fs::read(out2.join("rgb").join("cam_000.png")).unwrap(),
        std::fs::read(out.join("rgb").join("001.png")).unwrap()
    );
    // A render that fails (its second camera is broken) leaves the earlier folder as it was, and no
    // partial folder beside it.
    let zero = [[0.0f64; 4]; 4];
    let bad = serde_json::json!([
        {"width": 48, "height": 36, "world_mat": cams[1].world_mat},
        {"width": 48, "height": 36, "world_mat": zero}
    ]);
    std::fs::write(d.join("bad_cams.json"), bad.to_string()).unwrap();
    let before = std::fs::read(out2.join("rgb").join("cam_000.png")).unwrap();
    let o = bin()
        .arg("render")
        .arg(&run)
        .arg("--camera")
        .arg(d.join("bad_cams.json"))
        .arg("--out")
        .arg(&out2)
        .output()
        .unwrap();
    assert!(!o.status.success(), "{}", text(&o));
    assert_eq!(std::fs::read(out2.join("rgb").join("cam_000.png")).unwrap(), before);
    assert!(
        std::fs::read_dir(&d)
            .unwrap()
            .all(|e| !e.unwrap().file_name().to_string_lossy().contains("partial")),
        "a partial folder was left"
    );
    // The run as an object moved along a trajectory: a video capture in the NeuS layout.
    let pose = |x: f64| serde_json::json!({"t": [x, 0.0, 0.0], "q": [1.0, 0.0, 0.0, 0.0]});
    let traj = serde_json::json!({
        "capture": "moved", "fps": 10.0,
        "bodies": [{"name": "toy", "initial": {"t": [0.0, 0.0, 0.0], "q": [1.0, 0.0, 0.0, 0.0], "v": [0.0, 0.0, 0.0], "omega": [0.0, 0.0, 0.0]},
                    "poses": [pose(0.0), pose(0.004), pose(0.008)]}],
        "contact": {"restitution": 0.5, "friction": 0.3, "model": "pganeus"}
    });
    std::fs::write(d.join("traj.json"), traj.to_string()).unwrap();
    let moved = d.join("moved");
    let o = bin()
        .arg("render")
        .arg("--trajectory")
        .arg(d.join("traj.json"))
        .arg("--object")
        .arg(format!("toy={}", run.display()))
        .arg("--camera")
        .arg(d.join("cams.json"))
        .arg("--out")
        .arg(&moved)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let c = pganeus_io::open_capture(&moved).unwrap();
    assert_eq!(c.len(), 3);
    assert!(c.masks.is_some() && c.extra_masks.iter().any(|(n, _)| n == "toy"));
    assert_eq!(c.info.as_ref().and_then(|i| i.fps), Some(10.0));
    assert!(moved.join("animation.png").exists());
    // The object moves between frames, so the frames differ.
    assert_ne!(
        std::fs::read(&c.images[0]).unwrap(),
        std::fs::read(&c.images[2]).unwrap()
    );
    // With a scene and a fixed camera, the scene is rendered once and the object composited over it;
    // --reference-compositing traces both in every frame; --orbit turns the camera to a new view.
    let with_scene = |out: &str, extra: &[&str]| {
        bin()
            .arg("render")
            .arg("--trajectory")
            .arg(d.join("traj.json"))
            .arg("--scene")
            .arg(&run)
            .arg("--object")
            .arg(format!("toy={}", run.display()))
            .arg("--camera")
            .arg(d.join("cams.json"))
            .arg("--out")
            .arg(d.join(out))
            .args(extra)
            .output()
            .unwrap()
    };
    let o = with_scene("fast", &[]);
    assert!(o.status.success() && text(&o).contains("rendered once"), "{}", text(&o));
    let o = with_scene("reference", &["--reference-compositing"]);
    assert!(
        o.status.success() && !text(&o).contains("rendered once"),
        "{}",
        text(&o)
    );
    let o = with_scene("orbit", &["--orbit", "-40"]);
    assert!(o.status.success(), "{}", text(&o));
    for out in ["fast", "reference", "orbit"] {
        assert_eq!(pganeus_io::open_capture(&d.join(out)).unwrap().len(), 3, "{out}");
    }
    let cam =
        |out: &str| pganeus_io::read_cameras_npz(&d.join(out).join("cameras_sphere.npz"), 3).unwrap()[0].world_mat;
    assert_eq!(cam("fast"), cam("reference"));
    assert_ne!(cam("fast"), cam("orbit"));
    // The composed renderer's timings, one JSON line per figure.
    let o = bin()
        .arg("bench-compose")
        .arg("--scene")
        .arg(&run)
        .arg("--object")
        .arg(format!("toy={}", run.display()))
        .arg("--trajectory")
        .arg(d.join("traj.json"))
        .arg("--views")
        .arg(&capture)
        .arg("--window-only")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 9, "{}", text(&o));
    assert!(lines.iter().all(|l| l["rays_per_s"].as_f64().unwrap() > 0.0));
    // A body of the trajectory named wrongly is refused, naming the bodies.
    let o = bin()
        .arg("render")
        .arg("--trajectory")
        .arg(d.join("traj.json"))
        .arg("--object")
        .arg(format!("cup={}", run.display()))
        .arg("--camera")
        .arg(d.join("cams.json"))
        .arg("--out")
        .arg(d.join("moved2"))
        .output()
        .unwrap();
    assert!(
        !o.status.success() && text(&o).contains("no body named \"cup\""),
        "{}",
        text(&o)
    );
    // The zero level as a mesh, simplified, and as points with the field's normals.
    let o = bin()
        .arg("mesh")
        .arg(&run)
        .args([
            "--res",
            "48",
            "--largest-piece",
            "--faces",
            "400",
            "--point-count",
            "300",
            "--out",
        ])
        .arg(d.join("zero.ply"))
        .arg("--points")
        .arg(d.join("zero_points.ply"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let m = pganeus_io::read_ply(&d.join("zero.ply")).unwrap();
    assert!(
        !m.mesh.faces.is_empty() && m.mesh.faces.len() <= 400,
        "{} faces",
        m.mesh.faces.len()
    );
    let p = pganeus_io::read_ply(&d.join("zero_points.ply")).unwrap();
    let normals = p.normals.expect("points come with normals");
    assert!(p.mesh.vertices.len() > 100 && p.mesh.vertices.len() <= 300);
    assert!(normals
        .iter()
        .all(|n| ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-4));
    // Switching render (Eq. 3–4): the run as both poses, A turned over about x
    // into B. A camera below B's board is camera 1 moved by p_b = R p_a + T, so
    // it renders camera 1's image through the other field.
    let a_to_b = geom::Pose::new(
        geom::Quat::exp(geom::Vec3::new(std::f64::consts::PI, 0.0, 0.0)),
        geom::Vec3::new(0.01, -0.02, 0.0),
    );
    let doc = serde_json::json!({"q_1to2": a_to_b.q.to_array_re(), "T_1to2": a_to_b.t.to_array()});
    std::fs::write(d.join("transform.json"), doc.to_string()).unwrap();
    let mut below = geom::Camera::from_world_mat(&cams[1].world_mat, 48, 36).unwrap();
    below.world_to_cam = below.world_to_cam.compose(&a_to_b.inverse());
    assert!(below.center().z < 0.0);
    let above = geom::Camera::from_world_mat(&cams[1].world_mat, 48, 36).unwrap();
    let json = serde_json::json!([
        {"width": 48, "height": 36, "world_mat": below.world_mat()},
        {"width": 48, "height": 36, "world_mat": above.world_mat()},
    ]);
    std::fs::write(d.join("cams_switch.json"), json.to_string()).unwrap();
    let out3 = d.join("renders3");
    let o = bin()
        .arg("render")
        .arg(&run)
        .args(["--other".as_ref(), run.as_os_str(), "--transform".as_ref()])
        .arg(d.join("transform.json"))
        .arg("--camera")
        .arg(d.join("cams_switch.json"))
        .arg("--out")
        .arg(&out3)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("cam_000: rendered by the other field"),
        "{}",
        text(&o)
    );
    for cam in ["cam_000.png", "cam_001.png"] {
        let (x, y) = (
            pganeus_io::read_png(&out3.join("rgb").join(cam)).unwrap(),
            pganeus_io::read_png(&out.join("rgb").join("001.png")).unwrap(),
        );
        let worst = x.data.iter().zip(&y.data).map(|(p, q)| p.abs_diff(*q)).max().unwrap();
        assert!(worst <= 1, "{cam}: differs from camera 1 by {worst}/255");
    }
    // A truncated checkpoint is a clear error.
    let ck = run.join("checkpoint.safetensors");
    let bytes = std::fs::read(&ck).unwrap();
    std::fs::write(&ck, &bytes[..bytes.len() - 100]).unwrap();
    let o = bin()
        .arg("render")
        .arg(&run)
        .arg("--views")
        .arg(&capture)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        !o.status.success() && text(&o).contains("checkpoint.safetensors") && text(&o).contains("truncated"),
        "{}",
        text(&o)
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn train_refuses_bad_captures_before_training() {
    let d = scratch("bad-capture");
    let capture = tiny_capture(&d);
    let cams = pganeus_io::read_cameras_npz(&capture.join("cameras_sphere.npz"), 6).unwrap();
    let try_train = |cap: &Path| {
        bin()
            .arg("train")
            .arg(cap)
            .arg("--out")
            .arg(d.join("run-bad"))
            .args(["--iterations", "5"])
            .output()
            .unwrap()
    };
    // A non-invertible camera (a zero row in world_mat) → named.
    let mut bad = cams.clone();
    bad[3].world_mat[1] = [0.0; 4];
    let mut arrays = Vec::new();
    for (i, c) in bad.iter().enumerate() {
        arrays.push((
            format!("world_mat_{i}"),
            pganeus_io::NpyArray::f64(vec![4, 4], c.world_mat.iter().flatten().copied().collect()),
        ));
        arrays.push((
            format!("scale_mat_{i}"),
            pganeus_io::NpyArray::f64(vec![4, 4], c.scale_mat.iter().flatten().copied().collect()),
        ));
    }
    let refs: Vec<(&str, &pganeus_io::NpyArray)> = arrays.iter().map(|(n, a)| (n.as_str(), a)).collect();
    pganeus_io::write_npz(&capture.join("cameras_sphere.npz"), &refs).unwrap();
    let o = try_train(&capture);
    assert!(!o.status.success() && text(&o).contains("world_mat_3"), "{}", text(&o));
    // A missing entry → named.
    pganeus_io::write_npz(&capture.join("cameras_sphere.npz"), &refs[..refs.len() - 2]).unwrap();
    let o = try_train(&capture);
    assert!(!o.status.success() && text(&o).contains("world_mat_5"), "{}", text(&o));
    pganeus_io::write_cameras_npz(&capture.join("cameras_sphere.npz"), &cams).unwrap();
    // A mask of another size → named.
    let mask = capture.join("mask").join("002.png");
    pganeus_io::write_png(&mask, &pganeus_io::Image::new(10, 10, 1)).unwrap();
    let o = try_train(&capture);
    assert!(!o.status.success() && text(&o).contains("002.png"), "{}", text(&o));
    assert!(
        !d.join("run-bad").join("checkpoint.safetensors").exists(),
        "nothing trained"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// `scenes/cup_house.obj` moved by `f` (an OBJ with the same faces).
fn moved_cup(f: impl Fn([f64; 3]) -> [f64; 3]) -> String {
    testkit::moved_obj(
        &std::fs::read_to_string(repo().join("scenes/cup_house.obj")).unwrap(),
        f,
    )
}

#[test]
fn mesh_tools_merge_compare_and_bake() {
    let d = scratch("mesh-tools");
    // The cup upright (cavity on the board) and turned over about x (on its roof's apex).
    std::fs::write(d.join("a.obj"), moved_cup(|p| [p[0] + 0.01, p[1], p[2] + 0.02])).unwrap();
    std::fs::write(d.join("b.obj"), moved_cup(|p| [p[0], -p[1] + 0.02, -p[2] + 0.035])).unwrap();
    let out = d.join("merged");
    let o = bin()
        .arg("merge")
        .arg(d.join("a.obj"))
        .arg(d.join("b.obj"))
        .args(["--res", "96", "--faces", "3000", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("transform.json")).unwrap()).unwrap();
    assert!(t["residual"].as_f64().unwrap() < 1e-4, "{t}");
    // Block 60 × 50 × 40 mm, roof 15 mm high, cavity 44 × 34 × 24 mm: 99.1 cm³.
    let volume = t["object"]["volume_m3"].as_f64().unwrap();
    assert!((volume / 9.91e-5 - 1.0).abs() < 0.03, "{t}");
    let o = bin()
        .arg("compare-mesh")
        .arg(out.join("merged.ply"))
        .arg(d.join("b.obj"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let m: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // The cup is 8.6 cm across: within 1 % of that, and nearly the same volume.
    assert!(m["chamfer_mean"].as_f64().unwrap() < 8.6e-4, "{m}");
    assert!(m["volume_iou"].as_f64().unwrap() > 0.95, "{m}");
    let o = bin()
        .arg("bake")
        .arg(out.join("merged.ply"))
        .args(["--res", "24", "--out"])
        .arg(d.join("cup.grid"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(d.join("cup.grid").exists());

    // A known transform (from markers, say) used as given: written back unchanged, residual checked.
    let known = serde_json::json!({"q_1to2": [0.0, 1.0, 0.0, 0.0], "T_1to2": [-0.01, 0.02, 0.055]});
    std::fs::write(d.join("known.json"), known.to_string()).unwrap();
    let o = bin()
        .current_dir(&d)
        .args([
            "merge",
            "a.obj",
            "b.obj",
            "--res",
            "64",
            "--start",
            "known.json",
            "--no-refine",
            "--out",
            "given",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("given/transform.json")).unwrap()).unwrap();
    assert_eq!(t["T_1to2"], known["T_1to2"], "{t}");
    assert_eq!(t["icp_iterations"], 0, "{t}");
    // The inputs relative to the merge's folder: the tree reads the same from any working directory.
    assert_eq!(
        (t["a"].as_str(), t["b"].as_str()),
        (Some("../a.obj"), Some("../b.obj")),
        "{t}"
    );
    assert!(t["residual"].as_f64().unwrap() < 1e-4, "{t}");

    // Bad input: an open mesh (the last face gone) and an empty one, named in the message;
    // a failed merge leaves the earlier output alone.
    let cup = moved_cup(|p| p);
    let open = &cup[..cup.trim_end().rfind("\nf ").unwrap()];
    std::fs::write(d.join("open.obj"), open).unwrap();
    std::fs::write(d.join("empty.obj"), "# nothing\n").unwrap();
    let before = std::fs::read(out.join("merged.ply")).unwrap();
    for (args, needle) in [
        (vec!["merge", "open.obj", "b.obj", "--out", "merged"], "open.obj"),
        (vec!["merge", "a.obj", "empty.obj", "--out", "merged"], "empty.obj"),
        (vec!["compare-mesh", "empty.obj", "b.obj"], "empty.obj"),
        (vec!["bake", "open.obj", "--out", "open.grid"], "open.obj"),
    ] {
        let o = bin().current_dir(&d).args(&args).output().unwrap();
        let msg = text(&o);
        assert!(!o.status.success() && msg.contains(needle), "{args:?}: {msg}");
    }
    assert_eq!(std::fs::read(out.join("merged.ply")).unwrap(), before);
    assert!(!d.join("open.grid").exists());
    // compare-mesh works on an open mesh, but says why there is no volume IoU.
    let o = bin()
        .current_dir(&d)
        .args(["compare-mesh", "open.obj", "b.obj"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("open.obj") && text(&o).contains("\"volume_iou\": null"),
        "{}",
        text(&o)
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// A scene field, tiny but real: the board plane start and a small background field.
const TINY_SCENE_TRAIN: &str = r#"
iterations = 600
batch_rays = 512
steps_per_ray = 256
max_samples_per_ray = 32
occupancy_res = 32
occupancy_warmup = 100
anneal_end = 100
level_every = 25
checkpoint_every = 600
[field.grid]
levels = 10
log2_table_size = 15
max_resolution = 512
[field.background]
samples = 12
[field.background.grid]
levels = 4
log2_table_size = 12
max_resolution = 64
"#;

/// The tiny tabletop scene run trained into a clean surface (the same checks as `neus`'s backdrop test, which
/// trains its library twin; this run is the tabletop's): the board where it is, the wall standing, sparse
/// occupancy, no fog. Before the scene kind (a sphere start, a constant colour behind it) such a capture gave
/// a fog filling most of the sphere.
fn board_and_wall_stand(run: &Path) {
    let f = neus::checkpoint::load_field(&run.join("checkpoint.safetensors")).unwrap();
    let h = testkit::TabletopHeights::measure(|x, y| f.field.surface_height(f.centre, f.radius, x, y, -0.05, 0.2));
    let (median, worst) = h.board_error();
    // The last two log lines (steps 550 and 600): occupancy and the batch PSNR.
    let log = std::fs::read_to_string(run.join("log.jsonl")).unwrap();
    let lines: Vec<serde_json::Value> = log
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|l| l["psnr"].is_number() && l["occupied"].is_number())
        .collect();
    let last = &lines[lines.len() - 2..];
    let occupied = last[1]["occupied"].as_f64().unwrap();
    let psnr = last.iter().map(|l| l["psnr"].as_f64().unwrap()).sum::<f64>() / 2.0;
    eprintln!(
        "scene run: occupied {occupied:.3}, batch PSNR {psnr:.1} dB, {}",
        h.in_mm()
    );
    // Measured: the wall's top 71–76 mm; painted onto the board it is below 10 mm.
    for w in &h.wall {
        assert!((w - 0.07).abs() < 0.015, "the wall's top at {:.1} mm, not 70", w * 1e3);
    }
    // Measured: median 1.9 mm, worst 2.4 mm (at 96×72 a pixel spans ~13 mm of the board).
    assert!(median < 0.003, "board height off by {:.1} mm (median)", median * 1e3);
    assert!(worst < 0.005, "board height off by {:.1} mm (worst)", worst * 1e3);
    // Empty space is known to be empty (measured 0.104; a fog fills most of the grid).
    assert!(occupied < 0.2, "occupancy {occupied:.3}");
    assert!(psnr > 20.0, "batch PSNR {psnr:.1} dB");
}

/// A toy sliding on the board (not reaching the wall), against `scene` shapes.
fn slide_scene(scene: &str) -> String {
    format!(
        r#"
[sim]
fps = 30
frames = 30
substeps = 20
[contact]
restitution = 0.5
friction = 0.25
{scene}
[[body]]
name = "toy"
mass = 0.08
t = [-0.15, -0.08, 0.0181]
v = [0.7, 0.05, 0.0]
omega = [0.0, 0.0, 1.5]
contact_points = 500
[body.shape]
shape = "rounded_box"
half = [0.03, 0.022, 0.018]
radius = 0.005
"#
    )
}

/// `train --kind` defaults to scene for the synth background capture (capture.json says so), the preview is
/// cut at the unit sphere and compares with the true scene, `bake` of the run covers the board region with the
/// floor below it, and the simulator reads the grid.
#[test]
#[ignore = "slow: a scene trained, previewed against the true scene, baked and simulated on, ~37 s"]
fn scene_train_bake_and_simulate_on_the_reconstruction() {
    let d = scratch("scene");
    tiny_dataset(&d, 96, 72, 16);
    std::fs::write(d.join("tiny.toml"), TINY_SCENE_TRAIN).unwrap();
    let run = d.join("run");
    let o = bin()
        .arg("train")
        .arg(d.join("data/background"))
        .arg("--out")
        .arg(&run)
        .arg("--config")
        .arg(d.join("tiny.toml"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("training the scene field (capture.json)"),
        "{}",
        text(&o)
    );
    let cfg = std::fs::read_to_string(run.join("config.toml")).unwrap();
    assert!(
        cfg.contains("kind = \"scene\"") && cfg.contains("init = \"board\""),
        "{cfg}"
    );
    board_and_wall_stand(&run);
    // The preview is cut at the unit sphere and compares with the true scene over the board.
    let o = bin()
        .arg("compare-mesh")
        .arg(run.join("preview.ply"))
        .arg("--truth")
        .arg(d.join("data/truth.json"))
        .args(["--capture", "background"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let cmp: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let chamfer = cmp["chamfer_mean"].as_f64().unwrap();
    eprintln!("scene preview: Chamfer {:.2} mm to the true scene", chamfer * 1e3);
    // Measured 3.4 mm with the wall standing (4.5 mm when it was painted on the board); a fog is hundreds of millimetres off.
    assert!(chamfer < 0.01, "preview Chamfer {chamfer}");

    let grid = d.join("scene.sdf");
    let o = bin().arg("bake").arg(&run).arg("--out").arg(&grid).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    // A scene's planes are made exact by default: the board (its normal up) among them.
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.contains("planes: ") && said.contains(", 1.000)·x = "), "{said}");
    // `--no-planes` only blurs: another grid, and no planes said.
    let blurred = d.join("scene_blurred.sdf");
    let o = bin()
        .arg("bake")
        .arg(&run)
        .arg("--no-planes")
        .arg("--out")
        .arg(&blurred)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(!String::from_utf8_lossy(&o.stdout).contains("planes: "), "{}", text(&o));
    assert_ne!(std::fs::read(&blurred).unwrap(), std::fs::read(&grid).unwrap());
    let g = sim::sdf::SdfGrid::load(&grid).unwrap();
    let top = g.max_corner();
    // The board region: the sphere's square (±0.45 m) in x, y; in z from 10 % of its radius (4.5 cm) below the
    // board to as far above the highest reconstructed surface, not the whole cube (±0.45 m).
    assert!(
        g.origin()[0] < -0.4 && top[0] > 0.4,
        "grid x {} – {}",
        g.origin()[0],
        top[0]
    );
    assert!(
        g.origin()[2] < -0.04 && g.origin()[2] > -0.1,
        "grid bottom {}",
        g.origin()[2]
    );
    assert!(top[2] > 0.045 && top[2] < 0.25, "grid top {}", top[2]);
    // Under the board is solid, however little was seen there.
    use sim::sdf::Sdf;
    for p in [[0.0, 0.0, -0.03], [-0.2, 0.1, -0.01], [0.1, -0.2, -0.04]] {
        let d: f64 = g.distance_local(geom::Vec3::<f64>::cst(p));
        assert!(d < 0.0, "{p:?} below the board has distance {d}");
    }
    // The wall (a 4 cm thick box up to 7 cm) is solid in the grid, the air beside it is not.
    let inside: f64 = g.distance_local(geom::Vec3::<f64>::cst([0.22, 0.0, 0.04]));
    let beside: f64 = g.distance_local(geom::Vec3::<f64>::cst([0.1, 0.0, 0.04]));
    assert!(inside < 0.0 && beside > 0.02, "wall {inside}, beside it {beside}");

    // The simulator reads it: a toy sliding on the reconstructed board stays on it at its resting height.
    let f = d.join("baked.toml");
    std::fs::write(
        &f,
        slide_scene(&format!(
            "[[scene]]\nshape = \"grid\"\nfile = {:?}\n",
            grid.display().to_string()
        )),
    )
    .unwrap();
    let out = d.join("baked.json");
    let o = bin()
        .args(["simulate", "--scene"])
        .arg(&f)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let traj = pganeus_io::read_trajectory(&out).unwrap();
    let (worst, frame) = traj.bodies[0]
        .poses
        .iter()
        .enumerate()
        .map(|(k, p)| ((p.t[2] - 0.018).abs(), k))
        .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
    eprintln!(
        "toy on the baked scene: height off by at most {:.1} mm (frame {frame})",
        worst * 1e3
    );
    // Measured 3.2 mm; at 96×72 a pixel spans 13 mm of the board and the reconstructed board is within ~4 mm of z = 0.
    assert!(
        worst < 0.005,
        "frame {frame}: the toy's centre {:.1} mm off its resting height",
        worst * 1e3
    );
    let _ = std::fs::remove_dir_all(&d);
}
