//! One module per file format.

pub mod image_file;
pub mod jpeg;
pub mod mesh_file;
pub mod neus;
pub mod npz;
pub mod obj;
pub mod ply;
pub mod png;
pub mod safetensors;
pub mod trajectory;
