//! Fully connected networks as NeuS uses them (SDF network with geometric initialisation, colour network), on
//! batches of rows: each layer of a row chunk is one product ([`crate::small_gemm`]), chunks run in parallel with rayon,
//! and the parameter gradient is reduced over chunks in a fixed order so that the thread count does not change it.

use crate::kernels;
use crate::small_gemm::gemm_rows;
use crate::{Activation, GradMode};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Largest row chunk of one rayon task.
const MAX_CHUNK_ROWS: usize = 512;
/// Parameter floats per task in the gradient reduction.
const REDUCE_BLOCK: usize = 2048;

/// Network shape and activations.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MlpConfig {
    /// `[in, hidden…, out]`; at least two entries, all ≥ 1.
    pub dims: Vec<usize>,
    /// Activation after every hidden layer.
    pub hidden: Activation,
    /// Activation after the last layer.
    pub output: Activation,
}

#[derive(Clone, Copy, Debug)]
struct Layer {
    n_in: usize,
    n_out: usize,
    /// Offset of W (n_out × n_in, row-major) in the flat parameters.
    w: usize,
    /// Offset of b (n_out).
    b: usize,
    act: Activation,
}

/// A multilayer perceptron over a flat parameter buffer: layer `l` stores W (out×in, row-major) then b (out).
#[derive(Clone, Debug)]
pub struct Mlp {
    cfg: MlpConfig,
    layers: Vec<Layer>,
    param_count: usize,
}

impl Mlp {
    /// Panics if `dims` has fewer than two entries or a zero entry.
    pub fn new(cfg: &MlpConfig) -> Self {
        assert!(cfg.dims.len() >= 2, "Mlp: dims needs [in, …, out], got {:?}", cfg.dims);
        assert!(cfg.dims.iter().all(|&d| d > 0), "Mlp: zero width in {:?}", cfg.dims);
        let nl = cfg.dims.len() - 1;
        let mut layers = Vec::with_capacity(nl);
        let mut off = 0;
        for l in 0..nl {
            let (n_in, n_out) = (cfg.dims[l], cfg.dims[l + 1]);
            let act = if l + 1 == nl { cfg.output } else { cfg.hidden };
            layers.push(Layer {
                n_in,
                n_out,
                w: off,
                b: off + n_in * n_out,
                act,
            });
            off += n_in * n_out + n_out;
        }
        Self {
            cfg: cfg.clone(),
            layers,
            param_count: off,
        }
    }

    pub fn config(&self) -> &MlpConfig {
        &self.cfg
    }

    pub fn param_count(&self) -> usize {
        self.param_count
    }

    pub fn input_dim(&self) -> usize {
        self.cfg.dims[0]
    }

    pub fn output_dim(&self) -> usize {
        *self.cfg.dims.last().unwrap()
    }

    pub fn num_layers(&self) -> usize {
        self.layers.len()
    }

    /// Where layer `l`'s W (out×in, row-major) lies in the flat parameters.
    pub fn weight_range(&self, l: usize) -> Range<usize> {
        let ly = self.layers[l];
        ly.w..ly.w + ly.n_in * ly.n_out
    }

    /// Where layer `l`'s bias lies in the flat parameters.
    pub fn bias_range(&self, l: usize) -> Range<usize> {
        let ly = self.layers[l];
        ly.b..ly.b + ly.n_out
    }

    /// `(n_in, n_out, weight offset, bias offset, activation)` per layer, the form the reference kernels take.
    pub fn layer_table(&self) -> Vec<(usize, usize, usize, usize, Activation)> {
        self.layers.iter().map(|l| (l.n_in, l.n_out, l.w, l.b, l.act)).collect()
    }

    /// Kaiming-uniform-like: W ~ U(±√(6/n_in)), zero biases.
    pub fn init_params(&self, params: &mut [f32], rng: &mut geom::SplitMix64) {
        assert_eq!(params.len(), self.param_count, "Mlp::init_params: params length");
        params.fill(0.0);
        for (l, ly) in self.layers.iter().enumerate() {
            let bound = (6.0 / ly.n_in as f64).sqrt();
            for w in &mut params[self.weight_range(l)] {
                *w = rng.range(-bound, bound) as f32;
            }
        }
    }

