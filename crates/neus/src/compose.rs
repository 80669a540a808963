//! Objects in their scene (Eq. 5–7): the scene's field and any number of
//! posed object fields rendered along the same rays. Each field samples the
//! ray in its own unit frame (a ray of the camera moved by the inverse of the
//! object's pose, Eq. 7, and by the capture's normalisation), takes NeuS
//! opacities of its own sections, and all samples of all fields are
//! composited in one depth order with one transmittance (as the paper's
//! reference code merges them). Outputs colour, depth and each object's
//! opacity (its soft silhouette); the backward pass gives, per object, the
//! gradient with respect to its pose through the fields' input-point
//! gradients, the finite-difference normals and the view direction.
//!
//! A fixed camera's fast path: the scene rendered once per pixel
//! ([`prerender_scene`]) stands behind the objects ([`Behind::Scene`]): each
//! object's samples in front of the scene's surface (where the scene's
//! transmittance falls below ½) are composited over the scene's colour and
//! depth, those behind it are occluded, and only pixels whose rays meet an
//! object's occupied cells are traced. Exact where the scene's surface is
//! sharp (a trained scene's is); tested against the reference.
//!
//! Pose tangent: `δ = (δt, δω)`, world axes, perturbing a pose `(R, t)` to
//! `(exp(δω) R, t + δt)` (a rotation about the body's origin, the centre of
//! mass). Gradients are `[dL/dδt, dL/dδω]`.

use crate::background_field::BackgroundScratch;
use crate::checkpoint::LoadedField;
use crate::occupancy::{sample_ray, sphere_span, BatchMarch};
use crate::ray_rounds::RayRounds;
use crate::render_view::RenderSettings;
use crate::volume::{composite_alpha_backward, section_alpha_backward};
use geom::{Camera, Pose, Vec3};
use rayon::prelude::*;

/// One field placed in the world for a render.
pub struct Layer<'a> {
    pub field: &'a LoadedField,
    /// `p_capture = capture_from_world · p_world` (identity for the scene: its capture is the world).
    pub capture_from_world: Pose<f64>,
    /// The object this layer draws (its opacity output and pose gradient); `None` for the scene.
    pub object: Option<usize>,
    /// The object's origin in the world (the centre of rotations of its pose tangent).
    pub pivot: Vec3<f64>,
    pub settings: RenderSettings,
    /// A sphere (unit frame) around every occupied cell: rays that miss it have no samples.
    bound: Option<([f32; 3], f32)>,
}

impl<'a> Layer<'a> {
    /// The static scene: its field in the world frame.
    pub fn scene(field: &'a LoadedField) -> Self {
        Self {
            field,
            capture_from_world: Pose::identity(),
            object: None,
            pivot: Vec3::new(0.0, 0.0, 0.0),
            settings: RenderSettings::of(field),
            bound: field.occupancy.bounding_sphere(),
        }
    }

    /// Object `index`'s field whose capture holds the body at `capture_from_body`, with the body at `pose`.
    pub fn object(field: &'a LoadedField, capture_from_body: &Pose<f64>, pose: &Pose<f64>, index: usize) -> Self {
        Self {
            field,
            capture_from_world: capture_from_body.compose(&pose.inverse()),
            object: Some(index),
            pivot: pose.t,
            settings: RenderSettings::of(field),
            bound: field.occupancy.bounding_sphere(),
        }
    }

    /// A world ray in this layer's unit frame.
    fn ray_to_unit(&self, o: Vec3<f64>, d: Vec3<f64>) -> ([f32; 3], [f32; 3]) {
        let a = &self.capture_from_world;
        let r = self.field.radius;
        let ou = (a.transform_point(o) - self.field.centre) * (1.0 / r);
        let du = a.transform_vector(d);
        (ou.to_array().map(|v| v as f32), du.to_array().map(|v| v as f32))
    }

