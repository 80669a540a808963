//! Zero-level points: Newton steps along a field's gradient land on its
//! zero level with the field's normal, and the largest piece of a mesh is
//! found.
use geom::{SplitMix64, TriMesh, Vec3};
use mesh::{components, largest_component, zero_level_points};

type V = Vec3<f64>;

#[test]
fn projected_points_lie_on_a_non_metric_sphere() {
    let r = 0.05;
    // Zero on the sphere |x| = r, but not a distance: steeper outside, curved.
    let field = |pts: &[V]| -> Vec<f64> {
        pts.iter()
            .map(|p| {
                let d = p.norm() - r;
                2.0 * d + 30.0 * d * d
            })
            .collect()
    };
    let mut rng = SplitMix64::new(3);
    let start: Vec<V> = (0..500).map(|_| rng.dir() * (r + rng.range(-0.004, 0.004))).collect();
    let (pts, normals) = zero_level_points(&field, &start, 1e-5, 4, 1e-9);
    assert_eq!(pts.len(), start.len(), "every point should converge");
    for (p, n) in pts.iter().zip(&normals) {
        assert!((p.norm() - r).abs() < 1e-9, "point off the sphere by {}", p.norm() - r);
        let radial = *p * (1.0 / p.norm());
        assert!(n.dot(radial) > 1.0 - 1e-8, "normal {n:?} at {p:?}");
    }
    // A field without a zero level near the points gives nothing, not bad points.
    let (none, _) = zero_level_points(&|p: &[V]| vec![1.0; p.len()], &start, 1e-5, 2, 1e-6);
    assert!(none.is_empty());
}

fn tetrahedron(offset: [f64; 3], size: f64) -> TriMesh {
    let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        .map(|p| [0, 1, 2].map(|k| offset[k] + size * p[k]));
    TriMesh::new(v.to_vec(), vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
}

#[test]
fn the_largest_piece_is_kept() {
    let (small, big) = (tetrahedron([5.0, 0.0, 0.0], 0.1), tetrahedron([0.0; 3], 1.0));
    // A small tetrahedron and two big ones, sharing nothing: three pieces.
    let mut both = small.clone();
    for m in [&big, &tetrahedron([0.0, 3.0, 0.0], 1.0)] {
        let n = both.vertices.len() as u32;
        both.vertices.extend(&m.vertices);
        both.faces.extend(m.faces.iter().map(|f| f.map(|i| i + n)));
    }
    // A repeated face of the small one makes it the largest by face count.
    both.faces.push([0, 1, 2]);
    let pieces = components(&both);
    assert_eq!(pieces.len(), 3);
    assert_eq!(pieces.iter().map(|p| p.len()).collect::<Vec<_>>(), vec![5, 4, 4]);
    let largest = largest_component(&both);
    assert_eq!(largest.faces.len(), 5);
    assert_eq!(largest.vertices.len(), 4);
    assert!(
        largest.vertices.iter().all(|v| v[0] >= 5.0),
        "the small tetrahedron has the duplicate face"
    );
}
