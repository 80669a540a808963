//! Spherical harmonics: closed forms, the associated-Legendre reference, and orthonormality on the sphere.

use crate::common;

use common::*;
use field::kernels::reference;
use field::{sh_encode, sh_encode_backward, SH_DIM};
use geom::SplitMix64;
use std::f64::consts::PI;

fn encode(d: [f64; 3]) -> Vec<f32> {
    let mut out = vec![0.0f32; SH_DIM];
    sh_encode(&to_f32(&d), &mut out);
    out
}

#[test]
fn closed_forms_on_the_axes() {
    let c0 = 0.5 / PI.sqrt();
    let c1 = (3.0 / (4.0 * PI)).sqrt();
    let c20 = (5.0 / (16.0 * PI)).sqrt();
    let c22 = (15.0 / (16.0 * PI)).sqrt();
    let c30 = (7.0 / (16.0 * PI)).sqrt();
    let c31 = (21.0 / (32.0 * PI)).sqrt();
    let c33 = (35.0 / (32.0 * PI)).sqrt();
    // +z: only m = 0 terms: Y_l^0 = √((2l+1)/4π) P_l(1).
    let mut e = [0.0; 16];
    e[0] = c0;
    e[2] = c1;
    e[6] = 2.0 * c20;
    e[12] = 2.0 * c30;
    let cases: Vec<([f64; 3], [f64; 16])> = vec![
        ([0.0, 0.0, 1.0], e),
        ([1.0, 0.0, 0.0], {
            // +x: θ = π/2, φ = 0.
            let mut e = [0.0; 16];
            e[0] = c0;
            e[3] = -c1;
            e[6] = -c20;
            e[8] = c22;
            e[13] = c31;
            e[15] = -c33;
            e
        }),
        ([0.0, 1.0, 0.0], {
            // +y: θ = π/2, φ = π/2.
            let mut e = [0.0; 16];
            e[0] = c0;
            e[1] = -c1;
            e[6] = -c20;
            e[8] = -c22;
            e[9] = c33;
            e[11] = c31;
            e
        }),
    ];
    for (d, expect) in cases {
        let got = encode(d);
        for k in 0..16 {
            assert!(
                (got[k] as f64 - expect[k]).abs() < 1e-6,
                "dir {d:?} coefficient {k}: {} vs {}",
                got[k],
                expect[k]
            );
        }
    }
    // A diagonal direction, degree 2 by hand: x = y = z = 1/√3.
    let s = 1.0 / 3f64.sqrt();
    let got = encode([s, s, s]);
    let c2 = (15.0 / (4.0 * PI)).sqrt();
    assert!((got[4] as f64 - c2 / 3.0).abs() < 1e-6); // xy
    assert!((got[5] as f64 + c2 / 3.0).abs() < 1e-6); // −yz
    assert!((got[6] as f64 - 0.0).abs() < 1e-6); // 3z² − 1 = 0
    assert!((got[10] as f64 - (105.0 / (4.0 * PI)).sqrt() * s * s * s).abs() < 1e-6);
    // xyz
}

#[test]
fn matches_associated_legendre_reference() {
    let mut rng = SplitMix64::new(5);
    let n = 2000;
    let dirs: Vec<[f64; 3]> = (0..n).map(|_| rng.dir().to_array()).collect();
    let flat: Vec<f32> = dirs.iter().flat_map(|d| d.map(|x| x as f32)).collect();
    let mut out = vec![0.0f32; n * SH_DIM];
    sh_encode(&flat, &mut out);
    for (i, d) in dirs.iter().enumerate() {
        let d32 = d.map(|x| x as f32 as f64);
        let r = reference::sh_naive(d32);
        for k in 0..16 {
            assert!((out[i * 16 + k] as f64 - r[k]).abs() < 2e-6, "dir {i} coefficient {k}");
        }
    }
}

#[test]
fn orthonormal_on_the_sphere() {
    // Fibonacci-sphere quadrature with 20 000 nodes.
    let n = 20_000;
    let golden = PI * (3.0 - 5f64.sqrt());
    let mut flat = Vec::with_capacity(n * 3);
    for i in 0..n {
        let z = 1.0 - (2 * i + 1) as f64 / n as f64;
        let r = (1.0 - z * z).sqrt();
        let phi = golden * i as f64;
        flat.extend([(r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32]);
    }
    let mut out = vec![0.0f32; n * SH_DIM];
    sh_encode(&flat, &mut out);
    for a in 0..16 {
        for b in 0..16 {
            let g: f64 = (0..n)
                .map(|i| out[i * 16 + a] as f64 * out[i * 16 + b] as f64)
                .sum::<f64>()
                * 4.0
                * PI
                / n as f64;
            let expect = if a == b { 1.0 } else { 0.0 };
            assert!((g - expect).abs() < 1e-3, "<Y{a}, Y{b}> = {g}");
        }
    }
}

#[test]
fn backward_matches_finite_differences() {
    // Any directions (not only unit ones): the backward is the polynomials' derivative.
    let mut rng = SplitMix64::new(9);
    let n = 300;
    let dirs: Vec<[f64; 3]> = (0..n).map(|_| (rng.dir() * rng.range(0.5, 1.5)).to_array()).collect();
    let weights: Vec<f32> = (0..n * SH_DIM).map(|_| rng.range(-1.0, 1.0) as f32).collect();
    let flat: Vec<f32> = dirs.iter().flat_map(|d| d.map(|x| x as f32)).collect();
    let mut grad = vec![0.25f32; n * 3];
    sh_encode_backward(&flat, &weights, &mut grad);
    let h = 1e-3;
    for (i, d) in dirs.iter().enumerate() {
        for k in 0..3 {
            let (mut up, mut down) = (*d, *d);
            up[k] += h;
            down[k] -= h;
            let (a, b) = (encode(up), encode(down));
            let fd: f64 = (0..16)
                .map(|c| weights[i * 16 + c] as f64 * (a[c] as f64 - b[c] as f64) / (2.0 * h))
                .sum();
            // The buffer is added to (it started at 0.25).
            let got = grad[i * 3 + k] as f64 - 0.25;
            assert!(
                (got - fd).abs() < 2e-3 * (1.0 + fd.abs()),
                "dir {i} axis {k}: {got} vs {fd}"
            );
        }
    }
}
