//! Element-wise activations of the MLP layers, with their derivatives.

use serde::{Deserialize, Serialize};

/// Activation applied after a layer.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Activation {
    /// Identity.
    None,
    /// `max(0, z)` (derivative 0 at z = 0).
    Relu,
    /// `ln(1 + exp(β z)) / β`, linear above `β z > 20` (as PyTorch). NeuS uses β = 100.
    Softplus { beta: f32 },
    /// `1 / (1 + exp(−z))`.
    Sigmoid,
}

/// `e^x` for `x ≤ 0` without a libm call, so that loops over it vectorise: `x = n ln2 + r` with `|r| ≤ ln2/2`
/// (Cody–Waite split of ln2), `e^r` by its degree-7 Taylor polynomial (truncation ≤ 6e-9 relative), `2^n` by
/// building the float's exponent bits. Relative error ≈ 1e-7 for `x ≥ −40`; below, it returns `e^−40` (4e-18):
/// callers add it to O(1) numbers, and smaller values would reach subnormal floats in `ln_1p_unit`, which cost
/// ~100× more cycles on x86.
#[inline(always)]
pub(crate) fn exp_neg(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    // Adding 1.5·2^23 rounds to an integer held in the low mantissa bits.
    const MAGIC: f32 = 12_582_912.0;
    let x = x.max(-40.0);
    let t = x * LOG2E + MAGIC;
    // Wrapping integer arithmetic: with overflow checks (the test profile's) a checked add would branch and keep
    // the loops that call this from vectorising (half of GA's test time went here).
    let n_int = (t.to_bits() as i32).wrapping_sub(MAGIC.to_bits() as i32);
    let n = t - MAGIC;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0)))))));
    p * f32::from_bits((n_int.wrapping_add(127) << 23) as u32)
}

/// `ln(1 + e)` for `e ∈ [0, 1]`: `2 artanh(u)`, `u = e/(2 + e) ∈ [0, 1/3]`, series to `u^15` (truncation
/// ≤ 2e-9 relative). Accurate for small `e` too, where `ln(1 + e) ≈ e`.
#[inline(always)]
pub(crate) fn ln_1p_unit(e: f32) -> f32 {
    let u = e / (2.0 + e);
    let u2 = u * u;
    let s = 1.0
        + u2 * (1.0 / 3.0
            + u2 * (1.0 / 5.0
                + u2 * (1.0 / 7.0 + u2 * (1.0 / 9.0 + u2 * (1.0 / 11.0 + u2 * (1.0 / 13.0 + u2 * (1.0 / 15.0)))))));
    2.0 * u * s
}

/// Softplus with slope `β` and its derivative σ(βz), branch-free: one `exp_neg`, one `ln_1p_unit`. Above
/// `βz > 20` the `ln(1 + e^{−βz})` term is below f32 resolution, so this equals PyTorch's linear threshold.
#[inline(always)]
pub(crate) fn softplus_fast(z: f32, beta: f32, inv_beta: f32) -> (f32, f32) {
    let x = beta * z;
    let e = exp_neg(-x.abs());
    let l = ln_1p_unit(e);
    let inv = 1.0 / (1.0 + e);
    let sig = if x >= 0.0 { inv } else { e * inv };
    ((x.max(0.0) + l) * inv_beta, sig)
}

/// Sigmoid and its derivative, branch-free with `exp_neg`.
#[inline(always)]
pub(crate) fn sigmoid_fast(z: f32) -> (f32, f32) {
    let e = exp_neg(-z.abs());
    let inv = 1.0 / (1.0 + e);
    let s = if z >= 0.0 { inv } else { e * inv };
    (s, s * (1.0 - s))
}
