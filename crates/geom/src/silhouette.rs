//! A mesh's silhouette in a camera: the pixel centres its projected triangles
//! cover. Cheap enough to score many candidate poses against a mask before any
//! field is rendered.

use crate::{Camera, Pose, TriMesh, Vec3};

/// Row-major `width × height` coverage of `mesh` (body frame) placed at `pose` (body → world). Triangles
/// with a corner behind the camera are left out.
pub fn silhouette(camera: &Camera<f64>, mesh: &TriMesh, pose: &Pose<f64>) -> Vec<bool> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut cover = vec![false; w * h];
    let uvz: Vec<(f64, f64, f64)> = mesh
        .vertices
        .iter()
        .map(|p| camera.project(pose.transform_point(Vec3::cst(*p))))
        .collect();
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| uvz[i as usize]);
        if !(a.2 > 0.0 && b.2 > 0.0 && c.2 > 0.0) {
            continue;
        }
        let (x0, x1) = (
            (a.0.min(b.0).min(c.0) - 0.5).ceil().max(0.0) as usize,
            ((a.0.max(b.0).max(c.0) - 0.5).floor() + 1.0).clamp(0.0, w as f64) as usize,
        );
        let (y0, y1) = (
            (a.1.min(b.1).min(c.1) - 0.5).ceil().max(0.0) as usize,
            ((a.1.max(b.1).max(c.1) - 0.5).floor() + 1.0).clamp(0.0, h as f64) as usize,
        );
        let edge = |p: (f64, f64, f64), q: (f64, f64, f64), r: (f64, f64)| {
            (q.0 - p.0) * (r.1 - p.1) - (q.1 - p.1) * (r.0 - p.0)
        };
        for y in y0..y1 {
            for x in x0..x1 {
                let p = (x as f64 + 0.5, y as f64 + 0.5);
                let (e0, e1, e2) = (edge(a, b, p), edge(b, c, p), edge(c, a, p));
                if (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0) {
                    cover[y * w + x] = true;
                }
            }
        }
    }
    cover
}

/// Intersection over union of two coverages of the same size (0 when both are empty).
pub fn coverage_iou(a: &[bool], b: &[bool]) -> f64 {
    let (mut i, mut u) = (0usize, 0usize);
    for (&x, &y) in a.iter().zip(b) {
        i += (x && y) as usize;
        u += (x || y) as usize;
    }
    if u == 0 {
        0.0
    } else {
        i as f64 / u as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Intrinsics, Quat};

    /// A square of side `s` in the plane z = 0, facing +z.
    fn square(s: f64) -> TriMesh {
        let h = 0.5 * s;
        TriMesh::new(
            vec![[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn a_square_facing_the_camera_covers_its_projected_area() {
        let k = Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 50.0,
            cy: 40.0,
            skew: 0.0,
        };
        // Looking down -z from 1 m: a 0.2 m square spans 20 × 20 pixels.
        let cam = Camera::look_at(
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            k,
            100,
            80,
        );
        let cover = silhouette(&cam, &square(0.2), &Pose::identity());
        assert_eq!(cover.iter().filter(|&&c| c).count(), 400);
        // Moved by half its width, it overlaps itself by a third.
        let moved = Pose::new(Quat::identity(), Vec3::new(0.1, 0.0, 0.0));
        let other = silhouette(&cam, &square(0.2), &moved);
        assert!((coverage_iou(&cover, &other) - 1.0 / 3.0).abs() < 1e-9);
        // Behind the camera it covers nothing.
        let behind = Pose::new(Quat::identity(), Vec3::new(0.0, 0.0, 2.0));
        assert!(!silhouette(&cam, &square(0.2), &behind).iter().any(|&c| c));
    }
}
