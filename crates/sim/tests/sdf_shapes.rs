//! The analytic SDFs (Plane, Cuboid, Sphere, RoundedBox, Capsule, Wedge, a
//! Union and a Transformed shape): gradients against central differences,
//! unit gradients, signs at known points, exactness against independent
//! brute-force distances, and dual numbers seeded on the point (first
//! derivatives for every shape, second derivatives for Sphere and Capsule).
//!
//! Staying away from kinks (STYLE habit 9). Each case has a test-side
//! `smooth` rule computed from the shape's features, not from the library:
//! - inside a polytope (box, the inner box of the rounded box, the wedge's
//!   five face planes) the distance is the max of affine pieces; a point is
//!   kept when its two nearest faces differ in distance by more than 1e-4;
//! - outside a convex shape the distance is C¹ with curvature ≤ 1/D, where D
//!   is the distance to the nearest kink carrier (edge, corner, segment,
//!   centre); points with D < 1e-3 are skipped, so the third derivative is
//!   ≤ 1e6 and the central-difference truncation (eps = 1e-6) is ≤ 2e-7;
//! - for the union, points where the two parts' distances differ by less
//!   than 1e-4 (the medial surface between them) are skipped.
//!
//! Both margins are ≥ 100 × eps, so no stencil point crosses a kink.

use geom::{Dual, Pose, Quat, Vec3};
use sim::sdf::{Capsule, Cuboid, Plane, RoundedBox, Sdf, Shape, Sphere, Wedge};
use testkit::{check_jacobian, GradTolerance};

type V = Vec3<f64>;

use geom::SplitMix64 as Rng;

const KINK_MARGIN: f64 = 1e-4;
const CURVATURE_MARGIN: f64 = 1e-3;

// ---------------------------------------------------------------------------
// Test-side geometry: features, smoothness rules and independent distances.

/// Signed plane values `n·p − o` of a convex polytope (inside iff all < 0).
fn box_planes(p: V, h: [f64; 3]) -> Vec<f64> {
    (0..3).flat_map(|a| [p[a] - h[a], -p[a] - h[a]]).collect()
}

fn wedge_planes(p: V, h: [f64; 3]) -> Vec<f64> {
    let [hx, hy, hz] = h;
    let l = (hx * hx + hz * hz).sqrt();
    vec![
        -p.z - hz,                  // bottom z = −hz
        p.x - hx,                   // the high side x = hx
        (-hz * p.x + hx * p.z) / l, // the slope through (−hx, −hz) and (hx, hz)
        p.y - hy,
        -p.y - hy,
    ]
}

/// The polytope rule: inside, the two nearest faces are KINK_MARGIN apart;
/// outside, the distance (≥ the largest plane value) is ≥ CURVATURE_MARGIN.
fn polytope_smooth(planes: &[f64]) -> bool {
    let max = planes.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if max > 0.0 {
        return max > CURVATURE_MARGIN;
    }
    let mut depth: Vec<f64> = planes.iter().map(|v| -v).collect();
    depth.sort_by(f64::total_cmp);
    depth[1] - depth[0] > KINK_MARGIN
}

