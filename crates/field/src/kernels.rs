//! Hot loops as free functions over slices (STYLE habit 4). No allocation (apart from `matrixmultiply`'s own
//! packing buffers inside [`gemm`]), no I/O, no config structs: the owning types (`HashGrid`, `Mlp`, `Adam`) check
//! shapes and then call these. [`mod@reference`] holds a naive scalar version of every kernel; the tests check
//! that the fast paths match it.

/// Per-level constants of the hash encoding, precomputed by `HashGrid::new`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LevelGeom {
    /// Cells per axis; the level has `res + 1` vertices per axis.
    pub res: u32,
    /// Table entries (each `features_per_level` floats). A power of two when hashed.
    pub entries: u32,
    /// Dense indexing `x + (res+1)·(y + (res+1)·z)` when `(res+1)³ ≤ entries`, spatial hash otherwise.
    pub dense: bool,
}

/// Primes of the spatial hash (Teschner et al. 2003, as Instant-NGP): `x·1 ⊕ y·P1 ⊕ z·P2 mod T`.
pub const HASH_P1: u32 = 2_654_435_761;
pub const HASH_P2: u32 = 805_459_861;

/// Cell and fractional position of one coordinate. Coordinates are clamped to `[0, 1]`; the last cell is closed on
/// the right so that `x = 1` lands in cell `res − 1` with fraction 1.
#[inline(always)]
fn cell_frac(x: f32, res: u32, r: f32) -> (u32, f32) {
    let p = x.clamp(0.0, 1.0) * r;
    let c = (p as u32).min(res - 1);
    (c, p - c as f32)
}

/// Table indices of the 8 corners of the cell holding `p` and the fractional position in it. Corner `c` is offset
/// by `(c & 1, (c >> 1) & 1, c >> 2)` from the cell's lower vertex.
#[inline(always)]
fn locate(g: LevelGeom, r: f32, p: &[f32]) -> ([u32; 8], [f32; 3]) {
    let (cx, fx) = cell_frac(p[0], g.res, r);
    let (cy, fy) = cell_frac(p[1], g.res, r);
    let (cz, fz) = cell_frac(p[2], g.res, r);
    let mut idx = [0u32; 8];
    if g.dense {
        let s = g.res + 1;
        let base = cx + s * (cy + s * cz);
        let (dy, dz) = (s, s * s);
        idx = [
            base,
            base + 1,
            base + dy,
            base + dy + 1,
            base + dz,
            base + dz + 1,
            base + dz + dy,
            base + dz + dy + 1,
        ];
    } else {
        let mask = g.entries - 1;
        let hx = [cx, cx.wrapping_add(1)];
        let hy = [cy.wrapping_mul(HASH_P1), cy.wrapping_add(1).wrapping_mul(HASH_P1)];
        let hz = [cz.wrapping_mul(HASH_P2), cz.wrapping_add(1).wrapping_mul(HASH_P2)];
        for (c, i) in idx.iter_mut().enumerate() {
            *i = (hx[c & 1] ^ hy[(c >> 1) & 1] ^ hz[c >> 2]) & mask;
        }
    }
    (idx, [fx, fy, fz])
}

/// Trilinear weights of the 8 corners at fractions `f` along x, y, z, in the hash grid's corner order (x
/// fastest: corner `c` is `+1` along x if `c & 1`, along y if `c & 2`, along z if `c & 4`).
#[inline(always)]
pub fn weights(f: [f32; 3]) -> [f32; 8] {
    let wx = [1.0 - f[0], f[0]];
    let wy = [1.0 - f[1], f[1]];
    let wz = [1.0 - f[2], f[2]];
    let mut w = [0.0; 8];
    for (c, wc) in w.iter_mut().enumerate() {
        *wc = wx[c & 1] * wy[(c >> 1) & 1] * wz[c >> 2];
    }
    w
}

/// Points per block of the two-pass kernels: pass 1 computes the corner indices and weights of a block (pure
/// arithmetic), pass 2 gathers. Keeping the gathers together lets the CPU keep many cache misses in flight, which
/// is what bounds these kernels on the large hashed levels.
const BLOCK: usize = 64;

/// Encode `points` (n×3) at one level into columns `col..col+F` of `out` (row stride `stride`).
/// `table` is this level's slice of the parameters (`entries × F`).
pub fn encode_level<const F: usize>(
    table: &[f32],
    g: LevelGeom,
    points: &[f32],
    out: &mut [f32],
    stride: usize,
    col: usize,
) {
    let r = g.res as f32;
    let mut idx = [[0u32; 8]; BLOCK];
    let mut wts = [[0f32; 8]; BLOCK];
    for (pts, o) in points.chunks(BLOCK * 3).zip(out.chunks_mut(BLOCK * stride)) {
        for ((p, i), w) in pts.chunks_exact(3).zip(idx.iter_mut()).zip(wts.iter_mut()) {
            let (ci, f) = locate(g, r, p);
            *i = ci;
            *w = weights(f);
        }
        for ((row, i), w) in o.chunks_exact_mut(stride).zip(&idx).zip(&wts) {
            let mut acc = [0.0f32; F];
            for c in 0..8 {
                let e = &table[i[c] as usize * F..][..F];
                for k in 0..F {
                    acc[k] += w[c] * e[k];
                }
            }
            row[col..col + F].copy_from_slice(&acc);
        }
    }
}

