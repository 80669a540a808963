//! Rendering whole views from a trained field: colour, depth and normals,
//! and PSNR against a capture's images.

use crate::background_field::BackgroundScratch;
use crate::fd_samples::{fd_gradients, fd_points, FdOut};
use crate::neus_field::{drop_view_dependence, NeusField};
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
    /// Colour from the point alone (the field is still in its view-independent first steps).
    pub view_independent: bool,
}

/// Buffers of [`render_rays`], reused across calls (a view is rendered in
/// chunks: allocating per chunk cost more than rendering on scenes, where
/// every ray carries samples).
#[derive(Default)]
pub struct RenderScratch {
    t: Vec<f32>,
    dt: Vec<f32>,
    offsets: Vec<usize>,
    pts: Vec<f32>,
    sdirs: Vec<f32>,
    unit01: Vec<f32>,
    enc: Vec<f32>,
    input: Vec<f32>,
    sdf_mlp: MlpScratch,
    sdf_out: Vec<f32>,
    sh: Vec<f32>,
    grad: Vec<[f32; 3]>,
    sdf0: Vec<f32>,
    cos: Vec<f32>,
    color_in: Vec<f32>,
    color_mlp: MlpScratch,
    rgb: Vec<[f32; 3]>,
    alpha: Vec<f32>,
    w: Vec<f32>,
    bg: BackgroundScratch,
}

/// Render rays (origins and directions in unit coordinates): each ray's
/// output and its normal (Σ w n).
pub fn render_rays(
    field: &NeusField,
    occupancy: &OccupancyGrid,
    set: &RenderSettings,
    origins: &[[f32; 3]],
    dirs: &[[f32; 3]],
    sc: &mut RenderScratch,
) -> Vec<(crate::volume::RayOutput, [f32; 3])> {
    sc.t.clear();
    sc.dt.clear();
    sc.offsets.clear();
    sc.offsets.push(0);
    let march = Marching {
        steps: set.steps_per_ray,
        cap: set.max_samples_per_ray,
    };
    for (o, d) in origins.iter().zip(dirs) {
        sample_ray(occupancy, *o, *d, march, 0.5, &mut sc.t, &mut sc.dt);
        sc.offsets.push(sc.t.len());
    }
    let m = sc.t.len();
    let eps = set.fd_eps;
    fd_points(origins, dirs, &sc.offsets, &sc.t, eps, &mut sc.pts, &mut sc.sdirs);
    let width = 1 + field.config.feature_dim;
    let out = field.sdf_forward(
        &sc.pts,
        set.active_levels,
        &mut sc.unit01,
        &mut sc.enc,
        &mut sc.input,
        &mut sc.sdf_mlp,
    );
    sc.sdf_out.clear();
    sc.sdf_out.extend_from_slice(out);
    let cin = SH_DIM + 3 + field.config.feature_dim;
    sc.sh.resize(m * SH_DIM, 0.0);
    sh_encode(&sc.sdirs, &mut sc.sh);
    if set.view_independent {
        drop_view_dependence(&mut sc.sh);
    }
    sc.grad.resize(m, [0.0; 3]);
    sc.sdf0.resize(m, 0.0);
    sc.cos.resize(m, 0.0);
    sc.color_in.resize(m * cin, 0.0);
    fd_gradients(
        &sc.sdf_out,
        width,
        eps,
        &sc.sdirs,
        &sc.sh,
        FdOut {
            grad: &mut sc.grad,
            sdf0: &mut sc.sdf0,
            cos: &mut sc.cos,
            color_in: &mut sc.color_in,
        },
    );
    let rgb = field
        .color
        .forward(&field.color_params, &sc.color_in, m, &mut sc.color_mlp);
    sc.rgb.clear();
    sc.rgb.extend(rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
    let inv_s = field.inv_s();
    field.colour_behind(origins, dirs, |_| 0.5, &mut sc.bg);
    (0..origins.len())
        .map(|i| {
            let (a, b) = (sc.offsets[i], sc.offsets[i + 1]);
            sc.alpha.resize(b - a, 0.0);
            sc.w.resize(b - a, 0.0);
            let x = RayInputs {
                sdf: &sc.sdf0[a..b],
                cos: &sc.cos[a..b],
                dt: &sc.dt[a..b],
                t: &sc.t[a..b],
                rgb: &sc.rgb[a..b],
                inv_s,
                anneal: 1.0,
                background: sc.bg.out[i],
            };
            let o = render_ray(&x, &mut sc.alpha, &mut sc.w);
            let mut n = [0.0f32; 3];
            for (s, wi) in (a..b).zip(&sc.w) {
                let g = sc.grad[s];
                let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt().max(1e-8);
                for k in 0..3 {
                    n[k] += wi * g[k] / len;
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
    // About 2,000 rays per chunk: a scene's rays all carry samples (up to 4 SDF
    // evaluations × the sample cap each), and the MLP scratch grows with them.
    let rows_per_chunk = (2048 / w.max(1)).max(1);
    let mut scratch = RenderScratch::default();
    for y0 in (0..h).step_by(rows_per_chunk as usize) {
        let (mut o, mut d) = (Vec::new(), Vec::new());
        for y in y0..(y0 + rows_per_chunk).min(h) {
            for x in 0..w {
                let r = camera.ray(x as f64 + 0.5, y as f64 + 0.5);
                o.push(r.origin.to_array().map(|v| v as f32));
                d.push(r.dir.to_array().map(|v| v as f32));
            }
        }
        for (out, nrm) in render_rays(field, occupancy, set, &o, &d, &mut scratch) {
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
