//! Raw footage is what its lens says: the corners of a printed board found in a raw render (through the
//! lens, optical blur, sRGB) sit where the lens in `camera_truth.json` projects them.

use calib::detect::{detect_markers, DetectorSettings};
use geom::{Camera, Intrinsics, Vec3};
use synth::render::{Light, RenderObject, RenderScene};

#[test]
fn a_raw_render_is_seen_through_its_lens() {
    let spec = calib::BoardSpec {
        kind: calib::BoardKind::ArucoGrid,
        dictionary: "DICT_5X5_1000".into(),
        size: [6, 4],
        marker_length: 0.04,
        marker_separation: Some(0.01),
        square_length: None,
        legacy: false,
        first_id: 0,
    };
    let board = calib::Board::new(spec).unwrap();
    let print = std::sync::Arc::new(synth::print::Print {
        board: board.clone(),
        margin: 0.01,
    });
    let slab = sim::sdf::Shape::Cuboid(sim::sdf::Cuboid {
        half: [0.3, 0.3, 0.005],
    });
    let tex = synth::texture::Texture::new(
        synth::texture::Pattern::Checker,
        0.03,
        vec![[0.5, 0.5, 0.5], [0.5, 0.5, 0.5]],
        1,
    );
    let scene = RenderScene {
        objects: vec![RenderObject {
            shape: slab,
            pose: geom::Pose::from_translation(Vec3::new(0.0, 0.0, -0.005)),
            texture: tex,
            bound: None,
            mask_id: None,
            print: Some(print),
        }],
        light: Light {
            ambient: 1.0,
            intensity: 0.0,
            ..Light::default()
        },
    };
    for k1 in [0.0, -0.12] {
        let raw = synth::RawDesc {
            width: 480,
            height: 360,
            distortion: [k1, 0.0, 0.0, 0.0, 0.0],
            ..Default::default()
        };
        let lens = calib::Lens {
            fx: 435.0,
            fy: 435.0,
            cx: 241.0,
            cy: 178.0,
            distortion: raw.distortion,
        };
        let k = Intrinsics::centred(435.0, 480, 360);
        let cam = Camera::look_at(
            Vec3::new(0.08, -0.2, 0.32),
            Vec3::new(0.02, 0.01, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            k,
            480,
            360,
        );
        let r = synth::raw::render_raw(std::slice::from_ref(&scene), &cam.world_to_cam, &lens, &raw, 16);
        let mut rng = geom::SplitMix64::new(1);
        let img = synth::raw::develop(&r, [1.0; 3], 0.0, &mut rng);
        let gray = calib::gray::Gray::from_image(&img);
        let found = detect_markers(&gray, board.dictionary, &DetectorSettings::default());
        let (mut rad, mut n, mut rms) = (0.0, 0, 0.0);
        for m in &found {
            for (c, b) in m.corners.iter().zip(&board.marker(m.id).unwrap().corners) {
                let w = board.to_world(*b);
                let p = lens.project(cam.world_to_cam.transform_point(Vec3::new(w[0], w[1], w[2])));
                let (dx, dy) = (c[0] - p[0], c[1] - p[1]);
                let (rx, ry) = (p[0] - lens.cx, p[1] - lens.cy);
                let rr = (rx * rx + ry * ry).sqrt().max(1e-9);
                rad += (dx * rx + dy * ry) / rr;
                rms += dx * dx + dy * dy;
                n += 1;
            }
        }
        let (radial, rms) = (rad / n as f64, (rms / n as f64).sqrt());
        eprintln!(
            "k1 {k1}: {} markers, radial mean {radial:.4} px, rms {rms:.4} px",
            found.len()
        );
        assert_eq!(found.len(), 24, "every marker of the print");
        assert!(
            radial.abs() < 0.05 && rms < 0.12,
            "k1 {k1}: corners {rms:.3} px (rms) from the lens's projection, {radial:.3} px outward"
        );
    }
}
