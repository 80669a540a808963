//! The scalar trait every geometric routine is generic over, so that plain
//! `f64` and forward-mode [`Dual`](crate::Dual) numbers run the same code.

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// A real scalar: `f64`, or a dual number carrying derivatives.
///
/// Comparisons are made on the value part ([`Real::re`]) by the caller, so
/// branches (contact on/off, clamps) pick the same side for a dual number as
/// for its value.
pub trait Real:
    Copy
    + Debug
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
{
    /// A constant (zero derivatives).
    fn cst(x: f64) -> Self;
    /// The value part.
    fn re(self) -> f64;
    fn sqrt(self) -> Self;
    fn sin(self) -> Self;
    fn cos(self) -> Self;
    fn exp(self) -> Self;
    fn ln(self) -> Self;
    fn atan2(self, x: Self) -> Self;
    fn zero() -> Self {
        Self::cst(0.0)
    }
    fn one() -> Self {
        Self::cst(1.0)
    }
    fn abs(self) -> Self {
        if self.re() < 0.0 {
            -self
        } else {
            self
        }
    }
    fn recip(self) -> Self {
        Self::one() / self
    }
    /// The larger by value (derivatives of the one chosen).
    fn max(self, o: Self) -> Self {
        if self.re() >= o.re() {
            self
        } else {
            o
        }
    }
    /// The smaller by value (derivatives of the one chosen).
    fn min(self, o: Self) -> Self {
        if self.re() <= o.re() {
            self
        } else {
            o
        }
    }
    fn clamp(self, lo: f64, hi: f64) -> Self {
        if self.re() < lo {
            Self::cst(lo)
        } else if self.re() > hi {
            Self::cst(hi)
        } else {
            self
        }
    }
    fn is_finite(self) -> bool;
}

impl Real for f64 {
    #[inline]
    fn cst(x: f64) -> Self {
        x
    }
    #[inline]
    fn re(self) -> f64 {
        self
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn sin(self) -> Self {
        f64::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline]
    fn ln(self) -> Self {
        f64::ln(self)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        f64::atan2(self, x)
    }
    #[inline]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}
