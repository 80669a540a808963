//! A torque-free asymmetric body keeps its world angular momentum, and its
//! kinetic energy to within the integrator's first-order error.
use crate::common;
use common::*;
use geom::Mat3;
use sim::BodyState;

#[test]
fn asymmetric_body_conserves_angular_momentum_in_free_flight() {
    let body = cuboid_body([0.05, 0.02, 0.01], 0.3, 100);
    let w = world_with(
        config(60.0, 121, 20),
        ground(),
        vec![(
            body,
            BodyState::new([0.0, 0.0, 100.0], [0.9, 0.1, 0.3, 0.2], [0.0; 3], [3.0, 1.0, 5.0]),
            contact(0.3, 0.4),
        )],
    );
    let b = &w.bodies[0];
    let momentum = |s: &BodyState<f64>| {
        let r = s.pose.q.to_mat();
        r.mul_mat(&b.inertia).mul_mat(&r.transpose()).mul_vec(s.omega)
    };
    let energy = |s: &BodyState<f64>| {
        let r = s.pose.q.to_mat();
        0.5 * s
            .omega
            .dot(r.mul_mat(&b.inertia).mul_mat(&r.transpose()).mul_vec(s.omega))
    };
    let traj = w.simulate(&w.params());
    let l0 = momentum(&traj.frames[0][0]);
    let e0 = energy(&traj.frames[0][0]);
    let mut omega_changed = 0.0f64;
    for f in &traj.frames {
        let l = momentum(&f[0]);
        assert!(
            (l - l0).norm() < 1e-9 * l0.norm().max(1.0),
            "L drifted: {l:?} vs {l0:?}"
        );
        assert!((energy(&f[0]) - e0).abs() < 0.02 * e0, "energy drift above 2 %");
        omega_changed = omega_changed.max((f[0].omega - traj.frames[0][0].omega).norm());
    }
    // The body tumbles: ω itself must change (it would stay fixed without the gyroscopic step).
    assert!(
        omega_changed > 0.1,
        "ω stayed constant ({omega_changed}), so the body does not precess"
    );
    let _ = Mat3::<f64>::identity();
}
