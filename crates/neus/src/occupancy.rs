//! Empty-space skipping (as NeuS2 and instant-nsr-pl do): a grid over the
//! unit cube marks cells whose SDF is within reach of the surface; samples
//! are taken only there. Refreshed from the field during training.

use std::sync::OnceLock;

/// Occupancy of `res³` cells covering [-1, 1]³.
#[derive(Clone, Debug)]
pub struct OccupancyGrid {
    pub res: usize,
    /// 1 = may hold surface.
    cells: Vec<u8>,
    /// [`Self::bounding_sphere`], computed on first use and dropped by every change of the cells: a posed
    /// object's layer asks for it at every step of a pose fit, and two scans of an object's 64³ cells at
    /// every step were 1 % of a fit.
    bound: OnceLock<Option<([f32; 3], f32)>>,
}

impl OccupancyGrid {
    /// Everything occupied (the field is unknown).
    pub fn full(res: usize) -> Self {
        Self::from_cells(res, vec![1; res * res * res])
    }

    /// The grid of `cells` (`res³` of them, x fastest; non-zero = may hold surface).
    pub fn from_cells(res: usize, cells: Vec<u8>) -> Self {
        assert_eq!(cells.len(), res * res * res, "OccupancyGrid::from_cells: {res}³ cells");
        Self {
            res,
            cells,
            bound: OnceLock::new(),
        }
    }

    /// The cells, x fastest (non-zero = may hold surface).
    pub fn cells(&self) -> &[u8] {
        &self.cells
    }

    pub fn cell_size(&self) -> f32 {
        2.0 / self.res as f32
    }

    /// Centre of cell `idx` in unit coordinates.
    pub fn centre(&self, idx: usize) -> [f32; 3] {
        let r = self.res;
        let (i, j, k) = (idx % r, (idx / r) % r, idx / (r * r));
        let h = self.cell_size();
        [i, j, k].map(|c| -1.0 + (c as f32 + 0.5) * h)
    }

    #[inline]
    pub fn occupied(&self, p: [f32; 3]) -> bool {
        self.cell_at(p).is_some_and(|(_, idx)| self.cells[idx] != 0)
    }

    /// The cell coordinates of `p` (in cells, `[0, res)` on each axis) and its cell's index; `None` outside
    /// the grid.
    #[inline]
    fn cell_at(&self, p: [f32; 3]) -> Option<([f32; 3], usize)> {
        let r = self.res as f32;
        let g = p.map(|c| (c + 1.0) * 0.5 * r);
        // In [0, r) the cast truncates as `floor` would, and x ∈ [0, r) ⇔ ⌊x⌋ ∈ [0, r) for an integer r:
        // without SSE4.1 `floor` is a libm call, a tenth of a pose fit's time.
        if g.iter().any(|v| !(0.0..r).contains(v)) {
            return None;
        }
        Some((g, g[0] as usize + self.res * (g[1] as usize + self.res * g[2] as usize)))
    }

    /// Set cells from SDF values at their centres: occupied when `|sdf| ≤ band`.
    pub fn update(&mut self, indices: &[usize], sdf: &[f32], band: f32) {
        for (&i, &s) in indices.iter().zip(sdf) {
            self.cells[i] = u8::from(s.abs() <= band);
        }
        self.bound = OnceLock::new();
    }

    /// A sphere (unit coordinates) holding every occupied cell whole, `None` when none is occupied.
    pub fn bounding_sphere(&self) -> Option<([f32; 3], f32)> {
        *self.bound.get_or_init(|| self.scan_bounding_sphere())
    }

    fn scan_bounding_sphere(&self) -> Option<([f32; 3], f32)> {
        let r = self.res;
        let (mut lo, mut hi) = ([usize::MAX; 3], [0usize; 3]);
        for (idx, _) in self.cells.iter().enumerate().filter(|(_, &c)| c != 0) {
            let ijk = [idx % r, (idx / r) % r, idx / (r * r)];
            for k in 0..3 {
                lo[k] = lo[k].min(ijk[k]);
                hi[k] = hi[k].max(ijk[k]);
            }
        }
        if lo[0] == usize::MAX {
            return None;
        }
        let h = self.cell_size();
        let centre = [0, 1, 2].map(|k| -1.0 + 0.5 * (lo[k] + hi[k] + 1) as f32 * h);
        // The farthest occupied cell's centre plus half a cell's diagonal, a hair wider: f32 rounding must
        // not drop a ray that grazes a corner cell.
        let far = (0..self.cells.len())
            .filter(|&i| self.cells[i] != 0)
            .map(|i| {
                let c = self.centre(i);
                (0..3).map(|k| (c[k] - centre[k]).powi(2)).sum::<f32>()
            })
            .fold(0.0f32, f32::max)
            .sqrt();
        let radius = (far + 0.5 * h * 3f32.sqrt()) * (1.0 + 1e-4) + 1e-5;
        Some((centre, radius))
    }

