//! A raw session from `synth --raw` (a printed board on the table, handheld JPEGs through a distorting
//! lens, a video with motion blur, close-ups for the lens) through `calibrate`, and through COLMAP
//! (pycolmap) and `import-colmap`: the lens and every camera against the truth beside it.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use pipeline::import::{import_colmap, ImportArgs, ImportColmapArgs};
use pipeline::Quiet;

/// A session small enough for the test tier: 12 views a capture, 3 video frames, 8 close-ups, raw 480 × 360.
fn small_raw_scene(kind: calib::BoardKind, seed: u64) -> synth::SynthScene {
    let mut s = synth::preset("tabletop", synth::Scale::Small).unwrap();
    s.cameras.views = 12;
    s.videos.truncate(1);
    s.videos[0].frames = 3;
    let mut s = synth::with_raw(s, kind, seed);
    if let Some(raw) = &mut s.raw {
        raw.calibration_views = 8;
    }
    s
}

/// The aruco-grid session, rendered once for the tests that share it: its folder and scene.
fn aruco_session() -> &'static (PathBuf, synth::SynthScene) {
    static SESSION: OnceLock<(PathBuf, synth::SynthScene)> = OnceLock::new();
    SESSION.get_or_init(|| {
        let root = testkit::scratch_dir("pipeline", "raw_session_aruco");
        let scene = small_raw_scene(calib::BoardKind::ArucoGrid, 2);
        synth::generate(&scene, Path::new("."), &root.join("data"), &mut |_, _, _| {}).unwrap();
        (root, scene)
    })
}

#[test]
#[ignore = "slow: renders a raw session and imports it whole, about 60 s"]
fn a_synth_raw_session_imports_and_calibrates_to_its_truth() {
    // The ChArUco board's session is measured by the benchmark (docs/results.md): at this test's size its
    // lens from 8 close-ups is 0.2-0.33 % off in focal length, above the 0.3 % this test holds the grid to;
    // and its wide background views see the 30 mm markers at ~15 px, too few and too small to pin a camera to
    // 2 mm (calibrate leaves such photos out).
    let kind = calib::BoardKind::ArucoGrid;
    let (root, scene) = aruco_session();
    let data = root.join("out");
    // `import` calibrates every folder of the session together (the close-ups for the lens only).
    let mut a = pipeline::import_session::ImportSessionArgs::new(root.join("data/raw"), &data);
    a.width = Some(160);
    let imported = pipeline::import_session::run(&a, &Quiet).unwrap();
    check_session(&imported.session, &data, scene);
    objects_masks_match_their_silhouettes(root, &data);
    let outcome = imported.calibration;
    let dropped: usize =
        serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(root.join("out/calibration.json")).unwrap())
            .unwrap()["captures"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["skipped"].as_array().unwrap().len())
            .sum();
    let sigmas: Vec<String> =
        serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(root.join("out/calibration.json")).unwrap())
            .unwrap()["captures"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|c| {
                c["views"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| format!("{:.2}", v["centre_sigma_mm"].as_f64().unwrap_or(-1.0)))
                    .collect::<Vec<_>>()
            })
            .collect();
    eprintln!(
        "{kind:?}: {dropped} photos left out; centre sigmas (mm): {}",
        sigmas.join(" ")
    );
    // The cameras as import wrote them (calibration.json and each capture) against the truth.
    let c = pipeline::session_truth::cameras(&data, &root.join("data")).unwrap();
    eprintln!(
        "{kind:?}: focal {:.3} %, principal point {:.2} px, {} of {} cameras, centres within {:.2} mm, rotations within {:.3} deg, rms {:.3} px",
        c.focal_percent, c.principal_px, c.cameras, c.photos, c.centre_mm[1], c.turn_deg[1], outcome.rms
    );
    assert_eq!(c.cameras + dropped, c.photos, "every photo compared or left out");
    assert!(
        c.focal_percent < 0.3 && c.principal_px < 2.0,
        "{kind:?}: focal {} %, principal point {} px",
        c.focal_percent,
        c.principal_px
    );
    assert!(
        c.centre_mm[1] < 2.0 && c.turn_deg[1] < 0.2,
        "{kind:?}: centres {} mm, rotations {} deg",
        c.centre_mm[1],
        c.turn_deg[1]
    );
}

