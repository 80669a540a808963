//! One body against the static scene, for one substep.

use super::contact_set::{patches, select_contacts, Colliding};
use super::sequential_impulses::{solve, Law, Row, Side};
use super::support_point::{Near, Touch};
use super::{angular_term, contact_impulse, hold_tilt_derivatives, torsional_impulse, world_inertia_inv, Detection};
use crate::config::ContactModel;
use crate::sdf::{Sdf, Shape};
use crate::{BodyState, RigidBody};
use geom::{Mat3, Real, Vec3};

/// Apply the contact impulse (if any point collides) and push the body out of
/// the scene if it has sunk in. Returns how many points (multi-point) or patches (mean-point) pushed (0: none).
pub(crate) fn contact_body_scene<S: Real>(
    body: &RigidBody,
    st: &mut BodyState<S>,
    scene: &Shape,
    restitution: S,
    friction: S,
    det: &Detection,
) -> usize {
    let delta = det.delta;
    let t_re = st.pose.t.re();
    // Cull: no point is within Δ when the scene is farther than that over the body's bounding ball.
    if scene.lower_bound_in_ball(t_re, body.bounding_radius) > delta {
        return 0;
    }
    // Detection (Eq. 8) runs on plain numbers: the set of colliding points is
    // a discrete choice, its derivative is zero.
    let rot_re = st.pose.q.re().to_mat();
    let (v_re, w_re) = (st.v.re(), st.omega.re());
    // The other surface seen from the body (body frame).
    let rot_re_t = rot_re.transpose();
    let scene_from_body = |x: Vec3<f64>| {
        let (d, g) = scene.distance_grad_local(t_re + rot_re.mul_vec(x));
        (d, rot_re_t.mul_vec(g.normalize_or(Vec3::zero())))
    };
    let speed = v_re.norm() + w_re.norm() * body.bounding_radius;
    let scene_bound = |c: Vec3<f64>, r: f64| scene.lower_bound_in_ball(t_re + rot_re.mul_vec(c), r);
    let near = Near::find(body, det, speed, scene_from_body, scene_bound);
    let colliding = near.colliding(det, &rot_re, t_re, |x| v_re + w_re.cross(x - t_re));
    let rot = st.pose.q.to_mat();
    let rot_t = rot.transpose();
    // The body-frame point of a touch with its derivatives (a support moves with the pose).
    let local = |touch: &Touch| {
        touch.local(|x: Vec3<S>| {
            let (_, g) = scene.distance_grad_local(st.pose.t + rot.mul_vec(x));
            -rot_t.mul_vec(g.normalize_or(Vec3::zero()))
        })
    };
    let mut hit = 0;
    if det.model == ContactModel::MultiPoint && !colliding.is_empty() {
        let mut chosen = Vec::new();
        select_contacts(&colliding, &mut chosen);
        let rows: Vec<Row<S>> = chosen
            .iter()
            .filter_map(|&c| {
                let r = rot.mul_vec(local(&near.touches[colliding[c].index]));
                let (_, g) = scene.distance_grad_local(st.pose.t + r);
                g.try_normalize().map(|n| Row {
                    ra: r,
                    rb: Vec3::zero(),
                    n,
                })
            })
            .collect();
        let mut side = Side {
            v: &mut st.v,
            omega: &mut st.omega,
            inv_mass: 1.0 / body.mass,
            inv_inertia: world_inertia_inv(&rot, &body.inertia_inv),
        };
        hit = solve(&mut side, None, &rows, &Law::of(restitution, friction, det));
    } else if !colliding.is_empty() {
        // One averaged point per patch: a face pressed against a wall while it slides on the board is two
        // contacts. Averaged together their mean lies inside the body, nearer the board, and takes the
        // board's normal, so the wall's push is lost (the body sinks into the wall until the wall's
        // points alone collide).
        let patches = patches(&colliding);
        let iw_inv = world_inertia_inv(&rot, &body.inertia_inv);
        let mut gathered: Vec<Colliding> = Vec::new();
        for members in &patches {
            // One patch (a body on the board) is every colliding point: no copy.
            let patch: &[Colliding] = if patches.len() == 1 {
                &colliding
            } else {
                gathered.clear();
                gathered.extend(members.iter().map(|&i| colliding[i]));
                &gathered
            };
            let r = rot.mul_vec(near.mean(patch, local));
            let (_, g) = scene.distance_grad_local(st.pose.t + r);
            let Some(n) = g.try_normalize() else { continue };
            let vc = st.v + st.omega.cross(r);
            let k = Mat3::identity()
                .scale(S::cst(1.0 / body.mass))
                .sub(&angular_term(r, &iw_inv));
            let resting = -vc.dot(n).re() < det.restitution_threshold;
            if let Some(j) = contact_impulse(vc, n, &k, restitution, friction, det) {
                st.v += j * S::cst(1.0 / body.mass);
                st.omega += iw_inv.mul_vec(r.cross(j));
                let radius = near.patch_radius(patch);
                let tau = torsional_impulse(st.omega.dot(n), n.dot(iw_inv.mul_vec(n)), j.dot(n), friction, radius);
                st.omega += iw_inv.mul_vec(n * tau);
                if resting {
                    hold_tilt_derivatives(
                        &mut st.omega,
                        n.re(),
                        patch,
                        st.pose.t.re(),
                        &iw_inv.re(),
                        j.dot(n).re(),
                    );
                }
                hit += 1;
            }
        }
    }
    // Positional correction: move the deepest point back onto the surface.
    if let Some(deepest) = near.deepest() {
        let x = st.pose.t + rot.mul_vec(local(deepest));
        let (d, g) = scene.distance_grad_local(x);
        if d.re() < 0.0 {
            if let Some(n) = g.try_normalize() {
                st.pose.t -= n * d;
            }
        }
    }
    hit
}
