//! Multiresolution hash encoding (Müller et al. 2022, Instant-NGP, §3): `L` levels of trilinearly interpolated
//! feature grids, resolutions in geometric progression (eq. 2–3), coarse levels indexed densely and fine levels
//! through a spatial hash (eq. 4). All levels live in one flat parameter buffer with an offset table.

use crate::kernels::{self, LevelGeom};
use crate::ConfigError;
use crate::GradMode;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Points per rayon task in `encode` and `encode_backward_input`.
const POINT_CHUNK: usize = 256;

/// Hash-grid hyper-parameters (Instant-NGP Table 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HashGridConfig {
    /// Number of levels `L`. Default 16.
    pub levels: usize,
    /// Features per level `F`: 1, 2, 4 or 8. Default 2.
    pub features_per_level: usize,
    /// log2 of the largest table size `T` (entries per level). Default 19.
    pub log2_table_size: u32,
    /// Coarsest resolution `N_min` (cells per axis). Default 16.
    pub base_resolution: u32,
    /// Finest resolution `N_max` (cells per axis). Default 2048.
    pub max_resolution: u32,
}

impl Default for HashGridConfig {
    fn default() -> Self {
        Self {
            levels: 16,
            features_per_level: 2,
            log2_table_size: 19,
            base_resolution: 16,
            max_resolution: 2048,
        }
    }
}

impl HashGridConfig {
    /// The finest level's cell over the unit cube [-1, 1]³ (`2 / N_max`): the step a field's normals are
    /// taken at by finite differences.
    pub fn finest_cell(&self) -> f32 {
        2.0 / self.max_resolution as f32
    }

    /// Check ranges: `levels ≥ 1`, `F ∈ {1,2,4,8}`, `3 ≤ log2 T ≤ 28`, `1 ≤ N_min ≤ N_max ≤ 2^20`.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.levels == 0 {
            return Err(ConfigError::new("levels", "must be at least 1"));
        }
        if ![1, 2, 4, 8].contains(&self.features_per_level) {
            return Err(ConfigError::new(
                "features_per_level",
                format!("must be 1, 2, 4 or 8, got {}", self.features_per_level),
            ));
        }
        if !(3..=28).contains(&self.log2_table_size) {
            return Err(ConfigError::new(
                "log2_table_size",
                format!("must be 3 to 28, got {}", self.log2_table_size),
            ));
        }
        if self.base_resolution == 0 || self.base_resolution > self.max_resolution || self.max_resolution > 1 << 20 {
            return Err(ConfigError::new(
                "base_resolution",
                format!(
                    "need 1 ≤ base_resolution ({}) ≤ max_resolution ({}) ≤ 2^20",
                    self.base_resolution, self.max_resolution
                ),
            ));
        }
        Ok(())
    }

    /// Growth factor `b = exp((ln N_max − ln N_min)/(L − 1))` (eq. 3); 1 for a single level.
    pub fn growth_factor(&self) -> f64 {
        self.ln_growth_factor().exp()
    }

    fn ln_growth_factor(&self) -> f64 {
        if self.levels <= 1 {
            return 0.0;
        }
        ((self.max_resolution as f64).ln() - (self.base_resolution as f64).ln()) / (self.levels - 1) as f64
    }
}

/// The hash encoding: level geometry and the offset table. Holds no parameters; they live in the caller's flat
/// buffer (`param_count()` floats), level `l` at `level_range(l)`, entry `e` of a level at `e·F .. e·F + F`.
#[derive(Clone, Debug)]
pub struct HashGrid {
    cfg: HashGridConfig,
    geoms: Vec<LevelGeom>,
    /// `offsets[l]` = start of level `l` in the flat parameters, in floats; `offsets[L]` = total.
    offsets: Vec<usize>,
}

