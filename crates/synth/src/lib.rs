//! Synthetic tabletop scenes with exact ground truth — the project's own
//! stand-in for the paper's Blender data: analytic (or baked mesh) SDFs,
//! sphere-traced with soft shadows, motion from the project's simulator, and
//! captures written in the NeuS layout (docs/formats.md) with `truth.json`.

mod build;
pub mod cameras;
pub mod contact_sheet;
pub mod desc;
pub mod generate;
pub mod presets;
pub mod print;
mod rapier_motion;
pub mod raw;
pub mod render;
pub mod texture;

pub use build::SynthError;
pub use desc::{CameraLike, Physics, RawDesc, SynthScene};
pub use generate::{frame_name, generate, simulate_videos, Summary, IMAGE_GAINS};
pub use presets::{contact_scenes, preset, with_raw, Scale, CONTACT_SCENES, PRESETS};
