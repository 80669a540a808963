//! Samples with finite-difference neighbours, shared by training and
//! rendering: the points to evaluate (each sample and a step `eps` along x,
//! y, z: four blocks of `m` points), and from the SDF outputs the gradient,
//! the cosine with the ray, and the colour MLP's input rows.

use field::SH_DIM;
use rayon::prelude::*;

/// Samples a parallel task takes. Between the field's own parallel kernels these loops ran on one core (a
/// fit's main thread spent a fifth of its time in them and the passes' other serial loops, the second core
/// idle).
pub(crate) const SAMPLE_CHUNK: usize = 1024;

/// Fill `points` (4 blocks of `m` points, 3 floats each) and `sample_dirs`
/// (one ray direction per sample) for rays `i` with samples `offsets[i]..offsets[i + 1]` at distances `t`.
pub(crate) fn fd_points(
    origins: &[[f32; 3]],
    dirs: &[[f32; 3]],
    offsets: &[usize],
    t: &[f32],
    eps: f32,
    points: &mut Vec<f32>,
    sample_dirs: &mut Vec<f32>,
) {
    let m = t.len();
    points.resize(4 * m * 3, 0.0);
    sample_dirs.resize(m * 3, 0.0);
    let (b0, rest) = points.split_at_mut(m * 3);
    let (b1, rest) = rest.split_at_mut(m * 3);
    let (b2, b3) = rest.split_at_mut(m * 3);
    let c3 = SAMPLE_CHUNK * 3;
    b0.par_chunks_mut(c3)
        .zip(b1.par_chunks_mut(c3))
        .zip(b2.par_chunks_mut(c3))
        .zip(b3.par_chunks_mut(c3))
        .zip(sample_dirs.par_chunks_mut(c3))
        .enumerate()
        .for_each(|(c, ((((q0, q1), q2), q3), sd))| {
            let first = c * SAMPLE_CHUNK;
            // The ray of the chunk's first sample: the last whose samples start at or before it.
            let mut ray = offsets.partition_point(|&o| o <= first) - 1;
            let mut blocks = [q0, q1, q2, q3];
            for r in 0..sd.len() / 3 {
                let s = first + r;
                while offsets[ray + 1] <= s {
                    ray += 1;
                }
                let (o, d) = (origins[ray], dirs[ray]);
                let p = [o[0] + t[s] * d[0], o[1] + t[s] * d[1], o[2] + t[s] * d[2]];
                sd[r * 3..r * 3 + 3].copy_from_slice(&d);
                for (b, block) in blocks.iter_mut().enumerate() {
                    let mut q = p;
                    if b > 0 {
                        q[b - 1] += eps;
                    }
                    block[r * 3..r * 3 + 3].copy_from_slice(&q);
                }
            }
        });
}

/// Per-sample results of [`fd_gradients`].
pub(crate) struct FdOut<'a> {
    pub grad: &'a mut [[f32; 3]],
    pub sdf0: &'a mut [f32],
    pub cos: &'a mut [f32],
    /// Rows of `SH_DIM + 3 + feature_dim`: SH of the direction, unit normal, feature.
    pub color_in: &'a mut [f32],
}

/// From the SDF MLP outputs of the 4 blocks (`width` = 1 + feature_dim per
/// row): gradient, SDF, cosine and colour input of each of the `m` samples.
/// Returns Σ (|∇s| − 1)² for the eikonal term (summed by chunks, in order: the same bits on any number of
/// threads).
pub(crate) fn fd_gradients(sdf_out: &[f32], width: usize, eps: f32, sample_dirs: &[f32], sh: &[f32], o: FdOut) -> f64 {
    let m = o.sdf0.len();
    let cin = SH_DIM + 3 + (width - 1);
    let partial: Vec<f64> = o
        .grad
        .par_chunks_mut(SAMPLE_CHUNK)
        .zip(o.sdf0.par_chunks_mut(SAMPLE_CHUNK))
        .zip(o.cos.par_chunks_mut(SAMPLE_CHUNK))
        .zip(o.color_in.par_chunks_mut(SAMPLE_CHUNK * cin))
        .enumerate()
        .map(|(c, (((grad, sdf0), cos), color_in))| {
            let mut eik = 0.0f64;
            for r in 0..grad.len() {
                let s = c * SAMPLE_CHUNK + r;
                let s0 = sdf_out[s * width];
                let g: [f32; 3] = std::array::from_fn(|k| (sdf_out[((k + 1) * m + s) * width] - s0) / eps);
                let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt().max(1e-8);
                eik += ((len - 1.0) * (len - 1.0)) as f64;
                grad[r] = g;
                sdf0[r] = s0;
                let d = &sample_dirs[s * 3..s * 3 + 3];
                cos[r] = g[0] * d[0] + g[1] * d[1] + g[2] * d[2];
                let row = &mut color_in[r * cin..(r + 1) * cin];
                row[..SH_DIM].copy_from_slice(&sh[s * SH_DIM..(s + 1) * SH_DIM]);
                for k in 0..3 {
                    row[SH_DIM + k] = g[k] / len;
                }
                row[SH_DIM + 3..].copy_from_slice(&sdf_out[s * width + 1..(s + 1) * width]);
            }
            eik
        })
        .collect();
    partial.iter().sum()
}
