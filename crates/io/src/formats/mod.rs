//! One module per file format.

pub mod obj;
pub mod ply;
pub mod trajectory;
