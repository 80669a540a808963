//! One field along a batch of rays, evaluated front to back in rounds with
//! early ray termination (as instant-ngp and NeuS2 stop a ray): each round
//! takes the next part of every live ray's samples, and a ray is dropped
//! once its own transmittance through this field is below a threshold. Its
//! later samples could add at most that much to any composite the field joins
//! (the composite's transmittance is never above the field's own), so the
//! colours change by less than the threshold while a surface's far side and
//! what lies behind it are evaluated at most to the end of the round in which
//! the ray became opaque (rounds end at a third, two thirds and all of each
//! ray's samples). Forward and backward run over all
//! rounds' samples as one list in ray order.

use crate::baked_geometry::BakedGeometry;
use crate::field_pass::{FieldPass, InputGrads, PassSettings, SampleGrads};
use crate::neus_field::NeusField;
use crate::volume::section_alpha;

/// How much of each ray's samples the rounds have taken when they end.
const ROUND_ENDS: [f32; 3] = [0.34, 0.67, 1.0];

/// The evaluated samples of a batch of rays (after [`RayRounds::forward`]: per sample in ray order).
#[derive(Default)]
pub struct RayRounds {
    /// Ray `i`'s evaluated samples are `offsets[i]..offsets[i + 1]`.
    pub offsets: Vec<usize>,
    pub t: Vec<f32>,
    pub dt: Vec<f32>,
    pub sdf: Vec<f32>,
    pub cos: Vec<f32>,
    pub rgb: Vec<[f32; 3]>,
    /// The SDF's gradient (finite differences; normals come from it).
    pub grad: Vec<[f32; 3]>,
    /// NeuS section opacity.
    pub alpha: Vec<f32>,
    /// Each sample's round and index in that round's pass.
    src: Vec<(u32, u32)>,
    rounds: Vec<Round>,
    trans: Vec<f32>,
    taken: Vec<usize>,
}

/// One round's pass and the rays it evaluated.
#[derive(Default)]
struct Round {
    pass: FieldPass,
    rays: Vec<usize>,
    origins: Vec<[f32; 3]>,
    dirs: Vec<[f32; 3]>,
    offsets: Vec<usize>,
    t: Vec<f32>,
    d_sdf: Vec<f32>,
    d_cos: Vec<f32>,
    d_rgb: Vec<[f32; 3]>,
    d_point: Vec<[f32; 3]>,
    d_dir: Vec<[f32; 3]>,
}

