//! A camera's lens: pinhole intrinsics and OpenCV's distortion (k1, k2, p1, p2, k3), projecting camera-frame
//! points to pixels (pixel centres at integers) and back.

use geom::{Real, Vec3};
use serde::{Deserialize, Serialize};

/// Focal lengths and principal point (pixels) and OpenCV's distortion coefficients `[k1, k2, p1, p2, k3]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Lens {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// `[k1, k2, p1, p2, k3]`, OpenCV's order.
    pub distortion: [f64; 5],
}

/// The lens as nine numbers in a fixed order: fx, fy, cx, cy, k1, k2, p1, p2, k3.
pub const LENS_PARAMETERS: usize = 9;

impl Lens {
    /// A lens without distortion.
    pub fn pinhole(fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        Lens {
            fx,
            fy,
            cx,
            cy,
            distortion: [0.0; 5],
        }
    }

    /// The nine numbers (see [`LENS_PARAMETERS`]).
    pub fn to_array(&self) -> [f64; LENS_PARAMETERS] {
        let d = self.distortion;
        [self.fx, self.fy, self.cx, self.cy, d[0], d[1], d[2], d[3], d[4]]
    }

    /// The lens of nine numbers.
    pub fn from_array(a: [f64; LENS_PARAMETERS]) -> Self {
        Lens {
            fx: a[0],
            fy: a[1],
            cx: a[2],
            cy: a[3],
            distortion: [a[4], a[5], a[6], a[7], a[8]],
        }
    }

    /// The pixel a camera-frame point is seen at (OpenCV's `projectPoints`).
    pub fn project(&self, p: Vec3<f64>) -> [f64; 2] {
        project_with(&self.to_array(), p)
    }

    /// Where the normalised (undistorted) image point `(x, y)` lands on the sensor, pixels.
    pub fn distort(&self, x: f64, y: f64) -> [f64; 2] {
        project_with(&self.to_array(), Vec3::new(x, y, 1.0))
    }

    /// The normalised image point `(x, y)` (on the plane z = 1) seen at pixel `(u, v)`: the distortion
    /// inverted by Newton's method.
    pub fn undistort(&self, u: f64, v: f64) -> [f64; 2] {
        let target = [(u - self.cx) / self.fx, (v - self.cy) / self.fy];
        let [k1, k2, p1, p2, k3] = self.distortion;
        let mut p = target;
        for _ in 0..20 {
            let (x, y) = (p[0], p[1]);
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            let dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2); // d radial / d r2
            let fx = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - target[0];
            let fy = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - target[1];
            let a = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x;
            let b = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
            let c = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
            let d = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x;
            let det = a * d - b * c;
            if det.abs() < 1e-12 {
                break;
            }
            let (dx, dy) = ((d * fx - b * fy) / det, (a * fy - c * fx) / det);
            p = [x - dx, y - dy];
            if dx.abs() + dy.abs() < 1e-14 {
                break;
            }
        }
        p
    }
}

/// OpenCV's projection of a camera-frame point with the lens `a` (nine numbers), in any scalar: the pixel.
pub fn project_with<S: Real>(a: &[S; LENS_PARAMETERS], p: Vec3<S>) -> [S; 2] {
    let (x, y) = (p.x / p.z, p.y / p.z);
    let [fx, fy, cx, cy, k1, k2, p1, p2, k3] = *a;
    let r2 = x * x + y * y;
    let radial = S::one() + r2 * (k1 + r2 * (k2 + r2 * k3));
    let xd = x * radial + p1 * x * y * 2.0 + p2 * (r2 + x * x * 2.0);
    let yd = y * radial + p1 * (r2 + y * y * 2.0) + p2 * x * y * 2.0;
    [fx * xd + cx, fy * yd + cy]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undistort_inverts_distort() {
        let lens = Lens {
            fx: 800.0,
            fy: 805.0,
            cx: 480.0,
            cy: 355.0,
            distortion: [-0.28, 0.11, 0.001, -0.0007, -0.02],
        };
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.55, 0.4), (0.6, 0.45)] {
            let [u, v] = lens.distort(x, y);
            let back = lens.undistort(u, v);
            assert!(
                (back[0] - x).abs() < 1e-10 && (back[1] - y).abs() < 1e-10,
                "{x} {y} -> {back:?}"
            );
        }
    }
}
