//! What a scene capture sees beyond the unit sphere (the table past the board,
//! the room, a backdrop): a density field over the contracted space outside
//! the sphere, composited behind the sphere's content. This is NeRF++'s
//! background model (Zhang et al. 2020, which NeuS uses for unmasked data) in
//! the form instant-nsr-pl gives it: a point `x` with `|x| > 1` is contracted
//! to `(2 − 1/|x|) x/|x|` (mip-NeRF 360), a shell of radius 1–2 that a small
//! hash grid covers, a density MLP gives `σ` and a feature, and a colour MLP
//! takes the feature and the view direction. Samples are spread evenly in
//! disparity from where the ray leaves the sphere to infinity; what lies
//! beyond the last sample is the field's constant background colour.
//!
//! Densities are per unit of contracted length, so the whole outside (from
//! the sphere to infinity) is one unit of it along any ray.

use crate::occupancy::sphere_span;
use crate::volume::{composite_density, composite_density_backward};
use field::ConfigError;
use field::{sh_encode, Activation, GradMode, HashGrid, HashGridConfig, Mlp, MlpConfig, MlpScratch, Touched, SH_DIM};
use geom::SplitMix64;
use serde::{Deserialize, Serialize};

/// Architecture and sampling of the background field (recorded in checkpoints).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BackgroundConfig {
    /// Hash grid over the contracted space (the shell fills the middle of its cube). Default 8 levels × 2
    /// features, 2^17 entries, resolutions 16–512.
    pub grid: HashGridConfig,
    /// Hidden width of the density MLP. Default 64.
    pub hidden: usize,
    /// Feature passed from the density MLP to the colour MLP. Default 15.
    pub feature_dim: usize,
    /// Hidden width of the colour MLP. Default 64.
    pub color_hidden: usize,
    /// Samples per ray beyond the sphere. Default 24.
    pub samples: usize,
}

impl Default for BackgroundConfig {
    fn default() -> Self {
        Self {
            grid: HashGridConfig {
                levels: 8,
                features_per_level: 2,
                log2_table_size: 17,
                base_resolution: 16,
                max_resolution: 512,
            },
            hidden: 64,
            feature_dim: 15,
            color_hidden: 64,
            samples: 24,
        }
    }
}

impl BackgroundConfig {
    /// Check ranges; keys are named as in the `[field.background]` table.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.grid.validate().map_err(|e| e.within("grid"))?;
        for (name, v) in [
            ("hidden", self.hidden),
            ("feature_dim", self.feature_dim),
            ("color_hidden", self.color_hidden),
            ("samples", self.samples),
        ] {
            if v == 0 {
                return Err(ConfigError::new(name, "must be at least 1"));
            }
        }
        Ok(())
    }
}

/// The background field and its parameters.
pub struct BackgroundField {
    pub config: BackgroundConfig,
    pub grid: HashGrid,
    pub density: Mlp,
    pub color: Mlp,
    pub grid_params: Vec<f32>,
    pub density_params: Vec<f32>,
    pub color_params: Vec<f32>,
}

/// Densities above `exp(MAX_LOG_DENSITY)` are clamped (instant-nsr-pl's truncated exponential).
const MAX_LOG_DENSITY: f32 = 15.0;

/// mip-NeRF 360's contraction of unit-sphere coordinates: inside the sphere unchanged, outside into the shell
/// `1 < |c| < 2`.
#[inline]
pub fn contract(p: [f32; 3]) -> [f32; 3] {
    let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    if r <= 1.0 {
        return p;
    }
    let s = (2.0 - 1.0 / r) / r;
    p.map(|v| v * s)
}

/// Distances along a ray of the background samples: from where it leaves the unit sphere (or, for a ray that
/// misses it, its closest approach), `t = t₀ + u/(1 − u)` for `u` evenly spread over [0, 1) with `jitter`.
fn sample_distances(o: [f32; 3], d: [f32; 3], n: usize, jitter: f32, out: &mut [f32]) {
    let t0 = match sphere_span(o, d) {
        Some((_, far)) => far,
        None => (-(o[0] * d[0] + o[1] * d[1] + o[2] * d[2])).max(0.0),
    };
    for (k, t) in out.iter_mut().enumerate().take(n) {
        // A jitter drawn in f64 may round to 1.0 in f32: keep u below 1 (t finite).
        let u = ((k as f32 + jitter) / n as f32).min(0.9999);
        *t = t0 + u / (1.0 - u);
    }
}

