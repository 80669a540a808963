//! Rendering whole views from a trained field: colour, depth and normals,
//! and PSNR against a capture's images.

use crate::background_field::BackgroundScratch;
use crate::field_pass::PassSettings;
use crate::neus_field::NeusField;
use crate::occupancy::{sample_ray, Marching, OccupancyGrid};
use crate::ray_rounds::RayRounds;
use crate::volume::{render_ray, RayInputs};
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
    /// Samples at which the field was evaluated.
    pub samples: usize,
}

pub use crate::volume::STOP_TRANSMITTANCE;

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
    /// A ray through a field stops once its transmittance through that field is below this (0: never; see
    /// [`crate::ray_rounds`]): colour and opacity change by less than this, and the samples past the round
    /// (a third of the ray's samples) in which the ray became opaque are never evaluated.
    pub stop_transmittance: f32,
}

/// Buffers of [`render_rays`], reused across calls (a view is rendered in
/// chunks: allocating per chunk cost more than rendering on scenes, where
/// every ray carries samples).
#[derive(Default)]
pub struct RenderScratch {
    t: Vec<f32>,
    dt: Vec<f32>,
    offsets: Vec<usize>,
    eval: RayRounds,
    alpha: Vec<f32>,
    w: Vec<f32>,
    bg: BackgroundScratch,
    /// The rays the background field is evaluated for, and what it gives every ray (zero where stopped).
    open_o: Vec<[f32; 3]>,
    open_d: Vec<[f32; 3]>,
    behind: Vec<[f32; 3]>,
}

impl RenderSettings {
    /// A trained field's settings for rendering: twice its training's steps and sample cap, every level,
    /// the finest cell as the finite-difference step.
    pub fn of(l: &crate::checkpoint::LoadedField) -> Self {
        let c = &l.config;
        let g = &c.field.grid;
        Self {
            steps_per_ray: c.steps_per_ray * 2,
            max_samples_per_ray: c.max_samples_per_ray * 2,
            active_levels: g.levels,
            fd_eps: g.finest_cell(),
            view_independent: l.step < c.view_independent_steps,
            stop_transmittance: STOP_TRANSMITTANCE,
        }
    }

    /// What the field pass needs of these settings.
    pub fn pass(&self) -> PassSettings {
        PassSettings {
            active_levels: self.active_levels,
            fd_eps: self.fd_eps,
            view_independent: self.view_independent,
        }
    }

    /// How rays are marched: equal steps counted from the ray's origin (see [`Marching::anchored`]).
    pub fn marching(&self) -> Marching {
        Marching {
            steps: self.steps_per_ray,
            cap: self.max_samples_per_ray,
            anchored: true,
        }
    }
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
    let march = set.marching();
    for (o, d) in origins.iter().zip(dirs) {
        sample_ray(occupancy, *o, *d, march, 0.5, &mut sc.t, &mut sc.dt);
        sc.offsets.push(sc.t.len());
    }
    sc.eval.forward(
        field,
        None,
        origins,
        dirs,
        &sc.offsets,
        &sc.t,
        &sc.dt,
        set.pass(),
        set.stop_transmittance,
    );
    let p = &sc.eval;
    let inv_s = field.inv_s();
    // What lies behind, for the rays still open (a stopped ray's background adds less than the threshold,
    // and on a scene nearly every ray stops at the board).
    let stop = set.stop_transmittance;
    let open = |i: &usize| p.transmittance()[*i] >= stop;
    sc.open_o.clear();
    sc.open_d.clear();
    for i in (0..origins.len()).filter(open) {
        sc.open_o.push(origins[i]);
        sc.open_d.push(dirs[i]);
    }
    field.colour_behind(&sc.open_o, &sc.open_d, |_| 0.5, &mut sc.bg);
    sc.behind.clear();
    sc.behind.resize(origins.len(), [0.0; 3]);
    for (i, c) in (0..origins.len()).filter(open).zip(&sc.bg.out) {
        sc.behind[i] = *c;
    }
    (0..origins.len())
        .map(|i| {
            let (a, b) = (p.offsets[i], p.offsets[i + 1]);
            sc.alpha.resize(b - a, 0.0);
            sc.w.resize(b - a, 0.0);
            let x = RayInputs {
                sdf: &p.sdf[a..b],
                cos: &p.cos[a..b],
                dt: &p.dt[a..b],
                t: &p.t[a..b],
                rgb: &p.rgb[a..b],
                inv_s,
                anneal: 1.0,
                background: sc.behind[i],
            };
            let o = render_ray(&x, &mut sc.alpha, &mut sc.w);
            let mut n = [0.0f32; 3];
            for (s, wi) in (a..b).zip(&sc.w) {
                let g = p.grad[s];
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
        samples: 0,
    };
    // About 2,000 rays per chunk: a scene's rays all carry samples (up to 4 SDF
    // evaluations × the sample cap each), and the MLP scratch grows with them.
    let rows_per_chunk = (2048 / w.max(1)).max(1);
    let mut scratch = RenderScratch::default();
    let (mut o, mut d) = (Vec::new(), Vec::new());
    for y0 in (0..h).step_by(rows_per_chunk as usize) {
        o.clear();
        d.clear();
        for y in y0..(y0 + rows_per_chunk).min(h) {
            for x in 0..w {
                let r = camera.ray(x as f64 + 0.5, y as f64 + 0.5);
                o.push(r.origin.to_array().map(|v| v as f32));
                d.push(r.dir.to_array().map(|v| v as f32));
            }
        }
        let rays = render_rays(field, occupancy, set, &o, &d, &mut scratch);
        img.samples += scratch.eval.t.len();
        for (out, nrm) in rays {
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
