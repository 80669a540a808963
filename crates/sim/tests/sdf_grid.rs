//! `SdfGrid`: baked spheres and boxes against their analytic SDFs, the
//! trilinear gradient against dual numbers and central differences, the
//! extension outside the grid box, the `PGASDF01` byte format (round trip and
//! malformed input) and save/load through a temporary directory.
//!
//! Error bounds used below, for a grid of spacing h:
//! - trilinear interpolation of a C² function errs by at most
//!   (h²/8)·Σᵢ max|∂ᵢᵢf| over the cell; for a sphere SDF Σᵢ ∂ᵢᵢf = 2/|x|, so
//!   the bound is h²/(4ρ) with ρ the cell's smallest distance to the centre;
//! - where the SDF is affine on the whole cell (a box, inside one face's
//!   region) interpolation is exact and only the f32 storage rounding
//!   (≤ 6e-8·|d|) remains;
//! - each component of the trilinear gradient is a weighted mean of forward
//!   differences along cell edges, each equal to ∂f at some edge point ξ, so
//!   it errs by at most max‖H‖·|ξ − x| ≤ √3·h/ρ for the sphere (‖H‖ = 1/ρ),
//!   plus f32 rounding / h;
//! - anything 1-Lipschitz interpolated from nodes within a cell errs by less
//!   than the cell's half diagonal; "within half a voxel" (h/2) holds for the
//!   sphere and box because their kinks are thin (checked, not assumed).

use geom::{Dual, Vec3};
use sim::sdf::{Cuboid, GridError, Sdf, SdfGrid, Sphere};
use std::path::Path;
use testkit::{check_jacobian, GradTolerance};

type V = Vec3<f64>;

use geom::SplitMix64 as Rng;

const H: f64 = 0.05;
const LO: [f64; 3] = [-1.0, -0.9, -1.1];
const HI: [f64; 3] = [1.0, 0.9, 1.0];
const SPHERE: Sphere = Sphere { radius: 0.6 };
const CUBOID: Cuboid = Cuboid { half: [0.5, 0.3, 0.4] };

fn sphere_grid() -> SdfGrid {
    SdfGrid::bake(&SPHERE, LO, HI, H).expect("valid bounds")
}
fn cuboid_grid() -> SdfGrid {
    SdfGrid::bake(&CUBOID, LO, HI, H).expect("valid bounds")
}

/// Cell index and fractional coordinates of `p` (inside the grid).
fn cell_of(g: &SdfGrid, p: V) -> ([usize; 3], [f64; 3]) {
    let mut c = [0; 3];
    let mut u = [0.0; 3];
    for a in 0..3 {
        let f = (p[a] - g.origin()[a]) / g.spacing();
        let i = (f.floor().max(0.0) as usize).min(g.dims()[a] - 2);
        c[a] = i;
        u[a] = f - i as f64;
    }
    (c, u)
}

fn node(g: &SdfGrid, i: [usize; 3]) -> V {
    V::new(
        g.origin()[0] + i[0] as f64 * g.spacing(),
        g.origin()[1] + i[1] as f64 * g.spacing(),
        g.origin()[2] + i[2] as f64 * g.spacing(),
    )
}

fn corners(g: &SdfGrid, c: [usize; 3]) -> Vec<V> {
    (0..8)
        .map(|k| node(g, [c[0] + (k & 1), c[1] + ((k >> 1) & 1), c[2] + ((k >> 2) & 1)]))
        .collect()
}

