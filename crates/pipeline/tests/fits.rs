//! The fit of one body and of several, end to end, in-process through `pipeline::fit` (the `pganeus fit`
//! command's contract, its arguments and exit codes, is tested in the CLI's tests). One test binary, so
//! that the two long tests share the two cores; both are in the slow tier (`cargo test -- --ignored`).

use geom::{Camera, Intrinsics, Vec3};
use neus::checkpoint::save_field;
use neus::untrained_field::untrained_field;
use neus::{CaptureSubject, FieldInit};
use pipeline::fit::{FitInputs, FitOutcome, FitRun, Stage};
use pipeline::render::RenderArgs;
use pipeline::{Quiet, Resume};
use recon::VideoFitConfig;
use std::path::{Path, PathBuf};

/// The bodies of the scene file `scene` simulated into the trajectory file `out` (what `pganeus simulate`
/// writes).
fn simulate(scene: &Path, out: &Path) -> pganeus_io::Trajectory {
    let s = scene_file::SceneFile::load(scene).unwrap();
    let w = &s.world;
    let traj = w.simulate(&w.params());
    let t = scene_file::trajectory_file(&s.name, w, &traj, sim::ENGINE, Default::default());
    pganeus_io::write_trajectory(out, &t).unwrap();
    pganeus_io::read_trajectory(out).unwrap()
}

/// The motion in `trajectory` filmed through the cameras of `cameras` into the capture `out`, each body
/// `NAME=DIR` of `objects` in the scene run `scene` (what `pganeus render --trajectory` writes).
fn film(trajectory: &Path, scene: &Path, objects: &[String], cameras: &Path, out: &Path) {
    let mut a = RenderArgs::new(out.to_path_buf());
    a.trajectory = Some(trajectory.to_path_buf());
    a.scene = Some(scene.to_path_buf());
    a.object = objects.to_vec();
    a.camera = Some(cameras.to_path_buf());
    pipeline::render::run(&a, &Quiet).unwrap();
}

/// The settings `text` over fit's defaults.
fn settings(text: &str) -> VideoFitConfig {
    pipeline::run_folder::settings_over(&VideoFitConfig::default(), text, "the test's settings").unwrap()
}

/// A whole fit of `inputs` with `config` into `out`, resumed where it stopped.
fn fit(inputs: &FitInputs, config: &VideoFitConfig, out: &Path) -> pipeline::Result<FitOutcome> {
    FitRun::open(inputs.clone(), config.clone(), out, Resume::Continue)?.run(&Stage::ALL, &Quiet)
}

/// A 96×72 video camera at `eye` looking at `target`, focal length `focal` image widths.
fn camera(focal: f64, eye: Vec3<f64>, target: Vec3<f64>) -> Camera<f64> {
    let (w, h) = (96, 72);
    let k = Intrinsics::centred(focal * w as f64, w, h);
    Camera::look_at(eye, target, Vec3::new(0.0, 0.0, 1.0), k, w, h)
}

/// `cam` as a `--camera` file in `d` (cams.json).
fn camera_file(d: &Path, cam: &Camera<f64>) -> PathBuf {
    let cams = serde_json::json!([{"width": cam.width, "height": cam.height, "world_mat": cam.world_mat()}]);
    let path = d.join("cams.json");
    std::fs::write(&path, cams.to_string()).unwrap();
    path
}

