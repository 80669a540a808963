//! 3-vectors and 3×3 matrices over any [`Real`].

use crate::Real;
use std::ops::{Add, AddAssign, Index, Mul, Neg, Sub, SubAssign};

#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Vec3<S> {
    pub x: S,
    pub y: S,
    pub z: S,
}

impl<S: Real> Vec3<S> {
    #[inline]
    pub fn new(x: S, y: S, z: S) -> Self {
        Self { x, y, z }
    }
    #[inline]
    pub fn zero() -> Self {
        Self::splat(S::zero())
    }
    #[inline]
    pub fn splat(v: S) -> Self {
        Self::new(v, v, v)
    }
    /// A constant vector from plain numbers.
    #[inline]
    pub fn cst(a: [f64; 3]) -> Self {
        Self::new(S::cst(a[0]), S::cst(a[1]), S::cst(a[2]))
    }
    #[inline]
    pub fn from_array(a: [S; 3]) -> Self {
        Self::new(a[0], a[1], a[2])
    }
    #[inline]
    pub fn to_array(self) -> [S; 3] {
        [self.x, self.y, self.z]
    }
    /// The value parts.
    #[inline]
    pub fn re(self) -> Vec3<f64> {
        Vec3::new(self.x.re(), self.y.re(), self.z.re())
    }
    #[inline]
    pub fn dot(self, o: Self) -> S {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline]
    pub fn cross(self, o: Self) -> Self {
        Self::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    #[inline]
    pub fn norm_sq(self) -> S {
        self.dot(self)
    }
    #[inline]
    pub fn norm(self) -> S {
        self.norm_sq().sqrt()
    }
    /// Unit vector, or `None` when the length is below `1e-12`.
    #[inline]
    pub fn try_normalize(self) -> Option<Self> {
        let n = self.norm();
        (n.re() > 1e-12).then(|| self * n.recip())
    }
    /// Unit vector, or `fallback` when the length is ~0.
    #[inline]
    pub fn normalize_or(self, fallback: Self) -> Self {
        self.try_normalize().unwrap_or(fallback)
    }
    #[inline]
    pub fn scale(self, s: f64) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
    #[inline]
    pub fn map(self, f: impl Fn(S) -> S) -> Self {
        Self::new(f(self.x), f(self.y), f(self.z))
    }
    /// Embed plain numbers as constants.
    #[inline]
    pub fn lift(v: Vec3<f64>) -> Self {
        Self::new(S::cst(v.x), S::cst(v.y), S::cst(v.z))
    }
    #[inline]
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
}

impl<S: Real> Add for Vec3<S> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<S: Real> Sub for Vec3<S> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<S: Real> Neg for Vec3<S> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}
impl<S: Real> Mul<S> for Vec3<S> {
    type Output = Self;
    #[inline]
    fn mul(self, s: S) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
}
impl<S: Real> AddAssign for Vec3<S> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<S: Real> SubAssign for Vec3<S> {
    #[inline]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}
impl<S> Index<usize> for Vec3<S> {
    type Output = S;
    #[inline]
    fn index(&self, i: usize) -> &S {
        match i {
            0 => &self.x,
            1 => &self.y,
            2 => &self.z,
            _ => panic!("Vec3 index {i} out of range"),
        }
    }
}

/// Row-major 3×3 matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mat3<S> {
    pub m: [[S; 3]; 3],
}

impl<S: Real> Mat3<S> {
    pub fn from_rows(r: [[S; 3]; 3]) -> Self {
        Self { m: r }
    }
    pub fn identity() -> Self {
        Self::diag(Vec3::splat(S::one()))
    }
    pub fn zero() -> Self {
        Self { m: [[S::zero(); 3]; 3] }
    }
    pub fn diag(d: Vec3<S>) -> Self {
        let z = S::zero();
        Self {
            m: [[d.x, z, z], [z, d.y, z], [z, z, d.z]],
        }
    }
    pub fn cst(m: [[f64; 3]; 3]) -> Self {
        Self {
            m: m.map(|r| r.map(S::cst)),
        }
    }
    pub fn lift(m: Mat3<f64>) -> Self {
        Self::cst(m.m)
    }
    pub fn re(&self) -> Mat3<f64> {
        Mat3 {
            m: self.m.map(|r| r.map(|v| v.re())),
        }
    }
    /// The cross-product matrix `[v]×`, with `[v]× w = v × w`.
    pub fn skew(v: Vec3<S>) -> Self {
        let z = S::zero();
        Self {
            m: [[z, -v.z, v.y], [v.z, z, -v.x], [-v.y, v.x, z]],
        }
    }
    /// `a bᵀ`.
    pub fn outer(a: Vec3<S>, b: Vec3<S>) -> Self {
        Self {
            m: [
                [a.x * b.x, a.x * b.y, a.x * b.z],
                [a.y * b.x, a.y * b.y, a.y * b.z],
                [a.z * b.x, a.z * b.y, a.z * b.z],
            ],
        }
    }
    pub fn row(&self, i: usize) -> Vec3<S> {
        Vec3::from_array(self.m[i])
    }
    pub fn col(&self, j: usize) -> Vec3<S> {
        Vec3::new(self.m[0][j], self.m[1][j], self.m[2][j])
    }
    pub fn transpose(&self) -> Self {
        let m = &self.m;
        Self {
            m: [
                [m[0][0], m[1][0], m[2][0]],
                [m[0][1], m[1][1], m[2][1]],
                [m[0][2], m[1][2], m[2][2]],
            ],
        }
    }
    pub fn mul_vec(&self, v: Vec3<S>) -> Vec3<S> {
        Vec3::new(self.row(0).dot(v), self.row(1).dot(v), self.row(2).dot(v))
    }
    pub fn mul_mat(&self, o: &Self) -> Self {
        let mut r = Self::zero();
        for i in 0..3 {
            for j in 0..3 {
                r.m[i][j] = self.m[i][0] * o.m[0][j] + self.m[i][1] * o.m[1][j] + self.m[i][2] * o.m[2][j];
            }
        }
        r
    }
    pub fn add(&self, o: &Self) -> Self {
        let mut r = *self;
        for i in 0..3 {
            for j in 0..3 {
                r.m[i][j] += o.m[i][j];
            }
        }
        r
    }
    pub fn sub(&self, o: &Self) -> Self {
        self.add(&o.scale(S::cst(-1.0)))
    }
    pub fn scale(&self, s: S) -> Self {
        Self {
            m: self.m.map(|r| r.map(|v| v * s)),
        }
    }
    pub fn det(&self) -> S {
        let m = &self.m;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }
    /// Inverse by the adjugate, or `None` when `|det|` is below `1e-300`.
    pub fn try_inverse(&self) -> Option<Self> {
        let d = self.det();
        if d.re().abs() < 1e-300 || !d.re().is_finite() {
            return None;
        }
        let m = &self.m;
        let inv_d = d.recip();
        let c = |a: usize, b: usize, c: usize, e: usize| m[a][b] * m[c][e] - m[a][e] * m[c][b];
        let adj = [
            [c(1, 1, 2, 2), -c(0, 1, 2, 2), c(0, 1, 1, 2)],
            [-c(1, 0, 2, 2), c(0, 0, 2, 2), -c(0, 0, 1, 2)],
            [c(1, 0, 2, 1), -c(0, 0, 2, 1), c(0, 0, 1, 1)],
        ];
        Some(Self {
            m: adj.map(|r| r.map(|v| v * inv_d)),
        })
    }
    pub fn trace(&self) -> S {
        self.m[0][0] + self.m[1][1] + self.m[2][2]
    }
}
