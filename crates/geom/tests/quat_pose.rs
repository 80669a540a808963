//! Quaternions, poses and 3×3 matrices: Hamilton product, matrix round trips
//! (random rotations plus angles near 0 and near π), SO(3)/SE(3) exp/log round
//! trips, the left Jacobian against a finite-difference definition and a
//! cancellation-free reference, `try_inverse`, `det` and `rotation_distance`.
//!
//! Tolerances: every map here is well conditioned for the inputs chosen, so
//! results agree to a few hundred ulps. Where a bound is looser than `1e-12`
//! the reason is given next to it.

use geom::{left_jacobian, rotation_distance, Mat3, Pose, Quat, Vec3};
use std::f64::consts::PI;

use geom::SplitMix64 as Rng;

/// The unit quaternion of angle `theta` about unit `axis`, built directly
/// (not through `Quat::exp`).
fn axis_angle(axis: Vec3<f64>, theta: f64) -> Quat<f64> {
    let (s, c) = (0.5 * theta).sin_cos();
    Quat::new(c, axis.x * s, axis.y * s, axis.z * s)
}

fn vdist(a: Vec3<f64>, b: Vec3<f64>) -> f64 {
    (a - b).norm()
}

fn mdist(a: &Mat3<f64>, b: &Mat3<f64>) -> f64 {
    let mut m: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            m = m.max((a.m[i][j] - b.m[i][j]).abs());
        }
    }
    m
}

/// Distance between quaternions up to sign (q and −q are the same rotation).
fn qdist_signless(a: Quat<f64>, b: Quat<f64>) -> f64 {
    let (a, b) = (a.to_array(), b.to_array());
    let plus = (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max);
    let minus = (0..4).map(|i| (a[i] + b[i]).abs()).fold(0.0, f64::max);
    plus.min(minus)
}

/// Random rotations plus hand-picked angles near 0 and near π (including
/// exactly π, where `w = 0` and the sign of `q` is ambiguous).
fn test_rotations() -> Vec<Quat<f64>> {
    let mut rng = Rng(0x5EED_0001);
    let mut qs: Vec<Quat<f64>> = (0..2000).map(|_| rng.quat()).collect();
    let axes = [
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(1.0, 1.0, 1.0) * (1.0 / 3f64.sqrt()),
        Vec3::new(-0.3, 0.8, 0.52).normalize_or(Vec3::new(1.0, 0.0, 0.0)),
    ];
    for _ in 0..20 {
        let ax = rng.dir();
        for &delta in &[0.0, 1e-12, 1e-9, 1e-6, 1e-3, 0.1] {
            qs.push(axis_angle(ax, delta));
            qs.push(axis_angle(ax, PI - delta));
        }
    }
    for ax in axes {
        for &delta in &[0.0, 1e-12, 1e-9, 1e-6, 1e-3] {
            qs.push(axis_angle(ax, delta));
            qs.push(axis_angle(ax, PI - delta));
            qs.push(axis_angle(ax, -(PI - delta)));
        }
    }
    qs
}

#[test]
fn hamilton_basis_products() {
    // i j = k, j k = i, k i = j and i² = −1 pin the Hamilton (not JPL) convention.
    let i = Quat::<f64>::cst([0.0, 1.0, 0.0, 0.0]);
    let j = Quat::<f64>::cst([0.0, 0.0, 1.0, 0.0]);
    let k = Quat::<f64>::cst([0.0, 0.0, 0.0, 1.0]);
    assert_eq!((i * j).to_array(), [0.0, 0.0, 0.0, 1.0]);
    assert_eq!((j * k).to_array(), [0.0, 1.0, 0.0, 0.0]);
    assert_eq!((k * i).to_array(), [0.0, 0.0, 1.0, 0.0]);
    assert_eq!((j * i).to_array(), [0.0, 0.0, 0.0, -1.0]);
    assert_eq!((i * i).to_array(), [-1.0, 0.0, 0.0, 0.0]);
    // A right-handed quarter turn about z takes x to y.
    let qz = axis_angle(Vec3::new(0.0, 0.0, 1.0), 0.5 * PI);
    let r = qz.rotate(Vec3::new(1.0, 0.0, 0.0));
    assert!(vdist(r, Vec3::new(0.0, 1.0, 0.0)) < 1e-15, "{r:?}");
}

