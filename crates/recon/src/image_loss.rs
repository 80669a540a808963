//! The image terms of Eq. 9 for one body in one frame of a fixed camera, and
//! their gradient with respect to the body's pose: the body's field is
//! rendered in its scene (composed over the scene pre-rendered through the
//! same camera) and compared with the frame:
//!
//! - colour L1 inside the body's mask, after a brightness gain that matches the rendered colours to
//!   the frame's (a video under another light or exposure than the static captures;
//!   [`crate::exposure_gain`]),
//! - chromaticity L1 inside the mask (beyond the paper), `|c(r) − c(t)|` with `c(x) = x / (Σx + ε)`:
//!   the colour with the brightness divided out. The object's field holds its appearance as the static captures lit it; in the
//!   video a turned body shows its faces to the light at other angles, and a white light's shading scales
//!   a pixel's channels together (the tabletop drop's tumble: colour L1 0.20–0.25 at the *true* pose against
//!   0.05 in flight, chromaticity 0.006–0.010 against 0.005), so chromaticity follows the body's pattern
//!   where the colours alone point elsewhere,
//! - a two-sided silhouette term, `(o − m)²` between the body's rendered
//!   opacity `o` and the mask `m`: a body spilling out of its mask costs as
//!   much as one that leaves it uncovered (the paper's published code renders
//!   only pixels inside the mask, which lets poses drift toward the camera,
//!   its Fig. 11),
//! - a pull toward the mask, `o · D / D₀` with `D` the pixel's distance to
//!   the mask: a pose that misses most of its mask still gets a gradient from
//!   every pixel it covers, where `(o − m)²` alone only sees its border.
//!
//! With several bodies in the video, the others are drawn too, where they
//! stand ([`Occluder`]): a body in front hides the fitted one as it does in
//! the frame, whose per-body masks are what each body shows.
//!
//! A moving body in a frame with a shutter time is drawn as the mean of its
//! renders over the time the shutter is open ([`crate::shutter`]); the other
//! bodies are drawn at their instant.
//!
//! The pose gradient is on the tangent `(δt, δω)`: world axes, rotation about
//! the body origin (the composed renderer's convention).

use crate::exposure_gain::ExposureGain;
use crate::shutter::{box_corners, shutter_ends, shutter_poses, Motion};
use geom::{silhouette, Camera, Pose, SplitMix64, TriMesh, Vec3};
use neus::compose::{Behind, ComposedRay, Composer, FixedSamples, Layer, PooledComposer, RayGradient};
use neus::ObjectModel;
use serde::{Deserialize, Serialize};
use std::sync::{Mutex, MutexGuard};

/// One frame of a fixed camera: its image and one body's mask.
#[derive(Clone)]
pub struct FrameTarget {
    pub camera: Camera<f64>,
    /// Row-major, `width × height`, linear 0–1 as the renderer outputs.
    pub rgb: Vec<[f32; 3]>,
    pub mask: Vec<bool>,
    /// The brightness of this video relative to the object's captures: the rendered colours are
    /// multiplied by it before they are compared, where the weights do not fit a gain of their own
    /// ([`ImageLossWeights::exposure_gain`]). 1: as captured. `fit` sets it from the first pose.
    pub exposure: f64,
    /// Seconds the shutter was open (0: an instant). A body whose motion is known
    /// ([`PreparedFrame::set_motion`]) is then drawn as the mean over that time ([`crate::shutter`]).
    pub shutter: f64,
    /// The mask was computed from the frame ([`mod@crate::video_masks`]), not drawn: its edge is uncertain by
    /// about a pixel (a body's partial pixels, a blurred edge), so the pixels along it are left to the colour
    /// terms ([`PreparedFrame`]'s edge band).
    pub mask_computed: bool,
}

impl FrameTarget {
    /// The frame with its mask's whole outline in the silhouette terms, computed or not: the search for a
    /// first pose works from the outline (its overlap and its pull), and leaving a computed edge's pixels to
    /// the colours pays only once a pose is near (on the camera-like backdrop's drop the band let the search
    /// end 43 mm off, in a wrong minimum; without it 21 mm, which the first-pose fit then brought to 7 mm).
    pub fn with_whole_outline(&self) -> FrameTarget {
        FrameTarget {
            mask_computed: false,
            ..self.clone()
        }
    }

    /// The mask's centroid in pixel coordinates and its area in pixels (`None` when it is empty).
    pub fn mask_centroid(&self) -> Option<([f64; 2], usize)> {
        let w = self.camera.width as usize;
        let (mut su, mut sv, mut n) = (0.0, 0.0, 0usize);
        for (i, _) in self.mask.iter().enumerate().filter(|(_, &m)| m) {
            su += (i % w) as f64 + 0.5;
            sv += (i / w) as f64 + 0.5;
            n += 1;
        }
        (n > 0).then(|| ([su / n as f64, sv / n as f64], n))
    }

