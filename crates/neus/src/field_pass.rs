//! One field at a batch of ray samples, forward and backward: the SDF there and
//! a step away along x, y, z (finite-difference gradient), cosines, normals,
//! colours; and back from the samples' gradients to the field's parameters
//! (training) and/or to each sample's point and ray direction (a posed
//! object's pose gradient). Training, rendering and the composed renderer all
//! run this one pipeline.

use crate::baked_geometry::BakedGeometry;
use crate::fd_samples::{fd_gradients, fd_points, FdOut, SAMPLE_CHUNK};
use crate::neus_field::{drop_view_dependence, NeusField, SdfBackwardScratch, SdfGrads};
use field::{sh_encode, sh_encode_backward, GradMode, MlpScratch, Touched, SH_DIM};
use rayon::prelude::*;

/// How a pass evaluates the field.
#[derive(Clone, Copy, Debug)]
pub struct PassSettings {
    pub active_levels: usize,
    /// Finite-difference step for gradients, unit coordinates.
    pub fd_eps: f32,
    /// Colour from the point alone (a scene's first steps).
    pub view_independent: bool,
}

/// The field's parameter gradients (overwritten; the grid's touched entries recorded).
pub struct ParamGrads<'a> {
    pub grid: &'a mut [f32],
    pub sdf: &'a mut [f32],
    pub color: &'a mut [f32],
    pub touched: &'a mut Touched,
}

/// Gradients of each sample's point and ray direction (unit coordinates; overwritten).
pub struct InputGrads<'a> {
    pub point: &'a mut [[f32; 3]],
    pub dir: &'a mut [[f32; 3]],
}

/// What [`FieldPass::backward`] starts from, one entry per sample.
pub struct SampleGrads<'a> {
    pub sdf: &'a [f32],
    pub cos: &'a [f32],
    pub rgb: &'a [[f32; 3]],
    /// Weight of the eikonal term per sample (the loss's weight over the sample count); 0 for none.
    pub eikonal: f32,
    /// Weight of the no-overhang term max(0, −∂s/∂z) per sample; 0 for none.
    pub overhang: f32,
}

/// The buffers of one pass; after [`FieldPass::forward`], the per-sample results are public.
#[derive(Default)]
pub struct FieldPass {
    points: Vec<f32>,
    /// Each sample's ray direction (m × 3).
    pub dirs: Vec<f32>,
    unit01: Vec<f32>,
    enc: Vec<f32>,
    sdf_in: Vec<f32>,
    sdf_mlp: MlpScratch,
    /// A bake's outputs (the network's are read from `sdf_mlp`).
    sdf_out: Vec<f32>,
    sh: Vec<f32>,
    color_in: Vec<f32>,
    color_mlp: MlpScratch,
    /// Finite-difference SDF gradient at each sample.
    pub grad: Vec<[f32; 3]>,
    /// SDF at each sample.
    pub sdf: Vec<f32>,
    /// `dir · ∇s` at each sample.
    pub cos: Vec<f32>,
    pub rgb: Vec<[f32; 3]>,
    /// Σ (|∇s| − 1)² over the samples.
    pub eikonal_sum: f64,
    /// Σ max(0, −∂s/∂z) over the samples (unit coordinates share the world's z axis).
    pub overhang_sum: f64,
    settings: Option<PassSettings>,
    /// The last forward read a baked geometry.
    baked: bool,
    d_color_out: Vec<f32>,
    d_color_in: Vec<f32>,
    d_sdf_out: Vec<f32>,
    d_points4: Vec<f32>,
    d_sh: Vec<f32>,
    d_dirs: Vec<f32>,
    sdf_back: SdfBackwardScratch,
}

impl FieldPass {
    /// Samples count of the last forward pass.
    pub fn len(&self) -> usize {
        self.sdf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.sdf.is_empty()
    }

    /// Evaluate `field` at the samples `t[offsets[i]..offsets[i + 1]]` of rays `(origins[i], dirs[i])`.
    pub fn forward(
        &mut self,
        field: &NeusField,
        origins: &[[f32; 3]],
        dirs: &[[f32; 3]],
        offsets: &[usize],
        t: &[f32],
        set: PassSettings,
    ) {
        self.forward_with(field, None, origins, dirs, offsets, t, set);
    }