impl HashGrid {
    /// Build the level table. Level `l` has resolution `floor(N_min · b^l)` (computed in f64 with a 1e-6 guard so
    /// that the last level is exactly `N_max`). It is dense when `(res+1)³ ≤ T`, with `(res+1)³` rounded up to a
    /// multiple of 8 entries, and hashed with `T` entries otherwise. Panics on an invalid config (see `validate`).
    pub fn new(cfg: &HashGridConfig) -> Self {
        if let Err(e) = cfg.validate() {
            panic!("hash grid: {e}");
        }
        let t = 1u64 << cfg.log2_table_size;
        let ln_b = cfg.ln_growth_factor();
        let mut geoms = Vec::with_capacity(cfg.levels);
        let mut offsets = vec![0];
        for l in 0..cfg.levels {
            let res = ((cfg.base_resolution as f64 * (ln_b * l as f64).exp() + 1e-6).floor() as u32)
                .clamp(cfg.base_resolution, cfg.max_resolution);
            let dense_size = (res as u64 + 1).pow(3);
            let (dense, entries) = if dense_size <= t {
                (true, dense_size.next_multiple_of(8).min(t))
            } else {
                (false, t)
            };
            geoms.push(LevelGeom {
                res,
                entries: entries as u32,
                dense,
            });
            offsets.push(offsets[l] + entries as usize * cfg.features_per_level);
        }
        Self {
            cfg: cfg.clone(),
            geoms,
            offsets,
        }
    }

    pub fn config(&self) -> &HashGridConfig {
        &self.cfg
    }

    /// Total floats of all levels.
    pub fn param_count(&self) -> usize {
        self.offsets[self.cfg.levels]
    }

    /// `levels · features_per_level`.
    pub fn output_dim(&self) -> usize {
        self.cfg.levels * self.cfg.features_per_level
    }

    pub fn levels(&self) -> usize {
        self.cfg.levels
    }

    pub fn features_per_level(&self) -> usize {
        self.cfg.features_per_level
    }

    /// Level `l`'s slice of the flat parameters, in floats.
    pub fn level_range(&self, level: usize) -> Range<usize> {
        self.offsets[level]..self.offsets[level + 1]
    }

    /// Geometry (resolution, entries, dense or hashed) of level `l`.
    pub fn level_geom(&self, level: usize) -> LevelGeom {
        self.geoms[level]
    }

    /// `(geometry, offset in floats)` of every level, the form the reference kernels take.
    pub fn level_table(&self) -> Vec<(LevelGeom, usize)> {
        self.geoms.iter().copied().zip(self.offsets.iter().copied()).collect()
    }

    /// Uniform in ±1e-4 (Instant-NGP §4).
    pub fn init_params(&self, params: &mut [f32], rng: &mut geom::SplitMix64) {
        assert_eq!(params.len(), self.param_count(), "HashGrid::init_params: params length");
        for p in params {
            *p = rng.range(-1e-4, 1e-4) as f32;
        }
    }

    fn check_active(&self, active_levels: usize) -> usize {
        active_levels.min(self.cfg.levels)
    }

    /// Encode `points` (N×3 row-major, coordinates in `[0, 1]`, clamped outside) into `out` (N×output_dim).
    /// Levels ≥ `active_levels` output 0 (progressive activation). Rayon over chunks of 256 points; inside a chunk
    /// the levels are the outer loop so each level's table stays in cache for the whole chunk.
    pub fn encode(&self, params: &[f32], points: &[f32], out: &mut [f32], active_levels: usize) {
        assert_eq!(params.len(), self.param_count(), "HashGrid::encode: params length");
        assert_eq!(
            points.len() % 3,
            0,
            "HashGrid::encode: points length not a multiple of 3"
        );
        let n = points.len() / 3;
        let dim = self.output_dim();
        assert_eq!(out.len(), n * dim, "HashGrid::encode: out length");
        let f = self.cfg.features_per_level;
        let active = self.check_active(active_levels);
        points
            .par_chunks(POINT_CHUNK * 3)
            .zip(out.par_chunks_mut(POINT_CHUNK * dim))
            .for_each(|(pts, o)| {
                for l in 0..self.cfg.levels {
                    let col = l * f;
                    if l >= active {
                        for row in o.chunks_exact_mut(dim) {
                            row[col..col + f].fill(0.0);
                        }
                        continue;
                    }
                    let table = &params[self.level_range(l)];
                    let g = self.geoms[l];
                    match f {
                        1 => kernels::encode_level::<1>(table, g, pts, o, dim, col),
                        2 => kernels::encode_level::<2>(table, g, pts, o, dim, col),
                        4 => kernels::encode_level::<4>(table, g, pts, o, dim, col),
                        8 => kernels::encode_level::<8>(table, g, pts, o, dim, col),
                        _ => unreachable!("validated in new"),
                    }
                }
            });
    }

