//! The one error type of the crate. Every variant carries the file's path so a
//! message read on its own says which file is wrong, and says its cause itself:
//! the cause is not also given as the error's `source()`, so a printer that
//! walks the chain (the CLI's) shows it once.

use std::path::{Path, PathBuf};

/// Everything that can go wrong reading or writing a pganeus file.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened or read.
    #[error("cannot read {}: {cause}", path.display())]
    Open {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        cause: std::io::Error,
    },
    /// The file (or its temporary sibling, or its folder) could not be written.
    #[error("cannot write {}: {cause}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        cause: std::io::Error,
    },
    /// The JSON is malformed or does not have the expected shape.
    /// serde_json's message ends with the line and column.
    #[error("{}: bad JSON: {cause}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The parser's error, with line and column.
        cause: serde_json::Error,
    },
    /// The PLY file is malformed (header, truncated body, bad index, ...).
    #[error("{}: bad PLY file: {msg}", path.display())]
    Ply {
        /// The file.
        path: PathBuf,
        /// What is wrong, in plain words.
        msg: String,
    },
    /// The OBJ file is malformed; `msg` starts with the line number.
    #[error("{}: bad OBJ file: {msg}", path.display())]
    Obj {
        /// The file.
        path: PathBuf,
        /// What is wrong, in plain words, with the line number.
        msg: String,
    },
    /// The file parses but a value breaks the contract of docs/formats.md
    /// (not finite, non-unit quaternion, lengths that disagree, ...).
    #[error("{}: invalid value at `{field}`: {msg}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Where in the file, e.g. `bodies[0].poses[12].q`.
        field: String,
        /// What is wrong, in plain words.
        msg: String,
    },
    /// The PNG file is malformed, truncated or of a kind this crate does not
    /// read; or an image to write is inconsistent.
    #[error("{}: bad PNG file: {msg}", path.display())]
    Png {
        /// The file.
        path: PathBuf,
        /// What is wrong, in plain words.
        msg: String,
    },
    /// The NPY or NPZ file is malformed (header, dtype, ZIP structure, CRC, ...).
    /// For an entry of an NPZ archive, `msg` starts with the entry's name.
    #[error("{}: bad NPY/NPZ file: {msg}", path.display())]
    Npz {
        /// The file.
        path: PathBuf,
        /// What is wrong, in plain words.
        msg: String,
    },
    /// The safetensors file is malformed (header length, JSON, dtype, shape,
    /// offsets, truncated buffer, ...), or a tensor asked for is missing or of
    /// another dtype or shape; `msg` names the tensor.
    #[error("{}: bad safetensors file: {msg}", path.display())]
    Safetensors {
        /// The file.
        path: PathBuf,
        /// What is wrong, in plain words.
        msg: String,
    },
    /// A capture folder breaks the layout of docs/formats.md ("A capture"): a
    /// missing mask or camera, images of different sizes, ... `path` is the
    /// offending file (or folder).
    #[error("{}: {msg}", path.display())]
    Capture {
        /// The offending file or folder.
        path: PathBuf,
        /// What is wrong, in plain words.
        msg: String,
    },
}

impl IoError {
    /// The file (or folder) the error is about.
    pub fn path(&self) -> &Path {
        match self {
            IoError::Open { path, .. }
            | IoError::Write { path, .. }
            | IoError::Json { path, .. }
            | IoError::Ply { path, .. }
            | IoError::Obj { path, .. }
            | IoError::Invalid { path, .. }
            | IoError::Png { path, .. }
            | IoError::Npz { path, .. }
            | IoError::Safetensors { path, .. }
            | IoError::Capture { path, .. } => path,
        }
    }

    /// The message without the path, e.g. `bad PNG file: truncated`.
    pub(crate) fn detail(&self) -> String {
        match self {
            IoError::Open { cause, .. } => format!("cannot read: {cause}"),
            IoError::Write { cause, .. } => format!("cannot write: {cause}"),
            IoError::Json { cause, .. } => format!("bad JSON: {cause}"),
            IoError::Ply { msg, .. } => format!("bad PLY file: {msg}"),
            IoError::Obj { msg, .. } => format!("bad OBJ file: {msg}"),
            IoError::Invalid { field, msg, .. } => format!("invalid value at `{field}`: {msg}"),
            IoError::Png { msg, .. } => format!("bad PNG file: {msg}"),
            IoError::Npz { msg, .. } => format!("bad NPY/NPZ file: {msg}"),
            IoError::Safetensors { msg, .. } => format!("bad safetensors file: {msg}"),
            IoError::Capture { msg, .. } => msg.clone(),
        }
    }
}

/// `std::result::Result` with [`IoError`].
pub type Result<T> = std::result::Result<T, IoError>;
