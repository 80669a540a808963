//! Zero levels of analytic SDFs: closed and outward (sim's closed-mesh check,
//! positive volume, face normals away from the centre), within half a voxel
//! of the true surface both ways, at 32 and 64 points per side; exact zeros on
//! grid planes and random sign patterns still closed, without zero-area
//! faces where they can be removed; open surfaces that leave the grid; empty
//! cases; the same mesh for 1 and 2 threads.

use crate::common;

use common::{assert_no_unused_vertices, check_open_mesh, face_normal, grid_from, grid_of, zero_area_faces};
use geom::{SplitMix64, TriMesh, Vec3};
use mesh::{extract_zero_level, GridError, ScalarGrid};
use sim::mass_properties_mesh::mesh_volume;
use sim::sdf::{Cuboid, MeshDistance, Sdf, Sphere};
use sim::{check_closed_mesh, sample_surface::sample_surface};

const MIN: [f64; 3] = [-1.0; 3];
const MAX: [f64; 3] = [1.0; 3];

/// Distances of the mesh's vertices to the true surface, and of `truth`
/// (points on the true surface) to the mesh, each sorted.
fn two_way_distances(m: &TriMesh, sdf: &impl Sdf, truth: &[Vec3<f64>]) -> (Vec<f64>, Vec<f64>) {
    let mut to_truth: Vec<f64> = m
        .vertices
        .iter()
        .map(|&v| sdf.distance_local(Vec3::<f64>::cst(v)).abs())
        .collect();
    let md = MeshDistance::new(m).unwrap();
    let mut to_mesh: Vec<f64> = truth.iter().map(|&p| md.closest_point(p).0).collect();
    to_truth.sort_by(f64::total_cmp);
    to_mesh.sort_by(f64::total_cmp);
    (to_truth, to_mesh)
}

fn p95(sorted: &[f64]) -> f64 {
    sorted[(sorted.len() * 95).div_ceil(100) - 1]
}

fn max(sorted: &[f64]) -> f64 {
    sorted[sorted.len() - 1]
}

/// Outward normals of a convex shape around the origin: every face (but
/// slivers below `min_area`) faces away from the origin.
fn assert_outward(m: &TriMesh, min_area: f64) {
    let mut checked = 0;
    for f in 0..m.faces.len() {
        let n = face_normal(m, f);
        if n.norm() * 0.5 < min_area {
            continue;
        }
        let [a, b, c] = m.triangle(f).map(Vec3::<f64>::cst);
        assert!(n.dot(a + b + c) > 0.0, "face {f} points inward");
        checked += 1;
    }
    assert!(checked > m.faces.len() / 2);
}

/// `n` points uniform on the surface of a box of half extents `h`.
fn box_surface_points(h: [f64; 3], n: usize, seed: u64) -> Vec<Vec3<f64>> {
    let areas = [h[1] * h[2], h[0] * h[2], h[0] * h[1]];
    let total: f64 = areas.iter().sum();
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| {
            let r = rng.next_f64() * total;
            let axis = if r < areas[0] {
                0
            } else if r < areas[0] + areas[1] {
                1
            } else {
                2
            };
            let mut p = [0.0; 3];
            for a in 0..3 {
                p[a] = if a == axis {
                    if rng.next_f64() < 0.5 {
                        -h[a]
                    } else {
                        h[a]
                    }
                } else {
                    rng.range(-h[a], h[a])
                };
            }
            Vec3::cst(p)
        })
        .collect()
}

#[test]
fn sphere_is_closed_outward_and_within_half_a_voxel() {
    let sphere = Sphere { radius: 0.6 };
    let mut rng = SplitMix64::new(7);
    let truth: Vec<Vec3<f64>> = (0..4000).map(|_| rng.dir() * 0.6).collect();
    for res in [32, 64] {
        let grid = grid_of(&sphere, MIN, MAX, res);
        let h = grid.spacing;
        let m = extract_zero_level(&grid);
        check_closed_mesh(&m).unwrap_or_else(|e| panic!("res {res}: {e}"));
        assert_no_unused_vertices(&m);
        let v = mesh_volume(&m);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.6f64.powi(3);
        assert!(
            v > 0.0 && (v - exact).abs() < 0.03 * exact,
            "res {res}: volume {v} vs {exact}"
        );
        assert_outward(&m, 1e-6 * h * h);
        assert_eq!(zero_area_faces(&m), 0);
        let (to_truth, to_mesh) = two_way_distances(&m, &sphere, &truth);
        let (a, b) = (max(&to_truth), max(&to_mesh));
        assert!(a < 0.5 * h && b < 0.5 * h, "res {res}: {a} {b} (h {h})");
    }
}

