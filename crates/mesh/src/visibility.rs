//! What a capture's cameras saw of a partial reconstruction. The board
//! (z < 0) and the object itself hide parts of it: the underside where it
//! stands, but also an overhang, or a roof whose apex it stands on. A surface
//! point counts as seen by a camera when it is in the image and the segment
//! from just outside the surface to the camera meets neither the surface nor
//! the board. The segment is sphere-traced through a grid baked from the
//! part's own SDF, so each test costs a few trilinear lookups.

use geom::{Camera, Vec3};
use sim::sdf::{Sdf, SdfGrid};

use crate::sample_sdf_grid::sample_sdf_grid;
use crate::zero_level_points::BatchSdf;

type V = Vec3<f64>;

/// The cameras of one capture and its part's SDF on a grid, in that capture's frame.
pub struct Visibility {
    cameras: Vec<Camera<f64>>,
    grid: SdfGrid,
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Visibility {
    /// Bakes `sdf` over the box `[lo, hi]` with `resolution` nodes along its longest side.
    pub fn new(sdf: &BatchSdf, lo: [f64; 3], hi: [f64; 3], resolution: usize, cameras: Vec<Camera<f64>>) -> Self {
        let sampled = sample_sdf_grid(
            &|pts: &[[f64; 3]]| {
                let pts: Vec<V> = pts.iter().map(|p| V::cst(*p)).collect();
                sdf(&pts).iter().map(|v| *v as f32).collect()
            },
            lo,
            hi,
            resolution.max(2),
        );
        let grid = SdfGrid::from_values(sampled.origin, sampled.spacing, sampled.dims, sampled.values)
            .expect("a valid grid by construction");
        let (lo, hi) = (grid.origin(), grid.max_corner());
        Self { cameras, grid, lo, hi }
    }

    /// Number of cameras.
    pub fn cameras(&self) -> usize {
        self.cameras.len()
    }

    fn inside_box(&self, p: V) -> bool {
        let a = p.to_array();
        (0..3).all(|k| a[k] >= self.lo[k] && a[k] <= self.hi[k])
    }

    /// Whether nothing lies between `p` (just outside the surface) and `camera`.
    fn clear_line(&self, p: V, camera: &Camera<f64>) -> bool {
        let (u, v, depth) = camera.project(p);
        if !(depth > 0.0 && u >= 0.0 && v >= 0.0 && u < camera.width as f64 && v < camera.height as f64) {
            return false;
        }
        let c = camera.center();
        if p.z < 0.0 || c.z < 0.0 {
            return false; // the board is opaque
        }
        let h = self.grid.spacing();
        let length = (c - p).norm();
        let dir = (c - p) * (1.0 / length);
        let mut t = 0.0;
        for _ in 0..512 {
            let q = p + dir * t;
            if t >= length || !self.inside_box(q) {
                return true;
            }
            let d = self.grid.distance_local(q);
            if d < 0.3 * h {
                return false;
            }
            t += d.max(0.5 * h);
        }
        true
    }

    /// The fraction of cameras that see the surface point nearest to `x`.
    pub fn seen_fraction(&self, x: V) -> f64 {
        if self.cameras.is_empty() {
            return 0.0;
        }
        let (s, g) = self.grid.distance_grad_local(x);
        let n = g * (1.0 / g.norm().max(1e-12));
        let p = x - n * s + n * (1.5 * self.grid.spacing());
        let seen = self.cameras.iter().filter(|c| self.clear_line(p, c)).count();
        seen as f64 / self.cameras.len() as f64
    }
}