    /// How many cells are occupied.
    pub fn occupied_cells(&self) -> usize {
        self.cells.iter().filter(|&&c| c != 0).count()
    }

    /// Fraction of occupied cells.
    pub fn occupied_fraction(&self) -> f32 {
        self.occupied_cells() as f32 / self.cells.len() as f32
    }

    /// For every cell (x fastest), whether an occupied cell lies within `radius` cells of it along each axis
    /// (a cube of side 2·radius + 1 about it): a max filter along x, then y, then z.
    pub fn near_occupied(&self, radius: usize) -> Vec<bool> {
        let r = self.res;
        let mut near: Vec<bool> = self.cells.iter().map(|&c| c != 0).collect();
        let mut line = vec![false; r];
        let mut dist_before = vec![usize::MAX; r];
        for (axis_stride, outer) in [(1, [r, r * r]), (r, [1, r * r]), (r * r, [1, r])] {
            for a in 0..r {
                for b in 0..r {
                    let first = a * outer[0] + b * outer[1];
                    for (i, v) in line.iter_mut().enumerate() {
                        *v = near[first + i * axis_stride];
                    }
                    // Cells to the last occupied one before and the next after, within the radius.
                    let mut last = None::<usize>;
                    for (i, &v) in line.iter().enumerate() {
                        if v {
                            last = Some(i);
                        }
                        dist_before[i] = last.map_or(usize::MAX, |l| i - l);
                    }
                    let mut next = None::<usize>;
                    for i in (0..r).rev() {
                        if line[i] {
                            next = Some(i);
                        }
                        let after = next.map_or(usize::MAX, |n| n - i);
                        near[first + i * axis_stride] = dist_before[i].min(after) <= radius;
                    }
                }
            }
        }
        near
    }
}

/// Where a ray enters and leaves the unit sphere (`None` if it misses).
#[inline]
pub fn sphere_span(o: [f32; 3], d: [f32; 3]) -> Option<(f32, f32)> {
    let b = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
    let c = o[0] * o[0] + o[1] * o[1] + o[2] * o[2] - 1.0;
    let disc = b * b - c;
    if disc <= 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let (near, far) = (-b - s, -b + s);
    (far > 0.0).then_some((near.max(0.0), far))
}

/// How rays are marched.
#[derive(Clone, Copy, Debug)]
pub struct Marching {
    /// Equal steps across the unit sphere's diameter.
    pub steps: usize,
    /// At most this many samples per ray.
    pub cap: usize,
    /// Count the steps from the ray's origin (t = 0) instead of from where it enters the sphere: the
    /// samples stay where they are along the ray when the field moves (a posed object), so a rendering
    /// changes smoothly with the pose.
    pub anchored: bool,
}

/// Samples along one ray, appended to `out_t` (section midpoints) and
/// `out_dt` (section lengths). March equal steps across the sphere; keep
/// those in occupied cells; if more than `cap` remain, keep every k-th (from
/// a random start) and widen the sections to match.
pub fn sample_ray(
    grid: &OccupancyGrid,
    o: [f32; 3],
    d: [f32; 3],
    march: Marching,
    jitter: f32,
    out_t: &mut Vec<f32>,
    out_dt: &mut Vec<f32>,
) {
    let Some(steps) = MarchSteps::new(grid, o, d, march, jitter) else {
        return;
    };
    let dt = steps.dt;
    // Every occupied step first, then every stride-th of them kept in place.
    let from = out_t.len();
    out_t.extend(steps);
    let count = out_t.len() - from;
    if count == 0 {
        return;
    }
    let stride = count.div_ceil(march.cap);
    let start = ((jitter * stride as f32) as usize).min(stride - 1);
    let mut kept = from;
    for seen in (start..count).step_by(stride) {
        out_t[kept] = out_t[from + seen];
        kept += 1;
    }
    out_t.truncate(kept);
    out_dt.resize(out_dt.len() + (kept - from), dt * stride as f32);
}

