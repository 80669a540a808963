//! Generated datasets agree with their own ground truth: bodies project into
//! their masks, masks match an independent rasterisation of the posed mesh,
//! videos follow truth.json, cameras round-trip through the npz loader,
//! renders are deterministic, and bad scenes are refused with the field named.
use geom::{Camera, Pose, Quat, TriMesh, Vec3};
use std::path::{Path, PathBuf};
use synth::{preset, Scale, SynthScene};

fn scratch(name: &str) -> PathBuf {
    testkit::scratch_dir("synth", name)
}

/// The tabletop preset at test size.
fn small_tabletop(w: u32, h: u32, views: usize, frames: usize) -> SynthScene {
    let mut s = preset("tabletop", Scale::Small).unwrap();
    s.cameras.width = w;
    s.cameras.height = h;
    s.cameras.views = views;
    for v in &mut s.videos {
        v.frames = frames;
    }
    s
}

fn generate(scene: &SynthScene, dir: &Path) {
    synth::generate(scene, Path::new("."), dir, &mut |_, _, _| {}).unwrap();
}

fn cameras(capture: &Path, n: usize) -> Vec<Camera<f64>> {
    let mats = pganeus_io::read_cameras_npz(&capture.join("cameras_sphere.npz"), n).unwrap();
    let img = pganeus_io::read_png(&capture.join("image").join(synth::frame_name(0, n))).unwrap();
    mats.iter()
        .map(|m| Camera::from_world_mat(&m.world_mat, img.width, img.height).unwrap())
        .collect()
}

fn pose_of(p: &pganeus_io::Pose) -> Pose<f64> {
    Pose::new(Quat::cst(p.q), Vec3::cst(p.t))
}

fn posed(mesh: &TriMesh, p: &pganeus_io::Pose) -> Vec<Vec3<f64>> {
    let pose = pose_of(p);
    mesh.vertices
        .iter()
        .map(|v| pose.transform_point(Vec3::cst(*v)))
        .collect()
}

fn mask_pixel(mask: &pganeus_io::Image, u: f64, v: f64) -> bool {
    let (x, y) = (u.floor() as i64, v.floor() as i64);
    x >= 0 && y >= 0 && (x as u32) < mask.width && (y as u32) < mask.height && mask.pixel(x as u32, y as u32)[0] > 127
}

/// Inside the mask up to half a pixel: a vertex on the silhouette's edge
/// falls on either side of a binary pixel-centre mask, so exactly on-edge
/// vertices count; a misalignment of a pixel or more does not pass.
fn mask_at(mask: &pganeus_io::Image, u: f64, v: f64) -> bool {
    [(0.0, 0.0), (0.5, 0.0), (-0.5, 0.0), (0.0, 0.5), (0.0, -0.5)]
        .iter()
        .any(|(du, dv)| mask_pixel(mask, u + du, v + dv))
}

