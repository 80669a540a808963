//! With no contact, the centre follows t0 + v0 t + ½ g t² exactly: the
//! velocity held between substeps is the one at their middle (leapfrog), so
//! semi-implicit Euler's ½ g t dt (a few millimetres after a second, which a
//! video of a real throw does not have) is gone.
use crate::common;
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
        let z = 10.0 + 1.0 * t - 0.5 * 9.81 * t * t;
        let p = f[0].pose.t;
        assert!((p.z - z).abs() < 1e-9, "frame {k}: z {} vs {}", p.z, z);
        assert!((p.x - 0.5 * t).abs() < 1e-9 && (p.y + 0.2 * t).abs() < 1e-9);
        // Frame 0 holds the given v0; later frames the velocity half a substep back.
        let tv = if k == 0 { 0.0 } else { t - 0.5 * dt };
        assert!((f[0].v.z - (1.0 - 9.81 * tv)).abs() < 1e-9, "frame {k}: v_z");
    }
}