#[test]
fn hamilton_product_equals_rotating_twice() {
    let mut rng = Rng(11);
    for _ in 0..500 {
        let (a, b) = (rng.quat(), rng.quat());
        let v = rng.vec(3.0);
        let once = (a * b).rotate(v);
        let twice = a.rotate(b.rotate(v));
        // |v| ≤ 3√3, a handful of roundings per rotation.
        assert!(
            vdist(once, twice) < 1e-13,
            "a={a:?} b={b:?} v={v:?}: {once:?} vs {twice:?}"
        );
        // The matrix of a product is the product of the matrices.
        assert!(mdist(&(a * b).to_mat(), &a.to_mat().mul_mat(&b.to_mat())) < 1e-14);
        // Rotation preserves length.
        assert!((once.norm() - v.norm()).abs() < 1e-13);
    }
}

#[test]
fn to_mat_is_a_rotation_matching_rotate() {
    let mut rng = Rng(12);
    for q in test_rotations() {
        let r = q.to_mat();
        let rrt = r.mul_mat(&r.transpose());
        assert!(mdist(&rrt, &Mat3::identity()) < 1e-14, "R Rᵀ ≠ I for {q:?}");
        assert!((r.det() - 1.0).abs() < 1e-14, "det R = {} for {q:?}", r.det());
        let v = rng.vec(2.0);
        assert!(
            vdist(r.mul_vec(v), q.rotate(v)) < 1e-14,
            "to_mat and rotate disagree for {q:?}"
        );
    }
}

#[test]
fn from_mat_round_trip_many_rotations() {
    // Every branch of from_mat divides by 4× a component that is ≥ 1/2 (the
    // trace branch has w = √(1 + tr)/2 ≥ 1/2; otherwise the largest diagonal
    // gives the largest of x², y², z², ≥ (1 − w²)/3 ≥ 1/4), so the round trip
    // is good to a few ulps even at angle π; 1e-14 leaves headroom.
    for q in test_rotations() {
        let back = Quat::from_mat(&q.to_mat());
        assert!(back.w >= 0.0, "from_mat must return w ≥ 0, got {back:?}");
        let e = qdist_signless(q, back);
        assert!(e < 1e-14, "from_mat(to_mat(q)) = {back:?} for q = {q:?} (err {e:e})");
        assert!((back.norm() - 1.0).abs() < 1e-15);
    }
}

#[test]
fn so3_exp_matches_axis_angle_and_log_inverts_it() {
    let mut rng = Rng(13);
    let mut cases = Vec::new();
    for _ in 0..1000 {
        cases.push(rng.dir() * rng.range(0.0, PI));
    }
    for _ in 0..20 {
        let ax = rng.dir();
        // Near 0 (both the Taylor branches of exp/log and just past them) and
        // up to just below π.
        for &th in &[
            0.0,
            1e-300,
            1e-12,
            1e-9,
            0.99e-6,
            1.01e-6,
            1e-8,
            2e-8,
            1e-4,
            PI - 1e-3,
            PI - 1e-6,
            PI - 1e-9,
        ] {
            cases.push(ax * th);
        }
    }
    for phi in cases {
        let th = phi.norm();
        let q = Quat::exp(phi);
        let reference = if th > 0.0 {
            axis_angle(phi * (1.0 / th), th)
        } else {
            Quat::identity()
        };
        assert!(
            qdist_signless(q, reference) < 1e-15,
            "exp({phi:?}) = {q:?}, expected {reference:?}"
        );
        assert!((q.norm() - 1.0).abs() < 1e-15);
        let back = q.log();
        // log goes through atan2(|v|, w), which is well conditioned for every
        // angle in [0, π): errors are ~1e-16 · π.
        assert!(vdist(back, phi) < 1e-14, "log(exp({phi:?})) = {back:?}, θ = {th}");
        // The angle in [0, π].
        assert!((q.angle() - th).abs() < 1e-14);
        // exp(log(q)) = q (log picks w ≥ 0, and so does exp for θ < π).
        let again = Quat::exp(back);
        assert!(qdist_signless(again, q) < 1e-15);
    }
}

#[test]
fn log_of_q_and_minus_q_agree() {
    let mut rng = Rng(14);
    for q in test_rotations().into_iter().chain((0..200).map(|_| rng.quat())) {
        if q.w == 0.0 {
            // Angle exactly π: ±π·axis are both valid logs; nothing to compare.
            continue;
        }
        let neg = Quat::new(-q.w, -q.x, -q.y, -q.z);
        let (a, b) = (q.log(), neg.log());
        // log flips to w ≥ 0 first, so both follow the very same path.
        assert_eq!(a, b, "log(q) ≠ log(−q) for q = {q:?}");
        assert!(a.norm() <= PI + 1e-15);
    }
}

