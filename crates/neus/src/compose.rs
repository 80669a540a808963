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
//! Pose tangent: `δ = (δt, δω)`, world axes, perturbing a pose `(R, t)` to
//! `(exp(δω) R, t + δt)` (a rotation about the body's origin, the centre of
//! mass). Gradients are `[dL/dδt, dL/dδω]`.

use crate::background_field::BackgroundScratch;
use crate::checkpoint::LoadedField;
use crate::field_pass::{FieldPass, InputGrads, SampleGrads};
use crate::occupancy::sample_ray;
use crate::render_view::RenderSettings;
use crate::volume::{composite_alpha_backward, section_alpha, section_alpha_backward};
use geom::{Camera, Pose, Vec3};

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
}

/// What one ray renders to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ComposedRay {
    pub rgb: [f32; 3],
    /// Σ w t, metres along the ray (0 where nothing was hit).
    pub depth: f32,
    /// Σ w over every field's samples.
    pub opacity: f32,
}

/// What the loss says of one ray: the gradients of its outputs.
#[derive(Clone, Debug, Default)]
pub struct RayGradient {
    pub rgb: [f32; 3],
    pub depth: f32,
    /// One per object (missing entries count as 0).
    pub object_opacity: Vec<f32>,
}

/// A layer's samples and the buffers of its passes.
#[derive(Default)]
struct LayerState {
    origins: Vec<[f32; 3]>,
    dirs: Vec<[f32; 3]>,
    offsets: Vec<usize>,
    t: Vec<f32>,
    dt: Vec<f32>,
    pass: FieldPass,
    alpha: Vec<f32>,
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

/// The composed renderer's state: after [`Composer::forward`], the outputs, and what
/// [`Composer::backward`] needs. Reuse one across chunks and frames: its buffers are kept.
#[derive(Default)]
pub struct Composer {
    layers: Vec<LayerState>,
    merged: Vec<Merged>,
    merged_offsets: Vec<usize>,
    background: Vec<[f32; 3]>,
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
}

impl Composer {
    /// Render world rays (`dirs` of unit length) through `layers`; `objects` is the number of objects the
    /// layers' indices refer to. Behind everything: the scene's background (its background field or colour),
    /// or `background` when no layer is the scene.
    pub fn forward(
        &mut self,
        layers: &[Layer<'_>],
        objects: usize,
        background: [f32; 3],
        origins: &[Vec3<f64>],
        dirs: &[Vec3<f64>],
    ) {
        let n = origins.len();
        self.objects = objects;
        self.world_o.clear();
        self.world_o.extend_from_slice(origins);
        self.world_d.clear();
        self.world_d.extend_from_slice(dirs);
        self.layers.resize_with(layers.len(), LayerState::default);
        for (layer, st) in layers.iter().zip(&mut self.layers) {
            st.origins.clear();
            st.dirs.clear();
            st.offsets.clear();
            st.offsets.push(0);
            st.t.clear();
            st.dt.clear();
            let march = layer.settings.marching();
            for (o, d) in origins.iter().zip(dirs) {
                let (ou, du) = layer.ray_to_unit(*o, *d);
                st.origins.push(ou);
                st.dirs.push(du);
                sample_ray(&layer.field.occupancy, ou, du, march, 0.5, &mut st.t, &mut st.dt);
                st.offsets.push(st.t.len());
            }
            let f = &layer.field.field;
            st.inv_s = f.inv_s();
            st.pass
                .forward(f, &st.origins, &st.dirs, &st.offsets, &st.t, layer.settings.pass());
            st.alpha.clear();
            let p = &st.pass;
            st.alpha
                .extend((0..st.t.len()).map(|s| section_alpha(p.sdf[s], p.cos[s], st.dt[s], st.inv_s, 1.0)));
        }
        // Behind everything.
        self.background.clear();
        match layers.iter().position(|l| l.object.is_none()) {
            Some(i) => {
                let st = &self.layers[i];
                layers[i]
                    .field
                    .field
                    .colour_behind(&st.origins, &st.dirs, |_| 0.5, &mut self.bg);
                self.background.extend_from_slice(&self.bg.out);
            }
            None => self.background.resize(n, background),
        }
        // Every field's samples in one depth order (metres along the world ray).
        self.merged.clear();
        self.merged_offsets.clear();
        self.merged_offsets.push(0);
        for i in 0..n {
            let start = self.merged.len();
            for (li, (layer, st)) in layers.iter().zip(&self.layers).enumerate() {
                let r = layer.field.radius as f32;
                for s in st.offsets[i]..st.offsets[i + 1] {
                    self.merged.push(Merged {
                        t: st.t[s] * r,
                        layer: li as u32,
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
            for m in &self.merged[self.merged_offsets[i]..self.merged_offsets[i + 1]] {
                let st = &self.layers[m.layer as usize];
                let s = m.sample as usize;
                let a = st.alpha[s] as f64;
                let w = trans * a;
                let c = st.pass.rgb[s];
                for k in 0..3 {
                    rgb[k] += w * c[k] as f64;
                }
                depth += w * m.t as f64;
                opacity += w;
                if let Some(obj) = layers[m.layer as usize].object {
                    per_object[obj] += w;
                }
                trans *= 1.0 - a;
            }
            for k in 0..3 {
                rgb[k] += trans * self.background[i][k] as f64;
            }
            for (obj, v) in per_object.iter().enumerate() {
                self.object_opacity[i * objects + obj] = *v as f32;
            }
            self.out.push(ComposedRay {
                rgb: rgb.map(|v| v as f32),
                depth: depth as f32,
                opacity: opacity as f32,
            });
        }
    }

    /// The gradient with respect to each object's pose (`[dL/dδt, dL/dδω]`, module docs) of the loss whose
    /// gradients with respect to the last [`Self::forward`]'s outputs are `grads` (one per ray). `layers`
    /// must be the forward's.
    pub fn backward(&mut self, layers: &[Layer<'_>], grads: &[RayGradient]) -> Vec<[f64; 6]> {
        let n = self.out.len();
        assert_eq!(grads.len(), n, "Composer::backward: one gradient per ray");
        for st in &mut self.layers {
            let m = st.t.len();
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
            self.alpha.clear();
            self.alpha.extend(
                merged
                    .iter()
                    .map(|m| self.layers[m.layer as usize].alpha[m.sample as usize]),
            );
            self.trans.resize(k, 0.0);
            self.d_alpha.resize(k, 0.0);
            let layers_st = &self.layers;
            let dot = |c: [f32; 3]| c[0] * g.rgb[0] + c[1] * g.rgb[1] + c[2] * g.rgb[2];
            let v = |j: usize| {
                let m = merged[j];
                let c = layers_st[m.layer as usize].pass.rgb[m.sample as usize];
                let op = layers[m.layer as usize]
                    .object
                    .and_then(|o| g.object_opacity.get(o).copied())
                    .unwrap_or(0.0);
                dot(c) + m.t * g.depth + op
            };
            composite_alpha_backward(
                &self.alpha,
                v,
                dot(self.background[i]),
                &mut self.trans,
                &mut self.d_alpha,
            );
            for (j, m) in merged.iter().enumerate() {
                if layers[m.layer as usize].object.is_none() {
                    continue; // the scene is fixed
                }
                let st = &mut self.layers[m.layer as usize];
                let s = m.sample as usize;
                let w = self.trans[j] * self.alpha[j];
                st.d_rgb[s] = g.rgb.map(|d| w * d);
                let p = &st.pass;
                let (ds, dc, _) = section_alpha_backward(p.sdf[s], p.cos[s], st.dt[s], st.inv_s, 1.0, self.d_alpha[j]);
                st.d_sdf[s] = ds;
                st.d_cos[s] = dc;
            }
        }
        // Through each object's field to its samples' points and directions, then to its pose.
        let mut out = vec![[0.0f64; 6]; self.objects];
        for (layer, st) in layers.iter().zip(&mut self.layers) {
            let Some(obj) = layer.object else { continue };
            let m = st.t.len();
            if m == 0 {
                continue;
            }
            st.d_point.resize(m, [0.0; 3]);
            st.d_dir.resize(m, [0.0; 3]);
            st.pass.backward(
                &layer.field.field,
                SampleGrads {
                    sdf: &st.d_sdf,
                    cos: &st.d_cos,
                    rgb: &st.d_rgb,
                    eikonal: 0.0,
                },
                None,
                Some(InputGrads {
                    point: &mut st.d_point,
                    dir: &mut st.d_dir,
                }),
            );
            let a = &layer.capture_from_world;
            let r = layer.field.radius;
            let (mut gt, mut gw) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.0));
            for i in 0..n {
                let (o, d) = (self.world_o[i], self.world_d[i]);
                for s in st.offsets[i]..st.offsets[i + 1] {
                    // dL/dx and dL/dd in world axes: u = (A x − c) / r, d_u = R_A d.
                    let gx = a.inverse_transform_vector(Vec3::cst(st.d_point[s].map(f64::from))) * (1.0 / r);
                    let gd = a.inverse_transform_vector(Vec3::cst(st.d_dir[s].map(f64::from)));
                    let x = o + d * (st.t[s] as f64 * r);
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
    /// `pixels × objects`.
    pub object_opacity: Vec<f32>,
    pub objects: usize,
}

/// Render a whole view of `camera` (world) through `layers`, in chunks of rows.
pub fn render_composed(
    layers: &[Layer<'_>],
    objects: usize,
    background: [f32; 3],
    camera: &Camera<f64>,
    composer: &mut Composer,
) -> ComposedImage {
    let (w, h) = (camera.width, camera.height);
    let n = (w * h) as usize;
    let mut img = ComposedImage {
        width: w,
        height: h,
        rgb: Vec::with_capacity(n),
        depth: Vec::with_capacity(n),
        opacity: Vec::with_capacity(n),
        object_opacity: Vec::with_capacity(n * objects),
        objects,
    };
    let rows = (2048 / w.max(1)).max(1);
    let (mut o, mut d) = (Vec::new(), Vec::new());
    for y0 in (0..h).step_by(rows as usize) {
        o.clear();
        d.clear();
        for y in y0..(y0 + rows).min(h) {
            for x in 0..w {
                let r = camera.ray(x as f64 + 0.5, y as f64 + 0.5);
                o.push(r.origin);
                d.push(r.dir);
            }
        }
        composer.forward(layers, objects, background, &o, &d);
        for r in &composer.out {
            img.rgb.push(r.rgb);
            img.depth.push(r.depth);
            img.opacity.push(r.opacity);
        }
        img.object_opacity.extend_from_slice(&composer.object_opacity);
    }
    img
}
