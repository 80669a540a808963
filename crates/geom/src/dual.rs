//! Forward-mode dual numbers with `N` derivative slots.
//!
//! The simulator's parameters are few (14 per body), so one forward pass with
//! `Dual<16>` gives the derivatives of every output with respect to all of a
//! body's parameters at once.

use crate::Real;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// `re + Σ eps[i] ε_i` with `ε_i ε_j = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<const N: usize> {
    pub re: f64,
    pub eps: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// A constant.
    #[inline]
    pub fn new(re: f64) -> Self {
        Self { re, eps: [0.0; N] }
    }
    /// The variable number `slot`: value `re`, derivative 1 in that slot.
    #[inline]
    pub fn var(re: f64, slot: usize) -> Self {
        let mut eps = [0.0; N];
        eps[slot] = 1.0;
        Self { re, eps }
    }
    /// `f(re)` with derivative `df(re)` by the chain rule.
    #[inline]
    fn chain(self, f: f64, df: f64) -> Self {
        let mut eps = self.eps;
        for e in &mut eps {
            *e *= df;
        }
        Self { re: f, eps }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: Self) -> Self {
        self.re += o.re;
        for i in 0..N {
            self.eps[i] += o.eps[i];
        }
        self
    }
}
impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, o: Self) -> Self {
        self.re -= o.re;
        for i in 0..N {
            self.eps[i] -= o.eps[i];
        }
        self
    }
}
impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        let mut eps = [0.0; N];
        for (i, e) in eps.iter_mut().enumerate() {
            *e = self.re * o.eps[i] + o.re * self.eps[i];
        }
        Self {
            re: self.re * o.re,
            eps,
        }
    }
}
impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.re;
        let re = self.re * inv;
        let mut eps = [0.0; N];
        for (i, e) in eps.iter_mut().enumerate() {
            *e = (self.eps[i] - re * o.eps[i]) * inv;
        }
        Self { re, eps }
    }
}
impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(mut self) -> Self {
        self.re = -self.re;
        for e in &mut self.eps {
            *e = -*e;
        }
        self
    }
}
impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: f64) -> Self {
        self.re += o;
        self
    }
}
impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, o: f64) -> Self {
        self.re -= o;
        self
    }
}
impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(mut self, o: f64) -> Self {
        self.re *= o;
        for e in &mut self.eps {
            *e *= o;
        }
        self
    }
}
impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: f64) -> Self {
        self * (1.0 / o)
    }
}
macro_rules! assign_ops {
    ($($tr:ident $m:ident $op:tt),*) => {$(
        impl<const N: usize> $tr for Dual<N> {
            #[inline]
            fn $m(&mut self, o: Self) { *self = *self $op o; }
        }
    )*};
}
assign_ops!(AddAssign add_assign +, SubAssign sub_assign -, MulAssign mul_assign *, DivAssign div_assign /);

impl<const N: usize> Real for Dual<N> {
    #[inline]
    fn cst(x: f64) -> Self {
        Self::new(x)
    }
    #[inline]
    fn re(self) -> f64 {
        self.re
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.re.sqrt();
        // d sqrt at 0 is infinite; callers guard zero lengths (`normalize_or`).
        self.chain(s, 0.5 / s)
    }
    #[inline]
    fn sin(self) -> Self {
        self.chain(self.re.sin(), self.re.cos())
    }
    #[inline]
    fn cos(self) -> Self {
        self.chain(self.re.cos(), -self.re.sin())
    }
    #[inline]
    fn exp(self) -> Self {
        let e = self.re.exp();
        self.chain(e, e)
    }
    #[inline]
    fn ln(self) -> Self {
        self.chain(self.re.ln(), 1.0 / self.re)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        // d atan2(y, x) = (x dy - y dx) / (x² + y²)
        let r2 = self.re * self.re + x.re * x.re;
        let mut eps = [0.0; N];
        for (i, e) in eps.iter_mut().enumerate() {
            *e = (x.re * self.eps[i] - self.re * x.eps[i]) / r2;
        }
        Self {
            re: self.re.atan2(x.re),
            eps,
        }
    }
    #[inline]
    fn is_finite(self) -> bool {
        self.re.is_finite() && self.eps.iter().all(|e| e.is_finite())
    }
}
