//! The one error type of the crate. Every variant carries the file's path so a
//! message read on its own says which file is wrong.

use std::path::PathBuf;

/// Everything that can go wrong reading or writing a pganeus file.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened or read.
    #[error("cannot read {}: {source}", path.display())]
    Open {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The file (or its temporary sibling, or its folder) could not be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The JSON is malformed or does not have the expected shape.
    /// serde_json's message ends with the line and column.
    #[error("{}: bad JSON: {source}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The parser's error, with line and column.
        source: serde_json::Error,
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
    /// The file parses but a value breaks the contract of FORMATS.md
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
}

/// `std::result::Result` with [`IoError`].
pub type Result<T> = std::result::Result<T, IoError>;
