//! Adam (Kingma & Ba 2015) over a flat parameter buffer, dense or sparse ("lazy": only the hash-table entries
//! touched since the last step move, the others keep their moments, as Instant-NGP's sparse updates).

use crate::hash_grid::{HashGrid, Touched};
use crate::kernels;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Floats per rayon task of a dense step.
const DENSE_BLOCK: usize = 16 * 1024;

/// Adam hyper-parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AdamConfig {
    /// Base learning rate; the trainer's schedule scales it and passes the result to each step. Default 1e-2.
    pub lr: f32,
    /// First-moment decay. Default 0.9.
    pub beta1: f32,
    /// Second-moment decay. Default 0.99.
    pub beta2: f32,
    /// Added to √v̂. Default 1e-15 (as Instant-NGP).
    pub eps: f32,
    /// L2 weight decay added to the gradient (not decoupled). Default 0.
    pub weight_decay: f32,
}

impl Default for AdamConfig {
    fn default() -> Self {
        Self {
            lr: 1e-2,
            beta1: 0.9,
            beta2: 0.99,
            eps: 1e-15,
            weight_decay: 0.0,
        }
    }
}

/// Adam state of one parameter buffer. `step` counts the steps taken on this buffer (bias correction).
#[derive(Clone, Debug)]
pub struct Adam {
    pub m: Vec<f32>,
    pub v: Vec<f32>,
    pub step: u64,
}

impl Adam {
    /// Zero moments for a buffer of `n` floats.
    pub fn new(n: usize) -> Self {
        Self {
            m: vec![0.0; n],
            v: vec![0.0; n],
            step: 0,
        }
    }

    fn coeffs(&self, cfg: &AdamConfig, lr: f32) -> kernels::AdamCoeffs {
        let t = self.step as f64;
        kernels::AdamCoeffs {
            lr,
            beta1: cfg.beta1,
            beta2: cfg.beta2,
            eps: cfg.eps,
            weight_decay: cfg.weight_decay,
            bc1: (1.0 - (cfg.beta1 as f64).powf(t)) as f32,
            bc2: (1.0 - (cfg.beta2 as f64).powf(t)) as f32,
        }
    }

    /// One step over every float with learning rate `lr`; zeroes `grad`.
    pub fn step_dense(&mut self, cfg: &AdamConfig, lr: f32, params: &mut [f32], grad: &mut [f32]) {
        let n = self.m.len();
        assert!(
            params.len() == n && grad.len() == n,
            "Adam::step_dense: buffers of {n} floats expected"
        );
        self.step += 1;
        let c = self.coeffs(cfg, lr);
        params
            .par_chunks_mut(DENSE_BLOCK)
            .zip(grad.par_chunks_mut(DENSE_BLOCK))
            .zip(self.m.par_chunks_mut(DENSE_BLOCK))
            .zip(self.v.par_chunks_mut(DENSE_BLOCK))
            .for_each(|(((p, g), m), v)| kernels::adam_update(p, g, m, v, c));
    }

    /// Lazy step over the hash-grid buffer: only the entries in `touched` are updated (their gradient zeroed);
    /// the others keep parameters and moments. The step counter advances once per call. Clears `touched`.
    /// Parallel over levels (disjoint slices).
    pub fn step_sparse(
        &mut self,
        cfg: &AdamConfig,
        lr: f32,
        params: &mut [f32],
        grad: &mut [f32],
        touched: &mut Touched,
        grid: &HashGrid,
    ) {
        let n = grid.param_count();
        assert!(
            self.m.len() == n && params.len() == n && grad.len() == n,
            "Adam::step_sparse: buffers of the grid's {n} floats expected"
        );
        assert_eq!(
            touched.levels.len(),
            grid.levels(),
            "Adam::step_sparse: touched built for another grid"
        );
        self.step += 1;
        let c = self.coeffs(cfg, lr);
        let f = grid.features_per_level();
        let mut parts = Vec::with_capacity(grid.levels());
        let (mut p, mut g, mut m, mut v) = (params, grad, &mut self.m[..], &mut self.v[..]);
        for l in 0..grid.levels() {
            let len = grid.level_range(l).len();
            let (p0, p1) = p.split_at_mut(len);
            let (g0, g1) = g.split_at_mut(len);
            let (m0, m1) = m.split_at_mut(len);
            let (v0, v1) = v.split_at_mut(len);
            parts.push((p0, g0, m0, v0));
            (p, g, m, v) = (p1, g1, m1, v1);
        }
        parts
            .into_par_iter()
            .zip(touched.levels.par_iter_mut())
            .for_each(|((p, g, m, v), t)| {
                kernels::adam_update_marked(p, g, m, v, &mut t.bits, f, c);
            });
    }
}