/// Distance from `p` to the solid box (0 inside).
fn box_outside_distance(p: V, h: [f64; 3]) -> f64 {
    let o: Vec<f64> = (0..3).map(|a| (p[a].abs() - h[a]).max(0.0)).collect();
    (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt()
}

/// Box distance face by face: the closest point on each of the six face
/// rectangles (projection, then clamping), the minimum, and the sign from
/// strict containment. Independent of the library's `|p| − h` formula.
fn box_distance_by_faces(p: V, h: [f64; 3]) -> f64 {
    let mut best = f64::INFINITY;
    for a in 0..3 {
        for s in [-1.0, 1.0] {
            let mut c = [0.0; 3];
            for b in 0..3 {
                c[b] = if b == a { s * h[a] } else { p[b].clamp(-h[b], h[b]) };
            }
            best = best.min((p - V::cst(c)).norm());
        }
    }
    let inside = (0..3).all(|a| p[a].abs() < h[a]);
    if inside {
        -best
    } else {
        best
    }
}

fn capsule_axis_distance(p: V, c: &Capsule) -> f64 {
    let cz = p.z.clamp(-c.half_length, c.half_length);
    V::new(p.x, p.y, p.z - cz).norm()
}

/// Points on a surface and a bound `cover` on the distance from any surface
/// point to the nearest sample: then `|d| ≤ min_k |p − s_k| ≤ |d| + cover`.
struct SurfaceSamples {
    pts: Vec<V>,
    cover: f64,
}

impl SurfaceSamples {
    fn nearest(&self, p: V) -> f64 {
        self.pts
            .iter()
            .map(|s| (*s - p).norm_sq())
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    }
    /// Interval holding the true signed distance, given the sign.
    fn interval(&self, p: V, inside: bool) -> (f64, f64) {
        let d = self.nearest(p);
        if inside {
            (-d, -(d - self.cover))
        } else {
            (d - self.cover, d)
        }
    }
}

/// A parametric grid `a + (i/n)(b − a) + (j/n)(c − a)` over a parallelogram
/// (or the triangle half of it when `triangle`), boundaries included. Every
/// surface point lies in a grid cell whose corner (i, j) is a sample (for the
/// triangle too: s_i + t_j ≤ s + t ≤ 1), and no two points of a cell are
/// further apart than its longer diagonal, which is therefore the cover.
/// The hypotenuse gets its own samples as well (harmless extra points).
fn sample_face(a: V, b: V, c: V, n: usize, triangle: bool, out: &mut SurfaceSamples) {
    let (u, v) = (b - a, c - a);
    for i in 0..=n {
        for j in 0..=n {
            let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
            if triangle && s + t > 1.0 + 1e-12 {
                continue;
            }
            out.pts.push(a + u * s + v * t);
        }
        if triangle {
            // The hypotenuse, at the same density.
            let s = i as f64 / n as f64;
            out.pts.push(a + u * s + v * (1.0 - s));
        }
    }
    let diag = (u * (1.0 / n as f64) + v * (1.0 / n as f64))
        .norm()
        .max((u - v).norm() / n as f64);
    out.cover = out.cover.max(diag);
}

fn wedge_samples(w: &Wedge, n: usize) -> SurfaceSamples {
    let [hx, hy, hz] = w.half;
    let mut s = SurfaceSamples {
        pts: Vec::new(),
        cover: 0.0,
    };
    for y in [-hy, hy] {
        // Triangle (−hx, −hz), (hx, −hz), (hx, hz) at this y.
        let (a, b, c) = (V::new(hx, y, -hz), V::new(-hx, y, -hz), V::new(hx, y, hz));
        sample_face(a, b, c, n, true, &mut s);
    }
    let ey = V::new(0.0, 2.0 * hy, 0.0);
    let lo = V::new(0.0, -hy, 0.0);
    // Bottom, high side and slope, each a rectangle swept along y.
    for (p0, p1) in [
        (V::new(-hx, 0.0, -hz), V::new(hx, 0.0, -hz)),
        (V::new(hx, 0.0, -hz), V::new(hx, 0.0, hz)),
        (V::new(-hx, 0.0, -hz), V::new(hx, 0.0, hz)),
    ] {
        sample_face(p0 + lo, p1 + lo, p0 + lo + ey, n, false, &mut s);
    }
    s
}

/// Latitude/longitude samples of a sphere. From any surface point, walking
/// at most r·dθ/2 along its meridian and then at most r·dφ/2 along a
/// parallel reaches a sample (chords are shorter than arcs), so the cover is
/// at most r (dθ + dφ) / 2.
fn sphere_samples(r: f64, m: usize) -> SurfaceSamples {
    let n = 2 * m;
    let (dth, dph) = (std::f64::consts::PI / m as f64, 2.0 * std::f64::consts::PI / n as f64);
    let mut pts = Vec::new();
    for i in 0..=m {
        let th = i as f64 * dth;
        for j in 0..n {
            let ph = j as f64 * dph;
            pts.push(V::new(r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), r * th.cos()));
        }
    }
    SurfaceSamples {
        pts,
        cover: 0.5 * r * (dth + dph),
    }
}

// ---------------------------------------------------------------------------
// The cases.

type Rule = Box<dyn Fn(V) -> bool>;
type Interval = Box<dyn Fn(V) -> (f64, f64)>;