#[test]
fn log_at_exactly_pi_has_angle_pi() {
    for ax in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.6, 0.8)] {
        let q = Quat::new(0.0, ax.x, ax.y, ax.z);
        let phi = q.log();
        assert!((phi.norm() - PI).abs() < 1e-15, "{phi:?}");
        assert!(vdist(phi * (1.0 / PI), ax) < 1e-15 || vdist(phi * (-1.0 / PI), ax) < 1e-15);
    }
}

fn random_pose(rng: &mut Rng) -> Pose<f64> {
    Pose::new(rng.quat(), rng.vec(5.0))
}

#[test]
fn pose_compose_inverse_and_point_round_trips() {
    let mut rng = Rng(15);
    for _ in 0..500 {
        let (a, b) = (random_pose(&mut rng), random_pose(&mut rng));
        let p = rng.vec(4.0);
        // compose = first b, then a.
        let ab = a.compose(&b);
        let lhs = ab.transform_point(p);
        let rhs = a.transform_point(b.transform_point(p));
        // Values up to ~|t| + |p| ≈ 15, a few roundings each.
        assert!(vdist(lhs, rhs) < 1e-13, "{lhs:?} vs {rhs:?}");
        // Pose ∘ inverse and inverse ∘ pose are the identity.
        for id in [a.compose(&a.inverse()), a.inverse().compose(&a)] {
            assert!(qdist_signless(id.q, Quat::identity()) < 1e-15, "{id:?}");
            assert!(id.t.norm() < 1e-14, "{id:?}");
        }
        // transform_point / inverse_transform_point round trip, both ways.
        assert!(vdist(a.inverse_transform_point(a.transform_point(p)), p) < 1e-14);
        assert!(vdist(a.transform_point(a.inverse_transform_point(p)), p) < 1e-14);
        // inverse_transform_point is transform_point of the inverse.
        assert!(vdist(a.inverse().transform_point(p), a.inverse_transform_point(p)) < 1e-14);
        // Vectors ignore translation.
        let v = rng.vec(1.0);
        assert!(
            vdist(
                a.transform_vector(v),
                a.transform_point(v) - a.transform_point(Vec3::zero())
            ) < 1e-14
        );
        assert!(vdist(a.inverse_transform_vector(a.transform_vector(v)), v) < 1e-14);
        // The homogeneous matrix applies the pose: p_world = R p + t.
        let m = a.to_matrix();
        let mp = Vec3::new(
            m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
            m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
            m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3],
        );
        assert!(vdist(mp, a.transform_point(p)) < 1e-13);
        assert_eq!(m[3], [0.0, 0.0, 0.0, 1.0]);
    }
}

#[test]
fn se3_exp_log_round_trip() {
    let mut rng = Rng(16);
    let mut cases = Vec::new();
    for _ in 0..500 {
        cases.push((rng.vec(3.0), rng.dir() * rng.range(0.0, PI - 1e-3)));
    }
    for _ in 0..10 {
        let (rho, ax) = (rng.vec(3.0), rng.dir());
        for &th in &[0.0, 1e-12, 1e-8, 0.99e-5, 1.01e-5, 1e-3, PI - 1e-2] {
            cases.push((rho, ax * th));
        }
    }
    for (rho, phi) in cases {
        let pose = Pose::exp(rho, phi);
        let (rho2, phi2) = pose.log();
        // V has singular values between 2/π and 1 for θ < π, so inverting it
        // loses at most a factor ~1.6; |rho| ≤ 3√3.
        assert!(vdist(phi2, phi) < 1e-14, "phi {phi:?} -> {phi2:?}");
        assert!(vdist(rho2, rho) < 1e-13, "rho {rho:?} -> {rho2:?} (θ = {})", phi.norm());
        // exp(log(pose)) = pose.
        let again = Pose::exp(rho2, phi2);
        assert!(qdist_signless(again.q, pose.q) < 1e-15);
        assert!(vdist(again.t, pose.t) < 1e-13);
    }
}

#[test]
fn se3_exp_translation_is_left_jacobian_times_rho() {
    let mut rng = Rng(17);
    for _ in 0..200 {
        let (rho, phi) = (rng.vec(2.0), rng.dir() * rng.range(0.0, 3.0));
        let pose = Pose::exp(rho, phi);
        assert!(vdist(pose.t, left_jacobian(phi).mul_vec(rho)) < 1e-15);
        assert!(qdist_signless(pose.q, Quat::exp(phi)) == 0.0);
    }
    // A pure translation twist is a pure translation.
    let rho = Vec3::new(0.3, -1.0, 2.0);
    let p = Pose::exp(rho, Vec3::zero());
    assert_eq!(p.t, rho);
    assert_eq!(p.q, Quat::identity());
    assert_eq!(left_jacobian(Vec3::<f64>::zero()), Mat3::identity());
}

