//! Quadric decimation keeps a closed mesh closed and close to its shape:
//! a sphere to a tenth of its faces stays within a small fraction of its
//! radius, and a finely tessellated box loses its flat-face triangles
//! while its corners stay exact.
use crate::common;

use geom::TriMesh;
use mesh::{chamfer, decimate, extract_zero_level, normal_consistency};

fn sphere(r: f64, res: usize) -> TriMesh {
    extract_zero_level(&common::grid_of(
        &sim::sdf::Sphere { radius: r },
        [-1.2 * r; 3],
        [1.2 * r; 3],
        res,
    ))
}

#[test]
fn a_sphere_keeps_its_shape_at_a_tenth_of_its_faces() {
    let r = 0.05;
    let fine = sphere(r, 96);
    sim::check_closed_mesh(&fine).unwrap();
    let target = fine.faces.len() / 10;
    let coarse = decimate(&fine, target);
    sim::check_closed_mesh(&coarse).unwrap();
    assert!(
        coarse.faces.len() <= target && coarse.faces.len() > target - 10,
        "{} faces",
        coarse.faces.len()
    );
    let c = chamfer(&coarse, &fine, 20000, 1);
    assert!(
        c.mean < 0.002 * r && c.max < 0.02 * r,
        "Chamfer mean {:.2e}, max {:.2e}",
        c.mean,
        c.max
    );
    let nc = normal_consistency(&coarse, &fine, 20000, 2);
    assert!(nc > 0.99, "normal consistency {nc}");
    // Vertices stay on the sphere: quadrics keep them on the tangent planes.
    let worst = coarse
        .vertices
        .iter()
        .map(|v| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - r).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.01 * r, "a vertex {worst} off the sphere");
}

#[test]
fn a_tessellated_box_collapses_to_its_corners() {
    let h = [0.03, 0.02, 0.01];
    let fine = sim::tessellate::cuboid_mesh(&sim::sdf::Cuboid { half: h }, 12);
    sim::check_closed_mesh(&fine).unwrap();
    let coarse = decimate(&fine, 12);
    sim::check_closed_mesh(&coarse).unwrap();
    assert_eq!(coarse.faces.len(), 12, "a box needs 12 triangles");
    assert_eq!(coarse.vertices.len(), 8);
    for v in &coarse.vertices {
        for k in 0..3 {
            assert!((v[k].abs() - h[k]).abs() < 1e-9, "vertex {v:?} is not a corner");
        }
    }
    // Asking for fewer than a closed mesh can have stops at what stays closed.
    let least = decimate(&fine, 0);
    sim::check_closed_mesh(&least).unwrap();
    assert!(least.faces.len() >= 4);
}
