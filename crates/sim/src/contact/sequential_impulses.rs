//! Sequential impulses (projected Gauss–Seidel, as Catto's Box2D and Rapier
//! solve contacts) over a set of contact points between a body and the fixed
//! scene or another body: each sweep visits every point and changes its
//! accumulated normal impulse so the point stops approaching (clamped to push
//! only), then its friction impulse in the tangent plane so the point stops
//! slipping (clamped to Coulomb's disc of radius μ × its normal impulse).
//! Restitution comes last, as Box2D and Rapier apply it once the contact set
//! is resolved: the points that approached faster than the threshold are
//! driven, in further sweeps, to `−k_n v_n` (their approach speed before the
//! solve); solving it with the rest made a tipping box bounce off its first
//! corner differently from Rapier (the tipping slide's unfitted error
//! 8.4 → 0.6 mm). Fixed numbers of sweeps, in the generic scalar, so
//! forward-mode dual numbers carry exact derivatives through the clamps.

use geom::{Mat3, Real, Vec3};

/// One side of the contact set: its velocities (changed in place) and inverse mass properties.
pub(crate) struct Side<'a, S> {
    pub v: &'a mut Vec3<S>,
    pub omega: &'a mut Vec3<S>,
    pub inv_mass: f64,
    /// World frame.
    pub inv_inertia: Mat3<S>,
}

/// A contact point: offsets from each side's centre of mass (world axes) and the unit normal pointing from
/// the second side towards the first.
pub(crate) struct Row<S> {
    pub ra: Vec3<S>,
    pub rb: Vec3<S>,
    pub n: Vec3<S>,
}

/// What the solver needs of the contact parameters.
pub(crate) struct Law<S> {
    pub restitution: S,
    pub friction: S,
    /// Approach speeds below this bounce with restitution 0, m/s.
    pub restitution_threshold: f64,
    pub sweeps: usize,
}

impl<S: Real> Law<S> {
    /// The law of a contact with these parameters under `det`'s restitution threshold and sweep count.
    pub fn of(restitution: S, friction: S, det: &super::Detection) -> Self {
        Self {
            restitution,
            friction,
            restitution_threshold: det.restitution_threshold,
            sweeps: det.sweeps,
        }
    }
}

/// Per-row state of a solve.
struct Solving<S> {
    t1: Vec3<S>,
    t2: Vec3<S>,
    mass_n: S,
    mass_t1: S,
    mass_t2: S,
    target: S,
    lambda_n: S,
    lambda_t1: S,
    lambda_t2: S,
}

fn relative<S: Real>(a: &Side<'_, S>, b: &Option<Side<'_, S>>, r: &Row<S>) -> Vec3<S> {
    let va = *a.v + a.omega.cross(r.ra);
    match b {
        Some(b) => va - (*b.v + b.omega.cross(r.rb)),
        None => va,
    }
}

fn apply<S: Real>(a: &mut Side<'_, S>, b: &mut Option<Side<'_, S>>, r: &Row<S>, p: Vec3<S>) {
    *a.v += p * S::cst(a.inv_mass);
    *a.omega += a.inv_inertia.mul_vec(r.ra.cross(p));
    if let Some(b) = b {
        *b.v -= p * S::cst(b.inv_mass);
        *b.omega -= b.inv_inertia.mul_vec(r.rb.cross(p));
    }
}

/// `1 / (u · K u)`: the impulse along `u` per unit of velocity change along `u` at the point.
fn effective_mass<S: Real>(a: &Side<'_, S>, b: &Option<Side<'_, S>>, r: &Row<S>, u: Vec3<S>) -> S {
    let ca = r.ra.cross(u);
    let mut k = S::cst(a.inv_mass) + ca.dot(a.inv_inertia.mul_vec(ca));
    if let Some(b) = b {
        let cb = r.rb.cross(u);
        k = k + S::cst(b.inv_mass) + cb.dot(b.inv_inertia.mul_vec(cb));
    }
    k.recip()
}

/// Two unit vectors completing `n` to an orthonormal frame.
pub(crate) fn tangents<S: Real>(n: Vec3<S>) -> (Vec3<S>, Vec3<S>) {
    let nr = n.re();
    // The world axis least aligned with n.
    let axis = if nr.x.abs() < 0.57 {
        Vec3::new(1.0, 0.0, 0.0)
    } else if nr.y.abs() < 0.57 {
        Vec3::new(0.0, 1.0, 0.0)
    } else {
        Vec3::new(0.0, 0.0, 1.0)
    };
    let t1 = n.cross(Vec3::lift(axis));
    let t1 = t1 * t1.norm().recip();
    (t1, n.cross(t1))
}

/// Solve the contact set `rows` between `a` and `b` (`None`: the fixed scene). Returns how many points
/// pushed (a positive normal impulse).
pub(crate) fn solve<S: Real>(a: &mut Side<'_, S>, mut b: Option<Side<'_, S>>, rows: &[Row<S>], law: &Law<S>) -> usize {
    let mut st: Vec<Solving<S>> = rows
        .iter()
        .map(|r| {
            let (t1, t2) = tangents(r.n);
            let vn0 = relative(a, &b, r).dot(r.n);
            let target = if -vn0.re() > law.restitution_threshold {
                -(law.restitution * vn0)
            } else {
                S::zero()
            };
            Solving {
                t1,
                t2,
                mass_n: effective_mass(a, &b, r, r.n),
                mass_t1: effective_mass(a, &b, r, t1),
                mass_t2: effective_mass(a, &b, r, t2),
                target,
                lambda_n: S::zero(),
                lambda_t1: S::zero(),
                lambda_t2: S::zero(),
            }
        })
        .collect();
    for _ in 0..law.sweeps {
        for (r, s) in rows.iter().zip(st.iter_mut()) {
            // Normal: stop the approach, never pull.
            let vn = relative(a, &b, r).dot(r.n);
            let total = (s.lambda_n - s.mass_n * vn).max(S::zero());
            let dn = total - s.lambda_n;
            s.lambda_n = total;
            apply(a, &mut b, r, r.n * dn);
            // Friction: stop the slip, within μ λ_n.
            let rel = relative(a, &b, r);
            let mut l1 = s.lambda_t1 - s.mass_t1 * rel.dot(s.t1);
            let mut l2 = s.lambda_t2 - s.mass_t2 * rel.dot(s.t2);
            let limit = law.friction * s.lambda_n;
            let len2 = l1 * l1 + l2 * l2;
            if len2.re() > limit.re() * limit.re() {
                if len2.re() > 0.0 {
                    let shrink = limit * len2.sqrt().recip();
                    l1 *= shrink;
                    l2 *= shrink;
                } else {
                    l1 = S::zero();
                    l2 = S::zero();
                }
            }
            let p = s.t1 * (l1 - s.lambda_t1) + s.t2 * (l2 - s.lambda_t2);
            s.lambda_t1 = l1;
            s.lambda_t2 = l2;
            apply(a, &mut b, r, p);
        }
    }
    // Restitution last (as Box2D and Rapier do): the bouncing points' normal velocities driven to their
    // targets once the contact set is resolved.
    for _ in 0..law.sweeps {
        for (r, s) in rows.iter().zip(st.iter_mut()) {
            if s.target.re() <= 0.0 {
                continue;
            }
            let vn = relative(a, &b, r).dot(r.n);
            let total = (s.lambda_n + s.mass_n * (s.target - vn)).max(S::zero());
            let dn = total - s.lambda_n;
            s.lambda_n = total;
            apply(a, &mut b, r, r.n * dn);
        }
    }
    st.iter().filter(|s| s.lambda_n.re() > 0.0).count()
}
