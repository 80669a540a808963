//! Forward-mode dual numbers: every elementary function's derivative against
//! its closed form and central differences, `atan2` in all four quadrants,
//! a composite function, `Quat::exp` at exactly φ = 0 (its Taylor branch),
//! `Quat::log` there, `Quat::normalize_or_identity`, and the named fallbacks
//! of `Vec3::normalize_or` for near-zero vectors.
//!
//! Finite differences here are central with step `h = 1e-6` unless stated:
//! truncation `h²|f'''|/6 ≲ 1e-12` and rounding `ε|f|/h ≲ 1e-10` for the
//! arguments used (|f| ≤ ~10), so `1e-8 + 1e-8·|f'|` is a safe yet tight bound.

use geom::{Dual, Quat, Real, Vec3};
use std::f64::consts::PI;

type D1 = Dual<1>;

/// Central difference of a scalar function.
fn cd(f: impl Fn(f64) -> f64, x: f64, h: f64) -> f64 {
    (f(x + h) - f(x - h)) / (2.0 * h)
}

/// Central-difference gradient of `f: R^n → R`.
fn cd_grad(f: impl Fn(&[f64]) -> f64, x: &[f64], h: f64) -> Vec<f64> {
    (0..x.len())
        .map(|j| {
            let mut xp = x.to_vec();
            let mut xm = x.to_vec();
            xp[j] += h;
            xm[j] -= h;
            (f(&xp) - f(&xm)) / (2.0 * h)
        })
        .collect()
}

fn close(a: f64, b: f64, abs: f64, rel: f64) -> bool {
    (a - b).abs() <= abs + rel * a.abs().max(b.abs())
}

/// Check `f` on a dual number against its closed-form derivative (to
/// rounding) and against central differences of its `f64` version.
fn check_unary(name: &str, fd: impl Fn(D1) -> D1, ff: impl Fn(f64) -> f64, df: impl Fn(f64) -> f64, xs: &[f64]) {
    for &x in xs {
        let y = fd(D1::var(x, 0));
        assert_eq!(y.re, ff(x), "{name}({x}): value part");
        let exact = df(x);
        // The dual rule is the closed form itself, evaluated once: a few ulps.
        assert!(
            close(y.eps[0], exact, 0.0, 1e-15),
            "{name}'({x}) = {}, expected {exact}",
            y.eps[0]
        );
        let num = cd(&ff, x, 1e-6);
        assert!(
            close(y.eps[0], num, 1e-8, 1e-8),
            "{name}'({x}) = {}, central difference {num}",
            y.eps[0]
        );
    }
}

#[test]
fn elementary_functions() {
    check_unary(
        "sqrt",
        |d| d.sqrt(),
        f64::sqrt,
        |x| 0.5 / x.sqrt(),
        &[0.01, 0.5, 1.0, 2.0, 9.0, 123.4],
    );
    let angles = [-3.0, -1.5, -0.2, 0.0, 0.7, std::f64::consts::FRAC_PI_2, 2.5, 6.0];
    check_unary("sin", |d| d.sin(), f64::sin, f64::cos, &angles);
    check_unary("cos", |d| d.cos(), f64::cos, |x| -x.sin(), &angles);
    check_unary("exp", |d| d.exp(), f64::exp, f64::exp, &[-5.0, -1.0, 0.0, 0.3, 2.0]);
    check_unary("ln", |d| d.ln(), f64::ln, |x| 1.0 / x, &[0.05, 0.5, 1.0, 3.0, 10.0]);
    check_unary(
        "recip",
        |d| d.recip(),
        |x| 1.0 / x,
        |x| -1.0 / (x * x),
        &[-4.0, -0.3, 0.25, 2.0],
    );
    check_unary("abs", |d| d.abs(), f64::abs, f64::signum, &[-2.0, -0.1, 0.1, 3.0]);
}

#[test]
fn sqrt_at_zero_has_no_finite_derivative() {
    // Documented in dual.rs: d√x is infinite at 0 and callers guard it.
    let s = D1::var(0.0, 0).sqrt();
    assert_eq!(s.re, 0.0);
    assert!(!s.is_finite());
    assert!(Real::is_finite(D1::var(4.0, 0).sqrt()));
}