/// The samples of a batch of rays, marched in parallel chunks and joined in ray order: the same samples as
/// one ray after another (on one thread the march was a tenth of a pose fit's time while the other core
/// waited). Its buffers are kept, so that a march allocates nothing once warm.
#[derive(Default)]
pub struct BatchMarch {
    chunks: Vec<MarchChunk>,
}

/// What the march gives for one chunk of rays: the samples, where each ray's end, and the points set aside.
#[derive(Default)]
struct MarchChunk {
    ends: Vec<usize>,
    t: Vec<f32>,
    dt: Vec<f32>,
    points: Vec<[f32; 3]>,
}

/// Rays marched together by one task: enough to amortise its start, few enough to share the cores.
const MARCH_CHUNK: usize = 32;

impl BatchMarch {
    /// March rays `0..rays`: `march_ray(i, t, dt)` appends ray `i`'s samples (as [`sample_ray`] does). Every
    /// ray's samples are appended to `t` and `dt` in ray order, and where each ends to `offsets`.
    pub fn run(
        &mut self,
        rays: usize,
        march_ray: impl Fn(usize, &mut Vec<f32>, &mut Vec<f32>) + Sync,
        offsets: &mut Vec<usize>,
        t: &mut Vec<f32>,
        dt: &mut Vec<f32>,
    ) {
        let mut none = Vec::new();
        self.run_with_points(rays, |i, t, dt, _| march_ray(i, t, dt), offsets, t, dt, &mut none);
    }

    /// [`Self::run`], where a ray may also set points aside (`march_ray(i, t, dt, points)` appends them),
    /// joined in ray order into `points`: a training step's regulariser points among the samples it drops.
    pub fn run_with_points(
        &mut self,
        rays: usize,
        march_ray: impl Fn(usize, &mut Vec<f32>, &mut Vec<f32>, &mut Vec<[f32; 3]>) + Sync,
        offsets: &mut Vec<usize>,
        t: &mut Vec<f32>,
        dt: &mut Vec<f32>,
        points: &mut Vec<[f32; 3]>,
    ) {
        use rayon::prelude::*;
        let chunks = rays.div_ceil(MARCH_CHUNK);
        if self.chunks.len() < chunks {
            self.chunks.resize_with(chunks, MarchChunk::default);
        }
        self.chunks[..chunks].par_iter_mut().enumerate().for_each(|(c, chunk)| {
            chunk.ends.clear();
            chunk.t.clear();
            chunk.dt.clear();
            chunk.points.clear();
            for i in c * MARCH_CHUNK..((c + 1) * MARCH_CHUNK).min(rays) {
                march_ray(i, &mut chunk.t, &mut chunk.dt, &mut chunk.points);
                chunk.ends.push(chunk.t.len());
            }
        });
        for chunk in &self.chunks[..chunks] {
            let base = t.len();
            offsets.extend(chunk.ends.iter().map(|e| base + e));
            t.extend_from_slice(&chunk.t);
            dt.extend_from_slice(&chunk.dt);
            points.extend_from_slice(&chunk.points);
        }
    }
}

/// A step in an empty cell jumps only to steps at least this far (in cells) inside the cell's far faces, and
/// only from a point this far inside every face: far above the rounding of a point's cell coordinates
/// (~3·10⁻⁵ at 128³), so every step jumped over is one the grid would place in the same empty cell.
const SKIP_MARGIN: f32 = 1e-3;

/// Where the march steps of one ray lie along it (`t`), for the steps inside the sphere and in occupied cells,
/// in order. A step in
/// an empty cell jumps past the later steps in that cell (by the ray's exit from it): the steps found are
/// exactly those a test of every step finds, with a fraction of the lookups (a cell is 4–8 steps wide).
struct MarchSteps<'a> {
    grid: &'a OccupancyGrid,
    o: [f32; 3],
    d: [f32; 3],
    base: f32,
    dt: f32,
    jitter: f32,
    near: f32,
    far: f32,
    /// The next step to look at, and the number of steps.
    k: usize,
    n: usize,
}

