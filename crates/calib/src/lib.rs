//! Cameras from a printed board.
//!
//! - [`dictionary`]: OpenCV's predefined marker dictionaries (bit tables extracted from OpenCV).
//! - [`board`]: the board file (`board.toml`) and the board's geometry, in OpenCV's board frame and the world.
//! - [`draw`]: a board's image exactly as OpenCV draws it, and a true-size SVG to print.

pub mod board;
pub mod dictionary;
pub mod draw;
pub mod error;

pub use board::{Board, BoardKind, BoardMarker, BoardSpec};
pub use dictionary::Dictionary;
pub use error::{CalibError, Result};
