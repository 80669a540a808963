//! With no contact, the centre follows t0 + v0 t + ½ g t² (the semi-implicit
//! Euler error, ½ g t dt, is accounted for exactly).
mod common;
use common::*;
use sim::BodyState;

#[test]
fn free_fall_matches_closed_form() {
    let cfg = config(60.0, 61, 10);
    let dt = cfg.dt();
    let w = world_with(
        cfg,
        ground(),
        vec![(
            cuboid_body([0.02; 3], 0.1, 200),
            BodyState::new([0.0, 0.0, 10.0], [1.0, 0.0, 0.0, 0.0], [0.5, -0.2, 1.0], [0.0; 3]),
            contact(0.3, 0.4),
        )],
    );
    let traj = w.simulate(&w.params());
    for (k, f) in traj.frames.iter().enumerate() {
        let t = k as f64 / 60.0;
        // Semi-implicit Euler: z_n = z0 + v0 t + ½ g t² + ½ g t dt (velocity updated first).
        let z = 10.0 + 1.0 * t - 0.5 * 9.81 * t * t - 0.5 * 9.81 * t * dt;
        let p = f[0].pose.t;
        assert!((p.z - z).abs() < 1e-9, "frame {k}: z {} vs {}", p.z, z);
        assert!((p.x - 0.5 * t).abs() < 1e-9 && (p.y + 0.2 * t).abs() < 1e-9);
        let exact = 10.0 + 1.0 * t - 0.5 * 9.81 * t * t;
        assert!(
            (p.z - exact).abs() < 0.5 * 9.81 * t * dt + 1e-9,
            "within the scheme's O(dt) of the exact curve"
        );
    }
}
