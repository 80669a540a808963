//! The crate's error: each says which file (or image) and what to do.

use std::path::PathBuf;

/// What can go wrong calibrating.
#[derive(Debug, thiserror::Error)]
pub enum CalibError {
    /// A file could not be read.
    #[error("cannot read {}: {cause}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        cause: std::io::Error,
    },
    /// A board file is malformed or describes no board OpenCV can draw.
    #[error("{}: bad board file: {msg}", path.display())]
    BoardSpec {
        /// The file.
        path: PathBuf,
        /// What is wrong and how to fix it.
        msg: String,
    },
    /// A file of another format (image, camera) could not be read or written.
    #[error(transparent)]
    Io(#[from] pganeus_io::IoError),
    /// The input cannot give what was asked (no board seen, too few views, ...).
    #[error("{msg}")]
    Input {
        /// What is wrong, naming the files, and what to do.
        msg: String,
    },
}

/// The crate's result.
pub type Result<T> = std::result::Result<T, CalibError>;
