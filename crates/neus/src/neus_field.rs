//! The NeuS field (Eq. 1): a multiresolution hash encoding and a small SDF
//! MLP give the signed distance and a feature vector; a colour MLP takes the
//! view direction (spherical harmonics), the normal and the feature.

use crate::background_field::{BackgroundConfig, BackgroundField, BackgroundScratch};
use field::{Activation, GradMode, HashGrid, HashGridConfig, Mlp, MlpConfig, MlpScratch, Touched, SH_DIM};
use geom::SplitMix64;
use serde::{Deserialize, Serialize};

/// How the SDF starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FieldInit {
    /// A sphere of `init_radius` about the centre (an object).
    Sphere,
    /// The half-space below the board, the world's plane z = 0 (a scene: captures are calibrated on the board).
    Board,
}

/// Architecture of the field (recorded in every checkpoint).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FieldConfig {
    pub grid: HashGridConfig,
    /// Hidden widths of the SDF MLP. Default `[64]`.
    pub sdf_hidden: Vec<usize>,
    /// Length of the feature vector passed to the colour MLP. Default 15.
    pub feature_dim: usize,
    /// Hidden widths of the colour MLP. Default `[64, 64]`.
    pub color_hidden: Vec<usize>,
    /// Hidden activation of the SDF MLP. Default softplus with β = 100 (as
    /// NeuS): smooth, so finite-difference normals are well behaved.
    pub sdf_activation: Activation,
    /// Hidden activation of the colour MLP. Default ReLU (as NeuS).
    pub color_activation: Activation,
    /// How the SDF starts. Default `sphere`.
    pub init: FieldInit,
    /// Radius of the initial sphere, unit coordinates. Default 0.5.
    pub init_radius: f32,
    /// Initial value of the variance parameter (inv_s = exp(10 · variance)). Default 0.3.
    pub init_variance: f32,
    /// A field for what lies beyond the unit sphere (scenes); without it, a constant colour. Default none.
    pub background: Option<BackgroundConfig>,
}

impl Default for FieldConfig {
    fn default() -> Self {
        Self {
            grid: HashGridConfig::default(),
            sdf_hidden: vec![64],
            feature_dim: 15,
            color_hidden: vec![64, 64],
            sdf_activation: Activation::Softplus { beta: 100.0 },
            color_activation: Activation::Relu,
            init: FieldInit::Sphere,
            init_radius: 0.5,
            init_variance: 0.3,
            background: None,
        }
    }
}

/// The field and its parameters.
pub struct NeusField {
    pub config: FieldConfig,
    pub grid: HashGrid,
    pub sdf: Mlp,
    pub color: Mlp,
    pub grid_params: Vec<f32>,
    pub sdf_params: Vec<f32>,
    pub color_params: Vec<f32>,
    /// `[variance, background r, g, b]`: the colour behind everything (behind the background field, if any).
    pub extra: Vec<f32>,
    pub background: Option<BackgroundField>,
}

/// Where [`NeusField::sdf_backward`] puts its gradients.
pub struct SdfGrads<'a> {
    pub grid: &'a mut [f32],
    pub sdf: &'a mut [f32],
    pub touched: &'a mut Touched,
}

/// Buffers of [`NeusField::sdf_backward`].
#[derive(Default)]
pub struct SdfBackwardScratch {
    d_in: Vec<f32>,
    d_enc: Vec<f32>,
    d_unit01: Vec<f32>,
}

/// The buffers of an SDF-only pass at a batch of points, forward ([`NeusField::sdf_forward`]) and back
/// ([`NeusField::sdf_backward`]) with the outputs' gradient in `d_out`: the stereo points' term and the
/// regulariser points'.
#[derive(Default)]
pub struct SdfPassScratch {
    pub unit01: Vec<f32>,
    pub enc: Vec<f32>,
    pub input: Vec<f32>,
    pub mlp: MlpScratch,
    pub d_out: Vec<f32>,
    pub back: SdfBackwardScratch,
}

/// Input width of the SDF MLP: xyz then the encoding.
pub const XYZ: usize = 3;

impl NeusField {
    /// Every parameter vector with its name (the checkpoint's tensor name), in a fixed order: the hash grid,
    /// the SDF and colour MLPs, the extras, then the background field's grid, density and colour MLPs when
    /// there is one. Adam's state, the checkpoint and the parameter average follow this order.
    pub fn params(&self) -> Vec<(&'static str, &[f32])> {
        let mut out: Vec<(&'static str, &[f32])> = vec![
            ("grid", &self.grid_params),
            ("sdf", &self.sdf_params),
            ("color", &self.color_params),
            ("extra", &self.extra),
        ];
        if let Some(b) = &self.background {
            out.extend([
                ("background.grid", &b.grid_params[..]),
                ("background.density", &b.density_params),
                ("background.color", &b.color_params),
            ]);
        }
        out
    }