    /// Geometric initialisation (Atzmon & Lipman 2020, SAL; as NeuS and IDR): output 0 starts as the SDF
    /// `|x| − radius` of a sphere in the first `n_plain_inputs` inputs. Weights from the remaining inputs (hash
    /// features) and all biases but the SDF's start at 0, so they do not disturb it. Needs ≥ 1 hidden layer.
    ///
    /// As NeuS: hidden layers N(0, 2/n_out), the SDF row of the last layer N(√π/√n_in, 1e-4), its bias −radius.
    /// Two changes, both exact for ReLU networks:
    /// - The first layer is scaled up by `k` so that its rows have unit (expected) norm, and the SDF row down by
    ///   `k`. A ReLU network is positively homogeneous, so this is the same function; with softplus it keeps the
    ///   softplus–ReLU gap (`ln 2/β` per unit at z = 0, β = 100) from growing with the width.
    /// - With 3 plain inputs, the first layer's rows are ± pairs of a randomly rotated Fibonacci sphere of
    ///   directions instead of Gaussian draws. A pair gives `relu(z) + relu(−z) = |z|`, and the directions are a
    ///   quadrature of the sphere rather than a Monte-Carlo sample, so with one hidden layer (SDF row weights
    ///   `4/h`) the start is the sphere up to quadrature and softplus error (width 64: mean error ~1e-3).
    ///   Deeper networks keep NeuS's Gaussian hidden layers and its Monte-Carlo error (~0.05–0.1 mean at widths
    ///   64–256).
    ///
    /// Outputs other than 0 (geometric features) get the `init_params` rule.
    pub fn init_geometric(&self, params: &mut [f32], rng: &mut geom::SplitMix64, radius: f32, n_plain_inputs: usize) {
        assert_eq!(params.len(), self.param_count, "Mlp::init_geometric: params length");
        let nl = self.layers.len();
        assert!(nl >= 2, "Mlp::init_geometric: needs at least one hidden layer");
        assert!(
            (1..=self.input_dim()).contains(&n_plain_inputs),
            "Mlp::init_geometric: n_plain_inputs {n_plain_inputs} not in 1..={}",
            self.input_dim()
        );
        params.fill(0.0);
        let first = self.layers[0];
        let h1 = first.n_out;
        let pairs = if n_plain_inputs == 3 { h1 / 2 } else { 0 };
        // NeuS draws first-layer rows N(0, 2/h) (expected norm √(2·n_plain/h)); k scales them to unit norm.
        let k = (h1 as f64 / (2.0 * n_plain_inputs as f64)).sqrt();
        {
            let w = &mut params[self.weight_range(0)];
            if pairs > 0 {
                for (j, u) in fibonacci_directions(pairs, rng).into_iter().enumerate() {
                    for d in 0..3 {
                        w[j * first.n_in + d] = u[d] as f32;
                        w[(j + pairs) * first.n_in + d] = -u[d] as f32;
                    }
                }
            }
            let std = k * (2.0 / h1 as f64).sqrt();
            for j in 2 * pairs..h1 {
                for d in 0..n_plain_inputs {
                    w[j * first.n_in + d] = (std * gauss(rng)) as f32;
                }
            }
        }
        for l in 1..nl - 1 {
            let std = (2.0 / self.layers[l].n_out as f64).sqrt();
            for w in &mut params[self.weight_range(l)] {
                *w = (std * gauss(rng)) as f32;
            }
        }
        let last = self.layers[nl - 1];
        let w = &mut params[self.weight_range(nl - 1)];
        let (row0, rest) = w.split_at_mut(last.n_in);
        if nl == 2 && pairs > 0 {
            // Σ_pairs |u_j·x| ≈ (h/2)·E|u·x̂|·|x| = (h/4)|x| for unit directions u uniform on the sphere.
            let c = 4.0 / h1 as f64;
            for (j, x) in row0.iter_mut().enumerate() {
                *x = if j < 2 * pairs {
                    (c + 1e-4 * gauss(rng) / k) as f32
                } else {
                    0.0
                };
            }
        } else {
            let mean = (std::f64::consts::PI / last.n_in as f64).sqrt();
            for x in row0.iter_mut() {
                *x = ((mean + 1e-4 * gauss(rng)) / k) as f32;
            }
        }
        let bound = (6.0 / last.n_in as f64).sqrt();
        for x in rest {
            *x = rng.range(-bound, bound) as f32;
        }
        params[last.b] = -radius;
    }

