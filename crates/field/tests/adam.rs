//! Adam: convergence on a quadratic, the fast path against the scalar reference, and sparse (lazy) steps
//! against dense ones on the touched hash-table entries.

use crate::common;

use common::*;
use field::kernels::reference;
use field::{Adam, AdamConfig, GradMode, HashGrid, HashGridConfig, Touched};
use geom::SplitMix64;

#[test]
fn dense_adam_minimises_a_quadratic() {
    // f(p) = Σ a_i (p_i − c_i)², curvatures over three decades.
    let mut rng = SplitMix64::new(1);
    let n = 50_000;
    let a: Vec<f32> = (0..n).map(|i| 10f32.powf((i % 4) as f32 - 1.0)).collect();
    let c = uniform(&mut rng, n, -1.0, 1.0);
    let mut p = vec![0.0f32; n];
    let mut grad = vec![0.0f32; n];
    let cfg = AdamConfig {
        lr: 0.05,
        ..Default::default()
    };
    let mut adam = Adam::new(n);
    let loss = |p: &[f32]| {
        p.iter()
            .zip(&c)
            .zip(&a)
            .map(|((p, c), a)| (a * (p - c) * (p - c)) as f64)
            .sum::<f64>()
    };
    let start = loss(&p);
    for t in 0..600 {
        for i in 0..n {
            grad[i] = 2.0 * a[i] * (p[i] - c[i]);
        }
        let lr = cfg.lr * 0.99f32.powi(t);
        adam.step_dense(&cfg, lr, &mut p, &mut grad);
        assert!(grad.iter().all(|&g| g == 0.0), "grad not zeroed");
    }
    assert_eq!(adam.step, 600);
    let end = loss(&p);
    assert!(end < 1e-6 * start, "loss {start} → {end}");
    assert!(max_abs_diff(&p, &c) < 2e-3, "max |p − c| = {}", max_abs_diff(&p, &c));
}

#[test]
fn dense_step_matches_reference_and_is_thread_independent() {
    let mut rng = SplitMix64::new(2);
    let n = 40_000;
    let cfg = AdamConfig {
        lr: 1e-2,
        weight_decay: 1e-3,
        eps: 1e-8,
        ..Default::default()
    };
    let p0 = uniform(&mut rng, n, -1.0, 1.0);
    let grads: Vec<Vec<f32>> = (0..3).map(|_| uniform(&mut rng, n, -1.0, 1.0)).collect();
    let run = |threads| {
        with_threads(threads, || {
            let mut p = p0.clone();
            let mut adam = Adam::new(n);
            for g in &grads {
                let mut g = g.clone();
                adam.step_dense(&cfg, 3e-3, &mut p, &mut g);
            }
            (p, adam.m, adam.v)
        })
    };
    let (p1, m1, v1) = run(1);
    let (p2, m2, v2) = run(2);
    assert_eq!(p1, p2);
    assert_eq!((m1.clone(), v1.clone()), (m2, v2));
    let (mut p, mut m, mut v) = (p0.clone(), vec![0.0; n], vec![0.0; n]);
    for (t, g) in grads.iter().enumerate() {
        let mut g = g.clone();
        reference::adam_naive(
            &mut p,
            &mut g,
            &mut m,
            &mut v,
            t as u64 + 1,
            3e-3,
            0.9,
            0.99,
            1e-8,
            1e-3,
        );
    }
    assert!(
        max_abs_diff(&p, &p1) < 1e-6,
        "params differ by {}",
        max_abs_diff(&p, &p1)
    );
    assert!(max_rel_diff(&m, &m1) < 1e-6 && max_rel_diff(&v, &v1) < 1e-6);
}

fn grid() -> HashGrid {
    HashGrid::new(&HashGridConfig {
        levels: 4,
        features_per_level: 2,
        log2_table_size: 12,
        base_resolution: 4,
        max_resolution: 64,
    })
}

/// Fill `grad` (kept zero outside `touched`) from a random batch through `encode_backward`.
fn batch_grad(grid: &HashGrid, rng: &mut SplitMix64, grad: &mut [f32], touched: &mut Touched) {
    let n = 200;
    let pts = uniform(rng, n * 3, 0.0, 1.0);
    let d_out = uniform(rng, n * grid.output_dim(), -1.0, 1.0);
    grid.encode_backward(&pts, &d_out, grad, touched, GradMode::Accumulate, grid.levels());
}