/// Accumulate the parameter gradient of one level: `grad[idx·F + k] += w · d_out[p, col + k]` for the 8 corners of
/// every point, and set each corner entry's bit in `bits` (a bitset over the level's entries).
#[allow(clippy::too_many_arguments)]
pub fn encode_level_backward<const F: usize>(
    g: LevelGeom,
    points: &[f32],
    d_out: &[f32],
    stride: usize,
    col: usize,
    grad: &mut [f32],
    bits: &mut [u64],
) {
    let r = g.res as f32;
    let mut idx = [[0u32; 8]; BLOCK];
    let mut wts = [[0f32; 8]; BLOCK];
    for (pts, d_blk) in points.chunks(BLOCK * 3).zip(d_out.chunks(BLOCK * stride)) {
        for ((p, i), w) in pts.chunks_exact(3).zip(idx.iter_mut()).zip(wts.iter_mut()) {
            let (ci, f) = locate(g, r, p);
            *i = ci;
            *w = weights(f);
        }
        for ((d, i), w) in d_blk.chunks_exact(stride).zip(&idx).zip(&wts) {
            let d = &d[col..col + F];
            for c in 0..8 {
                let e = &mut grad[i[c] as usize * F..][..F];
                for k in 0..F {
                    e[k] += w[c] * d[k];
                }
                bits[(i[c] >> 6) as usize] |= 1u64 << (i[c] & 63);
            }
        }
    }
}

/// Add dL/dpoints of one level to `d_points` (n×3): the gradient of the trilinear interpolant with respect to the
/// `[0, 1]` coordinates (zero along an axis where the coordinate was clamped).
pub fn encode_level_backward_input<const F: usize>(
    table: &[f32],
    g: LevelGeom,
    points: &[f32],
    d_out: &[f32],
    stride: usize,
    col: usize,
    d_points: &mut [f32],
) {
    let r = g.res as f32;
    let mut idx = [[0u32; 8]; BLOCK];
    let mut frac = [[0f32; 3]; BLOCK];
    for ((pts, d_blk), dp_blk) in points
        .chunks(BLOCK * 3)
        .zip(d_out.chunks(BLOCK * stride))
        .zip(d_points.chunks_mut(BLOCK * 3))
    {
        for ((p, i), f) in pts.chunks_exact(3).zip(idx.iter_mut()).zip(frac.iter_mut()) {
            (*i, *f) = locate(g, r, p);
        }
        for ((((p, d), dp), i), f) in pts
            .chunks_exact(3)
            .zip(d_blk.chunks_exact(stride))
            .zip(dp_blk.chunks_exact_mut(3))
            .zip(&idx)
            .zip(&frac)
        {
            let d = &d[col..col + F];
            // s[c] = Σ_k d_k · table[idx_c, k]: the upstream gradient projected on each corner's features.
            let mut s = [0.0f32; 8];
            for c in 0..8 {
                let e = &table[i[c] as usize * F..][..F];
                let mut acc = 0.0;
                for k in 0..F {
                    acc += d[k] * e[k];
                }
                s[c] = acc;
            }
            // ∂/∂fx of Σ w_c s_c = Σ_{y,z} wy·wz·(s[1,y,z] − s[0,y,z]), and likewise for y and z.
            let (wx, wy, wz) = ([1.0 - f[0], f[0]], [1.0 - f[1], f[1]], [1.0 - f[2], f[2]]);
            let gx = wy[0] * wz[0] * (s[1] - s[0])
                + wy[1] * wz[0] * (s[3] - s[2])
                + wy[0] * wz[1] * (s[5] - s[4])
                + wy[1] * wz[1] * (s[7] - s[6]);
            let gy = wx[0] * wz[0] * (s[2] - s[0])
                + wx[1] * wz[0] * (s[3] - s[1])
                + wx[0] * wz[1] * (s[6] - s[4])
                + wx[1] * wz[1] * (s[7] - s[5]);
            let gz = wx[0] * wy[0] * (s[4] - s[0])
                + wx[1] * wy[0] * (s[5] - s[1])
                + wx[0] * wy[1] * (s[6] - s[2])
                + wx[1] * wy[1] * (s[7] - s[3]);
            let inside = |x: f32| if (0.0..=1.0).contains(&x) { r } else { 0.0 };
            dp[0] += gx * inside(p[0]);
            dp[1] += gy * inside(p[1]);
            dp[2] += gz * inside(p[2]);
        }
    }
}