    /// Initialisation for a scene: output 0 starts as the signed distance `n·x − offset` of the half-space below
    /// the plane `n·x = offset` (unit `normal`, inside below), in the first 3 inputs. Needs exactly one hidden
    /// layer with a softplus or ReLU activation and 3 plain inputs.
    ///
    /// A ± pair of hidden units with rows `±u` and biases `±b` gives `act(u·x + b) − act(−u·x − b) = u·x + b`
    /// exactly for softplus (and ReLU), so any SDF row weights `c_j` on the pairs give the linear function
    /// `(Σ c_j u_j)·x + Σ c_j b_j`. The directions `u_j` are a randomly rotated Fibonacci sphere (as in
    /// [`Mlp::init_geometric`]) and the biases spread over ±0.5, so the units start different from one another
    /// and learn different things; `c` is the least-norm solution of `Σ c_j u_j = n` and the output bias
    /// absorbs the rest. Weights from the other inputs (hash features) start at 0; outputs other than 0 get the
    /// `init_params` rule.
    pub fn init_geometric_plane(&self, params: &mut [f32], rng: &mut geom::SplitMix64, normal: [f32; 3], offset: f32) {
        assert_eq!(
            params.len(),
            self.param_count,
            "Mlp::init_geometric_plane: params length"
        );
        assert_eq!(
            self.layers.len(),
            2,
            "Mlp::init_geometric_plane: needs exactly one hidden layer"
        );
        let (first, last) = (self.layers[0], self.layers[1]);
        assert!(
            first.n_in >= 3 && first.n_out >= 2,
            "Mlp::init_geometric_plane: needs ≥ 3 inputs and ≥ 2 hidden units"
        );
        params.fill(0.0);
        let pairs = first.n_out / 2;
        let dirs = fibonacci_directions(pairs, rng);
        let biases: Vec<f64> = (0..pairs).map(|_| rng.range(-0.5, 0.5)).collect();
        // c = Uᵀ (U Uᵀ)⁻¹ n: the least-norm row weights whose pairs sum to the plane's normal.
        let mut gram = geom::Mat3::<f64>::zero();
        for u in &dirs {
            let u = geom::Vec3::cst(*u);
            gram = gram.add(&geom::Mat3::outer(u, u));
        }
        let n = geom::Vec3::new(normal[0] as f64, normal[1] as f64, normal[2] as f64);
        let y = gram.try_inverse().unwrap_or(geom::Mat3::identity()).mul_vec(n);
        let c: Vec<f64> = dirs.iter().map(|u| u[0] * y.x + u[1] * y.y + u[2] * y.z).collect();
        {
            let w = &mut params[self.weight_range(0)];
            for j in 0..pairs {
                for d in 0..3 {
                    w[j * first.n_in + d] = dirs[j][d] as f32;
                    w[(j + pairs) * first.n_in + d] = -dirs[j][d] as f32;
                }
            }
        }
        {
            let b = &mut params[self.bias_range(0)];
            for j in 0..pairs {
                b[j] = biases[j] as f32;
                b[j + pairs] = -biases[j] as f32;
            }
        }
        let w = &mut params[self.weight_range(1)];
        let (row0, rest) = w.split_at_mut(last.n_in);
        for j in 0..pairs {
            row0[j] = c[j] as f32;
            row0[j + pairs] = -c[j] as f32;
        }
        let bound = (6.0 / last.n_in as f64).sqrt();
        for x in rest {
            *x = rng.range(-bound, bound) as f32;
        }
        let absorbed: f64 = c.iter().zip(&biases).map(|(c, b)| c * b).sum();
        params[last.b] = (-(offset as f64) - absorbed) as f32;
    }

