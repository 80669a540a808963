//! Two bodies: the points of `a` against the SDF of `b` (in `b`'s frame), for
//! one substep. Call twice with the roles swapped for both directions.

use super::contact_set::{select_contacts, Colliding};
use super::sequential_impulses::{solve, Law, Row, Side};
use super::{angular_term, contact_impulse, patch_radius, torsional_impulse, world_inertia_inv, Detection};
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
    let pose_b_re = sb.pose.re();
    let rot_a_re = sa.pose.q.re().to_mat();
    let (va, wa, vb, wb) = (sa.v.re(), sa.omega.re(), sb.v.re(), sb.omega.re());
    let mut sum = Vec3::<f64>::zero();
    let mut sum_sq = 0.0;
    let mut count = 0usize;
    let mut deepest: Option<(f64, usize)> = None;
    let mut colliding = Vec::new();
    for (i, r) in a.contact_points.iter().enumerate() {
        let x = ta + rot_a_re.mul_vec(*r);
        let (d, g) = b.sdf.distance_grad(&pose_b_re, x);
        if d > delta {
            continue;
        }
        if d < deepest.map_or(0.0, |(dd, _)| dd) {
            deepest = Some((d, i));
        }
        let rel = (va + wa.cross(x - ta)) - (vb + wb.cross(x - tb));
        let n = g.normalize_or(Vec3::zero());
        if det.collides(d, rel.dot(n)) {
            sum += *r;
            sum_sq += r.norm_sq();
            count += 1;
            if det.model == ContactModel::MultiPoint {
                colliding.push(Colliding {
                    index: i,
                    distance: d,
                    normal: n,
                    at: x,
                });
            }
        }
    }
    let rot_a = sa.pose.q.to_mat();
    let mut hit = false;
    if det.model == ContactModel::MultiPoint && count > 0 {
        let mut chosen = Vec::new();
        select_contacts(&colliding, &mut chosen);
        let rows: Vec<Row<S>> = chosen
            .iter()
            .filter_map(|&c| {
                let x = sa.pose.t + rot_a.mul_vec(Vec3::lift(a.contact_points[colliding[c].index]));
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
    } else if count > 0 {
        let rbar = sum * (1.0 / count as f64);
        let c = sa.pose.t + rot_a.mul_vec(Vec3::lift(rbar));
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
                let radius = patch_radius(sum, sum_sq, count);
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
    if let Some((_, i)) = deepest {
        let x = sa.pose.t + rot_a.mul_vec(Vec3::lift(a.contact_points[i]));
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
