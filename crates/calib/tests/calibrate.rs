//! Calibration from rendered views of a printed board through a lens with distortion: detection, then the
//! lens and the poses against the truth.

use crate::common;

use calib::board_views::{render, View};
use calib::calibrate::{calibrate, CalibrationSettings, ViewPoints};
use calib::detect::{detect_markers, DetectorSettings};
use calib::{Board, BoardSpec, Lens};
use common::opencv_reference;
use geom::Vec3;
use std::path::Path;

/// What `pganeus calibrate` does: a calibration from the corners as detected, then another from the markers'
/// corners refined again knowing the lens.
fn calibrate_two_pass(b: &Board, grays: &[calib::gray::Gray], size: (usize, usize)) -> calib::calibrate::Calibration {
    let mut found: Vec<_> = grays
        .iter()
        .map(|g| detect_markers(g, b.dictionary, &DetectorSettings::default()))
        .collect();
    let views: Vec<ViewPoints> = found.iter().map(|f| ViewPoints::from_detections(b, f, &[])).collect();
    let first = calibrate(&views, size, &CalibrationSettings::default()).unwrap();
    let views: Vec<ViewPoints> = grays
        .iter()
        .zip(found.iter_mut())
        .map(|(g, f)| {
            calib::detect::refine_with_lens(g, f, b.dictionary, &first.lens);
            ViewPoints::from_detections(b, f, &[])
        })
        .collect();
    calibrate(&views, size, &CalibrationSettings::default()).unwrap()
}

#[test]
fn a_lens_with_distortion_and_every_camera_from_rendered_views() {
    let b = Board::new(
        BoardSpec::parse(
            "kind = \"aruco_grid\"\ndictionary = \"DICT_5X5_1000\"\nsize = [8, 6]\nmarker_length = 0.03\nmarker_separation = 0.006\n",
            Path::new("board.toml"),
        )
        .unwrap(),
    )
    .unwrap();
    let size = (800, 600);
    let lens = Lens {
        fx: 760.0,
        fy: 758.0,
        cx: 404.0,
        cy: 297.0,
        distortion: [-0.24, 0.08, 0.0006, -0.0004, 0.0],
    };
    let mut rng = geom::SplitMix64::new(5);
    let mut grays = Vec::new();
    let mut truth = Vec::new();
    for k in 0..10 {
        let distance = rng.range(0.4, 0.55);
        let tilt = rng.range(0.2, 0.7);
        let view = View::looking_at(
            &b,
            760.0,
            size,
            distance,
            tilt,
            rng.range(-3.1, 3.1),
            rng.range(-3.1, 3.1),
        )
        .with_lens(lens);
        grays.push(render(&b, &view, size, 3, 2.0, k));
        truth.push(view);
    }
    let c = calibrate_two_pass(&b, &grays, size);
    let centre = |r: geom::Quat<f64>, t: Vec3<f64>| r.conj().rotate(-t);
    let mut worst_centre: f64 = 0.0;
    let mut worst_angle: f64 = 0.0;
    for (p, t) in c.poses.iter().zip(&truth) {
        worst_centre = worst_centre.max((centre(p.rotation, p.translation) - centre(t.rotation, t.translation)).norm());
        worst_angle = worst_angle.max(geom::rotation_distance(p.rotation, t.rotation).to_degrees());
    }
    let focal = (c.lens.fx / lens.fx - 1.0).abs().max((c.lens.fy / lens.fy - 1.0).abs());
    let principal = (c.lens.cx - lens.cx).hypot(c.lens.cy - lens.cy);
    eprintln!(
        "rms {:.3} px; focal {:.3} %, principal point {principal:.2} px, k1 {:.4} ({:.4}); centres worst {:.2} mm, rotations worst {worst_angle:.3} deg",
        c.rms,
        focal * 100.0,
        c.lens.distortion[0],
        lens.distortion[0],
        worst_centre * 1000.0
    );
    assert!(focal < 0.003 && principal < 2.0, "{:?}", c.lens);
    assert!(
        worst_centre < 0.002 && worst_angle < 0.2,
        "centres {worst_centre} m, rotations {worst_angle} deg"
    );
}

/// Errors of a calibration against the truth: focal (share), principal point (px), camera centres (m, median
/// and worst), rotations (degrees, median and worst).
fn errors(
    lens: &Lens,
    poses: &[(geom::Quat<f64>, Vec3<f64>)],
    truth_lens: &Lens,
    truth: &[View],
) -> (f64, f64, [f64; 2], [f64; 2]) {
    let centre = |r: geom::Quat<f64>, t: Vec3<f64>| r.conj().rotate(-t);
    let mut centres: Vec<f64> = poses
        .iter()
        .zip(truth)
        .map(|(p, t)| (centre(p.0, p.1) - centre(t.rotation, t.translation)).norm())
        .collect();
    let mut angles: Vec<f64> = poses
        .iter()
        .zip(truth)
        .map(|(p, t)| geom::rotation_distance(p.0, t.rotation).to_degrees())
        .collect();
    centres.sort_by(f64::total_cmp);
    angles.sort_by(f64::total_cmp);
    let focal = (lens.fx / truth_lens.fx - 1.0)
        .abs()
        .max((lens.fy / truth_lens.fy - 1.0).abs());
    let principal = (lens.cx - truth_lens.cx).hypot(lens.cy - truth_lens.cy);
    (
        focal,
        principal,
        [centres[centres.len() / 2], centres[centres.len() - 1]],
        [angles[angles.len() / 2], angles[angles.len() - 1]],
    )
}

