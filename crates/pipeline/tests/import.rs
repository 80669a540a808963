//! `import-colmap` and `import-transforms` on reconstructions whose cameras are a rendered session's true
//! ones moved into an arbitrary world (scale, rotation, offset): the board's alignment gives the true
//! cameras back; the table's plane and a scale bar give their heights and spacing; bad inputs are refused
//! with nothing written.

use crate::common;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use calib::board_views::View;
use common::{around, board, lens, shoot, BOARD, SIZE};
use geom::{Pose, Quat, Similarity, Vec3};
use pipeline::import::{import_colmap, import_transforms, ImportArgs, ImportColmapArgs, ImportTransformsArgs};
use pipeline::Quiet;

/// The truth's world → the reconstruction's: metres to "units" of about 1/0.27 m, turned and moved.
fn secret() -> Similarity {
    Similarity {
        scale: 3.7,
        rotation: Quat::exp(Vec3::new(1.9, -0.6, 0.8)),
        translation: Vec3::new(-2.0, 5.0, 0.7),
    }
}

/// Photos of the board (JPEG) in `root/images`; their true world-to-camera poses.
fn session(root: &Path) -> (Vec<View>, Vec<Pose<f64>>) {
    std::fs::write(root.join("board.toml"), BOARD).unwrap();
    let views = around(8, 31);
    shoot(&root.join("images"), &views, true, 500);
    let b = board();
    let poses = views
        .iter()
        .map(|v| b.world_to_camera(v.rotation, v.translation))
        .collect();
    (views, poses)
}

/// Sparse points as a reconstruction has them: most on the table (z = 0), some on things above it.
fn table_points() -> Vec<Vec3<f64>> {
    let mut rng = geom::SplitMix64::new(5);
    (0..600)
        .map(|i| {
            let (x, y) = (rng.range(-0.3, 0.3), rng.range(-0.25, 0.25));
            let z = if i % 5 == 0 {
                rng.range(0.01, 0.12)
            } else {
                rng.range(-3e-4, 3e-4)
            };
            Vec3::new(x, y, z)
        })
        .collect()
}

fn names() -> Vec<String> {
    (0..8).map(|k| format!("IMG_{k:04}.jpg")).collect()
}

/// A COLMAP text model of the session in the secret world (OPENCV camera, COLMAP's half-pixel principal point).
fn write_colmap(dir: &Path, poses: &[Pose<f64>]) {
    std::fs::create_dir_all(dir).unwrap();
    let l = lens();
    let d = l.distortion;
    std::fs::write(
        dir.join("cameras.txt"),
        format!(
            "# Camera list\n1 OPENCV {} {} {} {} {} {} {} {} {} {}\n",
            SIZE.0,
            SIZE.1,
            l.fx,
            l.fy,
            l.cx + 0.5,
            l.cy + 0.5,
            d[0],
            d[1],
            d[2],
            d[3]
        ),
    )
    .unwrap();
    let s = secret();
    let mut images = String::from("# Image list\n");
    for (k, (pose, name)) in poses.iter().zip(names()).enumerate() {
        let p = s.move_camera(pose);
        let [w, x, y, z] = p.q.to_array();
        writeln!(
            images,
            "{} {w} {x} {y} {z} {} {} {} 1 {name}\n",
            k + 1,
            p.t.x,
            p.t.y,
            p.t.z
        )
        .unwrap();
    }
    std::fs::write(dir.join("images.txt"), images).unwrap();
    let mut points = String::new();
    for (k, p) in table_points().iter().enumerate() {
        let q = s.apply(*p);
        writeln!(points, "{} {} {} {} 128 128 128 0.5 1 0", k + 1, q.x, q.y, q.z).unwrap();
    }
    std::fs::write(dir.join("points3D.txt"), points).unwrap();
}