    /// `pose` slid parallel to the image plane, at its depth, until its origin (the body's centre of mass)
    /// projects onto the mask's centroid; unchanged when it already projects within a quarter of the
    /// mask's radius of it, or when the mask is empty. A predicted start that missed the body by more than
    /// its size leaves the silhouette terms nothing to pull on (a toss moves a small object by more than its
    /// width per frame); the centroid is only a guess of where the origin projects, so a close start keeps
    /// its own.
    pub fn centred_on_mask(&self, pose: &Pose<f64>) -> Pose<f64> {
        let Some(([mu, mv], area)) = self.mask_centroid() else {
            return *pose;
        };
        let (u, v, depth) = self.camera.project(pose.t);
        let radius = (area as f64 / std::f64::consts::PI).sqrt();
        if !(depth > 0.0) || (u - mu).hypot(v - mv) <= 0.25 * radius {
            return *pose;
        }
        let ray = self.camera.ray(mu, mv);
        let forward = self.camera.world_to_cam.inverse().q.rotate(Vec3::new(0.0, 0.0, 1.0));
        let along = depth / ray.dir.dot(forward).max(1e-6);
        Pose::new(pose.q, ray.at(along))
    }

    /// `pose` slid along the line of sight through its origin to the depth where `mesh` (the body's shape)
    /// covers as many pixels as the mask: a silhouette's area falls with its depth squared, and the depth
    /// is what one view tells least. `None` where the two areas already agree within `tolerance` (a share
    /// of the mask's), or either is empty. A body partly hidden by the scene has a smaller mask than its
    /// silhouette: this start is then too far, and is one guess among others.
    pub fn sized_to_mask(&self, mesh: &TriMesh, pose: &Pose<f64>, tolerance: f64) -> Option<Pose<f64>> {
        let scale = self.depth_scale_to_mask(mesh, pose)?;
        if (scale * scale - 1.0).abs() <= tolerance {
            return None;
        }
        let eye = self.camera.center();
        Some(Pose::new(pose.q, eye + (pose.t - eye) * scale))
    }

    /// The factor on `pose`'s distance from the camera that gives `mesh`'s silhouette the mask's area: the
    /// square root of their areas' ratio (area falls with depth squared). `None` when either is empty.
    pub fn depth_scale_to_mask(&self, mesh: &TriMesh, pose: &Pose<f64>) -> Option<f64> {
        let area = self.mask.iter().filter(|&&m| m).count();
        let covered = silhouette(&self.camera, mesh, pose).iter().filter(|&&c| c).count();
        (area > 0 && covered > 0).then(|| (covered as f64 / area as f64).sqrt())
    }
}

/// How the image terms are weighed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImageLossWeights {
    /// Colour L1 inside the mask. Default 1.
    pub colour: f64,
    /// Compare the colours after the brightness gain that maps the rendered ones onto the frame's, fitted
    /// at every evaluation ([`crate::exposure_gain`]), instead of the frame's own `exposure`: a video
    /// under another light or exposure than the static captures shows the same texture brighter or
    /// darker, and the raw L1 then hardly tells a body from its half-turn. The first-pose search fits it
    /// for each candidate; `fit` then measures it at the first pose and keeps it for the whole video.
    /// Refitted at every step of a fit it costs accuracy: it takes the brightness out of the colour
    /// term's pull (the PA test: v0 7.0 % off against 3.7 %; the CLI's tossed ball refined from its
    /// guess: 5.3 mm in its last frame against 2.8). Default false; true in the search's refinement
    /// ([`crate::FirstPoseSearchConfig`]).
    pub exposure_gain: bool,
    /// Chromaticity L1 inside the mask (the colour with the brightness divided out, so that shading
    /// changes as the body turns under the light cost little: only the floor of the division keeps a
    /// pixel at half the brightness from costing nothing). Its values are about a tenth of the
    /// colour's. Default 0 (GA, which follows a body through its turns, sets 5).
    pub chromaticity: f64,
    /// The two-sided silhouette term. Default 1.
    pub silhouette: f64,
    /// The pull toward the mask. Default 1.
    pub pull: f64,
    /// Pixels at this distance from the mask cost as much in the pull as a silhouette miss. Default 10.
    pub pull_scale_px: f64,
    /// Pixels around the mask and the body's projection that are rendered. Default 12.
    pub margin_px: u32,
    /// Samples along each ray through the body, as a multiple of its field's training (steps and cap; the
    /// renderer's own default for pictures is 2). Default 2.
    pub ray_steps: f64,
}

