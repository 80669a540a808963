//! Hash-grid encoding: level table, fast kernels against the naive reference, finite differences, thread-count
//! determinism, progressive activation, grad modes and the touched-entry record.

use crate::common;

use common::*;
use field::kernels::{reference, HASH_P1, HASH_P2};
use field::{GradMode, HashGrid, HashGridConfig, Touched};
use geom::SplitMix64;
use testkit::{check_jacobian, GradTolerance};

/// Resolutions 2, 4, 8, 16, 32 (b = 2). With T = 1024, levels 0–2 are dense ((res+1)³ = 27, 125, 729) and levels
/// 3–4 are hashed (4913, 35937 > 1024), so both index paths run.
fn small_cfg(features: usize) -> HashGridConfig {
    HashGridConfig {
        levels: 5,
        features_per_level: features,
        log2_table_size: 10,
        base_resolution: 2,
        max_resolution: 32,
    }
}

/// Random parameters U(−1, 1) (larger than the real init so that errors show).
fn random_params(grid: &HashGrid, rng: &mut SplitMix64) -> Vec<f32> {
    uniform(rng, grid.param_count(), -1.0, 1.0)
}

/// Points mostly in [0,1]³, some outside (clamped) and some on the faces.
fn random_points(rng: &mut SplitMix64, n: usize) -> Vec<f32> {
    let mut pts = uniform(rng, n * 3, -0.1, 1.1);
    for (i, p) in pts.iter_mut().enumerate().take(24) {
        *p = if i % 2 == 0 { 0.0 } else { 1.0 };
    }
    pts
}

#[test]
fn level_table_follows_geometric_progression() {
    let grid = HashGrid::new(&HashGridConfig::default());
    let res: Vec<u32> = (0..16).map(|l| grid.level_geom(l).res).collect();
    assert_eq!(res[0], 16);
    assert_eq!(res[15], 2048);
    let b = HashGridConfig::default().growth_factor();
    for (l, &r) in res.iter().enumerate() {
        assert_eq!(r, (16.0 * b.powi(l as i32) + 1e-6).floor() as u32, "level {l}");
    }
    // Dense exactly while (res+1)³ ≤ 2^19.
    for l in 0..16 {
        let g = grid.level_geom(l);
        let dense_size = (g.res as u64 + 1).pow(3);
        assert_eq!(g.dense, dense_size <= 1 << 19, "level {l}");
        if g.dense {
            assert_eq!(g.entries as u64, dense_size.next_multiple_of(8));
        } else {
            assert_eq!(g.entries, 1 << 19);
        }
        assert_eq!(grid.level_range(l).len(), g.entries as usize * 2);
    }
    assert!(grid.level_geom(0).dense && !grid.level_geom(15).dense);
    assert_eq!(grid.output_dim(), 32);
    assert_eq!(grid.param_count(), grid.level_range(15).end);

    let small = HashGrid::new(&small_cfg(2));
    let res: Vec<u32> = (0..5).map(|l| small.level_geom(l).res).collect();
    assert_eq!(res, [2, 4, 8, 16, 32]);
    let dense: Vec<bool> = (0..5).map(|l| small.level_geom(l).dense).collect();
    assert_eq!(dense, [true, true, true, false, false]);
}

#[test]
fn config_validation_and_serde_defaults() {
    assert!(HashGridConfig::default().validate().is_ok());
    let bad = HashGridConfig {
        features_per_level: 3,
        ..Default::default()
    };
    assert!(bad.validate().is_err());
    let bad = HashGridConfig {
        base_resolution: 64,
        max_resolution: 32,
        ..Default::default()
    };
    assert!(bad.validate().is_err());
    let single = HashGrid::new(&HashGridConfig {
        levels: 1,
        base_resolution: 8,
        max_resolution: 8,
        ..Default::default()
    });
    assert_eq!(single.level_geom(0).res, 8);
}

