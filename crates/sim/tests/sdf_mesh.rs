//! `MeshDistance` on the tessellated box and sphere: winding numbers (the
//! hierarchical approximation against an exact sum of solid angles computed
//! here by L'Huilier's theorem), signed distances against the analytic SDFs
//! (exact for the box and wedge polyhedra, within the tessellation's
//! Hausdorff distance for the sphere), grids baked from the mesh against
//! grids baked from the shape, an inside-out mesh, an open mesh, and the
//! construction errors.

use geom::{Dual, TriMesh, Vec3};
use sim::sdf::{Cuboid, MeshDistance, MeshSdfError, Sdf, SdfGrid, Sphere, Wedge};
use sim::tessellate::{cuboid_mesh, sphere_mesh, wedge_mesh};

type V = Vec3<f64>;

use geom::SplitMix64 as Rng;

const CUBOID: Cuboid = Cuboid { half: [0.5, 0.3, 0.4] };
const SPHERE: Sphere = Sphere { radius: 0.6 };
/// Hierarchical winding numbers are trusted to this (dipole far field).
const WINDING_TOL: f64 = 0.02;

fn box_mesh() -> TriMesh {
    cuboid_mesh(&CUBOID, 3)
}
fn ball_mesh() -> TriMesh {
    sphere_mesh(&SPHERE, 12)
}

/// Solid angle of triangle `t` seen from `p` by L'Huilier's theorem (not the
/// Van Oosterom–Strackee formula the library uses), signed by orientation.
fn solid_angle_lhuilier(p: V, t: [[f64; 3]; 3]) -> f64 {
    let [a, b, c] = t.map(|v| V::cst(v) - p);
    let ang = |u: V, v: V| u.cross(v).norm().atan2(u.dot(v));
    let (ta, tb, tc) = (ang(b, c), ang(a, c), ang(a, b));
    let s = 0.5 * (ta + tb + tc);
    let prod = (0.5 * s).tan() * (0.5 * (s - ta)).tan() * (0.5 * (s - tb)).tan() * (0.5 * (s - tc)).tan();
    let e = 4.0 * prod.max(0.0).sqrt().atan();
    let det = a.dot(b.cross(c));
    if det < 0.0 {
        -e
    } else {
        e
    }
}

/// Exact generalized winding number: every triangle's solid angle, summed.
fn exact_winding(m: &TriMesh, p: V) -> f64 {
    (0..m.faces.len())
        .map(|f| solid_angle_lhuilier(p, m.triangle(f)))
        .sum::<f64>()
        / (4.0 * std::f64::consts::PI)
}

/// `n` random points inside and `n` outside, each at least `margin` from
/// the surface of `sdf`.
fn points_off_surface(sdf: &impl Sdf, seed: u64, n: usize, reach: f64, margin: f64) -> (Vec<V>, Vec<V>) {
    let mut rng = Rng(seed);
    let (mut inside, mut outside) = (Vec::new(), Vec::new());
    while inside.len() < n || outside.len() < n {
        let p = rng.vec(reach);
        let d = sdf.distance_local(p);
        if d < -margin && inside.len() < n {
            inside.push(p);
        } else if d > margin && outside.len() < n {
            outside.push(p);
        }
    }
    (inside, outside)
}

