//! Helpers shared by the mesh tests.
#![allow(dead_code)]

use std::collections::HashMap;

use geom::{TriMesh, Vec3};
use mesh::{sample_sdf_grid, ScalarGrid};
use sim::sdf::Sdf;

/// `sdf` (an analytic shape) sampled over `[min, max]` with `resolution` points on the longest side.
pub fn grid_of(sdf: &impl Sdf, min: [f64; 3], max: [f64; 3], resolution: usize) -> ScalarGrid {
    sample_sdf_grid(
        &|pts: &[[f64; 3]]| {
            pts.iter()
                .map(|&p| sdf.distance_local(Vec3::<f64>::cst(p)) as f32)
                .collect()
        },
        min,
        max,
        resolution,
    )
}

/// A grid from a function of the point, evaluated point by point.
pub fn grid_from(origin: [f64; 3], spacing: f64, dims: [usize; 3], mut f: impl FnMut([f64; 3]) -> f32) -> ScalarGrid {
    let mut g = ScalarGrid::new(origin, spacing, dims, vec![0.0; dims[0] * dims[1] * dims[2]]).unwrap();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                g.values[i + dims[0] * (j + dims[1] * k)] = f(g.point(i, j, k));
            }
        }
    }
    g
}

/// Twice the area vector of face `f`.
pub fn face_normal(m: &TriMesh, f: usize) -> Vec3<f64> {
    let [a, b, c] = m.triangle(f).map(Vec3::<f64>::cst);
    (b - a).cross(c - a)
}

pub fn zero_area_faces(m: &TriMesh) -> usize {
    (0..m.faces.len())
        .filter(|&f| face_normal(m, f).norm_sq() == 0.0)
        .count()
}

/// Checks a possibly open mesh: valid indices, finite vertices, no face using
/// a vertex twice, each directed edge at most once (consistent orientation,
/// at most two faces per edge). Returns the boundary edges (used in one
/// direction only).
pub fn check_open_mesh(m: &TriMesh) -> Vec<(u32, u32)> {
    assert!(
        m.vertices.iter().all(|v| v.iter().all(|c| c.is_finite())),
        "non-finite vertex"
    );
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for (fi, f) in m.faces.iter().enumerate() {
        assert!(
            f.iter().all(|&i| (i as usize) < m.vertices.len()),
            "face {fi} has a bad index"
        );
        assert!(
            f[0] != f[1] && f[1] != f[2] && f[0] != f[2],
            "face {fi} repeats a vertex: {f:?}"
        );
        for s in 0..3 {
            *directed.entry((f[s], f[(s + 1) % 3])).or_default() += 1;
        }
    }
    let mut boundary = Vec::new();
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "directed edge ({a}, {b}) in {n} faces");
        if !directed.contains_key(&(b, a)) {
            boundary.push((a, b));
        }
    }
    boundary.sort_unstable();
    boundary
}

/// Every vertex is used by some face.
pub fn assert_no_unused_vertices(m: &TriMesh) {
    let mut used = vec![false; m.vertices.len()];
    m.faces.iter().flatten().for_each(|&v| used[v as usize] = true);
    assert!(used.iter().all(|&u| u), "unused vertices");
}