#[test]
fn atan2_all_quadrants() {
    // y = slot 0, x = slot 1. Sixteen directions (four per quadrant, at least
    // 0.1 rad off the axes) at three radii, plus the axes where atan2 is
    // smooth: (y, x) = (0, 1), (1, 0), (−1, 0), (2, 1e-9). Not the negative
    // x axis: that is the branch cut (y = 0, x < 0), where finite differences
    // in y jump by 2π; the dual rule's derivative there is checked below.
    let mut pts = Vec::new();
    for k in 0..16 {
        let a = -PI + 0.1 + k as f64 * (2.0 * PI / 16.0);
        for r in [0.01, 1.0, 30.0] {
            pts.push((r * a.sin(), r * a.cos()));
        }
    }
    pts.extend([(0.0, 1.0), (1.0, 0.0), (-1.0, 0.0), (2.0, 1e-9)]);
    for &(y0, x0) in &pts {
        let v = Dual::<2>::var(y0, 0).atan2(Dual::<2>::var(x0, 1));
        assert_eq!(v.re, y0.atan2(x0));
        let r2 = x0 * x0 + y0 * y0;
        let exact = [x0 / r2, -y0 / r2];
        let h = 1e-6 * r2.sqrt();
        let num = cd_grad(|p| p[0].atan2(p[1]), &[y0, x0], h);
        for s in 0..2 {
            assert!(
                close(v.eps[s], exact[s], 0.0, 1e-15),
                "atan2 at ({y0}, {x0}) slot {s}: {}",
                v.eps[s]
            );
            // Relative step, so the error bounds scale with 1/r.
            assert!(
                close(v.eps[s], num[s], 1e-8 / r2.sqrt(), 1e-8),
                "atan2 at ({y0}, {x0}) slot {s}: dual {} vs fd {}",
                v.eps[s],
                num[s]
            );
        }
    }
    // On the branch cut: the dual value is the one-sided limit from above (π)
    // and the derivative in y is x / r² = −1, the same on both sides.
    let v = Dual::<2>::var(0.0, 0).atan2(Dual::<2>::var(-1.0, 1));
    assert_eq!(v.re, PI);
    assert_eq!(v.eps, [-1.0, 0.0]);
}

#[test]
fn arithmetic_and_division() {
    let pairs = [(1.5, -0.25), (-3.0, 7.0), (0.1, 0.2), (1e3, -1e-3)];
    for &(a0, b0) in &pairs {
        let (a, b) = (Dual::<2>::var(a0, 0), Dual::<2>::var(b0, 1));
        let q = a / b;
        assert_eq!(q.re, a0 / b0);
        // d(a/b) = (1/b, −a/b²)
        assert!(close(q.eps[0], 1.0 / b0, 0.0, 1e-15));
        assert!(close(q.eps[1], -a0 / (b0 * b0), 0.0, 1e-15));
        // Steps relative to each argument: h = 1e-6 |x|, so the relative
        // truncation (h/b)² ≤ 1e-12 and rounding ε/1e-6 ≈ 1e-10.
        let num = [cd(|a| a / b0, a0, 1e-6 * a0.abs()), cd(|b| a0 / b, b0, 1e-6 * b0.abs())];
        for s in 0..2 {
            assert!(
                close(q.eps[s], num[s], 0.0, 1e-8),
                "a/b at ({a0},{b0}): {} vs {}",
                q.eps[s],
                num[s]
            );
        }
        let p = a * b;
        assert_eq!(p.eps, [b0, a0]);
        assert_eq!((a + b).eps, [1.0, 1.0]);
        assert_eq!((a - b).eps, [1.0, -1.0]);
        assert_eq!((-a).eps, [-1.0, 0.0]);
        // With plain numbers on the right: constants carry no derivative.
        assert_eq!((a + 2.0).eps, [1.0, 0.0]);
        assert_eq!((a - 2.0).eps, [1.0, 0.0]);
        assert_eq!((a * 3.0).eps, [3.0, 0.0]);
        assert_eq!((a / 4.0).eps, [0.25, 0.0]);
        // The assign forms equal the binary ones.
        let mut c = a;
        c *= b;
        assert_eq!(c, a * b);
        c /= b;
        assert!(close(c.re, a0, 0.0, 1e-15));
        c += b;
        c -= a;
        assert!(close(c.eps[1], 1.0, 0.0, 1e-15));
    }
}

#[test]
fn min_max_clamp_take_the_chosen_sides_derivative() {
    let (a, b) = (Dual::<2>::var(1.0, 0), Dual::<2>::var(2.0, 1));
    assert_eq!(a.max(b).eps, [0.0, 1.0]);
    assert_eq!(a.min(b).eps, [1.0, 0.0]);
    // Outside the interval the result is a constant, inside it is untouched.
    assert_eq!(b.clamp(0.0, 1.5), Dual::new(1.5));
    assert_eq!(a.clamp(0.0, 1.5), a);
    assert_eq!((-b).clamp(0.0, 1.5), Dual::new(0.0));
}

