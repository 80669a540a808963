//! Contact points: a deterministic, area-uniform sample of a mesh surface.

use geom::{TriMesh, Vec3};

/// SplitMix64: tiny, seedable and the same on every platform and version.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// `count` points spread uniformly by area over the surface, from `seed`.
pub fn sample_surface(mesh: &TriMesh, count: usize, seed: u64) -> Vec<Vec3<f64>> {
    let mut cumulative = Vec::with_capacity(mesh.faces.len());
    let mut total = 0.0;
    for f in 0..mesh.faces.len() {
        let [a, b, c] = mesh.triangle(f).map(Vec3::<f64>::cst);
        total += (b - a).cross(c - a).norm() * 0.5;
        cumulative.push(total);
    }
    let mut rng = SplitMix64::new(seed);
    (0..count)
        .map(|_| {
            let target = rng.next_f64() * total;
            let f = cumulative.partition_point(|&c| c <= target).min(mesh.faces.len() - 1);
            let [a, b, c] = mesh.triangle(f).map(Vec3::<f64>::cst);
            // Uniform barycentric sample (square-root warp).
            let (r1, r2) = (rng.next_f64().sqrt(), rng.next_f64());
            a * (1.0 - r1) + b * (r1 * (1.0 - r2)) + c * (r1 * r2)
        })
        .collect()
}