/// Which affine piece of the box SDF a point is in: inside, the nearest face
/// (axis, side); outside, the set of axes beyond the box (only single-axis
/// sets are affine). `None` when not affine or within `margin` of a switch.
fn box_piece(p: V, h: [f64; 3], margin: f64) -> Option<(usize, i8)> {
    let q: Vec<f64> = (0..3).map(|a| p[a].abs() - h[a]).collect();
    let beyond: Vec<usize> = (0..3).filter(|&a| q[a] > -margin).collect();
    if q.iter().any(|&v| v > 0.0) {
        // Outside: affine only beyond exactly one face, away from the others.
        if beyond.len() == 1 && p[beyond[0]].abs() > margin {
            let a = beyond[0];
            return Some((a, if p[a] > 0.0 { 1 } else { -1 }));
        }
        return None;
    }
    let mut faces: Vec<(f64, usize, i8)> = (0..3)
        .flat_map(|a| [(h[a] - p[a], a, 1i8), (h[a] + p[a], a, -1i8)])
        .collect();
    faces.sort_by(|x, y| x.0.total_cmp(&y.0));
    (faces[1].0 - faces[0].0 > margin).then_some((faces[0].1, faces[0].2))
}

#[test]
fn baked_dims_cover_the_bounds() {
    let g = sphere_grid();
    assert_eq!(g.origin(), LO);
    assert_eq!(g.spacing(), H);
    assert_eq!(g.values().len(), g.dims().iter().product::<usize>());
    let top = g.max_corner();
    for a in 0..3 {
        assert!(top[a] >= HI[a] - 1e-12 && top[a] < HI[a] + H, "axis {a}: {top:?}");
    }
    // Node values are the analytic SDF rounded to f32.
    for (k, &v) in g.values().iter().enumerate().step_by(97) {
        let (nx, ny) = (g.dims()[0], g.dims()[1]);
        let p = node(&g, [k % nx, (k / nx) % ny, k / (nx * ny)]);
        assert_eq!(v, SPHERE.distance_local(p) as f32);
        // Trilinear at a node is the node value (the node may land at u = 1 of
        // the previous cell after rounding, hence 1e-12 rather than equality).
        assert!((g.distance_local(p) - v as f64).abs() < 1e-12);
    }
}

#[test]
fn sphere_values_match_the_analytic_sdf() {
    let g = sphere_grid();
    let mut rng = Rng(1);
    let mut worst_ratio: f64 = 0.0;
    for _ in 0..20000 {
        let p = rng.in_box(LO, g.max_corner());
        let (d, a) = (g.distance_local(p), SPHERE.distance_local(p));
        let err = (d - a).abs();
        assert!(err <= 0.5 * H, "{p:?}: grid {d} vs analytic {a}");
        // Away from the centre, the curvature bound h²/(4ρ) (ρ = smallest
        // |x| on the cell, ≥ |p| − √3 h) is much tighter than h/2.
        let rho = p.norm() - 3f64.sqrt() * H;
        if rho > 0.1 {
            let bound = H * H / (4.0 * rho) + 6e-8 * (a.abs() + H);
            assert!(err <= bound, "{p:?}: error {err:e} above the curvature bound {bound:e}");
            worst_ratio = worst_ratio.max(err / bound);
        }
    }
    // The bound is not vacuous: the worst point uses a fair part of it.
    assert!(worst_ratio > 0.2, "worst error is only {worst_ratio} of the bound");
}

#[test]
fn cuboid_values_exact_where_affine_and_within_half_a_voxel_elsewhere() {
    let g = cuboid_grid();
    let mut rng = Rng(2);
    let mut affine = 0;
    for _ in 0..20000 {
        let p = rng.in_box(LO, g.max_corner());
        let (d, a) = (g.distance_local(p), CUBOID.distance_local(p));
        assert!((d - a).abs() <= 0.5 * H, "{p:?}: grid {d} vs analytic {a}");
        let (c, _) = cell_of(&g, p);
        let pieces: Vec<_> = corners(&g, c)
            .into_iter()
            .map(|x| box_piece(x, CUBOID.half, 1e-9))
            .collect();
        if pieces[0].is_some() && pieces.iter().all(|x| *x == pieces[0]) {
            affine += 1;
            // f32 rounding of values ≤ 1.5: 1.5 · 2⁻²⁴ ≈ 9e-8.
            assert!(
                (d - a).abs() < 2e-7,
                "{p:?} in an affine cell: grid {d} vs analytic {a}"
            );
        }
    }
    assert!(affine > 4000, "only {affine} points in affine cells");
}