impl<'a> MarchSteps<'a> {
    fn new(grid: &'a OccupancyGrid, o: [f32; 3], d: [f32; 3], march: Marching, jitter: f32) -> Option<Self> {
        let (near, far) = sphere_span(o, d)?;
        let dt = 2.0 / march.steps as f32;
        let base = if march.anchored { (near / dt).floor() * dt } else { near };
        let n = ((far - base) / dt).ceil() as usize;
        Some(Self {
            grid,
            o,
            d,
            base,
            dt,
            jitter,
            near,
            far,
            k: 0,
            n,
        })
    }

    /// The first step past the empty cell at cell coordinates `g` (point at step `k`), or `k + 1` where the
    /// point lies too near a face for the jump to be safe.
    fn past_empty_cell(&self, k: usize, g: [f32; 3]) -> usize {
        let r = self.grid.res as f32;
        let mut t_leave = f32::INFINITY;
        for a in 0..3 {
            let cell = g[a] as usize as f32;
            let frac = g[a] - cell;
            if !(SKIP_MARGIN..=1.0 - SKIP_MARGIN).contains(&frac) {
                return k + 1;
            }
            let target = if self.d[a] > 0.0 {
                cell + 1.0 - SKIP_MARGIN
            } else if self.d[a] < 0.0 {
                cell + SKIP_MARGIN
            } else {
                continue;
            };
            // The ray's parameter where its cell coordinate along `a` reaches `target`.
            let t = ((target / (0.5 * r) - 1.0) - self.o[a]) / self.d[a];
            t_leave = t_leave.min(t);
        }
        if !t_leave.is_finite() {
            return self.n;
        }
        let next = ((t_leave - self.base) / self.dt - self.jitter).ceil();
        if next >= self.n as f32 {
            self.n
        } else {
            (next.max(0.0) as usize).max(k + 1)
        }
    }
}