#[test]
fn sparse_step_equals_dense_step_on_touched_entries() {
    let grid = grid();
    assert!(grid.level_geom(0).dense && !grid.level_geom(3).dense);
    let np = grid.param_count();
    let cfg = AdamConfig::default();
    let mut rng = SplitMix64::new(3);
    let mut params = vec![0.0f32; np];
    grid.init_params(&mut params, &mut rng);
    let mut grad = vec![0.0f32; np];
    let mut touched = Touched::new(&grid);
    batch_grad(&grid, &mut rng, &mut grad, &mut touched);
    assert!(
        !touched.is_empty() && touched.len() < np / 2,
        "{} of {} entries touched",
        touched.len(),
        np / 2
    );

    // First step from zero moments: a dense step moves exactly the entries with gradient, so both agree everywhere.
    let (mut pd, mut gd, mut dense) = (params.clone(), grad.clone(), Adam::new(np));
    dense.step_dense(&cfg, 1e-2, &mut pd, &mut gd);
    let (mut ps, mut sparse) = (params.clone(), Adam::new(np));
    let touched_before: Vec<Vec<u32>> = (0..4).map(|l| touched.entries(l).collect()).collect();
    sparse.step_sparse(&cfg, 1e-2, &mut ps, &mut grad, &mut touched, &grid);
    assert_eq!(ps, pd);
    assert_eq!((&sparse.m, &sparse.v, sparse.step), (&dense.m, &dense.v, dense.step));
    assert!(grad.iter().all(|&g| g == 0.0), "sparse step left gradient");
    assert!(touched.is_empty(), "sparse step did not clear touched");

    // Second step on another batch: touched entries match a dense step; untouched ones keep params and moments
    // (lazy Adam), where the dense step would have decayed the moments and kept moving the params.
    batch_grad(&grid, &mut rng, &mut grad, &mut touched);
    let touched_now: Vec<Vec<u32>> = (0..4).map(|l| touched.entries(l).collect()).collect();
    let (mut pd2, mut gd2, mut dense2) = (ps.clone(), grad.clone(), dense.clone());
    dense2.step_dense(&cfg, 1e-2, &mut pd2, &mut gd2);
    let (ps_before, m_before) = (ps.clone(), sparse.m.clone());
    sparse.step_sparse(&cfg, 1e-2, &mut ps, &mut grad, &mut touched, &grid);
    let mut moved_lazily = 0;
    for l in 0..4 {
        let start = grid.level_range(l).start;
        for e in 0..grid.level_geom(l).entries {
            let is_touched = touched_now[l].contains(&e);
            for k in 0..2 {
                let i = start + e as usize * 2 + k;
                if is_touched {
                    assert_eq!(ps[i], pd2[i], "level {l} entry {e}");
                    assert_eq!(sparse.m[i], dense2.m[i]);
                } else {
                    assert_eq!(ps[i], ps_before[i], "untouched level {l} entry {e} moved");
                    assert_eq!(sparse.m[i], m_before[i]);
                    if touched_before[l].contains(&e) && pd2[i] != ps[i] {
                        moved_lazily += 1;
                    }
                }
            }
        }
    }
    assert!(moved_lazily > 0, "the dense step should move entries with old momentum");
}

#[test]
fn sparse_adam_fits_a_target_encoding() {
    // Fit the grid so that its encoding of fixed points matches that of a random teacher grid: loss ½|enc − y|².
    let grid = grid();
    let np = grid.param_count();
    let mut rng = SplitMix64::new(4);
    let mut params = vec![0.0f32; np];
    grid.init_params(&mut params, &mut rng);
    let n = 500;
    let pts = uniform(&mut rng, n * 3, 0.0, 1.0);
    let teacher = uniform(&mut rng, np, -0.5, 0.5);
    let mut target = vec![0.0f32; n * grid.output_dim()];
    grid.encode(&teacher, &pts, &mut target, 4);
    let mut out = vec![0.0f32; target.len()];
    let mut grad = vec![0.0f32; np];
    let mut touched = Touched::new(&grid);
    let mut adam = Adam::new(np);
    let cfg = AdamConfig {
        lr: 1e-2,
        ..Default::default()
    };
    let loss = |out: &[f32]| {
        out.iter()
            .zip(&target)
            .map(|(o, y)| 0.5 * ((o - y) * (o - y)) as f64)
            .sum::<f64>()
    };
    grid.encode(&params, &pts, &mut out, 4);
    let start = loss(&out);
    for _ in 0..300 {
        grid.encode(&params, &pts, &mut out, 4);
        let d_out: Vec<f32> = out.iter().zip(&target).map(|(o, y)| o - y).collect();
        grid.encode_backward(&pts, &d_out, &mut grad, &mut touched, GradMode::Accumulate, 4);
        adam.step_sparse(&cfg, cfg.lr, &mut params, &mut grad, &mut touched, &grid);
    }
    grid.encode(&params, &pts, &mut out, 4);
    let end = loss(&out);
    assert!(end < 1e-3 * start, "loss {start} → {end}");
}