/// `C = alpha·A·B + beta·C` with arbitrary strides (row stride `rs*`, column stride `cs*`), through
/// `matrixmultiply::sgemm`. `A` is m×k, `B` is k×n, `C` is m×n. With `beta = 0`, `C` is not read.
#[allow(clippy::too_many_arguments)]
pub fn gemm(
    m: usize,
    k: usize,
    n: usize,
    alpha: f32,
    a: &[f32],
    rsa: usize,
    csa: usize,
    b: &[f32],
    rsb: usize,
    csb: usize,
    beta: f32,
    c: &mut [f32],
    rsc: usize,
    csc: usize,
) {
    if m == 0 || n == 0 {
        return;
    }
    let last = |rows: usize, cols: usize, rs: usize, cs: usize| (rows - 1) * rs + (cols - 1) * cs;
    assert!(last(m, n, rsc, csc) < c.len(), "gemm: C too short");
    if k == 0 {
        for i in 0..m {
            for j in 0..n {
                let x = &mut c[i * rsc + j * csc];
                *x = if beta == 0.0 { 0.0 } else { beta * *x };
            }
        }
        return;
    }
    assert!(last(m, k, rsa, csa) < a.len(), "gemm: A too short");
    assert!(last(k, n, rsb, csb) < b.len(), "gemm: B too short");
    // SAFETY: the asserts above keep every element that sgemm reads or writes inside the slices; `c` is a unique
    // borrow, so it does not alias `a` or `b`.
    unsafe {
        matrixmultiply::sgemm(
            m,
            k,
            n,
            alpha,
            a.as_ptr(),
            rsa as isize,
            csa as isize,
            b.as_ptr(),
            rsb as isize,
            csb as isize,
            beta,
            c.as_mut_ptr(),
            rsc as isize,
            csc as isize,
        );
    }
}

/// Apply `act` in place to `x` and write its derivative to `deriv` (same length). `Activation::None` leaves
/// `deriv` untouched (the backward pass skips the multiply). Softplus and sigmoid use the branch-free,
/// libm-free forms of `activation.rs` (relative error ~1e-7) so that the loops vectorise.
pub fn activate(act: crate::Activation, x: &mut [f32], deriv: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU has AVX-512F, checked just above.
        unsafe { activate_avx512(act, x, deriv) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        unsafe { activate_avx2(act, x, deriv) };
        return;
    }
    activate_portable(act, x, deriv);
}

/// [`activate`] compiled for AVX2: eight lanes instead of SSE's four. The same operations in the same order (no
/// FMA contraction), so the results are bit for bit those of [`activate_portable`]. The softplus is a quarter of a
/// pose fit's time (`bench_field`'s MLP figures).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn activate_avx2(act: crate::Activation, x: &mut [f32], deriv: &mut [f32]) {
    activate_portable(act, x, deriv);
}

/// [`activate`] compiled for AVX-512: sixteen lanes, bit for bit the portable build (as [`activate_avx2`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn activate_avx512(act: crate::Activation, x: &mut [f32], deriv: &mut [f32]) {
    activate_portable(act, x, deriv);
}

#[inline(always)]
fn activate_portable(act: crate::Activation, x: &mut [f32], deriv: &mut [f32]) {
    use crate::activation::{sigmoid_fast, softplus_fast};
    match act {
        crate::Activation::None => {}
        crate::Activation::Relu => {
            for (v, d) in x.iter_mut().zip(deriv.iter_mut()) {
                let pos = *v > 0.0;
                *d = if pos { 1.0 } else { 0.0 };
                *v = if pos { *v } else { 0.0 };
            }
        }
        crate::Activation::Softplus { beta } => {
            let inv_beta = 1.0 / beta;
            for (v, d) in x.iter_mut().zip(deriv.iter_mut()) {
                (*v, *d) = softplus_fast(*v, beta, inv_beta);
            }
        }
        crate::Activation::Sigmoid => {
            for (v, d) in x.iter_mut().zip(deriv.iter_mut()) {
                (*v, *d) = sigmoid_fast(*v);
            }
        }
    }
}

/// `bias` added to every row of `x` (row length = `bias.len()`), then [`activate`]: one pass over the layer's
/// outputs after a product that did not read them (`beta = 0`). Copying the bias into every row before the
/// product was a call of `memcpy` per row, 3 % of a pose fit's time.
pub fn bias_activate(act: crate::Activation, bias: &[f32], x: &mut [f32], deriv: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU has AVX-512F, checked just above.
        unsafe { bias_activate_avx512(act, bias, x, deriv) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        unsafe { bias_activate_avx2(act, bias, x, deriv) };
        return;
    }
    bias_activate_portable(act, bias, x, deriv);
}

/// [`bias_activate`] compiled for AVX2, bit for bit the portable build (as [`activate_avx2`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn bias_activate_avx2(act: crate::Activation, bias: &[f32], x: &mut [f32], deriv: &mut [f32]) {
    bias_activate_portable(act, bias, x, deriv);
}

/// [`bias_activate`] compiled for AVX-512, bit for bit the portable build.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn bias_activate_avx512(act: crate::Activation, bias: &[f32], x: &mut [f32], deriv: &mut [f32]) {
    bias_activate_portable(act, bias, x, deriv);
}