    /// [`NeusField::params`], mutable.
    pub fn params_mut(&mut self) -> Vec<(&'static str, &mut Vec<f32>)> {
        let mut out = vec![
            ("grid", &mut self.grid_params),
            ("sdf", &mut self.sdf_params),
            ("color", &mut self.color_params),
            ("extra", &mut self.extra),
        ];
        if let Some(b) = &mut self.background {
            out.extend([
                ("background.grid", &mut b.grid_params),
                ("background.density", &mut b.density_params),
                ("background.color", &mut b.color_params),
            ]);
        }
        out
    }

    /// A new field. `board_height` is the board plane z = 0 of the world in unit coordinates (`−centre_z /
    /// radius`), where a `Board` init puts the surface.
    pub fn new(config: &FieldConfig, seed: u64, board_height: f32) -> Self {
        let grid = HashGrid::new(&config.grid);
        let sdf_in = XYZ + grid.output_dim();
        let mut dims = vec![sdf_in];
        dims.extend(&config.sdf_hidden);
        dims.push(1 + config.feature_dim);
        let sdf = Mlp::new(&MlpConfig {
            dims,
            hidden: config.sdf_activation,
            output: Activation::None,
        });
        let mut cdims = vec![SH_DIM + 3 + config.feature_dim];
        cdims.extend(&config.color_hidden);
        cdims.push(3);
        let color = Mlp::new(&MlpConfig {
            dims: cdims,
            hidden: config.color_activation,
            output: Activation::Sigmoid,
        });
        let mut rng = SplitMix64::new(seed);
        let mut grid_params = vec![0.0; grid.param_count()];
        grid.init_params(&mut grid_params, &mut rng);
        let mut sdf_params = vec![0.0; sdf.param_count()];
        match config.init {
            FieldInit::Sphere => sdf.init_geometric(&mut sdf_params, &mut rng, config.init_radius, XYZ),
            FieldInit::Board => sdf.init_geometric_plane(&mut sdf_params, &mut rng, [0.0, 0.0, 1.0], board_height),
        }
        let mut color_params = vec![0.0; color.param_count()];
        color.init_params(&mut color_params, &mut rng);
        let extra = vec![config.init_variance, 0.5, 0.5, 0.5];
        let background = config.background.as_ref().map(|b| BackgroundField::new(b, &mut rng));
        Self {
            config: config.clone(),
            grid,
            sdf,
            color,
            grid_params,
            sdf_params,
            color_params,
            extra,
            background,
        }
    }

    /// Zero the colour MLP's weights from the view direction's higher harmonics (all but the constant one).
    /// While a run ignores the view direction those inputs are 0 and their weights get no gradient, so random
    /// weights would stay as initialised and jolt every colour the step the direction comes on (a 4 dB drop
    /// in held-out PSNR on the tabletop scene). From zero the view dependence grows from what the images ask.
    pub fn zero_view_weights(&mut self) {
        let n_in = self.color.input_dim();
        let w = self.color.weight_range(0);
        for row in self.color_params[w].chunks_exact_mut(n_in) {
            row[1..SH_DIM].fill(0.0);
        }
    }

    /// The sharpness `s` of Φ_s.
    pub fn inv_s(&self) -> f32 {
        (self.extra[0] * 10.0).exp().clamp(1e-3, 1e6)
    }

    pub fn background(&self) -> [f32; 3] {
        [self.extra[1], self.extra[2], self.extra[3]].map(|v| v.clamp(0.0, 1.0))
    }

    /// The colour behind each ray's samples (unit coordinates), into `sc.out`: the background field's, or the
    /// constant colour. `jitter(i)` places ray i's background samples in their strata (0.5: the middle).
    pub fn colour_behind(
        &self,
        origins: &[[f32; 3]],
        dirs: &[[f32; 3]],
        jitter: impl Fn(usize) -> f32,
        sc: &mut BackgroundScratch,
    ) {
        let end = self.background();
        match &self.background {
            Some(b) => b.forward(origins, dirs, jitter, end, sc),
            None => {
                sc.out.clear();
                sc.out.resize(origins.len(), end);
            }
        }
    }