#[test]
fn gradient_near_the_surface() {
    let mut rng = Rng(3);
    // Sphere: |x| within 0.1 of the radius; bound √3 h/ρ + f32/h per component.
    let g = sphere_grid();
    for _ in 0..3000 {
        let p = loop {
            let p = rng.in_box(LO, g.max_corner());
            if (p.norm() - SPHERE.radius).abs() < 0.1 {
                break p;
            }
        };
        let (_, gg) = g.distance_grad_local(p);
        let (_, ga) = SPHERE.distance_grad_local(p);
        let rho = p.norm() - 3f64.sqrt() * H;
        let bound = 3f64.sqrt() * H / rho + 1e-5;
        for a in 0..3 {
            assert!(
                (gg[a] - ga[a]).abs() <= bound,
                "{p:?}: grid grad {gg:?} vs {ga:?} (bound {bound})"
            );
        }
        // As a direction it is good to a few degrees.
        let cos = gg.dot(ga) / gg.norm();
        assert!(cos > 0.99, "{p:?}: cos angle {cos}");
    }
    // Box: within 0.1 of a face and ≥ 1e-9 from every piece switch over the
    // whole cell (so away from edges and medial planes): exact up to
    // f32 rounding / h ≈ 2e-6.
    let g = cuboid_grid();
    let mut checked = 0;
    for _ in 0..20000 {
        let p = rng.in_box(LO, g.max_corner());
        if CUBOID.distance_local(p).abs() > 0.1 {
            continue;
        }
        let (c, _) = cell_of(&g, p);
        let pieces: Vec<_> = corners(&g, c)
            .into_iter()
            .map(|x| box_piece(x, CUBOID.half, 1e-9))
            .collect();
        if pieces[0].is_none() || pieces.iter().any(|x| *x != pieces[0]) {
            continue;
        }
        checked += 1;
        let (_, gg) = g.distance_grad_local(p);
        let (_, ga) = CUBOID.distance_grad_local(p);
        assert!((gg - ga).norm() < 1e-5, "{p:?}: grid grad {gg:?} vs {ga:?}");
    }
    assert!(checked > 1000, "only {checked} near-surface affine points");
}

fn seeded(p: V) -> Vec3<Dual<3>> {
    Vec3::new(Dual::var(p.x, 0), Dual::var(p.y, 1), Dual::var(p.z, 2))
}

#[test]
fn dual_derivative_of_the_trilinear_value_is_its_gradient() {
    // The returned gradient is the exact derivative of the piecewise
    // trilinear value, so the two agree to rounding (1e-9 is generous).
    let mut rng = Rng(4);
    for g in [sphere_grid(), cuboid_grid()] {
        let mut pts: Vec<V> = (0..5000).map(|_| rng.in_box(LO, g.max_corner())).collect();
        // Exactly on nodes, faces and the far corner too (the cell choice
        // there is a convention, but value and gradient must stay coherent).
        pts.push(node(&g, [3, 4, 5]));
        pts.push(V::new(node(&g, [7, 0, 0]).x, 0.123, -0.321));
        pts.push(V::cst(g.max_corner()));
        pts.push(V::cst(g.origin()));
        for p in pts {
            let (d, gd) = g.distance_grad_local(seeded(p));
            let (df, gf) = g.distance_grad_local(p);
            assert!((d.re - df).abs() < 1e-12);
            assert!((gd.re() - gf).norm() < 1e-12);
            for a in 0..3 {
                assert!(
                    (d.eps[a] - gf[a]).abs() < 1e-9,
                    "{p:?}: ∂d/∂x{a} {} vs gradient {}",
                    d.eps[a],
                    gf[a]
                );
            }
        }
    }
}

