//! A reconstruction made elsewhere (COLMAP, nerfstudio, instant-ngp): each registered image's lens and pose
//! in the reconstruction's own world (arbitrary units and axes), and its sparse points if it has them.

use geom::{Pose, Similarity, Vec3};

use crate::lens::Lens;

/// One registered image.
#[derive(Clone, Debug, PartialEq)]
pub struct RegisteredImage {
    /// The image's path as the reconstruction names it (relative to its images folder).
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// OpenCV's convention (pixel centres at integers).
    pub lens: Lens,
    /// World to camera, OpenCV's camera axes (x right, y down, z forward).
    pub pose: Pose<f64>,
}

/// Registered images and sparse points.
#[derive(Clone, Debug, Default)]
pub struct Reconstruction {
    pub images: Vec<RegisteredImage>,
    /// Sparse points (world), empty when the source has none.
    pub points: Vec<Vec3<f64>>,
}

impl Reconstruction {
    /// The same reconstruction in another world: every camera and point moved by `s`.
    pub fn transformed(&self, s: &Similarity) -> Reconstruction {
        Reconstruction {
            images: self
                .images
                .iter()
                .map(|i| RegisteredImage {
                    pose: s.move_camera(&i.pose),
                    ..i.clone()
                })
                .collect(),
            points: self.points.iter().map(|p| s.apply(*p)).collect(),
        }
    }
}
