//! How precisely one image of a fixed camera places a body: across its line of
//! sight to about an edge's precision, along it `z / d` times worse (a body of
//! apparent size `d f / z` pixels changes size by one edge precision over
//! `z / d` of that edge). GA's contact penalty leaves what the image can tell
//! to the image ([`crate::contact_penalty`]), and a pose that the simulation
//! misses is reported at a depth weighed by it ([`crate::video_fit::depth_share`]).

use geom::{Camera, Pose, Vec3};

/// How precisely a silhouette's edge is placed, in pixels: the image's and the reconstruction's surface
/// together (a quarter pixel; the tabletop toy's fitted poses land within 0.05–0.2 px across the line of
/// sight, and their depth within `z / d` times a quarter pixel or better at both of its scales).
pub const EDGE_PRECISION_PX: f64 = 0.25;

/// One image's precision on a body's position (one standard deviation, m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImagePrecision {
    /// The unit line of sight from the camera to the body.
    pub sight: Vec3<f64>,
    /// Across the line of sight.
    pub across: f64,
    /// Along it.
    pub along: f64,
}

impl ImagePrecision {
    /// At distance `z` from the camera, for a body of `diameter` seen with a focal length of `focal_px`
    /// pixels along the unit `sight`.
    pub fn at_distance(sight: Vec3<f64>, z: f64, diameter: f64, focal_px: f64) -> Self {
        let across = EDGE_PRECISION_PX * z / focal_px;
        Self {
            sight,
            across,
            along: z / diameter.max(1e-9) * across,
        }
    }

    /// A body of `diameter` at `pose` seen by `camera`.
    pub fn of(camera: &Camera<f64>, pose: &Pose<f64>, diameter: f64) -> Self {
        let offset = pose.t - camera.center();
        let z = offset.norm();
        let sight = offset.normalize_or(Vec3::new(0.0, 0.0, -1.0));
        Self::at_distance(sight, z, diameter, camera.k.fx)
    }

    /// The precision along the direction `n` (normalised here): the ellipsoid's extent along it.
    pub fn along_direction(&self, n: Vec3<f64>) -> f64 {
        let len = n.norm();
        if !(len > 0.0) {
            return self.across;
        }
        let c = self.sight.dot(n) / len;
        let c2 = (c * c).min(1.0);
        (self.along * self.along * c2 + self.across * self.across * (1.0 - c2)).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_image_tells_depth_worse_than_across_and_in_between_obliquely() {
        // 0.4 m off, 50 mm across, f = 290 px: an edge to 0.34 mm, the depth 8 times worse.
        let sight = Vec3::new(0.0, 0.0, 1.0);
        let p = ImagePrecision::at_distance(sight, 0.4, 0.05, 290.0);
        assert!((p.across - 0.25 * 0.4 / 290.0).abs() < 1e-12);
        assert!((p.along / p.across - 8.0).abs() < 1e-9);
        assert!((p.along_direction(Vec3::new(0.0, 0.0, -2.0)) - p.along).abs() < 1e-12);
        assert!((p.along_direction(Vec3::new(1.0, 0.0, 0.0)) - p.across).abs() < 1e-12);
        let oblique = p.along_direction(Vec3::new(1.0, 0.0, 1.0));
        assert!(oblique > p.across && oblique < p.along, "{oblique}");
        // Twice as far: an edge twice as coarse, the depth four times.
        let far = ImagePrecision::at_distance(sight, 0.8, 0.05, 290.0);
        assert!((far.along / p.along - 4.0).abs() < 1e-9);
    }
}
