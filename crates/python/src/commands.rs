//! The stages, called with a command line's words: parsed by the same `clap` definitions as the `pganeus`
//! command (so the defaults, the checks and the messages are the command's), run with the GIL released, their
//! progress forwarded to a Python callback.

use crate::errors;
use clap::Parser;
use pipeline::{calibrate, demo, eval, fit, report_page, surfaces, synth, train, video_masks, Event, Observer};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::Mutex;

/// The stages a caller can run, under the command's names.
#[derive(Parser)]
#[command(name = "pganeus", no_binary_name = true)]
enum Command {
    Train(train::TrainArgs),
    Merge(surfaces::MergeArgs),
    Bake(surfaces::BakeArgs),
    Mesh(surfaces::MeshArgs),
    Fit(fit::FitArgs),
    Eval(eval::EvalArgs),
    Report(report_page::ReportArgs),
    Calibrate(calibrate::CalibrateArgs),
    Masks(video_masks::MasksArgs),
    Synth(synth::SynthArgs),
    Demo(demo::DemoArgs),
}

/// Runs one stage; what it says when it ends (a fit's summary, the demo's report), if anything.
fn run(command: Command, observer: &dyn Observer) -> pipeline::Result<Option<String>> {
    Ok(match command {
        Command::Train(a) => train::run(&a, observer).map(|_| None)?,
        Command::Merge(a) => surfaces::merge(&a, observer).map(|_| None)?,
        Command::Bake(a) => surfaces::bake(&a, observer).map(|_| None)?,
        Command::Mesh(a) => surfaces::mesh(&a, observer).map(|_| None)?,
        Command::Fit(a) => Some(fit::run(&a, observer)?.summary).filter(|s| !s.is_empty()),
        Command::Eval(a) => eval::run(&a, observer).map(|_| None)?,
        Command::Report(a) => report_page::run(&a, observer).map(|_| None)?,
        Command::Calibrate(a) => calibrate::run(&a, observer).map(|_| None)?,
        Command::Masks(a) => video_masks::run(&a, observer).map(|_| None)?,
        Command::Synth(a) => synth::run(&a, observer).map(|_| None)?,
        Command::Demo(a) => Some(demo::run(&a, &demo::Library, observer)?.display().to_string()),
    })
}

/// Why a stage was stopped from Python: Ctrl-C, or the progress callback raised. The stage unwinds (its
/// outputs are written whole or not at all) and the error is raised in the caller.
struct Stopped;

/// Forwards a stage's events to a Python callable, and stops the stage when Python asks it to.
struct Forward {
    callback: Option<Py<PyAny>>,
    stopped: Mutex<Option<PyErr>>,
}

impl Forward {
    fn stop(&self, e: PyErr) -> ! {
        *self.stopped.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
        resume_unwind(Box::new(Stopped))
    }
}

impl Observer for Forward {
    fn event(&self, event: Event<'_>) {
        let outcome: PyResult<()> = Python::attach(|py| {
            // Only the main thread sees signals; elsewhere this is a no-op.
            py.check_signals()?;
            let Some(callback) = &self.callback else { return Ok(()) };
            let d = PyDict::new(py);
            match event {
                Event::Started { task, what, steps } => {
                    d.set_item("event", "started")?;
                    d.set_item("task", task)?;
                    d.set_item("what", what)?;
                    d.set_item("steps", steps)?;
                }
                Event::Progress { task, done, steps } => {
                    d.set_item("event", "progress")?;
                    d.set_item("task", task)?;
                    d.set_item("done", done)?;
                    d.set_item("steps", steps)?;
                }
                Event::Status { task, text } => {
                    d.set_item("event", "status")?;
                    d.set_item("task", task)?;
                    d.set_item("text", text)?;
                }
                Event::Finished { task } => {
                    d.set_item("event", "finished")?;
                    d.set_item("task", task)?;
                }
                Event::Note(text) => {
                    d.set_item("event", "note")?;
                    d.set_item("text", text)?;
                }
            }
            callback.call1(py, (d,)).map(|_| ())
        });
        if let Err(e) = outcome {
            self.stop(e);
        }
    }
}

/// Runs the stage `argv` names (`["fit", "data/slide", "--scene", ...]`, the command's words after
/// `pganeus`), reporting to `progress(event: dict)`; what the stage says at its end, or None.
#[pyfunction]
#[pyo3(signature = (argv, progress=None))]
pub fn run_command(py: Python<'_>, argv: Vec<String>, progress: Option<Py<PyAny>>) -> PyResult<Option<String>> {
    let command = Command::try_parse_from(&argv).map_err(|e| {
        let name = argv.first().map(String::as_str).unwrap_or("");
        errors::SettingsError::new_err(format!("pganeus.{name}: {}", e.render().to_string().trim_end()))
    })?;
    let forward = Forward {
        callback: progress,
        stopped: Mutex::new(None),
    };
    let outcome = py.detach(|| catch_unwind(AssertUnwindSafe(|| run(command, &forward))));
    match outcome {
        Ok(result) => result.map_err(|e| errors::to_py(&e)),
        Err(payload) if payload.is::<Stopped>() => {
            let stopped = forward.stopped.lock().unwrap_or_else(|p| p.into_inner()).take();
            Err(stopped.unwrap_or_else(|| PyKeyboardInterrupt::new_err("stopped")))
        }
        Err(payload) => resume_unwind(payload),
    }
}
