//! Time per 2^16-point batch of the field's hot paths, with 1 and 2 threads:
//! `cargo run -p field --release --example bench_field`. Prints a table and one JSON line per figure.
//! Inputs are built outside the timed blocks; each figure is the median of several repetitions after a warm-up.

use field::{Activation, Adam, AdamConfig, GradMode, HashGrid, HashGridConfig, Mlp, MlpConfig, MlpScratch, Touched};
use geom::SplitMix64;
use std::time::Instant;

const N: usize = 1 << 16;
const REPS: usize = 9;

fn uniform(rng: &mut SplitMix64, n: usize, lo: f64, hi: f64) -> Vec<f32> {
    (0..n).map(|_| rng.range(lo, hi) as f32).collect()
}

/// Median wall time of `reps` runs of `f(true)`, in ms, after one warm-up run. `f(false)` (the reset) runs untimed
/// before each.
fn time_ms(reps: usize, mut f: impl FnMut(bool)) -> f64 {
    f(false);
    f(true);
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            f(false);
            let s = Instant::now();
            f(true);
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(|a, b| a.partial_cmp(b).unwrap());
    t[reps / 2]
}

fn main() {
    let mut rng = SplitMix64::new(2024);
    let grid = HashGrid::new(&HashGridConfig::default());
    let mut grid_params = vec![0.0f32; grid.param_count()];
    grid.init_params(&mut grid_params, &mut rng);
    let points = uniform(&mut rng, N * 3, 0.0, 1.0);
    // NeuS-like batch: 1024 rays × 64 samples, consecutive in the batch, each ray a chord of the unit cube.
    let mut ray_points = Vec::with_capacity(N * 3);
    for _ in 0..N / 64 {
        let o = [0; 3].map(|_| rng.range(0.2, 0.8));
        let d = rng.dir().to_array();
        for k in 0..64 {
            let t = (k as f64 / 63.0 - 0.5) * 0.6;
            ray_points.extend((0..3).map(|i| (o[i] + t * d[i]).clamp(0.0, 1.0) as f32));
        }
    }
    let d_enc = uniform(&mut rng, N * grid.output_dim(), -1e-3, 1e-3);

    let sdf = Mlp::new(&MlpConfig {
        dims: vec![35, 64, 16],
        hidden: Activation::Softplus { beta: 100.0 },
        output: Activation::None,
    });
    let mut sdf_params = vec![0.0f32; sdf.param_count()];
    sdf.init_geometric(&mut sdf_params, &mut rng, 0.5, 3);
    let sdf_in = uniform(&mut rng, N * 35, -1.0, 1.0);
    let sdf_dout = uniform(&mut rng, N * 16, -1.0, 1.0);

    let color = Mlp::new(&MlpConfig {
        dims: vec![34, 64, 64, 3],
        hidden: Activation::Relu,
        output: Activation::Sigmoid,
    });
    let mut color_params = vec![0.0f32; color.param_count()];
    color.init_params(&mut color_params, &mut rng);
    let color_in = uniform(&mut rng, N * 34, -1.0, 1.0);
    let color_dout = uniform(&mut rng, N * 3, -1.0, 1.0);

    println!(
        "field bench: batch of {N} points, hash grid {} levels × 2^{} entries ({} floats), median of {REPS}",
        grid.levels(),
        grid.config().log2_table_size,
        grid.param_count()
    );
    println!("{:<46} {:>10} {:>10}", "figure", "1 thread", "2 threads");
    let mut rows: Vec<(String, [f64; 2])> = Vec::new();
    let mut record = |name: &str, threads: usize, ms: f64| {
        if let Some(r) = rows.iter_mut().find(|r| r.0 == name) {
            r.1[threads - 1] = ms;
        } else {
            let mut v = [0.0; 2];
            v[threads - 1] = ms;
            rows.push((name.to_string(), v));
        }
        println!("{{\"bench\":\"{name}\",\"threads\":{threads},\"n\":{N},\"ms\":{ms:.3}}}");
    };

    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let mut out = vec![0.0f32; N * grid.output_dim()];
            let ms = time_ms(REPS, |_| grid.encode(&grid_params, &points, &mut out, grid.levels()));
            record("hash encode (uniform random points)", threads, ms);
            let ms = time_ms(REPS, |_| {
                grid.encode(&grid_params, &ray_points, &mut out, grid.levels())
            });
            record("hash encode (ray-ordered points)", threads, ms);

            let mut grad = vec![0.0f32; grid.param_count()];
            let mut touched = Touched::new(&grid);
            let mut adam = Adam::new(grid.param_count());
            let cfg = AdamConfig::default();
            let mut p = grid_params.clone();
            // The backward pass accumulates into a buffer that the sparse Adam step zeroes (the training loop);
            // each figure resets with the other operation, untimed.
            let ms = time_ms(REPS, |timed| {
                if timed {
                    grid.encode_backward(&points, &d_enc, &mut grad, &mut touched, GradMode::Accumulate, 16);
                } else {
                    adam.step_sparse(&cfg, 1e-3, &mut p, &mut grad, &mut touched, &grid);
                }
            });
            record("hash encode_backward (uniform)", threads, ms);
            let ms = time_ms(REPS, |timed| {
                if timed {
                    grid.encode_backward(&ray_points, &d_enc, &mut grad, &mut touched, GradMode::Accumulate, 16);
                } else {
                    adam.step_sparse(&cfg, 1e-3, &mut p, &mut grad, &mut touched, &grid);
                }
            });
            record("hash encode_backward (ray-ordered)", threads, ms);
            let ms = time_ms(REPS, |timed| {
                if timed {
                    adam.step_sparse(&cfg, 1e-3, &mut p, &mut grad, &mut touched, &grid);
                } else {
                    grid.encode_backward(&points, &d_enc, &mut grad, &mut touched, GradMode::Accumulate, 16);
                }
            });
            record("adam step_sparse after a uniform batch", threads, ms);
            let ms = time_ms(REPS, |timed| {
                if timed {
                    adam.step_sparse(&cfg, 1e-3, &mut p, &mut grad, &mut touched, &grid);
                } else {
                    grid.encode_backward(&ray_points, &d_enc, &mut grad, &mut touched, GradMode::Accumulate, 16);
                }
            });
            record("adam step_sparse after a ray batch", threads, ms);
            let mut gd = vec![0.0f32; grid.param_count()];
            let ms = time_ms(REPS, |_| adam.step_dense(&cfg, 1e-3, &mut p, &mut gd));
            record("adam step_dense (all grid floats)", threads, ms);

            let mut dp = vec![0.0f32; N * 3];
            let ms = time_ms(REPS, |_| {
                grid.encode_backward_input(&grid_params, &points, &d_enc, &mut dp, GradMode::Overwrite, 16)
            });
            record("hash encode_backward_input (uniform)", threads, ms);
            let ms = time_ms(REPS, |_| {
                grid.encode_backward_input(&grid_params, &ray_points, &d_enc, &mut dp, GradMode::Overwrite, 16)
            });
            record("hash encode_backward_input (ray-ordered)", threads, ms);

            let mut scratch = MlpScratch::new();
            let mut g = vec![0.0f32; sdf.param_count()];
            let mut d_in = vec![0.0f32; N * 35];
            let ms = time_ms(REPS, |_| {
                sdf.forward(&sdf_params, &sdf_in, N, &mut scratch);
                sdf.backward(
                    &sdf_params,
                    &mut scratch,
                    &sdf_dout,
                    &mut g,
                    GradMode::Overwrite,
                    Some(&mut d_in),
                );
            });
            record("mlp 35-64-16 softplus fwd+bwd (+d_input)", threads, ms);
            let ms = time_ms(REPS, |_| {
                sdf.forward(&sdf_params, &sdf_in, N, &mut scratch);
            });
            record("mlp 35-64-16 softplus fwd only", threads, ms);

            let mut scratch = MlpScratch::new();
            let mut g = vec![0.0f32; color.param_count()];
            let mut d_in = vec![0.0f32; N * 34];
            let ms = time_ms(REPS, |_| {
                color.forward(&color_params, &color_in, N, &mut scratch);
                color.backward(
                    &color_params,
                    &mut scratch,
                    &color_dout,
                    &mut g,
                    GradMode::Overwrite,
                    Some(&mut d_in),
                );
            });
            record("mlp 34-64-64-3 relu fwd+bwd (+d_input)", threads, ms);

            // The activation alone, over a hidden layer's outputs (N rows of 64).
            let z = uniform(&mut SplitMix64::new(3), N * 64, -0.05, 0.05);
            let (mut x, mut d) = (z.clone(), vec![0.0f32; N * 64]);
            let ms = time_ms(REPS, |timed| {
                if timed {
                    field::kernels::activate(Activation::Softplus { beta: 100.0 }, &mut x, &mut d);
                } else {
                    x.copy_from_slice(&z);
                }
            });
            record("softplus β=100 over N × 64 (one thread's loop)", threads, ms);

            // The products alone, as the MLP calls them on one chunk of 512 rows (N / 512 chunks, one after
            // another): a layer 64 wide from 35 inputs forward, its input gradient and its weight gradient.
            let chunk = 512;
            let a: Vec<f32> = uniform(&mut SplitMix64::new(1), chunk * 64, -1.0, 1.0);
            let b: Vec<f32> = uniform(&mut SplitMix64::new(2), chunk * 64, -1.0, 1.0);
            let mut c = vec![0.0f32; chunk * 64];
            for (name, m, k, n, transposed) in [
                ("product 512×35 · 35×64 (forward)", chunk, 35, 64, false),
                ("product 512×64 · 64×35 (input gradient)", chunk, 64, 35, false),
                ("product (512×64)ᵀ · 512×35 (weight gradient)", 64, chunk, 35, true),
            ] {
                let (rsa, csa) = if transposed { (1, m) } else { (k, 1) };
                let ms = time_ms(REPS, |_| {
                    for _ in 0..N / chunk {
                        field::small_gemm::gemm_rows(m, k, n, &a, rsa, csa, &b, n, &mut c, n);
                    }
                });
                record(name, threads, ms);
                let ms = time_ms(REPS, |_| {
                    for _ in 0..N / chunk {
                        field::kernels::gemm(m, k, n, 1.0, &a, rsa, csa, &b, n, 1, 0.0, &mut c, n, 1);
                    }
                });
                record(&format!("{name}, matrixmultiply"), threads, ms);
            }
        });
    }
    println!();
    println!("{:<46} {:>10} {:>10}", "figure (ms per batch)", "1 thread", "2 threads");
    for (name, v) in rows {
        println!("{name:<46} {:>10.2} {:>10.2}", v[0], v[1]);
    }
}
