//! A gray image in `f32` (0–255) with the two samplings detection needs: bilinear at a subpixel position and
//! box means from an integral image. Pixel centres are at integer coordinates (OpenCV's convention).

use pganeus_io::Image;

/// A gray image, row by row.
#[derive(Clone, Debug)]
pub struct Gray {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` values, 0 black to 255 white.
    pub data: Vec<f32>,
}

impl Gray {
    /// An image's luma (ITU-R BT.601 weights, as OpenCV's `cvtColor(..., COLOR_RGB2GRAY)`).
    pub fn from_image(image: &Image) -> Self {
        let c = image.channels as usize;
        let data = image
            .data
            .chunks_exact(c)
            .map(|p| match c {
                1 => p[0] as f32,
                _ => 0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32,
            })
            .collect();
        Gray {
            width: image.width as usize,
            height: image.height as usize,
            data,
        }
    }

    /// The image in linear light (0–255): the sRGB encoding cameras write undone, so that a pixel's value is
    /// proportional to the light it got and edges can be located by halfway crossings.
    pub fn to_linear(&self) -> Gray {
        // A table of the 8-bit values, interpolated between them (the data may be fractional).
        let table: Vec<f32> = (0..=256)
            .map(|v| 255.0 * srgb_to_linear((v as f64 / 255.0).min(1.0)) as f32)
            .collect();
        let data = self
            .data
            .iter()
            .map(|&v| {
                let v = v.clamp(0.0, 255.0);
                let i = v.floor() as usize;
                let f = v - i as f32;
                table[i] * (1.0 - f) + table[(i + 1).min(256)] * f
            })
            .collect();
        Gray {
            width: self.width,
            height: self.height,
            data,
        }
    }

    /// The value at pixel `(x, y)`, clamped to the image.
    pub fn at_clamped(&self, x: i64, y: i64) -> f32 {
        let x = x.clamp(0, self.width as i64 - 1) as usize;
        let y = y.clamp(0, self.height as i64 - 1) as usize;
        self.data[y * self.width + x]
    }

    /// Bilinear interpolation at `(x, y)`, the border replicated beyond the image.
    pub fn bilinear(&self, x: f64, y: f64) -> f32 {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = self.at_clamped(x0, y0) * (1.0 - fx) + self.at_clamped(x0 + 1, y0) * fx;
        let bottom = self.at_clamped(x0, y0 + 1) * (1.0 - fx) + self.at_clamped(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// Sums over rectangles in constant time.
pub struct Integral {
    width: usize,
    height: usize,
    /// `(width + 1) * (height + 1)` prefix sums.
    sums: Vec<f64>,
}

impl Integral {
    /// The integral image of `gray`.
    pub fn new(gray: &Gray) -> Self {
        let (w, h) = (gray.width, gray.height);
        let mut sums = vec![0.0; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0.0;
            for x in 0..w {
                row += gray.data[y * w + x] as f64;
                sums[(y + 1) * (w + 1) + x + 1] = sums[y * (w + 1) + x + 1] + row;
            }
        }
        Integral {
            width: w,
            height: h,
            sums,
        }
    }

    /// The mean over the `2r + 1` square centred on `(x, y)`, cut to the image.
    pub fn box_mean(&self, x: usize, y: usize, r: usize) -> f32 {
        let (x0, y0) = (x.saturating_sub(r), y.saturating_sub(r));
        let (x1, y1) = ((x + r + 1).min(self.width), (y + r + 1).min(self.height));
        let w = self.width + 1;
        let s = self.sums[y1 * w + x1] - self.sums[y0 * w + x1] - self.sums[y1 * w + x0] + self.sums[y0 * w + x0];
        (s / ((x1 - x0) * (y1 - y0)) as f64) as f32
    }
}

/// The sRGB transfer function inverted: an encoded value (0–1) back to linear light.
pub fn srgb_to_linear(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB transfer function: linear light (0–1) to the encoded value (0–1) a camera writes.
pub fn linear_to_srgb(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn srgb_encoding_and_decoding_are_inverse() {
        for i in 0..=1000 {
            let v = i as f64 / 1000.0;
            assert!(
                (super::linear_to_srgb(super::srgb_to_linear(v)) - v).abs() < 1e-12,
                "{v}"
            );
        }
    }
}