/// A hashed vertex reads exactly the entry `(x ⊕ y·P1 ⊕ z·P2) mod T`; a dense one `x + (res+1)(y + (res+1)z)`.
#[test]
fn vertices_read_the_entry_of_the_index_formula() {
    let grid = HashGrid::new(&small_cfg(1));
    // params[e] = e within each level, so the output at a vertex is its entry index.
    let mut params = vec![0.0f32; grid.param_count()];
    for l in 0..5 {
        for (e, p) in params[grid.level_range(l)].iter_mut().enumerate() {
            *p = e as f32;
        }
    }
    let mut rng = SplitMix64::new(3);
    for _ in 0..50 {
        let v: [u32; 3] = [0; 3].map(|_| (rng.next_u64() % 33) as u32);
        // At resolution 32 the vertex v/32 is exact in f32; for the coarser levels use their own vertices.
        for l in 0..5 {
            let g = grid.level_geom(l);
            let vl = v.map(|c| c.min(g.res));
            let p: Vec<f32> = vl.iter().map(|&c| c as f32 / g.res as f32).collect();
            let mut out = vec![0.0f32; 5];
            grid.encode(&params, &p, &mut out, 5);
            let expect = if g.dense {
                vl[0] + (g.res + 1) * (vl[1] + (g.res + 1) * vl[2])
            } else {
                (vl[0] ^ vl[1].wrapping_mul(HASH_P1) ^ vl[2].wrapping_mul(HASH_P2)) % g.entries
            };
            assert_eq!(out[l], expect as f32, "level {l} vertex {vl:?}");
        }
    }
}

#[test]
fn encode_matches_reference() {
    for f in [1, 2, 4, 8] {
        let grid = HashGrid::new(&small_cfg(f));
        let mut rng = SplitMix64::new(10 + f as u64);
        let params = random_params(&grid, &mut rng);
        let n = 1000;
        let pts = random_points(&mut rng, n);
        for active in [5, 3, 0] {
            let mut fast = vec![f32::NAN; n * grid.output_dim()];
            grid.encode(&params, &pts, &mut fast, active);
            let mut naive = vec![0.0f32; fast.len()];
            reference::encode_naive(&params, &grid.level_table(), f, &pts, &mut naive, active);
            let err = max_abs_diff(&fast, &naive);
            assert!(err < 1e-5, "F={f} active={active}: max |fast − naive| = {err}");
        }
    }
}

#[test]
fn encode_backward_matches_reference() {
    for f in [1, 2, 4, 8] {
        let grid = HashGrid::new(&small_cfg(f));
        let mut rng = SplitMix64::new(20 + f as u64);
        let n = 700;
        let pts = random_points(&mut rng, n);
        let d_out = uniform(&mut rng, n * grid.output_dim(), -1.0, 1.0);
        for active in [5, 2] {
            let mut fast = vec![f32::NAN; grid.param_count()];
            let mut touched = Touched::new(&grid);
            grid.encode_backward(&pts, &d_out, &mut fast, &mut touched, GradMode::Overwrite, active);
            let mut naive = vec![0.0f32; grid.param_count()];
            reference::encode_backward_naive(&grid.level_table(), f, &pts, &d_out, &mut naive, active);
            let err = max_rel_diff(&fast, &naive);
            assert!(err < 1e-5, "F={f} active={active}: max rel |fast − naive| = {err}");
        }
    }
}

#[test]
fn encode_backward_input_matches_reference() {
    for f in [1, 2, 4, 8] {
        let grid = HashGrid::new(&small_cfg(f));
        let mut rng = SplitMix64::new(30 + f as u64);
        let params = random_params(&grid, &mut rng);
        let n = 700;
        let pts = random_points(&mut rng, n);
        let d_out = uniform(&mut rng, n * grid.output_dim(), -1.0, 1.0);
        for active in [5, 1] {
            let mut fast = vec![f32::NAN; n * 3];
            grid.encode_backward_input(&params, &pts, &d_out, &mut fast, GradMode::Overwrite, active);
            let mut naive = vec![0.0f32; n * 3];
            reference::encode_backward_input_naive(&params, &grid.level_table(), f, &pts, &d_out, &mut naive, active);
            // Sums of up to 8·F·levels terms of size res·|d|·|param| with cancellation: compare to the largest entry.
            let scale = naive.iter().fold(1.0f32, |m, x| m.max(x.abs()));
            let err = max_abs_diff(&fast, &naive) / scale;
            assert!(
                err < 1e-6,
                "F={f} active={active}: max |fast − naive| / max |naive| = {err}"
            );
        }
    }
}