#[inline(always)]
fn bias_activate_portable(act: crate::Activation, bias: &[f32], x: &mut [f32], deriv: &mut [f32]) {
    for (row, d) in x.chunks_exact_mut(bias.len()).zip(deriv.chunks_exact_mut(bias.len())) {
        for (v, b) in row.iter_mut().zip(bias) {
            *v += b;
        }
        activate_portable(act, row, d);
    }
}

/// `a[i] *= b[i]`.
pub fn mul_assign(a: &mut [f32], b: &[f32]) {
    for (x, y) in a.iter_mut().zip(b) {
        *x *= y;
    }
}

/// `sums[j] = Σ_r rows[r, j]` (row length = `sums.len()`), rows summed in order.
pub fn column_sums(rows: &[f32], sums: &mut [f32]) {
    sums.fill(0.0);
    for r in rows.chunks_exact(sums.len()) {
        for (s, x) in sums.iter_mut().zip(r) {
            *s += x;
        }
    }
}

/// The numbers of one Adam step: learning rate, decays, ε, L2 weight decay and the bias corrections
/// `bc1 = 1 − β1^t`, `bc2 = 1 − β2^t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdamCoeffs {
    pub lr: f32,
    pub beta1: f32,
    pub beta2: f32,
    pub eps: f32,
    pub weight_decay: f32,
    pub bc1: f32,
    pub bc2: f32,
}

/// One Adam update of one float, applied with weight `on` ∈ {0, 1}: with 0 every value comes back bit-for-bit
/// unchanged, with 1 it is the Adam step (Kingma & Ba, Alg. 1; weight decay as L2 added to the gradient) and the
/// gradient is zeroed. Written as masked increments (`m + on·(1−β1)(g − m)`) so that dense and masked loops
/// share one formula and vectorise.
#[inline(always)]
fn adam_masked(p: f32, g: f32, m: f32, v: f32, on: f32, c: AdamCoeffs) -> (f32, f32, f32, f32) {
    let gi = g + c.weight_decay * p;
    let m = m + on * ((1.0 - c.beta1) * (gi - m));
    let v = v + on * ((1.0 - c.beta2) * (gi * gi - v));
    // lr·m̂/(√v̂ + ε) with the bias corrections folded into constants (one sqrt, one division).
    let step = (c.lr / c.bc1) * m / ((v * (1.0 / c.bc2)).sqrt() + c.eps);
    (p - on * step, g * (1.0 - on), m, v)
}

/// One Adam update over aligned slices (moments updated in place, `grad` zeroed).
pub fn adam_update(params: &mut [f32], grad: &mut [f32], m: &mut [f32], v: &mut [f32], c: AdamCoeffs) {
    let n = params.len();
    assert!(
        grad.len() == n && m.len() == n && v.len() == n,
        "adam_update: length mismatch"
    );
    for i in 0..n {
        let (p, g, mi, vi) = adam_masked(params[i], grad[i], m[i], v[i], 1.0, c);
        (params[i], grad[i], m[i], v[i]) = (p, g, mi, vi);
    }
}

/// Adam update of the floats whose `mask` is 1; those with mask 0 are left bit-for-bit unchanged.
pub fn adam_update_masked(
    params: &mut [f32],
    grad: &mut [f32],
    m: &mut [f32],
    v: &mut [f32],
    mask: &[f32],
    c: AdamCoeffs,
) {
    let n = params.len();
    assert!(
        grad.len() == n && m.len() == n && v.len() == n && mask.len() == n,
        "adam_update_masked: lengths"
    );
    for i in 0..n {
        let (p, g, mi, vi) = adam_masked(params[i], grad[i], m[i], v[i], mask[i], c);
        (params[i], grad[i], m[i], v[i]) = (p, g, mi, vi);
    }
}

/// Adam update restricted to the entries whose bit is set in `bits` (entry `e` covers floats
/// `e·width .. (e+1)·width`, `width` ∈ {1, 2, 4, 8}), in memory order; the bits are cleared. Words with few set
/// bits go bit by bit; fuller words (most of them in a NeuS batch) through the masked update of the whole word, which
/// vectorises, so that a sparse step costs about a dense one at worst.
pub fn adam_update_marked(
    params: &mut [f32],
    grad: &mut [f32],
    m: &mut [f32],
    v: &mut [f32],
    bits: &mut [u64],
    width: usize,
    c: AdamCoeffs,
) {
    let n = params.len();
    assert!(
        grad.len() == n && m.len() == n && v.len() == n,
        "adam_update_marked: length mismatch"
    );
    assert!(
        [1, 2, 4, 8].contains(&width) && bits.len() * 64 * width >= n,
        "adam_update_marked: bad width or bitset"
    );
    let shift = width.trailing_zeros();
    let mut mask = [0.0f32; 64 * 8];
    for (w, word) in bits.iter_mut().enumerate() {
        let mut b = *word;
        if b == 0 {
            continue;
        }
        *word = 0;
        let base = w * 64 * width;
        let end = (base + 64 * width).min(n);
        if b.count_ones() > 8 {
            let len = end - base;
            for (t, mk) in mask[..len].iter_mut().enumerate() {
                *mk = ((b >> (t >> shift)) & 1) as f32;
            }
            let r = base..end;
            adam_update_masked(
                &mut params[r.clone()],
                &mut grad[r.clone()],
                &mut m[r.clone()],
                &mut v[r],
                &mask[..len],
                c,
            );
            continue;
        }
        while b != 0 {
            let start = base + b.trailing_zeros() as usize * width;
            b &= b - 1;
            for i in start..start + width {
                (params[i], grad[i], m[i], v[i]) = adam_masked(params[i], grad[i], m[i], v[i], 1.0, c);
            }
        }
    }
}