    /// Gradient with respect to the parameters from `d_out` (N×output_dim), into `grad` (param_count) per `mode`.
    /// Parallel over levels: each level's slice of `grad` (and of `touched`) is split off with `split_at_mut`, so no
    /// two threads write the same entry, and each level sums its points in order, so the result does not depend on
    /// the thread count. Every corner entry read is recorded in `touched` (a superset of the entries with nonzero
    /// gradient); the optimizer clears it.
    ///
    /// `Overwrite` zeroes every level's slice first (a memset of all param_count floats, ~5 ms for the default
    /// grid): the training loop should use `Accumulate` into a buffer that `Adam::step_sparse` keeps zero outside
    /// `touched`.
    /// Inactive levels (≥ `active_levels`) get zero gradient (`Overwrite`) or are left alone (`Accumulate`), and
    /// nothing of them is recorded in `touched`.
    pub fn encode_backward(
        &self,
        points: &[f32],
        d_out: &[f32],
        grad: &mut [f32],
        touched: &mut Touched,
        mode: GradMode,
        active_levels: usize,
    ) {
        if mode == GradMode::Ignore {
            return;
        }
        assert_eq!(
            points.len() % 3,
            0,
            "HashGrid::encode_backward: points length not a multiple of 3"
        );
        let n = points.len() / 3;
        let dim = self.output_dim();
        assert_eq!(d_out.len(), n * dim, "HashGrid::encode_backward: d_out length");
        assert_eq!(grad.len(), self.param_count(), "HashGrid::encode_backward: grad length");
        assert_eq!(
            touched.levels.len(),
            self.cfg.levels,
            "HashGrid::encode_backward: touched built for another grid"
        );
        let f = self.cfg.features_per_level;
        let active = self.check_active(active_levels);
        let mut slices: Vec<&mut [f32]> = Vec::with_capacity(self.cfg.levels);
        let mut rest = grad;
        for l in 0..self.cfg.levels {
            let (head, tail) = rest.split_at_mut(self.offsets[l + 1] - self.offsets[l]);
            slices.push(head);
            rest = tail;
        }
        slices
            .into_par_iter()
            .zip(touched.levels.par_iter_mut())
            .enumerate()
            .for_each(|(l, (g_l, t_l))| {
                if mode == GradMode::Overwrite {
                    g_l.fill(0.0);
                }
                if l >= active {
                    return;
                }
                let geom = self.geoms[l];
                let col = l * f;
                let bits = &mut t_l.bits[..];
                match f {
                    1 => kernels::encode_level_backward::<1>(geom, points, d_out, dim, col, g_l, bits),
                    2 => kernels::encode_level_backward::<2>(geom, points, d_out, dim, col, g_l, bits),
                    4 => kernels::encode_level_backward::<4>(geom, points, d_out, dim, col, g_l, bits),
                    8 => kernels::encode_level_backward::<8>(geom, points, d_out, dim, col, g_l, bits),
                    _ => unreachable!("validated in new"),
                }
            });
    }