/// The truth's world-to-camera pose of each image of a raw folder (by file name), from the truth capture.
fn truth_cameras(data: &Path, name: &str) -> Vec<(String, geom::Pose<f64>)> {
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("camera_truth.json")).unwrap()).unwrap();
    let capture = pganeus_io::open_capture(&data.join(name)).unwrap();
    let files = truth["captures"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == name)
        .unwrap()["files"]
        .as_array()
        .unwrap()
        .clone();
    files
        .iter()
        .zip(&capture.cameras)
        .map(|(f, c)| {
            let cam = geom::Camera::from_world_mat(&c.world_mat, capture.width, capture.height).unwrap();
            (f.as_str().unwrap().to_string(), cam.world_to_cam)
        })
        .collect()
}

#[test]
#[ignore = "slow: COLMAP (pycolmap) reconstructs a raw session's photos, about 25 s"]
fn colmaps_model_of_a_raw_session_imports_to_the_true_cameras() {
    let (root, _) = aruco_session();
    let data = root.join("data");
    let images = data.join("raw/background");
    // COLMAP holding the lens, as with a lens calibrated beforehand (`calibrate --lens-only`): the poses are
    // COLMAP's own, and the import's conventions (half a pixel, axes, the board's world) are what is tested.
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("camera_truth.json")).unwrap()).unwrap();
    let k = |r: usize, c: usize| truth["lens"]["K"][r][c].as_f64().unwrap();
    let d: Vec<f64> = truth["lens"]["distortion"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let lens = format!(
        "{},{},{},{},{},{},{},{}",
        k(0, 0),
        k(1, 1),
        k(0, 2) + 0.5,
        k(1, 2) + 0.5,
        d[0],
        d[1],
        d[2],
        d[3]
    );
    let python = std::env::var("PGANEUS_PYCOLMAP_PYTHON").unwrap_or_else(|_| "python3".into());
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/colmap/reconstruct.py");
    let out = std::process::Command::new(&python)
        .arg(&script)
        .arg(&images)
        .arg(root.join("colmap"))
        .arg(&lens)
        .output()
        .expect("run Python; set PGANEUS_PYCOLMAP_PYTHON to a Python with pycolmap");
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{report}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("pycolmap: {}", report.trim());

    // The model as COLMAP wrote it (binary) holds the lens it was given in its own pixel convention: read
    // back, it is the true lens in OpenCV's (the half pixel) to the digits COLMAP keeps.
    let model = calib::colmap::read_model(&root.join("colmap/sparse/0")).unwrap();
    assert_eq!(model.cameras.len(), 1, "one camera for every photo");
    let read = model.cameras.values().next().unwrap().lens;
    let (fx, fy, cx, cy) = (k(0, 0), k(1, 1), k(0, 2), k(1, 2));
    for (found, truth) in [(read.fx, fx), (read.fy, fy), (read.cx, cx), (read.cy, cy)] {
        assert!(
            (found - truth).abs() < 1e-6,
            "COLMAP's lens read as {read:?}; the truth fx {fx} fy {fy} cx {cx} cy {cy}"
        );
    }
    for (found, truth) in read.distortion[..4].iter().zip(&d) {
        assert!(
            (found - truth).abs() < 1e-9,
            "distortion {:?} against {d:?}",
            read.distortion
        );
    }

    let mut import = ImportArgs::new(root.join("imported"));
    import.board = Some(data.join("raw/board.toml"));
    import.width = Some(160);
    let a = ImportColmapArgs {
        model: root.join("colmap/sparse/0"),
        images,
        import,
    };
    let outcome = import_colmap(&a, &Quiet).unwrap();
    let truth = truth_cameras(&data, "background");
    let mut centres = Vec::new();
    let mut angles = Vec::new();
    for (name, pose) in &outcome.cameras {
        let t = &truth.iter().find(|(f, _)| f == name).unwrap().1;
        centres.push((pose.inverse().t - t.inverse().t).norm());
        angles.push(geom::rotation_distance(pose.q, t.q).to_degrees());
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (worst_centre, worst_angle) = (
        centres.iter().copied().fold(0.0, f64::max),
        angles.iter().copied().fold(0.0, f64::max),
    );
    let (median_centre, median_angle) = (median(&mut centres), median(&mut angles));
    eprintln!(
        "{} of {} photos registered; centres median {:.2} mm, worst {:.2} mm; rotations median {median_angle:.3} deg, worst {worst_angle:.3} deg",
        outcome.cameras.len(),
        truth.len(),
        1000.0 * median_centre,
        1000.0 * worst_centre
    );
    assert!(
        outcome.cameras.len() + 2 >= truth.len(),
        "COLMAP registered {} of {}",
        outcome.cameras.len(),
        truth.len()
    );
    // COLMAP's poses from 12 photos of 480 x 360 (SIFT on JPEG) scatter by about 1 mm and 0.1 deg about
    // the truth (24 photos: 0.8 mm, 0.04 deg); a wrong axis, scale or world would be centimetres off.
    assert!(
        median_centre < 2.5e-3 && median_angle < 0.15,
        "{median_centre} m, {median_angle} deg"
    );
    assert!(
        worst_centre < 6e-3 && worst_angle < 0.5,
        "{worst_centre} m, {worst_angle} deg"
    );
}

/// `import`'s session of the aruco session: its scene, its one object and its video, each capture of the
/// kind its folder says.
fn check_session(session: &pipeline::import_session::Session, data: &Path, scene: &synth::SynthScene) {
    assert_eq!(session.scene, "background");
    assert_eq!(session.objects.len(), 1);
    assert_eq!(session.objects[0].captures, ["toy_a".to_string(), "toy_b".to_string()]);
    assert_eq!(session.videos, vec![scene.videos[0].name.clone()]);
    assert_eq!(&pipeline::import_session::read_session(data).unwrap(), session);
    let subject = |c: &str| {
        let info: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(data.join(c).join("capture.json")).unwrap()).unwrap();
        (
            info["kind"].as_str().map(str::to_string),
            info["subject"].as_str().map(str::to_string),
        )
    };
    assert_eq!(subject("background"), (Some("static".into()), Some("scene".into())));
    assert_eq!(subject("toy_a"), (Some("static".into()), Some("object".into())));
    assert_eq!(subject(&scene.videos[0].name).0, Some("video".into()));
}