struct Case {
    name: &'static str,
    shape: Shape,
    /// Sampling box half-width.
    reach: f64,
    smooth: Rule,
    inside: Vec<V>,
    outside: Vec<V>,
    /// An interval holding the true signed distance, from an independent
    /// computation (exact formulas give lo = hi).
    exact: Option<Interval>,
}

fn plane() -> Plane {
    let n = V::new(0.3, -0.2, 0.9).normalize_or(V::new(0.0, 0.0, 1.0));
    Plane {
        normal: n.to_array(),
        offset: 0.25,
    }
}
const CUBOID: Cuboid = Cuboid { half: [0.5, 0.3, 0.8] };
const SPHERE: Sphere = Sphere { radius: 0.7 };
const ROUNDED: RoundedBox = RoundedBox {
    half: [0.6, 0.4, 0.5],
    radius: 0.15,
};
const CAPSULE: Capsule = Capsule {
    half_length: 0.5,
    radius: 0.3,
};
const WEDGE: Wedge = Wedge { half: [0.6, 0.4, 0.3] };

/// Union parts: a ball of radius 0.4 at (−0.8, 0, 0) and a rotated box at
/// (0.7, 0.1, 0.2); they are disjoint, so the min of their SDFs is exact.
const BALL_C: [f64; 3] = [-0.8, 0.0, 0.0];
const BALL_R: f64 = 0.4;
const UBOX_HALF: [f64; 3] = [0.3, 0.2, 0.25];
fn ubox_pose() -> Pose<f64> {
    Pose::new(Quat::exp(V::new(0.3, -0.5, 0.8)), V::new(0.7, 0.1, 0.2))
}
fn wedge_pose() -> Pose<f64> {
    Pose::new(Quat::exp(V::new(-1.1, 0.4, 0.7)), V::new(0.2, -0.3, 0.1))
}

fn union_parts(p: V) -> (f64, f64) {
    let da = (p - V::cst(BALL_C)).norm() - BALL_R;
    let db = box_distance_by_faces(ubox_pose().inverse_transform_point(p), UBOX_HALF);
    (da, db)
}

