//! A frozen field's geometry baked onto a lattice, as SNeRG and instant-ngp's
//! baking do: its SDF and the features the colour MLP reads, sampled `sub`
//! times finer than the occupancy grid in the occupied cells and their
//! neighbours (bricks of `(sub + 1)³` points, one per cell), then read back by
//! trilinear interpolation. A posed object in a fit is evaluated at four
//! points a sample (the sample and its three finite-difference neighbours),
//! forward and back to the points; the hash grid and the SDF MLP there were
//! about half of a fit's time (profile notebook), where a lookup reads eight
//! lattice points. The normals are baked too (the network's own
//! finite-difference gradient at each lattice point, interpolated): normals
//! taken from differences of the interpolated SDF are smoothed over the
//! lattice's step, which drew a trained body's silhouette thinner and its
//! colours off (the fit's body sat nearer the camera). Only for fields that
//! no longer train: nothing flows back to the network's parameters.

use crate::fd_samples::SAMPLE_CHUNK;
use crate::neus_field::NeusField;
use crate::occupancy::OccupancyGrid;
use field::MlpScratch;
use rayon::prelude::*;

/// Cell index where a cell has no brick.
const NONE: u32 = u32::MAX;
/// A lattice point's record: the SDF, the normal gradient (3), the curvature (3), then the features.
const SDF: usize = 0;
const GRAD: usize = 1;
const CURVATURE: usize = 4;
const FEATURES: usize = 7;

/// The baked SDF and features of one field (unit coordinates, as the field's).
pub struct BakedGeometry {
    res: usize,
    sub: usize,
    feature_dim: usize,
    /// `res³` entries (x fastest): the cell's brick, or [`NONE`].
    brick_of_cell: Vec<u32>,
    /// Per brick, `(sub + 1)³` lattice points (x fastest), each one record of `FEATURES + feature_dim`
    /// floats, so that a lookup's eight corners are eight short runs of memory (kept as four arrays they
    /// were some thirty cache lines a lookup, and the lookups a third of a fit's time):
    /// - the SDF;
    /// - the network's SDF gradient as its renderer takes it (forward differences at the render's step): a
    ///   lookup's normal is their trilinear mix, continuous across the lattice;
    /// - half the SDF's second difference along x, y and z (`h² ∂²s/∂x_k² / 2`). Trilinear interpolation of a
    ///   surface curving at radius `R` misses it by up to `h² / 8R` — outward for a convex one: the demo's toy
    ///   rendered 0.07 % less opaque at four steps a cell, which a fit reads as the body 0.2 mm nearer the
    ///   camera. The lookup takes `Σ_k w_k (1 − w_k)` times these (interpolated) off: exact for a quadratic
    ///   SDF, the lattice points' own values at lattice points, continuous across the lattice cells' faces (a
    ///   face's points are the same in the bricks either side);
    /// - the `feature_dim` features.
    lattice: Vec<f32>,
    /// The SDF given where no brick is: a cell's width, empty space (no sample of the occupancy's marching
    /// lands there).
    outside: f32,
}

/// Where a point falls: its brick's first lattice point, the lower corner's offset in the brick, the
/// weights along x, y, z.
#[derive(Clone, Copy)]
struct Lookup {
    brick: usize,
    corner: usize,
    w: [f32; 3],
}

/// One bake job's buffers (see [`BakedGeometry::bake`]).
#[derive(Default)]
struct BakeScratch {
    unit01: Vec<f32>,
    enc: Vec<f32>,
    input: Vec<f32>,
    mlp: MlpScratch,
    four: Vec<f32>,
}