/// `V(φ)` from cancellation-free formulas: `(1 − cos θ)/θ² = 2 sin²(θ/2)/θ²`,
/// and `(θ − sin θ)/θ³` by its series below θ = 0.1 (7 terms, error < 1e-20).
fn left_jacobian_reference(phi: Vec3<f64>) -> Mat3<f64> {
    let th = phi.norm();
    let (a, b) = if th == 0.0 {
        (0.5, 1.0 / 6.0)
    } else {
        let h = (0.5 * th).sin();
        let a = 2.0 * h * h / (th * th);
        let b = if th < 0.1 {
            // Σ (−1)^k θ^{2k} / (2k+3)!
            let t2 = th * th;
            let mut term = 1.0 / 6.0;
            let mut sum = 0.0;
            for k in 0..7 {
                sum += term;
                term *= -t2 / (((2 * k + 4) * (2 * k + 5)) as f64);
            }
            sum
        } else {
            (th - th.sin()) / (th * th * th)
        };
        (a, b)
    };
    let k = Mat3::skew(phi);
    Mat3::identity().add(&k.scale(a)).add(&k.mul_mat(&k).scale(b))
}

#[test]
fn left_jacobian_matches_reference_and_is_continuous_at_the_switch() {
    let mut rng = Rng(18);
    let ax = rng.dir();
    // θ² < 1e-10 (θ < 1e-5) takes the Taylor branch.
    let mut thetas = vec![
        0.0,
        1e-12,
        1e-9,
        1e-7,
        1e-6,
        0.999_999e-5,
        1e-5,
        1.000_001e-5,
        3e-5,
        1e-4,
        1e-3,
        0.1,
        1.0,
        3.0,
    ];
    thetas.extend((0..100).map(|_| rng.range(0.0, PI)));
    for th in thetas {
        let phi = ax * th;
        let (v, r) = (left_jacobian(phi), left_jacobian_reference(phi));
        // The library's large-angle branch computes 1 − cos θ directly; at
        // θ ≈ 1e-5 that has a relative error ~ 1e-16 / 5e-11 ≈ 2e-6, which
        // enters V as a·θ·2e-6 ≈ 1e-11. 1e-10 bounds it with headroom.
        let e = mdist(&v, &r);
        assert!(e < 1e-10, "V(θ = {th:e}) differs from the reference by {e:e}");
    }
    // Either side of the branch switch at θ = 1e-5.
    let below = left_jacobian(ax * (1e-5 * (1.0 - 1e-9)));
    let above = left_jacobian(ax * (1e-5 * (1.0 + 1e-9)));
    assert!(
        mdist(&below, &above) < 1e-10,
        "jump of {:e} at the switch",
        mdist(&below, &above)
    );
}

#[test]
fn left_jacobian_matches_finite_difference_definition() {
    // Definition: exp(φ + δ) = exp(J_l(φ) δ) exp(φ) + O(|δ|²), so column j of
    // J_l is d/dh log(exp(φ + h e_j) exp(φ)⁻¹) at h = 0. Central differences
    // with h = 1e-5: truncation ~ h² = 1e-10, rounding ~ 1e-16 / h = 1e-11.
    let mut rng = Rng(19);
    let h = 1e-5;
    let mut phis: Vec<Vec3<f64>> = (0..100).map(|_| rng.dir() * rng.range(0.0, 3.0)).collect();
    phis.push(Vec3::zero());
    phis.push(Vec3::new(0.0, 0.0, 2e-6));
    for phi in phis {
        let base_inv = Quat::exp(phi).conj();
        let j = left_jacobian(phi);
        for col in 0..3 {
            let mut e = [0.0; 3];
            e[col] = h;
            let ev = Vec3::new(e[0], e[1], e[2]);
            let plus = (Quat::exp(phi + ev) * base_inv).log();
            let minus = (Quat::exp(phi - ev) * base_inv).log();
            let fd = (plus - minus) * (0.5 / h);
            let an = j.col(col);
            assert!(vdist(fd, an) < 1e-8, "φ = {phi:?}, column {col}: fd {fd:?} vs V {an:?}");
        }
    }
}

