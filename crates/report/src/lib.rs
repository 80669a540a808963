//! The report stage: what a run looks like to a reader. [`chart`] draws line charts as SVG (inlined in the
//! page) and PNG (for papers and READMEs); [`raster`] shades meshes for turntable strips and views from
//! cameras the capture never had; [`page`] assembles one HTML file with every picture embedded, so it opens
//! anywhere without a network or the run's folder; [`run_page`] draws a run's records (trajectories,
//! evaluations, logs) into its tables and charts.

pub mod chart;
pub mod page;
pub mod raster;
pub mod run_page;

pub use chart::{Chart, Mark, Series};
pub use page::Page;
pub use raster::{face_towards, turntable, Paint, Raster};
