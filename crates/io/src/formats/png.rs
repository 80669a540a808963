//! 8-bit PNG images: the `image/` and `mask/` files of a capture (docs/formats.md, "A capture").
//!
//! Reading accepts every PNG colour type and bit depth and brings it to 8-bit
//! gray, RGB or RGBA ([`Image::channels`] 1, 3 or 4):
//! - palette images are expanded to RGB, or to RGBA when they carry a `tRNS` chunk;
//! - gray images of 1, 2 or 4 bits are scaled to 8 bits;
//! - gray + alpha becomes RGBA (the gray value copied to R, G and B), so no
//!   information is lost and there are only three layouts to handle;
//! - a `tRNS` colour key adds an alpha channel (gray → RGBA, RGB → RGBA);
//! - 16-bit samples keep their high byte.
//!
//! Writing is deterministic (the same image always gives the same bytes) and
//! uses the encoder's fast setting, since captures are written by the thousand.

use std::io::{BufReader, Cursor};
use std::path::Path;

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};

/// An 8-bit image, row-major with interleaved channels: the sample `c` of the
/// pixel at column `x`, row `y` is `data[(y * width + x) * channels + c]`.
/// Row 0 is the top of the image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples per pixel: 1 (gray), 3 (RGB) or 4 (RGBA).
    pub channels: u8,
    /// `width * height * channels` samples.
    pub data: Vec<u8>,
}

impl Image {
    /// A black (and, with 4 channels, fully transparent) image.
    ///
    /// # Panics
    /// If `channels` is not 1, 3 or 4, or the size does not fit in memory.
    pub fn new(width: u32, height: u32, channels: u8) -> Self {
        assert!(
            matches!(channels, 1 | 3 | 4),
            "Image::new: channels must be 1, 3 or 4, not {channels}"
        );
        let len = sample_count(width, height, channels).expect("Image::new: image too large");
        Self {
            width,
            height,
            channels,
            data: vec![0; len],
        }
    }

    /// Checks that `channels` is 1, 3 or 4 and that `data` holds exactly
    /// `width * height * channels` samples; the error says what is wrong.
    pub fn check(&self) -> std::result::Result<(), String> {
        if !matches!(self.channels, 1 | 3 | 4) {
            return Err(format!("channels is {}, must be 1, 3 or 4", self.channels));
        }
        match sample_count(self.width, self.height, self.channels) {
            Some(n) if n == self.data.len() => Ok(()),
            Some(n) => Err(format!(
                "{}x{} pixels of {} channels need {n} samples, data has {}",
                self.width,
                self.height,
                self.channels,
                self.data.len()
            )),
            None => Err(format!("{}x{} pixels is too large", self.width, self.height)),
        }
    }

    /// The samples of the pixel at column `x`, row `y` (`channels` of them).
    ///
    /// # Panics
    /// If `(x, y)` is outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> &[u8] {
        let i = self.offset(x, y);
        &self.data[i..i + self.channels as usize]
    }

    /// The samples of the pixel at column `x`, row `y`, to modify.
    ///
    /// # Panics
    /// If `(x, y)` is outside the image.
    pub fn pixel_mut(&mut self, x: u32, y: u32) -> &mut [u8] {
        let i = self.offset(x, y);
        let c = self.channels as usize;
        &mut self.data[i..i + c]
    }

    fn offset(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) is outside a {}x{} image",
            self.width,
            self.height
        );
        (y as usize * self.width as usize + x as usize) * self.channels as usize
    }

    /// The image as RGB: gray is copied to R, G and B; alpha is dropped.
    pub fn to_rgb(&self) -> Image {
        let data = match self.channels {
            1 => self.data.iter().flat_map(|&g| [g, g, g]).collect(),
            4 => self.data.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect(),
            _ => self.data.clone(),
        };
        Image {
            width: self.width,
            height: self.height,
            channels: 3,
            data,
        }
    }

    /// The image as one gray channel, e.g. to read a mask.
    ///
    /// RGB and RGBA pixels become their luma `(299 R + 587 G + 114 B) / 1000`
    /// (ITU-R BT.601, rounded); alpha is ignored. Black stays 0 and white stays
    /// 255, so a black-and-white mask reads the same whichever channel one
    /// would pick (NeuS's loader takes the first channel OpenCV gives, blue).
    pub fn to_gray(&self) -> Image {
        let luma = |p: &[u8]| ((299 * p[0] as u32 + 587 * p[1] as u32 + 114 * p[2] as u32 + 500) / 1000) as u8;
        let data = match self.channels {
            3 => self.data.chunks_exact(3).map(luma).collect(),
            4 => self.data.chunks_exact(4).map(luma).collect(),
            _ => self.data.clone(),
        };
        Image {
            width: self.width,
            height: self.height,
            channels: 1,
            data,
        }
    }
}

