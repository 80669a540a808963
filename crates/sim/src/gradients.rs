//! Exact derivatives of a whole trajectory by forward-mode dual numbers: one
//! pass per block of 16 parameters, blocks run in parallel.

use crate::state::STATE_LEN;
use crate::world::{FrameContacts, World};
use crate::BodyState;
use geom::Dual;
use rayon::prelude::*;

/// Derivative slots per pass.
pub const DUAL_WIDTH: usize = 16;
type D = Dual<DUAL_WIDTH>;

/// A trajectory with `d state / d params`.
#[derive(Clone, Debug)]
pub struct TrajectoryGrad {
    pub frames: Vec<Vec<BodyState<f64>>>,
    pub contacts: Vec<FrameContacts>,
    /// Parameter indices the Jacobian columns stand for.
    pub wrt: Vec<usize>,
    /// `[frame][body][state component][column]`, flattened.
    jac: Vec<f64>,
    bodies: usize,
}

impl TrajectoryGrad {
    /// `d state[frame][body][component] / d params[wrt[col]]`; components are
    /// ordered as [`BodyState::to_array`].
    pub fn d(&self, frame: usize, body: usize, component: usize, col: usize) -> f64 {
        self.jac[self.index(frame, body, component, col)]
    }

    /// The row of derivatives of one state component.
    pub fn row(&self, frame: usize, body: usize, component: usize) -> &[f64] {
        let i = self.index(frame, body, component, 0);
        &self.jac[i..i + self.wrt.len()]
    }

    fn index(&self, frame: usize, body: usize, component: usize, col: usize) -> usize {
        ((frame * self.bodies + body) * STATE_LEN + component) * self.wrt.len() + col
    }
}

/// Simulate with parameters `params` and differentiate every state with
/// respect to `params[wrt[..]]`.
pub fn simulate_with_gradients(world: &World, params: &[f64], wrt: &[usize]) -> TrajectoryGrad {
    assert!(wrt.iter().all(|&i| i < params.len()), "parameter index out of range");
    let chunks: Vec<&[usize]> = if wrt.is_empty() {
        vec![&[][..]]
    } else {
        wrt.chunks(DUAL_WIDTH).collect()
    };
    let runs: Vec<_> = chunks
        .par_iter()
        .map(|chunk| {
            let mut p: Vec<D> = params.iter().map(|&v| D::new(v)).collect();
            for (slot, &i) in chunk.iter().enumerate() {
                p[i] = D::var(params[i], slot);
            }
            world.simulate(&p)
        })
        .collect();
    let first = &runs[0];
    let nb = world.bodies.len();
    let nf = first.frames.len();
    let mut jac = vec![0.0; nf * nb * STATE_LEN * wrt.len()];
    for (c, run) in runs.iter().enumerate() {
        for (k, frame) in run.frames.iter().enumerate() {
            for (b, st) in frame.iter().enumerate() {
                for (comp, v) in st.to_array().iter().enumerate() {
                    for slot in 0..chunks[c].len() {
                        let col = c * DUAL_WIDTH + slot;
                        jac[((k * nb + b) * STATE_LEN + comp) * wrt.len() + col] = v.eps[slot];
                    }
                }
            }
        }
    }
    TrajectoryGrad {
        frames: first
            .frames
            .iter()
            .map(|f| f.iter().map(|s| s.re()).collect())
            .collect(),
        contacts: first.contacts.clone(),
        wrt: wrt.to_vec(),
        jac,
        bodies: nb,
    }
}
