//! Analytic shapes with exact distances and gradients.

use super::Sdf;
use geom::{Real, Vec3};
use serde::{Deserialize, Serialize};

/// Half-space below the plane `normal · p = offset` (normal pointing out).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plane {
    pub normal: [f64; 3],
    pub offset: f64,
}

impl Sdf for Plane {
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
        let n = Vec3::<S>::cst(self.normal);
        (p.dot(n) - self.offset, n)
    }
}

/// Box centred at the origin with half extents `half`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cuboid {
    pub half: [f64; 3],
}

/// Sign of the value part as a constant (+1 at 0).
fn sign<S: Real>(x: S) -> S {
    S::cst(if x.re() < 0.0 { -1.0 } else { 1.0 })
}

/// Exact box distance with its gradient.
fn box_distance<S: Real>(p: Vec3<S>, half: [f64; 3]) -> (S, Vec3<S>) {
    let a = [p.x.abs(), p.y.abs(), p.z.abs()];
    let q = [a[0] - half[0], a[1] - half[1], a[2] - half[2]];
    let s = [sign(p.x), sign(p.y), sign(p.z)];
    let outside = q.iter().any(|v| v.re() > 0.0);
    if outside {
        let o = q.map(|v| v.max(S::zero()));
        let len = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
        let inv = len.recip();
        (len, Vec3::new(o[0] * inv * s[0], o[1] * inv * s[1], o[2] * inv * s[2]))
    } else {
        // Inside: the nearest face is the axis with the largest q.
        let k = (0..3).max_by(|&i, &j| q[i].re().total_cmp(&q[j].re())).unwrap_or(0);
        let mut g = Vec3::zero();
        match k {
            0 => g.x = s[0],
            1 => g.y = s[1],
            _ => g.z = s[2],
        }
        (q[k], g)
    }
}

impl Sdf for Cuboid {
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
        box_distance(p, self.half)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sphere {
    pub radius: f64,
}

impl Sdf for Sphere {
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
        let l = p.norm();
        (l - self.radius, p.normalize_or(Vec3::cst([0.0, 0.0, 1.0])))
    }
}

/// Box with outer half extents `half` whose edges are rounded by `radius`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RoundedBox {
    pub half: [f64; 3],
    pub radius: f64,
}

impl Sdf for RoundedBox {
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
        let r = self.radius;
        let (d, g) = box_distance(p, [self.half[0] - r, self.half[1] - r, self.half[2] - r]);
        (d - r, g)
    }
}

/// Capsule along z: the segment `z ∈ [-half_length, half_length]` swept by a
/// sphere of `radius`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Capsule {
    pub half_length: f64,
    pub radius: f64,
}

impl Sdf for Capsule {
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
        let cz = p.z.clamp(-self.half_length, self.half_length);
        let d = Vec3::new(p.x, p.y, p.z - cz);
        let fallback = Vec3::cst([0.0, 0.0, if p.z.re() < 0.0 { -1.0 } else { 1.0 }]);
        (d.norm() - self.radius, d.normalize_or(fallback))
    }
}

/// A ramp: the prism over the triangle with corners `(-hx, -hz)`, `(hx, -hz)`,
/// `(hx, hz)` in the xz-plane (rising towards +x), extruded over `|y| ≤ hy`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Wedge {
    pub half: [f64; 3],
}

impl Wedge {
    fn corners(&self) -> [[f64; 2]; 3] {
        let [hx, _, hz] = self.half;
        [[-hx, -hz], [hx, -hz], [hx, hz]]
    }
}

/// Exact signed distance to a counter-clockwise convex polygon in 2-D, with gradient.
fn convex_polygon_distance<S: Real>(p: [S; 2], poly: &[[f64; 2]]) -> (S, [S; 2]) {
    let mut best: Option<(f64, S, [S; 2], [f64; 2])> = None;
    let mut inside = true;
    for i in 0..poly.len() {
        let a = poly[i];
        let b = poly[(i + 1) % poly.len()];
        let e = [b[0] - a[0], b[1] - a[1]];
        let len2 = e[0] * e[0] + e[1] * e[1];
        let w = [p[0] - a[0], p[1] - a[1]];
        // Outward normal of a counter-clockwise edge.
        let nrm = [e[1] / len2.sqrt(), -e[0] / len2.sqrt()];
        if (w[0] * nrm[0] + w[1] * nrm[1]).re() > 0.0 {
            inside = false;
        }
        let t = ((w[0] * e[0] + w[1] * e[1]) / len2).clamp(0.0, 1.0);
        let c = [w[0] - t * e[0], w[1] - t * e[1]];
        let d2 = c[0] * c[0] + c[1] * c[1];
        if best.as_ref().is_none_or(|bst| d2.re() < bst.0) {
            best = Some((d2.re(), d2, c, nrm));
        }
    }
    let (d2re, d2, c, nrm) = best.expect("polygon has edges");
    if d2re < 1e-24 {
        return (S::zero(), [S::cst(nrm[0]), S::cst(nrm[1])]);
    }
    let d = d2.sqrt();
    let sgn = if inside { -1.0 } else { 1.0 };
    let inv = d.recip() * sgn;
    (d * sgn, [c[0] * inv, c[1] * inv])
}

impl Sdf for Wedge {
    fn distance_grad_local<S: Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
        let (d2, g2) = convex_polygon_distance([p.x, p.z], &self.corners());
        let wy = p.y.abs() - self.half[1];
        let sy = sign(p.y);
        if d2.re() > 0.0 && wy.re() > 0.0 {
            let l = (d2 * d2 + wy * wy).sqrt();
            let inv = l.recip();
            (l, Vec3::new(g2[0] * d2 * inv, sy * wy * inv, g2[1] * d2 * inv))
        } else if d2.re() >= wy.re() {
            (d2, Vec3::new(g2[0], S::zero(), g2[1]))
        } else {
            (wy, Vec3::new(S::zero(), sy, S::zero()))
        }
    }
}
