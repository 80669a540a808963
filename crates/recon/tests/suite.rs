//! Every integration test of the crate in one binary: one link instead of one per file, and the tests of
//! all the files share the cores (a file's last long test no longer leaves one idle).

mod colliding_bodies;
mod common;
mod fit_physics;
mod physics_from_video;
mod pose_from_image;
mod poses_from_video;
mod shutter;
mod sphere_toy;
mod target;
mod value_ranges;