fn sample_count(width: u32, height: u32, channels: u8) -> Option<usize> {
    (width as usize)
        .checked_mul(height as usize)?
        .checked_mul(channels as usize)
}

/// Reads a PNG file into an 8-bit gray, RGB or RGBA image (see the module doc
/// for how other layouts are converted).
pub fn read_png(path: &Path) -> Result<Image> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })?;
    read_png_bytes(&bytes, path)
}

/// [`read_png`] from bytes already in memory; `path` is only used in errors.
pub fn read_png_bytes(bytes: &[u8], path: &Path) -> Result<Image> {
    let err = |msg: String| IoError::Png {
        path: path.to_path_buf(),
        msg,
    };
    check_signature(bytes).map_err(err)?;

    let mut decoder = png::Decoder::new(Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().map_err(|e| err(describe(&e)))?;
    let (width, height) = (reader.info().width, reader.info().height);
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| err(format!("{width}x{height} pixels is too large")))?;
    // DEFLATE expands at most ~1032 times and a 1-bit palette index can become
    // 4 bytes of RGBA, so a real file is never this small for its size: it is
    // truncated or corrupt, and allocating for it would only waste memory.
    if size / 40_000 > bytes.len() {
        return Err(err(format!(
            "truncated: the header says {width}x{height} pixels but the file has only {} bytes",
            bytes.len()
        )));
    }
    let mut buf = vec![0u8; size];
    let out = reader.next_frame(&mut buf).map_err(|e| err(describe(&e)))?;
    // Reading up to IEND catches files cut after the image data.
    reader.finish().map_err(|e| err(describe(&e)))?;
    buf.truncate(out.buffer_size());

    if out.bit_depth != png::BitDepth::Eight {
        return Err(err(format!(
            "unexpected bit depth {:?} after conversion",
            out.bit_depth
        )));
    }
    let (channels, data) = match out.color_type {
        png::ColorType::Grayscale => (1, buf),
        png::ColorType::Rgb => (3, buf),
        png::ColorType::Rgba => (4, buf),
        png::ColorType::GrayscaleAlpha => (4, buf.chunks_exact(2).flat_map(|p| [p[0], p[0], p[0], p[1]]).collect()),
        png::ColorType::Indexed => return Err(err("palette was not expanded".to_string())),
    };
    let image = Image {
        width: out.width,
        height: out.height,
        channels,
        data,
    };
    image.check().map_err(err)?;
    Ok(image)
}

/// The width and height of a PNG file, from its header only (the pixels are
/// not decoded, so this is fast).
pub fn read_png_size(path: &Path) -> Result<(u32, u32)> {
    let err = |msg: String| IoError::Png {
        path: path.to_path_buf(),
        msg,
    };
    let file = std::fs::File::open(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })?;
    let mut reader = BufReader::with_capacity(512, file);
    let mut signature = [0u8; 8];
    std::io::Read::read_exact(&mut reader, &mut signature)
        .map_err(|e| err(format!("not a PNG (cannot read its signature: {e})")))?;
    check_signature(&signature).map_err(err)?;
    std::io::Seek::seek(&mut reader, std::io::SeekFrom::Start(0)).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })?;
    let mut decoder = png::Decoder::new(reader);
    let info = decoder.read_header_info().map_err(|e| err(describe(&e)))?;
    Ok((info.width, info.height))
}

