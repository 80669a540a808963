//! `pganeus fit` with several bodies, end to end on a CI-sized video (96×72,
//! 8 frames): three balls (one untrained sphere field saved as a run, so
//! nothing is trained here) on a board (an untrained board field as the scene run): one rolls
//! into a second at rest, which it knocks on; a third is tossed apart from
//! them. `simulate` moves them with pair values unlike the board's,
//! `render --trajectory` films them with a mask per body, and `fit` recovers
//! every body's poses, the collision frame and the launches from guesses
//! 8 mm and 10° off (the same code as two bodies: no special case).

use geom::{Camera, Intrinsics, Pose, Quat, Vec3};
use neus::checkpoint::save_field;
use neus::untrained_field::untrained_field;
use neus::{CaptureSubject, FieldInit};
use std::process::{Command, Output};

mod common;
use common::{bin, text};

fn run_ok(cmd: &mut Command) -> Output {
    let o = cmd.output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    o
}

/// 96×72, looking down at the three balls from the front.
fn camera() -> Camera<f64> {
    let (w, h) = (96, 72);
    let k = Intrinsics {
        fx: 1.2 * w as f64,
        fy: 1.2 * w as f64,
        cx: 0.5 * w as f64,
        cy: 0.5 * h as f64,
        skew: 0.0,
    };
    Camera::look_at(
        Vec3::new(-0.02, -0.36, 0.3),
        Vec3::new(-0.02, 0.03, 0.02),
        Vec3::new(0.0, 0.0, 1.0),
        k,
        w,
        h,
    )
}

const SMALL_FIT: &str = r#"
launch_frames = 3
pga_multi_start = false
[first_pose]
iterations = 40
rays_per_step = 192
[ga]
hypotheses = false
[ga.pose]
iterations = 15
rays_per_step = 192
lr_translation = 0.001
lr_rotation = 0.01
[pga]
iterations = 25
"#;

const NAMES: [&str; 3] = ["rolling", "struck", "tossed"];