impl Iterator for MarchSteps<'_> {
    type Item = f32;

    fn next(&mut self) -> Option<f32> {
        while self.k < self.n {
            let k = self.k;
            let t = self.base + (k as f32 + self.jitter) * self.dt;
            if t < self.near {
                self.k += 1;
                continue;
            }
            if t >= self.far {
                self.k = self.n;
                break;
            }
            let p = [
                self.o[0] + t * self.d[0],
                self.o[1] + t * self.d[1],
                self.o[2] + t * self.d[2],
            ];
            let Some((g, idx)) = self.grid.cell_at(p) else {
                self.k += 1;
                continue;
            };
            if self.grid.cells[idx] != 0 {
                self.k += 1;
                return Some(t);
            }
            self.k = self.past_empty_cell(k, g);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geom::SplitMix64;

    /// `sample_ray` as it was before steps jumped over empty cells: every step tested.
    fn sample_ray_testing_every_step(
        grid: &OccupancyGrid,
        o: [f32; 3],
        d: [f32; 3],
        march: Marching,
        jitter: f32,
    ) -> (Vec<f32>, Vec<f32>) {
        let (mut out_t, mut out_dt) = (Vec::new(), Vec::new());
        let Some((near, far)) = sphere_span(o, d) else {
            return (out_t, out_dt);
        };
        let dt = 2.0 / march.steps as f32;
        let base = if march.anchored { (near / dt).floor() * dt } else { near };
        let n = ((far - base) / dt).ceil() as usize;
        let at = |k: usize| base + (k as f32 + jitter) * dt;
        let keep = |t: f32| t >= near && t < far && grid.occupied([o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]]);
        let count = (0..n).filter(|&k| keep(at(k))).count();
        if count == 0 {
            return (out_t, out_dt);
        }
        let stride = count.div_ceil(march.cap);
        let start = ((jitter * stride as f32) as usize).min(stride - 1);
        for (seen, k) in (0..n).filter(|&k| keep(at(k))).enumerate() {
            if seen % stride == start {
                out_t.push(at(k));
                out_dt.push(dt * stride as f32);
            }
        }
        (out_t, out_dt)
    }

    /// The near-occupied mask is the cube about every occupied cell, as a direct search finds it.
    #[test]
    fn near_occupied_marks_the_cube_about_every_occupied_cell() {
        let res = 12;
        let mut rng = SplitMix64::new(3);
        let cells: Vec<u8> = (0..res * res * res).map(|_| u8::from(rng.next_f64() < 0.01)).collect();
        let grid = OccupancyGrid::from_cells(res, cells.clone());
        for radius in [0, 1, 3] {
            let near = grid.near_occupied(radius);
            for z in 0..res {
                for y in 0..res {
                    for x in 0..res {
                        let want = (0..res * res * res).any(|j| {
                            let (jx, jy, jz) = (j % res, (j / res) % res, j / (res * res));
                            cells[j] != 0
                                && jx.abs_diff(x) <= radius
                                && jy.abs_diff(y) <= radius
                                && jz.abs_diff(z) <= radius
                        });
                        assert_eq!(
                            near[(z * res + y) * res + x],
                            want,
                            "radius {radius} at ({x}, {y}, {z})"
                        );
                    }
                }
            }
        }
        assert!(grid.near_occupied(1).iter().filter(|&&n| n).count() > cells.iter().filter(|&&c| c != 0).count());
    }

    /// Jumping over empty cells finds exactly the samples a test of every step finds, bit for bit: sparse and
    /// dense grids, fine and coarse, rays from inside and outside the sphere, along and near the cells' faces.
    #[test]
    fn jumping_over_empty_cells_keeps_every_sample_of_the_full_march() {
        let mut rng = SplitMix64::new(7);
        let mut f = || rng.next_f64() as f32;
        let mut rays = 0;
        for (res, fill) in [
            (8, 0.3),
            (16, 0.05),
            (64, 0.03),
            (128, 0.01),
            (128, 0.5),
            (32, 0.0),
            (32, 1.0),
        ] {
            let mut cells = vec![0u8; res * res * res];
            for c in cells.iter_mut() {
                *c = u8::from(f() < fill);
            }
            // A slab of occupied cells too, as a board makes.
            for i in 0..res * res {
                cells[res * res * (res / 3) + i] = 1;
            }
            let grid = OccupancyGrid::from_cells(res, cells);
            for r in 0..400 {
                let mut d = [f() - 0.5, f() - 0.5, f() - 0.5];
                // Rays along an axis, in a face's plane, and nearly so.
                match r % 8 {
                    0 => d = [0.0, 0.0, 1.0],
                    1 => d[1] = 0.0,
                    2 => d[0] = 1e-7,
                    _ => {}
                }
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-12);
                let d = d.map(|v| v / l);
                let far = r % 2 == 0;
                let mut o = [f() * 2.0 - 1.0, f() * 2.0 - 1.0, f() * 2.0 - 1.0].map(|v| v * 0.9);
                if r % 8 == 1 {
                    // On a face's plane.
                    o[1] = -1.0 + 2.0 * (res / 2) as f32 / res as f32;
                }
                if far {
                    o = [o[0] - 3.0 * d[0], o[1] - 3.0 * d[1], o[2] - 3.0 * d[2]];
                }
                for (steps, cap, anchored) in [(512, 48, false), (256, 1000, true), (1024, 16, false)] {
                    let march = Marching { steps, cap, anchored };
                    let jitter = f();
                    let want = sample_ray_testing_every_step(&grid, o, d, march, jitter);
                    let (mut t, mut dt) = (Vec::new(), Vec::new());
                    sample_ray(&grid, o, d, march, jitter, &mut t, &mut dt);
                    assert_eq!((t, dt), want, "res {res}, fill {fill}, ray {r}: o {o:?} d {d:?}");
                    rays += 1;
                }
            }
        }
        assert_eq!(rays, 7 * 400 * 3);
    }

    /// The kept bounding sphere follows the cells: an update that empties the grid but one cell shrinks it.
    #[test]
    fn the_kept_bounding_sphere_follows_an_update_of_the_cells() {
        let mut g = OccupancyGrid::full(8);
        let (_, whole) = g.bounding_sphere().expect("every cell is occupied");
        assert!(whole > 1.7, "{whole}: the sphere around the whole cube");
        let corner = 0;
        let indices: Vec<usize> = (0..g.cells().len()).collect();
        let sdf: Vec<f32> = indices.iter().map(|&i| if i == corner { 0.0 } else { 1.0 }).collect();
        g.update(&indices, &sdf, 0.1);
        let (centre, radius) = g.bounding_sphere().expect("one cell is occupied");
        assert_eq!(centre, g.centre(corner));
        assert!(radius < 0.25, "{radius}: the sphere around one cell of a quarter unit");
        g.update(&[corner], &[1.0], 0.1);
        assert_eq!(g.bounding_sphere(), None);
    }
}