/// The encoding is linear in the parameters, so central differences are exact up to f32 rounding: every entry must
/// pass (pass_fraction 1), with a large step.
#[test]
fn encode_backward_matches_finite_differences() {
    // Resolutions 2, 4, 8 with T = 64: level 0 dense (27 entries → 32), levels 1–2 hashed.
    let cfg = HashGridConfig {
        levels: 3,
        features_per_level: 2,
        log2_table_size: 6,
        base_resolution: 2,
        max_resolution: 8,
    };
    let grid = HashGrid::new(&cfg);
    assert!(grid.level_geom(0).dense && !grid.level_geom(2).dense);
    let mut rng = SplitMix64::new(40);
    let n = 4;
    let pts = uniform(&mut rng, n * 3, 0.0, 1.0);
    let params = random_params(&grid, &mut rng);
    let dim = grid.output_dim();
    let f = |x: &[f64]| {
        let mut out = vec![0.0f32; n * dim];
        grid.encode(&to_f32(x), &pts, &mut out, 3);
        to_f64(&out)
    };
    let mut analytic = Vec::new();
    for row in 0..n * dim {
        let mut d_out = vec![0.0f32; n * dim];
        d_out[row] = 1.0;
        let mut grad = vec![0.0f32; grid.param_count()];
        let mut touched = Touched::new(&grid);
        grid.encode_backward(&pts, &d_out, &mut grad, &mut touched, GradMode::Overwrite, 3);
        analytic.push(to_f64(&grad));
    }
    let tol = GradTolerance {
        eps: 0.25,
        abs_tol: 1e-6,
        rel_tol: 1e-5,
        pass_fraction: 1.0,
    };
    check_jacobian(
        "hash grid d/dparams",
        &f,
        &to_f64(&params),
        &analytic,
        &names("param", grid.param_count()),
        tol,
    )
    .unwrap();
}

/// Within a cell the interpolant is linear along each axis, so central differences are exact there; the points are
/// drawn so that every level's fractional position is in [0.1, 0.9] and ±eps·res (≤ 0.032) never crosses a cell
/// face. What remains is f32 rounding of the outputs (~1e-7 / 2e-3 ≈ 5e-5).
#[test]
fn encode_backward_input_matches_finite_differences() {
    let grid = HashGrid::new(&small_cfg(2));
    let mut rng = SplitMix64::new(50);
    let params = random_params(&grid, &mut rng);
    let n = 6;
    let mut pts = Vec::new();
    while pts.len() < n * 3 {
        let p = [0; 3].map(|_| rng.range(0.0, 1.0));
        let ok = (0..5).all(|l| {
            let r = grid.level_geom(l).res as f64;
            p.iter().all(|&x| {
                let fr = x * r - (x * r).floor();
                (0.1..=0.9).contains(&fr)
            })
        });
        if ok {
            pts.extend(p.map(|x| x as f32));
        }
    }
    let dim = grid.output_dim();
    let f = |x: &[f64]| {
        let mut out = vec![0.0f32; n * dim];
        grid.encode(&params, &to_f32(x), &mut out, 5);
        to_f64(&out)
    };
    let mut analytic = Vec::new();
    for row in 0..n * dim {
        let mut d_out = vec![0.0f32; n * dim];
        d_out[row] = 1.0;
        let mut dp = vec![0.0f32; n * 3];
        grid.encode_backward_input(&params, &pts, &d_out, &mut dp, GradMode::Overwrite, 5);
        analytic.push(to_f64(&dp));
    }
    let tol = GradTolerance {
        eps: 1e-3,
        abs_tol: 2e-3,
        rel_tol: 1e-3,
        pass_fraction: 1.0,
    };
    let worst = check_jacobian(
        "hash grid d/dpoints",
        &f,
        &to_f64(&pts),
        &analytic,
        &names("x", n * 3),
        tol,
    )
    .unwrap();
    assert!(worst < 1e-2, "worst relative error {worst}");
}

#[test]
fn one_and_two_threads_give_identical_results() {
    let grid = HashGrid::new(&small_cfg(2));
    let mut rng = SplitMix64::new(60);
    let params = random_params(&grid, &mut rng);
    let n = 3000;
    let pts = random_points(&mut rng, n);
    let d_out = uniform(&mut rng, n * grid.output_dim(), -1.0, 1.0);
    let run = |threads| {
        with_threads(threads, || {
            let mut out = vec![0.0f32; n * grid.output_dim()];
            grid.encode(&params, &pts, &mut out, 5);
            let mut grad = vec![0.0f32; grid.param_count()];
            let mut touched = Touched::new(&grid);
            grid.encode_backward(&pts, &d_out, &mut grad, &mut touched, GradMode::Overwrite, 5);
            let mut dp = vec![0.0f32; n * 3];
            grid.encode_backward_input(&params, &pts, &d_out, &mut dp, GradMode::Overwrite, 5);
            let lists: Vec<Vec<u32>> = (0..5).map(|l| touched.entries(l).collect()).collect();
            (out, grad, dp, lists)
        })
    };
    let (o1, g1, d1, t1) = run(1);
    let (o2, g2, d2, t2) = run(2);
    assert!(
        o1.iter().zip(&o2).all(|(a, b)| a.to_bits() == b.to_bits()),
        "encode differs"
    );
    assert!(
        g1.iter().zip(&g2).all(|(a, b)| a.to_bits() == b.to_bits()),
        "encode_backward differs"
    );
    assert!(
        d1.iter().zip(&d2).all(|(a, b)| a.to_bits() == b.to_bits()),
        "encode_backward_input differs"
    );
    assert_eq!(t1, t2, "touched lists differ");
}

