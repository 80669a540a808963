//! Every integration test of the crate in one binary: one link instead of one per file, and the tests of
//! all the files share the cores (a file's last long test no longer leaves one idle).

mod angular_momentum;
mod common;
mod free_fall;
mod friction_slide;
mod gradients;
mod mass_properties;
mod momentum_conservation;
mod resting_contact;
mod restitution_bounce;
mod rolling_ball;
mod scene_planes;
mod sdf_grid;
mod sdf_mesh;
mod sdf_shapes;
mod slope_and_energy;
