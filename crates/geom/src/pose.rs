//! Rigid poses `p_world = R(q) p_body + t` (docs/formats.md) and the exp/log maps
//! of SE(3).

use crate::{Mat3, Quat, Real, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose<S> {
    pub q: Quat<S>,
    pub t: Vec3<S>,
}

impl<S: Real> Pose<S> {
    pub fn new(q: Quat<S>, t: Vec3<S>) -> Self {
        Self { q, t }
    }
    pub fn identity() -> Self {
        Self::new(Quat::identity(), Vec3::zero())
    }
    pub fn from_translation(t: Vec3<S>) -> Self {
        Self::new(Quat::identity(), t)
    }
    pub fn lift(p: Pose<f64>) -> Self {
        Self::new(Quat::lift(p.q), Vec3::lift(p.t))
    }
    pub fn re(self) -> Pose<f64> {
        Pose::new(self.q.re(), self.t.re())
    }
    /// Body point to world.
    pub fn transform_point(&self, p: Vec3<S>) -> Vec3<S> {
        self.q.rotate(p) + self.t
    }
    /// Body direction to world.
    pub fn transform_vector(&self, v: Vec3<S>) -> Vec3<S> {
        self.q.rotate(v)
    }
    /// World point to body.
    pub fn inverse_transform_point(&self, p: Vec3<S>) -> Vec3<S> {
        self.q.conj().rotate(p - self.t)
    }
    /// World direction to body.
    pub fn inverse_transform_vector(&self, v: Vec3<S>) -> Vec3<S> {
        self.q.conj().rotate(v)
    }
    /// `self ∘ o`: first `o`, then `self`.
    pub fn compose(&self, o: &Self) -> Self {
        Self::new(self.q * o.q, self.q.rotate(o.t) + self.t)
    }
    pub fn inverse(&self) -> Self {
        let qi = self.q.conj();
        Self::new(qi, -qi.rotate(self.t))
    }
    /// The 4×4 homogeneous matrix, row-major.
    pub fn to_matrix(&self) -> [[S; 4]; 4] {
        let r = self.q.to_mat().m;
        let z = S::zero();
        [
            [r[0][0], r[0][1], r[0][2], self.t.x],
            [r[1][0], r[1][1], r[1][2], self.t.y],
            [r[2][0], r[2][1], r[2][2], self.t.z],
            [z, z, z, S::one()],
        ]
    }
    /// SE(3) exp of a twist `(rho, phi)` (translation part first).
    pub fn exp(rho: Vec3<S>, phi: Vec3<S>) -> Self {
        Self::new(Quat::exp(phi), left_jacobian(phi).mul_vec(rho))
    }
    /// SE(3) log: the twist `(rho, phi)` with `Pose::exp(rho, phi) == self`.
    pub fn log(&self) -> (Vec3<S>, Vec3<S>) {
        let phi = self.q.log();
        let v = left_jacobian(phi);
        let rho = v.try_inverse().map(|vi| vi.mul_vec(self.t)).unwrap_or(self.t);
        (rho, phi)
    }
}

/// The left Jacobian of SO(3), `V = I + (1−cos θ)/θ² [φ]× + (θ−sin θ)/θ³ [φ]×²`.
pub fn left_jacobian<S: Real>(phi: Vec3<S>) -> Mat3<S> {
    let th2 = phi.norm_sq();
    let (a, b) = if th2.re() < 1e-10 {
        (
            S::cst(0.5) - th2 * (1.0 / 24.0),
            S::cst(1.0 / 6.0) - th2 * (1.0 / 120.0),
        )
    } else {
        let th = th2.sqrt();
        ((S::one() - th.cos()) / th2, (th - th.sin()) / (th2 * th))
    };
    let k = Mat3::skew(phi);
    let k2 = k.mul_mat(&k);
    Mat3::identity().add(&k.scale(a)).add(&k2.scale(b))
}