/// Real spherical harmonics up to degree 3 of unit directions (n×3) into `out` (n×16), in the order and sign
/// convention (Condon–Shortley phase) of Instant-NGP's `SphericalHarmonics` encoding: index `l² + l + m`.
pub fn sh_encode_rows(dirs: &[f32], out: &mut [f32]) {
    for (d, o) in dirs.chunks_exact(3).zip(out.chunks_exact_mut(16)) {
        let (x, y, z) = (d[0], d[1], d[2]);
        let (xx, yy, zz) = (x * x, y * y, z * z);
        o[0] = 0.282_094_8;
        o[1] = -0.488_602_5 * y;
        o[2] = 0.488_602_5 * z;
        o[3] = -0.488_602_5 * x;
        o[4] = 1.092_548_4 * x * y;
        o[5] = -1.092_548_4 * y * z;
        o[6] = 0.946_174_7 * zz - 0.315_391_57;
        o[7] = -1.092_548_4 * x * z;
        o[8] = 0.546_274_2 * (xx - yy);
        o[9] = 0.590_043_6 * y * (yy - 3.0 * xx);
        o[10] = 2.890_611_4 * x * y * z;
        o[11] = 0.457_045_8 * y * (1.0 - 5.0 * zz);
        o[12] = 0.373_176_33 * z * (5.0 * zz - 3.0);
        o[13] = 0.457_045_8 * x * (1.0 - 5.0 * zz);
        o[14] = 1.445_305_7 * z * (xx - yy);
        o[15] = 0.590_043_6 * x * (3.0 * yy - xx);
    }
}

/// Backward of [`sh_encode_rows`]: `d_dirs` (n×3) += `Σ_k d_out[k] ∂Y_k/∂d`, the derivative of each polynomial with
/// respect to the components as given (no projection onto the sphere: callers move directions by rotations).
pub fn sh_backward_rows(dirs: &[f32], d_out: &[f32], d_dirs: &mut [f32]) {
    const A: f32 = 0.488_602_5;
    const B: f32 = 1.092_548_4;
    const C: f32 = 0.946_174_7;
    const E: f32 = 0.546_274_2;
    const F: f32 = 0.590_043_6;
    const G: f32 = 2.890_611_4;
    const H: f32 = 0.457_045_8;
    const I: f32 = 0.373_176_33;
    const J: f32 = 1.445_305_7;
    for ((d, g), dd) in dirs
        .chunks_exact(3)
        .zip(d_out.chunks_exact(16))
        .zip(d_dirs.chunks_exact_mut(3))
    {
        let (x, y, z) = (d[0], d[1], d[2]);
        let (xx, yy, zz) = (x * x, y * y, z * z);
        // One row per coefficient: (∂/∂x, ∂/∂y, ∂/∂z).
        let rows: [[f32; 3]; 15] = [
            [0.0, -A, 0.0],
            [0.0, 0.0, A],
            [-A, 0.0, 0.0],
            [B * y, B * x, 0.0],
            [0.0, -B * z, -B * y],
            [0.0, 0.0, 2.0 * C * z],
            [-B * z, 0.0, -B * x],
            [2.0 * E * x, -2.0 * E * y, 0.0],
            [-6.0 * F * x * y, 3.0 * F * (yy - xx), 0.0],
            [G * y * z, G * x * z, G * x * y],
            [0.0, H * (1.0 - 5.0 * zz), -10.0 * H * y * z],
            [0.0, 0.0, I * (15.0 * zz - 3.0)],
            [H * (1.0 - 5.0 * zz), 0.0, -10.0 * H * x * z],
            [2.0 * J * x * z, -2.0 * J * y * z, J * (xx - yy)],
            [3.0 * F * (yy - xx), 6.0 * F * x * y, 0.0],
        ];
        for (k, r) in rows.iter().enumerate() {
            let gk = g[k + 1];
            dd[0] += gk * r[0];
            dd[1] += gk * r[1];
            dd[2] += gk * r[2];
        }
    }
}

/// Naive scalar versions of the kernels, written independently of the fast paths (different loop order, 64-bit
/// index arithmetic, `%` instead of masks, plain triple loops instead of GEMM). Used by the tests only, but public
/// so that other crates' tests can use them too.
pub mod reference {
    use super::LevelGeom;

