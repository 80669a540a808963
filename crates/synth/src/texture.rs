//! Procedural colour textures evaluated at a 3-D point of an object's own
//! frame, so a body's texture moves with it. Rich in detail on purpose:
//! colour-based pose fitting needs gradients everywhere.

use geom::Vec3;
use serde::{Deserialize, Serialize};

/// The pattern that picks between the palette colours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Pattern {
    /// 3-D checkerboard of cells `scale` wide.
    Checker,
    /// Bands `scale` wide along `direction`.
    Stripes,
    /// Smooth fractal noise with features about `scale` wide.
    Noise,
    /// Noise-warped bands, like marble or wood grain.
    Marble,
}

/// A procedural texture: a pattern over a palette, modulated by fine noise.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Texture {
    pub pattern: Pattern,
    /// Feature size, m.
    pub scale: f64,
    /// Two or more linear RGB colours in [0, 1]; the pattern blends between them.
    pub colors: Vec<[f64; 3]>,
    /// Stripes and marble: the direction across the bands (default x).
    #[serde(default = "default_direction")]
    pub direction: [f64; 3],
    /// Strength of the fine noise laid over the pattern, 0–1 (default 0.35).
    #[serde(default = "default_detail")]
    pub detail: f64,
    /// Seed of the noise (default 0).
    #[serde(default)]
    pub seed: u64,
}

fn default_direction() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}
fn default_detail() -> f64 {
    0.35
}

impl Texture {
    pub fn new(pattern: Pattern, scale: f64, colors: Vec<[f64; 3]>, seed: u64) -> Self {
        Self {
            pattern,
            scale,
            colors,
            direction: default_direction(),
            detail: default_detail(),
            seed,
        }
    }

    /// Check the texture; `field` names it in messages.
    pub fn validate(&self, field: &str) -> Result<(), String> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(format!("{field}.scale: must be positive, got {}", self.scale));
        }
        if self.colors.len() < 2 {
            return Err(format!("{field}.colors: give at least two colours"));
        }
        for (i, c) in self.colors.iter().enumerate() {
            if c.iter().any(|v| !(0.0..=1.0).contains(v)) {
                return Err(format!("{field}.colors[{i}]: components must be in [0, 1], got {c:?}"));
            }
        }
        if !(0.0..=1.0).contains(&self.detail) {
            return Err(format!("{field}.detail: must be in [0, 1], got {}", self.detail));
        }
        if self.direction.iter().any(|v| !v.is_finite()) || Vec3::<f64>::cst(self.direction).try_normalize().is_none() {
            return Err(format!("{field}.direction: must be a non-zero vector"));
        }
        Ok(())
    }

    /// Linear RGB albedo at `p` (object frame).
    pub fn albedo(&self, p: Vec3<f64>) -> [f64; 3] {
        let q = p * (1.0 / self.scale);
        let t = match self.pattern {
            Pattern::Checker => {
                let c = q.x.floor() as i64 + q.y.floor() as i64 + q.z.floor() as i64;
                if c.rem_euclid(2) == 0 {
                    0.0
                } else {
                    1.0
                }
            }
            Pattern::Stripes => {
                let d = Vec3::cst(self.direction).normalize_or(Vec3::new(1.0, 0.0, 0.0));
                let s = q.dot(d);
                0.5 + 0.5 * (s * std::f64::consts::PI).sin().signum()
            }
            // fBm clusters around 0.5: stretch it so the whole palette shows.
            Pattern::Noise => ((fbm(q, 4, self.seed) - 0.5) * 3.0 + 0.5).clamp(0.0, 1.0),
            Pattern::Marble => {
                let d = Vec3::cst(self.direction).normalize_or(Vec3::new(1.0, 0.0, 0.0));
                let s = q.dot(d) + 2.0 * fbm(q * 0.5, 4, self.seed);
                0.5 + 0.5 * (s * std::f64::consts::PI).sin()
            }
        };
        let base = palette(&self.colors, t);
        // Fine detail at a quarter of the feature size.
        let n = fbm(q * 4.0, 3, self.seed.wrapping_add(17)) - 0.5;
        let m = 1.0 + self.detail * 1.4 * n;
        base.map(|c| (c * m).clamp(0.0, 1.0))
    }
}

/// Blend a palette with `t ∈ [0, 1]` (piecewise linear).
fn palette(colors: &[[f64; 3]], t: f64) -> [f64; 3] {
    let n = colors.len() - 1;
    let x = t.clamp(0.0, 1.0) * n as f64;
    let i = (x.floor() as usize).min(n.saturating_sub(1));
    let f = x - i as f64;
    let (a, b) = (colors[i], colors[(i + 1).min(n)]);
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * f)
}

/// A hash of a lattice point to [0, 1).
fn lattice(ix: i64, iy: i64, iz: i64, seed: u64) -> f64 {
    let mut h = seed ^ 0x9E37_79B9_7F4A_7C15;
    for v in [ix, iy, iz] {
        h ^= v as u64;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 29;
    }
    h = h.wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^= h >> 32;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Trilinear value noise with a smooth fade, in [0, 1).
fn value_noise(p: Vec3<f64>, seed: u64) -> f64 {
    let (fx, fy, fz) = (p.x.floor(), p.y.floor(), p.z.floor());
    let (ix, iy, iz) = (fx as i64, fy as i64, fz as i64);
    let fade = |t: f64| t * t * (3.0 - 2.0 * t);
    let (u, v, w) = (fade(p.x - fx), fade(p.y - fy), fade(p.z - fz));
    let mut acc = 0.0;
    for dz in 0..2 {
        for dy in 0..2 {
            for dx in 0..2 {
                let wx = if dx == 1 { u } else { 1.0 - u };
                let wy = if dy == 1 { v } else { 1.0 - v };
                let wz = if dz == 1 { w } else { 1.0 - w };
                acc += wx * wy * wz * lattice(ix + dx, iy + dy, iz + dz, seed);
            }
        }
    }
    acc
}

/// Fractal sum of `octaves` noise layers, in [0, 1).
fn fbm(p: Vec3<f64>, octaves: u32, seed: u64) -> f64 {
    let (mut sum, mut amp, mut norm, mut q) = (0.0, 0.5, 0.0, p);
    for o in 0..octaves {
        sum += amp * value_noise(q, seed.wrapping_add(o as u64 * 101));
        norm += amp;
        amp *= 0.5;
        q = q * 2.03;
    }
    sum / norm
}
