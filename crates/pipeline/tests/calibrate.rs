//! `calibrate` on a rendered raw session: photos (JPEG) and a video (PNG) of a printed board through a
//! distorting lens → captures whose cameras are the true ones in the board's world; bad sessions refused
//! with nothing written.

use std::path::PathBuf;

use crate::common;

use calib::board_views::View;
use common::{around, board, lens, shoot, BOARD, SIZE};
use pipeline::calibrate::{run, CalibrateArgs};
use pipeline::Quiet;

fn session(name: &str) -> (PathBuf, Vec<View>, View) {
    let root = testkit::scratch_dir("pipeline", name);
    std::fs::write(root.join("board.toml"), BOARD).unwrap();
    let photos = around(9, 1);
    shoot(&root.join("background"), &photos, true, 100);
    let fixed = View::looking_at(&board(), 580.0, SIZE, 0.45, 0.6, 0.7, 0.2).with_lens(lens());
    shoot(&root.join("drop"), &[fixed; 4], false, 200);
    (root, photos, fixed)
}

#[test]
fn a_session_gives_the_true_cameras_in_the_boards_world() {
    let (root, photos, fixed) = session("calibrate_session");
    let mut a = CalibrateArgs::new(vec![], root.join("board.toml"), root.join("out"));
    a.scenes = vec![root.join("background")];
    a.videos = vec![root.join("drop")];
    a.width = Some(320);
    let outcome = run(&a, &Quiet).unwrap();
    eprintln!("rms {:.3} px, lens {:?}", outcome.rms, outcome.lens);
    assert!(outcome.rms < 0.3, "rms {}", outcome.rms);
    let l = lens();
    assert!(
        (outcome.lens.fx / l.fx - 1.0).abs() < 0.003 && (outcome.lens.cx - l.cx).abs() < 2.0,
        "{:?}",
        outcome.lens
    );
    let b = board();
    let check = |name: &str, truth: &[View]| {
        let capture = pganeus_io::open_capture(&root.join("out").join(name)).unwrap();
        assert_eq!((capture.width, capture.height, capture.len()), (320, 240, truth.len()));
        for (mats, view) in capture.cameras.iter().zip(truth) {
            let cam = geom::Camera::from_world_mat(&mats.world_mat, 320, 240).unwrap();
            let want = b.world_to_camera(view.rotation, view.translation);
            let centre_error = (cam.center() - want.inverse().t).norm();
            let angle = geom::rotation_distance(cam.world_to_cam.q, want.q).to_degrees();
            eprintln!(
                "{name}: centre off by {:.2} mm, rotation by {angle:.3} deg",
                centre_error * 1000.0
            );
            assert!(
                centre_error < 0.002 && angle < 0.2,
                "{name}: centre off by {centre_error} m, rotation by {angle} deg"
            );
            assert!((cam.k.fx - l.fx / 2.0).abs() < 0.01 * l.fx, "{:?}", cam.k);
        }
    };
    check("background", &photos);
    check("drop", &[fixed; 4]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("out/calibration.json")).unwrap()).unwrap();
    assert_eq!(report["captures"][1]["kind"], "video");
    assert!(report["rms_px"].as_f64().unwrap() < 0.3);
    let info = pganeus_io::read_capture_info(&root.join("out/drop/capture.json")).unwrap();
    assert_eq!(info.kind, pganeus_io::CaptureKind::Video);
    // The scene's region holds the whole printed board (its photos all see it), centred on the table.
    let info = pganeus_io::read_capture_info(&root.join("out/background/capture.json")).unwrap();
    assert_eq!(info.subject, Some(pganeus_io::CaptureSubject::Scene));
    let region = &report["captures"][0]["region"];
    assert!(region["rule"].as_str().unwrap().starts_with("a scene"), "{region}");
    let centre: Vec<f64> = serde_json::from_value(region["centre"].clone()).unwrap();
    let radius = region["radius"].as_f64().unwrap();
    eprintln!("scene region {centre:?} r {radius}");
    assert!(centre[2].abs() < 1e-9 && centre[0].hypot(centre[1]) < 0.05, "{region}");
    let [half_x, half_y] = [0.5 * b.extent[0], 0.5 * b.extent[1]];
    for (x, y) in [
        (half_x, half_y),
        (-half_x, half_y),
        (half_x, -half_y),
        (-half_x, -half_y),
    ] {
        assert!(
            (x - centre[0]).hypot(y - centre[1]) < radius,
            "board corner ({x}, {y}) outside {region}"
        );
    }
    assert!(radius < 0.5, "{region}");
}

#[test]
fn bad_sessions_are_refused_naming_the_problem_and_write_nothing() {
    let (root, _, _) = session("calibrate_bad");
    let out = root.join("out");
    let fails = |a: &CalibrateArgs, want: &str| {
        let e = run(a, &Quiet).unwrap_err().chain();
        assert!(e.contains(want), "wanted {want:?} in: {e}");
        assert!(!out.exists(), "{want}: the output was written");
    };
    // A camera that moves during the video.
    let moving = root.join("moving");
    let mut views = around(2, 9);
    views.extend(around(2, 10));
    shoot(&moving, &views, false, 300);
    let mut a = CalibrateArgs::new(vec![root.join("background")], root.join("board.toml"), &out);
    a.videos = vec![moving.clone()];
    fails(&a, "the camera moves during the video");
    // Too few views.
    let few = root.join("few");
    shoot(&few, &around(2, 4), true, 400);
    fails(
        &CalibrateArgs::new(vec![few], root.join("board.toml"), &out),
        "needs at least 3",
    );
    // Another camera's size.
    let other = root.join("other");
    std::fs::create_dir_all(&other).unwrap();
    pganeus_io::write_png(&other.join("a.png"), &pganeus_io::Image::new(320, 200, 1)).unwrap();
    fails(
        &CalibrateArgs::new(vec![root.join("background"), other], root.join("board.toml"), &out),
        "is 320x200",
    );
    // A board file of another dictionary: nothing of it in the images.
    std::fs::write(root.join("wrong.toml"), BOARD.replace("DICT_4X4_50", "DICT_6X6_250")).unwrap();
    fails(
        &CalibrateArgs::new(vec![root.join("background")], root.join("wrong.toml"), &out),
        "no marker of the board",
    );
    // The right dictionary with other ids.
    std::fs::write(root.join("ids.toml"), format!("{BOARD}first_id = 24\n")).unwrap();
    fails(
        &CalibrateArgs::new(vec![root.join("background")], root.join("ids.toml"), &out),
        "first_id",
    );
    // Lengths that do not match the print.
    std::fs::write(
        root.join("lengths.toml"),
        BOARD.replace("marker_separation = 0.008", "marker_separation = 0.02"),
    )
    .unwrap();
    fails(
        &CalibrateArgs::new(vec![root.join("background")], root.join("lengths.toml"), &out),
        "match the print",
    );
}