/// The object's masks computed from the imported (undistorted, calibrated) photos, written as `train`
/// writes them, against the true mesh posed as it rested, drawn through each calibrated camera.
fn objects_masks_match_their_silhouettes(root: &Path, data: &Path) {
    let runs = root.join("runs");
    for capture in ["toy_a", "toy_b"] {
        let loaded = neus::Dataset::load(&data.join(capture)).unwrap();
        let (masks, _) = pipeline::object_masks::compute(&loaded).unwrap();
        pipeline::video_masks::write_masks(&runs.join(capture).join("mask"), &masks, loaded.width as usize).unwrap();
    }
    let scores = pipeline::session_truth::masks(data, &runs, &root.join("fits"), &root.join("data")).unwrap();
    assert_eq!(scores.len(), 2, "the two captures, no video fitted");
    for m in &scores {
        let (_, worst) = m.worst().unwrap();
        eprintln!("{}: IoU per view {:.3?}", m.capture, m.views);
        // Measured 2026-12-06 (12 photos a capture at 480 x 360, those calibrate keeps, 160 wide):
        // toy_a 11 views 0.942-0.980, toy_b 9 views 0.845-0.978 (mean 0.947): fewer views than the 24 of
        // the measurement in docs/commands/masks.md, so the hull holds less.
        assert!(m.views.len() >= 8, "{}: {} views", m.capture, m.views.len());
        assert!(
            m.mean() > 0.93 && worst > 0.8,
            "{}: mean {:.3}, worst {worst:.3}",
            m.capture,
            m.mean()
        );
    }
}