impl Default for ImageLossWeights {
    fn default() -> Self {
        Self {
            colour: 1.0,
            exposure_gain: false,
            chromaticity: 0.0,
            silhouette: 1.0,
            pull: 1.0,
            pull_scale_px: 10.0,
            margin_px: 12,
            ray_steps: 2.0,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FrameError {
    #[error("the image has {got} pixels, its camera {want}")]
    ImageSize { got: usize, want: usize },
    #[error("the mask has {got} pixels, the camera {want}")]
    MaskSize { got: usize, want: usize },
    #[error("the pre-rendered scene has {got} pixels, the camera {want}")]
    SceneSize { got: usize, want: usize },
}

/// The image terms measured on some pixels.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ImageLoss {
    /// The weighted sum (per rendered pixel).
    pub loss: f64,
    pub colour_l1: f64,
    pub chromaticity_l1: f64,
    pub silhouette: f64,
    pub pull: f64,
    /// Mean squared colour error (over channels and pixels, 0–1 values): the PSNR of the rendered pixels.
    pub mse: f64,
    /// Pixels where the body's opacity is above ½ and the mask is set, and where either is.
    pub intersection: usize,
    pub union: usize,
    pub pixels: usize,
    /// The rendered and the frame's colours summed over the pixels inside the mask (every channel): their
    /// ratio is the video's brightness over all the pixels measured ([`Self::measured_exposure`]).
    pub colour_sums: [f64; 2],
}

impl ImageLoss {
    /// Silhouette IoU (0 when neither the body nor the mask shows).
    pub fn iou(&self) -> f64 {
        if self.union == 0 {
            0.0
        } else {
            self.intersection as f64 / self.union as f64
        }
    }

    /// PSNR of the rendered pixels against the frame, dB (capped at 100).
    pub fn psnr(&self) -> f64 {
        (-10.0 * self.mse.max(1e-10).log10()).min(100.0)
    }

    /// The frame's brightness relative to the rendering over every pixel measured inside the mask (the
    /// gain [`ImageLossWeights::exposure_gain`] fits; 1 where nothing was rendered there).
    pub fn measured_exposure(&self) -> f64 {
        let [rendered, frame] = self.colour_sums;
        ExposureGain::of_sums(rendered, frame, self.pixels).gain
    }

    /// Pixel-weighted sum of two measurements.
    pub fn add(&mut self, o: &ImageLoss) {
        let (a, b) = (self.pixels as f64, o.pixels as f64);
        let n = (a + b).max(1.0);
        let mix = |x: f64, y: f64| (x * a + y * b) / n;
        self.loss = mix(self.loss, o.loss);
        self.colour_l1 = mix(self.colour_l1, o.colour_l1);
        self.chromaticity_l1 = mix(self.chromaticity_l1, o.chromaticity_l1);
        self.silhouette = mix(self.silhouette, o.silhouette);
        self.pull = mix(self.pull, o.pull);
        self.mse = mix(self.mse, o.mse);
        self.colour_sums = [0, 1].map(|k| self.colour_sums[k] + o.colour_sums[k]);
        self.intersection += o.intersection;
        self.union += o.union;
        self.pixels += o.pixels;
    }
}

/// Another body in the frame, drawn at its pose (not fitted here): it hides what it stands in front of.
#[derive(Clone, Copy)]
pub struct Occluder<'a> {
    pub object: &'a ObjectModel,
    pub pose: Pose<f64>,
}

/// A frame ready for the loss: its mask's distance transform and box, and the other bodies in it.
pub struct PreparedFrame<'a> {
    pub frame: &'a FrameTarget,
    occluders: Vec<Occluder<'a>>,
    /// What the other bodies put along each pixel's ray, rendered the first time the pixel is: they stand
    /// still while this body is fitted, and a fit draws the same pixels of its window again and again (80
    /// steps of 1,024 of a few thousand), so drawing them once per pixel gives the same images for a
    /// fraction of the work.
    occluded: Mutex<OccluderSamples>,
    /// Pixels from the mask (Euclidean, by a two-pass chamfer transform).
    mask_distance: Vec<f32>,
    /// `[x0, y0, x1, y1]` of the mask, or `None` when it is empty (the body is out of view or hidden).
    mask_box: Option<[u32; 4]>,
    /// The fitted body's velocity at the frame's instant, for the frame's shutter time ([`Self::set_motion`]).
    motion: Option<Motion>,
    /// Pixels on a computed mask's edge (either side): compared by colour, not by the silhouette terms.
    edge_band: Vec<bool>,
}

impl<'a> PreparedFrame<'a> {
    /// Checks the sizes of `frame` (and of `scene`, the scene pre-rendered through its camera).
    pub fn new(frame: &'a FrameTarget, scene: &[ComposedRay]) -> Result<Self, FrameError> {
        let (w, h) = (frame.camera.width, frame.camera.height);
        let n = (w * h) as usize;
        if frame.rgb.len() != n {
            return Err(FrameError::ImageSize {
                got: frame.rgb.len(),
                want: n,
            });
        }
        if frame.mask.len() != n {
            return Err(FrameError::MaskSize {
                got: frame.mask.len(),
                want: n,
            });
        }
        if scene.len() != n {
            return Err(FrameError::SceneSize {
                got: scene.len(),
                want: n,
            });
        }
        Ok(Self {
            frame,
            occluders: Vec::new(),
            occluded: Mutex::default(),
            mask_distance: distance_to_mask(&frame.mask, w, h),
            mask_box: bounding_box(&frame.mask, w),
            motion: None,
            edge_band: if frame.mask_computed {
                edge_band(&frame.mask, w as usize)
            } else {
                Vec::new()
            },
        })
    }

