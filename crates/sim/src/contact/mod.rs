//! Contact response (DESIGN.md, "The contact model"): which points collide
//! (Eq. 8), the target velocity at each contact patch's averaged point, and the impulse
//! that produces it.

mod contact_body_body;
mod contact_body_scene;
mod contact_set;
mod sequential_impulses;
mod support_point;

pub(crate) use contact_body_body::contact_body_body;
pub(crate) use contact_body_scene::contact_body_scene;
pub(crate) use support_point::SampleStart;

use crate::config::{ContactModel, FrictionModel};
use geom::{Mat3, Real, Vec3};

/// How a contact point is tested (Eq. 8 plus the optional speculative rule).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Detection {
    /// Δ, m.
    pub delta: f64,
    /// Substep length when the speculative rule is on, else 0 (so `d + dt·v_n ≤ 0`
    /// reduces to nothing stronger than `d ≤ Δ`).
    pub speculative_dt: Option<f64>,
    pub restitution_threshold: f64,
    pub friction: FrictionModel,
    pub model: ContactModel,
    /// Sweeps of the multi-point solver.
    pub sweeps: usize,
    /// Slide samples to their body's support ([`support_point`]).
    pub supports: bool,
}

impl Detection {
    /// Whether a point at distance `d` with normal speed `vn` (= v·n) collides.
    #[inline]
    pub fn collides(&self, d: f64, vn: f64) -> bool {
        d <= self.delta && vn < 0.0 && self.speculative_dt.is_none_or(|dt| d + dt * vn <= 0.0)
    }
}

/// The impulse at a contact with normal `n`, relative velocity `vc` and
/// contact mass matrix `k` (Δv_c = K j), or `None` when the point is not
/// approaching (`v_c · n ≥ 0`).
///
/// Restitution: the normal velocity becomes `−k v_n`, with `k = 0` below the
/// restitution threshold so resting contact does not chatter. Friction follows
/// [`FrictionModel`].
pub(crate) fn contact_impulse<S: Real>(
    vc: Vec3<S>,
    n: Vec3<S>,
    k: &Mat3<S>,
    restitution: S,
    friction: S,
    det: &Detection,
) -> Option<Vec3<S>> {
    let vn_s = vc.dot(n);
    if vn_s.re() >= 0.0 {
        return None;
    }
    let vn = n * vn_s;
    let vt = vc - vn;
    let vn_abs = -vn_s;
    let kn = if vn_abs.re() < det.restitution_threshold {
        S::zero()
    } else {
        restitution
    };
    let k_inv = k.try_inverse()?;
    match det.friction {
        FrictionModel::Velocity => {
            let vt_len2 = vt.norm_sq();
            let a = if vt_len2.re() < 1e-20 {
                S::zero()
            } else {
                (S::one() - friction * (kn + 1.0) * vn_abs / vt_len2.sqrt()).max(S::zero())
            };
            let vc_new = vt * a - vn * kn;
            Some(k_inv.mul_vec(vc_new - vc))
        }
        FrictionModel::Coulomb => {
            // Impulse that bounces and sticks; keep it if it lies in the friction cone.
            let j_stick = k_inv.mul_vec(-(vn * kn) - vc);
            let jn = j_stick.dot(n);
            let jt = j_stick - n * jn;
            let jt_len2 = jt.norm_sq();
            if jt_len2.re() <= (friction * jn).re().powi(2) || jt_len2.re() < 1e-30 {
                return Some(j_stick);
            }
            // Sliding: j = λ (n + mu t̂), λ set by the normal velocity target.
            let dir = n + jt * (friction / jt_len2.sqrt());
            let lambda = vn_abs * (kn + 1.0) / n.dot(k.mul_vec(dir));
            Some(dir * lambda)
        }
    }
}

/// Torsional friction of the contact patch: the angular impulse about `n`
/// that stops the relative spin `spin_n` (= (ω_a − ω_b)·n), capped at
/// `mu · j_n · radius` (a patch of RMS radius `radius` under normal impulse
/// `j_n`). One averaged contact point cannot resist spin about the normal, so
/// without this a body resting on a plane keeps turning.
/// `inv_inertia_n` is `nᵀ (I_a⁻¹ + I_b⁻¹) n`.
pub(crate) fn torsional_impulse<S: Real>(spin_n: S, inv_inertia_n: S, jn: S, friction: S, radius: f64) -> S {
    let stop = -spin_n / inv_inertia_n;
    let cap = friction * jn * radius;
    if cap.re() <= 0.0 {
        S::zero()
    } else if stop.re() > cap.re() {
        cap
    } else if stop.re() < -cap.re() {
        -cap
    } else {
        stop
    }
}