fn cases() -> Vec<Case> {
    let pl = plane();
    let n = V::cst(pl.normal);
    let t = n.cross(V::new(1.0, 0.0, 0.0)).normalize_or(V::new(0.0, 1.0, 0.0));
    let wedge_bf = std::rc::Rc::new(wedge_samples(&WEDGE, 150));
    let wedge_bf2 = wedge_bf.clone();
    let sphere_bf = sphere_samples(SPHERE.radius, 150);
    let wp = wedge_pose();
    vec![
        Case {
            name: "plane",
            shape: Shape::Plane(pl),
            reach: 1.5,
            smooth: Box::new(|_| true),
            inside: vec![n * (pl.offset - 0.5) + t * 3.0, n * -10.0],
            outside: vec![n * (pl.offset + 0.01) - t * 2.0, n * 5.0],
            exact: Some(Box::new(move |p| {
                let d = p.dot(n) - pl.offset;
                (d, d)
            })),
        },
        Case {
            name: "cuboid",
            shape: Shape::Cuboid(CUBOID),
            reach: 1.5,
            smooth: Box::new(|p| polytope_smooth(&box_planes(p, CUBOID.half))),
            inside: vec![V::zero(), V::new(0.49, -0.29, 0.79), V::new(-0.2, 0.1, -0.7)],
            outside: vec![
                V::new(0.51, 0.0, 0.0),
                V::new(0.0, -0.31, 0.0),
                V::new(0.45, 0.25, 0.85),
            ],
            exact: Some(Box::new(|p| {
                let d = box_distance_by_faces(p, CUBOID.half);
                (d, d)
            })),
        },
        Case {
            name: "sphere",
            shape: Shape::Sphere(SPHERE),
            reach: 1.5,
            smooth: Box::new(|p| p.norm() > CURVATURE_MARGIN),
            inside: vec![V::zero(), V::new(0.69, 0.0, 0.0), V::new(0.4, 0.4, -0.4)],
            outside: vec![V::new(0.0, 0.0, 0.71), V::new(0.5, 0.5, 0.5), V::new(-3.0, 1.0, 0.0)],
            exact: Some(Box::new(move |p| {
                let inside = p.norm() < SPHERE.radius;
                sphere_bf.interval(p, inside)
            })),
        },
        Case {
            name: "rounded box",
            shape: Shape::RoundedBox(ROUNDED),
            reach: 1.5,
            smooth: Box::new(|p| {
                let inner = ROUNDED.half.map(|h| h - ROUNDED.radius);
                let d = box_outside_distance(p, inner);
                if d > 0.0 {
                    d > CURVATURE_MARGIN
                } else {
                    polytope_smooth(&box_planes(p, inner))
                }
            }),
            // The corner (0.6, 0.4, 0.5) is cut off by the rounding: the point
            // just inside the sharp corner is outside the rounded box.
            inside: vec![V::zero(), V::new(0.59, 0.0, 0.0), V::new(0.5, 0.3, 0.4)],
            outside: vec![V::new(0.59, 0.39, 0.49), V::new(0.0, 0.41, 0.0), V::new(1.0, 1.0, 1.0)],
            exact: None,
        },
        Case {
            name: "capsule",
            shape: Shape::Capsule(CAPSULE),
            reach: 1.2,
            smooth: Box::new(|p| capsule_axis_distance(p, &CAPSULE) > CURVATURE_MARGIN),
            inside: vec![
                V::zero(),
                V::new(0.0, 0.0, 0.79),
                V::new(0.29, 0.0, -0.5),
                V::new(0.2, 0.2, 0.1),
            ],
            outside: vec![V::new(0.0, 0.0, 0.81), V::new(0.31, 0.0, 0.0), V::new(0.25, 0.0, 0.75)],
            exact: Some(Box::new(|p| {
                // Dense samples of the axis segment, spacing 2h/K: the
                // nearest sample is within h/K of the closest axis point.
                const K: usize = 4000;
                let h = CAPSULE.half_length;
                let m = (0..=K)
                    .map(|k| (p - V::new(0.0, 0.0, -h + 2.0 * h * k as f64 / K as f64)).norm())
                    .fold(f64::INFINITY, f64::min);
                (m - h / K as f64 - CAPSULE.radius, m - CAPSULE.radius)
            })),
        },
        Case {
            name: "wedge",
            shape: Shape::Wedge(WEDGE),
            reach: 1.0,
            smooth: Box::new(|p| polytope_smooth(&wedge_planes(p, WEDGE.half))),
            // Rising towards +x: near the top of the high side is inside, the
            // same height over the low end is outside.
            inside: vec![
                V::new(0.5, 0.0, 0.2),
                V::new(0.0, 0.39, -0.29),
                V::new(0.59, -0.3, 0.28),
            ],
            outside: vec![
                V::new(-0.5, 0.0, 0.2),
                V::new(0.0, 0.0, 0.01),
                V::new(0.61, 0.0, 0.0),
                V::new(0.3, 0.41, -0.2),
            ],
            exact: Some(Box::new(move |p| {
                let inside = wedge_planes(p, WEDGE.half).iter().all(|&v| v < 0.0);
                wedge_bf.interval(p, inside)
            })),
        },
        Case {
            name: "union",
            shape: Shape::Union(vec![
                Shape::Sphere(Sphere { radius: BALL_R }).transformed(Pose::from_translation(V::cst(BALL_C))),
                Shape::Cuboid(Cuboid { half: UBOX_HALF }).transformed(ubox_pose()),
            ]),
            reach: 1.5,
            smooth: Box::new(|p| {
                let (da, db) = union_parts(p);
                if (da - db).abs() <= KINK_MARGIN {
                    return false;
                }
                if da < db {
                    (p - V::cst(BALL_C)).norm() > CURVATURE_MARGIN
                } else {
                    polytope_smooth(&box_planes(ubox_pose().inverse_transform_point(p), UBOX_HALF))
                }
            }),
            inside: vec![V::cst(BALL_C), V::new(0.7, 0.1, 0.2), V::new(-0.5, 0.1, 0.1)],
            outside: vec![V::zero(), V::new(0.0, 2.0, 0.0), V::new(-1.21, 0.0, 0.0)],
            exact: Some(Box::new(|p| {
                let (da, db) = union_parts(p);
                (da.min(db), da.min(db))
            })),
        },
        Case {
            name: "transformed wedge",
            shape: Shape::Wedge(WEDGE).transformed(wp),
            reach: 1.2,
            smooth: Box::new(move |p| polytope_smooth(&wedge_planes(wp.inverse_transform_point(p), WEDGE.half))),
            inside: vec![
                wp.transform_point(V::new(0.5, 0.0, 0.2)),
                wp.t + wp.transform_vector(V::new(0.3, 0.1, -0.2)),
            ],
            outside: vec![
                wp.transform_point(V::new(-0.5, 0.0, 0.2)),
                wp.transform_point(V::new(0.0, 0.45, 0.0)),
            ],
            exact: Some(Box::new(move |p| {
                let l = wp.inverse_transform_point(p);
                let inside = wedge_planes(l, WEDGE.half).iter().all(|&v| v < 0.0);
                wedge_bf2.interval(l, inside)
            })),
        },
    ]
}

