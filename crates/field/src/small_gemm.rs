//! `C = A·B` for the MLPs' shapes: B and C row-major and narrow (a layer's 3–64 outputs or inputs), A a chunk
//! of rows or its transpose. `matrixmultiply` packs both operands into panels at every call; at these sizes
//! the packing is a third of the product's time (9 % of an object's training, `perf`) and its tiles leave
//! lanes idle on 16- and 3-wide layers. With AVX-512 the product runs here instead, unpacked: each block of
//! six rows of C lives in up to 24 registers (four 16-lane vectors a row, the last one masked), one row of B
//! is loaded per step of the sum and every element of A broadcast from where it lies. Without AVX-512 the
//! call goes to `matrixmultiply`.
//!
//! The sum runs over `k` in order with one fused multiply-add a term, so its bits differ from
//! `matrixmultiply`'s (which blocks the sum) by rounding; on one CPU they are the same run to run and for any
//! number of threads (the MLP's chunks are fixed).

/// `C = A·B` (beta 0: C is not read): A is m×k with row stride `rsa` and column stride `csa`, B is k×n
/// row-major with row stride `ldb`, C is m×n row-major with row stride `ldc`.
#[allow(clippy::too_many_arguments)]
pub fn gemm_rows(
    m: usize,
    k: usize,
    n: usize,
    a: &[f32],
    rsa: usize,
    csa: usize,
    b: &[f32],
    ldb: usize,
    c: &mut [f32],
    ldc: usize,
) {
    if m == 0 || n == 0 {
        return;
    }
    // Checked arithmetic: the field crate builds without overflow checks, and a wrapped bound would pass.
    let end =
        |rows: usize, stride: usize, last: usize| (rows - 1).checked_mul(stride).and_then(|x| x.checked_add(last));
    assert!(
        ldb >= n && ldc >= n,
        "gemm_rows: rows of B and C overlap (ldb {ldb}, ldc {ldc}, n {n})"
    );
    assert!(end(m, ldc, n).is_some_and(|e| e <= c.len()), "gemm_rows: C too short");
    if k == 0 {
        for i in 0..m {
            c[i * ldc..i * ldc + n].fill(0.0);
        }
        return;
    }
    let a_end = end(m, rsa, 0).and_then(|x| (k - 1).checked_mul(csa).and_then(|y| x.checked_add(y)));
    assert!(a_end.is_some_and(|e| e < a.len()), "gemm_rows: A too short");
    assert!(end(k, ldb, n).is_some_and(|e| e <= b.len()), "gemm_rows: B too short");
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU has AVX-512F (checked just above); the asserts keep every element read or written
        // inside the slices, and `c` is a unique borrow.
        unsafe { avx512::gemm(m, k, n, a, rsa, csa, b, ldb, c, ldc) };
        return;
    }
    crate::kernels::gemm(m, k, n, 1.0, a, rsa, csa, b, ldb, 1, 0.0, c, ldc, 1);
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use std::arch::x86_64::*;

    /// Rows of C a block holds.
    const MR: usize = 6;

    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn gemm(
        m: usize,
        k: usize,
        n: usize,
        a: &[f32],
        rsa: usize,
        csa: usize,
        b: &[f32],
        ldb: usize,
        c: &mut [f32],
        ldc: usize,
    ) {
        // Panels of up to 64 columns (four vectors); the last vector of the last panel masked.
        let mut j0 = 0;
        while j0 < n {
            let width = (n - j0).min(64);
            let vectors = width.div_ceil(16);
            let tail = width - 16 * (vectors - 1);
            let mask: __mmask16 = if tail == 16 { 0xffff } else { (1u16 << tail) - 1 };
            let mut i0 = 0;
            while i0 < m {
                let rows = (m - i0).min(MR);
                let (ap, bp, cp) = (
                    a.as_ptr().add(i0 * rsa),
                    b.as_ptr().add(j0),
                    c.as_mut_ptr().add(i0 * ldc + j0),
                );
                // SAFETY (for each call): the block's rows i0..i0+rows and columns j0..j0+width lie inside the
                // operands (the caller's asserts), the masked lanes are neither read nor written.
                macro_rules! block {
                    ($v:literal) => {
                        match rows {
                            6 => block::<$v, 6>(k, ap, rsa, csa, bp, ldb, cp, ldc, mask),
                            5 => block::<$v, 5>(k, ap, rsa, csa, bp, ldb, cp, ldc, mask),
                            4 => block::<$v, 4>(k, ap, rsa, csa, bp, ldb, cp, ldc, mask),
                            3 => block::<$v, 3>(k, ap, rsa, csa, bp, ldb, cp, ldc, mask),
                            2 => block::<$v, 2>(k, ap, rsa, csa, bp, ldb, cp, ldc, mask),
                            _ => block::<$v, 1>(k, ap, rsa, csa, bp, ldb, cp, ldc, mask),
                        }
                    };
                }
                match vectors {
                    4 => block!(4),
                    3 => block!(3),
                    2 => block!(2),
                    _ => block!(1),
                }
                i0 += rows;
            }
            j0 += width;
        }
    }

    /// One block: `R` rows of C, `V` vectors of 16 columns (the last masked by `mask`).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn block<const V: usize, const R: usize>(
        k: usize,
        a: *const f32,
        rsa: usize,
        csa: usize,
        b: *const f32,
        ldb: usize,
        c: *mut f32,
        ldc: usize,
        mask: __mmask16,
    ) {
        let mut acc = [[_mm512_setzero_ps(); V]; R];
        for p in 0..k {
            let row = b.add(p * ldb);
            let mut bv = [_mm512_setzero_ps(); V];
            for (v, x) in bv.iter_mut().enumerate() {
                *x = if v + 1 == V {
                    _mm512_maskz_loadu_ps(mask, row.add(16 * v))
                } else {
                    _mm512_loadu_ps(row.add(16 * v))
                };
            }
            for (i, acc_row) in acc.iter_mut().enumerate() {
                let x = _mm512_set1_ps(*a.add(i * rsa + p * csa));
                for v in 0..V {
                    acc_row[v] = _mm512_fmadd_ps(x, bv[v], acc_row[v]);
                }
            }
        }
        for (i, acc_row) in acc.iter().enumerate() {
            let out = c.add(i * ldc);
            for (v, x) in acc_row.iter().enumerate() {
                if v + 1 == V {
                    _mm512_mask_storeu_ps(out.add(16 * v), mask, *x);
                } else {
                    _mm512_storeu_ps(out.add(16 * v), *x);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every shape the MLPs use (and odd ones: a panel and a bit, one row, one column), A as rows and as the
    /// transpose of a chunk (the weight gradient's), against the sum in f64.
    #[test]
    fn products_match_the_f64_sum_for_every_shape_and_stride() {
        let mut rng = geom::SplitMix64::new(7);
        for &(m, k, n) in &[
            (512, 35, 64),
            (512, 64, 16),
            (512, 34, 64),
            (512, 64, 64),
            (512, 64, 3),
            (64, 512, 35),
            (3, 512, 64),
            (16, 512, 64),
            (7, 5, 70),
            (1, 1, 1),
            (13, 3, 129),
        ] {
            for transposed in [false, true] {
                let a: Vec<f32> = (0..m * k).map(|_| rng.range(-1.0, 1.0) as f32).collect();
                let (rsa, csa) = if transposed { (1, m) } else { (k, 1) };
                let ldb = n + 3;
                let b: Vec<f32> = (0..k * ldb).map(|_| rng.range(-1.0, 1.0) as f32).collect();
                let ldc = n + 1;
                let mut c = vec![f32::NAN; (m - 1) * ldc + n + 1];
                gemm_rows(m, k, n, &a, rsa, csa, &b, ldb, &mut c, ldc);
                for i in 0..m {
                    for j in 0..n {
                        let want: f64 = (0..k)
                            .map(|p| a[i * rsa + p * csa] as f64 * b[p * ldb + j] as f64)
                            .sum();
                        let got = c[i * ldc + j] as f64;
                        assert!(
                            (got - want).abs() <= 1e-5 * (k as f64).sqrt() * 2.0,
                            "{m}×{k}×{n} (A transposed: {transposed}) at ({i}, {j}): {got} against {want}"
                        );
                    }
                    // Past the row's n columns, C is not written (the masked lanes).
                    assert!(c[i * ldc + n].is_nan(), "{m}×{k}×{n}: wrote past column {n} of row {i}");
                }
            }
        }
    }
}
