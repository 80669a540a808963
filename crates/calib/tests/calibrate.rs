//! Calibration from rendered views of a printed board through a lens with distortion: detection, then the
//! lens and the poses against the truth.

use calib::board_views::{render, View};
use calib::calibrate::{calibrate, CalibrationSettings, ViewPoints};
use calib::detect::{detect_markers, DetectorSettings};
use calib::{Board, BoardSpec, Lens};
use geom::Vec3;
use std::path::Path;

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
    let mut views = Vec::new();
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
        let image = render(&b, &view, size, 3, 2.0, k);
        let found = detect_markers(&image, b.dictionary, &DetectorSettings::default());
        let mut v = ViewPoints::default();
        for m in &found {
            for (c, p) in m.corners.iter().zip(&b.marker(m.id).unwrap().corners) {
                v.image.push(*c);
                v.board.push(*p);
            }
        }
        views.push(v);
        truth.push(view);
    }
    let c = calibrate(&views, size, &CalibrationSettings::default()).unwrap();
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
