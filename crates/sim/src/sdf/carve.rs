//! A body's volume cut out of a scene's grid: where a video saw the body, the
//! scene is not. A reconstructed scene is wrong most where bodies touch it:
//! NeuS rounds the concave corners it sees at grazing angles (the foot of a
//! wall on the board, into a fillet 10–15 mm wide), and a body that slides
//! into the corner meets the fillet, which kicks it up and turns it. The poses
//! the images gave the body there say the fillet is free space.

use super::{Sdf, SdfGrid, Shape};
use geom::{Pose, Vec3};

impl SdfGrid {
    /// This grid with `body` (its signed distance in its own frame, within `radius` of its origin) cut out
    /// at each of `poses`: at every node inside the body deeper than `margin(pose index, the scene's unit
    /// normal at the node)`, the value is raised to that depth less the margin (the union of the free space
    /// with the body shrunk by the margin: a pose known to within the margin cuts nothing where it merely
    /// grazes the scene). The nodes raised, counted once per pose.
    pub fn carved(
        &self,
        body: &Shape,
        radius: f64,
        poses: &[Pose<f64>],
        margin: impl Fn(usize, Vec3<f64>) -> f64,
    ) -> (SdfGrid, usize) {
        let mut values = self.values().to_vec();
        let (origin, h, dims) = (self.origin(), self.spacing(), self.dims());
        let [nx, ny, _] = dims;
        let mut raised = 0;
        for (index, pose) in poses.iter().enumerate() {
            // The nodes of the box around the body's bounding sphere.
            let range = |a: usize| {
                let c = pose.t.to_array()[a];
                let lo = ((c - radius - origin[a]) / h).floor().max(0.0) as usize;
                let hi = ((c + radius - origin[a]) / h).ceil().max(0.0) as usize;
                lo..(hi + 1).min(dims[a])
            };
            for k in range(2) {
                for j in range(1) {
                    for i in range(0) {
                        let p = Vec3::new(
                            origin[0] + i as f64 * h,
                            origin[1] + j as f64 * h,
                            origin[2] + k as f64 * h,
                        );
                        let inside = body.distance(pose, p);
                        if inside >= 0.0 {
                            continue;
                        }
                        let (_, normal) = self.distance_grad_local(p);
                        let cut = -(inside + margin(index, normal.normalize_or(Vec3::new(0.0, 0.0, 1.0))));
                        let v = &mut values[i + nx * (j + ny * k)];
                        if cut > f64::from(*v) {
                            *v = cut as f32;
                            raised += 1;
                        }
                    }
                }
            }
        }
        let grid = SdfGrid::from_values(origin, h, dims, values).expect("the same grid's dimensions");
        (grid, raised)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sdf::{Cuboid, Plane};

    /// A board (z = 0) and a wall (x = 0.1) meeting in a fillet of radius 15 mm, as a reconstruction rounds
    /// the corner, baked at 2 mm.
    fn filleted_corner() -> SdfGrid {
        struct Fillet;
        impl Sdf for Fillet {
            fn distance_grad_local<S: geom::Real>(&self, p: Vec3<S>) -> (S, Vec3<S>) {
                // The free space is x < 0.1, z > 0, less the corner outside the circle about (0.085, 0.015).
                let (x, z) = (p.x, p.z);
                let r = 0.015;
                if x.re() > 0.085 && z.re() < 0.015 {
                    let (dx, dz) = (x - 0.085, z - 0.015);
                    let d = (dx * dx + dz * dz).sqrt();
                    let g = Vec3::new(-dx / d, S::zero(), -dz / d);
                    return (-d + r, g);
                }
                let (board, wall) = (z, -(x - 0.1));
                if board.re() < wall.re() {
                    (board, Vec3::new(S::zero(), S::zero(), S::one()))
                } else {
                    (wall, Vec3::new(-S::one(), S::zero(), S::zero()))
                }
            }
        }
        SdfGrid::bake(&Fillet, [-0.05, -0.05, -0.03], [0.13, 0.05, 0.08], 0.002).expect("a grid")
    }

    #[test]
    fn a_body_seen_in_a_rounded_corner_cuts_the_fillet_away_and_nothing_else() {
        let grid = filleted_corner();
        let block = Shape::Cuboid(Cuboid {
            half: [0.02, 0.02, 0.02],
        });
        // The block pressed into the corner (its faces on the board and on the wall), and one on the
        // board well away from it.
        let poses = [
            Pose::from_translation(Vec3::new(0.08, 0.0, 0.02)),
            Pose::from_translation(Vec3::new(0.0, 0.0, 0.02)),
        ];
        let margin = 0.0005;
        let (carved, raised) = grid.carved(&block, 0.035, &poses, |_, _| margin);
        assert!(raised > 0);
        let at = |g: &SdfGrid, x: f64, z: f64| g.distance_local(Vec3::new(x, 0.0, z));
        // In the fillet, inside the block's corner (a node 2 mm inside both faces): 3.4 mm deep in the
        // scene before, free after, by the block's depth there less the margin.
        assert!(at(&grid, 0.098, 0.002) < -0.003, "{}", at(&grid, 0.098, 0.002));
        assert!(
            (at(&carved, 0.098, 0.002) - 0.0015).abs() < 1e-6,
            "{}",
            at(&carved, 0.098, 0.002)
        );
        // The board and the wall away from the block, and beneath a block that merely rests on the
        // board, are as they were.
        for (x, z) in [(0.0, -0.004), (-0.03, 0.0), (0.104, 0.05), (0.02, -0.01), (0.05, 0.03)] {
            assert_eq!(at(&carved, x, z), at(&grid, x, z), "({x}, {z})");
        }
        // The board under the block in the corner: a block sunk 0.3 mm (within its margin) cuts nothing.
        let sunk = [Pose::from_translation(Vec3::new(0.0, 0.0, 0.0197))];
        let (_, raised) = grid.carved(&block, 0.035, &sunk, |_, _| margin);
        assert_eq!(raised, 0);
        // Against a plane the grid is exact.
        let plane = Shape::Plane(Plane {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
        });
        let flat = SdfGrid::bake(&plane, [-0.05, -0.05, -0.03], [0.05, 0.05, 0.05], 0.002).expect("a grid");
        let (_, raised) = flat.carved(&block, 0.035, &sunk, |_, _| margin);
        assert_eq!(raised, 0);
    }
}