#[test]
fn gradient_matches_central_differences_inside_a_cell() {
    // Within a cell the value is trilinear (degree 1 per axis), so central
    // differences are exact up to rounding (1e-16/eps ≈ 1e-10). Points whose
    // fractional coordinates are within 1e-4 of a cell face are skipped so the
    // ±1e-6 stencil stays in the cell.
    let tol = GradTolerance {
        eps: 1e-6,
        abs_tol: 1e-8,
        rel_tol: 0.0,
        pass_fraction: 1.0,
    };
    let names = ["x", "y", "z"].map(String::from);
    let mut rng = Rng(5);
    for g in [sphere_grid(), cuboid_grid()] {
        let mut checked = 0;
        for _ in 0..3000 {
            let p = rng.in_box(LO, g.max_corner());
            let (_, u) = cell_of(&g, p);
            if u.iter().any(|&t| !(1e-4..=1.0 - 1e-4).contains(&t)) {
                continue;
            }
            checked += 1;
            let (_, grad) = g.distance_grad_local(p);
            let f = |x: &[f64]| vec![g.distance_local(V::new(x[0], x[1], x[2]))];
            check_jacobian("grid", &f, &p.to_array(), &[grad.to_array().to_vec()], &names, tol)
                .unwrap_or_else(|e| panic!("at {p:?}: {e}"));
        }
        assert!(checked > 2900);
    }
}

/// The nearest point of the grid box.
fn clamp_to(g: &SdfGrid, p: V) -> V {
    let hi = g.max_corner();
    V::new(
        p.x.clamp(g.origin()[0], hi[0]),
        p.y.clamp(g.origin()[1], hi[1]),
        p.z.clamp(g.origin()[2], hi[2]),
    )
}

#[test]
fn outside_the_grid_box_the_distance_grows() {
    let g = sphere_grid();
    let hi = g.max_corner();
    let mut rng = Rng(6);
    for _ in 0..2000 {
        let p = rng.in_box([-3.0; 3], [3.0; 3]);
        let c = clamp_to(&g, p);
        let out = p - c;
        if out.norm() < 1e-3 {
            continue;
        }
        let d = g.distance_local(p);
        // The value at the nearest box point plus the distance to it.
        assert!((d - (g.distance_local(c) + out.norm())).abs() < 1e-12, "{p:?}");
        // Moving further out along the outward direction adds exactly the
        // distance moved; the gradient's clamped components are those of
        // that direction (the others carry the grid's in-plane slope).
        let n = out * (1.0 / out.norm());
        for t in [0.01, 0.5, 2.0] {
            assert!((g.distance_local(p + n * t) - (d + t)).abs() < 1e-12);
        }
        let (_, grad) = g.distance_grad_local(p);
        for a in 0..3 {
            let clamped = p[a] < g.origin()[a] || p[a] > hi[a];
            if clamped {
                assert!((grad[a] - n[a]).abs() < 1e-12, "{p:?}: {grad:?} vs {n:?}");
            }
        }
        // Never below the analytic distance minus the in-box error: the
        // sphere lies well inside the box, so outside it the baked grid is
        // a conservative (larger-or-equal) estimate.
        assert!(d >= SPHERE.distance_local(p) - 0.5 * H);
    }
    // Continuity across the box faces.
    for a in 0..3 {
        for (side, face) in [(-1.0, g.origin()[a]), (1.0, hi[a])] {
            let mut p = V::new(0.1, -0.2, 0.15).to_array();
            p[a] = face;
            let on = g.distance_local(V::cst(p));
            p[a] = face + side * 1e-9;
            let off = g.distance_local(V::cst(p));
            assert!((on - off).abs() < 2e-9, "axis {a}, side {side}: {on} vs {off}");
        }
    }
}

#[test]
fn outside_the_grid_box_the_gradient_is_the_derivative_of_the_distance() {
    let g = sphere_grid();
    let mut rng = Rng(7);
    for _ in 0..500 {
        let p = rng.in_box([-3.0; 3], [3.0; 3]);
        if (p - clamp_to(&g, p)).norm() < 1e-3 {
            continue;
        }
        let (d, _) = g.distance_grad_local(seeded(p));
        let (_, grad) = g.distance_grad_local(p);
        for a in 0..3 {
            assert!(
                (d.eps[a] - grad[a]).abs() < 1e-9,
                "{p:?}: ∂d/∂x{a} = {} but gradient {}",
                d.eps[a],
                grad[a]
            );
        }
    }
}

