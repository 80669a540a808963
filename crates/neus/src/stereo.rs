//! Multi-view stereo points for a scene's start: a plane sweep with patch NCC
//! against neighbouring views, then a cross-view depth check. NeuS adds
//! geometry in free space only through samples that already carry density, so
//! an obstacle standing on a flat start rarely grows (it is painted onto the
//! board instead); points on its textured faces, pulled onto the zero level
//! (Geo-NeuS's explicit SDF supervision, here from our own stereo rather than
//! SfM), make it grow. Textureless pixels give no point, which is right: they
//! carry no parallax either.

use crate::occupancy::sphere_span;
use crate::{CaptureSubject, Dataset};
use field::ConfigError;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// How the stereo points are found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StereoConfig {
    /// Views compared with each reference view (the nearest by angle about the region's centre). Default 3.
    pub neighbours: usize,
    /// Patch half-width in pixels, rounded down to whole samples at the stride (at least one). Default 2: a
    /// 5×5 patch at stride 1, 3×3 samples 2 px apart at stride 2. Wider patches at the foot of a wall straddle
    /// the concave corner and put points in the air in front of it, which grow a fillet there (at the
    /// tabletop's wall at 320×240, 129 of 418 points near the foot with 5×5 samples at stride 2, 66 with 3×3).
    pub patch_radius: usize,
    /// Reference pixels and patch samples this many pixels apart (0: 1 up to 200 px wide, else 2). Default 0.
    pub stride: usize,
    /// Depth hypotheses across each ray's chord of the unit sphere. Default 128.
    pub hypotheses: usize,
    /// Keep a pixel when the mean NCC of its best two neighbours reaches this. Default 0.7.
    pub min_ncc: f32,
    /// Skip reference patches whose grey-level deviation is below this (no texture, no parallax). Default 0.02.
    pub min_contrast: f32,
    /// A point must agree with a neighbour's depth within this fraction of its depth. Default 0.01.
    pub depth_agreement: f32,
    /// Points are averaged in cubes of this edge (unit coordinates), so that every part of the surface weighs
    /// by its area, not by how many views see it; a cube with a single point is dropped as an outlier.
    /// Default 2/128.
    pub voxel: f32,
}

impl Default for StereoConfig {
    fn default() -> Self {
        Self {
            neighbours: 3,
            patch_radius: 2,
            stride: 0,
            hypotheses: 128,
            min_ncc: 0.7,
            min_contrast: 0.02,
            depth_agreement: 0.01,
            voxel: 2.0 / 128.0,
        }
    }
}

impl StereoConfig {
    /// Check ranges; keys are named as in the `[stereo]` table.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |key: &str, problem: String| Err(ConfigError::new(key, problem));
        if self.neighbours < 2 {
            return bad("neighbours", "must be at least 2 (the best two are averaged)".into());
        }
        if !(1..=8).contains(&self.patch_radius) {
            return bad("patch_radius", format!("must be 1 to 8, got {}", self.patch_radius));
        }
        if self.hypotheses < 3 {
            return bad("hypotheses", format!("must be at least 3, got {}", self.hypotheses));
        }
        if !(self.min_ncc.is_finite() && self.min_ncc <= 1.0) {
            return bad("min_ncc", format!("must be at most 1, got {}", self.min_ncc));
        }
        if !(self.voxel.is_finite() && self.voxel > 0.0) {
            return bad("voxel", format!("must be positive, got {}", self.voxel));
        }
        if !(self.depth_agreement.is_finite() && self.depth_agreement > 0.0) {
            return bad(
                "depth_agreement",
                format!("must be positive, got {}", self.depth_agreement),
            );
        }
        Ok(())
    }
}

/// A view's camera in unit coordinates, in f32 for the sweep.
#[derive(Clone, Copy)]
struct Cam {
    /// World-to-camera rotation (rows) and translation.
    r: [[f32; 3]; 3],
    t: [f32; 3],
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    skew: f32,
    centre: [f32; 3],
}

impl Cam {
    fn of(view: &crate::dataset::View) -> Self {
        let c = &view.camera;
        let m = c.world_to_cam.q.to_mat();
        let t = c.world_to_cam.t;
        let centre = c.center();
        Self {
            r: m.m.map(|row| row.map(|v| v as f32)),
            t: [t.x, t.y, t.z].map(|v| v as f32),
            fx: c.k.fx as f32,
            fy: c.k.fy as f32,
            cx: c.k.cx as f32,
            cy: c.k.cy as f32,
            skew: c.k.skew as f32,
            centre: [centre.x, centre.y, centre.z].map(|v| v as f32),
        }
    }