/// A composite `R³ → R` exercising every rule.
fn composite<S: Real>(x: S, y: S, z: S) -> S {
    let a = (x.sin() * y).exp() / (z * z + 1.0).sqrt();
    let b = (x * z).cos() + 2.0;
    let c = y.atan2(x - 3.0) * x;
    a + b.ln() - c + (y * y + 0.5).recip() * z
}

#[test]
fn composite_function() {
    let pts = [[0.3, -0.7, 1.2], [-1.1, 0.4, -0.5], [2.0, 1.5, 0.1], [0.0, 0.0, 0.0]];
    for p in pts {
        let v = composite(
            Dual::<3>::var(p[0], 0),
            Dual::<3>::var(p[1], 1),
            Dual::<3>::var(p[2], 2),
        );
        // Dual division is a · (1/b), not a / b: each quotient differs by an
        // ulp, and the sum of terms of size ~3 carries that to ~1e-15.
        assert!(close(v.re, composite(p[0], p[1], p[2]), 1e-14, 0.0));
        let num = cd_grad(|q| composite(q[0], q[1], q[2]), &p, 1e-6);
        for s in 0..3 {
            assert!(
                close(v.eps[s], num[s], 1e-8, 1e-8),
                "at {p:?} slot {s}: dual {} vs fd {}",
                v.eps[s],
                num[s]
            );
        }
    }
}

fn dual_vec(p: [f64; 3]) -> Vec3<Dual<3>> {
    Vec3::new(Dual::var(p[0], 0), Dual::var(p[1], 1), Dual::var(p[2], 2))
}

/// `d(w, x, y, z)/dφ` of `Quat::exp` by central differences, `[component][slot]`.
fn quat_exp_fd(phi: [f64; 3], h: f64) -> [[f64; 3]; 4] {
    let mut j = [[0.0; 3]; 4];
    for s in 0..3 {
        let (mut pp, mut pm) = (phi, phi);
        pp[s] += h;
        pm[s] -= h;
        let (qp, qm) = (
            Quat::<f64>::exp(Vec3::cst(pp)).to_array(),
            Quat::<f64>::exp(Vec3::cst(pm)).to_array(),
        );
        for c in 0..4 {
            j[c][s] = (qp[c] - qm[c]) / (2.0 * h);
        }
    }
    j
}

#[test]
fn quat_exp_derivative_at_exactly_zero() {
    // φ = 0 exactly takes the Taylor branch (θ² < 1e-12). The derivative there
    // is dw/dφ = 0 and d(x, y, z)/dφ = I/2. Finite differences with h = 1e-4
    // step into the closed-form branch; their truncation error is
    // (sin(h/2)/h − 1/2) ≈ h²/48 ≈ 2e-10, hence the 1e-9 bound.
    let q = Quat::exp(dual_vec([0.0; 3]));
    assert_eq!(q.re().to_array(), [1.0, 0.0, 0.0, 0.0]);
    let comps = q.to_array();
    for (c, comp) in comps.iter().enumerate() {
        for s in 0..3 {
            let expected = if c > 0 && c - 1 == s { 0.5 } else { 0.0 };
            assert_eq!(comp.eps[s], expected, "d q[{c}] / dφ[{s}] at φ = 0");
        }
    }
    let fd = quat_exp_fd([0.0; 3], 1e-4);
    for c in 0..4 {
        for s in 0..3 {
            assert!(
                (comps[c].eps[s] - fd[c][s]).abs() < 1e-9,
                "q[{c}]/φ[{s}]: {} vs {}",
                comps[c].eps[s],
                fd[c][s]
            );
        }
    }
}

#[test]
fn quat_exp_derivative_on_both_sides_of_the_taylor_switch() {
    // θ = 5e-7 (Taylor) and θ = 2e-6 (closed form); central differences with
    // h = 1e-4 as above. Far from 0, h = 1e-6 gives ~1e-10.
    for (phi, h) in [
        ([3e-7, -4e-7, 0.0], 1e-4),
        ([1.2e-6, 0.0, -1.6e-6], 1e-4),
        ([0.3, -1.2, 0.8], 1e-6),
        ([2.0, 1.0, -0.5], 1e-6),
    ] {
        let q = Quat::exp(dual_vec(phi)).to_array();
        let fd = quat_exp_fd(phi, h);
        for c in 0..4 {
            for s in 0..3 {
                assert!(
                    (q[c].eps[s] - fd[c][s]).abs() < 1e-9,
                    "φ = {phi:?}: q[{c}]/φ[{s}] dual {} vs fd {}",
                    q[c].eps[s],
                    fd[c][s]
                );
            }
        }
        // The derivative keeps |q| = 1: q · dq = 0.
        for s in 0..3 {
            let radial: f64 = q.iter().map(|c| c.re * c.eps[s]).sum();
            assert!(radial.abs() < 1e-15);
        }
    }
}