/// The runs both tests fit with, in `d`: an untrained board field as the scene run (`scene/`) and an
/// untrained sphere field as the ball's run (`ball/`), so nothing is trained here. Returns the ball's mesh:
/// loading the run as an object extracts its zero level once and caches it beside the checkpoint
/// (`ball/object_mesh.ply`), the body the simulator moves as `fit` builds it; `render` and `fit` find it
/// again there.
fn untrained_runs(d: &Path) -> (PathBuf, PathBuf, geom::TriMesh) {
    let scene = d.join("scene");
    let ball = d.join("ball");
    std::fs::create_dir_all(&scene).unwrap();
    std::fs::create_dir_all(&ball).unwrap();
    let mut board = untrained_field(FieldInit::Board, Vec3::new(0.0, 0.0, 0.05), 0.3, 7);
    board.config.kind = CaptureSubject::Scene;
    board.capture = PathBuf::from("background");
    save_field(&board, &scene.join("checkpoint.safetensors")).unwrap();
    let sphere = untrained_field(FieldInit::Sphere, Vec3::new(0.0, 0.0, 0.03), 0.06, 3);
    save_field(&sphere, &ball.join("checkpoint.safetensors")).unwrap();
    neus::ObjectModel::load(&ball).unwrap();
    let mesh = pganeus_io::read_mesh(&ball.join("object_mesh.ply")).unwrap();
    (scene, ball, mesh)
}

mod one_body {
    //! The fit of one body end to end on a CI-sized video: a ball (an untrained sphere field saved as a
    //! run, so nothing is trained here) tossed onto a board (an untrained board field as the scene run),
    //! simulated, filmed, then fitted from a guess 1 cm and 10° off; and the bad inputs a fit must refuse
    //! without writing anything.

    use geom::{Camera, Pose, Quat, Vec3};
    use pipeline::fit::{FitInputs, FitRun, Stage};
    use pipeline::{Quiet, Resume};
    use recon::VideoFitConfig;
    use std::path::{Path, PathBuf};

    use super::{camera_file, film, fit, settings, simulate, untrained_runs};

    /// The video's camera: 96×72, looking down at the toss from the front.
    fn camera() -> Camera<f64> {
        super::camera(1.1, Vec3::new(0.05, -0.33, 0.25), Vec3::new(0.05, 0.01, 0.02))
    }

    struct Fixture {
        d: PathBuf,
        scene: PathBuf,
        ball: PathBuf,
        video: PathBuf,
        truth: pganeus_io::Trajectory,
        /// Where the ball's body frame sat in its capture (the sphere's centre of mass).
        com: Vec3<f64>,
    }

    /// A scene run, a ball run, the ball's simulated toss and its video.
    fn fixture(d: &Path) -> Fixture {
        let (scene, ball, mesh) = untrained_runs(d);
        let com = sim::mass_properties(&mesh, 1.0).center_of_mass;
        let scene_file = r#"
[sim]
fps = 30
frames = 10
[contact]
restitution = 0.5
friction = 0.3
[[scene]]
shape = "plane"
[[body]]
name = "ball"
mesh = "ball/object_mesh.ply"
density = 1000
t = [-0.04, 0.0, 0.06]
v = [0.6, 0.1, 0.3]
omega = [0.0, 4.0, 0.0]
"#;
        std::fs::write(d.join("toss.toml"), scene_file).unwrap();
        let truth = simulate(&d.join("toss.toml"), &d.join("truth.json"));
        let cams = camera_file(d, &camera());
        let video = d.join("toss");
        film(
            &d.join("truth.json"),
            &scene,
            &[format!("ball={}", ball.display())],
            &cams,
            &video,
        );
        Fixture {
            d: d.to_path_buf(),
            scene,
            ball,
            video,
            truth,
            com,
        }
    }

    /// An `init.json` for `name` placing the ball's capture pose at `pose` in frame 0 (body frame → world).
    fn init_for(name: &str, pose: Pose<f64>, com: Vec3<f64>) -> String {
        // p_frame0 = R(q) p_capture + t with p_capture = p_body + com.
        let t = pose.t - pose.q.rotate(com);
        serde_json::json!({name: {"capture": "toy_b", "t": t.to_array(), "q": pose.q.to_array_re()}}).to_string()
    }

