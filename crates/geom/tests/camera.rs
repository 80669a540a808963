//! Pinhole cameras (OpenCV axes: x right, y down, z forward) and the NeuS
//! `world_mat = [[K, 0], [0, 1]] @ W2C`: the world_mat → from_world_mat round
//! trip (with skew, and with any positive or negative scale of the 3×4 part),
//! project ∘ ray = id at pixel centres, positive depth in front, look_at
//! framing, degenerate `up`, and the three error cases.
//!
//! Tolerances: the RQ split is Gram–Schmidt on the rows of `K R`, whose
//! condition number is ~fx/fy ≈ 1 here, so K (entries ≤ ~1500 px) and the
//! pose come back to ~1e-12 relative; the brief's 1e-9 absolute bound is met
//! with room to spare.

use geom::{Camera, CameraError, Intrinsics, Quat, Vec3};

use geom::SplitMix64 as Rng;

const W: u32 = 800;
const H: u32 = 600;

fn random_intrinsics(rng: &mut Rng, skew: bool) -> Intrinsics {
    Intrinsics {
        fx: rng.range(300.0, 1500.0),
        fy: rng.range(300.0, 1500.0),
        cx: rng.range(350.0, 450.0),
        cy: rng.range(250.0, 350.0),
        skew: if skew { rng.range(-20.0, 20.0) } else { 0.0 },
    }
}

/// A camera 2–6 units from a target near the origin, world up +z (or a
/// random up that is not parallel to the view direction).
fn random_camera(rng: &mut Rng, skew: bool) -> (Camera<f64>, Vec3<f64>, Vec3<f64>, Vec3<f64>) {
    let target = rng.vec(0.5);
    let eye = target + rng.dir() * rng.range(2.0, 6.0);
    let fwd = (target - eye).normalize_or(Vec3::new(0.0, 0.0, 1.0));
    let up = loop {
        let u = if rng.range(0.0, 1.0) < 0.5 {
            Vec3::new(0.0, 0.0, 1.0)
        } else {
            rng.dir()
        };
        if u.cross(fwd).norm() > 0.2 {
            break u;
        }
    };
    let k = random_intrinsics(rng, skew);
    (Camera::look_at(eye, target, up, k, W, H), eye, target, up)
}

fn qdist_signless(a: Quat<f64>, b: Quat<f64>) -> f64 {
    let (a, b) = (a.to_array(), b.to_array());
    let plus = (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max);
    let minus = (0..4).map(|i| (a[i] + b[i]).abs()).fold(0.0, f64::max);
    plus.min(minus)
}

fn assert_same_camera(a: &Camera<f64>, b: &Camera<f64>, what: &str) {
    let (ka, kb) = (a.k, b.k);
    for (name, x, y) in [
        ("fx", ka.fx, kb.fx),
        ("fy", ka.fy, kb.fy),
        ("cx", ka.cx, kb.cx),
        ("cy", ka.cy, kb.cy),
        ("skew", ka.skew, kb.skew),
    ] {
        assert!((x - y).abs() < 1e-9, "{what}: {name} {x} vs {y}");
    }
    let dq = qdist_signless(a.world_to_cam.q, b.world_to_cam.q);
    assert!(
        dq < 1e-9,
        "{what}: rotation differs by {dq:e}: {:?} vs {:?}",
        a.world_to_cam.q,
        b.world_to_cam.q
    );
    let dt = (a.world_to_cam.t - b.world_to_cam.t).norm();
    assert!(dt < 1e-9, "{what}: translation differs by {dt:e}");
    assert_eq!((a.width, a.height), (b.width, b.height));
}

#[test]
fn world_mat_is_k_times_w2c() {
    let mut rng = Rng(1);
    let (cam, ..) = random_camera(&mut rng, true);
    let p = cam.world_mat();
    assert_eq!(p[3], [0.0, 0.0, 0.0, 1.0]);
    // P [X; 1] = z (u, v, 1) with (u, v, z) = project(X).
    for _ in 0..50 {
        let x = rng.vec(1.0);
        let (u, v, z) = cam.project(x);
        let h: Vec<f64> = (0..3)
            .map(|i| p[i][0] * x.x + p[i][1] * x.y + p[i][2] * x.z + p[i][3])
            .collect();
        assert!((h[2] - z).abs() < 1e-12 * z.abs().max(1.0));
        assert!(
            (h[0] / h[2] - u).abs() < 1e-9 && (h[1] / h[2] - v).abs() < 1e-9,
            "{h:?} vs ({u}, {v})"
        );
    }
}

