//! `pganeus`: one subcommand per pipeline stage. Commands parse their arguments, call the `pipeline`
//! library and draw its progress; the method is in the library crates.

mod commands;
#[cfg(test)]
mod docs_check;

use clap::{Parser, Subcommand};
use commands::Bars;
use pipeline::{
    board, calibrate, demo, eval, fit, import, import_session, render, report_page, run_session, surfaces, synth,
    train, video_masks,
};

#[derive(Parser)]
#[command(
    name = "pganeus",
    version,
    about = "Neural surfaces and rigid-body physics from camera footage (PGA-NeuS)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The whole method on the synthetic tabletop scene in one command (synth, train, merge, bake, fit, eval, report.md).
    Demo(demo::DemoArgs),
    /// A calibration board to print, from its board file: SVG at true size, or PNG at a dpi as OpenCV draws it.
    Board(board::BoardArgs),
    /// The lens and every camera from photos and videos of a printed board; NeuS captures in the board's metric world.
    Calibrate(calibrate::CalibrateArgs),
    /// A raw session (board.toml, background/, one folder per object pose and per video) → calibrated captures and session.json.
    Import(import_session::ImportSessionArgs),
    /// A NeuS capture from a COLMAP sparse model, put into the board's metric world (or the table's, with a scale).
    ImportColmap(import::ImportColmapArgs),
    /// A NeuS capture from a nerfstudio / instant-ngp transforms.json, put into the board's metric world.
    ImportTransforms(import::ImportTransformsArgs),
    /// The whole method on a data folder `import` wrote: scene, objects (masks computed), merge, bake, each video's fit, report.
    Run(run_session::RunArgs),
    /// Render a synthetic tabletop dataset with exact ground truth (NeuS layout).
    Synth(synth::SynthArgs),
    /// Train a NeuS field (SDF + colour) on a capture.
    Train(train::TrainArgs),
    /// Render a trained field from a capture's cameras (RGB, depth, normals) and print PSNR.
    Render(render::RenderArgs),
    /// The zero level of a trained field as a mesh (world coordinates).
    Mesh(surfaces::MeshArgs),
    /// Sample a trained field's or a closed mesh's SDF into a grid file for the simulator.
    Bake(surfaces::BakeArgs),
    /// One closed object from reconstructions in two poses (ICP, trim under the board, fuse).
    Merge(surfaces::MergeArgs),
    /// Chamfer distance, normal consistency and volume IoU of two meshes, as JSON.
    CompareMesh(surfaces::CompareMeshArgs),
    /// Simulate the bodies of a scene file and write trajectory.json.
    Simulate(commands::simulate::SimulateArgs),
    /// Find the launch velocity that brings a body to a point at a frame (Sec. 4.1).
    Target(commands::target::TargetArgs),
    /// Masks of the moving bodies in every frame of a fixed-camera video, computed against the trained scene.
    Masks(video_masks::MasksArgs),
    /// A body's pose in every frame of a fixed-camera video and the physics that explains it (first pose, PA, GA, PGA).
    Fit(fit::FitArgs),
    /// Score a fit against a scene's truth.json: per-frame position, rotation, ADD(-S), silhouette IoU; launch and contact errors; the object's mesh.
    Eval(eval::EvalArgs),
    /// One self-contained HTML page for a run's folder: inputs, meshes, each fit's motion (video and a novel view), charts (PNG and SVG too), tables.
    Report(report_page::ReportArgs),
    /// Recover v0, omega0, k_n and mu of a body from a pose sequence (Eq. 11).
    FitPhysics(commands::fit_physics::FitPhysicsArgs),
    /// Time the simulator (forward and with gradients) and print JSON lines.
    BenchSim(commands::bench_sim::BenchSimArgs),
    /// How well each contact model, fitted, explains motion Rapier made (JSON lines).
    BenchContact(commands::bench_contact::BenchContactArgs),
    /// Composed-rendering timings (rays/s; reference and fixed-camera fast path; JSON lines).
    BenchCompose(commands::bench_compose::BenchComposeArgs),
    /// Train on a synthetic object or scene capture and print speed, held-out PSNR and Chamfer distance as JSON lines.
    BenchTrain(commands::bench_train::BenchTrainArgs),
}