#[test]
fn quat_log_derivative_at_identity_is_identity() {
    // log(exp(φ)) = φ, so its Jacobian at φ = 0 (both small-angle branches)
    // is exactly I.
    let back = Quat::exp(dual_vec([0.0; 3])).log();
    for (i, c) in back.to_array().iter().enumerate() {
        let mut e = [0.0; 3];
        e[i] = 1.0;
        assert_eq!(c.re, 0.0);
        assert_eq!(c.eps, e, "d log(exp(φ))[{i}] / dφ");
    }
}

#[test]
fn normalize_or_identity_derivative() {
    // d(q/|q|)/dq = (I − q̂ q̂ᵀ) / |q|; compare with central differences.
    for q0 in [[1.0, 2.0, -0.5, 0.3], [0.01, -0.02, 0.005, 0.0], [-3.0, 0.0, 0.0, 4.0]] {
        let q = Quat::new(
            Dual::<4>::var(q0[0], 0),
            Dual::var(q0[1], 1),
            Dual::var(q0[2], 2),
            Dual::var(q0[3], 3),
        );
        let n = q.normalize_or_identity().to_array();
        let len = q0.iter().map(|v| v * v).sum::<f64>().sqrt();
        let h = 1e-6 * len;
        for c in 0..4 {
            for s in 0..4 {
                let exact = ((c == s) as u8 as f64 - q0[c] * q0[s] / (len * len)) / len;
                let (mut qp, mut qm) = (q0, q0);
                qp[s] += h;
                qm[s] -= h;
                let f = |a: [f64; 4]| Quat::<f64>::cst(a).normalize_or_identity().to_array()[c];
                let num = (f(qp) - f(qm)) / (2.0 * h);
                assert!(close(n[c].eps[s], exact, 1e-15 / len, 1e-14), "{q0:?} [{c}][{s}]");
                assert!(
                    close(n[c].eps[s], num, 1e-8 / len, 1e-8),
                    "{q0:?} [{c}][{s}] dual {} vs fd {num}",
                    n[c].eps[s]
                );
            }
        }
    }
    // Below 1e-12 the fallback is the identity, a constant.
    let tiny = Quat::new(
        Dual::<4>::var(1e-13, 0),
        Dual::var(0.0, 1),
        Dual::var(0.0, 2),
        Dual::var(0.0, 3),
    );
    assert_eq!(tiny.normalize_or_identity(), Quat::identity());
    assert_eq!(Quat::<f64>::cst([0.0; 4]).normalize_or_identity(), Quat::identity());
}

#[test]
fn vec3_normalize_or_near_zero_returns_the_fallback() {
    let fb = Vec3::new(0.0, 0.0, 1.0);
    for v in [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1e-13, 0.0, 0.0),
        Vec3::new(-3e-13, 4e-13, 0.0),
        Vec3::new(5e-13, -5e-13, 5e-13),
        Vec3::new(1e-300, 0.0, -1e-300),
    ] {
        assert_eq!(v.normalize_or(fb), fb, "{v:?}");
        assert!(v.try_normalize().is_none());
    }
    // Just above the 1e-12 threshold the vector is normalised.
    let n = Vec3::new(2e-12, 0.0, 0.0).normalize_or(fb);
    assert!((n.x - 1.0).abs() < 1e-15 && n.y == 0.0 && n.z == 0.0, "{n:?}");
    let n = Vec3::new(3.0, -4.0, 0.0).normalize_or(fb);
    assert!((n.x - 0.6).abs() < 1e-15 && (n.y + 0.8).abs() < 1e-15);
    // Dual numbers: the zero vector gives the fallback with its own
    // derivatives (here none), never the NaNs of d√x at 0.
    let z = dual_vec([0.0; 3]).normalize_or(Vec3::cst([1.0, 0.0, 0.0]));
    assert_eq!(z, Vec3::cst([1.0, 0.0, 0.0]));
    assert!(z.is_finite());
    // And a regular vector has derivative (I − n nᵀ)/|v|.
    let p = [0.3, -1.2, 0.4];
    let nd = dual_vec(p).normalize_or(Vec3::cst([1.0, 0.0, 0.0]));
    let len = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    for c in 0..3 {
        let num = cd_grad(|q| Vec3::new(q[0], q[1], q[2]).normalize_or(fb)[c], &p, 1e-6);
        for s in 0..3 {
            let exact = ((c == s) as u8 as f64 - p[c] * p[s] / (len * len)) / len;
            assert!(close(nd[c].eps[s], exact, 1e-15, 1e-14));
            assert!(close(nd[c].eps[s], num[s], 1e-8, 1e-8));
        }
    }
}