    fn camera_coords(&self, p: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|i| dot(self.r[i], p) + self.t[i])
    }

    /// Pixel coordinates (pixel centres at integer + 0.5) and depth.
    fn project(&self, p: [f32; 3]) -> (f32, f32, f32) {
        let q = self.camera_coords(p);
        let u = (q[0] * self.fx + q[1] * self.skew) / q[2] + self.cx;
        let v = q[1] * self.fy / q[2] + self.cy;
        (u, v, q[2])
    }

    /// The unit world direction through pixel coordinates `(u, v)`.
    fn ray_dir(&self, u: f32, v: f32) -> [f32; 3] {
        let y = (v - self.cy) / self.fy;
        let x = (u - self.cx - self.skew * y) / self.fx;
        // Rᵀ (x, y, 1)
        let d: [f32; 3] = std::array::from_fn(|j| self.r[0][j] * x + self.r[1][j] * y + self.r[2][j]);
        let n = dot(d, d).sqrt();
        d.map(|v| v / n)
    }

    /// The camera's x or y axis in the world (a row of R).
    fn axis(&self, k: usize) -> [f32; 3] {
        self.r[k]
    }
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// A grey image with bilinear lookups at pixel coordinates (centres at + 0.5).
struct Grey {
    w: usize,
    h: usize,
    px: Vec<f32>,
}

impl Grey {
    fn of(rgb: &[[f32; 3]], w: usize, h: usize) -> Self {
        Self {
            w,
            h,
            px: rgb.iter().map(|c| 0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]).collect(),
        }
    }

    #[inline]
    fn at(&self, x: usize, y: usize) -> f32 {
        self.px[y * self.w + x]
    }

    /// `None` outside the image.
    #[inline]
    fn bilinear(&self, u: f32, v: f32) -> Option<f32> {
        let (x, y) = (u - 0.5, v - 0.5);
        if !(x >= 0.0 && y >= 0.0 && x <= (self.w - 1) as f32 && y <= (self.h - 1) as f32) {
            return None;
        }
        let (x0, y0) = ((x as usize).min(self.w - 2), (y as usize).min(self.h - 2));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let top = self.at(x0, y0) * (1.0 - fx) + self.at(x0 + 1, y0) * fx;
        let bottom = self.at(x0, y0 + 1) * (1.0 - fx) + self.at(x0 + 1, y0 + 1) * fx;
        Some(top * (1.0 - fy) + bottom * fy)
    }
}

/// One view's depth map on its stride grid: depth along the optical axis (NaN where no match) and the point.
struct DepthMap {
    cols: usize,
    rows: usize,
    depth: Vec<f32>,
    points: Vec<[f32; 3]>,
}

/// Each view's neighbours: the nearest others by the angle their centres make about the unit sphere's centre,
/// at least 3° apart (some parallax).
fn neighbours(cams: &[Cam], k: usize) -> Vec<Vec<usize>> {
    let dirs: Vec<[f32; 3]> = cams
        .iter()
        .map(|c| {
            let n = dot(c.centre, c.centre).sqrt().max(1e-9);
            c.centre.map(|v| v / n)
        })
        .collect();
    let min_cos = 3f32.to_radians().cos();
    (0..cams.len())
        .map(|i| {
            let mut others: Vec<(f32, usize)> = (0..cams.len())
                .filter(|&j| j != i)
                .map(|j| (dot(dirs[i], dirs[j]), j))
                .filter(|&(c, _)| c < min_cos)
                .collect();
            others.sort_by(|a, b| b.0.total_cmp(&a.0));
            others.into_iter().take(k).map(|(_, j)| j).collect()
        })
        .collect()
}