fn main() {
    pipeline::allocator::keep_freed_memory();
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .with_writer(std::io::stderr)
        .with_target(false)
        .init();
    let cli = Cli::parse();
    let result = dispatch(cli.command);
    if let Err(e) = result {
        // The chain of causes (no error quotes its source in its own message).
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// Runs one subcommand.
fn dispatch(command: Command) -> anyhow::Result<()> {
    let bars = Bars::default();
    match command {
        Command::Demo(a) => demo::run(&a, &demo::Library, &bars).map(|_| ())?,
        Command::Board(a) => board::run(&a, &bars).map(|_| ())?,
        Command::Calibrate(a) => calibrate::run(&a, &bars).map(|_| ())?,
        Command::Import(a) => import_session::run(&a, &bars).map(|_| ())?,
        Command::ImportColmap(a) => import::import_colmap(&a, &bars).map(|_| ())?,
        Command::ImportTransforms(a) => import::import_transforms(&a, &bars).map(|_| ())?,
        Command::Run(a) => run_session::run(&a, &demo::Library, &bars).map(|_| ())?,
        Command::Synth(a) => synth::run(&a, &bars)?,
        Command::Train(a) => train::run(&a, &bars)?,
        Command::Render(a) => render::run(&a, &bars)?,
        Command::Mesh(a) => surfaces::mesh(&a, &bars)?,
        Command::Bake(a) => surfaces::bake(&a, &bars)?,
        Command::CompareMesh(a) => surfaces::compare_mesh(&a, &bars)?,
        Command::Merge(a) => surfaces::merge(&a, &bars)?,
        Command::Simulate(a) => commands::simulate::run(a)?,
        Command::Target(a) => commands::target::run(a)?,
        Command::Fit(a) => {
            let outcome = fit::run(&a, &bars)?;
            if !outcome.summary.is_empty() {
                println!("{}", outcome.summary);
            }
        }
        Command::Eval(a) => eval::run(&a, &bars).map(|_| ())?,
        Command::Masks(a) => video_masks::run(&a, &bars).map(|_| ())?,
        Command::Report(a) => report_page::run(&a, &bars)?,
        Command::FitPhysics(a) => commands::fit_physics::run(a)?,
        Command::BenchSim(a) => commands::bench_sim::run(a)?,
        Command::BenchCompose(a) => commands::bench_compose::run(a)?,
        Command::BenchContact(a) => commands::bench_contact::run(a)?,
        Command::BenchTrain(a) => commands::bench_train::run(a)?,
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// A library caller's `FitArgs::new` is the command with only the required flags.
    #[test]
    fn fit_args_new_has_the_commands_defaults() {
        let argv = [
            "pganeus", "fit", "v", "--scene", "s", "--object", "toy=m", "--init", "auto", "--out", "o",
        ];
        let Command::Fit(parsed) = Cli::try_parse_from(argv).unwrap().command else {
            panic!("not a fit")
        };
        assert_eq!(parsed, fit::FitArgs::new("v", "s", &["toy=m"], "o"));
    }

    /// Every subcommand's `--help` ends with examples, and every example parses: its subcommand and flags
    /// exist and take the values given.
    #[test]
    fn every_subcommand_has_examples_that_parse() {
        let cli = Cli::command();
        let mut checked = 0;
        for sub in cli.get_subcommands() {
            let help = sub.get_after_help().map(|h| h.to_string()).unwrap_or_default();
            assert!(
                help.starts_with("Examples:"),
                "{}: no examples in --help",
                sub.get_name()
            );
            let examples: Vec<&str> = help.lines().filter_map(|l| l.trim().strip_prefix("pganeus ")).collect();
            assert!(!examples.is_empty(), "{}: {help}", sub.get_name());
            for example in examples {
                // A shell line may chain a second command or redirect the output.
                for command in example.split(" && pganeus ") {
                    let words = command.split(" > ").next().unwrap_or("").split_whitespace();
                    let argv: Vec<&str> = std::iter::once("pganeus").chain(words).collect();
                    if let Err(e) = Cli::try_parse_from(&argv) {
                        panic!(
                            "{}: the example `{}` does not parse: {e}",
                            sub.get_name(),
                            argv.join(" ")
                        );
                    }
                    checked += 1;
                }
            }
        }
        assert!(checked >= 20, "{checked} examples");
    }

    /// The demo runs each stage through the library with typed arguments and prints the command line a user
    /// would type for it: the two say the same (the command line, parsed, gives the stage's arguments).
    #[test]
    fn each_demo_stage_runs_what_its_command_line_says() {
        use pipeline::demo::{plan, DemoArgs, StageJob};
        use pipeline::synth::{PhysicsArg, ScaleArg};
        let mut checked = 0;
        for (preset, physics, quick, scale, camera_like) in [
            ("tabletop", None, false, ScaleArg::Small, false),
            ("tabletop", None, true, ScaleArg::Small, true),
            ("backdrop", Some(PhysicsArg::Rapier), false, ScaleArg::Large, false),
            ("two-body", Some(PhysicsArg::Pganeus), true, ScaleArg::Small, false),
            ("raw", None, false, ScaleArg::Small, false),
        ] {
            let a = DemoArgs {
                quick,
                out: None,
                force: false,
                preset: preset.into(),
                physics,
                scale,
                camera_like,
            };
            let (mut stages, _) = plan(&a).unwrap();
            if preset == "two-body" {
                // `run` on an imported session with two objects, scored against a truth.
                let session = pipeline::import_session::Session {
                    source: "session".into(),
                    board: "session/board.toml".into(),
                    scene: "background".into(),
                    objects: ["toy", "block"]
                        .map(|n| pipeline::import_session::SessionObject {
                            name: n.into(),
                            captures: [format!("{n}_a"), format!("{n}_b")],
                        })
                        .to_vec(),
                    videos: vec!["push".into(), "toss".into()],
                    video_bodies: [("toss".to_string(), vec!["toy".to_string()])].into(),
                };
                let mut run = pipeline::run_session::RunArgs::new("data", "out/session");
                run.quick = quick;
                run.truth = Some("data/truth.json".into());
                stages.extend(pipeline::run_session::stages_for(&run, &session));
            }
            for stage in stages {
                let argv: Vec<&str> = std::iter::once("pganeus")
                    .chain(stage.argv.iter().map(String::as_str))
                    .collect();
                let parsed = Cli::try_parse_from(&argv)
                    .unwrap_or_else(|e| panic!("{}: `{}` does not parse: {e}", stage.name, argv.join(" ")))
                    .command;
                match (parsed, &stage.job) {
                    (Command::Synth(p), StageJob::Synth(j)) => assert_eq!(&p, j),
                    (Command::Import(p), StageJob::Import(j)) => assert_eq!(&p, j),
                    (Command::Train(p), StageJob::Train(j)) => assert_eq!(&p, j),
                    (Command::Merge(p), StageJob::Merge(j)) => assert_eq!(&p, j),
                    (Command::Bake(p), StageJob::Bake(j)) => assert_eq!(&p, j),
                    (Command::Eval(p), StageJob::Eval(j)) => assert_eq!(&p, j),
                    (Command::Report(p), StageJob::Report(j)) => assert_eq!(&p, j),
                    (Command::Fit(p), StageJob::Fit { inputs, config, out }) => {
                        assert_eq!(&p.inputs().unwrap(), inputs, "{}", stage.name);
                        assert_eq!((&p.config, &p.out), (config, out), "{}", stage.name);
                        assert!(p.stages.is_none() && !p.force, "{}", stage.name);
                    }
                    (_, job) => panic!("{}: `{}` is another command than {job:?}", stage.name, argv.join(" ")),
                }
                checked += 1;
            }
        }
        assert!(checked >= 40, "{checked} stages");
    }
}