#[test]
#[ignore = "slow: OpenCV's calibrateCamera (Python) beside ours on 14 rendered JPEG views"]
fn at_least_as_accurate_as_opencvs_calibration_on_the_same_images() {
    let spec = "kind = \"aruco_grid\"\ndictionary = \"DICT_5X5_1000\"\nsize = [8, 6]\nmarker_length = 0.03\nmarker_separation = 0.006\n";
    let b = Board::new(BoardSpec::parse(spec, Path::new("board.toml")).unwrap()).unwrap();
    let size = (800, 600);
    let lens = Lens {
        fx: 700.0,
        fy: 702.0,
        cx: 398.0,
        cy: 305.0,
        distortion: [-0.26, 0.09, 0.0007, -0.0005, 0.0],
    };
    let dir = testkit::scratch_dir("calib", "opencv_calibrate");
    let seed: u64 = std::env::var("SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(21);
    let mut rng = geom::SplitMix64::new(seed);
    let (mut truth, mut paths, mut grays) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..14 {
        let view = View::looking_at(
            &b,
            700.0,
            size,
            rng.range(0.38, 0.6),
            rng.range(0.2, 0.75),
            rng.range(-3.1, 3.1),
            rng.range(-3.1, 3.1),
        )
        .with_lens(lens);
        let image = render(&b, &view, size, 3, 2.5, 50 + k).to_image();
        let path = dir.join(format!("{k:02}.jpg"));
        std::fs::write(
            &path,
            testkit::jpeg_bytes(&image.data, image.width, image.height, 1, 90),
        )
        .unwrap();
        grays.push(calib::gray::Gray::from_image(&pganeus_io::read_image(&path).unwrap()));
        truth.push(view);
        paths.push(path.to_string_lossy().into_owned());
    }
    let ours = calibrate_two_pass(&b, &grays, size);
    let our_poses: Vec<_> = ours.poses.iter().map(|p| (p.rotation, p.translation)).collect();
    let (focal, principal, centres, angles) = errors(&ours.lens, &our_poses, &lens, &truth);

    let case = serde_json::json!({"images": paths, "board": {"kind": "aruco_grid", "dictionary": "DICT_5X5_1000", "size": [8, 6], "marker_length": 0.03, "marker_separation": 0.006, "first_id": 0}});
    std::fs::write(dir.join("case.json"), case.to_string()).unwrap();
    let version = opencv_reference("calibrate", &dir.join("case.json"), &dir.join("opencv.json"));
    let cv: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("opencv.json")).unwrap()).unwrap();
    let k = |r: usize, c: usize| cv["K"][r][c].as_f64().unwrap();
    let d: Vec<f64> = cv["dist"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let cv_lens = Lens {
        fx: k(0, 0),
        fy: k(1, 1),
        cx: k(0, 2),
        cy: k(1, 2),
        distortion: [d[0], d[1], d[2], d[3], d[4]],
    };
    let mut cv_poses = Vec::new();
    let mut cv_truth = Vec::new();
    for (p, t) in cv["poses"].as_array().unwrap().iter().zip(&truth) {
        if p.is_null() {
            continue;
        }
        let rv = Vec3::new(
            p["rvec"][0].as_f64().unwrap(),
            p["rvec"][1].as_f64().unwrap(),
            p["rvec"][2].as_f64().unwrap(),
        );
        let tv = Vec3::new(
            p["tvec"][0].as_f64().unwrap(),
            p["tvec"][1].as_f64().unwrap(),
            p["tvec"][2].as_f64().unwrap(),
        );
        cv_poses.push((geom::Quat::exp(rv), tv));
        cv_truth.push(*t);
    }
    let (cv_focal, cv_principal, cv_centres, cv_angles) = errors(&cv_lens, &cv_poses, &lens, &cv_truth);
    eprintln!(
        "OpenCV {}: rms {:.3} px, focal {:.3} %, principal point {cv_principal:.2} px, centres {:.2} / {:.2} mm, rotations {:.3} / {:.3} deg ({} views)\n\
         ours: rms {:.3} px, focal {:.3} %, principal point {principal:.2} px, centres {:.2} / {:.2} mm, rotations {:.3} / {:.3} deg ({} views)",
        version,
        cv["rms"].as_f64().unwrap(),
        cv_focal * 100.0,
        cv_centres[0] * 1000.0,
        cv_centres[1] * 1000.0,
        cv_angles[0],
        cv_angles[1],
        cv_poses.len(),
        ours.rms,
        focal * 100.0,
        centres[0] * 1000.0,
        centres[1] * 1000.0,
        angles[0],
        angles[1],
        our_poses.len()
    );
    assert!(
        focal <= cv_focal.max(0.001) && principal <= cv_principal.max(1.0),
        "focal {focal} vs {cv_focal}, principal {principal} vs {cv_principal}"
    );
    assert!(
        centres[0] <= cv_centres[0] && centres[1] <= cv_centres[1],
        "centres {centres:?} vs OpenCV's {cv_centres:?}"
    );
    assert!(
        angles[0] <= cv_angles[0].max(0.01) && angles[1] <= cv_angles[1].max(0.02),
        "rotations {angles:?} vs OpenCV's {cv_angles:?}"
    );
}