fn random_points(seed: u64, n: usize, reach: f64) -> Vec<V> {
    let mut rng = Rng(seed);
    (0..n).map(|_| rng.vec(reach)).collect()
}

fn grad_of(shape: &Shape, p: V) -> (f64, V) {
    shape.distance_grad_local(p)
}

// ---------------------------------------------------------------------------
// Tests.

#[test]
fn gradient_matches_central_differences_away_from_kinks() {
    // eps = 1e-6: truncation ≤ 2e-7 (see the module doc), rounding ≈ 1e-16/1e-6.
    let tol = GradTolerance {
        eps: 1e-6,
        abs_tol: 1e-6,
        rel_tol: 0.0,
        pass_fraction: 1.0,
    };
    let names = ["x", "y", "z"].map(String::from);
    for case in cases() {
        let mut checked = 0;
        for p in random_points(101, 1500, case.reach) {
            if !(case.smooth)(p) {
                continue;
            }
            checked += 1;
            let (_, g) = grad_of(&case.shape, p);
            let f = |x: &[f64]| vec![case.shape.distance_local(V::new(x[0], x[1], x[2]))];
            check_jacobian(case.name, &f, &p.to_array(), &[g.to_array().to_vec()], &names, tol)
                .unwrap_or_else(|e| panic!("at {p:?}: {e}"));
        }
        assert!(checked > 1000, "{}: only {checked} smooth points", case.name);
    }
}

#[test]
fn gradient_has_unit_length_everywhere() {
    // Exact SDFs have |∇d| = 1 off the kinks; on them the shapes pick one
    // side or a named fallback, so the unit length holds at every sample.
    for case in cases() {
        for p in random_points(102, 3000, case.reach)
            .into_iter()
            .chain(case.inside.clone())
            .chain(case.outside.clone())
        {
            let (d, g) = grad_of(&case.shape, p);
            assert!(d.is_finite() && g.is_finite(), "{} at {p:?}", case.name);
            assert!(
                (g.norm() - 1.0).abs() < 1e-9,
                "{} at {p:?}: |grad| = {}",
                case.name,
                g.norm()
            );
        }
    }
}

#[test]
fn degenerate_points_get_a_finite_unit_gradient() {
    // Sphere centre, a point on the capsule's axis, the box centre (three-way
    // tie of faces), a point on the wedge's medial plane y = 0 at its centre.
    let pts: Vec<(Shape, V)> = vec![
        (Shape::Sphere(SPHERE), V::zero()),
        (Shape::Capsule(CAPSULE), V::new(0.0, 0.0, 0.2)),
        (Shape::Capsule(CAPSULE), V::new(0.0, 0.0, -0.5)),
        (Shape::Cuboid(Cuboid { half: [0.5; 3] }), V::zero()),
        (Shape::RoundedBox(ROUNDED), V::zero()),
        (Shape::Wedge(WEDGE), V::new(0.2, 0.0, -0.1)),
    ];
    for (s, p) in pts {
        let (d, g) = s.distance_grad_local(p);
        assert!(d < 0.0 && d.is_finite(), "{s:?} at {p:?}: {d}");
        assert!((g.norm() - 1.0).abs() < 1e-12, "{s:?} at {p:?}: {g:?}");
    }
    assert_eq!(Shape::Sphere(SPHERE).distance_local(V::zero()), -SPHERE.radius);
    assert_eq!(
        Shape::Capsule(CAPSULE).distance_local(V::new(0.0, 0.0, 0.3)),
        -CAPSULE.radius
    );
}

