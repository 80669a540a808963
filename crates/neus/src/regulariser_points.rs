//! The eikonal and no-overhang terms at points apart from the rendered samples. When a training step keeps
//! only the samples near the surface (`sample_band`), the field a centimetre off the surface — which the
//! simulator reads — is no longer held to a distance by the eikonal term: at 10 mm over the demo's board a
//! band-trained scene read 9.1 mm with a gradient of length 0.64 tilted 5.5° (profile notebook). So a step
//! sets aside every few of the samples it drops and evaluates only the SDF there (a step away along x, y, z
//! for the gradient, no colour): each such point stands for the dropped samples it was picked from, and the
//! two terms' mean over all samples is what it was before the band.

use crate::neus_field::{NeusField, SdfGrads, SdfPassScratch};
use field::GradMode;

/// A step keeps one in this many of its dropped samples as a regulariser point: a quarter of the SDF work
/// they would have cost (and none of the colour's), while each occupied cell a ray crosses still gets
/// points at every step on average.
pub const REGULARISER_EVERY: usize = 4;

/// The buffers of [`RegulariserPoints::run`], kept between steps.
#[derive(Default)]
pub struct RegulariserPoints {
    points4: Vec<f32>,
    pass: SdfPassScratch,
}

/// Each term's weight per point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RegulariserWeights {
    pub eikonal: f32,
    pub overhang: f32,
}

/// The unweighted sums over the points.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RegulariserSums {
    /// Σ (|∇s| − 1)².
    pub eikonal: f64,
    /// Σ max(0, −∂s/∂z).
    pub overhang: f64,
}