/// Hold a body flat on its contact patch in the derivatives (the mean-point model only; the values are
/// left as they are). One averaged point under a face leaves a tilt about that point free in the
/// derivatives: friction at the face and the support under the centre of mass both tip it, and the
/// tangent dynamics drift without bound once the body slides or rests (d x / d v0 of a box slid to rest
/// 2.3 against 0.30 by differences). The values stay flat only because the colliding set shifts to the
/// sinking side as the body tilts, a discrete choice with no derivative. What that shift does is hold the
/// tilt rate at zero while the patch can give the torque; so, where the contact rests or slides (its
/// normal speed under the restitution threshold), the derivative of the tilt rate about each axis of the
/// patch is removed when the torque that would stop the tilt, `|ω·a| / (aᵀ I⁻¹ a)`, is within what the
/// patch's support can give, `j_n` times its half-width across the axis (√3 × the RMS spread of the
/// colliding points, as for an even patch). An edge (no width across it) holds nothing, so a body tipping
/// over one keeps its derivatives.
///
/// Only a body whose centre of mass stands over the patch is held: one rocking or sliding on a corner,
/// its centre beside the few points that touch, tilts in its values too.
///
/// `patch`: the colliding points (their world positions are read), `centre`: the body's centre of mass (world), `n`: the contact
/// normal, `jn`: the normal impulse of the substep.
pub(crate) fn hold_tilt_derivatives<S: Real>(
    omega: &mut Vec3<S>,
    n: Vec3<f64>,
    patch: &[contact_set::Colliding],
    centre: Vec3<f64>,
    inertia_inv_world: &Mat3<f64>,
    jn: f64,
) {
    if patch.len() < 3 || jn <= 0.0 {
        return;
    }
    let count = patch.len() as f64;
    let mean = patch.iter().fold(Vec3::zero(), |a, p| a + p.at) * (1.0 / count);
    let (t1, t2) = sequential_impulses::tangents(n);
    let (mut c11, mut c22, mut c12) = (0.0, 0.0, 0.0);
    for p in patch {
        let (a, b) = ((p.at - mean).dot(t1), (p.at - mean).dot(t2));
        c11 += a * a / count;
        c22 += b * b / count;
        c12 += a * b / count;
    }
    // The patch's principal axes in the tangent plane and the spread along each.
    let angle = 0.5 * (2.0 * c12).atan2(c11 - c22);
    let (s, c) = angle.sin_cos();
    let e1 = t1 * c + t2 * s;
    let e2 = t2 * c - t1 * s;
    let var1 = c11 * c * c + 2.0 * c12 * s * c + c22 * s * s;
    let var2 = c11 * s * s - 2.0 * c12 * s * c + c22 * c * c;
    let (h1, h2) = ((3.0 * var1.max(0.0)).sqrt(), (3.0 * var2.max(0.0)).sqrt());
    let over = centre - mean;
    if over.dot(e1).abs() >= h1 || over.dot(e2).abs() >= h2 {
        return;
    }
    for (axis, half_width) in [(e1, h2), (e2, h1)] {
        let rate = omega.dot(Vec3::lift(axis));
        let stop = rate.re().abs() / axis.dot(inertia_inv_world.mul_vec(axis));
        if half_width > 0.0 && stop <= jn * half_width {
            *omega -= Vec3::lift(axis) * (rate - S::cst(rate.re()));
        }
    }
}

/// `[r]× I⁻¹ [r]×` (the angular part of the contact mass matrix).
pub(crate) fn angular_term<S: Real>(r: Vec3<S>, inertia_inv_world: &Mat3<S>) -> Mat3<S> {
    let k = Mat3::skew(r);
    k.mul_mat(inertia_inv_world).mul_mat(&k)
}

/// World inverse inertia `R I⁻¹ Rᵀ`.
pub(crate) fn world_inertia_inv<S: Real>(rot: &Mat3<S>, inertia_inv: &Mat3<f64>) -> Mat3<S> {
    rot.mul_mat(&Mat3::lift(*inertia_inv)).mul_mat(&rot.transpose())
}
