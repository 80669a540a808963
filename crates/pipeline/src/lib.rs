//! The PGA-NeuS method as a library: every stage a user runs, with its run folder, its resume and its
//! progress, and nothing of a terminal. The `pganeus` binary is one front end over it (it parses arguments
//! and draws [`Event`]s as progress bars); a binding or a workflow is another.
//!
//! | stage | module | the paper |
//! | --- | --- | --- |
//! | a printable calibration board | [`board`] | — |
//! | cameras, lens and NeuS captures from photos and videos of the board | [`calibrate`] | — |
//! | NeuS captures from COLMAP models and `transforms.json`, in the board's metric world | [`import`] | — |
//! | synthetic datasets with their truth | [`synth`] | — |
//! | NeuS training of objects and scenes | [`train`] | Sec. 3.2, Eq. 1–2 |
//! | views, depth and normals of a field; objects moving in their scene | [`render`], [`render_trajectory`] | Eq. 3–7 |
//! | meshes, SDF grids for the simulator, the two-pose merge | [`surfaces`] | Sec. 3.2, Fig. 2b |
//! | a body's motion and physics from a video: first pose, PA, GA, PGA; several bodies | [`fit`] | Sec. 3.3–3.4, Eq. 7–11 |
//! | a fit scored against a truth | [`eval`] | — |
//! | one HTML page for a run | [`report_page`] | — |
//! | the whole method on a synthetic scene | [`demo`] | — |
//! | an imported synthetic session against its truth: cameras and computed masks | [`session_truth`] | — |
//!
//! The method's decisions that need no files (which pose a frame reports, which start of a multi-start is
//! kept) live in `recon`; this crate reads and writes the run folders around them. Errors are [`Error`]s
//! that name the file or the setting; progress goes to an [`Observer`].

pub mod allocator;
pub mod board;
pub mod calibrate;
pub mod cameras;
mod capture_writer;
pub mod demo;
mod error;
pub mod eval;
pub mod fit;
pub mod images;
pub mod import;
pub mod import_session;
pub mod object_masks;
mod objects;
mod observer;
pub mod off_surface;
pub mod render;
pub mod render_trajectory;
pub mod report_page;
pub mod run_folder;
pub mod run_session;
pub mod session_truth;
pub mod surfaces;
pub mod synth;
pub mod train;
pub mod video_masks;

pub use error::{Context, Error, Result};
pub use objects::{load_objects, parse_objects};
pub use observer::{Event, Observer, Quiet, Task};

/// What to do with a run folder that already holds a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resume {
    /// Go on with the same run (the same inputs and settings; anything else is refused).
    Continue,
    /// Start over: the run's earlier results are removed first.
    StartOver,
}

/// Says `text` to the user through `observer` (a line the CLI prints on standard output).
pub(crate) fn note(observer: &dyn Observer, text: impl AsRef<str>) {
    observer.event(Event::Note(text.as_ref()));
}