    /// Forward `input` (n×in, row-major) through the network; returns the n×out output held by `scratch`.
    /// Rows are cut into fixed chunks (the size depends only on `n`), each chunk one product per layer, chunks in
    /// parallel. `scratch` keeps what `backward` needs, and reallocates only when `n` grows.
    pub fn forward<'s>(&self, params: &[f32], input: &[f32], n: usize, scratch: &'s mut MlpScratch) -> &'s [f32] {
        assert_eq!(params.len(), self.param_count, "Mlp::forward: params length");
        assert_eq!(input.len(), n * self.input_dim(), "Mlp::forward: input length");
        scratch.resize(self, n);
        // Each layer's W transposed (n_in × n_out, at W's offset), so that the product reads it row by row.
        scratch.weights_t.resize(self.param_count, 0.0);
        for ly in &self.layers {
            let (w, wt) = (
                &params[ly.w..][..ly.n_in * ly.n_out],
                &mut scratch.weights_t[ly.w..][..ly.n_in * ly.n_out],
            );
            for o in 0..ly.n_out {
                for i in 0..ly.n_in {
                    wt[i * ly.n_out + o] = w[o * ly.n_in + i];
                }
            }
        }
        let wt = &scratch.weights_t;
        let lay = &scratch.layout;
        let nc = n.div_ceil(lay.rows);
        let d_in = self.input_dim();
        let d_out = self.output_dim();
        scratch.storage[..nc * lay.stride]
            .par_chunks_mut(lay.stride)
            .zip(scratch.out[..n * d_out].par_chunks_mut(lay.rows * d_out))
            .zip(input.par_chunks(lay.rows * d_in))
            .for_each(|((st, o), inp)| self.forward_chunk(params, wt, lay, st, o, inp));
        scratch.forward_done = true;
        &scratch.out[..n * d_out]
    }

    fn forward_chunk(&self, params: &[f32], wt: &[f32], lay: &ChunkLayout, st: &mut [f32], o: &mut [f32], inp: &[f32]) {
        let r = inp.len() / self.input_dim();
        st[..inp.len()].copy_from_slice(inp);
        let nl = self.layers.len();
        for (l, ly) in self.layers.iter().enumerate() {
            let (left, right) = st.split_at_mut(lay.g_off[l]);
            let a_in = &left[lay.a_off[l]..][..r * ly.n_in];
            let (g, rest) = right.split_at_mut(lay.rows * ly.n_out);
            let a_out: &mut [f32] = if l + 1 < nl {
                &mut rest[..r * ly.n_out]
            } else {
                &mut o[..r * ly.n_out]
            };
            let w_t = &wt[ly.w..ly.w + ly.n_in * ly.n_out];
            gemm_rows(r, ly.n_in, ly.n_out, a_in, ly.n_in, 1, w_t, ly.n_out, a_out, ly.n_out);
            kernels::bias_activate(ly.act, &params[ly.b..ly.b + ly.n_out], a_out, &mut g[..r * ly.n_out]);
        }
    }

    /// Backward after `forward` on the same `scratch` and `params`: the parameter gradient into `grad`
    /// (param_count; any length, e.g. empty, with `GradMode::Ignore`) per `mode`, and, if given, dL/dinput into `d_input` (n×in), which is overwritten. `d_out` is
    /// n×out. Per-chunk partial gradients are summed in chunk order, so 1 and 2 threads give identical results.
    pub fn backward(
        &self,
        params: &[f32],
        scratch: &mut MlpScratch,
        d_out: &[f32],
        grad: &mut [f32],
        mode: GradMode,
        d_input: Option<&mut [f32]>,
    ) {
        let want_params = mode != GradMode::Ignore;
        if !want_params && d_input.is_none() {
            return;
        }
        assert_eq!(params.len(), self.param_count, "Mlp::backward: params length");
        assert!(
            scratch.forward_done && scratch.dims == self.cfg.dims,
            "Mlp::backward: scratch does not hold a forward pass of this network"
        );
        let n = scratch.n;
        assert_eq!(d_out.len(), n * self.output_dim(), "Mlp::backward: d_out length");
        if want_params {
            assert_eq!(grad.len(), self.param_count, "Mlp::backward: grad length");
        }
        let lay = &scratch.layout;
        let nc = n.div_ceil(lay.rows);
        let storage = &mut scratch.storage[..nc * lay.stride];
        let d_out_rows = lay.rows * self.output_dim();
        match d_input {
            Some(di) => {
                assert_eq!(di.len(), n * self.input_dim(), "Mlp::backward: d_input length");
                storage
                    .par_chunks_mut(lay.stride)
                    .zip(d_out.par_chunks(d_out_rows))
                    .zip(di.par_chunks_mut(lay.rows * self.input_dim()))
                    .for_each(|((st, d), di)| self.backward_chunk(params, lay, st, d, Some(di), want_params));
            }
            None => storage
                .par_chunks_mut(lay.stride)
                .zip(d_out.par_chunks(d_out_rows))
                .for_each(|(st, d)| self.backward_chunk(params, lay, st, d, None, want_params)),
        }
        if !want_params {
            return;
        }
        let storage = &scratch.storage[..nc * lay.stride];
        let (stride, part) = (lay.stride, lay.part_off);
        grad.par_chunks_mut(REDUCE_BLOCK).enumerate().for_each(|(bi, g)| {
            let start = part + bi * REDUCE_BLOCK;
            if mode == GradMode::Overwrite {
                g.fill(0.0);
            }
            for c in 0..nc {
                let p = &storage[c * stride + start..][..g.len()];
                for (x, y) in g.iter_mut().zip(p) {
                    *x += y;
                }
            }
        });
    }

    fn backward_chunk(
        &self,
        params: &[f32],
        lay: &ChunkLayout,
        st: &mut [f32],
        d_out: &[f32],
        mut d_input: Option<&mut [f32]>,
        want_params: bool,
    ) {
        let nl = self.layers.len();
        let r = d_out.len() / self.output_dim();
        let (acts, tail) = st.split_at_mut(lay.delta_off);
        let (mut cur, tail) = tail.split_at_mut(lay.rows * lay.max_dim);
        let (mut nxt, part) = tail.split_at_mut(lay.rows * lay.max_dim);
        let part = &mut part[..self.param_count];
        let last = self.layers[nl - 1];
        cur[..d_out.len()].copy_from_slice(d_out);
        if last.act != Activation::None {
            kernels::mul_assign(&mut cur[..d_out.len()], &acts[lay.g_off[nl - 1]..][..d_out.len()]);
        }
        for l in (0..nl).rev() {
            let ly = self.layers[l];
            let delta = &cur[..r * ly.n_out];
            let w = &params[ly.w..ly.w + ly.n_in * ly.n_out];
            if want_params {
                let a_in = &acts[lay.a_off[l]..][..r * ly.n_in];
                let dw = &mut part[ly.w..ly.w + ly.n_in * ly.n_out];
                gemm_rows(ly.n_out, r, ly.n_in, delta, 1, ly.n_out, a_in, ly.n_in, dw, ly.n_in);
                kernels::column_sums(delta, &mut part[ly.b..ly.b + ly.n_out]);
            }
            if l > 0 {
                let prev = &mut nxt[..r * ly.n_in];
                gemm_rows(r, ly.n_out, ly.n_in, delta, ly.n_out, 1, w, ly.n_in, prev, ly.n_in);
                if self.layers[l - 1].act != Activation::None {
                    kernels::mul_assign(prev, &acts[lay.g_off[l - 1]..][..r * ly.n_in]);
                }
                std::mem::swap(&mut cur, &mut nxt);
            } else if let Some(di) = d_input.take() {
                gemm_rows(r, ly.n_out, ly.n_in, delta, ly.n_out, 1, w, ly.n_in, di, ly.n_in);
            }
        }
    }
}