    const SMALL_FIT: &str = r#"
launch_frames = 3
rounds = 1
pga_multi_start = false
[first_pose]
iterations = 60
rays_per_step = 256
[pa]
iterations = 40
rays_per_frame = 128
window_steps = 10
[ga]
contact_points = 8
[ga.pose]
iterations = 25
rays_per_step = 256
lr_translation = 0.001
lr_rotation = 0.01
[ga.end_search]
screened = 4
screen_iterations = 10
refined = 2
twin_iterations = 20
[ga.end_search.refine]
iterations = 40
rays_per_step = 256
[pga]
iterations = 20
[auto_init]
screened = 4
screen_iterations = 10
refined = 2
twin_iterations = 20
[auto_init.refine]
iterations = 40
rays_per_step = 256
"#;

    /// The fit of `video` with the ball's object `ball` from the guess `init`.
    fn inputs(f: &Fixture, video: &Path, ball: &Path, init: &Path) -> FitInputs {
        let mut inputs = FitInputs::new(video, &f.scene, [("ball", ball)]);
        inputs.init = init.to_path_buf();
        inputs
    }

    #[test]
    #[ignore = "slow: a ball's toss fitted end to end (first pose, PA, GA, PGA, value ranges), resumed, and 8 bad inputs refused, ~150 s"]
    fn fit_recovers_a_toss_and_refuses_bad_inputs() {
        let d = testkit::scratch_dir("cli", "fit");
        let f = fixture(&d);
        std::fs::write(d.join("small.toml"), SMALL_FIT).unwrap();
        let truth_poses: Vec<Pose<f64>> = f.truth.bodies[0]
            .poses
            .iter()
            .map(|p| Pose::new(Quat::cst(p.q), Vec3::cst(p.t)))
            .collect();
        // A guess 1 cm and 10° off, as two marker detections give.
        let p0 = truth_poses[0];
        let off = Pose::new(
            Quat::exp(Vec3::new(0.0, 0.0, 10f64.to_radians())) * p0.q,
            p0.t + Vec3::new(0.008, -0.006, 0.0),
        );
        std::fs::write(d.join("init.json"), init_for("ball", off, f.com)).unwrap();
        let small = settings(SMALL_FIT);
        let toss = inputs(&f, &f.video, &f.ball, &d.join("init.json"));
        let out = d.join("fit");
        let t = std::time::Instant::now();
        let outcome = fit(&toss, &small, &out).unwrap();
        eprintln!("{}\nfit took {:.1} s", outcome.summary, t.elapsed().as_secs_f64());
        // The outcome holds every stage's result: the first pose, PA's world, GA's poses, the kept world and
        // where each reported pose came from.
        assert_eq!(outcome.first_poses.len(), 1);
        assert!(outcome.pa.is_some());
        assert_eq!(outcome.ga.as_ref().map(|g| g[0].len()), Some(10));
        assert_eq!(outcome.reported.as_ref().map(|r| r[0].len()), Some(10));
        assert_eq!(
            outcome.trajectory.as_deref(),
            Some(out.join("trajectory.json").as_path())
        );
        for file in [
            "trajectory.json",
            "pa.json",
            "ga.json",
            "pga.json",
            "first_pose.json",
            "config.toml",
            "log.jsonl",
            "strip.png",
            "animation.png",
            "object.ply",
            "render/009.png",
        ] {
            assert!(out.join(file).exists(), "{file} is missing");
        }
        let fitted = pganeus_io::read_trajectory(&out.join("trajectory.json")).unwrap();
        let b = &fitted.bodies[0];
        let reference = &b.extra["object"]["reference"];
        assert_eq!(reference["capture"], "toy_b");
        let errors: Vec<f64> = b
            .poses
            .iter()
            .zip(&truth_poses)
            .map(|(p, truth)| (Vec3::cst(p.t) - truth.t).norm())
            .collect();
        for (k, e) in errors.iter().enumerate() {
            eprintln!("frame {k}: {:.2} mm", e * 1e3);
        }
        let worst = errors.iter().cloned().fold(0.0, f64::max);
        let sum: f64 = errors.iter().sum();
        let ious: Vec<f64> = fitted.extra["frames"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["iou"].as_f64().unwrap())
            .collect();
        eprintln!(
            "fit vs truth: mean {:.2} mm, worst {:.2} mm; IoU worst {:.3}; v0 {:?} (true {:?})",
            sum / b.poses.len() as f64 * 1e3,
            worst * 1e3,
            ious.iter().cloned().fold(1.0, f64::min),
            b.initial.v,
            f.truth.bodies[0].initial.v
        );
        // Measured (2026-11-24): mean 2.2 mm, worst 4.2 mm (the last frames, rolling, where depth comes from the
        // physics alone: the ball is 14 px wide), IoU worst 0.88, v0 8 mm/s off. With the chromaticity term in
        // GA: the last frame 6.0 mm. With GA holding the ball on the board only where a contact is known, and
        // PGA weighing depth least (2026-11-26): mean 0.9 mm, worst 2.8 mm (frame 8), IoU worst 0.98, v0 5 mm/s
        // off. Each bound leaves room for the random pixel batches, not for a fit that lost the ball (before
        // the mask-centred starts: 24 mm).
        assert!(worst < 0.005, "worst frame {:.2} mm off", worst * 1e3);
        assert!(
            sum / (errors.len() as f64) < 0.002,
            "mean {:.2} mm off",
            sum / errors.len() as f64 * 1e3
        );
        assert!(ious.iter().all(|&i| i > 0.9), "IoU {ious:?}");
        let dv = (Vec3::<f64>::cst(b.initial.v) - Vec3::cst(f.truth.bodies[0].initial.v)).norm();
        assert!(dv < 0.03, "v0 {:?} is {dv:.3} m/s off", b.initial.v);
        // The launch fitted to the ball's flight alone (before it lands), beside the kept one.
        let flight = &b.extra["flight"];
        let fv: [f64; 3] = serde_json::from_value(flight["v0"].clone()).expect("the flight's launch");
        let fdv = (Vec3::<f64>::cst(fv) - Vec3::cst(f.truth.bodies[0].initial.v)).norm();
        eprintln!(
            "the flight's launch ({} frames, the kept launch bent: {}): {fdv:.4} m/s off",
            flight["frames"], flight["bent"]
        );
        // Measured 0.004 m/s (the kept launch 0.003).
        assert!(fdv < 0.02, "the flight's v0 {fv:?} is {fdv:.3} m/s off");
        // Each contact value with the range the motion cannot tell from it: the fitted value inside, and the
        // friction (the ball hardly slides in ten frames: it stays near its start, 0.5, against the true 0.3)
        // left open to the truth.
        let range = |key: &str| -> [f64; 2] {
            let r = fitted.contact.extra[key]
                .as_array()
                .unwrap_or_else(|| panic!("no {key}"));
            [r[0].as_f64().unwrap(), r[1].as_f64().unwrap()]
        };
        let (kn, mu) = (range("restitution_range"), range("friction_range"));
        // How long the fitted motion converges in its step size: the ball flies predictably until it lands.
        let horizon = &fitted.extra["horizon"];
        let predictable = horizon["predictable_frames"].as_u64().expect("the horizon") as usize;
        let spread = horizon["step_spread_px"].as_array().expect("the spread per frame");
        assert_eq!(spread.len(), fitted.bodies[0].poses.len());
        assert!(predictable >= 3, "{horizon}");
        assert!(
            spread[..predictable]
                .iter()
                .all(|d| d.as_f64().unwrap() <= recon::HORIZON_PX),
            "{horizon}"
        );
        eprintln!(
            "restitution {} in {kn:?}, friction {} in {mu:?}",
            fitted.contact.restitution, fitted.contact.friction
        );
        assert!(kn[0] <= fitted.contact.restitution && fitted.contact.restitution <= kn[1]);
        // The world in the outcome is the one the file reports.
        let world = outcome.world.as_ref().expect("the kept world");
        assert_eq!(world.scene_contact[0].restitution, fitted.contact.restitution);
        assert_eq!(world.initial[0].v.to_array(), fitted.bodies[0].initial.v);
        assert!(mu[0] <= fitted.contact.friction && fitted.contact.friction <= mu[1]);
        assert!(
            mu[0] <= f.truth.contact.friction && f.truth.contact.friction <= mu[1],
            "friction {mu:?}"
        );

        // Run again: the finished fit is left as it is.
        let again = fit(&toss, &small, &out).unwrap();
        assert!(
            again.finished_before && again.summary.contains("already finished"),
            "{}",
            again.summary
        );
        // A fit stopped before its end (no trajectory.json yet) resumes: every stage is read back, nothing
        // refitted.
        std::fs::remove_file(out.join("trajectory.json")).unwrap();
        let again = fit(&toss, &small, &out).unwrap();
        for file in ["first_pose.json", "pa.json", "ga.json"] {
            assert!(
                again.read_back.contains(&out.join(file)),
                "{file}: {:?}",
                again.read_back
            );
        }
        // What it finishes with is the uninterrupted fit's, bit for bit (the stage files read back exactly).
        let resumed = pganeus_io::read_trajectory(&out.join("trajectory.json")).unwrap();
        assert_eq!(resumed.bodies[0].initial, fitted.bodies[0].initial);
        assert_eq!(resumed.bodies[0].poses, fitted.bodies[0].poses);
        assert_eq!(
            (resumed.contact.restitution, resumed.contact.friction),
            (fitted.contact.restitution, fitted.contact.friction)
        );
        for key in ["restitution_range", "friction_range"] {
            assert_eq!(resumed.contact.extra[key], fitted.contact.extra[key], "{key}");
        }
        assert_eq!(resumed.bodies[0].extra["flight"], fitted.bodies[0].extra["flight"]);
        // Other settings into the same folder are refused unless the fit starts over.
        let other = settings(&SMALL_FIT.replace("rounds = 1", "rounds = 2"));
        match FitRun::open(toss.clone(), other, &out, Resume::Continue) {
            Err(e @ pipeline::Error::OutputTaken(_)) => assert!(e.to_string().contains("--force"), "{e}"),
            Err(e) => panic!("refused for another reason: {}", e.chain()),
            Ok(_) => panic!("another fit's settings accepted into {}", out.display()),
        }

        first_pose_without_a_guess(&f, &truth_poses[0]);
        refusals(&f, &small);
        let _ = std::fs::remove_dir_all(&d);
    }