    /// Whether a ray (unit frame) can meet an occupied cell of this layer's field.
    fn meets_unit(&self, o: [f32; 3], d: [f32; 3]) -> bool {
        let Some((c, r)) = self.bound else { return false };
        let oc = [0, 1, 2].map(|k| (o[k] - c[k]) / r);
        sphere_span(oc, d).is_some()
    }

    /// Whether a world ray can meet an occupied cell of this layer's field.
    pub fn meets(&self, o: Vec3<f64>, d: Vec3<f64>) -> bool {
        let (ou, du) = self.ray_to_unit(o, d);
        self.meets_unit(ou, du)
    }
}

/// What stands behind the layers along each ray.
#[derive(Clone, Copy, Debug)]
pub enum Behind<'a> {
    /// A constant colour (depth and opacity 0). Ignored when a layer is the scene: its background is behind.
    Colour([f32; 3]),
    /// The scene, pre-rendered along the same rays ([`prerender_scene`]; one per ray): objects' samples
    /// beyond its surface are occluded, the rest composited over its colour, depth and opacity.
    Scene(&'a [ComposedRay]),
}

/// What one ray renders to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ComposedRay {
    pub rgb: [f32; 3],
    /// Σ w t, metres along the ray (0 where nothing was hit).
    pub depth: f32,
    /// Σ w over every field's samples.
    pub opacity: f32,
    /// Metres along the ray to the first sample after which the transmittance is below ½ (the surface
    /// seen; infinite where the ray stays mostly clear).
    pub surface: f32,
}

/// What the loss says of one ray: the gradients of its outputs.
#[derive(Clone, Debug, Default)]
pub struct RayGradient {
    pub rgb: [f32; 3],
    pub depth: f32,
    /// One per object (missing entries count as 0).
    pub object_opacity: Vec<f32>,
}

/// Samples of fields rendered earlier and held fixed, per ray: bodies drawn where they stand while another is
/// fitted. [`Composer::forward_over`] merges them with its layers' samples in depth order exactly as if their
/// layers were rendered again, after its own layers (that order breaks ties at equal depths): a field's NeuS
/// opacities along a ray come from its own samples only. Objects only: the scene's layer also gives what
/// stands behind.
#[derive(Clone, Debug)]
pub struct FixedSamples {
    /// Ray `i`'s samples are `offsets[i]..offsets[i + 1]`, front to back.
    offsets: Vec<usize>,
    /// Metres along the ray.
    t: Vec<f32>,
    alpha: Vec<f32>,
    rgb: Vec<[f32; 3]>,
    /// The object each sample belongs to.
    object: Vec<u32>,
}

impl Default for FixedSamples {
    /// No rays.
    fn default() -> Self {
        Self {
            offsets: vec![0],
            t: Vec::new(),
            alpha: Vec::new(),
            rgb: Vec::new(),
            object: Vec::new(),
        }
    }
}

impl FixedSamples {
    /// No rays.
    pub fn clear(&mut self) {
        self.offsets.clear();
        self.offsets.push(0);
        self.t.clear();
        self.alpha.clear();
        self.rgb.clear();
        self.object.clear();
    }

    /// How many rays.
    pub fn rays(&self) -> usize {
        self.offsets.len() - 1
    }

    /// How many samples, over every ray.
    pub fn samples(&self) -> usize {
        self.t.len()
    }

    /// Appends ray `i` of `other`.
    pub fn push_ray_of(&mut self, other: &FixedSamples, i: usize) {
        let r = other.offsets[i]..other.offsets[i + 1];
        self.t.extend_from_slice(&other.t[r.clone()]);
        self.alpha.extend_from_slice(&other.alpha[r.clone()]);
        self.rgb.extend_from_slice(&other.rgb[r.clone()]);
        self.object.extend_from_slice(&other.object[r]);
        self.offsets.push(self.t.len());
    }
}

