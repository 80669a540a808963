//! Every integration test of the crate in one binary: one link instead of one per file, and the tests of
//! all the files share the cores (a file's last long test no longer leaves one idle).

mod bad_inputs;
mod bake_npz;
mod captures;
mod cli;
mod common;
mod determinism;
mod eval;
mod import_cycles;
mod kill_resume;
mod report;