    /// `--init auto`: the first stage alone finds the ball in flight (its silhouette's size gives the depth).
    fn first_pose_without_a_guess(f: &Fixture, truth: &Pose<f64>) {
        let out = f.d.join("auto");
        let auto = inputs(f, &f.video, &f.ball, Path::new("auto"));
        let outcome = FitRun::open(auto, settings(SMALL_FIT), &out, Resume::Continue)
            .unwrap()
            .run(&[Stage::First], &Quiet)
            .unwrap();
        assert!(outcome.ga.is_none() && outcome.world.is_none());
        let found: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("first_pose.json")).unwrap()).unwrap();
        let t: Vec<f64> = found["t"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let e = (Vec3::new(t[0], t[1], t[2]) - truth.t).norm();
        eprintln!("--init auto: first pose {:.2} mm off", e * 1e3);
        let guess: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("init_auto.json")).unwrap()).unwrap();
        assert_eq!(guess["ball"]["capture"], "toy_b");
        assert!(e < 0.004, "--init auto: first pose {:.2} mm off", e * 1e3);
    }

    /// Each bad input: an error whose message has the needle, and no output folder.
    fn refusals(f: &Fixture, small: &VideoFitConfig) {
        let d = &f.d;
        let good_init = d.join("init.json");
        let refused = |name: &str, inputs: FitInputs, config: &VideoFitConfig, needle: &str| {
            let out = d.join(format!("refused_{name}"));
            let e = match fit(&inputs, config, &out) {
                Err(e) => e.chain(),
                Ok(_) => panic!("{name}: accepted"),
            };
            assert!(e.contains(needle), "{name}: {e}");
            assert!(!out.exists(), "{name}: wrote {}", out.display());
        };
        let expect = |name: &str, video: &Path, ball: &Path, init: &Path, needle: &str| {
            refused(name, inputs(f, video, ball, init), small, needle)
        };
        let object = f.ball.as_path();
        // A camera that moves.
        let moving = d.join("moving");
        testkit::copy_dir(&f.video, &moving);
        let npz = moving.join("cameras_sphere.npz");
        let mut cams = pganeus_io::read_cameras_npz(&npz, 10).unwrap();
        cams[4].world_mat[0][3] += 5.0;
        pganeus_io::write_cameras_npz(&npz, &cams).unwrap();
        expect("moving", &moving, object, &good_init, "fixed camera");
        // No mask folder for the body: one body's masks are computed from the frames and the scene, so the
        // inputs are accepted (the masks themselves are measured by `video_masks`'s tests).
        let unmasked = d.join("unmasked");
        testkit::copy_dir(&f.video, &unmasked);
        std::fs::remove_dir_all(unmasked.join("mask")).unwrap();
        std::fs::remove_dir_all(unmasked.join("mask_ball")).unwrap();
        FitRun::open(
            inputs(f, &unmasked, object, &good_init),
            small.clone(),
            d.join("unmasked_fit"),
            Resume::Continue,
        )
        .unwrap_or_else(|e| panic!("unmasked: {}", e.chain()));
        // Masks empty in every frame.
        let empty = d.join("empty");
        testkit::copy_dir(&f.video, &empty);
        for dir in ["mask", "mask_ball"] {
            for e in std::fs::read_dir(empty.join(dir)).unwrap() {
                let p = e.unwrap().path();
                let mut m = pganeus_io::read_png(&p).unwrap();
                m.data.iter_mut().for_each(|v| *v = 0);
                pganeus_io::write_png(&p, &m).unwrap();
            }
        }
        expect("empty", &empty, object, &good_init, "empty in every frame");
        // An object folder that is neither a merge nor a run.
        let nothing = d.join("nothing");
        std::fs::create_dir_all(&nothing).unwrap();
        expect("no_merge", &f.video, &nothing, &good_init, "neither a merge output");
        // A guess for a body the video has no mask for.
        let mut two: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&good_init).unwrap()).unwrap();
        two["cup"] = two["ball"].clone();
        std::fs::write(d.join("two.json"), two.to_string()).unwrap();
        expect("extra_guess", &f.video, object, &d.join("two.json"), "\"cup\"");
        // A guess whose object projects outside the image.
        let far = init_for("ball", Pose::from_translation(Vec3::new(3.0, 0.0, 0.03)), f.com);
        std::fs::write(d.join("far.json"), far).unwrap();
        expect("outside", &f.video, object, &d.join("far.json"), "outside the image");
        // Settings the simulator refuses: named, and nothing written (they were checked only after the
        // output folder was opened).
        let no_substeps = settings(&format!("{SMALL_FIT}\n[sim]\nsubsteps = 0\n"));
        refused(
            "settings",
            inputs(f, &f.video, object, &good_init),
            &no_substeps,
            "sim.substeps",
        );
    }
}