#[test]
fn world_mat_round_trip_random_look_at_cameras() {
    let mut rng = Rng(2);
    for n in 0..400 {
        let skew = n % 2 == 1;
        let (cam, ..) = random_camera(&mut rng, skew);
        let back = Camera::from_world_mat(&cam.world_mat(), W, H).expect("valid camera");
        assert_same_camera(&cam, &back, &format!("camera {n} (skew {skew})"));
        // from_world_mat returns the quaternion with w ≥ 0.
        assert!(back.world_to_cam.q.w >= 0.0);
    }
}

#[test]
fn world_mat_round_trip_under_any_scale_of_the_3x4_part() {
    // P is only defined up to scale; a negative scale must not flip R to a
    // reflection or the camera to look backwards.
    let mut rng = Rng(3);
    for n in 0..100 {
        let (cam, ..) = random_camera(&mut rng, n % 2 == 0);
        for s in [2.5, 1e-3, 1.0 / cam.k.fx, 1e4, -1.0, -0.7, -3.0, -1e-3] {
            let mut p = cam.world_mat();
            for row in p.iter_mut().take(3) {
                for v in row.iter_mut() {
                    *v *= s;
                }
            }
            let back = Camera::from_world_mat(&p, W, H).unwrap_or_else(|e| panic!("scale {s}: {e}"));
            assert_same_camera(&cam, &back, &format!("camera {n}, scale {s}"));
        }
    }
}

#[test]
fn project_inverts_ray_at_pixel_centres() {
    let mut rng = Rng(4);
    for n in 0..20 {
        let (cam, eye, ..) = random_camera(&mut rng, n % 2 == 0);
        assert!((cam.center() - eye).norm() < 1e-14 * eye.norm().max(1.0) * 10.0);
        for j in (0..H).step_by(37) {
            for i in (0..W).step_by(41) {
                let (u, v) = (i as f64 + 0.5, j as f64 + 0.5);
                let ray = cam.ray(u, v);
                assert!((ray.dir.norm() - 1.0).abs() < 1e-15);
                assert!((ray.origin - eye).norm() < 1e-13);
                for s in [0.1, 1.0, 7.5] {
                    let (pu, pv, depth) = cam.project(ray.at(s));
                    // Errors ~ f · ε |eye| / (s · dir_z) ≲ 1e-11 px.
                    assert!(
                        (pu - u).abs() < 1e-9 && (pv - v).abs() < 1e-9,
                        "camera {n}: pixel ({u}, {v}) at s = {s} projects to ({pu}, {pv})"
                    );
                    // In front of the camera: positive depth, and the ray is
                    // parametrised by distance so depth ≤ s.
                    assert!(depth > 0.0 && depth <= s * (1.0 + 1e-15), "depth {depth} at s = {s}");
                    // Behind the camera the depth is negative.
                    assert!(cam.project(ray.at(-s)).2 < 0.0);
                }
            }
        }
    }
}

#[test]
fn camera_looks_along_plus_z() {
    // Identity world-to-camera: the camera frame is the world frame.
    let k = Intrinsics {
        fx: 500.0,
        fy: 400.0,
        cx: 320.0,
        cy: 240.0,
        skew: 0.0,
    };
    let cam = Camera {
        k,
        world_to_cam: geom::Pose::identity(),
        width: 640,
        height: 480,
    };
    let (u, v, z) = cam.project(Vec3::new(0.0, 0.0, 2.0));
    assert_eq!((u, v, z), (320.0, 240.0, 2.0));
    // +x is right (u grows), +y is down (v grows).
    let (u, v, _) = cam.project(Vec3::new(1.0, 0.0, 2.0));
    assert_eq!((u, v), (570.0, 240.0));
    let (u, v, _) = cam.project(Vec3::new(0.0, 1.0, 2.0));
    assert_eq!((u, v), (320.0, 440.0));
    assert_eq!(cam.ray(320.0, 240.0).dir, Vec3::new(0.0, 0.0, 1.0));
}

