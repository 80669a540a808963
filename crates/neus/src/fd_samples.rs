//! Samples with finite-difference neighbours, shared by training and
//! rendering: the points to evaluate (each sample and a step `eps` along x,
//! y, z: four blocks of `m` points), and from the SDF outputs the gradient,
//! the cosine with the ray, and the colour MLP's input rows.

use field::SH_DIM;
use rayon::prelude::*;

/// Samples a parallel task takes (the finite-difference passes here and in `FieldPass`, a bake's lookups). Between the field's own parallel kernels these loops ran on one core (a
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Across chunk boundaries, rays that end mid-chunk and rays without samples: every sample's four points
    /// and direction are its own ray's, and the eikonal sum is the serial one.
    #[test]
    fn chunks_find_each_samples_ray() {
        let mut rng = geom::SplitMix64::new(5);
        let (mut origins, mut dirs, mut offsets, mut t) = (Vec::new(), Vec::new(), vec![0], Vec::new());
        while t.len() < 3 * SAMPLE_CHUNK + 100 {
            origins.push([0; 3].map(|_| rng.range(-1.0, 1.0) as f32));
            dirs.push([0; 3].map(|_| rng.range(-1.0, 1.0) as f32));
            // Empty rays too, and some longer than a chunk.
            let count = match rng.next_u64() % 5 {
                0 => 0,
                1 => SAMPLE_CHUNK + 7,
                _ => (rng.next_u64() % 300) as usize,
            };
            t.extend((0..count).map(|_| rng.range(0.0, 2.0) as f32));
            offsets.push(t.len());
        }
        let (eps, m) = (1e-3f32, t.len());
        let (mut points, mut sample_dirs) = (Vec::new(), Vec::new());
        fd_points(&origins, &dirs, &offsets, &t, eps, &mut points, &mut sample_dirs);
        for (i, (o, d)) in origins.iter().zip(&dirs).enumerate() {
            for s in offsets[i]..offsets[i + 1] {
                assert_eq!(&sample_dirs[s * 3..s * 3 + 3], d, "sample {s}'s direction");
                for b in 0..4 {
                    let want: [f32; 3] =
                        std::array::from_fn(|k| o[k] + t[s] * d[k] + if b == k + 1 { eps } else { 0.0 });
                    assert_eq!(
                        &points[(b * m + s) * 3..(b * m + s) * 3 + 3],
                        &want,
                        "sample {s}, block {b}"
                    );
                }
            }
        }
        // The gradient pass over made-up outputs (width 2: the SDF and one feature).
        let width = 2;
        let sdf_out: Vec<f32> = (0..4 * m * width).map(|_| rng.range(-1.0, 1.0) as f32 * 1e-3).collect();
        let sh = vec![0.0; m * SH_DIM];
        let (mut grad, mut sdf0, mut cos) = (vec![[0.0; 3]; m], vec![0.0; m], vec![0.0; m]);
        let mut color_in = vec![0.0; m * (SH_DIM + 3 + 1)];
        let eik = fd_gradients(
            &sdf_out,
            width,
            eps,
            &sample_dirs,
            &sh,
            FdOut {
                grad: &mut grad,
                sdf0: &mut sdf0,
                cos: &mut cos,
                color_in: &mut color_in,
            },
        );
        let serial: f64 = grad
            .iter()
            .map(|g| {
                let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt().max(1e-8);
                ((len - 1.0) * (len - 1.0)) as f64
            })
            .sum();
        assert!((eik - serial).abs() <= 1e-9 * serial.max(1.0), "{eik} against {serial}");
        for s in [0, SAMPLE_CHUNK - 1, SAMPLE_CHUNK, m - 1] {
            let want: [f32; 3] =
                std::array::from_fn(|k| (sdf_out[((k + 1) * m + s) * width] - sdf_out[s * width]) / eps);
            assert_eq!(grad[s], want, "sample {s}'s gradient");
            assert_eq!(
                color_in[s * (SH_DIM + 4) + SH_DIM + 3],
                sdf_out[s * width + 1],
                "sample {s}'s feature"
            );
        }
    }
}
