//! A ball dropped from h (no damping) rebounds to about k_n² h, within 10 %.
mod common;
use common::*;
use sim::BodyState;

#[test]
fn dropped_ball_rebounds_to_restitution_squared_height() {
    for model in MODELS {
        let r = 0.03;
        let h = 0.5;
        for k_n in [0.3, 0.5, 0.8] {
            let w = world_with(
                config_in(model, 120.0, 200, 10),
                ground(),
                vec![(
                    sphere_body(r, 0.1, 1000),
                    BodyState::new([0.0, 0.0, r + h], [1.0, 0.0, 0.0, 0.0], [0.0; 3], [0.0; 3]),
                    contact(k_n, 0.3),
                )],
            );
            let traj = w.simulate(&w.params());
            // Highest point after the first bounce (velocity turned upward).
            let zs: Vec<f64> = traj.frames.iter().map(|f| f[0].pose.t.z - r).collect();
            let bounce = zs.iter().position(|&z| z < 0.01).expect("ball reaches the ground");
            let peak = zs[bounce..].iter().cloned().fold(f64::MIN, f64::max);
            let expected = k_n * k_n * h;
            let err = (peak - expected).abs() / expected;
            assert!(
                err < 0.10,
                "{model:?}: k_n {k_n}: rebound {peak:.4} m, expected {expected:.4} m ({:.1} %)",
                err * 100.0
            );
        }
    }
}