    /// The fitted body's velocity at the frame's instant (`None`: unknown, drawn at its instant). With the
    /// frame's shutter time the body is drawn over it; the velocity is held while the pose moves.
    pub fn set_motion(&mut self, motion: Option<Motion>) {
        self.motion = motion;
    }

    /// The other bodies of the frame, drawn where they stand.
    pub fn set_occluders(&mut self, occluders: Vec<Occluder<'a>>) {
        self.occluders = occluders;
        *self.occluded.get_mut().unwrap_or_else(|e| e.into_inner()) = OccluderSamples::default();
    }

    /// The cache with the other bodies' samples along the rays of `pixels` (`origins`, `dirs`) gathered in its
    /// `gathered`; the pixels not drawn yet are drawn first (through `composer`).
    fn occluder_samples(
        &self,
        composer: &mut Composer,
        pixels: &[usize],
        origins: &[Vec3<f64>],
        dirs: &[Vec3<f64>],
        weights: &ImageLossWeights,
    ) -> MutexGuard<'_, OccluderSamples> {
        // Held while the missing pixels are drawn (in parallel, on rayon): a frame belongs to one fit, so no
        // task of that drawing waits for this lock.
        let mut cache = self.occluded.lock().unwrap_or_else(|e| e.into_inner());
        let n = self.frame.rgb.len();
        if cache.slot.len() != n || cache.ray_steps != weights.ray_steps {
            *cache = OccluderSamples {
                ray_steps: weights.ray_steps,
                slot: vec![u32::MAX; n],
                ..OccluderSamples::default()
            };
        }
        let mut missing: Vec<usize> = (0..pixels.len())
            .filter(|&j| cache.slot[pixels[j]] == u32::MAX)
            .collect();
        missing.sort_by_key(|&j| pixels[j]);
        missing.dedup_by_key(|j| pixels[*j]);
        if !missing.is_empty() {
            let cam = &self.frame.camera;
            let layers: Vec<Layer> = self
                .occluders
                .iter()
                .enumerate()
                .map(|(i, o)| body_layer(o.object, &o.pose, 1 + i, cam, weights))
                .collect();
            let o: Vec<Vec3<f64>> = missing.iter().map(|&j| origins[j]).collect();
            let d: Vec<Vec3<f64>> = missing.iter().map(|&j| dirs[j]).collect();
            composer.forward(&layers, 1 + layers.len(), Behind::Colour([0.0; 3]), &o, &d);
            let drawn = composer.samples_as_fixed(&layers);
            for (r, &j) in missing.iter().enumerate() {
                cache.slot[pixels[j]] = cache.samples.rays() as u32;
                cache.samples.push_ray_of(&drawn, r);
            }
        }
        let OccluderSamples {
            slot,
            samples,
            gathered,
            ..
        } = &mut *cache;
        gathered.clear();
        for &p in pixels {
            gathered.push_ray_of(samples, slot[p] as usize);
        }
        cache
    }

    /// Whether the mask shows the body at all.
    pub fn has_mask(&self) -> bool {
        self.mask_box.is_some()
    }

    /// The pixels worth rendering, `[x0, y0, x1, y1]` (inclusive): the mask's box and the body's projected
    /// box at `pose` (over the shutter time where it moves), grown by `margin` pixels; `None` when neither is
    /// in the image.
    pub fn window(&self, object: &ObjectModel, pose: &Pose<f64>, margin: u32) -> Option<[u32; 4]> {
        let cam = &self.frame.camera;
        let (w, h) = (cam.width as f64, cam.height as f64);
        let mut b: Option<[f64; 4]> = self.mask_box.map(|b| b.map(|v| v as f64));
        let corners = box_corners(object.mesh_bounds);
        for (pose, c) in shutter_ends(pose, self.motion.as_ref(), self.frame.shutter)
            .iter()
            .flat_map(|p| corners.iter().map(move |&c| (p, c)))
        {
            let (u, v, z) = cam.project(pose.transform_point(c));
            if z > 0.0 {
                b = Some(match b {
                    None => [u, v, u, v],
                    Some(b) => [b[0].min(u), b[1].min(v), b[2].max(u), b[3].max(v)],
                });
            }
        }
        let m = margin as f64;
        let [x0, y0, x1, y1] = b?;
        if x1 + m < 0.0 || y1 + m < 0.0 || x0 - m > w - 1.0 || y0 - m > h - 1.0 {
            return None;
        }
        Some([
            (x0 - m).clamp(0.0, w - 1.0) as u32,
            (y0 - m).clamp(0.0, h - 1.0) as u32,
            (x1 + m).clamp(0.0, w - 1.0) as u32,
            (y1 + m).clamp(0.0, h - 1.0) as u32,
        ])
    }

    /// `count` random pixels of `window` (with repeats), or all of it when `count` is 0.
    pub fn pixels(&self, window: [u32; 4], count: usize, rng: &mut SplitMix64) -> Vec<usize> {
        let [x0, y0, x1, y1] = window;
        let w = self.frame.camera.width as usize;
        let (bw, bh) = ((x1 - x0 + 1) as usize, (y1 - y0 + 1) as usize);
        let at = |i: usize| (y0 as usize + i / bw) * w + x0 as usize + i % bw;
        if count == 0 {
            return (0..bw * bh).map(at).collect();
        }
        (0..count)
            .map(|_| at((rng.next_f64() * (bw * bh) as f64) as usize % (bw * bh)))
            .collect()
    }

    /// The image terms on `pixels` with the body at `pose`, and with `grad` their pose gradient
    /// `[dL/dδt, dL/dδω]` (of the per-pixel mean). `scene`: the scene pre-rendered through the camera. A
    /// moving body in a frame with a shutter time is drawn at its sub-poses, each through its own composer
    /// (`composer` and others from the pool), and their colours and opacities averaged.
    #[allow(clippy::too_many_arguments)]
    pub fn loss(
        &self,
        composer: &mut Composer,
        object: &ObjectModel,
        scene: &[ComposedRay],
        pose: &Pose<f64>,
        pixels: &[usize],
        weights: &ImageLossWeights,
        grad: bool,
    ) -> (ImageLoss, [f64; 6]) {
        let cam = &self.frame.camera;
        let w = cam.width as usize;
        // The fitted body is object 0; the others follow it, drawn from the cache.
        let subs = shutter_poses(pose, self.motion.as_ref(), self.frame.shutter, cam, object.mesh_bounds);
        let layers: Vec<[Layer; 1]> = subs
            .iter()
            .map(|s| [body_layer(object, &s.pose, 0, cam, weights)])
            .collect();
        let objects = 1 + self.occluders.len();
        let (mut o, mut d, mut under) = (Vec::new(), Vec::new(), Vec::new());
        for &p in pixels {
            let r = cam.ray((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
            o.push(r.origin);
            d.push(r.dir);
            under.push(scene[p].clone());
        }
        let others = (!self.occluders.is_empty()).then(|| self.occluder_samples(composer, pixels, &o, &d, weights));
        let fixed = others.as_ref().map(|cache| &cache.gathered);
        let mut pooled: Vec<PooledComposer> = (1..subs.len()).map(|_| PooledComposer::take()).collect();
        let mut composers: Vec<&mut Composer> = std::iter::once(composer)
            .chain(pooled.iter_mut().map(|c| &mut **c))
            .collect();
        for (c, layers) in composers.iter_mut().zip(&layers) {
            c.forward_over(layers, objects, Behind::Scene(&under), &o, &d, fixed);
        }
        drop(others);
        // The frame's colours and the body's opacity: the mean over the shutter's sub-poses.
        let share = 1.0 / subs.len() as f32;
        let (rendered_rgb, opacity): (Vec<[f32; 3]>, Vec<f32>) = (0..pixels.len())
            .map(|j| {
                composers.iter().fold(([0.0f32; 3], 0.0f32), |(rgb, op), c| {
                    let r = c.out[j].rgb;
                    (
                        [0, 1, 2].map(|k| rgb[k] + share * r[k]),
                        op + share * c.object_opacity[j * objects],
                    )
                })
            })
            .unzip();
        let n = pixels.len().max(1) as f64;
        let mut out = ImageLoss {
            pixels: pixels.len(),
            ..ImageLoss::default()
        };
        // The colour L1 over the pixels inside the mask (and on a computed mask's uncertain edge, where the
        // composed colour decides), after the brightness gain (fitted, or the frame's).
        let on_edge = |p: usize| self.edge_band.get(p).copied().unwrap_or(false);
        let in_mask: Vec<usize> = (0..pixels.len())
            .filter(|&j| self.frame.mask[pixels[j]] || on_edge(pixels[j]))
            .collect();
        let rendered_in: Vec<[f64; 3]> = in_mask.iter().map(|&j| rendered_rgb[j].map(f64::from)).collect();
        let target_in: Vec<[f64; 3]> = in_mask
            .iter()
            .map(|&j| self.frame.rgb[pixels[j]].map(f64::from))
            .collect();
        let gain = if weights.exposure_gain {
            ExposureGain::fit(&rendered_in, &target_in)
        } else {
            ExposureGain::fixed(self.frame.exposure)
        };
        out.colour_sums = [&rendered_in, &target_in].map(|c| c.iter().flatten().sum());
        let (colour_sum, colour_grad) = gain.l1_with_gradient(&rendered_in, &target_in);
        out.colour_l1 = colour_sum;
        let mut colour_grad_of = vec![[0.0f64; 3]; pixels.len()];
        for (&j, g) in in_mask.iter().zip(&colour_grad) {
            colour_grad_of[j] = *g;
        }
        let mut grads = Vec::with_capacity(if grad { pixels.len() } else { 0 });
        for (j, &p) in pixels.iter().enumerate() {
            let rendered_rgb = rendered_rgb[j];
            let op = opacity[j] as f64;
            let inside = self.frame.mask[p];
            let edge = on_edge(p);
            let m = if inside { 1.0 } else { 0.0 };
            let dist = self.mask_distance[p] as f64 / weights.pull_scale_px;
            let mut g_rgb = [0.0f32; 3];
            for k in 0..3 {
                let e = (rendered_rgb[k] - self.frame.rgb[p][k]) as f64;
                out.mse += e * e / 3.0;
            }
            if inside || edge {
                for k in 0..3 {
                    g_rgb[k] = (weights.colour * colour_grad_of[j][k] / n) as f32;
                }
                let (c, dc) = chromaticity_l1(rendered_rgb.map(f64::from), self.frame.rgb[p].map(f64::from));
                out.chromaticity_l1 += c;
                for (g, d) in g_rgb.iter_mut().zip(dc) {
                    *g += (weights.chromaticity * d / n) as f32;
                }
            }
            // The silhouette terms leave a computed mask's edge to the colours.
            let shape = if edge { 0.0 } else { 1.0 };
            out.silhouette += shape * (op - m) * (op - m);
            out.pull += op * dist;
            out.intersection += (op > 0.5 && inside) as usize;
            out.union += (op > 0.5 || inside) as usize;
            if grad {
                // Each sub-pose's render enters the mean with its share.
                let g_op = (weights.silhouette * shape * 2.0 * (op - m) + weights.pull * dist) / n;
                grads.push(RayGradient {
                    rgb: g_rgb.map(|g| g * share),
                    depth: 0.0,
                    object_opacity: vec![g_op as f32 * share],
                });
            }
        }
        out.colour_l1 /= n;
        out.chromaticity_l1 /= n;
        out.silhouette /= n;
        out.pull /= n;
        out.mse /= n;
        out.loss = weights.colour * out.colour_l1
            + weights.chromaticity * out.chromaticity_l1
            + weights.silhouette * out.silhouette
            + weights.pull * out.pull;
        let mut g = [0.0; 6];
        if grad {
            // The fitted body's gradient alone: the others stand still here. Each sub-pose's pulled back to
            // the frame's pose.
            for ((c, layers), sub) in composers.iter_mut().zip(&layers).zip(&subs) {
                let gs = sub.to_frame_gradient(c.backward_of(layers, &grads, |object| object == 0)[0]);
                for (a, b) in g.iter_mut().zip(gs) {
                    *a += b;
                }
            }
        }
        (out, g)
    }

    /// The image terms over every pixel of the window at `pose` (in chunks), for reports.
    pub fn evaluate(
        &self,
        composer: &mut Composer,
        object: &ObjectModel,
        scene: &[ComposedRay],
        pose: &Pose<f64>,
        weights: &ImageLossWeights,
    ) -> ImageLoss {
        let mut total = ImageLoss::default();
        let Some(window) = self.window(object, pose, weights.margin_px) else {
            return total;
        };
        let pixels = self.pixels(window, 0, &mut SplitMix64::new(0));
        // Chunks as large as a fit's steps: the composer's buffers grow to the largest batch it renders (a
        // window of 4,096 rays took 1 GB), and they are kept for the fit's steps.
        for chunk in pixels.chunks(EVALUATE_CHUNK) {
            let (l, _) = self.loss(composer, object, scene, pose, chunk, weights, false);
            total.add(&l);
        }
        total
    }
}

/// The other bodies' samples per pixel of a frame ([`PreparedFrame::occluded`]).
#[derive(Default)]
struct OccluderSamples {
    /// The ray steps they were drawn with ([`ImageLossWeights::ray_steps`]).
    ray_steps: f64,
    /// Per pixel: its ray in `samples`, or `u32::MAX` while it is not drawn yet.
    slot: Vec<u32>,
    samples: FixedSamples,
    /// The rays of the last call's pixels, gathered from `samples` (kept: a fit gathers at every step).
    gathered: FixedSamples,
}

/// Body `index` at `pose` as the loss draws it: through the capture that saw it best from `cam`, with the ray
/// steps `weights` ask for.
fn body_layer<'b>(
    object: &'b ObjectModel,
    pose: &Pose<f64>,
    index: usize,
    cam: &Camera<f64>,
    weights: &ImageLossWeights,
) -> Layer<'b> {
    let of = object.route(pose, cam);
    let mut layer = Layer::object(&of.field, &of.capture_from_body, pose, index);
    let trained = &of.field.config;
    let scaled = |n: usize| ((n as f64 * weights.ray_steps).round() as usize).max(1);
    layer.settings.steps_per_ray = scaled(trained.steps_per_ray);
    layer.settings.max_samples_per_ray = scaled(trained.max_samples_per_ray);
    layer
}