    /// `d_points` (N×3) = or += (per `mode`) dL/dpoints with respect to the `[0, 1]` coordinates. Zero along an axis
    /// where the coordinate lies outside `[0, 1]` (clamped). Rayon over point chunks, levels summed in order.
    pub fn encode_backward_input(
        &self,
        params: &[f32],
        points: &[f32],
        d_out: &[f32],
        d_points: &mut [f32],
        mode: GradMode,
        active_levels: usize,
    ) {
        if mode == GradMode::Ignore {
            return;
        }
        assert_eq!(
            params.len(),
            self.param_count(),
            "HashGrid::encode_backward_input: params length"
        );
        assert_eq!(
            points.len() % 3,
            0,
            "HashGrid::encode_backward_input: points length not a multiple of 3"
        );
        let n = points.len() / 3;
        let dim = self.output_dim();
        assert_eq!(d_out.len(), n * dim, "HashGrid::encode_backward_input: d_out length");
        assert_eq!(
            d_points.len(),
            n * 3,
            "HashGrid::encode_backward_input: d_points length"
        );
        let f = self.cfg.features_per_level;
        let active = self.check_active(active_levels);
        points
            .par_chunks(POINT_CHUNK * 3)
            .zip(d_out.par_chunks(POINT_CHUNK * dim))
            .zip(d_points.par_chunks_mut(POINT_CHUNK * 3))
            .for_each(|((pts, d), dp)| {
                if mode == GradMode::Overwrite {
                    dp.fill(0.0);
                }
                for l in 0..active {
                    let table = &params[self.level_range(l)];
                    let g = self.geoms[l];
                    let col = l * f;
                    match f {
                        1 => kernels::encode_level_backward_input::<1>(table, g, pts, d, dim, col, dp),
                        2 => kernels::encode_level_backward_input::<2>(table, g, pts, d, dim, col, dp),
                        4 => kernels::encode_level_backward_input::<4>(table, g, pts, d, dim, col, dp),
                        8 => kernels::encode_level_backward_input::<8>(table, g, pts, d, dim, col, dp),
                        _ => unreachable!("validated in new"),
                    }
                }
            });
    }
}

/// The table entries that received gradient since the last optimizer step: one bitset per level over the level's
/// entries (entry `e` of level `l` covers floats `level_range(l).start + e·F ..+F`). Marking is a branch-free OR in
/// the backward pass and deduplicates by construction; the sparse Adam step walks the set bits in memory order
/// (sequential access to parameters and moments, whole 64-entry words at once when full) and clears them. A scan of
/// the bitsets costs ~1 MB of reads for the default grid, negligible next to the backward pass.
#[derive(Clone, Debug)]
pub struct Touched {
    pub(crate) levels: Vec<TouchedLevel>,
}

#[derive(Clone, Debug)]
pub(crate) struct TouchedLevel {
    pub(crate) bits: Vec<u64>,
}

impl Touched {
    /// Empty record sized for `grid`.
    pub fn new(grid: &HashGrid) -> Self {
        let levels = grid
            .geoms
            .iter()
            .map(|g| TouchedLevel {
                bits: vec![0; (g.entries as usize).div_ceil(64)],
            })
            .collect();
        Self { levels }
    }

    /// Forget every entry.
    pub fn clear(&mut self) {
        for t in &mut self.levels {
            t.bits.fill(0);
        }
    }

    /// Entries of `level` touched since the last clear, ascending.
    pub fn entries(&self, level: usize) -> impl Iterator<Item = u32> + '_ {
        self.levels[level].bits.iter().enumerate().flat_map(|(w, &word)| {
            let mut b = word;
            std::iter::from_fn(move || {
                if b == 0 {
                    return None;
                }
                let t = b.trailing_zeros();
                b &= b - 1;
                Some(w as u32 * 64 + t)
            })
        })
    }

    pub fn contains(&self, level: usize, entry: u32) -> bool {
        let t = &self.levels[level];
        t.bits
            .get((entry >> 6) as usize)
            .is_some_and(|w| w & (1u64 << (entry & 63)) != 0)
    }

    /// Touched entries over all levels.
    pub fn len(&self) -> usize {
        self.levels
            .iter()
            .flat_map(|t| &t.bits)
            .map(|w| w.count_ones() as usize)
            .sum()
    }

    pub fn is_empty(&self) -> bool {
        self.levels.iter().all(|t| t.bits.iter().all(|&w| w == 0))
    }

    pub fn levels(&self) -> usize {
        self.levels.len()
    }
}