/// The lower bound over a ball holds for every point of it, on a grid whose values are far from a distance
/// (a sphere's, scaled up threefold and roughened), for balls inside, across and outside the grid box; and it
/// is not empty-handed: over a ball far from the surface it stays above zero.
#[test]
fn the_lower_bound_over_a_ball_holds_for_every_point_in_it() {
    let base = sphere_grid();
    let mut rng = Rng::new(17);
    let values: Vec<f32> = base
        .values()
        .iter()
        .map(|&v| (3.0 * v as f64 + 0.02 * rng.range(-1.0, 1.0)) as f32)
        .collect();
    let g = SdfGrid::from_values(base.origin(), base.spacing(), base.dims(), values).unwrap();
    let mut worst = f64::INFINITY;
    for trial in 0..400 {
        // Centres up to 0.4 beyond the grid box, radii from a tenth of a cell to five cells.
        let c = V::new(rng.range(-1.4, 1.4), rng.range(-1.3, 1.3), rng.range(-1.5, 1.4));
        let r = rng.range(0.1 * H, 5.0 * H);
        let bound = g.lower_bound_in_ball(c, r);
        for _ in 0..200 {
            let p = c + rng.dir() * (r * rng.next_f64().cbrt());
            let d = g.distance_local(p);
            assert!(
                d >= bound - 1e-12,
                "trial {trial}: {d} < bound {bound} (centre {c:?}, radius {r})"
            );
            worst = worst.min(d - bound);
        }
    }
    assert!(worst >= -1e-12);
    // The sphere's surface is at 0.6 from the origin: a ball of 0.05 about (0, 0, 0.9) is far from it.
    assert!(g.lower_bound_in_ball(V::new(0.0, 0.0, 0.9), 0.05) > 0.3);
    // The exact shapes' bound is their distance less the radius.
    assert!((SPHERE.lower_bound_in_ball(V::new(0.0, 0.0, 0.9), 0.05) - 0.25).abs() < 1e-12);
}

#[test]
fn bytes_round_trip_exactly() {
    for g in [sphere_grid(), cuboid_grid()] {
        let b = g.to_bytes();
        assert_eq!(&b[..8], b"PGASDF01");
        assert_eq!(b.len(), 52 + 4 * g.values().len());
        assert_eq!(u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize, g.dims()[0]);
        assert_eq!(f64::from_le_bytes(b[44..52].try_into().unwrap()), g.spacing());
        let back = SdfGrid::from_bytes(&b, Path::new("mem.sdf")).expect("round trip");
        assert_eq!(back, g);
        assert_eq!(back.to_bytes(), b);
    }
    // Values that are not the f32 of a nice number survive bit for bit.
    let v: Vec<f32> = (0..2 * 3 * 4).map(|i| (i as f32 * 0.1).sin() * 1e-3 - 7.25e5).collect();
    let g = SdfGrid::from_values([0.1, -1e-7, 3.3], 0.013, [2, 3, 4], v).unwrap();
    let back = SdfGrid::from_bytes(&g.to_bytes(), Path::new("x")).unwrap();
    assert_eq!(back, g);
}

fn assert_format_error(r: Result<SdfGrid, GridError>, path: &Path, what: &str) {
    match r {
        Err(GridError::Format { path: p, msg }) => {
            assert_eq!(p, path, "{what}");
            assert!(!msg.is_empty());
        }
        other => panic!("{what}: expected GridError::Format, got {other:?}"),
    }
}