/// A merged sample's opacity, colour and object: of a layer's samples or of the fixed ones.
fn merged_sample(
    fixed: &FixedSamples,
    states: &[LayerState],
    layers: &[Layer<'_>],
    m: &Merged,
) -> (f32, [f32; 3], Option<usize>) {
    let s = m.sample as usize;
    if m.layer == FIXED {
        return (fixed.alpha[s], fixed.rgb[s], Some(fixed.object[s] as usize));
    }
    let e = &states[m.layer as usize].eval;
    (e.alpha[s], e.rgb[s], layers[m.layer as usize].object)
}

/// [`Merged::layer`] of a fixed sample ([`FixedSamples`]): its `sample` indexes the composer's copy of them.
const FIXED: u32 = u32::MAX;

/// A layer's samples and the buffers of its passes.
#[derive(Default)]
struct LayerState {
    origins: Vec<[f32; 3]>,
    dirs: Vec<[f32; 3]>,
    /// Every sample the marching gives (before early termination).
    all_offsets: Vec<usize>,
    all_t: Vec<f32>,
    all_dt: Vec<f32>,
    march: BatchMarch,
    /// The samples evaluated (`offsets`, `t`, `dt`, `alpha`, …: per ray, front to back).
    eval: RayRounds,
    inv_s: f32,
    d_sdf: Vec<f32>,
    d_cos: Vec<f32>,
    d_rgb: Vec<[f32; 3]>,
    d_point: Vec<[f32; 3]>,
    d_dir: Vec<[f32; 3]>,
}

/// A sample in a ray's merged depth order.
#[derive(Clone, Copy)]
struct Merged {
    t: f32,
    layer: u32,
    sample: u32,
}

/// Composers given back by [`PooledComposer`]s, their buffers kept.
static COMPOSER_POOL: std::sync::Mutex<Vec<Composer>> = std::sync::Mutex::new(Vec::new());
/// At most this many composers wait in the pool: as many as are alive at once — a frame's starts side by side
/// (4), and a blurred frame's extra sub-poses (up to 5, `recon::shutter`). A smaller pool drops a composer and
/// allocates it afresh at every step of a blurred frame.
const COMPOSER_POOL_SIZE: usize = 10;

/// A [`Composer`] lent from a process-wide pool and given back when dropped. For short-lived users such as one
/// frame's pose fit: GA fits every frame from several starts for a few dozen steps each, and a new composer
/// allocates and page-faults its buffers afresh (hundreds of MB at 256 rays of a few hundred samples), which
/// took a quarter of GA's time.
pub struct PooledComposer(Option<Composer>);

impl PooledComposer {
    /// One from the pool, or a new one if it is empty.
    pub fn take() -> Self {
        let pooled = COMPOSER_POOL.lock().unwrap_or_else(|e| e.into_inner()).pop();
        Self(Some(pooled.unwrap_or_default()))
    }
}

impl std::ops::Deref for PooledComposer {
    type Target = Composer;
    fn deref(&self) -> &Composer {
        self.0.as_ref().expect("held until dropped")
    }
}

impl std::ops::DerefMut for PooledComposer {
    fn deref_mut(&mut self) -> &mut Composer {
        self.0.as_mut().expect("held until dropped")
    }
}

impl Drop for PooledComposer {
    fn drop(&mut self) {
        let mut pool = COMPOSER_POOL.lock().unwrap_or_else(|e| e.into_inner());
        if pool.len() < COMPOSER_POOL_SIZE {
            pool.extend(self.0.take());
        }
    }
}

/// The composed renderer's state: after [`Composer::forward`], the outputs, and what
/// [`Composer::backward`] needs. Reuse one across chunks and frames: its buffers are kept.
#[derive(Default)]
pub struct Composer {
    layers: Vec<LayerState>,
    merged: Vec<Merged>,
    merged_offsets: Vec<usize>,
    background: Vec<[f32; 3]>,
    /// What stands behind, per ray: its depth (weighted by the transmittance left) and opacity.
    behind_depth: Vec<f32>,
    behind_opacity: Vec<f32>,
    behind_surface: Vec<f32>,
    world_o: Vec<Vec3<f64>>,
    world_d: Vec<Vec3<f64>>,
    objects: usize,
    /// One per ray.
    pub out: Vec<ComposedRay>,
    /// `rays × objects`: each object's opacity along each ray.
    pub object_opacity: Vec<f32>,
    trans: Vec<f32>,
    alpha: Vec<f32>,
    d_alpha: Vec<f32>,
    bg: BackgroundScratch,
    /// The last forward's fixed samples (empty: none).
    fixed: FixedSamples,
}

impl Composer {
    /// Render world rays (`dirs` of unit length) through `layers`; `objects` is the number of objects the
    /// layers' indices refer to. Behind everything: the scene's background (its background field or colour)
    /// when a layer is the scene, else `behind`.
    pub fn forward(
        &mut self,
        layers: &[Layer<'_>],
        objects: usize,
        behind: Behind<'_>,
        origins: &[Vec3<f64>],
        dirs: &[Vec3<f64>],
    ) {
        self.forward_over(layers, objects, behind, origins, dirs, None);
    }

    /// [`Self::forward`] with `fixed` samples (one entry per ray) merged in: what other fields, not traced
    /// here, put along the same rays ([`FixedSamples`]). Their objects' opacities are outputs as the layers'
    /// are; the backward pass stops at them.
    pub fn forward_over(
        &mut self,
        layers: &[Layer<'_>],
        objects: usize,
        behind: Behind<'_>,
        origins: &[Vec3<f64>],
        dirs: &[Vec3<f64>],
        fixed: Option<&FixedSamples>,
    ) {
        let n = origins.len();
        self.fixed.clear();
        if let Some(f) = fixed {
            assert_eq!(f.rays(), n, "Composer::forward_over: one fixed entry per ray");
            self.fixed.clone_from(f);
        }
        let scene_layer = layers.iter().position(|l| l.object.is_none());
        if let Behind::Scene(s) = behind {
            assert!(
                scene_layer.is_none(),
                "Composer::forward: a scene layer and a pre-rendered scene"
            );
            assert_eq!(s.len(), n, "Composer::forward: one pre-rendered scene pixel per ray");
        }
        self.objects = objects;
        self.world_o.clear();
        self.world_o.extend_from_slice(origins);
        self.world_d.clear();
        self.world_d.extend_from_slice(dirs);
        self.layers.resize_with(layers.len(), LayerState::default);
        for (layer, st) in layers.iter().zip(&mut self.layers) {
            st.origins.clear();
            st.dirs.clear();
            st.all_offsets.clear();
            st.all_offsets.push(0);
            st.all_t.clear();
            st.all_dt.clear();
            let march = layer.settings.marching();
            for (o, d) in origins.iter().zip(dirs) {
                let (ou, du) = layer.ray_to_unit(*o, *d);
                st.origins.push(ou);
                st.dirs.push(du);
            }
            let (os, ds) = (&st.origins, &st.dirs);
            st.march.run(
                os.len(),
                |i, t, dt| {
                    if layer.meets_unit(os[i], ds[i]) {
                        sample_ray(&layer.field.occupancy, os[i], ds[i], march, 0.5, t, dt);
                    }
                },
                &mut st.all_offsets,
                &mut st.all_t,
                &mut st.all_dt,
            );
            let f = &layer.field.field;
            st.inv_s = f.inv_s();
            st.eval.forward(
                f,
                layer.field.baked(),
                &st.origins,
                &st.dirs,
                &st.all_offsets,
                &st.all_t,
                &st.all_dt,
                layer.settings.pass(),
                layer.settings.stop_transmittance,
            );
        }
        // Behind everything.
        self.background.clear();
        self.behind_depth.clear();
        self.behind_opacity.clear();
        self.behind_surface.clear();
        match (scene_layer, behind) {
            (Some(i), _) => {
                let st = &self.layers[i];
                layers[i]
                    .field
                    .field
                    .colour_behind(&st.origins, &st.dirs, |_| 0.5, &mut self.bg);
                self.background.extend_from_slice(&self.bg.out);
            }
            (None, Behind::Colour(c)) => self.background.resize(n, c),
            (None, Behind::Scene(s)) => {
                self.background.extend(s.iter().map(|p| p.rgb));
                self.behind_depth.extend(s.iter().map(|p| p.depth));
                self.behind_opacity.extend(s.iter().map(|p| p.opacity));
                self.behind_surface.extend(s.iter().map(|p| p.surface));
            }
        }
        self.behind_depth.resize(n, 0.0);
        self.behind_opacity.resize(n, 0.0);
        self.behind_surface.resize(n, f32::INFINITY);
        // Every field's samples in one depth order (metres along the world ray).
        self.merged.clear();
        self.merged_offsets.clear();
        self.merged_offsets.push(0);
        for i in 0..n {
            let start = self.merged.len();
            // Samples behind a pre-rendered scene's surface are hidden by it.
            let cut = self.behind_surface[i];
            for (li, (layer, st)) in layers.iter().zip(&self.layers).enumerate() {
                let r = layer.field.radius as f32;
                for s in st.eval.offsets[i]..st.eval.offsets[i + 1] {
                    if st.eval.t[s] * r > cut {
                        continue;
                    }
                    self.merged.push(Merged {
                        t: st.eval.t[s] * r,
                        layer: li as u32,
                        sample: s as u32,
                    });
                }
            }
            // After the layers' samples, in their own depth order: the stable sort then breaks ties as it
            // would have with their layers after these.
            if self.fixed.rays() == n {
                for s in self.fixed.offsets[i]..self.fixed.offsets[i + 1] {
                    if self.fixed.t[s] > cut {
                        continue;
                    }
                    self.merged.push(Merged {
                        t: self.fixed.t[s],
                        layer: FIXED,
                        sample: s as u32,
                    });
                }
            }
            self.merged[start..].sort_by(|a, b| a.t.total_cmp(&b.t));
            self.merged_offsets.push(self.merged.len());
        }
        self.out.clear();
        self.object_opacity.clear();
        self.object_opacity.resize(n * objects, 0.0);
        // Accumulated in f64: a depth is a sum of hundreds of samples' w·t, and its rounding would swamp
        // the small changes a pose gradient is about.
        let mut per_object = vec![0.0f64; objects];
        for i in 0..n {
            let (mut rgb, mut depth, mut opacity) = ([0.0f64; 3], 0.0f64, 0.0f64);
            per_object.iter_mut().for_each(|v| *v = 0.0);
            let mut trans = 1.0f64;
            let mut surface = f32::INFINITY;
            for m in &self.merged[self.merged_offsets[i]..self.merged_offsets[i + 1]] {
                let (a, c, obj) = self.sample_of(layers, m);
                let a = a as f64;
                let w = trans * a;
                for k in 0..3 {
                    rgb[k] += w * c[k] as f64;
                }
                depth += w * m.t as f64;
                opacity += w;
                if let Some(obj) = obj {
                    per_object[obj] += w;
                }
                trans *= 1.0 - a;
                if trans < 0.5 && surface.is_infinite() {
                    surface = m.t;
                }
            }
            for k in 0..3 {
                rgb[k] += trans * self.background[i][k] as f64;
            }
            depth += trans * self.behind_depth[i] as f64;
            opacity += trans * self.behind_opacity[i] as f64;
            if surface.is_infinite() {
                surface = self.behind_surface[i];
            }
            for (obj, v) in per_object.iter().enumerate() {
                self.object_opacity[i * objects + obj] = *v as f32;
            }
            self.out.push(ComposedRay {
                rgb: rgb.map(|v| v as f32),
                depth: depth as f32,
                opacity: opacity as f32,
                surface,
            });
        }
    }

    /// A merged sample's opacity, colour and object.
    fn sample_of(&self, layers: &[Layer<'_>], m: &Merged) -> (f32, [f32; 3], Option<usize>) {
        merged_sample(&self.fixed, &self.layers, layers, m)
    }

    /// Every sample of the last forward, per ray in depth order, as [`FixedSamples`] (those behind a
    /// pre-rendered scene's surface left out): the fields of this render held fixed for later ones.
    pub fn samples_as_fixed(&self, layers: &[Layer<'_>]) -> FixedSamples {
        assert!(
            layers.iter().all(|l| l.object.is_some()),
            "Composer::samples_as_fixed: objects only (the scene's layer gives what stands behind too)"
        );
        let mut out = FixedSamples::default();
        for i in 0..self.out.len() {
            for m in &self.merged[self.merged_offsets[i]..self.merged_offsets[i + 1]] {
                let (a, c, obj) = self.sample_of(layers, m);
                out.t.push(m.t);
                out.alpha.push(a);
                out.rgb.push(c);
                out.object.push(obj.expect("objects only") as u32);
            }
            out.offsets.push(out.t.len());
        }
        out
    }

    /// How many samples the last [`Self::forward`] evaluated, over all layers.
    pub fn evaluated_samples(&self) -> usize {
        self.layers.iter().map(|l| l.eval.t.len()).sum()
    }

    /// The gradient with respect to each object's pose (`[dL/dδt, dL/dδω]`, module docs) of the loss whose
    /// gradients with respect to the last [`Self::forward`]'s outputs are `grads` (one per ray). `layers`
    /// must be the forward's.
    pub fn backward(&mut self, layers: &[Layer<'_>], grads: &[RayGradient]) -> Vec<[f64; 6]> {
        self.backward_of(layers, grads, |_| true)
    }

    /// [`Self::backward`] for the objects `wanted` says yes to; the others' entries are zero. Bodies drawn
    /// only to hide what they stand in front of (another body fitted in a frame) are not traced back
    /// through their fields: that is as much work as their forward pass, and nothing uses it.
    pub fn backward_of(
        &mut self,
        layers: &[Layer<'_>],
        grads: &[RayGradient],
        wanted: impl Fn(usize) -> bool,
    ) -> Vec<[f64; 6]> {
        let traced = |layer: &Layer<'_>| layer.object.is_some_and(&wanted);
        let n = self.out.len();
        assert_eq!(grads.len(), n, "Composer::backward: one gradient per ray");
        for st in &mut self.layers {
            let m = st.eval.t.len();
            st.d_sdf.clear();
            st.d_sdf.resize(m, 0.0);
            st.d_cos.clear();
            st.d_cos.resize(m, 0.0);
            st.d_rgb.clear();
            st.d_rgb.resize(m, [0.0; 3]);
        }
        // Through the compositing to each sample's opacity and colour.
        for (i, g) in grads.iter().enumerate() {
            let merged = &self.merged[self.merged_offsets[i]..self.merged_offsets[i + 1]];
            let k = merged.len();
            let (fixed, states) = (&self.fixed, &self.layers);
            self.alpha.clear();
            self.alpha
                .extend(merged.iter().map(|m| merged_sample(fixed, states, layers, m).0));
            self.trans.resize(k, 0.0);
            self.d_alpha.resize(k, 0.0);
            let dot = |c: [f32; 3]| c[0] * g.rgb[0] + c[1] * g.rgb[1] + c[2] * g.rgb[2];
            let v = |j: usize| {
                let m = &merged[j];
                let (_, c, obj) = merged_sample(fixed, states, layers, m);
                let op = obj.and_then(|o| g.object_opacity.get(o).copied()).unwrap_or(0.0);
                dot(c) + m.t * g.depth + op
            };
            composite_alpha_backward(
                &self.alpha,
                v,
                dot(self.background[i]) + self.behind_depth[i] * g.depth,
                &mut self.trans,
                &mut self.d_alpha,
            );
            for (j, m) in merged.iter().enumerate() {
                if m.layer == FIXED || !traced(&layers[m.layer as usize]) {
                    continue; // the scene is fixed, and so are bodies not wanted
                }
                let st = &mut self.layers[m.layer as usize];
                let s = m.sample as usize;
                let w = self.trans[j] * self.alpha[j];
                st.d_rgb[s] = g.rgb.map(|d| w * d);
                let e = &st.eval;
                let (ds, dc, _) = section_alpha_backward(e.sdf[s], e.cos[s], e.dt[s], st.inv_s, 1.0, self.d_alpha[j]);
                st.d_sdf[s] = ds;
                st.d_cos[s] = dc;
            }
        }
        // Through each object's field to its samples' points and directions, then to its pose.
        let mut out = vec![[0.0f64; 6]; self.objects];
        for (layer, st) in layers.iter().zip(&mut self.layers) {
            let Some(obj) = layer.object.filter(|_| traced(layer)) else {
                continue;
            };
            let m = st.eval.t.len();
            if m == 0 {
                continue;
            }
            st.d_point.resize(m, [0.0; 3]);
            st.d_dir.resize(m, [0.0; 3]);
            st.eval.backward_inputs(
                &layer.field.field,
                layer.field.baked(),
                &st.d_sdf,
                &st.d_cos,
                &st.d_rgb,
                &mut st.d_point,
                &mut st.d_dir,
            );
            let a = &layer.capture_from_world;
            let r = layer.field.radius;
            let (mut gt, mut gw) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.0));
            for i in 0..n {
                let (o, d) = (self.world_o[i], self.world_d[i]);
                for s in st.eval.offsets[i]..st.eval.offsets[i + 1] {
                    // dL/dx and dL/dd in world axes: u = (A x − c) / r, d_u = R_A d.
                    let gx = a.inverse_transform_vector(Vec3::cst(st.d_point[s].map(f64::from))) * (1.0 / r);
                    let gd = a.inverse_transform_vector(Vec3::cst(st.d_dir[s].map(f64::from)));
                    let x = o + d * (st.eval.t[s] as f64 * r);
                    // Moving the object by δ moves its content; the query point moves the other way.
                    gt -= gx;
                    gw += gx.cross(x - layer.pivot) + gd.cross(d);
                }
            }
            let e = &mut out[obj];
            for k in 0..3 {
                e[k] += gt.to_array()[k];
                e[3 + k] += gw.to_array()[k];
            }
        }
        out
    }
}

/// A composed view: colour, depth (metres along each ray), total opacity and each object's opacity.
pub struct ComposedImage {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<[f32; 3]>,
    pub depth: Vec<f32>,
    pub opacity: Vec<f32>,
    /// Metres to the surface seen ([`ComposedRay::surface`]).
    pub surface: Vec<f32>,
    /// `pixels × objects`.
    pub object_opacity: Vec<f32>,
    pub objects: usize,
    /// Pixels whose rays went through the fields (the others meet no object and show what is behind).
    pub traced: usize,
    /// Samples the fields were evaluated at.
    pub samples: usize,
}

impl ComposedImage {
    /// Pixel `p` as a ray's output.
    pub fn pixel(&self, p: usize) -> ComposedRay {
        ComposedRay {
            rgb: self.rgb[p],
            depth: self.depth[p],
            opacity: self.opacity[p],
            surface: self.surface[p],
        }
    }
}

/// Render a whole view of `camera` (world) through `layers`, in chunks. With a scene layer every pixel is
/// traced; without one, only pixels whose rays meet an object's occupied cells, the others showing `behind`.
pub fn render_composed(
    layers: &[Layer<'_>],
    objects: usize,
    behind: Behind<'_>,
    camera: &Camera<f64>,
    composer: &mut Composer,
) -> ComposedImage {
    const CHUNK: usize = 2048;
    let (w, h) = (camera.width, camera.height);
    let n = (w * h) as usize;
    let behind_at = |p: usize| match behind {
        Behind::Colour(c) => ComposedRay {
            rgb: c,
            depth: 0.0,
            opacity: 0.0,
            surface: f32::INFINITY,
        },
        Behind::Scene(s) => s[p].clone(),
    };
    if let Behind::Scene(s) = behind {
        assert_eq!(s.len(), n, "render_composed: one pre-rendered scene pixel per pixel");
    }
    let mut img = ComposedImage {
        width: w,
        height: h,
        rgb: Vec::with_capacity(n),
        depth: Vec::with_capacity(n),
        opacity: Vec::with_capacity(n),
        surface: Vec::with_capacity(n),
        object_opacity: vec![0.0; n * objects],
        objects,
        traced: 0,
        samples: 0,
    };
    for p in 0..n {
        let b = behind_at(p);
        img.rgb.push(b.rgb);
        img.depth.push(b.depth);
        img.opacity.push(b.opacity);
        img.surface.push(b.surface);
    }
    let trace_all = layers.iter().any(|l| l.object.is_none());
    let (mut o, mut d, mut pix, mut under) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            let r = camera.ray(x as f64 + 0.5, y as f64 + 0.5);
            if !trace_all && !layers.iter().any(|l| l.meets(r.origin, r.dir)) {
                continue;
            }
            let p = (y * w + x) as usize;
            o.push(r.origin);
            d.push(r.dir);
            pix.push(p);
            if let Behind::Scene(s) = behind {
                under.push(s[p].clone());
            }
        }
    }
    // Chunks side by side, one composer each (the caller's and pooled ones): a chunk's pass leaves one core
    // idle between its parallel kernels. The chunks are the same whatever the threads, and so are the bits.
    let threads = rayon::current_num_threads().max(1);
    let mut pooled: Vec<PooledComposer> = (1..threads).map(|_| PooledComposer::take()).collect();
    let mut composers: Vec<&mut Composer> = std::iter::once(composer)
        .chain(pooled.iter_mut().map(|p| &mut **p))
        .collect();
    let chunks: Vec<std::ops::Range<usize>> = (0..pix.len())
        .step_by(CHUNK)
        .map(|a| a..(a + CHUNK).min(pix.len()))
        .collect();
    for group in chunks.chunks(threads) {
        let results: Vec<(Vec<ComposedRay>, Vec<f32>, usize)> = composers
            .par_iter_mut()
            .zip(group.par_iter())
            .map(|(c, range)| {
                let b = match behind {
                    Behind::Scene(_) => Behind::Scene(&under[range.clone()]),
                    c => c,
                };
                c.forward(layers, objects, b, &o[range.clone()], &d[range.clone()]);
                let n = range.len();
                (
                    c.out[..n].to_vec(),
                    c.object_opacity[..n * objects].to_vec(),
                    c.evaluated_samples(),
                )
            })
            .collect();
        for (range, (out, object_opacity, samples)) in group.iter().zip(results) {
            for (j, r) in out.iter().enumerate() {
                let p = pix[range.start + j];
                img.rgb[p] = r.rgb;
                img.depth[p] = r.depth;
                img.opacity[p] = r.opacity;
                img.surface[p] = r.surface;
                img.object_opacity[p * objects..(p + 1) * objects]
                    .copy_from_slice(&object_opacity[j * objects..(j + 1) * objects]);
            }
            img.traced += range.len();
            img.samples += samples;
        }
    }
    img
}

/// The scene alone through a fixed camera, per pixel: what objects are composited over ([`Behind::Scene`]).
pub fn prerender_scene(scene: &LoadedField, camera: &Camera<f64>, composer: &mut Composer) -> Vec<ComposedRay> {
    let img = render_composed(&[Layer::scene(scene)], 0, Behind::Colour([0.0; 3]), camera, composer);
    (0..img.rgb.len()).map(|p| img.pixel(p)).collect()
}