#[test]
fn look_at_frames_the_target() {
    let mut rng = Rng(5);
    for n in 0..300 {
        let (cam, eye, target, up) = random_camera(&mut rng, n % 3 == 0);
        let dist = (target - eye).norm();
        // The target is on the optical axis, at the principal point.
        let (u, v, z) = cam.project(target);
        assert!(
            (u - cam.k.cx).abs() < 1e-9 && (v - cam.k.cy).abs() < 1e-9,
            "({u}, {v}) vs {:?}",
            cam.k
        );
        assert!((z - dist).abs() < 1e-12, "depth {z} vs distance {dist}");
        // World up is up in the image (v decreases, OpenCV y is down) and
        // forward × up is to the right (u increases).
        let fwd = (target - eye) * (1.0 / dist);
        let up_perp = (up - fwd * up.dot(fwd)).normalize_or(Vec3::zero());
        let right = fwd.cross(up_perp);
        let (_, v_up, _) = cam.project(target + up_perp * (0.1 * dist));
        let (u_right, v_right, _) = cam.project(target + right * (0.1 * dist));
        assert!(
            v_up < cam.k.cy - 1.0,
            "camera {n}: up went to v = {v_up} (cy = {})",
            cam.k.cy
        );
        assert!(
            u_right > cam.k.cx + 1.0,
            "camera {n}: right went to u = {u_right} (cx = {})",
            cam.k.cx
        );
        // With zero skew, pure right stays on the principal row.
        if cam.k.skew == 0.0 {
            assert!((v_right - cam.k.cy).abs() < 1e-9);
        }
        // A proper rotation (det +1), not a reflection.
        assert!((cam.world_to_cam.q.to_mat().det() - 1.0).abs() < 1e-14);
    }
}

#[test]
fn look_at_with_up_parallel_to_the_view_direction_still_works() {
    let k = Intrinsics {
        fx: 600.0,
        fy: 600.0,
        cx: 400.0,
        cy: 300.0,
        skew: 0.0,
    };
    for (eye, up) in [
        (Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.0, 0.0, 1.0)),
        (Vec3::new(0.0, 0.0, -5.0), Vec3::new(0.0, 0.0, 1.0)),
        (Vec3::new(3.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)),
        (Vec3::new(-3.0, 0.0, 0.0), Vec3::new(-2.0, 0.0, 0.0)),
        (Vec3::new(1.0, 2.0, 2.0), Vec3::zero()),
    ] {
        let cam = Camera::look_at(eye, Vec3::zero(), up, k, W, H);
        let r = cam.world_to_cam.q.to_mat();
        assert!((r.det() - 1.0).abs() < 1e-14, "eye {eye:?}: det {}", r.det());
        let rrt = r.mul_mat(&r.transpose());
        for i in 0..3 {
            for j in 0..3 {
                assert!((rrt.m[i][j] - if i == j { 1.0 } else { 0.0 }).abs() < 1e-14);
            }
        }
        let (u, v, z) = cam.project(Vec3::zero());
        assert!(
            (u - 400.0).abs() < 1e-9 && (v - 300.0).abs() < 1e-9,
            "eye {eye:?}: ({u}, {v})"
        );
        assert!((z - eye.norm()).abs() < 1e-12);
    }
}

fn valid_world_mat() -> [[f64; 4]; 4] {
    let mut rng = Rng(6);
    random_camera(&mut rng, true).0.world_mat()
}

#[test]
fn non_finite_entries_are_rejected() {
    for (i, j) in [(0, 0), (1, 3), (2, 2), (3, 3), (3, 0)] {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut p = valid_world_mat();
            p[i][j] = bad;
            assert_eq!(
                Camera::from_world_mat(&p, W, H),
                Err(CameraError::NotFinite),
                "entry ({i}, {j}) = {bad}"
            );
        }
    }
}