/// Stereo points (unit coordinates) from the given views of a capture. With masks, reference pixels are those
/// of the subject: outside a scene's masks (they mark what is not scene), inside an object's.
pub fn stereo_points(data: &Dataset, views: &[usize], subject: CaptureSubject, cfg: &StereoConfig) -> Vec<[f32; 3]> {
    let (w, h) = (data.width as usize, data.height as usize);
    if views.len() < 3 || w < 8 || h < 8 {
        return Vec::new();
    }
    let cams: Vec<Cam> = views.iter().map(|&v| Cam::of(&data.views[v])).collect();
    let greys: Vec<Grey> = views.iter().map(|&v| Grey::of(&data.views[v].rgb, w, h)).collect();
    let masks: Vec<Option<&Vec<f32>>> = views.iter().map(|&v| data.views[v].mask.as_ref()).collect();
    let nbrs = neighbours(&cams, cfg.neighbours);
    let stride = if cfg.stride > 0 {
        cfg.stride
    } else if w <= 200 {
        1
    } else {
        2
    };
    let maps: Vec<DepthMap> = (0..views.len())
        .into_par_iter()
        .map(|i| sweep(i, &cams, &greys, masks[i], subject, &nbrs[i], stride, cfg))
        .collect();
    let found: usize = maps
        .iter()
        .map(|m| m.depth.iter().filter(|d| d.is_finite()).count())
        .sum();
    // Keep points that a neighbour's own depth map confirms.
    let mut out = Vec::new();
    for (i, map) in maps.iter().enumerate() {
        for (k, &p) in map.points.iter().enumerate() {
            if !map.depth[k].is_finite() {
                continue;
            }
            let agrees = nbrs[i].iter().any(|&j| {
                let (u, v, z) = cams[j].project(p);
                let (gx, gy) = ((u / stride as f32).floor(), (v / stride as f32).floor());
                let m = &maps[j];
                if !(gx >= 0.0 && gy >= 0.0 && (gx as usize) < m.cols && (gy as usize) < m.rows) {
                    return false;
                }
                let zj = m.depth[gy as usize * m.cols + gx as usize];
                zj.is_finite() && (z - zj).abs() <= cfg.depth_agreement * z
            });
            if agrees {
                out.push(p);
            }
        }
    }
    let means = voxel_means(&out, cfg.voxel);
    tracing::debug!(
        "stereo: {} views at stride {stride}, {} depth hypotheses each: {found} depths found, {} confirmed by a \
         neighbour, {} points after {:.4}-unit voxels",
        views.len(),
        cfg.hypotheses,
        out.len(),
        means.len(),
        cfg.voxel
    );
    means
}

/// The mean of the points in each cube of edge `voxel` that holds at least two, in a stable order.
fn voxel_means(points: &[[f32; 3]], voxel: f32) -> Vec<[f32; 3]> {
    let mut cells: std::collections::BTreeMap<[i32; 3], ([f64; 3], usize)> = Default::default();
    for p in points {
        let key = p.map(|v| (v / voxel).floor() as i32);
        let e = cells.entry(key).or_insert(([0.0; 3], 0));
        for k in 0..3 {
            e.0[k] += p[k] as f64;
        }
        e.1 += 1;
    }
    cells
        .values()
        .filter(|(_, n)| *n >= 2)
        .map(|(s, n)| s.map(|v| (v / *n as f64) as f32))
        .collect()
}