/// `n` unit directions spread evenly over the sphere (a Fibonacci lattice) under a random rotation: a
/// quadrature of the sphere rather than a Monte-Carlo sample.
fn fibonacci_directions(n: usize, rng: &mut geom::SplitMix64) -> Vec<[f64; 3]> {
    let q = rng.quat();
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|j| {
            let z = 1.0 - (2 * j + 1) as f64 / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * j as f64;
            q.rotate(geom::Vec3::new(r * phi.cos(), r * phi.sin(), z)).to_array()
        })
        .collect()
}

/// Standard normal draw (Box–Muller).
fn gauss(rng: &mut geom::SplitMix64) -> f64 {
    let u1 = 1.0 - rng.next_f64();
    let u2 = rng.next_f64();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Where each buffer of one row chunk lies in the chunk's slice of the scratch storage (floats):
/// `[input copy | g_0 | a_1 | g_1 | a_2 | … | g_{L−1} | delta A | delta B | parameter-gradient part]`, where `a_l`
/// is the input of layer `l` and `g_l` the activation derivative of layer `l`'s output. The last layer's output
/// lives in the contiguous `out` buffer instead.
#[derive(Clone, Debug, Default)]
struct ChunkLayout {
    rows: usize,
    stride: usize,
    a_off: Vec<usize>,
    g_off: Vec<usize>,
    delta_off: usize,
    max_dim: usize,
    part_off: usize,
}

/// Activations of a batch, reused across calls (STYLE habit 16). `forward` sizes it; it only reallocates when the
/// batch grows.
#[derive(Clone, Debug, Default)]
pub struct MlpScratch {
    n: usize,
    dims: Vec<usize>,
    layout: ChunkLayout,
    storage: Vec<f32>,
    out: Vec<f32>,
    /// The last `forward`'s weights, each layer's W transposed at its offset.
    weights_t: Vec<f32>,
    forward_done: bool,
}

impl MlpScratch {
    pub fn new() -> Self {
        Self::default()
    }

    /// Rows of the last `forward`.
    pub fn len(&self) -> usize {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The output of the last `forward` (n×out).
    pub fn output(&self) -> &[f32] {
        &self.out[..self.n * self.dims.last().copied().unwrap_or(0)]
    }

    /// Floats held (storage and output), to check that reuse does not grow it.
    pub fn capacity_floats(&self) -> usize {
        self.storage.capacity() + self.out.capacity() + self.weights_t.capacity()
    }

    /// Lay the scratch out for `n` rows of `mlp`. Allocates only when more room is needed than ever before.
    pub fn resize(&mut self, mlp: &Mlp, n: usize) {
        let rows = n.div_ceil(8).next_multiple_of(16).clamp(16, MAX_CHUNK_ROWS);
        if self.dims != mlp.cfg.dims || self.layout.rows != rows {
            self.dims.clone_from(&mlp.cfg.dims);
            let dims = &self.dims;
            let nl = dims.len() - 1;
            let lay = &mut self.layout;
            lay.rows = rows;
            lay.max_dim = dims.iter().copied().max().unwrap();
            lay.a_off.clear();
            lay.g_off.clear();
            lay.a_off.push(0);
            let mut off = rows * dims[0];
            for l in 0..nl {
                lay.g_off.push(off);
                off += rows * dims[l + 1];
                if l + 1 < nl {
                    lay.a_off.push(off);
                    off += rows * dims[l + 1];
                }
            }
            lay.delta_off = off;
            off += 2 * rows * lay.max_dim;
            lay.part_off = off;
            off += mlp.param_count;
            // Whole cache lines per chunk, so two threads never share one.
            lay.stride = off.next_multiple_of(16);
        }
        let nc = n.div_ceil(rows);
        let need = nc * self.layout.stride;
        if self.storage.len() < need {
            self.storage.resize(need, 0.0);
        }
        let out = n * mlp.output_dim();
        if self.out.len() < out {
            self.out.resize(out, 0.0);
        }
        self.n = n;
        self.forward_done = false;
    }
}
