//! Contact response (DESIGN.md, "The contact model"): which points collide
//! (Eq. 8), the target velocity at the averaged contact point, and the impulse
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

/// `[r]× I⁻¹ [r]×` (the angular part of the contact mass matrix).
pub(crate) fn angular_term<S: Real>(r: Vec3<S>, inertia_inv_world: &Mat3<S>) -> Mat3<S> {
    let k = Mat3::skew(r);
    k.mul_mat(inertia_inv_world).mul_mat(&k)
}

/// World inverse inertia `R I⁻¹ Rᵀ`.
pub(crate) fn world_inertia_inv<S: Real>(rot: &Mat3<S>, inertia_inv: &Mat3<f64>) -> Mat3<S> {
    rot.mul_mat(&Mat3::lift(*inertia_inv)).mul_mat(&rot.transpose())
}