/// Rays per chunk of [`PreparedFrame::evaluate`].
const EVALUATE_CHUNK: usize = 512;

/// Added to a pixel's summed channels before dividing: a dark pixel's chromaticity is mostly noise.
const CHROMATICITY_FLOOR: f64 = 0.05;

/// One pixel's chromaticity L1 (the mean over channels of `|c(r) − c(t)|`, `c(x) = x / (Σx + floor)`) of
/// the rendered `r` against the target `t`, and its gradient in `r`.
fn chromaticity_l1(r: [f64; 3], t: [f64; 3]) -> (f64, [f64; 3]) {
    let (sr, st) = (
        r.iter().sum::<f64>() + CHROMATICITY_FLOOR,
        t.iter().sum::<f64>() + CHROMATICITY_FLOOR,
    );
    let e: [f64; 3] = std::array::from_fn(|k| r[k] / sr - t[k] / st);
    let signed_r: f64 = (0..3).map(|k| e[k].signum() * r[k]).sum();
    // d c_k / d r_j = δ_kj / s − r_k / s².
    let grad = std::array::from_fn(|j| (e[j].signum() / sr - signed_r / (sr * sr)) / 3.0);
    (e.iter().map(|v| v.abs()).sum::<f64>() / 3.0, grad)
}

/// `[x0, y0, x1, y1]` (inclusive) of the set pixels, or `None` if there are none.
fn bounding_box(mask: &[bool], width: u32) -> Option<[u32; 4]> {
    let w = width as usize;
    let mut b: Option<[u32; 4]> = None;
    for (p, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = ((p % w) as u32, (p / w) as u32);
        b = Some(match b {
            None => [x, y, x, y],
            Some([a, c, e, f]) => [a.min(x), c.min(y), e.max(x), f.max(y)],
        });
    }
    b
}

