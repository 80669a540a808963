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
        let r = self.res as f32;
        let mut idx = 0usize;
        let mut mul = 1usize;
        for &c in &p {
            // In [0, r) the cast truncates as `floor` would, and x ∈ [0, r) ⇔ ⌊x⌋ ∈ [0, r) for an integer r:
            // without SSE4.1 `floor` is a libm call, a tenth of a pose fit's time.
            let g = (c + 1.0) * 0.5 * r;
            if !(0.0..r).contains(&g) {
                return false;
            }
            idx += g as usize * mul;
            mul *= self.res;
        }
        self.cells[idx] != 0
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
    let (steps, cap) = (march.steps, march.cap);
    let Some((near, far)) = sphere_span(o, d) else { return };
    let dt = 2.0 / steps as f32;
    let base = if march.anchored { (near / dt).floor() * dt } else { near };
    let n = ((far - base) / dt).ceil() as usize;
    let at = |k: usize| base + (k as f32 + jitter) * dt;
    let occupied = |t: f32| grid.occupied([o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]]);
    let inside = |t: f32| t >= near && t < far;
    let count = (0..n).filter(|&k| inside(at(k)) && occupied(at(k))).count();
    if count == 0 {
        return;
    }
    let stride = count.div_ceil(cap);
    let start = ((jitter * stride as f32) as usize).min(stride - 1);
    let mut seen = 0usize;
    for k in 0..n {
        let t = at(k);
        if !inside(t) || !occupied(t) {
            continue;
        }
        if seen % stride == start {
            out_t.push(t);
            out_dt.push(dt * stride as f32);
        }
        seen += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
