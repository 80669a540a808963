//! Every integration test of the crate in one binary: one link instead of one per file, and the tests of
//! all the files share the cores (a file's last long test no longer leaves one idle).

mod brightness;
mod calibrate;
mod common;
mod fits;
mod import;
mod object_masks;
mod raw_session;
mod session;
mod video_masks;
