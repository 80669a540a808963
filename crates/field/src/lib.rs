//! Neural-field building blocks for pganeus, on the CPU:
//!
//! - [`HashGrid`]: the multiresolution hash encoding of Instant-NGP (Müller et al. 2022): resolutions
//!   `N_l = ⌊N_min · b^l⌋`, `b = exp((ln N_max − ln N_min)/(L − 1))` (eq. 2–3), spatial hash
//!   `(x·1 ⊕ y·π₂ ⊕ z·π₃) mod T` (eq. 4), trilinear interpolation of the 8 cell corners; all levels in one flat
//!   parameter buffer with an offset table, backward split by level so no two threads write the same entry, and a
//!   [`Touched`] record for sparse optimizer steps. Progressive level activation (Neuralangelo) by `active_levels`.
//! - [`Mlp`]: NeuS-style fully connected networks (SDF network with the geometric initialisation of SAL,
//!   Atzmon & Lipman 2020, softplus β = 100; colour network), one sgemm per layer and row chunk.
//! - [`sh_encode`]: degree-3 real spherical harmonics of view directions.
//! - [`Adam`]: Adam (Kingma & Ba 2015) over flat buffers, with lazy sparse steps for the hash tables.
//!
//! Forward/backward pairs follow one naming: `encode`, `encode_backward` (parameters), `encode_backward_input`
//! (inputs), each taking a [`GradMode`]. The hot loops are free functions in [`kernels`], with naive scalar
//! versions in [`mod@kernels::reference`] that the tests compare against.

mod activation;
mod adam;
mod config_error;
mod hash_grid;
pub mod kernels;
mod mlp;
mod sh;
pub mod small_gemm;

pub use activation::Activation;
pub use adam::{Adam, AdamConfig};
pub use config_error::ConfigError;
pub use hash_grid::{HashGrid, HashGridConfig, Touched};
pub use kernels::LevelGeom;
pub use mlp::{Mlp, MlpConfig, MlpScratch};
pub use sh::{sh_encode, sh_encode_backward, SH_DIM};

/// What a backward pass does with a gradient buffer (as tiny-cuda-nn's `GradientMode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GradMode {
    /// Do not compute it; the buffer is left alone.
    Ignore,
    /// Replace the buffer's contents.
    Overwrite,
    /// Add to the buffer's contents.
    Accumulate,
}
