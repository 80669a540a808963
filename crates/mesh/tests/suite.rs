//! Every integration test of the crate in one binary: one link instead of one per file, and the tests of
//! all the files share the cores (a file's last long test no longer leaves one idle).

mod common;
mod decimate;
mod icp;
mod marching_tetrahedra;
mod merge;
mod mesh_metrics;
mod sample_sdf_grid;
mod zero_level_points;