    fn corner_index(g: LevelGeom, x: u64, y: u64, z: u64) -> usize {
        if g.dense {
            let s = g.res as u64 + 1;
            (x + s * y + s * s * z) as usize
        } else {
            let h = (x as u32) ^ (y as u32).wrapping_mul(super::HASH_P1) ^ (z as u32).wrapping_mul(super::HASH_P2);
            (h as u64 % g.entries as u64) as usize
        }
    }

    /// (cell, fraction, d pos/dx) of one coordinate.
    fn cell(x: f32, res: u32) -> (u64, f32, f32) {
        let inside = (0.0..=1.0).contains(&x);
        let xc = x.clamp(0.0, 1.0);
        let p = xc * res as f32;
        let mut c = p.floor() as u64;
        if c >= res as u64 {
            c = res as u64 - 1;
        }
        (c, p - c as f32, if inside { res as f32 } else { 0.0 })
    }

    /// Per point, per level: `out[p, l·F + k] = Σ_corners w · table_l[idx, k]`; levels ≥ `active` give 0.
    /// `levels[l] = (geometry, offset of the level in params, in floats)`.
    pub fn encode_naive(
        params: &[f32],
        levels: &[(LevelGeom, usize)],
        features: usize,
        points: &[f32],
        out: &mut [f32],
        active: usize,
    ) {
        let n = points.len() / 3;
        let dim = levels.len() * features;
        for p in 0..n {
            for (l, &(g, off)) in levels.iter().enumerate() {
                for k in 0..features {
                    out[p * dim + l * features + k] = 0.0;
                }
                if l >= active {
                    continue;
                }
                let c: Vec<_> = (0..3).map(|d| cell(points[p * 3 + d], g.res)).collect();
                for dz in 0..2u64 {
                    for dy in 0..2u64 {
                        for dx in 0..2u64 {
                            let w = |d: usize, b: u64| if b == 1 { c[d].1 } else { 1.0 - c[d].1 };
                            let wt = w(0, dx) * w(1, dy) * w(2, dz);
                            let i = corner_index(g, c[0].0 + dx, c[1].0 + dy, c[2].0 + dz);
                            for k in 0..features {
                                out[p * dim + l * features + k] += wt * params[off + i * features + k];
                            }
                        }
                    }
                }
            }
        }
    }

    /// `grad[off + idx·F + k] += w · d_out[p, l·F + k]` over all points and active levels (accumulates).
    pub fn encode_backward_naive(
        levels: &[(LevelGeom, usize)],
        features: usize,
        points: &[f32],
        d_out: &[f32],
        grad: &mut [f32],
        active: usize,
    ) {
        let n = points.len() / 3;
        let dim = levels.len() * features;
        for p in 0..n {
            for (l, &(g, off)) in levels.iter().enumerate().take(active) {
                let c: Vec<_> = (0..3).map(|d| cell(points[p * 3 + d], g.res)).collect();
                for dz in 0..2u64 {
                    for dy in 0..2u64 {
                        for dx in 0..2u64 {
                            let w = |d: usize, b: u64| if b == 1 { c[d].1 } else { 1.0 - c[d].1 };
                            let wt = w(0, dx) * w(1, dy) * w(2, dz);
                            let i = corner_index(g, c[0].0 + dx, c[1].0 + dy, c[2].0 + dz);
                            for k in 0..features {
                                grad[off + i * features + k] += wt * d_out[p * dim + l * features + k];
                            }
                        }
                    }
                }
            }
        }
    }

