//! NeuS on two CPU cores (Sec. 3.2, Eq. 1–2 of the paper): a hash-grid SDF
//! field with colour, rays from a NeuS-layout capture, empty-space skipping
//! with an occupancy grid, NeuS's unbiased volume rendering, training with
//! colour, eikonal and mask losses, checkpoints that resume, and rendering,
//! also of two fields of one object switched by the camera's side (Eq. 3–4).

pub mod checkpoint;
pub mod config;
pub mod dataset;
mod fd_samples;
pub mod neus_field;
pub mod occupancy;
pub mod render_view;
pub mod switching;
pub mod trainer;
pub mod volume;

pub use config::TrainConfig;
pub use dataset::{Dataset, DatasetError};
pub use neus_field::{FieldConfig, NeusField};
pub use trainer::{LossTerms, NeusTrainer, StepStats};
