//! Images as the stages read and write them: a capture's frames and masks, side-by-side pairs and strips.

use crate::Result;
use pganeus_io::Image;
use std::path::Path;

/// A colour in [0, 1] as a byte.
pub fn to8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// A capture's image as RGB in [0, 1].
pub fn reference_frame(path: &Path) -> Result<Vec<[f32; 3]>> {
    let img = pganeus_io::read_image(path)?;
    let ch = img.channels as usize;
    Ok(img
        .data
        .chunks_exact(ch)
        .map(|p| {
            if ch >= 3 {
                [p[0], p[1], p[2]].map(|v| v as f32 / 255.0)
            } else {
                [p[0] as f32 / 255.0; 3]
            }
        })
        .collect())
}

/// A mask image as inside (≥ 128 in its first channel) or not, per pixel.
pub fn read_mask(path: &Path) -> Result<Vec<bool>> {
    let m = pganeus_io::read_image(path)?;
    let ch = m.channels as usize;
    Ok(m.data.chunks_exact(ch).map(|p| p[0] >= 128).collect())
}

/// Two images of the same height side by side (`left` may be grey or RGBA; `right` is RGB).
pub fn beside(left: &Image, right: &Image) -> Image {
    let (l, r) = (left.to_rgb(), right);
    let mut out = Image::new(l.width + r.width, l.height, 3);
    fn row(img: &Image, y: usize) -> &[u8] {
        let w = img.width as usize * 3;
        &img.data[y * w..(y + 1) * w]
    }
    for y in 0..l.height as usize {
        let d = y * out.width as usize * 3;
        out.data[d..d + l.width as usize * 3].copy_from_slice(row(&l, y));
        out.data[d + l.width as usize * 3..d + out.width as usize * 3].copy_from_slice(row(r, y));
    }
    out
}

/// Up to `count` frames, evenly spaced, one above the other.
pub fn strip(pairs: &[Image], count: usize) -> Image {
    let n = pairs.len();
    let picks: Vec<usize> = if n <= count {
        (0..n).collect()
    } else {
        (0..count).map(|i| i * (n - 1) / (count - 1)).collect()
    };
    let (w, h) = (pairs[0].width, pairs[0].height);
    let mut out = Image::new(w, h * picks.len() as u32, 3);
    for (row, &k) in picks.iter().enumerate() {
        let len = (w * h * 3) as usize;
        let at = row * len;
        out.data[at..at + len].copy_from_slice(&pairs[k].to_rgb().data);
    }
    out
}
