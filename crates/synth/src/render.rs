//! A CPU sphere tracer over the same SDFs the simulator uses: RGB with
//! stratified supersampling, soft shadows from one directional light, and
//! exact object ids at pixel centres (the masks).

use crate::texture::Texture;
use geom::{Camera, Pose, Ray, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sim::sdf::{Sdf, Shape};

type V = Vec3<f64>;

/// Lighting: ambient plus one directional light with soft shadows, and a sky.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Light {
    /// Ambient light, 0–1. Default 0.35.
    pub ambient: f64,
    /// Direction towards the light (need not be unit). Default (0.4, −0.3, 1).
    pub direction: [f64; 3],
    /// Strength of the directional light. Default 0.75.
    pub intensity: f64,
    /// Shadow softness: larger is sharper (penumbra ~ 1/softness). Default 12.
    pub softness: f64,
    /// Sky colour at the horizon and the zenith (rays that hit nothing).
    pub sky_horizon: [f64; 3],
    pub sky_zenith: [f64; 3],
}

impl Default for Light {
    fn default() -> Self {
        Self {
            ambient: 0.35,
            direction: [0.4, -0.3, 1.0],
            intensity: 0.75,
            softness: 12.0,
            sky_horizon: [0.75, 0.78, 0.82],
            sky_zenith: [0.45, 0.55, 0.7],
        }
    }
}

/// One thing in a rendered scene.
#[derive(Clone, Debug)]
pub struct RenderObject {
    /// Geometry in the object's frame.
    pub shape: Shape,
    /// Object frame to world.
    pub pose: Pose<f64>,
    pub texture: Texture,
    /// A ball (centre in the world, radius) holding the object, or `None` when unbounded.
    pub bound: Option<(V, f64)>,
    /// Which mask the object belongs to (`Some(k)` for body k), `None` for scenery.
    pub mask_id: Option<usize>,
    /// A board printed on the object's top face at world z = 0 (the board slab's), over its texture.
    pub print: Option<std::sync::Arc<crate::print::Print>>,
}

impl RenderObject {
    #[inline]
    fn distance(&self, p: V) -> f64 {
        self.shape.distance(&self.pose, p)
    }
}

/// Everything a camera sees.
#[derive(Clone, Debug)]
pub struct RenderScene {
    pub objects: Vec<RenderObject>,
    pub light: Light,
}

/// A rendered view: linear RGB per pixel, and the mask id seen at each pixel centre.
pub struct Rendered {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<[f32; 3]>,
    /// `Some(k)`: body k at the pixel centre; empty when the render was asked for colour only.
    pub ids: Vec<Option<usize>>,
}

const MAX_STEPS: usize = 400;
const MAX_DIST: f64 = 30.0;

/// Nearest object and its distance at `p`, using each object's bounding ball
/// as a cheap lower bound while far away.
#[inline]
fn nearest(scene: &RenderScene, p: V) -> (f64, usize) {
    let mut best = (f64::INFINITY, usize::MAX);
    for (i, o) in scene.objects.iter().enumerate() {
        if let Some((c, r)) = o.bound {
            let lb = (p - c).norm() - r;
            if lb >= best.0 {
                continue;
            }
            // Far from the ball: the ball's distance is a safe step.
            if lb > 0.05 * r.max(0.01) {
                best = (lb, i);
                continue;
            }
        }
        let d = o.distance(p);
        if d < best.0 {
            best = (d, i);
        }
    }
    best
}

/// March along `ray`; the hit distance and object.
fn trace(scene: &RenderScene, ray: &Ray<f64>) -> Option<(f64, usize)> {
    let mut t = 0.0;
    for _ in 0..MAX_STEPS {
        let p = ray.at(t);
        let (d, i) = nearest(scene, p);
        let eps = 2e-5 * (1.0 + t);
        if d < eps {
            // The bound may have been used: confirm with the exact distance.
            let exact = scene.objects[i].distance(p);
            if exact < eps {
                return Some((t, i));
            }
            t += exact.max(eps);
        } else {
            t += d;
        }
        if t > MAX_DIST {
            return None;
        }
    }
    None
}

