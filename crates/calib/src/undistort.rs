//! Images through an ideal pinhole: each output pixel's ray looked up through the real lens, a few samples
//! per output pixel averaged (so a smaller output is not aliased).

use pganeus_io::Image;

use crate::lens::Lens;

/// `image` (taken through `lens`) as seen through the distortion-free `target` at `width` × `height`; samples
/// the source falls short of are black. Pixel centres at integers in both lenses (OpenCV's convention).
pub fn undistort_image(image: &Image, lens: &Lens, target: &Lens, width: u32, height: u32) -> Image {
    let channels = image.channels as usize;
    let mut out = Image::new(width, height, image.channels);
    // Samples per side: enough to cover a source pixel at least once per output pixel.
    let ratio = (lens.fx / target.fx).max(lens.fy / target.fy);
    let per_side = ratio.ceil().clamp(1.0, 4.0) as usize;
    let (sw, sh) = (image.width as i64, image.height as i64);
    let sample = |x: f64, y: f64, c: usize| -> Option<f64> {
        if !(x >= -0.5 && y >= -0.5 && x <= sw as f64 - 0.5 && y <= sh as f64 - 0.5) {
            return None;
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: i64, yi: i64| {
            let (xi, yi) = (xi.clamp(0, sw - 1) as usize, yi.clamp(0, sh - 1) as usize);
            image.data[(yi * image.width as usize + xi) * channels + c] as f64
        };
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
        let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
        Some(top * (1.0 - fy) + bottom * fy)
    };
    for y in 0..height as usize {
        for x in 0..width as usize {
            let mut sums = [0.0f64; 4];
            for i in 0..per_side {
                for j in 0..per_side {
                    let u = x as f64 - 0.5 + (j as f64 + 0.5) / per_side as f64;
                    let v = y as f64 - 0.5 + (i as f64 + 0.5) / per_side as f64;
                    let [sx, sy] = lens.distort((u - target.cx) / target.fx, (v - target.cy) / target.fy);
                    if let Some(first) = sample(sx, sy, 0) {
                        sums[0] += first;
                        for (c, s) in sums.iter_mut().enumerate().take(channels).skip(1) {
                            *s += sample(sx, sy, c).unwrap_or(0.0);
                        }
                    }
                }
            }
            let all = per_side * per_side;
            for c in 0..channels {
                // Samples off the source count as black, so an image's edge fades rather than jumps.
                out.data[(y * width as usize + x) * channels + c] =
                    (sums[c] / all as f64).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
    out
}

/// The pinhole that sees what `lens` sees at a `scale`d size (pixel centres at integers): the same focal
/// lengths and principal point, scaled.
pub fn scaled_pinhole(lens: &Lens, scale: f64) -> Lens {
    Lens::pinhole(
        lens.fx * scale,
        lens.fy * scale,
        (lens.cx + 0.5) * scale - 0.5,
        (lens.cy + 0.5) * scale - 0.5,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_distortion_free_lens_at_the_same_size_changes_nothing() {
        let mut image = Image::new(20, 10, 1);
        for (i, v) in image.data.iter_mut().enumerate() {
            *v = (i * 7 % 251) as u8;
        }
        let lens = Lens::pinhole(30.0, 30.0, 9.5, 4.5);
        assert_eq!(undistort_image(&image, &lens, &lens, 20, 10), image);
    }

    #[test]
    fn straight_lines_come_out_straight() {
        // A vertical black line seen through barrel distortion is curved; undistorted it is one column again.
        let lens = Lens {
            fx: 200.0,
            fy: 200.0,
            cx: 99.5,
            cy: 74.5,
            distortion: [-0.3, 0.1, 0.0, 0.0, 0.0],
        };
        let (w, h) = (200u32, 150u32);
        let mut image = Image::new(w, h, 1);
        let line_x = 0.35; // normalised x of the line
        for y in 0..h {
            for x in 0..w {
                let [nx, _] = lens.undistort(x as f64, y as f64);
                image.data[(y * w + x) as usize] = if (nx - line_x).abs() < 0.01 { 0 } else { 255 };
            }
        }
        let target = Lens::pinhole(200.0, 200.0, 99.5, 74.5);
        let out = undistort_image(&image, &lens, &target, w, h);
        let column = (line_x * 200.0 + 99.5).round() as usize;
        for y in [20usize, 75, 130] {
            let row = &out.data[y * w as usize..(y + 1) * w as usize];
            let dark: Vec<usize> = (0..w as usize).filter(|&x| row[x] < 128).collect();
            let middle = dark.iter().sum::<usize>() as f64 / dark.len() as f64;
            assert!(
                (middle - column as f64).abs() <= 0.6,
                "row {y}: the line's middle at {middle}, it is at {column}"
            );
        }
    }
}
