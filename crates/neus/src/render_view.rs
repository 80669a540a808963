//! Rendering whole views from a trained field: colour, depth and normals,
//! and PSNR against a capture's images.

use crate::neus_field::NeusField;
use crate::occupancy::{sample_ray, Marching, OccupancyGrid};
use crate::volume::{render_ray, RayInputs};
use field::{sh_encode, MlpScratch, SH_DIM};
use geom::Camera;

/// A rendered view.
pub struct ViewImage {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<[f32; 3]>,
    /// Σ w t in unit coordinates (0 where nothing was hit).
    pub depth: Vec<f32>,
    /// Σ w n (unit coordinates' axes are the world's).
    pub normal: Vec<[f32; 3]>,
    pub opacity: Vec<f32>,
}

/// Settings for rendering (the trainer's, or finer).
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    pub steps_per_ray: usize,
    pub max_samples_per_ray: usize,
    pub active_levels: usize,
    /// Finite-difference step for normals, unit coordinates.
    pub fd_eps: f32,
}

/// Render rays (origins and directions in unit coordinates).
pub fn render_rays(
    field: &NeusField,
    occupancy: &OccupancyGrid,
    set: &RenderSettings,
    origins: &[[f32; 3]],
    dirs: &[[f32; 3]],
) -> Vec<(crate::volume::RayOutput, [f32; 3])> {
    let (mut t, mut dt, mut offsets) = (Vec::new(), Vec::new(), vec![0usize]);
    let march = Marching {
        steps: set.steps_per_ray,
        cap: set.max_samples_per_ray,
    };
    for (o, d) in origins.iter().zip(dirs) {
        sample_ray(occupancy, *o, *d, march, 0.5, &mut t, &mut dt);
        offsets.push(t.len());
    }
    let m = t.len();
    let eps = set.fd_eps;
    let mut pts = vec![0.0f32; 4 * m * 3];
    let mut sdirs = vec![0.0f32; m * 3];
    for (i, (o, d)) in origins.iter().zip(dirs).enumerate() {
        for s in offsets[i]..offsets[i + 1] {
            let p = [o[0] + t[s] * d[0], o[1] + t[s] * d[1], o[2] + t[s] * d[2]];
            sdirs[s * 3..s * 3 + 3].copy_from_slice(d);
            for b in 0..4 {
                let mut q = p;
                if b > 0 {
                    q[b - 1] += eps;
                }
                pts[(b * m + s) * 3..(b * m + s) * 3 + 3].copy_from_slice(&q);
            }
        }
    }
    let width = 1 + field.config.feature_dim;
    let (mut enc, mut input, mut scratch) = (Vec::new(), Vec::new(), MlpScratch::default());
    let out = field
        .sdf_forward(&pts, set.active_levels, &mut enc, &mut input, &mut scratch)
        .to_vec();
    let cin = SH_DIM + 3 + field.config.feature_dim;
    let mut sh = vec![0.0f32; m * SH_DIM];
    sh_encode(&sdirs, &mut sh);
    let mut color_in = vec![0.0f32; m * cin];
    let mut sdf0 = vec![0.0f32; m];
    let mut cos = vec![0.0f32; m];
    let mut normals = vec![[0.0f32; 3]; m];
    for s in 0..m {
        let s0 = out[s * width];
        let g: [f32; 3] = std::array::from_fn(|k| (out[((k + 1) * m + s) * width] - s0) / eps);
        let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt().max(1e-8);
        sdf0[s] = s0;
        cos[s] = g[0] * sdirs[s * 3] + g[1] * sdirs[s * 3 + 1] + g[2] * sdirs[s * 3 + 2];
        normals[s] = g.map(|v| v / len);
        let row = &mut color_in[s * cin..(s + 1) * cin];
        row[..SH_DIM].copy_from_slice(&sh[s * SH_DIM..(s + 1) * SH_DIM]);
        row[SH_DIM..SH_DIM + 3].copy_from_slice(&normals[s]);
        row[SH_DIM + 3..].copy_from_slice(&out[s * width + 1..(s + 1) * width]);
    }
    let mut cscratch = MlpScratch::default();
    let rgb: Vec<[f32; 3]> = field
        .color
        .forward(&field.color_params, &color_in, m, &mut cscratch)
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let (inv_s, bg) = (field.inv_s(), field.background());
    let (mut alpha, mut w) = (Vec::new(), Vec::new());
    (0..origins.len())
        .map(|i| {
            let (a, b) = (offsets[i], offsets[i + 1]);
            alpha.resize(b - a, 0.0);
            w.resize(b - a, 0.0);
            let x = RayInputs {
                sdf: &sdf0[a..b],
                cos: &cos[a..b],
                dt: &dt[a..b],
                t: &t[a..b],
                rgb: &rgb[a..b],
                inv_s,
                anneal: 1.0,
                background: bg,
            };
            let o = render_ray(&x, &mut alpha, &mut w);
            let mut n = [0.0f32; 3];
            for (s, wi) in (a..b).zip(&w) {
                for k in 0..3 {
                    n[k] += wi * normals[s][k];
                }
            }
            (o, n)
        })
        .collect()
}

/// Render a whole view through `camera` (pose in unit coordinates).
pub fn render_view(
    field: &NeusField,
    occupancy: &OccupancyGrid,
    set: &RenderSettings,
    camera: &Camera<f64>,
) -> ViewImage {
    let (w, h) = (camera.width, camera.height);
    let n = (w * h) as usize;
    let mut img = ViewImage {
        width: w,
        height: h,
        rgb: Vec::with_capacity(n),
        depth: Vec::with_capacity(n),
        normal: Vec::with_capacity(n),
        opacity: Vec::with_capacity(n),
    };
    let rows_per_chunk = (8192 / w.max(1)).max(1);
    for y0 in (0..h).step_by(rows_per_chunk as usize) {
        let (mut o, mut d) = (Vec::new(), Vec::new());
        for y in y0..(y0 + rows_per_chunk).min(h) {
            for x in 0..w {
                let r = camera.ray(x as f64 + 0.5, y as f64 + 0.5);
                o.push(r.origin.to_array().map(|v| v as f32));
                d.push(r.dir.to_array().map(|v| v as f32));
            }
        }
        for (out, nrm) in render_rays(field, occupancy, set, &o, &d) {
            img.rgb.push(out.rgb);
            img.depth.push(out.depth);
            img.normal.push(nrm);
            img.opacity.push(out.opacity);
        }
    }
    img
}

/// PSNR (dB) of `rgb` against `gt`, over the pixels where `mask` is 1 (all without a mask).
pub fn psnr(rgb: &[[f32; 3]], gt: &[[f32; 3]], mask: Option<&[f32]>) -> f32 {
    let (mut se, mut n) = (0.0f64, 0.0f64);
    for (i, (a, b)) in rgb.iter().zip(gt).enumerate() {
        let w = mask.map_or(1.0, |m| m[i]) as f64;
        for k in 0..3 {
            se += w * ((a[k] - b[k]) as f64).powi(2);
        }
        n += 3.0 * w;
    }
    (-10.0 * (se / n.max(1.0)).max(1e-12).log10()) as f32
}