#[test]
fn static_captures_agree_with_the_posed_mesh() {
    let dir = scratch("static");
    let mut scene = small_tabletop(160, 120, 4, 2);
    scene.videos.truncate(1);
    generate(&scene, &dir);
    let truth = pganeus_io::read_truth(&dir.join("truth.json")).unwrap();
    let body = &truth.bodies[0];
    let mesh = pganeus_io::read_ply(&dir.join(&body.mesh)).unwrap().mesh;
    for sc in &body.static_captures {
        let cap = dir.join(&sc.capture);
        let cams = cameras(&cap, 4);
        let pts = posed(&mesh, &sc.pose);
        for (i, cam) in cams.iter().enumerate() {
            let mask = pganeus_io::read_png(&cap.join("mask").join(synth::frame_name(i, 4)))
                .unwrap()
                .to_gray();
            let inside = pts
                .iter()
                .filter(|p| {
                    let (u, v, _) = cam.project(**p);
                    mask_at(&mask, u, v)
                })
                .count();
            let frac = inside as f64 / pts.len() as f64;
            assert!(
                frac >= 0.98,
                "{} view {i}: {:.1} % of vertices inside the mask",
                sc.capture,
                frac * 100.0
            );
            let cover = geom::silhouette(cam, &mesh, &pose_of(&sc.pose));
            let raster = cover.iter().filter(|c| **c).count() as f64;
            let masked = mask.data.iter().filter(|m| **m > 127).count() as f64;
            let err = (masked - raster).abs() / raster;
            assert!(
                err < 0.01,
                "{} view {i}: mask {masked} px vs rasterised {raster} px ({:.2} %)",
                sc.capture,
                err * 100.0
            );
            assert!(raster > 500.0, "the body is visible and large enough for the test");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn videos_follow_truth_and_cameras_round_trip() {
    let dir = scratch("video");
    let scene = small_tabletop(96, 72, 2, 12);
    generate(&scene, &dir);
    let truth = pganeus_io::read_truth(&dir.join("truth.json")).unwrap();
    let mesh = pganeus_io::read_ply(&dir.join("toy.ply")).unwrap().mesh;
    for (vdesc, video) in scene.videos.iter().zip(&truth.videos) {
        let cap = dir.join(&video.capture);
        let n = video.bodies[0].poses.len();
        assert_eq!(n, 12);
        let index = pganeus_io::open_capture(&cap).unwrap();
        assert_eq!(index.images.len(), n);
        assert_eq!(index.masks.as_ref().map(|m| m.len()), Some(n));
        assert!(
            index.extra_masks.iter().any(|(name, m)| name == "toy" && m.len() == n),
            "mask_toy/ is listed"
        );
        let info = pganeus_io::read_capture_info(&cap.join("capture.json")).unwrap();
        assert_eq!(info.fps, Some(vdesc.fps));
        let cams = cameras(&cap, n);
        // The fixed camera, exactly as placed.
        let k = synth::cameras::intrinsics(96, 72, scene.cameras.fov_deg);
        let c = &vdesc.camera;
        let expect = synth::cameras::orbit(
            Vec3::cst(c.look_at),
            c.distance,
            c.elevation_deg,
            c.azimuth_deg,
            k,
            96,
            72,
        );
        let mats = pganeus_io::read_cameras_npz(&cap.join("cameras_sphere.npz"), n).unwrap();
        for m in &mats {
            assert_eq!(m.world_mat, expect.world_mat(), "world_mat must round-trip exactly");
        }
        let mut moved = 0.0f64;
        for (k, pose) in video.bodies[0].poses.iter().enumerate() {
            let mask = pganeus_io::read_png(&cap.join("mask_toy").join(synth::frame_name(k, n)))
                .unwrap()
                .to_gray();
            let pts = posed(&mesh, pose);
            let inside = pts
                .iter()
                .filter(|p| {
                    let (u, v, _) = cams[k].project(**p);
                    mask_at(&mask, u, v)
                })
                .count();
            let frac = inside as f64 / pts.len() as f64;
            assert!(
                frac >= 0.95,
                "{} frame {k}: {:.1} % of the posed vertices inside mask_toy",
                video.capture,
                frac * 100.0
            );
            moved = moved.max((Vec3::cst(pose.t) - Vec3::cst(video.bodies[0].poses[0].t)).norm());
        }
        assert!(moved > 0.05, "{}: the body moves", video.capture);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn renders_are_deterministic() {
    let (a, b) = (scratch("det-a"), scratch("det-b"));
    let mut scene = small_tabletop(48, 36, 2, 3);
    scene.videos.truncate(1);
    generate(&scene, &a);
    generate(&scene, &b);
    let mut files = Vec::new();
    fn walk(d: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out)
            } else {
                out.push(p)
            }
        }
    }
    walk(&a, &mut files);
    assert!(files.len() > 20);
    for f in files {
        let rel = f.strip_prefix(&a).unwrap();
        assert_eq!(
            std::fs::read(&f).unwrap(),
            std::fs::read(b.join(rel)).unwrap(),
            "{} differs",
            rel.display()
        );
    }
    let _ = std::fs::remove_dir_all(&a);
    let _ = std::fs::remove_dir_all(&b);
}

/// Generate from a TOML text; expect an error mentioning every needle.
fn rejected(name: &str, text: &str, needles: &[&str]) {
    let msg = match toml::from_str::<SynthScene>(text) {
        Err(e) => e.to_string(),
        Ok(scene) => match synth::generate(&scene, Path::new("."), &scratch(name), &mut |_, _, _| {}) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("{name}: a bad scene was accepted"),
        },
    };
    for n in needles {
        assert!(msg.contains(n), "{name}: {msg:?} does not mention {n:?}");
    }
    let _ = std::fs::remove_dir_all(scratch(name));
}

#[test]
fn bad_scenes_are_refused_with_the_field_named() {
    let mut s = small_tabletop(32, 24, 1, 2);
    s.videos.truncate(1);
    let good = toml::to_string(&s).unwrap();
    rejected(
        "shape",
        &good.replacen("kind = \"box\"", "kind = \"torus\"", 1),
        &["torus"],
    );
    rejected(
        "field",
        &good.replacen("mass = 0.08", "mass = 0.08\nmas = 1.0", 1),
        &["mas"],
    );
    rejected(
        "frames",
        &good.replacen("frames = 2", "frames = 0", 1),
        &["videos[0] (slide).frames"],
    );
    rejected(
        "negative",
        &good.replacen("half = [0.02, 0.12, 0.035]", "half = [0.02, -0.12, 0.035]", 1),
        &["obstacles[0] (wall).shape.half", "positive"],
    );
    rejected(
        "overlap",
        &good.replacen("t = [-0.12, -0.02, 0.018]", "t = [-0.12, -0.02, 0.005]", 1),
        &["videos[0] (slide).bodies[0] (toy)", "inside the board"],
    );
    rejected(
        "in-wall",
        &good.replacen("t = [-0.12, -0.02, 0.018]", "t = [0.22, 0.0, 0.03]", 1),
        &["inside the board or an obstacle"],
    );
    rejected(
        "camera",
        &good.replacen("distance = 0.42", "distance = 0.0001", 1).replacen(
            "look_at = [0.07, 0.0, 0.0]",
            "look_at = [0.22, 0.0, 0.03]",
            1,
        ),
        &["camera", "inside"],
    );
}

#[test]
fn printed_presets_read_back_identically() {
    for name in synth::PRESETS {
        for scale in [Scale::Small, Scale::Large] {
            let p = preset(name, scale).unwrap();
            let text = toml::to_string(&p).unwrap();
            let back: SynthScene = toml::from_str(&text).unwrap();
            assert_eq!(back, p, "{name}");
        }
    }
}

#[test]
fn a_body_from_a_mesh_file_renders_through_its_baked_sdf() {
    let dir = scratch("mesh-body");
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = sim::tessellate::wedge_mesh(&sim::sdf::Wedge {
        half: [0.03, 0.02, 0.015],
    });
    pganeus_io::write_ply(
        &dir.join("wedge.ply"),
        &pganeus_io::PlyMesh::from_mesh(mesh),
        pganeus_io::PlyEncoding::Ascii,
    )
    .unwrap();
    let mut scene = small_tabletop(96, 72, 2, 3);
    scene.videos.truncate(1);
    scene.bodies[0].shape = synth::desc::ShapeDesc::Mesh {
        file: "wedge.ply".into(),
    };
    scene.videos[0].bodies[0].t = [-0.12, -0.02, 0.03];
    let out = dir.join("data");
    synth::generate(&scene, &dir, &out, &mut |_, _, _| {}).unwrap();
    let truth = pganeus_io::read_truth(&out.join("truth.json")).unwrap();
    let body_mesh = pganeus_io::read_ply(&out.join("toy.ply")).unwrap().mesh;
    // toy.ply is in the body frame: its centre of mass is the origin (the
    // wedge's is a third of the way in from its box centre).
    let com = sim::mass_properties(&body_mesh, 1.0).center_of_mass;
    assert!(com.norm() < 1e-9, "centre of mass {com:?}");
    assert!(
        (body_mesh.vertices.iter().map(|v| v[0]).fold(f64::MIN, f64::max) - 0.02).abs() < 1e-9,
        "x max = hx − hx/3"
    );
    let sc = &truth.bodies[0].static_captures[0];
    let cap = out.join(&sc.capture);
    let cams = cameras(&cap, 2);
    let pts = posed(&body_mesh, &sc.pose);
    for (i, cam) in cams.iter().enumerate() {
        let mask = pganeus_io::read_png(&cap.join("mask").join(synth::frame_name(i, 2)))
            .unwrap()
            .to_gray();
        // Corners on the board lie on the line where board and body meet,
        // which either may own. The raised corners are tips of an acute
        // silhouette, whose nearest covered pixel centre may be over half a
        // pixel away: they must be within 1.5 px of the mask.
        let raised: Vec<_> = pts.iter().filter(|p| p.z > 2e-3).collect();
        assert_eq!(raised.len(), 2, "a wedge has two corners off the board (its top edge)");
        for p in raised {
            let (u, v, _) = cam.project(*p);
            let near = (0..mask.height).any(|y| {
                (0..mask.width)
                    .any(|x| mask.pixel(x, y)[0] > 127 && (x as f64 + 0.5 - u).hypot(y as f64 + 0.5 - v) <= 1.5)
            });
            assert!(
                near,
                "view {i}: raised corner {p:?} at ({u:.1}, {v:.1}) is not within 1.5 px of the mask"
            );
        }
        let cover = geom::silhouette(cam, &body_mesh, &pose_of(&sc.pose));
        let raster = cover.iter().filter(|c| **c).count() as f64;
        let masked = mask.data.iter().filter(|m| **m > 127).count() as f64;
        assert!(
            (masked - raster).abs() / raster < 0.03,
            "view {i}: mask {masked} vs rasterised {raster}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