#[test]
fn progressive_activation_zeroes_inactive_levels() {
    let grid = HashGrid::new(&small_cfg(2));
    let mut rng = SplitMix64::new(70);
    let params = random_params(&grid, &mut rng);
    let n = 300;
    let pts = uniform(&mut rng, n * 3, 0.0, 1.0);
    let dim = grid.output_dim();
    let active = 2;
    let mut full = vec![0.0f32; n * dim];
    grid.encode(&params, &pts, &mut full, 5);
    let mut part = vec![f32::NAN; n * dim];
    grid.encode(&params, &pts, &mut part, active);
    for p in 0..n {
        for c in 0..dim {
            let v = part[p * dim + c];
            if c < active * 2 {
                assert_eq!(v, full[p * dim + c]);
            } else {
                assert_eq!(v, 0.0, "point {p} column {c}");
            }
        }
    }
    // Parameter gradient: zero (Overwrite) and untouched on inactive levels.
    let d_out = uniform(&mut rng, n * dim, -1.0, 1.0);
    let mut grad = vec![7.0f32; grid.param_count()];
    let mut touched = Touched::new(&grid);
    grid.encode_backward(&pts, &d_out, &mut grad, &mut touched, GradMode::Overwrite, active);
    for l in 0..5 {
        let g = &grad[grid.level_range(l)];
        if l < active {
            assert!(g.iter().any(|&x| x != 0.0), "active level {l} got no gradient");
            assert!(touched.entries(l).next().is_some());
        } else {
            assert!(g.iter().all(|&x| x == 0.0), "inactive level {l} has gradient");
            assert!(touched.entries(l).next().is_none(), "inactive level {l} touched");
        }
    }
    // Accumulate leaves inactive levels alone.
    let mut acc = vec![7.0f32; grid.param_count()];
    grid.encode_backward(&pts, &d_out, &mut acc, &mut touched, GradMode::Accumulate, active);
    assert!(acc[grid.level_range(4)].iter().all(|&x| x == 7.0));
    // Input gradient: as if d_out were zero on the inactive levels.
    let mut d_masked = d_out.clone();
    for p in 0..n {
        d_masked[p * dim + active * 2..(p + 1) * dim].fill(0.0);
    }
    let mut a = vec![0.0f32; n * 3];
    grid.encode_backward_input(&params, &pts, &d_out, &mut a, GradMode::Overwrite, active);
    let mut b = vec![0.0f32; n * 3];
    grid.encode_backward_input(&params, &pts, &d_masked, &mut b, GradMode::Overwrite, 5);
    assert!(max_abs_diff(&a, &b) < 1e-4 * b.iter().fold(1.0f32, |m, x| m.max(x.abs())));
}

#[test]
fn grad_modes() {
    let grid = HashGrid::new(&small_cfg(2));
    let mut rng = SplitMix64::new(80);
    let params = random_params(&grid, &mut rng);
    let n = 200;
    let pts = uniform(&mut rng, n * 3, 0.0, 1.0);
    let d_out = uniform(&mut rng, n * grid.output_dim(), -1.0, 1.0);
    let mut touched = Touched::new(&grid);
    let mut once = vec![3.0f32; grid.param_count()];
    grid.encode_backward(&pts, &d_out, &mut once, &mut touched, GradMode::Overwrite, 5);
    let mut twice = vec![0.0f32; grid.param_count()];
    grid.encode_backward(&pts, &d_out, &mut twice, &mut touched, GradMode::Accumulate, 5);
    grid.encode_backward(&pts, &d_out, &mut twice, &mut touched, GradMode::Accumulate, 5);
    let doubled: Vec<f32> = once.iter().map(|x| 2.0 * x).collect();
    assert!(max_abs_diff(&twice, &doubled) < 1e-5);
    let mut ignored = vec![3.0f32; grid.param_count()];
    let mut fresh = Touched::new(&grid);
    grid.encode_backward(&pts, &d_out, &mut ignored, &mut fresh, GradMode::Ignore, 5);
    assert!(ignored.iter().all(|&x| x == 3.0) && fresh.is_empty());

    let mut dp_once = vec![5.0f32; n * 3];
    grid.encode_backward_input(&params, &pts, &d_out, &mut dp_once, GradMode::Overwrite, 5);
    let mut dp_acc = vec![1.0f32; n * 3];
    grid.encode_backward_input(&params, &pts, &d_out, &mut dp_acc, GradMode::Accumulate, 5);
    let plus_one: Vec<f32> = dp_once.iter().map(|x| x + 1.0).collect();
    assert!(max_rel_diff(&dp_acc, &plus_one) < 1e-5);
    let mut dp_ign = vec![5.0f32; n * 3];
    grid.encode_backward_input(&params, &pts, &d_out, &mut dp_ign, GradMode::Ignore, 5);
    assert!(dp_ign.iter().all(|&x| x == 5.0));
}

