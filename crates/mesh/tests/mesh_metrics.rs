//! Chamfer distance: zero for a mesh and itself, the known law for two
//! spheres offset by δ (point distances ≈ δ·|cos θ|, so mean δ/2, p95 0.95 δ,
//! max δ), empty meshes, and the extracted sphere against a fine tessellation.

use geom::TriMesh;
use mesh::{chamfer, extract_zero_level, sample_sdf_grid};
use sim::sdf::{Sdf, Sphere};
use sim::tessellate::sphere_mesh;

fn shifted(m: &TriMesh, d: [f64; 3]) -> TriMesh {
    TriMesh::new(
        m.vertices
            .iter()
            .map(|v| [v[0] + d[0], v[1] + d[1], v[2] + d[2]])
            .collect(),
        m.faces.clone(),
    )
}

#[test]
fn a_mesh_is_at_zero_distance_from_itself() {
    let m = sphere_mesh(&Sphere { radius: 0.5 }, 8);
    let s = chamfer(&m, &m, 2000, 1);
    assert!(s.mean < 1e-12 && s.p95 < 1e-12 && s.max < 1e-12, "{s:?}");
}

#[test]
fn offset_spheres_follow_the_cosine_law() {
    let m = sphere_mesh(&Sphere { radius: 1.0 }, 24);
    let delta = 0.02;
    let s = chamfer(&m, &shifted(&m, [delta, 0.0, 0.0]), 20_000, 5);
    assert!((s.mean - 0.5 * delta).abs() < 0.05 * delta, "{s:?}");
    assert!((s.p95 - 0.95 * delta).abs() < 0.05 * delta, "{s:?}");
    assert!(s.max <= 1.02 * delta && s.max > 0.95 * delta, "{s:?}");
    assert!(s.mean <= s.p95 && s.p95 <= s.max);
}

#[test]
fn empty_meshes() {
    let m = sphere_mesh(&Sphere { radius: 0.5 }, 4);
    let e = TriMesh::default();
    let both = chamfer(&e, &e, 10, 0);
    assert_eq!((both.mean, both.p95, both.max), (0.0, 0.0, 0.0));
    assert!(chamfer(&m, &e, 10, 0).mean.is_infinite());
    assert!(chamfer(&e, &m, 10, 0).max.is_infinite());
    // Zero samples is taken as one.
    assert!(chamfer(&m, &m, 0, 0).max < 1e-12);
}

#[test]
fn extracted_sphere_is_close_to_a_fine_tessellation() {
    let sphere = Sphere { radius: 0.6 };
    let field = |pts: &[[f64; 3]]| {
        pts.iter()
            .map(|&p| sphere.distance_local(geom::Vec3::<f64>::cst(p)) as f32)
            .collect()
    };
    let coarse = extract_zero_level(&sample_sdf_grid(&field, [-1.0; 3], [1.0; 3], 32));
    let fine = extract_zero_level(&sample_sdf_grid(&field, [-1.0; 3], [1.0; 3], 64));
    let truth = sphere_mesh(&sphere, 32);
    let c = chamfer(&coarse, &truth, 5000, 2);
    let f = chamfer(&fine, &truth, 5000, 2);
    let h = 2.0 / 31.0;
    assert!(c.max < 0.5 * h, "{c:?}");
    // Finer grid, closer surface.
    assert!(f.mean < c.mean, "{f:?} vs {c:?}");
}