impl BakedGeometry {
    /// Bake `field` (all levels) in `occupancy`'s occupied cells (a sample lies in one: the march keeps no
    /// other), `sub` lattice steps a cell, its normals from forward differences `fd_eps` apart (as the
    /// renderer takes the network's).
    pub fn bake(field: &NeusField, occupancy: &OccupancyGrid, sub: usize, fd_eps: f32) -> Self {
        assert!(sub >= 1, "BakedGeometry::bake: at least one step a cell");
        assert!(fd_eps > 0.0, "BakedGeometry::bake: a positive difference step");
        let res = occupancy.res;
        let cells = occupancy.cells();
        let mut brick_of_cell = vec![NONE; res * res * res];
        let mut bricks: Vec<[usize; 3]> = Vec::new();
        for k in 0..res {
            for j in 0..res {
                for i in 0..res {
                    let c = (k * res + j) * res + i;
                    if cells[c] != 0 {
                        brick_of_cell[c] = bricks.len() as u32;
                        bricks.push([i, j, k]);
                    }
                }
            }
        }
        let side = sub + 1;
        let per = side * side * side;
        let h = 2.0 / (res * sub) as f32;
        // Bricks share the lattice points on their faces: each point is evaluated once, in the brick of the
        // highest cell that holds it (its coordinates there the lowest), and copied to the others.
        let owner = |b: &[usize; 3], local: [usize; 3]| -> usize {
            let global: [usize; 3] = std::array::from_fn(|k| b[k] * sub + local[k]);
            for choice in 0..8 {
                let mut cell = [0usize; 3];
                let mut at = [0usize; 3];
                let mut ok = true;
                for k in 0..3 {
                    let (c, l) = (global[k] / sub, global[k] % sub);
                    // Bit k of `choice`: the cell below, whose far face the point is on.
                    let below = choice >> k & 1 == 1;
                    let (c, l) = if below { (c.wrapping_sub(1), sub) } else { (c, l) };
                    if c >= res || (below && !global[k].is_multiple_of(sub)) {
                        ok = false;
                        break;
                    }
                    cell[k] = c;
                    at[k] = l;
                }
                if !ok {
                    continue;
                }
                let brick = brick_of_cell[(cell[2] * res + cell[1]) * res + cell[0]];
                if brick != NONE {
                    return brick as usize * per + (at[2] * side + at[1]) * side + at[0];
                }
            }
            unreachable!("a brick's point lies in its own brick")
        };
        let mut slot_of = Vec::with_capacity(bricks.len() * per);
        let mut points = Vec::new();
        let mut unique = 0usize;
        for (bi, b) in bricks.iter().enumerate() {
            for z in 0..side {
                for y in 0..side {
                    for x in 0..side {
                        let own = bi * per + (z * side + y) * side + x;
                        let o = owner(b, [x, y, z]);
                        if o == own {
                            let lattice = [b[0] * sub + x, b[1] * sub + y, b[2] * sub + z];
                            points.extend(lattice.map(|l| -1.0 + l as f32 * h));
                            slot_of.push(unique);
                            unique += 1;
                        } else {
                            // Its owner's slot once every owner has one (below).
                            slot_of.push(usize::MAX - o);
                        }
                    }
                }
            }
        }
        for i in 0..slot_of.len() {
            if slot_of[i] >= unique {
                slot_of[i] = slot_of[usize::MAX - slot_of[i]];
            }
        }
        let fdim = field.config.feature_dim;
        let width = 1 + fdim;
        let levels = field.config.grid.levels;
        let mut u_sdf = vec![0.0f32; unique];
        let mut u_features = vec![0.0f32; unique * fdim];
        let mut u_grad = vec![[0.0f32; 3]; unique];
        const BAKE_CHUNK: usize = 8192;
        points
            .par_chunks(BAKE_CHUNK * 3)
            .zip(u_sdf.par_chunks_mut(BAKE_CHUNK))
            .zip(u_features.par_chunks_mut(BAKE_CHUNK * fdim.max(1)))
            .zip(u_grad.par_chunks_mut(BAKE_CHUNK))
            // The buffers live as long as a rayon job, not a chunk: a chunk's are tens of megabytes, and
            // fresh ones cost their page faults (a third of the bake).
            .for_each_init(BakeScratch::default, |b, (((p, s), f), g)| {
                let BakeScratch {
                    unit01,
                    enc,
                    input,
                    mlp,
                    four,
                } = b;
                // Each point, then it moved by the step along x, y and z, side by side (the four share
                // their coarser hash cells).
                four.clear();
                for q in p.chunks_exact(3) {
                    four.extend_from_slice(q);
                    for k in 0..3 {
                        let mut moved = [q[0], q[1], q[2]];
                        moved[k] += fd_eps;
                        four.extend(moved);
                    }
                }
                let out = field.sdf_forward(four, levels, unit01, enc, input, mlp);
                for (r, rows) in out.chunks_exact(4 * width).enumerate() {
                    let row = &rows[..width];
                    s[r] = row[0];
                    f[r * fdim..(r + 1) * fdim].copy_from_slice(&row[1..]);
                    g[r] = std::array::from_fn(|k| (rows[(k + 1) * width] - row[0]) / fd_eps);
                }
            });
        let sdf: Vec<f32> = slot_of.iter().map(|&u| u_sdf[u]).collect();
        Self::from_parts(
            (res, sub, fdim),
            brick_of_cell,
            &sdf,
            |i| u_grad[slot_of[i]],
            |i| &u_features[slot_of[i] * fdim..(slot_of[i] + 1) * fdim],
            occupancy.cell_size(),
        )
    }

