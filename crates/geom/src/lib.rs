//! Geometry shared by every stage: scalars (plain and dual), vectors,
//! quaternions, rigid poses (Eq. 5–7 of the paper), pinhole cameras and rays.
//!
//! Everything that a gradient must flow through is generic over [`Real`], so
//! the simulator runs the same code on `f64` and on [`Dual`] numbers.

pub mod camera;
pub mod dual;
pub mod eigen;
pub mod mask;
pub mod pose;
pub mod quat;
pub mod real;
pub mod rng;
pub mod silhouette;
pub mod similarity;
pub mod trimesh;
pub mod vec3;

pub use camera::{Camera, CameraError, Intrinsics, Ray};
pub use dual::Dual;
pub use eigen::{point_covariance, symmetric_eigen};
pub use pose::{left_jacobian, Pose};
pub use quat::{rotation_distance, Quat};
pub use real::Real;
pub use rng::SplitMix64;
pub use silhouette::{coverage_iou, silhouette};
pub use similarity::Similarity;
pub use trimesh::{bounding_box, TriMesh};
pub use vec3::{Mat3, Vec3};