/// Soft shadow factor towards the light, in [0, 1] (Quilez's penumbra estimate).
fn soft_shadow(scene: &RenderScene, p: V, l: V, k: f64) -> f64 {
    let mut res: f64 = 1.0;
    let mut t = 2e-3;
    for _ in 0..128 {
        let (d, _) = nearest(scene, p + l * t);
        if d < 1e-5 {
            return 0.0;
        }
        res = res.min(k * d / t);
        t += d.clamp(1e-3, 0.2);
        if t > 3.0 || res < 1e-3 {
            break;
        }
    }
    res.clamp(0.0, 1.0)
}

fn shade(scene: &RenderScene, ray: &Ray<f64>) -> ([f64; 3], Option<usize>) {
    let light = &scene.light;
    match trace(scene, ray) {
        None => {
            let s = ray.dir.z.clamp(0.0, 1.0);
            (
                std::array::from_fn(|k| light.sky_horizon[k] + (light.sky_zenith[k] - light.sky_horizon[k]) * s),
                None,
            )
        }
        Some((t, i)) => {
            let o = &scene.objects[i];
            let p = ray.at(t);
            let (_, g) = o.shape.distance_grad(&o.pose, p);
            let mut n = g.normalize_or(-ray.dir);
            if n.dot(ray.dir) > 0.0 {
                n = -n;
            }
            let local = o.pose.inverse_transform_point(p);
            let printed = match &o.print {
                Some(print) if p.z > -1e-4 && n.z > 0.5 => print.albedo(p.x, p.y),
                _ => None,
            };
            let albedo = printed.unwrap_or_else(|| o.texture.albedo(local));
            let l = V::cst(light.direction).normalize_or(V::new(0.0, 0.0, 1.0));
            let lambert = n.dot(l).max(0.0);
            let shadow = if lambert > 0.0 {
                soft_shadow(scene, p + n * 1e-3, l, light.softness)
            } else {
                0.0
            };
            let lit = light.ambient + light.intensity * lambert * shadow;
            (albedo.map(|a| a * lit), o.mask_id)
        }
    }
}

/// Sample offsets inside a pixel: an n×n stratified grid with a fixed jitter
/// (deterministic: the same image every run), recentred so that their mean is
/// the pixel's centre: an off-centre mean shifts every image by the same
/// fraction of a pixel, which a real camera does not do and which biases
/// stereo depth and NeuS alike.
fn subpixel_offsets(spp: usize) -> Vec<(f64, f64)> {
    let n = (spp as f64).sqrt().ceil().max(1.0) as usize;
    let mut rng = geom::SplitMix64::new(0x5EED);
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            out.push((
                (i as f64 + rng.next_f64()) / n as f64,
                (j as f64 + rng.next_f64()) / n as f64,
            ));
        }
    }
    out.truncate(spp.max(1));
    let k = out.len() as f64;
    let (mx, my) = out.iter().fold((0.0, 0.0), |a, o| (a.0 + o.0 / k, a.1 + o.1 / k));
    out.iter().map(|&(x, y)| (x + 0.5 - mx, y + 0.5 - my)).collect()
}

/// Render `scene` through `camera` with `spp` samples per pixel.
pub fn render(scene: &RenderScene, camera: &Camera<f64>, spp: usize) -> Rendered {
    render_rays(scene, camera.width, camera.height, spp, true, &|u, v| camera.ray(u, v))
}

