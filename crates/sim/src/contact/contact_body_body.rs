//! Two bodies: the points of `a` against the SDF of `b` (in `b`'s frame), for
//! one substep. Call twice with the roles swapped for both directions.

use super::contact_set::select_contacts;
use super::sequential_impulses::{solve, Law, Row, Side};
use super::support_point::{Near, Touch};
use super::{angular_term, contact_impulse, torsional_impulse, world_inertia_inv, Detection};
use crate::config::ContactModel;
use crate::sdf::Sdf;
use crate::{BodyState, RigidBody};
use geom::{Mat3, Real, Vec3};

/// Apply `+j` to `a` and `−j` to `b`. Returns whether an impulse was applied.
pub(crate) fn contact_body_body<S: Real>(
    a: &RigidBody,
    sa: &mut BodyState<S>,
    b: &RigidBody,
    sb: &mut BodyState<S>,
    restitution: S,
    friction: S,
    det: &Detection,
) -> bool {
    let delta = det.delta;
    let (ta, tb) = (sa.pose.t.re(), sb.pose.t.re());
    if (ta - tb).norm() > a.bounding_radius + b.bounding_radius + delta {
        return false;
    }
    let rot_a_re = sa.pose.q.re().to_mat();
    let (va, wa, vb, wb) = (sa.v.re(), sa.omega.re(), sb.v.re(), sb.omega.re());
    // `b` seen from `a` (a's body frame).
    // a's frame to b's: x_b = R_bᵀ (t_a + R_a x − t_b).
    let rot_b_re_t = sb.pose.q.re().to_mat().transpose();
    let a_to_b = rot_b_re_t.mul_mat(&rot_a_re);
    let (b_to_a, a_origin_in_b) = (a_to_b.transpose(), rot_b_re_t.mul_vec(ta - tb));
    let b_from_a = |x: Vec3<f64>| {
        let (d, g) = b.sdf.distance_grad_local(a_origin_in_b + a_to_b.mul_vec(x));
        (d, b_to_a.mul_vec(g.normalize_or(Vec3::zero())))
    };
    // The fastest any point of `a` moves relative to `b` (a bound).
    let speed = (va - vb).norm() + wa.norm() * a.bounding_radius + wb.norm() * (a.bounding_radius + (ta - tb).norm());
    let b_bound = |c: Vec3<f64>, r: f64| b.sdf.lower_bound_in_ball(a_origin_in_b + a_to_b.mul_vec(c), r);
    let near = Near::find(a, det, speed, b_from_a, b_bound);
    let colliding = near.colliding(det, &rot_a_re, ta, |x| {
        (va + wa.cross(x - ta)) - (vb + wb.cross(x - tb))
    });
    let rot_a = sa.pose.q.to_mat();
    let rot_a_t = rot_a.transpose();
    // The a-frame point of a touch with its derivatives (a support moves with both poses).
    let local = |touch: &Touch| {
        touch.local(|x: Vec3<S>| {
            let (_, g) = b.sdf.distance_grad(&sb.pose, sa.pose.t + rot_a.mul_vec(x));
            -rot_a_t.mul_vec(g.normalize_or(Vec3::zero()))
        })
    };
    let mut hit = false;
    if det.model == ContactModel::MultiPoint && !colliding.is_empty() {
        let mut chosen = Vec::new();
        select_contacts(&colliding, &mut chosen);
        let rows: Vec<Row<S>> = chosen
            .iter()
            .filter_map(|&c| {
                let x = sa.pose.t + rot_a.mul_vec(local(&near.touches[colliding[c].index]));
                let (_, g) = b.sdf.distance_grad(&sb.pose, x);
                g.try_normalize().map(|n| Row {
                    ra: x - sa.pose.t,
                    rb: x - sb.pose.t,
                    n,
                })
            })
            .collect();
        let ia_inv = world_inertia_inv(&rot_a, &a.inertia_inv);
        let ib_inv = world_inertia_inv(&sb.pose.q.to_mat(), &b.inertia_inv);
        let mut side_a = Side {
            v: &mut sa.v,
            omega: &mut sa.omega,
            inv_mass: 1.0 / a.mass,
            inv_inertia: ia_inv,
        };
        let side_b = Side {
            v: &mut sb.v,
            omega: &mut sb.omega,
            inv_mass: 1.0 / b.mass,
            inv_inertia: ib_inv,
        };
        hit = solve(&mut side_a, Some(side_b), &rows, &Law::of(restitution, friction, det)) > 0;
    } else if !colliding.is_empty() {
        let c = sa.pose.t + rot_a.mul_vec(near.mean(&colliding, local));
        let (ra, rb) = (c - sa.pose.t, c - sb.pose.t);
        let (_, g) = b.sdf.distance_grad(&sb.pose, c);
        if let Some(n) = g.try_normalize() {
            let vc = (sa.v + sa.omega.cross(ra)) - (sb.v + sb.omega.cross(rb));
            let ia_inv = world_inertia_inv(&rot_a, &a.inertia_inv);
            let ib_inv = world_inertia_inv(&sb.pose.q.to_mat(), &b.inertia_inv);
            let k = Mat3::identity()
                .scale(S::cst(1.0 / a.mass + 1.0 / b.mass))
                .sub(&angular_term(ra, &ia_inv))
                .sub(&angular_term(rb, &ib_inv));
            if let Some(j) = contact_impulse(vc, n, &k, restitution, friction, det) {
                sa.v += j * S::cst(1.0 / a.mass);
                sa.omega += ia_inv.mul_vec(ra.cross(j));
                sb.v -= j * S::cst(1.0 / b.mass);
                sb.omega -= ib_inv.mul_vec(rb.cross(j));
                let radius = near.patch_radius(&colliding);
                let spin = (sa.omega - sb.omega).dot(n);
                let inv_n = n.dot(ia_inv.mul_vec(n)) + n.dot(ib_inv.mul_vec(n));
                let tau = torsional_impulse(spin, inv_n, j.dot(n), friction, radius);
                sa.omega += ia_inv.mul_vec(n * tau);
                sb.omega -= ib_inv.mul_vec(n * tau);
                hit = true;
            }
        }
    }
    // Positional correction, shared by inverse mass.
    if let Some(deepest) = near.deepest() {
        let x = sa.pose.t + rot_a.mul_vec(local(deepest));
        let (d, g) = b.sdf.distance_grad(&sb.pose, x);
        if d.re() < 0.0 {
            if let Some(n) = g.try_normalize() {
                let wa_share = b.mass / (a.mass + b.mass);
                sa.pose.t -= n * (d * wa_share);
                sb.pose.t += n * (d * (1.0 - wa_share));
            }
        }
    }
    hit
}