#[test]
fn malformed_bytes_give_format_errors() {
    let path = Path::new("some/dir/broken.sdf");
    let good = cuboid_grid().to_bytes();
    // Truncated anywhere: inside the magic, inside the header, inside values.
    for n in [0, 3, 8, 20, 51, 52, 53, good.len() - 4, good.len() - 1] {
        assert_format_error(
            SdfGrid::from_bytes(&good[..n], path),
            path,
            &format!("truncated to {n}"),
        );
    }
    // One byte too many.
    let mut long = good.clone();
    long.push(0);
    assert_format_error(SdfGrid::from_bytes(&long, path), path, "trailing byte");
    // Wrong magic (and the right magic of another version).
    for magic in [b"PGASDF02", b"NOTASDF!", b"pgasdf01"] {
        let mut b = good.clone();
        b[..8].copy_from_slice(magic);
        assert_format_error(SdfGrid::from_bytes(&b, path), path, "wrong magic");
    }
    // A dimension below 2 (the byte count still matching).
    let mut g1 = SdfGrid::from_values([0.0; 3], 1.0, [2, 2, 2], vec![0.0; 8])
        .unwrap()
        .to_bytes();
    g1[8..12].copy_from_slice(&1u32.to_le_bytes());
    g1.truncate(52 + 4 * 4);
    assert_format_error(SdfGrid::from_bytes(&g1, path), path, "dims 1");
    // Non-positive or NaN spacing, NaN origin, NaN value.
    for (off, bad) in [(44, 0.0f64), (44, -0.5), (44, f64::NAN), (20, f64::NAN)] {
        let mut b = good.clone();
        b[off..off + 8].copy_from_slice(&bad.to_le_bytes());
        assert_format_error(SdfGrid::from_bytes(&b, path), path, &format!("{bad} at byte {off}"));
    }
    let mut b = good.clone();
    b[60..64].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_format_error(SdfGrid::from_bytes(&b, path), path, "NaN value");
}