/// Each pixel's distance (pixels) to the nearest set pixel of `mask`: a two-pass chamfer transform with
/// steps of 1 and √2 (within 8 % of Euclidean), enough for a pull. Without a set pixel, a large distance.
/// The pixels on `mask`'s edge, either side: those with a 4-neighbour of the other kind.
fn edge_band(mask: &[bool], width: usize) -> Vec<bool> {
    let height = mask.len() / width.max(1);
    (0..mask.len())
        .map(|p| {
            let (x, y) = (p % width, p / width);
            [
                (x > 0).then(|| p - 1),
                (x + 1 < width).then(|| p + 1),
                (y > 0).then(|| p - width),
                (y + 1 < height).then(|| p + width),
            ]
            .into_iter()
            .flatten()
            .any(|q| mask[q] != mask[p])
        })
        .collect()
}

pub(crate) fn distance_to_mask(mask: &[bool], width: u32, height: u32) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    let far = 1e6f32;
    let mut d: Vec<f32> = mask.iter().map(|&m| if m { 0.0 } else { far }).collect();
    let (a, b) = (1.0f32, std::f32::consts::SQRT_2);
    let relax = |d: &mut Vec<f32>, x: usize, y: usize, dx: isize, dy: isize| {
        let (xn, yn) = (x as isize + dx, y as isize + dy);
        if xn >= 0 && yn >= 0 && (xn as usize) < w && (yn as usize) < h {
            let step = if dx != 0 && dy != 0 { b } else { a };
            let v = d[yn as usize * w + xn as usize] + step;
            if v < d[y * w + x] {
                d[y * w + x] = v;
            }
        }
    };
    for y in 0..h {
        for x in 0..w {
            for (dx, dy) in [(-1, 0), (-1, -1), (0, -1), (1, -1)] {
                relax(&mut d, x, y, dx, dy);
            }
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            for (dx, dy) in [(1, 0), (1, 1), (0, 1), (-1, 1)] {
                relax(&mut d, x, y, dx, dy);
            }
        }
    }
    d
}