    /// The lattice from its values per lattice point (`grad(i)`, `features(i)` of lattice point `i`, whose
    /// SDF is `sdf[i]`), the curvature taken from the SDF's.
    fn from_parts<'a>(
        (res, sub, feature_dim): (usize, usize, usize),
        brick_of_cell: Vec<u32>,
        sdf: &[f32],
        grad: impl Fn(usize) -> [f32; 3],
        features: impl Fn(usize) -> &'a [f32],
        outside: f32,
    ) -> Self {
        let curvature = half_second_differences(sdf, sub);
        let mut lattice = Vec::with_capacity(sdf.len() * (FEATURES + feature_dim));
        for (i, &v) in sdf.iter().enumerate() {
            lattice.push(v);
            lattice.extend_from_slice(&grad(i));
            lattice.extend_from_slice(&curvature[i]);
            let f = features(i);
            assert_eq!(f.len(), feature_dim, "BakedGeometry: a lattice point's features");
            lattice.extend_from_slice(f);
        }
        Self {
            res,
            sub,
            feature_dim,
            brick_of_cell,
            lattice,
            outside,
        }
    }

    /// Lattice point `i`'s record (see [`Self::lattice`]'s fields).
    #[inline]
    fn record(&self, i: usize) -> &[f32] {
        let r = FEATURES + self.feature_dim;
        &self.lattice[i * r..(i + 1) * r]
    }

    /// Bricks baked.
    pub fn bricks(&self) -> usize {
        self.lattice.len() / ((FEATURES + self.feature_dim) * (self.sub + 1).pow(3))
    }

    /// Memory the lattice holds, bytes.
    pub fn bytes(&self) -> usize {
        4 * (self.lattice.len() + self.brick_of_cell.len())
    }

    /// The lattice's step, unit coordinates.
    pub fn step(&self) -> f32 {
        2.0 / (self.res * self.sub) as f32
    }

    /// Output row width: the SDF, then the features (as the SDF MLP's).
    pub fn width(&self) -> usize {
        1 + self.feature_dim
    }

    #[inline]
    fn locate(&self, p: &[f32]) -> Option<Lookup> {
        let r = self.res as f32;
        let side = self.sub + 1;
        let mut cell = [0usize; 3];
        let mut voxel = [0usize; 3];
        let mut w = [0.0f32; 3];
        for k in 0..3 {
            let g = (p[k] + 1.0) * 0.5 * r;
            // In [0, r) the cast truncates as `floor` would (see `OccupancyGrid::occupied`); the far face
            // belongs to the last cell.
            if !(0.0..=r).contains(&g) {
                return None;
            }
            let c = (g as usize).min(self.res - 1);
            let f = ((g - c as f32) * self.sub as f32).min(self.sub as f32);
            let v = (f.max(0.0) as usize).min(self.sub - 1);
            cell[k] = c;
            voxel[k] = v;
            w[k] = (f - v as f32).clamp(0.0, 1.0);
        }
        let brick = self.brick_of_cell[(cell[2] * self.res + cell[1]) * self.res + cell[0]];
        (brick != NONE).then(|| Lookup {
            brick: brick as usize * side * side * side,
            corner: (voxel[2] * side + voxel[1]) * side + voxel[0],
            w,
        })
    }

    /// The eight lattice points around a lookup and their weights, in the hash grid's corner order (x fastest).
    #[inline]
    fn corners(&self, l: &Lookup) -> ([usize; 8], [f32; 8]) {
        let side = self.sub + 1;
        let (dy, dz) = (side, side * side);
        let base = l.brick + l.corner;
        let idx = [
            base,
            base + 1,
            base + dy,
            base + dy + 1,
            base + dz,
            base + dz + 1,
            base + dz + dy,
            base + dz + dy + 1,
        ];
        (idx, field::kernels::weights(l.w))
    }

    /// The weights' derivatives along x, y, z (per lattice step).
    #[inline]
    fn corner_slopes(w: [f32; 3]) -> [[f32; 8]; 3] {
        let [x, y, z] = w;
        let (ox, oy, oz) = (1.0 - x, 1.0 - y, 1.0 - z);
        [
            [-oy * oz, oy * oz, -y * oz, y * oz, -oy * z, oy * z, -y * z, y * z],
            [-ox * oz, -x * oz, ox * oz, x * oz, -ox * z, -x * z, ox * z, x * z],
            [-ox * oy, -x * oy, -ox * y, -x * y, ox * oy, x * oy, ox * y, x * y],
        ]
    }

    /// The SDF at a lookup: the corners' trilinear mix less the interpolated curvature at the point's weights.
    #[inline]
    fn sdf_at(&self, l: &Lookup, idx: &[usize; 8], wt: &[f32; 8]) -> f32 {
        let q = l.w.map(|w| w * (1.0 - w));
        (0..8)
            .map(|i| {
                let v = self.record(idx[i]);
                let k = &v[CURVATURE..CURVATURE + 3];
                wt[i] * (v[SDF] - q[0] * k[0] - q[1] * k[1] - q[2] * k[2])
            })
            .sum()
    }

    /// The gradient in the looked-up point (unit coordinates; its corners and weights from [`Self::corners`])
    /// of `d_sdf` times its SDF, plus `d_features` (when given) dotted with its features, plus `d_grad` dotted
    /// with its interpolated normal gradient.
    fn point_gradient(
        &self,
        (l, idx, wt): (&Lookup, &[usize; 8], &[f32; 8]),
        d_sdf: f32,
        d_features: Option<&[f32]>,
        d_grad: [f32; 3],
    ) -> [f32; 3] {
        let slopes = Self::corner_slopes(l.w);
        // The curvature's weights w_k (1 − w_k), and its interpolated values.
        let q = l.w.map(|w| w * (1.0 - w));
        let c: [f32; 3] = std::array::from_fn(|k| (0..8).map(|i| wt[i] * self.record(idx[i])[CURVATURE + k]).sum());
        // d(out)/d(corner value) · the corner's value, summed over the outputs read (the SDF's corner value
        // with its curvature taken off at the point's weights).
        let mut dv = [0.0f32; 8];
        for i in 0..8 {
            let v = self.record(idx[i]);
            let (k, g) = (&v[CURVATURE..CURVATURE + 3], &v[GRAD..GRAD + 3]);
            dv[i] = d_sdf * (v[SDF] - q[0] * k[0] - q[1] * k[1] - q[2] * k[2])
                + d_grad[0] * g[0]
                + d_grad[1] * g[1]
                + d_grad[2] * g[2];
        }
        if let Some(d) = d_features {
            for i in 0..8 {
                let f = &self.record(idx[i])[FEATURES..];
                dv[i] += d.iter().zip(f).map(|(a, b)| a * b).sum::<f32>();
            }
        }
        // Unit coordinates to lattice steps.
        let scale = 0.5 * (self.res * self.sub) as f32;
        std::array::from_fn(|k| {
            let own = -d_sdf * (1.0 - 2.0 * l.w[k]) * c[k];
            scale * ((0..8).map(|i| slopes[k][i] * dv[i]).sum::<f32>() + own)
        })
    }

    /// A finite-difference pass's outputs at `points` (four blocks of `m` points, as
    /// [`crate::field_pass::FieldPass`] lays them out: each sample `p`, then `q_k = p + e e_k` for k = x, y, z):
    /// rows of [`Self::width`] into `out`, the features only in the first block (the neighbours' are zero).
    ///
    /// A neighbour's row holds `s(p) + (q_k − p)_k n_k(p)`, with `n` the baked normal gradient interpolated at
    /// the sample, so that the pass's difference `(row_k − s(p)) / e` is the network's gradient as the lattice
    /// holds it, whatever the step: the neighbours' points are not read.
    pub fn forward_fd(&self, points: &[f32], m: usize, out: &mut Vec<f32>) {
        let width = self.width();
        assert_eq!(
            points.len(),
            4 * m * 3,
            "BakedGeometry::forward_fd: four blocks of m points"
        );
        out.clear();
        out.resize(4 * m * width, 0.0);
        let (b0, rest) = out.split_at_mut(m * width);
        let (b1, rest) = rest.split_at_mut(m * width);
        let (b2, b3) = rest.split_at_mut(m * width);
        b0.par_chunks_mut(SAMPLE_CHUNK * width)
            .zip(b1.par_chunks_mut(SAMPLE_CHUNK * width))
            .zip(b2.par_chunks_mut(SAMPLE_CHUNK * width))
            .zip(b3.par_chunks_mut(SAMPLE_CHUNK * width))
            .enumerate()
            .for_each(|(c, (((r0, r1), r2), r3))| {
                let mut neighbours = [r1, r2, r3];
                for (r, row) in r0.chunks_exact_mut(width).enumerate() {
                    let s = c * SAMPLE_CHUNK + r;
                    let p = &points[s * 3..s * 3 + 3];
                    let Some(l) = self.locate(p) else {
                        row[0] = self.outside;
                        for block in neighbours.iter_mut() {
                            block[r * width] = self.outside;
                        }
                        continue;
                    };
                    let (idx, wt) = self.corners(&l);
                    let mut n = [0.0f32; 3];
                    for i in 0..8 {
                        let v = self.record(idx[i]);
                        for (o, f) in row[1..].iter_mut().zip(&v[FEATURES..]) {
                            *o += wt[i] * f;
                        }
                        for (nk, gk) in n.iter_mut().zip(&v[GRAD..GRAD + 3]) {
                            *nk += wt[i] * gk;
                        }
                    }
                    let here = self.sdf_at(&l, &idx, &wt);
                    row[0] = here;
                    for (k, block) in neighbours.iter_mut().enumerate() {
                        let e = points[((k + 1) * m + s) * 3 + k] - p[k];
                        block[r * width] = here + e * n[k];
                    }
                }
            });
    }

    /// Backward of [`Self::forward_fd`] to the points: `d_points` (4m × 3, overwritten) from the rows'
    /// gradients `d_out` (4m × width), each row's point moved alone (a neighbour's row reads its sample's
    /// point too, and its own only through its offset `e`).
    pub fn backward_fd_points(&self, points: &[f32], m: usize, d_out: &[f32], d_points: &mut [f32]) {
        let width = self.width();
        assert_eq!(d_out.len(), 4 * m * width, "BakedGeometry::backward_fd_points: 4m rows");
        assert_eq!(
            d_points.len(),
            4 * m * 3,
            "BakedGeometry::backward_fd_points: 4m points"
        );
        let (g0, rest) = d_points.split_at_mut(m * 3);
        let (g1, rest) = rest.split_at_mut(m * 3);
        let (g2, g3) = rest.split_at_mut(m * 3);
        g0.par_chunks_mut(SAMPLE_CHUNK * 3)
            .zip(g1.par_chunks_mut(SAMPLE_CHUNK * 3))
            .zip(g2.par_chunks_mut(SAMPLE_CHUNK * 3))
            .zip(g3.par_chunks_mut(SAMPLE_CHUNK * 3))
            .enumerate()
            .for_each(|(c, (((q0, q1), q2), q3))| {
                let mut neighbours = [q1, q2, q3];
                for (r, g) in q0.chunks_exact_mut(3).enumerate() {
                    let s = c * SAMPLE_CHUNK + r;
                    let p = &points[s * 3..s * 3 + 3];
                    for block in neighbours.iter_mut() {
                        block[r * 3..r * 3 + 3].fill(0.0);
                    }
                    let Some(l) = self.locate(p) else {
                        g.fill(0.0);
                        continue;
                    };
                    let d = &d_out[s * width..(s + 1) * width];
                    let d_nb: [f32; 3] = std::array::from_fn(|k| d_out[((k + 1) * m + s) * width]);
                    let e: [f32; 3] = std::array::from_fn(|k| points[((k + 1) * m + s) * 3 + k] - p[k]);
                    let (idx, wt) = self.corners(&l);
                    let n: [f32; 3] =
                        std::array::from_fn(|k| (0..8).map(|i| wt[i] * self.record(idx[i])[GRAD + k]).sum());
                    // Row k = s(p) + (q_k − p)_k n_k(p): s(p) is read by every row, n_k(p) by row k.
                    let d_grad: [f32; 3] = std::array::from_fn(|k| d_nb[k] * e[k]);
                    let mut sum =
                        self.point_gradient((&l, &idx, &wt), d[0] + d_nb.iter().sum::<f32>(), Some(&d[1..]), d_grad);
                    for (k, block) in neighbours.iter_mut().enumerate() {
                        block[r * 3 + k] = d_nb[k] * n[k];
                        sum[k] -= d_nb[k] * n[k];
                    }
                    g.copy_from_slice(&sum);
                }
            });
    }
}

