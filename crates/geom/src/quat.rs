//! Unit quaternions `[w, x, y, z]` (Hamilton convention) and the exp/log maps
//! of SO(3).

use crate::{Mat3, Real, Vec3};
use std::ops::Mul;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quat<S> {
    pub w: S,
    pub x: S,
    pub y: S,
    pub z: S,
}

impl<S: Real> Quat<S> {
    pub fn new(w: S, x: S, y: S, z: S) -> Self {
        Self { w, x, y, z }
    }
    pub fn identity() -> Self {
        Self::new(S::one(), S::zero(), S::zero(), S::zero())
    }
    /// From `[w, x, y, z]` plain numbers (not normalised).
    pub fn cst(a: [f64; 4]) -> Self {
        Self::new(S::cst(a[0]), S::cst(a[1]), S::cst(a[2]), S::cst(a[3]))
    }
    pub fn lift(q: Quat<f64>) -> Self {
        Self::cst(q.to_array_re())
    }
    pub fn to_array(self) -> [S; 4] {
        [self.w, self.x, self.y, self.z]
    }
    pub fn to_array_re(self) -> [f64; 4] {
        [self.w.re(), self.x.re(), self.y.re(), self.z.re()]
    }
    pub fn re(self) -> Quat<f64> {
        Quat::cst(self.to_array_re())
    }
    pub fn vec(self) -> Vec3<S> {
        Vec3::new(self.x, self.y, self.z)
    }
    pub fn norm(self) -> S {
        (self.w * self.w + self.x * self.x + self.y * self.y + self.z * self.z).sqrt()
    }
    /// Unit quaternion, or identity when the norm is ~0.
    pub fn normalize_or_identity(self) -> Self {
        let n = self.norm();
        if n.re() < 1e-12 {
            return Self::identity();
        }
        let inv = n.recip();
        Self::new(self.w * inv, self.x * inv, self.y * inv, self.z * inv)
    }
    pub fn conj(self) -> Self {
        Self::new(self.w, -self.x, -self.y, -self.z)
    }
    /// Rotate a vector: `q v q*` (for a unit quaternion).
    pub fn rotate(self, v: Vec3<S>) -> Vec3<S> {
        // v' = v + 2w (u×v) + 2 u×(u×v), u = vector part.
        let u = self.vec();
        let t = u.cross(v) * S::cst(2.0);
        v + t * self.w + u.cross(t)
    }
    /// The rotation matrix of a unit quaternion.
    pub fn to_mat(self) -> Mat3<S> {
        let (w, x, y, z) = (self.w, self.x, self.y, self.z);
        let two = S::cst(2.0);
        let one = S::one();
        Mat3::from_rows([
            [
                one - two * (y * y + z * z),
                two * (x * y - w * z),
                two * (x * z + w * y),
            ],
            [
                two * (x * y + w * z),
                one - two * (x * x + z * z),
                two * (y * z - w * x),
            ],
            [
                two * (x * z - w * y),
                two * (y * z + w * x),
                one - two * (x * x + y * y),
            ],
        ])
    }
    /// The quaternion of a rotation matrix (Shepperd's method), `w ≥ 0`.
    pub fn from_mat(m: &Mat3<S>) -> Self {
        let m = &m.m;
        let tr = m[0][0] + m[1][1] + m[2][2];
        let q = if tr.re() > 0.0 {
            let s = (tr + 1.0).sqrt() * S::cst(2.0);
            Self::new(
                s * S::cst(0.25),
                (m[2][1] - m[1][2]) / s,
                (m[0][2] - m[2][0]) / s,
                (m[1][0] - m[0][1]) / s,
            )
        } else if m[0][0].re() > m[1][1].re() && m[0][0].re() > m[2][2].re() {
            let s = (m[0][0] - m[1][1] - m[2][2] + 1.0).sqrt() * S::cst(2.0);
            Self::new(
                (m[2][1] - m[1][2]) / s,
                s * S::cst(0.25),
                (m[0][1] + m[1][0]) / s,
                (m[0][2] + m[2][0]) / s,
            )
        } else if m[1][1].re() > m[2][2].re() {
            let s = (m[1][1] - m[0][0] - m[2][2] + 1.0).sqrt() * S::cst(2.0);
            Self::new(
                (m[0][2] - m[2][0]) / s,
                (m[0][1] + m[1][0]) / s,
                s * S::cst(0.25),
                (m[1][2] + m[2][1]) / s,
            )
        } else {
            let s = (m[2][2] - m[0][0] - m[1][1] + 1.0).sqrt() * S::cst(2.0);
            Self::new(
                (m[1][0] - m[0][1]) / s,
                (m[0][2] + m[2][0]) / s,
                (m[1][2] + m[2][1]) / s,
                s * S::cst(0.25),
            )
        };
        let q = q.normalize_or_identity();
        if q.w.re() < 0.0 {
            Self::new(-q.w, -q.x, -q.y, -q.z)
        } else {
            q
        }
    }
    /// SO(3) exp: the rotation by angle `|phi|` about `phi/|phi|`.
    /// Uses a Taylor series near zero so derivatives stay exact at `phi = 0`.
    pub fn exp(phi: Vec3<S>) -> Self {
        let th2 = phi.norm_sq();
        let (c, s_over) = if th2.re() < 1e-12 {
            // cos(θ/2) ≈ 1 − θ²/8, sin(θ/2)/θ ≈ 1/2 − θ²/48
            (S::one() - th2 * (1.0 / 8.0), S::cst(0.5) - th2 * (1.0 / 48.0))
        } else {
            let th = th2.sqrt();
            let h = th * 0.5;
            (h.cos(), h.sin() / th)
        };
        Self::new(c, phi.x * s_over, phi.y * s_over, phi.z * s_over)
    }
    /// SO(3) log: the rotation vector of a unit quaternion, angle in [0, π].
    pub fn log(self) -> Vec3<S> {
        let q = if self.w.re() < 0.0 {
            Self::new(-self.w, -self.x, -self.y, -self.z)
        } else {
            self
        };
        let v = q.vec();
        let s2 = v.norm_sq();
        if s2.re() < 1e-16 {
            // θ ≈ 2 |v| / w
            return v * (S::cst(2.0) / q.w);
        }
        let s = s2.sqrt();
        let th = s.atan2(q.w) * 2.0;
        v * (th / s)
    }
    /// Angle of the rotation, in [0, π].
    pub fn angle(self) -> S {
        self.log().norm()
    }
}

impl Quat<f64> {
    /// Unit length: left bit for bit when it already is to within rounding (a quaternion a program wrote and
    /// read back), else normalised (or the identity when the norm is ~0).
    pub fn unit(self) -> Self {
        if (self.norm() - 1.0).abs() <= 8.0 * f64::EPSILON {
            self
        } else {
            self.normalize_or_identity()
        }
    }
}

impl<S: Real> Mul for Quat<S> {
    type Output = Self;
    /// Hamilton product: `(a * b).rotate(v) == a.rotate(b.rotate(v))`.
    fn mul(self, o: Self) -> Self {
        let (a, b) = (self, o);
        Self::new(
            a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
            a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
            a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
            a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
        )
    }
}

/// Angle in radians between two rotations.
pub fn rotation_distance(a: Quat<f64>, b: Quat<f64>) -> f64 {
    (a.conj() * b).angle()
}
