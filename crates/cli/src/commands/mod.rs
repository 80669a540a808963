pub mod bench_compose;
pub mod bench_contact;
pub mod bench_sim;
pub mod bench_train;
pub mod fit_physics;
pub mod simulate;
pub mod target;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use pipeline::{Event, Observer};
use std::collections::HashMap;
use std::sync::Mutex;

fn style() -> ProgressStyle {
    ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} {elapsed_precise} eta {eta}")
        .expect("valid template")
        .progress_chars("=> ")
}

/// A progress bar on stderr (hidden when stderr is not a terminal).
pub fn progress(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(style());
    pb.set_message(what.to_string());
    pb
}

/// The library's events on a terminal: each task a progress bar on stderr (hidden when stderr is not a
/// terminal), each note a line on stdout (printed above the bars).
#[derive(Default)]
pub struct Bars {
    multi: MultiProgress,
    bars: Mutex<HashMap<u64, (ProgressBar, String)>>,
}

impl Observer for Bars {
    fn event(&self, event: Event<'_>) {
        let mut bars = self.bars.lock().expect("no panic while holding the bars");
        match event {
            Event::Started { task, what, steps } => {
                let pb = self.multi.add(progress(steps, what));
                bars.insert(task, (pb, what.to_string()));
            }
            Event::Progress { task, done, steps } => {
                if let Some((pb, _)) = bars.get(&task) {
                    pb.set_length(steps);
                    pb.set_position(done);
                }
            }
            Event::Status { task, text } => {
                if let Some((pb, what)) = bars.get(&task) {
                    pb.set_message(format!("{what}: {text}"));
                }
            }
            Event::Finished { task } => {
                if let Some((pb, _)) = bars.remove(&task) {
                    pb.finish_and_clear();
                    self.multi.remove(&pb);
                }
            }
            Event::Note(text) => {
                if bars.is_empty() {
                    println!("{text}");
                } else {
                    self.multi.suspend(|| println!("{text}"));
                }
            }
        }
    }
}