/// The smallest pixel window `[x0, y0, x1, y1]` holding both.
pub(crate) fn window_union(a: [u32; 4], b: [u32; 4]) -> [u32; 4] {
    [a[0].min(b[0]), a[1].min(b[1]), a[2].max(b[2]), a[3].max(b[3])]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_to_a_single_pixel_is_near_euclidean() {
        let (w, h) = (21u32, 15u32);
        let mut mask = vec![false; (w * h) as usize];
        mask[(7 * w + 10) as usize] = true;
        let d = distance_to_mask(&mask, w, h);
        for y in 0..h {
            for x in 0..w {
                let e = ((x as f32 - 10.0).powi(2) + (y as f32 - 7.0).powi(2)).sqrt();
                let got = d[(y * w + x) as usize];
                assert!((got - e).abs() <= 0.09 * e + 1e-6, "({x},{y}): {got} vs {e}");
            }
        }
        assert_eq!(bounding_box(&mask, w), Some([10, 7, 10, 7]));
        assert_eq!(bounding_box(&[false; 4], 2), None);
    }

    #[test]
    fn the_exposure_is_measured_over_every_chunk_together() {
        // Two chunks of an evaluation: one inside the mask (the frame 0.8 times as bright), one with no
        // pixel inside it. The ratio of the summed colours is the measurement; the empty chunk adds nothing.
        let inside = ImageLoss {
            pixels: 4096,
            colour_sums: [1000.0, 800.0],
            ..ImageLoss::default()
        };
        let outside = ImageLoss {
            pixels: 4096,
            ..ImageLoss::default()
        };
        let mut total = ImageLoss::default();
        total.add(&inside);
        total.add(&outside);
        assert!((total.measured_exposure() - 0.8).abs() < 1e-12, "{total:?}");
        assert_eq!(ImageLoss::default().measured_exposure(), 1.0);
    }

    #[test]
    fn chromaticity_ignores_brightness_and_its_gradient_matches_finite_differences() {
        let t = [0.8, 0.5, 0.1];
        let (same, _) = chromaticity_l1(t.map(|v| 0.5 * v), t);
        // Only the floor keeps a pixel at half the brightness from costing nothing (0.011 here).
        assert!(same < 0.02, "{same}");
        let (bluer, _) = chromaticity_l1([0.4, 0.25, 0.3], t);
        assert!(bluer > 10.0 * same, "{bluer} against {same}");
        let r = [0.3, 0.45, 0.2];
        let (_, g) = chromaticity_l1(r, t);
        let h = 1e-6;
        for j in 0..3 {
            let (mut a, mut b) = (r, r);
            a[j] += h;
            b[j] -= h;
            let fd = (chromaticity_l1(a, t).0 - chromaticity_l1(b, t).0) / (2.0 * h);
            assert!((g[j] - fd).abs() < 1e-6, "channel {j}: {} against {fd}", g[j]);
        }
    }

    #[test]
    fn a_far_start_is_centred_on_the_mask_at_its_depth() {
        let (w, h) = (64u32, 48u32);
        let k = geom::Intrinsics {
            fx: 70.0,
            fy: 70.0,
            cx: 32.0,
            cy: 24.0,
            skew: 0.0,
        };
        let camera = Camera::look_at(
            Vec3::new(0.0, -0.5, 0.3),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            k,
            w,
            h,
        );
        // A disc of radius 4 px around (44.5, 30.5).
        let mask: Vec<bool> = (0..w * h)
            .map(|i| ((i % w) as f64 - 44.0).hypot((i / w) as f64 - 30.0) <= 4.0)
            .collect();
        let frame = FrameTarget {
            camera,
            rgb: vec![[0.0; 3]; (w * h) as usize],
            mask,
            exposure: 1.0,
            shutter: 0.0,
            mask_computed: false,
        };
        let ([mu, mv], area) = frame.mask_centroid().unwrap();
        assert!(
            (mu - 44.5).abs() < 1e-9 && (mv - 30.5).abs() < 1e-9 && area > 40,
            "{mu} {mv} {area}"
        );
        let far = Pose::new(geom::Quat::exp(Vec3::new(0.1, 0.2, 0.3)), Vec3::new(-0.05, 0.02, 0.01));
        let centred = frame.centred_on_mask(&far);
        let (u, v, depth) = camera.project(centred.t);
        assert!((u - mu).abs() < 1e-6 && (v - mv).abs() < 1e-6, "({u}, {v})");
        assert!((depth - camera.project(far.t).2).abs() < 1e-9);
        assert_eq!(centred.q, far.q);
        // A start already over the mask keeps its own guess of where its origin projects.
        let near = Pose::new(far.q, camera.ray(45.0, 31.0).at(0.5));
        assert_eq!(frame.centred_on_mask(&near), near);
        let empty = FrameTarget {
            mask: vec![false; (w * h) as usize],
            ..frame
        };
        assert_eq!(empty.centred_on_mask(&far), far);
    }

    #[test]
    fn a_start_at_the_wrong_depth_is_sized_to_the_mask() {
        let (w, h) = (96u32, 72u32);
        let k = geom::Intrinsics::centred(1.2 * w as f64, w, h);
        let camera = Camera::look_at(
            Vec3::new(0.0, -0.4, 0.3),
            Vec3::new(0.0, 0.0, 0.02),
            Vec3::new(0.0, 0.0, 1.0),
            k,
            w,
            h,
        );
        let mesh = sim::tessellate::cuboid_mesh(
            &sim::sdf::Cuboid {
                half: [0.03, 0.02, 0.015],
            },
            2,
        );
        let truth = Pose::new(geom::Quat::exp(Vec3::new(0.1, 0.2, 0.5)), Vec3::new(0.01, 0.02, 0.03));
        let frame = FrameTarget {
            camera,
            rgb: vec![[0.0; 3]; (w * h) as usize],
            mask: silhouette(&camera, &mesh, &truth),
            exposure: 1.0,
            shutter: 0.0,
            mask_computed: false,
        };
        // 12 % farther along the line of sight: 20 % less area.
        let eye = camera.center();
        let far = Pose::new(truth.q, eye + (truth.t - eye) * 1.12);
        let sized = frame.sized_to_mask(&mesh, &far, 0.05).expect("the areas differ");
        let (d_truth, d_sized) = ((truth.t - eye).norm(), (sized.t - eye).norm());
        // Along the same line of sight, within a pixel's rim of the depth (about 1 %).
        assert!(
            (d_sized / d_truth - 1.0).abs() < 0.015,
            "depth {d_sized} against {d_truth}"
        );
        let unit = |v: Vec3<f64>| v.scale(1.0 / v.norm());
        assert!((unit(sized.t - eye) - unit(truth.t - eye)).norm() < 1e-9);
        assert_eq!(sized.q, truth.q);
        assert!(
            frame.sized_to_mask(&mesh, &truth, 0.05).is_none(),
            "already the mask's size"
        );
    }
}
