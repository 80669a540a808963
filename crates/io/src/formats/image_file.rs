//! Images by file extension: PNG ([`super::png`]) or JPEG ([`super::jpeg`]), for captures whose images and
//! masks come in either (real footage and many public datasets are JPEG).

use super::jpeg::{read_jpeg, read_jpeg_size};
use super::png::{read_png, read_png_size, Image};
use crate::error::{IoError, Result};
use std::path::Path;

#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Png,
    Jpeg,
}

fn kind(path: &Path) -> Option<Kind> {
    let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
    match ext.as_str() {
        "png" => Some(Kind::Png),
        "jpg" | "jpeg" => Some(Kind::Jpeg),
        _ => None,
    }
}

/// Whether `path` names an image this crate reads (`.png`, `.jpg`, `.jpeg`, any case).
pub fn is_image_file(path: &Path) -> bool {
    kind(path).is_some()
}

fn unknown(path: &Path) -> IoError {
    IoError::Png {
        path: path.to_path_buf(),
        msg: "not an image this tool reads: the name must end in .png, .jpg or .jpeg".into(),
    }
}

/// Reads a PNG or JPEG (by extension) into an 8-bit gray, RGB or RGBA image.
pub fn read_image(path: &Path) -> Result<Image> {
    match kind(path) {
        Some(Kind::Png) => read_png(path),
        Some(Kind::Jpeg) => read_jpeg(path),
        None => Err(unknown(path)),
    }
}

/// The size of a PNG or JPEG (by extension), from its header.
pub fn read_image_size(path: &Path) -> Result<(u32, u32)> {
    match kind(path) {
        Some(Kind::Png) => read_png_size(path),
        Some(Kind::Jpeg) => read_jpeg_size(path),
        None => Err(unknown(path)),
    }
}