#[test]
/// With positive upstream gradients every corner read gets a positive gradient, so the touched set must equal the
/// set of entries with nonzero gradient.
fn touched_marks_exactly_the_entries_with_gradient() {
    let grid = HashGrid::new(&small_cfg(2));
    let mut rng = SplitMix64::new(90);
    let n = 400;
    let pts = uniform(&mut rng, n * 3, 0.0, 1.0);
    let d_out = uniform(&mut rng, n * grid.output_dim(), 0.5, 1.0);
    let mut grad = vec![0.0f32; grid.param_count()];
    let mut touched = Touched::new(&grid);
    grid.encode_backward(&pts, &d_out, &mut grad, &mut touched, GradMode::Overwrite, 5);
    // A second pass over half the points changes nothing in the set.
    grid.encode_backward(
        &pts[..n * 3 / 2],
        &d_out[..n * grid.output_dim() / 2],
        &mut grad,
        &mut touched,
        GradMode::Accumulate,
        5,
    );
    let mut total = 0;
    for l in 0..5 {
        let range = grid.level_range(l);
        let entries: Vec<u32> = touched.entries(l).collect();
        assert!(
            entries.windows(2).all(|w| w[0] < w[1]),
            "entries not ascending and unique at level {l}"
        );
        total += entries.len();
        for (e, chunk) in grad[range].chunks_exact(2).enumerate() {
            let nonzero = chunk.iter().any(|&x| x != 0.0);
            let listed = touched.contains(l, e as u32);
            assert_eq!(listed, entries.binary_search(&(e as u32)).is_ok());
            assert_eq!(
                listed, nonzero,
                "level {l} entry {e}: touched {listed}, gradient {nonzero}"
            );
        }
    }
    assert_eq!(touched.len(), total);
    touched.clear();
    assert!(touched.is_empty());
    assert!((0..5).all(|l| (0..grid.level_geom(l).entries).all(|e| !touched.contains(l, e))));
}

#[test]
fn points_outside_the_unit_cube_are_clamped() {
    let grid = HashGrid::new(&small_cfg(2));
    let mut rng = SplitMix64::new(100);
    let params = random_params(&grid, &mut rng);
    let outside = [-0.3f32, 0.4, 1.7, 2.0, -1.0, 0.25];
    let clamped: Vec<f32> = outside.iter().map(|x| x.clamp(0.0, 1.0)).collect();
    let dim = grid.output_dim();
    let mut a = vec![0.0f32; 2 * dim];
    let mut b = vec![0.0f32; 2 * dim];
    grid.encode(&params, &outside, &mut a, 5);
    grid.encode(&params, &clamped, &mut b, 5);
    assert_eq!(a, b);
    let d_out = vec![1.0f32; 2 * dim];
    let mut dp = vec![0.0f32; 6];
    grid.encode_backward_input(&params, &outside, &d_out, &mut dp, GradMode::Overwrite, 5);
    for (i, (&x, &g)) in outside.iter().zip(&dp).enumerate() {
        if !(0.0..=1.0).contains(&x) {
            assert_eq!(g, 0.0, "coordinate {i} = {x} is clamped");
        } else {
            assert_ne!(g, 0.0, "coordinate {i} = {x} is inside");
        }
    }
}

#[test]
fn init_params_is_small_and_seeded() {
    let grid = HashGrid::new(&small_cfg(2));
    let mut a = vec![0.0f32; grid.param_count()];
    let mut b = vec![0.0f32; grid.param_count()];
    grid.init_params(&mut a, &mut SplitMix64::new(1));
    grid.init_params(&mut b, &mut SplitMix64::new(1));
    assert_eq!(a, b);
    assert!(a.iter().all(|x| x.abs() <= 1e-4));
    assert!(a.iter().any(|x| x.abs() > 5e-5));
}
