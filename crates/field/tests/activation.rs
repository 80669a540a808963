//! The vectorisable softplus and sigmoid of the activation kernel against f64 closed forms.

use field::kernels::{activate, reference};
use field::Activation;

#[test]
fn fast_activations_match_the_f64_reference() {
    // z from −3 to 3 in fine steps, plus the extremes.
    let mut z: Vec<f32> = (-30_000..=30_000).map(|i| i as f32 * 1e-4).collect();
    z.extend([-1e4, -100.0, -88.0, -87.5, 87.5, 100.0, 1e4, 0.0, -0.0, 1e-30, -1e-30]);
    for act in [
        Activation::Softplus { beta: 1.0 },
        Activation::Softplus { beta: 10.0 },
        Activation::Softplus { beta: 100.0 },
        Activation::Sigmoid,
        Activation::Relu,
    ] {
        let mut v = z.clone();
        let mut d = vec![0.0f32; z.len()];
        activate(act, &mut v, &mut d);
        for i in 0..z.len() {
            let (rv, rd) = reference::activation_naive(act, z[i]);
            let ev = (v[i] - rv).abs() / rv.abs().max(1e-3);
            let ed = (d[i] - rd).abs();
            assert!(
                ev < 1e-6 || (v[i] - rv).abs() < 1e-12,
                "{act:?} z={}: value {} vs {rv}",
                z[i],
                v[i]
            );
            assert!(ed < 1e-6, "{act:?} z={}: derivative {} vs {rd}", z[i], d[i]);
            assert!(v[i].is_finite() && d[i].is_finite());
        }
    }
}