#[test]
fn sign_at_known_points() {
    for case in cases() {
        for p in &case.inside {
            let d = case.shape.distance_local(*p);
            assert!(d < 0.0, "{}: {p:?} should be inside, d = {d}", case.name);
        }
        for p in &case.outside {
            let d = case.shape.distance_local(*p);
            assert!(d > 0.0, "{}: {p:?} should be outside, d = {d}", case.name);
        }
    }
}

#[test]
fn distances_match_independent_brute_force() {
    for case in cases() {
        let Some(exact) = &case.exact else { continue };
        let n = if case.name.contains("wedge") || case.name == "sphere" {
            250
        } else {
            2000
        };
        let mut pts = random_points(103, n, case.reach);
        pts.extend(case.inside.iter().chain(&case.outside));
        for p in pts {
            let d = case.shape.distance_local(p);
            let (lo, hi) = exact(p);
            // 1e-12 is rounding only: the intervals are exact bounds.
            assert!(
                lo - 1e-12 <= d && d <= hi + 1e-12,
                "{} at {p:?}: d = {d}, independent interval [{lo}, {hi}]",
                case.name
            );
        }
    }
}

#[test]
fn sampled_bounds_are_tight_enough_to_mean_something() {
    // The brute-force intervals above are only useful when narrow.
    let w = wedge_samples(&WEDGE, 150);
    assert!(w.cover < 0.012, "wedge cover {}", w.cover);
    let s = sphere_samples(SPHERE.radius, 150);
    assert!(s.cover < 0.015, "sphere cover {}", s.cover);
}

#[test]
fn rounded_box_is_the_inner_box_grown_by_the_radius() {
    // Outside the inner box, the rounded box's distance is the inner box's
    // (face-wise, independent) minus the radius.
    let inner = ROUNDED.half.map(|h| h - ROUNDED.radius);
    for p in random_points(104, 2000, 1.5) {
        if box_outside_distance(p, inner) > 0.0 {
            let d = Shape::RoundedBox(ROUNDED).distance_local(p);
            let e = box_distance_by_faces(p, inner) - ROUNDED.radius;
            assert!((d - e).abs() < 1e-12, "{p:?}: {d} vs {e}");
        }
    }
}

#[test]
fn world_frame_queries_rotate_the_gradient() {
    // distance_grad(pose, p): the gradient matches central differences of
    // distance(pose, ·) in world coordinates.
    let pose = Pose::new(Quat::exp(V::new(0.4, 1.0, -0.6)), V::new(1.0, -2.0, 0.5));
    let tol = GradTolerance {
        eps: 1e-6,
        abs_tol: 1e-6,
        rel_tol: 0.0,
        pass_fraction: 1.0,
    };
    let names = ["x", "y", "z"].map(String::from);
    for case in cases() {
        for l in random_points(105, 300, case.reach) {
            if !(case.smooth)(l) {
                continue;
            }
            let p = pose.transform_point(l);
            let (d, g) = case.shape.distance_grad(&pose, p);
            let (dl, gl) = case.shape.distance_grad_local(l);
            assert!((d - dl).abs() < 1e-12);
            // p round-trips through the pose with ~1e-15 error, which moves
            // the gradient by up to that over the distance to the nearest
            // kink carrier (≥ |d| here).
            assert!((g - pose.transform_vector(gl)).norm() < 1e-14 * (1.0 + 1.0 / dl.abs()));
            assert!((case.shape.distance(&pose, p) - d).abs() < 1e-15);
            let f = |x: &[f64]| vec![case.shape.distance(&pose, V::new(x[0], x[1], x[2]))];
            check_jacobian(case.name, &f, &p.to_array(), &[g.to_array().to_vec()], &names, tol)
                .unwrap_or_else(|e| panic!("at local {l:?}: {e}"));
        }
    }
}

fn seeded(p: V) -> Vec3<Dual<3>> {
    Vec3::new(Dual::var(p.x, 0), Dual::var(p.y, 1), Dual::var(p.z, 2))
}