/// Hausdorff distance between the unit-ish sphere and its inscribed
/// tessellation: every face lies between its plane's distance h_f from the
/// centre and the sphere, so the gap is at most max_f (r − h_f).
fn tessellation_gap(m: &TriMesh, r: f64) -> f64 {
    (0..m.faces.len())
        .map(|f| {
            let [a, b, c] = m.triangle(f).map(V::cst);
            let n = (b - a).cross(c - a);
            r - a.dot(n).abs() / n.norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn the_meshes_are_closed_and_outward() {
    // The exact winding number of a closed outward mesh is 1 inside and 0
    // outside up to rounding; this also validates the test's own solid angle.
    for (name, m) in [("box", box_mesh()), ("ball", ball_mesh())] {
        let mut rng = Rng(1);
        for _ in 0..40 {
            let p = rng.vec(1.0);
            let d = if name == "box" {
                CUBOID.distance_local(p)
            } else {
                SPHERE.distance_local(p)
            };
            if d.abs() < 0.05 {
                continue;
            }
            let w = exact_winding(&m, p);
            let expected = if d < 0.0 { 1.0 } else { 0.0 };
            assert!((w - expected).abs() < 1e-9, "{name} at {p:?}: exact winding {w}");
        }
    }
}

#[test]
fn hierarchical_winding_number_inside_and_outside() {
    for (name, m, margin) in [("box", box_mesh(), 0.01), ("ball", ball_mesh(), 0.05)] {
        let md = MeshDistance::new(&m).unwrap();
        let (inside, outside) = if name == "box" {
            points_off_surface(&CUBOID, 2, 1500, 1.5, margin)
        } else {
            points_off_surface(&SPHERE, 2, 1500, 1.5, margin)
        };
        for p in &inside {
            let w = md.winding_number(*p);
            assert!((w - 1.0).abs() < WINDING_TOL, "{name}: winding {w} inside at {p:?}");
        }
        for p in &outside {
            let w = md.winding_number(*p);
            assert!(w.abs() < WINDING_TOL, "{name}: winding {w} outside at {p:?}");
        }
        // Far away the whole mesh is one dipole with zero net normal.
        for p in [V::new(50.0, 0.0, 0.0), V::new(-3.0, 7.0, 2.0)] {
            assert!(md.winding_number(p).abs() < 1e-9);
        }
        // Against the exact sum at a few points, including ones very close
        // to the surface (where only exact near-field terms should be used).
        let mut few: Vec<V> = inside.iter().chain(&outside).step_by(97).cloned().collect();
        few.extend([
            V::new(0.0, 0.0, 0.399),
            V::new(0.0, 0.0, 0.401),
            V::new(0.499, 0.0, 0.0),
            V::new(0.0, 0.599, 0.0),
        ]);
        for p in few {
            let (w, e) = (md.winding_number(p), exact_winding(&m, p));
            assert!(
                (w - e).abs() < WINDING_TOL,
                "{name} at {p:?}: hierarchical {w} vs exact {e}"
            );
        }
    }
}

#[test]
fn box_mesh_signed_distance_is_the_analytic_box_sdf() {
    // The tessellated box is exactly the box, so the closest-point distance
    // is exact: 1e-9 leaves room only for rounding.
    for n in [1, 3] {
        let md = MeshDistance::new(&cuboid_mesh(&CUBOID, n)).unwrap();
        let mut rng = Rng(3);
        let mut pts: Vec<V> = (0..3000).map(|_| rng.vec(1.2)).collect();
        // Near the surface on both sides, near edges and corners.
        for s in [-1e-4, 1e-4, -1e-6, 1e-6] {
            pts.push(V::new(0.5 + s, 0.1, -0.2));
            pts.push(V::new(0.3, -0.3 - s, 0.1));
            pts.push(V::new(0.5 + s, 0.3 + s, 0.0));
            pts.push(V::new(-0.5 - s, 0.3 + s, -0.4 - s));
        }
        for p in pts {
            let (d, g) = md.signed_distance(p);
            let (da, ga) = CUBOID.distance_grad_local(p);
            assert!((d - da).abs() < 1e-9, "n = {n}, {p:?}: mesh {d} vs box {da}");
            // Away from kinks (inside: a unique nearest face; outside: any
            // point) the gradients agree too.
            let q: Vec<f64> = (0..3).map(|a| p[a].abs() - CUBOID.half[a]).collect();
            let mut sorted = q.clone();
            sorted.sort_by(f64::total_cmp);
            let smooth = da > 1e-6 || (da < -1e-6 && sorted[2] - sorted[1] > 1e-3);
            if smooth {
                assert!((g - ga).norm() < 1e-9, "n = {n}, {p:?}: mesh grad {g:?} vs box {ga:?}");
            }
            // The unsigned part is the closest point's distance.
            let (u, c) = md.closest_point(p);
            assert!((u - d.abs()).abs() < 1e-15 && ((c - p).norm() - u).abs() < 1e-12);
            // The closest point lies on the box surface.
            assert!(CUBOID.distance_local(c).abs() < 1e-12);
        }
    }
}

#[test]
fn wedge_mesh_signed_distance_is_the_analytic_wedge_sdf() {
    let w = Wedge { half: [0.6, 0.4, 0.3] };
    let md = MeshDistance::new(&wedge_mesh(&w)).unwrap();
    let mut rng = Rng(4);
    for _ in 0..3000 {
        let p = rng.vec(1.0);
        let (d, da) = (md.signed_distance(p).0, w.distance_local(p));
        assert!((d - da).abs() < 1e-9, "{p:?}: mesh {d} vs wedge {da}");
    }
}

#[test]
fn sphere_mesh_signed_distance_within_the_tessellation_gap() {
    let m = ball_mesh();
    let gap = tessellation_gap(&m, SPHERE.radius) + 1e-12;
    // n = 12 cells per cube edge: the gap is a few thousandths of r.
    assert!(gap < 0.01 * SPHERE.radius && gap > 1e-4, "gap {gap}");
    let md = MeshDistance::new(&m).unwrap();
    let mut rng = Rng(5);
    let mut worst: f64 = 0.0;
    for _ in 0..3000 {
        let p = rng.vec(1.2);
        let (d, da) = (md.signed_distance(p).0, SPHERE.distance_local(p));
        // Points between the two surfaces may differ by up to twice the gap
        // (one distance to each); elsewhere by the Hausdorff distance.
        let bound = if da.abs() > gap { gap } else { 2.0 * gap };
        assert!(
            (d - da).abs() <= bound,
            "{p:?}: mesh {d} vs sphere {da} (bound {bound})"
        );
        if da.abs() > gap {
            worst = worst.max((d - da).abs());
        }
    }
    // The inscribed mesh is inside the sphere: mesh distance ≥ sphere's.
    // And the bound is approached (it is not vacuous).
    assert!(worst > 0.3 * gap, "worst {worst} vs gap {gap}");
}

#[test]
fn mesh_sdf_dual_derivative_is_its_gradient() {
    // distance_grad_local lifts the f64 result to first order: ∂d/∂p = g.
    let md = MeshDistance::new(&box_mesh()).unwrap();
    let mut rng = Rng(6);
    for _ in 0..200 {
        let p = rng.vec(1.0);
        let (d, g) = md.distance_grad_local(Vec3::new(Dual::<3>::var(p.x, 0), Dual::var(p.y, 1), Dual::var(p.z, 2)));
        let (df, gf) = md.signed_distance(p);
        assert_eq!(d.re, df);
        assert_eq!(g.re(), gf);
        assert_eq!(d.eps, gf.to_array());
    }
}

#[test]
fn grid_baked_from_the_mesh_matches_grid_baked_from_the_shape() {
    let (lo, hi, h) = ([-0.8, -0.7, -0.75], [0.8, 0.7, 0.75], 0.05);
    let mut rng = Rng(7);
    // Box: the mesh SDF equals the box SDF to 1e-9, so the f32 node values
    // match to one f32 ulp (≤ 1.2e-7 for |d| ≤ 1).
    let gm = SdfGrid::bake(&MeshDistance::new(&box_mesh()).unwrap(), lo, hi, h).unwrap();
    let ga = SdfGrid::bake(&CUBOID, lo, hi, h).unwrap();
    assert_eq!(gm.dims(), ga.dims());
    for (a, b) in gm.values().iter().zip(ga.values()) {
        assert!((a - b).abs() <= 1.2e-7, "node {a} vs {b}");
    }
    // Ball: node values differ by ≤ 2·gap (+ f32 rounding); interpolated
    // values then differ by no more, far within half a voxel.
    let m = ball_mesh();
    let gap = tessellation_gap(&m, SPHERE.radius) + 1e-12;
    let gm = SdfGrid::bake(&MeshDistance::new(&m).unwrap(), lo, hi, h).unwrap();
    let ga = SdfGrid::bake(&SPHERE, lo, hi, h).unwrap();
    for (a, b) in gm.values().iter().zip(ga.values()) {
        assert!(((a - b).abs() as f64) <= 2.0 * gap + 2e-7, "node {a} vs {b}");
    }
    let top = ga.max_corner();
    for _ in 0..5000 {
        let p = V::new(
            rng.range(lo[0], top[0]),
            rng.range(lo[1], top[1]),
            rng.range(lo[2], top[2]),
        );
        let (a, b) = (gm.distance_local(p), ga.distance_local(p));
        assert!((a - b).abs() <= (2.0 * gap + 2e-7).min(0.5 * h), "{p:?}: {a} vs {b}");
    }
}

/// The mesh with every face's winding reversed (normals pointing in).
fn flipped(m: &TriMesh) -> TriMesh {
    TriMesh::new(m.vertices.clone(), m.faces.iter().map(|f| [f[0], f[2], f[1]]).collect())
}

#[test]
fn inside_out_mesh_is_turned_outward() {
    // A consistently oriented mesh with inward normals has negative volume;
    // MeshDistance turns it, so signs and gradients are those of the outward mesh.
    let m = flipped(&box_mesh());
    assert!(
        (exact_winding(&m, Vec3::new(0.0, 0.0, 0.0)) + 1.0).abs() < 1e-9,
        "the raw mesh winds −1 inside"
    );
    let md = MeshDistance::new(&m).unwrap();
    let (inside, outside) = points_off_surface(&CUBOID, 8, 500, 1.2, 0.01);
    for p in inside.iter().chain(&outside) {
        let w = md.winding_number(*p);
        let expect = if CUBOID.distance_local(*p) < 0.0 { 1.0 } else { 0.0 };
        assert!((w - expect).abs() < WINDING_TOL, "winding {w} at {p:?}");
        let (d, da) = (md.signed_distance(*p).0, CUBOID.distance_local(*p));
        assert!((d - da).abs() < 1e-9, "{p:?}: {d} vs {da}");
    }
}

#[test]
fn slightly_open_mesh_still_gets_the_sign() {
    // Drop one of the 216 triangles of the n = 6 box mesh: the winding number
    // inside becomes 1 − Ω_hole/4π, still far above 0.5 away from the hole.
    let mut m = cuboid_mesh(&CUBOID, 6);
    let removed = m.triangle(0);
    m.faces.remove(0);
    let hole = removed.iter().fold(V::zero(), |a, v| a + V::cst(*v)) * (1.0 / 3.0);
    let md = MeshDistance::new(&m).unwrap();
    let (inside, outside) = points_off_surface(&CUBOID, 9, 500, 1.2, 0.02);
    for p in inside.iter().filter(|p| (**p - hole).norm() > 0.1) {
        let w = md.winding_number(*p);
        assert!(w > 0.8 && w < 1.0 + WINDING_TOL, "inside {p:?}: winding {w}");
        assert!(md.signed_distance(*p).0 < 0.0);
    }
    for p in outside.iter().filter(|p| (**p - hole).norm() > 0.1) {
        assert!(md.winding_number(*p) < 0.2);
        assert!(md.signed_distance(*p).0 > 0.0);
    }
}

#[test]
fn on_the_surface_the_distance_is_zero() {
    let md = MeshDistance::new(&box_mesh()).unwrap();
    for p in [V::new(0.5, 0.1, -0.2), V::new(-0.2, 0.3, 0.1), V::new(0.5, 0.3, 0.4)] {
        let (d, g) = md.signed_distance(p);
        assert!(d.abs() < 1e-15, "{p:?}: {d}");
        assert!((g.norm() - 1.0).abs() < 1e-15);
    }
}

#[test]
fn on_and_very_near_a_face_the_gradient_is_the_face_normal() {
    let md = MeshDistance::new(&box_mesh()).unwrap();
    for (p, n) in [
        (V::new(0.5, 0.1, -0.2), V::new(1.0, 0.0, 0.0)),
        (V::new(0.5 + 1e-13, 0.1, -0.2), V::new(1.0, 0.0, 0.0)),
        (V::new(0.1, -0.3, 0.05), V::new(0.0, -1.0, 0.0)),
        (V::new(0.1, 0.2, -0.4 + 1e-13), V::new(0.0, 0.0, -1.0)),
    ] {
        let (_, g) = md.signed_distance(p);
        assert!((g - n).norm() < 1e-9, "{p:?}: gradient {g:?}, face normal {n:?}");
    }
}

#[test]
fn construction_errors() {
    assert!(matches!(
        MeshDistance::new(&TriMesh::default()),
        Err(MeshSdfError::Empty)
    ));
    let verts_only = TriMesh::new(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![]);
    assert!(matches!(MeshDistance::new(&verts_only), Err(MeshSdfError::Empty)));
    let bad = TriMesh::new(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 3]]);
    match MeshDistance::new(&bad) {
        Err(MeshSdfError::BadIndex { face, index, count }) => assert_eq!((face, index, count), (0, 3, 3)),
        other => panic!("expected BadIndex, got {other:?}"),
    }
    let nan = TriMesh::new(vec![[0.0; 3], [1.0, f64::NAN, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]);
    assert!(matches!(MeshDistance::new(&nan), Err(MeshSdfError::NotFinite(1))));
    assert_eq!(MeshSdfError::Empty.to_string(), "the mesh has no triangles");
}