    /// [`Self::forward`], the geometry (SDF, features and normals) read from `baked` when given (the field frozen:
    /// [`crate::baked_geometry`]), the colour MLP still `field`'s.
    #[allow(clippy::too_many_arguments)]
    pub fn forward_with(
        &mut self,
        field: &NeusField,
        baked: Option<&BakedGeometry>,
        origins: &[[f32; 3]],
        dirs: &[[f32; 3]],
        offsets: &[usize],
        t: &[f32],
        set: PassSettings,
    ) {
        let m = t.len();
        self.settings = Some(set);
        self.baked = baked.is_some();
        fd_points(origins, dirs, offsets, t, set.fd_eps, &mut self.points, &mut self.dirs);
        let width = 1 + field.config.feature_dim;
        match baked {
            Some(b) => {
                assert_eq!(b.width(), width, "FieldPass: a bake of another field");
                b.forward_fd(&self.points, m, &mut self.sdf_out);
            }
            None => {
                field.sdf_forward(
                    &self.points,
                    set.active_levels,
                    &mut self.unit01,
                    &mut self.enc,
                    &mut self.sdf_in,
                    &mut self.sdf_mlp,
                );
            }
        }
        // The network's outputs are read where its MLP left them (no copy); a bake's from `sdf_out`.
        let sdf_out: &[f32] = if baked.is_some() {
            &self.sdf_out
        } else {
            self.sdf_mlp.output()
        };
        let cin = SH_DIM + 3 + field.config.feature_dim;
        self.sh.resize(m * SH_DIM, 0.0);
        sh_encode(&self.dirs, &mut self.sh);
        if set.view_independent {
            drop_view_dependence(&mut self.sh);
        }
        self.grad.resize(m, [0.0; 3]);
        self.sdf.resize(m, 0.0);
        self.cos.resize(m, 0.0);
        self.color_in.resize(m * cin, 0.0);
        self.eikonal_sum = fd_gradients(
            sdf_out,
            width,
            set.fd_eps,
            &self.dirs,
            &self.sh,
            FdOut {
                grad: &mut self.grad,
                sdf0: &mut self.sdf,
                cos: &mut self.cos,
                color_in: &mut self.color_in,
            },
        );
        self.overhang_sum = self.grad.iter().map(|g| (-g[2]).max(0.0) as f64).sum();
        let rgb = field
            .color
            .forward(&field.color_params, &self.color_in, m, &mut self.color_mlp);
        self.rgb.clear();
        self.rgb.extend(rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
    }

    /// Back from the samples' gradients (after [`Self::forward`] with the same field) to the parameters
    /// and/or to each sample's point and direction.
    pub fn backward(
        &mut self,
        field: &NeusField,
        g: SampleGrads<'_>,
        params: Option<ParamGrads<'_>>,
        inputs: Option<InputGrads<'_>>,
    ) {
        self.backward_with(field, None, g, params, inputs);
    }

    /// [`Self::backward`] after [`Self::forward_with`] with the same `baked`: to the inputs only (a baked
    /// geometry belongs to a field that no longer trains).
    pub fn backward_with(
        &mut self,
        field: &NeusField,
        baked: Option<&BakedGeometry>,
        g: SampleGrads<'_>,
        params: Option<ParamGrads<'_>>,
        inputs: Option<InputGrads<'_>>,
    ) {
        let set = self.settings.expect("FieldPass::backward before forward");
        assert_eq!(
            baked.is_some(),
            self.baked,
            "FieldPass::backward_with: the forward's geometry"
        );
        assert!(
            baked.is_none() || params.is_none(),
            "FieldPass::backward_with: a baked geometry has no parameters"
        );
        let m = self.len();
        let (eps, fdim) = (set.fd_eps, field.config.feature_dim);
        let width = 1 + fdim;
        let cin = SH_DIM + 3 + fdim;

        // Colour MLP: to its parameters, the direction's encoding, the normal and the feature.
        self.d_color_out.clear();
        self.d_color_out.extend(g.rgb.iter().flatten());
        self.d_color_in.resize(m * cin, 0.0);
        let mut no_grad: [f32; 0] = [];
        let (mode, color_buf, sdf_grads) = match params {
            Some(p) => (
                GradMode::Overwrite,
                p.color,
                Some(SdfGrads {
                    grid: p.grid,
                    sdf: p.sdf,
                    touched: p.touched,
                }),
            ),
            None => (GradMode::Ignore, &mut no_grad[..], None),
        };
        field.color.backward(
            &field.color_params,
            &mut self.color_mlp,
            &self.d_color_out,
            color_buf,
            mode,
            Some(&mut self.d_color_in),
        );

        // Back to the SDF outputs of the 4 blocks.
        // Every entry is written below (no zero-fill first: it was a serial pass over 4m rows).
        self.d_sdf_out.resize(4 * m * width, 0.0);
        {
            let (b0, rest) = self.d_sdf_out.split_at_mut(m * width);
            let (b1, rest) = rest.split_at_mut(m * width);
            let (b2, b3) = rest.split_at_mut(m * width);
            let (grad, dirs, d_color_in) = (&self.grad, &self.dirs, &self.d_color_in);
            let cw = SAMPLE_CHUNK * width;
            b0.par_chunks_mut(cw)
                .zip(b1.par_chunks_mut(cw))
                .zip(b2.par_chunks_mut(cw))
                .zip(b3.par_chunks_mut(cw))
                .enumerate()
                .for_each(|(c, (((r0, r1), r2), r3))| {
                    let mut neighbours = [r1, r2, r3];
                    for r in 0..r0.len() / width {
                        let s = c * SAMPLE_CHUNK + r;
                        let gr = grad[s];
                        let len = (gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2]).sqrt().max(1e-8);
                        let n = gr.map(|v| v / len);
                        let dn: [f32; 3] = std::array::from_fn(|k| d_color_in[s * cin + SH_DIM + k]);
                        let ndn = n[0] * dn[0] + n[1] * dn[1] + n[2] * dn[2];
                        let d = &dirs[s * 3..s * 3 + 3];
                        let mut dg = [0.0f32; 3];
                        for k in 0..3 {
                            dg[k] = (dn[k] - n[k] * ndn) / len + g.cos[s] * d[k] + g.eikonal * 2.0 * (len - 1.0) * n[k];
                        }
                        if gr[2] < 0.0 {
                            dg[2] -= g.overhang;
                        }
                        let mut d0 = g.sdf[s];
                        for (k, block) in neighbours.iter_mut().enumerate() {
                            block[r * width] = dg[k] / eps;
                            block[r * width + 1..(r + 1) * width].fill(0.0);
                            d0 -= dg[k] / eps;
                        }
                        r0[r * width] = d0;
                        r0[r * width + 1..(r + 1) * width]
                            .copy_from_slice(&d_color_in[s * cin + SH_DIM + 3..s * cin + SH_DIM + 3 + fdim]);
                    }
                });
        }
        let want_inputs = inputs.is_some();
        if want_inputs {
            self.d_points4.resize(4 * m * 3, 0.0);
        }
        match baked {
            Some(b) => {
                if want_inputs {
                    b.backward_fd_points(&self.points, m, &self.d_sdf_out, &mut self.d_points4);
                }
            }
            None => field.sdf_backward(
                &self.unit01,
                &mut self.sdf_mlp,
                &self.d_sdf_out,
                GradMode::Overwrite,
                &mut self.sdf_back,
                sdf_grads,
                want_inputs.then_some(&mut self.d_points4[..]),
                set.active_levels,
            ),
        }
        let Some(inputs) = inputs else { return };

        // Each sample's point moves its three neighbours with it.
        for s in 0..m {
            inputs.point[s] = std::array::from_fn(|k| (0..4).map(|b| self.d_points4[(b * m + s) * 3 + k]).sum::<f32>());
        }
        // The direction: through the cosine and, unless the colour ignores it, its encoding.
        self.d_dirs.clear();
        self.d_dirs.resize(m * 3, 0.0);
        if !set.view_independent {
            self.d_sh.resize(m * SH_DIM, 0.0);
            for s in 0..m {
                self.d_sh[s * SH_DIM..(s + 1) * SH_DIM].copy_from_slice(&self.d_color_in[s * cin..s * cin + SH_DIM]);
            }
            sh_encode_backward(&self.dirs, &self.d_sh, &mut self.d_dirs);
        }
        for s in 0..m {
            inputs.dir[s] = std::array::from_fn(|k| self.d_dirs[s * 3 + k] + g.cos[s] * self.grad[s][k]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::neus_field::FieldConfig;

    /// With the view weights zeroed, switching the view direction on leaves every colour as it was; with
    /// random ones (the plain start) it does not.
    #[test]
    fn zeroed_view_weights_make_the_switch_to_view_dependence_seamless() {
        let origins = [[0.1, -0.6, 0.2], [-0.5, 0.1, 0.3], [0.0, 0.0, -0.7]];
        let dirs = [[0.0, 1.0, 0.0], [0.8, 0.0, -0.6], [0.0, 0.6, 0.8]];
        let offsets = [0, 4, 8, 12];
        let t: Vec<f32> = (0..12).map(|i| 0.3 + 0.05 * i as f32).collect();
        let rgb = |field: &NeusField, view_independent: bool| {
            let mut pass = FieldPass::default();
            let set = PassSettings {
                active_levels: 8,
                fd_eps: 1e-3,
                view_independent,
            };
            pass.forward(field, &origins, &dirs, &offsets, &t, set);
            pass.rgb
        };
        let mut field = NeusField::new(&FieldConfig::default(), 7, 0.0);
        let jolt = |f: &NeusField| {
            rgb(f, true)
                .iter()
                .zip(rgb(f, false))
                .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f32::max))
                .fold(0.0, f32::max)
        };
        assert!(
            jolt(&field) > 1e-3,
            "random view weights change the colour: {}",
            jolt(&field)
        );
        field.zero_view_weights();
        assert_eq!(jolt(&field), 0.0);
    }

    /// The eikonal and no-overhang terms' parameter gradients match central differences of their sums.
    #[test]
    fn regulariser_gradients_match_central_differences() {
        let origins = [[0.1, -0.6, 0.2], [-0.5, 0.1, 0.3], [0.0, 0.2, 0.7]];
        let dirs = [[0.0, 1.0, 0.0], [0.8, 0.0, -0.6], [0.0, -0.6, -0.8]];
        let offsets = [0, 6, 12, 18];
        let t: Vec<f32> = (0..18).map(|i| 0.2 + 0.07 * (i % 6) as f32).collect();
        let set = PassSettings {
            active_levels: 8,
            fd_eps: 1e-3,
            view_independent: false,
        };
        let (w_eik, w_over) = (0.3f32, 0.7f32);
        let field = NeusField::new(&FieldConfig::default(), 11, 0.0);
        let loss = |f: &NeusField| {
            let mut pass = FieldPass::default();
            pass.forward(f, &origins, &dirs, &offsets, &t, set);
            w_eik as f64 * pass.eikonal_sum + w_over as f64 * pass.overhang_sum
        };
        let mut pass = FieldPass::default();
        pass.forward(&field, &origins, &dirs, &offsets, &t, set);
        let m = pass.len();
        assert!(
            pass.overhang_sum > 0.05,
            "the sphere's lower half overhangs: {}",
            pass.overhang_sum
        );
        let zeros = vec![0.0f32; m];
        let (mut grid, mut sdf, mut color) = (
            vec![0.0; field.grid_params.len()],
            vec![0.0; field.sdf_params.len()],
            vec![0.0; field.color_params.len()],
        );
        let mut touched = Touched::new(&field.grid);
        pass.backward(
            &field,
            SampleGrads {
                sdf: &zeros,
                cos: &zeros,
                rgb: &vec![[0.0; 3]; m],
                eikonal: w_eik,
                overhang: w_over,
            },
            Some(ParamGrads {
                grid: &mut grid,
                sdf: &mut sdf,
                color: &mut color,
                touched: &mut touched,
            }),
            None,
        );
        // The SDF MLP's largest gradients, against central differences.
        let mut order: Vec<usize> = (0..sdf.len()).collect();
        order.sort_by(|&a, &b| sdf[b].abs().total_cmp(&sdf[a].abs()));
        for &i in &order[..8] {
            let h = 2e-3;
            let mut f = NeusField::new(&FieldConfig::default(), 11, 0.0);
            f.sdf_params[i] += h;
            let up = loss(&f);
            f.sdf_params[i] -= 2.0 * h;
            let down = loss(&f);
            let numeric = (up - down) / (2.0 * h as f64);
            let err = (numeric - sdf[i] as f64).abs();
            assert!(
                err <= 0.03 * numeric.abs().max(0.05),
                "sdf parameter {i}: analytic {} numeric {numeric}",
                sdf[i]
            );
        }
    }
}