/// Render `scene` at `width` × `height` with `spp` samples per pixel, the ray through image position `(u, v)`
/// (pixel centres at integer + 0.5) given by `ray`: any lens. `with_ids`: also trace each pixel's centre for
/// the mask id (one more ray per pixel, a fifth of the work at 4 samples: raw footage has no masks).
pub fn render_rays(
    scene: &RenderScene,
    width: u32,
    height: u32,
    spp: usize,
    with_ids: bool,
    ray: &(dyn Fn(f64, f64) -> Ray<f64> + Sync),
) -> Rendered {
    render_samples(scene, width, height, &subpixel_offsets(spp), with_ids, ray)
}

/// [`render_rays`] with the samples' positions inside a pixel given (`(0.5, 0.5)` is its centre).
fn render_samples(
    scene: &RenderScene,
    width: u32,
    height: u32,
    offsets: &[(f64, f64)],
    with_ids: bool,
    ray: &(dyn Fn(f64, f64) -> Ray<f64> + Sync),
) -> Rendered {
    let (w, h) = (width as usize, height as usize);
    type Row = (Vec<[f32; 3]>, Vec<Option<usize>>);
    let rows: Vec<Row> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut rgb = Vec::with_capacity(w);
            let mut ids = Vec::with_capacity(if with_ids { w } else { 0 });
            for x in 0..w {
                if with_ids {
                    let centre = ray(x as f64 + 0.5, y as f64 + 0.5);
                    ids.push(trace(scene, &centre).and_then(|(_, i)| scene.objects[i].mask_id));
                }
                let mut acc = [0.0; 3];
                for &(dx, dy) in offsets {
                    let (c, _) = shade(scene, &ray(x as f64 + dx, y as f64 + dy));
                    for k in 0..3 {
                        acc[k] += c[k];
                    }
                }
                let inv = 1.0 / offsets.len() as f64;
                rgb.push(acc.map(|v| (v * inv) as f32));
            }
            (rgb, ids)
        })
        .collect();
    let mut rgb = Vec::with_capacity(w * h);
    let mut ids = Vec::with_capacity(w * h);
    for (r, i) in rows {
        rgb.extend(r);
        ids.extend(i);
    }
    Rendered {
        width,
        height,
        rgb,
        ids,
    }
}

/// `scenes` (the instants of a shutter time, or one instant) rendered at `spp` samples per pixel in all (at
/// least one per instant) and averaged: a moving body blurs. The instants share one stratified set of
/// positions in the pixel, so a still part of the image is sampled as [`render_rays`] samples it. The mask
/// ids are those of instant `ids_of` (the frame's own), if given.
pub fn render_instants(
    scenes: &[RenderScene],
    width: u32,
    height: u32,
    spp: usize,
    ids_of: Option<usize>,
    ray: &(dyn Fn(f64, f64) -> Ray<f64> + Sync),
) -> Rendered {
    let n = scenes.len().max(1);
    let per_instant = spp.div_ceil(n).max(1);
    let offsets = subpixel_offsets(per_instant * n);
    let mut out = Rendered {
        width,
        height,
        rgb: vec![[0.0; 3]; width as usize * height as usize],
        ids: Vec::new(),
    };
    for (k, s) in scenes.iter().enumerate() {
        let mine: Vec<(f64, f64)> = offsets.iter().skip(k).step_by(n).copied().collect();
        let r = render_samples(s, width, height, &mine, ids_of == Some(k), ray);
        for (a, b) in out.rgb.iter_mut().zip(&r.rgb) {
            for c in 0..3 {
                a[c] += b[c] / scenes.len() as f32;
            }
        }
        if ids_of == Some(k) {
            out.ids = r.ids;
        }
    }
    out
}

/// The distance from `p` to the nearest object (for placement checks).
pub fn scene_distance(scene: &RenderScene, p: V) -> f64 {
    scene
        .objects
        .iter()
        .map(|o| o.distance(p))
        .fold(f64::INFINITY, f64::min)
}

/// sRGB encoding of a linear value, to 8 bits.
pub fn to_srgb8(v: f32) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5).floor() as u8
}