impl RegulariserPoints {
    /// The two terms at `points` (unit coordinates), the gradient taken by forward differences of step `eps`;
    /// the gradient of `w.eikonal · Σ (|∇s| − 1)² + w.overhang · Σ max(0, −∂s/∂z)` is added to `grads` (the
    /// SDF MLP's and the grid's parameters). Returns the sums.
    pub fn run(
        &mut self,
        field: &NeusField,
        points: &[[f32; 3]],
        active_levels: usize,
        eps: f32,
        w: RegulariserWeights,
        grads: SdfGrads<'_>,
    ) -> RegulariserSums {
        let n = points.len();
        if n == 0 {
            return RegulariserSums::default();
        }
        self.points4.clear();
        for b in 0..4 {
            for p in points {
                let mut q = *p;
                if b > 0 {
                    q[b - 1] += eps;
                }
                self.points4.extend(q);
            }
        }
        let width = 1 + field.config.feature_dim;
        let out = field.sdf_forward(
            &self.points4,
            active_levels,
            &mut self.pass.unit01,
            &mut self.pass.enc,
            &mut self.pass.input,
            &mut self.pass.mlp,
        );
        self.pass.d_out.clear();
        self.pass.d_out.resize(4 * n * width, 0.0);
        let mut sums = RegulariserSums::default();
        for s in 0..n {
            let s0 = out[s * width];
            let g: [f32; 3] = std::array::from_fn(|k| (out[((k + 1) * n + s) * width] - s0) / eps);
            let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt().max(1e-8);
            sums.eikonal += ((len - 1.0) * (len - 1.0)) as f64;
            sums.overhang += (-g[2]).max(0.0) as f64;
            let mut dg: [f32; 3] = std::array::from_fn(|k| w.eikonal * 2.0 * (len - 1.0) * g[k] / len);
            if g[2] < 0.0 {
                dg[2] -= w.overhang;
            }
            let mut d0 = 0.0;
            for k in 0..3 {
                self.pass.d_out[((k + 1) * n + s) * width] = dg[k] / eps;
                d0 -= dg[k] / eps;
            }
            self.pass.d_out[s * width] = d0;
        }
        field.sdf_backward(
            &self.pass.unit01,
            &mut self.pass.mlp,
            &self.pass.d_out,
            GradMode::Accumulate,
            &mut self.pass.back,
            Some(grads),
            None,
            active_levels,
        );
        sums
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::neus_field::FieldConfig;
    use field::Touched;

    /// The two terms' parameter gradients match central differences of their weighted sums, for the SDF
    /// MLP and the grid, and are added to what the buffers held.
    #[test]
    fn the_terms_gradients_match_central_differences() {
        let points: Vec<[f32; 3]> = (0..40)
            .map(|i| {
                let a = i as f32 * 0.7;
                // Above and below the equator, away from ∂s/∂z = 0 where the no-overhang term has its kink.
                let z = if i % 2 == 0 {
                    -0.25 - 0.01 * i as f32
                } else {
                    0.25 + 0.01 * i as f32
                };
                [0.45 * a.cos(), 0.45 * a.sin(), z]
            })
            .collect();
        // A step of a hundredth keeps the difference quotient clear of the SDF's f32 rounding.
        let (levels, eps, w_eik, w_over) = (8, 1e-2, 0.3f32, 0.7f32);
        // The sphere the field starts as, roughened by the grid's entries, so that |∇s| is off one.
        let make = || {
            let mut f = NeusField::new(&FieldConfig::default(), 5, 0.0);
            for (i, v) in f.grid_params.iter_mut().enumerate() {
                *v += 0.05 * (i as f32 * 0.37).sin();
            }
            // The geometric start gives the encoding zero weight: give it some.
            for (i, v) in f.sdf_params.iter_mut().enumerate() {
                *v += 0.05 * (i as f32 * 0.61).cos();
            }
            f
        };
        let field = make();
        let loss = |f: &NeusField| {
            let mut g = (vec![0.0; f.grid_params.len()], vec![0.0; f.sdf_params.len()]);
            let mut touched = Touched::new(&f.grid);
            let s = RegulariserPoints::default().run(
                f,
                &points,
                levels,
                eps,
                RegulariserWeights::default(),
                SdfGrads {
                    grid: &mut g.0,
                    sdf: &mut g.1,
                    touched: &mut touched,
                },
            );
            w_eik as f64 * s.eikonal + w_over as f64 * s.overhang
        };
        let (mut grid, mut sdf) = (vec![1.0; field.grid_params.len()], vec![1.0; field.sdf_params.len()]);
        let mut touched = Touched::new(&field.grid);
        let sums = RegulariserPoints::default().run(
            &field,
            &points,
            levels,
            eps,
            RegulariserWeights {
                eikonal: w_eik,
                overhang: w_over,
            },
            SdfGrads {
                grid: &mut grid,
                sdf: &mut sdf,
                touched: &mut touched,
            },
        );
        assert!(
            sums.eikonal > 0.1 && sums.overhang > 0.05,
            "both terms active: {sums:?}"
        );
        // The buffers started at one: the gradient is what was added.
        let check = |name: &str, analytic: &[f32], h: f32, nudge: &dyn Fn(&mut NeusField, usize, f32)| {
            let mut order: Vec<usize> = (0..analytic.len()).collect();
            order.sort_by(|&a, &b| (analytic[b] - 1.0).abs().total_cmp(&(analytic[a] - 1.0).abs()));
            for &i in &order[..6] {
                let mut f = make();
                nudge(&mut f, i, h);
                let up = loss(&f);
                nudge(&mut f, i, -2.0 * h);
                let down = loss(&f);
                let numeric = (up - down) / (2.0 * h as f64);
                let a = (analytic[i] - 1.0) as f64;
                assert!(
                    (numeric - a).abs() <= 0.03 * numeric.abs().max(0.05),
                    "{name} parameter {i}: analytic {a} numeric {numeric}"
                );
            }
        };
        check("sdf", &sdf, 2e-3, &|f, i, h| f.sdf_params[i] += h);
        check("grid", &grid, 2e-3, &|f, i, h| f.grid_params[i] += h);
    }
}
