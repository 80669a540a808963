//! NeuS volume rendering of one ray (Eq. 2) and its backward pass.
//!
//! Each sample is the midpoint of a section of length `dt`; the SDF at the
//! section ends is estimated from the midpoint value and the gradient
//! (`s ∓ cos·dt/2`, with NeuS's cosine annealing), and the section's opacity
//! is the unbiased `α = (Φ_s(s_prev) − Φ_s(s_next)) / Φ_s(s_prev)`, clamped to
//! [0, 1]. Weights `w_i = T_i α_i`; colour `Σ w_i c_i + T_n c_bg`.

/// Where rendering stops a ray (its transmittance through the field, see
/// [`crate::render_view::RenderSettings::stop_transmittance`]): what is behind adds less than a thousandth (a
/// quarter of an 8-bit step) to the pixel. Training skips the background field behind such rays.
pub const STOP_TRANSMITTANCE: f32 = 1e-3;

/// Inputs of one ray, `n` samples.
pub struct RayInputs<'a> {
    /// SDF at each midpoint.
    pub sdf: &'a [f32],
    /// `dir · ∇s` at each midpoint.
    pub cos: &'a [f32],
    /// Section lengths.
    pub dt: &'a [f32],
    /// Distance of each midpoint along the ray (for depth).
    pub t: &'a [f32],
    /// Colour at each midpoint.
    pub rgb: &'a [[f32; 3]],
    /// Sharpness `s` of Φ_s (inverse standard deviation).
    pub inv_s: f32,
    /// Cosine annealing ratio in [0, 1] (1 = the true cosine).
    pub anneal: f32,
    pub background: [f32; 3],
}

/// What a ray renders to.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayOutput {
    pub rgb: [f32; 3],
    /// Σ w_i: 1 where the ray hit the object.
    pub opacity: f32,
    /// Σ w_i t_i.
    pub depth: f32,
}

/// Gradients of one ray's inputs.
pub struct RayGrads<'a> {
    pub sdf: &'a mut [f32],
    pub cos: &'a mut [f32],
    pub rgb: &'a mut [[f32; 3]],
    pub inv_s: &'a mut f32,
    pub background: &'a mut [f32; 3],
}

const EPS: f32 = 1e-5;

#[inline]
fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// `iter_cos` of NeuS: the (annealed, never positive) slope used to estimate
/// the SDF at the section ends, and its derivative in `cos`.
#[inline]
fn iter_cos(c: f32, anneal: f32) -> (f32, f32) {
    let a = (0.5 - 0.5 * c).max(0.0);
    let b = (-c).max(0.0);
    let v = -((1.0 - anneal) * a + anneal * b);
    let dv = (1.0 - anneal) * 0.5 * f32::from(c < 1.0) + anneal * f32::from(c < 0.0);
    (v, dv)
}

/// The opacity of one section: SDF `sdf` and `cos = dir · ∇s` at its midpoint, length `dt`.
#[inline]
pub fn section_alpha(sdf: f32, cos: f32, dt: f32, inv_s: f32, anneal: f32) -> f32 {
    let (ic, _) = iter_cos(cos, anneal);
    let half = ic * dt * 0.5;
    let p = sigmoid((sdf - half) * inv_s);
    let n = sigmoid((sdf + half) * inv_s);
    ((p - n + EPS) / (p + EPS)).clamp(0.0, 1.0)
}

/// Gradients of one section's opacity, from `d_alpha`: `(d_sdf, d_cos, d_inv_s)` (zero where the opacity is
/// clamped).
#[inline]
pub fn section_alpha_backward(sdf: f32, cos: f32, dt: f32, inv_s: f32, anneal: f32, d_alpha: f32) -> (f32, f32, f32) {
    let (ic, dic) = iter_cos(cos, anneal);
    let half = ic * dt * 0.5;
    let (ep, en) = (sdf - half, sdf + half);
    let p = sigmoid(ep * inv_s);
    let q = sigmoid(en * inv_s);
    let raw = (p - q + EPS) / (p + EPS);
    if !(0.0..=1.0).contains(&raw) {
        return (0.0, 0.0, 0.0);
    }
    // α = 1 − Φ(next) / (Φ(prev) + ε)
    let d_p = d_alpha * q / ((p + EPS) * (p + EPS));
    let d_q = -d_alpha / (p + EPS);
    let d_ep = d_p * p * (1.0 - p);
    let d_en = d_q * q * (1.0 - q);
    let d_inv_s = d_ep * ep + d_en * en;
    let (d_ep, d_en) = (d_ep * inv_s, d_en * inv_s);
    (d_ep + d_en, (d_en - d_ep) * dt * 0.5 * dic, d_inv_s)
}

/// Opacity of each section; `alpha` has the samples' length.
pub fn alphas(x: &RayInputs, alpha: &mut [f32]) {
    for i in 0..x.sdf.len() {
        alpha[i] = section_alpha(x.sdf[i], x.cos[i], x.dt[i], x.inv_s, x.anneal);
    }
}

/// Weights `w_i = T_i α_i` from the opacities.
pub fn weights(alpha: &[f32], w: &mut [f32]) -> f32 {
    let mut trans = 1.0f32;
    for (wi, &a) in w.iter_mut().zip(alpha) {
        *wi = trans * a;
        trans *= 1.0 - a;
    }
    trans
}

