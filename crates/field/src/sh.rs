//! Real spherical harmonics up to degree 3 as a view-direction encoding (as Instant-NGP's `SphericalHarmonics`).

use crate::kernels;
use rayon::prelude::*;

/// Coefficients per direction (degrees 0–3).
pub const SH_DIM: usize = 16;

/// Directions per rayon task.
const SH_CHUNK: usize = 1024;

/// Encode unit directions `dirs` (N×3) into `out` (N×16): real spherical harmonics with the Condon–Shortley phase,
/// coefficient `l² + l + m` for degree `l`, order `m`. Directions are used as given (not normalised here).
pub fn sh_encode(dirs: &[f32], out: &mut [f32]) {
    assert_eq!(dirs.len() % 3, 0, "sh_encode: dirs length not a multiple of 3");
    assert_eq!(out.len(), dirs.len() / 3 * SH_DIM, "sh_encode: out length");
    dirs.par_chunks(SH_CHUNK * 3)
        .zip(out.par_chunks_mut(SH_CHUNK * SH_DIM))
        .for_each(|(d, o)| kernels::sh_encode_rows(d, o));
}

/// Backward of [`sh_encode`]: `d_dirs` (N×3) += the gradient with respect to the directions' components, from
/// `d_out` (N×16).
pub fn sh_encode_backward(dirs: &[f32], d_out: &[f32], d_dirs: &mut [f32]) {
    assert_eq!(dirs.len() % 3, 0, "sh_encode_backward: dirs length not a multiple of 3");
    assert_eq!(d_out.len(), dirs.len() / 3 * SH_DIM, "sh_encode_backward: d_out length");
    assert_eq!(d_dirs.len(), dirs.len(), "sh_encode_backward: d_dirs length");
    dirs.par_chunks(SH_CHUNK * 3)
        .zip(d_out.par_chunks(SH_CHUNK * SH_DIM))
        .zip(d_dirs.par_chunks_mut(SH_CHUNK * 3))
        .for_each(|((d, g), dd)| kernels::sh_backward_rows(d, g, dd));
}