#[test]
fn box_is_closed_outward_and_within_half_a_voxel() {
    let cuboid = Cuboid { half: [0.55, 0.4, 0.3] };
    let truth = box_surface_points(cuboid.half, 4000, 3);
    for res in [32, 64] {
        let grid = grid_of(&cuboid, MIN, MAX, res);
        let h = grid.spacing;
        let m = extract_zero_level(&grid);
        check_closed_mesh(&m).unwrap_or_else(|e| panic!("res {res}: {e}"));
        let v = mesh_volume(&m);
        let exact = 8.0 * 0.55 * 0.4 * 0.3;
        assert!(
            v > 0.0 && (v - exact).abs() < 0.05 * exact,
            "res {res}: volume {v} vs {exact}"
        );
        assert_outward(&m, 1e-6 * h * h);
        // Vertices lie within half a voxel of the box; the box's sharp edges
        // are cut off (as by any marching method), so its surface is within
        // half a voxel of the mesh but for those edges, and within one voxel
        // everywhere.
        let (to_truth, to_mesh) = two_way_distances(&m, &cuboid, &truth);
        let (a, b, c) = (max(&to_truth), p95(&to_mesh), max(&to_mesh));
        assert!(a < 0.5 * h && b < 0.5 * h && c < h, "res {res}: {a} {b} {c} (h {h})");
    }
}

/// A box whose faces lie on grid planes: the SDF is exactly 0 on whole planes
/// of grid points, so many crossings land on the same point. The mesh is still
/// closed, the coincident vertices are welded and no zero-area face is left.
#[test]
fn box_on_grid_planes_exact_zeros() {
    let cuboid = Cuboid {
        half: [0.5, 0.375, 0.25],
    };
    for n in [17, 33] {
        let h = 2.0 / (n - 1) as f64;
        let grid = grid_from(MIN, h, [n; 3], |p| cuboid.distance_local(Vec3::<f64>::cst(p)) as f32);
        assert!(grid.values.iter().filter(|&&v| v == 0.0).count() > 100);
        let m = extract_zero_level(&grid);
        check_closed_mesh(&m).unwrap();
        assert_no_unused_vertices(&m);
        assert_eq!(zero_area_faces(&m), 0, "n {n}");
        // Vertices sit exactly on the box. Cubes along half of the box's
        // edges are split so that a tetrahedron with only zero corners lies
        // inside the box; 0 counts as outside, so those edges are cut off by
        // a triangular prism of h²/2 per unit length: at most 6 edges' worth.
        let v = mesh_volume(&m);
        let exact = 8.0 * 0.5 * 0.375 * 0.25;
        assert!(
            v <= exact + 1e-12 && exact - v <= 0.5 * h * h * 2.0 * (1.0 + 0.75 + 0.5) + 1e-12,
            "volume {v}"
        );
        for p in &m.vertices {
            assert!(cuboid.distance_local(Vec3::<f64>::cst(*p)).abs() < 1e-12);
        }
        assert_outward(&m, 1e-9);
    }
}

/// Random signs, with many exact zeros: whatever the pattern, the surface is
/// closed and consistently oriented, and it bounds a non-negative volume.
#[test]
fn random_sign_patterns_stay_closed() {
    let n = 10;
    for seed in 0..40u64 {
        let mut rng = SplitMix64::new(seed);
        let quantised = seed % 2 == 0;
        let grid = grid_from([0.0; 3], 0.1, [n; 3], |p| {
            let edge = p.iter().any(|&c| c < 0.05 || c > 0.1 * (n - 1) as f64 - 0.05);
            let r = rng.next_f64();
            if edge {
                1.0
            } else if quantised {
                [-1.0, 0.0, 1.0][(r * 3.0) as usize]
            } else {
                (r - 0.5) as f32
            }
        });
        let m = extract_zero_level(&grid);
        if m.faces.is_empty() {
            continue;
        }
        check_closed_mesh(&m).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        check_open_mesh(&m);
        assert_no_unused_vertices(&m);
        assert!(mesh_volume(&m) > -1e-12, "seed {seed}");
    }
}

/// A tilted plane and a sphere larger than the grid: open surfaces whose
/// boundary lies on the faces of the grid box, still oriented consistently.
#[test]
fn surfaces_leaving_the_grid_are_valid_open_meshes() {
    let tilted = |p: [f64; 3]| (p[2] - 0.3 * p[0] - 0.1 * p[1] - 0.05) as f32;
    let flat = |p: [f64; 3]| p[2] as f32; // zero on a whole grid plane
    let big = Sphere { radius: 1.2 };
    let big_sphere = |p: [f64; 3]| big.distance_local(Vec3::<f64>::cst(p)) as f32;
    type Field<'a> = &'a dyn Fn([f64; 3]) -> f32;
    let fields: [(&str, Field); 3] = [("tilted", &tilted), ("flat", &flat), ("sphere", &big_sphere)];
    for (name, f) in fields {
        let grid = grid_from(MIN, 2.0 / 20.0, [21; 3], f);
        let m = extract_zero_level(&grid);
        assert!(!m.faces.is_empty(), "{name}");
        let boundary = check_open_mesh(&m);
        assert!(!boundary.is_empty(), "{name}");
        for (a, b) in boundary {
            for v in [a, b] {
                let p = m.vertices[v as usize];
                assert!(
                    p.iter().any(|&c| (c.abs() - 1.0).abs() < 1e-12),
                    "{name}: boundary vertex {p:?} inside the grid"
                );
            }
        }
        // Normals along the field's gradient (central differences at the centroid).
        for fi in 0..m.faces.len() {
            let n = face_normal(&m, fi);
            if n.norm() < 1e-9 {
                continue;
            }
            let [a, b, c] = m.triangle(fi).map(Vec3::<f64>::cst);
            let x = ((a + b + c) * (1.0 / 3.0)).to_array();
            let e = 1e-3;
            let g = Vec3::from_array([0, 1, 2].map(|k| {
                let (mut p, mut q) = (x, x);
                p[k] += e;
                q[k] -= e;
                f(p) as f64 - f(q) as f64
            }));
            assert!(n.dot(g) > 0.0, "{name}: face {fi} points the wrong way");
        }
    }
}