    /// `d_points[p] += Σ_levels,k d_out[p, l·F+k] · ∂out[p, l·F+k]/∂point` (accumulates).
    pub fn encode_backward_input_naive(
        params: &[f32],
        levels: &[(LevelGeom, usize)],
        features: usize,
        points: &[f32],
        d_out: &[f32],
        d_points: &mut [f32],
        active: usize,
    ) {
        let n = points.len() / 3;
        let dim = levels.len() * features;
        for p in 0..n {
            for (l, &(g, off)) in levels.iter().enumerate().take(active) {
                let c: Vec<_> = (0..3).map(|d| cell(points[p * 3 + d], g.res)).collect();
                for dz in 0..2u64 {
                    for dy in 0..2u64 {
                        for dx in 0..2u64 {
                            let b = [dx, dy, dz];
                            let i = corner_index(g, c[0].0 + dx, c[1].0 + dy, c[2].0 + dz);
                            for axis in 0..3 {
                                // ∂w/∂x_axis = Π_{d≠axis} w_d · (±1) · dpos/dx.
                                let mut dw = if b[axis] == 1 { 1.0 } else { -1.0 } * c[axis].2;
                                for d in 0..3 {
                                    if d != axis {
                                        dw *= if b[d] == 1 { c[d].1 } else { 1.0 - c[d].1 };
                                    }
                                }
                                for k in 0..features {
                                    d_points[p * 3 + axis] +=
                                        dw * params[off + i * features + k] * d_out[p * dim + l * features + k];
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// One scalar Adam step over the whole buffer (zeroes `grad`). `t` is the step number after incrementing.
    #[allow(clippy::too_many_arguments)]
    pub fn adam_naive(
        params: &mut [f32],
        grad: &mut [f32],
        m: &mut [f32],
        v: &mut [f32],
        t: u64,
        lr: f32,
        beta1: f32,
        beta2: f32,
        eps: f32,
        weight_decay: f32,
    ) {
        let bc1 = 1.0 - (beta1 as f64).powf(t as f64);
        let bc2 = 1.0 - (beta2 as f64).powf(t as f64);
        for i in 0..params.len() {
            let g = grad[i] + weight_decay * params[i];
            m[i] = beta1 * m[i] + (1.0 - beta1) * g;
            v[i] = beta2 * v[i] + (1.0 - beta2) * g * g;
            let mh = m[i] / bc1 as f32;
            let vh = v[i] / bc2 as f32;
            params[i] -= lr * mh / (vh.sqrt() + eps);
            grad[i] = 0.0;
        }
    }

    /// Apply an activation to one pre-activation: (value, derivative).
    pub fn activation_naive(act: crate::Activation, z: f32) -> (f32, f32) {
        use crate::Activation::*;
        match act {
            None => (z, 1.0),
            Relu => {
                if z > 0.0 {
                    (z, 1.0)
                } else {
                    (0.0, 0.0)
                }
            }
            Softplus { beta } => {
                let x = (beta as f64) * z as f64;
                let v = if x > 20.0 {
                    z as f64
                } else {
                    x.exp().ln_1p() / beta as f64
                };
                let d = 1.0 / (1.0 + (-x).exp());
                (v as f32, if x > 20.0 { 1.0 } else { d as f32 })
            }
            Sigmoid => {
                let s = 1.0 / (1.0 + (-(z as f64)).exp());
                (s as f32, (s * (1.0 - s)) as f32)
            }
        }
    }

    /// Naive MLP forward: returns the pre-activations and activations of every layer (index 0 of `acts` is the
    /// input). `layers[l] = (n_in, n_out, weight offset, bias offset, activation)`, W row-major out×in.
    #[allow(clippy::type_complexity)]
    pub fn mlp_forward_naive(
        params: &[f32],
        layers: &[(usize, usize, usize, usize, crate::Activation)],
        input: &[f32],
        n: usize,
    ) -> (Vec<Vec<f32>>, Vec<Vec<f32>>) {
        let mut pre = Vec::new();
        let mut acts = vec![input[..n * layers[0].0].to_vec()];
        for &(ni, no, wo, bo, act) in layers {
            let a = acts.last().unwrap();
            let mut z = vec![0.0f32; n * no];
            let mut y = vec![0.0f32; n * no];
            for r in 0..n {
                for o in 0..no {
                    let mut s = params[bo + o];
                    for i in 0..ni {
                        s += params[wo + o * ni + i] * a[r * ni + i];
                    }
                    z[r * no + o] = s;
                    y[r * no + o] = activation_naive(act, s).0;
                }
            }
            pre.push(z);
            acts.push(y);
        }
        (pre, acts)
    }

    /// Naive MLP backward: (parameter gradient, input gradient) for upstream `d_out` (n×out).
    pub fn mlp_backward_naive(
        params: &[f32],
        layers: &[(usize, usize, usize, usize, crate::Activation)],
        input: &[f32],
        n: usize,
        d_out: &[f32],
        param_count: usize,
    ) -> (Vec<f32>, Vec<f32>) {
        let (pre, acts) = mlp_forward_naive(params, layers, input, n);
        let mut grad = vec![0.0f32; param_count];
        let mut delta = d_out.to_vec();
        for l in (0..layers.len()).rev() {
            let (ni, no, wo, bo, act) = layers[l];
            for r in 0..n {
                for o in 0..no {
                    delta[r * no + o] *= activation_naive(act, pre[l][r * no + o]).1;
                }
            }
            let a = &acts[l];
            for r in 0..n {
                for o in 0..no {
                    grad[bo + o] += delta[r * no + o];
                    for i in 0..ni {
                        grad[wo + o * ni + i] += delta[r * no + o] * a[r * ni + i];
                    }
                }
            }
            let mut prev = vec![0.0f32; n * ni];
            for r in 0..n {
                for i in 0..ni {
                    let mut s = 0.0;
                    for o in 0..no {
                        s += delta[r * no + o] * params[wo + o * ni + i];
                    }
                    prev[r * ni + i] = s;
                }
            }
            delta = prev;
        }
        (grad, delta)
    }

    /// Real spherical harmonics from associated Legendre polynomials, index `l² + l + m`, degree ≤ 3, with the
    /// Condon–Shortley phase: `Y_l^m = √2 K P_l^m(cos θ) cos(mφ)` for m > 0, `√2 K P_l^|m| sin(|m|φ)` for m < 0,
    /// `K P_l^0` for m = 0, `K = √((2l+1)/(4π) · (l−|m|)!/(l+|m|)!)`.
    pub fn sh_naive(d: [f64; 3]) -> [f64; 16] {
        let ct = d[2];
        let st = (1.0 - ct * ct).max(0.0).sqrt();
        let phi = d[1].atan2(d[0]);
        // P_l^m(ct) with the Condon–Shortley phase, l ≤ 3, 0 ≤ m ≤ l.
        let p = |l: i32, m: i32| -> f64 {
            match (l, m) {
                (0, 0) => 1.0,
                (1, 0) => ct,
                (1, 1) => -st,
                (2, 0) => 0.5 * (3.0 * ct * ct - 1.0),
                (2, 1) => -3.0 * ct * st,
                (2, 2) => 3.0 * st * st,
                (3, 0) => 0.5 * (5.0 * ct * ct * ct - 3.0 * ct),
                (3, 1) => -1.5 * (5.0 * ct * ct - 1.0) * st,
                (3, 2) => 15.0 * ct * st * st,
                (3, 3) => -15.0 * st * st * st,
                _ => unreachable!(),
            }
        };
        let fact = |k: i32| (1..=k).map(f64::from).product::<f64>();
        let mut out = [0.0; 16];
        for l in 0..=3i32 {
            for m in -l..=l {
                let am = m.abs();
                let k = ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI) * fact(l - am) / fact(l + am)).sqrt();
                let v = match m.cmp(&0) {
                    std::cmp::Ordering::Equal => k * p(l, 0),
                    std::cmp::Ordering::Greater => 2f64.sqrt() * k * p(l, am) * (am as f64 * phi).cos(),
                    std::cmp::Ordering::Less => 2f64.sqrt() * k * p(l, am) * (am as f64 * phi).sin(),
                };
                out[(l * l + l + m) as usize] = v;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Activation;

    /// The AVX2 and AVX-512 builds of the activations (those this CPU has) give the portable build's bits:
    /// the same operations, wider lanes.
    #[test]
    fn every_build_of_the_activations_gives_the_same_bits() {
        let z: Vec<f32> = (-20_000..=20_000).map(|i| i as f32 * 3e-4).collect();
        type Build = fn(Activation, &mut [f32], &mut [f32]);
        let mut builds: Vec<(&str, Build)> = vec![("dispatched", activate)];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2.
                builds.push(("avx2", |a, x, d| unsafe { activate_avx2(a, x, d) }));
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F.
                builds.push(("avx512", |a, x, d| unsafe { activate_avx512(a, x, d) }));
            }
        }
        for act in [
            Activation::Softplus { beta: 100.0 },
            Activation::Sigmoid,
            Activation::Relu,
        ] {
            let (mut pv, mut pd) = (z.clone(), vec![0.0f32; z.len()]);
            activate_portable(act, &mut pv, &mut pd);
            for (name, build) in &builds {
                let (mut v, mut d) = (z.clone(), vec![0.0f32; z.len()]);
                build(act, &mut v, &mut d);
                for i in 0..z.len() {
                    assert_eq!(v[i].to_bits(), pv[i].to_bits(), "{name} {act:?} value at z = {}", z[i]);
                    assert_eq!(
                        d[i].to_bits(),
                        pd[i].to_bits(),
                        "{name} {act:?} derivative at z = {}",
                        z[i]
                    );
                }
            }
        }
    }

    /// The bias added in the activation's pass gives the bits of the bias added first: every build, every
    /// activation (the product before it adds nothing where the bias was copied in before).
    #[test]
    fn the_bias_added_with_the_activation_is_the_bias_added_before_it() {
        let bias: Vec<f32> = (0..64).map(|j| (j as f32 - 30.0) * 7e-3).collect();
        let z: Vec<f32> = (0..64 * 301).map(|i| ((i * 7919) % 4001) as f32 * 1e-3 - 2.0).collect();
        type Build = fn(Activation, &[f32], &mut [f32], &mut [f32]);
        let mut builds: Vec<(&str, Build)> = vec![("dispatched", bias_activate), ("portable", bias_activate_portable)];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2.
                builds.push(("avx2", |a, b, x, d| unsafe { bias_activate_avx2(a, b, x, d) }));
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F.
                builds.push(("avx512", |a, b, x, d| unsafe { bias_activate_avx512(a, b, x, d) }));
            }
        }
        for act in [
            Activation::Softplus { beta: 100.0 },
            Activation::Sigmoid,
            Activation::Relu,
            Activation::None,
        ] {
            let mut pv: Vec<f32> = z.iter().enumerate().map(|(i, x)| bias[i % 64] + x).collect();
            let mut pd = vec![0.0f32; z.len()];
            activate_portable(act, &mut pv, &mut pd);
            for (name, build) in &builds {
                let (mut v, mut d) = (z.clone(), vec![0.0f32; z.len()]);
                build(act, &bias, &mut v, &mut d);
                for i in 0..z.len() {
                    assert_eq!(v[i].to_bits(), pv[i].to_bits(), "{name} {act:?} value {i}");
                    assert_eq!(d[i].to_bits(), pd[i].to_bits(), "{name} {act:?} derivative {i}");
                }
            }
        }
    }
}
