//! Cameras from a printed board.
//!
//! - [`dictionary`]: OpenCV's predefined marker dictionaries (bit tables extracted from OpenCV).
//! - [`board`]: the board file (`board.toml`) and the board's geometry, in OpenCV's board frame and the world.
//! - [`draw`]: a board's image exactly as OpenCV draws it, and a true-size SVG to print.
//! - [`detect`]: ArUco markers in an image (ids and subpixel corners); [`subpix`]: OpenCV's `cornerSubPix`.
//! - [`charuco`]: a ChArUco board's chessboard corners between its detected markers.
//! - [`colmap`]: COLMAP sparse models (text and binary); [`transforms`]: nerfstudio's and instant-ngp's
//!   `transforms.json`; both read into a [`reconstruction`], which [`align`] puts into the board's world.
//! - [`calibrate`]: the lens (OpenCV's model, [`lens`]) and each view's pose from a board seen in several views.
//! - [`undistort`]: images through an ideal pinhole, at any size.
//! - [`region`]: the region a capture's cameras look at (its `scale_mat`).
//! - [`board_views`]: rendered views of a board with their truth (tests, benchmarks).
//! - [`homography`]: plane-to-image homographies; [`gray`]: the gray images detection reads.

pub mod align;
pub mod board;
pub mod board_views;
pub mod calibrate;
pub mod charuco;
pub mod colmap;
pub mod detect;
pub mod dictionary;
pub mod draw;
pub mod error;
pub mod gray;
pub mod homography;
pub mod lens;
mod linalg;
pub mod reconstruction;
pub mod region;
pub mod subpix;
pub mod transforms;
pub mod undistort;

pub use board::{Board, BoardKind, BoardMarker, BoardSpec};
pub use dictionary::Dictionary;
pub use error::{CalibError, Result};
pub use lens::Lens;