#[test]
fn dual_derivative_of_the_distance_is_the_gradient() {
    // Same formulas on both paths, different rounding (the dual path divides
    // by multiplying with a reciprocal). Shapes that normalise `p − closest`
    // (the wedge's polygon, the box outside) amplify that rounding by 1/|d|,
    // so the bound is 1e-14 · (1 + 1/|d|).
    for case in cases() {
        for p in random_points(106, 1000, case.reach) {
            if !(case.smooth)(p) {
                continue;
            }
            let (d, g) = case.shape.distance_grad_local(seeded(p));
            let (df, gf) = case.shape.distance_grad_local(p);
            let tol = 1e-14 * (1.0 + 1.0 / df.abs());
            assert!((d.re - df).abs() < 1e-14, "{} at {p:?}", case.name);
            assert!(
                (g.re() - gf).norm() < tol,
                "{} at {p:?}: {:?} vs {gf:?}",
                case.name,
                g.re()
            );
            for a in 0..3 {
                assert!(
                    (d.eps[a] - gf[a]).abs() < tol,
                    "{} at {p:?}: ∂d/∂x{a} = {} but gradient {}",
                    case.name,
                    d.eps[a],
                    gf[a]
                );
            }
        }
    }
}

/// Hessian check: the dual derivative of the gradient against central
/// differences of the f64 gradient. Points are kept ≥ 0.05 from the axis /
/// centre (Hessian ~ 1/ρ ≤ 20, its derivative ~ 1/ρ² ≤ 400, truncation
/// ≤ 1e-12 · 400 · 1/6 ≈ 1e-10) and, for the capsule, ≥ 1e-4 from the
/// planes |z| = h where the Hessian jumps (cylinder ↔ cap) although the
/// gradient is continuous.
fn hessian_check(name: &str, shape: &Shape, keep: impl Fn(V) -> bool) {
    let tol = GradTolerance {
        eps: 1e-6,
        abs_tol: 1e-7,
        rel_tol: 1e-6,
        pass_fraction: 1.0,
    };
    let names = ["x", "y", "z"].map(String::from);
    let mut checked = 0;
    for p in random_points(107, 1500, 1.3) {
        if !keep(p) {
            continue;
        }
        checked += 1;
        let (_, g) = shape.distance_grad_local(seeded(p));
        let analytic: Vec<Vec<f64>> = (0..3).map(|i| g[i].eps.to_vec()).collect();
        let f = |x: &[f64]| {
            shape
                .distance_grad_local(V::new(x[0], x[1], x[2]))
                .1
                .to_array()
                .to_vec()
        };
        check_jacobian(name, &f, &p.to_array(), &analytic, &names, tol).unwrap_or_else(|e| panic!("at {p:?}: {e}"));
        // The Hessian of an exact SDF annihilates the gradient: H ∇d = 0.
        let gr = g.re();
        for row in &analytic {
            let hv = row[0] * gr.x + row[1] * gr.y + row[2] * gr.z;
            assert!(hv.abs() < 1e-12, "{name} at {p:?}: H∇d = {hv}");
        }
    }
    assert!(checked > 1000, "{name}: only {checked} points");
}

#[test]
fn sphere_hessian_matches_finite_differences() {
    hessian_check("sphere", &Shape::Sphere(SPHERE), |p| p.norm() > 0.05);
    // And equals (I − n nᵀ)/|p| exactly.
    let p = V::new(0.3, -0.4, 1.2);
    let (_, g) = Sphere { radius: 0.7 }.distance_grad_local(seeded(p));
    let (l, n) = (p.norm(), p * (1.0 / p.norm()));
    for i in 0..3 {
        for j in 0..3 {
            let e = ((i == j) as u8 as f64 - n[i] * n[j]) / l;
            assert!((g[i].eps[j] - e).abs() < 1e-15);
        }
    }
}

#[test]
fn capsule_hessian_matches_finite_differences() {
    hessian_check("capsule", &Shape::Capsule(CAPSULE), |p| {
        capsule_axis_distance(p, &CAPSULE) > 0.05 && (p.z.abs() - CAPSULE.half_length).abs() > KINK_MARGIN
    });
}