/// Half the second difference of `sdf` along x, y, z at every lattice point of every brick (`sub` steps a
/// side): central inside a brick, at a brick's faces the one a step inward (a brick's points are all it
/// has); zero with a single step.
fn half_second_differences(sdf: &[f32], sub: usize) -> Vec<[f32; 3]> {
    let side = sub + 1;
    let per = side * side * side;
    let stride = [1, side, side * side];
    let mut out = vec![[0.0f32; 3]; sdf.len()];
    if sub < 2 {
        return out;
    }
    for (brick, vals) in sdf.chunks_exact(per).enumerate() {
        for z in 0..side {
            for y in 0..side {
                for x in 0..side {
                    let at = [x, y, z];
                    let here = (z * side + y) * side + x;
                    for k in 0..3 {
                        // The centre of the three points: this one unless it is on a face.
                        let centre = here - stride[k] * at[k] + stride[k] * at[k].clamp(1, sub - 1);
                        let d2 = vals[centre - stride[k]] - 2.0 * vals[centre] + vals[centre + stride[k]];
                        out[brick * per + here][k] = 0.5 * d2;
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::neus_field::FieldConfig;

    /// A field whose occupancy holds a shell around its zero level (as a trained object's does).
    fn field_and_shell() -> (NeusField, OccupancyGrid) {
        let field = NeusField::new(&FieldConfig::default(), 3, 0.0);
        let res = 16;
        let mut occ = OccupancyGrid::full(res);
        let idx: Vec<usize> = (0..res * res * res).collect();
        let centres: Vec<f32> = idx.iter().flat_map(|&i| occ.centre(i)).collect();
        let sdf = field.sdf_values(&centres, field.config.grid.levels);
        occ.update(&idx, &sdf, 2.0 * occ.cell_size());
        (field, occ)
    }

    /// Points inside the shell's cells, four blocks as a finite-difference pass makes them.
    fn fd_points(occ: &OccupancyGrid, m: usize, eps: f32) -> Vec<f32> {
        let occupied: Vec<usize> = (0..occ.cells().len()).filter(|&i| occ.cells()[i] != 0).collect();
        assert!(occupied.len() > 20, "a shell: {} cells", occupied.len());
        let h = occ.cell_size();
        let mut base = Vec::new();
        for s in 0..m {
            let c = occ.centre(occupied[(s * 7919) % occupied.len()]);
            let jitter = [0.37, -0.21, 0.11].map(|j: f32| j * h * ((s % 5) as f32 - 2.0) / 2.0);
            base.push([c[0] + jitter[0], c[1] + jitter[1], c[2] + jitter[2]]);
        }
        let mut pts = Vec::with_capacity(4 * m * 3);
        for b in 0..4 {
            for p in &base {
                let mut q = *p;
                if b > 0 {
                    q[b - 1] += eps;
                }
                pts.extend_from_slice(&q);
            }
        }
        pts
    }

    /// The network's step for its normals, as the renderer takes it.
    fn eps_of(field: &NeusField) -> f32 {
        field.config.grid.finest_cell()
    }

    /// The network's SDF at `points` and its forward-difference gradient `eps` apart, as the renderer takes it.
    fn network_with_gradient(field: &NeusField, points: &[f32], eps: f32) -> (Vec<f32>, Vec<[f32; 3]>) {
        let levels = field.config.grid.levels;
        let here = field.sdf_values(points, levels);
        let moved: Vec<Vec<f32>> = (0..3)
            .map(|k| {
                let q: Vec<f32> = points
                    .chunks_exact(3)
                    .flat_map(|p| std::array::from_fn::<f32, 3, _>(|j| p[j] + if j == k { eps } else { 0.0 }))
                    .collect();
                field.sdf_values(&q, levels)
            })
            .collect();
        let grad = (0..here.len())
            .map(|r| std::array::from_fn(|k| (moved[k][r] - here[r]) / eps))
            .collect();
        (here, grad)
    }

    /// At lattice points the bake gives the network's values, features and normal gradient.
    #[test]
    fn the_lattice_holds_the_networks_values() {
        let (field, occ) = field_and_shell();
        let eps = eps_of(&field);
        let baked = BakedGeometry::bake(&field, &occ, 4, eps);
        let m = 64;
        // Lattice points: a whole multiple of the lattice step; the neighbours a lattice step away.
        let h = baked.step();
        let pts = fd_points(&occ, m, h);
        let snapped: Vec<f32> = pts.iter().map(|v| ((v + 1.0) / h).round() * h - 1.0).collect();
        let mut out = Vec::new();
        baked.forward_fd(&snapped, m, &mut out);
        let width = baked.width();
        let (mut u, mut e, mut i) = (vec![], vec![], vec![]);
        let mut sc = MlpScratch::default();
        let net = field
            .sdf_forward(
                &snapped[..3 * m],
                field.config.grid.levels,
                &mut u,
                &mut e,
                &mut i,
                &mut sc,
            )
            .to_vec();
        let (_, grad) = network_with_gradient(&field, &snapped[..3 * m], eps);
        for r in 0..4 * m {
            let s = r % m;
            let want = if r < m {
                net[s * width]
            } else {
                let k = r / m - 1;
                net[s * width] + (snapped[r * 3 + k] - snapped[s * 3 + k]) * grad[s][k]
            };
            assert!(
                (out[r * width] - want).abs() < 1e-5,
                "row {r}: SDF {} against {want}",
                out[r * width]
            );
            if r < m {
                for f in 1..width {
                    assert!(
                        (out[r * width + f] - net[r * width + f]).abs() < 1e-5,
                        "row {r}: feature {f}"
                    );
                }
            } else {
                assert!(out[r * width + 1..(r + 1) * width].iter().all(|&v| v == 0.0));
            }
        }
    }

    /// For a quadratic SDF the lookup is exact between lattice points too (the curvature's correction; its
    /// gradient, linear, interpolates exactly), and the plain trilinear mix is not.
    #[test]
    fn a_quadratic_sdf_is_interpolated_exactly() {
        let (res, sub) = (2usize, 4usize);
        let f = |p: [f32; 3]| {
            3.0 * (p[0] + 0.6) * (p[0] + 0.6) + 2.0 * (p[1] + 0.7) * (p[1] + 0.7) - (p[2] + 0.4) * (p[2] + 0.4)
                + 0.5 * p[0] * p[1]
                - 0.2
        };
        let grad_f = |p: [f32; 3]| {
            [
                6.0 * (p[0] + 0.6) + 0.5 * p[1],
                4.0 * (p[1] + 0.7) + 0.5 * p[0],
                -2.0 * (p[2] + 0.4),
            ]
        };
        let side = sub + 1;
        let h = 2.0 / (res * sub) as f32;
        let (mut sdf, mut grad) = (Vec::new(), Vec::new());
        for z in 0..side {
            for y in 0..side {
                for x in 0..side {
                    let p = [x, y, z].map(|l| -1.0 + l as f32 * h);
                    sdf.push(f(p));
                    grad.push(grad_f(p));
                }
            }
        }
        let mut brick_of_cell = vec![NONE; res * res * res];
        brick_of_cell[0] = 0;
        let baked = BakedGeometry::from_parts((res, sub, 0), brick_of_cell, &sdf, |i| grad[i], |_| &[], 1.0);
        let m = 50;
        let eps = 0.05;
        let mut samples = Vec::new();
        for s in 0..m {
            let t = s as f32 * 0.618_034;
            samples.push([t.fract(), (t * 1.7).fract(), (t * 2.3).fract()].map(|u| -1.0 + 0.999 * u));
        }
        let mut pts = Vec::new();
        for b in 0..4 {
            for p in &samples {
                let mut q = *p;
                if b > 0 {
                    q[b - 1] += eps;
                }
                pts.extend(q);
            }
        }
        let mut out = Vec::new();
        baked.forward_fd(&pts, m, &mut out);
        let mut plain_worst = 0.0f32;
        for r in 0..4 * m {
            let (s, p) = (r % m, samples[r % m]);
            let want = if r < m { f(p) } else { f(p) + eps * grad_f(p)[r / m - 1] };
            assert!((out[r] - want).abs() < 2e-5, "point {r}: {} against {want}", out[r]);
            if r < m {
                let l = baked.locate(&pts[3 * s..3 * s + 3]).expect("inside the brick");
                let (idx, wt) = baked.corners(&l);
                let plain: f32 = (0..8).map(|i| wt[i] * baked.record(idx[i])[SDF]).sum();
                plain_worst = plain_worst.max((plain - want).abs());
            }
        }
        assert!(plain_worst > 1e-3, "the plain mix misses the curvature: {plain_worst}");
    }

    /// The baked SDF and normals stay near the network's between lattice points (the field is smooth at the
    /// lattice's scale).
    #[test]
    fn the_baked_sdf_is_near_the_networks_between_lattice_points() {
        let (field, occ) = field_and_shell();
        let baked = BakedGeometry::bake(&field, &occ, 4, eps_of(&field));
        let m = 200;
        let pts = fd_points(&occ, m, 1e-3);
        let mut out = Vec::new();
        baked.forward_fd(&pts, m, &mut out);
        let net = field.sdf_values(&pts, field.config.grid.levels);
        let worst = (0..4 * m)
            .map(|r| (out[r * baked.width()] - net[r]).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 0.02 * occ.cell_size().max(0.05), "worst SDF difference {worst}");
    }

    /// The points' gradient matches central differences of a weighted sum of the outputs.
    #[test]
    fn point_gradients_match_central_differences() {
        let (field, occ) = field_and_shell();
        let baked = BakedGeometry::bake(&field, &occ, 3, eps_of(&field));
        let m = 40;
        let pts = fd_points(&occ, m, 1e-3);
        let width = baked.width();
        let weights: Vec<f32> = (0..4 * m * width)
            .map(|i| {
                let row = i / width;
                if row >= m && i % width != 0 {
                    0.0
                } else {
                    ((i * 37 % 11) as f32 - 5.0) / 5.0
                }
            })
            .collect();
        let loss = |p: &[f32]| {
            let mut o = Vec::new();
            baked.forward_fd(p, m, &mut o);
            o.iter()
                .zip(&weights)
                .map(|(a, b)| (*a as f64) * (*b as f64))
                .sum::<f64>()
        };
        let mut grad = vec![0.0f32; 4 * m * 3];
        baked.backward_fd_points(&pts, m, &weights, &mut grad);
        // A step well inside a lattice cell (the interpolant is piecewise smooth), for samples not on a face.
        let h = 1e-4f32;
        let mut checked = 0;
        for (j, &g) in grad.iter().enumerate() {
            let sample = pts[(j / 3 % m) * 3 + j % 3];
            let frac = ((sample + 1.0) / baked.step()).fract();
            if !(0.05..0.95).contains(&frac) {
                continue;
            }
            let (mut up, mut down) = (pts.clone(), pts.clone());
            up[j] += h;
            down[j] -= h;
            let fd = (loss(&up) - loss(&down)) / (2.0 * h as f64);
            let tol = 2e-2 * fd.abs().max(1.0);
            assert!((g as f64 - fd).abs() < tol, "coordinate {j}: {g} against {fd}");
            checked += 1;
        }
        assert!(checked > 300, "only {checked} coordinates checked");
    }

    /// Outside every brick: the empty-space SDF, no features, no gradient.
    #[test]
    fn outside_the_bricks_is_empty_space() {
        let field = NeusField::new(&FieldConfig::default(), 3, 0.0);
        let mut cells = vec![0u8; 8 * 8 * 8];
        cells[0] = 1;
        let occ = OccupancyGrid::from_cells(8, cells);
        let baked = BakedGeometry::bake(&field, &occ, 2, eps_of(&field));
        assert_eq!(baked.bricks(), 1, "the occupied cell alone");
        let far = [0.9f32, 0.9, 0.9];
        let pts: Vec<f32> = (0..4).flat_map(|_| far).collect();
        let mut out = Vec::new();
        baked.forward_fd(&pts, 1, &mut out);
        assert_eq!(out[0], occ.cell_size());
        assert!(out[1..baked.width()].iter().all(|&v| v == 0.0));
        let mut g = vec![1.0f32; 12];
        baked.backward_fd_points(&pts, 1, &vec![1.0; 4 * baked.width()], &mut g);
        assert!(g.iter().all(|&v| v == 0.0));
    }
}