#[test]
fn fit_recovers_three_balls_one_knocking_another() {
    let d = testkit::scratch_dir("cli", "fit_bodies");
    let scene = d.join("scene");
    let ball = d.join("ball");
    std::fs::create_dir_all(&scene).unwrap();
    std::fs::create_dir_all(&ball).unwrap();
    let mut board = untrained_field(FieldInit::Board, Vec3::new(0.0, 0.0, 0.05), 0.3, 7);
    board.config.kind = CaptureSubject::Scene;
    board.capture = "background".into();
    save_field(&board, &scene.join("checkpoint.safetensors")).unwrap();
    let sphere = untrained_field(FieldInit::Sphere, Vec3::new(0.0, 0.0, 0.03), 0.06, 3);
    save_field(&sphere, &ball.join("checkpoint.safetensors")).unwrap();
    run_ok(
        bin()
            .arg("mesh")
            .arg(&ball)
            .arg("--out")
            .arg(d.join("ball.ply"))
            .args(["--res", "192"]),
    );
    let mesh = pganeus_io::read_mesh(&d.join("ball.ply")).unwrap();
    let com = sim::mass_properties(&mesh, 1.0).center_of_mass;
    let radius = mesh
        .vertices
        .iter()
        .map(|v| (Vec3::cst(*v) - com).norm())
        .fold(0.0, f64::max);
    // The scene file places the centre of mass: just above the board.
    let z = radius + 0.001;
    let scene_file = format!(
        r#"
[sim]
fps = 30
frames = 8
[contact]
restitution = 0.5
friction = 0.3
[[scene]]
shape = "plane"
[[body]]
name = "rolling"
mesh = "ball.ply"
density = 1000
t = [-0.16, 0.0, {z}]
v = [1.2, 0.0, 0.0]
[[body]]
name = "struck"
mesh = "ball.ply"
density = 1000
t = [0.0, 0.008, {z}]
[[body]]
name = "tossed"
mesh = "ball.ply"
density = 1000
t = [-0.02, 0.11, {z2}]
v = [-0.3, 0.0, 0.2]
[[pair]]
bodies = ["rolling", "struck"]
restitution = 0.85
friction = 0.15
"#,
        z2 = z + 0.05
    );
    std::fs::write(d.join("balls.toml"), scene_file).unwrap();
    run_ok(
        bin()
            .args(["simulate", "--scene"])
            .arg(d.join("balls.toml"))
            .arg("--out")
            .arg(d.join("truth.json")),
    );
    let truth = pganeus_io::read_trajectory(&d.join("truth.json")).unwrap();
    let cam = camera();
    let cams = serde_json::json!([{"width": cam.width, "height": cam.height, "world_mat": cam.world_mat()}]);
    std::fs::write(d.join("cams.json"), cams.to_string()).unwrap();
    let video = d.join("balls");
    let mut render = bin();
    render
        .args(["render", "--trajectory"])
        .arg(d.join("truth.json"))
        .arg("--scene")
        .arg(&scene)
        .arg("--camera")
        .arg(d.join("cams.json"))
        .arg("--out")
        .arg(&video);
    for n in NAMES {
        render.arg("--object").arg(format!("{n}={}", ball.display()));
    }
    run_ok(&mut render);

    // The frame the simulator first reports the two balls touching.
    let pair = &truth.contact.extra["pairs"][0];
    let touch = pair["contact"]
        .as_array()
        .unwrap()
        .iter()
        .position(|c| c.as_bool() == Some(true))
        .expect("the rolling ball reaches the struck one");
    let true_poses = |b: usize| -> Vec<Pose<f64>> {
        truth.bodies[b]
            .poses
            .iter()
            .map(|p| Pose::new(Quat::cst(p.q), Vec3::cst(p.t)))
            .collect()
    };
    // Guesses 8 mm and 10° off: p_frame0 = R(q) p_capture + t, with p_capture = p_body + com.
    let mut init = serde_json::Map::new();
    for (b, n) in NAMES.iter().enumerate() {
        let p0 = true_poses(b)[0];
        let off = Pose::new(
            Quat::exp(Vec3::new(0.0, 0.0, 10f64.to_radians())) * p0.q,
            p0.t + Vec3::new(0.006, -0.005, 0.0) * if b % 2 == 0 { 1.0 } else { -1.0 },
        );
        let t = off.t - off.q.rotate(com);
        init.insert(
            n.to_string(),
            serde_json::json!({"capture": "toy_b", "t": t.to_array(), "q": off.q.to_array_re()}),
        );
    }
    std::fs::write(d.join("init.json"), serde_json::Value::Object(init).to_string()).unwrap();
    std::fs::write(d.join("small.toml"), SMALL_FIT).unwrap();
    let out = d.join("fit");
    let mut fit = bin();
    fit.arg("fit")
        .arg(&video)
        .arg("--scene")
        .arg(&scene)
        .arg("--init")
        .arg(d.join("init.json"))
        .arg("--config")
        .arg(d.join("small.toml"))
        .arg("--out")
        .arg(&out);
    for n in NAMES {
        fit.arg("--object").arg(format!("{n}={}", ball.display()));
    }
    let t = std::time::Instant::now();
    let o = run_ok(&mut fit);
    eprintln!("{}\nfit took {:.1} s", text(&o), t.elapsed().as_secs_f64());
    for file in [
        "trajectory.json",
        "ga_tracked.json",
        "pga_tracked.json",
        "ga.json",
        "pga.json",
        "first_pose.json",
        "strip.png",
        "object_struck.ply",
        "render/007.png",
    ] {
        assert!(out.join(file).exists(), "{file} is missing");
    }
    // GA's poses put the collision within a frame of the simulator's report.
    let log = std::fs::read_to_string(out.join("log.jsonl")).unwrap();
    let found: Vec<u64> = log
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter_map(|v| v["first_contact"].as_u64())
        .collect();
    eprintln!("collision: frame {touch} (simulator), {found:?} (found)");
    assert!(
        found.iter().any(|&k| (k as i64 - touch as i64).abs() <= 1),
        "collision found in frames {found:?}, the simulator's is {touch}"
    );
    let fitted = pganeus_io::read_trajectory(&out.join("trajectory.json")).unwrap();
    for (b, n) in NAMES.iter().enumerate() {
        let body = fitted
            .bodies
            .iter()
            .find(|x| x.name == *n)
            .expect("every body in the output");
        let truth_b = true_poses(b);
        let errors: Vec<f64> = body
            .poses
            .iter()
            .zip(&truth_b)
            .map(|(p, t)| (Vec3::cst(p.t) - t.t).norm() * 1e3)
            .collect();
        let ious: Vec<f64> = body.extra["frames"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["iou"].as_f64().unwrap())
            .collect();
        let worst = errors.iter().cloned().fold(0.0, f64::max);
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        eprintln!(
            "{n}: position mm {errors:.1?}; IoU worst {:.3}; v0 {:?} (true {:?})",
            ious.iter().cloned().fold(1.0, f64::min),
            body.initial.v,
            truth.bodies[b].initial.v
        );
        // Measured (2026-11-25): rolling 2.2 mm on average (worst 6.3, the impact), struck 2.1 (4.0), tossed
        // 8.0 (12.3: a 14 px ball in flight, its depth along the line of sight from its silhouette's size);
        // IoU worst 0.90. Each body's bound leaves room for the pixel batches, not for a body lost, swapped
        // or stuck; accuracy at scale is measured on the two-body synth at 320×240 (README).
        let bound = [5.0, 5.0, 12.0][b];
        assert!(mean < bound, "{n}: {mean:.2} mm off on average (bound {bound} mm)");
        assert!(worst < 20.0, "{n}: worst frame {worst:.2} mm off");
        assert!(ious.iter().all(|&i| i > 0.75), "{n}: IoU {ious:?}");
    }
    let _ = std::fs::remove_dir_all(&d);
}
