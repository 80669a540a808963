//! NeuS on two CPU cores (Sec. 3.2, Eq. 1–2 of the paper): a hash-grid SDF
//! field with colour, rays from a NeuS-layout capture, empty-space skipping
//! with an occupancy grid, NeuS's unbiased volume rendering, training with
//! colour, eikonal and mask losses, checkpoints that resume, and rendering,
//! also of two fields of one object switched by the camera's side (Eq. 3–4).
//! Objects start from a sphere; scenes start from the board plane and put
//! what lies beyond the unit sphere in a background field (NeRF++), with
//! multi-view stereo points pulling the zero level onto obstacles early.
//! Each training view's exposure and white balance are learned beside the
//! field (`appearance`), so a camera's changes stay out of it.

pub mod appearance;
pub mod background_field;
pub mod baked_geometry;
pub mod checkpoint;
pub mod compose;
pub mod config;
pub mod dataset;
mod fd_samples;
pub mod field_pass;
pub mod holdout;
pub mod neus_field;
pub mod object_model;
pub mod occupancy;
pub mod param_average;
pub mod ray_rounds;
pub mod regulariser_points;
pub mod render_view;
pub mod step_phases;
pub mod stereo;
pub mod surface;
pub mod surface_band;
pub mod switching;
pub mod trainer;
pub mod untrained_field;
pub mod volume;

pub use config::{CaptureSubject, TrainConfig};
pub use dataset::{Dataset, DatasetError};
pub use field::ConfigError;
pub use neus_field::{FieldConfig, FieldInit, NeusField};
pub use object_model::{ObjectError, ObjectModel};
pub use trainer::{LossTerms, NeusTrainer, StepStats, TrainError};