#[test]
fn mat3_inverse_and_det() {
    let mut rng = Rng(20);
    for _ in 0..500 {
        // Diagonally dominant, so the condition number is below ~10.
        let mut m = Mat3::<f64>::zero();
        for i in 0..3 {
            for j in 0..3 {
                m.m[i][j] = rng.range(-1.0, 1.0) + if i == j { 4.0 } else { 0.0 };
            }
        }
        let inv = m.try_inverse().expect("well-conditioned matrix");
        assert!(mdist(&inv.mul_mat(&m), &Mat3::identity()) < 1e-14);
        assert!(mdist(&m.mul_mat(&inv), &Mat3::identity()) < 1e-14);
        // det(AB) = det A det B, det Aᵀ = det A, det A⁻¹ = 1 / det A.
        let mut n = Mat3::<f64>::zero();
        for i in 0..3 {
            for j in 0..3 {
                n.m[i][j] = rng.range(-2.0, 2.0);
            }
        }
        let (da, db) = (m.det(), n.det());
        assert!((m.mul_mat(&n).det() - da * db).abs() < 1e-12 * (1.0 + (da * db).abs()));
        assert!((m.transpose().det() - da).abs() < 1e-13 * da.abs());
        assert!((inv.det() * da - 1.0).abs() < 1e-14);
    }
    // Known values.
    assert_eq!(Mat3::diag(Vec3::new(2.0, 3.0, -4.0)).det(), -24.0);
    // A unimodular integer matrix: the adjugate and det are exact in f64.
    let m = Mat3::from_rows([[1.0, 2.0, 3.0], [0.0, 1.0, 4.0], [5.0, 6.0, 0.0]]);
    assert_eq!(m.det(), 1.0);
    let inv = m.try_inverse().unwrap();
    assert_eq!(inv.m, [[-24.0, 18.0, 5.0], [20.0, -15.0, -4.0], [-5.0, 4.0, 1.0]]);
}

#[test]
fn mat3_singular_has_no_inverse() {
    // Rank 2, with an exactly-zero determinant in floating point.
    let m = Mat3::from_rows([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]]);
    assert_eq!(m.det(), 0.0);
    assert!(m.try_inverse().is_none());
    assert!(Mat3::<f64>::zero().try_inverse().is_none());
    // Non-finite entries give None, not a matrix of NaNs.
    let mut n = Mat3::<f64>::identity();
    n.m[1][1] = f64::NAN;
    assert!(n.try_inverse().is_none());
    // Tiny but regular matrices are still inverted (the threshold is 1e-300 on det).
    let small = Mat3::<f64>::identity().scale(1e-50);
    let inv = small.try_inverse().expect("det 1e-150 is invertible");
    assert!(mdist(&inv.mul_mat(&small), &Mat3::identity()) < 1e-15);
}

#[test]
fn rotation_distance_is_the_relative_angle() {
    let mut rng = Rng(21);
    for _ in 0..500 {
        let q = rng.quat();
        let delta = rng.dir() * rng.range(0.0, PI - 1e-6);
        let r = q * Quat::exp(delta);
        let d = rotation_distance(q, r);
        assert!((d - delta.norm()).abs() < 1e-13, "{d} vs {}", delta.norm());
        // Symmetric and blind to the sign of either quaternion.
        assert!((rotation_distance(r, q) - d).abs() < 1e-13);
        let neg = Quat::new(-r.w, -r.x, -r.y, -r.z);
        assert!((rotation_distance(q, neg) - d).abs() < 1e-13);
        // Left multiplication by a common rotation leaves it unchanged.
        let g = rng.quat();
        assert!((rotation_distance(g * q, g * r) - d).abs() < 1e-12);
        // Triangle inequality.
        let s = rng.quat();
        assert!(rotation_distance(q, s) <= rotation_distance(q, r) + rotation_distance(r, s) + 1e-12);
    }
    let q = rng.quat();
    assert!(rotation_distance(q, q) < 1e-15);
    assert!(rotation_distance(q, Quat::new(-q.w, -q.x, -q.y, -q.z)) < 1e-15);
    // Two rotations about the same axis: |a − b|, never more than π.
    let ax = rng.dir();
    assert!((rotation_distance(Quat::exp(ax * 0.3), Quat::exp(ax * 2.9)) - 2.6).abs() < 1e-14);
    assert!((rotation_distance(Quat::exp(ax * -2.0), Quat::exp(ax * 2.0)) - (2.0 * PI - 4.0)).abs() < 1e-14);
}