#[test]
fn singular_blocks_are_rejected() {
    // All-zero 3×3 block.
    let mut p = valid_world_mat();
    for row in p.iter_mut().take(3) {
        row[..3].copy_from_slice(&[0.0; 3]);
    }
    assert_eq!(Camera::from_world_mat(&p, W, H), Err(CameraError::Singular));
    // Rank 2 and rank 1 with small integer entries, so the determinant is
    // exactly 0 in floating point.
    let rank2 = [
        [1.0, 2.0, 3.0, 0.5],
        [4.0, 5.0, 6.0, 1.0],
        [7.0, 8.0, 9.0, 2.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let rank1 = [
        [1.0, 2.0, 3.0, 0.5],
        [2.0, 4.0, 6.0, 1.0],
        [-1.0, -2.0, -3.0, 2.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    for p in [rank2, rank1] {
        let m = geom::Mat3::from_rows([0, 1, 2].map(|i| [p[i][0], p[i][1], p[i][2]]));
        assert_eq!(m.det(), 0.0);
        assert_eq!(Camera::from_world_mat(&p, W, H), Err(CameraError::Singular), "{p:?}");
    }
}

#[test]
fn numerically_singular_blocks_are_rejected() {
    let mut rng = Rng(7);
    for n in 0..20 {
        let mut p = random_camera(&mut rng, n % 2 == 0).0.world_mat();
        // Rank 2: the third row is a copy of the first, or the sum of the first two.
        if n % 2 == 0 {
            p[2] = p[0];
        } else {
            p[2] = [0, 1, 2, 3].map(|j| p[0][j] + p[1][j]);
        }
        let m = geom::Mat3::from_rows([0, 1, 2].map(|i| [p[i][0], p[i][1], p[i][2]]));
        let got = Camera::from_world_mat(&p, W, H);
        assert_eq!(got, Err(CameraError::Singular), "case {n}: det {:e}", m.det());
    }
}

#[test]
fn last_row_must_be_affine() {
    for last in [
        [0.0, 0.0, 1.0, 1.0],
        [0.1, 0.0, 0.0, 1.0],
        [0.0, -1e-6, 0.0, 1.0],
        [0.0, 0.0, 0.0, 0.0],
    ] {
        let mut p = valid_world_mat();
        p[3] = last;
        assert_eq!(
            Camera::from_world_mat(&p, W, H),
            Err(CameraError::LastRowNotAffine),
            "last row {last:?}"
        );
    }
}

#[test]
fn last_row_with_a_scaled_last_entry_is_rejected() {
    for last in [[0.0, 0.0, 0.0, 2.0], [0.0, 0.0, 0.0, -1.0], [0.0, 0.0, 0.0, 1e-11]] {
        let mut p = valid_world_mat();
        p[3] = last;
        assert_eq!(
            Camera::from_world_mat(&p, W, H),
            Err(CameraError::LastRowNotAffine),
            "last row {last:?}"
        );
    }
}

#[test]
fn error_messages_name_the_problem() {
    assert!(CameraError::NotFinite.to_string().contains("NaN"));
    assert!(CameraError::Singular.to_string().contains("singular"));
    assert!(CameraError::LastRowNotAffine.to_string().contains("[0, 0, 0, 1]"));
}

/// A point projects to the same pixel and a depth scaled by 1/radius from a
/// field's unit frame (`p_world = centre + radius · p_unit`), and the frame
/// change undoes itself.
#[test]
fn unit_frame_projects_the_same_and_round_trips() {
    let mut rng = Rng::new(11);
    for _ in 0..50 {
        let (cam, target, _, _) = random_camera(&mut rng, true);
        let (centre, radius) = (rng.vec(1.0), rng.range(0.05, 3.0));
        let unit = cam.in_unit_frame(centre, radius);
        let p_world = target + rng.vec(0.3);
        let (u, v, z) = cam.project(p_world);
        let (uu, vu, zu) = unit.project((p_world - centre) * (1.0 / radius));
        // Relative: a point near the camera's plane projects far out.
        let tol = 1e-9 * u.abs().max(v.abs()).max(1.0);
        assert!(
            (u - uu).abs() < tol && (v - vu).abs() < tol,
            "pixel moved: {u},{v} vs {uu},{vu}"
        );
        assert!(
            (z / radius - zu).abs() < 1e-10 * z.abs().max(1.0),
            "depth {z} / {radius} vs {zu}"
        );
        let back = unit.from_unit_frame(centre, radius);
        let d = back.world_to_cam.t - cam.world_to_cam.t;
        assert!(
            d.norm() < 1e-12 * cam.world_to_cam.t.norm().max(1.0),
            "round trip off by {d:?}"
        );
    }
}