/// Buffers of one batch of rays, kept from the forward pass for the backward pass.
#[derive(Default)]
pub struct BackgroundScratch {
    /// Sample points in the grid's [0, 1] cube (`contract(p)/4 + 1/2`), rays × samples × 3.
    unit01: Vec<f32>,
    /// Contracted length of each sample's section.
    delta: Vec<f32>,
    enc: Vec<f32>,
    density_mlp: MlpScratch,
    sigma: Vec<f32>,
    ray_sh: Vec<f32>,
    flat_dirs: Vec<f32>,
    t: Vec<f32>,
    color_in: Vec<f32>,
    color_mlp: MlpScratch,
    rgb: Vec<[f32; 3]>,
    /// The background colour of each ray.
    pub out: Vec<[f32; 3]>,
    end: [f32; 3],
    d_sigma: Vec<f32>,
    d_rgb: Vec<[f32; 3]>,
    d_color_out: Vec<f32>,
    d_color_in: Vec<f32>,
    d_density_out: Vec<f32>,
    d_enc: Vec<f32>,
}

/// Gradients of the background field's parameters.
pub struct BackgroundGrads<'a> {
    pub grid: &'a mut [f32],
    pub touched: &'a mut Touched,
    pub density: &'a mut [f32],
    pub color: &'a mut [f32],
}

impl BackgroundField {
    pub fn new(config: &BackgroundConfig, rng: &mut SplitMix64) -> Self {
        let grid = HashGrid::new(&config.grid);
        let density = Mlp::new(&MlpConfig {
            dims: vec![grid.output_dim(), config.hidden, 1 + config.feature_dim],
            hidden: Activation::Relu,
            output: Activation::None,
        });
        let color = Mlp::new(&MlpConfig {
            dims: vec![SH_DIM + config.feature_dim, config.color_hidden, 3],
            hidden: Activation::Relu,
            output: Activation::Sigmoid,
        });
        let mut grid_params = vec![0.0; grid.param_count()];
        grid.init_params(&mut grid_params, rng);
        let mut density_params = vec![0.0; density.param_count()];
        density.init_params(&mut density_params, rng);
        let mut color_params = vec![0.0; color.param_count()];
        color.init_params(&mut color_params, rng);
        Self {
            config: config.clone(),
            grid,
            density,
            color,
            grid_params,
            density_params,
            color_params,
        }
    }