const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

fn check_signature(bytes: &[u8]) -> std::result::Result<(), String> {
    let n = bytes.len().min(8);
    if bytes[..n] != SIGNATURE[..n] {
        Err("not a PNG (bad signature)".to_string())
    } else if n < 8 {
        Err(format!("truncated: {n} bytes"))
    } else {
        Ok(())
    }
}

fn describe(e: &png::DecodingError) -> String {
    match e {
        png::DecodingError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "truncated: the file ends before the image does".to_string()
        }
        png::DecodingError::LimitsExceeded => "too large to decode".to_string(),
        e => format!("corrupt: {e}"),
    }
}

/// Encodes `image` as an 8-bit PNG (gray, RGB or RGBA as `channels` says).
/// The same image always gives the same bytes.
///
/// # Panics
/// If [`Image::check`] fails or the image is empty (PNG needs at least one
/// pixel). [`write_png`] returns these as errors instead.
pub fn encode_png(image: &Image) -> Vec<u8> {
    try_encode(image).unwrap_or_else(|msg| panic!("encode_png: {msg}"))
}

/// Encodes `image` as PNG and writes it to `path` atomically.
pub fn write_png(path: &Path, image: &Image) -> Result<()> {
    let bytes = try_encode(image).map_err(|msg| IoError::Png {
        path: path.to_path_buf(),
        msg: format!("cannot encode: {msg}"),
    })?;
    write_atomic(path, &bytes)
}

/// Encodes `image` as PNG stating `dpi` dots per inch (what a printer reads to print it at its true size) and
/// writes it to `path` atomically.
pub fn write_png_at_dpi(path: &Path, image: &Image, dpi: f64) -> Result<()> {
    let bytes = try_encode_at(image, Some(dpi)).map_err(|msg| IoError::Png {
        path: path.to_path_buf(),
        msg: format!("cannot encode: {msg}"),
    })?;
    write_atomic(path, &bytes)
}

/// Writes `frames` (all of one size and channel count) as an animated PNG
/// (APNG, played in a loop) at `fps` frames per second, atomically. Viewers
/// without APNG support show the first frame.
pub fn write_apng(path: &Path, frames: &[Image], fps: f64) -> Result<()> {
    let bytes = try_encode_apng(frames, fps).map_err(|msg| IoError::Png {
        path: path.to_path_buf(),
        msg: format!("cannot encode the animation: {msg}"),
    })?;
    write_atomic(path, &bytes)
}

/// The smallest rectangle `(x, y, width, height)` holding every pixel where `a` and `b` (same size)
/// differ; a single pixel when they are equal (an APNG frame cannot be empty).
fn changed_rect(a: &Image, b: &Image) -> (u32, u32, u32, u32) {
    let (w, c) = (a.width as usize, a.channels as usize);
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for (y, (ra, rb)) in a.data.chunks_exact(w * c).zip(b.data.chunks_exact(w * c)).enumerate() {
        if ra == rb {
            continue;
        }
        let first = (0..w).find(|&x| ra[x * c..(x + 1) * c] != rb[x * c..(x + 1) * c]);
        let last = (0..w).rev().find(|&x| ra[x * c..(x + 1) * c] != rb[x * c..(x + 1) * c]);
        if let (Some(f), Some(l)) = (first, last) {
            (x0, x1, y0, y1) = (x0.min(f), x1.max(l), y0.min(y), y1.max(y));
        }
    }
    if x0 == usize::MAX {
        return (0, 0, 1, 1);
    }
    (x0 as u32, y0 as u32, (x1 - x0 + 1) as u32, (y1 - y0 + 1) as u32)
}

