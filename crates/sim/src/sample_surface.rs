//! A deterministic, area-uniform sample of a mesh surface.

use geom::{SplitMix64, TriMesh, Vec3};

/// `count` points spread uniformly by area over the surface, from `seed`.
pub fn sample_surface(mesh: &TriMesh, count: usize, seed: u64) -> Vec<Vec3<f64>> {
    sample_surface_with_normals(mesh, count, seed)
        .into_iter()
        .map(|(p, _)| p)
        .collect()
}

/// [`sample_surface`] with the unit normal of the face each point lies on.
pub fn sample_surface_with_normals(mesh: &TriMesh, count: usize, seed: u64) -> Vec<(Vec3<f64>, Vec3<f64>)> {
    let mut cumulative = Vec::with_capacity(mesh.faces.len());
    let mut total = 0.0;
    for f in 0..mesh.faces.len() {
        total += mesh.triangle_area(f);
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
            let p = a * (1.0 - r1) + b * (r1 * (1.0 - r2)) + c * (r1 * r2);
            (p, (b - a).cross(c - a).normalize_or(Vec3::zero()))
        })
        .collect()
}