/// The same cameras as nerfstudio writes them (OpenGL camera-to-world), with the points in a PLY.
fn write_transforms(root: &Path, poses: &[Pose<f64>]) -> PathBuf {
    let s = secret();
    let l = lens();
    let frames: Vec<serde_json::Value> = poses
        .iter()
        .zip(names())
        .map(|(pose, name)| {
            let c2w = s.move_camera(pose).inverse();
            let r = c2w.q.to_mat().m;
            let t = c2w.t;
            serde_json::json!({
                "file_path": format!("images/{name}"),
                "transform_matrix": [
                    [r[0][0], -r[0][1], -r[0][2], t.x],
                    [r[1][0], -r[1][1], -r[1][2], t.y],
                    [r[2][0], -r[2][1], -r[2][2], t.z],
                    [0.0, 0.0, 0.0, 1.0]
                ]
            })
        })
        .collect();
    let d = l.distortion;
    let doc = serde_json::json!({
        "camera_model": "OPENCV", "w": SIZE.0, "h": SIZE.1, "fl_x": l.fx, "fl_y": l.fy,
        "cx": l.cx + 0.5, "cy": l.cy + 0.5, "k1": d[0], "k2": d[1], "p1": d[2], "p2": d[3],
        "frames": frames, "ply_file_path": "sparse_pc.ply"
    });
    let cloud = geom::TriMesh {
        vertices: table_points().iter().map(|p| s.apply(*p).to_array()).collect(),
        faces: Vec::new(),
    };
    pganeus_io::write_ply(
        &root.join("sparse_pc.ply"),
        &pganeus_io::PlyMesh::from_mesh(cloud),
        pganeus_io::PlyEncoding::Ascii,
    )
    .unwrap();
    let path = root.join("transforms.json");
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    path
}

/// The capture's cameras against the truth: the worst centre distance (m) and rotation (deg).
fn worst(found: &[(String, Pose<f64>)], truth: &[Pose<f64>]) -> (f64, f64) {
    found.iter().zip(truth).fold((0.0f64, 0.0f64), |(c, r), ((_, f), t)| {
        (
            c.max((f.inverse().t - t.inverse().t).norm()),
            r.max(geom::rotation_distance(f.q, t.q).to_degrees()),
        )
    })
}

#[test]
fn a_colmap_model_aligned_to_the_board_gives_the_true_cameras() {
    let root = testkit::scratch_dir("pipeline", "import_colmap");
    let (_, truth) = session(&root);
    write_colmap(&root.join("sparse/0"), &truth);
    let mut import = ImportArgs::new(root.join("capture"));
    import.board = Some(root.join("board.toml"));
    import.width = Some(320);
    let a = ImportColmapArgs {
        model: root.join("sparse/0"),
        images: root.join("images"),
        import,
    };
    let outcome = import_colmap(&a, &Quiet).unwrap();
    let (centre, angle) = worst(&outcome.cameras, &truth);
    eprintln!(
        "colmap + board: centres within {:.3} mm, rotations within {angle:.4} deg, scale {:.5} (truth {:.5})",
        centre * 1000.0,
        outcome.similarity.scale,
        1.0 / secret().scale
    );
    assert_eq!(outcome.alignment, "board");
    assert!(centre < 1e-4 && angle < 0.01, "{centre} m, {angle} deg");
    assert!((outcome.similarity.scale * secret().scale - 1.0).abs() < 2e-3);

    // The capture reads back with the same cameras (the captures' pixel convention, undistorted images).
    let capture = pganeus_io::open_capture(&root.join("capture")).unwrap();
    assert_eq!((capture.width, capture.height), (320, 240));
    assert_eq!(capture.cameras.len(), 8);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("capture/import.json")).unwrap()).unwrap();
    assert_eq!(report["alignment"]["method"], "board");
    let cam = geom::Camera::from_world_mat(&capture.cameras[3].world_mat, 320, 240).unwrap();
    assert!((cam.center() - truth[3].inverse().t).norm() < 5e-4);
    assert!((cam.k.fx - lens().fx / 2.0).abs() < 1e-9);
    assert!((cam.k.cx - (lens().cx + 0.5) / 2.0).abs() < 1e-9);
}

