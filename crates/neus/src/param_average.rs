//! Polyak averaging: the mean of a field's parameters over the last steps of a run.
//!
//! Late in a run Adam's steps are about the learning rate whatever the gradient's size, so the iterates
//! wander about the optimum: on the tabletop scene the board's height moved by ±1 mm from one 50-step
//! snapshot to the next at the last learning rate, and which snapshot a run ended on decided its held-out
//! PSNR and where a body simulated against it bounced. The mean over the last steps sits in the middle of
//! that wandering (Polyak & Juditsky 1992; SWA, Izmailov et al. 2018).

use crate::neus_field::NeusField;
use rayon::prelude::*;

/// The running mean of every parameter vector of a field (hash grid, SDF and colour MLPs, the extras, and
/// the background field's when there is one), in [`NeusField::params`] order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParamAverage {
    /// Iterates averaged so far.
    pub count: usize,
    pub means: Vec<Vec<f32>>,
}

impl ParamAverage {
    /// Add the field's current parameters to the mean.
    pub fn add(&mut self, field: &NeusField) {
        let params = field.params();
        if self.count == 0 {
            self.means = params.iter().map(|(_, p)| p.to_vec()).collect();
            self.count = 1;
            return;
        }
        self.count += 1;
        let w = 1.0 / self.count as f32;
        for (mean, (_, p)) in self.means.iter_mut().zip(params) {
            mean.par_chunks_mut(1 << 16)
                .zip(p.par_chunks(1 << 16))
                .for_each(|(m, x)| {
                    for (a, b) in m.iter_mut().zip(x) {
                        *a += (b - *a) * w;
                    }
                });
        }
    }

    /// Put the mean into the field (nothing when no iterate was added).
    pub fn apply(&self, field: &mut NeusField) {
        if self.count == 0 {
            return;
        }
        for ((_, p), mean) in field.params_mut().into_iter().zip(&self.means) {
            p.copy_from_slice(mean);
        }
    }
}
