//! NeuS rendering of one ray: the backward pass matches finite differences,
//! and the weights along a ray through an analytic sphere match the closed
//! form of NeuS's weight function.
use neus::volume::{render_ray, render_ray_backward, RayGrads, RayInputs};
use testkit::{check_jacobian, GradTolerance};

/// f32 arithmetic: a 1e-3 step and a 2 % relative tolerance are what single precision allows.
const F32_TOL: GradTolerance = GradTolerance {
    eps: 1e-3,
    abs_tol: 2e-4,
    rel_tol: 2e-2,
    pass_fraction: 1.0,
};

/// A ray approaching a surface: SDF decreasing along it, so every section is
/// opaque-ish and away from the α clamp.
struct Case {
    sdf: Vec<f32>,
    cos: Vec<f32>,
    dt: Vec<f32>,
    t: Vec<f32>,
    rgb: Vec<[f32; 3]>,
    inv_s: f32,
    bg: [f32; 3],
}

fn case() -> Case {
    let n = 8;
    let mut rng = geom::SplitMix64::new(5);
    let t: Vec<f32> = (0..n).map(|i| 0.2 + 0.05 * i as f32).collect();
    Case {
        sdf: (0..n).map(|i| 0.12 - 0.035 * i as f32).collect(),
        cos: (0..n).map(|_| -0.4 - 0.5 * rng.next_f64() as f32).collect(),
        dt: vec![0.05; n],
        t,
        rgb: (0..n).map(|_| [0; 3].map(|_| rng.next_f64() as f32)).collect(),
        inv_s: 20.0,
        bg: [0.3, 0.6, 0.9],
    }
}

/// Flatten the inputs to differentiate: sdf, cos, rgb, inv_s, bg.
fn pack(c: &Case) -> Vec<f64> {
    let mut x: Vec<f64> = c.sdf.iter().chain(&c.cos).map(|v| *v as f64).collect();
    x.extend(c.rgb.iter().flatten().map(|v| *v as f64));
    x.push(c.inv_s as f64);
    x.extend(c.bg.iter().map(|v| *v as f64));
    x
}

fn unpack(c: &Case, x: &[f64]) -> Case {
    let n = c.sdf.len();
    Case {
        sdf: x[..n].iter().map(|v| *v as f32).collect(),
        cos: x[n..2 * n].iter().map(|v| *v as f32).collect(),
        dt: c.dt.clone(),
        t: c.t.clone(),
        rgb: (0..n).map(|i| [0, 1, 2].map(|k| x[2 * n + 3 * i + k] as f32)).collect(),
        inv_s: x[5 * n] as f32,
        bg: [0, 1, 2].map(|k| x[5 * n + 1 + k] as f32),
    }
}

fn inputs(c: &Case, anneal: f32) -> RayInputs<'_> {
    RayInputs {
        sdf: &c.sdf,
        cos: &c.cos,
        dt: &c.dt,
        t: &c.t,
        rgb: &c.rgb,
        inv_s: c.inv_s,
        anneal,
        background: c.bg,
    }
}

#[test]
fn backward_matches_finite_differences() {
    let c = case();
    let n = c.sdf.len();
    let (d_rgb, d_op, d_depth) = ([0.7f32, -0.4, 0.25], 0.6f32, -0.3f32);
    for anneal in [0.3f32, 1.0] {
        let loss = |x: &[f64]| {
            let cc = unpack(&c, x);
            let (mut a, mut w) = (vec![0.0; n], vec![0.0; n]);
            let o = render_ray(&inputs(&cc, anneal), &mut a, &mut w);
            let l = (0..3).map(|k| o.rgb[k] * d_rgb[k]).sum::<f32>() + o.opacity * d_op + o.depth * d_depth;
            vec![l as f64]
        };
        let (mut a, mut tr) = (vec![0.0; n], vec![0.0; n]);
        let (mut gs, mut gc, mut gr) = (vec![0.0; n], vec![0.0; n], vec![[0.0f32; 3]; n]);
        let (mut gi, mut gb) = (0.0f32, [0.0f32; 3]);
        render_ray_backward(
            &inputs(&c, anneal),
            d_rgb,
            d_op,
            d_depth,
            &mut a,
            &mut tr,
            RayGrads {
                sdf: &mut gs,
                cos: &mut gc,
                rgb: &mut gr,
                inv_s: &mut gi,
                background: &mut gb,
            },
        );
        let mut analytic: Vec<f64> = gs.iter().chain(&gc).map(|v| *v as f64).collect();
        analytic.extend(gr.iter().flatten().map(|v| *v as f64));
        analytic.push(gi as f64);
        analytic.extend(gb.iter().map(|v| *v as f64));
        let names: Vec<String> = (0..analytic.len()).map(|i| format!("x{i}")).collect();
        check_jacobian("render_ray", &loss, &pack(&c), &[analytic], &names, F32_TOL)
            .unwrap_or_else(|e| panic!("anneal {anneal}: {e}"));
    }
}