    /// The colour behind each ray (origins and unit directions in unit-sphere coordinates), into `sc.out`.
    /// `jitter(i)` places ray i's samples within their strata (0.5: the middle); `end` is the colour at infinity.
    pub fn forward(
        &self,
        origins: &[[f32; 3]],
        dirs: &[[f32; 3]],
        jitter: impl Fn(usize) -> f32,
        end: [f32; 3],
        sc: &mut BackgroundScratch,
    ) {
        let (r, s) = (origins.len(), self.config.samples);
        let m = r * s;
        sc.unit01.resize(m * 3, 0.0);
        sc.delta.resize(m, 0.0);
        sc.t.resize(s, 0.0);
        let t = &mut sc.t;
        for i in 0..r {
            let (o, d) = (origins[i], dirs[i]);
            sample_distances(o, d, s, jitter(i), t);
            let mut prev = [0.0f32; 3];
            for k in 0..s {
                let c = contract([o[0] + t[k] * d[0], o[1] + t[k] * d[1], o[2] + t[k] * d[2]]);
                let at = (i * s + k) * 3;
                for a in 0..3 {
                    sc.unit01[at + a] = c[a] * 0.25 + 0.5;
                }
                if k > 0 {
                    sc.delta[i * s + k - 1] = dist(prev, c);
                }
                prev = c;
            }
            // The last section reaches infinity, where the contracted point is 2·d.
            sc.delta[i * s + s - 1] = dist(prev, d.map(|v| 2.0 * v));
        }
        let e = self.grid.output_dim();
        sc.enc.resize(m * e, 0.0);
        self.grid
            .encode(&self.grid_params, &sc.unit01, &mut sc.enc, self.grid.levels());
        let width = 1 + self.config.feature_dim;
        let dout = self
            .density
            .forward(&self.density_params, &sc.enc, m, &mut sc.density_mlp);
        sc.sigma.clear();
        sc.sigma
            .extend(dout.chunks_exact(width).map(|row| row[0].min(MAX_LOG_DENSITY).exp()));
        sc.ray_sh.resize(r * SH_DIM, 0.0);
        sc.flat_dirs.clear();
        sc.flat_dirs.extend(dirs.iter().flatten());
        sh_encode(&sc.flat_dirs, &mut sc.ray_sh);
        let cin = SH_DIM + self.config.feature_dim;
        sc.color_in.resize(m * cin, 0.0);
        for (j, row) in sc.color_in.chunks_exact_mut(cin).enumerate() {
            let i = j / s;
            row[..SH_DIM].copy_from_slice(&sc.ray_sh[i * SH_DIM..(i + 1) * SH_DIM]);
            row[SH_DIM..].copy_from_slice(&dout[j * width + 1..(j + 1) * width]);
        }
        let rgb = self
            .color
            .forward(&self.color_params, &sc.color_in, m, &mut sc.color_mlp);
        sc.rgb.clear();
        sc.rgb.extend(rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        sc.end = end;
        sc.out.clear();
        for i in 0..r {
            let k = i * s..(i + 1) * s;
            let (c, _) = composite_density(&sc.sigma[k.clone()], &sc.delta[k.clone()], &sc.rgb[k], end);
            sc.out.push(c);
        }
    }

    /// Backward after [`forward`](Self::forward) on the same scratch: `d_out` is dL/d(colour) per ray. Adds to
    /// the parameter gradients (the grid's through `touched`) and returns dL/d(colour at infinity).
    pub fn backward(&self, sc: &mut BackgroundScratch, d_out: &[[f32; 3]], g: BackgroundGrads) -> [f32; 3] {
        let s = self.config.samples;
        let r = d_out.len();
        let m = r * s;
        sc.d_sigma.resize(m, 0.0);
        sc.d_rgb.resize(m, [0.0; 3]);
        let mut d_end = [0.0f32; 3];
        for i in 0..r {
            let k = i * s..(i + 1) * s;
            let de = composite_density_backward(
                &sc.sigma[k.clone()],
                &sc.delta[k.clone()],
                &sc.rgb[k.clone()],
                sc.end,
                d_out[i],
                &mut sc.d_sigma[k.clone()],
                &mut sc.d_rgb[k],
            );
            for c in 0..3 {
                d_end[c] += de[c];
            }
        }
        let cin = SH_DIM + self.config.feature_dim;
        sc.d_color_out.clear();
        sc.d_color_out.extend(sc.d_rgb.iter().flatten());
        sc.d_color_in.resize(m * cin, 0.0);
        self.color.backward(
            &self.color_params,
            &mut sc.color_mlp,
            &sc.d_color_out,
            g.color,
            GradMode::Accumulate,
            Some(&mut sc.d_color_in),
        );
        let width = 1 + self.config.feature_dim;
        sc.d_density_out.resize(m * width, 0.0);
        for j in 0..m {
            let row = &mut sc.d_density_out[j * width..(j + 1) * width];
            // σ = exp(min(raw, 15)); the gradient passes as if untruncated (as trunc_exp).
            row[0] = sc.d_sigma[j] * sc.sigma[j];
            row[1..].copy_from_slice(&sc.d_color_in[j * cin + SH_DIM..(j + 1) * cin]);
        }
        let e = self.grid.output_dim();
        sc.d_enc.resize(m * e, 0.0);
        self.density.backward(
            &self.density_params,
            &mut sc.density_mlp,
            &sc.d_density_out,
            g.density,
            GradMode::Accumulate,
            Some(&mut sc.d_enc),
        );
        self.grid.encode_backward(
            &sc.unit01,
            &sc.d_enc,
            g.grid,
            g.touched,
            GradMode::Accumulate,
            self.grid.levels(),
        );
        d_end
    }
}

#[inline]
fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