mod several_bodies {
    //! The fit of several bodies, end to end on a CI-sized video (96×72, 8 frames): three balls (one
    //! untrained sphere field saved as a run, so nothing is trained here) on a board (an untrained board
    //! field as the scene run): one rolls into a second at rest, which it knocks on; a third is tossed apart
    //! from them. The simulator moves them with pair values unlike the board's, the renderer films them with
    //! a mask per body, and the fit recovers every body's poses, the collision frame and the launches from
    //! guesses 8 mm and 10° off (the same code as two bodies: no special case).

    use geom::{Camera, Pose, Quat, Vec3};
    use pipeline::fit::FitInputs;

    use super::{camera_file, film, fit, settings, simulate, untrained_runs};

    /// 96×72, looking down at the three balls from the front.
    fn camera() -> Camera<f64> {
        super::camera(1.2, Vec3::new(-0.02, -0.36, 0.3), Vec3::new(-0.02, 0.03, 0.02))
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
[ranges]
steps = 11
iterations = 4
"#;

    const NAMES: [&str; 3] = ["rolling", "struck", "tossed"];

    #[test]
    #[ignore = "slow: three balls, one knocking another, fitted end to end by the collision schedule and resumed, ~120 s"]
    fn fit_recovers_three_balls_one_knocking_another() {
        let d = testkit::scratch_dir("cli", "fit_bodies");
        let (scene, ball, mesh) = untrained_runs(&d);
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
substeps = 40  # a converged reference: the fit starts at 10
[contact]
restitution = 0.5
friction = 0.3
[[scene]]
shape = "plane"
[[body]]
name = "rolling"
mesh = "ball/object_mesh.ply"
density = 1000
t = [-0.16, 0.0, {z}]
v = [1.2, 0.0, 0.0]
[[body]]
name = "struck"
mesh = "ball/object_mesh.ply"
density = 1000
t = [0.0, 0.008, {z}]
[[body]]
name = "tossed"
mesh = "ball/object_mesh.ply"
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
        let truth = simulate(&d.join("balls.toml"), &d.join("truth.json"));
        let cams = camera_file(&d, &camera());
        let video = d.join("balls");
        let objects: Vec<String> = NAMES.iter().map(|n| format!("{n}={}", ball.display())).collect();
        film(&d.join("truth.json"), &scene, &objects, &cams, &video);

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
        let small = settings(SMALL_FIT);
        let out = d.join("fit");
        let mut balls = FitInputs::new(&video, &scene, NAMES.map(|n| (n, ball.clone())));
        balls.init = d.join("init.json");
        // A video without a body's masks: what moves is found against the scene and split among the bodies,
        // which look alike here, so by where their guesses put them in the first frame, then followed; the
        // fit writes them out before its first stage.
        let unmasked = d.join("balls_unmasked");
        testkit::copy_dir(&video, &unmasked);
        std::fs::remove_dir_all(unmasked.join("mask_struck")).unwrap();
        let computed = d.join("fit_unmasked");
        pipeline::fit::FitRun::open(
            FitInputs {
                video: unmasked.clone(),
                ..balls.clone()
            },
            small.clone(),
            &computed,
            pipeline::Resume::Continue,
        )
        .unwrap()
        .run(&[pipeline::fit::Stage::First], &pipeline::Quiet)
        .unwrap();
        assert!(
            !computed.join("mask_rolling").exists(),
            "a body with its own masks keeps them"
        );
        for k in 0..8 {
            let name = format!("{k:03}.png");
            let found = pipeline::images::read_mask(&computed.join("mask_struck").join(&name)).unwrap();
            let truth = pipeline::images::read_mask(&video.join("mask_struck").join(&name)).unwrap();
            // The struck ball, not another: its true mask covered, and nothing far from it (a computed mask
            // takes every pixel a body touches: a ring of a pixel, a third of a ball this small).
            let near = geom::mask::dilate(&truth, 96, 2);
            let count = |m: &[bool]| m.iter().filter(|&&x| x).count() as f64;
            let covered = (0..truth.len()).filter(|&p| truth[p] && found[p]).count() as f64 / count(&truth);
            let inside = (0..found.len()).filter(|&p| found[p] && near[p]).count() as f64 / count(&found);
            eprintln!("struck, frame {k}: true mask covered {covered:.3}, found within 2 px of it {inside:.3}");
            assert!(
                covered > 0.95 && inside > 0.95,
                "struck, frame {k}: {covered:.3} of its true mask found, {inside:.3} of the found near it"
            );
        }
        let t = std::time::Instant::now();
        let outcome = fit(&balls, &small, &out).unwrap();
        eprintln!("{}\nfit took {:.1} s", outcome.summary, t.elapsed().as_secs_f64());
        assert_eq!(outcome.reported.as_ref().map(|r| r.len()), Some(3));
        for file in [
            "trajectory.json",
            "ga_tracked.json",
            "pga_tracked.json",
            "ga.json",
            "pga.json",
            "pga_guess.json",
            "pga_launch.json",
            "first_pose.json",
            "strip.png",
            "object_struck.ply",
            "render/007.png",
        ] {
            assert!(out.join(file).exists(), "{file} is missing");
        }
        // GA's poses put the collision within a frame of the simulator's report.
        let log: Vec<serde_json::Value> = std::fs::read_to_string(out.join("log.jsonl"))
            .unwrap()
            .lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect();
        // The first round's motion does not converge at 10 substeps past the collision: the second round and
        // its stage file are at 20.
        let second_round: Vec<u64> = log.iter().filter_map(|v| v["second_round_substeps"].as_u64()).collect();
        assert_eq!(second_round, [20], "the second round's substeps in log.jsonl");
        let second_substeps =
            pganeus_io::read_trajectory(&out.join("pga.json")).unwrap().extra["sim"]["substeps"].clone();
        assert_eq!(second_substeps, 20, "pga.json");
        let found: Vec<u64> = log.iter().filter_map(|v| v["first_contact"].as_u64()).collect();
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
            // IoU worst 0.90. 2026-12-07, the motion made at 40 substeps (converged: at the fit's 10 it was not,
            // and a fit can only follow it by being as wrong) and the second round at 20: worst 3.5, 3.4 and
            // 2.0 mm (without the finer round 5.9, 0.9 and 5.1; on the motion made at 10, 8.9, 4.7, 7.9). Each
            // body's bound leaves room for the pixel batches, not for a body lost, swapped or stuck; accuracy
            // at scale is measured on the two-body synth at 320×240 (README).
            let bound = [5.0, 5.0, 12.0][b];
            assert!(mean < bound, "{n}: {mean:.2} mm off on average (bound {bound} mm)");
            assert!(worst < 20.0, "{n}: worst frame {worst:.2} mm off");
            assert!(ious.iter().all(|&i| i > 0.75), "{n}: IoU {ious:?}");
        }
        // Every pair's values with the ranges the motion cannot tell from them, each around its value.
        let pairs = fitted.contact.extra["pairs"].as_array().expect("contact.pairs");
        for p in pairs {
            for value in ["restitution", "friction"] {
                let v = p[value].as_f64().unwrap();
                let r = p[format!("{value}_range")]
                    .as_array()
                    .unwrap_or_else(|| panic!("{p}: no range"));
                let (lo, hi) = (r[0].as_f64().unwrap(), r[1].as_f64().unwrap());
                assert!(lo <= v && v <= hi, "{p}");
            }
        }
        // Stopped before its end, it resumes from its stage files to the same result, bit for bit (both rounds'
        // worlds read back, the round kept by comparing them, the ranges from the kept one).
        std::fs::remove_file(out.join("trajectory.json")).unwrap();
        fit(&balls, &small, &out).unwrap();
        let resumed = pganeus_io::read_trajectory(&out.join("trajectory.json")).unwrap();
        for (a, b) in resumed.bodies.iter().zip(&fitted.bodies) {
            assert_eq!((&a.initial, &a.poses), (&b.initial, &b.poses), "{}", a.name);
        }
        assert_eq!(resumed.contact.extra["pairs"], fitted.contact.extra["pairs"]);
        let _ = std::fs::remove_dir_all(&d);
    }
}