#[test]
fn flat_plane_points_up() {
    let grid = grid_from(MIN, 0.1, [21; 3], |p| p[2] as f32);
    let m = extract_zero_level(&grid);
    assert!(m.faces.len() > 100);
    for f in 0..m.faces.len() {
        let n = face_normal(&m, f);
        assert!(n.z > 0.0 && n.x.abs() < 1e-12 && n.y.abs() < 1e-12, "face {f}: {n:?}");
    }
    for p in &m.vertices {
        assert_eq!(p[2], 0.0);
    }
}

#[test]
fn no_zero_level_gives_an_empty_mesh() {
    for value in [1.0f32, -1.0, 0.0, f32::NAN] {
        let grid = grid_from(MIN, 0.25, [9, 8, 7], |_| value);
        assert_eq!(extract_zero_level(&grid), TriMesh::default(), "all {value}");
    }
    // Fewer than two points along an axis: no cube at all.
    let flat = ScalarGrid::new([0.0; 3], 1.0, [5, 5, 1], vec![-1.0; 25]).unwrap();
    assert_eq!(extract_zero_level(&flat), TriMesh::default());
    let none = ScalarGrid::new([0.0; 3], 1.0, [0, 0, 0], vec![]).unwrap();
    assert_eq!(extract_zero_level(&none), TriMesh::default());
}

#[test]
fn single_negative_point_is_a_small_closed_blob() {
    let grid = grid_from([0.0; 3], 1.0, [3; 3], |p| if p == [1.0; 3] { -1.0 } else { 1.0 });
    let m = extract_zero_level(&grid);
    check_closed_mesh(&m).unwrap();
    // One vertex on each of the 14 grid edges at the point, half way.
    assert_eq!(m.vertices.len(), 14);
    assert!(mesh_volume(&m) > 0.0);
}

#[test]
fn infinite_and_nan_values_do_not_break_the_mesh() {
    let grid = grid_from(MIN, 0.1, [21; 3], |p| {
        let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.5;
        if p[0] > 0.6 {
            f32::NAN
        } else if d > 0.3 {
            f32::INFINITY
        } else if d < -0.3 {
            f32::NEG_INFINITY
        } else {
            d as f32
        }
    });
    let m = extract_zero_level(&grid);
    check_closed_mesh(&m).unwrap();
}

#[test]
fn same_mesh_for_one_and_two_threads() {
    let sphere = Sphere { radius: 0.7 };
    let grid = grid_of(&sphere, MIN, MAX, 64);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| extract_zero_level(&grid))
    };
    let one = run(1);
    assert!(!one.faces.is_empty());
    assert_eq!(one, run(2));
}

#[test]
fn grid_constructor_checks_its_parts() {
    assert_eq!(
        ScalarGrid::new([0.0; 3], 1.0, [2, 2, 2], vec![0.0; 7]),
        Err(GridError::ValueCount {
            dims: [2, 2, 2],
            expected: 8,
            found: 7
        })
    );
    assert_eq!(
        ScalarGrid::new([0.0; 3], 0.0, [1, 1, 1], vec![0.0]),
        Err(GridError::Spacing(0.0))
    );
    assert!(ScalarGrid::new([f64::NAN, 0.0, 0.0], 1.0, [1, 1, 1], vec![0.0]).is_err());
    let g = ScalarGrid::new([1.0, 2.0, 3.0], 0.5, [2, 3, 4], (0..24).map(|i| i as f32).collect()).unwrap();
    assert_eq!(g.point(1, 2, 3), [1.5, 3.0, 4.5]);
    assert_eq!(g.value(1, 2, 3), (1 + 2 * (2 + 3 * 3)) as f32);
}

#[test]
#[should_panic(expected = "values for a grid")]
fn inconsistent_grid_panics_with_a_message() {
    let g = ScalarGrid {
        origin: [0.0; 3],
        spacing: 1.0,
        dims: [2, 2, 2],
        values: vec![0.0; 3],
    };
    extract_zero_level(&g);
}

/// The extracted surface of a sphere samples like the sphere: surface samples
/// of the mesh lie within a small fraction of a voxel of the true radius.
#[test]
fn surface_samples_lie_on_the_sphere() {
    let sphere = Sphere { radius: 0.5 };
    let grid = grid_of(&sphere, MIN, MAX, 64);
    let m = extract_zero_level(&grid);
    let worst = sample_surface(&m, 5000, 1)
        .iter()
        .map(|p| (p.norm() - 0.5).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.1 * grid.spacing, "{worst}");
}