#[test]
fn a_transforms_file_aligned_to_its_table_and_a_scale_bar_gives_heights_and_spacing() {
    let root = testkit::scratch_dir("pipeline", "import_transforms");
    let (views, truth) = session(&root);
    let path = write_transforms(&root, &truth);
    // Two board corners 0.2 m apart, clicked in the first and third photos.
    let b = board();
    let (p, q) = (b.markers[0].corners[0], b.markers[4].corners[0]);
    let length = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
    let (u, v) = (views[0].project(p), views[2].project(q));
    let mut import = ImportArgs::new(root.join("capture"));
    import.scale_bar = Some(vec![format!(
        "IMG_0000.jpg:{:.2},{:.2} IMG_0002.jpg:{:.2},{:.2} {:.1}mm",
        u[0],
        u[1],
        v[0],
        v[1],
        length * 1000.0
    )]);
    let a = ImportTransformsArgs {
        transforms: path.clone(),
        import,
    };
    let outcome = import_transforms(&a, &Quiet).unwrap();
    assert_eq!(outcome.alignment, "plane");
    // No board: the heights above the table and the distances between cameras are the truth's, not x and y.
    let centres: Vec<Vec3<f64>> = outcome.cameras.iter().map(|(_, p)| p.inverse().t).collect();
    let truth_centres: Vec<Vec3<f64>> = truth.iter().map(|p| p.inverse().t).collect();
    let mut worst_height = 0.0f64;
    let mut worst_spacing = 0.0f64;
    for i in 0..centres.len() {
        worst_height = worst_height.max((centres[i].z - truth_centres[i].z).abs());
        for j in 0..i {
            let d = (centres[i] - centres[j]).norm() - (truth_centres[i] - truth_centres[j]).norm();
            worst_spacing = worst_spacing.max(d.abs());
        }
    }
    eprintln!(
        "transforms + plane + scale bar: heights within {:.2} mm, spacings within {:.2} mm",
        worst_height * 1000.0,
        worst_spacing * 1000.0
    );
    assert!(
        worst_height < 2e-3 && worst_spacing < 2e-3,
        "{worst_height} {worst_spacing}"
    );

    // The same file with the board: the true cameras.
    let mut import = ImportArgs::new(root.join("capture_board"));
    import.board = Some(root.join("board.toml"));
    let outcome = import_transforms(
        &ImportTransformsArgs {
            transforms: path,
            import,
        },
        &Quiet,
    )
    .unwrap();
    let (centre, angle) = worst(&outcome.cameras, &truth);
    assert!(centre < 1e-4 && angle < 0.01, "{centre} m, {angle} deg");
}

#[test]
fn bad_imports_are_refused_naming_the_problem_and_write_nothing() {
    let root = testkit::scratch_dir("pipeline", "import_bad");
    let (_, truth) = session(&root);
    write_colmap(&root.join("sparse/0"), &truth);
    let run = |import: ImportArgs, images: &str| {
        let a = ImportColmapArgs {
            model: root.join("sparse/0"),
            images: root.join(images),
            import,
        };
        let e = import_colmap(&a, &Quiet).unwrap_err().to_string();
        assert!(!a.import.out.exists(), "{} written after: {e}", a.import.out.display());
        e
    };
    let out = root.join("out");
    // No scale at all.
    let e = run(ImportArgs::new(&out), "images");
    assert!(e.contains("--board") && e.contains("--scale-bar"), "{e}");
    // The wrong images folder.
    std::fs::create_dir_all(root.join("other")).unwrap();
    let mut a = ImportArgs::new(&out);
    a.scale = Some(0.27);
    let e = run(a, "other");
    assert!(e.contains("IMG_0000.jpg") && e.contains("other"), "{e}");
    // A board that is not in the images.
    std::fs::write(root.join("wrong.toml"), BOARD.replace("DICT_4X4_50", "DICT_6X6_250")).unwrap();
    let mut a = ImportArgs::new(&out);
    a.board = Some(root.join("wrong.toml"));
    let e = run(a, "images");
    assert!(e.contains("wrong.toml") && e.contains("seen in 0"), "{e}");
    // A scale bar naming an image the model does not have.
    let mut a = ImportArgs::new(&out);
    a.scale_bar = Some(vec![
        "IMG_0099.jpg:10,10".into(),
        "IMG_0001.jpg:20,20".into(),
        "0.2".into(),
    ]);
    let e = run(a, "images");
    assert!(e.contains("IMG_0099.jpg is not a registered image"), "{e}");
}