/// Render one ray. `alpha` and `w` are scratch of the samples' length.
pub fn render_ray(x: &RayInputs, alpha: &mut [f32], w: &mut [f32]) -> RayOutput {
    alphas(x, alpha);
    let trans = weights(alpha, w);
    let mut out = RayOutput::default();
    for i in 0..w.len() {
        for k in 0..3 {
            out.rgb[k] += w[i] * x.rgb[i][k];
        }
        out.opacity += w[i];
        out.depth += w[i] * x.t[i];
    }
    for k in 0..3 {
        out.rgb[k] += trans * x.background[k];
    }
    out
}

/// Backward of alpha compositing `Σ T_i α_i v_i + T_n v_end` (`T_i = Π_{j<i} (1 − α_j)`), where `v(i)` is
/// what a unit of sample i's weight adds to the loss (its colour dotted with the colour's gradient, plus the
/// opacity's and depth's) and `v_end` what the light that passes every sample adds. Writes `trans` (T_i) and
/// `d_alpha`; returns `T_n`.
pub fn composite_alpha_backward(
    alpha: &[f32],
    v: impl Fn(usize) -> f32,
    v_end: f32,
    trans: &mut [f32],
    d_alpha: &mut [f32],
) -> f32 {
    let n = alpha.len();
    let mut t = 1.0f32;
    for i in 0..n {
        trans[i] = t;
        t *= 1.0 - alpha[i];
    }
    let mut after = t * v_end; // Σ_{j>i} w_j v_j + T_n v_end
    for i in (0..n).rev() {
        let vi = v(i);
        d_alpha[i] = trans[i] * vi - after / (1.0 - alpha[i]).max(1e-6);
        after += trans[i] * alpha[i] * vi;
    }
    t
}

/// Backward of [`render_ray`] for `d_rgb`, `d_opacity`, `d_depth`: writes the
/// per-sample gradients and adds to the scalar ones. `alpha` and `trans` are
/// scratch of the samples' length.
pub fn render_ray_backward(
    x: &RayInputs,
    d_rgb: [f32; 3],
    d_opacity: f32,
    d_depth: f32,
    alpha: &mut [f32],
    trans: &mut [f32],
    g: RayGrads,
) {
    alphas(x, alpha);
    let v = |i: usize| {
        x.rgb[i][0] * d_rgb[0] + x.rgb[i][1] * d_rgb[1] + x.rgb[i][2] * d_rgb[2] + d_opacity + x.t[i] * d_depth
    };
    let v_bg = x.background[0] * d_rgb[0] + x.background[1] * d_rgb[1] + x.background[2] * d_rgb[2];
    // g.sdf holds dL/dα until each sample's section backward replaces it.
    let t_end = composite_alpha_backward(alpha, v, v_bg, trans, g.sdf);
    for k in 0..3 {
        g.background[k] += t_end * d_rgb[k];
    }
    for i in 0..x.sdf.len() {
        let w = trans[i] * alpha[i];
        g.rgb[i] = d_rgb.map(|d| w * d);
        // Through the clamp, the sigmoids and the end-point estimates.
        let (ds, dc, dis) = section_alpha_backward(x.sdf[i], x.cos[i], x.dt[i], x.inv_s, x.anneal, g.sdf[i]);
        g.sdf[i] = ds;
        g.cos[i] = dc;
        *g.inv_s += dis;
    }
}

/// Alpha compositing of density samples (NeRF, for the content beyond the
/// unit sphere): `α_k = 1 − exp(−σ_k δ_k)`, `w_k = T_k α_k`, colour
/// `Σ w_k c_k + T_n c_end` where `c_end` is what lies at infinity. Returns the
/// colour and `T_n`.
pub fn composite_density(sigma: &[f32], delta: &[f32], rgb: &[[f32; 3]], c_end: [f32; 3]) -> ([f32; 3], f32) {
    let mut out = [0.0f32; 3];
    let mut trans = 1.0f32;
    for k in 0..sigma.len() {
        let keep = (-sigma[k] * delta[k]).exp();
        let w = trans * (1.0 - keep);
        for c in 0..3 {
            out[c] += w * rgb[k][c];
        }
        trans *= keep;
    }
    for c in 0..3 {
        out[c] += trans * c_end[c];
    }
    (out, trans)
}

/// Backward of [`composite_density`] for `d_out`: writes `d_sigma` and
/// `d_rgb` per sample and returns the gradient of `c_end`. With
/// `x_k = σ_k δ_k`, `∂C/∂x_k = T_k (1 − α_k) c_k − (what lies behind k)`:
/// no division, so it stays finite when a sample is opaque.
pub fn composite_density_backward(
    sigma: &[f32],
    delta: &[f32],
    rgb: &[[f32; 3]],
    c_end: [f32; 3],
    d_out: [f32; 3],
    d_sigma: &mut [f32],
    d_rgb: &mut [[f32; 3]],
) -> [f32; 3] {
    let n = sigma.len();
    let dot = |c: [f32; 3]| c[0] * d_out[0] + c[1] * d_out[1] + c[2] * d_out[2];
    // Forward again, keeping the transmittance in front of each sample in d_sigma.
    let mut trans = 1.0f32;
    for k in 0..n {
        d_sigma[k] = trans;
        trans *= (-sigma[k] * delta[k]).exp();
    }
    let mut after = trans * dot(c_end);
    for k in (0..n).rev() {
        let t_k = d_sigma[k];
        let keep = (-sigma[k] * delta[k]).exp();
        let w = t_k * (1.0 - keep);
        d_rgb[k] = d_out.map(|g| w * g);
        let v = dot(rgb[k]);
        d_sigma[k] = (t_k * keep * v - after) * delta[k];
        after += w * v;
    }
    d_out.map(|g| trans * g)
}
