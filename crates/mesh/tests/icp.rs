//! ICP recovers a known rigid transform of a partial point cloud (30°, 2 cm)
//! within 0.1° / 0.1 mm, and the automatic start finds a turned-over pose.
use geom::{rotation_distance, Pose, Quat, TriMesh, Vec3};
use mesh::{icp, icp_auto, IcpConfig, IcpTarget};
use sim::sample_surface::sample_surface;
use sim::sdf::{Sdf, Wedge};

/// A wedge (no proper rotational symmetry), as points with outward normals.
fn wedge_cloud(count: usize, seed: u64) -> (Vec<Vec3<f64>>, Vec<Vec3<f64>>) {
    let w = Wedge {
        half: [0.03, 0.02, 0.015],
    };
    let mesh: TriMesh = sim::tessellate::wedge_mesh(&w);
    let pts = sample_surface(&mesh, count, seed);
    let normals = pts.iter().map(|p| w.distance_grad_local(*p).1).collect();
    (pts, normals)
}

/// The visible part (seen from above) of another sample of the wedge, moved
/// by `truth⁻¹`, so that `truth` maps it back onto the target.
fn partial_source(truth: &Pose<f64>, seed: u64) -> Vec<Vec3<f64>> {
    let (body, _) = wedge_cloud(8000, seed);
    let inv = truth.inverse();
    body.into_iter()
        .filter(|p| p.z > -0.012)
        .map(|p| inv.transform_point(p))
        .collect()
}

fn assert_recovers(r: &mesh::IcpResult, truth: &Pose<f64>, what: &str) {
    let angle = rotation_distance(r.transform.q, truth.q).to_degrees();
    let shift = (r.transform.t - truth.t).norm();
    assert!(angle < 0.1, "{what}: rotation off by {angle}°");
    assert!(shift < 1e-4, "{what}: translation off by {} mm", shift * 1e3);
    assert!(r.residual < 1e-4, "{what}: residual {}", r.residual);
}

#[test]
fn recovers_a_known_transform_of_a_partial_cloud() {
    let (target, normals) = wedge_cloud(20000, 1);
    let tgt = IcpTarget::new(target, normals);
    let axis = Vec3::new(0.3, -0.2, 0.4).normalize_or(Vec3::zero());
    // From a start near the answer (10°, 5 mm), plain point-to-plane ICP.
    let near = Pose::new(Quat::exp(axis * 10f64.to_radians()), Vec3::new(0.004, -0.002, 0.002));
    let r = icp(
        &partial_source(&near, 2),
        &tgt,
        Pose::identity(),
        &IcpConfig::default(),
        100,
    );
    assert_recovers(&r, &near, "10°, 5 mm from the identity");
    // 30° and 2 cm (a third of the object) is beyond plain ICP's basin on
    // this shape (it slides along the slope); the automatic start gets it.
    let far = Pose::new(Quat::exp(axis * 30f64.to_radians()), Vec3::new(0.02, -0.01, 0.005));
    let r = icp_auto(&partial_source(&far, 2), &tgt, &IcpConfig::default());
    assert_recovers(&r, &far, "30°, 2 cm with the automatic start");
}

#[test]
fn automatic_start_finds_a_turned_over_pose() {
    let (target, normals) = wedge_cloud(20000, 1);
    let tgt = IcpTarget::new(target, normals);
    let (src_body, _) = wedge_cloud(6000, 3);
    let truth = Pose::new(
        Quat::exp(Vec3::new(1.0, 0.0, 0.0) * std::f64::consts::PI) * Quat::exp(Vec3::new(0.0, 0.0, 0.3)),
        Vec3::new(0.05, 0.02, -0.01),
    );
    let inv = truth.inverse();
    let source: Vec<_> = src_body.iter().map(|p| inv.transform_point(*p)).collect();
    // Plain ICP from the identity does not get there …
    let plain = icp(&source, &tgt, Pose::identity(), &IcpConfig::default(), 100);
    let plain_angle = rotation_distance(plain.transform.q, truth.q).to_degrees();
    // … the automatic start does.
    let r = icp_auto(&source, &tgt, &IcpConfig::default());
    let angle = rotation_distance(r.transform.q, truth.q).to_degrees();
    assert!(
        angle < 0.1,
        "automatic start: rotation off by {angle}° (plain ICP: {plain_angle}°)"
    );
    assert!((r.transform.t - truth.t).norm() < 1e-4);
    assert!(
        plain_angle > 10.0,
        "the test case should defeat plain ICP ({plain_angle}°)"
    );
}

#[test]
fn metrics_of_a_mesh_against_itself_and_a_shifted_copy() {
    let w = Wedge {
        half: [0.03, 0.02, 0.015],
    };
    let m = sim::tessellate::wedge_mesh(&w);
    assert!((mesh::normal_consistency(&m, &m, 2000, 1) - 1.0).abs() < 1e-9);
    assert!((mesh::volume_iou(&m, &m, 20000, 1) - 1.0).abs() < 1e-12);
    // Two copies shifted along x by s: the cross-section area grows linearly
    // in x (0 at x = −hx, A_max at +hx) and sections are nested, so the
    // overlap is ∫ A(x − s) dx = A_max / (2hx) · (2hx − s)² / 2.
    let s = 0.02;
    let shifted = TriMesh::new(
        m.vertices.iter().map(|v| [v[0] + s, v[1], v[2]]).collect(),
        m.faces.clone(),
    );
    let iou = mesh::volume_iou(&m, &shifted, 200000, 2);
    let (hx, area_max) = (0.03f64, 2.0 * 0.015 * 2.0 * 0.02);
    let vol = 0.5 * area_max * 2.0 * hx;
    let overlap = 0.5 * area_max / (2.0 * hx) * (2.0 * hx - s).powi(2);
    let exact = overlap / (2.0 * vol - overlap);
    assert!((iou - exact).abs() < 0.01, "IoU {iou} vs exact {exact}");
}
