//! Time of ICP on 50 000 points: a wedge's surface sample (target, with
//! normals, k-d tree built inside the timed block) and another sample of its
//! upper part moved by 10° and 5 mm (plain point-to-plane ICP from the
//! identity) or by 30° and 2 cm (the automatic start, 24 hypotheses on a
//! subsample, then full ICP). Prints one JSON line per figure:
//! `cargo bench -p mesh --bench icp`.

use std::time::Instant;

use geom::{Pose, Quat, Vec3};
use mesh::{icp, icp_auto, IcpConfig, IcpTarget};
use sim::sample_surface::sample_surface;
use sim::sdf::{Sdf, Wedge};

fn main() {
    const N: usize = 50_000;
    let w = Wedge {
        half: [0.03, 0.02, 0.015],
    };
    let mesh = sim::tessellate::wedge_mesh(&w);
    let target = sample_surface(&mesh, N, 1);
    let normals: Vec<_> = target.iter().map(|p| w.distance_grad_local(*p).1).collect();
    let upper: Vec<_> = sample_surface(&mesh, 2 * N, 2)
        .into_iter()
        .filter(|p| p.z > -0.012)
        .take(N)
        .collect();
    let axis = Vec3::new(0.3, -0.2, 0.4).normalize_or(Vec3::zero());
    let cases = [
        ("icp", 10.0, Vec3::new(0.004, -0.002, 0.002)),
        ("icp_auto", 30.0, Vec3::new(0.02, -0.01, 0.005)),
    ];
    for (name, degrees, shift) in cases {
        let truth = Pose::new(Quat::exp(axis * f64::to_radians(degrees)), shift);
        let inv = truth.inverse();
        let source: Vec<_> = upper.iter().map(|p| inv.transform_point(*p)).collect();
        let mut best = f64::INFINITY;
        let mut last = None;
        for _ in 0..3 {
            let t = Instant::now();
            let tgt = IcpTarget::new(target.clone(), normals.clone());
            let r = if name == "icp" {
                icp(&source, &tgt, Pose::identity(), &IcpConfig::default(), 100)
            } else {
                icp_auto(&source, &tgt, &IcpConfig::default())
            };
            best = best.min(t.elapsed().as_secs_f64());
            last = Some(r);
        }
        let r = last.expect("three runs");
        let angle = geom::rotation_distance(r.transform.q, truth.q).to_degrees();
        println!(
            "{{\"bench\": \"{name}\", \"points\": {}, \"target_points\": {N}, \"seconds\": {best:.3}, \"iterations\": {}, \"rotation_error_deg\": {angle:.2e}, \"translation_error_m\": {:.2e}, \"threads\": {}}}",
            source.len(),
            r.iterations,
            (r.transform.t - truth.t).norm(),
            rayon::current_num_threads()
        );
    }
}
