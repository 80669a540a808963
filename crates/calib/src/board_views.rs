//! Views of a board with their truth, for tests and benchmarks: a camera (any lens) looking at the printed
//! board on a grey table, each pixel the mean of a grid of samples over its area (the sensor integrates
//! light), with noise.

use crate::gray::{linear_to_srgb, Gray};
use crate::{Board, Lens};
use geom::{Quat, SplitMix64, Vec3};

/// A camera: its lens and the board-to-camera rotation and translation (board frame: OpenCV's, metres).
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub lens: Lens,
    pub rotation: Quat<f64>,
    pub translation: Vec3<f64>,
}

impl View {
    /// A camera at `distance` from the board's centre, looking at it along a direction tilted `tilt` radians
    /// from the board's normal toward azimuth `azimuth`, rolled by `roll` radians.
    pub fn looking_at(
        board: &Board,
        focal: f64,
        size: (usize, usize),
        distance: f64,
        tilt: f64,
        azimuth: f64,
        roll: f64,
    ) -> View {
        let centre = Vec3::new(board.extent[0] / 2.0, board.extent[1] / 2.0, 0.0);
        // The printed face looks along -z of OpenCV's board frame (z goes into the board).
        let dir = Vec3::new(tilt.sin() * azimuth.cos(), tilt.sin() * azimuth.sin(), -tilt.cos());
        let eye = centre + dir * distance;
        let forward = (centre - eye) * (1.0 / distance);
        let up_hint = Vec3::new(0.0, -1.0, 0.0);
        let right = forward.cross(up_hint);
        let right = right * (1.0 / right.norm());
        let down = forward.cross(right);
        // Camera axes: x right, y down, z forward; rows of the board-to-camera rotation.
        let (c, s) = (roll.cos(), roll.sin());
        let (r2, d2) = (right * c + down * s, down * c - right * s);
        let m = [
            [r2.x, r2.y, r2.z],
            [d2.x, d2.y, d2.z],
            [forward.x, forward.y, forward.z],
        ];
        let rotation = Quat::from_mat(&geom::Mat3 { m });
        let translation = -(rotation.rotate(eye));
        let lens = Lens::pinhole(focal, focal, (size.0 as f64 - 1.0) / 2.0, (size.1 as f64 - 1.0) / 2.0);
        View {
            lens,
            rotation,
            translation,
        }
    }

    /// The same view through another lens.
    pub fn with_lens(self, lens: Lens) -> View {
        View { lens, ..self }
    }

    /// Where a board point (metres, z = 0) is seen, pixels.
    pub fn project(&self, p: [f64; 2]) -> [f64; 2] {
        self.lens
            .project(self.rotation.rotate(Vec3::new(p[0], p[1], 0.0)) + self.translation)
    }

    /// The board point seen at pixel position `(u, v)` (the ray meets the plane z = 0).
    pub fn unproject(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        let [x, y] = self.lens.undistort(u, v);
        let d_cam = Vec3::new(x, y, 1.0);
        let inv = self.rotation.conj();
        let d = inv.rotate(d_cam);
        let o = inv.rotate(-self.translation);
        if d.z.abs() < 1e-12 {
            return None;
        }
        let s = -o.z / d.z;
        (s > 0.0).then_some([o.x + s * d.x, o.y + s * d.y])
    }
}

/// The board seen by `view`: white paper with black ink on a grey table, `samples`² samples per pixel
/// averaged in linear light and encoded as a camera does (sRGB), then Gaussian noise of `noise` (0–255).
pub fn render(board: &Board, view: &View, size: (usize, usize), samples: usize, noise: f64, seed: u64) -> Gray {
    let (w, h) = size;
    let mut rng = SplitMix64::new(seed);
    // Linear reflectances: paper, toner, a grey table.
    let (paper, ink, table) = (0.78, 0.02, 0.16);
    let margin = 0.02;
    let mut data = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut sum = 0.0;
            for i in 0..samples {
                for j in 0..samples {
                    let u = x as f64 - 0.5 + (j as f64 + 0.5) / samples as f64;
                    let v = y as f64 - 0.5 + (i as f64 + 0.5) / samples as f64;
                    sum += match view.unproject(u, v) {
                        Some(p)
                            if p[0] > -margin
                                && p[1] > -margin
                                && p[0] < board.extent[0] + margin
                                && p[1] < board.extent[1] + margin =>
                        {
                            if board.is_black(p) {
                                ink
                            } else {
                                paper
                            }
                        }
                        _ => table,
                    };
                }
            }
            let gauss = (-2.0 * rng.next_f64().max(1e-12).ln()).sqrt() * (std::f64::consts::TAU * rng.next_f64()).cos();
            let linear = sum / (samples * samples) as f64;
            data[y * w + x] = (255.0 * linear_to_srgb(linear) + noise * gauss).clamp(0.0, 255.0) as f32;
        }
    }
    Gray {
        width: w,
        height: h,
        data,
    }
}

impl Gray {
    /// The image rounded to 8 bits, one channel.
    pub fn to_image(&self) -> pganeus_io::Image {
        let mut out = pganeus_io::Image::new(self.width as u32, self.height as u32, 1);
        for (o, v) in out.data.iter_mut().zip(&self.data) {
            *o = v.round().clamp(0.0, 255.0) as u8;
        }
        out
    }
}
