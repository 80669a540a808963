pub mod bench_compose;
pub mod bench_contact;
pub mod bench_sim;
pub mod bench_train;
pub mod fit;
pub mod fit_physics;
pub mod mesh_cmds;
pub mod render;
pub mod render_trajectory;
pub mod simulate;
pub mod synth;
pub mod target;
pub mod train;

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar on stderr (hidden when stderr is not a terminal).
pub fn progress(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} {elapsed_precise} eta {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// A run folder's checkpoint, or the checkpoint file itself.
pub(crate) fn checkpoint_of(run: &std::path::Path) -> std::path::PathBuf {
    if run.is_dir() {
        run.join("checkpoint.safetensors")
    } else {
        run.to_path_buf()
    }
}
