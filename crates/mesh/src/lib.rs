//! Meshes from fields (stage 2 of DESIGN.md, "mesh"): the zero level of a
//! signed distance field sampled on a grid, distances between meshes, and
//! the two-pose object of Sec. 3.2 (ICP, visibility, the fused SDF).
//!
//! NeuS (and PGA-NeuS, Sec. 3.2) take the reconstructed surface to be the
//! zero level `{x : f(x) = 0}` of the learned SDF `f` and extract it with
//! marching cubes; this crate does it with marching tetrahedra
//! ([`extract_zero_level`]), which needs no ambiguity table and gives a
//! closed, consistently oriented mesh wherever the zero level stays inside
//! the grid. [`sample_sdf_grid`] evaluates a (batched, possibly neural) field
//! on the grid; [`chamfer`] measures a mesh against another; [`decimate`]
//! simplifies a mesh by quadric edge collapses; [`zero_level_points`] puts
//! points on a field's zero level with its normals; [`merge_two_poses`]
//! aligns two partial reconstructions by ICP and fuses them (Fig. 2b).

mod collapse_coincident;
mod components;
mod decimate;
pub mod icp;
pub mod kdtree;
mod marching_tetrahedra;
pub mod merge;
mod mesh_metrics;
pub mod pose_metrics;
mod sample_sdf_grid;
pub mod symmetry;
pub mod visibility;
mod zero_level_points;

pub use components::{components, faces_where, largest_component, sub_mesh};
pub use decimate::decimate;
pub use icp::{icp, icp_auto, icp_evaluate, icp_hypotheses, inlier_fraction, IcpConfig, IcpResult, IcpTarget};
pub use marching_tetrahedra::{extract_zero_level, GridError, ScalarGrid};
pub use merge::{
    merge_two_poses, merge_two_poses_reporting, MergeConfig, MergeError, MergeStage, Merged, PartialSurface,
};
pub use mesh_metrics::{chamfer, normal_consistency, volume_iou, ChamferStats};
pub use pose_metrics::{PoseErrors, SurfacePoints};
pub use sample_sdf_grid::sample_sdf_grid;
pub use symmetry::proper_symmetries;
pub use zero_level_points::{values_and_gradients, zero_level_points, BatchSdf};