    /// SDF MLP outputs (N × (1 + feature_dim)) at unit-coordinate points
    /// (N × 3). `unit01` (the points in the hash grid's [0, 1] cube, kept
    /// for the backward pass), `enc` and `input` are scratch.
    pub fn sdf_forward<'s>(
        &self,
        points: &[f32],
        active_levels: usize,
        unit01: &mut Vec<f32>,
        enc: &mut Vec<f32>,
        input: &mut Vec<f32>,
        scratch: &'s mut MlpScratch,
    ) -> &'s [f32] {
        let n = points.len() / 3;
        let e = self.grid.output_dim();
        enc.resize(n * e, 0.0);
        input.resize(n * (XYZ + e), 0.0);
        unit01.clear();
        unit01.extend(points.iter().map(|v| (v + 1.0) * 0.5));
        self.grid.encode(&self.grid_params, unit01, enc, active_levels);
        for i in 0..n {
            let row = &mut input[i * (XYZ + e)..(i + 1) * (XYZ + e)];
            row[..XYZ].copy_from_slice(&points[i * 3..i * 3 + 3]);
            row[XYZ..].copy_from_slice(&enc[i * e..(i + 1) * e]);
        }
        self.sdf.forward(&self.sdf_params, input, n, scratch)
    }

    /// Backward of [`Self::sdf_forward`]: from the outputs' gradient (N × (1 + feature_dim)) to the SDF
    /// MLP's parameters (`mode`) and, through the encoding, to the hash grid's (accumulated; the touched
    /// entries recorded), when `grads` is given; and to the input points (`d_points`, N × 3, unit coordinates,
    /// overwritten) when given. `d_in`, `d_enc` and `d_unit01` are scratch.
    #[allow(clippy::too_many_arguments)]
    pub fn sdf_backward(
        &self,
        unit01: &[f32],
        mlp: &mut MlpScratch,
        d_out: &[f32],
        mode: GradMode,
        scratch: &mut SdfBackwardScratch,
        grads: Option<SdfGrads<'_>>,
        d_points: Option<&mut [f32]>,
        active_levels: usize,
    ) {
        let n = unit01.len() / 3;
        let e = self.grid.output_dim();
        let sc = scratch;
        sc.d_in.resize(n * (XYZ + e), 0.0);
        let mut none = [];
        let (param_grads, mode) = match grads {
            Some(g) => (Some(g), mode),
            None => (None, GradMode::Ignore),
        };
        let (sdf_grad, grid_grads) = match param_grads {
            Some(g) => (g.sdf, Some((g.grid, g.touched))),
            None => (&mut none[..], None),
        };
        self.sdf
            .backward(&self.sdf_params, mlp, d_out, sdf_grad, mode, Some(&mut sc.d_in));
        sc.d_enc.resize(n * e, 0.0);
        for i in 0..n {
            sc.d_enc[i * e..(i + 1) * e].copy_from_slice(&sc.d_in[i * (XYZ + e) + XYZ..(i + 1) * (XYZ + e)]);
        }
        if let Some((grid, touched)) = grid_grads {
            self.grid
                .encode_backward(unit01, &sc.d_enc, grid, touched, GradMode::Accumulate, active_levels);
        }
        if let Some(dp) = d_points {
            // The MLP sees the point itself and its encoding of (p + 1) / 2.
            sc.d_unit01.resize(n * 3, 0.0);
            self.grid.encode_backward_input(
                &self.grid_params,
                unit01,
                &sc.d_enc,
                &mut sc.d_unit01,
                GradMode::Overwrite,
                active_levels,
            );
            for i in 0..n {
                for k in 0..3 {
                    dp[i * 3 + k] = sc.d_in[i * (XYZ + e) + k] + 0.5 * sc.d_unit01[i * 3 + k];
                }
            }
        }
    }

    /// The world height where the zero level last crosses (from inside below to outside above) the vertical
    /// line at world `(x, y)` between heights `lo` and `hi` (400 samples, linear interpolation), for a field
    /// whose unit sphere is `p_world = centre + radius · p_unit`: the top of the board or of an obstacle.
    pub fn surface_height(
        &self,
        centre: geom::Vec3<f64>,
        radius: f64,
        x: f64,
        y: f64,
        lo: f64,
        hi: f64,
    ) -> Option<f64> {
        let n = 400;
        let zs: Vec<f64> = (0..=n).map(|k| lo + (hi - lo) * k as f64 / n as f64).collect();
        let pts: Vec<f32> = zs
            .iter()
            .flat_map(|&z| {
                ((geom::Vec3::new(x, y, z) - centre) * (1.0 / radius))
                    .to_array()
                    .map(|v| v as f32)
            })
            .collect();
        let sdf = self.sdf_values(&pts, self.config.grid.levels);
        (0..n)
            .rev()
            .find(|&k| sdf[k] <= 0.0 && sdf[k + 1] > 0.0)
            .map(|k| zs[k] + (zs[k + 1] - zs[k]) * (sdf[k] as f64 / (sdf[k] - sdf[k + 1]) as f64))
    }

    /// SDF values only, in batches (for meshing and occupancy updates).
    pub fn sdf_values(&self, points: &[f32], active_levels: usize) -> Vec<f32> {
        let (mut unit01, mut enc, mut input) = (Vec::new(), Vec::new(), Vec::new());
        let mut scratch = MlpScratch::default();
        let width = 1 + self.config.feature_dim;
        let mut out = Vec::with_capacity(points.len() / 3);
        for chunk in points.chunks(3 * 65536) {
            let o = self.sdf_forward(chunk, active_levels, &mut unit01, &mut enc, &mut input, &mut scratch);
            out.extend(o.chunks_exact(width).map(|r| r[0]));
        }
        out
    }
}

/// Keep only the constant spherical harmonic of each row (colour from the point alone): a scene's first steps,
/// where a view-dependent colour could paint an unformed obstacle onto the surface behind it, differently for
/// each view, instead of growing it.
pub(crate) fn drop_view_dependence(sh: &mut [f32]) {
    for row in sh.chunks_exact_mut(SH_DIM) {
        row[1..].fill(0.0);
    }
}