#[test]
fn huge_dims_in_the_header_give_a_format_error() {
    let path = Path::new("huge.sdf");
    let mut b = cuboid_grid().to_bytes();
    for off in [8, 12, 16] {
        b[off..off + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    }
    assert_format_error(SdfGrid::from_bytes(&b, path), path, "dims u32::MAX");
}

#[test]
fn infinite_spacing_is_rejected() {
    let r = SdfGrid::bake(&SPHERE, LO, HI, f64::INFINITY);
    assert!(matches!(r, Err(GridError::Bounds(_))), "bake: {r:?}");
    let path = Path::new("inf.sdf");
    let mut b = cuboid_grid().to_bytes();
    b[44..52].copy_from_slice(&f64::INFINITY.to_le_bytes());
    assert_format_error(SdfGrid::from_bytes(&b, path), path, "infinite spacing");
}

#[test]
fn invalid_bounds_are_rejected() {
    for (min, max, h) in [
        (LO, HI, 0.0),
        (LO, HI, -0.1),
        (LO, HI, f64::NAN),
        (HI, LO, 0.1),
        ([0.0; 3], [1.0, 0.0, 1.0], 0.1),
        ([f64::NAN, 0.0, 0.0], [1.0; 3], 0.1),
        ([0.0; 3], [f64::INFINITY, 1.0, 1.0], 0.1),
        ([0.0; 3], [1.0; 3], 1e-4), // 10001³ nodes, above the 512³ cap
    ] {
        let r = SdfGrid::bake(&SPHERE, min, max, h);
        assert!(matches!(r, Err(GridError::Bounds(_))), "{min:?}..{max:?} h={h}: {r:?}");
    }
    assert!(matches!(
        SdfGrid::from_values([0.0; 3], 1.0, [2, 2, 2], vec![0.0; 7]),
        Err(GridError::Bounds(_))
    ));
    assert!(matches!(
        SdfGrid::from_values([0.0; 3], 1.0, [2, 2, 1], vec![0.0; 4]),
        Err(GridError::Bounds(_))
    ));
    assert!(matches!(
        SdfGrid::from_values([0.0; 3], 0.0, [2, 2, 2], vec![0.0; 8]),
        Err(GridError::Bounds(_))
    ));
}

/// A unique scratch directory under the system temp dir, removed on drop.
struct TempDir(std::path::PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        let dir = std::env::temp_dir().join(format!("pganeus-sdf-grid-{tag}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create temp dir");
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn save_and_load_through_a_temp_dir() {
    let dir = TempDir::new("save");
    let path = dir.0.join("sphere.sdf");
    let g = sphere_grid();
    g.save(&path).expect("save");
    // The temporary file was renamed away.
    assert!(!path.with_extension("sdf.tmp").exists());
    let back = SdfGrid::load(&path).expect("load");
    assert_eq!(back, g);
    // Saving again overwrites in place.
    let c = cuboid_grid();
    c.save(&path).expect("overwrite");
    assert_eq!(SdfGrid::load(&path).unwrap(), c);
    assert_eq!(std::fs::read_dir(&dir.0).unwrap().count(), 1);
    // A missing file is an Io error carrying the path.
    let missing = dir.0.join("missing.sdf");
    match SdfGrid::load(&missing) {
        Err(GridError::Io { path, .. }) => assert_eq!(path, missing),
        other => panic!("expected Io error, got {other:?}"),
    }
    // A garbage file is a Format error carrying the path.
    let junk = dir.0.join("junk.sdf");
    std::fs::write(&junk, b"hello").unwrap();
    assert_format_error(SdfGrid::load(&junk), &junk, "junk file");
    // Saving into a directory that does not exist is an Io error.
    let nowhere = dir.0.join("no/such/dir/x.sdf");
    assert!(matches!(g.save(&nowhere), Err(GridError::Io { .. })));
    let kept = dir.0.clone();
    drop(dir);
    assert!(!kept.exists(), "temp dir cleaned up");
}

#[test]
fn smoothing_keeps_planes_and_removes_roughness() {
    let dims = [12, 10, 9];
    let (origin, h) = ([-0.1, -0.2, -0.05], 0.01);
    let plane = |i: usize, j: usize, k: usize| {
        let p = [0, 1, 2].map(|a| origin[a] + [i, j, k][a] as f64 * h);
        // A tilted plane's signed distance: linear in the position.
        (0.3 * p[0] - 0.2 * p[1] + 0.93 * p[2] - 0.004) / (0.3f64 * 0.3 + 0.2 * 0.2 + 0.93 * 0.93).sqrt()
    };
    let mut rng = geom::SplitMix64::new(4);
    let (mut clean, mut rough) = (Vec::new(), Vec::new());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let d = plane(i, j, k);
                clean.push(d as f32);
                rough.push((d + rng.range(-5e-4, 5e-4)) as f32);
            }
        }
    }
    let g = SdfGrid::from_values(origin, h, dims, clean.clone())
        .unwrap()
        .smoothed(1.5);
    for (a, b) in g.values().iter().zip(&clean) {
        assert!(
            (a - b).abs() < 1e-6,
            "a plane must stay where it is, borders included: {a} vs {b}"
        );
    }
    let err =
        |v: &[f32]| (v.iter().zip(&clean).map(|(a, b)| ((a - b) as f64).powi(2)).sum::<f64>() / v.len() as f64).sqrt();
    let rough_grid = SdfGrid::from_values(origin, h, dims, rough.clone()).unwrap();
    let before = err(rough_grid.values());
    let after = err(rough_grid.smoothed(1.5).values());
    assert!(after < 0.35 * before, "roughness {before:.2e} → {after:.2e}");
    assert_eq!(rough_grid.smoothed(0.0), rough_grid);
}

/// Grid files (`bake --out`), mutated: refused or read, never a panic, and a read one has finite values.
#[test]
fn mutated_grid_files_are_refused_or_read_never_a_panic() {
    let seeds = vec![sphere_grid().to_bytes(), cuboid_grid().to_bytes()];
    let r = testkit::fuzz::fuzz("grid", &seeds, 3000, 11, |b| {
        match SdfGrid::from_bytes(b, Path::new("g.sdf")) {
            Ok(g) => {
                assert!(g.distance_local(V::new(0.0, 0.0, 0.0)).is_finite());
                true
            }
            Err(_) => false,
        }
    });
    println!("{r}");
    assert!(r.panics.is_empty(), "{r}: {:?}", r.panics.first());
    assert!(r.accepted > 0 && r.accepted < r.cases, "{r}");
}