/// The samples of `image` inside a rectangle, row by row.
fn crop(image: &Image, (x, y, w, h): (u32, u32, u32, u32)) -> Vec<u8> {
    let c = image.channels as usize;
    let row = image.width as usize * c;
    let mut out = Vec::with_capacity(w as usize * h as usize * c);
    for r in y as usize..(y + h) as usize {
        out.extend_from_slice(&image.data[r * row + x as usize * c..r * row + (x + w) as usize * c]);
    }
    out
}

/// APNG bytes: the first frame whole, each later one as the rectangle that changed since the frame
/// before it, drawn over that frame (a still camera's video stores little more than its moving parts).
fn try_encode_apng(frames: &[Image], fps: f64) -> std::result::Result<Vec<u8>, String> {
    let first = frames.first().ok_or("no frames")?;
    for (i, f) in frames.iter().enumerate() {
        f.check().map_err(|e| format!("frame {i}: {e}"))?;
        if (f.width, f.height, f.channels) != (first.width, first.height, first.channels) {
            return Err(format!("frame {i} differs in size or channels from frame 0"));
        }
    }
    if first.width == 0 || first.height == 0 {
        return Err(format!("a PNG cannot be {}x{}", first.width, first.height));
    }
    if !(fps.is_finite() && fps > 0.0) {
        return Err(format!("fps must be positive, got {fps}"));
    }
    let color = match first.channels {
        1 => png::ColorType::Grayscale,
        3 => png::ColorType::Rgb,
        _ => png::ColorType::Rgba,
    };
    let e = |e: png::EncodingError| e.to_string();
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, first.width, first.height);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Balanced);
    encoder.set_animated(frames.len() as u32, 0).map_err(e)?;
    // The delay as a fraction: 1000 / (fps · 1000) s.
    let den = (fps * 100.0).round().clamp(1.0, u16::MAX as f64) as u16;
    encoder.set_frame_delay(100, den).map_err(e)?;
    // Later frames are drawn over the one before (with RGBA, their pixels replace it, alpha and all).
    encoder.set_dispose_op(png::DisposeOp::None).map_err(e)?;
    encoder.set_blend_op(png::BlendOp::Source).map_err(e)?;
    let mut writer = encoder.write_header().map_err(e)?;
    writer.write_image_data(&first.data).map_err(e)?;
    for pair in frames.windows(2) {
        let rect = changed_rect(&pair[0], &pair[1]);
        writer.reset_frame_position().map_err(e)?;
        writer.set_frame_dimension(rect.2, rect.3).map_err(e)?;
        writer.set_frame_position(rect.0, rect.1).map_err(e)?;
        writer.write_image_data(&crop(&pair[1], rect)).map_err(e)?;
    }
    writer.finish().map_err(e)?;
    Ok(bytes)
}

fn try_encode(image: &Image) -> std::result::Result<Vec<u8>, String> {
    try_encode_at(image, None)
}

/// Encodes `image`; with `dpi`, the file says its pixel density (a `pHYs` chunk), so a printer prints it at
/// its true size.
fn try_encode_at(image: &Image, dpi: Option<f64>) -> std::result::Result<Vec<u8>, String> {
    image.check()?;
    if image.width == 0 || image.height == 0 {
        return Err(format!("a PNG cannot be {}x{}", image.width, image.height));
    }
    let color = match image.channels {
        1 => png::ColorType::Grayscale,
        3 => png::ColorType::Rgb,
        _ => png::ColorType::Rgba,
    };
    let mut bytes = Vec::with_capacity(image.data.len() / 2 + 1024);
    let mut encoder = png::Encoder::new(&mut bytes, image.width, image.height);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    if let Some(dpi) = dpi {
        let per_metre = (dpi / 0.0254).round() as u32;
        encoder.set_pixel_dims(Some(png::PixelDimensions {
            xppu: per_metre,
            yppu: per_metre,
            unit: png::Unit::Meter,
        }));
    }
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(&image.data).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())?;
    Ok(bytes)
}
