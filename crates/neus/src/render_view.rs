//! Rendering whole views from a trained field: colour, depth and normals,
//! and PSNR against a capture's images.

use crate::fd_samples::{fd_gradients, fd_points, FdOut};
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
    let (mut pts, mut sdirs) = (Vec::new(), Vec::new());
    fd_points(origins, dirs, &offsets, &t, eps, &mut pts, &mut sdirs);
    let width = 1 + field.config.feature_dim;
    let (mut unit01, mut enc, mut input, mut scratch) = (Vec::new(), Vec::new(), Vec::new(), MlpScratch::default());
    let out = field.sdf_forward(&pts, set.active_levels, &mut unit01, &mut enc, &mut input, &mut scratch);
    let cin = SH_DIM + 3 + field.config.feature_dim;
    let mut sh = vec![0.0f32; m * SH_DIM];
    sh_encode(&sdirs, &mut sh);
    let (mut grad, mut sdf0, mut cos, mut color_in) = (
        vec![[0.0f32; 3]; m],
        vec![0.0f32; m],
        vec![0.0f32; m],
        vec![0.0f32; m * cin],
    );
    fd_gradients(
        out,
        width,
        eps,
        &sdirs,
        &sh,
        FdOut {
            grad: &mut grad,
            sdf0: &mut sdf0,
            cos: &mut cos,
            color_in: &mut color_in,
        },
    );
    let normals: Vec<[f32; 3]> = grad
        .iter()
        .map(|g| {
            let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt().max(1e-8);
            g.map(|v| v / len)
        })
        .collect();
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
