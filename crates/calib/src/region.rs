//! The region a capture's cameras look at, which becomes its `scale_mat` (the field's unit sphere).
//!
//! The rule: the centre is the point nearest every camera's optical axis (least squares), not below the
//! board; the radius is what the cameras frame there, the median over cameras of their distance to the
//! centre times the tangent of half their narrower field of view.

use geom::Vec3;

/// A camera for the rule: where it is, where it looks (unit), and the tangent of half its narrower field
/// of view.
#[derive(Clone, Copy, Debug)]
pub struct Looking {
    pub centre: Vec3<f64>,
    pub forward: Vec3<f64>,
    pub half_fov_tan: f64,
}

impl Looking {
    /// The camera of a world-to-camera pose (OpenCV's axes: it looks along its +z).
    pub fn from_pose(world_to_cam: &geom::Pose<f64>, half_fov_tan: f64) -> Looking {
        let c2w = world_to_cam.inverse();
        Looking {
            centre: c2w.t,
            forward: c2w.transform_vector(Vec3::new(0.0, 0.0, 1.0)),
            half_fov_tan,
        }
    }
}

/// The point nearest a set of lines (each an origin and a unit direction) in least squares,
/// `Σ (I − d dᵀ) p = Σ (I − d dᵀ) c`, with that system's matrix; `None` when it is singular.
pub fn nearest_point_to_lines(lines: &[(Vec3<f64>, Vec3<f64>)]) -> Option<(Vec3<f64>, [[f64; 3]; 3])> {
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    for (c, d) in lines {
        let (c, d) = (c.to_array(), d.to_array());
        for i in 0..3 {
            for j in 0..3 {
                let m = if i == j { 1.0 } else { 0.0 } - d[i] * d[j];
                a[i][j] += m;
                b[i] += m * c[j];
            }
        }
    }
    let inv = crate::homography::invert3(&a)?;
    let p = Vec3::new(
        (0..3).map(|j| inv[0][j] * b[j]).sum(),
        (0..3).map(|j| inv[1][j] * b[j]).sum(),
        (0..3).map(|j| inv[2][j] * b[j]).sum(),
    );
    Some((p, a))
}

/// The ball (centre, radius) the cameras look at; `None` when the axes are parallel (one camera, or a
/// video) and none meets the board: then the region must be given.
pub fn looked_at_region(cameras: &[Looking]) -> Option<(Vec3<f64>, f64)> {
    if cameras.is_empty() {
        return None;
    }
    let axes: Vec<(Vec3<f64>, Vec3<f64>)> = cameras.iter().map(|c| (c.centre, c.forward)).collect();
    let centre = match nearest_point_to_lines(&axes) {
        Some((p, a)) if cameras.len() > 1 && condition_ok(&a) => p,
        _ => {
            // One camera (or parallel axes): where the mean axis meets the board.
            let n = cameras.len() as f64;
            let c = cameras.iter().fold(Vec3::zero(), |s, k| s + k.centre) * (1.0 / n);
            let d = cameras.iter().fold(Vec3::zero(), |s, k| s + k.forward) * (1.0 / n);
            if d.z >= -1e-6 {
                return None;
            }
            c + d * (-c.z / d.z)
        }
    };
    let centre = Vec3::new(centre.x, centre.y, centre.z.max(0.0));
    let mut radii: Vec<f64> = cameras
        .iter()
        .map(|k| (k.centre - centre).norm() * k.half_fov_tan)
        .collect();
    radii.sort_by(f64::total_cmp);
    Some((centre, radii[radii.len() / 2]))
}

/// Whether the axes constrain the point in every direction (not all parallel).
fn condition_ok(a: &[[f64; 3]; 3]) -> bool {
    let (values, _) = geom::symmetric_eigen(*a);
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    lo > 1e-3 * hi
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cameras_around_a_point_look_at_it() {
        let target = Vec3::new(0.05, -0.02, 0.03);
        let cams: Vec<Looking> = (0..8)
            .map(|k| {
                let a = k as f64 * 0.8;
                let centre = target + Vec3::new(a.cos() * 0.4, a.sin() * 0.4, 0.3);
                Looking {
                    centre,
                    forward: (target - centre) * (1.0 / (target - centre).norm()),
                    half_fov_tan: 0.4,
                }
            })
            .collect();
        let (c, r) = looked_at_region(&cams).unwrap();
        assert!((c - target).norm() < 1e-9);
        assert!((r - 0.5 * 0.4).abs() < 1e-9);
        let one = looked_at_region(&cams[..1]).unwrap();
        assert!(one.0.z.abs() < 1e-12, "one camera: where its axis meets the board");
    }
}