/// The plane sweep of one reference view: for each grid pixel, fronto-parallel patches at depths across the
/// unit sphere, scored by the mean NCC of the two best neighbours; the best depth refined by a parabola.
#[allow(clippy::too_many_arguments)]
fn sweep(
    i: usize,
    cams: &[Cam],
    greys: &[Grey],
    mask: Option<&Vec<f32>>,
    subject: CaptureSubject,
    nbrs: &[usize],
    stride: usize,
    cfg: &StereoConfig,
) -> DepthMap {
    let keep_masked = subject == CaptureSubject::Object;
    let g = &greys[i];
    let cam = cams[i];
    let (cols, rows) = (g.w / stride, g.h / stride);
    let pr = (cfg.patch_radius / stride).max(1) as isize;
    let offsets: Vec<(f32, f32)> = (-pr..=pr)
        .flat_map(|b| (-pr..=pr).map(move |a| ((a * stride as isize) as f32, (b * stride as isize) as f32)))
        .collect();
    let n = offsets.len() as f32;
    let d = cfg.hypotheses;
    let (ax, ay) = (cam.axis(0), cam.axis(1));
    let axis_z = cam.axis(2);
    let mut depth = vec![f32::NAN; cols * rows];
    let mut points = vec![[0.0; 3]; cols * rows];
    let mut reference = vec![0.0f32; offsets.len()];
    let mut scores = vec![0.0f32; d];
    let mut per_nbr = vec![0.0f32; nbrs.len()];
    for gy in 0..rows {
        for gx in 0..cols {
            let (px, py) = (gx * stride + stride / 2, gy * stride + stride / 2);
            if mask.is_some_and(|m| (m[py * g.w + px] > 0.5) != keep_masked) {
                continue;
            }
            let (u, v) = (px as f32 + 0.5, py as f32 + 0.5);
            // The reference patch, normalised.
            let mut ok = true;
            for (r, &(a, b)) in reference.iter_mut().zip(&offsets) {
                match g.bilinear(u + a, v + b) {
                    Some(x) => *r = x,
                    None => ok = false,
                }
            }
            if !ok {
                continue;
            }
            let mean = reference.iter().sum::<f32>() / n;
            let sd = (reference.iter().map(|x| (x - mean) * (x - mean)).sum::<f32>() / n).sqrt();
            if sd < cfg.min_contrast {
                continue;
            }
            for r in reference.iter_mut() {
                *r = (*r - mean) / sd;
            }
            let dir = cam.ray_dir(u, v);
            let Some((near, far)) = sphere_span(cam.centre, dir) else {
                continue;
            };
            let step = (far - near) / d as f32;
            let cos_axis = dot(dir, axis_z);
            for (k, score) in scores.iter_mut().enumerate() {
                let t = near + (k as f32 + 0.5) * step;
                let p: [f32; 3] = std::array::from_fn(|c| cam.centre[c] + t * dir[c]);
                // One patch sample to the next, in the world, on the plane parallel to the image at this depth.
                let z = t * cos_axis;
                let (sx, sy) = (z / cam.fx, z / cam.fy);
                let px_: [f32; 3] = std::array::from_fn(|c| p[c] + sx * ax[c]);
                let py_: [f32; 3] = std::array::from_fn(|c| p[c] + sy * ay[c]);
                for (slot, &j) in per_nbr.iter_mut().zip(nbrs) {
                    *slot = ncc(&cams[j], &greys[j], p, px_, py_, &offsets, &reference);
                }
                // The best two (an occluded neighbour does not veto).
                let (mut b1, mut b2) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
                for &s in per_nbr.iter() {
                    if s > b1 {
                        b2 = b1;
                        b1 = s;
                    } else if s > b2 {
                        b2 = s;
                    }
                }
                *score = 0.5 * (b1 + b2);
            }
            let (best, &top) = scores
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .expect("at least three hypotheses");
            if !(top >= cfg.min_ncc) || best == 0 || best + 1 == d {
                continue;
            }
            let (l, r) = (scores[best - 1], scores[best + 1]);
            let curve = l - 2.0 * top + r;
            let shift = if curve < 0.0 {
                (0.5 * (l - r) / curve).clamp(-0.5, 0.5)
            } else {
                0.0
            };
            let t = near + (best as f32 + 0.5 + shift) * step;
            let cell = gy * cols + gx;
            depth[cell] = t * cos_axis;
            points[cell] = std::array::from_fn(|c| cam.centre[c] + t * dir[c]);
        }
    }
    DepthMap {
        cols,
        rows,
        depth,
        points,
    }
}

/// NCC of the normalised reference patch with the neighbour's image at the patch's points (centre `p`, one
/// sample step along the reference camera's x and y at `px`, `py`), projected through an affine approximation
/// of the plane's homography. −1 when the patch leaves the image or is flat there.
fn ncc(
    cam: &Cam,
    grey: &Grey,
    p: [f32; 3],
    px: [f32; 3],
    py: [f32; 3],
    offsets: &[(f32, f32)],
    reference: &[f32],
) -> f32 {
    let (u0, v0, z0) = cam.project(p);
    if z0 <= 1e-6 {
        return -1.0;
    }
    let (ux, vx, _) = cam.project(px);
    let (uy, vy, _) = cam.project(py);
    let (dux, dvx, duy, dvy) = (ux - u0, vx - v0, uy - u0, vy - v0);
    let mut vals = [0.0f32; 81];
    let vals = &mut vals[..offsets.len().min(81)];
    let mut sum = 0.0;
    for (val, &(a, b)) in vals.iter_mut().zip(offsets) {
        match grey.bilinear(u0 + a * dux + b * duy, v0 + a * dvx + b * dvy) {
            Some(x) => {
                *val = x;
                sum += x;
            }
            None => return -1.0,
        }
    }
    let n = vals.len() as f32;
    let mean = sum / n;
    let (mut cross, mut var) = (0.0, 0.0);
    for (&x, &r) in vals.iter().zip(reference) {
        let c = x - mean;
        cross += c * r;
        var += c * c;
    }
    if var <= 1e-8 {
        return -1.0;
    }
    cross / (var.sqrt() * n.sqrt())
}
