//! JPEG images through zune-jpeg, to the same [`Image`] as PNG: gray stays gray, colour (YCbCr, CMYK) becomes
//! RGB. Errors name the file; no input panics.

use super::png::Image;
use crate::error::{IoError, Result};
use std::path::Path;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;
use zune_jpeg::JpegDecoder;

fn err(path: &Path, msg: String) -> IoError {
    IoError::Png {
        path: path.to_path_buf(),
        msg: format!("JPEG: {msg}"),
    }
}

fn read(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })
}

/// The width and height in a JPEG's header.
pub fn read_jpeg_size(path: &Path) -> Result<(u32, u32)> {
    let bytes = read(path)?;
    let mut d = JpegDecoder::new(ZCursor::new(&bytes[..]));
    d.decode_headers().map_err(|e| err(path, format!("{e:?}")))?;
    let info = d.info().ok_or_else(|| err(path, "no header".into()))?;
    Ok((info.width as u32, info.height as u32))
}

/// Reads a JPEG file into an 8-bit gray or RGB image.
pub fn read_jpeg(path: &Path) -> Result<Image> {
    read_jpeg_bytes(&read(path)?, path)
}

/// A JPEG holds at least a few bits per 8×8 block; a header claiming far more pixels than the file could
/// hold is damage, refused before the decoder allocates for it.
const MAX_PIXELS_PER_BYTE: usize = 2000;

/// [`read_jpeg`] from bytes in memory; `path` is only used in errors.
pub fn read_jpeg_bytes(bytes: &[u8], path: &Path) -> Result<Image> {
    let mut probe = JpegDecoder::new(ZCursor::new(bytes));
    probe.decode_headers().map_err(|e| err(path, format!("{e:?}")))?;
    let info = probe.info().ok_or_else(|| err(path, "no header".into()))?;
    let pixels = info.width as usize * info.height as usize;
    if pixels > MAX_PIXELS_PER_BYTE * bytes.len() {
        return Err(err(
            path,
            format!(
                "truncated or damaged: the header says {}x{} pixels but the file has only {} bytes",
                info.width,
                info.height,
                bytes.len()
            ),
        ));
    }
    let (out, channels) = if info.components == 1 {
        (ColorSpace::Luma, 1)
    } else {
        (ColorSpace::RGB, 3)
    };
    let options = DecoderOptions::default().jpeg_set_out_colorspace(out);
    let mut d = JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    let data = d.decode().map_err(|e| err(path, format!("{e:?}")))?;
    let image = Image {
        width: info.width as u32,
        height: info.height as u32,
        channels,
        data,
    };
    image.check().map_err(|m| err(path, m))?;
    Ok(image)
}

/// `image` (gray or RGB; RGBA loses its alpha) as a baseline JPEG file's bytes at `quality` (1–100).
pub fn encode_jpeg(image: &Image, quality: u8) -> std::result::Result<Vec<u8>, String> {
    image.check()?;
    if image.width > u16::MAX as u32 || image.height > u16::MAX as u32 || image.width == 0 || image.height == 0 {
        return Err(format!("a JPEG cannot be {}x{}", image.width, image.height));
    }
    let (data, color) = match image.channels {
        1 => (image.data.clone(), jpeg_encoder::ColorType::Luma),
        3 => (image.data.clone(), jpeg_encoder::ColorType::Rgb),
        _ => (image.to_rgb().data, jpeg_encoder::ColorType::Rgb),
    };
    let mut out = Vec::new();
    jpeg_encoder::Encoder::new(&mut out, quality.clamp(1, 100))
        .encode(&data, image.width as u16, image.height as u16, color)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

/// Writes `image` as a JPEG at `quality` (1–100), atomically.
pub fn write_jpeg(path: &Path, image: &Image, quality: u8) -> Result<()> {
    let bytes = encode_jpeg(image, quality).map_err(|msg| err(path, format!("cannot encode: {msg}")))?;
    crate::atomic::write_atomic(path, &bytes)
}