impl RayRounds {
    /// Evaluate `field` at the samples `t[offsets[i]..offsets[i + 1]]` (with section lengths `dt`) of rays
    /// `(origins[i], dirs[i])`, dropping a ray once its transmittance is below `stop` (0: never, one round);
    /// its geometry from `baked` when given ([`FieldPass::forward_with`]).
    #[allow(clippy::too_many_arguments)]
    pub fn forward(
        &mut self,
        field: &NeusField,
        baked: Option<&BakedGeometry>,
        origins: &[[f32; 3]],
        dirs: &[[f32; 3]],
        offsets: &[usize],
        t: &[f32],
        dt: &[f32],
        set: PassSettings,
        stop: f32,
    ) {
        let n = origins.len();
        let inv_s = field.inv_s();
        let ends: &[f32] = if stop > 0.0 { &ROUND_ENDS } else { &[1.0] };
        self.rounds.resize_with(ends.len(), Round::default);
        self.trans.clear();
        self.trans.resize(n, 1.0);
        self.taken.clear();
        self.taken.resize(n, 0);
        for (round, &end) in self.rounds.iter_mut().zip(ends) {
            round.rays.clear();
            round.origins.clear();
            round.dirs.clear();
            round.offsets.clear();
            round.offsets.push(0);
            round.t.clear();
            for i in 0..n {
                let count = offsets[i + 1] - offsets[i];
                let upto = if end >= 1.0 {
                    count
                } else {
                    ((count as f32 * end).ceil() as usize).min(count)
                };
                if self.trans[i] < stop || upto <= self.taken[i] {
                    continue;
                }
                round.rays.push(i);
                round.origins.push(origins[i]);
                round.dirs.push(dirs[i]);
                round
                    .t
                    .extend_from_slice(&t[offsets[i] + self.taken[i]..offsets[i] + upto]);
                round.offsets.push(round.t.len());
            }
            if round.rays.is_empty() {
                continue;
            }
            round
                .pass
                .forward_with(field, baked, &round.origins, &round.dirs, &round.offsets, &round.t, set);
            let p = &round.pass;
            for (j, &i) in round.rays.iter().enumerate() {
                let first = offsets[i] + self.taken[i];
                for s in round.offsets[j]..round.offsets[j + 1] {
                    let a = section_alpha(p.sdf[s], p.cos[s], dt[first + s - round.offsets[j]], inv_s, 1.0);
                    self.trans[i] *= 1.0 - a;
                }
                self.taken[i] += round.offsets[j + 1] - round.offsets[j];
            }
        }
        // Every ray's evaluated samples, front to back: its part of each round in turn.
        // Each round lists its rays in increasing order: walk them together.
        let mut next: Vec<usize> = vec![0; self.rounds.len()];
        self.offsets.clear();
        self.offsets.push(0);
        self.t.clear();
        self.dt.clear();
        self.sdf.clear();
        self.cos.clear();
        self.rgb.clear();
        self.grad.clear();
        self.alpha.clear();
        self.src.clear();
        for i in 0..n {
            for (r, round) in self.rounds.iter().enumerate() {
                if next[r] >= round.rays.len() || round.rays[next[r]] != i {
                    continue;
                }
                let j = next[r];
                next[r] += 1;
                for s in round.offsets[j]..round.offsets[j + 1] {
                    let p = &round.pass;
                    let k = offsets[i] + self.t.len() - self.offsets[i];
                    self.t.push(t[k]);
                    self.dt.push(dt[k]);
                    self.sdf.push(p.sdf[s]);
                    self.cos.push(p.cos[s]);
                    self.rgb.push(p.rgb[s]);
                    self.grad.push(p.grad[s]);
                    self.alpha.push(section_alpha(p.sdf[s], p.cos[s], dt[k], inv_s, 1.0));
                    self.src.push((r as u32, s as u32));
                }
            }
            self.offsets.push(self.t.len());
        }
    }

    /// Each ray's transmittance through the field over its evaluated samples (after [`Self::forward`]): a ray
    /// below the threshold was stopped, and what lies behind it adds less than that to its colour.
    pub fn transmittance(&self) -> &[f32] {
        &self.trans
    }

    /// From the gradients of each evaluated sample's SDF, cosine and colour (ray order, as
    /// [`Self::forward`] left them) to each sample's point and direction (unit frame; overwritten).
    #[allow(clippy::too_many_arguments)]
    pub fn backward_inputs(
        &mut self,
        field: &NeusField,
        baked: Option<&BakedGeometry>,
        d_sdf: &[f32],
        d_cos: &[f32],
        d_rgb: &[[f32; 3]],
        d_point: &mut [[f32; 3]],
        d_dir: &mut [[f32; 3]],
    ) {
        for round in &mut self.rounds {
            let m = round.t.len();
            round.d_sdf.clear();
            round.d_sdf.resize(m, 0.0);
            round.d_cos.clear();
            round.d_cos.resize(m, 0.0);
            round.d_rgb.clear();
            round.d_rgb.resize(m, [0.0; 3]);
        }
        for (k, &(r, s)) in self.src.iter().enumerate() {
            let round = &mut self.rounds[r as usize];
            round.d_sdf[s as usize] = d_sdf[k];
            round.d_cos[s as usize] = d_cos[k];
            round.d_rgb[s as usize] = d_rgb[k];
        }
        for round in &mut self.rounds {
            let m = round.t.len();
            if m == 0 || round.rays.is_empty() {
                continue;
            }
            round.d_point.resize(m, [0.0; 3]);
            round.d_dir.resize(m, [0.0; 3]);
            round.pass.backward_with(
                field,
                baked,
                SampleGrads {
                    sdf: &round.d_sdf,
                    cos: &round.d_cos,
                    rgb: &round.d_rgb,
                    eikonal: 0.0,
                    overhang: 0.0,
                },
                None,
                Some(InputGrads {
                    point: &mut round.d_point,
                    dir: &mut round.d_dir,
                }),
            );
        }
        for (k, &(r, s)) in self.src.iter().enumerate() {
            let round = &self.rounds[r as usize];
            d_point[k] = round.d_point[s as usize];
            d_dir[k] = round.d_dir[s as usize];
        }
    }
}
