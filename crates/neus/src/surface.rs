//! A field's zero level as a mesh in world coordinates.

use crate::neus_field::NeusField;
use geom::{TriMesh, Vec3};

/// The zero level of a field inside the unit sphere's cube, in world
/// coordinates (`p_world = centre + radius · p_unit`). A field with a
/// background field (a scene) keeps only the faces inside the unit sphere:
/// beyond it the background field holds the content, and the SDF there was
/// never trained (an open mesh, cut at the sphere).
pub fn zero_level_mesh(field: &NeusField, levels: usize, centre: Vec3<f64>, radius: f64, res: usize) -> TriMesh {
    zero_level_mesh_reporting(field, levels, centre, radius, res, &|_| {})
}

/// [`zero_level_mesh`], telling `sampled` how many of the grid's `res³` points each batch evaluated (for a
/// progress bar; batches run in parallel).
pub fn zero_level_mesh_reporting(
    field: &NeusField,
    levels: usize,
    centre: Vec3<f64>,
    radius: f64,
    res: usize,
    sampled: &(dyn Fn(usize) + Sync),
) -> TriMesh {
    let grid = mesh::sample_sdf_grid(
        &|pts: &[[f64; 3]]| {
            let flat: Vec<f32> = pts.iter().flatten().map(|v| *v as f32).collect();
            let values = field.sdf_values(&flat, levels);
            sampled(pts.len());
            values
        },
        [-1.0; 3],
        [1.0; 3],
        res,
    );
    let mut m = mesh::extract_zero_level(&grid);
    if field.background.is_some() {
        // Centroid inside the unit sphere: |a + b + c| ≤ 3.
        m = mesh::faces_where(&m, |[a, b, c]| {
            (0..3).map(|k| (a[k] + b[k] + c[k]).powi(2)).sum::<f64>() <= 9.0
        });
    }
    for v in &mut m.vertices {
        *v = (centre + Vec3::cst(*v) * radius).to_array();
    }
    m
}
