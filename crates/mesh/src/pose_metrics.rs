//! How far an estimated pose of a body is from its true pose, measured on the
//! body's surface as pose-estimation benchmarks do (Hinterstoisser et al.,
//! ACCV 2012): ADD, the mean distance between the surface points placed by
//! each pose, and ADD-S, each point placed by the estimate to the nearest
//! point placed by the truth (a symmetric body turned onto itself scores 0);
//! beside them the centre's distance and the rotation angle, as is and up to
//! the shape's own symmetries ([`crate::symmetry`]).

use crate::kdtree::KdTree;
use crate::symmetry::proper_symmetries;
use geom::{rotation_distance, Pose, TriMesh, Vec3};
use sim::sample_surface::sample_surface;

/// The errors of one estimated pose (lengths in the mesh's units, the angle in radians).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseErrors {
    /// Distance between the body origins.
    pub position: f64,
    /// Angle of the rotation taking one orientation to the other, in [0, π].
    pub rotation: f64,
    /// The same angle to the nearest orientation the shape cannot be told from (the truth turned by one of
    /// the shape's symmetries); `rotation` for a shape without any. A texture may tell them apart where the
    /// shape does not: both are reported. The symmetries are found from surface samples, to about 0.1°.
    pub rotation_up_to_symmetry: f64,
    /// ADD: mean distance of each surface point under the estimate to the same point under the truth.
    pub add: f64,
    /// ADD-S: mean distance of each surface point under the estimate to the nearest surface point under
    /// the truth.
    pub add_s: f64,
}

/// Points spread over a body's surface (body frame), with a search tree for ADD-S, and the shape's
/// symmetries.
pub struct SurfacePoints {
    points: Vec<Vec3<f64>>,
    tree: KdTree,
    symmetries: Vec<Pose<f64>>,
}

impl SurfacePoints {
    /// `count` points drawn uniformly by area (the same `seed`, the same points).
    pub fn new(mesh: &TriMesh, count: usize, seed: u64) -> Self {
        let points = if mesh.faces.is_empty() {
            mesh.vertices.iter().map(|v| Vec3::cst(*v)).collect()
        } else {
            sample_surface(mesh, count.max(1), seed)
        };
        let tree = KdTree::new(&points);
        let symmetries = proper_symmetries(mesh, count, seed);
        Self {
            points,
            tree,
            symmetries,
        }
    }

    /// How many proper symmetries the shape has (the identity counts: 1 for a shape without any).
    pub fn symmetries(&self) -> usize {
        self.symmetries.len()
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The errors of `estimate` against `truth` (both body → world).
    pub fn errors(&self, estimate: &Pose<f64>, truth: &Pose<f64>) -> PoseErrors {
        let n = self.points.len().max(1) as f64;
        let (mut add, mut add_s) = (0.0, 0.0);
        for p in &self.points {
            let x = estimate.transform_point(*p);
            add += (x - truth.transform_point(*p)).norm();
            // The nearest truth-placed point: search in the body frame the truth places.
            let back = truth.inverse_transform_point(x);
            add_s += self.tree.nearest(back).map_or(0.0, |(_, d2)| d2.sqrt());
        }
        PoseErrors {
            position: (estimate.t - truth.t).norm(),
            rotation: rotation_distance(estimate.q, truth.q),
            rotation_up_to_symmetry: self
                .symmetries
                .iter()
                .map(|s| rotation_distance(estimate.q, truth.q * s.q))
                .fold(f64::INFINITY, f64::min),
            add: add / n,
            add_s: add_s / n,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geom::Quat;

    fn cube(h: f64) -> TriMesh {
        let v: Vec<[f64; 3]> = (0..8)
            .map(|i| {
                [
                    if i & 1 == 0 { -h } else { h },
                    if i & 2 == 0 { -h } else { h },
                    if i & 4 == 0 { -h } else { h },
                ]
            })
            .collect();
        // Two triangles per face (orientation does not matter for sampling).
        let quads: [[u32; 4]; 6] = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let faces = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        TriMesh { vertices: v, faces }
    }

    #[test]
    fn a_shift_scores_its_length_and_a_symmetry_scores_zero_in_add_s() {
        let pts = SurfacePoints::new(&cube(0.02), 2000, 1);
        let truth = Pose::new(Quat::exp(Vec3::new(0.2, -0.1, 0.4)), Vec3::new(0.1, 0.0, 0.03));
        let same = pts.errors(&truth, &truth);
        // ADD-S goes through the inverse pose: exact up to rounding.
        assert!(
            same.position == 0.0 && same.rotation == 0.0 && same.add == 0.0 && same.add_s < 1e-15,
            "{same:?}"
        );
        let shifted = Pose::new(truth.q, truth.t + Vec3::new(0.0, 0.003, 0.004));
        let e = pts.errors(&shifted, &truth);
        assert!(
            (e.position - 0.005).abs() < 1e-12 && (e.add - 0.005).abs() < 1e-12,
            "{e:?}"
        );
        assert!(e.add_s < e.add && e.rotation == 0.0, "{e:?}");
        // A quarter turn about a cube's axis: the same surface, far in ADD, near 0 in ADD-S (within the 2 mm spacing of the samples).
        let turned = Pose::new(
            truth.q * Quat::exp(Vec3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2)),
            truth.t,
        );
        let e = pts.errors(&turned, &truth);
        assert!((e.rotation - std::f64::consts::FRAC_PI_2).abs() < 1e-9, "{e:?}");
        assert!(e.add > 0.015 && e.add_s < 0.002, "{e:?}");
        // Up to the cube's symmetries the quarter turn is none (to the 0.1° the symmetries are found to from
        // samples), and a further small turn is itself.
        assert!(pts.symmetries() == 24 && e.rotation_up_to_symmetry < 3e-3, "{e:?}");
        let off = Pose::new(turned.q * Quat::exp(Vec3::new(0.05, 0.0, 0.0)), truth.t);
        let e = pts.errors(&off, &truth);
        assert!((e.rotation_up_to_symmetry - 0.05).abs() < 3e-3, "{e:?}");
    }
}
