//! A computed mask's edge to the pixel: a pixel the body covers in part shows a blend of the body's colour
//! and the background's, and stands out from the background well before the body covers half of it. A
//! mask thresholded on the difference is then a ring of such pixels too large (1–2 % of a body's area at
//! a video's size, and a silhouette 1 % too large puts a body in flight 1 % too close to the camera). Each
//! pixel on the mask's border is re-decided by where its colour lies between the background's and the
//! body's nearby interior (the blend's weight is the part it covers, as a camera integrates light): in
//! where it is more body than background.

/// Body colours and background colours nearer than this (summed colour distance) cannot say how much of a
/// pixel the body covers: such a pixel keeps its verdict.
const LEAST_CONTRAST: f32 = 0.1;

/// How far from the blend's line (a fraction of the body–background contrast) a pixel's colour may be and
/// still be read as a blend.
const OFF_LINE: f32 = 0.35;

/// `mask` with each pixel on its border (either side) re-decided: inside where the pixel's colour `image`
/// is at least half of the way from `background` (per pixel, `None` where unknown) to the mean colour of the
/// mask's interior pixels within two pixels of it.
pub fn refine_edges(mask: &[bool], image: &[[f32; 3]], background: &[Option<[f32; 3]>], width: usize) -> Vec<bool> {
    let height = mask.len() / width.max(1);
    let at = |x: i64, y: i64| -> Option<usize> {
        (x >= 0 && y >= 0 && (x as usize) < width && (y as usize) < height).then(|| y as usize * width + x as usize)
    };
    let inside = |x: i64, y: i64| at(x, y).is_some_and(|p| mask[p]);
    // Interior: in the mask with all four neighbours in it.
    let interior =
        |x: i64, y: i64| inside(x, y) && inside(x - 1, y) && inside(x + 1, y) && inside(x, y - 1) && inside(x, y + 1);
    let mut out = mask.to_vec();
    for p in 0..mask.len() {
        let (x, y) = ((p % width) as i64, (p / width) as i64);
        let border = [(1, 0), (-1, 0), (0, 1), (0, -1)]
            .iter()
            .any(|&(dx, dy)| at(x + dx, y + dy).is_some_and(|q| mask[q] != mask[p]));
        let Some(b) = background[p] else { continue };
        if !border {
            continue;
        }
        let mut sum = [0.0f32; 3];
        let mut n = 0usize;
        for dy in -2..=2 {
            for dx in -2..=2 {
                if interior(x + dx, y + dy) {
                    let c = image[at(x + dx, y + dy).expect("interior is inside")];
                    (0..3).for_each(|i| sum[i] += c[i]);
                    n += 1;
                }
            }
        }
        if n == 0 {
            continue;
        }
        let body = sum.map(|v| v / n as f32);
        let axis: [f32; 3] = std::array::from_fn(|i| body[i] - b[i]);
        let contrast = axis.iter().map(|v| v * v).sum::<f32>();
        if contrast < LEAST_CONTRAST * LEAST_CONTRAST {
            continue;
        }
        let c = image[p];
        let covered = (0..3).map(|i| (c[i] - b[i]) * axis[i]).sum::<f32>() / contrast;
        // A colour off the line between the two (the body's texture changes at its edge, its rounded
        // edge is shaded) says nothing about the part covered.
        let off_line = (0..3).map(|i| (c[i] - b[i] - covered * axis[i]).powi(2)).sum::<f32>();
        if off_line > OFF_LINE * OFF_LINE * contrast {
            continue;
        }
        out[p] = covered >= 0.5;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_disc_drawn_with_partial_pixels_is_masked_by_pixel_centres() {
        // A disc of radius 9.3 px, each pixel's colour the blend by the part of it the disc covers (4 × 4
        // samples); the first mask takes every pixel the disc touches (a ring too large).
        let (w, h) = (32usize, 32usize);
        let (cx, cy, r) = (15.7f64, 16.2f64, 9.3f64);
        let (body, board) = ([0.8f32, 0.3, 0.2], [0.3f32, 0.35, 0.4]);
        let mut image = Vec::new();
        let (mut touched, mut truth) = (Vec::new(), Vec::new());
        for p in 0..w * h {
            let (x, y) = ((p % w) as f64, (p / w) as f64);
            let mut cover = 0.0;
            for i in 0..4 {
                for j in 0..4 {
                    let (sx, sy) = (x + (i as f64 + 0.5) / 4.0, y + (j as f64 + 0.5) / 4.0);
                    cover += f64::from(((sx - cx).powi(2) + (sy - cy).powi(2)).sqrt() < r) / 16.0;
                }
            }
            let a = cover as f32;
            image.push(std::array::from_fn(|k| a * body[k] + (1.0 - a) * board[k]));
            touched.push(cover > 0.0);
            truth.push(((x + 0.5 - cx).powi(2) + (y + 0.5 - cy).powi(2)).sqrt() < r);
        }
        let background = vec![Some(board); w * h];
        let refined = refine_edges(&touched, &image, &background, w);
        let before = geom::coverage_iou(&touched, &truth);
        let after = geom::coverage_iou(&refined, &truth);
        assert!(before < 0.92, "{before}");
        assert!(after > 0.97, "IoU {before:.3} -> {after:.3}");
    }
}