/// Φ_s, the logistic CDF.
fn phi(x: f64, s: f64) -> f64 {
    1.0 / (1.0 + (-s * x).exp())
}

#[test]
fn sphere_weights_match_the_closed_form() {
    // A ray along a diameter of a sphere (radius 0.5, centre at distance 1.2):
    // before the centre the SDF is f(t) = 0.7 − t, linear with slope −1, so
    // NeuS's opaque density gives T(t) = Φ_s(f(t)) / Φ_s(f(0)) and the weight
    // of a section [a, b] is exactly (Φ_s(f(a)) − Φ_s(f(b))) / Φ_s(f(0)).
    let (r, c, s) = (0.5f64, 1.2f64, 64.0f64);
    let n = 200;
    let dt = 1.1 / n as f64;
    let mids: Vec<f64> = (0..n).map(|i| (i as f64 + 0.5) * dt).collect();
    let f = |t: f64| (t - c).abs() - r;
    let case = Case {
        sdf: mids.iter().map(|&t| f(t) as f32).collect(),
        cos: vec![-1.0; n],
        dt: vec![dt as f32; n],
        t: mids.iter().map(|&t| t as f32).collect(),
        rgb: vec![[1.0, 1.0, 1.0]; n],
        inv_s: s as f32,
        bg: [0.0; 3],
    };
    let (mut a, mut w) = (vec![0.0; n], vec![0.0; n]);
    let out = render_ray(&inputs(&case, 1.0), &mut a, &mut w);
    let mut worst = 0.0f64;
    for i in 0..n {
        let (lo, hi) = (i as f64 * dt, (i + 1) as f64 * dt);
        let exact = (phi(f(lo), s) - phi(f(hi), s)) / phi(f(0.0), s);
        worst = worst.max((w[i] as f64 - exact).abs());
    }
    // f32 sigmoids and the 1e-5 guard in α bound the agreement.
    assert!(worst < 2e-4, "largest weight error {worst}");
    // The surface is at t = 0.7: the weights peak there and sum to ~1.
    let peak = (0..n).max_by(|&i, &j| w[i].total_cmp(&w[j])).unwrap();
    assert!((mids[peak] - 0.7).abs() <= dt, "peak at {}", mids[peak]);
    assert!((out.opacity - 1.0).abs() < 1e-3, "opacity {}", out.opacity);
    assert!((out.depth as f64 - 0.7).abs() < 0.01, "depth {}", out.depth);
}

/// The background field's compositing (density samples, colour at infinity): its backward matches finite
/// differences for σ, the sample colours and the colour at infinity, with one sample nearly opaque.
#[test]
fn density_compositing_backward_matches_finite_differences() {
    use neus::volume::{composite_density, composite_density_backward};
    let n = 6;
    let mut rng = geom::SplitMix64::new(9);
    let sigma: Vec<f32> = (0..n)
        .map(|i| {
            if i == 3 {
                40.0
            } else {
                0.5 + 3.0 * rng.next_f64() as f32
            }
        })
        .collect();
    let delta: Vec<f32> = (0..n).map(|_| 0.05 + 0.1 * rng.next_f64() as f32).collect();
    let rgb: Vec<[f32; 3]> = (0..n).map(|_| [0; 3].map(|_| rng.next_f64() as f32)).collect();
    let end = [0.2f32, 0.5, 0.8];
    let d_out = [0.6f32, -0.3, 0.9];
    let mut x: Vec<f64> = sigma.iter().map(|v| *v as f64).collect();
    x.extend(rgb.iter().flatten().map(|v| *v as f64));
    x.extend(end.iter().map(|v| *v as f64));
    let loss = |x: &[f64]| {
        let s: Vec<f32> = x[..n].iter().map(|v| *v as f32).collect();
        let c: Vec<[f32; 3]> = (0..n).map(|i| [0, 1, 2].map(|k| x[n + 3 * i + k] as f32)).collect();
        let e = [0, 1, 2].map(|k| x[4 * n + k] as f32);
        let (o, _) = composite_density(&s, &delta, &c, e);
        vec![(0..3).map(|k| (o[k] * d_out[k]) as f64).sum()]
    };
    let (mut ds, mut dc) = (vec![0.0f32; n], vec![[0.0f32; 3]; n]);
    let de = composite_density_backward(&sigma, &delta, &rgb, end, d_out, &mut ds, &mut dc);
    let mut analytic: Vec<f64> = ds.iter().map(|v| *v as f64).collect();
    analytic.extend(dc.iter().flatten().map(|v| *v as f64));
    analytic.extend(de.iter().map(|v| *v as f64));
    let names: Vec<String> = (0..analytic.len()).map(|i| format!("x{i}")).collect();
    check_jacobian("composite_density", &loss, &x, &[analytic], &names, F32_TOL).unwrap_or_else(|e| panic!("{e}"));
}
