//! Corners to a fraction of a pixel: OpenCV's `cornerSubPix` (the point where the image gradients in a window
//! are all orthogonal to the lines to it), step for step.

use crate::gray::Gray;

/// When the iteration stops.
#[derive(Clone, Copy, Debug)]
pub struct SubpixSettings {
    /// Half the window's side, pixels (the window is `2 * half_window + 1` square).
    pub half_window: usize,
    /// At most this many steps.
    pub max_iterations: usize,
    /// Stop when a step moves the point less than this, pixels.
    pub min_step: f64,
}

/// `start` refined; `start` itself where the refinement leaves the window or the image (poor convergence).
pub fn corner_subpix(gray: &Gray, start: [f64; 2], s: &SubpixSettings) -> [f64; 2] {
    let w = s.half_window as i64;
    let side = (2 * w + 1) as usize;
    let weights: Vec<f64> = {
        let mut m = vec![0.0; side * side];
        for i in 0..side {
            let y = (i as f32 - w as f32) / w as f32;
            let vy = (-y * y).exp();
            for j in 0..side {
                let x = (j as f32 - w as f32) / w as f32;
                m[i * side + j] = (vy * (-x * x).exp()) as f64;
            }
        }
        m
    };
    let inside = |p: [f64; 2]| p[0] >= 0.0 && p[1] >= 0.0 && p[0] < gray.width as f64 && p[1] < gray.height as f64;
    let mut c = start;
    let patch_side = side + 2;
    let mut patch = vec![0.0f64; patch_side * patch_side];
    for _ in 0..s.max_iterations.clamp(1, 100) {
        for i in 0..patch_side {
            for j in 0..patch_side {
                let x = c[0] - (w + 1) as f64 + j as f64;
                let y = c[1] - (w + 1) as f64 + i as f64;
                patch[i * patch_side + j] = gray.bilinear(x, y) as f64;
            }
        }
        let (mut a, mut b, mut cc, mut bb1, mut bb2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for i in 0..side {
            let py = i as f64 - w as f64;
            for j in 0..side {
                let at = |di: usize, dj: usize| patch[(i + di) * patch_side + j + dj];
                let m = weights[i * side + j];
                let gx = at(1, 2) - at(1, 0);
                let gy = at(2, 1) - at(0, 1);
                let (gxx, gxy, gyy) = (gx * gx * m, gx * gy * m, gy * gy * m);
                let px = j as f64 - w as f64;
                a += gxx;
                b += gxy;
                cc += gyy;
                bb1 += gxx * px + gxy * py;
                bb2 += gxy * px + gyy * py;
            }
        }
        let det = a * cc - b * b;
        if det.abs() <= f64::EPSILON * f64::EPSILON {
            break;
        }
        let scale = 1.0 / det;
        let next = [
            c[0] + cc * scale * bb1 - b * scale * bb2,
            c[1] - b * scale * bb1 + a * scale * bb2,
        ];
        let step2 = (next[0] - c[0]).powi(2) + (next[1] - c[1]).powi(2);
        if !inside(next) {
            break;
        }
        c = next;
        if step2 <= s.min_step * s.min_step {
            break;
        }
    }
    if (c[0] - start[0]).abs() > w as f64 || (c[1] - start[1]).abs() > w as f64 {
        start
    } else {
        c
    }
}
